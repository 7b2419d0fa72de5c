/* csm_eval.cl - convolution shadow map visibility, one receiver of one
 * light per work-item (hl_csm_eval_one; Annen et al. 2008): a blocker search over a box of
 * half-width (d - z_near) tan(theta), the average blocker depth z_avg from
 * the z-weighted planes, a box of half-width (d - z_avg) tan(theta) for
 * the filtered test, then V^p against contact leaks. Boxes read the
 * summed-area tables (csm_sat.cl) at fractional corners: the table of a
 * piecewise-constant image is bilinear inside each texel, so bilinear
 * interpolation between integer corners is exact (16 reads a plane).
 * A box no wider than 2 dh texels (dh = prm[41]) is summed texel by
 * texel from the texels' (z, sin(c1 z), cos(c1 z)) (csm_basis.cl) instead (the series evaluated at each texel,
 * weighted by its overlap): the tables' entries reach 1e4 at R = 256, so
 * a corner difference carries about 1e-3 of rounding, too much once
 * divided by a box of a few texels (test_csm_sat.c, precision).
 * Outside the map is empty (the frame holds every caster with an empty
 * margin): a box reaching past the edge averages its inside with "lit",
 * and a receiver whose boxes miss the map is lit. The widths use the
 * receiver's own depth, also beyond the far plane; the series uses at
 * most 1 (on the far plane), where it is valid.
 * prm (floats): zmin su sv bias eps wmin leak_a leak_b c1, coef[16],
 * coefb[16], direct_half, bias_b (hl_csm_eval_params in
 * host/src/dynamic/csm.h).
 * Twin: host/src/dynamic/twins/csm_eval.c. Depends on: hl_shared.h.
 */

/* The share of the box (centre, half-widths) inside [0, R]^2: 0 when it
 * misses the map (or a coordinate is not finite). */
static float hl_csm_inside(float cx, float cy, float wu, float wv, uint R)
{
    float fR = (float)R;
    float u0 = fmax(cx - wu, 0.0f), u1 = fmin(cx + wu, fR);
    float v0 = fmax(cy - wv, 0.0f), v1 = fmin(cy + wv, fR);
    if (!(u1 > u0 && v1 > v0)) return 0.0f;
    return ((u1 - u0) * (v1 - v0)) / ((2.0f * wu) * (2.0f * wv));
}

/* 16 taps of a box [u0, u1] x [v0, v1] (clipped to [0, R]): index into a
 * plane and weight (corner sign / area times the bilinear weight). */
/* the most planes of one light: 2 M + 2 Mb + 1 with M, Mb <= 16 */
#define HL_CSM_MAX_PLANES 65

static void hl_csm_box_taps(float cx, float cy, float wu, float wv, uint R, uint *idx, float *w)
{
    float fR = (float)R;
    float u0 = fmax(cx - wu, 0.0f), u1 = fmin(cx + wu, fR);
    float v0 = fmax(cy - wv, 0.0f), v1 = fmin(cy + wv, fR);
    float inv = 1.0f / ((u1 - u0) * (v1 - v0));
    float xs[2] = {u0, u1}, ys[2] = {v0, v1};
    for (uint c = 0; c < 4; c++) {
        float x = xs[c & 1], y = ys[c >> 1];
        float sg = ((c == 0 || c == 3) ? inv : -inv);
        uint X = min((uint)x, R - 1), Y = min((uint)y, R - 1);
        float fx = x - (float)X, fy = y - (float)Y;
        for (uint t = 0; t < 4; t++) {
            uint xi = X + (t & 1), yi = Y + (t >> 1);
            float wx = (t & 1) ? fx : 1.0f - fx, wy = (t >> 1) ? fy : 1.0f - fy;
            uint k = 4 * c + t;
            int live = xi > 0 && yi > 0;
            idx[k] = live ? (yi - 1) * R + (xi - 1) : 0;
            w[k] = live ? sg * (wx * wy) : 0.0f;
        }
    }
}

/* Box averages of f_n(db, z), z and f_n z over [u0, u1] x [v0, v1],
 * texel by texel, with f_n = 1/2 + sum_k coef[k] sin((2k-1) c1 (z - db)).
 * zsc: per texel z, sin(c1 z), cos(c1 z); (s0, c0) = (sin, cos)(c1 db). */
static void hl_csm_direct(__global const float *zsc, uint R, float cx, float cy, float wu, float wv, float s0,
                          float c0, __constant float *coef, uint n, float *out)
{
    float fR = (float)R;
    float u0 = fmax(cx - wu, 0.0f), u1 = fmin(cx + wu, fR);
    float v0 = fmax(cy - wv, 0.0f), v1 = fmin(cy + wv, fR);
    /* the box misses the map: all empty (and no float-to-uint of a negative) */
    if (!(u1 > u0 && v1 > v0)) { out[0] = 1.0f; out[1] = 1.0f; out[2] = 1.0f; return; }
    uint i0 = (uint)u0, i1 = min((uint)ceil(u1), R), j0 = (uint)v0, j1 = min((uint)ceil(v1), R);
    float af = 0.0f, az = 0.0f, afz = 0.0f;
    for (uint j = j0; j < j1; j++) {
        float wy = fmin((float)(j + 1), v1) - fmax((float)j, v0);
        for (uint i = i0; i < i1; i++) {
            float ov = (fmin((float)(i + 1), u1) - fmax((float)i, u0)) * wy;
            __global const float *t4 = zsc + 4 * ((size_t)j * R + i);
            float z = t4[0];
            /* sin and cos of c1 (z - db) by the difference formulas */
            float s = t4[1] * c0 - t4[2] * s0, c = t4[2] * c0 + t4[1] * s0;
            float rs = 2.0f * s * c, rc = c * c - s * s, f = 0.5f;
            for (uint k = 0; k < n; k++) {
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
    /* outside the map: empty texels, z = 1 and f = 1 */
    float full = (2.0f * wu) * (2.0f * wv), outside = fmax(full - (u1 - u0) * (v1 - v0), 0.0f);
    float inv = 1.0f / full;
    out[0] = (af + outside) * inv;
    out[1] = (az + outside) * inv;
    out[2] = (afz + outside) * inv;
}

/* Box sums of planes p0..p1-1 into acc[p] (plus each plane's mean): the
 * planes are interleaved by texel, so each tap reads them in one run. */
static void hl_csm_box(__global const float *sat, __global const float *mean, uint P, const uint *idx, const float *w, uint p0, uint p1,
                       float *acc)
{
    for (uint p = p0; p < p1; p++) acc[p] = 0.0f;
    for (uint t = 0; t < 16; t++) {
        __global const float *row = sat + (size_t)idx[t] * P;
        for (uint p = p0; p < p1; p++) acc[p] += w[t] * row[p];
    }
    for (uint p = p0; p < p1; p++) acc[p] += mean[p];
}

/* The blocker search's box averages of fbar = 1 - f and fbar z (order
 * Mb), out[0], out[1]. */
static void hl_csm_search(__global const float *sat, __global const float *mean, __global const float *zsc, uint R,
                          uint M, uint Mb, float cx, float cy, float wu, float wv, float dh,
                          __constant float *coefb, const float *cs, const float *sn, float *out)
{
    float dv[3];
    if (wu <= dh && wv <= dh) {
        hl_csm_direct(zsc, R, cx, cy, wu, wv, sn[0], cs[0], coefb, Mb, dv);
        out[0] = 1.0f - dv[0];
        out[1] = dv[1] - dv[2];
        return;
    }
    float in = hl_csm_inside(cx, cy, wu, wv, R);
    if (!(in > 0.0f)) { out[0] = 0.0f; out[1] = 0.0f; return; }
    uint P = 2 * M + 2 * Mb + 1, idx[16];
    float w[16], a[HL_CSM_MAX_PLANES];
    hl_csm_box_taps(cx, cy, wu, wv, R, idx, w);
    hl_csm_box(sat, mean, P, idx, w, 0, 1 + 2 * Mb, a);
    hl_csm_box(sat, mean, P, idx, w, 1 + 2 * M, P, a);
    float fb = 0.5f, fz = 0.5f * a[0];
    for (uint k = 0; k < Mb; k++) {
        uint p = 1 + 2 * k, q = 1 + 2 * M + 2 * k;
        fb -= coefb[k] * (cs[k] * a[p] - sn[k] * a[p + 1]);
        fz -= coefb[k] * (cs[k] * a[q] - sn[k] * a[q + 1]);
    }
    /* outside: fbar = 0 */
    out[0] = fb * in;
    out[1] = fz * in;
}

/* The filtered test over the penumbra box (order M), unclamped. */
static float hl_csm_filter(__global const float *sat, __global const float *mean, __global const float *zsc, uint R,
                           uint M, uint Mb, float cx, float cy, float wu, float wv, float dh,
                           __constant float *coef, const float *cs, const float *sn)
{
    float dv[3];
    if (wu <= dh && wv <= dh) {
        hl_csm_direct(zsc, R, cx, cy, wu, wv, sn[0], cs[0], coef, M, dv);
        return dv[0];
    }
    float in = hl_csm_inside(cx, cy, wu, wv, R);
    if (!(in > 0.0f)) return 1.0f;
    uint P = 2 * M + 2 * Mb + 1, idx[16];
    float w[16], a[HL_CSM_MAX_PLANES];
    hl_csm_box_taps(cx, cy, wu, wv, R, idx, w);
    hl_csm_box(sat, mean, P, idx, w, 1, 1 + 2 * M, a);
    float V = 0.5f;
    for (uint k = 0; k < M; k++) V += coef[k] * (cs[k] * a[1 + 2 * k] - sn[k] * a[2 + 2 * k]);
    return V * in + (1.0f - in); /* outside: lit */
}

/* sin and cos of (2k - 1) ph, k = 1..n, by the rotation of csm_basis.cl */
static void hl_csm_phases(float ph, uint n, float *cs, float *sn)
{
    float s = sin(ph), c = cos(ph);
    float rs = 2.0f * s * c, rc = c * c - s * s;
    for (uint k = 0; k < n; k++) {
        sn[k] = s;
        cs[k] = c;
        float s2 = s * rc + c * rs, c2 = c * rc - s * rs;
        s = s2;
        c = c2;
    }
}

/* Receiver (cx, cy, dt) of light `light` with parameters prm and the
 * map's nearest depth zmin (prm[0] unread) into o[0] = V, o[1] = z_avg
 * (-1: nothing in front). */
static void hl_csm_eval_one(__global const float *sats, __global const float *means, __global const float *zscs,
                            uint light, uint R, uint M, uint Mb, float zmin, __constant float *prm, float cx, float cy,
                            float dt, float *o)
{
    uint P = 2 * M + 2 * Mb + 1;
    __global const float *sat = sats + (size_t)light * P * R * R, *mean = means + (size_t)light * P;
    __global const float *zsc = zscs + (size_t)light * R * R * 4;
    float su = prm[1], sv = prm[2], bias = prm[3], eps = prm[4], wmin = prm[5];
    float la = prm[6], lb = prm[7], c1 = prm[8], dh = prm[41], bias_b = prm[42];
    __constant float *coef = prm + 9, *coefb = prm + 25;
    float d = fmin(dt, 1.0f); /* beyond the far plane: on it, for the series */
    float db = d - bias;
    /* nothing in the map is nearer than the receiver: lit */
    if (!(d > zmin)) { o[0] = 1.0f; o[1] = -1.0f; return; }
    float fR = (float)R;
    /* phases c_k d' for the filter (bias 1/M) and the search (1/Mb: its
     * band is as wide as its order makes it) */
    float cs[16], sn[16], csb[16], snb[16];
    hl_csm_phases(c1 * db, M, cs, sn);
    hl_csm_phases(c1 * (d - bias_b), Mb, csb, snb);
    float ws = dt - zmin, sr[2];
    hl_csm_search(sat, mean, zsc, R, M, Mb, cx, cy, clamp(ws * su, wmin, fR), clamp(ws * sv, wmin, fR), dh, coefb, csb,
                  snb, sr);
    if (!(sr[0] >= eps)) { o[0] = 1.0f; o[1] = -1.0f; return; }
    float za = clamp(sr[1] / sr[0], zmin, d);
    float wp = dt - za;
    float V = hl_csm_filter(sat, mean, zsc, R, M, Mb, cx, cy, clamp(wp * su, wmin, fR), clamp(wp * sv, wmin, fR), dh,
                            coef, cs, sn);
    V = clamp(V, 0.0f, 1.0f);
    float pw = 1.0f + la * exp(-lb * wp);
    o[0] = V > 0.0f ? pow(V, pw) : 0.0f;
    o[1] = za;
}

/* Lights of the build in one launch (csm.c, hl_csm_visibility_batch,
 * which a single light's visibility is a batch of one): receiver r
 * belongs to entry which[r] of the batch, light lights[which[r]] with
 * the parameters at prms + which[r] * nprm. */
__kernel void hl_csm_eval_batch(__global const float *sats, __global const float *means, __global const float *zscs,
                                uint R, uint M, uint Mb, __constant float *prms, uint nprm,
                                __global const uint *lights, __global const uint *which, __global const float *uvd,
                                uint n, __global float *out)
{
    size_t r = get_global_id(0);
    if (r >= n) return;
    const uint j = which[r];
    float o[2];
    __constant float *prm = prms + (size_t)j * nprm;
    hl_csm_eval_one(sats, means, zscs, lights[j], R, M, Mb, prm[0], prm, uvd[3 * r], uvd[3 * r + 1], uvd[3 * r + 2], o);
    out[2 * r] = o[0];
    out[2 * r + 1] = o[1];
}

/* The device frame's evaluation (host/src/dynamic/dyn_frame.c): entries
 * j0 .. j0 + nl - 1 of a group at every one of N receivers, work-item
 * (j - j0) N + v reading the group's place j N + v of uvd and V; uvd as
 * hl_dyn_prepare leaves it (u = NaN: the light does not reach the
 * receiver, passed by); entry j's parameters and build light at j - j0
 * of prms and lights, the map's nearest depth from zmins (hl_csm_zmin)
 * rather than prm[0]; V only, left on the device. */
__kernel void hl_csm_eval_grid(__global const float *sats, __global const float *means, __global const float *zscs,
                               uint R, uint M, uint Mb, __constant float *prms, uint nprm, __global const uint *lights,
                               __global const float *zmins, __global const float *uvd, uint N, uint j0, uint nl,
                               __global float *V)
{
    const size_t id = get_global_id(0), at = (size_t)j0 * N + id;
    if (id >= (size_t)nl * N || isnan(uvd[3 * at])) return;
    const uint jj = (uint)(id / N), light = lights[jj];
    float o[2];
    hl_csm_eval_one(sats, means, zscs, light, R, M, Mb, zmins[light], prms + (size_t)jj * nprm, uvd[3 * at],
                    uvd[3 * at + 1], uvd[3 * at + 2], o);
    V[at] = o[0];
}

/* Each of K maps' nearest depth (below 1, the empty texel's, or 1): one
 * group a map, a minimum in any order being the same. */
__kernel void hl_csm_zmin(__global const float *depth, uint R2, __global float *zmin, __local float *part)
{
    const uint k = (uint)get_group_id(0), l = (uint)get_local_id(0), L = (uint)get_local_size(0);
    __global const float *map = depth + (size_t)k * R2;
    float m = 1.0f;
    for (uint i = l; i < R2; i += L) m = fmin(m, map[i]);
    part[l] = m;
    for (uint h = L / 2; h > 0; h /= 2) {
        barrier(CLK_LOCAL_MEM_FENCE);
        if (l < h) part[l] = fmin(part[l], part[l + h]);
    }
    if (l == 0) zmin[k] = part[0];
}
