/* csm_basis.c - twin of kernels/dynamic/csm_basis.cl: one row of one
 * depth map to the basis planes (z, S_k, C_k, z S_k, z C_k) and their row
 * sums and the texels' (z, sin(c1 z), cos(c1 z), 0), with the kernel's
 * rotation recurrence and order of additions.
 * Depends on: csm.h. */
#include <math.h>

#include "csm.h"

void hl_ref_csm_basis(const float *depth, uint32_t R, uint32_t M, uint32_t Mb, float c1, uint32_t row, float *img,
                      float *rowsum, float *zsc)
{
    const uint32_t P = hl_csm_planes(M, Mb);
    const float *z_row = depth + (size_t)row * R;
    float *out = img + (size_t)row * R * P;
    float *t4 = zsc + (size_t)row * R * 4;
    float acc[2 * HL_CSM_M_MAX + 2 * HL_CSM_M_MAX + 1];
    for (uint32_t p = 0; p < P; p++) acc[p] = 0.0f;
    for (uint32_t i = 0; i < R; i++) {
        float z = z_row[i];
        float ph = c1 * z;
        float s = sinf(ph), c = cosf(ph);
        float rs = 2.0f * s * c, rc = c * c - s * s;
        float *o = out + (size_t)i * P;
        t4[4 * i] = z;
        t4[4 * i + 1] = s;
        t4[4 * i + 2] = c;
        t4[4 * i + 3] = 0.0f;
        o[0] = z;
        acc[0] += z;
        for (uint32_t k = 0; k < M; k++) {
            o[1 + 2 * k] = s;
            o[2 + 2 * k] = c;
            acc[1 + 2 * k] += s;
            acc[2 + 2 * k] += c;
            if (k < Mb) {
                float zs = z * s, zc = z * c;
                o[1 + 2 * M + 2 * k] = zs;
                o[2 + 2 * M + 2 * k] = zc;
                acc[1 + 2 * M + 2 * k] += zs;
                acc[2 + 2 * M + 2 * k] += zc;
            }
            float s2 = s * rc + c * rs, c2 = c * rc - s * rs;
            s = s2;
            c = c2;
        }
    }
    for (uint32_t p = 0; p < P; p++) rowsum[(size_t)p * R + row] = acc[p];
}
