/* bounce.cl - one bounce's gather (host/src/precompute/bounce.h): work-item
 * r of a chunk writes vertex r's T_b, ncoef floats, as the sum over its K
 * samples of rho(y) / K times the hit triangle's corners' rows of T_(b-1),
 * weighted by the hit's barycentrics. The twin
 * (host/src/precompute/twins/bounce.c) adds in the same order: samples,
 * corners, terms; no contraction, so the bits agree.
 */
#pragma OPENCL FP_CONTRACT OFF

/* SLOT: the slots' type, ushort where ncoef fits 16 bits, else uint
 * (hl_bounce_src); the values binary16s, zero or normal, times their
 * row's scale: decoded as their bits moved into a float's (2^-112 of the
 * value) times 2^112, exact, and cheaper than vload_half on a CPU. */
#define HL_BOUNCE_GATHER(NAME, SLOT)                                                                           \
    kernel void NAME(global const uint *start, global const SLOT *slot, global const ushort *val,               \
                     global const float *scale, global const uint *indices, global const float *rho,          \
                     global const uint *prim, global const float *uv, uint K, uint ncoef, uint count,          \
                     global float *out)                                                                        \
    {                                                                                                          \
        const uint r = get_global_id(0);                                                                       \
        if (r >= count) return;                                                                                \
        global float *o = out + (size_t)r * ncoef;                                                             \
        for (uint s = 0; s < ncoef; s++) o[s] = 0.0f;                                                          \
        const float invK = 1.0f / (float)K;                                                                    \
        for (uint k = 0; k < K; k++) {                                                                         \
            const size_t q = (size_t)r * K + k;                                                                \
            const uint p = prim[q];                                                                            \
            if (p == 0xffffffffu) continue;                                                                    \
            const float u = uv[2 * q], v = uv[2 * q + 1], w0 = 1.0f - u - v;                                   \
            const uint c[3] = {indices[3 * (size_t)p], indices[3 * (size_t)p + 1], indices[3 * (size_t)p + 2]}; \
            const float b[3] = {w0, u, v};                                                                     \
            const float ry = w0 * rho[c[0]] + u * rho[c[1]] + v * rho[c[2]];                                   \
            for (int j = 0; j < 3; j++) {                                                                      \
                const float w = ry * b[j] * invK * scale[c[j]];                                                \
                const uint e1 = start[c[j] + 1];                                                               \
                for (uint e = start[c[j]]; e < e1; e++) {                                                      \
                    const uint h = val[e];                                                                     \
                    const float t = w * (as_float(((h & 0x8000u) << 16) | ((h & 0x7fffu) << 13)) * 0x1p112f);    \
                    o[slot[e]] = o[slot[e]] + t;                                                               \
                }                                                                                              \
            }                                                                                                  \
        }                                                                                                      \
    }

HL_BOUNCE_GATHER(hl_bounce_gather, ushort)
HL_BOUNCE_GATHER(hl_bounce_gather_wide, uint)
