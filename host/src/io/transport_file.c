/* transport_file.c - the transport file (.hlt) writer: streaming rows and
 * entries to their final places in path + ".partial" (locked while a
 * writer has it), checkpoints and resume, and the atomic publish (header,
 * fsync, rename onto path, sync of the directory).
 *
 * A shard writer (precompute --shard i/n) writes the whole mesh but the
 * rows of its own vertices only, under TF_SHARD_MAGIC; a copying writer
 * (merge) takes the mesh section's bytes from another file instead of a
 * mesh in memory.
 *
 * The byte layout lives in host/FORMAT.md and transport_layout.h; the
 * loader is transport_load.c, the report transport_report.c.
 *
 * Depends on: transport_layout.h (header coding, checks, CRC-32 by zlib's
 * crc32_z), hl_internal.h (hl_fail, allocation), POSIX
 * open/pread/pwrite/fsync/rename/ftruncate, flock.
 */
#define _DEFAULT_SOURCE /* flock */
#define _FILE_OFFSET_BITS 64
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/types.h>
#include <unistd.h>

#include "transport_file.h"
#include "transport_layout.h"

/* ---------------------------------------------------------------- streams */

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
    tf_header hdr; /* hdr.shard.count 0: a whole file */
    uint32_t rows_total; /* rows this file holds: V (3 V with a row a channel), or the shard's */
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
    if (hl_tf_pwrite_all(w->fd, s->buf, s->len, s->pos) != 0) return writer_io_error(w, "write");
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
    if (hl_tf_pwrite_all(w->fd, zeros, (size_t)(to - from), from) != 0) return writer_io_error(w, "write");
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

static int info_params_differ(const hl_transport_info *a, const hl_transport_info *b)
{
    return a->N != b->N || a->C != b->C || a->supersample != b->supersample || a->rule != b->rule ||
           a->K != b->K || HL_AS_U32(a->eps) != HL_AS_U32(b->eps) || a->quant != b->quant ||
           HL_AS_U32(a->ray_offset) != HL_AS_U32(b->ray_offset) || a->vertex_count != b->vertex_count ||
           a->object_vertex_count != b->object_vertex_count || a->triangle_count != b->triangle_count ||
           a->block_count != b->block_count || a->basis != b->basis || a->sh_order != b->sh_order ||
           (a->channels == 3) != (b->channels == 3);
}

/* The mesh's agreement with info, and its contents. */
static hl_result mesh_problem(hl_context *ctx, const char *path, const hl_transport_info *info, const hl_mesh *mesh)
{
    char msg[256];
    if (mesh->vertex_count != info->vertex_count || mesh->triangle_count != info->triangle_count ||
        mesh->object_vertex_count != info->object_vertex_count)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: mesh has %u vertices (%u object), %u triangles; info says %u (%u), %u", path,
                       mesh->vertex_count, mesh->object_vertex_count, mesh->triangle_count, info->vertex_count,
                       info->object_vertex_count, info->triangle_count);
    if (!mesh->positions || !mesh->normals || !mesh->albedo || (mesh->triangle_count && !mesh->indices))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: mesh arrays missing", path);
    if (hl_tf_mesh_problem(mesh->vertex_count, mesh->triangle_count, mesh->positions, mesh->normals,
                           mesh->albedo, mesh->indices, msg, sizeof msg))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: mesh: %s", path, msg);
    return HL_OK;
}

/* Checks the arguments and plans the header; no file is touched. mesh may
 * be NULL for a copying writer; shard NULL or of count 0: a whole file. */
static hl_result writer_new(hl_context *ctx, const char *path, const hl_transport_info *info, const hl_mesh *mesh,
                            const tf_shard *shard, hl_tfile_writer **out)
{
    char msg[256];
    *out = NULL;
    if (!path || !*path || !info)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "transport writer: path, info, mesh and out are required");
    if (hl_tf_info_problem(info, msg, sizeof msg))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: transport parameters: %s", path, msg);
    tf_shard sh = {0, 0, 0, info->vertex_count};
    if (shard && shard->count) {
        if (shard->index >= shard->count || shard->count > info->vertex_count)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "%s: shard %u of %u: the index must be below the count, and the count at most the %u "
                           "vertices", path, shard->index, shard->count, info->vertex_count);
        sh.index = shard->index;
        sh.count = shard->count;
        tf_shard_range(info->vertex_count, sh.index, sh.count, &sh.first, &sh.end);
    }
    hl_result r = mesh ? mesh_problem(ctx, path, info, mesh) : HL_OK;
    if (r != HL_OK) return r;

    hl_tfile_writer *w = hl_calloc(ctx, 1, sizeof *w, "the transport writer");
    if (!w) return HL_ERR_OUT_OF_MEMORY;
    w->ctx = ctx;
    w->fd = -1;
    w->path = hl_tf_path_with(ctx, path, NULL);
    w->tmp_path = hl_tf_path_with(ctx, path, ".partial");
    if (!w->path || !w->tmp_path) {
        writer_free(w);
        return HL_ERR_OUT_OF_MEMORY;
    }

    tf_header *h = &w->hdr;
    h->info = *info;
    h->shard = sh;
    /* a row a channel: the range's rows for red, then green, then blue */
    w->rows_total = (sh.end - sh.first) * (info->channels == 3 ? 3u : 1u);
    h->info.version = TF_VERSION;
    h->info.coefficients_kept = 0;
    h->info.rays_cast = h->info.rays_culled = 0;
    h->header_size = TF_HEADER_SIZE;
    h->sec[SEC_MESH].offset = TF_HEADER_SIZE;
    h->sec[SEC_MESH].size = mesh_bytes(info->vertex_count, info->triangle_count);
    h->sec[SEC_ROWS].offset = align_up(h->sec[SEC_MESH].offset + h->sec[SEC_MESH].size);
    h->sec[SEC_ROWS].size = (uint64_t)w->rows_total * row_record_bytes(info->block_count);
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

/* Creates, locks and empties the partial file of a new writer. */
static hl_result writer_create(hl_context *ctx, hl_tfile_writer *w)
{
    w->fd = open(w->tmp_path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (w->fd < 0) {
        int e = errno;
        hl_result r = hl_fail(ctx, HL_ERR_IO, "%s: cannot create %s: %s", w->path, w->tmp_path, strerror(e));
        writer_free(w);
        return r;
    }
    hl_result r = writer_lock(w);
    if (r == HL_OK && ftruncate(w->fd, 0) != 0) r = writer_io_error(w, "truncate");
    if (r != HL_OK) writer_free(w); /* not ours to remove */
    return r;
}

/* The mesh goes out through the rows stream, which then restarts at the
 * row table: one buffer serves both. */
static hl_result write_mesh(hl_tfile_writer *w, const hl_mesh *mesh)
{
    size_t v3 = 3 * (size_t)mesh->vertex_count;
    tf_stream *s = &w->rows;
    stream_start(s, w->hdr.sec[SEC_MESH].offset);
    hl_result r = put_words(w, s, mesh->positions, v3);
    if (r == HL_OK) r = put_words(w, s, mesh->normals, v3);
    if (r == HL_OK) r = put_words(w, s, mesh->albedo, v3);
    if (r == HL_OK) r = put_words(w, s, mesh->indices, 3 * (size_t)mesh->triangle_count);
    if (r == HL_OK) r = stream_flush(w, s);
    w->hdr.sec[SEC_MESH].crc = s->crc;
    return r;
}

/* After the mesh: the padding, the streams at their sections and the
 * first checkpoint. Aborts the writer on failure. */
static hl_result writer_start_rows(hl_tfile_writer *w, hl_tfile_writer **out)
{
    tf_header *h = &w->hdr;
    hl_result r = write_padding(w, h->sec[SEC_MESH].offset + h->sec[SEC_MESH].size, h->sec[SEC_ROWS].offset);
    if (r != HL_OK) {
        hl_tfile_writer_abort(w);
        return r;
    }
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

hl_result hl_tfile_writer_open_shard(hl_context *ctx, const char *path, const hl_transport_info *info,
                                     const hl_mesh *mesh, uint32_t shard_index, uint32_t shard_count,
                                     hl_tfile_writer **out)
{
    if (out) *out = NULL;
    if (!out || !mesh)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "transport writer: path, info, mesh and out are required");
    tf_shard sh = {shard_index, shard_count, 0, 0};
    hl_tfile_writer *w;
    hl_result r = writer_new(ctx, path, info, mesh, &sh, &w);
    if (r == HL_OK) r = writer_create(ctx, w);
    if (r != HL_OK) return r;
    r = write_mesh(w, mesh);
    if (r != HL_OK) {
        hl_tfile_writer_abort(w);
        return r;
    }
    return writer_start_rows(w, out);
}

hl_result hl_tfile_writer_open(hl_context *ctx, const char *path, const hl_transport_info *info,
                               const hl_mesh *mesh, hl_tfile_writer **out)
{
    return hl_tfile_writer_open_shard(ctx, path, info, mesh, 0, 0, out);
}

/* Copying buffer of the mesh section: as the loader's row reader. */
#define TF_COPY_BYTES ((size_t)1 << 20)

hl_result hl_tfile_writer_open_copy(hl_context *ctx, const char *path, const hl_transport_info *info, int src_fd,
                                    const char *src_path, uint64_t mesh_offset, uint32_t mesh_crc,
                                    hl_tfile_writer **out)
{
    if (out) *out = NULL;
    if (!out || src_fd < 0 || !src_path)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "transport writer: path, info, source and out are required");
    hl_tfile_writer *w;
    hl_result r = writer_new(ctx, path, info, NULL, NULL, &w);
    if (r == HL_OK) r = writer_create(ctx, w);
    if (r != HL_OK) return r;
    uint8_t *buf = hl_malloc(ctx, TF_COPY_BYTES, "the mesh copy");
    uint64_t left = w->hdr.sec[SEC_MESH].size, from = mesh_offset, to = w->hdr.sec[SEC_MESH].offset;
    uint32_t crc = 0;
    if (!buf) r = HL_ERR_OUT_OF_MEMORY;
    while (r == HL_OK && left > 0) {
        size_t k = left < TF_COPY_BYTES ? (size_t)left : TF_COPY_BYTES;
        int e = hl_tf_pread_all(src_fd, buf, k, from);
        if (e != 0)
            r = hl_fail(ctx, e < 0 ? HL_ERR_IO : HL_ERR_FORMAT, "%s: cannot read its mesh section: %s", src_path,
                        e < 0 ? strerror(errno) : "the file ends inside it");
        else if (hl_tf_pwrite_all(w->fd, buf, k, to) != 0) r = writer_io_error(w, "write");
        crc = crc_update(crc, buf, k);
        from += k;
        to += k;
        left -= k;
    }
    free(buf);
    if (r == HL_OK && crc != mesh_crc)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: checksum mismatch in the mesh section (stored %08x, computed %08x)",
                    src_path, (unsigned)mesh_crc, (unsigned)crc);
    if (r != HL_OK) {
        hl_tfile_writer_abort(w);
        return r;
    }
    w->hdr.sec[SEC_MESH].crc = crc;
    return writer_start_rows(w, out);
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
    hl_tf_header_encode(&p, TF_PARTIAL_MAGIC, w->appended, bytes);
    if (hl_tf_pwrite_all(w->fd, bytes, sizeof bytes, 0) != 0) return writer_io_error(w, "write");
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
        if (hl_tf_pread_all(w->fd, buf, k, off) != 0) {
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
    return hl_tfile_writer_resume_shard(ctx, path, info, mesh, 0, 0, out, done);
}

/* A whole file's range is not stored (its shard words are zero). */
static int shard_differs(const tf_shard *a, const tf_shard *b)
{
    return a->index != b->index || a->count != b->count || (a->count && (a->first != b->first || a->end != b->end));
}

hl_result hl_tfile_writer_resume_shard(hl_context *ctx, const char *path, const hl_transport_info *info,
                                       const hl_mesh *mesh, uint32_t shard_index, uint32_t shard_count,
                                       hl_tfile_writer **out, hl_tfile_progress *done)
{
    if (out) *out = NULL;
    memset(done, 0, sizeof *done);
    if (!out || !mesh)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "transport writer: path, info, mesh and out are required");
    tf_shard sh = {shard_index, shard_count, 0, 0};
    hl_tfile_writer *w;
    hl_result r = writer_new(ctx, path, info, mesh, &sh, &w);
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
    if (r == HL_OK && hl_tf_pread_all(w->fd, bytes, sizeof bytes, 0) != 0) why = "too short to hold a checkpoint";
    if (r == HL_OK && !why) {
        hl_tf_header_decode(bytes, &p);
        uint32_t appended = get_u32(bytes + H_APPENDED);
        uint64_t rows = (uint64_t)appended * row_record_bytes(h->info.block_count);
        if (memcmp(bytes, TF_PARTIAL_MAGIC, 8) != 0) why = "not a partial transport file";
        else if (get_u32(bytes + H_HEADER_CRC) != crc_update(0, bytes, H_HEADER_CRC)) why = "its checkpoint is corrupt";
        else if (get_u32(bytes + H_VERSION) != TF_VERSION) why = "written by another format version";
        else if (info_params_differ(&p.info, &h->info)) why = "made with other parameters or another mesh";
        else if (shard_differs(&p.shard, &h->shard))
            why = p.shard.count ? (h->shard.count ? "made for another shard" : "made for a shard (--shard)")
                                : "made for a whole run, without --shard";
        else if (p.sec[SEC_MESH].offset != h->sec[SEC_MESH].offset || p.sec[SEC_MESH].size != h->sec[SEC_MESH].size ||
                 p.sec[SEC_MESH].crc != mesh_crc(mesh))
            why = "made from another mesh";
        else if (appended > w->rows_total || p.sec[SEC_ROWS].offset != h->sec[SEC_ROWS].offset ||
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
    if (vertex_count > w->rows_total - w->appended)
        return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: append of %u rows after %u would exceed the %u rows of the file", w->path,
                       vertex_count, w->appended, w->rows_total);

    /* Validate everything first so that a refusal leaves the file as it was. */
    uint32_t B = info->block_count;
    char msg[256];
    for (uint32_t i = 0; i < vertex_count; i++) {
        uint32_t v = w->hdr.shard.first + (w->appended + i) % (w->hdr.shard.end - w->hdr.shard.first);
        uint64_t sum = 0;
        if (hl_tf_row_quant_problem(info->quant, rq[i], msg, sizeof msg))
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: %s", w->path, v, msg);
        if (hl_tf_row_problem(info->N, block_counts + (size_t)i * B, NULL, &sum, msg, sizeof msg))
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: %s", w->path, v, msg);
        if (sum != nnz[i])
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: block counts sum to %" PRIu64
                           " but nnz is %u", w->path, v, sum, nnz[i]);
        if (nnz[i] && !entries)
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: entries missing", w->path, v);
        if (i + 1 < vertex_count && 2 * (size_t)nnz[i] > entry_stride_bytes)
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex %u: %u entries overrun the stride of %zu bytes",
                           w->path, v, nnz[i], entry_stride_bytes);
        if (nnz[i] && (hl_tf_row_problem(info->N, block_counts + (size_t)i * B, entries + i * entry_stride_bytes,
                                         &sum, msg, sizeof msg) ||
                       hl_tf_row_slots_problem(info->N, tf_slot_limit(info), block_counts + (size_t)i * B,
                                               entries + i * entry_stride_bytes, msg, sizeof msg)))
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
    } else if (w->appended != w->rows_total) {
        r = hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: finished after %u of %u rows", w->path, w->appended,
                    w->rows_total);
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
        hl_tf_header_encode(h, h->shard.count ? TF_SHARD_MAGIC : TF_MAGIC, 0, bytes);
        r = write_padding(w, h->sec[SEC_ROWS].offset + h->sec[SEC_ROWS].size, h->sec[SEC_ENTRIES].offset);
        if (r == HL_OK && hl_tf_pwrite_all(w->fd, bytes, sizeof bytes, 0) != 0) r = writer_io_error(w, "write");
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
