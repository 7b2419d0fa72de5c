/* rays.c - Embree 3 scene and visibility rays, on all cores.
 *
 * One concern: every ray the library casts. It is the only file that
 * includes Embree's headers, so the scene and all its queries live here:
 * the precompute's visibility rows (hl_rt_visibility), the benchmark's raw
 * ray rate, and the single rays of the renderer and the tests (primary,
 * occluded, occluded from a vertex). Depends on: Embree 3, rays.h, geom.h
 * (the cube texels), core's threads.
 *
 * Rays go out in 16-ray packets (rtcOccluded16), the fastest query on the
 * machines we measured. A vertex's rays share an origin and are ordered by
 * cube texel, so packets are coherent. Threads take vertices from an atomic
 * counter; each writes only its own vertex rows.
 */
#define _POSIX_C_SOURCE 200809L
#include <embree3/rtcore.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rays.h"

/* Texels whose centre lies this many texel half-widths below the horizon
 * still get rays: part of their footprint may be above it. */
#define HL_HORIZON_MARGIN 1.5f

/* The robust ray offset (ray_offset 0): each vertex's origin moves along
 * its normal by 2^-HL_ROBUST_SHIFT of the larger of its largest coordinate
 * magnitude and its longest edge. The errors of a ray-triangle test near
 * the vertex scale with those two (the coordinates' spacing, and the edges
 * Embree subtracts and crosses), so the offset clears the vertex's own
 * triangles at any scale and position, while it stays far below the gaps
 * of real contacts and creases (a fixed fraction of the bounding-box
 * diagonal let origins pass through nearby geometry). 2^-16 is 256 units
 * in the last place of the coordinate; hl.rays.offset measures
 * the choice.
 *
 * The same length is each ray's tnear (whatever the offset, robust or
 * given): a surface that meets the vertex (a wall rising from a concave
 * edge, a trim's side standing on a panel, faces of other, unwelded
 * vertices at the same point) contains the offset origin, since the
 * offset runs along it, and every ray would meet it at t = 0, so that a
 * vertex at the foot of a step came out wholly black. Hits nearer than
 * the offset are the vertex's own neighbourhood, which the offset exists
 * to step over, not blockers it can resolve; a ray that enters a closed
 * solid there still meets the solid's far side. */
#define HL_ROBUST_SHIFT 16

struct hl_rt {
    hl_context *ctx;
    RTCDevice device;
    RTCScene scene;
    uint32_t nverts;
    float *robust; /* per vertex: the robust offset's size */
    const hl_mesh *mesh; /* for hl_rt_occluded_from_vertex (filtered scenes) */
    int filtered;
    char err[512];
};

void hl_rt_longest_edges(const float *P, uint32_t nverts, const uint32_t *tri, uint32_t ntris, float *e)
{
    memset(e, 0, (size_t)nverts * sizeof *e);
    for (uint32_t t = 0; t < ntris; t++) {
        const uint32_t *f = tri + 3 * (size_t)t;
        for (int k = 0; k < 3; k++) {
            const float *a = P + 3 * (size_t)f[k], *b = P + 3 * (size_t)f[(k + 1) % 3];
            float d = fmaxf(fabsf(a[0] - b[0]), fmaxf(fabsf(a[1] - b[1]), fabsf(a[2] - b[2])));
            e[f[k]] = fmaxf(e[f[k]], d);
            e[f[(k + 1) % 3]] = fmaxf(e[f[(k + 1) % 3]], d);
        }
    }
}

float hl_rt_offset_size(const float p[3], float edge)
{
    float m = fmaxf(edge, fmaxf(fabsf(p[0]), fmaxf(fabsf(p[1]), fabsf(p[2]))));
    return ldexpf(m, -HL_ROBUST_SHIFT);
}

/* Per vertex: 2^-HL_ROBUST_SHIFT max(|p|_inf, longest edge). */
static float *robust_offsets(const hl_mesh *mesh)
{
    float *s = calloc(mesh->vertex_count ? mesh->vertex_count : 1, sizeof(float));
    if (!s) return NULL;
    hl_rt_longest_edges(mesh->positions, mesh->vertex_count, mesh->indices, mesh->triangle_count, s);
    for (uint32_t v = 0; v < mesh->vertex_count; v++) s[v] = hl_rt_offset_size(mesh->positions + 3 * (size_t)v, s[v]);
    return s;
}

static void embree_error(void *user, enum RTCError code, const char *str)
{
    hl_rt *rt = user;
    if (rt && !rt->err[0]) snprintf(rt->err, sizeof rt->err, "Embree error %d: %s", (int)code, str ? str : "");
}

static hl_result rt_create(hl_context *ctx, const hl_mesh *mesh, int filtered, hl_rt **out)
{
    *out = NULL;
    hl_rt *rt = calloc(1, sizeof *rt);
    if (!rt) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    rt->ctx = ctx;
    rt->nverts = mesh->vertex_count;
    rt->mesh = mesh;
    rt->filtered = filtered;
    rt->robust = robust_offsets(mesh);
    if (!rt->robust) {
        free(rt);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u ray offsets", mesh->vertex_count);
    }
    char cfg[64];
    snprintf(cfg, sizeof cfg, "threads=%d", ctx->threads);
    rt->device = rtcNewDevice(cfg);
    if (!rt->device) {
        free(rt->robust);
        free(rt);
        return hl_fail(ctx, HL_ERR_EMBREE, "Embree: cannot create a device (error %d)", (int)rtcGetDeviceError(NULL));
    }
    rtcSetDeviceErrorFunction(rt->device, embree_error, rt);
    rt->scene = rtcNewScene(rt->device);
    rtcSetSceneFlags(rt->scene, RTC_SCENE_FLAG_ROBUST | (filtered ? RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION : 0));
    rtcSetSceneBuildQuality(rt->scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = rtcNewGeometry(rt->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                        mesh->vertex_count);
    unsigned *ib = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                           mesh->triangle_count);
    if (vb && ib) {
        memcpy(vb, mesh->positions, (size_t)mesh->vertex_count * 3 * sizeof(float));
        memcpy(ib, mesh->indices, (size_t)mesh->triangle_count * 3 * sizeof(unsigned));
        rtcCommitGeometry(geom);
        rtcAttachGeometry(rt->scene, geom);
    }
    rtcReleaseGeometry(geom);
    rtcCommitScene(rt->scene);
    if (rt->err[0] || !vb || !ib) {
        hl_result r = hl_fail(ctx, HL_ERR_EMBREE, "Embree: building the scene failed: %s", rt->err[0] ? rt->err : "no buffer");
        hl_rt_destroy(rt);
        return r;
    }
    *out = rt;
    return HL_OK;
}

hl_result hl_rt_create(hl_context *ctx, const hl_mesh *mesh, hl_rt **out) { return rt_create(ctx, mesh, 0, out); }

hl_result hl_rt_create_filtered(hl_context *ctx, const hl_mesh *mesh, hl_rt **out)
{
    return rt_create(ctx, mesh, 1, out);
}

void hl_rt_destroy(hl_rt *rt)
{
    if (!rt) return;
    if (rt->scene) rtcReleaseScene(rt->scene);
    if (rt->device) rtcReleaseDevice(rt->device);
    free(rt->robust);
    free(rt);
}

typedef struct vis_job {
    hl_rt *rt;
    const hl_geom *g;
    const hl_mesh *mesh;
    uint32_t first, count, S;
    float offset;
    uint8_t *vis;
    struct packet *store; /* raw-rate set-up: packets are kept, not traced */
    size_t nstore, capstore;
    atomic_uint next;
    atomic_ullong cast, culled;
} vis_job;

/* Sub-texel offsets of the S x S rays of a texel, in face units. */
static void sub_offsets(uint32_t S, uint32_t C, float *off)
{
    for (uint32_t a = 0; a < S; a++) off[a] = (((float)a + 0.5f) / (float)S - 0.5f) * 2.0f / (float)C;
}

typedef struct packet {
    struct RTCRay16 ray;
    int valid[16] __attribute__((aligned(64)));
    uint32_t texel[16];
    int n;
} packet;

static void flush_packet(vis_job *job, packet *pk, struct RTCIntersectContext *ic, uint8_t *row)
{
    if (!pk->n) return;
    for (int i = pk->n; i < 16; i++) pk->valid[i] = 0;
    if (job->store) {
        if (job->nstore < job->capstore) job->store[job->nstore++] = *pk;
        pk->n = 0;
        return;
    }
    rtcOccluded16(pk->valid, job->rt->scene, ic, &pk->ray);
    if (row)
        for (int i = 0; i < pk->n; i++)
            if (pk->ray.tfar[i] >= 0.0f) row[pk->texel[i]]++;
    pk->n = 0;
}

/* Lanes' constant fields are set once; per vertex only the origin, per
 * ray only the direction, tnear, tfar and valid change (Embree writes
 * only tfar). */
static void packet_init(packet *pk)
{
    memset(pk, 0, sizeof *pk);
    for (int i = 0; i < 16; i++) {
        pk->ray.mask[i] = 0xffffffffu;
        pk->ray.id[i] = (unsigned)i;
    }
}

/* One coordinate of a ray origin: p + n offset, rounded away from the
 * surface. Far from the origin the offset can be below the spacing of
 * the coordinates (1/16 at 1e6, against 1e-3 of a unit scene's diagonal),
 * and rounding to nearest would put the origin back on the surface,
 * where its rays hit the surface itself. */
float hl_rt_origin_coord(float p, float n, float offset)
{
    float o = p + n * offset;
    double want = (double)p + (double)n * offset;
    if (n > 0.0f && (double)o < want) o = nextafterf(o, INFINITY);
    if (n < 0.0f && (double)o > want) o = nextafterf(o, -INFINITY);
    return o;
}

static void trace_vertex(vis_job *job, uint32_t v, packet *pk, const float *off)
{
    const hl_geom *g = job->g;
    const uint32_t C = g->C, S = job->S;
    const float *p = job->mesh->positions + 3 * (size_t)v, *n = job->mesh->normals + 3 * (size_t)v;
    const float dist = job->offset > 0.0f ? job->offset : job->rt->robust[v];
    const float o[3] = {hl_rt_origin_coord(p[0], n[0], dist), hl_rt_origin_coord(p[1], n[1], dist),
                        hl_rt_origin_coord(p[2], n[2], dist)};
    const float margin = -HL_HORIZON_MARGIN / (float)C;
    uint8_t *row = job->vis ? job->vis + (size_t)(v - job->first) * g->ncube : NULL;
    if (row) memset(row, 0, g->ncube);
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (int i = 0; i < 16; i++) {
        pk->ray.org_x[i] = o[0];
        pk->ray.org_y[i] = o[1];
        pk->ray.org_z[i] = o[2];
    }
    uint64_t cast = 0, culled = 0;
    pk->n = 0;
    for (uint32_t c = 0; c < g->ncube; c++) {
        const float *d = g->cube_dirs + 4 * (size_t)c;
        if (c % C == 0) {
            /* along a face row d is affine, so n.d - margin |d| (margin < 0)
               is convex and its culled set is an interval: a row whose end
               texels are both culled is culled whole */
            const float *e = d + 4 * (size_t)(C - 1);
            if (d[0] * n[0] + d[1] * n[1] + d[2] * n[2] <= margin && e[0] * n[0] + e[1] * n[1] + e[2] * n[2] <= margin) {
                culled += (uint64_t)S * S * C;
                c += C - 1;
                continue;
            }
        }
        if (d[0] * n[0] + d[1] * n[1] + d[2] * n[2] <= margin) {
            culled += (uint64_t)S * S;
            continue;
        }
        int face = (int)(c / (C * C));
        uint32_t r = (c / C) % C, col = c % C;
        float sc = 2.0f * ((float)col + 0.5f) / (float)C - 1.0f, tc = 2.0f * ((float)r + 0.5f) / (float)C - 1.0f;
        for (uint32_t a = 0; a < S; a++)
            for (uint32_t b = 0; b < S; b++) {
                float dir[3];
                if (S == 1) { dir[0] = d[0]; dir[1] = d[1]; dir[2] = d[2]; }
                else hl_cube_face_dir(face, sc + off[b], tc + off[a], dir);
                int i = pk->n++;
                pk->ray.dir_x[i] = dir[0];
                pk->ray.dir_y[i] = dir[1];
                pk->ray.dir_z[i] = dir[2];
                /* hits nearer than the offset are ignored (the robust
                   offset's comment); supersampled directions are not unit */
                pk->ray.tnear[i] = S == 1 ? dist : dist / sqrtf(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
                pk->ray.tfar[i] = INFINITY;
                pk->valid[i] = -1;
                pk->texel[i] = c;
                if (pk->n == 16) flush_packet(job, pk, &ic, row);
                cast++;
            }
    }
    flush_packet(job, pk, &ic, row);
    atomic_fetch_add(&job->cast, cast);
    atomic_fetch_add(&job->culled, culled);
}

static void *vis_worker(void *arg)
{
    vis_job *job = arg;
    packet *pk = aligned_alloc(64, sizeof *pk);
    float off[16];
    if (!pk) return NULL;
    packet_init(pk);
    sub_offsets(job->S, job->g->C, off);
    for (;;) {
        uint32_t i = atomic_fetch_add(&job->next, 4u);
        if (i >= job->count || hl_context_cancelled(job->rt->ctx)) break;
        uint32_t end = i + 4 < job->count ? i + 4 : job->count;
        for (; i < end; i++) trace_vertex(job, job->first + i, pk, off);
    }
    free(pk);
    return NULL;
}

static hl_result run_job(hl_rt *rt, vis_job *job)
{
    hl_run_threads(rt->ctx->threads, vis_worker, job);
    if (rt->err[0]) return hl_fail(rt->ctx, HL_ERR_EMBREE, "Embree: %s", rt->err);
    if (hl_context_cancelled(rt->ctx)) return hl_fail(rt->ctx, HL_ERR_INTERRUPTED, "interrupted");
    return HL_OK;
}

static hl_result check_job(hl_rt *rt, const hl_mesh *mesh, uint32_t S)
{
    if (mesh->vertex_count != rt->nverts)
        return hl_fail(rt->ctx, HL_ERR_INVALID_ARGUMENT, "visibility of a mesh of %u vertices on a scene built from %u",
                       mesh->vertex_count, rt->nverts);
    if (S < 1 || S > 15)
        return hl_fail(rt->ctx, HL_ERR_INVALID_ARGUMENT, "supersample = %u: must be 1 to 15 (S x S rays per texel count in 8 bits)", S);
    return HL_OK;
}

float hl_rt_robust_offset(const hl_rt *rt, uint32_t v) { return v < rt->nverts ? rt->robust[v] : 0.0f; }

hl_result hl_rt_visibility(hl_rt *rt, const hl_geom *g, const hl_mesh *mesh, uint32_t first, uint32_t count,
                           uint32_t S, float offset, uint8_t *vis, hl_vis_counts *counts)
{
    hl_result r = check_job(rt, mesh, S);
    if (r != HL_OK) return r;
    vis_job job = {.rt = rt, .g = g, .mesh = mesh, .first = first, .count = count, .S = S, .offset = offset, .vis = vis};
    atomic_init(&job.next, 0u);
    atomic_init(&job.cast, 0ull);
    atomic_init(&job.culled, 0ull);
    r = run_job(rt, &job);
    if (counts) {
        counts->rays_cast += atomic_load(&job.cast);
        counts->rays_culled += atomic_load(&job.culled);
    }
    return r;
}

typedef struct raw_job {
    hl_rt *rt;
    packet *pk;
    size_t n;
    atomic_size_t next;
} raw_job;

static void *raw_worker(void *arg)
{
    raw_job *job = arg;
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    packet *local = aligned_alloc(64, sizeof *local);
    if (!local) return NULL;
    for (;;) {
        size_t i = atomic_fetch_add(&job->next, 64);
        if (i >= job->n) break;
        size_t end = i + 64 < job->n ? i + 64 : job->n;
        for (; i < end; i++) {
            /* tfar is overwritten by the query: trace a copy */
            *local = job->pk[i];
            rtcOccluded16(local->valid, job->rt->scene, &ic, &local->ray);
        }
    }
    free(local);
    return NULL;
}

hl_result hl_rt_raw_rate(hl_rt *rt, const hl_geom *g, const hl_mesh *mesh, const uint32_t *verts,
                         uint32_t nverts, uint32_t S, float offset, double *rays_per_s)
{
    hl_result r = check_job(rt, mesh, S);
    if (r != HL_OK) return r;
    *rays_per_s = 0.0;
    /* the same packets hl_rt_visibility builds, made up front */
    size_t cap = (size_t)nverts * ((g->ncube * S * S + 15) / 16 + 1);
    vis_job job = {.rt = rt, .g = g, .mesh = mesh, .first = 0, .count = mesh->vertex_count, .S = S, .offset = offset};
    job.store = aligned_alloc(64, cap * sizeof(packet));
    packet *pk = aligned_alloc(64, sizeof(packet));
    if (!job.store || !pk) {
        free(job.store);
        free(pk);
        return hl_fail(rt->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %zu ray packets", cap);
    }
    job.capstore = cap;
    packet_init(pk);
    atomic_init(&job.cast, 0ull);
    atomic_init(&job.culled, 0ull);
    float off[16];
    sub_offsets(S, g->C, off);
    for (uint32_t i = 0; i < nverts; i++) trace_vertex(&job, verts[i], pk, off);
    uint64_t rays = atomic_load(&job.cast);
    raw_job rj = {.rt = rt, .pk = job.store, .n = job.nstore};
    atomic_init(&rj.next, (size_t)0);
    double t0 = hl_now();
    hl_run_threads(rt->ctx->threads, raw_worker, &rj);
    double dt = hl_now() - t0;
    free(job.store);
    free(pk);
    if (rt->err[0]) return hl_fail(rt->ctx, HL_ERR_EMBREE, "Embree: %s", rt->err);
    *rays_per_s = dt > 0 ? (double)rays / dt : 0.0;
    return HL_OK;
}

/* ------------------------------------------------------------ primary rays */

typedef struct primary_job {
    hl_rt *rt;
    uint32_t count;
    const float *org, *dir;
    uint32_t *prim;
    float *u, *v;
    uint8_t *occluded; /* set: occlusion queries instead of closest hits */
    const float *tnear; /* occlusion queries: per ray, or NULL for 0 */
    const float *tfar;  /* occlusion queries: per ray, or NULL for infinity */
    atomic_uint next;
} primary_job;

static void *primary_worker(void *arg)
{
    primary_job *j = arg;
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    for (;;) {
        uint32_t i0 = atomic_fetch_add(&j->next, 256u);
        if (i0 >= j->count) break;
        uint32_t end = i0 + 256 < j->count ? i0 + 256 : j->count;
        for (uint32_t i = i0; i < end && j->occluded; i++) {
            struct RTCRay ray;
            memset(&ray, 0, sizeof ray);
            ray.org_x = j->org[3 * (size_t)i];
            ray.org_y = j->org[3 * (size_t)i + 1];
            ray.org_z = j->org[3 * (size_t)i + 2];
            ray.dir_x = j->dir[3 * (size_t)i];
            ray.dir_y = j->dir[3 * (size_t)i + 1];
            ray.dir_z = j->dir[3 * (size_t)i + 2];
            ray.tnear = j->tnear ? j->tnear[i] : 0.0f;
            ray.tfar = j->tfar ? j->tfar[i] : INFINITY;
            ray.mask = 0xffffffffu;
            rtcOccluded1(j->rt->scene, &ic, &ray);
            j->occluded[i] = ray.tfar < 0.0f;
        }
        for (uint32_t i = i0; i < end && !j->occluded; i++) {
            struct RTCRayHit rh;
            memset(&rh, 0, sizeof rh);
            rh.ray.org_x = j->org[3 * (size_t)i];
            rh.ray.org_y = j->org[3 * (size_t)i + 1];
            rh.ray.org_z = j->org[3 * (size_t)i + 2];
            rh.ray.dir_x = j->dir[3 * (size_t)i];
            rh.ray.dir_y = j->dir[3 * (size_t)i + 1];
            rh.ray.dir_z = j->dir[3 * (size_t)i + 2];
            rh.ray.tfar = INFINITY;
            rh.ray.mask = 0xffffffffu;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(j->rt->scene, &ic, &rh);
            int hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
            j->prim[i] = hit ? rh.hit.primID : UINT32_MAX;
            j->u[i] = hit ? rh.hit.u : 0.0f;
            j->v[i] = hit ? rh.hit.v : 0.0f;
        }
    }
    return NULL;
}

hl_result hl_rt_trace_primary(hl_rt *rt, uint32_t count, const float *org, const float *dir,
                              uint32_t *prim, float *u, float *v)
{
    primary_job j = {.rt = rt, .count = count, .org = org, .dir = dir, .prim = prim, .u = u, .v = v};
    atomic_init(&j.next, 0u);
    hl_run_threads(rt->ctx->threads, primary_worker, &j);
    if (rt->err[0]) return hl_fail(rt->ctx, HL_ERR_EMBREE, "Embree: %s", rt->err);
    return HL_OK;
}

hl_result hl_rt_trace_occluded(hl_rt *rt, uint32_t count, const float *org, const float *dir, const float *tnear,
                               uint8_t *occluded)
{
    return hl_rt_trace_occluded_seg(rt, count, org, dir, tnear, NULL, occluded);
}

hl_result hl_rt_trace_occluded_seg(hl_rt *rt, uint32_t count, const float *org, const float *dir, const float *tnear,
                                   const float *tfar, uint8_t *occluded)
{
    primary_job j = {.rt = rt, .count = count, .org = org, .dir = dir, .occluded = occluded, .tnear = tnear, .tfar = tfar};
    atomic_init(&j.next, 0u);
    hl_run_threads(rt->ctx->threads, primary_worker, &j);
    if (rt->err[0]) return hl_fail(rt->ctx, HL_ERR_EMBREE, "Embree: %s", rt->err);
    return HL_OK;
}

/* ------------------------------------------------ rays from a vertex itself */

/* The intersection context of hl_rt_occluded_from_vertex: Embree hands
 * the filter the pointer to its first member. */
typedef struct own_filter {
    struct RTCIntersectContext ic;
    const uint32_t *indices;
    uint32_t vertex;
} own_filter;

/* A ray that starts exactly on a vertex meets the vertex's own triangles
 * only at t = 0 (it leaves their plane at once), so those hits are
 * dropped and every other one counts from the robust offset's distance
 * on (its tnear): nearer, other surfaces through the vertex (a wall on a
 * concave edge, unwelded vertices' faces) are met at t = 0 by every ray,
 * as in hl_rt_visibility. */
static void skip_own_triangles(const struct RTCFilterFunctionNArguments *a)
{
    const own_filter *f = (const own_filter *)(const void *)a->context;
    for (unsigned i = 0; i < a->N; i++) {
        if (a->valid[i] != -1) continue;
        /* RTCHitN is N hits by field (Ng x, y, z, u, v, primID, ...):
           rtcore_ray.h's RTCHitN_primID, which is C++ only */
        const unsigned prim = ((const unsigned *)(const void *)a->hit)[5 * (size_t)a->N + i];
        const uint32_t *t = f->indices + 3 * (size_t)prim;
        if (t[0] == f->vertex || t[1] == f->vertex || t[2] == f->vertex) a->valid[i] = 0;
    }
}

typedef struct own_job {
    hl_rt *rt;
    uint32_t vertex, count;
    const float *dir;
    uint8_t *occluded;
    atomic_uint next;
} own_job;

static void *own_worker(void *arg)
{
    own_job *j = arg;
    own_filter f;
    rtcInitIntersectContext(&f.ic);
    f.ic.filter = skip_own_triangles;
    f.indices = j->rt->mesh->indices;
    f.vertex = j->vertex;
    const float *p = j->rt->mesh->positions + 3 * (size_t)j->vertex;
    const float tnear = j->rt->robust[j->vertex];
    for (;;) {
        uint32_t i0 = atomic_fetch_add(&j->next, 256u);
        if (i0 >= j->count) break;
        uint32_t end = i0 + 256 < j->count ? i0 + 256 : j->count;
        for (uint32_t i = i0; i < end; i++) {
            struct RTCRay ray;
            memset(&ray, 0, sizeof ray);
            ray.org_x = p[0];
            ray.org_y = p[1];
            ray.org_z = p[2];
            ray.dir_x = j->dir[3 * (size_t)i];
            ray.dir_y = j->dir[3 * (size_t)i + 1];
            ray.dir_z = j->dir[3 * (size_t)i + 2];
            ray.tnear = tnear / sqrtf(ray.dir_x * ray.dir_x + ray.dir_y * ray.dir_y + ray.dir_z * ray.dir_z);
            ray.tfar = INFINITY;
            ray.mask = 0xffffffffu;
            rtcOccluded1(j->rt->scene, &f.ic, &ray);
            j->occluded[i] = ray.tfar < 0.0f;
        }
    }
    return NULL;
}

hl_result hl_rt_occluded_from_vertex(hl_rt *rt, uint32_t vertex, uint32_t count, const float *dir, uint8_t *occluded)
{
    if (!rt->filtered || vertex >= rt->nverts)
        return hl_fail(rt->ctx, HL_ERR_INVALID_ARGUMENT,
                       "rays from vertex %u: needs a scene from hl_rt_create_filtered of a mesh with that vertex",
                       vertex);
    own_job j = {.rt = rt, .vertex = vertex, .count = count, .dir = dir, .occluded = occluded};
    atomic_init(&j.next, 0u);
    hl_run_threads(rt->ctx->threads, own_worker, &j);
    if (rt->err[0]) return hl_fail(rt->ctx, HL_ERR_EMBREE, "Embree: %s", rt->err);
    return HL_OK;
}
