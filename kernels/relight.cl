/* relight.cl - vertex colours: B(v) = albedo(v) * sum_i T_i(v) L_i over the
 * kept lighting terms. One work-item per vertex goes block by block. Each
 * vertex-block has a 256-bit mask of the slots it stores (built on load
 * from the index bytes); AND with the mask of kept lighting slots gives the
 * terms to take, and a popcount gives each one's place among the block's
 * entries. The work follows the few kept terms, not the tens stored. A
 * block whose detail slots keep no lighting term takes only its slot 0 (a
 * coarse coefficient). Terms are added in slot order, as the twin
 * (host/src/ref/relight_ref.c, which skips nothing) adds them; the skipped
 * terms are exact zeros, so the sums round the same.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_relight(global const uchar2 *entries, global const ulong *row_offset,
                       global const ushort *block_counts, global const hl_row_quant *rq,
                       uint scheme, uint nblocks, global const float4 *light,
                       global const uchar *block_used, global const uint *kept_bits,
                       global const uint *vmask, global const float4 *albedo,
                       global float4 *out, uint nverts)
{
    uint v = get_global_id(0);
    if (v >= nverts) return;
    global const uchar2 *e = entries + row_offset[v];
    global const ushort *bc = block_counts + (size_t)v * nblocks;
    global const uint *vm = vmask + (size_t)v * nblocks * 8;
    hl_row_quant q = rq[v];
    float4 acc = (float4)(0.0f);
    for (uint b = 0; b < nblocks; b++, vm += 8) {
        uint n = bc[b];
        if (!n) continue;
        global const float4 *l = light + (size_t)b * HL_BLOCK;
        if (!block_used[b]) {
            if (vm[0] & 1u) acc += hl_dequant(scheme, e[0].y, q.a, q.b) * l[0];
        } else {
            uint rank = 0;
            for (uint w = 0; w < 8; w++) {
                uint have = vm[w], hit = have & kept_bits[b * 8 + w];
                while (hit) {
                    uint low = hit & (0u - hit), bit = 31u - clz(low);
                    uint k = rank + popcount(have & (low - 1u));
                    acc += hl_dequant(scheme, e[k].y, q.a, q.b) * l[w * 32u + bit];
                    hit ^= low;
                }
                rank += popcount(have);
            }
        }
        e += n;
    }
    out[v] = acc * albedo[v];
}
