/* dyn_reference.c - the exact reference of the dynamic method and its
 * K-lights variant (dyn_reference.h): the bodies merged into one
 * world-space mesh, one Embree scene of it, and per vertex one occlusion
 * ray per cube texel (S x S with supersampling) from rays.c's robust
 * offset, on ctx's threads; the texels carry the map's energy and first
 * moment as area_lights.c resamples them.
 * Depends on: dyn_reference.h, area_lights.h, dyn_frame.h
 * (hl_frame_to_world), rays.h and geom.h (visibility), core.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "area_lights.h"
#include "dyn_frame.h"
#include "dyn_reference.h"
#include "geom.h"
#include "hl_internal.h"
#include "rays.h"

#define PI_D 3.14159265358979323846

/* Vertices traced at once: their visibility rows (6 F^2 bytes each, 25 MB
 * at F = 64) are summed before the next chunk, so memory stays bounded on
 * any mesh while a chunk keeps every thread busy. */
#define HL_DYNREF_CHUNK 1024u

/* The paraboloid resolution hl_geom_create needs beside the cube (its
 * smallest): the reference uses only the cube's directions. */
#define HL_DYNREF_GEOM_N 8u

typedef struct ref_job {
    hl_context *ctx;
    const hl_dyn_object *obj;
    uint32_t nobj;
    const float *const *albedo;
    float *const *rgb;
    const hl_light_split *split;
    uint32_t S;
    int lights;        /* 0: exact, 1: kept lights with traced visibility */
    hl_mesh world;     /* merged, world space */
    uint32_t *vstart;  /* nobj + 1 */
} ref_job;

static void job_free(ref_job *j)
{
    free(j->world.positions); free(j->world.normals); free(j->world.indices); free(j->vstart);
}

hl_result hl_dyn_world_merge(hl_context *ctx, const hl_dyn_object *obj, uint32_t nobj, hl_mesh *m, uint32_t *vstart)
{
    uint64_t nv = 0, nt = 0;
    memset(m, 0, sizeof *m);
    for (uint32_t b = 0; b < nobj; b++) {
        const hl_dyn_object *o = &obj[b];
        if (!o->pos || !o->tri) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: body %u has a NULL array", b);
        for (size_t i = 0; i < 3 * (size_t)o->ntris; i++)
            if (o->tri[i] >= o->nverts)
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: body %u indexes vertex %u of %u", b,
                               o->tri[i], o->nverts);
        vstart[b] = (uint32_t)nv;
        nv += o->nverts, nt += o->ntris;
        if (nv > UINT32_MAX / 3 || nt > UINT32_MAX / 3)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: too many vertices or triangles");
    }
    vstart[nobj] = (uint32_t)nv;
    m->vertex_count = m->object_vertex_count = (uint32_t)nv, m->triangle_count = (uint32_t)nt;
    m->positions = malloc(nv * 12 + 12), m->normals = malloc(nv * 12 + 12), m->indices = malloc(nt * 12 + 12);
    if (!m->positions || !m->normals || !m->indices)
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's world mesh");
    for (uint32_t b = 0, t0 = 0; b < nobj; b++) {
        const hl_dyn_object *o = &obj[b];
        hl_frame_to_world(o, m->positions + 3 * (size_t)vstart[b], m->normals + 3 * (size_t)vstart[b]);
        for (size_t i = 0; i < 3 * (size_t)o->ntris; i++) m->indices[3 * (size_t)t0 + i] = o->tri[i] + vstart[b];
        t0 += o->ntris;
    }
    for (size_t i = 0; i < 3 * nv; i++)
        if (!isfinite(m->positions[i]) || !isfinite(m->normals[i]))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: a position or normal is not finite");
    return HL_OK;
}

/* The bodies merged into j->world at their transforms. */
static hl_result merge_world(ref_job *j)
{
    j->vstart = calloc((size_t)j->nobj + 1, sizeof(uint32_t));
    if (!j->vstart) return hl_fail(j->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference");
    for (uint32_t b = 0; b < j->nobj; b++)
        if (!j->albedo[b] || !j->rgb[b])
            return hl_fail(j->ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: body %u has a NULL array", b);
    return hl_dyn_world_merge(j->ctx, j->obj, j->nobj, &j->world, j->vstart);
}

/* The body of world vertex v and its index in the body. */
static uint32_t body_of(const ref_job *j, uint32_t v, uint32_t *local)
{
    uint32_t b = 0;
    while (v >= j->vstart[b + 1]) b++;
    *local = v - j->vstart[b];
    return b;
}

/* Exact: sum over texels of their unoccluded share times max(0, n . moment). */
static void shade_exact(const ref_job *j, const float *n, const uint8_t *row, double E[3])
{
    const hl_light_split *s = j->split;
    const uint32_t nt = 6 * s->F * s->F;
    const double inv = 1.0 / ((double)j->S * j->S);
    E[0] = E[1] = E[2] = 0;
    for (uint32_t t = 0; t < nt; t++) {
        if (!row[t]) continue;
        const float *m = s->texel_moment + 9 * (size_t)t;
        for (int c = 0; c < 3; c++) {
            double d = (double)n[0] * m[3 * c] + (double)n[1] * m[3 * c + 1] + (double)n[2] * m[3 * c + 2];
            if (d > 0.0) E[c] += d * row[t] * inv;
        }
    }
}

/* Kept lights: V_k from the traced texels above the horizon weighted by
 * their energy's luminance, times E_k; plus the folded ambient. num, den:
 * split->count scratch each. */
static void shade_lights(const ref_job *j, const float *n, const uint8_t *row, double *num, double *den, double E[3])
{
    const hl_light_split *s = j->split;
    const uint32_t nt = 6 * s->F * s->F, K = s->count;
    const double inv = 1.0 / ((double)j->S * j->S);
    memset(num, 0, K * sizeof *num), memset(den, 0, K * sizeof *den);
    for (uint32_t t = 0; t < nt; t++) {
        uint32_t k = s->owner[t];
        if (k >= K) continue;
        const float *d = s->texel_dir + 3 * (size_t)t, *e = s->texel_energy + 3 * (size_t)t;
        if (n[0] * d[0] + n[1] * d[1] + n[2] * d[2] <= 0.0f) continue;
        double w = 0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2];
        den[k] += w, num[k] += w * row[t] * inv;
    }
    float a[3];
    hl_light_split_ambient(s, n, a);
    for (int c = 0; c < 3; c++) E[c] = a[c];
    for (uint32_t k = 0; k < K; k++) {
        float Ek[3];
        hl_area_light_irradiance(s, k, n, Ek);
        /* no texel above the horizon: E_k is 0 (or a sliver), V = 1 */
        double V = den[k] > 0.0 ? num[k] / den[k] : 1.0;
        for (int c = 0; c < 3; c++) E[c] += V * Ek[c];
    }
}

static hl_result run(ref_job *j, hl_dyn_ref_stats *stats)
{
    double t0 = hl_now();
    hl_result r = merge_world(j);
    hl_rt *rt = NULL;
    hl_geom *g = NULL;
    uint8_t *vis = NULL;
    double *scratch = NULL;
    const uint32_t F = j->split->F, nv = j->world.vertex_count;
    hl_vis_counts counts = {0, 0};
    if (r == HL_OK) r = hl_rt_create(j->ctx, &j->world, &rt);
    if (r == HL_OK) r = hl_geom_create(j->ctx, HL_DYNREF_GEOM_N, F, &g);
    if (r == HL_OK) {
        vis = hl_malloc(j->ctx, (size_t)HL_DYNREF_CHUNK * g->ncube, "the reference's visibility rows");
        scratch = hl_calloc(j->ctx, 2 * (size_t)j->split->count + 2, sizeof(double), "the reference's light sums");
        if (!vis || !scratch) r = HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t v0 = 0; r == HL_OK && v0 < nv; v0 += HL_DYNREF_CHUNK) {
        uint32_t cnt = nv - v0 < HL_DYNREF_CHUNK ? nv - v0 : HL_DYNREF_CHUNK;
        r = hl_rt_visibility(rt, g, &j->world, v0, cnt, j->S, 0.0f, vis, &counts);
        for (uint32_t i = 0; r == HL_OK && i < cnt; i++) {
            uint32_t lv, b = body_of(j, v0 + i, &lv);
            const float *n = j->world.normals + 3 * (size_t)(v0 + i);
            const uint8_t *row = vis + (size_t)i * g->ncube;
            double E[3];
            if (j->lights) shade_lights(j, n, row, scratch, scratch + j->split->count + 1, E);
            else shade_exact(j, n, row, E);
            for (int c = 0; c < 3; c++)
                j->rgb[b][3 * (size_t)lv + c] = (float)(j->albedo[b][3 * (size_t)lv + c] / PI_D * fmax(E[c], 0.0));
        }
    }
    free(vis);
    free(scratch);
    hl_geom_destroy(g);
    hl_rt_destroy(rt);
    if (stats) {
        stats->vertices = nv, stats->F = F, stats->S = j->S;
        stats->rays_cast = counts.rays_cast, stats->rays_culled = counts.rays_culled;
        stats->seconds = hl_now() - t0;
    }
    job_free(j);
    return r;
}

static hl_result check_args(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, const float *const *albedo,
                            float *const *rgb, uint32_t S)
{
    if (!objects || !albedo || !rgb || nobj == 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: no bodies or a NULL argument");
    if (S < 1 || S > HL_DYNREF_MAX_S)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: S = %u rays a texel side, expected 1 to %u", S,
                       HL_DYNREF_MAX_S);
    return HL_OK;
}

hl_result hl_dyn_reference_exact(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj,
                                 const float *const *albedo, const hl_env *env, uint32_t F, uint32_t S,
                                 float *const *rgb, hl_dyn_ref_stats *stats)
{
    if (!F) F = HL_DYNREF_DEFAULT_FACE;
    if (!S) S = HL_DYNREF_DEFAULT_S;
    hl_result r = check_args(ctx, objects, nobj, albedo, rgb, S);
    if (r != HL_OK) return r;
    if (!env) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: no environment");
    if (F < 4 || F > HL_LIGHTS_MAX_FACE)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: face resolution %u, expected 4 to %u", F,
                       HL_LIGHTS_MAX_FACE);
    /* the split only resamples the map here: its texels are what counts */
    hl_light_split_params p;
    hl_light_split_defaults(&p);
    p.face_res = F;
    p.lights = 0;
    hl_light_split *s = NULL;
    r = hl_area_lights_split(ctx, env, &p, &s);
    if (r != HL_OK) return r;
    ref_job j = {.ctx = ctx, .obj = objects, .nobj = nobj, .albedo = albedo, .rgb = rgb, .split = s, .S = S};
    r = run(&j, stats);
    hl_light_split_destroy(s);
    return r;
}

hl_result hl_dyn_reference_lights(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj,
                                  const float *const *albedo, const hl_light_split *split, uint32_t S,
                                  float *const *rgb, hl_dyn_ref_stats *stats)
{
    if (!S) S = HL_DYNREF_LIGHTS_DEFAULT_S;
    hl_result r = check_args(ctx, objects, nobj, albedo, rgb, S);
    if (r != HL_OK) return r;
    if (!split || split->F < 4)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic reference: no split, or one of faces under 4 texels");
    ref_job j = {.ctx = ctx, .obj = objects, .nobj = nobj, .albedo = albedo, .rgb = rgb, .split = split, .S = S,
                 .lights = 1};
    return run(&j, stats);
}
