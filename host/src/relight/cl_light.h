/* cl_light.h - the relight's device state (struct hl_cl_light), private to
 * the files that build and run it: cl_columns.c (the transport turned into
 * columns of tiles), cl_relight.c (the lighting launches) and
 * cl_light_probe.c (what bench measures of them).
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
    cl_mem cells, turned, start, runs, slots, weight; /* tables and inputs */
    cl_mem Lp, Lw, Lsel, used, bits, res, keys;    /* lighting stages */
    cl_mem col, cols, rel, rstart, back, albedo, B, acc; /* transport, by column */
    cl_mem ord, klist;                              /* vertex at each position; kept slots */
    void *host[4];                                  /* CPU devices: their memory */
    uint32_t nranges, *range_start;                 /* vertices of each work-item */
    uint32_t tstride;                               /* most tiles in a range */
    uint64_t col_entries;                           /* tile entries in all columns */
    uint32_t *col_start;                            /* host copy, for counting bytes */
    uint32_t *order;                                /* vertex at each position */
    /* lighting captured from surroundings (hl_cl_light_set_capture): the
       capture writes Lp in env2para's place, env2para (when capture_env)
       writing the fallback lighting into Lenv first */
    struct hl_capture *capture;
    const struct hl_capture_scene *cscene;
    int capture_env;
    cl_mem Lenv;
};

/* Orders the vertices, cuts them into ranges and uploads t's rows as
 * columns (cl_columns.c): l->order, range_start, nranges, tstride,
 * col_entries, col_start and the buffers col, cols, rel, rstart, back. */
hl_result hl_cl_light_build_columns(hl_cl_light *l, const hl_transport *t);

/* Enqueues the dot products into the device's colour buffer, without
 * waiting (cl_relight.c). */
hl_result hl_cl_light_enq_relight(hl_cl_light *l);

#endif
