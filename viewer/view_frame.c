/* view_frame.c - the viewer's frames: the pending lighting work (a new
 * sky, a new environment, a relight fed to OpenGL), the camera, the frame
 * loop with its timings, screenshots, and the messages and HUD (the
 * window title).
 *
 * Dependencies: GLFW 3 (time, events, the window's title and buffers),
 * the haarlight library and haarlight_tools.h (the relighter's colours
 * left on the host or written into OpenGL's buffer), gl_draw.c.
 */
#define _POSIX_C_SOURCE 200809L
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "haarlight_tools.h"
#include "viewer.h"

/* ---------------------------------------------------------------- messages */

/* The last error of the relighter's context. */
const char *vw_rl_error(const viewer *v) { return hl_context_last_error(v->gctx ? v->gctx : v->ctx); }

void vw_say(viewer *v, int error, const char *fmt, ...)
{
    char line[sizeof v->msg];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    /* a drag repeats its complaint on every mouse move: print it once */
    int repeat = !strcmp(line, v->msg) && glfwGetTime() < v->msg_until;
    memcpy(v->msg, line, sizeof line);
    if (!repeat && (error || !v->o.cd.quiet)) fprintf(stderr, "%s%s\n", error ? "haarlight: " : "", v->msg);
    v->msg_until = glfwGetTime() + VW_MESSAGE_SECONDS;
    v->redraw = 1;
}

/* The HUD of --dynamic: the method in use and its times. */
static void dynamic_title(viewer *v, char *title, size_t size)
{
    char method[400];
    vw_dyn_hud(v, method, sizeof method);
    snprintf(title, size, "%.0f fps | %s | upload %.2f ms, draw %.1f ms | EV %+.1f | glare %s | env %d/%d %s, rot %.0f | %s",
             v->fps, method, 1e3 * v->t_upload, 1e3 * v->t_draw, (double)v->exposure, v->glare ? "on" : "off",
             v->cur + 1, v->n_envs, v->envs[v->cur].label, (double)v->rd.rotate_deg, hl_context_device_name(v->ctx));
}

void vw_update_title(viewer *v)
{
    char *title = v->hud, terms[80];
    size_t size = sizeof v->hud;
    int tn;
    if (v->rd.terms == HL_TERMS_ALL) tn = snprintf(terms, sizeof terms, "all (%u)", v->st.terms_kept);
    else tn = snprintf(terms, sizeof terms, "%u", v->st.terms_kept);
    /* colours written on the device are not read back, so not counted */
    if (v->st.negative_counted && v->st.negative_vertices && tn > 0 && (size_t)tn < sizeof terms)
        snprintf(terms + tn, sizeof terms - (size_t)tn, ", %u clamped below 0", v->st.negative_vertices);
    int n = 0;
    if (v->msg[0] && glfwGetTime() < v->msg_until) n = snprintf(title, size, "%s | ", v->msg);
    if (n < 0 || (size_t)n >= size) n = 0;
    char lighting[300]; /* with surroundings: the capture's part */
    if (v->su.s) vw_sur_hud(v, lighting, sizeof lighting);
    else snprintf(lighting, sizeof lighting, "relight %.1f ms", 1e3 * v->t_relight);
    if (v->dy.on)
        dynamic_title(v, title + n, size - (size_t)n);
    else
        snprintf(title + n, size - (size_t)n,
                 "%.0f fps | %s, upload %.2f ms, draw %.1f ms | M %s, energy %.3f%% | EV %+.1f | glare %s | "
                 "env %d/%d %s, rot %.0f | %s | %s",
                 v->fps, lighting, 1e3 * v->t_upload, 1e3 * v->t_draw, terms, 100.0 * v->st.energy_kept,
                 (double)v->exposure, v->glare ? "on" : "off", v->cur + 1, v->n_envs, v->envs[v->cur].label,
                 (double)v->rd.rotate_deg, hl_context_device_name(v->ctx), v->feed);
    glfwSetWindowTitle(v->win, title);
}

/* ---------------------------------------------------------------- lighting */

/* Gives up CL/GL interop (setup failed, or a relight into the GL buffer
 * did) and says why; the colours are read back from then on. */
void vw_interop_off(viewer *v, const char *why)
{
    snprintf(v->feed, sizeof v->feed, "readback (GL interop failed: %.100s)", why);
    vw_say(v, 1, "%s", v->feed);
    hl_view_gl_colours_destroy(v->glmem);
    v->glmem = NULL;
}

/* The environment of slot i to the relighter; the black slot of
 * --surroundings alone is not given until another map was, so that the
 * relighter lights with them alone, as relight does. */
static int relighter_env(viewer *v, int i)
{
    if (!v->rl || (i == v->black_slot && !v->rl_env_set)) return 1;
    if (hl_relighter_set_env(v->rl, v->envs[i].env) != HL_OK) return 0;
    v->rl_env_set = 1;
    return 1;
}

/* The pending lighting work: a new sky, a new environment, a relight. */
static void update_lighting(viewer *v)
{
    char err[512];
    v->t_relight = v->t_upload = 0.0;
    if (v->sky_dirty) {
        v->sky_dirty = 0;
        hl_env *sky = NULL;
        if (vw_make_sky(v, &sky) != HL_OK) {
            vw_say(v, 1, "%s", hl_context_last_error(v->ctx));
        } else {
            env_slot *s = &v->envs[v->sky_slot];
            hl_env_destroy(s->env);
            s->env = sky;
            vw_sky_label(v, s);
            if (v->cur == v->sky_slot) v->env_dirty = 1;
        }
    }
    if (v->env_dirty) {
        v->env_dirty = 0;
        const hl_env *env = v->envs[v->cur].env;
        /* the texture first: it fails before the relighter is touched */
        int gl_ok = vw_gl_set_env(v->gl, env, err, sizeof err);
        int cl_ok = gl_ok && relighter_env(v, v->cur);
        if (gl_ok && !cl_ok) snprintf(err, sizeof err, "%s", vw_rl_error(v));
        if (!cl_ok) {
            vw_say(v, 1, "%s: %s (keeping the current lighting)", v->envs[v->cur].label, err);
            if (v->loaded < 0) {
                v->failed = v->quit = 1;
                return;
            }
            v->cur = v->loaded;
            vw_gl_set_env(v->gl, v->envs[v->cur].env, err, sizeof err);
            if (gl_ok && relighter_env(v, v->cur)) v->light_dirty = 1;
        } else {
            v->loaded = v->cur;
            v->light_dirty = 1;
        }
        v->dy.env_dirty = 1;
    }
    /* --dynamic: its frame, or PRT's below when the scene is at rest */
    if (v->dy.on && (vw_dyn_frame(v) || v->dy.showing || !v->t)) {
        v->light_dirty = 0;
        return;
    }
    vw_sur_frame(v); /* surroundings moved: light_dirty */
    if (v->light_dirty) {
        v->light_dirty = 0;
        double t0 = glfwGetTime();
        hl_relight_stats st;
        const float *rgba = NULL;
        int on_device = 0;
        if (v->glmem) {
            vw_gl_finish(); /* OpenGL is done with the buffer before OpenCL acquires it */
            if (hl_view_run_gl(v->rl, &v->rd, v->glmem, &st) == HL_OK) on_device = 1;
            else vw_interop_off(v, vw_rl_error(v));
        }
        if (!on_device && hl_view_run4(v->rl, &v->rd, &rgba, &st) != HL_OK) {
            vw_say(v, 1, "relight: %s", vw_rl_error(v));
            return;
        }
        double t1 = glfwGetTime();
        vw_sur_note(v, 1, st.reused, t1 - t0);
        v->st = st;
        if (v->auto_requested) {
            v->auto_requested = 0;
            vw_auto_exposure(v);
        }
        if (st.reused) return; /* nothing changed: the colours drawn are these already */
        if (on_device) vw_gl_colours_written(v->gl);
        else vw_gl_upload_colours(v->gl, rgba);
        v->t_relight = t1 - t0;
        v->t_upload = glfwGetTime() - t1;
    }
}

/* ---------------------------------------------------------------- camera */

/* The camera for the current eye and target through hl_render's own
 * camera code; a camera it refuses leaves the previous one. */
int vw_update_camera(viewer *v, int automatic)
{
    hl_camera_desc d = v->o.cam;
    d.width = v->fb_w;
    d.height = v->fb_h;
    if (!automatic) { /* automatic: the options' eye and target, or the framing of hl_render */
        memcpy(d.eye, v->eye, sizeof d.eye);
        memcpy(d.target, v->target, sizeof d.target);
    }
    hl_camera_view cv;
    if (hl_camera_query_view(v->ctx, v->mesh, &d, &cv) != HL_OK) {
        vw_say(v, 1, "%s", hl_context_last_error(v->ctx));
        memcpy(v->eye, v->view.eye, sizeof v->eye);
        return 0;
    }
    v->view = cv;
    memcpy(v->eye, cv.eye, sizeof v->eye);
    memcpy(v->target, cv.target, sizeof v->target);
    return 1;
}

/* ---------------------------------------------------------------- capture */

/* Writes the frame just drawn through the project's image writer; in
 * headless runs also compares the window's tone-mapped pixels with
 * hl_tonemap_srgb8 of the linear frame. */
static int capture(viewer *v, const vw_frame *f, const char *path, int check_display)
{
    char err[512];
    hl_image *img = NULL;
    uint8_t *disp = NULL;
    size_t n = 3 * (size_t)v->fb_w * v->fb_h;
    if (hl_image_create(v->ctx, v->fb_w, v->fb_h, &img) != HL_OK) {
        vw_say(v, 1, "%s: %s", path, hl_context_last_error(v->ctx));
        return 0;
    }
    if (check_display && !(disp = malloc(n))) check_display = 0;
    int ok = vw_gl_read(v->gl, f, img->rgb, disp, err, sizeof err);
    if (!ok) vw_say(v, 1, "%s: %s", path, err);
    if (ok && disp) {
        size_t differ = 0;
        int worst = 0;
        for (size_t i = 0; i < n; i++) {
            int d = abs((int)disp[i] - (int)hl_tonemap_srgb8(img->rgb[i], v->exposure));
            differ += d != 0;
            worst = d > worst ? d : worst;
        }
        if (!v->o.cd.quiet)
            fprintf(stderr, "display check: %zu of %zu tone-mapped values on screen differ from hl_tonemap_srgb8 "
                            "of the linear frame (largest difference %d codes)\n", differ, n, worst);
    }
    if (ok && hl_image_save(v->ctx, img, path, v->exposure) != HL_OK) {
        vw_say(v, 1, "%s", hl_context_last_error(v->ctx));
        ok = 0;
    }
    if (ok) vw_say(v, 0, "wrote %s (%u x %u, EV %+.2f)", path, v->fb_w, v->fb_h, (double)v->exposure);
    free(disp);
    hl_image_destroy(img);
    return ok;
}

/* ---------------------------------------------------------------- frame loop */

static void add_times(time_sums *s, const viewer *v, double frame)
{
    s->relight += v->t_relight;
    s->upload += v->t_upload;
    s->draw += v->t_draw;
    s->present += v->t_present;
    s->frame += frame;
    s->n++;
}

void vw_print_times(const viewer *v)
{
    if (v->o.cd.quiet || v->first_frame == 0.0) return;
    const time_sums *a = &v->all, *l = &v->lit;
    fprintf(stderr,
            "view: %llu frames at %u x %u, %u vertices, %u triangles; device %s; colours by %s; OpenGL: %s\n"
            "  first frame %.1f ms (shader compilation, first uploads; not in the means)\n",
            (unsigned long long)a->n + 1, v->fb_w, v->fb_h, v->mesh->vertex_count, v->mesh->triangle_count,
            hl_context_device_name(v->ctx), v->feed, vw_gl_renderer(v->gl), 1e3 * v->first_frame);
    if (l->n)
        fprintf(stderr,
                "  %llu frames with a lighting change, mean: relight %.2f ms + upload %.2f ms + draw %.2f ms + "
                "present %.2f ms = frame %.2f ms (%.1f fps)\n",
                (unsigned long long)l->n, 1e3 * l->relight / (double)l->n, 1e3 * l->upload / (double)l->n,
                1e3 * l->draw / (double)l->n, 1e3 * l->present / (double)l->n, 1e3 * l->frame / (double)l->n,
                (double)l->n / l->frame);
    if (v->su.s)
        fprintf(stderr,
                "  surroundings: %llu captures with relight (mean %.2f ms); %llu frames found them and the map "
                "unchanged (lighting: unchanged, no capture, no relight)\n",
                (unsigned long long)v->su.n_work, v->su.n_work ? 1e3 * v->su.t_work / (double)v->su.n_work : 0.0,
                (unsigned long long)v->su.n_unchanged);
    fprintf(stderr, "  last HUD: %s\n", v->hud);
    uint64_t k = a->n - l->n;
    if (k)
        fprintf(stderr, "  %llu frames without one (redraw only), mean: draw %.2f ms + present %.2f ms = frame %.2f ms\n",
                (unsigned long long)k, 1e3 * (a->draw - l->draw) / (double)k,
                1e3 * (a->present - l->present) / (double)k, 1e3 * (a->frame - l->frame) / (double)k);
}

static int pending(const viewer *v)
{
    return v->sky_dirty || v->env_dirty || v->light_dirty || v->camera_dirty || v->resized || v->redraw ||
           v->shot_requested || v->auto_requested || v->spinning || vw_dyn_pending(v) || vw_sur_pending(v);
}

int vw_run_loop(viewer *v)
{
    char err[512];
    int headless = v->frames_limit > 0, rc = 0;
    uint32_t frame = 0;
    for (;;) {
        if (headless || pending(v)) glfwPollEvents();
        else glfwWaitEventsTimeout(0.25); /* wakes to notice Ctrl-C and messages running out */
        if (v->quit || glfwWindowShouldClose(v->win) || hl_context_cancelled(v->ctx)) break;
        if (!headless && !pending(v)) {
            if (v->msg[0] && glfwGetTime() >= v->msg_until) {
                v->msg[0] = '\0';
                vw_update_title(v);
            }
            continue;
        }
        double t_start = glfwGetTime();
        if (v->spinning) vw_rotate_env(v, v->spin_deg);
        if (v->resized) {
            v->resized = 0;
            if (!vw_gl_resize(v->gl, v->fb_w, v->fb_h, err, sizeof err)) {
                fprintf(stderr, "haarlight: %s\n", err);
                return 1;
            }
            v->camera_dirty = 1;
        }
        if (v->camera_dirty) {
            vw_update_camera(v, v->camera_dirty == 2);
            v->camera_dirty = 0;
        }
        update_lighting(v);
        if (v->failed) return 1;
        int lit = v->t_relight > 0.0;
        vw_frame f;
        /* the depth range holds the surroundings too, when they are drawn */
    if (v->su.s) vw_camera_matrix(&v->view, v->su.centre, v->su.radius, f.mvp);
    else vw_camera_matrix(&v->view, v->centre, v->radius, f.mvp);
        f.view = v->view;
        f.rotate_deg = v->rd.rotate_deg;
        f.exposure_ev = v->exposure;
        f.glare = v->glare;
    f.surroundings = v->su.s && v->su.show;
        double t0 = glfwGetTime();
        vw_gl_draw(v->gl, &f);
        double t1 = glfwGetTime();
        v->t_draw = t1 - t0;
        v->redraw = 0;
        if (headless && frame + 1 == v->frames_limit && v->shot_path && !capture(v, &f, v->shot_path, 1)) rc = 1;
        if (v->shot_requested) {
            char name[64];
            vw_screenshot_name(name, sizeof name);
            capture(v, &f, name, 0);
            v->shot_requested = 0;
        }
        double t2 = glfwGetTime();
        glfwSwapBuffers(v->win);
        double t3 = glfwGetTime();
        v->t_present = t3 - t2;
        /* frames per second over busy stretches; an idle gap restarts it */
        double gap = t3 - v->last_frame_end;
        if (v->last_frame_end > 0.0 && gap < 0.5) v->fps = v->fps > 0.0 ? 0.9 * v->fps + 0.1 / gap : 1.0 / gap;
        v->last_frame_end = t3;
        double work = (t1 - t_start) + v->t_present;
        if (v->first_frame == 0.0) v->first_frame = work; /* shader compilation, first uploads: kept apart */
        else {
            add_times(&v->all, v, work);
            if (lit) add_times(&v->lit, v, work);
        }
        vw_update_title(v);
        if (v->keys) {
            vw_input_type(v, v->keys);
            v->keys = NULL;
        }
        if (headless && ++frame >= v->frames_limit) break;
    }
    if (hl_context_cancelled(v->ctx)) {
        fprintf(stderr, "haarlight: interrupted\n");
        return 130;
    }
    if (headless && frame < v->frames_limit) {
        fprintf(stderr, "haarlight: the window was closed after %u of %u frames%s%s\n", frame, v->frames_limit,
                v->shot_path ? "; not written: " : "", v->shot_path ? v->shot_path : "");
        return 1;
    }
    return rc;
}
