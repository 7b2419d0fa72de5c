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
int hl_cl_light_one_albedo(const hl_cl_light *l) { return !l->albedo_step; }

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

int hl_cl_light_gpu_shape(const hl_cl_light *l) { return l->cl->gpu_shape; }

int hl_cl_light_tile_walk(const hl_cl_light *l, uint32_t rg, double entries, uint32_t kept)
{
    if (l->cl->gpu_shape) return 0; /* relight_items.cl has one walk */
    const uint32_t nt = (l->range_start[rg + 1] - l->range_start[rg]) / HL_TILE;
    return hl_tile_walk_pays((uint64_t)entries, kept, nt);
}

hl_result hl_cl_light_tile_words(hl_cl_light *l, const uint32_t *bits, uint64_t *dense, uint64_t *mixed)
{
    *dense = *mixed = 0;
    if (l->rows || l->nparts > 1)
        return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "hl_cl_light_tile_words: needs the columns in one part");
    const size_t nc = l->g->ncoef, ts = l->tstride, nrel = (size_t)l->nranges * nc * ts * 2;
    uint32_t *ks = malloc(nc * sizeof *ks), *rel = malloc(nrel * 4);
    double *per = malloc((l->nranges ? l->nranges : 1) * sizeof *per);
    cl_int e = ks && rel && per ? CL_SUCCESS : CL_OUT_OF_HOST_MEMORY;
    if (e == CL_SUCCESS) e = clEnqueueReadBuffer(l->cl->queue, l->rel, CL_TRUE, 0, nrel * 4, rel, 0, NULL, NULL);
    uint32_t m = 0;
    for (size_t s = 0; e == CL_SUCCESS && s < nc; s++)
        if ((bits[s / 32] >> (s % 32)) & 1u) ks[m++] = (uint32_t)s;
    if (e == CL_SUCCESS) hl_cl_light_kept_entries(l, bits, per);
    /* as the kernel's walk_tiles goes: groups of kept slots in order, the
       last group padded with the last slot, then words of 32 tiles */
    for (size_t rg = 0; e == CL_SUCCESS && m && rg < l->nranges; rg++) {
        const uint32_t nt = (l->range_start[rg + 1] - l->range_start[rg]) / HL_TILE;
        if (!hl_cl_light_tile_walk(l, (uint32_t)rg, per[rg], m)) continue;
        for (uint32_t j0 = 0; j0 < m; j0 += HL_TILE_GROUP)
            for (uint32_t w = 0; 32 * w < nt; w++) {
                const uint32_t n = nt - 32 * w < 32 ? nt - 32 * w : 32, want = n == 32 ? ~0u : (1u << n) - 1u;
                uint32_t all = want;
                for (uint32_t g = 0; g < HL_TILE_GROUP; g++) {
                    const uint32_t s = ks[j0 + g < m ? j0 + g : m - 1];
                    all &= rel[2 * ((rg * nc + s) * ts + w)];
                }
                if (all == want) ++*dense;
                else ++*mixed;
            }
    }
    free(ks);
    free(rel);
    free(per);
    if (e == CL_OUT_OF_HOST_MEMORY) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    CL_TRY(l->ctx, e, "read-back");
    return HL_OK;
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
    if (l->cl->gpu_shape) {
        /* relight_items.cl: per kept slot its place in the list and its
           light, and per range its column's start and its word of tile
           bits (read by each of the range's groups, counted once: the
           cache holds them); each kept entry's halves; per position its
           scale; per vertex its albedo, place and colour */
        double b = kept * (20.0 + (double)l->nranges * 12.0) + (double)l->range_start[l->nranges] * 4.0 +
                   (double)l->nverts * (20.0 + 16.0 * l->albedo_step);
        for (size_t rg = 0; rg < l->nranges; rg++) b += per[rg] * 2.0 * HL_TILE;
        free(per);
        *bytes = b;
        return HL_OK;
    }
    /* per kept slot its place in the list and, per range, its column's
       start and end; per vertex slot its scale; per vertex its albedo,
       place and colour (the albedo one for all when albedo_step is 0).
       Then per range, by its walk (hl_tile_walk_pays):
       both read each kept entry's halves and, per kept slot and 32 tiles,
       a word of tile bits and a count (the column walk up to its last
       entry: counted whole); the column walk reads its sums too (zeroed,
       then read once they leave the cache), while the tile walk's sums
       and entry 0 stay in the cache. */
    double b = kept * (4.0 + (double)l->nranges * 8.0) + (double)l->range_start[l->nranges] * 4.0 +
               (double)l->nverts * (20.0 + 16.0 * l->albedo_step);
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
