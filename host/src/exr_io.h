/* exr_io.h - the OpenEXR wrapper (exr_io.c is the only file that sees
 * OpenEXR headers).
 *
 * Reading decodes every compression the library knows, DWAB included.
 * 32-bit float channels keep their full value wherever OpenEXRCore can
 * decode the file (not DWAA/DWAB); elsewhere they pass through half
 * floats, and a value the halves cannot hold is refused (exr_io.c says
 * why). Pixels come back as linear float RGB, alpha dropped, row 0 = the
 * first row stored.
 */
#ifndef HL_EXR_IO_H
#define HL_EXR_IO_H

#include <stdint.h>

#include "haarlight.h"

/* Largest side and pixel count accepted from a file, checked before any
 * allocation. */
#define HL_EXR_MAX_SIDE 65536u
#define HL_EXR_MAX_PIXELS ((uint64_t)1 << 28)

/* Flags of hl_exr_read_rgb_. */
#define HL_EXR_REQUIRE_2TO1 1u /* refuse (HL_ERR_FORMAT) unless width == 2 * height */

/* Reads path into a malloc'ed array of 3 * width * height floats (*rgb,
 * freed by the caller with free()). Values are copied as stored: NaN, Inf
 * and negative values are left for the caller to repair. Errors name the
 * file: HL_ERR_IO when it cannot be opened or read, HL_ERR_FORMAT when it
 * is not a readable OpenEXR image (bad magic, corrupt or truncated data,
 * size out of bounds, not 2:1 when asked, float values beyond the half
 * range in a DWAA/DWAB file). */
hl_result hl_exr_read_rgb_(hl_context *ctx, const char *path, unsigned flags,
                           uint32_t *width, uint32_t *height, float **rgb);

/* Writes 3 * width * height linear floats to path (directly, not
 * atomically: the caller renames) as a 32-bit float RGB scanline image
 * with ZIP compression: every value as it is. Errors (HL_ERR_IO) name the
 * file. */
hl_result hl_exr_write_rgb_(hl_context *ctx, const char *path, uint32_t width,
                            uint32_t height, const float *rgb);

#endif
