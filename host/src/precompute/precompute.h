/* precompute.h - internal pieces of the precompute that `check`, the
 * benchmark and the tests reuse. */
#ifndef HL_PRECOMPUTE_H
#define HL_PRECOMPUTE_H

#include "cl_backend.h"
#include "geom.h"

/* Defaults (documented in haarlight.h and the CLI's --help). */
#define HL_DEFAULT_N 64u
#define HL_DEFAULT_C 64u
#define HL_DEFAULT_EPS 1e-5f
#define HL_DEFAULT_QUANT HL_QUANT_SQRT8
#define HL_DEFAULT_CHUNK 1024u

/* Fills defaults into d and checks every option; errors name the option. */
hl_result hl_precompute_resolve(hl_context *ctx, hl_precompute_desc *d);

/* Truncation parameters of a resolved descriptor. */
hl_trunc_params hl_precompute_trunc_params(const hl_precompute_desc *d);

/* Runs the four plain-C twins on `rows` rows of io (threads from ctx). */
hl_result hl_ref_rows(hl_context *ctx, const hl_geom *g, uint32_t rows, float vis_scale,
                      hl_trunc_params tp, uint32_t scheme, const hl_chunk_buf *io);

/* hl_ref_rows with the rows projected onto spherical harmonics of the
 * order (Y: hl_sh_matrix's, per solid angle) in Haar's place; Y NULL:
 * Haar. cube non-zero: cube-face Haar of that side instead (hl_cube_rows
 * and hl_cube_haar in the place of cube2para and Haar). */
hl_result hl_ref_rows_basis(hl_context *ctx, const hl_geom *g, const float *Y, uint32_t sh_order, uint32_t cube,
                            uint32_t rows, float vis_scale, hl_trunc_params tp, uint32_t scheme,
                            const hl_chunk_buf *io);

/* Allocates / frees host chunk buffers for max_rows rows. */
hl_result hl_chunk_buf_alloc(hl_context *ctx, const hl_geom *g, uint32_t max_rows, hl_chunk_buf *b);
void hl_chunk_buf_free(hl_chunk_buf *b);

#endif
