/* view.c - `haarlight view`: interactive relighting in a GLFW window.
 *
 * Every lighting change (environment, its rotation, the sun of the
 * built-in sky, the number of terms M) runs the relighter - the lighting
 * stages and the sparse dot products on the context's device - and feeds
 * the vertex colours to OpenGL; a camera move or an exposure change only
 * redraws, and with nothing to do the loop sleeps in glfwWaitEvents.
 * Rendering is in gl_draw.c, the helpers in view_util.c; this file holds
 * the options, the window, the input, the frame loop and the HUD (the
 * window title).
 *
 * Dependencies: GLFW 3 (the only file that sees it), the haarlight
 * library, the CLI helpers (cli.h).
 */
#define _POSIX_C_SOURCE 200809L
#define GLFW_INCLUDE_NONE
#define GLFW_EXPOSE_NATIVE_X11
#define GLFW_EXPOSE_NATIVE_GLX
#include <GLFW/glfw3.h>
#include <GLFW/glfw3native.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_backend.h"
#include "cli.h"
#include "hl_internal.h"
#include "lighting.h"
#include "viewer.h"

#define VW_KEYS                                                                              \
    "keys and mouse:\n"                                                                      \
    "  left drag              orbit the camera about its target\n"                           \
    "  scroll                 zoom\n"                                                        \
    "  right drag, shift + left drag   turn the environment about +Y\n"                      \
    "  ctrl + left drag       move the sun of the built-in sky (azimuth, elevation)\n"        \
    "  left / right           turn the environment by -/+ 10 degrees\n"                      \
    "  up / down              sun elevation +/- 5 degrees (built-in sky)\n"                   \
    "  page up / page down    sun azimuth +/- 15 degrees (built-in sky)\n"                    \
    "  + / -                  double / halve M, the lighting terms kept (up to all)\n"        \
    "  ] / [                  exposure +/- 0.5 EV\n"                                          \
    "  a                      automatic exposure (as relight's)\n"                            \
    "  g                      glare on / off\n"                                               \
    "  1 .. 9                 environment 1 .. 9 (command-line order, then dropped files)\n"  \
    "  drop an .exr file      load it as the next environment and show it\n"                  \
    "  space                  spin the environment (a lighting change every frame)\n"         \
    "  p                      screenshot: haarlight-view-NNN.png in the current folder\n"     \
    "  r                      reset the camera\n"                                             \
    "  h                      print this list\n"                                              \
    "  q, escape              quit\n"

static const char *const usage_view =
    "usage: haarlight view SCENE.hlt [--env ENV.exr ...] [--sky] [options]\n"
    "\n"
    "Opens a window on a transport file from `haarlight precompute` and relights it\n"
    "interactively. Every lighting change runs the lighting stages and the dot\n"
    "products on the device; a camera or exposure change only redraws, and an\n"
    "unchanged scene does no work. The window title is the HUD: frame rate, time of\n"
    "the relight, the upload and the draw, M, the lighting energy kept, the device\n"
    "and how the colours reach OpenGL.\n"
    "\n"
    "lighting:\n"
    "  --env ENV.exr        an equirectangular OpenEXR; repeat for more (keys 1..9)\n"
    "  --sky                the built-in sun and sky (the default without --env)\n"
    CLI_USAGE_SKY
    CLI_USAGE_LIGHTING
    "display:\n"
    "  --exposure EV        scale by 2^EV before the sRGB curve (default: automatic,\n"
    "                       as relight's: the 90th percentile of vertex luminance to 0.8)\n"
    "  --no-glare           start with the glare filter off\n"
    "  --readback           read the colours back to the host even where the device\n"
    "                       could write them into OpenGL's buffer (cl_khr_gl_sharing)\n"
    CLI_USAGE_CAMERA
    "capture (headless):\n"
    "  --frames N           draw N frames, print the timings and exit\n"
    "  --screenshot PATH    with --frames (default 1): write the last frame, .png\n"
    "                       (tone-mapped like relight's PNG) or .exr (linear)\n"
    "  --spin DEG           turn the environment by DEG every frame (a lighting change\n"
    "                       every frame, for timing)\n"
    "  --drop ENV.exr       treat ENV.exr as dropped on the window (for tests)\n"
    "running:\n"
    CLI_USAGE_RUNNING
    "\n" VW_KEYS;

#define VW_MAX_ENVS 64
#define VW_MAX_DROPS 8
/* hl_sky_desc's default sun elevation, for the keys that move it. */
#define VW_SUN_DEFAULT_ELEVATION 35.0f
#define VW_DEFAULT_TERMS 200u
#define VW_MESSAGE_SECONDS 6.0
/* Mouse and key steps. */
#define VW_ORBIT_RAD_PER_PIXEL 0.006
#define VW_DRAG_DEG_PER_PIXEL 0.3
#define VW_ZOOM_PER_NOTCH 0.9
#define VW_ENV_KEY_DEG 10.0f
#define VW_SUN_KEY_ELEVATION 5.0f
#define VW_SUN_KEY_AZIMUTH 15.0f
#define VW_EXPOSURE_STEP 0.5f

typedef struct env_slot {
    char label[128];
    hl_env *env;
} env_slot;

/* Sums of per-frame times in seconds, for the averages printed at exit. */
typedef struct time_sums {
    double relight, upload, draw, present, frame;
    uint64_t n;
} time_sums;

enum { DRAG_NONE, DRAG_ORBIT, DRAG_ENV, DRAG_SUN };

typedef struct viewer {
    cli_scene_opts o;
    const char *scene, *shot_path;
    const char *drops[VW_MAX_DROPS];
    int n_drops;
    uint32_t frames_limit;
    float spin_deg;

    hl_context *ctx;
    hl_transport *t;
    hl_relighter *rl;
    hl_context *gctx;  /* shares buffers with the window's GL context (interop);
                          the relighter lives on it when set, else on ctx */
    void *glmem;       /* the GL colour buffer as an OpenCL buffer (interop) */
    int interop, readback_asked;
    float *rgb;
    env_slot envs[VW_MAX_ENVS];
    int n_envs, cur, loaded, sky_slot;
    float sun_el, sun_az;
    hl_relight_desc rd;
    hl_relight_stats st;
    float exposure;
    int exposure_auto, glare, spinning;
    char feed[160];

    float eye[3], target[3], up[3];
    hl_camera_view view;
    float centre[3], radius;

    GLFWwindow *win;
    vw_gl *gl;
    uint32_t fb_w, fb_h;
    int drag;
    double last_x, last_y;

    /* work waiting for the next frame */
    int sky_dirty, env_dirty, light_dirty, camera_dirty, resized, redraw, shot_requested, auto_requested, quit;
    int failed; /* the first environment could not be set: nothing to show */

    char msg[512];
    double msg_until;
    double fps, last_frame_end, first_frame;
    double t_relight, t_upload, t_draw, t_present;
    time_sums all, lit;
} viewer;

/* ---------------------------------------------------------------- messages */

static void interop_off(viewer *v, const char *why);

/* The last error of the relighter's context. */
static const char *rl_error(const viewer *v) { return hl_context_last_error(v->gctx ? v->gctx : v->ctx); }

/* A line in the HUD for a while, and on stderr (errors always, the rest
 * unless quiet). */
static void say(viewer *v, int error, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static void say(viewer *v, int error, const char *fmt, ...)
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

static const char *base_name(const char *path)
{
    const char *s = strrchr(path, '/');
    return s ? s + 1 : path;
}

static void sky_label(viewer *v, env_slot *s)
{
    snprintf(s->label, sizeof s->label, "built-in sky (sun %.0f deg up, azimuth %.0f deg)", (double)v->sun_el,
             (double)v->sun_az);
}

static void update_title(viewer *v)
{
    char title[1024], terms[80];
    int tn;
    if (v->rd.terms == HL_TERMS_ALL) tn = snprintf(terms, sizeof terms, "all (%u)", v->st.terms_kept);
    else tn = snprintf(terms, sizeof terms, "%u", v->st.terms_kept);
    /* colours written on the device are not read back, so not counted */
    if (v->st.negative_counted && v->st.negative_vertices && tn > 0 && (size_t)tn < sizeof terms)
        snprintf(terms + tn, sizeof terms - (size_t)tn, ", %u clamped below 0", v->st.negative_vertices);
    int n = 0;
    if (v->msg[0] && glfwGetTime() < v->msg_until) n = snprintf(title, sizeof title, "%s | ", v->msg);
    snprintf(title + n, sizeof title - (size_t)n,
             "%.0f fps | relight %.1f ms, upload %.2f ms, draw %.1f ms | M %s, energy %.3f%% | EV %+.1f | glare %s | "
             "env %d/%d %s, rot %.0f | %s | %s",
             v->fps, 1e3 * v->t_relight, 1e3 * v->t_upload, 1e3 * v->t_draw, terms, 100.0 * v->st.energy_kept,
             (double)v->exposure, v->glare ? "on" : "off", v->cur + 1, v->n_envs, v->envs[v->cur].label,
             (double)v->rd.rotate_deg, hl_context_device_name(v->ctx), v->feed);
    glfwSetWindowTitle(v->win, title);
}

/* ---------------------------------------------------------------- lighting */

static int add_env(viewer *v, hl_env *env, const char *label)
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
        say(v, 0, "no environment %d: %d loaded", i + 1, v->n_envs);
        return;
    }
    if (i == v->cur) return;
    v->cur = i;
    v->env_dirty = 1;
    if (v->exposure_auto) v->auto_requested = 1;
}

/* Loads a dropped (or --drop) file; an unreadable one leaves the lighting
 * as it was. */
static void drop_file(viewer *v, const char *path)
{
    hl_env *env = NULL;
    hl_env_stats es;
    if (hl_env_load(v->ctx, path, &env, &es) != HL_OK) {
        say(v, 1, "%s (keeping the current lighting)", hl_context_last_error(v->ctx));
        return;
    }
    int i = add_env(v, env, base_name(path));
    if (i < 0) {
        say(v, 1, "%s: already %d environments loaded", path, VW_MAX_ENVS);
        return;
    }
    say(v, 0, "loaded %s as environment %d (%llu NaN/Inf pixels set to 0, %llu negative ones clamped)", path, i + 1,
        (unsigned long long)es.nonfinite_pixels, (unsigned long long)es.negative_pixels);
    choose_env(v, i);
}

static void move_sun(viewer *v, float d_el, float d_az)
{
    if (v->sky_slot < 0) {
        say(v, 0, "the sun belongs to the built-in sky: start with --sky");
        return;
    }
    if (v->cur != v->sky_slot) {
        say(v, 0, "the sun belongs to the built-in sky: press %d first", v->sky_slot + 1);
        return;
    }
    v->sun_el = fmaxf(-90.0f, fminf(90.0f, v->sun_el + d_el));
    v->sun_az = fmodf(v->sun_az + d_az, 360.0f);
    v->sky_dirty = 1;
}

static hl_result make_sky(viewer *v, hl_env **out)
{
    hl_sky_desc d = v->o.sky;
    d.sun_elevation_deg = v->sun_el == 0.0f ? 1e-3f : v->sun_el; /* 0 would mean the default */
    d.sun_azimuth_deg = v->sun_az;
    return hl_env_create_sky(v->ctx, &d, out);
}

static void rotate_env(viewer *v, float deg)
{
    v->rd.rotate_deg = fmodf(v->rd.rotate_deg + deg, 360.0f);
    v->light_dirty = 1;
}

static void change_terms(viewer *v, int up)
{
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
static void auto_exposure(viewer *v)
{
    if (hl_relighter_run(v->rl, &v->rd, v->rgb, NULL) == HL_OK) v->exposure = hl_exposure_auto(v->t->mesh, v->rgb);
    else say(v, 1, "automatic exposure: %s", rl_error(v));
}

/* The pending lighting work: a new sky, a new environment, a relight. */
static void update_lighting(viewer *v)
{
    char err[512];
    v->t_relight = v->t_upload = 0.0;
    if (v->sky_dirty) {
        v->sky_dirty = 0;
        hl_env *sky = NULL;
        if (make_sky(v, &sky) != HL_OK) {
            say(v, 1, "%s", hl_context_last_error(v->ctx));
        } else {
            env_slot *s = &v->envs[v->sky_slot];
            hl_env_destroy(s->env);
            s->env = sky;
            sky_label(v, s);
            if (v->cur == v->sky_slot) v->env_dirty = 1;
        }
    }
    if (v->env_dirty) {
        v->env_dirty = 0;
        const hl_env *env = v->envs[v->cur].env;
        /* the texture first: it fails before the relighter is touched */
        int gl_ok = vw_gl_set_env(v->gl, env, err, sizeof err);
        int cl_ok = gl_ok && hl_relighter_set_env(v->rl, env) == HL_OK;
        if (gl_ok && !cl_ok) snprintf(err, sizeof err, "%s", rl_error(v));
        if (!cl_ok) {
            say(v, 1, "%s: %s (keeping the current lighting)", v->envs[v->cur].label, err);
            if (v->loaded < 0) {
                v->failed = v->quit = 1;
                return;
            }
            v->cur = v->loaded;
            vw_gl_set_env(v->gl, v->envs[v->cur].env, err, sizeof err);
            if (gl_ok && hl_relighter_set_env(v->rl, v->envs[v->cur].env) == HL_OK) v->light_dirty = 1;
        } else {
            v->loaded = v->cur;
            v->light_dirty = 1;
        }
    }
    if (v->light_dirty) {
        v->light_dirty = 0;
        double t0 = glfwGetTime();
        hl_relight_stats st;
        const float *rgba = NULL;
        int on_device = 0;
        if (v->glmem) {
            vw_gl_finish(); /* OpenGL is done with the buffer before OpenCL acquires it */
            if (hl_relighter_run_into(v->rl, &v->rd, v->glmem, 1, &st) == HL_OK) on_device = 1;
            else interop_off(v, rl_error(v));
        }
        if (!on_device && hl_relighter_run4(v->rl, &v->rd, &rgba, &st) != HL_OK) {
            say(v, 1, "relight: %s", rl_error(v));
            return;
        }
        double t1 = glfwGetTime();
        v->st = st;
        if (v->auto_requested) {
            v->auto_requested = 0;
            auto_exposure(v);
        }
        if (on_device) vw_gl_colours_written(v->gl);
        else vw_gl_upload_colours(v->gl, rgba);
        v->t_relight = t1 - t0;
        v->t_upload = glfwGetTime() - t1;
    }
}

/* ---------------------------------------------------------------- camera */

/* The camera for the current eye and target through hl_render's own
 * camera code; a camera it refuses leaves the previous one. */
static int update_camera(viewer *v, int automatic)
{
    hl_camera_desc d = v->o.cam;
    d.width = v->fb_w;
    d.height = v->fb_h;
    if (!automatic) { /* automatic: the options' eye and target, or the framing of hl_render */
        memcpy(d.eye, v->eye, sizeof d.eye);
        memcpy(d.target, v->target, sizeof d.target);
    }
    hl_camera_view cv;
    if (hl_camera_query_view(v->ctx, v->t->mesh, &d, &cv) != HL_OK) {
        say(v, 1, "%s", hl_context_last_error(v->ctx));
        memcpy(v->eye, v->view.eye, sizeof v->eye);
        return 0;
    }
    v->view = cv;
    memcpy(v->eye, cv.eye, sizeof v->eye);
    memcpy(v->target, cv.target, sizeof v->target);
    return 1;
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
        auto_exposure(v);
        v->redraw = 1;
        break;
    case 'g': case 'G': v->glare = !v->glare; v->redraw = 1; break;
    case 'p': case 'P': v->shot_requested = 1; v->redraw = 1; break;
    case 'r': case 'R': v->camera_dirty = 2; break;
    case ' ': v->spinning = !v->spinning; v->redraw = 1; break;
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
    case GLFW_KEY_LEFT: rotate_env(v, -VW_ENV_KEY_DEG); break;
    case GLFW_KEY_RIGHT: rotate_env(v, VW_ENV_KEY_DEG); break;
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
    else if (button == GLFW_MOUSE_BUTTON_LEFT) v->drag = DRAG_ORBIT;
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
    case DRAG_ENV: rotate_env(v, (float)(dx * VW_DRAG_DEG_PER_PIXEL)); break;
    case DRAG_SUN: move_sun(v, (float)(-dy * VW_DRAG_DEG_PER_PIXEL), (float)(dx * VW_DRAG_DEG_PER_PIXEL)); break;
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
    for (int i = 0; i < count; i++) drop_file(of(w), paths[i]);
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

static void on_glfw_error(int code, const char *what)
{
    fprintf(stderr, "haarlight: GLFW error 0x%x: %s\n", (unsigned)code, what);
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
        say(v, 1, "%s: %s", path, hl_context_last_error(v->ctx));
        return 0;
    }
    if (check_display && !(disp = malloc(n))) check_display = 0;
    int ok = vw_gl_read(v->gl, f, img->rgb, disp, err, sizeof err);
    if (!ok) say(v, 1, "%s: %s", path, err);
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
        say(v, 1, "%s", hl_context_last_error(v->ctx));
        ok = 0;
    }
    if (ok) say(v, 0, "wrote %s (%u x %u, EV %+.2f)", path, v->fb_w, v->fb_h, (double)v->exposure);
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

static void print_times(const viewer *v)
{
    if (v->o.cd.quiet || v->first_frame == 0.0) return;
    const time_sums *a = &v->all, *l = &v->lit;
    fprintf(stderr,
            "view: %llu frames at %u x %u, %u vertices, %u triangles; device %s; colours by %s; OpenGL: %s\n"
            "  first frame %.1f ms (shader compilation, first uploads; not in the means)\n",
            (unsigned long long)a->n + 1, v->fb_w, v->fb_h, v->t->mesh->vertex_count, v->t->mesh->triangle_count,
            hl_context_device_name(v->ctx), v->feed, vw_gl_renderer(v->gl), 1e3 * v->first_frame);
    if (l->n)
        fprintf(stderr,
                "  %llu frames with a lighting change, mean: relight %.2f ms + upload %.2f ms + draw %.2f ms + "
                "present %.2f ms = frame %.2f ms (%.1f fps)\n",
                (unsigned long long)l->n, 1e3 * l->relight / (double)l->n, 1e3 * l->upload / (double)l->n,
                1e3 * l->draw / (double)l->n, 1e3 * l->present / (double)l->n, 1e3 * l->frame / (double)l->n,
                (double)l->n / l->frame);
    uint64_t k = a->n - l->n;
    if (k)
        fprintf(stderr, "  %llu frames without one (redraw only), mean: draw %.2f ms + present %.2f ms = frame %.2f ms\n",
                (unsigned long long)k, 1e3 * (a->draw - l->draw) / (double)k,
                1e3 * (a->present - l->present) / (double)k, 1e3 * (a->frame - l->frame) / (double)k);
}

static int pending(const viewer *v)
{
    return v->sky_dirty || v->env_dirty || v->light_dirty || v->camera_dirty || v->resized || v->redraw ||
           v->shot_requested || v->auto_requested || v->spinning;
}

static int run_loop(viewer *v)
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
                update_title(v);
            }
            continue;
        }
        double t_start = glfwGetTime();
        if (v->spinning) rotate_env(v, v->spin_deg);
        if (v->resized) {
            v->resized = 0;
            if (!vw_gl_resize(v->gl, v->fb_w, v->fb_h, err, sizeof err)) {
                fprintf(stderr, "haarlight: %s\n", err);
                return 1;
            }
            v->camera_dirty = 1;
        }
        if (v->camera_dirty) {
            update_camera(v, v->camera_dirty == 2);
            v->camera_dirty = 0;
        }
        update_lighting(v);
        if (v->failed) return 1;
        int lit = v->t_relight > 0.0;
        vw_frame f;
        vw_camera_matrix(&v->view, v->centre, v->radius, f.mvp);
        f.view = v->view;
        f.rotate_deg = v->rd.rotate_deg;
        f.exposure_ev = v->exposure;
        f.glare = v->glare;
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
        update_title(v);
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

/* ---------------------------------------------------------------- setup */

static int open_window(viewer *v)
{
    char err[512];
    glfwSetErrorCallback(on_glfw_error);
    if (!glfwInit()) {
        fprintf(stderr, "haarlight: cannot open a window: GLFW found no display (is DISPLAY set? under no X "
                        "server, try xvfb-run -a)\n");
        return 0;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_DEPTH_BITS, 0); /* depth lives in the float render target */
    glfwWindowHint(GLFW_SRGB_CAPABLE, GLFW_FALSE);
    int w = v->o.cam.width ? (int)v->o.cam.width : 960, h = v->o.cam.height ? (int)v->o.cam.height : 720;
    v->win = glfwCreateWindow(w, h, "haarlight view", NULL, NULL);
    if (!v->win) {
        fprintf(stderr, "haarlight: cannot create a window with an OpenGL 3.3 core context\n");
        return 0;
    }
    glfwMakeContextCurrent(v->win);
    glfwSwapInterval(v->frames_limit ? 0 : 1);
    glfwSetWindowUserPointer(v->win, v);
    int fw = 0, fh = 0;
    glfwGetFramebufferSize(v->win, &fw, &fh);
    v->fb_w = (uint32_t)(fw > 0 ? fw : 1);
    v->fb_h = (uint32_t)(fh > 0 ? fh : 1);
    if ((v->o.cam.width && v->fb_w != v->o.cam.width) || (v->o.cam.height && v->fb_h != v->o.cam.height))
        fprintf(stderr, "haarlight: the window's framebuffer is %u x %u, not the %u x %u asked for\n", v->fb_w,
                v->fb_h, v->o.cam.width, v->o.cam.height);
    float thr[256];
    vw_tonemap_thresholds(thr);
    if (!vw_gl_create(v->t->mesh, thr, &v->gl, err, sizeof err) ||
        !vw_gl_resize(v->gl, v->fb_w, v->fb_h, err, sizeof err)) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 0;
    }
    glfwSetCharCallback(v->win, on_char);
    glfwSetKeyCallback(v->win, on_key);
    glfwSetMouseButtonCallback(v->win, on_button);
    glfwSetCursorPosCallback(v->win, on_cursor);
    glfwSetScrollCallback(v->win, on_scroll);
    glfwSetDropCallback(v->win, on_drop);
    glfwSetFramebufferSizeCallback(v->win, on_resize);
    glfwSetWindowRefreshCallback(v->win, on_refresh);
    return 1;
}

/* Options; returns -1 to go on, else the exit code. */
static int parse(viewer *v, int argc, char **argv, const char **env_args, int *n_env_args)
{
    const char *usage = usage_view;
    cli_scene_opts_init(&v->o);
    *n_env_args = 0;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        int k = cli_scene_opt(argc, argv, &i, usage, &v->o);
        if (k < 0) return -k;
        if (k) continue;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            fputs(usage, stdout);
            return 0;
        }
        if (!strcmp(a, "--sky")) {
            if (*n_env_args == VW_MAX_ENVS) return usage_error(usage, "%s", "too many environments");
            env_args[(*n_env_args)++] = NULL; /* NULL: the sky, in its place in the list */
            continue;
        }
        if (!strcmp(a, "--no-glare")) {
            v->glare = 0;
            continue;
        }
        if (!strcmp(a, "--readback")) {
            v->readback_asked = 1;
            continue;
        }
        int takes = !strcmp(a, "--env") || !strcmp(a, "--frames") || !strcmp(a, "--screenshot") ||
                    !strcmp(a, "--spin") || !strcmp(a, "--drop");
        if (takes && i + 1 >= argc) return usage_error(usage, "option %s needs a value", a);
        const char *val = takes ? argv[++i] : NULL;
        if (!strcmp(a, "--env")) {
            if (*n_env_args == VW_MAX_ENVS) return usage_error(usage, "%s", "too many environments");
            env_args[(*n_env_args)++] = val;
        } else if (!strcmp(a, "--frames")) {
            if (!parse_u32(val, &v->frames_limit) || v->frames_limit < 1 || v->frames_limit > 1000000)
                return usage_error(usage, "--frames %s: expected 1 to 1000000", val);
        } else if (!strcmp(a, "--screenshot")) {
            size_t n = strlen(val);
            if (n < 5 || (strcmp(val + n - 4, ".png") && strcmp(val + n - 4, ".exr")))
                return usage_error(usage, "--screenshot %s: expected a .png or .exr name", val);
            v->shot_path = val;
        } else if (!strcmp(a, "--spin")) {
            if (!parse_float(val, &v->spin_deg) || fabsf(v->spin_deg) > 360.0f)
                return usage_error(usage, "--spin %s: expected -360 to 360 degrees per frame", val);
            v->spinning = v->spin_deg != 0.0f;
        } else if (!strcmp(a, "--drop")) {
            if (v->n_drops == VW_MAX_DROPS) return usage_error(usage, "%s", "too many --drop files");
            v->drops[v->n_drops++] = val;
        } else if (a[0] == '-' && a[1]) {
            return usage_error(usage, "unknown option %s", a);
        } else if (!v->scene) {
            v->scene = a;
        } else {
            return usage_error(usage, "unexpected argument %s", a);
        }
    }
    if (!v->scene) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (v->shot_path && !v->frames_limit) v->frames_limit = 1;
    if (v->o.sky_set || *n_env_args == 0) {
        int have = 0;
        for (int i = 0; i < *n_env_args; i++) have |= env_args[i] == NULL;
        if (!have) env_args[(*n_env_args)++] = NULL;
    }
    return -1;
}

/* The relighter on the first context, its colours read back; prints the
 * error and returns 0 on failure. */
static int readback_relighter(viewer *v)
{
    hl_result r = hl_relighter_create(v->ctx, v->t, &v->rl);
    if (r != HL_OK) cli_fail(v->ctx, r);
    return r == HL_OK;
}

/* Context, transport, environments, relighter: everything that can fail
 * on bad input, before any window opens. */
static int load(viewer *v, const char **env_args, int n_env_args)
{
    char err[4096];
    if (hl_context_create(&v->o.cd, &v->ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 0;
    }
    cli_watch(v->ctx, NULL); /* Ctrl-C cancels it: the loop polls it */
    if (hl_transport_load(v->ctx, v->scene, &v->t) != HL_OK) {
        cli_fail(v->ctx, HL_ERR_IO);
        return 0;
    }
    hl_camera_view cv; /* an impossible camera fails here, before any window */
    if (cli_camera_complete(v->ctx, v->t->mesh, &v->o) != HL_OK ||
        hl_camera_query_view(v->ctx, v->t->mesh, &v->o.cam, &cv) != HL_OK) {
        cli_fail(v->ctx, HL_ERR_INVALID_ARGUMENT);
        return 0;
    }
    v->sun_el = v->o.sky.sun_elevation_deg != 0.0f ? v->o.sky.sun_elevation_deg : VW_SUN_DEFAULT_ELEVATION;
    v->sun_az = v->o.sky.sun_azimuth_deg;
    v->sky_slot = -1;
    for (int i = 0; i < n_env_args; i++) {
        hl_env *env = NULL;
        hl_result r = env_args[i] ? cli_env_load(v->ctx, env_args[i], &env, 0) : make_sky(v, &env);
        if (r != HL_OK) {
            cli_fail(v->ctx, r);
            return 0;
        }
        int k = add_env(v, env, env_args[i] ? base_name(env_args[i]) : "");
        if (!env_args[i]) {
            v->sky_slot = k;
            sky_label(v, &v->envs[k]);
        }
    }
    v->rgb = calloc(3 * (size_t)v->t->info.vertex_count, sizeof *v->rgb); /* zero until the first relight */
    if (!v->rgb) {
        fprintf(stderr, "haarlight: out of memory for %u vertex colours\n", v->t->info.vertex_count);
        return 0;
    }
    v->interop = vw_feed_mode(v->ctx, v->readback_asked, v->feed, sizeof v->feed);
    if (v->interop) return 1; /* the relighter waits for the window's GL context (setup_interop) */
    return readback_relighter(v);
}

/* Gives up CL/GL interop (setup failed, or a relight into the GL buffer
 * did) and says why; the colours are read back from then on. */
static void interop_off(viewer *v, const char *why)
{
    snprintf(v->feed, sizeof v->feed, "readback (GL interop failed: %.100s)", why);
    say(v, 1, "%s", v->feed);
    hl_cl_mem_release(v->glmem);
    v->glmem = NULL;
}

/* With a device that lists cl_khr_gl_sharing: a second context on the same
 * device that shares the window's GLX context, the relighter on it, and
 * the GL colour buffer wrapped for the dot products to write. On any
 * failure the relighter is made on the first context and the colours are
 * read back. Needs the window's context current. */
static int setup_interop(viewer *v)
{
    if (!v->interop) return 1;
    char why[4096] = "";
    void *glx = (void *)glfwGetGLXContext(v->win), *dpy = (void *)glfwGetX11Display();
    if (!glx || !dpy) {
        snprintf(why, sizeof why, "the window's OpenGL context is not a GLX context");
    } else {
        intptr_t props[5];
        hl_cl_glx_properties(glx, dpy, props);
        hl_context_desc cd = v->o.cd;
        cd.cl_properties = props;
        if (hl_context_create(&cd, &v->gctx, why, sizeof why) == HL_OK) {
            if (hl_relighter_create(v->gctx, v->t, &v->rl) != HL_OK ||
                hl_cl_gl_buffer(v->gctx, vw_gl_colour_buffer(v->gl), &v->glmem) != HL_OK)
                snprintf(why, sizeof why, "%s", hl_context_last_error(v->gctx));
        }
    }
    if (!why[0]) return 1;
    interop_off(v, why);
    hl_relighter_destroy(v->rl);
    v->rl = NULL;
    hl_context_destroy(v->gctx);
    v->gctx = NULL;
    return readback_relighter(v);
}

int cmd_view(int argc, char **argv)
{
    viewer *v = calloc(1, sizeof *v);
    const char **env_args = calloc(VW_MAX_ENVS + 1, sizeof *env_args);
    if (!v || !env_args) {
        free(v);
        fprintf(stderr, "haarlight: out of memory\n");
        return 1;
    }
    v->glare = 1;
    v->spin_deg = 1.0f; /* the space key's step until --spin says otherwise */
    int n_env_args = 0, rc = parse(v, argc, argv, env_args, &n_env_args);
    if (rc < 0) rc = load(v, env_args, n_env_args) ? -1 : 1;
    if (rc < 0) rc = open_window(v) ? -1 : 3;
    if (rc < 0) rc = setup_interop(v) ? -1 : 1;
    if (rc < 0) {
        v->rd = v->o.rd;
        if (v->rd.terms == 0) v->rd.terms = VW_DEFAULT_TERMS;
        v->exposure = v->o.exposure;
        v->exposure_auto = !v->o.exposure_set;
        v->auto_requested = v->exposure_auto;
        float up_default[3] = {0.0f, 1.0f, 0.0f};
        int up_given = v->o.cam.up[0] != 0.0f || v->o.cam.up[1] != 0.0f || v->o.cam.up[2] != 0.0f;
        memcpy(v->up, up_given ? v->o.cam.up : up_default, sizeof v->up);
        vw_mesh_bounds(v->t->mesh, v->centre, &v->radius);
        v->cur = 0;
        v->loaded = -1;
        v->env_dirty = 1;
        if (!update_camera(v, 1)) rc = 2;
    }
    if (rc < 0) {
        if (!v->o.cd.quiet)
            fprintf(stderr, "view %s: %u vertices on %s; OpenGL: %s; colours by %s\n", v->scene,
                    v->t->mesh->vertex_count, hl_context_device_name(v->ctx), vw_gl_renderer(v->gl), v->feed);
        cli_watch(v->ctx, v->gctx);
        for (int i = 0; i < v->n_drops; i++) drop_file(v, v->drops[i]);
        rc = run_loop(v);
        print_times(v);
    }
    cli_unwatch();
    hl_cl_mem_release(v->glmem); /* the sharing objects before the GL buffer and context go */
    hl_relighter_destroy(v->rl);
    hl_context_destroy(v->gctx);
    vw_gl_destroy(v->gl);
    if (v->win) glfwDestroyWindow(v->win);
    glfwTerminate();
    for (int i = 0; i < v->n_envs; i++) hl_env_destroy(v->envs[i].env);
    free(v->rgb);
    hl_transport_destroy(v->t);
    hl_context_destroy(v->ctx);
    free(env_args);
    free(v);
    return rc;
}
