/* test_precompute.c - the whole chunk path of a precompute (suite
 * "precompute").
 *
 * precompute.pipeline  the OpenCL chunk (cube2para, Haar, truncation,
 *                      quantisation) against hl_ref_rows byte for byte.
 * precompute.ref_oom   the plain-C twins under address-space limits:
 *                      running out of memory is reported
 *                      (HL_ERR_OUT_OF_MEMORY and a message), never an abort.
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL),
 * tests/common/stage_fixture.h, fork/setrlimit/mallopt.
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
#include "stage_fixture.h"

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
        {"pipeline", case_pipeline},
        {"ref_oom", case_ref_oom},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
