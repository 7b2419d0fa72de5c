/* enclosed.c - a body's vertices inside its own closed parts (enclosed.h):
 * Embree closest hits along a few directions over each vertex's
 * hemisphere, each hit tested for a back face by its winding.
 * Depends on: enclosed.h, rays.h, core.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "enclosed.h"
#include "rays.h"

/* The winding's normal of triangle t (not unit). */
static void tri_normal(const hl_dyn_object *o, uint32_t t, double ng[3])
{
    const float *a = o->pos + 3 * (size_t)o->tri[3 * (size_t)t], *b = o->pos + 3 * (size_t)o->tri[3 * (size_t)t + 1],
                *c = o->pos + 3 * (size_t)o->tri[3 * (size_t)t + 2];
    const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    ng[0] = e1[1] * e2[2] - e1[2] * e2[1], ng[1] = e1[2] * e2[0] - e1[0] * e2[2], ng[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

/* Whether the body's winding agrees with its normals on the share of
 * triangles HL_ENCLOSED_WINDING_SHARE asks. */
static int winding_trusted(const hl_dyn_object *o)
{
    uint64_t agree = 0;
    for (uint32_t t = 0; t < o->ntris; t++) {
        double ng[3], s = 0.0;
        tri_normal(o, t, ng);
        for (int c = 0; c < 3; c++) {
            const float *n = o->normal + 3 * (size_t)o->tri[3 * (size_t)t + c];
            s += ng[0] * n[0] + ng[1] * n[1] + ng[2] * n[2];
        }
        agree += s > 0.0;
    }
    return (double)agree >= HL_ENCLOSED_WINDING_SHARE * (double)o->ntris;
}

/* Whether each of the nvl vertices vl passes: every one of its rays
 * along dirs (nd, those at least HL_ENCLOSED_MIN_COS above its horizon,
 * and its normal) first meets a face of the body from behind, beyond
 * HL_ENCLOSED_MIN_GAP offsets. pass[i] for vl[i]. */
static hl_result enclosed_pass(hl_context *ctx, hl_rt *rt, const hl_dyn_object *o, const uint32_t *vl, uint32_t nvl,
                               const float (*dirs)[3], uint32_t nd, uint8_t *pass)
{
    const uint32_t chunk = 131072u / (nd + 1) > 0 ? 131072u / (nd + 1) : 1, rays = chunk * (nd + 1);
    float *org = malloc((size_t)rays * 12), *dir = malloc((size_t)rays * 12);
    float *u = malloc((size_t)rays * 4), *v = malloc((size_t)rays * 4);
    uint32_t *prim = malloc((size_t)rays * 4), *first = malloc(((size_t)chunk + 1) * sizeof *first);
    hl_result r = HL_OK;
    if (!(org && dir && u && v && prim && first))
        r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the enclosed vertices' rays");
    for (uint32_t i0 = 0; r == HL_OK && i0 < nvl; i0 += chunk) {
        const uint32_t nv = nvl - i0 < chunk ? nvl - i0 : chunk;
        uint32_t n = 0;
        for (uint32_t i = 0; i < nv; i++) {
            const uint32_t vi = vl[i0 + i];
            const float *p = o->pos + 3 * (size_t)vi, *nn = o->normal + 3 * (size_t)vi;
            const float off = hl_rt_robust_offset(rt, vi);
            float oo[3];
            for (int c = 0; c < 3; c++) oo[c] = hl_rt_origin_coord(p[c], nn[c], off);
            first[i] = n;
            for (uint32_t k = 0; k <= nd; k++) {
                const float *d = k < nd ? dirs[k] : nn;
                if (k < nd && d[0] * nn[0] + d[1] * nn[1] + d[2] * nn[2] < HL_ENCLOSED_MIN_COS) continue;
                memcpy(org + 3 * (size_t)n, oo, 12);
                memcpy(dir + 3 * (size_t)n, d, 12);
                n++;
            }
        }
        first[nv] = n;
        r = hl_rt_trace_primary(rt, n, org, dir, prim, u, v);
        for (uint32_t i = 0; r == HL_OK && i < nv; i++) {
            const float off = hl_rt_robust_offset(rt, vl[i0 + i]);
            int all = first[i + 1] > first[i];
            for (uint32_t k = first[i]; all && k < first[i + 1]; k++) {
                if (prim[k] == UINT32_MAX) { all = 0; break; }
                double ng[3];
                tri_normal(o, prim[k], ng);
                const float *d = dir + 3 * (size_t)k;
                all = ng[0] * d[0] + ng[1] * d[1] + ng[2] * d[2] > 0.0; /* met from behind */
                /* a face met within a few offsets is a twin of the vertex's
                   own (a sheet modelled with both sides), not a shell */
                const uint32_t *tv = o->tri + 3 * (size_t)prim[k];
                const float *A = o->pos + 3 * (size_t)tv[0], *B = o->pos + 3 * (size_t)tv[1], *C = o->pos + 3 * (size_t)tv[2];
                const float *q = org + 3 * (size_t)k;
                double dd = 0.0;
                for (int c = 0; c < 3; c++) {
                    const double h = (1.0 - u[k] - v[k]) * A[c] + u[k] * B[c] + v[k] * C[c] - q[c];
                    dd += h * h;
                }
                if (sqrt(dd) < HL_ENCLOSED_MIN_GAP * off) all = 0;
            }
            pass[i0 + i] = (uint8_t)all;
        }
    }
    free(org); free(dir); free(u); free(v); free(prim); free(first);
    return r;
}

hl_result hl_dyn_enclosed(hl_context *ctx, const hl_dyn_object *o, uint8_t *out, uint32_t *count)
{
    memset(out, 0, o->nverts);
    *count = 0;
    if (!o->normal || !o->ntris || !winding_trusted(o)) return HL_OK;
    /* the first pass: the 26 directions of a 3 x 3 x 3 grid */
    float grid[26][3], fib[HL_ENCLOSED_CONFIRM][3];
    uint32_t nd = 0;
    for (int z = -1; z <= 1; z++)
        for (int y = -1; y <= 1; y++)
            for (int x = -1; x <= 1; x++) {
                if (!x && !y && !z) continue;
                const float l = sqrtf((float)(x * x + y * y + z * z));
                grid[nd][0] = (float)x / l, grid[nd][1] = (float)y / l, grid[nd][2] = (float)z / l;
                nd++;
            }
    /* the confirmation: a Fibonacci sphere, about 20 degrees apart */
    for (uint32_t k = 0; k < HL_ENCLOSED_CONFIRM; k++) {
        const double y = 1.0 - (2.0 * k + 1.0) / HL_ENCLOSED_CONFIRM, rr = sqrt(fmax(0.0, 1.0 - y * y));
        const double ph = (double)k * 2.39996322972865332;
        fib[k][0] = (float)(rr * cos(ph)), fib[k][1] = (float)y, fib[k][2] = (float)(rr * sin(ph));
    }
    /* the body as a mesh for Embree (borrowed arrays, not modified) */
    hl_mesh m = {.vertex_count = o->nverts, .triangle_count = o->ntris, .object_vertex_count = o->nverts,
                 .positions = (float *)o->pos, .normals = (float *)o->normal, .indices = (uint32_t *)o->tri};
    hl_rt *rt = NULL;
    hl_result r = hl_rt_create(ctx, &m, &rt);
    if (r != HL_OK) return r;
    uint32_t *vl = malloc((size_t)o->nverts * sizeof *vl);
    uint8_t *pass = malloc(o->nverts);
    if (!vl || !pass) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u vertices' enclosure", o->nverts);
    for (uint32_t v = 0; r == HL_OK && v < o->nverts; v++) vl[v] = v;
    if (r == HL_OK) r = enclosed_pass(ctx, rt, o, vl, o->nverts, (const float(*)[3])grid, nd, pass);
    uint32_t nc = 0;
    for (uint32_t v = 0; r == HL_OK && v < o->nverts; v++)
        if (pass[v]) vl[nc++] = v;
    if (r == HL_OK && nc) r = enclosed_pass(ctx, rt, o, vl, nc, (const float(*)[3])fib, HL_ENCLOSED_CONFIRM, pass);
    for (uint32_t i = 0; r == HL_OK && i < nc; i++)
        if (pass[i]) out[vl[i]] = 1, (*count)++;
    free(vl);
    free(pass);
    hl_rt_destroy(rt);
    return r;
}
