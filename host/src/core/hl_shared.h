/* hl_shared.h - data layouts and scalar formulas shared by host and kernels.
 *
 * Compiles as C11 and as OpenCL C 1.2: the build prepends this file to every
 * kernel program. Anything both sides must agree on to the bit lives here
 * (struct layouts, quantisation formulas), so that the OpenCL stages and
 * their plain-C twins produce identical integers from identical floats.
 * The host pins the layouts with _Static_assert in host/src/device/layout_check.c.
 */
#ifndef HL_SHARED_H
#define HL_SHARED_H

#ifdef __OPENCL_C_VERSION__
/* No fused multiply-add contraction anywhere in the program, these inline
 * formulas included: the plain-C twins are built with -ffp-contract=off,
 * and both sides must round alike. */
#pragma OPENCL FP_CONTRACT OFF
#define HL_U32 uint
#define HL_U64 ulong
#define HL_INLINE inline
#define HL_AS_U32(f) as_uint(f)
#define HL_AS_F32(u) as_float(u)
#define HL_FABSF fabs
#define HL_FMAXF fmax
#define HL_FMINF fmin
#define HL_GLOBAL global /* shared functions' pointers into device buffers */
#define HL_FREXPF frexp
#define HL_LDEXPF ldexp
#define HL_RINTF rint
#else
#include <math.h>
#include <stdint.h>
#include <string.h>
#define HL_FABSF fabsf
#define HL_FMAXF fmaxf
#define HL_FMINF fminf
#define HL_GLOBAL
#define HL_FREXPF frexpf
#define HL_LDEXPF ldexpf
#define HL_RINTF rintf
#define HL_U32 uint32_t
#define HL_U64 uint64_t
#define HL_INLINE static inline
static inline uint32_t hl_as_u32_(float f) { uint32_t u; memcpy(&u, &f, 4); return u; }
static inline float hl_as_f32_(uint32_t u) { float f; memcpy(&f, &u, 4); return f; }
#define HL_AS_U32(f) hl_as_u32_(f)
#define HL_AS_F32(u) hl_as_f32_(u)
#endif

/* Coefficient slots per sparse block: an in-block index fits in 8 bits. */
#define HL_BLOCK 256

/* Vertices per tile in the device's dot products: one tile's terms for one
 * slot are added as one 16-wide vector. */
#define HL_TILE 16

/* The dot products (kernels/relight/relight.cl) walk a range's tiles one of two
 * ways. The column walk takes the kept slots 4 at a time and visits the
 * tiles any of the 4 holds, loading and storing each such tile's sums in
 * memory once per group (entry 0 for a slot the tile lacks). The tile walk
 * adds 8 kept slots at a time, tile by tile, into sums held in registers,
 * over every tile, reading an all-zero entry wherever a tile lacks a slot.
 * The tile walk is taken where the kept slots' entries fill at least
 * 7/16 of the range's tiles (entries: their count over the m kept slots;
 * nt tiles); the host counts bytes by the same rule. Both walks forced
 * (each prefetching its columns), the tile walk took 0.77 to 0.89 of the
 * column walk's time on the dragon at fills 0.70 to 0.48, 1.05 at 0.40
 * and 1.28 at 0.28; on the bunny with ground 0.83 to 0.89 at fills 0.68
 * to 0.49 and 1.03 at 0.34: the crossing lies near 0.42 on the one, 0.37
 * on the other (docs/SCALE.md). */
#define HL_TILE_GROUP 8 /* kept slots the tile walk adds per pass */
/* The GPU shape's dot products (kernels/relight/relight_items.cl) take a
 * work-item a position, over ranges of this many tiles: 512 positions,
 * one 32-bit word of tile bits a slot, shared by the range's work-items. */
#define HL_ITEMS_RANGE_TILES 32
HL_INLINE int hl_tile_walk_pays(HL_U64 entries, HL_U32 m, HL_U32 nt)
{
    return m > 0 && 16 * entries >= (HL_U64)7 * m * nt;
}

/* Truncation rules and quantisation schemes. They are public too:
 * haarlight.h defines the same values for the host, and where it came
 * first its definitions stand (host/src/tools/public_pins.c asserts that
 * the two agree); the kernels, which see this file alone, get them here. */
#ifndef HAARLIGHT_H
/* Truncation rules. */
#define HL_TRUNC_DEFAULT 0u
#define HL_TRUNC_ALL 1u    /* keep every non-zero coefficient */
#define HL_TRUNC_TOPK 2u   /* keep the K largest |T_i| */
#define HL_TRUNC_ENERGY 3u /* keep the fewest holding (1 - eps) of the energy,
                              at most K when K > 0 */

/* Quantisation schemes for the 8-bit stored value. */
#define HL_QUANT_DEFAULT 0u
#define HL_QUANT_LINEAR8 1u /* q = round(255 (v - lo) / (hi - lo)); lo, hi =
                               min and max kept value (the seed scheme) */
#define HL_QUANT_LOG8 2u    /* sign bit + 7-bit magnitude, uniform in the
                               float bit pattern (a piecewise-linear log2)
                               between the min and max kept |v| */
#define HL_QUANT_SQRT8 3u   /* sign bit + 7-bit magnitude, uniform in
                               sqrt(|v| / max kept |v|) (the default) */
#define HL_QUANT_MAX 3u
#endif

/* One entry of the cubemap-to-paraboloid table: the part of a paraboloid
 * texel's footprint that falls in one cube texel. m is the first moment of
 * that part, the integral of w dw over it, so n.m is its cosine-weighted
 * solid angle exactly wherever the part lies above the horizon. The table
 * exists in two orders: by paraboloid texel (index = cube texel, face * C *
 * C + row * C + col; ascending within a texel) for the plain-C twin, and by
 * cube texel (index = paraboloid texel) for the kernel, which then skips
 * cube texels with no visibility. Both add a texel's parts in the same
 * order, so they round identically. */
typedef struct hl_c2p_entry {
    float mx, my, mz;
    HL_U32 index;
} hl_c2p_entry;

/* Per-vertex dequantisation parameters (meaning depends on the scheme):
 * LINEAR8: a = lo, b = hi.  LOG8: a = min |v|, b = max |v|. */
typedef struct hl_row_quant {
    float a;
    float b;
} hl_row_quant;

/* The terms as the relight's dot products hold them (host/src/core/half.h
 * says why): e for a row with parameters (a, b), whose terms are scaled by
 * 2^-e and sums by 2^e (both exact: e is clamped so that 2^e and 2^-e are
 * normal); the nearest half to x (|x| below 65520; ties to even), as its
 * bits; and a half's value. */
HL_INLINE int hl_half_exponent(HL_U32 scheme, float a, float b)
{
    float m = scheme != HL_QUANT_LINEAR8 ? HL_FABSF(b) : HL_FMAXF(HL_FABSF(a), HL_FABSF(b));
    int e = 0;
    if (m > 0.0f && isfinite(m)) HL_FREXPF(m, &e);
    return e < -125 ? -125 : e > 125 ? 125 : e;
}

HL_INLINE HL_U32 hl_half_bits(float x)
{
    HL_U32 u = HL_AS_U32(x), sign = (u >> 16) & 0x8000u;
    u &= 0x7fffffffu;
    if (u >= 0x38800000u) { /* 2^-14 and above: a normal half */
        HL_U32 r = u - (112u << 23);
        r += 0xfffu + ((r >> 13) & 1u);
        return sign | (r >> 13);
    }
    /* a subnormal half: a whole multiple of 2^-24 (the scaling is exact,
       the rounding to nearest even) */
    return sign | (HL_U32)HL_RINTF(HL_AS_F32(u) * 16777216.0f);
}

HL_INLINE float hl_half_value(HL_U32 h)
{
    HL_U32 ex = (h >> 10) & 31u, m = h & 1023u;
    float v = ex ? HL_LDEXPF((float)(m | 1024u), (int)ex - 25) : HL_LDEXPF((float)m, -24);
    return (h & 0x8000u) ? -v : v;
}

/* Per-vertex result of the truncation stage. Coefficient i is kept when
 * key_i > thresh, or key_i == thresh and fewer than ties earlier
 * coefficients (in slot order) with key == thresh were kept. key is the bit
 * pattern of |T_i|, which orders non-negative floats. Zeros are never kept. */
typedef struct hl_trunc_result {
    HL_U32 thresh;
    HL_U32 ties;
    HL_U32 count;
    HL_U32 pad_;
} hl_trunc_result;

/* Truncation parameters passed to the stage. */
typedef struct hl_trunc_params {
    HL_U32 rule;
    HL_U32 K;       /* top-K count, or cap for the energy rule (0: none) */
    HL_U32 eps_q20; /* eps in units of 2^-20 */
    HL_U32 pad_;
} hl_trunc_params;

/* ---- lighting ---- */

#ifndef HAARLIGHT_H /* as the truncation rules above */
/* Selection of the lighting terms: priority of coefficient i is |Y_i|
 * times a weight, Y the luminance coefficient (RGB share one index set). */
#define HL_SELECT_DEFAULT 0u
#define HL_SELECT_AREA 1u        /* weight: solid angle of i's support */
#define HL_SELECT_UNWEIGHTED 2u  /* weight 1 */
#define HL_SELECT_TRANSPORT 3u   /* weight: mean |T_i| over the vertices */
#endif

/* One environment cell's share of a paraboloid texel (at rotation 0):
 * weight = the solid angle of the part of cell (row, col) inside the
 * texel, over the texel's total, so a texel's weights sum to 1. */
typedef struct hl_env_tap {
    HL_U32 row;
    HL_U32 col;
    float weight;
    HL_U32 pad_;
} hl_env_tap;

typedef struct hl_select_params {
    HL_U32 M;      /* terms to keep (>= number of non-zeros: all) */
    HL_U32 scheme; /* HL_SELECT_* */
    HL_U32 pad_[2];
} hl_select_params;

typedef struct hl_select_result {
    float energy_total; /* sum of (Y_i 2^-energy_exp)^2 over all coefficients */
    float energy_kept;  /* ... over the kept ones */
    HL_U32 kept;
    HL_U32 blocks_used; /* 256-blocks holding a kept term */
    float energy_dropped; /* ... over the others, summed apart: with a
                             bright sun total - kept cancels to nothing
                             in float, and the error bound needs this */
    HL_U32 energy_exp;  /* e + 127, see hl_light_energy_scale */
    HL_U32 pad_[2];
} hl_select_result;

/* The energies are sums of squares of Y_i s, where s = 2^-e brings the
 * largest |Y_i| into [1, 2) (e clamped to [-126, 126], so that s is a
 * normal float). Unscaled, Y^2 overflows float above |Y| = 1.8e19 and
 * underflows below 1e-19; scaled, neither happens for any finite
 * lighting, and a power-of-two scale rounds nothing, so in between the
 * sums are those of Y^2 times s^2 exactly. Returns s; *biased = e + 127. */
HL_INLINE float hl_light_energy_scale(float ymax, HL_U32 *biased)
{
    HL_U32 b = (HL_AS_U32(ymax) >> 23) & 255u; /* e + 127 for a normal ymax */
    if (b == 255u) b = 127u;                    /* not finite: no scale */
    if (b < 1u) b = 1u;                         /* zero or subnormal */
    if (b > 253u) b = 253u;
    *biased = b;
    return HL_AS_F32((254u - b) << 23);         /* 2^(127 - b) = 2^-e */
}

/* The order in which the selection sums its energies (select.cl,
 * select_group.cl and the twin alike, so that all three give the same
 * bits): the slots cut into HL_SELECT_LANES chunks of hl_select_chunk
 * consecutive slots (a whole number of 32-slot words, so that each chunk
 * owns its words of kept bits; the last chunks may be empty), each chunk
 * summed in slot order, then the chunks' sums added pairwise
 * (hl_select_fold). The GPU shape's selection gives each chunk to one of
 * a work-group's HL_SELECT_LANES work-items; the tree is also closer to
 * the exact sum than one long run of additions. */
#define HL_SELECT_LANES 256u
HL_INLINE HL_U32 hl_select_chunk(HL_U32 ncoef)
{
    HL_U32 c = (ncoef + HL_SELECT_LANES - 1u) / HL_SELECT_LANES;
    return (c + 31u) / 32u * 32u;
}
/* e[0] += ... the pairwise tree over e[0 .. HL_SELECT_LANES - 1]: at each
 * step h (128, 64, ..., 1) e[k] += e[k + h] for k < h. */
HL_INLINE void hl_select_fold(float *e)
{
    for (HL_U32 h = HL_SELECT_LANES / 2u; h > 0u; h /= 2u)
        for (HL_U32 k = 0; k < h; k++) e[k] += e[k + h];
}

/* The selection's result from its sums and counts (select.cl and
 * select_group.cl write it alike). */
HL_INLINE hl_select_result hl_select_result_of(float total, float kept_energy, float dropped, HL_U32 kept,
                                               HL_U32 blocks, HL_U32 exp_biased)
{
    hl_select_result s;
    s.energy_total = total;
    s.energy_kept = kept_energy;
    s.kept = kept;
    s.blocks_used = blocks;
    s.energy_dropped = dropped;
    s.energy_exp = exp_biased;
    s.pad_[0] = s.pad_[1] = 0u;
    return s;
}

/* Luminance of linear Rec.709 RGB. */
HL_INLINE float hl_luminance(float r, float g, float b)
{
    return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}

#ifdef __OPENCL_C_VERSION__
/* One pass of a radix select for the `need` largest keys: the highest
 * 8-bit bin that reaches them, with need reduced by the keys in the bins
 * above it (the plain-C twins sort instead). */
HL_INLINE uint hl_radix_bin(const uint *hist, uint *need)
{
    uint b = 255;
    for (; b > 0; b--) {
        if (hist[b] >= *need) break;
        *need -= hist[b];
    }
    return b;
}

/* The orthonormal non-standard Haar of one n x n map x (destroyed: the
 * averages are compacted in place, which row-major order never reads
 * back) into o: coefficient k at o[slot[k]], k in the Mallat layout, or
 * at o[k] when slot is 0. Twin: hl_ref_haar_square. */
HL_INLINE void hl_haar_square(global float *x, global float *o, global const uint *slot, uint n)
{
    for (uint s = n; s >= 2; s /= 2) {
        uint h = s / 2;
        for (uint i = 0; i < h; i++)
            for (uint j = 0; j < h; j++) {
                float a = x[(2 * i) * n + 2 * j], b = x[(2 * i) * n + 2 * j + 1];
                float c = x[(2 * i + 1) * n + 2 * j], d = x[(2 * i + 1) * n + 2 * j + 1];
                uint k1 = i * n + j + h, k2 = (i + h) * n + j, k3 = (i + h) * n + j + h;
                o[slot ? slot[k1] : k1] = (a - b + c - d) * 0.5f;
                o[slot ? slot[k2] : k2] = (a + b - c - d) * 0.5f;
                o[slot ? slot[k3] : k3] = (a - b - c + d) * 0.5f;
                x[i * n + j] = (a + b + c + d) * 0.5f;
            }
    }
    o[slot ? slot[0] : 0] = x[0];
}

/* A vertex's colour as the dot products leave it: truncated lighting and
 * transport can sum to a little below zero where the exact answer is
 * dark, and no output may hold negative light, so each channel is clamped
 * at zero (unless keep_negative); w keeps the lowest channel before the
 * clamp (0 when none was negative). Comparisons, not fmin/fmax, so that
 * -0 and +0 come out as in the twin (hl_ref_relight). */
HL_INLINE float4 hl_colour_out(float4 c, uint keep_negative)
{
    float lo = 0.0f;
    lo = c.x < lo ? c.x : lo;
    lo = c.y < lo ? c.y : lo;
    lo = c.z < lo ? c.z : lo;
    if (!keep_negative) {
        c.x = c.x > 0.0f ? c.x : 0.0f;
        c.y = c.y > 0.0f ? c.y : 0.0f;
        c.z = c.z > 0.0f ? c.z : 0.0f;
    }
    c.w = lo;
    return c;
}

/* The clamp's tally over a work-item's vertices, so that the host need
 * not read every colour to report it: *lo the lowest channel before the
 * clamp (0 if none was negative), *hi the brightest channel as written,
 * *n the vertices with a channel below zero. Scalars, so that they stay
 * in registers across the colours' loop. Each work-item writes them as
 * (lo, hi, n's bits, 0) and the host joins the work-items' tallies
 * (lighting.c). */
HL_INLINE void hl_tally_add(float4 c, float *lo, float *hi, uint *n)
{
    const float m = c.y > c.x ? c.y : c.x, top = c.z > m ? c.z : m;
    *lo = c.w < *lo ? c.w : *lo;
    *hi = top > *hi ? top : *hi;
    *n += c.w < 0.0f ? 1u : 0u;
}
#endif

/* Key of a coefficient: |v| as ordered bits. */
HL_INLINE HL_U32 hl_key(float v) { return HL_AS_U32(v) & 0x7fffffffu; }

/* Fixed-point energy of a coefficient for the energy rule, with a per-row
 * scale 2^s chosen from the row's largest key so that sums are exact
 * integers (no float summation-order effects). */
HL_INLINE float hl_energy_scale(HL_U32 max_key)
{
    float m = HL_AS_F32(max_key);
    HL_U32 sq = HL_AS_U32(m * m);
    int e = (int)(sq >> 23) - 127;
    int s = 39 - e;
    if (s > 127) s = 127;
    if (s < -126) s = -126;
    return HL_AS_F32((HL_U32)(s + 127) << 23);
}

HL_INLINE HL_U64 hl_energy(float v, float scale)
{
    float e = (v * v) * scale;
    return (HL_U64)e;
}

/* Energy that the rule may drop: floor(total / 2^20) * eps_q20. */
HL_INLINE HL_U64 hl_energy_drop(HL_U64 total, HL_U32 eps_q20)
{
    return (total >> 20) * (HL_U64)eps_q20;
}

/* ---- quantisation formulas (identical in both compilers) ---- */

HL_INLINE HL_U32 hl_quant_linear8(float v, float lo, float hi)
{
    float range = hi - lo;
    if (!(range > 0.0f)) return 0u;
    float x = (v - lo) / range * 255.0f;
    if (x < 0.0f) x = 0.0f;
    if (x > 255.0f) x = 255.0f;
    return (HL_U32)(x + 0.5f);
}

/* linear8's step between codes: a multiply, not a division, and computed
 * once per vertex where the dot products decode (hl_dequant_params). */
HL_INLINE float hl_linear8_step(float lo, float hi) { return (hi - lo) * (1.0f / 255.0f); }

HL_INLINE float hl_dequant_linear8(HL_U32 q, float lo, float hi)
{
    return lo + (float)q * hl_linear8_step(lo, hi);
}

/* log8: the magnitude's float bit pattern on a grid of 128 points from
 * min |v| in whole steps of step = (bits(max) - bits(min)) / 127 (rounded
 * down, so the last point is at most 126 units below max). Decoding is one
 * integer multiply-add (the device decodes each term once, on load). */
HL_INLINE HL_U32 hl_log8_step(float mn, float mx)
{
    HL_U32 kmn = HL_AS_U32(mn), kmx = HL_AS_U32(mx);
    return kmx > kmn ? (kmx - kmn) / 127u : 0u;
}

HL_INLINE HL_U32 hl_quant_log8(float v, float mn, float mx)
{
    HL_U32 sign = (HL_AS_U32(v) >> 31) << 7;
    HL_U32 step = hl_log8_step(mn, mx);
    if (step == 0u) return sign;
    HL_U32 k = hl_key(v), kmn = HL_AS_U32(mn), kmx = HL_AS_U32(mx);
    if (k < kmn) k = kmn;
    if (k > kmx) k = kmx;
    HL_U32 q = (k - kmn + step / 2u) / step;
    return sign | (q > 127u ? 127u : q);
}

/* Decoding from the parameters as bit patterns: p0 = bits(min |v|),
 * p1 = step. */
HL_INLINE float hl_dequant_log8_p(HL_U32 code, HL_U32 p0, HL_U32 p1)
{
    return HL_AS_F32((p0 + (code & 127u) * p1) | ((code & 128u) << 24));
}

HL_INLINE float hl_dequant_log8(HL_U32 code, float mn, float mx)
{
    return hl_dequant_log8_p(code, HL_AS_U32(mn), hl_log8_step(mn, mx));
}

/* sqrt8: |v| = max s^2 with s on a grid of 127ths, so the step between
 * codes is ~2 s / 127 of the row's largest magnitude: fine where the large
 * terms that make a vertex's colour sit (1.6% of the value at the top,
 * against log8's ~6.8% over a typical 12-octave row), coarser for the
 * small ones, whose errors weigh little. The smallest non-zero magnitude
 * is about 1/127^2 = 6.2e-5 of the largest.
 * Subtractive dither: each (vertex, slot) has a fixed offset d in
 * [-1/2, 1/2) (hl_dither_key), the code is q = round(127 s + d) and the
 * decoded s is (q - d) / 127. The error stays within half a step, as with
 * plain rounding, but no longer follows the value: coefficients that vary
 * smoothly over a surface no longer step together, which drew contour
 * bands along the ground. (The 2003 paper dithered its codes too.)
 * Encoding compares |v| with max t, t = ((2q - 1 - 2d) / 254)^2, by
 * bisection: IEEE multiplies and comparisons only, so every device and the
 * host give the same code. Code 0 is 0. */

/* A well-mixed 32-bit hash of (vertex, slot): the dither's key. */
HL_INLINE HL_U32 hl_dither_key(HL_U32 vertex, HL_U32 slot)
{
    HL_U32 x = vertex * 0x9e3779b9u ^ (slot + 0x7f4a7c15u);
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

/* The dither offset of a key: a multiple of 1/256 in [-1/2, 1/2), exact
 * in float. */
HL_INLINE float hl_dither(HL_U32 key) { return (float)(int)(key >> 24) * (1.0f / 256.0f) - 0.5f; }

HL_INLINE float hl_sqrt8_threshold(HL_U32 q, float d)
{
    float s = ((float)(2u * q - 1u) - 2.0f * d) * (1.0f / 254.0f);
    return s * s;
}

HL_INLINE HL_U32 hl_quant_sqrt8(float v, float mx, HL_U32 key)
{
    HL_U32 sign = (HL_AS_U32(v) >> 31) << 7;
    float m = HL_AS_F32(hl_key(v)), d = hl_dither(key);
    HL_U32 lo = 0u, hi = 127u; /* the largest q with m >= mx t_q (t_0 = 0) */
    while (lo < hi) {
        HL_U32 mid = (lo + hi + 1u) / 2u;
        if (m >= mx * hl_sqrt8_threshold(mid, d)) lo = mid;
        else hi = mid - 1u;
    }
    return sign | lo;
}

HL_INLINE float hl_dequant_sqrt8(HL_U32 code, float mx, HL_U32 key)
{
    if (!(code & 127u)) return 0.0f;
    float s = ((float)(code & 127u) - hl_dither(key)) * (1.0f / 127.0f);
    return HL_AS_F32(HL_AS_U32(mx * (s * s)) | ((code & 128u) << 24));
}

/* Decoding in any scheme; key = hl_dither_key(vertex, slot) (only sqrt8
 * uses it). */
HL_INLINE float hl_dequant(HL_U32 scheme, HL_U32 code, float a, float b, HL_U32 key)
{
    return scheme == HL_QUANT_LOG8    ? hl_dequant_log8(code, a, b)
           : scheme == HL_QUANT_SQRT8 ? hl_dequant_sqrt8(code, b, key)
                                      : hl_dequant_linear8(code, a, b);
}

/* The code of v in a scheme, for a row whose kept values (magnitudes for
 * log8 and sqrt8) run from a to b; key as for hl_dequant. */
HL_INLINE HL_U32 hl_quant(HL_U32 scheme, float v, float a, float b, HL_U32 key)
{
    return scheme == HL_QUANT_LOG8    ? hl_quant_log8(v, a, b)
           : scheme == HL_QUANT_SQRT8 ? hl_quant_sqrt8(v, b, key)
                                      : hl_quant_linear8(v, a, b);
}

/* ---- the dynamic frame's receivers: one formula for the host
 * (host/src/dynamic/dyn_frame.c) and the device
 * (kernels/dynamic/dyn_shade.cl), so that both give the same bits ---- */

/* Texels added to the filter's half-width in the receiver-plane bias
 * (hl_dyn_receiver): csm.h's smallest half-width (0.5) plus one for the
 * box's rounding to whole texels. */
#define HL_FRAME_BIAS_TEXELS 1.5f
/* The most of the blocker-search half-width (normalised depth) that the
 * receiver-plane bias covers. The whole width, (d - zmin) tan(theta),
 * reaches half the depth range under a wide light and pushes a receiver
 * past its own blockers: the bunny leaked 11 to 18% of its light. A flat
 * ground, the body that needed the whole width, is out of the maps it
 * cannot shadow (shadow_map.h), so what remains to cover is a body's own
 * curved or flat surface across a short stretch of the filter. On the
 * bunny with its ground under studio.exr (test_dyn_reference accuracy):
 * no cap 11.8% at rest and 9.0% moved, 0.05: 10.5% and 6.5%, 0.02: 10.0%
 * and 6.2%, 0: 9.7% and 6.4%. 0.02 keeps a little cover for flat faces
 * of bodies that are not flat as a whole (a box) at the same error. */
#define HL_FRAME_BIAS_CAP 0.02f
/* Blocks a side that a light is cut into for the occlusion by flat
 * bodies (hl_dyn_flat_one): a 32 x 32 texel light becomes 8 x 8 blocks
 * of 4 x 4 texels, so a receiver costs at most 64 ray-plane tests a
 * light. The shadow of a ground edge is as soft as a block (under 11
 * degrees at F = 32), far below the lights' own size. */
#define HL_FRAME_FLAT_BLOCKS 8u

/* A light's map as its receivers read it, HL_DYN_LF floats: the frame as
 * the rasteriser packs it (hl_shadow_frame_pack, 16 floats: origin,
 * right, up, toward_far, R / width, R / height, 1 / depth_range, the skip
 * mask's bits), tan of the filter's half-extent (16), a texel's size in
 * normalised depth, max(width, height) / R / depth_range (17), the
 * light's direction (18..20), 0 (21..23). */
#define HL_DYN_LF 24u

/* Receiver p (unit normal n, of body `body`) in the map lf whose nearest
 * depth is zmin: uvd = (u, v) in texels and d in normalised depth, moved
 * towards the light by the receiver-plane bias (Isidoro 2006, for
 * filtered shadow maps). The filter reads a box of half-width up to the
 * blocker search's, (d - zmin) tan(theta) in depth units, here capped at
 * HL_FRAME_BIAS_CAP, plus HL_FRAME_BIAS_TEXELS; over that box the
 * receiver's own tangent plane comes nearer the light by up to
 * (|n.right| + |n.up|) / (n.l) times the half-width, and those texels
 * would be taken for blockers, so d is moved that much (not below 0).
 * A receiver of a body left out of the map (a flat ground, the skip
 * mask) gets none: its surface is not in the map. The bias grows as
 * 1 / (n.l) as a light grazes the surface while E_k shrinks as n.l, so
 * what it loses (a blocker nearer than the bias is not seen: the contact
 * leak) carries little energy at grazing angles.
 * rpl (HL_DYN_RPL floats) = the tangent plane's slopes in the map, dd/du
 * and dd/dv (normalised depth per texel), and d before the bias: the
 * small boxes test each texel against the plane there instead
 * (msm_eval.cl). 0, 0 and d for a body out of the map (no own surface to
 * pass by) and where n.l <= 0. */
#define HL_DYN_RPL 3u
HL_INLINE void hl_dyn_receiver(HL_GLOBAL const float *lf, float zmin, const float *p, const float *n, HL_U32 body,
                               float *uvd, float *rpl)
{
    const float q0 = p[0] - lf[0], q1 = p[1] - lf[1], q2 = p[2] - lf[2];
    uvd[0] = (q0 * lf[3] + q1 * lf[4] + q2 * lf[5]) * lf[12];
    uvd[1] = (q0 * lf[6] + q1 * lf[7] + q2 * lf[8]) * lf[13];
    float d = (q0 * lf[9] + q1 * lf[10] + q2 * lf[11]) * lf[14];
    rpl[0] = 0.0f;
    rpl[1] = 0.0f;
    rpl[2] = d;
    if (!(body < 32u && ((HL_AS_U32(lf[15]) >> body) & 1u))) {
        const float nl = n[0] * lf[18] + n[1] * lf[19] + n[2] * lf[20];
        float bias = 0.0f; /* nl <= 0: E_k = 0 there, never evaluated */
        if (nl > 0.0f) {
            const float sr = n[0] * lf[3] + n[1] * lf[4] + n[2] * lf[5];
            const float su = n[0] * lf[6] + n[1] * lf[7] + n[2] * lf[8];
            const float nr = HL_FABSF(sr), nu = HL_FABSF(su);
            const float hw = HL_FMINF(HL_FMAXF(d - zmin, 0.0f) * lf[16], HL_FRAME_BIAS_CAP) + HL_FRAME_BIAS_TEXELS * lf[17];
            bias = (nr + nu) / nl * hw;
            /* the plane n . (x - p) = 0 with toward_far = -l: a step a
               along right (a R / width texels) moves the depth by
               a (n.right) / (n.l) / depth_range */
            rpl[0] = sr / nl * (lf[14] / lf[12]);
            rpl[1] = su / nl * (lf[14] / lf[13]);
        }
        d = HL_FMAXF(d - bias, 0.0f);
    }
    uvd[2] = d;
}

/* A light as the flat bodies' occlusion reads it, HL_DYN_FL floats: its
 * direction (0..2), the sine of its extent, or 2 past a hemisphere (3),
 * the unit directions of its rectangle's four corner texels (4..15), the
 * block count's bits (16), 0 (17..19), then per block (at most
 * HL_FRAME_FLAT_BLOCKS^2) its luminance moment (n . it is the block's
 * irradiance where the block is above n's horizon) and the moment's unit
 * direction. */
#define HL_DYN_FL (20u + 6u * HL_FRAME_FLAT_BLOCKS * HL_FRAME_FLAT_BLOCKS)
/* A flat body left out of the maps, HL_DYN_FB floats: its plane's unit
 * normal (0..2) and a point of it (3..5), unit axes u (6..8) and v = n x
 * u (9..11) in the plane, its extent along u and v from that point (lo
 * 12, 13, hi 14, 15), the bits of its first vertex and its vertex count
 * among the receivers (16, 17), 0 (18, 19). */
#define HL_DYN_FB 20u

/* Whether the ray from a receiver (q: its offset from the body's point,
 * sr = n . q) along unit w meets the flat body's extent. */
HL_INLINE int hl_dyn_flat_hit(HL_GLOBAL const float *fb, const float *q, float sr, HL_GLOBAL const float *w)
{
    const float sw = fb[0] * w[0] + fb[1] * w[1] + fb[2] * w[2];
    if (!(sr * sw < 0.0f)) return 0; /* the ray leaves the plane behind */
    const float tt = -sr / sw;
    const float h0 = q[0] + tt * w[0], h1 = q[1] + tt * w[1], h2 = q[2] + tt * w[2];
    const float a = h0 * fb[6] + h1 * fb[7] + h2 * fb[8];
    const float b = h0 * fb[9] + h1 * fb[10] + h2 * fb[11];
    return a >= fb[12] && a <= fb[14] && b >= fb[13] && b <= fb[15];
}

/* Visibility V of light lt at receiver x (unit normal nv, receiver index
 * vi) after the flat body fb, which is out of the light's map: V times
 * the share of the light's irradiance at the receiver whose rays miss the
 * body, block by block. Exact up to the blocks' size, with no depth bias,
 * so the underside of a body resting on the ground is dark to the
 * contact, while rays that pass beyond the ground's edge still arrive. A
 * receiver of the body itself, or on its plane, is not behind it; nor is
 * one on the light's side where the light's whole cone is. When the rays
 * of the four corner texels all meet the body, so do those of every
 * texel between (their directions lie in the corners' convex hull, and
 * so do their hits in the plane, as does the body's extent). */
HL_INLINE float hl_dyn_flat_one(HL_GLOBAL const float *lt, HL_GLOBAL const float *fb, const float *x, const float *nv,
                                HL_U32 vi, float V)
{
    const HL_U32 first = HL_AS_U32(fb[16]), count = HL_AS_U32(fb[17]);
    if (vi >= first && vi - first < count) return V;
    const float q[3] = {x[0] - fb[3], x[1] - fb[4], x[2] - fb[5]};
    const float sr = fb[0] * q[0] + fb[1] * q[1] + fb[2] * q[2];
    const float sl = fb[0] * lt[0] + fb[1] * lt[1] + fb[2] * lt[2];
    if (sr == 0.0f || (sr * sl > 0.0f && HL_FABSF(sl) >= lt[3])) return V;
    int corners_in = 1;
    for (HL_U32 c = 0; c < 4u && corners_in; c++) corners_in = hl_dyn_flat_hit(fb, q, sr, lt + 4 + 3 * c);
    if (corners_in) return 0.0f;
    float all = 0.0f, open = 0.0f;
    const HL_U32 nblk = HL_AS_U32(lt[16]);
    for (HL_U32 j = 0; j < nblk; j++) {
        HL_GLOBAL const float *m = lt + 20 + 6 * j;
        const float e = nv[0] * m[0] + nv[1] * m[1] + nv[2] * m[2];
        if (!(e > 0.0f)) continue;
        all += e;
        if (!hl_dyn_flat_hit(fb, q, sr, m + 3)) open += e;
    }
    return all > 0.0f ? V * (open / all) : V;
}

/* ------------------------------------------------- the capture's triangles */

/* Floats per packed triangle of the capture (capture.h, hl_capture_pack):
 * v0 relative to the capture point, e1, e2, emitted RGB, cones and planes. */
#define HL_CAPTURE_FLOATS 40u
/* Floats per node of the capture's bounding-volume hierarchy (box min,
 * box max, each with a fourth float unused) and the deepest node the host
 * builds below the root, which bounds the traversal's stack. */
#define HL_CAPTURE_NODE_FLOATS 8u
#define HL_CAPTURE_STACK 48u

/* Moller-Trumbore, both sides: the distance from the origin along (dx, dy,
 * dz) to packed triangle T where the ray hits it, or INFINITY. One
 * function for every caster of the capture (its kernel and twin, listed,
 * traced), so a hit is the same float wherever it is found. */
HL_INLINE float hl_capture_tri_t(HL_GLOBAL const float *T, float dx, float dy, float dz)
{
    HL_GLOBAL const float *v0 = T, *e1 = T + 4, *e2 = T + 8;
    float px = dy * e2[2] - dz * e2[1], py = dz * e2[0] - dx * e2[2], pz = dx * e2[1] - dy * e2[0];
    float det = e1[0] * px + e1[1] * py + e1[2] * pz;
    if (det == 0.0f) return INFINITY; /* the ray lies in the triangle's plane */
    float inv = 1.0f / det;
    float tx = -v0[0], ty = -v0[1], tz = -v0[2];
    float u = (tx * px + ty * py + tz * pz) * inv;
    if (u < 0.0f || u > 1.0f) return INFINITY;
    float qx = ty * e1[2] - tz * e1[1], qy = tz * e1[0] - tx * e1[2], qz = tx * e1[1] - ty * e1[0];
    float v = (dx * qx + dy * qy + dz * qz) * inv;
    if (v < 0.0f || u + v > 1.0f) return INFINITY;
    float t = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv;
    return t > 0.0f ? t : INFINITY;
}

/* Where the ray from the origin with inverse direction (ix, iy, iz)
 * enters node box nd (slabs), or INFINITY when it misses the box or enters
 * beyond best. The host pads every box by far more than the rounding of
 * Moller-Trumbore's hit point, so a box holding a hit is never missed. */
HL_INLINE float hl_capture_slab(HL_GLOBAL const float *nd, float ix, float iy, float iz, float best)
{
    float a = nd[0] * ix, b = nd[4] * ix;
    float lo = a < b ? a : b, hi = a < b ? b : a;
    a = nd[1] * iy;
    b = nd[5] * iy;
    float l = a < b ? a : b, h = a < b ? b : a;
    lo = l > lo ? l : lo;
    hi = h < hi ? h : hi;
    a = nd[2] * iz;
    b = nd[6] * iz;
    l = a < b ? a : b;
    h = a < b ? b : a;
    lo = l > lo ? l : lo;
    hi = h < hi ? h : hi;
    return lo <= hi && hi >= 0.0f && lo <= best ? lo : INFINITY;
}

/* 1 / d, with |d| below 1e-20 taken as 1e-20 of its sign: a finite
 * inverse, so that a box side at 0 gives 0 and no NaN. */
HL_INLINE float hl_capture_inv(float d)
{
    return 1.0f / (d > 1e-20f || d < -1e-20f ? d : (d < 0.0f ? -1e-20f : 1e-20f));
}

/* The nearest packed triangle along (dx, dy, dz) from the origin, or -1,
 * through the hierarchy (capture_bvh.c): node k's box at nodes[8 k]; its
 * links[2 k], links[2 k + 1] are (first, count) for a leaf holding
 * order[first .. first + count), (second child, 0) for an inner node whose
 * first child is k + 1. Nearer child first; a pushed node is skipped when
 * the ray entered it beyond the nearest hit found since. Ties go to the
 * lower index, so the hit is the one testing every triangle in order
 * finds (hl.capture.twin checks it). */
HL_INLINE int hl_capture_trace(HL_GLOBAL const float *tris, HL_GLOBAL const float *nodes, HL_GLOBAL const HL_U32 *links,
                               HL_GLOBAL const HL_U32 *order, float dx, float dy, float dz)
{
    const float ix = hl_capture_inv(dx), iy = hl_capture_inv(dy), iz = hl_capture_inv(dz);
    float best = INFINITY, enter[HL_CAPTURE_STACK];
    HL_U32 stack[HL_CAPTURE_STACK], sp = 0, node = 0;
    int hit = -1;
    if (!(hl_capture_slab(nodes, ix, iy, iz, best) < INFINITY)) return -1;
    for (;;) {
        const HL_U32 first = links[2u * node], count = links[2u * node + 1u];
        if (count) {
            for (HL_U32 k = first; k < first + count; k++) {
                const HL_U32 i = order[k];
                const float t = hl_capture_tri_t(tris + HL_CAPTURE_FLOATS * i, dx, dy, dz);
                if (t < best || (t == best && (int)i < hit)) {
                    best = t;
                    hit = (int)i;
                }
            }
        } else {
            const HL_U32 l = node + 1u, r = first;
            const float tl = hl_capture_slab(nodes + HL_CAPTURE_NODE_FLOATS * l, ix, iy, iz, best);
            const float tr = hl_capture_slab(nodes + HL_CAPTURE_NODE_FLOATS * r, ix, iy, iz, best);
            if (tl < INFINITY || tr < INFINITY) {
                const int left = tl <= tr;
                const float tf = left ? tr : tl;
                if (tf < INFINITY) {
                    stack[sp] = left ? r : l;
                    enter[sp] = tf;
                    sp++;
                }
                node = left ? l : r;
                continue;
            }
        }
        for (;;) { /* the next pushed node the ray enters before its nearest hit */
            if (sp == 0) return hit;
            sp--;
            if (enter[sp] <= best) break;
        }
        node = stack[sp];
    }
}

#endif
