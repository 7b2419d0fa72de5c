/* view_dynamic.c - `haarlight view --dynamic`: the viewer on the dynamic
 * method (hl_dynamic_*): its options, the scene (from a mesh or scene
 * file, or from a transport's mesh so that PRT can serve the frames where
 * nothing moved), the frames (a new one only when a body moved, the time
 * changed or the lights changed), the animation's clock, picking and
 * dragging bodies with the mouse, and the method's part of the HUD.
 *
 * Dependencies: GLFW 3 (the clock), the haarlight library ("dynamic
 * scenes" in haarlight.h), the CLI helpers (cli.h), gl_draw.c for the
 * uploads, view_util.c for rays.
 */
#define _POSIX_C_SOURCE 200809L
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "viewer.h"

/* The transport's mesh and the dynamic scene's must hold the same vertices
 * in the same order for PRT's colours and the dynamic method's to be
 * drawn on one vertex buffer: positions may differ by float rounding of
 * the scene's rest transforms, at most this share of the mesh's diagonal. */
#define VW_SAME_VERTEX_TOL 1e-5

static const float identity_xf[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

/* ---------------------------------------------------------------- options */

/* BODY:X,Y,Z, the name up to the last ':' (relight-dynamic's form). */
static int parse_move(const char *s, vw_dyn *y)
{
    const char *colon = strrchr(s, ':');
    if (!colon || colon == s || y->nmoves >= VW_MAX_MOVES) return 0;
    float t[3];
    if (!parse_vec3(colon + 1, t)) return 0;
    size_t n = (size_t)(colon - s);
    char *name = malloc(n + 1);
    if (!name) return 0;
    memcpy(name, s, n);
    name[n] = 0;
    y->move_name[y->nmoves] = name;
    memcpy(y->move[y->nmoves++], t, sizeof t);
    return 1;
}

static int parse_drag(const char *s, float d[4])
{
    char tail;
    if (sscanf(s, "%f,%f,%f,%f%c", &d[0], &d[1], &d[2], &d[3], &tail) != 4) return 0;
    for (int k = 0; k < 4; k++)
        if (!isfinite(d[k]) || d[k] < 0.0f) return 0;
    return 1;
}

int vw_dyn_opt(viewer *v, int argc, char **argv, int *i, const char *usage)
{
    vw_dyn *y = &v->dy;
    const char *a = argv[*i], *val = NULL;
    if (!strcmp(a, "--dynamic")) return y->on = 1;
    if (!strcmp(a, "--ground")) return y->ground = 1;
    if (!strcmp(a, "--rest-pose")) return y->rest_pose = 1;
    if (!strcmp(a, "--play")) return y->play = 1;
    static const char *const with_value[] = {"--hlt", "--lights", "--order", "--shadow-res", "--sharp-res", "--sharp", "--time",
                                             "--move", "--drag", "--shadow", NULL};
    int k = 0;
    while (with_value[k] && strcmp(a, with_value[k])) k++;
    if (!with_value[k]) return 0;
    if (*i + 1 >= argc) return -usage_error(usage, "option %s needs a value", a);
    val = argv[++*i];
    if (!strcmp(a, "--hlt")) {
        y->hlt = val;
    } else if (!strcmp(a, "--lights")) {
        if (!parse_u32(val, &y->lights) || y->lights < 1 || y->lights > INT32_MAX)
            return -usage_error(usage, "--lights %s: expected K >= 1", val);
    } else if (!strcmp(a, "--order")) {
        if (!parse_u32(val, &y->desc.order) || y->desc.order < 4 || y->desc.order > 16)
            return -usage_error(usage, "--order %s: expected 4 to 16", val);
    } else if (!strcmp(a, "--shadow")) {
        if (!strcmp(val, "moments")) y->desc.shadow = HL_DYNAMIC_SHADOW_MOMENTS;
        else if (!strcmp(val, "csm")) y->desc.shadow = HL_DYNAMIC_SHADOW_CSM;
        else return -usage_error(usage, "--shadow %s: expected csm or moments", val);
    } else if (!strcmp(a, "--shadow-res")) {
        uint32_t r = 0;
        if (!parse_u32(val, &r) || r < 16 || r > 1024 || r % 16)
            return -usage_error(usage, "--shadow-res %s: expected a multiple of 16 from 16 to 1024", val);
        y->desc.shadow_res = r;
    } else if (!strcmp(a, "--sharp")) {
        if (!parse_sharp(val, &y->desc.sharp)) return -usage_error(usage, "--sharp %s: expected rays, maps or off", val);
    } else if (!strcmp(a, "--sharp-res")) {
        uint32_t r = 0;
        if (!parse_u32(val, &r) || r < 16 || r > 1024 || r % 16)
            return -usage_error(usage, "--sharp-res %s: expected a multiple of 16 from 16 to 1024", val);
        y->desc.sharp_res = r;
    } else if (!strcmp(a, "--time")) {
        if (!parse_float(val, &y->time0) || !(y->time0 >= 0.0f) || !isfinite(y->time0))
            return -usage_error(usage, "--time %s: expected seconds, finite and >= 0", val);
    } else if (!strcmp(a, "--move")) {
        if (!parse_move(val, y)) return -usage_error(usage, "--move %s: expected BODY:X,Y,Z (at most 64 moves)", val);
    } else {
        if (!parse_drag(val, y->drag)) return -usage_error(usage, "--drag %s: expected X0,Y0,X1,Y1 (window pixels)", val);
        y->drag_set = 1;
    }
    return 1;
}

/* ---------------------------------------------------------------- loading */

static int ends_with(const char *s, const char *tail)
{
    size_t n = strlen(s), m = strlen(tail);
    return n >= m && !strcmp(s + n - m, tail);
}

/* Same vertices, same order, same triangles: else PRT and the dynamic
 * method cannot share the vertex buffer. Prints why not. */
static int same_mesh(const hl_mesh *a, const hl_mesh *b, const char *a_name, const char *b_name)
{
    if (a->vertex_count != b->vertex_count || a->triangle_count != b->triangle_count) {
        fprintf(stderr,
                "haarlight: %s has %u vertices and %u triangles but the dynamic scene of %s has %u and %u: the "
                "transport does not belong to that scene, so PRT cannot draw its frames at rest\n",
                a_name, a->vertex_count, a->triangle_count, b_name, b->vertex_count, b->triangle_count);
        return 0;
    }
    double tol = VW_SAME_VERTEX_TOL * hl_mesh_query_diagonal(a);
    for (uint32_t i = 0; i < a->vertex_count; i++)
        for (int k = 0; k < 3; k++) {
            double d = fabs((double)a->positions[3 * (size_t)i + k] - b->positions[3 * (size_t)i + k]);
            if (!(d <= tol)) {
                fprintf(stderr,
                        "haarlight: %s and the dynamic scene of %s differ at vertex %u (coordinate %d off by %g, "
                        "tolerance %g): their vertices are not the same or not in the same order, so PRT cannot "
                        "draw the dynamic scene's frames at rest\n",
                        a_name, b_name, i, k, d, tol);
                return 0;
            }
        }
    for (size_t i = 0; i < 3 * (size_t)a->triangle_count; i++)
        if (a->indices[i] != b->indices[i]) {
            fprintf(stderr, "haarlight: %s and the dynamic scene of %s differ at triangle %zu: not the same mesh\n",
                    a_name, b_name, i / 3);
            return 0;
        }
    return 1;
}

/* --move: the body by name (the first of that name, as hl_dynamic_move),
 * as a transform so that a drag can start from it. */
static int apply_moves(viewer *v)
{
    vw_dyn *y = &v->dy;
    for (uint32_t m = 0; m < y->nmoves; m++) {
        uint32_t b = 0;
        while (b < y->nb && strcmp(hl_dynamic_body_name(y->d, b), y->move_name[m])) b++;
        if (b == y->nb) { /* the library's message lists the bodies */
            hl_dynamic_move(y->d, y->move_name[m], y->move[m]);
            fprintf(stderr, "haarlight: --move: %s\n", hl_context_last_error(v->ctx));
            return 0;
        }
        float xf[12];
        memcpy(xf, identity_xf, sizeof xf);
        xf[3] = y->move[m][0], xf[7] = y->move[m][1], xf[11] = y->move[m][2];
        if (hl_dynamic_set_transform(y->d, b, xf) != HL_OK) {
            fprintf(stderr, "haarlight: --move: %s\n", hl_context_last_error(v->ctx));
            return 0;
        }
        memcpy(y->xf[b], xf, sizeof xf);
    }
    return 1;
}

static void count_moved(vw_dyn *y)
{
    y->moved = 0;
    for (uint32_t b = 0; b < y->nb; b++) y->moved += memcmp(y->xf[b], identity_xf, sizeof identity_xf) != 0;
}

int vw_dyn_load(viewer *v, int *rc)
{
    vw_dyn *y = &v->dy;
    *rc = 1;
    int scene_is_hlt = ends_with(v->scene, ".hlt");
    const char *hlt = scene_is_hlt ? v->scene : y->hlt;
    if (scene_is_hlt && y->hlt) {
        *rc = 2;
        fprintf(stderr, "haarlight: --hlt %s: SCENE %s is a transport already\n", y->hlt, v->scene);
        return 0;
    }
    if (scene_is_hlt && y->ground) {
        *rc = 2;
        fprintf(stderr, "haarlight: --ground: %s is a transport, whose mesh has its ground (or none) already\n",
                v->scene);
        return 0;
    }
    if (hlt && hl_transport_load(v->ctx, hlt, &v->t) != HL_OK) {
        cli_fail(v->ctx, HL_ERR_IO);
        return 0;
    }
    v->t_path = hlt;
    const int flags = (y->ground ? HL_DYNAMIC_GROUND : 0) | (y->rest_pose ? HL_DYNAMIC_REST_POSE : 0);
    hl_result r = scene_is_hlt ? hl_dynamic_create_from_mesh(v->ctx, v->t->mesh, 0, &y->desc, &y->d)
                               : hl_dynamic_create_from_file(v->ctx, v->scene, flags, &y->desc, &y->d);
    if (r != HL_OK) {
        cli_fail(v->ctx, r);
        return 0;
    }
    const hl_mesh *dm = hl_dynamic_mesh(y->d);
    if (v->t && !same_mesh(v->t->mesh, dm, hlt, v->scene)) return 0;
    y->nb = hl_dynamic_body_count(y->d);
    y->xf = malloc((size_t)y->nb * sizeof *y->xf);
    y->rgba = calloc(4 * (size_t)dm->vertex_count, sizeof *y->rgba);
    if (!y->xf || !y->rgba) {
        fprintf(stderr, "haarlight: out of memory for the dynamic scene (%u vertices)\n", dm->vertex_count);
        return 0;
    }
    for (uint32_t b = 0; b < y->nb; b++) memcpy(y->xf[b], identity_xf, sizeof identity_xf);
    if (!apply_moves(v)) {
        *rc = 2;
        return 0;
    }
    count_moved(y);
    hl_dynamic_time_range(y->d, &y->t_start, &y->t_end);
    y->time = y->time0;
    y->playing = y->play && y->t_end > y->t_start;
    if (y->play && !y->playing && !v->o.cd.quiet)
        fprintf(stderr, "view: %s has no animation: --play has nothing to play\n", v->scene);
    if (!y->lights) y->lights = VW_DYN_DEFAULT_LIGHTS;
    y->env_dirty = y->dirty = 1;
    v->mesh = v->t ? v->t->mesh : dm;
    return 1;
}

void vw_dyn_destroy(viewer *v)
{
    vw_dyn *y = &v->dy;
    hl_dynamic_destroy(y->d);
    y->d = NULL;
    free(y->xf);
    free(y->rgba);
    for (uint32_t m = 0; m < y->nmoves; m++) free(y->move_name[m]);
}

/* ---------------------------------------------------------------- frames */

static int animated(const vw_dyn *y) { return y->t_end > y->t_start; }

/* PRT draws the frame when there is a transport and the scene is as it was
 * precomputed: no body moved and the animation at time 0 (the pose the
 * vertex check saw). */
static int at_rest(const viewer *v)
{
    const vw_dyn *y = &v->dy;
    return v->t && y->moved == 0 && !(animated(y) && (y->playing || y->time != 0.0));
}

int vw_dyn_pending(const viewer *v)
{
    return v->dy.on && (v->dy.playing || v->dy.dirty);
}

static void advance_clock(vw_dyn *y)
{
    double now = glfwGetTime();
    if (y->playing) {
        y->time += now - y->play_clock;
        if (y->time > y->t_end) y->time = y->t_start + fmod(y->time - y->t_start, y->t_end - y->t_start);
        y->dirty = 1;
    }
    y->play_clock = now;
}

/* Back to PRT: the transport's positions and a relight. */
static void back_to_rest(viewer *v)
{
    v->dy.showing = 0;
    v->mesh = v->t->mesh;
    vw_gl_upload_positions(v->gl, v->mesh->positions);
    vw_mesh_bounds(v->mesh, v->centre, &v->radius);
    v->light_dirty = 1;
}

/* A dynamic frame; 0 on failure (said). */
static int render(viewer *v)
{
    vw_dyn *y = &v->dy;
    if (y->env_dirty) {
        y->env_dirty = 0;
        y->env_failed = hl_dynamic_set_env(y->d, v->envs[v->cur].env, (int32_t)y->lights, 0.0f, v->rd.rotate_deg,
                                           &y->li) != HL_OK;
        if (y->env_failed) vw_say(v, 1, "dynamic lights: %s", hl_context_last_error(v->ctx));
    }
    y->dirty = 0;
    if (y->env_failed) return 0;
    if (hl_dynamic_render(y->d, y->time, &y->rgb, &y->st) != HL_OK) {
        vw_say(v, 1, "dynamic frame: %s", hl_context_last_error(v->ctx));
        return 0;
    }
    return 1;
}

int vw_dyn_frame(viewer *v)
{
    vw_dyn *y = &v->dy;
    advance_clock(y);
    if (at_rest(v)) {
        y->dirty = 0;
        if (y->showing) back_to_rest(v);
        return 0;
    }
    v->light_dirty = 0; /* PRT's work waits until the scene is at rest again */
    if (!y->dirty && !y->env_dirty && y->showing) return 0;
    double t0 = glfwGetTime();
    if (!render(v)) {
        if (!y->ok && !v->t) v->failed = v->quit = 1; /* nothing to show at all */
        return 0;
    }
    y->ok = 1;
    double t1 = glfwGetTime();
    const hl_mesh *m = hl_dynamic_mesh(y->d);
    for (size_t i = 0; i < m->vertex_count; i++) {
        memcpy(y->rgba + 4 * i, y->rgb + 3 * i, 3 * sizeof *y->rgba);
        y->rgba[4 * i + 3] = 1.0f;
    }
    v->mesh = m;
    vw_gl_upload_positions(v->gl, m->positions);
    vw_gl_upload_colours(v->gl, y->rgba);
    vw_mesh_bounds(m, v->centre, &v->radius); /* a moved body may leave the old depth range */
    y->showing = 1;
    if (v->auto_requested) {
        v->auto_requested = 0;
        v->exposure = hl_exposure_auto(m, y->rgb);
    }
    v->t_relight = t1 - t0;
    v->t_upload = glfwGetTime() - t1;
    return 1;
}

int vw_dyn_toggle_play(viewer *v)
{
    vw_dyn *y = &v->dy;
    if (!y->on || !animated(y)) return 0;
    y->playing = !y->playing;
    y->play_clock = glfwGetTime();
    y->dirty = 1;
    return 1;
}

void vw_dyn_reset(viewer *v)
{
    vw_dyn *y = &v->dy;
    for (uint32_t b = 0; b < y->nb; b++) {
        memcpy(y->xf[b], identity_xf, sizeof identity_xf);
        hl_dynamic_set_transform(y->d, b, identity_xf); /* the identity cannot be refused */
    }
    y->moved = 0;
    y->time = y->time0;
    y->playing = 0;
    y->dirty = 1;
}

/* ---------------------------------------------------------------- dragging */

/* The body holding vertex i (bodies are contiguous, in order). */
static uint32_t body_of(const vw_dyn *y, uint32_t i)
{
    for (uint32_t b = 0; b < y->nb; b++) {
        uint32_t first = 0, count = 0;
        hl_dynamic_body_vertices(y->d, b, &first, &count);
        if (i >= first && i - first < count) return b;
    }
    return y->nb;
}

int vw_dyn_grab(viewer *v, double x, double y_px, double w, double h)
{
    vw_dyn *y = &v->dy;
    if (!y->on || !y->d) return 0;
    double o[3] = {v->view.eye[0], v->view.eye[1], v->view.eye[2]}, d[3];
    vw_pixel_ray(&v->view, x, y_px, w, h, d);
    /* the mesh drawn: the transport's at rest (same vertices, checked) */
    const hl_mesh *m = v->mesh;
    double best = INFINITY;
    uint32_t hit_tri = UINT32_MAX;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *ix = m->indices + 3 * (size_t)t;
        double s = vw_ray_triangle(o, d, m->positions + 3 * (size_t)ix[0], m->positions + 3 * (size_t)ix[1],
                                   m->positions + 3 * (size_t)ix[2]);
        if (s > 0.0 && s < best) best = s, hit_tri = t;
    }
    if (hit_tri == UINT32_MAX) return 0;
    uint32_t b = body_of(y, m->indices[3 * (size_t)hit_tri]);
    /* the ground is what bodies are dragged across, unless it is all there is */
    if (b >= y->nb || (y->nb > 1 && !strcmp(hl_dynamic_body_name(y->d, b), "ground"))) return 0;
    y->drag_body = b;
    memcpy(y->drag_xf, y->xf[b], sizeof y->drag_xf);
    for (int k = 0; k < 3; k++) y->grab[k] = (float)(o[k] + best * d[k]);
    v->drag = DRAG_BODY;
    vw_say(v, 0, "dragging \"%s\"", hl_dynamic_body_name(y->d, b));
    return 1;
}

void vw_dyn_drag(viewer *v, double x, double y_px, double w, double h)
{
    vw_dyn *y = &v->dy;
    double delta[3];
    if (!vw_drag_delta(&v->view, x, y_px, w, h, y->grab, VW_DRAG_MAX_RADII * v->radius, delta)) return;
    float xf[12];
    memcpy(xf, y->drag_xf, sizeof xf);
    xf[3] += (float)delta[0];
    xf[11] += (float)delta[2];
    if (hl_dynamic_set_transform(y->d, y->drag_body, xf) != HL_OK) {
        vw_say(v, 1, "drag: %s", hl_context_last_error(v->ctx));
        return;
    }
    memcpy(y->xf[y->drag_body], xf, sizeof xf);
    count_moved(y);
    y->dirty = 1;
}

int vw_dyn_start(viewer *v)
{
    vw_dyn *y = &v->dy;
    y->play_clock = glfwGetTime(); /* --play counts from the first frame, not from glfwInit */
    if (!y->drag_set || !y->on) return 1; /* without --dynamic, --drag is the surroundings' */
    if (!vw_input_drag(v, y->drag[0], y->drag[1], y->drag[2], y->drag[3])) {
        fprintf(stderr, "haarlight: --drag: no body under window point %g,%g (the ground is not dragged)\n",
                (double)y->drag[0], (double)y->drag[1]);
        return 0;
    }
    const float *xf = y->xf[y->drag_body];
    /* %.9g: the floats as set, so that relight-dynamic --move repeats them */
    fprintf(stderr, "view: dragged body \"%s\" to translation %.9g,%.9g,%.9g\n",
            hl_dynamic_body_name(y->d, y->drag_body), (double)xf[3], (double)xf[7], (double)xf[11]);
    return 1;
}

/* ---------------------------------------------------------------- HUD */

void vw_dyn_hud(const viewer *v, char *buf, size_t size)
{
    const vw_dyn *y = &v->dy;
    const hl_dynamic_stats *s = &y->st;
    int n;
    if (!y->showing)
        n = snprintf(buf, size, "PRT at rest: relight %.1f ms, M %u, energy %.3f%%", 1e3 * v->t_relight,
                     v->st.terms_kept, 100.0 * v->st.energy_kept);
    else if (s->reused)
        n = snprintf(buf, size, "dynamic: reused (nothing moved)");
    else {
        /* as hl_dynamic_create resolves it: an order alone asks for CSM */
        const char *rep = y->desc.shadow == HL_DYNAMIC_SHADOW_CSM ||
                                  (y->desc.shadow == HL_DYNAMIC_SHADOW_DEFAULT && y->desc.order)
                              ? "CSM"
                              : "moments";
        n = snprintf(buf, size,
                     "dynamic K %u: irradiance %.0f + shadow maps %.0f + %s build %.0f + %s eval %.0f + "
                     "shading %.0f = %.0f ms, %u shadow maps kept",
                     y->li.lights_kept, 1e3 * s->t_irradiance, 1e3 * s->t_shadow_maps, rep, 1e3 * s->t_csm_build, rep,
                     1e3 * s->t_csm_eval, 1e3 * s->t_shading, 1e3 * s->t_total, s->maps_kept);
    }
    if (n < 0 || (size_t)n >= size) return;
    if (animated(y))
        n += snprintf(buf + n, size - (size_t)n, ", t %.2f s of %.2f-%.2f %s", y->time, y->t_start, y->t_end,
                      y->playing ? "playing" : "paused");
    if (n >= 0 && (size_t)n < size && y->moved)
        snprintf(buf + n, size - (size_t)n, ", %u bod%s moved", y->moved, y->moved == 1 ? "y" : "ies");
}
