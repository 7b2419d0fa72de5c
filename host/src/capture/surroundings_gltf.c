/* surroundings_gltf.c - glTF's KHR_materials_emissive_strength, read from
 * the file's JSON because assimp 5.2 (Debian's 5.2.5) does not: it gives
 * the emissive factor (clamped to [0, 1] by glTF) as
 * AI_MATKEY_COLOR_EMISSIVE and drops the strength, so a glTF lamp brighter
 * than 1 would load at radiance 1. Assimp also renumbers materials (used
 * ones first, its default last), so the strength is attached through the
 * primitives, whose order assimp keeps (one aiMesh per primitive), and
 * the count is checked so a mismatch is an error, not a wrong light.
 * A small cursor over the JSON, no tree: only materials[].extensions
 * .KHR_materials_emissive_strength.emissiveStrength and
 * meshes[].primitives[].material are read; everything else is skipped.
 *
 * Depends on: surroundings.h, hl_internal.h (errors, allocation), libc.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "surroundings.h"

/* The extension's name, looked for before parsing anything. */
#define GLTF_EXT "KHR_materials_emissive_strength"
/* The longest key compared; longer keys are skipped as non-matching. */
#define GLTF_KEY_MAX 64

typedef struct js {
    const char *p, *end;
    int bad;
} js;

static void ws(js *j)
{
    while (j->p < j->end && (*j->p == ' ' || *j->p == '\t' || *j->p == '\n' || *j->p == '\r')) j->p++;
}

static int peek(js *j)
{
    ws(j);
    return j->p < j->end ? (unsigned char)*j->p : -1;
}

/* A string at the cursor; its first cap - 1 bytes (escapes kept raw) into
 * out when out is not NULL. */
static void str(js *j, char *out, size_t cap)
{
    size_t n = 0;
    if (peek(j) != '"') { j->bad = 1; return; }
    j->p++;
    while (j->p < j->end && *j->p != '"') {
        if (*j->p == '\\') j->p++;
        if (out && n + 1 < cap && j->p < j->end) out[n++] = *j->p;
        j->p++;
    }
    if (j->p >= j->end) { j->bad = 1; return; }
    j->p++;
    if (out) out[n] = 0;
}

static double num(js *j)
{
    char buf[64];
    size_t n = 0;
    ws(j);
    while (j->p < j->end && n + 1 < sizeof buf && strchr("+-0123456789.eE", *j->p)) buf[n++] = *j->p++;
    buf[n] = 0;
    char *e = NULL;
    double v = n ? strtod(buf, &e) : 0.0;
    if (!n || *e) j->bad = 1;
    return v;
}

static void skip(js *j, int depth);

/* The next member of the object being read: 1 with its key in key and the
 * cursor on its value, 0 after the closing brace. Call after '{'. */
static int member(js *j, char key[GLTF_KEY_MAX])
{
    int c = peek(j);
    if (c == '}') { j->p++; return 0; }
    if (c == ',') j->p++;
    str(j, key, GLTF_KEY_MAX);
    if (peek(j) != ':') j->bad = 1;
    else j->p++;
    return !j->bad;
}

/* The next element of the array being read: 1 with the cursor on it, 0
 * after the closing bracket. Call after '['. */
static int element(js *j)
{
    int c = peek(j);
    if (c == ']') { j->p++; return 0; }
    if (c == ',') j->p++;
    return !j->bad && peek(j) >= 0;
}

/* Consumes the opening c ('{' or '['); bad when the value is not one. */
static int enter(js *j, int c)
{
    if (peek(j) != c) { j->bad = 1; return 0; }
    j->p++;
    return 1;
}

static void skip(js *j, int depth)
{
    char key[GLTF_KEY_MAX];
    int c = peek(j);
    if (depth > HL_GLTF_MAX_DEPTH || c < 0) { j->bad = 1; return; }
    if (c == '"') str(j, NULL, 0);
    else if (c == '{') {
        j->p++;
        while (!j->bad && member(j, key)) skip(j, depth + 1);
    } else if (c == '[') {
        j->p++;
        while (!j->bad && element(j)) skip(j, depth + 1);
    } else if (c == 't' || c == 'f' || c == 'n')
        while (j->p < j->end && *j->p >= 'a' && *j->p <= 'z') j->p++;
    else num(j);
}

/* A growing list of floats (strengths per material, material per primitive). */
typedef struct flist {
    double *v;
    size_t n, cap;
} flist;

static int push(flist *l, double v)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        double *g = realloc(l->v, cap * sizeof *g);
        if (!g) return 0;
        l->v = g;
        l->cap = cap;
    }
    l->v[l->n++] = v;
    return 1;
}

/* One material: its strength, 1 without the extension. */
static double material(js *j)
{
    char k1[GLTF_KEY_MAX], k2[GLTF_KEY_MAX], k3[GLTF_KEY_MAX];
    double s = 1.0;
    if (!enter(j, '{')) return s;
    while (!j->bad && member(j, k1)) {
        if (strcmp(k1, "extensions") || !enter(j, '{')) { skip(j, 1); continue; }
        while (!j->bad && member(j, k2)) {
            if (strcmp(k2, GLTF_EXT) || !enter(j, '{')) { skip(j, 2); continue; }
            while (!j->bad && member(j, k3)) {
                if (strcmp(k3, "emissiveStrength")) skip(j, 3);
                else s = num(j);
            }
        }
    }
    return s;
}

/* One mesh: each primitive's material index (-1 without one) onto prims. */
static int mesh(js *j, flist *prims)
{
    char k1[GLTF_KEY_MAX], k2[GLTF_KEY_MAX];
    if (!enter(j, '{')) return 1;
    while (!j->bad && member(j, k1)) {
        if (strcmp(k1, "primitives") || !enter(j, '[')) { skip(j, 1); continue; }
        while (!j->bad && element(j)) {
            double m = -1.0;
            if (!enter(j, '{')) break;
            while (!j->bad && member(j, k2)) {
                if (strcmp(k2, "material")) skip(j, 3);
                else m = num(j);
            }
            if (!push(prims, m)) return 0;
        }
    }
    return 1;
}

/* The JSON text of the file (a .glb's first chunk), or NULL when the file
 * is not glTF; *err set when it cannot be read. */
static char *json_of(const char *path, size_t *len, int *err)
{
    *err = 0;
    const char *dot = strrchr(path, '.');
    FILE *f = fopen(path, "rb");
    if (!f) { *err = errno; return NULL; }
    unsigned char h[20];
    size_t got = fread(h, 1, sizeof h, f);
    int glb = got == sizeof h && !memcmp(h, "glTF", 4) && !memcmp(h + 16, "JSON", 4);
    int text = dot && (!strcmp(dot, ".gltf") || !strcmp(dot, ".GLTF"));
    size_t off = 0, n = 0;
    if (glb) {
        n = (size_t)h[12] | (size_t)h[13] << 8 | (size_t)h[14] << 16 | (size_t)h[15] << 24;
        off = 20;
    } else if (text && fseek(f, 0, SEEK_END) == 0) {
        long e = ftell(f);
        n = e > 0 ? (size_t)e : 0;
    }
    char *buf = (glb || text) && n ? malloc(n + 1) : NULL;
    if (buf && (fseek(f, (long)off, SEEK_SET) != 0 || fread(buf, 1, n, f) != n)) {
        free(buf);
        buf = NULL;
        *err = EIO;
    } else if (!buf && (glb || text) && n)
        *err = ENOMEM;
    fclose(f);
    if (buf) buf[n] = 0;
    *len = n;
    return buf;
}

/* Reads the materials' strengths and the primitives' materials. */
static void parse_root(js *j, flist *mats, flist *prims, int *oom)
{
    char key[GLTF_KEY_MAX];
    if (!enter(j, '{')) return;
    while (!j->bad && !*oom && member(j, key)) {
        if (!strcmp(key, "materials") && enter(j, '[')) {
            while (!j->bad && !*oom && element(j)) *oom = !push(mats, material(j));
        } else if (!strcmp(key, "meshes") && enter(j, '[')) {
            while (!j->bad && !*oom && element(j)) *oom = !mesh(j, prims);
        } else
            skip(j, 1);
    }
}

hl_result hl_gltf_emissive_strength_(hl_context *ctx, const char *path, uint32_t nmeshes, float *strength)
{
    for (uint32_t m = 0; m < nmeshes; m++) strength[m] = 1.0f;
    size_t len = 0;
    int err = 0;
    char *text = json_of(path, &len, &err);
    if (err) return hl_fail(ctx, HL_ERR_IO, "%s: cannot read the glTF JSON for emissive strength: %s", path, strerror(err));
    if (!text || !strstr(text, GLTF_EXT)) { /* (a .glb's JSON is NUL-terminated by json_of) */
        free(text);
        return HL_OK;
    }
    js j = {text, text + len, 0};
    flist mats = {0}, prims = {0};
    int oom = 0;
    parse_root(&j, &mats, &prims, &oom);
    hl_result r = HL_OK;
    if (oom) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory reading the glTF JSON", path);
    else if (j.bad) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: malformed glTF JSON near byte %ld", path, (long)(j.p - text));
    else if (prims.n != nmeshes)
        r = hl_fail(ctx, HL_ERR_FORMAT,
                    "%s: %zu primitives in the glTF but %u meshes from the importer: cannot tell which "
                    "triangles KHR_materials_emissive_strength applies to",
                    path, prims.n, nmeshes);
    for (size_t i = 0; i < mats.n && r == HL_OK; i++)
        if (!(isfinite(mats.v[i]) && mats.v[i] >= 0.0 && mats.v[i] <= 3.4e38))
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: material %zu: emissiveStrength %g is not a finite number >= 0", path, i,
                        mats.v[i]);
    for (size_t i = 0; i < prims.n && r == HL_OK; i++) {
        double m = prims.v[i];
        if (m < 0.0) continue; /* assimp's default material: no emission */
        if (m != floor(m) || m >= (double)mats.n)
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: primitive %zu: material %g is not one of the %zu materials", path, i, m,
                        mats.n);
        else
            strength[i] = (float)mats.v[(size_t)m];
    }
    free(mats.v);
    free(prims.v);
    free(text);
    return r;
}
