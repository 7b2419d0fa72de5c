/* test_file.c - transport file writer and reader (suite "file").
 *
 * Cases: roundtrip (bit-exact write/load for N = 8 and 64, both quant
 * schemes, several append patterns, query_row against a hand dequant),
 * atomic (no file or temporary after abort or failure, existing files
 * untouched, unwritable paths named), truncated (every prefix refused),
 * corrupt (every single-byte flip refused unless it lands in padding;
 * forged headers and contents with valid checksums refused), badappend
 * (invalid rows and parameters refused without changing the writer).
 *
 * The header offsets below are those of host/FORMAT.md, so this test also
 * pins the documented layout. It carries its own bitwise CRC-32 to forge
 * valid checksums and to cross-check the library's table-driven one.
 * Depends on: haarlight_core (reference backend only), POSIX dirent.
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#include "hl_test.h"
#include "transport_file.h"

/* FORMAT.md, "Header". */
enum {
    F_VERSION = 8,
    F_N = 16,
    F_VERTEX_COUNT = 48,
    F_TRIANGLE_COUNT = 56,
    F_COEF = 64,
    F_FILE_SIZE = 88,
    F_MESH_OFFSET = 96,
    F_MESH_SIZE = 104,
    F_ROWS_OFFSET = 112,
    F_ROWS_SIZE = 120,
    F_ENTRIES_OFFSET = 128,
    F_ENTRIES_SIZE = 136,
    F_MESH_CRC = 144,
    F_ROWS_CRC = 148,
    F_ENTRIES_CRC = 152,
    F_HEADER_CRC = 188,
    F_HEADER_SIZE = 192
};

/* ---------------------------------------------------------------- helpers */

static uint64_t rng_next(void) { return hl_rng_next(); }
static uint32_t rng_below(uint32_t n) { return n ? (uint32_t)(rng_next() % n) : 0; }
static float rng_float(float lo, float hi) { return lo + (hi - lo) * (float)(rng_next() >> 40) / 16777216.0f; }


static uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint64_t rd64(const uint8_t *p) { return (uint64_t)rd32(p) | (uint64_t)rd32(p + 4) << 32; }
static void wr32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static void wr64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static void fix_header_crc(uint8_t *f) { wr32(f + F_HEADER_CRC, hl_test_crc32(f, F_HEADER_CRC)); }
/* Recomputes a section's checksum after an edit (crc_field: F_*_CRC). */
static void fix_section_crc(uint8_t *f, int offset_field, int crc_field)
{
    uint64_t off = rd64(f + offset_field), size = rd64(f + offset_field + 8);
    wr32(f + crc_field, hl_test_crc32(f + off, (size_t)size));
    fix_header_crc(f);
}

static hl_context *make_ctx(void) { return hl_test_ref_context(0); }

static void tmp_path(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", hl_test_env("HL_TMP", "."), name);
}

static int read_file(const char *path, uint8_t **data, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return -1;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    *data = malloc(n > 0 ? (size_t)n : 1);
    *size = fread(*data, 1, (size_t)n, f);
    fclose(f);
    return *size == (size_t)n ? 0 : -1;
}

static int write_file(const char *path, const uint8_t *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    size_t k = fwrite(data, 1, size, f);
    return fclose(f) == 0 && k == size ? 0 : -1;
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* Number of entries in dir whose name starts with prefix. */
static int count_prefixed(const char *dir, const char *prefix)
{
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (strncmp(e->d_name, prefix, strlen(prefix)) == 0) n++;
    closedir(d);
    return n;
}

/* ---------------------------------------------------------------- synthetic data */

typedef struct synth {
    hl_transport_info info;
    hl_mesh mesh;
    hl_row_quant *rq;
    uint16_t *counts;
    uint8_t *entries; /* vertex v at v * stride */
    size_t stride;
    uint32_t *nnz;
    uint64_t total;
} synth;

static uint32_t slots_of(uint32_t N, uint32_t b)
{
    uint32_t rest = 2 * N * N - b * HL_BLOCK;
    return rest < HL_BLOCK ? rest : HL_BLOCK;
}

static void synth_make(synth *s, uint32_t N, uint32_t quant, uint32_t V, uint32_t T)
{
    memset(s, 0, sizeof *s);
    hl_transport_info *i = &s->info;
    i->N = N;
    i->C = 32;
    i->supersample = 2;
    i->rule = HL_TRUNC_ENERGY;
    i->K = 77;
    i->eps = 1e-3f;
    i->quant = quant;
    i->ray_offset = 1e-4f;
    i->vertex_count = V;
    i->object_vertex_count = V - V / 4;
    i->triangle_count = T;
    i->block_count = (2 * N * N + HL_BLOCK - 1) / HL_BLOCK;

    hl_mesh *m = &s->mesh;
    m->vertex_count = V;
    m->triangle_count = T;
    m->object_vertex_count = i->object_vertex_count;
    m->positions = malloc(3 * V * sizeof(float));
    m->normals = malloc(3 * V * sizeof(float));
    m->albedo = malloc(3 * V * sizeof(float));
    m->indices = malloc((3 * T + 1) * sizeof(uint32_t));
    for (uint32_t k = 0; k < 3 * V; k++) {
        m->positions[k] = rng_float(-10, 10);
        m->normals[k] = rng_float(-1, 1);
        m->albedo[k] = rng_float(0, 1);
    }
    for (uint32_t v = 0; v < V; v++) { /* unit normals, as the mesh layer makes them */
        float *q = m->normals + 3 * (size_t)v;
        float len = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (len < 1e-3f) q[0] = 1.0f, q[1] = q[2] = 0.0f, len = 1.0f;
        for (int k = 0; k < 3; k++) q[k] /= len;
    }
    for (uint32_t k = 0; k < 3 * T; k++) m->indices[k] = rng_below(V);

    uint32_t B = i->block_count;
    s->stride = 2 * (size_t)2 * N * N + 6; /* odd padding: the writer must honour the stride */
    s->rq = malloc(V * sizeof *s->rq);
    s->counts = calloc((size_t)V * B, sizeof *s->counts);
    s->entries = calloc((size_t)V, s->stride);
    s->nnz = calloc(V, sizeof *s->nnz);
    for (uint32_t v = 0; v < V; v++) {
        if (quant != HL_QUANT_LINEAR8) {
            s->rq[v].a = rng_float(1e-6f, 1e-3f);
            s->rq[v].b = rng_float(1e-2f, 2.0f);
        } else {
            s->rq[v].a = rng_float(-1.0f, 0.0f);
            s->rq[v].b = rng_float(0.0f, 1.0f);
        }
        uint32_t mode = v % 5; /* 0 empty, 1 full blocks, else sparse */
        uint8_t *e = s->entries + v * s->stride;
        uint32_t n = 0;
        for (uint32_t b = 0; b < B; b++) {
            uint32_t slots = slots_of(N, b);
            uint32_t c = mode == 0 ? 0 : mode == 1 ? (b % 2 == 0 ? slots : 0) : rng_below(slots / (mode + 1) + 1);
            /* selection sampling: c distinct indices in increasing order */
            uint32_t chosen = 0;
            for (uint32_t idx = 0; idx < slots && chosen < c; idx++) {
                if (rng_below(slots - idx) < c - chosen) {
                    e[2 * n] = (uint8_t)idx;
                    e[2 * n + 1] = (uint8_t)rng_below(256);
                    n++;
                    chosen++;
                }
            }
            s->counts[(size_t)v * B + b] = (uint16_t)c;
        }
        s->nnz[v] = n;
        s->total += n;
    }
}

static void synth_free(synth *s)
{
    free(s->mesh.positions);
    free(s->mesh.normals);
    free(s->mesh.albedo);
    free(s->mesh.indices);
    free(s->rq);
    free(s->counts);
    free(s->entries);
    free(s->nnz);
}

/* Writes s in appends of the given sizes (cycled; 0 is a legal empty append). */
static hl_result synth_write(hl_context *ctx, const char *path, const synth *s, const uint32_t *sizes,
                             int nsizes)
{
    hl_tfile_writer *w = NULL;
    hl_result r = hl_tfile_writer_open(ctx, path, &s->info, &s->mesh, &w);
    if (r != HL_OK) return r;
    uint32_t B = s->info.block_count, v = 0;
    for (int k = 0; v < s->info.vertex_count; k = (k + 1) % nsizes) {
        uint32_t n = sizes[k];
        if (n > s->info.vertex_count - v) n = s->info.vertex_count - v;
        r = hl_tfile_writer_append(w, n, s->rq + v, s->counts + (size_t)v * B, s->entries + v * s->stride,
                                   s->stride, s->nnz + v);
        if (r != HL_OK) {
            hl_tfile_writer_abort(w);
            return r;
        }
        v += n;
    }
    hl_transport_info fin = s->info;
    fin.coefficients_kept = s->total;
    fin.rays_cast = 123456789012ull;
    fin.rays_culled = 98765432101ull;
    return hl_tfile_writer_finish(w, &fin);
}

/* Compares a loaded transport with the data it was written from, bit for bit. */
static void synth_compare(const hl_transport *t, const synth *s, const char *what)
{
    const hl_transport_info *a = &t->info, *e = &s->info;
    uint32_t V = e->vertex_count, B = e->block_count;
    HL_CHECK(a->version == HL_TRANSPORT_VERSION, "%s: version %u", what, a->version);
    HL_CHECK(a->N == e->N && a->C == e->C && a->supersample == e->supersample && a->rule == e->rule &&
                 a->K == e->K && a->quant == e->quant && memcmp(&a->eps, &e->eps, 4) == 0 &&
                 memcmp(&a->ray_offset, &e->ray_offset, 4) == 0,
             "%s: parameters differ", what);
    HL_CHECK(a->vertex_count == V && a->object_vertex_count == e->object_vertex_count &&
                 a->triangle_count == e->triangle_count && a->block_count == B,
             "%s: counts differ", what);
    HL_CHECK(a->coefficients_kept == s->total, "%s: coefficients_kept %llu, wrote %llu", what,
             (unsigned long long)a->coefficients_kept, (unsigned long long)s->total);
    HL_CHECK(a->rays_cast == 123456789012ull && a->rays_culled == 98765432101ull, "%s: ray counters", what);
    const hl_mesh *m = t->mesh;
    HL_CHECK(m && m->vertex_count == V && m->triangle_count == e->triangle_count &&
                 m->object_vertex_count == e->object_vertex_count,
             "%s: mesh counts", what);
    if (!m) return;
    HL_CHECK(memcmp(m->positions, s->mesh.positions, 12 * (size_t)V) == 0, "%s: positions", what);
    HL_CHECK(memcmp(m->normals, s->mesh.normals, 12 * (size_t)V) == 0, "%s: normals", what);
    HL_CHECK(memcmp(m->albedo, s->mesh.albedo, 12 * (size_t)V) == 0, "%s: albedo", what);
    HL_CHECK(memcmp(m->indices, s->mesh.indices, 12 * (size_t)e->triangle_count) == 0, "%s: indices", what);
    HL_CHECK(memcmp(t->row_quant, s->rq, 8 * (size_t)V) == 0, "%s: row_quant", what);
    HL_CHECK(memcmp(t->block_counts, s->counts, 2 * (size_t)V * B) == 0, "%s: block counts", what);

    uint32_t slots = 2 * e->N * e->N;
    float *dense = malloc(slots * sizeof(float)), *want = malloc(slots * sizeof(float));
    uint64_t off = 0;
    int bad_rows = 0, bad_offsets = 0, bad_entries = 0;
    for (uint32_t v = 0; v < V; v++) {
        if (t->row_offset[v] != off) bad_offsets++;
        const uint8_t *src = s->entries + v * s->stride;
        if (memcmp(t->entries + 2 * off, src, 2 * (size_t)s->nnz[v]) != 0) bad_entries++;
        /* hand dequantisation, straight from the scheme's formula */
        memset(want, 0, slots * sizeof(float));
        uint32_t k = 0;
        for (uint32_t b = 0; b < B; b++)
            for (uint32_t j = 0; j < s->counts[(size_t)v * B + b]; j++, k++) {
                uint32_t slot = b * HL_BLOCK + src[2 * k], code = src[2 * k + 1];
                want[slot] = hl_dequant(e->quant, code, s->rq[v].a, s->rq[v].b, hl_dither_key(v, slot));
            }
        for (uint32_t q = 0; q < slots; q++) dense[q] = 12345.0f; /* query_row must clear */
        hl_transport_query_row(t, v, dense);
        if (memcmp(dense, want, slots * sizeof(float)) != 0) bad_rows++;
        off += s->nnz[v];
    }
    HL_CHECK(t->row_offset[V] == off, "%s: final row offset", what);
    HL_CHECK(bad_offsets == 0, "%s: %d row offsets differ", what, bad_offsets);
    HL_CHECK(bad_entries == 0, "%s: %d vertices' entries differ", what, bad_entries);
    HL_CHECK(bad_rows == 0, "%s: %d query_row results differ from hand dequantisation", what, bad_rows);
    free(dense);
    free(want);
}

/* ---------------------------------------------------------------- cases */

static void case_roundtrip(void)
{
    hl_context *ctx = make_ctx();
    static const uint32_t Ns[] = {8, 64};
    static const uint32_t quants[] = {HL_QUANT_LINEAR8, HL_QUANT_LOG8, HL_QUANT_SQRT8};
    static const uint32_t pattern_a[] = {1, 0, 3, 7, 2, 16};
    static const uint32_t pattern_b[] = {1000};
    for (int ni = 0; ni < 2; ni++)
        for (int qi = 0; qi < 3; qi++) {
            synth s;
            synth_make(&s, Ns[ni], quants[qi], 37, 50);
            char what[64], pa[512], pb[512];
            snprintf(what, sizeof what, "N=%u quant=%u", Ns[ni], quants[qi]);
            tmp_path(pa, sizeof pa, "file_roundtrip_a.hlt");
            tmp_path(pb, sizeof pb, "file_roundtrip_b.hlt");
            hl_result r = synth_write(ctx, pa, &s, pattern_a, 6);
            HL_CHECK(r == HL_OK, "%s: write: %s", what, hl_context_last_error(ctx));
            r = synth_write(ctx, pb, &s, pattern_b, 1);
            HL_CHECK(r == HL_OK, "%s: write in one append: %s", what, hl_context_last_error(ctx));

            hl_transport *t = NULL;
            r = hl_transport_load(ctx, pa, &t);
            HL_CHECK(r == HL_OK, "%s: load: %s", what, hl_context_last_error(ctx));
            if (t) {
                synth_compare(t, &s, what);
                if (ni == 1 && qi == 0) hl_transport_describe(t, pa, stdout);
            }
            hl_transport_destroy(t);

            /* Append pattern must not change a byte; the header CRC must be
             * the IEEE CRC-32 this test computes bit by bit. */
            uint8_t *fa = NULL, *fb = NULL;
            size_t na = 0, nb = 0;
            HL_CHECK(read_file(pa, &fa, &na) == 0 && read_file(pb, &fb, &nb) == 0, "%s: reread", what);
            HL_CHECK(na == nb && fa && fb && memcmp(fa, fb, na) == 0, "%s: append pattern changed the bytes", what);
            if (fa && na >= F_HEADER_SIZE) {
                HL_CHECK(memcmp(fa, "HLTRANS1", 8) == 0, "%s: magic", what);
                HL_CHECK(rd32(fa + F_HEADER_CRC) == hl_test_crc32(fa, F_HEADER_CRC), "%s: header CRC", what);
                HL_CHECK(rd64(fa + F_FILE_SIZE) == na, "%s: file_size field", what);
                HL_CHECK(rd64(fa + F_ENTRIES_SIZE) == 2 * s.total, "%s: entries_size field", what);
                uint64_t eo = rd64(fa + F_ENTRIES_OFFSET);
                HL_CHECK(rd32(fa + F_ENTRIES_CRC) == hl_test_crc32(fa + eo, (size_t)(2 * s.total)),
                         "%s: entries CRC", what);
            }
            printf("%s: %zu bytes, %llu coefficients\n", what, na, (unsigned long long)s.total);
            free(fa);
            free(fb);
            remove(pa);
            remove(pb);
            synth_free(&s);
        }
    hl_context_destroy(ctx);
}

static void case_atomic(void)
{
    hl_context *ctx = make_ctx();
    char dir[512], path[600], bad[600];
    tmp_path(dir, sizeof dir, "file_atomic");
    mkdir(dir, 0777);
    snprintf(path, sizeof path, "%s/out.hlt", dir);
    remove(path);
    synth s;
    synth_make(&s, 16, HL_QUANT_LINEAR8, 9, 4);
    /* abort with no previous file: nothing at all remains */
    hl_tfile_writer *w = NULL;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &s.info, &s.mesh, &w) == HL_OK, "open: %s", hl_context_last_error(ctx));
    HL_CHECK(hl_tfile_writer_append(w, 4, s.rq, s.counts, s.entries, s.stride, s.nnz) == HL_OK, "append");
    HL_CHECK(count_prefixed(dir, "out.hlt") == 1, "temporary file should exist while writing");
    hl_tfile_writer_abort(w);
    HL_CHECK(!file_exists(path), "aborted write left %s", path);
    HL_CHECK(count_prefixed(dir, "out.hlt") == 0, "aborted write left a temporary file");
    hl_tfile_writer_abort(NULL);

    /* an existing file survives an aborted and a failed rewrite */
    static const uint32_t all[] = {100};
    HL_CHECK(synth_write(ctx, path, &s, all, 1) == HL_OK, "write: %s", hl_context_last_error(ctx));
    uint8_t *before = NULL, *after = NULL;
    size_t nbefore = 0, nafter = 0;
    HL_CHECK(read_file(path, &before, &nbefore) == 0, "read");
    synth s2;
    synth_make(&s2, 16, HL_QUANT_LOG8, 9, 4);
    HL_CHECK(hl_tfile_writer_open(ctx, path, &s2.info, &s2.mesh, &w) == HL_OK, "reopen");
    HL_CHECK(hl_tfile_writer_append(w, 9, s2.rq, s2.counts, s2.entries, s2.stride, s2.nnz) == HL_OK, "append");
    hl_tfile_writer_abort(w);
    HL_CHECK(read_file(path, &after, &nafter) == 0 && nafter == nbefore && memcmp(before, after, nbefore) == 0,
             "aborted write changed the existing file");
    free(after);
    after = NULL;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &s2.info, &s2.mesh, &w) == HL_OK, "reopen");
    HL_CHECK(hl_tfile_writer_append(w, 5, s2.rq, s2.counts, s2.entries, s2.stride, s2.nnz) == HL_OK, "append");
    hl_result r = hl_tfile_writer_finish(w, NULL); /* 4 vertices missing */
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, "early finish gave %d", (int)r);
    printf("early finish: %s\n", hl_context_last_error(ctx));
    HL_CHECK(read_file(path, &after, &nafter) == 0 && nafter == nbefore && memcmp(before, after, nbefore) == 0,
             "failed finish changed the existing file");
    HL_CHECK(count_prefixed(dir, "out.hlt") == 1, "failed finish left a temporary file");
    free(after);
    after = NULL;

    /* a finished rewrite replaces the file */
    HL_CHECK(synth_write(ctx, path, &s2, all, 1) == HL_OK, "rewrite: %s", hl_context_last_error(ctx));
    HL_CHECK(read_file(path, &after, &nafter) == 0 && (nafter != nbefore || memcmp(before, after, nbefore) != 0),
             "finished rewrite did not replace the file");
    HL_CHECK(count_prefixed(dir, "out.hlt") == 1, "finished rewrite left a temporary file");
    free(before);
    free(after);

    /* unwritable destination: a missing directory */
    snprintf(bad, sizeof bad, "%s/no_such_dir/out.hlt", dir);
    w = (hl_tfile_writer *)1;
    r = hl_tfile_writer_open(ctx, bad, &s.info, &s.mesh, &w);
    const char *msg = hl_context_last_error(ctx);
    printf("missing directory: %s\n", msg);
    HL_CHECK(r == HL_ERR_IO, "missing directory gave %d", (int)r);
    HL_CHECK(w == NULL, "failed open must clear *out");
    HL_CHECK(strstr(msg, bad) != NULL, "message should name %s", bad);
    HL_CHECK(strstr(msg, strerror(ENOENT)) != NULL, "message should carry strerror");

    /* loading a missing file is an I/O error naming it */
    hl_transport *t = (hl_transport *)1;
    r = hl_transport_load(ctx, bad, &t);
    HL_CHECK(r == HL_ERR_IO && t == NULL && strstr(hl_context_last_error(ctx), bad), "load of missing file: %d %s",
             (int)r, hl_context_last_error(ctx));
    remove(path);
    rmdir(dir);
    synth_free(&s);
    synth_free(&s2);
    hl_context_destroy(ctx);
}

/* A small file with every feature: short last block (N = 8), empty rows,
 * ground vertices, padding between sections. */
static void small_file(hl_context *ctx, const char *path, synth *s)
{
    static const uint32_t pattern[] = {2, 3};
    synth_make(s, 8, HL_QUANT_LOG8, 6, 4);
    hl_result r = synth_write(ctx, path, s, pattern, 2);
    HL_CHECK(r == HL_OK, "small file: %s", hl_context_last_error(ctx));
}

static void case_truncated(void)
{
    hl_context *ctx = make_ctx();
    char path[512], cut[512];
    tmp_path(path, sizeof path, "file_trunc_src.hlt");
    tmp_path(cut, sizeof cut, "file_trunc.hlt");
    synth s;
    small_file(ctx, path, &s);
    uint8_t *data = NULL;
    size_t size = 0;
    HL_CHECK(read_file(path, &data, &size) == 0, "read");
    int refused = 0, named = 0;
    for (size_t len = 0; len < size; len++) {
        write_file(cut, data, len);
        hl_transport *t = NULL;
        hl_result r = hl_transport_load(ctx, cut, &t);
        if (r == HL_ERR_FORMAT && t == NULL) refused++;
        else HL_CHECK(0, "length %zu of %zu: result %d", len, size, (int)r);
        if (strstr(hl_context_last_error(ctx), "truncated")) named++;
        if (len == 0 || len == 100 || len == size - 1) printf("length %zu: %s\n", len, hl_context_last_error(ctx));
        hl_transport_destroy(t);
    }
    printf("%d of %zu truncations refused, %d say \"truncated\"\n", refused, size, named);
    HL_CHECK((size_t)named == size, "every truncation should be reported as truncated");
    /* trailing bytes are refused too */
    uint8_t *longer = calloc(size + 3, 1);
    memcpy(longer, data, size);
    write_file(cut, longer, size + 3);
    hl_transport *t = NULL;
    HL_CHECK(hl_transport_load(ctx, cut, &t) == HL_ERR_FORMAT, "trailing data accepted");
    hl_transport_destroy(t);
    free(longer);
    free(data);
    remove(cut);
    remove(path);
    synth_free(&s);
    hl_context_destroy(ctx);
}

/* Loads bytes via a file; returns the result and the error message. */
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

static void case_corrupt(void)
{
    hl_context *ctx = make_ctx();
    char path[512], bad[512];
    tmp_path(path, sizeof path, "file_corrupt_src.hlt");
    tmp_path(bad, sizeof bad, "file_corrupt.hlt");
    synth s;
    small_file(ctx, path, &s);
    uint8_t *data = NULL;
    size_t size = 0;
    HL_CHECK(read_file(path, &data, &size) == 0, "read");
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
    f[rows_off + 10 * 2 + 8] = 129; /* vertex 2: 129 entries in a 128-slot block */
    f[rows_off + 10 * 2 + 9] = 0;
    fix_section_crc(f, F_ROWS_OFFSET, F_ROWS_CRC);
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
    free(f);
    free(data);
    remove(bad);
    remove(path);
    synth_free(&s);
    hl_context_destroy(ctx);
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

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"roundtrip", case_roundtrip}, {"atomic", case_atomic},       {"truncated", case_truncated},
        {"corrupt", case_corrupt},     {"badappend", case_badappend}, {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
