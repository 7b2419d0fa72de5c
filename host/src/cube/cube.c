/* cube.c - Haar wavelets over the six faces of a cube: the transform and
 * its inverse, the transport regrouped from the visibility cube, and the
 * environment taps of each face texel (cube.h).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cube.h"
#include "sh.h"
#include "twins.h"

/* Rays per cell when sharing a cell among the texels it overlaps: as the
 * paraboloid's taps (light_tables.c), so both bases see the environment
 * through quadratures of the same density. */
#define HL_CUBE_CELL_RAYS 16
/* Room for the texels one cell overlaps (at most 9 up to Cq = 2 N). */
#define HL_CUBE_CELL_TEXELS 64
/* Omega of [0, u] x [0, v] on a face at distance 1 (signed). */
static double face_F(double u, double v) { return atan(u * v / sqrt(1.0 + u * u + v * v)); }

double hl_cube_rect_omega(double u0, double u1, double v0, double v1)
{
    return face_F(u1, v1) - face_F(u0, v1) - face_F(u1, v0) + face_F(u0, v0);
}

void hl_cube_haar(uint32_t Cq, float *T, float *coef)
{
    for (int f = 0; f < 6; f++)
        hl_ref_haar_square(T + (size_t)f * Cq * Cq, coef + (size_t)f * Cq * Cq, NULL, Cq); /* Mallat layout */
}

void hl_cube_haar_inverse(uint32_t Cq, float *coef, float *T)
{
    for (int f = 0; f < 6; f++) {
        const float *o = coef + (size_t)f * Cq * Cq;
        float *x = T + (size_t)f * Cq * Cq;
        x[0] = o[0];
        for (uint32_t s = 2; s <= Cq; s *= 2) {
            const uint32_t h = s / 2;
            /* backwards, so that a block's four outputs never land on an
               average another block has still to read */
            for (uint32_t i = h; i-- > 0;)
                for (uint32_t j = h; j-- > 0;) {
                    const float A = x[i * Cq + j], H = o[i * Cq + j + h], V = o[(i + h) * Cq + j],
                                D = o[(i + h) * Cq + j + h];
                    x[(2 * i) * Cq + 2 * j] = (A + H + V + D) * 0.5f;
                    x[(2 * i) * Cq + 2 * j + 1] = (A - H + V - D) * 0.5f;
                    x[(2 * i + 1) * Cq + 2 * j] = (A + H - V - D) * 0.5f;
                    x[(2 * i + 1) * Cq + 2 * j + 1] = (A - H - V + D) * 0.5f;
                }
        }
    }
}

void hl_cube_rows(const hl_geom *g, uint32_t Cq, const uint8_t *vis, float scale, const float n[3], float *T)
{
    const uint32_t C = g->C, r = C / Cq;
    memset(T, 0, (size_t)6 * Cq * Cq * sizeof *T);
    for (uint32_t c = 0; c < g->ncube; c++) {
        const uint32_t v = vis[c];
        if (!v) continue;
        const uint32_t f = c / (C * C), row = (c / C) % C, col = c % C;
        float acc = 0.0f;
        for (uint32_t e = g->p2c_start[c]; e < g->p2c_start[c + 1]; e++) {
            const hl_c2p_entry *m = &g->p2c[e];
            const float w = n[0] * m->mx + n[1] * m->my + n[2] * m->mz;
            if (w > 0.0f) acc += (float)v * w;
        }
        T[(size_t)f * Cq * Cq + (row / r) * Cq + col / r] += acc;
    }
    for (uint32_t q = 0; q < 6 * Cq * Cq; q++) T[q] *= scale;
}

hl_result hl_cube_quad_create(hl_context *ctx, uint32_t C, uint32_t Q, hl_cube_quad **out)
{
    *out = NULL;
    if (C < 1 || C > 512 || Q < 1 || Q > HL_SH_MAX_QUAD)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "cube quadrature: side %u, %u points (1 to %u)", C, Q, HL_SH_MAX_QUAD);
    hl_cube_quad *cq = hl_calloc(ctx, 1, sizeof *cq, "the cube quadrature");
    if (!cq) return HL_ERR_OUT_OF_MEMORY;
    cq->C = C, cq->Q = Q;
    cq->m = hl_alloc_big(ctx, (size_t)6 * C * C * Q * Q * 3 * sizeof(float), "the cube quadrature");
    if (!cq->m) {
        free(cq);
        return HL_ERR_OUT_OF_MEMORY;
    }
    double x[HL_SH_MAX_QUAD], w[HL_SH_MAX_QUAD];
    hl_sh_gauss(Q, x, w);
    const double h = 2.0 / C;
    float *o = cq->m;
    for (uint32_t c = 0; c < 6 * C * C; c++) {
        const uint32_t f = c / (C * C), row = (c / C) % C, col = c % C;
        for (uint32_t a = 0; a < Q; a++)
            for (uint32_t b = 0; b < Q; b++) {
                const double u = -1.0 + h * (col + 0.5 + 0.5 * x[b]), v = -1.0 + h * (row + 0.5 + 0.5 * x[a]);
                const double r2 = 1.0 + u * u + v * v, dw = 0.25 * h * h * w[a] * w[b] / (r2 * sqrt(r2));
                float d[3];
                hl_cube_face_dir((int)f, (float)u, (float)v, d);
                const double len = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
                for (int k = 0; k < 3; k++) *o++ = (float)(d[k] / len * dw);
            }
    }
    *out = cq;
    return HL_OK;
}

void hl_cube_quad_destroy(hl_cube_quad *q)
{
    if (!q) return;
    hl_free_big(q->m);
    free(q);
}

void hl_cube_rows_exact(const hl_cube_quad *cq, uint32_t Cq, const uint8_t *vis, float scale, const float n[3],
                        float *T)
{
    const uint32_t C = cq->C, r = C / Cq, P = cq->Q * cq->Q;
    memset(T, 0, (size_t)6 * Cq * Cq * sizeof *T);
    for (uint32_t c = 0; c < 6 * C * C; c++) {
        const uint32_t v = vis[c];
        if (!v) continue;
        const uint32_t f = c / (C * C), row = (c / C) % C, col = c % C;
        const float *m = cq->m + (size_t)c * P * 3;
        float acc = 0.0f;
        for (uint32_t p = 0; p < P; p++) {
            const float w = n[0] * m[3 * p] + n[1] * m[3 * p + 1] + n[2] * m[3 * p + 2];
            if (w > 0.0f) acc += w;
        }
        T[(size_t)f * Cq * Cq + (row / r) * Cq + col / r] += (float)v * acc;
    }
    for (uint32_t q = 0; q < 6 * Cq * Cq; q++) T[q] *= scale;
}

void hl_cube_lighting(const hl_cube_tables *ct, const float *cells, float *L)
{
    hl_ref_env2para(cells, ct->wc, ct->tap_start, ct->taps, 0, 0.0f, ct->ntex, L);
}

/* ---------------------------------------------------------------- taps */

/* The parts of one cell, texel by texel. */
typedef struct cell_parts {
    uint32_t tex[HL_CUBE_CELL_TEXELS];
    double w[HL_CUBE_CELL_TEXELS];
    int n, over;
} cell_parts;

static void credit(cell_parts *p, uint32_t q, double w)
{
    int e = 0;
    while (e < p->n && p->tex[e] != q) e++;
    if (e == p->n) {
        if (p->n == HL_CUBE_CELL_TEXELS) { p->over = 1; return; }
        p->tex[p->n] = q, p->w[p->n++] = 0.0;
    }
    p->w[e] += w;
}

/* The texel of the direction at polar angle th (from +Y) and azimuth
 * (cos, sin) = (cp, sp), the equirectangular map's. */
static uint32_t texel_at(uint32_t Cq, double th, double cp, double sp)
{
    const float d[3] = {(float)(sin(th) * cp), (float)cos(th), (float)(sin(th) * sp)};
    return hl_dir_to_cube(d, Cq);
}

/* Adds to th[] the polar angles in (th0, th1) where a meridian crosses the
 * lines u = -1 + 2k / Cq of the faces' grids, in closed form: on the side
 * faces the coordinate along the meridian is cot(th) over |cos phi| or
 * |sin phi| (the other one is constant: those lines are meridians), on the
 * +-Y faces it is |tan th| times cos phi or sin phi. The faces' own edges
 * are grid lines (k = 0, Cq), so a stretch between two of these angles
 * lies in one texel. th0 and th1 on the same side of the horizon. */
static int crossings(uint32_t Cq, double th0, double th1, double cp, double sp, double *th, int n)
{
    const double a[2] = {fabs(cp), fabs(sp)}, half = 0.5 * HL_PI;
    const int upper = th1 <= half;
    for (int q = 0; q < 2; q++) {
        if (a[q] <= 0.0) continue;
        /* side faces: cot(th) = u a, cot falling from cot th0 to cot th1 */
        const double c0 = th0 > 0.0 ? cos(th0) / sin(th0) : INFINITY, c1 = th1 < HL_PI ? cos(th1) / sin(th1) : -INFINITY;
        double k0 = ceil(0.5 * Cq * (c1 / a[q] + 1.0)), k1 = floor(0.5 * Cq * (c0 / a[q] + 1.0));
        for (double k = fmax(k0, 0.0); k <= fmin(k1, (double)Cq); k++) {
            const double t = atan2(1.0, (-1.0 + 2.0 * k / Cq) * a[q]);
            if (t > th0 && t < th1) th[n++] = t;
        }
        /* +-Y faces: |tan th| = u / a for u > 0, growing with th above the
           horizon and falling below it */
        const double e0 = upper ? th0 : HL_PI - th1, e1 = upper ? th1 : HL_PI - th0; /* angles from the pole */
        k0 = ceil(0.5 * Cq * (tan(e0) * a[q] + 1.0)), k1 = e1 < half ? floor(0.5 * Cq * (tan(e1) * a[q] + 1.0)) : Cq;
        for (double k = fmax(k0, 0.5 * Cq + 1.0); k <= fmin(k1, (double)Cq); k++) {
            const double e = atan((-1.0 + 2.0 * k / Cq) / a[q]), t = upper ? e : HL_PI - e;
            if (t > th0 && t < th1) th[n++] = t;
        }
    }
    return n;
}

static int by_value(const void *pa, const void *pb)
{
    const double a = *(const double *)pa, b = *(const double *)pb;
    return a < b ? -1 : a > b;
}

typedef struct tap_triple { uint32_t texel, cell; double w; } tap_triple;

/* The rays of each column of cells, in azimuth: the column is first cut
 * where the side faces' grid lines cross it (they are meridians: on +-X
 * tan(phi) = z / x is -+ the face coordinate, on +-Z cot(phi) is), so that
 * these lines are exact; each piece then gets rays at the middles of equal
 * steps, HL_CUBE_CELL_RAYS to a whole cell. Only the +-Y faces' lines and
 * the edges between those faces and the sides fall between rays. ray[3 i
 * .. 3 i + 2] = cos phi, sin phi, step; start: wc + 1 offsets. */
static hl_result column_rays(hl_context *ctx, uint32_t Cq, uint32_t wc, double **ray_out, uint32_t **start_out)
{
    const uint32_t nb = 5 * (Cq + 1), R = HL_CUBE_CELL_RAYS;
    double *br = hl_malloc(ctx, (size_t)nb * sizeof(double), "cube environment taps");
    double *ray = hl_malloc(ctx, ((size_t)wc * R + nb) * 3 * sizeof(double), "cube environment taps");
    uint32_t *start = hl_malloc(ctx, ((size_t)wc + 1) * 4, "cube environment taps");
    if (!br || !ray || !start) {
        free(br), free(ray), free(start);
        return HL_ERR_OUT_OF_MEMORY;
    }
    /* every grid line's azimuths about [-pi, pi): tan phi = u and cot phi = u */
    for (uint32_t k = 0; k <= Cq; k++) {
        const double u = -1.0 + 2.0 * k / Cq, t = atan(u), c = atan2(1.0, u);
        double *o = br + 5 * k;
        o[0] = t, o[1] = t - HL_PI, o[2] = t + HL_PI, o[3] = c, o[4] = c - HL_PI;
    }
    qsort(br, nb, sizeof *br, by_value);
    const double W = 2.0 * HL_PI / wc;
    uint32_t n = 0, b = 0;
    for (uint32_t k = 0; k < wc; k++) {
        const double p0 = -HL_PI + k * W, p1 = p0 + W;
        start[k] = n;
        double a = p0;
        while (b < nb && br[b] <= p0) b++;
        for (;;) {
            const double e = b < nb && br[b] < p1 ? br[b] : p1;
            if (e > a) {
                const uint32_t m = (uint32_t)ceil(R * (e - a) / W - 1e-9);
                for (uint32_t i = 0; i < (m ? m : 1); i++) {
                    const double phi = a + (i + 0.5) * (e - a) / (m ? m : 1);
                    ray[3 * n] = cos(phi), ray[3 * n + 1] = sin(phi), ray[3 * n + 2] = (e - a) / (m ? m : 1);
                    n++;
                }
            }
            if (e >= p1) break;
            a = e, b++;
        }
    }
    start[wc] = n;
    free(br);
    *ray_out = ray, *start_out = start;
    return HL_OK;
}

/* Each cell split among the texels it overlaps by rays in azimuth
 * (column_rays), each cut where it crosses the grid lines (crossings):
 * a cell's parts add up to its solid angle exactly, a texel's to its own
 * within the quadrature in azimuth. The taps are the parts over the
 * texel's total, so a texel holds its mean radiance. */
static hl_result build_taps(hl_context *ctx, hl_cube_tables *ct)
{
    const uint32_t wc = ct->wc, hc = ct->hc, Cq = ct->Cq;
    size_t cap = (size_t)wc * hc * 2 + ct->ntex, n = 0;
    tap_triple *tr = hl_malloc(ctx, cap * sizeof *tr, "cube environment taps");
    uint32_t *count = hl_calloc(ctx, (size_t)ct->ntex + 1, 4, "cube environment taps"), *rs = NULL;
    double *ray = NULL;
    hl_result r = HL_OK;
    if (!tr || !count) r = HL_ERR_OUT_OF_MEMORY;
    if (r == HL_OK) r = column_rays(ctx, Cq, wc, &ray, &rs);
    for (uint32_t row = 0; row < hc && r == HL_OK; row++) {
        const double th0 = HL_PI * row / hc, th1 = HL_PI * (row + 1) / hc;
        for (uint32_t k = 0; k < wc && r == HL_OK; k++) {
            cell_parts p;
            p.n = p.over = 0;
            for (uint32_t i = rs[k]; i < rs[k + 1]; i++) {
                const double cp = ray[3 * i], sp = ray[3 * i + 1], dphi = ray[3 * i + 2];
                /* the stretches between crossings, each in one texel:
                   its solid angle (cos a - cos b) dphi, exactly */
                double th[4 * 514 + 2];
                int nt = crossings(Cq, th0, th1, cp, sp, th + 1, 0) + 2;
                th[0] = th0, th[nt - 1] = th1;
                qsort(th + 1, (size_t)nt - 2, sizeof *th, by_value);
                for (int e = 0; e + 1 < nt; e++)
                    if (th[e + 1] > th[e])
                        credit(&p, texel_at(Cq, 0.5 * (th[e] + th[e + 1]), cp, sp), (cos(th[e]) - cos(th[e + 1])) * dphi);
            }
            if (p.over) {
                r = hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                            "cube side %u: an environment cell of a %u x %u grid meets more than %d texels", Cq, wc, hc,
                            HL_CUBE_CELL_TEXELS);
                break;
            }
            for (int e = 0; e < p.n; e++) {
                if (n == cap) {
                    cap *= 2;
                    tap_triple *np = realloc(tr, cap * sizeof *np);
                    if (!np) { r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for cube environment taps"); break; }
                    tr = np;
                }
                tr[n++] = (tap_triple){p.tex[e], row * wc + k, p.w[e]};
                ct->tap_total[p.tex[e]] += p.w[e];
                count[p.tex[e] + 1]++;
            }
        }
    }
    free(ray);
    free(rs);
    /* a texel no ray crossed (far finer than the cells) takes the cell of
       its centre direction */
    for (uint32_t q = 0; q < ct->ntex && r == HL_OK; q++) {
        if (ct->tap_total[q] > 0.0) continue;
        const uint32_t f = q / (Cq * Cq), row = (q / Cq) % Cq, col = q % Cq;
        float d[3];
        hl_cube_face_dir((int)f, 2.0f * ((float)col + 0.5f) / (float)Cq - 1.0f, 2.0f * ((float)row + 0.5f) / (float)Cq - 1.0f, d);
        const double len = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
        const double u = 0.5 + atan2(d[2], d[0]) / (2.0 * HL_PI), v = acos(d[1] / len) / HL_PI;
        uint32_t ck = (uint32_t)floor(u * wc) % wc, cr = (uint32_t)floor(v * hc);
        if (cr >= hc) cr = hc - 1;
        if (n == cap) {
            tap_triple *np = realloc(tr, (cap + ct->ntex) * sizeof *np);
            if (!np) { r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for cube environment taps"); break; }
            tr = np, cap += ct->ntex;
        }
        tr[n++] = (tap_triple){q, cr * wc + ck, 1.0};
        count[q + 1]++;
    }
    if (r == HL_OK) {
        for (uint32_t q = 0; q < ct->ntex; q++) count[q + 1] += count[q];
        ct->taps = hl_malloc(ctx, (n ? n : 1) * sizeof *ct->taps, "cube environment taps");
        if (!ct->taps) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r == HL_OK) {
        memcpy(ct->tap_start, count, ((size_t)ct->ntex + 1) * 4);
        /* counting sort by texel keeps cell order within a texel */
        for (size_t i = 0; i < n; i++) {
            const uint32_t q = tr[i].texel;
            const double tot = ct->tap_total[q] > 0.0 ? ct->tap_total[q] : 1.0;
            ct->taps[count[q]++] = (hl_env_tap){tr[i].cell / wc, tr[i].cell % wc, (float)(tr[i].w / tot), 0u};
        }
        ct->ntaps = (uint32_t)n;
    }
    free(tr);
    free(count);
    return r;
}

void hl_cube_lighting_haar(const hl_cube_tables *ct, const float *cells, uint32_t s0, float f, uint32_t ncoef,
                           float *Lp, float *Lw)
{
    const uint32_t nt = ct->ntex;
    hl_ref_env2para(cells, ct->wc, ct->tap_start, ct->taps, s0, f, nt, Lp);
    for (int c = 0; c < 3; c++) {
        float *w = Lw + (size_t)c * ncoef;
        hl_cube_haar(ct->Cq, Lp + (size_t)c * nt, w);
        memset(w + nt, 0, (size_t)(ncoef - nt) * sizeof *w);
    }
}

uint32_t hl_cube_default_side(uint32_t N, uint32_t C)
{
    uint32_t q = N / 2;
    while (q >= 2 && C % q) q /= 2;
    return q >= 2 ? q : 0;
}

void hl_cube_support_areas(uint32_t Cq, float *area)
{
    const double h = 2.0 / Cq;
    for (uint32_t q = 0; q < 6 * Cq * Cq; q++) {
        uint32_t r0, c0, w;
        hl_geom_support(Cq, (q / Cq) % Cq, q % Cq, &r0, &c0, &w);
        area[q] = (float)hl_cube_rect_omega(-1.0 + c0 * h, -1.0 + (c0 + w) * h, -1.0 + r0 * h, -1.0 + (r0 + w) * h);
    }
}

hl_result hl_cube_tables_create(hl_context *ctx, uint32_t Cq, uint32_t C, uint32_t wc, uint32_t hc,
                                hl_cube_tables **out)
{
    *out = NULL;
    if (Cq < 2 || Cq > 512 || (Cq & (Cq - 1)) || C % Cq)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "cube side %u: expected a power of two from 2 to 512 that divides the visibility cube's side %u",
                       Cq, C);
    if (wc < 4 || hc < 2)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "cube tables: a %u x %u cell grid", wc, hc);
    hl_cube_tables *ct = hl_calloc(ctx, 1, sizeof *ct, "the cube tables");
    if (!ct) return HL_ERR_OUT_OF_MEMORY;
    ct->Cq = Cq, ct->C = C, ct->ntex = 6 * Cq * Cq, ct->wc = wc, ct->hc = hc;
    ct->omega = hl_malloc(ctx, (size_t)ct->ntex * sizeof(double), "the cube tables");
    ct->area = hl_malloc(ctx, (size_t)ct->ntex * sizeof(float), "the cube tables");
    ct->tap_start = hl_malloc(ctx, ((size_t)ct->ntex + 1) * 4, "the cube tables");
    ct->tap_total = hl_calloc(ctx, ct->ntex, sizeof(double), "the cube tables");
    hl_result r = ct->omega && ct->area && ct->tap_start && ct->tap_total ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    const double h = 2.0 / Cq;
    for (uint32_t q = 0; q < ct->ntex && r == HL_OK; q++) {
        const uint32_t row = (q / Cq) % Cq, col = q % Cq;
        ct->omega[q] = hl_cube_rect_omega(-1.0 + col * h, -1.0 + (col + 1) * h, -1.0 + row * h, -1.0 + (row + 1) * h);
    }
    if (r == HL_OK) hl_cube_support_areas(Cq, ct->area);
    if (r == HL_OK) r = build_taps(ctx, ct);
    if (r != HL_OK) {
        hl_cube_tables_destroy(ct);
        return r;
    }
    *out = ct;
    return HL_OK;
}

void hl_cube_tables_destroy(hl_cube_tables *ct)
{
    if (!ct) return;
    free(ct->omega);
    free(ct->area);
    free(ct->tap_start);
    free(ct->taps);
    free(ct->tap_total);
    free(ct);
}
