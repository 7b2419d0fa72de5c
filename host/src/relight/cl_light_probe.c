/* cl_light_probe.c - what `haarlight bench` measures of the relight's dot
 * products: their work-items, the column entries each walks for a
 * selection, the bytes they read, and the kernel's own time; and the
 * device memory a relighter holds.
 *
 * Depends on: cl_light.h (the column layout, OpenCL), hl_shared.h (which
 * walk a range takes), core's clock.
 */
#include <stdlib.h>

#include "capture.h"
#include "cl_light.h"

uint32_t hl_cl_light_ranges(const hl_cl_light *l) { return l->nranges; }

uint64_t hl_cl_light_device_bytes(const hl_cl_light *l)
{
    const cl_mem *all[] = HL_CL_LIGHT_BUFFERS(l);
    uint64_t sum = 0;
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) {
        size_t bytes = 0;
        if (*all[i] && clGetMemObjectInfo(*all[i], CL_MEM_SIZE, sizeof bytes, &bytes, NULL) == CL_SUCCESS) sum += bytes;
    }
    for (size_t i = 0; l->resident && i < 4 * (size_t)l->nparts; i++) {
        size_t bytes = 0;
        if (l->pbuf[i] && clGetMemObjectInfo(l->pbuf[i], CL_MEM_SIZE, sizeof bytes, &bytes, NULL) == CL_SUCCESS)
            sum += bytes;
    }
    return sum;
}

double hl_cl_light_kept_entries(const hl_cl_light *l, const uint32_t *bits, double *per_range)
{
    const size_t nc = l->g->ncoef;
    double kept = 0.0;
    for (size_t rg = 0; rg < l->nranges; rg++) per_range[rg] = 0.0;
    for (size_t s = 0; s < nc; s++) {
        if (!((bits[s / 32] >> (s % 32)) & 1u)) continue;
        kept += 1.0;
        for (size_t rg = 0; rg < l->nranges; rg++) {
            const uint32_t *c = l->col_start + rg * (nc + 1);
            per_range[rg] += (double)(c[s + 1] - c[s]);
        }
    }
    return kept;
}

int hl_cl_light_tile_walk(const hl_cl_light *l, uint32_t rg, double entries, uint32_t kept)
{
    const uint32_t nt = (l->range_start[rg + 1] - l->range_start[rg]) / HL_TILE;
    return hl_tile_walk_pays((uint64_t)entries, kept, nt);
}

hl_result hl_cl_light_bytes_read(hl_cl_light *l, double *bytes)
{
    if (l->rows) return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_light_bytes_read: a relighter over rows has no columns");
    const size_t nc = l->g->ncoef;
    uint32_t *bits = malloc(nc / 8);
    double *per = malloc((l->nranges ? l->nranges : 1) * sizeof *per);
    if (!bits || !per) {
        free(bits);
        free(per);
        return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    }
    cl_int e = clEnqueueReadBuffer(l->cl->queue, l->bits, CL_TRUE, 0, nc / 8, bits, 0, NULL, NULL);
    if (e != CL_SUCCESS) {
        free(bits);
        free(per);
        CL_TRY(l->ctx, e, "read-back");
    }
    const double kept = hl_cl_light_kept_entries(l, bits, per);
    free(bits);
    /* per kept slot its place in the list and, per range, its column's
       start and end; per vertex slot its scale; per vertex its albedo,
       place and colour. Then per range, by its walk (hl_tile_walk_pays):
       both read each kept entry's halves and, per kept slot and 32 tiles,
       a word of tile bits and a count (the column walk up to its last
       entry: counted whole); the column walk reads its sums too (zeroed,
       then read once they leave the cache), while the tile walk's sums
       and entry 0 stay in the cache. */
    double b = kept * (4.0 + (double)l->nranges * 8.0) + (double)l->range_start[l->nranges] * 4.0 +
               (double)l->nverts * 36.0;
    for (size_t rg = 0; rg < l->nranges; rg++) {
        const uint32_t n = l->range_start[rg + 1] - l->range_start[rg], nt = n / HL_TILE;
        b += per[rg] * 2.0 * HL_TILE + kept * ((nt + 31) / 32) * 8.0;
        if (!hl_cl_light_tile_walk(l, (uint32_t)rg, per[rg], (uint32_t)kept)) b += n * 24.0;
    }
    free(per);
    *bytes = b;
    return HL_OK;
}

hl_result hl_cl_light_time_capture(hl_cl_light *l, uint32_t reps, double *seconds)
{
    if (!l->capture) return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "no surroundings have been captured yet");
    /* the capture alone, as a lighting change enqueues it (packing and
       uploading the triangles included), one at a time: the next pack
       rewrites what an upload reads */
    cl_mem env = l->capture_env ? l->Lenv : NULL;
    TRY(hl_capture_enqueue(l->capture, l->cscene, env, l->Lp));
    CL_TRY(l->ctx, clFinish(l->cl->queue), "clFinish");
    double t0 = hl_now();
    for (uint32_t i = 0; i < reps; i++) {
        TRY(hl_capture_enqueue(l->capture, l->cscene, env, l->Lp));
        /* the next pack rewrites what this upload reads */
        CL_TRY(l->ctx, clFinish(l->cl->queue), "clFinish");
    }
    *seconds = (hl_now() - t0) / (reps ? reps : 1);
    return HL_OK;
}

hl_result hl_cl_light_time_relight(hl_cl_light *l, uint32_t reps, double *seconds)
{
    /* the kernel alone, several launches in one submission */
    TRY(hl_cl_light_enq_relight(l));
    CL_TRY(l->ctx, clFinish(l->cl->queue), "clFinish");
    double t0 = hl_now();
    for (uint32_t i = 0; i < reps; i++) TRY(hl_cl_light_enq_relight(l));
    CL_TRY(l->ctx, clFinish(l->cl->queue), "clFinish");
    *seconds = (hl_now() - t0) / (reps ? reps : 1);
    return HL_OK;
}
