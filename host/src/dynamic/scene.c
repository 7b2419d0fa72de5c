/* scene.c - making a dynamic scene: a file read through assimp (one rigid
 * body per node that holds triangles, the node hierarchy and the chosen
 * animation's channels, checked rigid) and the built-in scene (a mesh and
 * its ground as two bodies). scene.h states the rules; scene_anim.c moves
 * the scene.
 *
 * Depends on: assimp C API (Debian libassimp-dev 5.2) with the guards of
 * io/assimp_guard.h in the same order as io/mesh_import.c, the shared
 * mesh builder (hl_mesh_build_) and hl_mesh_add_ground, scene.h,
 * hl_internal.h, POSIX (stat). With keep_triangles (for the captured
 * lighting's surroundings) bodies skip the mesh builder and the materials'
 * emission is read.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "assimp_guard.h"
#include "material.h"
#include "mesh_ops.h"
#include "scene.h"

/* The name of the built-in scene in messages. */
#define HL_DYN_BUILTIN_NAME "built-in scene"

/* ---------------------------------------------------------------- files and assimp */

static hl_result open_checked(hl_context *ctx, const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    hl_result r = HL_OK;
    char msg[160];
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) r = hl_fail(ctx, HL_ERR_IO, "%s: not a regular file", path);
    else if (st.st_size == 0) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: empty file", path);
    else if (hl_assimp_file_problem_(path, f, (uint64_t)st.st_size, msg, sizeof msg))
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: %s", path, msg);
    fclose(f);
    return r;
}

/* A failed import, told apart by assimp's message as mesh_import.c does. */
static hl_result import_failure(hl_context *ctx, const char *path)
{
    char msg[512];
    snprintf(msg, sizeof msg, "%s", aiGetErrorString());
    if (strstr(msg, "mNumMeshes is 0"))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: the file holds no mesh (importer: %s)", path, msg);
    if (strstr(msg, "contains no faces") || strstr(msg, "contains no vertices"))
        return hl_fail(ctx, HL_ERR_MESH, "%s: a mesh has no faces or vertices (importer: %s)", path, msg);
    if (strstr(msg, "bad_alloc"))
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory while importing the file (importer: %s)", path,
                       msg);
    return hl_fail(ctx, HL_ERR_FORMAT, "%s: importer: %s", path, msg);
}

/* The guarded import (mesh_import.c's load_assimp gives why this order):
 * validate only, the scene guard, then again with triangulation. No
 * pre-transforming: the node transforms are what moves. */
static hl_result import_scene(hl_context *ctx, const char *path, const struct aiScene **out)
{
    *out = NULL;
    hl_result r = open_checked(ctx, path);
    if (r != HL_OK) return r;
    const struct aiScene *s = aiImportFile(path, aiProcess_ValidateDataStructure);
    if (!s) return import_failure(ctx, path);
    r = hl_raw_scene_problem_(ctx, path, s);
    aiReleaseImport(s);
    if (r != HL_OK) return r;
    s = aiImportFile(path, aiProcess_ValidateDataStructure | aiProcess_Triangulate);
    if (!s) return import_failure(ctx, path);
    *out = s;
    return HL_OK;
}

/* ---------------------------------------------------------------- the scene's lifetime */

static hl_dyn_scene *scene_new(hl_context *ctx, const char *name, uint32_t nnodes)
{
    hl_dyn_scene *s = hl_calloc(ctx, 1, sizeof *s, "the scene");
    if (!s) return NULL;
    s->ctx = ctx;
    s->name = hl_malloc(ctx, strlen(name) + 1, "the scene's name");
    s->nodes = hl_calloc(ctx, nnodes ? nnodes : 1, sizeof *s->nodes, "the scene's nodes");
    s->bodies = hl_calloc(ctx, nnodes ? nnodes : 1, sizeof *s->bodies, "the scene's bodies");
    s->world = hl_malloc(ctx, (nnodes ? nnodes : 1) * 12 * sizeof(double), "the scene's transforms");
    if (!s->name || !s->nodes || !s->bodies || !s->world) {
        hl_dyn_scene_destroy(s);
        return NULL;
    }
    memcpy(s->name, name, strlen(name) + 1);
    s->nnodes = nnodes;
    for (int i = 0; i < 9; i++) s->up[i] = i % 4 == 0 ? 1.0 : 0.0;
    for (int i = 0; i < 12; i++) s->place[i] = i % 5 == 0 ? 1.0 : 0.0;
    return s;
}

void hl_dyn_scene_destroy(hl_dyn_scene *s)
{
    if (!s) return;
    for (uint32_t n = 0; s->nodes && n < s->nnodes; n++) {
        dyn_node *nd = &s->nodes[n];
        free(nd->name);
        free(nd->ch.pos_t);
        free(nd->ch.pos);
        free(nd->ch.rot_t);
        free(nd->ch.rot);
    }
    hl_materials_free_(&s->mats);
    for (uint32_t b = 0; s->bodies && b < s->nbodies; b++) {
        hl_surface_destroy(s->bodies[b].surf);
        free(s->bodies[b].pos);
        free(s->bodies[b].normal);
        free(s->bodies[b].albedo);
        free(s->bodies[b].tri);
        free(s->bodies[b].tri_mesh);
    }
    free(s->mesh_emission);
    free(s->nodes);
    free(s->bodies);
    free(s->world);
    free(s->anim_name);
    free(s->name);
    free(s);
}

static char *dup_str(hl_context *ctx, const char *str)
{
    size_t n = strlen(str) + 1;
    char *d = hl_malloc(ctx, n, "a name");
    if (d) memcpy(d, str, n);
    return d;
}

static void set_identity(double x[12])
{
    memset(x, 0, 12 * sizeof(double));
    x[0] = x[5] = x[10] = 1.0;
}

/* A body takes over a built mesh's arrays. */
static void body_take(dyn_body *b, hl_mesh *m, uint32_t node, const double kinv[9])
{
    b->pos = m->positions;
    b->normal = m->normals;
    b->albedo = m->albedo;
    b->tri = m->indices;
    b->nverts = m->vertex_count;
    b->ntris = m->triangle_count;
    m->positions = m->normals = m->albedo = NULL;
    m->indices = NULL;
    hl_mesh_destroy(m);
    b->node = node;
    memcpy(b->kinv, kinv, 9 * sizeof(double));
    set_identity(b->P);
}

/* ---------------------------------------------------------------- nodes */

/* The node tree in depth-first order, parents before children, with a
 * stack of its own (the guard has walked the same tree). */
static hl_result flatten_nodes(hl_dyn_scene *s, const struct aiScene *as, const struct aiNode **src)
{
    hl_context *ctx = s->ctx;
    const struct aiNode **stack = hl_malloc(ctx, s->nnodes * sizeof *stack, "the node walk");
    int32_t *pstack = hl_malloc(ctx, s->nnodes * sizeof *pstack, "the node walk");
    hl_result r = HL_OK;
    if (!stack || !pstack) r = HL_ERR_OUT_OF_MEMORY;
    size_t top = 0;
    uint32_t k = 0;
    if (r == HL_OK) {
        stack[top] = as->mRootNode;
        pstack[top++] = -1;
    }
    while (r == HL_OK && top > 0) {
        const struct aiNode *an = stack[--top];
        dyn_node *n = &s->nodes[k];
        src[k] = an;
        n->parent = pstack[top];
        n->body = -1;
        n->name = dup_str(ctx, an->mName.data);
        if (!n->name) { r = HL_ERR_OUT_OF_MEMORY; break; }
        const struct aiMatrix4x4 *m = &an->mTransformation;
        const double rows[16] = {m->a1, m->a2, m->a3, m->a4, m->b1, m->b2, m->b3, m->b4,
                                 m->c1, m->c2, m->c3, m->c4, m->d1, m->d2, m->d3, m->d4};
        for (int i = 0; i < 16; i++)
            if (!isfinite(rows[i])) {
                r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\" has a non-finite transform", s->name, n->name);
                break;
            }
        if (r == HL_OK && (rows[12] != 0.0 || rows[13] != 0.0 || rows[14] != 0.0 || rows[15] != 1.0))
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\" has a projective transform (last row %g %g %g %g)",
                        s->name, n->name, rows[12], rows[13], rows[14], rows[15]);
        memcpy(n->rest, rows, 12 * sizeof(double));
        double lin[9] = {rows[0], rows[1], rows[2], rows[4], rows[5], rows[6], rows[8], rows[9], rows[10]};
        if (r == HL_OK && !hl_dyn_decompose_(lin, n->rest_q, n->scale))
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\" has a singular transform (a zero scale)", s->name,
                        n->name);
        for (int i = 0; i < 3; i++) n->rest_t[i] = rows[4 * i + 3];
        for (unsigned i = 0; i < an->mNumMeshes && !n->triangles; i++) {
            const struct aiMesh *am = as->mMeshes[an->mMeshes[i]]; /* in range: the guard checked */
            for (unsigned f = 0; f < am->mNumFaces && !n->triangles; f++) n->triangles = am->mFaces[f].mNumIndices == 3;
        }
        for (unsigned c = an->mNumChildren; r == HL_OK && c-- > 0;) {
            stack[top] = an->mChildren[c];
            pstack[top++] = (int32_t)k;
        }
        k++;
    }
    free(stack);
    free(pstack);
    return r;
}

static uint32_t count_nodes(const struct aiNode *root, hl_context *ctx, int *oom)
{
    /* the guard already walked this tree; a second walk counts it */
    size_t cap = 64, top = 0;
    uint32_t n = 0;
    const struct aiNode **st = hl_malloc(ctx, cap * sizeof *st, "the node walk");
    if (!st) { *oom = 1; return 0; }
    st[top++] = root;
    while (top > 0) {
        const struct aiNode *nd = st[--top];
        n++;
        if (top + nd->mNumChildren > cap) {
            while (top + nd->mNumChildren > cap) cap *= 2;
            const struct aiNode **g = realloc(st, cap * sizeof *st);
            if (!g) { free(st); *oom = 1; return 0; }
            st = g;
        }
        for (unsigned c = 0; c < nd->mNumChildren; c++) st[top++] = nd->mChildren[c];
    }
    free(st);
    return n;
}

/* ---------------------------------------------------------------- bodies of a file */

/* Node k's meshes merged: positions baked with K (normals with K^-T,
 * winding reversed where K mirrors), then the shared builder. */
typedef struct merged {
    float *pos, *nrm, *col, *tex;
    uint32_t *idx;
    uint64_t nv, nt, skipped;
    int normals, colors, textured;
    const hl_materials *mats; /* the albedo's sources (material.h) */
    float fallback[3];
    hl_surface in;            /* with textured: the surface by input triangle */
    uint32_t *origin;         /* with textured: the builder's triangle origins */
} merged;

static void merge_meshes(const struct aiScene *as, const struct aiNode *an, const double K[9], merged *m)
{
    double kinv[9];
    hl_dyn_inv3_(K, kinv); /* K is invertible: hl_dyn_polar_ succeeded */
    int mirror = K[0] * (K[4] * K[8] - K[5] * K[7]) - K[1] * (K[3] * K[8] - K[5] * K[6]) +
                     K[2] * (K[3] * K[7] - K[4] * K[6]) < 0.0;
    size_t base = 0, t = 0;
    for (unsigned i = 0; i < an->mNumMeshes; i++) {
        const struct aiMesh *am = as->mMeshes[an->mMeshes[i]];
        for (size_t v = 0; v < am->mNumVertices; v++) {
            const double p[3] = {am->mVertices[v].x, am->mVertices[v].y, am->mVertices[v].z};
            for (int r = 0; r < 3; r++)
                m->pos[3 * (base + v) + r] = (float)(K[3 * r] * p[0] + K[3 * r + 1] * p[1] + K[3 * r + 2] * p[2]);
            if (m->normals) {
                const double n[3] = {am->mNormals[v].x, am->mNormals[v].y, am->mNormals[v].z};
                for (int r = 0; r < 3; r++) /* (K^-1)^T n */
                    m->nrm[3 * (base + v) + r] = (float)(kinv[r] * n[0] + kinv[3 + r] * n[1] + kinv[6 + r] * n[2]);
            }
            if (m->colors) hl_material_vertex_base_(m->mats, am, v, m->fallback, m->col + 3 * (base + v));
        }
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            const struct aiFace *af = &am->mFaces[f];
            if (af->mNumIndices != 3) continue;
            for (int c = 0; c < 3; c++) {
                /* an index past this mesh stays out of range for the builder to report */
                uint64_t ix = af->mIndices[c] < am->mNumVertices ? base + af->mIndices[c] : UINT32_MAX;
                m->idx[3 * t + (size_t)(mirror && c ? 3 - c : c)] = (uint32_t)(ix > UINT32_MAX ? UINT32_MAX : ix);
            }
            if (m->textured) {
                float tx[9];
                hl_surface_face_(m->mats, am, af, m->fallback, &m->in, t, mirror);
                hl_material_face_tex_(m->mats, am, af, tx);
                for (int c = 0; c < 3; c++) /* the corners as idx has them */
                    memcpy(m->tex + 9 * t + 3 * (size_t)(mirror && c ? 3 - c : c), tx + 3 * c, 3 * sizeof(float));
            }
            t++;
        }
        base += am->mNumVertices;
    }
}

static hl_result count_meshes(hl_dyn_scene *s, const struct aiScene *as, const struct aiNode *an, merged *m)
{
    m->normals = an->mNumMeshes > 0;
    m->colors = m->textured = 0;
    for (unsigned i = 0; i < an->mNumMeshes; i++) {
        const struct aiMesh *am = as->mMeshes[an->mMeshes[i]];
        if (s->anim_name && am->mNumBones)
            return hl_fail(s->ctx, HL_ERR_MESH,
                           "%s: node \"%s\": the animation is not rigid: its mesh \"%s\" is skinned (%u bones), "
                           "which is not followed" HL_DYN_REST_POSE_HINT,
                           s->name, an->mName.data, am->mName.data, am->mNumBones);
        m->nv += am->mNumVertices;
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            if (am->mFaces[f].mNumIndices == 3) m->nt++;
            else m->skipped++;
        }
        if (!am->mNormals) m->normals = 0;
        const hl_material *h = am->mMaterialIndex < m->mats->count ? &m->mats->mat[am->mMaterialIndex] : NULL;
        if (am->mColors[0] || (h && h->given)) m->colors = 1;
        if (h && h->tex >= 0 && am->mTextureCoords[h->uv]) m->textured = 1;
    }
    if (m->nv > UINT32_MAX || m->nt > UINT32_MAX)
        return hl_fail(s->ctx, HL_ERR_MESH, "%s: node \"%s\": %llu vertices and %llu triangles exceed the 2^32 limit",
                       s->name, an->mName.data, (unsigned long long)m->nv, (unsigned long long)m->nt);
    return HL_OK;
}

/* keep_triangles: the merged triangles as they are, three vertices each,
 * with the file mesh each came from (the faces walked in merge_meshes's
 * order). */
static hl_result keep_body(hl_dyn_scene *s, const struct aiScene *as, const struct aiNode *an, const merged *m,
                           dyn_body *b)
{
    hl_context *ctx = s->ctx;
    if (m->nt > UINT32_MAX / 3)
        return hl_fail(ctx, HL_ERR_MESH, "%s: node \"%s\": %llu triangles exceed the 2^32 vertex limit", s->name,
                       an->mName.data, (unsigned long long)m->nt);
    b->pos = hl_malloc(ctx, (size_t)m->nt * 9 * sizeof(float), "triangle corners");
    b->tri = hl_malloc(ctx, (size_t)m->nt * 3 * sizeof(uint32_t), "triangle indices");
    b->tri_mesh = hl_malloc(ctx, (size_t)m->nt * sizeof(uint32_t), "triangle meshes");
    if (!b->pos || !b->tri || !b->tri_mesh) return HL_ERR_OUT_OF_MEMORY;
    size_t t = 0;
    for (unsigned i = 0; i < an->mNumMeshes; i++) {
        const struct aiMesh *am = as->mMeshes[an->mMeshes[i]];
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            if (am->mFaces[f].mNumIndices != 3) continue;
            for (int c = 0; c < 3; c++) {
                uint32_t ix = m->idx[3 * t + (size_t)c];
                if (ix >= m->nv)
                    return hl_fail(ctx, HL_ERR_MESH, "%s: node \"%s\": mesh \"%s\" has a face index out of range",
                                   s->name, an->mName.data, am->mName.data);
                memcpy(b->pos + 9 * t + 3 * (size_t)c, m->pos + 3 * (size_t)ix, 3 * sizeof(float));
                b->tri[3 * t + (size_t)c] = (uint32_t)(3 * t + (size_t)c);
            }
            b->tri_mesh[t++] = an->mMeshes[i];
        }
    }
    b->nverts = (uint32_t)(3 * m->nt);
    b->ntris = (uint32_t)m->nt;
    return HL_OK;
}

/* Node k becomes the next body if its meshes hold triangles. */
static hl_result make_body(hl_dyn_scene *s, const struct aiScene *as, const struct aiNode *an, uint32_t k,
                           const hl_mesh_load_desc *desc, int keep, const hl_materials *mats, const float fallback[3])
{
    hl_context *ctx = s->ctx;
    merged m;
    memset(&m, 0, sizeof m);
    m.mats = mats;
    memcpy(m.fallback, fallback, sizeof m.fallback);
    hl_result r = count_meshes(s, as, an, &m);
    if (r != HL_OK || an->mNumMeshes == 0) return r;
    if (m.nt == 0) {
        if (!ctx || !ctx->quiet)
            fprintf(stderr, "haarlight: %s: node \"%s\" holds no triangles; it is not a body\n", s->name,
                    an->mName.data);
        return HL_OK;
    }
    if (m.skipped && (!ctx || !ctx->quiet))
        fprintf(stderr, "haarlight: %s: node \"%s\": skipped %llu point/line primitives\n", s->name, an->mName.data,
                (unsigned long long)m.skipped);
    /* the stretch of the node's world transform at the start: constant
       over time, as check_rigid made sure */
    const double *w = s->world + 12 * (size_t)k;
    double L[9] = {w[0], w[1], w[2], w[4], w[5], w[6], w[8], w[9], w[10]}, Q[9], K[9], kinv[9];
    if (!hl_dyn_polar_(L, Q, K) || !hl_dyn_inv3_(K, kinv))
        return hl_fail(ctx, HL_ERR_MESH, "%s: node \"%s\": its world transform is singular (a zero scale)", s->name,
                       an->mName.data);
    if (keep) m.normals = m.colors = m.textured = 0;
    m.pos = hl_malloc(ctx, (size_t)m.nv * 3 * sizeof(float), "vertex positions");
    m.nrm = m.normals ? hl_malloc(ctx, (size_t)m.nv * 3 * sizeof(float), "vertex normals") : NULL;
    m.col = m.colors ? hl_malloc(ctx, (size_t)m.nv * 3 * sizeof(float), "vertex colours") : NULL;
    m.tex = m.textured ? hl_malloc(ctx, (size_t)m.nt * 9 * sizeof(float), "texture averages") : NULL;
    int surf_oom = 0;
    if (m.textured) {
        m.origin = hl_malloc(ctx, (size_t)m.nt * sizeof(uint32_t), "triangle origins");
        surf_oom = !m.origin || hl_surface_arrays_(ctx, &m.in, (uint32_t)m.nt) != HL_OK;
    }
    m.idx = hl_malloc(ctx, (size_t)m.nt * 3 * sizeof(uint32_t), "triangle indices");
    size_t nlen = strlen(s->name) + strlen(an->mName.data) + 16;
    char *name = hl_malloc(ctx, nlen, "a name");
    hl_mesh *mesh = NULL;
    hl_surface *surf = NULL;
    if (!m.pos || !m.idx || (m.normals && !m.nrm) || (m.colors && !m.col) || (m.textured && !m.tex) || surf_oom ||
        !name)
        r = HL_ERR_OUT_OF_MEMORY;
    if (r == HL_OK) {
        snprintf(name, nlen, "%s (node \"%s\")", s->name, an->mName.data);
        merge_meshes(as, an, K, &m);
        if (keep) {
            dyn_body *b = &s->bodies[s->nbodies];
            r = keep_body(s, as, an, &m, b);
            b->node = k;
            memcpy(b->kinv, kinv, sizeof kinv);
            set_identity(b->P);
            s->nbodies++; /* even on failure, so that destroy frees its arrays */
            if (r == HL_OK) s->nodes[k].body = (int32_t)(s->nbodies - 1);
        } else {
            hl_mesh_stats st;
            r = hl_mesh_build_(ctx, name, (uint32_t)m.nv, m.pos, m.nrm, m.col, &(hl_mesh_extra){m.tex, m.origin},
                               (uint32_t)m.nt, m.idx, desc, &mesh, &st);
            if (r == HL_OK && m.textured)
                r = hl_surface_finish_(ctx, &m.in, m.origin, mesh->triangle_count, st.flipped, &surf);
            if (r != HL_OK) {
                hl_mesh_destroy(mesh);
                mesh = NULL;
            }
        }
    }
    if (r == HL_OK && !keep) {
        s->nodes[k].body = (int32_t)s->nbodies;
        s->bodies[s->nbodies].surf = surf;
        surf = NULL;
        body_take(&s->bodies[s->nbodies++], mesh, k, kinv);
    }
    hl_surface_destroy(surf);
    hl_surface_arrays_free_(&m.in);
    free(m.origin);
    free(m.pos);
    free(m.nrm);
    free(m.col);
    free(m.tex);
    free(m.idx);
    free(name);
    return r;
}

/* keep_triangles: each file mesh's emission, from its material. */
static hl_result read_emission(hl_dyn_scene *s, const struct aiScene *as)
{
    s->nmeshes = as->mNumMeshes;
    s->mesh_emission = hl_calloc(s->ctx, as->mNumMeshes ? as->mNumMeshes : 1, 3 * sizeof(float), "mesh emission");
    if (!s->mesh_emission) return HL_ERR_OUT_OF_MEMORY;
    for (unsigned i = 0; i < as->mNumMeshes; i++) {
        unsigned mi = as->mMeshes[i]->mMaterialIndex; /* in range: validated by the import */
        if (!as->mMaterials || mi >= as->mNumMaterials) continue;
        const struct aiMaterial *mat = as->mMaterials[mi];
        struct aiColor4D c;
        ai_real k = 1;
        if (aiGetMaterialColor(mat, AI_MATKEY_COLOR_EMISSIVE, &c) != aiReturn_SUCCESS) continue;
        if (aiGetMaterialFloatArray(mat, AI_MATKEY_EMISSIVE_INTENSITY, &k, NULL) != aiReturn_SUCCESS) k = 1;
        s->mesh_emission[3 * i] = (float)(c.r * k);
        s->mesh_emission[3 * i + 1] = (float)(c.g * k);
        s->mesh_emission[3 * i + 2] = (float)(c.b * k);
    }
    return HL_OK;
}

static hl_result check_desc(hl_context *ctx, const char *path, const hl_dyn_scene_desc *d, double up[9])
{
    int a = d->mesh.up_axis;
    for (int i = 0; i < 9; i++) up[i] = i % 4 == 0 ? 1.0 : 0.0;
    if (a == 'z' || a == 'Z') { /* (x, y, z) -> (x, z, -y), as the mesh builder turns a +Z-up file */
        up[4] = 0.0; up[5] = 1.0;
        up[7] = -1.0; up[8] = 0.0;
    } else if (a != 0 && a != 'y' && a != 'Y')
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: up axis %d is neither 'y' nor 'z'", path, a);
    return HL_OK;
}

hl_result hl_dyn_scene_load_desc(hl_context *ctx, const char *path, const hl_dyn_scene_desc *desc,
                                 hl_dyn_scene **out)
{
    if (out) *out = NULL;
    if (!path || !out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_dyn_scene_load: path and out are required");
    hl_dyn_scene_desc d;
    memset(&d, 0, sizeof d);
    if (desc) d = *desc;
    double up[9];
    hl_result r = check_desc(ctx, path, &d, up);
    if (r != HL_OK) return r;
    const struct aiScene *as = NULL;
    r = import_scene(ctx, path, &as);
    if (r != HL_OK) return r;
    int oom = 0;
    uint32_t nn = count_nodes(as->mRootNode, ctx, &oom);
    hl_dyn_scene *s = oom ? NULL : scene_new(ctx, path, nn);
    const struct aiNode **src = s ? hl_malloc(ctx, nn * sizeof *src, "the node walk") : NULL;
    if (!src) r = HL_ERR_OUT_OF_MEMORY;
    if (r == HL_OK) {
        memcpy(s->up, up, sizeof up);
        r = flatten_nodes(s, as, src);
    }
    if (r == HL_OK) r = hl_dyn_load_animation_(s, as, &d);
    if (r == HL_OK) r = hl_dyn_check_rigid_(s);
    if (r == HL_OK) hl_dyn_compose_(s, s->t_start, NULL); /* the world transforms at the start, no body yet */
    hl_mesh_load_desc md = d.mesh;
    md.up_axis = 0; /* the turn is the scene's, applied to the root */
    if (r == HL_OK && d.keep_triangles) r = read_emission(s, as);
    hl_materials mats;
    memset(&mats, 0, sizeof mats);
    float fallback[3] = {0, 0, 0};
    if (r == HL_OK && !d.keep_triangles) r = hl_mesh_resolve_albedo_(ctx, path, md.albedo, HL_DEFAULT_ALBEDO, fallback);
    if (r == HL_OK && !d.keep_triangles) r = hl_materials_read_(ctx, path, as, &mats);
    if (r == HL_OK) hl_materials_note_(ctx, path, &mats);
    for (uint32_t k = 0; k < nn && r == HL_OK; k++)
        r = make_body(s, as, src[k], k, &md, d.keep_triangles, &mats, fallback);
    if (r == HL_OK && mats.ntex) { /* the bodies' surfaces use its textures */
        s->mats = mats;
        memset(&mats, 0, sizeof mats);
    }
    hl_materials_free_(&mats);
    if (r == HL_OK && s->nbodies == 0)
        r = hl_fail(ctx, HL_ERR_MESH, "%s: no node of the scene holds a triangle: no geometry to move", path);
    free(src);
    aiReleaseImport(as);
    if (r != HL_OK) {
        hl_dyn_scene_destroy(s);
        return r;
    }
    *out = s;
    return HL_OK;
}

hl_result hl_dyn_scene_load(hl_context *ctx, const char *path, hl_dyn_scene **out)
{
    return hl_dyn_scene_load_desc(ctx, path, NULL, out);
}

/* ---------------------------------------------------------------- the built-in scene */

/* Body b gets the vertices [v0, v1) of mesh and the triangles that use
 * only them, renumbered from 0. */
static hl_result copy_part(hl_context *ctx, const hl_mesh *mesh, uint32_t v0, uint32_t v1, dyn_body *b)
{
    uint32_t nt = 0, nv = v1 - v0;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *f = mesh->indices + 3 * (size_t)t;
        nt += f[0] >= v0 && f[0] < v1 && f[1] >= v0 && f[1] < v1 && f[2] >= v0 && f[2] < v1;
    }
    b->pos = hl_malloc(ctx, (size_t)nv * 3 * sizeof(float), "body positions");
    b->normal = hl_malloc(ctx, (size_t)nv * 3 * sizeof(float), "body normals");
    b->albedo = hl_malloc(ctx, (size_t)nv * 3 * sizeof(float), "body albedo");
    b->tri = hl_malloc(ctx, ((size_t)nt + 1) * 3 * sizeof(uint32_t), "body triangles");
    if (!b->pos || !b->normal || !b->albedo || !b->tri) return HL_ERR_OUT_OF_MEMORY;
    memcpy(b->pos, mesh->positions + 3 * (size_t)v0, (size_t)nv * 3 * sizeof(float));
    memcpy(b->normal, mesh->normals + 3 * (size_t)v0, (size_t)nv * 3 * sizeof(float));
    if (mesh->albedo) memcpy(b->albedo, mesh->albedo + 3 * (size_t)v0, (size_t)nv * 3 * sizeof(float));
    else for (size_t i = 0; i < (size_t)nv * 3; i++) b->albedo[i] = HL_DEFAULT_ALBEDO;
    uint32_t k = 0;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *f = mesh->indices + 3 * (size_t)t;
        if (!(f[0] >= v0 && f[0] < v1 && f[1] >= v0 && f[1] < v1 && f[2] >= v0 && f[2] < v1)) continue;
        for (int c = 0; c < 3; c++) b->tri[3 * (size_t)k + c] = f[c] - v0;
        k++;
    }
    b->nverts = nv;
    b->ntris = nt;
    return HL_OK;
}

/* The ground hl_mesh_add_ground would add under the object: it is run on
 * a copy of the object, and what it appends becomes the ground body. */
static hl_result make_ground(hl_context *ctx, const dyn_body *obj, const hl_ground_desc *desc, dyn_body *ground)
{
    hl_mesh tmp = {obj->nverts, obj->ntris, obj->nverts, NULL, NULL, NULL, NULL};
    tmp.positions = hl_malloc(ctx, (size_t)obj->nverts * 3 * sizeof(float), "ground work");
    tmp.normals = hl_malloc(ctx, (size_t)obj->nverts * 3 * sizeof(float), "ground work");
    tmp.albedo = hl_malloc(ctx, (size_t)obj->nverts * 3 * sizeof(float), "ground work");
    tmp.indices = hl_malloc(ctx, ((size_t)obj->ntris + 1) * 3 * sizeof(uint32_t), "ground work");
    hl_result r = HL_ERR_OUT_OF_MEMORY;
    if (tmp.positions && tmp.normals && tmp.albedo && tmp.indices) {
        memcpy(tmp.positions, obj->pos, (size_t)obj->nverts * 3 * sizeof(float));
        memcpy(tmp.normals, obj->normal, (size_t)obj->nverts * 3 * sizeof(float));
        memcpy(tmp.albedo, obj->albedo, (size_t)obj->nverts * 3 * sizeof(float));
        memcpy(tmp.indices, obj->tri, (size_t)obj->ntris * 3 * sizeof(uint32_t));
        r = hl_mesh_add_ground(ctx, &tmp, desc);
    }
    if (r == HL_OK) r = copy_part(ctx, &tmp, tmp.object_vertex_count, tmp.vertex_count, ground);
    free(tmp.positions);
    free(tmp.normals);
    free(tmp.albedo);
    free(tmp.indices);
    return r;
}

hl_result hl_dyn_scene_from_mesh(hl_context *ctx, const hl_mesh *mesh, const hl_ground_desc *ground,
                                 hl_dyn_scene **out)
{
    if (out) *out = NULL;
    if (!mesh || !out || !mesh->positions || !mesh->normals || !mesh->indices || mesh->object_vertex_count == 0 ||
        mesh->object_vertex_count > mesh->vertex_count)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_dyn_scene_from_mesh: a mesh with an object and out are required");
    uint32_t ov = mesh->object_vertex_count;
    int has_ground = ov < mesh->vertex_count;
    if (has_ground && ground)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: the mesh already has a ground plane", HL_DYN_BUILTIN_NAME);
    uint32_t nb = has_ground || ground ? 2 : 1;
    hl_dyn_scene *s = scene_new(ctx, HL_DYN_BUILTIN_NAME, nb);
    if (!s) return HL_ERR_OUT_OF_MEMORY;
    static const char *names[2] = {"object", "ground"};
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < nb && r == HL_OK; k++) {
        dyn_node *n = &s->nodes[k];
        n->name = dup_str(ctx, names[k]);
        n->parent = -1;
        n->body = (int32_t)k;
        set_identity(n->rest);
        n->rest_q[0] = 1.0;
        n->scale[0] = n->scale[1] = n->scale[2] = 1.0;
        dyn_body *b = &s->bodies[k];
        b->node = k;
        set_identity(b->P);
        for (int i = 0; i < 9; i++) b->kinv[i] = i % 4 == 0 ? 1.0 : 0.0;
        s->nbodies = k + 1;
        if (!n->name) r = HL_ERR_OUT_OF_MEMORY;
        else if (k == 0) r = copy_part(ctx, mesh, 0, ov, b);
        else if (has_ground) r = copy_part(ctx, mesh, ov, mesh->vertex_count, b);
        else r = make_ground(ctx, &s->bodies[0], ground, b);
    }
    if (r == HL_OK && s->bodies[0].ntris == 0)
        r = hl_fail(ctx, HL_ERR_MESH, "%s: the mesh's object has no triangles", HL_DYN_BUILTIN_NAME);
    if (r != HL_OK) {
        hl_dyn_scene_destroy(s);
        return r;
    }
    *out = s;
    return HL_OK;
}

/* Times at which a moving scene's bounds are taken for its ground: the
 * animation's ends and evenly between (a key between two samples moves a
 * body less than a 63rd of its range). */
#define HL_DYN_GROUND_SAMPLES 64u

hl_result hl_dyn_scene_add_ground(hl_dyn_scene *s, const hl_ground_desc *desc)
{
    if (!s) return HL_ERR_INVALID_ARGUMENT;
    hl_context *ctx = s->ctx;
    /* the bodies' world bounds over the whole animation (the program's
       transforms included), and their mean albedo */
    double t0 = 0.0, t1 = 0.0;
    const int moving = hl_dyn_scene_animation(s, &t0, &t1) != NULL && t1 > t0;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < (moving ? HL_DYN_GROUND_SAMPLES : 1u); i++) {
        float l[3], h[3];
        const double t = moving ? t0 + (t1 - t0) * i / (HL_DYN_GROUND_SAMPLES - 1u) : t0;
        hl_result rb = hl_dyn_scene_bounds(s, t, l, h);
        if (rb != HL_OK) return rb;
        for (int k = 0; k < 3; k++) lo[k] = fminf(lo[k], l[k]), hi[k] = fmaxf(hi[k], h[k]);
    }
    double mean[3] = {0, 0, 0};
    uint64_t nv = 0;
    for (uint32_t b = 0; b < s->nbodies; b++)
        for (uint32_t v = 0; v < s->bodies[b].nverts; v++, nv++)
            for (int k = 0; k < 3; k++) mean[k] += s->bodies[b].albedo ? s->bodies[b].albedo[3 * (size_t)v + k] : HL_DEFAULT_ALBEDO;
    /* hl_mesh_add_ground on the two corners of those bounds, each with the
       mean albedo: the ground it would put under the whole motion */
    float pos[6] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]}, nrm[6] = {0, 1, 0, 0, 1, 0}, alb[6];
    for (int k = 0; k < 3; k++) alb[k] = alb[3 + k] = nv ? (float)(mean[k] / (double)nv) : HL_DEFAULT_ALBEDO;
    hl_mesh tmp = {2, 0, 2, NULL, NULL, NULL, NULL};
    tmp.positions = hl_malloc(ctx, sizeof pos, "ground work");
    tmp.normals = hl_malloc(ctx, sizeof nrm, "ground work");
    tmp.albedo = hl_malloc(ctx, sizeof alb, "ground work");
    tmp.indices = hl_malloc(ctx, 3 * sizeof(uint32_t), "ground work");
    hl_result r = tmp.positions && tmp.normals && tmp.albedo && tmp.indices ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    if (r == HL_OK) {
        memcpy(tmp.positions, pos, sizeof pos);
        memcpy(tmp.normals, nrm, sizeof nrm);
        memcpy(tmp.albedo, alb, sizeof alb);
        r = hl_mesh_add_ground(ctx, &tmp, desc);
    }
    /* a root node of its own whose world transform is the identity: the
       scene's up turn, applied to every root, undone by its rest */
    dyn_node *nodes = r == HL_OK ? realloc(s->nodes, ((size_t)s->nnodes + 1) * sizeof *nodes) : NULL;
    if (nodes) s->nodes = nodes;
    dyn_body *bodies = nodes ? realloc(s->bodies, ((size_t)s->nbodies + 1) * sizeof *bodies) : NULL;
    if (bodies) s->bodies = bodies;
    double *world = bodies ? realloc(s->world, ((size_t)s->nnodes + 1) * 12 * sizeof *world) : NULL;
    if (world) s->world = world;
    if (r == HL_OK && !world) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the ground");
    if (r == HL_OK) {
        dyn_node *n = &s->nodes[s->nnodes];
        memset(n, 0, sizeof *n);
        dyn_body *b = &s->bodies[s->nbodies];
        memset(b, 0, sizeof *b);
        n->parent = -1;
        n->body = (int32_t)s->nbodies;
        set_identity(n->rest);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) n->rest[4 * i + j] = s->up[3 * j + i]; /* the turn's inverse, its transpose */
        n->rest_q[0] = 1.0;
        n->scale[0] = n->scale[1] = n->scale[2] = 1.0;
        b->node = s->nnodes;
        set_identity(b->P);
        for (int i = 0; i < 9; i++) b->kinv[i] = i % 4 == 0 ? 1.0 : 0.0;
        n->name = dup_str(ctx, "ground");
        r = n->name ? copy_part(ctx, &tmp, tmp.object_vertex_count, tmp.vertex_count, b) : HL_ERR_OUT_OF_MEMORY;
        s->nnodes++, s->nbodies++; /* destroyed with the scene either way */
    }
    free(tmp.positions);
    free(tmp.normals);
    free(tmp.albedo);
    free(tmp.indices);
    return r;
}

hl_result hl_dyn_scene_from_triangles(hl_context *ctx, const char *name, const char *body_name,
                                      const float *positions, uint32_t count, hl_dyn_scene **out)
{
    if (out) *out = NULL;
    if (!name || !body_name || !positions || !out || count == 0 || count > UINT32_MAX / 3)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_dyn_scene_from_triangles: triangles and out are required");
    hl_dyn_scene *s = scene_new(ctx, name, 1);
    if (!s) return HL_ERR_OUT_OF_MEMORY;
    dyn_node *n = &s->nodes[0];
    dyn_body *b = &s->bodies[0];
    s->nbodies = 1;
    n->name = dup_str(ctx, body_name);
    n->parent = -1;
    n->body = 0;
    set_identity(n->rest);
    n->rest_q[0] = 1.0;
    n->scale[0] = n->scale[1] = n->scale[2] = 1.0;
    set_identity(b->P);
    for (int i = 0; i < 9; i++) b->kinv[i] = i % 4 == 0 ? 1.0 : 0.0;
    b->pos = hl_malloc(ctx, (size_t)count * 9 * sizeof(float), "triangle corners");
    b->tri = hl_malloc(ctx, (size_t)count * 3 * sizeof(uint32_t), "triangle indices");
    b->tri_mesh = hl_calloc(ctx, count, sizeof(uint32_t), "triangle meshes");
    s->nmeshes = 1;
    s->mesh_emission = hl_calloc(ctx, 1, 3 * sizeof(float), "mesh emission");
    if (!n->name || !b->pos || !b->tri || !b->tri_mesh || !s->mesh_emission) {
        hl_dyn_scene_destroy(s);
        return HL_ERR_OUT_OF_MEMORY;
    }
    memcpy(b->pos, positions, (size_t)count * 9 * sizeof(float));
    for (uint32_t i = 0; i < 3 * count; i++) b->tri[i] = i;
    b->nverts = 3 * count;
    b->ntris = count;
    *out = s;
    return HL_OK;
}

/* ---------------------------------------------------------------- queries */

uint32_t hl_dyn_scene_body_count(const hl_dyn_scene *s) { return s ? s->nbodies : 0; }

const char *hl_dyn_scene_body_name(const hl_dyn_scene *s, uint32_t body)
{
    return s && body < s->nbodies ? s->nodes[s->bodies[body].node].name : NULL;
}

const float *hl_dyn_scene_body_albedo(const hl_dyn_scene *s, uint32_t body)
{
    return s && body < s->nbodies ? s->bodies[body].albedo : NULL;
}

int32_t hl_dyn_scene_body_parent(const hl_dyn_scene *s, uint32_t body)
{
    if (!s || body >= s->nbodies) return -1;
    int32_t n = s->nodes[s->bodies[body].node].parent;
    while (n >= 0 && s->nodes[n].body < 0) n = s->nodes[n].parent;
    return n >= 0 ? s->nodes[n].body : -1;
}

const uint32_t *hl_dyn_scene_body_tri_mesh(const hl_dyn_scene *s, uint32_t body)
{
    return s && body < s->nbodies ? s->bodies[body].tri_mesh : NULL;
}

uint32_t hl_dyn_scene_mesh_count(const hl_dyn_scene *s) { return s ? s->nmeshes : 0; }

const float *hl_dyn_scene_mesh_emission(const hl_dyn_scene *s, uint32_t mesh)
{
    return s && s->mesh_emission && mesh < s->nmeshes ? s->mesh_emission + 3 * (size_t)mesh : NULL;
}

int32_t hl_dyn_scene_find(const hl_dyn_scene *s, const char *name)
{
    if (!s || !name) return -1;
    for (uint32_t n = 0; n < s->nnodes; n++) /* depth-first order */
        if (s->nodes[n].body >= 0 && strcmp(s->nodes[n].name, name) == 0) return s->nodes[n].body;
    return -1;
}

const char *hl_dyn_scene_animation(const hl_dyn_scene *s, double *start, double *end)
{
    if (start) *start = s ? s->t_start : 0.0;
    if (end) *end = s ? s->t_end : 0.0;
    return s ? s->anim_name : NULL;
}
