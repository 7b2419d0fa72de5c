/* cube.h - Haar wavelets over the six faces of a cube, as Ng, Ramamoorthi
 * and Hanrahan (2003) lay out the sphere: the face texels of a cube of
 * side Cq (a power of two), each face's orthonormal non-standard 2D Haar
 * transform, the transport of a vertex regrouped from the visibility cube
 * onto these texels, and each texel's mean radiance taken from the
 * environment's cells.
 *
 * Texel q = face Cq^2 + row Cq + col, the faces in OpenGL order (+X -X +Y
 * -Y +Z -Z, geom.h's hl_cube_face_dir; col follows sc, row follows tc).
 * Coefficients in the same order per face, in the Mallat layout: (0, 0)
 * the face's scaling coefficient, then the details as the paraboloid's
 * (geom.h's hl_geom_support gives a coefficient's support). Plain C, the
 * twin of a device pipeline to come: no state, nothing allocated but the
 * tables.
 *
 * Depends on maps/ (geom.h: the visibility cube and its footprint table;
 * twins.h: the environment taps' sum), sh/ (sh.h: Gauss-Legendre nodes)
 * and core.
 */
#ifndef HL_CUBE_H
#define HL_CUBE_H

#include "geom.h"

/* The tables of one face side Cq on one visibility cube (side C, a
 * multiple of Cq) and one cell grid (wc x hc equirectangular cells, as
 * lighting.h's hl_env_to_cells makes them). */
typedef struct hl_cube_tables {
    uint32_t Cq, C, ntex;   /* ntex = 6 Cq^2 */
    double *omega;          /* ntex: each texel's exact solid angle */
    float *area;            /* ntex, coefficient order: the solid angle of
                               each wavelet's support (area-weighted selection) */
    uint32_t wc, hc;
    uint32_t *tap_start;    /* ntex + 1: CSR rows of taps by texel */
    hl_env_tap *taps;       /* weights: each cell's share of the texel */
    double *tap_total;      /* ntex: the solid angle the taps found (before
                               normalising), for the tests */
    uint32_t ntaps;
} hl_cube_tables;

/* Cq: a power of two, 2 to 512, dividing C. */
/* A cube-face file's lighting, the twin of its device stages: each face
 * texel's mean radiance from the environment's cells turned by (s0, f)
 * (three planes of 6 Cq^2 into Lp, destroyed), then the faces' Haar into
 * Lw (three planes of ncoef, zero past 6 Cq^2). */
void hl_cube_lighting_haar(const hl_cube_tables *ct, const float *cells, uint32_t s0, float f, uint32_t ncoef,
                           float *Lp, float *Lw);

/* The default cube side for paraboloids of side N and visibility cubes
 * of side C: the largest power of two from 2 up to N / 2 (so 6 C'^2 fits
 * the 2 N^2 slots) that divides C; 0 when there is none. */
uint32_t hl_cube_default_side(uint32_t N, uint32_t C);

/* The solid angle of each face wavelet's support (a square of its face),
 * in coefficient order: 6 Cq^2 floats into area. */
void hl_cube_support_areas(uint32_t Cq, float *area);
hl_result hl_cube_tables_create(hl_context *ctx, uint32_t Cq, uint32_t C, uint32_t wc, uint32_t hc,
                                hl_cube_tables **out);
void hl_cube_tables_destroy(hl_cube_tables *ct);

/* Exact solid angle of the rectangle [u0, u1] x [v0, v1] of a face at
 * distance 1 from the centre (face coordinates in [-1, 1]). */
double hl_cube_rect_omega(double u0, double u1, double v0, double v1);

/* The forward transform of all six faces of T (6 Cq^2 texels, destroyed:
 * it works in place) into coef. Orthonormal: a 2 x 2 step of a, b (top
 * row) and c, d gives (a+b+c+d)/2 to the coarser level and the details
 * H = (a-b+c-d)/2, V = (a+b-c-d)/2, D = (a-b-c+d)/2, as the paraboloid's. */
void hl_cube_haar(uint32_t Cq, float *T, float *coef);
/* Its inverse: coef (destroyed) back to the texels T. */
void hl_cube_haar_inverse(uint32_t Cq, float *coef, float *T);

/* One vertex's transport on the face texels: T[q] = scale * the sum over
 * the visibility texels c inside q and over the footprint-table entries e
 * of c (g->p2c) of vis[c] max(0, n . m_e). The same products as
 * hl_ref_cube2para's, grouped by cube texel instead of by paraboloid texel,
 * so the rows of both add up to the same total. g->C must be a multiple
 * of Cq. */
void hl_cube_rows(const hl_geom *g, uint32_t Cq, const uint8_t *vis, float scale, const float n[3], float *T);

/* The visibility cube's texels (side C) by Q x Q Gauss-Legendre points
 * each, in face coordinates with the solid-angle factor (1 + u^2 +
 * v^2)^(-3/2): per point its direction times its solid angle (3 floats). */
typedef struct hl_cube_quad {
    uint32_t C, Q;
    float *m;   /* 6 C^2 Q^2 x 3 */
} hl_cube_quad;
hl_result hl_cube_quad_create(hl_context *ctx, uint32_t C, uint32_t Q, hl_cube_quad **out);
void hl_cube_quad_destroy(hl_cube_quad *q);

/* One vertex's transport on the face texels, each visibility texel's
 * clamped cosine integrated over its own footprint: T[q] = scale * the sum
 * over the visibility texels c inside q of vis[c] times the sum over c's
 * points of max(0, n . w dw). Unlike hl_cube_rows, whose texels take the
 * footprint table's pieces (grouped by the centres of 8 x 8 sub-samples
 * of each paraboloid texel, so a cube texel's pieces miss its own moment
 * by 11% rms at C = 64), every texel here gets its own footprint. */
void hl_cube_rows_exact(const hl_cube_quad *cq, uint32_t Cq, const uint8_t *vis, float scale, const float n[3],
                        float *T);

/* Each texel's mean radiance: R, G, B planes of ntex floats from cells (4
 * floats per cell, wc x hc), by the taps. */
void hl_cube_lighting(const hl_cube_tables *ct, const float *cells, float *L);

#endif
