/* image.c - linear RGB images, tone mapping and image files.
 *
 * .exr goes to exr_io.c (linear); .png is written with libpng: 8-bit RGB
 * tone-mapped here (hl_tonemap_srgb8), adaptive per-row filtering, zlib
 * compression. Every file is written to "<path>.tmp.<pid>", synced and
 * renamed onto path when complete; on failure the temporary file is
 * removed and path is left as it was.
 * Depends on: exr_io.c, libpng, hl_publish_tmp (sync and rename), POSIX getpid.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include <png.h>

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

/* What libpng reports while a PNG is written. libpng never prints: its
 * error and warning handlers record the message here, and the error
 * handler longjmps back to the setjmp in png_encode, whose caller
 * (png_write, owner of this state) turns the message into the error. */
typedef struct png_sink {
    FILE *f;
    int io_errno;      /* errno of the first failed write, 0 if none */
    char error[256];   /* libpng's error message, "" if none */
    char warning[256]; /* its last warning, "" if none */
} png_sink;

static void png_on_error(png_structp png, png_const_charp msg)
{
    png_sink *s = png_get_error_ptr(png);
    if (s && !s->error[0]) snprintf(s->error, sizeof s->error, "%s", msg ? msg : "unknown error");
    png_longjmp(png, 1); /* never return: libpng's default handler would print */
}

static void png_on_warning(png_structp png, png_const_charp msg)
{
    png_sink *s = png_get_error_ptr(png);
    if (s) snprintf(s->warning, sizeof s->warning, "%s", msg ? msg : "unknown warning");
}

static void png_on_write(png_structp png, png_bytep data, size_t n)
{
    png_sink *s = png_get_io_ptr(png);
    errno = 0;
    if (fwrite(data, 1, n, s->f) != n) {
        if (!s->io_errno) s->io_errno = errno ? errno : EIO;
        png_error(png, "write failed");
    }
}

/* hl_image_save flushes and syncs the file once libpng is done. */
static void png_on_flush(png_structp png) { (void)png; }

/* zlib level 5: on the demo's 960 x 720 renders (sky, city) the files
 * are 2% smaller than the former hand-written encoder's, written in 1.0 to
 * 1.2 times its time (0.1 to 0.18 s); level 6 saves 5% more at 1.3 to 1.6
 * times, level 9 10% more at 5 to 10 times. */
enum { HL_PNG_LEVEL = 5 };

/* The part that runs under libpng's setjmp. Nothing local to this function
 * changes between setjmp and a longjmp except y and the row's bytes, which
 * are not used after one; the caller owns every allocation. Returns 0 when
 * the file was written, 1 when libpng raised an error (recorded in the
 * sink). */
static int png_encode(png_structp png, png_infop info, const hl_image *img, float exposure_ev, uint8_t *row)
{
    if (setjmp(png_jmpbuf(png))) return 1;
    png_set_IHDR(png, info, img->width, img->height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    /* Each row filtered with the type whose output has the smallest sum of
     * absolute values (libpng's heuristic over all five types). */
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_ALL_FILTERS);
    png_set_compression_level(png, HL_PNG_LEVEL);
    /* IDAT chunks of up to 1 MiB: 12 bytes of chunk framing per MiB
     * rather than per 8 KiB (libpng's default). */
    png_set_compression_buffer_size(png, (size_t)1 << 20);
    png_write_info(png, info);
    size_t n = 3 * (size_t)img->width;
    for (uint32_t y = 0; y < img->height; y++) {
        const float *src = img->rgb + 3 * (size_t)y * img->width;
        for (size_t i = 0; i < n; i++) row[i] = hl_tonemap_srgb8(src[i], exposure_ev);
        png_write_row(png, row);
    }
    png_write_end(png, NULL);
    return 0;
}

/* Writes img as PNG to the open file f with libpng: 8-bit RGB from
 * hl_tonemap_srgb8, adaptive row filters, one zlib stream. */
static hl_result png_write(hl_context *ctx, const hl_image *img, FILE *f, float exposure_ev,
                           const char *path)
{
    png_sink *sink = hl_calloc(ctx, 1, sizeof *sink, "PNG writer");
    uint8_t *row = sink ? hl_malloc(ctx, 3 * (size_t)img->width, "PNG row") : NULL;
    if (!row) {
        free(sink);
        return HL_ERR_OUT_OF_MEMORY;
    }
    sink->f = f;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, sink, png_on_error, png_on_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    hl_result r = HL_OK;
    if (!info) {
        const char *why = sink->error[0] ? sink->error : sink->warning;
        r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: libpng cannot start a PNG writer%s%s", path,
                    why[0] ? ": " : "", why);
    } else {
        png_set_write_fn(png, sink, png_on_write, png_on_flush);
        if (png_encode(png, info, img, exposure_ev, row) != 0) {
            if (sink->io_errno)
                r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write PNG data: %s", path, strerror(sink->io_errno));
            else if (sink->warning[0])
                r = hl_fail(ctx, HL_ERR_IO, "%s: libpng cannot write the PNG: %s (after its warning: %s)", path,
                            sink->error, sink->warning);
            else
                r = hl_fail(ctx, HL_ERR_IO, "%s: libpng cannot write the PNG: %s", path, sink->error);
        }
    }
    png_destroy_write_struct(&png, &info);
    free(row);
    free(sink);
    return r;
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
        if (fclose(f) != 0 && r == HL_OK) {
            int e = errno;
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write %s: %s", path, tmp, strerror(e));
        }
    } else {
        fclose(f);
        r = hl_exr_write_rgb_(ctx, tmp, img->width, img->height, img->rgb);
    }
    r = hl_publish_tmp(ctx, tmp, path, r);
    free(tmp);
    return r;
}
