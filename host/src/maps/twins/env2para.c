/* env2para.c - twin of kernels/maps/env2para.cl. */
#include "twins.h"

void hl_ref_env2para(const float *cells, uint32_t wc, const uint32_t *start, const hl_env_tap *taps,
                     uint32_t s0, float f, uint32_t ncoef, float *L)
{
    for (uint32_t j = 0; j < ncoef; j++) {
        float acc[3] = {0.0f, 0.0f, 0.0f};
        for (uint32_t e = start[j]; e < start[j + 1]; e++) {
            uint32_t k = (taps[e].col + s0) % wc, k1 = (k + 1) % wc;
            const float *a = cells + 4 * ((size_t)taps[e].row * wc + k), *b = cells + 4 * ((size_t)taps[e].row * wc + k1);
            for (int c = 0; c < 3; c++) acc[c] += taps[e].weight * (a[c] + f * (b[c] - a[c]));
        }
        for (int c = 0; c < 3; c++) L[(size_t)c * ncoef + j] = acc[c];
    }
}
