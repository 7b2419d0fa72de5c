/* gltf_out.c - a coloured mesh as binary glTF 2.0 (.glb), written by
 * assimp's exporter.
 *
 * One mesh, one node, one unlit material: positions, normals, COLOR_0 the
 * linear radiance per vertex (alpha 1; glTF's vertex colours are linear,
 * so a viewer that multiplies them into the base colour shows the relit
 * mesh), and COLOR_1 the same colours tone-mapped for display (exposure,
 * then the sRGB curve, as `relight`'s PNG; values in [0, 1]), which a
 * viewer that knows nothing of HDR can show as they are. The scene is
 * built here in assimp's C structures and copied by the exporter, which
 * frees nothing of ours. The file is written to <path>.tmp.<pid>, synced
 * and renamed onto path when complete.
 * Depends on: hl_internal.h (hl_publish_tmp), hl_tonemap_srgb8, assimp's exporter.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <assimp/cexport.h>
#include <assimp/scene.h>

#include "hl_internal.h"

typedef struct glb_scene {
    struct aiScene scene;
    struct aiNode root;
    struct aiMesh mesh;
    struct aiMaterial material;
    struct aiMaterialProperty unlit;
    struct aiMaterialProperty *props[1];
    int unlit_value;
    struct aiMesh *meshes[1];
    struct aiMaterial *materials[1];
    unsigned int node_meshes[1];
} glb_scene;

static void set_name(struct aiString *s, const char *name)
{
    const size_t n = strlen(name);
    s->length = (ai_uint32)n;
    memcpy(s->data, name, n + 1);
}

static void free_arrays(glb_scene *g)
{
    free(g->mesh.mVertices);
    free(g->mesh.mNormals);
    free(g->mesh.mColors[0]);
    free(g->mesh.mColors[1]);
    if (g->mesh.mFaces) free(g->mesh.mFaces[0].mIndices); /* one block for all faces */
    free(g->mesh.mFaces);
}

/* Fills g's arrays from the mesh and the colours; 0 when out of memory. */
static int fill(glb_scene *g, const hl_mesh *m, const float *rgb, float exposure_ev)
{
    struct aiMesh *am = &g->mesh;
    const uint32_t nv = m->vertex_count, nt = m->triangle_count;
    am->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
    am->mNumVertices = nv;
    am->mNumFaces = nt;
    am->mVertices = malloc((size_t)nv * sizeof *am->mVertices);
    am->mNormals = malloc((size_t)nv * sizeof *am->mNormals);
    am->mColors[0] = malloc((size_t)nv * sizeof *am->mColors[0]);
    am->mColors[1] = malloc((size_t)nv * sizeof *am->mColors[1]);
    am->mFaces = calloc(nt ? nt : 1, sizeof *am->mFaces);
    unsigned int *idx = malloc((size_t)nt * 3 * sizeof *idx + 1);
    if (!am->mVertices || !am->mNormals || !am->mColors[0] || !am->mColors[1] || !am->mFaces || !idx) {
        free(idx);
        return 0;
    }
    for (uint32_t v = 0; v < nv; v++) {
        const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v, *c = rgb + 3 * (size_t)v;
        am->mVertices[v] = (struct aiVector3D){p[0], p[1], p[2]};
        am->mNormals[v] = (struct aiVector3D){n[0], n[1], n[2]};
        am->mColors[0][v] = (struct aiColor4D){c[0], c[1], c[2], 1.0f};
        am->mColors[1][v] = (struct aiColor4D){hl_tonemap_srgb8(c[0], exposure_ev) / 255.0f,
                                               hl_tonemap_srgb8(c[1], exposure_ev) / 255.0f,
                                               hl_tonemap_srgb8(c[2], exposure_ev) / 255.0f, 1.0f};
    }
    for (uint32_t t = 0; t < nt; t++) {
        for (int k = 0; k < 3; k++) idx[3 * (size_t)t + (size_t)k] = m->indices[3 * (size_t)t + (size_t)k];
        am->mFaces[t].mNumIndices = 3;
        am->mFaces[t].mIndices = idx + 3 * (size_t)t;
    }
    if (nt == 0) free(idx);
    set_name(&am->mName, "relit");
    g->meshes[0] = am;
    /* unlit (KHR_materials_unlit): the colours are the light already, and
       a viewer that shades them again would light the mesh twice */
    g->unlit_value = aiShadingMode_Unlit;
    set_name(&g->unlit.mKey, "$mat.shadingm");
    g->unlit.mDataLength = sizeof g->unlit_value;
    g->unlit.mType = aiPTI_Buffer; /* assimp reads an enum only from a buffer */
    g->unlit.mData = (char *)&g->unlit_value;
    g->props[0] = &g->unlit;
    g->material.mProperties = g->props;
    g->material.mNumProperties = g->material.mNumAllocated = 1;
    g->materials[0] = &g->material;
    g->node_meshes[0] = 0;
    struct aiNode *root = &g->root;
    set_name(&root->mName, "haarlight");
    root->mTransformation.a1 = root->mTransformation.b2 = root->mTransformation.c3 = root->mTransformation.d4 = 1.0f;
    root->mNumMeshes = 1;
    root->mMeshes = g->node_meshes;
    g->scene.mRootNode = root;
    g->scene.mNumMeshes = 1;
    g->scene.mMeshes = g->meshes;
    g->scene.mNumMaterials = 1;
    g->scene.mMaterials = g->materials;
    return 1;
}

static hl_result check_colours(hl_context *ctx, const char *path, const hl_mesh *m, const float *rgb)
{
    for (size_t i = 0; i < 3 * (size_t)m->vertex_count; i++)
        if (!isfinite(rgb[i]) || rgb[i] < 0.0f)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %zu has a colour that is negative or not finite (%g)",
                           path, i / 3, (double)rgb[i]);
    return HL_OK;
}

hl_result hl_mesh_save_glb(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb, const char *path,
                           float exposure_ev)
{
    if (!mesh || !vertex_rgb || !path || !*path)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_mesh_save_glb: mesh, colours and path are required");
    if (!isfinite(exposure_ev))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: exposure %g is not finite", path, (double)exposure_ev);
    hl_result r = check_colours(ctx, path, mesh, vertex_rgb);
    if (r != HL_OK) return r;
    glb_scene *g = calloc(1, sizeof *g);
    const size_t n = strlen(path) + 32;
    char *tmp = malloc(n);
    if (!g || !tmp || !fill(g, mesh, vertex_rgb, exposure_ev)) {
        if (g) free_arrays(g);
        free(g);
        free(tmp);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory building the glTF scene", path);
    }
    snprintf(tmp, n, "%s.tmp.%ld", path, (long)getpid());
    if (aiExportScene(&g->scene, "glb2", tmp, 0) != aiReturn_SUCCESS)
        r = hl_fail(ctx, HL_ERR_IO, "%s: assimp could not write %s", path, tmp);
    free_arrays(g);
    free(g);
    r = hl_publish_tmp(ctx, tmp, path, r);
    free(tmp);
    return r;
}
