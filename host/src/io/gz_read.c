/* gz_read.c - a gzip file decompressed whole into memory (gz_read.h).
 *
 * zlib's inflate with the gzip wrapper only (windowBits 16 + 15), not
 * gzread: gzread passes data that are not gzip through unchanged, which
 * would hand garbage to the importer instead of saying what is wrong. The
 * stream's own CRC-32 and length are checked by inflate at each member's
 * end, so a corrupt body is caught here, not by the importer.
 *
 * Depends on: gz_read.h, hl_internal.h (hl_fail, allocation), zlib, POSIX
 * fstat.
 */
#define _POSIX_C_SOURCE 200809L
#define _FILE_OFFSET_BITS 64
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#include "gz_read.h"

/* Compressed bytes read at a time: large enough that fread's cost is
 * negligible, small next to any output. */
#define GZ_IN_BYTES ((size_t)256 << 10)
/* First output buffer when the trailer's length is no guide (0, or a
 * member of 4 GiB or more, which it stores modulo 2^32). */
#define GZ_FIRST_OUT ((uint64_t)1 << 20)
/* Output handed to one inflate call: avail_out is an unsigned int. */
#define GZ_STEP_OUT ((uint64_t)1 << 30)

int hl_gz_is_gz_name(const char *path)
{
    size_t n = path ? strlen(path) : 0;
    return n > 3 && path[n - 3] == '.' && (path[n - 2] | 0x20) == 'g' && (path[n - 1] | 0x20) == 'z';
}

/* The length the last member's trailer gives (ISIZE: the uncompressed
 * length modulo 2^32), as the first guess of the output's size. */
static uint64_t trailer_guess(FILE *f, uint64_t file_size)
{
    unsigned char t[4];
    if (file_size < 18 || fseeko(f, (off_t)(file_size - 4), SEEK_SET) != 0 || fread(t, 1, 4, f) != 4) {
        rewind(f);
        return GZ_FIRST_OUT;
    }
    rewind(f);
    uint64_t isize = (uint64_t)t[0] | (uint64_t)t[1] << 8 | (uint64_t)t[2] << 16 | (uint64_t)t[3] << 24;
    return isize ? isize : GZ_FIRST_OUT;
}

typedef struct gz_job {
    hl_context *ctx;
    const char *path;
    FILE *f;
    uint64_t cap;
    z_stream zs;
    unsigned char *in;
    uint8_t *out;
    uint64_t out_cap; /* bytes of out usable for output (one more holds the 0) */
    uint64_t used;
} gz_job;

/* Room for more output: doubles the buffer, up to cap + 1 bytes so that a
 * stream longer than cap is seen as such. */
static hl_result grow(gz_job *j)
{
    uint64_t limit = j->cap + 1, want = j->out_cap * 2;
    if (want < GZ_FIRST_OUT) want = GZ_FIRST_OUT;
    if (want > limit) want = limit;
    if (want > SIZE_MAX - 1)
        return hl_fail(j->ctx, HL_ERR_OUT_OF_MEMORY, "%s: decompressed data too large for this host", j->path);
    uint8_t *p = realloc(j->out, (size_t)want + 1);
    if (!p)
        return hl_fail(j->ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory for %llu decompressed bytes", j->path,
                       (unsigned long long)want);
    j->out = p;
    j->out_cap = want;
    return HL_OK;
}

/* Inflates the whole file; members follow one another until the input
 * ends, which it may only do at a member's end. */
static hl_result inflate_all(gz_job *j)
{
    int member_done = 0;
    uint64_t read_total = 0;
    for (;;) {
        if (j->zs.avail_in == 0) {
            size_t n = fread(j->in, 1, GZ_IN_BYTES, j->f);
            if (n == 0 && ferror(j->f))
                return hl_fail(j->ctx, HL_ERR_IO, "%s: cannot read: %s", j->path, strerror(errno));
            if (n == 0) {
                if (member_done) return HL_OK;
                return hl_fail(j->ctx, HL_ERR_FORMAT,
                               "%s: truncated gzip file: the stream stops after %llu compressed bytes, "
                               "%llu decompressed, before its end",
                               j->path, (unsigned long long)read_total, (unsigned long long)j->used);
            }
            read_total += n;
            j->zs.next_in = j->in;
            j->zs.avail_in = (uInt)n;
        }
        if (member_done) { /* more input after a member: the next one */
            if (inflateReset(&j->zs) != Z_OK)
                return hl_fail(j->ctx, HL_ERR_FORMAT, "%s: cannot restart the gzip stream", j->path);
            member_done = 0;
        }
        if (j->used == j->out_cap) {
            if (j->used > j->cap)
                return hl_fail(j->ctx, HL_ERR_FORMAT,
                               "%s: decompresses to more than %llu bytes, the most a gzipped mesh may hold",
                               j->path, (unsigned long long)j->cap);
            hl_result r = grow(j);
            if (r != HL_OK) return r;
        }
        uint64_t room = j->out_cap - j->used;
        j->zs.next_out = j->out + j->used;
        j->zs.avail_out = (uInt)(room < GZ_STEP_OUT ? room : GZ_STEP_OUT);
        uInt before = j->zs.avail_out;
        int z = inflate(&j->zs, Z_NO_FLUSH);
        j->used += before - j->zs.avail_out;
        if (z == Z_STREAM_END) member_done = 1;
        else if (z == Z_MEM_ERROR)
            return hl_fail(j->ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory inflating the gzip stream", j->path);
        else if (z == Z_DATA_ERROR || z == Z_NEED_DICT || z == Z_STREAM_ERROR)
            return hl_fail(j->ctx, HL_ERR_FORMAT, "%s: %s (zlib: %s)", j->path,
                           read_total <= GZ_IN_BYTES && j->used == 0 ? "not gzip data, or corrupt"
                                                                     : "corrupt gzip data",
                           j->zs.msg ? j->zs.msg : "error");
        /* Z_OK and Z_BUF_ERROR: more input or more room, given above */
    }
}

hl_result hl_gz_read_file(hl_context *ctx, const char *path, uint64_t cap, uint8_t **data, size_t *size)
{
    *data = NULL;
    *size = 0;
    gz_job j = {.ctx = ctx, .path = path, .cap = cap};
    j.f = fopen(path, "rb");
    if (!j.f) return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    hl_result r = HL_OK;
    if (fstat(fileno(j.f), &st) != 0 || !S_ISREG(st.st_mode)) r = hl_fail(ctx, HL_ERR_IO, "%s: not a regular file", path);
    else if (st.st_size == 0) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: empty file", path);
    if (r == HL_OK) {
        uint64_t guess = trailer_guess(j.f, (uint64_t)st.st_size);
        j.out_cap = guess < cap ? guess : cap + 1;
        j.in = malloc(GZ_IN_BYTES);
        j.out = j.out_cap < SIZE_MAX ? malloc((size_t)j.out_cap + 1) : NULL;
        if (!j.in || !j.out) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory for the gzip reader", path);
    }
    int inited = 0;
    if (r == HL_OK) {
        if (inflateInit2(&j.zs, 16 + MAX_WBITS) != Z_OK)
            r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: cannot start zlib's inflate", path);
        else inited = 1;
    }
    if (r == HL_OK) r = inflate_all(&j);
    if (r == HL_OK && j.used > cap)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: decompresses to more than %llu bytes, the most a gzipped mesh may hold",
                    path, (unsigned long long)cap);
    if (inited) inflateEnd(&j.zs);
    fclose(j.f);
    free(j.in);
    if (r != HL_OK) {
        free(j.out);
        return r;
    }
    j.out[j.used] = 0;
    *data = j.out;
    *size = (size_t)j.used;
    return HL_OK;
}
