/* instances.c - an Embree 3 scene of rigid instances, and orthographic
 * depth maps of it by one ray per texel centre.
 *
 * One concern: the dynamic method's Embree side. Each object gets its own
 * scene (its BVH, built once at creation, robust so shared edges leave no
 * holes); the top-level scene holds one instance geometry per object, so
 * a rigid motion changes an instance's transform and re-commits the top
 * level, whose BVH has one box per object. Rays go in 16-ray packets
 * (rtcIntersect16) of 16 neighbouring texels of a row: parallel rays
 * from neighbouring origins, the most coherent packets a map offers.
 * Threads take rows from an atomic counter and write only their rows.
 * Depends on: Embree 3, instances.h, core's threads.
 */
#define _POSIX_C_SOURCE 200809L
#include <embree3/rtcore.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instances.h"

/* Rows of one map a thread takes at a time: 4 rows of R = 256 is 64
 * packets, enough to keep the counter's traffic negligible. */
#define HL_INST_ROWS_PER_TAKE 4u

struct hl_inst_scene {
    hl_context *ctx;
    RTCDevice device;
    RTCScene top;
    uint32_t nobj;
    RTCScene *objs;    /* one per object */
    RTCGeometry *inst; /* one instance per object, in top */
    int dirty;         /* a transform changed since the last commit */
    uint64_t builds, commits;
    char err[512];
};

static void inst_error(void *user, enum RTCError code, const char *str)
{
    hl_inst_scene *s = user;
    if (s && !s->err[0]) snprintf(s->err, sizeof s->err, "Embree error %d: %s", (int)code, str ? str : "");
}

void hl_inst_destroy(hl_inst_scene *s)
{
    if (!s) return;
    for (uint32_t i = 0; s->inst && i < s->nobj; i++)
        if (s->inst[i]) rtcReleaseGeometry(s->inst[i]);
    for (uint32_t i = 0; s->objs && i < s->nobj; i++)
        if (s->objs[i]) rtcReleaseScene(s->objs[i]);
    if (s->top) rtcReleaseScene(s->top);
    if (s->device) rtcReleaseDevice(s->device);
    free(s->objs);
    free(s->inst);
    free(s);
}

/* The object's own BVH: a triangle geometry in a scene of its own. */
static int build_object(hl_inst_scene *s, const hl_inst_mesh *m, RTCScene *out)
{
    RTCScene sc = rtcNewScene(s->device);
    *out = sc;
    if (!sc) return 0;
    rtcSetSceneFlags(sc, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(sc, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry g = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) return 0;
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m->nverts);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m->ntris);
    if (vb && ib) {
        memcpy(vb, m->pos, (size_t)m->nverts * 3 * sizeof(float));
        memcpy(ib, m->tri, (size_t)m->ntris * 3 * sizeof(unsigned));
        rtcCommitGeometry(g);
        rtcAttachGeometry(sc, g);
    }
    rtcReleaseGeometry(g);
    if (!vb || !ib) return 0;
    rtcCommitScene(sc);
    s->builds++;
    return 1;
}

hl_result hl_inst_create(hl_context *ctx, const hl_inst_mesh *objs, uint32_t nobj, hl_inst_scene **out)
{
    *out = NULL;
    hl_inst_scene *s = calloc(1, sizeof *s);
    if (!s) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for an instance scene");
    s->ctx = ctx;
    s->nobj = nobj;
    s->objs = calloc(nobj ? nobj : 1, sizeof *s->objs);
    s->inst = calloc(nobj ? nobj : 1, sizeof *s->inst);
    if (!s->objs || !s->inst) {
        hl_inst_destroy(s);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u instances", nobj);
    }
    char cfg[64];
    snprintf(cfg, sizeof cfg, "threads=%d", ctx->threads);
    s->device = rtcNewDevice(cfg);
    if (!s->device) {
        hl_inst_destroy(s);
        return hl_fail(ctx, HL_ERR_EMBREE, "Embree: cannot create a device (error %d)", (int)rtcGetDeviceError(NULL));
    }
    rtcSetDeviceErrorFunction(s->device, inst_error, s);
    s->top = rtcNewScene(s->device);
    /* the top level is rebuilt at every motion: a fast build of nobj boxes */
    if (s->top) rtcSetSceneBuildQuality(s->top, RTC_BUILD_QUALITY_LOW);
    int ok = s->top != NULL;
    for (uint32_t i = 0; ok && i < nobj; i++) {
        ok = build_object(s, &objs[i], &s->objs[i]);
        if (ok) s->inst[i] = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_INSTANCE);
        ok = ok && s->inst[i];
        if (!ok) break;
        rtcSetGeometryInstancedScene(s->inst[i], s->objs[i]);
        rtcSetGeometryTransform(s->inst[i], 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, objs[i].xf);
        rtcCommitGeometry(s->inst[i]);
        rtcAttachGeometryByID(s->top, s->inst[i], i);
    }
    if (ok) {
        rtcCommitScene(s->top);
        s->commits++;
    }
    if (!ok || s->err[0]) {
        hl_result r = hl_fail(ctx, HL_ERR_EMBREE, "Embree: building the instance scene failed: %s",
                              s->err[0] ? s->err : "out of memory");
        hl_inst_destroy(s);
        return r;
    }
    *out = s;
    return HL_OK;
}

hl_result hl_inst_set_transform(hl_inst_scene *s, uint32_t i, const float *xf)
{
    if (i >= s->nobj)
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "instance %u of a scene of %u objects", i, s->nobj);
    rtcSetGeometryTransform(s->inst[i], 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, xf);
    rtcCommitGeometry(s->inst[i]);
    s->dirty = 1;
    return HL_OK;
}

void hl_inst_counts(const hl_inst_scene *s, uint64_t *object_builds, uint64_t *scene_commits)
{
    *object_builds = s->builds;
    *scene_commits = s->commits;
}

typedef struct depth_job {
    hl_inst_scene *s;
    const hl_inst_ortho *frames;
    uint32_t K, R;
    float *depth;
    atomic_uint next; /* the next row, over all maps: k R + j */
    atomic_int no_memory; /* a thread could not get its packet */
} depth_job;

/* Row j of map k, 16 texels a packet. */
static void depth_row(depth_job *job, struct RTCRayHit16 *rh, int *valid, uint32_t k, uint32_t j)
{
    const hl_inst_ortho *f = &job->frames[k];
    const uint32_t R = job->R;
    const float inv = 1.0f / f->depth_range, fy = ((float)j + 0.5f) / (float)R * f->height;
    float *row = job->depth + ((size_t)k * R + j) * R;
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (uint32_t i0 = 0; i0 < R; i0 += 16) {
        uint32_t n = R - i0 < 16 ? R - i0 : 16;
        for (uint32_t l = 0; l < 16; l++) {
            valid[l] = l < n ? -1 : 0;
            float fx = ((float)(i0 + l) + 0.5f) / (float)R * f->width;
            rh->ray.org_x[l] = f->origin[0] + fx * f->right[0] + fy * f->up[0];
            rh->ray.org_y[l] = f->origin[1] + fx * f->right[1] + fy * f->up[1];
            rh->ray.org_z[l] = f->origin[2] + fx * f->right[2] + fy * f->up[2];
            rh->ray.dir_x[l] = f->far[0];
            rh->ray.dir_y[l] = f->far[1];
            rh->ray.dir_z[l] = f->far[2];
            rh->ray.tnear[l] = 0.0f;
            rh->ray.tfar[l] = INFINITY;
            rh->ray.mask[l] = 0xffffffffu;
            rh->ray.flags[l] = 0;
            rh->hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
            rh->hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, job->s->top, &ic, rh);
        for (uint32_t l = 0; l < n; l++) {
            float d = rh->hit.geomID[l] != RTC_INVALID_GEOMETRY_ID ? rh->ray.tfar[l] * inv : 1.0f;
            row[i0 + l] = d > 0.0f ? (d < 1.0f ? d : 1.0f) : 0.0f;
        }
    }
}

static void *depth_worker(void *arg)
{
    depth_job *job = arg;
    struct RTCRayHit16 *rh = aligned_alloc(64, sizeof *rh);
    int *valid = aligned_alloc(64, 64);
    const uint32_t rows = job->K * job->R;
    if (!rh || !valid) atomic_store(&job->no_memory, 1);
    for (;;) {
        if (!rh || !valid) break;
        uint32_t r0 = atomic_fetch_add(&job->next, HL_INST_ROWS_PER_TAKE);
        if (r0 >= rows || hl_context_cancelled(job->s->ctx)) break;
        for (uint32_t r = r0; r < r0 + HL_INST_ROWS_PER_TAKE && r < rows; r++) depth_row(job, rh, valid, r / job->R, r % job->R);
    }
    free(rh);
    free(valid);
    return NULL;
}

hl_result hl_inst_depth_maps(hl_inst_scene *s, const hl_inst_ortho *frames, uint32_t K, float *depth)
{
    if (!K) return HL_OK;
    uint32_t R = frames[0].R;
    for (uint32_t k = 1; k < K; k++)
        if (frames[k].R != R)
            return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "depth maps of different sizes (%u and %u) in one call", R, frames[k].R);
    if ((uint64_t)K * R > UINT32_MAX / 2)
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%u depth maps of %u rows: too many rows", K, R);
    if (s->dirty) {
        rtcCommitScene(s->top);
        s->commits++;
        s->dirty = 0;
    }
    depth_job job = {.s = s, .frames = frames, .K = K, .R = R, .depth = depth};
    atomic_init(&job.next, 0u);
    atomic_init(&job.no_memory, 0);
    hl_run_threads(s->ctx->threads, depth_worker, &job);
    /* another thread may have done the rows, but not surely all of them */
    if (atomic_load(&job.no_memory)) return hl_fail(s->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for ray packets");
    if (s->err[0]) return hl_fail(s->ctx, HL_ERR_EMBREE, "Embree: %s", s->err);
    if (hl_context_cancelled(s->ctx)) return hl_fail(s->ctx, HL_ERR_INTERRUPTED, "interrupted");
    return HL_OK;
}

typedef struct occ_job {
    hl_inst_scene *s;
    uint32_t count;
    const float *org, *dir, *tnear;
    uint8_t *occ;
    atomic_uint next; /* the next ray */
    atomic_int no_memory;
} occ_job;

/* Rays a thread takes at a time: 64 packets. */
#define HL_INST_OCC_TAKE 1024u

static void *occ_worker(void *arg)
{
    occ_job *job = arg;
    struct RTCRay16 *ray = aligned_alloc(64, sizeof *ray);
    int *valid = aligned_alloc(64, 64);
    if (!ray || !valid) atomic_store(&job->no_memory, 1);
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    while (ray && valid) {
        const uint32_t r0 = atomic_fetch_add(&job->next, HL_INST_OCC_TAKE);
        if (r0 >= job->count || hl_context_cancelled(job->s->ctx)) break;
        const uint32_t r1 = job->count - r0 < HL_INST_OCC_TAKE ? job->count : r0 + HL_INST_OCC_TAKE;
        for (uint32_t i0 = r0; i0 < r1; i0 += 16) {
            const uint32_t n = r1 - i0 < 16 ? r1 - i0 : 16;
            for (uint32_t l = 0; l < 16; l++) {
                const uint32_t i = i0 + (l < n ? l : 0);
                valid[l] = l < n ? -1 : 0;
                ray->org_x[l] = job->org[3 * (size_t)i], ray->org_y[l] = job->org[3 * (size_t)i + 1];
                ray->org_z[l] = job->org[3 * (size_t)i + 2];
                ray->dir_x[l] = job->dir[3 * (size_t)i], ray->dir_y[l] = job->dir[3 * (size_t)i + 1];
                ray->dir_z[l] = job->dir[3 * (size_t)i + 2];
                ray->tnear[l] = job->tnear ? job->tnear[i] : 0.0f;
                ray->tfar[l] = INFINITY;
                ray->mask[l] = 0xffffffffu;
                ray->flags[l] = 0;
                ray->time[l] = 0.0f;
                ray->id[l] = l;
            }
            rtcOccluded16(valid, job->s->top, &ic, ray);
            /* Embree sets tfar to -inf where something blocks */
            for (uint32_t l = 0; l < n; l++) job->occ[i0 + l] = ray->tfar[l] < 0.0f;
        }
    }
    free(ray);
    free(valid);
    return NULL;
}

hl_result hl_inst_occluded(hl_inst_scene *s, uint32_t count, const float *org, const float *dir, const float *tnear,
                           uint8_t *occ)
{
    if (!count) return HL_OK;
    if (count > UINT32_MAX - HL_INST_OCC_TAKE)
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%u occlusion rays in one call: too many", count);
    if (s->dirty) {
        rtcCommitScene(s->top);
        s->commits++;
        s->dirty = 0;
    }
    occ_job job = {.s = s, .count = count, .org = org, .dir = dir, .tnear = tnear, .occ = occ};
    atomic_init(&job.next, 0u);
    atomic_init(&job.no_memory, 0);
    hl_run_threads(s->ctx->threads, occ_worker, &job);
    if (atomic_load(&job.no_memory)) return hl_fail(s->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for ray packets");
    if (s->err[0]) return hl_fail(s->ctx, HL_ERR_EMBREE, "Embree: %s", s->err);
    if (hl_context_cancelled(s->ctx)) return hl_fail(s->ctx, HL_ERR_INTERRUPTED, "interrupted");
    return HL_OK;
}
