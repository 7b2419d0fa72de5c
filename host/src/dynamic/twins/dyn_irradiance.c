/* dyn_irradiance.c - twin of kernels/dynamic/dyn_irradiance.cl: one kept
 * light's irradiance at one normal (n . evec, 0, or the row-by-row texel
 * sum across the horizon, its runs found in texel units) and the folded lights' SH9 ambient; the
 * kernel's float formulas and order of additions, on the module's packed
 * tables (irradiance.h).
 * Depends on: irradiance.h. */
#include <float.h>
#include <math.h>

#include "irradiance.h"

/* the kernel's hl_dyn_irr_clamp */
static uint32_t clampidx(float v, uint32_t lo, uint32_t hi)
{
    if (!(v > (float)lo)) return lo;
    return v >= (float)hi ? hi : (uint32_t)v;
}

/* the kernel's hl_dyn_irr_straddle: runs found in texel units */
static void straddle(const float *lf, const uint32_t *lu, const float *mom, const float *pre, float n0, float n1,
                     float n2, float *acc)
{
    const uint32_t x0 = lu[0], y0 = lu[1], x1 = lu[2], y1 = lu[3], w = x1 - x0;
    const float c = lf[22];
    const float *M = mom + 9 * (size_t)lu[5];
    const float *P = pre + 18 * (size_t)lu[6];
    float g0 = n0 * lf[13] + n1 * lf[14] + n2 * lf[15];
    float gs = n0 * lf[16] + n1 * lf[17] + n2 * lf[18];
    float gt = n0 * lf[19] + n1 * lf[20] + n2 * lf[21];
    float G0 = (g0 - gs) - gt, GX = gs * c, GY = gt * c;
    float r = GX != 0.0f ? -1.0f / GX : 0.0f;
    acc[0] = 0.0f;
    acc[1] = 0.0f;
    acc[2] = 0.0f;
    for (uint32_t y = y0; y < y1; y++) {
        float ya = (float)y, yb = (float)(y + 1);
        float lo = G0 + GY * (GY > 0.0f ? ya : yb), hi = G0 + GY * (GY > 0.0f ? yb : ya);
        uint32_t pa = x0, pb = x0, c0 = x0, c1 = x0;
        if (GX > 0.0f) {
            pa = clampidx(ceilf(lo * r), x0, x1);
            pb = x1;
            c0 = clampidx(floorf(hi * r), x0, pa);
            c1 = pa;
        } else if (GX < 0.0f) {
            pb = clampidx(floorf(lo * r), x0, x1);
            c0 = pb;
            c1 = clampidx(ceilf(hi * r), pb, x1);
        } else if (lo >= 0.0f) {
            pb = x1;
        } else if (!(hi <= 0.0f)) {
            c1 = x1;
        }
        if (pb > pa) {
            const float *qa = P + 18 * ((size_t)(y - y0) * (w + 1) + (pa - x0));
            const float *qb = P + 18 * ((size_t)(y - y0) * (w + 1) + (pb - x0));
            for (int ch = 0; ch < 3; ch++) {
                float s0 = (qb[3 * ch] - qa[3 * ch]) + (qb[9 + 3 * ch] - qa[9 + 3 * ch]);
                float s1 = (qb[3 * ch + 1] - qa[3 * ch + 1]) + (qb[10 + 3 * ch] - qa[10 + 3 * ch]);
                float s2 = (qb[3 * ch + 2] - qa[3 * ch + 2]) + (qb[11 + 3 * ch] - qa[11 + 3 * ch]);
                acc[ch] += n0 * s0 + n1 * s1 + n2 * s2;
            }
        }
        const float *m = M + 9 * ((size_t)(y - y0) * w + (c0 - x0));
        for (uint32_t x = c0; x < c1; x++, m += 9)
            for (int ch = 0; ch < 3; ch++) {
                float d = n0 * m[3 * ch] + n1 * m[3 * ch + 1] + n2 * m[3 * ch + 2];
                if (d > 0.0f) acc[ch] += d;
            }
    }
}

int hl_ref_dyn_irr_light(const float *lf, const uint32_t *lu, const float *mom, const float *pre, const float n[3],
                         float rgb[3])
{
    const float n0 = n[0], n1 = n[1], n2 = n[2];
    rgb[0] = 0.0f;
    rgb[1] = 0.0f;
    rgb[2] = 0.0f;
    if (!(fabsf(n0) <= FLT_MAX && fabsf(n1) <= FLT_MAX && fabsf(n2) <= FLT_MAX)) return 0;
    float nd = n0 * lf[0] + n1 * lf[1] + n2 * lf[2], se = lf[3];
    if (nd >= se) {
        for (int c = 0; c < 3; c++) {
            float e = n0 * lf[4 + 3 * c] + n1 * lf[5 + 3 * c] + n2 * lf[6 + 3 * c];
            rgb[c] = e > 0.0f ? e : 0.0f;
        }
    } else if (!(nd <= -se)) {
        float acc[3];
        straddle(lf, lu, mom, pre, n0, n1, n2, acc);
        for (int c = 0; c < 3; c++) rgb[c] = acc[c] > 0.0f ? acc[c] : 0.0f;
    }
    return rgb[0] > 0.0f || rgb[1] > 0.0f || rgb[2] > 0.0f;
}

void hl_ref_dyn_irr_ambient(const float *sh, const float n[3], float rgb[3])
{
    float x = n[0], y = n[1], z = n[2];
    float xy = x * y, yz = y * z, zz = z * z, xz = x * z, d = x * x - y * y;
    for (int c = 0; c < 3; c++) {
        const float *q = sh + 9 * c;
        rgb[c] = q[0] + q[1] * x + q[2] * y + q[3] * z + q[4] * xy + q[5] * yz + q[6] * zz + q[7] * xz + q[8] * d;
    }
}
