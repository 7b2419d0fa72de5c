/* select_group.cl - the GPU shape's selection of lighting terms: the result
 * of hl_select (select.cl) bit for bit, by one work-group of
 * HL_SELECT_LANES work-items instead of one work-item, which on a GPU ran
 * thousands of times slower than the group's width.
 *
 * Work-item k takes chunk k of the slots (hl_select_chunk consecutive
 * slots: whole words of kept bits). The radix select's histograms are
 * counted with local atomics (counts come out the same in any order) and
 * its bin found from their suffix sums, as hl_radix_bin finds it; the
 * ties kept are the lowest slots, found by a prefix sum of each chunk's
 * ties; the kept list is placed by a prefix sum of each chunk's kept
 * count; the energies are summed by chunk and tree, the order select.cl
 * and the twin sum them in (hl_select_fold). So every output, energies
 * included, equals select.cl's.
 * Twin: host/src/relight/twins/select.c.
 */
#pragma OPENCL FP_CONTRACT OFF

#define SG_LANES HL_SELECT_LANES
/* 256-blocks a lighting holds at most: 2 N^2 slots, N up to 256 */
#define SG_MAX_BLOCKS 512u

/* Exclusive prefix sum over the group of x (one uint a work-item): the
 * sum of the lower work-items' x; *total gets the sum of all. Integer
 * sums, so exact. Every work-item of the group must call it. */
static uint scan_excl(local uint *buf, uint k, uint x, uint *total)
{
    barrier(CLK_LOCAL_MEM_FENCE);
    buf[k] = x;
    for (uint d = 1; d < SG_LANES; d *= 2u) {
        barrier(CLK_LOCAL_MEM_FENCE);
        const uint y = k >= d ? buf[k - d] : 0u;
        barrier(CLK_LOCAL_MEM_FENCE);
        buf[k] += y;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    *total = buf[SG_LANES - 1u];
    return buf[k] - x;
}

kernel __attribute__((reqd_work_group_size(SG_LANES, 1, 1)))
void hl_select_group(global const float *L, uint ncoef, global const float *weight, hl_select_params p,
                     global float4 *out, global uchar *block_used, global uint *kept_bits, uint nblocks,
                     global hl_select_result *res, global uint *keys, global uint *kept_list)
{
    local uint buf[SG_LANES], hist[256], pick[2], ymax_bits, used[SG_MAX_BLOCKS / 32u];
    local float et[SG_LANES], ek[SG_LANES], ed[SG_LANES];
    const uint k = get_local_id(0), chunk = hl_select_chunk(ncoef);
    const uint i0 = min(k * chunk, ncoef), i1 = min(i0 + chunk, ncoef);

    /* the priorities' keys, once; the non-zero count and the largest |Y| */
    if (k == 0u) ymax_bits = 0u;
    if (k < SG_MAX_BLOCKS / 32u) used[k] = 0u;
    uint nnz = 0;
    float ymax = 0.0f;
    for (uint i = i0; i < i1; i++) {
        const float y = hl_luminance(L[i], L[ncoef + i], L[2 * ncoef + i]);
        const uint key = hl_key(fabs(y) * weight[i]);
        keys[i] = key;
        nnz += key != 0u;
        ymax = fmax(ymax, fabs(y));
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    /* a maximum of non-negative floats, as their bits (fmax drops NaN as
       select.cl's running fmax does) */
    atomic_max(&ymax_bits, as_uint(ymax));
    uint nnz_all;
    scan_excl(buf, k, nnz, &nnz_all); /* its barriers also order ymax_bits */
    uint eb;
    const float es = hl_light_energy_scale(as_float(ymax_bits), &eb);

    /* the radix select, 8 bits a pass; the same for every work-item */
    uint need = min(p.M, nnz_all), thresh = 0xffffffffu, ties = 0u;
    if (need > 0u) {
        uint prefix = 0u, mask = 0u;
        for (int shift = 24; shift >= 0; shift -= 8) {
            hist[k] = 0u; /* SG_LANES == 256 bins */
            barrier(CLK_LOCAL_MEM_FENCE);
            for (uint i = i0; i < i1; i++) {
                const uint key = keys[i];
                if (key && (key & mask) == prefix) atomic_inc(&hist[(key >> shift) & 255u]);
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            /* work-item k holds bin b = 255 - k: the keys in bins above b
               are the exclusive sum, those in b and above the inclusive */
            const uint b = 255u - (uint)k, h = hist[b];
            uint all;
            const uint above = scan_excl(buf, k, h, &all);
            /* hl_radix_bin: the highest bin whose keys with those above
               reach need, or bin 0 once the bins above it do not */
            if (above < need && (b == 0u || above + h >= need)) {
                pick[0] = b;
                pick[1] = need - above;
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            prefix |= pick[0] << shift;
            mask |= 255u << shift;
            need = pick[1];
            barrier(CLK_LOCAL_MEM_FENCE);
        }
        thresh = prefix;
        ties = need;
    }

    /* the kept: every key above thresh, and the first `ties` keys equal
       to it in slot order; each chunk's first tie and first list place */
    uint eq = 0u, gt = 0u;
    for (uint i = i0; i < i1; i++) {
        const uint key = keys[i];
        gt += key > thresh;
        eq += key == thresh && key != 0u;
    }
    uint total;
    uint seen = scan_excl(buf, k, eq, &total);
    const uint mine = gt + (ties > seen ? min(eq, ties - seen) : 0u);
    uint kept;
    uint at = scan_excl(buf, k, mine, &kept);

    float pt = 0.0f, pk = 0.0f, pd = 0.0f;
    uint word = 0u;
    for (uint i = i0; i < i1; i++) {
        const float r = L[i], g = L[ncoef + i], b = L[2 * ncoef + i];
        const float y = hl_luminance(r, g, b) * es;
        pt += y * y;
        const uint key = keys[i];
        const int keep = key > thresh || (key == thresh && key != 0u && seen++ < ties);
        out[i] = keep ? (float4)(r, g, b, 0.0f) : (float4)(0.0f);
        if (keep) {
            pk += y * y;
            if (i & 255u) atomic_or(&used[i >> 13], 1u << ((i >> 8) & 31u));
            word |= 1u << (i & 31u);
            kept_list[1u + at++] = i;
        } else {
            pd += y * y;
        }
        if ((i & 31u) == 31u || i + 1u == i1) {
            kept_bits[i >> 5] = word;
            word = 0u;
        }
    }
    /* the energies: the chunks' sums, then the tree of hl_select_fold */
    et[k] = pt;
    ek[k] = pk;
    ed[k] = pd;
    for (uint h = SG_LANES / 2u; h > 0u; h /= 2u) {
        barrier(CLK_LOCAL_MEM_FENCE);
        if (k < h) {
            et[k] += et[k + h];
            ek[k] += ek[k + h];
            ed[k] += ed[k + h];
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    uint nused = 0u;
    for (uint b = k; b < nblocks; b += SG_LANES) {
        const uint f = (used[b >> 5] >> (b & 31u)) & 1u;
        block_used[b] = (uchar)f;
        nused += f;
    }
    uint blocks;
    scan_excl(buf, k, nused, &blocks);
    if (k == 0u) {
        kept_list[0] = kept;
        *res = hl_select_result_of(et[0], ek[0], ed[0], kept, blocks, eb);
    }
}
