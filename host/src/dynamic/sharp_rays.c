/* sharp_rays.c - the sharp lights' visibility by occlusion rays
 * (sharp_rays.h): the receivers in chunks; per chunk the 5 first rays of
 * every lit receiver traced at once, then the rest of the grid for those
 * whose first rays disagree.
 * Depends on: sharp_rays.h, instances.h, rays.h (the robust offset),
 * core.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "instances.h"
#include "rays.h"
#include "sharp_rays.h"

/* Receivers a chunk holds: 2^16, so its ray arrays (G^2 rays each, 29
 * bytes a ray) stay near 30 MB whatever the mesh. */
#define HL_SHARP_RAYS_CHUNK (1u << 16)

#define G HL_SHARP_RAYS_GRID
#define GG (G * G)

struct hl_sharp_rays {
    hl_context *ctx;
    hl_inst_scene *scene;
    uint32_t nobj, N;
    float *edge;              /* N: each receiver's longest edge */
    float *org, *dir, *tnear; /* a chunk's rays */
    uint8_t *occ;
    uint32_t *first;          /* chunk receiver + 1: its first ray */
    uint8_t *mark;            /* chunk receiver: 1 lit (rays cast), 2 in a penumbra */
};

void hl_sharp_rays_destroy(hl_sharp_rays *sr)
{
    if (!sr) return;
    hl_inst_destroy(sr->scene);
    free(sr->edge); free(sr->org); free(sr->dir); free(sr->tnear); free(sr->occ); free(sr->first); free(sr->mark);
    free(sr);
}

hl_result hl_sharp_rays_create(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, hl_sharp_rays **out)
{
    *out = NULL;
    hl_sharp_rays *sr = hl_calloc(ctx, 1, sizeof *sr, "the sharp lights' rays");
    if (!sr) return HL_ERR_OUT_OF_MEMORY;
    sr->ctx = ctx;
    sr->nobj = nobj;
    uint64_t N = 0;
    for (uint32_t b = 0; b < nobj; b++) N += objects[b].nverts;
    sr->N = (uint32_t)N;
    hl_inst_mesh *m = calloc(nobj, sizeof *m);
    sr->edge = malloc((N ? N : 1) * sizeof *sr->edge);
    const size_t chunk = N < HL_SHARP_RAYS_CHUNK ? (size_t)N : HL_SHARP_RAYS_CHUNK, nr = chunk * GG;
    sr->org = malloc(3 * nr * 4), sr->dir = malloc(3 * nr * 4), sr->tnear = malloc(nr * 4), sr->occ = malloc(nr);
    sr->first = malloc((chunk + 1) * 4), sr->mark = malloc(chunk ? chunk : 1);
    if (!m || !sr->edge || !sr->org || !sr->dir || !sr->tnear || !sr->occ || !sr->first || !sr->mark) {
        free(m);
        hl_sharp_rays_destroy(sr);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the sharp lights' rays (%u receivers)", (uint32_t)N);
    }
    size_t at = 0;
    for (uint32_t b = 0; b < nobj; b++) {
        const hl_dyn_object *o = &objects[b];
        m[b] = (hl_inst_mesh){.pos = o->pos, .nverts = o->nverts, .tri = o->tri, .ntris = o->ntris, .xf = o->xf};
        /* edges keep their length under a rigid motion */
        hl_rt_longest_edges(o->pos, o->nverts, o->tri, o->ntris, sr->edge + at);
        at += o->nverts;
    }
    hl_result r = hl_inst_create(ctx, m, nobj, &sr->scene);
    free(m);
    if (r != HL_OK) {
        hl_sharp_rays_destroy(sr);
        return r;
    }
    *out = sr;
    return HL_OK;
}

hl_result hl_sharp_rays_set_transform(hl_sharp_rays *sr, uint32_t b, const float *xf)
{
    return hl_inst_set_transform(sr->scene, b, xf);
}

/* Sample (i, j) of the grid (i, j < G), or dir itself for i = G. */
static void sample_dir(const float dir[3], const float t1[3], const float t2[3], float ta, uint32_t i, uint32_t j,
                       float d[3])
{
    const float x = i < G ? (2.0f * (float)i + 1.0f) / (float)G - 1.0f : 0.0f;
    const float y = i < G ? (2.0f * (float)j + 1.0f) / (float)G - 1.0f : 0.0f;
    float l = 0.0f;
    for (int c = 0; c < 3; c++) d[c] = dir[c] + ta * (x * t1[c] + y * t2[c]), l += d[c] * d[c];
    l = 1.0f / sqrtf(l);
    for (int c = 0; c < 3; c++) d[c] *= l;
}

/* One ray of receiver v (position p, normal n) along d at slot s, when d
 * is above its horizon. Returns 1 if cast. */
static int put_ray(hl_sharp_rays *sr, const float *p, const float *n, float edge, const float d[3], size_t s)
{
    if (!(n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0.0f)) return 0;
    const float off = hl_rt_offset_size(p, edge);
    for (int c = 0; c < 3; c++) sr->org[3 * s + c] = hl_rt_origin_coord(p[c], n[c], off), sr->dir[3 * s + c] = d[c];
    sr->tnear[s] = off;
    return 1;
}

/* The 5 first samples: the grid's corners and the centre. */
static const uint32_t FIRST5[5][2] = {{0, 0}, {G - 1, 0}, {0, G - 1}, {G - 1, G - 1}, {G, 0}};

hl_result hl_sharp_rays_visibility(hl_sharp_rays *sr, const float *wpos, const float *wnrm, const float *E,
                                   const float dir[3], float spread, float *V, uint64_t *rays)
{
    /* an orthonormal basis about dir */
    const float a[3] = {fabsf(dir[0]) < 0.6f ? 1.0f : 0.0f, fabsf(dir[0]) < 0.6f ? 0.0f : 1.0f, 0.0f};
    float t1[3] = {a[1] * dir[2] - a[2] * dir[1], a[2] * dir[0] - a[0] * dir[2], a[0] * dir[1] - a[1] * dir[0]};
    const float l1 = 1.0f / sqrtf(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    for (int c = 0; c < 3; c++) t1[c] *= l1;
    const float t2[3] = {dir[1] * t1[2] - dir[2] * t1[1], dir[2] * t1[0] - dir[0] * t1[2], dir[0] * t1[1] - dir[1] * t1[0]};
    const float ta = tanf(spread > 0.0f ? spread : 0.0f);
    uint64_t cast = 0;
    for (uint32_t v0 = 0; v0 < sr->N; v0 += HL_SHARP_RAYS_CHUNK) {
        const uint32_t cnt = sr->N - v0 < HL_SHARP_RAYS_CHUNK ? sr->N - v0 : HL_SHARP_RAYS_CHUNK;
        /* pass 1: the 5 first rays of each lit receiver */
        size_t s = 0;
        for (uint32_t i = 0; i < cnt; i++) {
            const size_t v = (size_t)v0 + i;
            const float *e = E + 3 * v, *p = wpos + 3 * v, *n = wnrm + 3 * v;
            sr->first[i] = (uint32_t)s;
            sr->mark[i] = e[0] > 0.0f || e[1] > 0.0f || e[2] > 0.0f;
            V[v] = sr->mark[i] ? 1.0f : 0.0f; /* no sample above the horizon: E is a sliver */
            if (!sr->mark[i]) continue;
            for (int k = 0; k < 5; k++) {
                float d[3];
                sample_dir(dir, t1, t2, ta, FIRST5[k][0], FIRST5[k][1], d);
                s += (size_t)put_ray(sr, p, n, sr->edge[v], d, s);
            }
        }
        sr->first[cnt] = (uint32_t)s;
        hl_result r = hl_inst_occluded(sr->scene, (uint32_t)s, sr->org, sr->dir, sr->tnear, sr->occ);
        if (r != HL_OK) return r;
        cast += s;
        for (uint32_t i = 0; i < cnt; i++) {
            const uint32_t f = sr->first[i], m = sr->first[i + 1] - f;
            if (!m) continue;
            uint32_t blocked = 0;
            for (uint32_t k = 0; k < m; k++) blocked += sr->occ[f + k];
            if (blocked == m) V[(size_t)v0 + i] = 0.0f;
            else if (blocked) sr->mark[i] = 2;
        }
        /* pass 2: the whole grid where the first rays disagree (their
           corner rays cast again, which keeps the counting plain) */
        s = 0;
        for (uint32_t i = 0; i < cnt; i++) {
            sr->first[i] = (uint32_t)s;
            if (sr->mark[i] != 2) continue;
            const size_t v = (size_t)v0 + i;
            for (uint32_t gi = 0; gi < G; gi++)
                for (uint32_t gj = 0; gj < G; gj++) {
                    float d[3];
                    sample_dir(dir, t1, t2, ta, gi, gj, d);
                    s += (size_t)put_ray(sr, wpos + 3 * v, wnrm + 3 * v, sr->edge[v], d, s);
                }
        }
        sr->first[cnt] = (uint32_t)s;
        r = hl_inst_occluded(sr->scene, (uint32_t)s, sr->org, sr->dir, sr->tnear, sr->occ);
        if (r != HL_OK) return r;
        cast += s;
        for (uint32_t i = 0; i < cnt; i++) {
            const uint32_t f = sr->first[i], m = sr->first[i + 1] - f;
            if (sr->mark[i] != 2 || !m) continue;
            uint32_t free_ = 0;
            for (uint32_t k = 0; k < m; k++) free_ += !sr->occ[f + k];
            V[(size_t)v0 + i] = (float)free_ / (float)m;
        }
    }
    if (rays) *rays = cast;
    return HL_OK;
}
