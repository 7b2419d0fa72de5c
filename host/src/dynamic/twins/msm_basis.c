/* msm_basis.c - twin of kernels/dynamic/msm_basis.cl: one row of one depth
 * map to the four moments of x = 2 z - 1 per texel (planes and zsc), the
 * coverage (planes), and their row sums, in the kernel's order of additions.
 * Depends on: csm.h. */
#include "csm.h"

void hl_ref_msm_basis(const float *depth, uint32_t R, float kb, uint32_t row, float *img, float *rowsum, float *zsc)
{
    const size_t at = (size_t)row * R;
    const float *z_row = depth + at;
    float *o = img + at * 5, *t4 = zsc + at * 4;
    float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f, a3 = 0.0f, a4 = 0.0f;
    for (uint32_t i = 0; i < R; i++) {
        float z = z_row[i], x = z >= 1.0f ? 1.0f : 2.0f * (z * kb) - 1.0f;
        float x2 = x * x, x3 = x2 * x, x4 = x2 * x2, c = z >= 1.0f ? 0.0f : 1.0f;
        o[5 * i] = t4[4 * i] = x;
        o[5 * i + 1] = t4[4 * i + 1] = x2;
        o[5 * i + 2] = t4[4 * i + 2] = x3;
        o[5 * i + 3] = t4[4 * i + 3] = x4;
        o[5 * i + 4] = c;
        a0 += x;
        a1 += x2;
        a2 += x3;
        a3 += x4;
        a4 += c;
    }
    rowsum[row] = a0;
    rowsum[R + row] = a1;
    rowsum[2 * (size_t)R + row] = a2;
    rowsum[3 * (size_t)R + row] = a3;
    rowsum[4 * (size_t)R + row] = a4;
}
