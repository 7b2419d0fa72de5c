/* transport_layout.c - the shared layout code of transport files (.hlt):
 * header encoding and decoding, the checks that the writer applies to its
 * caller's data and the loader to a file's (parameters, mesh, rows), and
 * whole-buffer positioned reads and writes.
 *
 * Depends on: transport_layout.h (offsets, byte coding, CRC-32 by zlib's
 * crc32_z), hl_internal.h, libm, POSIX pread/pwrite.
 */
#define _POSIX_C_SOURCE 200809L /* pread, pwrite, O_CLOEXEC */
#define _FILE_OFFSET_BITS 64
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

#include "transport_layout.h"

/* ---------------------------------------------------------------- header */

void hl_tf_header_encode(const tf_header *h, const char *magic, uint32_t appended, uint8_t out[TF_HEADER_SIZE])
{
    const hl_transport_info *i = &h->info;
    memset(out, 0, TF_HEADER_SIZE);
    memcpy(out + H_MAGIC, magic, 8);
    if (appended) put_u32(out + H_APPENDED, appended);
    if (h->shard.count) {
        put_u32(out + H_SHARD_INDEX, h->shard.index);
        put_u32(out + H_SHARD_COUNT, h->shard.count);
        put_u32(out + H_SHARD_FIRST, h->shard.first);
        put_u32(out + H_SHARD_END, h->shard.end);
    }
    /* zero for Haar, so a Haar file keeps the bytes of files from before */
    put_u32(out + H_BASIS, i->basis);
    put_u32(out + H_SH_ORDER, i->sh_order);
    /* the channels in the high half: 0 for one row a vertex, so such a
       file keeps the bytes of files from before */
    put_u32(out + H_BOUNCES, i->bounces | (i->channels == 3 ? 3u << 16 : 0u));
    put_u32(out + H_VERSION, TF_VERSION);
    put_u32(out + H_HEADER_SIZE, TF_HEADER_SIZE);
    put_u32(out + H_N, i->N);
    put_u32(out + H_C, i->C);
    put_u32(out + H_SUPERSAMPLE, i->supersample);
    put_u32(out + H_RULE, i->rule);
    put_u32(out + H_K, i->K);
    put_u32(out + H_EPS, HL_AS_U32(i->eps));
    put_u32(out + H_QUANT, i->quant);
    put_u32(out + H_RAY_OFFSET, HL_AS_U32(i->ray_offset));
    put_u32(out + H_VERTEX_COUNT, i->vertex_count);
    put_u32(out + H_OBJECT_VERTEX_COUNT, i->object_vertex_count);
    put_u32(out + H_TRIANGLE_COUNT, i->triangle_count);
    put_u32(out + H_BLOCK_COUNT, i->block_count);
    put_u64(out + H_COEFFICIENTS_KEPT, i->coefficients_kept);
    put_u64(out + H_RAYS_CAST, i->rays_cast);
    put_u64(out + H_RAYS_CULLED, i->rays_culled);
    put_u64(out + H_FILE_SIZE, h->file_size);
    for (int s = 0; s < SEC_COUNT; s++) {
        put_u64(out + H_SECTIONS + 16 * s, h->sec[s].offset);
        put_u64(out + H_SECTIONS + 16 * s + 8, h->sec[s].size);
        put_u32(out + H_SECTION_CRCS + 4 * s, h->sec[s].crc);
    }
    put_u32(out + H_HEADER_CRC, crc_update(0, out, H_HEADER_CRC));
}

void hl_tf_header_decode(const uint8_t *in, tf_header *h)
{
    hl_transport_info *i = &h->info;
    memset(h, 0, sizeof *h);
    i->version = get_u32(in + H_VERSION);
    h->header_size = get_u32(in + H_HEADER_SIZE);
    i->N = get_u32(in + H_N);
    i->C = get_u32(in + H_C);
    i->supersample = get_u32(in + H_SUPERSAMPLE);
    i->rule = get_u32(in + H_RULE);
    i->K = get_u32(in + H_K);
    i->eps = HL_AS_F32(get_u32(in + H_EPS));
    i->quant = get_u32(in + H_QUANT);
    i->ray_offset = HL_AS_F32(get_u32(in + H_RAY_OFFSET));
    i->vertex_count = get_u32(in + H_VERTEX_COUNT);
    i->object_vertex_count = get_u32(in + H_OBJECT_VERTEX_COUNT);
    i->triangle_count = get_u32(in + H_TRIANGLE_COUNT);
    i->block_count = get_u32(in + H_BLOCK_COUNT);
    i->coefficients_kept = get_u64(in + H_COEFFICIENTS_KEPT);
    i->rays_cast = get_u64(in + H_RAYS_CAST);
    i->rays_culled = get_u64(in + H_RAYS_CULLED);
    h->file_size = get_u64(in + H_FILE_SIZE);
    for (int s = 0; s < SEC_COUNT; s++) {
        h->sec[s].offset = get_u64(in + H_SECTIONS + 16 * s);
        h->sec[s].size = get_u64(in + H_SECTIONS + 16 * s + 8);
        h->sec[s].crc = get_u32(in + H_SECTION_CRCS + 4 * s);
    }
    h->shard.index = get_u32(in + H_SHARD_INDEX);
    h->shard.count = get_u32(in + H_SHARD_COUNT);
    h->shard.first = get_u32(in + H_SHARD_FIRST);
    h->shard.end = get_u32(in + H_SHARD_END);
    i->basis = get_u32(in + H_BASIS);
    i->sh_order = get_u32(in + H_SH_ORDER);
    i->bounces = get_u32(in + H_BOUNCES) & 0xffffu;
    i->channels = get_u32(in + H_BOUNCES) >> 16;
    if (!i->channels) i->channels = 1;
    for (unsigned k = H_RESERVED; k < H_HEADER_CRC; k++)
        if (in[k] && !tf_basis_byte(k)) h->reserved_nonzero = 1;
}

/* ---------------------------------------------------------------- checks */

int hl_tf_info_problem(const hl_transport_info *i, char *msg, size_t n)
{
    if (i->N < 8 || i->N > 256 || (i->N & (i->N - 1)))
        return snprintf(msg, n, "N = %u is not a power of two in 8..256", i->N), 1;
    if (i->C < 1 || i->C > 4096) return snprintf(msg, n, "C = %u is outside 1..4096", i->C), 1;
    if (i->supersample < 1 || i->supersample > 15)
        return snprintf(msg, n, "supersample = %u is outside 1..15", i->supersample), 1;
    if (i->rule != HL_TRUNC_ALL && i->rule != HL_TRUNC_TOPK && i->rule != HL_TRUNC_ENERGY)
        return snprintf(msg, n, "rule = %u is not a known truncation rule", i->rule), 1;
    if (!(i->eps >= 0.0f && i->eps <= 1.0f))
        return snprintf(msg, n, "eps = %g is outside [0, 1]", (double)i->eps), 1;
    if (i->quant < HL_QUANT_LINEAR8 || i->quant > HL_QUANT_MAX)
        return snprintf(msg, n, "quant = %u is not a known quantisation scheme", i->quant), 1;
    if (!(i->ray_offset >= 0.0f && isfinite(i->ray_offset)))
        return snprintf(msg, n, "ray_offset = %g is not a finite non-negative number", (double)i->ray_offset), 1;
    if (i->vertex_count == 0) return snprintf(msg, n, "vertex_count is 0"), 1;
    if (i->bounces > HL_MAX_BOUNCES)
        return snprintf(msg, n, "bounces = %u is outside 0..%u", i->bounces, HL_MAX_BOUNCES), 1;
    if (i->channels != 0 && i->channels != 1 && i->channels != 3)
        return snprintf(msg, n, "channels = %u: rows a vertex must be 1 or 3", i->channels), 1;
    if (i->channels == 3 && !i->bounces)
        return snprintf(msg, n, "channels = 3 without bounces: only bounces off coloured surfaces have a row a channel"), 1;
    if (i->channels == 3 && i->vertex_count > UINT32_MAX / 3)
        return snprintf(msg, n, "vertex_count = %u with 3 rows a vertex: more rows than a file can index", i->vertex_count), 1;
    if (i->object_vertex_count > i->vertex_count)
        return snprintf(msg, n, "object_vertex_count = %u exceeds vertex_count = %u", i->object_vertex_count,
                        i->vertex_count),
               1;
    if (i->block_count != blocks_for(i->N))
        return snprintf(msg, n, "block_count = %u, but N = %u needs %u", i->block_count, i->N, blocks_for(i->N)), 1;
    if (i->basis != HL_TRANSPORT_BASIS_HAAR && i->basis != HL_TRANSPORT_BASIS_SH && i->basis != HL_TRANSPORT_BASIS_CUBE)
        return snprintf(msg, n, "basis = %u is not a known basis (0 Haar, 1 spherical harmonics, 2 cube-face Haar)",
                        i->basis), 1;
    /* the cube side: a power of two the faces' Haar can halve down to 1,
       whose 6 C'^2 coefficients fit the slots, cutting the visibility cube
       into whole texels */
    const uint32_t cs = i->sh_order;
    if (i->basis == HL_TRANSPORT_BASIS_CUBE && (cs < 2 || cs > 512 || (cs & (cs - 1))))
        return snprintf(msg, n, "sh_order = %u (the cube side) is not a power of two in 2..512", cs), 1;
    if (i->basis == HL_TRANSPORT_BASIS_CUBE && 6 * cs * cs > slot_total(i->N))
        return snprintf(msg, n, "sh_order = %u (the cube side): its %u coefficients exceed the %u slots of N = %u", cs,
                        6 * cs * cs, slot_total(i->N), i->N), 1;
    if (i->basis == HL_TRANSPORT_BASIS_CUBE && i->C % cs)
        return snprintf(msg, n, "sh_order = %u (the cube side) does not divide C = %u", cs, i->C), 1;
    if (i->basis == HL_TRANSPORT_BASIS_HAAR && i->sh_order != 0)
        return snprintf(msg, n, "sh_order = %u in a Haar file (must be 0)", i->sh_order), 1;
    if (i->basis == HL_TRANSPORT_BASIS_SH && (i->sh_order < 1 || i->sh_order > 32))
        return snprintf(msg, n, "sh_order = %u is outside 1..32", i->sh_order), 1;
    if (i->basis == HL_TRANSPORT_BASIS_SH && i->sh_order * i->sh_order > slot_total(i->N))
        return snprintf(msg, n, "sh_order = %u: its %u coefficients exceed the %u slots of N = %u", i->sh_order,
                        i->sh_order * i->sh_order, slot_total(i->N), i->N), 1;
    return 0;
}

int hl_tf_sections_problem(const tf_header *h, const uint64_t expect[SEC_COUNT], char *msg, size_t n)
{
    static const char *const size_fields[SEC_COUNT] = {"mesh_size", "rows_size", "entries_size"};
    static const char *const offset_fields[SEC_COUNT] = {"mesh_offset", "rows_offset", "entries_offset"};
    uint64_t end = TF_HEADER_SIZE;
    for (int s = 0; s < SEC_COUNT; s++) {
        if (h->sec[s].size != expect[s])
            return snprintf(msg, n, "header field %s = %" PRIu64 ", the counts need %" PRIu64, size_fields[s],
                            h->sec[s].size, expect[s]), 1;
        if (h->sec[s].offset < end || h->sec[s].offset % TF_ALIGN != 0 || h->sec[s].offset > h->file_size ||
            h->sec[s].size > h->file_size - h->sec[s].offset)
            return snprintf(msg, n, "header field %s = %" PRIu64
                            " is misaligned, overlaps or lies outside the file (%" PRIu64 " bytes)",
                            offset_fields[s], h->sec[s].offset, h->file_size), 1;
        end = h->sec[s].offset + h->sec[s].size;
    }
    if (h->file_size != end)
        return snprintf(msg, n, "header field file_size = %" PRIu64 " but the entries end at %" PRIu64, h->file_size,
                        end), 1;
    return 0;
}

int hl_tf_shard_header_problem(const tf_header *h, const uint8_t bytes[TF_HEADER_SIZE], char *msg, size_t n)
{
    const hl_transport_info *i = &h->info;
    const tf_shard *s = &h->shard;
    if (hl_tf_info_problem(i, msg, n)) return 1;
    if (s->count == 0 || s->count > i->vertex_count || s->index >= s->count)
        return snprintf(msg, n, "shard %u of %u is impossible for %u vertices", s->index, s->count, i->vertex_count), 1;
    uint32_t first, end;
    tf_shard_range(i->vertex_count, s->index, s->count, &first, &end);
    if (s->first != first || s->end != end)
        return snprintf(msg, n, "shard %u of %u holds vertices [%u, %u), but %u vertices split into %u give it [%u, %u)",
                        s->index, s->count, s->first, s->end, i->vertex_count, s->count, first, end), 1;
    for (unsigned k = H_RESERVED; k < H_HEADER_CRC; k++)
        if (bytes[k] && (k < H_SHARD_INDEX || k >= H_SHARD_END + 4) && !tf_basis_byte(k))
            return snprintf(msg, n, "reserved header byte %u is not zero", k), 1;
    uint64_t rows = (uint64_t)(end - first) * (i->channels == 3 ? 3 : 1), max_coef = rows * slot_total(i->N);
    if (i->coefficients_kept > max_coef)
        return snprintf(msg, n, "header field coefficients_kept = %" PRIu64 " exceeds the shard's %" PRIu64
                        " vertices x 2N^2", i->coefficients_kept, rows), 1;
    const uint64_t expect[SEC_COUNT] = {mesh_bytes(i->vertex_count, i->triangle_count),
                                        rows * row_record_bytes(i->block_count), 2 * i->coefficients_kept};
    return hl_tf_sections_problem(h, expect, msg, n);
}

static int finite3(const float *p) { return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]); }

int hl_tf_mesh_problem(uint32_t vertices, uint32_t triangles, const float *pos, const float *nrm,
                       const float *alb, const uint32_t *idx, char *msg, size_t n)
{
    for (uint32_t v = 0; v < vertices; v++) {
        if (!finite3(pos + 3 * (size_t)v)) return snprintf(msg, n, "vertex %u: position is not finite", v), 1;
        if (!finite3(nrm + 3 * (size_t)v)) return snprintf(msg, n, "vertex %u: normal is not finite", v), 1;
        if (!finite3(alb + 3 * (size_t)v)) return snprintf(msg, n, "vertex %u: albedo is not finite", v), 1;
        /* what the mesh layer guarantees (mesh.c): unit normals, albedo in
           [0, 1]; anything else is a forged or damaged file */
        const float *q = nrm + 3 * (size_t)v, *c = alb + 3 * (size_t)v;
        double len = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]);
        if (fabs(len - 1.0) > 1e-3) return snprintf(msg, n, "vertex %u: normal is not of unit length (%g)", v, len), 1;
        for (int k = 0; k < 3; k++)
            if (!(c[k] >= 0.0f && c[k] <= 1.0f))
                return snprintf(msg, n, "vertex %u: albedo %g is outside [0, 1]", v, (double)c[k]), 1;
    }
    for (uint32_t t = 0; t < triangles; t++)
        for (int k = 0; k < 3; k++)
            if (idx[3 * (size_t)t + k] >= vertices)
                return snprintf(msg, n, "triangle %u: index %u is not below vertex_count %u", t,
                                idx[3 * (size_t)t + k], vertices),
                       1;
    return 0;
}

int hl_tf_row_quant_problem(uint32_t quant, hl_row_quant rq, char *msg, size_t n)
{
    if (!isfinite(rq.a) || !isfinite(rq.b))
        return snprintf(msg, n, "quantisation parameters (%g, %g) are not finite", (double)rq.a, (double)rq.b), 1;
    /* LOG8 interpolates bit patterns of magnitudes: a sign bit would make
     * the dequantised values meaningless. */
    if (quant != HL_QUANT_LINEAR8 && ((HL_AS_U32(rq.a) | HL_AS_U32(rq.b)) >> 31))
        return snprintf(msg, n, "%s magnitudes (%g, %g) are negative", quant == HL_QUANT_LOG8 ? "log8" : "sqrt8",
                        (double)rq.a, (double)rq.b), 1;
    if (rq.a > rq.b)
        return snprintf(msg, n, "quantisation range (%g, %g) is reversed", (double)rq.a, (double)rq.b), 1;
    if (quant == HL_QUANT_LINEAR8 && !isfinite(rq.b - rq.a))
        return snprintf(msg, n, "linear8 range (%g, %g) overflows", (double)rq.a, (double)rq.b), 1;
    return 0;
}

int hl_tf_row_problem(uint32_t N, const uint16_t *counts, const uint8_t *entries, uint64_t *nnz, char *msg,
                      size_t n)
{
    uint32_t blocks = blocks_for(N);
    uint64_t sum = 0;
    for (uint32_t b = 0; b < blocks; b++) {
        uint32_t slots = slots_in_block(N, b);
        if (counts[b] > slots)
            return snprintf(msg, n, "block %u holds %u entries, more than its %u slots", b, counts[b], slots), 1;
        if (entries) {
            const uint8_t *e = entries + 2 * sum;
            for (uint32_t j = 0; j < counts[b]; j++) {
                uint32_t idx = e[2 * j];
                if (idx >= slots)
                    return snprintf(msg, n, "block %u entry %u: index %u is outside the block's %u slots", b, j,
                                    idx, slots),
                           1;
                if (j > 0 && idx <= e[2 * (j - 1)])
                    return snprintf(msg, n, "block %u entry %u: index %u does not increase (previous %u)", b, j,
                                    idx, e[2 * (j - 1)]),
                           1;
            }
        }
        sum += counts[b];
    }
    *nnz = sum;
    return 0;
}

int hl_tf_row_slots_problem(uint32_t N, uint32_t limit, const uint16_t *counts, const uint8_t *entries, char *msg,
                            size_t n)
{
    if (limit >= slot_total(N)) return 0;
    uint64_t e = 0;
    /* a block's indices increase (hl_tf_row_problem), so its last entry
       holds its largest slot */
    for (uint32_t b = 0; b < blocks_for(N); b++) {
        e += counts[b];
        if (!counts[b]) continue;
        uint32_t slot = b * HL_BLOCK + entries[2 * (e - 1)];
        if (slot >= limit)
            return snprintf(msg, n, "block %u entry %u: slot %u is not below the basis's %u coefficients", b,
                            counts[b] - 1u, slot, limit), 1;
    }
    return 0;
}

/* ---------------------------------------------------------------- file I/O */

int hl_tf_pwrite_all(int fd, const void *data, size_t n, uint64_t off)
{
    const uint8_t *p = data;
    while (n > 0) {
        ssize_t k = pwrite(fd, p, n, (off_t)off);
        if (k < 0) {
            if (errno == EINTR) continue;
            return -1;
        }
        if (k == 0) {
            errno = EIO;
            return -1;
        }
        p += k;
        n -= (size_t)k;
        off += (uint64_t)k;
    }
    return 0;
}

char *hl_tf_path_with(hl_context *ctx, const char *s, const char *suffix)
{
    size_t a = strlen(s), b = suffix ? strlen(suffix) : 0;
    char *p = hl_malloc(ctx, a + b + 1, "a file name");
    if (!p) return NULL;
    memcpy(p, s, a);
    if (b) memcpy(p + a, suffix, b);
    p[a + b] = 0;
    return p;
}

int hl_tf_pread_all(int fd, void *data, size_t n, uint64_t off)
{
    uint8_t *p = data;
    while (n > 0) {
        ssize_t k = pread(fd, p, n, (off_t)off);
        if (k < 0) {
            if (errno == EINTR) continue;
            return -1;
        }
        if (k == 0) return 1;
        p += k;
        n -= (size_t)k;
        off += (uint64_t)k;
    }
    return 0;
}
