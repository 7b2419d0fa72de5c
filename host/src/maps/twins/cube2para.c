/* cube2para.c - twin of kernels/maps/cube2para.cl. */
#include "twins.h"

void hl_ref_cube2para(const hl_geom *g, const uint8_t *vis, float scale,
                      const float n[3], float *T)
{
    for (uint32_t j = 0; j < g->ncoef; j++) {
        float acc = 0.0f;
        for (uint32_t e = g->c2p_start[j]; e < g->c2p_start[j + 1]; e++) {
            const hl_c2p_entry *c = &g->c2p[e];
            uint32_t v = vis[c->index];
            if (!v) continue;
            float w = n[0] * c->mx + n[1] * c->my + n[2] * c->mz;
            if (w > 0.0f) acc += (float)v * w;
        }
        T[j] = acc * scale;
    }
}
