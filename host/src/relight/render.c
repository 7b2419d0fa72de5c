/* render.c - pictures of a coloured mesh from Embree primary rays.
 *
 * hl_render shoots one ray through the centre of every pixel of a pinhole
 * camera (vertical field of view, image row 0 at the top; no
 * supersampling, so a constant-coloured mesh gives exactly that colour).
 * A hit shows the vertex colours interpolated with the hit's barycentrics;
 * a miss shows the environment (or black). With eye and target both zero
 * the camera frames the object (the ground plane excluded) by itself.
 *
 * With a textured surface (hl_render_surface), a pixel of a textured
 * triangle shows the texture's albedo there times the interpolated
 * irradiance instead.
 *
 * Dependencies: hl_internal.h (errors, allocation), material.h (the
 * surface and its sampler), rays.h (Embree scene
 * and primary rays), the environment and image functions of haarlight.h,
 * libc, libm.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "hl_internal.h"
#include "material.h"
#include "rays.h"

/* Defaults listed in haarlight.h above hl_camera_desc. */
#define HL_CAM_DEFAULT_WIDTH 960u
#define HL_CAM_DEFAULT_HEIGHT 720u
#define HL_CAM_DEFAULT_FOV 35.0
#define HL_CAM_MAX_SIDE 16384u
/* Automatic framing: elevation of the eye above the object's centre, and
 * the margin around the object's bounding sphere. */
#define HL_CAM_AUTO_ELEVATION_DEG 20.0
#define HL_CAM_AUTO_MARGIN 1.1
/* Rays traced per call of hl_rt_trace_primary: bounds the scratch memory
 * whatever the image size. */
#define HL_RENDER_CHUNK (1u << 18)

typedef struct cam {
    uint32_t width, height;
    double eye[3];
    double fwd[3], right[3], up[3]; /* unit, right-handed: right = fwd x up */
    double tan_half_v, tan_half_h;
} cam;

static int finite3(const float v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static int zero3(const float v[3])
{
    return v[0] == 0.0f && v[1] == 0.0f && v[2] == 0.0f;
}

static void cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static double norm(const double a[3])
{
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

/* Eye and target that frame vertices [0, object_vertex_count). */
static void auto_frame(const hl_mesh *mesh, double tan_half_v, double tan_half_h, double eye[3],
                       double target[3])
{
    uint32_t n = mesh->object_vertex_count;
    if (n == 0 || n > mesh->vertex_count) n = mesh->vertex_count;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            double p = mesh->positions[3 * (size_t)i + k];
            if (p < lo[k]) lo[k] = p;
            if (p > hi[k]) hi[k] = p;
        }
    double radius = 0.0;
    for (int k = 0; k < 3; k++) target[k] = 0.5 * (lo[k] + hi[k]);
    for (uint32_t i = 0; i < n; i++) {
        double d[3];
        for (int k = 0; k < 3; k++) d[k] = mesh->positions[3 * (size_t)i + k] - target[k];
        double r = norm(d);
        if (r > radius) radius = r;
    }
    if (!(radius > 0.0)) radius = 1.0; /* a single point: any scale will do */
    /* A sphere of radius R at distance D fills a cone of half-angle asin(R/D). */
    double half_v = atan(tan_half_v), half_h = atan(tan_half_h);
    double half = half_v < half_h ? half_v : half_h;
    double dist = HL_CAM_AUTO_MARGIN * radius / sin(half);
    double el = HL_CAM_AUTO_ELEVATION_DEG * HL_PI / 180.0;
    eye[0] = target[0];
    eye[1] = target[1] + dist * sin(el);
    eye[2] = target[2] + dist * cos(el);
}

static hl_result setup_camera(hl_context *ctx, const hl_mesh *mesh, const hl_camera_desc *desc,
                              cam *c)
{
    hl_camera_desc d;
    memset(&d, 0, sizeof d);
    if (desc) d = *desc;
    c->width = d.width ? d.width : HL_CAM_DEFAULT_WIDTH;
    c->height = d.height ? d.height : HL_CAM_DEFAULT_HEIGHT;
    if (c->width > HL_CAM_MAX_SIDE || c->height > HL_CAM_MAX_SIDE)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "render: image size %u x %u is too large (at most %u pixels a side)", c->width,
                       c->height, HL_CAM_MAX_SIDE);
    double fov = d.fov_deg == 0.0f ? HL_CAM_DEFAULT_FOV : (double)d.fov_deg;
    if (!isfinite(fov) || fov <= 0.0 || fov >= 180.0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "render: vertical field of view %g degrees is not in (0, 180)", fov);
    if (!finite3(d.eye) || !finite3(d.target) || !finite3(d.up))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "render: camera eye (%g, %g, %g), target (%g, %g, %g) or up (%g, %g, %g) is not finite",
                       (double)d.eye[0], (double)d.eye[1], (double)d.eye[2], (double)d.target[0],
                       (double)d.target[1], (double)d.target[2], (double)d.up[0], (double)d.up[1],
                       (double)d.up[2]);
    c->tan_half_v = tan(0.5 * fov * HL_PI / 180.0);
    c->tan_half_h = c->tan_half_v * (double)c->width / (double)c->height;

    double eye[3], target[3], up[3];
    if (zero3(d.eye) && zero3(d.target)) {
        auto_frame(mesh, c->tan_half_v, c->tan_half_h, eye, target);
    } else {
        for (int k = 0; k < 3; k++) {
            eye[k] = d.eye[k];
            target[k] = d.target[k];
        }
    }
    if (zero3(d.up)) {
        up[0] = 0.0;
        up[1] = 1.0;
        up[2] = 0.0;
    } else {
        for (int k = 0; k < 3; k++) up[k] = d.up[k];
    }

    double f[3] = {target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]};
    double fl = norm(f);
    if (!(fl > 0.0) || !isfinite(fl))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "render: camera eye and target are the same point (%g, %g, %g)", eye[0], eye[1],
                       eye[2]);
    double ul = norm(up);
    if (!isfinite(ul))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "render: camera up vector is too large");
    for (int k = 0; k < 3; k++) {
        f[k] /= fl;
        up[k] /= ul;
    }
    double r[3];
    cross(f, up, r);
    double rl = norm(r);
    /* sin of the angle between up and the view direction: below about a
     * thousandth of a degree the picture's roll is meaningless. */
    if (!(rl > 1e-5))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "render: camera up (%g, %g, %g) is parallel to the view direction (%g, %g, %g)",
                       up[0], up[1], up[2], f[0], f[1], f[2]);
    for (int k = 0; k < 3; k++) r[k] /= rl;
    double u[3];
    cross(r, f, u);
    for (int k = 0; k < 3; k++) {
        c->eye[k] = eye[k];
        c->fwd[k] = f[k];
        c->right[k] = r[k];
        c->up[k] = u[k];
    }
    return HL_OK;
}

/* Direction of the ray through the centre of pixel (x, y), not unit. */
static void pixel_dir(const cam *c, uint32_t x, uint32_t y, float dir[3])
{
    double sx = (2.0 * ((double)x + 0.5) / (double)c->width - 1.0) * c->tan_half_h;
    double sy = (1.0 - 2.0 * ((double)y + 0.5) / (double)c->height) * c->tan_half_v;
    for (int k = 0; k < 3; k++) dir[k] = (float)(c->fwd[k] + sx * c->right[k] + sy * c->up[k]);
}

static hl_result check_inputs(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                              const hl_env *background, float rotate_deg)
{
    if (!mesh) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "render: mesh is NULL");
    if (!vertex_rgb) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "render: vertex colours are NULL");
    if (mesh->vertex_count == 0 || mesh->triangle_count == 0 || !mesh->positions || !mesh->indices)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "render: mesh is empty (%u vertices, %u triangles) or has no arrays",
                       mesh->vertex_count, mesh->triangle_count);
    if (mesh->object_vertex_count > mesh->vertex_count)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "render: mesh has %u object vertices but only %u vertices",
                       mesh->object_vertex_count, mesh->vertex_count);
    for (size_t i = 0; i < 3 * (size_t)mesh->triangle_count; i++)
        if (mesh->indices[i] >= mesh->vertex_count)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "render: triangle %zu refers to vertex %u of %u", i / 3, mesh->indices[i],
                           mesh->vertex_count);
    for (size_t i = 0; i < 3 * (size_t)mesh->vertex_count; i++)
        if (!isfinite(mesh->positions[i]))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "render: vertex %zu (counting from 0) has a non-finite position", i / 3);
    for (size_t i = 0; i < 3 * (size_t)mesh->vertex_count; i++)
        if (!isfinite(vertex_rgb[i]))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "render: colour of vertex %zu (counting from 0) is not finite (channel %zu = %g)",
                           i / 3, i % 3, (double)vertex_rgb[i]);
    if (background && (!background->rgb || background->width == 0 || background->height == 0))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "render: background environment has no pixels");
    if (!isfinite(rotate_deg))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "render: environment rotation %g is not finite",
                       (double)rotate_deg);
    return HL_OK;
}

/* A pixel on a textured triangle t at barycentrics (u, v): the albedo
 * there times the irradiance interpolated from the vertices. A vertex
 * whose albedo is zero in a channel gives no irradiance in it (its colour
 * there is zero whatever the light). */
static void shade_textured(const hl_mesh *mesh, const float *vertex_rgb, const hl_surface *su, uint32_t t, float u,
                           float v, float px[3])
{
    const uint32_t *tri = mesh->indices + 3 * (size_t)t;
    const float l[3] = {1.0f - u - v, u, v};
    float tc[2] = {0, 0}, base[3] = {0, 0, 0}, tex[3];
    double irr[3] = {0, 0, 0}; /* a huge colour over a tiny albedo stays finite */
    for (int c = 0; c < 3; c++) {
        tc[0] += l[c] * su->uv[6 * (size_t)t + 2 * (size_t)c];
        tc[1] += l[c] * su->uv[6 * (size_t)t + 2 * (size_t)c + 1];
        for (int k = 0; k < 3; k++) {
            base[k] += l[c] * su->base[9 * (size_t)t + 3 * (size_t)c + (size_t)k];
            const double a = mesh->albedo[3 * (size_t)tri[c] + (size_t)k];
            if (a > 1e-6) irr[k] += l[c] * vertex_rgb[3 * (size_t)tri[c] + (size_t)k] / a;
        }
    }
    hl_texture_sample_(&su->mats.tex[su->tex[t]], tc[0], tc[1], tex);
    for (int k = 0; k < 3; k++) {
        const double x = (double)base[k] * tex[k] * irr[k];
        /* rounding of 1 - u - v must not make light negative */
        px[k] = x > 0.0 ? (float)fmin(x, FLT_MAX) : 0.0f;
    }
}

hl_result hl_render(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                    const hl_env *background, float rotate_deg, const hl_camera_desc *camera,
                    hl_image **out)
{
    return hl_render_surface(ctx, mesh, vertex_rgb, NULL, background, rotate_deg, camera, out);
}

hl_result hl_render_surface(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb, const hl_surface *surface,
                            const hl_env *background, float rotate_deg, const hl_camera_desc *camera, hl_image **out)
{
    if (out) *out = NULL;
    if (!ctx) return HL_ERR_INVALID_ARGUMENT;
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "render: no output image pointer given");
    hl_result r = check_inputs(ctx, mesh, vertex_rgb, background, rotate_deg);
    if (r != HL_OK) return r;
    if (surface && (surface->triangle_count > mesh->triangle_count || !mesh->albedo))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "render: the textured surface (%u triangles) is not this mesh's (%u)",
                       surface->triangle_count, mesh->triangle_count);
    cam c;
    memset(&c, 0, sizeof c);
    r = setup_camera(ctx, mesh, camera, &c);
    if (r != HL_OK) return r;

    size_t npix = (size_t)c.width * c.height;
    uint32_t chunk = npix < HL_RENDER_CHUNK ? (uint32_t)npix : HL_RENDER_CHUNK;
    hl_image *img = NULL;
    hl_rt *rt = NULL;
    float *org = NULL, *dir = NULL, *bu = NULL, *bv = NULL;
    uint32_t *prim = NULL;

    r = hl_image_create(ctx, c.width, c.height, &img);
    if (r != HL_OK) goto done;
    org = hl_malloc(ctx, (size_t)chunk * 3 * sizeof(float), "render ray origins");
    dir = org ? hl_malloc(ctx, (size_t)chunk * 3 * sizeof(float), "render ray directions") : NULL;
    bu = dir ? hl_malloc(ctx, (size_t)chunk * sizeof(float), "render hit barycentrics") : NULL;
    bv = bu ? hl_malloc(ctx, (size_t)chunk * sizeof(float), "render hit barycentrics") : NULL;
    prim = bv ? hl_malloc(ctx, (size_t)chunk * sizeof(uint32_t), "render hit triangles") : NULL;
    if (!prim) {
        r = HL_ERR_OUT_OF_MEMORY;
        goto done;
    }
    r = hl_rt_create(ctx, mesh, &rt);
    if (r != HL_OK) goto done;

    float eye[3] = {(float)c.eye[0], (float)c.eye[1], (float)c.eye[2]};
    for (size_t first = 0; first < npix; first += chunk) {
        if (hl_context_cancelled(ctx)) {
            r = hl_fail(ctx, HL_ERR_INTERRUPTED, "render: interrupted");
            goto done;
        }
        uint32_t n = npix - first < chunk ? (uint32_t)(npix - first) : chunk;
        for (uint32_t i = 0; i < n; i++) {
            size_t p = first + i;
            memcpy(org + 3 * (size_t)i, eye, sizeof eye);
            pixel_dir(&c, (uint32_t)(p % c.width), (uint32_t)(p / c.width), dir + 3 * (size_t)i);
        }
        r = hl_rt_trace_primary(rt, n, org, dir, prim, bu, bv);
        if (r != HL_OK) goto done;
        for (uint32_t i = 0; i < n; i++) {
            float *px = img->rgb + 3 * (first + i);
            if (prim[i] == UINT32_MAX || prim[i] >= mesh->triangle_count) {
                if (background) {
                    if (camera && camera->nearest_background) hl_env_query(background, dir + 3 * (size_t)i, rotate_deg, px);
                    else hl_env_query_smooth(background, dir + 3 * (size_t)i, rotate_deg, px);
                } else {
                    px[0] = px[1] = px[2] = 0.0f;
                }
                continue;
            }
            if (surface && prim[i] < surface->triangle_count && surface->tex[prim[i]] >= 0) {
                shade_textured(mesh, vertex_rgb, surface, prim[i], bu[i], bv[i], px);
                continue;
            }
            const uint32_t *tri = mesh->indices + 3 * (size_t)prim[i];
            const float *c0 = vertex_rgb + 3 * (size_t)tri[0];
            const float *c1 = vertex_rgb + 3 * (size_t)tri[1];
            const float *c2 = vertex_rgb + 3 * (size_t)tri[2];
            /* c0 + u (c1 - c0) + v (c2 - c0) = (1-u-v) c0 + u c1 + v c2,
             * written so that equal corner colours come out exactly. */
            float u = bu[i], v = bv[i];
            for (int k = 0; k < 3; k++) px[k] = c0[k] + u * (c1[k] - c0[k]) + v * (c2[k] - c0[k]);
        }
    }
    *out = img;
    img = NULL;
    r = HL_OK;

done:
    hl_rt_destroy(rt);
    free(org);
    free(dir);
    free(bu);
    free(bv);
    free(prim);
    hl_image_destroy(img);
    return r;
}

/* The camera above as the viewer needs it (haarlight.h, viewer support):
 * the same setup_camera and auto_frame, so that the viewer's first frame
 * is the picture hl_render makes. */
hl_result hl_camera_query_view(hl_context *ctx, const hl_mesh *mesh, const hl_camera_desc *desc,
                               hl_camera_view *out)
{
    if (!ctx) return HL_ERR_INVALID_ARGUMENT;
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "camera: no output given");
    if (!mesh || !mesh->positions || mesh->vertex_count == 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "camera: the mesh is empty");
    cam c;
    memset(&c, 0, sizeof c);
    hl_result r = setup_camera(ctx, mesh, desc, &c);
    if (r != HL_OK) return r;
    double eye[3], target[3];
    if (!desc || (zero3(desc->eye) && zero3(desc->target))) {
        auto_frame(mesh, c.tan_half_v, c.tan_half_h, eye, target);
    } else {
        for (int k = 0; k < 3; k++) target[k] = desc->target[k];
    }
    out->width = c.width;
    out->height = c.height;
    for (int k = 0; k < 3; k++) {
        out->eye[k] = (float)c.eye[k];
        out->target[k] = (float)target[k];
        out->forward[k] = (float)c.fwd[k];
        out->right[k] = (float)c.right[k];
        out->up[k] = (float)c.up[k];
    }
    out->tan_half_y = (float)c.tan_half_v;
    out->tan_half_x = (float)c.tan_half_h;
    return HL_OK;
}
