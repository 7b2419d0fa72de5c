/* test_cube_pipeline.c - Haar over the six cube faces through the real
 * pipeline (suite "cube_pipeline"): `precompute --basis cube-haar`, and
 * the relighter's lighting taken onto the same faces.
 *
 * Cases, each printing its tolerance and the worst error it saw:
 *   kernel    hl_cube_face_rows and hl_cube_face_haar (OpenCL) against
 *             their twins hl_cube_rows and hl_cube_haar (cube/cube.h) bit
 *             for bit at sides 2, 4 and 8, slots past 6 C'^2 zero; each
 *             face row's sum against the paraboloid row's (cube2para: the
 *             same products, summed in another order).
 *   constant  the bunny (N = C = 16, C' = 8) under a constant map, M = 6,
 *             200 and all, both backends: every vertex's colour against
 *             the exact one (the paraboloid rows' sums) within its bound
 *             (a sqrt8 step of the row's largest coefficient on each of
 *             the six faces' scaling terms, which are all a constant map
 *             has, plus what the energy rule may drop). M = 1 keeps one
 *             face of six, so it is not exact; its error is printed.
 *   cl_ref    the OpenCL file equals the reference's byte for byte, and so
 *             does the merge of three shards; relight
 *             under city.exr, M = 200 and all, OpenCL against reference;
 *             the device's cube lighting stage (turned 37 degrees) against
 *             the twins; --select area's weights are the face wavelets'
 *             supports (cube.h's table) and rank alike on both backends;
 *             a quarter turn equals the map rolled by a quarter, both
 *             backends; surroundings refused.
 *   bench     relight with every term against bench-basis's cube colours
 *             (exact rows of the same pieces, HL_CUBE_ROWS_SHARED) at 256
 *             vertices, within each vertex's quantisation and truncation
 *             bound.
 *   bad       the command refuses --cube-side 1, 3, too big for N, not
 *             dividing -C, without --basis cube-haar, and --sh-order with
 *             it (exit 2, naming the option); the library refuses the same
 *             descriptors.
 * Depends on: haarlight_core (internals: cube.h, twins.h, cl_backend.h,
 * geom.h, lighting.h, hl_shared.h; haarlight_tools.h for bench-basis and
 * the exact rows), data/bunny_lowres.obj and data/city.exr.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_backend.h"
#include "cube.h"
#include "geom.h"
#include "haarlight_tools.h"
#include "hl_shared.h"
#include "hl_test.h"
#include "lighting.h"
#include "pipeline_test.h"
#include "twins.h"

#define SCENE_N 16u
#define SCENE_SIDE 8u /* the default at N = C = 16 */


/* ------------------------------------------------------------ kernel */

static void t_kernel(void)
{
    hl_context *cl = hl_test_cl_context(0), *ref = hl_test_ref_context(0);
    if (!cl) exit(HL_TEST_SKIP);
    const uint32_t N = SCENE_N, C = 16, R = 7, nc = 2 * N * N;
    hl_geom *g = NULL;
    HL_CHECK(hl_geom_create(ref, N, C, &g) == HL_OK, "geom");
    const size_t nv = (size_t)R * g->ncube;
    uint8_t *vis = malloc(nv);
    float *nrm = malloc((size_t)R * 16), *dev = malloc((size_t)R * nc * 4), *twin = malloc((size_t)nc * 4);
    float *in = malloc((size_t)R * nc * 4), *par = malloc((size_t)nc * 4), *tmp = malloc((size_t)nc * 4);
    /* rows as the rays leave them: counts 0..4, about half zero, one row
       all zero; unit normals */
    for (size_t i = 0; i < nv; i++) vis[i] = hl_rng_unit() < 0.5 ? 0 : (uint8_t)(1 + hl_rng_unit() * 4);
    memset(vis + 2 * (size_t)g->ncube, 0, g->ncube);
    for (uint32_t v = 0; v < R; v++) {
        double d[3], l = 0.0;
        for (int k = 0; k < 3; k++) {
            d[k] = hl_rng_unit() * 2.0 - 1.0;
            l += d[k] * d[k];
        }
        for (int k = 0; k < 3; k++) nrm[4 * v + k] = (float)(d[k] / sqrt(l));
        nrm[4 * v + 3] = 0.0f;
    }
    const float scale = (float)(1.0 / HL_PI);
    static const uint32_t sides[] = {2, 4, 8};
    double worst_sum = 0.0;
    for (size_t si = 0; si < 3; si++) {
        const uint32_t Cq = sides[si], nt = 6 * Cq * Cq;
        hl_cl_pipe *p = NULL;
        HL_CHECK(hl_cl_pipe_create(cl, g, R, &p) == HL_OK && hl_cl_pipe_set_cube(p, Cq) == HL_OK, "pipe: %s",
                 hl_context_last_error(cl));
        HL_CHECK(hl_cl_pipe_cube_rows(p, R, vis, scale, nrm, dev) == HL_OK, "rows: %s", hl_context_last_error(cl));
        double worst = 0.0;
        uint32_t differ = 0;
        for (uint32_t v = 0; v < R; v++) {
            hl_cube_rows(g, Cq, vis + (size_t)v * g->ncube, scale, nrm + 4 * v, twin);
            const float *d = dev + (size_t)v * nc;
            double big = 0.0, sc = 0.0, sp = 0.0;
            for (uint32_t q = 0; q < nt; q++) big = fmax(big, fabs(twin[q]));
            for (uint32_t q = 0; q < nt; q++) {
                differ += memcmp(&d[q], &twin[q], 4) != 0;
                worst = fmax(worst, fabs((double)d[q] - twin[q]) / (big > 0.0 ? big : 1.0));
                sc += twin[q];
            }
            /* the paraboloid row of the same products */
            hl_ref_cube2para(g, vis + (size_t)v * g->ncube, scale, nrm + 4 * v, par);
            for (uint32_t j = 0; j < nc; j++) sp += par[j];
            if (sp > 0.0) worst_sum = fmax(worst_sum, fabs(sc - sp) / sp);
            else HL_CHECK(sc == 0.0, "row %u: face sum %g where the paraboloid's is 0", v, sc);
        }
        char what[160];
        snprintf(what, sizeof what, "C' = %u: hl_cube_face_rows against hl_cube_rows (relative to the row's largest)", Cq);
        hl_check_error(what, worst, 0.0);
        HL_CHECK(differ == 0, "C' = %u: %u face texels differ in their bits", Cq, differ);
        /* the faces' Haar on rows with zero texels */
        for (size_t i = 0; i < (size_t)R * nc; i++) in[i] = hl_rng_unit() < 0.5 ? 0.0f : (float)(hl_rng_unit() * 1e-3);
        /* the coefficient buffer dirtied first (the paraboloid Haar writes
           every slot), so the kernel's zeroing of the slots past 6 C'^2 is
           what the tail check sees */
        HL_CHECK(hl_cl_pipe_haar(p, R, in, dev) == HL_OK, "dirty: %s", hl_context_last_error(cl));
        HL_CHECK(hl_cl_pipe_cube_haar(p, R, in, dev) == HL_OK, "haar: %s", hl_context_last_error(cl));
        worst = 0.0;
        differ = 0;
        uint32_t tail = 0;
        for (uint32_t v = 0; v < R; v++) {
            memcpy(tmp, in + (size_t)v * nc, (size_t)nt * 4);
            hl_cube_haar(Cq, tmp, twin);
            const float *d = dev + (size_t)v * nc;
            double big = 0.0;
            for (uint32_t k = 0; k < nt; k++) big = fmax(big, fabs(twin[k]));
            for (uint32_t k = 0; k < nt; k++) {
                differ += memcmp(&d[k], &twin[k], 4) != 0;
                worst = fmax(worst, fabs((double)d[k] - twin[k]) / (big > 0.0 ? big : 1.0));
            }
            for (uint32_t k = nt; k < nc; k++) tail += d[k] != 0.0f;
        }
        snprintf(what, sizeof what, "C' = %u: hl_cube_face_haar against hl_cube_haar (relative to the row's largest)", Cq);
        hl_check_error(what, worst, 0.0);
        HL_CHECK(differ == 0, "C' = %u: %u coefficients differ in their bits", Cq, differ);
        HL_CHECK(tail == 0, "C' = %u: %u slots from 6 C'^2 on are not zero", Cq, tail);
        hl_cl_pipe_destroy(p);
    }
    /* the same non-negative products in two orders: float precision */
    hl_check_error("face rows' sums against the paraboloid rows' (relative)", worst_sum, 1e-5);
    free(vis);
    free(nrm);
    free(dev);
    free(twin);
    free(in);
    free(par);
    free(tmp);
    hl_geom_destroy(g);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* ------------------------------------------------------------ scenes */

/* The bunny's cube-face transport at path, made on ctx. */
static hl_mesh *cube_scene(hl_context *ctx, const char *path)
{
    const hl_precompute_desc d = {.N = SCENE_N, .C = SCENE_N, .basis = HL_TRANSPORT_BASIS_CUBE};
    return pt_scene(ctx, path, &d);
}

static hl_transport *load(hl_context *ctx, const char *path)
{
    hl_transport *t = NULL;
    HL_CHECK(hl_transport_load(ctx, path, &t) == HL_OK, "load: %s", hl_context_last_error(ctx));
    HL_CHECK(t->info.basis == HL_TRANSPORT_BASIS_CUBE && t->info.sh_order == SCENE_SIDE, "basis %u side %u",
             t->info.basis, t->info.sh_order);
    return t;
}


/* An upper bound on |t_v|, the untruncated row's norm, from what the file
 * keeps: the kept coefficients' norm is within sqrt(nnz) sqrt8 steps of
 * the decoded ones', and the energy rule keeps at least 1 - eps of |t|^2. */
static double row_norm_bound(const hl_transport *t, uint32_t v)
{
    const hl_row_quant q = t->row_quant[v];
    const uint32_t nb = t->info.block_count;
    uint64_t e = t->row_offset[v];
    double ss = 0.0, n = 0.0;
    for (uint32_t b = 0; b < nb; b++)
        for (uint32_t k = 0; k < t->block_counts[(size_t)v * nb + b]; k++, e++) {
            const uint32_t slot = b * HL_BLOCK + t->entries[2 * e];
            const double x = hl_dequant(t->info.quant, t->entries[2 * e + 1], q.a, q.b, hl_dither_key(v, slot));
            ss += x * x;
            n += 1.0;
        }
    return (sqrt(ss) + sqrt(n) * pt_sqrt8_step() * q.b) / sqrt(1.0 - t->info.eps);
}

/* ------------------------------------------------------------ constant */

static void t_constant(void)
{
    hl_context *ref = hl_test_ref_context(0), *cl = hl_test_cl_context(0);
    const char *path = hl_test_tmp_path("cube_pipeline_constant.hlt");
    hl_mesh *mesh = cube_scene(ref, path);
    hl_transport *t = load(ref, path);
    const uint32_t V = t->info.vertex_count, nc = 2 * SCENE_N * SCENE_N;
    const float c = 0.75f;
    float *rgb_in = malloc(64 * 32 * 12);
    for (int i = 0; i < 64 * 32 * 3; i++) rgb_in[i] = c;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ref, 64, 32, rgb_in, &env, NULL) == HL_OK, "env");
    /* the exact colours: the paraboloid rows' sums (the same products as
       the face rows') */
    uint32_t *idx = malloc((size_t)V * 4);
    for (uint32_t v = 0; v < V; v++) idx[v] = v;
    float *texel = malloc((size_t)V * nc * 4);
    double *sums = malloc((size_t)V * sizeof(double)), *tn = malloc((size_t)V * sizeof(double));
    hl_bench_ref *br = NULL;
    HL_CHECK(hl_bench_ref_create(ref, t, &br) == HL_OK, "bench ref: %s", hl_context_last_error(ref));
    HL_CHECK(hl_bench_ref_rows(br, idx, V, texel, NULL) == HL_OK, "rows: %s", hl_context_last_error(ref));
    for (uint32_t v = 0; v < V; v++) {
        double s = 0.0;
        for (uint32_t j = 0; j < nc; j++) s += texel[(size_t)v * nc + j];
        sums[v] = s;
        tn[v] = row_norm_bound(t, v);
    }
    /* a constant map in the faces' Haar: each face's scaling term c C' */
    const double l0 = c * SCENE_SIDE, eps = t->info.eps, q = pt_sqrt8_step();
    float *rgb = malloc((size_t)V * 12);
    /* per vertex, six terms l0 t_f: each t_f off by at most a sqrt8 step
       of the row's largest, b, or dropped by the energy rule (the dropped
       ones' sum at most sqrt(6 eps) |t|); the float sums add 1e-5 */
    double *bound = malloc((size_t)V * sizeof(double));
    for (uint32_t v = 0; v < V; v++)
        bound[v] = l0 * (6.0 * q * t->row_quant[v].b + sqrt(6.0 * eps) * tn[v]) + 1e-5 * l0 * sqrt(6.0) * tn[v];
    static const uint32_t Ms[] = {6, 200, 0, 1};
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
                     backend ? "OpenCL" : "reference", Ms[m] == 0 ? "all" : Ms[m] == 6 ? "6" : Ms[m] == 1 ? "1" : "200");
            if (Ms[m] == 1) {
                printf("%s: worst %.4g, not asserted (one face's scaling term of the six)\n", what, worst);
            } else {
                hl_check_error(what, worst, 1.0);
            }
            printf("    (the largest error relative to the exact colour: %.3g)\n", worst_rel);
        }
    }
    free(rgb);
    free(bound);
    free(rgb_in);
    free(idx);
    free(texel);
    free(sums);
    free(tn);
    hl_bench_ref_destroy(br);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_mesh_destroy(mesh);
    remove(path);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* ------------------------------------------------------------ cl_ref */


/* The device's cube lighting stage turned by deg against the twins:
 * env2para's on the face texels' taps, then hl_cube_haar. */
static void check_stage(hl_context *cl, hl_context *ref, const hl_transport *t, const hl_env *env, float deg)
{
    const uint32_t nc = 2 * t->info.N * t->info.N, Cq = t->info.sh_order, nt = 6 * Cq * Cq;
    hl_relighter *r = NULL;
    HL_CHECK(hl_relighter_create(cl, t, &r) == HL_OK && hl_relighter_set_env(r, env) == HL_OK, "relighter: %s",
             hl_context_last_error(cl));
    const hl_light_geom *lg = hl_relighter_tables(r);
    uint32_t s0 = 0;
    float f = 0.0f, *cells = NULL;
    hl_rotation_to_shift(deg, lg->wc, &s0, &f);
    hl_cube_tables *ct = NULL;
    HL_CHECK(hl_cube_tables_create(ref, Cq, t->info.C, lg->wc, lg->hc, &ct) == HL_OK, "tables");
    HL_CHECK(hl_env_to_cells(ref, env, lg->wc, lg->hc, &cells) == HL_OK, "cells");
    float *Lw = malloc((size_t)nc * 12), *Lp = malloc((size_t)nt * 12), *tw = malloc((size_t)nc * 12);
    HL_CHECK(hl_cl_light_stage_cube(hl_relighter_device(r), s0, f, Lw) == HL_OK, "stage: %s", hl_context_last_error(cl));
    hl_ref_env2para(cells, lg->wc, ct->tap_start, ct->taps, s0, f, nt, Lp);
    memset(tw, 0, (size_t)nc * 12);
    for (int ch = 0; ch < 3; ch++) hl_cube_haar(Cq, Lp + (size_t)ch * nt, tw + (size_t)ch * nc);
    char what[160];
    snprintf(what, sizeof what,
             "the relighter's cube lighting stage (OpenCL, turned %g degrees) against the twins, relative to the largest",
             (double)deg);
    hl_check_error(what, hl_test_rel_diff(tw, Lw, 3 * (size_t)nc), 1e-6);
    free(Lw);
    free(Lp);
    free(tw);
    hl_free_big(cells);
    hl_cube_tables_destroy(ct);
    hl_relighter_destroy(r);
}

static void t_cl_ref(void)
{
    hl_context *ref = hl_test_ref_context(0), *cl = hl_test_cl_context(0);
    if (!cl) exit(HL_TEST_SKIP);
    const char *pr = hl_test_tmp_path("cube_pipeline_ref.hlt"), *pc = hl_test_tmp_path("cube_pipeline_cl.hlt");
    hl_mesh *m1 = cube_scene(ref, pr), *m2 = cube_scene(cl, pc);
    pt_check_same_file(pr, pc, "precompute, OpenCL against reference");
    /* three shards merged: the basis words carried, the same file */
    {
        hl_precompute_desc d = {.N = SCENE_N, .C = SCENE_N, .basis = HL_TRANSPORT_BASIS_CUBE};
        const char *sp[3] = {hl_test_tmp_path("cube_pipeline_s0.hlt"), hl_test_tmp_path("cube_pipeline_s1.hlt"),
                             hl_test_tmp_path("cube_pipeline_s2.hlt")};
        const char *pm = hl_test_tmp_path("cube_pipeline_merged.hlt");
        for (uint32_t i = 0; i < 3; i++)
            HL_CHECK(hl_precompute_shard(ref, m1, &d, i, 3, sp[i], NULL) == HL_OK, "shard %u: %s", i,
                     hl_context_last_error(ref));
        HL_CHECK(hl_transport_merge(ref, pm, sp, 3, NULL) == HL_OK, "merge: %s", hl_context_last_error(ref));
        pt_check_same_file(pr, pm, "three shards merged, against the whole run");
        for (int i = 0; i < 3; i++) remove(sp[i]);
        remove(pm);
    }
    hl_transport *t = load(ref, pr);
    hl_env *env = NULL;
    HL_CHECK(hl_env_load(ref, hl_test_data_path("city.exr"), &env, NULL) == HL_OK, "env: %s", hl_context_last_error(ref));
    const uint32_t V = t->info.vertex_count, nc = 2 * SCENE_N * SCENE_N, Cq = SCENE_SIDE, nt = 6 * Cq * Cq;
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
    check_stage(cl, ref, t, env, 0.0f);
    check_stage(cl, ref, t, env, 37.0f);
    /* --select area: each face wavelet's support, as cube.h's table has
       it, nothing past 6 C'^2; then the same ranking on both backends */
    {
        hl_cube_tables *ct = NULL;
        hl_relighter *r = NULL;
        HL_CHECK(hl_relighter_create(ref, t, &r) == HL_OK, "relighter");
        HL_CHECK(hl_cube_tables_create(ref, Cq, t->info.C, hl_relighter_tables(r)->wc, hl_relighter_tables(r)->hc,
                                       &ct) == HL_OK, "tables");
        float *w = malloc((size_t)nc * 4);
        HL_CHECK(hl_selection_weights(ref, t, hl_relighter_tables(r), HL_SELECT_AREA, w) == HL_OK, "weights");
        uint32_t differ = 0;
        for (uint32_t k = 0; k < nc; k++) differ += k < nt ? memcmp(&w[k], &ct->area[k], 4) != 0 : w[k] != 0.0f;
        HL_CHECK(differ == 0, "%u area weights differ from the face wavelets' supports", differ);
        printf("area weights: the %u face wavelets' supports (%.4g to %.4g sr), zero past them\n", nt, (double)w[nt - 1],
               (double)w[0]);
        free(w);
        hl_cube_tables_destroy(ct);
        hl_relighter_destroy(r);
    }
    pt_relight(ref, t, env, 50, HL_SELECT_AREA, 0.0f, x);
    pt_relight(cl, t, env, 50, HL_SELECT_AREA, 0.0f, y);
    hl_check_error("M = 50, --select area: OpenCL against reference (relative to the brightest)",
                   hl_test_rel_diff(x, y, 3 * (size_t)V), 1e-5);
    /* a quarter turn is the map rolled by a quarter of its width: 256
       columns over the 128 cells of N = 16, so the cells roll by 32 */
    {
        const uint32_t W = 256, H = 128;
        float *p0 = malloc((size_t)W * H * 12), *p1 = malloc((size_t)W * H * 12);
        for (uint32_t i = 0; i < W * H * 3; i++) p0[i] = (float)(hl_rng_unit() * 2.0);
        for (uint32_t row = 0; row < H; row++)
            for (uint32_t col = 0; col < W; col++)
                memcpy(p1 + 3 * ((size_t)row * W + col), p0 + 3 * ((size_t)row * W + (col + W / 4) % W), 12);
        hl_env *e0 = NULL, *e1 = NULL;
        HL_CHECK(hl_env_create(ref, W, H, p0, &e0, NULL) == HL_OK && hl_env_create(ref, W, H, p1, &e1, NULL) == HL_OK,
                 "envs");
        for (int backend = 0; backend < 2; backend++) {
            hl_context *ctx = backend ? cl : ref;
            pt_relight(ctx, t, e0, 200, 0, 90.0f, x);
            pt_relight(ctx, t, e1, 200, 0, 0.0f, y);
            char what[160];
            snprintf(what, sizeof what, "%s, M = 200: turned 90 degrees against the map rolled a quarter",
                     backend ? "OpenCL" : "reference");
            hl_check_error(what, hl_test_rel_diff(x, y, 3 * (size_t)V), 0.0);
        }
        hl_env_destroy(e0);
        hl_env_destroy(e1);
        free(p0);
        free(p1);
    }
    /* surroundings: refused, naming the basis */
    {
        hl_relighter *r = NULL;
        HL_CHECK(hl_relighter_create(ref, t, &r) == HL_OK, "relighter");
        hl_result res = hl_relighter_set_surroundings(r, (hl_surroundings *)(uintptr_t)1);
        printf("surroundings: %s\n", hl_context_last_error(ref));
        HL_CHECK(res == HL_ERR_INVALID_ARGUMENT && strstr(hl_context_last_error(ref), "cube-face Haar"),
                 "surroundings on a cube-face file: %d", (int)res);
        hl_relighter_destroy(r);
    }
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
    const char *path = hl_test_tmp_path("cube_pipeline_bench.hlt");
    hl_mesh *mesh = cube_scene(ref, path);
    hl_transport *t = load(ref, path);
    const uint32_t V = t->info.vertex_count, n = 256, Cq = SCENE_SIDE, nt = 6 * Cq * Cq;
    uint32_t idx[256];
    for (uint32_t i = 0; i < n; i++) idx[i] = (uint32_t)((uint64_t)i * V / n);
    hl_env *env = NULL;
    HL_CHECK(hl_env_load(ref, hl_test_data_path("city.exr"), &env, NULL) == HL_OK, "env: %s", hl_context_last_error(ref));
    hl_basis_bench *bb = NULL;
    const double *exact = NULL;
    double *cube = malloc((size_t)n * 3 * sizeof(double));
    HL_CHECK(hl_basis_bench_create_ex(ref, t, idx, n, 2, Cq, HL_CUBE_ROWS_SHARED, &bb) == HL_OK, "bench: %s",
             hl_context_last_error(ref));
    HL_CHECK(hl_basis_bench_set_env(bb, env, &exact) == HL_OK, "bench env: %s", hl_context_last_error(ref));
    HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_CUBE, nt, cube) == HL_OK, "bench colours");
    /* the bound's lighting: the faces' Haar of the texel means, as the
       relighter makes it */
    hl_relighter *r = NULL;
    HL_CHECK(hl_relighter_create(ref, t, &r) == HL_OK, "relighter");
    const hl_light_geom *lg = hl_relighter_tables(r);
    hl_cube_tables *ct = NULL;
    float *cells = NULL, *Lp = malloc((size_t)nt * 12), *Lw = malloc((size_t)nt * 4);
    HL_CHECK(hl_cube_tables_create(ref, Cq, t->info.C, lg->wc, lg->hc, &ct) == HL_OK, "tables");
    HL_CHECK(hl_env_to_cells(ref, env, lg->wc, lg->hc, &cells) == HL_OK, "cells");
    hl_cube_lighting(ct, cells, Lp);
    double l1[3] = {0}, l2[3];
    for (int ch = 0; ch < 3; ch++) {
        double l[6 * SCENE_SIDE * SCENE_SIDE];
        hl_cube_haar(Cq, Lp + (size_t)ch * nt, Lw);
        for (uint32_t k = 0; k < nt; k++) l1[ch] += fabs(l[k] = Lw[k]);
        l2[ch] = pt_norm2(l, nt);
    }
    double tn[256];
    for (uint32_t i = 0; i < n; i++) tn[i] = row_norm_bound(t, idx[i]);
    pt_check_against(ref, t, mesh, env, idx, n, cube, tn, l1, l2,
                     "city.exr, all 384 terms: relight against bench-basis's cube colours, over each vertex's bound");
    free(Lp);
    free(Lw);
    free(cube);
    hl_free_big(cells);
    hl_cube_tables_destroy(ct);
    hl_relighter_destroy(r);
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
        {"-N 16 -C 8 --basis cube-haar --cube-side 1", "--cube-side 1"},
        {"-N 16 -C 8 --basis cube-haar --cube-side 3", "--cube-side 3"},
        {"-N 16 -C 8 --basis cube-haar --cube-side 1024", "--cube-side 1024"},
        {"-N 16 -C 32 --basis cube-haar --cube-side 16", "--cube-side 16 (1536 coefficients) with -N 16 (512 slots)"},
        {"-N 16 -C 12 --basis cube-haar --cube-side 8", "-C 12"},
        {"-N 16 -C 9 --basis cube-haar", "-C 9"},
        {"-N 16 -C 8 --cube-side 4", "--cube-side needs --basis cube-haar"},
        {"-N 16 -C 8 --basis sh --cube-side 4", "--cube-side needs --basis cube-haar"},
        {"-N 16 -C 8 --basis cube-haar --sh-order 4", "--sh-order needs --basis sh"},
        {"-N 16 -C 8 --basis cube", "--basis cube"},
    };
    pt_refuse_options(cases, sizeof cases / sizeof cases[0], "cube_pipeline_bad");
    char err[4096];
    int rc = pt_run_precompute("-N 16 -C 8 --basis cube-haar --cube-side 4", "cube_pipeline_bad", 1, err, sizeof err);
    HL_CHECK(rc == 0, "--basis cube-haar --cube-side 4: exit %d: %s", rc, err);
    /* the library refuses the same */
    static const hl_precompute_desc bad[] = {
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_CUBE, .cube_side = 1},
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_CUBE, .cube_side = 3},
        {.N = 16, .C = 32, .basis = HL_TRANSPORT_BASIS_CUBE, .cube_side = 16},
        {.N = 16, .C = 12, .basis = HL_TRANSPORT_BASIS_CUBE, .cube_side = 8},
        {.N = 16, .C = 9, .basis = HL_TRANSPORT_BASIS_CUBE},
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_HAAR, .cube_side = 4},
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_SH, .cube_side = 4},
        {.N = 16, .C = 8, .basis = HL_TRANSPORT_BASIS_CUBE, .sh_order = 4},
        {.N = 16, .C = 8, .basis = 3},
    };
    pt_library_refuses(bad, sizeof bad / sizeof bad[0], "cube_pipeline_lib");
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"kernel", t_kernel}, {"constant", t_constant}, {"cl_ref", t_cl_ref},
        {"bench", t_bench},   {"bad", t_bad},           {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
