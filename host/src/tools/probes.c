/* probes.c - the benchmarks' measurements of the machine: what the dot
 * products read, the dot-product kernel timed alone, the device's read
 * bandwidth (`bench`), and Embree's raw occlusion rate on the precompute's
 * rays (`bench-precompute`).
 *
 * Depends on the OpenCL backend (cl_backend.h), the relighter's internals
 * (lighting.h), the precompute's option checks (precompute.h) and the ray
 * caster (rays.h).
 */
#include "cl_backend.h"
#include "haarlight_tools.h"
#include "lighting.h"
#include "precompute.h"
#include "rays.h"

/* Each measure below over every plane's device where the transport has a
 * row a channel (hl_relighter_planes): their bytes and times add. */
static hl_result sum_planes(hl_relighter *r, uint32_t reps, double *sum,
                            hl_result (*measure)(hl_cl_light *, uint32_t, double *))
{
    hl_relighter *sub[3];
    const uint32_t n = hl_relighter_planes(r, sub);
    *sum = 0.0;
    for (uint32_t c = 0; c < n; c++) {
        hl_cl_light *l = hl_relighter_device(sub[c]); /* NULL on the reference backend */
        if (!l) return hl_fail(NULL, HL_ERR_UNSUPPORTED, "no OpenCL device behind this relighter");
        double one;
        hl_result res = measure(l, reps, &one);
        if (res != HL_OK) return res;
        *sum += one;
    }
    return HL_OK;
}

static hl_result bytes_of(hl_cl_light *l, uint32_t reps, double *bytes)
{
    (void)reps;
    return hl_cl_light_bytes_read(l, bytes);
}

hl_result hl_bench_bytes_read(hl_relighter *r, double *bytes) { return sum_planes(r, 0, bytes, bytes_of); }

hl_result hl_bench_time_dots(hl_relighter *r, uint32_t reps, double *seconds)
{
    return sum_planes(r, reps, seconds, hl_cl_light_time_relight);
}

hl_result hl_bench_time_capture(hl_relighter *r, uint32_t reps, double *seconds)
{
    return sum_planes(r, reps, seconds, hl_cl_light_time_capture);
}

hl_result hl_bench_read_bandwidth(hl_context *ctx, size_t bytes, uint32_t reps, double *bytes_per_s)
{
    return hl_cl_read_bandwidth(ctx, bytes, reps, bytes_per_s);
}

hl_result hl_bench_precompute_resolve(hl_context *ctx, hl_precompute_desc *d)
{
    return hl_precompute_resolve(ctx, d);
}

hl_result hl_bench_raw_ray_rates(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *resolved,
                                 const uint32_t *verts, uint32_t nverts, uint32_t rounds, double *rays_per_s)
{
    hl_geom *g = NULL;
    hl_rt *rt = NULL;
    hl_result r = hl_geom_create(ctx, resolved->N, resolved->C, &g);
    if (r == HL_OK) r = hl_rt_create(ctx, mesh, &rt);
    const float offset = resolved->ray_offset * hl_mesh_query_diagonal(mesh);
    for (uint32_t k = 0; k < rounds && r == HL_OK; k++)
        r = hl_rt_raw_rate(rt, g, mesh, verts, nverts, resolved->supersample, offset, &rays_per_s[k]);
    hl_rt_destroy(rt);
    hl_geom_destroy(g);
    return r;
}
