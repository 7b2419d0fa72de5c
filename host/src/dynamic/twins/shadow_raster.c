/* shadow_raster.c - twin of kernels/dynamic/shadow_raster.cl: the same
 * float operations in the same order (contraction off), one map, a plain
 * float minimum instead of atomic_min on the bit patterns: the depths are
 * non-negative and never -0, so both orders agree and equal depths have
 * equal bits. The coverage
 * rule (top-left, edges evaluated from their lexicographically smaller
 * end) is described in the kernel. Depends on: shadow_map.h.
 */
#include <math.h>

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

static float raster_edge(tv u, tv v, float px, float py)
{
    int flip = v.x < u.x || (v.x == u.x && v.y < u.y);
    tv s = flip ? v : u, e = flip ? u : v;
    float E = (e.x - s.x) * (py - s.y) - (e.y - s.y) * (px - s.x);
    return flip ? -E : E;
}

static int raster_inside(float E, tv u, tv v)
{
    float dx = v.x - u.x, dy = v.y - u.y;
    return E > 0.0f || (E == 0.0f && (dy < 0.0f || (dy == 0.0f && dx < 0.0f)));
}

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
    for (uint32_t t = t0; t < t1; t++) {
        const uint32_t *f = tri + 4 * (size_t)t;
        const float *x = xf + 12 * (size_t)f[3];
        tv a = raster_vertex(pos, f[0], x, fr), b = raster_vertex(pos, f[1], x, fr), c = raster_vertex(pos, f[2], x, fr);
        float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if (!(area != 0.0f)) continue;
        if (area < 0.0f) { tv s = b; b = c; c = s; }
        int i0, i1, j0, j1;
        raster_span(fminf(a.x, fminf(b.x, c.x)), fmaxf(a.x, fmaxf(b.x, c.x)), R, &i0, &i1);
        raster_span(fminf(a.y, fminf(b.y, c.y)), fmaxf(a.y, fmaxf(b.y, c.y)), R, &j0, &j1);
        for (int j = j0; j <= j1; j++) {
            float py = (float)j + 0.5f;
            for (int i = i0; i <= i1; i++) {
                float px = (float)i + 0.5f;
                float ea = raster_edge(b, c, px, py), eb = raster_edge(c, a, px, py), ec = raster_edge(a, b, px, py);
                if (!raster_inside(ea, b, c) || !raster_inside(eb, c, a) || !raster_inside(ec, a, b)) continue;
                float sum = ea + eb + ec;
                float d = sum > 0.0f ? (ea * a.z + eb * b.z + ec * c.z) / sum : fminf(a.z, fminf(b.z, c.z));
                d = d > 0.0f ? d : 0.0f;
                d = d < 1.0f ? d : 1.0f;
                float *m = map + (size_t)j * R + (size_t)i;
                if (d < *m) *m = d;
            }
        }
    }
}
