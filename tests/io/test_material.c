/* test_material.c - albedo from a file's materials (suite "material",
 * host/src/io/material.c through hl_mesh_load and the dynamic scenes).
 *
 * Cases:
 *   factor    three primitives: two materials' base-colour factors, one
 *             without a material (the load's albedo); each vertex's albedo
 *             is its material's factor to the float.
 *   colors    COLOR_0 times the factor, per vertex.
 *   texture   a 4 x 4 grid of quads, each with its own four vertices (so
 *             the file has a UV seam everywhere), textured with four
 *             quadrants of distinct colours: the vertices weld to 25, and
 *             each vertex's albedo is the texture's hat-weighted average
 *             over its neighbourhood, against this file's own fine
 *             integration of the texture (bilinear, repeating, sRGB
 *             decoded); the quadrants land where the UVs put them.
 *   render    a picture with the textured surface shows the factor times
 *             the texture at each pixel's UV; a surface for another mesh
 *             is refused.
 *   glb       .glb output with the surface read back: the texture embedded
 *             as it was, UVs, unlit materials, COLOR_0 the base colour x
 *             the irradiance where textured; and a file whose every
 *             triangle is textured.
 *   dynamic   the dynamic method's scene from the same file holds the same
 *             albedo at the same positions.
 *   dynamic_surface  an animated file's bodies keep their textured
 *             surface (hl_dynamic_surface), corner for corner.
 *   bad       a texture not found, or in a format the decoder does not
 *             read, is left out (the factor alone); one named by a path on
 *             another machine is found beside the model; a damaged one, one
 *             of absurd size and a non-finite factor (OBJ/MTL) are refused,
 *             naming the model and the texture; a missing normal texture
 *             only warns.
 * Depends on: haarlight.h (hl_mesh_load, hl_image_save, hl_dynamic_*),
 * hl_test.h, libc.
 */
#define _POSIX_C_SOURCE 200809L
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

/* ---------------------------------------------------------------- a glTF writer */

typedef struct prim {
    uint32_t nv, nt;
    const float *pos, *uv, *col; /* uv, col may be NULL */
    const uint32_t *idx;
    int material; /* -1: none */
} prim;

typedef struct blob {
    unsigned char *p;
    size_t n, cap;
} blob;

static size_t put(blob *b, const void *src, size_t n)
{
    while (b->n + n > b->cap) {
        b->cap = b->cap ? 2 * b->cap : 4096;
        b->p = realloc(b->p, b->cap);
    }
    size_t at = b->n;
    memcpy(b->p + at, src, n);
    b->n += n;
    return at;
}

static void base64(FILE *f, const unsigned char *p, size_t n)
{
    static const char a[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (size_t i = 0; i < n; i += 3) {
        unsigned v = (unsigned)p[i] << 16 | (i + 1 < n ? (unsigned)p[i + 1] << 8 : 0) | (i + 2 < n ? p[i + 2] : 0);
        fputc(a[v >> 18 & 63], f);
        fputc(a[v >> 12 & 63], f);
        fputc(i + 1 < n ? a[v >> 6 & 63] : '=', f);
        fputc(i + 2 < n ? a[v & 63] : '=', f);
    }
}

/* Set: write_gltf gives node 0 a translation animation, from (0, 0, 0)
 * at 0 s to (2, 0, 0) at 1 s. */
static int animate;

/* materials: the JSON of the "materials" array's members (NULL: none);
 * images: the JSON of "images" (NULL: none; textures i use image i). */
static void write_gltf(const char *path, const prim *pr, int np, const char *materials, const char *images, int ntex)
{
    blob b = {0};
    char acc[8192] = "", views[8192] = "", meshes[8192] = "";
    int na = 0;
    for (int i = 0; i < np; i++) {
        const prim *q = &pr[i];
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t v = 0; v < q->nv; v++)
            for (int k = 0; k < 3; k++) {
                lo[k] = fminf(lo[k], q->pos[3 * v + k]);
                hi[k] = fmaxf(hi[k], q->pos[3 * v + k]);
            }
        const void *data[4] = {q->pos, q->uv, q->col, q->idx};
        const size_t bytes[4] = {q->nv * 12u, q->nv * 8u, q->nv * 12u, q->nt * 12u};
        int id[4] = {-1, -1, -1, -1};
        for (int a = 0; a < 4; a++) {
            if (!data[a]) continue;
            size_t at = put(&b, data[a], bytes[a]);
            char s[512];
            snprintf(s, sizeof s, "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}", na ? "," : "", at, bytes[a]);
            strcat(views, s);
            if (a == 0)
                snprintf(s, sizeof s, ",{\"bufferView\":%d,\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\",\"min\":[%g,%g,%g],\"max\":[%g,%g,%g]}",
                         na, q->nv, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
            else
                snprintf(s, sizeof s, ",{\"bufferView\":%d,\"componentType\":%d,\"count\":%u,\"type\":\"%s\"}", na,
                         a == 3 ? 5125 : 5126, a == 3 ? 3 * q->nt : q->nv, a == 1 ? "VEC2" : a == 3 ? "SCALAR" : "VEC3");
            strcat(acc, na ? s : s + 1);
            id[a] = na++;
        }
        char s[512], attr[256];
        snprintf(attr, sizeof attr, "\"POSITION\":%d", id[0]);
        if (id[1] >= 0) snprintf(attr + strlen(attr), sizeof attr - strlen(attr), ",\"TEXCOORD_0\":%d", id[1]);
        if (id[2] >= 0) snprintf(attr + strlen(attr), sizeof attr - strlen(attr), ",\"COLOR_0\":%d", id[2]);
        char mat[32] = "";
        if (q->material >= 0) snprintf(mat, sizeof mat, ",\"material\":%d", q->material);
        snprintf(s, sizeof s, "%s{\"attributes\":{%s},\"indices\":%d%s}", i ? "," : "", attr, id[3], mat);
        strcat(meshes, s);
    }
    int anim_in = -1, anim_out = -1;
    if (animate) {
        const float times[2] = {0, 1}, moves[6] = {0, 0, 0, 2, 0, 0};
        char a[512];
        size_t at = put(&b, times, sizeof times);
        snprintf(a, sizeof a, ",{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":8}", at);
        strcat(views, a);
        snprintf(a, sizeof a, ",{\"bufferView\":%d,\"componentType\":5126,\"count\":2,\"type\":\"SCALAR\",\"min\":[0],\"max\":[1]}", na);
        strcat(acc, a);
        anim_in = na++;
        at = put(&b, moves, sizeof moves);
        snprintf(a, sizeof a, ",{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":24}", at);
        strcat(views, a);
        snprintf(a, sizeof a, ",{\"bufferView\":%d,\"componentType\":5126,\"count\":2,\"type\":\"VEC3\"}", na);
        strcat(acc, a);
        anim_out = na++;
    }
    FILE *f = fopen(path, "w");
    fprintf(f, "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],");
    if (animate)
        fprintf(f, "\"animations\":[{\"name\":\"slide\",\"samplers\":[{\"input\":%d,\"output\":%d}],"
                   "\"channels\":[{\"sampler\":0,\"target\":{\"node\":0,\"path\":\"translation\"}}]}],",
                anim_in, anim_out);
    fprintf(f, "\"meshes\":[{\"primitives\":[%s]}],\"accessors\":[%s],\"bufferViews\":[%s],", meshes, acc, views);
    if (materials) fprintf(f, "\"materials\":[%s],", materials);
    if (images) {
        fprintf(f, "\"images\":[%s],\"textures\":[", images);
        for (int t = 0; t < ntex; t++) fprintf(f, "%s{\"source\":%d}", t ? "," : "", t);
        fprintf(f, "],");
    }
    fprintf(f, "\"buffers\":[{\"byteLength\":%zu,\"uri\":\"data:application/octet-stream;base64,", b.n);
    base64(f, b.p, b.n);
    fprintf(f, "\"}]}\n");
    fclose(f);
    free(b.p);
}

/* A unit quad in the xz plane at height y (two triangles), UVs [0, 1]. */
static const float quad_uv[] = {0, 0, 1, 0, 1, 1, 0, 1};
static const uint32_t quad_idx[] = {0, 1, 2, 0, 2, 3};
static void quad_at(float x, float y, float *pos)
{
    const float c[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (int v = 0; v < 4; v++) {
        pos[3 * v] = x + c[v][0];
        pos[3 * v + 1] = y;
        pos[3 * v + 2] = -c[v][1];
    }
}

static hl_mesh *load(hl_context *ctx, const char *path, float albedo)
{
    hl_mesh_load_desc d = {.albedo = {albedo, albedo, albedo}};
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_load(ctx, path, &d, &m, NULL);
    HL_CHECK(r == HL_OK, "load %s: %s", path, hl_context_last_error(ctx));
    return r == HL_OK ? m : NULL;
}

/* ---------------------------------------------------------------- factor, colours */

static void case_factor(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    const char *path = hl_test_tmp_path("material_factor.gltf");
    float pos[3][12];
    for (int i = 0; i < 3; i++) quad_at(2.0f * (float)i, 0.0f, pos[i]);
    prim pr[3];
    for (int i = 0; i < 3; i++) pr[i] = (prim){4, 2, pos[i], NULL, NULL, quad_idx, i < 2 ? i : -1};
    const float f[2][3] = {{0.2f, 0.4f, 0.6f}, {0.9f, 0.1f, 0.3f}};
    char mats[512];
    snprintf(mats, sizeof mats,
             "{\"name\":\"a\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[%.9g,%.9g,%.9g,1]}},"
             "{\"name\":\"b\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[%.9g,%.9g,%.9g,1]}}",
             f[0][0], f[0][1], f[0][2], f[1][0], f[1][1], f[1][2]);
    write_gltf(path, pr, 3, mats, NULL, 0);
    for (int pass = 0; pass < 2; pass++) {
        const float fallback = pass ? 0.5f : 0.0f; /* 0: the default, 0.8 */
        hl_mesh *m = load(ctx, path, fallback);
        if (!m) continue;
        HL_CHECK(m->vertex_count == 12, "%u vertices, 12 expected", m->vertex_count);
        double worst = 0.0;
        for (uint32_t v = 0; v < m->vertex_count; v++) {
            int q = (int)floorf(m->positions[3 * v] / 2.0f + 0.25f); /* which quad */
            for (int k = 0; k < 3; k++) {
                float want = q < 2 ? f[q][k] : (pass ? 0.5f : 0.8f);
                worst = fmax(worst, fabs((double)m->albedo[3 * v + k] - want));
            }
        }
        char what[96];
        snprintf(what, sizeof what, "albedo against the factors (no material: %g)", pass ? 0.5 : 0.8);
        hl_check_error(what, worst, 0.0);
        hl_mesh_destroy(m);
    }
    hl_context_destroy(ctx);
}

static void case_colors(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    const char *path = hl_test_tmp_path("material_colors.gltf");
    float pos[12], col[12];
    quad_at(0, 0, pos);
    for (int v = 0; v < 4; v++)
        for (int k = 0; k < 3; k++) col[3 * v + k] = 0.25f * (float)(v + 1) * (k == 1 ? 0.5f : 1.0f);
    prim pr = {4, 2, pos, NULL, col, quad_idx, 0};
    write_gltf(path, &pr, 1, "{\"name\":\"m\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.75,0.25,1]}}",
               NULL, 0);
    hl_mesh *m = load(ctx, path, 0.0f);
    if (m) {
        const float f[3] = {0.5f, 0.75f, 0.25f};
        double worst = 0.0;
        for (uint32_t v = 0; v < m->vertex_count; v++) {
            int fv = -1; /* the file's vertex at this position */
            for (int u = 0; u < 4; u++)
                if (pos[3 * u] == m->positions[3 * v] && pos[3 * u + 2] == m->positions[3 * v + 2]) fv = u;
            HL_CHECK(fv >= 0, "vertex %u is at no file vertex", v);
            for (int k = 0; fv >= 0 && k < 3; k++)
                worst = fmax(worst, fabs((double)m->albedo[3 * v + k] - (double)(f[k] * col[3 * fv + k])));
        }
        hl_check_error("albedo against COLOR_0 x the factor", worst, 1e-7);
        hl_mesh_destroy(m);
    }
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- texture */

#define TEX 32
#define GRID 4
/* sRGB codes of the quadrants: top-left, top-right, bottom-left, bottom-right */
static const float quadrant[4][3] = {{0.9f, 0.1f, 0.1f}, {0.1f, 0.8f, 0.2f}, {0.1f, 0.2f, 0.9f}, {0.7f, 0.7f, 0.7f}};

static double srgb_decode(double c)
{
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

/* The texture as written: linear values whose PNG codes are known. */
static void texel(int x, int y, const hl_image *img, double out[3])
{
    for (int k = 0; k < 3; k++)
        out[k] = srgb_decode(hl_tonemap_srgb8(img->rgb[3 * ((size_t)y * TEX + x) + k], 0.0f) / 255.0);
}

/* The test's own bilinear, repeating lookup, in glTF's convention: v = 0
 * at the image's top row. */
static void lookup(const hl_image *img, double u, double v, double out[3])
{
    double x = u * TEX - 0.5, y = v * TEX - 0.5, fx = floor(x), fy = floor(y), ax = x - fx, ay = y - fy;
    double t[4][3];
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++)
            texel((((int)fx + i) % TEX + TEX) % TEX, (((int)fy + j) % TEX + TEX) % TEX, img, t[2 * j + i]);
    for (int k = 0; k < 3; k++)
        out[k] = (1 - ay) * ((1 - ax) * t[0][k] + ax * t[1][k]) + ay * ((1 - ax) * t[2][k] + ax * t[3][k]);
}

static void case_texture(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_image *img = NULL;
    HL_CHECK(hl_image_create(ctx, TEX, TEX, &img) == HL_OK, "image");
    if (!img) return;
    for (int y = 0; y < TEX; y++)
        for (int x = 0; x < TEX; x++) {
            int q = (y >= TEX / 2) * 2 + (x >= TEX / 2);
            for (int k = 0; k < 3; k++) /* linear values of the sRGB codes */
                img->rgb[3 * ((size_t)y * TEX + x) + k] = (float)srgb_decode(quadrant[q][k]);
        }
    const char *png = hl_test_tmp_path("material tex.png"); /* a space: the URI is percent-encoded */
    HL_CHECK(hl_image_save(ctx, img, png, 0.0f) == HL_OK, "png: %s", hl_context_last_error(ctx));
    /* GRID x GRID quads of size 1/GRID in UV and 1 in space, each with
       its own four vertices */
    enum { NQ = GRID * GRID };
    float pos[NQ * 12], uv[NQ * 8];
    uint32_t idx[NQ * 6];
    for (int j = 0; j < GRID; j++)
        for (int i = 0; i < GRID; i++) {
            int q = j * GRID + i;
            quad_at((float)i, 0.0f, pos + 12 * q);
            for (int v = 0; v < 4; v++) {
                pos[12 * q + 3 * v + 2] -= (float)j;
                uv[8 * q + 2 * v] = ((float)i + quad_uv[2 * v]) / GRID;
                uv[8 * q + 2 * v + 1] = ((float)j + quad_uv[2 * v + 1]) / GRID;
            }
            for (int c = 0; c < 6; c++) idx[6 * q + c] = 4u * (uint32_t)q + quad_idx[c];
        }
    prim pr = {NQ * 4, NQ * 2, pos, uv, NULL, idx, 0};
    const char *path = hl_test_tmp_path("material_texture.gltf");
    write_gltf(path, &pr, 1,
               "{\"name\":\"t\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[1,0.5,1,1],"
               "\"baseColorTexture\":{\"index\":0}}}",
               "{\"uri\":\"material%20tex.png\"}", 1);
    hl_mesh *m = load(ctx, path, 0.0f);
    if (m) {
        HL_CHECK(m->vertex_count == (GRID + 1) * (GRID + 1), "%u vertices after welding the UV seams, %d expected",
                 m->vertex_count, (GRID + 1) * (GRID + 1));
        /* reference: the hat function of the vertex over the quads around
           it, integrated on a fine grid of each triangle */
        enum { FINE = 240 };
        double worst = 0.0, worst_q = 0.0;
        for (uint32_t v = 0; v < m->vertex_count; v++) {
            double vx = m->positions[3 * v], vz = -m->positions[3 * v + 2];
            double acc[3] = {0, 0, 0}, w = 0.0;
            for (int q = 0; q < NQ; q++)
                for (int t = 0; t < 2; t++) {
                    const uint32_t *c = idx + 6 * q + 3 * t;
                    int corner = -1;
                    for (int k = 0; k < 3; k++)
                        if (pos[3 * c[k]] == vx && -pos[3 * c[k] + 2] == vz) corner = k;
                    if (corner < 0) continue;
                    for (int a = 0; a < FINE; a++)
                        for (int bb = 0; a + bb < FINE; bb++) {
                            double l1 = (a + 1.0 / 3) / FINE, l2 = (bb + 1.0 / 3) / FINE, l[3] = {1 - l1 - l2, l1, l2};
                            double su = 0, sv = 0, rgb[3];
                            for (int k = 0; k < 3; k++) {
                                su += l[k] * uv[2 * c[k]];
                                sv += l[k] * uv[2 * c[k] + 1];
                            }
                            lookup(img, su, sv, rgb);
                            for (int k = 0; k < 3; k++) acc[k] += l[corner] * rgb[k];
                            w += l[corner];
                        }
                }
            const double factor[3] = {1.0, 0.5, 1.0};
            for (int k = 0; k < 3; k++)
                worst = fmax(worst, fabs(m->albedo[3 * v + k] - factor[k] * acc[k] / w));
            /* a vertex inside a quadrant has its colour there */
            int gx = (int)lround(vx), gz = (int)lround(vz);
            if (gx % 2 == 1 && gz % 2 == 1) {
                int q = (gz < GRID / 2 ? 0 : 2) + (gx >= GRID / 2); /* v = 0 is the top row */
                for (int k = 0; k < 3; k++)
                    worst_q = fmax(worst_q, fabs(m->albedo[3 * v + k] - factor[k] * srgb_decode(quadrant[q][k])));
            }
        }
        hl_check_error("vertex albedo against the fine hat-weighted average of the texture", worst, 4e-3);
        hl_check_error("albedo of the quadrants' inner vertices against their colours", worst_q, 0.03);
        hl_mesh_destroy(m);
    }
    hl_image_destroy(img);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- render */

/* A textured quad seen from above: each pixel that hits it shows the
 * factor times the texture at the hit's UV (the colours given are the
 * albedo itself: irradiance 1), from the test's own ray-plane
 * intersection and lookup; another mesh is refused by hl_surface_load. */
static void case_render(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_image *img = NULL;
    hl_image_create(ctx, TEX, TEX, &img);
    for (int y = 0; y < TEX; y++)
        for (int x = 0; x < TEX; x++)
            for (int k = 0; k < 3; k++)
                img->rgb[3 * ((size_t)y * TEX + x) + k] = (float)srgb_decode(0.1 + 0.8 * ((x * 7 + y * 3 + k * 5) % 11) / 10.0);
    HL_CHECK(hl_image_save(ctx, img, hl_test_tmp_path("material_render.png"), 0.0f) == HL_OK, "png");
    float pos[12];
    quad_at(0, 0, pos);
    prim pr = {4, 2, pos, quad_uv, NULL, quad_idx, 0};
    const char *path = hl_test_tmp_path("material_render.gltf");
    write_gltf(path, &pr, 1,
               "{\"name\":\"r\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,1,0.75,1],"
               "\"baseColorTexture\":{\"index\":0}}}",
               "{\"uri\":\"material_render.png\"}", 1);
    hl_mesh *m = load(ctx, path, 0.0f);
    hl_surface *su = NULL;
    hl_result r = m ? hl_surface_load(ctx, path, NULL, m, &su) : HL_ERR_MESH;
    HL_CHECK(r == HL_OK && hl_surface_texture_count(su) == 1, "surface: %s", hl_context_last_error(ctx));
    if (su) {
        hl_camera_desc cd = {.width = 64, .height = 64, .fov_deg = 30, .eye = {0.5f, 3, -0.5f},
                             .target = {0.5f, 0, -0.5f}, .up = {0, 0, -1}};
        hl_image *pic = NULL;
        r = hl_render_surface(ctx, m, m->albedo, su, NULL, 0.0f, &cd, &pic);
        HL_CHECK(r == HL_OK, "render: %s", hl_context_last_error(ctx));
        hl_camera_view cv;
        hl_camera_query_view(ctx, m, &cd, &cv);
        double worst = 0.0;
        int inside = 0;
        for (uint32_t y = 0; pic && y < cv.height; y++)
            for (uint32_t x = 0; x < cv.width; x++) {
                double sx = 2.0 * (x + 0.5) / cv.width - 1.0, sy = 1.0 - 2.0 * (y + 0.5) / cv.height, d[3];
                for (int k = 0; k < 3; k++) d[k] = cv.forward[k] + sx * cv.tan_half_x * cv.right[k] + sy * cv.tan_half_y * cv.up[k];
                double t = -cv.eye[1] / d[1], hx = cv.eye[0] + t * d[0], hz = cv.eye[2] + t * d[2];
                double u = hx, v = -hz; /* quad_at's corners (x, -z) carry UVs (x, -z) */
                if (u < 0.01 || u > 0.99 || v < 0.01 || v > 0.99) continue;
                double want[3];
                lookup(img, u, v, want);
                const double factor[3] = {0.5, 1.0, 0.75};
                for (int k = 0; k < 3; k++)
                    worst = fmax(worst, fabs(pic->rgb[3 * ((size_t)y * cv.width + x) + k] - factor[k] * want[k]));
                inside++;
            }
        HL_CHECK(inside > 1000, "only %d pixels on the quad", inside);
        hl_check_error("textured pixels against the factor x the texture at their UV", worst, 1e-5);
        hl_image_destroy(pic);
        /* another mesh */
        float other[12];
        quad_at(0, 0.25f, other);
        hl_mesh *o = NULL;
        const uint32_t other_idx[6] = {0, 1, 3, 1, 2, 3}; /* the other diagonal */
        hl_mesh_create(ctx, 4, other, NULL, NULL, 2, other_idx, &o);
        hl_surface *bad = NULL;
        r = hl_surface_load(ctx, path, NULL, o, &bad);
        HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && !bad && strstr(hl_context_last_error(ctx), path),
                 "a surface for another mesh: %d %s", (int)r, hl_context_last_error(ctx));
        printf("refused as expected: %s\n", hl_context_last_error(ctx));
        hl_mesh_destroy(o);
    }
    hl_surface_destroy(su);
    hl_mesh_destroy(m);
    hl_image_destroy(img);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- glb */

/* A textured quad and an untextured one written as .glb with their
 * surface, colours twice the albedo (irradiance 2), and read back with
 * assimp: the texture embedded byte for byte, the textured primitive's
 * material unlit with it as base colour, its UVs those of the file, its
 * COLOR_0 the base colour x 2; the other primitive's COLOR_0 the
 * colours as written. */
static void case_glb(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_image *img = NULL;
    hl_image_create(ctx, 8, 8, &img);
    for (int i = 0; i < 8 * 8 * 3; i++) img->rgb[i] = 0.02f * (float)(i % 37);
    const char *png = hl_test_tmp_path("material_glb.png");
    HL_CHECK(hl_image_save(ctx, img, png, 0.0f) == HL_OK, "png");
    hl_image_destroy(img);
    float pos[2][12];
    quad_at(0, 0, pos[0]);
    quad_at(2, 0, pos[1]);
    prim pr[2] = {{4, 2, pos[0], quad_uv, NULL, quad_idx, 0}, {4, 2, pos[1], NULL, NULL, quad_idx, 1}};
    const char *path = hl_test_tmp_path("material_glb.gltf");
    write_gltf(path, pr, 2,
               "{\"name\":\"t\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.25,1,1],"
               "\"baseColorTexture\":{\"index\":0}}},"
               "{\"name\":\"u\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.3,0.6,0.9,1]}}",
               "{\"uri\":\"material_glb.png\"}", 1);
    hl_mesh *m = load(ctx, path, 0.0f);
    hl_surface *su = NULL;
    if (m) HL_CHECK(hl_surface_load(ctx, path, NULL, m, &su) == HL_OK, "surface: %s", hl_context_last_error(ctx));
    const char *out = hl_test_tmp_path("material_out.glb");
    if (su) {
        float *rgb = malloc((size_t)m->vertex_count * 12);
        for (uint32_t i = 0; i < 3 * m->vertex_count; i++) rgb[i] = 2.0f * m->albedo[i];
        HL_CHECK(hl_mesh_save_glb_surface(ctx, m, rgb, su, out, 0.0f) == HL_OK, "save: %s", hl_context_last_error(ctx));
        const struct aiScene *s = aiImportFile(out, 0);
        HL_CHECK(s && s->mNumTextures == 1 && s->mNumMeshes == 2, "read back %s: %s", out, s ? "" : aiGetErrorString());
        if (s && s->mNumTextures == 1 && s->mNumMeshes == 2) {
            size_t n = 0;
            uint8_t *bytes = hl_test_read_file(png, &n);
            const struct aiTexture *t = s->mTextures[0];
            HL_CHECK(t->mHeight == 0 && t->mWidth == n && bytes && !memcmp(t->pcData, bytes, n),
                     "the texture is the PNG as it was (%u bytes, %zu in the file)", t->mWidth, n);
            free(bytes);
            double uv_err = 0.0, c0_err = 0.0, plain_err = 0.0;
            int textured = 0;
            for (unsigned k = 0; k < s->mNumMeshes; k++) {
                const struct aiMesh *am = s->mMeshes[k];
                const struct aiMaterial *mat = s->mMaterials[am->mMaterialIndex];
                int shading = 0;
                aiGetMaterialIntegerArray(mat, AI_MATKEY_SHADING_MODEL, &shading, NULL);
                HL_CHECK(shading == aiShadingMode_Unlit, "primitive %u's material is unlit (%d)", k, shading);
                struct aiString tp;
                const int has_tex = aiGetMaterialTexture(mat, aiTextureType_BASE_COLOR, 0, &tp, NULL, NULL, NULL, NULL,
                                                         NULL, NULL) == aiReturn_SUCCESS;
                HL_CHECK(has_tex == (am->mTextureCoords[0] != NULL), "primitive %u: texture %d, UVs %d", k, has_tex,
                         am->mTextureCoords[0] != NULL);
                textured += has_tex;
                for (unsigned v = 0; v < am->mNumVertices; v++) {
                    const float x = am->mVertices[v].x, z = am->mVertices[v].z;
                    if (has_tex) { /* quad_at's corner (x, -z) has UV (x, -z) in glTF's convention */
                        uv_err = fmax(uv_err, fabs(am->mTextureCoords[0][v].x - x));
                        uv_err = fmax(uv_err, fabs((1.0f - am->mTextureCoords[0][v].y) - (-z)));
                        const float want[3] = {1.0f, 0.5f, 2.0f}; /* the factor x 2 */
                        const float *c = &am->mColors[0][v].r;
                        for (int ch = 0; ch < 3; ch++) c0_err = fmax(c0_err, fabs(c[ch] - want[ch]));
                    } else {
                        const float want[3] = {0.6f, 1.2f, 1.8f};
                        const float *c = &am->mColors[0][v].r;
                        for (int ch = 0; ch < 3; ch++) plain_err = fmax(plain_err, fabs(c[ch] - want[ch]));
                    }
                }
            }
            HL_CHECK(textured == 1, "%d textured primitives, 1 expected", textured);
            hl_check_error("UVs read back (assimp's convention, v up)", uv_err, 1e-7);
            hl_check_error("textured COLOR_0 against the base colour x the irradiance", c0_err, 1e-6);
            hl_check_error("untextured COLOR_0 against the colours written", plain_err, 1e-6);
        }
        if (s) aiReleaseImport(s);
        free(rgb);
    }
    hl_surface_destroy(su);
    hl_mesh_destroy(m);
    /* every triangle textured: no untextured primitive to write */
    const char *only = hl_test_tmp_path("material_glb_only.gltf");
    write_gltf(only, pr, 1, "{\"name\":\"t\",\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}",
               "{\"uri\":\"material_glb.png\"}", 1);
    m = load(ctx, only, 0.0f);
    su = NULL;
    if (m && hl_surface_load(ctx, only, NULL, m, &su) == HL_OK) {
        const char *out2 = hl_test_tmp_path("material_out_only.glb");
        hl_result r = hl_mesh_save_glb_surface(ctx, m, m->albedo, su, out2, 0.0f);
        HL_CHECK(r == HL_OK, "a .glb whose every triangle is textured: %s", hl_context_last_error(ctx));
        const struct aiScene *s2 = r == HL_OK ? aiImportFile(out2, aiProcess_ValidateDataStructure) : NULL;
        HL_CHECK(s2 && s2->mNumMeshes == 1 && s2->mNumTextures == 1 && s2->mMeshes[0]->mTextureCoords[0],
                 "read back: one textured mesh (%s)", s2 ? "" : aiGetErrorString());
        if (s2) aiReleaseImport(s2);
    } else
        HL_CHECK(0, "surface: %s", hl_context_last_error(ctx));
    hl_surface_destroy(su);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- dynamic */

/* An animated file, moved body by body: hl_dynamic_surface gives the
 * bodies' textured surface for the merged mesh, each textured corner's
 * UV the file's at that corner (quad_at's UV is (x, -z), assimp's v up),
 * and the ground's triangles none. */
static void case_dynamic_surface(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_image *img = NULL;
    hl_image_create(ctx, 4, 4, &img);
    for (int i = 0; i < 48; i++) img->rgb[i] = 0.02f * (float)i;
    HL_CHECK(hl_image_save(ctx, img, hl_test_tmp_path("material_anim.png"), 0.0f) == HL_OK, "png");
    hl_image_destroy(img);
    float pos[12];
    quad_at(0, 0, pos);
    prim pr = {4, 2, pos, quad_uv, NULL, quad_idx, 0};
    const char *path = hl_test_tmp_path("material_anim.gltf");
    animate = 1;
    write_gltf(path, &pr, 1, "{\"name\":\"t\",\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}",
               "{\"uri\":\"material_anim.png\"}", 1);
    animate = 0;
    hl_dynamic *d = NULL;
    HL_CHECK(hl_dynamic_create_from_file(ctx, path, HL_DYNAMIC_GROUND, NULL, &d) == HL_OK, "%s",
             hl_context_last_error(ctx));
    const hl_surface *su = d ? hl_dynamic_surface(d) : NULL;
    HL_CHECK(su && hl_surface_texture_count(su) == 1, "the bodies' surface has %u textures",
             hl_surface_texture_count(su));
    if (su) {
        const hl_mesh *m = hl_dynamic_mesh(d);
        HL_CHECK(hl_surface_triangle_count(su) == m->triangle_count, "%u surface triangles for %u",
                 hl_surface_triangle_count(su), m->triangle_count);
        double worst = 0.0;
        uint32_t textured = 0;
        for (uint32_t t = 0; t < m->triangle_count; t++) {
            int32_t k;
            float uv[6];
            hl_surface_triangle(su, t, &k, uv, NULL);
            const int ground = m->indices[3 * (size_t)t] >= m->object_vertex_count;
            HL_CHECK((k >= 0) == !ground, "triangle %u: texture %d, ground %d", t, k, ground);
            if (k < 0) continue;
            textured++;
            for (int c = 0; c < 3; c++) { /* at rest, time 0: where the file has it */
                const float *p = m->positions + 3 * (size_t)m->indices[3 * (size_t)t + (size_t)c];
                worst = fmax(worst, fabs(uv[2 * c] - p[0]));
                worst = fmax(worst, fabs((1.0f - uv[2 * c + 1]) - (-p[2])));
            }
        }
        HL_CHECK(textured == 2, "%u textured triangles, 2 expected", textured);
        hl_check_error("the bodies' corner UVs against the file's", worst, 1e-6);
    }
    hl_dynamic_destroy(d);
    hl_context_destroy(ctx);
}

static void case_dynamic(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    const char *path = hl_test_tmp_path("material_dynamic.gltf");
    float pos[2][12];
    quad_at(0, 0, pos[0]);
    quad_at(2, 0.5f, pos[1]);
    prim pr[2] = {{4, 2, pos[0], quad_uv, NULL, quad_idx, 0}, {4, 2, pos[1], NULL, NULL, quad_idx, 1}};
    hl_image *img = NULL;
    hl_image_create(ctx, 2, 2, &img);
    for (int i = 0; i < 12; i++) img->rgb[i] = 0.05f * (float)(i + 1);
    const char *png = hl_test_tmp_path("material_dynamic.png");
    HL_CHECK(hl_image_save(ctx, img, png, 0.0f) == HL_OK, "png");
    write_gltf(path, pr, 2,
               "{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}},"
               "{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.3,0.6,0.9,1]}}",
               "{\"uri\":\"material_dynamic.png\"}", 1);
    hl_mesh *m = load(ctx, path, 0.0f);
    hl_dynamic *d = NULL;
    hl_result r = hl_dynamic_create_from_file(ctx, path, 0, NULL, &d);
    HL_CHECK(r == HL_OK, "dynamic scene: %s", hl_context_last_error(ctx));
    if (m && d) {
        const hl_mesh *dm = hl_dynamic_mesh(d);
        HL_CHECK(dm->vertex_count == m->vertex_count, "%u and %u vertices", dm->vertex_count, m->vertex_count);
        double worst = 0.0;
        int unmatched = 0;
        for (uint32_t v = 0; v < m->vertex_count; v++) {
            int found = 0;
            for (uint32_t u = 0; u < dm->vertex_count && !found; u++)
                if (dm->positions[3 * u] == m->positions[3 * v] && dm->positions[3 * u + 1] == m->positions[3 * v + 1] &&
                    dm->positions[3 * u + 2] == m->positions[3 * v + 2]) {
                    found = 1;
                    for (int k = 0; k < 3; k++)
                        worst = fmax(worst, fabs((double)dm->albedo[3 * u + k] - m->albedo[3 * v + k]));
                }
            unmatched += !found;
        }
        HL_CHECK(unmatched == 0, "%d vertices of the mesh are not in the dynamic scene", unmatched);
        hl_check_error("dynamic scene's albedo against the loaded mesh's", worst, 0.0);
        double spread = 0.0; /* the texture must have reached it */
        for (uint32_t v = 1; v < dm->vertex_count; v++) spread = fmax(spread, fabs(dm->albedo[3 * v] - dm->albedo[0]));
        HL_CHECK(spread > 0.05, "the albedo varies by %g only", spread);
    }
    hl_dynamic_destroy(d);
    hl_mesh_destroy(m);
    hl_image_destroy(img);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- bad */

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    fwrite(p, 1, n, f);
    fclose(f);
}

static void expect_refusal(hl_context *ctx, const char *path, hl_result want, const char *needle)
{
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
    const char *e = hl_context_last_error(ctx);
    HL_CHECK(r == want && !m && strstr(e, path) && strstr(e, needle), "%s: result %d (want %d), message \"%s\"", path,
             (int)r, (int)want, e);
    printf("refused as expected: %s\n", e);
    hl_mesh_destroy(m);
}

static void case_bad(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    float pos[12];
    quad_at(0, 0, pos);
    prim pr = {4, 2, pos, quad_uv, NULL, quad_idx, 0};
    const char *tex_mat = "{\"name\":\"m\",\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}";
    /* left out, the file loading with the factor alone (here white: no
       material, the default 0.8): a texture not found, one in a format
       the decoder does not read, one named by a path on another machine
       that is not beside the model either */
    const char *p1 = hl_test_tmp_path("material_missing.gltf");
    write_bytes(hl_test_tmp_path("material_other.png"), "this is not a PNG file", 22);
    const char *left[3] = {"{\"uri\":\"no_such_texture.png\"}", "{\"uri\":\"material_other.png\"}",
                           "{\"uri\":\"C:%5Ctextures%5Cno_such.png\"}"};
    for (int k = 0; k < 3; k++) {
        write_gltf(p1, &pr, 1, tex_mat, left[k], 1);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, p1, NULL, &m, NULL);
        double worst = 0.0;
        for (uint32_t v = 0; m && v < 3 * m->vertex_count; v++) worst = fmax(worst, fabs(m->albedo[v] - 0.8f));
        HL_CHECK(r == HL_OK && m && worst == 0.0, "%s: result %d, albedo off 0.8 by %g: %s", left[k], (int)r, worst,
                 hl_context_last_error(ctx));
        hl_mesh_destroy(m);
    }
    /* a texture found beside the model under a path of another machine */
    const char *p6 = hl_test_tmp_path("material_moved.gltf");
    write_gltf(p6, &pr, 1, tex_mat, "{\"uri\":\"D:%5Cassets%5Cmaterial_whole.png\"}", 1);
    hl_image *img = NULL;
    hl_image_create(ctx, 64, 64, &img);
    for (size_t i = 0; i < 64 * 64 * 3; i++) img->rgb[i] = (float)(i % 7) / 7.0f;
    const char *whole = hl_test_tmp_path("material_whole.png");
    hl_image_save(ctx, img, whole, 0.0f);
    hl_image_destroy(img);
    {
        hl_mesh *m = NULL;
        hl_surface *su = NULL;
        hl_result r = hl_mesh_load(ctx, p6, NULL, &m, NULL);
        if (r == HL_OK) r = hl_surface_load(ctx, p6, NULL, m, &su);
        HL_CHECK(r == HL_OK && hl_surface_texture_count(su) == 1, "a texture beside the model, named D:\\...: %s",
                 hl_context_last_error(ctx));
        hl_surface_destroy(su);
        hl_mesh_destroy(m);
    }
    FILE *f = fopen(whole, "rb");
    unsigned char buf[65536];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    write_bytes(hl_test_tmp_path("material_cut.png"), buf, n / 2);
    const char *p3 = hl_test_tmp_path("material_cut.gltf");
    write_gltf(p3, &pr, 1, tex_mat, "{\"uri\":\"material_cut.png\"}", 1);
    expect_refusal(ctx, p3, HL_ERR_FORMAT, "material_cut.png");
    /* absurd size: a PNG whose header claims 16,000 x 16,000 pixels */
    unsigned char big[33] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R',
                             0, 0, 0x3E, 0x80, 0, 0, 0x3E, 0x80, 8, 2, 0, 0, 0};
    uint32_t crc = hl_test_crc32(big + 12, 17);
    for (int k = 0; k < 4; k++) big[29 + k] = (unsigned char)(crc >> (24 - 8 * k));
    write_bytes(hl_test_tmp_path("material_big.png"), big, sizeof big);
    const char *p4 = hl_test_tmp_path("material_big.gltf");
    write_gltf(p4, &pr, 1, tex_mat, "{\"uri\":\"material_big.png\"}", 1);
    expect_refusal(ctx, p4, HL_ERR_FORMAT, "16000 x 16000");
    /* a non-finite factor, from an OBJ's material */
    const char *obj = hl_test_tmp_path("material_nan.obj");
    f = fopen(obj, "w");
    fprintf(f, "mtllib material_nan.mtl\nv 0 0 0\nv 1 0 0\nv 0 0 -1\nusemtl red\nf 1 2 3\n");
    fclose(f);
    f = fopen(hl_test_tmp_path("material_nan.mtl"), "w");
    fprintf(f, "newmtl red\nKd nan 0.5 0.5\n");
    fclose(f);
    expect_refusal(ctx, obj, HL_ERR_FORMAT, "not finite");
    /* a normal texture that is missing: loads, with the base colour texture */
    const char *p5 = hl_test_tmp_path("material_normal.gltf");
    write_gltf(p5, &pr, 1,
               "{\"name\":\"m\",\"normalTexture\":{\"index\":1},\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}",
               "{\"uri\":\"material_whole.png\"},{\"uri\":\"no_such_normals.png\"}", 2);
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_load(ctx, p5, NULL, &m, NULL);
    HL_CHECK(r == HL_OK, "a missing normal texture refused the file: %s", hl_context_last_error(ctx));
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"factor", case_factor},   {"colors", case_colors}, {"texture", case_texture},
                                         {"dynamic", case_dynamic}, {"bad", case_bad},       {"render", case_render}, {"glb", case_glb}, {"dynamic_surface", case_dynamic_surface},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
