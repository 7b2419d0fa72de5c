/* gl_draw.c - everything the viewer draws, in OpenGL 3.3 core.
 *
 * A frame: the mesh (per-vertex linear colours, interpolated like
 * hl_render's barycentrics), the surroundings' flat triangles when there
 * are any, and then the environment behind it (a full-
 * screen triangle at the far plane, each pixel reading the equirectangular
 * map along its own view direction with docs/CONVENTIONS.md's mapping, bilinear like
 * hl_env_query_smooth) into an RGBA16F target; optionally the glare (a
 * bright-pass of exposure-scaled values above 1 into a quarter-size float
 * target, a separable Gaussian blur, added back); then the tone map onto
 * the window: 2^EV, then hl_tonemap_srgb8 itself, as its table of code
 * thresholds (vw_tonemap_thresholds), searched per channel.
 *
 * Dependencies: OpenGL 3.3 core through <GL/glcorearb.h> with the entry
 * points of libGL (GL_GLEXT_PROTOTYPES); haarlight.h for meshes and
 * environments. The caller owns the context and makes it current.
 */
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "viewer.h"

/* Glare: the blurred excess is added back at this gain; the blur's
 * standard deviation is in quarter-size pixels (4 window pixels each). */
#define VW_GLARE_GAIN 0.3f
#define VW_GLARE_SIGMA 3.0
#define VW_GLARE_RADIUS 9 /* taps each side: 3 sigma */
#define VW_GLARE_DOWN 4   /* quarter size: 4 x 4 window pixels per texel */

struct vw_gl {
    GLuint vao, empty_vao, vbo_pos, vbo_rgb, ebo;
    /* a textured surface (vw_gl_set_surface): its triangles' corners, one
       range a texture, drawn with the positions and colours read from the
       buffers above through buffer textures; ebo then holds the rest */
    GLuint vao_tex, vbo_tex, prog_tex, tbo[2], *tex_ids;
    uint32_t ntex;
    GLint *tex_first;
    GLsizei *tex_count;
    GLuint vao_sur, vbo_sur, prog_sur; /* the surroundings' triangles */
    GLsizei sur_count;                 /* their vertices */
    GLsizei index_count;
    uint32_t vertex_count;
    int have_colours;
    GLuint env_tex, thr_tex;
    GLuint prog_mesh, prog_bg, prog_bright, prog_blur, prog_final;
    uint32_t w, h, qw, qh;
    GLuint fbo_scene, tex_scene, rb_depth;
    GLuint fbo_q[2], tex_q[2];
    GLuint fbo_lin, tex_lin;
    float blur_w[VW_GLARE_RADIUS + 1];
    char renderer[256];
};

/* ---------------------------------------------------------------- shaders */

static const char *const vs_mesh =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec3 a_rgb;\n"
    "uniform mat4 u_mvp;\n"
    "out vec3 v_rgb;\n"
    "void main() { v_rgb = a_rgb; gl_Position = u_mvp * vec4(a_pos, 1.0); }\n";

static const char *const fs_mesh =
    "#version 330 core\n"
    "in vec3 v_rgb;\n"
    "out vec4 o;\n"
    "void main() { o = vec4(v_rgb, 1.0); }\n";

/* A textured triangle: hl_render_surface's pixel, base x texture x the
 * irradiance interpolated from the vertices (colour over albedo), the
 * positions and colours fetched by vertex from the mesh's buffers so that
 * moved bodies and every new frame's colours are followed. The texture is
 * sRGB (decoded before bilinear filtering, as the library's sampler
 * does), repeating, without mipmaps; v is flipped into GL's rows. */
static const char *const vs_tex =
    "#version 330 core\n"
    "layout(location = 0) in int a_vid;\n"
    "layout(location = 1) in vec2 a_uv;\n"
    "layout(location = 2) in vec3 a_base;\n"
    "layout(location = 3) in vec3 a_alb;\n"
    "uniform samplerBuffer u_pos;\n"
    "uniform samplerBuffer u_rgb;\n"
    "uniform mat4 u_mvp;\n"
    "out vec2 v_uv;\n"
    "out vec3 v_base, v_irr;\n"
    "void main() {\n"
    "  vec3 p = vec3(texelFetch(u_pos, 3 * a_vid).r, texelFetch(u_pos, 3 * a_vid + 1).r,\n"
    "                texelFetch(u_pos, 3 * a_vid + 2).r);\n"
    "  vec3 c = texelFetch(u_rgb, a_vid).rgb;\n"
    "  v_irr = vec3(a_alb.x > 1e-6 ? c.x / a_alb.x : 0.0, a_alb.y > 1e-6 ? c.y / a_alb.y : 0.0,\n"
    "               a_alb.z > 1e-6 ? c.z / a_alb.z : 0.0);\n"
    "  v_uv = vec2(a_uv.x, 1.0 - a_uv.y);\n"
    "  v_base = a_base;\n"
    "  gl_Position = u_mvp * vec4(p, 1.0);\n"
    "}\n";

static const char *const fs_tex =
    "#version 330 core\n"
    "uniform sampler2D u_tex;\n"
    "in vec2 v_uv;\n"
    "in vec3 v_base, v_irr;\n"
    "out vec4 o;\n"
    "void main() { o = vec4(max(v_base * texture(u_tex, v_uv).rgb * v_irr, 0.0), 1.0); }\n";

/* The surroundings: flat colours, each either radiance (an emitter, tone-
 * mapped like the mesh) or a display value (a dark body's grey, divided
 * by the exposure scale here so that the tone map gives it back). */
static const char *const vs_sur =
    "#version 330 core\n"
    "layout(location = 0) in vec3 a_pos;\n"
    "layout(location = 1) in vec3 a_rgb;\n"
    "layout(location = 2) in float a_display;\n"
    "uniform mat4 u_mvp;\n"
    "uniform float u_scale;\n"
    "flat out vec3 v_rgb;\n"
    "void main() {\n"
    "  v_rgb = a_display > 0.5 ? a_rgb / u_scale : a_rgb;\n"
    "  gl_Position = u_mvp * vec4(a_pos, 1.0);\n"
    "}\n";

static const char *const fs_sur =
    "#version 330 core\n"
    "flat in vec3 v_rgb;\n"
    "out vec4 o;\n"
    "void main() { o = vec4(v_rgb, 1.0); }\n";

/* A triangle covering the viewport, at the far plane (depth 1). */
static const char *const vs_full =
    "#version 330 core\n"
    "void main() {\n"
    "  vec2 p = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);\n"
    "  gl_Position = vec4(p, 1.0, 1.0);\n"
    "}\n";

/* The pixel's ray as hl_render shoots it, then docs/CONVENTIONS.md: u = 0.5 +
 * atan2(z, x) / 2pi + rotation / 360, v = acos(y) / pi, row 0 = +Y at
 * t = 0. Repeat along u and clamp along v is hl_env_query_smooth's
 * wrap across the seam and clamp at the poles. */
static const char *const fs_bg =
    "#version 330 core\n"
    "uniform sampler2D u_env;\n"
    "uniform vec3 u_fwd, u_right, u_up;\n"
    "uniform vec2 u_tan, u_size;\n"
    "uniform float u_rot;\n"
    "out vec4 o;\n"
    "const float PI = 3.14159265358979;\n"
    "void main() {\n"
    "  vec2 s = 2.0 * gl_FragCoord.xy / u_size - 1.0;\n"
    "  vec3 d = u_fwd + s.x * u_tan.x * u_right + s.y * u_tan.y * u_up;\n"
    "  float u = 0.5 + atan(d.z, d.x) / (2.0 * PI) + u_rot;\n"
    "  float v = acos(clamp(d.y / length(d), -1.0, 1.0)) / PI;\n"
    "  o = vec4(texture(u_env, vec2(u - floor(u), v)).rgb, 1.0);\n"
    "}\n";

/* Average over a 4 x 4 block of the excess above 1 after exposure. */
static const char *const fs_bright =
    "#version 330 core\n"
    "uniform sampler2D u_src;\n"
    "uniform float u_scale;\n"
    "out vec4 o;\n"
    "void main() {\n"
    "  ivec2 lim = textureSize(u_src, 0) - 1, base = ivec2(gl_FragCoord.xy) * 4;\n"
    "  vec3 acc = vec3(0.0);\n"
    "  for (int j = 0; j < 4; j++)\n"
    "    for (int i = 0; i < 4; i++)\n"
    "      acc += max(texelFetch(u_src, min(base + ivec2(i, j), lim), 0).rgb * u_scale - 1.0, 0.0);\n"
    "  o = vec4(acc / 16.0, 1.0);\n"
    "}\n";

static const char *const fs_blur =
    "#version 330 core\n"
    "#define R 9\n"
    "uniform sampler2D u_src;\n"
    "uniform ivec2 u_dir;\n"
    "uniform float u_w[R + 1];\n"
    "out vec4 o;\n"
    "void main() {\n"
    "  ivec2 lim = textureSize(u_src, 0) - 1, p = ivec2(gl_FragCoord.xy);\n"
    "  vec3 acc = u_w[0] * texelFetch(u_src, p, 0).rgb;\n"
    "  for (int k = 1; k <= R; k++)\n"
    "    acc += u_w[k] * (texelFetch(u_src, clamp(p + k * u_dir, ivec2(0), lim), 0).rgb +\n"
    "                     texelFetch(u_src, clamp(p - k * u_dir, ivec2(0), lim), 0).rgb);\n"
    "  o = vec4(acc, 1.0);\n"
    "}\n";

/* Composite, then either linear radiance out (screenshots) or the 8-bit
 * code that hl_tonemap_srgb8 gives. The sRGB curve in float only guesses
 * the code k (within one); u_thr holds, for each k, the least values that
 * give k and k + 1 (vw_tonemap_thresholds), and those decide, so the
 * result is the C function's, not this formula's. (A bisection over all
 * 255 thresholds would need 24 fetches a pixel: on llvmpipe, as much as
 * the rest of the frame.) */
static const char *const fs_final =
    "#version 330 core\n"
    "uniform sampler2D u_hdr, u_glare, u_thr;\n"
    "uniform float u_scale;\n"
    "uniform float u_gain;\n"
    "uniform int u_linear;\n"
    "out vec4 o;\n"
    "float code(float x) {\n"
    "  float e = clamp(x, 0.0, 1.0);\n"
    "  float y = e < 0.0031308 ? 12.92 * e : 1.055 * pow(e, 1.0 / 2.4) - 0.055;\n"
    "  int k = clamp(int(floor(y * 255.0 + 0.5)), 0, 255);\n"
    "  vec2 t = texelFetch(u_thr, ivec2(k, 0), 0).rg;\n"
    "  return float(clamp(k + int(x >= t.g) - int(x < t.r), 0, 255));\n"
    "}\n"
    "void main() {\n"
    "  vec3 c = texelFetch(u_hdr, ivec2(gl_FragCoord.xy), 0).rgb;\n"
    "  if (u_gain > 0.0) c += u_gain * texture(u_glare, gl_FragCoord.xy / (4.0 * vec2(textureSize(u_glare, 0)))).rgb / u_scale;\n"
    "  if (u_linear != 0) { o = vec4(c, 1.0); return; }\n"
    "  vec3 x = c * u_scale;\n"
    "  o = vec4(code(x.r), code(x.g), code(x.b), 255.0) / 255.0;\n"
    "}\n";

/* The compile or link status of a shader or program; on failure the log
 * goes to err. */
static int status_ok(GLuint obj, void (*get_iv)(GLuint, GLenum, GLint *), GLenum which,
                     void (*get_log)(GLuint, GLsizei, GLsizei *, GLchar *), const char *what, char *err,
                     size_t err_size)
{
    GLint ok = 0;
    get_iv(obj, which, &ok);
    if (ok) return 1;
    char log[2048] = "";
    get_log(obj, sizeof log, NULL, log);
    snprintf(err, err_size, "OpenGL: the %s shaders do not %s: %s", what,
             which == GL_COMPILE_STATUS ? "compile" : "link", log);
    return 0;
}

static GLuint compile(GLenum type, const char *src, const char *what, char *err, size_t err_size)
{
    GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    if (status_ok(s, glGetShaderiv, GL_COMPILE_STATUS, glGetShaderInfoLog, what, err, err_size)) return s;
    glDeleteShader(s);
    return 0;
}

static GLuint program(const char *vs, const char *fs, const char *what, char *err, size_t err_size)
{
    GLuint v = compile(GL_VERTEX_SHADER, vs, what, err, err_size);
    GLuint f = v ? compile(GL_FRAGMENT_SHADER, fs, what, err, err_size) : 0;
    if (!f) {
        glDeleteShader(v);
        return 0;
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    if (status_ok(p, glGetProgramiv, GL_LINK_STATUS, glGetProgramInfoLog, what, err, err_size)) return p;
    glDeleteProgram(p);
    return 0;
}

static GLint loc(GLuint prog, const char *name)
{
    return glGetUniformLocation(prog, name);
}

/* ---------------------------------------------------------------- targets */

static void float_texture(GLuint tex, GLenum internal, uint32_t w, uint32_t h, GLint filter)
{
    glBindTexture(GL_TEXTURE_2D, tex);
    glTexImage2D(GL_TEXTURE_2D, 0, (GLint)internal, (GLsizei)w, (GLsizei)h, 0, GL_RGBA, GL_FLOAT, NULL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filter);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filter);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

static int attach(GLuint fbo, GLuint tex, GLuint depth, const char *what, char *err, size_t err_size)
{
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex, 0);
    if (depth) glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    GLenum st = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    if (st != GL_FRAMEBUFFER_COMPLETE) {
        snprintf(err, err_size, "OpenGL: the %s render target is incomplete (status 0x%x)", what, (unsigned)st);
        return 0;
    }
    return 1;
}

int vw_gl_resize(vw_gl *g, uint32_t w, uint32_t h, char *err, size_t err_size)
{
    if (w < 1) w = 1;
    if (h < 1) h = 1;
    g->w = w;
    g->h = h;
    g->qw = (w + VW_GLARE_DOWN - 1) / VW_GLARE_DOWN;
    g->qh = (h + VW_GLARE_DOWN - 1) / VW_GLARE_DOWN;
    float_texture(g->tex_scene, GL_RGBA16F, w, h, GL_NEAREST);
    glBindRenderbuffer(GL_RENDERBUFFER, g->rb_depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, (GLsizei)w, (GLsizei)h);
    for (int i = 0; i < 2; i++) float_texture(g->tex_q[i], GL_RGBA16F, g->qw, g->qh, GL_LINEAR);
    float_texture(g->tex_lin, GL_RGBA32F, w, h, GL_NEAREST);
    return attach(g->fbo_scene, g->tex_scene, g->rb_depth, "scene", err, err_size) &&
           attach(g->fbo_q[0], g->tex_q[0], 0, "glare", err, err_size) &&
           attach(g->fbo_q[1], g->tex_q[1], 0, "glare", err, err_size) &&
           attach(g->fbo_lin, g->tex_lin, 0, "capture", err, err_size);
}

/* ---------------------------------------------------------------- setup */

int vw_gl_create(const hl_mesh *mesh, const float thr[256], vw_gl **out, char *err, size_t err_size)
{
    *out = NULL;
    vw_gl *g = calloc(1, sizeof *g);
    if (!g) {
        snprintf(err, err_size, "out of memory");
        return 0;
    }
    snprintf(g->renderer, sizeof g->renderer, "%s, OpenGL %s", (const char *)glGetString(GL_RENDERER),
             (const char *)glGetString(GL_VERSION));
    g->prog_mesh = program(vs_mesh, fs_mesh, "mesh", err, err_size);
    g->prog_bg = g->prog_mesh ? program(vs_full, fs_bg, "background", err, err_size) : 0;
    g->prog_bright = g->prog_bg ? program(vs_full, fs_bright, "bright-pass", err, err_size) : 0;
    g->prog_blur = g->prog_bright ? program(vs_full, fs_blur, "blur", err, err_size) : 0;
    g->prog_final = g->prog_blur ? program(vs_full, fs_final, "tone-map", err, err_size) : 0;
    g->prog_sur = g->prog_final ? program(vs_sur, fs_sur, "surroundings", err, err_size) : 0;
    g->prog_tex = g->prog_sur ? program(vs_tex, fs_tex, "textured mesh", err, err_size) : 0;
    if (!g->prog_tex) {
        vw_gl_destroy(g);
        return 0;
    }

    g->vertex_count = mesh->vertex_count;
    g->index_count = (GLsizei)(3 * (size_t)mesh->triangle_count);
    glGenVertexArrays(1, &g->vao);
    glGenVertexArrays(1, &g->empty_vao);
    glBindVertexArray(g->vao);
    glGenBuffers(1, &g->vbo_pos);
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo_pos);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(12 * (size_t)mesh->vertex_count), mesh->positions, GL_DYNAMIC_DRAW);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 12, NULL);
    glEnableVertexAttribArray(0);
    glGenBuffers(1, &g->vbo_rgb);
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo_rgb);
    /* 4 floats per vertex, the layout the dot products write, so that CL/GL
       interop and the read-back path (hl_relighter_run4) both fill it as is */
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(16 * (size_t)mesh->vertex_count), NULL, GL_STREAM_DRAW);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 16, NULL);
    glEnableVertexAttribArray(1);
    glGenBuffers(1, &g->ebo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g->ebo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(4 * (size_t)g->index_count), mesh->indices, GL_STATIC_DRAW);
    glBindVertexArray(0);

    glGenTextures(1, &g->env_tex);
    glGenTextures(1, &g->thr_tex);
    glBindTexture(GL_TEXTURE_2D, g->thr_tex);
    float pairs[2 * 256];
    for (int k = 0; k < 256; k++) {
        pairs[2 * k] = k ? thr[k] : -INFINITY;
        pairs[2 * k + 1] = k < 255 ? thr[k + 1] : INFINITY;
    }
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RG32F, 256, 1, 0, GL_RG, GL_FLOAT, pairs);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);

    glGenTextures(1, &g->tex_scene);
    glGenTextures(2, g->tex_q);
    glGenTextures(1, &g->tex_lin);
    glGenRenderbuffers(1, &g->rb_depth);
    glGenFramebuffers(1, &g->fbo_scene);
    glGenFramebuffers(2, g->fbo_q);
    glGenFramebuffers(1, &g->fbo_lin);

    double sum = 0.0, w[VW_GLARE_RADIUS + 1];
    for (int k = 0; k <= VW_GLARE_RADIUS; k++) {
        w[k] = exp(-0.5 * k * k / (VW_GLARE_SIGMA * VW_GLARE_SIGMA));
        sum += k ? 2.0 * w[k] : w[k];
    }
    for (int k = 0; k <= VW_GLARE_RADIUS; k++) g->blur_w[k] = (float)(w[k] / sum);

    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        snprintf(err, err_size, "OpenGL: error 0x%x while uploading the mesh (%u vertices)", (unsigned)e,
                 mesh->vertex_count);
        vw_gl_destroy(g);
        return 0;
    }
    *out = g;
    return 1;
}

void vw_gl_destroy(vw_gl *g)
{
    if (!g) return;
    GLuint progs[] = {g->prog_mesh, g->prog_bg, g->prog_bright, g->prog_blur, g->prog_final, g->prog_sur, g->prog_tex};
    for (size_t i = 0; i < sizeof progs / sizeof progs[0]; i++)
        if (progs[i]) glDeleteProgram(progs[i]);
    GLuint bufs[] = {g->vbo_pos, g->vbo_rgb, g->ebo, g->vbo_sur, g->vbo_tex};
    glDeleteBuffers(5, bufs);
    GLuint vaos[] = {g->vao, g->empty_vao, g->vao_sur, g->vao_tex};
    glDeleteVertexArrays(4, vaos);
    glDeleteTextures(2, g->tbo);
    if (g->tex_ids) glDeleteTextures((GLsizei)g->ntex, g->tex_ids);
    free(g->tex_ids);
    free(g->tex_first);
    free(g->tex_count);
    GLuint texs[] = {g->env_tex, g->thr_tex, g->tex_scene, g->tex_q[0], g->tex_q[1], g->tex_lin};
    glDeleteTextures(6, texs);
    glDeleteRenderbuffers(1, &g->rb_depth);
    GLuint fbos[] = {g->fbo_scene, g->fbo_q[0], g->fbo_q[1], g->fbo_lin};
    glDeleteFramebuffers(4, fbos);
    free(g);
}

const char *vw_gl_renderer(const vw_gl *g)
{
    return g->renderer;
}

int vw_gl_set_env(vw_gl *g, const hl_env *env, char *err, size_t err_size)
{
    GLint max = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max);
    if (env->width > (uint32_t)max) {
        snprintf(err, err_size, "environment %u x %u is wider than the OpenGL texture limit (%d)", env->width,
                 env->height, (int)max);
        return 0;
    }
    glBindTexture(GL_TEXTURE_2D, g->env_tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, (GLsizei)env->width, (GLsizei)env->height, 0, GL_RGB, GL_FLOAT, env->rgb);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        snprintf(err, err_size, "OpenGL: error 0x%x while uploading a %u x %u environment", (unsigned)e, env->width,
                 env->height);
        return 0;
    }
    return 1;
}

void vw_gl_upload_positions(vw_gl *g, const float *positions)
{
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo_pos);
    glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(12 * (size_t)g->vertex_count), positions);
}

void vw_gl_upload_colours(vw_gl *g, const float *vertex_rgba)
{
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo_rgb);
    glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(16 * (size_t)g->vertex_count), vertex_rgba);
    g->have_colours = 1;
}

int vw_gl_set_surroundings(vw_gl *g, const float *verts, uint32_t vertex_count, char *err, size_t err_size)
{
    const GLsizei stride = 7 * sizeof(float);
    if (!g->vao_sur) {
        glGenVertexArrays(1, &g->vao_sur);
        glGenBuffers(1, &g->vbo_sur);
        glBindVertexArray(g->vao_sur);
        glBindBuffer(GL_ARRAY_BUFFER, g->vbo_sur);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, NULL);
        glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride, (const void *)(3 * sizeof(float)));
        glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, stride, (const void *)(6 * sizeof(float)));
        for (GLuint a = 0; a < 3; a++) glEnableVertexAttribArray(a);
        glBindVertexArray(0);
    }
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo_sur);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)stride * vertex_count), verts, GL_DYNAMIC_DRAW);
    g->sur_count = (GLsizei)vertex_count;
    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        snprintf(err, err_size, "OpenGL: error 0x%x while uploading %u vertices of surroundings", (unsigned)e,
                 vertex_count);
        g->sur_count = 0;
        return 0;
    }
    return 1;
}

/* Texture k of su within max_side on both sides. */
static int fits(const hl_surface *su, uint32_t k, GLint max_side)
{
    uint32_t w = 0, h = 0;
    hl_surface_texture(su, k, &w, &h);
    return max_side > 0 && w <= (uint32_t)max_side && h <= (uint32_t)max_side;
}

int vw_gl_set_surface(vw_gl *g, const hl_mesh *mesh, const hl_surface *su, char *err, size_t err_size)
{
    const uint32_t nt = hl_surface_triangle_count(su), ntex = hl_surface_texture_count(su);
    if (!nt || !ntex) return 1; /* nothing textured: the colours as they are */
    /* what this GL can hold: a texture wider than it is drawn with the
       vertex colours, and so is everything when the positions' buffer
       texture would be longer than it allows (3 floats a vertex) */
    GLint max_tex = 0, max_tbo = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_tbo);
    if ((uint64_t)mesh->vertex_count * 3 > (uint64_t)(max_tbo > 0 ? max_tbo : 0)) {
        fprintf(stderr, "haarlight: warning: %u vertices exceed this OpenGL's buffer texture (%d texels): the textures "
                        "are not drawn, the vertex colours are\n", mesh->vertex_count, (int)max_tbo);
        return 1;
    }
    for (uint32_t k = 0; k < ntex; k++) {
        uint32_t w = 0, h = 0;
        hl_surface_texture(su, k, &w, &h);
        if (w > (uint32_t)max_tex || h > (uint32_t)max_tex)
            fprintf(stderr, "haarlight: warning: texture %u is %u x %u, more than this OpenGL's %d on a side: its "
                            "triangles show their vertex colours\n", k, w, h, (int)max_tex);
    }
    /* corners grouped by texture: vid (int), uv, base, albedo */
    enum { STRIDE = 4 + 8 * 4 };
    uint32_t *count = calloc(ntex, sizeof *count), textured = 0;
    if (!count) goto oom;
    for (uint32_t t = 0; t < nt; t++) {
        int32_t k;
        hl_surface_triangle(su, t, &k, NULL, NULL);
        if (k >= 0 && (uint32_t)k < ntex && fits(su, (uint32_t)k, max_tex)) count[k]++, textured++;
    }
    unsigned char *buf = malloc((size_t)textured * 3 * STRIDE + 1);
    uint32_t *plain = malloc(((size_t)mesh->triangle_count - textured) * 12 + 1);
    g->tex_first = calloc(ntex, sizeof *g->tex_first);
    g->tex_count = calloc(ntex, sizeof *g->tex_count);
    g->tex_ids = calloc(ntex, sizeof *g->tex_ids);
    if (!buf || !plain || !g->tex_first || !g->tex_count || !g->tex_ids) {
        free(buf);
        free(plain);
        free(count);
        goto oom;
    }
    for (uint32_t k = 0, at = 0; k < ntex; k++) {
        g->tex_first[k] = (GLint)at;
        g->tex_count[k] = (GLsizei)(3 * count[k]);
        at += 3 * count[k];
    }
    uint32_t *fill = calloc(ntex, sizeof *fill), np = 0;
    for (uint32_t t = 0; fill && t < mesh->triangle_count; t++) {
        int32_t k = -1;
        float uv[6], base[9];
        if (t < nt) hl_surface_triangle(su, t, &k, uv, base);
        if (k < 0 || (uint32_t)k >= ntex || !fits(su, (uint32_t)k, max_tex)) {
            memcpy(plain + 3 * (size_t)np++, mesh->indices + 3 * (size_t)t, 12);
            continue;
        }
        for (int c = 0; c < 3; c++) {
            const int32_t vid = (int32_t)mesh->indices[3 * (size_t)t + (size_t)c];
            float f[8] = {uv[2 * c], uv[2 * c + 1], base[3 * c], base[3 * c + 1], base[3 * c + 2]};
            memcpy(f + 5, mesh->albedo + 3 * (size_t)vid, 12);
            unsigned char *d = buf + (size_t)(g->tex_first[k] + (GLint)(3 * fill[k] + (uint32_t)c)) * STRIDE;
            memcpy(d, &vid, 4);
            memcpy(d + 4, f, sizeof f);
        }
        fill[k]++;
    }
    free(count);
    if (!fill) {
        free(buf);
        free(plain);
        goto oom;
    }
    free(fill);
    glGenVertexArrays(1, &g->vao_tex);
    glGenBuffers(1, &g->vbo_tex);
    glBindVertexArray(g->vao_tex);
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo_tex);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)((size_t)textured * 3 * STRIDE), buf, GL_STATIC_DRAW);
    glVertexAttribIPointer(0, 1, GL_INT, STRIDE, NULL);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, STRIDE, (const void *)4);
    glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, STRIDE, (const void *)12);
    glVertexAttribPointer(3, 3, GL_FLOAT, GL_FALSE, STRIDE, (const void *)24);
    for (GLuint a = 0; a < 4; a++) glEnableVertexAttribArray(a);
    glBindVertexArray(0);
    free(buf);
    /* the plain pass draws the rest */
    glBindVertexArray(g->vao);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g->ebo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(12 * (size_t)np), plain, GL_STATIC_DRAW);
    glBindVertexArray(0);
    g->index_count = (GLsizei)(3 * np);
    free(plain);
    glGenTextures(2, g->tbo);
    glBindTexture(GL_TEXTURE_BUFFER, g->tbo[0]);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_R32F, g->vbo_pos);
    glBindTexture(GL_TEXTURE_BUFFER, g->tbo[1]);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_RGBA32F, g->vbo_rgb);
    glGenTextures((GLsizei)ntex, g->tex_ids);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    for (uint32_t k = 0; k < ntex; k++) {
        uint32_t w = 0, h = 0;
        const uint8_t *px = hl_surface_texture(su, k, &w, &h);
        if (!fits(su, k, max_tex)) continue; /* its triangles are in the plain pass */
        glBindTexture(GL_TEXTURE_2D, g->tex_ids[k]);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_SRGB8, (GLsizei)w, (GLsizei)h, 0, GL_RGB, GL_UNSIGNED_BYTE, px);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    g->ntex = ntex;
    GLenum e = glGetError();
    if (e != GL_NO_ERROR) {
        snprintf(err, err_size,
                 "OpenGL: error 0x%x while uploading the textured surface (%u triangles, %u textures of the model)",
                 (unsigned)e, textured, ntex);
        return 0;
    }
    return 1;
oom:
    snprintf(err, err_size, "out of memory for the textured surface");
    return 0;
}

unsigned vw_gl_colour_buffer(const vw_gl *g) { return g->vbo_rgb; }

void vw_gl_finish(void) { glFinish(); }

void vw_gl_colours_written(vw_gl *g) { g->have_colours = 1; }

/* ---------------------------------------------------------------- frame */

static void bind_texture(GLuint unit, GLuint tex)
{
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(GL_TEXTURE_2D, tex);
}

static void full_screen(vw_gl *g)
{
    glBindVertexArray(g->empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
}

static void draw_scene(vw_gl *g, const vw_frame *f)
{
    glBindFramebuffer(GL_FRAMEBUFFER, g->fbo_scene);
    glViewport(0, 0, (GLsizei)g->w, (GLsizei)g->h);
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_LESS);
    if (g->have_colours) {
        glUseProgram(g->prog_mesh);
        glUniformMatrix4fv(loc(g->prog_mesh, "u_mvp"), 1, GL_FALSE, f->mvp);
        glBindVertexArray(g->vao);
        glDrawElements(GL_TRIANGLES, g->index_count, GL_UNSIGNED_INT, NULL);
    }
    if (g->have_colours && g->ntex) {
        GLuint p = g->prog_tex;
        glUseProgram(p);
        glUniformMatrix4fv(loc(p, "u_mvp"), 1, GL_FALSE, f->mvp);
        glActiveTexture(GL_TEXTURE1);
        glBindTexture(GL_TEXTURE_BUFFER, g->tbo[0]);
        glActiveTexture(GL_TEXTURE2);
        glBindTexture(GL_TEXTURE_BUFFER, g->tbo[1]);
        glUniform1i(loc(p, "u_pos"), 1);
        glUniform1i(loc(p, "u_rgb"), 2);
        glUniform1i(loc(p, "u_tex"), 3);
        glBindVertexArray(g->vao_tex);
        for (uint32_t k = 0; k < g->ntex; k++) {
            if (!g->tex_count[k]) continue;
            bind_texture(3, g->tex_ids[k]);
            glDrawArrays(GL_TRIANGLES, g->tex_first[k], g->tex_count[k]);
        }
        glActiveTexture(GL_TEXTURE0);
    }
    if (f->surroundings && g->sur_count) {
        glUseProgram(g->prog_sur);
        glUniformMatrix4fv(loc(g->prog_sur, "u_mvp"), 1, GL_FALSE, f->mvp);
        glUniform1f(loc(g->prog_sur, "u_scale"), (float)exp2((double)f->exposure_ev));
        glBindVertexArray(g->vao_sur);
        glDrawArrays(GL_TRIANGLES, 0, g->sur_count);
    }
    /* the background only where no triangle was drawn */
    glDepthFunc(GL_LEQUAL);
    glDepthMask(GL_FALSE);
    GLuint p = g->prog_bg;
    glUseProgram(p);
    bind_texture(0, g->env_tex);
    glUniform1i(loc(p, "u_env"), 0);
    glUniform3fv(loc(p, "u_fwd"), 1, f->view.forward);
    glUniform3fv(loc(p, "u_right"), 1, f->view.right);
    glUniform3fv(loc(p, "u_up"), 1, f->view.up);
    glUniform2f(loc(p, "u_tan"), f->view.tan_half_x, f->view.tan_half_y);
    glUniform2f(loc(p, "u_size"), (float)g->w, (float)g->h);
    glUniform1f(loc(p, "u_rot"), (float)fmod((double)f->rotate_deg / 360.0, 1.0));
    full_screen(g);
    glDepthMask(GL_TRUE);
    glDisable(GL_DEPTH_TEST);
}

static void draw_glare(vw_gl *g, float scale)
{
    glViewport(0, 0, (GLsizei)g->qw, (GLsizei)g->qh);
    glBindFramebuffer(GL_FRAMEBUFFER, g->fbo_q[0]);
    glUseProgram(g->prog_bright);
    bind_texture(0, g->tex_scene);
    glUniform1i(loc(g->prog_bright, "u_src"), 0);
    glUniform1f(loc(g->prog_bright, "u_scale"), scale);
    full_screen(g);
    glUseProgram(g->prog_blur);
    glUniform1i(loc(g->prog_blur, "u_src"), 0);
    glUniform1fv(loc(g->prog_blur, "u_w"), VW_GLARE_RADIUS + 1, g->blur_w);
    for (int pass = 0; pass < 2; pass++) { /* horizontal into q[1], vertical back into q[0] */
        glBindFramebuffer(GL_FRAMEBUFFER, g->fbo_q[1 - pass]);
        bind_texture(0, g->tex_q[pass]);
        glUniform2i(loc(g->prog_blur, "u_dir"), pass == 0, pass == 1);
        full_screen(g);
    }
}

static void draw_final(vw_gl *g, const vw_frame *f, GLuint fbo, int linear)
{
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, (GLsizei)g->w, (GLsizei)g->h);
    GLuint p = g->prog_final;
    glUseProgram(p);
    bind_texture(0, g->tex_scene);
    bind_texture(1, g->tex_q[0]);
    bind_texture(2, g->thr_tex);
    glUniform1i(loc(p, "u_hdr"), 0);
    glUniform1i(loc(p, "u_glare"), 1);
    glUniform1i(loc(p, "u_thr"), 2);
    glUniform1f(loc(p, "u_scale"), (float)exp2((double)f->exposure_ev));
    glUniform1f(loc(p, "u_gain"), f->glare ? VW_GLARE_GAIN : 0.0f);
    glUniform1i(loc(p, "u_linear"), linear);
    full_screen(g);
    glActiveTexture(GL_TEXTURE0);
}

void vw_gl_draw(vw_gl *g, const vw_frame *f)
{
    draw_scene(g, f);
    if (f->glare) draw_glare(g, (float)exp2((double)f->exposure_ev));
    draw_final(g, f, 0, 0);
    glFinish();
}

int vw_gl_read(vw_gl *g, const vw_frame *f, float *rgb, uint8_t *srgb8, char *err, size_t err_size)
{
    size_t n = (size_t)g->w * g->h;
    float *px = malloc(4 * n * sizeof *px);
    uint8_t *b8 = srgb8 ? malloc(4 * n) : NULL;
    if (!px || (srgb8 && !b8)) {
        free(px);
        free(b8);
        snprintf(err, err_size, "out of memory for a %u x %u capture", g->w, g->h);
        return 0;
    }
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    if (b8) { /* the window's back buffer as drawn by vw_gl_draw */
        glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
        glReadBuffer(GL_BACK);
        glReadPixels(0, 0, (GLsizei)g->w, (GLsizei)g->h, GL_RGBA, GL_UNSIGNED_BYTE, b8);
    }
    draw_final(g, f, g->fbo_lin, 1);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, g->fbo_lin);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glReadPixels(0, 0, (GLsizei)g->w, (GLsizei)g->h, GL_RGBA, GL_FLOAT, px);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    GLenum e = glGetError();
    for (uint32_t y = 0; y < g->h; y++) { /* OpenGL rows go up, images' rows down */
        const float *src = px + 4 * (size_t)(g->h - 1 - y) * g->w;
        const uint8_t *s8 = b8 ? b8 + 4 * (size_t)(g->h - 1 - y) * g->w : NULL;
        for (uint32_t x = 0; x < g->w; x++)
            for (int c = 0; c < 3; c++) {
                rgb[3 * ((size_t)y * g->w + x) + c] = src[4 * (size_t)x + c];
                if (s8) srgb8[3 * ((size_t)y * g->w + x) + c] = s8[4 * (size_t)x + c];
            }
    }
    free(px);
    free(b8);
    if (e != GL_NO_ERROR) {
        snprintf(err, err_size, "OpenGL: error 0x%x while reading the frame back", (unsigned)e);
        return 0;
    }
    return 1;
}
