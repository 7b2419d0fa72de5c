/* test_transport_hostile.c - corrupt transport files and bad rows (suite
 * "transport_hostile").
 *
 * Cases: corrupt (every single-byte flip refused unless it lands in
 * padding; forged headers and contents with valid checksums refused),
 * badappend (invalid rows and parameters refused without changing the
 * writer), basis (the basis words at 176 and 180: an unknown basis, an
 * order out of range or too big for N, an order given to a Haar file, an
 * entry at or past L^2, a reserved byte beside them, all refused naming
 * the file and the field; the writer refuses such an entry too, and a
 * spherical-harmonic file within its L^2 slots reads back entry for
 * entry), pieces (the loader's threaded pieces and row checks, made
 * small). The header offsets are those of host/FORMAT.md, so this test
 * also pins the documented layout; checksums are forged with the test's
 * own bitwise CRC-32.
 * Depends on: haarlight_core (reference backend only),
 * tests/common/transport_synth.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#include "hl_test.h"
#include "transport_file.h"
#include "transport_synth.h"

static hl_result load_bytes(hl_context *ctx, const char *path, const uint8_t *data, size_t size, hl_transport **t)
{
    write_file(path, data, size);
    *t = NULL;
    return hl_transport_load(ctx, path, t);
}

static void expect_refused(hl_context *ctx, const char *path, const uint8_t *data, size_t size, const char *what,
                           const char *needle)
{
    hl_transport *t = NULL;
    hl_result r = load_bytes(ctx, path, data, size, &t);
    const char *msg = hl_context_last_error(ctx);
    printf("%s: %s\n", what, msg);
    HL_CHECK(r == HL_ERR_FORMAT && t == NULL, "%s: result %d", what, (int)r);
    HL_CHECK(strstr(msg, needle) != NULL, "%s: message should mention \"%s\"", what, needle);
    hl_transport_destroy(t);
}

/* small_file written to HL_TMP/NAME_src.hlt (path), its bytes (size in
 * *size), and bad, HL_TMP/NAME.hlt, for the forgeries. */
static uint8_t *small_bytes(hl_context *ctx, const char *name, char *path, char *bad, size_t n, synth *s, size_t *size)
{
    char file[128];
    snprintf(file, sizeof file, "%s_src.hlt", name);
    tmp_path(path, n, file);
    snprintf(file, sizeof file, "%s.hlt", name);
    tmp_path(bad, n, file);
    small_file(ctx, path, s);
    uint8_t *data = NULL;
    *size = 0;
    HL_CHECK(read_file(path, &data, size) == 0, "read");
    return data;
}

/* Frees what small_bytes and a case made and removes both files. */
static void small_done(hl_context *ctx, synth *s, uint8_t *data, uint8_t *f, const char *path, const char *bad)
{
    free(f);
    free(data);
    remove(bad);
    remove(path);
    synth_free(s);
    hl_context_destroy(ctx);
}

/* Vertex v of an N = 8 file (row records of 8 + 2 bytes) claims 129
 * entries in its 128-slot block; the rows' checksum made to match. */
static void overfill_count(uint8_t *f, uint64_t rows_off, uint32_t v)
{
    f[rows_off + 10 * (uint64_t)v + 8] = 129;
    f[rows_off + 10 * (uint64_t)v + 9] = 0;
    fix_section_crc(f, F_ROWS_OFFSET, F_ROWS_CRC);
}

static void case_corrupt(void)
{
    hl_context *ctx = make_ctx();
    char path[512], bad[512];
    synth s;
    size_t size = 0;
    uint8_t *data = small_bytes(ctx, "file_corrupt", path, bad, sizeof path, &s, &size);
    uint8_t *f = malloc(size);

    uint64_t mesh_end = rd64(data + F_MESH_OFFSET) + rd64(data + F_MESH_SIZE);
    uint64_t rows_end = rd64(data + F_ROWS_OFFSET) + rd64(data + F_ROWS_SIZE);
    uint64_t rows_off = rd64(data + F_ROWS_OFFSET), entries_off = rd64(data + F_ENTRIES_OFFSET);
    printf("file %zu bytes, padding [%llu, %llu) and [%llu, %llu)\n", size, (unsigned long long)mesh_end,
           (unsigned long long)rows_off, (unsigned long long)rows_end, (unsigned long long)entries_off);

    /* every byte, three flip patterns */
    static const uint8_t masks[] = {0x01, 0x80, 0xFF};
    int refused = 0, padding_ok = 0;
    for (size_t pos = 0; pos < size; pos++)
        for (int m = 0; m < 3; m++) {
            memcpy(f, data, size);
            f[pos] ^= masks[m];
            hl_transport *t = NULL;
            hl_result r = load_bytes(ctx, bad, f, size, &t);
            int in_padding = (pos >= mesh_end && pos < rows_off) || (pos >= rows_end && pos < entries_off);
            if (r == HL_ERR_FORMAT && !t) {
                refused++;
                HL_CHECK(!in_padding, "flip at %zu (padding) refused: %s", pos, hl_context_last_error(ctx));
            } else if (r == HL_OK && t) {
                HL_CHECK(in_padding, "flip 0x%02x at %zu accepted", masks[m], pos);
                synth_compare(t, &s, "padding flip");
                padding_ok++;
            } else {
                HL_CHECK(0, "flip at %zu: result %d", pos, (int)r);
            }
            hl_transport_destroy(t);
        }
    printf("%d flips refused, %d in padding loaded identically\n", refused, padding_ok);

    /* forged headers with valid CRCs */
    memcpy(f, data, size);
    memcpy(f, "HLTRANS2", 8);
    expect_refused(ctx, bad, f, size, "magic", "not a haarlight transport file");
    memcpy(f, data, size);
    wr32(f + F_VERSION, 1);
    fix_header_crc(f);
    expect_refused(ctx, bad, f, size, "version", "version 1, this build reads 2");
    memcpy(f, data, size);
    wr32(f + F_N, 12);
    fix_header_crc(f);
    expect_refused(ctx, bad, f, size, "N", "N = 12");
    memcpy(f, data, size);
    wr32(f + F_VERTEX_COUNT, 0xFFFFFFF0u);
    fix_header_crc(f);
    expect_refused(ctx, bad, f, size, "huge vertex_count", "mesh_size");

    /* consistent forgery: every size agrees with a 2^31-vertex file, so only
     * the real file size stands between the reader and a 100 GB malloc */
    {
        uint32_t V = 0x7FFFFFFFu, T = 0x7FFFFFFFu;
        uint64_t mesh = 36ull * V + 12ull * T, ro = (192 + mesh + 63) / 64 * 64, rs = 10ull * V;
        uint64_t eo = (ro + rs + 63) / 64 * 64;
        memcpy(f, data, size);
        wr32(f + F_VERTEX_COUNT, V);
        wr32(f + F_TRIANGLE_COUNT, T);
        wr64(f + F_COEF, 0);
        wr64(f + F_MESH_SIZE, mesh);
        wr64(f + F_ROWS_OFFSET, ro);
        wr64(f + F_ROWS_SIZE, rs);
        wr64(f + F_ENTRIES_OFFSET, eo);
        wr64(f + F_ENTRIES_SIZE, 0);
        wr64(f + F_FILE_SIZE, eo);
        fix_header_crc(f);
        expect_refused(ctx, bad, f, size, "consistent huge header", "truncated: expected");
    }

    /* valid checksums, invalid contents: the structure checks must catch them */
    uint64_t mo = rd64(data + F_MESH_OFFSET);
    uint32_t V = s.info.vertex_count, T = s.info.triangle_count;
    memcpy(f, data, size);
    wr32(f + mo + 36 * V + 12 * 2 + 4, V); /* triangle 2, second index */
    fix_section_crc(f, F_MESH_OFFSET, F_MESH_CRC);
    expect_refused(ctx, bad, f, size, "index out of range", "triangle 2");
    memcpy(f, data, size);
    wr32(f + mo + 12 * 3 + 4, 0x7FC00000u); /* vertex 3 position y = NaN */
    fix_section_crc(f, F_MESH_OFFSET, F_MESH_CRC);
    expect_refused(ctx, bad, f, size, "NaN position", "vertex 3");
    memcpy(f, data, size);
    wr32(f + mo + 24 * V + 12 * 4, 0x7F800000u); /* vertex 4 albedo r = +Inf */
    fix_section_crc(f, F_MESH_OFFSET, F_MESH_CRC);
    expect_refused(ctx, bad, f, size, "Inf albedo", "vertex 4");
    memcpy(f, data, size);
    wr32(f + mo + 24 * V + 12 * 2 + 4, 0x40000000u); /* vertex 2 albedo g = 2 */
    fix_section_crc(f, F_MESH_OFFSET, F_MESH_CRC);
    expect_refused(ctx, bad, f, size, "albedo above 1", "vertex 2: albedo");
    memcpy(f, data, size);
    wr32(f + mo + 12 * V + 12 * 3, 0x40000000u); /* vertex 3 normal x = 2 */
    fix_section_crc(f, F_MESH_OFFSET, F_MESH_CRC);
    expect_refused(ctx, bad, f, size, "normal not of unit length", "vertex 3: normal");
    (void)T;

    /* row records: 8 + 2 bytes for N = 8 */
    memcpy(f, data, size);
    overfill_count(f, rows_off, 2);
    expect_refused(ctx, bad, f, size, "count over slots", "vertex 2");
    memcpy(f, data, size);
    f[rows_off + 10 * 0 + 8] += 1; /* vertex 0 is empty; now it claims an entry */
    fix_section_crc(f, F_ROWS_OFFSET, F_ROWS_CRC);
    expect_refused(ctx, bad, f, size, "count sum", "vertex");
    memcpy(f, data, size);
    wr32(f + rows_off + 10 * 3, 0xBF800000u); /* vertex 3 log8 min = -1 */
    fix_section_crc(f, F_ROWS_OFFSET, F_ROWS_CRC);
    expect_refused(ctx, bad, f, size, "negative log8 magnitude", "vertex 3");

    /* entries: the first vertex with two entries in its (single) block */
    uint64_t off = 0;
    uint32_t target = V;
    for (uint32_t v = 0; v < V; v++) {
        if (s.nnz[v] >= 2) {
            target = v;
            break;
        }
        off += s.nnz[v];
    }
    HL_CHECK(target < V, "small file needs a vertex with two entries");
    if (target < V) {
        char needle[32];
        snprintf(needle, sizeof needle, "vertex %u", target);
        memcpy(f, data, size);
        uint8_t *e = f + entries_off + 2 * off;
        uint8_t tmp = e[0];
        e[0] = e[2];
        e[2] = tmp; /* indices now decrease */
        fix_section_crc(f, F_ENTRIES_OFFSET, F_ENTRIES_CRC);
        expect_refused(ctx, bad, f, size, "decreasing indices", needle);
        memcpy(f, data, size);
        e = f + entries_off + 2 * off;
        e[2] = e[0]; /* duplicate index */
        fix_section_crc(f, F_ENTRIES_OFFSET, F_ENTRIES_CRC);
        expect_refused(ctx, bad, f, size, "duplicate index", needle);
        memcpy(f, data, size);
        e = f + entries_off + 2 * off;
        e[2 * (s.nnz[target] - 1)] = 200; /* beyond the 128 slots of N = 8 */
        fix_section_crc(f, F_ENTRIES_OFFSET, F_ENTRIES_CRC);
        expect_refused(ctx, bad, f, size, "index beyond slots", needle);
    }
    small_done(ctx, &s, data, f, path, bad);
}

static void expect_append_refused(hl_tfile_writer *w, hl_context *ctx, const char *what, const hl_row_quant *rq,
                                  const uint16_t *counts, const uint8_t *entries, size_t stride,
                                  const uint32_t *nnz, uint32_t n)
{
    hl_result r = hl_tfile_writer_append(w, n, rq, counts, entries, stride, nnz);
    printf("%s: %s\n", what, hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, "%s: result %d", what, (int)r);
}

static void case_badappend(void)
{
    hl_context *ctx = make_ctx();
    char path[512], ref[512];
    tmp_path(path, sizeof path, "file_badappend.hlt");
    tmp_path(ref, sizeof ref, "file_badappend_ref.hlt");
    synth s;
    synth_make(&s, 8, HL_QUANT_LOG8, 4, 2);
    static const uint32_t all[] = {100};
    HL_CHECK(synth_write(ctx, ref, &s, all, 1) == HL_OK, "reference write: %s", hl_context_last_error(ctx));

    /* bad parameters at open */
    hl_tfile_writer *w = NULL;
    hl_transport_info bi = s.info;
    bi.N = 12;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &bi, &s.mesh, &w) == HL_ERR_INVALID_ARGUMENT && !w, "N = 12");
    bi = s.info;
    bi.block_count = 2;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &bi, &s.mesh, &w) == HL_ERR_INVALID_ARGUMENT && !w, "block_count");
    bi = s.info;
    bi.rule = HL_TRUNC_DEFAULT;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &bi, &s.mesh, &w) == HL_ERR_INVALID_ARGUMENT && !w, "rule 0");
    bi = s.info;
    bi.vertex_count = 5;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &bi, &s.mesh, &w) == HL_ERR_INVALID_ARGUMENT && !w, "mesh mismatch");
    s.mesh.indices[1] = 4;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &s.info, &s.mesh, &w) == HL_ERR_INVALID_ARGUMENT && !w, "bad index");
    printf("bad mesh index: %s\n", hl_context_last_error(ctx));
    s.mesh.indices[1] = 0;
    HL_CHECK(!file_exists(path), "refused open left a file");

    /* a reference file to compare with, from s with indices[1] = 0 */
    remove(ref);
    HL_CHECK(synth_write(ctx, ref, &s, all, 1) == HL_OK, "reference write: %s", hl_context_last_error(ctx));

    HL_CHECK(hl_tfile_writer_open(ctx, path, &s.info, &s.mesh, &w) == HL_OK, "open: %s", hl_context_last_error(ctx));
    hl_row_quant rq = {1e-3f, 1.0f};
    uint16_t cnt[1];
    uint8_t e[8];
    uint32_t nz;

    cnt[0] = 129;
    nz = 129;
    uint8_t big[2 * 129] = {0};
    for (int k = 0; k < 129; k++) big[2 * k] = (uint8_t)k;
    expect_append_refused(w, ctx, "129 entries in 128 slots", &rq, cnt, big, sizeof big, &nz, 1);
    cnt[0] = 3;
    nz = 2;
    e[0] = 1, e[2] = 2, e[4] = 3;
    expect_append_refused(w, ctx, "counts sum to 3, nnz 2", &rq, cnt, e, 8, &nz, 1);
    cnt[0] = 2;
    nz = 2;
    e[0] = 5, e[2] = 5;
    expect_append_refused(w, ctx, "duplicate index", &rq, cnt, e, 8, &nz, 1);
    e[0] = 7, e[2] = 3;
    expect_append_refused(w, ctx, "decreasing index", &rq, cnt, e, 8, &nz, 1);
    e[0] = 3, e[2] = 200;
    expect_append_refused(w, ctx, "index past the short block", &rq, cnt, e, 8, &nz, 1);
    e[0] = 3, e[2] = 4;
    hl_row_quant nanq = {NAN, 1.0f}, negq = {-1.0f, 1.0f};
    expect_append_refused(w, ctx, "NaN row parameter", &nanq, cnt, e, 8, &nz, 1);
    expect_append_refused(w, ctx, "negative log8 magnitude", &negq, cnt, e, 8, &nz, 1);
    /* two vertices whose rows overlap because the stride is too short */
    hl_row_quant rq2[2] = {rq, rq};
    uint16_t cnt2[2] = {2, 2};
    uint32_t nz2[2] = {2, 2};
    expect_append_refused(w, ctx, "stride shorter than a row", rq2, cnt2, e, 2, nz2, 2);
    /* second vertex of a batch is bad: the first must not be written */
    uint16_t cnt3[2] = {0, 200};
    uint32_t nz3[2] = {0, 200};
    expect_append_refused(w, ctx, "bad second vertex", rq2, cnt3, big, 0, nz3, 2);
    expect_append_refused(w, ctx, "too many vertices", s.rq, s.counts, s.entries, s.stride, s.nnz, 5);

    /* after all the refusals, the real rows give the reference bytes */
    HL_CHECK(hl_tfile_writer_append(w, 4, s.rq, s.counts, s.entries, s.stride, s.nnz) == HL_OK, "valid append: %s",
             hl_context_last_error(ctx));
    expect_append_refused(w, ctx, "append past the end", s.rq, s.counts, s.entries, s.stride, s.nnz, 1);
    hl_transport_info fin = s.info;
    fin.coefficients_kept = s.total + 1;
    hl_result r = hl_tfile_writer_finish(w, &fin);
    printf("wrong coefficients_kept: %s\n", hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && !file_exists(path), "wrong coefficients_kept at finish");

    HL_CHECK(hl_tfile_writer_open(ctx, path, &s.info, &s.mesh, &w) == HL_OK, "open");
    expect_append_refused(w, ctx, "bad second vertex again", rq2, cnt3, big, 0, nz3, 2);
    HL_CHECK(hl_tfile_writer_append(w, 4, s.rq, s.counts, s.entries, s.stride, s.nnz) == HL_OK, "valid append");
    fin.coefficients_kept = s.total;
    fin.rays_cast = 123456789012ull;
    fin.rays_culled = 98765432101ull;
    HL_CHECK(hl_tfile_writer_finish(w, &fin) == HL_OK, "finish: %s", hl_context_last_error(ctx));
    uint8_t *a = NULL, *b = NULL;
    size_t na = 0, nb = 0;
    HL_CHECK(read_file(path, &a, &na) == 0 && read_file(ref, &b, &nb) == 0 && na == nb && memcmp(a, b, na) == 0,
             "refused appends changed the output");
    free(a);
    free(b);
    remove(path);
    remove(ref);
    synth_free(&s);
    hl_context_destroy(ctx);
}

/* Header offsets of the basis words (host/FORMAT.md). */
enum { F_BASIS = 176, F_SH_ORDER = 180 };

/* Drops every entry of s at or past slot limit (the rows of a basis of
 * limit coefficients), keeping the counts and totals in step. */
static void keep_slots_below(synth *s, uint32_t limit)
{
    const uint32_t B = s->info.block_count;
    s->total = 0;
    for (uint32_t v = 0; v < s->info.vertex_count; v++) {
        uint8_t *e = s->entries + v * s->stride;
        uint32_t n = 0, k = 0;
        for (uint32_t b = 0; b < B; b++) {
            uint32_t c = 0;
            for (uint32_t j = 0; j < s->counts[(size_t)v * B + b]; j++, k++)
                if (b * HL_BLOCK + e[2 * k] < limit) {
                    e[2 * n] = e[2 * k];
                    e[2 * n + 1] = e[2 * k + 1];
                    n++;
                    c++;
                }
            s->counts[(size_t)v * B + b] = (uint16_t)c;
        }
        s->nnz[v] = n;
        s->total += n;
    }
}

/* The writer refuses s's rows under basis and order (the second word)
 * while an entry lies at or past limit, the basis's coefficients; kept
 * to slots below limit they are written to path and read back with that
 * basis and order, entry for entry. */
static void write_basis_rows(hl_context *ctx, const char *path, synth *s, uint32_t basis, uint32_t order,
                             uint32_t limit, const char *what)
{
    char needle[64];
    snprintf(needle, sizeof needle, "is not below the basis's %u coefficients", limit);
    s->info.basis = basis;
    s->info.sh_order = order;
    static const uint32_t one[] = {1};
    HL_CHECK(synth_write(ctx, path, s, one, 1) == HL_ERR_INVALID_ARGUMENT && strstr(hl_context_last_error(ctx), needle),
             "%s: the writer took an entry past %u: %s", what, limit, hl_context_last_error(ctx));
    printf("writer: %s\n", hl_context_last_error(ctx));
    keep_slots_below(s, limit);
    HL_CHECK(synth_write(ctx, path, s, one, 1) == HL_OK, "%s, slots below %u: %s", what, limit,
             hl_context_last_error(ctx));
    hl_transport *t = NULL;
    HL_CHECK(hl_transport_load(ctx, path, &t) == HL_OK && t->info.basis == basis && t->info.sh_order == order,
             "%s: %s", what, hl_context_last_error(ctx));
    if (t) synth_compare(t, s, what);
    printf("%s with %llu entries read back\n", what, (unsigned long long)s->total);
    hl_transport_destroy(t);
}

static void case_basis(void)
{
    hl_context *ctx = make_ctx();
    char path[512], bad[512];
    synth s;
    size_t size = 0;
    uint8_t *data = small_bytes(ctx, "file_basis", path, bad, sizeof path, &s, &size); /* N = 8: 128 slots */
    HL_CHECK(rd32(data + F_BASIS) == 0 && rd32(data + F_SH_ORDER) == 0, "a Haar file has zero basis words");
    hl_transport *t = NULL;
    HL_CHECK(hl_transport_load(ctx, path, &t) == HL_OK, "load: %s", hl_context_last_error(ctx));
    uint32_t top = 0; /* the highest slot any entry uses */
    for (uint32_t v = 0; t && v < t->info.vertex_count; v++) {
        uint64_t e = t->row_offset[v];
        for (uint32_t b = 0; b < t->info.block_count; b++)
            for (uint32_t j = 0; j < t->block_counts[(size_t)v * t->info.block_count + b]; j++, e++)
                if (b * HL_BLOCK + t->entries[2 * e] > top) top = b * HL_BLOCK + t->entries[2 * e];
    }
    HL_CHECK(t && t->info.basis == HL_TRANSPORT_BASIS_HAAR && t->info.sh_order == 0, "Haar file read as Haar");
    hl_transport_destroy(t);
    printf("highest slot used: %u\n", top);
    uint8_t *f = malloc(size);
    static const struct { uint32_t basis, order; const char *what, *needle; } forged[] = {
        {3, 0, "unknown basis", "basis = 3"},
        {0xFFFFFFFFu, 0, "unknown basis (all ones)", "basis = 4294967295"},
        {0, 5, "an order in a Haar file", "sh_order = 5 in a Haar file"},
        {1, 0, "order 0", "sh_order = 0"},
        {1, 33, "order 33", "sh_order = 33"},
        {1, 12, "order 12 (144 coefficients) with N = 8 (128 slots)", "sh_order = 12"},
    };
    for (size_t k = 0; k < sizeof forged / sizeof forged[0]; k++) {
        memcpy(f, data, size);
        wr32(f + F_BASIS, forged[k].basis);
        wr32(f + F_SH_ORDER, forged[k].order);
        fix_header_crc(f);
        expect_refused(ctx, bad, f, size, forged[k].what, forged[k].needle);
        expect_refused(ctx, bad, f, size, forged[k].what, "file_basis.hlt");
    }
    memcpy(f, data, size);
    f[170] = 1; /* still reserved in a whole file */
    fix_header_crc(f);
    expect_refused(ctx, bad, f, size, "reserved byte 170", "reserved header bytes");
    /* 184 holds the bounces baked in: at most HL_MAX_BOUNCES */
    memcpy(f, data, size);
    wr32(f + 184, HL_MAX_BOUNCES + 1);
    fix_header_crc(f);
    expect_refused(ctx, bad, f, size, "17 bounces", "bounces = 17");
    /* 186 the rows a vertex: 3 only with bounces; 2 never; and a file
       that says 3 must hold three planes of rows (this one holds one) */
    static const struct {
        uint32_t word;
        const char *what, *needle;
    } planes[] = {
        {3u << 16, "3 rows a vertex without bounces", "without bounces"},
        {2u << 16 | 1u, "2 rows a vertex", "channels = 2"},
        {3u << 16 | 1u, "3 rows a vertex but one plane of rows", "rows_size"},
    };
    for (size_t k = 0; k < sizeof planes / sizeof planes[0]; k++) {
        memcpy(f, data, size);
        wr32(f + 184, planes[k].word);
        fix_header_crc(f);
        expect_refused(ctx, bad, f, size, planes[k].what, planes[k].needle);
    }
    /* orders 1 to 11 over this file, whose entries reach slot 127:
       refused, naming the first slot at or past L^2 */
    int refused = 0;
    for (uint32_t L = 1; L <= 11; L++) {
        memcpy(f, data, size);
        wr32(f + F_BASIS, 1);
        wr32(f + F_SH_ORDER, L);
        fix_header_crc(f);
        if (L * L <= top) {
            expect_refused(ctx, bad, f, size, "an entry past L^2", "is not below the basis's");
            refused++;
        }
    }
    HL_CHECK(refused == 11, "%d of 11 orders refused with slot %u used", refused, top);
    /* the writer refuses the same rows under order 3; kept to slots 0..8
       they are written, and read back as order 3, entry for entry */
    write_basis_rows(ctx, bad, &s, HL_TRANSPORT_BASIS_SH, 3, 9, "spherical-harmonic file, order 3");
    small_done(ctx, &s, data, f, path, bad);
}

/* Cube-face Haar (basis 2, the cube side in the second word) on the
 * small file (N = 8: 128 slots, C = 32): sides that are no power of two
 * from 2, or whose 6 C'^2 coefficients pass the slots, refused; sides 2
 * and 4 refused for entries at or past 6 C'^2; the writer refuses them
 * too, and rows kept to slots 0..23 are written and read back as side 2. */
static void case_cube_basis(void)
{
    hl_context *ctx = make_ctx();
    char path[512], bad[512];
    synth s;
    size_t size = 0;
    uint8_t *data = small_bytes(ctx, "file_cube", path, bad, sizeof path, &s, &size);
    uint8_t *f = malloc(size);
    static const struct { uint32_t side; const char *what, *needle; } forged[] = {
        {0, "cube side 0", "sh_order = 0 (the cube side) is not a power of two"},
        {1, "cube side 1", "sh_order = 1 (the cube side) is not a power of two"},
        {3, "cube side 3", "sh_order = 3 (the cube side) is not a power of two"},
        {1024, "cube side 1024", "sh_order = 1024 (the cube side) is not a power of two"},
        {8, "cube side 8 (384 coefficients) with N = 8 (128 slots)", "its 384 coefficients exceed the 128 slots"},
        {2, "an entry past 6 C'^2 = 24", "is not below the basis's 24 coefficients"},
        {4, "an entry past 6 C'^2 = 96", "is not below the basis's 96 coefficients"},
    };
    for (size_t k = 0; k < sizeof forged / sizeof forged[0]; k++) {
        memcpy(f, data, size);
        wr32(f + F_BASIS, HL_TRANSPORT_BASIS_CUBE);
        wr32(f + F_SH_ORDER, forged[k].side);
        fix_header_crc(f);
        expect_refused(ctx, bad, f, size, forged[k].what, forged[k].needle);
        expect_refused(ctx, bad, f, size, forged[k].what, "file_cube.hlt");
    }
    write_basis_rows(ctx, bad, &s, HL_TRANSPORT_BASIS_CUBE, 2, 24, "cube-face Haar file, side 2");
    small_done(ctx, &s, data, f, path, bad);
}

/* The first two indices of the row whose entries start at entry off
 * swapped (now decreasing); the entries' checksum made to match. */
static void unorder_row(uint8_t *f, uint64_t entries_off, uint64_t off)
{
    uint8_t *e = f + entries_off + 2 * off, tmp = e[0];
    e[0] = e[2];
    e[2] = tmp;
    fix_section_crc(f, F_ENTRIES_OFFSET, F_ENTRIES_CRC);
}

/* The loader's pieces and row chunks made small (HL_TEST_LOAD_PIECE = 64
 * bytes, HL_TEST_ROW_CHUNK = 3 vertices) on 4 threads: a good file loads
 * entry for entry (the pieces' checksums joined); a byte changed in the
 * last piece fails the joined checksum; of two bad rows in different
 * chunks the lower vertex is named, and a bad block count is named before
 * bad entries above it but after bad entries below it, as one pass in
 * vertex order would. */
static void case_pieces(void)
{
    setenv("HL_TEST_LOAD_PIECE", "64", 1);
    setenv("HL_TEST_ROW_CHUNK", "3", 1);
    hl_context *ctx = hl_test_ref_context(4);
    char path[512], bad[512], needle[32];
    tmp_path(path, sizeof path, "file_pieces_src.hlt");
    tmp_path(bad, sizeof bad, "file_pieces.hlt");
    synth s;
    synth_make(&s, 8, HL_QUANT_SQRT8, 40, 60);
    static const uint32_t all[] = {1000};
    hl_result r = synth_write(ctx, path, &s, all, 1);
    HL_CHECK(r == HL_OK, "write: %s", hl_context_last_error(ctx));
    uint8_t *data = NULL;
    size_t size = 0;
    HL_CHECK(read_file(path, &data, &size) == 0, "read");
    const uint64_t rows_off = rd64(data + F_ROWS_OFFSET), entries_off = rd64(data + F_ENTRIES_OFFSET);
    printf("%llu entry bytes: %llu pieces of 64, %u vertices in chunks of 3\n", (unsigned long long)(2 * s.total),
           (unsigned long long)((2 * s.total + 63) / 64), s.info.vertex_count);
    HL_CHECK(2 * s.total > 4 * 64, "the file should span at least 5 pieces");
    hl_transport *t = NULL;
    r = hl_transport_load(ctx, path, &t);
    HL_CHECK(r == HL_OK, "load in pieces: %s", hl_context_last_error(ctx));
    if (t) synth_compare(t, &s, "pieces");
    hl_transport_destroy(t);

    uint8_t *f = malloc(size);
    memcpy(f, data, size);
    f[entries_off + 2 * s.total - 1] ^= 0x55;
    expect_refused(ctx, bad, f, size, "a byte of the last piece", "checksum mismatch in the entries section");

    /* two rows with two entries or more, in different chunks, and a row
       before the first */
    uint32_t a = s.info.vertex_count, b = a;
    uint64_t off = 0, offa = 0, offb = 0;
    for (uint32_t v = 0; v < s.info.vertex_count; off += s.nnz[v], v++) {
        if (s.nnz[v] < 2 || v < 4) continue;
        if (a == s.info.vertex_count) a = v, offa = off;
        else if (b == s.info.vertex_count && v / 3 > a / 3) b = v, offb = off;
    }
    HL_CHECK(b < s.info.vertex_count, "the file needs two rows of two entries in different chunks past vertex 3");
    if (b < s.info.vertex_count) {
        memcpy(f, data, size);
        unorder_row(f, entries_off, offa);
        unorder_row(f, entries_off, offb);
        snprintf(needle, sizeof needle, "vertex %u:", a);
        expect_refused(ctx, bad, f, size, "bad entries in two chunks", needle);
        memcpy(f, data, size);
        unorder_row(f, entries_off, offb);
        overfill_count(f, rows_off, 1);
        expect_refused(ctx, bad, f, size, "a bad count below bad entries", "vertex 1:");
        memcpy(f, data, size);
        unorder_row(f, entries_off, offa);
        overfill_count(f, rows_off, b);
        snprintf(needle, sizeof needle, "vertex %u:", a);
        expect_refused(ctx, bad, f, size, "bad entries below a bad count", needle);
    }
    free(f);
    free(data);
    remove(bad);
    remove(path);
    synth_free(&s);
    hl_context_destroy(ctx);
    unsetenv("HL_TEST_LOAD_PIECE");
    unsetenv("HL_TEST_ROW_CHUNK");
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"corrupt", case_corrupt},
        {"badappend", case_badappend},
        {"basis", case_basis},
        {"cube_basis", case_cube_basis},
        {"pieces", case_pieces},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
