/* cl_program.c - the OpenCL program: its source and build, and the kernel
 * handles a context keeps.
 *
 * Kernels come from the binary (host/embed_kernels.cmake) or, when the
 * context names a kernel folder, from the kernels folder on disk. hl_shared.h is
 * prepended to the program so both sides share one layout.
 * Depends on: cl_internal.h (OpenCL), the embedded kernel table.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"

typedef struct { const char *name; const char *source; } hl_embedded_kernel;
extern const char *const hl_embedded_shared;
extern const hl_embedded_kernel hl_embedded_kernels[];

const char *const hl_cl_kernel_names[K_COUNT] = {"hl_cube2para", "hl_haar",   "hl_truncate", "hl_quantize", "hl_turn",
                                                 "hl_env2para",  "hl_select", "hl_relight",  "hl_read_bandwidth",
                                                 "hl_sh_project_rows", "hl_cube_face_rows", "hl_cube_face_haar",
                                                 "hl_relight_rows", "hl_select_group", "hl_haar_group",
                                                 "hl_relight_items", "hl_read_bandwidth_grid"};

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
            snprintf(path, sizeof path, "%s/../host/src/core/hl_shared.h", ctx->kernel_dir);
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

hl_result hl_cl_build_program(hl_context *ctx, struct hl_cl *cl)
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
    /* tests: the tile walk's passes made short (HL_TEST_SUM_TILES tiles,
       kernels/relight/relight.cl), so that a small mesh takes several */
    const char *pass = getenv("HL_TEST_SUM_TILES");
    const unsigned long tiles = pass ? strtoul(pass, NULL, 10) : 0;
    if (tiles > 0) snprintf(opts + strlen(opts), sizeof opts - strlen(opts), " -DHL_SUM_TILES=%lu", tiles);
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
                hl_cl_err_name(e), (int)e, log ? log : "(no log)");
        free(log);
        return HL_ERR_OPENCL;
    }
    for (int i = 0; i < K_COUNT; i++) {
        cl->k[i] = clCreateKernel(cl->program, hl_cl_kernel_names[i], &e);
        CL_TRY(ctx, e, hl_cl_kernel_names[i]);
    }
    return HL_OK;
}
