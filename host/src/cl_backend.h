/* cl_backend.h - the library's only view of OpenCL (cl_backend.c includes
 * the OpenCL headers; nothing else does).
 *
 * hl_cl owns the platform, device, queue, program and kernels of a context.
 * Stage runners take host arrays and return host arrays, so callers never
 * see cl_mem. Errors carry the cl_int name and, for builds, the build log.
 */
#ifndef HL_CL_BACKEND_H
#define HL_CL_BACKEND_H

#include "hl_internal.h"

struct hl_geom;

hl_result hl_cl_create(hl_context *ctx, int platform, int device);
void hl_cl_destroy(struct hl_cl *cl);

#endif
