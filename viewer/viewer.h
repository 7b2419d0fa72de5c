/* viewer.h - the interactive viewer (`haarlight view`): interfaces between
 * its files.
 *
 *   view.c        the command: options, loading, the GLFW window, CL/GL
 *                 sharing
 *   view_frame.c  the frame loop: lighting work, camera, screenshots,
 *                 timings, messages and the HUD
 *   view_input.c  keys, mouse and dropped files; the environment list
 *   gl_draw.c     every OpenGL call: mesh, background, glare, tone mapping,
 *                 read-back (the only file that sees OpenGL)
 *   view_dynamic.c --dynamic: the dynamic method's scene, its frames,
 *                 the animation, picking and dragging bodies, its HUD
 *   view_surround.c --surroundings: lighting captured from the scene's
 *                 surroundings, their animation, picking and dragging
 *                 their bodies, their triangles for drawing, their HUD
 *   view_util.c   what needs neither OpenGL nor GLFW: camera maths, the
 *                 tone-map table, the colour feed decision, file names,
 *                 mouse rays and their hits
 * The view*.c files see GLFW; gl_draw.c does not.
 *
 * Not thread safe: everything runs on the thread that owns the window.
 */
#ifndef HL_VIEWER_H
#define HL_VIEWER_H

#include <stddef.h>
#include <stdint.h>

#include "cli.h"
#include "haarlight.h"
#include "haarlight_tools.h"

/* `haarlight view ...` (argv after the command name); returns the exit code. */
int cmd_view(int argc, char **argv);

/* The help's list of keys (usage and the h key). */
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
    "  q, escape              quit\n"                                                        \
    "with --dynamic:\n"                                                                       \
    "  left drag on a body    move it across the horizontal plane through the grab point\n"   \
    "                         (the ground itself is not dragged; elsewhere: orbit)\n"         \
    "  space                  play / pause the animation (scenes without one: spin)\n"       \
    "  b                      bodies back to their animation, the time to --time (PRT\n"    \
    "                         again where that is at rest and there is a transport)\n"    \
    "with --surroundings (lit as captured from ONE point, the centre of the object's\n"    \
    "bounding box, ground left out):\n"                                                    \
    "  left drag on a body    move that body of the surroundings across the horizontal\n" \
    "                         plane through the grab point (elsewhere, or where the\n"    \
    "                         object is in front or they are hidden: orbit)\n"            \
    "  space                  play / pause their animation, looping over its range (none:\n" \
    "                         spin the environment)\n"                                      \
    "  b                      their bodies back where the file puts them, the time to --time\n" \
    "  s                      show / hide them (they light the object either way)\n"


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
/* A drag (a body of --dynamic or of the surroundings) follows the mouse
 * ray to the plane through the grab point; near the horizon that point
 * runs off to infinity, so a move is held within this many bounding radii
 * of the mesh. */
#define VW_DRAG_MAX_RADII 4.0

typedef struct vw_gl vw_gl;
struct GLFWwindow;

typedef struct env_slot {
    char label[128];
    hl_env *env;
} env_slot;

/* Sums of per-frame times in seconds, for the averages printed at exit. */
typedef struct time_sums {
    double relight, upload, draw, present, frame;
    uint64_t n;
} time_sums;

enum { DRAG_NONE, DRAG_ORBIT, DRAG_ENV, DRAG_SUN, DRAG_BODY, DRAG_SURR };

/* --move options one run takes (as relight-dynamic's). */
#define VW_MAX_MOVES 64
/* --lights default: relight-dynamic's, so that the two agree unasked. */
#define VW_DYN_DEFAULT_LIGHTS 32

/* The dynamic method's part of the viewer (--dynamic). */
typedef struct vw_dyn {
    int on;                 /* --dynamic given */
    const char *hlt;        /* --hlt: the transport for frames at rest */
    int ground;             /* --ground */
    int rest_pose;          /* --rest-pose */
    uint32_t lights;        /* --lights K */
    hl_dynamic_desc desc;   /* --shadow-res, --order */
    float time0;            /* --time */
    int play;               /* --play */
    uint32_t nmoves;
    char *move_name[VW_MAX_MOVES];
    float move[VW_MAX_MOVES][3];
    int drag_set;           /* --drag X0,Y0,X1,Y1 */
    float drag[4];

    hl_dynamic *d;
    uint32_t nb;
    float (*xf)[12];        /* each body's transform after its animation */
    uint32_t moved;         /* bodies whose transform is not the identity */
    double time, t_start, t_end, play_clock;
    int playing;
    int env_dirty;          /* the lights must be split again (map or rotation) */
    int env_failed;         /* the last split failed: no dynamic frame until
                               the next map or rotation (the old lights would
                               not match the map on screen) */
    int dirty;              /* a body moved or the time changed */
    int showing;            /* the colours on screen are the dynamic method's */
    int ok;                 /* the last frame rendered */
    float *rgb;             /* the last frame's colours (3 per vertex, owned by d) */
    float *rgba;            /* the same, 4 per vertex, for the colour buffer */
    hl_dynamic_lights li;
    hl_dynamic_stats st;
    /* the body being dragged: its transform and the grab point at the press */
    uint32_t drag_body;
    float drag_xf[12], grab[3];
} vw_dyn;

/* Lighting captured from the scene's surroundings (--surroundings). */
typedef struct vw_sur {
    hl_surroundings *s;     /* NULL without --surroundings */
    uint32_t nb, nt;        /* bodies, triangles */
    uint32_t *body;         /* each triangle's body (nb: not found) */
    float (*xf)[12];        /* each body's transform after its animation */
    uint32_t moved;         /* bodies whose transform is not the identity */
    float *verts;           /* 3 vertices a triangle, 7 floats each, for drawing */
    double time0, time, t_start, t_end, play_clock;
    int playing, show;
    int dirty;              /* moved or the time changed: pose, upload, relight */
    int work;               /* the last frame captured and relit */
    int unchanged;          /* the last frame asked and the relighter found
                               nothing changed (stats.reused): no work */
    float centre[3], radius; /* the sphere around the mesh and the surroundings */
    uint64_t n_work, n_unchanged;
    double t_work;          /* the sum of the capture + relight times */
    uint32_t drag_body;     /* the body being dragged, its transform and the
                               grab point at the press */
    float drag_xf[12], grab[3];
} vw_sur;

typedef struct viewer {
    cli_scene_opts o;
    const char *scene, *shot_path;
    const char *keys; /* --keys: typed after the first frame */
    const char *drops[VW_MAX_DROPS];
    int n_drops;
    uint32_t frames_limit;
    float spin_deg;

    hl_context *ctx;
    hl_transport *t;     /* NULL with --dynamic and no transport */
    const char *t_path;  /* the file t was loaded from */
    hl_transport *t_rows; /* t loaded again for a second try at the relighter (make_relighter) */
    const hl_mesh *mesh; /* the mesh drawn: the transport's or the dynamic scene's */
    const char *textures; /* --textures MODEL */
    int keep_winding;     /* --keep-winding: how MODEL was read for the transport */
    hl_surface *surface;  /* its textured surface, or a --dynamic file's own; NULL without */
    const hl_surface *draw_surface; /* the one drawn: surface, or the dynamic bodies' */
    vw_dyn dy;
    vw_sur su;
    hl_relighter *rl;
    hl_context *gctx;  /* shares buffers with the window's GL context (interop);
                          the relighter lives on it when set, else on ctx */
    hl_gl_colours *glmem; /* the GL colour buffer as an OpenCL buffer (interop) */
    int interop, readback_asked;
    float *rgb;
    env_slot envs[VW_MAX_ENVS];
    int n_envs, cur, loaded, sky_slot;
    int black_slot;    /* --surroundings without --env or --sky: no map (black),
                          which the relighter is not given until another map was */
    int rl_env_set;    /* the relighter has had an environment */
    float sun_el, sun_az;
    hl_relight_desc rd;
    hl_relight_stats st;
    float exposure;
    int exposure_auto, glare, spinning;
    char feed[160];

    float eye[3], target[3], up[3];
    hl_camera_view view;
    float centre[3], radius;

    struct GLFWwindow *win;
    vw_gl *gl;
    uint32_t fb_w, fb_h;
    int drag;
    double last_x, last_y;

    /* work waiting for the next frame */
    int sky_dirty, env_dirty, light_dirty, camera_dirty, resized, redraw, shot_requested, auto_requested, quit;
    int failed; /* the first environment could not be set: nothing to show */

    char msg[512], hud[1024];
    double msg_until;
    double fps, last_frame_end, first_frame;
    double t_relight, t_upload, t_draw, t_present;
    time_sums all, lit;
} viewer;

/* ---------------------------------------------------------------- view_frame.c */

/* The last error of the relighter's context. */
const char *vw_rl_error(const viewer *v);
/* A line in the HUD for a while, and on stderr (errors always, the rest
 * unless quiet). */
void vw_say(viewer *v, int error, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
void vw_update_title(viewer *v);
/* Gives up CL/GL interop (setup failed, or a relight into the GL buffer
 * did) and says why; the colours are read back from then on. */
void vw_interop_off(viewer *v, const char *why);
/* The camera for the current eye and target (automatic: the options' or
 * hl_render's framing); a camera hl_render refuses leaves the previous one
 * and returns 0. */
int vw_update_camera(viewer *v, int automatic);
/* Frames until quit, the window closes, Ctrl-C or --frames; returns the
 * exit code. vw_print_times then gives the mean timings. */
int vw_run_loop(viewer *v);
void vw_print_times(const viewer *v);

/* ---------------------------------------------------------------- view_input.c */

/* Sets the window's input callbacks (its user pointer is the viewer). */
void vw_input_attach(struct GLFWwindow *w);
/* A left-button drag from window point (x0, y0) to (x1, y1) through the
 * mouse callbacks themselves (--drag); 1 if it grabbed a body. */
int vw_input_drag(viewer *v, double x0, double y0, double x1, double y1);
/* Each character of keys as if typed (--keys). */
void vw_input_type(viewer *v, const char *keys);
/* Appends an environment (owned from then on); returns its index, or -1
 * (and destroys it) when the list is full. */
int vw_add_env(viewer *v, hl_env *env, const char *label);
void vw_sky_label(viewer *v, env_slot *s);
/* The built-in sky at the current sun. */
hl_result vw_make_sky(viewer *v, hl_env **out);
/* Loads a dropped (or --drop) file and shows it; an unreadable one leaves
 * the lighting as it was. */
void vw_drop_file(viewer *v, const char *path);
void vw_rotate_env(viewer *v, float deg);
/* Automatic exposure from the current colours. */
void vw_auto_exposure(viewer *v);

/* ---------------------------------------------------------------- view_dynamic.c */

/* --dynamic's options; 1 taken, 0 not one of them, -2 usage error
 * (printed). */
int vw_dyn_opt(viewer *v, int argc, char **argv, int *i, const char *usage);
/* The dynamic scene (and the transport, when there is one) before any
 * window: scene, transport and their vertex order checked, moves applied;
 * prints the error and returns 0 on failure (*rc the exit code). */
int vw_dyn_load(viewer *v, int *rc);
/* Before the first frame: --drag through the mouse's own path. */
int vw_dyn_start(viewer *v);
/* The frame's lighting work in --dynamic mode (after the environment was
 * set): PRT at rest with a transport, else a dynamic frame when something
 * changed; 1 if the colours changed. */
int vw_dyn_frame(viewer *v);
/* Whether the next frame has dynamic work (playing, a moved body). */
int vw_dyn_pending(const viewer *v);
/* The HUD's method part. */
void vw_dyn_hud(const viewer *v, char *buf, size_t size);
/* Mouse: a press at window pixel (x, y) of a w x h window; returns 1 and
 * starts a body drag when a body is under it. */
int vw_dyn_grab(viewer *v, double x, double y, double w, double h);
void vw_dyn_drag(viewer *v, double x, double y, double w, double h);
/* Space: play / pause; 0 when there is no animation. */
int vw_dyn_toggle_play(viewer *v);
/* Every body back to its animation and the time to --time. */
void vw_dyn_reset(viewer *v);
void vw_dyn_destroy(viewer *v);

/* ---------------------------------------------------------------- view_surround.c */

/* Before any window: the surroundings posed at --time, each triangle's
 * body; prints the error and returns 0 on failure. */
int vw_sur_load(viewer *v);
/* Once the relighter exists (after the CL/GL choice): it captures them. */
int vw_sur_attach(viewer *v);
/* Before the first frame: --play's clock, --drag through the mouse's path;
 * 0 (printed) when --drag finds no body of the surroundings. */
int vw_sur_start(viewer *v);
/* The frame's part before the relight: the clock, the pose, the upload;
 * marks the lighting dirty when something moved. */
void vw_sur_frame(viewer *v);
/* After a relight (or none: ran 0): what the frame did, for the HUD. */
void vw_sur_note(viewer *v, int ran, int reused, double seconds);
int vw_sur_pending(const viewer *v);
void vw_sur_hud(const viewer *v, char *buf, size_t size);
int vw_sur_grab(viewer *v, double x, double y, double w, double h);
void vw_sur_drag(viewer *v, double x, double y, double w, double h);
int vw_sur_toggle_play(viewer *v);
void vw_sur_reset(viewer *v);
void vw_sur_destroy(viewer *v);

/* ---------------------------------------------------------------- gl_draw.c */

/* What one frame shows. */
typedef struct vw_frame {
    float mvp[16];          /* column-major clip-from-world */
    hl_camera_view view;    /* for the background's per-pixel directions */
    float rotate_deg;       /* environment rotation (docs/CONVENTIONS.md) */
    float exposure_ev;
    int glare;
    int surroundings;       /* draw the surroundings' triangles */
} vw_frame;

/* Needs a current OpenGL 3.3 core context. Uploads the mesh once; the
 * tone-map table thr (vw_tonemap_thresholds) is copied. On failure returns
 * 0 with the message in err. */
int vw_gl_create(const hl_mesh *mesh, const float thr[256], vw_gl **out, char *err, size_t err_size);
void vw_gl_destroy(vw_gl *g);
/* The GL_RENDERER and GL_VERSION strings, for the HUD. */
const char *vw_gl_renderer(const vw_gl *g);
/* (Re)creates the render targets for a framebuffer of w x h pixels. */
int vw_gl_resize(vw_gl *g, uint32_t w, uint32_t h, char *err, size_t err_size);
/* Uploads the environment drawn as background. */
int vw_gl_set_env(vw_gl *g, const hl_env *env, char *err, size_t err_size);
/* Replaces the vertex positions (3 floats per vertex; bodies moved). */
void vw_gl_upload_positions(vw_gl *g, const float *positions);
/* The surroundings' triangles, 7 floats a vertex: position, colour, and
 * 1 where the colour is a display value (divided by 2^EV when drawn) or 0
 * where it is radiance (tone-mapped like the mesh). */
int vw_gl_set_surroundings(vw_gl *g, const float *verts, uint32_t vertex_count, char *err, size_t err_size);
/* Copies 4 floats per vertex (the dot products' layout) into the colour
 * buffer. */
void vw_gl_upload_colours(vw_gl *g, const float *vertex_rgba);
/* The mesh's textured surface (hl_surface_load): its textured triangles
 * drawn as hl_render_surface shades them, the rest as before. 0 with a
 * message on failure. */
int vw_gl_set_surface(vw_gl *g, const hl_mesh *mesh, const hl_surface *su, char *err, size_t err_size);
/* The colour buffer object, for OpenCL to write into (clCreateFromGLBuffer);
 * vw_gl_finish before OpenCL acquires it, vw_gl_colours_written after. */
unsigned vw_gl_colour_buffer(const vw_gl *g);
void vw_gl_finish(void);
void vw_gl_colours_written(vw_gl *g);
/* Scene into the float target, optional glare, tone map onto the window's
 * back buffer. Returns when the GPU has finished (so it can be timed). */
void vw_gl_draw(vw_gl *g, const vw_frame *f);
/* After vw_gl_draw, before the buffers are swapped: the frame as linear
 * radiance (glare included, 3 floats per pixel, row 0 at the top) and, if
 * srgb8 is not NULL, the tone-mapped back buffer (3 bytes per pixel). */
int vw_gl_read(vw_gl *g, const vw_frame *f, float *rgb, uint8_t *srgb8, char *err, size_t err_size);

/* ---------------------------------------------------------------- view_util.c */

/* thr[k] (k = 1..255) is the least float x with hl_tonemap_srgb8(x, 0) >= k
 * (thr[0] = 0): hl_tonemap_srgb8 as a table, so that the display shader
 * tone-maps with the very function the PNG writer uses. */
void vw_tonemap_thresholds(float thr[256]);

/* Bounding sphere of every vertex, ground included (for the depth range). */
void vw_mesh_bounds(const hl_mesh *mesh, float centre[3], float *radius);
/* Clip-from-world matrix for the camera, near and far planes around the
 * bounding sphere. */
void vw_camera_matrix(const hl_camera_view *v, const float centre[3], float radius, float mvp[16]);
/* Turns eye about target: yaw about up, pitch about the camera's right
 * axis (refused near the poles, so up never meets the view direction). */
void vw_orbit(float eye[3], const float target[3], const float up[3], double yaw, double pitch);
/* Moves eye towards target by the factor (> 0), keeping a minimum distance. */
void vw_zoom(float eye[3], const float target[3], double factor, double min_distance);

/* How vertex colours reach OpenGL, decided at run time for ctx's device:
 * 1 to try CL/GL interop (the device lists cl_khr_gl_sharing and
 * readback_asked is 0), else 0; buf gets the line for the HUD. */
int vw_feed_mode(hl_context *ctx, int readback_asked, char *buf, size_t size);

/* The world-space ray through window pixel (x, y) (from the top left) of
 * a w x h window, as hl_render shoots it: origin the eye, dir unnormalised. */
void vw_pixel_ray(const hl_camera_view *cv, double x, double y, double w, double h, double dir[3]);
/* Distance along the ray (o, d) to triangle (a, b, c), or -1 on a miss
 * (either side counts). */
double vw_ray_triangle(const double o[3], const double d[3], const float *a, const float *b, const float *c);

/* A drag across the horizontal plane through grab: the translation
 * (y 0) from grab to where the ray through window pixel (x, y) meets that
 * plane, held within `most` of grab; 0 when the ray meets it not at all
 * or behind the eye. */
int vw_drag_delta(const hl_camera_view *cv, double x, double y, double w, double h, const float grab[3],
                  double most, double delta[3]);
/* The smallest sphere around two spheres. */
void vw_sphere_union(const float c0[3], float r0, const float c1[3], float r1, float c[3], float *r);

/* "haarlight-view-NNN.png" in the current folder, the first not taken. */
void vw_screenshot_name(char *buf, size_t size);

/* The file name of a path (after its last '/'). */
const char *vw_base_name(const char *path);

#endif
