/* env2para.cl - environment cells to dual-paraboloid lighting, with a
 * rotation about +Y. One work-item per paraboloid texel sums its taps:
 * the cells overlapping its footprint, weighted by the overlap's share of
 * the texel's solid angle (fixed at rotation 0). A turn of the content is
 * an offset of s0 + f cells along every row; the fraction blends each cell
 * with its neighbour. A constant map gives a constant result, and each
 * cell's light is shared out in full. Output: three planes (R, G, B) of
 * ncoef texels. Twin: host/src/ref/env2para_ref.c.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_env2para(global const float4 *cells, uint wc, global const uint *start,
                        global const hl_env_tap *taps, uint s0, float f, uint ncoef,
                        global float *L)
{
    uint j = get_global_id(0);
    if (j >= ncoef) return;
    uint mask = wc - 1u; /* wc is a power of two */
    float4 acc = (float4)(0.0f);
    for (uint e = start[j]; e < start[j + 1]; e++) {
        hl_env_tap tap = taps[e];
        global const float4 *row = cells + (size_t)tap.row * wc;
        uint k = tap.col + s0;
        float4 a = row[k & mask], b = row[(k + 1u) & mask];
        acc += tap.weight * (a + f * (b - a));
    }
    L[j] = acc.x;
    L[ncoef + j] = acc.y;
    L[2 * ncoef + j] = acc.z;
}
