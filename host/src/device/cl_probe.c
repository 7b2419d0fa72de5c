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
    const size_t items = 64, per = bytes / 128 / items * 2; /* float16s per item, even */
    cl_int e;
    /* memory of the kind the transport columns live in (on a CPU device,
       huge pages advised), which reads faster than PoCL's own */
    void *host = NULL;
    cl_mem buf = NULL;
    hl_result res = hl_cl_big_buf(ctx, &buf, items * per * 64, NULL, &host, "the bandwidth buffer");
    if (res != HL_OK) {
        hl_free_big(host);
        return res;
    }
    cl_mem out = NULL;
    res = hl_cl_make_buf(ctx, &out, CL_MEM_WRITE_ONLY, items * 4, NULL, "the bandwidth sums");
    if (res != HL_OK) {
        hl_cl_release_buf(cl, &buf);
        hl_free_big(host);
        return res;
    }
    const cl_uchar fill = 1; /* floats of 2.4e-38: normal, so no slow subnormal sums */
    e = clEnqueueFillBuffer(cl->queue, buf, &fill, 1, 0, items * per * 64, 0, NULL, NULL);
    cl_kernel k = cl->k[K_BANDWIDTH];
    cl_ulong pi = per;
    if (e == CL_SUCCESS) e = clSetKernelArg(k, 0, sizeof buf, &buf);
    if (e == CL_SUCCESS) e = clSetKernelArg(k, 1, sizeof pi, &pi);
    if (e == CL_SUCCESS) e = clSetKernelArg(k, 2, sizeof out, &out);
    double best[64];
    if (reps > 64) reps = 64;
    size_t global = items, local = 1;
    for (uint32_t r = 0; e == CL_SUCCESS && r <= reps; r++) {
        double t0 = hl_now();
        e = clEnqueueNDRangeKernel(cl->queue, k, 1, NULL, &global, &local, 0, NULL, NULL);
        if (e == CL_SUCCESS) e = clFinish(cl->queue);
        if (r > 0) best[r - 1] = hl_now() - t0; /* the first run warms up */
    }
    hl_cl_release_buf(cl, &buf);
    hl_cl_release_buf(cl, &out);
    hl_free_big(host); /* PoCL is done with it once the buffer is released */
    CL_TRY(ctx, e, "the bandwidth kernel");
    /* median */
    for (uint32_t i = 1; i < reps; i++)
        for (uint32_t j = i; j > 0 && best[j - 1] > best[j]; j--) { double x = best[j]; best[j] = best[j - 1]; best[j - 1] = x; }
    *bytes_per_s = (double)(items * per * 64) / best[reps / 2];
    return HL_OK;
}
