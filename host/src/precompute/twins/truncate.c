/* truncate.c - twin of kernels/precompute/truncate.cl: sort, then walk. */
#include <stdlib.h>

#include "twins.h"

static int by_key_desc(const void *pa, const void *pb)
{
    const hl_ref_key *a = pa, *b = pb;
    if (a->key != b->key) return a->key > b->key ? -1 : 1;
    return a->slot < b->slot ? -1 : (a->slot > b->slot);
}

hl_trunc_result hl_ref_truncate(const hl_geom *g, const float *coef, hl_trunc_params p, hl_ref_key *scratch)
{
    hl_trunc_result r = {0xffffffffu, 0u, 0u, 0u};
    hl_ref_key *k = scratch;
    uint32_t nnz = 0, maxkey = 0;
    for (uint32_t i = 0; i < g->ncoef; i++) {
        uint32_t key = hl_key(coef[i]);
        if (!key) continue;
        k[nnz].key = key;
        k[nnz].slot = i;
        nnz++;
        if (key > maxkey) maxkey = key;
    }
    qsort(k, nnz, sizeof *k, by_key_desc);
    uint32_t count = nnz;
    if (p.rule == HL_TRUNC_TOPK) {
        count = p.K < nnz ? p.K : nnz;
    } else if (p.rule == HL_TRUNC_ENERGY) {
        float scale = hl_energy_scale(maxkey);
        uint64_t total = 0, acc = 0;
        for (uint32_t i = 0; i < nnz; i++) total += hl_energy(coef[k[i].slot], scale);
        uint64_t target = total - hl_energy_drop(total, p.eps_q20);
        count = 0;
        while (acc < target && count < nnz) acc += hl_energy(coef[k[count++].slot], scale);
        if (p.K > 0 && count > p.K) count = p.K;
    }
    if (count > 0) {
        r.thresh = k[count - 1].key;
        for (uint32_t i = 0; i < count; i++) r.ties += k[i].key == r.thresh;
    }
    r.count = count;
    return r;
}
