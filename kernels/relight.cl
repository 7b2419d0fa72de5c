/* relight.cl - vertex colours: B(v) = albedo(v) * sum_i T_i(v) L_i over the
 * kept lighting terms. One work-item per vertex walks its packed entries
 * block by block, skipping whole blocks in which the lighting keeps no
 * term, and dequantises on the fly. Twin: host/src/ref/relight_ref.c
 * (which skips nothing; the skipped terms are exact zeros, so the sums
 * round the same).
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_relight(global const uchar2 *entries, global const ulong *row_offset,
                       global const ushort *block_counts, global const hl_row_quant *rq,
                       uint scheme, uint nblocks, global const float4 *light,
                       global const uchar *block_used, global const float4 *albedo,
                       global float4 *out, uint nverts)
{
    uint v = get_global_id(0);
    if (v >= nverts) return;
    global const uchar2 *e = entries + row_offset[v];
    global const ushort *bc = block_counts + (size_t)v * nblocks;
    hl_row_quant q = rq[v];
    float4 acc = (float4)(0.0f);
    for (uint b = 0; b < nblocks; b++) {
        uint n = bc[b];
        global const float4 *l = light + (size_t)b * HL_BLOCK;
        if (!block_used[b]) {
            if (n && e[0].x == 0) acc += hl_dequant(scheme, e[0].y, q.a, q.b) * l[0];
        } else {
            for (uint k = 0; k < n; k++) {
                uchar2 x = e[k];
                float t = hl_dequant(scheme, x.y, q.a, q.b);
                acc += t * l[x.x];
            }
        }
        e += n;
    }
    out[v] = acc * albedo[v];
}
