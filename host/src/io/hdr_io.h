/* hdr_io.h - Radiance .hdr (RGBE) maps (hdr_io.c is the only file that
 * sees stb_image). */
#ifndef HL_HDR_IO_H
#define HL_HDR_IO_H

#include <stddef.h>
#include <stdint.h>

#include "haarlight.h"

/* Whether a file's first n bytes are a Radiance header's magic. */
int hl_hdr_sniff_(const uint8_t *head, size_t n);

/* Reads path into a malloc'ed array of 3 * width * height floats (*rgb,
 * freed by the caller with free()), row 0 = the first row stored, divided
 * by the header's EXPOSURE. Errors name the file: HL_ERR_IO when it cannot
 * be opened or read, HL_ERR_FORMAT for a header that is not Radiance's, a
 * pixel format other than 32-bit_rle_rgbe, an orientation other than
 * "-Y H +X W", sizes beyond the limits of exr_io.h, and truncated or
 * corrupt pixels. */
hl_result hl_hdr_read_rgb_(hl_context *ctx, const char *path, uint32_t *width, uint32_t *height, float **rgb);

#endif
