/* capture.cl - the surroundings seen from the capture point, straight into
 * the dual-paraboloid lighting. Twin: host/src/capture/twins/capture.c.
 *
 * One work-item per paraboloid texel (map 0: y >= 0, docs/CONVENTIONS.md).
 * It shoots S x S stratified rays through the texel's footprint in the
 * (s, t) plane, each weighted by the solid angle it stands for,
 * 4 / (1 + s^2 + t^2)^2 (rays beyond the unit disc are skipped), finds
 * the nearest triangle (Moller-Trumbore, both sides, the lowest index on
 * a tie: what testing every triangle in order finds) and averages the
 * emitted radiance: the texel's mean radiance, what env2para writes. Rays that hit nothing take
 * the texel's value of env_L (when have_env), weighted by their share.
 * A texel lists the triangles of its tile's list (made on the host) whose
 * bounding cone meets its cone and whose view (the planes through the
 * capture point and their edges) it does not lie wholly outside of, with
 * a margin. Cost: 2 N^2 texels x (its tile's triangles + S^2 x its own).
 * A texel listing more than HL_CAPTURE_LIST, or whose tile lists more
 * than HL_CAPTURE_SCAN, and a rim sliver's one ray, trace the hierarchy
 * (hl_capture_trace, hl_shared.h; nodes, links and order from
 * capture_bvh.c) instead of testing every triangle. It casts no ray
 * where none is listed, or where one listed triangle's view holds the
 * texel's cone with a margin and every other listed one lies behind that
 * triangle's plane
 * (the rays would all hit it first): the same sums, without the rays.
 * Triangles: HL_CAPTURE_F4 float4 each: v0 relative to the capture point,
 * e1 = v1 - v0, e2 = v2 - v0, emitted RGB, the bounding cone (unit axis,
 * half-angle in radians; more than pi: every direction), the half-angle's
 * cosine and sine, the plane (unit normal away from the capture point,
 * distance), the edges' planes through the capture point (unit normals
 * into the view; 0 for a triangle seen edge-on). Texel table (cones): two
 * float4 a texel: its cone's unit axis and 0 if none of it is in the disc,
 * 1 if some of its rays are, 2 for a rim sliver none of its rays reach;
 * the half-angle's cosine and sine, the sine of the half-angle plus the
 * cover margin, the half-angle (capture.h, hl_capture_texel_cones).
 * Output: three planes (R, G, B) of ncoef = 2 N^2 texels. Ray casting, not
 * rasterisation: a straight edge is a circle arc in a paraboloid map, and
 * a few triangles cost little per ray.
 */
#pragma OPENCL FP_CONTRACT OFF

#define HL_CAPTURE_F4 10
/* Candidates a texel lists; a texel whose cone meets more traces its rays
 * through the hierarchy. 256: a few walls and a lamp list far fewer. */
#define HL_CAPTURE_LIST 256u
/* A tile listing more triangles than this: its texels list none and
 * trace every ray (capture.h). */
#define HL_CAPTURE_SCAN 2048u

/* Tiles per side of each map (capture.h): a texel's candidates are among
 * its tile's, listed by the host. */
#define HL_CAPTURE_TILES 8u

/* "Behind a plane" allows a corner this far in front, relative to the
 * plane's distance (capture.h). */
#define HL_CAPTURE_PLANE_TOL 1e-5f

/* Nearest of the n listed triangles (ascending) along direction (dx, dy,
 * dz) from the origin, or -1: the first on a tie. */
static int hl_capture_nearest(global const float4 *tris, const uint *list, uint n, float dx, float dy, float dz)
{
    float best = INFINITY;
    int hit = -1;
    for (uint e = 0; e < n; e++) {
        float t = hl_capture_tri_t((global const float *)(tris + HL_CAPTURE_F4 * list[e]), dx, dy, dz);
        if (t < best) {
            best = t;
            hit = (int)list[e];
        }
    }
    return hit;
}

/* Whether the texel's cone (axis ax, sc the sine of its half-angle plus
 * the cover margin) lies wholly outside one of the triangle's edge planes:
 * no ray of the texel can hit it (never for a triangle seen edge-on). */
static int hl_capture_outside(global const float4 *T, float4 ax, float sc)
{
    float4 n0 = T[7], n1 = T[8], n2 = T[9];
    return ax.x * n0.x + ax.y * n0.y + ax.z * n0.z < -sc || ax.x * n1.x + ax.y * n1.y + ax.z * n1.z < -sc ||
           ax.x * n2.x + ax.y * n2.y + ax.z * n2.z < -sc;
}

/* The listed triangle that every ray of the texel (cone axis ax, sine sc
 * of its half-angle plus the cover margin) hits first, or -1: of those
 * whose view holds the texel's cone, the one with every other listed
 * triangle behind its plane. */
static int hl_capture_cover(global const float4 *tris, const uint *list, uint n, float4 ax, float sc)
{
    for (uint e = 0; e < n; e++) {
        global const float4 *T = tris + HL_CAPTURE_F4 * list[e];
        float4 n0 = T[7], n1 = T[8], n2 = T[9];
        if (!(ax.x * n0.x + ax.y * n0.y + ax.z * n0.z >= sc && ax.x * n1.x + ax.y * n1.y + ax.z * n1.z >= sc &&
              ax.x * n2.x + ax.y * n2.y + ax.z * n2.z >= sc))
            continue;
        float4 pl = T[6];
        float lim = pl.w - HL_CAPTURE_PLANE_TOL * pl.w;
        int in = 1;
        for (uint f = 0; f < n && in; f++) {
            if (f == e) continue;
            global const float4 *B = tris + HL_CAPTURE_F4 * list[f];
            float4 v0 = B[0], e1 = B[1], e2 = B[2];
            for (int v = 0; v < 3 && in; v++) {
                float x = v0.x + (v == 1 ? e1.x : v == 2 ? e2.x : 0.0f);
                float y = v0.y + (v == 1 ? e1.y : v == 2 ? e2.y : 0.0f);
                float z = v0.z + (v == 1 ? e1.z : v == 2 ? e2.z : 0.0f);
                in = pl.x * x + pl.y * y + pl.z * z >= lim;
            }
        }
        if (in) return (int)list[e];
    }
    return -1;
}

kernel void hl_capture(global const float4 *tris, uint ntris, uint N, uint S, global const float *env_L,
                       uint have_env, global float *L, global const float4 *cones, global const uint *tile_start,
                       global const uint *tile_list, global const float *nodes, global const uint *links,
                       global const uint *order)
{
    uint ncoef = 2u * N * N, j = get_global_id(0);
    if (j >= ncoef) return;
    uint map = j / (N * N), rem = j % (N * N), row = rem / N, col = rem % N;
    float h = 2.0f / (float)N, hs = h / (float)S, sy = map ? -1.0f : 1.0f;
    float s0 = -1.0f + (float)col * h, t0 = -1.0f + (float)row * h;
    float4 axis = cones[2u * j], cb4 = cones[2u * j + 1u];
    float ar = 0.0f, ag = 0.0f, ab = 0.0f, wsum = 0.0f, wmiss = 0.0f;
    if (axis.w != 0.0f) { /* some of the texel in the disc */
        /* the cones meet when the axes' angle is at most alpha + beta:
           their dot product at least cos(alpha + beta), no acos per pair */
        float cb = cb4.x, sb = cb4.y, beta = cb4.w;
        uint list[HL_CAPTURE_LIST];
        uint n = 0, T = N / HL_CAPTURE_TILES;
        uint tile = map * HL_CAPTURE_TILES * HL_CAPTURE_TILES + row / T * HL_CAPTURE_TILES + col / T;
        /* a crowded tile: no list of the texel's own, every ray traced */
        if (tile_start[tile + 1u] - tile_start[tile] > HL_CAPTURE_SCAN) n = HL_CAPTURE_LIST + 1u;
        for (uint e = tile_start[tile]; e < tile_start[tile + 1u] && n <= HL_CAPTURE_LIST; e++) {
            uint i = tile_list[e];
            float4 cone = tris[HL_CAPTURE_F4 * i + 4], cs = tris[HL_CAPTURE_F4 * i + 5];
            float dot = axis.x * cone.x + axis.y * cone.y + axis.z * cone.z;
            if ((cone.w + beta >= 3.14159265f || dot >= cs.x * cb - cs.y * sb) &&
                !hl_capture_outside(tris + HL_CAPTURE_F4 * i, axis, cb4.z)) {
                if (n < HL_CAPTURE_LIST) list[n] = i;
                n++;
            }
        }
        const uint *use = n <= HL_CAPTURE_LIST ? list : 0; /* overflow: the hierarchy */
        /* no ray to cast where no triangle is listed, or where one listed
           triangle is in front of every ray: the same sums */
        int all = use && n == 0 ? -1 : use ? hl_capture_cover(tris, list, n, axis, cb4.z) : -1;
        int cast = !(use && (n == 0 || all >= 0));
        /* nothing listed and some rays in the disc: all of them miss */
        const int none = use && n == 0 && axis.w == 1.0f;
        if (none) wsum = wmiss = 1.0f;
        for (uint a = 0; !none && a < S; a++)
            for (uint b = 0; b < S; b++) {
                float s = s0 + ((float)b + 0.5f) * hs, t = t0 + ((float)a + 0.5f) * hs;
                float r2 = s * s + t * t;
                if (r2 > 1.0f) continue;
                float k = 1.0f / (1.0f + r2), dw = 4.0f * k * k;
                float dx = 2.0f * s * k, dy = sy * ((1.0f - r2) * k), dz = 2.0f * t * k;
                int hit = !cast ? all
                          : use ? hl_capture_nearest(tris, use, n, dx, dy, dz)
                                : hl_capture_trace((global const float *)tris, nodes, links, order, dx, dy, dz);
                if (hit >= 0) {
                    float4 em = tris[HL_CAPTURE_F4 * (uint)hit + 3];
                    ar += dw * em.x;
                    ag += dw * em.y;
                    ab += dw * em.z;
                } else {
                    wmiss += dw;
                }
                wsum += dw;
            }
        if (wsum == 0.0f) {
            /* a sliver of the rim no sub-sample fell in: one ray at the
               in-disc point nearest the texel centre, as geom.c does
               (the hierarchy: the point may lie outside the texel) */
            float cs = s0 + 0.5f * h, ct = t0 + 0.5f * h, q = 0.9999999f / sqrt(cs * cs + ct * ct);
            float s = cs * q, t = ct * q, r2 = s * s + t * t, k = 1.0f / (1.0f + r2);
            int hit = hl_capture_trace((global const float *)tris, nodes, links, order, 2.0f * s * k, sy * ((1.0f - r2) * k),
                                       2.0f * t * k);
            if (hit >= 0) {
                float4 em = tris[HL_CAPTURE_F4 * (uint)hit + 3];
                ar = em.x;
                ag = em.y;
                ab = em.z;
            } else {
                wmiss = 1.0f;
            }
            wsum = 1.0f;
        }
    }
    float inv = wsum > 0.0f ? 1.0f / wsum : 0.0f, miss = wmiss * inv;
    float r = ar * inv, g = ag * inv, bl = ab * inv;
    if (have_env) {
        r += miss * env_L[j];
        g += miss * env_L[ncoef + j];
        bl += miss * env_L[2u * ncoef + j];
    }
    L[j] = r;
    L[ncoef + j] = g;
    L[2u * ncoef + j] = bl;
}
