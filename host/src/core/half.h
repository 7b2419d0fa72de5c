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

/* hl_half_exponent, hl_half_bits and hl_half_value are in hl_shared.h,
 * where the kernel that relights from the rows (relight_rows.cl) uses
 * them too. */

/* A decoded value t of a row with exponent e as the device holds it (the
 * half of t 2^-e), and as the dot products add it (that half's value). */
static inline uint16_t hl_half_held(float t, int e) { return (uint16_t)hl_half_bits(ldexpf(t, -e)); }
static inline float hl_half_term(float t, int e) { return hl_half_value(hl_half_held(t, e)); }

#endif
