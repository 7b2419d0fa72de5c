/* dyn_traced.h - the simplest method a user could write instead of the
 * dynamic method's shadow maps, for the benchmark to race against: per
 * vertex, for each of the K kept lights, S occlusion rays stratified over
 * the light's texels, so that
 *     B = albedo / pi * (sum_k V_k E_k(n) + ambient(n)),
 * V_k the share of the light's rays above the vertex's horizon that
 * nothing blocks, E_k and the folded ambient as the frame takes them.
 * Everything a frame needs is redone each call (the bodies may have
 * moved): the world mesh, Embree's scene of it, the rays.
 * Depends on: dynamic.h, area_lights.h, dyn_reference.h
 * (hl_dyn_world_merge), maps' geom.h (cube directions), visibility's
 * rays.h (Embree), core.
 */
#ifndef HL_DYN_TRACED_H
#define HL_DYN_TRACED_H

#include <stdint.h>

#include "area_lights.h"
#include "dynamic.h"
#include "haarlight.h"

/* Rays a light per vertex: 1 to 1024. Above 1024 the Monte Carlo noise
 * (about 1 / sqrt(S) of a penumbra's contrast, 3% at 1024) is below the
 * exact reference's own error, so more measure nothing. */
#define HL_DYNTRACED_MAX_S 1024u

typedef struct hl_dyn_traced_stats {
    uint32_t vertices, lights, S;
    uint64_t rays_cast;   /* above the horizon: traced */
    uint64_t rays_below;  /* below it: not traced */
    double t_build;       /* world mesh and Embree's scene */
    double t_rays;        /* sample directions and origins */
    double t_trace;       /* Embree's occlusion rays */
    double t_shade;       /* E_k, ambient, the sum */
    double seconds;       /* the whole call */
} hl_dyn_traced_stats;

/* The traced method on objects as at the frame (world = xf p), the kept
 * lights of split (split->count), S rays a light: body b's colours into
 * rgb[b], 3 floats per vertex. Light k's samples at a vertex are
 * stratified over its energy: sample s takes the texel of the light
 * (row by row of its rectangle) that holds the fraction (s + j) / S of
 * the light's luminance energy, and a point in that texel, j and the
 * point jittered by a hash of the vertex, light and sample (so the result
 * is deterministic and does not depend on the threads); so V_k tends to
 * the K-lights reference's energy-weighted share as S grows. A light
 * with no ray above the horizon has V = 1 (its E_k is 0 or a sliver).
 * Runs on ctx's threads. stats may be NULL. */
hl_result hl_dyn_traced(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, const float *const *albedo,
                        const hl_light_split *split, uint32_t S, float *const *rgb, hl_dyn_traced_stats *stats);

#endif
