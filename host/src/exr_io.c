/* exr_io.c - OpenEXR reading and writing; the only file that includes
 * OpenEXR headers.
 *
 * Uses the C wrapper of the C++ library (ImfCRgbaFile.h): on Debian 12 the
 * OpenEXRCore C API cannot decode DWAB, which the shared environments use.
 * The wrapper catches every C++ exception and returns 0, with the text in
 * ImfErrorMessage(). Sizes from the header are bounded before anything is
 * allocated, and pixels are read in strips so that the temporary half
 * buffer stays small.
 * Depends on: libOpenEXR-3_1 (through the hl_openexr CMake target).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <ImfCRgbaFile.h>

#include "exr_io.h"
#include "hl_internal.h"

/* Rows per strip: about 4 Mi pixels (32 MiB of halves), whole DWAB chunks
 * of 256 rows when the image is narrow enough. */
static uint32_t strip_rows(uint32_t width)
{
    uint32_t rows = (uint32_t)((1u << 22) / width);
    if (rows > 256) rows = 256;
    return rows ? rows : 1;
}

static const char *imf_message(void)
{
    const char *m = ImfErrorMessage();
    return m && *m ? m : "unknown OpenEXR error";
}

/* Pointer that maps pixel (x0, y0) of the data window to first. The
 * library addresses base + x * xStride + y * yStride (in pixels). */
static ImfRgba *frame_base(ImfRgba *first, int64_t x0, int64_t y0, uint32_t width)
{
    intptr_t offset = (intptr_t)(x0 + y0 * (int64_t)width) * (intptr_t)sizeof(ImfRgba);
    return (ImfRgba *)(void *)((intptr_t)(void *)first - offset);
}

/* Opens the file ourselves first so that "cannot open" (HL_ERR_IO) and
 * "not an OpenEXR file" (HL_ERR_FORMAT) get precise messages before the
 * library sees it. */
static hl_result check_file(hl_context *ctx, const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        int e = errno;
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot open environment map: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode))
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot read environment map: not a regular file", path);
    FILE *f = fopen(path, "rb");
    if (!f) {
        int e = errno;
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot open environment map: %s", path, strerror(e));
    }
    unsigned char magic[4];
    size_t got = fread(magic, 1, sizeof magic, f);
    int read_error = ferror(f);
    fclose(f);
    if (read_error)
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot read environment map", path);
    if (got == 0)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not an OpenEXR file: the file is empty", path);
    if (got < sizeof magic)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not an OpenEXR file: only %zu bytes", path, got);
    if (magic[0] != 0x76 || magic[1] != 0x2f || magic[2] != 0x31 || magic[3] != 0x01)
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: not an OpenEXR file: bad magic number %02x %02x %02x %02x at byte 0",
                       path, magic[0], magic[1], magic[2], magic[3]);
    return HL_OK;
}

hl_result hl_exr_read_rgb_(hl_context *ctx, const char *path, unsigned flags,
                           uint32_t *width, uint32_t *height, float **rgb)
{
    *width = *height = 0;
    *rgb = NULL;
    hl_result r = check_file(ctx, path);
    if (r != HL_OK) return r;

    ImfInputFile *in = ImfOpenInputFile(path);
    if (!in) return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, imf_message());

    int xmin = 0, ymin = 0, xmax = -1, ymax = -1;
    ImfHeaderDataWindow(ImfInputHeader(in), &xmin, &ymin, &xmax, &ymax);
    int64_t w64 = (int64_t)xmax - (int64_t)xmin + 1;
    int64_t h64 = (int64_t)ymax - (int64_t)ymin + 1;
    if (w64 < 1 || h64 < 1 || w64 > (int64_t)HL_EXR_MAX_SIDE || h64 > (int64_t)HL_EXR_MAX_SIDE ||
        (uint64_t)w64 * (uint64_t)h64 > HL_EXR_MAX_PIXELS) {
        ImfCloseInputFile(in);
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: data window (%d,%d)-(%d,%d) gives a size of %lld x %lld pixels, "
                       "outside 1..%u per side and %llu pixels in all",
                       path, xmin, ymin, xmax, ymax, (long long)w64, (long long)h64,
                       HL_EXR_MAX_SIDE, (unsigned long long)HL_EXR_MAX_PIXELS);
    }
    uint32_t w = (uint32_t)w64, h = (uint32_t)h64;
    if ((flags & HL_EXR_REQUIRE_2TO1) && w != 2 * h) {
        ImfCloseInputFile(in);
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: %u x %u pixels is not an equirectangular map (width must be 2 x height)",
                       path, w, h);
    }
    int channels = ImfInputChannels(in);
    if ((channels & (IMF_WRITE_RGB | IMF_WRITE_Y)) == 0) {
        ImfCloseInputFile(in);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: no R, G, B or Y channel to read", path);
    }

    uint32_t rows = strip_rows(w);
    float *out = hl_malloc(ctx, sizeof(float) * 3 * (size_t)w * h, "environment pixels");
    ImfRgba *strip = hl_malloc(ctx, sizeof(ImfRgba) * (size_t)w * rows, "OpenEXR scanline strip");
    if (!out || !strip) {
        free(out);
        free(strip);
        ImfCloseInputFile(in);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t y0 = 0; y0 < h; y0 += rows) {
        uint32_t n = h - y0 < rows ? h - y0 : rows;
        int first = (int)((int64_t)ymin + y0), last = (int)((int64_t)ymin + y0 + n - 1);
        if (!ImfInputSetFrameBuffer(in, frame_base(strip, xmin, first, w), 1, w) ||
            !ImfInputReadPixels(in, first, last)) {
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: corrupt or truncated pixel data in rows %u..%u: %s",
                        path, y0, y0 + n - 1, imf_message());
            break;
        }
        for (size_t i = 0; i < (size_t)n * w; i++) {
            float *o = out + 3 * ((size_t)y0 * w + i);
            o[0] = ImfHalfToFloat(strip[i].r);
            o[1] = ImfHalfToFloat(strip[i].g);
            o[2] = ImfHalfToFloat(strip[i].b);
        }
    }
    free(strip);
    ImfCloseInputFile(in);
    if (r != HL_OK) {
        free(out);
        return r;
    }
    *width = w;
    *height = h;
    *rgb = out;
    return HL_OK;
}

static ImfHalf to_half(float f)
{
    ImfHalf h;
    if (f > 65504.0f) f = 65504.0f;
    if (f < -65504.0f) f = -65504.0f;
    ImfFloatToHalf(f, &h);
    return h;
}

hl_result hl_exr_write_rgb_(hl_context *ctx, const char *path, uint32_t width,
                            uint32_t height, const float *rgb)
{
    if (width < 1 || height < 1 || width > HL_EXR_MAX_SIDE || height > HL_EXR_MAX_SIDE ||
        (uint64_t)width * height > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: cannot write a %u x %u OpenEXR image",
                       path, width, height);
    ImfHeader *hdr = ImfNewHeader();
    if (!hdr) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: cannot create an OpenEXR header: %s", path, imf_message());
    ImfHeaderSetDisplayWindow(hdr, 0, 0, (int)width - 1, (int)height - 1);
    ImfHeaderSetDataWindow(hdr, 0, 0, (int)width - 1, (int)height - 1);
    ImfHeaderSetCompression(hdr, IMF_ZIP_COMPRESSION);
    ImfHeaderSetLineOrder(hdr, IMF_INCREASING_Y);
    ImfOutputFile *out = ImfOpenOutputFile(path, hdr, IMF_WRITE_RGB);
    ImfDeleteHeader(hdr);
    if (!out) return hl_fail(ctx, HL_ERR_IO, "%s: cannot create OpenEXR file: %s", path, imf_message());

    uint32_t rows = strip_rows(width);
    ImfRgba *strip = hl_malloc(ctx, sizeof(ImfRgba) * (size_t)width * rows, "OpenEXR scanline strip");
    if (!strip) {
        ImfCloseOutputFile(out);
        return HL_ERR_OUT_OF_MEMORY;
    }
    hl_result r = HL_OK;
    ImfHalf one;
    ImfFloatToHalf(1.0f, &one);
    for (uint32_t y0 = 0; y0 < height; y0 += rows) {
        uint32_t n = height - y0 < rows ? height - y0 : rows;
        for (size_t i = 0; i < (size_t)n * width; i++) {
            const float *p = rgb + 3 * ((size_t)y0 * width + i);
            strip[i].r = to_half(p[0]);
            strip[i].g = to_half(p[1]);
            strip[i].b = to_half(p[2]);
            strip[i].a = one;
        }
        if (!ImfOutputSetFrameBuffer(out, frame_base(strip, 0, y0, width), 1, width) ||
            !ImfOutputWritePixels(out, (int)n)) {
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write OpenEXR rows %u..%u: %s", path, y0,
                        y0 + n - 1, imf_message());
            break;
        }
    }
    free(strip);
    if (!ImfCloseOutputFile(out) && r == HL_OK)
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot finish OpenEXR file: %s", path, imf_message());
    return r;
}
