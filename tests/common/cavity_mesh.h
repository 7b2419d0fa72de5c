/* cavity_mesh.h - a spherical cavity for the interreflection tests
 * (tests/precompute/test_bounce.c, tests/tools/test_bench_ref.c): a unit
 * sphere without its cap theta < theta0 about +Y, as rings from theta0 to
 * the south pole, normals inward. Seen from inside, every point sees the
 * opening with the same form factor f = (1 - cos theta0) / 2, which is
 * what the closed forms of the tests rely on.
 *
 * Depends on: haarlight.h (hl_mesh_create).
 */
#ifndef HL_TEST_CAVITY_MESH_H
#define HL_TEST_CAVITY_MESH_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "haarlight.h"

/* The sphere's rings and segments: fine enough that its polygons are
 * within 0.1% of the sphere's area, coarse enough for a quick test. */
#define HL_CAVITY_RINGS 24u
#define HL_CAVITY_SEGS 48u
#define HL_CAVITY_VERTICES (HL_CAVITY_RINGS * HL_CAVITY_SEGS + 1u)

/* The cavity with albedo rho (R, G, B) at every vertex; NULL on failure
 * (the reason printed). */
static inline hl_mesh *hl_test_cavity(hl_context *ctx, double theta0, const float rho[3])
{
    const uint32_t R = HL_CAVITY_RINGS, S = HL_CAVITY_SEGS, nv = HL_CAVITY_VERTICES, nt = 2 * (R - 1) * S + S;
    const double pi = 3.14159265358979323846;
    float *p = malloc((size_t)nv * 12), *n = malloc((size_t)nv * 12), *a = malloc((size_t)nv * 12);
    uint32_t *ix = malloc((size_t)nt * 12), t = 0;
    hl_mesh *m = NULL;
    if (p && n && a && ix) {
        for (uint32_t j = 0; j < R; j++)
            for (uint32_t s = 0; s < S; s++) {
                const double th = theta0 + (pi - theta0) * j / R, ph = 2.0 * pi * s / S;
                float *q = p + 3 * (j * S + s);
                q[0] = (float)(sin(th) * cos(ph)), q[1] = (float)cos(th), q[2] = (float)(sin(th) * sin(ph));
            }
        p[3 * (nv - 1)] = 0.0f, p[3 * (nv - 1) + 1] = -1.0f, p[3 * (nv - 1) + 2] = 0.0f;
        for (uint32_t v = 0; v < nv; v++)
            for (int c = 0; c < 3; c++) n[3 * v + c] = -p[3 * v + c], a[3 * v + c] = rho[c];
        for (uint32_t j = 0; j + 1 < R; j++)
            for (uint32_t s = 0; s < S; s++) {
                const uint32_t a0 = j * S + s, a1 = j * S + (s + 1) % S, b0 = a0 + S, b1 = a1 + S;
                ix[3 * t] = a0, ix[3 * t + 1] = a1, ix[3 * t + 2] = b0, t++;
                ix[3 * t] = a1, ix[3 * t + 1] = b1, ix[3 * t + 2] = b0, t++;
            }
        for (uint32_t s = 0; s < S; s++) {
            const uint32_t a0 = (R - 1) * S + s, a1 = (R - 1) * S + (s + 1) % S;
            ix[3 * t] = a0, ix[3 * t + 1] = a1, ix[3 * t + 2] = nv - 1, t++;
        }
        if (hl_mesh_create(ctx, nv, p, n, a, nt, ix, &m) != HL_OK)
            fprintf(stderr, "cavity: %s\n", hl_context_last_error(ctx));
    }
    free(p);
    free(n);
    free(a);
    free(ix);
    return m;
}

#endif
