/* rays.h - visibility sampling with Embree 3 (rays.c is the only file that
 * includes Embree's headers).
 *
 * For each vertex, one occlusion ray per cube texel (S x S with
 * supersampling) for the texels above the vertex's horizon; texels below
 * it are culled. Output per vertex: ncube bytes, the number of unoccluded
 * rays of each texel. Rows are written by vertex index, so the result does
 * not depend on the number of threads.
 */
#ifndef HL_RAYS_H
#define HL_RAYS_H

#include "geom.h"

typedef struct hl_rt hl_rt;

hl_result hl_rt_create(hl_context *ctx, const hl_mesh *mesh, hl_rt **out);
/* The same scene, which can also answer hl_rt_occluded_from_vertex (its
 * rays are a little slower); mesh must outlive it. */
hl_result hl_rt_create_filtered(hl_context *ctx, const hl_mesh *mesh, hl_rt **out);
void hl_rt_destroy(hl_rt *rt);

typedef struct hl_vis_counts {
    uint64_t rays_cast;
    uint64_t rays_culled; /* directions (texels x S^2) below the horizon */
} hl_vis_counts;

/* Visibility of vertices [first, first + count) into vis (count * ncube
 * bytes), using ctx's thread count; mesh is the one the scene was built
 * from. offset: absolute ray-origin offset along the normal, or 0 for the
 * robust offset (per vertex, sized to its coordinates and edges: rays.c). */
hl_result hl_rt_visibility(hl_rt *rt, const hl_geom *g, const hl_mesh *mesh, uint32_t first,
                           uint32_t count, uint32_t S, float offset, uint8_t *vis,
                           hl_vis_counts *counts);

/* The robust offset of vertex v (what offset 0 uses). */
float hl_rt_robust_offset(const hl_rt *rt, uint32_t v);

/* Embree's raw occlusion rate on the same rays as hl_rt_visibility builds
 * for the listed vertices: the packets are made first, then only the
 * rtcOccluded16 calls are timed, on ctx's thread count. Returns rays/s. */
hl_result hl_rt_raw_rate(hl_rt *rt, const hl_geom *g, const hl_mesh *mesh, const uint32_t *verts,
                         uint32_t nverts, uint32_t S, float offset, double *rays_per_s);

/* The robust offset's parts, for rays cast outside an hl_rt (the
 * dynamic frame's sharp lights): e[v] = vertex v's longest edge (largest
 * coordinate difference), and the offset of a vertex at p with longest
 * edge `edge`. */
void hl_rt_longest_edges(const float *P, uint32_t nverts, const uint32_t *tri, uint32_t ntris, float *e);
float hl_rt_offset_size(const float p[3], float edge);
/* One coordinate of a ray origin offset from a surface point p along its
 * normal n: p + n offset, rounded away from the surface, so that far from
 * the origin (where the offset is below the coordinates' spacing) it never
 * lands back on the surface. */
float hl_rt_origin_coord(float p, float n, float offset);

/* Closest hits of `count` rays (origins and directions, 3 floats each,
 * directions need not be unit): prim[i] = triangle index or UINT32_MAX
 * for a miss, (u[i], v[i]) = barycentrics of vertices 1 and 2 of that
 * triangle. Runs on ctx's threads. */
hl_result hl_rt_trace_primary(hl_rt *rt, uint32_t count, const float *org, const float *dir,
                              uint32_t *prim, float *u, float *v);

/* Occlusion of `count` rays (3 floats each for origin and direction):
 * occluded[i] = 1 when anything lies along ray i from tnear[i] on (in
 * units of the direction's length; tnear NULL: from the origin). Rays
 * from an offset vertex pass the offset, as hl_rt_visibility does. */
hl_result hl_rt_trace_occluded(hl_rt *rt, uint32_t count, const float *org, const float *dir, const float *tnear,
                               uint8_t *occluded);
/* The same along segments: only what lies between tnear[i] and tfar[i]
 * (tfar NULL: infinity), e.g. up to just short of a point on a light. */
hl_result hl_rt_trace_occluded_seg(hl_rt *rt, uint32_t count, const float *org, const float *dir, const float *tnear,
                                   const float *tfar, uint8_t *occluded);

/* Occlusion of `count` rays from vertex `vertex` itself, with no offset:
 * hits on the vertex's own triangles (which such a ray meets only at its
 * origin) are dropped, every other hit counts from the robust offset's
 * distance on (the surfaces through the vertex itself are met at t = 0
 * by every ray: rays.c). An offset-free way to cast
 * rays from a vertex, independent of the precompute's offset (bench's
 * continuous reference). Needs hl_rt_create_filtered. */
hl_result hl_rt_occluded_from_vertex(hl_rt *rt, uint32_t vertex, uint32_t count, const float *dir,
                                     uint8_t *occluded);

#endif
