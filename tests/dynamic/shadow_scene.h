/* shadow_scene.h - the scene and helpers of the shadow-map tests
 * (test_shadow_raster.c, test_shadow_skip.c): the bunny on a ground of
 * GROUND_N x GROUND_N quads as two objects, fixed and random light
 * directions, rigid transforms, rendering K maps and comparing two sets.
 * Depends on: hl_test.h, shadow_map.h, HL_REPO_DATA (bunny_lowres.obj).
 */
#ifndef HL_TEST_SHADOW_SCENE_H
#define HL_TEST_SHADOW_SCENE_H

#include <stdint.h>

#include "hl_test.h"
#include "shadow_map.h"

#define R_TEST 256u

/* ---------------------------------------------------------------- scene */

/* The bunny and a ground of GROUND_N x GROUND_N quads under it, as two
 * objects with identity transforms. */
#define GROUND_N 96u

typedef struct scene {
    hl_mesh *bunny;
    float *gpos;
    uint32_t *gtri;
    hl_dyn_object obj[2];
} scene;

static const float XF_ID[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

static inline hl_context *ref_ctx(void) { return hl_test_ref_context(2); }


static inline int scene_load(hl_context *ctx, scene *s)
{
    memset(s, 0, sizeof *s);
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    if (hl_mesh_load(ctx, path, NULL, &s->bunny, NULL) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(ctx));
        return 0;
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v = 0; v < s->bunny->vertex_count; v++)
        for (int c = 0; c < 3; c++) {
            lo[c] = fminf(lo[c], s->bunny->positions[3 * v + c]);
            hi[c] = fmaxf(hi[c], s->bunny->positions[3 * v + c]);
        }
    const uint32_t n = GROUND_N + 1;
    float half = 0.75f * fmaxf(hi[0] - lo[0], hi[2] - lo[2]), cx = 0.5f * (lo[0] + hi[0]), cz = 0.5f * (lo[2] + hi[2]);
    s->gpos = malloc((size_t)n * n * 12);
    s->gtri = malloc((size_t)GROUND_N * GROUND_N * 24);
    for (uint32_t j = 0; j < n; j++)
        for (uint32_t i = 0; i < n; i++) {
            float *p = s->gpos + 3 * (size_t)(j * n + i);
            p[0] = cx - half + 2.0f * half * (float)i / (float)GROUND_N;
            p[1] = lo[1];
            p[2] = cz - half + 2.0f * half * (float)j / (float)GROUND_N;
        }
    for (uint32_t j = 0; j < GROUND_N; j++)
        for (uint32_t i = 0; i < GROUND_N; i++) {
            uint32_t a = j * n + i, *t = s->gtri + 6 * (size_t)(j * GROUND_N + i);
            t[0] = a; t[1] = a + n; t[2] = a + 1;
            t[3] = a + 1; t[4] = a + n; t[5] = a + n + 1;
        }
    s->obj[0] = (hl_dyn_object){.pos = s->bunny->positions, .nverts = s->bunny->vertex_count, .tri = s->bunny->indices,
                                .ntris = s->bunny->triangle_count};
    s->obj[1] = (hl_dyn_object){.pos = s->gpos, .nverts = n * n, .tri = s->gtri, .ntris = 2 * GROUND_N * GROUND_N};
    memcpy(s->obj[0].xf, XF_ID, 48);
    memcpy(s->obj[1].xf, XF_ID, 48);
    return 1;
}

static inline void scene_free(scene *s)
{
    hl_mesh_destroy(s->bunny);
    free(s->gpos); free(s->gtri);
}

static inline void unit3(float *d)
{
    double n = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
    for (int c = 0; c < 3; c++) d[c] = (float)(d[c] / n);
}

/* Lights: +Y, -Y, a grazing one, one on the horizon, then random ones. */
static inline void light_dirs(float (*d)[3], uint32_t K)
{
    static const float fixed[4][3] = {{0, 1, 0}, {0, -1, 0}, {0.6f, 0.02f, 0.8f}, {-1, 0, 0}};
    for (uint32_t k = 0; k < K; k++) {
        if (k < 4) memcpy(d[k], fixed[k], 12);
        else
            do {
                for (int c = 0; c < 3; c++) d[k][c] = (float)((double)(hl_rng_next() >> 11) / 9007199254740992.0 * 2.0 - 1.0);
            } while (d[k][0] * d[k][0] + d[k][1] * d[k][1] + d[k][2] * d[k][2] < 0.01f);
        unit3(d[k]);
    }
}

/* A rotation by angle about unit axis a, then a translation t. */
static inline void make_xf(const double *a, double angle, const double *t, float *xf)
{
    double c = cos(angle), s = sin(angle), C = 1.0 - c;
    double R[9] = {c + a[0] * a[0] * C,        a[0] * a[1] * C - a[2] * s, a[0] * a[2] * C + a[1] * s,
                   a[1] * a[0] * C + a[2] * s, c + a[1] * a[1] * C,        a[1] * a[2] * C - a[0] * s,
                   a[2] * a[0] * C - a[1] * s, a[2] * a[1] * C + a[0] * s, c + a[2] * a[2] * C};
    for (int r = 0; r < 3; r++) {
        for (int k = 0; k < 3; k++) xf[4 * r + k] = (float)R[3 * r + k];
        xf[4 * r + 3] = (float)t[r];
    }
}

static inline float *render(hl_context *ctx, const hl_dyn_object *obj, uint32_t nobj, hl_shadow_method m, const float (*dirs)[3],
                     uint32_t K, hl_shadow_frame *frames)
{
    hl_shadow_maps *sm = NULL;
    float *depth = malloc((size_t)K * R_TEST * R_TEST * 4);
    if (hl_shadow_maps_create(ctx, obj, nobj, R_TEST, m, &sm) != HL_OK ||
        hl_shadow_maps_render(sm, dirs, K, depth, frames) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(ctx));
        free(depth);
        depth = NULL;
    }
    hl_shadow_maps_destroy(sm);
    return depth;
}

/* Compares two sets of K maps: texels covered by one only, and the worst
 * depth difference where both are covered. */
static inline void compare_maps(const float *a, const float *b, size_t n, size_t *mismatch, double *worst, size_t *covered)
{
    *mismatch = 0;
    *worst = 0.0;
    *covered = 0;
    for (size_t i = 0; i < n; i++) {
        int ca = a[i] < HL_SHADOW_EMPTY, cb = b[i] < HL_SHADOW_EMPTY;
        if (ca != cb) { (*mismatch)++; continue; }
        if (!ca) continue;
        (*covered)++;
        double e = fabs((double)a[i] - (double)b[i]);
        if (!(e <= *worst)) *worst = e;
    }
}

#endif
