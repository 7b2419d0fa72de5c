/* dyn_frame.h - one frame of the dynamic method (Annen et al. 2008): the
 * stages joined. Per vertex of every body, in world space,
 *     B(v) = albedo / pi * ( sum_k V_k(v) E_k(n_v) + ambient(n_v) )
 * with E_k the exact irradiance of kept light k (area_lights.h), V_k the
 * convolution shadow map's visibility of light k (shadow_map.h, csm.h)
 * and ambient the folded lights' SH9 term, unshadowed.
 * The shading sum is plain C on the host (dyn_frame.c).
 * Depends on: dynamic.h, area_lights.h, shadow_map.h, csm.h, core.
 */
#ifndef HL_DYN_FRAME_H
#define HL_DYN_FRAME_H

#include <stdint.h>

#include "area_lights.h"
#include "csm.h"
#include "dynamic.h"
#include "shadow_map.h"

/* The filterable representation a frame takes by default: the moment
 * shadow maps (csm.h). On the bunny with its ground (K = 32, R = 128, the
 * low-resolution bunny) a frame took 40 to 60 ms against 150 for CSM at
 * M = 16 on 2 cores, and its error against the exact reference was at or
 * below CSM's on each of the eight shared maps and the sky, at rest and
 * moved (DYNAMIC.md, section 3b). CSM stays, as the founding method. */
#define HL_FRAME_DEFAULT_SHADOW HL_SHADOW_REP_MOMENTS

/* Memory the convolution shadow maps of one batch of lights may take:
 * 256 MiB. At R = 256, M = Mb = 16 a light takes 18.4 MB (csm.h), so a
 * batch holds 14 lights and K = 32 runs in 3 batches. The work per light
 * is the same in any batch: on PoCL (2 cores, the bunny on its ground,
 * K = 32) a steady frame took 330-360 ms for batches of 1 to 32 lights
 * (test_dyn_frame timing MIB), while a first frame pays for touching the
 * batch's fresh memory (+100 ms at 14 lights, +700 ms at 32); and 32
 * lights at once (589 MB) would not fit small devices or the
 * HL_DEVICE_MEMORY limits people set. */
#define HL_FRAME_DEFAULT_BUDGET (256ull << 20)
/* On a device whose memory limit (the device's, or HL_DEVICE_MEMORY)
 * leaves less, the budget is this share of what is left after the shadow
 * maps' buffers: 0.5, so the evaluation's per-receiver buffers and
 * other users of the context still fit beside a batch. */
#define HL_FRAME_DEVICE_SHARE 0.5
/* A kept light whose energy (luminance of radiance x solid angle) is
 * below this share of the map's is shaded unshadowed (V = 1) and gets no
 * shadow map: 1e-4. Its shadow could change a vertex's irradiance by at
 * most 1e-4 of the map's energy (E_k(n) <= its energy for any n), below
 * what an 8-bit picture shows, while a map costs as much as the brightest
 * light's. */
#define HL_FRAME_MIN_SHARE 1e-4f
/* The largest half-angle handed to the filter: csm.h takes [0, pi/2);
 * a light is a rectangle of one cube face, whose cone is at most
 * 54.7 degrees, so this only guards against a malformed light. */
#define HL_FRAME_MAX_THETA 1.5f

/* Sharp lights. A light is sharp when its filter, at a blocker as far
 * as tier 0's map is wide, is under HL_FRAME_SHARP_TEXELS texels of
 * half-width in a map of size R: tan(theta) R < 4 (a sun of 2 degrees
 * at R = 128: 1.3 texels; a sky light of 10 degrees: 22). Such a filter
 * leaves the shadow's edge to the texels, so their size and phase are
 * the error; a wide light's filter spans many texels, and finer ones
 * change little (DYNAMIC.md, section 6). Up to HL_FRAME_SHARP_MAX of
 * them, the strongest, are taken apart (hl_sharp_mode):
 *   rays: Embree occlusion rays from every receiver (sharp_rays.h), 5
 *     a receiver and 16 in a penumbra: no texels at all. The default
 *     with moments;
 *   maps: maps of R_sharp = HL_FRAME_SHARP_SCALE R (at most
 *     HL_CSM_R_MAX) in a second tier;
 *   off: they stay in tier 0. The default with CSM, the founding
 *     method as published. */
typedef enum hl_sharp_mode {
    HL_SHARP_DEFAULT = 0,
    HL_SHARP_RAYS = 1,
    HL_SHARP_MAPS = 2,
    HL_SHARP_OFF = 3
} hl_sharp_mode;
#define HL_FRAME_SHARP_TEXELS 4.0f
#define HL_FRAME_SHARP_MAX 4u
#define HL_FRAME_SHARP_SCALE 4u

/* A face of a body lies on a flat body's plane (a ground) when its
 * vertices are within this share of the scene's extent of it: 1e-4, as
 * shadow_map.c's HL_SHADOW_SIDE_TOL takes a body resting on the ground.
 * The ground's receivers under such faces (a solid's underside) get no
 * light (dyn_frame.c, contact_cover). */
#define HL_FRAME_CONTACT_TOL 1e-4

/* HL_FRAME_BIAS_TEXELS, HL_FRAME_BIAS_CAP and HL_FRAME_FLAT_BLOCKS, shared
 * with the kernels, are in hl_shared.h beside the formulas that use them
 * (hl_dyn_receiver, hl_dyn_flat_one). */

/* Receivers (summed over lights) whose visibility one call of
 * hl_csm_visibility_batch takes at most, beyond one light's: the host
 * arrays of a group (32 bytes a receiver, 64 MiB here) hold so many, and
 * a batch's lights go in as many groups as that takes. */
#define HL_FRAME_GROUP_RECEIVERS (1u << 21)

typedef struct hl_frame_settings {
    uint32_t R;           /* shadow map size; 0: HL_SHADOW_DEFAULT_R (128) */
    uint32_t R_sharp;     /* the sharp lights' map size with HL_SHARP_MAPS,
                             R..HL_CSM_R_MAX; 0: the default above */
    uint32_t M;           /* CSM order, 4..16; 0: HL_CSM_M_DEFAULT (16) */
    uint32_t Mb;          /* blocker-search order, 4..M; 0: M */
    uint64_t budget;      /* bytes for one batch's CSM; 0: HL_FRAME_DEFAULT_BUDGET */
    float min_share;      /* < 0: HL_FRAME_MIN_SHARE; 0: shadow every light */
    hl_shadow_method method; /* HL_SHADOW_RASTER by default */
    hl_shadow_rep shadow;    /* the filterable representation; 0: HL_FRAME_DEFAULT_SHADOW */
    hl_sharp_mode sharp;     /* 0: maps where R_sharp > R is given, else rays
                                with moments and off with CSM */
} hl_frame_settings;

/* Seconds per stage of the last frame (lights are given: the split is
 * the caller's) and what was skipped. */
typedef struct hl_frame_stats {
    uint32_t receivers;         /* vertices of all bodies */
    uint32_t lights;            /* split->count */
    uint32_t shadowed;          /* lights that got a shadow map */
    uint32_t skipped_horizon;   /* E_k = 0 on every receiver */
    uint32_t skipped_negligible;/* below min_share: shaded with V = 1 */
    uint32_t batches, batch_lights; /* batches run, lights a batch holds (tier 0) */
    uint32_t R, R_sharp;        /* the map sizes (R_sharp 0: one size) */
    hl_sharp_mode sharp_mode;   /* rays, maps or off (never the default) */
    uint32_t sharp;             /* shadowed lights taken by rays or maps of R_sharp */
    uint64_t sharp_rays;        /* rays cast for them (0 when kept) */
    uint32_t covered;           /* receivers of a flat body under another
                                   body's contact faces: dark */
    uint32_t enclosed;          /* receivers inside their body's own closed
                                   parts (enclosed.h): dark */
    uint32_t maps_kept;         /* shadowed lights whose shadows were the last
                                   frame's, not made again: maps and tables
                                   (per size, 0 or all its lights:
                                   hl_frame_render), or the sharp lights'
                                   traced visibility (all or none) */
    double t_irradiance;        /* E_k and ambient at every receiver */
    double t_shadow_maps;       /* set_transform and rendering */
    double t_csm_build, t_csm_eval, t_shading;
    double t_sharp_rays;        /* the sharp lights' rays and their sums */
    double t_total;
} hl_frame_stats;

typedef struct hl_frame_state hl_frame_state;

/* Prepares the shadow maps (a copy of the objects' meshes) and the CSM
 * module for up to `max_lights` lights per frame (the batch is the
 * smaller of that and what the budget holds). Fails with a message on
 * bad settings (R outside HL_CSM_R_MIN..HL_CSM_R_MAX or not a multiple of
 * HL_CSM_SCAN_LANES, M or Mb out of range, max_lights 0) or objects the
 * shadow maps refuse. */
hl_result hl_frame_state_create(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, uint32_t max_lights,
                                const hl_frame_settings *settings, hl_frame_state **out);
void hl_frame_state_destroy(hl_frame_state *st);

/* One frame: objects are the same bodies as at create (same counts and
 * meshes; only their xf may change: a changed xf costs a set_transform),
 * albedo[b] 3 per vertex of body b, split's kept lights (count <= the
 * max_lights of create). rgb[b] gets 3 floats per vertex of body b,
 * linear, >= 0. stats may be NULL. The last frame's shadow maps and
 * their tables are used again where they still hold: one batch, the
 * same split, lights and directions, and no body they draw moved (a
 * flat body left out of them may have: stats->maps_kept); the sharp
 * lights' traced visibility where the split, lights and directions are
 * the same and no body at all moved. */
hl_result hl_frame_render(hl_frame_state *st, const hl_dyn_object *objects, uint32_t nobj, const float *const *albedo,
                          const hl_light_split *split, float *const *rgb, hl_frame_stats *stats);

/* Body positions and normals to world space (xf: dynamic.h's layout);
 * normals renormalised, a missing normal array gives +Y. */
void hl_frame_to_world(const hl_dyn_object *o, float *pos, float *nrm);

#endif
