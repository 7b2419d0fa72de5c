/* capture.c - the capture's checks, the triangles packed for the kernel and
 * the runs on either backend: kernels/capture/capture.cl on the OpenCL
 * device, or the twin (twins/capture.c) on the context's threads.
 * Depends on: capture.h, cl_internal.h (the device's program, queue and
 * counted buffers), core (hl_run_threads, errors), libm.
 */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "cl_internal.h"

/* Texels per claim of a reference worker: small enough to balance the
 * rim's cheaper texels, large enough that the atomic is rare. */
#define HL_CAPTURE_CHUNK 64u

struct hl_capture {
    hl_context *ctx;
    uint32_t N, S, ncoef;
    float *tris;         /* HL_CAPTURE_FLOATS per triangle, packed */
    float *cones;        /* the texel table (hl_capture_texel_cones) */
    float *tile_cones;   /* the tiles' (hl_capture_tile_cones) */
    hl_capture_accel acc; /* the hierarchy and the tiles' lists */
    uint32_t ntris;      /* triangles the last run packed */
    uint32_t cap_tris;   /* triangles tris has room for */
    cl_kernel k;
    cl_mem tris_d, env_d, L_d, cones_d, tstart_d, tlist_d, nodes_d, links_d, order_d;
    /* bytes the growing device buffers hold */
    size_t dev_tris, dev_list, dev_nodes, dev_links, dev_order;
};

void hl_capture_destroy(hl_capture *c)
{
    if (!c) return;
    if (c->ctx->cl) {
        if (c->k) clReleaseKernel(c->k);
        hl_cl_release_buf(c->ctx->cl, &c->tris_d);
        hl_cl_release_buf(c->ctx->cl, &c->env_d);
        hl_cl_release_buf(c->ctx->cl, &c->L_d);
        hl_cl_release_buf(c->ctx->cl, &c->cones_d);
        hl_cl_release_buf(c->ctx->cl, &c->tstart_d);
        hl_cl_release_buf(c->ctx->cl, &c->tlist_d);
        hl_cl_release_buf(c->ctx->cl, &c->nodes_d);
        hl_cl_release_buf(c->ctx->cl, &c->links_d);
        hl_cl_release_buf(c->ctx->cl, &c->order_d);
    }
    free(c->tris);
    free(c->cones);
    free(c->tile_cones);
    hl_capture_accel_free(&c->acc);
    free(c);
}

hl_result hl_capture_create(hl_context *ctx, uint32_t N, uint32_t S, hl_capture **out)
{
    *out = NULL;
    if (N < 8 || N > 256 || (N & (N - 1)))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: N = %u: the paraboloid resolution must be a power of two from 8 to 256", N);
    if (S == 0) S = hl_capture_default_s(N);
    if (S > HL_CAPTURE_MAX_S)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: %u rays per texel side: at most %u", S, HL_CAPTURE_MAX_S);
    hl_capture *c = hl_calloc(ctx, 1, sizeof *c, "the capture");
    if (!c) return HL_ERR_OUT_OF_MEMORY;
    c->ctx = ctx;
    c->N = N;
    c->S = S;
    c->ncoef = 2 * N * N;
    c->cones = hl_malloc(ctx, (size_t)c->ncoef * HL_CAPTURE_CONE_FLOATS * 4, "the capture's texel table");
    c->tile_cones = hl_malloc(ctx, (size_t)HL_CAPTURE_NTILES * HL_CAPTURE_CONE_FLOATS * 4, "the capture's tile table");
    if (!c->cones || !c->tile_cones) {
        hl_capture_destroy(c);
        return HL_ERR_OUT_OF_MEMORY;
    }
    hl_capture_texel_cones(N, S, c->cones);
    hl_capture_tile_cones(N, c->tile_cones);
    if (ctx->cl) {
        cl_int e;
        c->k = clCreateKernel(ctx->cl->program, "hl_capture", &e);
        hl_result r = e == CL_SUCCESS ? HL_OK
                                      : hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: the kernel hl_capture: %s (%d)", hl_cl_err_name(e), (int)e);
        if (r == HL_OK) r = hl_cl_make_buf(ctx, &c->env_d, CL_MEM_READ_ONLY, (size_t)c->ncoef * 12, NULL, "the capture's fallback lighting");
        if (r == HL_OK) r = hl_cl_make_buf(ctx, &c->L_d, CL_MEM_WRITE_ONLY, (size_t)c->ncoef * 12, NULL, "the captured lighting");
        if (r == HL_OK)
            r = hl_cl_make_buf(ctx, &c->cones_d, CL_MEM_READ_ONLY, (size_t)c->ncoef * HL_CAPTURE_CONE_FLOATS * 4, c->cones,
                               "the capture's texel table");
        if (r == HL_OK)
            r = hl_cl_make_buf(ctx, &c->tstart_d, CL_MEM_READ_ONLY, sizeof c->acc.tile_start, NULL, "the capture's tile lists");
        if (r != HL_OK) {
            hl_capture_destroy(c);
            return r;
        }
    }
    *out = c;
    return HL_OK;
}

hl_result hl_capture_check(hl_context *ctx, uint32_t ncoef, const hl_capture_scene *s)
{
    if (!s || !s->positions || !s->emission || s->triangle_count == 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: no surroundings (no triangles given)");
    for (int a = 0; a < 3; a++)
        if (!isfinite(s->center[a]))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: the capture point is not finite");
    for (uint32_t i = 0; i < s->triangle_count; i++) {
        for (int q = 0; q < 9; q++) {
            const float p = s->positions[9 * (size_t)i + q];
            if (!isfinite(p))
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: triangle %u has a corner that is not finite", i);
            if (fabs((double)p - s->center[q % 3]) > HL_CAPTURE_MAX_DIST)
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                               "capture: triangle %u has a corner %g from the capture point along an axis: at most %g "
                               "(the rays' float products would overflow)",
                               i, fabs((double)p - s->center[q % 3]), HL_CAPTURE_MAX_DIST);
        }
        for (int q = 0; q < 3; q++) {
            float e = s->emission[3 * (size_t)i + q];
            if (!isfinite(e) || e < 0.0f)
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: triangle %u emits %g in channel %d: radiance must be finite and >= 0",
                               i, (double)e, q);
        }
    }
    if (s->fallback_L)
        for (uint32_t j = 0; j < 3 * ncoef; j++)
            if (!isfinite(s->fallback_L[j]) || s->fallback_L[j] < 0.0f)
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: the fallback lighting's value %u is %g: it must be finite and >= 0",
                               j, (double)s->fallback_L[j]);
    return HL_OK;
}

/* The triangle's plane (unit normal away from the capture point, and its
 * distance) and its edges' planes through the capture point (unit normals
 * into its view), from the rounded corners c; the edges' normals 0 when
 * the plane passes (nearly) through the capture point, so that nothing is
 * taken as covered by a triangle seen edge-on. */
static void pack_planes(const double c[3][3], float *o)
{
    double e1[3], e2[3], m[3], lm = 0.0, cmax = 0.0;
    for (int a = 0; a < 3; a++) {
        e1[a] = c[1][a] - c[0][a];
        e2[a] = c[2][a] - c[0][a];
    }
    m[0] = e1[1] * e2[2] - e1[2] * e2[1];
    m[1] = e1[2] * e2[0] - e1[0] * e2[2];
    m[2] = e1[0] * e2[1] - e1[1] * e2[0];
    for (int a = 0; a < 3; a++) lm += m[a] * m[a];
    for (int v = 0; v < 3; v++)
        cmax = fmax(cmax, sqrt(c[v][0] * c[v][0] + c[v][1] * c[v][1] + c[v][2] * c[v][2]));
    lm = sqrt(lm);
    double d = lm > 0.0 ? (m[0] * c[0][0] + m[1] * c[0][1] + m[2] * c[0][2]) / lm : 0.0;
    const double sg = d < 0.0 ? -1.0 : 1.0;
    for (int k = 24; k < 40; k++) o[k] = 0.0f;
    for (int a = 0; a < 3 && lm > 0.0; a++) o[24 + a] = (float)(sg * m[a] / lm);
    o[27] = (float)fabs(d);
    /* 1e-6 of the farthest corner: the plane's distance is then far
       above its rounding, and the view a solid angle, not a sliver */
    if (!(fabs(d) > 1e-6 * cmax)) return;
    for (int k = 0; k < 3; k++) {
        const double *p = c[(k + 1) % 3], *q = c[(k + 2) % 3], *r = c[k];
        double n[3] = {p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]};
        double ln = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), side = n[0] * r[0] + n[1] * r[1] + n[2] * r[2];
        if (!(ln > 0.0) || side == 0.0) {
            for (int z = 28; z < 40; z++) o[z] = 0.0f;
            return;
        }
        for (int a = 0; a < 3; a++) o[28 + 4 * k + a] = (float)((side > 0.0 ? 1.0 : -1.0) * n[a] / ln);
    }
}

/* Unit direction through (s, t) of a map whose pole is sy * Y. */
static void para_dir(double s, double t, double sy, double d[3])
{
    const double r2 = s * s + t * t, k = 1.0 / (1.0 + r2);
    d[0] = 2.0 * s * k;
    d[1] = sy * (1.0 - r2) * k;
    d[2] = 2.0 * t * k;
}

/* Whether a ray of texel (col, row) lands in the disc: the float sums
 * the kernel and the twin make. */
static int any_ray_in_disc(uint32_t N, uint32_t S, uint32_t col, uint32_t row)
{
    float h = 2.0f / (float)N, hs = h / (float)S;
    float s0 = -1.0f + (float)col * h, t0 = -1.0f + (float)row * h;
    for (uint32_t a = 0; a < S; a++)
        for (uint32_t b = 0; b < S; b++) {
            float s = s0 + ((float)b + 0.5f) * hs, t = t0 + ((float)a + 0.5f) * hs;
            if (!(s * s + t * t > 1.0f)) return 1;
        }
    return 0;
}

/* The cone holding the square [s0, s0 + w] x [t0, t0 + w] of the map
 * whose pole is sy * Y (HL_CAPTURE_CONE_FLOATS, the flag left as is):
 * about the direction through its centre, through its farthest corner.
 * The square's preimage of that cap is a disc (the cap is far from the
 * map's opposite pole), which holds the corners, so all of the square. */
static void square_cone(double s0, double t0, double w, double sy, float *o)
{
    double axis[3], beta = 0.0;
    para_dir(s0 + 0.5 * w, t0 + 0.5 * w, sy, axis);
    const double cs[4][2] = {{s0, t0}, {s0 + w, t0}, {s0, t0 + w}, {s0 + w, t0 + w}};
    for (int k = 0; k < 4; k++) {
        double d[3];
        para_dir(cs[k][0], cs[k][1], sy, d);
        double dp = axis[0] * d[0] + axis[1] * d[1] + axis[2] * d[2];
        beta = fmax(beta, acos(dp > 1.0 ? 1.0 : dp < -1.0 ? -1.0 : dp));
    }
    beta += HL_CAPTURE_CONE_MARGIN;
    for (int a = 0; a < 3; a++) o[a] = (float)axis[a];
    o[4] = (float)cos(beta);
    o[5] = (float)sin(beta);
    o[6] = beta + HL_CAPTURE_COVER_MARGIN < 0.5 * HL_PI ? (float)sin(beta + HL_CAPTURE_COVER_MARGIN) : 2.0f;
    o[7] = (float)beta;
}

void hl_capture_texel_cones(uint32_t N, uint32_t S, float *cones)
{
    const double h = 2.0 / N;
    for (uint32_t j = 0; j < 2 * N * N; j++) {
        uint32_t map = j / (N * N), rem = j % (N * N), row = rem / N, col = rem % N;
        const double s0 = -1.0 + col * h, t0 = -1.0 + row * h, s1 = s0 + h, t1 = t0 + h;
        /* the texel's point nearest the pole: none of it in the disc, no light */
        const double ns = s0 > 0.0 ? s0 : (s1 < 0.0 ? s1 : 0.0), nt = t0 > 0.0 ? t0 : (t1 < 0.0 ? t1 : 0.0);
        float *o = cones + HL_CAPTURE_CONE_FLOATS * (size_t)j;
        square_cone(s0, t0, h, map ? -1.0 : 1.0, o);
        o[3] = !(ns * ns + nt * nt < 1.0) ? 0.0f : any_ray_in_disc(N, S, col, row) ? 1.0f : 2.0f;
    }
}

void hl_capture_tile_cones(uint32_t N, float *cones)
{
    (void)N; /* a tile is the same square of the map at every N */
    const double w = 2.0 / HL_CAPTURE_TILES;
    for (uint32_t k = 0; k < HL_CAPTURE_NTILES; k++) {
        uint32_t map = k / (HL_CAPTURE_TILES * HL_CAPTURE_TILES), rem = k % (HL_CAPTURE_TILES * HL_CAPTURE_TILES);
        float *o = cones + HL_CAPTURE_CONE_FLOATS * (size_t)k;
        square_cone(-1.0 + (rem % HL_CAPTURE_TILES) * w, -1.0 + (rem / HL_CAPTURE_TILES) * w, w, map ? -1.0 : 1.0, o);
        o[3] = 1.0f;
    }
}

/* Corners relative to the centre (in double, then rounded once), the two
 * edges, so every ray starts at the origin, and a cone from the origin
 * holding the triangle (from the rounded corners the kernel tests): the
 * narrower of the one around its bounding sphere and the one around its
 * corners' directions; everything (half-angle 4 > pi) when neither holds. */
void hl_capture_pack(const hl_capture_scene *s, float *tris)
{
    for (uint32_t i = 0; i < s->triangle_count; i++) {
        const float *p = s->positions + 9 * (size_t)i;
        float *o = tris + HL_CAPTURE_FLOATS * (size_t)i;
        for (int a = 0; a < 3; a++) {
            o[a] = (float)((double)p[a] - s->center[a]);
            o[4 + a] = (float)((double)p[3 + a] - p[a]);
            o[8 + a] = (float)((double)p[6 + a] - p[a]);
            o[12 + a] = s->emission[3 * (size_t)i + a];
        }
        o[3] = o[7] = o[11] = o[15] = 0.0f;
        double c[3][3], m[3] = {0, 0, 0}, R2 = 0.0, d2 = 0.0;
        for (int a = 0; a < 3; a++) {
            c[0][a] = o[a];
            c[1][a] = (double)o[a] + o[4 + a];
            c[2][a] = (double)o[a] + o[8 + a];
            m[a] = (c[0][a] + c[1][a] + c[2][a]) / 3.0;
            d2 += m[a] * m[a];
        }
        for (int v = 0; v < 3; v++) {
            double e2 = 0.0;
            for (int a = 0; a < 3; a++) e2 += (c[v][a] - m[a]) * (c[v][a] - m[a]);
            if (e2 > R2) R2 = e2;
        }
        double R = sqrt(R2) * (1.0 + 1e-6), d = sqrt(d2), axis[3] = {0, 0, 0}, alpha = 4.0;
        if (d > R) {
            for (int a = 0; a < 3; a++) axis[a] = m[a] / d;
            alpha = asin(R / d);
        }
        /* a large triangle close by: the cap around its corners' mean
           direction through the farthest corner holds it when that cap is
           less than a hemisphere (such a cap is convex on the sphere) */
        double u[3][3], sum[3] = {0, 0, 0}, ls = 0.0;
        int ok = 1;
        for (int v = 0; v < 3; v++) {
            double l = sqrt(c[v][0] * c[v][0] + c[v][1] * c[v][1] + c[v][2] * c[v][2]);
            if (l == 0.0) ok = 0;
            for (int a = 0; a < 3 && ok; a++) {
                u[v][a] = c[v][a] / l;
                sum[a] += u[v][a];
            }
        }
        for (int a = 0; a < 3 && ok; a++) ls += sum[a] * sum[a];
        if (ok && ls > 0.0) {
            double cmin = 1.0;
            for (int v = 0; v < 3; v++) {
                double dp = (sum[0] * u[v][0] + sum[1] * u[v][1] + sum[2] * u[v][2]) / sqrt(ls);
                if (dp < cmin) cmin = dp;
            }
            double beta = acos(cmin > 1.0 ? 1.0 : cmin) * (1.0 + 1e-6);
            if (beta < 0.5 * HL_PI - 1e-3 && beta < alpha) {
                for (int a = 0; a < 3; a++) axis[a] = sum[a] / sqrt(ls);
                alpha = beta;
            }
        }
        for (int a = 0; a < 3; a++) o[16 + a] = (float)axis[a];
        o[19] = alpha >= 4.0 ? 4.0f : nextafterf((float)alpha, 4.0f);
        o[20] = (float)cos((double)o[19]);
        o[21] = (float)sin((double)o[19]);
        o[22] = o[23] = 0.0f;
        pack_planes(c, o);
    }
}

typedef struct ref_job {
    const hl_capture *c;
    hl_capture_tables tb;
    const float *env_L;
    float *L;
    atomic_uint next;
} ref_job;

static void *ref_worker(void *arg)
{
    ref_job *j = arg;
    const hl_capture *c = j->c;
    for (;;) {
        uint32_t t0 = atomic_fetch_add(&j->next, HL_CAPTURE_CHUNK);
        if (t0 >= c->ncoef) break;
        uint32_t t1 = t0 + HL_CAPTURE_CHUNK < c->ncoef ? t0 + HL_CAPTURE_CHUNK : c->ncoef;
        for (uint32_t t = t0; t < t1; t++) hl_ref_capture_texel(&j->tb, c->N, c->S, j->env_L, 1, t, j->L);
    }
    return NULL;
}

/* Enqueues the capture of the packed triangles on the device: fallback
 * lighting from env (a cl_mem of 3 x ncoef floats, or NULL for black),
 * output into L (the same size). Nothing waits: c->tris is read by the
 * upload until the queue has passed it, so the caller waits (a blocking
 * read or clFinish) before the next pack. */
static hl_result enqueue_device(hl_capture *c, uint32_t ntris, cl_mem env, cl_mem L)
{
    hl_context *ctx = c->ctx;
    cl_command_queue q = ctx->cl->queue;
    size_t tbytes = (size_t)ntris * HL_CAPTURE_FLOATS * 4;
    CL_TRY(ctx, clEnqueueWriteBuffer(q, c->tris_d, CL_FALSE, 0, tbytes, c->tris, 0, NULL, NULL), "uploading the surroundings");
    const hl_capture_accel *a = &c->acc;
    CL_TRY(ctx, clEnqueueWriteBuffer(q, c->tstart_d, CL_FALSE, 0, sizeof a->tile_start, a->tile_start, 0, NULL, NULL),
           "uploading the tile lists");
    if (a->tile_start[HL_CAPTURE_NTILES])
        CL_TRY(ctx, clEnqueueWriteBuffer(q, c->tlist_d, CL_FALSE, 0, (size_t)a->tile_start[HL_CAPTURE_NTILES] * 4,
                                         a->tile_list, 0, NULL, NULL),
               "uploading the tile lists");
    CL_TRY(ctx, clEnqueueWriteBuffer(q, c->nodes_d, CL_FALSE, 0, (size_t)a->nnodes * HL_CAPTURE_NODE_FLOATS * 4, a->nodes, 0,
                                     NULL, NULL),
           "uploading the hierarchy");
    CL_TRY(ctx, clEnqueueWriteBuffer(q, c->links_d, CL_FALSE, 0, (size_t)a->nnodes * 8, a->links, 0, NULL, NULL),
           "uploading the hierarchy");
    CL_TRY(ctx, clEnqueueWriteBuffer(q, c->order_d, CL_FALSE, 0, (size_t)ntris * 4, a->order, 0, NULL, NULL),
           "uploading the hierarchy");
    cl_uint have_env = env != NULL;
    cl_mem envm = env ? env : c->env_d; /* an unused argument still needs a buffer */
    cl_uint nt = ntris, N = c->N, S = c->S;
#define SETARG(i, v) CL_TRY(ctx, clSetKernelArg(c->k, i, sizeof(v), &(v)), "clSetKernelArg (hl_capture)")
    SETARG(0, c->tris_d);
    SETARG(1, nt);
    SETARG(2, N);
    SETARG(3, S);
    SETARG(4, envm);
    SETARG(5, have_env);
    SETARG(6, L);
    SETARG(7, c->cones_d);
    SETARG(8, c->tstart_d);
    SETARG(9, c->tlist_d);
    SETARG(10, c->nodes_d);
    SETARG(11, c->links_d);
    SETARG(12, c->order_d);
#undef SETARG
    size_t local = ctx->cl->wg ? ctx->cl->wg : 1;
    size_t global = ((size_t)c->ncoef + local - 1) / local * local;
    CL_TRY(ctx, clEnqueueNDRangeKernel(q, c->k, 1, NULL, &global, &local, 0, NULL, NULL), "hl_capture");
    return HL_OK;
}

static hl_result run_device(hl_capture *c, uint32_t ntris, const float *env_L, float *L)
{
    hl_context *ctx = c->ctx;
    cl_command_queue q = ctx->cl->queue;
    if (env_L)
        CL_TRY(ctx, clEnqueueWriteBuffer(q, c->env_d, CL_FALSE, 0, (size_t)c->ncoef * 12, env_L, 0, NULL, NULL),
               "uploading the fallback lighting");
    hl_result r = enqueue_device(c, ntris, env_L ? c->env_d : NULL, c->L_d);
    if (r != HL_OK) {
        clFinish(q);
        return r;
    }
    CL_TRY(ctx, clEnqueueReadBuffer(q, c->L_d, CL_TRUE, 0, (size_t)c->ncoef * 12, L, 0, NULL, NULL), "reading the captured lighting");
    return HL_OK;
}

/* Makes *m hold at least bytes (room: what it holds now), growing by
 * half again so that a scene growing a little at a time is not
 * reallocated each capture. */
static hl_result grow_buf(hl_context *ctx, cl_mem *m, size_t *room, size_t bytes, const char *what)
{
    if (bytes <= *room && *m) return HL_OK;
    hl_cl_release_buf(ctx->cl, m);
    *room = 0;
    size_t want = bytes + bytes / 2;
    hl_result r = hl_cl_make_buf(ctx, m, CL_MEM_READ_ONLY, want ? want : 4, NULL, what);
    if (r == HL_OK) *room = want;
    return r;
}

/* Checks scene, packs its triangles into c->tris and builds the
 * hierarchy and the tiles' lists (growing them and the device's copies as
 * needed). No cap on the triangles: memory grows with them (about
 * hl_capture_usage's bytes), time with the triangles the texels' rays
 * meet (docs/CAPTURE.md). */
static hl_result load_scene(hl_capture *c, const hl_capture_scene *scene)
{
    hl_context *ctx = c->ctx;
    hl_result r = hl_capture_check(ctx, c->ncoef, scene);
    if (r != HL_OK) return r;
    const uint32_t n = scene->triangle_count;
    if (n > c->cap_tris) {
        float *p = realloc(c->tris, (size_t)n * HL_CAPTURE_FLOATS * 4);
        if (!p) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "capture: out of memory for %u triangles", n);
        c->tris = p;
        c->cap_tris = n;
    }
    hl_capture_pack(scene, c->tris);
    if (!hl_capture_accel_build(&c->acc, c->tris, n, c->tile_cones))
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "capture: out of memory for the hierarchy of %u triangles", n);
    c->ntris = n;
    if (ctx->cl) {
        const hl_capture_accel *a = &c->acc;
        r = grow_buf(ctx, &c->tris_d, &c->dev_tris, (size_t)n * HL_CAPTURE_FLOATS * 4, "the surroundings");
        if (r == HL_OK)
            r = grow_buf(ctx, &c->tlist_d, &c->dev_list, (size_t)a->tile_start[HL_CAPTURE_NTILES] * 4,
                         "the capture's tile lists");
        if (r == HL_OK)
            r = grow_buf(ctx, &c->nodes_d, &c->dev_nodes, (size_t)a->nnodes * HL_CAPTURE_NODE_FLOATS * 4,
                         "the capture's hierarchy");
        if (r == HL_OK) r = grow_buf(ctx, &c->links_d, &c->dev_links, (size_t)a->nnodes * 8, "the capture's hierarchy");
        if (r == HL_OK) r = grow_buf(ctx, &c->order_d, &c->dev_order, (size_t)n * 4, "the capture's hierarchy");
    }
    return r;
}

void hl_capture_usage(const hl_capture *c, uint32_t *triangles, size_t *host_bytes, size_t *device_bytes)
{
    const size_t maps = (size_t)c->ncoef * HL_CAPTURE_CONE_FLOATS * 4 + (size_t)HL_CAPTURE_NTILES * HL_CAPTURE_CONE_FLOATS * 4;
    if (triangles) *triangles = c->ntris;
    if (host_bytes) *host_bytes = sizeof *c + maps + (size_t)c->cap_tris * HL_CAPTURE_FLOATS * 4 + hl_capture_accel_bytes(&c->acc);
    if (device_bytes) {
        size_t d = 0;
        if (c->ctx->cl) {
            /* the texel table, the two maps, the grown buffers */
            d = (size_t)c->ncoef * HL_CAPTURE_CONE_FLOATS * 4 + 2 * (size_t)c->ncoef * 12 + sizeof c->acc.tile_start;
            d += c->dev_tris + c->dev_list + c->dev_nodes + c->dev_links + c->dev_order;
        }
        *device_bytes = d;
    }
}

hl_result hl_capture_enqueue(hl_capture *c, const hl_capture_scene *scene, void *env_mem, void *L_mem)
{
    if (!c->ctx->cl) return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "capture: a device buffer needs the OpenCL backend");
    if (scene->fallback_L)
        return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "capture: the fallback lighting goes in env_mem here");
    hl_result r = load_scene(c, scene);
    if (r != HL_OK) return r;
    return enqueue_device(c, scene->triangle_count, (cl_mem)env_mem, (cl_mem)L_mem);
}

hl_result hl_capture_run(hl_capture *c, const hl_capture_scene *scene, float *L)
{
    hl_context *ctx = c->ctx;
    if (!L) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: no output map given");
    hl_result r = load_scene(c, scene);
    if (r != HL_OK) return r;
    const uint32_t n = scene->triangle_count;
    if (ctx->cl) return run_device(c, n, scene->fallback_L, L);
    const hl_capture_accel *a = &c->acc;
    ref_job job = {c, {c->tris, n, c->cones, a->tile_start, a->tile_list, a->nodes, a->links, a->order}, scene->fallback_L, L, 0};
    atomic_init(&job.next, 0u);
    hl_run_threads(ctx->threads, ref_worker, &job);
    return HL_OK;
}
