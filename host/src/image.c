/* image.c - linear RGB images, tone mapping and image files.
 *
 * .exr goes to exr_io.c (linear); .png is written here by a small encoder:
 * 8-bit RGB, no filtering, a zlib stream of stored deflate blocks, with
 * CRC-32 and Adler-32 computed in this file. Every file is written to
 * "<path>.tmp.<pid>" and renamed onto path when complete; on failure the
 * temporary file is removed and path is left as it was.
 * Depends on: exr_io.c, POSIX rename/unlink/getpid.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "exr_io.h"
#include "hl_internal.h"

hl_result hl_image_create(hl_context *ctx, uint32_t width, uint32_t height, hl_image **out)
{
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_image_create: out is NULL");
    *out = NULL;
    if (width < 1 || height < 1 || width > HL_EXR_MAX_SIDE || height > HL_EXR_MAX_SIDE ||
        (uint64_t)width * height > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "image size %u x %u is outside 1..%u per side and %llu pixels", width, height,
                       HL_EXR_MAX_SIDE, (unsigned long long)HL_EXR_MAX_PIXELS);
    hl_image *img = hl_calloc(ctx, 1, sizeof *img, "image");
    if (!img) return HL_ERR_OUT_OF_MEMORY;
    img->rgb = hl_calloc(ctx, 3 * (size_t)width * height, sizeof(float), "image pixels");
    if (!img->rgb) {
        free(img);
        return HL_ERR_OUT_OF_MEMORY;
    }
    img->width = width;
    img->height = height;
    *out = img;
    return HL_OK;
}

void hl_image_destroy(hl_image *img)
{
    if (!img) return;
    free(img->rgb);
    free(img);
}

uint8_t hl_tonemap_srgb8(float linear, float exposure_ev)
{
    double x = (double)linear * exp2((double)exposure_ev);
    if (!(x > 0.0)) return 0; /* also NaN */
    if (x >= 1.0) return 255;
    double y = x < 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
    double code = floor(y * 255.0 + 0.5);
    return (uint8_t)(code < 0.0 ? 0.0 : code > 255.0 ? 255.0 : code);
}

/* ---------------------------------------------------------------- PNG */

/* CRC-32 table (PNG, ISO 3309, reflected polynomial 0xEDB88320). Built
 * per file written, so that nothing global is shared between threads. */
static void crc_init(uint32_t table[256])
{
    for (uint32_t n = 0; n < 256; n++) {
        uint32_t c = n;
        for (int k = 0; k < 8; k++) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        table[n] = c;
    }
}

/* Running CRC-32: start with 0xFFFFFFFF, finish with ~. */
static uint32_t crc_update(const uint32_t table[256], uint32_t c, const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++) c = table[(c ^ p[i]) & 0xFFu] ^ (c >> 8);
    return c;
}

static void put_be32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

/* A PNG being written: IDAT bytes are collected in buf and flushed as one
 * chunk whenever it fills. */
typedef struct png_writer {
    FILE *f;
    int failed;
    uint8_t *buf;
    size_t used, cap;
    uint32_t adler_a, adler_b;
    uint32_t crc_table[256];
} png_writer;

static void write_chunk(png_writer *w, const char type[4], const uint8_t *data, uint32_t len)
{
    uint8_t head[8], tail[4];
    put_be32(head, len);
    memcpy(head + 4, type, 4);
    uint32_t c = crc_update(w->crc_table, 0xFFFFFFFFu, head + 4, 4);
    c = crc_update(w->crc_table, c, data, len);
    put_be32(tail, ~c);
    if (fwrite(head, 1, 8, w->f) != 8 || (len && fwrite(data, 1, len, w->f) != len) ||
        fwrite(tail, 1, 4, w->f) != 4)
        w->failed = 1;
}

static void idat_put(png_writer *w, const uint8_t *p, size_t n)
{
    while (n) {
        size_t take = w->cap - w->used < n ? w->cap - w->used : n;
        memcpy(w->buf + w->used, p, take);
        w->used += take;
        p += take;
        n -= take;
        if (w->used == w->cap) {
            write_chunk(w, "IDAT", w->buf, (uint32_t)w->used);
            w->used = 0;
        }
    }
}

/* Adler-32 of the uncompressed data, kept as two running sums mod 65521. */
static void adler_update(png_writer *w, const uint8_t *p, size_t n)
{
    uint32_t a = w->adler_a, b = w->adler_b;
    while (n) {
        size_t k = n < 5552 ? n : 5552; /* largest run without overflow */
        n -= k;
        while (k--) {
            a += *p++;
            b += a;
        }
        a %= 65521u;
        b %= 65521u;
    }
    w->adler_a = a;
    w->adler_b = b;
}

/* Writes img as PNG to the open file f. */
static hl_result png_write(hl_context *ctx, const hl_image *img, FILE *f, float exposure_ev,
                           const char *path)
{
    png_writer w = {.f = f, .cap = (size_t)1 << 20, .adler_a = 1, .adler_b = 0};
    crc_init(w.crc_table);
    size_t row_bytes = 1 + 3 * (size_t)img->width;
    uint8_t *row = hl_malloc(ctx, row_bytes, "PNG row");
    w.buf = hl_malloc(ctx, w.cap, "PNG chunk buffer");
    if (!row || !w.buf) {
        free(row);
        free(w.buf);
        return HL_ERR_OUT_OF_MEMORY;
    }
    static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    if (fwrite(sig, 1, 8, f) != 8) w.failed = 1;
    uint8_t ihdr[13];
    put_be32(ihdr, img->width);
    put_be32(ihdr + 4, img->height);
    ihdr[8] = 8;  /* bit depth */
    ihdr[9] = 2;  /* colour type: RGB */
    ihdr[10] = 0; /* deflate */
    ihdr[11] = 0; /* adaptive filtering (every row uses filter 0) */
    ihdr[12] = 0; /* no interlace */
    write_chunk(&w, "IHDR", ihdr, sizeof ihdr);

    /* zlib header: CM = 8, CINFO = 7 (32K window), FCHECK so that the
     * 16-bit value is a multiple of 31, no dictionary, fastest level. */
    static const uint8_t zhead[2] = {0x78, 0x01};
    idat_put(&w, zhead, 2);
    /* The raw stream (filter byte + RGB per row) is cut into stored blocks
     * of at most 65535 bytes; a block may span rows. */
    uint64_t total = (uint64_t)row_bytes * img->height, done = 0;
    size_t block_left = 0;
    for (uint32_t y = 0; y < img->height && !w.failed; y++) {
        const float *src = img->rgb + 3 * (size_t)y * img->width;
        row[0] = 0;
        for (size_t i = 0; i < 3 * (size_t)img->width; i++) row[1 + i] = hl_tonemap_srgb8(src[i], exposure_ev);
        adler_update(&w, row, row_bytes);
        size_t pos = 0;
        while (pos < row_bytes) {
            if (block_left == 0) {
                uint64_t remain = total - done;
                uint16_t len = (uint16_t)(remain < 65535u ? remain : 65535u);
                uint8_t bh[5] = {(uint8_t)(remain <= 65535u ? 1 : 0), (uint8_t)len, (uint8_t)(len >> 8),
                                 (uint8_t)~len, (uint8_t)((uint16_t)~len >> 8)};
                idat_put(&w, bh, 5);
                block_left = len;
            }
            size_t take = row_bytes - pos < block_left ? row_bytes - pos : block_left;
            idat_put(&w, row + pos, take);
            pos += take;
            block_left -= take;
            done += take;
        }
    }
    uint8_t adler[4];
    put_be32(adler, (w.adler_b << 16) | w.adler_a);
    idat_put(&w, adler, 4);
    if (w.used) write_chunk(&w, "IDAT", w.buf, (uint32_t)w.used);
    write_chunk(&w, "IEND", NULL, 0);
    free(row);
    free(w.buf);
    if (w.failed) {
        int e = errno;
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot write PNG data: %s", path, strerror(e));
    }
    return HL_OK;
}

/* ---------------------------------------------------------------- saving */

static int has_ext(const char *path, const char *ext)
{
    size_t n = strlen(path), k = strlen(ext);
    return n > k && strcasecmp(path + n - k, ext) == 0;
}

hl_result hl_image_save(hl_context *ctx, const hl_image *img, const char *path, float exposure_ev)
{
    if (!img || !img->rgb || img->width < 1 || img->height < 1)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_image_save: no image to write");
    if (!path || !*path) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_image_save: no path given");
    int exr = has_ext(path, ".exr"), png = has_ext(path, ".png");
    if (!exr && !png)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: unknown image type (the name must end in .exr or .png)", path);
    if (png && !isfinite(exposure_ev))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: exposure %g is not finite", path,
                       (double)exposure_ev);

    size_t n = strlen(path);
    char *tmp = hl_malloc(ctx, n + 32, "temporary file name");
    if (!tmp) return HL_ERR_OUT_OF_MEMORY;
    snprintf(tmp, n + 32, "%s.tmp.%ld", path, (long)getpid());

    /* Create the temporary file here for both formats, so that an
     * unwritable place is reported with the system's reason. */
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        int e = errno;
        hl_result r = hl_fail(ctx, HL_ERR_IO, "%s: cannot create %s: %s", path, tmp, strerror(e));
        free(tmp);
        return r;
    }
    hl_result r = HL_OK;
    if (png) {
        r = png_write(ctx, img, f, exposure_ev, path);
        if (fflush(f) != 0 && r == HL_OK) {
            int e = errno;
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write %s: %s", path, tmp, strerror(e));
        }
        if (fclose(f) != 0 && r == HL_OK) {
            int e = errno;
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot close %s: %s", path, tmp, strerror(e));
        }
    } else {
        fclose(f);
        r = hl_exr_write_rgb_(ctx, tmp, img->width, img->height, img->rgb);
    }
    if (r == HL_OK && rename(tmp, path) != 0) {
        int e = errno;
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot rename %s onto it: %s", path, tmp, strerror(e));
    }
    if (r != HL_OK) unlink(tmp);
    free(tmp);
    return r;
}
