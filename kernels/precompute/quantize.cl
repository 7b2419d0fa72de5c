/* quantize.cl - 8-bit quantisation and packing into 256-slot blocks.
 * One work-item per row: a pass for the range of the kept values, a pass
 * that writes (index, code) pairs in slot order. Each row owns a fixed
 * span of ncoef pairs in `entries`; row v is vertex first + v (sqrt8's
 * dither depends on it). Twin: host/src/precompute/twins/quantize.c.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_quantize(global const float *coef, uint ncoef, uint nblocks,
                        global const hl_trunc_result *tr, uint scheme,
                        global hl_row_quant *rq, global ushort *block_counts,
                        global uchar *entries, global uint *nnz, uint nrows, uint first)
{
    uint v = get_global_id(0);
    if (v >= nrows) return;
    global const float *c = coef + (size_t)v * ncoef;
    hl_trunc_result t = tr[v];
    float lo = INFINITY, hi = -INFINITY;
    uint ties = 0;
    for (uint i = 0; i < ncoef; i++) {
        uint k = hl_key(c[i]);
        if (k > t.thresh || (k == t.thresh && k != 0 && ties++ < t.ties)) {
            float x = scheme != HL_QUANT_LINEAR8 ? fabs(c[i]) : c[i];
            lo = min(lo, x);
            hi = max(hi, x);
        }
    }
    if (t.count == 0) { lo = 0.0f; hi = 0.0f; }
    hl_row_quant q;
    q.a = lo;
    q.b = hi;
    rq[v] = q;
    global ushort *bc = block_counts + (size_t)v * nblocks;
    global uchar *out = entries + (size_t)v * ncoef * 2;
    for (uint b = 0; b < nblocks; b++) bc[b] = 0;
    uint n = 0;
    ties = 0;
    for (uint i = 0; i < ncoef; i++) {
        uint k = hl_key(c[i]);
        if (k > t.thresh || (k == t.thresh && k != 0 && ties++ < t.ties)) {
            uint code = hl_quant(scheme, c[i], lo, hi, hl_dither_key(first + v, i));
            out[2 * n] = (uchar)(i & 255u);
            out[2 * n + 1] = (uchar)code;
            bc[i >> 8]++;
            n++;
        }
    }
    nnz[v] = n;
}
