/* transport_synth.h - synthetic transport files for the writer and reader
 * tests (tests/io): the header offsets of host/FORMAT.md, little-endian
 * reads and writes, checksum forging, scratch files, synthetic rows made,
 * written and compared, and a small file with every feature.
 * Depends on: hl_test.h, transport_file.h, POSIX dirent/stat, HL_TMP.
 */
#ifndef HL_TEST_TRANSPORT_SYNTH_H
#define HL_TEST_TRANSPORT_SYNTH_H


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

static inline uint64_t rng_next(void) { return hl_rng_next(); }
static inline uint32_t rng_below(uint32_t n) { return n ? (uint32_t)(rng_next() % n) : 0; }
static inline float rng_float(float lo, float hi) { return lo + (hi - lo) * (float)(rng_next() >> 40) / 16777216.0f; }


static inline uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t rd64(const uint8_t *p) { return (uint64_t)rd32(p) | (uint64_t)rd32(p + 4) << 32; }
static inline void wr32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void wr64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}
static inline void fix_header_crc(uint8_t *f) { wr32(f + F_HEADER_CRC, hl_test_crc32(f, F_HEADER_CRC)); }
/* Recomputes a section's checksum after an edit (crc_field: F_*_CRC). */
static inline void fix_section_crc(uint8_t *f, int offset_field, int crc_field)
{
    uint64_t off = rd64(f + offset_field), size = rd64(f + offset_field + 8);
    wr32(f + crc_field, hl_test_crc32(f + off, (size_t)size));
    fix_header_crc(f);
}

static inline hl_context *make_ctx(void) { return hl_test_ref_context(0); }

static inline void tmp_path(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", hl_test_env("HL_TMP", "."), name);
}

static inline int read_file(const char *path, uint8_t **data, size_t *size)
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

static inline int write_file(const char *path, const uint8_t *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    size_t k = fwrite(data, 1, size, f);
    return fclose(f) == 0 && k == size ? 0 : -1;
}

static inline int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* Number of entries in dir whose name starts with prefix. */
static inline int count_prefixed(const char *dir, const char *prefix)
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

static inline uint32_t slots_of(uint32_t N, uint32_t b)
{
    uint32_t rest = 2 * N * N - b * HL_BLOCK;
    return rest < HL_BLOCK ? rest : HL_BLOCK;
}

static inline void synth_make(synth *s, uint32_t N, uint32_t quant, uint32_t V, uint32_t T)
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

static inline void synth_free(synth *s)
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
static inline hl_result synth_write(hl_context *ctx, const char *path, const synth *s, const uint32_t *sizes,
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
static inline void synth_compare(const hl_transport *t, const synth *s, const char *what)
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


/* A small file with every feature: short last block (N = 8), empty rows,
 * ground vertices, padding between sections. */
static inline void small_file(hl_context *ctx, const char *path, synth *s)
{
    static const uint32_t pattern[] = {2, 3};
    synth_make(s, 8, HL_QUANT_LOG8, 6, 4);
    hl_result r = synth_write(ctx, path, s, pattern, 2);
    HL_CHECK(r == HL_OK, "small file: %s", hl_context_last_error(ctx));
}

#endif
