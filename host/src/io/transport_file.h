/* transport_file.h - streaming writer and report for transport files (.hlt).
 *
 * The byte layout is documented in host/FORMAT.md (and transport_layout.h);
 * the writer is transport_file.c, the report transport_report.c, and the
 * reader is the public hl_transport_load (transport_load.c). The
 * precompute pipeline opens a writer, appends vertex rows in order as
 * chunks finish, and finishes it. Memory stays bounded: the mesh is
 * written at open, rows and entries are streamed straight to their final
 * positions in a partial file (path + ".partial", locked while a writer
 * has it), and only the header is written at finish, just before the file
 * is renamed onto path. A checkpoint records in the partial file's header
 * area what has been appended so far, so that a run that was interrupted
 * or killed can resume there and still write the same bytes.
 *
 * Errors: HL_ERR_INVALID_ARGUMENT for bad parameters or appended data (the
 * writer is left as it was, so the caller may still abort or continue),
 * HL_ERR_IO for file system failures (the writer is then unusable except for
 * abort), HL_ERR_OUT_OF_MEMORY. Messages go to the context.
 *
 * Thread safety: a writer belongs to one thread at a time, like its context.
 * Depends on: hl_internal.h (hl_fail, allocation), POSIX file I/O.
 */
#ifndef HL_TRANSPORT_FILE_H
#define HL_TRANSPORT_FILE_H

#include <stdio.h>

#include "hl_internal.h"

typedef struct hl_tfile_writer hl_tfile_writer;

/* Creates the temporary file and writes the mesh into it. info gives every
 * parameter (resolved, no zero defaults: rule, quant, supersample >= 1) and
 * the vertex, object vertex, triangle and block counts, which must agree
 * with mesh; its version, coefficients_kept and ray counters are ignored.
 * On failure *out is NULL and nothing is left on disk. */
hl_result hl_tfile_writer_open(hl_context *ctx, const char *path,
                               const hl_transport_info *info,
                               const hl_mesh *mesh, hl_tfile_writer **out);

/* As open, for shard shard_index of shard_count (a precompute spread over
 * machines, FORMAT.md "Shard files"): the whole mesh, then the rows of the
 * shard's vertices only (transport_layout.h, tf_shard_range), appended in
 * order from its first; finish writes the shard magic. shard_count 0 is a
 * whole file, as open. */
hl_result hl_tfile_writer_open_shard(hl_context *ctx, const char *path, const hl_transport_info *info,
                                     const hl_mesh *mesh, uint32_t shard_index, uint32_t shard_count,
                                     hl_tfile_writer **out);

/* As open for a whole file, with the mesh section copied byte for byte
 * from bytes mesh_offset.. of the open file src_fd (src_path in messages),
 * whose CRC-32 must be mesh_crc (else HL_ERR_FORMAT naming src_path, and
 * nothing is left on disk). The mesh is neither held nor re-checked: merge
 * takes it from shards whose writer checked it. */
hl_result hl_tfile_writer_open_copy(hl_context *ctx, const char *path, const hl_transport_info *info, int src_fd,
                                    const char *src_path, uint64_t mesh_offset, uint32_t mesh_crc,
                                    hl_tfile_writer **out);

/* Appends the next vertex_count vertices in vertex order. Vertex i has
 * row parameters rq[i], block counts block_counts[i * block_count ..] and
 * nnz[i] entries (2 * nnz[i] bytes: in-block index, quantised value) at
 * entries + i * entry_stride_bytes, ordered by block then strictly
 * increasing index. The whole call is validated before anything is
 * written, so a refused append (HL_ERR_INVALID_ARGUMENT) changes nothing. */
hl_result hl_tfile_writer_append(hl_tfile_writer *w, uint32_t vertex_count,
                                 const hl_row_quant *rq,
                                 const uint16_t *block_counts,
                                 const uint8_t *entries,
                                 size_t entry_stride_bytes,
                                 const uint32_t *nnz);

/* Checks that every vertex was appended, writes the header with the
 * checksums, fsyncs and renames the temporary file onto path. final_info
 * supplies rays_cast and rays_culled (NULL: zero); its parameters and counts
 * must equal those given at open, and its coefficients_kept must be 0 or the
 * number appended. The writer is consumed whatever the result: on failure
 * the temporary file is removed and path is untouched. Do not call abort
 * after finish. */
hl_result hl_tfile_writer_finish(hl_tfile_writer *w,
                                 const hl_transport_info *final_info);

/* Removes the partial file and frees the writer. NULL does nothing. */
void hl_tfile_writer_abort(hl_tfile_writer *w);

/* Makes what has been appended so far resumable: flushes the rows and
 * entries and writes a checkpoint (counts, sizes and running checksums,
 * and the ray counters given) in the partial file's header area. Survives
 * the process being killed; a checkpoint whose data did not reach the disk
 * (a power loss) is refused on resume by its checksums. */
hl_result hl_tfile_writer_checkpoint(hl_tfile_writer *w, uint64_t rays_cast, uint64_t rays_culled);

/* Closes the writer and leaves its partial file (and last checkpoint) for a
 * later resume. */
void hl_tfile_writer_keep(hl_tfile_writer *w);

/* Vertices appended so far (of the shard's, for a shard writer). */
uint32_t hl_tfile_writer_appended(const hl_tfile_writer *w);

typedef struct hl_tfile_progress {
    uint32_t appended;      /* vertices already in the file */
    uint64_t coefficients;  /* their entries */
    uint64_t rays_cast, rays_culled;
} hl_tfile_progress;

/* Reopens path + ".partial" at its last checkpoint, after checking that it
 * was made with the same parameters (info, as for open) and the same mesh
 * and that every byte it covers matches its checksums; data past the
 * checkpoint are dropped. With no partial file, returns HL_OK with *out
 * NULL (the caller opens a new one). done gets what is already written. */
hl_result hl_tfile_writer_resume(hl_context *ctx, const char *path, const hl_transport_info *info,
                                 const hl_mesh *mesh, hl_tfile_writer **out, hl_tfile_progress *done);
/* As resume, for a shard's partial file: it must have been made for the
 * same shard (a whole run's is refused, and the other way round). */
hl_result hl_tfile_writer_resume_shard(hl_context *ctx, const char *path, const hl_transport_info *info,
                                       const hl_mesh *mesh, uint32_t shard_index, uint32_t shard_count,
                                       hl_tfile_writer **out, hl_tfile_progress *done);

/* As hl_transport_load, without the entries: t->entries is NULL and
 * they stay in the file, whose entries section starts at
 * *entries_offset (entry e's two bytes at *entries_offset + 2 e). They
 * are checked as the loader checks them (checksum, every row) in one
 * pass through a buffer of whole rows, at least 1 MiB: for a reader of a
 * chunk of rows at a time (the bounce phase). */
hl_result hl_transport_load_streamed(hl_context *ctx, const char *path, hl_transport **out, uint64_t *entries_offset);

/* Human report of a loaded transport for `haarlight info`: parameters,
 * counts, per-vertex statistics, ray counters and sizes. path is only
 * printed (and its size queried); it may be NULL. */
void hl_transport_describe(const hl_transport *t, const char *path, FILE *f);

#endif
