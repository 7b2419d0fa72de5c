/* csm.c - convolution shadow maps for the dynamic method: a batch of
 * lights' basis planes and summed-area tables (kept on the device between
 * hl_csm_build and hl_csm_visibility), and per-receiver visibility with
 * the filter width from the average blocker depth. The reference backend
 * runs the twins (host/src/dynamic/twins/csm_*.c) on host memory.
 * Depends on: csm.h, cl_internal.h (OpenCL: buffers, CL_TRY), dynamic.h.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"
#include "csm.h"

/* planes a group of the GPU shape's scan takes (csm_sat_items.cl): 16
 * lanes x 16 planes, groups of 256 */
#define HL_CSM_SAT_CHUNK 16u

/* floats of the eval kernel's parameter block (csm_eval.cl: prm) */
#define CSM_PRM_FLOATS (11 + 2 * HL_CSM_M_MAX)

struct hl_csm {
    hl_context *ctx;
    hl_shadow_rep rep;
    uint32_t R, M, Mb, P, K_max, K;
    float *zmin;  /* per light of the last build */
    float *stage; /* K_max R^2 depths, validated and clamped to [0, 1] */
    /* reference backend */
    float *img, *rowsum, *mean, *zsc;
    /* OpenCL */
    cl_kernel kb, km, ks;
    cl_kernel kbt, krs, kss; /* the GPU shape's basis, row sums and scan (csm_*_items.cl) */
    cl_kernel keb;           /* the evaluation of several lights (hl_csm_eval_batch) */
    cl_kernel keg, kz;       /* the device frame's evaluation, the maps' nearest depths */
    cl_kernel kmb, kmeb, kmeg; /* moments: basis, evaluation of several lights, the device frame's */
    cl_mem depth_d, img_d, rowsum_d, mean_d, zsc_d, prm_d, uvd_d, rpl_d, out_d, which_d, lights_d, zmin_d;
    uint32_t prm_cap; /* lights whose parameters prm_d holds (within the device's constant memory) */
    size_t io_cap;    /* receivers the uvd, out and which buffers hold */
    float *out_h;     /* 2 per receiver, read back */
    uint32_t *which_h; /* each receiver's entry of the batch */
    float *rpl_h;      /* HL_DYN_RPL per receiver: the planes uploaded when none are given */
};

size_t hl_csm_bytes_per_light_rep(hl_shadow_rep rep, uint32_t R, uint32_t M, uint32_t Mb)
{
    size_t P = rep == HL_SHADOW_REP_MOMENTS ? HL_MSM_PLANES : hl_csm_planes(M, Mb), R2 = (size_t)R * R;
    return 4 * (P * R2 + R2 + 4 * R2 + P * R + P);
}

size_t hl_csm_bytes_per_light(uint32_t R, uint32_t M, uint32_t Mb)
{
    return hl_csm_bytes_per_light_rep(HL_SHADOW_REP_CSM, R, M, Mb);
}

uint32_t hl_csm_batch_fit_rep(hl_shadow_rep rep, uint32_t R, uint32_t M, uint32_t Mb, uint64_t bytes)
{
    uint64_t per = hl_csm_bytes_per_light_rep(rep, R, M ? M : HL_CSM_M_DEFAULT, Mb ? Mb : (M ? M : HL_CSM_M_DEFAULT));
    uint64_t k = bytes / per;
    return k < 1 ? 1u : k > UINT32_MAX ? UINT32_MAX : (uint32_t)k;
}

uint32_t hl_csm_batch_fit(uint32_t R, uint32_t M, uint32_t Mb, uint64_t bytes)
{
    return hl_csm_batch_fit_rep(HL_SHADOW_REP_CSM, R, M, Mb, bytes);
}

hl_shadow_rep hl_csm_rep(const hl_csm *c) { return c->rep; }

void hl_msm_params(hl_msm_eval_params *p, uint32_t R, float zmin, float su, float sv, float texel)
{
    memset(p, 0, sizeof *p);
    p->R = R;
    p->zmin = zmin;
    p->su = su;
    p->sv = sv;
    p->bias = HL_MSM_BIAS;
    p->eps = HL_CSM_BLOCKER_EPS; /* above alpha's spurious share (at most alpha) */
    p->wmin = HL_CSM_MIN_HALF_WIDTH;
    p->alpha = HL_MSM_ALPHA;
    p->leak_a = HL_MSM_LEAK_A;
    p->leak_b = HL_MSM_LEAK_B;
    p->lbr = HL_MSM_LBR;
    p->direct_half = HL_CSM_DIRECT_HALF;
    p->kb = 1.0f - HL_MSM_FAR_BAND;
    p->ptex = HL_MSM_PER_TEXEL;
    p->tbias = HL_MSM_TEXEL_BIAS;
    p->near_half = HL_MSM_NEAR_HALF;
    p->sbias = HL_MSM_SMALL_BIAS;
    /* tests and tuning: HL_TEST_MSM=alpha,bias,lbr,leak_a overrides;
       HL_TEST_MSMT=on,texel_bias,small_bias the per-texel test's (on 0:
       off, 2: with the leak reduction), HL_TEST_MSMN=half the near
       search's */
    const char *tt = getenv("HL_TEST_MSMT"), *tn = getenv("HL_TEST_MSMN"), *tf = getenv("HL_TEST_MSMF");
    if (tt) {
        float on, b, sb;
        if (sscanf(tt, "%f,%f,%f", &on, &b, &sb) == 3 && on >= 0.0f && b >= 0.0f && sb >= 0.0f && sb < 1.0f)
            p->ptex = on, p->tbias = b, p->sbias = sb;
    }
    if (tn) {
        float h = strtof(tn, NULL);
        if (h >= 0.0f && h <= HL_CSM_DIRECT_HALF) p->near_half = h;
    }
    p->tfloor = HL_MSM_TEXEL_FLOOR;
    if (tf) {
        float h = strtof(tf, NULL);
        if (h >= 0.0f && h <= 16.0f) p->tfloor = h;
    }
    p->tfloor *= texel;
    const char *t = getenv("HL_TEST_MSM");
    if (t) {
        float a, b, l, la;
        if (sscanf(t, "%f,%f,%f,%f", &a, &b, &l, &la) == 4 && a >= 0.0f && a < 1.0f && b >= 0.0f && b < 1.0f &&
            l >= 0.0f && l < 1.0f && la >= 0.0f)
            p->alpha = a, p->bias = b, p->lbr = l, p->leak_a = la;
    }
}

/* The parameter block of msm_eval.cl (prm) from p. */
static void pack_msm_params(const hl_msm_eval_params *p, float *prm)
{
    const float v[HL_MSM_PRM_FLOATS] = {p->zmin, p->su, p->sv, p->bias, p->eps, p->wmin, p->alpha, p->leak_a,
                                        p->leak_b, p->lbr, p->direct_half, p->kb, p->ptex, p->tbias,
                                        p->near_half, p->sbias, p->tfloor};
    memcpy(prm, v, sizeof v);
}

void hl_csm_params(hl_csm_eval_params *p, uint32_t R, uint32_t M, uint32_t Mb, float zmin, float su, float sv)
{
    memset(p, 0, sizeof *p);
    p->R = R;
    p->M = M;
    p->Mb = Mb;
    p->zmin = zmin;
    p->su = su;
    p->sv = sv;
    p->bias = HL_CSM_BIAS_M / (float)M;
    p->bias_b = HL_CSM_BIAS_M / (float)Mb;
    p->eps = HL_CSM_BLOCKER_EPS;
    p->wmin = HL_CSM_MIN_HALF_WIDTH;
    p->leak_a = HL_CSM_LEAK_A;
    p->leak_b = HL_CSM_LEAK_B;
    const double h = HL_CSM_HALF_PERIOD;
    p->c1 = (float)(HL_PI / h);
    p->direct_half = HL_CSM_DIRECT_HALF;
    for (uint32_t k = 1; k <= M; k++) {
        double ck = HL_PI * (2.0 * k - 1.0) / h, x = (double)k / M, xb = (double)k / Mb;
        p->coef[k - 1] = (float)(exp(-HL_CSM_ALPHA * x * x) * 2.0 / (h * ck));
        if (k <= Mb) p->coefb[k - 1] = (float)(exp(-HL_CSM_ALPHA * xb * xb) * 2.0 / (h * ck));
    }
}

void hl_csm_destroy(hl_csm *c)
{
    if (!c) return;
    struct hl_cl *cl = c->ctx->cl;
    if (cl) {
        if (cl->queue) clFinish(cl->queue);
        cl_mem *all[] = {&c->depth_d, &c->img_d,   &c->rowsum_d, &c->mean_d,   &c->zsc_d, &c->prm_d,
                         &c->uvd_d,   &c->rpl_d,   &c->out_d,   &c->which_d,  &c->lights_d, &c->zmin_d};
        for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) hl_cl_release_buf(cl, all[i]);
        cl_kernel ks[] = {c->kb, c->km, c->ks, c->kbt, c->krs, c->kss, c->keb, c->keg, c->kz, c->kmb, c->kmeb, c->kmeg};
        for (size_t i = 0; i < sizeof ks / sizeof ks[0]; i++)
            if (ks[i]) clReleaseKernel(ks[i]);
    }
    hl_free_big(c->img);
    hl_free_big(c->stage);
    free(c->rowsum);
    free(c->mean);
    hl_free_big(c->zsc);
    free(c->zmin);
    free(c->out_h);
    free(c->which_h);
    free(c->rpl_h);
    free(c);
}

static hl_result create_device(hl_csm *c)
{
    hl_context *ctx = c->ctx;
    struct hl_cl *cl = ctx->cl;
    cl_int e;
    const char *names[12] = {"hl_csm_basis",         "hl_csm_sat_mean",       "hl_csm_sat_scan",
                             "hl_csm_basis_texels",  "hl_csm_basis_rowsums",  "hl_csm_sat_scan_items",
                             "hl_csm_eval_batch",    "hl_csm_eval_grid",      "hl_csm_zmin",
                             "hl_msm_basis",         "hl_msm_eval_batch",     "hl_msm_eval_grid"};
    cl_kernel *ks[12] = {&c->kb,  &c->km, &c->ks, &c->kbt, &c->krs,  &c->kss,
                         &c->keb, &c->keg, &c->kz, &c->kmb, &c->kmeb, &c->kmeg};
    for (int i = 0; i < 12; i++) {
        *ks[i] = clCreateKernel(cl->program, names[i], &e);
        CL_TRY(ctx, e, names[i]);
    }
    size_t K = c->K_max, R2 = (size_t)c->R * c->R, P = c->P;
    TRY(hl_cl_make_buf(ctx, &c->depth_d, CL_MEM_READ_ONLY, K * R2 * 4, NULL, "CSM depth maps"));
    TRY(hl_cl_make_buf(ctx, &c->img_d, CL_MEM_READ_WRITE, K * P * R2 * 4, NULL, "CSM summed-area tables"));
    TRY(hl_cl_make_buf(ctx, &c->rowsum_d, CL_MEM_READ_WRITE, K * P * c->R * 4, NULL, "CSM row sums"));
    TRY(hl_cl_make_buf(ctx, &c->mean_d, CL_MEM_READ_WRITE, K * P * 4, NULL, "CSM plane means"));
    TRY(hl_cl_make_buf(ctx, &c->zsc_d, CL_MEM_READ_WRITE, K * R2 * 16, NULL, "CSM texel phases"));
    TRY(hl_cl_make_buf(ctx, &c->zmin_d, CL_MEM_READ_WRITE, K * 4, NULL, "CSM nearest depths"));
    /* the batch's parameters live in constant memory (64 KB at least):
       as many lights as it holds, and the batch's at most */
    cl_ulong cmax = 65536;
    clGetDeviceInfo(cl->device, CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE, sizeof cmax, &cmax, NULL);
    uint64_t fit = cmax / (CSM_PRM_FLOATS * 4);
    c->prm_cap = fit < 1 ? 1u : fit < K ? (uint32_t)fit : (uint32_t)K;
    /* tests: fewer lights a launch, so that a small batch takes several */
    const char *t = getenv("HL_TEST_CSM_BATCH");
    if (t && strtoul(t, NULL, 10) > 0 && strtoul(t, NULL, 10) < c->prm_cap) c->prm_cap = (uint32_t)strtoul(t, NULL, 10);
    TRY(hl_cl_make_buf(ctx, &c->prm_d, CL_MEM_READ_ONLY, (size_t)c->prm_cap * CSM_PRM_FLOATS * 4, NULL,
                       "CSM parameters"));
    TRY(hl_cl_make_buf(ctx, &c->lights_d, CL_MEM_READ_ONLY, (size_t)c->prm_cap * 4, NULL, "CSM batch lights"));
    return HL_OK;
}

hl_result hl_csm_create(hl_context *ctx, uint32_t R, uint32_t M, uint32_t Mb, uint32_t K_max, hl_csm **out)
{
    return hl_csm_create_rep(ctx, HL_SHADOW_REP_CSM, R, M, Mb, K_max, out);
}

hl_result hl_csm_create_rep(hl_context *ctx, hl_shadow_rep rep, uint32_t R, uint32_t M, uint32_t Mb, uint32_t K_max,
                            hl_csm **out)
{
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_csm_create: no output pointer");
    *out = NULL;
    if (!ctx) return HL_ERR_INVALID_ARGUMENT;
    if (M == 0) M = HL_CSM_M_DEFAULT;
    if (Mb == 0) Mb = M;
    if (M < HL_CSM_M_MIN || M > HL_CSM_M_MAX)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: order M = %u is outside %u..%u", M,
                       HL_CSM_M_MIN, HL_CSM_M_MAX);
    if (Mb < HL_CSM_M_MIN || Mb > M)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "convolution shadow maps: blocker-search order %u is outside %u..M (M = %u)", Mb,
                       HL_CSM_M_MIN, M);
    if (R < HL_CSM_R_MIN || R > HL_CSM_R_MAX || R % HL_CSM_SCAN_LANES)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "convolution shadow maps: map size R = %u must be a multiple of %u in %u..%u", R,
                       HL_CSM_SCAN_LANES, HL_CSM_R_MIN, HL_CSM_R_MAX);
    if (rep != HL_SHADOW_REP_CSM && rep != HL_SHADOW_REP_MOMENTS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "shadow maps: representation %d is neither CSM (1) nor moments (2)",
                       (int)rep);
    if (K_max == 0 || (uint64_t)K_max * hl_csm_bytes_per_light_rep(rep, R, M, Mb) > ((uint64_t)1 << 40))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "convolution shadow maps: a batch of %u lights is impossible (at least 1, at most 1 TiB)", K_max);
    hl_csm *c = calloc(1, sizeof *c);
    if (!c) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the shadow-map module");
    c->ctx = ctx;
    c->R = R;
    c->M = M;
    c->Mb = Mb;
    c->rep = rep;
    c->P = rep == HL_SHADOW_REP_MOMENTS ? HL_MSM_PLANES : hl_csm_planes(M, Mb);
    c->K_max = K_max;
    size_t R2 = (size_t)R * R, KP = (size_t)K_max * c->P;
    hl_result r = HL_OK;
    c->zmin = hl_malloc(ctx, K_max * sizeof *c->zmin, "shadow-map depth minima");
    c->stage = c->zmin ? hl_alloc_big(ctx, K_max * R2 * 4, "shadow-map depths") : NULL;
    if (!c->stage) r = HL_ERR_OUT_OF_MEMORY;
    if (r == HL_OK && ctx->cl) {
        r = create_device(c);
    } else if (r == HL_OK) {
        c->img = hl_alloc_big(ctx, KP * R2 * 4, "shadow-map summed-area tables");
        c->rowsum = c->img ? hl_malloc(ctx, KP * R * 4, "shadow-map row sums") : NULL;
        c->mean = c->rowsum ? hl_malloc(ctx, KP * 4, "shadow-map plane means") : NULL;
        c->zsc = c->mean ? hl_alloc_big(ctx, K_max * R2 * 16, "shadow-map texel phases") : NULL;
        if (!c->zsc) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r != HL_OK) { hl_csm_destroy(c); return r; }
    *out = c;
    return HL_OK;
}

/* Copies the maps into the staging area, depths above 1 as 1; refuses
 * NaN, Inf and negative depths; records each map's smallest depth. */
static hl_result stage_depths(hl_csm *c, const float *depth, uint32_t K)
{
    size_t R2 = (size_t)c->R * c->R;
    for (uint32_t k = 0; k < K; k++) {
        float zmin = 1.0f;
        for (size_t i = 0; i < R2; i++) {
            float z = depth[k * R2 + i];
            if (!(z >= 0.0f) || isinf(z))
                return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT,
                               "convolution shadow maps: depth %g at texel (%zu, %zu) of map %u is not a depth "
                               "in [0, 1] (NaN, Inf or negative)",
                               (double)z, i % c->R, i / c->R, k);
            if (z > 1.0f) z = 1.0f;
            if (z < zmin) zmin = z;
            c->stage[k * R2 + i] = z;
        }
        c->zmin[k] = zmin;
    }
    return HL_OK;
}

#define SETARG(k, i, v) CL_TRY(ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")


/* The build on the device from the staged maps (depth NULL: uploaded
 * into depth_d), or from maps already in device memory. */
static hl_result build_device(hl_csm *c, uint32_t K, int upto, cl_mem depth)
{
    hl_context *ctx = c->ctx;
    struct hl_cl *cl = ctx->cl;
    cl_uint R = c->R, M = c->M, Mb = c->Mb, nrows = K * c->R, np = K * c->P;
    cl_float c1 = (float)(HL_PI / HL_CSM_HALF_PERIOD);
    if (!depth) {
        CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, c->depth_d, CL_FALSE, 0, (size_t)K * R * R * 4, c->stage, 0, NULL,
                                         NULL),
               "shadow-map upload");
        depth = c->depth_d;
    }
    const int gpu = cl->gpu_shape;
    if (c->rep == HL_SHADOW_REP_MOMENTS) { /* a row a work-item on either shape: 4 planes are cheap */
        cl_float kb = 1.0f - HL_MSM_FAR_BAND;
        SETARG(c->kmb, 0, depth); SETARG(c->kmb, 1, R); SETARG(c->kmb, 2, kb); SETARG(c->kmb, 3, nrows);
        SETARG(c->kmb, 4, c->img_d); SETARG(c->kmb, 5, c->rowsum_d); SETARG(c->kmb, 6, c->zsc_d);
        TRY(hl_cl_launch(ctx, c->kmb, nrows, 0, "hl_msm_basis"));
    } else if (gpu) { /* a work-item a texel, then a work-item a row and plane */
        cl_uint nt = K * R * R, nrs = nrows * c->P, P = c->P;
        SETARG(c->kbt, 0, depth); SETARG(c->kbt, 1, R); SETARG(c->kbt, 2, M); SETARG(c->kbt, 3, Mb);
        SETARG(c->kbt, 4, c1); SETARG(c->kbt, 5, nt); SETARG(c->kbt, 6, c->img_d); SETARG(c->kbt, 7, c->zsc_d);
        TRY(hl_cl_launch(ctx, c->kbt, nt, 0, "hl_csm_basis_texels"));
        SETARG(c->krs, 0, c->img_d); SETARG(c->krs, 1, R); SETARG(c->krs, 2, P); SETARG(c->krs, 3, nrs);
        SETARG(c->krs, 4, c->rowsum_d);
        TRY(hl_cl_launch(ctx, c->krs, nrs, 0, "hl_csm_basis_rowsums"));
    } else {
        SETARG(c->kb, 0, depth); SETARG(c->kb, 1, R); SETARG(c->kb, 2, M); SETARG(c->kb, 3, Mb);
        SETARG(c->kb, 4, c1); SETARG(c->kb, 5, nrows); SETARG(c->kb, 6, c->img_d); SETARG(c->kb, 7, c->rowsum_d);
        SETARG(c->kb, 8, c->zsc_d);
        TRY(hl_cl_launch(ctx, c->kb, nrows, 0, "hl_csm_basis"));
    }
    SETARG(c->km, 0, c->rowsum_d); SETARG(c->km, 1, R); SETARG(c->km, 2, np); SETARG(c->km, 3, c->mean_d);
    TRY(hl_cl_launch(ctx, c->km, np, 0, "hl_csm_sat_mean"));
    /* rows (minus the mean), then columns; planes interleaved by texel */
    cl_uint P = c->P;
    /* the GPU shape: a group a line and HL_CSM_SAT_CHUNK planes, a
       work-item a lane and plane (csm_sat_items.cl) */
    const cl_uint chunk = HL_CSM_SAT_CHUNK, nchunks = (P + chunk - 1) / chunk;
    for (cl_uint pass = 0; (int)pass < upto - 1; pass++) {
        cl_uint step = pass ? R * P : P, line_step = pass ? P : R * P, sub = pass ? 0 : 1;
        cl_kernel k = gpu ? c->kss : c->ks;
        SETARG(k, 0, c->img_d); SETARG(k, 1, c->mean_d); SETARG(k, 2, R); SETARG(k, 3, P);
        SETARG(k, 4, step); SETARG(k, 5, line_step); SETARG(k, 6, sub);
        if (gpu) {
            SETARG(k, 7, chunk);
            CL_TRY(ctx, clSetKernelArg(k, 8, 2 * HL_CSM_SCAN_LANES * chunk * sizeof(float), NULL), "clSetKernelArg");
            const size_t group = (size_t)HL_CSM_SCAN_LANES * chunk;
            TRY(hl_cl_launch(ctx, k, (size_t)K * R * nchunks * group, group, "hl_csm_sat_scan_items"));
        } else {
            CL_TRY(ctx, clSetKernelArg(k, 7, 2 * HL_CSM_SCAN_LANES * P * sizeof(float), NULL), "clSetKernelArg");
            TRY(hl_cl_launch(ctx, k, (size_t)K * R * HL_CSM_SCAN_LANES, HL_CSM_SCAN_LANES, "hl_csm_sat_scan"));
        }
    }
    CL_TRY(ctx, clFinish(cl->queue), "shadow-map build");
    return HL_OK;
}

static void build_ref(hl_csm *c, uint32_t K, int upto)
{
    const uint32_t R = c->R, P = c->P;
    const size_t R2 = (size_t)R * R;
    const float c1 = (float)(HL_PI / HL_CSM_HALF_PERIOD);
    for (uint32_t k = 0; k < K; k++) {
        float *img = c->img + (size_t)k * P * R2, *rs = c->rowsum + (size_t)k * P * R, *mean = c->mean + (size_t)k * P;
        float *zsc = c->zsc + 4 * k * R2;
        for (uint32_t row = 0; row < R; row++) {
            if (c->rep == HL_SHADOW_REP_MOMENTS) hl_ref_msm_basis(c->stage + k * R2, R, 1.0f - HL_MSM_FAR_BAND, row, img, rs, zsc);
            else hl_ref_csm_basis(c->stage + k * R2, R, c->M, c->Mb, c1, row, img, rs, zsc);
        }
        for (uint32_t p = 0; p < P; p++) {
            mean[p] = hl_ref_csm_sat_mean(rs + (size_t)p * R, R);
            for (uint32_t row = 0; upto >= 2 && row < R; row++)
                hl_ref_csm_sat_scan(img + (size_t)row * R * P + p, P, R, mean[p]);
        }
        for (uint32_t p = 0; upto >= 3 && p < P; p++)
            for (uint32_t col = 0; col < R; col++) hl_ref_csm_sat_scan(img + (size_t)col * P + p, (size_t)R * P, R, 0.0f);
    }
}

hl_result hl_csm_build(hl_csm *c, const float *depth, uint32_t K)
{
    return hl_csm_build_upto(c, depth, K, HL_CSM_UPTO_ALL);
}

hl_result hl_csm_build_upto(hl_csm *c, const float *depth, uint32_t K, int upto)
{
    if (!c) return HL_ERR_INVALID_ARGUMENT;
    if (!depth || K == 0 || K > c->K_max)
        return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT,
                       "convolution shadow maps: build of %u maps (%s); the batch holds 1..%u", K,
                       depth ? "given" : "no depth array", c->K_max);
    c->K = 0;
    TRY(stage_depths(c, depth, K));
    if (c->ctx->cl) TRY(build_device(c, K, upto, NULL));
    else build_ref(c, K, upto);
    c->K = K;
    return HL_OK;
}

/* Work-items a group of hl_csm_zmin: a power of two. */
#define HL_CSM_ZMIN_GROUP 256u

hl_result hl_csm_build_on_device(hl_csm *c, void *depth, uint32_t K)
{
    if (!c) return HL_ERR_INVALID_ARGUMENT;
    hl_context *ctx = c->ctx;
    if (!ctx->cl || !depth || K == 0 || K > c->K_max)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: a device build of %u maps (%s); the batch holds 1..%u",
                       K, ctx->cl ? "" : "no OpenCL device", c->K_max);
    c->K = 0;
    cl_mem d = depth;
    /* each map's nearest depth, on the device for hl_csm_eval_grid and
       here for hl_csm_visibility */
    cl_uint R2 = c->R * c->R;
    size_t local = 1;
    while (local * 2 <= HL_CSM_ZMIN_GROUP && local * 2 <= ctx->cl->max_wg) local *= 2;
    size_t global = (size_t)K * local;
    SETARG(c->kz, 0, d); SETARG(c->kz, 1, R2); SETARG(c->kz, 2, c->zmin_d);
    CL_TRY(ctx, clSetKernelArg(c->kz, 3, local * sizeof(float), NULL), "clSetKernelArg");
    CL_TRY(ctx, clEnqueueNDRangeKernel(ctx->cl->queue, c->kz, 1, NULL, &global, &local, 0, NULL, NULL), "hl_csm_zmin");
    CL_TRY(ctx, clEnqueueReadBuffer(ctx->cl->queue, c->zmin_d, CL_FALSE, 0, (size_t)K * 4, c->zmin, 0, NULL, NULL),
           "read-back");
    TRY(build_device(c, K, HL_CSM_UPTO_ALL, d)); /* its finish waits for the read-back too */
    c->K = K;
    return HL_OK;
}

hl_result hl_csm_read_planes(hl_csm *c, uint32_t k, float *planes, float *means, float *zsc)
{
    if (k >= c->K) return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: no light %u", k);
    size_t n = (size_t)c->P * c->R * c->R, off = (size_t)k * n, R2 = (size_t)c->R * c->R;
    if (!c->ctx->cl) {
        memcpy(planes, c->img + off, n * 4);
        memcpy(means, c->mean + (size_t)k * c->P, (size_t)c->P * 4);
        if (zsc) memcpy(zsc, c->zsc + 4 * k * R2, R2 * 16);
        return HL_OK;
    }
    hl_context *ctx = c->ctx;
    cl_command_queue q = ctx->cl->queue;
    CL_TRY(ctx, clEnqueueReadBuffer(q, c->img_d, CL_TRUE, off * 4, n * 4, planes, 0, NULL, NULL), "read-back");
    CL_TRY(ctx, clEnqueueReadBuffer(q, c->mean_d, CL_TRUE, (size_t)k * c->P * 4, (size_t)c->P * 4, means, 0, NULL, NULL),
           "read-back");
    if (zsc)
        CL_TRY(ctx, clEnqueueReadBuffer(q, c->zsc_d, CL_TRUE, k * R2 * 16, R2 * 16, zsc, 0, NULL, NULL), "read-back");
    return HL_OK;
}

void hl_csm_sizes(const hl_csm *c, uint32_t *R, uint32_t *M, uint32_t *Mb, uint32_t *P)
{
    if (R) *R = c->R;
    if (M) *M = c->M;
    if (Mb) *Mb = c->Mb;
    if (P) *P = c->P;
}

static hl_result check_frame(hl_csm *c, float theta, const hl_shadow_frame *f)
{
    if (!f) return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: no shadow frame");
    if (!(theta >= 0.0f) || !(theta < (float)(HL_PI / 2)))
        return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT,
                       "convolution shadow maps: light half-extent %g rad is outside [0, pi/2)", (double)theta);
    if (f->R != c->R)
        return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: frame of %u texels, module of %u",
                       f->R, c->R);
    float dims[3] = {f->width, f->height, f->depth_range};
    for (int i = 0; i < 3; i++)
        if (!(dims[i] > 0.0f) || isinf(dims[i]))
            return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT,
                           "convolution shadow maps: frame width, height and depth range must be positive and finite "
                           "(%g, %g, %g)", (double)f->width, (double)f->height, (double)f->depth_range);
    return HL_OK;
}

/* The parameter block of csm_eval.cl (prm) from p. */
static void pack_params(const hl_csm_eval_params *p, float *prm)
{
    const float head[9] = {p->zmin, p->su, p->sv, p->bias, p->eps, p->wmin, p->leak_a, p->leak_b, p->c1};
    memcpy(prm, head, sizeof head);
    memcpy(prm + 9, p->coef, sizeof p->coef);
    memcpy(prm + 9 + HL_CSM_M_MAX, p->coefb, sizeof p->coefb);
    prm[9 + 2 * HL_CSM_M_MAX] = p->direct_half;
    prm[10 + 2 * HL_CSM_M_MAX] = p->bias_b;
}

/* Room for n receivers in the device's batch buffers and their host sides. */
static hl_result io_room(hl_csm *c, size_t n)
{
    if (n <= c->io_cap) return HL_OK;
    hl_context *ctx = c->ctx;
    struct hl_cl *cl = ctx->cl;
    hl_cl_release_buf(cl, &c->uvd_d);
    hl_cl_release_buf(cl, &c->rpl_d);
    hl_cl_release_buf(cl, &c->out_d);
    hl_cl_release_buf(cl, &c->which_d);
    free(c->out_h);
    free(c->which_h);
    free(c->rpl_h);
    c->which_h = NULL;
    c->rpl_h = NULL;
    c->io_cap = 0;
    c->out_h = hl_malloc(ctx, n * 8, "shadow-map visibility");
    if (!c->out_h) return HL_ERR_OUT_OF_MEMORY;
    c->which_h = hl_malloc(ctx, n * 4, "shadow-map receivers' lights");
    if (!c->which_h) return HL_ERR_OUT_OF_MEMORY;
    c->rpl_h = hl_malloc(ctx, n * HL_DYN_RPL * 4, "shadow-map receivers' planes");
    if (!c->rpl_h) return HL_ERR_OUT_OF_MEMORY;
    TRY(hl_cl_make_buf(ctx, &c->uvd_d, CL_MEM_READ_ONLY, n * 12, NULL, "CSM receivers"));
    TRY(hl_cl_make_buf(ctx, &c->rpl_d, CL_MEM_READ_ONLY, n * HL_DYN_RPL * 4, NULL, "shadow-map receivers' planes"));
    TRY(hl_cl_make_buf(ctx, &c->out_d, CL_MEM_WRITE_ONLY, n * 8, NULL, "CSM visibility"));
    TRY(hl_cl_make_buf(ctx, &c->which_d, CL_MEM_READ_ONLY, n * 4, NULL, "CSM receivers' lights"));
    c->io_cap = n;
    return HL_OK;
}

/* Entries j0 .. j1 - 1 of a batch (at most prm_cap; prm: their parameter
 * blocks) on the device: one upload of each array, one launch, one
 * read-back into out_h (2 floats a receiver, from start[j0]). */
static hl_result eval_device(hl_csm *c, uint32_t j0, uint32_t j1, const uint32_t *ks, const float *prm,
                             const float *uvd, const float *rpl, const uint32_t *start)
{
    hl_context *ctx = c->ctx;
    struct hl_cl *cl = ctx->cl;
    const size_t r0 = start[j0], n = (size_t)start[j1] - r0, nl = j1 - j0;
    TRY(io_room(c, n));
    for (uint32_t j = j0; j < j1; j++)
        for (size_t r = start[j]; r < start[j + 1]; r++) c->which_h[r - r0] = j - j0;
    const size_t np = c->rep == HL_SHADOW_REP_MOMENTS ? HL_MSM_PRM_FLOATS : CSM_PRM_FLOATS;
    CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, c->prm_d, CL_FALSE, 0, nl * np * 4, prm + j0 * np, 0, NULL, NULL),
           "upload");
    CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, c->lights_d, CL_FALSE, 0, nl * 4, ks + j0, 0, NULL, NULL), "upload");
    CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, c->which_d, CL_FALSE, 0, n * 4, c->which_h, 0, NULL, NULL), "upload");
    CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, c->uvd_d, CL_FALSE, 0, n * 12, uvd + 3 * r0, 0, NULL, NULL), "upload");
    cl_uint R = c->R, M = c->M, Mb = c->Mb, nprm = CSM_PRM_FLOATS, nn = (cl_uint)n;
    if (c->rep == HL_SHADOW_REP_MOMENTS) {
        cl_uint nm = HL_MSM_PRM_FLOATS;
        cl_kernel k = c->kmeb;
        const float *pl = rpl ? rpl + HL_DYN_RPL * r0 : c->rpl_h;
        if (!rpl) /* no planes: each receiver's faces the light at its depth */
            for (size_t i = 0; i < n; i++)
                c->rpl_h[HL_DYN_RPL * i] = 0.0f, c->rpl_h[HL_DYN_RPL * i + 1] = 0.0f,
                c->rpl_h[HL_DYN_RPL * i + 2] = uvd[3 * (r0 + i) + 2];
        CL_TRY(ctx, clEnqueueWriteBuffer(cl->queue, c->rpl_d, CL_TRUE, 0, n * HL_DYN_RPL * 4, pl, 0, NULL, NULL),
               "upload");
        SETARG(k, 0, c->img_d); SETARG(k, 1, c->mean_d); SETARG(k, 2, c->zsc_d); SETARG(k, 3, R);
        SETARG(k, 4, c->prm_d); SETARG(k, 5, nm); SETARG(k, 6, c->lights_d); SETARG(k, 7, c->which_d);
        SETARG(k, 8, c->uvd_d); SETARG(k, 9, c->rpl_d); SETARG(k, 10, nn); SETARG(k, 11, c->out_d);
        TRY(hl_cl_launch(ctx, k, n, 0, "hl_msm_eval_batch"));
        CL_TRY(ctx, clEnqueueReadBuffer(cl->queue, c->out_d, CL_TRUE, 0, n * 8, c->out_h, 0, NULL, NULL), "read-back");
        return HL_OK;
    }
    SETARG(c->keb, 0, c->img_d); SETARG(c->keb, 1, c->mean_d); SETARG(c->keb, 2, c->zsc_d); SETARG(c->keb, 3, R);
    SETARG(c->keb, 4, M); SETARG(c->keb, 5, Mb); SETARG(c->keb, 6, c->prm_d); SETARG(c->keb, 7, nprm);
    SETARG(c->keb, 8, c->lights_d); SETARG(c->keb, 9, c->which_d); SETARG(c->keb, 10, c->uvd_d); SETARG(c->keb, 11, nn);
    SETARG(c->keb, 12, c->out_d);
    TRY(hl_cl_launch(ctx, c->keb, n, 0, "hl_csm_eval_batch"));
    CL_TRY(ctx, clEnqueueReadBuffer(cl->queue, c->out_d, CL_TRUE, 0, n * 8, c->out_h, 0, NULL, NULL), "read-back");
    return HL_OK;
}

hl_result hl_csm_visibility_batch(hl_csm *c, uint32_t nl, const uint32_t *ks, const float *thetas,
                                  const hl_shadow_frame *const *frames, const float *uvd, const float *rpl,
                                  const uint32_t *start, float *V, float *zavg)
{
    if (!c) return HL_ERR_INVALID_ARGUMENT;
    if (nl == 0) return HL_OK;
    if (!ks || !thetas || !frames || !start)
        return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: no batch arrays");
    for (uint32_t j = 0; j < nl; j++) {
        if (ks[j] >= c->K)
            return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT,
                           "convolution shadow maps: light %u is not in the last build (%u lights)", ks[j], c->K);
        if (start[j + 1] < start[j])
            return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: the batch's receiver counts fall");
        TRY(check_frame(c, thetas[j], frames[j]));
    }
    const size_t n = (size_t)start[nl] - start[0];
    if (n == 0) return HL_OK;
    if (!uvd || !V) return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: no receiver arrays");
    for (size_t i = 3 * (size_t)start[0]; i < 3 * (size_t)start[nl]; i++)
        if (!isfinite(uvd[i]))
            return hl_fail(c->ctx, HL_ERR_INVALID_ARGUMENT,
                           "convolution shadow maps: receiver %zu has a non-finite coordinate (%g)", i / 3, (double)uvd[i]);
    const int mom = c->rep == HL_SHADOW_REP_MOMENTS;
    const size_t np = mom ? HL_MSM_PRM_FLOATS : CSM_PRM_FLOATS;
    hl_msm_eval_params *pm = mom ? hl_malloc(c->ctx, nl * sizeof *pm, "shadow-map parameters") : NULL;
    if (mom && !pm) return HL_ERR_OUT_OF_MEMORY;
    hl_csm_eval_params *p = hl_malloc(c->ctx, nl * sizeof *p, "shadow-map parameters");
    float *prm = p ? hl_malloc(c->ctx, (size_t)nl * CSM_PRM_FLOATS * 4, "shadow-map parameters") : NULL;
    if (!prm) {
        free(p);
        free(pm);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t j = 0; j < nl; j++) {
        const hl_shadow_frame *f = frames[j];
        double t = tan((double)thetas[j]) * f->depth_range * c->R;
        if (mom) {
            hl_msm_params(&pm[j], c->R, c->zmin[ks[j]], (float)(t / f->width), (float)(t / f->height),
                          hl_shadow_frame_texel(f));
            pack_msm_params(&pm[j], prm + (size_t)j * np);
        } else {
            hl_csm_params(&p[j], c->R, c->M, c->Mb, c->zmin[ks[j]], (float)(t / f->width), (float)(t / f->height));
            pack_params(&p[j], prm + (size_t)j * np);
        }
    }
    hl_result r = HL_OK;
    for (uint32_t j0 = 0; j0 < nl && r == HL_OK; j0 += c->ctx->cl ? c->prm_cap : nl) {
        const uint32_t j1 = c->ctx->cl && nl - j0 > c->prm_cap ? j0 + c->prm_cap : nl;
        if (c->ctx->cl) r = eval_device(c, j0, j1, ks, prm, uvd, rpl, start);
        for (uint32_t j = j0; j < j1 && r == HL_OK; j++) {
            const size_t lp = (size_t)ks[j] * c->P, R2 = (size_t)c->R * c->R;
            for (size_t i = start[j]; i < start[j + 1]; i++) {
                float o[2];
                const float *oi = o;
                if (c->ctx->cl) oi = c->out_h + 2 * (i - start[j0]);
                else if (mom)
                    hl_ref_msm_eval(c->img + lp * R2, c->mean + lp, c->zsc + 4 * (size_t)ks[j] * R2, &pm[j], uvd + 3 * i,
                                    rpl ? rpl + HL_DYN_RPL * i : NULL, o);
                else hl_ref_csm_eval(c->img + lp * R2, c->mean + lp, c->zsc + 4 * (size_t)ks[j] * R2, &p[j], uvd + 3 * i, o);
                V[i] = oi[0];
                if (zavg) zavg[i] = oi[1];
            }
        }
    }
    free(prm);
    free(p);
    free(pm);
    return r;
}

void *hl_csm_zmin_buffer(const hl_csm *c) { return c->zmin_d; }

hl_result hl_csm_eval_grid(hl_csm *c, uint32_t nl, const uint32_t *ks, const float *thetas,
                           const hl_shadow_frame *const *frames, void *uvd, void *rpl, uint32_t N, void *V)
{
    if (!c) return HL_ERR_INVALID_ARGUMENT;
    hl_context *ctx = c->ctx;
    if (!ctx->cl || !uvd || !V || !ks || !thetas || !frames || (c->rep == HL_SHADOW_REP_MOMENTS && !rpl))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "convolution shadow maps: a device evaluation without its arrays");
    float prm[CSM_PRM_FLOATS * 64];
    const int mom = c->rep == HL_SHADOW_REP_MOMENTS;
    const size_t np = mom ? HL_MSM_PRM_FLOATS : CSM_PRM_FLOATS;
    for (uint32_t j0 = 0; j0 < nl; j0 += c->prm_cap < 64 ? c->prm_cap : 64) {
        const uint32_t cap = c->prm_cap < 64 ? c->prm_cap : 64, n = nl - j0 < cap ? nl - j0 : cap;
        for (uint32_t j = j0; j < j0 + n; j++) {
            if (ks[j] >= c->K)
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                               "convolution shadow maps: light %u is not in the last build (%u lights)", ks[j], c->K);
            TRY(check_frame(c, thetas[j], frames[j]));
            const hl_shadow_frame *f = frames[j];
            double t = tan((double)thetas[j]) * f->depth_range * c->R;
            if (mom) {
                hl_msm_eval_params pm;
                hl_msm_params(&pm, c->R, c->zmin[ks[j]], (float)(t / f->width), (float)(t / f->height),
                              hl_shadow_frame_texel(f));
                pack_msm_params(&pm, prm + (size_t)(j - j0) * np);
            } else {
                hl_csm_eval_params p;
                hl_csm_params(&p, c->R, c->M, c->Mb, c->zmin[ks[j]], (float)(t / f->width), (float)(t / f->height));
                pack_params(&p, prm + (size_t)(j - j0) * np);
            }
        }
        /* written before the next chunk's: the host arrays are reused */
        CL_TRY(ctx, clEnqueueWriteBuffer(ctx->cl->queue, c->prm_d, CL_TRUE, 0, (size_t)n * np * 4, prm, 0, NULL, NULL),
               "upload");
        CL_TRY(ctx, clEnqueueWriteBuffer(ctx->cl->queue, c->lights_d, CL_TRUE, 0, (size_t)n * 4, ks + j0, 0, NULL, NULL),
               "upload");
        cl_uint R = c->R, M = c->M, Mb = c->Mb, nprm = CSM_PRM_FLOATS, nn = N, jj = j0, cnt = n;
        cl_mem u = uvd, v = V, pr = rpl;
        if (mom) {
            cl_uint nm = HL_MSM_PRM_FLOATS;
            cl_kernel k = c->kmeg;
            SETARG(k, 0, c->img_d); SETARG(k, 1, c->mean_d); SETARG(k, 2, c->zsc_d); SETARG(k, 3, R);
            SETARG(k, 4, c->prm_d); SETARG(k, 5, nm); SETARG(k, 6, c->lights_d); SETARG(k, 7, c->zmin_d);
            SETARG(k, 8, u); SETARG(k, 9, pr); SETARG(k, 10, nn); SETARG(k, 11, jj); SETARG(k, 12, cnt);
            SETARG(k, 13, v);
            TRY(hl_cl_launch(ctx, k, (size_t)n * N, 0, "hl_msm_eval_grid"));
            continue;
        }
        SETARG(c->keg, 0, c->img_d); SETARG(c->keg, 1, c->mean_d); SETARG(c->keg, 2, c->zsc_d); SETARG(c->keg, 3, R);
        SETARG(c->keg, 4, M); SETARG(c->keg, 5, Mb); SETARG(c->keg, 6, c->prm_d); SETARG(c->keg, 7, nprm);
        SETARG(c->keg, 8, c->lights_d); SETARG(c->keg, 9, c->zmin_d); SETARG(c->keg, 10, u); SETARG(c->keg, 11, nn);
        SETARG(c->keg, 12, jj); SETARG(c->keg, 13, cnt); SETARG(c->keg, 14, v);
        TRY(hl_cl_launch(ctx, c->keg, (size_t)n * N, 0, "hl_csm_eval_grid"));
    }
    return HL_OK;
}

hl_result hl_csm_visibility(hl_csm *c, uint32_t k, float theta, const hl_shadow_frame *f, const float *uvd, uint32_t n,
                            float *V, float *zavg)
{
    if (!c) return HL_ERR_INVALID_ARGUMENT;
    const uint32_t start[2] = {0, n};
    return hl_csm_visibility_batch(c, 1, &k, &theta, &f, uvd, NULL, start, V, zavg);
}
