/* precompute.c - mesh to transport file, chunk by chunk.
 *
 * Per chunk: Embree visibility on the host, then the four stages (OpenCL or
 * the plain-C twins), then the rows are appended to the file. With OpenCL
 * the device works on chunk k while the host casts the rays of chunk k+1;
 * two host slots make that safe. Memory is bounded by the chunk size.
 * A shard (hl_precompute_shard) runs the same chunks over its own range of
 * vertices only and writes a shard file, which merge.c joins with the
 * others; every row depends on its vertex alone (its rays, and the dither
 * key of its global index), so the joined rows are those of one run.
 * With --basis sh the rows are projected onto spherical harmonics
 * (hl_sh_matrix) where Haar would run; with --basis cube-haar they are made
 * on the cube's faces (hl_cube_rows) and go through the faces' Haar
 * (hl_cube_haar) instead of cube2para and Haar. Truncation, quantisation
 * and the blocks are the same.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bounce.h"
#include "values_file.h"
#include "cube.h"
#include "haarlight_tools.h"
#include "precompute.h"
#include "rays.h"
#include "sh.h"
#include "twins.h"
#include "transport_file.h"

hl_result hl_precompute_resolve(hl_context *ctx, hl_precompute_desc *d)
{
    if (!d->N) d->N = HL_DEFAULT_N;
    if (!d->C) d->C = HL_DEFAULT_C;
    if (!d->supersample) d->supersample = 1;
    if (!d->rule) d->rule = HL_TRUNC_ENERGY;
    if (d->rule == HL_TRUNC_ENERGY && d->eps == 0.0f) d->eps = HL_DEFAULT_EPS;
    if (!d->quant) d->quant = HL_DEFAULT_QUANT;
    if (!d->chunk) d->chunk = HL_DEFAULT_CHUNK;
    if (d->N < 8 || d->N > 256 || (d->N & (d->N - 1)))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "N = %u: the paraboloid resolution must be a power of two from 8 to 256", d->N);
    if (d->C < 4 || d->C > 512)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "C = %u: the cubemap resolution must be from 4 to 512", d->C);
    if (d->supersample > 15)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "supersample = %u: must be 1 to 15", d->supersample);
    if (d->rule != HL_TRUNC_ALL && d->rule != HL_TRUNC_TOPK && d->rule != HL_TRUNC_ENERGY)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "unknown truncation rule %u", d->rule);
    if (!(d->eps >= 0.0f && d->eps < 1.0f))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "eps = %g: the dropped energy fraction must be in [0, 1)", (double)d->eps);
    if (d->quant < HL_QUANT_LINEAR8 || d->quant > HL_QUANT_MAX)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "unknown quantisation scheme %u", d->quant);
    if (!(d->ray_offset >= 0.0f && d->ray_offset < 0.1f))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "ray offset %g: must be 0 (robust, the default) or in (0, 0.1) of the bounding-box diagonal",
                       (double)d->ray_offset);
    if (d->basis != HL_TRANSPORT_BASIS_HAAR && d->basis != HL_TRANSPORT_BASIS_SH && d->basis != HL_TRANSPORT_BASIS_CUBE)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "basis %u: must be 0 (Haar), 1 (spherical harmonics) or 2 (cube-face Haar)", d->basis);
    if (d->basis != HL_TRANSPORT_BASIS_CUBE && d->cube_side)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "cube side %u given for basis %u (--cube-side needs --basis cube-haar)",
                       d->cube_side, d->basis);
    if (d->basis == HL_TRANSPORT_BASIS_CUBE && d->sh_order)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "spherical-harmonic order %u given for cube-face Haar (--sh-order needs --basis sh)", d->sh_order);
    if (d->basis == HL_TRANSPORT_BASIS_CUBE) {
        /* the largest side that fits the slots and cuts the visibility
           cube into whole texels, as bench-basis chooses it */
        const uint32_t q = d->cube_side ? d->cube_side : hl_cube_default_side(d->N, d->C);
        if (q < 2 || q > 512 || (q & (q - 1)) || d->C % q || 6 * q * q > 2 * d->N * d->N)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "cube side %u: must be a power of two from 2 to 512 that divides C = %u, with its 6 C'^2 "
                           "coefficients at most the 2 N^2 = %u slots of N = %u",
                           q, d->C, 2 * d->N * d->N, d->N);
        d->cube_side = q;
    }
    if (d->basis == HL_TRANSPORT_BASIS_HAAR && d->sh_order)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "spherical-harmonic order %u given for the Haar basis (--sh-order needs --basis sh)", d->sh_order);
    if (d->basis == HL_TRANSPORT_BASIS_SH && !d->sh_order) d->sh_order = HL_DEFAULT_SH_ORDER;
    if (d->basis == HL_TRANSPORT_BASIS_SH &&
        (d->sh_order > HL_SH_MAX_ORDER || d->sh_order * d->sh_order > 2 * d->N * d->N))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "spherical-harmonic order %u: must be 1 to %u with order^2 at most the 2 N^2 = %u slots of N = %u",
                       d->sh_order, HL_SH_MAX_ORDER, 2 * d->N * d->N, d->N);
    if (d->bounces > HL_MAX_BOUNCES)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "bounces = %u: at most %u", d->bounces, HL_MAX_BOUNCES);
    if (d->bounce_rays > 4096)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "bounce rays = %u: at most 4096 a vertex", d->bounce_rays);
    if (d->chunk > (1u << 20))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "chunk = %u: at most %u vertices", d->chunk, 1u << 20);
    return HL_OK;
}

hl_trunc_params hl_precompute_trunc_params(const hl_precompute_desc *d)
{
    hl_trunc_params p = {d->rule, d->K, (uint32_t)lrintf(d->eps * 1048576.0f), 0};
    return p;
}

hl_result hl_chunk_buf_alloc(hl_context *ctx, const hl_geom *g, uint32_t R, hl_chunk_buf *b)
{
    memset(b, 0, sizeof *b);
    b->vis = hl_alloc_big(ctx, (size_t)R * g->ncube, "visibility");
    b->normals4 = hl_alloc_big(ctx, (size_t)R * 16, "normals");
    b->tr = hl_alloc_big(ctx, (size_t)R * sizeof *b->tr, "truncation results");
    b->rq = hl_alloc_big(ctx, (size_t)R * sizeof *b->rq, "quantisation parameters");
    b->bc = hl_alloc_big(ctx, (size_t)R * g->nblocks * 2, "block counts");
    b->entries = hl_alloc_big(ctx, (size_t)R * g->ncoef * 2, "entries");
    b->nnz = hl_alloc_big(ctx, (size_t)R * 4, "entry counts");
    if (!b->vis || !b->normals4 || !b->tr || !b->rq || !b->bc || !b->entries || !b->nnz) {
        hl_chunk_buf_free(b);
        return HL_ERR_OUT_OF_MEMORY;
    }
    return HL_OK;
}

void hl_chunk_buf_free(hl_chunk_buf *b)
{
    hl_free_big(b->vis);
    hl_free_big(b->normals4);
    hl_free_big(b->tr);
    hl_free_big(b->rq);
    hl_free_big(b->bc);
    hl_free_big(b->entries);
    hl_free_big(b->nnz);
    hl_free_big(b->coef);
    memset(b, 0, sizeof *b);
}

/* ------------------------------------------------ reference, threaded */

typedef struct ref_job {
    const hl_geom *g;
    const float *shY; /* the harmonic projection (hl_sh_matrix); NULL: Haar */
    uint32_t sh_stride, sh_count;
    uint32_t cube;    /* cube-face Haar: the faces' side; 0: none */
    uint32_t rows;
    float scale;
    hl_trunc_params tp;
    uint32_t scheme;
    const hl_chunk_buf *io;
    atomic_uint next;
    atomic_int oom;
} ref_job;

static void *ref_worker(void *arg)
{
    ref_job *j = arg;
    const hl_geom *g = j->g;
    float *T = malloc((size_t)g->ncoef * sizeof(float)), *coef = malloc((size_t)g->ncoef * sizeof(float));
    hl_ref_key *keys = malloc((size_t)g->ncoef * sizeof *keys); /* hl_ref_truncate's, for every row */
    if (!T || !coef || !keys) {
        atomic_store(&j->oom, 1);
        free(T);
        free(coef);
        free(keys);
        return NULL;
    }
    for (;;) {
        uint32_t v = atomic_fetch_add(&j->next, 1u);
        if (v >= j->rows) break;
        const hl_chunk_buf *io = j->io;
        if (j->cube) {
            /* the kernels' twins (cube_haar.cl): the faces' rows and Haar,
               the slots past the 6 Cq^2 coefficients empty */
            const uint32_t nt = 6 * j->cube * j->cube;
            hl_cube_rows(g, j->cube, io->vis + (size_t)v * g->ncube, j->scale, io->normals4 + 4 * (size_t)v, T);
            hl_cube_haar(j->cube, T, coef);
            memset(coef + nt, 0, (size_t)(g->ncoef - nt) * sizeof(float));
        } else {
            hl_ref_cube2para(g, io->vis + (size_t)v * g->ncube, j->scale, io->normals4 + 4 * (size_t)v, T);
            if (j->shY) hl_ref_sh_project_rows(T, g->ncoef, j->shY, j->sh_stride, j->sh_count, coef);
            else hl_ref_haar(g, T, coef);
        }
        io->tr[v] = hl_ref_truncate(g, coef, j->tp, keys);
        io->nnz[v] = hl_ref_quantize(g, coef, io->tr[v], j->scheme, io->first + v, &io->rq[v],
                                     io->bc + (size_t)v * g->nblocks, io->entries + (size_t)v * g->ncoef * 2);
        if (io->coef) memcpy(io->coef + (size_t)v * g->ncoef, coef, (size_t)g->ncoef * sizeof(float));
    }
    free(T);
    free(coef);
    free(keys);
    return NULL;
}

hl_result hl_ref_rows(hl_context *ctx, const hl_geom *g, uint32_t rows, float vis_scale, hl_trunc_params tp,
                      uint32_t scheme, const hl_chunk_buf *io)
{
    return hl_ref_rows_basis(ctx, g, NULL, 0, 0, rows, vis_scale, tp, scheme, io);
}

hl_result hl_ref_rows_basis(hl_context *ctx, const hl_geom *g, const float *shY, uint32_t sh_order, uint32_t cube,
                            uint32_t rows, float vis_scale, hl_trunc_params tp, uint32_t scheme, const hl_chunk_buf *io)
{
    ref_job j = {.g = g, .shY = shY, .sh_stride = hl_sh_stride(sh_order), .sh_count = hl_sh_count(sh_order),
                 .cube = cube, .rows = rows, .scale = vis_scale, .tp = tp, .scheme = scheme, .io = io};
    atomic_init(&j.next, 0u);
    atomic_init(&j.oom, 0);
    hl_run_threads(ctx->threads, ref_worker, &j);
    if (atomic_load(&j.oom))
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference stages' scratch (%zu bytes per thread)",
                       (size_t)g->ncoef * (2 * sizeof(float) + sizeof(hl_ref_key)));
    return HL_OK;
}

/* ------------------------------------------------ the whole run */

/* On a terminal a line rewritten in place after every chunk; otherwise
 * (a batch job's log) a whole line every HL_PROGRESS_EVERY seconds and at
 * the end, so that a log shows the rate and the time left without a line
 * a chunk. */
#define HL_PROGRESS_EVERY 30.0
static void progress(hl_context *ctx, uint32_t done, uint32_t total, uint64_t rays, double t_rays, double t0,
                     double *shown)
{
    if (ctx->quiet) return;
    const int tty = isatty(2);
    const double now = hl_now(), el = now - t0, eta = done ? el * (double)(total - done) / done : 0.0;
    if (!tty && done < total && now - *shown < HL_PROGRESS_EVERY) return;
    *shown = now;
    fprintf(stderr, "%sprecompute: %u/%u vertices (%3.0f%%), %.1f Mrays/s, ETA %.0f s%s", tty ? "\r" : "", done, total,
            100.0 * done / total, t_rays > 0 ? (double)rays / t_rays * 1e-6 : 0.0, eta, tty ? "   " : "\n");
    if (tty && done == total) fputc('\n', stderr);
}

static void fill_normals(const hl_mesh *m, uint32_t first, uint32_t count, float *n4)
{
    for (uint32_t i = 0; i < count; i++) {
        const float *n = m->normals + 3 * (size_t)(first + i);
        n4[4 * i] = n[0];
        n4[4 * i + 1] = n[1];
        n4[4 * i + 2] = n[2];
        n4[4 * i + 3] = 0.0f;
    }
}

/* One run's state, shared by its phases: open, the chunk loop, close. */
typedef struct pc_run {
    hl_context *ctx;
    const hl_mesh *mesh;
    const char *out_path;
    hl_precompute_desc d;
    hl_precompute_stats st;
    double t_start, t_shown; /* t_shown: the last progress line */
    hl_geom *g;
    hl_rt *rt;
    hl_cl_pipe *pipe;
    float *shY;        /* spherical harmonics: the projection (hl_sh_matrix) */
    hl_tfile_writer *w;
    hl_vfile_writer *vw; /* --keep-floats: the values file */
    hl_chunk_buf buf[2];
    uint32_t V, R;
    uint32_t shard_index, shard_count; /* count 0: the whole mesh */
    uint32_t lo, hi;  /* the vertices [lo, hi) this run computes */
    uint32_t start; /* the first vertex not yet written (lo, or later on resume) */
    uint32_t nchunks;
    float offset, vis_scale;
    hl_trunc_params tp;
    hl_vis_counts vc, vc_done; /* vc_done: rays of the vertices appended */
    hl_vis_counts vc_resumed;  /* rays of a resumed file's earlier runs */
    hl_transport_info info;
} pc_run;

/* The file's header fields known before the first row. */
static void fill_info(pc_run *u)
{
    const hl_precompute_desc *d = &u->d;
    hl_transport_info *info = &u->info;
    info->N = d->N;
    info->C = d->C;
    info->supersample = d->supersample;
    info->rule = d->rule;
    info->K = d->K;
    info->eps = d->rule == HL_TRUNC_ENERGY ? d->eps : 0.0f;
    info->quant = d->quant;
    info->ray_offset = d->ray_offset;
    info->vertex_count = u->V;
    info->object_vertex_count = u->mesh->object_vertex_count;
    info->triangle_count = u->mesh->triangle_count;
    info->block_count = u->g->nblocks;
    info->basis = d->basis;
    info->sh_order = d->basis == HL_TRANSPORT_BASIS_SH ? d->sh_order : d->basis == HL_TRANSPORT_BASIS_CUBE ? d->cube_side : 0;
}

/* With --resume, the writer of out_path.partial and where it stopped (no
 * writer when there is nothing to resume). */
static hl_result resume_writer(pc_run *u)
{
    hl_tfile_progress done;
    hl_result r = hl_tfile_writer_resume_shard(u->ctx, u->out_path, &u->info, u->mesh, u->shard_index,
                                               u->shard_count, &u->w, &done);
    if (r == HL_OK && u->w) {
        u->start = u->lo + done.appended;
        u->st.coefficients_kept = done.coefficients;
        u->vc.rays_cast = u->vc_done.rays_cast = done.rays_cast;
        u->vc.rays_culled = u->vc_done.rays_culled = done.rays_culled;
        u->vc_resumed = u->vc;
        u->nchunks = (u->hi - u->start + u->R - 1) / u->R;
        if (!u->ctx->quiet && u->shard_count)
            fprintf(stderr, "precompute: resuming %s.partial at vertex %u (shard %u/%u: vertices %u..%u)\n",
                    u->out_path, u->start, u->shard_index, u->shard_count, u->lo, u->hi - 1);
        else if (!u->ctx->quiet)
            fprintf(stderr, "precompute: resuming %s.partial at vertex %u of %u\n", u->out_path, u->start, u->V);
    } else if (r == HL_OK && !u->ctx->quiet) {
        fprintf(stderr, "precompute: no %s.partial to resume; starting from the beginning\n", u->out_path);
    }
    return r;
}

/* Tables, ray tracer, host chunk buffers, device pipeline and the writer. */
static hl_result run_open(pc_run *u)
{
    hl_context *ctx = u->ctx;
    hl_result r = hl_geom_create(ctx, u->d.N, u->d.C, &u->g);
    if (r == HL_OK) r = hl_rt_create(ctx, u->mesh, &u->rt);
    if (r == HL_OK) r = hl_chunk_buf_alloc(ctx, u->g, u->R, &u->buf[0]);
    if (r == HL_OK) r = hl_chunk_buf_alloc(ctx, u->g, u->R, &u->buf[1]);
    for (int s = 0; s < 2 && r == HL_OK && u->d.keep_floats; s++)
        if (!(u->buf[s].coef = hl_alloc_big(ctx, (size_t)u->R * u->g->ncoef * 4, "the coefficients (--keep-floats)")))
            r = HL_ERR_OUT_OF_MEMORY;
    if (r == HL_OK && u->d.basis == HL_TRANSPORT_BASIS_SH) r = hl_sh_matrix(ctx, u->d.N, u->d.sh_order, 1, &u->shY);
    if (r == HL_OK && ctx->backend == HL_BACKEND_OPENCL) r = hl_cl_pipe_create(ctx, u->g, u->R, &u->pipe);
    if (r == HL_OK && u->pipe && u->shY)
        r = hl_cl_pipe_set_sh(u->pipe, u->shY, hl_sh_stride(u->d.sh_order), hl_sh_count(u->d.sh_order));
    if (r == HL_OK && u->pipe && u->d.basis == HL_TRANSPORT_BASIS_CUBE) r = hl_cl_pipe_set_cube(u->pipe, u->d.cube_side);
    if (r == HL_OK) {
        fill_info(u);
        if (u->d.resume) r = resume_writer(u);
        const int resumed = u->w != NULL;
        if (r == HL_OK && !u->w)
            r = hl_tfile_writer_open_shard(ctx, u->out_path, &u->info, u->mesh, u->shard_index, u->shard_count, &u->w);
        if (r == HL_OK && u->d.keep_floats) {
            r = hl_vfile_writer_open(ctx, u->out_path, u->lo, u->hi - u->lo, resumed, u->st.coefficients_kept, &u->vw);
            /* a resume refused for its floats leaves the rows' partial file as it was */
            if (r != HL_OK && resumed) {
                hl_tfile_writer_keep(u->w);
                u->w = NULL;
            }
        }
    }
    return r;
}

/* The visibility rows of count vertices from first into slot s. */
static hl_result cast_chunk(pc_run *u, int s, uint32_t first, uint32_t count)
{
    double t0 = hl_now();
    fill_normals(u->mesh, first, count, u->buf[s].normals4);
    hl_result r = hl_rt_visibility(u->rt, u->g, u->mesh, first, count, u->d.supersample, u->offset, u->buf[s].vis, &u->vc);
    u->st.seconds_rays += hl_now() - t0;
    return r;
}

/* The chunk's rows into the file (and their floats into the values
 * file), then a checkpoint with the rays counted so far (vc). */
static hl_result append_rows(pc_run *u, const hl_chunk_buf *b, uint32_t count, hl_vis_counts vc)
{
    const uint32_t nc = u->g->ncoef;
    hl_result r = hl_tfile_writer_append(u->w, count, b->rq, b->bc, b->entries, (size_t)nc * 2, b->nnz);
    if (r == HL_OK && u->vw)
        r = hl_vfile_writer_append(u->vw, count, b->coef, nc, b->bc, u->g->nblocks, b->entries, (size_t)nc * 2, b->nnz);
    for (uint32_t i = 0; i < count; i++) u->st.coefficients_kept += b->nnz[i];
    u->vc_done = vc;
    /* the floats on disk before the checkpoint that counts them */
    if (r == HL_OK && u->vw) r = hl_vfile_writer_sync(u->vw);
    if (r == HL_OK) r = hl_tfile_writer_checkpoint(u->w, u->vc_done.rays_cast, u->vc_done.rays_culled);
    return r;
}

/* Waits for the device's chunk k in slot s and appends its rows; the rays
 * counted before the next chunk was cast (vc_before) are the ones its
 * checkpoint records. */
static hl_result append_device_chunk(pc_run *u, int s, uint32_t k, hl_vis_counts vc_before)
{
    double t0 = hl_now();
    hl_result r = hl_cl_pipe_wait(u->pipe, s);
    u->st.seconds_kernels += hl_now() - t0;
    if (r != HL_OK) return r;
    const hl_chunk_buf *b = &u->buf[s];
    uint32_t pf = u->start + k * u->R, pc = u->hi - pf < u->R ? u->hi - pf : u->R;
    /* the rays of chunk k are cast but its rows are not written */
    r = append_rows(u, b, pc, vc_before);
    if (r != HL_OK) return r;
    progress(u->ctx, pf + pc - u->lo, u->hi - u->lo, u->vc.rays_cast, u->st.seconds_rays, u->t_start, &u->t_shown);
    return HL_OK;
}

/* The four stages on the chunk in slot s: submitted to the device (its
 * rows are appended when the next chunk's rays are cast), or run by the
 * twins and appended now. */
static hl_result run_chunk(pc_run *u, int s, uint32_t first, uint32_t count)
{
    hl_chunk_buf *b = &u->buf[s];
    b->first = first;
    if (u->pipe) return hl_cl_pipe_submit(u->pipe, s, count, u->vis_scale, u->tp, u->d.quant, b);
    double t0 = hl_now();
    hl_result r = hl_ref_rows_basis(u->ctx, u->g, u->shY, u->d.sh_order, u->d.basis == HL_TRANSPORT_BASIS_CUBE ? u->d.cube_side : 0, count, u->vis_scale, u->tp, u->d.quant, b);
    u->st.seconds_kernels += hl_now() - t0;
    if (r == HL_OK) r = append_rows(u, b, count, u->vc);
    progress(u->ctx, first + count - u->lo, u->hi - u->lo, u->vc.rays_cast, u->st.seconds_rays, u->t_start, &u->t_shown);
    return r;
}

/* Chunk k's rays are cast while the device runs chunk k-1. */
static hl_result run_chunks(pc_run *u)
{
    hl_result r = HL_OK;
    for (uint32_t k = 0; r == HL_OK && k <= u->nchunks; k++) {
        int s = (int)(k & 1u);
        uint32_t first = u->start + k * u->R;
        uint32_t count = k < u->nchunks ? (u->hi - first < u->R ? u->hi - first : u->R) : 0;
        hl_vis_counts vc_before = u->vc;
        if (k < u->nchunks && (r = cast_chunk(u, s, first, count)) != HL_OK) break;
        if (u->pipe && k > 0 && (r = append_device_chunk(u, 1 - s, k - 1, vc_before)) != HL_OK) break;
        if (k == u->nchunks) break;
        r = run_chunk(u, s, first, count);
        if (r == HL_OK && hl_context_cancelled(u->ctx)) r = HL_ERR_INTERRUPTED;
    }
    return r;
}

/* Finishes the file (or keeps or removes the partial one), frees the
 * run's resources and fills the statistics. */
static hl_result run_close(pc_run *u, hl_result r, hl_precompute_stats *stats)
{
    if (r == HL_ERR_INTERRUPTED && u->w)
        hl_fail(u->ctx, HL_ERR_INTERRUPTED,
                "interrupted: %s not written; %u of %u vertices are kept in %s.partial (run again with --resume "
                "to continue)",
                u->out_path, hl_tfile_writer_appended(u->w), u->hi - u->lo, u->out_path);
    if (r == HL_OK) {
        u->info.coefficients_kept = u->st.coefficients_kept;
        u->info.rays_cast = u->vc.rays_cast;
        u->info.rays_culled = u->vc.rays_culled;
        if (u->vw) r = hl_vfile_writer_finish(u->vw);
        u->vw = NULL;
        if (r == HL_OK) r = hl_tfile_writer_finish(u->w, &u->info);
        else hl_tfile_writer_abort(u->w);
        u->w = NULL;
    }
    hl_vfile_writer_close(u->vw, r == HL_ERR_INTERRUPTED);
    if (r == HL_OK && !u->d.keep_floats) {
        /* an earlier --keep-floats run's floats are not this file's */
        char old[4096 + 8];
        if ((size_t)snprintf(old, sizeof old, "%s.values", u->out_path) < sizeof old) unlink(old);
    }
    /* an interrupted run keeps its partial file for --resume; any other
       failure removes it */
    if (u->w && r == HL_ERR_INTERRUPTED) hl_tfile_writer_keep(u->w);
    else if (u->w) hl_tfile_writer_abort(u->w);
    hl_cl_pipe_destroy(u->pipe);
    hl_free_big(u->shY);
    hl_chunk_buf_free(&u->buf[0]);
    hl_chunk_buf_free(&u->buf[1]);
    hl_rt_destroy(u->rt);
    hl_geom_destroy(u->g);
    u->st.rays_cast = u->vc.rays_cast - u->vc_resumed.rays_cast; /* by this run */
    u->st.rays_culled = u->vc.rays_culled - u->vc_resumed.rays_culled;
    u->st.seconds_total = hl_now() - u->t_start;
    if (stats) *stats = u->st;
    return r;
}

static hl_result precompute_bounced(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *d,
                                    const char *out_path, hl_precompute_stats *stats);

/* --bounces with --direct-rows: the bounce phase alone, from that finished
 * direct file (which stays), for the whole mesh or one shard. */
static hl_result bounces_from(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *d, uint32_t shard_index,
                              uint32_t shard_count, const char *out_path, hl_precompute_stats *stats)
{
    double sec = 0.0;
    uint64_t kept = 0;
    hl_result r = hl_bounce_check_albedo(ctx, mesh);
    if (r == HL_OK) r = hl_bounce_file(ctx, d, mesh, d->direct_rows, shard_index, shard_count, out_path, &sec, &kept);
    if (stats) {
        stats->seconds_bounces = stats->seconds_total = sec;
        if (r == HL_OK) stats->coefficients_kept = kept;
    }
    return r;
}

hl_result hl_precompute_shard(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *desc,
                              uint32_t shard_index, uint32_t shard_count, const char *out_path,
                              hl_precompute_stats *stats)
{
    pc_run u = {.ctx = ctx, .mesh = mesh, .out_path = out_path, .shard_index = shard_index, .shard_count = shard_count};
    if (stats) memset(stats, 0, sizeof *stats);
    if (desc) u.d = *desc;
    hl_result r = hl_precompute_resolve(ctx, &u.d);
    if (r != HL_OK) return r;
    if (!mesh || mesh->vertex_count == 0 || mesh->triangle_count == 0)
        return hl_fail(ctx, HL_ERR_MESH, "the mesh is empty");
    if (u.d.direct_rows && !u.d.bounces)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--direct-rows %s: only the bounces start from direct rows "
                       "(give --bounces B)", u.d.direct_rows);
    if (u.d.keep_floats && u.d.bounces)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "--keep-floats with --bounces: the floats are kept for the bounces of a later --direct-rows run; "
                       "a bounced file's rows are not direct rows (--bounces keeps the floats between its own phases)");
    if (u.d.bounces && shard_count && !u.d.direct_rows)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "--bounces with --shard: the bounces read every vertex's direct rows, so they shard as a second "
                       "phase: shard and merge the direct precompute (no --bounces), then run --bounces B --direct-rows "
                       "MERGED.hlt --shard I/N and merge those (docs/BOUNCES.md)");
    if (shard_count && (shard_index >= shard_count || shard_count > mesh->vertex_count))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "shard %u/%u: the index must be below the count, and the count from 1 to the mesh's %u "
                       "vertices", shard_index, shard_count, mesh->vertex_count);
    if (u.d.bounces && u.d.direct_rows) return bounces_from(ctx, mesh, &u.d, shard_index, shard_count, out_path, stats);
    if (u.d.bounces) return precompute_bounced(ctx, mesh, &u.d, out_path, stats);
    u.V = mesh->vertex_count;
    u.lo = 0;
    u.hi = u.V;
    if (shard_count) hl_shard_range(u.V, shard_index, shard_count, &u.lo, &u.hi);
    u.t_start = u.t_shown = hl_now();
    u.start = u.lo;
    u.R = u.d.chunk < u.hi - u.lo ? u.d.chunk : u.hi - u.lo;
    u.nchunks = (u.hi - u.lo + u.R - 1) / u.R;
    u.offset = u.d.ray_offset * hl_mesh_query_diagonal(mesh); /* 0: robust */
    u.vis_scale = (float)(1.0 / (HL_PI * u.d.supersample * u.d.supersample));
    u.tp = hl_precompute_trunc_params(&u.d);
    r = run_open(&u);
    if (r == HL_OK) r = run_chunks(&u);
    return run_close(&u, r, stats);
}

hl_result hl_precompute(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *desc,
                        const char *out_path, hl_precompute_stats *stats)
{
    return hl_precompute_shard(ctx, mesh, desc, 0, 0, out_path, stats);
}

/* --bounces: the direct rows into OUT.direct.hlt (resumable as any run),
 * then the bounce phase from them into OUT; the direct file is removed
 * once OUT is written. */
static hl_result precompute_bounced(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *d,
                                    const char *out_path, hl_precompute_stats *stats)
{
    char direct[4096];
    if ((size_t)snprintf(direct, sizeof direct, "%s.direct.hlt", out_path) >= sizeof direct)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: the path is too long", out_path);
    /* checked before the direct rays, not after them */
    hl_result r = hl_bounce_check_albedo(ctx, mesh);
    if (r != HL_OK) return r;
    hl_precompute_desc dd = *d;
    dd.bounces = 0;
    dd.keep_floats = 1; /* the bounces start from the floats, not the codes */
    char values[4096 + 8];
    snprintf(values, sizeof values, "%s.values", direct);
    const double t0 = hl_now();
    /* --resume after the direct rows were done: the bounces only */
    if (d->resume && access(direct, F_OK) == 0) {
        if (!ctx->quiet) fprintf(stderr, "precompute: resuming with the direct rows of %s\n", direct);
        if (stats) memset(stats, 0, sizeof *stats);
    } else {
        r = hl_precompute_shard(ctx, mesh, &dd, 0, 0, direct, stats);
    }
    double sec = 0.0;
    uint64_t kept = 0;
    if (r == HL_OK) r = hl_bounce_file(ctx, d, mesh, direct, 0, 0, out_path, &sec, &kept);
    /* kept only for --resume after an interruption */
    if (r != HL_ERR_INTERRUPTED) {
        unlink(direct);
        unlink(values);
    }
    if (stats) {
        stats->seconds_bounces = sec;
        if (r == HL_OK) stats->coefficients_kept = kept;
        stats->seconds_total = hl_now() - t0;
    }
    return r;
}
