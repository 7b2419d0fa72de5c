/* csm_sat.c - twin of kernels/dynamic/csm_sat.cl: a plane's mean from its
 * row sums, and the prefix sum of one line in HL_CSM_SCAN_LANES runs plus
 * a tree over the runs' sums, the kernel's additions in the kernel's
 * order (so both round alike). Depends on: csm.h. */
#include "csm.h"

float hl_ref_csm_sat_mean(const float *rowsum, uint32_t R)
{
    float s = 0.0f;
    for (uint32_t i = 0; i < R; i++) s += rowsum[i];
    return s / ((float)R * (float)R);
}

void hl_ref_csm_sat_scan(float *b, size_t step, uint32_t R, float sub)
{
    enum { L = HL_CSM_SCAN_LANES };
    const uint32_t run = R / L;
    float a[L], t[L];
    for (uint32_t l = 0; l < L; l++) {
        float acc = 0.0f;
        for (uint32_t i = l * run; i < (l + 1) * run; i++) {
            acc += b[(size_t)i * step] - sub;
            b[(size_t)i * step] = acc;
        }
        a[l] = acc;
    }
    /* the kernel's tree: step off adds the sum off lanes back */
    for (uint32_t off = 1; off < L; off <<= 1) {
        for (uint32_t l = 0; l < L; l++) t[l] = l >= off ? a[l - off] + a[l] : a[l];
        for (uint32_t l = 0; l < L; l++) a[l] = t[l];
    }
    for (uint32_t l = 1; l < L; l++) {
        float o = a[l - 1];
        for (uint32_t i = l * run; i < (l + 1) * run; i++) b[(size_t)i * step] += o;
    }
}
