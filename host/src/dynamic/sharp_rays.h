/* sharp_rays.h - the visibility of the dynamic frame's sharp lights (a
 * sun: a light whose filter would span under a few texels of a shadow
 * map, dyn_frame.h) by Embree occlusion rays from every receiver, instead
 * of a shadow map. A map leaves such a light's shadow edge to its texels,
 * so its error is their size and phase; rays have neither, and a sharp
 * light needs few of them.
 *
 * Light k is taken as the uniform square light of its spread
 * (dynamic.h): directions dir + tan(spread) (x t1 + y t2), (x, y) on the
 * centres of a HL_SHARP_RAYS_GRID^2 grid of [-1, 1]^2. Each receiver
 * first casts 5 rays: the grid's 4 corner samples and dir itself. When
 * they agree (all blocked or all free) that is its visibility, 0 or 1;
 * else it casts the rest of the grid, and V is the share of the grid's
 * samples above its horizon that nothing blocks. Rays leave from rays.c's
 * robust offset along the normal, with the offset as tnear, as the exact
 * reference's do, and meet every body: an Embree scene of rigid
 * instances (instances.h), each body's BVH built once.
 * Depends on: dynamic.h, visibility's instances.h and rays.h, core.
 */
#ifndef HL_SHARP_RAYS_H
#define HL_SHARP_RAYS_H

#include <stdint.h>

#include "dynamic.h"
#include "hl_internal.h"

/* Samples a side of a sharp light's square: 4, so 16 rays where a
 * receiver's 5 first rays disagree (a penumbra) and 5 elsewhere. */
#define HL_SHARP_RAYS_GRID 4u

typedef struct hl_sharp_rays hl_sharp_rays;

/* The bodies as hl_frame_state_create takes them (their meshes are
 * copied into Embree's BVHs). */
hl_result hl_sharp_rays_create(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, hl_sharp_rays **out);
void hl_sharp_rays_destroy(hl_sharp_rays *sr);

/* Body b's new transform (xf: dynamic.h's layout). */
hl_result hl_sharp_rays_set_transform(hl_sharp_rays *sr, uint32_t b, const float *xf);

/* Visibility V[v] in [0, 1] of the light towards unit dir with the
 * given spread at the N receivers (world positions and unit normals, 3
 * floats each; N the bodies' vertices in order) where E (3 per receiver,
 * the light's irradiance) is above 0; elsewhere V[v] = 0. rays (may be
 * NULL) gets the rays cast. */
hl_result hl_sharp_rays_visibility(hl_sharp_rays *sr, const float *wpos, const float *wnrm, const float *E,
                                   const float dir[3], float spread, float *V, uint64_t *rays);

#endif
