/* lighting.c - environment cells, their runs per paraboloid texel, and the
 * relighter (hl_relighter_*) on either backend.
 *
 * An environment is resampled once onto a cell grid of 8N x 4N cells (area
 * weighted, so no light is lost whatever its resolution). Each paraboloid
 * texel takes the cells that overlap it at rotation 0, each weighted by its
 * share of the texel's solid angle (taps); a rotation about +Y is then an
 * offset along the cell rows. A lighting change runs env2para, Haar,
 * selection and the dot products (kernels/ or host/src/ref/).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cl_backend.h"
#include "lighting.h"
#include "twins.h"

void hl_rotation_to_shift(float rotate_deg, uint32_t wc, uint32_t *s0, float *f)
{
    double s = fmod((double)rotate_deg / 360.0 * wc, (double)wc);
    if (s < 0) s += wc;
    double w = floor(s);
    *s0 = (uint32_t)w % wc;
    *f = (float)(s - w);
}

static uint32_t cell_of(uint32_t wc, uint32_t hc, const float d[3])
{
    double u = 0.5 + atan2(d[2], d[0]) / (2.0 * HL_PI), v = acos(fmax(-1.0, fmin(1.0, d[1]))) / HL_PI;
    uint32_t k = (uint32_t)floor(u * wc) % wc, r = (uint32_t)floor(v * hc);
    if (r >= hc) r = hc - 1;
    return r * wc + k;
}

/* Solid angle of each wavelet's support: a summed-area table per map. */
static hl_result build_area(hl_context *ctx, const hl_geom *g, hl_light_geom *lg)
{
    const uint32_t N = g->N;
    double *sat = hl_calloc(ctx, (size_t)(N + 1) * (N + 1), sizeof(double), "support areas");
    if (!sat) return HL_ERR_OUT_OF_MEMORY;
    for (int map = 0; map < 2; map++) {
        for (uint32_t r = 0; r < N; r++)
            for (uint32_t c = 0; c < N; c++)
                sat[(r + 1) * (N + 1) + c + 1] = g->omega[(size_t)map * N * N + r * N + c] + sat[r * (N + 1) + c + 1] +
                                                 sat[(r + 1) * (N + 1) + c] - sat[r * (N + 1) + c];
        for (uint32_t r = 0; r < N; r++)
            for (uint32_t c = 0; c < N; c++) {
                uint32_t r0, c0, w;
                hl_geom_support(N, r, c, &r0, &c0, &w);
                double a = sat[(r0 + w) * (N + 1) + c0 + w] - sat[r0 * (N + 1) + c0 + w] - sat[(r0 + w) * (N + 1) + c0] +
                           sat[r0 * (N + 1) + c0];
                lg->area[hl_geom_slot(g, map, r, c)] = (float)a;
            }
    }
    free(sat);
    return HL_OK;
}

/* Rays per cell when sharing a cell among the texels it overlaps. */
#define HL_CELL_RAYS 16
/* Room for the texels one cell overlaps (a cell is at most 0.4 texels a
 * side, so it meets at most 4). */
#define HL_CELL_TEXELS 16

typedef struct tap_triple { uint32_t texel, cell; float w; } tap_triple;

/* Solid angle below radius rho in a paraboloid map, up to a constant:
 * the radial integral of 4 rho / (1 + rho^2)^2. */
static double rho_integral(double rho) { return -2.0 / (1.0 + rho * rho); }

/* The parts of one cell in the texels of its map. In the map's plane the
 * cell is an annular sector: rho in [ra, rb] (rho = tan of half the angle
 * from the map's pole) and polar angle psi = the longitude phi, over which
 * the solid angle is 4 rho / (1 + rho^2)^2 drho dpsi. Each of the
 * HL_CELL_RAYS rays (cosine cs[p], sine sn[p]) at the middles of equal
 * steps of psi is walked through the texel grid, crediting each texel with
 * the exact radial integral of its stretch times the step dpsi. A cell's
 * parts add up to its solid angle exactly, and a texel's to its own within
 * the quadrature in psi, so a light smaller than a texel keeps its energy
 * to 0.2% wherever it is (4 x 4 point samples per cell, used before, were
 * up to 6.5% off near the horizon at N = 64). Adds into tex[], w[] (nt
 * entries so far); returns the new count. */
static int cell_parts(uint32_t N, uint32_t map, double ra, double rb, const double *cs, const double *sn, double dpsi,
                      uint32_t *tex, double *w, int nt)
{
    const double h = 2.0 / N;
    for (int p = 0; p < HL_CELL_RAYS; p++) {
        const double c = cs[p], s = sn[p];
        double rho = ra, f0 = rho_integral(ra);
        int col = (int)floor((rho * c + 1.0) / h), row = (int)floor((rho * s + 1.0) / h);
        for (int step = 0; step < 4 * (int)N + 4; step++) {
            col = col < 0 ? 0 : col >= (int)N ? (int)N - 1 : col;
            row = row < 0 ? 0 : row >= (int)N ? (int)N - 1 : row;
            /* where the ray leaves this texel's column and row */
            double xs = c > 0.0 ? (-1.0 + (col + 1) * h) / c : c < 0.0 ? (-1.0 + col * h) / c : INFINITY;
            double xt = s > 0.0 ? (-1.0 + (row + 1) * h) / s : s < 0.0 ? (-1.0 + row * h) / s : INFINITY;
            double end = fmax(rho, fmin(rb, fmin(xs, xt))), f1 = rho_integral(end);
            uint32_t j = map * N * N + (uint32_t)row * N + (uint32_t)col;
            int e = 0;
            while (e < nt && tex[e] != j) e++;
            if (e == nt && nt < HL_CELL_TEXELS) { tex[nt] = j; w[nt++] = 0.0; }
            if (e < nt) w[e] += (f1 - f0) * dpsi;
            rho = end;
            f0 = f1;
            if (end >= rb) break;
            if (xs <= xt) col += c > 0.0 ? 1 : -1;
            if (xt <= xs) row += s > 0.0 ? 1 : -1;
        }
    }
    return nt;
}

static hl_result build_taps(hl_context *ctx, const hl_geom *g, hl_light_geom *lg)
{
    const uint32_t wc = lg->wc, hc = lg->hc, nc = g->ncoef;
    size_t cap = (size_t)wc * hc * 2 + nc, n = 0;
    tap_triple *tr = hl_malloc(ctx, cap * sizeof *tr, "environment taps");
    uint32_t *count = hl_calloc(ctx, (size_t)nc + 1, 4, "environment taps");
    double *tot = hl_calloc(ctx, nc, sizeof(double), "environment taps");
    double *cs = hl_malloc(ctx, (size_t)wc * HL_CELL_RAYS * 2 * sizeof(double), "environment taps");
    if (!tr || !count || !tot || !cs) { free(tr); free(count); free(tot); free(cs); return HL_ERR_OUT_OF_MEMORY; }
    /* the rays' directions in psi = phi, the same for every row */
    double *sn = cs + (size_t)wc * HL_CELL_RAYS;
    const double dpsi = 2.0 * HL_PI / wc / HL_CELL_RAYS;
    for (size_t q = 0; q < (size_t)wc * HL_CELL_RAYS; q++) {
        double phi = 2.0 * HL_PI * (((double)q + 0.5) / HL_CELL_RAYS / wc - 0.5);
        cs[q] = cos(phi);
        sn[q] = sin(phi);
    }
    for (uint32_t r = 0; r < hc; r++) {
        /* rows split at the horizon (hc even); map 1 measures from -Y */
        double th0 = HL_PI * r / hc, th1 = HL_PI * (r + 1) / hc;
        uint32_t map = 2 * r >= hc;
        double ra = map ? tan(0.5 * (HL_PI - th1)) : tan(0.5 * th0), rb = map ? tan(0.5 * (HL_PI - th0)) : tan(0.5 * th1);
        for (uint32_t k = 0; k < wc; k++) {
            uint32_t tex[HL_CELL_TEXELS];
            double w[HL_CELL_TEXELS];
            int nt = cell_parts(g->N, map, ra, rb, cs + (size_t)k * HL_CELL_RAYS, sn + (size_t)k * HL_CELL_RAYS, dpsi, tex, w, 0);
            for (int e = 0; e < nt; e++) {
                if (n == cap) {
                    cap *= 2;
                    tap_triple *p = realloc(tr, cap * sizeof *p);
                    if (!p) { free(tr); free(count); free(tot); free(cs); return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for environment taps"); }
                    tr = p;
                }
                tr[n++] = (tap_triple){tex[e], r * wc + k, (float)w[e]};
                tot[tex[e]] += w[e];
                count[tex[e] + 1]++;
            }
        }
    }
    free(cs);
    /* texels no ray crossed (rim slivers) take the cell at their in-disc
       point nearest the centre */
    for (uint32_t j = 0; j < nc; j++) {
        if (tot[j] > 0.0 || g->omega[j] <= 0.0f) continue;
        uint32_t map = j / (g->N * g->N), row = (j / g->N) % g->N, col = j % g->N;
        double h = 2.0 / g->N, cs = -1.0 + (col + 0.5) * h, ct = -1.0 + (row + 0.5) * h, rr = sqrt(cs * cs + ct * ct);
        if (rr > 1.0) { cs *= (1.0 - 1e-7) / rr; ct *= (1.0 - 1e-7) / rr; }
        double r2 = cs * cs + ct * ct, q = 1.0 / (1.0 + r2);
        float d[3] = {(float)(2 * cs * q), (float)((map ? -1 : 1) * (1 - r2) * q), (float)(2 * ct * q)};
        if (n == cap) {
            tap_triple *p = realloc(tr, (cap + nc) * sizeof *p);
            if (!p) { free(tr); free(count); free(tot); return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for environment taps"); }
            tr = p;
            cap += nc;
        }
        tr[n++] = (tap_triple){j, cell_of(wc, hc, d), 1.0f};
        tot[j] = 1.0;
        count[j + 1]++;
    }
    for (uint32_t j = 0; j < nc; j++) count[j + 1] += count[j];
    lg->taps = hl_malloc(ctx, n * sizeof *lg->taps, "environment taps");
    if (!lg->taps) { free(tr); free(count); free(tot); return HL_ERR_OUT_OF_MEMORY; }
    memcpy(lg->tap_start, count, ((size_t)nc + 1) * 4);
    /* counting sort by texel keeps cell order within a texel */
    for (size_t i = 0; i < n; i++) {
        uint32_t j = tr[i].texel;
        lg->taps[count[j]++] = (hl_env_tap){tr[i].cell / wc, tr[i].cell % wc, (float)(tr[i].w / tot[j]), 0u};
    }
    lg->ntaps = (uint32_t)n;
    free(tr);
    free(count);
    free(tot);
    return HL_OK;
}

hl_result hl_light_geom_create(hl_context *ctx, const hl_geom *g, hl_light_geom **out)
{
    *out = NULL;
    hl_light_geom *lg = hl_calloc(ctx, 1, sizeof *lg, "lighting tables");
    if (!lg) return HL_ERR_OUT_OF_MEMORY;
    lg->N = g->N;
    lg->ncoef = g->ncoef;
    lg->nblocks = g->nblocks;
    lg->wc = g->N * 8 < 64 ? 64 : g->N * 8;
    lg->hc = lg->wc / 2;
    lg->cell_omega = hl_malloc(ctx, lg->hc * sizeof(double), "cell solid angles");
    lg->tap_start = hl_malloc(ctx, ((size_t)g->ncoef + 1) * 4, "environment runs");
    lg->area = hl_malloc(ctx, (size_t)g->ncoef * 4, "support areas");
    hl_result r = HL_ERR_OUT_OF_MEMORY;
    if (lg->cell_omega && lg->tap_start && lg->area) {
        for (uint32_t row = 0; row < lg->hc; row++)
            lg->cell_omega[row] = 2.0 * HL_PI / lg->wc * (cos(HL_PI * row / lg->hc) - cos(HL_PI * (row + 1) / lg->hc));
        r = build_area(ctx, g, lg);
        if (r == HL_OK) r = build_taps(ctx, g, lg);
    }
    if (r != HL_OK) {
        hl_light_geom_destroy(lg);
        return r;
    }
    *out = lg;
    return HL_OK;
}

void hl_light_geom_destroy(hl_light_geom *lg)
{
    if (!lg) return;
    free(lg->cell_omega);
    free(lg->tap_start);
    free(lg->taps);
    free(lg->area);
    free(lg);
}

/* Overlap of [a0, a1) and [b0, b1). */
static double overlap(double a0, double a1, double b0, double b1)
{
    double lo = a0 > b0 ? a0 : b0, hi = a1 < b1 ? a1 : b1;
    return hi > lo ? hi - lo : 0.0;
}

hl_result hl_env_to_cells(hl_context *ctx, const hl_env *env, uint32_t wc, uint32_t hc, float **cells4)
{
    *cells4 = NULL;
    const uint32_t W = env->width, H = env->height;
    double *tmp = hl_calloc(ctx, (size_t)hc * W * 3, sizeof(double), "environment resampling");
    float *cells = hl_alloc_big(ctx, (size_t)wc * hc * 16, "environment cells");
    if (!tmp || !cells) { free(tmp); hl_free_big(cells); return HL_ERR_OUT_OF_MEMORY; }
    /* rows: weights are solid angles, d(cos theta) */
    for (uint32_t r = 0; r < hc; r++) {
        double c0 = cos(HL_PI * r / hc), c1 = cos(HL_PI * (r + 1) / hc), wsum = 0.0;
        uint32_t y0 = (uint32_t)floor((double)r * H / hc), y1 = (uint32_t)ceil((double)(r + 1) * H / hc);
        if (y1 > H) y1 = H;
        for (uint32_t y = y0; y < y1; y++) {
            /* overlap in cos(theta), which decreases with theta */
            double e0 = cos(HL_PI * y / H), e1 = cos(HL_PI * (y + 1) / H);
            double w = overlap(c1, c0, e1, e0);
            if (w <= 0.0) continue;
            wsum += w;
            for (uint32_t x = 0; x < W; x++)
                for (int c = 0; c < 3; c++) tmp[((size_t)r * W + x) * 3 + c] += w * env->rgb[((size_t)y * W + x) * 3 + c];
        }
        for (size_t i = 0; i < (size_t)W * 3; i++) tmp[(size_t)r * W * 3 + i] /= wsum > 0 ? wsum : 1.0;
    }
    /* columns: weights are lengths in u */
    for (uint32_t k = 0; k < wc; k++) {
        double u0 = (double)k / wc, u1 = (double)(k + 1) / wc, wsum = 0.0;
        uint32_t x0 = (uint32_t)floor(u0 * W), x1 = (uint32_t)ceil(u1 * W);
        if (x1 > W) x1 = W;
        for (uint32_t r = 0; r < hc; r++) {
            double s[3] = {0, 0, 0};
            wsum = 0.0;
            for (uint32_t x = x0; x < x1; x++) {
                double w = overlap(u0, u1, (double)x / W, (double)(x + 1) / W);
                wsum += w;
                for (int c = 0; c < 3; c++) s[c] += w * tmp[((size_t)r * W + x) * 3 + c];
            }
            float *o = cells + 4 * ((size_t)r * wc + k);
            for (int c = 0; c < 3; c++) o[c] = (float)(s[c] / (wsum > 0 ? wsum : 1.0));
            o[3] = 0.0f;
        }
    }
    free(tmp);
    *cells4 = cells;
    return HL_OK;
}

/* ------------------------------------------------------------ relighter */

struct hl_relighter {
    hl_context *ctx;
    const hl_transport *t;
    hl_geom *g;
    hl_light_geom *lg;
    hl_cl_light *cl;        /* NULL: the plain-C reference */
    float *cells;           /* current environment, 4 floats per cell */
    uint64_t env_serial;
    float *albedo4;
    float *weights[HL_SELECT_TRANSPORT + 1]; /* per scheme, made when first asked */
    uint32_t uploaded_weights;
    double max_row_norm;    /* max over vertices of |T_v| */
    float *B4;
    float *Lp, *Lw, *Lsel;  /* reference scratch */
    uint8_t *used;
    uint32_t *bits;
    hl_ref_key *keys;       /* hl_ref_select's scratch */
    int have_last;
    void *last_out;         /* where the last colours went: NULL for B4 */
    hl_relight_desc last;
    uint64_t last_serial;
    hl_relight_stats last_stats;
};

void hl_relighter_destroy(hl_relighter *r)
{
    if (!r) return;
    hl_cl_light_destroy(r->cl);
    hl_light_geom_destroy(r->lg);
    hl_geom_destroy(r->g);
    hl_free_big(r->cells);
    free(r->albedo4);
    for (int i = 0; i <= (int)HL_SELECT_TRANSPORT; i++) free(r->weights[i]);
    free(r->B4);
    free(r->Lp);
    free(r->Lw);
    free(r->Lsel);
    free(r->used);
    free(r->bits);
    free(r->keys);
    free(r);
}

hl_result hl_relighter_create(hl_context *ctx, const hl_transport *t, hl_relighter **out)
{
    *out = NULL;
    if (!t || !t->mesh) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_relighter_create: no transport");
    hl_relighter *r = hl_calloc(ctx, 1, sizeof *r, "the relighter");
    if (!r) return HL_ERR_OUT_OF_MEMORY;
    r->ctx = ctx;
    r->t = t;
    const uint32_t V = t->info.vertex_count;
    hl_result res = hl_geom_create(ctx, t->info.N, t->info.C, &r->g);
    if (res == HL_OK) res = hl_light_geom_create(ctx, r->g, &r->lg);
    const uint32_t nc = r->g ? r->g->ncoef : 0;
    if (res == HL_OK) {
        r->albedo4 = hl_malloc(ctx, (size_t)V * 16, "albedo");
        r->B4 = hl_malloc(ctx, (size_t)V * 16, "vertex colours");
        r->Lp = hl_malloc(ctx, (size_t)nc * 12, "lighting");
        r->Lw = hl_malloc(ctx, (size_t)nc * 12, "lighting");
        r->Lsel = hl_malloc(ctx, (size_t)nc * 16, "lighting");
        r->used = hl_malloc(ctx, r->g->nblocks, "block flags");
        r->bits = hl_malloc(ctx, (size_t)nc / 8, "kept-slot bits");
        r->keys = hl_malloc(ctx, (size_t)nc * sizeof *r->keys, "the selection's sort keys");
        if (!r->albedo4 || !r->B4 || !r->Lp || !r->Lw || !r->Lsel || !r->used || !r->bits || !r->keys)
            res = HL_ERR_OUT_OF_MEMORY;
    }
    if (res == HL_OK) {
        for (uint32_t v = 0; v < V; v++) {
            memcpy(r->albedo4 + 4 * (size_t)v, t->mesh->albedo + 3 * (size_t)v, 12);
            r->albedo4[4 * (size_t)v + 3] = 0.0f;
        }
        /* |T_v| for the error bound */
        for (uint32_t v = 0; v < V; v++) {
            double ss = 0.0;
            const hl_row_quant q = t->row_quant[v];
            uint64_t e = t->row_offset[v];
            for (uint32_t b = 0; b < t->info.block_count; b++)
                for (uint32_t k = 0; k < t->block_counts[(size_t)v * t->info.block_count + b]; k++, e++) {
                    const uint32_t slot = b * HL_BLOCK + t->entries[2 * e];
                    double x = hl_dequant(t->info.quant, t->entries[2 * e + 1], q.a, q.b, hl_dither_key(v, slot));
                    ss += x * x;
                }
            if (ss > r->max_row_norm) r->max_row_norm = ss;
        }
        r->max_row_norm = sqrt(r->max_row_norm);
        r->uploaded_weights = HL_SELECT_AREA;
        if (ctx->backend == HL_BACKEND_OPENCL) res = hl_cl_light_create(ctx, r->g, r->lg, t, r->albedo4, &r->cl);
    }
    if (res != HL_OK) {
        hl_relighter_destroy(r);
        return res;
    }
    *out = r;
    return HL_OK;
}

hl_result hl_relighter_set_env(hl_relighter *r, const hl_env *env)
{
    if (!env || !env->rgb || env->width == 0 || env->height == 0)
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "hl_relighter_set_env: no environment");
    float *cells = NULL;
    hl_result res = hl_env_to_cells(r->ctx, env, r->lg->wc, r->lg->hc, &cells);
    if (res != HL_OK) return res;
    if (r->cl) res = hl_cl_light_set_cells(r->cl, cells);
    if (res != HL_OK) {
        hl_free_big(cells);
        return res;
    }
    hl_free_big(r->cells);
    r->cells = cells;
    r->env_serial++;
    return HL_OK;
}

hl_result hl_selection_weights(hl_context *ctx, const hl_transport *t, const hl_light_geom *lg, uint32_t scheme,
                               float *w)
{
    const uint32_t nc = lg->ncoef, nb = lg->nblocks, V = t->info.vertex_count;
    if (scheme == HL_SELECT_AREA) {
        memcpy(w, lg->area, (size_t)nc * 4);
        return HL_OK;
    }
    if (scheme == HL_SELECT_UNWEIGHTED) {
        for (uint32_t i = 0; i < nc; i++) w[i] = 1.0f;
        return HL_OK;
    }
    if (scheme != HL_SELECT_TRANSPORT) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "unknown selection scheme %u", scheme);
    /* mean |T_i| over the vertices */
    double *acc = hl_calloc(ctx, nc, sizeof(double), "transport weights");
    if (!acc) return HL_ERR_OUT_OF_MEMORY;
    for (uint32_t v = 0; v < V; v++) {
        uint64_t e = t->row_offset[v];
        const hl_row_quant q = t->row_quant[v];
        for (uint32_t b = 0; b < nb; b++)
            for (uint32_t k = 0; k < t->block_counts[(size_t)v * nb + b]; k++, e++)
            {
                const uint32_t slot = b * HL_BLOCK + t->entries[2 * e];
                acc[slot] += fabs(hl_dequant(t->info.quant, t->entries[2 * e + 1], q.a, q.b, hl_dither_key(v, slot)));
            }
    }
    for (uint32_t i = 0; i < nc; i++) w[i] = (float)(acc[i] / (V ? V : 1));
    free(acc);
    return HL_OK;
}

/* The weights of a scheme (1 to HL_SELECT_TRANSPORT), made once. */
static hl_result scheme_weights(hl_relighter *r, uint32_t scheme, const float **out)
{
    if (!r->weights[scheme]) {
        float *w = hl_malloc(r->ctx, (size_t)r->g->ncoef * 4, "selection weights");
        if (!w) return HL_ERR_OUT_OF_MEMORY;
        hl_result res = hl_selection_weights(r->ctx, r->t, r->lg, scheme, w);
        if (res != HL_OK) {
            free(w);
            return res;
        }
        r->weights[scheme] = w;
    }
    *out = r->weights[scheme];
    return HL_OK;
}

static hl_result run_reference(hl_relighter *r, uint32_t s0, float f, hl_select_params sp, const float *weight,
                               int keep_negative, hl_select_result *sr)
{
    const hl_geom *g = r->g;
    const hl_transport *t = r->t;
    hl_ref_env2para(r->cells, r->lg->wc, r->lg->tap_start, r->lg->taps, s0, f, g->ncoef, r->Lp);
    for (int c = 0; c < 3; c++) hl_ref_haar(g, r->Lp + (size_t)c * g->ncoef, r->Lw + (size_t)c * g->ncoef);
    *sr = hl_ref_select(r->Lw, g->ncoef, weight, sp, r->Lsel, r->used, r->bits, g->nblocks, r->keys);
    for (uint32_t v = 0; v < t->info.vertex_count; v++) {
        hl_ref_relight(t->entries + 2 * t->row_offset[v], t->block_counts + (size_t)v * g->nblocks, t->row_quant[v],
                       t->info.quant, v, g->nblocks, r->Lsel, r->albedo4 + 4 * (size_t)v, keep_negative,
                       r->B4 + 4 * (size_t)v);
    }
    return HL_OK;
}

/* How much negative light the dot products met (the fourth float of each
 * vertex: its lowest channel before the clamp), against the brightest
 * channel of all. */
static void negative_light(const float *B4, uint32_t V, hl_relight_stats *st)
{
    float lo = 0.0f, hi = 0.0f;
    uint32_t n = 0;
    for (uint32_t v = 0; v < V; v++) {
        const float *b = B4 + 4 * (size_t)v;
        if (b[3] < 0.0f) n++;
        if (b[3] < lo) lo = b[3];
        for (int c = 0; c < 3; c++)
            if (b[c] > hi) hi = b[c];
    }
    st->negative_counted = 1;
    st->negative_vertices = n;
    st->most_negative = hi > 0.0f ? (double)lo / hi : (lo < 0.0f ? -1.0 : 0.0);
}

/* A lighting change, its colours into B4 (and from there into vertex_rgb
 * when given) or, with out set, into that device buffer
 * (hl_cl_light_run_into). */
static hl_result run(hl_relighter *r, const hl_relight_desc *desc, float *vertex_rgb, void *out, int gl,
                     hl_relight_stats *stats)
{
    hl_relight_desc d = {0};
    if (desc) d = *desc;
    if (!d.terms) d.terms = 200;
    if (!d.select) d.select = HL_SELECT_TRANSPORT;
    if (d.select > HL_SELECT_TRANSPORT) return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "unknown selection scheme %u", d.select);
    if (!isfinite(d.rotate_deg)) return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "rotation is not a finite number");
    if (!r->cells) return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "no environment set (hl_relighter_set_env)");
    const uint32_t V = r->t->info.vertex_count;
    hl_relight_stats st = {0};
    double t0 = hl_now();
    if (out && !r->cl)
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "colours into a device buffer need the OpenCL backend");
    if (r->have_last && r->last_out == out && r->last_serial == r->env_serial && r->last.terms == d.terms &&
        r->last.select == d.select && r->last.rotate_deg == d.rotate_deg &&
        r->last.keep_negative == d.keep_negative) {
        st = r->last_stats;
        st.reused = 1;
    } else {
        const float *weight = NULL;
        hl_result res = scheme_weights(r, d.select, &weight);
        if (res == HL_OK && r->cl && r->uploaded_weights != d.select) {
            res = hl_cl_light_set_weights(r->cl, weight);
            if (res == HL_OK) r->uploaded_weights = d.select;
        }
        uint32_t s0;
        float f;
        hl_rotation_to_shift(d.rotate_deg, r->lg->wc, &s0, &f);
        hl_select_params sp = {d.terms, d.select, {0, 0}};
        hl_select_result sr;
        r->have_last = 0; /* B4 or out may be half written on failure */
        if (r->cl) hl_cl_light_keep_negative(r->cl, d.keep_negative);
        if (res == HL_OK && out) res = hl_cl_light_run_into(r->cl, s0, f, sp, out, gl, &sr);
        else if (res == HL_OK)
            res = r->cl ? hl_cl_light_run(r->cl, s0, f, sp, r->B4, &sr)
                        : run_reference(r, s0, f, sp, weight, d.keep_negative, &sr);
        if (res != HL_OK) return res;
        if (!out) negative_light(r->B4, V, &st);
        double et = sr.energy_total, ek = sr.energy_kept;
        st.terms_kept = sr.kept;
        st.energy_kept = et > 0 ? ek / et : 1.0;
        /* the energies are of Y 2^-e (hl_light_energy_scale) */
        st.error_bound = r->max_row_norm * sqrt((double)sr.energy_dropped) * ldexp(1.0, (int)sr.energy_exp - 127);
        st.blocks_skipped = 1.0 - (double)sr.blocks_used / r->g->nblocks;
        r->have_last = 1;
        r->last_out = out;
        r->last = d;
        r->last_serial = r->env_serial;
        r->last_stats = st;
    }
    if (vertex_rgb)
        for (uint32_t v = 0; v < V; v++)
            for (int c = 0; c < 3; c++) vertex_rgb[3 * (size_t)v + c] = r->B4[4 * (size_t)v + c];
    st.seconds = hl_now() - t0;
    if (stats) *stats = st;
    return HL_OK;
}

hl_result hl_relighter_run(hl_relighter *r, const hl_relight_desc *desc, float *vertex_rgb, hl_relight_stats *stats)
{
    return run(r, desc, vertex_rgb, NULL, 0, stats);
}

hl_result hl_relighter_run4(hl_relighter *r, const hl_relight_desc *desc, const float **rgba, hl_relight_stats *stats)
{
    hl_result res = run(r, desc, NULL, NULL, 0, stats);
    *rgba = res == HL_OK ? r->B4 : NULL;
    return res;
}

hl_result hl_relighter_run_into(hl_relighter *r, const hl_relight_desc *desc, void *cl_out, int gl,
                                hl_relight_stats *stats)
{
    if (!cl_out) return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "no colour buffer given");
    return run(r, desc, NULL, cl_out, gl, stats);
}

struct hl_cl_light *hl_relighter_device(hl_relighter *r) { return r ? r->cl : NULL; }
const hl_light_geom *hl_relighter_tables(const hl_relighter *r) { return r ? r->lg : NULL; }
