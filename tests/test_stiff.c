/* test_stiff.c - numerical stability under stiff and extreme input (suite
 * "stiff", issue 5's "Numerical stability" list).
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
 * Cases (ctest hl.stiff.<case>; `test_stiff all` runs them in turn):
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
 *   resolution     (N, C) over 8 .. 256: white furnace per N
 *   truncation     K = 0 (keeps nothing; the CLI refuses --terms 0), K = 1
 *                  (min == max quantises exactly), K = all (every non-zero)
 *   zero_transport vertices inside a closed box and facing down onto the
 *                  ground: empty rows, a = b = 0, colours exactly 0
 *   scale          the scene at 1e-6 and 1e6, and 2e5 and 1e6 away from
 *                  the origin: the unit scene's rays from the same
 *                  origins, colours within what those allow
 *   shape          zero-area triangles, duplicate vertices, zero normals
 *   accumulation   rows of up to 2 N^2 terms at N = 128 and 256 against
 *                  double sums
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL), HL_TMP, HL_BIN.
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

#define U_F32 5.9604644775390625e-08     /* 2^-24, float unit roundoff */
#define SUB_HALF 7.0064923216240854e-46  /* 2^-150, half the least subnormal */

/* ---------------------------------------------------------------- cases */

/* Every scenario counts as one case of the suite (both backends run in
 * it); hl_test_failures tells whether it passed. */
static int cases_run, cases_failed, case_mark;
static char case_label[200];

static void case_begin(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(case_label, sizeof case_label, fmt, ap);
    va_end(ap);
    case_mark = hl_test_failures;
    printf("== %s\n", case_label);
}

static void case_end(void)
{
    int bad = hl_test_failures != case_mark;
    cases_run++;
    cases_failed += bad;
    printf("== %s: %s\n", case_label, bad ? "FAILED" : "passed");
}

/* The test cannot go on without its memory. */
static void *need(void *p)
{
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    return p;
}

static size_t count_nonfinite(const float *x, size_t n)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++) k += !isfinite(x[i]);
    return k;
}

/* ---------------------------------------------------------------- contexts */

static hl_context *contexts[2]; /* 0: OpenCL, 1: the plain-C reference */
static const char *const backend_name[2] = {"OpenCL", "reference"};

static hl_context *ctx_for(int b)
{
    if (!contexts[b]) {
        hl_context_desc d = {.backend = b ? HL_BACKEND_REFERENCE : HL_BACKEND_OPENCL,
                             .cl_platform = -1, .cl_device = -1, .quiet = 1};
        char err[4096];
        if (hl_context_create(&d, &contexts[b], err, sizeof err) != HL_OK) {
            fprintf(stderr, "cannot create the %s context: %s\n", backend_name[b], err);
            exit(1);
        }
    }
    return contexts[b];
}

static hl_context *ref_ctx(void) { return ctx_for(1); }

/* ---------------------------------------------------------------- meshes */

/* Appends an n x n grid of quads over [-half, half]^2 at height y, normal
 * +Y, to the arrays (3 floats per vertex, 3 indices per triangle). */
typedef struct builder {
    double *p;
    float *n;
    uint32_t *idx;
    uint32_t nv, nt;
} builder;

static void add_vertex(builder *b, double x, double y, double z, float nx, float ny, float nz)
{
    double *p = b->p + 3 * (size_t)b->nv;
    float *n = b->n + 3 * (size_t)b->nv;
    p[0] = x, p[1] = y, p[2] = z;
    n[0] = nx, n[1] = ny, n[2] = nz;
    b->nv++;
}

static void add_tri(builder *b, uint32_t i, uint32_t j, uint32_t k)
{
    uint32_t *t = b->idx + 3 * (size_t)b->nt++;
    t[0] = i, t[1] = j, t[2] = k;
}

static void add_grid(builder *b, uint32_t n, double half, double y)
{
    uint32_t first = b->nv, row = n + 1;
    for (uint32_t j = 0; j <= n; j++)
        for (uint32_t i = 0; i <= n; i++)
            add_vertex(b, -half + 2.0 * half * i / n, y, -half + 2.0 * half * j / n, 0, 1, 0);
    /* (a, c, b): (c - a) x (b - a) = +Z x +X = +Y */
    for (uint32_t j = 0; j < n; j++)
        for (uint32_t i = 0; i < n; i++) {
            uint32_t a = first + j * row + i;
            add_tri(b, a, a + row, a + 1);
            add_tri(b, a + 1, a + row, a + row + 1);
        }
}

/* A box of half-size h about c with one flat normal per face (24
 * vertices), wound outward. */
static void add_box(builder *b, const double c[3], double h)
{
    for (int k = 0; k < 3; k++)
        for (int s = -1; s <= 1; s += 2) {
            int u = (k + 1) % 3, v = (k + 2) % 3; /* e_u x e_v = e_k */
            static const int cu[4] = {-1, 1, 1, -1}, cv[4] = {-1, -1, 1, 1};
            uint32_t first = b->nv;
            for (int q = 0; q < 4; q++) {
                int qq = s > 0 ? q : 3 - q;
                double p[3];
                p[k] = c[k] + s * h;
                p[u] = c[u] + cu[qq] * h;
                p[v] = c[v] + cv[qq] * h;
                float nn[3] = {0, 0, 0};
                nn[k] = (float)s;
                add_vertex(b, p[0], p[1], p[2], nn[0], nn[1], nn[2]);
            }
            add_tri(b, first, first + 1, first + 2);
            add_tri(b, first, first + 2, first + 3);
        }
}

static hl_mesh *build_mesh(const builder *b, double scale, const double shift[3], int with_normals)
{
    float *P = need(malloc((size_t)b->nv * 12));
    for (uint32_t i = 0; i < 3 * b->nv; i++) P[i] = (float)(b->p[i] * scale + shift[i % 3]);
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_create(ref_ctx(), b->nv, P, with_normals ? b->n : NULL, NULL, b->nt, b->idx, &m);
    HL_CHECK(r == HL_OK, "mesh: %s", hl_context_last_error(ref_ctx()));
    free(P);
    return m;
}

static builder builder_new(uint32_t max_vertices, uint32_t max_triangles)
{
    builder b = {need(malloc((size_t)max_vertices * 3 * sizeof(double))), need(malloc((size_t)max_vertices * 12)),
                 need(malloc((size_t)max_triangles * 12)), 0, 0};
    return b;
}

static void builder_free(builder *b)
{
    free(b->p);
    free(b->n);
    free(b->idx);
}

/* The small scene: a 4 x 4 ground of 8 x 8 quads at y = 0 and a unit box
 * floating 0.25 above it (105 vertices). Its coordinates are multiples of
 * 1/4, so a copy 1e6 away (float spacing 1/16 there) is exact. */
static const double no_shift[3] = {0, 0, 0};

static hl_mesh *scene_mesh(double scale, const double shift[3])
{
    builder b = builder_new(81 + 24, 128 + 12);
    add_grid(&b, 8, 2.0, 0.0);
    const double c[3] = {0.0, 0.75, 0.0};
    add_box(&b, c, 0.5);
    hl_mesh *m = build_mesh(&b, scale, shift, 1);
    builder_free(&b);
    return m;
}

/* One open quad, normal +Y, albedo 1 (the white furnace). */
static hl_mesh *quad_mesh(void)
{
    const float P[12] = {-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1};
    const float Nn[12] = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    const float A[12] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};
    const uint32_t I[6] = {0, 2, 1, 0, 3, 2};
    hl_mesh *m = NULL;
    HL_CHECK(hl_mesh_create(ref_ctx(), 4, P, Nn, A, 2, I, &m) == HL_OK, "quad: %s", hl_context_last_error(ref_ctx()));
    return m;
}

/* ---------------------------------------------------------------- precompute */

/* 1 when the two files hold the same bytes; *size gets the first's. */
static int same_bytes(const char *pa, const char *pb, size_t *size)
{
    FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
    int same = fa && fb;
    *size = 0;
    while (same) {
        char x[4096], y[4096];
        size_t na = fread(x, 1, sizeof x, fa), nb = fread(y, 1, sizeof y, fb);
        same = na == nb && memcmp(x, y, na) == 0;
        *size += na;
        if (na < sizeof x) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

/* Precomputes on both backends into HL_TMP/stiff_<name>.hlt; the files
 * must be byte-identical. Returns that path (one static buffer) or NULL. */
static const char *precompute_both(const hl_mesh *m, const hl_precompute_desc *d, const char *name)
{
    static char path[2][1024];
    if (!m) return NULL;
    for (int b = 0; b < 2; b++) {
        snprintf(path[b], sizeof path[b], "%s/stiff_%s%s.hlt", hl_test_env("HL_TMP", "/tmp"), name, b ? "" : "_cl");
        hl_result r = hl_precompute(ctx_for(b), m, d, path[b], NULL);
        HL_CHECK(r == HL_OK, "%s precompute of %s: %s", backend_name[b], name, hl_context_last_error(ctx_for(b)));
        if (r != HL_OK) return NULL;
    }
    size_t n = 0;
    int same = same_bytes(path[0], path[1], &n);
    printf("%s: OpenCL and reference transport files %s (%zu bytes)\n", name, same ? "identical" : "DIFFER", n);
    HL_CHECK(same, "%s: the backends' transport files differ", name);
    remove(path[0]);
    return path[1];
}

/* ---------------------------------------------------------------- relighting */

/* One transport relit on both backends. */
typedef struct rig {
    hl_transport *t[2];
    hl_relighter *r[2];
    uint32_t V;
    float *rgb[2];
    hl_relight_stats st[2];
} rig;

static void rig_close(rig *g)
{
    for (int b = 0; b < 2; b++) {
        hl_relighter_destroy(g->r[b]);
        hl_transport_destroy(g->t[b]);
        free(g->rgb[b]);
    }
    memset(g, 0, sizeof *g);
}

static int rig_open(rig *g, const char *path)
{
    memset(g, 0, sizeof *g);
    if (!path) return 0;
    for (int b = 0; b < 2; b++) {
        hl_context *c = ctx_for(b);
        hl_result r = hl_transport_load(c, path, &g->t[b]);
        if (r == HL_OK) r = hl_relighter_create(c, g->t[b], &g->r[b]);
        HL_CHECK(r == HL_OK, "%s: %s", backend_name[b], hl_context_last_error(c));
        if (r != HL_OK) {
            rig_close(g);
            return 0;
        }
    }
    g->V = g->t[1]->info.vertex_count;
    g->rgb[0] = need(malloc((size_t)g->V * 12));
    g->rgb[1] = need(malloc((size_t)g->V * 12));
    return 1;
}

/* Relights env with `terms` terms on both backends. Every colour and
 * statistic must be finite, and the backends must agree bit for bit
 * (colours, terms kept, energy kept, bound, blocks skipped). The colours
 * kept for the accuracy checks are the sums before the clamp at zero
 * (keep_negative), which the bounds are about; the clamped colours every
 * output gets must be exactly those sums clamped. */
static int rig_run_sel(rig *g, const hl_env *env, uint32_t terms, uint32_t select, const char *what)
{
    hl_relight_desc d = {.terms = terms, .select = select, .keep_negative = 1}, dc = d;
    dc.keep_negative = 0;
    char w[320];
    float *clamped = need(malloc((size_t)g->V * 12));
    for (int b = 0; b < 2; b++) {
        hl_result r = hl_relighter_set_env(g->r[b], env);
        if (r == HL_OK) r = hl_relighter_run(g->r[b], &dc, clamped, NULL);
        if (r == HL_OK) r = hl_relighter_run(g->r[b], &d, g->rgb[b], &g->st[b]);
        HL_CHECK(r == HL_OK, "%s, %s: %s", what, backend_name[b], hl_context_last_error(ctx_for(b)));
        if (r != HL_OK) {
            free(clamped);
            return 0;
        }
        size_t off = 0;
        for (size_t i = 0; i < (size_t)g->V * 3; i++) {
            const float x = g->rgb[b][i], want = x > 0.0f ? x : 0.0f;
            off += memcmp(&clamped[i], &want, 4) != 0;
        }
        snprintf(w, sizeof w, "%s, %s: clamped colours that are not the sums clamped at zero", what, backend_name[b]);
        hl_check_error(w, (double)off, 0.0);
        const hl_relight_stats *s = &g->st[b];
        size_t bad = count_nonfinite(g->rgb[b], (size_t)g->V * 3) + !isfinite(s->energy_kept) +
                     !isfinite(s->error_bound) + !isfinite(s->blocks_skipped);
        snprintf(w, sizeof w, "%s, %s: NaN or Inf among %u colours and the statistics", what, backend_name[b], 3 * g->V);
        hl_check_error(w, (double)bad, 0.0);
    }
    const hl_relight_stats *a = &g->st[0], *b = &g->st[1];
    size_t diff = a->terms_kept != b->terms_kept || memcmp(&a->energy_kept, &b->energy_kept, 8) != 0 ||
                  memcmp(&a->error_bound, &b->error_bound, 8) != 0 || a->blocks_skipped != b->blocks_skipped;
    for (size_t i = 0; i < (size_t)g->V * 3; i++) diff += memcmp(g->rgb[0] + i, g->rgb[1] + i, 4) != 0;
    snprintf(w, sizeof w, "%s: colours and statistics where OpenCL and the reference differ in any bit", what);
    hl_check_error(w, (double)diff, 0.0);
    free(clamped);
    return 1;
}

static int rig_run(rig *g, const hl_env *env, uint32_t terms, const char *what)
{
    return rig_run_sel(g, env, terms, HL_SELECT_DEFAULT, what);
}

/* ---------------------------------------------------------------- references */

static uint32_t log2_of(uint32_t N)
{
    uint32_t l = 0;
    while ((1u << l) < N) l++;
    return l;
}

/* Slot order and solid angles depend on N only: one small-C geometry per N. */
static hl_geom *geom_cache[9];

static const hl_geom *geom_of(uint32_t N)
{
    const uint32_t l = log2_of(N);
    if (!geom_cache[l] && hl_geom_create(ref_ctx(), N, 4, &geom_cache[l]) != HL_OK) {
        fprintf(stderr, "geometry N=%u: %s\n", N, hl_context_last_error(ref_ctx()));
        exit(1);
    }
    return geom_cache[l];
}

/* The orthonormal non-standard Haar transform from its definition, in
 * double: the coefficient at Mallat position (row, col) of a map is 1 / w
 * times the signed sum of the texels of its w x w support. The scaling
 * coefficient (0, 0) adds them all; a detail at level h (the power of two
 * with h <= max(row, col) < 2h) subtracts the right half of its support
 * when col >= h, the bottom half when row >= h, and so the top-right and
 * bottom-left quarters when both (docs/CONVENTIONS.md: (a-b+c-d)/2, (a+b-c-d)/2 and
 * (a-b-c+d)/2 at (i, j+h), (i+h, j), (i+h, j+h), applied level by level). */
static void haar_double(const hl_geom *g, const float *in, double *out)
{
    const uint32_t N = g->N;
    for (int map = 0; map < 2; map++) {
        const float *x = in + (size_t)map * N * N;
        for (uint32_t row = 0; row < N; row++)
            for (uint32_t col = 0; col < N; col++) {
                uint32_t r0, c0, w, m = row > col ? row : col, h = 1;
                hl_geom_support(N, row, col, &r0, &c0, &w);
                while (2 * h <= m) h *= 2;
                const int by_col = m > 0 && col >= h, by_row = m > 0 && row >= h;
                double sum = 0.0;
                for (uint32_t r = r0; r < r0 + w; r++)
                    for (uint32_t c = c0; c < c0 + w; c++) {
                        int neg = (by_col && c >= c0 + w / 2) ^ (by_row && r >= r0 + w / 2);
                        sum += neg ? -(double)x[(size_t)r * N + c] : (double)x[(size_t)r * N + c];
                    }
                out[hl_geom_slot(g, map, row, col)] = sum / w;
            }
    }
}

/* The lighting as the plain-C stages make it (rotation 0): paraboloid
 * texels Lp, their float Haar Lw, and the double Haar Ld; 3 planes each. */
typedef struct lighting {
    uint32_t N, nc;
    float *Lp, *Lw;
    double *Ld;
    double norm[3]; /* |Lp|_2 per channel */
} lighting;

static void lighting_make(lighting *L, const hl_light_geom *lg, const hl_env *env)
{
    const hl_geom *g = geom_of(lg->N);
    const size_t nc = g->ncoef;
    L->N = g->N;
    L->nc = g->ncoef;
    L->Lp = need(malloc(nc * 12));
    L->Lw = need(malloc(nc * 12));
    L->Ld = need(malloc(nc * 3 * sizeof(double)));
    float *cells = NULL, *tmp = need(malloc(nc * 4));
    if (hl_env_to_cells(ref_ctx(), env, lg->wc, lg->hc, &cells) != HL_OK) {
        fprintf(stderr, "cells: %s\n", hl_context_last_error(ref_ctx()));
        exit(1);
    }
    hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, 0, 0.0f, g->ncoef, L->Lp);
    for (int c = 0; c < 3; c++) {
        memcpy(tmp, L->Lp + c * nc, nc * 4);
        hl_ref_haar(g, tmp, L->Lw + c * nc);
        haar_double(g, L->Lp + c * nc, L->Ld + c * nc);
        double s = 0.0;
        for (size_t j = 0; j < nc; j++) s += (double)L->Lp[c * nc + j] * L->Lp[c * nc + j];
        L->norm[c] = sqrt(s);
    }
    hl_free_big(cells);
    free(tmp);
}

static void lighting_free(lighting *L)
{
    free(L->Lp);
    free(L->Lw);
    free(L->Ld);
}

/* The lighting's energy over the sphere, sum_j L_j Omega_j (channel c). */
static double lighting_energy(const lighting *L, int c)
{
    const hl_geom *g = geom_of(L->N);
    double e = 0.0;
    for (uint32_t j = 0; j < L->nc; j++) e += (double)L->Lp[(size_t)c * L->nc + j] * g->omega[j];
    return e;
}

/* Worst error of one stored value against the unquantised one. linear8:
 * half a step (b - a) / 255, plus the float rounding of the decode (four
 * operations on values up to max(|a|, |b|)) and of the encode's x + 0.5.
 * log8: the key is on a grid of step keys from bits(a), rounded to the
 * nearest (step / 2 + 1 keys) or capped at the last point (at most 126
 * keys below bits(b)); a key is at most 2^-23 of the value. sqrt8: s =
 * sqrt(m / b) is rounded to a 127th, so |m - b s'^2| <= b (2 s + 1/254)
 * / 254, plus the float rounding of the thresholds and the decode (a few
 * units in the last place of b). A value not stored (0) is off by itself. */
static double quant_error(uint32_t scheme, hl_row_quant q, float raw, float stored)
{
    if (stored == 0.0f) return fabs((double)raw);
    if (scheme == HL_QUANT_LOG8) {
        double keys = hl_log8_step(q.a, q.b) / 2.0 + 127.0;
        return fmax(fabs((double)raw), fabs((double)stored)) * keys * ldexp(1.0, -23);
    }
    if (scheme == HL_QUANT_SQRT8) {
        double sq = sqrt(fabs((double)raw) / q.b);
        return q.b * (2.0 * sq + 1.0 / 254.0) / 254.0 + 8.0 * U_F32 * q.b;
    }
    return ((double)q.b - q.a) / 510.0 * (1.0 + 1e-4) + 4.0 * U_F32 * fmax(fabs((double)q.a), fabs((double)q.b));
}

/* Per vertex and channel: the double references and the sizes the bounds
 * need (albedo not included). */
typedef struct sample {
    double ref;     /* sum T_i Ld_i */
    double ref_f;   /* sum T_i Lw_i: the library's own float lighting */
    double ref_raw; /* sum raw_i Ld_i: the unquantised transport */
    double abs_sum; /* sum |T_i Lw_i| */
    double quant;   /* sum |Ld_i| q_i */
    double t1, t2;  /* |T|_1, |T|_2 */
    uint32_t n;     /* stored terms */
} sample;

static sample *samples_make(const hl_transport *t, const lighting *L, const float *raw)
{
    const uint32_t V = t->info.vertex_count, nc = L->nc;
    sample *S = calloc((size_t)V * 3, sizeof *S);
    float *row = need(malloc((size_t)nc * 4)), *code = need(malloc((size_t)nc * 4));
    if (!S) exit(1);
    for (uint32_t v = 0; v < V; v++) {
        hl_transport_query_terms(t, v, row);
        hl_transport_query_row(t, v, code);
        double t1 = 0.0, t2 = 0.0;
        uint32_t n = 0;
        for (uint32_t i = 0; i < nc; i++)
            if (row[i] != 0.0f) {
                t1 += fabs((double)row[i]);
                t2 += (double)row[i] * row[i];
                n++;
            }
        for (int c = 0; c < 3; c++) {
            sample *s = S + 3 * (size_t)v + c;
            const float *lw = L->Lw + (size_t)c * nc;
            const double *ld = L->Ld + (size_t)c * nc;
            s->t1 = t1;
            s->t2 = sqrt(t2);
            s->n = n;
            for (uint32_t i = 0; i < nc; i++) {
                if (row[i] != 0.0f) {
                    s->ref += (double)row[i] * ld[i];
                    s->ref_f += (double)row[i] * lw[i];
                    s->abs_sum += fabs((double)row[i] * lw[i]);
                }
                if (raw) {
                    float x = raw[(size_t)v * nc + i];
                    s->ref_raw += (double)x * ld[i];
                    s->quant += fabs(ld[i]) * (quant_error(t->info.quant, t->row_quant[v], x, code[i]) +
                                                fabs((double)code[i] - row[i]));
                }
            }
        }
    }
    free(row);
    free(code);
    return S;
}

static double gamma_n(uint32_t n) { return n * U_F32 / (1.0 - n * U_F32); }

/* Bound (b): accumulation and albedo product, subnormal floor included. */
static double bound_accumulation(const sample *s, double albedo, float B)
{
    return albedo * (gamma_n(s->n) * s->abs_sum + 2.0 * s->n * SUB_HALF) + U_F32 * fabs((double)B) + SUB_HALF;
}

/* Bound (a): the float Haar transform of the lighting. */
static double bound_haar(const sample *s, double albedo, double lnorm, uint32_t N)
{
    const double levels = log2_of(N);
    return albedo * (s->t2 * 6.0 * U_F32 * levels * lnorm * (1.0 + 1e-4) + s->t1 * 6.0 * levels * SUB_HALF);
}

/* Checks colours against B_ref (and against the unquantised transport
 * when samples carry it). Prints the worst error with the bound at that
 * point; the check is the worst ratio of error to bound. */
static void check_colours(const char *what, const hl_transport *t, const lighting *L, const sample *S,
                          const float *rgb, int with_raw)
{
    const uint32_t V = t->info.vertex_count;
    double worst[3] = {0, 0, 0}, err_at[3] = {0, 0, 0}, bound_at[3] = {0, 0, 0}, worst_rel = 0.0, rel_ref = 0.0;
    uint32_t rel_v = 0;
    for (uint32_t v = 0; v < V; v++)
        for (int c = 0; c < 3; c++) {
            const sample *s = S + 3 * (size_t)v + c;
            const double a = t->mesh->albedo[3 * (size_t)v + c];
            const float B = rgb[3 * (size_t)v + c];
            const double acc = bound_accumulation(s, a, B), haar = bound_haar(s, a, L->norm[c], L->N);
            const double e[3] = {fabs(B - a * s->ref_f), fabs(B - a * s->ref), fabs(B - a * s->ref_raw)};
            const double bd[3] = {acc, acc + haar, acc + haar + a * s->quant};
            for (int k = 0; k < (with_raw ? 3 : 2); k++) {
                double ratio = e[k] / bd[k];
                if (!(ratio <= worst[k])) {
                    worst[k] = ratio;
                    err_at[k] = e[k];
                    bound_at[k] = bd[k];
                }
            }
            if (fabs(s->ref) > 0 && e[1] / fabs(a * s->ref) > worst_rel) {
                worst_rel = e[1] / fabs(a * s->ref);
                rel_ref = a * s->ref;
                rel_v = v;
            }
        }
    static const char *const kind[3] = {
        "vs its own float lighting in double (accumulation)",
        "vs B_ref (lighting Haar + accumulation)",
        "vs the unquantised transport (+ 8-bit quantisation)"};
    for (int k = 0; k < (with_raw ? 3 : 2); k++) {
        char w[400];
        printf("%s %s: worst error %.4g where the bound is %.4g\n", what, kind[k], err_at[k], bound_at[k]);
        snprintf(w, sizeof w, "%s %s, error / bound", what, kind[k]);
        hl_check_error(w, worst[k], 1.0);
    }
    printf("%s: largest relative error %.3g (vertex %u, B_ref %.4g)\n", what, worst_rel, rel_v, rel_ref);
}

/* Unquantised, untruncated rows of every vertex (V x 2N^2), recomputed from
 * the rays by the plain-C stages exactly as the precompute computes them. */
static float *raw_rows(const hl_transport *t)
{
    const hl_transport_info *in = &t->info;
    hl_geom *g = NULL;
    hl_rt *rt = NULL;
    if (hl_geom_create(ref_ctx(), in->N, in->C, &g) != HL_OK || hl_rt_create(ref_ctx(), t->mesh, &rt) != HL_OK) {
        fprintf(stderr, "raw rows: %s\n", hl_context_last_error(ref_ctx()));
        exit(1);
    }
    const uint32_t V = in->vertex_count, nc = g->ncoef;
    uint8_t *vis = need(malloc((size_t)V * g->ncube));
    float *out = need(malloc((size_t)V * nc * 4)), *T = need(malloc((size_t)nc * 4));
    const float off = in->ray_offset * hl_mesh_query_diagonal(t->mesh);
    const float scale = (float)(1.0 / (HL_PI * in->supersample * in->supersample));
    HL_CHECK(hl_rt_visibility(rt, g, t->mesh, 0, V, in->supersample, off, vis, NULL) == HL_OK, "rays");
    for (uint32_t v = 0; v < V; v++) {
        hl_ref_cube2para(g, vis + (size_t)v * g->ncube, scale, t->mesh->normals + 3 * (size_t)v, T);
        hl_ref_haar(g, T, out + (size_t)v * nc);
    }
    free(vis);
    free(T);
    hl_rt_destroy(rt);
    hl_geom_destroy(g);
    return out;
}

/* The references for one lighting of a rig's transport. */
typedef struct reference {
    lighting L;
    sample *S;
} reference;

static void reference_make(reference *R, const rig *g, const hl_env *env, const float *raw)
{
    lighting_make(&R->L, hl_relighter_tables(g->r[1]), env);
    R->S = samples_make(g->t[1], &R->L, raw);
}

static void reference_free(reference *R)
{
    free(R->S);
    lighting_free(&R->L);
}

/* check_colours for both backends. */
static void check_both(const char *what, const rig *g, const reference *R, int with_raw)
{
    for (int b = 0; b < 2; b++) {
        char w[256];
        snprintf(w, sizeof w, "%s, %s", what, backend_name[b]);
        check_colours(w, g->t[b], &R->L, R->S, g->rgb[b], with_raw);
    }
}

/* The small scene precomputed on both backends (N, C, truncation rule,
 * the rest default) and opened on both; NULL when that fails (and then
 * nothing is held). */
static hl_mesh *open_scene(rig *g, uint32_t N, uint32_t C, uint32_t rule, const char *name)
{
    hl_precompute_desc d = {.N = N, .C = C, .rule = rule};
    hl_mesh *m = scene_mesh(1.0, no_shift);
    if (rig_open(g, precompute_both(m, &d, name))) return m;
    hl_mesh_destroy(m);
    return NULL;
}

static void close_scene(rig *g, hl_mesh *m)
{
    rig_close(g);
    hl_mesh_destroy(m);
}

/* ---------------------------------------------------------------- environments */

static hl_env *env_of(uint32_t W, const float *px)
{
    hl_env *e = NULL;
    hl_env_stats st;
    hl_result r = hl_env_create(ref_ctx(), W, W / 2, px, &e, &st);
    HL_CHECK(r == HL_OK, "environment %ux%u: %s", W, W / 2, hl_context_last_error(ref_ctx()));
    return e;
}

static float *pixels_const(uint32_t W, float value)
{
    size_t n = (size_t)W * (W / 2) * 3;
    float *px = need(malloc(n * 4));
    for (size_t i = 0; i < n; i++) px[i] = value;
    return px;
}

/* A light smaller than a texel keeps its energy: each cell's parts are
 * exact radially and within the 16-ray quadrature in longitude, 0.2% at
 * worst (lighting.c); 0.5% leaves room and no room for the 6.5% that
 * point-sampled parts lost near the horizon. */
#define ENERGY_TOL 0.005

static double rng_unit(void) { return (double)(hl_rng_next() >> 11) * (1.0 / 9007199254740992.0); }

/* Solid angle of pixel row y of an equirectangular map W x W/2. */
static double pixel_omega(uint32_t W, uint32_t y)
{
    const uint32_t H = W / 2;
    return 2.0 * HL_PI / W * (cos(HL_PI * y / H) - cos(HL_PI * (y + 1) / H));
}

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
                   1 / N^2) plus linear 8-bit steps (hl.light.furnace) */
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

/* ================================================================ resolution */

/* White furnace through the whole pipeline for (N, C) pairs, every
 * coefficient kept, log8: the open quad (albedo 1) under a constant 1
 * gives B = 1. On the unquantised transport the tolerance is the table's
 * first moments, 1 / N^2 (hl.analytic.furnace: normal +Y and C even, so no
 * part straddles the horizon); the stored rows add their 8-bit
 * quantisation, sum |L_i| q_i, and the float bounds. */
static void case_resolution(void)
{
    static const uint32_t NC[][2] = {{8, 8}, {16, 16}, {32, 32}, {64, 64}, {128, 128}, {256, 256}, {256, 8}, {8, 256}};
    hl_mesh *m = quad_mesh();
    float *px = pixels_const(64, 1.0f);
    hl_env *env = env_of(64, px);
    for (size_t k = 0; k < sizeof NC / sizeof NC[0]; k++) {
        const uint32_t N = NC[k][0], C = NC[k][1];
        case_begin("resolution: N=%u C=%u", N, C);
        double t0 = hl_now();
        hl_precompute_desc d = {.N = N, .C = C, .rule = HL_TRUNC_ALL};
        char name[64], what[96];
        snprintf(name, sizeof name, "res_%u_%u", N, C);
        snprintf(what, sizeof what, "N=%u C=%u", N, C);
        rig g;
        if (env && rig_open(&g, precompute_both(m, &d, name))) {
            if (rig_run(&g, env, HL_TERMS_ALL, what)) {
                float *raw = raw_rows(g.t[1]);
                reference R;
                reference_make(&R, &g, env, raw);
                check_both(what, &g, &R, 1);
                double worst = 0.0, tol_at = 0.0, err_at = 0.0, quant_at = 0.0, raw_worst = 0.0;
                for (uint32_t v = 0; v < g.V; v++)
                    for (int c = 0; c < 3; c++) {
                        const sample *s = R.S + 3 * (size_t)v + c;
                        float B = g.rgb[1][3 * (size_t)v + c];
                        double tol = 1.0 / ((double)N * N) + s->quant + bound_accumulation(s, 1.0, B) +
                                     bound_haar(s, 1.0, R.L.norm[c], N);
                        double e = fabs(B - 1.0);
                        raw_worst = fmax(raw_worst, fabs(s->ref_raw - 1.0));
                        if (e / tol > worst) worst = e / tol, tol_at = tol, err_at = e, quant_at = s->quant;
                    }
                char w[160];
                snprintf(w, sizeof w, "%s: furnace on the unquantised transport, |B - 1|", what);
                hl_check_error(w, raw_worst, 1.0 / ((double)N * N));
                printf("%s: furnace worst |B - 1| %.4g, tolerance 1/N^2 %.4g + quantisation %.4g + rounding = %.4g\n",
                       what, err_at, 1.0 / ((double)N * N), quant_at, tol_at);
                snprintf(w, sizeof w, "%s: furnace |B - 1| / tolerance", what);
                hl_check_error(w, worst, 1.0);
                const hl_row_quant q0 = g.t[1]->row_quant[0];
                printf("%s: vertex 0 keeps %llu coefficients, |v| from %.3g to %.3g (%.1f octaves over 127 log8 steps)\n",
                       what, (unsigned long long)(g.t[1]->row_offset[1] - g.t[1]->row_offset[0]), (double)q0.a,
                       (double)q0.b, log2((double)q0.b / q0.a));
                free(raw);
                reference_free(&R);
            }
            rig_close(&g);
        }
        printf("%s: %.2f s\n", what, hl_now() - t0);
        case_end();
    }
    hl_env_destroy(env);
    free(px);
    hl_mesh_destroy(m);
}

/* K = 0, 1 and all. The API's top-K rule with K = 0 keeps nothing (as
 * haarlight.h says: "required, >= 1 unless keep none"): an empty but valid
 * file whose colours are all 0; the CLI refuses --terms 0. K = 1 leaves
 * one value per row, min == max, which both schemes store exactly. K =
 * all keeps exactly the non-zero coefficients. */
static void case_truncation(void)
{
    hl_mesh *m = scene_mesh(1.0, no_shift);
    const uint32_t W = 256;
    float *px = pixels_const(W, 1.0f);
    for (int c = 0; c < 3; c++) px[3 * (30 * (size_t)W + 77) + c] = 1e4f;
    hl_env *env = env_of(W, px);
    float *raw = NULL;

    case_begin("truncation: K=0 through the API");
    {
        hl_precompute_desc d = {.N = 16, .C = 16, .rule = HL_TRUNC_TOPK, .K = 0};
        rig g;
        if (rig_open(&g, precompute_both(m, &d, "k0"))) {
            printf("K=0: %llu coefficients kept of %u vertices\n", (unsigned long long)g.t[1]->info.coefficients_kept, g.V);
            HL_CHECK(g.t[1]->info.coefficients_kept == 0, "K=0 must keep nothing");
            if (env && rig_run(&g, env, HL_TERMS_ALL, "K=0")) {
                size_t nz = 0;
                for (int b = 0; b < 2; b++)
                    for (size_t i = 0; i < (size_t)g.V * 3; i++) nz += g.rgb[b][i] != 0.0f;
                hl_check_error("K=0: non-zero colours", (double)nz, 0.0);
                printf("K=0: energy kept %g, bound %g\n", g.st[1].energy_kept, g.st[1].error_bound);
            }
            rig_close(&g);
        }
    }
    case_end();

    case_begin("truncation: K=0 through the CLI");
    {
        const char *obj = hl_test_tmp_path("stiff_k0.obj"), *out = hl_test_tmp_path("stiff_k0_cli.hlt");
        const char *log = hl_test_tmp_path("stiff_k0.log");
        FILE *f = fopen(obj, "w");
        if (f) {
            fputs("v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\nf 1 4 3\n", f);
            fclose(f);
        }
        char cmd[4096];
        remove(out);
        snprintf(cmd, sizeof cmd, "'%s' precompute '%s' --terms 0 -o '%s' > '%s' 2>&1", hl_test_env("HL_BIN", "haarlight"),
                 obj, out, log);
        int rc = system(cmd);
        char msg[1024] = "";
        f = fopen(log, "r");
        if (f) {
            msg[fread(msg, 1, sizeof msg - 1, f)] = '\0';
            fclose(f);
        }
        struct stat sb;
        msg[strcspn(msg, "\n")] = '\0';
        printf("--terms 0: exit %d, message: %s\n", rc, msg);
        HL_CHECK(rc != 0 && strstr(msg, "--terms") && stat(out, &sb) != 0,
                 "the CLI must refuse --terms 0, name the option and write nothing");
        remove(obj);
        remove(log);
    }
    case_end();

    for (int q = 0; q < 2; q++) {
        const uint32_t scheme = q ? HL_QUANT_LINEAR8 : HL_QUANT_LOG8;
        const char *qn = q ? "linear8" : "log8";
        case_begin("truncation: K=1, %s", qn);
        hl_precompute_desc d = {.N = 16, .C = 16, .rule = HL_TRUNC_TOPK, .K = 1, .quant = scheme};
        char name[32];
        snprintf(name, sizeof name, "k1_%s", qn);
        rig g;
        if (rig_open(&g, precompute_both(m, &d, name))) {
            const uint32_t nc = 2 * 16 * 16;
            if (!raw) raw = raw_rows(g.t[1]);
            float *row = need(malloc(nc * 4));
            size_t bad = 0;
            for (uint32_t v = 0; v < g.V; v++) {
                /* the largest |raw| (first in slot order on ties) */
                uint32_t best = 0;
                for (uint32_t i = 1; i < nc; i++)
                    if (hl_key(raw[(size_t)v * nc + i]) > hl_key(raw[(size_t)v * nc + best])) best = i;
                hl_transport_query_row(g.t[1], v, row);
                hl_row_quant rq = g.t[1]->row_quant[v];
                float want = raw[(size_t)v * nc + best];
                for (uint32_t i = 0; i < nc; i++) bad += memcmp(row + i, i == best ? &want : &(float){0.0f}, 4) != 0;
                bad += scheme == HL_QUANT_LOG8 ? (rq.a != fabsf(want) || rq.b != fabsf(want)) : (rq.a != want || rq.b != want);
            }
            char w[128];
            snprintf(w, sizeof w, "K=1 %s: stored values (and a, b) not exactly the largest coefficient", qn);
            hl_check_error(w, (double)bad, 0.0);
            free(row);
            if (env) rig_run(&g, env, HL_TERMS_ALL, name);
            rig_close(&g);
        }
        case_end();

        case_begin("truncation: K=all, %s", qn);
        hl_precompute_desc da = {.N = 16, .C = 16, .rule = HL_TRUNC_ALL, .quant = scheme};
        snprintf(name, sizeof name, "kall_%s", qn);
        if (rig_open(&g, precompute_both(m, &da, name))) {
            const uint32_t nc = 2 * 16 * 16;
            uint64_t nonzero = 0;
            size_t wrong = 0;
            for (uint32_t v = 0; v < g.V; v++) {
                uint64_t nz = 0;
                for (uint32_t i = 0; i < nc; i++) nz += raw[(size_t)v * nc + i] != 0.0f;
                nonzero += nz;
                wrong += nz != g.t[1]->row_offset[v + 1] - g.t[1]->row_offset[v];
            }
            printf("K=all %s: %llu kept, %llu non-zero coefficients\n", qn,
                   (unsigned long long)g.t[1]->info.coefficients_kept, (unsigned long long)nonzero);
            hl_check_error("K=all: rows whose kept count is not their non-zero count", (double)wrong, 0.0);
            if (env && rig_run(&g, env, HL_TERMS_ALL, name)) {
                reference R;
                reference_make(&R, &g, env, raw);
                check_both(name, &g, &R, 1);
                reference_free(&R);
            }
            rig_close(&g);
        }
        case_end();
    }
    free(raw);
    hl_env_destroy(env);
    free(px);
    hl_mesh_destroy(m);
}

/* ================================================================ degenerate transport */

/* A triangle inside a closed box sees nothing; a triangle facing straight
 * down just above a wide ground sees only the ground. Their rows are
 * empty (a = b = 0 in both schemes) and their colours exactly 0. */
static void case_zero_transport(void)
{
    builder b = builder_new(64, 64);
    add_grid(&b, 4, 8.0, 0.0);
    /* closed box, 8 shared corners, wound outward, y in [0.5, 1.5] */
    const uint32_t c0 = b.nv;
    for (int i = 0; i < 8; i++) add_vertex(&b, i & 1 ? 0.5 : -0.5, i & 2 ? 1.5 : 0.5, i & 4 ? 0.5 : -0.5, 0, 0, 0);
    static const uint32_t faces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    for (int f = 0; f < 6; f++) {
        add_tri(&b, c0 + faces[f][0], c0 + faces[f][1], c0 + faces[f][2]);
        add_tri(&b, c0 + faces[f][0], c0 + faces[f][2], c0 + faces[f][3]);
    }
    /* inside: normal +Y; outside, 0.05 above the ground: normal -Y */
    const uint32_t in0 = b.nv;
    add_vertex(&b, -0.1, 1.0, -0.1, 0, 0, 0);
    add_vertex(&b, -0.1, 1.0, 0.1, 0, 0, 0);
    add_vertex(&b, 0.1, 1.0, -0.1, 0, 0, 0);
    add_tri(&b, in0, in0 + 1, in0 + 2);
    add_vertex(&b, 4.0, 0.05, 4.0, 0, 0, 0);
    add_vertex(&b, 4.2, 0.05, 4.0, 0, 0, 0);
    add_vertex(&b, 4.0, 0.05, 4.2, 0, 0, 0);
    add_tri(&b, in0 + 3, in0 + 4, in0 + 5);
    hl_mesh *m = build_mesh(&b, 1.0, no_shift, 0);
    builder_free(&b);
    if (!m) return;
    /* find them again: normals come from the winding */
    uint32_t dark[6], nd = 0;
    for (uint32_t v = 0; v < m->vertex_count && nd < 6; v++) {
        const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v;
        if ((p[1] == 1.0f && fabsf(p[0]) < 0.2f && n[1] == 1.0f) || (p[1] == 0.05f && n[1] == -1.0f)) dark[nd++] = v;
    }
    HL_CHECK(nd == 6, "found %u of the 6 dark vertices (normals +Y inside, -Y above the ground)", nd);
    const uint32_t W = 256;
    float *px = pixels_const(W, 1.0f);
    for (int c = 0; c < 3; c++) px[3 * (30 * (size_t)W + 77) + c] = 1e5f;
    hl_env *env = env_of(W, px);
    for (int q = 0; q < 2; q++) {
        const uint32_t scheme = q ? HL_QUANT_LINEAR8 : HL_QUANT_LOG8;
        for (int rule = 0; rule < 2; rule++) {
            const char *qn = q ? "linear8" : "log8", *rn = rule ? "all" : "energy";
            case_begin("zero_transport: %s, rule %s", qn, rn);
            hl_precompute_desc d = {.N = 16, .C = 16, .rule = rule ? HL_TRUNC_ALL : HL_TRUNC_ENERGY, .quant = scheme};
            char name[48];
            snprintf(name, sizeof name, "zero_%s_%s", qn, rn);
            rig g;
            if (rig_open(&g, precompute_both(m, &d, name))) {
                float *raw = raw_rows(g.t[1]);
                size_t nonzero_raw = 0, stored = 0, ab = 0, lit = 0;
                const uint32_t nc = 2 * 16 * 16;
                for (uint32_t k = 0; k < nd; k++) {
                    uint32_t v = dark[k];
                    for (uint32_t i = 0; i < nc; i++) nonzero_raw += raw[(size_t)v * nc + i] != 0.0f;
                    stored += g.t[1]->row_offset[v + 1] - g.t[1]->row_offset[v];
                    ab += g.t[1]->row_quant[v].a != 0.0f || g.t[1]->row_quant[v].b != 0.0f;
                }
                hl_check_error("dark vertices: non-zero unquantised coefficients (every ray blocked)", (double)nonzero_raw, 0.0);
                hl_check_error("dark vertices: stored entries", (double)stored, 0.0);
                hl_check_error("dark vertices: a, b not both 0 (min == max == 0)", (double)ab, 0.0);
                if (env && rig_run(&g, env, HL_TERMS_ALL, name)) {
                    for (int bk = 0; bk < 2; bk++)
                        for (uint32_t k = 0; k < nd; k++)
                            for (int c = 0; c < 3; c++) lit += g.rgb[bk][3 * (size_t)dark[k] + c] != 0.0f;
                    hl_check_error("dark vertices: non-zero colours (both backends)", (double)lit, 0.0);
                }
                free(raw);
                rig_close(&g);
            }
            case_end();
        }
    }
    hl_env_destroy(env);
    free(px);
    hl_mesh_destroy(m);
}

/* ================================================================ mesh scale and shape */

/* Where rays.c starts the rays of a vertex, along one axis: p + n offset,
 * the nearest float on the far side of the surface. Returns the distance
 * from p (exact: o and p are neighbouring floats). */
static double origin_shift(float p, float n, float offset)
{
    double want = (double)p + (double)n * offset;
    float o = (float)want;
    if (n > 0.0f && (double)o < want) o = nextafterf(o, INFINITY);
    if (n < 0.0f && (double)o > want) o = nextafterf(o, -INFINITY);
    return fabs((double)o - p);
}

/* Visibility rows of mesh m, one ray per cube texel, each vertex with its
 * own offset along its normal (offsets NULL: all `offset`). */
static uint8_t *visibility(const hl_mesh *m, const hl_geom *g, float offset, const float *offsets)
{
    hl_rt *rt = NULL;
    uint8_t *vis = need(malloc((size_t)m->vertex_count * g->ncube));
    hl_result r = hl_rt_create(ref_ctx(), m, &rt);
    for (uint32_t v = 0; r == HL_OK && v < m->vertex_count; v += offsets ? 1 : m->vertex_count)
        r = hl_rt_visibility(rt, g, m, v, offsets ? 1 : m->vertex_count, 1, offsets ? offsets[v] : offset,
                             vis + (size_t)v * g->ncube, NULL);
    HL_CHECK(r == HL_OK, "rays: %s", hl_context_last_error(ref_ctx()));
    hl_rt_destroy(rt);
    return vis;
}

/* The small scene at 1e-6 and 1e6, and 1e6 and 2e5 away from the origin.
 * Ray offsets are 1e-3 of the diagonal, under the spacing of the
 * coordinates out there (1/16 at 1e6, 1/64 at 2e5), where rays.c keeps
 * the origin one float off the surface rather than on it.
 *   Rays: the same as the unit scene's from the same origins (the unit
 *   scene traced with each vertex's own offset, the distance its origin
 *   has from the surface in the far scene; the normals are axis-aligned,
 *   so that is one number). The unit coordinates are multiples of 1/4, so
 *   translated copies are exact and the rays must agree exactly; scaled
 *   copies round, and a ray through an edge may tip: at most 1e-4 of them.
 *   Colours: |B - B_unit| at most what the differing rays make of the
 *   unquantised transport (|sum_i (raw_i - raw_unit_i) L_i|), plus the
 *   8-bit quantisation of both rows and the float bounds. */
static void case_scale(void)
{
    static const struct { const char *name; double scale, shift[3]; } sc[] = {
        {"unit", 1.0, {0, 0, 0}},
        {"scale 1e-6", 1e-6, {0, 0, 0}},
        {"scale 1e6", 1e6, {0, 0, 0}},
        {"shifted +1e6 x", 1.0, {1e6, 0, 0}},
        {"shifted +1e6 x, y, z", 1.0, {1e6, 1e6, 1e6}},
        {"shifted +2e5 x, y, z", 1.0, {2e5, 2e5, 2e5}},
    };
    const int ns = sizeof sc / sizeof sc[0];
    const uint32_t N = 16, C = 32;
    hl_geom *g = NULL;
    HL_CHECK(hl_geom_create(ref_ctx(), N, C, &g) == HL_OK, "geometry");
    hl_sky_desc sky = {.width = 256};
    hl_env *env = NULL;
    HL_CHECK(hl_env_create_sky(ref_ctx(), &sky, &env) == HL_OK, "sky");
    hl_mesh *m0 = NULL;
    float *rgb0 = NULL;
    sample *S0 = NULL;
    for (int s = 0; s < ns && g && env; s++) {
        case_begin("scale: %s", sc[s].name);
        hl_mesh *m = scene_mesh(sc[s].scale, sc[s].shift);
        hl_precompute_desc d = {.N = N, .C = C, .rule = HL_TRUNC_ALL};
        char name[48];
        snprintf(name, sizeof name, "scale_%d", s);
        rig rg;
        if (m && rig_open(&rg, precompute_both(m, &d, name))) {
            if (rig_run(&rg, env, HL_TERMS_ALL, sc[s].name)) {
                const uint32_t V = rg.V;
                float *raw = raw_rows(rg.t[1]);
                lighting L;
                lighting_make(&L, hl_relighter_tables(rg.r[1]), env);
                sample *S = samples_make(rg.t[1], &L, raw);
                if (s == 0) {
                    m0 = m, m = NULL;
                    rgb0 = need(malloc((size_t)V * 12));
                    memcpy(rgb0, rg.rgb[1], (size_t)V * 12);
                    S0 = S, S = NULL;
                } else if (m0 && V == m0->vertex_count) {
                    /* the rays, against the unit scene's from the same origins */
                    const float off = 1e-3f * hl_mesh_query_diagonal(m);
                    float *offs = need(malloc((size_t)V * 4));
                    for (uint32_t v = 0; v < V; v++) {
                        int k = 0;
                        while (k < 2 && m->normals[3 * (size_t)v + k] == 0.0f) k++;
                        offs[v] = (float)(origin_shift(m->positions[3 * (size_t)v + k], m->normals[3 * (size_t)v + k], off) /
                                          sc[s].scale);
                    }
                    uint8_t *vis = visibility(m, g, off, NULL), *vis0 = visibility(m0, g, 0.0f, offs);
                    size_t dt = 0, open = 0;
                    for (size_t i = 0; i < (size_t)V * g->ncube; i++) {
                        dt += vis[i] != vis0[i];
                        open += vis0[i] != 0;
                    }
                    char w[200];
                    int exact = sc[s].scale == 1.0;
                    snprintf(w, sizeof w, "%s: rays that differ from the unit scene's from the same origins (of %zu open)",
                             sc[s].name, open);
                    hl_check_error(w, (double)dt, exact ? 0.0 : 1e-4 * (double)V * g->ncube);
                    /* the colours */
                    double worst = 0.0, e_at = 0.0, b_at = 0.0, rel = 0.0;
                    for (uint32_t v = 0; v < V; v++)
                        for (int c = 0; c < 3; c++) {
                            const size_t i = 3 * (size_t)v + c;
                            const double a = m->albedo[i];
                            const float B = rg.rgb[1][i], B0 = rgb0[i];
                            double bound = a * fabs(S[i].ref_raw - S0[i].ref_raw) + a * (S[i].quant + S0[i].quant) +
                                           bound_accumulation(S + i, a, B) + bound_haar(S + i, a, L.norm[c], N) +
                                           bound_accumulation(S0 + i, a, B0) + bound_haar(S0 + i, a, L.norm[c], N);
                            double e = fabs((double)B - B0);
                            rel = fmax(rel, e / fabs((double)B0));
                            if (!(e / bound <= worst)) worst = e / bound, e_at = e, b_at = bound;
                        }
                    printf("%s: %zu rays differ from the unit scene's; largest relative colour difference %.3g; worst "
                           "|B - B_unit| %.4g where the bound is %.4g\n",
                           sc[s].name, dt, rel, e_at, b_at);
                    snprintf(w, sizeof w, "%s: |B - B_unit| / (differing rays + quantisation of both + rounding)", sc[s].name);
                    hl_check_error(w, worst, 1.0);
                    free(vis);
                    free(vis0);
                    free(offs);
                }
                free(S);
                free(raw);
                lighting_free(&L);
            }
            rig_close(&rg);
        }
        hl_mesh_destroy(m);
        case_end();
    }
    free(S0);
    free(rgb0);
    hl_mesh_destroy(m0);
    hl_env_destroy(env);
    hl_geom_destroy(g);
}

/* Zero-area triangles (collinear and repeated corners), duplicate
 * vertices and zero (and NaN) normals, built in memory and read from an
 * OBJ: they load, every normal is a unit vector, and the precompute and
 * the relight give finite colours on both backends. */
static void case_shape(void)
{
    /* a floor quad, a tent over it, and the trouble */
    static const float P[] = {
        -1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1,            /* 0-3 floor */
        -0.5f, 0.2f, 0, 0.5f, 0.2f, 0, 0, 0.6f, 0,         /* 4-6 tent */
        -0.5f, 0.2f, 0, 0.5f, 0.2f, 0,                     /* 7-8 duplicates of 4, 5 */
        0, 0.2f, 0.5f, 0, 0.4f, 0.5f, 0, 0.6f, 0.5f,       /* 9-11 collinear */
        0.5f, 0.2f, 0.5f,                                  /* 12 */
    };
    static const float Nn[] = {
        0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0,                /* zero normals at 1 and 3 */
        0, 0, 1, 0, 0, 1, 0, 0, 0,                         /* zero at 6 */
        0, 0, 1, 0, 0, 1,
        0, 0, 0, NAN, NAN, NAN, 1, 0, 0,                   /* zero, NaN */
        0, 0, 0,
    };
    static const uint32_t I[] = {
        0, 2, 1, 0, 3, 2,          /* floor */
        4, 5, 6, 8, 7, 6,          /* tent, front and back through the duplicates */
        9, 10, 11,                 /* zero area: collinear */
        4, 4, 5,                   /* repeated corner */
        12, 12, 12,                /* a point */
        7, 5, 6,                   /* duplicate-only triangle */
        9, 12, 10,
    };
    const uint32_t nv = sizeof P / 12, nt = sizeof I / 12;
    const uint32_t W = 128;
    float *px = pixels_const(W, 1.0f);
    for (int c = 0; c < 3; c++) px[3 * (20 * (size_t)W + 40) + c] = 1e5f;
    hl_env *env = env_of(W, px);
    for (int src = 0; src < 2; src++) {
        case_begin("shape: %s", src ? "OBJ file" : "hl_mesh_create");
        hl_mesh *m = NULL;
        hl_mesh_stats st = {0};
        hl_result r;
        if (src == 0) {
            r = hl_mesh_create(ref_ctx(), nv, P, Nn, NULL, nt, I, &m);
        } else {
            const char *path = hl_test_tmp_path("stiff_shape.obj");
            FILE *f = fopen(path, "w");
            for (uint32_t v = 0; f && v < nv; v++) fprintf(f, "v %.9g %.9g %.9g\n", P[3 * v], P[3 * v + 1], P[3 * v + 2]);
            for (uint32_t v = 0; f && v < nv; v++) fprintf(f, "vn %.9g %.9g %.9g\n", Nn[3 * v], Nn[3 * v + 1], Nn[3 * v + 2]);
            for (uint32_t t = 0; f && t < nt; t++)
                fprintf(f, "f %u//%u %u//%u %u//%u\n", I[3 * t] + 1, I[3 * t] + 1, I[3 * t + 1] + 1, I[3 * t + 1] + 1,
                        I[3 * t + 2] + 1, I[3 * t + 2] + 1);
            if (f) fclose(f);
            r = hl_mesh_load(ref_ctx(), path, NULL, &m, &st);
            printf("OBJ: %u file vertices, %u triangles; merged %u, degenerate %u, unreferenced %u, normals %d\n",
                   st.file_vertices, st.file_triangles, st.merged_vertices, st.degenerate_triangles,
                   st.unreferenced_vertices, st.had_normals);
            remove(path);
        }
        HL_CHECK(r == HL_OK, "load: %s", hl_context_last_error(ref_ctx()));
        if (m) {
            double worst = 0.0;
            for (uint32_t v = 0; v < m->vertex_count; v++) {
                const float *n = m->normals + 3 * (size_t)v;
                double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
                if (!(fabs(len - 1.0) <= worst)) worst = fabs(len - 1.0);
            }
            printf("%u vertices, %u triangles kept of %u\n", m->vertex_count, m->triangle_count, nt);
            hl_check_error("| |n| - 1 | over the normals (NaN fails)", worst, 4.0 * FLT_EPSILON);
            HL_CHECK(m->triangle_count <= nt - 3, "the three zero-area triangles must be dropped");
            hl_precompute_desc d = {.N = 16, .C = 16};
            rig g;
            if (rig_open(&g, precompute_both(m, &d, src ? "shape_obj" : "shape_mem"))) {
                if (env) rig_run(&g, env, HL_TERMS_ALL, "odd shapes");
                rig_close(&g);
            }
        }
        hl_mesh_destroy(m);
        case_end();
    }
    hl_env_destroy(env);
    free(px);
}

/* ================================================================ accumulation */

/* Long rows: every coefficient kept at N = 128 and 256 (the box's walls
 * face sideways, so their rows fill both maps) under a noisy map whose
 * Haar coefficients are all non-zero. The float sums against double sums
 * of the same float products: the rigorous gamma_n bound, and the
 * statistical one, 4 u sqrt(n) sum |T_i L_i|, which independent roundings
 * meet with a wide margin. */
static void case_accumulation(void)
{
    static const uint32_t Ns[] = {128, 256};
    hl_mesh *m = scene_mesh(1.0, no_shift);
    for (int k = 0; k < 2; k++) {
        const uint32_t N = Ns[k], W = 8 * N;
        case_begin("accumulation: N=%u", N);
        double t0 = hl_now();
        hl_precompute_desc d = {.N = N, .C = 8, .rule = HL_TRUNC_ALL};
        char name[32];
        snprintf(name, sizeof name, "accum_%u", N);
        rig g;
        float *px = need(malloc((size_t)W * (W / 2) * 12));
        for (size_t i = 0; i < (size_t)W * (W / 2) * 3; i++) px[i] = (float)(2.0 * rng_unit());
        hl_env *env = env_of(W, px);
        if (env && rig_open(&g, precompute_both(m, &d, name))) {
            if (rig_run(&g, env, HL_TERMS_ALL, name)) {
                reference R;
                reference_make(&R, &g, env, NULL);
                check_both(name, &g, &R, 0);
                double worst = 0.0, e_at = 0.0, b_at = 0.0;
                uint32_t longest = 0;
                for (uint32_t v = 0; v < g.V; v++)
                    for (int c = 0; c < 3; c++) {
                        const sample *s = R.S + 3 * (size_t)v + c;
                        double a = g.t[1]->mesh->albedo[3 * (size_t)v + c];
                        float B = g.rgb[1][3 * (size_t)v + c];
                        double bound = a * 4.0 * U_F32 * sqrt((double)s->n) * s->abs_sum + U_F32 * fabs((double)B);
                        double e = fabs(B - a * s->ref_f);
                        if (s->n > longest) longest = s->n;
                        if (e / bound > worst) worst = e / bound, e_at = e, b_at = bound;
                    }
                printf("%s: longest row %u terms of %u; worst error %.4g where 4 u sqrt(n) sum|T L| is %.4g\n", name,
                       longest, R.L.nc, e_at, b_at);
                hl_check_error("float sum vs double sum / (4 u sqrt(n) sum |T_i L_i| + u |B|)", worst, 1.0);
                reference_free(&R);
            }
            rig_close(&g);
        }
        hl_env_destroy(env);
        free(px);
        printf("%s: %.2f s\n", name, hl_now() - t0);
        case_end();
    }
    hl_mesh_destroy(m);
}

/* ---------------------------------------------------------------- main */

static const hl_test_case stiff_cases[] = {
    {"sun_sky", case_sun_sky},
    {"black", case_black},
    {"single_pixel", case_single_pixel},
    {"negative", case_negative},
    {"denormal", case_denormal},
    {"env_sizes", case_env_sizes},
    {"resolution", case_resolution},
    {"truncation", case_truncation},
    {"zero_transport", case_zero_transport},
    {"scale", case_scale},
    {"shape", case_shape},
    {"accumulation", case_accumulation},
    {NULL, NULL},
};

static void cleanup(void)
{
    for (int b = 0; b < 2; b++) hl_context_destroy(contexts[b]);
    for (int l = 0; l < 9; l++) hl_geom_destroy(geom_cache[l]);
}

int main(int argc, char **argv)
{
    int rc;
    if (argc >= 2 && strcmp(argv[1], "all") == 0) {
        for (const hl_test_case *c = stiff_cases; c->name; c++) c->fn();
        rc = hl_test_failures ? 1 : 0;
    } else {
        rc = hl_test_main(argc, argv, stiff_cases);
    }
    if (cases_run)
        printf("stiff%s%s: %d cases, %s\n", argc >= 2 ? " " : "", argc >= 2 ? argv[1] : "", cases_run,
               cases_failed ? "some FAILED" : "all passed");
    if (cases_failed) printf("stiff: %d of %d cases failed\n", cases_failed, cases_run);
    cleanup();
    return rc;
}
