/* exposure.c - the automatic exposure shared by `haarlight relight` and
 * the viewer, so that both tone-map a scene alike.
 *
 * Depends on: hl_luminance (hl_shared.h), libc, libm.
 */
#include <math.h>
#include <stdlib.h>

#include "hl_internal.h"

/* Where the 90th percentile of the object's vertex luminance lands: sunlit
 * surfaces stay just below white and the sky's soft shadows keep their
 * gradations. The object's vertices only (those before the ground, or all
 * where there is none): a ground that far outnumbers them (16,129 of
 * 17,968 vertices on the low-resolution bunny) would otherwise set the
 * exposure alone, and under a bright lamp near the object, or a ground in
 * shadow, clip the lit object to white. */
#define HL_AUTO_EXPOSURE_TARGET 0.8f
#define HL_EXPOSURE_LIMIT 64.0f

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

float hl_exposure_auto(const hl_mesh *mesh, const float *vertex_rgb)
{
    if (!mesh || !vertex_rgb || mesh->vertex_count == 0) return 0.0f;
    /* the object's vertices: those before the ground */
    uint32_t n = mesh->object_vertex_count > 0 && mesh->object_vertex_count < mesh->vertex_count ? mesh->object_vertex_count
                                                                                                    : mesh->vertex_count;
    float *y = malloc((size_t)n * sizeof *y);
    if (!y) return 0.0f;
    for (uint32_t v = 0; v < n; v++)
        y[v] = hl_luminance(vertex_rgb[3 * (size_t)v], vertex_rgb[3 * (size_t)v + 1], vertex_rgb[3 * (size_t)v + 2]);
    qsort(y, n, sizeof *y, cmp_float);
    float p90 = y[(size_t)n * 9 / 10];
    free(y);
    if (!(p90 > 0.0f) || !isfinite(p90)) return 0.0f;
    float ev = log2f(HL_AUTO_EXPOSURE_TARGET / p90);
    return ev < -HL_EXPOSURE_LIMIT ? -HL_EXPOSURE_LIMIT : ev > HL_EXPOSURE_LIMIT ? HL_EXPOSURE_LIMIT : ev;
}
