/* tools_common.c - the small services of haarlight_tools.h that every
 * tool uses: failures recorded on a context, the clock, luminance, and the
 * transport report of `haarlight info`, a mesh load that says what of
 * the file's motion it leaves behind.
 *
 * Depends on the core (hl_internal.h) and the transport file module
 * (transport_file.h).
 */
#include <stdarg.h>
#include <stdio.h>

#include "haarlight_tools.h"
#include "hl_internal.h"
#include "transport_file.h"

hl_result hl_tools_fail(hl_context *ctx, hl_result code, const char *fmt, ...)
{
    char msg[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return hl_fail(ctx, code, "%s", msg);
}

double hl_tools_now(void) { return hl_now(); }

float hl_tools_luminance(float r, float g, float b) { return hl_luminance(r, g, b); }

void hl_tools_transport_report(const hl_transport *t, const char *path, void *file)
{
    hl_transport_describe(t, path, (FILE *)file);
}

hl_result hl_tools_mesh_load(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, hl_mesh **out,
                             hl_mesh_stats *stats, uint32_t motion[3])
{
    hl_mesh_motion m;
    hl_result r = hl_mesh_load_motion_(ctx, path, desc, out, stats, &m);
    motion[0] = m.animations;
    motion[1] = m.skinned;
    motion[2] = m.morphing;
    return r;
}
