/* view_input.c - what the keys, the mouse and dropped files do to the
 * viewer: the environment list (the built-in sky's slot, loaded and
 * dropped maps), turning the environment, moving the sun, changing M and
 * the exposure, the orbit and zoom of the camera, and (--dynamic,
 * --surroundings) the animation and dragging bodies (view_dynamic.c,
 * view_surround.c). The work itself
 * waits for the next frame (view_frame.c): input only marks it.
 *
 * Dependencies: GLFW 3 (callbacks, key codes), the haarlight library.
 */
#define _POSIX_C_SOURCE 200809L
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <math.h>
#include <stdio.h>

#include "viewer.h"

/* ---------------------------------------------------------------- environments */

void vw_sky_label(viewer *v, env_slot *s)
{
    snprintf(s->label, sizeof s->label, "built-in sky (sun %.0f deg up, azimuth %.0f deg)", (double)v->sun_el,
             (double)v->sun_az);
}

int vw_add_env(viewer *v, hl_env *env, const char *label)
{
    if (v->n_envs == VW_MAX_ENVS) {
        hl_env_destroy(env);
        return -1;
    }
    env_slot *s = &v->envs[v->n_envs];
    s->env = env;
    snprintf(s->label, sizeof s->label, "%s", label);
    return v->n_envs++;
}

static void choose_env(viewer *v, int i)
{
    if (i >= v->n_envs) {
        vw_say(v, 0, "no environment %d: %d loaded", i + 1, v->n_envs);
        return;
    }
    if (i == v->cur) return;
    v->cur = i;
    v->env_dirty = 1;
    if (v->exposure_auto) v->auto_requested = 1;
}

/* Loads a dropped (or --drop) file; an unreadable one leaves the lighting
 * as it was. */
void vw_drop_file(viewer *v, const char *path)
{
    hl_env *env = NULL;
    hl_env_stats es;
    if (hl_env_load_layout(v->ctx, path, v->o.layout, &env, &es) != HL_OK) {
        vw_say(v, 1, "%s (keeping the current lighting)", hl_context_last_error(v->ctx));
        return;
    }
    int i = vw_add_env(v, env, vw_base_name(path));
    if (i < 0) {
        vw_say(v, 1, "%s: already %d environments loaded", path, VW_MAX_ENVS);
        return;
    }
    vw_say(v, 0, "loaded %s as environment %d (%llu NaN/Inf pixels set to 0, %llu negative ones clamped)", path, i + 1,
        (unsigned long long)es.nonfinite_pixels, (unsigned long long)es.negative_pixels);
    choose_env(v, i);
}

static void move_sun(viewer *v, float d_el, float d_az)
{
    if (v->sky_slot < 0) {
        vw_say(v, 0, "the sun belongs to the built-in sky: start with --sky");
        return;
    }
    if (v->cur != v->sky_slot) {
        vw_say(v, 0, "the sun belongs to the built-in sky: press %d first", v->sky_slot + 1);
        return;
    }
    v->sun_el = fmaxf(-90.0f, fminf(90.0f, v->sun_el + d_el));
    v->sun_az = fmodf(v->sun_az + d_az, 360.0f);
    v->sky_dirty = 1;
}

hl_result vw_make_sky(viewer *v, hl_env **out)
{
    hl_sky_desc d = v->o.sky;
    d.sun_elevation_deg = v->sun_el == 0.0f ? 1e-3f : v->sun_el; /* 0 would mean the default */
    d.sun_azimuth_deg = v->sun_az;
    return hl_env_create_sky(v->ctx, &d, out);
}

void vw_rotate_env(viewer *v, float deg)
{
    v->rd.rotate_deg = fmodf(v->rd.rotate_deg + deg, 360.0f);
    v->light_dirty = 1;
    v->dy.env_dirty = 1; /* the dynamic method splits the turned map again */
    v->dy.dirty |= v->dy.showing;
}

static void change_terms(viewer *v, int up)
{
    if (!v->t) {
        vw_say(v, 0, "M is PRT's: this scene has no transport (--hlt)");
        return;
    }
    uint32_t all = 2u * v->t->info.N * v->t->info.N, m = v->rd.terms;
    if (up) m = m == HL_TERMS_ALL || m >= all / 2 ? HL_TERMS_ALL : 2 * m;
    else m = m == HL_TERMS_ALL ? all / 2 : m > 1 ? m / 2 : 1;
    if (m != v->rd.terms) {
        v->rd.terms = m;
        v->light_dirty = 1;
    }
}

/* Automatic exposure from the current colours, brought to the host (no
 * new relight where they are there already: same settings, read back). */
void vw_auto_exposure(viewer *v)
{
    if (v->dy.showing) { /* the dynamic method's colours are on the host */
        v->exposure = hl_exposure_auto(v->mesh, v->dy.rgb);
        return;
    }
    if (!v->rl) return; /* no colours yet: the first frame sets it */
    if (hl_relighter_run(v->rl, &v->rd, v->rgb, NULL) == HL_OK) v->exposure = hl_exposure_auto(v->t->mesh, v->rgb);
    else vw_say(v, 1, "automatic exposure: %s", vw_rl_error(v));
}

/* ---------------------------------------------------------------- input */

static viewer *of(GLFWwindow *w)
{
    return glfwGetWindowUserPointer(w);
}

static void on_char(GLFWwindow *w, unsigned int c)
{
    viewer *v = of(w);
    switch (c) {
    case '+': case '=': change_terms(v, 1); break;
    case '-': case '_': change_terms(v, 0); break;
    case ']': v->exposure += VW_EXPOSURE_STEP; v->exposure_auto = 0; v->redraw = 1; break;
    case '[': v->exposure -= VW_EXPOSURE_STEP; v->exposure_auto = 0; v->redraw = 1; break;
    case 'a': case 'A':
        v->exposure_auto = 1;
        vw_auto_exposure(v);
        v->redraw = 1;
        break;
    case 'g': case 'G': v->glare = !v->glare; v->redraw = 1; break;
    case 'p': case 'P': v->shot_requested = 1; v->redraw = 1; break;
    case 'r': case 'R': v->camera_dirty = 2; break;
    case 'b': case 'B':
        if (v->dy.on) vw_dyn_reset(v);
        else vw_sur_reset(v);
        break;
    case 's': case 'S':
        if (v->su.s) {
            v->su.show = !v->su.show;
            v->redraw = 1;
        }
        break;
    case ' ':
        if (!vw_dyn_toggle_play(v) && !vw_sur_toggle_play(v)) v->spinning = !v->spinning;
        v->redraw = 1;
        break;
    case 'h': case 'H': case '?': fputs(VW_KEYS, stdout); fflush(stdout); break;
    case 'q': case 'Q': v->quit = 1; break;
    default:
        if (c >= '1' && c <= '9') choose_env(v, (int)(c - '1'));
        break;
    }
}

static void on_key(GLFWwindow *w, int key, int scancode, int action, int mods)
{
    (void)scancode;
    (void)mods;
    viewer *v = of(w);
    if (action == GLFW_RELEASE) return;
    switch (key) {
    case GLFW_KEY_ESCAPE: v->quit = 1; break;
    case GLFW_KEY_LEFT: vw_rotate_env(v, -VW_ENV_KEY_DEG); break;
    case GLFW_KEY_RIGHT: vw_rotate_env(v, VW_ENV_KEY_DEG); break;
    case GLFW_KEY_UP: move_sun(v, VW_SUN_KEY_ELEVATION, 0.0f); break;
    case GLFW_KEY_DOWN: move_sun(v, -VW_SUN_KEY_ELEVATION, 0.0f); break;
    case GLFW_KEY_PAGE_UP: move_sun(v, 0.0f, VW_SUN_KEY_AZIMUTH); break;
    case GLFW_KEY_PAGE_DOWN: move_sun(v, 0.0f, -VW_SUN_KEY_AZIMUTH); break;
    default: break;
    }
}

static void on_button(GLFWwindow *w, int button, int action, int mods)
{
    viewer *v = of(w);
    if (action == GLFW_RELEASE) {
        v->drag = DRAG_NONE;
        return;
    }
    glfwGetCursorPos(w, &v->last_x, &v->last_y);
    if (button == GLFW_MOUSE_BUTTON_RIGHT || (button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_SHIFT)))
        v->drag = DRAG_ENV;
    else if (button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_CONTROL)) v->drag = DRAG_SUN;
    else if (button == GLFW_MOUSE_BUTTON_LEFT) {
        int ww = 0, wh = 0; /* cursor positions are in window coordinates */
        glfwGetWindowSize(w, &ww, &wh);
        if (!(ww > 0 && wh > 0 &&
              (vw_dyn_grab(v, v->last_x, v->last_y, ww, wh) || vw_sur_grab(v, v->last_x, v->last_y, ww, wh))))
            v->drag = DRAG_ORBIT;
    }
}

static void on_cursor(GLFWwindow *w, double x, double y)
{
    viewer *v = of(w);
    double dx = x - v->last_x, dy = y - v->last_y;
    v->last_x = x;
    v->last_y = y;
    switch (v->drag) {
    case DRAG_ORBIT:
        vw_orbit(v->eye, v->target, v->up, -dx * VW_ORBIT_RAD_PER_PIXEL, -dy * VW_ORBIT_RAD_PER_PIXEL);
        v->camera_dirty = 1;
        break;
    case DRAG_ENV: vw_rotate_env(v, (float)(dx * VW_DRAG_DEG_PER_PIXEL)); break;
    case DRAG_SUN: move_sun(v, (float)(-dy * VW_DRAG_DEG_PER_PIXEL), (float)(dx * VW_DRAG_DEG_PER_PIXEL)); break;
    case DRAG_BODY:
    case DRAG_SURR: {
        int ww = 0, wh = 0;
        glfwGetWindowSize(w, &ww, &wh);
        if (ww > 0 && wh > 0 && v->drag == DRAG_BODY) vw_dyn_drag(v, x, y, ww, wh);
        else if (ww > 0 && wh > 0) vw_sur_drag(v, x, y, ww, wh);
        break;
    }
    default: break;
    }
}

static void on_scroll(GLFWwindow *w, double xoff, double yoff)
{
    (void)xoff;
    viewer *v = of(w);
    vw_zoom(v->eye, v->target, pow(VW_ZOOM_PER_NOTCH, yoff), 1e-3 * v->radius);
    v->camera_dirty = 1;
}

static void on_drop(GLFWwindow *w, int count, const char **paths)
{
    for (int i = 0; i < count; i++) vw_drop_file(of(w), paths[i]);
}

static void on_resize(GLFWwindow *w, int width, int height)
{
    viewer *v = of(w);
    if (width < 1 || height < 1) return; /* minimised */
    v->fb_w = (uint32_t)width;
    v->fb_h = (uint32_t)height;
    v->resized = 1;
}

static void on_refresh(GLFWwindow *w)
{
    of(w)->redraw = 1;
}


void vw_input_type(viewer *v, const char *keys)
{
    for (const char *c = keys; *c; c++) on_char(v->win, (unsigned char)*c);
}

int vw_input_drag(viewer *v, double x0, double y0, double x1, double y1)
{
    glfwSetCursorPos(v->win, x0, y0); /* the press reads where the cursor is */
    on_button(v->win, GLFW_MOUSE_BUTTON_LEFT, GLFW_PRESS, 0);
    int grabbed = v->drag == DRAG_BODY || v->drag == DRAG_SURR;
    if (grabbed) on_cursor(v->win, x1, y1);
    on_button(v->win, GLFW_MOUSE_BUTTON_LEFT, GLFW_RELEASE, 0);
    return grabbed;
}

void vw_input_attach(struct GLFWwindow *w)
{
    glfwSetCharCallback(w, on_char);
    glfwSetKeyCallback(w, on_key);
    glfwSetMouseButtonCallback(w, on_button);
    glfwSetCursorPosCallback(w, on_cursor);
    glfwSetScrollCallback(w, on_scroll);
    glfwSetDropCallback(w, on_drop);
    glfwSetFramebufferSizeCallback(w, on_resize);
    glfwSetWindowRefreshCallback(w, on_refresh);
}
