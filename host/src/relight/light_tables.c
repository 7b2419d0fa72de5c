/* light_tables.c - the lighting tables of a paraboloid resolution: the
 * environment resampled onto cells, each paraboloid texel's runs of cells
 * (taps), and the solid angle of each wavelet's support.
 *
 * An environment is resampled once onto a cell grid of 8N x 4N cells (area
 * weighted, so no light is lost whatever its resolution). Each paraboloid
 * texel takes the cells that overlap it at rotation 0, each weighted by its
 * share of the texel's solid angle (taps); a rotation about +Y is then an
 * offset along the cell rows.
 * Depends on: lighting.h, geom.h (the paraboloid maps), core, libm.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lighting.h"

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
