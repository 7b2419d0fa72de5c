/* shadow_map.c - one orthographic depth map per distant light, per frame,
 * for rigid objects: checking the objects, fitting each light's frame to
 * the moving scene, and rendering the maps by the chosen method (the
 * OpenCL rasteriser, its plain-C twin on the reference backend, or Embree
 * rays into instanced objects).
 *
 * Depends on: shadow_map.h (dynamic.h), cl_internal.h (the device, its
 * program and counted buffers), instances.h (Embree), core's threads.
 *
 * The default is the rasteriser. On data/bunny_lowres.obj with a ground
 * of 96 x 96 quads (22k triangles), 32 maps of 256^2 on two shared cores
 * took about 60 ms of CPU time (PoCL kernel or twin) against about 130 ms
 * for the Embree rays; a frame with one object moved costs the same as
 * any frame (a transform upload, or one top-level commit). Its twin
 * matches it bit for bit, its maps can stay on the device for the
 * convolution stage, and it needs no BVH. The rays win on dense meshes:
 * their cost follows the texels, the rasteriser's the triangles (the
 * 70k-triangle bunny: about 180 ms of CPU for the rays, 200 ms raster).
 */
#include <float.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"
#include "instances.h"
#include "shadow_map.h"

/* A transform is rigid when its 3x3 part R has R^T R = I to this much per
 * entry and det R > 0. Rotations built in float (trigonometry, quaternion
 * products) are off by a few 1e-7; 1e-4 also takes matrices printed to 5
 * or 6 digits, yet refuses a scale of 1.0001 or any shear worth a texel. */
#define HL_SHADOW_RIGID_TOL 1e-4

/* A light direction is unit when its length is within this of 1 (the
 * callers normalise; anything further off is a bug worth an error). */
#define HL_SHADOW_UNIT_TOL 1e-3

/* Below this |y| of the far direction, right is far x (+Y) (so for a
 * level light `up` is world up); above it, far x (-Z). Either cross product
 * then has length at least sqrt(1 - 0.99^2) = 0.14: no direction, the
 * poles included, meets a degenerate basis. */
#define HL_SHADOW_POLE_COS 0.99

/* Padding of the depth range on each side, as a fraction of the larger
 * of the depth and lateral extents: the nearest point gets depth >= about
 * 1e-3 and the farthest <= 1 - 1e-3, far beyond float rounding (1e-7),
 * so every surface stays below the empty value 1, for 0.2% of the range.
 * The lateral extent keeps it non-zero for a flat scene seen face-on. */
#define HL_SHADOW_DEPTH_PAD 1e-3

/* A body is flat when all its vertices lie within this fraction of its
 * bounding box's diagonal of one plane: float positions of a generated
 * plane are within 1e-7 of it, a scanned "flat" base of a statue is not
 * (and must then stay in the maps). */
#define HL_SHADOW_PLANE_TOL 1e-5

/* Another body is on one side of a flat body's plane when none of its
 * vertices is more than this fraction of the scene's extent on the other:
 * a body resting on the ground touches it, and its float vertices may dip
 * a hair below. The box's corners decide where they are all on one side
 * (the box holds the vertices); where a corner is not, the vertices do:
 * a turned body's box reaches beyond the body (CesiumMilkTruck's wheels,
 * turned 10 degrees, dip 0.069 below the ground by their boxes, 29 times
 * this tolerance, and kept the ground in every map, fitted to the ground
 * instead of the truck). */
#define HL_SHADOW_SIDE_TOL 1e-4

/* A flat body is never left out for a light within this cosine of its
 * plane: seen edge-on it covers no texel anyway, and the side test is
 * then ill-conditioned. */
#define HL_SHADOW_PLANE_MIN_COS 1e-3

/* Floats of a flat body's plane record (find_plane). */
#define HL_SHADOW_PLANE_F 13

/* A flat body fills its extent (a rectangle in its plane) when its
 * triangles' area is this close to the extent's: then what it hides can
 * be taken from the extent (dyn_frame.c). A disc, an L or a ground with
 * holes, or a rectangle turned in its plane against the extent's axes,
 * fall short and stay in the maps for lights on the far side. */
#define HL_SHADOW_RECT_TOL 1e-3

/* Work-items per map on a CPU device (wg 1): each takes ntris / 64
 * consecutive triangles, so 2 cores get 64 K items to balance. */
#define HL_SHADOW_CPU_CHUNKS 64u

struct hl_shadow_maps {
    hl_context *ctx;
    hl_shadow_method method;
    uint32_t R, nobj, nverts, ntris;
    float *pos;    /* all objects' vertices, 3 floats each */
    uint32_t *tri; /* 4 per triangle: indices into pos, object */
    float *xf;     /* 12 per object */
    float *box;    /* 6 per object: own-coordinate min and max */
    float *corners; /* 24 per object: the boxes' corners in world space */
    float *plane;   /* HL_SHADOW_PLANE_F per object: find_plane's record */
    float *fitpts;  /* 24 per object: the corners a map is fitted to */
    uint32_t *vstart; /* nobj + 1: each object's first vertex in pos */
    uint8_t *side;  /* per object: which side of its plane (flat_sides) */
    int skip_planes;
    hl_shadow_frame *frames;
    float *packed; /* 16 per map */
    uint32_t kcap;
    /* the rasteriser on a device */
    cl_kernel kern;
    cl_mem dpos, dtri, dxf, dframes, ddepth;
    uint32_t dkcap;
    int xf_dirty;
    /* Embree */
    hl_inst_scene *inst;
    hl_inst_ortho *ortho;
};

/* ---------------------------------------------------------------- checks */

static int finite3(const float *p) { return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]); }

/* NULL when xf is a proper rigid transform, else what is wrong. */
static const char *rigid_problem(const float *xf)
{
    for (int i = 0; i < 12; i++)
        if (!isfinite(xf[i])) return "a non-finite entry";
    double worst = 0.0;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double d = 0.0;
            for (int r = 0; r < 3; r++) d += (double)xf[4 * r + a] * (double)xf[4 * r + b];
            worst = fmax(worst, fabs(d - (a == b ? 1.0 : 0.0)));
        }
    if (!(worst <= HL_SHADOW_RIGID_TOL)) return "a 3x3 part that is not orthonormal (a scale or shear)";
    double det = (double)xf[0] * ((double)xf[5] * xf[10] - (double)xf[6] * xf[9]) -
                 (double)xf[1] * ((double)xf[4] * xf[10] - (double)xf[6] * xf[8]) +
                 (double)xf[2] * ((double)xf[4] * xf[9] - (double)xf[5] * xf[8]);
    if (det <= 0.0) return "a reflection (determinant -1)";
    return NULL;
}

static hl_result check_object(hl_context *ctx, const hl_dyn_object *o, uint32_t i)
{
    if ((o->nverts && !o->pos) || (o->ntris && !o->tri))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: object %u has %u vertices and %u triangles but no %s array", i,
                       o->nverts, o->ntris, o->nverts && !o->pos ? "position" : "index");
    for (uint32_t v = 0; v < o->nverts; v++)
        if (!finite3(o->pos + 3 * (size_t)v))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: object %u, vertex %u is not finite (%g %g %g)", i, v,
                           (double)o->pos[3 * (size_t)v], (double)o->pos[3 * (size_t)v + 1], (double)o->pos[3 * (size_t)v + 2]);
    for (size_t t = 0; t < 3 * (size_t)o->ntris; t++)
        if (o->tri[t] >= o->nverts)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: object %u, triangle %zu names vertex %u of %u", i, t / 3,
                           o->tri[t], o->nverts);
    const char *why = rigid_problem(o->xf);
    if (why) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: object %u's transform is not rigid: %s", i, why);
    return HL_OK;
}

static hl_result check_objects(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, uint32_t R)
{
    if (R < HL_SHADOW_MIN_R || R > HL_SHADOW_MAX_R)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: R = %u texels: must be %u to %u", R, HL_SHADOW_MIN_R,
                       HL_SHADOW_MAX_R);
    if (!objects || !nobj) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: no objects");
    uint64_t nv = 0, nt = 0;
    for (uint32_t i = 0; i < nobj; i++) {
        TRY(check_object(ctx, &objects[i], i));
        nv += objects[i].nverts;
        nt += objects[i].ntris;
    }
    if (!nt) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: the %u objects have no triangles", nobj);
    /* 4 indices per triangle and 3 floats per vertex, counted in uint32 */
    if (nv > UINT32_MAX / 3 || nt > UINT32_MAX / 4)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: %llu vertices and %llu triangles: too many",
                       (unsigned long long)nv, (unsigned long long)nt);
    return HL_OK;
}

/* ------------------------------------------------------------- the frame */

static void cross3(const double *a, const double *b, double *o)
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static void normalize3(double *v)
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int c = 0; c < 3; c++) v[c] /= n;
}

void hl_shadow_fit_frame(const float *pts, uint32_t npts, const float dir[3], uint32_t R, hl_shadow_frame *fr)
{
    double f[3] = {-(double)dir[0], -(double)dir[1], -(double)dir[2]}, r[3], u[3];
    normalize3(f);
    const double hint[3] = {0.0, fabs(f[1]) < HL_SHADOW_POLE_COS ? 1.0 : 0.0, fabs(f[1]) < HL_SHADOW_POLE_COS ? 0.0 : -1.0};
    cross3(f, hint, r);
    normalize3(r);
    cross3(r, f, u); /* unit: r and f are orthonormal */
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < npts; i++) {
        const float *p = pts + 3 * (size_t)i;
        const double *ax[3] = {r, u, f};
        for (int a = 0; a < 3; a++) {
            double d = ax[a][0] * p[0] + ax[a][1] * p[1] + ax[a][2] * p[2];
            lo[a] = fmin(lo[a], d);
            hi[a] = fmax(hi[a], d);
        }
    }
    if (!npts)
        for (int a = 0; a < 3; a++) lo[a] = hi[a] = 0.0;
    double ext = fmax(hi[0] - lo[0], hi[1] - lo[1]), dz = hi[2] - lo[2];
    if (!(ext > 0.0)) ext = dz > 0.0 ? dz : 1.0; /* a point or a segment along the light */
    /* the bounds fill R - 2 margin texels, centred */
    double texel = ext / (double)(R - 2 * HL_SHADOW_MARGIN_TEXELS), width = texel * (double)R;
    double pad = HL_SHADOW_DEPTH_PAD * fmax(dz, ext), range = dz + 2.0 * pad;
    double o_r = 0.5 * (lo[0] + hi[0]) - 0.5 * width, o_u = 0.5 * (lo[1] + hi[1]) - 0.5 * width, o_f = lo[2] - pad;
    for (int c = 0; c < 3; c++) {
        fr->origin[c] = (float)(o_r * r[c] + o_u * u[c] + o_f * f[c]);
        fr->right[c] = (float)r[c];
        fr->up[c] = (float)u[c];
        fr->toward_far[c] = (float)f[c];
    }
    fr->width = fr->height = (float)width;
    fr->depth_range = (float)range;
    fr->R = R;
    fr->skip_mask = 0;
}

void hl_shadow_frame_pack(const hl_shadow_frame *fr, float out[16])
{
    for (int c = 0; c < 3; c++) {
        out[c] = fr->origin[c];
        out[3 + c] = fr->right[c];
        out[6 + c] = fr->up[c];
        out[9 + c] = fr->toward_far[c];
    }
    out[12] = (float)fr->R / fr->width;
    out[13] = (float)fr->R / fr->height;
    out[14] = 1.0f / fr->depth_range;
    memcpy(&out[15], &fr->skip_mask, 4); /* the kernel reads the bits back with as_uint */
}

/* Every object's own box's corners, moved to world space. */
static void world_corners(hl_shadow_maps *sm)
{
    for (uint32_t o = 0; o < sm->nobj; o++) {
        const float *b = sm->box + 6 * (size_t)o, *x = sm->xf + 12 * (size_t)o;
        for (int c = 0; c < 8; c++) {
            float p[3] = {b[(c & 1) ? 3 : 0], b[(c & 2) ? 4 : 1], b[(c & 4) ? 5 : 2]};
            float *w = sm->corners + 24 * (size_t)o + 3 * c;
            for (int k = 0; k < 3; k++)
                w[k] = (float)((double)x[4 * k] * p[0] + (double)x[4 * k + 1] * p[1] + (double)x[4 * k + 2] * p[2] +
                               (double)x[4 * k + 3]);
        }
    }
}

/* ---------------------------------------------------------------- create */

void hl_shadow_maps_destroy(hl_shadow_maps *sm)
{
    if (!sm) return;
    if (sm->ctx->cl) {
        if (sm->ctx->cl->queue) clFinish(sm->ctx->cl->queue);
        cl_mem *all[] = {&sm->dpos, &sm->dtri, &sm->dxf, &sm->dframes, &sm->ddepth};
        for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) hl_cl_release_buf(sm->ctx->cl, all[i]);
    }
    if (sm->kern) clReleaseKernel(sm->kern);
    hl_inst_destroy(sm->inst);
    free(sm->pos);
    free(sm->tri);
    free(sm->xf);
    free(sm->box);
    free(sm->corners);
    free(sm->fitpts);
    free(sm->plane);
    free(sm->vstart);
    free(sm->side);
    free(sm->frames);
    free(sm->packed);
    free(sm->ortho);
    free(sm);
}

/* The objects, one after another, in sm's own arrays. */
static void copy_objects(hl_shadow_maps *sm, const hl_dyn_object *objects)
{
    uint32_t v0 = 0, t0 = 0;
    for (uint32_t o = 0; o < sm->nobj; o++) {
        const hl_dyn_object *ob = &objects[o];
        sm->vstart[o] = v0;
        memcpy(sm->pos + 3 * (size_t)v0, ob->pos, (size_t)ob->nverts * 12);
        for (uint32_t t = 0; t < ob->ntris; t++) {
            uint32_t *d = sm->tri + 4 * (size_t)(t0 + t);
            for (int k = 0; k < 3; k++) d[k] = v0 + ob->tri[3 * (size_t)t + k];
            d[3] = o;
        }
        memcpy(sm->xf + 12 * (size_t)o, ob->xf, 48);
        float *b = sm->box + 6 * (size_t)o;
        for (int k = 0; k < 3; k++) { b[k] = ob->nverts ? INFINITY : 0.0f; b[3 + k] = ob->nverts ? -INFINITY : 0.0f; }
        for (uint32_t v = 0; v < ob->nverts; v++)
            for (int k = 0; k < 3; k++) {
                b[k] = fminf(b[k], ob->pos[3 * (size_t)v + k]);
                b[3 + k] = fmaxf(b[3 + k], ob->pos[3 * (size_t)v + k]);
            }
        v0 += ob->nverts;
        t0 += ob->ntris;
    }
    sm->vstart[sm->nobj] = v0;
}

/* The plane record of a flat object (own coordinates, HL_SHADOW_PLANE_F
 * floats): unit normal n, w with n . p = w for every vertex, an in-plane
 * axis u, the vertices' extent along u and along v = n x u, 1 (flat), and
 * 1 when the triangles fill that extent (HL_SHADOW_RECT_TOL); all zeros
 * when it is not flat. The normal is the area-weighted sum of its
 * triangles' normals. */
static void find_plane(const hl_dyn_object *ob, const float *box, float *pl)
{
    memset(pl, 0, HL_SHADOW_PLANE_F * sizeof *pl);
    double n[3] = {0, 0, 0}, c[3] = {0, 0, 0};
    for (uint32_t t = 0; t < ob->ntris; t++) {
        const float *a = ob->pos + 3 * (size_t)ob->tri[3 * (size_t)t], *b = ob->pos + 3 * (size_t)ob->tri[3 * (size_t)t + 1],
                    *d = ob->pos + 3 * (size_t)ob->tri[3 * (size_t)t + 2];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]}, x[3];
        cross3(e1, e2, x);
        for (int k = 0; k < 3; k++) n[k] += x[k];
    }
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), area = 0.0;
    if (!(len > 0.0) || !ob->nverts) return;
    for (uint32_t t = 0; t < ob->ntris; t++) {
        const float *a = ob->pos + 3 * (size_t)ob->tri[3 * (size_t)t], *b = ob->pos + 3 * (size_t)ob->tri[3 * (size_t)t + 1],
                    *d = ob->pos + 3 * (size_t)ob->tri[3 * (size_t)t + 2];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]}, x[3];
        cross3(e1, e2, x);
        area += 0.5 * sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    }
    for (int k = 0; k < 3; k++) n[k] /= len;
    for (uint32_t v = 0; v < ob->nverts; v++)
        for (int k = 0; k < 3; k++) c[k] += ob->pos[3 * (size_t)v + k];
    double w = (n[0] * c[0] + n[1] * c[1] + n[2] * c[2]) / ob->nverts;
    double diag = sqrt((box[3] - box[0]) * (box[3] - box[0]) + (box[4] - box[1]) * (box[4] - box[1]) +
                       (box[5] - box[2]) * (box[5] - box[2]));
    /* u: across the axis least aligned with n */
    int m = fabs(n[0]) <= fabs(n[1]) && fabs(n[0]) <= fabs(n[2]) ? 0 : fabs(n[1]) <= fabs(n[2]) ? 1 : 2;
    double e[3] = {0, 0, 0}, u[3], vv[3];
    e[m] = 1.0;
    cross3(n, e, u);
    normalize3(u);
    cross3(n, u, vv);
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (uint32_t v = 0; v < ob->nverts; v++) {
        const float *p = ob->pos + 3 * (size_t)v;
        if (fabs(n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - w) > HL_SHADOW_PLANE_TOL * diag) return;
        double a = u[0] * p[0] + u[1] * p[1] + u[2] * p[2], b = vv[0] * p[0] + vv[1] * p[1] + vv[2] * p[2];
        lo[0] = fmin(lo[0], a), hi[0] = fmax(hi[0], a), lo[1] = fmin(lo[1], b), hi[1] = fmax(hi[1], b);
    }
    for (int k = 0; k < 3; k++) pl[k] = (float)n[k], pl[4 + k] = (float)u[k];
    pl[3] = (float)w;
    pl[7] = (float)lo[0], pl[8] = (float)hi[0], pl[9] = (float)lo[1], pl[10] = (float)hi[1];
    pl[11] = 1.0f;
    double box_area = (hi[0] - lo[0]) * (hi[1] - lo[1]);
    pl[12] = box_area > 0.0 && fabs(area / box_area - 1.0) <= HL_SHADOW_RECT_TOL ? 1.0f : 0.0f;
}

void hl_shadow_maps_skip_planes(hl_shadow_maps *sm, int on)
{
    if (sm) sm->skip_planes = on && sm->method == HL_SHADOW_RASTER;
}

/* a rotation (the 3x3 of xf) applied to a vector */
static void rotate3(const float *x, const float *a, double *out)
{
    for (int k = 0; k < 3; k++) out[k] = (double)x[4 * k] * a[0] + (double)x[4 * k + 1] * a[1] + (double)x[4 * k + 2] * a[2];
}

int hl_shadow_maps_flat(const hl_shadow_maps *sm, uint32_t o, hl_flat_body *fb)
{
    if (!sm || o >= sm->nobj) return 0;
    const float *pl = sm->plane + HL_SHADOW_PLANE_F * (size_t)o, *x = sm->xf + 12 * (size_t)o;
    if (pl[11] != 1.0f) return 0;
    double n[3], u[3], v[3], p[3];
    rotate3(x, pl, n);
    rotate3(x, pl + 4, u);
    cross3(n, u, v);
    for (int k = 0; k < 3; k++) p[k] = n[k] * pl[3] + x[4 * k + 3];
    for (int k = 0; k < 3; k++) {
        fb->n[k] = (float)n[k], fb->u[k] = (float)u[k], fb->v[k] = (float)v[k], fb->p[k] = (float)p[k];
    }
    fb->lo[0] = pl[7], fb->hi[0] = pl[8], fb->lo[1] = pl[9], fb->hi[1] = pl[10];
    fb->rect = pl[12] == 1.0f;
    return 1;
}

/* The scene's largest extent from the bodies' world corners (once a
 * render, for skip_mask's tolerance). */
static double scene_extent(const hl_shadow_maps *sm)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < 8 * (size_t)sm->nobj; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], sm->corners[3 * i + (size_t)k]);
            hi[k] = fmax(hi[k], sm->corners[3 * i + (size_t)k]);
        }
    return fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
}

/* Sides of flat body fb's plane that body q lies on, within tol: bit 0
 * every vertex at or above it (h >= -tol), bit 1 every one at or below.
 * The box's corners first, then, for a side they do not show, the
 * vertices moved to world space (HL_SHADOW_SIDE_TOL). */
static unsigned body_sides(const hl_shadow_maps *sm, uint32_t q, const hl_flat_body *fb, double tol)
{
    double lo = INFINITY, hi = -INFINITY;
    for (int c = 0; c < 8; c++) {
        const float *w = sm->corners + 24 * (size_t)q + 3 * c;
        double h = fb->n[0] * (w[0] - fb->p[0]) + fb->n[1] * (w[1] - fb->p[1]) + fb->n[2] * (w[2] - fb->p[2]);
        lo = fmin(lo, h), hi = fmax(hi, h);
    }
    unsigned sides = (lo >= -tol ? 1u : 0u) | (hi <= tol ? 2u : 0u);
    if (sides == 3u || sm->vstart[q + 1] == sm->vstart[q]) return sides;
    /* h(v) = m . v + c with m = R^T n and c = n . (t - p) */
    const float *x = sm->xf + 12 * (size_t)q;
    double m[3], c = 0.0;
    for (int k = 0; k < 3; k++) {
        m[k] = fb->n[0] * x[k] + fb->n[1] * x[4 + k] + fb->n[2] * x[8 + k];
        c += fb->n[k] * ((double)x[4 * k + 3] - fb->p[k]);
    }
    lo = INFINITY, hi = -INFINITY;
    for (uint32_t v = sm->vstart[q]; v < sm->vstart[q + 1]; v++) {
        const float *p = sm->pos + 3 * (size_t)v;
        double h = m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + c;
        lo = fmin(lo, h), hi = fmax(hi, h);
    }
    return (lo >= -tol ? 1u : 0u) | (hi <= tol ? 2u : 0u);
}

/* Per flat body, the sides of its plane that every other body lies on
 * (body_sides' bits, ANDed), at the bodies' current transforms: once a
 * render, after world_corners. ext: scene_extent. */
static void flat_sides(hl_shadow_maps *sm, double ext)
{
    const double tol = HL_SHADOW_SIDE_TOL * ext;
    for (uint32_t o = 0; o < sm->nobj && o < 32; o++) {
        hl_flat_body fb;
        sm->side[o] = 0;
        if (!sm->skip_planes || !hl_shadow_maps_flat(sm, o, &fb)) continue;
        unsigned sides = 3u;
        for (uint32_t q = 0; q < sm->nobj && sides; q++)
            if (q != o) sides &= body_sides(sm, q, &fb, tol);
        sm->side[o] = (uint8_t)sides;
    }
}

/* The bodies light dir may leave out (shadow_map.h), from flat_sides. */
static uint32_t skip_mask(const hl_shadow_maps *sm, const float dir[3])
{
    if (!sm->skip_planes) return 0;
    uint32_t mask = 0;
    for (uint32_t o = 0; o < sm->nobj && o < 32; o++) {
        hl_flat_body fb;
        if (!hl_shadow_maps_flat(sm, o, &fb)) continue;
        double s = fb.n[0] * dir[0] + fb.n[1] * dir[1] + fb.n[2] * dir[2];
        if (!(fabs(s) >= HL_SHADOW_PLANE_MIN_COS)) continue;
        /* every other body on one side of the plane, either one */
        const int above = sm->side[o] & 1u, below = (sm->side[o] >> 1) & 1u;
        /* with the others on the light's side it hides nothing from them;
           on the far side, what it hides is taken from its extent, which
           only a body filling it may have taken */
        if ((s > 0.0 && above) || (s < 0.0 && below) || (fb.rect && (above || below))) mask |= 1u << o;
    }
    return mask;
}

/* Frame k for light dir, fitted to the corners of the bodies not left out. */
static void fit_one(hl_shadow_maps *sm, const float dir[3], hl_shadow_frame *fr)
{
    uint32_t mask = skip_mask(sm, dir), n = 0;
    for (uint32_t o = 0; o < sm->nobj; o++)
        if (o >= 32 || !(mask >> o & 1u)) memcpy(sm->fitpts + 24 * (size_t)n++, sm->corners + 24 * (size_t)o, 96);
    hl_shadow_fit_frame(sm->fitpts, 8 * n, dir, sm->R, fr);
    fr->skip_mask = mask;
}

void hl_shadow_maps_skip_masks(hl_shadow_maps *sm, const float (*dirs)[3], uint32_t K, uint32_t *masks)
{
    world_corners(sm);
    flat_sides(sm, scene_extent(sm));
    for (uint32_t k = 0; k < K; k++) masks[k] = skip_mask(sm, dirs[k]);
}

static hl_result create_device(hl_shadow_maps *sm)
{
    hl_context *ctx = sm->ctx;
    cl_int e;
    sm->kern = clCreateKernel(ctx->cl->program, "hl_shadow_raster", &e);
    CL_TRY(ctx, e, "hl_shadow_raster");
    TRY(hl_cl_make_buf(ctx, &sm->dpos, CL_MEM_READ_ONLY, (size_t)sm->nverts * 12, sm->pos, "shadow-map vertices"));
    TRY(hl_cl_make_buf(ctx, &sm->dtri, CL_MEM_READ_ONLY, (size_t)sm->ntris * 16, sm->tri, "shadow-map triangles"));
    TRY(hl_cl_make_buf(ctx, &sm->dxf, CL_MEM_READ_ONLY, (size_t)sm->nobj * 48, sm->xf, "object transforms"));
    return HL_OK;
}

static hl_result create_embree(hl_shadow_maps *sm, const hl_dyn_object *objects)
{
    hl_inst_mesh *m = calloc(sm->nobj, sizeof *m);
    if (!m) return hl_fail(sm->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u objects", sm->nobj);
    for (uint32_t o = 0; o < sm->nobj; o++)
        m[o] = (hl_inst_mesh){.pos = objects[o].pos, .nverts = objects[o].nverts, .tri = objects[o].tri,
                              .ntris = objects[o].ntris, .xf = objects[o].xf};
    hl_result r = hl_inst_create(sm->ctx, m, sm->nobj, &sm->inst);
    free(m);
    return r;
}

hl_result hl_shadow_maps_create(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, uint32_t R,
                                hl_shadow_method method, hl_shadow_maps **out)
{
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: no place for the result");
    *out = NULL;
    if (method != HL_SHADOW_RASTER && method != HL_SHADOW_EMBREE)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: unknown method %d", (int)method);
    TRY(check_objects(ctx, objects, nobj, R));
    hl_shadow_maps *sm = calloc(1, sizeof *sm);
    if (!sm) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for shadow maps");
    sm->ctx = ctx;
    sm->method = method;
    sm->R = R;
    sm->nobj = nobj;
    for (uint32_t o = 0; o < nobj; o++) {
        sm->nverts += objects[o].nverts;
        sm->ntris += objects[o].ntris;
    }
    sm->pos = malloc((size_t)sm->nverts * 12 + 12);
    sm->tri = malloc((size_t)sm->ntris * 16);
    sm->xf = malloc((size_t)nobj * 48);
    sm->box = malloc((size_t)nobj * 24);
    sm->corners = malloc((size_t)nobj * 96);
    sm->fitpts = malloc((size_t)nobj * 96);
    sm->plane = malloc((size_t)nobj * HL_SHADOW_PLANE_F * sizeof(float));
    sm->vstart = malloc(((size_t)nobj + 1) * sizeof *sm->vstart);
    sm->side = calloc(nobj, 1);
    if (!sm->pos || !sm->tri || !sm->xf || !sm->box || !sm->corners || !sm->fitpts || !sm->plane || !sm->vstart ||
        !sm->side) {
        hl_shadow_maps_destroy(sm);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u vertices and %u triangles", sm->nverts, sm->ntris);
    }
    copy_objects(sm, objects);
    for (uint32_t o = 0; o < nobj; o++)
        find_plane(&objects[o], sm->box + 6 * (size_t)o, sm->plane + HL_SHADOW_PLANE_F * (size_t)o);
    hl_result r = HL_OK;
    if (method == HL_SHADOW_EMBREE) r = create_embree(sm, objects);
    else if (ctx->cl) r = create_device(sm);
    if (r != HL_OK) { hl_shadow_maps_destroy(sm); return r; }
    *out = sm;
    return HL_OK;
}

hl_result hl_shadow_maps_set_transform(hl_shadow_maps *sm, uint32_t object, const float xf[12])
{
    if (object >= sm->nobj)
        return hl_fail(sm->ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: object %u of %u", object, sm->nobj);
    if (!xf) return hl_fail(sm->ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: no transform for object %u", object);
    const char *why = rigid_problem(xf);
    if (why) return hl_fail(sm->ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: the new transform of object %u is not rigid: %s", object, why);
    memcpy(sm->xf + 12 * (size_t)object, xf, 48);
    sm->xf_dirty = 1;
    if (sm->inst) return hl_inst_set_transform(sm->inst, object, xf);
    return HL_OK;
}

void hl_shadow_maps_embree_counts(const hl_shadow_maps *sm, uint64_t *object_builds, uint64_t *scene_commits)
{
    *object_builds = *scene_commits = 0;
    if (sm->inst) hl_inst_counts(sm->inst, object_builds, scene_commits);
}

/* ---------------------------------------------------------------- render */

static hl_result ensure_k(hl_shadow_maps *sm, uint32_t K)
{
    if (K <= sm->kcap) return HL_OK;
    hl_shadow_frame *f = realloc(sm->frames, (size_t)K * sizeof *f);
    if (f) sm->frames = f;
    float *p = realloc(sm->packed, (size_t)K * 64);
    if (p) sm->packed = p;
    hl_inst_ortho *o = realloc(sm->ortho, (size_t)K * sizeof *o);
    if (o) sm->ortho = o;
    if (!f || !p || !o) return hl_fail(sm->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u shadow-map frames", K);
    sm->kcap = K;
    return HL_OK;
}

static hl_result render_device(hl_shadow_maps *sm, uint32_t K, float *depth)
{
    hl_context *ctx = sm->ctx;
    struct hl_cl *cl = ctx->cl;
    size_t mapbytes = (size_t)sm->R * sm->R * 4;
    if (K > sm->dkcap) {
        hl_cl_release_buf(cl, &sm->dframes);
        hl_cl_release_buf(cl, &sm->ddepth);
        sm->dkcap = 0;
        TRY(hl_cl_make_buf(ctx, &sm->dframes, CL_MEM_READ_ONLY, (size_t)K * 64, NULL, "shadow-map frames"));
        TRY(hl_cl_make_buf(ctx, &sm->ddepth, CL_MEM_READ_WRITE, K * mapbytes, NULL, "shadow maps"));
        sm->dkcap = K;
    }
    if (sm->xf_dirty)
        CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, sm->dxf, CL_FALSE, 0, (size_t)sm->nobj * 48, sm->xf, 0, NULL, NULL),
               "upload of the transforms");
    sm->xf_dirty = 0;
    CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, sm->dframes, CL_FALSE, 0, (size_t)K * 64, sm->packed, 0, NULL, NULL),
           "upload of the frames");
    const float empty = HL_SHADOW_EMPTY;
    CL_TRY(ctx, clEnqueueFillBuffer(cl->queue, sm->ddepth, &empty, 4, 0, K * mapbytes, 0, NULL, NULL), "clearing the maps");
    cl_uint ntris = sm->ntris, R = sm->R;
    cl_uint per = !cl->gpu_shape ? (ntris + HL_SHADOW_CPU_CHUNKS - 1) / HL_SHADOW_CPU_CHUNKS : 1;
    size_t items = (ntris + per - 1) / per;
    size_t local[2] = {cl->wg, 1}, global[2] = {(items + cl->wg - 1) / cl->wg * cl->wg, K};
    cl_kernel k = sm->kern;
#define SARG(i, v) CL_TRY(ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")
    SARG(0, sm->dpos); SARG(1, sm->dtri); SARG(2, ntris); SARG(3, sm->dxf); SARG(4, sm->dframes); SARG(5, R);
    SARG(6, per); SARG(7, sm->ddepth);
#undef SARG
    CL_TRY(ctx, clEnqueueNDRangeKernel(cl->queue, k, 2, NULL, global, local, 0, NULL, NULL), "hl_shadow_raster");
    if (depth)
        CL_TRY(ctx, clEnqueueReadBuffer(cl->queue, sm->ddepth, CL_TRUE, 0, K * mapbytes, depth, 0, NULL, NULL),
               "read-back of the shadow maps");
    else /* left on the device (hl_shadow_maps_device_depth); waited for, for the frame's stage times */
        CL_TRY(ctx, clFinish(cl->queue), "the shadow maps");
    return HL_OK;
}

void *hl_shadow_maps_device_depth(const hl_shadow_maps *sm) { return sm->ddepth; }

typedef struct twin_job {
    hl_shadow_maps *sm;
    uint32_t K;
    float *depth;
    atomic_uint next;
} twin_job;

static void *twin_worker(void *arg)
{
    twin_job *j = arg;
    hl_shadow_maps *sm = j->sm;
    size_t n = (size_t)sm->R * sm->R;
    for (;;) {
        uint32_t k = atomic_fetch_add(&j->next, 1u);
        if (k >= j->K || hl_context_cancelled(sm->ctx)) break;
        float *map = j->depth + k * n;
        for (size_t i = 0; i < n; i++) map[i] = HL_SHADOW_EMPTY;
        hl_ref_shadow_raster(sm->pos, sm->tri, 0, sm->ntris, sm->xf, sm->packed + 16 * (size_t)k, sm->R, map);
    }
    return NULL;
}

static hl_result render_embree(hl_shadow_maps *sm, uint32_t K, float *depth)
{
    for (uint32_t k = 0; k < K; k++) {
        const hl_shadow_frame *f = &sm->frames[k];
        hl_inst_ortho *o = &sm->ortho[k];
        memcpy(o->origin, f->origin, 12);
        memcpy(o->right, f->right, 12);
        memcpy(o->up, f->up, 12);
        memcpy(o->far, f->toward_far, 12);
        o->width = f->width;
        o->height = f->height;
        o->depth_range = f->depth_range;
        o->R = f->R;
    }
    return hl_inst_depth_maps(sm->inst, sm->ortho, K, depth);
}

/* The maps of sm->frames (packed too) by sm's method. */
static hl_result render_frames(hl_shadow_maps *sm, uint32_t K, float *depth)
{
    hl_context *ctx = sm->ctx;
    if (sm->method == HL_SHADOW_EMBREE) return render_embree(sm, K, depth);
    if (ctx->cl) return render_device(sm, K, depth);
    twin_job j = {.sm = sm, .K = K, .depth = depth};
    atomic_init(&j.next, 0u);
    hl_run_threads(ctx->threads, twin_worker, &j);
    if (hl_context_cancelled(ctx)) return hl_fail(ctx, HL_ERR_INTERRUPTED, "interrupted");
    return HL_OK;
}

hl_result hl_shadow_maps_render(hl_shadow_maps *sm, const float (*dirs)[3], uint32_t K, float *depth,
                                hl_shadow_frame *frames)
{
    hl_context *ctx = sm->ctx;
    /* no depth array: the maps stay on the device, where they are made there */
    const int on_device = ctx->cl && sm->method == HL_SHADOW_RASTER;
    if (!dirs || (!depth && !on_device) || !K)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: %s", !K ? "no lights" : "no directions or no depth array");
    if ((uint64_t)K * sm->R * sm->R > SIZE_MAX / 8)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: %u maps of %u^2 texels do not fit in memory", K, sm->R);
    for (uint32_t k = 0; k < K; k++) {
        double n = sqrt((double)dirs[k][0] * dirs[k][0] + (double)dirs[k][1] * dirs[k][1] + (double)dirs[k][2] * dirs[k][2]);
        if (!finite3(dirs[k]) || !(fabs(n - 1.0) <= HL_SHADOW_UNIT_TOL))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: light %u's direction (%g %g %g) is not a unit vector", k,
                           (double)dirs[k][0], (double)dirs[k][1], (double)dirs[k][2]);
    }
    TRY(ensure_k(sm, K));
    world_corners(sm);
    flat_sides(sm, scene_extent(sm));
    for (uint32_t k = 0; k < K; k++) {
        fit_one(sm, dirs[k], &sm->frames[k]);
        hl_shadow_frame_pack(&sm->frames[k], sm->packed + 16 * (size_t)k);
    }
    if (frames) memcpy(frames, sm->frames, (size_t)K * sizeof *frames);
    return render_frames(sm, K, depth);
}

hl_result hl_shadow_maps_render_in(hl_shadow_maps *sm, const hl_shadow_frame *frames, uint32_t K, float *depth)
{
    hl_context *ctx = sm->ctx;
    if (!frames || !depth || !K)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: %s", !K ? "no lights" : "no frames or no depth array");
    if ((uint64_t)K * sm->R * sm->R > SIZE_MAX / 8)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: %u maps of %u^2 texels do not fit in memory", K, sm->R);
    for (uint32_t k = 0; k < K; k++) {
        const hl_shadow_frame *f = &frames[k];
        int ok = f->R == sm->R && finite3(f->origin) && finite3(f->right) && finite3(f->up) && finite3(f->toward_far) &&
                 isfinite(f->width) && isfinite(f->height) && isfinite(f->depth_range) && f->width > 0.0f &&
                 f->height > 0.0f && f->depth_range > 0.0f;
        if (!ok)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "shadow maps: frame %u is not usable (R %u, this module's %u; sizes must be finite and positive)", k,
                           f->R, sm->R);
    }
    TRY(ensure_k(sm, K));
    memcpy(sm->frames, frames, (size_t)K * sizeof *frames);
    for (uint32_t k = 0; k < K; k++) hl_shadow_frame_pack(&sm->frames[k], sm->packed + 16 * (size_t)k);
    return render_frames(sm, K, depth);
}
