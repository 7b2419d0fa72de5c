/* lighting.c - the relighter (hl_relighter_*) on either backend, and the
 * selection weights it ranks the lighting terms by.
 *
 * A lighting change runs env2para, Haar, selection and the dot products:
 * on the device (cl_relight.c) or through the plain-C twins (twins/). The
 * tables it reads come from light_tables.c; a repeated change with the
 * same settings reuses the last colours. A spherical-harmonic transport
 * (hl_transport_info.basis) gets its lighting projected onto the same
 * harmonics in Haar's place (hl_sh_matrix), into the same slots; a
 * cube-face Haar one gets each face texel's mean radiance (cube/cube.h's
 * taps, env2para's kernels) and the faces' Haar instead of env2para and
 * Haar. Selection and the dot products are the same for every basis.
 * Depends on: lighting.h, cl_backend.h (the device stages), twins.h,
 * the transport (hl_dequant; transport_layout.h to read a file's header
 * again for hl_relighter_create_from_file), core.
 */
#define _POSIX_C_SOURCE 200809L /* O_CLOEXEC */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "capture.h"
#include "cl_backend.h"
#include "cube.h"
#include "haarlight_tools.h"
#include "lighting.h"
#include "sh.h"
#include "surroundings.h"
#include "transport_layout.h"
#include "twins.h"

struct hl_relighter {
    hl_context *ctx;
    const hl_transport *t;
    hl_geom *g;
    hl_light_geom *lg;
    hl_cl_light *cl;        /* NULL: the plain-C reference */
    float *cells;           /* current environment, 4 floats per cell */
    uint64_t env_serial;
    float *albedo4;
    float *weights[HL_SELECT_TRANSPORT + 1]; /* per scheme, made when first asked */
    uint32_t uploaded_weights;
    double max_row_norm;    /* max over vertices of |T_v| */
    float *B4;              /* the reference's colours (NULL on OpenCL) */
    const float *rgba;      /* the last colours: B4, or the device's, mapped */
    float *shY;             /* spherical harmonics: the lighting's projection; NULL: Haar */
    hl_cube_tables *cube;   /* cube-face Haar: the face texels' taps; NULL: none */
    float *Lp, *Lw, *Lsel;  /* reference scratch */
    uint8_t *used;
    uint32_t *bits;
    hl_ref_key *keys;       /* hl_ref_select's scratch */
    int have_last;
    void *last_out;         /* where the last colours went: NULL for rgba */
    hl_relight_desc last;
    uint64_t last_serial;
    hl_relight_stats last_stats;
    /* surroundings (hl_relighter_set_surroundings): the capture, a copy of
       the triangles it last captured (9 + 3 floats each, so an unchanged
       frame is found by comparing) and the scene it reads */
    hl_surroundings *sur;
    hl_capture *cap;
    float *sur_pos, *sur_em;
    uint32_t sur_n, sur_room;
    hl_capture_scene cscene;
    float *Lenv;            /* reference: the environment behind them */
    /* more than one capture point (hl_relighter_set_probes): the points,
       made again when the triangles move, and the blended colours */
    uint32_t probes_max;
    double probe_tol;
    hl_probe_set probes;
    int probes_stale;
    float centre[3];        /* the one capture point's place */
    double reach;           /* the farthest vertex from it (< 0: not yet measured) */
    float *blend4;          /* V x 4: the colours blended over the points */
    /* a row a channel (coloured bounces, channels 3): a relighter per
       channel's plane of rows, its albedo that channel's alone, and this
       one only passes the settings on and gathers each plane's channel */
    struct hl_relighter *sub[3];
    hl_transport *plane;    /* 3: the planes as transports of their own */
    float *sum4;            /* V x 4: the gathered colours */
};

void hl_relighter_destroy(hl_relighter *r)
{
    if (!r) return;
    if (r->sub[0] || r->plane) {
        for (int c = 0; c < 3; c++) {
            hl_relighter_destroy(r->sub[c]);
            if (r->plane) free(r->plane[c].row_offset);
        }
        free(r->plane);
        hl_free_big(r->sum4);
        free(r);
        return;
    }
    hl_cl_light_destroy(r->cl);
    hl_light_geom_destroy(r->lg);
    hl_geom_destroy(r->g);
    hl_free_big(r->cells);
    free(r->albedo4);
    for (int i = 0; i <= (int)HL_SELECT_TRANSPORT; i++) free(r->weights[i]);
    free(r->B4);
    hl_free_big(r->shY);
    hl_cube_tables_destroy(r->cube);
    free(r->Lp);
    free(r->Lw);
    free(r->Lsel);
    free(r->used);
    free(r->bits);
    free(r->keys);
    hl_capture_destroy(r->cap);
    free(r->sur_pos);
    free(r->sur_em);
    free(r->Lenv);
    hl_probe_set_free(&r->probes);
    hl_free_big(r->blend4);
    free(r);
}

/* The capture point: the centre of the bounding box of the object's
 * vertices (those before the ground). */
void hl_object_centre(const hl_mesh *m, float c[3])
{
    uint32_t n = m->object_vertex_count ? m->object_vertex_count : m->vertex_count;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v = 0; v < n; v++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fminf(lo[a], m->positions[3 * (size_t)v + a]);
            hi[a] = fmaxf(hi[a], m->positions[3 * (size_t)v + a]);
        }
    for (int a = 0; a < 3; a++) c[a] = n ? 0.5f * (lo[a] + hi[a]) : 0.0f;
}

/* The transport weights' partial sums: vertices in chunks whose count
 * and bounds depend only on the vertex and slot counts (never on the
 * threads), each summed alone, then the chunks added in order, so the
 * weights have the same bits however many threads made them. */
typedef struct weight_job {
    const hl_transport *t;
    uint32_t nc, nchunks, per;
    double *part; /* nchunks x nc */
    double *most; /* nchunks: the largest |T_v|^2 of each */
    atomic_uint next;
} weight_job;

/* One row's |T_i| added into acc by slot; returns its |T_v|^2. */
static double weigh_row(const hl_transport *t, uint32_t v, double *acc)
{
    const uint32_t nb = t->info.block_count;
    const hl_row_quant q = t->row_quant[v];
    const uint8_t *en = t->entries;
    double ss = 0.0;
    uint64_t e = t->row_offset[v];
    for (uint32_t b = 0; b < nb; b++)
        for (uint32_t k = 0; k < t->block_counts[(size_t)v * nb + b]; k++, e++) {
            const uint32_t slot = b * HL_BLOCK + en[2 * e];
            double x = hl_dequant(t->info.quant, en[2 * e + 1], q.a, q.b, hl_dither_key(v, slot));
            ss += x * x;
            acc[slot] += fabs(x);
        }
    return ss;
}

/* weigh_row for sqrt8 (the default), the same sums bit for bit in half
 * the time (most of a big file's first relight): the magnitude alone, as
 * hl_dequant_sqrt8 makes it (the sign changes neither x^2 nor |x|), and
 * no additions for zero codes (they add exact zeros to sums that are
 * never -0). */
static double weigh_row_sqrt8(const hl_transport *t, uint32_t v, double *acc)
{
    const uint32_t nb = t->info.block_count;
    const float mx = t->row_quant[v].b;
    const uint8_t *en = t->entries;
    double ss = 0.0;
    uint64_t e = t->row_offset[v];
    for (uint32_t b = 0; b < nb; b++) {
        const uint64_t end = e + t->block_counts[(size_t)v * nb + b];
        for (; e < end; e++) {
            const uint32_t code = en[2 * e + 1] & 127u, slot = b * HL_BLOCK + en[2 * e];
            if (!code) continue;
            const float s = ((float)code - hl_dither(hl_dither_key(v, slot))) * (1.0f / 127.0f);
            const float m = mx * (s * s); /* rounded to float first, as hl_dequant_sqrt8 returns it */
            const double x = m;
            ss += x * x;
            acc[slot] += x;
        }
    }
    return ss;
}

static void *weight_worker(void *arg)
{
    weight_job *j = arg;
    const hl_transport *t = j->t;
    const uint32_t V = t->info.vertex_count;
    for (uint32_t c; (c = atomic_fetch_add(&j->next, 1u)) < j->nchunks;) {
        double *acc = j->part + (size_t)c * j->nc, most = 0.0;
        const uint64_t v0 = (uint64_t)c * j->per, v1 = v0 + j->per < V ? v0 + j->per : V;
        for (uint32_t v = (uint32_t)v0; v < v1; v++) {
            const double ss = t->info.quant == HL_QUANT_SQRT8 ? weigh_row_sqrt8(t, v, acc) : weigh_row(t, v, acc);
            if (ss > most) most = ss;
        }
        j->most[c] = most;
    }
    return NULL;
}

/* The transport selection weights (mean |T_i| over the vertices) into w
 * (nc floats) and, when row_norm is given, the largest |T_v|: one pass
 * over the entries on the context's threads, summed in one order whoever
 * asks (weight_job). */
static hl_result transport_weights(hl_context *ctx, const hl_transport *t, uint32_t nc, float *w, double *row_norm)
{
    const uint32_t V = t->info.vertex_count;
    /* at most 64 chunks (their sums: 64 x 8 nc bytes), of 4,096 vertices or more */
    uint32_t nchunks = (V + 4095) / 4096;
    if (nchunks > 64) nchunks = 64;
    if (nchunks < 1) nchunks = 1;
    weight_job j = {.t = t, .nc = nc, .nchunks = nchunks, .per = (V + nchunks - 1) / nchunks};
    atomic_init(&j.next, 0u);
    j.part = hl_calloc(ctx, (size_t)nchunks * nc, sizeof(double), "transport weights");
    j.most = hl_calloc(ctx, nchunks, sizeof(double), "transport weights");
    if (!j.part || !j.most) {
        free(j.part);
        free(j.most);
        return HL_ERR_OUT_OF_MEMORY;
    }
    int threads = hl_context_threads(ctx);
    hl_run_threads(threads < (int)nchunks ? threads : (int)nchunks, weight_worker, &j);
    double most = 0.0;
    for (uint32_t c = 0; c < nchunks; c++) most = j.most[c] > most ? j.most[c] : most;
    for (uint32_t c = 1; c < nchunks; c++)
        for (uint32_t i = 0; i < nc; i++) j.part[i] += j.part[(size_t)c * nc + i];
    if (row_norm) *row_norm = sqrt(most);
    for (uint32_t i = 0; i < nc; i++) w[i] = (float)(j.part[i] / (V ? V : 1));
    free(j.part);
    free(j.most);
    return HL_OK;
}

/* What the relighter needs of the rows besides the columns, read once at
 * creation rather than at the first lighting change: max_row_norm (for
 * the error bound) and the transport selection weights. */
static hl_result row_measures(hl_relighter *r, const hl_transport *t)
{
    float *w = hl_malloc(r->ctx, (size_t)r->g->ncoef * 4, "selection weights");
    if (!w) return HL_ERR_OUT_OF_MEMORY;
    hl_result res = transport_weights(r->ctx, t, r->g->ncoef, w, &r->max_row_norm);
    if (res != HL_OK) {
        free(w);
        return res;
    }
    r->weights[HL_SELECT_TRANSPORT] = w;
    return HL_OK;
}

/* hl_relighter_create; with drop and src, drop's entries (t's) are freed
 * once read for row_measures, and the columns read them from src. only:
 * the one channel whose albedo is kept (the others zero), or -1. */
static hl_result create_one(hl_context *ctx, const hl_transport *t, hl_transport *drop, const hl_row_source *src,
                            int rows, int only, hl_relighter **out)
{
    *out = NULL;
    if (!t || !t->mesh) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_relighter_create: no transport");
    hl_relighter *r = hl_calloc(ctx, 1, sizeof *r, "the relighter");
    if (!r) return HL_ERR_OUT_OF_MEMORY;
    r->ctx = ctx;
    r->t = t;
    const uint32_t V = t->info.vertex_count;
    hl_result res = hl_geom_create(ctx, t->info.N, t->info.C, &r->g);
    if (res == HL_OK) res = hl_light_geom_create(ctx, r->g, &r->lg);
    const uint32_t nc = r->g ? r->g->ncoef : 0;
    if (res == HL_OK) {
        r->albedo4 = hl_malloc(ctx, (size_t)V * 16, "albedo");
        /* OpenCL: the colours are read where the device wrote them */
        r->B4 = ctx->backend == HL_BACKEND_OPENCL ? NULL : hl_malloc(ctx, (size_t)V * 16, "vertex colours");
        r->Lp = hl_malloc(ctx, (size_t)nc * 12, "lighting");
        r->Lw = hl_malloc(ctx, (size_t)nc * 12, "lighting");
        r->Lsel = hl_malloc(ctx, (size_t)nc * 16, "lighting");
        r->used = hl_malloc(ctx, r->g->nblocks, "block flags");
        r->bits = hl_malloc(ctx, (size_t)nc / 8, "kept-slot bits");
        r->keys = hl_malloc(ctx, (size_t)nc * sizeof *r->keys, "the selection's sort keys");
        if (!r->albedo4 || (!r->B4 && ctx->backend != HL_BACKEND_OPENCL) || !r->Lp || !r->Lw || !r->Lsel ||
            !r->used || !r->bits || !r->keys)
            res = HL_ERR_OUT_OF_MEMORY;
    }
    if (res == HL_OK) {
        for (uint32_t v = 0; v < V; v++) {
            memcpy(r->albedo4 + 4 * (size_t)v, t->mesh->albedo + 3 * (size_t)v, 12);
            r->albedo4[4 * (size_t)v + 3] = 0.0f;
            for (int c = 0; c < 3 && only >= 0; c++)
                if (c != only) r->albedo4[4 * (size_t)v + c] = 0.0f;
        }
        res = row_measures(r, t);
        hl_object_centre(t->mesh, r->cscene.center);
        memcpy(r->centre, r->cscene.center, sizeof r->centre);
        r->reach = -1.0;
        r->probes_max = 1;
        /* the device starts with lg->area, the Haar supports' (an SH
           transport's area weights differ: uploaded when first used) */
        r->uploaded_weights = t->info.basis == HL_TRANSPORT_BASIS_HAAR ? HL_SELECT_AREA : 0u;
        if (res == HL_OK && t->info.basis == HL_TRANSPORT_BASIS_SH)
            res = hl_sh_matrix(ctx, t->info.N, t->info.sh_order, 0, &r->shY);
        if (res == HL_OK && t->info.basis == HL_TRANSPORT_BASIS_CUBE)
            res = hl_cube_tables_create(ctx, t->info.sh_order, t->info.C, r->lg->wc, r->lg->hc, &r->cube);
        /* from here on the OpenCL relighter reads no entries but the
           columns' (from src once dropped) */
        if (res == HL_OK && drop && src && ctx->backend == HL_BACKEND_OPENCL) {
            hl_free_big(drop->entries);
            drop->entries = NULL;
        }
        if (res == HL_OK && ctx->backend == HL_BACKEND_OPENCL)
            res = rows ? hl_cl_light_create_rows(ctx, r->g, r->lg, t, r->albedo4, &r->cl)
                       : hl_cl_light_create_from(ctx, r->g, r->lg, t, src, r->albedo4, &r->cl);
        /* the columns are built: the row table goes too (72 bytes a vertex) */
        if (res == HL_OK && drop && src && ctx->backend == HL_BACKEND_OPENCL) {
            hl_free_big(drop->block_counts);
            free(drop->row_offset);
            drop->block_counts = NULL;
            drop->row_offset = NULL;
        }
        if (res == HL_OK && r->cl && r->shY)
            res = hl_cl_light_set_sh(r->cl, r->shY, hl_sh_stride(t->info.sh_order), hl_sh_count(t->info.sh_order));
        if (res == HL_OK && r->cl && r->cube)
            res = hl_cl_light_set_cube(r->cl, r->cube->Cq, r->cube->tap_start, r->cube->taps, r->cube->ntaps);
    }
    if (res != HL_OK) {
        hl_relighter_destroy(r);
        return res;
    }
    *out = r;
    return HL_OK;
}

/* A transport with a row a channel: each plane of V rows becomes a
 * transport of its own (its offsets from its first entry, the rest
 * pointing into t's arrays, which it must outlive) with a relighter of its
 * own. Nothing of t is dropped: the planes share its arrays. */
static hl_result create_planes(hl_context *ctx, const hl_transport *t, const hl_row_source *src, int rows,
                               hl_relighter **out)
{
    *out = NULL;
    hl_relighter *r = hl_calloc(ctx, 1, sizeof *r, "the relighter");
    if (!r) return HL_ERR_OUT_OF_MEMORY;
    r->ctx = ctx;
    r->t = t;
    const uint32_t V = t->info.vertex_count, nb = t->info.block_count;
    r->plane = hl_calloc(ctx, 3, sizeof *r->plane, "the channels' rows");
    r->sum4 = r->plane ? hl_alloc_big(ctx, (size_t)V * 16, "vertex colours") : NULL;
    hl_result res = r->sum4 ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    for (uint32_t c = 0; c < 3 && res == HL_OK; c++) {
        hl_transport *p = &r->plane[c];
        const uint64_t base = t->row_offset[(size_t)c * V];
        p->row_offset = hl_malloc(ctx, ((size_t)V + 1) * 8, "the channels' row offsets");
        if (!p->row_offset) {
            res = HL_ERR_OUT_OF_MEMORY;
            break;
        }
        for (uint32_t v = 0; v <= V; v++) p->row_offset[v] = t->row_offset[(size_t)c * V + v] - base;
        p->info = t->info;
        p->info.channels = 1;
        p->info.coefficients_kept = p->row_offset[V];
        p->mesh = t->mesh;
        p->row_quant = t->row_quant + (size_t)c * V;
        p->block_counts = t->block_counts + (size_t)c * V * nb;
        p->entries = t->entries ? t->entries + 2 * base : NULL;
        hl_row_source one;
        if (src) {
            one = *src;
            one.offset += 2 * base;
        }
        res = create_one(ctx, p, NULL, src ? &one : NULL, rows, (int)c, &r->sub[c]);
    }
    if (res != HL_OK) {
        hl_relighter_destroy(r);
        return res;
    }
    *out = r;
    return HL_OK;
}

static hl_result create_src(hl_context *ctx, const hl_transport *t, hl_transport *drop, const hl_row_source *src,
                            int rows, hl_relighter **out)
{
    if (t && t->mesh && t->info.channels == 3) return create_planes(ctx, t, src, rows, out);
    return create_one(ctx, t, drop, src, rows, -1, out);
}

hl_result hl_relighter_create(hl_context *ctx, const hl_transport *t, hl_relighter **out)
{
    return create_src(ctx, t, NULL, NULL, 0, out);
}

uint32_t hl_relighter_planes(hl_relighter *r, hl_relighter **sub)
{
    if (r && r->sub[0]) {
        for (int c = 0; c < 3; c++) sub[c] = r->sub[c];
        return 3;
    }
    sub[0] = r;
    return 1;
}

hl_result hl_relighter_create_once(hl_context *ctx, hl_transport *t, const char *path, hl_relighter **out)
{
    if (ctx->backend != HL_BACKEND_OPENCL || !ctx->cl || !t || !t->entries) return hl_relighter_create(ctx, t, out);
    /* the entries in one buffer, and beside them the row table (16 bytes
       and 2 a block a vertex), albedo and colours (32 a vertex) and 64 MiB
       for the lighting stages; else the columns (in parts where need be) */
    const uint64_t V = hl_transport_rows(&t->info), bytes = 2 * t->info.coefficients_kept;
    const uint64_t all = bytes + V * (48 + 2 * (uint64_t)t->info.block_count) + ((uint64_t)64 << 20);
    if (bytes > hl_cl_largest_buffer(ctx) || all > hl_cl_memory_free(ctx))
        return path ? hl_relighter_create_from_file(ctx, t, path, out) : hl_relighter_create(ctx, t, out);
    return create_src(ctx, t, NULL, NULL, 1, out);
}

/* Opens path for reading t's rows again: its header must be intact and
 * describe t, and its entries' checksum (in the header, which its own
 * checksum covers) must be that of t's entries, so the rows read back are
 * those loaded (short of a file rewritten meanwhile, which can garble the
 * colours but not the memory: every index read is bounded). */
static hl_result open_rows(hl_context *ctx, const hl_transport *t, const char *path, hl_row_source *src)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    uint8_t bytes[TF_HEADER_SIZE];
    tf_header h;
    struct stat st;
    const hl_transport_info *i = &t->info;
    uint32_t ecrc = 0;
    if (hl_tf_crc_threads(ctx, t->entries, 2 * i->coefficients_kept, &ecrc) != HL_OK) {
        close(fd);
        return HL_ERR_OUT_OF_MEMORY;
    }
    int bad = hl_tf_pread_all(fd, bytes, sizeof bytes, 0) != 0 || fstat(fd, &st) != 0 ||
              memcmp(bytes, TF_MAGIC, 8) != 0 || get_u32(bytes + H_HEADER_CRC) != crc_update(0, bytes, H_HEADER_CRC);
    if (!bad) {
        hl_tf_header_decode(bytes, &h);
        bad = h.file_size != (uint64_t)st.st_size || h.info.N != i->N || h.info.quant != i->quant ||
              h.info.vertex_count != i->vertex_count || h.info.block_count != i->block_count ||
              h.info.basis != i->basis || h.info.sh_order != i->sh_order ||
              h.info.coefficients_kept != i->coefficients_kept || h.sec[SEC_ENTRIES].size != 2 * i->coefficients_kept ||
              h.sec[SEC_ENTRIES].crc != ecrc;
    }
    if (bad) {
        close(fd);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not the transport file this transport was loaded from, or changed since",
                       path);
    }
    *src = (hl_row_source){path, fd, h.sec[SEC_ENTRIES].offset};
    return HL_OK;
}

hl_result hl_relighter_create_from_file(hl_context *ctx, hl_transport *t, const char *path, hl_relighter **out)
{
    *out = NULL;
    if (!t || !t->mesh || !path) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_relighter_create_from_file: no transport or path");
    if (ctx->backend != HL_BACKEND_OPENCL || !t->entries) return hl_relighter_create(ctx, t, out);
    hl_row_source src;
    hl_result res = open_rows(ctx, t, path, &src);
    if (res != HL_OK) return res;
    res = create_src(ctx, t, t, &src, 0, out);
    close(src.fd);
    return res;
}

/* A setting passed on to every channel's relighter (create_planes). */
#define FORWARD_TO_PLANES(r, call)                                                  \
    do {                                                                            \
        if ((r)->sub[0]) {                                                          \
            hl_result res_ = HL_OK;                                                 \
            for (int c_ = 0; c_ < 3 && res_ == HL_OK; c_++) {                       \
                hl_relighter *p_ = (r)->sub[c_];                                    \
                res_ = call;                                                        \
            }                                                                       \
            return res_;                                                            \
        }                                                                           \
    } while (0)

hl_result hl_relighter_set_surroundings(hl_relighter *r, hl_surroundings *s)
{
    if (!r) return HL_ERR_INVALID_ARGUMENT;
    FORWARD_TO_PLANES(r, hl_relighter_set_surroundings(p_, s));
    /* the capture draws the surroundings on the paraboloid texels, which a
       cube-face transport's lighting never passes through */
    if (s && r->cube)
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT,
                       "surroundings: not supported on a cube-face Haar transport (basis 2); precompute with --basis "
                       "haar or sh to relight under surroundings");
    if (s && !r->cap) {
        hl_result res = hl_capture_create(r->ctx, r->g->N, 0, &r->cap);
        if (res != HL_OK) return res;
    }
    if (s && !r->cl && !r->Lenv) {
        r->Lenv = hl_malloc(r->ctx, (size_t)r->g->ncoef * 12, "the environment behind the surroundings");
        if (!r->Lenv) return HL_ERR_OUT_OF_MEMORY;
    }
    r->sur = s;
    r->sur_n = 0; /* the next run captures whatever the triangles are */
    r->env_serial++;
    return HL_OK;
}

hl_result hl_relighter_set_probes(hl_relighter *r, uint32_t max_probes, double tol)
{
    if (!r) return HL_ERR_INVALID_ARGUMENT;
    FORWARD_TO_PLANES(r, hl_relighter_set_probes(p_, max_probes, tol));
    if (max_probes < 1 || max_probes > HL_PROBES_MAX)
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "probes: %u capture points: expected 1 to %u", max_probes,
                       HL_PROBES_MAX);
    if (!(tol >= 0.0) || !isfinite(tol))
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "probes: the parallax tolerance %g must be a finite number >= 0",
                       tol);
    if (max_probes > 1 && !r->blend4) {
        r->blend4 = hl_alloc_big(r->ctx, (size_t)r->t->info.vertex_count * 16, "the colours blended over the probes");
        if (!r->blend4) return HL_ERR_OUT_OF_MEMORY;
    }
    r->probes_max = max_probes;
    r->probe_tol = tol > 0.0 ? tol : 2.0 / r->g->N;
    r->probes_stale = 1;
    r->env_serial++;
    return HL_OK;
}

/* Takes the surroundings' current triangles: a new lighting (env_serial)
 * when they differ from the last captured ones. */
static hl_result take_surroundings(hl_relighter *r)
{
    const float *pos = NULL, *em = NULL;
    hl_result res = hl_surroundings_triangles(r->sur, &pos, &em);
    if (res != HL_OK) return res;
    const uint32_t n = hl_surroundings_triangle_count(r->sur);
    if (n == r->sur_n && !memcmp(pos, r->sur_pos, (size_t)n * 36) && !memcmp(em, r->sur_em, (size_t)n * 12))
        return HL_OK;
    if (n > r->sur_room) {
        float *p = realloc(r->sur_pos, (size_t)n * 36), *e = p ? realloc(r->sur_em, (size_t)n * 12) : NULL;
        if (p) r->sur_pos = p;
        if (e) r->sur_em = e;
        if (!p || !e) return hl_fail(r->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u triangles of surroundings", n);
        r->sur_room = n;
    }
    memcpy(r->sur_pos, pos, (size_t)n * 36);
    memcpy(r->sur_em, em, (size_t)n * 12);
    r->sur_n = n;
    r->cscene.positions = r->sur_pos;
    r->cscene.emission = r->sur_em;
    r->cscene.triangle_count = n;
    r->env_serial++;
    r->probes_stale = 1;
    /* checked here, where the file can be named (the capture checks again) */
    res = hl_capture_check(r->ctx, r->g->ncoef, &r->cscene);
    if (res != HL_OK) {
        char why[1024];
        snprintf(why, sizeof why, "%s", hl_context_last_error(r->ctx));
        r->sur_n = 0; /* not captured: the next run checks again */
        return hl_fail(r->ctx, res, "%s: %s", hl_surroundings_name_(r->sur), why);
    }
    return HL_OK;
}

hl_result hl_relighter_set_env(hl_relighter *r, const hl_env *env)
{
    FORWARD_TO_PLANES(r, hl_relighter_set_env(p_, env));
    if (!env || !env->rgb || env->width == 0 || env->height == 0)
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "hl_relighter_set_env: no environment");
    float *cells = NULL;
    hl_result res = hl_env_to_cells(r->ctx, env, r->lg->wc, r->lg->hc, &cells);
    if (res != HL_OK) return res;
    if (r->cl) res = hl_cl_light_set_cells(r->cl, cells);
    if (res != HL_OK) {
        hl_free_big(cells);
        return res;
    }
    hl_free_big(r->cells);
    r->cells = cells;
    r->env_serial++;
    return HL_OK;
}

hl_result hl_selection_weights(hl_context *ctx, const hl_transport *t, const hl_light_geom *lg, uint32_t scheme,
                               float *w)
{
    const uint32_t nc = lg->ncoef;
    if (scheme == HL_SELECT_AREA && t->info.basis == HL_TRANSPORT_BASIS_SH) {
        /* every harmonic's support is the whole sphere; the slots past
           L^2 hold no lighting */
        for (uint32_t i = 0; i < nc; i++) w[i] = i < t->info.sh_order * t->info.sh_order ? (float)(4.0 * HL_PI) : 0.0f;
        return HL_OK;
    }
    if (scheme == HL_SELECT_AREA && t->info.basis == HL_TRANSPORT_BASIS_CUBE) {
        /* each face wavelet's support, a square of its face: its exact
           solid angle; the slots past 6 Cq^2 hold no lighting */
        const uint32_t Cq = t->info.sh_order, nt = 6 * Cq * Cq;
        hl_cube_support_areas(Cq, w);
        memset(w + nt, 0, (size_t)(nc - nt) * sizeof *w);
        return HL_OK;
    }
    if (scheme == HL_SELECT_AREA) {
        memcpy(w, lg->area, (size_t)nc * 4);
        return HL_OK;
    }
    if (scheme == HL_SELECT_UNWEIGHTED) {
        for (uint32_t i = 0; i < nc; i++) w[i] = 1.0f;
        return HL_OK;
    }
    if (scheme != HL_SELECT_TRANSPORT) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "unknown selection scheme %u", scheme);
    return transport_weights(ctx, t, nc, w, NULL);
}

/* The weights of a scheme (1 to HL_SELECT_TRANSPORT), made once. */
static hl_result scheme_weights(hl_relighter *r, uint32_t scheme, const float **out)
{
    if (!r->weights[scheme]) {
        float *w = hl_malloc(r->ctx, (size_t)r->g->ncoef * 4, "selection weights");
        if (!w) return HL_ERR_OUT_OF_MEMORY;
        hl_result res = hl_selection_weights(r->ctx, r->t, r->lg, scheme, w);
        if (res != HL_OK) {
            free(w);
            return res;
        }
        r->weights[scheme] = w;
    }
    *out = r->weights[scheme];
    return HL_OK;
}

static hl_result run_reference(hl_relighter *r, uint32_t s0, float f, hl_select_params sp, const float *weight,
                               int keep_negative, hl_select_result *sr)
{
    const hl_geom *g = r->g;
    const hl_transport *t = r->t;
    if (r->cube) {
        /* the face texels' mean radiance (3 planes of 6 Cq^2), then each
           face's Haar into the slots: the kernels' twins */
        hl_cube_lighting_haar(r->cube, r->cells, s0, f, g->ncoef, r->Lp, r->Lw);
    } else if (r->sur) {
        /* the surroundings over the environment (or black) */
        if (r->cells) hl_ref_env2para(r->cells, r->lg->wc, r->lg->tap_start, r->lg->taps, s0, f, g->ncoef, r->Lenv);
        r->cscene.fallback_L = r->cells ? r->Lenv : NULL;
        hl_result res = hl_capture_run(r->cap, &r->cscene, r->Lp);
        r->cscene.fallback_L = NULL;
        if (res != HL_OK) return res;
    } else {
        hl_ref_env2para(r->cells, r->lg->wc, r->lg->tap_start, r->lg->taps, s0, f, g->ncoef, r->Lp);
    }
    const uint32_t order = t->info.sh_order;
    for (int c = 0; c < 3 && !r->cube; c++) {
        float *Lp = r->Lp + (size_t)c * g->ncoef, *Lw = r->Lw + (size_t)c * g->ncoef;
        if (r->shY) hl_ref_sh_project_rows(Lp, g->ncoef, r->shY, hl_sh_stride(order), hl_sh_count(order), Lw);
        else hl_ref_haar(g, Lp, Lw);
    }
    *sr = hl_ref_select(r->Lw, g->ncoef, weight, sp, r->Lsel, r->used, r->bits, g->nblocks, r->keys);
    for (uint32_t v = 0; v < t->info.vertex_count; v++) {
        hl_ref_relight(t->entries + 2 * t->row_offset[v], t->block_counts + (size_t)v * g->nblocks, t->row_quant[v],
                       t->info.quant, v, g->nblocks, r->Lsel, r->albedo4 + 4 * (size_t)v, keep_negative,
                       r->B4 + 4 * (size_t)v);
    }
    return HL_OK;
}

/* How much negative light the dot products met (the fourth float of each
 * vertex: its lowest channel before the clamp), against the brightest
 * channel of all. */
static void negative_stats(uint32_t n, float lo, float hi, hl_relight_stats *st)
{
    st->negative_counted = 1;
    st->negative_vertices = n;
    st->most_negative = hi > 0.0f ? (double)lo / hi : (lo < 0.0f ? -1.0 : 0.0);
}

/* The clamp's count from the colours themselves (the reference; on
 * OpenCL the dot products tally it as they write them,
 * hl_cl_light_clamp_tally, which spares this pass: 0.4 ms of a dragon's
 * change). */
static void negative_light(const float *rgba, uint32_t V, uint32_t *negative, float *lowest, float *brightest)
{
    float lo = 0.0f, hi = 0.0f;
    uint32_t n = 0;
    for (uint32_t v = 0; v < V; v++) {
        const float *b = rgba + 4 * (size_t)v;
        if (b[3] < 0.0f) n++;
        if (b[3] < lo) lo = b[3];
        for (int c = 0; c < 3; c++)
            if (b[c] > hi) hi = b[c];
    }
    *negative = n;
    *lowest = lo;
    *brightest = hi;
}

/* What the selection kept, into st. */
static void selection_stats(const hl_relighter *r, const hl_select_result *sr, hl_relight_stats *st)
{
    double et = sr->energy_total, ek = sr->energy_kept;
    st->terms_kept = sr->kept;
    st->energy_kept = et > 0 ? ek / et : 1.0;
    /* the energies are of Y 2^-e (hl_light_energy_scale) */
    st->error_bound = r->max_row_norm * sqrt((double)sr->energy_dropped) * ldexp(1.0, (int)sr->energy_exp - 127);
    st->blocks_skipped = 1.0 - (double)sr->blocks_used / r->g->nblocks;
}

/* st made the worst of itself and one (first: st becomes one): the most
 * terms, the least energy kept, the largest bound, the fewest blocks
 * skipped, the largest parallax. */
static void worst_stats(hl_relight_stats *st, const hl_relight_stats *one, int first)
{
    if (first) *st = *one;
    st->terms_kept = one->terms_kept > st->terms_kept ? one->terms_kept : st->terms_kept;
    st->energy_kept = one->energy_kept < st->energy_kept ? one->energy_kept : st->energy_kept;
    st->error_bound = one->error_bound > st->error_bound ? one->error_bound : st->error_bound;
    st->blocks_skipped = one->blocks_skipped < st->blocks_skipped ? one->blocks_skipped : st->blocks_skipped;
    st->parallax = one->parallax > st->parallax ? one->parallax : st->parallax;
}

/* The capture points for the surroundings' current triangles (one, the
 * object's centre, without hl_relighter_set_probes: its bound is still
 * measured, for stats.parallax). */
static hl_result place_probes(hl_relighter *r)
{
    hl_probe_set_free(&r->probes);
    memcpy(r->cscene.center, r->centre, sizeof r->centre);
    if (r->reach < 0.0) r->reach = hl_probe_reach(r->t->mesh->positions, r->t->info.vertex_count, r->centre);
    hl_result res = hl_probe_set_build(r->ctx, r->t->mesh->positions, r->t->info.vertex_count, r->centre, r->reach,
                                       &r->cscene, r->probes_max, r->probe_tol, &r->probes);
    if (res == HL_OK) r->probes_stale = 0;
    return res;
}

/* A change under more than one capture point: each point's capture and
 * relight in turn (on either backend, as a run with one), each vertex's
 * colours added into blend4 with its weights, in the points' order. The
 * stats are the worst point's: the most terms, the least energy kept, the
 * largest bound, the fewest blocks skipped. */
static hl_result run_probes(hl_relighter *r, uint32_t s0, float f, hl_select_params sp, const float *weight,
                            int keep_negative, hl_relight_stats *st)
{
    const hl_probe_set *p = &r->probes;
    float *acc = r->blend4;
    memset(acc, 0, (size_t)r->t->info.vertex_count * 16);
    hl_result res = HL_OK;
    for (uint32_t k = 0; k < p->count && res == HL_OK; k++) {
        memcpy(r->cscene.center, p->points + 3 * (size_t)k, 12);
        const float *rgba = r->B4;
        hl_select_result sr;
        if (r->cl) {
            res = hl_cl_light_set_capture(r->cl, r->cap, &r->cscene, r->cells != NULL);
            if (res == HL_OK) res = hl_cl_light_run(r->cl, s0, f, sp, &rgba, &sr);
        } else {
            res = run_reference(r, s0, f, sp, weight, keep_negative, &sr);
        }
        if (res != HL_OK) break;
        for (uint32_t e = p->start[k]; e < p->start[k + 1]; e++) {
            const size_t v = p->vert[e];
            const float w = p->weight[e];
            for (int c = 0; c < 4; c++) acc[4 * v + c] += w * rgba[4 * v + c];
        }
        hl_relight_stats one = {0};
        selection_stats(r, &sr, &one);
        worst_stats(st, &one, k == 0);
    }
    memcpy(r->cscene.center, r->centre, sizeof r->centre);
    return res;
}

static hl_result run(hl_relighter *r, const hl_relight_desc *desc, float *vertex_rgb, void *out, int gl,
                     hl_relight_stats *stats);

/* A change with a row a channel: each channel's relighter in turn, each
 * vertex's channel c from plane c's (the others are zero there: their
 * albedo is), the fourth float the lowest of the three. The stats are the
 * worst plane's, as run_probes takes the worst point's; the negative
 * light is counted from the gathered colours. */
static hl_result run_planes(hl_relighter *r, const hl_relight_desc *desc, float *vertex_rgb, void *out, int gl,
                            hl_relight_stats *stats)
{
    const double t0 = hl_now();
    const uint32_t V = r->t->info.vertex_count;
    hl_relight_stats st = {0};
    int reused = 1;
    for (int c = 0; c < 3; c++) {
        hl_relight_stats one;
        hl_result res = run(r->sub[c], desc, NULL, NULL, 0, &one);
        if (res != HL_OK) return res;
        const float *p = r->sub[c]->rgba;
        for (uint32_t v = 0; v < V; v++) {
            float *q = r->sum4 + 4 * (size_t)v;
            q[c] = p[4 * (size_t)v + c];
            q[3] = c ? fminf(q[3], p[4 * (size_t)v + 3]) : p[4 * (size_t)v + 3];
        }
        reused &= one.reused;
        worst_stats(&st, &one, c == 0);
    }
    st.reused = reused;
    r->rgba = r->sum4;
    uint32_t n;
    float lo, hi;
    negative_light(r->sum4, V, &n, &lo, &hi);
    negative_stats(n, lo, hi, &st);
    if (out) {
        hl_result res = hl_cl_light_write_colours(r->sub[0]->cl, r->sum4, out, gl);
        if (res != HL_OK) return res;
    }
    if (vertex_rgb)
        for (uint32_t v = 0; v < V; v++)
            for (int c = 0; c < 3; c++) vertex_rgb[3 * (size_t)v + c] = r->sum4[4 * (size_t)v + c];
    st.seconds = hl_now() - t0;
    if (stats) *stats = st;
    return HL_OK;
}

/* A lighting change, its colours into rgba (and from there into vertex_rgb
 * when given) or, with out set, into that device buffer
 * (hl_cl_light_run_into). */
static hl_result run(hl_relighter *r, const hl_relight_desc *desc, float *vertex_rgb, void *out, int gl,
                     hl_relight_stats *stats)
{
    if (r->sub[0]) {
        if (out && !r->sub[0]->cl)
            return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "colours into a device buffer need the OpenCL backend");
        return run_planes(r, desc, vertex_rgb, out, gl, stats);
    }
    hl_relight_desc d = {0};
    if (desc) d = *desc;
    if (!d.terms) d.terms = 200;
    if (!d.select) d.select = HL_SELECT_TRANSPORT;
    if (d.select > HL_SELECT_TRANSPORT) return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "unknown selection scheme %u", d.select);
    if (!isfinite(d.rotate_deg)) return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "rotation is not a finite number");
    if (!r->cells && !r->sur)
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "no environment or surroundings set (hl_relighter_set_env)");
    if (r->sur) {
        hl_result res = take_surroundings(r);
        if (res != HL_OK) return res;
    }
    const uint32_t V = r->t->info.vertex_count;
    hl_relight_stats st = {0};
    double t0 = hl_now();
    if (out && !r->cl)
        return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "colours into a device buffer need the OpenCL backend");
    if (r->have_last && r->last_out == out && r->last_serial == r->env_serial && r->last.terms == d.terms &&
        r->last.select == d.select && r->last.rotate_deg == d.rotate_deg &&
        r->last.keep_negative == d.keep_negative) {
        st = r->last_stats;
        st.reused = 1;
        if (!out && r->cl && r->rgba != r->blend4) {
            hl_result res = hl_cl_light_colours(r->cl, &r->rgba);
            if (res != HL_OK) return res;
        }
    } else {
        const float *weight = NULL;
        hl_result res = scheme_weights(r, d.select, &weight);
        if (res == HL_OK && r->cl && r->uploaded_weights != d.select) {
            res = hl_cl_light_set_weights(r->cl, weight);
            if (res == HL_OK) r->uploaded_weights = d.select;
        }
        uint32_t s0;
        float f;
        hl_rotation_to_shift(d.rotate_deg, r->lg->wc, &s0, &f);
        hl_select_params sp = {d.terms, d.select, {0, 0}};
        hl_select_result sr;
        r->have_last = 0; /* rgba or out may be half written on failure */
        if (r->cl) hl_cl_light_keep_negative(r->cl, d.keep_negative);
        if (res == HL_OK && r->sur && r->probes_stale) res = place_probes(r);
        const int multi = res == HL_OK && r->sur && r->probes.count > 1;
        if (res == HL_OK && multi) {
            res = run_probes(r, s0, f, sp, weight, d.keep_negative, &st);
            r->rgba = r->blend4;
            /* the blend is the host's: into a device buffer as a write */
            if (res == HL_OK && out) res = hl_cl_light_write_colours(r->cl, r->blend4, out, gl);
        } else {
            if (res == HL_OK && r->cl)
                res = hl_cl_light_set_capture(r->cl, r->sur ? r->cap : NULL, &r->cscene, r->cells != NULL);
            if (res == HL_OK && out) res = hl_cl_light_run_into(r->cl, s0, f, sp, out, gl, &sr);
            else if (res == HL_OK)
                res = r->cl ? hl_cl_light_run(r->cl, s0, f, sp, &r->rgba, &sr)
                            : run_reference(r, s0, f, sp, weight, d.keep_negative, &sr);
            if (res == HL_OK) selection_stats(r, &sr, &st);
        }
        if (res != HL_OK) return res;
        if (!r->cl) r->rgba = multi ? r->blend4 : r->B4;
        if (!out) {
            uint32_t n;
            float lo, hi;
            if (r->cl && !multi) hl_cl_light_clamp_tally(r->cl, &n, &lo, &hi);
            else negative_light(r->rgba, V, &n, &lo, &hi);
            negative_stats(n, lo, hi, &st);
        }
        if (r->sur) {
            st.probes = r->probes.count;
            st.parallax = r->probes.worst_ratio;
        }
        r->have_last = 1;
        r->last_out = out;
        r->last = d;
        r->last_serial = r->env_serial;
        r->last_stats = st;
    }
    if (vertex_rgb)
        for (uint32_t v = 0; v < V; v++)
            for (int c = 0; c < 3; c++) vertex_rgb[3 * (size_t)v + c] = r->rgba[4 * (size_t)v + c];
    st.seconds = hl_now() - t0;
    if (stats) *stats = st;
    return HL_OK;
}

hl_result hl_relighter_run(hl_relighter *r, const hl_relight_desc *desc, float *vertex_rgb, hl_relight_stats *stats)
{
    return run(r, desc, vertex_rgb, NULL, 0, stats);
}

hl_result hl_relighter_run4(hl_relighter *r, const hl_relight_desc *desc, const float **rgba, hl_relight_stats *stats)
{
    hl_result res = run(r, desc, NULL, NULL, 0, stats);
    *rgba = res == HL_OK ? r->rgba : NULL;
    return res;
}

hl_result hl_relighter_run_into(hl_relighter *r, const hl_relight_desc *desc, void *cl_out, int gl,
                                hl_relight_stats *stats)
{
    if (!cl_out) return hl_fail(r->ctx, HL_ERR_INVALID_ARGUMENT, "no colour buffer given");
    return run(r, desc, NULL, cl_out, gl, stats);
}

hl_result hl_relighter_memory_use(const hl_relighter *r, hl_relighter_memory *m)
{
    if (!m) return HL_ERR_INVALID_ARGUMENT;
    memset(m, 0, sizeof *m);
    if (!r) return HL_ERR_INVALID_ARGUMENT;
    if (r->sub[0]) {
        /* the three planes' together */
        for (int c = 0; c < 3; c++) {
            hl_relighter_memory one;
            hl_result res = hl_relighter_memory_use(r->sub[c], &one);
            if (res != HL_OK) return res;
            m->device_bytes += one.device_bytes;
            m->column_bytes += one.column_bytes;
            m->parts = one.parts > m->parts ? one.parts : m->parts;
            m->resident = c ? (one.resident < m->resident ? one.resident : m->resident) : one.resident;
        }
        return HL_OK;
    }
    if (!r->cl) return HL_OK;
    m->device_bytes = hl_cl_light_device_bytes(r->cl);
    m->column_bytes = hl_cl_light_column_bytes(r->cl);
    m->parts = hl_cl_light_parts(r->cl);
    m->resident = (uint32_t)hl_cl_light_parts_resident(r->cl);
    return HL_OK;
}

/* With a row a channel, the red plane's (hl_relighter_planes gives all three). */
struct hl_cl_light *hl_relighter_device(hl_relighter *r) { return r ? (r->sub[0] ? r->sub[0]->cl : r->cl) : NULL; }

hl_result hl_bench_capture_cost(hl_relighter *r, uint32_t reps, hl_capture_cost *cost)
{
    memset(cost, 0, sizeof *cost);
    if (r && r->sub[0]) {
        /* each plane captures for itself: their times add */
        double sum = 0.0;
        for (int c = 0; c < 3; c++) {
            hl_result res = hl_bench_capture_cost(r->sub[c], reps, cost);
            if (res != HL_OK) return res;
            sum += cost->seconds;
        }
        cost->seconds = sum;
        return HL_OK;
    }
    if (!r || !r->cap || !r->sur_n)
        return hl_fail(r ? r->ctx : NULL, HL_ERR_INVALID_ARGUMENT, "no surroundings have been captured yet");
    if (!reps) reps = 1;
    hl_capture_usage(r->cap, &cost->triangles, &cost->host_bytes, &cost->device_bytes);
    if (r->cl) return hl_cl_light_time_capture(r->cl, reps, &cost->seconds);
    /* the reference: the same capture again, into a map of its own */
    float *L = hl_malloc(r->ctx, (size_t)r->g->ncoef * 12, "a captured map");
    if (!L) return HL_ERR_OUT_OF_MEMORY;
    r->cscene.fallback_L = r->cells ? r->Lenv : NULL;
    hl_result res = HL_OK;
    const double t0 = hl_now();
    for (uint32_t k = 0; k < reps && res == HL_OK; k++) res = hl_capture_run(r->cap, &r->cscene, L);
    cost->seconds = (hl_now() - t0) / reps;
    r->cscene.fallback_L = NULL;
    free(L);
    return res;
}
const hl_light_geom *hl_relighter_tables(const hl_relighter *r) { return r ? (r->sub[0] ? r->sub[0]->lg : r->lg) : NULL; }
