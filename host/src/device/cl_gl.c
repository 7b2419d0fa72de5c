/* cl_gl.c - sharing buffers with OpenGL: the context properties that tie
 * an OpenCL context to a GLX context, device handles over GL buffer
 * objects (the viewer's colour buffer, written by the dot products), and
 * taking such a buffer from OpenGL and giving it back around a launch.
 *
 * Depends on: cl_internal.h and CL/cl_gl.h (OpenCL).
 */
#include "cl_internal.h"
#include <CL/cl_gl.h>

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

void hl_cl_mem_release(void *mem)
{
    if (mem) clReleaseMemObject((cl_mem)mem);
}

hl_result hl_cl_gl_acquire(hl_context *ctx, cl_mem m)
{
    CL_TRY(ctx, clEnqueueAcquireGLObjects(ctx->cl->queue, 1, &m, 0, NULL, NULL), "clEnqueueAcquireGLObjects");
    return HL_OK;
}

cl_int hl_cl_gl_release(struct hl_cl *cl, cl_mem m) { return clEnqueueReleaseGLObjects(cl->queue, 1, &m, 0, NULL, NULL); }
