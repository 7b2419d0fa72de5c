/* instances.h - an Embree scene of rigid instances and orthographic
 * depth maps of it (instances.c; with rays.c the only files that include
 * Embree's headers).
 *
 * Each object's BVH is built once; moving an object sets its instance's
 * transform and re-commits only the small top-level scene. A depth map
 * casts one ray per texel centre of an orthographic frame, from its near
 * plane along its far direction, in 16-ray packets on ctx's threads.
 * Depends on: core. Plain arrays only (visibility sits above dynamic/).
 */
#ifndef HL_INSTANCES_H
#define HL_INSTANCES_H

#include <stdint.h>

#include "hl_internal.h"

typedef struct hl_inst_scene hl_inst_scene;

/* One object: its mesh in its own coordinates, copied at creation. */
typedef struct hl_inst_mesh {
    const float *pos;    /* 3 per vertex */
    uint32_t nverts;
    const uint32_t *tri; /* 3 per triangle, < nverts (checked by the caller) */
    uint32_t ntris;
    const float *xf;     /* 12: rigid transform, row-major 3x4 */
} hl_inst_mesh;

/* An orthographic frame: texel (i, j) casts from origin + ((i + 0.5) / R)
 * width right + ((j + 0.5) / R) height up along far, and stores
 * min(t / depth_range, 1) (1: no hit). */
typedef struct hl_inst_ortho {
    float origin[3], right[3], up[3], far[3];
    float width, height, depth_range;
    uint32_t R;
} hl_inst_ortho;

hl_result hl_inst_create(hl_context *ctx, const hl_inst_mesh *objs, uint32_t nobj, hl_inst_scene **out);
void hl_inst_destroy(hl_inst_scene *s);

/* New transform of object i (12 floats): the instance's only; the scene
 * is committed before the next depth map. */
hl_result hl_inst_set_transform(hl_inst_scene *s, uint32_t i, const float *xf);

/* K maps of R R floats each, map k at depth + k R R (row j at j R). */
hl_result hl_inst_depth_maps(hl_inst_scene *s, const hl_inst_ortho *frames, uint32_t K, float *depth);

/* Occlusion of `count` rays (origins and directions, 3 floats each):
 * occ[i] = 1 when anything of the scene lies along ray i from tnear[i]
 * on (in units of the direction's length; tnear NULL: 0), in 16-ray
 * packets of consecutive rays on ctx's threads. */
hl_result hl_inst_occluded(hl_inst_scene *s, uint32_t count, const float *org, const float *dir, const float *tnear,
                           uint8_t *occ);

/* Counts for the tests: object BVH builds (one per object, at creation)
 * and top-level commits. */
void hl_inst_counts(const hl_inst_scene *s, uint64_t *object_builds, uint64_t *scene_commits);

#endif
