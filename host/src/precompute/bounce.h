/* bounce.h - diffuse interreflection baked into the transport
 * (precompute --bounces B, docs/BOUNCES.md).
 *
 * With T_0 the direct rows (visibility times cosine over pi, as the
 * precompute makes them), bounce b gathers at each vertex x
 *   T_b(x) = (1 / K) sum_k rho(y_k) T_(b-1)(y_k)
 * over K cosine-weighted directions of x's hemisphere, y_k the first
 * surface hit (T and rho interpolated over the hit triangle from its
 * corners; a miss or a back face adds nothing): the Monte Carlo estimate
 * of the integral of (rho(y) / pi) T_(b-1)(y) max(0, n . w) dw, whose
 * cosine over pi is the sampling density. The file's rows are then
 * T_0 + T_1 + ... + T_B, truncated and quantised as the direct rows are,
 * so relighting is unchanged. Where every albedo is grey the file has a
 * row a vertex; where some surface is coloured, a row a vertex and
 * channel (hl_transport_info.channels 3): each channel's bounces gathered
 * with that channel's rho, from the same rays, into a plane of rows, and
 * the relighter dots each channel's lighting with its own plane.
 */
#ifndef HL_BOUNCE_H
#define HL_BOUNCE_H

#include "hl_internal.h"
#include "rays.h"

/* A sample that hit nothing (or a surface from behind). */
#define HL_BOUNCE_MISS 0xffffffffu

/* Rows as the gather reads them: vertex v's terms are e in [start[v],
 * start[v + 1]), slots ascending: slot16[e] (slot32[e] where ncoef is
 * above 65536; the other NULL) and the value scale[v] x val[e], val an
 * IEEE binary16, zero or normal, and scale[v] a power of two that puts
 * the row's largest term in [2^14, 2^15) (terms below 2^-28 of it are
 * zero). Four bytes a term instead of eight: the gather reads the rows of
 * every vertex, the phase's largest memory, and a binary16's relative
 * rounding (2^-11 at most) is far below the bounce's sampling noise and
 * the file's 8-bit codes (docs/BOUNCES.md). Normal binary16s alone, so
 * that the gather decodes them with a shift and one exact product
 * (hl_half_bits_to_float), no subnormals on either side. */
typedef struct hl_bounce_src {
    uint32_t V;
    uint32_t *start;
    uint16_t *slot16;
    uint32_t *slot32;
    uint16_t *val;
    float *scale;
} hl_bounce_src;

/* One row's n terms (slots ascending, values finite) into slot16 or
 * slot32 (whichever is not NULL) and half, and *scale its scale (a row
 * whose largest term is below 2^-100 is stored as zeros: its scale would
 * be a float subnormal, which a device may flush). */
void hl_bounce_encode(uint32_t n, const uint32_t *slot, const float *val, uint16_t *slot16, uint32_t *slot32,
                      uint16_t *half, float *scale);

/* The binary16 h (zero or normal) as a float, exactly: its bits moved
 * into a float's, which is 2^-112 of it, times 2^112 (the gather's
 * decoding, kernels/precompute/bounce.cl). */
static inline float hl_half_to_float(uint16_t h)
{
    union {
        uint32_t u;
        float f;
    } x = {((uint32_t)(h & 0x8000u) << 16) | ((uint32_t)(h & 0x7fffu) << 13)};
    return x.f * 0x1p112f;
}

/* The twin of kernels/precompute/bounce.cl: one vertex's T_b into out
 * (ncoef floats, overwritten) from its K samples (prim[k] the hit
 * triangle or HL_BOUNCE_MISS, uv[2 k ..] the barycentrics of its corners
 * 1 and 2), the triangles' corners (indices, 3 a triangle), the
 * vertices' albedo rho in the channel gathered and the rows of T_(b-1). */
void hl_ref_bounce_gather(const hl_bounce_src *src, const uint32_t *indices, const float *rho, const uint32_t *prim,
                          const float *uv, uint32_t K, uint32_t ncoef, float *out);

/* K cosine-weighted directions about vertex v's normal into dir (3 K
 * floats): stratified over the sqrt(K) x sqrt(K) grid where K is a
 * square, each jittered by a hash of key and the sample, so the rays
 * depend on nothing else. The precompute's key is v; bench's reference
 * mixes in the bounce, for rays of its own each bounce. */
void hl_bounce_dirs(const hl_mesh *m, uint32_t v, uint32_t key, uint32_t K, float *dir);

/* The bounce rays of count vertices, list[first + i] (list NULL: first +
 * i), K each (hl_bounce_dirs, keyed by the vertex ^ salt: 0 for the
 * precompute's), from the vertex's robust ray origin, traced with rt:
 * prim (HL_BOUNCE_MISS for a miss, or a surface hit from behind: its
 * interpolated normal along the ray), hu and hv the barycentrics of the
 * hit's corners 1 and 2, count K each; org and dir: 3 count K floats of
 * scratch (dir then holds the directions). */
hl_result hl_bounce_cast(hl_rt *rt, const hl_mesh *m, const uint32_t *list, uint32_t first, uint32_t count, uint32_t K,
                         uint32_t salt, float *org, float *dir, uint32_t *prim, float *hu, float *hv);

/* The rows a vertex a bounced file of m needs: 3 where some vertex's
 * albedo differs between channels, else 1. */
uint32_t hl_bounce_channels(const hl_mesh *m);

/* Refuses (HL_ERR_INVALID_ARGUMENT, naming the vertex and channel) a mesh
 * with an albedo outside [0, 1]: each bounce would add light. */
hl_result hl_bounce_check_albedo(hl_context *ctx, const hl_mesh *m);

/* The bounce phase: reads the direct transport at direct_path (made from
 * mesh with the same parameters: its mesh section must hold mesh's
 * positions, else HL_ERR_INVALID_ARGUMENT), gathers d->bounces bounces on ctx's
 * backend and writes T_0 + ... + T_B to out_path (atomically, its header
 * recording the bounces); *kept: the coefficients it holds. With
 * shard_count > 0, out_path is shard shard_index's file: the last bounce
 * of its vertices only (the bounces before it of every vertex), which
 * merge joins into the bytes of one run. Progress on stderr unless ctx is
 * quiet. */
hl_result hl_bounce_file(hl_context *ctx, const hl_precompute_desc *d, const hl_mesh *mesh, const char *direct_path,
                         uint32_t shard_index, uint32_t shard_count, const char *out_path, double *seconds,
                         uint64_t *kept);

#endif
