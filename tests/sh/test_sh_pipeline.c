/* test_sh_pipeline.c - spherical harmonics through the real pipeline
 * (suite "sh_pipeline"): `precompute --basis sh`, and the relighter's
 * lighting projected onto the same harmonics.
 *
 * Cases, each printing its tolerance and the worst error it saw:
 *   kernel    hl_sh_project_rows (OpenCL) against its twin on rows with
 *             zero texels, for the transport's matrix (per solid angle)
 *             and the lighting's; the twin against the projection in
 *             double as bench-basis computes it (the integrals
 *             unrounded); slots from L^2 on are zero.
 *   constant  the bunny (N = C = 16, order 20) under a constant map:
 *             every vertex's colour against the exact one (the
 *             unquantised rows' sums), with M = 1, 200 and all terms, on
 *             both backends: within the sqrt8 step of the row's largest
 *             coefficient times the first term, plus what the energy
 *             truncation may drop.
 *   cl_ref    the file made on the OpenCL device equals the reference
 *             backend's byte for byte; relight under data/city.exr on
 *             both backends, M = 200 and all, colours against each other;
 *             the relighter's SH lighting stage on the device against
 *             the twin;
 *             area-weighted selection equals the unweighted one (every
 *             harmonic's support is the sphere).
 *   bench     relight with every term against bench-basis's SH colours
 *             (the exact rows projected in double) at 256 vertices, per
 *             vertex within the quantisation and truncation bound.
 *   bad       the command refuses --sh-order 0 and 33, an order whose
 *             L^2 passes 2 N^2, --sh-order without --basis sh and an
 *             unknown basis (exit 2, naming the option); the library
 *             refuses the same descriptors.
 * Depends on: haarlight_core (internals: sh.h, twins.h, cl_backend.h,
 * geom.h; haarlight_tools.h for bench-basis and the exact rows),
 * data/bunny_lowres.obj and data/city.exr.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_backend.h"
#include "geom.h"
#include "haarlight_tools.h"
#include "hl_test.h"
#include "lighting.h"
#include "pipeline_test.h"
#include "sh.h"
#include "twins.h"

#define SCENE_N 16u
#define SCENE_ORDER 20u


/* ------------------------------------------------------------ kernel */

static void t_kernel(void)
{
    hl_context *cl = hl_test_cl_context(0), *ref = hl_test_ref_context(0);
    if (!cl) exit(HL_TEST_SKIP);
    const uint32_t N = SCENE_N, L = SCENE_ORDER, nc = 2 * N * N, ns = L * L, st = hl_sh_stride(L), R = 7;
    hl_geom *g = NULL;
    hl_cl_pipe *p = NULL;
    double *Ybar = NULL;
    HL_CHECK(hl_geom_create(ref, N, N, &g) == HL_OK, "geom");
    HL_CHECK(hl_cl_pipe_create(cl, g, R, &p) == HL_OK, "pipe: %s", hl_context_last_error(cl));
    HL_CHECK(hl_sh_texel_integrals(ref, N, L, HL_SH_QUAD, &Ybar) == HL_OK, "integrals");
    float *in = malloc((size_t)R * nc * 4), *dev = malloc((size_t)R * nc * 4), *twin = malloc((size_t)nc * 4);
    double *exact = malloc((size_t)ns * sizeof(double)), *absum = malloc((size_t)ns * sizeof(double));
    /* rows as the pipeline sees them: non-negative, about half the texels
       zero (below the horizon), one row all zero */
    for (uint32_t i = 0; i < R * nc; i++) in[i] = hl_rng_unit() < 0.5 ? 0.0f : (float)(hl_rng_unit() * 1e-3);
    memset(in + 3 * (size_t)nc, 0, (size_t)nc * 4);
    const double s4pi = sqrt(4.0 * HL_PI), u = ldexp(1.0, -24);
    /* float sums of nc products of float-rounded matrix entries: within
       (nc + 1) u of the sum of the terms' magnitudes (Higham's bound) */
    const double tol_double = (nc + 1) * u;
    for (int per = 1; per >= 0; per--) {
        float *Y = NULL;
        HL_CHECK(hl_sh_matrix(ref, N, L, per, &Y) == HL_OK, "matrix");
        HL_CHECK(hl_cl_pipe_set_sh(p, Y, st, ns) == HL_OK, "set: %s", hl_context_last_error(cl));
        /* the coefficient buffer dirtied first (the Haar writes every
           slot), so the zeroing of the slots past L^2 is what the tail
           check sees */
        HL_CHECK(hl_cl_pipe_haar(p, R, in, dev) == HL_OK, "dirty: %s", hl_context_last_error(cl));
        HL_CHECK(hl_cl_pipe_sh_project(p, R, in, dev) == HL_OK, "kernel: %s", hl_context_last_error(cl));
        double worst_twin = 0.0, worst_double = 0.0;
        uint32_t tail = 0;
        for (uint32_t v = 0; v < R; v++) {
            const float *x = in + (size_t)v * nc, *d = dev + (size_t)v * nc;
            hl_ref_sh_project_rows(x, nc, Y, st, ns, twin);
            double big = 0.0;
            for (uint32_t k = 0; k < ns; k++) big = fmax(big, fabs(twin[k]));
            for (uint32_t k = 0; k < nc; k++) {
                if (k >= ns) tail += d[k] != 0.0f || twin[k] != 0.0f;
                else if (big > 0.0) worst_twin = fmax(worst_twin, fabs((double)d[k] - twin[k]) / big);
                else worst_twin = fmax(worst_twin, fabs((double)d[k] - twin[k]));
            }
            /* bench-basis's projection: in double, from the integrals */
            memset(exact, 0, (size_t)ns * sizeof(double));
            memset(absum, 0, (size_t)ns * sizeof(double));
            for (uint32_t j = 0; j < nc; j++) {
                const double *y = Ybar + (size_t)j * ns, om = s4pi * y[0];
                if (x[j] == 0.0f || (per && om <= 0.0)) continue;
                const double w = per ? x[j] / om : x[j];
                for (uint32_t k = 0; k < ns; k++) {
                    exact[k] += w * y[k];
                    absum[k] += fabs(w * y[k]);
                }
            }
            for (uint32_t k = 0; k < ns; k++)
                if (absum[k] > 0.0) worst_double = fmax(worst_double, fabs(twin[k] - exact[k]) / absum[k]);
                else HL_CHECK(twin[k] == 0.0f, "row %u slot %u: %g where every term is zero", v, k, (double)twin[k]);
        }
        char what[160];
        snprintf(what, sizeof what, "%s matrix: kernel against twin (relative to the row's largest)",
                 per ? "transport" : "lighting");
        hl_check_error(what, worst_twin, 0.0); /* the twin's sums in its order, FP_CONTRACT off: bit for bit */
        snprintf(what, sizeof what, "%s matrix: twin against the double projection (relative to sum |terms|)",
                 per ? "transport" : "lighting");
        hl_check_error(what, worst_double, tol_double);
        HL_CHECK(tail == 0, "%u slots from L^2 on are not zero", tail);
        hl_free_big(Y);
    }
    free(in);
    free(dev);
    free(twin);
    free(exact);
    free(absum);
    hl_free_big(Ybar);
    hl_cl_pipe_destroy(p);
    hl_geom_destroy(g);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* ------------------------------------------------------------ scenes */

/* The bunny's SH transport at path, made on ctx. */
static hl_mesh *sh_scene(hl_context *ctx, const char *path, uint32_t order)
{
    const hl_precompute_desc d = {.N = SCENE_N, .C = SCENE_N, .basis = HL_TRANSPORT_BASIS_SH, .sh_order = order};
    return pt_scene(ctx, path, &d);
}

static hl_transport *load(hl_context *ctx, const char *path)
{
    hl_transport *t = NULL;
    HL_CHECK(hl_transport_load(ctx, path, &t) == HL_OK, "load: %s", hl_context_last_error(ctx));
    HL_CHECK(t->info.basis == HL_TRANSPORT_BASIS_SH && t->info.sh_order == SCENE_ORDER, "basis %u order %u",
             t->info.basis, t->info.sh_order);
    return t;
}

/* Colours (3 floats a vertex) of t under env with M terms (0: all) and a
 * selection scheme (0: the default). */
/* The exact rows of the n vertices idx projected in double as bench-basis
 * does it: t (n x order^2); with the Ybar it used (*Ybar, order^2 a texel)
 * and, when sums is given, each row's sum of T_j. */
static void exact_sh_rows(hl_context *ctx, const hl_transport *t, const uint32_t *idx, uint32_t n, double *tsh,
                          double **Ybar, double *sums)
{
    const uint32_t nc = 2 * t->info.N * t->info.N, ns = hl_sh_count(t->info.sh_order);
    hl_bench_ref *br = NULL;
    float *texel = malloc((size_t)n * nc * 4);
    HL_CHECK(hl_bench_ref_create(ctx, t, &br) == HL_OK, "bench ref: %s", hl_context_last_error(ctx));
    HL_CHECK(hl_bench_ref_rows(br, idx, n, texel, NULL) == HL_OK, "rows: %s", hl_context_last_error(ctx));
    HL_CHECK(hl_sh_texel_integrals(ctx, t->info.N, t->info.sh_order, HL_SH_QUAD, Ybar) == HL_OK, "integrals");
    const double s4pi = sqrt(4.0 * HL_PI);
    for (uint32_t i = 0; i < n; i++) {
        const float *T = texel + (size_t)i * nc;
        double *o = tsh + (size_t)i * ns, sum = 0.0;
        memset(o, 0, (size_t)ns * sizeof(double));
        for (uint32_t j = 0; j < nc; j++) {
            const double *y = *Ybar + (size_t)j * ns, om = s4pi * y[0];
            sum += T[j];
            if (T[j] == 0.0f || om <= 0.0) continue;
            for (uint32_t k = 0; k < ns; k++) o[k] += T[j] / om * y[k];
        }
        if (sums) sums[i] = sum;
    }
    free(texel);
    hl_bench_ref_destroy(br);
}


/* ------------------------------------------------------------ constant */

static void t_constant(void)
{
    hl_context *ref = hl_test_ref_context(0), *cl = hl_test_cl_context(0);
    const char *path = hl_test_tmp_path("sh_pipeline_constant.hlt");
    hl_mesh *mesh = sh_scene(ref, path, SCENE_ORDER);
    hl_transport *t = load(ref, path);
    const uint32_t V = t->info.vertex_count, ns = SCENE_ORDER * SCENE_ORDER;
    const float c = 0.75f;
    float *rgb_in = malloc(64 * 32 * 12);
    for (int i = 0; i < 64 * 32 * 3; i++) rgb_in[i] = c;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ref, 64, 32, rgb_in, &env, NULL) == HL_OK, "env");
    uint32_t *idx = malloc((size_t)V * 4);
    for (uint32_t v = 0; v < V; v++) idx[v] = v;
    double *tsh = malloc((size_t)V * ns * sizeof(double)), *sums = malloc((size_t)V * sizeof(double)), *Ybar = NULL;
    exact_sh_rows(ref, t, idx, V, tsh, &Ybar, sums);
    const double l0 = c * sqrt(4.0 * HL_PI), eps = t->info.eps, q = pt_sqrt8_step();
    float *rgb = malloc((size_t)V * 12);
    /* per vertex: the first coefficient is off by at most a sqrt8 step of
       the row's largest, b, or dropped by the energy rule (then |t_0| <=
       sqrt(eps) |t|); the float sums add 1e-5 */
    double *bound = malloc((size_t)V * sizeof(double));
    for (uint32_t v = 0; v < V; v++) {
        const double tn = pt_norm2(tsh + (size_t)v * ns, ns);
        bound[v] = l0 * (q * t->row_quant[v].b + sqrt(eps) * tn) + 1e-5 * l0 * tn;
    }
    static const uint32_t Ms[] = {1, 200, 0};
    for (int backend = 0; backend < 2; backend++) {
        hl_context *ctx = backend ? cl : ref;
        if (!ctx) {
            printf("no OpenCL device: the OpenCL relight is not checked\n");
            continue;
        }
        for (size_t m = 0; m < sizeof Ms / sizeof Ms[0]; m++) {
            double worst, worst_rel;
            pt_constant_errors(ctx, t, mesh, env, Ms[m], c, sums, bound, rgb, &worst, &worst_rel);
            char what[160];
            snprintf(what, sizeof what, "%s, M = %s: error over the vertex's bound (sqrt8 step of b, truncation)",
                     backend ? "OpenCL" : "reference", Ms[m] == 1 ? "1" : Ms[m] == 200 ? "200" : "all");
            hl_check_error(what, worst, 1.0);
            printf("    (the largest error relative to the exact colour: %.3g)\n", worst_rel);
        }
    }
    free(rgb);
    free(bound);
    free(rgb_in);
    free(idx);
    free(tsh);
    free(sums);
    hl_free_big(Ybar);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_mesh_destroy(mesh);
    remove(path);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* ------------------------------------------------------------ cl_ref */

static void t_cl_ref(void)
{
    hl_context *ref = hl_test_ref_context(0), *cl = hl_test_cl_context(0);
    if (!cl) exit(HL_TEST_SKIP);
    const char *pr = hl_test_tmp_path("sh_pipeline_ref.hlt"), *pc = hl_test_tmp_path("sh_pipeline_cl.hlt");
    hl_mesh *m1 = sh_scene(ref, pr, SCENE_ORDER), *m2 = sh_scene(cl, pc, SCENE_ORDER);
    pt_check_same_file(pr, pc, "precompute, OpenCL against reference");
    hl_transport *t = load(ref, pr);
    hl_env *env = NULL;
    HL_CHECK(hl_env_load(ref, hl_test_data_path("city.exr"), &env, NULL) == HL_OK, "env: %s", hl_context_last_error(ref));
    const uint32_t V = t->info.vertex_count;
    float *x = malloc((size_t)V * 12), *y = malloc((size_t)V * 12);
    static const uint32_t Ms[] = {200, 0};
    for (size_t m = 0; m < 2; m++) {
        pt_relight(ref, t, env, Ms[m], 0, 0.0f, x);
        pt_relight(cl, t, env, Ms[m], 0, 0.0f, y);
        char what[128];
        snprintf(what, sizeof what, "city.exr, M = %s: OpenCL against reference (relative to the brightest)",
                 Ms[m] ? "200" : "all");
        /* the same float sums in another order on the device */
        hl_check_error(what, hl_test_rel_diff(x, y, 3 * (size_t)V), 1e-5);
    }
    /* the relighter's own lighting stage on the device, against the twin
       with the lighting matrix */
    {
        const uint32_t nc = 2 * t->info.N * t->info.N, ns = SCENE_ORDER * SCENE_ORDER;
        hl_relighter *r = NULL;
        float *Lp = malloc((size_t)nc * 12), *Lw = malloc((size_t)nc * 12), *tw = malloc((size_t)nc * 4), *Y = NULL;
        HL_CHECK(hl_relighter_create(cl, t, &r) == HL_OK, "relighter: %s", hl_context_last_error(cl));
        HL_CHECK(hl_sh_matrix(ref, t->info.N, SCENE_ORDER, 0, &Y) == HL_OK, "matrix");
        for (uint32_t i = 0; i < 3 * nc; i++) Lp[i] = (float)(hl_rng_unit() * 4.0);
        HL_CHECK(hl_cl_light_stage_sh(hl_relighter_device(r), Lp, Lw) == HL_OK, "stage: %s", hl_context_last_error(cl));
        double worst = 0.0;
        for (int ch = 0; ch < 3; ch++) {
            hl_ref_sh_project_rows(Lp + (size_t)ch * nc, nc, Y, hl_sh_stride(SCENE_ORDER), ns, tw);
            double big = 0.0;
            for (uint32_t k = 0; k < nc; k++) big = fmax(big, fabs(tw[k]));
            for (uint32_t k = 0; k < nc; k++)
                worst = fmax(worst, fabs((double)Lw[(size_t)ch * nc + k] - tw[k]) / big);
        }
        /* the twin's sums in its order, FP_CONTRACT off: bit for bit */
        hl_check_error("the relighter's SH lighting stage (OpenCL) against the twin, relative to the largest", worst,
                       0.0);
        hl_free_big(Y);
        free(Lp);
        free(Lw);
        free(tw);
        hl_relighter_destroy(r);
    }
    /* every harmonic's support is the sphere: area-weighted selection
       ranks as the unweighted one (on both backends: the device's weights
       are uploaded, not the Haar supports it starts with) */
    pt_relight(ref, t, env, 50, HL_SELECT_UNWEIGHTED, 0.0f, x);
    for (int backend = 0; backend < 2; backend++) {
        pt_relight(backend ? cl : ref, t, env, 50, HL_SELECT_AREA, 0.0f, y);
        HL_CHECK(memcmp(x, y, (size_t)V * 12) == 0, "%s: M = 50 by area differs from unweighted",
                 backend ? "OpenCL" : "reference");
    }
    printf("M = 50: area-weighted selection equals the unweighted one on both backends\n");
    free(x);
    free(y);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_mesh_destroy(m1);
    hl_mesh_destroy(m2);
    remove(pr);
    remove(pc);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* ------------------------------------------------------------ bench */

static void t_bench(void)
{
    hl_context *ref = hl_test_ref_context(0);
    const char *path = hl_test_tmp_path("sh_pipeline_bench.hlt");
    hl_mesh *mesh = sh_scene(ref, path, SCENE_ORDER);
    hl_transport *t = load(ref, path);
    const uint32_t V = t->info.vertex_count, n = 256, ns = SCENE_ORDER * SCENE_ORDER, nc = 2 * SCENE_N * SCENE_N;
    uint32_t idx[256];
    for (uint32_t i = 0; i < n; i++) idx[i] = (uint32_t)((uint64_t)i * V / n);
    hl_env *env = NULL;
    HL_CHECK(hl_env_load(ref, hl_test_data_path("city.exr"), &env, NULL) == HL_OK, "env: %s", hl_context_last_error(ref));
    hl_basis_bench *bb = NULL;
    const double *exact = NULL;
    double *sh = malloc((size_t)n * 3 * sizeof(double));
    HL_CHECK(hl_basis_bench_create(ref, t, idx, n, SCENE_ORDER, &bb) == HL_OK, "bench: %s", hl_context_last_error(ref));
    HL_CHECK(hl_basis_bench_set_env(bb, env, &exact) == HL_OK, "bench env: %s", hl_context_last_error(ref));
    HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_SH, ns, sh) == HL_OK, "bench colours");
    /* the bound's pieces: the exact rows and the lighting in harmonics */
    double *tsh = malloc((size_t)n * ns * sizeof(double)), *Ybar = NULL, l[3][SCENE_ORDER * SCENE_ORDER];
    exact_sh_rows(ref, t, idx, n, tsh, &Ybar, NULL);
    hl_bench_ref *br = NULL;
    float *Lp = malloc((size_t)nc * 12);
    HL_CHECK(hl_bench_ref_create(ref, t, &br) == HL_OK && hl_bench_ref_lighting(br, env, Lp, NULL) == HL_OK, "lighting");
    double l1[3] = {0}, l2[3], tn[256];
    for (int ch = 0; ch < 3; ch++) {
        hl_sh_project(Ybar, nc, ns, Lp + (size_t)ch * nc, 1, l[ch]);
        for (uint32_t k = 0; k < ns; k++) l1[ch] += fabs(l[ch][k]);
        l2[ch] = pt_norm2(l[ch], ns);
    }
    for (uint32_t i = 0; i < n; i++) tn[i] = pt_norm2(tsh + (size_t)i * ns, ns);
    pt_check_against(ref, t, mesh, env, idx, n, sh, tn, l1, l2,
                     "city.exr, all 400 terms: relight against bench-basis's SH colours, over each vertex's bound");
    free(Lp);
    free(tsh);
    free(sh);
    hl_free_big(Ybar);
    hl_bench_ref_destroy(br);
    hl_basis_bench_destroy(bb);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_mesh_destroy(mesh);
    remove(path);
    hl_context_destroy(ref);
}

/* ------------------------------------------------------------ bad */

static void t_bad(void)
{
    static const pt_bad_option cases[] = {
        {"-C 8 -N 16 --basis sh --sh-order 0", "--sh-order 0"},
        {"-C 8 -N 16 --basis sh --sh-order 33", "--sh-order 33"},
        {"-C 8 -N 16 --basis sh --sh-order 23", "--sh-order 23"}, /* 529 > 2 x 16^2 = 512 */
        /* order 20 by default on -N 8 (128 slots) */
        {"-C 8 -N 16 --basis sh -N 8", "--sh-order 20 (400 coefficients) with -N 8"},
        {"-C 8 -N 16 --sh-order 4", "--sh-order needs --basis sh"},
        {"-C 8 -N 16 --basis haar --sh-order 4", "--sh-order needs --basis sh"},
        {"-C 8 -N 16 --basis wavelet", "--basis wavelet"},
    };
    pt_refuse_options(cases, sizeof cases / sizeof cases[0], "sh_pipeline_bad");
    char err[4096];
    int rc = pt_run_precompute("-C 8 -N 16 --basis sh --sh-order 3", "sh_pipeline_bad", 1, err, sizeof err);
    HL_CHECK(rc == 0, "--basis sh --sh-order 3: exit %d: %s", rc, err);
    /* the library refuses the same */
    static const hl_precompute_desc bad[] = {
        {.N = 16, .C = 8, .basis = 3},
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_SH, .sh_order = 33},
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_SH, .sh_order = 23},
        {.N = 8, .C = 8, .basis = HL_TRANSPORT_BASIS_SH}, /* the default 20 on 128 slots */
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_HAAR, .sh_order = 4},
    };
    pt_library_refuses(bad, sizeof bad / sizeof bad[0], "sh_pipeline_lib");
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"kernel", t_kernel},
        {"constant", t_constant},
        {"cl_ref", t_cl_ref},
        {"bench", t_bench},
        {"bad", t_bad},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
