/* relight_rows.cl - vertex colours straight from the rows as the file
 * stores them (8-bit codes in 256-slot blocks), for a relight of one or a
 * few lighting changes: no column layout is built (relight.cl's columns
 * take seconds to lay out on a big mesh and pay off over many changes).
 *
 * Each work-item takes `per` consecutive vertices. A vertex walks its
 * blocks, skips those with no kept slot (their 8 words of kept bits all
 * zero) and, in the others, the entries whose slot is not kept (bits); each kept term is decoded
 * (hl_dequant with the vertex's dither), scaled by 2^-e and rounded to
 * half precision as the columns hold it (host/src/core/half.h), and added
 * with one fused multiply-add per colour in ascending slot order. So the
 * sums are those of relight.cl and of its twin, bit for bit (a skipped
 * term would add t x 0, which leaves a sum that is never -0 unchanged).
 * Then the sums times 2^e, times the albedo (one for all where
 * albedo_step is 0: every vertex has the same), clamped at zero (unless
 * keep_negative), the fourth float the lowest channel before the clamp;
 * each work-item's clamp tally (hl_tally_add) into tally.
 * Twin: hl_ref_relight (host/src/relight/twins/relight.c).
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_relight_rows(global const uchar *entries, global const ulong *row_offset,
                            global const ushort *block_counts, global const float2 *row_quant, uint scheme,
                            uint nblocks, uint ncoef, global const uint *bits,
                            global const float4 *light, global const float4 *albedo, uint keep_negative,
                            global float4 *out, uint nverts, uint per, global float4 *tally, uint albedo_step)
{
    const uint v0 = get_global_id(0) * per;
    if (v0 >= nverts) return; /* past the last item: they fill the last group, and write no tally */
    float lo = 0.0f, hi = 0.0f;
    uint neg = 0;
    for (uint v = v0; v < v0 + per && v < nverts; v++) {
        const float2 q = row_quant[v];
        const int ex = hl_half_exponent(scheme, q.x, q.y);
        const float inv = ldexp(1.0f, -ex), back = ldexp(1.0f, ex);
        float sr = 0.0f, sg = 0.0f, sb = 0.0f;
        ulong e = row_offset[v];
        global const ushort *bc = block_counts + (size_t)v * nblocks;
        for (uint b = 0; b < nblocks; b++) {
            const uint n = bc[b];
            /* the block's words of kept bits (fewer in a short last block) */
            global const uint *kb = bits + b * (HL_BLOCK / 32u);
            const uint nw = min(HL_BLOCK / 32u, (ncoef - b * HL_BLOCK + 31u) / 32u);
            uint any = 0u;
            for (uint w = 0; w < nw; w++) any |= kb[w];
            if (!any) {
                e += n;
                continue;
            }
            for (uint k = 0; k < n; k++, e++) {
                const uint slot = b * HL_BLOCK + entries[2 * e];
                if (!((bits[slot >> 5] >> (slot & 31u)) & 1u)) continue;
                float t = hl_dequant(scheme, entries[2 * e + 1], q.x, q.y, hl_dither_key(v, slot));
                t = hl_half_value(hl_half_bits(t * inv)); /* hl_half_term of half.h */
                const float4 l = light[slot];
                sr = fma(t, l.x, sr);
                sg = fma(t, l.y, sg);
                sb = fma(t, l.z, sb);
            }
        }
        const float4 c = hl_colour_out(((float4)(sr, sg, sb, 0.0f) * back) * albedo[v * albedo_step], keep_negative);
        out[v] = c;
        hl_tally_add(c, &lo, &hi, &neg);
    }
    tally[get_global_id(0)] = (float4)(lo, hi, as_float(neg), 0.0f);
}
