/* values_file.h - a direct transport's kept terms as floats, beside it
 * (FILE.values for FILE; host/FORMAT.md "Values files").
 *
 * The bounce phase of precompute --bounces starts from the finished
 * direct rows. Decoded from their 8-bit codes and coded again with the
 * bounces, the direct light would be quantised twice; this file keeps
 * the same terms as the floats they were coded from, so that the sum is
 * coded once. One float per entry of the transport, in the transport's
 * entry order: a shard's values cover its vertices, and the shards'
 * values concatenated are the merged file's.
 *
 * Layout (little-endian): 32 bytes of header, "HLVALUE1", u32 first
 * vertex, u32 vertex count, u64 entry count, u32 CRC-32 of the floats,
 * u32 zero; then the entry count's floats.
 *
 * The writer streams into FILE.values.partial alongside the transport's
 * writer (synced before each of its checkpoints, so a resumed transport
 * never covers more entries than the values hold) and publishes it at
 * finish. The reader checks the header, the size, the checksum, and
 * (hl_vfile_check) that every float codes to its entry's code within one
 * step, so a values file of other rows than its transport's is refused.
 * Depends on: hl_internal.h, hl_shared.h (the quantisers), zlib.
 */
#ifndef HL_VALUES_FILE_H
#define HL_VALUES_FILE_H

#include "hl_internal.h"

typedef struct hl_vfile_writer hl_vfile_writer;

/* The writer of transport_path + ".values" for vertices [first, first +
 * count). resume_entries: 0 starts afresh; else a resumed transport
 * already holds that many entries, and the existing partial file (of the
 * same vertices, at least that long) continues after them. */
hl_result hl_vfile_writer_open(hl_context *ctx, const char *transport_path, uint32_t first, uint32_t count,
                               int resume, uint64_t resume_entries, hl_vfile_writer **out);
/* The kept terms of count rows: row i's nnz[i] entries (block order, as
 * the transport's) whose slots are b * 256 + entries[2 e] and whose floats
 * are coef[i * ncoef + slot]. */
hl_result hl_vfile_writer_append(hl_vfile_writer *w, uint32_t count, const float *coef, uint32_t ncoef,
                                 const uint16_t *block_counts, uint32_t nblocks, const uint8_t *entries,
                                 size_t entry_stride, const uint32_t *nnz);
/* Flushes what was appended (before the transport's checkpoint). */
hl_result hl_vfile_writer_sync(hl_vfile_writer *w);
/* Writes the header and publishes the file; consumes the writer. */
hl_result hl_vfile_writer_finish(hl_vfile_writer *w);
/* keep: leave the partial file for --resume; else remove it. NULL: nothing. */
void hl_vfile_writer_close(hl_vfile_writer *w, int keep);

/* The reader of transport t's floats (t loaded from transport_path), in
 * transport_path + ".values": *out NULL (HL_OK) when there is no such
 * file; HL_ERR_FORMAT naming it when its header, size or checksum (one
 * pass at open through a buffer of 1 MiB) is wrong or it covers other
 * vertices or another entry count than t. The floats are read a chunk of
 * rows at a time after (hl_vfile_read), not held. */
typedef struct hl_vfile_reader hl_vfile_reader;
hl_result hl_vfile_open(hl_context *ctx, const char *transport_path, const hl_transport *t, hl_vfile_reader **out);
/* That the floats vals of vertices [first, first + count) (entries: their
 * entries, from t->row_offset[first] on) code to their entries' codes
 * within one step: else HL_ERR_FORMAT naming the file (floats of other
 * rows). Every chunk once, before the floats are used. */
hl_result hl_vfile_check(hl_context *ctx, const hl_vfile_reader *rd, const char *transport_path, const hl_transport *t,
                         uint32_t first, uint32_t count, const uint8_t *entries, const float *vals);
/* Floats [first, first + n) into dst. */
hl_result hl_vfile_read(hl_context *ctx, hl_vfile_reader *rd, uint64_t first, size_t n, float *dst);
void hl_vfile_close(hl_vfile_reader *rd);

/* Joins the values of count shard files (shard_paths, any order) into
 * out_path + ".values". *written 0 (HL_OK, an older out_path + ".values"
 * removed) when not every shard has values (a warning when some have). */
hl_result hl_vfile_merge(hl_context *ctx, const char *out_path, const char *const *shard_paths, uint32_t count,
                         int *written);

#endif
