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

/* Cube face resolution of the exact reference's directions: 32, so
 * 6 x 32^2 = 6144 directions, each a cube texel holding its share of the
 * map's energy and first moment exactly (area_lights.c resamples the map
 * by area), seen through one ray at its centre. A texel spans 1.7 to 3.6
 * degrees: the visibility is a step at that size, far below the shadow
 * maps' filter widths. */
#define HL_DYNREF_DEFAULT_FACE 32u

/* Rays per texel side S (S x S per texel): 1. hl.dyn_reference.furnace
 * and the occluded case pass at 1; S = 2 changed the bunny's exact
 * reference by under 1% relative L2 (measured with `test_dyn_reference
 * accuracy`'s S argument) at four times the rays. At most 16 (rays.c's
 * per-texel count is a byte). */
#define HL_DYNREF_DEFAULT_S 1u
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
 * unoccluded: the best a single visibility per light can do. */
hl_result hl_dyn_reference_lights(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj,
                                  const float *const *albedo, const hl_light_split *split, uint32_t S,
                                  float *const *rgb, hl_dyn_ref_stats *stats);

#endif
