/* mesh_import.c - hl_mesh_load: reading mesh files through assimp.
 *
 * With assimp_guard.c and dynamic/scene.c (scenes of moving bodies), the only
 * files that include assimp. Every format
 * (OBJ, PLY, glTF, ...) goes through aiImportFile; the raw arrays then go
 * to hl_mesh_build_ in mesh.c, which welds, drops degenerates and computes
 * normals. assimp's OBJ importer gives each face corner its own vertex and
 * drops vertices no face uses, so for OBJ the "merged" count includes that
 * expansion and unreferenced vertices of the file are not seen. Files and
 * scenes that would hang, abort, corrupt or exhaust assimp 5.2 are refused
 * by the guards of assimp_guard.c before it gets to them; load_assimp
 * gives the safe order of calls.
 *
 * A gzipped file (`mesh.obj.gz`: any X.gz whose inner extension assimp
 * reads) is decompressed into memory by gz_read.c and imported from there
 * with the inner extension as the format's hint, through the same guards.
 *
 * Dependencies: assimp C API (Debian libassimp-dev 5.2), assimp_guard.h,
 * gz_read.h (zlib), POSIX (stat, fmemopen), hl_internal.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "assimp_guard.h"
#include "gz_read.h"
#include "hl_internal.h"
#include "material.h"
#include "mesh_ops.h"

/* Where the importer reads from: the file itself, or its bytes in memory
 * (a decompressed .gz) with the format's extension as assimp's hint. path
 * is the file's name either way, for messages. */
typedef struct mesh_src {
    const char *path;
    const uint8_t *data; /* NULL: assimp opens path */
    size_t size;
    const char *hint; /* extension without the dot, for data */
} mesh_src;

static const struct aiScene *import_scene(const mesh_src *src, unsigned flags)
{
    if (!src->data) return aiImportFile(src->path, flags);
    return aiImportFileFromMemory((const char *)src->data, (unsigned)src->size, flags, src->hint);
}

/* Opens path to learn whether it is a readable, non-empty regular file, so
 * that a missing file is HL_ERR_IO and an empty one HL_ERR_FORMAT whatever
 * the importer would have said. Returns the open stream on success. */
static hl_result open_checked(hl_context *ctx, const char *path, FILE **out, size_t *size)
{
    *out = NULL;
    FILE *f = fopen(path, "rb");
    if (!f) return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(f);
        return hl_fail(ctx, HL_ERR_IO, "%s: not a regular file", path);
    }
    if (st.st_size == 0) {
        fclose(f);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: empty file", path);
    }
    if ((unsigned long long)st.st_size >= (unsigned long long)SIZE_MAX) {
        fclose(f);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: file too large", path);
    }
    *out = f;
    *size = (size_t)st.st_size;
    return HL_OK;
}

/* A file the importer may be given: open_checked's checks, then the
 * guards that refuse what would hang or crash assimp. */
static hl_result guard_file(hl_context *ctx, const char *path)
{
    FILE *f = NULL;
    size_t size = 0;
    hl_result r = open_checked(ctx, path, &f, &size);
    if (r != HL_OK) return r;
    char msg[160];
    int bad = hl_assimp_file_problem_(path, f, size, msg, sizeof msg);
    fclose(f);
    return bad ? hl_fail(ctx, HL_ERR_FORMAT, "%s: %s", path, msg) : HL_OK;
}

/* The motion a raw scene holds: its animations, and its meshes with bones
 * or morph targets. */
static void read_motion(const struct aiScene *s, hl_mesh_motion *motion)
{
    motion->animations = s->mNumAnimations;
    for (unsigned m = 0; m < s->mNumMeshes; m++) {
        motion->skinned += s->mMeshes[m]->mNumBones > 0;
        motion->morphing += s->mMeshes[m]->mNumAnimMeshes > 0;
    }
}

static void skipped_note(hl_context *ctx, const char *path, uint64_t skipped)
{
    if (skipped && ctx && !ctx->quiet)
        fprintf(stderr, "haarlight: %s: skipped %llu point/line primitives\n", path,
                (unsigned long long)skipped);
}

/* After a failed import: assimp's validation reports a mesh without faces
 * or vertices, a scene without meshes, and any other inconsistency of the
 * scene an importer built, like any other error, and an allocation that
 * failed inside it comes back as "std::bad_alloc", so they are told apart
 * by its message. (Importing without validation to count them instead is
 * not safe: assimp's scene preprocessing then walks the unvalidated data
 * and crashes on some corrupt files.) */
static hl_result assimp_failure(hl_context *ctx, const char *path, const char *msg)
{
    if (strstr(msg, "contains no faces"))
        return hl_fail(ctx, HL_ERR_MESH, "%s: the mesh has no faces (importer: %s)", path, msg);
    if (strstr(msg, "contains no vertices"))
        return hl_fail(ctx, HL_ERR_MESH, "%s: the mesh has no vertices (importer: %s)", path, msg);
    if (strstr(msg, "mNumMeshes is 0"))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: the file holds no mesh (importer: %s)", path, msg);
    if (strstr(msg, "bad_alloc"))
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory while importing the file (importer: %s)", path,
                       msg);
    if (strncmp(msg, "Validation failed", 17) == 0)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: the importer built an inconsistent scene from the file (importer: %s)",
                       path, msg);
    return hl_fail(ctx, HL_ERR_FORMAT, "%s: importer: %s", path, msg);
}

/* Copies the post-processed scene's meshes, one after the other, into
 * pos (and nrm, col, tex where not NULL) and its triangles into idx; other
 * faces (points, lines) are left out. col gets each vertex's albedo base
 * and tex each triangle's texture averages (material.h). The arrays hold
 * the totals that load_assimp counted. */
/* With a surface wanted, su gets each input triangle's UVs, texture and
 * corner bases (struct hl_surface's layout, by input triangle). */
static void copy_scene(const struct aiScene *s, const hl_materials *mats, const float fallback[3], float *pos,
                       float *nrm, float *col, float *tex, uint32_t *idx, hl_surface *su)
{
    size_t base = 0, t = 0;
    for (unsigned m = 0; m < s->mNumMeshes; m++) {
        const struct aiMesh *am = s->mMeshes[m];
        for (size_t v = 0; v < am->mNumVertices; v++) {
            float *p = pos + 3 * (base + v);
            p[0] = (float)am->mVertices[v].x;
            p[1] = (float)am->mVertices[v].y;
            p[2] = (float)am->mVertices[v].z;
            if (nrm) {
                float *n = nrm + 3 * (base + v);
                n[0] = (float)am->mNormals[v].x;
                n[1] = (float)am->mNormals[v].y;
                n[2] = (float)am->mNormals[v].z;
            }
            if (col) hl_material_vertex_base_(mats, am, v, fallback, col + 3 * (base + v));
        }
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            const struct aiFace *af = &am->mFaces[f];
            if (af->mNumIndices != 3) continue;
            for (int k = 0; k < 3; k++) {
                /* An index past this mesh's vertices stays out of range
                 * after the offset so the builder reports it. */
                uint64_t i = af->mIndices[k] < am->mNumVertices ? base + af->mIndices[k] : UINT32_MAX;
                idx[3 * t + k] = (uint32_t)(i > UINT32_MAX ? UINT32_MAX : i);
            }
            if (tex) hl_material_face_tex_(mats, am, af, tex + 9 * t);
            if (su) hl_surface_face_(mats, am, af, fallback, su, t, 0);
            t++;
        }
        base += am->mNumVertices;
    }
}

static hl_result load_assimp(hl_context *ctx, const mesh_src *src, const hl_mesh_load_desc *desc,
                             hl_mesh **out, hl_mesh_stats *stats, hl_mesh_motion *motion, hl_surface **surf)
{
    const char *path = src->path;
    /* The safe order of calls with assimp 5.2's C API:
     * 1. aiImportFile with validation only: the raw scene, whose failures
     *    come back cleanly.
     * 2. hl_raw_scene_problem_ (assimp_guard.c): refuses what
     *    triangulation and flattening would abort, throw or overrun on.
     * 3. The scene is released and the file imported again in one call
     *    with the steps. aiApplyPostProcessing on the raw scene cannot
     *    fail safely: when a step throws (the DeadlyImportError of
     *    PretransformVertices, std::bad_alloc when a mesh placed by many
     *    nodes takes more memory than there is), the importer deletes the
     *    scene and aiApplyPostProcessing then releases it again through
     *    aiReleaseImport (a use after free; AC/nosurfaces.ac of
     *    assimp-testmodels crashed there). Inside aiImportFile the same
     *    failure is a NULL scene with the message. The steps cannot be
     *    asked of the first import: it must be checked before they run.
     * Vertex joining and normal generation stay off: the builder does both
     * and counts what it changed. The second import costs one more parse
     * of the file (under a second for every assimp test model). */
    const struct aiScene *s = import_scene(src, aiProcess_ValidateDataStructure);
    if (!s) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", aiGetErrorString());
        return assimp_failure(ctx, path, msg);
    }
    hl_result r = hl_raw_scene_problem_(ctx, path, s);
    if (r == HL_OK && motion) read_motion(s, motion); /* what the baked pose leaves behind */
    aiReleaseImport(s);
    if (r != HL_OK) return r;
    s = import_scene(src, aiProcess_ValidateDataStructure | aiProcess_Triangulate | aiProcess_PreTransformVertices);
    if (!s) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", aiGetErrorString());
        return assimp_failure(ctx, path, msg);
    }
    uint64_t nv = 0, nt = 0, skipped = 0;
    int all_normals = s->mNumMeshes > 0;
    hl_materials mats;
    memset(&mats, 0, sizeof mats);
    r = hl_materials_read_(ctx, path, s, &mats);
    if (r != HL_OK) {
        aiReleaseImport(s);
        return r;
    }
    const int colors = hl_materials_any_given_(&mats, s), textured = hl_materials_textured_(&mats, s);
    const int any_colors = hl_materials_any_colors_(s);
    for (unsigned m = 0; m < s->mNumMeshes; m++) {
        const struct aiMesh *am = s->mMeshes[m];
        nv += am->mNumVertices;
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            if (am->mFaces[f].mNumIndices == 3) nt++;
            else skipped++;
        }
        if (!am->mNormals) all_normals = 0;
    }
    float *pos = NULL, *nrm = NULL, *col = NULL, *tex = NULL;
    uint32_t *idx = NULL, *origin = NULL;
    hl_surface in; /* with surf: by input triangle */
    memset(&in, 0, sizeof in);
    if (s->mNumMeshes == 0) {
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: the file holds no mesh", path);
        goto done;
    }
    if (nv > UINT32_MAX || nt > UINT32_MAX) {
        r = hl_fail(ctx, HL_ERR_MESH, "%s: %llu vertices and %llu triangles exceed the 2^32 limit", path,
                    (unsigned long long)nv, (unsigned long long)nt);
        goto done;
    }
    skipped_note(ctx, path, skipped);
    pos = hl_malloc(ctx, (size_t)nv * 3 * sizeof(float), "vertex positions");
    nrm = all_normals ? hl_malloc(ctx, (size_t)nv * 3 * sizeof(float), "vertex normals") : NULL;
    col = colors ? hl_malloc(ctx, (size_t)nv * 3 * sizeof(float), "vertex albedo") : NULL;
    tex = textured ? hl_malloc(ctx, (size_t)nt * 9 * sizeof(float), "texture averages") : NULL;
    idx = hl_malloc(ctx, (size_t)nt * 3 * sizeof(uint32_t), "triangle indices");
    float fallback[3];
    r = hl_mesh_resolve_albedo_(ctx, path, desc ? desc->albedo : (const float[3]){0, 0, 0}, HL_DEFAULT_ALBEDO,
                                fallback);
    if (r != HL_OK) goto done;
    if (surf) origin = hl_malloc(ctx, (size_t)nt * sizeof(uint32_t), "triangle origins");
    if (!pos || !idx || (all_normals && !nrm) || (colors && !col) || (textured && !tex) ||
        (surf && (!origin || hl_surface_arrays_(ctx, &in, (uint32_t)nt) != HL_OK))) {
        r = HL_ERR_OUT_OF_MEMORY;
        goto done;
    }
    copy_scene(s, &mats, fallback, pos, nrm, col, tex, idx, surf ? &in : NULL);
    aiReleaseImport(s);
    s = NULL;
    hl_materials_note_(ctx, path, &mats);
    hl_mesh_stats st;
    r = hl_mesh_build_(ctx, path, (uint32_t)nv, pos, nrm, col, &(hl_mesh_extra){tex, origin}, (uint32_t)nt, idx, desc,
                       out, &st);
    if (r == HL_OK) {
        st.had_colors = any_colors;
        if (stats) *stats = st;
    }
    if (r == HL_OK && surf) {
        r = hl_surface_finish_(ctx, &in, origin, (*out)->triangle_count, st.flipped, surf);
        if (r == HL_OK) { /* the surface owns the textures */
            (*surf)->mats = mats;
            memset(&mats, 0, sizeof mats);
        }
        if (r != HL_OK) {
            hl_mesh_destroy(*out);
            *out = NULL;
        }
    }
done:
    if (s) aiReleaseImport(s);
    hl_materials_free_(&mats);
    hl_surface_arrays_free_(&in);
    free(origin);
    free(pos);
    free(nrm);
    free(col);
    free(tex);
    free(idx);
    return r;
}

/* ---------------------------------------------------------------- gzip */

/* The longest inner extension taken as a format hint: assimp's own are at
 * most 8 characters (".assbin"); anything longer is no format it reads. */
#define GZ_MAX_EXT 15

/* path = NAME.EXT.gz: decompressed into memory (at most HL_GZ_MAX_BYTES),
 * put through the file guards under the name NAME.EXT (they go by the
 * extension), and imported with EXT as the hint. */
static hl_result load_gz(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, hl_mesh **out,
                         hl_mesh_stats *stats, hl_mesh_motion *motion, hl_surface **surf)
{
    size_t n = strlen(path) - 3; /* without ".gz" */
    char inner[4096], ext[GZ_MAX_EXT + 2];
    if (n >= sizeof inner) return hl_fail(ctx, HL_ERR_IO, "%s: file name too long", path);
    memcpy(inner, path, n);
    inner[n] = 0;
    const char *base = strrchr(inner, '/'), *dot = strrchr(base ? base : inner, '.');
    if (!dot || !dot[1] || dot == (base ? base + 1 : inner))
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: a gzipped mesh needs its format's extension before .gz (as in mesh.obj.gz)", path);
    if (strlen(dot) > GZ_MAX_EXT + 1 || !aiIsExtensionSupported(dot))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: the importer reads no %.20s files, so cannot read this one", path, dot);
    snprintf(ext, sizeof ext, "%s", dot);
    uint8_t *data = NULL;
    size_t size = 0;
    hl_result r = hl_gz_read_file(ctx, path, HL_GZ_MAX_BYTES, &data, &size);
    if (r != HL_OK) return r;
    if (size == 0) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: empty file inside the gzip stream", path);
    char msg[160];
    if (r == HL_OK) {
        FILE *f = fmemopen(data, size, "rb");
        if (!f) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: cannot read the decompressed data: %s", path, strerror(errno));
        else {
            if (hl_assimp_file_problem_(inner, f, size, msg, sizeof msg)) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: %s", path, msg);
            fclose(f);
        }
    }
    if (r == HL_OK) {
        mesh_src src = {.path = path, .data = data, .size = size, .hint = ext + 1};
        r = load_assimp(ctx, &src, desc, out, stats, motion, surf);
    }
    free(data);
    return r;
}

/* ---------------------------------------------------------------- public */

hl_result hl_mesh_load(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc,
                       hl_mesh **out, hl_mesh_stats *stats)
{
    return hl_mesh_load_motion_(ctx, path, desc, out, stats, NULL);
}

hl_result hl_mesh_probe_motion_(hl_context *ctx, const char *path, hl_mesh_motion *motion)
{
    memset(motion, 0, sizeof *motion);
    if (!path) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_mesh_probe_motion_: no path");
    if (hl_gz_is_gz_name(path)) { /* decompressed once only by a load */
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load_motion_(ctx, path, NULL, &m, NULL, motion);
        hl_mesh_destroy(m);
        return r;
    }
    hl_result r = guard_file(ctx, path);
    if (r != HL_OK) return r;
    mesh_src src = {.path = path};
    const struct aiScene *s = import_scene(&src, aiProcess_ValidateDataStructure);
    if (!s) {
        char m2[512];
        snprintf(m2, sizeof m2, "%s", aiGetErrorString());
        return assimp_failure(ctx, path, m2);
    }
    r = hl_raw_scene_problem_(ctx, path, s);
    if (r == HL_OK) read_motion(s, motion);
    aiReleaseImport(s);
    return r;
}

hl_result hl_mesh_load_motion_(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, hl_mesh **out,
                               hl_mesh_stats *stats, hl_mesh_motion *motion)
{
    return hl_mesh_load_surface_(ctx, path, desc, out, stats, motion, NULL);
}

hl_result hl_mesh_load_surface_(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, hl_mesh **out,
                                hl_mesh_stats *stats, hl_mesh_motion *motion, hl_surface **surf)
{
    if (surf) *surf = NULL;
    if (out) *out = NULL;
    if (stats) memset(stats, 0, sizeof *stats);
    if (motion) memset(motion, 0, sizeof *motion);
    if (!path || !out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_mesh_load: path and out are required");
    hl_result r;
    if (hl_gz_is_gz_name(path)) {
        r = load_gz(ctx, path, desc, out, stats, motion, surf);
        if (r != HL_OK && motion) memset(motion, 0, sizeof *motion);
        return r;
    }
    r = guard_file(ctx, path);
    if (r != HL_OK) return r;
    mesh_src src = {.path = path};
    r = load_assimp(ctx, &src, desc, out, stats, motion, surf);
    if (r != HL_OK && motion) memset(motion, 0, sizeof *motion);
    return r;
}
