/* transport_file.c - transport file (.hlt) writer, reader and report.
 *
 * The byte layout lives in host/FORMAT.md; the constants below must match
 * it. Everything is little-endian and encoded byte by byte, so files are
 * identical whatever the host. The reader trusts nothing: every size is
 * checked against the header and the real file size before anything is
 * allocated, every section carries a CRC-32, and the contents are validated
 * after the checksums so that a forged but consistent file is still refused
 * with a message naming the vertex or triangle.
 *
 * Depends on: hl_internal.h (hl_fail, allocation), hl_mesh_destroy (mesh.c),
 * zlib (crc32_z),
 * POSIX open/pread/pwrite/fsync/rename/ftruncate, flock.
 */
#define _DEFAULT_SOURCE /* flock */
#define _FILE_OFFSET_BITS 64
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include <zlib.h>

#include "half.h"
#include "transport_file.h"

/* ---------------------------------------------------------------- format */

#define TF_MAGIC "HLTRANS1"
/* An unfinished file (path + ".partial"), resumable: the header area holds
 * a checkpoint in the same layout, with the sections' sizes and checksums
 * so far and the vertices appended so far in the first reserved word. */
#define TF_PARTIAL_MAGIC "HLTPART1"
#define TF_VERSION HL_TRANSPORT_VERSION
#define TF_HEADER_SIZE 192u
#define TF_ALIGN 64u /* section alignment: lets a later reader mmap them */

/* Header field offsets (FORMAT.md, "Header"). */
enum {
    H_MAGIC = 0,
    H_VERSION = 8,
    H_HEADER_SIZE = 12,
    H_N = 16,
    H_C = 20,
    H_SUPERSAMPLE = 24,
    H_RULE = 28,
    H_K = 32,
    H_EPS = 36,
    H_QUANT = 40,
    H_RAY_OFFSET = 44,
    H_VERTEX_COUNT = 48,
    H_OBJECT_VERTEX_COUNT = 52,
    H_TRIANGLE_COUNT = 56,
    H_BLOCK_COUNT = 60,
    H_COEFFICIENTS_KEPT = 64,
    H_RAYS_CAST = 72,
    H_RAYS_CULLED = 80,
    H_FILE_SIZE = 88,
    H_SECTIONS = 96, /* 3 x (u64 offset, u64 size) */
    H_SECTION_CRCS = 144, /* 3 x u32 */
    H_RESERVED = 156,
    H_APPENDED = 156, /* partial files only */
    H_HEADER_CRC = 188
};

enum { SEC_MESH, SEC_ROWS, SEC_ENTRIES, SEC_COUNT };
static const char *const section_names[SEC_COUNT] = {"mesh", "row table", "entries"};

/* Largest row record: N = 256 gives 512 blocks. */
#define TF_MAX_BLOCKS 512u
#define TF_MAX_RECORD (8u + 2u * TF_MAX_BLOCKS)

typedef struct tf_section {
    uint64_t offset, size;
    uint32_t crc;
} tf_section;

typedef struct tf_header {
    hl_transport_info info;
    uint32_t header_size;
    uint64_t file_size;
    tf_section sec[SEC_COUNT];
    int reserved_nonzero;
} tf_header;

/* ---------------------------------------------------------------- bytes */

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

static void put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}

static uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get_u64(const uint8_t *p) { return (uint64_t)get_u32(p) | (uint64_t)get_u32(p + 4) << 32; }

static int host_is_little_endian(void)
{
    const uint16_t one = 1;
    uint8_t b;
    memcpy(&b, &one, 1);
    return b == 1;
}

/* In-place conversion of 32-bit words between file order and host order. */
static void swap_words_if_big_endian(void *data, size_t words)
{
    if (host_is_little_endian()) return;
    uint8_t *p = data;
    for (size_t i = 0; i < words; i++, p += 4) {
        uint32_t v = get_u32(p);
        memcpy(p, &v, 4);
    }
}

static uint64_t align_up(uint64_t x) { return (x + (TF_ALIGN - 1)) & ~(uint64_t)(TF_ALIGN - 1); }

/* ---------------------------------------------------------------- CRC-32 */

/* IEEE 802.3 CRC-32 (reflected polynomial 0xEDB88320, as PNG), computed
 * by zlib's crc32_z. crc is the value returned by the previous call (0 to
 * start), so a section's CRC can be built piece by piece. */
static uint32_t crc_update(uint32_t crc, const void *data, size_t n)
{
    return (uint32_t)crc32_z(crc, data, n);
}

/* ---------------------------------------------------------------- header */

/* magic: TF_MAGIC, or TF_PARTIAL_MAGIC for the checkpoint of an unfinished
 * file, which also records the vertices appended so far (H_APPENDED). */
static void header_encode(const tf_header *h, const char *magic, uint32_t appended,
                          uint8_t out[TF_HEADER_SIZE])
{
    const hl_transport_info *i = &h->info;
    memset(out, 0, TF_HEADER_SIZE);
    memcpy(out + H_MAGIC, magic, 8);
    if (appended) put_u32(out + H_APPENDED, appended);
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

static void header_decode(const uint8_t *in, tf_header *h)
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
    for (unsigned k = H_RESERVED; k < H_HEADER_CRC; k++)
        if (in[k]) h->reserved_nonzero = 1;
}

/* ---------------------------------------------------------------- checks */

static uint32_t slot_total(uint32_t N) { return 2u * N * N; }
static uint32_t blocks_for(uint32_t N) { return (slot_total(N) + HL_BLOCK - 1) / HL_BLOCK; }

/* Slots of block b: HL_BLOCK except a short last block (N = 8). */
static uint32_t slots_in_block(uint32_t N, uint32_t b)
{
    uint32_t rest = slot_total(N) - b * HL_BLOCK;
    return rest < HL_BLOCK ? rest : HL_BLOCK;
}

static uint64_t mesh_bytes(uint32_t vertices, uint32_t triangles)
{
    return 36u * (uint64_t)vertices + 12u * (uint64_t)triangles;
}

static uint64_t row_record_bytes(uint32_t block_count) { return 8u + 2u * (uint64_t)block_count; }

/* Describes the first out-of-range parameter into msg and returns 1; 0 when
 * all are valid. Shared by writer (caller's bug) and reader (bad file). */
static int info_problem(const hl_transport_info *i, char *msg, size_t n)
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
    if (i->object_vertex_count > i->vertex_count)
        return snprintf(msg, n, "object_vertex_count = %u exceeds vertex_count = %u", i->object_vertex_count,
                        i->vertex_count),
               1;
    if (i->block_count != blocks_for(i->N))
        return snprintf(msg, n, "block_count = %u, but N = %u needs %u", i->block_count, i->N, blocks_for(i->N)), 1;
    return 0;
}

static int finite3(const float *p) { return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]); }

static int mesh_problem(uint32_t vertices, uint32_t triangles, const float *pos, const float *nrm,
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

static int row_quant_problem(uint32_t quant, hl_row_quant rq, char *msg, size_t n)
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

/* Checks one vertex's block counts and entries. entries may be NULL to
 * check only the counts (the sum is returned in *nnz either way). */
static int row_problem(uint32_t N, const uint16_t *counts, const uint8_t *entries, uint64_t *nnz, char *msg,
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

/* ---------------------------------------------------------------- file I/O */

static int pwrite_all(int fd, const void *data, size_t n, uint64_t off)
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

/* 0: read all; 1: end of file first; -1: error (errno). */
static int pread_all(int fd, void *data, size_t n, uint64_t off)
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

/* ---------------------------------------------------------------- writer */

#define TF_STREAM_BYTES ((size_t)256 << 10)

/* A sequential run of bytes at a known file offset, checksummed as it is
 * flushed. Rows and entries each have one, so both can be streamed to
 * their final places without holding either in memory. */
typedef struct tf_stream {
    uint64_t pos; /* file offset of buf[0] */
    uint64_t written;
    uint32_t crc;
    size_t len;
    uint8_t buf[TF_STREAM_BYTES];
} tf_stream;

struct hl_tfile_writer {
    hl_context *ctx;
    char *path;
    char *tmp_path;
    int fd;
    int failed; /* after an I/O error only abort is useful */
    tf_header hdr;
    uint32_t appended;
    uint64_t coefficients;
    tf_stream rows, entries;
};

static hl_result writer_io_error(hl_tfile_writer *w, const char *what)
{
    int e = errno;
    w->failed = 1;
    return hl_fail(w->ctx, HL_ERR_IO, "%s: cannot %s %s: %s", w->path, what, w->tmp_path, strerror(e));
}

static hl_result stream_flush(hl_tfile_writer *w, tf_stream *s)
{
    if (s->len == 0) return HL_OK;
    s->crc = crc_update(s->crc, s->buf, s->len);
    if (pwrite_all(w->fd, s->buf, s->len, s->pos) != 0) return writer_io_error(w, "write");
    s->pos += s->len;
    s->len = 0;
    return HL_OK;
}

static hl_result stream_put(hl_tfile_writer *w, tf_stream *s, const void *data, size_t n)
{
    const uint8_t *p = data;
    s->written += n;
    while (n > 0) {
        size_t k = TF_STREAM_BYTES - s->len;
        if (k > n) k = n;
        memcpy(s->buf + s->len, p, k);
        s->len += k;
        p += k;
        n -= k;
        if (s->len == TF_STREAM_BYTES) {
            hl_result r = stream_flush(w, s);
            if (r != HL_OK) return r;
        }
    }
    return HL_OK;
}

static void stream_start(tf_stream *s, uint64_t pos)
{
    s->pos = pos;
    s->written = 0;
    s->crc = 0;
    s->len = 0;
}

/* 4-byte words (uint32 or float bit patterns), little-endian. */
static hl_result put_words(hl_tfile_writer *w, tf_stream *s, const void *v, size_t count)
{
    uint8_t tmp[4096];
    size_t used = 0;
    for (size_t i = 0; i < count; i++) {
        uint32_t u;
        memcpy(&u, (const uint8_t *)v + 4 * i, 4);
        put_u32(tmp + used, u);
        used += 4;
        if (used == sizeof tmp || i + 1 == count) {
            hl_result r = stream_put(w, s, tmp, used);
            if (r != HL_OK) return r;
            used = 0;
        }
    }
    return HL_OK;
}

/* Zero bytes from `from` up to `to`, so padding is explicit in the file
 * rather than a hole whose length depends on what follows. */
static hl_result write_padding(hl_tfile_writer *w, uint64_t from, uint64_t to)
{
    static const uint8_t zeros[TF_ALIGN];
    if (to <= from) return HL_OK;
    if (pwrite_all(w->fd, zeros, (size_t)(to - from), from) != 0) return writer_io_error(w, "write");
    return HL_OK;
}

static void writer_free(hl_tfile_writer *w)
{
    if (!w) return;
    if (w->fd >= 0) close(w->fd);
    free(w->path);
    free(w->tmp_path);
    free(w);
}

static char *dup_string(hl_context *ctx, const char *s, const char *suffix)
{
    size_t a = strlen(s), b = suffix ? strlen(suffix) : 0;
    char *p = hl_malloc(ctx, a + b + 1, "a file name");
    if (!p) return NULL;
    memcpy(p, s, a);
    if (b) memcpy(p + a, suffix, b);
    p[a + b] = 0;
    return p;
}

static int info_params_differ(const hl_transport_info *a, const hl_transport_info *b)
{
    return a->N != b->N || a->C != b->C || a->supersample != b->supersample || a->rule != b->rule ||
           a->K != b->K || HL_AS_U32(a->eps) != HL_AS_U32(b->eps) || a->quant != b->quant ||
           HL_AS_U32(a->ray_offset) != HL_AS_U32(b->ray_offset) || a->vertex_count != b->vertex_count ||
           a->object_vertex_count != b->object_vertex_count || a->triangle_count != b->triangle_count ||
           a->block_count != b->block_count;
}

/* Checks the arguments and plans the header; no file is touched. */
static hl_result writer_new(hl_context *ctx, const char *path, const hl_transport_info *info, const hl_mesh *mesh,
                            hl_tfile_writer **out)
{
    char msg[256];
    *out = NULL;
    if (!path || !*path || !info || !mesh)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "transport writer: path, info, mesh and out are required");
    if (info_problem(info, msg, sizeof msg))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: transport parameters: %s", path, msg);
    if (mesh->vertex_count != info->vertex_count || mesh->triangle_count != info->triangle_count ||
        mesh->object_vertex_count != info->object_vertex_count)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: mesh has %u vertices (%u object), %u triangles; info says %u (%u), %u", path,
                       mesh->vertex_count, mesh->object_vertex_count, mesh->triangle_count, info->vertex_count,
                       info->object_vertex_count, info->triangle_count);
    if (!mesh->positions || !mesh->normals || !mesh->albedo || (mesh->triangle_count && !mesh->indices))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: mesh arrays missing", path);
    if (mesh_problem(mesh->vertex_count, mesh->triangle_count, mesh->positions, mesh->normals, mesh->albedo,
                     mesh->indices, msg, sizeof msg))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: mesh: %s", path, msg);

    hl_tfile_writer *w = hl_calloc(ctx, 1, sizeof *w, "the transport writer");
    if (!w) return HL_ERR_OUT_OF_MEMORY;
    w->ctx = ctx;
    w->fd = -1;
    w->path = dup_string(ctx, path, NULL);
    w->tmp_path = dup_string(ctx, path, ".partial");
    if (!w->path || !w->tmp_path) {
        writer_free(w);
        return HL_ERR_OUT_OF_MEMORY;
    }

    tf_header *h = &w->hdr;
    h->info = *info;
    h->info.version = TF_VERSION;
    h->info.coefficients_kept = 0;
    h->info.rays_cast = h->info.rays_culled = 0;
    h->header_size = TF_HEADER_SIZE;
    h->sec[SEC_MESH].offset = TF_HEADER_SIZE;
    h->sec[SEC_MESH].size = mesh_bytes(info->vertex_count, info->triangle_count);
    h->sec[SEC_ROWS].offset = align_up(h->sec[SEC_MESH].offset + h->sec[SEC_MESH].size);
    h->sec[SEC_ROWS].size = (uint64_t)info->vertex_count * row_record_bytes(info->block_count);
    h->sec[SEC_ENTRIES].offset = align_up(h->sec[SEC_ROWS].offset + h->sec[SEC_ROWS].size);
    *out = w;
    return HL_OK;
}

/* One writer per partial file: a second precompute onto the same path
 * would interleave its rows with ours. */
static hl_result writer_lock(hl_tfile_writer *w)
{
    if (flock(w->fd, LOCK_EX | LOCK_NB) == 0) return HL_OK;
    int e = errno;
    return hl_fail(w->ctx, HL_ERR_IO, "%s: %s is in use by another precompute (%s)", w->path, w->tmp_path,
                   e == EWOULDBLOCK ? "locked" : strerror(e));
}

/* CRC-32 of the mesh section as it would be written. */
static uint32_t mesh_crc(const hl_mesh *mesh)
{
    const void *parts[4] = {mesh->positions, mesh->normals, mesh->albedo, mesh->indices};
    size_t words[4] = {3 * (size_t)mesh->vertex_count, 3 * (size_t)mesh->vertex_count,
                       3 * (size_t)mesh->vertex_count, 3 * (size_t)mesh->triangle_count};
    uint32_t crc = 0;
    uint8_t tmp[4096];
    for (int k = 0; k < 4; k++)
        for (size_t i = 0; i < words[k];) {
            size_t n = 0;
            for (; n < sizeof tmp && i < words[k]; n += 4, i++) {
                uint32_t u;
                memcpy(&u, (const uint8_t *)parts[k] + 4 * i, 4);
                put_u32(tmp + n, u);
            }
            crc = crc_update(crc, tmp, n);
        }
    return crc;
}

hl_result hl_tfile_writer_open(hl_context *ctx, const char *path, const hl_transport_info *info,
                               const hl_mesh *mesh, hl_tfile_writer **out)
{
    if (out) *out = NULL;
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "transport writer: path, info, mesh and out are required");
    hl_tfile_writer *w;
    hl_result r = writer_new(ctx, path, info, mesh, &w);
    if (r != HL_OK) return r;
    tf_header *h = &w->hdr;
    w->fd = open(w->tmp_path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (w->fd < 0) {
        int e = errno;
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot create %s: %s", path, w->tmp_path, strerror(e));
        writer_free(w);
        return r;
    }
    r = writer_lock(w);
    if (r == HL_OK && ftruncate(w->fd, 0) != 0) r = writer_io_error(w, "truncate");
    if (r != HL_OK) {
        writer_free(w); /* not ours to remove */
        return r;
    }

    /* The mesh goes out now through the rows stream, which then restarts at
     * the row table: one buffer serves both. */
    size_t v3 = 3 * (size_t)mesh->vertex_count;
    tf_stream *s = &w->rows;
    stream_start(s, h->sec[SEC_MESH].offset);
    r = put_words(w, s, mesh->positions, v3);
    if (r == HL_OK) r = put_words(w, s, mesh->normals, v3);
    if (r == HL_OK) r = put_words(w, s, mesh->albedo, v3);
    if (r == HL_OK) r = put_words(w, s, mesh->indices, 3 * (size_t)mesh->triangle_count);
    if (r == HL_OK) r = stream_flush(w, s);
    if (r == HL_OK) r = write_padding(w, h->sec[SEC_MESH].offset + h->sec[SEC_MESH].size, h->sec[SEC_ROWS].offset);
    if (r != HL_OK) {
        hl_tfile_writer_abort(w);
        return r;
    }
    h->sec[SEC_MESH].crc = s->crc;
    stream_start(&w->rows, h->sec[SEC_ROWS].offset);
    stream_start(&w->entries, h->sec[SEC_ENTRIES].offset);
    /* resumable from the start: the mesh is in */
    r = hl_tfile_writer_checkpoint(w, 0, 0);
    if (r != HL_OK) {
        hl_tfile_writer_abort(w);
        return r;
    }
    *out = w;
    return HL_OK;
}

hl_result hl_tfile_writer_checkpoint(hl_tfile_writer *w, uint64_t rays_cast, uint64_t rays_culled)
{
    if (!w) return HL_ERR_INVALID_ARGUMENT;
    if (w->failed) return hl_fail(w->ctx, HL_ERR_IO, "%s: the writer failed earlier", w->path);
    hl_result r = stream_flush(w, &w->rows);
    if (r == HL_OK) r = stream_flush(w, &w->entries);
    if (r != HL_OK) return r;
    tf_header p = w->hdr;
    p.info.coefficients_kept = w->coefficients;
    p.info.rays_cast = rays_cast;
    p.info.rays_culled = rays_culled;
    p.sec[SEC_ROWS].size = (uint64_t)w->appended * row_record_bytes(p.info.block_count);
    p.sec[SEC_ROWS].crc = w->rows.crc;
    p.sec[SEC_ENTRIES].size = 2 * w->coefficients;
    p.sec[SEC_ENTRIES].crc = w->entries.crc;
    p.file_size = p.sec[SEC_ENTRIES].offset + p.sec[SEC_ENTRIES].size;
    uint8_t bytes[TF_HEADER_SIZE];
    header_encode(&p, TF_PARTIAL_MAGIC, w->appended, bytes);
    if (pwrite_all(w->fd, bytes, sizeof bytes, 0) != 0) return writer_io_error(w, "write");
    return HL_OK;
}

/* The CRC-32 of bytes [off, off + n) of the partial file. */
static int file_crc(hl_tfile_writer *w, uint64_t off, uint64_t n, uint32_t *crc)
{
    uint8_t *buf = malloc(1u << 20);
    if (!buf) return -1;
    uint32_t c = 0;
    while (n > 0) {
        size_t k = n < (1u << 20) ? (size_t)n : (1u << 20);
        if (pread_all(w->fd, buf, k, off) != 0) {
            free(buf);
            return -1;
        }
        c = crc_update(c, buf, k);
        off += k;
        n -= k;
    }
    free(buf);
    *crc = c;
    return 0;
}

hl_result hl_tfile_writer_resume(hl_context *ctx, const char *path, const hl_transport_info *info,
                                 const hl_mesh *mesh, hl_tfile_writer **out, hl_tfile_progress *done)
{
    if (out) *out = NULL;
    memset(done, 0, sizeof *done);
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "transport writer: path, info, mesh and out are required");
    hl_tfile_writer *w;
    hl_result r = writer_new(ctx, path, info, mesh, &w);
    if (r != HL_OK) return r;
    w->fd = open(w->tmp_path, O_RDWR | O_CLOEXEC);
    if (w->fd < 0) {
        int e = errno;
        r = e == ENOENT ? HL_OK : hl_fail(ctx, HL_ERR_IO, "%s: cannot open %s: %s", path, w->tmp_path, strerror(e));
        writer_free(w);
        return r;
    }
    r = writer_lock(w);
    uint8_t bytes[TF_HEADER_SIZE];
    tf_header p;
    const tf_header *h = &w->hdr;
    const char *why = NULL;
    if (r == HL_OK && pread_all(w->fd, bytes, sizeof bytes, 0) != 0) why = "too short to hold a checkpoint";
    if (r == HL_OK && !why) {
        header_decode(bytes, &p);
        uint32_t appended = get_u32(bytes + H_APPENDED);
        uint64_t rows = (uint64_t)appended * row_record_bytes(h->info.block_count);
        if (memcmp(bytes, TF_PARTIAL_MAGIC, 8) != 0) why = "not a partial transport file";
        else if (get_u32(bytes + H_HEADER_CRC) != crc_update(0, bytes, H_HEADER_CRC)) why = "its checkpoint is corrupt";
        else if (get_u32(bytes + H_VERSION) != TF_VERSION) why = "written by another format version";
        else if (info_params_differ(&p.info, &h->info)) why = "made with other parameters or another mesh";
        else if (p.sec[SEC_MESH].offset != h->sec[SEC_MESH].offset || p.sec[SEC_MESH].size != h->sec[SEC_MESH].size ||
                 p.sec[SEC_MESH].crc != mesh_crc(mesh))
            why = "made from another mesh";
        else if (appended > h->info.vertex_count || p.sec[SEC_ROWS].offset != h->sec[SEC_ROWS].offset ||
                 p.sec[SEC_ROWS].size != rows || p.sec[SEC_ENTRIES].offset != h->sec[SEC_ENTRIES].offset ||
                 p.sec[SEC_ENTRIES].size != 2 * p.info.coefficients_kept)
            why = "its checkpoint is inconsistent";
        else {
            uint32_t c[SEC_COUNT];
            for (int k = 0; k < SEC_COUNT && !why; k++)
                if (file_crc(w, p.sec[k].offset, p.sec[k].size, &c[k]) != 0 || c[k] != p.sec[k].crc)
                    why = "its data do not match its checkpoint (cut short or changed)";
            if (!why) {
                w->hdr.sec[SEC_MESH].crc = p.sec[SEC_MESH].crc;
                w->appended = appended;
                w->coefficients = p.info.coefficients_kept;
                stream_start(&w->rows, p.sec[SEC_ROWS].offset + p.sec[SEC_ROWS].size);
                w->rows.crc = p.sec[SEC_ROWS].crc;
                w->rows.written = p.sec[SEC_ROWS].size;
                stream_start(&w->entries, p.sec[SEC_ENTRIES].offset + p.sec[SEC_ENTRIES].size);
                w->entries.crc = p.sec[SEC_ENTRIES].crc;
                w->entries.written = p.sec[SEC_ENTRIES].size;
                if (ftruncate(w->fd, (off_t)(p.sec[SEC_ENTRIES].offset + p.sec[SEC_ENTRIES].size)) != 0)
                    r = writer_io_error(w, "truncate");
                done->appended = appended;
                done->coefficients = p.info.coefficients_kept;
                done->rays_cast = p.info.rays_cast;
                done->rays_culled = p.info.rays_culled;
            }
        }
    }
    if (r == HL_OK && why)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot resume from %s: %s; remove it or run without --resume", path,
                    w->tmp_path, why);
    if (r != HL_OK) {
        memset(done, 0, sizeof *done);
        writer_free(w);
        return r;
    }
    *out = w;
    return HL_OK;
}

hl_result hl_tfile_writer_append(hl_tfile_writer *w, uint32_t vertex_count, const hl_row_quant *rq,
                                 const uint16_t *block_counts, const uint8_t *entries, size_t entry_stride_bytes,
                                 const uint32_t *nnz)
{
    if (!w) return HL_ERR_INVALID_ARGUMENT;
    if (w->failed) return hl_fail(w->ctx, HL_ERR_IO, "%s: the writer failed earlier", w->path);
    if (vertex_count == 0) return HL_OK;
    const hl_transport_info *info = &w->hdr.info;
    if (!rq || !block_counts || !nnz)
        return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: append: arrays missing", w->path);
    if (vertex_count > info->vertex_count - w->appended)
        return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: append of %u vertices after %u would exceed vertex_count %u", w->path, vertex_count,
                       w->appended, info->vertex_count);

    /* Validate everything first so that a refusal leaves the file as it was. */
    uint32_t B = info->block_count;
    char msg[256];
    for (uint32_t i = 0; i < vertex_count; i++) {
        uint32_t v = w->appended + i;
        uint64_t sum = 0;
        if (row_quant_problem(info->quant, rq[i], msg, sizeof msg))
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: %s", w->path, v, msg);
        if (row_problem(info->N, block_counts + (size_t)i * B, NULL, &sum, msg, sizeof msg))
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: %s", w->path, v, msg);
        if (sum != nnz[i])
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: block counts sum to %" PRIu64
                           " but nnz is %u", w->path, v, sum, nnz[i]);
        if (nnz[i] && !entries)
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: entries missing", w->path, v);
        if (i + 1 < vertex_count && 2 * (size_t)nnz[i] > entry_stride_bytes)
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: %u entries overrun the stride of %zu bytes",
                           w->path, v, nnz[i], entry_stride_bytes);
        if (nnz[i] && row_problem(info->N, block_counts + (size_t)i * B, entries + i * entry_stride_bytes, &sum,
                                  msg, sizeof msg))
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: %s", w->path, v, msg);
    }

    uint8_t rec[TF_MAX_RECORD];
    size_t rec_bytes = (size_t)row_record_bytes(B);
    for (uint32_t i = 0; i < vertex_count; i++) {
        put_u32(rec, HL_AS_U32(rq[i].a));
        put_u32(rec + 4, HL_AS_U32(rq[i].b));
        for (uint32_t b = 0; b < B; b++) put_u16(rec + 8 + 2 * b, block_counts[(size_t)i * B + b]);
        hl_result r = stream_put(w, &w->rows, rec, rec_bytes);
        if (r == HL_OK && nnz[i]) r = stream_put(w, &w->entries, entries + i * entry_stride_bytes, 2 * (size_t)nnz[i]);
        if (r != HL_OK) return r;
        w->coefficients += nnz[i];
    }
    w->appended += vertex_count;
    return HL_OK;
}


/* Makes the rename durable; failure here only weakens crash safety. */
static void sync_parent_dir(const char *path)
{
    const char *slash = strrchr(path, '/');
    char dir[4096];
    if (!slash) {
        snprintf(dir, sizeof dir, ".");
    } else if (slash == path) {
        snprintf(dir, sizeof dir, "/");
    } else {
        size_t n = (size_t)(slash - path);
        if (n >= sizeof dir) return;
        memcpy(dir, path, n);
        dir[n] = 0;
    }
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) return;
    (void)fsync(fd);
    close(fd);
}

hl_result hl_tfile_writer_finish(hl_tfile_writer *w, const hl_transport_info *final_info)
{
    if (!w) return HL_ERR_INVALID_ARGUMENT;
    hl_result r = HL_OK;
    tf_header *h = &w->hdr;
    if (w->failed) {
        r = hl_fail(w->ctx, HL_ERR_IO, "%s: the writer failed earlier", w->path);
    } else if (w->appended != h->info.vertex_count) {
        r = hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: finished after %u of %u vertices", w->path, w->appended,
                    h->info.vertex_count);
    } else if (final_info && info_params_differ(final_info, &h->info)) {
        r = hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: final parameters differ from those given at open",
                    w->path);
    } else if (final_info && final_info->coefficients_kept && final_info->coefficients_kept != w->coefficients) {
        r = hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT,
                    "%s: coefficients_kept %" PRIu64 " but %" PRIu64 " were appended", w->path,
                    final_info->coefficients_kept, w->coefficients);
    }
    if (r == HL_OK) r = stream_flush(w, &w->rows);
    if (r == HL_OK) r = stream_flush(w, &w->entries);
    if (r == HL_OK) {
        h->info.coefficients_kept = w->coefficients;
        h->info.rays_cast = final_info ? final_info->rays_cast : 0;
        h->info.rays_culled = final_info ? final_info->rays_culled : 0;
        h->sec[SEC_ROWS].crc = w->rows.crc;
        h->sec[SEC_ENTRIES].size = 2 * w->coefficients;
        h->sec[SEC_ENTRIES].crc = w->entries.crc;
        h->file_size = h->sec[SEC_ENTRIES].offset + h->sec[SEC_ENTRIES].size;
        uint8_t bytes[TF_HEADER_SIZE];
        header_encode(h, TF_MAGIC, 0, bytes);
        r = write_padding(w, h->sec[SEC_ROWS].offset + h->sec[SEC_ROWS].size, h->sec[SEC_ENTRIES].offset);
        if (r == HL_OK && pwrite_all(w->fd, bytes, sizeof bytes, 0) != 0) r = writer_io_error(w, "write");
        if (r == HL_OK && fsync(w->fd) != 0) r = writer_io_error(w, "sync");
    }
    if (r == HL_OK) {
        int fd = w->fd;
        w->fd = -1;
        if (close(fd) != 0) r = writer_io_error(w, "close");
    }
    if (r == HL_OK && rename(w->tmp_path, w->path) != 0) {
        int e = errno;
        r = hl_fail(w->ctx, HL_ERR_IO, "%s: cannot rename %s onto it: %s", w->path, w->tmp_path, strerror(e));
    }
    if (r != HL_OK) {
        hl_tfile_writer_abort(w);
        return r;
    }
    sync_parent_dir(w->path);
    writer_free(w);
    return HL_OK;
}

uint32_t hl_tfile_writer_appended(const hl_tfile_writer *w) { return w ? w->appended : 0; }

void hl_tfile_writer_keep(hl_tfile_writer *w)
{
    writer_free(w);
}

void hl_tfile_writer_abort(hl_tfile_writer *w)
{
    if (!w) return;
    if (w->fd >= 0) {
        close(w->fd);
        w->fd = -1;
    }
    if (w->tmp_path) unlink(w->tmp_path);
    writer_free(w);
}

/* ---------------------------------------------------------------- reader */

typedef struct tf_reader {
    hl_context *ctx;
    const char *path;
    int fd;
    uint64_t file_size;
} tf_reader;

/* Reads a section range into memory; the file size was checked against the
 * header already, so a short read means the file changed under us. */
static hl_result read_range(tf_reader *rd, void *dst, uint64_t bytes, uint64_t off, const char *what)
{
    if (bytes > SIZE_MAX) return hl_fail(rd->ctx, HL_ERR_OUT_OF_MEMORY, "%s: %s too large for this host", rd->path, what);
    int k = pread_all(rd->fd, dst, (size_t)bytes, off);
    if (k < 0) return hl_fail(rd->ctx, HL_ERR_IO, "%s: cannot read the %s: %s", rd->path, what, strerror(errno));
    if (k > 0)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: truncated while reading the %s (file shrank?)", rd->path, what);
    return HL_OK;
}

static hl_result check_crc(tf_reader *rd, int sec, uint32_t stored, uint32_t computed)
{
    if (stored == computed) return HL_OK;
    return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: checksum mismatch in the %s section (stored %08" PRIx32
                   ", computed %08" PRIx32 ")", rd->path, section_names[sec], stored, computed);
}

static hl_result read_header(tf_reader *rd, tf_header *h)
{
    uint8_t bytes[TF_HEADER_SIZE];
    size_t have = rd->file_size < TF_HEADER_SIZE ? (size_t)rd->file_size : TF_HEADER_SIZE;
    hl_result r = read_range(rd, bytes, have, 0, "header");
    if (r != HL_OK) return r;
    size_t magic_have = have < 8 ? have : 8;
    if (memcmp(bytes, TF_MAGIC, magic_have) != 0)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: not a haarlight transport file", rd->path);
    if (have >= H_VERSION + 4 && get_u32(bytes + H_VERSION) != TF_VERSION)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: version %" PRIu32 ", this build reads %u", rd->path,
                       get_u32(bytes + H_VERSION), TF_VERSION);
    if (have < TF_HEADER_SIZE)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: truncated: expected at least %u bytes, file has %" PRIu64,
                       rd->path, TF_HEADER_SIZE, rd->file_size);
    if (get_u32(bytes + H_HEADER_SIZE) != TF_HEADER_SIZE)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header_size %" PRIu32 ", version 1 has %u", rd->path,
                       get_u32(bytes + H_HEADER_SIZE), TF_HEADER_SIZE);
    uint32_t stored = get_u32(bytes + H_HEADER_CRC);
    uint32_t computed = crc_update(0, bytes, H_HEADER_CRC);
    if (stored != computed)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: checksum mismatch in the header (stored %08" PRIx32
                       ", computed %08" PRIx32 ")", rd->path, stored, computed);
    header_decode(bytes, h);
    if (h->reserved_nonzero)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: reserved header bytes %u..%u are not zero", rd->path,
                       (unsigned)H_RESERVED, (unsigned)H_HEADER_CRC - 1);

    char msg[256];
    const hl_transport_info *i = &h->info;
    if (info_problem(i, msg, sizeof msg)) return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header field %s", rd->path, msg);
    uint64_t max_coef = (uint64_t)i->vertex_count * slot_total(i->N);
    if (i->coefficients_kept > max_coef)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header field coefficients_kept = %" PRIu64
                       " exceeds vertex_count x 2N^2 = %" PRIu64, rd->path, i->coefficients_kept, max_coef);

    /* Sizes follow from the counts; offsets are free but ordered, aligned
     * past the header and inside the file, so no section overlaps another. */
    const uint64_t expect[SEC_COUNT] = {mesh_bytes(i->vertex_count, i->triangle_count),
                                        (uint64_t)i->vertex_count * row_record_bytes(i->block_count),
                                        2 * i->coefficients_kept};
    static const char *const size_fields[SEC_COUNT] = {"mesh_size", "rows_size", "entries_size"};
    static const char *const offset_fields[SEC_COUNT] = {"mesh_offset", "rows_offset", "entries_offset"};
    uint64_t end = TF_HEADER_SIZE;
    for (int s = 0; s < SEC_COUNT; s++) {
        if (h->sec[s].size != expect[s])
            return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header field %s = %" PRIu64 ", the counts need %" PRIu64,
                           rd->path, size_fields[s], h->sec[s].size, expect[s]);
        if (h->sec[s].offset < end || h->sec[s].offset % TF_ALIGN != 0 || h->sec[s].offset > h->file_size ||
            h->sec[s].size > h->file_size - h->sec[s].offset)
            return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header field %s = %" PRIu64
                           " is misaligned, overlaps or lies outside the file (%" PRIu64 " bytes)",
                           rd->path, offset_fields[s], h->sec[s].offset, h->file_size);
        end = h->sec[s].offset + h->sec[s].size;
    }
    if (h->file_size != end)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header field file_size = %" PRIu64 " but the entries end at %" PRIu64,
                       rd->path, h->file_size, end);
    if (rd->file_size < h->file_size)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: truncated: expected %" PRIu64 " bytes, file has %" PRIu64,
                       rd->path, h->file_size, rd->file_size);
    if (rd->file_size > h->file_size)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: %" PRIu64 " bytes of trailing data after the %" PRIu64
                       " bytes the header describes", rd->path, rd->file_size - h->file_size, h->file_size);
    return HL_OK;
}

static hl_result read_mesh(tf_reader *rd, const tf_header *h, hl_mesh **out)
{
    const hl_transport_info *i = &h->info;
    const tf_section *sec = &h->sec[SEC_MESH];
    hl_mesh *m = calloc(1, sizeof *m);
    if (!m) return hl_fail(rd->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory allocating the mesh");
    *out = m;
    size_t v3 = 3 * (size_t)i->vertex_count, t3 = 3 * (size_t)i->triangle_count;
    m->positions = hl_malloc(rd->ctx, v3 * sizeof(float), "mesh positions");
    m->normals = hl_malloc(rd->ctx, v3 * sizeof(float), "mesh normals");
    m->albedo = hl_malloc(rd->ctx, v3 * sizeof(float), "mesh albedo");
    m->indices = hl_malloc(rd->ctx, t3 * sizeof(uint32_t), "mesh indices");
    if (!m->positions || !m->normals || !m->albedo || !m->indices) return HL_ERR_OUT_OF_MEMORY;
    m->vertex_count = i->vertex_count;
    m->triangle_count = i->triangle_count;
    m->object_vertex_count = i->object_vertex_count;

    void *parts[4] = {m->positions, m->normals, m->albedo, m->indices};
    size_t words[4] = {v3, v3, v3, t3};
    uint64_t off = sec->offset;
    uint32_t crc = 0;
    for (int p = 0; p < 4; p++) {
        hl_result r = read_range(rd, parts[p], 4 * (uint64_t)words[p], off, "mesh section");
        if (r != HL_OK) return r;
        crc = crc_update(crc, parts[p], 4 * words[p]);
        swap_words_if_big_endian(parts[p], words[p]);
        off += 4 * (uint64_t)words[p];
    }
    hl_result r = check_crc(rd, SEC_MESH, sec->crc, crc);
    if (r != HL_OK) return r;
    char msg[256];
    if (mesh_problem(m->vertex_count, m->triangle_count, m->positions, m->normals, m->albedo, m->indices, msg,
                     sizeof msg))
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: mesh: %s", rd->path, msg);
    return HL_OK;
}

static hl_result read_rows(tf_reader *rd, const tf_header *h, hl_transport *t)
{
    const hl_transport_info *i = &h->info;
    const tf_section *sec = &h->sec[SEC_ROWS];
    uint32_t B = i->block_count;
    size_t rec = (size_t)row_record_bytes(B);
    size_t chunk = ((size_t)1 << 20) / rec;
    if (chunk > i->vertex_count) chunk = i->vertex_count;
    uint8_t *buf = hl_malloc(rd->ctx, chunk * rec, "the row table reader");
    if (!buf) return HL_ERR_OUT_OF_MEMORY;
    uint32_t crc = 0;
    hl_result r = HL_OK;
    for (uint64_t v0 = 0; v0 < i->vertex_count && r == HL_OK; v0 += chunk) {
        size_t n = i->vertex_count - v0 < chunk ? (size_t)(i->vertex_count - v0) : chunk;
        r = read_range(rd, buf, (uint64_t)n * rec, sec->offset + (uint64_t)v0 * rec, "row table");
        if (r != HL_OK) break;
        crc = crc_update(crc, buf, n * rec);
        for (size_t k = 0; k < n; k++) {
            const uint8_t *p = buf + k * rec;
            size_t v = (size_t)v0 + k;
            t->row_quant[v].a = HL_AS_F32(get_u32(p));
            t->row_quant[v].b = HL_AS_F32(get_u32(p + 4));
            for (uint32_t b = 0; b < B; b++) t->block_counts[v * B + b] = get_u16(p + 8 + 2 * b);
        }
    }
    free(buf);
    if (r != HL_OK) return r;
    return check_crc(rd, SEC_ROWS, sec->crc, crc);
}

/* Derives row_offset and checks every row against the entries. Runs after
 * all checksums, so it reports structure errors in files that are intact
 * but were written wrongly. */
static hl_result validate_rows(tf_reader *rd, hl_transport *t)
{
    const hl_transport_info *i = &t->info;
    uint32_t B = i->block_count;
    uint64_t off = 0;
    char msg[256];
    for (uint32_t v = 0; v < i->vertex_count; v++) {
        t->row_offset[v] = off;
        uint64_t nnz = 0;
        const uint16_t *counts = t->block_counts + (size_t)v * B;
        if (row_quant_problem(i->quant, t->row_quant[v], msg, sizeof msg))
            return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: vertex %u: %s", rd->path, v, msg);
        if (row_problem(i->N, counts, NULL, &nnz, msg, sizeof msg))
            return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: vertex %u: %s", rd->path, v, msg);
        if (nnz > i->coefficients_kept - off)
            return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: vertex %u: block counts run past coefficients_kept = %" PRIu64,
                           rd->path, v, i->coefficients_kept);
        if (row_problem(i->N, counts, t->entries + 2 * off, &nnz, msg, sizeof msg))
            return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: vertex %u: %s", rd->path, v, msg);
        off += nnz;
    }
    t->row_offset[i->vertex_count] = off;
    if (off != i->coefficients_kept)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: block counts of all vertices sum to %" PRIu64
                       ", coefficients_kept says %" PRIu64, rd->path, off, i->coefficients_kept);
    return HL_OK;
}

hl_result hl_transport_load(hl_context *ctx, const char *path, hl_transport **out)
{
    if (out) *out = NULL;
    if (!path || !out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_transport_load: path and out are required");
    tf_reader *rd = hl_calloc(ctx, 1, sizeof *rd, "the transport reader");
    if (!rd) return HL_ERR_OUT_OF_MEMORY;
    rd->ctx = ctx;
    rd->path = path;
    rd->fd = open(path, O_RDONLY | O_CLOEXEC);
    if (rd->fd < 0) {
        int e = errno;
        free(rd);
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    hl_transport *t = NULL;
    hl_result r = HL_OK;
    struct stat st;
    if (fstat(rd->fd, &st) != 0) {
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot stat: %s", path, strerror(errno));
    } else if (!S_ISREG(st.st_mode)) {
        r = hl_fail(ctx, HL_ERR_IO, "%s: not a regular file", path);
    }
    tf_header h;
    if (r == HL_OK) {
        rd->file_size = (uint64_t)st.st_size;
        r = read_header(rd, &h);
    }
    if (r == HL_OK && (h.sec[SEC_MESH].size > SIZE_MAX / 4 || h.sec[SEC_ROWS].size > SIZE_MAX / 4 ||
                       h.sec[SEC_ENTRIES].size > SIZE_MAX / 4))
        r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: file too large for this host's address space", path);
    if (r == HL_OK) {
        t = hl_calloc(ctx, 1, sizeof *t, "the transport");
        if (!t) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r == HL_OK) {
        t->info = h.info;
        r = read_mesh(rd, &h, &t->mesh);
    }
    if (r == HL_OK) {
        /* Every size below is bounded by the file size checked in
         * read_header: rows need >= 10 bytes per vertex on disk. */
        size_t V = h.info.vertex_count, B = h.info.block_count;
        t->row_quant = hl_malloc(ctx, V * sizeof *t->row_quant, "row quantisation parameters");
        t->block_counts = hl_alloc_big(ctx, V * B * sizeof *t->block_counts, "block counts");
        t->row_offset = hl_malloc(ctx, (V + 1) * sizeof *t->row_offset, "row offsets");
        t->entries = hl_alloc_big(ctx, (size_t)h.sec[SEC_ENTRIES].size, "transport entries");
        if (!t->row_quant || !t->block_counts || !t->row_offset || !t->entries) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r == HL_OK) r = read_rows(rd, &h, t);
    if (r == HL_OK) r = read_range(rd, t->entries, h.sec[SEC_ENTRIES].size, h.sec[SEC_ENTRIES].offset, "entries section");
    if (r == HL_OK)
        r = check_crc(rd, SEC_ENTRIES, h.sec[SEC_ENTRIES].crc,
                      crc_update(0, t->entries, (size_t)h.sec[SEC_ENTRIES].size));
    if (r == HL_OK) r = validate_rows(rd, t);
    close(rd->fd);
    free(rd);
    if (r != HL_OK) {
        hl_transport_destroy(t);
        return r;
    }
    *out = t;
    return HL_OK;
}

void hl_transport_destroy(hl_transport *t)
{
    if (!t) return;
    hl_mesh_destroy(t->mesh);
    free(t->row_quant);
    hl_free_big(t->block_counts);
    free(t->row_offset);
    hl_free_big(t->entries);
    free(t);
}

void hl_transport_query_row(const hl_transport *t, uint32_t v, float *dense)
{
    if (!t || !dense) return;
    const hl_transport_info *i = &t->info;
    memset(dense, 0, (size_t)slot_total(i->N) * sizeof *dense);
    if (v >= i->vertex_count) return;
    const uint8_t *e = t->entries + 2 * t->row_offset[v];
    const uint16_t *counts = t->block_counts + (size_t)v * i->block_count;
    hl_row_quant rq = t->row_quant[v];
    for (uint32_t b = 0; b < i->block_count; b++) {
        float *base = dense + (size_t)b * HL_BLOCK;
        for (uint32_t j = 0; j < counts[b]; j++, e += 2)
            base[e[0]] = hl_dequant(i->quant, e[1], rq.a, rq.b, hl_dither_key(v, b * HL_BLOCK + e[0]));
    }
}

void hl_transport_query_terms(const hl_transport *t, uint32_t v, float *dense)
{
    hl_transport_query_row(t, v, dense);
    if (!t || !dense || v >= t->info.vertex_count) return;
    const hl_row_quant rq = t->row_quant[v];
    const int ex = hl_half_exponent(t->info.quant, rq.a, rq.b);
    for (uint32_t i = 0; i < slot_total(t->info.N); i++)
        if (dense[i] != 0.0f) dense[i] = ldexpf(hl_half_term(dense[i], ex), ex);
}

/* ---------------------------------------------------------------- report */

static const char *rule_name(uint32_t rule)
{
    switch (rule) {
    case HL_TRUNC_ALL: return "all non-zeros";
    case HL_TRUNC_TOPK: return "top-K";
    case HL_TRUNC_ENERGY: return "energy";
    default: return "unknown";
    }
}

static const char *quant_name(uint32_t quant)
{
    switch (quant) {
    case HL_QUANT_LINEAR8: return "linear8 (8-bit linear between the row's min and max)";
    case HL_QUANT_LOG8: return "log8 (sign + 7-bit log magnitude)";
    case HL_QUANT_SQRT8: return "sqrt8 (sign + 7-bit square-root magnitude)";
    default: return "unknown";
    }
}

void hl_transport_describe(const hl_transport *t, const char *path, FILE *f)
{
    if (!t || !f) return;
    const hl_transport_info *i = &t->info;
    uint32_t V = i->vertex_count, B = i->block_count;
    uint64_t min_nnz = UINT64_MAX, max_nnz = 0, nonempty = 0;
    for (uint32_t v = 0; v < V; v++) {
        uint64_t n = t->row_offset[v + 1] - t->row_offset[v];
        if (n < min_nnz) min_nnz = n;
        if (n > max_nnz) max_nnz = n;
        for (uint32_t b = 0; b < B; b++) nonempty += t->block_counts[(size_t)v * B + b] != 0;
    }
    if (V == 0) min_nnz = 0;
    double dv = V ? (double)V : 1.0;
    uint64_t entry_bytes = 2 * i->coefficients_kept;
    uint64_t directions = i->rays_cast + i->rays_culled;

    if (path) {
        struct stat st;
        if (stat(path, &st) == 0)
            fprintf(f, "file               %s (%" PRIu64 " bytes)\n", path, (uint64_t)st.st_size);
        else
            fprintf(f, "file               %s\n", path);
    }
    fprintf(f, "format version     %u\n", i->version);
    fprintf(f, "paraboloid N       %u (2 x %u^2 = %u coefficient slots)\n", i->N, i->N, slot_total(i->N));
    fprintf(f, "cubemap C          %u, supersample %u x %u\n", i->C, i->supersample, i->supersample);
    fprintf(f, "truncation         %s", rule_name(i->rule));
    if (i->rule == HL_TRUNC_TOPK || i->rule == HL_TRUNC_ENERGY) {
        if (i->K)
            fprintf(f, ", K %u", i->K);
        else
            fprintf(f, ", K none");
    }
    if (i->rule == HL_TRUNC_ENERGY) fprintf(f, ", eps %g", (double)i->eps);
    fprintf(f, "\n");
    fprintf(f, "quantisation       %s\n", quant_name(i->quant));
    if (i->ray_offset > 0.0f) fprintf(f, "ray offset         %g x bounding-box diagonal\n", (double)i->ray_offset);
    else fprintf(f, "ray offset         robust (2^-16 of the vertex's largest coordinate or longest edge)\n");
    fprintf(f, "vertices           %u (object %u, ground %u)\n", V, i->object_vertex_count,
            V - i->object_vertex_count);
    fprintf(f, "triangles          %u\n", i->triangle_count);
    fprintf(f, "blocks per vertex  %u of %u slots\n", B, HL_BLOCK);
    fprintf(f, "coefficients kept  %" PRIu64 " (per vertex: mean %.1f, min %" PRIu64 ", max %" PRIu64 ")\n",
            i->coefficients_kept, (double)i->coefficients_kept / dv, min_nnz, max_nnz);
    fprintf(f, "non-empty blocks   %.2f per vertex (of %u)\n", (double)nonempty / dv, B);
    fprintf(f, "rays cast          %" PRIu64 " (%.0f per vertex)\n", i->rays_cast, (double)i->rays_cast / dv);
    fprintf(f, "rays culled        %" PRIu64 " (%.1f%% of all directions)\n", i->rays_culled,
            directions ? 100.0 * (double)i->rays_culled / (double)directions : 0.0);
    fprintf(f, "entry section      %" PRIu64 " bytes (%.1f per vertex)\n", entry_bytes, (double)entry_bytes / dv);
}
