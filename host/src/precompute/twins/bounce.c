/* twins/bounce.c - plain-C twin of kernels/precompute/bounce.cl: one
 * bounce's gather for one vertex, in the kernel's order (samples, then
 * corners, then the hit vertex's terms; products and sums rounded apart),
 * so the two give the same bits.
 */
#include "bounce.h"

void hl_ref_bounce_gather(const hl_bounce_src *src, const uint32_t *indices, const float *rho, const uint32_t *prim,
                          const float *uv, uint32_t K, uint32_t ncoef, float *out)
{
    for (uint32_t s = 0; s < ncoef; s++) out[s] = 0.0f;
    const float invK = 1.0f / (float)K;
    for (uint32_t k = 0; k < K; k++) {
        const uint32_t p = prim[k];
        if (p == HL_BOUNCE_MISS) continue;
        const float u = uv[2 * k], v = uv[2 * k + 1], w0 = 1.0f - u - v;
        const uint32_t c[3] = {indices[3 * (size_t)p], indices[3 * (size_t)p + 1], indices[3 * (size_t)p + 2]};
        const float b[3] = {w0, u, v};
        const float ry = w0 * rho[c[0]] + u * rho[c[1]] + v * rho[c[2]];
        for (int j = 0; j < 3; j++) {
            const float w = ry * b[j] * invK * src->scale[c[j]];
            const uint32_t e0 = src->start[c[j]], e1 = src->start[c[j] + 1];
            for (uint32_t e = e0; e < e1; e++) {
                const uint32_t s = src->slot16 ? src->slot16[e] : src->slot32[e];
                const float t = w * hl_half_to_float(src->val[e]);
                out[s] = out[s] + t;
            }
        }
    }
}
