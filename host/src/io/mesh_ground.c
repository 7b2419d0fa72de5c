/* mesh_ground.c - the ground plane added under a mesh
 * (hl_mesh_add_ground) and the mesh's bounding-box diagonal
 * (hl_mesh_query_diagonal).
 *
 * Depends on: mesh_ops.h (albedo rule and default), hl_internal.h
 * (errors, allocation), libc, libm.
 */
#include <math.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#include <stdlib.h>
#include <string.h>

#include "mesh_ops.h"

/* Built-in defaults (see the comments in haarlight.h). */
#define HL_GROUND_RESOLUTION 96u
#define HL_GROUND_MARGIN 0.75f
/* The default ground holds the shadow of the object's top under a light
 * this high above the horizon, whatever the light's azimuth. */
#define HL_GROUND_SUN_DEG 15.0
/* Beyond the uniform square (the footprint plus HL_GROUND_MARGIN x its
 * extent on every side), cells grow by this ratio from one to the next:
 * the shadows that fall there are long ones, of a low light, whose
 * penumbrae widen with their distance from the object. */
#define HL_GROUND_GROWTH 1.25
/* A ground finer than this would be a precompute of days; it is surely a
 * mistake, and bounding it keeps every count inside uint32. */
#define HL_GROUND_MAX_RESOLUTION 4096u
/* The widest margin, in extents of the footprint: a thin pole's default
 * ground would otherwise be as wide as its height is to its width. */
#define HL_GROUND_MAX_MARGIN 64.0f

hl_result hl_mesh_add_ground(hl_context *ctx, hl_mesh *mesh, const hl_ground_desc *desc)
{
    hl_ground_desc d = {0};
    if (desc) d = *desc;
    if (!mesh || mesh->object_vertex_count == 0 || !mesh->positions)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: the mesh is empty");
    if (mesh->object_vertex_count != mesh->vertex_count)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: the mesh already has one");
    uint32_t res = d.resolution ? d.resolution : HL_GROUND_RESOLUTION;
    if (res > HL_GROUND_MAX_RESOLUTION)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: resolution %u exceeds %u", res,
                       HL_GROUND_MAX_RESOLUTION);
    if (d.margin != 0.0f && (!(d.margin > 0.0f) || !isfinite(d.margin)))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: margin %g must be positive", (double)d.margin);
    if (d.margin > HL_GROUND_MAX_MARGIN)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: margin %g exceeds %g x the object's extent",
                       (double)d.margin, (double)HL_GROUND_MAX_MARGIN);
    uint32_t nv = mesh->vertex_count, nt = mesh->triangle_count;

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double mean[3] = {0, 0, 0};
    for (size_t v = 0; v < nv; v++)
        for (int k = 0; k < 3; k++) {
            double p = mesh->positions[3 * v + k];
            if (p < lo[k]) lo[k] = p;
            if (p > hi[k]) hi[k] = p;
            mean[k] += mesh->albedo ? mesh->albedo[3 * v + k] : HL_DEFAULT_ALBEDO;
        }
    float albedo[3];
    /* a neutral grey: a coloured or textured object does not tint its
       ground; a grey object's ground is its own grey, to the bit */
    const float grey = (float)((mean[0] + mean[1] + mean[2]) / (3.0 * (double)nv));
    float fallback[3] = {grey, grey, grey};
    if (d.albedo[0] == 0.0f && d.albedo[1] == 0.0f && d.albedo[2] == 0.0f) {
        memcpy(albedo, fallback, sizeof albedo);
    } else {
        hl_result r = hl_mesh_resolve_albedo_(ctx, "ground plane", d.albedo, 0.0f, albedo);
        if (r != HL_OK) return r;
    }

    /* A square centred on the footprint, uniform over the footprint plus
     * margin x its larger extent on every side (at most HL_GROUND_MARGIN),
     * and graded beyond that out to the whole margin: by default the
     * distance at which the object's top casts its shadow under a light
     * HL_GROUND_SUN_DEG above the horizon. */
    double ext = fmax(hi[0] - lo[0], hi[2] - lo[2]);
    if (!(ext > 0.0)) ext = fmax(hi[1] - lo[1], 1.0);
    const double height = hi[1] - lo[1];
    double margin = d.margin != 0.0f ? (double)d.margin
                                     : fmax(HL_GROUND_MARGIN, height / tan(HL_GROUND_SUN_DEG * M_PI / 180.0) / ext);
    if (margin > HL_GROUND_MAX_MARGIN) margin = HL_GROUND_MAX_MARGIN; /* a needle: its shadow is a line */
    const double inner = fmin(margin, (double)HL_GROUND_MARGIN);
    double side = ext * (1.0 + 2.0 * inner);
    double cx = 0.5 * (lo[0] + hi[0]), cz = 0.5 * (lo[2] + hi[2]);
    double x0 = cx - 0.5 * side, z0 = cz - 0.5 * side, step = side / res;
    float y = (float)lo[1];
    /* the graded steps out to (margin - inner) x ext on each side,
       scaled so that the last lands on it exactly */
    const double out = (margin - inner) * ext;
    uint32_t k = 0;
    double grow = 0.0;
    for (double c = step * HL_GROUND_GROWTH; out > 0.0 && grow < out; c *= HL_GROUND_GROWTH) grow += c, k++;
    const uint32_t n = res + 1 + 2 * k; /* coordinates along each axis */
    double *coord = hl_malloc(ctx, 2 * (size_t)n * sizeof(double), "ground coordinates");
    if (!coord) return HL_ERR_OUT_OF_MEMORY;
    double *cxs = coord, *czs = coord + n;
    for (uint32_t i = 0; i <= res; i++) { /* the last lands exactly on the far edge */
        cxs[k + i] = i == res ? x0 + side : x0 + step * i;
        czs[k + i] = i == res ? z0 + side : z0 + step * i;
    }
    double c = step * HL_GROUND_GROWTH * (k ? out / grow : 0.0), at = 0.0;
    for (uint32_t i = 1; i <= k; i++, c *= HL_GROUND_GROWTH) {
        at = i == k ? out : at + c;
        cxs[k - i] = x0 - at;
        cxs[k + res + i] = x0 + side + at;
        czs[k - i] = z0 - at;
        czs[k + res + i] = z0 + side + at;
    }
    const uint32_t q = n - 1; /* quads along each axis */
    uint64_t gv = (uint64_t)n * n, gt = 2 * (uint64_t)q * q;
    if (nv + gv > UINT32_MAX || nt + gt > UINT32_MAX) {
        free(coord);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: %u x %u grid makes the mesh too large", q, q);
    }

    size_t tv = (size_t)(nv + gv), tt = (size_t)(nt + gt);
    float *pos = hl_malloc(ctx, tv * 3 * sizeof(float), "ground positions");
    float *nrm = hl_malloc(ctx, tv * 3 * sizeof(float), "ground normals");
    float *alb = hl_malloc(ctx, tv * 3 * sizeof(float), "ground albedo");
    uint32_t *idx = hl_malloc(ctx, tt * 3 * sizeof(uint32_t), "ground indices");
    if (!pos || !nrm || !alb || !idx) {
        free(pos);
        free(nrm);
        free(alb);
        free(idx);
        free(coord);
        return HL_ERR_OUT_OF_MEMORY;
    }
    memcpy(pos, mesh->positions, (size_t)nv * 3 * sizeof(float));
    memcpy(nrm, mesh->normals, (size_t)nv * 3 * sizeof(float));
    if (mesh->albedo) memcpy(alb, mesh->albedo, (size_t)nv * 3 * sizeof(float));
    else for (size_t i = 0; i < (size_t)nv * 3; i++) alb[i] = HL_DEFAULT_ALBEDO;
    memcpy(idx, mesh->indices, (size_t)nt * 3 * sizeof(uint32_t));

    for (uint32_t j = 0; j < n; j++)
        for (uint32_t i = 0; i < n; i++) {
            size_t v = nv + (size_t)j * n + i;
            pos[3 * v] = (float)cxs[i];
            pos[3 * v + 1] = y;
            pos[3 * v + 2] = (float)czs[j];
            nrm[3 * v] = 0.0f;
            nrm[3 * v + 1] = 1.0f;
            nrm[3 * v + 2] = 0.0f;
            memcpy(alb + 3 * v, albedo, sizeof albedo);
        }
    free(coord);
    /* (a, c, b) with a=(i,j), b=(i+1,j), c=(i,j+1): (c-a) x (b-a) = +Z x +X
     * = +Y, counter-clockwise seen from above. */
    size_t t = nt;
    for (uint32_t j = 0; j < q; j++)
        for (uint32_t i = 0; i < q; i++) {
            uint32_t a = nv + j * n + i, b = a + 1, cc = a + n, e = cc + 1;
            uint32_t *f = idx + 3 * t;
            f[0] = a; f[1] = cc; f[2] = b;
            f[3] = b; f[4] = cc; f[5] = e;
            t += 2;
        }

    free(mesh->positions);
    free(mesh->normals);
    free(mesh->albedo);
    free(mesh->indices);
    mesh->positions = pos;
    mesh->normals = nrm;
    mesh->albedo = alb;
    mesh->indices = idx;
    mesh->object_vertex_count = nv;
    mesh->vertex_count = (uint32_t)tv;
    mesh->triangle_count = (uint32_t)tt;
    return HL_OK;
}

float hl_mesh_query_diagonal(const hl_mesh *mesh)
{
    if (!mesh || !mesh->positions || mesh->vertex_count == 0) return 0.0f;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < mesh->vertex_count; v++)
        for (int k = 0; k < 3; k++) {
            double p = mesh->positions[3 * v + k];
            if (p < lo[k]) lo[k] = p;
            if (p > hi[k]) hi[k] = p;
        }
    double d2 = 0.0;
    for (int k = 0; k < 3; k++) d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    return (float)sqrt(d2);
}

