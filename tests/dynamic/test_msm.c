/* test_msm.c - moment shadow maps (kernels/dynamic/msm_basis.cl,
 * msm_eval.cl, twins host/src/dynamic/twins/msm_*.c, module csm.c with
 * HL_SHADOW_REP_MOMENTS), suite "msm".
 *
 * msm.twin       the device's planes (four moments and the coverage),
 *                means, tables and texel moments against the reference
 *                backend's (the twins), and
 *                the evaluation kernel against its twin on the device's
 *                own tables, V and z_avg, with random receiver planes
 *                (the small boxes' per-texel test) and without (NULL);
 *                also through a batch of lights.
 * msm.bound      the Hamburger 4MSM bound (twin) on distributions whose
 *                answer is known: one blocker share over empty texels
 *                (the bound and the blocker depth are exact at alpha = 0;
 *                float against a double version of the same steps), two
 *                blocker depths (a lower bound), a receiver in front
 *                (at most alpha of shadow).
 * msm.precision  box averages of the four moments and the coverage from
 *                the float tables
 *                against double sums, boxes wider than the texel-by-texel
 *                limit, R = 128 and 256: the worst error must stay below
 *                the margin that alpha buys (0.079 alpha / 3), the reason
 *                for HL_MSM_ALPHA.
 * msm.plane      a receiver plane at d = 0.8 under a square blocker at
 *                z = 0.4: lit outside, dark in the umbra, monotone across
 *                the penumbra, z_avg = 0.4, no acne where the plane itself
 *                is in the map.
 * msm.bad_input  an unknown representation, a map size the tables refuse,
 *                --shadow out of range, an order with moments.
 * Depends on: csm.h, hl_test.h.
 */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#define CL_TARGET_OPENCL_VERSION 120 /* as the library builds: cl_internal.h then skips its GL part */
#include "cl_internal.h"
#include "csm.h"
#include "hl_test.h"
#include "shadow_map_util.h"

/* whether the device divides and takes square roots correctly rounded
 * (cl_program.c then builds with -cl-fp32-correctly-rounded-divide-sqrt) */
static int hl_cl_correct_divide(hl_context *ctx)
{
    cl_device_fp_config fp = 0;
    if (!ctx->cl || clGetDeviceInfo(ctx->cl->device, CL_DEVICE_SINGLE_FP_CONFIG, sizeof fp, &fp, NULL) != CL_SUCCESS) return 0;
    return (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) != 0;
}

/* a blocker square, a ramp and noise: the maps of test_csm_eval twin */
static void mixed_map(float *z, uint32_t R)
{
    square_map(z, R, R / 4, R / 2, 0.3f, 1.0f);
    for (uint32_t j = 5 * R / 8; j < 7 * R / 8; j++)
        for (uint32_t i = R / 8; i < 15 * R / 16; i++) z[(size_t)j * R + i] = 0.5f + 0.3f * (float)i / (float)R;
    for (uint32_t j = 0; j < R / 4; j++)
        for (uint32_t i = 3 * R / 4; i < R; i++) z[(size_t)j * R + i] = (float)(0.2 + 0.8 * hl_rng_unit());
}

static double maxdiff(const float *a, const float *b, size_t n)
{
    double w = 0;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)a[i] - b[i]);
        if (!(d <= w)) w = d != d ? INFINITY : d;
    }
    return w;
}

static void case_twin(void)
{
    hl_context *ctx = hl_test_cl_context(0), *ref = hl_test_ref_context(1);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    const uint32_t R = 128, n = 6000, K = 2;
    const size_t R2 = (size_t)R * R;
    hl_csm *c = NULL, *cr = NULL;
    HL_CHECK(hl_csm_create_rep(ctx, HL_SHADOW_REP_MOMENTS, R, 0, 0, K, &c) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_csm_create_rep(ref, HL_SHADOW_REP_MOMENTS, R, 0, 0, K, &cr) == HL_OK, "%s", hl_context_last_error(ref));
    if (!c || !cr) return;
    uint32_t P = 0;
    hl_csm_sizes(c, NULL, NULL, NULL, &P);
    HL_CHECK(P == HL_MSM_PLANES, "moments take %u planes, not %u", HL_MSM_PLANES, P);
    float *z = malloc(K * R2 * 4), *uvd = malloc(n * 12), *V = malloc(n * 4), *za = malloc(n * 4);
    float *Vr = malloc(n * 4), *zar = malloc(n * 4), *rpl = malloc(n * HL_DYN_RPL * 4);
    float *sat = malloc(5 * R2 * 4), *mean = malloc(20), *t4 = malloc(R2 * 16);
    float *satr = malloc(5 * R2 * 4), *meanr = malloc(20), *t4r = malloc(R2 * 16);
    mixed_map(z, R);
    for (size_t i = 0; i < R2; i++) z[R2 + i] = (float)(0.2 + 0.8 * hl_rng_unit());
    HL_CHECK(hl_csm_build(c, z, K) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_csm_build(cr, z, K) == HL_OK, "%s", hl_context_last_error(ref));
    hl_shadow_frame f = frame_of(R);
    double w_tab = 0, w_mean = 0, w_t4 = 0, w_V = 0, w_za = 0, w_end = 0;
    uint32_t nsmall = 0;
    for (uint32_t pass = 0; pass < 2 * K; pass++) {
        const uint32_t k = pass % K;
        random_receivers(uvd, n, R);
        /* the first K passes with planes: slopes up to 0.02 of the depth
           a texel (a receiver at about 70 degrees to the light in these
           maps), the depth before the receiver-plane bias up to 0.03
           behind uvd's; then without (NULL, planes facing the light) */
        const float *pl = pass < K ? rpl : NULL;
        for (uint32_t i = 0; i < n; i++) {
            rpl[HL_DYN_RPL * i] = (float)(0.04 * hl_rng_unit() - 0.02);
            rpl[HL_DYN_RPL * i + 1] = (float)(0.04 * hl_rng_unit() - 0.02);
            rpl[HL_DYN_RPL * i + 2] = uvd[3 * i + 2] + (float)(0.03 * hl_rng_unit());
        }
        float theta = k ? 0.02f : 0.08f;
        const uint32_t start[2] = {0, n};
        const hl_shadow_frame *fp = &f;
        HL_CHECK(hl_csm_visibility_batch(c, 1, &k, &theta, &fp, uvd, pl, start, V, za) == HL_OK, "%s",
                 hl_context_last_error(ctx));
        HL_CHECK(hl_csm_visibility_batch(cr, 1, &k, &theta, &fp, uvd, pl, start, Vr, zar) == HL_OK, "%s",
                 hl_context_last_error(ref));
        hl_csm_read_planes(c, k, sat, mean, t4);
        hl_csm_read_planes(cr, k, satr, meanr, t4r);
        w_tab = fmax(w_tab, maxdiff(sat, satr, 5 * R2));
        w_mean = fmax(w_mean, maxdiff(mean, meanr, 5));
        w_t4 = fmax(w_t4, maxdiff(t4, t4r, 4 * R2));
        float zmin = 1.0f;
        for (size_t i = 0; i < R2; i++) zmin = fminf(zmin, z[k * R2 + i]);
        double t = tan((double)theta) * f.depth_range * R;
        hl_msm_eval_params p;
        hl_msm_params(&p, R, zmin, (float)(t / f.width), (float)(t / f.height), hl_shadow_frame_texel(&f));
        for (uint32_t i = 0; i < n; i++) {
            float o[2];
            hl_ref_msm_eval(sat, mean, t4, &p, uvd + 3 * i, pl ? pl + HL_DYN_RPL * i : NULL, o);
            /* a filter box within the per-texel limit (z_avg found) */
            if (pl && za[i] >= 0.0f && (uvd[3 * i + 2] - za[i]) * p.su <= p.direct_half) nsmall++;
            w_V = fmax(w_V, fabs((double)o[0] - V[i]));
            w_za = fmax(w_za, fabs((double)o[1] - za[i]));
            if (!(V[i] >= 0.0f && V[i] <= 1.0f)) w_V = INFINITY;
        }
        w_end = fmax(w_end, fmax(maxdiff(V, Vr, n), maxdiff(za, zar, n)));
    }
    /* The basis is products of the texel's x alone, and the scans are
     * csm_sat.cl's (bit for bit with their twin, test_csm_sat.c): the same
     * float operations in the same order, no contraction, so the tables
     * agree to the bit. */
    hl_check_error("moment tables, device vs twin, absolute", w_tab, 0.0);
    hl_check_error("plane means, device vs twin, absolute", w_mean, 0.0);
    hl_check_error("texel moments, device vs twin, absolute", w_t4, 0.0);
    /* The evaluation uses + - * / and sqrt only (the contact exponent's
     * exp and pow are off by default, HL_MSM_LEAK_A = 0), and the program
     * is built with correctly rounded division and sqrt where the device
     * offers it; then kernel and twin agree to the bit. Where it does
     * not, division and sqrt may be 2.5 and 3 ulp off: the bound divides
     * by differences of the roots, which can turn that into about 1e-5 of
     * V near a degenerate matrix; so the tolerance is 0 only with
     * correctly rounded division. */
    const double tol = hl_cl_correct_divide(ctx) ? 0.0 : 1e-4;
    hl_check_error("V, kernel vs twin on the kernel's tables, absolute", w_V, tol);
    hl_check_error("z_avg, kernel vs twin on the kernel's tables, absolute", w_za, tol);
    hl_check_error("V and z_avg, OpenCL module vs reference backend end to end", w_end, tol);
    printf("receivers with planes whose filter box was tested texel by texel: %u of %u\n", nsmall, K * n);
    HL_CHECK(nsmall > n / 10, "too few small boxes (%u) to test the per-texel path", nsmall);
    free(rpl);
    free(z); free(uvd); free(V); free(za); free(Vr); free(zar);
    free(sat); free(mean); free(t4); free(satr); free(meanr); free(t4r);
    hl_csm_destroy(c);
    hl_csm_destroy(cr);
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

/* ---- bound: the 4MSM steps in double, to separate rounding from method */
static double bound_d(const double m[4], double xf, double alpha, double *wb, double *xb)
{
    double ka = 1.0 - alpha;
    double b1 = ka * m[0], b2 = ka * m[1] + alpha / 3.0, b3 = ka * m[2], b4 = ka * m[3] + alpha * 0.2;
    double d22 = b2 - b1 * b1, l32 = (b3 - b1 * b2) / d22, d33 = (b4 - b2 * b2) - l32 * l32 * d22;
    double y2 = xf - b1, y3 = (xf * xf - b2) - l32 * y2;
    double c3 = y3 / d33, c2 = y2 / d22 - l32 * c3, c1 = 1.0 - b1 * c2 - b2 * c3;
    double ph = -0.5 * c2 / c3, q = c1 / c3, r = sqrt(fmax(ph * ph - q, 0.0));
    double x2 = ph - r, x3 = ph + r, G = 0, w = 0, xm = xf;
    if (xf <= x2) G = 0;
    else if (xf <= x3) G = (xf * x3 - b1 * (xf + x3) + b2) / ((x3 - x2) * (xf - x2)), w = G, xm = x2;
    else {
        double w1 = (x2 * x3 - b1 * (x2 + x3) + b2) / ((xf - x2) * (xf - x3));
        G = 1 - w1, w = G, xm = (b1 - w1 * xf) / G;
    }
    if (wb) *wb = w, *xb = xm;
    return G;
}

/* moments of share beta at x_b and 1 - beta at x = 1 (empty texels) */
static void two_point(double beta, double xb, double *m)
{
    double p = xb;
    for (int k = 0; k < 4; k++, p *= xb) m[k] = beta * p + (1 - beta);
}

static void case_bound(void)
{
    const float alpha = HL_MSM_ALPHA;
    double w_round = 0, w_zround = 0, w_exact = 0, w_zb = 0, leak = 0, front = 0, w_lower = 0;
    for (int a = 0; a < 200; a++) {
        double beta = 0.05 + 0.9 * hl_rng_unit(), zb = 0.05 + 0.75 * hl_rng_unit();
        double xb = 2 * zb - 1, m[4];
        two_point(beta, xb, m);
        float mf[4] = {(float)m[0], (float)m[1], (float)m[2], (float)m[3]};
        /* receivers from 0.1 behind the blocker to 0.1 before the empty
           texels' depth 1 */
        for (int r = 0; r < 5; r++) {
            double zf = zb + 0.1 + (0.8 - zb) * r / 4.0, xf = 2 * zf - 1;
            double wd, xd, wd0, xd0;
            double Gd = bound_d(m, xf, alpha, &wd, &xd), G0 = bound_d(m, xf, 0.0, &wd0, &xd0);
            float wf, xff;
            float G = hl_ref_msm_bound(mf, (float)xf, alpha, &wf, &xff);
            w_round = fmax(w_round, fabs(G - Gd));
            w_zround = fmax(w_zround, fabs(0.5 * ((double)xff - xd)));
            w_exact = fmax(w_exact, fabs(G0 - beta));
            w_zb = fmax(w_zb, fabs(0.5 * (xd0 + 1) - zb));
            leak = fmax(leak, beta - G);
        }
        /* a receiver in front of the blocker: the blend gives at most alpha */
        double xf = 2 * (zb - 0.02) - 1;
        front = fmax(front, hl_ref_msm_bound(mf, (float)xf, alpha, NULL, NULL));
        /* two blocker depths and empty texels: a lower bound of the share */
        double z1 = 0.1 + 0.3 * hl_rng_unit(), z2 = z1 + 0.1 + 0.3 * hl_rng_unit(), s1 = 0.3 * hl_rng_unit(),
               s2 = 0.3 * hl_rng_unit();
        double x1 = 2 * z1 - 1, x2 = 2 * z2 - 1, p1 = x1, p2 = x2;
        float mm[4];
        for (int k = 0; k < 4; k++, p1 *= x1, p2 *= x2) mm[k] = (float)(s1 * p1 + s2 * p2 + (1 - s1 - s2));
        float G2 = hl_ref_msm_bound(mm, (float)(2 * (z2 + 0.05) - 1), alpha, NULL, NULL);
        w_lower = fmax(w_lower, G2 - (s1 + s2));
    }
    /* exact at alpha = 0: the two-point distribution is the only one with
     * its moments, so the sharp bound is its share and the canonical
     * representation's point below the receiver is the blocker (double
     * rounding only) */
    hl_check_error("one blocker, alpha = 0 in double: bound vs its share", w_exact, 1e-9);
    hl_check_error("one blocker, alpha = 0 in double: z_avg vs its depth", w_zb, 1e-9);
    /* float against double at the default alpha: the Cholesky's pivots
     * are at least 0.079 alpha = 8e-6 (d22, d33), formed from moments
     * near 1 rounded to 6e-8: relative error up to about 1e-2 in the
     * pivots, which the bound (a ratio of such terms) carries to about
     * 1e-3 at the worst; 5e-3 is a quarter of the blocker threshold
     * HL_CSM_BLOCKER_EPS (0.02), the most that may move */
    hl_check_error("one blocker: float bound vs double, absolute", w_round, 5e-3);
    hl_check_error("one blocker: float z_avg vs double, absolute", w_zround, 5e-3);
    printf("one blocker, receivers 0.1 or more from the blocker and from depth 1: the most light the bound leaks at "
           "alpha = %g (share - bound): %.4g\n", (double)alpha, leak);
    /* the leak by the receiver's distance behind the blocker (share 0.5
       at 0.3): what alpha costs at contact */
    double m[4];
    two_point(0.5, 2 * 0.3 - 1, m);
    float mf[4] = {(float)m[0], (float)m[1], (float)m[2], (float)m[3]};
    static const double gaps[5] = {0.005, 0.01, 0.02, 0.05, 0.1};
    printf("leak (0.5 - bound) of a receiver behind a blocker at 0.3 (share 0.5), by its distance:");
    for (int g = 0; g < 5; g++) printf(" %.3f: %.4f", gaps[g], 0.5 - hl_ref_msm_bound(mf, (float)(2 * (0.3 + gaps[g]) - 1), alpha, NULL, NULL));
    printf("\n");
    hl_check_error("receiver in front: shadow from the blend (at most alpha)", front, (double)alpha);
    /* a sharp lower bound: above the true share only by rounding (5e-3 as above) */
    hl_check_error("two blockers: bound minus the true share (a lower bound)", w_lower, 5e-3);
}

/* ---- precision: table box averages against double sums */
static void case_precision(void)
{
    hl_context *ref = hl_test_ref_context(1);
    static const uint32_t Rs[2] = {128, 256};
    double worst_all = 0;
    for (int a = 0; a < 2; a++) {
        const uint32_t R = Rs[a];
        const size_t R2 = (size_t)R * R;
        hl_csm *c = NULL;
        HL_CHECK(hl_csm_create_rep(ref, HL_SHADOW_REP_MOMENTS, R, 0, 0, 1, &c) == HL_OK, "%s", hl_context_last_error(ref));
        if (!c) continue;
        float *z = malloc(R2 * 4), *sat = malloc(5 * R2 * 4), *mean = malloc(20), *t4 = malloc(R2 * 16);
        double *pre = calloc(5 * (R + 1) * (R + 1), sizeof(double));
        mixed_map(z, R);
        hl_csm_build(c, z, 1);
        hl_csm_read_planes(c, 0, sat, mean, t4);
        /* double prefix sums of the texels' exact moments */
        for (uint32_t j = 0; j < R; j++)
            for (uint32_t i = 0; i < R; i++) {
                double zz = z[(size_t)j * R + i];
                double x = zz >= 1.0 ? 1.0 : 2.0 * (double)(float)(zz * (1.0f - HL_MSM_FAR_BAND)) - 1.0, p = x;
                for (int k = 0; k < 5; k++, p *= x) {
                    size_t at = 5 * ((size_t)(j + 1) * (R + 1) + (i + 1)) + k;
                    double v = k < 4 ? p : zz >= 1.0 ? 0.0 : 1.0; /* plane 4: the coverage */
                    pre[at] = v + pre[5 * ((size_t)j * (R + 1) + (i + 1)) + k] + pre[5 * ((size_t)(j + 1) * (R + 1) + i) + k] -
                              pre[5 * ((size_t)j * (R + 1) + i) + k];
                }
            }
        double worst = 0;
        for (int b = 0; b < 20000; b++) {
            /* integer boxes inside the map, half-widths above the direct
               limit: the tables' taps are then the four corners */
            uint32_t w = 9u + (uint32_t)(hl_rng_unit() * (R - 9u)); /* 2 HL_CSM_DIRECT_HALF + 1 = 9 */
            uint32_t h = 9u + (uint32_t)(hl_rng_unit() * (R - 9u));
            if (w > R) w = R;
            if (h > R) h = R;
            uint32_t i0 = (uint32_t)(hl_rng_unit() * (R - w + 1)), j0 = (uint32_t)(hl_rng_unit() * (R - h + 1));
            if (i0 + w > R) i0 = R - w;
            if (j0 + h > R) j0 = R - h;
            for (int k = 0; k < 5; k++) {
                /* as msm_eval.cl forms it: corner sums / area + mean */
                float ia = 1.0f / ((float)w * (float)h), acc = 0.0f;
                uint32_t xs[2] = {i0, i0 + w}, ys[2] = {j0, j0 + h};
                for (int q = 0; q < 4; q++) {
                    uint32_t X = xs[q & 1], Y = ys[q >> 1];
                    if (X == 0 || Y == 0) continue;
                    float sg = (q == 0 || q == 3) ? ia : -ia;
                    acc += sg * sat[5 * ((size_t)(Y - 1) * R + (X - 1)) + k];
                }
                double got = (double)(acc + mean[k]);
                size_t A = 5 * ((size_t)(j0 + h) * (R + 1) + (i0 + w)) + k, B = 5 * ((size_t)j0 * (R + 1) + (i0 + w)) + k;
                size_t C = 5 * ((size_t)(j0 + h) * (R + 1) + i0) + k, D = 5 * ((size_t)j0 * (R + 1) + i0) + k;
                double want = (pre[A] - pre[B] - pre[C] + pre[D]) / ((double)w * h);
                worst = fmax(worst, fabs(got - want));
            }
        }
        printf("R = %u: worst box average error of the four moments and the coverage from the float tables: %.3g\n", R, worst);
        if (R == 128) worst_all = worst;
        free(z); free(sat); free(mean); free(t4); free(pre);
        hl_csm_destroy(c);
    }
    /* The blended Hankel matrix's smallest eigenvalue is at least 0.079
     * alpha (the uniform distribution's, 0.0794, times alpha); an error of
     * delta in each moment moves the 3 x 3 matrix by at most 3 delta in
     * the spectral norm. Positive definite at the default R = 128 needs
     * 3 delta < 0.079 alpha. */
    hl_check_error("R = 128: 3 x worst moment error against 0.079 alpha", 3.0 * worst_all, 0.0794 * (double)HL_MSM_ALPHA);
    hl_context_destroy(ref);
}

/* ---- plane: a receiver plane under a square blocker */
static void case_plane(void)
{
    hl_context *ctxs[2] = {hl_test_cl_context(0), hl_test_ref_context(1)};
    const uint32_t R = 128;
    const size_t R2 = (size_t)R * R;
    for (int q = 0; q < 2; q++) {
        hl_context *ctx = ctxs[q];
        if (!ctx) continue;
        hl_csm *c = NULL;
        HL_CHECK(hl_csm_create_rep(ctx, HL_SHADOW_REP_MOMENTS, R, 0, 0, 1, &c) == HL_OK, "%s", hl_context_last_error(ctx));
        if (!c) continue;
        float *z = malloc(R2 * 4);
        /* blocker square at 0.4 on texels [48, 80); the plane at 0.8 is
           itself in the map elsewhere (acne check) */
        square_map(z, R, 48, 80, 0.4f, 0.8f);
        HL_CHECK(hl_csm_build(c, z, 1) == HL_OK, "%s", hl_context_last_error(ctx));
        hl_shadow_frame f = frame_of(R);
        const uint32_t n = R * 4;
        float uvd[4 * 128 * 3], V[4 * 128], za[4 * 128];
        const float theta = 0.05f, d = 0.8f;
        /* the receiver-plane bias of hl_dyn_receiver: 1.5 texels of a
           flat plane facing the light gives none; d as the frame has it */
        for (uint32_t i = 0; i < n; i++) uvd[3 * i] = (float)(i % R) + 0.5f, uvd[3 * i + 1] = 64.0f, uvd[3 * i + 2] = d;
        HL_CHECK(hl_csm_visibility(c, 0, theta, &f, uvd, R, V, za) == HL_OK, "%s", hl_context_last_error(ctx));
        /* penumbra half-width (d - z_b) tan(theta) R / width, in texels */
        double hw = (d - 0.4) * tan(theta) * f.depth_range * R / f.width;
        double lit_worst = 0, umbra_worst = 0, rise = 0, zerr = 0;
        for (uint32_t i = 0; i < R; i++) {
            double u = i + 0.5;
            if (u < 48 - hw - 1 || u > 80 + hw + 1) lit_worst = fmax(lit_worst, 1.0 - V[i]);
            else if (u > 48 + hw + 1 && u < 80 - hw - 1) {
                umbra_worst = fmax(umbra_worst, V[i]);
                zerr = fmax(zerr, fabs(za[i] - 0.4));
            }
            if (i > 0 && i <= 64) rise = fmax(rise, V[i] - V[i - 1]); /* falling into the shadow */
        }
        printf("%s: penumbra half-width %.2f texels\n", q ? "reference backend" : "OpenCL", hw);
        /* lit: the plane is its own blocker candidate at 0.8 with the bias
           0.01 in front; alpha's blend can shadow at most alpha */
        hl_check_error("lit plane outside the penumbra: 1 - V", lit_worst, (double)HL_MSM_ALPHA);
        /* the umbra: the two-point distribution (0.4 and 0.8) is exact up
           to alpha's leak and float rounding (msm.bound: 5e-3) */
        hl_check_error("umbra: V", umbra_worst, 5e-3);
        hl_check_error("umbra: z_avg vs 0.4", zerr, 5e-3);
        /* monotone into the shadow, within the bound's float rounding */
        hl_check_error("penumbra: V rising towards the umbra", rise, 5e-3);
        free(z);
        hl_csm_destroy(c);
        hl_context_destroy(ctx);
    }
}

static void case_bad_input(void)
{
    hl_context *ref = hl_test_ref_context(1);
    hl_csm *c = NULL;
    HL_CHECK(hl_csm_create_rep(ref, (hl_shadow_rep)7, 64, 0, 0, 1, &c) != HL_OK && !c, "representation 7 accepted");
    HL_CHECK(strstr(hl_context_last_error(ref), "representation") != NULL, "message: %s", hl_context_last_error(ref));
    HL_CHECK(hl_csm_create_rep(ref, HL_SHADOW_REP_MOMENTS, 100, 0, 0, 1, &c) != HL_OK && !c, "R = 100 accepted");
    hl_mesh *m = NULL;
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    if (hl_mesh_load(ref, path, NULL, &m, NULL) == HL_OK) {
        hl_dynamic_desc dd = {0, 0, 5, 0, 0};
        hl_dynamic *d = NULL;
        HL_CHECK(hl_dynamic_create_from_mesh(ref, m, 1, &dd, &d) != HL_OK && !d, "shadow 5 accepted");
        HL_CHECK(strstr(hl_context_last_error(ref), "--shadow") != NULL, "message: %s", hl_context_last_error(ref));
        /* an order is CSM's: refused with moments asked for */
        hl_dynamic_desc om = {0, 8, HL_DYNAMIC_SHADOW_MOMENTS, 0, 0};
        HL_CHECK(hl_dynamic_create_from_mesh(ref, m, 1, &om, &d) != HL_OK && !d, "order 8 with moments accepted");
        HL_CHECK(strstr(hl_context_last_error(ref), "--order") != NULL, "message: %s", hl_context_last_error(ref));
        hl_mesh_destroy(m);
    }
    hl_context_destroy(ref);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"twin", case_twin},           {"bound", case_bound}, {"precision", case_precision},
                                         {"plane", case_plane},         {"bad_input", case_bad_input},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
