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
 * (ascending), or of all when list is NULL (the brute force). */
static int nearest(const float *tris, uint32_t ntris, const uint32_t *list, uint32_t n, float dx, float dy, float dz)
{
    float best = INFINITY;
    int hit = -1;
    uint32_t count = list ? n : ntris;
    for (uint32_t e = 0; e < count; e++) {
        uint32_t i = list ? list[e] : e;
        float t = hl_capture_tri_t(tris + HL_CAPTURE_FLOATS * (size_t)i, dx, dy, dz);
        if (t < best) {
            best = t;
            hit = (int)i;
        }
    }
    return hit;
}

/* The ray's hit: through the hierarchy, or (use_cones 0) of every triangle. */
static int trace(const hl_capture_tables *tb, int use_cones, float dx, float dy, float dz)
{
    return use_cones ? hl_capture_trace(tb->tris, tb->nodes, tb->links, tb->order, dx, dy, dz)
                     : nearest(tb->tris, tb->ntris, NULL, 0, dx, dy, dz);
}

/* Lists the triangles of the texel's tile that can be hit by a ray of the
 * texel (hl_capture_meets); returns their count, more than
 * HL_CAPTURE_LIST when the list overflowed. */
static uint32_t cull(const float *tris, const uint32_t *tl, uint32_t tn, const float *cone_t, uint32_t *list)
{
    uint32_t n = 0;
    for (uint32_t e = 0; e < tn && n <= HL_CAPTURE_LIST; e++) {
        const uint32_t i = tl[e];
        if (hl_capture_meets(tris + HL_CAPTURE_FLOATS * (size_t)i, cone_t)) {
            if (n < HL_CAPTURE_LIST) list[n] = i;
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
static int cover(const float *tris, const uint32_t *list, uint32_t n, const float *cone_t)
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

void hl_ref_capture_texel(const hl_capture_tables *tb, uint32_t N, uint32_t S, const float *env_L, int use_cones,
                          uint32_t j, float *L)
{
    const float *tris = tb->tris;
    const uint32_t ncoef = 2u * N * N;
    uint32_t map = j / (N * N), rem = j % (N * N), row = rem / N, col = rem % N;
    float h = 2.0f / (float)N, hs = h / (float)S, sy = map ? -1.0f : 1.0f;
    float s0 = -1.0f + (float)col * h, t0 = -1.0f + (float)row * h;
    const float *cone_t = tb->cones + 8 * (size_t)j;
    float ar = 0.0f, ag = 0.0f, ab = 0.0f, wsum = 0.0f, wmiss = 0.0f;
    if (cone_t[3] != 0.0f) { /* some of the texel in the disc */
        uint32_t list[HL_CAPTURE_LIST];
        const uint32_t T = N / HL_CAPTURE_TILES, tile = map * HL_CAPTURE_TILES * HL_CAPTURE_TILES + row / T * HL_CAPTURE_TILES + col / T;
        const uint32_t l0 = use_cones ? tb->tile_start[tile] : 0, ln = use_cones ? tb->tile_start[tile + 1] - l0 : 0;
        /* a crowded tile: no list of the texel's own, every ray traced */
        uint32_t n = use_cones && ln <= HL_CAPTURE_SCAN ? cull(tris, tb->tile_list + l0, ln, cone_t, list) : HL_CAPTURE_LIST + 1;
        const uint32_t *use = n <= HL_CAPTURE_LIST ? list : NULL; /* overflow: the hierarchy */
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
                float dx = 2.0f * s * k, dy = sy * ((1.0f - r2) * k), dz = 2.0f * t * k;
                int hit = !cast ? all : use ? nearest(tris, tb->ntris, use, n, dx, dy, dz) : trace(tb, use_cones, dx, dy, dz);
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
               (the hierarchy: the point may lie outside the texel) */
            float cs = s0 + 0.5f * h, ct = t0 + 0.5f * h, q = 0.9999999f / sqrtf(cs * cs + ct * ct);
            float s = cs * q, t = ct * q, r2 = s * s + t * t, k = 1.0f / (1.0f + r2);
            int hit = trace(tb, use_cones, 2.0f * s * k, sy * ((1.0f - r2) * k), 2.0f * t * k);
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
