/* bench_basis.c - `bench-basis`: the same exact transport and lighting in
 * three bases, the paraboloid Haar wavelets, the Haar wavelets over the
 * six faces of a cube (the 2003 paper's layout) and real spherical
 * harmonics, the lighting cut to M terms, as Ng, Ramamoorthi and Hanrahan
 * (2003) compared the bases; the transport whole or cut to equal bytes;
 * and the time of one lighting change in each.
 *
 * The rows are bench_refs.c's exact ones: the same rays (hl_rt_visibility
 * with the transport's supersampling and offset) and the same
 * cube-to-paraboloid step. The cube rows take the same products of that
 * step grouped by cube texel (hl_cube_rows), so that both add up to the
 * same total. The paraboloid lighting is bench_refs.c's; the cube texels'
 * mean radiance comes from the same cells by taps built as carefully
 * (cube.c). Spherical harmonics see the paraboloid texel maps as the
 * piecewise-constant functions they stand for: the lighting's texel means
 * L_j project to l_k = sum_j L_j Ybar_jk, the transport to t_k = sum_j
 * (T_j / Omega_j) Ybar_jk, with Ybar_jk the integral of Y_k over texel j
 * (sh.h) and Omega_j = sqrt(4 pi) Ybar_j0 the same quadrature's solid
 * angle, so that a constant lighting gives the exact colours with the
 * first term alone.
 *
 * Depends on the benchmark's references (haarlight_tools.h), sh/sh.h,
 * cube/cube.h, maps (geom.h, twins.h), the ray caster (rays.h), the
 * lighting tables (lighting.h) and core.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cube.h"
#include "haarlight_tools.h"
#include "lighting.h"
#include "rays.h"
#include "sh.h"
#include "twins.h"

/* Gauss-Legendre points per side of a visibility texel for the cube rows
 * on their own footprints: the integrand is smooth but where the horizon
 * cuts a texel, and 4 x 4 points put the solid angle of every texel within
 * 2e-8 of its closed form, an unshadowed row's sum within 5e-7 of 1 at
 * C = 64 (hl.cube.rows). */
#define HL_BB_CUBE_QUAD 4u

/* The three families of bases: where their rows and lighting live. */
enum { FAM_PARA, FAM_CUBE, FAM_SH, FAM_COUNT };

struct hl_basis_bench {
    hl_context *ctx;
    const hl_transport *t;
    hl_bench_ref *br;
    hl_geom *g;
    hl_light_geom *lg;     /* its cell grid (wc x hc) */
    hl_cube_tables *ct;
    hl_cube_quad *cquad;   /* own-footprint cube rows only */
    uint32_t n, ncoef, ncube, Cq, order, nsh;
    uint32_t count[FAM_COUNT];
    uint32_t *idx;
    float *haar;      /* n x ncoef: exact rows, paraboloid Haar slots */
    float *cube;      /* n x ncube: exact rows, cube Haar coefficients */
    double *tsh;      /* n x nsh: the rows in spherical harmonics */
    uint32_t *rank[2]; /* n x count, FAM_PARA and FAM_CUBE: each
                          coefficient's place in its row by magnitude
                          (made when a byte budget is first asked for) */
    double *Ybar;     /* ncoef x nsh: texel integrals */
    float *Lp, *Lq;   /* 3 x ncoef, 3 x ncube: the lighting's texel means */
    float *Lw, *Lc;   /* 3 x ncoef, 3 x ncube: their Haar coefficients */
    float *w_area, *w_transport;   /* ncoef: the relighter's selection weights */
    float *wc_transport;           /* ncube: mean |T_i| of the sampled cube rows */
    double *lsh;      /* 3 x nsh: the lighting's harmonic coefficients */
    double *exact;    /* n x 3: the paraboloid's exact colours */
    double *exact_cube; /* n x 3: the cube's (its rows and lighting whole) */
    uint32_t *kept;   /* the indices of the terms kept, ascending */
    void *scratch;    /* the largest count: sort keys, or 3 planes of floats */
    int have_env;
};

const char *hl_basis_name(hl_basis basis)
{
    switch (basis) {
    case HL_BASIS_HAAR: return "haar";
    case HL_BASIS_HAAR_AREA: return "haar-area";
    case HL_BASIS_HAAR_TRANSPORT: return "haar-transport";
    case HL_BASIS_SH: return "sh";
    case HL_BASIS_SH_NONLINEAR: return "sh-nonlinear";
    case HL_BASIS_CUBE: return "cube-haar";
    case HL_BASIS_CUBE_AREA: return "cube-haar-area";
    case HL_BASIS_CUBE_TRANSPORT: return "cube-haar-transport";
    default: return "?";
    }
}

static int family(hl_basis basis)
{
    return basis <= HL_BASIS_HAAR_TRANSPORT ? FAM_PARA : basis >= HL_BASIS_CUBE ? FAM_CUBE : FAM_SH;
}

void hl_basis_bench_destroy(hl_basis_bench *b)
{
    if (!b) return;
    hl_bench_ref_destroy(b->br);
    hl_cube_tables_destroy(b->ct);
    hl_cube_quad_destroy(b->cquad);
    hl_light_geom_destroy(b->lg);
    hl_geom_destroy(b->g);
    free(b->idx);
    hl_free_big(b->haar);
    hl_free_big(b->cube);
    hl_free_big(b->tsh);
    hl_free_big(b->rank[0]);
    hl_free_big(b->rank[1]);
    hl_free_big(b->Ybar);
    free(b->Lp);
    free(b->Lq);
    free(b->Lw);
    free(b->Lc);
    free(b->w_area);
    free(b->w_transport);
    free(b->wc_transport);
    free(b->lsh);
    free(b->exact);
    free(b->exact_cube);
    free(b->kept);
    free(b->scratch);
    free(b);
}

uint32_t hl_basis_bench_default_cube_side(uint32_t N, uint32_t C) { return hl_cube_default_side(N, C); }

uint32_t hl_basis_bench_cube_side(const hl_basis_bench *b) { return b->Cq; }

/* Each vertex's texel row as the piecewise-constant function T_j / Omega_j,
 * projected. */
static void project_rows(hl_basis_bench *b, const float *texel)
{
    const uint32_t nc = b->ncoef, ns = b->nsh;
    const double s4pi = sqrt(4.0 * HL_PI);
    for (uint32_t k = 0; k < b->n; k++) {
        const float *T = texel + (size_t)k * nc;
        double *out = b->tsh + (size_t)k * ns;
        memset(out, 0, (size_t)ns * sizeof(double));
        for (uint32_t j = 0; j < nc; j++) {
            const double *y = b->Ybar + (size_t)j * ns, om = s4pi * y[0];
            if (T[j] == 0.0f || om <= 0.0) continue;
            const double v = T[j] / om;
            for (uint32_t q = 0; q < ns; q++) out[q] += v * y[q];
        }
    }
}

/* The exact rows of the sampled vertices, from one set of rays each: as
 * hl_bench_ref_rows on the paraboloid (the same calls), and regrouped on
 * the cube faces; texel gets the paraboloid texels (n x ncoef). */
static hl_result make_rows(hl_basis_bench *b, float *texel)
{
    const hl_mesh *m = b->t->mesh;
    const uint32_t S = b->t->info.supersample;
    const float offset = b->t->info.ray_offset * hl_mesh_query_diagonal(m), scale = (float)(1.0 / (HL_PI * S * S));
    hl_rt *rt = NULL;
    uint8_t *vis = malloc(b->g->ncube);
    float *T = malloc((size_t)(b->ncoef > b->ncube ? b->ncoef : b->ncube) * 4);
    hl_result r = vis && T ? hl_rt_create_filtered(b->ctx, m, &rt)
                           : hl_tools_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the exact transport");
    for (uint32_t k = 0; k < b->n && r == HL_OK; k++) {
        const uint32_t v = b->idx[k];
        const float *nrm = m->normals + 3 * (size_t)v;
        r = hl_rt_visibility(rt, b->g, m, v, 1, S, offset, vis, NULL);
        if (r != HL_OK) break;
        hl_ref_cube2para(b->g, vis, scale, nrm, T);
        memcpy(texel + (size_t)k * b->ncoef, T, (size_t)b->ncoef * 4);
        hl_ref_haar(b->g, T, b->haar + (size_t)k * b->ncoef); /* in place in T: after the copy */
        if (!b->Cq) continue;
        if (b->cquad) hl_cube_rows_exact(b->cquad, b->Cq, vis, scale, nrm, T);
        else hl_cube_rows(b->g, b->Cq, vis, scale, nrm, T);
        hl_cube_haar(b->Cq, T, b->cube + (size_t)k * b->ncube);
    }
    hl_rt_destroy(rt);
    free(vis);
    free(T);
    if (r != HL_OK) return r;
    /* the cube's transport weights: the mean |T_i| of the sampled rows */
    for (uint32_t i = 0; i < b->ncube; i++) {
        double s = 0.0;
        for (uint32_t k = 0; k < b->n; k++) s += fabsf(b->cube[(size_t)k * b->ncube + i]);
        b->wc_transport[i] = (float)(s / b->n);
    }
    return HL_OK;
}

hl_result hl_basis_bench_create_ex(hl_context *ctx, const hl_transport *t, const uint32_t *idx, uint32_t n,
                                   uint32_t sh_order, uint32_t cube_side, hl_cube_rows_mode cube_rows,
                                   hl_basis_bench **out)
{
    *out = NULL;
    if (sh_order < 1 || sh_order > HL_SH_MAX_ORDER || n < 1)
        return hl_tools_fail(ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: spherical-harmonic order %u (1 to %u), %u vertices",
                             sh_order, HL_SH_MAX_ORDER, n);
    /* Cq = 0: no power of two divides C, and the cube bases are left out */
    const uint32_t C = t->info.C, Cq = cube_side ? cube_side : hl_basis_bench_default_cube_side(t->info.N, C);
    if (cube_side && (Cq < 2 || Cq > 512 || (Cq & (Cq - 1)) || C % Cq))
        return hl_tools_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                             "bench-basis: cube side %u: expected a power of two from 2 to 512 that divides the "
                             "transport's C = %u",
                             Cq, C);
    for (uint32_t k = 0; k < n; k++)
        if (idx[k] >= t->info.vertex_count)
            return hl_tools_fail(ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: vertex %u of %u", idx[k], t->info.vertex_count);
    hl_basis_bench *b = hl_calloc(ctx, 1, sizeof *b, "the basis comparison");
    if (!b) return HL_ERR_OUT_OF_MEMORY;
    b->ctx = ctx;
    b->t = t;
    b->n = n;
    b->ncoef = 2 * t->info.N * t->info.N;
    b->Cq = Cq;
    b->ncube = 6 * Cq * Cq;
    b->order = sh_order;
    b->nsh = hl_sh_count(sh_order);
    b->count[FAM_PARA] = b->ncoef, b->count[FAM_CUBE] = b->ncube, b->count[FAM_SH] = b->nsh;
    const uint32_t nc = b->ncoef, nq = b->ncube;
    uint32_t most = nc > nq ? nc : nq;
    most = most > b->nsh ? most : b->nsh;
    float *texel = hl_alloc_big(ctx, (size_t)n * nc * 4, "the exact rows in texels");
    b->idx = malloc((size_t)n * 4);
    b->haar = hl_alloc_big(ctx, (size_t)n * nc * 4, "the exact rows");
    b->cube = hl_alloc_big(ctx, (size_t)n * (nq ? nq : 1) * 4, "the exact rows on the cube");
    b->tsh = hl_alloc_big(ctx, (size_t)n * b->nsh * sizeof(double), "the rows in spherical harmonics");
    b->Lp = malloc((size_t)nc * 12);
    b->Lw = malloc((size_t)nc * 12);
    b->Lq = malloc((size_t)(nq ? nq : 1) * 12);
    b->Lc = malloc((size_t)(nq ? nq : 1) * 12);
    b->w_area = malloc((size_t)nc * 4);
    b->w_transport = malloc((size_t)nc * 4);
    b->wc_transport = malloc((size_t)(nq ? nq : 1) * 4);
    b->lsh = malloc((size_t)b->nsh * 3 * sizeof(double));
    b->exact = malloc((size_t)n * 3 * sizeof(double));
    b->exact_cube = malloc((size_t)n * 3 * sizeof(double));
    b->kept = malloc((size_t)most * 4);
    b->scratch = malloc((size_t)most * 16); /* a term_key, or 3 floats + a double */
    hl_result r = HL_OK;
    if (!texel || !b->idx || !b->haar || !b->cube || !b->tsh || !b->Lp || !b->Lw || !b->Lq || !b->Lc || !b->w_area ||
        !b->w_transport || !b->wc_transport || !b->lsh || !b->exact || !b->exact_cube || !b->kept || !b->scratch)
        r = hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the basis comparison of %u vertices", n);
    if (r == HL_OK) {
        memcpy(b->idx, idx, (size_t)n * 4);
        r = hl_bench_ref_create(ctx, t, &b->br);
    }
    if (r == HL_OK) r = hl_geom_create(ctx, t->info.N, C, &b->g);
    if (r == HL_OK) r = hl_light_geom_create(ctx, b->g, &b->lg);
    if (r == HL_OK && Cq) r = hl_cube_tables_create(ctx, Cq, C, b->lg->wc, b->lg->hc, &b->ct);
    if (r == HL_OK && Cq && cube_rows == HL_CUBE_ROWS_OWN) r = hl_cube_quad_create(ctx, C, HL_BB_CUBE_QUAD, &b->cquad);
    if (r == HL_OK) r = make_rows(b, texel);
    if (r == HL_OK) r = hl_bench_ref_weights(b->br, HL_SELECT_AREA, b->w_area);
    if (r == HL_OK) r = hl_bench_ref_weights(b->br, HL_SELECT_TRANSPORT, b->w_transport);
    if (r == HL_OK) r = hl_sh_texel_integrals(ctx, t->info.N, sh_order, HL_SH_QUAD, &b->Ybar);
    if (r == HL_OK) project_rows(b, texel);
    hl_free_big(texel);
    if (r != HL_OK) {
        hl_basis_bench_destroy(b);
        return r;
    }
    *out = b;
    return HL_OK;
}

hl_result hl_basis_bench_create(hl_context *ctx, const hl_transport *t, const uint32_t *idx, uint32_t n,
                                uint32_t sh_order, hl_basis_bench **out)
{
    return hl_basis_bench_create_ex(ctx, t, idx, n, sh_order, 0, HL_CUBE_ROWS_SHARED, out);
}

uint32_t hl_basis_bench_count(const hl_basis_bench *b, hl_basis basis)
{
    return (int)basis < 0 || basis >= HL_BASIS_COUNT ? 0 : b->count[family(basis)];
}

/* The cube texel means and their Haar coefficients of env. */
static hl_result cube_lighting(hl_basis_bench *b, const hl_env *env)
{
    float *cells = NULL;
    hl_result r = hl_env_to_cells(b->ctx, env, b->lg->wc, b->lg->hc, &cells);
    if (r == HL_OK) hl_cube_lighting(b->ct, cells, b->Lq);
    hl_free_big(cells);
    return r;
}

/* The three Haar transforms of one map's texel means (the lighting
 * transform that is timed). */
static void para_transform(hl_basis_bench *b, float *tmp)
{
    memcpy(tmp, b->Lp, (size_t)b->ncoef * 12);
    for (int c = 0; c < 3; c++) hl_ref_haar(b->g, tmp + (size_t)c * b->ncoef, b->Lw + (size_t)c * b->ncoef);
}

static void cube_transform(hl_basis_bench *b, float *tmp)
{
    memcpy(tmp, b->Lq, (size_t)b->ncube * 12);
    for (int c = 0; c < 3; c++) hl_cube_haar(b->Cq, tmp + (size_t)c * b->ncube, b->Lc + (size_t)c * b->ncube);
}

static void sh_transform(hl_basis_bench *b)
{
    for (int c = 0; c < 3; c++)
        hl_sh_project(b->Ybar, b->ncoef, b->nsh, b->Lp + (size_t)c * b->ncoef, 1, b->lsh + (size_t)c * b->nsh);
}

hl_result hl_basis_bench_set_env(hl_basis_bench *b, const hl_env *env, const double **exact)
{
    *exact = NULL;
    b->have_env = 0;
    const uint32_t nc = b->ncoef;
    hl_result r = hl_bench_ref_lighting(b->br, env, b->Lp, b->Lw);
    if (r == HL_OK && b->Cq) r = cube_lighting(b, env);
    if (r != HL_OK) return r;
    if (b->Cq) cube_transform(b, b->scratch);
    sh_transform(b);
    /* as bench_refs.c's exact colours: each row dotted with the lighting
       in float64, in slot order, times the albedo */
    const float *albedo = b->t->mesh->albedo;
    for (uint32_t k = 0; k < b->n; k++)
        for (int c = 0; c < 3; c++) {
            const float *row = b->haar + (size_t)k * nc, *l = b->Lw + (size_t)c * nc;
            const float *rq = b->cube + (size_t)k * b->ncube, *lq = b->Lc + (size_t)c * b->ncube;
            double s = 0.0, sq = 0.0;
            for (uint32_t i = 0; i < nc; i++) s += (double)row[i] * l[i];
            for (uint32_t i = 0; i < b->ncube; i++) sq += (double)rq[i] * lq[i];
            b->exact[3 * k + c] = s * albedo[3 * (size_t)b->idx[k] + c];
            b->exact_cube[3 * k + c] = sq * albedo[3 * (size_t)b->idx[k] + c];
        }
    b->have_env = 1;
    *exact = b->exact;
    return HL_OK;
}

/* A term and its priority, sorted larger first, ties to the lower index
 * (so the choice is repeatable). */
typedef struct term_key { double key; uint32_t i; } term_key;
static int by_priority(const void *pa, const void *pb)
{
    const term_key *a = pa, *b = pb;
    if (a->key != b->key) return a->key > b->key ? -1 : 1;
    return a->i < b->i ? -1 : a->i > b->i;
}
static int by_index(const void *pa, const void *pb)
{
    const uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
    return a < b ? -1 : a > b;
}

/* kept[0 .. M-1] = the M of the count terms whose lighting (3 planes,
 * `stride` apart, floats lf or doubles ld) has the largest |luminance|
 * times weight[i] (weight NULL: 1), ascending. */
static void keep_largest(hl_basis_bench *b, const float *lf, const double *ld, size_t stride, uint32_t count,
                         const float *weight, uint32_t M)
{
    term_key *key = b->scratch;
    for (uint32_t i = 0; i < count; i++) {
        double v[3];
        for (int c = 0; c < 3; c++) v[c] = lf ? (double)lf[c * stride + i] : ld[c * stride + i];
        /* Rec. 709 luminance, as the relighter's selection ranks terms */
        key[i].key = fabs(0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]) * (weight ? (double)weight[i] : 1.0);
        key[i].i = i;
    }
    qsort(key, count, sizeof *key, by_priority);
    for (uint32_t i = 0; i < M; i++) b->kept[i] = key[i].i;
    qsort(b->kept, M, sizeof *b->kept, by_index);
}

/* The M lighting terms of basis into b->kept. */
static void select_terms(hl_basis_bench *b, hl_basis basis, uint32_t M)
{
    const uint32_t nc = b->ncoef, nq = b->ncube, ns = b->nsh;
    switch (basis) {
    case HL_BASIS_HAAR: keep_largest(b, b->Lw, NULL, nc, nc, NULL, M); break;
    case HL_BASIS_HAAR_AREA: keep_largest(b, b->Lw, NULL, nc, nc, b->w_area, M); break;
    case HL_BASIS_HAAR_TRANSPORT: keep_largest(b, b->Lw, NULL, nc, nc, b->w_transport, M); break;
    case HL_BASIS_SH_NONLINEAR: keep_largest(b, NULL, b->lsh, ns, ns, NULL, M); break;
    case HL_BASIS_CUBE: keep_largest(b, b->Lc, NULL, nq, nq, NULL, M); break;
    case HL_BASIS_CUBE_AREA: keep_largest(b, b->Lc, NULL, nq, nq, b->ct->area, M); break;
    case HL_BASIS_CUBE_TRANSPORT: keep_largest(b, b->Lc, NULL, nq, nq, b->wc_transport, M); break;
    default:
        for (uint32_t q = 0; q < M; q++) b->kept[q] = q;
    }
}

static hl_result check_args(hl_basis_bench *b, hl_basis basis, uint32_t M)
{
    if (!b->have_env) return hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: no environment set");
    if ((int)basis < 0 || basis >= HL_BASIS_COUNT || M < 1 || M > hl_basis_bench_count(b, basis))
        return hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: %u terms of %s (1 to %u)", M,
                             hl_basis_name(basis), hl_basis_bench_count(b, basis));
    return HL_OK;
}

/* The dot products over the kept terms (b->kept, M of them), of the
 * rows cut to their first K entries by rank (K = count: whole), times
 * the albedo. The kept terms go in ascending order, so whole rows with
 * every term add the exact colours' products in their order. */
static void dots(hl_basis_bench *b, int fam, uint32_t M, uint32_t K, double *rgb)
{
    const uint32_t cnt = b->count[fam];
    const float *albedo = b->t->mesh->albedo;
    const float *Lf = fam == FAM_PARA ? b->Lw : b->Lc;
    for (uint32_t k = 0; k < b->n; k++) {
        const uint32_t *rank = fam == FAM_SH || K >= cnt ? NULL : b->rank[fam] + (size_t)k * cnt;
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            if (fam == FAM_SH) {
                const double *row = b->tsh + (size_t)k * cnt, *l = b->lsh + (size_t)c * cnt;
                for (uint32_t q = 0; q < M; q++) {
                    const uint32_t i = b->kept[q];
                    if (i < K) s += row[i] * l[i];
                }
            } else {
                const float *row = (fam == FAM_PARA ? b->haar : b->cube) + (size_t)k * cnt, *l = Lf + (size_t)c * cnt;
                for (uint32_t q = 0; q < M; q++) {
                    const uint32_t i = b->kept[q];
                    if (!rank || rank[i] < K) s += (double)row[i] * l[i];
                }
            }
            rgb[3 * k + c] = s * albedo[3 * (size_t)b->idx[k] + c];
        }
    }
}

const double *hl_basis_bench_exact(const hl_basis_bench *b, hl_basis basis)
{
    if (!b->have_env || (family(basis) == FAM_CUBE && !b->Cq)) return NULL;
    return family(basis) == FAM_CUBE ? b->exact_cube : b->exact;
}

hl_result hl_basis_bench_continuous(hl_basis_bench *b, const hl_env *env, uint32_t n2, double *cont)
{
    if (!b->have_env || n2 < 1 || n2 > b->n)
        return hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: the continuous reference of %u of %u vertices%s",
                             n2, b->n, b->have_env ? "" : " before an environment");
    uint32_t *idx2 = malloc((size_t)n2 * 4);
    double *ex = malloc((size_t)n2 * 3 * sizeof(double));
    hl_result r = idx2 && ex ? HL_OK : hl_tools_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    for (uint32_t k = 0; k < n2 && r == HL_OK; k++) idx2[k] = b->idx[(uint64_t)k * b->n / n2];
    if (r == HL_OK) r = hl_bench_ref_colours(b->br, idx2, n2, idx2, n2, &env, 1, &ex, &cont);
    free(idx2);
    free(ex);
    return r;
}

hl_result hl_basis_bench_colours(hl_basis_bench *b, hl_basis basis, uint32_t M, double *rgb)
{
    hl_result r = check_args(b, basis, M);
    if (r != HL_OK) return r;
    select_terms(b, basis, M);
    dots(b, family(basis), M, b->count[family(basis)], rgb);
    return HL_OK;
}

uint32_t hl_basis_bench_entries(const hl_basis_bench *b, hl_basis basis, uint32_t bytes)
{
    const uint32_t cnt = hl_basis_bench_count(b, basis), fixed = 8 + 2 * ((cnt + 255) / 256);
    if (bytes <= fixed) return 0;
    const uint32_t K = (bytes - fixed) / 2;
    return K < cnt ? K : cnt;
}

/* Each row's coefficients ranked by magnitude (ties to the lower index),
 * once per Haar family. */
static hl_result make_ranks(hl_basis_bench *b, int fam)
{
    if (b->rank[fam]) return HL_OK;
    const uint32_t cnt = b->count[fam];
    const float *rows = fam == FAM_PARA ? b->haar : b->cube;
    b->rank[fam] = hl_alloc_big(b->ctx, (size_t)b->n * cnt * 4, "the rows' ranks");
    if (!b->rank[fam]) return HL_ERR_OUT_OF_MEMORY;
    term_key *key = b->scratch;
    for (uint32_t k = 0; k < b->n; k++) {
        const float *row = rows + (size_t)k * cnt;
        uint32_t *rk = b->rank[fam] + (size_t)k * cnt;
        for (uint32_t i = 0; i < cnt; i++) key[i].key = fabsf(row[i]), key[i].i = i;
        qsort(key, cnt, sizeof *key, by_priority);
        for (uint32_t i = 0; i < cnt; i++) rk[key[i].i] = i;
    }
    return HL_OK;
}

hl_result hl_basis_bench_colours_bytes(hl_basis_bench *b, hl_basis basis, uint32_t M, uint32_t bytes, double *rgb)
{
    hl_result r = check_args(b, basis, M);
    const int fam = family(basis);
    if (r == HL_OK && fam != FAM_SH) r = make_ranks(b, fam);
    if (r != HL_OK) return r;
    select_terms(b, basis, M);
    dots(b, fam, M, hl_basis_bench_entries(b, basis, bytes), rgb);
    return HL_OK;
}

hl_result hl_basis_bench_time(hl_basis_bench *b, hl_basis basis, uint32_t M, uint32_t reps, hl_basis_time *out)
{
    hl_result r = check_args(b, basis, M);
    if (r != HL_OK) return r;
    const int fam = family(basis);
    double *rgb = malloc((size_t)b->n * 3 * sizeof(double));
    float *tmp = malloc((size_t)(b->ncoef > b->ncube ? b->ncoef : b->ncube) * 12);
    if (!rgb || !tmp) {
        free(rgb), free(tmp);
        return hl_tools_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    }
    const double scale = (double)b->t->info.vertex_count / b->n;
    *out = (hl_basis_time){INFINITY, INFINITY, INFINITY};
    for (uint32_t i = 0; i < (reps ? reps : 1); i++) {
        const double t0 = hl_now();
        if (fam == FAM_PARA) para_transform(b, tmp);
        else if (fam == FAM_CUBE) cube_transform(b, tmp);
        else sh_transform(b);
        const double t1 = hl_now();
        select_terms(b, basis, M);
        const double t2 = hl_now();
        dots(b, fam, M, b->count[fam], rgb);
        const double t3 = hl_now();
        out->transform = fmin(out->transform, t1 - t0);
        out->select = fmin(out->select, t2 - t1);
        out->dots = fmin(out->dots, (t3 - t2) * scale);
    }
    free(rgb);
    free(tmp);
    return HL_OK;
}
