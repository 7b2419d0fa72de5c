/* dyn_irradiance.c - twin of kernels/dynamic/dyn_irradiance.cl: one kept
 * light's irradiance at one normal (n . evec, 0, or the row-by-row texel
 * sum across the horizon) and the folded lights' SH9 ambient; the
 * kernel's float formulas and order of additions, on the module's packed
 * tables (irradiance.h).
 * Depends on: irradiance.h. */
#include <float.h>
#include <math.h>

#include "irradiance.h"

/* the kernel's hl_dyn_irr_edge */
static uint32_t edge(float v, float F, int up, uint32_t lo, uint32_t hi)
{
    float x = (v + 1.0f) * 0.5f * F;
    x = up ? ceilf(x) : floorf(x);
    if (!(x > (float)lo)) return lo;
    return x >= (float)hi ? hi : (uint32_t)x;
}

/* the kernel's hl_dyn_irr_straddle */
static void straddle(const float *lf, const uint32_t *lu, const float *mom, const float *pre, float n0, float n1,
                     float n2, float *acc)
{
    const uint32_t x0 = lu[0], y0 = lu[1], x1 = lu[2], y1 = lu[3], w = x1 - x0;
    const float F = lf[22];
    const float *M = mom + 9 * (size_t)lu[5];
    const float *P = pre + 18 * (size_t)lu[6];
    float g0 = n0 * lf[13] + n1 * lf[14] + n2 * lf[15];
    float gs = n0 * lf[16] + n1 * lf[17] + n2 * lf[18];
    float gt = n0 * lf[19] + n1 * lf[20] + n2 * lf[21];
    acc[0] = 0.0f;
    acc[1] = 0.0f;
    acc[2] = 0.0f;
    for (uint32_t y = y0; y < y1; y++) {
        float t0 = 2.0f * (float)y / F - 1.0f, t1 = 2.0f * (float)(y + 1) / F - 1.0f;
        float lo = g0 + (gt > 0.0f ? gt * t0 : gt * t1), hi = g0 + (gt > 0.0f ? gt * t1 : gt * t0);
        uint32_t a0 = x0, a1 = x0, b0 = x0, b1 = x0;
        if (gs == 0.0f) {
            if (lo >= 0.0f) a1 = x1;
            else if (hi <= 0.0f) b1 = x1;
        } else if (gs > 0.0f) {
            a0 = edge(-lo / gs, F, 1, x0, x1);
            a1 = x1;
            b1 = edge(-hi / gs, F, 0, x0 + 1, x1 + 1) - 1;
        } else {
            a1 = edge(-lo / gs, F, 0, x0 + 1, x1 + 1) - 1;
            b0 = edge(-hi / gs, F, 1, x0, x1);
            b1 = x1;
        }
        if (a1 < a0) a1 = a0;
        if (b1 < b0) b1 = b0;
        const float *row = M + 9 * (size_t)(y - y0) * w;
        const float *pa = P + 18 * ((size_t)(y - y0) * (w + 1) + (a0 - x0));
        const float *pb = P + 18 * ((size_t)(y - y0) * (w + 1) + (a1 - x0));
        for (int c = 0; c < 3; c++) {
            float s0 = (pb[3 * c] - pa[3 * c]) + (pb[9 + 3 * c] - pa[9 + 3 * c]);
            float s1 = (pb[3 * c + 1] - pa[3 * c + 1]) + (pb[10 + 3 * c] - pa[10 + 3 * c]);
            float s2 = (pb[3 * c + 2] - pa[3 * c + 2]) + (pb[11 + 3 * c] - pa[11 + 3 * c]);
            acc[c] += n0 * s0 + n1 * s1 + n2 * s2;
        }
        for (uint32_t x = x0; x < x1; x++) {
            if (x >= a0 && x < a1) x = a1;
            if (x >= b0 && x < b1) x = b1;
            if (x >= a0 && x < a1) x = a1;
            if (x >= x1) break;
            const float *m = row + 9 * (size_t)(x - x0);
            for (int c = 0; c < 3; c++) {
                float d = n0 * m[3 * c] + n1 * m[3 * c + 1] + n2 * m[3 * c + 2];
                if (d > 0.0f) acc[c] += d;
            }
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
