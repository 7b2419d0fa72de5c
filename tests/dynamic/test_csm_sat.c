/* test_csm_sat.c - the convolution shadow maps' summed-area tables
 * (kernels/dynamic/csm_sat.cl, twin host/src/dynamic/twins/csm_sat.c),
 * suite "csm_sat".
 *
 * csm_sat.twin       the device's tables against the twin's scans of the
 *                    device's own basis planes and means (same additions in
 *                    the same order: bit for bit), R = 48, 64, 256.
 * csm_sat.precision  box sums from the float tables (plus mean x area, as
 *                    the evaluation forms them) against direct
 *                    double-precision box sums, boxes of every size 1..R,
 *                    R = 256 and 512; with and without the mean subtracted.
 * Depends on: csm.h, hl_test.h.
 */
#include <float.h>

#include "csm.h"
#include "hl_test.h"


/* a blocker square at 0.4 over empty texels, a ramp, and noisy patches:
 * long runs of one value (the hard case for a prefix sum) and noise */
static void make_map(float *z, uint32_t R)
{
    for (uint32_t j = 0; j < R; j++)
        for (uint32_t i = 0; i < R; i++) {
            float v = 1.0f;
            if (i > R / 8 && i < R / 2 && j > R / 8 && j < R / 2) v = 0.4f;
            else if (j > 2 * R / 3) v = (float)i / (float)R;
            else if (i > 3 * R / 4) v = (float)hl_rng_unit();
            z[(size_t)j * R + i] = v;
        }
}

/* the module's scans, rows then columns, on interleaved planes */
static void twin_scans(float *planes, const float *means, uint32_t R, uint32_t P, int sub)
{
    size_t R2 = (size_t)R * R;
    (void)R2;
    for (uint32_t p = 0; p < P; p++) {
        for (uint32_t row = 0; row < R; row++)
            hl_ref_csm_sat_scan(planes + (size_t)row * R * P + p, P, R, sub ? means[p] : 0.0f);
        for (uint32_t col = 0; col < R; col++) hl_ref_csm_sat_scan(planes + (size_t)col * P + p, (size_t)R * P, R, 0.0f);
    }
}

static void case_twin(void)
{
    hl_context *ctx = hl_test_cl_context(0);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    static const uint32_t Rs[] = {48, 64, 256};
    for (int a = 0; a < 3; a++) {
        uint32_t R = Rs[a], M = 8, Mb = 4, K = 2, P = hl_csm_planes(M, Mb);
        size_t R2 = (size_t)R * R;
        hl_csm *c = NULL;
        HL_CHECK(hl_csm_create(ctx, R, M, Mb, K, &c) == HL_OK, "%s", hl_context_last_error(ctx));
        if (!c) continue;
        float *z = malloc(K * R2 * 4), *basis = malloc(K * P * R2 * 4), *dev = malloc(P * R2 * 4);
        float *m1 = malloc(K * P * 4), *m3 = malloc(P * 4);
        for (uint32_t k = 0; k < K; k++) make_map(z + k * R2, R);
        HL_CHECK(hl_csm_build_upto(c, z, K, HL_CSM_UPTO_BASIS) == HL_OK, "%s", hl_context_last_error(ctx));
        for (uint32_t k = 0; k < K; k++) hl_csm_read_planes(c, k, basis + k * P * R2, m1 + k * P, NULL);
        HL_CHECK(hl_csm_build(c, z, K) == HL_OK, "%s", hl_context_last_error(ctx));
        double worst = 0;
        for (uint32_t k = 0; k < K; k++) {
            hl_csm_read_planes(c, k, dev, m3, NULL);
            twin_scans(basis + k * P * R2, m1 + k * P, R, P, 1);
            for (size_t i = 0; i < P * R2; i++) {
                double e = fabs((double)dev[i] - basis[k * P * R2 + i]);
                if (!(e <= worst)) worst = e;
            }
        }
        /* same float additions in the same order, no contraction: equal */
        char what[96];
        snprintf(what, sizeof what, "R=%u tables, kernel vs twin on the kernel's planes, absolute", R);
        hl_check_error(what, worst, 0.0);
        free(z); free(basis); free(dev); free(m1); free(m3);
        hl_csm_destroy(c);
    }
    hl_context_destroy(ctx);
}

/* the corner function G(X, Y) (sum of texels i < X, j < Y) of a table */
static double corner_f(const float *t, uint32_t R, uint32_t X, uint32_t Y)
{
    return X && Y ? (double)t[(size_t)(Y - 1) * R + (X - 1)] : 0.0;
}

/* worst |float box sum - double box sum| over boxes of every size */
static double box_error(const float *sat, float mean, const double *D, uint32_t R, double *maxabs)
{
    double worst = 0;
    *maxabs = 0;
    for (size_t i = 0; i < (size_t)R * R; i++) *maxabs = fmax(*maxabs, fabs((double)sat[i]));
    for (uint32_t s = 1; s <= R; s++)
        for (int trial = 0; trial < 3; trial++) {
            uint32_t x0 = (uint32_t)(hl_rng_unit() * (R - s + 1)), y0 = (uint32_t)(hl_rng_unit() * (R - s + 1));
            if (x0 > R - s) x0 = R - s;
            if (y0 > R - s) y0 = R - s;
            uint32_t x1 = x0 + s, y1 = y0 + s;
            /* as the evaluation forms it: float corners, plus mean x area */
            float b = (float)corner_f(sat, R, x1, y1) - (float)corner_f(sat, R, x0, y1) - (float)corner_f(sat, R, x1, y0) +
                      (float)corner_f(sat, R, x0, y0);
            b += mean * (float)s * (float)s;
            double ex = D[(size_t)y1 * (R + 1) + x1] - D[(size_t)y0 * (R + 1) + x1] - D[(size_t)y1 * (R + 1) + x0] +
                        D[(size_t)y0 * (R + 1) + x0];
            double e = fabs((double)b - ex);
            if (!(e <= worst)) worst = e;
        }
    return worst;
}

static void case_precision(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    static const uint32_t Rs[] = {256, 512};
    for (int a = 0; a < 2; a++) {
        uint32_t R = Rs[a], M = 4, Mb = 4, P = hl_csm_planes(M, Mb);
        size_t R2 = (size_t)R * R;
        hl_csm *c = NULL;
        HL_CHECK(hl_csm_create(ctx, R, M, Mb, 1, &c) == HL_OK, "%s", hl_context_last_error(ctx));
        if (!c) continue;
        float *z = malloc(R2 * 4), *basis = malloc(P * R2 * 4), *sat = malloc(P * R2 * 4), *raw = malloc(P * R2 * 4);
        float *mean = malloc(P * 4), *zero = calloc(P, 4);
        double *D = calloc((R + 1) * (R + 1), sizeof *D);
        make_map(z, R);
        HL_CHECK(hl_csm_build_upto(c, z, 1, HL_CSM_UPTO_BASIS) == HL_OK, "%s", hl_context_last_error(ctx));
        hl_csm_read_planes(c, 0, basis, mean, NULL);
        HL_CHECK(hl_csm_build(c, z, 1) == HL_OK, "%s", hl_context_last_error(ctx));
        hl_csm_read_planes(c, 0, sat, mean, NULL);
        memcpy(raw, basis, P * R2 * 4);
        twin_scans(raw, zero, R, P, 0);
        double worst = 0, worst_raw = 0, big = 0, big_raw = 0;
        float *xs = malloc(R2 * 4), *ss = malloc(R2 * 4), *rr = malloc(R2 * 4);
        for (uint32_t p = 0; p < P; p++) {
            for (size_t i = 0; i < R2; i++) {
                xs[i] = basis[i * P + p];
                ss[i] = sat[i * P + p];
                rr[i] = raw[i * P + p];
            }
            const float *x = xs;
            for (uint32_t j = 0; j < R; j++)
                for (uint32_t i = 0; i < R; i++)
                    D[(size_t)(j + 1) * (R + 1) + i + 1] = (double)x[(size_t)j * R + i] + D[(size_t)j * (R + 1) + i + 1] +
                                                           D[(size_t)(j + 1) * (R + 1) + i] - D[(size_t)j * (R + 1) + i];
            double m1, m2;
            worst = fmax(worst, box_error(ss, mean[p], D, R, &m1));
            worst_raw = fmax(worst_raw, box_error(rr, 0.0f, D, R, &m2));
            big = fmax(big, m1);
            big_raw = fmax(big_raw, m2);
        }
        free(xs); free(ss); free(rr);
        printf("R=%u: largest table entry %.1f with the mean subtracted, %.1f without; worst box-sum error without: %.3g\n",
               R, big, big_raw, worst_raw);
        /* Bound: each corner entry has rounded about 2 (R/16 + 4) times
         * (a run, the tree, the offset, in each direction), each rounding
         * at most half an ulp of the entry's size, and the random-walk
         * sum of n such errors is near sqrt(n) of them; four corners and
         * the float subtractions add 4 more roundings of the largest:
         * 4 x (sqrt(2 (R/16 + 4)) + 1) x 2^-24 x max|entry|. */
        double n = 2.0 * (R / 16.0 + 4.0);
        double tol = 4.0 * (sqrt(n) + 1.0) * ldexp(1.0, -24) * big;
        char what[128];
        snprintf(what, sizeof what, "R=%u box sums (mean subtracted) vs double direct, absolute", R);
        hl_check_error(what, worst, tol);
        free(z); free(basis); free(sat); free(raw); free(mean); free(zero); free(D);
        hl_csm_destroy(c);
    }
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"twin", case_twin}, {"precision", case_precision}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
