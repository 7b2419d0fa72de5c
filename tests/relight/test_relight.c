/* test_relight.c - the sparse dot products (kernels/relight/relight.cl
 * and its plain-C twin host/src/relight/twins/relight.c) and whole
 * relights through the public API, suite "relight".
 *
 * relight.twin         lighting Haar, selection and dot products: OpenCL
 *                      equals C bit for bit, both walks of the kernel
 *                      (by tile, by column) and the ranges' balance.
 * relight.twin_passes  the same with the tile walk in passes of 3 tiles.
 * relight.relighter    whole relights against the exact discrete sum.
 * relight.into         colours left on the device equal the read-back ones.
 * relight.furnace      an open vertex under a white sky gives its albedo.
 * relight.orientation  the shading follows docs/CONVENTIONS.md's
 *                      directions and turn.
 * relight.extreme      very bright and very dim lighting stay finite and
 *                      scale.
 * relight.negative     no light below zero comes out; the clamp's count and
 *                      lowest value, tallied by the kernel (by column and
 *                      from the rows), match those of the colours.
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL),
 * tests/common/light_util.h.
 */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include <stdint.h>

#include "cl_backend.h"
#include "geom.h"
#include "half.h"
#include "haarlight_tools.h"
#include "hl_test.h"
#include "lighting.h"
#include "twins.h"
#include "light_util.h"

static void case_twin(void) { lighting_chain(1); }

/* The same with the tile walk's passes 3 tiles long (HL_TEST_SUM_TILES,
 * a build option of the kernels): each range walked in several passes,
 * each starting inside a word of tile bits. The tile walk is the CPU
 * shape's (its ranges a core each), so the case asks for that shape
 * whatever the device: the GPU shape has no passes. */
static void case_twin_passes(void)
{
    setenv("HL_TEST_SUM_TILES", "3", 1);
    setenv("HL_DEVICE_SHAPE", "cpu", 1);
    lighting_chain(1);
    unsetenv("HL_TEST_SUM_TILES");
}

/* Whole relights through the public API. */
static void case_relighter(void)
{
    const char *path = make_transport("light_c.hlt", "--terms all --quant linear8");
    for (int backend = 0; backend < 2; backend++) {
        hl_context *ctx = ctx_of(backend ? HL_BACKEND_REFERENCE : HL_BACKEND_OPENCL);
        hl_transport *t = NULL;
        HL_CHECK(path && hl_transport_load(ctx, path, &t) == HL_OK, "transport");
        if (!t) return;
        const uint32_t V = t->info.vertex_count, nc = 2 * t->info.N * t->info.N;
        hl_relighter *r = NULL;
        HL_CHECK(hl_relighter_create(ctx, t, &r) == HL_OK, "%s", hl_context_last_error(ctx));
        hl_env *env = make_env(ctx, 256, 40, 20, 5e3f);
        HL_CHECK(hl_relighter_set_env(r, env) == HL_OK, "set env");
        float *rgb = malloc((size_t)V * 12);
        hl_relight_stats st;
        hl_relight_desc d = {.terms = HL_TERMS_ALL, .rotate_deg = 33.0f};
        HL_CHECK(hl_relighter_run(r, &d, rgb, &st) == HL_OK, "%s", hl_context_last_error(ctx));
        /* exact discrete result in float64: sum over the row as the dot
           products add it (hl_transport_query_terms) of T_i times the Haar
           lighting */
        hl_geom *g = NULL;
        hl_light_geom *lg = NULL;
        hl_geom_create(ctx, t->info.N, t->info.C, &g);
        hl_light_geom_create(ctx, g, &lg);
        float *cells = NULL, *Lp = malloc((size_t)nc * 12), *Lw = malloc((size_t)nc * 12), *row = malloc((size_t)nc * 4);
        hl_env_to_cells(ctx, env, lg->wc, lg->hc, &cells);
        uint32_t s0;
        float f;
        hl_rotation_to_shift(33.0f, lg->wc, &s0, &f);
        hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, s0, f, nc, Lp);
        for (int c = 0; c < 3; c++) hl_ref_haar(g, Lp + (size_t)c * nc, Lw + (size_t)c * nc);
        double worst = 0.0, scale = 0.0, worst_half = 0.0;
        float *code = malloc((size_t)nc * 4);
        for (uint32_t v = 0; v < V; v++) {
            hl_transport_query_terms(t, v, row); /* the terms as the dot products add them */
            /* each within 2^-11 of the dequantised term, or 2^-24 of the
               row's largest magnitude (2^-25 of 2^e, half.h) */
            hl_transport_query_row(t, v, code);
            const int ex = hl_half_exponent(t->info.quant, t->row_quant[v].a, t->row_quant[v].b);
            for (uint32_t i = 0; i < nc; i++)
                worst_half = fmax(worst_half, fabs((double)row[i] - code[i]) /
                                                  (ldexp(fabs((double)code[i]), -11) + ldexp(1.0, ex - 25)));
            for (int c = 0; c < 3; c++) {
                double exact = 0.0;
                for (uint32_t i = 0; i < nc; i++) exact += (double)row[i] * Lw[(size_t)c * nc + i];
                exact *= t->mesh->albedo[3 * v + c];
                worst = fmax(worst, fabs(exact - rgb[3 * v + c]));
                scale = fmax(scale, fabs(exact));
            }
        }
        free(code);
        hl_check_error("terms rounded to half: |term - dequantised| / (2^-11 |dequantised| + 2^(e-25))", worst_half,
                       1.0);
        char what[128];
        snprintf(what, sizeof what, "%s, all terms: vs float64 sum over the stored rows (relative to max)",
                 backend ? "reference" : "OpenCL");
        /* float accumulation of up to 2 N^2 terms against float64 */
        hl_check_error(what, worst / scale, 1e-5);
        HL_CHECK(st.energy_kept > 0.999999 && st.error_bound < 1e-3 * scale, "all terms keep all energy (%g, bound %g)",
                 st.energy_kept, st.error_bound);
        /* fewer terms: the energy kept falls, the bound holds */
        hl_relight_desc d2 = {.terms = 50, .rotate_deg = 33.0f};
        float *rgb2 = malloc((size_t)V * 12);
        hl_relighter_run(r, &d2, rgb2, &st);
        double werr = 0.0;
        for (size_t i = 0; i < (size_t)V * 3; i++) werr = fmax(werr, fabs((double)rgb2[i] - rgb[i]));
        printf("M=50: energy kept %.5f, bound %.4g, worst |B - B_all| %.4g, %.0f%% of blocks skipped\n", st.energy_kept,
               st.error_bound, werr, 100 * st.blocks_skipped);
        /* the bound is on luminance with albedo 1; albedo <= 1 and the
           channels of this map stay within 1.5 x its luminance */
        HL_CHECK(werr <= 1.5 * st.error_bound + 1e-6, "error %g exceeds the bound %g", werr, st.error_bound);
        /* the same request again does no work */
        hl_relighter_run(r, &d2, rgb2, &st);
        HL_CHECK(st.reused == 1, "an unchanged request must be reused");
        free(rgb2);
        free(rgb); free(Lp); free(Lw); free(row);
        hl_free_big(cells);
        hl_light_geom_destroy(lg);
        hl_geom_destroy(g);
        hl_env_destroy(env);
        hl_relighter_destroy(r);
        hl_transport_destroy(t);
        hl_context_destroy(ctx);
    }
}

/* Colours left on the device (the viewer's GL interop path, here with a
 * plain buffer, since PoCL shares no GL buffers): bit-identical to the
 * read-back path, which still works after; a short buffer and the
 * reference backend are refused by name. */
static void case_into(void)
{
    const char *path = make_transport("light_i.hlt", "");
    hl_context *ctx = ctx_of(HL_BACKEND_OPENCL), *ref = ctx_of(HL_BACKEND_REFERENCE);
    hl_transport *t = NULL;
    HL_CHECK(path && ctx && hl_transport_load(ctx, path, &t) == HL_OK, "transport");
    if (!t) return;
    const uint32_t V = t->info.vertex_count;
    hl_relighter *r = NULL, *rr = NULL;
    HL_CHECK(hl_relighter_create(ctx, t, &r) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_relighter_create(ref, t, &rr) == HL_OK, "%s", hl_context_last_error(ref));
    hl_env *env = make_env(ctx, 256, 70, 30, 2e3f);
    HL_CHECK(hl_relighter_set_env(r, env) == HL_OK && hl_relighter_set_env(rr, env) == HL_OK, "set env");
    float *rgb = malloc((size_t)V * 12), *rgb2 = malloc((size_t)V * 12), *b4 = malloc((size_t)V * 16);
    void *buf = NULL, *small = NULL;
    HL_CHECK(hl_cl_buffer(ctx, (size_t)V * 16, &buf) == HL_OK && hl_cl_buffer(ctx, (size_t)V * 16 - 16, &small) == HL_OK,
             "buffers");
    hl_relight_stats st, st2;
    uint32_t diff = 0;
    for (int k = 0; k < 3; k++) {
        hl_relight_desc d = {.terms = 60u + 70u * (uint32_t)k, .rotate_deg = 10.0f + 41.0f * (float)k};
        HL_CHECK(hl_relighter_run(r, &d, rgb, &st) == HL_OK, "%s", hl_context_last_error(ctx));
        memset(b4, 0xff, (size_t)V * 16);
        HL_CHECK(hl_relighter_run_into(r, &d, buf, 0, &st2) == HL_OK, "%s", hl_context_last_error(ctx));
        HL_CHECK(!st2.reused, "a new target must be written, not reused");
        HL_CHECK(hl_cl_buffer_read(ctx, buf, (size_t)V * 16, b4) == HL_OK, "read");
        HL_CHECK(st.terms_kept == st2.terms_kept && st.energy_kept == st2.energy_kept, "same statistics");
        for (uint32_t v = 0; v < V; v++) {
            diff += !(b4[4 * (size_t)v + 3] <= 0.0f); /* the lowest channel before the clamp */
            for (int c = 0; c < 3; c++) diff += memcmp(&b4[4 * (size_t)v + c], &rgb[3 * (size_t)v + c], 4) != 0;
        }
        /* the read-back path again, on new settings: the kernel's output
           argument must be its own buffer once more */
        d.rotate_deg += 5.0f;
        HL_CHECK(hl_relighter_run(r, &d, rgb, &st) == HL_OK && hl_relighter_run(rr, &d, rgb2, &st2) == HL_OK, "runs");
        for (size_t i = 0; i < (size_t)V * 3; i++) diff += memcmp(&rgb[i], &rgb2[i], 4) != 0;
    }
    printf("into: %u vertices x 3 settings, %u words differ (tolerance 0: bit-identical)\n", V, diff);
    HL_CHECK(diff == 0, "%u words differ between the device buffer, the read-back and the reference", diff);
    hl_relight_desc d = {.terms = 77};
    HL_CHECK(hl_relighter_run_into(r, &d, small, 0, &st) == HL_ERR_INVALID_ARGUMENT &&
                 strstr(hl_context_last_error(ctx), "colour buffer holds"),
             "a short buffer must be refused: %s", hl_context_last_error(ctx));
    HL_CHECK(hl_relighter_run_into(rr, &d, buf, 0, &st) == HL_ERR_INVALID_ARGUMENT &&
                 strstr(hl_context_last_error(ref), "OpenCL backend"),
             "the reference must refuse: %s", hl_context_last_error(ref));
    /* sharing properties a device may refuse: then a clear error, no context */
    intptr_t props[] = {0x2008 /* CL_GL_CONTEXT_KHR */, 1, 0x200A /* CL_GLX_DISPLAY_KHR */, 1, 0};
    hl_context_desc cd = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .cl_properties = props};
    hl_context *gc = NULL;
    char err[4096] = "";
    hl_result gr = hl_context_create(&cd, &gc, err, sizeof err);
    printf("into: a context with bogus GL sharing properties: %s\n", gr == HL_OK ? "accepted" : err);
    HL_CHECK(gr != HL_OK ? gc == NULL && strstr(err, "sharing properties") != NULL : gc != NULL,
             "refused properties must fail with the reason: %s", err);
    /* PoCL accepts them; it must then never be asked to wrap a GL buffer
       (its clCreateFromGLBuffer aborts the process), which is why the
       viewer tries interop only on devices listing cl_khr_gl_sharing */
    hl_context_destroy(gc);
    hl_cl_buffer_release(ctx, buf);
    hl_cl_buffer_release(ctx, small);
    free(rgb); free(rgb2); free(b4);
    hl_env_destroy(env);
    hl_relighter_destroy(r);
    hl_relighter_destroy(rr);
    hl_transport_destroy(t);
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

/* An open, upward-facing vertex under a white sky of radiance 1: B =
 * albedo. A flat quad has no occlusion at all. */
static void case_furnace(void)
{
    hl_context *ctx = ctx_of(HL_BACKEND_OPENCL);
    char obj[1024], hlt[1024], cmd[4096];
    snprintf(obj, sizeof obj, "%s/light_quad.obj", hl_test_env("HL_TMP", "/tmp"));
    snprintf(hlt, sizeof hlt, "%s/light_quad.hlt", hl_test_env("HL_TMP", "/tmp"));
    FILE *f = fopen(obj, "w");
    fputs("v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\nf 1 4 3\n", f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "'%s' precompute '%s' -o '%s' -q --albedo 1 --quant linear8 --terms all", hl_test_env("HL_BIN", "haarlight"), obj, hlt);
    HL_CHECK(system(cmd) == 0, "precompute");
    hl_transport *t = NULL;
    HL_CHECK(hl_transport_load(ctx, hlt, &t) == HL_OK, "load");
    if (!t) return;
    hl_relighter *r = NULL;
    hl_relighter_create(ctx, t, &r);
    float *px = malloc(64 * 32 * 12);
    for (int i = 0; i < 64 * 32 * 3; i++) px[i] = 1.0f;
    hl_env *env = NULL;
    hl_env_create(ctx, 64, 32, px, &env, NULL);
    hl_relighter_set_env(r, env);
    float rgb[12];
    hl_relight_desc d = {.terms = HL_TERMS_ALL};
    HL_CHECK(hl_relighter_run(r, &d, rgb, NULL) == HL_OK, "run");
    double worst = 0.0;
    for (int i = 0; i < 12; i++) worst = fmax(worst, fabs(rgb[i] - 1.0));
    /* cube texels straddling the horizon (4.4e-5 at C = N = 64, see
       hl.analytic.furnace) plus linear 8-bit quantisation of the row */
    hl_check_error("white furnace through the relighter, |B - 1|", worst, 5e-3);
    free(px);
    hl_env_destroy(env);
    hl_relighter_destroy(r);
    hl_transport_destroy(t);
    hl_context_destroy(ctx);
}

/* The lighting follows docs/CONVENTIONS.md end to end. Small triangles facing +-X,
 * +-Y, +-Z and two oblique ways, far apart (nothing shadows them), albedo
 * 1, are relit with every term under a lobe max(0, w.d)^8 about an
 * oblique d, turned by 0, 90 and 200 degrees. Each colour must match the
 * same map integrated here over its pixels, with directions and the turn
 * written out from docs/CONVENTIONS.md (not taken from env.c): B = 1/pi sum_p L_p
 * max(0, n . R_y(deg) w_p) omega_p. A mirrored axis, or a turn the wrong
 * way round, swaps bright and dark faces. Tolerance: 0.05 of the
 * brightest face; N = C = 32 and the cell grid give 0.009 to 0.018, while
 * the expectation turned the wrong way gave 0.49 to 1.0, and with z
 * mirrored 0.90 to 1.0. */
#define ORI_FACES 8
static void case_orientation(void)
{
    static const float nrm[ORI_FACES][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},         {0, -1, 0},
                                            {0, 0, 1},  {0, 0, -1}, {0.6f, 0.48f, 0.64f}, {-0.48f, 0.6f, -0.64f}};
    float P[ORI_FACES * 9], Nv[ORI_FACES * 9], A[ORI_FACES * 9];
    uint32_t I[ORI_FACES * 3];
    for (int f = 0; f < ORI_FACES; f++) {
        /* a triangle of side 0.02 about (20 f, 0, 0), in the plane normal to n */
        const float *n = nrm[f];
        float t[3] = {n[1] - n[2], n[2] - n[0], n[0] - n[1]}; /* orthogonal to n */
        float tl = sqrtf(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
        float b[3] = {n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]};
        for (int c = 0; c < 3; c++) {
            t[c] /= tl;
            b[c] /= tl;
        }
        static const float corner[3][2] = {{0, 0}, {0.02f, 0}, {0, 0.02f}};
        for (int k = 0; k < 3; k++) {
            for (int c = 0; c < 3; c++) {
                P[9 * f + 3 * k + c] = (c == 0 ? 20.0f * (float)f : 0.0f) + corner[k][0] * t[c] + corner[k][1] * b[c];
                Nv[9 * f + 3 * k + c] = n[c];
                A[9 * f + 3 * k + c] = 1.0f;
            }
            I[3 * f + k] = (uint32_t)(3 * f + k);
        }
    }
    /* the lobe, on a 256 x 128 map */
    const uint32_t W = 256, H = 128;
    const double d[3] = {0.3, 0.5, 0.81};
    double dl = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    float *px = malloc((size_t)W * H * 12);
    double *wdir = malloc((size_t)W * H * 3 * sizeof(double)), *om = malloc((size_t)H * sizeof(double));
    for (uint32_t y = 0; y < H; y++) {
        om[y] = 2.0 * HL_PI / W * (cos(HL_PI * y / H) - cos(HL_PI * (y + 1) / H));
        for (uint32_t x = 0; x < W; x++) {
            double phi = 2.0 * HL_PI * ((x + 0.5) / W - 0.5), th = HL_PI * (y + 0.5) / H;
            double *w = wdir + 3 * ((size_t)y * W + x);
            w[0] = sin(th) * cos(phi);
            w[1] = cos(th);
            w[2] = sin(th) * sin(phi);
            double c = (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dl;
            float L = c > 0 ? (float)pow(c, 8.0) : 0.0f;
            for (int k = 0; k < 3; k++) px[3 * ((size_t)y * W + x) + k] = L;
        }
    }
    /* the expected colours, per turn and face, and the brightest per turn */
    static const float turns[] = {0.0f, 90.0f, 200.0f};
    enum { TURNS = sizeof turns / sizeof turns[0] };
    double want[TURNS][ORI_FACES], top[TURNS];
    for (size_t k = 0; k < TURNS; k++) {
        double cs = cos(turns[k] * HL_PI / 180.0), sn = sin(turns[k] * HL_PI / 180.0);
        top[k] = 0.0;
        for (int f = 0; f < ORI_FACES; f++) {
            double acc = 0.0;
            for (size_t p = 0; p < (size_t)W * H; p++) {
                const double *w = wdir + 3 * p;
                /* R_y(deg) w, right-handed: +Z goes to +X at 90 */
                double rw[3] = {w[0] * cs + w[2] * sn, w[1], -w[0] * sn + w[2] * cs};
                double c = nrm[f][0] * rw[0] + nrm[f][1] * rw[1] + nrm[f][2] * rw[2];
                if (c > 0) acc += px[3 * p] * c * om[p / W];
            }
            want[k][f] = acc / HL_PI;
            top[k] = fmax(top[k], want[k][f]);
        }
    }
    for (int backend = 0; backend < 2; backend++) {
        hl_context *ctx = ctx_of(backend ? HL_BACKEND_REFERENCE : HL_BACKEND_OPENCL);
        hl_mesh *m = NULL;
        hl_transport *t = NULL;
        hl_relighter *r = NULL;
        hl_env *env = NULL;
        char hlt[1024];
        snprintf(hlt, sizeof hlt, "%s/light_orientation_%d.hlt", hl_test_env("HL_TMP", "/tmp"), backend);
        hl_precompute_desc pd = {.N = 32, .C = 32, .rule = HL_TRUNC_ALL};
        hl_result res = hl_mesh_create(ctx, 3 * ORI_FACES, P, Nv, A, ORI_FACES, I, &m);
        if (res == HL_OK) res = hl_precompute(ctx, m, &pd, hlt, NULL);
        if (res == HL_OK) res = hl_transport_load(ctx, hlt, &t);
        if (res == HL_OK) res = hl_relighter_create(ctx, t, &r);
        if (res == HL_OK) res = hl_env_create(ctx, W, H, px, &env, NULL);
        if (res == HL_OK) res = hl_relighter_set_env(r, env);
        HL_CHECK(res == HL_OK, "orientation scene: %s", hl_context_last_error(ctx));
        for (size_t k = 0; res == HL_OK && k < TURNS; k++) {
            float rgb[3 * 3 * ORI_FACES];
            hl_relight_desc rd = {.terms = HL_TERMS_ALL, .rotate_deg = turns[k]};
            res = hl_relighter_run(r, &rd, rgb, NULL);
            HL_CHECK(res == HL_OK, "relight: %s", hl_context_last_error(ctx));
            if (res != HL_OK) break;
            double worst = 0.0;
            printf("%s, turned %g:", backend ? "reference" : "OpenCL", (double)turns[k]);
            for (int f = 0; f < ORI_FACES; f++) {
                printf(" %.4f/%.4f", (double)rgb[9 * f], want[k][f]);
                for (int v = 0; v < 3; v++)
                    for (int c = 0; c < 3; c++)
                        worst = fmax(worst, fabs(rgb[9 * f + 3 * v + c] - want[k][f]) / top[k]);
            }
            printf(" (relit/integrated)\n");
            char what[160];
            snprintf(what, sizeof what, "%s, lobe turned %g: |B - integral| / brightest face",
                     backend ? "reference" : "OpenCL", (double)turns[k]);
            hl_check_error(what, worst, 0.05);
        }
        hl_env_destroy(env);
        hl_relighter_destroy(r);
        hl_transport_destroy(t);
        hl_mesh_destroy(m);
        remove(hlt);
        hl_context_destroy(ctx);
    }
    free(px);
    free(wdir);
    free(om);
}

/* Lighting far brighter or dimmer than usual: the energy kept and the
 * error bound stay finite and scale as they should (the squared
 * luminances overflowed float above about 1.8e19 and underflowed below
 * 1e-19 before the energies were summed at a power-of-two scale), and
 * the colours scale with the light. */
static void case_extreme(void)
{
    const char *path = make_transport("light_x.hlt", "");
    static const float scales[] = {1e21f, 1e-25f};
    for (int backend = 0; backend < 2; backend++) {
        hl_context *ctx = ctx_of(backend ? HL_BACKEND_REFERENCE : HL_BACKEND_OPENCL);
        hl_transport *t = NULL;
        HL_CHECK(path && ctx && hl_transport_load(ctx, path, &t) == HL_OK, "transport");
        if (!t) {
            hl_context_destroy(ctx);
            return;
        }
        const uint32_t V = t->info.vertex_count;
        hl_relighter *r = NULL;
        HL_CHECK(hl_relighter_create(ctx, t, &r) == HL_OK, "%s", hl_context_last_error(ctx));
        float *rgb1 = malloc((size_t)V * 12), *rgb = malloc((size_t)V * 12);
        hl_relight_desc d = {.terms = 60, .rotate_deg = 20.0f};
        hl_relight_stats st1, st;
        hl_env *env = make_env_scaled(ctx, 256, 70, 30, 2e3f, 1.0f);
        HL_CHECK(r && env && hl_relighter_set_env(r, env) == HL_OK && hl_relighter_run(r, &d, rgb1, &st1) == HL_OK,
                 "unit lighting: %s", hl_context_last_error(ctx));
        hl_env_destroy(env);
        double bmax = 0.0;
        for (size_t i = 0; i < (size_t)V * 3; i++) bmax = fmax(bmax, fabs((double)rgb1[i]));
        printf("%s, unit lighting, M=60: energy kept %.6f, bound %.4g\n", backend ? "reference" : "OpenCL",
               st1.energy_kept, st1.error_bound);
        HL_CHECK(st1.energy_kept > 0.0 && st1.energy_kept < 1.0, "energy kept %g: M = 60 should drop some", st1.energy_kept);
        for (int k = 0; k < 2; k++) {
            const double S = scales[k];
            env = make_env_scaled(ctx, 256, 70, 30, 2e3f, scales[k]);
            HL_CHECK(env && hl_relighter_set_env(r, env) == HL_OK && hl_relighter_run(r, &d, rgb, &st) == HL_OK,
                     "lighting x %g: %s", S, hl_context_last_error(ctx));
            hl_env_destroy(env);
            double worst = 0.0;
            for (size_t i = 0; i < (size_t)V * 3; i++) {
                double e = fabs((double)rgb[i] / S - rgb1[i]) / bmax;
                if (!(e <= worst)) worst = e;
            }
            printf("lighting x %g: energy kept %.6f, bound %.4g\n", S, st.energy_kept, st.error_bound);
            char what[160];
            snprintf(what, sizeof what, "%s, lighting x %g: energy kept against unit lighting's",
                     backend ? "reference" : "OpenCL", S);
            hl_check_error(what, fabs(st.energy_kept - st1.energy_kept), 1e-5);
            snprintf(what, sizeof what, "%s, lighting x %g: error bound / scale against unit lighting's (relative)",
                     backend ? "reference" : "OpenCL", S);
            hl_check_error(what, fabs(st.error_bound / S - st1.error_bound) / st1.error_bound, 1e-4);
            snprintf(what, sizeof what, "%s, lighting x %g: colours / scale against unit lighting's (relative to max)",
                     backend ? "reference" : "OpenCL", S);
            hl_check_error(what, worst, 1e-4);
        }
        free(rgb1);
        free(rgb);
        hl_relighter_destroy(r);
        hl_transport_destroy(t);
        hl_context_destroy(ctx);
    }
    /* brighter than HL_MAX_RADIANCE: refused by name, not relit to Inf/NaN */
    hl_context *ref = ctx_of(HL_BACKEND_REFERENCE);
    float px[8 * 4 * 3];
    for (int i = 0; i < 8 * 4 * 3; i++) px[i] = HL_MAX_RADIANCE;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ref, 8, 4, px, &env, NULL) == HL_OK, "a map at the limit is accepted: %s",
             hl_context_last_error(ref));
    hl_env_destroy(env);
    env = NULL;
    px[13] = 2e30f;
    hl_result res = hl_env_create(ref, 8, 4, px, &env, NULL);
    printf("a map with one channel at 2e30: %s\n", hl_context_last_error(ref));
    HL_CHECK(res == HL_ERR_FORMAT && !env && strstr(hl_context_last_error(ref), "1 pixel is brighter than"),
             "a map above the limit must be refused by name");
    hl_sky_desc sky = {.sun_irradiance = 1e35f, .width = 64};
    res = hl_env_create_sky(ref, &sky, &env);
    printf("a sky with sun irradiance 1e35: %s\n", hl_context_last_error(ref));
    HL_CHECK(res == HL_ERR_FORMAT && !env && strstr(hl_context_last_error(ref), "sky:"),
             "a sky above the limit must be refused by name");
    hl_context_destroy(ref);
}

/* A lone sun on black: truncated lighting and transport sum to below zero
 * at many vertices (the exact answer is never negative). The colours that
 * come out are clamped at zero on both backends, bit for bit alike, and
 * the relighter counts what it clamped; keep_negative shows the raw sums. */
static void case_negative(void)
{
    hl_context *cl = ctx_of(HL_BACKEND_OPENCL), *ref = ctx_of(HL_BACKEND_REFERENCE);
    hl_transport *t = NULL;
    /* 1,983 vertices: not a whole number of the colours loop's 8, so its
       last few go one at a time */
    const char *path = make_transport("light_neg.hlt", "--ground-res 11");
    HL_CHECK(path && cl && hl_transport_load(ref, path, &t) == HL_OK, "transport");
    if (!t || !cl) return;
    const uint32_t V = t->info.vertex_count, W = 256, H = 128;
    HL_CHECK(V % 8 != 0, "%u vertices: the colours' one-at-a-time tail is not exercised", V);
    float *px = calloc((size_t)W * H * 3, sizeof(float));
    for (int c = 0; c < 3; c++) px[3 * ((size_t)30 * W + 70) + c] = 5e4f; /* high above the horizon */
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ref, W, H, px, &env, NULL) == HL_OK, "lone sun");
    free(px);
    /* OpenCL by column (its clamp tallied per range), the reference (from
       the colours), OpenCL from the rows (tallied per work-item) */
    hl_relighter *r[3] = {NULL, NULL, NULL};
    HL_CHECK(hl_relighter_create(cl, t, &r[0]) == HL_OK && hl_relighter_create(ref, t, &r[1]) == HL_OK &&
                 hl_relighter_create_once(cl, t, NULL, &r[2]) == HL_OK,
             "relighters");
    HL_CHECK(hl_cl_light_ranges(hl_relighter_device(r[2])) == 0, "the third relighter walks the rows");
    for (int b = 0; b < 3; b++) HL_CHECK(hl_relighter_set_env(r[b], env) == HL_OK, "set env");
    float *raw[3] = {malloc((size_t)V * 12), malloc((size_t)V * 12), malloc((size_t)V * 12)};
    float *out[3] = {malloc((size_t)V * 12), malloc((size_t)V * 12), malloc((size_t)V * 12)};
    uint32_t raw_negative = 0, out_negative = 0, differ = 0;
    for (uint32_t m = 0; m < 3; m++) {
        const uint32_t M = m == 0 ? 50u : m == 1 ? 200u : HL_TERMS_ALL;
        hl_relight_stats st[3], sr[3];
        for (int b = 0; b < 3; b++) {
            hl_relight_desc keep = {.terms = M, .keep_negative = 1}, clamp = {.terms = M};
            HL_CHECK(hl_relighter_run(r[b], &keep, raw[b], &sr[b]) == HL_OK, "raw run");
            HL_CHECK(hl_relighter_run(r[b], &clamp, out[b], &st[b]) == HL_OK, "clamped run");
        }
        /* what the clamp should have done, from the raw sums */
        uint32_t n = 0;
        float lo = 0.0f, hi = 0.0f;
        for (uint32_t v = 0; v < V; v++) {
            float vlo = 0.0f;
            for (int c = 0; c < 3; c++) {
                float x = raw[1][3 * (size_t)v + c], y = out[1][3 * (size_t)v + c];
                vlo = x < vlo ? x : vlo;
                hi = y > hi ? y : hi;
                out_negative += !(y >= 0.0f) + !(out[0][3 * (size_t)v + c] >= 0.0f);
                differ += y != (x > 0.0f ? x : 0.0f); /* clamped, and nothing else changed */
            }
            n += vlo < 0.0f;
            lo = vlo < lo ? vlo : lo;
        }
        for (int b = 0; b < 3; b++) {
            differ += memcmp(raw[b], raw[1], (size_t)V * 12) != 0 || memcmp(out[b], out[1], (size_t)V * 12) != 0;
            differ += !st[b].negative_counted || st[b].negative_vertices != n ||
                      st[b].most_negative != (hi > 0.0f ? (double)lo / hi : 0.0);
            differ += sr[b].negative_vertices != n; /* counted on the raw run too */
        }
        raw_negative += n;
        printf("negative: lone sun, M = %s: %u of %u vertices below zero before the clamp, the lowest %.3g%% of the "
               "brightest; OpenCL %u (rows %u), reference %u clamped\n", M == HL_TERMS_ALL ? "all" : (m ? "200" : "50"),
               n, V, 100.0 * (hi > 0.0f ? (double)lo / hi : 0.0), st[0].negative_vertices, st[2].negative_vertices,
               st[1].negative_vertices);
    }
    printf("negative: %u channels below zero in the clamped colours (tolerance 0); %u mismatches between the "
           "backends, the raw sums and the counts (tolerance 0)\n", out_negative, differ);
    HL_CHECK(raw_negative > 0, "the lone sun must drive some raw sums below zero, or this case tests nothing");
    HL_CHECK(out_negative == 0, "%u clamped channels are below zero", out_negative);
    HL_CHECK(differ == 0, "%u mismatches", differ);
    for (int b = 0; b < 3; b++) {
        hl_relighter_destroy(r[b]);
        free(raw[b]);
        free(out[b]);
    }
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"twin", case_twin},
        {"twin_passes", case_twin_passes},
        {"relighter", case_relighter},
        {"into", case_into},
        {"furnace", case_furnace},
        {"orientation", case_orientation},
        {"extreme", case_extreme},
        {"negative", case_negative},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
