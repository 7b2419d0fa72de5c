/* shadow_raster.c - twin of kernels/dynamic/shadow_raster.cl: the same
 * float operations in the same order (contraction off), one map, a plain
 * float minimum instead of atomic_min on the bit patterns: the depths are
 * non-negative and never -0, so both orders agree and equal depths have
 * equal bits. The coverage
 * rule (top-left, edges evaluated from their lexicographically smaller
 * end) is described in the kernel. Depends on: shadow_map.h.
 */
#include <math.h> /* ceilf, floorf */
#include <string.h>

#include "shadow_map.h"

typedef struct tv { float x, y, z; } tv;

static tv raster_vertex(const float *pos, uint32_t v, const float *xf, const float *fr)
{
    float px = pos[3 * (size_t)v], py = pos[3 * (size_t)v + 1], pz = pos[3 * (size_t)v + 2];
    float wx = xf[0] * px + xf[1] * py + xf[2] * pz + xf[3];
    float wy = xf[4] * px + xf[5] * py + xf[6] * pz + xf[7];
    float wz = xf[8] * px + xf[9] * py + xf[10] * pz + xf[11];
    float qx = wx - fr[0], qy = wy - fr[1], qz = wz - fr[2];
    tv o;
    o.x = (qx * fr[3] + qy * fr[4] + qz * fr[5]) * fr[12];
    o.y = (qx * fr[6] + qy * fr[7] + qz * fr[8]) * fr[13];
    o.z = (qx * fr[9] + qy * fr[10] + qz * fr[11]) * fr[14];
    return o;
}

/* Edge u -> v set up once per triangle: evaluated from its
 * lexicographically smaller end s, E = ex (py - sy) - ey (px - sx),
 * negated when u is not that end; tl: the edge is top-left. */
typedef struct edge { float sx, sy, ex, ey; int flip, tl; } edge;

static edge raster_edge_setup(tv u, tv v)
{
    edge g;
    g.flip = v.x < u.x || (v.x == u.x && v.y < u.y);
    tv s = g.flip ? v : u, e = g.flip ? u : v;
    g.sx = s.x;
    g.sy = s.y;
    g.ex = e.x - s.x;
    g.ey = e.y - s.y;
    float dx = v.x - u.x, dy = v.y - u.y;
    g.tl = dy < 0.0f || (dy == 0.0f && dx < 0.0f);
    return g;
}

/* E at column centre px given the row's term ex (py - sy); inside: E > 0,
 * or E == 0 on a top-left edge. */
static int raster_edge_at(const edge *g, float row, float px, float *E)
{
    float e = row - g->ey * (px - g->sx);
    e = g->flip ? -e : e;
    *E = e;
    return e > 0.0f || (e == 0.0f && g->tl);
}

static float min3(float a, float b, float c) { float m = a < b ? a : b; return m < c ? m : c; }
static float max3(float a, float b, float c) { float m = a > b ? a : b; return m > c ? m : c; }

static void raster_span(float lo, float hi, uint32_t R, int *first, int *last)
{
    float f = ceilf(lo - 0.5f), l = floorf(hi - 0.5f);
    f = f > 0.0f ? f : 0.0f;
    f = f < (float)R ? f : (float)R;
    l = l > -1.0f ? l : -1.0f;
    l = l < (float)R - 1.0f ? l : (float)R - 1.0f;
    *first = (int)f;
    *last = (int)l;
}

void hl_ref_shadow_raster(const float *pos, const uint32_t *tri, uint32_t t0, uint32_t t1, const float *xf,
                          const float *fr, uint32_t R, float *map)
{
    uint32_t skip;
    memcpy(&skip, &fr[15], 4);
    for (uint32_t t = t0; t < t1; t++) {
        const uint32_t *f = tri + 4 * (size_t)t;
        if (f[3] < 32u && (skip >> f[3] & 1u)) continue;
        const float *x = xf + 12 * (size_t)f[3];
        tv a = raster_vertex(pos, f[0], x, fr), b = raster_vertex(pos, f[1], x, fr), c = raster_vertex(pos, f[2], x, fr);
        float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if (!(area != 0.0f)) continue;
        if (area < 0.0f) { tv s = b; b = c; c = s; }
        int i0, i1, j0, j1;
        raster_span(min3(a.x, b.x, c.x), max3(a.x, b.x, c.x), R, &i0, &i1);
        raster_span(min3(a.y, b.y, c.y), max3(a.y, b.y, c.y), R, &j0, &j1);
        edge ga = raster_edge_setup(b, c), gb = raster_edge_setup(c, a), gc = raster_edge_setup(a, b);
        for (int j = j0; j <= j1; j++) {
            float py = (float)j + 0.5f;
            float ra = ga.ex * (py - ga.sy), rb = gb.ex * (py - gb.sy), rc = gc.ex * (py - gc.sy);
            for (int i = i0; i <= i1; i++) {
                float px = (float)i + 0.5f, ea, eb, ec;
                if (!raster_edge_at(&ga, ra, px, &ea) || !raster_edge_at(&gb, rb, px, &eb) || !raster_edge_at(&gc, rc, px, &ec))
                    continue;
                float sum = ea + eb + ec;
                float d = sum > 0.0f ? (ea * a.z + eb * b.z + ec * c.z) / sum : min3(a.z, b.z, c.z);
                d = d > 0.0f ? d : 0.0f;
                d = d < 1.0f ? d : 1.0f;
                float *m = map + (size_t)j * R + (size_t)i;
                if (d < *m) *m = d;
            }
        }
    }
}
