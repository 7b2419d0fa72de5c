/* twins/capture.c - the plain-C twin of kernels/capture/capture.cl: one
 * paraboloid texel of the captured lighting, the same float operations in
 * the same order (the build turns contraction off), so the kernel can be
 * checked against it and the reference backend gives the same map.
 * The cones' acos may round differently from the device's, but the cone
 * margin keeps every cull right on both, so the hits are the same.
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

/* Unit direction through (s, t) of a map whose pole is sy * Y. */
static void dir_of(float s, float t, float sy, float d[3])
{
    float r2 = s * s + t * t, k = 1.0f / (1.0f + r2);
    d[0] = 2.0f * s * k;
    d[1] = sy * ((1.0f - r2) * k);
    d[2] = 2.0f * t * k;
}

static float angle(const float a[3], const float b[3])
{
    float c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    return acosf(c < -1.0f ? -1.0f : c > 1.0f ? 1.0f : c);
}

static float corner_angle(const float axis[3], float s, float t, float sy)
{
    float d[3];
    dir_of(s, t, sy, d);
    return angle(axis, d);
}

/* Lists the triangles whose cone meets the cone of the texel [s0, s1] x
 * [t0, t1] (the paraboloid map takes circles to circles, so the cap
 * through the farthest corner holds all of the texel); returns their
 * count, more than HL_CAPTURE_LIST when the list overflowed. */
static uint32_t cull(const float *tris, uint32_t ntris, float s0, float t0, float h, float sy, uint16_t *list)
{
    float axis[3], s1 = s0 + h, t1 = t0 + h;
    dir_of(s0 + 0.5f * h, t0 + 0.5f * h, sy, axis);
    float beta = fmaxf(fmaxf(corner_angle(axis, s0, t0, sy), corner_angle(axis, s1, t0, sy)),
                       fmaxf(corner_angle(axis, s0, t1, sy), corner_angle(axis, s1, t1, sy)));
    beta += HL_CAPTURE_CONE_MARGIN;
    /* the cones meet when the axes' angle is at most alpha + beta: their
       dot product at least cos(alpha + beta), no acos per pair */
    float cb = cosf(beta), sb = sinf(beta);
    uint32_t n = 0;
    for (uint32_t i = 0; i < ntris && n <= HL_CAPTURE_LIST; i++) {
        const float *cone = tris + HL_CAPTURE_FLOATS * (size_t)i + 16, *cs = cone + 4;
        float dot = axis[0] * cone[0] + axis[1] * cone[1] + axis[2] * cone[2];
        if (cone[3] + beta >= 3.14159265f || dot >= cs[0] * cb - cs[1] * sb) {
            if (n < HL_CAPTURE_LIST) list[n] = (uint16_t)i;
            n++;
        }
    }
    return n;
}

void hl_ref_capture_texel(const float *tris, uint32_t ntris, uint32_t N, uint32_t S, const float *env_L,
                          int use_cones, uint32_t j, float *L)
{
    const uint32_t ncoef = 2u * N * N;
    uint32_t map = j / (N * N), rem = j % (N * N), row = rem / N, col = rem % N;
    float h = 2.0f / (float)N, hs = h / (float)S, sy = map ? -1.0f : 1.0f;
    float s0 = -1.0f + (float)col * h, t0 = -1.0f + (float)row * h, s1 = s0 + h, t1 = t0 + h;
    /* the texel's point nearest the pole: none of it in the disc, no light */
    float ns = s0 > 0.0f ? s0 : (s1 < 0.0f ? s1 : 0.0f), nt = t0 > 0.0f ? t0 : (t1 < 0.0f ? t1 : 0.0f);
    float ar = 0.0f, ag = 0.0f, ab = 0.0f, wsum = 0.0f, wmiss = 0.0f;
    if (ns * ns + nt * nt < 1.0f) {
        uint16_t list[HL_CAPTURE_LIST];
        uint32_t n = use_cones ? cull(tris, ntris, s0, t0, h, sy, list) : HL_CAPTURE_LIST + 1;
        const uint16_t *use = n <= HL_CAPTURE_LIST ? list : NULL; /* overflow: every triangle */
        for (uint32_t a = 0; a < S; a++)
            for (uint32_t b = 0; b < S; b++) {
                float s = s0 + ((float)b + 0.5f) * hs, t = t0 + ((float)a + 0.5f) * hs;
                float r2 = s * s + t * t;
                if (r2 > 1.0f) continue;
                float k = 1.0f / (1.0f + r2), dw = 4.0f * k * k;
                int hit = nearest(tris, ntris, use, n, 2.0f * s * k, sy * ((1.0f - r2) * k), 2.0f * t * k);
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
