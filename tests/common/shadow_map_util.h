/* shadow_map_util.h - synthetic shadow maps shared by the filterable
 * shadow tests (tests/dynamic/test_csm_eval.c, test_msm.c).
 * Depends on: csm.h (hl_shadow_frame).
 */
#ifndef HL_TEST_SHADOW_MAP_UTIL_H
#define HL_TEST_SHADOW_MAP_UTIL_H

#include <stddef.h>
#include <stdint.h>

#include "csm.h"
#include "hl_test.h"

/* a frame looking down -z: 10 x 10 world units, depth range 10 */
static inline hl_shadow_frame frame_of(uint32_t R)
{
    hl_shadow_frame f = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, 10.0f, 10.0f, 10.0f, R, 0};
    return f;
}

/* z_in inside texels [i0, i1) x [i0, i1), z_out elsewhere */
static inline void square_map(float *z, uint32_t R, uint32_t i0, uint32_t i1, float z_in, float z_out)
{
    for (uint32_t j = 0; j < R; j++)
        for (uint32_t i = 0; i < R; i++) z[(size_t)j * R + i] = (i >= i0 && i < i1 && j >= i0 && j < i1) ? z_in : z_out;
}

/* n receivers (u, v, depth, 3 floats each) at random over the map's R x R
 * texels and 4 texels past its edges, depths in [0, 1) */
static inline void random_receivers(float *uvd, uint32_t n, uint32_t R)
{
    for (uint32_t i = 0; i < n; i++) {
        uvd[3 * i] = (float)(hl_rng_unit() * (R + 8) - 4);
        uvd[3 * i + 1] = (float)(hl_rng_unit() * (R + 8) - 4);
        uvd[3 * i + 2] = (float)hl_rng_unit();
    }
}

#endif
