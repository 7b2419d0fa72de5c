/* view.c - `haarlight view`: interactive relighting in a GLFW window.
 *
 * Every lighting change (environment, its rotation, the sun of the
 * built-in sky, the number of terms M) runs the relighter - the lighting
 * stages and the sparse dot products on the context's device - and feeds
 * the vertex colours to OpenGL; a camera move or an exposure change only
 * redraws, and with nothing to do the loop sleeps in glfwWaitEvents.
 * With --dynamic the colours come from the dynamic method instead
 * whenever a body moved or the animation is not at time 0
 * (view_dynamic.c), and from the relighter otherwise, when a transport is
 * given. This file holds the command: its options, loading everything
 * that can fail on bad input, the window and its OpenGL context, and the
 * CL/GL sharing; the frames are view_frame.c's, the input view_input.c's,
 * the dynamic method's part view_dynamic.c's, the drawing gl_draw.c's and
 * the helpers view_util.c's.
 *
 * Dependencies: GLFW 3 (the window, the GLX context for sharing), the
 * haarlight library and haarlight_tools.h (CL/GL sharing), the CLI
 * helpers (cli.h).
 */
#define _POSIX_C_SOURCE 200809L
#define GLFW_INCLUDE_NONE
#define GLFW_EXPOSE_NATIVE_X11
#define GLFW_EXPOSE_NATIVE_GLX
#include <GLFW/glfw3.h>
#include <GLFW/glfw3native.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "haarlight_tools.h"
#include "viewer.h"

static const char *const usage_view =
    "usage: haarlight view SCENE.hlt [--env ENV.exr ...] [--sky] [options]\n"
    "       haarlight view SCENE.hlt --surroundings FILE [--time T] [--env ENV.exr ... | --sky]\n"
    "                      [options]\n"
    "       haarlight view --dynamic (SCENE.hlt | MESH | SCENE) [options]\n"
    "\n"
    "Opens a window on a transport file from `haarlight precompute` and relights it\n"
    "interactively. Every lighting change runs the lighting stages and the dot\n"
    "products on the device; a camera or exposure change only redraws, and an\n"
    "unchanged scene does no work. The window title is the HUD: frame rate, time of\n"
    "the relight, the upload and the draw, M, the lighting energy kept, the device\n"
    "and how the colours reach OpenGL.\n"
    "\n"
    "lighting:\n"
    "  --env ENV.exr        an equirectangular OpenEXR or Radiance .hdr; repeat for more\n"
    "                       (keys 1..9)\n"
    "  --sky                the built-in sun and sky (the default without --env and\n"
    "                       --surroundings)\n"
    CLI_USAGE_SKY
    "  --surroundings FILE  light from surroundings: any mesh file assimp reads (glTF, FBX,\n"
    "                       OBJ, ...); emissive materials give light (emissive colour x\n"
    "                       glTF emissive strength), the others are dark and hide what\n"
    "                       lies behind them; any number of triangles. The relighter\n"
    "                       captures them at every lighting change, as seen from the\n"
    "                       centre of the object's bounding box (ground left out), so\n"
    "                       surroundings close to a large object light all of it as if\n"
    "                       from its centre, unless --probes says otherwise. Directions\n"
    "                       they leave open are lit by --env or --sky if given, else\n"
    "                       black (--rotate and the keys turn the environment only).\n"
    "                       They are drawn (an emitter in its emitted colour at the\n"
    "                       exposure, a dark body in grey; s hides them) and can be\n"
    "                       dragged and played (keys below); a frame where nothing\n"
    "                       moved and the environment is the same does no lighting work\n"
    "                       (the HUD says \"lighting: unchanged\")\n"
    CLI_USAGE_SURROUNDINGS_TRANSFORM
    "  --probes N           capture the surroundings from up to N points (1 to 256; default\n"
    "                       1) where an emitter is near, each vertex blended over the\n"
    "                       points near it (as relight's --probes): each point costs a\n"
    "                       capture and a relight a lighting change\n"
    "  --time T             seconds into the animation of the surroundings, or of\n"
    "                       --dynamic's scene (default 0; held at the first or last key\n"
    "                       outside its range)\n"
    "  --play               start playing that animation (in real time, looping)\n"
    "  --drag X0,Y0,X1,Y1   before the first frame, a left-button drag from window point\n"
    "                       X0,Y0 to X1,Y1 through the mouse's own handlers (for tests;\n"
    "                       prints the body's translation): a body of the surroundings,\n"
    "                       or with --dynamic a body of the scene\n"
    CLI_USAGE_LAYOUT
    CLI_USAGE_LIGHTING
    "display:\n"
    "  --exposure EV        scale by 2^EV before the sRGB curve (default: automatic,\n"
    "                       as relight's: the object's 90th percentile of vertex\n"
    "                       luminance to 0.8, the ground left out)\n"
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
    "  --textures MODEL     keep MODEL's base-colour textures sharp, as relight --textures\n"
    "                       (MODEL: the file SCENE.hlt was precomputed from); a --dynamic\n"
    "                       file keeps its own, animated or not\n"
    "  --keep-winding       as given to precompute, for reading --textures' MODEL\n"
    "  --keys STRING        type STRING's characters after the first frame (for tests;\n"
    "                       the keys below that are characters)\n"
    "dynamic scenes (--dynamic: the second method, relight-dynamic's, which needs no\n"
    "precompute, so bodies may move; a frame costs as much as one relight-dynamic run,\n"
    "and one is made only when a body moved, the time or the lighting changed):\n"
    "  --dynamic            SCENE.hlt: the transport's mesh and ground as bodies \"object\"\n"
    "                       and \"ground\"; MESH or SCENE (any file assimp reads): every\n"
    "                       node with triangles a body, moving by the file's animation.\n"
    "                       With a transport, frames where nothing moved (no body moved,\n"
    "                       the animation at time 0) are PRT's (exact self-shadowing,\n"
    "                       --terms) and the others the dynamic method's; the HUD names\n"
    "                       the method and gives the dynamic frame's time by stage\n"
    "  --hlt SCENE.hlt      with a MESH or SCENE: the transport for frames at rest; its\n"
    "                       mesh must be the dynamic scene's, vertex for vertex\n"
    "  --ground             a ground plane (body \"ground\"), as relight-dynamic --ground\n"
    "  --rest-pose          the file's animation not followed, as relight-dynamic --rest-pose\n"
    "  --lights K           area lights with shadows (default 32)\n"
    "  --shadow-res R       shadow map size, a multiple of 16 from 16 to 1024 (default 128)\n"
    "  --sharp MODE         the sharp lights (a sun): rays, maps or off (relight-dynamic\n"
    "                       --help)\n"
    "  --sharp-res RS       the sharp lights' map size with --sharp maps (relight-dynamic\n"
    "                       --help)\n"
    "  --order M            convolution shadow map order, 4 to 16 (default 16); given\n"
    "                       alone it asks for CSM\n"
    "  --shadow S           moments (the default) or csm: the filterable shadow map\n"
    "                       (relight-dynamic --help)\n"
    "  --time, --play, --drag  as above, on the dynamic scene\n"
    "  --move BODY:X,Y,Z    translate the body named BODY before the first frame\n"
    "                       (repeatable; as relight-dynamic's --move)\n"
    "running:\n"
    CLI_USAGE_RUNNING
    "\n" VW_KEYS;

/* ---------------------------------------------------------------- setup */

static void on_glfw_error(int code, const char *what)
{
    fprintf(stderr, "haarlight: GLFW error 0x%x: %s\n", (unsigned)code, what);
}

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
    if (!vw_gl_create(v->mesh, thr, &v->gl, err, sizeof err) ||
        !vw_gl_resize(v->gl, v->fb_w, v->fb_h, err, sizeof err) ||
        (v->draw_surface && !vw_gl_set_surface(v->gl, v->mesh, v->draw_surface, err, sizeof err))) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 0;
    }
    vw_input_attach(v->win);
    return 1;
}

/* Options; returns -1 to go on, else the exit code. */
static int parse(viewer *v, int argc, char **argv, const char **env_args, int *n_env_args)
{
    const char *usage = usage_view, *dyn_opt = NULL, *shared_opt = NULL;
    cli_scene_opts_init(&v->o);
    v->o.accept_surroundings = 1; /* --surroundings and --time (also --dynamic's --time) */
    *n_env_args = 0;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        int k = cli_scene_opt(argc, argv, &i, usage, &v->o);
        if (k < 0) return -k;
        if (k) continue;
        k = vw_dyn_opt(v, argc, argv, &i, usage);
        if (k < 0) return -k;
        if (k) {
            if (!strcmp(a, "--play") || !strcmp(a, "--drag")) shared_opt = a; /* --dynamic's or the surroundings' */
            else if (strcmp(a, "--dynamic")) dyn_opt = a;
            continue;
        }
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
        if (!strcmp(a, "--keep-winding")) {
            v->keep_winding = 1;
            continue;
        }
        int takes = !strcmp(a, "--env") || !strcmp(a, "--frames") || !strcmp(a, "--screenshot") ||
                    !strcmp(a, "--spin") || !strcmp(a, "--drop") || !strcmp(a, "--keys") || !strcmp(a, "--textures");
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
        } else if (!strcmp(a, "--keys")) {
            v->keys = val;
        } else if (!strcmp(a, "--textures")) {
            v->textures = val;
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
    if (!v->scene) return usage_error(usage, "%s", v->dy.on ? "no SCENE given" : "no SCENE.hlt given");
    if (dyn_opt && !v->dy.on) return usage_error(usage, "%s is an option of --dynamic (give --dynamic)", dyn_opt);
    if (v->dy.on && v->o.surroundings)
        return usage_error(usage, "%s", "--surroundings light a transport through the relighter, not --dynamic's scene");
    if (shared_opt && !v->dy.on && !v->o.surroundings)
        return usage_error(usage, "%s is an option of --surroundings or --dynamic", shared_opt);
    if (v->o.place_set && !v->o.surroundings)
        return usage_error(usage, "%s", "--surroundings-transform needs --surroundings");
    if (v->o.probes_set && !v->o.surroundings) return usage_error(usage, "%s", "--probes needs --surroundings");
    if (v->o.time_set && !v->dy.on && !v->o.surroundings)
        return usage_error(usage, "%s", "--time needs --surroundings or --dynamic");
    v->dy.time0 = (float)v->o.time; /* --dynamic's --time is read by the shared parser */
    if (v->shot_path && !v->frames_limit) v->frames_limit = 1;
    if (v->o.sky_set || (*n_env_args == 0 && !v->o.surroundings)) { /* surroundings alone: black, as relight */
        int have = 0;
        for (int i = 0; i < *n_env_args; i++) have |= env_args[i] == NULL;
        if (!have) env_args[(*n_env_args)++] = NULL;
    }
    return -1;
}

/* The relighter on ctx, its columns laid out from the file's rows
 * (hl_relighter_create_from_file): the loaded entries are weighed, then
 * freed before the columns are made, so the two are never in memory
 * together (on the dragon 1.28 GB less at the peak). A try that failed
 * after freeing them (the interop's, below) leaves the transport without
 * entries: the file is then loaded again for the relighter, and v->t
 * keeps the mesh that is drawn. */
static hl_result make_relighter(viewer *v, hl_context *ctx)
{
    hl_transport *t = v->t_rows ? v->t_rows : v->t;
    if (!t->entries) {
        hl_transport_destroy(v->t_rows);
        v->t_rows = NULL;
        hl_result r = hl_transport_load(ctx, v->t_path, &v->t_rows);
        if (r != HL_OK) return r;
        t = v->t_rows;
    }
    return hl_relighter_create_from_file(ctx, t, v->t_path, &v->rl);
}

/* The relighter on the first context, its colours read back; prints the
 * error and returns 0 on failure. */
static int readback_relighter(viewer *v)
{
    hl_result r = make_relighter(v, v->ctx);
    if (r != HL_OK) cli_fail(v->ctx, r);
    return r == HL_OK;
}

/* Context, transport (and dynamic scene), environments, relighter:
 * everything that can fail on bad input, before any window opens. Returns
 * 1, or 0 on failure, 2 on a usage error found late (--dynamic's). */
static int load(viewer *v, const char **env_args, int n_env_args)
{
    char err[4096];
    if (hl_context_create(&v->o.cd, &v->ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 0;
    }
    cli_watch(v->ctx, NULL); /* Ctrl-C cancels it: the loop polls it */
    if (v->dy.on) {
        int rc = 1;
        if (!vw_dyn_load(v, &rc)) return rc == 2 ? 2 : 0; /* 2: a usage error */
    } else if (hl_transport_load(v->ctx, v->scene, &v->t) != HL_OK) {
        cli_fail(v->ctx, HL_ERR_IO);
        return 0;
    } else {
        v->mesh = v->t->mesh;
        v->t_path = v->scene;
    }
    /* textures: --textures MODEL, or a --dynamic file loaded as one mesh
       (as relight-dynamic; an animated file's bodies keep per-vertex albedo) */
    const hl_mesh_load_desc md = {.keep_winding = v->keep_winding};
    if (v->textures && hl_surface_load(v->ctx, v->textures, &md, v->mesh, &v->surface) != HL_OK) {
        cli_fail(v->ctx, HL_ERR_INVALID_ARGUMENT);
        return 0;
    }
    v->draw_surface = v->surface;
    if (!v->textures && v->dy.on && v->dy.d) v->draw_surface = hl_dynamic_surface(v->dy.d); /* bodies' own */
    if (!v->textures && v->dy.on && !v->t && !v->draw_surface) {
        const int quiet = hl_context_quiet(v->ctx);
        hl_context_set_quiet(v->ctx, 1);
        if (hl_surface_load(v->ctx, v->scene, NULL, v->mesh, &v->surface) != HL_OK) v->surface = NULL;
        hl_context_set_quiet(v->ctx, quiet);
        v->draw_surface = v->surface;
    }
    if (v->draw_surface && !v->o.cd.quiet && hl_surface_texture_count(v->draw_surface))
        fprintf(stderr, "textures: %u, per pixel\n", hl_surface_texture_count(v->draw_surface));
    hl_camera_view cv; /* an impossible camera fails here, before any window */
    if (cli_camera_complete(v->ctx, v->mesh, &v->o) != HL_OK ||
        hl_camera_query_view(v->ctx, v->mesh, &v->o.cam, &cv) != HL_OK) {
        cli_fail(v->ctx, HL_ERR_INVALID_ARGUMENT);
        return 0;
    }
    v->sun_el = v->o.sky.sun_elevation_deg != 0.0f ? v->o.sky.sun_elevation_deg : VW_SUN_DEFAULT_ELEVATION;
    v->sun_az = v->o.sky.sun_azimuth_deg;
    v->sky_slot = v->black_slot = -1;
    if (v->o.surroundings && !vw_sur_load(v)) return 0;
    if (n_env_args == 0) { /* surroundings alone: a black map, drawn behind them and not given to the relighter */
        static const float black[6] = {0};
        hl_env *env = NULL;
        if (hl_env_create(v->ctx, 2, 1, black, &env, NULL) != HL_OK) {
            cli_fail(v->ctx, HL_ERR_OUT_OF_MEMORY);
            return 0;
        }
        v->black_slot = vw_add_env(v, env, "none (black)");
    }
    for (int i = 0; i < n_env_args; i++) {
        hl_env *env = NULL;
        hl_result r = env_args[i] ? cli_env_load(v->ctx, env_args[i], v->o.layout, &env, 0) : vw_make_sky(v, &env);
        if (r != HL_OK) {
            cli_fail(v->ctx, r);
            return 0;
        }
        int k = vw_add_env(v, env, env_args[i] ? vw_base_name(env_args[i]) : "");
        if (!env_args[i]) {
            v->sky_slot = k;
            vw_sky_label(v, &v->envs[k]);
        }
    }
    v->rgb = calloc(3 * (size_t)v->mesh->vertex_count, sizeof *v->rgb); /* zero until the first relight */
    if (!v->rgb) {
        fprintf(stderr, "haarlight: out of memory for %u vertex colours\n", v->mesh->vertex_count);
        return 0;
    }
    if (!v->t) { /* the dynamic method alone: its colours come to the host */
        snprintf(v->feed, sizeof v->feed, "upload (dynamic method: colours on the host)");
        return 1;
    }
    v->interop = vw_feed_mode(v->ctx, v->readback_asked, v->feed, sizeof v->feed);
    if (v->interop) return 1; /* the relighter waits for the window's GL context (setup_interop) */
    return readback_relighter(v);
}

/* With a device that lists cl_khr_gl_sharing: a second context on the same
 * device that shares the window's GLX context, the relighter on it, and
 * the GL colour buffer wrapped for the dot products to write. On any
 * failure the relighter is made on the first context and the colours are
 * read back. Needs the window's context current. */
static int setup_interop(viewer *v)
{
    if (!v->interop || !v->t) return 1;
    char why[4096] = "";
    void *glx = (void *)glfwGetGLXContext(v->win), *dpy = (void *)glfwGetX11Display();
    if (!glx || !dpy) {
        snprintf(why, sizeof why, "the window's OpenGL context is not a GLX context");
    } else {
        intptr_t props[5];
        hl_view_glx_properties(glx, dpy, props);
        hl_context_desc cd = v->o.cd;
        cd.cl_properties = props;
        if (hl_context_create(&cd, &v->gctx, why, sizeof why) == HL_OK) {
            /* the GL buffer first: a relighter that failed after it
               freed the entries costs a second load (make_relighter) */
            if (hl_view_gl_colours_create(v->gctx, vw_gl_colour_buffer(v->gl), &v->glmem) != HL_OK ||
                make_relighter(v, v->gctx) != HL_OK)
                snprintf(why, sizeof why, "%s", hl_context_last_error(v->gctx));
        }
    }
    if (!why[0]) return 1;
    vw_interop_off(v, why);
    hl_relighter_destroy(v->rl);
    v->rl = NULL;
    hl_view_gl_colours_destroy(v->glmem);
    v->glmem = NULL;
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
    if (rc < 0) {
        rc = load(v, env_args, n_env_args);
        rc = rc == 1 ? -1 : rc == 2 ? 2 : 1;
    }
    if (rc < 0) rc = open_window(v) ? -1 : 3;
    if (rc < 0) rc = setup_interop(v) && vw_sur_attach(v) ? -1 : 1;
    if (rc < 0) {
        v->rd = v->o.rd;
        if (v->rd.terms == 0) v->rd.terms = VW_DEFAULT_TERMS;
        v->exposure = v->o.exposure;
        v->exposure_auto = !v->o.exposure_set;
        v->auto_requested = v->exposure_auto;
        float up_default[3] = {0.0f, 1.0f, 0.0f};
        int up_given = v->o.cam.up[0] != 0.0f || v->o.cam.up[1] != 0.0f || v->o.cam.up[2] != 0.0f;
        memcpy(v->up, up_given ? v->o.cam.up : up_default, sizeof v->up);
        vw_mesh_bounds(v->mesh, v->centre, &v->radius);
        v->cur = 0;
        v->loaded = -1;
        v->env_dirty = 1;
        if (!vw_update_camera(v, 1)) rc = 2;
        else if (!vw_dyn_start(v) || !vw_sur_start(v)) rc = 2;
    }
    if (rc < 0) {
        if (!v->o.cd.quiet)
            fprintf(stderr, "view %s: %u vertices on %s; OpenGL: %s; colours by %s\n", v->scene,
                    v->mesh->vertex_count, hl_context_device_name(v->ctx), vw_gl_renderer(v->gl), v->feed);
        cli_watch(v->ctx, v->gctx);
        for (int i = 0; i < v->n_drops; i++) vw_drop_file(v, v->drops[i]);
        rc = vw_run_loop(v);
        vw_print_times(v);
    }
    cli_unwatch();
    hl_view_gl_colours_destroy(v->glmem); /* the sharing objects before the GL buffer and context go */
    hl_relighter_destroy(v->rl);
    hl_context_destroy(v->gctx);
    vw_gl_destroy(v->gl);
    if (v->win) glfwDestroyWindow(v->win);
    glfwTerminate();
    for (int i = 0; i < v->n_envs; i++) hl_env_destroy(v->envs[i].env);
    free(v->rgb);
    vw_dyn_destroy(v);
    vw_sur_destroy(v);
    hl_transport_destroy(v->t);
    hl_surface_destroy(v->surface);
    hl_transport_destroy(v->t_rows);
    hl_context_destroy(v->ctx);
    free(env_args);
    free(v);
    return rc;
}
