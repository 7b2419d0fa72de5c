/* context.c - the context's accessors, result strings and small host
 * helpers: errors, allocation, threads, the clock, cancellation.
 *
 * The context owns the compute device and the last error message, and the
 * cancellation flag. Nothing here is global. Creating and destroying a
 * context opens and closes the device, so those two live above core, in
 * device/context_open.c: core depends on nothing but libc and pthreads.
 */
#define _POSIX_C_SOURCE 200809L
#define _DEFAULT_SOURCE /* MADV_HUGEPAGE is a Linux extension */
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include "hl_internal.h"

static const char *const result_strings[HL_RESULT_COUNT] = {
    [HL_OK] = "success",
    [HL_ERR_INVALID_ARGUMENT] = "invalid argument",
    [HL_ERR_OUT_OF_MEMORY] = "out of memory",
    [HL_ERR_IO] = "input/output error",
    [HL_ERR_FORMAT] = "malformed file",
    [HL_ERR_MESH] = "invalid mesh",
    [HL_ERR_OPENCL] = "OpenCL error",
    [HL_ERR_EMBREE] = "Embree error",
    [HL_ERR_UNSUPPORTED] = "unsupported",
    [HL_ERR_INTERRUPTED] = "interrupted",
};

const char *hl_result_string(hl_result r)
{
    if ((int)r < 0 || r >= HL_RESULT_COUNT) return "unknown result code";
    return result_strings[r];
}

hl_result hl_fail(hl_context *ctx, hl_result code, const char *fmt, ...)
{
    if (ctx) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(ctx->err, sizeof ctx->err, fmt, ap);
        va_end(ap);
    }
    return code;
}

void *hl_malloc(hl_context *ctx, size_t bytes, const char *what)
{
    void *p = malloc(bytes ? bytes : 1);
    if (!p) hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory allocating %zu bytes for %s", bytes, what);
    return p;
}

void *hl_calloc(hl_context *ctx, size_t count, size_t size, const char *what)
{
    void *p = calloc(count ? count : 1, size ? size : 1);
    if (!p) hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory allocating %zu x %zu bytes for %s", count, size, what);
    return p;
}

void *hl_alloc_big(hl_context *ctx, size_t bytes, const char *what)
{
    void *p = NULL;
    /* madvise needs a page-aligned start; huge pages want 2 MiB */
    const size_t huge = (size_t)2 << 20;
    size_t align = bytes >= 2 * huge ? huge : 64;
    size_t rounded = (bytes + align - 1) & ~(align - 1);
    if (posix_memalign(&p, align, rounded ? rounded : 64) != 0) {
        hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory allocating %zu bytes for %s", bytes, what);
        return NULL;
    }
#ifdef MADV_HUGEPAGE
    if (align == huge) madvise(p, rounded, MADV_HUGEPAGE);
#endif
    return p;
}

void hl_free_big(void *p) { free(p); }

void hl_release_pages(void *p, size_t bytes)
{
    const long sz = sysconf(_SC_PAGESIZE);
    const uintptr_t pg = sz > 0 ? (uintptr_t)sz : 4096, a = (uintptr_t)p, b = a + bytes;
    const uintptr_t a2 = (a + pg - 1) / pg * pg, b2 = b / pg * pg;
#ifdef MADV_DONTNEED
    if (b2 > a2) madvise((void *)a2, b2 - a2, MADV_DONTNEED);
#endif
}

void hl_run_threads(int threads, void *(*fn)(void *), void *arg)
{
    pthread_t th[64];
    int n = threads > 64 ? 64 : threads, started = 0;
    for (int t = 1; t < n; t++)
        if (pthread_create(&th[started], NULL, fn, arg) == 0) started++;
    fn(arg);
    for (int t = 0; t < started; t++) pthread_join(th[t], NULL);
}

int hl_sync_fd(int fd)
{
    errno = 0;
    if (fsync(fd) == 0 || errno == EINVAL || errno == EROFS) return 0;
    return errno ? errno : EIO;
}

hl_result hl_publish_tmp(hl_context *ctx, const char *tmp, const char *path, hl_result r)
{
    /* on disk before the rename, as the files written through a FILE are */
    const int fd = r == HL_OK ? open(tmp, O_RDONLY) : -1;
    const int e = r != HL_OK ? 0 : fd < 0 ? errno : hl_sync_fd(fd);
    if (e) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write %s: %s", path, tmp, strerror(e));
    if (fd >= 0) close(fd);
    if (r == HL_OK && rename(tmp, path) != 0) {
        const int e2 = errno;
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot rename %s onto it: %s", path, tmp, strerror(e2));
    }
    if (r != HL_OK) unlink(tmp);
    return r;
}

double hl_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void hl_context_cancel(hl_context *ctx)
{
    /* one store to a lock-free atomic: async-signal-safe (see haarlight.h) */
    if (ctx) atomic_store(&ctx->cancelled, 1);
}

int hl_context_cancelled(const hl_context *ctx)
{
    return ctx && atomic_load(&ctx->cancelled) != 0;
}

int hl_parse_bytes(const char *s, uint64_t *out)
{
    if (!s || *s < '0' || *s > '9') return 0;
    uint64_t v = 0;
    for (; *s >= '0' && *s <= '9'; s++) {
        if (v > ((uint64_t)1 << 62) / 10) return 0;
        v = v * 10 + (uint64_t)(*s - '0');
    }
    unsigned shift = 0;
    if (*s == 'K' || *s == 'k') shift = 10;
    else if (*s == 'M' || *s == 'm') shift = 20;
    else if (*s == 'G' || *s == 'g') shift = 30;
    if (shift) s++;
    if (*s || v < 1 || v > (((uint64_t)1 << 62) >> shift)) return 0;
    *out = v << shift;
    return 1;
}

const char *hl_context_last_error(const hl_context *ctx) { return ctx ? ctx->err : ""; }
const char *hl_context_device_name(const hl_context *ctx) { return ctx ? ctx->device_name : ""; }
hl_backend hl_context_backend(const hl_context *ctx) { return ctx ? ctx->backend : HL_BACKEND_DEFAULT; }
void hl_context_set_quiet(hl_context *ctx, int quiet)
{
    if (ctx) ctx->quiet = quiet != 0;
}

int hl_context_quiet(const hl_context *ctx)
{
    return ctx ? ctx->quiet : 1;
}

int hl_context_threads(const hl_context *ctx) { return ctx ? ctx->threads : 1; }
