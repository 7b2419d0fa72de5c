/* msm_eval.cl - moment shadow map visibility (Peters and Klein 2015, with
 * the blocker depth from the same moments as in Peters, Muenstermann,
 * Wetzstein and Klein 2016), one receiver of one light per work-item
 * (hl_msm_eval_one). The steps of csm_eval.cl with four moments in place
 * of the Fourier series:
 *   1. the box average of the moments (x, x^2, x^3, x^4), x = 2 z - 1,
 *      and of the coverage c over the search region (d - z_near)
 *      tan(theta); the casters' own moments from them (hl_msm_casters);
 *   2. the three-point distribution with those moments and one point at
 *      the receiver (the canonical representation through x_f): its
 *      weight below x_f, times c, is the blocker share, its mean there
 *      the average blocker depth;
 *   3. the box average over (d - z_avg) tan(theta) and the Hamburger
 *      4MSM bound of the casters' moments there: the smallest shadowed
 *      share any distribution with those moments can have, times c;
 *      V = 1 - that, then V below lbr taken as 0 (light-leak reduction).
 * Boxes read the summed-area tables (csm_sat.cl, P = 4) at fractional
 * corners (16 taps, exact for a piecewise-constant image), or texel by
 * texel (zsc: each texel's four moments) up to dh texels of half-width,
 * where the tables' rounding would be large against the box.
 * Outside the map is empty: its texels have z = 1, x = 1 and all four
 * moments 1, so a box reaching past the edge averages its inside with
 * those, and one that misses the map is lit.
 * Boxes summed texel by texel test each texel instead (hl_msm_count,
 * when ptex is on): a texel blocks where its caster is in front of the
 * receiver's tangent plane there (rpl: its slopes in the map and its
 * depth before the receiver-plane bias, hl_dyn_receiver) less half a
 * texel's depth change along the plane; the moments' bound only for the
 * larger boxes, where the tables' corners cannot see single texels.
 * prm (floats, HL_MSM_PRM_FLOATS): zmin su sv bias eps wmin alpha leak_a
 * leak_b lbr direct_half kb ptex tbias near sbias tfloor (hl_msm_eval_params in
 * host/src/dynamic/csm.h).
 * Depths: a caster's z is at z' = z kb (kb = 1 - the far band,
 * msm_basis.cl), an empty texel at z' = 1; a receiver at z' = d kb, or in
 * the band's middle, 1 - (1 - kb) / 2, where it lies beyond the far plane.
 * Twin: host/src/dynamic/twins/msm_eval.c. Depends on: hl_shared.h.
 */

/* Box average of the four moments and the coverage over [cx - wu, cx +
 * wu] x [cy - wv, cy + wv] into m[0..4], outside the map counting as
 * empty (moments 1, coverage 0). */
static void hl_msm_box(__global const float *sat, __global const float *mean, __global const float *zsc, uint R,
                       float cx, float cy, float wu, float wv, float dh, float *m)
{
    float fR = (float)R;
    float u0 = fmax(cx - wu, 0.0f), u1 = fmin(cx + wu, fR);
    float v0 = fmax(cy - wv, 0.0f), v1 = fmin(cy + wv, fR);
    if (!(u1 > u0 && v1 > v0)) { m[0] = 1.0f; m[1] = 1.0f; m[2] = 1.0f; m[3] = 1.0f; m[4] = 0.0f; return; }
    float full = (2.0f * wu) * (2.0f * wv), area = (u1 - u0) * (v1 - v0);
    float outside = fmax(full - area, 0.0f), inv = 1.0f / full;
    float a[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    if (wu <= dh && wv <= dh) {
        uint i0 = (uint)u0, i1 = min((uint)ceil(u1), R), j0 = (uint)v0, j1 = min((uint)ceil(v1), R);
        for (uint j = j0; j < j1; j++) {
            float wy = fmin((float)(j + 1), v1) - fmax((float)j, v0);
            for (uint i = i0; i < i1; i++) {
                float ov = (fmin((float)(i + 1), u1) - fmax((float)i, u0)) * wy;
                __global const float *t4 = zsc + 4 * ((size_t)j * R + i);
                for (uint p = 0; p < 4; p++) a[p] += ov * t4[p];
                a[4] += t4[0] < 1.0f ? ov : 0.0f; /* a caster's x is below 1 */
            }
        }
        for (uint p = 0; p < 4; p++) m[p] = (a[p] + outside) * inv;
        m[4] = a[4] * inv;
        return;
    }
    /* the tables: corner (x, y) of the box read bilinearly between the
       four table entries around it; entry (i, j) sums texels [0, i) x
       [0, j) (0 on the first row and column, which the table omits) */
    float ia = 1.0f / area, xs[2] = {u0, u1}, ys[2] = {v0, v1};
    for (uint c = 0; c < 4; c++) {
        float x = xs[c & 1], y = ys[c >> 1];
        float sg = (c == 0 || c == 3) ? ia : -ia;
        uint X = min((uint)x, R - 1), Y = min((uint)y, R - 1);
        float fx = x - (float)X, fy = y - (float)Y;
        for (uint t = 0; t < 4; t++) {
            uint xi = X + (t & 1), yi = Y + (t >> 1);
            if (xi == 0 || yi == 0) continue;
            float w = sg * (((t & 1) ? fx : 1.0f - fx) * ((t >> 1) ? fy : 1.0f - fy));
            __global const float *e = sat + 5 * ((size_t)(yi - 1) * R + (xi - 1));
            for (uint p = 0; p < 5; p++) a[p] += w * e[p];
        }
    }
    for (uint p = 0; p < 4; p++) m[p] = ((a[p] + mean[p]) * area + outside) * inv;
    m[4] = ((a[4] + mean[4]) * area) * inv;
}

/* The per-texel test over the box [cx - wu, cx + wu] x [cy - wv, cy + wv]
 * (the same texels and overlaps as hl_msm_box's small boxes): a texel
 * blocks where it holds a caster (x < 1) in front of the receiver's
 * plane there, x0 + gu du + gv dv (du, dv: the texel's centre from the
 * receiver's; at most xmax, the far band's middle) less xt. o[0] = the
 * blockers' share of the box (outside the map is empty), o[1] = their
 * mean x (x0 where there are none). */
static void hl_msm_count(__global const float *zsc, uint R, float cx, float cy, float wu, float wv, float x0, float gu,
                         float gv, float xt, float xmax, float *o)
{
    float fR = (float)R;
    float u0 = fmax(cx - wu, 0.0f), u1 = fmin(cx + wu, fR);
    float v0 = fmax(cy - wv, 0.0f), v1 = fmin(cy + wv, fR);
    o[0] = 0.0f;
    o[1] = x0;
    if (!(u1 > u0 && v1 > v0)) return;
    float inv = 1.0f / ((2.0f * wu) * (2.0f * wv)), s = 0.0f, sx = 0.0f;
    uint i0 = (uint)u0, i1 = min((uint)ceil(u1), R), j0 = (uint)v0, j1 = min((uint)ceil(v1), R);
    for (uint j = j0; j < j1; j++) {
        float wy = fmin((float)(j + 1), v1) - fmax((float)j, v0);
        float xj = x0 + gv * (((float)j + 0.5f) - cy);
        for (uint i = i0; i < i1; i++) {
            float x = zsc[4 * ((size_t)j * R + i)];
            float xr = fmin(xj + gu * (((float)i + 0.5f) - cx), xmax);
            if (x < 1.0f && x < xr - xt) {
                float ov = (fmin((float)(i + 1), u1) - fmax((float)i, u0)) * wy;
                s += ov;
                sx += ov * x;
            }
        }
    }
    o[0] = s * inv;
    if (s > 0.0f) o[1] = sx / s;
}

/* The Hamburger 4MSM bound of moments m (of x) at the receiver x_f, with
 * the moments first blended with weight alpha towards the uniform
 * distribution's on [-1, 1], (0, 1/3, 0, 1/5), so the 3 x 3 Hankel matrix
 * stays positive definite in float. Returns the least shadowed share G;
 * *wb and *xb (when wb is not NULL) get the three-point distribution's
 * weight below x_f and its mean depth there (x). */
static float hl_msm_bound(const float *m, float xf, float alpha, float *wb, float *xb)
{
    float ka = 1.0f - alpha;
    float b1 = ka * m[0], b2 = ka * m[1] + alpha * (1.0f / 3.0f), b3 = ka * m[2], b4 = ka * m[3] + alpha * 0.2f;
    /* LDL^T of [[1 b1 b2] [b1 b2 b3] [b2 b3 b4]], then B c = (1, xf, xf^2) */
    float d22 = b2 - b1 * b1;
    float l32 = (b3 - b1 * b2) / d22;
    float d33 = (b4 - b2 * b2) - (l32 * l32) * d22;
    float y2 = xf - b1;
    float y3 = (xf * xf - b2) - l32 * y2;
    float c3 = y3 / d33;
    float c2 = y2 / d22 - l32 * c3;
    float c1 = (1.0f - b1 * c2) - b2 * c3;
    /* the other two points: roots of c1 + c2 x + c3 x^2 */
    float ph = -0.5f * c2 / c3, q = c1 / c3;
    float r = sqrt(fmax(ph * ph - q, 0.0f));
    float x2 = ph - r, x3 = ph + r;
    float G = 0.0f, w = 0.0f, xm = xf;
    if (xf <= x2) {
        G = 0.0f; /* both other points at or behind the receiver */
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
    /* a degenerate matrix (NaN) or rounding past the ends: the bound
       holds in [0, 1], and an undefined one claims no shadow */
    if (!(G >= 0.0f)) G = 0.0f;
    if (G > 1.0f) G = 1.0f;
    if (wb) {
        *wb = G > 0.0f ? w : 0.0f;
        *xb = G > 0.0f && xm == xm ? xm : xf;
    }
    return G;
}

/* The casters' own moments from a box's (m: four moments and coverage
 * c): the box is c of casters and 1 - c of empty texels at x = 1, so the
 * casters' k-th moment is (m_k - (1 - c)) / c. Taking the empty texels'
 * mass out leaves the four moments to describe the casters alone, where
 * the empty texels were usually most of the box and set the bound's
 * leaks. Below a coverage of alpha the division is not attempted (lit:
 * the callers test c first). The rounding of m is divided by c too, so
 * the blend is alpha / c (callers), the same margin against it. */
static void hl_msm_casters(const float *m, float alpha, float *g)
{
    float c = fmax(m[4], alpha), e = 1.0f - c, ic = 1.0f / c;
    for (uint p = 0; p < 4; p++) g[p] = (m[p] - e) * ic;
}

/* Receiver (cx, cy, dt) of light `light` (parameters prm, the map's
 * nearest depth zmin; its plane pl, HL_DYN_RPL floats) into o[0] = V,
 * o[1] = z_avg (-1: no blocker). */
static void hl_msm_eval_one(__global const float *sats, __global const float *means, __global const float *zscs,
                            uint light, uint R, float zmin, __constant float *prm, float cx, float cy, float dt,
                            const float *pl, float *o)
{
    __global const float *sat = sats + (size_t)light * 5 * R * R, *mean = means + (size_t)light * 5;
    __global const float *zsc = zscs + (size_t)light * 4 * R * R;
    float su = prm[1], sv = prm[2], bias = prm[3], eps = prm[4], wmin = prm[5], alpha = prm[6];
    float la = prm[7], lb = prm[8], lbr = prm[9], dh = prm[10], kb = prm[11];
    float ptex = prm[12], tb = prm[13], nh = prm[14], sb = prm[15], tf = prm[16];
    float d = fmin(dt, 1.0f); /* beyond the far plane: on it, for z_avg */
    if (!(d > zmin)) { o[0] = 1.0f; o[1] = -1.0f; return; }
    float zr = fmin(dt * kb, 1.0f - 0.5f * (1.0f - kb));
    float fR = (float)R, xf = 2.0f * (zr - bias * kb) - 1.0f, m[5], g[4], wb, xb, c2[2];
    /* the plane in x = 2 z' - 1 for the per-texel test: the far band's
       middle is x = kb */
    float gu = (2.0f * kb) * pl[0], gv = (2.0f * kb) * pl[1];
    float x0 = 2.0f * ((pl[2] - sb) * kb) - 1.0f, xt = tb * (fabs(gu) + fabs(gv)) + (2.0f * kb) * tf;
    float ws = dt - zmin, wsu = clamp(ws * su, wmin, fR), wsv = clamp(ws * sv, wmin, fR);
    float za;
    if (ptex > 0.0f && wsu <= dh && wsv <= dh) {
        hl_msm_count(zsc, R, cx, cy, wsu, wsv, x0, gu, gv, xt, kb, c2);
        if (!(c2[0] >= eps)) { o[0] = 1.0f; o[1] = -1.0f; return; }
        za = clamp(0.5f * (c2[1] + 1.0f) / kb, zmin, d);
    } else {
        hl_msm_box(sat, mean, zsc, R, cx, cy, wsu, wsv, dh, m);
        float cov = m[4];
        wb = 0.0f;
        xb = xf;
        if (cov >= eps) {
            hl_msm_casters(m, alpha, g);
            hl_msm_bound(g, xf, fmin(alpha / cov, 1.0f), &wb, &xb);
        }
        if (cov >= eps && cov * wb >= eps) {
            za = clamp(0.5f * (xb + 1.0f) / kb, zmin, d);
        } else if (ptex > 0.0f && nh > 0.0f) {
            /* the near search: blockers nearer than the biases that the
               large box's bound does not see, texel by texel */
            float wn = fmax(fmin(nh, fmin(wsu, wsv)), wmin);
            hl_msm_count(zsc, R, cx, cy, wn, wn, x0, gu, gv, xt, kb, c2);
            if (!(c2[0] >= eps)) { o[0] = 1.0f; o[1] = -1.0f; return; }
            za = clamp(0.5f * (c2[1] + 1.0f) / kb, zmin, d);
        } else {
            o[0] = 1.0f;
            o[1] = -1.0f;
            return;
        }
    }
    float wp = dt - za, wpu = clamp(wp * su, wmin, fR), wpv = clamp(wp * sv, wmin, fR);
    float V = 1.0f;
    if (ptex > 0.0f && wpu <= dh && wpv <= dh) {
        hl_msm_count(zsc, R, cx, cy, wpu, wpv, x0, gu, gv, xt, kb, c2);
        V = 1.0f - fmin(c2[0], 1.0f);
        /* the reduction as for the bound where ptex > 1, so that a box
           crossing the size limit does not change the visibility's scale */
        if (ptex > 1.0f && lbr > 0.0f) V = (V - lbr) / (1.0f - lbr);
    } else {
        hl_msm_box(sat, mean, zsc, R, cx, cy, wpu, wpv, dh, m);
        float cov = m[4];
        if (cov > 0.0f) {
            hl_msm_casters(m, alpha, g);
            V = 1.0f - fmin(cov, 1.0f) * hl_msm_bound(g, xf, fmin(alpha / cov, 1.0f), NULL, NULL);
        }
        /* light-leak reduction: visibility below lbr is taken as none */
        if (lbr > 0.0f) V = (V - lbr) / (1.0f - lbr);
    }
    V = clamp(V, 0.0f, 1.0f);
    if (la > 0.0f) {
        float pw = 1.0f + la * exp(-lb * wp);
        V = V > 0.0f ? pow(V, pw) : 0.0f;
    }
    o[0] = V;
    o[1] = za;
}

/* hl_csm_eval_batch's moment form (csm.c, hl_csm_visibility_batch):
 * receiver r belongs to entry which[r], light lights[which[r]], with the
 * parameters at prms + which[r] * nprm; its plane at rpl + HL_DYN_RPL r. */
__kernel void hl_msm_eval_batch(__global const float *sats, __global const float *means, __global const float *zscs,
                                uint R, __constant float *prms, uint nprm, __global const uint *lights,
                                __global const uint *which, __global const float *uvd, __global const float *rpl, uint n,
                                __global float *out)
{
    size_t r = get_global_id(0);
    if (r >= n) return;
    const uint j = which[r];
    float o[2], pl[HL_DYN_RPL];
    for (uint i = 0; i < HL_DYN_RPL; i++) pl[i] = rpl[HL_DYN_RPL * r + i];
    __constant float *prm = prms + (size_t)j * nprm;
    hl_msm_eval_one(sats, means, zscs, lights[j], R, prm[0], prm, uvd[3 * r], uvd[3 * r + 1], uvd[3 * r + 2], pl, o);
    out[2 * r] = o[0];
    out[2 * r + 1] = o[1];
}

/* hl_csm_eval_grid's moment form (the device frame, dyn_frame.c): entries
 * j0 .. j0 + nl - 1 at every one of N receivers, uvd and rpl as
 * hl_dyn_prepare leaves them (u = NaN: not reached), the nearest depth from zmins. */
__kernel void hl_msm_eval_grid(__global const float *sats, __global const float *means, __global const float *zscs,
                               uint R, __constant float *prms, uint nprm, __global const uint *lights,
                               __global const float *zmins, __global const float *uvd, __global const float *rpl, uint N,
                               uint j0, uint nl, __global float *V)
{
    const size_t id = get_global_id(0), at = (size_t)j0 * N + id;
    if (id >= (size_t)nl * N || isnan(uvd[3 * at])) return;
    const uint jj = (uint)(id / N), light = lights[jj];
    float o[2], pl[HL_DYN_RPL];
    for (uint i = 0; i < HL_DYN_RPL; i++) pl[i] = rpl[HL_DYN_RPL * at + i];
    hl_msm_eval_one(sats, means, zscs, light, R, zmins[light], prms + (size_t)jj * nprm, uvd[3 * at], uvd[3 * at + 1],
                    uvd[3 * at + 2], pl, o);
    V[at] = o[0];
}
