/* area_lights.h - the environment split into area lights (docs: DYNAMIC.md
 * sections 1 and 2): the map resampled onto a cube, a greedy split of each
 * face into rectangles, the K strongest kept as lights and the rest folded
 * into one unshadowed spherical-harmonic term, and the irradiance of each.
 * Plain C on the host, no kernel: it runs once per environment or rotation.
 * Depends on: dynamic.h (hl_area_light), haarlight.h (hl_env), core.
 */
#ifndef HL_AREA_LIGHTS_H
#define HL_AREA_LIGHTS_H

#include <stdint.h>

#include "dynamic.h"
#include "haarlight.h"

/* Cube face resolution F. 32: the 2008 paper split small cube maps; at 32
 * a texel spans about 3.6 degrees at a face's centre and 1.7 at its
 * corners, so a sun (0.5 degrees) fits in one or two, and the greedy split
 * of 6 x 32^2 texels takes under a millisecond (the resampling of a
 * 1024 x 512 map about 40 ms). 2..256: below 2 a face has no inside; at
 * 256 a texel (0.45 degrees at most) is near the pixels of a 1024 x 512
 * map (0.35 degrees), so finer faces add no detail from such maps. */
#define HL_LIGHTS_DEFAULT_FACE 32u
#define HL_LIGHTS_MIN_FACE 2u
#define HL_LIGHTS_MAX_FACE 256u
/* Split threshold t for HL_SPLIT_OF_MAP (a ring is added while it brings
 * more than t of the map's energy): 1e-3. On the eight shared maps at
 * F = 32, 3e-3 and above leave most of the energy in thousands of
 * one-texel lights (K = 32 folds 10-93% of it); 3e-4 and below fold
 * 0-2% but merge still more into face-sized lights (city.exr: 38 lights
 * at 3e-4, 6 at 1e-4, one a face); 1e-3 puts 90% of the energy in 4-6
 * lights (110 for sunset.exr) and K = 32 folds 2.5-12%. Its large lights
 * are still whole faces (city.exr: the +Y face, 57% of the energy, with
 * the sun in it). */
#define HL_LIGHTS_DEFAULT_THRESHOLD 1e-3f
/* t for HL_SPLIT_OF_LIGHT (a ring is added while it brings more than t of
 * the light's energy so far): 0.1, an even sky grows about 2 / t = 20
 * rings, past a face. On the eight shared maps at F = 32 it makes 53-126
 * lights, 90% of the energy in 5-23 of them, K = 32 folds 0.6-4.3%;
 * city.exr's sun is a one-texel light with 24% of the energy. 0.2 makes
 * 148-243 lights with K = 32 folding up to 19%; 0.05 makes 28-80 larger
 * lights. */
#define HL_LIGHTS_DEFAULT_THRESHOLD_OF_LIGHT 0.1f
/* Lights kept K (0: all). 32: DYNAMIC.md section 4 costs the shadow maps
 * at K = 32; every kept light costs a shadow map a frame. */
#define HL_LIGHTS_DEFAULT_KEEP 32

/* What a ring's energy E_delta is measured against when a light grows.
 * HL_SPLIT_OF_MAP: E_delta / E_map > t, the map's total energy, as
 * DYNAMIC.md section 1 says. Since a ring grows with the light, a ring
 * that passes is mostly followed by larger ones that pass, so on real maps
 * the lights come out as whole faces plus one-texel lights (a sun and its
 * glow inside a face-sized light; HL_LIGHTS_DEFAULT_THRESHOLD's numbers).
 * HL_SPLIT_OF_LIGHT: E_delta / E_light > t, the light's energy so far: a
 * sun stops at its glow's edge, an even sky grows about 2 / t rings. */
typedef enum hl_split_rule { HL_SPLIT_OF_MAP = 0, HL_SPLIT_OF_LIGHT = 1 } hl_split_rule;

typedef struct hl_light_split_params {
    uint32_t face_res;  /* F, HL_LIGHTS_MIN_FACE..HL_LIGHTS_MAX_FACE */
    float threshold;    /* t, --split-threshold, 0 < t < 1 */
    hl_split_rule rule; /* HL_SPLIT_OF_MAP by default */
    int32_t lights;     /* K, --lights, >= 0; 0: keep every light */
    float rotate_deg;   /* the map turned about +Y as relight's --rotate */
} hl_light_split_params;

/* The defaults above: HL_SPLIT_OF_LIGHT at its threshold (the map-relative
 * rule leaves a sun inside a face-sized light), K = 32, rotation 0. */
void hl_light_split_defaults(hl_light_split_params *p);

typedef struct hl_light_split_stats {
    double total_energy[3];   /* the map's energy (radiance x solid angle) */
    uint32_t lights_before;   /* lights the split made */
    uint32_t folded;          /* of them, folded into the SH term */
    double folded_share;      /* folded luminance energy / total */
    double folded_energy[3];
    uint32_t texels_per_face; /* F^2 */
    uint32_t subsamples;      /* S: each map pixel was cut into S x S */
    double seconds;           /* wall time of hl_area_lights_split */
} hl_light_split_stats;

/* Cube texel t = face F^2 + row F + column (OpenGL face order, rows and
 * columns as geom.c's hl_cube_face_dir: s = 2 (col + 0.5) / F - 1,
 * t = 2 (row + 0.5) / F - 1). */
typedef struct hl_light_split {
    uint32_t F;
    uint32_t total;         /* lights the split made */
    uint32_t count;         /* lights kept: lights[0..count-1] */
    hl_area_light *lights;  /* total, by luminance of energy, strongest
                               first; lights[count..total-1] are folded */
    float ambient_sh[9][3]; /* the folded radiance's SH9 projection, RGB
                               (basis order: see hl_light_sh9) */
    /* per texel (6 F^2): energy (3), moment (9: per channel the integral
       of L(w) w dw over the texel), radiance (3: energy / texel_omega),
       centre direction (3, unit), owner (index into lights) */
    float *texel_energy, *texel_moment, *texel_radiance, *texel_dir;
    uint32_t *owner;
    double *texel_omega;    /* F^2, one face (all six are alike) */
    double *row_moment;     /* 6 F rows of F + 1: prefix sums of the
                               moments (9) along each face row */
    hl_light_split_stats stats;
    /* unique per split made in this process: a new split may reuse a
       freed one's address, so what caches a split's tables keys on this */
    uint64_t serial;
} hl_light_split;

/* Splits env (finite, >= 0; others refused with HL_ERR_INVALID_ARGUMENT)
 * into lights; *out is NULL on failure. Errors name the option
 * (--lights, --split-threshold, --rotate) where a parameter is at fault. */
hl_result hl_area_lights_split(hl_context *ctx, const hl_env *env, const hl_light_split_params *p,
                               hl_light_split **out);
void hl_light_split_destroy(hl_light_split *s);

/* Irradiance of light k (any of the total: k < s->total) on unit normal n: n . evec
 * where the whole rectangle is above n's horizon (n . dir >= sin extent),
 * 0 where all of it is below, else the texel sum, row by row: the horizon
 * cuts a face along a straight line, so each row's texels wholly above it
 * are one run, summed from row_moment, and only the few it cuts are
 * summed one by one. */
void hl_area_light_irradiance(const hl_light_split *s, uint32_t k, const float n[3], float rgb[3]);
/* Reference: the sum over the light's texels of max(0, n . moment). */
void hl_area_light_irradiance_ref(const hl_light_split *s, uint32_t k, const float n[3], float rgb[3]);
/* Irradiance of the folded lights from the SH9 term (Ramamoorthi and
 * Hanrahan 2001: A0 = pi, A1 = 2pi/3, A2 = pi/4). */
void hl_light_split_ambient(const hl_light_split *s, const float n[3], float rgb[3]);
/* Reference: the sum over folded texels of energy max(0, n . centre
 * direction), the discrete light the SH9 term projects. */
void hl_light_split_ambient_ref(const hl_light_split *s, const float n[3], float rgb[3]);

/* The 9 real SH basis functions at unit w: Y00; Y1-1 (y), Y10 (z),
 * Y11 (x); Y2-2 (xy), Y2-1 (yz), Y20 (3z^2 - 1), Y21 (xz), Y22 (x^2 - y^2). */
void hl_light_sh9(const double w[3], double y[9]);

#endif
