/* haar.c - twin of kernels/maps/haar.cl, level by level in place. */
#include "twins.h"

void hl_ref_haar_square(float *x, float *o, const uint32_t *slot, uint32_t n)
{
    for (uint32_t s = n; s >= 2; s /= 2) {
        uint32_t h = s / 2;
        /* The average of block (i, j) goes to x[i][j], in place: that
         * element is read only by block (i / 2, j / 2), which comes no
         * later in this row-major walk and reads its four inputs before
         * writing, so every block still reads this level's values. */
        for (uint32_t i = 0; i < h; i++)
            for (uint32_t j = 0; j < h; j++) {
                float a = x[(2 * i) * n + 2 * j], b = x[(2 * i) * n + 2 * j + 1];
                float c = x[(2 * i + 1) * n + 2 * j], d = x[(2 * i + 1) * n + 2 * j + 1];
                const uint32_t k1 = i * n + j + h, k2 = (i + h) * n + j, k3 = (i + h) * n + j + h;
                o[slot ? slot[k1] : k1] = (a - b + c - d) * 0.5f;
                o[slot ? slot[k2] : k2] = (a + b - c - d) * 0.5f;
                o[slot ? slot[k3] : k3] = (a - b - c + d) * 0.5f;
                x[i * n + j] = (a + b + c + d) * 0.5f;
            }
    }
    o[slot ? slot[0] : 0] = x[0];
}

void hl_ref_haar(const hl_geom *g, float *T, float *coef)
{
    const size_t nn = (size_t)g->N * g->N;
    for (int map = 0; map < 2; map++) hl_ref_haar_square(T + map * nn, coef + map * nn, g->slot_of_mallat, g->N);
}
