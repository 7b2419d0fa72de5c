/* dyn_api.h - a look inside the dynamic method's public handle
 * (dyn_api.c), for the command's measuring tools (host/src/tools/): the
 * bodies as of the last frame, their albedo and the light split, so that
 * references and rival methods see exactly what the frame saw.
 * Not for the public API. Depends on: dynamic.h, area_lights.h.
 */
#ifndef HL_DYN_API_H
#define HL_DYN_API_H

#include <stdint.h>

#include "area_lights.h"
#include "dynamic.h"
#include "haarlight.h"

/* Borrowed from d, valid until its next render, set_env or destroy:
 * obj[b] holds body b at the last frame's pose (at rest before the first
 * frame), alb[b] its albedo (3 per vertex), vstart[b] its first vertex in
 * hl_dynamic_mesh, split the current lights (NULL before set_env). */
typedef struct hl_dynamic_view {
    hl_context *ctx;
    uint32_t nb;
    const hl_dyn_object *obj;
    const float *const *alb;
    const uint32_t *vstart;
    const hl_light_split *split;
} hl_dynamic_view;

void hl_dynamic_view_get(const hl_dynamic *d, hl_dynamic_view *v);

#endif
