/* env_layout.c - light-probe layouts (angular maps and cube crosses)
 * resampled onto the equirectangular grid every other stage reads.
 *
 * Orientation (docs/CONVENTIONS.md, "Map layouts"): every layout's centre
 * looks where the equirectangular map's centre looks, +X, with +Y up and
 * +Z to the right, as a light probe converted to a latitude-longitude
 * panorama keeps its front at the panorama's centre.
 * - Angular map (Debevec's light probes): a disc; the direction at angle a
 *   from +X lies at radius a / pi of the disc, towards its projection on
 *   the image plane (right = +Z, up = +Y); the rim is -X.
 * - Cube crosses: faces of side F; the horizontal cross (4F x 3F) holds
 *   -Z, +X, +Z, -X in its middle row, +Y above +X and -Y below it; the
 *   vertical cross (3F x 4F) holds -Z, +X, +Z in its second row, +Y above
 *   +X, and -Y then -X (upside down) below it. Every face continues its
 *   neighbours in the image across their shared edges.
 * Each equirectangular pixel is the average over its own solid angle
 * (SUB x SUB samples weighted by sin(theta)) of the source's nearest
 * pixels, so small bright sources keep their energy to the accuracy of
 * the sampling. Depends on: hl_internal.h, libm.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "env_layout.h"
#include "hl_internal.h"

/* Samples per side of an output pixel: enough that a source pixel about
 * the output pixel's size is caught with its share of the area to a few
 * percent (hl.env_layout measures the energy). */
#define SUB 4

typedef struct face {
    int col, row;          /* in units of F */
    float f[3], r[3], u[3]; /* centre, right and up directions */
} face;

/* Horizontal cross: -Z +X +Z -X in the middle row, +Y and -Y above and
 * below +X. */
static const face CROSS_H[6] = {
    {1, 1, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}},   {0, 1, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}},
    {2, 1, {0, 0, 1}, {-1, 0, 0}, {0, 1, 0}},  {3, 1, {-1, 0, 0}, {0, 0, -1}, {0, 1, 0}},
    {1, 0, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}},  {1, 2, {0, -1, 0}, {0, 0, 1}, {1, 0, 0}},
};
/* Vertical cross: as the horizontal one, but -X hangs below -Y, upside
 * down so that its edge continues -Y's. */
static const face CROSS_V[6] = {
    {1, 1, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}},   {0, 1, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}},
    {2, 1, {0, 0, 1}, {-1, 0, 0}, {0, 1, 0}},  {1, 3, {-1, 0, 0}, {0, 0, 1}, {0, -1, 0}},
    {1, 0, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}},  {1, 2, {0, -1, 0}, {0, 0, 1}, {1, 0, 0}},
};

static float dot3(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static uint32_t clampi(double x, uint32_t n)
{
    if (!(x >= 0.0)) return 0;
    const double m = floor(x);
    return m >= (double)n ? n - 1 : (uint32_t)m;
}

/* The source pixel a direction w (unit) falls in. */
static size_t source_pixel(hl_env_layout layout, uint32_t w, uint32_t h, const float d[3])
{
    if (layout == HL_LAYOUT_ANGULAR) {
        /* angle from +X, and the direction's projection (right +Z, up +Y) */
        const double a = acos(fmax(-1.0, fmin(1.0, (double)d[0]))), s = hypot((double)d[2], (double)d[1]);
        const double rad = a / HL_PI, x = s > 0.0 ? d[2] / s * rad : 0.0, y = s > 0.0 ? d[1] / s * rad : 0.0;
        return (size_t)clampi((1.0 - y) * 0.5 * h, h) * w + clampi((x + 1.0) * 0.5 * w, w);
    }
    const face *faces = layout == HL_LAYOUT_CROSS_H ? CROSS_H : CROSS_V;
    const uint32_t F = layout == HL_LAYOUT_CROSS_H ? w / 4 : w / 3;
    int best = 0;
    float most = -2.0f;
    for (int i = 0; i < 6; i++) {
        const float c = dot3(d, faces[i].f);
        if (c > most) { most = c; best = i; }
    }
    const face *fc = &faces[best];
    const double s = dot3(d, fc->r) / most, t = dot3(d, fc->u) / most;
    const uint32_t px = clampi((s + 1.0) * 0.5 * F, F), py = clampi((1.0 - t) * 0.5 * F, F);
    return ((size_t)fc->row * F + py) * w + (size_t)fc->col * F + px;
}

/* The smallest light probes taken: an angular map of fewer pixels, or a
 * cross of smaller faces, holds no more than a handful of directions and
 * is far likelier a mistake than a map. */
#define HL_MIN_PROBE_SIDE 8u
#define HL_MIN_CROSS_FACE 2u

hl_env_layout hl_env_layout_of_size_(uint32_t w, uint32_t h)
{
    if (w == 2 * h) return HL_LAYOUT_EQUIRECT;
    if (w == h && w >= HL_MIN_PROBE_SIDE) return HL_LAYOUT_ANGULAR;
    if (w % 4 == 0 && 3 * w == 4 * h && w / 4 >= HL_MIN_CROSS_FACE) return HL_LAYOUT_CROSS_H;
    if (w % 3 == 0 && 4 * w == 3 * h && w / 3 >= HL_MIN_CROSS_FACE) return HL_LAYOUT_CROSS_V;
    return HL_LAYOUT_AUTO;
}

const char *hl_env_layout_name_(hl_env_layout layout)
{
    switch (layout) {
    case HL_LAYOUT_EQUIRECT: return "equirectangular (2:1)";
    case HL_LAYOUT_ANGULAR: return "angular map (1:1, at least 8 x 8)";
    case HL_LAYOUT_CROSS_H: return "horizontal cross (4:3, faces of at least 2 pixels)";
    case HL_LAYOUT_CROSS_V: return "vertical cross (3:4, faces of at least 2 pixels)";
    default: return "unknown";
    }
}

hl_result hl_env_resample_layout_(hl_context *ctx, const char *path, hl_env_layout layout, uint32_t w, uint32_t h,
                                  const float *src, uint32_t *ow, uint32_t *oh, float **out)
{
    if (hl_env_layout_of_size_(w, h) != layout)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: %u x %u pixels is not the size of a%s %s", path, w, h,
                       layout == HL_LAYOUT_ANGULAR ? "n" : "", hl_env_layout_name_(layout));
    /* the output keeps about the source's resolution: 4 faces or the
       disc's diameter around the equator */
    const uint32_t H = layout == HL_LAYOUT_ANGULAR ? h : (layout == HL_LAYOUT_CROSS_H ? 2 * (w / 4) : 2 * (w / 3));
    const uint32_t W = 2 * H;
    float *rgb = hl_malloc(ctx, (size_t)W * H * 3 * sizeof *rgb, "resampled environment");
    if (!rgb) return HL_ERR_OUT_OF_MEMORY;
    /* the samples' longitudes are the same in every row: their sines and
       cosines once, not once a pixel */
    double *cs = hl_malloc(ctx, (size_t)W * SUB * 2 * sizeof *cs, "resampling table");
    if (!cs) {
        free(rgb);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t k = 0; k < W * SUB; k++) {
        const double phi = 2.0 * HL_PI * ((k + 0.5) / ((double)W * SUB) - 0.5);
        cs[2 * k] = cos(phi);
        cs[2 * k + 1] = sin(phi);
    }
    for (uint32_t j = 0; j < H; j++) {
        double st[SUB], ct[SUB];
        for (int b = 0; b < SUB; b++) {
            const double theta = HL_PI * (j + (b + 0.5) / SUB) / H;
            st[b] = sin(theta);
            ct[b] = cos(theta);
        }
        for (uint32_t i = 0; i < W; i++) {
            double acc[3] = {0, 0, 0}, wsum = 0.0;
            for (int b = 0; b < SUB; b++)
                for (int a = 0; a < SUB; a++) {
                    const double *c = cs + 2 * ((size_t)i * SUB + (size_t)a);
                    const float d[3] = {(float)(st[b] * c[0]), (float)ct[b], (float)(st[b] * c[1])};
                    const float *p = src + 3 * source_pixel(layout, w, h, d);
                    for (int k = 0; k < 3; k++) acc[k] += st[b] * p[k];
                    wsum += st[b];
                }
            for (int k = 0; k < 3; k++) rgb[3 * ((size_t)j * W + i) + (size_t)k] = (float)(acc[k] / wsum);
        }
    }
    free(cs);
    *ow = W;
    *oh = H;
    *out = rgb;
    return HL_OK;
}
