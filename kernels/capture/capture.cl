/* capture.cl - the surroundings seen from the capture point, straight into
 * the dual-paraboloid lighting. Twin: host/src/capture/twins/capture.c.
 *
 * One work-item per paraboloid texel (map 0: y >= 0, docs/CONVENTIONS.md).
 * It shoots S x S stratified rays through the texel's footprint in the
 * (s, t) plane, each weighted by the solid angle it stands for,
 * 4 / (1 + s^2 + t^2)^2 (rays beyond the unit disc are skipped), finds
 * the nearest triangle (Moller-Trumbore, both sides, every triangle in
 * order, the first on a tie) and averages the emitted radiance: the
 * texel's mean radiance, what env2para writes. Rays that hit nothing take
 * the texel's value of env_L (when have_env), weighted by their share.
 * Cost: 2 N^2 texels x (triangles + S^2 x the triangles whose bounding
 * cone meets the texel's); at worst 2 N^2 S^2 x triangles.
 * Triangles: HL_CAPTURE_F4 float4 each: v0 relative to the capture point,
 * e1 = v1 - v0, e2 = v2 - v0, emitted RGB, the bounding cone (unit axis,
 * half-angle in radians; more than pi: every direction), the half-angle's
 * cosine and sine. Output: three planes (R, G, B) of ncoef = 2 N^2
 * texels. Ray casting, not rasterisation: a straight edge is a circle arc
 * in a paraboloid map, and a few triangles cost little per ray.
 */
#pragma OPENCL FP_CONTRACT OFF

#define HL_CAPTURE_F4 6
/* Candidates a texel lists (ushort indices); a texel whose cone meets more
 * tests every triangle. 256: a few walls and a lamp list far fewer. */
#define HL_CAPTURE_LIST 256

/* Radians added to a texel's cone: more than the float error of the acos
 * of a dot product near 1 (about sqrt(2 * 2^-24) = 3.5e-4), so a cull is
 * never wrong and the hits are those of testing every triangle. */
#define HL_CAPTURE_CONE_MARGIN 4e-3f

/* Nearest triangle along direction (dx, dy, dz) from the origin, or -1:
 * of the n listed ones (ascending), or of all when list is NULL. */
static int hl_capture_nearest(global const float4 *tris, uint ntris, const ushort *list, uint n, float dx, float dy,
                              float dz)
{
    float best = INFINITY;
    int hit = -1;
    uint count = list ? n : ntris;
    for (uint e = 0; e < count; e++) {
        uint i = list ? (uint)list[e] : e;
        global const float4 *T = tris + HL_CAPTURE_F4 * i;
        float4 v0 = T[0], e1 = T[1], e2 = T[2];
        float px = dy * e2.z - dz * e2.y, py = dz * e2.x - dx * e2.z, pz = dx * e2.y - dy * e2.x;
        float det = e1.x * px + e1.y * py + e1.z * pz;
        if (det == 0.0f) continue; /* the ray lies in the triangle's plane */
        float inv = 1.0f / det;
        float tx = -v0.x, ty = -v0.y, tz = -v0.z;
        float u = (tx * px + ty * py + tz * pz) * inv;
        if (u < 0.0f || u > 1.0f) continue;
        float qx = ty * e1.z - tz * e1.y, qy = tz * e1.x - tx * e1.z, qz = tx * e1.y - ty * e1.x;
        float v = (dx * qx + dy * qy + dz * qz) * inv;
        if (v < 0.0f || u + v > 1.0f) continue;
        float t = (e2.x * qx + e2.y * qy + e2.z * qz) * inv;
        if (t > 0.0f && t < best) {
            best = t;
            hit = (int)i;
        }
    }
    return hit;
}

/* Unit direction through (s, t) of a map whose pole is sy * Y. */
static float4 hl_capture_dir(float s, float t, float sy)
{
    float r2 = s * s + t * t, k = 1.0f / (1.0f + r2);
    return (float4)(2.0f * s * k, sy * ((1.0f - r2) * k), 2.0f * t * k, 0.0f);
}

static float hl_capture_angle(float4 a, float4 b)
{
    return acos(clamp(a.x * b.x + a.y * b.y + a.z * b.z, -1.0f, 1.0f));
}

kernel void hl_capture(global const float4 *tris, uint ntris, uint N, uint S, global const float *env_L,
                       uint have_env, global float *L)
{
    uint ncoef = 2u * N * N, j = get_global_id(0);
    if (j >= ncoef) return;
    uint map = j / (N * N), rem = j % (N * N), row = rem / N, col = rem % N;
    float h = 2.0f / (float)N, hs = h / (float)S, sy = map ? -1.0f : 1.0f;
    float s0 = -1.0f + (float)col * h, t0 = -1.0f + (float)row * h, s1 = s0 + h, t1 = t0 + h;
    /* the texel's point nearest the pole: none of it in the disc, no light */
    float ns = s0 > 0.0f ? s0 : (s1 < 0.0f ? s1 : 0.0f), nt = t0 > 0.0f ? t0 : (t1 < 0.0f ? t1 : 0.0f);
    float ar = 0.0f, ag = 0.0f, ab = 0.0f, wsum = 0.0f, wmiss = 0.0f;
    if (ns * ns + nt * nt < 1.0f) {
        /* the texel's cone: the paraboloid map takes circles to circles,
           so the cap through its farthest corner holds all of it */
        float4 axis = hl_capture_dir(s0 + 0.5f * h, t0 + 0.5f * h, sy);
        float beta = fmax(fmax(hl_capture_angle(axis, hl_capture_dir(s0, t0, sy)), hl_capture_angle(axis, hl_capture_dir(s1, t0, sy))),
                          fmax(hl_capture_angle(axis, hl_capture_dir(s0, t1, sy)), hl_capture_angle(axis, hl_capture_dir(s1, t1, sy))));
        beta += HL_CAPTURE_CONE_MARGIN;
        /* the cones meet when the axes' angle is at most alpha + beta:
           their dot product at least cos(alpha + beta), no acos per pair */
        float cb = cos(beta), sb = sin(beta);
        ushort list[HL_CAPTURE_LIST];
        uint n = 0;
        for (uint i = 0; i < ntris && n <= HL_CAPTURE_LIST; i++) {
            float4 cone = tris[HL_CAPTURE_F4 * i + 4], cs = tris[HL_CAPTURE_F4 * i + 5];
            float dot = axis.x * cone.x + axis.y * cone.y + axis.z * cone.z;
            if (cone.w + beta >= 3.14159265f || dot >= cs.x * cb - cs.y * sb) {
                if (n < HL_CAPTURE_LIST) list[n] = (ushort)i;
                n++;
            }
        }
        const ushort *use = n <= HL_CAPTURE_LIST ? list : 0; /* overflow: every triangle */
        for (uint a = 0; a < S; a++)
            for (uint b = 0; b < S; b++) {
                float s = s0 + ((float)b + 0.5f) * hs, t = t0 + ((float)a + 0.5f) * hs;
                float r2 = s * s + t * t;
                if (r2 > 1.0f) continue;
                float k = 1.0f / (1.0f + r2), dw = 4.0f * k * k;
                int hit = hl_capture_nearest(tris, ntris, use, n, 2.0f * s * k, sy * ((1.0f - r2) * k), 2.0f * t * k);
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
               (every triangle: the point may lie outside the texel) */
            float cs = s0 + 0.5f * h, ct = t0 + 0.5f * h, q = 0.9999999f / sqrt(cs * cs + ct * ct);
            float s = cs * q, t = ct * q, r2 = s * s + t * t, k = 1.0f / (1.0f + r2);
            int hit = hl_capture_nearest(tris, ntris, 0, 0u, 2.0f * s * k, sy * ((1.0f - r2) * k), 2.0f * t * k);
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
