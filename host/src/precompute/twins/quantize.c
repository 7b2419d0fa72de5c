/* quantize.c - twin of kernels/precompute/quantize.cl. */
#include <math.h>
#include <string.h>

#include "twins.h"

uint32_t hl_ref_quantize(const hl_geom *g, const float *coef, hl_trunc_result tr,
                         uint32_t scheme, uint32_t vertex, hl_row_quant *rq, uint16_t *block_counts,
                         uint8_t *entries)
{
    /* mark the kept slots first, then quantise them */
    uint32_t ties = 0, n = 0;
    float lo = INFINITY, hi = -INFINITY;
    memset(block_counts, 0, g->nblocks * sizeof *block_counts);
    for (uint32_t i = 0; i < g->ncoef; i++) {
        uint32_t key = hl_key(coef[i]);
        int keep = key > tr.thresh || (key == tr.thresh && key != 0 && ties++ < tr.ties);
        if (!keep) continue;
        float v = scheme != HL_QUANT_LINEAR8 ? fabsf(coef[i]) : coef[i];
        if (v < lo) lo = v;
        if (v > hi) hi = v;
        entries[2 * n] = (uint8_t)(i % HL_BLOCK); /* value filled below */
        entries[2 * n + 1] = 0;
        block_counts[i / HL_BLOCK]++;
        n++;
    }
    if (n == 0) lo = hi = 0.0f;
    rq->a = lo;
    rq->b = hi;
    uint32_t e = 0;
    for (uint32_t b = 0; b < g->nblocks; b++)
        for (uint32_t k = 0; k < block_counts[b]; k++, e++) {
            const uint32_t slot = b * HL_BLOCK + entries[2 * e];
            uint32_t q = hl_quant(scheme, coef[slot], lo, hi, hl_dither_key(vertex, slot));
            entries[2 * e + 1] = (uint8_t)q;
        }
    return n;
}
