/* dyn_api.c - the public face of the dynamic method (haarlight.h,
 * "dynamic scenes"): a scene of rigid bodies (scene.h), its light split
 * (area_lights.h) and frame state (dyn_frame.h) behind one opaque handle,
 * and the bodies merged into one world-space hl_mesh per frame so that
 * relight's writers and renderer take the result as they are.
 * Depends on: scene.h, area_lights.h, dyn_frame.h, haarlight.h, core.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "area_lights.h"
#include "dyn_api.h"
#include "dyn_frame.h"
#include "haarlight.h"
#include "scene.h"

struct hl_dynamic {
    hl_context *ctx;
    hl_dyn_scene *scene;
    uint32_t nb;
    hl_dyn_object *obj;
    const float **alb;
    float **rgbs;          /* into rgb, per body */
    uint32_t *vstart;
    float *rgb;            /* 3 per vertex of mesh */
    hl_mesh *mesh;         /* merged, world space */
    hl_frame_settings set;
    hl_light_split *split;
    hl_frame_state *fs;
    uint32_t fs_lights;    /* max_lights of fs */
    /* the last frame's inputs: a frame with the same transforms and the
       same lights is the last frame again, and costs nothing */
    float *last_xf;        /* 12 per body */
    const hl_light_split *last_split;
    int have_last;
    hl_surface *surface; /* the bodies' textured surfaces merged as mesh is, or NULL */
};

void hl_dynamic_destroy(hl_dynamic *d)
{
    if (!d) return;
    hl_frame_state_destroy(d->fs);
    hl_light_split_destroy(d->split);
    hl_mesh_destroy(d->mesh);
    hl_surface_destroy(d->surface);
    hl_dyn_scene_destroy(d->scene);
    free(d->obj); free(d->alb); free(d->rgbs); free(d->vstart); free(d->rgb); free(d->last_xf);
    free(d);
}

/* The merged mesh's positions and normals from the bodies' current xf. */
static void update_mesh(hl_dynamic *d)
{
    for (uint32_t b = 0; b < d->nb; b++)
        hl_frame_to_world(&d->obj[b], d->mesh->positions + 3 * (size_t)d->vstart[b],
                          d->mesh->normals + 3 * (size_t)d->vstart[b]);
}

/* Takes the scene: arrays per body, the merged mesh at time 0. */
/* The bodies' textured surfaces as one for the merged mesh (its triangles
 * body after body; untextured bodies, the ground, with no texture); the
 * scene's textures move into it. None without a textured body. */
static hl_result merge_surfaces(hl_dynamic *d, uint32_t nt)
{
    hl_dyn_scene *s = d->scene;
    int any = 0;
    for (uint32_t b = 0; b < s->nbodies; b++) any |= s->bodies[b].surf != NULL;
    if (!any || !s->mats.ntex) return HL_OK;
    hl_surface *su = hl_calloc(d->ctx, 1, sizeof *su, "the surface");
    if (!su) return HL_ERR_OUT_OF_MEMORY;
    if (hl_surface_arrays_(d->ctx, su, nt) != HL_OK) {
        hl_surface_destroy(su);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t b = 0, t0 = 0; b < s->nbodies; b++) {
        const hl_surface *bs = s->bodies[b].surf;
        const uint32_t n = s->bodies[b].ntris;
        if (bs && bs->triangle_count == n) {
            memcpy(su->tex + t0, bs->tex, (size_t)n * sizeof(int32_t));
            memcpy(su->uv + 6 * (size_t)t0, bs->uv, (size_t)n * 6 * sizeof(float));
            memcpy(su->base + 9 * (size_t)t0, bs->base, (size_t)n * 9 * sizeof(float));
        } else
            for (uint32_t t = 0; t < n; t++) su->tex[t0 + t] = -1;
        t0 += n;
    }
    su->mats = s->mats;
    memset(&s->mats, 0, sizeof s->mats);
    d->surface = su;
    return HL_OK;
}

static hl_result dynamic_init(hl_context *ctx, hl_dyn_scene *scene, const hl_dynamic_desc *desc, hl_dynamic **out)
{
    uint32_t R = desc ? desc->shadow_res : 0, M = desc ? desc->order : 0, Rs = desc ? desc->sharp_res : 0;
    if (M && (M < HL_CSM_M_MIN || M > HL_CSM_M_MAX)) {
        hl_dyn_scene_destroy(scene);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--order %u: expected %u to %u", M, HL_CSM_M_MIN, HL_CSM_M_MAX);
    }
    if (R && (R < HL_CSM_R_MIN || R > HL_CSM_R_MAX || R % HL_CSM_SCAN_LANES)) {
        hl_dyn_scene_destroy(scene);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--shadow-res %u: expected a multiple of %u from %u to %u", R,
                       HL_CSM_SCAN_LANES, HL_CSM_R_MIN, HL_CSM_R_MAX);
    }
    const uint32_t Rmin = R ? R : HL_SHADOW_DEFAULT_R;
    if (Rs && (Rs < Rmin || Rs > HL_CSM_R_MAX || Rs % HL_CSM_SCAN_LANES)) {
        hl_dyn_scene_destroy(scene);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--sharp-res %u: expected a multiple of %u from the map size %u to %u",
                       Rs, HL_CSM_SCAN_LANES, Rmin, HL_CSM_R_MAX);
    }
    uint32_t shadow = desc ? desc->shadow : HL_DYNAMIC_SHADOW_DEFAULT;
    const uint32_t sharp = desc ? desc->sharp : HL_DYNAMIC_SHARP_DEFAULT;
    if (sharp > HL_DYNAMIC_SHARP_OFF) {
        hl_dyn_scene_destroy(scene);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--sharp %u: expected the default (%u), rays (%u), maps (%u) or off (%u)",
                       sharp, HL_DYNAMIC_SHARP_DEFAULT, HL_DYNAMIC_SHARP_RAYS, HL_DYNAMIC_SHARP_MAPS, HL_DYNAMIC_SHARP_OFF);
    }
    if (Rs && Rs != Rmin && sharp != HL_DYNAMIC_SHARP_DEFAULT && sharp != HL_DYNAMIC_SHARP_MAPS) {
        hl_dyn_scene_destroy(scene);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--sharp-res %u is the sharp lights' map size: not with --sharp %s", Rs,
                       sharp == HL_DYNAMIC_SHARP_RAYS ? "rays" : "off");
    }
    if (shadow != HL_DYNAMIC_SHADOW_DEFAULT && shadow != HL_DYNAMIC_SHADOW_CSM && shadow != HL_DYNAMIC_SHADOW_MOMENTS) {
        hl_dyn_scene_destroy(scene);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--shadow %u: expected the default (%u), csm (%u) or moments (%u)",
                       shadow, HL_DYNAMIC_SHADOW_DEFAULT, HL_DYNAMIC_SHADOW_CSM, HL_DYNAMIC_SHADOW_MOMENTS);
    }
    if (shadow == HL_DYNAMIC_SHADOW_MOMENTS && M) {
        hl_dyn_scene_destroy(scene);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "--order %u is the CSM's order: --shadow moments takes four moments, no order", M);
    }
    hl_dynamic *d = hl_calloc(ctx, 1, sizeof *d, "the dynamic scene");
    if (!d) { hl_dyn_scene_destroy(scene); return HL_ERR_OUT_OF_MEMORY; }
    d->ctx = ctx;
    d->scene = scene;
    d->nb = hl_dyn_scene_body_count(scene);
    d->set.min_share = -1.0f;
    d->set.R = R, d->set.M = M, d->set.R_sharp = Rs;
    /* the public values are the frame's (hl_sharp_mode) */
    _Static_assert(HL_DYNAMIC_SHARP_RAYS == HL_SHARP_RAYS && HL_DYNAMIC_SHARP_MAPS == HL_SHARP_MAPS &&
                       HL_DYNAMIC_SHARP_OFF == HL_SHARP_OFF && HL_DYNAMIC_SHARP_DEFAULT == HL_SHARP_DEFAULT,
                   "hl_dynamic_desc.sharp is cast to hl_sharp_mode");
    d->set.sharp = (hl_sharp_mode)sharp;
    /* an order given with the default asks for the CSM it is the order of
       (the viewer's and older callers' --order) */
    d->set.shadow = shadow == HL_DYNAMIC_SHADOW_MOMENTS              ? HL_SHADOW_REP_MOMENTS
                    : shadow == HL_DYNAMIC_SHADOW_CSM || M != 0      ? HL_SHADOW_REP_CSM
                                                                     : HL_SHADOW_REP_DEFAULT;
    d->obj = calloc(d->nb, sizeof *d->obj);
    d->alb = calloc(d->nb, sizeof *d->alb);
    d->rgbs = calloc(d->nb, sizeof *d->rgbs);
    d->vstart = calloc(d->nb, sizeof *d->vstart);
    d->mesh = calloc(1, sizeof *d->mesh);
    d->last_xf = calloc((size_t)d->nb * 12, sizeof *d->last_xf);
    hl_result r = (d->obj && d->alb && d->rgbs && d->vstart && d->mesh && d->last_xf) ? HL_OK
                  : hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the dynamic scene");
    if (r == HL_OK) r = hl_dyn_scene_at(scene, 0.0, d->obj);
    uint64_t nv = 0, nt = 0;
    for (uint32_t b = 0; r == HL_OK && b < d->nb; b++) d->vstart[b] = (uint32_t)nv, nv += d->obj[b].nverts, nt += d->obj[b].ntris;
    if (r == HL_OK && (nv > UINT32_MAX / 3 || nt > UINT32_MAX / 3))
        r = hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic scene: %llu vertices and %llu triangles are too many",
                    (unsigned long long)nv, (unsigned long long)nt);
    if (r == HL_OK) {
        hl_mesh *m = d->mesh;
        m->vertex_count = (uint32_t)nv, m->triangle_count = (uint32_t)nt;
        int32_t g = hl_dyn_scene_find(scene, "ground");
        /* the ground is last when the scene came from a mesh with one */
        m->object_vertex_count = (g >= 0 && (uint32_t)g == d->nb - 1 && d->nb > 1) ? d->vstart[g] : m->vertex_count;
        m->positions = malloc(nv * 12), m->normals = malloc(nv * 12), m->albedo = malloc(nv * 12);
        m->indices = malloc(nt * 12);
        d->rgb = calloc(nv * 3, sizeof(float));
        if (!m->positions || !m->normals || !m->albedo || !m->indices || !d->rgb)
            r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the dynamic scene's mesh");
    }
    for (uint32_t b = 0, t0 = 0; r == HL_OK && b < d->nb; b++) {
        const hl_dyn_object *o = &d->obj[b];
        d->alb[b] = hl_dyn_scene_body_albedo(scene, b);
        d->rgbs[b] = d->rgb + 3 * (size_t)d->vstart[b];
        memcpy(d->mesh->albedo + 3 * (size_t)d->vstart[b], d->alb[b], (size_t)o->nverts * 12);
        for (size_t i = 0; i < 3 * (size_t)o->ntris; i++) d->mesh->indices[3 * (size_t)t0 + i] = o->tri[i] + d->vstart[b];
        t0 += o->ntris;
    }
    if (r == HL_OK) r = merge_surfaces(d, (uint32_t)nt);
    if (r != HL_OK) { hl_dynamic_destroy(d); return r; }
    update_mesh(d);
    *out = d;
    return HL_OK;
}

const hl_surface *hl_dynamic_surface(const hl_dynamic *d)
{
    return d ? d->surface : NULL;
}

/* gd: the ground's options where one is added */
static hl_result from_mesh(hl_context *ctx, const hl_mesh *mesh, int ground, const hl_ground_desc *gd,
                           const hl_dynamic_desc *desc, hl_dynamic **out)
{
    if (!out || !mesh) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_create_from_mesh: a NULL argument");
    *out = NULL;
    hl_ground_desc none = {0};
    /* a mesh that carries its ground gives it as a body already */
    int add = ground && mesh->object_vertex_count == mesh->vertex_count;
    hl_dyn_scene *s = NULL;
    hl_result r = hl_dyn_scene_from_mesh(ctx, mesh, add ? (gd ? gd : &none) : NULL, &s);
    return r == HL_OK ? dynamic_init(ctx, s, desc, out) : r;
}

hl_result hl_dynamic_create_from_mesh(hl_context *ctx, const hl_mesh *mesh, int ground, const hl_dynamic_desc *desc,
                                      hl_dynamic **out)
{
    return from_mesh(ctx, mesh, ground, NULL, desc, out);
}

hl_result hl_dynamic_create_from_file(hl_context *ctx, const char *path, int ground, const hl_dynamic_desc *desc,
                                      hl_dynamic **out)
{
    return hl_dynamic_create_from_file_ground(ctx, path, ground, desc, NULL, out);
}

hl_result hl_dynamic_create_from_file_ground(hl_context *ctx, const char *path, int ground, const hl_dynamic_desc *desc,
                                             const hl_ground_desc *gd, hl_dynamic **out)
{
    if (!out || !path) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_create_from_file: a NULL argument");
    *out = NULL;
    const int flags = ground, rest = (flags & HL_DYNAMIC_REST_POSE) != 0;
    if (flags & ~(HL_DYNAMIC_GROUND | HL_DYNAMIC_REST_POSE))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_create_from_file: unknown flags 0x%x", (unsigned)flags);
    hl_result r = HL_OK;
    if (flags & HL_DYNAMIC_GROUND) {
        /* a still file: one mesh and its ground, as the transport of the
           same file has them (a viewer's --hlt pairs the two) */
        hl_mesh *m = NULL;
        hl_mesh_motion mo;
        r = hl_mesh_probe_motion_(ctx, path, &mo); /* an animated file is read once, as a scene */
        if (r == HL_OK && (rest || mo.animations == 0)) {
            r = hl_mesh_load(ctx, path, NULL, &m, NULL);
            if (r == HL_OK) r = from_mesh(ctx, m, 1, gd, desc, out);
        }
        hl_mesh_destroy(m);
        if (r != HL_OK || *out) return r;
    }
    hl_dyn_scene_desc sd = {0};
    sd.animation = rest ? HL_DYN_NO_ANIMATION : 0;
    hl_dyn_scene *s = NULL;
    r = hl_dyn_scene_load_desc(ctx, path, &sd, &s);
    /* an animated file keeps its bodies and motion over its ground */
    if (r == HL_OK && (flags & HL_DYNAMIC_GROUND)) r = hl_dyn_scene_add_ground(s, gd);
    if (r != HL_OK) {
        hl_dyn_scene_destroy(s);
        return r;
    }
    return dynamic_init(ctx, s, desc, out);
}

uint32_t hl_dynamic_body_count(const hl_dynamic *d) { return d ? d->nb : 0; }

const char *hl_dynamic_body_name(const hl_dynamic *d, uint32_t body)
{
    return d ? hl_dyn_scene_body_name(d->scene, body) : NULL;
}

void hl_dynamic_time_range(const hl_dynamic *d, double *start, double *end)
{
    double a = 0, b = 0;
    if (d) hl_dyn_scene_animation(d->scene, &a, &b);
    if (start) *start = a;
    if (end) *end = b;
}

const hl_mesh *hl_dynamic_mesh(const hl_dynamic *d) { return d ? d->mesh : NULL; }

hl_result hl_dynamic_move(hl_dynamic *d, const char *body, const float translate[3])
{
    if (!d) return HL_ERR_INVALID_ARGUMENT;
    if (!body || !translate) return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_move: a NULL argument");
    int32_t b = hl_dyn_scene_find(d->scene, body);
    if (b < 0) {
        char names[512] = "";
        size_t at = 0;
        for (uint32_t i = 0; i < d->nb && at < sizeof names; i++) {
            int n = snprintf(names + at, sizeof names - at, "%s\"%s\"", i ? ", " : "", hl_dyn_scene_body_name(d->scene, i));
            if (n < 0) break;
            at += (size_t)n;
        }
        return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "no body named \"%s\" (the bodies: %s)", body, names);
    }
    for (int k = 0; k < 3; k++)
        if (!isfinite(translate[k]))
            return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "move of \"%s\": the translation is not finite", body);
    double tr[3] = {translate[0], translate[1], translate[2]}, axis[3] = {0, 1, 0};
    return hl_dyn_scene_set_pose(d->scene, (uint32_t)b, tr, axis, 0.0);
}

hl_result hl_dynamic_set_transform(hl_dynamic *d, uint32_t body, const float xf[12])
{
    if (!d) return HL_ERR_INVALID_ARGUMENT;
    if (!xf) return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_set_transform: no transform");
    if (body >= d->nb)
        return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_set_transform: body %u of %u", body, d->nb);
    return hl_dyn_scene_set_transform(d->scene, body, xf);
}

hl_result hl_dynamic_body_vertices(const hl_dynamic *d, uint32_t body, uint32_t *first, uint32_t *count)
{
    if (!d || body >= d->nb) return HL_ERR_INVALID_ARGUMENT;
    if (first) *first = d->vstart[body];
    if (count) *count = d->obj[body].nverts;
    return HL_OK;
}

hl_result hl_dynamic_set_env(hl_dynamic *d, const hl_env *env, int32_t lights, float split_threshold, float rotate_deg,
                             hl_dynamic_lights *info)
{
    if (!d) return HL_ERR_INVALID_ARGUMENT;
    if (!env) return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_set_env: no environment");
    if (lights < 1) return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "--lights %d: at least one light is kept", lights);
    hl_light_split_params p;
    hl_light_split_defaults(&p);
    p.lights = lights;
    p.rotate_deg = rotate_deg;
    if (split_threshold != 0.0f) p.threshold = split_threshold; /* the split checks (0, 1) and NaN */
    hl_light_split *s = NULL;
    hl_result r = hl_area_lights_split(d->ctx, env, &p, &s);
    if (r != HL_OK) return r;
    hl_light_split_destroy(d->split);
    d->split = s;
    d->have_last = 0; /* new lights: the next frame is computed */
    if (info) {
        info->lights_made = s->total;
        info->lights_kept = s->count;
        info->folded = s->stats.folded;
        info->folded_share = s->stats.folded_share;
        info->seconds = s->stats.seconds;
    }
    return HL_OK;
}

hl_result hl_dynamic_render(hl_dynamic *d, double t, float **rgb_out, hl_dynamic_stats *st)
{
    if (!d) return HL_ERR_INVALID_ARGUMENT;
    if (!rgb_out) return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_render: no output pointer");
    *rgb_out = NULL;
    if (!d->split) return hl_fail(d->ctx, HL_ERR_INVALID_ARGUMENT, "hl_dynamic_render: no environment set");
    hl_result r = hl_dyn_scene_at(d->scene, t, d->obj);
    if (r != HL_OK) return r;
    int same = d->have_last && d->last_split == d->split;
    for (uint32_t b = 0; same && b < d->nb; b++) same = !memcmp(d->last_xf + 12 * (size_t)b, d->obj[b].xf, sizeof d->obj[b].xf);
    if (same) {
        *rgb_out = d->rgb;
        if (st) {
            memset(st, 0, sizeof *st);
            st->vertices = d->mesh->vertex_count;
            st->reused = 1;
        }
        return HL_OK;
    }
    d->have_last = 0;
    if (d->fs && d->fs_lights < d->split->count) {
        hl_frame_state_destroy(d->fs);
        d->fs = NULL;
    }
    if (!d->fs) {
        r = hl_frame_state_create(d->ctx, d->obj, d->nb, d->split->count, &d->set, &d->fs);
        if (r != HL_OK) return r;
        d->fs_lights = d->split->count;
    }
    hl_frame_stats fs;
    r = hl_frame_render(d->fs, d->obj, d->nb, d->alb, d->split, d->rgbs, &fs);
    if (r != HL_OK) return r;
    update_mesh(d);
    *rgb_out = d->rgb;
    for (uint32_t b = 0; b < d->nb; b++) memcpy(d->last_xf + 12 * (size_t)b, d->obj[b].xf, sizeof d->obj[b].xf);
    d->last_split = d->split;
    d->have_last = 1;
    if (st) {
        st->reused = 0;
        st->vertices = fs.receivers, st->lights = fs.lights, st->shadowed = fs.shadowed;
        st->skipped_horizon = fs.skipped_horizon, st->skipped_negligible = fs.skipped_negligible;
        st->batches = fs.batches, st->maps_kept = fs.maps_kept;
        st->shadow_res = fs.R, st->sharp = fs.sharp, st->sharp_res = fs.R_sharp, st->covered = fs.covered, st->enclosed = fs.enclosed;
        st->sharp_mode = fs.sharp_mode, st->sharp_rays = fs.sharp_rays, st->t_sharp_rays = fs.t_sharp_rays;
        st->folded_share = d->split->stats.folded_share;
        st->t_irradiance = fs.t_irradiance, st->t_shadow_maps = fs.t_shadow_maps;
        st->t_csm_build = fs.t_csm_build, st->t_csm_eval = fs.t_csm_eval, st->t_shading = fs.t_shading;
        st->t_total = fs.t_total;
    }
    return HL_OK;
}

/* For the measuring tools (dyn_api.h). */
void hl_dynamic_view_get(const hl_dynamic *d, hl_dynamic_view *v)
{
    v->ctx = d->ctx;
    v->nb = d->nb;
    v->obj = d->obj;
    v->alb = (const float *const *)d->alb;
    v->vstart = d->vstart;
    v->split = d->split;
}
