/* cl_device.c - choosing the OpenCL platform and device, opening a context
 * and queue on it (hl_cl_create), listing devices and their extensions,
 * and the names of OpenCL's error codes.
 *
 * Depends on: cl_internal.h (OpenCL), cl_program.c for the build.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"

const char *hl_cl_err_name(cl_int e)
{
    switch (e) {
#define E(x) case x: return #x;
    E(CL_SUCCESS) E(CL_DEVICE_NOT_FOUND) E(CL_DEVICE_NOT_AVAILABLE) E(CL_COMPILER_NOT_AVAILABLE)
    E(CL_MEM_OBJECT_ALLOCATION_FAILURE) E(CL_OUT_OF_RESOURCES) E(CL_OUT_OF_HOST_MEMORY)
    E(CL_BUILD_PROGRAM_FAILURE) E(CL_INVALID_VALUE) E(CL_INVALID_DEVICE) E(CL_INVALID_CONTEXT)
    E(CL_INVALID_COMMAND_QUEUE) E(CL_INVALID_MEM_OBJECT) E(CL_INVALID_PROGRAM)
    E(CL_INVALID_PROGRAM_EXECUTABLE) E(CL_INVALID_KERNEL_NAME) E(CL_INVALID_KERNEL)
    E(CL_INVALID_ARG_INDEX) E(CL_INVALID_ARG_VALUE) E(CL_INVALID_ARG_SIZE)
    E(CL_INVALID_KERNEL_ARGS) E(CL_INVALID_WORK_DIMENSION) E(CL_INVALID_WORK_GROUP_SIZE)
    E(CL_INVALID_WORK_ITEM_SIZE) E(CL_INVALID_GLOBAL_OFFSET) E(CL_INVALID_EVENT_WAIT_LIST)
    E(CL_INVALID_EVENT) E(CL_INVALID_OPERATION) E(CL_INVALID_BUFFER_SIZE)
    E(CL_INVALID_GLOBAL_WORK_SIZE) E(CL_INVALID_BUILD_OPTIONS) E(CL_INVALID_PLATFORM)
    E(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST) E(CL_MISALIGNED_SUB_BUFFER_OFFSET)
#undef E
    case -1001: return "CL_PLATFORM_NOT_FOUND_KHR (no OpenCL platform: is an ICD such as pocl-opencl-icd installed?)";
    default: return "unknown OpenCL error";
    }
}

/* The launches' shape (cl_internal.h): HL_DEVICE_SHAPE=cpu|gpu forces
 * one, else a CPU device gets the CPU shape and any other the GPU shape.
 * The GPU shape's work-groups: 64 work-items (two warps of 32, one
 * wavefront of 64), or the device's largest group where that is less. */
static int shape_is_gpu(cl_device_type type, int *forced)
{
    const char *v = getenv("HL_DEVICE_SHAPE");
    *forced = v && (!strcmp(v, "cpu") || !strcmp(v, "gpu"));
    return *forced ? !strcmp(v, "gpu") : !(type & CL_DEVICE_TYPE_CPU);
}

static hl_result choose_shape(hl_context *ctx, struct hl_cl *cl, cl_device_type type)
{
    const char *v = getenv("HL_DEVICE_SHAPE");
    if (v && *v && strcmp(v, "auto") != 0 && strcmp(v, "cpu") != 0 && strcmp(v, "gpu") != 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "HL_DEVICE_SHAPE=%s: expected cpu, gpu or auto", v);
    int forced;
    cl->gpu_shape = shape_is_gpu(type, &forced);
    cl->wg = cl->gpu_shape ? (cl->max_wg < 64 ? cl->max_wg : 64) : 1;
    return HL_OK;
}

/* The largest work-group kernel k may run with here, at most cap, as a
 * power of two. */
static size_t kernel_group(const struct hl_cl *cl, cl_kernel k, size_t cap)
{
    size_t most = 0;
    if (clGetKernelWorkGroupInfo(k, cl->device, CL_KERNEL_WORK_GROUP_SIZE, sizeof most, &most, NULL) != CL_SUCCESS)
        most = cl->max_wg;
    if (most > cl->max_wg) most = cl->max_wg;
    if (most > cap) most = cap;
    size_t p = 1;
    while (p * 2 <= most) p *= 2;
    return p;
}

/* The GPU shape's group sizes (cl_internal.h): up to 256 work-items, and
 * the selection as a group only where the kernel takes all
 * HL_SELECT_LANES (reqd_work_group_size) and its 6 KB of local memory. */
static void group_sizes(struct hl_cl *cl)
{
    /* tests: smaller groups, as a device with fewer registers a work-item
       would allow (HL_TEST_GROUP_CAP, a power of two) */
    const char *t = getenv("HL_TEST_GROUP_CAP");
    const size_t cap = t && strtoul(t, NULL, 10) > 0 && strtoul(t, NULL, 10) < 256 ? strtoul(t, NULL, 10) : 256;
    cl->haar_wg = kernel_group(cl, cl->k[K_HAAR_GROUP], cap);
    cl->items_wg = kernel_group(cl, cl->k[K_RELIGHT_ITEMS], cap);
    cl->select_group = cl->gpu_shape && kernel_group(cl, cl->k[K_SELECT_GROUP], HL_SELECT_LANES) == HL_SELECT_LANES &&
                       cl->local_mem >= 8192;
}

hl_result hl_cl_launch(hl_context *ctx, cl_kernel k, size_t n, size_t local, const char *what)
{
    if (!local) local = ctx->cl->gpu_shape ? ctx->cl->wg : 64;
    size_t global = (n + local - 1) / local * local;
    CL_TRY(ctx, clEnqueueNDRangeKernel(ctx->cl->queue, k, 1, NULL, &global, &local, 0, NULL, NULL), what);
    return HL_OK;
}

hl_result hl_cl_create(hl_context *ctx, int platform, int device, const intptr_t *properties,
                       uint64_t device_memory)
{
    cl_uint np = 0;
    cl_int e = clGetPlatformIDs(0, NULL, &np);
    if (e != CL_SUCCESS || np == 0)
        return hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: no platform found (%s); install an OpenCL driver such as pocl-opencl-icd, or use --device ref",
                       e == CL_SUCCESS ? "zero platforms" : hl_cl_err_name(e));
    cl_platform_id plats[16];
    if (np > 16) np = 16;
    clGetPlatformIDs(np, plats, NULL);
    /* no device named: HL_OPENCL_DEVICE=P:D names one (tests/gpu.sh runs
       the suite on a device of its choice so), else the first */
    const char *pick = getenv("HL_OPENCL_DEVICE"), *from = "";
    if (platform < 0 && device < 0 && pick && *pick) {
        from = " (named by HL_OPENCL_DEVICE)";
        int p = -1, d = -1;
        char tail;
        if (sscanf(pick, "%d:%d%c", &p, &d, &tail) != 2 || p < 0 || d < 0)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "HL_OPENCL_DEVICE=%s: expected P:D, as `haarlight devices` lists them", pick);
        platform = p;
        device = d;
    }
    if (platform >= (int)np)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "OpenCL: platform %d%s does not exist (%u found; see `haarlight devices`)",
                       platform, from, np);
    struct hl_cl *cl = calloc(1, sizeof *cl);
    if (!cl) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    ctx->cl = cl;
    int found = 0;
    for (cl_uint p = 0; p < np && !found; p++) {
        if (platform >= 0 && (int)p != platform) continue;
        cl_uint nd = 0;
        if (clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, 0, NULL, &nd) != CL_SUCCESS || nd == 0) continue;
        cl_device_id devs[16];
        if (nd > 16) nd = 16;
        clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, nd, devs, NULL);
        int want = device >= 0 ? device : 0;
        if (want >= (int)nd) {
            if (platform >= 0)
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "OpenCL: device %d does not exist on platform %u%s (%u found)",
                               device, p, from, nd);
            continue;
        }
        cl->platform = plats[p];
        cl->device = devs[want];
        found = 1;
    }
    if (!found) return hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: no device found on any platform; use --device ref");
    char pname[128] = "", dname[128] = "";
    clGetPlatformInfo(cl->platform, CL_PLATFORM_NAME, sizeof pname, pname, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_NAME, sizeof dname, dname, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_MAX_MEM_ALLOC_SIZE, sizeof cl->max_alloc, &cl->max_alloc, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_GLOBAL_MEM_SIZE, sizeof cl->limit, &cl->limit, NULL);
    if (device_memory && (!cl->limit || device_memory < cl->limit)) {
        cl->limit = device_memory;
        cl->limit_set = 1;
    }
    if (cl->limit && cl->max_alloc > cl->limit) cl->max_alloc = cl->limit;
    /* tests: a smaller largest allocation than the device's, in bytes */
    const char *cap = getenv("HL_TEST_MAX_ALLOC");
    if (cap && strtoull(cap, NULL, 10) > 0 && strtoull(cap, NULL, 10) < cl->max_alloc)
        cl->max_alloc = strtoull(cap, NULL, 10);
    snprintf(ctx->device_name, sizeof ctx->device_name, "OpenCL: %s / %s", pname, dname);
    cl_device_type type = 0;
    clGetDeviceInfo(cl->device, CL_DEVICE_TYPE, sizeof type, &type, NULL);
    cl->units = 1;
    clGetDeviceInfo(cl->device, CL_DEVICE_MAX_COMPUTE_UNITS, sizeof cl->units, &cl->units, NULL);
    if (cl->units < 1) cl->units = 1;
    cl->max_wg = 1;
    clGetDeviceInfo(cl->device, CL_DEVICE_MAX_WORK_GROUP_SIZE, sizeof cl->max_wg, &cl->max_wg, NULL);
    if (cl->max_wg < 1) cl->max_wg = 1;
    clGetDeviceInfo(cl->device, CL_DEVICE_LOCAL_MEM_SIZE, sizeof cl->local_mem, &cl->local_mem, NULL);
    cl->host_memory = (type & CL_DEVICE_TYPE_CPU) != 0;
    TRY(choose_shape(ctx, cl, type));
    snprintf(ctx->device_name + strlen(ctx->device_name), sizeof ctx->device_name - strlen(ctx->device_name),
             " (%s shape)", cl->gpu_shape ? "GPU" : "CPU");
    cl_context_properties props[34] = {CL_CONTEXT_PLATFORM, (cl_context_properties)cl->platform};
    size_t np_ = 2;
    for (size_t i = 0; properties && properties[i]; i += 2) {
        if (np_ + 3 > sizeof props / sizeof props[0])
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "OpenCL: more than 15 extra context properties");
        props[np_++] = (cl_context_properties)properties[i];
        props[np_++] = (cl_context_properties)properties[i + 1];
    }
    props[np_] = 0;
    cl->context = clCreateContext(props, 1, &cl->device, NULL, NULL, &e);
    if (e != CL_SUCCESS && properties && properties[0])
        return hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: %s refused a context with the given sharing properties (%s)", dname,
                       hl_cl_err_name(e));
    CL_TRY(ctx, e, "clCreateContext");
    cl->queue = clCreateCommandQueue(cl->context, cl->device, 0, &e);
    CL_TRY(ctx, e, "clCreateCommandQueue");
    TRY(hl_cl_build_program(ctx, cl));
    group_sizes(cl);
    return HL_OK;
}

void hl_cl_destroy(struct hl_cl *cl)
{
    if (!cl) return;
    for (int i = 0; i < K_COUNT; i++)
        if (cl->k[i]) clReleaseKernel(cl->k[i]);
    if (cl->program) clReleaseProgram(cl->program);
    if (cl->queue) clReleaseCommandQueue(cl->queue);
    if (cl->context) clReleaseContext(cl->context);
    free(cl);
}

hl_result hl_list_devices(void *file, char *err, size_t err_size)
{
    FILE *f = file;
    cl_uint np = 0;
    cl_int e = clGetPlatformIDs(0, NULL, &np);
    if (e != CL_SUCCESS || np == 0) {
        if (err && err_size)
            snprintf(err, err_size, "no OpenCL platform found (%s); install an OpenCL driver such as pocl-opencl-icd",
                     e == CL_SUCCESS ? "zero platforms" : hl_cl_err_name(e));
        return HL_ERR_OPENCL;
    }
    cl_platform_id plats[16];
    if (np > 16) np = 16;
    clGetPlatformIDs(np, plats, NULL);
    for (cl_uint p = 0; p < np; p++) {
        char name[256] = "", ver[256] = "";
        clGetPlatformInfo(plats[p], CL_PLATFORM_NAME, sizeof name, name, NULL);
        clGetPlatformInfo(plats[p], CL_PLATFORM_VERSION, sizeof ver, ver, NULL);
        fprintf(f, "platform %u: %s (%s)\n", p, name, ver);
        cl_uint nd = 0;
        if (clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, 0, NULL, &nd) != CL_SUCCESS) nd = 0;
        cl_device_id devs[16];
        if (nd > 16) nd = 16;
        if (nd) clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, nd, devs, NULL);
        for (cl_uint d = 0; d < nd; d++) {
            char dn[256] = "", dv[256] = "", ext[8192] = "";
            cl_uint cu = 0;
            cl_ulong mem = 0;
            cl_device_type type = 0;
            clGetDeviceInfo(devs[d], CL_DEVICE_NAME, sizeof dn, dn, NULL);
            clGetDeviceInfo(devs[d], CL_DEVICE_VERSION, sizeof dv, dv, NULL);
            clGetDeviceInfo(devs[d], CL_DEVICE_MAX_COMPUTE_UNITS, sizeof cu, &cu, NULL);
            clGetDeviceInfo(devs[d], CL_DEVICE_GLOBAL_MEM_SIZE, sizeof mem, &mem, NULL);
            clGetDeviceInfo(devs[d], CL_DEVICE_TYPE, sizeof type, &type, NULL);
            clGetDeviceInfo(devs[d], CL_DEVICE_EXTENSIONS, sizeof ext, ext, NULL);
            size_t wg = 0;
            cl_ulong lmem = 0;
            clGetDeviceInfo(devs[d], CL_DEVICE_MAX_WORK_GROUP_SIZE, sizeof wg, &wg, NULL);
            clGetDeviceInfo(devs[d], CL_DEVICE_LOCAL_MEM_SIZE, sizeof lmem, &lmem, NULL);
            fprintf(f, "  device %u: %s [%s] %s, %u compute units, %.1f GiB%s   (--device cl:%u:%u)\n", d, dn,
                    type & CL_DEVICE_TYPE_GPU ? "GPU" : type & CL_DEVICE_TYPE_CPU ? "CPU" : "other", dv, cu,
                    (double)mem / (1024.0 * 1024.0 * 1024.0), strstr(ext, "cl_khr_gl_sharing") ? ", GL sharing" : "", p, d);
            int forced;
            const int gpu = shape_is_gpu(type, &forced);
            fprintf(f, "            work-groups up to %zu, %.0f KiB local memory; runs in the %s shape%s\n", wg,
                    (double)lmem / 1024.0, gpu ? "GPU" : "CPU", forced ? " (HL_DEVICE_SHAPE)" : "");
        }
    }
    return HL_OK;
}

int hl_context_device_has_extension(const hl_context *ctx, const char *name)
{
    if (!ctx || !ctx->cl || !name || !*name) return 0;
    size_t n = 0;
    if (clGetDeviceInfo(ctx->cl->device, CL_DEVICE_EXTENSIONS, 0, NULL, &n) != CL_SUCCESS || !n) return 0;
    char *ext = malloc(n + 1);
    if (!ext) return 0;
    int found = 0;
    if (clGetDeviceInfo(ctx->cl->device, CL_DEVICE_EXTENSIONS, n, ext, NULL) == CL_SUCCESS) {
        ext[n] = '\0';
        size_t len = strlen(name);
        for (const char *p = ext; (p = strstr(p, name)) != NULL; p += len)
            if ((p == ext || p[-1] == ' ') && (p[len] == ' ' || p[len] == '\0')) { found = 1; break; }
    }
    free(ext);
    return found;
}
