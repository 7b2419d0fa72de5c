/* msm_eval.c - twin of kernels/dynamic/msm_eval.cl: one receiver of one
 * light against its moment tables: blocker share and depth from the
 * search box's moments, the Hamburger 4MSM bound over the penumbra box,
 * or in small boxes the per-texel test against the receiver's plane;
 * the kernel's formulas and order of operations.
 * Depends on: csm.h. */
#include <math.h>

#include "csm.h"

static float clampf(float x, float lo, float hi) { return x < lo ? lo : x > hi ? hi : x; }

/* the kernel's hl_msm_box */
static void box(const float *sat, const float *mean, const float *zsc, uint32_t R, float cx, float cy, float wu,
                float wv, float dh, float *m)
{
    float fR = (float)R;
    float u0 = fmaxf(cx - wu, 0.0f), u1 = fminf(cx + wu, fR);
    float v0 = fmaxf(cy - wv, 0.0f), v1 = fminf(cy + wv, fR);
    if (!(u1 > u0 && v1 > v0)) { m[0] = 1.0f; m[1] = 1.0f; m[2] = 1.0f; m[3] = 1.0f; m[4] = 0.0f; return; }
    float full = (2.0f * wu) * (2.0f * wv), area = (u1 - u0) * (v1 - v0);
    float outside = fmaxf(full - area, 0.0f), inv = 1.0f / full;
    float a[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    if (wu <= dh && wv <= dh) {
        uint32_t i0 = (uint32_t)u0, i1 = (uint32_t)ceilf(u1), j0 = (uint32_t)v0, j1 = (uint32_t)ceilf(v1);
        if (i1 > R) i1 = R;
        if (j1 > R) j1 = R;
        for (uint32_t j = j0; j < j1; j++) {
            float wy = fminf((float)(j + 1), v1) - fmaxf((float)j, v0);
            for (uint32_t i = i0; i < i1; i++) {
                float ov = (fminf((float)(i + 1), u1) - fmaxf((float)i, u0)) * wy;
                const float *t4 = zsc + 4 * ((size_t)j * R + i);
                for (uint32_t p = 0; p < 4; p++) a[p] += ov * t4[p];
                a[4] += t4[0] < 1.0f ? ov : 0.0f;
            }
        }
        for (uint32_t p = 0; p < 4; p++) m[p] = (a[p] + outside) * inv;
        m[4] = a[4] * inv;
        return;
    }
    float ia = 1.0f / area, xs[2] = {u0, u1}, ys[2] = {v0, v1};
    for (uint32_t c = 0; c < 4; c++) {
        float x = xs[c & 1], y = ys[c >> 1];
        float sg = (c == 0 || c == 3) ? ia : -ia;
        uint32_t X = (uint32_t)x < R - 1 ? (uint32_t)x : R - 1, Y = (uint32_t)y < R - 1 ? (uint32_t)y : R - 1;
        float fx = x - (float)X, fy = y - (float)Y;
        for (uint32_t t = 0; t < 4; t++) {
            uint32_t xi = X + (t & 1), yi = Y + (t >> 1);
            if (xi == 0 || yi == 0) continue;
            float w = sg * (((t & 1) ? fx : 1.0f - fx) * ((t >> 1) ? fy : 1.0f - fy));
            const float *e = sat + 5 * ((size_t)(yi - 1) * R + (xi - 1));
            for (uint32_t p = 0; p < 5; p++) a[p] += w * e[p];
        }
    }
    for (uint32_t p = 0; p < 4; p++) m[p] = ((a[p] + mean[p]) * area + outside) * inv;
    m[4] = ((a[4] + mean[4]) * area) * inv;
}

/* the kernel's hl_msm_count */
static void count(const float *zsc, uint32_t R, float cx, float cy, float wu, float wv, float x0, float gu, float gv,
                  float xt, float xmax, float *o)
{
    float fR = (float)R;
    float u0 = fmaxf(cx - wu, 0.0f), u1 = fminf(cx + wu, fR);
    float v0 = fmaxf(cy - wv, 0.0f), v1 = fminf(cy + wv, fR);
    o[0] = 0.0f;
    o[1] = x0;
    if (!(u1 > u0 && v1 > v0)) return;
    float inv = 1.0f / ((2.0f * wu) * (2.0f * wv)), s = 0.0f, sx = 0.0f;
    uint32_t i0 = (uint32_t)u0, i1 = (uint32_t)ceilf(u1), j0 = (uint32_t)v0, j1 = (uint32_t)ceilf(v1);
    if (i1 > R) i1 = R;
    if (j1 > R) j1 = R;
    for (uint32_t j = j0; j < j1; j++) {
        float wy = fminf((float)(j + 1), v1) - fmaxf((float)j, v0);
        float xj = x0 + gv * (((float)j + 0.5f) - cy);
        for (uint32_t i = i0; i < i1; i++) {
            float x = zsc[4 * ((size_t)j * R + i)];
            float xr = fminf(xj + gu * (((float)i + 0.5f) - cx), xmax);
            if (x < 1.0f && x < xr - xt) {
                float ov = (fminf((float)(i + 1), u1) - fmaxf((float)i, u0)) * wy;
                s += ov;
                sx += ov * x;
            }
        }
    }
    o[0] = s * inv;
    if (s > 0.0f) o[1] = sx / s;
}

/* the kernel's hl_msm_casters */
static void casters(const float *m, float alpha, float *g)
{
    float c = fmaxf(m[4], alpha), e = 1.0f - c, ic = 1.0f / c;
    for (uint32_t p = 0; p < 4; p++) g[p] = (m[p] - e) * ic;
}

float hl_ref_msm_bound(const float m[4], float xf, float alpha, float *wb, float *xb)
{
    float ka = 1.0f - alpha;
    float b1 = ka * m[0], b2 = ka * m[1] + alpha * (1.0f / 3.0f), b3 = ka * m[2], b4 = ka * m[3] + alpha * 0.2f;
    float d22 = b2 - b1 * b1;
    float l32 = (b3 - b1 * b2) / d22;
    float d33 = (b4 - b2 * b2) - (l32 * l32) * d22;
    float y2 = xf - b1;
    float y3 = (xf * xf - b2) - l32 * y2;
    float c3 = y3 / d33;
    float c2 = y2 / d22 - l32 * c3;
    float c1 = (1.0f - b1 * c2) - b2 * c3;
    float ph = -0.5f * c2 / c3, q = c1 / c3;
    float r = sqrtf(fmaxf(ph * ph - q, 0.0f));
    float x2 = ph - r, x3 = ph + r;
    float G = 0.0f, w = 0.0f, xm = xf;
    if (xf <= x2) {
        G = 0.0f;
    } else if (xf <= x3) {
        G = ((xf * x3 - b1 * (xf + x3)) + b2) / ((x3 - x2) * (xf - x2));
        w = G;
        xm = x2;
    } else {
        float w1 = ((x2 * x3 - b1 * (x2 + x3)) + b2) / ((xf - x2) * (xf - x3));
        G = 1.0f - w1;
        w = G;
        xm = (b1 - w1 * xf) / G;
    }
    if (!(G >= 0.0f)) G = 0.0f;
    if (G > 1.0f) G = 1.0f;
    if (wb) {
        *wb = G > 0.0f ? w : 0.0f;
        *xb = G > 0.0f && xm == xm ? xm : xf;
    }
    return G;
}

void hl_ref_msm_eval(const float *sat, const float *mean, const float *zsc, const hl_msm_eval_params *p,
                     const float uvd[3], const float *rpl, float out[2])
{
    const uint32_t R = p->R;
    float cx = uvd[0], cy = uvd[1], dt = uvd[2];
    const float pl[3] = {rpl ? rpl[0] : 0.0f, rpl ? rpl[1] : 0.0f, rpl ? rpl[2] : dt};
    float d = fminf(dt, 1.0f), kb = p->kb, dh = p->direct_half, eps = p->eps;
    out[0] = 1.0f;
    out[1] = -1.0f;
    if (!(d > p->zmin)) return;
    float zr = fminf(dt * kb, 1.0f - 0.5f * (1.0f - kb));
    float fR = (float)R, xf = 2.0f * (zr - p->bias * kb) - 1.0f, m[5], g[4], wb, xb, c2[2];
    float gu = (2.0f * kb) * pl[0], gv = (2.0f * kb) * pl[1];
    float x0 = 2.0f * ((pl[2] - p->sbias) * kb) - 1.0f, xt = p->tbias * (fabsf(gu) + fabsf(gv)) + (2.0f * kb) * p->tfloor;
    float ws = dt - p->zmin, wsu = clampf(ws * p->su, p->wmin, fR), wsv = clampf(ws * p->sv, p->wmin, fR);
    float za;
    if (p->ptex > 0.0f && wsu <= dh && wsv <= dh) {
        count(zsc, R, cx, cy, wsu, wsv, x0, gu, gv, xt, kb, c2);
        if (!(c2[0] >= eps)) return;
        za = clampf(0.5f * (c2[1] + 1.0f) / kb, p->zmin, d);
    } else {
        box(sat, mean, zsc, R, cx, cy, wsu, wsv, dh, m);
        float cov = m[4];
        wb = 0.0f;
        xb = xf;
        if (cov >= eps) {
            casters(m, p->alpha, g);
            hl_ref_msm_bound(g, xf, fminf(p->alpha / cov, 1.0f), &wb, &xb);
        }
        if (cov >= eps && cov * wb >= eps) {
            za = clampf(0.5f * (xb + 1.0f) / kb, p->zmin, d);
        } else if (p->ptex > 0.0f && p->near_half > 0.0f) {
            float wn = fmaxf(fminf(p->near_half, fminf(wsu, wsv)), p->wmin);
            count(zsc, R, cx, cy, wn, wn, x0, gu, gv, xt, kb, c2);
            if (!(c2[0] >= eps)) return;
            za = clampf(0.5f * (c2[1] + 1.0f) / kb, p->zmin, d);
        } else {
            return;
        }
    }
    float wp = dt - za, wpu = clampf(wp * p->su, p->wmin, fR), wpv = clampf(wp * p->sv, p->wmin, fR);
    float V = 1.0f;
    if (p->ptex > 0.0f && wpu <= dh && wpv <= dh) {
        count(zsc, R, cx, cy, wpu, wpv, x0, gu, gv, xt, kb, c2);
        V = 1.0f - fminf(c2[0], 1.0f);
        if (p->ptex > 1.0f && p->lbr > 0.0f) V = (V - p->lbr) / (1.0f - p->lbr);
    } else {
        box(sat, mean, zsc, R, cx, cy, wpu, wpv, dh, m);
        float cov = m[4];
        if (cov > 0.0f) {
            casters(m, p->alpha, g);
            V = 1.0f - fminf(cov, 1.0f) * hl_ref_msm_bound(g, xf, fminf(p->alpha / cov, 1.0f), NULL, NULL);
        }
        if (p->lbr > 0.0f) V = (V - p->lbr) / (1.0f - p->lbr);
    }
    V = clampf(V, 0.0f, 1.0f);
    if (p->leak_a > 0.0f) {
        float pw = 1.0f + p->leak_a * expf(-p->leak_b * wp);
        V = V > 0.0f ? powf(V, pw) : 0.0f;
    }
    out[0] = V;
    out[1] = za;
}
