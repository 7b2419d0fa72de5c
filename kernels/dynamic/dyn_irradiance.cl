/* dyn_irradiance.cl - the dynamic method's per-vertex irradiance: each
 * kept area light's E_k(n) and the folded lights' SH9 ambient at every
 * receiver normal (DYNAMIC.md section 2; the host's hl_area_light_irradiance
 * and hl_light_split_ambient in area_lights.c, here in float).
 *
 * E_k(n) = n . evec where the light's cone is wholly above n's horizon
 * (n . dir >= sin extent), 0 where wholly below, else the texel sum
 * sum_t max(0, n . m_t) (the host's straddle_sum): the horizon cuts a cube
 * face along a straight line, so the rows wholly above it form one run
 * of rows, summed from the prefix sums of the row totals, those wholly
 * below another (skipped), and only the rows it crosses are taken one by
 * one: in each, the texels wholly above form one run, summed from the
 * row's prefix sums, and only the few it cuts are summed texel by texel.
 * Each light is stored twice, by rows and by columns (a "view"), and the
 * view whose rows the horizon crosses fewer of is walked. A run always
 * reaches one end of its row (or of the light), so each row keeps both its
 * prefix sums and its suffix sums (from the right), each a double sum
 * rounded once to float on the host: a run is one read, right to float
 * rounding of the run itself (a difference of prefix sums would carry the
 * rounding of the whole row, and a sun early in a row would drown the dim
 * texels after it).
 *
 * Layout (host/src/dynamic/irradiance.h; the same numbers there):
 *   lf, HL_DYN_IRR_LF floats a light: dir (3), sin extent (or 2 for a
 *       cone past a hemisphere), evec (9, channel-major), the face's
 *       origin o, d/ds and d/dt (3 each: face_point(s, t) = o + s ds + t dt),
 *       2 / F, 0.
 *   lu, HL_DYN_IRR_LU uints a light: two views of HL_DYN_IRR_VIEW uints,
 *       by rows then by columns, each: c0 c1 (the view's columns), r0 r1
 *       (its rows), its first texel in mom, its first row entry in pre,
 *       its first row-total entry in pre, 0.
 *   mom: 9 floats a texel, a view's texels row by row.
 *   pre: entries of 9 floats (sums of moments): per row of a view, w + 1
 *       prefix sums (entry j: columns c0..c0+j-1) then w + 1 suffix sums
 *       (entry j: columns c0+j..c1-1), w = c1 - c0; per view the same
 *       2 (h + 1) over the rows' totals, h = r1 - r0.
 *   sh: 27 floats, per channel the quadratic K0 + q_x x + q_y y + q_z z +
 *       q_xy xy + q_yz yz + q_zz z^2 + q_xz xz + q_d (x^2 - y^2).
 * A normal with a non-finite component gets E = 0 (the module refuses
 * such normals before the kernel runs; this keeps every index in range);
 * the ambient is the polynomial's value (NaN for NaN).
 * Twin: host/src/dynamic/twins/dyn_irradiance.c. Depends on: hl_shared.h.
 */

#define HL_DYN_IRR_LF 24
#define HL_DYN_IRR_LU 16
#define HL_DYN_IRR_VIEW 8

/* v clamped to [lo, hi] as an index (v an integer-valued float, huge or
 * NaN: NaN gives lo). */
static uint hl_dyn_irr_clamp(float v, uint lo, uint hi)
{
    if (!(v > (float)lo)) return lo;
    return v >= (float)hi ? hi : (uint)v;
}

/* acc[c] += n . e[c] for a run's summed moments e (9 floats) */
static void hl_dyn_irr_add(__global const float *e, float n0, float n1, float n2, float *acc)
{
    for (int ch = 0; ch < 3; ch++) acc[ch] += n0 * e[3 * ch] + n1 * e[3 * ch + 1] + n2 * e[3 * ch + 2];
}

/* One row y of a view across the horizon. With lo and hi the least and
 * largest of G0 + GY Y over the row, texel x (spanning [x, x + 1]) is
 * wholly above where lo + GX (x or x + 1) >= 0 and wholly below where
 * hi + GX (x + 1 or x) <= 0; r = -1 / GX. Texels whose corners are within
 * rounding of the horizon may land in either run; their n . m is then 0
 * to that rounding either way. */
static void hl_dyn_irr_row(__global const uint *vu, __global const float *mom, __global const float *pre, uint y,
                           float G0, float GX, float GY, float r, float n0, float n1, float n2, float *acc)
{
    const uint x0 = vu[0], x1 = vu[1], w = x1 - x0, yr = y - vu[2];
    float ya = (float)y, yb = (float)(y + 1);
    float lo = G0 + GY * (GY > 0.0f ? ya : yb), hi = G0 + GY * (GY > 0.0f ? yb : ya);
    uint pa = x0, pb = x0, c0 = x0, c1 = x0; /* the run above, the texels cut */
    if (GX > 0.0f) { /* above: x >= -lo / GX; below: x + 1 <= -hi / GX */
        pa = hl_dyn_irr_clamp(ceil(lo * r), x0, x1);
        pb = x1;
        c0 = hl_dyn_irr_clamp(floor(hi * r), x0, pa);
        c1 = pa;
    } else if (GX < 0.0f) { /* above: x + 1 <= -lo / GX; below: x >= -hi / GX */
        pb = hl_dyn_irr_clamp(floor(lo * r), x0, x1);
        c0 = pb;
        c1 = hl_dyn_irr_clamp(ceil(hi * r), pb, x1);
    } else if (lo >= 0.0f) {
        pb = x1;
    } else if (!(hi <= 0.0f)) {
        c1 = x1;
    }
    /* the run [pa, pb) reaches x1 (a suffix) or starts at x0 (a prefix) */
    __global const float *q = pre + 9 * ((size_t)vu[5] + (size_t)yr * 2 * (w + 1));
    if (pb > pa) hl_dyn_irr_add(q + 9 * (pb == x1 ? (w + 1) + (pa - x0) : pb - x0), n0, n1, n2, acc);
    __global const float *m = mom + 9 * ((size_t)vu[4] + (size_t)yr * w + (c0 - x0));
    for (uint x = c0; x < c1; x++, m += 9)
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
static void hl_dyn_irr_straddle(__global const float *lf, __global const uint *lu, __global const float *mom,
                                __global const float *pre, float n0, float n1, float n2, float *acc)
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
    const uint x0 = lu[0], x1 = lu[1], y0 = lu[2], y1 = lu[3];
    float mX = GX > 0.0f ? GX * (float)x0 : GX * (float)x1, MX = GX > 0.0f ? GX * (float)x1 : GX * (float)x0;
    float A = G0 + mX, B = G0 + MX; /* a row is wholly above where A + GY Y >= 0 over it, below where B + GY Y <= 0 */
    float r = GX != 0.0f ? -1.0f / GX : 0.0f, rr = GY != 0.0f ? -1.0f / GY : 0.0f;
    uint ua = y0, ub = y0, ca = y0, cb = y0; /* rows wholly above [ua, ub), crossed [ca, cb) */
    if (GY > 0.0f) { /* above: y >= -A / GY; below: y + 1 <= -B / GY */
        ua = hl_dyn_irr_clamp(ceil(A * rr), y0, y1);
        ub = y1;
        ca = hl_dyn_irr_clamp(floor(B * rr), y0, ua);
        cb = ua;
    } else if (GY < 0.0f) { /* above: y + 1 <= -A / GY; below: y >= -B / GY */
        ub = hl_dyn_irr_clamp(floor(A * rr), y0, y1);
        ca = ub;
        cb = hl_dyn_irr_clamp(ceil(B * rr), ub, y1);
    } else if (A >= 0.0f) {
        ub = y1;
    } else if (!(B <= 0.0f)) {
        cb = y1;
    }
    acc[0] = 0.0f;
    acc[1] = 0.0f;
    acc[2] = 0.0f;
    __global const float *q = pre + 9 * (size_t)lu[6];
    if (ub > ua) hl_dyn_irr_add(q + 9 * (ub == y1 ? (y1 - y0 + 1) + (ua - y0) : ub - y0), n0, n1, n2, acc);
    for (uint y = ca; y < cb; y++) hl_dyn_irr_row(lu, mom, pre, y, G0, GX, GY, r, n0, n1, n2, acc);
}

/* Light k (blocks lf, lu) at normal (n0, n1, n2) into rgb; 1 if lit. */
static int hl_dyn_irr_one(__global const float *lf, __global const uint *lu, __global const float *mom,
                          __global const float *pre, float n0, float n1, float n2, float *rgb)
{
    rgb[0] = 0.0f;
    rgb[1] = 0.0f;
    rgb[2] = 0.0f;
    if (!(fabs(n0) <= FLT_MAX && fabs(n1) <= FLT_MAX && fabs(n2) <= FLT_MAX)) return 0;
    float nd = n0 * lf[0] + n1 * lf[1] + n2 * lf[2], se = lf[3];
    if (nd >= se) {
        for (int c = 0; c < 3; c++) {
            float e = n0 * lf[4 + 3 * c] + n1 * lf[5 + 3 * c] + n2 * lf[6 + 3 * c];
            rgb[c] = e > 0.0f ? e : 0.0f;
        }
    } else if (!(nd <= -se)) {
        float acc[3];
        hl_dyn_irr_straddle(lf, lu, mom, pre, n0, n1, n2, acc);
        for (int c = 0; c < 3; c++) rgb[c] = acc[c] > 0.0f ? acc[c] : 0.0f;
    }
    return rgb[0] > 0.0f || rgb[1] > 0.0f || rgb[2] > 0.0f;
}

/* One work-item per (receiver v = id 0, light k = id 1): E[(k N + v) 3 + c];
 * any[k] set to 1 where some receiver is lit (read first, so a light lit
 * everywhere costs one atomic per core, not one per receiver). */
__kernel void hl_dyn_irr_lights(__global const float *lf, __global const uint *lu, __global const float *mom,
                                __global const float *pre, __global const float *nrm, uint N, uint K,
                                __global float *E, volatile __global uint *any)
{
    size_t v = get_global_id(0), k = get_global_id(1);
    if (v >= N || k >= K) return;
    float rgb[3];
    int lit = hl_dyn_irr_one(lf + HL_DYN_IRR_LF * k, lu + HL_DYN_IRR_LU * k, mom, pre, nrm[3 * v], nrm[3 * v + 1],
                             nrm[3 * v + 2], rgb);
    __global float *e = E + 3 * (k * N + v);
    e[0] = rgb[0];
    e[1] = rgb[1];
    e[2] = rgb[2];
    if (lit && any[k] == 0u) atomic_or(any + k, 1u);
}

/* The folded lights' SH9 irradiance at receiver v: amb[3 v + c]. */
__kernel void hl_dyn_irr_ambient(__constant float *sh, __global const float *nrm, uint N, __global float *amb)
{
    size_t v = get_global_id(0);
    if (v >= N) return;
    float x = nrm[3 * v], y = nrm[3 * v + 1], z = nrm[3 * v + 2];
    float xy = x * y, yz = y * z, zz = z * z, xz = x * z, d = x * x - y * y;
    for (int c = 0; c < 3; c++) {
        __constant float *q = sh + 9 * c;
        amb[3 * v + c] = q[0] + q[1] * x + q[2] * y + q[3] * z + q[4] * xy + q[5] * yz + q[6] * zz + q[7] * xz + q[8] * d;
    }
}
