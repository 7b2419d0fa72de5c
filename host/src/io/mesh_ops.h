/* mesh_ops.h - the geometry the mesh builder (mesh.c) and the ground
 * plane (mesh_ground.c) share: albedo defaults, welding, the closed-mesh
 * test and signed volume behind orientation, and smooth normals
 * (mesh_ops.c).
 *
 * Depends on: hl_internal.h (errors, allocation).
 */
#ifndef HL_MESH_OPS_H
#define HL_MESH_OPS_H

#include <stdint.h>

#include "hl_internal.h"

/* Built-in default albedo (see the comments in haarlight.h). */
#define HL_DEFAULT_ALBEDO 0.8f

/* Cross product of (b - a) and (c - a) in double: twice the area vector. */
static inline void hl_tri_cross(const float *a, const float *b, const float *c, double *n)
{
    double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

/* Zero albedo means fallback; anything else must be a reflectance in
 * [0, 1] (HL_ERR_INVALID_ARGUMENT naming name otherwise). */
hl_result hl_mesh_resolve_albedo_(hl_context *ctx, const char *name, const float *in, float fallback, float *outv);

/* What two vertices must share to be welded: positions, and normals and
 * colours where given (NULL: not compared). */
typedef struct weld_key {
    const float *pos, *nrm, *col; /* nrm/col may be NULL */
} weld_key;

/* Welds the n vertices of k: equal bit patterns, except that -0 == +0.
 * remap[v] = welded id of vertex v; rep[w] = first vertex of welded id w.
 * Welded ids follow the order of first occurrence. Returns the id count,
 * or 0 after recording an allocation failure. */
uint32_t hl_mesh_weld_(hl_context *ctx, const weld_key *k, uint32_t n, uint32_t *remap, uint32_t *rep);

/* 1 if every directed edge appears once and its reverse appears once:
 * closed, manifold and consistently wound, so the signed volume has a
 * meaning. 0 otherwise; -1 after an allocation failure. */
int hl_mesh_closed_and_consistent_(hl_context *ctx, const uint32_t *idx, uint32_t tris);

/* Signed volume about center (the bounding-box centre, which keeps the
 * sum well conditioned for meshes far from the origin). */
double hl_mesh_signed_volume_(const float *pos, const uint32_t *idx, uint32_t tris, const double *center);

/* Area-weighted smooth normals of the nv vertices into nrm. Where the
 * weighted sum cancels (back-to-back flaps, needles) the normal of the
 * largest adjacent face is used instead, and +Y when even that is zero,
 * so no normal is ever NaN. HL_ERR_OUT_OF_MEMORY on failure. */
hl_result hl_mesh_smooth_normals_(hl_context *ctx, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t tris,
                                  float *nrm);

#endif
