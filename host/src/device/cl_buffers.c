/* cl_buffers.c - device buffers, each counted against the context's device
 * memory limit so a job too big for it is refused up front with a message
 * saying what to change; and the plain buffers cl_backend.h hands out as
 * void * (tests of the relight's device output).
 *
 * Depends on: cl_internal.h (OpenCL), core's allocation (hl_alloc_big).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"

static void fmt_bytes(char *out, size_t n, uint64_t b)
{
    if (b >= (1ull << 30)) snprintf(out, n, "%.2f GiB", (double)b / (double)(1ull << 30));
    else if (b >= (1ull << 20)) snprintf(out, n, "%.1f MiB", (double)b / (double)(1ull << 20));
    else if (b >= (1ull << 10)) snprintf(out, n, "%.1f KiB", (double)b / (double)(1ull << 10));
    else snprintf(out, n, "%llu bytes", (unsigned long long)b);
}

/* Allocates a buffer counted against the context's device memory limit. */
hl_result hl_cl_make_buf(hl_context *ctx, cl_mem *m, cl_mem_flags fl, size_t bytes, const void *init,
                         const char *what)
{
    cl_int e;
    struct hl_cl *cl = ctx->cl;
    if (cl->limit && bytes > cl->limit - cl->used) {
        char need[32], lim[32], used[32];
        fmt_bytes(need, sizeof need, bytes);
        fmt_bytes(lim, sizeof lim, cl->limit);
        fmt_bytes(used, sizeof used, cl->used);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY,
                       "OpenCL: %s needs %s, beyond %s %s%s (%s already in use); %suse --device ref, or for "
                       "precompute a smaller --chunk",
                       what, need, cl->limit_set ? "the device memory limit of" : "the device's", lim,
                       cl->limit_set ? " (--device-memory or HL_DEVICE_MEMORY)" : " of memory", used,
                       cl->limit_set ? "raise the limit, " : "");
    }
    if (bytes > cl->max_alloc)
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY,
                       "OpenCL: %s needs %zu bytes, more than the device's largest allocation (%llu); use a smaller --chunk or --device ref",
                       what, bytes, (unsigned long long)cl->max_alloc);
    if (init && !(fl & CL_MEM_USE_HOST_PTR)) fl |= CL_MEM_COPY_HOST_PTR;
    *m = clCreateBuffer(cl->context, fl, bytes ? bytes : 4, (void *)init, &e);
    CL_TRY(ctx, e, what);
    cl->used += bytes ? bytes : 4;
    return HL_OK;
}

/* Releases a buffer made by hl_cl_make_buf and gives its bytes back. */
void hl_cl_release_buf(struct hl_cl *cl, cl_mem *m)
{
    if (!*m) return;
    size_t bytes = 0;
    if (clGetMemObjectInfo(*m, CL_MEM_SIZE, sizeof bytes, &bytes, NULL) == CL_SUCCESS)
        cl->used = bytes < cl->used ? cl->used - bytes : 0;
    clReleaseMemObject(*m);
    *m = NULL;
}

/* The host memory is ours rather than PoCL's because PoCL's allocations
 * are not advised huge pages, and the dot products' scattered reads then
 * miss the TLB: PERF-NOTES measured 1.5x the read rate with huge pages. */
hl_result hl_cl_big_buf(hl_context *ctx, cl_mem *m, size_t bytes, const void *init, void **keep, const char *what)
{
    if (!ctx->cl->host_memory || !bytes) return hl_cl_make_buf(ctx, m, CL_MEM_READ_ONLY, bytes, init, what);
    *keep = hl_alloc_big(ctx, bytes, what);
    if (!*keep) return HL_ERR_OUT_OF_MEMORY;
    if (init) memcpy(*keep, init, bytes);
    return hl_cl_make_buf(ctx, m, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR, bytes, *keep, what);
}

hl_result hl_cl_adopt_buf(hl_context *ctx, cl_mem *m, size_t bytes, void **host, const char *what)
{
    if (ctx->cl->host_memory && bytes)
        return hl_cl_make_buf(ctx, m, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR, bytes, *host, what);
    hl_result r = hl_cl_make_buf(ctx, m, CL_MEM_READ_ONLY, bytes, *host, what);
    hl_free_big(*host);
    *host = NULL;
    return r;
}

uint64_t hl_cl_memory_used(const hl_context *ctx) { return ctx->cl ? ctx->cl->used : 0; }

uint64_t hl_cl_memory_free(const hl_context *ctx)
{
    const struct hl_cl *cl = ctx->cl;
    if (!cl) return 0;
    if (!cl->limit) return UINT64_MAX;
    return cl->limit > cl->used ? cl->limit - cl->used : 0;
}

uint64_t hl_cl_largest_buffer(const hl_context *ctx)
{
    const uint64_t left = hl_cl_memory_free(ctx);
    return ctx->cl && ctx->cl->max_alloc < left ? ctx->cl->max_alloc : left;
}

hl_result hl_cl_buffer(hl_context *ctx, size_t bytes, void **out)
{
    *out = NULL;
    if (!ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    cl_mem m = NULL;
    hl_result r = hl_cl_make_buf(ctx, &m, CL_MEM_READ_WRITE, bytes, NULL, "the colour buffer");
    *out = m;
    return r;
}

hl_result hl_cl_buffer_read(hl_context *ctx, void *mem, size_t bytes, void *dst)
{
    CL_TRY(ctx, clEnqueueReadBuffer(ctx->cl->queue, (cl_mem)mem, CL_TRUE, 0, bytes, dst, 0, NULL, NULL), "read-back");
    return HL_OK;
}

void hl_cl_buffer_release(hl_context *ctx, void *mem)
{
    cl_mem m = mem;
    if (ctx->cl) hl_cl_release_buf(ctx->cl, &m);
}
