/* relight.cl - vertex colours: B(v) = albedo(v) * sum_i T_i(v) L_i over the
 * kept lighting terms.
 *
 * The transport is held by column on the device (built on load from the
 * file's rows, see build_columns in host/src/cl_backend.c). The device
 * holds the vertices in its own order (order[p]: the vertex at position p;
 * see vertex_order), positions grouped in tiles of HL_TILE and tiles in
 * ranges, one range per work-item (range_start: position boundaries, whole
 * tiles); albedo and back are in position order, colours go to their
 * vertices. For each range and slot, the column lists the tiles in which
 * at least one vertex stores that slot, each as one entry of
 * 1 + HL_TILE / 2 words: a head (the tile in the range) and the tile's
 * HL_TILE terms as halves, decoded from the file's codes on load and scaled
 * by 2^-e per vertex (host/src/half.h; zero in lanes whose vertex does not
 * store the slot). A work-item walks only the kept slots' columns, in
 * ascending slot order, and adds each entry's terms as one vector into the
 * range's running sums (red, green and blue planes in `acc`), then scales
 * each vertex's sums back by 2^e (back). Zero lanes add exact zeros
 * (fma(0, l, s) = s), so every vertex sums its terms in the order the twin
 * does (host/src/ref/relight_ref.c walks whole rows) and rounds alike.
 */
#pragma OPENCL FP_CONTRACT OFF

#define HL_CAT_(a, b) a##b
#define HL_CAT(a, b) HL_CAT_(a, b)
#define FV HL_CAT(float, HL_TILE)            /* float16 */
#define LOAD_TERMS HL_CAT(vload_half, HL_TILE)

#if HL_TILE != 8 && HL_TILE != 16
#error "HL_TILE must be 8 or 16"
#endif

/* Adds d times the light to tile tq's running sums, each term with one
 * rounding (an explicit fused multiply-add; the twin calls fmaf). The sums
 * are addressed as whole aligned vectors (every range starts on a tile,
 * and tiles are HL_TILE floats), so each is one aligned load and store
 * rather than a split unaligned one. */
#define ADD_TILE(d)                          \
    do {                                     \
        vr[tq] = fma((d), lr, vr[tq]);       \
        vg[tq] = fma((d), lg, vg[tq]);       \
        vb[tq] = fma((d), lb, vb[tq]);       \
    } while (0)

kernel void hl_relight(global const uint *col, global const uint *col_start, global const uint *range_start,
                       global const float *back, uint ncoef, global const float4 *light, global const uint *kept_bits,
                       global const float4 *albedo, global float *acc, global float4 *out, uint nverts, uint nranges,
                       global const uint *order)
{
    uint w = get_global_id(0);
    if (w >= nranges) return;
    uint v0 = range_start[w], range = range_start[w + 1] - v0;
    uint v1 = min(v0 + range, nverts);
    global float *ar = acc + (size_t)3 * v0, *ag = ar + range, *ab = ag + range;
    global FV *vr = (global FV *)ar, *vg = (global FV *)ag, *vb = (global FV *)ab;
    for (uint i = 0; i < range / HL_TILE; i++) vr[i] = vg[i] = vb[i] = (FV)(0.0f);
    global const uint *cs = col_start + (size_t)w * (ncoef + 1);
    const uint stride = 1u + HL_TILE / 2u;
    for (uint word = 0; word < ncoef / 32u; word++) {
        uint bits = kept_bits[word];
        while (bits) {
            uint low = bits & (0u - bits), slot = word * 32u + (31u - clz(low));
            bits ^= low;
            float4 l = light[slot];
            FV lr = (FV)(l.x), lg = (FV)(l.y), lb = (FV)(l.z);
            global const uint *e = col + (size_t)cs[slot] * stride, *end = col + (size_t)cs[slot + 1] * stride;
            for (; e < end; e += stride) {
                uint tq = e[0];
                FV d = LOAD_TERMS(0, (global const half *)(e + 1));
                ADD_TILE(d);
            }
        }
    }
    for (uint v = v0; v < v1; v++) {
        uint i = v - v0;
        out[order[v]] = ((float4)(ar[i], ag[i], ab[i], 0.0f) * back[v]) * albedo[v];
    }
}
