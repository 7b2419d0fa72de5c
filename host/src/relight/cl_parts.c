/* cl_parts.c - the dot products in parts. Where the device memory limit
 * (the device's own, or hl_context_desc.device_memory: --device-memory,
 * HL_DEVICE_MEMORY) holds too few of the transport columns at once,
 * consecutive ranges are grouped into parts that fit, the columns wait in
 * host memory, and each lighting change uploads part after part into one
 * set of part-sized buffers just before that part's launch.
 *
 * Each vertex adds its kept terms in ascending slot order whatever range
 * or walk it is in (kernels/relight/relight.cl), so the colours are those
 * of one launch over all the columns, bit for bit; only the time of the
 * uploads is added.
 *
 * Depends on: cl_light.h (the device state, the column layout), OpenCL.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_light.h"

/* bytes of one column entry: HL_TILE halves */
#define ENTRY_BYTES ((uint64_t)2 * HL_TILE)

/* Device memory left free, per lighting slot, for what a relighter makes
 * later (the capture of surroundings: 68 bytes a slot of cone table and
 * lighting, the rest for some thousand triangles at 160 bytes; 1 MiB at
 * N = 64), so that a plan that just fits does not make those fail. */
#define HL_PARTS_HEADROOM_PER_SLOT 128u

/* Each range in a finer cut holds at most this fraction of the memory
 * left for the columns, so a part gathers several ranges (one per core at
 * least) and the cores stay busy. */
#define HL_PARTS_RANGES_PER_PART 2u

/* Bytes of the part buffers for a part of e entries (entry 0 not counted)
 * and n ranges: entries, starts, tile bits (8 bytes a slot and 32 tiles),
 * range starts. */
static uint64_t part_bytes(const hl_col_sizes *z, uint64_t e, uint64_t n)
{
    return (e + 1) * ENTRY_BYTES + n * (z->nc + 1) * 4 + n * z->nc * z->ts * 8 + (n + 1) * 4;
}

/* Entries of range rg: from its slot 0's start to its last slot's end. */
static uint64_t range_entries(const hl_col_sizes *z, size_t rg)
{
    return (uint64_t)z->cs[rg * (z->nc + 1) + z->nc] - z->cs[rg * (z->nc + 1)];
}

uint32_t hl_cl_light_parts(const hl_cl_light *l) { return l->nparts; }

uint64_t hl_cl_light_column_bytes(const hl_cl_light *l)
{
    const hl_col_sizes z = {NULL, l->col_entries + 1, l->g->ncoef, l->tstride, 0};
    return part_bytes(&z, l->col_entries, l->nranges);
}

static double mib(uint64_t b) { return (double)b / (double)(1u << 20); }

/* Groups the ranges greedily into parts, each making the part buffers
 * (sized by the largest part's entries and ranges) no larger than avail.
 * Returns the part count, 0 when one range alone is too big. */
static uint32_t group_ranges(hl_cl_light *l, const hl_col_sizes *z, uint64_t avail, uint32_t *pr)
{
    uint64_t maxe = 0, maxn = 0, e = 0, n = 0;
    uint32_t np = 0;
    pr[0] = 0;
    for (uint32_t rg = 0; rg < l->nranges; rg++) {
        const uint64_t er = range_entries(z, rg);
        if (part_bytes(z, er, 1) > avail) return 0;
        uint64_t me = e + er > maxe ? e + er : maxe, mn = n + 1 > maxn ? n + 1 : maxn;
        if (n && part_bytes(z, me, mn) > avail) { /* close the part before rg */
            pr[++np] = rg;
            e = n = 0;
            me = er > maxe ? er : maxe;
            mn = maxn > 1 ? maxn : 1;
        }
        e += er;
        n++;
        maxe = me;
        maxn = mn;
    }
    pr[++np] = l->nranges;
    return np;
}

hl_result hl_cl_light_plan_parts(hl_cl_light *l, const hl_col_sizes *z, uint32_t mult, uint32_t *finer)
{
    struct hl_cl *cl = l->cl;
    *finer = 0;
    free(l->part_range);
    l->nparts = 0;
    l->part_range = malloc(((size_t)l->nranges + 1) * 4);
    if (!l->part_range) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the relight's parts");
    /* made after the columns, per vertex: albedo (16), order (4), colours
       (16); per padded position: running sums (12), scales (4) */
    const uint64_t after = (uint64_t)l->nverts * 36 + (uint64_t)z->vpad * 16;
    const uint64_t held = cl->used + after + (uint64_t)z->nc * HL_PARTS_HEADROOM_PER_SLOT;
    const uint64_t avail = cl->limit > held ? cl->limit - held : 0;
    const uint64_t whole = part_bytes(z, z->run - 1, l->nranges);
    if (!cl->limit || whole <= avail) {
        l->nparts = 1;
        l->part_range[0] = 0;
        l->part_range[1] = l->nranges;
        return HL_OK;
    }
    l->nparts = group_ranges(l, z, avail, l->part_range);
    if (l->nparts) return HL_OK;
    /* one range is too big: on a CPU device cut finer, so that each range
       holds at most 1 / HL_PARTS_RANGES_PER_PART of what is free */
    const uint64_t units = cl->units > 1 ? cl->units : 1, tiles = (l->nverts + HL_TILE - 1) / HL_TILE;
    if (cl->wg == 1 && avail && (uint64_t)l->nranges < tiles) {
        uint64_t want = (whole / avail + 1) * HL_PARTS_RANGES_PER_PART / units + 1;
        if (want < 2 * (uint64_t)mult) want = 2 * (uint64_t)mult;
        if (want * units > tiles) want = (tiles + units - 1) / units;
        if (want > mult) {
            *finer = (uint32_t)want;
            return HL_OK;
        }
    }
    const char *lim = cl->limit_set ? " (--device-memory or HL_DEVICE_MEMORY)" : " (the device's)";
    const char *raise = cl->limit_set ? "raise the limit or " : "";
    if (!avail)
        return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY,
                       "OpenCL: the device memory limit of %.1f MiB%s leaves nothing for the transport columns: the "
                       "other buffers and the vertices' own need %.1f MiB; %suse --device ref",
                       mib(cl->limit), lim, mib(held), raise);
    uint64_t least = UINT64_MAX;
    uint32_t least_v = 0;
    for (uint32_t rg = 0; rg < l->nranges; rg++) {
        const uint64_t b = part_bytes(z, range_entries(z, rg), 1);
        if (b < least) {
            least = b;
            least_v = l->range_start[rg + 1] - l->range_start[rg];
        }
    }
    return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY,
                   "OpenCL: the device memory limit of %.1f MiB%s leaves %.1f MiB for the transport columns (the other "
                   "buffers and the vertices' own need %.1f MiB), and the smallest part (%u vertices) needs %.1f MiB; "
                   "%suse --device ref",
                   mib(cl->limit), lim, mib(avail), mib(held), least_v, mib(least), raise);
}

hl_result hl_cl_light_make_parts(hl_cl_light *l, const hl_col_sizes *z, void *col, void *rel)
{
    const size_t nc = z->nc;
    l->host_col = col;
    l->host_rel = rel;
    l->part_cs = malloc((size_t)l->nranges * (nc + 1) * 4);
    if (!l->part_cs) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the relight's parts");
    uint64_t maxe = 0, maxn = 0;
    for (uint32_t p = 0; p < l->nparts; p++) {
        const uint32_t r0 = l->part_range[p], r1 = l->part_range[p + 1];
        /* the part's entries follow entry 0 of its buffer */
        const uint32_t e0 = z->cs[(size_t)r0 * (nc + 1)], e1 = z->cs[(size_t)(r1 - 1) * (nc + 1) + nc];
        for (size_t i = (size_t)r0 * (nc + 1); i < (size_t)r1 * (nc + 1); i++) l->part_cs[i] = z->cs[i] - e0 + 1;
        if (e1 - e0 > maxe) maxe = e1 - e0;
        if (r1 - r0 > maxn) maxn = r1 - r0;
    }
    hl_context *ctx = l->ctx;
    hl_result r = hl_cl_make_buf(ctx, &l->col, CL_MEM_READ_ONLY, (size_t)((maxe + 1) * ENTRY_BYTES), NULL,
                                 "transport columns (one part)");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &l->cols, CL_MEM_READ_ONLY, (size_t)maxn * (nc + 1) * 4, NULL, "column starts (one part)");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &l->rel, CL_MEM_READ_ONLY, (size_t)maxn * nc * z->ts * 8, NULL,
                           "the columns' tile bits (one part)");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &l->rstart, CL_MEM_READ_ONLY, (size_t)(maxn + 1) * 4, NULL, "ranges (one part)");
    if (r != HL_OK) return r;
    /* entry 0, all zero, stays: each part's entries go after it */
    const uint32_t zero[HL_TILE / 2] = {0};
    CL_TRY(ctx, clEnqueueWriteBuffer(l->cl->queue, l->col, CL_TRUE, 0, sizeof zero, zero, 0, NULL, NULL), "upload");
    return HL_OK;
}

hl_result hl_cl_light_enq_part(hl_cl_light *l, uint32_t p, cl_uint *nr)
{
    const size_t nc = l->g->ncoef, ts = l->tstride;
    const uint32_t r0 = l->part_range[p], r1 = l->part_range[p + 1], n = r1 - r0;
    const uint32_t e0 = l->col_start[(size_t)r0 * (nc + 1)], e1 = l->col_start[(size_t)(r1 - 1) * (nc + 1) + nc];
    cl_command_queue q = l->cl->queue;
    /* not waited for: the host copies live as long as the relighter, and
       the queue runs in order, so the next part's uploads wait for this
       part's launch */
    if (e1 > e0)
        CL_TRY(l->ctx, clEnqueueWriteBuffer(q, l->col, CL_FALSE, (size_t)ENTRY_BYTES, (size_t)((e1 - e0) * ENTRY_BYTES),
                                            (const char *)l->host_col + (size_t)e0 * ENTRY_BYTES, 0, NULL, NULL),
               "upload of a part's columns");
    CL_TRY(l->ctx, clEnqueueWriteBuffer(q, l->cols, CL_FALSE, 0, (size_t)n * (nc + 1) * 4,
                                        l->part_cs + (size_t)r0 * (nc + 1), 0, NULL, NULL),
           "upload of a part's column starts");
    CL_TRY(l->ctx, clEnqueueWriteBuffer(q, l->rel, CL_FALSE, 0, (size_t)n * nc * ts * 8,
                                        (const char *)l->host_rel + (size_t)r0 * nc * ts * 8, 0, NULL, NULL),
           "upload of a part's tile bits");
    CL_TRY(l->ctx, clEnqueueWriteBuffer(q, l->rstart, CL_FALSE, 0, ((size_t)n + 1) * 4, l->range_start + r0, 0, NULL,
                                        NULL),
           "upload of a part's ranges");
    *nr = n;
    return HL_OK;
}
