/* select_ref.c - twin of kernels/select.cl: sorts the priorities. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ref.h"

typedef struct prio { uint32_t key, slot; } prio;

static int by_key_desc(const void *pa, const void *pb)
{
    const prio *a = pa, *b = pb;
    if (a->key != b->key) return a->key > b->key ? -1 : 1;
    return a->slot < b->slot ? -1 : (a->slot > b->slot);
}

hl_select_result hl_ref_select(const float *L, uint32_t n, const float *weight, hl_select_params p,
                               float *out, uint8_t *block_used, uint32_t *kept_bits, uint32_t nblocks)
{
    hl_select_result res = {0.0f, 0.0f, 0u, 0u, 0.0f, 0u, {0u, 0u}};
    prio *k = malloc((size_t)n * sizeof *k);
    uint8_t *keep = calloc(n, 1);
    if (!k || !keep) abort();
    uint32_t nnz = 0;
    float ymax = 0.0f;
    for (uint32_t i = 0; i < n; i++) {
        float y = hl_luminance(L[i], L[n + i], L[2 * n + i]);
        uint32_t key = hl_key(fabsf(y) * weight[i]);
        if (key) k[nnz++] = (prio){key, i};
        ymax = fmaxf(ymax, fabsf(y));
    }
    const float es = hl_light_energy_scale(ymax, &res.energy_exp);
    qsort(k, nnz, sizeof *k, by_key_desc);
    uint32_t m = p.M < nnz ? p.M : nnz;
    for (uint32_t i = 0; i < m; i++) keep[k[i].slot] = 1;
    memset(block_used, 0, nblocks);
    memset(kept_bits, 0, n / 32 * sizeof *kept_bits);
    for (uint32_t i = 0; i < n; i++) {
        float r = L[i], g = L[n + i], b = L[2 * n + i], y = hl_luminance(r, g, b) * es;
        res.energy_total += y * y;
        out[4 * i] = keep[i] ? r : 0.0f;
        out[4 * i + 1] = keep[i] ? g : 0.0f;
        out[4 * i + 2] = keep[i] ? b : 0.0f;
        out[4 * i + 3] = 0.0f;
        if (keep[i]) {
            res.energy_kept += y * y;
            res.kept++;
            if (i % HL_BLOCK) block_used[i / HL_BLOCK] = 1; /* detail slots only */
            kept_bits[i / 32] |= 1u << (i % 32);
        } else {
            res.energy_dropped += y * y;
        }
    }
    for (uint32_t b = 0; b < nblocks; b++) res.blocks_used += block_used[b];
    free(k);
    free(keep);
    return res;
}
