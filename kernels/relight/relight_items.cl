/* relight_items.cl - the GPU shape's dot products: relight.cl's colours
 * bit for bit, a work-item a position instead of a work-item a range.
 *
 * The columns are relight.cl's (see there), cut into ranges of rpos
 * positions, HL_ITEMS_RANGE_TILES tiles or (relit in parts) a power of
 * two fewer (host/src/relight/cl_columns.c), so each range holds one
 * word of tile bits a slot. A range's positions are shared by groups of
 * get_local_size(0) work-items (a power of two dividing rpos); work-item
 * p of a range is lane p % HL_TILE of tile p / HL_TILE. The group stages the kept slots, ITEMS_SLOTS at a
 * time, in local memory: each slot's light, its tile bits in the range
 * and where its column's entries start. Then every work-item walks the
 * staged slots in ascending order and, where its tile holds the slot,
 * reads its lane's half of the entry: the 16 lanes of a tile read one
 * 32-byte entry together. Each term is added with one fused multiply-add
 * a colour in ascending slot order, as the twin adds it (a tile that
 * lacks a slot reads entry 0, as relight.cl does, and adds exact zeros),
 * then the sums are scaled back by 2^e and times the albedo, clamped as
 * relight.cl clamps them (hl_colour_out).
 *
 * tally[(tally0 + w) * groups + g]: the clamp's tally (hl_tally_add) of
 * group g of range w, groups = rpos / the group's size (tally0: the
 * part's first range when relit in parts); min, max and a count, joined
 * in local memory in any order to the same result.
 * Twin: host/src/relight/twins/relight.c.
 */
#pragma OPENCL FP_CONTRACT OFF

#define ITEMS_SLOTS 128u   /* kept slots staged at a time */
#define ITEMS_MAX_GROUP 256u

kernel void hl_relight_items(global const uint *col, global const uint *col_start, global const uint2 *rel,
                             uint tstride, global const uint *range_start, global const float *back, uint ncoef,
                             global const float4 *light, global const uint *kept, global const float4 *albedo,
                             global float4 *out, uint nverts, uint nranges, global const uint *order,
                             uint keep_negative, global float4 *tally, uint tally0, uint albedo_step, uint rpos)
{
    local float4 sl[ITEMS_SLOTS];
    local uint sbits[ITEMS_SLOTS], sbase[ITEMS_SLOTS];
    local float tlo[ITEMS_MAX_GROUP], thi[ITEMS_MAX_GROUP];
    local uint tneg[ITEMS_MAX_GROUP];
    const uint lid = get_local_id(0), wg = get_local_size(0);
    const uint groups = rpos / wg;
    const uint w = get_group_id(0) / groups, g = get_group_id(0) % groups;
    if (w >= nranges) return; /* the whole group leaves together */
    const uint v0 = range_start[w], off = g * wg + lid, p = v0 + off;
    const int valid = p < range_start[w + 1];
    const uint tile = off / HL_TILE, lane = off % HL_TILE;
    global const uint *cs = col_start + (size_t)w * (ncoef + 1);
    global const uint2 *rw = rel + (size_t)w * ncoef * tstride;
    const uint m = kept[0], below = (1u << tile) - 1u; /* tile < 32 */
    float sr = 0.0f, sg = 0.0f, sb = 0.0f;
    for (uint j0 = 0; j0 < m; j0 += ITEMS_SLOTS) {
        const uint n = min(ITEMS_SLOTS, m - j0);
        barrier(CLK_LOCAL_MEM_FENCE);
        for (uint j = lid; j < n; j += wg) {
            const uint s = kept[1 + j0 + j];
            const uint2 r = rw[(size_t)s * tstride];
            sl[j] = light[s];
            sbits[j] = r.x;
            sbase[j] = cs[s] + r.y; /* the column's first entry in the word */
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        if (!valid) continue;
        /* a tile that lacks the slot reads entry 0 (all zero), so that no
           load waits on a branch and the unrolled loads are in flight
           together: one at a time, each waited for, 200 slots would cost
           200 memory latencies a work-item. Unrolled by hand, eight slots
           a step (the inner loop's count is fixed, so the compiler
           unrolls it whole), then the rest: "#pragma unroll 8" on the
           loop of n steps is refused with a warning by some compilers
           (PoCL's), and the sums are added in the same order either way */
#define ITEMS_SLOT(j)                                                                                  \
    {                                                                                                  \
        const uint bits = sbits[j];                                                                    \
        const uint e = (bits >> tile) & 1u ? sbase[j] + popcount(bits & below) : 0u;                   \
        const float d = vload_half(lane, (global const half *)(col + (size_t)e * (HL_TILE / 2u)));     \
        const float4 l = sl[j];                                                                        \
        sr = fma(d, l.x, sr);                                                                          \
        sg = fma(d, l.y, sg);                                                                          \
        sb = fma(d, l.z, sb);                                                                          \
    }
        uint j = 0;
        for (; j + 8u <= n; j += 8u)
            for (uint q = 0; q < 8u; q++) ITEMS_SLOT(j + q)
        for (; j < n; j++) ITEMS_SLOT(j)
#undef ITEMS_SLOT
    }
    float lo = 0.0f, hi = 0.0f;
    uint neg = 0u;
    if (valid && p < nverts) {
        const float4 c = hl_colour_out(((float4)(sr, sg, sb, 0.0f) * back[p]) * albedo[p * albedo_step], keep_negative);
        out[order[p]] = c;
        hl_tally_add(c, &lo, &hi, &neg);
    }
    tlo[lid] = lo;
    thi[lid] = hi;
    tneg[lid] = neg;
    for (uint h = wg / 2u; h > 0u; h /= 2u) {
        barrier(CLK_LOCAL_MEM_FENCE);
        if (lid < h) {
            tlo[lid] = tlo[lid + h] < tlo[lid] ? tlo[lid + h] : tlo[lid];
            thi[lid] = thi[lid + h] > thi[lid] ? thi[lid + h] : thi[lid];
            tneg[lid] += tneg[lid + h];
        }
    }
    if (lid == 0u) tally[(size_t)(tally0 + w) * groups + g] = (float4)(tlo[0], thi[0], as_float(tneg[0]), 0.0f);
}
