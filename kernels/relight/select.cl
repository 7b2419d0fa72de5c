/* select.cl - nonlinear approximation of the lighting: keep the M Haar
 * coefficients of highest priority |Y_i| * weight_i (Y the luminance
 * coefficient; RGB share the index set), by exact radix select on the
 * priority's bit pattern, ties to the lower slot. One work-item: the
 * vector is small. Writes the kept terms densely (zeros elsewhere) as
 * float4 RGB, a flag per 256-block, a bit per slot, the kept slots in
 * ascending order (kept_list: the count, then the slots; the dot products
 * walk it), and the energies for the error bound (the dropped energy
 * summed on its own: total - kept cancels in float when a bright sun
 * dominates), scaled by a power of two (hl_light_energy_scale) so that
 * they stay finite and non-zero, summed by chunks and a tree
 * (hl_select_chunk, hl_select_fold) as the GPU shape's select_group.cl
 * sums them.
 * A block's flag counts only its detail slots 1..255: slot 0 holds a
 * coarse coefficient (kept almost always), which would otherwise mark
 * every block used.
 * Twin: host/src/relight/twins/select.c.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_select(global const float *L, uint ncoef, global const float *weight,
                      hl_select_params p, global float4 *out, global uchar *block_used,
                      global uint *kept_bits, uint nblocks, global hl_select_result *res,
                      global uint *keys, global uint *kept_list)
{
    if (get_global_id(0) != 0) return;
    uint hist[256];
    uint nnz = 0;
    float ymax = 0.0f;
    /* the priorities' keys, once (the passes below read them 5 times) */
    for (uint i = 0; i < ncoef; i++) {
        float y = hl_luminance(L[i], L[ncoef + i], L[2 * ncoef + i]);
        keys[i] = hl_key(fabs(y) * weight[i]);
        nnz += keys[i] != 0u;
        ymax = fmax(ymax, fabs(y));
    }
    uint eb;
    float es = hl_light_energy_scale(ymax, &eb);
    uint need = min(p.M, nnz);
    uint thresh = 0xffffffffu, ties = 0;
    if (need > 0) {
        uint prefix = 0, mask = 0;
        for (int shift = 24; shift >= 0; shift -= 8) {
            for (int b = 0; b < 256; b++) hist[b] = 0;
            for (uint i = 0; i < ncoef; i++) {
                uint k = keys[i];
                if (k && (k & mask) == prefix) hist[(k >> shift) & 255u]++;
            }
            uint b = hl_radix_bin(hist, &need);
            prefix |= b << shift;
            mask |= 255u << shift;
        }
        thresh = prefix;
        ties = need;
    }
    for (uint b = 0; b < nblocks; b++) block_used[b] = 0;
    for (uint w = 0; w < ncoef / 32u; w++) kept_bits[w] = 0;
    float et[HL_SELECT_LANES], ek[HL_SELECT_LANES], ed[HL_SELECT_LANES];
    for (uint c = 0; c < HL_SELECT_LANES; c++) et[c] = ek[c] = ed[c] = 0.0f;
    const uint chunk = hl_select_chunk(ncoef);
    uint kept = 0, seen = 0;
    for (uint i = 0; i < ncoef; i++) {
        float r = L[i], g = L[ncoef + i], b = L[2 * ncoef + i];
        float y = hl_luminance(r, g, b) * es;
        const uint c = i / chunk;
        et[c] += y * y;
        uint k = keys[i];
        int keep = k > thresh || (k == thresh && k != 0u && seen++ < ties);
        out[i] = keep ? (float4)(r, g, b, 0.0f) : (float4)(0.0f);
        if (keep) {
            ek[c] += y * y;
            kept++;
            if (i & 255u) block_used[i >> 8] = 1;
            kept_bits[i >> 5] |= 1u << (i & 31u);
            kept_list[kept] = i;
        } else {
            ed[c] += y * y;
        }
    }
    kept_list[0] = kept;
    uint used = 0;
    for (uint b = 0; b < nblocks; b++) used += block_used[b];
    hl_select_fold(et);
    hl_select_fold(ek);
    hl_select_fold(ed);
    *res = hl_select_result_of(et[0], ek[0], ed[0], kept, used, eb);
}
