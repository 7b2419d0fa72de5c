/* test_sh.c - the real spherical harmonics and their texel integrals
 * (host/src/sh): known values, the addition theorem, orthonormality on the
 * sphere and over the paraboloid texels' footprints, the convergence of
 * the texel integrals in the quadrature's points, the projection of a
 * constant map, turns about +Y, and bad arguments; and bench-basis's
 * comparison (haarlight_tools.h) under a constant map.
 */
#define _POSIX_C_SOURCE 200809L
#include <unistd.h>

#include "hl_test.h"
#include "haarlight_tools.h"
#include "sh.h"
#include "geom.h"

#define NMAX (HL_SH_MAX_ORDER * HL_SH_MAX_ORDER)

static void unit(double *d)
{
    double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int i = 0; i < 3; i++) d[i] /= n;
}

/* A repeatable pseudo-random number in [-1, 1). */
static double rnd(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return (*s >> 8) / 8388608.0 - 1.0;
}

/* Directions spread over the sphere, and the poles and the equator. */
static void test_dir(int i, double *d)
{
    static const double fixed[6][3] = {{0, 1, 0}, {0, -1, 0}, {1, 0, 0}, {0, 0, -1}, {1e-9, 1, 0}, {0.3, -0.2, 0.9}};
    if (i < 6) {
        memcpy(d, fixed[i], sizeof fixed[i]);
    } else {
        uint32_t s = (uint32_t)i * 7919u;
        d[0] = rnd(&s), d[1] = rnd(&s), d[2] = rnd(&s);
    }
    unit(d);
}

/* Y of bands 0 to 2 written out (Condon-Shortley phase, polar axis +Y,
 * sin(m phi) ~ z), against the recurrence. */
static void t_values(void)
{
    hl_sh_tables tab;
    hl_sh_tables_init(&tab, 3);
    double worst = 0.0;
    for (int i = 0; i < 40; i++) {
        double d[3], Y[9];
        test_dir(i, d);
        const double x = d[0], y = d[1], z = d[2], pi = HL_PI;
        const double want[9] = {0.5 / sqrt(pi),
                                -sqrt(3 / (4 * pi)) * z, sqrt(3 / (4 * pi)) * y, -sqrt(3 / (4 * pi)) * x,
                                sqrt(15 / (4 * pi)) * x * z, -sqrt(15 / (4 * pi)) * y * z,
                                sqrt(5 / (16 * pi)) * (3 * y * y - 1), -sqrt(15 / (4 * pi)) * x * y,
                                sqrt(15 / (16 * pi)) * (x * x - z * z)};
        hl_sh_eval(&tab, d, Y);
        for (int k = 0; k < 9; k++) worst = fmax(worst, fabs(Y[k] - want[k]));
    }
    hl_check_error("bands 0-2 against their closed forms", worst, 1e-14);
}

/* sum_m Y_lm(a) Y_lm(b) = (2l + 1) / (4 pi) P_l(a . b), every band of
 * order 32, relative to (2l + 1) / (4 pi). */
static void t_addition(void)
{
    hl_sh_tables tab;
    hl_sh_tables_init(&tab, HL_SH_MAX_ORDER);
    double worst = 0.0, Ya[NMAX], Yb[NMAX];
    for (int i = 0; i < 30; i++) {
        double a[3], b[3];
        test_dir(i, a);
        test_dir(i + 17, b);
        hl_sh_eval(&tab, a, Ya);
        hl_sh_eval(&tab, b, Yb);
        const double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        double p0 = 1.0, p1 = c; /* Legendre P_l(c) */
        for (uint32_t l = 0; l < HL_SH_MAX_ORDER; l++) {
            double P = l == 0 ? 1.0 : l == 1 ? c : ((2.0 * l - 1.0) * c * p1 - (l - 1.0) * p0) / l;
            if (l >= 2) p0 = p1, p1 = P;
            double s = 0.0;
            for (uint32_t k = l * l; k < (l + 1) * (l + 1); k++) s += Ya[k] * Yb[k];
            const double norm = (2.0 * l + 1.0) / (4.0 * HL_PI);
            worst = fmax(worst, fabs(s - norm * P) / norm);
        }
    }
    hl_check_error("addition theorem, bands 0-31 (relative to (2l+1)/4pi)", worst, 1e-12);
}

/* The Gram matrix of order n by an exact product rule: Gauss-Legendre in
 * y (n nodes: exact to degree 2n - 1 >= 2(n - 1)) times 2n equal steps in
 * phi (exact for frequencies below 2n). Worst |G - I|. */
static double gram_sphere(uint32_t n)
{
    hl_sh_tables tab;
    hl_sh_tables_init(&tab, n);
    const uint32_t cnt = n * n, np = 2 * n;
    double gx[HL_SH_MAX_QUAD], gw[HL_SH_MAX_QUAD];
    hl_sh_gauss(n, gx, gw);
    double *G = calloc((size_t)cnt * cnt, sizeof(double)), Y[NMAX];
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t p = 0; p < np; p++) {
            const double phi = 2.0 * HL_PI * p / np, st = sqrt(1.0 - gx[i] * gx[i]);
            const double d[3] = {st * cos(phi), gx[i], st * sin(phi)}, w = gw[i] * 2.0 * HL_PI / np;
            hl_sh_eval(&tab, d, Y);
            for (uint32_t a = 0; a < cnt; a++)
                for (uint32_t b = 0; b <= a; b++) G[a * cnt + b] += w * Y[a] * Y[b];
        }
    double worst = 0.0;
    for (uint32_t a = 0; a < cnt; a++)
        for (uint32_t b = 0; b <= a; b++) worst = fmax(worst, fabs(G[a * cnt + b] - (a == b ? 1.0 : 0.0)));
    free(G);
    return worst;
}

static void t_orthonormal(void)
{
    hl_check_error("Gram matrix of order 20 (sphere, exact product rule) against I", gram_sphere(20), 1e-13);
    hl_check_error("Gram matrix of order 32 (sphere, exact product rule) against I", gram_sphere(32), 1e-13);
}

/* A rim texel's in-disc solid angle the other way: the sum of geom's
 * solid angles of its S x S sub-squares (closed form inside, 512 midpoint
 * strips in s on those the rim cuts, which converge as (h / S)^1.5: the
 * rim's square-root limit). */
static double rim_omega(double s0, double t0, double h, int S)
{
    const double e = h / S;
    double sum = 0.0;
    for (int a = 0; a < S; a++)
        for (int b = 0; b < S; b++) sum += hl_para_rect_omega(s0 + b * e, s0 + (b + 1) * e, t0 + a * e, t0 + (a + 1) * e);
    return sum;
}

/* The Gram matrix of order 12 (products of degree 22) summed over every
 * texel footprint of both N = 32 maps, rim pieces included; and each
 * texel's quadrature weights against its exact solid angle. */
static void t_footprint(void)
{
    const uint32_t N = 32, n = 12, cnt = n * n, Q = HL_SH_QUAD;
    hl_sh_tables tab;
    hl_sh_tables_init(&tab, n);
    double *G = calloc((size_t)cnt * cnt, sizeof(double)), Y[NMAX];
    double *pts = malloc((size_t)HL_SH_MAX_PIECES * Q * Q * 4 * sizeof(double));
    double wo_in = 0.0, wo_rim[2] = {0.0, 0.0};
    for (int map = 0; map < 2; map++)
        for (uint32_t row = 0; row < N; row++)
            for (uint32_t col = 0; col < N; col++) {
                uint32_t np = hl_sh_texel_points(N, map, col, row, Q, pts);
                double om = 0.0, h = 2.0 / N, s0 = -1.0 + col * h, t0 = -1.0 + row * h;
                for (uint32_t p = 0; p < np; p++) {
                    const double *q = pts + 4 * (size_t)p;
                    om += q[3];
                    hl_sh_eval(&tab, q, Y);
                    for (uint32_t a = 0; a < cnt; a++)
                        for (uint32_t b = 0; b <= a; b++) G[a * cnt + b] += q[3] * Y[a] * Y[b];
                }
                const double ex = hl_para_rect_omega(s0, s0 + h, t0, t0 + h);
                const double fs = fmax(fabs(s0), fabs(s0 + h)), ft = fmax(fabs(t0), fabs(t0 + h));
                if (fs * fs + ft * ft <= 1.0) wo_in = fmax(wo_in, fabs(om - ex) / ex);
                else if (ex > 0)
                    for (int i = 0; i < 2; i++)
                        wo_rim[i] = fmax(wo_rim[i], fabs(om - rim_omega(s0, t0, h, i ? 64 : 16)) / (h * h));
            }
    double worst = 0.0;
    for (uint32_t a = 0; a < cnt; a++)
        for (uint32_t b = 0; b <= a; b++) worst = fmax(worst, fabs(G[a * cnt + b] - (a == b ? 1.0 : 0.0)));
    hl_check_error("Gram matrix of order 12 over the N = 32 texel footprints against I", worst, 1e-12);
    /* the closed form is a difference of four O(1) values: ~1e-14 of a texel */
    hl_check_error("inner texels: quadrature weights against the closed-form solid angle (relative)", wo_in, 1e-12);
    /* rim texels against the sum over S x S sub-squares: the difference
       must fall at least 4-fold from S = 16 to S = 64 (it falls 8-fold, as
       the sub-squares' error does: the weights here are the limit) */
    printf("rim texels: weights against %d x %d sub-squares: %.3g of h^2; against %d x %d: %.3g\n", 16, 16,
           wo_rim[0], 64, 64, wo_rim[1]);
    hl_check_error("rim texels: S = 64 difference over the S = 16 one, against 1/4", wo_rim[1] / wo_rim[0], 0.25);
    hl_check_error("rim texels: weights against 64 x 64 sub-squares (relative to h^2)", wo_rim[1], 1e-7);
    free(G);
    free(pts);
}

/* Worst error of the texel integrals at Q points against a reference,
 * in units of the texel's solid angle times sqrt((2l + 1) / 4 pi), which
 * bounds |Y_lm| (addition theorem): a relative error of the texel's mean. */
static double ybar_err(const double *a, const double *ref, uint32_t N, uint32_t n)
{
    const uint32_t cnt = n * n;
    double worst = 0.0;
    for (uint32_t j = 0; j < 2 * N * N; j++) {
        const double om = ref[(size_t)j * cnt] * sqrt(4.0 * HL_PI);
        if (om <= 0.0) continue;
        for (uint32_t l = 0; l < n; l++) {
            const double scale = om * sqrt((2.0 * l + 1.0) / (4.0 * HL_PI));
            for (uint32_t k = l * l; k < (l + 1) * (l + 1); k++)
                worst = fmax(worst, fabs(a[(size_t)j * cnt + k] - ref[(size_t)j * cnt + k]) / scale);
        }
    }
    return worst;
}

/* Order 20 at N = 32 and 64: Q = 4 .. 12 against Q = 16; the library's
 * HL_SH_QUAD must reach 1e-9, and Q = 16 must agree with Q = 20 far
 * better than that (the reference has converged). */
static void t_convergence(void)
{
    const uint32_t n = 20, Ns[2] = {32, 64}, Qs[] = {4, 6, 8, HL_SH_QUAD, 12};
    char what[160];
    for (int i = 0; i < 2; i++) {
        const uint32_t N = Ns[i];
        double *ref = NULL, *ref2 = NULL, *a = NULL;
        if (hl_sh_texel_integrals(NULL, N, n, 16, &ref) != HL_OK || hl_sh_texel_integrals(NULL, N, n, 20, &ref2) != HL_OK) {
            HL_CHECK(0, "texel integrals failed");
            return;
        }
        snprintf(what, sizeof what, "N = %u, order %u: Q = 16 against Q = 20", N, n);
        hl_check_error(what, ybar_err(ref, ref2, N, n), 1e-12);
        double prev = INFINITY;
        for (size_t q = 0; q < sizeof Qs / sizeof Qs[0]; q++) {
            HL_CHECK(hl_sh_texel_integrals(NULL, N, n, Qs[q], &a) == HL_OK, "texel integrals failed");
            if (!a) continue;
            const double e = ybar_err(a, ref, N, n);
            printf("N = %u, order %u, Q = %2u: worst error of a texel's mean of Y_lm against Q = 16: %.3g\n", N, n,
                   Qs[q], e);
            if (Qs[q] <= 8) HL_CHECK(e < prev, "Q = %u: the error %.3g did not fall (was %.3g)", Qs[q], e, prev);
            if (Qs[q] == HL_SH_QUAD) {
                snprintf(what, sizeof what, "N = %u, order %u: the default Q = %u against Q = 16", N, n, HL_SH_QUAD);
                hl_check_error(what, e, 1e-9);
            }
            prev = e;
            hl_free_big(a);
            a = NULL;
        }
        hl_free_big(ref);
        hl_free_big(ref2);
    }
}

/* A map of constant value c projects to c sqrt(4 pi) at k = 0 and 0 elsewhere. */
static void t_constant(void)
{
    const uint32_t n = 20, cnt = n * n, Ns[2] = {32, 64};
    char what[120];
    for (int i = 0; i < 2; i++) {
        const uint32_t N = Ns[i], ntex = 2 * N * N;
        double *Yb = NULL, l[400];
        if (hl_sh_texel_integrals(NULL, N, n, HL_SH_QUAD, &Yb) != HL_OK) {
            HL_CHECK(0, "texel integrals failed");
            return;
        }
        float *L = malloc(ntex * sizeof(float));
        for (uint32_t j = 0; j < ntex; j++) L[j] = 2.5f;
        hl_sh_project(Yb, ntex, cnt, L, 1, l);
        double worst = fabs(l[0] - 2.5 * sqrt(4.0 * HL_PI));
        for (uint32_t k = 1; k < cnt; k++) worst = fmax(worst, fabs(l[k]));
        snprintf(what, sizeof what, "N = %u: constant 2.5 against 2.5 sqrt(4 pi) e_0 (relative)", N);
        hl_check_error(what, worst / (2.5 * sqrt(4.0 * HL_PI)), 1e-12);
        free(L);
        hl_free_big(Yb);
    }
}

/* Turns about +Y: point values at 37 degrees (any angle), then whole
 * maps turned by 90, 180 and 270 degrees, which move every texel onto
 * another ((s, t) -> (-t, s) per quarter turn), projected, against the
 * projection of the map before the turn rotated band by band. */
static void t_rotation(void)
{
    hl_sh_tables tab;
    const uint32_t n = 20, cnt = n * n, N = 32, ntex = 2 * N * N;
    hl_sh_tables_init(&tab, n);
    double worst = 0.0, Y[400], Yr[400];
    const double a = 37.0 * HL_PI / 180.0;
    for (int i = 0; i < 30; i++) {
        double d[3], dr[3];
        test_dir(i, d);
        /* phi grows by a: (x, z) turned from +X towards +Z */
        dr[0] = d[0] * cos(a) - d[2] * sin(a), dr[1] = d[1], dr[2] = d[0] * sin(a) + d[2] * cos(a);
        hl_sh_eval(&tab, d, Y);
        hl_sh_eval(&tab, dr, Yr);
        /* f = Y_k(R^-1 .) has Y_k's unit vector turned; its value at dr is Y_k(d) */
        for (uint32_t k = 0; k < cnt; k++) {
            double c[400] = {0};
            c[k] = 1.0;
            hl_sh_rotate_y(n, a, c);
            double v = 0.0;
            for (uint32_t q = 0; q < cnt; q++) v += c[q] * Yr[q];
            worst = fmax(worst, fabs(v - Y[k]));
        }
    }
    hl_check_error("point values turned by 37 degrees", worst, 1e-12);
    double *Yb = NULL;
    if (hl_sh_texel_integrals(NULL, N, n, HL_SH_QUAD, &Yb) != HL_OK) {
        HL_CHECK(0, "texel integrals failed");
        return;
    }
    float *L = malloc(ntex * sizeof(float)), *cur = malloc(ntex * sizeof(float)), *tmp = malloc(ntex * sizeof(float));
    uint32_t s = 12345u;
    for (uint32_t j = 0; j < ntex; j++) L[j] = (float)(1.0 + rnd(&s));
    double l[400], lr[400];
    hl_sh_project(Yb, ntex, cnt, L, 1, l);
    memcpy(cur, L, ntex * sizeof(float));
    for (int turn = 1; turn <= 3; turn++) {
        /* a quarter turn more: (s, t) -> (-t, s), so col' = N-1-row, row' = col */
        for (int map = 0; map < 2; map++)
            for (uint32_t row = 0; row < N; row++)
                for (uint32_t col = 0; col < N; col++)
                    tmp[(size_t)map * N * N + col * N + (N - 1 - row)] = cur[(size_t)map * N * N + row * N + col];
        memcpy(cur, tmp, ntex * sizeof(float));
        hl_sh_project(Yb, ntex, cnt, cur, 1, lr);
        double c[400], big = 0.0, err = 0.0;
        memcpy(c, l, sizeof c);
        hl_sh_rotate_y(n, turn * HL_PI / 2, c);
        for (uint32_t k = 0; k < cnt; k++) big = fmax(big, fabs(l[k])), err = fmax(err, fabs(c[k] - lr[k]));
        char what[120];
        snprintf(what, sizeof what, "N = 32 map turned by %d degrees: projection against rotated coefficients (relative)",
                 90 * turn);
        hl_check_error(what, err / big, 1e-12);
    }
    free(cur);
    free(tmp);
    free(L);
    hl_free_big(Yb);
}

/* bench-basis's tool on the bunny (N = C = 16) under a constant map: one
 * harmonic holds all the lighting, so SH at 1 and at 400 terms give the
 * exact colours (to the float rows' precision), and Haar with every term
 * gives them bit for bit (the same sums). */
static void t_tool(void)
{
    char mesh_path[1024], path[1024];
    snprintf(mesh_path, sizeof mesh_path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    snprintf(path, sizeof path, "%s/sh_tool_%ld.hlt", hl_test_env("HL_TMP", "/tmp"), (long)getpid());
    hl_context_desc cd = {.backend = HL_BACKEND_REFERENCE, .quiet = 1};
    char err[512];
    hl_context *ctx = NULL;
    hl_mesh *mesh = NULL;
    hl_transport *t = NULL;
    hl_env *env = NULL;
    hl_basis_bench *bb = NULL;
    hl_mesh_load_desc ld = {{0.8f, 0.6f, 0.4f}, 'y', 0};
    hl_precompute_desc d = {0};
    d.N = 16, d.C = 16;
    hl_result r = hl_context_create(&cd, &ctx, err, sizeof err);
    if (r == HL_OK) r = hl_mesh_load(ctx, mesh_path, &ld, &mesh, NULL);
    if (r == HL_OK) r = hl_precompute(ctx, mesh, &d, path, NULL);
    if (r == HL_OK) r = hl_transport_load(ctx, path, &t);
    remove(path);
    float *rgb = calloc(64 * 32 * 3, sizeof(float));
    for (int i = 0; i < 64 * 32 * 3; i++) rgb[i] = i % 3 == 0 ? 0.7f : i % 3 == 1 ? 1.3f : 0.2f;
    if (r == HL_OK) r = hl_env_create(ctx, 64, 32, rgb, &env, NULL);
    uint32_t idx[64];
    for (uint32_t k = 0; k < 64 && t; k++) idx[k] = (uint32_t)((uint64_t)k * t->info.vertex_count / 64);
    if (r == HL_OK) r = hl_basis_bench_create(ctx, t, idx, 64, 20, &bb);
    const double *exact = NULL;
    if (r == HL_OK) r = hl_basis_bench_set_env(bb, env, &exact);
    HL_CHECK(r == HL_OK, "set-up: %s", ctx ? hl_context_last_error(ctx) : err);
    if (r == HL_OK) {
        double c[64 * 3], big = 0.0, e1 = 0.0, e400 = 0.0;
        int same = 1;
        HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_SH, 1, c) == HL_OK, "sh at 1 term");
        for (int i = 0; i < 64 * 3; i++) big = fmax(big, fabs(exact[i])), e1 = fmax(e1, fabs(c[i] - exact[i]));
        HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_SH, 400, c) == HL_OK, "sh at 400 terms");
        for (int i = 0; i < 64 * 3; i++) e400 = fmax(e400, fabs(c[i] - exact[i]));
        for (hl_basis b = HL_BASIS_HAAR; b <= HL_BASIS_HAAR_TRANSPORT; b++) {
            HL_CHECK(hl_basis_bench_colours(bb, b, hl_basis_bench_count(bb, b), c) == HL_OK, "%s at every term",
                     hl_basis_name(b));
            for (int i = 0; i < 64 * 3; i++) same &= c[i] == exact[i];
        }
        HL_CHECK(big > 0.1, "the exact colours are dark (%g)", big);
        /* the float rows and taps carry about 1e-7 relative each (1.6e-7 seen) */
        hl_check_error("constant map: SH with 1 term against the exact colours (relative)", e1 / big, 1e-6);
        hl_check_error("constant map: SH with 400 terms against the exact colours (relative)", e400 / big, 1e-6);
        HL_CHECK(same, "Haar with every term is not the exact colours bit for bit");
        printf("Haar with all %u terms, each selection: the exact colours bit for bit: %s\n",
               hl_basis_bench_count(bb, HL_BASIS_HAAR), same ? "yes" : "no");
        HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_SH, 401, c) == HL_ERR_INVALID_ARGUMENT, "401 SH terms accepted");
        HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_HAAR, 0, c) == HL_ERR_INVALID_ARGUMENT, "0 terms accepted");
    }
    free(rgb);
    hl_basis_bench_destroy(bb);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_mesh_destroy(mesh);
    hl_context_destroy(ctx);
}

static void t_bad(void)
{
    hl_sh_tables tab;
    HL_CHECK(!hl_sh_tables_init(&tab, 0), "order 0 accepted");
    HL_CHECK(!hl_sh_tables_init(&tab, HL_SH_MAX_ORDER + 1), "order %u accepted", HL_SH_MAX_ORDER + 1);
    double *Yb = (double *)&tab;
    HL_CHECK(hl_sh_texel_integrals(NULL, 16, 0, 4, &Yb) == HL_ERR_INVALID_ARGUMENT && !Yb, "order 0 integrals");
    HL_CHECK(hl_sh_texel_integrals(NULL, 16, 4, 0, &Yb) == HL_ERR_INVALID_ARGUMENT, "Q = 0 accepted");
    HL_CHECK(hl_sh_texel_integrals(NULL, 16, 4, HL_SH_MAX_QUAD + 1, &Yb) == HL_ERR_INVALID_ARGUMENT, "Q too large");
    printf("bad arguments refused: %s\n", hl_test_failures ? "no" : "yes");
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"values", t_values},         {"addition", t_addition},
                                         {"orthonormal", t_orthonormal}, {"footprint", t_footprint},
                                         {"convergence", t_convergence}, {"constant", t_constant},
                                         {"rotation", t_rotation},       {"bad", t_bad},
                                         {"tool", t_tool},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
