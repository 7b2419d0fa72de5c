/* transport_load.c - the transport file (.hlt) loader (hl_transport_load)
 * with its checks, and the loaded transport's queries and release.
 *
 * The reader trusts nothing: every size is checked against the header and
 * the real file size before anything is allocated, every section carries a
 * CRC-32, and the contents are validated after the checksums so that a
 * forged but consistent file is still refused with a message naming the
 * vertex or triangle. The byte layout lives in host/FORMAT.md and
 * transport_layout.h.
 *
 * Depends on: transport_layout.h (header decoding, checks, CRC-32 by zlib's
 * crc32_z), hl_internal.h (hl_fail, allocation), hl_mesh_destroy (mesh.c),
 * half.h (hl_transport_query_terms), POSIX open/pread/fstat.
 */
#define _POSIX_C_SOURCE 200809L /* pread, pwrite, O_CLOEXEC */
#define _FILE_OFFSET_BITS 64
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include "half.h"
#include "transport_layout.h"

static const char *const section_names[SEC_COUNT] = {"mesh", "row table", "entries"};

/* ---------------------------------------------------------------- bytes */

/* In-place conversion of 32-bit words between file order and host order. */
static void swap_words_if_big_endian(void *data, size_t words)
{
    if (tf_host_little_endian()) return;
    uint8_t *p = data;
    for (size_t i = 0; i < words; i++, p += 4) {
        uint32_t v = get_u32(p);
        memcpy(p, &v, 4);
    }
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
    int k = hl_tf_pread_all(rd->fd, dst, (size_t)bytes, off);
    if (k < 0) return hl_fail(rd->ctx, HL_ERR_IO, "%s: cannot read the %s: %s", rd->path, what, strerror(errno));
    if (k > 0)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: truncated while reading the %s (file shrank?)", rd->path, what);
    return HL_OK;
}

/* The entries are read in pieces of this many bytes, each piece's
 * checksum taken while it is in cache (one pass over memory, not two), and
 * a file this big or bigger shows a progress line. */
#define TF_LOAD_PIECE ((size_t)64 << 20)
#define TF_LOAD_PROGRESS ((uint64_t)256 << 20)

/* The pieces are taken in turn by the context's threads, so the kernel's
 * zeroing of the fresh pages, the copy and the checksum spread over the
 * cores (on the 1.28 GB dragon they were a single core's 2 s); the pieces'
 * CRCs are then joined in file order (zlib's crc32_combine), the CRC one
 * pass would give. */
/* Tests: smaller pieces (HL_TEST_LOAD_PIECE bytes) and row chunks
 * (HL_TEST_ROW_CHUNK vertices), so that a small file takes the joined
 * checksums and the threaded row checks. */
static size_t test_size(const char *name, size_t normal)
{
    const char *s = getenv(name);
    const unsigned long long v = s ? strtoull(s, NULL, 10) : 0;
    return v > 0 && v < normal ? (size_t)v : normal;
}

/* Two zeroed tables of n entries each (of sa and sb bytes) for a threaded
 * pass; 0, with neither kept, when out of memory. */
static int job_tables(hl_context *ctx, size_t n, size_t sa, void **a, size_t sb, void **b, const char *what)
{
    *a = hl_calloc(ctx, n ? n : 1, sa, what);
    *b = *a ? hl_calloc(ctx, n ? n : 1, sb, what) : NULL;
    if (!*b) {
        free(*a);
        *a = NULL;
    }
    return *b != NULL;
}

/* fn on the context's threads, no more threads than items. */
static void run_on_threads(hl_context *ctx, size_t items, void *(*fn)(void *), void *arg)
{
    const int threads = hl_context_threads(ctx);
    if (items) hl_run_threads((size_t)threads < items ? threads : (int)items, fn, arg);
}

/* The CRC of bytes in pieces of `piece` from each piece's own CRC, joined
 * in order: the CRC one pass would give. */
static uint32_t join_crcs(const uint32_t *crc, size_t npieces, uint64_t bytes, size_t piece)
{
    uint32_t c = npieces ? crc[0] : 0;
    for (size_t p = 1; p < npieces; p++) {
        const uint64_t at = (uint64_t)p * piece;
        c = (uint32_t)crc32_combine(c, crc[p], (z_off_t)(bytes - at < piece ? bytes - at : piece));
    }
    return c;
}

typedef struct crc_job {
    const uint8_t *data;
    uint64_t bytes;
    size_t piece, npieces;
    uint32_t *crc;
    atomic_size_t next;
} crc_job;

static void *crc_worker(void *arg)
{
    crc_job *j = arg;
    for (size_t p; (p = atomic_fetch_add(&j->next, 1)) < j->npieces;) {
        const uint64_t at = (uint64_t)p * j->piece;
        j->crc[p] = crc_update(0, j->data + at, j->bytes - at < j->piece ? (size_t)(j->bytes - at) : j->piece);
    }
    return NULL;
}

hl_result hl_tf_crc_threads(hl_context *ctx, const void *data, uint64_t bytes, uint32_t *crc)
{
    crc_job j = {.data = data, .bytes = bytes, .piece = TF_LOAD_PIECE};
    j.npieces = (size_t)((bytes + j.piece - 1) / j.piece);
    j.crc = hl_calloc(ctx, j.npieces ? j.npieces : 1, sizeof *j.crc, "the checksums");
    if (!j.crc) return HL_ERR_OUT_OF_MEMORY;
    atomic_init(&j.next, 0);
    run_on_threads(ctx, j.npieces, crc_worker, &j);
    *crc = join_crcs(j.crc, j.npieces, bytes, j.piece);
    free(j.crc);
    return HL_OK;
}

typedef struct load_job {
    tf_reader *rd;
    uint8_t *dst;
    uint64_t bytes, off;
    size_t piece, npieces;
    uint32_t *crc; /* per piece */
    int *status;   /* per piece: 0 read, an errno, or -1 short */
    int show;
    double t0;
    atomic_size_t next;
    atomic_uint_fast64_t done;
    atomic_int failed, printing;
} load_job;

static void *load_worker(void *arg)
{
    load_job *j = arg;
    for (size_t p; !atomic_load(&j->failed) && (p = atomic_fetch_add(&j->next, 1)) < j->npieces;) {
        const uint64_t at = (uint64_t)p * j->piece;
        const size_t n = j->bytes - at < j->piece ? (size_t)(j->bytes - at) : j->piece;
        const int k = hl_tf_pread_all(j->rd->fd, j->dst + at, n, j->off + at);
        if (k != 0) {
            j->status[p] = k < 0 ? (errno ? errno : EIO) : -1;
            atomic_store(&j->failed, 1);
            break;
        }
        j->crc[p] = crc_update(0, j->dst + at, n);
        const uint64_t done = atomic_fetch_add(&j->done, n) + n;
        if (j->show && done < j->bytes && !atomic_exchange(&j->printing, 1)) {
            const double el = hl_now() - j->t0, mb = (double)done * 1e-6;
            fprintf(stderr, "\rloading %s: %.0f of %.0f MB (%.0f MB/s)   ", j->rd->path, mb, (double)j->bytes * 1e-6,
                    el > 0 ? mb / el : 0.0);
            atomic_store(&j->printing, 0);
        }
    }
    return NULL;
}

/* The entries section into dst, its CRC into *crc, with a progress line
 * on a terminal for a big file (not with the context's quiet flag). */
static hl_result read_entries(tf_reader *rd, uint8_t *dst, uint64_t bytes, uint64_t off, uint32_t *crc)
{
    if (bytes > SIZE_MAX) return hl_fail(rd->ctx, HL_ERR_OUT_OF_MEMORY, "%s: entries section too large for this host", rd->path);
    load_job j = {.rd = rd, .dst = dst, .bytes = bytes, .off = off, .piece = test_size("HL_TEST_LOAD_PIECE", TF_LOAD_PIECE)};
    j.npieces = (size_t)((bytes + j.piece - 1) / j.piece);
    j.show = !rd->ctx->quiet && bytes >= TF_LOAD_PROGRESS && isatty(2);
    j.t0 = hl_now();
    void *crcs, *status;
    if (!job_tables(rd->ctx, j.npieces, sizeof *j.crc, &crcs, sizeof *j.status, &status, "the entries' checksums"))
        return HL_ERR_OUT_OF_MEMORY;
    j.crc = crcs;
    j.status = status;
    atomic_init(&j.next, 0);
    atomic_init(&j.done, 0);
    atomic_init(&j.failed, 0);
    atomic_init(&j.printing, 0);
    run_on_threads(rd->ctx, j.npieces, load_worker, &j);
    hl_result r = HL_OK;
    /* the first piece that failed, as one pass would have met it */
    for (size_t p = 0; p < j.npieces && r == HL_OK; p++) {
        if (j.status[p] > 0)
            r = hl_fail(rd->ctx, HL_ERR_IO, "%s: cannot read the entries section: %s", rd->path, strerror(j.status[p]));
        else if (j.status[p] < 0)
            r = hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: truncated while reading the entries section (file shrank?)", rd->path);
    }
    const uint32_t c = r == HL_OK ? join_crcs(j.crc, j.npieces, bytes, j.piece) : 0;
    if (r == HL_OK && j.show) {
        const double el = hl_now() - j.t0, mb = (double)bytes * 1e-6;
        fprintf(stderr, "\rloading %s: %.0f of %.0f MB (%.0f MB/s)   \n", rd->path, mb, mb, el > 0 ? mb / el : 0.0);
    }
    free(j.crc);
    free(j.status);
    *crc = c;
    return r;
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
    if (have >= H_SHARD_END + 4 && memcmp(bytes, TF_SHARD_MAGIC, 8) == 0)
        return hl_fail(rd->ctx, HL_ERR_FORMAT,
                       "%s: a shard (%" PRIu32 " of %" PRIu32 ", vertices %" PRIu32 "..%" PRIu32
                       ") of a precompute spread over machines, not a whole transport file: join the shards "
                       "with `haarlight merge -o SCENE.hlt SHARD...`",
                       rd->path, get_u32(bytes + H_SHARD_INDEX), get_u32(bytes + H_SHARD_COUNT),
                       get_u32(bytes + H_SHARD_FIRST), get_u32(bytes + H_SHARD_END) - 1u);
    if (have >= 8 && memcmp(bytes, TF_PARTIAL_MAGIC, 8) == 0)
        return hl_fail(rd->ctx, HL_ERR_FORMAT,
                       "%s: an unfinished precompute, not a transport file: finish it with `haarlight precompute "
                       "--resume` (the same mesh and options)", rd->path);
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
    hl_tf_header_decode(bytes, h);
    if (h->reserved_nonzero)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: reserved header bytes %u..%u are not zero", rd->path,
                       (unsigned)H_RESERVED, (unsigned)H_HEADER_CRC - 1);

    char msg[256];
    const hl_transport_info *i = &h->info;
    if (hl_tf_info_problem(i, msg, sizeof msg))
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header field %s", rd->path, msg);
    uint64_t max_coef = (uint64_t)hl_transport_rows(i) * slot_total(i->N);
    if (i->coefficients_kept > max_coef)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: header field coefficients_kept = %" PRIu64
                       " exceeds rows x 2N^2 = %" PRIu64, rd->path, i->coefficients_kept, max_coef);

    /* Sizes follow from the counts; offsets are free but ordered, aligned
     * past the header and inside the file, so no section overlaps another. */
    const uint64_t expect[SEC_COUNT] = {mesh_bytes(i->vertex_count, i->triangle_count),
                                        (uint64_t)hl_transport_rows(i) * row_record_bytes(i->block_count),
                                        2 * i->coefficients_kept};
    if (hl_tf_sections_problem(h, expect, msg, sizeof msg)) return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: %s", rd->path, msg);
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
    if (hl_tf_mesh_problem(m->vertex_count, m->triangle_count, m->positions, m->normals, m->albedo, m->indices,
                           msg, sizeof msg))
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
    const uint32_t R = hl_transport_rows(i);
    if (chunk > R) chunk = R;
    uint8_t *buf = hl_malloc(rd->ctx, chunk * rec, "the row table reader");
    if (!buf) return HL_ERR_OUT_OF_MEMORY;
    uint32_t crc = 0;
    hl_result r = HL_OK;
    for (uint64_t v0 = 0; v0 < R && r == HL_OK; v0 += chunk) {
        size_t n = R - v0 < chunk ? (size_t)(R - v0) : chunk;
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

/* The rows' entries checked by the context's threads: vertices in chunks
 * taken in turn, each chunk stopping at its first bad row; the lowest bad
 * vertex is reported, as a single pass would. */
typedef struct row_job {
    const hl_transport *t;
    uint32_t nv, per, nchunks; /* vertices 0 .. nv - 1 */
    uint32_t *bad;             /* per chunk: its first bad vertex, or nv */
    char (*msg)[256];          /* per chunk: what is wrong there */
    atomic_uint next;
} row_job;

static void *row_worker(void *arg)
{
    row_job *j = arg;
    const hl_transport_info *i = &j->t->info;
    const uint32_t B = i->block_count, limit = tf_slot_limit(i);
    for (uint32_t c; (c = atomic_fetch_add(&j->next, 1u)) < j->nchunks;) {
        j->bad[c] = j->nv;
        /* 64-bit bounds: near 2^32 vertices a 32-bit product wraps */
        const uint64_t v0 = (uint64_t)c * j->per, v1 = v0 + j->per < j->nv ? v0 + j->per : j->nv;
        for (uint32_t v = (uint32_t)v0; v < v1; v++) {
            const uint16_t *counts = j->t->block_counts + (size_t)v * B;
            const uint8_t *e = j->t->entries + 2 * j->t->row_offset[v];
            uint64_t nnz;
            if (hl_tf_row_problem(i->N, counts, e, &nnz, j->msg[c], sizeof j->msg[c]) ||
                hl_tf_row_slots_problem(i->N, limit, counts, e, j->msg[c], sizeof j->msg[c])) {
                j->bad[c] = v;
                break;
            }
        }
    }
    return NULL;
}

/* A bad row, named by its vertex (and channel, for a row a channel). */
static hl_result row_fail(tf_reader *rd, const hl_transport_info *i, uint32_t row, const char *msg)
{
    static const char *const name[3] = {"red", "green", "blue"};
    if (i->channels == 3)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: vertex %u (%s row): %s", rd->path, row % i->vertex_count,
                       name[row / i->vertex_count], msg);
    return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: vertex %u: %s", rd->path, row, msg);
}

/* Derives row_offset and checks every row against the entries. Runs after
 * all checksums, so it reports structure errors in files that are intact
 * but were written wrongly. The counts and offsets first, in order (a bad
 * one stops there); then the entries of the rows before it, on the
 * context's threads. */
static hl_result validate_rows(tf_reader *rd, hl_transport *t)
{
    const hl_transport_info *i = &t->info;
    const uint32_t R = hl_transport_rows(i);
    uint32_t B = i->block_count, first = R; /* the first row whose counts are bad */
    uint64_t off = 0;
    char msg[256] = "";
    for (uint32_t v = 0; v < R && first == R; v++) {
        t->row_offset[v] = off;
        uint64_t nnz = 0;
        const uint16_t *counts = t->block_counts + (size_t)v * B;
        if (hl_tf_row_quant_problem(i->quant, t->row_quant[v], msg, sizeof msg) ||
            hl_tf_row_problem(i->N, counts, NULL, &nnz, msg, sizeof msg))
            first = v;
        else if (nnz > i->coefficients_kept - off)
            first = v, snprintf(msg, sizeof msg, "block counts run past coefficients_kept = %" PRIu64, i->coefficients_kept);
        else
            off += nnz;
    }
    /* without the entries in memory (hl_transport_load_streamed) they are
       checked by check_entries_streamed, after */
    row_job j = {.t = t, .nv = t->entries ? first : 0, .per = (uint32_t)test_size("HL_TEST_ROW_CHUNK", 8192)};
    j.nchunks = (uint32_t)(((uint64_t)j.nv + j.per - 1) / j.per);
    atomic_init(&j.next, 0u);
    void *bad, *msgs;
    if (!job_tables(rd->ctx, j.nchunks, sizeof *j.bad, &bad, sizeof *j.msg, &msgs, "the row checks"))
        return HL_ERR_OUT_OF_MEMORY;
    j.bad = bad;
    j.msg = msgs;
    run_on_threads(rd->ctx, j.nchunks, row_worker, &j);
    uint32_t c = 0;
    while (c < j.nchunks && j.bad[c] == first) c++;
    hl_result r = HL_OK;
    if (c < j.nchunks)
        r = row_fail(rd, i, j.bad[c], j.msg[c]);
    else if (first < R)
        r = row_fail(rd, i, first, msg);
    free(j.bad);
    free(j.msg);
    if (r != HL_OK) return r;
    t->row_offset[R] = off;
    if (off != i->coefficients_kept)
        return hl_fail(rd->ctx, HL_ERR_FORMAT, "%s: block counts of all vertices sum to %" PRIu64
                       ", coefficients_kept says %" PRIu64, rd->path, off, i->coefficients_kept);
    return HL_OK;
}

/* The entries section of a streamed load in one pass through a buffer of
 * whole rows: its checksum, then every row as validate_rows checks it
 * (the first bad one reported, once the checksum holds). */
static hl_result check_entries_streamed(tf_reader *rd, const tf_header *h, const hl_transport *t)
{
    const hl_transport_info *i = &t->info;
    const uint32_t R = hl_transport_rows(i), B = i->block_count, limit = tf_slot_limit(i);
    uint64_t most = 0;
    for (uint32_t v = 0; v < R; v++)
        if (t->row_offset[v + 1] - t->row_offset[v] > most) most = t->row_offset[v + 1] - t->row_offset[v];
    const size_t cap = 2 * most > ((size_t)1 << 20) ? (size_t)(2 * most) : (size_t)1 << 20;
    uint8_t *buf = hl_malloc(rd->ctx, cap, "the entries reader");
    if (!buf) return HL_ERR_OUT_OF_MEMORY;
    uint32_t crc = 0, bad = R;
    char msg[256] = "";
    hl_result r = HL_OK;
    for (uint32_t v0 = 0, v1; v0 < R && r == HL_OK; v0 = v1) {
        for (v1 = v0 + 1; v1 < R && 2 * (t->row_offset[v1 + 1] - t->row_offset[v0]) <= cap; v1++) {}
        const uint64_t e0 = t->row_offset[v0], bytes = 2 * (t->row_offset[v1] - e0);
        r = read_range(rd, buf, bytes, h->sec[SEC_ENTRIES].offset + 2 * e0, "entries");
        if (r != HL_OK) break;
        crc = crc_update(crc, buf, (size_t)bytes);
        for (uint32_t v = v0; v < v1 && bad == R; v++) {
            const uint16_t *counts = t->block_counts + (size_t)v * B;
            const uint8_t *e = buf + 2 * (t->row_offset[v] - e0);
            uint64_t nnz;
            if (hl_tf_row_problem(i->N, counts, e, &nnz, msg, sizeof msg) ||
                hl_tf_row_slots_problem(i->N, limit, counts, e, msg, sizeof msg))
                bad = v;
        }
    }
    free(buf);
    if (r == HL_OK) r = check_crc(rd, SEC_ENTRIES, h->sec[SEC_ENTRIES].crc, crc);
    if (r == HL_OK && bad < R) r = row_fail(rd, i, bad, msg);
    return r;
}

static hl_result load(hl_context *ctx, const char *path, hl_transport **out, uint64_t *entries_offset)
{
    const int streamed = entries_offset != NULL;
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
        size_t R = hl_transport_rows(&h.info), B = h.info.block_count;
        t->row_quant = hl_malloc(ctx, R * sizeof *t->row_quant, "row quantisation parameters");
        t->block_counts = hl_alloc_big(ctx, R * B * sizeof *t->block_counts, "block counts");
        t->row_offset = hl_malloc(ctx, (R + 1) * sizeof *t->row_offset, "row offsets");
        t->entries = streamed ? NULL : hl_alloc_big(ctx, (size_t)h.sec[SEC_ENTRIES].size, "transport entries");
        if (!t->row_quant || !t->block_counts || !t->row_offset || (!streamed && !t->entries)) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r == HL_OK) r = read_rows(rd, &h, t);
    uint32_t ecrc = 0;
    if (r == HL_OK && !streamed)
        r = read_entries(rd, t->entries, h.sec[SEC_ENTRIES].size, h.sec[SEC_ENTRIES].offset, &ecrc);
    if (r == HL_OK && !streamed) r = check_crc(rd, SEC_ENTRIES, h.sec[SEC_ENTRIES].crc, ecrc);
    if (r == HL_OK) r = validate_rows(rd, t);
    if (r == HL_OK && streamed) r = check_entries_streamed(rd, &h, t);
    if (r == HL_OK && streamed) *entries_offset = h.sec[SEC_ENTRIES].offset;
    close(rd->fd);
    free(rd);
    if (r != HL_OK) {
        hl_transport_destroy(t);
        return r;
    }
    *out = t;
    return HL_OK;
}

hl_result hl_transport_load(hl_context *ctx, const char *path, hl_transport **out)
{
    return load(ctx, path, out, NULL);
}

hl_result hl_transport_load_streamed(hl_context *ctx, const char *path, hl_transport **out, uint64_t *entries_offset)
{
    if (!entries_offset) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_transport_load_streamed: entries_offset is required");
    return load(ctx, path, out, entries_offset);
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
    if (v >= hl_transport_rows(i)) return;
    const uint8_t *e = t->entries + 2 * t->row_offset[v];
    const uint16_t *counts = t->block_counts + (size_t)v * i->block_count;
    hl_row_quant rq = t->row_quant[v];
    /* a channel's row is dithered by its vertex, as the plane's own */
    const uint32_t key = v % i->vertex_count;
    for (uint32_t b = 0; b < i->block_count; b++) {
        float *base = dense + (size_t)b * HL_BLOCK;
        for (uint32_t j = 0; j < counts[b]; j++, e += 2)
            base[e[0]] = hl_dequant(i->quant, e[1], rq.a, rq.b, hl_dither_key(key, b * HL_BLOCK + e[0]));
    }
}

void hl_transport_query_terms(const hl_transport *t, uint32_t v, float *dense)
{
    hl_transport_query_row(t, v, dense);
    if (!t || !dense || v >= hl_transport_rows(&t->info)) return;
    const hl_row_quant rq = t->row_quant[v];
    const int ex = hl_half_exponent(t->info.quant, rq.a, rq.b);
    for (uint32_t i = 0; i < slot_total(t->info.N); i++)
        if (dense[i] != 0.0f) dense[i] = ldexpf(hl_half_term(dense[i], ex), ex);
}
