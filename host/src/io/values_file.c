/* values_file.c - the floats of a direct transport's kept terms
 * (values_file.h says what and why; host/FORMAT.md "Values files").
 * Depends on: values_file.h, hl_shared.h (hl_quant, hl_dither_key),
 * transport_layout.h (little-endian coding, crc_update, companion file
 * names), POSIX I/O.
 */
#define _POSIX_C_SOURCE 200809L
#define _FILE_OFFSET_BITS 64
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "transport_layout.h"
#include "values_file.h"

#define VF_MAGIC "HLVALUE1"
#define VF_HEADER 32u
/* floats through a buffer of this many at a time (merge, checks) */
#define VF_CHUNK ((size_t)1 << 18)

struct hl_vfile_writer {
    hl_context *ctx;
    char *path, *tmp;
    FILE *f;
    uint32_t first, count;
    uint64_t entries;
    uint32_t crc;
    float *buf; /* one append's floats */
    size_t cap;
};

static void header_bytes(uint8_t *h, uint32_t first, uint32_t count, uint64_t entries, uint32_t crc)
{
    memset(h, 0, VF_HEADER);
    memcpy(h, VF_MAGIC, 8);
    put_u32(h + 8, first);
    put_u32(h + 12, count);
    put_u64(h + 16, entries);
    put_u32(h + 24, crc);
}

/* The header of the open file f (path in messages). */
static hl_result read_header(hl_context *ctx, FILE *f, const char *path, uint32_t *first, uint32_t *count,
                             uint64_t *entries, uint32_t *crc)
{
    uint8_t h[VF_HEADER];
    if (fread(h, 1, VF_HEADER, f) != VF_HEADER)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated: shorter than its %u-byte header", path, VF_HEADER);
    if (memcmp(h, VF_MAGIC, 8) != 0) return hl_fail(ctx, HL_ERR_FORMAT, "%s: not a values file (bad magic)", path);
    *first = get_u32(h + 8);
    *count = get_u32(h + 12);
    *entries = get_u64(h + 16);
    *crc = get_u32(h + 24);
    if (get_u32(h + 28) != 0) return hl_fail(ctx, HL_ERR_FORMAT, "%s: reserved header word is not zero", path);
    return HL_OK;
}

static uint64_t file_size(FILE *f)
{
    struct stat s;
    return fstat(fileno(f), &s) == 0 ? (uint64_t)s.st_size : 0;
}

/* n floats of f from where it stands, a buffer at a time: their
 * checksum into *crc (continued), and a copy appended to out (NULL:
 * none). Little-endian on disk, as the hosts that write them (checked
 * at open). */
static hl_result pass_floats(hl_context *ctx, FILE *f, const char *path, uint64_t n, uint32_t *crc,
                             hl_vfile_writer *out)
{
    float *b = malloc(VF_CHUNK * 4);
    if (!b) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    hl_result r = HL_OK;
    for (uint64_t done = 0; r == HL_OK && done < n;) {
        const size_t m = n - done < VF_CHUNK ? (size_t)(n - done) : VF_CHUNK;
        if (fread(b, 4, m, f) != m) {
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot read it", path);
            break;
        }
        *crc = crc_update(*crc, b, m * 4);
        if (out && fwrite(b, 4, m, out->f) != m) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write it", out->tmp);
        if (out) {
            out->crc = crc_update(out->crc, b, m * 4);
            out->entries += m;
        }
        done += m;
    }
    free(b);
    return r;
}

/* ------------------------------------------------------------- writer */

hl_result hl_vfile_writer_open(hl_context *ctx, const char *transport_path, uint32_t first, uint32_t count,
                               int resume, uint64_t resume_entries, hl_vfile_writer **out)
{
    *out = NULL;
    if (!tf_host_little_endian())
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "values files are little-endian; this host is not");
    hl_vfile_writer *w = calloc(1, sizeof *w);
    if (!w) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    w->ctx = ctx;
    w->first = first;
    w->count = count;
    w->path = hl_tf_path_with(ctx, transport_path, ".values");
    w->tmp = w->path ? hl_tf_path_with(ctx, w->path, ".partial") : NULL;
    if (!w->path || !w->tmp) {
        hl_vfile_writer_close(w, 1);
        return HL_ERR_OUT_OF_MEMORY;
    }
    hl_result r = HL_OK;
    if (resume && resume_entries) {
        /* the transport resumed with resume_entries entries: the values
           of exactly those, the rest dropped */
        w->f = fopen(w->tmp, "r+b");
        uint32_t f0 = 0, c0 = 0, crc0 = 0;
        uint64_t e0 = 0;
        if (!w->f)
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot resume the direct rows' floats: %s (run again without --resume)",
                        w->tmp, strerror(errno));
        if (r == HL_OK) r = read_header(ctx, w->f, w->tmp, &f0, &c0, &e0, &crc0);
        if (r == HL_OK && (f0 != first || c0 != count))
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: of vertices %u..%u, not this run's %u..%u (run again without --resume)",
                        w->tmp, f0, f0 + c0 - 1, first, first + count - 1);
        if (r == HL_OK && file_size(w->f) < VF_HEADER + 4 * resume_entries)
            r = hl_fail(ctx, HL_ERR_FORMAT,
                        "%s: holds fewer floats than the %llu entries resumed (run again without --resume)", w->tmp,
                        (unsigned long long)resume_entries);
        /* the running checksum of what stays */
        if (r == HL_OK) r = pass_floats(ctx, w->f, w->tmp, resume_entries, &w->crc, NULL);
        if (r == HL_OK && (fflush(w->f) != 0 || ftruncate(fileno(w->f), (off_t)(VF_HEADER + 4 * resume_entries)) != 0 ||
                           fseeko(w->f, (off_t)(VF_HEADER + 4 * resume_entries), SEEK_SET) != 0))
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot cut it to the resumed entries: %s", w->tmp, strerror(errno));
        w->entries = resume_entries;
    } else {
        uint8_t h[VF_HEADER];
        header_bytes(h, first, count, 0, 0);
        w->f = fopen(w->tmp, "wb");
        if (!w->f || fwrite(h, 1, VF_HEADER, w->f) != VF_HEADER)
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write it: %s", w->tmp, strerror(errno));
    }
    if (r != HL_OK) {
        hl_vfile_writer_close(w, resume); /* a refused resume leaves the partial file as it was */
        return r;
    }
    *out = w;
    return HL_OK;
}

hl_result hl_vfile_writer_append(hl_vfile_writer *w, uint32_t count, const float *coef, uint32_t ncoef,
                                 const uint16_t *block_counts, uint32_t nblocks, const uint8_t *entries,
                                 size_t entry_stride, const uint32_t *nnz)
{
    for (uint32_t i = 0; i < count; i++) {
        if (nnz[i] > w->cap) {
            float *b = realloc(w->buf, (size_t)nnz[i] * 4);
            if (!b) return hl_fail(w->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the direct rows' floats");
            w->buf = b;
            w->cap = nnz[i];
        }
        const uint8_t *en = entries + i * entry_stride;
        const uint16_t *bc = block_counts + (size_t)i * nblocks;
        uint32_t e = 0;
        for (uint32_t b = 0; b < nblocks; b++)
            for (uint32_t k = 0; k < bc[b] && e < nnz[i]; k++, e++)
                w->buf[e] = coef[(size_t)i * ncoef + b * HL_BLOCK + en[2 * e]];
        if (e != nnz[i])
            return hl_fail(w->ctx, HL_ERR_INVALID_ARGUMENT, "%s: a row's block counts and entry count disagree", w->tmp);
        if (e == 0) continue; /* an empty row: nothing to write (and no buffer yet) */
        if (fwrite(w->buf, 4, e, w->f) != e)
            return hl_fail(w->ctx, HL_ERR_IO, "%s: cannot write it: %s", w->tmp, strerror(errno));
        w->crc = crc_update(w->crc, w->buf, (size_t)e * 4);
        w->entries += e;
    }
    return HL_OK;
}

hl_result hl_vfile_writer_sync(hl_vfile_writer *w)
{
    if (fflush(w->f) != 0) return hl_fail(w->ctx, HL_ERR_IO, "%s: cannot write it: %s", w->tmp, strerror(errno));
    return HL_OK;
}

hl_result hl_vfile_writer_finish(hl_vfile_writer *w)
{
    uint8_t h[VF_HEADER];
    header_bytes(h, w->first, w->count, w->entries, w->crc);
    hl_result r = HL_OK;
    if (fseeko(w->f, 0, SEEK_SET) != 0 || fwrite(h, 1, VF_HEADER, w->f) != VF_HEADER || fflush(w->f) != 0)
        r = hl_fail(w->ctx, HL_ERR_IO, "%s: cannot write it: %s", w->tmp, strerror(errno));
    if (fclose(w->f) != 0 && r == HL_OK) r = hl_fail(w->ctx, HL_ERR_IO, "%s: cannot write it: %s", w->tmp, strerror(errno));
    w->f = NULL;
    r = hl_publish_tmp(w->ctx, w->tmp, w->path, r);
    free(w->tmp);
    w->tmp = NULL;
    hl_vfile_writer_close(w, 0);
    return r;
}

void hl_vfile_writer_close(hl_vfile_writer *w, int keep)
{
    if (!w) return;
    if (w->f) fclose(w->f);
    if (w->tmp && !keep) unlink(w->tmp);
    free(w->tmp);
    free(w->path);
    free(w->buf);
    free(w);
}

/* ------------------------------------------------------------- loader */

/* Whether code q2 is within one step of code q (sign-magnitude schemes:
 * the same sign, magnitudes one apart at most). */
static int near_code(uint32_t scheme, uint32_t q, uint32_t q2)
{
    if (scheme == HL_QUANT_LOG8 || scheme == HL_QUANT_SQRT8) {
        if ((q ^ q2) & 0x80u) return 0;
        q &= 0x7fu;
        q2 &= 0x7fu;
    }
    return q > q2 ? q - q2 <= 1u : q2 - q <= 1u;
}

struct hl_vfile_reader {
    FILE *f;
    char *path;
};

hl_result hl_vfile_open(hl_context *ctx, const char *transport_path, const hl_transport *t, hl_vfile_reader **out)
{
    *out = NULL;
    char *path = hl_tf_path_with(ctx, transport_path, ".values");
    if (!path) return HL_ERR_OUT_OF_MEMORY;
    FILE *f = fopen(path, "rb");
    if (!f && errno == ENOENT) {
        free(path);
        return HL_OK;
    }
    hl_result r = HL_OK;
    if (!f) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot open it: %s", path, strerror(errno));
    if (r == HL_OK && !tf_host_little_endian())
        r = hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: values files are little-endian; this host is not", path);
    uint32_t first = 0, count = 0, crc = 0, got = 0;
    uint64_t n = 0;
    const hl_transport_info *ti = &t->info;
    if (r == HL_OK) r = read_header(ctx, f, path, &first, &count, &n, &crc);
    if (r == HL_OK && (first != 0 || count != ti->vertex_count))
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: of vertices %u..%u, not the %u of %s", path, first,
                    first + count - (count > 0), ti->vertex_count, transport_path);
    if (r == HL_OK && n != ti->coefficients_kept)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: %llu floats for the %llu entries of %s", path, (unsigned long long)n,
                    (unsigned long long)ti->coefficients_kept, transport_path);
    if (r == HL_OK && file_size(f) != VF_HEADER + 4 * n)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: %llu bytes, its header says %llu (truncated or padded)", path,
                    (unsigned long long)file_size(f), (unsigned long long)(VF_HEADER + 4 * n));
    /* one pass through it, a buffer at a time, for the checksum */
    if (r == HL_OK) r = pass_floats(ctx, f, path, n, &got, NULL);
    if (r == HL_OK && got != crc) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: checksum mismatch (damaged)", path);
    hl_vfile_reader *rd = r == HL_OK ? malloc(sizeof *rd) : NULL;
    if (r == HL_OK && !rd) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    if (r != HL_OK) {
        if (f) fclose(f);
        free(path);
        return r;
    }
    rd->f = f;
    rd->path = path;
    *out = rd;
    return HL_OK;
}

hl_result hl_vfile_check(hl_context *ctx, const hl_vfile_reader *rd, const char *transport_path, const hl_transport *t,
                         uint32_t first, uint32_t count, const uint8_t *entries, const float *vals)
{
    const hl_transport_info *ti = &t->info;
    const uint32_t nb = ti->block_count;
    const uint64_t e0 = t->row_offset[first];
    for (uint32_t x = first; x < first + count; x++) {
        const hl_row_quant q = t->row_quant[x];
        uint64_t e = t->row_offset[x];
        for (uint32_t b = 0; b < nb; b++)
            for (uint32_t k = 0; k < t->block_counts[(size_t)x * nb + b]; k++, e++) {
                const uint32_t slot = b * HL_BLOCK + entries[2 * (e - e0)], code = entries[2 * (e - e0) + 1];
                const float y = vals[e - e0];
                if (!isfinite(y) || !near_code(ti->quant, code, hl_quant(ti->quant, y, q.a, q.b, hl_dither_key(x, slot))))
                    return hl_fail(ctx, HL_ERR_FORMAT,
                                   "%s: vertex %u, term %u: %g does not code to %s's stored value (these floats are of "
                                   "other rows)",
                                   rd->path, x, slot, (double)y, transport_path);
            }
    }
    return HL_OK;
}

hl_result hl_vfile_read(hl_context *ctx, hl_vfile_reader *rd, uint64_t first, size_t n, float *dst)
{
    if (n && (fseeko(rd->f, (off_t)(VF_HEADER + 4 * first), SEEK_SET) != 0 || fread(dst, 4, n, rd->f) != n))
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot read it: %s", rd->path, strerror(errno));
    return HL_OK;
}

void hl_vfile_close(hl_vfile_reader *rd)
{
    if (!rd) return;
    fclose(rd->f);
    free(rd->path);
    free(rd);
}

/* -------------------------------------------------------------- merge */

typedef struct vshard {
    char *path;
    uint32_t first, count, crc;
    uint64_t n;
} vshard;

static int by_first(const void *a, const void *b)
{
    const vshard *x = a, *y = b;
    return x->first < y->first ? -1 : x->first > y->first;
}

hl_result hl_vfile_merge(hl_context *ctx, const char *out_path, const char *const *shard_paths, uint32_t count,
                         int *written)
{
    *written = 0;
    vshard *s = calloc(count ? count : 1, sizeof *s);
    if (!s) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    hl_result r = HL_OK;
    uint32_t have = 0;
    for (uint32_t i = 0; i < count && r == HL_OK; i++) {
        s[i].path = hl_tf_path_with(ctx, shard_paths[i], ".values");
        if (!s[i].path) r = HL_ERR_OUT_OF_MEMORY;
        else have += access(s[i].path, F_OK) == 0;
    }
    if (r == HL_OK && have && have < count) {
        for (uint32_t i = 0; i < count; i++)
            if (access(s[i].path, F_OK) != 0) {
                if (!ctx->quiet)
                    fprintf(stderr,
                            "merge: warning: %s is missing, though %u of the %u shards have their direct rows' floats: "
                            "no values file written (precompute every shard with --keep-floats)\n",
                            s[i].path, have, count);
                break;
            }
        have = 0;
    }
    if (r == HL_OK && !have) {
        /* an older merge's values are not this file's */
        char *old = hl_tf_path_with(ctx, out_path, ".values");
        if (old) unlink(old);
        free(old);
    }
    if (r != HL_OK || !have) goto done;
    for (uint32_t i = 0; i < count && r == HL_OK; i++) {
        FILE *f = fopen(s[i].path, "rb");
        if (!f) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot open it: %s", s[i].path, strerror(errno));
        if (r == HL_OK) r = read_header(ctx, f, s[i].path, &s[i].first, &s[i].count, &s[i].n, &s[i].crc);
        if (r == HL_OK && file_size(f) != VF_HEADER + 4 * s[i].n)
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated or padded (its header says %llu floats)", s[i].path,
                        (unsigned long long)s[i].n);
        if (f) fclose(f);
    }
    if (r == HL_OK) qsort(s, count, sizeof *s, by_first);
    for (uint32_t i = 0, next = 0; i < count && r == HL_OK; next += s[i].count, i++)
        if (s[i].first != next)
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: starts at vertex %u, the shards before end at %u", s[i].path,
                        s[i].first, next);
    uint32_t total = 0;
    for (uint32_t i = 0; i < count; i++) total += s[i].count;
    hl_vfile_writer *w = NULL;
    if (r == HL_OK) r = hl_vfile_writer_open(ctx, out_path, 0, total, 0, 0, &w);
    for (uint32_t i = 0; i < count && r == HL_OK; i++) {
        FILE *f = fopen(s[i].path, "rb");
        uint32_t crc = 0;
        if (!f || fseeko(f, VF_HEADER, SEEK_SET) != 0) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot read it", s[i].path);
        if (r == HL_OK) r = pass_floats(ctx, f, s[i].path, s[i].n, &crc, w);
        if (f) fclose(f);
        if (r == HL_OK && crc != s[i].crc) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: checksum mismatch (damaged)", s[i].path);
    }
    if (r == HL_OK) {
        r = hl_vfile_writer_finish(w);
        *written = r == HL_OK;
    } else {
        hl_vfile_writer_close(w, 0);
    }
done:
    for (uint32_t i = 0; i < count; i++) free(s[i].path);
    free(s);
    return r;
}
