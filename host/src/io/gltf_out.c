/* gltf_out.c - a coloured mesh as binary glTF 2.0 (.glb), written by
 * assimp's exporter.
 *
 * Unlit materials (KHR_materials_unlit): the colours are the light
 * already. Positions, normals, COLOR_0 the linear radiance per vertex
 * (alpha 1; glTF's vertex colours are linear, so a viewer that multiplies
 * them into the base colour shows the relit mesh), and COLOR_1 the same
 * colours tone-mapped for display (exposure, then the sRGB curve, as
 * `relight`'s PNG; values in [0, 1]). Without a textured surface that is
 * one primitive whose vertices are the mesh's, in its order; with one,
 * textured triangles get primitives of their own (below). The scene is
 * built here in assimp's C structures and copied by the exporter, which
 * frees nothing of ours. The file is written to <path>.tmp.<pid>, synced
 * and renamed onto path when complete.
 * Depends on: hl_internal.h (hl_publish_tmp), hl_tonemap_srgb8, assimp's exporter.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <assimp/cexport.h>
#include <assimp/material.h>
#include <assimp/scene.h>

#include "hl_internal.h"
#include "material.h"

static void set_name(struct aiString *s, const char *name)
{
    const size_t n = strlen(name);
    s->length = (ai_uint32)n;
    memcpy(s->data, name, n + 1);
}

static hl_result check_colours(hl_context *ctx, const char *path, const hl_mesh *m, const float *rgb)
{
    for (size_t i = 0; i < 3 * (size_t)m->vertex_count; i++)
        if (!isfinite(rgb[i]) || rgb[i] < 0.0f)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %zu has a colour that is negative or not finite (%g)",
                           path, i / 3, (double)rgb[i]);
    return HL_OK;
}

/* ---------------------------------------------------------------- the scene */

/* Primitive 0 holds the untextured triangles (all of them without a
 * surface), its vertices the mesh's that they use, in the mesh's order.
 * With a textured surface, one primitive (aiMesh) per texture, each with
 * its own unlit material whose base-colour texture is the file's own PNG
 * or JPEG, embedded as it was. In a
 * textured primitive COLOR_0 is the base colour (factor x vertex colour)
 * times the irradiance (the vertex's radiance over its albedo), so that
 * glTF's base colour x texture x COLOR_0 is the radiance at each pixel,
 * in the same units as the other primitive's COLOR_0; COLOR_1 is the
 * vertex's tone-mapped radiance everywhere. Vertices are split where a
 * texture's UVs have a seam. */

typedef struct tex_glb {
    struct aiScene scene;
    struct aiNode root;
    uint32_t n;                     /* primitives */
    struct aiMesh *mesh, **mesh_ptr;
    struct aiMaterial *mat, **mat_ptr;
    struct aiMaterialProperty *prop, **prop_ptr; /* 2 a material: unlit, texture */
    char *path_data;                /* the texture properties' strings, 32 bytes each */
    struct aiTexture *tex, **tex_ptr;
    unsigned *node_meshes;
    int unlit_value;
} tex_glb;

typedef struct corner_key {
    uint32_t v, u, w; /* vertex, UV bits */
    uint32_t at;      /* corner number in the primitive */
} corner_key;

static int corner_cmp(const void *a, const void *b)
{
    const corner_key *x = a, *y = b;
    if (x->v != y->v) return x->v < y->v ? -1 : 1;
    if (x->u != y->u) return x->u < y->u ? -1 : 1;
    if (x->w != y->w) return x->w < y->w ? -1 : 1;
    return 0;
}

static uint32_t float_bits(float f)
{
    uint32_t b;
    f = f == 0.0f ? 0.0f : f; /* -0 and +0 are one UV */
    memcpy(&b, &f, sizeof b);
    return b;
}

static void tex_glb_free(tex_glb *g)
{
    for (uint32_t i = 0; g->mesh && i < g->n; i++) {
        struct aiMesh *am = &g->mesh[i];
        free(am->mVertices);
        free(am->mNormals);
        free(am->mColors[0]);
        free(am->mColors[1]);
        free(am->mTextureCoords[0]);
        if (am->mFaces) free(am->mFaces[0].mIndices);
        free(am->mFaces);
    }
    free(g->mesh);
    free(g->mesh_ptr);
    free(g->mat);
    free(g->mat_ptr);
    free(g->prop);
    free(g->prop_ptr);
    free(g->path_data);
    free(g->tex);
    free(g->tex_ptr);
    free(g->node_meshes);
}

/* Primitive i from the triangles whose group is i (group[t]; texture k is
 * group k + 1, 0 the rest). 0 when out of memory. */
static int fill_primitive(tex_glb *g, uint32_t i, const hl_mesh *m, const float *rgb, const hl_surface *su,
                          const int32_t *group, uint32_t count, float ev)
{
    struct aiMesh *am = &g->mesh[i];
    const int textured = i > 0;
    corner_key *k = malloc(((size_t)count * 3 + 1) * sizeof *k);
    uint32_t *vid = malloc(((size_t)count * 3 + 1) * sizeof *vid); /* the primitive's vertex of each corner */
    if (!k || !vid) {
        free(k);
        free(vid);
        return 0;
    }
    uint32_t c = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        if ((uint32_t)group[t] != i) continue;
        for (int q = 0; q < 3; q++, c++) {
            const float *uv = textured ? su->uv + 6 * (size_t)t + 2 * (size_t)q : NULL;
            k[c] = (corner_key){m->indices[3 * (size_t)t + (size_t)q], uv ? float_bits(uv[0]) : 0,
                                uv ? float_bits(uv[1]) : 0, c};
        }
    }
    qsort(k, c, sizeof *k, corner_cmp);
    uint32_t nv = 0;
    for (uint32_t j = 0; j < c; j++) {
        if (j == 0 || corner_cmp(&k[j], &k[j - 1])) nv++;
        vid[k[j].at] = nv - 1;
    }
    am->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
    am->mNumVertices = nv;
    am->mNumFaces = count;
    am->mMaterialIndex = i;
    am->mVertices = malloc((size_t)nv * sizeof *am->mVertices + 1);
    am->mNormals = malloc((size_t)nv * sizeof *am->mNormals + 1);
    am->mColors[0] = malloc((size_t)nv * sizeof *am->mColors[0] + 1);
    am->mColors[1] = malloc((size_t)nv * sizeof *am->mColors[1] + 1);
    if (textured) {
        am->mTextureCoords[0] = malloc((size_t)nv * sizeof *am->mTextureCoords[0] + 1);
        am->mNumUVComponents[0] = 2;
    }
    am->mFaces = calloc(count, sizeof *am->mFaces);
    unsigned int *idx = malloc((size_t)count * 3 * sizeof *idx + 1);
    if (!am->mVertices || !am->mNormals || !am->mColors[0] || !am->mColors[1] || (textured && !am->mTextureCoords[0]) ||
        !am->mFaces || !idx) {
        free(idx);
        free(k);
        free(vid);
        return 0;
    }
    /* each vertex from one of its corners: they share the vertex, and
       their UVs where textured */
    c = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        if ((uint32_t)group[t] != i) continue;
        am->mFaces[c / 3].mNumIndices = 3;
        am->mFaces[c / 3].mIndices = idx + c;
        for (int q = 0; q < 3; q++, c++) {
            const uint32_t v = m->indices[3 * (size_t)t + (size_t)q], o = vid[c];
            idx[c] = o;
            const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v, *l = rgb + 3 * (size_t)v;
            am->mVertices[o] = (struct aiVector3D){p[0], p[1], p[2]};
            am->mNormals[o] = (struct aiVector3D){n[0], n[1], n[2]};
            am->mColors[1][o] = (struct aiColor4D){hl_tonemap_srgb8(l[0], ev) / 255.0f,
                                                   hl_tonemap_srgb8(l[1], ev) / 255.0f,
                                                   hl_tonemap_srgb8(l[2], ev) / 255.0f, 1.0f};
            float c0[3] = {l[0], l[1], l[2]};
            if (textured) {
                const float *uv = su->uv + 6 * (size_t)t + 2 * (size_t)q, *b = su->base + 9 * (size_t)t + 3 * (size_t)q;
                am->mTextureCoords[0][o] = (struct aiVector3D){uv[0], uv[1], 0.0f};
                for (int ch = 0; ch < 3; ch++) { /* in double: a huge colour over a tiny albedo stays finite */
                    const double a = m->albedo[3 * (size_t)v + (size_t)ch];
                    c0[ch] = a > 1e-6 ? (float)fmin((double)b[ch] * (l[ch] / a), FLT_MAX) : 0.0f;
                }
            }
            am->mColors[0][o] = (struct aiColor4D){c0[0], c0[1], c0[2], 1.0f};
        }
    }
    free(k);
    free(vid);
    set_name(&am->mName, textured ? "relit-textured" : "relit");
    return 1;
}

/* Material i: unlit, and for a textured primitive the texture "*k". */
static void fill_material(tex_glb *g, uint32_t i, uint32_t tex_index)
{
    struct aiMaterialProperty *u = &g->prop[2 * i], *t = &g->prop[2 * i + 1];
    set_name(&u->mKey, "$mat.shadingm");
    u->mDataLength = sizeof g->unlit_value;
    u->mType = aiPTI_Buffer;
    u->mData = (char *)&g->unlit_value;
    g->prop_ptr[2 * i] = u;
    g->mat[i].mProperties = g->prop_ptr + 2 * i;
    g->mat[i].mNumProperties = g->mat[i].mNumAllocated = 1;
    if (i > 0) { /* an aiString's bytes: its length, then the characters and a 0 */
        char *d = g->path_data + 32 * (size_t)i;
        char name[24];
        snprintf(name, sizeof name, "*%u", tex_index);
        const ai_uint32 len = (ai_uint32)strlen(name);
        memcpy(d, &len, sizeof len);
        memcpy(d + sizeof len, name, len + 1);
        set_name(&t->mKey, _AI_MATKEY_TEXTURE_BASE);
        t->mSemantic = aiTextureType_BASE_COLOR;
        t->mIndex = 0;
        t->mDataLength = (unsigned)(sizeof len + len + 1);
        t->mType = aiPTI_String;
        t->mData = d;
        g->prop_ptr[2 * i + 1] = t;
        g->mat[i].mNumProperties = g->mat[i].mNumAllocated = 2;
    }
    g->mat_ptr[i] = &g->mat[i];
}

hl_result hl_mesh_save_glb(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb, const char *path,
                           float exposure_ev)
{
    return hl_mesh_save_glb_surface(ctx, mesh, vertex_rgb, NULL, path, exposure_ev);
}

hl_result hl_mesh_save_glb_surface(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                                   const hl_surface *surface, const char *path, float exposure_ev)
{
    if (!mesh || !vertex_rgb || !path || !*path)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_mesh_save_glb: mesh, colours and path are required");
    if (!isfinite(exposure_ev))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: exposure %g is not finite", path, (double)exposure_ev);
    hl_result r = check_colours(ctx, path, mesh, vertex_rgb);
    if (r != HL_OK) return r;
    /* without a texture to embed it is the plain file: one primitive */
    uint32_t embeddable = 0;
    for (uint32_t k = 0; surface && k < surface->mats.ntex; k++) embeddable += surface->mats.tex[k].file != NULL;
    if (!embeddable) surface = NULL;
    if (surface && (surface->triangle_count > mesh->triangle_count || !mesh->albedo))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: the textured surface (%u triangles) is not this mesh's (%u)",
                       path, surface->triangle_count, mesh->triangle_count);
    const hl_materials none = {0}, *mats = surface ? &surface->mats : &none;
    /* primitive 0: the untextured triangles; then one per embeddable
       texture that some triangle uses, numbered in order */
    int32_t *group = malloc(((size_t)mesh->triangle_count + 1) * sizeof *group);
    uint32_t *count = calloc((size_t)mats->ntex + 1, sizeof *count), *prim_of = calloc((size_t)mats->ntex + 1, sizeof *prim_of);
    const size_t n = strlen(path) + 32;
    char *tmp = malloc(n);
    tex_glb *g = calloc(1, sizeof *g);
    if (!group || !count || !prim_of || !tmp || !g) {
        r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory building the glTF scene", path);
        goto done;
    }
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        int32_t x = surface && t < surface->triangle_count ? surface->tex[t] : -1;
        if (x >= 0 && !mats->tex[x].file) x = -1;
        group[t] = x + 1;
        count[x + 1]++;
    }
    uint32_t np = 0, ntex = 0;
    for (uint32_t k = 0; k <= mats->ntex; k++)
        if (k == 0 || count[k]) prim_of[k] = np++;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) group[t] = (int32_t)prim_of[group[t]];
    g->n = np;
    g->mesh = calloc(np, sizeof *g->mesh);
    g->mesh_ptr = calloc(np, sizeof *g->mesh_ptr);
    g->mat = calloc(np, sizeof *g->mat);
    g->mat_ptr = calloc(np, sizeof *g->mat_ptr);
    g->prop = calloc(2 * (size_t)np, sizeof *g->prop);
    g->prop_ptr = calloc(2 * (size_t)np, sizeof *g->prop_ptr);
    g->path_data = calloc(np, 32);
    g->tex = calloc(np, sizeof *g->tex);
    g->tex_ptr = calloc(np, sizeof *g->tex_ptr);
    g->node_meshes = calloc(np, sizeof *g->node_meshes);
    int ok = g->mesh && g->mesh_ptr && g->mat && g->mat_ptr && g->prop && g->prop_ptr && g->path_data && g->tex &&
             g->tex_ptr && g->node_meshes;
    g->unlit_value = aiShadingMode_Unlit;
    for (uint32_t k = 0; ok && k <= mats->ntex; k++) {
        if (k > 0 && !count[k]) continue;
        const uint32_t i = prim_of[k];
        const uint32_t used = count[k];
        if (used == 0) { /* no untextured triangle: primitive 0 stays empty and is dropped below */
            fill_material(g, i, 0);
            continue;
        }
        ok = fill_primitive(g, i, mesh, vertex_rgb, surface, group, used, exposure_ev);
        if (!ok) break;
        if (k > 0) {
            const hl_texture *tx = &mats->tex[k - 1];
            struct aiTexture *e = &g->tex[ntex];
            e->mWidth = (unsigned)tx->file_size;
            e->mHeight = 0;
            snprintf(e->achFormatHint, sizeof e->achFormatHint, "%s", tx->format);
            e->pcData = (struct aiTexel *)tx->file; /* copied by the exporter, not freed here */
            g->tex_ptr[ntex] = e;
            fill_material(g, i, ntex++);
        } else
            fill_material(g, i, 0);
    }
    if (!ok) {
        r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory building the glTF scene", path);
        goto done;
    }
    /* only the non-empty primitives: primitive 0 is empty when every
       triangle is textured, and the exporter fails on an empty mesh */
    uint32_t nm = 0;
    for (uint32_t i = 0; i < np; i++)
        if (g->mesh[i].mNumFaces) {
            g->mesh_ptr[nm] = &g->mesh[i];
            g->node_meshes[nm] = nm;
            nm++;
        }
    set_name(&g->root.mName, "haarlight");
    g->root.mTransformation.a1 = g->root.mTransformation.b2 = g->root.mTransformation.c3 =
        g->root.mTransformation.d4 = 1.0f;
    g->root.mNumMeshes = nm;
    g->root.mMeshes = g->node_meshes;
    g->scene.mRootNode = &g->root;
    g->scene.mNumMeshes = nm;
    g->scene.mMeshes = g->mesh_ptr;
    g->scene.mNumMaterials = np;
    g->scene.mMaterials = g->mat_ptr;
    g->scene.mNumTextures = ntex;
    g->scene.mTextures = g->tex_ptr;
    snprintf(tmp, n, "%s.tmp.%ld", path, (long)getpid());
    if (aiExportScene(&g->scene, "glb2", tmp, 0) != aiReturn_SUCCESS)
        r = hl_fail(ctx, HL_ERR_IO, "%s: assimp could not write %s", path, tmp);
    r = hl_publish_tmp(ctx, tmp, path, r);
done:
    if (g) tex_glb_free(g);
    free(g);
    free(tmp);
    free(group);
    free(count);
    free(prim_of);
    return r;
}
