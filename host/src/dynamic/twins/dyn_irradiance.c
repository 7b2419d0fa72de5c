/* dyn_irradiance.c - twin of kernels/dynamic/dyn_irradiance.cl: one kept
 * light's irradiance at one normal (n . evec, 0, or the texel sum across
 * the horizon: runs of whole rows, runs of texels in the rows it
 * crosses) and the folded lights' SH9 ambient; the kernel's float
 * formulas and order of additions, on the module's packed tables
 * (irradiance.h). The kernel's comments explain the steps.
 * Depends on: irradiance.h. */
#include <float.h>
#include <math.h>

#include "irradiance.h"

/* ---- the kernel's functions, hl_dyn_irr_ -> irr_ ---- */

/* v clamped to [lo, hi] as an index (v an integer-valued float, huge or
 * NaN: NaN gives lo). */
static uint32_t irr_clamp(float v, uint32_t lo, uint32_t hi)
{
    if (!(v > (float)lo)) return lo;
    return v >= (float)hi ? hi : (uint32_t)v;
}

/* acc[c] += n . e[c] for a run's summed moments e (9 floats) */
static void irr_add(const float *e, float n0, float n1, float n2, float *acc)
{
    for (int ch = 0; ch < 3; ch++) acc[ch] += n0 * e[3 * ch] + n1 * e[3 * ch + 1] + n2 * e[3 * ch + 2];
}

/* One row y of a view across the horizon. With lo and hi the least and
 * largest of G0 + GY Y over the row, texel x (spanning [x, x + 1]) is
 * wholly above where lo + GX (x or x + 1) >= 0 and wholly below where
 * hi + GX (x + 1 or x) <= 0; r = -1 / GX. Texels whose corners are within
 * rounding of the horizon may land in either run; their n . m is then 0
 * to that rounding either way. */
static void irr_row(const uint32_t *vu, const float *mom, const float *pre, uint32_t y,
                           float G0, float GX, float GY, float r, float n0, float n1, float n2, float *acc)
{
    const uint32_t x0 = vu[0], x1 = vu[1], w = x1 - x0, yr = y - vu[2];
    float ya = (float)y, yb = (float)(y + 1);
    float lo = G0 + GY * (GY > 0.0f ? ya : yb), hi = G0 + GY * (GY > 0.0f ? yb : ya);
    uint32_t pa = x0, pb = x0, c0 = x0, c1 = x0; /* the run above, the texels cut */
    if (GX > 0.0f) { /* above: x >= -lo / GX; below: x + 1 <= -hi / GX */
        pa = irr_clamp(ceilf(lo * r), x0, x1);
        pb = x1;
        c0 = irr_clamp(floorf(hi * r), x0, pa);
        c1 = pa;
    } else if (GX < 0.0f) { /* above: x + 1 <= -lo / GX; below: x >= -hi / GX */
        pb = irr_clamp(floorf(lo * r), x0, x1);
        c0 = pb;
        c1 = irr_clamp(ceilf(hi * r), pb, x1);
    } else if (lo >= 0.0f) {
        pb = x1;
    } else if (!(hi <= 0.0f)) {
        c1 = x1;
    }
    /* the run [pa, pb) reaches x1 (a suffix) or starts at x0 (a prefix) */
    const float *q = pre + 9 * ((size_t)vu[5] + (size_t)yr * 2 * (w + 1));
    if (pb > pa) irr_add(q + 9 * (pb == x1 ? (w + 1) + (pa - x0) : pb - x0), n0, n1, n2, acc);
    const float *m = mom + 9 * ((size_t)vu[4] + (size_t)yr * w + (c0 - x0));
    for (uint32_t x = c0; x < c1; x++, m += 9)
        for (int ch = 0; ch < 3; ch++) {
            float d = n0 * m[3 * ch] + n1 * m[3 * ch + 1] + n2 * m[3 * ch + 2];
            if (d > 0.0f) acc[ch] += d;
        }
}

/* The texel sum of one light at a normal across its horizon. In texel
 * units (X = (s + 1) F / 2, Y likewise) n . face_point = G0 + GX X + GY Y.
 * The horizon crosses about w |GX| / |GY| of the h rows and h |GY| / |GX|
 * of the w columns: the view with fewer is walked (its X and Y swapped
 * for the columns). Rows wholly above: G0 + min over the row of
 * GX X + GY Y >= 0, a run of rows at one end; wholly below likewise. */
static void irr_straddle(const float *lf, const uint32_t *lu, const float *mom,
                                const float *pre, float n0, float n1, float n2, float *acc)
{
    const float c = lf[22]; /* 2 / F */
    float g0 = n0 * lf[13] + n1 * lf[14] + n2 * lf[15];
    float gs = n0 * lf[16] + n1 * lf[17] + n2 * lf[18];
    float gt = n0 * lf[19] + n1 * lf[20] + n2 * lf[21];
    float G0 = (g0 - gs) - gt, GX = gs * c, GY = gt * c;
    float w = (float)(lu[1] - lu[0]), h = (float)(lu[3] - lu[2]);
    if (w * (GX * GX) > h * (GY * GY)) { /* by columns */
        lu += HL_DYN_IRR_VIEW;
        float t = GX;
        GX = GY;
        GY = t;
    }
    const uint32_t x0 = lu[0], x1 = lu[1], y0 = lu[2], y1 = lu[3];
    float mX = GX > 0.0f ? GX * (float)x0 : GX * (float)x1, MX = GX > 0.0f ? GX * (float)x1 : GX * (float)x0;
    float A = G0 + mX, B = G0 + MX; /* a row is wholly above where A + GY Y >= 0 over it, below where B + GY Y <= 0 */
    float r = GX != 0.0f ? -1.0f / GX : 0.0f, rr = GY != 0.0f ? -1.0f / GY : 0.0f;
    uint32_t ua = y0, ub = y0, ca = y0, cb = y0; /* rows wholly above [ua, ub), crossed [ca, cb) */
    if (GY > 0.0f) { /* above: y >= -A / GY; below: y + 1 <= -B / GY */
        ua = irr_clamp(ceilf(A * rr), y0, y1);
        ub = y1;
        ca = irr_clamp(floorf(B * rr), y0, ua);
        cb = ua;
    } else if (GY < 0.0f) { /* above: y + 1 <= -A / GY; below: y >= -B / GY */
        ub = irr_clamp(floorf(A * rr), y0, y1);
        ca = ub;
        cb = irr_clamp(ceilf(B * rr), ub, y1);
    } else if (A >= 0.0f) {
        ub = y1;
    } else if (!(B <= 0.0f)) {
        cb = y1;
    }
    acc[0] = 0.0f;
    acc[1] = 0.0f;
    acc[2] = 0.0f;
    const float *q = pre + 9 * (size_t)lu[6];
    if (ub > ua) irr_add(q + 9 * (ub == y1 ? (y1 - y0 + 1) + (ua - y0) : ub - y0), n0, n1, n2, acc);
    for (uint32_t y = ca; y < cb; y++) irr_row(lu, mom, pre, y, G0, GX, GY, r, n0, n1, n2, acc);
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
        irr_straddle(lf, lu, mom, pre, n0, n1, n2, acc);
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
