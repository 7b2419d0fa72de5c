/* view_surround.c - `haarlight view SCENE.hlt --surroundings FILE`: the
 * object lit by its surroundings as captured from its centre. The
 * relighter captures them at every run (hl_relighter_set_surroundings);
 * this file poses them (the file's animation at the viewer's clock, each
 * body's drag after it), tells the frame loop when they moved, finds
 * which body each triangle belongs to so that a mouse press can pick
 * one, builds their flat-shaded triangles for gl_draw.c, and gives the
 * HUD its lighting part: the capture + relight time, or "unchanged" when
 * a frame asked and the relighter found nothing to do (stats.reused).
 *
 * Dependencies: GLFW 3 (the clock), the haarlight library ("captured
 * lighting" in haarlight.h), the CLI helpers (cli_surroundings_load),
 * gl_draw.c for the upload, view_util.c for rays and drags.
 */
#define _POSIX_C_SOURCE 200809L
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "viewer.h"

/* Floats per drawn vertex: position, colour, display flag (gl_draw.c). */
#define VW_SUR_FLOATS 7
/* A dark triangle is drawn as a grey of this display value (linear, before
 * the sRGB curve: about code 63 of 255) under a fixed light from above,
 * with this share unlit, so that its faces read apart but it stays dimmer
 * than anything the lamp lights well; the exposure does not change it. */
#define VW_SUR_GREY 0.05f
#define VW_SUR_AMBIENT 0.45f
static const double sur_light[3] = {0.36, 0.80, 0.48}; /* unit: up, a little to +X and +Z */

static const float identity_xf[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

/* ---------------------------------------------------------------- loading */

/* Which body each triangle belongs to, through the public interface only:
 * move one body at a time and see which triangles move with it. */
static int find_bodies(viewer *v)
{
    vw_sur *u = &v->su;
    const float *pos = NULL, *em = NULL;
    size_t n9 = 9 * (size_t)u->nt;
    float *rest = malloc(n9 * sizeof *rest);
    if (!rest || hl_surroundings_triangles(u->s, &pos, &em) != HL_OK) {
        free(rest);
        return 0;
    }
    memcpy(rest, pos, n9 * sizeof *rest);
    float big = 0.0f; /* a step that moves every coordinate, however large */
    for (size_t i = 0; i < n9; i++) big = fmaxf(big, fabsf(rest[i]));
    float step = 1.0f + big * 0x1p-10f;
    for (uint32_t t = 0; t < u->nt; t++) u->body[t] = u->nb;
    int ok = 1;
    for (uint32_t b = 0; b < u->nb && ok; b++) {
        float xf[12];
        memcpy(xf, identity_xf, sizeof xf);
        xf[3] = xf[7] = xf[11] = step;
        ok = hl_surroundings_set_transform(u->s, b, xf) == HL_OK && hl_surroundings_triangles(u->s, &pos, &em) == HL_OK;
        for (uint32_t t = 0; ok && t < u->nt; t++)
            if (memcmp(pos + 9 * (size_t)t, rest + 9 * (size_t)t, 36)) u->body[t] = b;
        ok = hl_surroundings_set_transform(u->s, b, identity_xf) == HL_OK && ok;
    }
    free(rest);
    return ok;
}

int vw_sur_load(viewer *v)
{
    vw_sur *u = &v->su;
    hl_result r = cli_surroundings_load(v->ctx, &v->o, &u->s, v->o.cd.quiet);
    if (r != HL_OK) {
        cli_fail(v->ctx, r);
        return 0;
    }
    u->nb = hl_surroundings_body_count(u->s);
    u->nt = hl_surroundings_triangle_count(u->s);
    u->body = malloc((size_t)u->nt * sizeof *u->body);
    u->xf = malloc((size_t)u->nb * sizeof *u->xf);
    u->verts = malloc(3 * (size_t)u->nt * VW_SUR_FLOATS * sizeof *u->verts);
    if (!u->body || !u->xf || !u->verts) {
        fprintf(stderr, "haarlight: out of memory for %u triangles of surroundings\n", u->nt);
        return 0;
    }
    if (!find_bodies(v)) {
        fprintf(stderr, "haarlight: %s: %s\n", v->o.surroundings, hl_context_last_error(v->ctx));
        return 0;
    }
    for (uint32_t b = 0; b < u->nb; b++) memcpy(u->xf[b], identity_xf, sizeof identity_xf);
    hl_surroundings_time_range(u->s, &u->t_start, &u->t_end);
    u->time0 = u->time = v->o.time;
    u->playing = v->dy.play && u->t_end > u->t_start;
    if (v->dy.play && !u->playing && !v->o.cd.quiet)
        fprintf(stderr, "view: %s has no animation: --play has nothing to play\n", v->o.surroundings);
    u->show = u->dirty = 1;
    return 1;
}

int vw_sur_attach(viewer *v)
{
    if (!v->su.s) return 1;
    if (hl_relighter_set_surroundings(v->rl, v->su.s) == HL_OK &&
        (!v->o.probes_set || hl_relighter_set_probes(v->rl, v->o.probes, 0.0) == HL_OK))
        return 1;
    fprintf(stderr, "haarlight: %s: %s\n", v->o.surroundings, vw_rl_error(v));
    return 0;
}

void vw_sur_destroy(viewer *v)
{
    vw_sur *u = &v->su;
    hl_surroundings_destroy(u->s);
    u->s = NULL;
    free(u->body);
    free(u->xf);
    free(u->verts);
}

/* ---------------------------------------------------------------- frames */

static int animated(const vw_sur *u) { return u->t_end > u->t_start; }

/* The drawn triangles at the current pose, and the sphere that holds them
 * and the mesh (the depth range). */
static int upload(viewer *v)
{
    vw_sur *u = &v->su;
    const float *pos = NULL, *em = NULL;
    char err[512];
    if (hl_surroundings_triangles(u->s, &pos, &em) != HL_OK) {
        vw_say(v, 1, "surroundings: %s", hl_context_last_error(v->ctx));
        return 0;
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t t = 0; t < u->nt; t++) {
        const float *p = pos + 9 * (size_t)t, *e = em + 3 * (size_t)t;
        double e1[3], e2[3], n[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = (double)p[3 + k] - p[k];
            e2[k] = (double)p[6 + k] - p[k];
        }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        double lit = len > 0.0 ? fabs(n[0] * sur_light[0] + n[1] * sur_light[1] + n[2] * sur_light[2]) / len : 0.0;
        int emits = e[0] > 0.0f || e[1] > 0.0f || e[2] > 0.0f;
        float grey = (float)(VW_SUR_GREY * (VW_SUR_AMBIENT + (1.0 - VW_SUR_AMBIENT) * lit));
        for (int c = 0; c < 3; c++) {
            float *o = u->verts + (3 * (size_t)t + (size_t)c) * VW_SUR_FLOATS;
            for (int k = 0; k < 3; k++) {
                o[k] = p[3 * c + k];
                o[3 + k] = emits ? e[k] : grey;
                lo[k] = fmin(lo[k], o[k]);
                hi[k] = fmax(hi[k], o[k]);
            }
            o[6] = emits ? 0.0f : 1.0f;
        }
    }
    float c[3], r2 = 0.0f;
    for (int k = 0; k < 3; k++) {
        c[k] = (float)(0.5 * (lo[k] + hi[k]));
        r2 += (float)((hi[k] - lo[k]) * (hi[k] - lo[k]) * 0.25);
    }
    vw_sphere_union(v->centre, v->radius, c, sqrtf(r2), u->centre, &u->radius);
    if (!vw_gl_set_surroundings(v->gl, u->verts, 3 * u->nt, err, sizeof err)) {
        vw_say(v, 1, "surroundings: %s", err);
        return 0;
    }
    return 1;
}

void vw_sur_frame(viewer *v)
{
    vw_sur *u = &v->su;
    if (!u->s) return;
    u->work = u->unchanged = 0;
    double now = glfwGetTime();
    if (u->playing) {
        u->time += now - u->play_clock;
        if (u->time > u->t_end) u->time = u->t_start + fmod(u->time - u->t_start, u->t_end - u->t_start);
        u->dirty = 1;
    }
    u->play_clock = now;
    if (!u->dirty) return;
    u->dirty = 0;
    if (hl_surroundings_set_time(u->s, u->time) != HL_OK) {
        vw_say(v, 1, "surroundings: %s", hl_context_last_error(v->ctx));
        return;
    }
    upload(v);
    v->light_dirty = 1; /* the relighter itself finds whether the triangles changed */
}

void vw_sur_note(viewer *v, int ran, int reused, double seconds)
{
    vw_sur *u = &v->su;
    if (!u->s || !ran) return;
    if (reused) {
        u->unchanged = 1;
        u->n_unchanged++;
    } else {
        u->work = 1;
        u->n_work++;
        u->t_work += seconds;
    }
}

int vw_sur_pending(const viewer *v)
{
    return v->su.s && (v->su.playing || v->su.dirty);
}

int vw_sur_toggle_play(viewer *v)
{
    vw_sur *u = &v->su;
    if (!u->s || !animated(u)) return 0;
    u->playing = !u->playing;
    u->play_clock = glfwGetTime();
    u->dirty = 1;
    vw_say(v, 0, "surroundings %s at %.2f s", u->playing ? "playing" : "paused", u->time);
    return 1;
}

void vw_sur_reset(viewer *v)
{
    vw_sur *u = &v->su;
    if (!u->s) return;
    for (uint32_t b = 0; b < u->nb; b++) {
        memcpy(u->xf[b], identity_xf, sizeof identity_xf);
        hl_surroundings_set_transform(u->s, b, identity_xf); /* the identity cannot be refused */
    }
    u->moved = 0;
    u->time = u->time0;
    u->playing = 0;
    u->dirty = 1;
}

/* ---------------------------------------------------------------- dragging */

int vw_sur_grab(viewer *v, double x, double y, double w, double h)
{
    vw_sur *u = &v->su;
    const float *pos = NULL, *em = NULL;
    if (!u->s || !u->show || hl_surroundings_triangles(u->s, &pos, &em) != HL_OK) return 0;
    double o[3] = {v->view.eye[0], v->view.eye[1], v->view.eye[2]}, d[3];
    vw_pixel_ray(&v->view, x, y, w, h, d);
    double best = INFINITY;
    uint32_t hit = UINT32_MAX;
    for (uint32_t t = 0; t < u->nt; t++) {
        const float *p = pos + 9 * (size_t)t;
        double s = vw_ray_triangle(o, d, p, p + 3, p + 6);
        if (s > 0.0 && s < best) best = s, hit = t;
    }
    if (hit == UINT32_MAX || u->body[hit] >= u->nb) return 0;
    const hl_mesh *m = v->mesh; /* the object (or its ground) in front of it hides it */
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *ix = m->indices + 3 * (size_t)t;
        double s = vw_ray_triangle(o, d, m->positions + 3 * (size_t)ix[0], m->positions + 3 * (size_t)ix[1],
                                   m->positions + 3 * (size_t)ix[2]);
        if (s > 0.0 && s < best) return 0;
    }
    uint32_t b = u->body[hit];
    u->drag_body = b;
    memcpy(u->drag_xf, u->xf[b], sizeof u->drag_xf);
    for (int k = 0; k < 3; k++) u->grab[k] = (float)(o[k] + best * d[k]);
    v->drag = DRAG_SURR;
    vw_say(v, 0, "dragging \"%s\" of the surroundings", hl_surroundings_body_name(u->s, b));
    return 1;
}

void vw_sur_drag(viewer *v, double x, double y, double w, double h)
{
    vw_sur *u = &v->su;
    double delta[3];
    if (!vw_drag_delta(&v->view, x, y, w, h, u->grab, VW_DRAG_MAX_RADII * v->radius, delta)) return;
    float xf[12];
    memcpy(xf, u->drag_xf, sizeof xf);
    xf[3] += (float)delta[0];
    xf[11] += (float)delta[2];
    if (hl_surroundings_set_transform(u->s, u->drag_body, xf) != HL_OK) {
        vw_say(v, 1, "drag: %s", hl_context_last_error(v->ctx));
        return;
    }
    memcpy(u->xf[u->drag_body], xf, sizeof xf);
    u->moved = 0;
    for (uint32_t b = 0; b < u->nb; b++) u->moved += memcmp(u->xf[b], identity_xf, sizeof identity_xf) != 0;
    u->dirty = 1;
}

int vw_sur_start(viewer *v)
{
    vw_sur *u = &v->su;
    if (!u->s) return 1;
    u->play_clock = glfwGetTime(); /* --play counts from the first frame */
    if (!v->dy.drag_set) return 1;
    const float *g = v->dy.drag;
    if (!vw_input_drag(v, g[0], g[1], g[2], g[3])) {
        fprintf(stderr, "haarlight: --drag: no body of the surroundings under window point %g,%g (or the object "
                        "hides it)\n", (double)g[0], (double)g[1]);
        return 0;
    }
    const float *xf = u->xf[u->drag_body];
    fprintf(stderr, "view: dragged body \"%s\" of the surroundings to translation %.9g,%.9g,%.9g\n",
            hl_surroundings_body_name(u->s, u->drag_body), (double)xf[3], (double)xf[7], (double)xf[11]);
    return 1;
}

/* ---------------------------------------------------------------- HUD */

void vw_sur_hud(const viewer *v, char *buf, size_t size)
{
    const vw_sur *u = &v->su;
    int n;
    if (u->work)
        n = snprintf(buf, size, "capture + relight %.1f ms", 1e3 * v->t_relight);
    else
        n = snprintf(buf, size, "lighting: unchanged");
    if (n < 0 || (size_t)n >= size) return;
    if (animated(u))
        n += snprintf(buf + n, size - (size_t)n, ", t %.2f s of %.2f-%.2f %s", u->time, u->t_start, u->t_end,
                      u->playing ? "playing" : "paused");
    if (n >= 0 && (size_t)n < size && u->moved)
        n += snprintf(buf + n, size - (size_t)n, ", %u bod%s moved", u->moved, u->moved == 1 ? "y" : "ies");
    if (n >= 0 && (size_t)n < size && !u->show) snprintf(buf + n, size - (size_t)n, ", surroundings hidden");
}
