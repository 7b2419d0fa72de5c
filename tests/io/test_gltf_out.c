/* test_gltf_out.c - binary glTF output (suite "gltf_out").
 *
 * Cases: roundtrip (a small mesh with known colours written as .glb and
 * read back with assimp: the same vertices, triangles, linear COLOR_0 to
 * the bit, tone-mapped COLOR_1 equal to hl_tonemap_srgb8 / 255, an unlit
 * material), bad (negative or non-finite colours and an unwritable place
 * are refused, naming the file, and leave nothing behind), blender (the
 * file imported by Blender in the background, when Blender is installed;
 * skipped otherwise).
 * Depends on: haarlight.h (hl_mesh_create, hl_mesh_save_glb), assimp,
 * hl_test.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "hl_test.h"

/* A tetrahedron-like fan: 5 vertices, 4 triangles, colours from dark to
 * a bright sun value. */
static hl_mesh *small_mesh(hl_context *ctx)
{
    static const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
    static const uint32_t tri[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 4};
    hl_mesh *m = NULL;
    HL_CHECK(hl_mesh_create(ctx, 5, pos, NULL, NULL, 4, tri, &m) == HL_OK, "mesh: %s", hl_context_last_error(ctx));
    return m;
}

static void colours(uint32_t n, float *rgb)
{
    for (uint32_t v = 0; v < n; v++) {
        rgb[3 * v] = 0.01f * (float)(v + 1);
        rgb[3 * v + 1] = 0.3f * (float)v;
        rgb[3 * v + 2] = v == n - 1 ? 2500.0f : 0.5f;
    }
}

static void case_roundtrip(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_mesh *m = small_mesh(ctx);
    if (!m) return;
    float *rgb = malloc((size_t)m->vertex_count * 12);
    colours(m->vertex_count, rgb);
    const char *path = hl_test_tmp_path("gltf_roundtrip.glb");
    const float ev = -1.5f;
    HL_CHECK(hl_mesh_save_glb(ctx, m, rgb, path, ev) == HL_OK, "save: %s", hl_context_last_error(ctx));
    const struct aiScene *s = aiImportFile(path, aiProcess_ValidateDataStructure);
    HL_CHECK(s && s->mNumMeshes == 1, "assimp reads %s: %s", path, aiGetErrorString());
    if (s && s->mNumMeshes == 1) {
        const struct aiMesh *am = s->mMeshes[0];
        HL_CHECK(am->mNumVertices == m->vertex_count && am->mNumFaces == m->triangle_count,
                 "%u vertices, %u triangles read back; %u and %u written", am->mNumVertices, am->mNumFaces,
                 m->vertex_count, m->triangle_count);
        HL_CHECK(am->mColors[0] && am->mColors[1], "COLOR_0 and COLOR_1 read back");
        double lin = 0.0, tm = 0.0, posn = 0.0;
        for (uint32_t v = 0; am->mColors[0] && am->mColors[1] && v < am->mNumVertices && v < m->vertex_count; v++)
            for (int c = 0; c < 3; c++) {
                const float *c0 = &am->mColors[0][v].r, *c1 = &am->mColors[1][v].r, *p = &am->mVertices[v].x;
                lin = fmax(lin, fabs((double)c0[c] - rgb[3 * v + (uint32_t)c]));
                tm = fmax(tm, fabs((double)c1[c] - hl_tonemap_srgb8(rgb[3 * v + (uint32_t)c], ev) / 255.0));
                posn = fmax(posn, fabs((double)p[c] - m->positions[3 * v + (uint32_t)c]));
            }
        hl_check_error("COLOR_0 against the linear colours", lin, 0.0);
        hl_check_error("COLOR_1 against the tone-mapped colours", tm, 1e-7);
        hl_check_error("positions", posn, 0.0);
        int shading = 0;
        const int got = s->mNumMaterials > 0 &&
                        aiGetMaterialIntegerArray(s->mMaterials[am->mMaterialIndex], AI_MATKEY_SHADING_MODEL, &shading, NULL) ==
                            aiReturn_SUCCESS;
        HL_CHECK(got && shading == aiShadingMode_Unlit, "the material is unlit (shading model %d)", shading);
    }
    if (s) aiReleaseImport(s);
    free(rgb);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static int leftovers(const char *dir, const char *prefix)
{
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));) n += !strncmp(e->d_name, prefix, strlen(prefix)) && strstr(e->d_name, ".tmp.");
    if (d) closedir(d);
    return n;
}

static void case_bad(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_mesh *m = small_mesh(ctx);
    if (!m) return;
    float *rgb = malloc((size_t)m->vertex_count * 12);
    const char *path = hl_test_tmp_path("gltf_bad.glb");
    remove(path);
    const float bad[2] = {-0.5f, NAN};
    for (int k = 0; k < 2; k++) {
        colours(m->vertex_count, rgb);
        rgb[4] = bad[k];
        const hl_result r = hl_mesh_save_glb(ctx, m, rgb, path, 0.0f);
        HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && strstr(hl_context_last_error(ctx), path) && access(path, F_OK) != 0,
                 "a colour of %g: result %d, message %s", (double)bad[k], (int)r, hl_context_last_error(ctx));
        printf("refused as expected: %s\n", hl_context_last_error(ctx));
    }
    colours(m->vertex_count, rgb);
    const char *nowhere = "/nonexistent-folder/out.glb";
    const hl_result r = hl_mesh_save_glb(ctx, m, rgb, nowhere, 0.0f);
    HL_CHECK(r == HL_ERR_IO && strstr(hl_context_last_error(ctx), nowhere), "unwritable: %d %s", (int)r,
             hl_context_last_error(ctx));
    printf("refused as expected: %s\n", hl_context_last_error(ctx));
    HL_CHECK(leftovers(hl_test_env("HL_TMP", "/tmp"), "gltf_bad.glb") == 0, "a temporary file was left behind");
    free(rgb);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* Blender, where installed, imports the file with its own glTF importer
 * and reports the vertex count. */
static void case_blender(void)
{
    if (system("command -v blender >/dev/null 2>&1") != 0) {
        printf("skipped: Blender is not installed (this case opens the .glb with `blender -b`)\n");
        hl_test_skipped = 1;
        return;
    }
    hl_context *ctx = hl_test_ref_context(1);
    hl_mesh *m = small_mesh(ctx);
    if (!m) return;
    float *rgb = malloc((size_t)m->vertex_count * 12);
    colours(m->vertex_count, rgb);
    const char *path = hl_test_tmp_path("gltf_blender.glb");
    HL_CHECK(hl_mesh_save_glb(ctx, m, rgb, path, 0.0f) == HL_OK, "save: %s", hl_context_last_error(ctx));
    char cmd[2048];
    snprintf(cmd, sizeof cmd,
             "blender -b --factory-startup --python-expr \"import bpy,sys; bpy.ops.wm.read_factory_settings(use_empty=True); "
             "bpy.ops.import_scene.gltf(filepath='%s'); "
             "n=sum(len(o.data.vertices) for o in bpy.data.objects if o.type=='MESH'); print('VERTICES', n); "
             "sys.exit(0 if n == %u else 3)\" >/dev/null 2>&1",
             path, m->vertex_count);
    HL_CHECK(system(cmd) == 0, "Blender did not import %s with %u vertices", path, m->vertex_count);
    free(rgb);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"roundtrip", case_roundtrip}, {"bad", case_bad}, {"blender", case_blender}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
