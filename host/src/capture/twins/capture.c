/* twins/capture.c - the plain-C twin of kernels/capture/capture.cl: one
 * paraboloid texel of the captured lighting, the same float operations in
 * the same order (the build turns contraction off), so the kernel can be
 * checked against it and the reference backend gives the same map.
 * The texels' cones come from one table (hl_capture_texel_cones) that both
 * read, so the culls, too, are the same.
 * Depends on: capture.h, libm.
 */
#include <math.h>

#include "capture.h"

/* Nearest triangle along direction (dx, dy, dz) from the origin, or -1
 * (Moller-Trumbore, both sides, first on a tie): of the n listed ones
 * (ascending), or of all when list is NULL. */
static int nearest(const float *tris, uint32_t ntris, const uint16_t *list, uint32_t n, float dx, float dy, float dz)
{
    float best = INFINITY;
    int hit = -1;
    uint32_t count = list ? n : ntris;
    for (uint32_t e = 0; e < count; e++) {
        uint32_t i = list ? (uint32_t)list[e] : e;
        const float *v0 = tris + HL_CAPTURE_FLOATS * (size_t)i, *e1 = v0 + 4, *e2 = v0 + 8;
        float px = dy * e2[2] - dz * e2[1], py = dz * e2[0] - dx * e2[2], pz = dx * e2[1] - dy * e2[0];
        float det = e1[0] * px + e1[1] * py + e1[2] * pz;
        if (det == 0.0f) continue; /* the ray lies in the triangle's plane */
        float inv = 1.0f / det;
        float tx = -v0[0], ty = -v0[1], tz = -v0[2];
        float u = (tx * px + ty * py + tz * pz) * inv;
        if (u < 0.0f || u > 1.0f) continue;
        float qx = ty * e1[2] - tz * e1[1], qy = tz * e1[0] - tx * e1[2], qz = tx * e1[1] - ty * e1[0];
        float v = (dx * qx + dy * qy + dz * qz) * inv;
        if (v < 0.0f || u + v > 1.0f) continue;
        float t = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv;
        if (t > 0.0f && t < best) {
            best = t;
            hit = (int)i;
        }
    }
    return hit;
}

/* Lists the triangles of the texel's tile that can be hit by a ray of the
 * texel (hl_capture_meets); returns their count, more than
 * HL_CAPTURE_LIST when the list overflowed. */
static uint32_t cull(const float *tris, const uint16_t *tl, uint32_t tn, const float *cone_t, uint16_t *list)
{
    uint32_t n = 0;
    for (uint32_t e = 0; e < tn && n <= HL_CAPTURE_LIST; e++) {
        const uint32_t i = tl[e];
        if (hl_capture_meets(tris + HL_CAPTURE_FLOATS * (size_t)i, cone_t)) {
            if (n < HL_CAPTURE_LIST) list[n] = (uint16_t)i;
            n++;
        }
    }
    return n;
}

/* The listed triangle that every ray of the texel hits first, or -1: its
 * view (the three planes through the capture point and its edges) holds
 * the texel's cone with HL_CAPTURE_COVER_MARGIN to spare, and every other
 * listed triangle lies behind its plane (to HL_CAPTURE_PLANE_TOL). Of the
 * triangles whose view holds the texel, only the nearest can pass. */
static int cover(const float *tris, const uint16_t *list, uint32_t n, const float *cone_t)
{
    const float sc = cone_t[6];
    for (uint32_t e = 0; e < n; e++) {
        const float *T = tris + HL_CAPTURE_FLOATS * (size_t)list[e], *en = T + 28;
        int in = 1;
        for (int k = 0; k < 3 && in; k++)
            in = cone_t[0] * en[4 * k] + cone_t[1] * en[4 * k + 1] + cone_t[2] * en[4 * k + 2] >= sc;
        if (!in) continue;
        const float *pl = T + 24;
        const float lim = pl[3] - HL_CAPTURE_PLANE_TOL * pl[3];
        for (uint32_t f = 0; f < n && in; f++) {
            if (f == e) continue;
            const float *B = tris + HL_CAPTURE_FLOATS * (size_t)list[f];
            for (int v = 0; v < 3 && in; v++) {
                float x = B[0] + (v == 1 ? B[4] : v == 2 ? B[8] : 0.0f);
                float y = B[1] + (v == 1 ? B[5] : v == 2 ? B[9] : 0.0f);
                float z = B[2] + (v == 1 ? B[6] : v == 2 ? B[10] : 0.0f);
                in = pl[0] * x + pl[1] * y + pl[2] * z >= lim;
            }
        }
        if (in) return (int)list[e];
    }
    return -1;
}

void hl_ref_capture_texel(const float *tris, uint32_t ntris, const float *cones, const uint32_t *tile_start,
                          const uint16_t *tile_list, uint32_t N, uint32_t S, const float *env_L, int use_cones,
                          uint32_t j, float *L)
{
    const uint32_t ncoef = 2u * N * N;
    uint32_t map = j / (N * N), rem = j % (N * N), row = rem / N, col = rem % N;
    float h = 2.0f / (float)N, hs = h / (float)S, sy = map ? -1.0f : 1.0f;
    float s0 = -1.0f + (float)col * h, t0 = -1.0f + (float)row * h;
    const float *cone_t = cones + 8 * (size_t)j;
    float ar = 0.0f, ag = 0.0f, ab = 0.0f, wsum = 0.0f, wmiss = 0.0f;
    if (cone_t[3] != 0.0f) { /* some of the texel in the disc */
        uint16_t list[HL_CAPTURE_LIST];
        const uint32_t T = N / HL_CAPTURE_TILES, tile = map * HL_CAPTURE_TILES * HL_CAPTURE_TILES + row / T * HL_CAPTURE_TILES + col / T;
        uint32_t n = use_cones ? cull(tris, tile_list + tile_start[tile], tile_start[tile + 1] - tile_start[tile], cone_t, list)
                               : HL_CAPTURE_LIST + 1;
        const uint16_t *use = n <= HL_CAPTURE_LIST ? list : NULL; /* overflow: every triangle */
        /* no ray to cast where no triangle is listed, or where one
           listed triangle is in front of every ray: the same sums */
        const int all = use && n == 0 ? -1 : use ? cover(tris, list, n, cone_t) : -1, cast = !(use && (n == 0 || all >= 0));
        /* nothing listed and some rays in the disc: all of them miss */
        const int none = use && n == 0 && cone_t[3] == 1.0f;
        if (none) wsum = wmiss = 1.0f;
        for (uint32_t a = 0; !none && a < S; a++)
            for (uint32_t b = 0; b < S; b++) {
                float s = s0 + ((float)b + 0.5f) * hs, t = t0 + ((float)a + 0.5f) * hs;
                float r2 = s * s + t * t;
                if (r2 > 1.0f) continue;
                float k = 1.0f / (1.0f + r2), dw = 4.0f * k * k;
                int hit = cast ? nearest(tris, ntris, use, n, 2.0f * s * k, sy * ((1.0f - r2) * k), 2.0f * t * k) : all;
                if (hit >= 0) {
                    const float *em = tris + HL_CAPTURE_FLOATS * (size_t)hit + 12;
                    ar += dw * em[0];
                    ag += dw * em[1];
                    ab += dw * em[2];
                } else {
                    wmiss += dw;
                }
                wsum += dw;
            }
        if (wsum == 0.0f) {
            /* a sliver of the rim no sub-sample fell in: one ray at the
               in-disc point nearest the texel centre, as geom.c does
               (every triangle: the point may lie outside the texel) */
            float cs = s0 + 0.5f * h, ct = t0 + 0.5f * h, q = 0.9999999f / sqrtf(cs * cs + ct * ct);
            float s = cs * q, t = ct * q, r2 = s * s + t * t, k = 1.0f / (1.0f + r2);
            int hit = nearest(tris, ntris, NULL, 0, 2.0f * s * k, sy * ((1.0f - r2) * k), 2.0f * t * k);
            if (hit >= 0) {
                const float *em = tris + HL_CAPTURE_FLOATS * (size_t)hit + 12;
                ar = em[0];
                ag = em[1];
                ab = em[2];
            } else {
                wmiss = 1.0f;
            }
            wsum = 1.0f;
        }
    }
    float inv = wsum > 0.0f ? 1.0f / wsum : 0.0f, miss = wmiss * inv;
    float r = ar * inv, g = ag * inv, bl = ab * inv;
    if (env_L) {
        r += miss * env_L[j];
        g += miss * env_L[ncoef + j];
        bl += miss * env_L[2u * ncoef + j];
    }
    L[j] = r;
    L[ncoef + j] = g;
    L[2u * ncoef + j] = bl;
}
