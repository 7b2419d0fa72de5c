/* mesh_ground.c - the ground plane added under a mesh
 * (hl_mesh_add_ground) and the mesh's bounding-box diagonal
 * (hl_mesh_query_diagonal).
 *
 * Depends on: mesh_ops.h (albedo rule and default), hl_internal.h
 * (errors, allocation), libc, libm.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_ops.h"

/* Built-in defaults (see the comments in haarlight.h). */
#define HL_GROUND_RESOLUTION 96u
#define HL_GROUND_MARGIN 0.75f
/* A ground finer than this would be a precompute of days; it is surely a
 * mistake, and bounding it keeps every count inside uint32. */
#define HL_GROUND_MAX_RESOLUTION 4096u

hl_result hl_mesh_add_ground(hl_context *ctx, hl_mesh *mesh, const hl_ground_desc *desc)
{
    hl_ground_desc d = {0};
    if (desc) d = *desc;
    if (!mesh || mesh->object_vertex_count == 0 || !mesh->positions)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: the mesh is empty");
    if (mesh->object_vertex_count != mesh->vertex_count)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: the mesh already has one");
    uint32_t res = d.resolution ? d.resolution : HL_GROUND_RESOLUTION;
    float margin = d.margin != 0.0f ? d.margin : HL_GROUND_MARGIN;
    if (res > HL_GROUND_MAX_RESOLUTION)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: resolution %u exceeds %u", res,
                       HL_GROUND_MAX_RESOLUTION);
    if (!(margin > 0.0f) || !isfinite(margin))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: margin %g must be positive", (double)margin);

    uint32_t nv = mesh->vertex_count, nt = mesh->triangle_count;
    uint64_t gv = (uint64_t)(res + 1) * (res + 1), gt = 2 * (uint64_t)res * res;
    if (nv + gv > UINT32_MAX || nt + gt > UINT32_MAX)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: %u x %u grid makes the mesh too large", res, res);

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

    /* A square centred on the footprint: cells stay square, and it covers
     * the footprint plus margin x its larger extent on every side. */
    double ext = fmax(hi[0] - lo[0], hi[2] - lo[2]);
    if (!(ext > 0.0)) ext = fmax(hi[1] - lo[1], 1.0);
    double side = ext * (1.0 + 2.0 * margin);
    double cx = 0.5 * (lo[0] + hi[0]), cz = 0.5 * (lo[2] + hi[2]);
    double x0 = cx - 0.5 * side, z0 = cz - 0.5 * side, step = side / res;
    float y = (float)lo[1];

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
        return HL_ERR_OUT_OF_MEMORY;
    }
    memcpy(pos, mesh->positions, (size_t)nv * 3 * sizeof(float));
    memcpy(nrm, mesh->normals, (size_t)nv * 3 * sizeof(float));
    if (mesh->albedo) memcpy(alb, mesh->albedo, (size_t)nv * 3 * sizeof(float));
    else for (size_t i = 0; i < (size_t)nv * 3; i++) alb[i] = HL_DEFAULT_ALBEDO;
    memcpy(idx, mesh->indices, (size_t)nt * 3 * sizeof(uint32_t));

    uint32_t row = res + 1;
    for (uint32_t j = 0; j <= res; j++)
        for (uint32_t i = 0; i <= res; i++) {
            size_t v = nv + (size_t)j * row + i;
            /* The last row and column land exactly on the far edge. */
            pos[3 * v] = (float)(i == res ? x0 + side : x0 + step * i);
            pos[3 * v + 1] = y;
            pos[3 * v + 2] = (float)(j == res ? z0 + side : z0 + step * j);
            nrm[3 * v] = 0.0f;
            nrm[3 * v + 1] = 1.0f;
            nrm[3 * v + 2] = 0.0f;
            memcpy(alb + 3 * v, albedo, sizeof albedo);
        }
    /* (a, c, b) with a=(i,j), b=(i+1,j), c=(i,j+1): (c-a) x (b-a) = +Z x +X
     * = +Y, counter-clockwise seen from above. */
    size_t t = nt;
    for (uint32_t j = 0; j < res; j++)
        for (uint32_t i = 0; i < res; i++) {
            uint32_t a = nv + j * row + i, b = a + 1, c = a + row, e = c + 1;
            uint32_t *f = idx + 3 * t;
            f[0] = a; f[1] = c; f[2] = b;
            f[3] = b; f[4] = c; f[5] = e;
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

