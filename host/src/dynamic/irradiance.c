/* irradiance.c - the dynamic method's per-vertex irradiance: a split's
 * kept lights packed into tables (kept on the device across frames) and
 * E_k(n) and the SH9 ambient at every receiver, by the kernels of
 * kernels/dynamic/dyn_irradiance.cl, or their twins on the context's
 * threads on the reference backend.
 * Depends on: irradiance.h, area_lights.h, cl_internal.h (OpenCL: buffers,
 * CL_TRY), core (hl_run_threads).
 */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"
#include "irradiance.h"

struct hl_dyn_irr {
    hl_context *ctx;
    hl_dyn_irr_tables t;
    /* OpenCL */
    cl_kernel kl, ka;
    cl_mem lf_d, lu_d, mom_d, pre_d, sh_d; /* the split's tables */
    cl_mem n_d, E_d, amb_d, any_d;         /* per run, grown as needed */
    size_t cap_n, cap_e;                   /* receivers; E floats */
    cl_uint *any_h;                        /* K */
    double t_compute, t_total;             /* of the last run, seconds */
};

/* face_point(s, t) = o + s ds + t dt for the six faces, OpenGL order (as
 * area_lights.c's face_point and geom.c's hl_cube_face_dir) */
static const float face_axes[6][9] = {
    {1, 0, 0, 0, 0, -1, 0, -1, 0}, {-1, 0, 0, 0, 0, 1, 0, -1, 0}, {0, 1, 0, 1, 0, 0, 0, 0, 1},
    {0, -1, 0, 1, 0, 0, 0, 0, -1}, {0, 0, 1, 1, 0, 0, 0, -1, 0},  {0, 0, -1, -1, 0, 0, 0, -1, 0},
};

static void free_tables(hl_dyn_irr_tables *t)
{
    free(t->lf);
    free(t->lu);
    hl_free_big(t->mom);
    hl_free_big(t->pre);
    memset(t, 0, sizeof *t);
}

/* The folded term as one quadratic a channel: hl_light_sh9's basis times
 * Ramamoorthi and Hanrahan's A_l, summed in double, rounded once. */
static void pack_ambient(const hl_light_split *s, float sh[27])
{
    const double c0 = 0.5 * sqrt(1.0 / HL_PI), c1 = sqrt(3.0 / (4.0 * HL_PI)), c2 = sqrt(15.0 / (4.0 * HL_PI)),
                 c20 = sqrt(5.0 / (16.0 * HL_PI)), c22 = sqrt(15.0 / (16.0 * HL_PI));
    const double A0 = HL_PI, A1 = 2.0 * HL_PI / 3.0, A2 = HL_PI / 4.0;
    for (int c = 0; c < 3; c++) {
        double u[9];
        for (int k = 0; k < 9; k++) u[k] = s->ambient_sh[k][c];
        double q[9] = {
            A0 * c0 * u[0] - A2 * c20 * u[6], /* Y20's -1 joins the constant */
            A1 * c1 * u[3], A1 * c1 * u[1], A1 * c1 * u[2],
            A2 * c2 * u[4], A2 * c2 * u[5], 3.0 * A2 * c20 * u[6], A2 * c2 * u[7], A2 * c22 * u[8],
        };
        for (int k = 0; k < 9; k++) sh[9 * c + k] = (float)q[k];
    }
}

/* Checks the split's rectangles and counts the texels and prefix entries
 * of both views. */
static hl_result measure(hl_context *ctx, const hl_light_split *s, size_t *texels, size_t *entries)
{
    *texels = *entries = 0;
    if (s->F < HL_LIGHTS_MIN_FACE || s->F > HL_LIGHTS_MAX_FACE || (s->count && !s->lights) || s->count > s->total ||
        (s->count && !s->texel_moment))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic irradiance: the light split is malformed (F = %u, %u "
                       "of %u lights kept)", s->F, s->count, s->total);
    for (uint32_t k = 0; k < s->count; k++) {
        const hl_area_light *l = &s->lights[k];
        if (l->face >= 6 || l->x0 >= l->x1 || l->x1 > s->F || l->y0 >= l->y1 || l->y1 > s->F)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "dynamic irradiance: light %u's rectangle (face %u, x %u..%u, y %u..%u) is not on a "
                           "%u x %u face", k, l->face, l->x0, l->x1, l->y0, l->y1, s->F, s->F);
        size_t w = l->x1 - l->x0, h = l->y1 - l->y0;
        *texels += 2 * w * h;
        *entries += 2 * (h * (w + 1) + (h + 1) + w * (h + 1) + (w + 1));
    }
    return HL_OK;
}

/* 2 (n + 1) entries from n sums of 9 (v[9 i + k]): prefix sums, then
 * suffix sums, each added in double from its own end and rounded once. */
static void put_sums(float *e, const double *v, uint32_t n)
{
    double acc[9] = {0};
    for (uint32_t i = 0; i <= n; i++) {
        for (int k = 0; k < 9; k++) {
            if (i > 0) acc[k] += v[9 * (size_t)(i - 1) + (size_t)k];
            e[9 * (size_t)i + (size_t)k] = (float)acc[k];
        }
    }
    memset(acc, 0, sizeof acc);
    for (uint32_t i = n + 1; i-- > 0;) {
        for (int k = 0; k < 9; k++) {
            if (i < n) acc[k] += v[9 * (size_t)i + (size_t)k];
            e[9 * ((size_t)n + 1 + i) + (size_t)k] = (float)acc[k];
        }
    }
}

/* One view of light l (by columns: rows and columns swapped) at texel T
 * and entry P: its uints, texels, row sums and row-total sums. row holds
 * 9 doubles per texel of a row, tot 9 per row. Returns the entries used. */
static size_t pack_view(const hl_light_split *s, const hl_area_light *l, int by_cols, hl_dyn_irr_tables *t, size_t T,
                        size_t P, uint32_t *vu, double *row, double *tot)
{
    const uint32_t F = s->F;
    const uint32_t c0 = by_cols ? l->y0 : l->x0, c1 = by_cols ? l->y1 : l->x1;
    const uint32_t r0 = by_cols ? l->x0 : l->y0, r1 = by_cols ? l->x1 : l->y1, w = c1 - c0, h = r1 - r0;
    const size_t B = P + (size_t)h * 2 * (w + 1);
    uint32_t u[HL_DYN_IRR_VIEW] = {c0, c1, r0, r1, (uint32_t)T, (uint32_t)P, (uint32_t)B, 0};
    memcpy(vu, u, sizeof u);
    for (uint32_t i = r0; i < r1; i++) {
        double *rt = tot + 9 * (size_t)(i - r0);
        memset(rt, 0, 9 * sizeof(double));
        for (uint32_t j = c0; j < c1; j++) {
            uint32_t x = by_cols ? i : j, y = by_cols ? j : i;
            const float *m = s->texel_moment + 9 * ((size_t)l->face * F * F + (size_t)y * F + x);
            memcpy(t->mom + 9 * (T + (size_t)(i - r0) * w + (j - c0)), m, 9 * sizeof(float));
            for (int k = 0; k < 9; k++) {
                row[9 * (size_t)(j - c0) + (size_t)k] = m[k];
                rt[k] += m[k];
            }
        }
        put_sums(t->pre + HL_DYN_IRR_PRE * (P + (size_t)(i - r0) * 2 * (w + 1)), row, w);
    }
    put_sums(t->pre + HL_DYN_IRR_PRE * B, tot, h);
    return (size_t)h * 2 * (w + 1) + 2 * ((size_t)h + 1);
}

/* One light's blocks and both views; advances *T and *P. scratch: 9 F
 * doubles twice. */
static void pack_light(const hl_light_split *s, uint32_t k, hl_dyn_irr_tables *t, size_t *T, size_t *P,
                       double *scratch)
{
    const hl_area_light *l = &s->lights[k];
    float *lf = t->lf + (size_t)HL_DYN_IRR_LF * k;
    memcpy(lf, l->dir, 3 * sizeof(float));
    /* the host's test, bit for bit (area_lights.c) */
    lf[3] = l->extent < (float)(0.5 * HL_PI) ? sinf(l->extent) : 2.0f;
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < 3; i++) lf[4 + 3 * c + i] = l->evec[c][i];
    memcpy(lf + 13, face_axes[l->face], 9 * sizeof(float));
    lf[22] = 2.0f / (float)s->F; /* texel units to face coordinates */
    lf[23] = 0.0f;
    const size_t n = (size_t)(l->x1 - l->x0) * (l->y1 - l->y0);
    for (int v = 0; v < 2; v++) {
        *P += pack_view(s, l, v, t, *T, *P, t->lu + (size_t)HL_DYN_IRR_LU * k + HL_DYN_IRR_VIEW * (size_t)v, scratch,
                        scratch + 9 * (size_t)s->F);
        *T += n;
    }
}

static hl_result pack(hl_context *ctx, const hl_light_split *s, hl_dyn_irr_tables *t)
{
    memset(t, 0, sizeof *t);
    size_t texels, entries;
    TRY(measure(ctx, s, &texels, &entries));
    if (texels > UINT32_MAX || entries > UINT32_MAX)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic irradiance: %zu texels in the kept lights (at most %u)",
                       texels, UINT32_MAX);
    const size_t K = s->count ? s->count : 1; /* no zero-sized arrays */
    t->lf = hl_malloc(ctx, K * HL_DYN_IRR_LF * sizeof(float), "the lights' irradiance tables");
    t->lu = hl_malloc(ctx, K * HL_DYN_IRR_LU * sizeof(uint32_t), "the lights' irradiance tables");
    t->mom = hl_alloc_big(ctx, (texels ? texels : 1) * 9 * sizeof(float), "the lights' texel moments");
    t->pre = hl_alloc_big(ctx, (entries ? entries : 1) * HL_DYN_IRR_PRE * sizeof(float), "the lights' row sums");
    if (!t->lf || !t->lu || !t->mom || !t->pre) {
        free_tables(t);
        return HL_ERR_OUT_OF_MEMORY;
    }
    t->K = s->count;
    t->F = s->F;
    t->texels = texels;
    t->entries = entries;
    double *scratch = hl_malloc(ctx, 18 * (size_t)s->F * sizeof(double), "the lights' row sums");
    if (!scratch) {
        free_tables(t);
        return HL_ERR_OUT_OF_MEMORY;
    }
    size_t T = 0, P = 0;
    for (uint32_t k = 0; k < s->count; k++) pack_light(s, k, t, &T, &P, scratch);
    free(scratch);
    pack_ambient(s, t->sh);
    return HL_OK;
}

/* ---------------------------------------------------------------- device */

static void release_tables_d(hl_dyn_irr *m)
{
    struct hl_cl *cl = m->ctx->cl;
    cl_mem *all[] = {&m->lf_d, &m->lu_d, &m->mom_d, &m->pre_d, &m->sh_d, &m->any_d};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) hl_cl_release_buf(cl, all[i]);
}

static hl_result upload_tables(hl_dyn_irr *m)
{
    hl_context *ctx = m->ctx;
    const hl_dyn_irr_tables *t = &m->t;
    const size_t K = t->K ? t->K : 1, ne = t->entries ? t->entries : 1, nt = t->texels ? t->texels : 1;
    const cl_mem_flags ro = CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR;
    TRY(hl_cl_make_buf(ctx, &m->lf_d, ro, K * HL_DYN_IRR_LF * 4, t->lf, "irradiance light blocks"));
    TRY(hl_cl_make_buf(ctx, &m->lu_d, ro, K * HL_DYN_IRR_LU * 4, t->lu, "irradiance light blocks"));
    TRY(hl_cl_make_buf(ctx, &m->mom_d, ro, nt * 9 * 4, t->mom, "irradiance texel moments"));
    TRY(hl_cl_make_buf(ctx, &m->pre_d, ro, ne * HL_DYN_IRR_PRE * 4, t->pre, "irradiance row sums"));
    TRY(hl_cl_make_buf(ctx, &m->sh_d, ro, sizeof t->sh, t->sh, "irradiance ambient"));
    TRY(hl_cl_make_buf(ctx, &m->any_d, CL_MEM_READ_WRITE, K * 4, NULL, "irradiance light flags"));
    return HL_OK;
}

void hl_dyn_irr_destroy(hl_dyn_irr *m)
{
    if (!m) return;
    struct hl_cl *cl = m->ctx->cl;
    if (cl) {
        if (cl->queue) clFinish(cl->queue);
        release_tables_d(m);
        cl_mem *io[] = {&m->n_d, &m->E_d, &m->amb_d};
        for (size_t i = 0; i < 3; i++) hl_cl_release_buf(cl, io[i]);
        if (m->kl) clReleaseKernel(m->kl);
        if (m->ka) clReleaseKernel(m->ka);
    }
    free_tables(&m->t);
    free(m->any_h);
    free(m);
}

hl_result hl_dyn_irr_set_split(hl_dyn_irr *m, const hl_light_split *split)
{
    if (!m) return HL_ERR_INVALID_ARGUMENT;
    hl_context *ctx = m->ctx;
    if (!split) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic irradiance: no light split given");
    if (ctx->cl) {
        clFinish(ctx->cl->queue);
        release_tables_d(m);
    }
    free_tables(&m->t);
    free(m->any_h);
    m->any_h = NULL;
    hl_dyn_irr_tables t;
    TRY(pack(ctx, split, &t));
    m->any_h = hl_malloc(ctx, (t.K ? t.K : 1) * sizeof *m->any_h, "irradiance light flags");
    if (!m->any_h) {
        free_tables(&t);
        return HL_ERR_OUT_OF_MEMORY;
    }
    m->t = t;
    if (ctx->cl) {
        hl_result r = upload_tables(m);
        if (r != HL_OK) {
            release_tables_d(m);
            free_tables(&m->t);
            return r;
        }
    }
    return HL_OK;
}

hl_result hl_dyn_irr_create(hl_context *ctx, const hl_light_split *split, hl_dyn_irr **out)
{
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_dyn_irr_create: no output pointer");
    *out = NULL;
    if (!ctx) return HL_ERR_INVALID_ARGUMENT;
    hl_dyn_irr *m = hl_calloc(ctx, 1, sizeof *m, "the dynamic irradiance module");
    if (!m) return HL_ERR_OUT_OF_MEMORY;
    m->ctx = ctx;
    hl_result r = HL_OK;
    if (ctx->cl) {
        cl_int e;
        m->kl = clCreateKernel(ctx->cl->program, "hl_dyn_irr_lights", &e);
        if (e == CL_SUCCESS) m->ka = clCreateKernel(ctx->cl->program, "hl_dyn_irr_ambient", &e);
        if (e != CL_SUCCESS)
            r = hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: the irradiance kernels: %s (%d); try --device ref",
                        hl_cl_err_name(e), (int)e);
    }
    if (r == HL_OK) r = hl_dyn_irr_set_split(m, split);
    if (r != HL_OK) {
        hl_dyn_irr_destroy(m);
        return r;
    }
    *out = m;
    return HL_OK;
}

const hl_dyn_irr_tables *hl_dyn_irr_get_tables(const hl_dyn_irr *m) { return m ? &m->t : NULL; }

#define SETARG(k, i, v) CL_TRY(ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")

/* The per-run buffers, grown to N receivers. */
static hl_result grow(hl_dyn_irr *m, uint32_t N)
{
    hl_context *ctx = m->ctx;
    struct hl_cl *cl = ctx->cl;
    size_t ne = (size_t)m->t.K * N * 3;
    if (N > m->cap_n) {
        hl_cl_release_buf(cl, &m->n_d);
        hl_cl_release_buf(cl, &m->amb_d);
        m->cap_n = 0;
        TRY(hl_cl_make_buf(ctx, &m->n_d, CL_MEM_READ_ONLY, (size_t)N * 12, NULL, "irradiance normals"));
        /* read and written by the device frame's sums (dyn_shade.cl) */
        TRY(hl_cl_make_buf(ctx, &m->amb_d, CL_MEM_READ_WRITE, (size_t)N * 12, NULL, "irradiance ambient"));
        m->cap_n = N;
    }
    if (ne > m->cap_e) {
        hl_cl_release_buf(cl, &m->E_d);
        m->cap_e = 0;
        TRY(hl_cl_make_buf(ctx, &m->E_d, CL_MEM_READ_WRITE, ne * 4, NULL, "the lights' irradiance"));
        m->cap_e = ne;
    }
    return HL_OK;
}

/* keep: E and the ambient (both computed) stay on the device, only any
 * comes back (hl_dyn_irr_run_kept). */
static hl_result run_device(hl_dyn_irr *m, const float *normals, uint32_t N, float *E, float *ambient, uint8_t *any,
                            int keep)
{
    hl_context *ctx = m->ctx;
    cl_command_queue q = ctx->cl->queue;
    const cl_uint K = m->t.K, n = N;
    TRY(grow(m, N));
    CL_TRY(ctx, clEnqueueWriteBuffer(q, m->n_d, CL_TRUE, 0, (size_t)N * 12, normals, 0, NULL, NULL), "upload");
    const double t0 = hl_now();
    if (K > 0) {
        const cl_uint zero = 0;
        CL_TRY(ctx, clEnqueueFillBuffer(q, m->any_d, &zero, 4, 0, (size_t)K * 4, 0, NULL, NULL), "clear");
        SETARG(m->kl, 0, m->lf_d); SETARG(m->kl, 1, m->lu_d); SETARG(m->kl, 2, m->mom_d); SETARG(m->kl, 3, m->pre_d);
        SETARG(m->kl, 4, m->n_d); SETARG(m->kl, 5, n); SETARG(m->kl, 6, K); SETARG(m->kl, 7, m->E_d);
        SETARG(m->kl, 8, m->any_d);
        size_t local[2] = {HL_DYN_IRR_WG, 1};
        size_t global[2] = {((size_t)N + HL_DYN_IRR_WG - 1) / HL_DYN_IRR_WG * HL_DYN_IRR_WG, K};
        CL_TRY(ctx, clEnqueueNDRangeKernel(q, m->kl, 2, NULL, global, local, 0, NULL, NULL), "hl_dyn_irr_lights");
    }
    if (ambient || keep) {
        SETARG(m->ka, 0, m->sh_d); SETARG(m->ka, 1, m->n_d); SETARG(m->ka, 2, n); SETARG(m->ka, 3, m->amb_d);
        size_t local = HL_DYN_IRR_WG, global = ((size_t)N + HL_DYN_IRR_WG - 1) / HL_DYN_IRR_WG * HL_DYN_IRR_WG;
        CL_TRY(ctx, clEnqueueNDRangeKernel(q, m->ka, 1, NULL, &global, &local, 0, NULL, NULL), "hl_dyn_irr_ambient");
    }
    /* the kernels alone, for hl_dyn_irr_times (one more wait, ~0.1 ms) */
    CL_TRY(ctx, clFinish(q), "the irradiance kernels");
    m->t_compute = hl_now() - t0;
    if (ambient && !keep)
        CL_TRY(ctx, clEnqueueReadBuffer(q, m->amb_d, CL_FALSE, 0, (size_t)N * 12, ambient, 0, NULL, NULL), "read-back");
    if (K > 0) {
        if (!keep)
            CL_TRY(ctx, clEnqueueReadBuffer(q, m->E_d, CL_FALSE, 0, (size_t)K * N * 12, E, 0, NULL, NULL), "read-back");
        CL_TRY(ctx, clEnqueueReadBuffer(q, m->any_d, CL_FALSE, 0, (size_t)K * 4, m->any_h, 0, NULL, NULL), "read-back");
    }
    CL_TRY(ctx, clFinish(q), "the irradiance kernels");
    for (cl_uint k = 0; any && k < K; k++) any[k] = m->any_h[k] ? 1 : 0;
    return HL_OK;
}

/* ---------------------------------------------------------------- reference */

typedef struct ref_job {
    const hl_dyn_irr_tables *t;
    const float *normals;
    uint32_t N;
    float *E, *ambient;
    atomic_uint next;
    atomic_int *any; /* K */
} ref_job;

static void *ref_worker(void *arg)
{
    ref_job *j = arg;
    const hl_dyn_irr_tables *t = j->t;
    for (;;) {
        uint32_t v0 = atomic_fetch_add(&j->next, HL_DYN_IRR_REF_CHUNK);
        if (v0 >= j->N) break;
        uint32_t v1 = j->N - v0 < HL_DYN_IRR_REF_CHUNK ? j->N : v0 + HL_DYN_IRR_REF_CHUNK;
        for (uint32_t v = v0; v < v1 && j->ambient; v++)
            hl_ref_dyn_irr_ambient(t->sh, j->normals + 3 * (size_t)v, j->ambient + 3 * (size_t)v);
        /* light by light, as the kernel's work-groups: one light's tables
           stay in cache (all of them may not: 1.2 MB for city.exr) */
        for (uint32_t k = 0; k < t->K; k++) {
            int lit = 0;
            for (uint32_t v = v0; v < v1; v++)
                lit |= hl_ref_dyn_irr_light(t->lf + (size_t)HL_DYN_IRR_LF * k, t->lu + (size_t)HL_DYN_IRR_LU * k,
                                            t->mom, t->pre, j->normals + 3 * (size_t)v,
                                            j->E + 3 * ((size_t)k * j->N + v));
            if (lit && !atomic_load_explicit(&j->any[k], memory_order_relaxed))
                atomic_store_explicit(&j->any[k], 1, memory_order_relaxed);
        }
    }
    return NULL;
}

static hl_result run_ref(hl_dyn_irr *m, const float *normals, uint32_t N, float *E, float *ambient, uint8_t *any)
{
    const uint32_t K = m->t.K;
    atomic_int *flags = hl_malloc(m->ctx, (K ? K : 1) * sizeof *flags, "irradiance light flags");
    if (!flags) return HL_ERR_OUT_OF_MEMORY;
    for (uint32_t k = 0; k < K; k++) atomic_init(&flags[k], 0);
    ref_job j = {.t = &m->t, .normals = normals, .N = N, .E = E, .ambient = ambient, .any = flags};
    atomic_init(&j.next, 0u);
    const double t0 = hl_now();
    hl_run_threads(m->ctx->threads, ref_worker, &j);
    m->t_compute = hl_now() - t0;
    for (uint32_t k = 0; any && k < K; k++) any[k] = atomic_load(&flags[k]) ? 1 : 0;
    free(flags);
    return HL_OK;
}

static hl_result run(hl_dyn_irr *m, const float *normals, uint32_t N, float *E, float *ambient, uint8_t *any, int keep)
{
    if (!m) return HL_ERR_INVALID_ARGUMENT;
    hl_context *ctx = m->ctx;
    const uint32_t K = m->t.K;
    if (!m->t.lf) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic irradiance: no light split (the last failed)");
    if (keep && !ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic irradiance: no device to keep it on");
    if (any) memset(any, 0, K);
    m->t_compute = m->t_total = 0.0;
    if (N == 0) return HL_OK;
    if (!normals || (K > 0 && !E && !keep))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic irradiance: no %s array for %u receivers",
                       normals ? "irradiance" : "normal", N);
    if ((uint64_t)K * N * 3 > SIZE_MAX / 4)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic irradiance: %u receivers x %u lights is too many", N, K);
    for (size_t i = 0; i < 3 * (size_t)N; i++)
        if (!isfinite(normals[i]))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "dynamic irradiance: receiver %zu's normal has a non-finite component (%g)", i / 3,
                           (double)normals[i]);
    const double t0 = hl_now();
    hl_result r = ctx->cl ? run_device(m, normals, N, E, ambient, any, keep) : run_ref(m, normals, N, E, ambient, any);
    m->t_total = hl_now() - t0;
    return r;
}

hl_result hl_dyn_irr_run(hl_dyn_irr *m, const float *normals, uint32_t N, float *E, float *ambient, uint8_t *any)
{
    return run(m, normals, N, E, ambient, any, 0);
}

hl_result hl_dyn_irr_run_kept(hl_dyn_irr *m, const float *normals, uint32_t N, uint8_t *any)
{
    return run(m, normals, N, NULL, NULL, any, 1);
}

void hl_dyn_irr_device_bufs(const hl_dyn_irr *m, void **E, void **ambient, void **normals)
{
    *E = m->E_d;
    *ambient = m->amb_d;
    if (normals) *normals = m->n_d;
}

void hl_dyn_irr_times(const hl_dyn_irr *m, double *compute, double *total)
{
    if (compute) *compute = m ? m->t_compute : 0.0;
    if (total) *total = m ? m->t_total : 0.0;
}
