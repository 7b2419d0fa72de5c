/* bench_basis.c - `bench-basis`: the same exact transport and lighting in
 * the paraboloid Haar basis and in real spherical harmonics, the lighting
 * cut to M terms, the transport untruncated, as Ng, Ramamoorthi and
 * Hanrahan (2003) compared the bases.
 *
 * The rows and the lighting are bench_refs.c's exact ones (the same rays,
 * the same cube-to-paraboloid step, the same environment-to-paraboloid
 * taps). Spherical harmonics see the texel maps as the piecewise-constant
 * functions they stand for: the lighting's texel means L_j project to
 * l_k = sum_j L_j Ybar_jk, the transport to t_k = sum_j (T_j / Omega_j)
 * Ybar_jk, with Ybar_jk the integral of Y_k over texel j (sh.h) and
 * Omega_j = sqrt(4 pi) Ybar_j0 the same quadrature's solid angle, so that
 * a constant lighting gives the exact colours with the first term alone.
 *
 * Depends on the benchmark's references (haarlight_tools.h), sh/sh.h and
 * core.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "haarlight_tools.h"
#include "sh.h"

struct hl_basis_bench {
    hl_context *ctx;
    const hl_transport *t;
    hl_bench_ref *br;
    uint32_t n, ncoef, order, nsh;
    uint32_t *idx;
    float *haar;      /* n x ncoef: exact rows, Haar slots */
    double *tsh;      /* n x nsh: the rows in spherical harmonics */
    double *Ybar;     /* ncoef x nsh: texel integrals */
    float *Lw;        /* 3 x ncoef: the lighting's Haar coefficients */
    float *w_area, *w_transport; /* ncoef: the relighter's selection weights */
    double *lsh;      /* 3 x nsh: its harmonic coefficients */
    double *exact;    /* n x 3 */
    uint8_t *keep;    /* max(ncoef, nsh): the terms kept */
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
    default: return "?";
    }
}

void hl_basis_bench_destroy(hl_basis_bench *b)
{
    if (!b) return;
    hl_bench_ref_destroy(b->br);
    free(b->idx);
    hl_free_big(b->haar);
    hl_free_big(b->tsh);
    hl_free_big(b->Ybar);
    free(b->Lw);
    free(b->w_area);
    free(b->w_transport);
    free(b->lsh);
    free(b->exact);
    free(b->keep);
    free(b);
}

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

hl_result hl_basis_bench_create(hl_context *ctx, const hl_transport *t, const uint32_t *idx, uint32_t n,
                                uint32_t sh_order, hl_basis_bench **out)
{
    *out = NULL;
    if (sh_order < 1 || sh_order > HL_SH_MAX_ORDER || n < 1)
        return hl_tools_fail(ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: spherical-harmonic order %u (1 to %u), %u vertices",
                             sh_order, HL_SH_MAX_ORDER, n);
    for (uint32_t k = 0; k < n; k++)
        if (idx[k] >= t->info.vertex_count)
            return hl_tools_fail(ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: vertex %u of %u", idx[k], t->info.vertex_count);
    hl_basis_bench *b = hl_calloc(ctx, 1, sizeof *b, "the basis comparison");
    if (!b) return HL_ERR_OUT_OF_MEMORY;
    b->ctx = ctx;
    b->t = t;
    b->n = n;
    b->ncoef = 2 * t->info.N * t->info.N;
    b->order = sh_order;
    b->nsh = hl_sh_count(sh_order);
    const uint32_t nc = b->ncoef, most = nc > b->nsh ? nc : b->nsh;
    float *texel = hl_alloc_big(ctx, (size_t)n * nc * 4, "the exact rows in texels");
    b->idx = malloc((size_t)n * 4);
    b->haar = hl_alloc_big(ctx, (size_t)n * nc * 4, "the exact rows");
    b->tsh = hl_alloc_big(ctx, (size_t)n * b->nsh * sizeof(double), "the rows in spherical harmonics");
    b->Lw = malloc((size_t)nc * 12);
    b->w_area = malloc((size_t)nc * 4);
    b->w_transport = malloc((size_t)nc * 4);
    b->lsh = malloc((size_t)b->nsh * 3 * sizeof(double));
    b->exact = malloc((size_t)n * 3 * sizeof(double));
    b->keep = malloc(most);
    hl_result r = HL_OK;
    if (!texel || !b->idx || !b->haar || !b->tsh || !b->Lw || !b->w_area || !b->w_transport || !b->lsh || !b->exact || !b->keep)
        r = hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the basis comparison of %u vertices", n);
    if (r == HL_OK) {
        memcpy(b->idx, idx, (size_t)n * 4);
        r = hl_bench_ref_create(ctx, t, &b->br);
    }
    if (r == HL_OK) r = hl_bench_ref_rows(b->br, idx, n, texel, b->haar);
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

uint32_t hl_basis_bench_count(const hl_basis_bench *b, hl_basis basis)
{
    return basis <= HL_BASIS_HAAR_TRANSPORT ? b->ncoef : b->nsh;
}

hl_result hl_basis_bench_set_env(hl_basis_bench *b, const hl_env *env, const double **exact)
{
    *exact = NULL;
    b->have_env = 0;
    const uint32_t nc = b->ncoef, ns = b->nsh;
    float *Lp = malloc((size_t)nc * 12);
    if (!Lp) return hl_tools_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the lighting");
    hl_result r = hl_bench_ref_lighting(b->br, env, Lp, b->Lw);
    for (int c = 0; c < 3 && r == HL_OK; c++)
        hl_sh_project(b->Ybar, nc, ns, Lp + (size_t)c * nc, 1, b->lsh + (size_t)c * ns);
    free(Lp);
    if (r != HL_OK) return r;
    /* as bench_refs.c's exact colours: each row dotted with the lighting
       in float64, in slot order, times the albedo */
    const float *albedo = b->t->mesh->albedo;
    for (uint32_t k = 0; k < b->n; k++)
        for (int c = 0; c < 3; c++) {
            const float *row = b->haar + (size_t)k * nc, *l = b->Lw + (size_t)c * nc;
            double s = 0.0;
            for (uint32_t i = 0; i < nc; i++) s += (double)row[i] * l[i];
            b->exact[3 * k + c] = s * albedo[3 * (size_t)b->idx[k] + c];
        }
    b->have_env = 1;
    *exact = b->exact;
    return HL_OK;
}

/* A term and its priority, sorted larger |luminance| first, ties to the
 * lower index (so the choice is repeatable). */
typedef struct term_key { double key; uint32_t i; } term_key;
static int by_priority(const void *pa, const void *pb)
{
    const term_key *a = pa, *b = pb;
    if (a->key != b->key) return a->key > b->key ? -1 : 1;
    return a->i < b->i ? -1 : a->i > b->i;
}

/* keep[i] = 1 for the M of the count terms whose lighting (3 planes,
 * `stride` apart, floats lf or doubles ld) has the largest |luminance|
 * times weight[i] (weight NULL: 1). */
static hl_result keep_largest(hl_basis_bench *b, const float *lf, const double *ld, size_t stride, uint32_t count,
                              const float *weight, uint32_t M)
{
    term_key *key = malloc((size_t)count * sizeof *key);
    if (!key) return hl_tools_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    for (uint32_t i = 0; i < count; i++) {
        double v[3];
        for (int c = 0; c < 3; c++) v[c] = lf ? (double)lf[c * stride + i] : ld[c * stride + i];
        /* Rec. 709 luminance, as the relighter's selection ranks terms */
        key[i].key = fabs(0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]) * (weight ? (double)weight[i] : 1.0);
        key[i].i = i;
    }
    qsort(key, count, sizeof *key, by_priority);
    memset(b->keep, 0, count);
    for (uint32_t i = 0; i < M; i++) b->keep[key[i].i] = 1;
    free(key);
    return HL_OK;
}

hl_result hl_basis_bench_colours(hl_basis_bench *b, hl_basis basis, uint32_t M, double *rgb)
{
    if (!b->have_env) return hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: no environment set");
    if ((int)basis < 0 || basis >= HL_BASIS_COUNT || M < 1 || M > hl_basis_bench_count(b, basis))
        return hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT, "bench-basis: %u terms of %s (1 to %u)", M,
                             hl_basis_name(basis), basis < HL_BASIS_COUNT ? hl_basis_bench_count(b, basis) : 0);
    const uint32_t nc = b->ncoef, ns = b->nsh;
    const float *albedo = b->t->mesh->albedo;
    hl_result r = HL_OK;
    if (basis == HL_BASIS_HAAR) r = keep_largest(b, b->Lw, NULL, nc, nc, NULL, M);
    else if (basis == HL_BASIS_HAAR_AREA) r = keep_largest(b, b->Lw, NULL, nc, nc, b->w_area, M);
    else if (basis == HL_BASIS_HAAR_TRANSPORT) r = keep_largest(b, b->Lw, NULL, nc, nc, b->w_transport, M);
    else if (basis == HL_BASIS_SH_NONLINEAR) r = keep_largest(b, NULL, b->lsh, ns, ns, NULL, M);
    else
        for (uint32_t q = 0; q < ns; q++) b->keep[q] = q < M;
    if (r != HL_OK) return r;
    for (uint32_t k = 0; k < b->n; k++)
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            if (basis <= HL_BASIS_HAAR_TRANSPORT) {
                const float *row = b->haar + (size_t)k * nc, *l = b->Lw + (size_t)c * nc;
                for (uint32_t i = 0; i < nc; i++)
                    if (b->keep[i]) s += (double)row[i] * l[i];
            } else {
                const double *row = b->tsh + (size_t)k * ns, *l = b->lsh + (size_t)c * ns;
                for (uint32_t q = 0; q < ns; q++)
                    if (b->keep[q]) s += row[q] * l[q];
            }
            rgb[3 * k + c] = s * albedo[3 * (size_t)b->idx[k] + c];
        }
    return HL_OK;
}
