/* cl_internal.h - the OpenCL side of the library, private to the files that
 * talk to the device: the struct hl_cl a context holds, the kernel handles,
 * the error macro and the counted buffers.
 *
 * Included only by the .c files that call OpenCL (device/cl_*.c,
 * device/context_open.c, precompute/cl_pipe.c, relight/cl_*.c); everything
 * else sees OpenCL through cl_backend.h, whose functions take host arrays
 * and opaque handles. Depends on: CL/cl.h, hl_internal.h (core).
 */
#ifndef HL_CL_INTERNAL_H
#define HL_CL_INTERNAL_H

#ifndef CL_TARGET_OPENCL_VERSION
#define CL_TARGET_OPENCL_VERSION 120
/* OpenGL buffers (cl_gl.c): enqueues taking m (from hl_cl_gl_buffer) from
 * OpenGL, and giving it back (the error code, for the caller's message). */
hl_result hl_cl_gl_acquire(hl_context *ctx, cl_mem m);
cl_int hl_cl_gl_release(struct hl_cl *cl, cl_mem m);

#endif
#include <CL/cl.h>

#include "cl_backend.h"
#include "hl_internal.h"

/* The program's kernels, in the order of hl_cl_kernel_names. */
enum { K_CUBE2PARA, K_HAAR, K_TRUNCATE, K_QUANTIZE, K_TURN, K_ENV2PARA, K_SELECT, K_RELIGHT, K_BANDWIDTH,
       K_SH_PROJECT, K_CUBE_ROWS, K_CUBE_HAAR, K_RELIGHT_ROWS,
       /* the GPU shape's own (cl->gpu_shape) */
       K_SELECT_GROUP, K_HAAR_GROUP, K_RELIGHT_ITEMS, K_BANDWIDTH_GRID, K_COUNT };
extern const char *const hl_cl_kernel_names[K_COUNT];

/* rows per work-item of hl_cube2para (HL_C2P_ROWS in kernels/maps/cube2para.cl) */
#define C2P_ROWS 4u

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
       device; used counts the buffers made through hl_cl_make_buf. */
    cl_ulong limit, used;
    int limit_set; /* the limit came from the caller, not the device */
    /* The shape of the launches (docs/DEVICES.md):
       chosen from the device's type, or forced (HL_DEVICE_SHAPE), so that
       PoCL runs the GPU shape's kernels in the tests too.
       CPU shape: each work-item walks its own long chunk (a row, a range
       of tiles), work-groups of 1, since PoCL would otherwise put every
       chunk of a group on one core. GPU shape: a work-item a vertex,
       texel or slot, work-groups of wg, whole stages in one group where
       they need barriers. */
    int gpu_shape;
    size_t wg;      /* work-group size: 1 in the CPU shape */
    size_t max_wg;  /* the device's largest work-group */
    cl_ulong local_mem; /* the device's local memory a group, bytes */
    /* the GPU shape's work-groups for the stages that run as groups (each
       a power of two, within what the device and the kernel allow):
       Haar of the lighting, the dot products; the selection runs as one
       group of HL_SELECT_LANES where select_group is set, else as
       select.cl's one work-item */
    size_t haar_wg, items_wg;
    int select_group;
    int host_memory; /* the device computes in host memory (a CPU device):
                        buffers may use our own pages in place */
    cl_uint units; /* compute units (cores on a CPU device) */
};

/* Enqueues kernel k over n work-items in groups of local, or (local 0)
 * of the shape's size, 64 in the CPU shape too: never a size left to the
 * runtime. Given none, PoCL picks one that divides n and compiles the
 * kernel anew for each size it has not seen, and n follows the mesh (a new
 * mesh's first dynamic frame spent 5 to 20 s compiling). n is rounded up
 * to whole groups: the kernel returns past its count. */
hl_result hl_cl_launch(hl_context *ctx, cl_kernel k, size_t n, size_t local, const char *what);

/* The name of an OpenCL error code, for messages. */
const char *hl_cl_err_name(cl_int e);

/* Builds the program from the embedded (or on-disk) kernels and makes the
 * kernel handles (cl_program.c). */
hl_result hl_cl_build_program(hl_context *ctx, struct hl_cl *cl);

/* Out of device memory or resources: a smaller precompute chunk may fit;
 * any other failure: only the reference backend is sure to help. */
#define CL_TRY(ctx, call, what)                                                            \
    do {                                                                                   \
        cl_int e_ = (call);                                                                \
        if (e_ != CL_SUCCESS) {                                                            \
            int mem_ = e_ == CL_MEM_OBJECT_ALLOCATION_FAILURE || e_ == CL_OUT_OF_RESOURCES; \
            return hl_fail((ctx), mem_ ? HL_ERR_OUT_OF_MEMORY : HL_ERR_OPENCL, "OpenCL: %s failed: %s (%d); %s", \
                           what, hl_cl_err_name(e_), (int)e_,                              \
                           mem_ ? "try a smaller --chunk (precompute) or --device ref" : "try --device ref"); \
        }                                                                                  \
    } while (0)

#define TRY(x) do { hl_result r_ = (x); if (r_ != HL_OK) return r_; } while (0)

/* The projection matrix of hl_sh_project_rows (hl_sh_matrix's: ncoef x
 * stride floats, count = order^2 <= stride, stride a multiple of 4) in a
 * new buffer *m, replacing any there (precompute/cl_pipe.c). */
hl_result hl_cl_sh_upload(hl_context *ctx, struct hl_cl *cl, uint32_t ncoef, const float *Y, uint32_t stride,
                          uint32_t count, cl_mem *m);
/* hl_sh_project_rows on rows of in (ncoef floats each) into out, its
 * slots from count on zeroed first (precompute/cl_pipe.c; the relight's
 * lighting uses it too). */
hl_result hl_cl_sh_project_enqueue(hl_context *ctx, struct hl_cl *cl, cl_mem in, cl_uint ncoef, cl_mem Y, cl_uint stride,
                                   cl_uint count, cl_mem out, cl_uint rows);

/* hl_cube_face_haar on rows of in (in_stride floats each, destroyed) into
 * out (out_stride floats each, the slots from 6 Cq^2 on zeroed)
 * (precompute/cl_pipe.c; the relight's cube lighting uses it too). */
hl_result hl_cl_cube_haar_enqueue(hl_context *ctx, struct hl_cl *cl, cl_mem in, cl_uint in_stride, cl_mem out,
                                  cl_uint out_stride, cl_uint Cq, cl_uint rows);

/* Buffers (cl_buffers.c). Allocates a buffer of ctx's device counted
 * against the context's device memory limit; init, when given, is copied
 * (or used, with CL_MEM_USE_HOST_PTR). */
hl_result hl_cl_make_buf(hl_context *ctx, cl_mem *m, cl_mem_flags fl, size_t bytes, const void *init,
                         const char *what);
/* Releases a buffer made by hl_cl_make_buf and gives its bytes back. */
void hl_cl_release_buf(struct hl_cl *cl, cl_mem *m);
/* A large read-only buffer, filled from init when given. On a CPU device
 * it lives in our own memory (*keep, to free with hl_free_big after the
 * buffer is released), allocated with huge pages advised. */
hl_result hl_cl_big_buf(hl_context *ctx, cl_mem *m, size_t bytes, const void *init, void **keep, const char *what);
/* The same over memory the caller already filled (*host, from
 * hl_alloc_big), so that the bytes are never held twice: on a CPU device
 * the buffer uses *host in place (free it with hl_free_big after the
 * buffer is released); elsewhere they are copied to the device and *host
 * is freed and set to NULL, whether or not the buffer was made. */
hl_result hl_cl_adopt_buf(hl_context *ctx, cl_mem *m, size_t bytes, void **host, const char *what);

/* OpenGL buffers (cl_gl.c): enqueues taking m (from hl_cl_gl_buffer) from
 * OpenGL, and giving it back (the error code, for the caller's message). */
hl_result hl_cl_gl_acquire(hl_context *ctx, cl_mem m);
cl_int hl_cl_gl_release(struct hl_cl *cl, cl_mem m);

#endif
