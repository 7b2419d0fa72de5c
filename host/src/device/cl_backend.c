/* cl_backend.c - everything OpenCL: device choice, program build, buffers
 * and the precompute stage launches. The only file that includes CL/cl.h.
 *
 * Kernels come from the binary (host/embed_kernels.cmake) or, when the
 * context names a kernel folder, from the kernels folder on disk. hl_shared.h is
 * prepended to the program so both sides share one layout.
 */
#define _POSIX_C_SOURCE 200809L
#define CL_TARGET_OPENCL_VERSION 120
#include <CL/cl.h>
#include <CL/cl_gl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_backend.h"
#include "geom.h"
#include "half.h"
#include "lighting.h"

typedef struct { const char *name; const char *source; } hl_embedded_kernel;
extern const char *const hl_embedded_shared;
extern const hl_embedded_kernel hl_embedded_kernels[];

enum { K_CUBE2PARA, K_HAAR, K_TRUNCATE, K_QUANTIZE, K_TURN, K_ENV2PARA, K_SELECT, K_RELIGHT, K_BANDWIDTH, K_COUNT };
static const char *const kernel_names[K_COUNT] = {"hl_cube2para", "hl_haar",   "hl_truncate", "hl_quantize", "hl_turn",
                                                  "hl_env2para",  "hl_select", "hl_relight",  "hl_read_bandwidth"};

struct hl_cl {
    cl_platform_id platform;
    cl_device_id device;
    cl_context context;
    cl_command_queue queue;
    cl_program program;
    cl_kernel k[K_COUNT];
    cl_ulong max_alloc;
    /* The device memory this context may hold at once: the device's global
       memory, or less (hl_context_desc.device_memory), so that a job too
       big for the memory a user grants is refused up front whatever the
       device; used counts the buffers made through make_buf. */
    cl_ulong limit, used;
    int limit_set; /* the limit came from the caller, not the device */
    size_t wg; /* work-group size: 1 on CPUs, where each work-item's long
                  row loop is the unit of work and PoCL would otherwise
                  put every row in one group on one core */
    cl_uint units; /* compute units (cores on a CPU device) */
};

static const char *cl_err_name(cl_int e)
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

/* Out of device memory or resources: a smaller precompute chunk may fit;
 * any other failure: only the reference backend is sure to help. */
#define CL_TRY(ctx, call, what)                                                            \
    do {                                                                                   \
        cl_int e_ = (call);                                                                \
        if (e_ != CL_SUCCESS) {                                                            \
            int mem_ = e_ == CL_MEM_OBJECT_ALLOCATION_FAILURE || e_ == CL_OUT_OF_RESOURCES; \
            return hl_fail((ctx), mem_ ? HL_ERR_OUT_OF_MEMORY : HL_ERR_OPENCL, "OpenCL: %s failed: %s (%d); %s", \
                           what, cl_err_name(e_), (int)e_,                                 \
                           mem_ ? "try a smaller --chunk (precompute) or --device ref" : "try --device ref"); \
        }                                                                                  \
    } while (0)

static char *read_text_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    char *buf = NULL;
    if (fseek(f, 0, SEEK_END) == 0) {
        long n = ftell(f);
        if (n >= 0 && n < (1L << 24) && fseek(f, 0, SEEK_SET) == 0) {
            buf = malloc((size_t)n + 1);
            if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) { free(buf); buf = NULL; }
            if (buf) buf[n] = 0;
        }
    }
    fclose(f);
    return buf;
}

/* One program source: the shared header, then every kernel file. */
static hl_result assemble_source(hl_context *ctx, char **out)
{
    size_t cap = 1 << 16, len = 0;
    char *src = malloc(cap);
    if (!src) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory assembling kernel source");
    src[0] = 0;
    const int from_disk = ctx->kernel_dir[0] != 0;
    for (int i = -1;; i++) {
        const char *text;
        char *owned = NULL;
        char path[1200];
        if (i < 0) { /* the shared header first */
            snprintf(path, sizeof path, "%s/../host/src/device/hl_shared.h", ctx->kernel_dir);
            text = hl_embedded_shared;
        } else {
            const hl_embedded_kernel *k = &hl_embedded_kernels[i];
            if (!k->name) break;
            snprintf(path, sizeof path, "%s/%s", ctx->kernel_dir, k->name);
            text = k->source;
        }
        if (from_disk) {
            owned = read_text_file(path);
            if (!owned) {
                free(src);
                return hl_fail(ctx, HL_ERR_IO, "%s: cannot read kernel source (HL_KERNEL_DIR is set to %s)", path, ctx->kernel_dir);
            }
            text = owned;
        }
        size_t n = strlen(text);
        if (len + n + 2 > cap) {
            while (len + n + 2 > cap) cap *= 2;
            char *p = realloc(src, cap);
            if (!p) { free(src); free(owned); return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory assembling kernel source"); }
            src = p;
        }
        memcpy(src + len, text, n);
        len += n;
        src[len++] = '\n';
        src[len] = 0;
        free(owned);
    }
    *out = src;
    return HL_OK;
}

/* rows per work-item of hl_cube2para (HL_C2P_ROWS in kernels/maps/cube2para.cl) */
#define C2P_ROWS 4u

static hl_result build_program(hl_context *ctx, struct hl_cl *cl)
{
    char *src = NULL;
    hl_result r = assemble_source(ctx, &src);
    if (r != HL_OK) return r;
    cl_int e;
    const char *srcs[1] = {src};
    cl->program = clCreateProgramWithSource(cl->context, 1, srcs, NULL, &e);
    free(src);
    CL_TRY(ctx, e, "clCreateProgramWithSource");
    char opts[256];
    snprintf(opts, sizeof opts, "-cl-std=CL1.2 -DHL_C2P_ROWS=%u", C2P_ROWS);
    cl_device_fp_config fp = 0;
    clGetDeviceInfo(cl->device, CL_DEVICE_SINGLE_FP_CONFIG, sizeof fp, &fp, NULL);
    /* the quantiser divides; correctly rounded division makes the OpenCL
       integers equal to the plain-C twin's where the device allows it */
    if (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) strcat(opts, " -cl-fp32-correctly-rounded-divide-sqrt");
    e = clBuildProgram(cl->program, 1, &cl->device, opts, NULL, NULL);
    if (e != CL_SUCCESS) {
        size_t n = 0;
        clGetProgramBuildInfo(cl->program, cl->device, CL_PROGRAM_BUILD_LOG, 0, NULL, &n);
        char *log = malloc(n + 1);
        if (log) {
            log[0] = 0;
            clGetProgramBuildInfo(cl->program, cl->device, CL_PROGRAM_BUILD_LOG, n, log, NULL);
            log[n] = 0;
        }
        hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: kernel build failed: %s (%d); build log:\n%s\n(use --device ref to run the plain-C reference instead)",
                cl_err_name(e), (int)e, log ? log : "(no log)");
        free(log);
        return HL_ERR_OPENCL;
    }
    for (int i = 0; i < K_COUNT; i++) {
        cl->k[i] = clCreateKernel(cl->program, kernel_names[i], &e);
        CL_TRY(ctx, e, kernel_names[i]);
    }
    return HL_OK;
}

hl_result hl_cl_create(hl_context *ctx, int platform, int device, const intptr_t *properties,
                       uint64_t device_memory)
{
    cl_uint np = 0;
    cl_int e = clGetPlatformIDs(0, NULL, &np);
    if (e != CL_SUCCESS || np == 0)
        return hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: no platform found (%s); install an OpenCL driver such as pocl-opencl-icd, or use --device ref",
                       e == CL_SUCCESS ? "zero platforms" : cl_err_name(e));
    cl_platform_id plats[16];
    if (np > 16) np = 16;
    clGetPlatformIDs(np, plats, NULL);
    if (platform >= (int)np)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "OpenCL: platform %d does not exist (%u found; see `haarlight devices`)", platform, np);
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
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "OpenCL: device %d does not exist on platform %u (%u found)", device, p, nd);
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
    snprintf(ctx->device_name, sizeof ctx->device_name, "OpenCL: %s / %s", pname, dname);
    cl_device_type type = 0;
    clGetDeviceInfo(cl->device, CL_DEVICE_TYPE, sizeof type, &type, NULL);
    cl->wg = (type & CL_DEVICE_TYPE_CPU) ? 1 : 64;
    cl->units = 1;
    clGetDeviceInfo(cl->device, CL_DEVICE_MAX_COMPUTE_UNITS, sizeof cl->units, &cl->units, NULL);
    if (cl->units < 1) cl->units = 1;
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
                       cl_err_name(e));
    CL_TRY(ctx, e, "clCreateContext");
    cl->queue = clCreateCommandQueue(cl->context, cl->device, 0, &e);
    CL_TRY(ctx, e, "clCreateCommandQueue");
    return build_program(ctx, cl);
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
                     e == CL_SUCCESS ? "zero platforms" : cl_err_name(e));
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
            fprintf(f, "  device %u: %s [%s] %s, %u compute units, %.1f GiB%s   (--device cl:%u:%u)\n", d, dn,
                    type & CL_DEVICE_TYPE_GPU ? "GPU" : type & CL_DEVICE_TYPE_CPU ? "CPU" : "other", dv, cu,
                    (double)mem / (1024.0 * 1024.0 * 1024.0), strstr(ext, "cl_khr_gl_sharing") ? ", GL sharing" : "", p, d);
        }
    }
    return HL_OK;
}

/* ------------------------------------------------------------ pipeline */

struct hl_cl_pipe {
    hl_context *ctx;
    struct hl_cl *cl;
    const hl_geom *g;
    uint32_t max_rows;
    cl_mem start, ent, slots;          /* geometry tables */
    cl_mem vis[2], nrm[2];             /* inputs, one per slot */
    cl_mem T, coef, tr, rq, bc, entries, nnz;
    cl_event done[2];
};

static void fmt_bytes(char *out, size_t n, uint64_t b)
{
    if (b >= (1ull << 30)) snprintf(out, n, "%.2f GiB", (double)b / (double)(1ull << 30));
    else if (b >= (1ull << 20)) snprintf(out, n, "%.1f MiB", (double)b / (double)(1ull << 20));
    else if (b >= (1ull << 10)) snprintf(out, n, "%.1f KiB", (double)b / (double)(1ull << 10));
    else snprintf(out, n, "%llu bytes", (unsigned long long)b);
}

/* Allocates a buffer counted against the context's device memory limit. */
static hl_result make_buf(hl_cl_pipe *p, cl_mem *m, cl_mem_flags fl, size_t bytes, const void *init, const char *what)
{
    cl_int e;
    struct hl_cl *cl = p->cl;
    if (cl->limit && bytes > cl->limit - cl->used) {
        char need[32], lim[32], used[32];
        fmt_bytes(need, sizeof need, bytes);
        fmt_bytes(lim, sizeof lim, cl->limit);
        fmt_bytes(used, sizeof used, cl->used);
        return hl_fail(p->ctx, HL_ERR_OUT_OF_MEMORY,
                       "OpenCL: %s needs %s, beyond %s %s%s (%s already in use); %suse --device ref, or for "
                       "precompute a smaller --chunk",
                       what, need, cl->limit_set ? "the device memory limit of" : "the device's", lim,
                       cl->limit_set ? " (--device-memory or HL_DEVICE_MEMORY)" : " of memory", used,
                       cl->limit_set ? "raise the limit, " : "");
    }
    if (bytes > cl->max_alloc)
        return hl_fail(p->ctx, HL_ERR_OUT_OF_MEMORY,
                       "OpenCL: %s needs %zu bytes, more than the device's largest allocation (%llu); use a smaller --chunk or --device ref",
                       what, bytes, (unsigned long long)cl->max_alloc);
    if (init && !(fl & CL_MEM_USE_HOST_PTR)) fl |= CL_MEM_COPY_HOST_PTR;
    *m = clCreateBuffer(cl->context, fl, bytes ? bytes : 4, (void *)init, &e);
    CL_TRY(p->ctx, e, what);
    cl->used += bytes ? bytes : 4;
    return HL_OK;
}

/* Releases a buffer made by make_buf and gives its bytes back. */
static void release_buf(struct hl_cl *cl, cl_mem *m)
{
    if (!*m) return;
    size_t bytes = 0;
    if (clGetMemObjectInfo(*m, CL_MEM_SIZE, sizeof bytes, &bytes, NULL) == CL_SUCCESS)
        cl->used = bytes < cl->used ? cl->used - bytes : 0;
    clReleaseMemObject(*m);
    *m = NULL;
}

hl_result hl_cl_pipe_create(hl_context *ctx, const hl_geom *g, uint32_t max_rows, hl_cl_pipe **out)
{
    *out = NULL;
    if (!ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    hl_cl_pipe *p = calloc(1, sizeof *p);
    if (!p) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    p->ctx = ctx;
    p->cl = ctx->cl;
    p->g = g;
    p->max_rows = max_rows;
    size_t R = max_rows, nc = g->ncoef;
    hl_result r = HL_OK;
#define B(m, fl, bytes, init, what) if (r == HL_OK) r = make_buf(p, &p->m, fl, bytes, init, what)
    B(start, CL_MEM_READ_ONLY, ((size_t)g->ncube + 1) * 4, g->p2c_start, "the table rows");
    B(ent, CL_MEM_READ_ONLY, (size_t)g->nentries * sizeof(hl_c2p_entry), g->p2c, "the table entries");
    B(slots, CL_MEM_READ_ONLY, (size_t)g->N * g->N * 4, g->slot_of_mallat, "the Haar slot order");
    B(vis[0], CL_MEM_READ_ONLY, R * g->ncube, NULL, "visibility (slot 0)");
    B(vis[1], CL_MEM_READ_ONLY, R * g->ncube, NULL, "visibility (slot 1)");
    B(nrm[0], CL_MEM_READ_ONLY, R * 16, NULL, "normals (slot 0)");
    B(nrm[1], CL_MEM_READ_ONLY, R * 16, NULL, "normals (slot 1)");
    B(T, CL_MEM_READ_WRITE, R * nc * 4, NULL, "paraboloid transport");
    B(coef, CL_MEM_READ_WRITE, R * nc * 4, NULL, "Haar coefficients");
    B(tr, CL_MEM_READ_WRITE, R * sizeof(hl_trunc_result), NULL, "truncation results");
    B(rq, CL_MEM_READ_WRITE, R * sizeof(hl_row_quant), NULL, "quantisation parameters");
    B(bc, CL_MEM_READ_WRITE, R * g->nblocks * 2, NULL, "block counts");
    B(entries, CL_MEM_READ_WRITE, R * nc * 2, NULL, "packed entries");
    B(nnz, CL_MEM_READ_WRITE, R * 4, NULL, "entry counts");
#undef B
    if (r != HL_OK) { hl_cl_pipe_destroy(p); return r; }
    *out = p;
    return HL_OK;
}

void hl_cl_pipe_destroy(hl_cl_pipe *p)
{
    if (!p) return;
    if (p->cl && p->cl->queue) clFinish(p->cl->queue);
    cl_mem *all[] = {&p->start, &p->ent, &p->slots, &p->vis[0], &p->vis[1], &p->nrm[0], &p->nrm[1],
                     &p->T, &p->coef, &p->tr, &p->rq, &p->bc, &p->entries, &p->nnz};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) release_buf(p->cl, all[i]);
    for (int s = 0; s < 2; s++)
        if (p->done[s]) clReleaseEvent(p->done[s]);
    free(p);
}

#define ARG(k, i, v) CL_TRY(p->ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")

static hl_result launch(hl_cl_pipe *p, int which, uint32_t rows)
{
    if (which == K_CUBE2PARA) rows = (rows + C2P_ROWS - 1) / C2P_ROWS;
    size_t local = p->cl->wg, global = (rows + local - 1) / local * local;
    CL_TRY(p->ctx, clEnqueueNDRangeKernel(p->cl->queue, p->cl->k[which], 1, NULL, &global, &local, 0, NULL, NULL),
           kernel_names[which]);
    return HL_OK;
}

static hl_result enqueue_cube2para(hl_cl_pipe *p, int slot, uint32_t rows, float scale)
{
    cl_kernel k = p->cl->k[K_CUBE2PARA];
    cl_uint ncube = p->g->ncube, ncoef = p->g->ncoef, n = rows;
    ARG(k, 0, p->vis[slot]); ARG(k, 1, ncube); ARG(k, 2, scale); ARG(k, 3, p->nrm[slot]);
    ARG(k, 4, p->start); ARG(k, 5, p->ent); ARG(k, 6, ncoef); ARG(k, 7, p->T); ARG(k, 8, n);
    return launch(p, K_CUBE2PARA, rows);
}

static hl_result enqueue_haar(hl_cl_pipe *p, uint32_t rows)
{
    cl_kernel k = p->cl->k[K_HAAR];
    cl_uint N = p->g->N, n = rows;
    ARG(k, 0, p->T); ARG(k, 1, p->coef); ARG(k, 2, p->slots); ARG(k, 3, N); ARG(k, 4, n);
    return launch(p, K_HAAR, rows);
}

static hl_result enqueue_truncate(hl_cl_pipe *p, uint32_t rows, hl_trunc_params tp)
{
    cl_kernel k = p->cl->k[K_TRUNCATE];
    cl_uint ncoef = p->g->ncoef, n = rows;
    ARG(k, 0, p->coef); ARG(k, 1, ncoef); ARG(k, 2, tp); ARG(k, 3, p->tr); ARG(k, 4, n);
    return launch(p, K_TRUNCATE, rows);
}

static hl_result enqueue_quantize(hl_cl_pipe *p, uint32_t rows, uint32_t scheme, uint32_t first)
{
    cl_kernel k = p->cl->k[K_QUANTIZE];
    cl_uint ncoef = p->g->ncoef, nb = p->g->nblocks, n = rows, sc = scheme, f0 = first;
    ARG(k, 0, p->coef); ARG(k, 1, ncoef); ARG(k, 2, nb); ARG(k, 3, p->tr); ARG(k, 4, sc);
    ARG(k, 5, p->rq); ARG(k, 6, p->bc); ARG(k, 7, p->entries); ARG(k, 8, p->nnz); ARG(k, 9, n);
    ARG(k, 10, f0);
    return launch(p, K_QUANTIZE, rows);
}

static hl_result check_rows(hl_cl_pipe *p, uint32_t rows)
{
    if (rows > p->max_rows)
        return hl_fail(p->ctx, HL_ERR_INVALID_ARGUMENT, "%u rows exceed the pipeline's %u", rows, p->max_rows);
    return HL_OK;
}

#define TRY(x) do { hl_result r_ = (x); if (r_ != HL_OK) return r_; } while (0)
#define WRITE(buf, bytes, src, blocking) \
    CL_TRY(p->ctx, clEnqueueWriteBuffer(p->cl->queue, buf, blocking, 0, bytes, src, 0, NULL, NULL), "upload")
#define READ(buf, bytes, dst, blocking, ev) \
    CL_TRY(p->ctx, clEnqueueReadBuffer(p->cl->queue, buf, blocking, 0, bytes, dst, 0, NULL, ev), "read-back")

hl_result hl_cl_pipe_submit(hl_cl_pipe *p, int slot, uint32_t rows, float vis_scale,
                            hl_trunc_params tp, uint32_t scheme, const hl_chunk_buf *io)
{
    TRY(check_rows(p, rows));
    const hl_geom *g = p->g;
    size_t R = rows;
    WRITE(p->vis[slot], R * g->ncube, io->vis, CL_FALSE);
    WRITE(p->nrm[slot], R * 16, io->normals4, CL_FALSE);
    TRY(enqueue_cube2para(p, slot, rows, vis_scale));
    TRY(enqueue_haar(p, rows));
    TRY(enqueue_truncate(p, rows, tp));
    TRY(enqueue_quantize(p, rows, scheme, io->first));
    READ(p->tr, R * sizeof(hl_trunc_result), io->tr, CL_FALSE, NULL);
    READ(p->rq, R * sizeof(hl_row_quant), io->rq, CL_FALSE, NULL);
    READ(p->bc, R * g->nblocks * 2, io->bc, CL_FALSE, NULL);
    READ(p->nnz, R * 4, io->nnz, CL_FALSE, NULL);
    if (p->done[slot]) { clReleaseEvent(p->done[slot]); p->done[slot] = NULL; }
    READ(p->entries, R * g->ncoef * 2, io->entries, CL_FALSE, &p->done[slot]);
    CL_TRY(p->ctx, clFlush(p->cl->queue), "clFlush");
    return HL_OK;
}

hl_result hl_cl_pipe_wait(hl_cl_pipe *p, int slot)
{
    if (!p->done[slot]) return HL_OK;
    CL_TRY(p->ctx, clWaitForEvents(1, &p->done[slot]), "waiting for the kernels");
    clReleaseEvent(p->done[slot]);
    p->done[slot] = NULL;
    return HL_OK;
}

hl_result hl_cl_pipe_cube2para(hl_cl_pipe *p, uint32_t rows, const uint8_t *vis, float scale,
                               const float *normals4, float *T)
{
    TRY(check_rows(p, rows));
    WRITE(p->vis[0], (size_t)rows * p->g->ncube, vis, CL_TRUE);
    WRITE(p->nrm[0], (size_t)rows * 16, normals4, CL_TRUE);
    TRY(enqueue_cube2para(p, 0, rows, scale));
    READ(p->T, (size_t)rows * p->g->ncoef * 4, T, CL_TRUE, NULL);
    return HL_OK;
}

hl_result hl_cl_pipe_haar(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef)
{
    TRY(check_rows(p, rows));
    WRITE(p->T, (size_t)rows * p->g->ncoef * 4, T, CL_TRUE);
    TRY(enqueue_haar(p, rows));
    READ(p->coef, (size_t)rows * p->g->ncoef * 4, coef, CL_TRUE, NULL);
    return HL_OK;
}

hl_result hl_cl_pipe_truncate(hl_cl_pipe *p, uint32_t rows, const float *coef, hl_trunc_params tp,
                              hl_trunc_result *tr)
{
    TRY(check_rows(p, rows));
    WRITE(p->coef, (size_t)rows * p->g->ncoef * 4, coef, CL_TRUE);
    TRY(enqueue_truncate(p, rows, tp));
    READ(p->tr, (size_t)rows * sizeof *tr, tr, CL_TRUE, NULL);
    return HL_OK;
}

hl_result hl_cl_pipe_quantize(hl_cl_pipe *p, uint32_t rows, uint32_t first, const float *coef,
                              const hl_trunc_result *tr, uint32_t scheme, hl_row_quant *rq, uint16_t *bc,
                              uint8_t *entries, uint32_t *nnz)
{
    TRY(check_rows(p, rows));
    const hl_geom *g = p->g;
    WRITE(p->coef, (size_t)rows * g->ncoef * 4, coef, CL_TRUE);
    WRITE(p->tr, (size_t)rows * sizeof *tr, tr, CL_TRUE);
    TRY(enqueue_quantize(p, rows, scheme, first));
    READ(p->rq, (size_t)rows * sizeof *rq, rq, CL_TRUE, NULL);
    READ(p->bc, (size_t)rows * g->nblocks * 2, bc, CL_TRUE, NULL);
    READ(p->entries, (size_t)rows * g->ncoef * 2, entries, CL_TRUE, NULL);
    READ(p->nnz, (size_t)rows * 4, nnz, CL_TRUE, NULL);
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

/* ------------------------------------------------------------ lighting */

struct hl_cl_light {
    hl_context *ctx;
    struct hl_cl *cl;
    const hl_geom *g;
    const hl_light_geom *lg;
    uint32_t nverts, scheme;
    cl_uint keep_negative; /* the dot products' clamp at zero is off */
    cl_mem cells, turned, start, runs, slots, weight; /* tables and inputs */
    cl_mem Lp, Lw, Lsel, used, bits, res, keys;    /* lighting stages */
    cl_mem col, cols, rel, rstart, back, albedo, B, acc; /* transport, by column */
    cl_mem ord, klist;                              /* vertex at each position; kept slots */
    void *host[4];                                  /* CPU devices: their memory */
    uint32_t nranges, *range_start;                 /* vertices of each work-item */
    uint32_t tstride;                               /* most tiles in a range */
    uint64_t col_entries;                           /* tile entries in all columns */
    uint32_t *col_start;                            /* host copy, for counting bytes */
    uint32_t *order;                                /* vertex at each position */
};

void hl_cl_light_destroy(hl_cl_light *l)
{
    if (!l) return;
    if (l->cl && l->cl->queue) clFinish(l->cl->queue);
    cl_mem *all[] = {&l->cells, &l->turned, &l->start, &l->runs, &l->slots, &l->weight, &l->Lp, &l->Lw, &l->Lsel, &l->used,
                     &l->bits, &l->res, &l->keys, &l->col, &l->cols, &l->rel, &l->rstart, &l->back, &l->albedo, &l->B,
                     &l->acc, &l->ord, &l->klist};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) release_buf(l->cl, all[i]);
    for (int i = 0; i < 4; i++) hl_free_big(l->host[i]);
    free(l->col_start);
    free(l->range_start);
    free(l->order);
    free(l);
}

static hl_result light_buf(hl_cl_light *l, cl_mem *m, cl_mem_flags fl, size_t bytes, const void *init, const char *what)
{
    hl_cl_pipe tmp = {.ctx = l->ctx, .cl = l->cl};
    return make_buf(&tmp, m, fl, bytes, init, what);
}

/* A large read-only buffer, filled from init when given. On a CPU device
 * it lives in our own memory (*keep, to free after the buffer is
 * released), allocated with huge pages advised (PoCL's allocations are
 * not, and the dot products' scattered reads then miss the TLB):
 * PERF-NOTES measured 1.5x the read rate with huge pages. */
static hl_result big_buf(hl_context *ctx, struct hl_cl *cl, cl_mem *m, size_t bytes, const void *init, void **keep,
                         const char *what)
{
    hl_cl_pipe tmp = {.ctx = ctx, .cl = cl};
    if (cl->wg != 1 || !bytes) return make_buf(&tmp, m, CL_MEM_READ_ONLY, bytes, init, what);
    *keep = hl_alloc_big(ctx, bytes, what);
    if (!*keep) return HL_ERR_OUT_OF_MEMORY;
    if (init) memcpy(*keep, init, bytes);
    return make_buf(&tmp, m, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR, bytes, *keep, what);
}

static hl_result light_big_buf(hl_cl_light *l, cl_mem *m, size_t bytes, const void *init, void **keep, const char *what)
{
    return big_buf(l->ctx, l->cl, m, bytes, init, keep, what);
}

typedef struct { uint64_t key; uint32_t v; } order_key;

static int order_cmp(const void *a, const void *b)
{
    const order_key *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->v < y->v ? -1 : x->v > y->v;
}

/* 7-bit grid coordinate of x in [lo, hi] (0 for NaN or an empty span) */
static uint32_t grid7(float x, float lo, float hi)
{
    double f = hi > lo ? ((double)x - lo) / ((double)hi - lo) * 128.0 : 0.0;
    if (!(f > 0.0)) return 0;
    return f >= 127.0 ? 127u : (uint32_t)f;
}

/* The order in which the device holds the vertices (l->order: the vertex
 * at each position): object before ground, then along a Z-order curve
 * through position and normal, 7 bits of each of the six coordinates
 * interleaved. Neighbours on that curve see alike and so store alike
 * slots, so a tile's vertices share their columns' entries: on the bunny
 * with ground at M = 200 the kept columns hold a fifth fewer entries than
 * in the file's order (376k against 476k), and 76% of them fill every
 * lane (34% in file order). On a CPU device cut_ranges then deals the
 * curve's tiles to the ranges. The sums are the same in any order. */
static hl_result vertex_order(hl_cl_light *l, const hl_transport *t)
{
    const size_t V = l->nverts;
    const hl_mesh *m = t->mesh;
    l->order = malloc((V ? V : 1) * 4);
    order_key *k = malloc((V ? V : 1) * sizeof *k);
    if (!l->order || !k) {
        free(k);
        return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the vertex order");
    }
    float lo[3] = {0.0f, 0.0f, 0.0f}, hi[3] = {0.0f, 0.0f, 0.0f};
    for (size_t v = 0; m && v < V; v++)
        for (int a = 0; a < 3; a++) {
            float x = m->positions[3 * v + a];
            if (v == 0 || x < lo[a]) lo[a] = x;
            if (v == 0 || x > hi[a]) hi[a] = x;
        }
    for (size_t v = 0; v < V; v++) {
        uint32_t q[6] = {0};
        for (int a = 0; m && a < 3; a++) {
            q[a] = grid7(m->positions[3 * v + a], lo[a], hi[a]);
            q[3 + a] = grid7(m->normals[3 * v + a], -1.0f, 1.0f);
        }
        uint64_t key = v >= t->info.object_vertex_count;
        for (int bit = 6; bit >= 0; bit--)
            for (int a = 0; a < 6; a++) key = key << 1 | ((q[a] >> bit) & 1u);
        k[v].key = key;
        k[v].v = (uint32_t)v;
    }
    qsort(k, V, sizeof *k, order_cmp);
    for (size_t i = 0; i < V; i++) l->order[i] = k[i].v;
    free(k);
    return HL_OK;
}

/* Range boundaries, in whole tiles (HL_TILE positions), into *starts;
 * returns the count, or 0 when out of memory. A range holds at most 65535
 * tiles (a column's entries are numbered 1 to 65535 in 16 bits).
 *
 * On a GPU: 4 tiles (64 vertices) per work-item, in curve order.
 *
 * On a CPU device: one range per core (more where a range would pass
 * 65535 tiles), and the tiles are dealt to the ranges in turn (tile c of
 * the curve to range c mod R), so l->order is rearranged here. Dealt
 * tiles give every range the same mix of the mesh (object and ground,
 * lit and shadowed sides), so each holds about the same share of the
 * kept terms under any lighting, and no core waits for the other. Cutting
 * the curve into R runs of equal stored terms instead gave the ranges
 * 174k and 203k kept entries at M = 200 under city.exr on the bunny with
 * ground (dealt: 188.7k and 188.1k); the dot products last as long as the
 * larger. The tiles themselves are unchanged, so the entry count is too. */
static uint32_t cut_ranges(hl_cl_light *l, uint32_t **starts)
{
    const size_t V = l->nverts, tiles = (V + HL_TILE - 1) / HL_TILE, max_tiles = 65535;
    if (l->cl->wg != 1) {
        const size_t per = 64 / HL_TILE, n = tiles ? (tiles + per - 1) / per : 1;
        uint32_t *rs = malloc((n + 1) * 4);
        if (!rs) return 0;
        for (size_t i = 0; i < n; i++) rs[i] = (uint32_t)(i * per * HL_TILE);
        rs[n] = (uint32_t)(tiles * HL_TILE);
        *starts = rs;
        return (uint32_t)n;
    }
    size_t R = l->cl->units > 1 ? l->cl->units : 1;
    if (R < (tiles + max_tiles - 1) / max_tiles) R = (tiles + max_tiles - 1) / max_tiles; /* dealt: at most 65535 each */
    if (tiles && R > tiles) R = tiles;
    uint32_t *rs = malloc((R + 1) * 4), *o = malloc((V ? V : 1) * 4);
    if (!rs || !o) {
        free(rs);
        free(o);
        return 0;
    }
    /* tile c goes to range (c + shift) mod R: the last tile, which may be
       partial, is then the last tile of the last range */
    const size_t shift = tiles ? (R - 1 - (tiles - 1) % R) : 0;
    size_t n = 0;
    for (size_t r = 0; r < R; r++) {
        rs[r] = (uint32_t)n;
        for (size_t c = (r + R - shift) % R; c < tiles; c += R)
            for (size_t v = c * HL_TILE; v < V && v < (c + 1) * HL_TILE; v++) o[n++] = l->order[v];
    }
    rs[R] = (uint32_t)(tiles * HL_TILE);
    free(l->order);
    l->order = o;
    *starts = rs;
    return (uint32_t)R;
}

/* The rows turned into columns (see kernels/relight/relight.cl): vertices in tiles
 * of HL_TILE, tiles in ranges (one work-item each, cut_ranges); for each
 * range and slot, the tiles that store the slot, in tile order, each as one
 * entry: a head word (the tile in the range) and the HL_TILE terms as
 * halves (half.h; zero in lanes whose vertex does not store the slot),
 * after an all-zero entry 0; and for each range, slot and tile the
 * entry's number in its column (1 for the first, 0 for none), in 16 bits.
 * Also each position's 2^e, which scales its sums back (1 in the
 * padding). */
static hl_result build_columns(hl_cl_light *l, const hl_transport *t)
{
    hl_context *ctx = l->ctx;
    const size_t nc = l->g->ncoef, V = l->nverts, nb = l->g->nblocks;
    TRY(vertex_order(l, t));
    l->nranges = cut_ranges(l, &l->range_start);
    if (!l->nranges) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the transport columns");
    const size_t vpad = V ? l->range_start[l->nranges] : HL_TILE, ncs = (size_t)l->nranges * (nc + 1);
    size_t ts = 1;
    for (size_t rg = 0; rg < l->nranges; rg++) {
        size_t n = (l->range_start[rg + 1] - l->range_start[rg]) / HL_TILE;
        if (n > ts) ts = n;
    }
    l->tstride = (uint32_t)ts;
    const size_t nrel = (size_t)l->nranges * nc * ts;
    uint32_t *cs = calloc(ncs, 4), *fill = malloc(ncs * 4), *last = malloc(nc * 4);
    const size_t stride = 1 + HL_TILE / 2; /* words per entry: head, halves */
    uint32_t *col = NULL;
    uint16_t *rel = hl_alloc_big(ctx, nrel * 2, "the transport columns' tile numbers");
    float *back = malloc(vpad * 4);
    int *ex = malloc((V ? V : 1) * sizeof *ex);
    hl_result r = HL_OK;
    if (!rel) r = HL_ERR_OUT_OF_MEMORY;
    else if (!cs || !fill || !last || !back || !ex)
        r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the transport columns");
    else memset(rel, 0, nrel * 2);
    for (size_t v = 0; v < vpad && r == HL_OK; v++) {
        if (v >= V) { back[v] = 1.0f; continue; } /* padding */
        const hl_row_quant q = t->row_quant[l->order[v]];
        ex[v] = hl_half_exponent(l->scheme, q.a, q.b);
        back[v] = ldexpf(1.0f, ex[v]);
    }
    /* pass 0 counts the tile entries of each (range, slot); pass 1 fills */
    for (int pass = 0; pass < 2 && r == HL_OK; pass++) {
        for (size_t rg = 0; rg < l->nranges; rg++) {
            uint32_t *c = (pass == 0 ? cs : fill) + rg * (nc + 1);
            const uint32_t *c0 = cs + rg * (nc + 1);
            uint16_t *rr = rel + rg * nc * ts;
            memset(last, 0xff, nc * 4);
            const size_t v0 = l->range_start[rg];
            for (size_t v = v0; v < V && v < l->range_start[rg + 1]; v++) {
                uint32_t tile = (uint32_t)((v - v0) / HL_TILE), lane = (uint32_t)(v % HL_TILE);
                const size_t u = l->order[v]; /* the vertex at position v */
                uint64_t e = t->row_offset[u];
                for (size_t b = 0; b < nb; b++)
                    for (uint32_t k = 0; k < t->block_counts[u * nb + b]; k++, e++) {
                        size_t s = b * HL_BLOCK + t->entries[2 * e];
                        int fresh = last[s] != tile;
                        last[s] = tile;
                        if (pass == 0) {
                            c[s + 1] += fresh;
                            continue;
                        }
                        if (fresh) {
                            rr[s * ts + tile] = (uint16_t)(++c[s] - c0[s]); /* at most 65535: cut_ranges */
                            col[(size_t)(c[s] - 1) * stride] = tile;
                        }
                        const hl_row_quant q = t->row_quant[u];
                        float term = hl_dequant(l->scheme, t->entries[2 * e + 1], q.a, q.b,
                                                hl_dither_key((uint32_t)u, (uint32_t)s));
                        ((uint16_t *)(col + (size_t)(c[s] - 1) * stride + 1))[lane] = hl_half_held(term, ex[v]);
                    }
            }
        }
        if (pass == 1) break;
        uint64_t run = 1; /* absolute starts, range after range, after entry 0 */
        for (size_t i = 0; i < ncs; i++) {
            if (i % (nc + 1) == 0) cs[i] = (uint32_t)run;
            else { run += cs[i]; cs[i] = (uint32_t)(run < UINT32_MAX ? run : UINT32_MAX); }
        }
        if (run >= UINT32_MAX) {
            r = hl_fail(ctx, HL_ERR_UNSUPPORTED, "the transport needs %llu column entries; one device holds at most 2^32",
                        (unsigned long long)run);
            break;
        }
        l->col_entries = run - 1;
        memcpy(fill, cs, ncs * 4);
        col = hl_alloc_big(ctx, (size_t)run * stride * 4, "transport columns");
        if (!col) r = HL_ERR_OUT_OF_MEMORY;
        else memset(col, 0, (size_t)run * stride * 4);
    }
    if (r == HL_OK)
        r = light_big_buf(l, &l->col, (l->col_entries + 1) * stride * 4, col, &l->host[0], "transport columns");
    if (r == HL_OK) r = light_big_buf(l, &l->cols, ncs * 4, cs, &l->host[1], "column starts");
    if (r == HL_OK) r = light_big_buf(l, &l->rel, nrel * 2, rel, &l->host[3], "the columns' tile numbers");
    if (r == HL_OK) r = light_buf(l, &l->rstart, CL_MEM_READ_ONLY, ((size_t)l->nranges + 1) * 4, l->range_start, "ranges");
    if (r == HL_OK) r = light_big_buf(l, &l->back, vpad * 4, back, &l->host[2], "the sums' scales");
    l->col_start = cs;
    free(fill);
    free(last);
    free(back);
    free(ex);
    hl_free_big(col);
    hl_free_big(rel);
    return r;
}

hl_result hl_cl_light_create(hl_context *ctx, const hl_geom *g, const hl_light_geom *lg, const hl_transport *t,
                             const float *albedo4, hl_cl_light **out)
{
    *out = NULL;
    if (!ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    hl_cl_light *l = calloc(1, sizeof *l);
    if (!l) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    l->ctx = ctx;
    l->cl = ctx->cl;
    l->g = g;
    l->lg = lg;
    l->nverts = t->info.vertex_count;
    l->scheme = t->info.quant;
    size_t nc = g->ncoef, V = l->nverts, cells = (size_t)lg->wc * lg->hc;
    hl_result r = HL_OK;
#define B(m, fl, bytes, init, what) if (r == HL_OK) r = light_buf(l, &l->m, fl, bytes, init, what)
    B(cells, CL_MEM_READ_ONLY, cells * 16, NULL, "environment cells");
    B(turned, CL_MEM_READ_WRITE, cells * 16, NULL, "environment cells");
    B(start, CL_MEM_READ_ONLY, (nc + 1) * 4, lg->tap_start, "environment runs");
    /* the taps as (cell index, weight bits): 8 bytes each */
    uint32_t *taps2 = malloc(((size_t)lg->ntaps + 1) * 8);
    if (!taps2) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the environment runs");
    for (size_t e = 0; taps2 && e < lg->ntaps; e++) {
        taps2[2 * e] = lg->taps[e].row * lg->wc + lg->taps[e].col;
        memcpy(&taps2[2 * e + 1], &lg->taps[e].weight, 4);
    }
    B(runs, CL_MEM_READ_ONLY, ((size_t)lg->ntaps + 1) * 8, taps2, "environment runs");
    free(taps2);
    B(slots, CL_MEM_READ_ONLY, (size_t)g->N * g->N * 4, g->slot_of_mallat, "the Haar slot order");
    B(weight, CL_MEM_READ_ONLY, nc * 4, lg->area, "selection weights");
    B(Lp, CL_MEM_READ_WRITE, 3 * nc * 4, NULL, "paraboloid lighting");
    B(Lw, CL_MEM_READ_WRITE, 3 * nc * 4, NULL, "wavelet lighting");
    B(Lsel, CL_MEM_READ_WRITE, nc * 16, NULL, "selected lighting");
    B(used, CL_MEM_READ_WRITE, g->nblocks, NULL, "block flags");
    B(bits, CL_MEM_READ_WRITE, nc / 8, NULL, "kept-slot bits");
    B(res, CL_MEM_READ_WRITE, sizeof(hl_select_result), NULL, "selection result");
    B(keys, CL_MEM_READ_WRITE, nc * 4, NULL, "selection keys");
    B(klist, CL_MEM_READ_WRITE, (nc + 1) * 4, NULL, "kept slots");
    if (r == HL_OK) r = build_columns(l, t);
    /* albedo in the device's vertex order */
    float *alb = r == HL_OK ? malloc((V ? V : 1) * 16) : NULL;
    if (r == HL_OK && !alb) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the albedo");
    for (size_t i = 0; alb && i < V; i++) memcpy(alb + 4 * i, albedo4 + 4 * (size_t)l->order[i], 16);
    B(albedo, CL_MEM_READ_ONLY, V * 16, alb, "albedo");
    free(alb);
    B(ord, CL_MEM_READ_ONLY, V * 4, l->order, "vertex order");
    B(B, CL_MEM_READ_WRITE, V * 16, NULL, "vertex colours");
    B(acc, CL_MEM_READ_WRITE, (size_t)3 * (l->nranges && V ? l->range_start[l->nranges] : 1) * 4, NULL, "running sums");
#undef B
    if (r != HL_OK) { hl_cl_light_destroy(l); return r; }
    *out = l;
    return HL_OK;
}

#define LWRITE(buf, bytes, src) \
    CL_TRY(l->ctx, clEnqueueWriteBuffer(l->cl->queue, buf, CL_TRUE, 0, bytes, src, 0, NULL, NULL), "upload")
#define LREAD(buf, bytes, dst, blocking) \
    CL_TRY(l->ctx, clEnqueueReadBuffer(l->cl->queue, buf, blocking, 0, bytes, dst, 0, NULL, NULL), "read-back")
#define LARG(k, i, v) CL_TRY(l->ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")

hl_result hl_cl_light_set_cells(hl_cl_light *l, const float *cells4)
{
    LWRITE(l->cells, (size_t)l->lg->wc * l->lg->hc * 16, cells4);
    return HL_OK;
}

hl_result hl_cl_light_set_weights(hl_cl_light *l, const float *weight)
{
    LWRITE(l->weight, (size_t)l->g->ncoef * 4, weight);
    return HL_OK;
}

static hl_result light_launch(hl_cl_light *l, int which, size_t items)
{
    /* selection is one work-item */
    size_t local = which == K_SELECT ? 1 : l->cl->wg;
    size_t global = (items + local - 1) / local * local;
    CL_TRY(l->ctx, clEnqueueNDRangeKernel(l->cl->queue, l->cl->k[which], 1, NULL, &global, &local, 0, NULL, NULL),
           kernel_names[which]);
    return HL_OK;
}

static hl_result enq_env2para(hl_cl_light *l, uint32_t s0, float f)
{
    /* CPU: 64 chunks of consecutive cells or texels; a GPU: one each per
       work-item */
    cl_kernel k = l->cl->k[K_TURN];
    cl_uint wc = l->lg->wc, ncell = l->lg->wc * l->lg->hc, nc = l->g->ncoef, sh = s0;
    cl_uint per = l->cl->wg == 1 ? (ncell + 63) / 64 : 1;
    LARG(k, 0, l->cells); LARG(k, 1, wc); LARG(k, 2, ncell); LARG(k, 3, sh); LARG(k, 4, f); LARG(k, 5, per);
    LARG(k, 6, l->turned);
    TRY(light_launch(l, K_TURN, (ncell + per - 1) / per));
    k = l->cl->k[K_ENV2PARA];
    per = l->cl->wg == 1 ? (nc + 63) / 64 : 1;
    LARG(k, 0, l->turned); LARG(k, 1, l->start); LARG(k, 2, l->runs); LARG(k, 3, nc); LARG(k, 4, per);
    LARG(k, 5, l->Lp);
    return light_launch(l, K_ENV2PARA, (nc + per - 1) / per);
}

static hl_result enq_haar3(hl_cl_light *l)
{
    cl_kernel k = l->cl->k[K_HAAR];
    cl_uint N = l->g->N, rows = 3;
    LARG(k, 0, l->Lp); LARG(k, 1, l->Lw); LARG(k, 2, l->slots); LARG(k, 3, N); LARG(k, 4, rows);
    return light_launch(l, K_HAAR, 3);
}

static hl_result enq_select(hl_cl_light *l, hl_select_params sp)
{
    cl_kernel k = l->cl->k[K_SELECT];
    cl_uint nc = l->g->ncoef, nb = l->g->nblocks;
    LARG(k, 0, l->Lw); LARG(k, 1, nc); LARG(k, 2, l->weight); LARG(k, 3, sp); LARG(k, 4, l->Lsel);
    LARG(k, 5, l->used); LARG(k, 6, l->bits); LARG(k, 7, nb); LARG(k, 8, l->res); LARG(k, 9, l->keys);
    LARG(k, 10, l->klist);
    return light_launch(l, K_SELECT, 1);
}

static hl_result enq_relight_to(hl_cl_light *l, cl_mem out)
{
    cl_kernel k = l->cl->k[K_RELIGHT];
    cl_uint nc = l->g->ncoef, nv = l->nverts, nr = l->nranges, ts = l->tstride;
    LARG(k, 0, l->col); LARG(k, 1, l->cols); LARG(k, 2, l->rel); LARG(k, 3, ts); LARG(k, 4, l->rstart);
    LARG(k, 5, l->back); LARG(k, 6, nc); LARG(k, 7, l->Lsel); LARG(k, 8, l->klist); LARG(k, 9, l->albedo);
    LARG(k, 10, l->acc); LARG(k, 11, out); LARG(k, 12, nv); LARG(k, 13, nr); LARG(k, 14, l->ord);
    LARG(k, 15, l->keep_negative);
    return light_launch(l, K_RELIGHT, l->nranges);
}

void hl_cl_light_keep_negative(hl_cl_light *l, int keep) { l->keep_negative = keep ? 1u : 0u; }

static hl_result enq_relight(hl_cl_light *l) { return enq_relight_to(l, l->B); }

/* The lighting stages up to the kept terms: env2para, Haar, selection. */
static hl_result enq_lighting(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp)
{
    TRY(enq_env2para(l, s0, f));
    TRY(enq_haar3(l));
    return enq_select(l, sp);
}

hl_result hl_cl_light_run(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp, float *B4, hl_select_result *res)
{
    /* one submission, one wait: launches cost ~50 us each to finish */
    TRY(enq_lighting(l, s0, f, sp));
    TRY(enq_relight(l));
    LREAD(l->res, sizeof *res, res, CL_FALSE);
    LREAD(l->B, (size_t)l->nverts * 16, B4, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_run_into(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp, void *out, int gl,
                               hl_select_result *res)
{
    cl_mem m = (cl_mem)out;
    size_t have = 0, need = (size_t)l->nverts * 16;
    CL_TRY(l->ctx, clGetMemObjectInfo(m, CL_MEM_SIZE, sizeof have, &have, NULL), "the colour buffer");
    if (have < need)
        return hl_fail(l->ctx, HL_ERR_INVALID_ARGUMENT, "the colour buffer holds %zu bytes; %u vertices need %zu", have,
                       l->nverts, need);
    TRY(enq_lighting(l, s0, f, sp));
    if (gl) CL_TRY(l->ctx, clEnqueueAcquireGLObjects(l->cl->queue, 1, &m, 0, NULL, NULL), "clEnqueueAcquireGLObjects");
    hl_result r = enq_relight_to(l, m);
    if (gl) {
        cl_int e = clEnqueueReleaseGLObjects(l->cl->queue, 1, &m, 0, NULL, NULL);
        if (r == HL_OK && e != CL_SUCCESS)
            r = hl_fail(l->ctx, HL_ERR_OPENCL, "OpenCL: clEnqueueReleaseGLObjects failed (%s)", cl_err_name(e));
    }
    /* the blocking read of the result also waits for the release: OpenGL
       may draw from the buffer once this returns */
    if (r == HL_OK) LREAD(l->res, sizeof *res, res, CL_TRUE);
    else clFinish(l->cl->queue);
    return r;
}

hl_result hl_cl_gl_buffer(hl_context *ctx, unsigned gl_buffer, void **out)
{
    *out = NULL;
    if (!ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    cl_int e;
    cl_mem m = clCreateFromGLBuffer(ctx->cl->context, CL_MEM_WRITE_ONLY, (cl_GLuint)gl_buffer, &e);
    CL_TRY(ctx, e, "clCreateFromGLBuffer");
    *out = m;
    return HL_OK;
}

void hl_cl_glx_properties(void *glx_context, void *x_display, intptr_t props[5])
{
    props[0] = CL_GL_CONTEXT_KHR;
    props[1] = (intptr_t)glx_context;
    props[2] = CL_GLX_DISPLAY_KHR;
    props[3] = (intptr_t)x_display;
    props[4] = 0;
}

hl_result hl_cl_buffer(hl_context *ctx, size_t bytes, void **out)
{
    *out = NULL;
    if (!ctx->cl) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "the context has no OpenCL device");
    hl_cl_pipe tmp = {.ctx = ctx, .cl = ctx->cl};
    cl_mem m = NULL;
    hl_result r = make_buf(&tmp, &m, CL_MEM_READ_WRITE, bytes, NULL, "the colour buffer");
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
    if (ctx->cl) release_buf(ctx->cl, &m);
}

void hl_cl_mem_release(void *mem)
{
    if (mem) clReleaseMemObject((cl_mem)mem);
}

hl_result hl_cl_light_stage_env2para(hl_cl_light *l, uint32_t s0, float f, float *Lp)
{
    TRY(enq_env2para(l, s0, f));
    LREAD(l->Lp, (size_t)3 * l->g->ncoef * 4, Lp, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_haar(hl_cl_light *l, const float *Lp, float *Lw)
{
    LWRITE(l->Lp, (size_t)3 * l->g->ncoef * 4, Lp);
    TRY(enq_haar3(l));
    LREAD(l->Lw, (size_t)3 * l->g->ncoef * 4, Lw, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_select(hl_cl_light *l, const float *Lw, hl_select_params sp, float *Lsel4,
                                   uint8_t *used, uint32_t *bits, hl_select_result *res)
{
    LWRITE(l->Lw, (size_t)3 * l->g->ncoef * 4, Lw);
    TRY(enq_select(l, sp));
    LREAD(l->Lsel, (size_t)l->g->ncoef * 16, Lsel4, CL_TRUE);
    LREAD(l->used, l->g->nblocks, used, CL_TRUE);
    LREAD(l->bits, l->g->ncoef / 8, bits, CL_TRUE);
    LREAD(l->res, sizeof *res, res, CL_TRUE);
    return HL_OK;
}

hl_result hl_cl_light_stage_relight(hl_cl_light *l, const float *Lsel4, const uint32_t *bits, float *B4)
{
    const size_t nc = l->g->ncoef;
    uint32_t *list = malloc((nc + 1) * 4); /* as hl_select writes it */
    if (!list) return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    list[0] = 0;
    for (size_t s = 0; s < nc; s++)
        if ((bits[s / 32] >> (s % 32)) & 1u) list[++list[0]] = (uint32_t)s;
    cl_int e = clEnqueueWriteBuffer(l->cl->queue, l->klist, CL_TRUE, 0, (nc + 1) * 4, list, 0, NULL, NULL);
    free(list);
    CL_TRY(l->ctx, e, "upload");
    LWRITE(l->Lsel, nc * 16, Lsel4);
    LWRITE(l->bits, nc / 8, bits);
    TRY(enq_relight(l));
    LREAD(l->B, (size_t)l->nverts * 16, B4, CL_TRUE);
    return HL_OK;
}

/* ------------------------------------------------------------ measuring */

uint32_t hl_cl_light_ranges(const hl_cl_light *l) { return l->nranges; }

double hl_cl_light_kept_entries(const hl_cl_light *l, const uint32_t *bits, double *per_range)
{
    const size_t nc = l->g->ncoef;
    double kept = 0.0;
    for (size_t rg = 0; rg < l->nranges; rg++) per_range[rg] = 0.0;
    for (size_t s = 0; s < nc; s++) {
        if (!((bits[s / 32] >> (s % 32)) & 1u)) continue;
        kept += 1.0;
        for (size_t rg = 0; rg < l->nranges; rg++) {
            const uint32_t *c = l->col_start + rg * (nc + 1);
            per_range[rg] += (double)(c[s + 1] - c[s]);
        }
    }
    return kept;
}

int hl_cl_light_tile_walk(const hl_cl_light *l, uint32_t rg, double entries, uint32_t kept)
{
    const uint32_t nt = (l->range_start[rg + 1] - l->range_start[rg]) / HL_TILE;
    return hl_tile_walk_pays((uint64_t)entries, kept, nt);
}

hl_result hl_cl_light_bytes_read(hl_cl_light *l, double *bytes)
{
    const size_t nc = l->g->ncoef;
    uint32_t *bits = malloc(nc / 8);
    double *per = malloc((l->nranges ? l->nranges : 1) * sizeof *per);
    if (!bits || !per) {
        free(bits);
        free(per);
        return hl_fail(l->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    }
    cl_int e = clEnqueueReadBuffer(l->cl->queue, l->bits, CL_TRUE, 0, nc / 8, bits, 0, NULL, NULL);
    if (e != CL_SUCCESS) {
        free(bits);
        free(per);
        CL_TRY(l->ctx, e, "read-back");
    }
    const double kept = hl_cl_light_kept_entries(l, bits, per);
    free(bits);
    /* per kept slot its place in the list and, per range, its column's
       start and end; per vertex slot its scale; per vertex its albedo,
       place and colour. Then per range, by its walk (hl_tile_walk_pays):
       the column walk reads each kept entry's head word and halves, and
       its sums (zeroed, then read once they leave the cache); the tile
       walk reads the halves and, per kept slot and tile, an entry number,
       while its sums and entry 0 stay in the cache. */
    double b = kept * (4.0 + (double)l->nranges * 8.0) + (double)l->range_start[l->nranges] * 4.0 +
               (double)l->nverts * 36.0;
    for (size_t rg = 0; rg < l->nranges; rg++) {
        const uint32_t n = l->range_start[rg + 1] - l->range_start[rg], nt = n / HL_TILE;
        if (hl_cl_light_tile_walk(l, (uint32_t)rg, per[rg], (uint32_t)kept))
            b += per[rg] * 2.0 * HL_TILE + kept * nt * 2.0;
        else
            b += per[rg] * (4.0 + 2.0 * HL_TILE) + n * 24.0;
    }
    free(per);
    *bytes = b;
    return HL_OK;
}

hl_result hl_cl_light_time_relight(hl_cl_light *l, uint32_t reps, double *seconds)
{
    /* the kernel alone, several launches in one submission */
    TRY(enq_relight(l));
    CL_TRY(l->ctx, clFinish(l->cl->queue), "clFinish");
    double t0 = hl_now();
    for (uint32_t i = 0; i < reps; i++) TRY(enq_relight(l));
    CL_TRY(l->ctx, clFinish(l->cl->queue), "clFinish");
    *seconds = (hl_now() - t0) / (reps ? reps : 1);
    return HL_OK;
}

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
    hl_result res = big_buf(ctx, cl, &buf, items * per * 64, NULL, &host, "the bandwidth buffer");
    if (res != HL_OK) {
        hl_free_big(host);
        return res;
    }
    cl_mem out = NULL;
    hl_cl_pipe tmp = {.ctx = ctx, .cl = cl};
    res = make_buf(&tmp, &out, CL_MEM_WRITE_ONLY, items * 4, NULL, "the bandwidth sums");
    if (res != HL_OK) {
        release_buf(cl, &buf);
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
    release_buf(cl, &buf);
    release_buf(cl, &out);
    hl_free_big(host); /* PoCL is done with it once the buffer is released */
    CL_TRY(ctx, e, "the bandwidth kernel");
    /* median */
    for (uint32_t i = 1; i < reps; i++)
        for (uint32_t j = i; j > 0 && best[j - 1] > best[j]; j--) { double x = best[j]; best[j] = best[j - 1]; best[j - 1] = x; }
    *bytes_per_s = (double)(items * per * 64) / best[reps / 2];
    return HL_OK;
}
