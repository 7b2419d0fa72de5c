/* bench_dyn_refs.c - what `haarlight bench-dynamic` measures the dynamic
 * method against (haarlight_tools.h, "bench-dynamic"): the exact and the
 * K-lights references of dyn_reference.h and the traced method of
 * dyn_traced.h, on a dynamic scene's bodies as of its last frame, with
 * its albedo and its lights, colours in hl_dynamic_mesh's vertex order.
 * Depends on: dyn_api.h (the handle's insides), dyn_reference.h,
 * dyn_traced.h, core.
 */
#include <stdlib.h>

#include "dyn_api.h"
#include "dyn_reference.h"
#include "dyn_traced.h"
#include "haarlight_tools.h"
#include "hl_internal.h"

_Static_assert(HL_BENCH_TRACED_MAX_S == HL_DYNTRACED_MAX_S, "the tools' S limit is the traced method's");

/* Per-body pointers into rgb (3 floats per vertex of the merged mesh). */
static float **body_rows(const hl_dynamic_view *v, float *rgb)
{
    float **rows = hl_calloc(v->ctx, v->nb, sizeof *rows, "the bench's colour rows");
    for (uint32_t b = 0; rows && b < v->nb; b++) rows[b] = rgb + 3 * (size_t)v->vstart[b];
    return rows;
}

hl_result hl_bench_dyn_exact(hl_dynamic *d, const hl_env *env, float *rgb, double *seconds)
{
    if (!d || !rgb) return HL_ERR_INVALID_ARGUMENT;
    hl_dynamic_view v;
    hl_dynamic_view_get(d, &v);
    float **rows = body_rows(&v, rgb);
    if (!rows) return HL_ERR_OUT_OF_MEMORY;
    hl_dyn_ref_stats st = {0};
    hl_result r = hl_dyn_reference_exact(v.ctx, v.obj, v.nb, v.alb, env, 0, 0, rows, &st);
    if (seconds) *seconds = st.seconds;
    free(rows);
    return r;
}

hl_result hl_bench_dyn_lights(hl_dynamic *d, float *rgb, double *seconds)
{
    if (!d || !rgb) return HL_ERR_INVALID_ARGUMENT;
    hl_dynamic_view v;
    hl_dynamic_view_get(d, &v);
    if (!v.split) return hl_fail(v.ctx, HL_ERR_INVALID_ARGUMENT, "K-lights reference: no environment set");
    float **rows = body_rows(&v, rgb);
    if (!rows) return HL_ERR_OUT_OF_MEMORY;
    hl_dyn_ref_stats st = {0};
    hl_result r = hl_dyn_reference_lights(v.ctx, v.obj, v.nb, v.alb, v.split, 0, rows, &st);
    if (seconds) *seconds = st.seconds;
    free(rows);
    return r;
}

hl_result hl_bench_dyn_traced(hl_dynamic *d, uint32_t S, float *rgb, hl_bench_traced_times *times)
{
    if (!d || !rgb) return HL_ERR_INVALID_ARGUMENT;
    hl_dynamic_view v;
    hl_dynamic_view_get(d, &v);
    if (!v.split) return hl_fail(v.ctx, HL_ERR_INVALID_ARGUMENT, "traced method: no environment set");
    float **rows = body_rows(&v, rgb);
    if (!rows) return HL_ERR_OUT_OF_MEMORY;
    hl_dyn_traced_stats st = {0};
    hl_result r = hl_dyn_traced(v.ctx, v.obj, v.nb, v.alb, v.split, S, rows, &st);
    if (times) {
        times->seconds = st.seconds, times->t_build = st.t_build, times->t_rays = st.t_rays;
        times->t_trace = st.t_trace, times->t_shade = st.t_shade, times->rays = st.rays_cast;
    }
    free(rows);
    return r;
}
