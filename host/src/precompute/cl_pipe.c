/* cl_pipe.c - the precompute's device stages (hl_cl_pipe_*): the buffers
 * for a chunk of rows, and the launches of cube2para, Haar, truncation and
 * quantisation on them, with the uploads and read-backs around them. With
 * a spherical-harmonic matrix set (hl_cl_pipe_set_sh), the projection onto
 * the harmonics takes the place of Haar: the rows' first order^2 slots,
 * the others zero. With a cube side set (hl_cl_pipe_set_cube), the rows
 * are made on the cube's faces instead (hl_cube_face_rows, in T's first
 * 6 Cq^2 floats) and go through the faces' Haar into the first 6 Cq^2
 * slots.
 *
 * Two input slots let the host cast the rays of the next chunk while the
 * device works on this one (precompute.c). Depends on: cl_internal.h
 * (OpenCL, the counted buffers, the kernel handles), geom.h (tables).
 */
#include <stdlib.h>

#include "cl_internal.h"
#include "geom.h"

struct hl_cl_pipe {
    hl_context *ctx;
    struct hl_cl *cl;
    const hl_geom *g;
    uint32_t max_rows;
    cl_mem start, ent, slots;          /* geometry tables */
    cl_mem vis[2], nrm[2];             /* inputs, one per slot */
    cl_mem T, coef, tr, rq, bc, entries, nnz;
    cl_mem shY;                        /* the harmonic projection; NULL: Haar */
    uint32_t sh_stride, sh_count;
    uint32_t cube;                     /* cube-face Haar: the faces' side; 0: none */
    cl_event done[2];
};

hl_result hl_cl_pipe_create(hl_context *ctx, const hl_geom *g, uint32_t max_rows, hl_cl_pipe **out)
{
    *out = NULL;
    if (!ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    hl_cl_pipe *p = calloc(1, sizeof *p);
    if (!p) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    p->ctx = ctx;
    p->cl = ctx->cl;
    p->g = g;
    p->max_rows = max_rows;
    size_t R = max_rows, nc = g->ncoef;
    hl_result r = HL_OK;
#define B(m, fl, bytes, init, what) if (r == HL_OK) r = hl_cl_make_buf(p->ctx, &p->m, fl, bytes, init, what)
    B(start, CL_MEM_READ_ONLY, ((size_t)g->ncube + 1) * 4, g->p2c_start, "the table rows");
    B(ent, CL_MEM_READ_ONLY, (size_t)g->nentries * sizeof(hl_c2p_entry), g->p2c, "the table entries");
    B(slots, CL_MEM_READ_ONLY, (size_t)g->N * g->N * 4, g->slot_of_mallat, "the Haar slot order");
    B(vis[0], CL_MEM_READ_ONLY, R * g->ncube, NULL, "visibility (slot 0)");
    B(vis[1], CL_MEM_READ_ONLY, R * g->ncube, NULL, "visibility (slot 1)");
    B(nrm[0], CL_MEM_READ_ONLY, R * 16, NULL, "normals (slot 0)");
    B(nrm[1], CL_MEM_READ_ONLY, R * 16, NULL, "normals (slot 1)");
    B(T, CL_MEM_READ_WRITE, R * nc * 4, NULL, "paraboloid transport");
    B(coef, CL_MEM_READ_WRITE, R * nc * 4, NULL, "Haar coefficients");
    B(tr, CL_MEM_READ_WRITE, R * sizeof(hl_trunc_result), NULL, "truncation results");
    B(rq, CL_MEM_READ_WRITE, R * sizeof(hl_row_quant), NULL, "quantisation parameters");
    B(bc, CL_MEM_READ_WRITE, R * g->nblocks * 2, NULL, "block counts");
    B(entries, CL_MEM_READ_WRITE, R * nc * 2, NULL, "packed entries");
    B(nnz, CL_MEM_READ_WRITE, R * 4, NULL, "entry counts");
#undef B
    if (r != HL_OK) { hl_cl_pipe_destroy(p); return r; }
    *out = p;
    return HL_OK;
}

void hl_cl_pipe_destroy(hl_cl_pipe *p)
{
    if (!p) return;
    if (p->cl && p->cl->queue) clFinish(p->cl->queue);
    cl_mem *all[] = {&p->start, &p->ent, &p->slots, &p->vis[0], &p->vis[1], &p->nrm[0], &p->nrm[1],
                     &p->T, &p->coef, &p->tr, &p->rq, &p->bc, &p->entries, &p->nnz, &p->shY};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) hl_cl_release_buf(p->cl, all[i]);
    for (int s = 0; s < 2; s++)
        if (p->done[s]) clReleaseEvent(p->done[s]);
    free(p);
}

#define ARG(k, i, v) CL_TRY(p->ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")

/* Kernel `which` over items work-items, rounded up to whole groups. */
static hl_result launch_items(hl_context *ctx, struct hl_cl *cl, int which, size_t items)
{
    size_t local = cl->wg, global = (items + local - 1) / local * local;
    CL_TRY(ctx, clEnqueueNDRangeKernel(cl->queue, cl->k[which], 1, NULL, &global, &local, 0, NULL, NULL),
           hl_cl_kernel_names[which]);
    return HL_OK;
}
#define CARG(k, i, v) CL_TRY(ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")

static hl_result launch(hl_cl_pipe *p, int which, uint32_t rows)
{
    if (which == K_CUBE2PARA) rows = (rows + C2P_ROWS - 1) / C2P_ROWS;
    return launch_items(p->ctx, p->cl, which, rows);
}

static hl_result enqueue_cube2para(hl_cl_pipe *p, int slot, uint32_t rows, float scale)
{
    cl_kernel k = p->cl->k[K_CUBE2PARA];
    cl_uint ncube = p->g->ncube, ncoef = p->g->ncoef, n = rows;
    ARG(k, 0, p->vis[slot]); ARG(k, 1, ncube); ARG(k, 2, scale); ARG(k, 3, p->nrm[slot]);
    ARG(k, 4, p->start); ARG(k, 5, p->ent); ARG(k, 6, ncoef); ARG(k, 7, p->T); ARG(k, 8, n);
    return launch(p, K_CUBE2PARA, rows);
}

static hl_result enqueue_haar(hl_cl_pipe *p, uint32_t rows)
{
    cl_kernel k = p->cl->k[K_HAAR];
    cl_uint N = p->g->N, n = rows;
    ARG(k, 0, p->T); ARG(k, 1, p->coef); ARG(k, 2, p->slots); ARG(k, 3, N); ARG(k, 4, n);
    return launch(p, K_HAAR, rows);
}

hl_result hl_cl_sh_upload(hl_context *ctx, struct hl_cl *cl, uint32_t ncoef, const float *Y, uint32_t stride,
                          uint32_t count, cl_mem *m)
{
    if (!Y || stride % 4 || count > stride || count > ncoef)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "spherical-harmonic projection: %u coefficients, stride %u, %u slots",
                       count, stride, ncoef);
    hl_cl_release_buf(cl, m);
    return hl_cl_make_buf(ctx, m, CL_MEM_READ_ONLY, (size_t)ncoef * stride * 4, Y, "the spherical-harmonic projection");
}

hl_result hl_cl_pipe_set_sh(hl_cl_pipe *p, const float *Y, uint32_t stride, uint32_t count)
{
    TRY(hl_cl_sh_upload(p->ctx, p->cl, p->g->ncoef, Y, stride, count, &p->shY));
    p->sh_stride = stride;
    p->sh_count = count;
    return HL_OK;
}

hl_result hl_cl_sh_project_enqueue(hl_context *ctx, struct hl_cl *cl, cl_mem in, cl_uint ncoef, cl_mem Y, cl_uint stride,
                                   cl_uint count, cl_mem out, cl_uint rows)
{
    /* the kernel writes only the first count slots of each row */
    const float zero = 0.0f;
    CL_TRY(ctx, clEnqueueFillBuffer(cl->queue, out, &zero, sizeof zero, 0, (size_t)rows * ncoef * 4, 0, NULL, NULL),
           "clEnqueueFillBuffer");
    cl_kernel k = cl->k[K_SH_PROJECT];
    CARG(k, 0, in); CARG(k, 1, ncoef); CARG(k, 2, Y); CARG(k, 3, stride); CARG(k, 4, count); CARG(k, 5, out);
    CARG(k, 6, rows);
    /* HL_SH_ROWS (4) rows a work-item: sh_project.cl */
    return launch_items(ctx, cl, K_SH_PROJECT, (size_t)(rows + 3) / 4 * (stride / 4));
}

static hl_result enqueue_sh(hl_cl_pipe *p, uint32_t rows)
{
    return hl_cl_sh_project_enqueue(p->ctx, p->cl, p->T, p->g->ncoef, p->shY, p->sh_stride, p->sh_count, p->coef, rows);
}

hl_result hl_cl_pipe_set_cube(hl_cl_pipe *p, uint32_t Cq)
{
    if (Cq < 2 || (Cq & (Cq - 1)) || p->g->C % Cq || 6 * Cq * Cq > p->g->ncoef)
        return hl_fail(p->ctx, HL_ERR_INVALID_ARGUMENT,
                       "hl_cl_pipe_set_cube: cube side %u (a power of two dividing C = %u, 6 C'^2 at most %u)", Cq,
                       p->g->C, p->g->ncoef);
    p->cube = Cq;
    return HL_OK;
}

static hl_result enqueue_cube_rows(hl_cl_pipe *p, int slot, uint32_t rows, float scale)
{
    cl_kernel k = p->cl->k[K_CUBE_ROWS];
    cl_uint C = p->g->C, Cq = p->cube, ncoef = p->g->ncoef, n = rows;
    ARG(k, 0, p->vis[slot]); ARG(k, 1, C); ARG(k, 2, Cq); ARG(k, 3, scale); ARG(k, 4, p->nrm[slot]);
    ARG(k, 5, p->start); ARG(k, 6, p->ent); ARG(k, 7, ncoef); ARG(k, 8, p->T); ARG(k, 9, n);
    return launch(p, K_CUBE_ROWS, rows);
}

hl_result hl_cl_cube_haar_enqueue(hl_context *ctx, struct hl_cl *cl, cl_mem in, cl_uint in_stride, cl_mem out,
                                  cl_uint out_stride, cl_uint Cq, cl_uint rows)
{
    cl_kernel k = cl->k[K_CUBE_HAAR];
    CARG(k, 0, in); CARG(k, 1, in_stride); CARG(k, 2, out); CARG(k, 3, out_stride); CARG(k, 4, Cq); CARG(k, 5, rows);
    /* one work-item per face of each row */
    return launch_items(ctx, cl, K_CUBE_HAAR, (size_t)rows * 6);
}

static hl_result enqueue_cube_haar(hl_cl_pipe *p, uint32_t rows)
{
    return hl_cl_cube_haar_enqueue(p->ctx, p->cl, p->T, p->g->ncoef, p->coef, p->g->ncoef, p->cube, rows);
}

static hl_result enqueue_truncate(hl_cl_pipe *p, uint32_t rows, hl_trunc_params tp)
{
    cl_kernel k = p->cl->k[K_TRUNCATE];
    cl_uint ncoef = p->g->ncoef, n = rows;
    ARG(k, 0, p->coef); ARG(k, 1, ncoef); ARG(k, 2, tp); ARG(k, 3, p->tr); ARG(k, 4, n);
    return launch(p, K_TRUNCATE, rows);
}

static hl_result enqueue_quantize(hl_cl_pipe *p, uint32_t rows, uint32_t scheme, uint32_t first)
{
    cl_kernel k = p->cl->k[K_QUANTIZE];
    cl_uint ncoef = p->g->ncoef, nb = p->g->nblocks, n = rows, sc = scheme, f0 = first;
    ARG(k, 0, p->coef); ARG(k, 1, ncoef); ARG(k, 2, nb); ARG(k, 3, p->tr); ARG(k, 4, sc);
    ARG(k, 5, p->rq); ARG(k, 6, p->bc); ARG(k, 7, p->entries); ARG(k, 8, p->nnz); ARG(k, 9, n);
    ARG(k, 10, f0);
    return launch(p, K_QUANTIZE, rows);
}

static hl_result check_rows(hl_cl_pipe *p, uint32_t rows)
{
    if (rows > p->max_rows)
        return hl_fail(p->ctx, HL_ERR_INVALID_ARGUMENT, "%u rows exceed the pipeline's %u", rows, p->max_rows);
    return HL_OK;
}

#define WRITE(buf, bytes, src, blocking) \
    CL_TRY(p->ctx, clEnqueueWriteBuffer(p->cl->queue, buf, blocking, 0, bytes, src, 0, NULL, NULL), "upload")
#define READ(buf, bytes, dst, blocking, ev) \
    CL_TRY(p->ctx, clEnqueueReadBuffer(p->cl->queue, buf, blocking, 0, bytes, dst, 0, NULL, ev), "read-back")

hl_result hl_cl_pipe_submit(hl_cl_pipe *p, int slot, uint32_t rows, float vis_scale,
                            hl_trunc_params tp, uint32_t scheme, const hl_chunk_buf *io)
{
    TRY(check_rows(p, rows));
    const hl_geom *g = p->g;
    size_t R = rows;
    WRITE(p->vis[slot], R * g->ncube, io->vis, CL_FALSE);
    WRITE(p->nrm[slot], R * 16, io->normals4, CL_FALSE);
    if (p->cube) {
        TRY(enqueue_cube_rows(p, slot, rows, vis_scale));
        TRY(enqueue_cube_haar(p, rows));
    } else {
        TRY(enqueue_cube2para(p, slot, rows, vis_scale));
        TRY(p->shY ? enqueue_sh(p, rows) : enqueue_haar(p, rows));
    }
    TRY(enqueue_truncate(p, rows, tp));
    TRY(enqueue_quantize(p, rows, scheme, io->first));
    READ(p->tr, R * sizeof(hl_trunc_result), io->tr, CL_FALSE, NULL);
    READ(p->rq, R * sizeof(hl_row_quant), io->rq, CL_FALSE, NULL);
    READ(p->bc, R * g->nblocks * 2, io->bc, CL_FALSE, NULL);
    READ(p->nnz, R * 4, io->nnz, CL_FALSE, NULL);
    if (io->coef) READ(p->coef, R * g->ncoef * 4, io->coef, CL_FALSE, NULL);
    if (p->done[slot]) { clReleaseEvent(p->done[slot]); p->done[slot] = NULL; }
    READ(p->entries, R * g->ncoef * 2, io->entries, CL_FALSE, &p->done[slot]);
    CL_TRY(p->ctx, clFlush(p->cl->queue), "clFlush");
    return HL_OK;
}

hl_result hl_cl_pipe_wait(hl_cl_pipe *p, int slot)
{
    if (!p->done[slot]) return HL_OK;
    CL_TRY(p->ctx, clWaitForEvents(1, &p->done[slot]), "waiting for the kernels");
    clReleaseEvent(p->done[slot]);
    p->done[slot] = NULL;
    return HL_OK;
}

hl_result hl_cl_pipe_cube2para(hl_cl_pipe *p, uint32_t rows, const uint8_t *vis, float scale,
                               const float *normals4, float *T)
{
    TRY(check_rows(p, rows));
    WRITE(p->vis[0], (size_t)rows * p->g->ncube, vis, CL_TRUE);
    WRITE(p->nrm[0], (size_t)rows * 16, normals4, CL_TRUE);
    TRY(enqueue_cube2para(p, 0, rows, scale));
    READ(p->T, (size_t)rows * p->g->ncoef * 4, T, CL_TRUE, NULL);
    return HL_OK;
}

/* One transform stage alone (Haar, the faces' Haar or the harmonic
 * projection): rows of T in, their coefficients out. */
static hl_result transform_alone(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef,
                                 hl_result (*enqueue)(hl_cl_pipe *, uint32_t))
{
    TRY(check_rows(p, rows));
    WRITE(p->T, (size_t)rows * p->g->ncoef * 4, T, CL_TRUE);
    TRY(enqueue(p, rows));
    READ(p->coef, (size_t)rows * p->g->ncoef * 4, coef, CL_TRUE, NULL);
    return HL_OK;
}

hl_result hl_cl_pipe_haar(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef)
{
    return transform_alone(p, rows, T, coef, enqueue_haar);
}

hl_result hl_cl_pipe_cube_rows(hl_cl_pipe *p, uint32_t rows, const uint8_t *vis, float scale,
                               const float *normals4, float *T)
{
    TRY(check_rows(p, rows));
    if (!p->cube) return hl_fail(p->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_pipe_cube_rows: no cube side set");
    WRITE(p->vis[0], (size_t)rows * p->g->ncube, vis, CL_TRUE);
    WRITE(p->nrm[0], (size_t)rows * 16, normals4, CL_TRUE);
    TRY(enqueue_cube_rows(p, 0, rows, scale));
    READ(p->T, (size_t)rows * p->g->ncoef * 4, T, CL_TRUE, NULL);
    return HL_OK;
}

hl_result hl_cl_pipe_cube_haar(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef)
{
    if (!p->cube) return hl_fail(p->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_pipe_cube_haar: no cube side set");
    return transform_alone(p, rows, T, coef, enqueue_cube_haar);
}

hl_result hl_cl_pipe_sh_project(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef)
{
    if (!p->shY) return hl_fail(p->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_pipe_sh_project: no projection set");
    return transform_alone(p, rows, T, coef, enqueue_sh);
}

hl_result hl_cl_pipe_truncate(hl_cl_pipe *p, uint32_t rows, const float *coef, hl_trunc_params tp,
                              hl_trunc_result *tr)
{
    TRY(check_rows(p, rows));
    WRITE(p->coef, (size_t)rows * p->g->ncoef * 4, coef, CL_TRUE);
    TRY(enqueue_truncate(p, rows, tp));
    READ(p->tr, (size_t)rows * sizeof *tr, tr, CL_TRUE, NULL);
    return HL_OK;
}

hl_result hl_cl_pipe_quantize(hl_cl_pipe *p, uint32_t rows, uint32_t first, const float *coef,
                              const hl_trunc_result *tr, uint32_t scheme, hl_row_quant *rq, uint16_t *bc,
                              uint8_t *entries, uint32_t *nnz)
{
    TRY(check_rows(p, rows));
    const hl_geom *g = p->g;
    WRITE(p->coef, (size_t)rows * g->ncoef * 4, coef, CL_TRUE);
    WRITE(p->tr, (size_t)rows * sizeof *tr, tr, CL_TRUE);
    TRY(enqueue_quantize(p, rows, scheme, first));
    READ(p->rq, (size_t)rows * sizeof *rq, rq, CL_TRUE, NULL);
    READ(p->bc, (size_t)rows * g->nblocks * 2, bc, CL_TRUE, NULL);
    READ(p->entries, (size_t)rows * g->ncoef * 2, entries, CL_TRUE, NULL);
    READ(p->nnz, (size_t)rows * 4, nnz, CL_TRUE, NULL);
    return HL_OK;
}
