/* env2para.cl - environment cells to dual-paraboloid lighting, with a
 * rotation about +Y. Twin: host/src/maps/twins/env2para.c.
 *
 * A turn of the content is an offset of s0 + f cells along every row:
 * hl_turn writes the turned grid once per change, each cell blended with
 * its neighbour by the fraction f. Then each paraboloid texel sums its
 * taps: the cells overlapping its footprint, weighted by the overlap's
 * share of the texel's solid angle (fixed at rotation 0). A constant map
 * gives a constant result, and each cell's light is shared out in full.
 * Both kernels give each work-item `per` consecutive cells or texels (a
 * contiguous chunk suits a CPU device). Output: three planes (R, G, B) of
 * ncoef texels.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_turn(global const float4 *cells, uint wc, uint ncells, uint s0, float f, uint per,
                    global float4 *turned)
{
    uint i0 = get_global_id(0) * per;
    uint i1 = min(i0 + per, ncells);
    uint mask = wc - 1u; /* wc is a power of two */
    for (uint i = i0; i < i1; i++) {
        global const float4 *row = cells + (i & ~mask);
        uint k = (i & mask) + s0;
        float4 a = row[k & mask], b = row[(k + 1u) & mask];
        turned[i] = a + f * (b - a);
    }
}

/* taps: (cell index row * wc + col, weight bits) pairs, the device's
 * compact copy of the hl_env_tap table */
kernel void hl_env2para(global const float4 *turned, global const uint *start, global const uint2 *taps,
                        uint ncoef, uint per, global float *L)
{
    uint j0 = get_global_id(0) * per;
    uint j1 = min(j0 + per, ncoef);
    for (uint j = j0; j < j1; j++) {
        float4 acc = (float4)(0.0f);
        for (uint e = start[j]; e < start[j + 1]; e++) {
            uint2 tap = taps[e];
            acc += as_float(tap.y) * turned[tap.x];
        }
        L[j] = acc.x;
        L[ncoef + j] = acc.y;
        L[2 * ncoef + j] = acc.z;
    }
}
