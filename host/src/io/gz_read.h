/* gz_read.h - a gzip file decompressed whole into memory, with a size cap
 * (gz_read.c). mesh_import.c uses it so that `FILE.obj.gz` (any X.gz
 * whose inner extension assimp reads) loads as it is.
 *
 * Depends on: hl_internal.h (hl_fail, allocation), zlib (inflate).
 */
#ifndef HL_GZ_READ_H
#define HL_GZ_READ_H

#include <stddef.h>
#include <stdint.h>

#include "hl_internal.h"

/* The most bytes a gzipped mesh may decompress to: assimp's from-memory
 * import takes an unsigned int length, so 4 GiB - 1 is its own limit; an
 * OBJ that size holds some 50 million vertices, past what the 32-bit
 * vertex counts of the file format and the relight's memory allow. */
#define HL_GZ_MAX_BYTES ((uint64_t)UINT32_MAX)

/* 1 when path ends in ".gz" (any case). */
int hl_gz_is_gz_name(const char *path);

/* Decompresses the gzip file path (one member or several, as gzip -c a b
 * writes) into a new buffer of *size bytes, plus a terminating 0 byte not
 * counted in *size (free with free()). More than cap decompressed bytes,
 * a truncated stream, data that are not gzip, a failed checksum or bytes
 * after the last member that are not another member: HL_ERR_FORMAT; a file
 * that cannot be opened or read: HL_ERR_IO; each naming path. */
hl_result hl_gz_read_file(hl_context *ctx, const char *path, uint64_t cap, uint8_t **data, size_t *size);

#endif
