/* capture_util.h - triangle soups for the tests of lighting captured from
 * surroundings: building them (emissive or dark triangles and quads), a
 * double-precision ray caster of this test's own, and an equirectangular
 * render of a soup from a point (the map the ordinary environment path
 * reads).
 * Depends on: hl_test.h, hl_internal.h (HL_PI), libm.
 */
#ifndef HL_TEST_CAPTURE_UTIL_H
#define HL_TEST_CAPTURE_UTIL_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "hl_internal.h"
#include "hl_test.h"

/* A growing triangle soup. */
typedef struct soup {
    float pos[9 * 512], em[3 * 512];
    uint32_t n;
} soup;

static inline void add_tri(soup *s, const double a[3], const double b[3], const double c[3], const float e[3])
{
    if (s->n >= 512) return;
    for (int k = 0; k < 3; k++) {
        s->pos[9 * s->n + k] = (float)a[k];
        s->pos[9 * s->n + 3 + k] = (float)b[k];
        s->pos[9 * s->n + 6 + k] = (float)c[k];
        s->em[3 * s->n + k] = e[k];
    }
    s->n++;
}

/* The square (parallelogram) centre +- u +- v, as two triangles. */
static inline void add_quad(soup *s, const double c[3], const double u[3], const double v[3], const float e[3])
{
    double p[4][3];
    for (int k = 0; k < 3; k++) {
        p[0][k] = c[k] - u[k] - v[k];
        p[1][k] = c[k] + u[k] - v[k];
        p[2][k] = c[k] + u[k] + v[k];
        p[3][k] = c[k] - u[k] + v[k];
    }
    add_tri(s, p[0], p[1], p[2], e);
    add_tri(s, p[0], p[2], p[3], e);
}

/* Nearest hit along unit direction d from the origin in double: this
 * test's own ray caster (index, or -1). */
static inline int cast(const soup *s, const float o[3], const double d[3])
{
    double best = INFINITY;
    int hit = -1;
    for (uint32_t i = 0; i < s->n; i++) {
        double p[3][3];
        for (int v = 0; v < 3; v++)
            for (int k = 0; k < 3; k++) p[v][k] = (double)s->pos[9 * i + 3 * v + k] - o[k];
        double e1[3], e2[3], n[3];
        for (int k = 0; k < 3; k++) { e1[k] = p[1][k] - p[0][k]; e2[k] = p[2][k] - p[0][k]; }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1]; n[1] = e1[2] * e2[0] - e1[0] * e2[2]; n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double dn = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
        if (dn == 0.0) continue;
        double t = (p[0][0] * n[0] + p[0][1] * n[1] + p[0][2] * n[2]) / dn;
        if (t <= 0.0 || t >= best) continue;
        /* the hit point inside all three edges (same side as the normal) */
        double x[3] = {t * d[0], t * d[1], t * d[2]};
        int in = 1;
        for (int v = 0; v < 3 && in; v++) {
            const double *a = p[v], *b = p[(v + 1) % 3];
            double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, ax[3] = {x[0] - a[0], x[1] - a[1], x[2] - a[2]};
            double cr[3] = {ab[1] * ax[2] - ab[2] * ax[1], ab[2] * ax[0] - ab[0] * ax[2], ab[0] * ax[1] - ab[1] * ax[0]};
            if (cr[0] * n[0] + cr[1] * n[1] + cr[2] * n[2] < 0.0) in = 0;
        }
        if (in) { best = t; hit = (int)i; }
    }
    return hit;
}

/* Sub-samples per pixel side of the equirectangular render. */
#define XC_SUB 3

/* Each pixel the mean radiance over its solid angle: sub-samples uniform
 * in longitude and cos(theta); misses see the constant sky. */
static inline float *render_equirect(const soup *s, const float o[3], uint32_t W, uint32_t H, const float sky[3])
{
    float *px = malloc((size_t)W * H * 12);
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            double acc[3] = {0, 0, 0};
            double c0 = cos(HL_PI * y / H), c1 = cos(HL_PI * (y + 1) / H);
            for (int a = 0; a < XC_SUB; a++)
                for (int b = 0; b < XC_SUB; b++) {
                    double ct = c0 + (c1 - c0) * (a + 0.5) / XC_SUB, st = sqrt(fmax(0.0, 1.0 - ct * ct));
                    double phi = 2.0 * HL_PI * ((x + (b + 0.5) / XC_SUB) / W - 0.5);
                    double d[3] = {st * cos(phi), ct, st * sin(phi)};
                    int h = cast(s, o, d);
                    for (int k = 0; k < 3; k++) acc[k] += h >= 0 ? s->em[3 * h + k] : sky[k];
                }
            for (int k = 0; k < 3; k++) px[3 * ((size_t)y * W + x) + k] = (float)(acc[k] / (XC_SUB * XC_SUB));
        }
    return px;
}

#endif
