/* mesh.c - triangle meshes: the shared builder and the mesh's lifetime.
 *
 * hl_mesh_create and the importers in mesh_import.c hand raw arrays to
 * hl_mesh_build_, which validates, welds vertices with equal positions
 * (bit-identical, except that -0 == +0), drops degenerate triangles and
 * unreferenced vertices, turns inward-wound closed meshes outward and
 * computes smooth normals, reporting every change in hl_mesh_stats. The
 * algorithms it uses are in mesh_ops.c; the ground plane and queries in
 * mesh_ground.c.
 *
 * Dependencies: mesh_ops.h, hl_internal.h (errors, allocation), libc,
 * libm. Mesh arrays are allocated with plain malloc and released with
 * free, so a mesh assembled by another module (the transport loader) can
 * be handed to hl_mesh_destroy as well.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_ops.h"

/* Triangles with area <= this x diagonal^2 are dropped (same rule as the
 * shared data README). */
#define HL_DEGENERATE_AREA 1e-12

static int is_finite3(const float *p)
{
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

/* ---------------------------------------------------------------- builder */

/* The state hl_mesh_build_ carries from phase to phase. The working arrays
 * are owned here and freed by build_free; vertex and face numbers in
 * messages count from 0, as in the arrays. */
typedef struct mesh_build {
    hl_context *ctx;
    const char *name;
    /* the caller's arrays (normals and colors may be NULL) */
    uint32_t vertex_count, triangle_count;
    const float *positions, *normals, *colors;
    const float *corner_tex;        /* 9 floats a triangle, or NULL */
    uint32_t *tri_origin;           /* the caller's, or NULL: b->orig is copied there */
    const uint32_t *indices;
    int up_z, keep_winding;
    float const_albedo[3];
    /* working arrays */
    float *pos, *nrm;               /* the caller's, in the engine's frame (nrm NULL without normals) */
    uint32_t *remap, *rep;          /* weld: remap[v] = welded id, rep[w] = first vertex of id w */
    uint32_t *tri, *newid;          /* kept triangles (welded ids), compaction of the welded ids */
    uint32_t *orig;                 /* with corner_tex or tri_origin: each kept triangle's input number */
    uint32_t welded, used;          /* welded ids; those the kept triangles reference */
    size_t kept;                    /* triangles kept */
    double lo[3], hi[3];            /* bounding box of the referenced geometry */
    hl_mesh_stats st;
} mesh_build;

static void build_free(mesh_build *b)
{
    free(b->pos);
    free(b->nrm);
    free(b->remap);
    free(b->rep);
    free(b->tri);
    free(b->newid);
    free(b->orig);
}

/* Options and arrays: everything that can refuse the input before any
 * allocation. */
static hl_result build_validate(mesh_build *b, const hl_mesh_load_desc *d)
{
    hl_context *ctx = b->ctx;
    const char *name = b->name;
    hl_result r = hl_mesh_resolve_albedo_(ctx, name, d->albedo, HL_DEFAULT_ALBEDO, b->const_albedo);
    if (r != HL_OK) return r;
    if (d->up_axis == 0 || d->up_axis == 'y' || d->up_axis == 'Y') b->up_z = 0;
    else if (d->up_axis == 'z' || d->up_axis == 'Z') b->up_z = 1;
    else return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: up axis %d is neither 'y' nor 'z'", name, d->up_axis);
    b->keep_winding = d->keep_winding;

    uint32_t vertex_count = b->vertex_count, triangle_count = b->triangle_count;
    const float *positions = b->positions, *colors = b->colors;
    if (vertex_count == 0) return hl_fail(ctx, HL_ERR_MESH, "%s: mesh has no vertices", name);
    if (triangle_count == 0)
        return hl_fail(ctx, HL_ERR_MESH, "%s: mesh has %u vertices but no faces", name, vertex_count);
    if (!positions || !b->indices)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: positions or indices are NULL", name);

    for (uint32_t v = 0; v < vertex_count; v++) {
        const float *p = positions + 3 * (size_t)v;
        if (!is_finite3(p))
            return hl_fail(ctx, HL_ERR_MESH, "%s: vertex %u (counting from 0) has a non-finite coordinate (%g, %g, %g)",
                           name, v, (double)p[0], (double)p[1], (double)p[2]);
        if (colors && !is_finite3(colors + 3 * (size_t)v))
            return hl_fail(ctx, HL_ERR_MESH, "%s: vertex %u (counting from 0) has a non-finite colour (%g, %g, %g)",
                           name, v, (double)colors[3 * (size_t)v], (double)colors[3 * (size_t)v + 1],
                           (double)colors[3 * (size_t)v + 2]);
    }
    for (uint32_t t = 0; t < triangle_count; t++)
        for (int c = 0; c < 3; c++) {
            uint32_t i = b->indices[3 * (size_t)t + c];
            if (i >= vertex_count)
                return hl_fail(ctx, HL_ERR_MESH,
                               "%s: face %u (counting from 0) refers to vertex %u, out of range (%u vertices)",
                               name, t, i, vertex_count);
        }
    return HL_OK;
}

/* Working copies in the engine's frame: +Z-up files turn so that +Z
 * becomes +Y; (x, y, z) -> (x, z, -y) is a proper rotation about +X.
 * Returns 0 after an allocation failure. */
static int build_frame(mesh_build *b)
{
    size_t nv = b->vertex_count;
    const int up_z = b->up_z;
    b->pos = hl_malloc(b->ctx, nv * 3 * sizeof(float), "vertex positions");
    if (!b->pos) return 0;
    if (b->normals) {
        b->nrm = hl_malloc(b->ctx, nv * 3 * sizeof(float), "vertex normals");
        if (!b->nrm) return 0;
    }
    for (size_t v = 0; v < nv; v++) {
        const float *p = b->positions + 3 * v;
        float *q = b->pos + 3 * v;
        if (up_z) { q[0] = p[0]; q[1] = p[2]; q[2] = -p[1]; }
        else { q[0] = p[0]; q[1] = p[1]; q[2] = p[2]; }
        if (b->nrm) {
            const float *n = b->normals + 3 * v;
            float *m = b->nrm + 3 * v;
            if (up_z) { m[0] = n[0]; m[1] = n[2]; m[2] = -n[1]; }
            else { m[0] = n[0]; m[1] = n[1]; m[2] = n[2]; }
        }
    }
    return 1;
}

/* Weld on position plus whatever attributes the caller supplied, so a
 * deliberate normal or colour seam survives. Returns 0 after an
 * allocation failure. */
static int build_weld(mesh_build *b)
{
    size_t nv = b->vertex_count;
    b->remap = hl_malloc(b->ctx, nv * sizeof(uint32_t), "the vertex remap");
    b->rep = hl_malloc(b->ctx, nv * sizeof(uint32_t), "the welded vertices");
    if (!b->remap || !b->rep) return 0;
    weld_key key = {b->pos, b->nrm, b->colors};
    b->welded = hl_mesh_weld_(b->ctx, &key, b->vertex_count, b->remap, b->rep);
    if (b->welded == 0) return 0;
    b->st.merged_vertices = b->vertex_count - b->welded;
    return 1;
}

/* Drops triangles with a repeated welded vertex or an area at most
 * HL_DEGENERATE_AREA x diagonal^2; the rest go to b->tri as welded ids.
 * HL_ERR_MESH when none is left. */
static hl_result build_drop_degenerate(mesh_build *b)
{
    const uint32_t *remap = b->remap, *rep = b->rep, *indices = b->indices;
    const float *pos = b->pos;
    size_t nt = b->triangle_count;
    /* The degenerate-area threshold scales with the referenced geometry
     * only; a stray unreferenced vertex must not change which faces stay. */
    for (int k = 0; k < 3; k++) {
        b->lo[k] = INFINITY;
        b->hi[k] = -INFINITY;
    }
    for (size_t i = 0; i < 3 * nt; i++) {
        const float *p = pos + 3 * (size_t)rep[remap[indices[i]]];
        for (int k = 0; k < 3; k++) {
            if (p[k] < b->lo[k]) b->lo[k] = p[k];
            if (p[k] > b->hi[k]) b->hi[k] = p[k];
        }
    }
    double diag2 = 0.0;
    for (int k = 0; k < 3; k++) diag2 += (b->hi[k] - b->lo[k]) * (b->hi[k] - b->lo[k]);
    double min_area2 = 2.0 * HL_DEGENERATE_AREA * diag2; /* |cross| is twice the area */

    uint32_t *tri = b->tri = hl_malloc(b->ctx, nt * 3 * sizeof(uint32_t), "triangle indices");
    if (!tri) return HL_ERR_OUT_OF_MEMORY;
    if ((b->corner_tex || b->tri_origin) && !(b->orig = hl_malloc(b->ctx, nt * sizeof(uint32_t), "triangle numbers")))
        return HL_ERR_OUT_OF_MEMORY;
    size_t kept = 0;
    for (size_t t = 0; t < nt; t++) {
        uint32_t a = remap[indices[3 * t]], c1 = remap[indices[3 * t + 1]], c2 = remap[indices[3 * t + 2]];
        if (a == c1 || c1 == c2 || a == c2) continue;
        double n[3];
        hl_tri_cross(pos + 3 * (size_t)rep[a], pos + 3 * (size_t)rep[c1], pos + 3 * (size_t)rep[c2], n);
        if (sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) <= min_area2) continue;
        tri[3 * kept] = a;
        tri[3 * kept + 1] = c1;
        tri[3 * kept + 2] = c2;
        if (b->orig) b->orig[kept] = (uint32_t)t;
        kept++;
    }
    b->kept = kept;
    b->st.degenerate_triangles = (uint32_t)(nt - kept);
    if (kept == 0)
        return hl_fail(b->ctx, HL_ERR_MESH,
                       "%s: all %u faces are degenerate (repeated vertex or zero area), nothing is left",
                       b->name, b->triangle_count);
    return HL_OK;
}

/* Compact: keep referenced welded vertices in first-occurrence order
 * (b->rep[0 .. used) becomes their first input vertex, b->tri their new
 * ids). Returns 0 after an allocation failure. */
static int build_compact(mesh_build *b)
{
    uint32_t welded = b->welded, *rep = b->rep, *tri = b->tri;
    uint32_t *newid = b->newid = hl_malloc(b->ctx, (size_t)welded * sizeof(uint32_t), "the vertex compaction");
    if (!newid) return 0;
    memset(newid, 0xFF, (size_t)welded * sizeof(uint32_t));
    for (size_t i = 0; i < 3 * b->kept; i++) newid[tri[i]] = 0;
    uint32_t used = 0;
    for (uint32_t w = 0; w < welded; w++)
        if (newid[w] != UINT32_MAX) {
            rep[used] = rep[w]; /* used <= w: overwriting in place is safe */
            newid[w] = used++;
        }
    for (size_t i = 0; i < 3 * b->kept; i++) tri[i] = newid[tri[i]];
    b->used = used;
    b->st.unreferenced_vertices = welded - used;
    return 1;
}

/* The output mesh: positions, albedo (the colours clamped, else the
 * constant) and indices; normals are allocated, not yet set. NULL after
 * an allocation failure. */
static hl_mesh *build_mesh(mesh_build *b)
{
    hl_context *ctx = b->ctx;
    size_t used = b->used, kept = b->kept;
    hl_mesh *mesh = hl_calloc(ctx, 1, sizeof *mesh, "the mesh");
    if (!mesh) return NULL;
    mesh->vertex_count = b->used;
    mesh->object_vertex_count = b->used;
    mesh->triangle_count = (uint32_t)kept;
    mesh->positions = hl_malloc(ctx, used * 3 * sizeof(float), "mesh positions");
    mesh->normals = hl_malloc(ctx, used * 3 * sizeof(float), "mesh normals");
    mesh->albedo = hl_malloc(ctx, used * 3 * sizeof(float), "mesh albedo");
    mesh->indices = hl_malloc(ctx, kept * 3 * sizeof(uint32_t), "mesh indices");
    if (!mesh->positions || !mesh->normals || !mesh->albedo || !mesh->indices) {
        hl_mesh_destroy(mesh);
        return NULL;
    }
    memcpy(mesh->indices, b->tri, kept * 3 * sizeof(uint32_t));
    for (size_t v = 0; v < used; v++)
        memcpy(mesh->positions + 3 * v, b->pos + 3 * (size_t)b->rep[v], 3 * sizeof(float));
    double *tex = NULL; /* with corner_tex: per vertex, sum of area x texture, then the area */
    if (b->corner_tex && !(tex = hl_calloc(ctx, used, 4 * sizeof(double), "the texture averages"))) {
        hl_mesh_destroy(mesh);
        return NULL;
    }
    for (size_t t = 0; tex && t < kept; t++) {
        const uint32_t *c = b->tri + 3 * t;
        double n[3];
        hl_tri_cross(mesh->positions + 3 * (size_t)c[0], mesh->positions + 3 * (size_t)c[1],
                     mesh->positions + 3 * (size_t)c[2], n);
        const double area = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const float *ct = b->corner_tex + 9 * (size_t)b->orig[t];
        for (int k = 0; k < 3; k++) {
            double *a = tex + 4 * (size_t)c[k];
            for (int q = 0; q < 3; q++) a[q] += area * ct[3 * k + q];
            a[3] += area;
        }
    }
    for (size_t v = 0; v < used; v++)
        for (int k = 0; k < 3; k++) {
            float a = b->colors ? b->colors[3 * (size_t)b->rep[v] + k] : b->const_albedo[k];
            if (tex && tex[4 * v + 3] > 0.0) a *= (float)(tex[4 * v + k] / tex[4 * v + 3]);
            mesh->albedo[3 * v + k] = a < 0.0f ? 0.0f : (a > 1.0f ? 1.0f : a);
        }
    free(tex);
    return mesh;
}

/* Orientation: only a closed, consistently wound mesh has an inside, so
 * only then can an inward winding be recognised and reversed. Returns 0
 * after an allocation failure. */
static int build_orient(mesh_build *b, hl_mesh *mesh)
{
    int closed = hl_mesh_closed_and_consistent_(b->ctx, mesh->indices, mesh->triangle_count);
    if (closed < 0) return 0;
    if (closed && !b->keep_winding) {
        double center[3] = {0.5 * (b->lo[0] + b->hi[0]), 0.5 * (b->lo[1] + b->hi[1]), 0.5 * (b->lo[2] + b->hi[2])};
        if (hl_mesh_signed_volume_(mesh->positions, mesh->indices, mesh->triangle_count, center) < 0.0) {
            for (size_t t = 0; t < b->kept; t++) {
                uint32_t s = mesh->indices[3 * t + 1];
                mesh->indices[3 * t + 1] = mesh->indices[3 * t + 2];
                mesh->indices[3 * t + 2] = s;
            }
            b->st.flipped = 1;
        }
    }
    return 1;
}

/* Normals: the file's where usable, else smooth ones from the final
 * winding. File normals follow a flip, since they pointed the same wrong
 * way as the winding. */
static hl_result build_normals(mesh_build *b, hl_mesh *mesh)
{
    size_t used = b->used;
    int need_smooth = b->nrm == NULL;
    if (b->nrm) {
        for (size_t v = 0; v < used; v++) {
            const float *n = b->nrm + 3 * (size_t)b->rep[v];
            double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
            float *o = mesh->normals + 3 * v;
            if (!(len > 1e-30) || !isfinite(len)) {
                o[0] = NAN; /* marks a vertex for the smooth fallback below */
                need_smooth = 1;
                continue;
            }
            double s = b->st.flipped ? -1.0 / len : 1.0 / len;
            for (int k = 0; k < 3; k++) o[k] = (float)(n[k] * s);
        }
    }
    if (!need_smooth) return HL_OK;
    float *smooth = b->nrm ? hl_malloc(b->ctx, used * 3 * sizeof(float), "smooth normals") : mesh->normals;
    if (!smooth) return HL_ERR_OUT_OF_MEMORY;
    hl_result r = hl_mesh_smooth_normals_(b->ctx, mesh->positions, b->used, mesh->indices, mesh->triangle_count,
                                          smooth);
    if (smooth != mesh->normals) {
        if (r == HL_OK)
            for (size_t v = 0; v < used; v++)
                if (isnan(mesh->normals[3 * v])) memcpy(mesh->normals + 3 * v, smooth + 3 * v, 3 * sizeof(float));
        free(smooth);
    }
    return r;
}

/* Shared by hl_mesh_create and the importers, in phases: validate, move to
 * the engine's frame, weld, drop degenerate triangles, compact, build the
 * mesh, orient, normals. name is used in messages. normals and colors may
 * be NULL. Vertex and face numbers in messages count from 0, as in the
 * arrays. */
hl_result hl_mesh_build_(hl_context *ctx, const char *name, uint32_t vertex_count,
                         const float *positions, const float *normals, const float *colors,
                         const hl_mesh_extra *extra, uint32_t triangle_count, const uint32_t *indices,
                         const hl_mesh_load_desc *desc, hl_mesh **out, hl_mesh_stats *stats)
{
    hl_mesh_load_desc d;
    memset(&d, 0, sizeof d);
    if (desc) d = *desc;
    if (!name) name = "<memory>";
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: no output mesh pointer given", name);
    *out = NULL;

    mesh_build b;
    memset(&b, 0, sizeof b);
    b.ctx = ctx;
    b.name = name;
    b.vertex_count = vertex_count;
    b.triangle_count = triangle_count;
    b.positions = positions;
    b.normals = normals;
    b.colors = colors;
    b.corner_tex = extra ? extra->corner_tex : NULL;
    b.tri_origin = extra ? extra->tri_origin : NULL;
    b.indices = indices;
    hl_result r = build_validate(&b, &d);
    if (r != HL_OK) return r;
    b.st.file_vertices = vertex_count;
    b.st.file_triangles = triangle_count;
    b.st.had_normals = normals != NULL;
    b.st.had_colors = colors != NULL;

    /* every failure below but a mesh with only degenerate faces is an
       allocation that failed (and recorded its message) */
    hl_mesh *mesh = NULL;
    r = HL_ERR_OUT_OF_MEMORY;
    if (build_frame(&b) && build_weld(&b)) {
        r = build_drop_degenerate(&b);
        if (r == HL_OK) {
            mesh = build_compact(&b) ? build_mesh(&b) : NULL;
            r = mesh && build_orient(&b, mesh) ? build_normals(&b, mesh) : HL_ERR_OUT_OF_MEMORY;
        }
    }
    if (r == HL_OK && b.tri_origin) memcpy(b.tri_origin, b.orig, b.kept * sizeof(uint32_t));
    build_free(&b);
    if (r != HL_OK) {
        hl_mesh_destroy(mesh);
        return r;
    }
    if (stats) *stats = b.st;
    *out = mesh;
    return HL_OK;
}

/* ---------------------------------------------------------------- public */

hl_result hl_mesh_create(hl_context *ctx, uint32_t vertex_count, const float *positions,
                         const float *normals, const float *albedo, uint32_t triangle_count,
                         const uint32_t *indices, hl_mesh **out)
{
    if (out) *out = NULL;
    if ((vertex_count && !positions) || (triangle_count && !indices))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "<memory>: positions or indices are NULL");
    return hl_mesh_build_(ctx, "<memory>", vertex_count, positions, normals, albedo, NULL, triangle_count,
                          indices, NULL, out, NULL);
}

void hl_mesh_destroy(hl_mesh *mesh)
{
    if (!mesh) return;
    free(mesh->positions);
    free(mesh->normals);
    free(mesh->albedo);
    free(mesh->indices);
    free(mesh);
}

