/* geom.h - direction parameterisations and the tables derived from them.
 *
 * Dual-paraboloid maps (docs/CONVENTIONS.md), OpenGL-order cubemaps, the
 * cubemap-to-paraboloid footprint table and the Haar coefficient order.
 * An hl_geom depends only on (N, C); build it once and share it read-only.
 */
#ifndef HL_GEOM_H
#define HL_GEOM_H

#include "hl_internal.h"

typedef struct hl_geom {
    uint32_t N, C;
    uint32_t ncoef;   /* 2 N^2: texels of both maps = Haar coefficients */
    uint32_t nblocks; /* ceil(ncoef / 256) */
    uint32_t ncube;   /* 6 C^2 */
    float *cube_dirs; /* 4 per cube texel: unit centre direction, pad */
    float *omega;     /* ncoef: paraboloid texel solid angle (0 outside) */
    uint32_t *c2p_start;   /* ncoef + 1: rows by paraboloid texel */
    hl_c2p_entry *c2p;     /* nentries, index = cube texel */
    uint32_t *p2c_start;   /* ncube + 1: rows by cube texel */
    hl_c2p_entry *p2c;     /* nentries, index = paraboloid texel */
    uint32_t nentries;
    uint32_t *slot_of_mallat; /* N^2: Mallat-layout position -> slot in map */
} hl_geom;

hl_result hl_geom_create(hl_context *ctx, uint32_t N, uint32_t C, hl_geom **out);
void hl_geom_destroy(hl_geom *g);

/* Paraboloid texel (col, row) of map (0: y >= 0, 1: y < 0) to the unit
 * direction through its centre. */
void hl_para_texel_dir(uint32_t N, int map, uint32_t col, uint32_t row, float d[3]);
/* Direction to paraboloid coordinates (s, t) in [-1, 1]^2 and map. */
void hl_dir_to_para(const float d[3], int *map, float *s, float *t);
/* Exact solid angle of the part of [s0,s1]x[t0,t1] inside the unit disc. */
double hl_para_rect_omega(double s0, double s1, double t0, double t1);

/* Cube texel (OpenGL face order +X -X +Y -Y +Z -Z) at face coordinates
 * (sc, tc) in [-1, 1] to an unnormalised direction, and back. */
void hl_cube_face_dir(int face, float sc, float tc, float d[3]);
uint32_t hl_dir_to_cube(const float d[3], uint32_t C);

/* Support of the Haar coefficient at Mallat position (row, col): the
 * texels [r0, r0 + w) x [c0, c0 + w) of its map. */
void hl_geom_support(uint32_t N, uint32_t row, uint32_t col, uint32_t *r0, uint32_t *c0, uint32_t *w);

/* Slot (0 .. 2N^2-1) of the Haar coefficient at Mallat position (row, col)
 * of map m. Slots put each 16x16 tile's details and one coarse coefficient
 * in one 256-block, so blocks are spatially compact. */
static inline uint32_t hl_geom_slot(const hl_geom *g, int map, uint32_t row, uint32_t col)
{
    return (uint32_t)map * g->N * g->N + g->slot_of_mallat[row * g->N + col];
}

#endif
