/* surface.c - hl_surface_load: a mesh's textured surface, read from the
 * file it was loaded from (material.h has the structure; mesh_import.c
 * builds it alongside the mesh) and matched against that mesh.
 *
 * Depends on: material.h, hl_internal.h, libc.
 */
#include <stdlib.h>
#include <string.h>

#include "material.h"

void hl_surface_destroy(hl_surface *s)
{
    if (!s) return;
    hl_surface_arrays_free_(s);
    hl_materials_free_(&s->mats);
    free(s);
}

uint32_t hl_surface_texture_count(const hl_surface *s)
{
    return s ? s->mats.ntex : 0;
}

uint32_t hl_surface_triangle_count(const hl_surface *s)
{
    return s ? s->triangle_count : 0;
}

hl_result hl_surface_triangle(const hl_surface *s, uint32_t t, int32_t *texture, float uv[6], float base[9])
{
    if (!s || t >= s->triangle_count || !texture) return HL_ERR_INVALID_ARGUMENT;
    *texture = s->tex[t];
    if (uv) memcpy(uv, s->uv + 6 * (size_t)t, 6 * sizeof(float));
    if (base) memcpy(base, s->base + 9 * (size_t)t, 9 * sizeof(float));
    return HL_OK;
}

const uint8_t *hl_surface_texture(const hl_surface *s, uint32_t k, uint32_t *width, uint32_t *height)
{
    if (!s || k >= s->mats.ntex) return NULL;
    if (width) *width = s->mats.tex[k].w;
    if (height) *height = s->mats.tex[k].h;
    return s->mats.tex[k].rgb;
}

hl_result hl_surface_load(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, const hl_mesh *mesh,
                          hl_surface **out)
{
    if (out) *out = NULL;
    if (!path || !mesh || !out)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_surface_load: path, mesh and out are required");
    hl_mesh *m = NULL;
    hl_surface *s = NULL;
    hl_result r = hl_mesh_load_surface_(ctx, path, desc, &m, NULL, NULL, &s);
    if (r != HL_OK) return r;
    /* the surface is per triangle: the object's triangles, which come
       first (the ground's after them), must be the file's, corner for
       corner; where they lie (another up axis, a moved body) does not
       matter */
    const char *why = NULL;
    uint32_t object_tris = 0; /* the triangles of the object's vertices alone */
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *f = mesh->indices + 3 * (size_t)t;
        object_tris += f[0] < mesh->object_vertex_count && f[1] < mesh->object_vertex_count &&
                       f[2] < mesh->object_vertex_count;
    }
    if (m->vertex_count != mesh->object_vertex_count || m->triangle_count != object_tris)
        why = "a different number of vertices or triangles";
    else if (memcmp(m->indices, mesh->indices, (size_t)m->triangle_count * 3 * sizeof(uint32_t)))
        why = "other triangles";
    if (why)
        r = hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                    "%s: this file's mesh (%u vertices, %u triangles) is not the one relit (%u object vertices, %u "
                    "triangles): %s; give the file it was precomputed from (with --keep-winding if precompute "
                    "had it; a transport of a pose, precompute --time, has its bodies in another order, which "
                    "textures do not follow)",
                    path, m->vertex_count, m->triangle_count, mesh->object_vertex_count, object_tris, why);
    hl_mesh_destroy(m);
    if (r != HL_OK) {
        hl_surface_destroy(s);
        return r;
    }
    *out = s;
    return HL_OK;
}
