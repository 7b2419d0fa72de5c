/* haar.c - twin of kernels/maps/haar.cl, level by level in place. */
#include "twins.h"

void hl_ref_haar(const hl_geom *g, float *T, float *coef)
{
    const uint32_t N = g->N;
    for (int map = 0; map < 2; map++) {
        float *x = T + (size_t)map * N * N; /* current averages, row stride N */
        for (uint32_t s = N; s >= 2; s /= 2) {
            uint32_t h = s / 2;
            /* The average of block (i, j) goes to x[i][j], in place: that
             * element is read only by block (i / 2, j / 2), which comes no
             * later in this row-major walk and reads its four inputs before
             * writing, so every block still reads this level's values. */
            for (uint32_t i = 0; i < h; i++)
                for (uint32_t j = 0; j < h; j++) {
                    float a = x[(2 * i) * N + 2 * j], b = x[(2 * i) * N + 2 * j + 1];
                    float c = x[(2 * i + 1) * N + 2 * j], d = x[(2 * i + 1) * N + 2 * j + 1];
                    coef[hl_geom_slot(g, map, i, j + h)] = (a - b + c - d) * 0.5f;
                    coef[hl_geom_slot(g, map, i + h, j)] = (a + b - c - d) * 0.5f;
                    coef[hl_geom_slot(g, map, i + h, j + h)] = (a - b - c + d) * 0.5f;
                    x[i * N + j] = (a + b + c + d) * 0.5f;
                }
        }
        coef[hl_geom_slot(g, map, 0, 0)] = x[0];
    }
}
