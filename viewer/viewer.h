/* viewer.h - the interactive viewer (`haarlight view`): interfaces between
 * its three files.
 *
 *   view.c       the command: options, loading, the GLFW window, input,
 *                the frame loop and the HUD (the only file that sees GLFW)
 *   gl_draw.c    every OpenGL call: mesh, background, glare, tone mapping,
 *                read-back (the only file that sees OpenGL)
 *   view_util.c  what needs neither: camera maths, the tone-map table, the
 *                colour feed decision, file names
 *
 * Not thread safe: everything runs on the thread that owns the window.
 */
#ifndef HL_VIEWER_H
#define HL_VIEWER_H

#include <stddef.h>
#include <stdint.h>

#include "haarlight.h"

/* `haarlight view ...` (argv after the command name); returns the exit code. */
int cmd_view(int argc, char **argv);

/* ---------------------------------------------------------------- gl_draw.c */

typedef struct vw_gl vw_gl;

/* What one frame shows. */
typedef struct vw_frame {
    float mvp[16];          /* column-major clip-from-world */
    hl_camera_view view;    /* for the background's per-pixel directions */
    float rotate_deg;       /* environment rotation (docs/CONVENTIONS.md) */
    float exposure_ev;
    int glare;
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
/* Copies 4 floats per vertex (the dot products' layout) into the colour
 * buffer. */
void vw_gl_upload_colours(vw_gl *g, const float *vertex_rgba);
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

/* "haarlight-view-NNN.png" in the current folder, the first not taken. */
void vw_screenshot_name(char *buf, size_t size);

#endif
