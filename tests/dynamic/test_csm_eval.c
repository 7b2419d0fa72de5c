/* test_csm_eval.c - convolution shadow map visibility
 * (kernels/dynamic/csm_eval.cl, twin host/src/dynamic/twins/csm_eval.c,
 * module host/src/dynamic/csm.c), suite "csm_eval".
 *
 * csm_eval.twin       the kernel against the twin on the device's own
 *                     tables, and the reference backend end to end.
 * csm_eval.plane      a receiver plane at d = 0.8 under a square blocker at
 *                     z = 0.4: lit outside, dark in the umbra, monotone
 *                     across the penumbra, whose width follows
 *                     (d - z_avg) tan(theta) for two theta and two d; no
 *                     acne where the plane itself is in the map.
 * csm_eval.edge       a map full of blocker: outside it counts as empty, so
 *                     a box half outside is half lit and one that misses
 *                     the map is lit.
 * csm_eval.contact    receivers just behind the blocker: dark with the
 *                     leak exponent, leaking without; B chosen here.
 * csm_eval.batch      several lights in one call (hl_csm_visibility_batch),
 *                     each with its own frame, half-extent and receivers,
 *                     one light with none, equal those light by light bit
 *                     for bit, also cut into calls of 2 lights
 *                     (HL_TEST_CSM_BATCH) and on the reference backend.
 * csm_eval.bad_input  orders, sizes, NaN depths and receivers, frames; a
 *                     batch beyond the device memory limit.
 * timing              not a ctest case (it asserts nothing): build time per
 *                     light at R = 256, M = 16 and evaluation time per 10^4
 *                     receivers per light on the OpenCL device (argument
 *                     "timing"), or the reference backend ("timing ref").
 * Depends on: csm.h, hl_test.h.
 */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "csm.h"
#include "hl_test.h"
#include "shadow_map_util.h"

static void case_twin(void)
{
    hl_context *ctx = hl_test_cl_context(0), *ref = hl_test_ref_context(1);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    const uint32_t R = 128, M = 16, Mb = 8, n = 4000;
    const size_t R2 = (size_t)R * R;
    uint32_t P = hl_csm_planes(M, Mb);
    hl_csm *c = NULL, *cr = NULL;
    HL_CHECK(hl_csm_create(ctx, R, M, Mb, 2, &c) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_csm_create(ref, R, M, Mb, 2, &cr) == HL_OK, "%s", hl_context_last_error(ref));
    if (!c || !cr) return;
    float *z = malloc(2 * R2 * 4), *uvd = malloc(n * 12), *V = malloc(n * 4), *za = malloc(n * 4);
    float *Vr = malloc(n * 4), *sat = malloc(P * R2 * 4), *mean = malloc(P * 4), *t4 = malloc(R2 * 16);
    square_map(z, R, 30, 70, 0.3f, 1.0f);
    for (uint32_t j = 80; j < 110; j++)
        for (uint32_t i = 20; i < 120; i++) z[(size_t)j * R + i] = 0.5f + 0.3f * (float)i / (float)R;
    for (size_t i = 0; i < R2; i++) z[R2 + i] = (float)(0.2 + 0.8 * hl_rng_unit());
    HL_CHECK(hl_csm_build(c, z, 2) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_csm_build(cr, z, 2) == HL_OK, "%s", hl_context_last_error(ref));
    hl_shadow_frame f = frame_of(R);
    double worst = 0, worst_za = 0, worst_ref = 0;
    for (uint32_t k = 0; k < 2; k++) {
        random_receivers(uvd, n, R);
        float theta = k ? 0.02f : 0.08f;
        HL_CHECK(hl_csm_visibility(c, k, theta, &f, uvd, n, V, za) == HL_OK, "%s", hl_context_last_error(ctx));
        HL_CHECK(hl_csm_visibility(cr, k, theta, &f, uvd, n, Vr, NULL) == HL_OK, "%s", hl_context_last_error(ref));
        hl_csm_read_planes(c, k, sat, mean, t4);
        float zmin = 1.0f;
        for (size_t i = 0; i < R2; i++) zmin = fminf(zmin, z[k * R2 + i]);
        double t = tan((double)theta) * f.depth_range * R;
        hl_csm_eval_params p;
        hl_csm_params(&p, R, M, Mb, zmin, (float)(t / f.width), (float)(t / f.height));
        for (uint32_t i = 0; i < n; i++) {
            float o[2];
            hl_ref_csm_eval(sat, mean, t4, &p, uvd + 3 * i, o);
            worst = fmax(worst, fabs((double)o[0] - V[i]));
            worst_za = fmax(worst_za, fabs((double)o[1] - za[i]));
            worst_ref = fmax(worst_ref, fabs((double)Vr[i] - V[i]));
        }
    }
    /* Same tables, same float operations in the same order: they differ by
     * PoCL's sin, cos, exp and pow against libm's (an ulp or two); the
     * phases' recurrence carries that to about 1e-6 in V before the leak
     * exponent (up to 31) multiplies it: 31 x 2e-6 = 6e-5. */
    hl_check_error("V, kernel vs twin on the kernel's tables, absolute", worst, 1e-4);
    hl_check_error("z_avg, kernel vs twin on the kernel's tables, absolute", worst_za, 1e-4);
    /* End to end the tables differ too (basis planes by up to 8e-6, so
     * entries by up to R^2 x 8e-6 in the worst case): measured only. */
    printf("V, OpenCL module vs reference backend end to end: worst difference %.3g\n", worst_ref);
    free(z); free(uvd); free(V); free(za); free(Vr); free(sat); free(mean); free(t4);
    hl_csm_destroy(c);
    hl_csm_destroy(cr);
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

/* 5 lights' maps in one build, visibility of each light alone and of all
 * in one batch (each its own frame, half-extent and receivers; light 3
 * with none): the same floats. */
static int batch_matches(hl_context *ctx, const char *what)
{
    enum { K = 5 };
    const uint32_t R = 64, M = 16, Mb = 8, counts[K] = {700, 1, 1200, 0, 333};
    const size_t R2 = (size_t)R * R;
    hl_csm *c = NULL;
    if (hl_csm_create(ctx, R, M, Mb, K, &c) != HL_OK) {
        HL_CHECK(0, "%s", hl_context_last_error(ctx));
        return 0;
    }
    uint32_t start[K + 1] = {0}, ks[K];
    float theta[K];
    hl_shadow_frame fr[K];
    const hl_shadow_frame *fp[K];
    for (uint32_t j = 0; j < K; j++) {
        start[j + 1] = start[j] + counts[j];
        ks[j] = (j * 3) % K; /* the batch takes the build's lights out of order */
        theta[j] = 0.01f + 0.03f * (float)j;
        fr[j] = frame_of(R);
        fr[j].width = 8.0f + (float)j;
        fp[j] = &fr[j];
    }
    const uint32_t n = start[K];
    float *z = malloc(K * R2 * 4), *uvd = malloc(n * 12), *Va = malloc(n * 4), *Vb = malloc(n * 4);
    float *za = malloc(n * 4), *zb = malloc(n * 4);
    for (uint32_t k = 0; k < K; k++) square_map(z + k * R2, R, 10 + 3 * k, 40 + 2 * k, 0.2f + 0.1f * (float)k, 1.0f);
    random_receivers(uvd, n, R);
    int ok = hl_csm_build(c, z, K) == HL_OK;
    for (uint32_t j = 0; ok && j < K; j++)
        ok = hl_csm_visibility(c, ks[j], theta[j], fp[j], uvd + 3 * (size_t)start[j], counts[j], Va + start[j],
                               za + start[j]) == HL_OK;
    ok = ok && hl_csm_visibility_batch(c, K, ks, theta, fp, uvd, NULL, start, Vb, zb) == HL_OK;
    HL_CHECK(ok, "%s: %s", what, hl_context_last_error(ctx));
    size_t diff = 0;
    for (uint32_t i = 0; ok && i < n; i++) diff += memcmp(Va + i, Vb + i, 4) != 0 || memcmp(za + i, zb + i, 4) != 0;
    printf("%s: %u lights, %u receivers, batch against light by light\n", what, K, n);
    hl_check_error("receivers whose V or z_avg differ (tolerance 0: bit for bit)", ok ? (double)diff : 1e30, 0.0);
    free(z); free(uvd); free(Va); free(Vb); free(za); free(zb);
    hl_csm_destroy(c);
    return ok;
}

static void case_batch(void)
{
    hl_context *ctx = hl_test_cl_context(0), *ref = hl_test_ref_context(1);
    if (!ctx || !ref) { HL_CHECK(0, "no context"); return; }
    batch_matches(ctx, "one launch");
    /* the device's parameter blocks hold 2 lights at a time (read when the
       module is made): 3 launches */
    setenv("HL_TEST_CSM_BATCH", "2", 1);
    batch_matches(ctx, "2 lights a launch");
    unsetenv("HL_TEST_CSM_BATCH");
    batch_matches(ref, "reference backend");
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

enum { PR = 256, PN = 513 }; /* map size; receivers on u = 0 .. 128 every 1/4 texel */

/* V along v = PR/2, u = 0 .. 128 at depth d (the blocker's edge is at
 * u = 96: texels 96..159 hold the square) */
static void profile(hl_csm *c, float theta, float d, float *V, float *za)
{
    hl_shadow_frame f = frame_of(PR);
    float uvd[3 * PN];
    for (uint32_t i = 0; i < PN; i++) {
        uvd[3 * i] = 0.25f * (float)i;
        uvd[3 * i + 1] = PR / 2.0f;
        uvd[3 * i + 2] = d;
    }
    HL_CHECK(hl_csm_visibility(c, 0, theta, &f, uvd, PN, V, za) == HL_OK, "visibility failed");
}

/* u where V falls through level (linear between samples), -1 if never */
static double crossing(const float *V, float level)
{
    for (uint32_t i = 0; i + 1 < PN; i++)
        if (V[i] >= level && V[i + 1] < level) return 0.25 * (i + (V[i] - level) / (double)(V[i] - V[i + 1]));
    return -1;
}

static void case_plane(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_csm *c = NULL;
    HL_CHECK(hl_csm_create(ctx, PR, 16, 16, 1, &c) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!c) return;
    float *z = malloc((size_t)PR * PR * 4), V[PN], za[PN];
    square_map(z, PR, 96, 160, 0.4f, 1.0f);
    HL_CHECK(hl_csm_build(c, z, 1) == HL_OK, "%s", hl_context_last_error(ctx));
    /* tan(theta) 0.05 and 0.1 at d = 0.8, then 0.1 at d = 0.6 */
    const double tans[3] = {0.05, 0.1, 0.1}, ds[3] = {0.8, 0.8, 0.6};
    double width[3], worst_lit = 0, worst_dark = 0, worst_rise = 0, rise_near = 0, worst_w = 0, worst_za = 0;
    for (int s = 0; s < 3; s++) {
        profile(c, (float)atan(tans[s]), (float)ds[s], V, za);
        double wp = (ds[s] - 0.4) * PR * tans[s]; /* half-width in texels: (d - z) tan(theta) R / width x range */
        for (uint32_t i = 0; i < PN; i++) {
            double u = 0.25 * i;
            if (u < 96 - wp - 2) worst_lit = fmax(worst_lit, 1.0 - V[i]);
            if (u > 96 + wp + 2) worst_dark = fmax(worst_dark, V[i]);
            if (i + 1 < PN && s < 2) worst_rise = fmax(worst_rise, (double)V[i + 1] - V[i]);
            if (i + 1 < PN && s == 2) rise_near = fmax(rise_near, (double)V[i + 1] - V[i]);
            /* z_avg where the blocker fills at least a quarter of the search box */
            if (u > 96 - wp / 2 && u < 96 + wp) worst_za = fmax(worst_za, fabs(za[i] - 0.4));
        }
        /* The box filter of the edge is a ramp over [96 - wp, 96 + wp]
         * and the leak exponent p bends it: V = ramp^p. Undo p with the
         * module's own z_avg, then the ramp's 10%-90% width is 0.8 x 2 wp. */
        float ramp[PN];
        for (uint32_t i = 0; i < PN; i++) {
            double p = 1.0 + HL_CSM_LEAK_A * exp(-HL_CSM_LEAK_B * (ds[s] - za[i]));
            ramp[i] = za[i] < 0 ? V[i] : (float)pow(V[i], 1 / p);
        }
        double expect = 1.6 * wp;
        width[s] = crossing(ramp, 0.1f) - crossing(ramp, 0.9f);
        printf("tan(theta) %.2f d %.1f: ramp's 10%%-90%% width %.3f texels, expected %.3f (half-width %.2f); V's %.3f\n",
               tans[s], ds[s], width[s], expect, wp, crossing(V, 0.1f) - crossing(V, 0.9f));
        worst_w = fmax(worst_w, fabs(width[s] / expect - 1));
    }
    /* lit and dark to the series' residual (0.011 at M = 16 outside the band) and the clamp */
    hl_check_error("lit receivers outside the penumbra, 1 - V", worst_lit, 0.02);
    hl_check_error("receivers in the umbra, V", worst_dark, 0.02);
    /* monotone at d = 0.8: the ramp of a box over an edge only falls;
     * float noise of the tables only */
    hl_check_error("d = 0.8: V rising along the path into the shadow", worst_rise, 1e-4);
    /* At d = 0.6 the outer fringe is not: where the blocker fraction is
     * just above HL_CSM_BLOCKER_EPS, the lit texels' residual (about 0.01
     * of 1 - f) pulls z_avg up, p = 1 + A exp(-B (d - z_avg)) grows, and V
     * dips before the ramp (a known limit, printed). */
    printf("d = 0.6: V rising along the path into the shadow (not asserted): %.4g\n", rise_near);
    /* z_avg where the blocker fills a quarter of the search box or more:
     * the lit texels' residual 0.01 x (1 - 1/4) / (1/4) x (1 - 0.4) = 0.018 at most */
    hl_check_error("|z_avg - 0.4| in the penumbra", worst_za, 0.02);
    /* widths follow the formula: the series' smooth edge and the
     * texel-sized minimum blur it by about a texel out of 4 to 8 */
    hl_check_error("penumbra width / formula - 1", worst_w, 0.15);
    /* and scale as tan(theta): twice the tangent, twice the width (same p) */
    hl_check_error("width ratio tan 0.1 / tan 0.05, minus 2", fabs(width[1] / width[0] - 2), 0.2);

    /* beyond the far plane (d = 1.2: the series takes it as 1, the
     * widths as 1.2): lit beside the blocker, dark under it */
    profile(c, (float)atan(0.05), 1.2f, V, za);
    double far_err = 0;
    for (uint32_t i = 0; i < PN; i++) {
        double u = 0.25 * i, wp = (1.2 - 0.4) * PR * 0.05;
        if (u < 96 - wp - 2) far_err = fmax(far_err, 1.0 - V[i]);
        if (u > 96 + wp + 2) far_err = fmax(far_err, V[i]);
    }
    hl_check_error("receivers beyond the far plane: |V - lit or dark|", far_err, 0.02);

    /* acne: the receiver plane itself in the map (z = 0.8 outside the square) */
    square_map(z, PR, 96, 160, 0.4f, 0.8f);
    HL_CHECK(hl_csm_build(c, z, 1) == HL_OK, "%s", hl_context_last_error(ctx));
    profile(c, (float)atan(0.1), 0.8f, V, za);
    double acne = 0;
    for (uint32_t i = 0; i < PN; i++)
        if (0.25 * i < 96 - 10.24 - 2) acne = fmax(acne, 1.0 - V[i]);
    hl_check_error("plane in its own map (self-shadowing), 1 - V", acne, 0.02);
    free(z);
    hl_csm_destroy(c);
    hl_context_destroy(ctx);
}

/* V at the centre of the umbra for a receiver delta behind the blocker
 * (z = 0.4), with leak parameters a, b, from the module's own tables */
static float contact_v(const float *sat, const float *mean, const float *zsc, uint32_t R, float delta, float a, float b)
{
    hl_csm_eval_params p;
    double t = tan(0.05) * 10.0 * R / 10.0;
    hl_csm_params(&p, R, 16, 16, 0.4f, (float)t, (float)t);
    p.leak_a = a;
    p.leak_b = b;
    float uvd[3] = {(float)R / 2.0f, (float)R / 2.0f, 0.4f + delta}, o[2];
    hl_ref_csm_eval(sat, mean, zsc, &p, uvd, o);
    return o[0];
}

static void case_contact(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    const uint32_t R = 64, P = hl_csm_planes(16, 16);
    hl_csm *c = NULL;
    HL_CHECK(hl_csm_create(ctx, R, 16, 16, 1, &c) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!c) return;
    float *z = malloc((size_t)R * R * 4), *sat = malloc((size_t)P * R * R * 4), mean[65];
    float *t4 = malloc((size_t)R * R * 16);
    square_map(z, R, 16, 48, 0.4f, 1.0f);
    HL_CHECK(hl_csm_build(c, z, 1) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_csm_read_planes(c, 0, sat, mean, t4);
    const float bias = HL_CSM_BIAS_M / 16.0f;
    /* receivers from 3/4 of the bias to 0.03 beyond it; closer than that a
     * receiver cannot be told from the blocker's own surface (which must
     * stay lit: csm_eval.plane, acne): printed, not asserted */
    const float deltas[4] = {0.75f * bias, bias, bias + 0.01f, bias + 0.03f};
    for (int i = 1; i <= 4; i++) {
        float dl = bias * (float)i / 8;
        printf("d - z = %.4f (not asserted): V %.4g with the leak exponent, %.4g without\n", dl,
               contact_v(sat, mean, t4, R, dl, HL_CSM_LEAK_A, HL_CSM_LEAK_B),
               contact_v(sat, mean, t4, R, dl, 0.0f, HL_CSM_LEAK_B));
    }
    double with = 0, without = 1;
    for (int i = 0; i < 4; i++) {
        float v1 = contact_v(sat, mean, t4, R, deltas[i], HL_CSM_LEAK_A, HL_CSM_LEAK_B);
        float v0 = contact_v(sat, mean, t4, R, deltas[i], 0.0f, HL_CSM_LEAK_B);
        printf("d - z = %.4f: V %.4g with the leak exponent, %.4g without\n", deltas[i], v1, v0);
        with = fmax(with, v1);
        if (i < 2) without = fmin(without, v0);
    }
    hl_check_error("contact receivers with the leak exponent, V", with, 0.05);
    /* without it the same receivers leak: at least 0.3 of the light at 3/4 of the bias and at the bias */
    HL_CHECK(without > 0.3, "without the exponent contact receivers should leak (V %.4g)", without);
    printf("contact receivers without the exponent, least V at d - z <= bias: %.4g (leaks)\n", without);
    /* B: the largest of 5, 10, 15, 20 that keeps every contact receiver
     * dark (V < 0.05): the largest B bends a penumbra further behind its
     * blocker least (p - 1 = 30 exp(-B (d - z_avg))). */
    static const float Bs[4] = {5, 10, 15, 20};
    float chosen = 0;
    for (int b = 0; b < 4; b++) {
        double worst = 0;
        for (int i = 0; i < 4; i++) worst = fmax(worst, contact_v(sat, mean, t4, R, deltas[i], HL_CSM_LEAK_A, Bs[b]));
        printf("B %.0f: darkest-case contact V %.4g, p - 1 at d - z_avg = 0.2: %.3f\n", Bs[b], worst,
               HL_CSM_LEAK_A * exp(-Bs[b] * 0.2));
        if (worst < 0.05) chosen = Bs[b];
    }
    hl_check_error("HL_CSM_LEAK_B minus the B chosen here", fabs(chosen - HL_CSM_LEAK_B), 0.0);
    free(z); free(sat); free(t4);
    hl_csm_destroy(c);
    hl_context_destroy(ctx);
}

#define EXPECT_FAIL(call, ctx)                                                                  \
    do {                                                                                        \
        hl_result r_ = (call);                                                                  \
        HL_CHECK(r_ == HL_ERR_INVALID_ARGUMENT, "%s should fail (got %d)", #call, (int)r_);     \
        printf("%s -> %s\n", #call, hl_context_last_error(ctx));                                \
        bad += r_ != HL_ERR_INVALID_ARGUMENT;                                                   \
    } while (0)

static void case_bad_input(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_csm *c = NULL;
    int bad = 0;
    EXPECT_FAIL(hl_csm_create(ctx, 64, 3, 0, 1, &c), ctx);
    EXPECT_FAIL(hl_csm_create(ctx, 64, 17, 0, 1, &c), ctx);
    EXPECT_FAIL(hl_csm_create(ctx, 64, 8, 2, 1, &c), ctx);
    EXPECT_FAIL(hl_csm_create(ctx, 64, 8, 12, 1, &c), ctx);
    EXPECT_FAIL(hl_csm_create(ctx, 8, 8, 0, 1, &c), ctx);
    EXPECT_FAIL(hl_csm_create(ctx, 100, 8, 0, 1, &c), ctx);
    EXPECT_FAIL(hl_csm_create(ctx, 8192, 8, 0, 1, &c), ctx);
    EXPECT_FAIL(hl_csm_create(ctx, 64, 8, 0, 0, &c), ctx);
    HL_CHECK(hl_csm_create(ctx, 32, 0, 0, 2, &c) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!c) return;
    float z[2 * 32 * 32];
    for (int i = 0; i < 2 * 32 * 32; i++) z[i] = 0.5f;
    EXPECT_FAIL(hl_csm_build(c, z, 3), ctx);
    z[100] = NAN;
    EXPECT_FAIL(hl_csm_build(c, z, 2), ctx);
    z[100] = -0.25f;
    EXPECT_FAIL(hl_csm_build(c, z, 2), ctx);
    z[100] = INFINITY;
    EXPECT_FAIL(hl_csm_build(c, z, 2), ctx);
    z[100] = 3.0f; /* beyond the far plane: nothing blocks, accepted */
    HL_CHECK(hl_csm_build(c, z, 1) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_shadow_frame f = frame_of(32), f2 = frame_of(64), f3 = frame_of(32);
    f3.depth_range = NAN;
    float uvd[6] = {1, 1, 0.5f, 2, 2, NAN}, V[2];
    EXPECT_FAIL(hl_csm_visibility(c, 0, 0.1f, &f, uvd, 2, V, NULL), ctx);
    EXPECT_FAIL(hl_csm_visibility(c, 1, 0.1f, &f, uvd, 1, V, NULL), ctx);
    EXPECT_FAIL(hl_csm_visibility(c, 0, -0.1f, &f, uvd, 1, V, NULL), ctx);
    EXPECT_FAIL(hl_csm_visibility(c, 0, 1.6f, &f, uvd, 1, V, NULL), ctx);
    EXPECT_FAIL(hl_csm_visibility(c, 0, NAN, &f, uvd, 1, V, NULL), ctx);
    EXPECT_FAIL(hl_csm_visibility(c, 0, 0.1f, &f2, uvd, 1, V, NULL), ctx);
    EXPECT_FAIL(hl_csm_visibility(c, 0, 0.1f, &f3, uvd, 1, V, NULL), ctx);
    HL_CHECK(hl_csm_visibility(c, 0, 0.1f, &f, uvd, 1, V, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(V[0] >= 0.0f && V[0] <= 1.0f, "V %g out of [0, 1]", V[0]);
    hl_csm_destroy(c);
    /* batches: 65 planes of 256^2 floats and the texels' phases, 18.4 MB a
     * light; a device limit of 64 MiB holds 3 */
    size_t per = hl_csm_bytes_per_light(256, 16, 16);
    HL_CHECK(per == 4 * (65 * 65536 + 5 * 65536 + 65 * 256 + 65), "bytes per light %zu", per);
    HL_CHECK(hl_csm_batch_fit(256, 16, 16, 64ull << 20) == 3, "batch fit %u", hl_csm_batch_fit(256, 16, 16, 64ull << 20));
    hl_context_desc dl = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .quiet = 1,
                          .device_memory = 64ull << 20};
    hl_context *cl = NULL;
    char err[1024];
    if (hl_context_create(&dl, &cl, err, sizeof err) == HL_OK) {
        hl_result r = hl_csm_create(cl, 256, 16, 16, 4, &c);
        HL_CHECK(r == HL_ERR_OUT_OF_MEMORY, "4 lights beyond a 64 MiB device limit should fail (got %d)", (int)r);
        printf("4 lights in 64 MiB -> %s\n", hl_context_last_error(cl));
        bad += r != HL_ERR_OUT_OF_MEMORY;
        hl_csm_destroy(c);
        c = NULL;
        HL_CHECK(hl_csm_create(cl, 256, 16, 16, 3, &c) == HL_OK, "%s", hl_context_last_error(cl));
        hl_csm_destroy(c);
        hl_context_destroy(cl);
    } else {
        HL_CHECK(0, "OpenCL context: %s", err);
    }
    hl_check_error("bad inputs accepted", bad, 0);
    hl_context_destroy(ctx);
}

/* build and evaluation times on a scene of 12 square blockers a light */
static void run_timing(int ref)
{
    hl_context *ctx = ref ? hl_test_ref_context(1) : hl_test_cl_context(0);
    if (!ctx) return;
    const uint32_t R = 256, K = 4, n = 10000;
    const size_t R2 = (size_t)R * R;
    hl_csm *c = NULL;
    if (hl_csm_create(ctx, R, 16, 16, K, &c) != HL_OK) { printf("%s\n", hl_context_last_error(ctx)); return; }
    float *z = malloc(K * R2 * 4), *uvd = malloc(n * 12), *V = malloc(n * 4);
    for (uint32_t k = 0; k < K; k++) {
        for (size_t i = 0; i < R2; i++) z[k * R2 + i] = 1.0f;
        for (int b = 0; b < 12; b++) {
            uint32_t x0 = (uint32_t)(hl_rng_unit() * 200), y0 = (uint32_t)(hl_rng_unit() * 200), w = (uint32_t)(10 + hl_rng_unit() * 50);
            float zz = (float)(0.1 + 0.5 * hl_rng_unit());
            for (uint32_t j = y0; j < y0 + w && j < R; j++)
                for (uint32_t i = x0; i < x0 + w && i < R; i++) z[k * R2 + j * R + i] = zz;
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        uvd[3 * i] = (float)(hl_rng_unit() * R);
        uvd[3 * i + 1] = (float)(hl_rng_unit() * R);
        uvd[3 * i + 2] = (float)(0.3 + 0.7 * hl_rng_unit());
    }
    hl_csm_build(c, z, K); /* warm-up */
    double t0 = hl_now();
    for (int rep = 0; rep < 3; rep++) hl_csm_build(c, z, K);
    printf("%s: build (basis + tables) %.2f ms per light, R = 256, M = 16, %.1f MB a light\n", ref ? "reference" : "OpenCL",
           1e3 * (hl_now() - t0) / (3 * K), (double)hl_csm_bytes_per_light(R, 16, 16) / 1e6);
    hl_shadow_frame f = frame_of(R);
    static const float thetas[3] = {0.01f, 0.05f, 0.2f};
    for (int t = 0; t < 3; t++) {
        hl_csm_visibility(c, 0, thetas[t], &f, uvd, n, V, NULL);
        t0 = hl_now();
        for (uint32_t k = 0; k < K; k++) hl_csm_visibility(c, k, thetas[t], &f, uvd, n, V, NULL);
        printf("  theta %.2f: %.2f ms per 10^4 receivers per light\n", thetas[t], 1e3 * (hl_now() - t0) / K);
    }
    free(z); free(uvd); free(V);
    hl_csm_destroy(c);
    hl_context_destroy(ctx);
}

/* Receivers at d = 0.8 along v = R/2 from u = -2w to 2w around the left
 * edge of a map that is all blocker at z = 0.4 (w: the boxes' half-width,
 * (0.8 - 0.4) tan(theta) in texels). Outside the map there is no caster
 * (the frame's margin holds the scene's bounds), so the filter averages
 * the inside with "lit": V(0) is the series' 1/2 bent by the leak
 * exponent, and a receiver whose boxes miss the map is lit exactly. */
static void case_edge(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_csm *c = NULL;
    HL_CHECK(hl_csm_create(ctx, PR, 16, 16, 1, &c) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!c) return;
    float *z = malloc((size_t)PR * PR * 4), V[PN], za[PN], uvd[3 * PN];
    square_map(z, PR, 0, PR, 0.4f, 0.4f);
    HL_CHECK(hl_csm_build(c, z, 1) == HL_OK, "%s", hl_context_last_error(ctx));
    const double tant = 0.1, w = 0.4 * PR * tant;
    hl_shadow_frame f = frame_of(PR);
    for (uint32_t i = 0; i < PN; i++) {
        uvd[3 * i] = (float)(-2.0 * w + 4.0 * w * i / (PN - 1));
        uvd[3 * i + 1] = PR / 2.0f;
        uvd[3 * i + 2] = 0.8f;
    }
    HL_CHECK(hl_csm_visibility(c, 0, (float)atan(tant), &f, uvd, PN, V, za) == HL_OK, "visibility failed");
    double miss = 0, mid = 0, inside = 0, rise = 0;
    double p = 1.0 + HL_CSM_LEAK_A * exp(-HL_CSM_LEAK_B * 0.4), half = pow(0.5, p);
    for (uint32_t i = 0; i < PN; i++) {
        double u = uvd[3 * i];
        if (u < -w - 0.01) miss = fmax(miss, fabs(1.0 - V[i]));
        if (fabs(u) < 1e-3) mid = fmax(mid, fabs(V[i] - half));
        if (u > w + 1.0) inside = fmax(inside, V[i]);
        if (i + 1 < PN) rise = fmax(rise, (double)V[i + 1] - V[i]);
    }
    hl_check_error("boxes that miss the map, |1 - V|", miss, 0.0);
    /* the series' residual outside its band, 0.011 at M = 16, and the
     * box's float corners */
    hl_check_error("box half outside the map, |V - 0.5^p|", mid, 0.02);
    hl_check_error("boxes inside the map, V", inside, 0.02);
    hl_check_error("V rising into the map", rise, 1e-4);
    free(z);
    hl_csm_destroy(c);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"twin", case_twin}, {"plane", case_plane}, {"edge", case_edge}, {"contact", case_contact},
                                         {"batch", case_batch}, {"bad_input", case_bad_input}, {NULL, NULL}};
    if (argc >= 2 && strcmp(argv[1], "timing") == 0) {
        run_timing(argc >= 3 && strcmp(argv[2], "ref") == 0);
        return 0;
    }
    return hl_test_main(argc, argv, cases);
}
