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
    float *tris;         /* 16 floats per triangle, packed */
    uint32_t cap_tris;   /* triangles tris (and tris_d) have room for */
    cl_kernel k;
    cl_mem tris_d, env_d, L_d;
};

void hl_capture_destroy(hl_capture *c)
{
    if (!c) return;
    if (c->ctx->cl) {
        if (c->k) clReleaseKernel(c->k);
        hl_cl_release_buf(c->ctx->cl, &c->tris_d);
        hl_cl_release_buf(c->ctx->cl, &c->env_d);
        hl_cl_release_buf(c->ctx->cl, &c->L_d);
    }
    free(c->tris);
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
    if (ctx->cl) {
        cl_int e;
        c->k = clCreateKernel(ctx->cl->program, "hl_capture", &e);
        hl_result r = e == CL_SUCCESS ? HL_OK
                                      : hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: the kernel hl_capture: %s (%d)", hl_cl_err_name(e), (int)e);
        if (r == HL_OK) r = hl_cl_make_buf(ctx, &c->env_d, CL_MEM_READ_ONLY, (size_t)c->ncoef * 12, NULL, "the capture's fallback lighting");
        if (r == HL_OK) r = hl_cl_make_buf(ctx, &c->L_d, CL_MEM_WRITE_ONLY, (size_t)c->ncoef * 12, NULL, "the captured lighting");
        if (r != HL_OK) {
            hl_capture_destroy(c);
            return r;
        }
    }
    *out = c;
    return HL_OK;
}

static hl_result check_scene(hl_context *ctx, uint32_t ncoef, const hl_capture_scene *s)
{
    if (!s || !s->positions || !s->emission || s->triangle_count == 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: no surroundings (no triangles given)");
    if (s->triangle_count > HL_CAPTURE_MAX_TRIS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: %u triangles: at most %u (every ray tests every triangle)",
                       s->triangle_count, HL_CAPTURE_MAX_TRIS);
    for (int a = 0; a < 3; a++)
        if (!isfinite(s->center[a]))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: the capture point is not finite");
    for (uint32_t i = 0; i < s->triangle_count; i++) {
        for (int q = 0; q < 9; q++)
            if (!isfinite(s->positions[9 * (size_t)i + q]))
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: triangle %u has a corner that is not finite", i);
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
    }
}

typedef struct ref_job {
    const hl_capture *c;
    uint32_t ntris;
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
        for (uint32_t t = t0; t < t1; t++) hl_ref_capture_texel(c->tris, j->ntris, c->N, c->S, j->env_L, 1, t, j->L);
    }
    return NULL;
}

static hl_result run_device(hl_capture *c, uint32_t ntris, const float *env_L, float *L)
{
    hl_context *ctx = c->ctx;
    cl_command_queue q = ctx->cl->queue;
    size_t tbytes = (size_t)ntris * HL_CAPTURE_FLOATS * 4;
    CL_TRY(ctx, clEnqueueWriteBuffer(q, c->tris_d, CL_FALSE, 0, tbytes, c->tris, 0, NULL, NULL), "uploading the surroundings");
    cl_uint have_env = env_L != NULL;
    if (env_L)
        CL_TRY(ctx, clEnqueueWriteBuffer(q, c->env_d, CL_FALSE, 0, (size_t)c->ncoef * 12, env_L, 0, NULL, NULL),
               "uploading the fallback lighting");
    cl_uint nt = ntris, N = c->N, S = c->S;
#define SETARG(i, v) CL_TRY(ctx, clSetKernelArg(c->k, i, sizeof(v), &(v)), "clSetKernelArg (hl_capture)")
    SETARG(0, c->tris_d);
    SETARG(1, nt);
    SETARG(2, N);
    SETARG(3, S);
    SETARG(4, c->env_d);
    SETARG(5, have_env);
    SETARG(6, c->L_d);
#undef SETARG
    size_t local = ctx->cl->wg ? ctx->cl->wg : 1;
    size_t global = ((size_t)c->ncoef + local - 1) / local * local;
    CL_TRY(ctx, clEnqueueNDRangeKernel(q, c->k, 1, NULL, &global, &local, 0, NULL, NULL), "hl_capture");
    CL_TRY(ctx, clEnqueueReadBuffer(q, c->L_d, CL_TRUE, 0, (size_t)c->ncoef * 12, L, 0, NULL, NULL), "reading the captured lighting");
    return HL_OK;
}

hl_result hl_capture_run(hl_capture *c, const hl_capture_scene *scene, float *L)
{
    hl_context *ctx = c->ctx;
    if (!L) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "capture: no output map given");
    hl_result r = check_scene(ctx, c->ncoef, scene);
    if (r != HL_OK) return r;
    const uint32_t n = scene->triangle_count;
    if (n > c->cap_tris) {
        float *p = realloc(c->tris, (size_t)n * HL_CAPTURE_FLOATS * 4);
        if (!p) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "capture: out of memory for %u triangles", n);
        c->tris = p;
        if (ctx->cl) {
            hl_cl_release_buf(ctx->cl, &c->tris_d);
            r = hl_cl_make_buf(ctx, &c->tris_d, CL_MEM_READ_ONLY, (size_t)n * HL_CAPTURE_FLOATS * 4, NULL, "the surroundings");
            if (r != HL_OK) {
                c->cap_tris = 0;
                return r;
            }
        }
        c->cap_tris = n;
    }
    hl_capture_pack(scene, c->tris);
    if (ctx->cl) return run_device(c, n, scene->fallback_L, L);
    ref_job job = {c, n, scene->fallback_L, L, 0};
    atomic_init(&job.next, 0u);
    hl_run_threads(ctx->threads, ref_worker, &job);
    return HL_OK;
}
