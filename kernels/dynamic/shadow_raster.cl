/* shadow_raster.cl - orthographic depth maps of rigid objects, one per
 * distant light: the nearest normalised depth at every texel centre a
 * triangle covers. Twin: host/src/dynamic/twins/shadow_raster.c (the same
 * float operations in the same order, contraction off).
 *
 * One work-item takes `per` consecutive triangles for one map (dimension
 * 1 is the map). Each vertex is moved by its object's rigid transform and
 * then into the map's texel space here, so a rigid motion changes only 12
 * floats on the device. Depths are non-negative floats, which order like
 * their bit patterns as unsigned integers, so atomic_min on the bits keeps
 * the nearest; the caller fills the map with 1.0f (empty) first.
 *
 * Coverage: a texel centre p is covered when every edge function is
 * positive, or zero on a top-left edge (of the triangle made
 * counter-clockwise in texel space, x right, y up: an edge going down, or
 * a horizontal edge going left). Each edge function is evaluated from the
 * edge's lexicographically smaller end, so the two triangles sharing an
 * edge get exactly opposite values and a centre on it belongs to one.
 *
 * Frame layout (16 floats per map): origin[3], right[3], up[3],
 * toward_far[3], R / width, R / height, 1 / depth_range, and the bits of
 * the skip mask (objects 0..31 not drawn into this map: flat bodies that
 * cast no shadow for this light, shadow_map.h).
 */
#pragma OPENCL FP_CONTRACT OFF

/* Vertex v (3 floats at pos + 3 v) of an object with transform xf, in the
 * texel space of frame fr: (column, row, normalised depth). */
float4 hl_shadow_raster_vertex(global const float *pos, uint v, global const float *xf, global const float *fr)
{
    float px = pos[3 * (size_t)v], py = pos[3 * (size_t)v + 1], pz = pos[3 * (size_t)v + 2];
    float wx = xf[0] * px + xf[1] * py + xf[2] * pz + xf[3];
    float wy = xf[4] * px + xf[5] * py + xf[6] * pz + xf[7];
    float wz = xf[8] * px + xf[9] * py + xf[10] * pz + xf[11];
    float qx = wx - fr[0], qy = wy - fr[1], qz = wz - fr[2];
    float x = (qx * fr[3] + qy * fr[4] + qz * fr[5]) * fr[12];
    float y = (qx * fr[6] + qy * fr[7] + qz * fr[8]) * fr[13];
    float z = (qx * fr[9] + qy * fr[10] + qz * fr[11]) * fr[14];
    return (float4)(x, y, z, 0.0f);
}

/* Edge u -> v set up once per triangle: evaluated from its
 * lexicographically smaller end s, E = ex (py - sy) - ey (px - sx),
 * negated when u is not that end; tl: the edge is top-left. */
typedef struct hl_shadow_raster_edge_t { float sx, sy, ex, ey; int flip, tl; } hl_shadow_raster_edge_t;

hl_shadow_raster_edge_t hl_shadow_raster_edge_setup(float4 u, float4 v)
{
    hl_shadow_raster_edge_t g;
    g.flip = v.x < u.x || (v.x == u.x && v.y < u.y);
    float4 s = g.flip ? v : u, e = g.flip ? u : v;
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
int hl_shadow_raster_edge_at(const hl_shadow_raster_edge_t *g, float row, float px, float *E)
{
    float e = row - g->ey * (px - g->sx);
    e = g->flip ? -e : e;
    *E = e;
    return e > 0.0f || (e == 0.0f && g->tl);
}

float hl_shadow_raster_min3(float a, float b, float c) { float m = a < b ? a : b; return m < c ? m : c; }
float hl_shadow_raster_max3(float a, float b, float c) { float m = a > b ? a : b; return m > c ? m : c; }

/* The first and last texel index whose centre (i + 0.5) lies in [lo, hi],
 * clamped to the map (so the int conversions stay in range); *first >
 * *last when none. */
void hl_shadow_raster_span(float lo, float hi, uint R, int *first, int *last)
{
    float f = ceil(lo - 0.5f), l = floor(hi - 0.5f);
    f = f > 0.0f ? f : 0.0f;
    f = f < (float)R ? f : (float)R;
    l = l > -1.0f ? l : -1.0f;
    l = l < (float)R - 1.0f ? l : (float)R - 1.0f;
    *first = (int)f;
    *last = (int)l;
}

kernel void hl_shadow_raster(global const float *pos, global const uint *tri, uint ntris, global const float *xf,
                             global const float *frames, uint R, uint per, global uint *depth)
{
    uint k = get_global_id(1);
    global const float *fr = frames + 16 * (size_t)k;
    global uint *map = depth + (size_t)k * R * R;
    size_t t0 = get_global_id(0) * (size_t)per, t1 = t0 + per < ntris ? t0 + per : ntris;
    uint skip = as_uint(fr[15]);
    for (size_t t = t0; t < t1; t++) {
        global const uint *f = tri + 4 * t;
        if (f[3] < 32u && (skip >> f[3] & 1u)) continue;
        global const float *x = xf + 12 * (size_t)f[3];
        float4 a = hl_shadow_raster_vertex(pos, f[0], x, fr);
        float4 b = hl_shadow_raster_vertex(pos, f[1], x, fr);
        float4 c = hl_shadow_raster_vertex(pos, f[2], x, fr);
        float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if (!(area != 0.0f)) continue; /* edge-on: covers no centre */
        if (area < 0.0f) { float4 s = b; b = c; c = s; }
        int i0, i1, j0, j1;
        hl_shadow_raster_span(hl_shadow_raster_min3(a.x, b.x, c.x), hl_shadow_raster_max3(a.x, b.x, c.x), R, &i0, &i1);
        hl_shadow_raster_span(hl_shadow_raster_min3(a.y, b.y, c.y), hl_shadow_raster_max3(a.y, b.y, c.y), R, &j0, &j1);
        hl_shadow_raster_edge_t ga = hl_shadow_raster_edge_setup(b, c), gb = hl_shadow_raster_edge_setup(c, a),
                                gc = hl_shadow_raster_edge_setup(a, b);
        for (int j = j0; j <= j1; j++) {
            float py = (float)j + 0.5f;
            float ra = ga.ex * (py - ga.sy), rb = gb.ex * (py - gb.sy), rc = gc.ex * (py - gc.sy);
            for (int i = i0; i <= i1; i++) {
                float px = (float)i + 0.5f, ea, eb, ec;
                if (!hl_shadow_raster_edge_at(&ga, ra, px, &ea) || !hl_shadow_raster_edge_at(&gb, rb, px, &eb) ||
                    !hl_shadow_raster_edge_at(&gc, rc, px, &ec))
                    continue;
                float sum = ea + eb + ec;
                float d = sum > 0.0f ? (ea * a.z + eb * b.z + ec * c.z) / sum
                                     : hl_shadow_raster_min3(a.z, b.z, c.z);
                d = d > 0.0f ? d : 0.0f; /* also turns -0 into +0, whose bits order */
                d = d < 1.0f ? d : 1.0f;
                atomic_min(map + (size_t)j * R + (size_t)i, as_uint(d));
            }
        }
    }
}
