/* fuzz_transport.c - libFuzzer target for the transport file reader
 * (hl_transport_load).
 *
 * Each input is loaded twice: as it is, and, when it starts with the magic
 * and holds a whole header, with every checksum recomputed over the ranges
 * its header names. Random mutations almost never keep the CRC-32s right,
 * so the second load is what reaches the reader's structural checks (mesh
 * contents, block counts, entry order) behind them.
 *
 * On success the transport must keep what haarlight.h promises: a mesh
 * with indices in range and finite values, row offsets that add up to
 * coefficients_kept, and rows that hl_transport_query_row and
 * hl_transport_describe walk without leaving their arrays.
 */
#include "fuzz_common.h"
#include "transport_file.h"

/* host/FORMAT.md, "Header". */
enum {
    F_HEADER_SIZE = 192,
    F_SECTIONS = 96,     /* 3 x (u64 offset, u64 size) */
    F_SECTION_CRCS = 144,/* 3 x u32 */
    F_HEADER_CRC = 188
};

static uint64_t rd64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = v << 8 | p[i];
    return v;
}

static void wr32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

/* Recomputes the section checksums whose ranges lie inside the input,
 * then the header's. */
static void fix_checksums(uint8_t *f, size_t size)
{
    for (int s = 0; s < 3; s++) {
        uint64_t off = rd64(f + F_SECTIONS + 16 * s), len = rd64(f + F_SECTIONS + 16 * s + 8);
        if (off <= size && len <= size - off) wr32(f + F_SECTION_CRCS + 4 * s, hl_test_crc32(f + off, (size_t)len));
    }
    wr32(f + F_HEADER_CRC, hl_test_crc32(f, F_HEADER_CRC));
}

static void check_transport(const hl_transport *t)
{
    const hl_transport_info *i = &t->info;
    FUZZ_REQUIRE(i->version == HL_TRANSPORT_VERSION, "version %u", i->version);
    FUZZ_REQUIRE(i->N >= 8 && i->N <= 256 && (i->N & (i->N - 1)) == 0, "N = %u", i->N);
    FUZZ_REQUIRE(i->block_count == (2 * i->N * i->N + HL_BLOCK - 1) / HL_BLOCK, "block_count %u for N %u",
                 i->block_count, i->N);
    FUZZ_REQUIRE(t->mesh && t->mesh->vertex_count == i->vertex_count &&
                     t->mesh->triangle_count == i->triangle_count &&
                     t->mesh->object_vertex_count == i->object_vertex_count,
                 "mesh counts disagree with the header");
    fuzz_check_mesh(t->mesh);

    uint32_t V = i->vertex_count, B = i->block_count;
    FUZZ_REQUIRE(t->row_offset[0] == 0 && t->row_offset[V] == i->coefficients_kept,
                 "row offsets run from %llu to %llu, coefficients_kept %llu", (unsigned long long)t->row_offset[0],
                 (unsigned long long)t->row_offset[V], (unsigned long long)i->coefficients_kept);
    for (uint32_t v = 0; v < V; v++) {
        uint64_t sum = 0;
        for (uint32_t b = 0; b < B; b++) sum += t->block_counts[(size_t)v * B + b];
        FUZZ_REQUIRE(t->row_offset[v + 1] - t->row_offset[v] == sum, "vertex %u: row length %llu, block counts %llu",
                     v, (unsigned long long)(t->row_offset[v + 1] - t->row_offset[v]), (unsigned long long)sum);
    }

    float *dense = malloc((size_t)2 * i->N * i->N * sizeof *dense);
    FUZZ_REQUIRE(dense != NULL, "out of memory");
    for (uint32_t v = 0; v < V; v++) hl_transport_query_row(t, v, dense);
    free(dense);

    static FILE *devnull = NULL;
    if (!devnull) devnull = fopen("/dev/null", "w");
    if (devnull) hl_transport_describe(t, NULL, devnull);
}

static void load(const uint8_t *data, size_t size)
{
    hl_context *ctx = fuzz_context();
    const char *path = fuzz_write_input(data, size, ".hlt");
    hl_transport *t = NULL;
    hl_result r = hl_transport_load(ctx, path, &t);
    unlink(path);
    fuzz_check_result(r, t);
    if (t) check_transport(t);
    hl_transport_destroy(t);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    load(data, size);
    if (size >= F_HEADER_SIZE && memcmp(data, "HLTRANS1", 8) == 0) {
        uint8_t *fixed = malloc(size);
        FUZZ_REQUIRE(fixed != NULL, "out of memory");
        memcpy(fixed, data, size);
        fix_checksums(fixed, size);
        if (memcmp(fixed, data, size) != 0) load(fixed, size);
        free(fixed);
    }
    return 0;
}
