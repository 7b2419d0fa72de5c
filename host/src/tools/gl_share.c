/* gl_share.c - the viewer's way to the relighter's colours: left in the
 * relighter (4 floats per vertex, the GL buffer's layout), or written by
 * the dot products straight into an OpenGL buffer (cl_khr_gl_sharing).
 *
 * Depends on the OpenCL backend (cl_backend.h) and the relighter's
 * internals (lighting.h).
 */
#include <stdlib.h>

#include "cl_backend.h"
#include "haarlight_tools.h"
#include "lighting.h"

/* The OpenCL buffer over the GL buffer object. */
struct hl_gl_colours {
    void *mem;
};

hl_result hl_view_run4(hl_relighter *r, const hl_relight_desc *desc, const float **rgba, hl_relight_stats *stats)
{
    return hl_relighter_run4(r, desc, rgba, stats);
}

void hl_view_glx_properties(void *glx_context, void *x_display, intptr_t props[5])
{
    hl_cl_glx_properties(glx_context, x_display, props);
}

hl_result hl_view_gl_colours_create(hl_context *ctx, unsigned gl_buffer, hl_gl_colours **out)
{
    *out = NULL;
    hl_gl_colours *c = hl_malloc(ctx, sizeof *c, "the GL colour buffer's handle");
    if (!c) return HL_ERR_OUT_OF_MEMORY;
    hl_result r = hl_cl_gl_buffer(ctx, gl_buffer, &c->mem);
    if (r != HL_OK) {
        free(c);
        return r;
    }
    *out = c;
    return HL_OK;
}

void hl_view_gl_colours_destroy(hl_gl_colours *c)
{
    if (!c) return;
    hl_cl_mem_release(c->mem);
    free(c);
}

hl_result hl_view_run_gl(hl_relighter *r, const hl_relight_desc *desc, hl_gl_colours *c, hl_relight_stats *stats)
{
    return hl_relighter_run_into(r, desc, c->mem, 1, stats);
}
