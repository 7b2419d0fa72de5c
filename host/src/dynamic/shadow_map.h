/* shadow_map.h - one orthographic depth map per distant light, per frame,
 * for a set of rigid objects (the dynamic method's shadow maps).
 *
 * Two ways make the maps: the OpenCL rasteriser (kernels/dynamic/
 * shadow_raster.cl; its plain-C twin below on the reference backend) and
 * Embree rays (one per texel centre, into a scene of one instance per
 * object: visibility/instances.h). Both fit the same frame per light
 * (hl_shadow_fit_frame) and write the same depth convention: dynamic.h's
 * hl_shadow_frame, empty texels exactly 1.0f.
 * Depends on: dynamic.h (the shared types), core.
 */
#ifndef HL_SHADOW_MAP_H
#define HL_SHADOW_MAP_H

#include <stdint.h>

#include "dynamic.h"
#include "hl_internal.h"

/* Map size: 128 by default. The paper's is 256, but the maps here span
 * the casters only (flat bodies stay out, hl_shadow_maps_skip_planes),
 * and on the bunny with its ground under the eight shared maps and the
 * sky R = 128 gives the same error as 256 within half a percentage point
 * (2.6 to 5.1% at rest against 2.2 to 5.2%) in half the frame time
 * (test_dyn_reference accuracy; docs/DYNAMIC.md). 8 keeps a one-texel
 * margin meaningful on each side; 4096 bounds one map at 64 MiB. */
#define HL_SHADOW_DEFAULT_R 128u
#define HL_SHADOW_MIN_R 8u
#define HL_SHADOW_MAX_R 4096u

/* What an empty texel holds: "nothing blocks" for the next stage. Every
 * covered texel holds less (the frame keeps all geometry below it). */
#define HL_SHADOW_EMPTY 1.0f

typedef enum hl_shadow_method {
    HL_SHADOW_RASTER = 0, /* the OpenCL kernel, or its twin (reference backend): the default */
    HL_SHADOW_EMBREE = 1, /* one Embree ray per texel centre, instanced objects */
} hl_shadow_method;

typedef struct hl_shadow_maps hl_shadow_maps;

/* Copies the objects (meshes and transforms: nothing stays borrowed) and
 * prepares the chosen method: device buffers for the rasteriser, one
 * Embree BVH per object for the rays. Fails with a message on an empty
 * set, no triangles, an index out of range, non-finite vertices, a
 * non-finite or non-rigid transform, or R outside [MIN_R, MAX_R]. */
hl_result hl_shadow_maps_create(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, uint32_t R,
                                hl_shadow_method method, hl_shadow_maps **out);

/* Moves one object: xf is its new rigid transform (dynamic.h's layout).
 * Costs 12 floats (and, with Embree, one instance update); no rebuild. */
hl_result hl_shadow_maps_set_transform(hl_shadow_maps *sm, uint32_t object, const float xf[12]);

/* Renders K maps into depth (K R R floats, map k at k R R, row j of map k
 * at k R R + j R: rows go along `up`, columns along `right`). dirs: unit
 * light directions (towards the light). frames (K, may be NULL) gets each
 * map's frame. depth may be NULL where the rasteriser runs on an OpenCL
 * device: the maps then stay in its memory (hl_shadow_maps_device_depth)
 * until the next render. */
hl_result hl_shadow_maps_render(hl_shadow_maps *sm, const float (*dirs)[3], uint32_t K, float *depth,
                                hl_shadow_frame *frames);

/* The same into frames the caller gives (K of them, each of this
 * module's R, e.g. from an earlier call): fixed frames, or two scenes
 * compared texel by texel. Nothing is refitted: geometry outside a frame
 * is clipped away. */
hl_result hl_shadow_maps_render_in(hl_shadow_maps *sm, const hl_shadow_frame *frames, uint32_t K, float *depth);

/* Flat bodies out of the maps (off by default; the rasteriser only, the
 * Embree path draws every body). A body whose vertices lie on one plane
 * cannot shadow itself. When every other body lies on one side of that
 * plane, it is left out of the map and of the frame's fit
 * (frame.skip_mask) for lights on the bodies' side, where it shadows
 * none of them; and, when it is a filled rectangle (flat.rect), also for
 * lights on the other side, where it hides the light from every point
 * whose ray meets the rectangle, which the caller works out from the
 * plane (hl_shadow_maps_flat) with no depth bias at the contact. The map then spans the casters only, so a bunny on a
 * ground four times its width gets four times finer texels and a depth
 * range of its own height. Bodies 32 and up are always drawn (the mask
 * has 32 bits). */
void hl_shadow_maps_skip_planes(hl_shadow_maps *sm, int on);

/* The skip_mask that hl_shadow_maps_render would give each of K lights
 * (dirs as there) at the current transforms, with nothing rendered: a
 * map made earlier for the same direction still holds what a new one
 * would when these masks are its own and no body it draws has moved
 * (dyn_frame.c keeps its maps by that). */
void hl_shadow_maps_skip_masks(hl_shadow_maps *sm, const float (*dirs)[3], uint32_t K, uint32_t *masks);

/* A flat body's plane in world space at its current transform. */
typedef struct hl_flat_body {
    float n[3], p[3];   /* unit normal, a point of the plane */
    float u[3], v[3];   /* unit axes in the plane, v = n x u */
    float lo[2], hi[2]; /* the body's extent along u and v, from p */
    int rect;           /* its triangles fill that extent (a rectangle) */
} hl_flat_body;

/* 1 and *fb when body o is flat (all its vertices on one plane), else 0. */
int hl_shadow_maps_flat(const hl_shadow_maps *sm, uint32_t o, hl_flat_body *fb);

/* The device buffer (a cl_mem) of the last render's maps, laid out as
 * depth above; NULL before the first render on a device. */
void *hl_shadow_maps_device_depth(const hl_shadow_maps *sm);

void hl_shadow_maps_destroy(hl_shadow_maps *sm);

/* For the tests: how many times the Embree path built an object's BVH
 * and committed its top-level scene (0 for the rasteriser). */
void hl_shadow_maps_embree_counts(const hl_shadow_maps *sm, uint64_t *object_builds, uint64_t *scene_commits);

/* Margin: texels left empty on each side of the scene's projected bounds.
 * One: the outermost ring of every map is then empty, so a filter or a
 * clamp-to-edge read beyond the map reads "nothing blocks" instead of
 * smearing a border blocker outwards, and a receiver the float rounding
 * puts a hair outside the bounds still lands on a texel of the map. */
#define HL_SHADOW_MARGIN_TEXELS 1u

/* The frame of a map of R x R texels for light direction dir (unit,
 * towards the light) over a scene whose points all lie in the convex hull
 * of `npts` world points pts (3 floats each). Square texels, the margin
 * above, and depths of the points strictly inside (0, 1). */
void hl_shadow_fit_frame(const float *pts, uint32_t npts, const float dir[3], uint32_t R, hl_shadow_frame *fr);

/* The 16 floats per map the rasteriser reads (shadow_raster.cl's layout). */
void hl_shadow_frame_pack(const hl_shadow_frame *fr, float out[16]);

/* Twin of kernels/dynamic/shadow_raster.cl for map k: pos (3 floats per
 * vertex, all objects one after another), tri (4 per triangle: three
 * indices into pos and the object), xf (12 per object), frames (16 per
 * map), map (R R floats, filled with HL_SHADOW_EMPTY first; each covered
 * centre keeps the smaller depth). Triangles [t0, t1) only. */
void hl_ref_shadow_raster(const float *pos, const uint32_t *tri, uint32_t t0, uint32_t t1, const float *xf,
                          const float *frame16, uint32_t R, float *map);

#endif
