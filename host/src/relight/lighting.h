/* lighting.h - tables for turning an environment into paraboloid lighting,
 * and the environment resampling (light_tables.c). Depends only on N (and
 * the cell grid that N implies); build once per transport. Also the
 * relighter's calls beyond the public ones (lighting.c).
 */
#ifndef HL_LIGHTING_H
#define HL_LIGHTING_H

#include "geom.h"

typedef struct hl_light_geom {
    uint32_t N, ncoef, nblocks;
    uint32_t wc, hc;        /* cell grid: wc x hc equirectangular cells */
    double *cell_omega;     /* hc: solid angle of one cell of each row */
    uint32_t *tap_start;    /* ncoef + 1: CSR rows of taps by texel */
    hl_env_tap *taps;
    uint32_t ntaps;
    float *area;            /* ncoef, slot order: solid angle of each
                               wavelet's support (area-weighted selection) */
} hl_light_geom;

hl_result hl_light_geom_create(hl_context *ctx, const hl_geom *g, hl_light_geom **out);
/* The selection weights of a scheme (HL_SELECT_AREA, _UNWEIGHTED or
 * _TRANSPORT: the mean |T_i| over t's vertices) into w (lg->ncoef floats). */
hl_result hl_selection_weights(hl_context *ctx, const hl_transport *t, const hl_light_geom *lg, uint32_t scheme,
                               float *w);
void hl_light_geom_destroy(hl_light_geom *lg);

/* Area-weighted box resampling of env onto the wc x hc cell grid (4 floats
 * per cell, the fourth 0): the integral of radiance over the sphere is
 * kept exactly, whatever the two resolutions. */
hl_result hl_env_to_cells(hl_context *ctx, const hl_env *env, uint32_t wc, uint32_t hc, float **cells4);

/* Rotation to a cell offset: s0 whole cells plus a fraction f. */
void hl_rotation_to_shift(float rotate_deg, uint32_t wc, uint32_t *s0, float *f);

/* The capture point of surroundings: the centre of the bounding box of
 * the object's vertices (those before the ground; all without one). */
void hl_object_centre(const hl_mesh *m, float c[3]);

/* hl_relighter_run with the colours left in the relighter: *rgba points at
 * 4 floats per vertex (the fourth: the lowest channel before the clamp at
 * zero, or 0), valid until the next run, anything else that runs on
 * the relighter's device (the bench probes) or destroy: on the OpenCL
 * backend the device's own colour buffer, mapped for reading.
 * Saves the copy to 3 floats where the caller wants 4 (the viewer's GL
 * buffer). */
hl_result hl_relighter_run4(hl_relighter *r, const hl_relight_desc *desc, const float **rgba, hl_relight_stats *stats);

/* hl_relighter_run with the colours left on the device: 4 floats per
 * vertex (the fourth as in hl_relighter_run4) written into cl_out, a cl_mem of the relighter's
 * context (see hl_cl_light_run_into; gl: it wraps an OpenGL buffer, which
 * is acquired and released around the dot products). Nothing is copied to
 * the host. OpenCL backend only. */
hl_result hl_relighter_run_into(hl_relighter *r, const hl_relight_desc *desc, void *cl_out, int gl,
                                hl_relight_stats *stats);

/* The relighter's device stages (NULL on the reference backend) and
 * tables, for the benchmark. */
struct hl_cl_light *hl_relighter_device(hl_relighter *r);
/* The relighters that do the work: r itself (returns 1), or with a row a
 * channel (hl_transport_info.channels 3) the three channels' (returns 3). */
uint32_t hl_relighter_planes(hl_relighter *r, hl_relighter **sub);
const hl_light_geom *hl_relighter_tables(const hl_relighter *r);

#endif
