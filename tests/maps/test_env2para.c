/* test_env2para.c - the environment to paraboloid resampling of the
 * lighting (kernels/maps/env2para.cl and its plain-C twin
 * host/src/maps/twins/env2para.c), suite "env2para".
 *
 * env2para.twin    the OpenCL stage against the twin at five rotations, a
 *                  one-pixel sun of 1e5 on the map: the same operations in
 *                  the same order.
 * env2para.energy  constant maps stay constant; a one-pixel sun keeps its
 *                  energy.
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL),
 * tests/common/light_util.h.
 */
#include <stdint.h>

#include "cl_backend.h"
#include "geom.h"
#include "half.h"
#include "hl_test.h"
#include "lighting.h"
#include "twins.h"
#include "light_util.h"

static void case_env2para(void)
{
    hl_context *cl = ctx_of(HL_BACKEND_OPENCL), *ref = ctx_of(HL_BACKEND_REFERENCE);
    hl_transport *t = NULL;
    const char *path = make_transport("light_a.hlt", "");
    HL_CHECK(path && hl_transport_load(ref, path, &t) == HL_OK, "transport");
    if (!t || !cl) return;
    hl_geom *g = NULL;
    hl_light_geom *lg = NULL;
    hl_geom_create(ref, t->info.N, t->info.C, &g);
    hl_light_geom_create(ref, g, &lg);
    float *alb = calloc((size_t)t->info.vertex_count, 16);
    hl_cl_light *l = NULL;
    HL_CHECK(hl_cl_light_create(cl, g, lg, t, alb, &l) == HL_OK, "%s", hl_context_last_error(cl));
    const size_t nc = g->ncoef;
    float *a = malloc(nc * 12), *b = malloc(nc * 12), *cells = NULL;
    /* the sun: 1 pixel of 1e5 on a 256 x 128 map */
    hl_env *env = make_env(ref, 256, 77, 30, 1e5f);
    HL_CHECK(hl_env_to_cells(ref, env, lg->wc, lg->hc, &cells) == HL_OK, "cells");
    hl_cl_light_set_cells(l, cells);
    static const float rots[] = {0.0f, 1.0f, 37.3f, -90.0f, 359.99f};
    double worst = 0.0;
    for (size_t i = 0; i < 5; i++) {
        uint32_t s0;
        float f;
        hl_rotation_to_shift(rots[i], lg->wc, &s0, &f);
        hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, s0, f, g->ncoef, a);
        HL_CHECK(hl_cl_light_stage_env2para(l, s0, f, b) == HL_OK, "%s", hl_context_last_error(cl));
        for (size_t k = 0; k < 3 * nc; k++) worst = fmax(worst, fabs((double)a[k] - b[k]) / fmax(1.0, fabs(a[k])));
    }
    /* same operations in the same order */
    hl_check_error("env2para OpenCL vs C (relative)", worst, 1e-6);
    hl_cl_light_destroy(l);
    hl_env_destroy(env);
    hl_free_big(cells);
    free(a); free(b); free(alb);
    hl_light_geom_destroy(lg);
    hl_geom_destroy(g);
    hl_transport_destroy(t);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* Constant maps stay constant; a one-pixel sun keeps its energy. */
static void case_energy(void)
{
    hl_context *ref = ctx_of(HL_BACKEND_REFERENCE);
    static const uint32_t Ns[] = {16, 64};
    for (size_t n = 0; n < 2; n++) {
        hl_geom *g = NULL;
        hl_light_geom *lg = NULL;
        hl_geom_create(ref, Ns[n], 16, &g);
        hl_light_geom_create(ref, g, &lg);
        const size_t nc = g->ncoef;
        float *L = malloc(nc * 12), *cells = NULL;
        /* constant radiance 2.5 */
        uint32_t W = 64;
        float *px = malloc((size_t)W * W / 2 * 12);
        for (size_t i = 0; i < (size_t)W * W / 2 * 3; i++) px[i] = 2.5f;
        hl_env *env = NULL;
        hl_env_create(ref, W, W / 2, px, &env, NULL);
        hl_env_to_cells(ref, env, lg->wc, lg->hc, &cells);
        double worst = 0.0;
        for (float rot = 0.0f; rot < 360.0f; rot += 47.1f) {
            uint32_t s0;
            float f;
            hl_rotation_to_shift(rot, lg->wc, &s0, &f);
            hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, s0, f, (uint32_t)nc, L);
            for (size_t j = 0; j < nc; j++)
                if (g->omega[j] > 0) worst = fmax(worst, fabs(L[j] - 2.5) / 2.5);
        }
        char what[128];
        snprintf(what, sizeof what, "N=%u constant map 2.5 -> every texel 2.5 (relative)", g->N);
        hl_check_error(what, worst, 1e-5);
        hl_env_destroy(env);
        hl_free_big(cells);
        /* a one-pixel sun on a 1024 x 512 map at several rotations: the
           paraboloid energy sum L_j Omega_j against the pixel's */
        W = 1024;
        px = realloc(px, (size_t)W * W / 2 * 12);
        memset(px, 0, (size_t)W * W / 2 * 12);
        int sx = 345, sy = 123;
        for (int c = 0; c < 3; c++) px[3 * ((size_t)sy * W + sx) + c] = 1e6f;
        hl_env_create(ref, W, W / 2, px, &env, NULL);
        double pix = 2.0 * HL_PI / W * (cos(HL_PI * sy / (W / 2)) - cos(HL_PI * (sy + 1) / (W / 2))) * 1e6;
        hl_env_to_cells(ref, env, lg->wc, lg->hc, &cells);
        worst = 0.0;
        for (float rot = 0.0f; rot < 360.0f; rot += 13.7f) {
            uint32_t s0;
            float f;
            hl_rotation_to_shift(rot, lg->wc, &s0, &f);
            hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, s0, f, (uint32_t)nc, L);
            double e = 0.0;
            for (size_t j = 0; j < nc; j++) e += (double)L[j] * g->omega[j];
            worst = fmax(worst, fabs(e - pix) / pix);
        }
        snprintf(what, sizeof what, "N=%u one-pixel sun energy over rotations (relative)", g->N);
        /* each cell is shared out by rays walked through the texel grid
           with the exact solid angle along each, so a texel's taps total
           its solid angle to about 1e-4 (DESIGN: the sun must keep its
           energy) */
        hl_check_error(what, worst, 1e-3);
        hl_env_destroy(env);
        hl_free_big(cells);
        free(px);
        free(L);
        hl_light_geom_destroy(lg);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ref);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"twin", case_env2para},
        {"energy", case_energy},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
