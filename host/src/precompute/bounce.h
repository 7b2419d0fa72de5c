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

/* Rows as the gather reads them: vertex v's terms are slot[e], val[e] for
 * e in [start[v], start[v + 1]), slots ascending. */
typedef struct hl_bounce_src {
    uint32_t V;
    uint32_t *start;
    uint32_t *slot;
    float *val;
} hl_bounce_src;

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
