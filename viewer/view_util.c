/* view_util.c - the viewer's helpers that need neither OpenGL nor GLFW:
 * the tone-map table, camera maths, mouse rays against triangles, the
 * colour feed decision, file names.
 *
 * Dependencies: haarlight.h (hl_tonemap_srgb8,
 * hl_context_*), libc, libm, POSIX (access).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "viewer.h"

#define VW_PI 3.14159265358979323846

/* ---------------------------------------------------------------- tone map */

void vw_tonemap_thresholds(float thr[256])
{
    thr[0] = 0.0f;
    /* hl_tonemap_srgb8 is monotonic in x, and positive floats order like
     * their bit patterns: bisect on the bits for each code's first value. */
    for (int k = 1; k < 256; k++) {
        uint32_t lo = 0, hi = 0x3f800000u; /* 0 .. 1.0f, where the code is 255 */
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo) / 2;
            float x;
            memcpy(&x, &mid, sizeof x);
            if (hl_tonemap_srgb8(x, 0.0f) >= k) hi = mid;
            else lo = mid + 1;
        }
        memcpy(&thr[k], &lo, sizeof lo);
    }
}

/* ---------------------------------------------------------------- camera */

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static int normalise3(double a[3])
{
    double l = sqrt(dot3(a, a));
    if (!(l > 0.0) || !isfinite(l)) return 0;
    for (int k = 0; k < 3; k++) a[k] /= l;
    return 1;
}

/* Rodrigues: v turned by angle about the unit axis a. */
static void rotate3(double v[3], const double a[3], double angle)
{
    double c = cos(angle), s = sin(angle), axv[3], d = dot3(a, v);
    cross3(a, v, axv);
    for (int k = 0; k < 3; k++) v[k] = v[k] * c + axv[k] * s + a[k] * d * (1.0 - c);
}

void vw_mesh_bounds(const hl_mesh *mesh, float centre[3], float *radius)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < mesh->vertex_count; i++)
        for (int k = 0; k < 3; k++) {
            double p = mesh->positions[3 * (size_t)i + k];
            lo[k] = p < lo[k] ? p : lo[k];
            hi[k] = p > hi[k] ? p : hi[k];
        }
    double c[3], r2 = 0.0;
    for (int k = 0; k < 3; k++) c[k] = 0.5 * (lo[k] + hi[k]);
    for (uint32_t i = 0; i < mesh->vertex_count; i++) {
        double d[3];
        for (int k = 0; k < 3; k++) d[k] = mesh->positions[3 * (size_t)i + k] - c[k];
        double q = dot3(d, d);
        r2 = q > r2 ? q : r2;
    }
    for (int k = 0; k < 3; k++) centre[k] = (float)c[k];
    *radius = r2 > 0.0 ? (float)sqrt(r2) : 1.0f;
}

void vw_camera_matrix(const hl_camera_view *v, const float centre[3], float radius, float mvp[16])
{
    double e[3], ax[3][3], d[3];
    for (int k = 0; k < 3; k++) {
        e[k] = v->eye[k];
        ax[0][k] = v->right[k];
        ax[1][k] = v->up[k];
        ax[2][k] = -(double)v->forward[k]; /* eye space looks down -z */
        d[k] = e[k] - centre[k];
    }
    /* The depth range just holds the bounding sphere; a 32-bit float depth
     * buffer keeps a 1e-5 near/far ratio precise. */
    double dist = sqrt(dot3(d, d)), far = 1.01 * (dist + radius), near = 0.99 * (dist - radius);
    if (near < 1e-5 * far) near = 1e-5 * far;
    double view[4][4] = {{0}}; /* row-major */
    for (int r = 0; r < 3; r++) {
        for (int k = 0; k < 3; k++) view[r][k] = ax[r][k];
        view[r][3] = -dot3(ax[r], e);
    }
    view[3][3] = 1.0;
    double proj[4][4] = {{0}};
    proj[0][0] = 1.0 / v->tan_half_x;
    proj[1][1] = 1.0 / v->tan_half_y;
    proj[2][2] = (far + near) / (near - far);
    proj[2][3] = 2.0 * far * near / (near - far);
    proj[3][2] = -1.0;
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) {
            double s = 0.0;
            for (int k = 0; k < 4; k++) s += proj[r][k] * view[k][c];
            mvp[c * 4 + r] = (float)s; /* column-major for OpenGL */
        }
}

void vw_orbit(float eye[3], const float target[3], const float up[3], double yaw, double pitch)
{
    double o[3], u[3] = {up[0], up[1], up[2]};
    for (int k = 0; k < 3; k++) o[k] = (double)eye[k] - target[k];
    if (!normalise3(u)) {
        u[0] = 0.0;
        u[1] = 1.0;
        u[2] = 0.0;
    }
    rotate3(o, u, yaw);
    double f[3] = {-o[0], -o[1], -o[2]}, r[3], p[3] = {o[0], o[1], o[2]};
    cross3(f, u, r);
    if (normalise3(r)) {
        rotate3(p, r, pitch);
        double pn[3] = {p[0], p[1], p[2]};
        /* within 2 degrees of the up axis the picture's roll would flip */
        if (normalise3(pn) && fabs(dot3(pn, u)) < cos(2.0 * VW_PI / 180.0))
            for (int k = 0; k < 3; k++) o[k] = p[k];
    }
    for (int k = 0; k < 3; k++) eye[k] = (float)(target[k] + o[k]);
}

void vw_zoom(float eye[3], const float target[3], double factor, double min_distance)
{
    double o[3];
    for (int k = 0; k < 3; k++) o[k] = (double)eye[k] - target[k];
    double d = sqrt(dot3(o, o)), want = d * factor;
    if (!(d > 0.0)) return;
    if (want < min_distance) want = min_distance;
    for (int k = 0; k < 3; k++) eye[k] = (float)(target[k] + o[k] * want / d);
}

/* ---------------------------------------------------------------- mouse rays */

void vw_pixel_ray(const hl_camera_view *cv, double x, double y, double w, double h, double dir[3])
{
    /* the pixel's centre in [-1, 1], +y up as the background shader's */
    double sx = 2.0 * x / w - 1.0, sy = 1.0 - 2.0 * y / h;
    for (int k = 0; k < 3; k++)
        dir[k] = cv->forward[k] + sx * cv->tan_half_x * cv->right[k] + sy * cv->tan_half_y * cv->up[k];
}

/* Moeller-Trumbore, in double. */
double vw_ray_triangle(const double o[3], const double d[3], const float *a, const float *b, const float *c)
{
    double e1[3], e2[3], p[3], s[3], q[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = (double)b[k] - a[k];
        e2[k] = (double)c[k] - a[k];
        s[k] = o[k] - a[k];
    }
    cross3(d, e2, p);
    double det = dot3(e1, p);
    if (fabs(det) < 1e-300) return -1.0; /* parallel to the plane */
    double u = dot3(s, p) / det;
    if (u < 0.0 || u > 1.0) return -1.0;
    cross3(s, e1, q);
    double w = dot3(d, q) / det;
    if (w < 0.0 || u + w > 1.0) return -1.0;
    double t = dot3(e2, q) / det;
    return t > 0.0 ? t : -1.0;
}

/* The plane y = grab.y; rays closer than this to parallel with it
 * (|dir.y| / |dir|) move nothing, since the meeting point runs off to
 * infinity. */
#define VW_DRAG_MIN_SLOPE 1e-4

int vw_drag_delta(const hl_camera_view *cv, double x, double y, double w, double h, const float grab[3],
                  double most, double delta[3])
{
    double o[3] = {cv->eye[0], cv->eye[1], cv->eye[2]}, d[3];
    vw_pixel_ray(cv, x, y, w, h, d);
    double len = sqrt(dot3(d, d));
    if (!(fabs(d[1]) > VW_DRAG_MIN_SLOPE * len)) return 0;
    double s = ((double)grab[1] - o[1]) / d[1];
    if (!(s > 0.0)) return 0; /* the plane is behind the eye along this ray */
    for (int k = 0; k < 3; k++) delta[k] = k == 1 ? 0.0 : o[k] + s * d[k] - grab[k];
    double dist = sqrt(delta[0] * delta[0] + delta[2] * delta[2]);
    if (dist > most)
        for (int k = 0; k < 3; k += 2) delta[k] *= most / dist;
    return 1;
}

void vw_sphere_union(const float c0[3], float r0, const float c1[3], float r1, float c[3], float *r)
{
    double d[3];
    for (int k = 0; k < 3; k++) d[k] = (double)c1[k] - c0[k];
    double dist = sqrt(dot3(d, d));
    if (dist + r1 <= r0) { /* the second lies inside the first */
        memcpy(c, c0, 3 * sizeof *c);
        *r = r0;
        return;
    }
    if (dist + r0 <= r1) {
        memcpy(c, c1, 3 * sizeof *c);
        *r = r1;
        return;
    }
    double R = 0.5 * (dist + r0 + r1), t = (R - r0) / dist; /* dist > 0 here */
    for (int k = 0; k < 3; k++) c[k] = (float)(c0[k] + t * d[k]);
    *r = (float)R;
}

/* ---------------------------------------------------------------- colour feed */

/* With cl_khr_gl_sharing the dot products write straight into the GL
 * colour buffer (view.c sets that up once the window exists); otherwise
 * the colours are read back to the host and uploaded. Only a device that
 * lists the extension is ever asked to share: PoCL's clCreateFromGLBuffer,
 * for one, aborts the process. */
int vw_feed_mode(hl_context *ctx, int readback_asked, char *buf, size_t size)
{
    if (hl_context_backend(ctx) == HL_BACKEND_REFERENCE)
        snprintf(buf, size, "readback (reference backend: colours computed on the host)");
    else if (!hl_context_device_has_extension(ctx, "cl_khr_gl_sharing"))
        snprintf(buf, size, "readback (device has no cl_khr_gl_sharing)");
    else if (readback_asked)
        snprintf(buf, size, "readback (--readback given)");
    else {
        snprintf(buf, size, "GL interop (cl_khr_gl_sharing)");
        return 1;
    }
    return 0;
}

/* ---------------------------------------------------------------- files */

void vw_screenshot_name(char *buf, size_t size)
{
    for (int i = 1; i < 100000; i++) {
        snprintf(buf, size, "haarlight-view-%03d.png", i);
        if (access(buf, F_OK) != 0) return;
    }
}

const char *vw_base_name(const char *path)
{
    const char *s = strrchr(path, '/');
    return s ? s + 1 : path;
}
