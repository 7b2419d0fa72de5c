/* sh_project.c - twin of kernels/maps/sh_project.cl: the same sums over
 * texels in the same order, one row at a time. */
#include <string.h>

#include "twins.h"

void hl_ref_sh_project_rows(const float *in, uint32_t ncoef, const float *Y, uint32_t stride, uint32_t nsh,
                            float *out)
{
    memset(out, 0, (size_t)ncoef * sizeof(float));
    for (uint32_t j = 0; j < ncoef; j++) {
        const float t = in[j];
        if (t == 0.0f) continue;
        const float *y = Y + (size_t)j * stride;
        for (uint32_t k = 0; k < nsh; k++) out[k] += t * y[k];
    }
}
