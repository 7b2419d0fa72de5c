/* capture_probes.c - where to capture near surroundings from: capture
 * points (probes) placed over the transport's vertices, more of them where
 * an emitter is near, and each vertex's weights over them.
 *
 * One capture point sees an emitter in one direction and solid angle; a
 * vertex at distance r from it, with the emitter at distance d, sees it up
 * to asin(r / d) radians away and at a distance off by up to a factor
 * 1 -+ r / d (the parallax, docs/CAPTURE.md). The vertices are split as a k-d tree (the cell with
 * the largest bound first, at the middle of its box's longest side) until
 * every cell's bound is within the tolerance or the budget is spent; each
 * cell's probe is its box's centre. A vertex's colour is then the blend
 * of the relights under each probe's capture, with weights that depend on
 * its distance to each probe only (so they vary continuously over the
 * mesh, with no seam where cells meet).
 * Depends on: capture.h (hl_capture_scene), core (errors, allocation).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"

/* A probe's weight reaches 0 at this many times its cell's half-diagonal:
 * past 1 so that neighbouring cells overlap and the blend is smooth;
 * every vertex lies within 1 of its own cell's probe, so it always has
 * one weight of at least (1 - 1 / 1.5^2)^2 = 0.31. */
#define HL_PROBE_REACH 1.5

typedef struct probe_cell {
    uint32_t a, b;    /* its vertices: idx[a .. b) */
    double lo[3], hi[3];
    double ratio;     /* the parallax bound of its probe, radians */
    double priority;  /* which cell is split first */
    int leaf_only;    /* cannot be split (one point) */
} probe_cell;

void hl_probe_set_free(hl_probe_set *p)
{
    if (!p) return;
    free(p->points);
    free(p->radius);
    free(p->start);
    free(p->vert);
    free(p->weight);
    memset(p, 0, sizeof *p);
}

/* Squared distance from p to the triangle (a, b, c), by the region of the
 * closest point (vertex, edge or face), in double. */
static double point_triangle_d2(const double p[3], const float *t)
{
    double a[3], ab[3], ac[3], ap[3];
    for (int k = 0; k < 3; k++) {
        a[k] = t[k];
        ab[k] = (double)t[3 + k] - t[k];
        ac[k] = (double)t[6 + k] - t[k];
        ap[k] = p[k] - a[k];
    }
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double q[3];
    const double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    double s = 0.0, u = 0.0;
    if (d1 <= 0.0 && d2 <= 0.0) {
        s = 0.0, u = 0.0;
    } else {
        double bp[3], cp[3];
        for (int k = 0; k < 3; k++) bp[k] = ap[k] - ab[k], cp[k] = ap[k] - ac[k];
        const double d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
        const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0.0 && d4 <= d3) s = 1.0, u = 0.0;
        else if (d6 >= 0.0 && d5 <= d6) s = 0.0, u = 1.0;
        else if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) s = d1 / (d1 - d3), u = 0.0;
        else if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) s = 0.0, u = d2 / (d2 - d6);
        else if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
            const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            s = 1.0 - w, u = w;
        } else {
            const double den = va + vb + vc;
            s = den > 0.0 ? vb / den : 0.0, u = den > 0.0 ? vc / den : 0.0;
        }
    }
    for (int k = 0; k < 3; k++) q[k] = a[k] + s * ab[k] + u * ac[k] - p[k];
    return DOT(q, q);
#undef DOT
}

double hl_probe_nearest_emitter(const hl_capture_scene *s, const double p[3])
{
    double best = INFINITY;
    for (uint32_t i = 0; i < s->triangle_count; i++) {
        const float *e = s->emission + 3 * (size_t)i, *t = s->positions + 9 * (size_t)i;
        if (!(e[0] > 0.0f || e[1] > 0.0f || e[2] > 0.0f)) continue;
        /* its bounding sphere first: most triangles are farther than the
           nearest found so far */
        double c[3], r2 = 0.0, d2c = 0.0;
        for (int k = 0; k < 3; k++) c[k] = ((double)t[k] + t[3 + k] + t[6 + k]) / 3.0;
        for (int v = 0; v < 3; v++) {
            double q = 0.0;
            for (int k = 0; k < 3; k++) q += (t[3 * v + k] - c[k]) * (t[3 * v + k] - c[k]);
            r2 = q > r2 ? q : r2;
        }
        for (int k = 0; k < 3; k++) d2c += (p[k] - c[k]) * (p[k] - c[k]);
        const double lower = sqrt(d2c) - sqrt(r2);
        if (lower >= best) continue;
        const double d = sqrt(point_triangle_d2(p, t));
        best = d < best ? d : best;
    }
    return best;
}

/* The bound of a probe at p serving points within rho of it (and the
 * nearest emitter's distance): an emitter point e at least d from p is
 * seen from x, |x - p| <= rho, at most asin(rho / d) away from where p
 * sees it (the angle at e of the triangle p x e), and its distance is
 * off by a factor within 1 -+ rho / d. With d <= rho any direction may
 * differ: pi / 2, the bound's largest value. */
static double parallax_bound(const hl_capture_scene *s, const double p[3], double rho, double *dist)
{
    const double d = hl_probe_nearest_emitter(s, p);
    if (dist) *dist = d;
    if (!isfinite(d)) return 0.0; /* nothing emits: no parallax to see */
    return d > rho ? asin(rho / d) : 0.5 * HL_PI;
}

static void cell_box(probe_cell *c, const float *pos, const uint32_t *idx)
{
    for (int k = 0; k < 3; k++) c->lo[k] = INFINITY, c->hi[k] = -INFINITY;
    for (uint32_t i = c->a; i < c->b; i++)
        for (int k = 0; k < 3; k++) {
            const double x = pos[3 * (size_t)idx[i] + k];
            c->lo[k] = x < c->lo[k] ? x : c->lo[k];
            c->hi[k] = x > c->hi[k] ? x : c->hi[k];
        }
}

static void cell_centre(const probe_cell *c, double p[3], double *rho)
{
    double r2 = 0.0;
    for (int k = 0; k < 3; k++) {
        p[k] = 0.5 * (c->lo[k] + c->hi[k]);
        r2 += 0.25 * (c->hi[k] - c->lo[k]) * (c->hi[k] - c->lo[k]);
    }
    *rho = sqrt(r2);
}

static void cell_measure(probe_cell *c, const float *pos, const uint32_t *idx, const hl_capture_scene *s)
{
    cell_box(c, pos, idx);
    double p[3], rho;
    cell_centre(c, p, &rho);
    double d;
    c->ratio = parallax_bound(s, p, rho, &d);
    /* rho / d, which the bound grows with, also past d <= rho (where the
       bound stops at pi / 2), so that such cells are split larger first
       (weighting it by the emitter's 1 / d^2 instead spent the points
       near the lamp and measured worse: docs/CAPTURE.md) */
    c->priority = !isfinite(d) ? 0.0 : rho / fmax(d, 1e-3 * rho);
    c->leaf_only = c->b - c->a < 2 || rho == 0.0;
}

/* Splits c at the middle of its box's longest side into c and *d; 0 when
 * every vertex falls on one side (a box one float wide). */
static int cell_split(probe_cell *c, probe_cell *d, uint32_t *idx, const float *pos)
{
    int ax = 0;
    for (int k = 1; k < 3; k++)
        if (c->hi[k] - c->lo[k] > c->hi[ax] - c->lo[ax]) ax = k;
    const double mid = 0.5 * (c->lo[ax] + c->hi[ax]);
    uint32_t i = c->a, j = c->b;
    while (i < j) {
        if (pos[3 * (size_t)idx[i] + ax] < mid) i++;
        else {
            const uint32_t t = idx[i];
            idx[i] = idx[--j];
            idx[j] = t;
        }
    }
    if (i == c->a || i == c->b) return 0;
    *d = *c;
    d->a = i;
    c->b = i;
    return 1;
}

/* Probe k's weight at x before normalising: (1 - u^2)^2 with u the
 * distance over its reach, 0 past it. */
static double probe_weight(const hl_probe_set *ps, uint32_t k, const float *x)
{
    const float *p = ps->points + 3 * (size_t)k;
    double d2 = 0.0;
    for (int a = 0; a < 3; a++) d2 += ((double)x[a] - p[a]) * ((double)x[a] - p[a]);
    const double reach = HL_PROBE_REACH * ps->radius[k], u2 = d2 / (reach * reach);
    return u2 < 1.0 ? (1.0 - u2) * (1.0 - u2) : 0.0;
}

/* One point, the relighter's own capture point as without probes, and
 * its bound; nothing to weigh. */
static hl_result one_point(hl_context *ctx, const float centre[3], hl_probe_set *out)
{
    out->count = 1;
    out->points = hl_malloc(ctx, 12, "the probes");
    if (!out->points) return HL_ERR_OUT_OF_MEMORY;
    memcpy(out->points, centre, 12);
    out->worst_ratio = out->single_ratio;
    return HL_OK;
}

double hl_probe_reach(const float *pos, uint32_t V, const float centre[3])
{
    double far2 = 0.0;
    for (uint32_t v = 0; v < V; v++) {
        double q = 0.0;
        for (int k = 0; k < 3; k++) q += (pos[3 * (size_t)v + k] - centre[k]) * (pos[3 * (size_t)v + k] - centre[k]);
        far2 = q > far2 ? q : far2;
    }
    return sqrt(far2);
}

hl_result hl_probe_set_build(hl_context *ctx, const float *pos, uint32_t V, const float centre[3], double reach,
                             const hl_capture_scene *s, uint32_t max_probes, double tol, hl_probe_set *out)
{
    memset(out, 0, sizeof *out);
    if (!V || !max_probes) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "probes: no vertices or no probes");
    /* the bound of the one capture point at the object's centre, as the
       relighter captures without probes: the farthest vertex from it */
    const double c0[3] = {centre[0], centre[1], centre[2]};
    out->single_ratio = parallax_bound(s, c0, reach >= 0.0 ? reach : hl_probe_reach(pos, V, centre), NULL);
    if (max_probes == 1) return one_point(ctx, centre, out);
    uint32_t *idx = hl_malloc(ctx, (size_t)V * 4, "the probes' vertex order");
    probe_cell *cell = hl_malloc(ctx, (size_t)max_probes * sizeof *cell, "the probes' cells");
    if (!idx || !cell) {
        free(idx);
        free(cell);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t v = 0; v < V; v++) idx[v] = v;
    uint32_t n = 1;
    cell[0] = (probe_cell){.a = 0, .b = V};
    cell_measure(&cell[0], pos, idx, s);
    for (;;) {
        uint32_t w = n;
        for (uint32_t k = 0; k < n; k++)
            if (!cell[k].leaf_only && (w == n || cell[k].priority > cell[w].priority)) w = k;
        if (w == n || n == max_probes || !(cell[w].ratio > tol)) break;
        if (!cell_split(&cell[w], &cell[n], idx, pos)) {
            cell[w].leaf_only = 1;
            continue;
        }
        cell_measure(&cell[w], pos, idx, s);
        cell_measure(&cell[n], pos, idx, s);
        n++;
    }
    free(idx);
    if (n == 1) {
        free(cell);
        return one_point(ctx, centre, out);
    }
    out->count = n;
    out->points = hl_malloc(ctx, (size_t)n * 12, "the probes");
    out->radius = hl_malloc(ctx, (size_t)n * 8, "the probes");
    out->start = hl_malloc(ctx, ((size_t)n + 1) * 4, "the probes' lists");
    hl_result res = out->points && out->radius && out->start ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    double root_rho = 0.0;
    for (uint32_t k = 0; k < n && res == HL_OK; k++) {
        double p[3], rho;
        cell_centre(&cell[k], p, &rho);
        for (int a = 0; a < 3; a++) out->points[3 * k + a] = (float)p[a];
        out->radius[k] = rho;
        root_rho = rho > root_rho ? rho : root_rho;
        out->worst_ratio = cell[k].ratio > out->worst_ratio ? cell[k].ratio : out->worst_ratio;
    }
    free(cell);
    /* a cell of one point has no extent: it reaches a little way */
    for (uint32_t k = 0; k < n && res == HL_OK; k++)
        if (!(out->radius[k] > 1e-6 * root_rho)) out->radius[k] = root_rho > 0.0 ? 1e-6 * root_rho : 1.0;
    /* the lists: counted, then filled with each vertex's weights over
       their sum */
    uint32_t *cnt = res == HL_OK ? calloc((size_t)n + 1, 4) : NULL;
    if (res == HL_OK && !cnt) res = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the probes' lists");
    for (uint32_t v = 0; v < V && res == HL_OK; v++)
        for (uint32_t k = 0; k < n; k++) cnt[k] += probe_weight(out, k, pos + 3 * (size_t)v) > 0.0;
    if (res == HL_OK) {
        out->start[0] = 0;
        for (uint32_t k = 0; k < n; k++) out->start[k + 1] = out->start[k] + cnt[k];
        out->vert = hl_malloc(ctx, (size_t)out->start[n] * 4 + 4, "the probes' lists");
        out->weight = hl_malloc(ctx, (size_t)out->start[n] * 4 + 4, "the probes' weights");
        if (!out->vert || !out->weight) res = HL_ERR_OUT_OF_MEMORY;
        else memset(cnt, 0, (size_t)n * 4);
    }
    for (uint32_t v = 0; v < V && res == HL_OK; v++) {
        const float *x = pos + 3 * (size_t)v;
        double sum = 0.0;
        for (uint32_t k = 0; k < n; k++) sum += probe_weight(out, k, x);
        for (uint32_t k = 0; k < n; k++) {
            const double w = probe_weight(out, k, x);
            if (!(w > 0.0)) continue;
            const uint32_t e = out->start[k] + cnt[k]++;
            out->vert[e] = v;
            out->weight[e] = (float)(w / sum);
        }
    }
    free(cnt);
    if (res != HL_OK) hl_probe_set_free(out);
    return res;
}
