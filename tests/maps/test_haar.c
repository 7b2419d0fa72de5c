/* test_haar.c - the Haar transform (kernels/maps/haar.cl and its plain-C
 * twin host/src/maps/twins/haar.c), suite "haar".
 *
 * haar.twin       the OpenCL stage against the twin on rows of real
 *                 visibility, N = 8 to 256 (needs an OpenCL device: PoCL).
 * haar.roundtrip  hl_ref_haar then an inverse written here from the step
 *                 formulas (double, level by level through hl_geom_slot).
 * haar.parseval   dot products and norms survive the transform.
 * haar.slots      the slot order is a permutation; 256-blocks are spatial
 *                 16x16 tiles plus one coarse coefficient (delta images).
 *
 * Every check prints its tolerance and worst error (hl_check_error).
 * Depends on: haarlight_core, tests/common (maths_util.h, stage_fixture.h).
 */
#include <float.h>
#include <stdint.h>

#include "cl_backend.h"
#include "geom.h"
#include "hl_test.h"
#include "precompute.h"
#include "rays.h"
#include "twins.h"
#include "maths_util.h"
#include "stage_fixture.h"

/* ================================================================ twin */

/* The OpenCL stage against hl_ref_haar, rows of real visibility. */
static void case_haar(void)
{
    static const uint32_t Ns[] = {8, 16, 64, 256};
    for (size_t k = 0; k < 4; k++) {
        fixture f;
        if (!setup(&f, Ns[k], 32, 24)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
        size_t n = (size_t)f.rows * f.g->ncoef;
        float *T = malloc(n * 4), *T2 = malloc(n * 4), *a = malloc(n * 4), *b = malloc(n * 4);
        ref_T(&f, T);
        memcpy(T2, T, n * 4);
        HL_CHECK(hl_cl_pipe_haar(f.pipe, f.rows, T, b) == HL_OK, "%s", hl_context_last_error(f.cl));
        for (uint32_t i = 0; i < f.rows; i++) hl_ref_haar(f.g, T2 + (size_t)i * f.g->ncoef, a + (size_t)i * f.g->ncoef);
        char what[64];
        snprintf(what, sizeof what, "haar N=%u OpenCL vs C, relative", f.g->N);
        hl_check_error(what, hl_test_rel_diff(a, b, n), 1e-6);
        free(T); free(T2); free(a); free(b);
        teardown(&f);
    }
}

/* ================================================================ haar */

static void case_roundtrip(void)
{
    hl_context *ctx = make_ctx();
    static const uint32_t Ns[] = {8, 16, 64, 256};
    for (size_t k = 0; k < sizeof Ns / sizeof Ns[0]; k++) {
        uint32_t N = Ns[k];
        hl_geom *g = make_geom(ctx, N, 4);
        float *x = xmalloc((size_t)g->ncoef * sizeof *x), *coef = xmalloc((size_t)g->ncoef * sizeof *coef);
        double *y = xmalloc((size_t)g->ncoef * sizeof *y);
        /* Random data everywhere, outside the disc too, with a positive
         * offset so the averages grow by 2 per level (the harder case for
         * rounding). */
        double xmax = 0.0;
        for (uint32_t i = 0; i < g->ncoef; i++) {
            x[i] = rng_float(-0.5, 1.5);
            xmax = fmax(xmax, fabs((double)x[i]));
        }
        for (uint32_t i = 0; i < g->ncoef; i++) coef[i] = NAN; /* every slot must be written */
        haar_of(g, x, coef);
        inverse_haar(g, coef, y);
        double worst = 0.0;
        for (uint32_t i = 0; i < g->ncoef; i++) {
            double e = fabs(y[i] - (double)x[i]);
            if (!(e <= worst)) worst = e; /* NaN (an unwritten slot) sticks */
        }
        /* Each level rounds three float additions and a halving; the
         * inverse (exact in double) carries each level's error down at the
         * same scale, so the error is a few ulps of max|x| per level. */
        double tol = 4.0 * FLT_EPSILON * ilog2u(N);
        char what[96];
        snprintf(what, sizeof what, "N=%u inverse(haar(x)) - x, relative to max|x|", N);
        hl_check_error(what, worst / xmax, tol);
        free(x);
        free(coef);
        free(y);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

static void case_parseval(void)
{
    hl_context *ctx = make_ctx();
    static const uint32_t Ns[] = {8, 16, 64, 256};
    for (size_t k = 0; k < sizeof Ns / sizeof Ns[0]; k++) {
        uint32_t N = Ns[k];
        hl_geom *g = make_geom(ctx, N, 4);
        size_t n = g->ncoef;
        float *x = xmalloc(n * sizeof *x), *y = xmalloc(n * sizeof *y);
        float *wx = xmalloc(n * sizeof *wx), *wy = xmalloc(n * sizeof *wy);
        double worst_dot = 0.0, worst_norm = 0.0;
        for (int trial = 0; trial < 4; trial++) {
            for (size_t i = 0; i < n; i++) {
                /* trial 0,1: zero-mean; 2,3: positive (transport-like) */
                x[i] = trial < 2 ? rng_float(-1, 1) : rng_float(0, 1);
                y[i] = trial < 2 ? rng_float(-1, 1) : rng_float(0, 2);
            }
            haar_of(g, x, wx);
            haar_of(g, y, wy);
            double nx = sqrt(dot_ff(x, x, n)), ny = sqrt(dot_ff(y, y, n));
            double e = fabs(dot_ff(x, y, n) - dot_ff(wx, wy, n)) / (nx * ny);
            if (!(e <= worst_dot)) worst_dot = e;
            e = fabs(sqrt(dot_ff(wx, wx, n)) - nx) / nx;
            if (!(e <= worst_norm)) worst_norm = e;
        }
        /* Every coefficient is within a few ulps x log2 N of its exact value
         * relative to the vector's scale (see roundtrip), so by
         * Cauchy-Schwarz the dot product is within that times ||x|| ||y||:
         * 4 * 2^-23 * 8 = 3.8e-6 at N = 256; the random-walk sum of the
         * independent roundings sits far lower. 1e-6 (the brief's figure)
         * leaves ample room for that and no room for a wrong coefficient. */
        char what[96];
        snprintf(what, sizeof what, "N=%u |x.y - Wx.Wy| / (|x||y|)", N);
        hl_check_error(what, worst_dot, 1e-6);
        snprintf(what, sizeof what, "N=%u | |Wx| - |x| | / |x|", N);
        hl_check_error(what, worst_norm, 1e-6);
        free(x);
        free(y);
        free(wx);
        free(wy);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

/* A delta at texel (r, c) of map m must give exactly 3 log2 N + 1 non-zero
 * coefficients (three details per level plus the scaling one), each in the
 * 256-block of the 16x16 tile holding (r, c) or in a coarse slot (slot %
 * 256 == 0). Returns the number of violations. */
static long delta_check(const hl_geom *g, int m, uint32_t r, uint32_t c, float *img, float *coef)
{
    const uint32_t N = g->N;
    memset(img, 0, (size_t)g->ncoef * sizeof *img);
    img[(size_t)m * N * N + r * N + c] = 1.0f;
    haar_of(g, img, coef);
    uint32_t expect_block = (uint32_t)m * N * N / HL_BLOCK + (r / 16) * (N / 16) + c / 16;
    long bad = 0;
    uint32_t nz = 0;
    for (uint32_t s = 0; s < g->ncoef; s++) {
        if (coef[s] == 0.0f) continue;
        nz++;
        if (s / HL_BLOCK != expect_block && s % HL_BLOCK != 0) bad++;
    }
    if (nz != 3 * ilog2u(N) + 1) bad++;
    return bad;
}

static void case_slots(void)
{
    hl_context *ctx = make_ctx();
    for (uint32_t N = 8; N <= 256; N *= 2) {
        hl_geom *g = make_geom(ctx, N, 4);
        uint8_t *seen = xcalloc(g->ncoef, 1);
        long bad = 0;
        for (int m = 0; m < 2; m++)
            for (uint32_t r = 0; r < N; r++)
                for (uint32_t c = 0; c < N; c++) {
                    uint32_t s = hl_geom_slot(g, m, r, c);
                    if (s >= g->ncoef || seen[s]++) bad++;
                }
        char what[128];
        snprintf(what, sizeof what, "N=%u slots out of range or repeated (of %u)", N, g->ncoef);
        hl_check_error(what, (double)bad, 0.0);
        free(seen);
        if (N >= 16) {
            /* Coarse coefficients (support larger than a tile): exactly one
             * per block, at the block's slot 0. */
            uint32_t T = N / 16;
            long badc = 0;
            for (int m = 0; m < 2; m++)
                for (uint32_t r = 0; r < N; r++)
                    for (uint32_t c = 0; c < N; c++) {
                        int coarse = r < T && c < T;
                        if (coarse != (hl_geom_slot(g, m, r, c) % HL_BLOCK == 0)) badc++;
                    }
            snprintf(what, sizeof what, "N=%u coarse coefficients not alone at slot 0 of a block", N);
            hl_check_error(what, (double)badc, 0.0);

            /* Delta images: every texel for N <= 64, a sample above (each
             * detail coefficient of a tile is hit by any delta inside its
             * support, so the full sweep covers every slot). */
            float *img = xmalloc((size_t)g->ncoef * sizeof *img), *coef = xmalloc((size_t)g->ncoef * sizeof *coef);
            long badd = 0, tested = 0;
            for (int m = 0; m < 2; m++)
                for (uint32_t r = 0; r < N; r++)
                    for (uint32_t c = 0; c < N; c++) {
                        if (N > 64 && (rng_next() % (N * N / 512)) != 0 && !(r % 16 == 15 && c % 16 == 15))
                            continue;
                        badd += delta_check(g, m, r, c, img, coef);
                        tested++;
                    }
            snprintf(what, sizeof what, "N=%u delta images (%ld) with coefficients outside their tile's block", N,
                     tested);
            hl_check_error(what, (double)badd, 0.0);
            free(img);
            free(coef);
        }
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"twin", case_haar},
        {"roundtrip", case_roundtrip},
        {"parseval", case_parseval},
        {"slots", case_slots},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
