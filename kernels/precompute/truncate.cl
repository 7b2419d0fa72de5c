/* truncate.cl - nonlinear truncation of one transport row per work-item.
 * Exact radix select on the bit patterns of |T_i| (4 passes of 8 bits), so
 * no sort and no float summation order: energies are fixed-point integers.
 * Twin: host/src/precompute/twins/truncate.c (sorts instead).
 */
#pragma OPENCL FP_CONTRACT OFF

/* Threshold key and ties for keeping the `need` largest keys (need >= 1). */
static void select_top(global const float *c, uint n, uint need, hl_trunc_result *r)
{
    uint hist[256];
    uint prefix = 0, mask = 0;
    for (int shift = 24; shift >= 0; shift -= 8) {
        for (int b = 0; b < 256; b++) hist[b] = 0;
        for (uint i = 0; i < n; i++) {
            uint k = hl_key(c[i]);
            if (k && (k & mask) == prefix) hist[(k >> shift) & 255u]++;
        }
        uint b = hl_radix_bin(hist, &need);
        prefix |= b << shift;
        mask |= 255u << shift;
    }
    r->thresh = prefix;
    r->ties = need;
}

/* Fewest largest coefficients holding all but eps of the row's energy. The
 * first histogram sees every coefficient, so it gives the total too. The
 * walk ends on the key of the last one kept, so it yields the threshold and
 * ties of that set as well. */
static uint energy_select(global const float *c, uint n, float scale, uint eps_q20, hl_trunc_result *r)
{
    ulong target = 0;
    uint hist[256];
    ulong ehist[256];
    uint prefix = 0, mask = 0, count = 0;
    ulong acc = 0;
    for (int shift = 24; shift >= 0; shift -= 8) {
        for (int b = 0; b < 256; b++) { hist[b] = 0; ehist[b] = 0; }
        for (uint i = 0; i < n; i++) {
            uint k = hl_key(c[i]);
            if (k && (k & mask) == prefix) {
                uint b = (k >> shift) & 255u;
                hist[b]++;
                ehist[b] += hl_energy(c[i], scale);
            }
        }
        if (shift == 24) {
            ulong total = 0;
            for (int b = 0; b < 256; b++) total += ehist[b];
            target = total - hl_energy_drop(total, eps_q20);
            if (!target) return 0;
        }
        int b = 255;
        for (; b > 0; b--) {
            if (acc + ehist[b] >= target) break;
            acc += ehist[b];
            count += hist[b];
        }
        prefix |= (uint)b << shift;
        mask |= 255u << shift;
    }
    /* the last bin is one key: equal energies, take as many as needed
       (acc < target here, so at least one) */
    ulong e = hl_energy(as_float(prefix), scale);
    uint need = e ? (uint)((target - acc + e - 1) / e) : 0u;
    r->thresh = prefix;
    r->ties = need;
    return count + need;
}

kernel void hl_truncate(global const float *coef, uint ncoef, hl_trunc_params p,
                        global hl_trunc_result *out, uint nrows)
{
    uint v = get_global_id(0);
    if (v >= nrows) return;
    global const float *c = coef + (size_t)v * ncoef;
    uint nnz = 0, maxkey = 0, minkey = 0xffffffffu, nmin = 0;
    for (uint i = 0; i < ncoef; i++) {
        uint k = hl_key(c[i]);
        if (!k) continue;
        nnz++;
        maxkey = max(maxkey, k);
        if (k < minkey) { minkey = k; nmin = 0; }
        nmin += k == minkey;
    }
    hl_trunc_result r = {0xffffffffu, 0u, 0u, 0u};
    uint count = nnz;
    if (p.rule == HL_TRUNC_TOPK) count = min(p.K, nnz);
    if (p.rule == HL_TRUNC_ENERGY) {
        if (nnz) r.count = energy_select(c, ncoef, hl_energy_scale(maxkey), p.eps_q20, &r);
        if (p.K > 0 && r.count > p.K) {
            r.count = p.K;
            select_top(c, ncoef, p.K, &r);
        }
    } else if (count == nnz) {
        /* everything non-zero: the threshold is the smallest key */
        r.count = nnz;
        if (nnz) { r.thresh = minkey; r.ties = nmin; }
    } else {
        r.count = count;
        if (count) select_top(c, ncoef, count, &r);
    }
    out[v] = r;
}
