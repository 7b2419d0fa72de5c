/* transport_layout.h - the byte layout of transport files (.hlt), shared by
 * the writer (transport_file.c), the loader (transport_load.c) and the
 * layout's own code (transport_layout.c): header offsets, section sizes,
 * little-endian byte coding, the CRC-32 and the checks both sides apply.
 *
 * The constants must match host/FORMAT.md. Everything is little-endian and
 * encoded byte by byte, so files are identical whatever the host.
 *
 * Depends on: hl_internal.h (types), zlib (crc32_z).
 */
#ifndef HL_TRANSPORT_LAYOUT_H
#define HL_TRANSPORT_LAYOUT_H

#include <stddef.h>
#include <string.h>
#include <stdint.h>

#include <zlib.h>

#include "hl_internal.h"

#define TF_MAGIC "HLTRANS1"
/* An unfinished file (path + ".partial"), resumable: the header area holds
 * a checkpoint in the same layout, with the sections' sizes and checksums
 * so far and the vertices appended so far in the first reserved word. */
#define TF_PARTIAL_MAGIC "HLTPART1"
/* One shard of a precompute spread over machines (haarlight precompute
 * --shard i/n): the header and mesh of the whole file, the rows and
 * entries of vertices [first, end) only, and the shard in the reserved
 * words H_SHARD_*. Its own magic, so that no reader takes it for a whole
 * transport; `haarlight merge` joins the n shards into one. */
#define TF_SHARD_MAGIC "HLTSHRD1"
#define TF_VERSION HL_TRANSPORT_VERSION
#define TF_HEADER_SIZE 192u
#define TF_ALIGN 64u /* section alignment: lets a later reader mmap them */

/* Header field offsets (FORMAT.md, "Header"). */
enum {
    H_MAGIC = 0,
    H_VERSION = 8,
    H_HEADER_SIZE = 12,
    H_N = 16,
    H_C = 20,
    H_SUPERSAMPLE = 24,
    H_RULE = 28,
    H_K = 32,
    H_EPS = 36,
    H_QUANT = 40,
    H_RAY_OFFSET = 44,
    H_VERTEX_COUNT = 48,
    H_OBJECT_VERTEX_COUNT = 52,
    H_TRIANGLE_COUNT = 56,
    H_BLOCK_COUNT = 60,
    H_COEFFICIENTS_KEPT = 64,
    H_RAYS_CAST = 72,
    H_RAYS_CULLED = 80,
    H_FILE_SIZE = 88,
    H_SECTIONS = 96, /* 3 x (u64 offset, u64 size) */
    H_SECTION_CRCS = 144, /* 3 x u32 */
    H_RESERVED = 156,
    H_APPENDED = 156, /* partial files only */
    H_SHARD_INDEX = 160, /* shard files and their partial files only: */
    H_SHARD_COUNT = 164,
    H_SHARD_FIRST = 168, /* the shard's vertices [first, end) */
    H_SHARD_END = 172,
    H_BASIS = 176,    /* HL_TRANSPORT_BASIS_*: 0 (Haar) in files from before */
    H_SH_ORDER = 180, /* spherical harmonics: L; cube-face Haar: C'; else 0 */
    H_BOUNCES = 184,  /* u16 interreflection bounces baked in (0 in files from before), then u16
                         channels: 3 for a row a channel (coloured bounces), else 0 */
    H_HEADER_CRC = 188
};

enum { SEC_MESH, SEC_ROWS, SEC_ENTRIES, SEC_COUNT };

/* Largest row record: N = 256 gives 512 blocks. */
#define TF_MAX_BLOCKS 512u
#define TF_MAX_RECORD (8u + 2u * TF_MAX_BLOCKS)

typedef struct tf_section {
    uint64_t offset, size;
    uint32_t crc;
} tf_section;

/* Shard index of count (count 0: a whole file, first 0, end V). */
typedef struct tf_shard {
    uint32_t index, count, first, end;
} tf_shard;

typedef struct tf_header {
    hl_transport_info info;
    uint32_t header_size;
    uint64_t file_size;
    tf_section sec[SEC_COUNT];
    tf_shard shard;
    int reserved_nonzero; /* any of bytes H_RESERVED..H_HEADER_CRC - 1 but the basis words */
} tf_header;

/* ---------------------------------------------------------------- bytes */

static inline void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static inline void put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

static inline void put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}

static inline uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }

static inline uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline uint64_t get_u64(const uint8_t *p) { return (uint64_t)get_u32(p) | (uint64_t)get_u32(p + 4) << 32; }

static inline uint64_t align_up(uint64_t x) { return (x + (TF_ALIGN - 1)) & ~(uint64_t)(TF_ALIGN - 1); }

/* ---------------------------------------------------------------- CRC-32 */

/* IEEE 802.3 CRC-32 (reflected polynomial 0xEDB88320, as PNG), computed
 * by zlib's crc32_z. crc is the value returned by the previous call (0 to
 * start), so a section's CRC can be built piece by piece. */
static inline uint32_t crc_update(uint32_t crc, const void *data, size_t n)
{
    return (uint32_t)crc32_z(crc, data, n);
}

/* crc_update(0, data, bytes) on the context's threads: pieces of 64 MiB
 * checksummed apart and joined in order (transport_load.c). */
hl_result hl_tf_crc_threads(hl_context *ctx, const void *data, uint64_t bytes, uint32_t *crc);

/* ---------------------------------------------------------------- sizes */

static inline uint32_t slot_total(uint32_t N) { return 2u * N * N; }
static inline uint32_t blocks_for(uint32_t N) { return (slot_total(N) + HL_BLOCK - 1) / HL_BLOCK; }

/* Whether header byte k is one of the basis words (not reserved). */
static inline int tf_basis_byte(unsigned k) { return k >= H_BASIS && k < H_BOUNCES + 4; }

/* The slots a row of the basis may fill: L^2 for spherical harmonics,
 * 6 C'^2 for cube-face Haar, else all 2 N^2. */
static inline uint32_t tf_slot_limit(const hl_transport_info *i)
{
    if (i->basis == HL_TRANSPORT_BASIS_CUBE) return 6 * i->sh_order * i->sh_order;
    return i->basis == HL_TRANSPORT_BASIS_SH ? i->sh_order * i->sh_order : slot_total(i->N);
}

/* Slots of block b: HL_BLOCK except a short last block (N = 8). */
static inline uint32_t slots_in_block(uint32_t N, uint32_t b)
{
    uint32_t rest = slot_total(N) - b * HL_BLOCK;
    return rest < HL_BLOCK ? rest : HL_BLOCK;
}

static inline uint64_t mesh_bytes(uint32_t vertices, uint32_t triangles)
{
    return 36u * (uint64_t)vertices + 12u * (uint64_t)triangles;
}

static inline uint64_t row_record_bytes(uint32_t block_count) { return 8u + 2u * (uint64_t)block_count; }

/* The vertices [*first, *end) of shard i of n (n >= 1, i < n, n <= V):
 * contiguous, in order, their lengths differing by at most one, and a
 * function of V, i and n alone, so that every machine splits alike. */
static inline void tf_shard_range(uint32_t V, uint32_t i, uint32_t n, uint32_t *first, uint32_t *end)
{
    *first = (uint32_t)((uint64_t)V * i / n);
    *end = (uint32_t)((uint64_t)V * (i + 1) / n);
}

/* ---------------------------------------------------------------- header */

/* magic: TF_MAGIC, or TF_PARTIAL_MAGIC for the checkpoint of an unfinished
 * file, which also records the vertices appended so far (H_APPENDED). */
void hl_tf_header_encode(const tf_header *h, const char *magic, uint32_t appended, uint8_t out[TF_HEADER_SIZE]);
/* Every field, unchecked (the shard words too, whatever the magic);
 * reserved_nonzero tells whether bytes H_RESERVED..H_HEADER_CRC - 1 hold
 * anything. */
void hl_tf_header_decode(const uint8_t *in, tf_header *h);

/* ---------------------------------------------------------------- checks */

/* Each describes the first problem into msg (n bytes) and returns 1, or
 * returns 0 when there is none. Shared by the writer (a caller's bug) and
 * the loader (a bad file). */

/* The parameters and counts of a header. */
int hl_tf_info_problem(const hl_transport_info *i, char *msg, size_t n);
/* Finite positions, unit normals, albedo in [0, 1], indices in range. */
int hl_tf_mesh_problem(uint32_t vertices, uint32_t triangles, const float *pos, const float *nrm,
                       const float *alb, const uint32_t *idx, char *msg, size_t n);
/* Sections against the sizes the counts imply (expect): ordered, 64-byte
 * aligned, past the header, inside file_size, which must end the last. */
int hl_tf_sections_problem(const tf_header *h, const uint64_t expect[SEC_COUNT], char *msg, size_t n);
/* A shard file's header: parameters, the shard (index below count, count
 * at most V, the range tf_shard_range gives), section sizes and offsets,
 * the other reserved bytes zero. The magic and CRC are checked before. */
int hl_tf_shard_header_problem(const tf_header *h, const uint8_t bytes[TF_HEADER_SIZE], char *msg, size_t n);
/* A row's quantisation parameters under scheme quant. */
int hl_tf_row_quant_problem(uint32_t quant, hl_row_quant rq, char *msg, size_t n);
/* Checks one vertex's block counts and entries. entries may be NULL to
 * check only the counts (the sum is returned in *nnz either way). */
int hl_tf_row_problem(uint32_t N, const uint16_t *counts, const uint8_t *entries, uint64_t *nnz, char *msg,
                      size_t n);
/* After hl_tf_row_problem passed on the entries: every slot is below limit
 * (tf_slot_limit), checked on each block's last entry. */
int hl_tf_row_slots_problem(uint32_t N, uint32_t limit, const uint16_t *counts, const uint8_t *entries, char *msg,
                            size_t n);

/* ---------------------------------------------------------------- file I/O */

/* n bytes at offset off, retried after EINTR and short writes: 0, or -1
 * with errno set. */
int hl_tf_pwrite_all(int fd, const void *data, size_t n, uint64_t off);
/* 0: read all; 1: end of file first; -1: error (errno). */
int hl_tf_pread_all(int fd, void *data, size_t n, uint64_t off);

/* s with suffix (may be NULL) appended, as a new string (free); NULL,
 * with the context told, when out of memory. For a file's companions
 * (".partial", ".values"). */
char *hl_tf_path_with(hl_context *ctx, const char *s, const char *suffix);

/* Whether this host stores words little-endian, as the files do. */
static inline int tf_host_little_endian(void)
{
    const uint16_t one = 1;
    uint8_t b;
    memcpy(&b, &one, 1);
    return b == 1;
}

#endif
