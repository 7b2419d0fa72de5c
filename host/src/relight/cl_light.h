/* cl_light.h - the relight's device state (struct hl_cl_light), private to
 * the files that build and run it: cl_columns.c (the transport turned into
 * columns of tiles), cl_relight.c (the lighting launches) and
 * cl_light_probe.c (what bench measures of them), cl_parts.c (the dot
 * products in parts where the device holds too few of the columns).
 *
 * Depends on: cl_internal.h (OpenCL, the counted buffers), lighting.h
 * (hl_light_geom), geom.h.
 */
#ifndef HL_CL_LIGHT_H
#define HL_CL_LIGHT_H

#include "cl_internal.h"
#include "geom.h"
#include "lighting.h"

struct hl_cl_light {
    hl_context *ctx;
    struct hl_cl *cl;
    const hl_geom *g;
    const hl_light_geom *lg;
    uint32_t nverts, scheme;
    cl_uint keep_negative; /* the dot products' clamp at zero is off */
    cl_uint albedo_step;   /* 1: an albedo a position; 0: one for all (every vertex's the same) */
    cl_mem cells, turned, start, runs, slots, weight; /* tables and inputs */
    cl_mem Lp, Lw, Lsel, used, bits, res, keys;    /* lighting stages */
    cl_mem shY;                                     /* spherical harmonics in Haar's place (NULL: Haar) */
    uint32_t sh_stride, sh_count;
    cl_mem cstart, cruns;                           /* cube-face Haar: the face texels' taps (NULL: none) */
    uint32_t cube;                                  /* the faces' side; 0: none */
    cl_mem col, cols, rel, rstart, back, albedo, B, acc; /* transport, by column */
    cl_mem tally;                                   /* each work-item's clamp tally (hl_tally_add) */
    uint32_t ntally;                                /* work-items that write one */
    float *tally_host;                              /* read back with the colours */
    const float *Bmap;                              /* B mapped for reading (NULL: not mapped) */
    cl_mem ord, klist;                              /* vertex at each position; kept slots */
    void *host[4];                                  /* CPU devices: their memory */
    uint32_t nranges, *range_start;                 /* each range's first position (a work-item's in the CPU shape) */
    uint32_t range_tiles;                           /* GPU shape: tiles a range (the last may have fewer) */
    uint32_t tstride;                               /* words of 32 tiles in the largest range */
    uint64_t col_entries;                           /* tile entries in all columns */
    uint32_t *col_start;                            /* host copy, for counting bytes */
    uint32_t *order;                                /* vertex at each position */
    /* relight in parts (cl_parts.c): where the device memory limit holds
       too few of the columns at once, nparts > 1 groups of consecutive
       ranges whose columns wait in host memory (host_col, host_rel, and
       part_cs: col_start rebased to each part's buffer) and go into one
       set of part-sized buffers (col, cols, rel, rstart) before each
       part's launch. nparts is 1 when the device holds them all. */
    uint32_t nparts, *part_range;                   /* part p: ranges [part_range[p], part_range[p + 1]) */
    /* resident parts: the device holds all the columns, but not in one
       allocation (its largest, CL_DEVICE_MAX_MEM_ALLOC_SIZE, is smaller):
       each part has buffers of its own, uploaded once (pbuf[4 p ..
       4 p + 3]: col, cols, rel, rstart), and no host copy is kept */
    int resident;
    cl_mem *pbuf;
    /* rows (hl_cl_light_create_rows): no columns; the dot products walk
       the rows as loaded (kernels/relight/relight_rows.cl): the entries
       (the transport's own memory on a CPU device), row offsets, block
       counts and row parameters */
    int rows;
    cl_mem rentries, roffset, rcounts, rquant;
    uint32_t *part_cs;
    void *host_col, *host_rel;
    /* lighting captured from surroundings (hl_cl_light_set_capture): the
       capture writes Lp in env2para's place, env2para (when capture_env)
       writing the fallback lighting into Lenv first */
    struct hl_capture *capture;
    const struct hl_capture_scene *cscene;
    int capture_env;
    cl_mem Lenv;
};

/* The addresses of every device buffer of l but the resident parts' (for
 * the walks that release or count them all): an initializer list. */
#define HL_CL_LIGHT_BUFFERS(l)                                                                                         \
    {&(l)->cells, &(l)->turned, &(l)->start, &(l)->runs, &(l)->slots, &(l)->weight, &(l)->Lp, &(l)->Lw, &(l)->Lsel,    \
     &(l)->used, &(l)->bits, &(l)->res, &(l)->keys, &(l)->col, &(l)->cols, &(l)->rel, &(l)->rstart, &(l)->back,        \
     &(l)->albedo, &(l)->B, &(l)->acc, &(l)->ord, &(l)->klist, &(l)->Lenv, &(l)->rentries, &(l)->roffset,            \
     &(l)->rcounts, &(l)->rquant, &(l)->shY, &(l)->cstart, &(l)->cruns, &(l)->tally}

/* Orders the vertices, cuts them into ranges and uploads t's rows as
 * columns (cl_columns.c): l->order, range_start, nranges, tstride,
 * col_entries, col_start and the buffers col, cols, rel, rstart, back.
 * Where t holds no entries, src says where in its file to read them. */
hl_result hl_cl_light_build_columns(hl_cl_light *l, const hl_transport *t, const hl_row_source *src);

/* The sizes of a cut of the columns, for planning the parts. */
typedef struct hl_col_sizes {
    const uint32_t *cs; /* each (range, slot)'s first entry, absolute */
    uint64_t run;       /* entries including entry 0 */
    size_t nc, ts, vpad;
} hl_col_sizes;

/* Plans the parts for the counted columns (cl_parts.c): sets nparts and
 * part_range and returns HL_OK; or, where one range is too big for the
 * device memory limit and a finer cut could fit, returns HL_OK with
 * *finer set to the range multiple to cut again with (CPU devices); or
 * fails naming the limit and what the smallest part needs. */
hl_result hl_cl_light_plan_parts(hl_cl_light *l, const hl_col_sizes *z, uint32_t mult, uint32_t *finer);

/* Makes the part-sized buffers and part_cs from the built columns; takes
 * host_col and host_rel (cl_parts.c). */
hl_result hl_cl_light_make_parts(hl_cl_light *l, const hl_col_sizes *z, void *col, void *rel);

/* Enqueues part p's uploads into the part buffers (cl_parts.c); its ranges
 * count into *nr. */
hl_result hl_cl_light_enq_part(hl_cl_light *l, uint32_t p, cl_uint *nr);
/* The buffers part p's launch reads (into m[0..3]: col, cols, rel,
 * rstart): its own where the parts are resident, else the shared ones. */
void hl_cl_light_part_bufs(const hl_cl_light *l, uint32_t p, cl_mem m[4]);
/* Releases resident parts' buffers (cl_parts.c). */
void hl_cl_light_release_parts(hl_cl_light *l);

/* The work-groups of a range in the dot products, each writing its own
 * clamp tally: 1 in the CPU shape (a work-item a range); in the GPU shape
 * (relight_items.cl) a range's positions over the group size
 * (hl_cl_light_items_group). */
uint32_t hl_cl_light_range_groups(const hl_cl_light *l);
/* The GPU shape's dot products' work-group: items_wg, or a range's
 * positions where a finer cut made them fewer. */
size_t hl_cl_light_items_group(const hl_cl_light *l);

/* Enqueues the dot products into the device's colour buffer, without
 * waiting (cl_relight.c). */
hl_result hl_cl_light_enq_relight(hl_cl_light *l);

#endif
