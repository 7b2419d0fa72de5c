/* dyn_util.h - helpers shared by the dynamic method's tests.
 * Depends on: hl_test.h, host/src/dynamic/area_lights.h.
 */
#ifndef HL_TEST_DYN_UTIL_H
#define HL_TEST_DYN_UTIL_H

#include "area_lights.h"
#include "hl_test.h"

/* env split into area lights at the defaults, K kept; NULL (a failed
 * check) when the split fails. */
static inline hl_light_split *split_of(hl_context *ctx, const hl_env *env, int32_t K)
{
    hl_light_split_params p;
    hl_light_split_defaults(&p);
    p.lights = K;
    hl_light_split *s = NULL;
    HL_CHECK(hl_area_lights_split(ctx, env, &p, &s) == HL_OK, "%s", hl_context_last_error(ctx));
    return s;
}

#endif
