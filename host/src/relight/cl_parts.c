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

int hl_cl_light_parts_resident(const hl_cl_light *l) { return l->resident; }

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
            /* the shared buffers take the largest part's entries and the
               most ranges of any part, which may come from two parts */
            if (part_bytes(z, me, mn) > avail) return 0;
        }
        e += er;
        n++;
        maxe = me;
        maxn = mn;
    }
    pr[++np] = l->nranges;
    return np;
}

/* In the CPU shape, asks for a cut of want ranges a core (at most a tile
 * each) when that is finer than mult: sets *finer and returns 1. In the
 * GPU shape, for ranges half as long (cl_columns.c's cut_ranges), down to
 * a tile. */
static int cut_finer(const hl_cl_light *l, uint64_t want, uint32_t mult, uint32_t *finer)
{
    const struct hl_cl *cl = l->cl;
    const uint64_t units = cl->units > 1 ? cl->units : 1, tiles = (l->nverts + HL_TILE - 1) / HL_TILE;
    if (cl->gpu_shape) {
        if (l->range_tiles <= 1 || (uint64_t)l->nranges >= tiles) return 0;
        *finer = 2 * mult;
        return 1;
    }
    if ((uint64_t)l->nranges >= tiles) return 0;
    if (want * units > tiles) want = (tiles + units - 1) / units;
    if (want <= mult) return 0;
    *finer = (uint32_t)want;
    return 1;
}

hl_result hl_cl_light_plan_parts(hl_cl_light *l, const hl_col_sizes *z, uint32_t mult, uint32_t *finer)
{
    struct hl_cl *cl = l->cl;
    *finer = 0;
    free(l->part_range);
    l->nparts = 0;
    l->part_range = malloc(((size_t)l->nranges + 1) * 4);
    if (!l->part_range) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the relight's parts");
    /* made after the columns: the albedo (16 a vertex, or one for all);
       per vertex order (4), colours (16); per padded position: running
       sums (12, the CPU shape's), scales (4); per range's work-group a
       clamp tally (16) */
    const uint64_t albedo = (l->albedo_step ? (uint64_t)l->nverts : 1) * 16;
    const uint64_t after = albedo + (uint64_t)l->nverts * 20 + (uint64_t)z->vpad * (cl->gpu_shape ? 4 : 16) +
                           (uint64_t)l->nranges * hl_cl_light_range_groups(l) * 16;
    const uint64_t held = cl->used + after + (uint64_t)z->nc * HL_PARTS_HEADROOM_PER_SLOT;
    uint64_t avail = cl->limit > held ? cl->limit - held : 0;
    const uint64_t whole = part_bytes(z, z->run - 1, l->nranges);
    /* the largest single buffer of the whole columns: entries or tile bits */
    const uint64_t col_buf = z->run * ENTRY_BYTES, rel_buf = (uint64_t)l->nranges * z->nc * z->ts * 8;
    const int fits = !cl->limit || whole <= avail;
    l->resident = 0;
    if (fits && (col_buf > rel_buf ? col_buf : rel_buf) <= cl->max_alloc) {
        l->nparts = 1;
        l->part_range[0] = 0;
        l->part_range[1] = l->nranges;
        return HL_OK;
    }
    if (fits) {
        /* the device holds them all, but no buffer may pass max_alloc:
           parts of their own buffers each, uploaded once; on a CPU device
           first cut finer, so that each part still has a range a core */
        if (mult == 1 && cl->units > 1 && !cl->gpu_shape &&
            cut_finer(l, (whole / cl->max_alloc + 1) * HL_PARTS_RANGES_PER_PART, mult, finer))
            return HL_OK;
        l->nparts = group_ranges(l, z, cl->max_alloc, l->part_range);
        l->resident = l->nparts > 0;
        if (l->nparts) return HL_OK;
    }
    /* parts uploaded in turn share one set of buffers, which must each fit
       the largest allocation too (part_bytes counts them together) */
    if (!cl->limit || avail > cl->max_alloc) avail = cl->max_alloc;
    l->nparts = group_ranges(l, z, avail, l->part_range);
    if (l->nparts) return HL_OK;
    /* one range is too big: on a CPU device cut finer, so that each range
       holds at most 1 / HL_PARTS_RANGES_PER_PART of what is free */
    if (avail) {
        const uint64_t units = cl->units > 1 ? cl->units : 1;
        uint64_t want = (whole / avail + 1) * HL_PARTS_RANGES_PER_PART / units + 1;
        if (want < 2 * (uint64_t)mult) want = 2 * (uint64_t)mult;
        if (cut_finer(l, want, mult, finer)) return HL_OK;
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

/* Resident parts upload their entries in pieces of this many bytes, each
 * piece's host pages given back once it is on the device: the peak holds
 * the columns and one piece, not the columns and one part (the 2M-vertex
 * terrain in 4 parts: 1.8 GB more). */
#define HL_RESIDENT_PIECE ((size_t)64 << 20)

/* Part p's columns, starts, tile bits and ranges into m (col, cols, rel,
 * rstart), the entries after m[0]'s entry 0; cs: the columns' absolute
 * starts. release (blocking uploads only): the host copy of the entries
 * given back piece by piece as they are uploaded. */
static hl_result upload_part(hl_cl_light *l, uint32_t p, const uint32_t *cs, const cl_mem m[4], cl_bool blocking,
                             int release)
{
    const size_t nc = l->g->ncoef, ts = l->tstride;
    const uint32_t r0 = l->part_range[p], r1 = l->part_range[p + 1], n = r1 - r0;
    const uint32_t e0 = cs[(size_t)r0 * (nc + 1)], e1 = cs[(size_t)(r1 - 1) * (nc + 1) + nc];
    cl_command_queue q = l->cl->queue;
    const size_t total = (size_t)((e1 - e0) * ENTRY_BYTES), piece = release ? HL_RESIDENT_PIECE : total;
    char *src = (char *)l->host_col + (size_t)e0 * ENTRY_BYTES;
    for (size_t at = 0; at < total; at += piece) {
        const size_t k = total - at < piece ? total - at : piece;
        CL_TRY(l->ctx, clEnqueueWriteBuffer(q, m[0], blocking, (size_t)ENTRY_BYTES + at, k, src + at, 0, NULL, NULL),
               "upload of a part's columns");
        if (release) hl_release_pages(src + at, k);
    }
    CL_TRY(l->ctx, clEnqueueWriteBuffer(q, m[1], blocking, 0, (size_t)n * (nc + 1) * 4,
                                        l->part_cs + (size_t)r0 * (nc + 1), 0, NULL, NULL),
           "upload of a part's column starts");
    CL_TRY(l->ctx, clEnqueueWriteBuffer(q, m[2], blocking, 0, (size_t)n * nc * ts * 8,
                                        (const char *)l->host_rel + (size_t)r0 * nc * ts * 8, 0, NULL, NULL),
           "upload of a part's tile bits");
    CL_TRY(l->ctx, clEnqueueWriteBuffer(q, m[3], blocking, 0, ((size_t)n + 1) * 4, l->range_start + r0, 0, NULL,
                                        NULL),
           "upload of a part's ranges");
    return HL_OK;
}

/* Buffers for a part of e entries and n ranges into m, entry 0 zeroed. */
static hl_result make_part_bufs(hl_cl_light *l, uint64_t e, uint64_t n, size_t ts, cl_mem m[4])
{
    hl_context *ctx = l->ctx;
    const size_t nc = l->g->ncoef;
    hl_result r = hl_cl_make_buf(ctx, &m[0], CL_MEM_READ_ONLY, (size_t)((e + 1) * ENTRY_BYTES), NULL,
                                 "transport columns (one part)");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &m[1], CL_MEM_READ_ONLY, (size_t)n * (nc + 1) * 4, NULL, "column starts (one part)");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &m[2], CL_MEM_READ_ONLY, (size_t)n * nc * ts * 8, NULL,
                           "the columns' tile bits (one part)");
    if (r == HL_OK)
        r = hl_cl_make_buf(ctx, &m[3], CL_MEM_READ_ONLY, (size_t)(n + 1) * 4, NULL, "ranges (one part)");
    if (r != HL_OK) return r;
    /* entry 0, all zero, stays: the part's entries go after it */
    const uint32_t zero[HL_TILE / 2] = {0};
    CL_TRY(ctx, clEnqueueWriteBuffer(l->cl->queue, m[0], CL_TRUE, 0, sizeof zero, zero, 0, NULL, NULL), "upload");
    return HL_OK;
}

/* Resident parts: each part's own buffers, uploaded once; the host copy
 * of each part's entries is given back to the system as soon as it is
 * uploaded (so the columns are not held twice), then freed. */
static hl_result make_resident(hl_cl_light *l, const hl_col_sizes *z)
{
    const size_t nc = z->nc;
    l->pbuf = calloc(4 * (size_t)l->nparts, sizeof *l->pbuf);
    if (!l->pbuf) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the relight's parts");
    for (uint32_t p = 0; p < l->nparts; p++) {
        const uint32_t r0 = l->part_range[p], r1 = l->part_range[p + 1];
        const uint32_t e0 = z->cs[(size_t)r0 * (nc + 1)], e1 = z->cs[(size_t)(r1 - 1) * (nc + 1) + nc];
        cl_mem *m = l->pbuf + 4 * (size_t)p;
        TRY(make_part_bufs(l, e1 - e0, r1 - r0, z->ts, m));
        TRY(upload_part(l, p, z->cs, m, CL_TRUE, 1));
    }
    hl_free_big(l->host_col);
    hl_free_big(l->host_rel);
    free(l->part_cs);
    l->host_col = l->host_rel = NULL;
    l->part_cs = NULL;
    return HL_OK;
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
    if (l->resident) return make_resident(l, z);
    cl_mem m[4] = {NULL, NULL, NULL, NULL};
    hl_result r = make_part_bufs(l, maxe, maxn, z->ts, m);
    l->col = m[0];
    l->cols = m[1];
    l->rel = m[2];
    l->rstart = m[3];
    return r;
}

hl_result hl_cl_light_enq_part(hl_cl_light *l, uint32_t p, cl_uint *nr)
{
    *nr = l->part_range[p + 1] - l->part_range[p];
    if (l->resident) return HL_OK; /* on the device since creation */
    /* not waited for: the host copies live as long as the relighter, and
       the queue runs in order, so the next part's uploads wait for this
       part's launch */
    const cl_mem m[4] = {l->col, l->cols, l->rel, l->rstart};
    return upload_part(l, p, l->col_start, m, CL_FALSE, 0);
}

void hl_cl_light_part_bufs(const hl_cl_light *l, uint32_t p, cl_mem m[4])
{
    if (l->resident && l->nparts > 1) {
        memcpy(m, l->pbuf + 4 * (size_t)p, 4 * sizeof *m);
        return;
    }
    m[0] = l->col;
    m[1] = l->cols;
    m[2] = l->rel;
    m[3] = l->rstart;
}

void hl_cl_light_release_parts(hl_cl_light *l)
{
    for (size_t i = 0; l->pbuf && i < 4 * (size_t)l->nparts; i++) hl_cl_release_buf(l->cl, &l->pbuf[i]);
    free(l->pbuf);
    l->pbuf = NULL;
}
