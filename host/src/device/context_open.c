/* context_open.c - creating and destroying a context (hl_context_create,
 * hl_context_destroy): the backend's choice, the thread count, and on the
 * OpenCL backend the device opened through hl_cl_create.
 *
 * It lives here, above core, so that core (errors, allocation, threads,
 * cancellation) calls nothing in device/. Depends on: cl_backend.h
 * (hl_cl_create, hl_cl_destroy), core (hl_fail, hl_parse_bytes).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "cl_backend.h"
#include "hl_internal.h"

hl_result hl_context_create(const hl_context_desc *desc, hl_context **out,
                            char *err, size_t err_size)
{
    hl_context_desc d = {0};
    if (desc) d = *desc;
    if (out) *out = NULL;
    if (err && err_size) err[0] = 0;
    if (!out) return HL_ERR_INVALID_ARGUMENT;
    hl_context *ctx = calloc(1, sizeof *ctx);
    if (!ctx) {
        if (err && err_size) snprintf(err, err_size, "out of memory creating the context");
        return HL_ERR_OUT_OF_MEMORY;
    }
    atomic_init(&ctx->cancelled, 0);
    ctx->backend = d.backend == HL_BACKEND_DEFAULT ? HL_BACKEND_OPENCL : d.backend;
    ctx->quiet = d.quiet;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    ctx->threads = d.threads > 0 ? d.threads : (cores > 0 ? (int)cores : 1);
    const char *kd = d.kernel_dir ? d.kernel_dir : getenv("HL_KERNEL_DIR");
    if (kd && *kd) snprintf(ctx->kernel_dir, sizeof ctx->kernel_dir, "%s", kd);

    hl_result r = HL_OK;
    if (ctx->backend == HL_BACKEND_OPENCL) {
        uint64_t limit = d.device_memory;
        const char *env = getenv("HL_DEVICE_MEMORY");
        if (!limit && env && *env && !hl_parse_bytes(env, &limit))
            r = hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                        "HL_DEVICE_MEMORY=%s: expected a byte count such as 512M or 2G", env);
        if (r == HL_OK) r = hl_cl_create(ctx, d.cl_platform, d.cl_device, d.cl_properties, limit);
    } else if (ctx->backend == HL_BACKEND_REFERENCE) {
        snprintf(ctx->device_name, sizeof ctx->device_name, "reference (plain C, %d threads)", ctx->threads);
    } else {
        r = hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "unknown backend %d", (int)d.backend);
    }
    if (r != HL_OK) {
        if (err && err_size) snprintf(err, err_size, "%s", ctx->err);
        hl_context_destroy(ctx);
        return r;
    }
    *out = ctx;
    return HL_OK;
}

void hl_context_destroy(hl_context *ctx)
{
    if (!ctx) return;
    hl_cl_destroy(ctx->cl);
    free(ctx);
}
