/* dynamic.h - the types the dynamic method's stages hand each other
 * (Annen et al. 2008: the environment split into area lights, one
 * convolution shadow map per light, no precompute). docs/DYNAMIC.md has
 * the maths; each stage has its own header beside this one.
 *
 * Conventions: world space is the transport's (docs/CONVENTIONS.md, +Y
 * up); directions point from the scene towards the light.
 */
#ifndef HL_DYNAMIC_H
#define HL_DYNAMIC_H

#include <stdint.h>

/* One rigid body of a scene at one time: its mesh in its own coordinates
 * and the rigid transform to world, world = R p + t with xf row-major
 * 3x4 ({R00 R01 R02 t0, R10 ..., R20 ...}). Arrays are borrowed. */
typedef struct hl_dyn_object {
    const float *pos;     /* 3 per vertex, the object's own coordinates */
    const float *normal;  /* 3 per vertex, unit, or NULL */
    uint32_t nverts;
    const uint32_t *tri;  /* 3 per triangle */
    uint32_t ntris;
    float xf[12];
} hl_dyn_object;

/* One area light: a rectangle of one cube face of the environment. */
typedef struct hl_area_light {
    float dir[3];       /* unit, energy-weighted centroid direction */
    float extent;       /* half-angle (radians) of the cone about dir that
                           holds the whole rectangle */
    float spread;       /* half-angle of the uniform square light with the
                           same angular spread of energy about dir:
                           atan(sqrt(3 (1 - |m| / E))), m the luminance
                           moment, E the luminance energy. What the shadow
                           filter's width uses: a light's energy gathers
                           near its brightest texel, and a sun is much
                           smaller than the texel that holds it */
    float omega;        /* solid angle */
    float energy[3];    /* RGB radiance times solid angle, summed */
    float radiance[3];  /* energy / omega */
    /* per channel c, sum over the texels of L_c(w) Omega(w) w: the
       irradiance on a normal n that sees all of the light is n . evec[c] */
    float evec[3][3];
    uint32_t face, x0, y0, x1, y1; /* the rectangle: texels x0..x1-1,
                                      y0..y1-1 of face (OpenGL order) */
} hl_area_light;

/* An orthographic shadow map's frame for a distant light: texel (i, j)
 * (column i, row j) has its centre at origin + ((i + 0.5) / R) width right
 * + ((j + 0.5) / R) height up; a point p has depth
 * d = dot(p - origin, toward_far) / depth_range in [0, 1], with
 * toward_far = -light direction (0: nearest the light). Depth 1 (or more)
 * in a map means nothing blocks there. */
typedef struct hl_shadow_frame {
    float origin[3];   /* the corner of texel (0, 0), on the near plane */
    float right[3], up[3], toward_far[3]; /* orthonormal */
    float width, height, depth_range;     /* world units */
    uint32_t R;        /* R x R texels */
    /* Bodies 0..31 left out of this map (bit b: body b): flat bodies that
     * cannot cast a shadow for this light (shadow_map.h,
     * hl_shadow_maps_skip_planes). They are still receivers. 0: all drawn. */
    uint32_t skip_mask;
} hl_shadow_frame;

/* A texel's size in normalised depth: max(width, height) / R /
 * depth_range (the receiver-plane bias and the moments' per-texel floor
 * are counted in it). */
static inline float hl_shadow_frame_texel(const hl_shadow_frame *f)
{
    return (f->width > f->height ? f->width : f->height) / (float)f->R / f->depth_range;
}

#endif
