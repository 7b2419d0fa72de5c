/* haar_group.cl - the GPU shape's Haar of the lighting: hl_haar's result
 * (haar.cl) bit for bit, a work-group per map of a row (2 nrows groups)
 * instead of a work-item per row.
 *
 * Each level's 2x2 blocks, in hl_haar_square's row-major order, are taken
 * a group's width at a time: every work-item reads its block's four
 * values, the group waits, then each writes its block's three details and
 * its average in place, and the group waits again. In place is safe as in
 * hl_haar_square: block (i, j)'s average goes to x[i n + j], before every
 * value that any later block reads (2 i' n + 2 j' and after, for a block
 * (i', j') later in row-major order), and a block's own values are read
 * before its group writes. The same operations on the same values, so
 * the same bits.
 * Twin: host/src/maps/twins/haar.c.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_haar_group(global float *T, global float *coef, global const uint *slot, uint N, uint nrows)
{
    const uint grp = get_group_id(0), lid = get_local_id(0), wg = get_local_size(0);
    if (grp >= 2u * nrows) return; /* the whole group leaves together */
    const size_t nn = (size_t)N * N, base = (size_t)grp * nn; /* row grp / 2, map grp % 2 */
    global float *x = T + base, *o = coef + base;
    const uint n = N;
    for (uint s = n; s >= 2u; s /= 2u) {
        const uint h = s / 2u, blocks = h * h;
        for (uint b0 = 0; b0 < blocks; b0 += wg) {
            const uint b = b0 + lid, i = b / h, j = b % h;
            const int in = b < blocks;
            float a = 0.0f, bb = 0.0f, c = 0.0f, d = 0.0f;
            if (in) {
                a = x[(2 * i) * n + 2 * j];
                bb = x[(2 * i) * n + 2 * j + 1];
                c = x[(2 * i + 1) * n + 2 * j];
                d = x[(2 * i + 1) * n + 2 * j + 1];
            }
            barrier(CLK_GLOBAL_MEM_FENCE);
            if (in) {
                const uint k1 = i * n + j + h, k2 = (i + h) * n + j, k3 = (i + h) * n + j + h;
                o[slot ? slot[k1] : k1] = (a - bb + c - d) * 0.5f;
                o[slot ? slot[k2] : k2] = (a + bb - c - d) * 0.5f;
                o[slot ? slot[k3] : k3] = (a - bb - c + d) * 0.5f;
                x[i * n + j] = (a + bb + c + d) * 0.5f;
            }
            barrier(CLK_GLOBAL_MEM_FENCE);
        }
    }
    if (lid == 0u) o[slot ? slot[0] : 0] = x[0];
}
