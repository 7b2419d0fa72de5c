/* haar_ref.c - twin of kernels/haar.cl: each level into a fresh array. */
#include <stdlib.h>
#include <string.h>

#include "ref.h"

void hl_ref_haar(const hl_geom *g, float *T, float *coef)
{
    const uint32_t N = g->N;
    float *avg = malloc((size_t)N * N / 4 * sizeof(float));
    if (!avg) abort(); /* N^2/4 floats: at most 64 KiB */
    for (int map = 0; map < 2; map++) {
        float *x = T + (size_t)map * N * N; /* current averages, row stride N */
        for (uint32_t s = N; s >= 2; s /= 2) {
            uint32_t h = s / 2;
            for (uint32_t i = 0; i < h; i++)
                for (uint32_t j = 0; j < h; j++) {
                    float a = x[(2 * i) * N + 2 * j], b = x[(2 * i) * N + 2 * j + 1];
                    float c = x[(2 * i + 1) * N + 2 * j], d = x[(2 * i + 1) * N + 2 * j + 1];
                    avg[i * h + j] = (a + b + c + d) * 0.5f;
                    coef[hl_geom_slot(g, map, i, j + h)] = (a - b + c - d) * 0.5f;
                    coef[hl_geom_slot(g, map, i + h, j)] = (a + b - c - d) * 0.5f;
                    coef[hl_geom_slot(g, map, i + h, j + h)] = (a - b - c + d) * 0.5f;
                }
            for (uint32_t i = 0; i < h; i++) memcpy(x + i * N, avg + i * h, h * sizeof(float));
        }
        coef[hl_geom_slot(g, map, 0, 0)] = x[0];
    }
    free(avg);
}
