/* bench_refs.c - the references `haarlight bench` measures errors
 * against, on a subset of vertices:
 *   exact:      untruncated, unquantised transport (recomputed from the
 *               rays by the plain-C twins) dotted with untruncated lighting,
 *               in float64;
 *   continuous: the original equirectangular map integrated directly, one
 *               Embree ray per map pixel, cast from the vertex itself with
 *               its own triangles skipped (no ray offset); independent of N
 *               and C and of the precompute's offset;
 * and the exact colours of every ground vertex (for the banding measure).
 * The exact rows and lighting are also given as they are, in texels and
 * in Haar coefficients (`bench-basis` projects them onto other bases).
 *
 * Depends on the ray caster (rays.h), the twins (twins.h) and the lighting
 * tables (lighting.h).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

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
