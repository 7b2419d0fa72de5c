/* dyn_reference.h - the exact reference of the dynamic method: per vertex
 * of every body in world space, the diffuse radiosity under the whole
 * environment with ray-traced visibility against all bodies,
 *     B(v) = albedo / pi * sum_w L(w) Omega(w) max(0, n . w) vis(v, w),
 * and the same with the K kept lights' visibility traced and the folded
 * ambient unshadowed (as the frame shades it), which separates the error
 * of the light split from that of the shadow maps.
 * Depends on: dynamic.h, area_lights.h, dyn_frame.h (hl_frame_to_world),
 * visibility's rays.h and geom.h (Embree occlusion rays), core.
 */
#ifndef HL_DYN_REFERENCE_H
#define HL_DYN_REFERENCE_H

#include <stdint.h>

#include "area_lights.h"
#include "dynamic.h"
#include "haarlight.h"

/* Cube face resolution F of the exact reference's directions: 64, so
 * 6 x 64^2 = 24576 directions, each a cube texel holding its share of the
 * map's energy and first moment exactly (area_lights.c resamples the map
 * by area), seen through S x S rays. The visibility is a step at a
 * texel's size (0.9 to 1.8 degrees), and a sun's energy sits in its
 * whole texel. On the bunny on its ground (test_dyn_reference
 * convergence MAP S F), the reference moved by, relative L2:
 *   F 32 S 1 (1.2 s) against F 64: 1.8% (city.exr), 1.4% (studio.exr);
 *   F 32 S 2 (3 s) against F 32 S 4: 0.5%, against F 64 S 2: 1.2%;
 *   F 64 S 1 (3.8 s) against F 128: 0.8% (city), 0.6% (studio).
 * So the texel size, not the rays a texel, limits it, and 64 keeps it
 * under 1%, well below the 5% the frame is measured against, at 3.8 s
 * on 2 cores for 11k vertices (32 was the first choice: 1.8%). */
#define HL_DYNREF_DEFAULT_FACE 64u

/* Rays per texel side S (S x S per texel) of the exact reference: 1 (see
 * above: a finer face is worth more than more rays a texel). For the
 * K-lights reference, whose texels are the split's (F = 32): 2, so its
 * rays leave at the 2 x 2 sub-texel centres, the directions of the exact
 * reference's F = 64 texels. At most 15 (rays.c counts a texel's
 * unoccluded rays in a byte). */
#define HL_DYNREF_DEFAULT_S 1u
#define HL_DYNREF_LIGHTS_DEFAULT_S 2u
#define HL_DYNREF_MAX_S 15u

typedef struct hl_dyn_ref_stats {
    uint32_t vertices;
    uint32_t F, S;
    uint64_t rays_cast, rays_culled; /* culled: below the vertex's horizon */
    double seconds;                  /* the whole call */
} hl_dyn_ref_stats;

/* The exact reference at face resolution F (0: HL_DYNREF_DEFAULT_FACE;
 * 4..HL_LIGHTS_MAX_FACE) and S rays a texel side (0: the default):
 * objects as at the frame (world = xf p), albedo[b] and rgb[b] 3 floats
 * per vertex of body b. Rays leave each vertex from rays.c's robust
 * offset along its normal (2^-16 of its largest coordinate or edge) and
 * meet every body. Runs on ctx's threads. stats may be NULL. */
hl_result hl_dyn_reference_exact(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj,
                                 const float *const *albedo, const hl_env *env, uint32_t F, uint32_t S,
                                 float *const *rgb, hl_dyn_ref_stats *stats);

/* The kept lights of split (split->count) with traced visibility:
 *     B = albedo / pi * (sum_k V_k E_k(n) + ambient(n))
 * with E_k and ambient as the frame takes them (hl_area_light_irradiance,
 * hl_light_split_ambient) and V_k the share of the light's energy
 * (luminance) in texels above the vertex's horizon whose S x S rays are
 * unoccluded: the best a single visibility per light can do. S: 0 for
 * HL_DYNREF_LIGHTS_DEFAULT_S. */
hl_result hl_dyn_reference_lights(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj,
                                  const float *const *albedo, const hl_light_split *split, uint32_t S,
                                  float *const *rgb, hl_dyn_ref_stats *stats);

/* The bodies merged into one world-space mesh (positions, normals,
 * indices; no albedo) at their transforms, body b's vertices from
 * vstart[b] (vstart: nobj + 1 entries, the last the total). Checks the
 * indices and that every position and normal is finite. On failure m may
 * hold arrays: free m's positions, normals and indices either way. */
hl_result hl_dyn_world_merge(hl_context *ctx, const hl_dyn_object *obj, uint32_t nobj, hl_mesh *m, uint32_t *vstart);

#endif
