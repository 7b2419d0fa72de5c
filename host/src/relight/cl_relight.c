/* cl_relight.c - the relight's device stages (hl_cl_light_*): the buffers
 * of a relighter, and a lighting change's launches (env2para, Haar of R, G
 * and B, selection, the dot products) in one submission, whole or stage
 * by stage, into a host array or a device (or OpenGL) buffer. For a
 * spherical-harmonic transport (hl_cl_light_set_sh) the projection onto
 * the harmonics takes Haar's place, into the first order^2 slots; for a
 * cube-face Haar one (hl_cl_light_set_cube) env2para's kernels run on the
 * face texels' taps and the faces' Haar follows, into the first 6 Cq^2.
 *
 * Depends on: cl_light.h (the device state, OpenCL), cl_columns.c for
 * the transport's layout, lighting.h (the environment's tables).
 */
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "cl_light.h"

/* Gives the colour buffer's mapping back before anything else is
 * enqueued that may touch it. */
static void unmap_colours(hl_cl_light *l)
{
    if (!l->Bmap) return;
    clEnqueueUnmapMemObject(l->cl->queue, l->B, (void *)l->Bmap, 0, NULL, NULL);
    l->Bmap = NULL;
}

void hl_cl_light_destroy(hl_cl_light *l)
{
    if (!l) return;
    if (l->cl && l->cl->queue) {
        unmap_colours(l);
        clFinish(l->cl->queue);
    }
    cl_mem *all[] = HL_CL_LIGHT_BUFFERS(l);
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) hl_cl_release_buf(l->cl, all[i]);
    hl_cl_light_release_parts(l);
    for (int i = 0; i < 4; i++) hl_free_big(l->host[i]);
    free(l->col_start);
    free(l->part_range);
    free(l->part_cs);
    hl_free_big(l->host_col);
    hl_free_big(l->host_rel);
    free(l->range_start);
    free(l->order);
    free(l->tally_host);
    free(l);
}

hl_result hl_cl_light_create(hl_context *ctx, const hl_geom *g, const hl_light_geom *lg, const hl_transport *t,
                             const float *albedo4, hl_cl_light **out)
{
    return hl_cl_light_create_from(ctx, g, lg, t, NULL, albedo4, out);
}

/* A tap table (CSR rows start[0..rows], taps) on the device: start as it
 * is, the taps as (cell index, weight bits), 8 bytes each. */
static hl_result upload_taps(hl_cl_light *l, uint32_t rows, const uint32_t *start, const hl_env_tap *taps,
                             uint32_t ntaps, cl_mem *mstart, cl_mem *mruns)
{
    hl_result r = hl_cl_make_buf(l->ctx, mstart, CL_MEM_READ_ONLY, ((size_t)rows + 1) * 4, start, "environment runs");
    uint32_t *taps2 = r == HL_OK ? malloc(((size_t)ntaps + 1) * 8) : NULL;
    if (r == HL_OK && !taps2) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the environment runs");
    for (size_t e = 0; taps2 && e < ntaps; e++) {
        taps2[2 * e] = taps[e].row * l->lg->wc + taps[e].col;
        memcpy(&taps2[2 * e + 1], &taps[e].weight, 4);
    }
    if (r == HL_OK) r = hl_cl_make_buf(l->ctx, mruns, CL_MEM_READ_ONLY, ((size_t)ntaps + 1) * 8, taps2, "environment runs");
    free(taps2);
    return r;
}

/* The rows as loaded, for hl_relight_rows: the entries in place on a CPU
 * device (CL_MEM_USE_HOST_PTR), the vertices in their own order. */
static hl_result upload_rows(hl_cl_light *l, const hl_transport *t)
{
    const size_t V = l->nverts, nb = t->info.block_count;
    hl_context *ctx = l->ctx;
    if (!t->entries) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the transport holds no entries to relight from");
    l->rows = 1;
    l->nparts = 1;
    l->order = malloc((V ? V : 1) * 4);
    if (!l->order) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the vertex order");
    for (size_t v = 0; v < V; v++) l->order[v] = (uint32_t)v;
    const size_t ebytes = (size_t)(2 * t->info.coefficients_kept);
    /* in place on a CPU device (no host pointer to use when there are no entries) */
    hl_result r = hl_cl_make_buf(ctx, &l->rentries, CL_MEM_READ_ONLY | (l->cl->host_memory && ebytes ? CL_MEM_USE_HOST_PTR : 0),
                                 ebytes ? ebytes : 4, ebytes ? t->entries : NULL, "the transport's entries");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &l->roffset, CL_MEM_READ_ONLY, (V + 1) * 8, t->row_offset, "the rows' offsets");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &l->rcounts, CL_MEM_READ_ONLY, V * nb * 2, t->block_counts, "the rows' block counts");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &l->rquant, CL_MEM_READ_ONLY, V * 8, t->row_quant, "the rows' parameters");
    return r;
}

/* Work-items of the rows' launch (relight_rows.cl), and the vertices
 * each takes (*per, when asked): on a CPU 256 chunks of consecutive
 * vertices, on a GPU one each. */
static cl_uint rows_items(const hl_cl_light *l, cl_uint *per)
{
    const cl_uint nv = l->nverts;
    cl_uint p = l->cl->gpu_shape ? 1 : (nv + 255) / 256;
    if (!p) p = 1;
    if (per) *per = p;
    return (nv + p - 1) / p;
}

static hl_result create_light(hl_context *ctx, const hl_geom *g, const hl_light_geom *lg, const hl_transport *t,
                              const hl_row_source *src, int rows, const float *albedo4, hl_cl_light **out);

hl_result hl_cl_light_create_rows(hl_context *ctx, const hl_geom *g, const hl_light_geom *lg, const hl_transport *t,
                                  const float *albedo4, hl_cl_light **out)
{
    return create_light(ctx, g, lg, t, NULL, 1, albedo4, out);
}

hl_result hl_cl_light_create_from(hl_context *ctx, const hl_geom *g, const hl_light_geom *lg, const hl_transport *t,
                                  const hl_row_source *src, const float *albedo4, hl_cl_light **out)
{
    return create_light(ctx, g, lg, t, src, 0, albedo4, out);
}

static hl_result create_light(hl_context *ctx, const hl_geom *g, const hl_light_geom *lg, const hl_transport *t,
                              const hl_row_source *src, int rows, const float *albedo4, hl_cl_light **out)
{
    *out = NULL;
    if (!ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    hl_cl_light *l = calloc(1, sizeof *l);
    if (!l) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    l->ctx = ctx;
    l->cl = ctx->cl;
    l->g = g;
    l->lg = lg;
    l->nverts = t->info.vertex_count;
    l->scheme = t->info.quant;
    size_t nc = g->ncoef, V = l->nverts, cells = (size_t)lg->wc * lg->hc;
    /* one albedo for all where every vertex has the same (scanned meshes
       without colours, the terrain): 16 bytes a vertex less for each
       change to read (before the columns: their memory plan counts it) */
    l->albedo_step = 0;
    for (size_t i = 1; i < V && !l->albedo_step; i++) l->albedo_step = memcmp(albedo4 + 4 * i, albedo4, 16) != 0;
    hl_result r = HL_OK;
#define B(m, fl, bytes, init, what) if (r == HL_OK) r = hl_cl_make_buf(l->ctx, &l->m, fl, bytes, init, what)
    B(cells, CL_MEM_READ_ONLY, cells * 16, NULL, "environment cells");
    B(turned, CL_MEM_READ_WRITE, cells * 16, NULL, "environment cells");
    if (r == HL_OK) r = upload_taps(l, (uint32_t)nc, lg->tap_start, lg->taps, lg->ntaps, &l->start, &l->runs);
    B(slots, CL_MEM_READ_ONLY, (size_t)g->N * g->N * 4, g->slot_of_mallat, "the Haar slot order");
    B(weight, CL_MEM_READ_ONLY, nc * 4, lg->area, "selection weights");
    B(Lp, CL_MEM_READ_WRITE, 3 * nc * 4, NULL, "paraboloid lighting");
    B(Lw, CL_MEM_READ_WRITE, 3 * nc * 4, NULL, "wavelet lighting");
    B(Lsel, CL_MEM_READ_WRITE, nc * 16, NULL, "selected lighting");
    B(used, CL_MEM_READ_WRITE, g->nblocks, NULL, "block flags");
    B(bits, CL_MEM_READ_WRITE, nc / 8, NULL, "kept-slot bits");
    B(res, CL_MEM_READ_WRITE, sizeof(hl_select_result), NULL, "selection result");
    B(keys, CL_MEM_READ_WRITE, nc * 4, NULL, "selection keys");
    B(klist, CL_MEM_READ_WRITE, (nc + 1) * 4, NULL, "kept slots");
    if (r == HL_OK) r = rows ? upload_rows(l, t) : hl_cl_light_build_columns(l, t, src);
    /* albedo in the device's vertex order, or the one albedo */
    const size_t na = l->albedo_step ? V : 1;
    float *alb = r == HL_OK ? calloc(na, 16) : NULL;
    if (r == HL_OK && !alb) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the albedo");
    for (size_t i = 0; alb && i < na && i < V; i++) memcpy(alb + 4 * i, albedo4 + 4 * (size_t)l->order[i], 16);
    B(albedo, CL_MEM_READ_ONLY, na * 16, alb, "albedo");
    free(alb);
    B(ord, CL_MEM_READ_ONLY, V * 4, l->order, "vertex order");
    /* on a CPU device in memory the host maps without a copy */
    B(B, CL_MEM_READ_WRITE | (l->cl->host_memory ? CL_MEM_ALLOC_HOST_PTR : 0), V * 16, NULL, "vertex colours");
    /* the CPU shape's running sums (the GPU shape keeps them in registers) */
    const size_t sums = l->cl->gpu_shape || !l->nranges || !V ? 1 : l->range_start[l->nranges];
    B(acc, CL_MEM_READ_WRITE, (size_t)3 * sums * 4, NULL, "running sums");
    /* a clamp tally per range (per work-group of a range in the GPU
       shape), or per work-item of the rows' launch (rows_items); the
       work-items past them, which fill the last group, write none */
    l->ntally = rows ? rows_items(l, NULL) : l->nranges * hl_cl_light_range_groups(l);
    const size_t tally_bytes = (l->ntally ? (size_t)l->ntally : 1) * 16;
    B(tally, CL_MEM_READ_WRITE, tally_bytes, NULL, "the clamp's tallies");
    if (r == HL_OK && !(l->tally_host = malloc(tally_bytes)))
        r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the clamp's tallies");
#undef B
    if (r != HL_OK) { hl_cl_light_destroy(l); return r; }
    *out = l;
    return HL_OK;
}

#define LWRITE(buf, bytes, src) \
    CL_TRY(l->ctx, clEnqueueWriteBuffer(l->cl->queue, buf, CL_TRUE, 0, bytes, src, 0, NULL, NULL), "upload")
#define LREAD(buf, bytes, dst, blocking) \
    CL_TRY(l->ctx, clEnqueueReadBuffer(l->cl->queue, buf, blocking, 0, bytes, dst, 0, NULL, NULL), "read-back")
#define LARG(k, i, v) CL_TRY(l->ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")

hl_result hl_cl_light_set_cells(hl_cl_light *l, const float *cells4)
{
    LWRITE(l->cells, (size_t)l->lg->wc * l->lg->hc * 16, cells4);
    return HL_OK;
}

hl_result hl_cl_light_set_weights(hl_cl_light *l, const float *weight)
{
    LWRITE(l->weight, (size_t)l->g->ncoef * 4, weight);
    return HL_OK;
}

size_t hl_cl_light_items_group(const hl_cl_light *l)
{
    const size_t pos = (size_t)l->range_tiles * HL_TILE;
    return l->cl->items_wg < pos ? l->cl->items_wg : pos;
}

uint32_t hl_cl_light_range_groups(const hl_cl_light *l)
{
    if (!l->cl->gpu_shape || !l->range_tiles) return 1u; /* no columns cut yet */
    return (uint32_t)((size_t)l->range_tiles * HL_TILE / hl_cl_light_items_group(l));
}

/* items work-items, in groups of the shape's size: one for select.cl,
 * HL_SELECT_LANES for select_group.cl (items 1: one group), haar_wg for
 * Haar's groups and items_wg for the GPU shape's dot products (items: a
 * multiple of the group). */
static hl_result light_launch(hl_cl_light *l, int which, size_t items)
{
    size_t local = which == K_SELECT             ? 1
                   : which == K_SELECT_GROUP     ? HL_SELECT_LANES
                   : which == K_HAAR_GROUP       ? l->cl->haar_wg
                   : which == K_RELIGHT_ITEMS    ? hl_cl_light_items_group(l)
                                                 : l->cl->wg;
    size_t global = which == K_SELECT_GROUP ? HL_SELECT_LANES : (items + local - 1) / local * local;
    CL_TRY(l->ctx, clEnqueueNDRangeKernel(l->cl->queue, l->cl->k[which], 1, NULL, &global, &local, 0, NULL, NULL),
           hl_cl_kernel_names[which]);
    return HL_OK;
}

/* env2para on a tap table of count texels (start, runs), into three
 * planes of count floats. */
static hl_result enq_env2para_on(hl_cl_light *l, uint32_t s0, float f, cl_mem start, cl_mem runs, cl_uint nc,
                                 cl_mem out)
{
    /* CPU: 64 chunks of consecutive cells or texels; a GPU: one each per
       work-item */
    cl_kernel k = l->cl->k[K_TURN];
    cl_uint wc = l->lg->wc, ncell = l->lg->wc * l->lg->hc, sh = s0;
    cl_uint per = l->cl->gpu_shape ? 1 : (ncell + 63) / 64;
    LARG(k, 0, l->cells); LARG(k, 1, wc); LARG(k, 2, ncell); LARG(k, 3, sh); LARG(k, 4, f); LARG(k, 5, per);
    LARG(k, 6, l->turned);
    TRY(light_launch(l, K_TURN, (ncell + per - 1) / per));
    k = l->cl->k[K_ENV2PARA];
    per = l->cl->gpu_shape ? 1 : (nc + 63) / 64;
    LARG(k, 0, l->turned); LARG(k, 1, start); LARG(k, 2, runs); LARG(k, 3, nc); LARG(k, 4, per);
    LARG(k, 5, out);
    return light_launch(l, K_ENV2PARA, (nc + per - 1) / per);
}

static hl_result enq_env2para(hl_cl_light *l, uint32_t s0, float f, cl_mem out)
{
    return enq_env2para_on(l, s0, f, l->start, l->runs, l->g->ncoef, out);
}

hl_result hl_cl_light_set_cube(hl_cl_light *l, uint32_t Cq, const uint32_t *tap_start, const hl_env_tap *taps,
                               uint32_t ntaps)
{
    if (Cq < 2 || (Cq & (Cq - 1)) || 6 * Cq * Cq > l->g->ncoef || !tap_start || !taps)
        return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_light_set_cube: cube side %u on %u slots", Cq,
                       l->g->ncoef);
    hl_cl_release_buf(l->cl, &l->cstart);
    hl_cl_release_buf(l->cl, &l->cruns);
    TRY(upload_taps(l, 6 * Cq * Cq, tap_start, taps, ntaps, &l->cstart, &l->cruns));
    l->cube = Cq;
    return HL_OK;
}

/* The face texels' mean radiance (R, G, B planes of 6 Cq^2 in Lp), then
 * the faces' Haar of each into Lw's slots, zeros past 6 Cq^2. */
static hl_result enq_cube3(hl_cl_light *l, uint32_t s0, float f)
{
    const cl_uint nt = 6 * l->cube * l->cube;
    TRY(enq_env2para_on(l, s0, f, l->cstart, l->cruns, nt, l->Lp));
    return hl_cl_cube_haar_enqueue(l->ctx, l->cl, l->Lp, nt, l->Lw, l->g->ncoef, l->cube, 3);
}

/* Haar of R, G and B: a work-item a row, or in the GPU shape a group a
 * map of a row (haar_group.cl). */
static hl_result enq_haar3(hl_cl_light *l)
{
    const int which = l->cl->gpu_shape ? K_HAAR_GROUP : K_HAAR;
    cl_kernel k = l->cl->k[which];
    cl_uint N = l->g->N, rows = 3;
    LARG(k, 0, l->Lp); LARG(k, 1, l->Lw); LARG(k, 2, l->slots); LARG(k, 3, N); LARG(k, 4, rows);
    return light_launch(l, which, which == K_HAAR_GROUP ? 2 * rows * l->cl->haar_wg : rows);
}

hl_result hl_cl_light_set_sh(hl_cl_light *l, const float *Y, uint32_t stride, uint32_t count)
{
    TRY(hl_cl_sh_upload(l->ctx, l->cl, l->g->ncoef, Y, stride, count, &l->shY));
    l->sh_stride = stride;
    l->sh_count = count;
    return HL_OK;
}

/* R, G and B projected onto the harmonics: slots from sh_count on zero,
 * so selection and the dot products see the usual 2 N^2 slots. */
static hl_result enq_sh3(hl_cl_light *l)
{
    return hl_cl_sh_project_enqueue(l->ctx, l->cl, l->Lp, l->g->ncoef, l->shY, l->sh_stride, l->sh_count, l->Lw, 3);
}

/* The selection: select.cl's one work-item, or in the GPU shape one
 * group (select_group.cl, the same results) where the device takes it and
 * the slots fill whole words of kept bits and at most 512 blocks. */
int hl_cl_light_select_as_group(const hl_cl_light *l)
{
    return l->cl->select_group && l->g->ncoef % 32 == 0 && l->g->nblocks <= 512;
}

static hl_result enq_select(hl_cl_light *l, hl_select_params sp)
{
    const int which = hl_cl_light_select_as_group(l) ? K_SELECT_GROUP : K_SELECT;
    cl_kernel k = l->cl->k[which];
    cl_uint nc = l->g->ncoef, nb = l->g->nblocks;
    LARG(k, 0, l->Lw); LARG(k, 1, nc); LARG(k, 2, l->weight); LARG(k, 3, sp); LARG(k, 4, l->Lsel);
    LARG(k, 5, l->used); LARG(k, 6, l->bits); LARG(k, 7, nb); LARG(k, 8, l->res); LARG(k, 9, l->keys);
    LARG(k, 10, l->klist);
    return light_launch(l, which, 1);
}

/* One launch over all the ranges, or one a part (cl_parts.c), each after
 * its part's uploads. */
static hl_result enq_relight_to(hl_cl_light *l, cl_mem out)
{
    unmap_colours(l);
    cl_kernel k = l->cl->k[K_RELIGHT];
    cl_uint nc = l->g->ncoef, nv = l->nverts, nr = l->nranges, ts = l->tstride;
    if (l->rows) {
        cl_uint nb = l->g->nblocks, per;
        const cl_uint items = rows_items(l, &per);
        k = l->cl->k[K_RELIGHT_ROWS];
        LARG(k, 0, l->rentries); LARG(k, 1, l->roffset); LARG(k, 2, l->rcounts); LARG(k, 3, l->rquant);
        LARG(k, 4, l->scheme); LARG(k, 5, nb); LARG(k, 6, nc); LARG(k, 7, l->bits); LARG(k, 8, l->Lsel);
        LARG(k, 9, l->albedo); LARG(k, 10, l->keep_negative); LARG(k, 11, out); LARG(k, 12, nv); LARG(k, 13, per);
        LARG(k, 14, l->tally); LARG(k, 15, l->albedo_step);
        return light_launch(l, K_RELIGHT_ROWS, items);
    }
    if (l->cl->gpu_shape) k = l->cl->k[K_RELIGHT_ITEMS];
    for (uint32_t p = 0; p < (l->nparts > 1 ? l->nparts : 1u); p++) {
        cl_mem m[4];
        if (l->nparts > 1) TRY(hl_cl_light_enq_part(l, p, &nr));
        hl_cl_light_part_bufs(l, p, m);
        const cl_uint t0 = l->nparts > 1 ? l->part_range[p] : 0;
        if (l->cl->gpu_shape) { /* relight_items.cl: a work-item a position */
            LARG(k, 0, m[0]); LARG(k, 1, m[1]); LARG(k, 2, m[2]); LARG(k, 3, ts); LARG(k, 4, m[3]);
            LARG(k, 5, l->back); LARG(k, 6, nc); LARG(k, 7, l->Lsel); LARG(k, 8, l->klist); LARG(k, 9, l->albedo);
            LARG(k, 10, out); LARG(k, 11, nv); LARG(k, 12, nr); LARG(k, 13, l->ord); LARG(k, 14, l->keep_negative);
            const cl_uint rpos = l->range_tiles * HL_TILE;
            LARG(k, 15, l->tally); LARG(k, 16, t0); LARG(k, 17, l->albedo_step); LARG(k, 18, rpos);
            TRY(light_launch(l, K_RELIGHT_ITEMS, (size_t)nr * rpos));
            continue;
        }
        LARG(k, 0, m[0]); LARG(k, 1, m[1]); LARG(k, 2, m[2]); LARG(k, 3, ts); LARG(k, 4, m[3]);
        LARG(k, 5, l->back); LARG(k, 6, nc); LARG(k, 7, l->Lsel); LARG(k, 8, l->klist); LARG(k, 9, l->albedo);
        LARG(k, 10, l->acc); LARG(k, 11, out); LARG(k, 12, nv); LARG(k, 13, nr); LARG(k, 14, l->ord);
        LARG(k, 15, l->keep_negative); LARG(k, 16, l->tally);
        LARG(k, 17, t0); LARG(k, 18, l->albedo_step);
        TRY(light_launch(l, K_RELIGHT, nr));
    }
    return HL_OK;
}

void hl_cl_light_keep_negative(hl_cl_light *l, int keep) { l->keep_negative = keep ? 1u : 0u; }

hl_result hl_cl_light_enq_relight(hl_cl_light *l) { return enq_relight_to(l, l->B); }

hl_result hl_cl_light_set_capture(hl_cl_light *l, struct hl_capture *cap, const struct hl_capture_scene *scene,
                                  int with_env)
{
    if (cap && with_env && !l->Lenv)
        TRY(hl_cl_make_buf(l->ctx, &l->Lenv, CL_MEM_READ_WRITE, (size_t)3 * l->g->ncoef * 4, NULL,
                           "the environment behind the surroundings"));
    l->capture = cap;
    l->cscene = cap ? scene : NULL;
    l->capture_env = cap && with_env;
    return HL_OK;
}

/* The paraboloid lighting into Lp: env2para, or the capture of the
 * surroundings over env2para's lighting (or black). */
static hl_result enq_paraboloid(hl_cl_light *l, uint32_t s0, float f)
{
    if (!l->capture) return enq_env2para(l, s0, f, l->Lp);
    if (l->capture_env) TRY(enq_env2para(l, s0, f, l->Lenv));
    return hl_capture_enqueue(l->capture, l->cscene, l->capture_env ? l->Lenv : NULL, l->Lp);
}

/* The lighting stages up to the kept terms: the paraboloid lighting,
 * Haar (or the harmonics), selection. */
static hl_result enq_lighting(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp)
{
    if (l->cube) {
        TRY(enq_cube3(l, s0, f));
    } else {
        TRY(enq_paraboloid(l, s0, f));
        TRY(l->shY ? enq_sh3(l) : enq_haar3(l));
    }
    return enq_select(l, sp);
}

hl_result hl_cl_light_colours(hl_cl_light *l, const float **B4)
{
    /* the wait for the dot products too; a map, not a read: no copy of
       16 bytes a vertex on a CPU device (0.9 ms of a dragon's change) */
    if (!l->Bmap) {
        cl_int e = CL_SUCCESS;
        void *p = clEnqueueMapBuffer(l->cl->queue, l->B, CL_TRUE, CL_MAP_READ, 0, (size_t)l->nverts * 16, 0, NULL,
                                     NULL, &e);
        CL_TRY(l->ctx, e, "mapping the vertex colours");
        l->Bmap = p;
    }
    *B4 = l->Bmap;
    return HL_OK;
}

hl_result hl_cl_light_run(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp, const float **B4,
                          hl_select_result *res)
{
    /* one submission, one wait: launches cost ~50 us each to finish */
    unmap_colours(l);
    TRY(enq_lighting(l, s0, f, sp));
    TRY(hl_cl_light_enq_relight(l));
    LREAD(l->res, sizeof *res, res, CL_FALSE);
    /* done by the time the colours' blocking map returns (in order) */
    if (l->ntally) LREAD(l->tally, (size_t)l->ntally * 16, l->tally_host, CL_FALSE);
    return hl_cl_light_colours(l, B4);
}

void hl_cl_light_clamp_tally(const hl_cl_light *l, uint32_t *negative, float *lowest, float *brightest)
{
    uint32_t n = 0;
    float lo = 0.0f, hi = 0.0f;
    for (uint32_t i = 0; i < l->ntally; i++) {
        const float *t = l->tally_host + 4 * (size_t)i;
        uint32_t c;
        memcpy(&c, &t[2], 4);
        n += c;
        lo = t[0] < lo ? t[0] : lo;
        hi = t[1] > hi ? t[1] : hi;
    }
    *negative = n;
    *lowest = lo;
    *brightest = hi;
}

/* out must hold 4 floats a vertex. */
static hl_result check_colour_buffer(hl_cl_light *l, cl_mem m)
{
    size_t have = 0, need = (size_t)l->nverts * 16;
    CL_TRY(l->ctx, clGetMemObjectInfo(m, CL_MEM_SIZE, sizeof have, &have, NULL), "the colour buffer");
    if (have < need)
        return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "the colour buffer holds %zu bytes; %u vertices need %zu", have,
                       l->nverts, need);
    return HL_OK;
}

hl_result hl_cl_light_run_into(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp, void *out, int gl,
                               hl_select_result *res)
{
    cl_mem m = (cl_mem)out;
    TRY(check_colour_buffer(l, m));
    TRY(enq_lighting(l, s0, f, sp));
    if (gl) TRY(hl_cl_gl_acquire(l->ctx, m));
    hl_result r = enq_relight_to(l, m);
    if (gl) {
        cl_int e = hl_cl_gl_release(l->cl, m);
        if (r == HL_OK && e != CL_SUCCESS)
            r = hl_fail(l->ctx, HL_ERR_OPENCL, "OpenCL: clEnqueueReleaseGLObjects failed (%s)", hl_cl_err_name(e));
    }
    /* the blocking read of the result also waits for the release: OpenGL
       may draw from the buffer once this returns */
    if (r == HL_OK) LREAD(l->res, sizeof *res, res, CL_TRUE);
    else clFinish(l->cl->queue);
    return r;
}

hl_result hl_cl_light_write_colours(hl_cl_light *l, const float *rgba4, void *out, int gl)
{
    cl_mem m = (cl_mem)out;
    TRY(check_colour_buffer(l, m));
    if (gl) TRY(hl_cl_gl_acquire(l->ctx, m));
    cl_int e = clEnqueueWriteBuffer(l->cl->queue, m, CL_TRUE, 0, (size_t)l->nverts * 16, rgba4, 0, NULL, NULL);
    hl_result r = e == CL_SUCCESS ? HL_OK
                                  : hl_fail(l->ctx, HL_ERR_OPENCL, "OpenCL: writing the blended colours failed (%s)",
                                            hl_cl_err_name(e));
    if (gl) {
        cl_int e2 = hl_cl_gl_release(l->cl, m);
        if (r == HL_OK && e2 != CL_SUCCESS)
            r = hl_fail(l->ctx, HL_ERR_OPENCL, "OpenCL: clEnqueueReleaseGLObjects failed (%s)", hl_cl_err_name(e2));
    }
    clFinish(l->cl->queue);
    return r;
}

hl_result hl_cl_light_stage_env2para(hl_cl_light *l, uint32_t s0, float f, float *Lp)
{
    TRY(enq_env2para(l, s0, f, l->Lp));
    LREAD(l->Lp, (size_t)3 * l->g->ncoef * 4, Lp, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_haar(hl_cl_light *l, const float *Lp, float *Lw)
{
    LWRITE(l->Lp, (size_t)3 * l->g->ncoef * 4, Lp);
    TRY(enq_haar3(l));
    LREAD(l->Lw, (size_t)3 * l->g->ncoef * 4, Lw, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_sh(hl_cl_light *l, const float *Lp, float *Lw)
{
    if (!l->shY) return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_light_stage_sh: no projection set");
    LWRITE(l->Lp, (size_t)3 * l->g->ncoef * 4, Lp);
    TRY(enq_sh3(l));
    LREAD(l->Lw, (size_t)3 * l->g->ncoef * 4, Lw, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_cube(hl_cl_light *l, uint32_t s0, float f, float *Lw)
{
    if (!l->cube) return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_light_stage_cube: no cube side set");
    TRY(enq_cube3(l, s0, f));
    LREAD(l->Lw, (size_t)3 * l->g->ncoef * 4, Lw, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_select(hl_cl_light *l, const float *Lw, hl_select_params sp, float *Lsel4,
                                   uint8_t *used, uint32_t *bits, hl_select_result *res)
{
    LWRITE(l->Lw, (size_t)3 * l->g->ncoef * 4, Lw);
    TRY(enq_select(l, sp));
    LREAD(l->Lsel, (size_t)l->g->ncoef * 16, Lsel4, CL_TRUE);
    LREAD(l->used, l->g->nblocks, used, CL_TRUE);
    LREAD(l->bits, l->g->ncoef / 8, bits, CL_TRUE);
    LREAD(l->res, sizeof *res, res, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_relight(hl_cl_light *l, const float *Lsel4, const uint32_t *bits, float *B4)
{
    const size_t nc = l->g->ncoef;
    uint32_t *list = malloc((nc + 1) * 4); /* as hl_select writes it */
    if (!list) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    list[0] = 0;
    for (size_t s = 0; s < nc; s++)
        if ((bits[s / 32] >> (s % 32)) & 1u) list[++list[0]] = (uint32_t)s;
    cl_int e = clEnqueueWriteBuffer(l->cl->queue, l->klist, CL_TRUE, 0, (nc + 1) * 4, list, 0, NULL, NULL);
    free(list);
    CL_TRY(l->ctx, e, "upload");
    LWRITE(l->Lsel, nc * 16, Lsel4);
    LWRITE(l->bits, nc / 8, bits);
    TRY(hl_cl_light_enq_relight(l));
    LREAD(l->B, (size_t)l->nverts * 16, B4, CL_TRUE);
    return HL_OK;
}
