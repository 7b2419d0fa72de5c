/* dyn_traced.c - the traced method (dyn_traced.h): the bodies merged in
 * world space, Embree's scene of them built, then vertices in chunks:
 * every vertex's sample directions towards every kept light (fixed slots,
 * in parallel), those above its horizon packed into one ray list (in
 * parallel after a prefix sum), traced at once, and each vertex shaded
 * from its lights' unoccluded shares (in parallel).
 * Depends on: dyn_traced.h, dyn_reference.h (hl_dyn_world_merge),
 * area_lights.h, geom.h (hl_cube_face_dir), rays.h, core (threads).
 */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "area_lights.h"
#include "dyn_reference.h"
#include "dyn_traced.h"
#include "geom.h"
#include "hl_internal.h"
#include "rays.h"

#define PI_D 3.14159265358979323846

/* Ray slots (K x S per vertex) a chunk holds: 2^20, so a chunk's arrays
 * (12 + 1 bytes a slot, 24 + 1 a packed ray) stay near 40 MB whatever K
 * and S, and a chunk is still thousands of vertices at K x S = 128. */
#define HL_DYNTRACED_CHUNK_SLOTS (1u << 20)

typedef enum { PHASE_DIRS, PHASE_PACK, PHASE_SHADE } phase;

typedef struct traced_job {
    hl_context *ctx;
    const hl_light_split *split;
    const float *const *albedo;
    float *const *rgb;
    uint32_t nobj, K, S;
    /* per kept light k, its texels tex[lstart[k] .. lstart[k+1]-1] (row by
       row of its rectangle) and their luminance energy's running sum cdf
       (normalised to end at 1) */
    uint32_t *lstart, *tex;
    float *cdf;
    hl_mesh world;
    uint32_t *vstart; /* nobj + 1 */
    hl_rt *rt;
    /* the chunk: vertices v0 .. v0 + cnt - 1 */
    uint32_t v0, cnt;
    float *sdir;      /* 3 per slot */
    uint8_t *live;    /* per slot: above the horizon */
    uint32_t *first;  /* per chunk vertex + 1: its first packed ray */
    float *org, *dir; /* 3 per packed ray */
    float *tnear;     /* per packed ray: the origin's offset (rays.c) */
    uint8_t *occ;     /* per packed ray */
    phase ph;
    atomic_uint next;
} traced_job;

/* A 32-bit integer hash (lowbias32, Wellons): the jitter of a sample. */
static uint32_t hash32(uint32_t x)
{
    x ^= x >> 16, x *= 0x7feb352dU, x ^= x >> 15, x *= 0x846ca68bU, x ^= x >> 16;
    return x;
}

static float unit_of(uint32_t h) { return (float)(h >> 8) * (1.0f / 16777216.0f); }

/* The texel of light k that holds u in [0, 1) of its energy. */
static uint32_t pick_texel(const traced_job *j, uint32_t k, float u)
{
    uint32_t lo = j->lstart[k], hi = j->lstart[k + 1] - 1;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (j->cdf[mid] > u) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/* Slots of chunk vertex i: light k's sample s at k S + s, the s-th of S
 * strata of the light's energy, a point of its texel; live when above the
 * horizon. Returns how many are. */
static uint32_t vertex_dirs(traced_job *j, uint32_t i)
{
    const uint32_t v = j->v0 + i, F = j->split->F;
    const float *n = j->world.normals + 3 * (size_t)v;
    float *d = j->sdir + 3 * (size_t)i * j->K * j->S;
    uint8_t *live = j->live + (size_t)i * j->K * j->S;
    uint32_t count = 0;
    for (uint32_t k = 0; k < j->K; k++)
        for (uint32_t s = 0; s < j->S; s++, d += 3, live++) {
            uint32_t h = hash32(v * 0x9E3779B1U ^ hash32(k * 0x85EBCA77U ^ hash32(s + 0x165667B1U)));
            uint32_t h2 = hash32(h), h3 = hash32(h2);
            float u = ((float)s + unit_of(h)) / (float)j->S;
            uint32_t t = j->tex[pick_texel(j, k, u < 1.0f ? u : 0.99999994f)];
            uint32_t face = t / (F * F), row = t / F % F, col = t % F;
            float sc = 2.0f * ((float)col + unit_of(h2)) / (float)F - 1.0f;
            float tc = 2.0f * ((float)row + unit_of(h3)) / (float)F - 1.0f;
            hl_cube_face_dir((int)face, sc, tc, d);
            float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            d[0] /= len, d[1] /= len, d[2] /= len;
            *live = n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0.0f;
            count += *live;
        }
    return count;
}

/* Every kept light's texels and the running sum of their luminance
 * energy; a light of no energy is sampled evenly. */
static hl_result light_tables(traced_job *j)
{
    const hl_light_split *sp = j->split;
    const uint32_t F = sp->F;
    j->lstart = hl_malloc(j->ctx, ((size_t)j->K + 1) * 4, "the traced method's lights");
    size_t nt = 0;
    for (uint32_t k = 0; k < j->K; k++)
        nt += (size_t)(sp->lights[k].x1 - sp->lights[k].x0) * (sp->lights[k].y1 - sp->lights[k].y0);
    j->tex = hl_malloc(j->ctx, nt * 4 + 4, "the traced method's light texels");
    j->cdf = hl_malloc(j->ctx, nt * 4 + 4, "the traced method's light energy");
    if (!j->lstart || !j->tex || !j->cdf) return HL_ERR_OUT_OF_MEMORY;
    uint32_t at = 0;
    for (uint32_t k = 0; k < j->K; k++) {
        const hl_area_light *L = &sp->lights[k];
        j->lstart[k] = at;
        double sum = 0.0;
        for (uint32_t y = L->y0; y < L->y1; y++)
            for (uint32_t x = L->x0; x < L->x1; x++, at++) {
                j->tex[at] = L->face * F * F + y * F + x;
                const float *e = sp->texel_energy + 3 * (size_t)j->tex[at];
                sum += 0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2];
                j->cdf[at] = (float)sum;
            }
        const uint32_t cnt = at - j->lstart[k];
        for (uint32_t i = 0; i < cnt; i++)
            j->cdf[j->lstart[k] + i] = sum > 0.0 ? (float)(j->cdf[j->lstart[k] + i] / sum) : (float)(i + 1) / (float)cnt;
        if (cnt) j->cdf[at - 1] = 1.0f;
        if (!cnt) return hl_fail(j->ctx, HL_ERR_INVALID_ARGUMENT, "traced method: light %u has no texel", k);
    }
    j->lstart[j->K] = at;
    return HL_OK;
}

/* The live slots of chunk vertex i packed from j->first[i], their origins
 * at rays.c's robust offset along the normal and their tnear the offset
 * (the directions are unit). */
static void vertex_pack(traced_job *j, uint32_t i)
{
    const uint32_t v = j->v0 + i, ns = j->K * j->S;
    const float *p = j->world.positions + 3 * (size_t)v, *n = j->world.normals + 3 * (size_t)v;
    const float off = hl_rt_robust_offset(j->rt, v);
    const float o[3] = {hl_rt_origin_coord(p[0], n[0], off), hl_rt_origin_coord(p[1], n[1], off),
                        hl_rt_origin_coord(p[2], n[2], off)};
    const float *d = j->sdir + 3 * (size_t)i * ns;
    const uint8_t *live = j->live + (size_t)i * ns;
    size_t at = j->first[i];
    for (uint32_t t = 0; t < ns; t++) {
        if (!live[t]) continue;
        memcpy(j->org + 3 * at, o, sizeof o);
        memcpy(j->dir + 3 * at, d + 3 * (size_t)t, 3 * sizeof(float));
        j->tnear[at] = off;
        at++;
    }
}

/* Chunk vertex i shaded: B = albedo / pi (sum_k V_k E_k + ambient). */
static void vertex_shade(traced_job *j, uint32_t i)
{
    const hl_light_split *sp = j->split;
    const uint32_t v = j->v0 + i, ns = j->K * j->S;
    const float *n = j->world.normals + 3 * (size_t)v;
    const uint8_t *live = j->live + (size_t)i * ns, *occ = j->occ + j->first[i];
    float a[3];
    hl_light_split_ambient(sp, n, a);
    double E[3] = {a[0], a[1], a[2]};
    for (uint32_t k = 0; k < j->K; k++) {
        uint32_t up = 0, open = 0;
        for (uint32_t s = 0; s < j->S; s++)
            if (live[k * j->S + s]) up++, open += !*occ++;
        float Ek[3];
        hl_area_light_irradiance(sp, k, n, Ek);
        /* no ray above the horizon: V = 1 on E_k = 0 or a sliver, as the
           K-lights reference */
        const double V = up ? (double)open / up : 1.0;
        for (int c = 0; c < 3; c++) E[c] += V * Ek[c];
    }
    uint32_t b = 0;
    while (v >= j->vstart[b + 1]) b++;
    const size_t lv = v - j->vstart[b];
    for (int c = 0; c < 3; c++)
        j->rgb[b][3 * lv + c] = (float)(j->albedo[b][3 * lv + c] / PI_D * fmax(E[c], 0.0));
}

static void *worker(void *arg)
{
    traced_job *j = arg;
    for (;;) {
        uint32_t i = atomic_fetch_add(&j->next, 1u);
        if (i >= j->cnt) break;
        if (j->ph == PHASE_DIRS) j->first[i + 1] = vertex_dirs(j, i);
        else if (j->ph == PHASE_PACK) vertex_pack(j, i);
        else vertex_shade(j, i);
    }
    return NULL;
}

static void run_phase(traced_job *j, phase ph)
{
    j->ph = ph;
    atomic_store(&j->next, 0u);
    hl_run_threads(j->ctx->threads, worker, j);
}

/* Every chunk of vertices: directions, packing, tracing, shading. */
static hl_result chunks(traced_job *j, hl_dyn_traced_stats *st)
{
    const uint32_t ns = j->K * j->S, nv = j->world.vertex_count;
    const uint32_t chunk = HL_DYNTRACED_CHUNK_SLOTS / ns ? HL_DYNTRACED_CHUNK_SLOTS / ns : 1;
    const size_t slots = (size_t)chunk * ns;
    j->sdir = hl_malloc(j->ctx, slots * 12, "the traced method's directions");
    j->live = hl_malloc(j->ctx, slots, "the traced method's horizon flags");
    j->first = hl_malloc(j->ctx, ((size_t)chunk + 1) * 4, "the traced method's ray starts");
    j->org = hl_malloc(j->ctx, slots * 12, "the traced method's ray origins");
    j->dir = hl_malloc(j->ctx, slots * 12, "the traced method's ray directions");
    j->tnear = hl_malloc(j->ctx, slots * 4, "the traced method's ray starts along the rays");
    j->occ = hl_malloc(j->ctx, slots + 1, "the traced method's occlusion");
    hl_result r = j->sdir && j->live && j->first && j->org && j->dir && j->tnear && j->occ ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    for (uint32_t v0 = 0; r == HL_OK && v0 < nv; v0 += chunk) {
        j->v0 = v0, j->cnt = nv - v0 < chunk ? nv - v0 : chunk;
        double t0 = hl_now();
        j->first[0] = 0;
        run_phase(j, PHASE_DIRS);
        for (uint32_t i = 0; i < j->cnt; i++) j->first[i + 1] += j->first[i]; /* counts to starts */
        run_phase(j, PHASE_PACK);
        const uint32_t nrays = j->first[j->cnt];
        st->rays_cast += nrays, st->rays_below += (uint64_t)j->cnt * ns - nrays;
        double t1 = hl_now();
        r = nrays ? hl_rt_trace_occluded(j->rt, nrays, j->org, j->dir, j->tnear, j->occ) : HL_OK;
        double t2 = hl_now();
        if (r == HL_OK) run_phase(j, PHASE_SHADE);
        st->t_rays += t1 - t0, st->t_trace += t2 - t1, st->t_shade += hl_now() - t2;
    }
    free(j->sdir); free(j->live); free(j->first); free(j->org); free(j->dir); free(j->tnear); free(j->occ);
    return r;
}

hl_result hl_dyn_traced(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, const float *const *albedo,
                        const hl_light_split *split, uint32_t S, float *const *rgb, hl_dyn_traced_stats *stats)
{
    const double t0 = hl_now();
    if (!objects || !albedo || !rgb || nobj == 0 || !split)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "traced method: no bodies, no lights or a NULL argument");
    if (S < 1 || S > HL_DYNTRACED_MAX_S)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "traced method: %u rays a light, expected 1 to %u", S,
                       HL_DYNTRACED_MAX_S);
    for (uint32_t b = 0; b < nobj; b++)
        if (!albedo[b] || !rgb[b])
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "traced method: body %u has no albedo or colours", b);
    hl_dyn_traced_stats st = {.lights = split->count, .S = S};
    traced_job j = {.ctx = ctx, .split = split, .albedo = albedo, .rgb = rgb, .nobj = nobj, .K = split->count, .S = S};
    j.vstart = calloc((size_t)nobj + 1, sizeof *j.vstart);
    hl_result r = j.vstart ? hl_dyn_world_merge(ctx, objects, nobj, &j.world, j.vstart)
                           : hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the traced method");
    if (r == HL_OK) r = hl_rt_create(ctx, &j.world, &j.rt);
    if (r == HL_OK && j.K > 0) r = light_tables(&j);
    st.t_build = hl_now() - t0;
    st.vertices = j.world.vertex_count;
    if (r == HL_OK && j.K > 0) r = chunks(&j, &st);
    for (uint32_t b = 0; r == HL_OK && j.K == 0 && b < nobj; b++) /* no kept light: the ambient alone */
        for (uint32_t v = 0; v < objects[b].nverts; v++) {
            float a[3];
            hl_light_split_ambient(split, j.world.normals + 3 * ((size_t)j.vstart[b] + v), a);
            for (int c = 0; c < 3; c++)
                rgb[b][3 * (size_t)v + c] = (float)(albedo[b][3 * (size_t)v + c] / PI_D * fmax(a[c], 0.0));
        }
    hl_rt_destroy(j.rt);
    free(j.world.positions); free(j.world.normals); free(j.world.indices); free(j.vstart);
    free(j.lstart); free(j.tex); free(j.cdf);
    st.seconds = hl_now() - t0;
    if (stats) *stats = st;
    return r;
}
