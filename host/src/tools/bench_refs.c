/* bench_refs.c - the references `haarlight bench` measures errors
 * against, on a subset of vertices:
 *   exact:      untruncated, unquantised transport (recomputed from the
 *               rays by the plain-C twins) dotted with untruncated lighting,
 *               in float64;
 *   continuous: the original equirectangular map integrated directly, one
 *               Embree ray per map pixel, cast from the vertex itself with
 *               its own triangles skipped (no ray offset); independent of N
 *               and C and of the precompute's offset;
 * and the exact colours of every ground vertex (for the banding measure);
 * and for a file with bounces the bounced exact reference (direct light of
 * every vertex, then each bounce's gather in float64 with per-channel
 * albedo, on its own rays: hl_bench_ref_bounced).
 * The exact rows and lighting are also given as they are, in texels and
 * in Haar coefficients (`bench-basis` projects them onto other bases).
 *
 * Depends on the ray caster (rays.h), the twins (twins.h) and the lighting
 * tables (lighting.h).
 */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bounce.h"
#include "haarlight_tools.h"
#include "lighting.h"
#include "rays.h"
#include "twins.h"

struct hl_bench_ref {
    hl_context *ctx;
    const hl_transport *t;
    hl_geom *g;
    hl_light_geom *lg;
    hl_rt *rt;      /* filtered: can cast from a vertex itself */
    float *Lw_all;  /* nenvs x 3 x ncoef: each environment's full lighting */
    int nenvs;
};

hl_result hl_bench_ref_create(hl_context *ctx, const hl_transport *t, hl_bench_ref **out)
{
    *out = NULL;
    hl_bench_ref *b = hl_calloc(ctx, 1, sizeof *b, "the benchmark's references");
    if (!b) return HL_ERR_OUT_OF_MEMORY;
    b->ctx = ctx;
    b->t = t;
    hl_result r = hl_geom_create(ctx, t->info.N, t->info.C, &b->g);
    if (r == HL_OK) r = hl_light_geom_create(ctx, b->g, &b->lg);
    if (r == HL_OK) r = hl_rt_create_filtered(ctx, t->mesh, &b->rt);
    if (r != HL_OK) {
        hl_bench_ref_destroy(b);
        return r;
    }
    *out = b;
    return HL_OK;
}

void hl_bench_ref_destroy(hl_bench_ref *b)
{
    if (!b) return;
    free(b->Lw_all);
    hl_rt_destroy(b->rt);
    hl_light_geom_destroy(b->lg);
    hl_geom_destroy(b->g);
    free(b);
}

/* The ray offset of the transport, in scene units. */
static float ray_offset(const hl_bench_ref *b)
{
    return b->t->info.ray_offset * hl_mesh_query_diagonal(b->t->mesh);
}

/* Scale of the visibility counts: 1 / (pi S^2). */
static float vis_scale(const hl_bench_ref *b)
{
    const uint32_t S = b->t->info.supersample;
    return (float)(1.0 / (HL_PI * S * S));
}

/* Untruncated lighting of env at rotation 0: R, G, B planes of texel
 * means (Lp, may be NULL) and of their Haar coefficients in slot order
 * (Lw, may be NULL). */
hl_result hl_bench_ref_lighting(hl_bench_ref *b, const hl_env *env, float *Lp_out, float *Lw)
{
    const hl_geom *g = b->g;
    float *cells = NULL, *Lp = malloc((size_t)g->ncoef * 12);
    if (!Lp) return hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    hl_result r = hl_env_to_cells(b->ctx, env, b->lg->wc, b->lg->hc, &cells);
    if (r == HL_OK) {
        hl_ref_env2para(cells, b->lg->wc, b->lg->tap_start, b->lg->taps, 0, 0.0f, g->ncoef, Lp);
        if (Lp_out) memcpy(Lp_out, Lp, (size_t)g->ncoef * 12);
        /* hl_ref_haar works in place in Lp, so after the copy */
        for (int c = 0; c < 3 && Lw; c++) hl_ref_haar(g, Lp + (size_t)c * g->ncoef, Lw + (size_t)c * g->ncoef);
    }
    hl_free_big(cells);
    free(Lp);
    return r;
}

hl_result hl_bench_ref_weights(hl_bench_ref *b, uint32_t scheme, float *w)
{
    return hl_selection_weights(b->ctx, b->t, b->lg, scheme, w);
}

/* The continuous reference: sum over map pixels of L V max(0, n.w) dw / pi
 * for each of the K2 vertices, one occlusion ray per pixel from the vertex
 * itself (hl_rt_occluded_from_vertex). */
static hl_result continuous(hl_bench_ref *b, const uint32_t *idx2, uint32_t K2, const hl_env *env, double *out)
{
    const hl_mesh *m = b->t->mesh;
    const uint32_t W = env->width, H = env->height;
    const size_t np = (size_t)W * H;
    float *dir = malloc(np * 12);
    uint8_t *occ = malloc(np);
    uint32_t *pix = malloc(np * 4);
    if (!dir || !occ || !pix) {
        free(dir); free(occ); free(pix);
        return hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the continuous reference");
    }
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < K2 && r == HL_OK; k++) {
        const uint32_t v = idx2[k];
        const float *n = m->normals + 3 * (size_t)v;
        uint32_t cnt = 0;
        for (uint32_t y = 0; y < H; y++) {
            double th = HL_PI * (y + 0.5) / H;
            for (uint32_t x = 0; x < W; x++) {
                double ph = 2.0 * HL_PI * ((x + 0.5) / W - 0.5);
                float d[3] = {(float)(sin(th) * cos(ph)), (float)cos(th), (float)(sin(th) * sin(ph))};
                if (d[0] * n[0] + d[1] * n[1] + d[2] * n[2] <= 0.0f) continue;
                for (int c = 0; c < 3; c++) dir[3 * (size_t)cnt + c] = d[c];
                pix[cnt++] = y * W + x;
            }
        }
        /* rays from the vertex itself, its own triangles skipped: no
           offset, so the precompute's offset cannot hide its own errors */
        r = hl_rt_occluded_from_vertex(b->rt, v, cnt, dir, occ);
        double acc[3] = {0, 0, 0};
        for (uint32_t i = 0; i < cnt && r == HL_OK; i++) {
            if (occ[i]) continue;
            uint32_t y = pix[i] / W;
            double om = 2.0 * HL_PI / W * (cos(HL_PI * y / H) - cos(HL_PI * (y + 1) / H));
            const float *d = dir + 3 * (size_t)i;
            double cosn = (double)d[0] * n[0] + (double)d[1] * n[1] + (double)d[2] * n[2];
            for (int c = 0; c < 3; c++) acc[c] += env->rgb[3 * (size_t)pix[i] + c] * cosn * om;
        }
        for (int c = 0; c < 3; c++) out[3 * k + c] = acc[c] / HL_PI * m->albedo[3 * (size_t)v + c];
    }
    free(dir); free(occ); free(pix);
    return r;
}

/* The untruncated transport rows of the n vertices idx (n x ncoef each):
 * texel values (texel, may be NULL) and their Haar coefficients in slot
 * order (raw, may be NULL). */
hl_result hl_bench_ref_rows(hl_bench_ref *b, const uint32_t *idx, uint32_t n, float *texel, float *raw)
{
    const hl_geom *g = b->g;
    const hl_mesh *m = b->t->mesh;
    const uint32_t nc = g->ncoef;
    float *T = malloc((size_t)nc * 4);
    uint8_t *vis = malloc(g->ncube);
    hl_result r = T && vis ? HL_OK : hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the exact transport");
    for (uint32_t k = 0; k < n && r == HL_OK; k++) {
        r = hl_rt_visibility(b->rt, g, m, idx[k], 1, b->t->info.supersample, ray_offset(b), vis, NULL);
        hl_ref_cube2para(g, vis, vis_scale(b), m->normals + 3 * (size_t)idx[k], T);
        if (texel) memcpy(texel + (size_t)k * nc, T, (size_t)nc * 4);
        if (raw) hl_ref_haar(g, T, raw + (size_t)k * nc); /* in place in T: after the copy */
    }
    free(vis);
    free(T);
    return r;
}

/* Each row dotted with the lighting Lw (3 planes), times the albedo. */
static void exact_dots(const hl_bench_ref *b, const float *raw, const uint32_t *idx, uint32_t n, const float *Lw,
                       double *exact)
{
    const uint32_t nc = b->g->ncoef;
    const hl_mesh *m = b->t->mesh;
    for (uint32_t k = 0; k < n; k++)
        for (int c = 0; c < 3; c++) {
            double s = 0.0;
            const float *row = raw + (size_t)k * nc, *l = Lw + (size_t)c * nc;
            for (uint32_t i = 0; i < nc; i++) s += (double)row[i] * l[i];
            exact[3 * k + c] = s * m->albedo[3 * (size_t)idx[k] + c];
        }
}

hl_result hl_bench_ref_colours(hl_bench_ref *b, const uint32_t *idx, uint32_t n, const uint32_t *idx2, uint32_t n_cont,
                               const hl_env *const *envs, int nenvs, double *const *exact, double *const *cont)
{
    const uint32_t nc = b->g->ncoef;
    float *raw = malloc((size_t)n * nc * 4);
    hl_result r = raw ? HL_OK : hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the exact transport");
    if (r == HL_OK) r = hl_bench_ref_rows(b, idx, n, NULL, raw);
    free(b->Lw_all);
    b->nenvs = 0;
    b->Lw_all = malloc((size_t)(nenvs > 0 ? nenvs : 1) * nc * 12);
    if (r == HL_OK && !b->Lw_all) r = hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the lighting");
    for (int e = 0; e < nenvs && r == HL_OK; e++) {
        float *Lw = b->Lw_all + (size_t)e * nc * 3;
        r = hl_bench_ref_lighting(b, envs[e], NULL, Lw);
        if (r == HL_OK) exact_dots(b, raw, idx, n, Lw, exact[e]);
        if (r == HL_OK && n_cont) r = continuous(b, idx2, n_cont, envs[e], cont[e]);
        if (r == HL_OK) b->nenvs = e + 1;
    }
    free(raw);
    return r;
}

hl_result hl_bench_ref_ground(hl_bench_ref *b, double **ground)
{
    const hl_geom *g = b->g;
    const hl_mesh *m = b->t->mesh;
    const uint32_t first = b->t->info.object_vertex_count, G = b->t->info.vertex_count - first, nc = g->ncoef;
    const uint32_t batch = 128; /* vertices whose rays are cast together */
    uint8_t *vis = malloc((size_t)batch * g->ncube);
    float *T = malloc((size_t)nc * 4), *row = malloc((size_t)nc * 4);
    hl_result r = vis && T && row ? HL_OK : hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the ground rows");
    for (int e = 0; e < b->nenvs && r == HL_OK; e++) {
        ground[e] = calloc((size_t)G * 3, sizeof(double));
        if (!ground[e]) r = hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the ground's exact colours");
    }
    for (uint32_t b0 = 0; b0 < G && r == HL_OK; b0 += batch) {
        const uint32_t nb = G - b0 < batch ? G - b0 : batch;
        r = hl_rt_visibility(b->rt, g, m, first + b0, nb, b->t->info.supersample, ray_offset(b), vis, NULL);
        for (uint32_t k = 0; k < nb && r == HL_OK; k++) {
            const uint32_t v = first + b0 + k;
            hl_ref_cube2para(g, vis + (size_t)k * g->ncube, vis_scale(b), m->normals + 3 * (size_t)v, T);
            hl_ref_haar(g, T, row);
            for (int e = 0; e < b->nenvs; e++)
                for (int c = 0; c < 3; c++) {
                    const float *l = b->Lw_all + ((size_t)e * 3 + c) * nc;
                    double sum = 0.0;
                    for (uint32_t i = 0; i < nc; i++) sum += (double)row[i] * l[i];
                    ground[e][3 * ((size_t)b0 + k) + c] = sum * m->albedo[3 * (size_t)v + c];
                }
        }
    }
    free(vis);
    free(T);
    free(row);
    return r;
}

/* ------------------------------------------------------------ bounced */

/* The bounced exact reference (docs/BOUNCES.md, "The bounced reference in
 * bench"). Everything is linear in the lighting, so it is computed in
 * lighting space, per channel c and environment e: E_0(v) = the untruncated
 * row of v dotted with the untruncated lighting (no albedo), then bounce b
 * F_b(x) = (1 / K) sum_k rho_c(y_k) F_(b-1)(y_k), F_0 = E_0, over K
 * cosine-weighted rays of x (fresh rays each bounce), and the colour
 * rho_c(x) (F_0 + ... + F_B)(x): the explicit sum of the bounces, not the
 * precompute's Horner form, so that each bounce's own noise can be followed.
 * A vertex's values are J = 3 nenvs doubles, index 3 e + c. */

/* Vertices a batch of visibility rays holds (ncube bytes each). */
#define BREF_BATCH 128u
/* Rays a chunk of the gathers casts at once (36 bytes each with the hits). */
#define BREF_CHUNK_RAYS 262144u

typedef struct bref_run {
    hl_bench_ref *b;
    const hl_mesh *m;
    uint32_t V, J, K, bounce;
    const float *Lw;      /* nenvs x 3 x ncoef */
    const float *rho;     /* V x 3 */
    /* the direct pass */
    const uint8_t *vis;   /* BREF_BATCH x ncube */
    uint32_t first, count;
    double *E0;           /* V x J */
    /* a gather: the chunk's vertices list[0 .. count) (list NULL: first + i),
       written at out[(first + i) J] */
    const uint32_t *list;
    const uint32_t *prim; /* count x K */
    const float *hu, *hv;
    const float *dir;
    const double *F, *SD; /* F_(b-1) and its standard error bound, V x J */
    double *Fo, *SDo, *own; /* F_b, its bound and its own gather's variance, at out */
    atomic_uint next;
    atomic_int oom;
} bref_run;

/* The direct pass's per-vertex work: row, Haar, dots. */
static void *bref_direct_worker(void *arg)
{
    bref_run *u = arg;
    const hl_geom *g = u->b->g;
    const uint32_t nc = g->ncoef, nenvs = u->J / 3;
    float *T = malloc((size_t)nc * 4), *row = malloc((size_t)nc * 4);
    if (!T || !row) atomic_store(&u->oom, 1);
    for (;;) {
        const uint32_t i = atomic_fetch_add(&u->next, 1u);
        if (i >= u->count || !T || !row) break;
        const uint32_t v = u->first + i;
        hl_ref_cube2para(g, u->vis + (size_t)i * g->ncube, vis_scale(u->b), u->m->normals + 3 * (size_t)v, T);
        hl_ref_haar(g, T, row);
        /* the sums of exact_dots, in the same order, so that bounce 0 is
           the direct exact reference bit for bit */
        for (uint32_t e = 0; e < nenvs; e++)
            for (int c = 0; c < 3; c++) {
                const float *l = u->Lw + ((size_t)e * 3 + c) * nc;
                double s = 0.0;
                for (uint32_t t = 0; t < nc; t++) s += (double)row[t] * l[t];
                u->E0[(size_t)v * u->J + 3 * e + c] = s;
            }
    }
    free(T);
    free(row);
    return NULL;
}

/* Whether K rays are an S x S grid of strata with S even, so that the
 * strata pair up along the grid's first axis (bref_gather_worker). */
static int bref_paired(uint32_t K)
{
    const uint32_t S = (uint32_t)sqrt((double)K);
    return S * S == K && S % 2 == 0;
}

/* One vertex's gather from its K hits: F_b, the variance of that mean, and
 * the noise it reads from F_(b-1), bounded by the hits' interpolated
 * standard errors summed (Minkowski: the errors of the hit rows may be
 * correlated, so no cancellation is assumed). The variance: with one ray a
 * stratum, from pairs of neighbouring strata (the collapsed-strata
 * estimator, (1 / K^2) sum over pairs of (s_1 - s_2)^2, which errs high by
 * the pairs' differences of stratum means); else the samples' spread over
 * K, which for stratified rays also errs high. */
static void *bref_gather_worker(void *arg)
{
    bref_run *u = arg;
    const uint32_t J = u->J, K = u->K;
    const int paired = bref_paired(K);
    double *acc = malloc((size_t)J * 5 * sizeof(double));
    if (!acc) atomic_store(&u->oom, 1);
    for (;;) {
        const uint32_t i = atomic_fetch_add(&u->next, 1u);
        if (i >= u->count || !acc) break;
        double *s1 = acc, *s2 = acc + J, *up = acc + 2 * J, *prev = acc + 3 * J, *cur = acc + 4 * J;
        memset(acc, 0, (size_t)J * 5 * sizeof(double));
        for (uint32_t k = 0; k < K; k++) {
            const size_t q = (size_t)i * K + k;
            const uint32_t p = u->prim[q];
            /* stratum k is column k % S of the grid: k and k + 1 pair
               when k is even (S even) */
            if (p == HL_BOUNCE_MISS) {
                memset(cur, 0, (size_t)J * sizeof(double));
            } else {
            const uint32_t *c = u->m->indices + 3 * (size_t)p;
            const double w[3] = {1.0 - u->hu[q] - u->hv[q], u->hu[q], u->hv[q]};
            double ry[3];
            for (int ch = 0; ch < 3; ch++)
                ry[ch] = w[0] * u->rho[3 * (size_t)c[0] + ch] + w[1] * u->rho[3 * (size_t)c[1] + ch] +
                         w[2] * u->rho[3 * (size_t)c[2] + ch];
            const double *f0 = u->F + (size_t)c[0] * J, *f1 = u->F + (size_t)c[1] * J, *f2 = u->F + (size_t)c[2] * J;
            const double *d0 = u->SD + (size_t)c[0] * J, *d1 = u->SD + (size_t)c[1] * J, *d2 = u->SD + (size_t)c[2] * J;
            for (uint32_t j = 0; j < J; j++) {
                const double r = ry[j % 3];
                cur[j] = r * (w[0] * f0[j] + w[1] * f1[j] + w[2] * f2[j]);
                s1[j] += cur[j];
                up[j] += r * (w[0] * d0[j] + w[1] * d1[j] + w[2] * d2[j]);
            }
            }
            for (uint32_t j = 0; j < J; j++) {
                if (!paired) s2[j] += cur[j] * cur[j];
                else if (k % 2) s2[j] += (cur[j] - prev[j]) * (cur[j] - prev[j]);
                else prev[j] = cur[j];
            }
        }
        const size_t o = ((size_t)u->first + i) * J;
        for (uint32_t j = 0; j < J; j++) {
            const double mean = s1[j] / K;
            const double var = paired ? s2[j] / ((double)K * K) : fmax(0.0, (s2[j] - K * mean * mean) / (K - 1)) / K;
            const double ub = up[j] / K;
            u->Fo[o + j] = mean;
            u->own[o + j] = var;
            u->SDo[o + j] = sqrt(var + ub * ub);
        }
    }
    free(acc);
    return NULL;
}

/* Bounce `bounce` gathered at the n vertices list (NULL: every vertex, in
 * order), results at position i of Fo, SDo and own. */
static hl_result bref_gather(bref_run *u, hl_rt *rt, const uint32_t *list, uint32_t n, int progress)
{
    hl_context *ctx = u->b->ctx;
    const uint32_t K = u->K, R = BREF_CHUNK_RAYS / K > 0 ? BREF_CHUNK_RAYS / K : 1;
    const size_t nr = (size_t)R * K;
    float *org = hl_alloc_big(ctx, nr * 12, "the reference's bounce rays");
    float *dir = org ? hl_alloc_big(ctx, nr * 12, "the reference's bounce rays") : NULL;
    float *hu = dir ? hl_alloc_big(ctx, nr * 8, "the reference's bounce hits") : NULL;
    uint32_t *prim = hu ? hl_alloc_big(ctx, nr * 4, "the reference's bounce hits") : NULL;
    hl_result r = prim ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    const double t0 = hl_now();
    uint32_t shown = 0;
    for (uint32_t first = 0; first < n && r == HL_OK; first += R) {
        const uint32_t count = n - first < R ? n - first : R;
        /* the precompute's rays (origin, back-face rule), with the bounce
           in the hash: rays of its own each bounce */
        r = hl_bounce_cast(rt, u->m, list, first, count, K, u->bounce * 0x9e3779b9u, org, dir, prim, hu, hu + nr);
        if (r != HL_OK) break;
        u->first = first;
        u->count = count;
        u->prim = prim;
        u->hu = hu;
        u->hv = hu + nr;
        atomic_store(&u->next, 0u);
        hl_run_threads(ctx->threads, bref_gather_worker, u);
        if (atomic_load(&u->oom)) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's gathers");
        if (r == HL_OK && hl_context_cancelled(ctx)) r = hl_fail(ctx, HL_ERR_INTERRUPTED, "interrupted");
        const uint32_t done = first + count;
        /* a line each tenth, once the phase has run a second */
        if (progress && (uint64_t)done * 10 / n > shown && hl_now() - t0 > 1.0) {
            shown = (uint32_t)((uint64_t)done * 10 / n);
            fprintf(stderr, "bench: bounced reference, bounce %u: %u of %u vertices x %u rays, %.1f s\n", u->bounce, done,
                    n, K, hl_now() - t0);
        }
    }
    hl_free_big(org);
    hl_free_big(dir);
    hl_free_big(hu);
    hl_free_big(prim);
    return r;
}

/* E_0 of every vertex, in batches of visibility rays. */
static hl_result bref_direct(bref_run *u, int progress)
{
    hl_bench_ref *b = u->b;
    const hl_geom *g = b->g;
    uint8_t *vis = hl_alloc_big(b->ctx, (size_t)BREF_BATCH * g->ncube, "the reference's visibility");
    if (!vis) return HL_ERR_OUT_OF_MEMORY;
    hl_result r = HL_OK;
    const double t0 = hl_now();
    uint32_t shown = 0;
    for (uint32_t first = 0; first < u->V && r == HL_OK; first += BREF_BATCH) {
        const uint32_t count = u->V - first < BREF_BATCH ? u->V - first : BREF_BATCH;
        r = hl_rt_visibility(b->rt, g, u->m, first, count, b->t->info.supersample, ray_offset(b), vis, NULL);
        if (r != HL_OK) break;
        u->vis = vis;
        u->first = first;
        u->count = count;
        atomic_store(&u->next, 0u);
        hl_run_threads(b->ctx->threads, bref_direct_worker, u);
        if (atomic_load(&u->oom)) r = hl_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the exact rows");
        if (r == HL_OK && hl_context_cancelled(b->ctx)) r = hl_fail(b->ctx, HL_ERR_INTERRUPTED, "interrupted");
        const uint32_t done = first + count;
        if (progress && (uint64_t)done * 10 / u->V > shown && hl_now() - t0 > 1.0) {
            shown = (uint32_t)((uint64_t)done * 10 / u->V);
            fprintf(stderr, "bench: bounced reference, direct light: %u of %u vertices, %.1f s\n", done, u->V,
                    hl_now() - t0);
        }
    }
    hl_free_big(vis);
    return r;
}

hl_result hl_bench_ref_bounced(hl_bench_ref *b, const uint32_t *idx, uint32_t n, uint32_t B, uint32_t K,
                               const hl_env *const *envs, int nenvs, int progress, double *const *exact,
                               double *noise_own, double *noise_bound)
{
    hl_context *ctx = b->ctx;
    const hl_mesh *m = b->t->mesh;
    const uint32_t V = b->t->info.vertex_count, nc = b->g->ncoef;
    if (B < 1 || B > HL_MAX_BOUNCES || K < 2 || nenvs < 1 || n < 1)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "the bounced reference: %u bounces (1 to %u), %u rays (at least 2), %d maps, %u vertices", B,
                       HL_MAX_BOUNCES, K, nenvs, n);
    for (uint32_t k = 0; k < n; k++)
        if (idx[k] >= V)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the bounced reference: vertex %u of %u", idx[k], V);
    for (uint32_t v = 0; v < V; v++)
        for (int c = 0; c < 3; c++) {
            const float a = m->albedo[3 * (size_t)v + c];
            if (!(a >= 0.0f && a <= 1.0f))
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                               "the bounced reference: vertex %u has albedo %g in channel %d, outside [0, 1]", v,
                               (double)a, c);
        }
    const uint32_t J = 3 * (uint32_t)nenvs;
    const size_t VJ = (size_t)V * J, nJ = (size_t)n * J;
    bref_run u = {.b = b, .m = m, .V = V, .J = J, .K = K, .rho = m->albedo};
    float *Lw = hl_alloc_big(ctx, (size_t)nenvs * 3 * nc * 4, "the lighting");
    /* F_(b-1) and F_b with their error bounds over every vertex; the sums
       at the subset */
    double *F = hl_alloc_big(ctx, VJ * 8, "the reference's bounces"), *Fn = hl_alloc_big(ctx, VJ * 8, "the reference's bounces");
    double *SD = hl_alloc_big(ctx, VJ * 8, "the reference's noise"), *SDn = hl_alloc_big(ctx, VJ * 8, "the reference's noise");
    double *own = hl_alloc_big(ctx, VJ * 8, "the reference's noise");
    double *sum = hl_calloc(ctx, nJ, 8, "the reference"), *own2 = hl_calloc(ctx, nJ, 8, "the reference");
    double *bnd = hl_calloc(ctx, nJ, 8, "the reference");
    hl_rt *rt = NULL;
    hl_result r = Lw && F && Fn && SD && SDn && own && sum && own2 && bnd ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    for (int e = 0; e < nenvs && r == HL_OK; e++) r = hl_bench_ref_lighting(b, envs[e], NULL, Lw + (size_t)e * 3 * nc);
    u.Lw = Lw;
    u.E0 = F;
    if (r == HL_OK) r = bref_direct(&u, progress);
    if (r == HL_OK) memset(SD, 0, VJ * 8); /* E_0 is exact: no noise */
    /* the precompute's plain scene for the bounce rays, as bounce.c casts them */
    if (r == HL_OK) r = hl_rt_create(ctx, m, &rt);
    for (uint32_t k = 0; k < n && r == HL_OK; k++)
        for (uint32_t j = 0; j < J; j++) sum[(size_t)k * J + j] = F[(size_t)idx[k] * J + j];
    const double t0 = hl_now();
    for (uint32_t bo = 0; bo <= B && r == HL_OK; bo++) {
        if (bo > 0) {
            /* intermediate bounces need every vertex, the last only the subset */
            const int last = bo == B;
            u.bounce = bo;
            u.F = F;
            u.SD = SD;
            u.Fo = Fn;
            u.SDo = SDn;
            u.own = own;
            r = bref_gather(&u, rt, last ? idx : NULL, last ? n : V, progress);
            for (uint32_t k = 0; k < n && r == HL_OK; k++) {
                const size_t at = (size_t)(last ? k : idx[k]) * J;
                for (uint32_t j = 0; j < J; j++) {
                    sum[(size_t)k * J + j] += Fn[at + j];
                    own2[(size_t)k * J + j] += own[at + j];
                    bnd[(size_t)k * J + j] += SDn[at + j];
                }
            }
            double *s = F;
            F = Fn, Fn = s;
            s = SD, SD = SDn, SDn = s;
            if (r == HL_OK && progress)
                fprintf(stderr, "bench: bounced reference: bounce %u/%u on %u vertices x %u rays, %.1f s\n", bo, B,
                        last ? n : V, K, hl_now() - t0);
        }
        /* the colours after bo bounces, and their noise over the subset */
        for (int e = 0; e < nenvs && r == HL_OK; e++) {
            double *out = exact[(size_t)bo * nenvs + e], sr = 0.0, so = 0.0, sb = 0.0;
            for (uint32_t k = 0; k < n; k++)
                for (int c = 0; c < 3; c++) {
                    const size_t j = (size_t)k * J + 3 * e + c;
                    const double a = m->albedo[3 * (size_t)idx[k] + c];
                    out[3 * k + c] = a * sum[j];
                    sr += out[3 * k + c] * out[3 * k + c];
                    so += a * a * own2[j];
                    sb += a * a * bnd[j] * bnd[j];
                }
            if (noise_own) noise_own[(size_t)bo * nenvs + e] = sr > 0 ? sqrt(so / sr) : 0.0;
            if (noise_bound) noise_bound[(size_t)bo * nenvs + e] = sr > 0 ? sqrt(sb / sr) : 0.0;
        }
    }
    hl_rt_destroy(rt);
    hl_free_big(Lw);
    hl_free_big(F);
    hl_free_big(Fn);
    hl_free_big(SD);
    hl_free_big(SDn);
    hl_free_big(own);
    free(sum);
    free(own2);
    free(bnd);
    return r;
}
