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
 * twins.h: the environment taps' sum) and core.
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

/* Each texel's mean radiance: R, G, B planes of ntex floats from cells (4
 * floats per cell, wc x hc), by the taps. */
void hl_cube_lighting(const hl_cube_tables *ct, const float *cells, float *L);

#endif
