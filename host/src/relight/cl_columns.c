/* cl_columns.c - the relight's transport layout on the device: the order
 * of the vertices (a Z-order curve), their cut into ranges of tiles (one
 * work-item each), and the rows turned into columns of tiles of half
 * precision terms (see kernels/relight/relight.cl), uploaded once per
 * relighter.
 *
 * Depends on: cl_light.h (the device state, OpenCL), half.h (the terms as
 * the dot products hold them), the transport (hl_dequant, hl_dither_key;
 * transport_layout.h's hl_tf_pread_all where the rows are read from the
 * file again).
 */
#include <errno.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "cl_light.h"
#include "half.h"
#include "transport_layout.h"

typedef struct { uint64_t key; uint32_t v; } order_key;

static int order_cmp(const void *a, const void *b)
{
    const order_key *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->v < y->v ? -1 : x->v > y->v;
}

/* 7-bit grid coordinate of x in [lo, hi] (0 for NaN or an empty span) */
static uint32_t grid7(float x, float lo, float hi)
{
    double f = hi > lo ? ((double)x - lo) / ((double)hi - lo) * 128.0 : 0.0;
    if (!(f > 0.0)) return 0;
    return f >= 127.0 ? 127u : (uint32_t)f;
}

/* The order in which the device holds the vertices (l->order: the vertex
 * at each position): object before ground, then along a Z-order curve
 * through position and normal, 7 bits of each of the six coordinates
 * interleaved. Neighbours on that curve see alike and so store alike
 * slots, so a tile's vertices share their columns' entries: on the bunny
 * with ground at M = 200 the kept columns hold a fifth fewer entries than
 * in the file's order (376k against 476k), and 76% of them fill every
 * lane (34% in file order). On a CPU device cut_ranges then deals the
 * curve's tiles to the ranges. The sums are the same in any order. */
static hl_result vertex_order(hl_cl_light *l, const hl_transport *t, uint32_t **curve)
{
    const size_t V = l->nverts;
    const hl_mesh *m = t->mesh;
    uint32_t *c = *curve = malloc((V ? V : 1) * 4);
    order_key *k = malloc((V ? V : 1) * sizeof *k);
    if (!c || !k) {
        free(k);
        return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the vertex order");
    }
    float lo[3] = {0.0f, 0.0f, 0.0f}, hi[3] = {0.0f, 0.0f, 0.0f};
    for (size_t v = 0; m && v < V; v++)
        for (int a = 0; a < 3; a++) {
            float x = m->positions[3 * v + a];
            if (v == 0 || x < lo[a]) lo[a] = x;
            if (v == 0 || x > hi[a]) hi[a] = x;
        }
    for (size_t v = 0; v < V; v++) {
        uint32_t q[6] = {0};
        for (int a = 0; m && a < 3; a++) {
            q[a] = grid7(m->positions[3 * v + a], lo[a], hi[a]);
            q[3 + a] = grid7(m->normals[3 * v + a], -1.0f, 1.0f);
        }
        uint64_t key = v >= t->info.object_vertex_count;
        for (int bit = 6; bit >= 0; bit--)
            for (int a = 0; a < 6; a++) key = key << 1 | ((q[a] >> bit) & 1u);
        k[v].key = key;
        k[v].v = (uint32_t)v;
    }
    qsort(k, V, sizeof *k, order_cmp);
    for (size_t i = 0; i < V; i++) c[i] = k[i].v;
    free(k);
    return HL_OK;
}

/* Range boundaries, in whole tiles (HL_TILE positions), into *starts;
 * returns the count, or 0 when out of memory.
 *
 * In the GPU shape: ranges of HL_ITEMS_RANGE_TILES tiles (512 positions)
 * in curve order, one word of tile bits a slot, walked by a work-item a
 * position (kernels/relight/relight_items.cl); mult > 1 (relight in
 * parts) makes them mult times shorter (a power of two, down to a tile).
 *
 * On a CPU device: one range per core, and the tiles are dealt to the ranges in turn (tile c of
 * the curve to range c mod R), so l->order is rearranged here. Dealt
 * tiles give every range the same mix of the mesh (object and ground,
 * lit and shadowed sides), so each holds about the same share of the
 * kept terms under any lighting, and no core waits for the other. Cutting
 * the curve into R runs of equal stored terms instead gave the ranges
 * 174k and 203k kept entries at M = 200 under city.exr on the bunny with
 * ground (dealt: 188.7k and 188.1k); the dot products last as long as the
 * larger. The tiles themselves are unchanged, so the entry count is too.
 * mult > 1 (relight in parts, cl_parts.c) makes mult ranges a core, so
 * that groups of them fit the device; l->order is made from curve. */
static uint32_t cut_ranges(hl_cl_light *l, const uint32_t *curve, uint32_t mult, uint32_t **starts)
{
    const size_t V = l->nverts, tiles = (V + HL_TILE - 1) / HL_TILE;
    if (l->cl->gpu_shape) {
        size_t per = HL_ITEMS_RANGE_TILES;
        while (per > 1 && per * mult > HL_ITEMS_RANGE_TILES) per /= 2;
        const size_t n = tiles ? (tiles + per - 1) / per : 1;
        l->range_tiles = (uint32_t)per;
        uint32_t *rs = malloc((n + 1) * 4);
        l->order = malloc((V ? V : 1) * 4);
        if (!rs || !l->order) {
            free(rs);
            return 0;
        }
        memcpy(l->order, curve, V * 4);
        for (size_t i = 0; i < n; i++) rs[i] = (uint32_t)(i * per * HL_TILE);
        rs[n] = (uint32_t)(tiles * HL_TILE);
        *starts = rs;
        return (uint32_t)n;
    }
    size_t R = (l->cl->units > 1 ? l->cl->units : 1) * (size_t)mult;
    if (tiles && R > tiles) R = tiles;
    uint32_t *rs = malloc((R + 1) * 4), *o = malloc((V ? V : 1) * 4);
    if (!rs || !o) {
        free(rs);
        free(o);
        return 0;
    }
    /* tile c goes to range (c + shift) mod R: the last tile, which may be
       partial, is then the last tile of the last range */
    const size_t shift = tiles ? (R - 1 - (tiles - 1) % R) : 0;
    size_t n = 0;
    for (size_t r = 0; r < R; r++) {
        rs[r] = (uint32_t)n;
        for (size_t c = (r + R - shift) % R; c < tiles; c += R)
            for (size_t v = c * HL_TILE; v < V && v < (c + 1) * HL_TILE; v++) o[n++] = curve[v];
    }
    rs[R] = (uint32_t)(tiles * HL_TILE);
    l->order = o;
    *starts = rs;
    return (uint32_t)R;
}

/* The rows turned into columns (see kernels/relight/relight.cl): vertices in tiles
 * of HL_TILE, tiles in ranges (one work-item each, cut_ranges); for each
 * range and slot, the tiles that store the slot, in tile order, each as one
 * entry: the HL_TILE terms as halves (half.h; zero in lanes whose vertex
 * does not store the slot),
 * after an all-zero entry 0; and for each range and slot the tiles its
 * column holds, 32 a word: a bit a tile, and the entries before the word.
 * Also each position's 2^e, which scales its sums back (1 in the
 * padding). */

/* words per column entry: HL_TILE halves */
#define COL_WORDS ((size_t)HL_TILE / 2)

/* The work of hl_cl_light_build_columns, shared by its phases. */
typedef struct col_build {
    hl_cl_light *l;
    const hl_transport *t;
    const hl_row_source *src; /* the file, where t holds no entries */
    size_t nc, nb, ts;      /* slots, blocks per row, words of 32 tiles in the largest range */
    size_t ncs, nrel, vpad; /* lengths of cs, of rel; positions with padding */
    uint64_t run;           /* entries, entry 0 included */
    uint32_t *cs;           /* each (range, slot)'s first entry (first, its count) */
    uint32_t *fill;         /* pass 1: each (range, slot)'s entries so far */
    uint32_t *rel;          /* each (range, slot, word of 32 tiles): tile bits, entries before */
    uint32_t *col;          /* the entries (made between the passes) */
    float *back;            /* each position's 2^e */
    int *ex;                /* each vertex position's e */
    float *inv;             /* and 2^-e */
} col_build;

/* Each position's e (half.h) and 2^e, which scales its sums back (1 in
 * the padding). */
static void column_scales(col_build *b)
{
    const hl_cl_light *l = b->l;
    for (size_t v = 0; v < b->vpad; v++) {
        if (v >= l->nverts) { b->back[v] = 1.0f; continue; } /* padding */
        const hl_row_quant q = b->t->row_quant[l->order[v]];
        b->ex[v] = hl_half_exponent(l->scheme, q.a, q.b);
        b->back[v] = ldexpf(1.0f, b->ex[v]);
        b->inv[v] = ldexpf(1.0f, -b->ex[v]);
    }
}

/* Row u's entries (2 bytes each): the transport's own, or, where it no
 * longer holds them (hl_relighter_create_from_file), read from its file
 * into row. Returns 0, or hl_tf_pread_all's failure (a short read means
 * the file changed since it was loaded). */
static int row_entries(const col_build *b, size_t u, uint8_t *row, const uint8_t **out)
{
    const hl_transport *t = b->t;
    if (t->entries) {
        *out = t->entries + 2 * t->row_offset[u];
        return 0;
    }
    const uint64_t n = t->row_offset[u + 1] - t->row_offset[u];
    *out = row;
    return hl_tf_pread_all(b->src->fd, row, (size_t)(2 * n), b->src->offset + 2 * t->row_offset[u]);
}

/* A pass's work shared by its threads: ranges taken in turn; the first
 * failure (a row that could not be read again) is kept for the caller. */
typedef struct pass_job {
    col_build *b;
    int pass;
    atomic_size_t next;
    atomic_int failed;
    size_t bad_vertex;
    int bad_errno, bad_short;
} pass_job;

/* One pass over the rows of range rg, with a thread's scratch (last: the
 * last tile seen to store each slot; row: one row read from the file).
 * Pass 0 counts, for each slot, the tiles that store it (into cs, one
 * place on); pass 1 gives each tile that first stores a slot the next
 * entry of the slot's column (its bit into rel),
 * writes every term as a half into its vertex's lane, and then counts
 * each column's entries before each word of rel. Ranges share nothing
 * they write. */
static int column_pass(pass_job *j, size_t rg, uint32_t *last, uint8_t *row)
{
    col_build *b = j->b;
    const int pass = j->pass;
    const hl_cl_light *l = b->l;
    const hl_transport *t = b->t;
    const size_t nc = b->nc, nb = b->nb, ts = b->ts, V = l->nverts;
    uint32_t *c = (pass == 0 ? b->cs : b->fill) + rg * (nc + 1);
    uint32_t *rr = pass == 0 ? NULL : b->rel + 2 * rg * nc * ts;
    memset(last, 0xff, nc * 4);
    const size_t v0 = l->range_start[rg];
    for (size_t v = v0; v < V && v < l->range_start[rg + 1]; v++) {
        uint32_t tile = (uint32_t)((v - v0) / HL_TILE), lane = (uint32_t)(v % HL_TILE);
        const size_t u = l->order[v]; /* the vertex at position v */
        const uint8_t *ent = NULL;
        int k = row_entries(b, u, row, &ent);
        if (k) {
            int none = 0;
            if (atomic_compare_exchange_strong(&j->failed, &none, 1)) {
                j->bad_vertex = u;
                j->bad_errno = k < 0 ? errno : 0;
                j->bad_short = k > 0;
            }
            return k;
        }
        size_t i = 0;
        for (size_t bl = 0; bl < nb; bl++)
            for (uint32_t n = 0; n < t->block_counts[u * nb + bl]; n++, i++) {
                size_t s = bl * HL_BLOCK + ent[2 * i];
                int fresh = last[s] != tile;
                last[s] = tile;
                if (pass == 0) {
                    c[s + 1] += fresh;
                    continue;
                }
                if (fresh) { /* a new entry: zeroed here, where its lanes are written */
                    rr[2 * (s * ts + tile / 32)] |= 1u << (tile % 32);
                    memset(b->col + (size_t)(c[s]++) * COL_WORDS, 0, COL_WORDS * 4);
                }
                const hl_row_quant q = t->row_quant[u];
                float term = hl_dequant(l->scheme, ent[2 * i + 1], q.a, q.b, hl_dither_key((uint32_t)u, (uint32_t)s));
                /* hl_half_held(term, e), its ldexpf as a multiply by 2^-e:
                   exact powers of two, so the same rounding, 4x faster */
                ((uint16_t *)(b->col + (size_t)(c[s] - 1) * COL_WORDS))[lane] = (uint16_t)hl_half_bits(term * b->inv[v]);
            }
    }
    for (size_t s = 0; pass == 1 && s < nc; s++) {
        uint32_t before = 0, *w = rr + 2 * s * ts;
        for (size_t i = 0; i < ts; i++) {
            w[2 * i + 1] = before;
            before += (uint32_t)__builtin_popcount(w[2 * i]);
        }
    }
    return 0;
}

static void *pass_worker(void *arg)
{
    pass_job *j = arg;
    const size_t nc = j->b->nc;
    uint32_t *last = malloc(nc * 4);
    uint8_t *row = j->b->t->entries ? NULL : malloc(2 * nc); /* a row stores each slot at most once */
    int ok = last && (j->b->t->entries || row);
    for (size_t rg; ok && !atomic_load(&j->failed) && (rg = atomic_fetch_add(&j->next, 1)) < j->b->l->nranges;)
        if (column_pass(j, rg, last, row)) break;
    if (!ok) {
        int none = 0;
        atomic_compare_exchange_strong(&j->failed, &none, 2); /* out of memory */
    }
    free(last);
    free(row);
    return NULL;
}

/* Pass `pass` over all ranges, on the context's threads (ranges in turn). */
static hl_result columns_pass(col_build *b, int pass)
{
    pass_job j = {.b = b, .pass = pass};
    atomic_init(&j.next, 0);
    atomic_init(&j.failed, 0);
    int threads = hl_context_threads(b->l->ctx);
    if (threads > (int)b->l->nranges) threads = (int)b->l->nranges;
    hl_run_threads(threads > 0 ? threads : 1, pass_worker, &j);
    const int f = atomic_load(&j.failed);
    if (f == 2) return hl_fail(b->l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the transport columns");
    if (f)
        return hl_fail(b->l->ctx, HL_ERR_IO, "%s: cannot read vertex %zu's row again (%s)", b->src->path, j.bad_vertex,
                       j.bad_short ? "the file is shorter than when it was loaded" : strerror(j.bad_errno));
    return HL_OK;
}

/* After pass 0: the counts in cs become absolute starts. */
static hl_result column_starts(col_build *b)
{
    hl_cl_light *l = b->l;
    uint64_t run = 1; /* absolute starts, range after range, after entry 0 */
    for (size_t i = 0; i < b->ncs; i++) {
        if (i % (b->nc + 1) == 0) b->cs[i] = (uint32_t)run;
        else { run += b->cs[i]; b->cs[i] = (uint32_t)(run < UINT32_MAX ? run : UINT32_MAX); }
    }
    if (run >= UINT32_MAX)
        return hl_fail(l->ctx, HL_ERR_UNSUPPORTED, "the transport needs %llu column entries; one device holds at most 2^32",
                       (unsigned long long)run);
    l->col_entries = run - 1;
    b->run = run;
    return HL_OK;
}

/* A cut of the vertices into ranges (cut_ranges, mult ranges a core on a
 * CPU device) and pass 0 over it: ranges, tstride, the starts in cs. */
static hl_result column_count(col_build *b, const uint32_t *curve, uint32_t mult)
{
    hl_cl_light *l = b->l;
    free(l->range_start);
    free(l->order);
    free(b->cs);
    l->order = l->range_start = b->cs = NULL;
    l->nranges = cut_ranges(l, curve, mult, &l->range_start);
    if (!l->nranges) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the transport columns");
    b->vpad = l->nverts ? l->range_start[l->nranges] : HL_TILE;
    b->ncs = (size_t)l->nranges * (b->nc + 1);
    b->ts = 1;
    for (size_t rg = 0; rg < l->nranges; rg++) {
        size_t n = ((l->range_start[rg + 1] - l->range_start[rg]) / HL_TILE + 31) / 32;
        if (n > b->ts) b->ts = n;
    }
    l->tstride = (uint32_t)b->ts;
    b->nrel = (size_t)l->nranges * b->nc * b->ts;
    b->cs = calloc(b->ncs, 4);
    if (!b->cs) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the transport columns");
    TRY(columns_pass(b, 0));
    return column_starts(b);
}

/* The memory pass 1 fills (the tile bits zeroed; each entry is zeroed
 * by pass 1 as it is made, so lanes whose vertex does not store a slot
 * stay zero): the entries and tile bits straight where the device reads
 * them on a CPU device (hl_cl_adopt_buf), so never held twice. */
static hl_result column_memory(col_build *b)
{
    hl_context *ctx = b->l->ctx;
    const size_t V = b->l->nverts;
    b->fill = malloc(b->ncs * 4);
    b->back = malloc(b->vpad * 4);
    b->ex = malloc((V ? V : 1) * sizeof *b->ex);
    b->inv = malloc((V ? V : 1) * sizeof *b->inv);
    if (!b->fill || !b->back || !b->ex || !b->inv) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the transport columns");
    memcpy(b->fill, b->cs, b->ncs * 4);
    b->rel = hl_alloc_big(ctx, b->nrel * 8, "the transport columns' tile bits");
    if (!b->rel) return HL_ERR_OUT_OF_MEMORY;
    memset(b->rel, 0, b->nrel * 8);
    b->col = hl_alloc_big(ctx, (size_t)b->run * COL_WORDS * 4, "transport columns");
    if (!b->col) return HL_ERR_OUT_OF_MEMORY;
    memset(b->col, 0, COL_WORDS * 4); /* entry 0; pass 1 zeroes each entry as it makes it */
    return HL_OK;
}

/* The columns, their starts, the tile bits, the ranges and the scales
 * onto the device: whole, or (nparts > 1) the columns kept on the host for
 * part-sized buffers (cl_parts.c). */
static hl_result column_upload(col_build *b, const hl_col_sizes *z)
{
    hl_cl_light *l = b->l;
    hl_context *ctx = l->ctx;
    hl_result r = HL_OK;
    void *col = b->col, *rel = b->rel;
    b->col = NULL;
    b->rel = NULL;
    if (l->nparts > 1) {
        r = hl_cl_light_make_parts(l, z, col, rel);
    } else {
        l->host[0] = col;
        l->host[3] = rel;
        r = hl_cl_adopt_buf(ctx, &l->col, (size_t)b->run * COL_WORDS * 4, &l->host[0], "transport columns");
        if (r == HL_OK) r = hl_cl_big_buf(ctx, &l->cols, b->ncs * 4, b->cs, &l->host[1], "column starts");
        /* on failure host[] is freed with the relighter */
        if (r == HL_OK) r = hl_cl_adopt_buf(ctx, &l->rel, b->nrel * 8, &l->host[3], "the columns' tile bits");
        if (r == HL_OK)
            r = hl_cl_make_buf(ctx, &l->rstart, CL_MEM_READ_ONLY, ((size_t)l->nranges + 1) * 4, l->range_start, "ranges");
    }
    if (r == HL_OK) r = hl_cl_big_buf(ctx, &l->back, b->vpad * 4, b->back, &l->host[2], "the sums' scales");
    return r;
}

hl_result hl_cl_light_build_columns(hl_cl_light *l, const hl_transport *t, const hl_row_source *src)
{
    const size_t nc = l->g->ncoef;
    if (!t->entries && !src)
        return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "the transport holds no entries and no file to read them from");
    uint32_t *curve = NULL;
    TRY(vertex_order(l, t, &curve));
    col_build b = {.l = l, .t = t, .src = src, .nc = nc, .nb = l->g->nblocks, .ts = 1};
    hl_result r = HL_OK;
    /* count; where one range is too big for the device's memory, cut finer
       and count again (cl_parts.c) */
    hl_col_sizes z = {0};
    for (uint32_t mult = 1, finer = 0; r == HL_OK; mult = finer) {
        r = column_count(&b, curve, mult);
        z = (hl_col_sizes){b.cs, b.run, nc, b.ts, b.vpad};
        if (r == HL_OK) r = hl_cl_light_plan_parts(l, &z, mult, &finer);
        if (!finer) break;
    }
    free(curve);
    if (r == HL_OK) r = column_memory(&b);
    if (r == HL_OK) column_scales(&b);
    if (r == HL_OK) r = columns_pass(&b, 1);
    if (r == HL_OK) r = column_upload(&b, &z);
    l->col_start = b.cs;
    free(b.fill);
    free(b.back);
    free(b.ex);
    free(b.inv);
    hl_free_big(b.col);
    hl_free_big(b.rel);
    return r;
}
