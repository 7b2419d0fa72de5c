/* irradiance.h - the dynamic method's per-vertex irradiance on the device
 * (DYNAMIC.md section 2): every kept light's E_k(n) and the folded lights'
 * SH9 ambient at each receiver normal, as area_lights.c's
 * hl_area_light_irradiance and hl_light_split_ambient compute them on the
 * host, in float (kernels/dynamic/dyn_irradiance.cl; twin
 * host/src/dynamic/twins/dyn_irradiance.c, run on the context's threads on
 * the reference backend).
 *
 * A split's lights are packed once into tables (per light a block of
 * floats and one of uints; the rectangle's texel moments, the prefix and
 * suffix sums of its rows and of its row totals, by rows and again by
 * columns; the ambient as one quadratic a channel)
 * and kept on the device until the next split replaces them.
 * Depends on: area_lights.h (hl_light_split), hl_internal.h (core).
 */
#ifndef HL_DYN_IRRADIANCE_H
#define HL_DYN_IRRADIANCE_H

#include <stddef.h>
#include <stdint.h>

#include "area_lights.h"
#include "hl_internal.h"

/* Floats of one light's block (the kernel's HL_DYN_IRR_LF): dir (0..2),
 * sin extent or 2 past a hemisphere (3), evec channel-major (4..12), the
 * face's origin (13..15), d/ds (16..18), d/dt (19..21) (face_point(s, t)
 * = o + s ds + t dt, OpenGL face order), 2 / F (22), 0 (23). */
#define HL_DYN_IRR_LF 24u
/* Uints of one light's block (HL_DYN_IRR_LU): two views of the light's
 * rectangle (HL_DYN_IRR_VIEW uints each), by rows (the face's rows y0..y1,
 * columns x0..x1) then by columns (rows x0..x1, columns y0..y1), each:
 * c0 c1 (its columns), r0 r1 (its rows), its first texel in mom (row by
 * row), its first row entry in pre, its first row-total entry in pre, 0. */
#define HL_DYN_IRR_LU 16u
#define HL_DYN_IRR_VIEW 8u
/* Floats of one entry of pre: 9 moment sums, each a double sum rounded
 * once. Per row of a view w + 1 prefix sums then w + 1 suffix sums
 * (w = c1 - c0); per view 2 (h + 1) sums of the row totals likewise. */
#define HL_DYN_IRR_PRE 9u
/* Receivers a reference-backend thread takes at a time: 256 normals x
 * 32 lights is about 1 ms of work, enough to make the counter's traffic
 * negligible, small enough that 11k receivers (43 chunks) spread evenly
 * over the threads. */
#define HL_DYN_IRR_REF_CHUNK 256u
/* Work-group width of the light kernel along the receivers (its second
 * dimension is the light, so a group reads one light's tables): 64. On
 * PoCL (2 cores, city.exr, 11k normals x 32 lights, the kernel before its
 * rows were split into views) widths 16, 64, 256 and a NULL local size
 * were within noise (CPU 53-54 ms); one work-item a receiver looping over
 * the lights took 57 ms at width 64 and 69 ms at 16. The global size is
 * rounded up to a multiple (a prime N would otherwise get groups of 1). */
#define HL_DYN_IRR_WG 64u

/* The packed tables of one split (host copies; the device holds the same). */
typedef struct hl_dyn_irr_tables {
    uint32_t K, F;       /* kept lights, cube face resolution */
    size_t texels;       /* 9 floats each in mom */
    size_t entries;      /* HL_DYN_IRR_PRE floats each in pre */
    float *lf;           /* K HL_DYN_IRR_LF */
    uint32_t *lu;        /* K HL_DYN_IRR_LU */
    float *mom, *pre;
    /* per channel c, sh[9 c ..]: K0, q_x, q_y, q_z, q_xy, q_yz, q_zz,
       q_xz, q_d: E_c(n) = K0 + q_x x + q_y y + q_z z + q_xy xy + q_yz yz
       + q_zz z^2 + q_xz xz + q_d (x^2 - y^2), in that order */
    float sh[27];
} hl_dyn_irr_tables;

typedef struct hl_dyn_irr hl_dyn_irr;

/* A module for split's kept lights (split->count of them, 0 allowed: the
 * ambient alone). The split is read now and not kept. */
hl_result hl_dyn_irr_create(hl_context *ctx, const hl_light_split *split, hl_dyn_irr **out);
/* Replaces the tables with a new split's (after hl_dynamic_set_env). On
 * failure the module holds no lights until a set_split succeeds. */
hl_result hl_dyn_irr_set_split(hl_dyn_irr *m, const hl_light_split *split);
/* Irradiance at N receivers (normals: 3 floats each, unit, finite):
 *   E: K x N x 3, light-major (E[(k N + v) 3 + c]), K = the split's count;
 *      may be NULL only when K = 0;
 *   ambient: N x 3, the folded lights' SH9 irradiance (not clamped: SH9
 *      rings slightly below 0 opposite a strong folded light, as the
 *      host's); NULL: not computed;
 *   any: K bytes, 1 where some receiver gets light from light k (E > 0 in
 *      a channel), else 0; NULL: not reported.
 * N = 0 is allowed (any all 0). A normal with a non-finite component is
 * refused (HL_ERR_INVALID_ARGUMENT naming the receiver). */
hl_result hl_dyn_irr_run(hl_dyn_irr *m, const float *normals, uint32_t N, float *E, float *ambient, uint8_t *any);
/* On an OpenCL context: hl_dyn_irr_run with E and the ambient both
 * computed and left in device memory (hl_dyn_irr_device_bufs: cl_mems,
 * the layouts above, valid until the next run; normals: the run's
 * normals as uploaded, 3 floats each, may be NULL), any read back. */
hl_result hl_dyn_irr_run_kept(hl_dyn_irr *m, const float *normals, uint32_t N, uint8_t *any);
void hl_dyn_irr_device_bufs(const hl_dyn_irr *m, void **E, void **ambient, void **normals);
/* Seconds of the last run (0 for N = 0): the kernels alone (the twins on the
 * reference backend), and all of it with the transfers and checks. */
void hl_dyn_irr_times(const hl_dyn_irr *m, double *compute, double *total);
/* The packed tables (for the tests): valid until the next set_split. */
const hl_dyn_irr_tables *hl_dyn_irr_get_tables(const hl_dyn_irr *m);
void hl_dyn_irr_destroy(hl_dyn_irr *m);

/* ---- twins (kernels/dynamic/dyn_irradiance.cl) ---- */

/* hl_dyn_irr_lights: light with blocks lf, lu at normal n; returns 1 when
 * some channel is above 0. A normal with a non-finite component gets 0
 * (the host's hl_area_light_irradiance crashes at a NaN normal and gives
 * Inf at some Inf normals; hl_dyn_irr_run refuses them). */
int hl_ref_dyn_irr_light(const float *lf, const uint32_t *lu, const float *mom, const float *pre, const float n[3],
                         float rgb[3]);
/* hl_dyn_irr_ambient: the quadratic of sh (27) at n (NaN for NaN, as the
 * host's hl_light_split_ambient). */
void hl_ref_dyn_irr_ambient(const float *sh, const float n[3], float rgb[3]);

#endif
