/* test_cube2para.c - the cube to dual paraboloid resampling
 * (kernels/maps/cube2para.cl) against its plain-C twin
 * (host/src/maps/twins/cube2para.c), suite "cube2para".
 *
 * cube2para.twin  rows of real visibility at three (N, C): the same
 *                 operations in the same order, within 1e-6 of max |T|.
 *                 Timings are printed for information only.
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL),
 * tests/common/stage_fixture.h.
 */
#include <stdint.h>

#include "cl_backend.h"
#include "geom.h"
#include "hl_test.h"
#include "precompute.h"
#include "rays.h"
#include "twins.h"
#include "stage_fixture.h"

static void case_cube2para(void)
{
    static const uint32_t res[][2] = {{64, 64}, {16, 32}, {128, 48}};
    for (size_t k = 0; k < 3; k++) {
        fixture f;
        if (!setup(&f, res[k][0], res[k][1], 96)) { HL_CHECK(0, "setup failed"); teardown(&f); return; }
        size_t n = (size_t)f.rows * f.g->ncoef;
        float *a = malloc(n * 4), *b = malloc(n * 4);
        ref_T(&f, a);
        /* the first launch compiles PoCL's work-group function: warm up */
        hl_cl_pipe_cube2para(f.pipe, f.rows, f.vis, VIS_SCALE, f.n4, b);
        double t0 = hl_now();
        HL_CHECK(hl_cl_pipe_cube2para(f.pipe, f.rows, f.vis, VIS_SCALE, f.n4, b) == HL_OK, "%s", hl_context_last_error(f.cl));
        printf("N=%u C=%u: %u rows in %.2f ms\n", f.g->N, f.g->C, f.rows, 1e3 * (hl_now() - t0));
        /* same operations in the same order: only contraction or a
           different rounding mode could make them differ */
        hl_check_error("cube2para OpenCL vs C, relative to max |T|", hl_test_rel_diff(a, b, n), 1e-6);
        free(a);
        free(b);
        teardown(&f);
    }
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"twin", case_cube2para},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
