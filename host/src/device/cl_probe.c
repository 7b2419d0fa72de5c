/* cl_probe.c - measuring the device itself (for `haarlight bench`): its
 * read bandwidth, which bounds the dot products.
 *
 * The relight's own probes (the kernel's time, the bytes it reads) need
 * its column layout and live with it (relight/cl_light_probe.c).
 * Depends on: cl_internal.h (OpenCL), core's clock and allocation.
 */
#include "cl_internal.h"

hl_result hl_cl_read_bandwidth(hl_context *ctx, size_t bytes, uint32_t reps, double *bytes_per_s)
{
    struct hl_cl *cl = ctx->cl;
    *bytes_per_s = 0.0;
    if (!cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    /* CPU shape: 64 work-items, each its own chunk (per float16s, even);
       GPU shape: 2,048 work-items a compute unit (what one holds at once
       on current GPUs) in groups of 256, reading float4s grid-wise
       (bandwidth.cl), the launches queued enough at a time (`batch`,
       from the first launch's time) to last a few milliseconds, so that
       one launch's latency (tens of microseconds, against 60 for 256 MiB
       at 4 TB/s) is not timed as reading */
    const int gpu = cl->gpu_shape;
    const size_t items = gpu ? (size_t)cl->units * 2048 : 64, per = bytes / 128 / 64 * 2;
    const size_t group = gpu ? (cl->max_wg < 256 ? cl->max_wg : 256) : 1;
    uint32_t batch = 1;
    size_t global = (items + group - 1) / group * group, local = group;
    cl_int e;
    /* memory of the kind the transport columns live in (on a CPU device,
       huge pages advised), which reads faster than PoCL's own */
    void *host = NULL;
    cl_mem buf = NULL;
    const size_t total = 64 * per * 64; /* bytes read a pass */
    hl_result res = hl_cl_big_buf(ctx, &buf, total, NULL, &host, "the bandwidth buffer");
    if (res != HL_OK) {
        hl_free_big(host);
        return res;
    }
    cl_mem out = NULL;
    res = hl_cl_make_buf(ctx, &out, CL_MEM_WRITE_ONLY, global * 4, NULL, "the bandwidth sums");
    if (res != HL_OK) {
        hl_cl_release_buf(cl, &buf);
        hl_free_big(host);
        return res;
    }
    const cl_uchar fill = 1; /* floats of 2.4e-38: normal, so no slow subnormal sums */
    e = clEnqueueFillBuffer(cl->queue, buf, &fill, 1, 0, total, 0, NULL, NULL);
    cl_kernel k = cl->k[gpu ? K_BANDWIDTH_GRID : K_BANDWIDTH];
    cl_ulong pi = gpu ? total / 16 : per; /* float4s in all, or float16s an item */
    if (e == CL_SUCCESS) e = clSetKernelArg(k, 0, sizeof buf, &buf);
    if (e == CL_SUCCESS) e = clSetKernelArg(k, 1, sizeof pi, &pi);
    if (e == CL_SUCCESS) e = clSetKernelArg(k, 2, sizeof out, &out);
    double best[64];
    if (reps > 64) reps = 64;
    for (uint32_t r = 0; e == CL_SUCCESS && r <= reps; r++) {
        double t0 = hl_now();
        for (uint32_t b = 0; e == CL_SUCCESS && b < batch; b++)
            e = clEnqueueNDRangeKernel(cl->queue, k, 1, NULL, &global, &local, 0, NULL, NULL);
        if (e == CL_SUCCESS) e = clFinish(cl->queue);
        const double t = (hl_now() - t0) / batch;
        if (r > 0) best[r - 1] = t; /* the first run warms up */
        if (r == 0 && gpu) batch = t > 0.0 && t < 4e-3 ? (uint32_t)(4e-3 / t) + 1 : 1;
    }
    hl_cl_release_buf(cl, &buf);
    hl_cl_release_buf(cl, &out);
    hl_free_big(host); /* PoCL is done with it once the buffer is released */
    CL_TRY(ctx, e, "the bandwidth kernel");
    /* median */
    for (uint32_t i = 1; i < reps; i++)
        for (uint32_t j = i; j > 0 && best[j - 1] > best[j]; j--) { double x = best[j]; best[j] = best[j - 1]; best[j - 1] = x; }
    *bytes_per_s = (double)total / best[reps / 2];
    return HL_OK;
}
