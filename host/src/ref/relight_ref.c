/* relight_ref.c - twin of kernels/relight.cl: walks the whole row (the terms
 * not kept meet a zero light and add nothing), one fused multiply-add per
 * term as the kernel does, on the terms as the kernel holds them (decoded,
 * scaled by 2^-e and rounded to half precision: ../half.h), then scales
 * the sums back by 2^e. */
#include <math.h>

#include "../half.h"
#include "ref.h"

void hl_ref_relight(const uint8_t *entries, const uint16_t *block_counts, hl_row_quant rq, uint32_t scheme,
                    uint32_t nblocks, const float *light, const float *albedo, float *rgb)
{
    float acc[3] = {0.0f, 0.0f, 0.0f};
    const int ex = hl_half_exponent(scheme, rq.a, rq.b);
    const float back = ldexpf(1.0f, ex);
    size_t e = 0;
    for (uint32_t b = 0; b < nblocks; b++)
        for (uint32_t k = 0; k < block_counts[b]; k++, e++) {
            float t = hl_half_term(hl_dequant(scheme, entries[2 * e + 1], rq.a, rq.b), ex);
            const float *l = light + 4 * ((size_t)b * HL_BLOCK + entries[2 * e]);
            for (int c = 0; c < 3; c++) acc[c] = fmaf(t, l[c], acc[c]);
        }
    for (int c = 0; c < 3; c++) rgb[c] = (acc[c] * back) * albedo[c];
}
