/* exr_io.h - the OpenEXR wrapper (exr_io.c and exr_check.c are the only
 * files that see OpenEXR headers).
 *
 * Reading decodes every compression the library knows, DWAB included.
 * OpenEXRCore reads every file it can decode (one scanline part, not DWA;
 * exr_io.c says which), half and 32-bit float channels alike, at their
 * full value; elsewhere the C++ library's wrapper reads the file through
 * half floats, and a float value the halves cannot hold is refused.
 * Pixels come back as linear float RGB, alpha dropped, row 0 = the first
 * row stored. A header is checked against the limits below, in every
 * part, before any decoder allocates for it, and so is every chunk's table
 * entry, header and extent in the file; a chunk whose data decompresses
 * to fewer bytes than it holds is refused (in DWA files, as far as the
 * C++ library checks; exr_check.c says what it misses).
 */
#ifndef HL_EXR_IO_H
#define HL_EXR_IO_H

#include <stdint.h>

#include "haarlight.h"

/* Largest side and pixel count accepted from a file, checked (in every
 * part) before any allocation. */
#define HL_EXR_MAX_SIDE 65536u
#define HL_EXR_MAX_PIXELS ((uint64_t)1 << 28)
/* Largest chunk (rows or tile) as decoded: a 2:1 map within
 * HL_EXR_MAX_PIXELS is at most 23170 wide, and 256 rows (DWA's chunk) of
 * float RGBA take 95 MB. The C++ reader allocates a few of these when it
 * opens the file. */
#define HL_EXR_MAX_CHUNK_BYTES ((uint64_t)1 << 27)
/* Most attributes and channels in a header, all parts together: the C++
 * reader keeps several hundred bytes for each (a map has a few dozen). */
#define HL_EXR_MAX_HEADER_ENTRIES 8192u

/* Flags of hl_exr_read_rgb_. */
#define HL_EXR_REQUIRE_2TO1 1u /* refuse (HL_ERR_FORMAT) unless width == 2 * height */

/* Reads path into a malloc'ed array of 3 * width * height floats (*rgb,
 * freed by the caller with free()). Values are copied as stored: NaN, Inf
 * and negative values are left for the caller to repair. Errors name the
 * file: HL_ERR_IO when it cannot be opened or read, HL_ERR_FORMAT when it
 * is not a readable OpenEXR image (bad magic, a header OpenEXRCore
 * rejects, sizes beyond the limits above or a chunk table beyond the file,
 * a chunk whose table entry, header or data does not fit the file (the
 * message names the part and the chunk), deep data, corrupt or truncated
 * data, data that decompresses short of its chunk (the message names the
 * rows or the part and the chunk), not 2:1 when asked, float values
 * beyond the half range where only halves can be read). */
hl_result hl_exr_read_rgb_(hl_context *ctx, const char *path, unsigned flags,
                           uint32_t *width, uint32_t *height, float **rgb);

/* Writes 3 * width * height linear floats to path (directly, not
 * atomically: the caller renames) as a 32-bit float RGB scanline image
 * with ZIP compression: every value as it is. Errors (HL_ERR_IO) name the
 * file. */
hl_result hl_exr_write_rgb_(hl_context *ctx, const char *path, uint32_t width,
                            uint32_t height, const float *rgb);

#endif
