/* hdr_io.c - Radiance .hdr (RGBE) environments, decoded by stb_image
 * (Debian's libstb), behind checks of our own.
 *
 * stb_image decodes both the run-length and the flat scanlines, but it
 * takes a truncated file for one padded with zeros, and it knows nothing
 * of the header's EXPOSURE. So the header is parsed here first, strictly:
 * the magic, a FORMAT of 32-bit_rle_rgbe (XYZE files are refused: their
 * primaries are not ours), EXPOSURE (the pixels were multiplied by it, so
 * they are divided back), and the standard resolution line "-Y H +X W"
 * (the only one stb reads: other orientations are refused by name). The
 * sizes are checked against the limits of OpenEXR maps and against the
 * bytes the file holds before stb allocates, and stb reads through a
 * callback that notices a read past the end (and keeps stb 5.2022's
 * run-length reader from looping for ever there).
 * Depends on: exr_io.h (the size limits shared by all map formats),
 * hl_internal.h, stb_image.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image.h>

#include "exr_io.h"
#include "hdr_io.h"
#include "hl_internal.h"

/* Longest header line we accept, and most header lines: real files have a
 * handful of short ones (software, FORMAT, EXPOSURE, a blank line). */
#define HDR_MAX_LINE 4096u
#define HDR_MAX_LINES 1024u

typedef struct hdr_src {
    const uint8_t *p;
    size_t n, at;
    int past_end; /* stb asked for bytes the file does not have */
} hdr_src;

/* Past the end, stb would read zeros, and a run-length scanline of zero
 * counts never advances: stb loops for ever on a truncated file. So the
 * end is marked, and stb is fed 0xFF bytes instead, which its run-length
 * reader refuses as bad data or consumes 127 pixels at a time (and the
 * flat reader reads as finite values): it stops soon, and the mark makes
 * the file refused whatever stb returns. */
static int src_read(void *user, char *data, int size)
{
    hdr_src *s = user;
    if (size <= 0) return 0;
    size_t left = s->n - s->at, want = (size_t)size;
    if (left == 0) {
        s->past_end = 1;
        memset(data, 0xFF, want);
        return size;
    }
    if (want > left) want = left;
    memcpy(data, s->p + s->at, want);
    s->at += want;
    return (int)want;
}

static void src_skip(void *user, int n)
{
    hdr_src *s = user;
    if (n < 0) {
        size_t back = (size_t)-(long)n;
        s->at = back > s->at ? 0 : s->at - back;
    } else if ((size_t)n > s->n - s->at) {
        s->at = s->n;
        s->past_end = 1;
    } else {
        s->at += (size_t)n;
    }
}

static int src_eof(void *user)
{
    const hdr_src *s = user;
    return s->at >= s->n;
}

/* The next header line (without its '\n') into line; 0 at a line too long
 * or the end of the file. */
static int next_line(const uint8_t *p, size_t n, size_t *at, char line[HDR_MAX_LINE])
{
    size_t k = 0;
    while (*at < n) {
        const uint8_t c = p[(*at)++];
        if (c == '\n') {
            line[k] = 0;
            return 1;
        }
        if (k + 1 >= HDR_MAX_LINE) return 0;
        line[k++] = (char)c;
    }
    return 0;
}

typedef struct hdr_header {
    uint32_t width, height;
    double exposure; /* product of the EXPOSURE lines, 1 without */
    size_t data_at;  /* first byte of the pixels */
} hdr_header;

static hl_result parse_header(hl_context *ctx, const char *path, const uint8_t *p, size_t n, hdr_header *h)
{
    char line[HDR_MAX_LINE];
    size_t at = 0;
    if (!next_line(p, n, &at, line) || (strcmp(line, "#?RADIANCE") && strcmp(line, "#?RGBE")))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not a Radiance .hdr file (it must begin with #?RADIANCE or #?RGBE)", path);
    h->exposure = 1.0;
    for (uint32_t i = 0;; i++) {
        if (i == HDR_MAX_LINES || !next_line(p, n, &at, line))
            return hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated or malformed .hdr header (no blank line ends it within %u lines of at most %u bytes)",
                           path, HDR_MAX_LINES, HDR_MAX_LINE);
        if (!line[0]) break;
        if (!strncmp(line, "FORMAT=", 7)) {
            if (strcmp(line + 7, "32-bit_rle_rgbe"))
                return hl_fail(ctx, HL_ERR_FORMAT, "%s: .hdr pixel format \"%.64s\" is not supported (only 32-bit_rle_rgbe; XYZE is not)", path, line + 7);
        } else if (!strncmp(line, "EXPOSURE=", 9)) {
            char *end = NULL;
            errno = 0;
            const double e = strtod(line + 9, &end);
            if (errno || end == line + 9 || !isfinite(e) || e <= 0.0)
                return hl_fail(ctx, HL_ERR_FORMAT, "%s: .hdr EXPOSURE \"%.64s\" is not a positive number", path, line + 9);
            h->exposure *= e;
        }
    }
    if (!next_line(p, n, &at, line))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated .hdr file (no resolution line)", path);
    unsigned long hh = 0, ww = 0;
    char ya[3], xa[3];
    int used = 0;
    if (sscanf(line, "%2s %lu %2s %lu%n", ya, &hh, xa, &ww, &used) != 4 || line[used] != 0)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: malformed .hdr resolution line \"%.64s\"", path, line);
    if (strcmp(ya, "-Y") || strcmp(xa, "+X"))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: .hdr orientation \"%s %s\" is not supported (only -Y H +X W, rows from the top)", path, ya, xa);
    if (hh < 1 || ww < 1 || hh > HL_EXR_MAX_SIDE || ww > HL_EXR_MAX_SIDE || (uint64_t)hh * ww > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: .hdr size %lu x %lu is outside 1 to %u a side and %llu pixels", path, ww, hh,
                       HL_EXR_MAX_SIDE, (unsigned long long)HL_EXR_MAX_PIXELS);
    if (h->exposure > 1e30 || h->exposure < 1e-30)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: .hdr EXPOSURE %g is outside 1e-30 to 1e30", path, h->exposure);
    h->width = (uint32_t)ww;
    h->height = (uint32_t)hh;
    h->data_at = at;
    return HL_OK;
}

/* The fewest bytes the pixels can take: a run-length scanline (widths 8 to
 * 32767) is 4 bytes and, per channel, at least one 2-byte run per 127
 * pixels; any other scanline is 4 bytes a pixel. */
static uint64_t least_bytes(uint32_t w, uint32_t h)
{
    const uint64_t rle = 4u + 8u * (((uint64_t)w + 126u) / 127u), flat = 4u * (uint64_t)w;
    const uint64_t line = (w >= 8 && w < 32768) ? (rle < flat ? rle : flat) : flat;
    return line * h;
}

static hl_result read_all(hl_context *ctx, const char *path, uint8_t **out, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f) return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    long size = -1;
    if (fseek(f, 0, SEEK_END) == 0) size = ftell(f);
    if (size < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot read its size", path);
    }
    /* a map within the pixel limit takes at most 4 bytes a pixel, plus
       its header */
    if ((uint64_t)size > 4u * HL_EXR_MAX_PIXELS + (uint64_t)HDR_MAX_LINE * HDR_MAX_LINES) {
        fclose(f);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: %ld bytes is larger than any .hdr map within the size limits", path, size);
    }
    uint8_t *p = malloc(size > 0 ? (size_t)size : 1);
    if (!p) {
        fclose(f);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory reading %ld bytes", path, size);
    }
    const size_t got = fread(p, 1, (size_t)size, f);
    const int bad = ferror(f);
    fclose(f);
    if (bad || got != (size_t)size) {
        free(p);
        return hl_fail(ctx, HL_ERR_IO, "%s: read error", path);
    }
    *out = p;
    *n = got;
    return HL_OK;
}

int hl_hdr_sniff_(const uint8_t *head, size_t n)
{
    return (n >= 10 && !memcmp(head, "#?RADIANCE", 10)) || (n >= 6 && !memcmp(head, "#?RGBE", 6));
}

hl_result hl_hdr_read_rgb_(hl_context *ctx, const char *path, uint32_t *width, uint32_t *height, float **rgb)
{
    uint8_t *p = NULL;
    size_t n = 0;
    hl_result r = read_all(ctx, path, &p, &n);
    if (r != HL_OK) return r;
    hdr_header h;
    r = parse_header(ctx, path, p, n, &h);
    if (r == HL_OK && n - h.data_at < least_bytes(h.width, h.height))
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated .hdr file: %zu bytes of pixels, where %u x %u pixels take at least %llu",
                    path, n - h.data_at, h.width, h.height, (unsigned long long)least_bytes(h.width, h.height));
    if (r != HL_OK) {
        free(p);
        return r;
    }
    hdr_src src = {p, n, 0, 0};
    const stbi_io_callbacks cb = {src_read, src_skip, src_eof};
    int w = 0, hgt = 0, comp = 0;
    float *img = stbi_loadf_from_callbacks(&cb, &src, &w, &hgt, &comp, 3);
    free(p);
    if (!img && src.past_end)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated .hdr pixels (a scanline runs past the end of the file)", path);
    if (!img)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: corrupt .hdr pixels (stb_image: %s)", path, stbi_failure_reason());
    if (src.past_end || (uint32_t)w != h.width || (uint32_t)hgt != h.height) {
        stbi_image_free(img);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: truncated or corrupt .hdr pixels (a scanline runs past the end of the file)", path);
    }
    const size_t count = 3u * (size_t)h.width * h.height;
    float *out = malloc(count * sizeof *out);
    if (!out) {
        stbi_image_free(img);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory for %u x %u pixels", path, h.width, h.height);
    }
    const double inv = 1.0 / h.exposure;
    for (size_t i = 0; i < count; i++) out[i] = h.exposure == 1.0 ? img[i] : (float)(img[i] * inv);
    stbi_image_free(img);
    *width = h.width;
    *height = h.height;
    *rgb = out;
    return HL_OK;
}
