/* test_stages.c - every OpenCL stage against its plain-C twin.
 *
 * Inputs are realistic: visibility from Embree on a small mesh with a
 * ground plane (the repo's data/ mesh), so rows have real shadows,
 * horizons and all-zero rows. Each stage gets identical inputs on both
 * sides; floats must agree to the stated tolerance and integers exactly.
 * Timings are printed for information only.
 *
 * ref_oom runs the plain-C twins under address-space limits and checks
 * that running out of memory is reported (HL_ERR_OUT_OF_MEMORY and a
 * message), never an abort.
 */
#define _DEFAULT_SOURCE /* fork, setrlimit, mallopt */
#include <signal.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "cl_backend.h"
#include "geom.h"
#include "hl_test.h"
#include "precompute.h"
#include "rays.h"
#include "twins.h"

typedef struct fixture {
    hl_context *cl, *ref;
    hl_mesh *mesh;
    hl_geom *g;
    hl_cl_pipe *pipe;
    uint32_t rows;
    uint8_t *vis;
    float *n4;
} fixture;

static hl_mesh *make_mesh(hl_context *ctx)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    hl_mesh *m = NULL;
    if (hl_mesh_load(ctx, path, NULL, &m, NULL) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(ctx));
        return NULL;
    }
    hl_ground_desc gd = {.resolution = 24};
    if (hl_mesh_add_ground(ctx, m, &gd) != HL_OK) {
        hl_mesh_destroy(m);
        return NULL;
    }
    return m;
}

/* rows vertices spread over the mesh, object and ground alike */
static int setup(fixture *f, uint32_t N, uint32_t C, uint32_t rows)
{
    memset(f, 0, sizeof *f);
    char err[4096];
    hl_context_desc dc = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1}, dr = {.backend = HL_BACKEND_REFERENCE};
    if (hl_context_create(&dc, &f->cl, err, sizeof err) != HL_OK) {
        fprintf(stderr, "OpenCL context: %s\n", err);
        return 0;
    }
    if (hl_context_create(&dr, &f->ref, err, sizeof err) != HL_OK) return 0;
    f->mesh = make_mesh(f->ref);
    if (!f->mesh) return 0;
    if (hl_geom_create(f->ref, N, C, &f->g) != HL_OK) return 0;
    if (hl_cl_pipe_create(f->cl, f->g, rows, &f->pipe) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(f->cl));
        return 0;
    }
    f->rows = rows;
    f->vis = malloc((size_t)rows * f->g->ncube);
    f->n4 = malloc((size_t)rows * 16);
    hl_rt *rt = NULL;
    if (hl_rt_create(f->ref, f->mesh, &rt) != HL_OK) return 0;
    float off = 1e-3f * hl_mesh_query_diagonal(f->mesh);
    for (uint32_t i = 0; i < rows; i++) {
        uint32_t v = (uint32_t)((uint64_t)i * f->mesh->vertex_count / rows);
        hl_rt_visibility(rt, f->g, f->mesh, v, 1, 1, off, f->vis + (size_t)i * f->g->ncube, NULL);
        memcpy(f->n4 + 4 * i, f->mesh->normals + 3 * (size_t)v, 12);
        f->n4[4 * i + 3] = 0.0f;
    }
    hl_rt_destroy(rt);
    return 1;
}

static void teardown(fixture *f)
{
    hl_cl_pipe_destroy(f->pipe);
    hl_geom_destroy(f->g);
    hl_mesh_destroy(f->mesh);
    hl_context_destroy(f->cl);
    hl_context_destroy(f->ref);
    free(f->vis);
    free(f->n4);
}

static const float VIS_SCALE = (float)(1.0 / 3.14159265358979323846);

/* Reference T and coefficients for all rows. */
static void ref_T(const fixture *f, float *T)
{
    for (uint32_t i = 0; i < f->rows; i++)
        hl_ref_cube2para(f->g, f->vis + (size_t)i * f->g->ncube, VIS_SCALE, f->n4 + 4 * i, T + (size_t)i * f->g->ncoef);
}

static double rel_diff(const float *a, const float *b, size_t n)
{
    double worst = 0.0, scale = 0.0;
    for (size_t i = 0; i < n; i++) scale = fmax(scale, fabs(a[i]));
    for (size_t i = 0; i < n; i++) worst = fmax(worst, fabs((double)a[i] - b[i]));
    return scale > 0 ? worst / scale : worst;
}

static void case_cube2para(void)
{
    static const uint32_t res[][2] = {{64, 64}, {16, 32}, {128, 48}};
    for (size_t k = 0; k < 3; k++) {
        fixture f;
        if (!setup(&f, res[k][0], res[k][1], 96)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
        size_t n = (size_t)f.rows * f.g->ncoef;
        float *a = malloc(n * 4), *b = malloc(n * 4);
        ref_T(&f, a);
        /* the first launch compiles PoCL's work-group function: warm up */
        hl_cl_pipe_cube2para(f.pipe, f.rows, f.vis, VIS_SCALE, f.n4, b);
        double t0 = hl_now();
        HL_CHECK(hl_cl_pipe_cube2para(f.pipe, f.rows, f.vis, VIS_SCALE, f.n4, b) == HL_OK, "%s", hl_context_last_error(f.cl));
        printf("N=%u C=%u: %u rows in %.2f ms\n", f.g->N, f.g->C, f.rows, 1e3 * (hl_now() - t0));
        /* same operations in the same order: only contraction or a
           different rounding mode could make them differ */
        hl_check_error("cube2para OpenCL vs C, relative to max |T|", rel_diff(a, b, n), 1e-6);
        free(a);
        free(b);
        teardown(&f);
    }
}

static void case_haar(void)
{
    static const uint32_t Ns[] = {8, 16, 64, 256};
    for (size_t k = 0; k < 4; k++) {
        fixture f;
        if (!setup(&f, Ns[k], 32, 24)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
        size_t n = (size_t)f.rows * f.g->ncoef;
        float *T = malloc(n * 4), *T2 = malloc(n * 4), *a = malloc(n * 4), *b = malloc(n * 4);
        ref_T(&f, T);
        memcpy(T2, T, n * 4);
        HL_CHECK(hl_cl_pipe_haar(f.pipe, f.rows, T, b) == HL_OK, "%s", hl_context_last_error(f.cl));
        for (uint32_t i = 0; i < f.rows; i++) hl_ref_haar(f.g, T2 + (size_t)i * f.g->ncoef, a + (size_t)i * f.g->ncoef);
        char what[64];
        snprintf(what, sizeof what, "haar N=%u OpenCL vs C, relative", f.g->N);
        hl_check_error(what, rel_diff(a, b, n), 1e-6);
        free(T); free(T2); free(a); free(b);
        teardown(&f);
    }
}

/* Coefficients of all rows plus synthetic rows: all zero, all equal
 * (every key tied), and one non-zero. */
static float *make_coef(fixture *f, uint32_t *rows_out)
{
    uint32_t rows = f->rows;
    size_t nc = f->g->ncoef;
    float *T = malloc((size_t)rows * nc * 4), *coef = malloc((size_t)rows * nc * 4);
    ref_T(f, T);
    for (uint32_t i = 0; i < rows; i++) hl_ref_haar(f->g, T + i * nc, coef + i * nc);
    memset(coef, 0, nc * 4);
    for (size_t j = 0; j < nc; j++) coef[nc + j] = (j & 1) ? -0.25f : 0.25f;
    memset(coef + 2 * nc, 0, nc * 4);
    coef[2 * nc + 77] = -3.0f;
    free(T);
    *rows_out = rows;
    return coef;
}

static const hl_trunc_params trunc_cases[] = {
    {HL_TRUNC_ALL, 0, 0, 0},         {HL_TRUNC_TOPK, 1, 0, 0},         {HL_TRUNC_TOPK, 100, 0, 0},
    {HL_TRUNC_TOPK, 8192, 0, 0},     {HL_TRUNC_TOPK, 100000, 0, 0},    {HL_TRUNC_TOPK, 0, 0, 0},
    {HL_TRUNC_ENERGY, 0, 10486, 0},  {HL_TRUNC_ENERGY, 0, 105, 0},     {HL_TRUNC_ENERGY, 50, 105, 0},
    {HL_TRUNC_ENERGY, 0, 0, 0},      {HL_TRUNC_ENERGY, 0, 1048575, 0},
};

static void case_truncate(void)
{
    fixture f;
    if (!setup(&f, 64, 64, 128)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
    uint32_t rows;
    float *coef = make_coef(&f, &rows);
    hl_trunc_result *a = malloc(rows * sizeof *a), *b = malloc(rows * sizeof *b);
    hl_ref_key *keys = malloc((size_t)f.g->ncoef * sizeof *keys);
    for (size_t c = 0; c < sizeof trunc_cases / sizeof *trunc_cases; c++) {
        hl_trunc_params p = trunc_cases[c];
        if (c == 0) hl_cl_pipe_truncate(f.pipe, rows, coef, p, b); /* warm-up: PoCL compiles lazily */
        double t0 = hl_now();
        HL_CHECK(hl_cl_pipe_truncate(f.pipe, rows, coef, p, b) == HL_OK, "%s", hl_context_last_error(f.cl));
        double t1 = hl_now();
        uint32_t mism = 0;
        uint64_t kept = 0;
        for (uint32_t i = 0; i < rows; i++) {
            a[i] = hl_ref_truncate(f.g, coef + (size_t)i * f.g->ncoef, p, keys);
            kept += a[i].count;
            if (a[i].thresh != b[i].thresh || a[i].ties != b[i].ties || a[i].count != b[i].count) {
                if (mism++ < 3)
                    fprintf(stderr, "row %u: C (%x %u %u) vs OpenCL (%x %u %u)\n", i, a[i].thresh, a[i].ties, a[i].count,
                            b[i].thresh, b[i].ties, b[i].count);
            }
        }
        printf("rule %u K %u eps_q20 %u: %.1f kept per row, %.2f ms OpenCL, %u of %u rows differ\n", p.rule, p.K,
               p.eps_q20, (double)kept / rows, 1e3 * (t1 - t0), mism, rows);
        HL_CHECK(mism == 0, "integer outputs must match exactly");
        /* rules that fix the count exactly */
        if (p.rule == HL_TRUNC_TOPK) HL_CHECK(a[3].count == (p.K < 8192 ? p.K : a[3].count), "top-K count");
        HL_CHECK(a[0].count == 0 && a[2].count == (p.rule == HL_TRUNC_TOPK && p.K == 0 ? 0u : 1u), "synthetic rows");
    }
    free(a); free(b); free(coef); free(keys);
    teardown(&f);
}

static void case_quantize(void)
{
    fixture f;
    if (!setup(&f, 64, 64, 128)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
    uint32_t rows;
    float *coef = make_coef(&f, &rows);
    const hl_geom *g = f.g;
    hl_trunc_result *tr = malloc(rows * sizeof *tr);
    hl_row_quant *rqa = malloc(rows * 8), *rqb = malloc(rows * 8);
    uint16_t *bca = malloc((size_t)rows * g->nblocks * 2), *bcb = malloc((size_t)rows * g->nblocks * 2);
    uint8_t *ea = calloc((size_t)rows * g->ncoef, 2), *eb = calloc((size_t)rows * g->ncoef, 2);
    uint32_t *na = malloc(rows * 4), *nb = malloc(rows * 4);
    hl_trunc_params tps[] = {{HL_TRUNC_ALL, 0, 0, 0}, {HL_TRUNC_ENERGY, 0, 105, 0}, {HL_TRUNC_TOPK, 7, 0, 0}};
    hl_ref_key *keys = malloc((size_t)g->ncoef * sizeof *keys);
    for (uint32_t scheme = HL_QUANT_LINEAR8; scheme <= HL_QUANT_MAX; scheme++)
        for (size_t c = 0; c < 3; c++) {
            for (uint32_t i = 0; i < rows; i++) tr[i] = hl_ref_truncate(g, coef + (size_t)i * g->ncoef, tps[c], keys);
            HL_CHECK(hl_cl_pipe_quantize(f.pipe, rows, 1000, coef, tr, scheme, rqb, bcb, eb, nb) == HL_OK, "%s",
                     hl_context_last_error(f.cl));
            uint32_t mism = 0;
            double qerr = 0.0, qscale = 0.0;
            for (uint32_t i = 0; i < rows; i++) {
                size_t eo = (size_t)i * g->ncoef * 2;
                na[i] = hl_ref_quantize(g, coef + (size_t)i * g->ncoef, tr[i], scheme, 1000 + i, &rqa[i],
                                        bca + (size_t)i * g->nblocks, ea + eo);
                int same = na[i] == nb[i] && na[i] == tr[i].count && rqa[i].a == rqb[i].a && rqa[i].b == rqb[i].b &&
                           !memcmp(bca + (size_t)i * g->nblocks, bcb + (size_t)i * g->nblocks, g->nblocks * 2) &&
                           !memcmp(ea + eo, eb + eo, 2 * (size_t)na[i]);
                mism += !same;
                /* quantisation error of the kept values, for the record */
                uint32_t e = 0;
                for (uint32_t b = 0; b < g->nblocks; b++)
                    for (uint32_t k = 0; k < bca[(size_t)i * g->nblocks + b]; k++, e++) {
                        uint32_t slot = b * 256 + ea[eo + 2 * e];
                        float v = coef[(size_t)i * g->ncoef + slot];
                        float d = hl_dequant(scheme, ea[eo + 2 * e + 1], rqa[i].a, rqa[i].b, hl_dither_key(1000 + i, slot));
                        qerr += ((double)v - d) * ((double)v - d);
                        qscale += (double)v * v;
                    }
            }
            printf("%s, rule %u: %u of %u rows differ; relative L2 quantisation error of kept values %.4f\n",
                   scheme == HL_QUANT_LOG8 ? "log8" : scheme == HL_QUANT_SQRT8 ? "sqrt8" : "linear8", tps[c].rule, mism, rows, qscale > 0 ? sqrt(qerr / qscale) : 0.0);
            HL_CHECK(mism == 0, "integer outputs and parameters must match exactly");
        }
    free(tr); free(rqa); free(rqb); free(bca); free(bcb); free(ea); free(eb); free(na); free(nb); free(coef); free(keys);
    teardown(&f);
}

/* The whole chunk path (what precompute runs) against hl_ref_rows. */
static void case_pipeline(void)
{
    fixture f;
    if (!setup(&f, 64, 64, 256)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
    const hl_geom *g = f.g;
    hl_chunk_buf a, b;
    hl_chunk_buf_alloc(f.ref, g, f.rows, &a);
    hl_chunk_buf_alloc(f.ref, g, f.rows, &b);
    memcpy(a.vis, f.vis, (size_t)f.rows * g->ncube);
    memcpy(b.vis, f.vis, (size_t)f.rows * g->ncube);
    memcpy(a.normals4, f.n4, (size_t)f.rows * 16);
    memcpy(b.normals4, f.n4, (size_t)f.rows * 16);
    hl_trunc_params tp = {HL_TRUNC_ENERGY, 0, 105, 0};
    hl_cl_pipe_submit(f.pipe, 0, f.rows, VIS_SCALE, tp, HL_QUANT_LOG8, &b); /* warm-up: PoCL compiles lazily */
    hl_cl_pipe_wait(f.pipe, 0);
    double t0 = hl_now();
    HL_CHECK(hl_ref_rows(f.ref, g, f.rows, VIS_SCALE, tp, HL_QUANT_LOG8, &a) == HL_OK, "ref rows");
    double t1 = hl_now();
    HL_CHECK(hl_cl_pipe_submit(f.pipe, 0, f.rows, VIS_SCALE, tp, HL_QUANT_LOG8, &b) == HL_OK, "%s", hl_context_last_error(f.cl));
    HL_CHECK(hl_cl_pipe_wait(f.pipe, 0) == HL_OK, "%s", hl_context_last_error(f.cl));
    double t2 = hl_now();
    uint32_t mism = 0;
    for (uint32_t i = 0; i < f.rows; i++) {
        size_t eo = (size_t)i * g->ncoef * 2;
        mism += !(a.nnz[i] == b.nnz[i] && a.rq[i].a == b.rq[i].a && a.rq[i].b == b.rq[i].b &&
                  !memcmp(a.bc + (size_t)i * g->nblocks, b.bc + (size_t)i * g->nblocks, g->nblocks * 2) &&
                  !memcmp(a.entries + eo, b.entries + eo, 2 * (size_t)a.nnz[i]));
    }
    printf("%u rows: reference %.1f ms, OpenCL %.1f ms; %u rows differ\n", f.rows, 1e3 * (t1 - t0), 1e3 * (t2 - t1), mism);
    HL_CHECK(mism == 0, "the OpenCL chunk must equal the reference byte for byte");
    hl_chunk_buf_free(&a);
    hl_chunk_buf_free(&b);
    teardown(&f);
}

/* sqrt8's subtractive dither on a smooth ramp of magnitudes (one per
 * vertex, as a coefficient varies over a surface): the error stays within
 * half a step in sqrt space, like plain rounding, but no longer follows
 * the value. Plain rounding's error is a sawtooth of the value itself
 * (correlation 1 with it); the dithered error must be nearly uncorrelated
 * with it, and unbiased. */
static void case_dither(void)
{
    const uint32_t n = 20000, slot = 77;
    const float b = 3.0f;
    double worst = 0.0, sum = 0.0, see = 0.0, srr = 0.0, ser = 0.0;
    for (uint32_t k = 0; k < n; k++) {
        const double s = (0.05 + 0.9 * k / (double)n); /* sqrt(|v| / b), smooth */
        const float v = (float)(b * s * s);
        const uint32_t key = hl_dither_key(k, slot), code = hl_quant_sqrt8(v, b, key);
        const double got = sqrt((double)hl_dequant_sqrt8(code, b, key) / b);
        const double err = got - sqrt((double)v / b), plain = nearbyint(127.0 * s) / 127.0 - s;
        worst = fmax(worst, fabs(err));
        sum += err;
        see += err * err;
        srr += plain * plain;
        ser += err * plain;
    }
    const double corr = ser / sqrt(see * srr), bias = sum / n;
    printf("dither: %u values: worst error %.3g of a step (tolerance 0.5 + 1e-4), bias %.3g of a step, correlation "
           "with plain rounding's error %.3f (tolerance 0.05)\n",
           n, 127.0 * worst, 127.0 * bias, corr);
    HL_CHECK(127.0 * worst <= 0.5 + 1e-4, "dithered error beyond half a step: %.4g", 127.0 * worst);
    HL_CHECK(fabs(corr) < 0.05, "the dithered error follows the value (correlation %.3f)", corr);
    HL_CHECK(fabs(127.0 * bias) < 0.02, "biased dither: %.3g of a step", 127.0 * bias);
}

/* ref_oom: hl_ref_rows (the four twins of a --device ref precompute) in
 * child processes, each under an address-space limit a little above what
 * it has mapped already, the margin rising from 0 in steps of 64 KiB. Each
 * child must exit by itself: either the rows are done, or
 * HL_ERR_OUT_OF_MEMORY with a message; a child killed by a signal (abort)
 * fails the case. The sweep must see both outcomes, so that it crossed
 * every allocation the twins make. N = 256 makes one row's scratch large
 * (a 512 KiB row and 1 MiB of sort keys), and every allocation of 64 KiB
 * or more is mapped afresh (mallopt), so none is served from memory the
 * parent freed and the limit bites each of them. Not run under
 * AddressSanitizer, whose shadow memory takes terabytes of address space. */
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HL_TEST_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define HL_TEST_ASAN 1
#endif

#ifndef HL_TEST_ASAN
static size_t mapped_bytes(void)
{
    unsigned long pages = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%lu", &pages) != 1) pages = 0;
        fclose(f);
    }
    return (size_t)pages * (size_t)sysconf(_SC_PAGESIZE);
}

/* Maps enough stack now that the children need not grow it under the limit. */
static void __attribute__((noinline)) touch_stack(void)
{
    volatile char pad[256 * 1024];
    for (size_t i = 0; i < sizeof pad; i += 1024) pad[i] = (char)i;
}

enum { OOM_OK = 0, OOM_REPORTED = 3, OOM_OTHER = 4, OOM_NO_LIMIT = 5 };

static int oom_child(hl_context *ctx, const hl_geom *g, uint32_t rows, const hl_chunk_buf *io, size_t margin)
{
#ifdef __GLIBC__
    mallopt(M_MMAP_THRESHOLD, 64 * 1024);
#endif
    struct rlimit rl;
    rl.rlim_cur = rl.rlim_max = (rlim_t)(mapped_bytes() + margin);
    if (mapped_bytes() == 0 || setrlimit(RLIMIT_AS, &rl) != 0) return OOM_NO_LIMIT;
    hl_trunc_params tp = {HL_TRUNC_ENERGY, 0, 105, 0};
    hl_result r = hl_ref_rows(ctx, g, rows, 1.0f / (float)HL_PI, tp, HL_QUANT_SQRT8, io);
    if (r == HL_OK) return OOM_OK;
    if (r == HL_ERR_OUT_OF_MEMORY && strstr(hl_context_last_error(ctx), "out of memory")) return OOM_REPORTED;
    return OOM_OTHER;
}
#endif

static void case_ref_oom(void)
{
#ifdef HL_TEST_ASAN
    printf("ref_oom: not run under AddressSanitizer\n");
#else
    hl_context_desc rd = {.backend = HL_BACKEND_REFERENCE, .threads = 1, .quiet = 1};
    hl_context *ctx = NULL;
    hl_geom *g = NULL;
    hl_chunk_buf io = {0};
    const uint32_t rows = 3;
    HL_CHECK(hl_context_create(&rd, &ctx, NULL, 0) == HL_OK, "reference context");
    HL_CHECK(ctx && hl_geom_create(ctx, 256, 16, &g) == HL_OK, "geometry N = 256");
    HL_CHECK(g && hl_chunk_buf_alloc(ctx, g, rows, &io) == HL_OK, "chunk buffers");
    if (!io.vis) {
        hl_geom_destroy(g);
        hl_context_destroy(ctx);
        return;
    }
    for (size_t i = 0; i < (size_t)rows * g->ncube; i++) io.vis[i] = (uint8_t)((i * 2654435761u >> 7) & 1u);
    for (uint32_t v = 0; v < rows; v++) {
        float *n = io.normals4 + 4 * (size_t)v;
        n[0] = 0.0f, n[1] = v == 1 ? 0.6f : 0.0f, n[2] = v == 1 ? 0.8f : 1.0f, n[3] = 0.0f;
    }
    touch_stack();
    fflush(stdout);
    const size_t step = 64 * 1024, steps = 64; /* margins 0 to 4 MiB */
    uint32_t n_ok = 0, n_reported = 0, n_killed = 0;
    size_t first_ok = 0;
    for (size_t k = 0; k <= steps; k++) {
        size_t margin = k * step;
        pid_t pid = fork();
        HL_CHECK(pid >= 0, "fork");
        if (pid < 0) break;
        if (pid == 0) _exit(oom_child(ctx, g, rows, &io, margin));
        int status = 0;
        HL_CHECK(waitpid(pid, &status, 0) == pid, "waitpid");
        if (WIFSIGNALED(status)) {
            n_killed++;
            HL_CHECK(0, "limit of %zu KiB above the mapped memory: the reference stages were killed by signal %d (%s) "
                     "instead of reporting HL_ERR_OUT_OF_MEMORY", margin / 1024, WTERMSIG(status),
                     WTERMSIG(status) == SIGABRT ? "abort" : "not abort");
            continue;
        }
        int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        HL_CHECK(code == OOM_OK || code == OOM_REPORTED, "limit of %zu KiB above the mapped memory: exit %d (%s)",
                 margin / 1024, code, code == OOM_NO_LIMIT ? "could not set the limit" : "another failure");
        if (code == OOM_REPORTED) n_reported++;
        if (code == OOM_OK && n_ok++ == 0) first_ok = margin;
    }
    printf("ref_oom: %zu limits from 0 to %zu KiB above the mapped memory: %u reported HL_ERR_OUT_OF_MEMORY with a "
           "message, %u completed the %u rows (from %zu KiB on), %u were killed by a signal\n",
           steps + 1, steps * step / 1024, n_reported, n_ok, rows, first_ok / 1024, n_killed);
    HL_CHECK(n_reported > 0, "no limit was tight enough to make the reference stages run out of memory");
    HL_CHECK(n_ok > 0, "no limit was loose enough for the reference stages to complete");
    hl_chunk_buf_free(&io);
    hl_geom_destroy(g);
    hl_context_destroy(ctx);
#endif
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"cube2para", case_cube2para}, {"haar", case_haar}, {"truncate", case_truncate},
        {"quantize", case_quantize},   {"pipeline", case_pipeline}, {"dither", case_dither},
        {"ref_oom", case_ref_oom},     {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
