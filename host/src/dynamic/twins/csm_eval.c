/* csm_eval.c - twin of kernels/dynamic/csm_eval.cl: one receiver of one
 * light: blocker search, average blocker depth, filtered shadow test over
 * the penumbra box (from the tables, or texel by texel for a small box),
 * contact-leak exponent; the kernel's formulas and order of additions.
 * Depends on: csm.h. */
#include <math.h>

#include "csm.h"

static float clampf(float x, float lo, float hi) { return x < lo ? lo : x > hi ? hi : x; }

/* the kernel's hl_csm_inside */
static float inside(float cx, float cy, float wu, float wv, uint32_t R)
{
    float fR = (float)R;
    float u0 = fmaxf(cx - wu, 0.0f), u1 = fminf(cx + wu, fR);
    float v0 = fmaxf(cy - wv, 0.0f), v1 = fminf(cy + wv, fR);
    if (!(u1 > u0 && v1 > v0)) return 0.0f;
    return ((u1 - u0) * (v1 - v0)) / ((2.0f * wu) * (2.0f * wv));
}

/* the kernel's hl_csm_box_taps */
static void box_taps(float cx, float cy, float wu, float wv, uint32_t R, uint32_t *idx, float *w)
{
    float fR = (float)R;
    float u0 = fmaxf(cx - wu, 0.0f), u1 = fminf(cx + wu, fR);
    float v0 = fmaxf(cy - wv, 0.0f), v1 = fminf(cy + wv, fR);
    float inv = 1.0f / ((u1 - u0) * (v1 - v0));
    float xs[2] = {u0, u1}, ys[2] = {v0, v1};
    for (uint32_t c = 0; c < 4; c++) {
        float x = xs[c & 1], y = ys[c >> 1];
        float sg = (c == 0 || c == 3) ? inv : -inv;
        uint32_t X = (uint32_t)x < R - 1 ? (uint32_t)x : R - 1, Y = (uint32_t)y < R - 1 ? (uint32_t)y : R - 1;
        float fx = x - (float)X, fy = y - (float)Y;
        for (uint32_t t = 0; t < 4; t++) {
            uint32_t xi = X + (t & 1), yi = Y + (t >> 1);
            float wx = (t & 1) ? fx : 1.0f - fx, wy = (t >> 1) ? fy : 1.0f - fy;
            uint32_t k = 4 * c + t;
            int live = xi > 0 && yi > 0;
            idx[k] = live ? (yi - 1) * R + (xi - 1) : 0;
            w[k] = live ? sg * (wx * wy) : 0.0f;
        }
    }
}

/* Box sums of planes p0..p1-1 into acc[p] (plus each plane's mean): the
 * planes are interleaved by texel, so each tap reads them in one run. */
static void box(const float *sat, const float *mean, uint32_t P, const uint32_t *idx, const float *w, uint32_t p0, uint32_t p1,
                       float *acc)
{
    for (uint32_t p = p0; p < p1; p++) acc[p] = 0.0f;
    for (uint32_t t = 0; t < 16; t++) {
        const float *row = sat + (size_t)idx[t] * P;
        for (uint32_t p = p0; p < p1; p++) acc[p] += w[t] * row[p];
    }
    for (uint32_t p = p0; p < p1; p++) acc[p] += mean[p];
}

/* the kernel's hl_csm_direct: box averages of f_n, z and f_n z texel by
 * texel, from the texels' (z, sin(c1 z), cos(c1 z)) and (s0, c0) =
 * (sin, cos)(c1 db) */
static void direct(const float *zsc, uint32_t R, float cx, float cy, float wu, float wv, float s0, float c0,
                   const float *coef, uint32_t n, float *out)
{
    float fR = (float)R;
    float u0 = fmaxf(cx - wu, 0.0f), u1 = fminf(cx + wu, fR);
    float v0 = fmaxf(cy - wv, 0.0f), v1 = fminf(cy + wv, fR);
    if (!(u1 > u0 && v1 > v0)) { out[0] = 1.0f; out[1] = 1.0f; out[2] = 1.0f; return; }
    uint32_t i0 = (uint32_t)u0, i1 = (uint32_t)ceilf(u1), j0 = (uint32_t)v0, j1 = (uint32_t)ceilf(v1);
    if (i1 > R) i1 = R;
    if (j1 > R) j1 = R;
    float af = 0.0f, az = 0.0f, afz = 0.0f;
    for (uint32_t j = j0; j < j1; j++) {
        float wy = fminf((float)(j + 1), v1) - fmaxf((float)j, v0);
        for (uint32_t i = i0; i < i1; i++) {
            float ov = (fminf((float)(i + 1), u1) - fmaxf((float)i, u0)) * wy;
            const float *t4 = zsc + 4 * ((size_t)j * R + i);
            float z = t4[0];
            float s = t4[1] * c0 - t4[2] * s0, c = t4[2] * c0 + t4[1] * s0;
            float rs = 2.0f * s * c, rc = c * c - s * s, f = 0.5f;
            for (uint32_t k = 0; k < n; k++) {
                f += coef[k] * s;
                float s2 = s * rc + c * rs, c2 = c * rc - s * rs;
                s = s2;
                c = c2;
            }
            af += ov * f;
            az += ov * z;
            afz += ov * (f * z);
        }
    }
    float full = (2.0f * wu) * (2.0f * wv), outside = fmaxf(full - (u1 - u0) * (v1 - v0), 0.0f);
    float inv = 1.0f / full;
    out[0] = (af + outside) * inv;
    out[1] = (az + outside) * inv;
    out[2] = (afz + outside) * inv;
}

/* the kernel's hl_csm_search: box averages of fbar and fbar z */
static void search(const float *sat, const float *mean, const float *zsc, const hl_csm_eval_params *p, float cx,
                   float cy, float wu, float wv, const float *cs, const float *sn, float *out)
{
    const uint32_t R = p->R, M = p->M;
    float dv[3];
    if (wu <= p->direct_half && wv <= p->direct_half) {
        direct(zsc, R, cx, cy, wu, wv, sn[0], cs[0], p->coefb, p->Mb, dv);
        out[0] = 1.0f - dv[0];
        out[1] = dv[1] - dv[2];
        return;
    }
    float in = inside(cx, cy, wu, wv, R);
    if (!(in > 0.0f)) { out[0] = 0.0f; out[1] = 0.0f; return; }
    const uint32_t Mb = p->Mb, P = hl_csm_planes(M, Mb);
    uint32_t idx[16];
    float w[16], a[4 * HL_CSM_M_MAX + 1];
    box_taps(cx, cy, wu, wv, R, idx, w);
    box(sat, mean, P, idx, w, 0, 1 + 2 * Mb, a);
    box(sat, mean, P, idx, w, 1 + 2 * M, P, a);
    float fb = 0.5f, fz = 0.5f * a[0];
    for (uint32_t k = 0; k < Mb; k++) {
        uint32_t s = 1 + 2 * k, q = 1 + 2 * M + 2 * k;
        fb -= p->coefb[k] * (cs[k] * a[s] - sn[k] * a[s + 1]);
        fz -= p->coefb[k] * (cs[k] * a[q] - sn[k] * a[q + 1]);
    }
    out[0] = fb * in;
    out[1] = fz * in;
}

/* the kernel's hl_csm_filter: the filtered test, unclamped */
static float filter(const float *sat, const float *mean, const float *zsc, const hl_csm_eval_params *p, float cx,
                    float cy, float wu, float wv, const float *cs, const float *sn)
{
    const uint32_t R = p->R;
    float dv[3];
    if (wu <= p->direct_half && wv <= p->direct_half) {
        direct(zsc, R, cx, cy, wu, wv, sn[0], cs[0], p->coef, p->M, dv);
        return dv[0];
    }
    float in = inside(cx, cy, wu, wv, R);
    if (!(in > 0.0f)) return 1.0f;
    const uint32_t M = p->M, P = hl_csm_planes(M, p->Mb);
    uint32_t idx[16];
    float w[16], a[4 * HL_CSM_M_MAX + 1];
    box_taps(cx, cy, wu, wv, R, idx, w);
    box(sat, mean, P, idx, w, 1, 1 + 2 * M, a);
    float V = 0.5f;
    for (uint32_t k = 0; k < M; k++) V += p->coef[k] * (cs[k] * a[1 + 2 * k] - sn[k] * a[2 + 2 * k]);
    return V * in + (1.0f - in);
}

/* the kernel's hl_csm_phases */
static void phases(float ph, uint32_t n, float *cs, float *sn)
{
    float s = sinf(ph), c = cosf(ph);
    float rs = 2.0f * s * c, rc = c * c - s * s;
    for (uint32_t k = 0; k < n; k++) {
        sn[k] = s;
        cs[k] = c;
        float s2 = s * rc + c * rs, c2 = c * rc - s * rs;
        s = s2;
        c = c2;
    }
}

void hl_ref_csm_eval(const float *sat, const float *mean, const float *zsc, const hl_csm_eval_params *p,
                     const float uvd[3], float out[2])
{
    const uint32_t R = p->R, M = p->M;
    float cx = uvd[0], cy = uvd[1], dt = uvd[2];
    float d = fminf(dt, 1.0f); /* beyond the far plane: on it, for the series */
    float db = d - p->bias;
    out[0] = 1.0f;
    out[1] = -1.0f;
    if (!(d > p->zmin)) return; /* nothing in the map is nearer: lit */
    float fR = (float)R;
    float cs[HL_CSM_M_MAX], sn[HL_CSM_M_MAX], csb[HL_CSM_M_MAX], snb[HL_CSM_M_MAX];
    phases(p->c1 * db, M, cs, sn);
    phases(p->c1 * (d - p->bias_b), p->Mb, csb, snb);
    float ws = dt - p->zmin, sr[2];
    search(sat, mean, zsc, p, cx, cy, clampf(ws * p->su, p->wmin, fR), clampf(ws * p->sv, p->wmin, fR), csb, snb, sr);
    if (!(sr[0] >= p->eps)) return;
    float za = clampf(sr[1] / sr[0], p->zmin, d);
    float wp = dt - za;
    float V = filter(sat, mean, zsc, p, cx, cy, clampf(wp * p->su, p->wmin, fR), clampf(wp * p->sv, p->wmin, fR), cs,
                     sn);
    V = clampf(V, 0.0f, 1.0f);
    float pw = 1.0f + p->leak_a * expf(-p->leak_b * wp);
    out[0] = V > 0.0f ? powf(V, pw) : 0.0f;
    out[1] = za;
}
