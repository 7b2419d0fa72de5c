/* tools_common.c - the small services of haarlight_tools.h that every
 * tool uses: failures recorded on a context, the clock, luminance, and the
 * transport report of `haarlight info`, a mesh load that says what of
 * the file's motion it leaves behind.
 *
 * Depends on the core (hl_internal.h) and the transport file module
 * (transport_file.h).
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "haarlight_tools.h"
#include "hl_internal.h"
#include "transport_file.h"
#include "../dynamic/dynamic.h"
#include "../dynamic/scene.h"

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

hl_result hl_tools_mesh_load_at(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, double t,
                                hl_mesh **out, char *anim, size_t anim_size)
{
    *out = NULL;
    if (!(t >= 0.0) || !isfinite(t)) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: time %g: expected >= 0", path, t);
    hl_dyn_scene_desc sd;
    memset(&sd, 0, sizeof sd);
    if (desc) sd.mesh = *desc;
    hl_dyn_scene *s = NULL;
    hl_result r = hl_dyn_scene_load_desc(ctx, path, &sd, &s);
    if (r != HL_OK) return r;
    double t0 = 0.0, t1 = 0.0;
    const char *name = hl_dyn_scene_animation(s, &t0, &t1);
    if (!name) {
        hl_dyn_scene_destroy(s);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: --time: the file has no animation to pose", path);
    }
    snprintf(anim, anim_size, "%s", name);
    uint32_t nb = hl_dyn_scene_body_count(s);
    hl_dyn_object *ob = hl_calloc(ctx, nb, sizeof *ob, "the bodies");
    r = ob ? hl_dyn_scene_at(s, t, ob) : HL_ERR_OUT_OF_MEMORY;
    uint64_t nv = 0, nt = 0;
    for (uint32_t b = 0; r == HL_OK && b < nb; b++) nv += ob[b].nverts, nt += ob[b].ntris;
    if (r == HL_OK && (nv > UINT32_MAX || nt > UINT32_MAX))
        r = hl_fail(ctx, HL_ERR_MESH, "%s: %llu vertices and %llu triangles exceed the 2^32 limit", path,
                    (unsigned long long)nv, (unsigned long long)nt);
    float *pos = NULL, *nrm = NULL, *alb = NULL;
    uint32_t *idx = NULL;
    if (r == HL_OK) {
        pos = hl_malloc(ctx, (size_t)nv * 12, "posed positions");
        nrm = hl_malloc(ctx, (size_t)nv * 12, "posed normals");
        alb = hl_malloc(ctx, (size_t)nv * 12, "posed albedo");
        idx = hl_malloc(ctx, (size_t)nt * 12, "posed triangles");
        if (!pos || !nrm || !alb || !idx) r = HL_ERR_OUT_OF_MEMORY;
    }
    size_t v0 = 0, t0i = 0;
    for (uint32_t b = 0; r == HL_OK && b < nb; b++) {
        const hl_dyn_object *o = &ob[b];
        const float *x = o->xf; /* rows [R | t] */
        for (uint32_t v = 0; v < o->nverts; v++) {
            const float *p = o->pos + 3 * (size_t)v, *n = o->normal ? o->normal + 3 * (size_t)v : NULL;
            for (int i = 0; i < 3; i++) {
                pos[3 * (v0 + v) + i] = x[4 * i] * p[0] + x[4 * i + 1] * p[1] + x[4 * i + 2] * p[2] + x[4 * i + 3];
                nrm[3 * (v0 + v) + i] = n ? x[4 * i] * n[0] + x[4 * i + 1] * n[1] + x[4 * i + 2] * n[2] : 0.0f;
            }
        }
        const float *a = hl_dyn_scene_body_albedo(s, b);
        for (size_t i = 0; i < 3 * (size_t)o->nverts; i++) alb[3 * v0 + i] = a ? a[i] : 0.8f;
        for (size_t i = 0; i < 3 * (size_t)o->ntris; i++) idx[3 * t0i + i] = (uint32_t)(v0 + o->tri[i]);
        v0 += o->nverts;
        t0i += o->ntris;
    }
    /* the scene turned the up axis already; the winding rule is the load's */
    const hl_mesh_load_desc bd = {.keep_winding = desc ? desc->keep_winding : 0};
    if (r == HL_OK) r = hl_mesh_build_(ctx, path, (uint32_t)nv, pos, nrm, alb, NULL, (uint32_t)nt, idx, &bd, out, NULL);
    free(pos);
    free(nrm);
    free(alb);
    free(idx);
    free(ob);
    hl_dyn_scene_destroy(s);
    return r;
}
