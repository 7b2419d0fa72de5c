/* test_select.c - the selection of lighting terms
 * (kernels/relight/select.cl) against its plain-C twin
 * (host/src/relight/twins/select.c), suite "select".
 *
 * select.twin  the lighting Haar of a map with a sun, then the selection
 *              for M = 1 to all terms, area-weighted and not: kept values,
 *              blocks, bits, counts and energies equal exactly
 *              (lighting_chain without the dot products).
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL),
 * tests/common/light_util.h.
 */
#include <stdint.h>

#include "cl_backend.h"
#include "geom.h"
#include "half.h"
#include "hl_test.h"
#include "lighting.h"
#include "twins.h"
#include "light_util.h"

static void case_twin(void) { lighting_chain(0); }

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"twin", case_twin},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
