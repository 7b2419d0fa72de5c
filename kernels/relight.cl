/* relight.cl - vertex colours: B(v) = albedo(v) * sum_i T_i(v) L_i over the
 * kept lighting terms. The transport is held by column on the device (built
 * on load from the file's rows): for each range of vertices and each slot,
 * the (vertex, code) entries that store it. One work-item owns a range and
 * walks only the columns of the kept slots, in ascending slot order, so the
 * traffic follows the kept terms and not the rows' length, and each vertex
 * adds its terms in the order the twin does (host/src/ref/relight_ref.c,
 * which walks whole rows; the terms it adds that are not kept are exact
 * zeros, so the sums round the same).
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_relight(global const ushort *col_vertex, global const uchar *col_code,
                       global const uint *col_start, uint range, global const hl_row_quant *rq,
                       uint scheme, uint ncoef, global const float4 *light,
                       global const uint *kept_bits, global const float4 *albedo,
                       global float4 *out, uint nverts)
{
    uint w = get_global_id(0);
    uint v0 = w * range;
    if (v0 >= nverts) return;
    uint v1 = min(v0 + range, nverts);
    for (uint v = v0; v < v1; v++) out[v] = (float4)(0.0f);
    global const uint *cs = col_start + (size_t)w * (ncoef + 1);
    for (uint word = 0; word < ncoef / 32u; word++) {
        uint bits = kept_bits[word];
        while (bits) {
            uint low = bits & (0u - bits), slot = word * 32u + (31u - clz(low));
            bits ^= low;
            float4 l = light[slot];
            for (uint k = cs[slot]; k < cs[slot + 1]; k++) {
                uint v = v0 + col_vertex[k];
                hl_row_quant q = rq[v];
                out[v] += hl_dequant(scheme, col_code[k], q.a, q.b) * l;
            }
        }
    }
    for (uint v = v0; v < v1; v++) out[v] *= albedo[v];
}
