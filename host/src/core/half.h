/* half.h - the transport terms as the dot products hold them.
 *
 * The file keeps each term as an 8-bit code (sqrt8, log8 or linear8). The device
 * does not decode codes in its dot products: decoding was two thirds of
 * their vector instructions, and the loop was bound by them, not by memory.
 * Instead the columns are built with each term already decoded, scaled by
 * 2^-e per vertex (e: the exponent of the row's largest magnitude, so its
 * terms fall below 1) and rounded to IEEE half precision (11 significant
 * bits, to nearest even). The kernel converts halves to floats exactly
 * (vload_half), and multiplies each vertex's sums by 2^e at the end.
 *
 * The twin (host/src/relight/twins/relight.c) adds the same terms through these same
 * functions, so the two agree bit for bit. A half holds a term to 2^-11
 * of itself, or, for a term over 2^14 times smaller than the row's
 * largest, to 2^-24 of that largest. The codes' own steps are far coarser:
 * 1/255 of the row's range (linear8), a grid of 128 points over the
 * row's magnitudes in float bit patterns (log8), or 128 squares of q / 127
 * times the row's largest magnitude (sqrt8).
 *
 * Header only. Used by the relight's columns (cl_columns.c), its twin, and
 * the transport reader (hl_transport_query_terms). Depends on:
 * hl_shared.h (the quantisation schemes), libm.
 */
#ifndef HL_HALF_H
#define HL_HALF_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "hl_shared.h"

/* e for a row with parameters (a, b): its terms are scaled by 2^-e, and its
 * sums by 2^e (both exact: e is clamped so that 2^e and 2^-e are normal). */
static inline int hl_half_exponent(uint32_t scheme, float a, float b)
{
    float m = scheme != HL_QUANT_LINEAR8 ? fabsf(b) : fmaxf(fabsf(a), fabsf(b));
    int e = 0;
    if (m > 0.0f && isfinite(m)) frexpf(m, &e);
    return e < -125 ? -125 : e > 125 ? 125 : e;
}

/* The nearest half to x (|x| below 65520; ties to even), as its bits. */
static inline uint16_t hl_half_bits(float x)
{
    uint32_t u;
    memcpy(&u, &x, 4);
    uint16_t sign = (uint16_t)((u >> 16) & 0x8000u);
    u &= 0x7fffffffu;
    if (u >= 0x38800000u) { /* 2^-14 and above: a normal half */
        uint32_t r = u - (112u << 23);
        r += 0xfffu + ((r >> 13) & 1u);
        return (uint16_t)(sign | (r >> 13));
    }
    float a;
    memcpy(&a, &u, 4);
    /* a subnormal half: a whole multiple of 2^-24 (the scaling is exact,
       the rounding to nearest even) */
    return (uint16_t)(sign | (uint16_t)lrintf(a * 16777216.0f));
}

static inline float hl_half_value(uint16_t h)
{
    uint32_t ex = (h >> 10) & 31u, m = h & 1023u;
    float v = ex ? ldexpf((float)(m | 1024u), (int)ex - 25) : ldexpf((float)m, -24);
    return (h & 0x8000u) ? -v : v;
}

/* A decoded value t of a row with exponent e as the device holds it (the
 * half of t 2^-e), and as the dot products add it (that half's value). */
static inline uint16_t hl_half_held(float t, int e) { return hl_half_bits(ldexpf(t, -e)); }
static inline float hl_half_term(float t, int e) { return hl_half_value(hl_half_held(t, e)); }

#endif
