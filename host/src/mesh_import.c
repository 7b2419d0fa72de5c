/* mesh_import.c - hl_mesh_load: reading mesh files through assimp.
 *
 * The only file that includes assimp. Every format (OBJ, PLY, glTF, ...)
 * goes through aiImportFile; the raw arrays then go to hl_mesh_build_ in
 * mesh.c, which welds, drops degenerates and computes normals. assimp's
 * OBJ importer gives each face corner its own vertex and drops vertices no
 * face uses, so for OBJ the "merged" count includes that expansion and
 * unreferenced vertices of the file are not seen. Hostile files that
 * would hang, abort, corrupt or exhaust assimp 5.2 itself (a PLY header
 * without end_header or with an element declared twice, a binary glTF
 * whose lengths exceed the file, faces without indices) are refused
 * before it gets to them.
 *
 * Dependencies: assimp C API (Debian libassimp-dev 5.2), POSIX (stat,
 * uselocale), hl_internal.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "hl_internal.h"

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

/* Reads one line, ended by \n or \r, into buf (the rest of a longer line
 * is dropped). Returns 0 at the end of the file. */
static int read_line(FILE *f, char *buf, size_t size)
{
    size_t n = 0;
    int c;
    while ((c = getc(f)) != EOF && c != '\n' && c != '\r')
        if (n + 1 < size) buf[n++] = (char)c;
    buf[n] = '\0';
    return c != EOF || n > 0;
}

/* A PLY header that assimp 5.2 mishandles badly enough to hang or corrupt
 * memory, checked before it reads the file: its reader never returns from
 * a header without an end_header line (it keeps asking for the next line
 * at the end of the file), and it sizes its arrays from the first element
 * of a name and overruns them when the name is declared again. A file that
 * starts with the PLY magic ("ply", any case, as assimp checks it) is
 * read up to its end_header line, which real files have within their
 * first kilobytes. Returns 0, or 1 with the problem in msg. */
static int ply_header_problem(FILE *f, char *msg, size_t msg_size)
{
    char line[256];
    if (!read_line(f, line, sizeof line) || (line[0] | 0x20) != 'p' || (line[1] | 0x20) != 'l' ||
        (line[2] | 0x20) != 'y')
        return 0;
    enum { MAX_NAMES = 32 };
    char names[MAX_NAMES][64];
    int count = 0;
    while (read_line(f, line, sizeof line)) {
        char word[16], name[64];
        int fields = sscanf(line, " %15s %63s", word, name);
        if (fields >= 1 && strcmp(word, "end_header") == 0) return 0;
        if (fields < 2 || strcmp(word, "element") != 0) continue;
        for (int i = 0; i < count; i++)
            if (strcmp(names[i], name) == 0)
                return snprintf(msg, msg_size, "PLY header declares element \"%s\" twice", name), 1;
        if (count < MAX_NAMES) memcpy(names[count++], name, sizeof name);
    }
    return snprintf(msg, msg_size, "PLY header has no end_header line (truncated or corrupt)"), 1;
}

/* Binary glTF (magic "glTF", versions 1 and 2): assimp 5.2 allocates and
 * zero-fills the first chunk at the length its header gives before
 * reading it, so a file of a few hundred bytes could claim gigabytes. The
 * total length in the header and the first chunk (from byte 20) must fit
 * in the file. Returns 0, or 1 with the problem in msg. */
static int glb_header_problem(FILE *f, uint64_t file_size, char *msg, size_t msg_size)
{
    unsigned char h[16];
    if (fread(h, 1, sizeof h, f) != sizeof h || memcmp(h, "glTF", 4) != 0) return 0;
    uint32_t word[2];
    for (int i = 0; i < 2; i++)
        word[i] = (uint32_t)h[8 + 4 * i] | (uint32_t)h[9 + 4 * i] << 8 | (uint32_t)h[10 + 4 * i] << 16 |
                  (uint32_t)h[11 + 4 * i] << 24;
    if (word[0] > file_size || (uint64_t)word[1] + 20 > file_size)
        return snprintf(msg, msg_size,
                        "binary glTF header gives a length of %u bytes and a first chunk of %u bytes, "
                        "but the file has %llu bytes", word[0], word[1], (unsigned long long)file_size),
               1;
    return 0;
}

static void skipped_note(hl_context *ctx, const char *path, uint64_t skipped)
{
    if (skipped && ctx && !ctx->quiet)
        fprintf(stderr, "haarlight: %s: skipped %llu point/line primitives\n", path,
                (unsigned long long)skipped);
}

/* After a failed import: assimp's validation reports a mesh without faces
 * or vertices, and a scene without meshes, like any other error, so they
 * are told apart by its message. (A second import without validation
 * would count them, but assimp's scene preprocessing then walks the
 * unvalidated data and crashes on some corrupt files.) */
static hl_result assimp_failure(hl_context *ctx, const char *path, const char *msg)
{
    if (strstr(msg, "contains no faces"))
        return hl_fail(ctx, HL_ERR_MESH, "%s: the mesh has no faces (importer: %s)", path, msg);
    if (strstr(msg, "contains no vertices"))
        return hl_fail(ctx, HL_ERR_MESH, "%s: the mesh has no vertices (importer: %s)", path, msg);
    if (strstr(msg, "mNumMeshes is 0"))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: the file holds no mesh (importer: %s)", path, msg);
    return hl_fail(ctx, HL_ERR_FORMAT, "%s: importer: %s", path, msg);
}

/* Faces that assimp's triangulation cannot take: it aborts the process
 * (ai_assert) on a face without indices, which some importers produce
 * from a corrupt file, and reads the positions of a polygon's indices
 * unchecked. Checked on the raw import, before that step runs. */
static hl_result raw_faces_problem(hl_context *ctx, const char *path, const struct aiScene *s)
{
    for (unsigned m = 0; m < s->mNumMeshes; m++) {
        const struct aiMesh *am = s->mMeshes[m];
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            const struct aiFace *af = &am->mFaces[f];
            if (af->mNumIndices == 0 || !af->mIndices)
                return hl_fail(ctx, HL_ERR_FORMAT, "%s: mesh %u face %u (counting from 0) has no vertex indices",
                               path, m, f);
            if (af->mNumIndices <= 3) continue; /* the builder checks triangles' indices */
            for (unsigned k = 0; k < af->mNumIndices; k++)
                if (af->mIndices[k] >= am->mNumVertices)
                    return hl_fail(ctx, HL_ERR_MESH,
                                   "%s: mesh %u face %u (counting from 0) refers to vertex %u, out of range "
                                   "(%u vertices)", path, m, f, af->mIndices[k], am->mNumVertices);
        }
    }
    return HL_OK;
}

static hl_result load_assimp(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc,
                             hl_mesh **out, hl_mesh_stats *stats)
{
    /* Vertex joining and normal generation stay off: the builder does both
     * and counts what it changed. The faces are checked between the raw
     * import and the steps that triangulate and flatten the scene. */
    const struct aiScene *s = aiImportFile(path, aiProcess_ValidateDataStructure);
    if (!s) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", aiGetErrorString());
        return assimp_failure(ctx, path, msg);
    }
    hl_result r = raw_faces_problem(ctx, path, s);
    if (r != HL_OK) {
        aiReleaseImport(s);
        return r;
    }
    s = aiApplyPostProcessing(s, aiProcess_Triangulate | aiProcess_PreTransformVertices);
    if (!s) /* the scene is released on failure */
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: importer: %s", path, aiGetErrorString());
    uint64_t nv = 0, nt = 0, skipped = 0;
    int all_normals = s->mNumMeshes > 0, all_colors = s->mNumMeshes > 0;
    for (unsigned m = 0; m < s->mNumMeshes; m++) {
        const struct aiMesh *am = s->mMeshes[m];
        nv += am->mNumVertices;
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            if (am->mFaces[f].mNumIndices == 3) nt++;
            else skipped++;
        }
        if (!am->mNormals) all_normals = 0;
        if (!am->mColors[0]) all_colors = 0;
    }
    float *pos = NULL, *nrm = NULL, *col = NULL;
    uint32_t *idx = NULL;
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
    col = all_colors ? hl_malloc(ctx, (size_t)nv * 3 * sizeof(float), "vertex colours") : NULL;
    idx = hl_malloc(ctx, (size_t)nt * 3 * sizeof(uint32_t), "triangle indices");
    if (!pos || !idx || (all_normals && !nrm) || (all_colors && !col)) {
        r = HL_ERR_OUT_OF_MEMORY;
        goto done;
    }
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
            if (col) {
                /* Colours are taken as linear reflectance and clamped. */
                float *c = col + 3 * (base + v);
                const float rgb[3] = {(float)am->mColors[0][v].r, (float)am->mColors[0][v].g,
                                      (float)am->mColors[0][v].b};
                for (int k = 0; k < 3; k++) c[k] = rgb[k] < 0.0f ? 0.0f : (rgb[k] > 1.0f ? 1.0f : rgb[k]);
            }
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
            t++;
        }
        base += am->mNumVertices;
    }
    aiReleaseImport(s);
    s = NULL;
    r = hl_mesh_build_(ctx, path, (uint32_t)nv, pos, nrm, col, (uint32_t)nt, idx, desc, out, stats);
done:
    if (s) aiReleaseImport(s);
    free(pos);
    free(nrm);
    free(col);
    free(idx);
    return r;
}

/* ---------------------------------------------------------------- public */

hl_result hl_mesh_load(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc,
                       hl_mesh **out, hl_mesh_stats *stats)
{
    if (out) *out = NULL;
    if (stats) memset(stats, 0, sizeof *stats);
    if (!path || !out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_mesh_load: path and out are required");
    FILE *f = NULL;
    size_t size = 0;
    hl_result r = open_checked(ctx, path, &f, &size);
    if (r != HL_OK) return r;
    char msg[160];
    int bad = ply_header_problem(f, msg, sizeof msg);
    if (!bad) {
        rewind(f);
        bad = glb_header_problem(f, size, msg, sizeof msg);
    }
    fclose(f);
    if (bad) return hl_fail(ctx, HL_ERR_FORMAT, "%s: %s", path, msg);
    return load_assimp(ctx, path, desc, out, stats);
}
