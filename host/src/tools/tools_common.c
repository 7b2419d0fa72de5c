/* tools_common.c - the small services of haarlight_tools.h that every
 * tool uses: failures recorded on a context, the clock, luminance, and the
 * transport report of `haarlight info`.
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
