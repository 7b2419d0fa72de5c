/* twins.h - plain-C twins of the OpenCL kernels, one vertex at a time:
 * the `--device ref` backend.
 *
 * Each function carries the name of its kernel, and its file mirrors the
 * kernel's place (kernels/STAGE/NAME.cl -> host/src/STAGE/twins/NAME.c,
 * hl_ref_NAME) and computes the same result in the most direct way, so the
 * tests check the maths and not the scheduling. Thread safe: no state.
 * None allocates, so none can fail: the two that sort take their scratch
 * from the caller (hl_ref_key, one per slot), which can own it across rows
 * and report an allocation that fails.
 * It sits in maps/ because every twin takes the map geometry (geom.h),
 * and the stages that hold twins all build on maps/.
 */
#ifndef HL_TWINS_H
#define HL_TWINS_H

#include "geom.h"

/* Scratch of the sorting twins: one per coefficient slot (g->ncoef). */
typedef struct hl_ref_key { uint32_t key, slot; } hl_ref_key;

/* T[j] = scale * sum over table entries e of texel j of
 * vis[e.cube] * max(0, n . m_e); scale = 1 / (pi * supersample^2). */
void hl_ref_cube2para(const hl_geom *g, const uint8_t *vis, float scale,
                      const float n[3], float *T);

/* Orthonormal non-standard 2D Haar of both N x N maps of T (destroyed),
 * written to coef in slot order. Works in place in T. */
void hl_ref_haar(const hl_geom *g, float *T, float *coef);
/* The orthonormal non-standard Haar of one n x n map x (destroyed: the
 * averages are compacted in place) into o: coefficient k at o[slot[k]],
 * k in the Mallat layout, or at o[k] when slot is NULL. Twin of
 * hl_haar_square (hl_shared.h). */
void hl_ref_haar_square(float *x, float *o, const uint32_t *slot, uint32_t n);

/* Chooses the kept coefficients of one row (see hl_trunc_result).
 * scratch: g->ncoef entries, contents ignored and overwritten. */
hl_trunc_result hl_ref_truncate(const hl_geom *g, const float *coef,
                                hl_trunc_params p, hl_ref_key *scratch);

/* Quantises the kept coefficients and packs them: entries gets (index,
 * code) byte pairs by block, block_counts one count per block. Returns the
 * number of entries. */
uint32_t hl_ref_quantize(const hl_geom *g, const float *coef,
                         hl_trunc_result tr, uint32_t scheme, uint32_t vertex,
                         hl_row_quant *rq, uint16_t *block_counts, uint8_t *entries);

/* Row in (ncoef texels) projected onto spherical harmonics: out[k] =
 * sum_j in[j] Y[j stride + k] for k < nsh, summed over j in order; out's
 * other slots (nsh .. ncoef - 1) are zeroed. Y: hl_sh_matrix's. */
void hl_ref_sh_project_rows(const float *in, uint32_t ncoef, const float *Y, uint32_t stride, uint32_t nsh,
                            float *out);

/* Lighting texel j = sum over its taps of weight * the tap's cell blended
 * with its neighbour: c[k + s0] + f (c[k + s0 + 1] - c[k + s0]) (indices
 * modulo wc). cells: 4 floats per cell, wc per row. L: R, G, B
 * planes of ncoef. */
void hl_ref_env2para(const float *cells, uint32_t wc, const uint32_t *start,
                     const hl_env_tap *runs, uint32_t s0, float f, uint32_t ncoef, float *L);

/* Keeps the p.M lighting terms of highest priority (see select.cl):
 * out gets 4 floats per slot (zero where not kept), block_used one flag per
 * block (detail slots), kept_bits one bit per slot (ncoef / 32 words; ncoef
 * is a multiple of 32).
 * scratch: ncoef entries, contents ignored and overwritten. */
hl_select_result hl_ref_select(const float *L, uint32_t ncoef, const float *weight,
                               hl_select_params p, float *out, uint8_t *block_used,
                               uint32_t *kept_bits, uint32_t nblocks, hl_ref_key *scratch);

/* One vertex: sum over all its entries of dequantised T times light
 * (4 floats per slot), times albedo (3 floats). rgba: 4 floats: the
 * colour, each channel clamped at zero unless keep_negative, then the
 * lowest channel before the clamp (0 when none is negative). */
void hl_ref_relight(const uint8_t *entries, const uint16_t *block_counts, hl_row_quant rq,
                    uint32_t scheme, uint32_t vertex, uint32_t nblocks, const float *light,
                    const float *albedo, int keep_negative, float *rgba);

#endif
