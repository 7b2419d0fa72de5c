/* precompute.c - mesh to transport file, chunk by chunk.
 *
 * Per chunk: Embree visibility on the host, then the four stages (OpenCL or
 * the plain-C twins), then the rows are appended to the file. With OpenCL
 * the device works on chunk k while the host casts the rays of chunk k+1;
 * two host slots make that safe. Memory is bounded by the chunk size.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "precompute.h"
#include "rays.h"
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
    memset(b, 0, sizeof *b);
}

/* ------------------------------------------------ reference, threaded */

typedef struct ref_job {
    const hl_geom *g;
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
        hl_ref_cube2para(g, io->vis + (size_t)v * g->ncube, j->scale, io->normals4 + 4 * (size_t)v, T);
        hl_ref_haar(g, T, coef);
        io->tr[v] = hl_ref_truncate(g, coef, j->tp, keys);
        io->nnz[v] = hl_ref_quantize(g, coef, io->tr[v], j->scheme, io->first + v, &io->rq[v],
                                     io->bc + (size_t)v * g->nblocks, io->entries + (size_t)v * g->ncoef * 2);
    }
    free(T);
    free(coef);
    free(keys);
    return NULL;
}

hl_result hl_ref_rows(hl_context *ctx, const hl_geom *g, uint32_t rows, float vis_scale, hl_trunc_params tp,
                      uint32_t scheme, const hl_chunk_buf *io)
{
    ref_job j = {.g = g, .rows = rows, .scale = vis_scale, .tp = tp, .scheme = scheme, .io = io};
    atomic_init(&j.next, 0u);
    atomic_init(&j.oom, 0);
    hl_run_threads(ctx->threads, ref_worker, &j);
    if (atomic_load(&j.oom))
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference stages' scratch (%zu bytes per thread)",
                       (size_t)g->ncoef * (2 * sizeof(float) + sizeof(hl_ref_key)));
    return HL_OK;
}

/* ------------------------------------------------ the whole run */

static void progress(hl_context *ctx, uint32_t done, uint32_t total, uint64_t rays, double t_rays, double t0)
{
    if (ctx->quiet || !isatty(2)) return;
    double el = hl_now() - t0, eta = done ? el * (double)(total - done) / done : 0.0;
    fprintf(stderr, "\rprecompute: %u/%u vertices (%3.0f%%), %.1f Mrays/s, ETA %.0f s   ", done, total,
            100.0 * done / total, t_rays > 0 ? (double)rays / t_rays * 1e-6 : 0.0, eta);
    if (done == total) fputc('\n', stderr);
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

hl_result hl_precompute(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *desc,
                        const char *out_path, hl_precompute_stats *stats)
{
    hl_precompute_desc d = {0};
    if (desc) d = *desc;
    hl_result r = hl_precompute_resolve(ctx, &d);
    if (r != HL_OK) return r;
    if (!mesh || mesh->vertex_count == 0 || mesh->triangle_count == 0)
        return hl_fail(ctx, HL_ERR_MESH, "the mesh is empty");
    double t_start = hl_now();
    hl_precompute_stats st = {0};
    hl_geom *g = NULL;
    hl_rt *rt = NULL;
    hl_cl_pipe *pipe = NULL;
    hl_tfile_writer *w = NULL;
    hl_chunk_buf buf[2] = {{0}};
    const uint32_t V = mesh->vertex_count, R = d.chunk < V ? d.chunk : V;
    uint32_t start = 0; /* vertices already written (resume) */
    uint32_t nchunks = (V + R - 1) / R;
    const float offset = d.ray_offset * hl_mesh_query_diagonal(mesh); /* 0: robust */
    const float vis_scale = (float)(1.0 / (HL_PI * d.supersample * d.supersample));
    const hl_trunc_params tp = hl_precompute_trunc_params(&d);
    hl_vis_counts vc = {0, 0}, vc_done = {0, 0}; /* vc_done: rays of the vertices appended */
    hl_vis_counts vc_resumed = {0, 0};              /* rays of a resumed file's earlier runs */
    hl_transport_info info = {0};

    r = hl_geom_create(ctx, d.N, d.C, &g);
    if (r == HL_OK) r = hl_rt_create(ctx, mesh, &rt);
    if (r == HL_OK) r = hl_chunk_buf_alloc(ctx, g, R, &buf[0]);
    if (r == HL_OK) r = hl_chunk_buf_alloc(ctx, g, R, &buf[1]);
    if (r == HL_OK && ctx->backend == HL_BACKEND_OPENCL) r = hl_cl_pipe_create(ctx, g, R, &pipe);
    if (r == HL_OK) {
        info.N = d.N;
        info.C = d.C;
        info.supersample = d.supersample;
        info.rule = d.rule;
        info.K = d.K;
        info.eps = d.rule == HL_TRUNC_ENERGY ? d.eps : 0.0f;
        info.quant = d.quant;
        info.ray_offset = d.ray_offset;
        info.vertex_count = V;
        info.object_vertex_count = mesh->object_vertex_count;
        info.triangle_count = mesh->triangle_count;
        info.block_count = g->nblocks;
        if (d.resume) {
            hl_tfile_progress done;
            r = hl_tfile_writer_resume(ctx, out_path, &info, mesh, &w, &done);
            if (r == HL_OK && w) {
                start = done.appended;
                st.coefficients_kept = done.coefficients;
                vc.rays_cast = vc_done.rays_cast = done.rays_cast;
                vc.rays_culled = vc_done.rays_culled = done.rays_culled;
                vc_resumed = vc;
                nchunks = (V - start + R - 1) / R;
                if (!ctx->quiet)
                    fprintf(stderr, "precompute: resuming %s.partial at vertex %u of %u\n", out_path, start, V);
            } else if (r == HL_OK && !ctx->quiet) {
                fprintf(stderr, "precompute: no %s.partial to resume; starting from the beginning\n", out_path);
            }
        }
        if (r == HL_OK && !w) r = hl_tfile_writer_open(ctx, out_path, &info, mesh, &w);
    }

    /* chunk k's rays are cast while the device runs chunk k-1 */
    for (uint32_t k = 0; r == HL_OK && k <= nchunks; k++) {
        int s = (int)(k & 1u);
        uint32_t first = start + k * R, count = k < nchunks ? (V - first < R ? V - first : R) : 0;
        hl_vis_counts vc_before = vc;
        if (k < nchunks) {
            double t0 = hl_now();
            fill_normals(mesh, first, count, buf[s].normals4);
            r = hl_rt_visibility(rt, g, mesh, first, count, d.supersample, offset, buf[s].vis, &vc);
            st.seconds_rays += hl_now() - t0;
            if (r != HL_OK) break;
        }
        if (pipe && k > 0) {
            double t0 = hl_now();
            r = hl_cl_pipe_wait(pipe, 1 - s);
            st.seconds_kernels += hl_now() - t0;
            if (r != HL_OK) break;
            uint32_t pf = start + (k - 1) * R, pc = V - pf < R ? V - pf : R;
            r = hl_tfile_writer_append(w, pc, buf[1 - s].rq, buf[1 - s].bc, buf[1 - s].entries, (size_t)g->ncoef * 2,
                                       buf[1 - s].nnz);
            for (uint32_t i = 0; i < pc; i++) st.coefficients_kept += buf[1 - s].nnz[i];
            /* the rays of chunk k are cast but its rows are not written */
            vc_done = vc_before;
            if (r == HL_OK) r = hl_tfile_writer_checkpoint(w, vc_done.rays_cast, vc_done.rays_culled);
            if (r != HL_OK) break;
            progress(ctx, pf + pc, V, vc.rays_cast, st.seconds_rays, t_start);
        }
        if (k == nchunks) break;
        buf[s].first = first;
        if (pipe) {
            r = hl_cl_pipe_submit(pipe, s, count, vis_scale, tp, d.quant, &buf[s]);
        } else {
            double t0 = hl_now();
            r = hl_ref_rows(ctx, g, count, vis_scale, tp, d.quant, &buf[s]);
            st.seconds_kernels += hl_now() - t0;
            if (r == HL_OK)
                r = hl_tfile_writer_append(w, count, buf[s].rq, buf[s].bc, buf[s].entries, (size_t)g->ncoef * 2,
                                           buf[s].nnz);
            for (uint32_t i = 0; i < count; i++) st.coefficients_kept += buf[s].nnz[i];
            vc_done = vc;
            if (r == HL_OK) r = hl_tfile_writer_checkpoint(w, vc_done.rays_cast, vc_done.rays_culled);
            progress(ctx, first + count, V, vc.rays_cast, st.seconds_rays, t_start);
        }
        if (r == HL_OK && hl_context_cancelled(ctx)) r = HL_ERR_INTERRUPTED;
    }
    if (r == HL_ERR_INTERRUPTED && w)
        hl_fail(ctx, HL_ERR_INTERRUPTED,
                "interrupted: %s not written; %u of %u vertices are kept in %s.partial (run again with --resume "
                "to continue)",
                out_path, hl_tfile_writer_appended(w), V, out_path);
    if (r == HL_OK) {
        info.coefficients_kept = st.coefficients_kept;
        info.rays_cast = vc.rays_cast;
        info.rays_culled = vc.rays_culled;
        r = hl_tfile_writer_finish(w, &info);
        w = NULL;
    }
    /* an interrupted run keeps its partial file for --resume; any other
       failure removes it */
    if (w && r == HL_ERR_INTERRUPTED) hl_tfile_writer_keep(w);
    else if (w) hl_tfile_writer_abort(w);
    hl_cl_pipe_destroy(pipe);
    hl_chunk_buf_free(&buf[0]);
    hl_chunk_buf_free(&buf[1]);
    hl_rt_destroy(rt);
    hl_geom_destroy(g);
    st.rays_cast = vc.rays_cast - vc_resumed.rays_cast; /* by this run */
    st.rays_culled = vc.rays_culled - vc_resumed.rays_culled;
    st.seconds_total = hl_now() - t_start;
    if (stats) *stats = st;
    return r;
}
