/* test_stiff_light.c - numerical stability under stiff and extreme
 * lighting (suite "stiff_light", issue 5's "Numerical stability" list;
 * tests/stiff/test_stiff_{transport,mesh}.c hold the rest of the list).
 *
 * Each case runs the kernels on both backends (OpenCL on PoCL and the
 * plain-C reference), asserts that no output is NaN or Inf and that the two
 * backends agree (their transport files byte for byte, their colours bit
 * for bit), and, where one applies, that the colours are within a stated
 * bound of a float64 reference:
 *
 *   B_ref = albedo * sum_i T_i L_i in double, T_i the row as the dot
 *   products add it (hl_transport_query_terms: dequantised, then rounded to
 *   half precision at a per-row scale), L_i the double Haar transform of
 *   the paraboloid lighting that the plain-C env2para stage makes.
 *
 * With every lighting term kept the float result differs from B_ref by
 *   (a) the float Haar transform of the lighting, |sum_i T_i dL_i| <=
 *       |T|_2 |dL|_2 with |dL|_2 <= 6 u log2(N) |L_para|_2: each output of
 *       a 2x2 step is three rounded additions, within 1.5 u of the block's
 *       1-norm, so 3 u of its 2-norm, 6 u for the block's four outputs,
 *       and the later levels are orthonormal;
 *   (b) the float accumulation of the n products, <= gamma_n sum |T_i L_i|
 *       (recursive fused multiply-adds), and the albedo product, u |B|;
 *   with u = 2^-24. In the subnormal range each operation may add 2^-150
 *   more, absolute. Against the unquantised transport, recomputed from the
 *   rays with the plain-C stages as `haarlight bench` does, the 8-bit
 *   quantisation and the rounding to half add sum_i |L_i| (q_i + |D_i -
 *   T_i|), D_i the dequantised term (hl_transport_query_row) and q_i its
 *   quantisation error (quant_error below).
 *
 * Cases (ctest hl.stiff_light.<case>; `test_stiff_light all` runs them in turn):
 *   sun_sky        one-pixel sun at 1, 1e3, 1e5, 1e7 x a sky of 1: all
 *                  terms against the references, 200 terms against the
 *                  reported error bound
 *   black          all-black map: colours exactly 0, energy kept 1, bound 0
 *   single_pixel   one lit pixel (sky, poles, seam, at and below the
 *                  horizon): colours against B_ref; the energy the
 *                  resampling keeps, there and from pole to pole
 *   negative       negative radiance, from memory and from an EXR: clamped
 *                  to 0, counted, and lit exactly like the clamped map
 *   denormal       subnormal radiance: finite and within bound
 *   env_sizes      2x1 up to 8192x4096 (1x1 and other non-2:1 sizes
 *                  refused): constant maps stay constant, furnace, energy
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL), HL_TMP, HL_BIN,
 * tests/common/stiff_{scene,reference}.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <float.h>
#include <stdarg.h>
#include <stdint.h>
#include <sys/stat.h>

#include "exr_io.h"
#include "geom.h"
#include "hl_test.h"
#include "lighting.h"
#include "rays.h"
#include "twins.h"
#include "stiff_scene.h"
#include "stiff_reference.h"

/* ================================================================ lighting */

/* A one-pixel sun at k times a sky of 1, k = 1 (a constant map) to 1e7,
 * on the small scene, every coefficient kept (N = C = 32, log8). */
static void case_sun_sky(void)
{
    rig g;
    hl_mesh *m = open_scene(&g, 32, 32, HL_TRUNC_ALL, "sun");
    if (!m) return;
    float *raw = raw_rows(g.t[1]);
    const uint32_t W = 256, sx = 77, sy = 30;
    float *px = pixels_const(W, 1.0f), *all = need(malloc((size_t)g.V * 12));

    /* the double Haar against the library's float one, on random data:
       within the bound (a) above */
    {
        const hl_geom *gg = geom_of(32);
        float *x = need(malloc((size_t)gg->ncoef * 4)), *y = need(malloc((size_t)gg->ncoef * 4)), *w = need(malloc((size_t)gg->ncoef * 4));
        double *z = need(malloc((size_t)gg->ncoef * 8)), e2 = 0.0, n2 = 0.0;
        for (uint32_t i = 0; i < gg->ncoef; i++) {
            x[i] = y[i] = (float)(rng_unit() * 2.0 - 0.5);
            n2 += (double)x[i] * x[i];
        }
        hl_ref_haar(gg, y, w);
        haar_double(gg, x, z);
        for (uint32_t i = 0; i < gg->ncoef; i++) e2 += (w[i] - z[i]) * (w[i] - z[i]);
        hl_check_error("N=32 |float Haar - double Haar|_2 / (6 u log2 N |x|_2)", sqrt(e2 / n2) / (6.0 * U_F32 * 5), 1.0);
        free(x), free(y), free(w), free(z);
    }

    static const double suns[] = {1.0, 1e3, 1e5, 1e7};
    for (int k = 0; k < 4; k++) {
        char what[128];
        snprintf(what, sizeof what, "sun %.0e x sky", suns[k]);
        case_begin("sun_sky: %s", what);
        for (int c = 0; c < 3; c++) px[3 * ((size_t)sy * W + sx) + c] = (float)suns[k];
        hl_env *env = env_of(W, px);
        if (env && rig_run(&g, env, HL_TERMS_ALL, what)) {
            reference R;
            reference_make(&R, &g, env, raw);
            check_both(what, &g, &R, 1);
            /* M = 200: the reported bound |B - B_M| <= |T_v| |L - L_M|
               holds (grey light: every channel is the luminance) */
            memcpy(all, g.rgb[1], (size_t)g.V * 12);
            snprintf(what, sizeof what, "sun %.0e x sky, M=200", suns[k]);
            if (rig_run(&g, env, 200, what)) {
                double worst = 0.0, err_at = 0.0, bound_at = 0.0;
                for (uint32_t v = 0; v < g.V; v++)
                    for (int c = 0; c < 3; c++) {
                        const sample *s = R.S + 3 * (size_t)v + c;
                        double a = g.t[1]->mesh->albedo[3 * (size_t)v + c];
                        float B = g.rgb[1][3 * (size_t)v + c], A = all[3 * (size_t)v + c];
                        double bound = a * g.st[1].error_bound * (1.0 + 1e-5) + bound_accumulation(s, a, B) +
                                       bound_accumulation(s, a, A);
                        double e = fabs((double)B - A);
                        if (e / bound > worst) worst = e / bound, err_at = e, bound_at = bound;
                    }
                printf("%s: %u terms, energy kept %.9f, reported bound %.4g; worst |B_M - B_all| %.4g where the "
                       "bound (with rounding) is %.4g\n",
                       what, g.st[1].terms_kept, g.st[1].energy_kept, g.st[1].error_bound, err_at, bound_at);
                char w2[200];
                snprintf(w2, sizeof w2, "%s: |B_M - B_all| / (albedo x reported bound + rounding)", what);
                hl_check_error(w2, worst, 1.0);
            }
            reference_free(&R);
        }
        hl_env_destroy(env);
        case_end();
    }
    free(px);
    free(all);
    free(raw);
    close_scene(&g, m);
}

/* All black: the colours are exactly 0; with no energy to keep, the energy
 * kept is 1 and the bound 0, for every M and selection scheme. */
static void case_black(void)
{
    rig g;
    hl_mesh *m = open_scene(&g, 16, 16, HL_TRUNC_DEFAULT, "black");
    if (!m) return;
    float *px = pixels_const(64, 0.0f);
    hl_env *env = env_of(64, px);
    static const uint32_t Ms[] = {HL_TERMS_ALL, 200, 1};
    static const uint32_t sel[] = {HL_SELECT_TRANSPORT, HL_SELECT_AREA, HL_SELECT_UNWEIGHTED};
    for (int i = 0; i < 3; i++)
        for (int s = 0; s < 3; s++) {
            char what[96];
            snprintf(what, sizeof what, "black map, M=%d, selection %u", Ms[i] == HL_TERMS_ALL ? -1 : (int)Ms[i], sel[s]);
            case_begin("black: %s", what);
            if (env && rig_run_sel(&g, env, Ms[i], sel[s], what))
                for (int b = 0; b < 2; b++) {
                    size_t nz = 0;
                    for (size_t k = 0; k < (size_t)g.V * 3; k++) nz += g.rgb[b][k] != 0.0f;
                    char w[200];
                    snprintf(w, sizeof w, "%s, %s: non-zero colours", what, backend_name[b]);
                    hl_check_error(w, (double)nz, 0.0);
                    const hl_relight_stats *st = &g.st[b];
                    printf("%s, %s: terms kept %u, energy kept %g, bound %g, blocks skipped %g\n", what,
                           backend_name[b], st->terms_kept, st->energy_kept, st->error_bound, st->blocks_skipped);
                    HL_CHECK(st->energy_kept == 1.0 && st->error_bound == 0.0 && st->terms_kept == 0,
                             "no energy: energy kept must be 1, the bound 0 and no term kept");
                }
            case_end();
        }
    hl_env_destroy(env);
    free(px);
    close_scene(&g, m);
}

/* One lit pixel (1e4) on a black 512 x 256 map: in the sky, at both poles
 * and on both sides of the seam, just above and below the horizon. */
static void case_single_pixel(void)
{
    rig g;
    hl_mesh *m = open_scene(&g, 32, 32, HL_TRUNC_ALL, "pixel");
    if (!m) return;
    const uint32_t W = 512;
    static const uint32_t at[][2] = {{300, 60}, {0, 0}, {511, 255}, {511, 0}, {0, 255}, {256, 127}, {130, 128}, {77, 200}};
    float *px = pixels_const(W, 0.0f);
    for (size_t k = 0; k < sizeof at / sizeof at[0]; k++) {
        const uint32_t x = at[k][0], y = at[k][1];
        char what[96];
        snprintf(what, sizeof what, "pixel (%u, %u) of %ux%u at 1e4", x, y, W, W / 2);
        case_begin("single_pixel: %s", what);
        for (int c = 0; c < 3; c++) px[3 * ((size_t)y * W + x) + c] = 1e4f;
        hl_env *env = env_of(W, px);
        if (env && rig_run(&g, env, HL_TERMS_ALL, what)) {
            reference R;
            reference_make(&R, &g, env, NULL);
            check_both(what, &g, &R, 0);
            /* the resampling keeps the pixel's energy */
            double want = 1e4 * pixel_omega(W, y), got = lighting_energy(&R.L, 0);
            char w[256];
            snprintf(w, sizeof w, "%s: paraboloid energy %.6g vs the pixel's %.6g (relative)", what, got, want);
            hl_check_error(w, fabs(got - want) / want, ENERGY_TOL);
            reference_free(&R);
        }
        hl_env_destroy(env);
        for (int c = 0; c < 3; c++) px[3 * ((size_t)y * W + x) + c] = 0.0f;
        case_end();
    }
    free(px);
    /* the energy from pole to pole, at N = 32 and 64: one pixel (half a
       cell a side) in every 4th row and in the eight rows at the horizon,
       each in another column */
    for (uint32_t N = 32; N <= 64; N *= 2) {
        case_begin("single_pixel: energy from pole to pole, N=%u", N);
        const uint32_t Wn = 16 * N;
        hl_light_geom *lg = NULL;
        HL_CHECK(hl_light_geom_create(ref_ctx(), geom_of(N), &lg) == HL_OK, "tables");
        float *pn = pixels_const(Wn, 0.0f);
        double worst = 0.0;
        uint32_t worst_y = 0, rows = 0;
        for (uint32_t y = 0; y < Wn / 2 && lg; y++) {
            if (y % 4 != 0 && (y + 4 < Wn / 4 || y >= Wn / 4 + 4)) continue;
            const uint32_t x = (y * 37u) % Wn;
            for (int c = 0; c < 3; c++) pn[3 * ((size_t)y * Wn + x) + c] = 1e4f;
            hl_env *env = env_of(Wn, pn);
            if (env) {
                lighting L;
                lighting_make(&L, lg, env);
                double want = 1e4 * pixel_omega(Wn, y), e = fabs(lighting_energy(&L, 0) - want) / want;
                if (!(e <= worst)) worst = e, worst_y = y;
                lighting_free(&L);
                rows++;
            }
            hl_env_destroy(env);
            for (int c = 0; c < 3; c++) pn[3 * ((size_t)y * Wn + x) + c] = 0.0f;
        }
        char w[160];
        snprintf(w, sizeof w, "N=%u one pixel of 1e4 in %u rows of %u: paraboloid energy vs the pixel's (relative; worst at row %u)",
                 N, rows, Wn / 2, worst_y);
        hl_check_error(w, worst, ENERGY_TOL);
        hl_light_geom_destroy(lg);
        free(pn);
        case_end();
    }
    close_scene(&g, m);
}

/* Negative radiance is clamped to 0 on load and counted; the map then
 * lights exactly like its clamped copy. From memory and from an EXR. */
static void case_negative(void)
{
    rig g;
    hl_mesh *m = open_scene(&g, 16, 16, HL_TRUNC_DEFAULT, "negative");
    if (!m) return;
    const uint32_t W = 128, H = 64;
    const size_t n = (size_t)W * H * 3;
    float *px = need(malloc(n * 4)), *clamped = need(malloc(n * 4)), *lit = need(malloc((size_t)g.V * 12));
    uint64_t negative = 0;
    for (size_t p = 0; p < (size_t)W * H; p++) {
        int neg = 0;
        for (int c = 0; c < 3; c++) {
            /* negatives at least 0.01 below zero */
            float v = hl_rng_next() % 3 == 0 ? -(float)(0.01 + rng_unit()) : (float)(2.0 * rng_unit());
            if (p == 5) v = -FLT_MAX;
            px[3 * p + c] = v;
            clamped[3 * p + c] = v < 0.0f ? 0.0f : v;
            neg |= v < 0.0f;
        }
        negative += (uint64_t)neg;
    }
    for (int src = 0; src < 2; src++) {
        case_begin("negative: %s", src ? "EXR file" : "from memory");
        hl_env *env = NULL, *ref = NULL;
        hl_env_stats st = {0, 0};
        uint64_t want = negative;
        const float *want_px = clamped; /* the file holds 32-bit floats: the same map */
        if (src == 0) {
            HL_CHECK(hl_env_create(ref_ctx(), W, H, px, &env, &st) == HL_OK, "create");
        } else {
            /* a float file: -FLT_MAX stays as it is */
            const char *path = hl_test_tmp_path("stiff_negative.exr");
            HL_CHECK(hl_exr_write_rgb_(ref_ctx(), path, W, H, px) == HL_OK, "write: %s", hl_context_last_error(ref_ctx()));
            HL_CHECK(hl_env_load(ref_ctx(), path, &env, &st) == HL_OK, "load: %s", hl_context_last_error(ref_ctx()));
            remove(path);
        }
        if (env) {
            printf("negative pixels counted %llu, expected %llu\n", (unsigned long long)st.negative_pixels,
                   (unsigned long long)want);
            HL_CHECK(st.negative_pixels == want && st.nonfinite_pixels == 0, "negative pixels miscounted");
            size_t bad = 0;
            for (size_t i = 0; i < n; i++) bad += memcmp(env->rgb + i, want_px + i, 4) != 0;
            hl_check_error("channels not equal to max(0, x)", (double)bad, 0.0);
            ref = env_of(W, want_px);
        }
        if (env && ref && rig_run(&g, env, HL_TERMS_ALL, "negative map") ) {
            memcpy(lit, g.rgb[1], (size_t)g.V * 12);
            reference R;
            reference_make(&R, &g, env, NULL);
            check_both("negative map", &g, &R, 0);
            reference_free(&R);
            if (rig_run(&g, ref, HL_TERMS_ALL, "clamped map")) {
                size_t diff = 0;
                for (size_t i = 0; i < (size_t)g.V * 3; i++) diff += memcmp(lit + i, g.rgb[1] + i, 4) != 0;
                hl_check_error("colours of the negative map vs its clamped copy (bits)", (double)diff, 0.0);
            }
        }
        hl_env_destroy(env);
        hl_env_destroy(ref);
        case_end();
    }
    free(px);
    free(clamped);
    free(lit);
    close_scene(&g, m);
}

/* Subnormal radiance: everywhere (1e-40, and the least subnormal), and as
 * noise on a sky of 1: finite and within the bound (with the subnormal
 * floor); and everywhere at N = 128: finite, OpenCL = reference. How much
 * slower a subnormal map relights is measured by `haarlight bench` (its
 * subnormal lighting table), not asserted here. */
static void case_denormal(void)
{
    rig g;
    hl_mesh *m = open_scene(&g, 32, 16, HL_TRUNC_ALL, "denormal");
    if (!m) return;
    const uint32_t W = 256;
    const size_t n = (size_t)W * (W / 2) * 3;
    for (int k = 0; k < 3; k++) {
        static const char *const name[3] = {"1e-40 everywhere", "least subnormal everywhere", "sky of 1, subnormal noise"};
        case_begin("denormal: %s", name[k]);
        float *px = need(malloc(n * 4));
        for (size_t i = 0; i < n; i++)
            px[i] = k == 0 ? 1e-40f : k == 1 ? FLT_TRUE_MIN : (i / 3) % 2 ? 1.0f : (float)(rng_unit() * 1e-38);
        hl_env *env = env_of(W, px);
        if (env && rig_run(&g, env, HL_TERMS_ALL, name[k])) {
            reference R;
            reference_make(&R, &g, env, NULL);
            check_both(name[k], &g, &R, 0);
            size_t lit = 0;
            for (size_t i = 0; i < (size_t)g.V * 3; i++) lit += g.rgb[1][i] > 0.0f;
            printf("%s: %zu of %u colours non-zero; energy kept %g, bound %g\n", name[k], lit, 3 * g.V,
                   g.st[1].energy_kept, g.st[1].error_bound);
            reference_free(&R);
        }
        hl_env_destroy(env);
        free(px);
        case_end();
    }
    rig_close(&g);
    /* at N = 128 (1.4 million stored terms, all of them lit): a 1024 x 512
       map of subnormals */
    case_begin("denormal: N=128");
    hl_precompute_desc dt = {.N = 128, .C = 8, .rule = HL_TRUNC_ALL};
    const uint32_t Wt = 1024;
    float *ps = pixels_const(Wt, 3e-39f);
    hl_env *es = env_of(Wt, ps);
    if (es && rig_open(&g, precompute_both(m, &dt, "denormal_n128"))) {
        rig_run(&g, es, HL_TERMS_ALL, "subnormal map at N=128");
        rig_close(&g);
    }
    hl_env_destroy(es);
    free(ps);
    case_end();
    hl_mesh_destroy(m);
}

/* 2x1 up to 8192x4096. A constant map stays constant on every texel, the
 * open quad sees B = 1, a random map keeps its energy, and the colours are
 * within the bound; 1x1 and every other non-2:1 size are refused. */
static void case_env_sizes(void)
{
    case_begin("env_sizes: refusals");
    {
        static const uint32_t bad[][2] = {{1, 1}, {0, 0}, {2, 2}, {4, 1}, {1, 2}, {3, 1}};
        float px[64] = {0};
        for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
            hl_env *e = NULL;
            hl_result r = hl_env_create(ref_ctx(), bad[k][0], bad[k][1], px, &e, NULL);
            const char *msg = hl_context_last_error(ref_ctx());
            printf("%u x %u: %s: %s\n", bad[k][0], bad[k][1], hl_result_string(r), msg);
            HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && !e && strstr(msg, "equirectangular"),
                     "%u x %u must be refused as not equirectangular", bad[k][0], bad[k][1]);
        }
        /* a 1x1 OpenEXR file */
        const char *path = hl_test_tmp_path("stiff_1x1.exr");
        HL_CHECK(hl_exr_write_rgb_(ref_ctx(), path, 1, 1, px) == HL_OK, "write 1x1");
        hl_env *e = NULL;
        hl_result r = hl_env_load(ref_ctx(), path, &e, NULL);
        const char *msg = hl_context_last_error(ref_ctx());
        printf("1x1 EXR: %s: %s\n", hl_result_string(r), msg);
        HL_CHECK(r == HL_ERR_FORMAT && !e && strstr(msg, path), "a 1x1 EXR must be refused, naming the file");
        remove(path);
    }
    case_end();

    hl_mesh *m = quad_mesh();
    hl_precompute_desc d = {.N = 16, .C = 16, .rule = HL_TRUNC_ALL, .quant = HL_QUANT_LINEAR8};
    rig g;
    if (!rig_open(&g, precompute_both(m, &d, "sizes"))) return;
    for (uint32_t W = 2; W <= 8192; W *= 2) {
        const uint32_t H = W / 2;
        case_begin("env_sizes: %ux%u", W, H);
        double t0 = hl_now();
        float *px = need(malloc((size_t)W * H * 12));
        for (int kind = 0; kind < 2; kind++) {
            double want = 0.0;
            for (uint32_t y = 0; y < H; y++) {
                double row = 0.0;
                for (size_t i = 3 * (size_t)y * W; i < 3 * ((size_t)y + 1) * W; i += 3) {
                    float v = kind == 0 ? 1.0f : (float)(0.5 + rng_unit());
                    px[i] = px[i + 1] = px[i + 2] = v;
                    row += v;
                }
                want += row * pixel_omega(W, y);
            }
            hl_env *env = NULL;
            if (W == 2 && kind == 1) {
                /* the smallest size through a file as well */
                const char *path = hl_test_tmp_path("stiff_2x1.exr");
                px[0] = px[1] = px[2] = 1.0f;
                px[3] = px[4] = px[5] = 3.0f;
                want = 2.0 * HL_PI * (1.0 + 3.0);
                HL_CHECK(hl_exr_write_rgb_(ref_ctx(), path, 2, 1, px) == HL_OK, "write 2x1");
                HL_CHECK(hl_env_load(ref_ctx(), path, &env, NULL) == HL_OK, "2x1 EXR: %s", hl_context_last_error(ref_ctx()));
                remove(path);
            } else {
                env = env_of(W, px);
            }
            char what[96];
            snprintf(what, sizeof what, "%ux%u %s", W, H, kind ? "random" : "constant 1");
            if (!env || !rig_run(&g, env, HL_TERMS_ALL, what)) {
                hl_env_destroy(env);
                continue;
            }
            reference R;
            reference_make(&R, &g, env, NULL);
            check_both(what, &g, &R, 0);
            const hl_geom *gg = geom_of(R.L.N);
            if (kind == 0) {
                double worst = 0.0, wb = 0.0;
                for (uint32_t j = 0; j < R.L.nc; j++)
                    if (gg->omega[j] > 0.0f) worst = fmax(worst, fabs(R.L.Lp[j] - 1.0));
                char w[160];
                snprintf(w, sizeof w, "%s: every texel 1", what);
                hl_check_error(w, worst, 1e-5);
                for (size_t i = 0; i < (size_t)g.V * 3; i++) wb = fmax(wb, fabs(g.rgb[1][i] - 1.0));
                /* the furnace at N = C = 16 (hl.analytic.furnace: moments
                   1 / N^2) plus linear 8-bit steps (hl.relight.furnace) */
                snprintf(w, sizeof w, "%s: open quad |B - 1|", what);
                hl_check_error(w, wb, 1.0 / 256 + 5e-3);
            } else {
                double got = lighting_energy(&R.L, 0);
                char w[256];
                snprintf(w, sizeof w, "%s: paraboloid energy %.6g vs the map's %.6g (relative)", what, got, want);
                hl_check_error(w, fabs(got - want) / want, ENERGY_TOL);
            }
            reference_free(&R);
            hl_env_destroy(env);
        }
        free(px);
        printf("%ux%u: %.2f s\n", W, H, hl_now() - t0);
        case_end();
    }
    rig_close(&g);
    hl_mesh_destroy(m);
}

static const hl_test_case stiff_cases[] = {
    {"sun_sky", case_sun_sky},
    {"black", case_black},
    {"single_pixel", case_single_pixel},
    {"negative", case_negative},
    {"denormal", case_denormal},
    {"env_sizes", case_env_sizes},
    {NULL, NULL},
};

int main(int argc, char **argv) { return stiff_main(argc, argv, stiff_cases); }
