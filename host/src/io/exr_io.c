/* exr_io.c - OpenEXR pixels: reading a map (choosing the decoder) and
 * writing an image. With exr_check.c, which checks a file before either
 * decoder sees it, the only files that include OpenEXR headers.
 *
 * Two of the library's C interfaces, because neither does everything on
 * Debian 12 (OpenEXR 3.1.5):
 * - OpenEXRCore (openexr.h) decodes half and 32-bit float channels to
 *   float exactly, and checks every chunk's data as it decodes it (a ZIP
 *   chunk must decompress to exactly its size), but cannot decode
 *   DWAA/DWAB, which the shared environments use, and decodes B44 blocks
 *   at a chunk's edges wrongly.
 * - The C wrapper of the C++ library (ImfCRgbaFile.h) decodes every
 *   compression, DWAB included, but only through half floats (a float
 *   channel comes back rounded to 11 significant bits, any value beyond
 *   +-65504 as infinite), and takes a ZIP chunk that decompresses to fewer
 *   bytes than it holds without an error, filling the rest of its pixels
 *   from its own uninitialised buffer.
 * So OpenEXRCore reads every file it can decode (read_core): one scanline
 * part, R, G, B or Y half or float, not subsampled, no chroma, not DWA,
 * and not B44 unless a channel read is float (B44 stores float channels
 * uncompressed). The wrapper reads the rest (read_wrapper): DWA, several
 * parts (it reads part 0), tiles (level 0), subsampled, chroma or integer
 * channels, B44 of half channels. Half values are the same either way
 * (both convert exactly). DWA loses nothing through halves either: its
 * lossy coder stores float R, G, B and Y through halves already (a 1e5
 * written to a float DWAB file reads back as 64704, here and with OpenEXR
 * 3.5's own Python reader). A float file that reaches the wrapper for
 * another reason (tiled, several parts) could hold values the halves
 * cannot, so any infinity in it is refused rather than passed on. Images
 * are written with OpenEXRCore as 32-bit float RGB, ZIP-compressed.
 * Every file is checked before either decoder sees it (exr_check.c: its
 * header parsed strictly and bounded against the file by
 * hl_exr_check_parts_, every chunk's table entry, header and extent by
 * hl_exr_check_chunks_, and what the wrapper will decode decoded once by
 * OpenEXRCore by hl_exr_check_decodes_).
 * The wrapper catches every C++ exception and returns 0, with the text in
 * ImfErrorMessage(); OpenEXRCore's messages go to a handler that keeps the
 * last one. The wrapper's pixels are read in strips so that its temporary
 * half buffer stays small.
 * Depends on: exr_check.h (the checks, OpenEXRCore's messages),
 * libOpenEXR-3_1 and libOpenEXRCore-3_1 (through the hl_openexr CMake
 * target).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <ImfCRgbaFile.h>
#include <openexr.h>

#include "exr_check.h"
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
static hl_result check_file(hl_context *ctx, const char *path, uint64_t *size)
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
    *size = (uint64_t)st.st_size;
    return HL_OK;
}

/* The channels read: R, G and B (a missing one reads 0), or Y alone (grey). */
enum { CH_R, CH_G, CH_B, CH_Y, CH_COUNT };
static const char *const channel_names[CH_COUNT] = {"R", "G", "B", "Y"};

static int channel_of(const char *name)
{
    for (int k = 0; name && k < CH_COUNT; k++)
        if (strcmp(name, channel_names[k]) == 0) return k;
    return -1;
}

/* What OpenEXRCore's header parse (no decoding) says of the file. */
typedef struct exr_layout {
    int any_float;          /* an R, G, B or Y channel is 32-bit float */
    int grey;               /* Y is read, as grey; R, G and B are not */
    exr_compression_t comp; /* part 0's compression */
    const char *reason;     /* why read_core does not read it (NULL: it does:
                               one scanline part, R/G/B/Y half or float, not
                               subsampled, no chroma, not DWA, not B44 with
                               only half R/G/B/Y) */
} exr_layout;

/* Y is grey when there is no R, G or B; beside them it wins only where no
 * R, G, B or Y channel is float: the C++ library's RGBA interface reads
 * any file with Y as luminance and drops R, G and B, and half files were
 * read by it before OpenEXRCore read them (they load as they did), while
 * OpenEXRCore has read float ones as RGB since it read float files.
 * B44 with only half R/G/B/Y stays with the wrapper: OpenEXRCore 3.1.5
 * decodes the B44 blocks at a chunk's edges wrongly (the last row of a
 * 130 x 65 map, every pixel of a 2 x 1 one, or "unable to decompress");
 * B44 leaves float channels uncompressed, so float files are not
 * affected, and went to OpenEXRCore before. */
static int probe(exr_context_t f, exr_layout *lay)
{
    int parts = 0;
    exr_storage_t st;
    const exr_attr_chlist_t *cl = NULL;
    memset(lay, 0, sizeof *lay);
    if (exr_get_count(f, &parts) != EXR_ERR_SUCCESS || exr_get_storage(f, 0, &st) != EXR_ERR_SUCCESS ||
        exr_get_compression(f, 0, &lay->comp) != EXR_ERR_SUCCESS ||
        exr_get_channels(f, 0, &cl) != EXR_ERR_SUCCESS || !cl)
        return 0;
    int rgb = 0, y = 0, odd = 0;
    for (int i = 0; i < cl->num_channels; i++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[i];
        if (e->name.str && (strcmp(e->name.str, "RY") == 0 || strcmp(e->name.str, "BY") == 0)) odd = 1;
        int k = channel_of(e->name.str);
        if (k < 0) continue;
        if (k == CH_Y) y = 1;
        else rgb = 1;
        if (e->pixel_type == EXR_PIXEL_FLOAT) lay->any_float = 1;
        else if (e->pixel_type != EXR_PIXEL_HALF) odd = 1;
        if (e->x_sampling != 1 || e->y_sampling != 1) odd = 1;
    }
    lay->grey = y && (!rgb || !lay->any_float);
    const int b44 = lay->comp == EXR_COMPRESSION_B44 || lay->comp == EXR_COMPRESSION_B44A;
    lay->reason = parts != 1                                       ? "a file of several parts"
                  : st != EXR_STORAGE_SCANLINE                     ? "a tiled or deep file"
                  : lay->comp == EXR_COMPRESSION_DWAA ||
                    lay->comp == EXR_COMPRESSION_DWAB              ? "DWA compression"
                  : !rgb && !y                                     ? "no R, G, B or Y channel"
                  : odd                                            ? "subsampled, chroma or integer channels"
                  : b44 && !lay->any_float                         ? "B44 compression of half channels"
                                                                   : NULL;
    return 1;
}

/* Reads a file that probe() passed, as float, chunk by chunk. */
static hl_result read_core(hl_context *ctx, const char *path, unsigned flags, exr_context_t f, const core_msg *msg,
                           int grey, uint32_t *width, uint32_t *height, float **rgb)
{
    exr_attr_box2i_t dw;
    int32_t spc = 0;
    exr_result_t rv = exr_get_data_window(f, 0, &dw);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(f, 0, &spc);
    if (rv != EXR_ERR_SUCCESS || spc < 1)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, core_text(msg, rv));
    uint32_t w, h;
    hl_result r = hl_exr_window_size_(ctx, path, "", flags, dw.min.x, dw.min.y, dw.max.x, dw.max.y, &w, &h);
    if (r != HL_OK) return r;
    float *out = hl_calloc(ctx, 3 * (size_t)w * h, sizeof(float), "environment pixels");
    float *unread = hl_malloc(ctx, sizeof(float) * (size_t)w * (size_t)spc, "OpenEXR unread channel rows");
    if (!out || !unread) {
        free(out);
        free(unread);
        return HL_ERR_OUT_OF_MEMORY;
    }

    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int inited = 0, chosen = 0;
    int64_t y = dw.min.y, first = 0, last = 0;
    for (; r == HL_OK && y <= (int64_t)dw.max.y; y += spc) {
        exr_chunk_info_t ci;
        memset(&ci, 0, sizeof ci);
        first = y - dw.min.y;
        last = first + spc - 1 < (int64_t)h - 1 ? first + spc - 1 : (int64_t)h - 1;
        rv = exr_read_scanline_chunk_info(f, 0, (int)y, &ci);
        if (rv == EXR_ERR_SUCCESS) {
            rv = inited ? exr_decoding_update(f, 0, &ci, &dec) : exr_decoding_initialize(f, 0, &ci, &dec);
            if (rv == EXR_ERR_SUCCESS) inited = 1;
        }
        if (rv == EXR_ERR_SUCCESS &&
            (ci.start_y < dw.min.y || (int64_t)ci.start_y - dw.min.y + ci.height > (int64_t)h || ci.width != (int32_t)w))
            rv = EXR_ERR_CORRUPT_CHUNK;
        /* Every channel is decoded somewhere: those not read go to a scratch
           row buffer. OpenEXRCore 3.1.5 picks its fast half-to-float
           routines (three or four interleaved channels) by the channels it
           writes, then writes every channel, through a NULL pointer for one
           left out (a fuzzer's B, G and one more half channel crashed it). */
        for (int c = 0; rv == EXR_ERR_SUCCESS && c < dec.channel_count; c++) {
            exr_coding_channel_info_t *ch = &dec.channels[c];
            int k = channel_of(ch->channel_name);
            int slot = grey ? (k == CH_Y ? 0 : -1) : (k == CH_Y ? -1 : k);
            if (slot < 0) {
                ch->decode_to_ptr = (uint8_t *)unread;
                ch->user_pixel_stride = (int32_t)sizeof(float);
                ch->user_line_stride = (int32_t)sizeof(float) * (int32_t)w;
            } else {
                ch->decode_to_ptr = (uint8_t *)(out + 3 * (size_t)(ci.start_y - dw.min.y) * w + (size_t)slot);
                ch->user_pixel_stride = 3 * (int32_t)sizeof(float);
                ch->user_line_stride = 3 * (int32_t)sizeof(float) * (int32_t)w;
            }
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
        }
        /* the routines suit every chunk: the channels' types and strides stay */
        if (rv == EXR_ERR_SUCCESS && !chosen) {
            rv = exr_decoding_choose_default_routines(f, 0, &dec);
            chosen = 1;
        }
        if (rv == EXR_ERR_SUCCESS) rv = exr_decoding_run(f, 0, &dec);
        if (rv != EXR_ERR_SUCCESS) {
            char sizes[96];
            hl_exr_chunk_sizes_(sizes, sizeof sizes, &ci);
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: corrupt or truncated pixel data in rows %lld..%lld%s: %s", path,
                        (long long)first, (long long)last, sizes, core_text(msg, rv));
        }
    }
    if (inited) exr_decoding_destroy(f, &dec);
    free(unread);
    if (r != HL_OK) {
        free(out);
        return r;
    }
    if (grey)
        for (size_t i = 0; i < (size_t)w * h; i++) out[3 * i + 1] = out[3 * i + 2] = out[3 * i];
    *width = w;
    *height = h;
    *rgb = out;
    return HL_OK;
}

/* Reads any file the C++ library can, through half floats. A non-NULL
 * float_why marks a file whose float channels may hold values the halves
 * cannot (they come back infinite), and says why it is read this way: any
 * infinity is then refused. */
static hl_result read_wrapper(hl_context *ctx, const char *path, unsigned flags, const char *float_why,
                              uint32_t *width, uint32_t *height, float **rgb)
{
    ImfInputFile *in = ImfOpenInputFile(path);
    if (!in) return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, imf_message());

    int xmin = 0, ymin = 0, xmax = -1, ymax = -1;
    ImfHeaderDataWindow(ImfInputHeader(in), &xmin, &ymin, &xmax, &ymax);
    uint32_t w, h;
    hl_result r = hl_exr_window_size_(ctx, path, "", flags, xmin, ymin, xmax, ymax, &w, &h);
    if (r != HL_OK) {
        ImfCloseInputFile(in);
        return r;
    }
    int channels = ImfInputChannels(in);
    if ((channels & (IMF_WRITE_RGB | IMF_WRITE_Y)) == 0) {
        ImfCloseInputFile(in);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: no R, G, B or Y channel to read", path);
    }

    uint32_t rows = strip_rows(w);
    float *out = hl_malloc(ctx, sizeof(float) * 3 * (size_t)w * h, "environment pixels");
    ImfRgba *strip = hl_calloc(ctx, (size_t)w * rows, sizeof(ImfRgba), "OpenEXR scanline strip");
    if (!out || !strip) {
        free(out);
        free(strip);
        ImfCloseInputFile(in);
        return HL_ERR_OUT_OF_MEMORY;
    }
    uint64_t infinite = 0;
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
            infinite += (uint64_t)(isinf(o[0]) || isinf(o[1]) || isinf(o[2]));
        }
    }
    free(strip);
    ImfCloseInputFile(in);
    if (r == HL_OK && float_why && infinite)
        r = hl_fail(ctx, HL_ERR_FORMAT,
                    "%s: %llu pixel%s infinite or beyond +-65504 as read: its 32-bit float channels are in %s, "
                    "which this build's OpenEXR (3.1) reads only through half floats, so such values are lost; "
                    "save the map as one scanline part with ZIP or PIZ compression", path,
                    (unsigned long long)infinite, infinite == 1 ? " is" : "s are", float_why);
    if (r != HL_OK) {
        free(out);
        return r;
    }
    *width = w;
    *height = h;
    *rgb = out;
    return HL_OK;
}

hl_result hl_exr_read_rgb_(hl_context *ctx, const char *path, unsigned flags,
                           uint32_t *width, uint32_t *height, float **rgb)
{
    *width = *height = 0;
    *rgb = NULL;
    uint64_t file_size = 0;
    hl_result r = check_file(ctx, path, &file_size);
    if (r != HL_OK) return r;

    /* OpenEXRCore parses the header first, bounding every attribute by the
       file's size (the C++ reader does not: a string attribute claiming
       2 GiB gets 2 GiB). Strict: required attributes must be there. A
       complaint it only reports (a chunkCount that disagrees, an attribute
       it skips) refuses the file too. */
    core_msg msg = {{0}};
    exr_context_initializer_t init = core_init(&msg);
    init.flags |= EXR_CONTEXT_FLAG_STRICT_HEADER | EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    exr_context_t f = NULL;
    exr_result_t rv = exr_start_read(&f, path, &init);
    if (rv != EXR_ERR_SUCCESS || msg.text[0])
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, core_text(&msg, rv));
    if (r == HL_OK) r = hl_exr_check_parts_(ctx, path, f, &msg, file_size);
    if (r == HL_OK) r = hl_exr_check_chunks_(ctx, path, f, &msg, file_size);
    exr_layout lay = {0, 0, 0, NULL};
    if (r == HL_OK && !probe(f, &lay))
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path,
                    core_text(&msg, EXR_ERR_MISSING_REQ_ATTR));
    if (r != HL_OK) {
        if (f) exr_finish(&f);
        return r;
    }
    /* Only now does a decoder see the file: OpenEXRCore where it can
       decode it (probe: one scanline part, R/G/B/Y half or float, not
       subsampled, no chroma, not DWA, not B44 of half channels), exactly
       and checking every chunk's decompressed size; else the C++ wrapper,
       after OpenEXRCore has decoded every chunk it will
       (hl_exr_check_decodes_) except for DWA and B44, which OpenEXRCore
       3.1.5 cannot decode (rightly). */
    const int core = !lay.reason;
    const int dwa = lay.comp == EXR_COMPRESSION_DWAA || lay.comp == EXR_COMPRESSION_DWAB;
    const int b44 = lay.comp == EXR_COMPRESSION_B44 || lay.comp == EXR_COMPRESSION_B44A;
    if (core) r = read_core(ctx, path, flags, f, &msg, lay.grey, width, height, rgb);
    else if (!dwa && !b44) r = hl_exr_check_decodes_(ctx, path, f, &msg);
    exr_finish(&f);
    if (core || r != HL_OK) return r;
    return read_wrapper(ctx, path, flags, lay.any_float && !dwa ? lay.reason : NULL, width, height, rgb);
}

hl_result hl_exr_write_rgb_(hl_context *ctx, const char *path, uint32_t width,
                            uint32_t height, const float *rgb)
{
    if (width < 1 || height < 1 || width > HL_EXR_MAX_SIDE || height > HL_EXR_MAX_SIDE ||
        (uint64_t)width * height > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: cannot write a %u x %u OpenEXR image",
                       path, width, height);
    core_msg msg = {{0}};
    exr_context_initializer_t init = core_init(&msg);
    exr_context_t f = NULL;
    int part = 0;
    int32_t spc = 0;
    exr_result_t rv = exr_start_write(&f, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS) rv = exr_add_part(f, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(f, part, (int32_t)width, (int32_t)height, EXR_COMPRESSION_ZIP);
    for (int c = CH_R; rv == EXR_ERR_SUCCESS && c <= CH_B; c++)
        rv = exr_add_channel(f, part, channel_names[c], EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(f);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(f, part, &spc);
    if (rv == EXR_ERR_SUCCESS && spc < 1) rv = EXR_ERR_INVALID_ARGUMENT;
    hl_result r = HL_OK;
    if (rv != EXR_ERR_SUCCESS)
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot create OpenEXR file: %s", path, core_text(&msg, rv));

    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int inited = 0, chosen = 0;
    for (uint32_t y = 0; r == HL_OK && y < height; y += (uint32_t)spc) {
        exr_chunk_info_t ci;
        rv = exr_write_scanline_chunk_info(f, part, (int)y, &ci);
        if (rv == EXR_ERR_SUCCESS) {
            rv = inited ? exr_encoding_update(f, part, &ci, &enc) : exr_encoding_initialize(f, part, &ci, &enc);
            if (rv == EXR_ERR_SUCCESS) inited = 1;
        }
        for (int c = 0; rv == EXR_ERR_SUCCESS && c < enc.channel_count; c++) {
            exr_coding_channel_info_t *ch = &enc.channels[c];
            int k = channel_of(ch->channel_name);
            ch->encode_from_ptr = (const uint8_t *)(rgb + 3 * (size_t)y * width + (size_t)(k < 0 ? 0 : k));
            ch->user_pixel_stride = 3 * (int32_t)sizeof(float);
            ch->user_line_stride = 3 * (int32_t)sizeof(float) * (int32_t)width;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
        }
        if (rv == EXR_ERR_SUCCESS && !chosen) {
            rv = exr_encoding_choose_default_routines(f, part, &enc);
            chosen = 1;
        }
        if (rv == EXR_ERR_SUCCESS) rv = exr_encoding_run(f, part, &enc);
        if (rv != EXR_ERR_SUCCESS) {
            uint32_t last = y + (uint32_t)spc - 1 < height - 1 ? y + (uint32_t)spc - 1 : height - 1;
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write OpenEXR rows %u..%u: %s", path, y, last,
                        core_text(&msg, rv));
        }
    }
    if (inited) exr_encoding_destroy(f, &enc);
    if (f) {
        rv = exr_finish(&f);
        if (rv != EXR_ERR_SUCCESS && r == HL_OK)
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot finish OpenEXR file: %s", path, core_text(&msg, rv));
    }
    return r;
}
