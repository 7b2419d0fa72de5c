/* material.c - albedo from a file's materials (material.h says what is
 * read and how it becomes per-vertex albedo).
 *
 * Textures are decoded by stb_image (PNG, JPEG and the other formats it
 * reads) after its header has been checked against the size limits, and
 * kept as 8-bit sRGB: a 256-entry table turns a texel into linear light
 * when it is sampled. stb_image does not check PNG's CRCs, so a corrupt
 * PNG whose data still inflates decodes as what it holds.
 *
 * Depends on: material.h, hl_internal.h, stb_image, POSIX (access).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <threads.h>
#include <sys/stat.h>
#include <unistd.h>

#include <assimp/material.h>
#include <stb_image.h>

#include "material.h"

/* Sub-triangles per side when averaging a texture over a triangle: four
 * per texel along a side (hl.material.texture: a sharp colour edge then
 * moves a vertex's average by under 0.4% of the colour; one per texel
 * moved it by 4%), at least 4 (16 samples: each corner has samples of
 * its own) and at most 64 (4,096 samples for a triangle covering a whole
 * texture). */
#define TEX_SUB_PER_TEXEL 4.0
#define TEX_SUB_MIN 4
#define TEX_SUB_MAX 64

static float srgb_lut[256];
static once_flag srgb_once = ONCE_FLAG_INIT;

static void lut_fill(void)
{
    for (int i = 0; i < 256; i++) {
        double c = i / 255.0;
        srgb_lut[i] = (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
    }
}

/* Samplers may run on several threads at once. */
static void lut_init(void) { call_once(&srgb_once, lut_fill); }

void hl_materials_free_(hl_materials *m)
{
    if (!m) return;
    for (uint32_t i = 0; i < m->ntex; i++) {
        free(m->tex[i].name);
        free(m->tex[i].rgb);
        free(m->tex[i].file);
    }
    free(m->tex);
    free(m->mat);
    memset(m, 0, sizeof *m);
}

/* ---------------------------------------------------------------- texture files */

/* glTF URIs are percent-encoded; other formats' paths may use '\'. */
static void decode_uri(const char *in, char *out, size_t cap)
{
    size_t k = 0;
    for (size_t i = 0; in[i] && k + 1 < cap; i++) {
        char c = in[i];
        if (c == '%' && in[i + 1] && in[i + 2]) {
            char hex[3] = {in[i + 1], in[i + 2], 0}, *end;
            long v = strtol(hex, &end, 16);
            if (*end == 0 && v > 0) {
                out[k++] = v == '\\' ? '/' : (char)v;
                i += 2;
                continue;
            }
        }
        out[k++] = c == '\\' ? '/' : c;
    }
    out[k] = 0;
}

/* The texture's file, candidate k (0, 1): the path as the material gives
 * it (relative to the model's folder; Blender's leading "//" means that
 * folder too), then its last component in the model's folder, where
 * assets are usually copied with their textures (a path absolute on
 * another machine, "C:\\textures\\wood.png", ends there). 0 when there is
 * no such candidate or it does not fit. */
static int texture_path(const char *model, const char *name, int k, char *out, size_t cap)
{
    char dec[4096];
    decode_uri(name, dec, sizeof dec);
    const char *rel = dec;
    if (rel[0] == '/' && rel[1] == '/') rel += 2;
    const int absolute = rel == dec && (dec[0] == '/' || (dec[0] && dec[1] == ':'));
    if (k == 1) {
        const char *base = strrchr(rel, '/');
        if (!base) return 0; /* candidate 0 was it already */
        rel = base + 1;
    } else if (absolute) {
        if (dec[0] != '/') return 0; /* a drive letter: not on this machine */
        return snprintf(out, cap, "%s", dec) < (int)cap;
    }
    const char *slash = strrchr(model, '/');
    if (!slash) return snprintf(out, cap, "%s", rel) < (int)cap;
    return snprintf(out, cap, "%.*s/%s", (int)(slash - model), model, rel) < (int)cap;
}

/* The first candidate that exists as a file into file, 0 when none (one
 * that exists but cannot be read is then an error when read). */
static int find_texture(const char *model, const char *name, char *file, size_t cap)
{
    struct stat st;
    for (int k = 0; k < 2; k++)
        if (texture_path(model, name, k, file, cap) && stat(file, &st) == 0 && S_ISREG(st.st_mode)) return 1;
    return 0;
}

static hl_result read_file(hl_context *ctx, const char *what, const char *file, uint8_t **data, size_t *size)
{
    *data = NULL;
    FILE *f = fopen(file, "rb");
    if (!f) return hl_fail(ctx, HL_ERR_IO, "%s: cannot open %s: %s", what, file, strerror(errno));
    hl_result r = HL_OK;
    long n = -1;
    if (fseek(f, 0, SEEK_END) == 0) n = ftell(f);
    if (n < 0 || fseek(f, 0, SEEK_SET) != 0) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot read %s", what, file);
    else if (n == 0) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: %s is empty", what, file);
    else if ((unsigned long long)n > HL_TEXTURE_MAX_FILE_BYTES)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: %s holds %ld bytes, more than the %llu MiB a texture may", what, file, n,
                    HL_TEXTURE_MAX_FILE_BYTES >> 20);
    if (r == HL_OK) {
        *data = hl_malloc(ctx, (size_t)n, "a texture file");
        if (!*data) r = HL_ERR_OUT_OF_MEMORY;
        else if (fread(*data, 1, (size_t)n, f) != (size_t)n) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot read %s", what, file);
    }
    fclose(f);
    if (r != HL_OK) {
        free(*data);
        *data = NULL;
    }
    *size = (size_t)n;
    return r;
}

static hl_result check_size(hl_context *ctx, const char *what, uint64_t w, uint64_t h)
{
    if (w == 0 || h == 0) return hl_fail(ctx, HL_ERR_FORMAT, "%s: the image has no pixels", what);
    if (w > HL_TEXTURE_MAX_SIDE || h > HL_TEXTURE_MAX_SIDE || w * h > HL_TEXTURE_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: %llu x %llu pixels: larger than a texture may be (%u on a side, %llu "
                                           "megapixels)",
                       what, (unsigned long long)w, (unsigned long long)h, HL_TEXTURE_MAX_SIDE,
                       HL_TEXTURE_MAX_PIXELS / 1000000ull);
    return HL_OK;
}

/* Compressed bytes (a PNG or JPEG file's) into t. */
static hl_result decode(hl_context *ctx, const char *what, const uint8_t *data, size_t size, hl_texture *t)
{
    if (size > (size_t)INT32_MAX) return hl_fail(ctx, HL_ERR_FORMAT, "%s: too many bytes", what);
    int w = 0, h = 0, comp = 0;
    if (!stbi_info_from_memory(data, (int)size, &w, &h, &comp))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not an image the decoder reads (%s)", what, stbi_failure_reason());
    hl_result r = check_size(ctx, what, (uint64_t)w, (uint64_t)h);
    if (r != HL_OK) return r;
    uint8_t *px = stbi_load_from_memory(data, (int)size, &w, &h, &comp, 3);
    if (!px) return hl_fail(ctx, HL_ERR_FORMAT, "%s: corrupt image (%s)", what, stbi_failure_reason());
    size_t bytes = (size_t)w * (size_t)h * 3;
    t->rgb = hl_malloc(ctx, bytes, "a texture");
    if (!t->rgb) {
        stbi_image_free(px);
        return HL_ERR_OUT_OF_MEMORY;
    }
    memcpy(t->rgb, px, bytes); /* ours to free with free() */
    stbi_image_free(px);
    t->w = (uint32_t)w;
    t->h = (uint32_t)h;
    static const uint8_t png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'}, jpg[3] = {0xFF, 0xD8, 0xFF};
    t->format = size >= 8 && !memcmp(data, png, 8) ? "png" : size >= 3 && !memcmp(data, jpg, 3) ? "jpg" : NULL;
    if (t->format) {
        t->file = hl_malloc(ctx, size, "a texture file");
        if (!t->file) return HL_ERR_OUT_OF_MEMORY;
        memcpy(t->file, data, size);
        t->file_size = size;
    }
    return HL_OK;
}

/* An embedded texture: "*N", or one whose file name matches. NULL when
 * name is an external file. */
static const struct aiTexture *embedded(const struct aiScene *s, const char *name)
{
    if (name[0] == '*') {
        char *end;
        unsigned long i = strtoul(name + 1, &end, 10);
        if (*end == 0 && name[1] && i < s->mNumTextures) return s->mTextures[i];
        return NULL;
    }
    for (unsigned i = 0; i < s->mNumTextures; i++)
        if (s->mTextures[i] && strcmp(s->mTextures[i]->mFilename.data, name) == 0) return s->mTextures[i];
    return NULL;
}

/* A texture that cannot be had (missing, or a format stb_image does not
 * read: PCX, DDS, TIFF, KTX2) is left out with a warning: the material's
 * colour is used without it. Real assets often name textures that were
 * not shipped with them, or by a path on the machine they were made on. */
static void left_out(hl_context *ctx, const char *what, const char *why)
{
    if (!ctx || !ctx->quiet)
        fprintf(stderr, "haarlight: %s: warning: %s; the material's colour is used without it\n", what, why);
}

/* 1 when stb_image recognises the bytes' format (a damaged file of a
 * format it reads is then an error, not a texture left out). */
static int known_image(const uint8_t *data, size_t size)
{
    int w, h, c;
    if (size > (size_t)INT32_MAX) return 0;
    if (stbi_info_from_memory(data, (int)size, &w, &h, &c)) return 1;
    /* stbi_info also fails on an image too large for it; the signatures
       of PNG and JPEG tell those apart from unknown formats */
    static const uint8_t png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'}, jpg[3] = {0xFF, 0xD8, 0xFF};
    return (size >= 8 && !memcmp(data, png, 8)) || (size >= 3 && !memcmp(data, jpg, 3));
}

/* The texture into t; t->rgb stays NULL when it is left out (left_out). */
static hl_result load_texture(hl_context *ctx, const char *path, const struct aiScene *s, const char *mat_name,
                              const char *name, hl_texture *t)
{
    char what[1024];
    snprintf(what, sizeof what, "%s: material \"%s\": base colour texture \"%s\"", path, mat_name, name);
    if (name[0] == '*' && !embedded(s, name))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: the file embeds no such texture", what);
    const struct aiTexture *e = embedded(s, name);
    if (e && e->mHeight == 0) { /* compressed bytes */
        if (!known_image((const uint8_t *)e->pcData, e->mWidth)) {
            left_out(ctx, what, "embedded in a format the decoder does not read");
            return HL_OK;
        }
        return decode(ctx, what, (const uint8_t *)e->pcData, e->mWidth, t);
    }
    if (e) { /* raw texels, BGRA */
        hl_result r = check_size(ctx, what, e->mWidth, e->mHeight);
        if (r != HL_OK) return r;
        size_t n = (size_t)e->mWidth * e->mHeight;
        t->rgb = hl_malloc(ctx, n * 3, "a texture");
        if (!t->rgb) return HL_ERR_OUT_OF_MEMORY;
        for (size_t i = 0; i < n; i++) {
            t->rgb[3 * i] = e->pcData[i].r;
            t->rgb[3 * i + 1] = e->pcData[i].g;
            t->rgb[3 * i + 2] = e->pcData[i].b;
        }
        t->w = e->mWidth;
        t->h = e->mHeight;
        return HL_OK;
    }
    char file[4096];
    if (!find_texture(path, name, file, sizeof file)) {
        left_out(ctx, what, "not found");
        return HL_OK;
    }
    uint8_t *data = NULL;
    size_t size = 0;
    hl_result r = read_file(ctx, what, file, &data, &size);
    if (r == HL_OK && !known_image(data, size)) {
        left_out(ctx, what, "in a format the decoder does not read");
        free(data);
        return HL_OK;
    }
    if (r == HL_OK) r = decode(ctx, what, data, size, t);
    free(data);
    return r;
}

/* ---------------------------------------------------------------- materials */

static int material_used(const struct aiScene *s, unsigned mi)
{
    for (unsigned i = 0; i < s->mNumMeshes; i++)
        if (s->mMeshes[i]->mMaterialIndex == mi) return 1;
    return 0;
}

/* The textures of kinds the engine does not use: a missing file is worth
 * a warning (a viewer of the relit .glb may miss it), not an error. */
static void warn_unused(hl_context *ctx, const char *path, const struct aiScene *s, const struct aiMaterial *mat,
                        const char *mat_name)
{
    if (ctx && ctx->quiet) return;
    /* one file often serves several kinds (roughness and metalness):
       each missing file is named once */
    enum { SEEN = 16 };
    struct aiString seen[SEEN];
    int nseen = 0;
    for (int type = aiTextureType_NONE + 1; type <= AI_TEXTURE_TYPE_MAX; type++) {
        if (type == aiTextureType_DIFFUSE || type == aiTextureType_BASE_COLOR) continue;
        unsigned n = aiGetMaterialTextureCount(mat, (enum aiTextureType)type);
        for (unsigned k = 0; k < n; k++) {
            struct aiString p;
            if (aiGetMaterialTexture(mat, (enum aiTextureType)type, k, &p, NULL, NULL, NULL, NULL, NULL, NULL) !=
                aiReturn_SUCCESS)
                continue;
            char file[4096];
            if (!p.data[0] || embedded(s, p.data) || p.data[0] == '*') continue;
            if (find_texture(path, p.data, file, sizeof file)) continue;
            int dup = 0;
            for (int i = 0; i < nseen && !dup; i++) dup = strcmp(seen[i].data, p.data) == 0;
            if (dup) continue;
            if (nseen < SEEN) seen[nseen++] = p;
            fprintf(stderr,
                    "haarlight: %s: material \"%s\": warning: %s texture \"%s\" not found; the engine does not use "
                    "it\n",
                    path, mat_name, aiTextureTypeToString((enum aiTextureType)type), p.data);
        }
    }
}

/* An OBJ file, gzipped or not, by its name. */
static int is_obj(const char *path)
{
    size_t n = strlen(path);
    if (n > 3 && !strcmp(path + n - 3, ".gz")) n -= 3;
    return n >= 4 && (!strncmp(path + n - 4, ".obj", 4) || !strncmp(path + n - 4, ".OBJ", 4));
}

static hl_result read_material(hl_context *ctx, const char *path, const struct aiScene *s, hl_materials *m,
                               unsigned mi)
{
    const struct aiMaterial *mat = s->mMaterials[mi];
    hl_material *h = &m->mat[mi];
    h->tex = -1;
    struct aiString nm;
    char mat_name[256];
    int named = aiGetMaterialString(mat, AI_MATKEY_NAME, &nm) == aiReturn_SUCCESS;
    snprintf(mat_name, sizeof mat_name, "%.200s", named ? nm.data : "");
    if (!named) snprintf(mat_name, sizeof mat_name, "#%u", mi);
    struct aiColor4D c = {1, 1, 1, 1};
    int has_factor = aiGetMaterialColor(mat, AI_MATKEY_BASE_COLOR, &c) == aiReturn_SUCCESS ||
                     aiGetMaterialColor(mat, AI_MATKEY_COLOR_DIFFUSE, &c) == aiReturn_SUCCESS;
    const float f[3] = {(float)c.r, (float)c.g, (float)c.b};
    for (int k = 0; k < 3; k++) {
        if (!isfinite(f[k]))
            return hl_fail(ctx, HL_ERR_FORMAT, "%s: material \"%s\": the base colour (%g, %g, %g) is not finite", path,
                           mat_name, (double)f[0], (double)f[1], (double)f[2]);
        h->factor[k] = has_factor ? (f[k] < 0.0f ? 0.0f : (f[k] > 1.0f ? 1.0f : f[k])) : 1.0f;
    }
    struct aiString tp;
    unsigned uv = 0;
    int textured =
        aiGetMaterialTexture(mat, aiTextureType_BASE_COLOR, 0, &tp, NULL, &uv, NULL, NULL, NULL, NULL) == aiReturn_SUCCESS ||
        aiGetMaterialTexture(mat, aiTextureType_DIFFUSE, 0, &tp, NULL, &uv, NULL, NULL, NULL, NULL) == aiReturn_SUCCESS;
    textured = textured && tp.data[0]; /* an empty name (MD5 writes one) names nothing */
    const int white = h->factor[0] == 1.0f && h->factor[2] == 1.0f && h->factor[1] == 1.0f;
    const int default_named = named && strcmp(nm.data, AI_DEFAULT_MATERIAL_NAME) == 0;
    /* assimp's OBJ reader makes a material of Kd 0.6 for a `usemtl` whose
       library it cannot find (and for none at all): in an OBJ file that
       grey, untextured, is taken for no material */
    const int obj_grey = is_obj(path) && f[0] == 0.6f && f[1] == 0.6f && f[2] == 0.6f;
    const int factor_given = !default_named && !white && !obj_grey; /* given without a texture */
    h->given = textured ? !default_named : factor_given;
    warn_unused(ctx, path, s, mat, mat_name);
    if (!textured) return HL_OK;
    if (uv >= AI_MAX_NUMBER_OF_TEXTURECOORDS)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: material \"%s\": the base colour texture uses UV set %u, which does not exist",
                       path, mat_name, uv);
    h->uv = uv;
    for (uint32_t i = 0; i < m->ntex; i++) /* shared by several materials */
        if (strcmp(m->tex[i].name, tp.data) == 0) {
            h->tex = (int32_t)i;
            return HL_OK;
        }
    hl_texture t;
    memset(&t, 0, sizeof t);
    t.name = hl_malloc(ctx, strlen(tp.data) + 1, "a texture name");
    if (!t.name) return HL_ERR_OUT_OF_MEMORY;
    strcpy(t.name, tp.data);
    hl_result r = load_texture(ctx, path, s, mat_name, tp.data, &t);
    if (r != HL_OK || !t.rgb) { /* an error, or left out: the factor alone, as if untextured */
        free(t.name);
        free(t.rgb);
        free(t.file);
        if (r == HL_OK) {
            m->left_out++;
            h->given = factor_given;
        }
        return r;
    }
    m->tex[m->ntex] = t;
    h->tex = (int32_t)m->ntex++;
    return HL_OK;
}

hl_result hl_materials_read_(hl_context *ctx, const char *path, const struct aiScene *s, hl_materials *out)
{
    memset(out, 0, sizeof *out);
    lut_init();
    if (!s->mMaterials || s->mNumMaterials == 0) return HL_OK;
    out->count = s->mNumMaterials;
    out->mat = hl_calloc(ctx, s->mNumMaterials, sizeof *out->mat, "the materials");
    out->tex = hl_calloc(ctx, s->mNumMaterials, sizeof *out->tex, "the textures");
    if (!out->mat || !out->tex) {
        hl_materials_free_(out);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (unsigned i = 0; i < s->mNumMaterials; i++) {
        out->mat[i].tex = -1;
        if (!material_used(s, i)) continue;
        hl_result r = read_material(ctx, path, s, out, i);
        if (r != HL_OK) {
            hl_materials_free_(out);
            return r;
        }
    }
    for (unsigned i = 0; i < s->mNumMeshes; i++) {
        const struct aiMesh *am = s->mMeshes[i];
        if (am->mMaterialIndex >= out->count) continue;
        const hl_material *h = &out->mat[am->mMaterialIndex];
        if (h->tex >= 0 && !am->mTextureCoords[h->uv]) {
            out->uv_missing++;
            if (!ctx || !ctx->quiet)
                fprintf(stderr,
                        "haarlight: %s: warning: mesh \"%s\" has a base colour texture but no UV set %u; its texture "
                        "is left out\n",
                        path, am->mName.data, h->uv);
        }
    }
    return HL_OK;
}

int hl_materials_any_given_(const hl_materials *m, const struct aiScene *s)
{
    for (unsigned i = 0; i < s->mNumMeshes; i++) {
        const struct aiMesh *am = s->mMeshes[i];
        if (am->mColors[0]) return 1;
        if (am->mMaterialIndex < m->count && m->mat[am->mMaterialIndex].given) return 1;
    }
    return 0;
}

int hl_materials_textured_(const hl_materials *m, const struct aiScene *s)
{
    for (unsigned i = 0; i < s->mNumMeshes; i++) {
        const struct aiMesh *am = s->mMeshes[i];
        if (am->mMaterialIndex < m->count && m->mat[am->mMaterialIndex].tex >= 0 &&
            am->mTextureCoords[m->mat[am->mMaterialIndex].uv])
            return 1;
    }
    return 0;
}

int hl_materials_any_colors_(const struct aiScene *s)
{
    for (unsigned i = 0; i < s->mNumMeshes; i++)
        if (s->mMeshes[i]->mColors[0]) return 1;
    return 0;
}

void hl_materials_note_(hl_context *ctx, const char *path, const hl_materials *m)
{
    if (ctx && ctx->quiet) return;
    uint32_t given = 0;
    for (uint32_t i = 0; i < m->count; i++) given += m->mat[i].given;
    if (!given) return;
    fprintf(stderr, "haarlight: %s: albedo from %u material%s", path, given, given == 1 ? "" : "s");
    for (uint32_t i = 0; i < m->ntex; i++)
        fprintf(stderr, "%s texture \"%s\" (%u x %u)", i ? "," : " with", m->tex[i].name, m->tex[i].w, m->tex[i].h);
    if (m->left_out) fprintf(stderr, "; %u base colour texture%s left out", m->left_out, m->left_out == 1 ? "" : "s");
    fprintf(stderr, "\n");
}

static const hl_material *mesh_material(const hl_materials *m, const struct aiMesh *am)
{
    return am->mMaterialIndex < m->count ? &m->mat[am->mMaterialIndex] : NULL;
}

void hl_material_vertex_base_(const hl_materials *m, const struct aiMesh *am, size_t v, const float fallback[3],
                              float out[3])
{
    const hl_material *h = mesh_material(m, am);
    const int given = h && h->given;
    for (int k = 0; k < 3; k++) out[k] = given ? h->factor[k] : (am->mColors[0] ? 1.0f : fallback[k]);
    if (am->mColors[0]) { /* linear, as glTF's COLOR_0; NaN passes on for the builder to report */
        const float c[3] = {(float)am->mColors[0][v].r, (float)am->mColors[0][v].g, (float)am->mColors[0][v].b};
        for (int k = 0; k < 3; k++) {
            float x = c[k] != c[k] ? c[k] : (c[k] < 0.0f ? 0.0f : (c[k] > 1.0f ? 1.0f : c[k]));
            out[k] *= x;
        }
    }
}

/* ---------------------------------------------------------------- sampling */

static uint32_t wrap(long i, uint32_t n)
{
    long r = i % (long)n;
    return (uint32_t)(r < 0 ? r + (long)n : r);
}

void hl_texture_sample_(const hl_texture *t, float u, float v, float rgb[3])
{
    /* the table is filled: every texture comes through hl_materials_read_ */
    /* texel centres at half-integers; v up, rows down */
    double x = (double)u * t->w - 0.5, y = (1.0 - (double)v) * t->h - 0.5;
    if (!isfinite(x) || !isfinite(y) || fabs(x) > 1e9 || fabs(y) > 1e9) x = y = 0.0;
    double fx = floor(x), fy = floor(y);
    float ax = (float)(x - fx), ay = (float)(y - fy);
    uint32_t x0 = wrap((long)fx, t->w), x1 = wrap((long)fx + 1, t->w);
    uint32_t y0 = wrap((long)fy, t->h), y1 = wrap((long)fy + 1, t->h);
    const uint8_t *p00 = t->rgb + 3 * ((size_t)y0 * t->w + x0), *p01 = t->rgb + 3 * ((size_t)y0 * t->w + x1);
    const uint8_t *p10 = t->rgb + 3 * ((size_t)y1 * t->w + x0), *p11 = t->rgb + 3 * ((size_t)y1 * t->w + x1);
    for (int k = 0; k < 3; k++) {
        float top = srgb_lut[p00[k]] + ax * (srgb_lut[p01[k]] - srgb_lut[p00[k]]);
        float bot = srgb_lut[p10[k]] + ax * (srgb_lut[p11[k]] - srgb_lut[p10[k]]);
        rgb[k] = top + ay * (bot - top);
    }
}

void hl_material_face_tex_(const hl_materials *m, const struct aiMesh *am, const struct aiFace *f, float out[9])
{
    for (int i = 0; i < 9; i++) out[i] = 1.0f;
    const hl_material *h = mesh_material(m, am);
    if (!h || h->tex < 0 || !am->mTextureCoords[h->uv] || f->mNumIndices != 3) return;
    const hl_texture *t = &m->tex[h->tex];
    float uv[3][2];
    for (int c = 0; c < 3; c++) {
        unsigned i = f->mIndices[c];
        if (i >= am->mNumVertices) return; /* the builder reports the index */
        uv[c][0] = (float)am->mTextureCoords[h->uv][i].x;
        uv[c][1] = (float)am->mTextureCoords[h->uv][i].y;
        if (!isfinite(uv[c][0]) || !isfinite(uv[c][1])) return;
    }
    /* the triangle's area in texels sets the subdivision */
    double e1u = uv[1][0] - uv[0][0], e1v = uv[1][1] - uv[0][1], e2u = uv[2][0] - uv[0][0], e2v = uv[2][1] - uv[0][1];
    double texels = 0.5 * fabs(e1u * e2v - e1v * e2u) * t->w * t->h;
    double nd = ceil(TEX_SUB_PER_TEXEL * sqrt(texels));
    int n = nd < TEX_SUB_MIN ? TEX_SUB_MIN : (nd > TEX_SUB_MAX ? TEX_SUB_MAX : (int)nd);
    /* centroids of the n^2 sub-triangles (n(n+1)/2 upright, n(n-1)/2
       inverted), each sample weighted towards corner c by its barycentric
       coordinate: the hat function of c */
    double acc[3][3] = {{0}}, wsum[3] = {0};
    for (int i = 0; i < n; i++)
        for (int j = 0; i + j < n; j++)
            for (int inv = 0; inv < 2; inv++) {
                if (inv && i + j >= n - 1) continue;
                double a = (i + (inv ? 2.0 : 1.0) / 3.0) / n, b = (j + (inv ? 2.0 : 1.0) / 3.0) / n;
                double l[3] = {1.0 - a - b, a, b};
                float rgb[3];
                hl_texture_sample_(t, (float)(l[0] * uv[0][0] + l[1] * uv[1][0] + l[2] * uv[2][0]),
                                   (float)(l[0] * uv[0][1] + l[1] * uv[1][1] + l[2] * uv[2][1]), rgb);
                for (int c = 0; c < 3; c++) {
                    wsum[c] += l[c];
                    for (int k = 0; k < 3; k++) acc[c][k] += l[c] * rgb[k];
                }
            }
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < 3; k++) out[3 * c + k] = (float)(acc[c][k] / wsum[c]);
}

/* ---------------------------------------------------------------- surfaces */

void hl_surface_face_(const hl_materials *mats, const struct aiMesh *am, const struct aiFace *af,
                      const float fallback[3], hl_surface *su, size_t t, int mirror)
{
    const hl_material *h = am->mMaterialIndex < mats->count ? &mats->mat[am->mMaterialIndex] : NULL;
    const int textured = h && h->tex >= 0 && am->mTextureCoords[h->uv];
    su->tex[t] = textured ? h->tex : -1;
    for (int c = 0; c < 3; c++) {
        const size_t q = (size_t)(mirror && c ? 3 - c : c); /* the corner as the triangle is stored */
        unsigned i = af->mIndices[c] < am->mNumVertices ? af->mIndices[c] : 0; /* else refused by the builder */
        su->uv[6 * t + 2 * q] = textured ? (float)am->mTextureCoords[h->uv][i].x : 0.0f;
        su->uv[6 * t + 2 * q + 1] = textured ? (float)am->mTextureCoords[h->uv][i].y : 0.0f;
        hl_material_vertex_base_(mats, am, i, fallback, su->base + 9 * t + 3 * q);
    }
}

hl_result hl_surface_arrays_(hl_context *ctx, hl_surface *su, uint32_t ntri)
{
    su->triangle_count = ntri;
    su->uv = hl_calloc(ctx, (size_t)ntri * 6 + 1, sizeof(float), "the surface's UVs");
    su->tex = hl_calloc(ctx, (size_t)ntri + 1, sizeof(int32_t), "the surface's textures");
    su->base = hl_calloc(ctx, (size_t)ntri * 9 + 1, sizeof(float), "the surface's colours");
    return su->uv && su->tex && su->base ? HL_OK : HL_ERR_OUT_OF_MEMORY;
}

void hl_surface_arrays_free_(hl_surface *su)
{
    free(su->uv);
    free(su->tex);
    free(su->base);
    su->uv = su->base = NULL;
    su->tex = NULL;
}

hl_result hl_surface_finish_(hl_context *ctx, const hl_surface *in, const uint32_t *origin, uint32_t ntri,
                             int flipped, hl_surface **out)
{
    hl_surface *su = hl_calloc(ctx, 1, sizeof *su, "the surface");
    if (!su) return HL_ERR_OUT_OF_MEMORY;
    const size_t nt = ntri;
    if (hl_surface_arrays_(ctx, su, ntri) != HL_OK) {
        hl_surface_destroy(su);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (size_t t = 0; t < nt; t++) {
        size_t o = origin[t];
        su->tex[t] = in->tex[o];
        for (int c = 0; c < 3; c++) {
            int from = flipped && c ? 3 - c : c; /* a flip swapped corners 1 and 2 */
            memcpy(su->uv + 6 * t + 2 * (size_t)c, in->uv + 6 * o + 2 * (size_t)from, 2 * sizeof(float));
            memcpy(su->base + 9 * t + 3 * (size_t)c, in->base + 9 * o + 3 * (size_t)from, 3 * sizeof(float));
        }
    }
    *out = su;
    return HL_OK;
}
