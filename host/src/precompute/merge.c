/* merge.c - joining the shard files of a precompute spread over machines
 * (precompute --shard i/n) into one transport file (hl_transport_merge).
 *
 * Every shard holds the whole mesh and the rows of its own contiguous
 * vertices (transport_layout.h, tf_shard_range), so the joined file is the
 * mesh of one shard, the shards' row tables one after the other and their
 * entries likewise; the header's counters are the sums. The output goes
 * through the ordinary writer (transport_file.c), which re-encodes and
 * re-checks each row and computes the checksums, so the bytes are those
 * of one unsharded run.
 *
 * It streams: first every shard's header is read and checked (files
 * closed again, so a thousand shards need no thousand descriptors), then
 * each shard is reopened in order, its header compared with the one read
 * first, and its rows and entries read through two 1 MiB buffers, checked
 * (checksums, counts, every row) and appended. What it holds: those two
 * buffers, the writer's two 256 KiB streams, a 1 MiB buffer while the mesh
 * is copied, and 200 bytes a shard.
 *
 * Depends on: transport_file.h (the writer), transport_layout.h (header
 * coding, checks), hl_internal.h, haarlight_tools.h (the declarations),
 * POSIX open/fstat.
 */
#define _POSIX_C_SOURCE 200809L
#define _FILE_OFFSET_BITS 64
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "haarlight_tools.h"
#include "transport_file.h"
#include "transport_layout.h"
#include "values_file.h"

/* A section reader's buffer: larger than one vertex's largest run of
 * entries (2 x 2 N^2 bytes, 256 KiB at N = 256) and its row record, so
 * that a vertex is always one contiguous piece of it. */
#define MERGE_READ_BYTES ((size_t)1 << 20)
/* Vertices between polls of the context's cancellation. */
#define MERGE_POLL_VERTICES 4096u

typedef struct shard_in {
    const char *path;
    uint8_t bytes[TF_HEADER_SIZE]; /* the header as read first */
    tf_header h;
    dev_t dev;
    ino_t ino;
    /* with a row a channel, the planes are merged one after the other:
       what of its sections the planes before took, and their checksums
       so far */
    uint64_t rows_taken, ents_taken, kept;
    uint32_t rows_crc, ents_crc;
} shard_in;

/* ---------------------------------------------------------------- headers */

/* Opens a shard read-only; the caller closes *fd. */
static hl_result open_shard(hl_context *ctx, shard_in *s, int *fd, uint64_t *size)
{
    *fd = open(s->path, O_RDONLY | O_CLOEXEC);
    if (*fd < 0) return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", s->path, strerror(errno));
    struct stat st;
    if (fstat(*fd, &st) != 0 || !S_ISREG(st.st_mode)) return hl_fail(ctx, HL_ERR_IO, "%s: not a regular file", s->path);
    s->dev = st.st_dev;
    s->ino = st.st_ino;
    *size = (uint64_t)st.st_size;
    return HL_OK;
}

/* Reads and checks one shard's header and its file's size. */
static hl_result read_shard_header(hl_context *ctx, shard_in *s, int fd, uint64_t size)
{
    uint8_t *b = s->bytes;
    int k = hl_tf_pread_all(fd, b, size < TF_HEADER_SIZE ? (size_t)size : TF_HEADER_SIZE, 0);
    if (k < 0) return hl_fail(ctx, HL_ERR_IO, "%s: cannot read: %s", s->path, strerror(errno));
    if (size >= 8 && memcmp(b, TF_MAGIC, 8) == 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: a whole transport file, not a shard: merge joins the files of precompute --shard I/N", s->path);
    if (size >= 8 && memcmp(b, TF_PARTIAL_MAGIC, 8) == 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: an unfinished precompute (.partial), not a shard: finish it with precompute --shard I/N "
                       "--resume", s->path);
    if (size < 8 || memcmp(b, TF_SHARD_MAGIC, 8) != 0)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not a shard of a haarlight precompute", s->path);
    if (size < TF_HEADER_SIZE)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated: expected at least %u bytes, file has %" PRIu64, s->path,
                       TF_HEADER_SIZE, size);
    if (get_u32(b + H_VERSION) != TF_VERSION)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: version %" PRIu32 ", this build reads %u", s->path,
                       get_u32(b + H_VERSION), TF_VERSION);
    if (get_u32(b + H_HEADER_SIZE) != TF_HEADER_SIZE || get_u32(b + H_HEADER_CRC) != crc_update(0, b, H_HEADER_CRC))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: checksum mismatch in the header (corrupt)", s->path);
    hl_tf_header_decode(b, &s->h);
    char msg[256];
    if (hl_tf_shard_header_problem(&s->h, b, msg, sizeof msg))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: header: %s", s->path, msg);
    if (size < s->h.file_size)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated: expected %" PRIu64 " bytes, file has %" PRIu64, s->path,
                       s->h.file_size, size);
    if (size > s->h.file_size)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: %" PRIu64 " bytes of trailing data after the %" PRIu64
                       " bytes the header describes", s->path, size - s->h.file_size, s->h.file_size);
    return HL_OK;
}

/* How a header field prints in a message. */
enum { AS_INT, AS_FLOAT, AS_HEX };

/* The first header field in which two shards differ, into msg; 0 when
 * they are shards of one precompute. */
static int shards_differ(const tf_header *a, const tf_header *b, char *msg, size_t n)
{
    const hl_transport_info *x = &a->info, *y = &b->info;
    struct {
        const char *name;
        uint32_t u, v;
        int as;
    } f[] = {
        {"the vertex count", x->vertex_count, y->vertex_count, AS_INT},
        {"the object's vertex count (is one --ground and the other not?)", x->object_vertex_count,
         y->object_vertex_count, AS_INT},
        {"the triangle count", x->triangle_count, y->triangle_count, AS_INT},
        {"the mesh (its section's CRC-32)", a->sec[SEC_MESH].crc, b->sec[SEC_MESH].crc, AS_HEX},
        {"N (-N)", x->N, y->N, AS_INT},
        {"C (-C)", x->C, y->C, AS_INT},
        {"the supersampling (--supersample)", x->supersample, y->supersample, AS_INT},
        {"the truncation rule (--terms, --energy)", x->rule, y->rule, AS_INT},
        {"K (--terms)", x->K, y->K, AS_INT},
        {"eps (--energy)", HL_AS_U32(x->eps), HL_AS_U32(y->eps), AS_FLOAT},
        {"the quantisation (--quant)", x->quant, y->quant, AS_INT},
        {"the ray offset (--ray-offset)", HL_AS_U32(x->ray_offset), HL_AS_U32(y->ray_offset), AS_FLOAT},
        {"the basis (--basis)", x->basis, y->basis, AS_INT},
        {"the spherical-harmonic order or cube side (--sh-order, --cube-side)", x->sh_order, y->sh_order, AS_INT},
        {"the bounces (--bounces)", x->bounces, y->bounces, AS_INT},
        {"the rows a vertex (coloured bounces)", x->channels, y->channels, AS_INT},
        {"the shard count (--shard I/N)", a->shard.count, b->shard.count, AS_INT},
    };
    for (size_t i = 0; i < sizeof f / sizeof f[0]; i++) {
        if (f[i].u == f[i].v) continue;
        if (f[i].as == AS_FLOAT)
            return snprintf(msg, n, "%s differs (%.9g and %.9g)", f[i].name, (double)HL_AS_F32(f[i].u),
                            (double)HL_AS_F32(f[i].v)), 1;
        if (f[i].as == AS_HEX)
            return snprintf(msg, n, "%s differs (%08" PRIx32 " and %08" PRIx32 ")", f[i].name, f[i].u, f[i].v), 1;
        return snprintf(msg, n, "%s differs (%" PRIu32 " and %" PRIu32 ")", f[i].name, f[i].u, f[i].v), 1;
    }
    return 0;
}

static int by_index(const void *a, const void *b)
{
    const shard_in *x = a, *y = b;
    return (x->h.shard.index > y->h.shard.index) - (x->h.shard.index < y->h.shard.index);
}

/* Every header read and checked, all of one precompute, each index once
 * and none missing; sorted by index. */
static hl_result check_set(hl_context *ctx, shard_in *s, uint32_t count)
{
    for (uint32_t i = 0; i < count; i++) {
        int fd = -1;
        uint64_t size = 0;
        hl_result r = open_shard(ctx, &s[i], &fd, &size);
        if (r == HL_OK) r = read_shard_header(ctx, &s[i], fd, size);
        if (fd >= 0) close(fd);
        if (r != HL_OK) return r;
        char msg[256];
        if (i > 0 && shards_differ(&s[0].h, &s[i].h, msg, sizeof msg))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s and %s are not shards of one precompute: %s", s[0].path,
                           s[i].path, msg);
    }
    qsort(s, count, sizeof *s, by_index);
    for (uint32_t i = 1; i < count; i++)
        if (s[i].h.shard.index == s[i - 1].h.shard.index)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s and %s are both shard %u of %u", s[i - 1].path, s[i].path,
                           s[i].h.shard.index, s[i].h.shard.count);
    uint32_t n = s[0].h.shard.count;
    if (count == n) return HL_OK;
    uint32_t next = 0, k = 0;
    char list[256] = "";
    size_t len = 0;
    for (uint32_t i = 0; i <= count && len < sizeof list - 32; i++) { /* the gaps between present indices */
        uint32_t upto = i < count ? s[i].h.shard.index : n;
        for (; next < upto && len < sizeof list - 32; next++, k++)
            len += (size_t)snprintf(list + len, sizeof list - len, "%s%u", k ? ", " : "", next);
        next = upto + 1;
    }
    return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%u of %u shards given (%s ...): shard%s %s%s missing", count, n,
                   s[0].path, n - count == 1 ? "" : "s", list, len >= sizeof list - 32 ? ", ..." : "");
}

/* ---------------------------------------------------------------- rows */

/* One section of a shard read in order through a buffer, checksummed as
 * it is read. */
typedef struct sec_reader {
    hl_context *ctx;
    const char *path, *what;
    int fd;
    uint64_t pos, left; /* next file offset to read; section bytes not yet read */
    uint8_t *buf;
    size_t at, len;
    uint32_t crc;   /* of the bytes taken */
    uint64_t taken;
} sec_reader;

/* The next n bytes (n <= MERGE_READ_BYTES) at *p, valid until the next call. */
static hl_result take(sec_reader *r, size_t n, uint32_t vertex, const uint8_t **p)
{
    if (r->len - r->at < n) {
        memmove(r->buf, r->buf + r->at, r->len - r->at);
        r->len -= r->at;
        r->at = 0;
        size_t want = MERGE_READ_BYTES - r->len;
        if (want > r->left) want = (size_t)r->left;
        int k = hl_tf_pread_all(r->fd, r->buf + r->len, want, r->pos);
        if (k != 0)
            return hl_fail(r->ctx, k < 0 ? HL_ERR_IO : HL_ERR_FORMAT, "%s: cannot read the %s: %s", r->path, r->what,
                           k < 0 ? strerror(errno) : "the file ends inside it (changed while merging?)");
        r->len += want;
        r->pos += want;
        r->left -= want;
        if (r->len < n)
            return hl_fail(r->ctx, HL_ERR_FORMAT, "%s: vertex %u: its %s run past the section's end", r->path, vertex,
                           r->what);
    }
    *p = r->buf + r->at;
    /* what is taken, not what is read ahead: a plane's reader may read
       into the next plane's bytes, which that plane's reader takes again */
    r->crc = crc_update(r->crc, *p, n);
    r->at += n;
    r->taken += n;
    return HL_OK;
}

/* From byte `from` of the section on, its checksum so far crc. */
static void reader_start(sec_reader *r, hl_context *ctx, const shard_in *s, int fd, int sec, const char *what,
                         uint8_t *buf, uint64_t from, uint32_t crc)
{
    *r = (sec_reader){.ctx = ctx, .path = s->path, .what = what, .fd = fd, .buf = buf, .crc = crc};
    r->pos = s->h.sec[sec].offset + from;
    r->left = s->h.sec[sec].size - from;
}

/* Checks one row of shard s as the loader would and appends it. */
static hl_result merge_row(hl_tfile_writer *w, const shard_in *s, sec_reader *rows, sec_reader *ents, uint32_t v,
                           uint64_t *kept)
{
    const hl_transport_info *i = &s->h.info;
    uint32_t B = i->block_count;
    const uint8_t *rec, *e = NULL;
    hl_result r = take(rows, (size_t)row_record_bytes(B), v, &rec);
    if (r != HL_OK) return r;
    hl_row_quant rq = {HL_AS_F32(get_u32(rec)), HL_AS_F32(get_u32(rec + 4))};
    uint16_t counts[TF_MAX_BLOCKS];
    for (uint32_t b = 0; b < B; b++) counts[b] = get_u16(rec + 8 + 2 * b);
    char msg[256];
    uint64_t nnz = 0;
    if (hl_tf_row_quant_problem(i->quant, rq, msg, sizeof msg) || hl_tf_row_problem(i->N, counts, NULL, &nnz, msg, sizeof msg))
        return hl_fail(rows->ctx, HL_ERR_FORMAT, "%s: vertex %u: %s", s->path, v, msg);
    if (nnz > i->coefficients_kept - *kept)
        return hl_fail(rows->ctx, HL_ERR_FORMAT, "%s: vertex %u: block counts run past coefficients_kept = %" PRIu64,
                       s->path, v, i->coefficients_kept);
    if (nnz) r = take(ents, 2 * (size_t)nnz, v, &e);
    if (r != HL_OK) return r;
    if (nnz && hl_tf_row_problem(i->N, counts, e, &nnz, msg, sizeof msg))
        return hl_fail(rows->ctx, HL_ERR_FORMAT, "%s: vertex %u: %s", s->path, v, msg);
    *kept += nnz;
    uint32_t nz = (uint32_t)nnz;
    return hl_tfile_writer_append(w, 1, &rq, counts, e, 2 * (size_t)nnz, &nz);
}

/* Reopens shard s, makes sure its header is the one checked, and appends
 * its rows of plane c (of planes: 1, or 3 with a row a channel); after its
 * last plane its checksums and its count of entries must hold. */
static hl_result merge_shard(hl_context *ctx, hl_tfile_writer *w, shard_in *s, uint8_t *bufs, uint32_t c,
                             uint32_t planes, hl_merge_stats *st)
{
    int fd = -1;
    uint64_t size = 0;
    uint8_t now[TF_HEADER_SIZE];
    hl_result r = open_shard(ctx, s, &fd, &size);
    if (r == HL_OK && (size != s->h.file_size || hl_tf_pread_all(fd, now, sizeof now, 0) != 0 ||
                       memcmp(now, s->bytes, sizeof now) != 0))
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: changed while merging", s->path);
    sec_reader rows, ents;
    reader_start(&rows, ctx, s, fd, SEC_ROWS, "row table", bufs, s->rows_taken, s->rows_crc);
    reader_start(&ents, ctx, s, fd, SEC_ENTRIES, "entries", bufs + MERGE_READ_BYTES, s->ents_taken, s->ents_crc);
    uint64_t kept = s->kept;
    for (uint32_t v = s->h.shard.first; r == HL_OK && v < s->h.shard.end; v++) {
        r = merge_row(w, s, &rows, &ents, v, &kept);
        if (r == HL_OK && (v - s->h.shard.first) % MERGE_POLL_VERTICES == 0 && hl_context_cancelled(ctx))
            r = hl_fail(ctx, HL_ERR_INTERRUPTED, "interrupted while merging %s", s->path);
    }
    if (fd >= 0) close(fd);
    if (r != HL_OK) return r;
    s->rows_taken += rows.taken;
    s->ents_taken += ents.taken;
    s->rows_crc = rows.crc;
    s->ents_crc = ents.crc;
    s->kept = kept;
    if (c + 1 < planes) return HL_OK;
    if (s->rows_taken != s->h.sec[SEC_ROWS].size || rows.crc != s->h.sec[SEC_ROWS].crc)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: checksum mismatch in the row table section (corrupt)", s->path);
    if (s->ents_taken != s->h.sec[SEC_ENTRIES].size || kept != s->h.info.coefficients_kept)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: block counts sum to %" PRIu64 ", coefficients_kept says %" PRIu64,
                       s->path, kept, s->h.info.coefficients_kept);
    if (ents.crc != s->h.sec[SEC_ENTRIES].crc)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: checksum mismatch in the entries section (corrupt)", s->path);
    st->bytes_read += s->h.file_size;
    return HL_OK;
}

/* ---------------------------------------------------------------- public */

void hl_shard_range(uint32_t vertex_count, uint32_t index, uint32_t count, uint32_t *first, uint32_t *end)
{
    if (count == 0 || index >= count) {
        *first = *end = 0;
        return;
    }
    tf_shard_range(vertex_count, index, count, first, end);
}

/* The output must not be one of its inputs: it is renamed over at the end. */
static hl_result output_is_input(hl_context *ctx, const char *out_path, const shard_in *s, uint32_t count)
{
    struct stat st;
    if (stat(out_path, &st) != 0) return HL_OK;
    for (uint32_t i = 0; i < count; i++)
        if (st.st_dev == s[i].dev && st.st_ino == s[i].ino)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: the output is one of the shards (%s)", out_path, s[i].path);
    return HL_OK;
}

hl_result hl_transport_merge(hl_context *ctx, const char *out_path, const char *const *shard_paths, uint32_t count,
                             hl_merge_stats *stats)
{
    hl_merge_stats st = {0};
    double t0 = hl_now();
    if (stats) *stats = st;
    if (!out_path || !*out_path || !shard_paths || count == 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "merge: an output and at least one shard are required");
    shard_in *s = hl_calloc(ctx, count, sizeof *s, "the shard headers");
    uint8_t *bufs = hl_malloc(ctx, 2 * MERGE_READ_BYTES, "the shard readers");
    hl_result r = s && bufs ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    for (uint32_t i = 0; r == HL_OK && i < count; i++) s[i].path = shard_paths[i];
    if (r == HL_OK) r = check_set(ctx, s, count);
    if (r == HL_OK) r = output_is_input(ctx, out_path, s, count);
    hl_transport_info info = r == HL_OK ? s[0].h.info : (hl_transport_info){0};
    hl_tfile_writer *w = NULL;
    if (r == HL_OK) {
        int fd = -1;
        uint64_t size;
        r = open_shard(ctx, &s[0], &fd, &size);
        if (r == HL_OK)
            r = hl_tfile_writer_open_copy(ctx, out_path, &info, fd, s[0].path, s[0].h.sec[SEC_MESH].offset,
                                          s[0].h.sec[SEC_MESH].crc, &w);
        if (fd >= 0) close(fd);
    }
    info.coefficients_kept = info.rays_cast = info.rays_culled = 0;
    /* a row a channel: the red rows of every shard, then the green, then
       the blue, as one run writes them */
    const uint32_t planes = info.channels == 3 ? 3 : 1;
    for (uint32_t c = 0; c < planes; c++)
        for (uint32_t i = 0; r == HL_OK && i < count; i++) r = merge_shard(ctx, w, &s[i], bufs, c, planes, &st);
    for (uint32_t i = 0; r == HL_OK && i < count; i++) {
        info.coefficients_kept += s[i].h.info.coefficients_kept;
        info.rays_cast += s[i].h.info.rays_cast;
        info.rays_culled += s[i].h.info.rays_culled;
    }
    if (r == HL_OK) {
        r = hl_tfile_writer_finish(w, &info);
        w = NULL;
    }
    hl_tfile_writer_abort(w);
    if (r == HL_OK) r = hl_vfile_merge(ctx, out_path, shard_paths, count, &st.values);
    if (r == HL_OK) {
        st.shards = count;
        st.vertices = info.vertex_count;
        st.coefficients_kept = info.coefficients_kept;
        struct stat o;
        st.bytes_written = stat(out_path, &o) == 0 ? (uint64_t)o.st_size : 0;
        st.seconds = hl_now() - t0;
        if (stats) *stats = st;
    }
    free(s);
    free(bufs);
    return r;
}
