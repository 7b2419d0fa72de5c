/* relight.c - twin of kernels/relight/relight.cl: walks the whole row (the terms
 * not kept meet a zero light and add nothing), one fused multiply-add per
 * term as the kernel does, on the terms as the kernel holds them (decoded,
 * scaled by 2^-e and rounded to half precision: core/half.h), then scales
 * the sums back by 2^e, times the albedo; then clamps each channel at zero
 * (unless keep_negative) and puts the lowest channel before the clamp, or
 * 0, in rgba[3], as the kernel does. */
#include <math.h>

#include "half.h"
#include "twins.h"

void hl_ref_relight(const uint8_t *entries, const uint16_t *block_counts, hl_row_quant rq, uint32_t scheme,
                    uint32_t vertex, uint32_t nblocks, const float *light, const float *albedo, int keep_negative,
                    float *rgba)
{
    float acc[3] = {0.0f, 0.0f, 0.0f};
    const int ex = hl_half_exponent(scheme, rq.a, rq.b);
    const float back = ldexpf(1.0f, ex);
    size_t e = 0;
    for (uint32_t b = 0; b < nblocks; b++)
        for (uint32_t k = 0; k < block_counts[b]; k++, e++) {
            float t = hl_half_term(
                hl_dequant(scheme, entries[2 * e + 1], rq.a, rq.b, hl_dither_key(vertex, b * HL_BLOCK + entries[2 * e])),
                ex);
            const float *l = light + 4 * ((size_t)b * HL_BLOCK + entries[2 * e]);
            for (int c = 0; c < 3; c++) acc[c] = fmaf(t, l[c], acc[c]);
        }
    float lo = 0.0f;
    for (int c = 0; c < 3; c++) {
        rgba[c] = (acc[c] * back) * albedo[c];
        lo = rgba[c] < lo ? rgba[c] : lo;
        if (!keep_negative) rgba[c] = rgba[c] > 0.0f ? rgba[c] : 0.0f;
    }
    rgba[3] = lo;
}
