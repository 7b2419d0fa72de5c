/* surroundings.c - the public hl_surroundings_*: triangles around an
 * object, each emitting an RGB radiance or dark, posed in world space at
 * a time and under the program's transforms, for the capture
 * (capture.h) to render.
 *
 * Bodies and motion are the dynamic method's scene (host/src/dynamic/
 * scene.h), loaded with keep_triangles: the shared mesh builder welds
 * equal positions and drops degenerate triangles, which would detach each
 * triangle's emission from it (a lamp and a wall sharing a corner, a
 * sliver on a lamp's edge), and the capture needs neither normals nor
 * welding, so each triangle is kept as the file gives it, with the file
 * mesh it came from. Its radiance is that mesh's material's emissive
 * colour times its emissive intensity, times glTF's emissive strength
 * (surroundings_gltf.c, since assimp 5.2 does not read it).
 *
 * The world-space triangles are cached: hl_surroundings_triangles poses
 * them only after the time or a transform changed, so asking twice gives
 * the same bytes at no cost (the relighter compares them to skip a frame).
 *
 * Depends on: capture.h, surroundings.h, scene.h
 * (the dynamic scene), hl_internal.h, libm.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "scene.h"
#include "surroundings.h"

/* The body name of surroundings made from arrays (the public header's). */
#define HL_SURR_ARRAY_BODY "surroundings"
/* The name of surroundings made from arrays, in messages. */
#define HL_SURR_ARRAY_NAME "surroundings from arrays"

struct hl_surroundings {
    hl_context *ctx;
    hl_dyn_scene *scene;
    uint32_t ntris, nbodies;
    float *emission;       /* 3 per triangle, bodies in order */
    int *emits;            /* per body */
    float *world;          /* 9 per triangle: the cache */
    hl_dyn_object *objs;   /* per body, scratch of the posing */
    double t;              /* the time asked for */
    int posed;             /* world holds the pose at t and the transforms */
};

void hl_surroundings_destroy(hl_surroundings *s)
{
    if (!s) return;
    hl_dyn_scene_destroy(s->scene);
    free(s->emission);
    free(s->emits);
    free(s->world);
    free(s->objs);
    free(s);
}

/* Every corner finite, every radiance finite and >= 0; notes which
 * bodies emit. name is the file or the arrays, for messages. */
static hl_result check_triangles(hl_surroundings *s, const char *name)
{
    uint32_t t = 0;
    for (uint32_t b = 0; b < s->nbodies; b++) {
        const hl_dyn_object *o = &s->objs[b];
        const char *body = hl_dyn_scene_body_name(s->scene, b);
        for (uint32_t i = 0; i < 9 * o->ntris; i++)
            if (!isfinite(o->pos[i]))
                return hl_fail(s->ctx, HL_ERR_MESH, "%s: body \"%s\": triangle %u has a non-finite corner", name, body,
                               i / 9);
        for (uint32_t i = 0; i < o->ntris; i++, t++) {
            const float *e = s->emission + 3 * (size_t)t;
            for (int c = 0; c < 3; c++)
                if (!(isfinite(e[c]) && e[c] >= 0.0f))
                    return hl_fail(s->ctx, HL_ERR_MESH,
                                   "%s: body \"%s\": triangle %u emits %g %g %g: radiance must be finite and >= 0",
                                   name, body, i, (double)e[0], (double)e[1], (double)e[2]);
            s->emits[b] |= e[0] > 0.0f || e[1] > 0.0f || e[2] > 0.0f;
        }
    }
    return HL_OK;
}

/* Takes the scene (destroyed on failure): counts its triangles (bodies in
 * order) and makes the arrays; the emission is filled by the caller. No
 * cap: the capture's hierarchy takes any count that fits in memory and
 * the 32-bit indices. */
static hl_result wrap_scene(hl_context *ctx, hl_dyn_scene *scene, const char *name, hl_surroundings **out)
{
    hl_surroundings *s = hl_calloc(ctx, 1, sizeof *s, "the surroundings");
    if (!s) {
        hl_dyn_scene_destroy(scene);
        return HL_ERR_OUT_OF_MEMORY;
    }
    s->ctx = ctx;
    s->scene = scene;
    s->nbodies = hl_dyn_scene_body_count(scene);
    s->objs = hl_calloc(ctx, s->nbodies, sizeof *s->objs, "the surroundings' bodies");
    s->emits = hl_calloc(ctx, s->nbodies, sizeof *s->emits, "the surroundings' bodies");
    double t0 = 0.0;
    hl_dyn_scene_animation(scene, &t0, NULL);
    s->t = t0 > 0.0 ? t0 : 0.0;
    hl_result r = s->objs && s->emits ? hl_dyn_scene_at(scene, s->t, s->objs) : HL_ERR_OUT_OF_MEMORY;
    uint64_t n = 0;
    for (uint32_t b = 0; r == HL_OK && b < s->nbodies; b++) n += s->objs[b].ntris;
    if (r == HL_OK && n == 0) r = hl_fail(ctx, HL_ERR_MESH, "%s: no triangles", name);
    if (r == HL_OK && n > UINT32_MAX / 9)
        r = hl_fail(ctx, HL_ERR_MESH, "%s: %llu triangles, more than 32-bit indices can count", name, (unsigned long long)n);
    s->ntris = (uint32_t)n;
    if (r == HL_OK) {
        s->emission = hl_calloc(ctx, n ? n : 1, 3 * sizeof(float), "triangle emission");
        s->world = hl_malloc(ctx, (n ? n : 1) * 9 * sizeof(float), "world triangles");
        if (!s->emission || !s->world) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r != HL_OK) {
        hl_surroundings_destroy(s);
        return r;
    }
    *out = s;
    return HL_OK;
}

hl_result hl_surroundings_load(hl_context *ctx, const char *path, hl_surroundings **out)
{
    if (out) *out = NULL;
    if (!path || !out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_surroundings_load: path and out are required");
    hl_dyn_scene_desc d;
    memset(&d, 0, sizeof d);
    d.keep_triangles = 1;
    hl_dyn_scene *scene = NULL;
    hl_result r = hl_dyn_scene_load_desc(ctx, path, &d, &scene);
    if (r != HL_OK) return r;
    hl_surroundings *s = NULL;
    r = wrap_scene(ctx, scene, path, &s);
    if (r != HL_OK) return r;
    uint32_t nm = hl_dyn_scene_mesh_count(scene);
    float *strength = hl_malloc(ctx, (nm ? nm : 1) * sizeof(float), "emissive strengths");
    if (!strength) r = HL_ERR_OUT_OF_MEMORY;
    else r = hl_gltf_emissive_strength_(ctx, path, nm, strength);
    uint32_t t = 0;
    for (uint32_t b = 0; r == HL_OK && b < s->nbodies; b++) {
        const uint32_t *tm = hl_dyn_scene_body_tri_mesh(scene, b);
        for (uint32_t i = 0; i < s->objs[b].ntris; i++, t++) {
            const float *e = hl_dyn_scene_mesh_emission(scene, tm[i]);
            for (int c = 0; c < 3; c++) s->emission[3 * (size_t)t + c] = e[c] * strength[tm[i]];
        }
    }
    free(strength);
    if (r == HL_OK) r = check_triangles(s, path);
    if (r != HL_OK) {
        hl_surroundings_destroy(s);
        return r;
    }
    *out = s;
    return HL_OK;
}

hl_result hl_surroundings_create(hl_context *ctx, const float *positions, const float *emission,
                                 uint32_t triangle_count, hl_surroundings **out)
{
    if (out) *out = NULL;
    if (!positions || !emission || !out)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_surroundings_create: positions, emission and out are required");
    if (triangle_count == 0) return hl_fail(ctx, HL_ERR_MESH, "%s: no triangles", HL_SURR_ARRAY_NAME);
    hl_dyn_scene *scene = NULL;
    hl_result r = hl_dyn_scene_from_triangles(ctx, HL_SURR_ARRAY_NAME, HL_SURR_ARRAY_BODY, positions, triangle_count,
                                              &scene);
    if (r != HL_OK) return r;
    hl_surroundings *s = NULL;
    r = wrap_scene(ctx, scene, HL_SURR_ARRAY_NAME, &s);
    if (r != HL_OK) return r;
    memcpy(s->emission, emission, (size_t)triangle_count * 3 * sizeof(float));
    r = check_triangles(s, HL_SURR_ARRAY_NAME);
    if (r != HL_OK) {
        hl_surroundings_destroy(s);
        return r;
    }
    *out = s;
    return HL_OK;
}

/* ---------------------------------------------------------------- queries */

uint32_t hl_surroundings_triangle_count(const hl_surroundings *s) { return s ? s->ntris : 0; }

const char *hl_surroundings_name_(const hl_surroundings *s) { return s ? s->scene->name : "(no surroundings)"; }

uint32_t hl_surroundings_body_count(const hl_surroundings *s) { return s ? s->nbodies : 0; }

const char *hl_surroundings_body_name(const hl_surroundings *s, uint32_t body)
{
    return s ? hl_dyn_scene_body_name(s->scene, body) : NULL;
}

int hl_surroundings_body_emits(const hl_surroundings *s, uint32_t body)
{
    return s && body < s->nbodies ? s->emits[body] : 0;
}

void hl_surroundings_time_range(const hl_surroundings *s, double *start, double *end)
{
    if (start) *start = 0.0;
    if (end) *end = 0.0;
    if (s) hl_dyn_scene_animation(s->scene, start, end);
}

/* ---------------------------------------------------------------- motion */

hl_result hl_surroundings_set_time(hl_surroundings *s, double t)
{
    if (!s) return hl_fail(NULL, HL_ERR_INVALID_ARGUMENT, "hl_surroundings_set_time: no surroundings");
    if (!isfinite(t) || t < 0.0)
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "surroundings: time %g s is not a finite number >= 0", t);
    if (t != s->t) s->posed = 0;
    s->t = t;
    return HL_OK;
}

hl_result hl_surroundings_set_transform(hl_surroundings *s, uint32_t body, const float xf[12])
{
    if (!s || !xf) return hl_fail(s ? s->ctx : NULL, HL_ERR_INVALID_ARGUMENT, "hl_surroundings_set_transform: surroundings and xf are required");
    hl_result r = hl_dyn_scene_set_transform(s->scene, body, xf);
    if (r == HL_OK) s->posed = 0;
    return r;
}

hl_result hl_surroundings_set_placement(hl_surroundings *s, const float shift[3], float scale, float yaw_deg)
{
    if (!s || !shift)
        return hl_fail(s ? s->ctx : NULL, HL_ERR_INVALID_ARGUMENT, "hl_surroundings_set_placement: surroundings and shift are required");
    for (int i = 0; i < 3; i++)
        if (!isfinite(shift[i]))
            return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "surroundings placement: shift %g %g %g is not finite",
                           (double)shift[0], (double)shift[1], (double)shift[2]);
    if (!(isfinite(scale) && scale > 0.0f))
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "surroundings placement: scale %g must be a finite number > 0",
                       (double)scale);
    if (!isfinite(yaw_deg))
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "surroundings placement: turn %g degrees is not finite",
                       (double)yaw_deg);
    /* x' = shift + scale Ry(yaw) x, Ry turning +X towards -Z as bench's turns do */
    const double a = (double)yaw_deg * 3.14159265358979323846 / 180.0, c = cos(a) * scale, sn = sin(a) * scale;
    const double m[12] = {c, 0.0, sn, shift[0], 0.0, scale, 0.0, shift[1], -sn, 0.0, c, shift[2]};
    hl_result r = hl_dyn_scene_set_placement(s->scene, m);
    if (r == HL_OK) s->posed = 0;
    return r;
}

hl_result hl_surroundings_triangles(hl_surroundings *s, const float **positions, const float **emission)
{
    if (!s || !positions || !emission)
        return hl_fail(s ? s->ctx : NULL, HL_ERR_INVALID_ARGUMENT, "hl_surroundings_triangles: surroundings, positions and emission are required");
    if (!s->posed) {
        hl_result r = hl_dyn_scene_at(s->scene, s->t, s->objs);
        if (r != HL_OK) return r;
        float *w = s->world;
        for (uint32_t b = 0; b < s->nbodies; b++) {
            const hl_dyn_object *o = &s->objs[b];
            for (uint32_t v = 0; v < 3 * o->ntris; v++, w += 3) { /* keep_triangles: vertex v is corner v */
                const float *p = o->pos + 3 * (size_t)v;
                for (int i = 0; i < 3; i++) {
                    const float *x = o->xf + 4 * i;
                    w[i] = (float)((double)x[0] * p[0] + (double)x[1] * p[1] + (double)x[2] * p[2] + x[3]);
                }
            }
        }
        s->posed = 1;
    }
    *positions = s->world;
    *emission = s->emission;
    return HL_OK;
}
