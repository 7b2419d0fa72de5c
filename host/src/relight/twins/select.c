/* select.c - twin of kernels/relight/select.cl and select_group.cl: sorts
 * the priorities; sums the energies by chunks and a tree, as both do
 * (hl_select_chunk, hl_select_fold). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "twins.h"

static int by_key_desc(const void *pa, const void *pb)
{
    const hl_ref_key *a = pa, *b = pb;
    if (a->key != b->key) return a->key > b->key ? -1 : 1;
    return a->slot < b->slot ? -1 : (a->slot > b->slot);
}

hl_select_result hl_ref_select(const float *L, uint32_t n, const float *weight, hl_select_params p,
                               float *out, uint8_t *block_used, uint32_t *kept_bits, uint32_t nblocks,
                               hl_ref_key *scratch)
{
    hl_select_result res = {0.0f, 0.0f, 0u, 0u, 0.0f, 0u, {0u, 0u}};
    hl_ref_key *k = scratch;
    uint32_t nnz = 0;
    float ymax = 0.0f;
    for (uint32_t i = 0; i < n; i++) {
        float y = hl_luminance(L[i], L[n + i], L[2 * n + i]);
        uint32_t key = hl_key(fabsf(y) * weight[i]);
        if (key) k[nnz++] = (hl_ref_key){key, i};
        ymax = fmaxf(ymax, fabsf(y));
    }
    const float es = hl_light_energy_scale(ymax, &res.energy_exp);
    qsort(k, nnz, sizeof *k, by_key_desc);
    uint32_t m = p.M < nnz ? p.M : nnz;
    memset(block_used, 0, nblocks);
    memset(kept_bits, 0, n / 32 * sizeof *kept_bits);
    for (uint32_t i = 0; i < m; i++) kept_bits[k[i].slot / 32] |= 1u << (k[i].slot % 32);
    float et[HL_SELECT_LANES] = {0}, ek[HL_SELECT_LANES] = {0}, ed[HL_SELECT_LANES] = {0};
    const uint32_t chunk = hl_select_chunk(n);
    for (uint32_t i = 0; i < n; i++) {
        float r = L[i], g = L[n + i], b = L[2 * n + i], y = hl_luminance(r, g, b) * es;
        uint32_t keep = (kept_bits[i / 32] >> (i % 32)) & 1u;
        const uint32_t c = i / chunk;
        et[c] += y * y;
        out[4 * i] = keep ? r : 0.0f;
        out[4 * i + 1] = keep ? g : 0.0f;
        out[4 * i + 2] = keep ? b : 0.0f;
        out[4 * i + 3] = 0.0f;
        if (keep) {
            ek[c] += y * y;
            res.kept++;
            if (i % HL_BLOCK) block_used[i / HL_BLOCK] = 1; /* detail slots only */
        } else {
            ed[c] += y * y;
        }
    }
    hl_select_fold(et);
    hl_select_fold(ek);
    hl_select_fold(ed);
    res.energy_total = et[0];
    res.energy_kept = ek[0];
    res.energy_dropped = ed[0];
    for (uint32_t b = 0; b < nblocks; b++) res.blocks_used += block_used[b];
    return res;
}
