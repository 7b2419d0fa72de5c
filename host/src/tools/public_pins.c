/* public_pins.c - compile-time checks that the constants haarlight.h
 * defines for users equal the ones hl_shared.h gives the kernels.
 *
 * hl_shared.h is read first, alone, as the kernels read it; its values
 * are kept as enumeration constants, its macros dropped, and haarlight.h
 * then defines its own, which must match. Nothing here runs.
 */
#include "hl_shared.h"

enum {
    SHARED_TRUNC_DEFAULT = HL_TRUNC_DEFAULT,
    SHARED_TRUNC_ALL = HL_TRUNC_ALL,
    SHARED_TRUNC_TOPK = HL_TRUNC_TOPK,
    SHARED_TRUNC_ENERGY = HL_TRUNC_ENERGY,
    SHARED_QUANT_DEFAULT = HL_QUANT_DEFAULT,
    SHARED_QUANT_LINEAR8 = HL_QUANT_LINEAR8,
    SHARED_QUANT_LOG8 = HL_QUANT_LOG8,
    SHARED_QUANT_SQRT8 = HL_QUANT_SQRT8,
    SHARED_QUANT_MAX = HL_QUANT_MAX,
    SHARED_SELECT_DEFAULT = HL_SELECT_DEFAULT,
    SHARED_SELECT_AREA = HL_SELECT_AREA,
    SHARED_SELECT_UNWEIGHTED = HL_SELECT_UNWEIGHTED,
    SHARED_SELECT_TRANSPORT = HL_SELECT_TRANSPORT
};

#undef HL_TRUNC_DEFAULT
#undef HL_TRUNC_ALL
#undef HL_TRUNC_TOPK
#undef HL_TRUNC_ENERGY
#undef HL_QUANT_DEFAULT
#undef HL_QUANT_LINEAR8
#undef HL_QUANT_LOG8
#undef HL_QUANT_SQRT8
#undef HL_QUANT_MAX
#undef HL_SELECT_DEFAULT
#undef HL_SELECT_AREA
#undef HL_SELECT_UNWEIGHTED
#undef HL_SELECT_TRANSPORT

#include "haarlight.h"

#define HL_PIN(name) _Static_assert(SHARED_##name == HL_##name, "haarlight.h and hl_shared.h disagree on HL_" #name)
HL_PIN(TRUNC_DEFAULT);
HL_PIN(TRUNC_ALL);
HL_PIN(TRUNC_TOPK);
HL_PIN(TRUNC_ENERGY);
HL_PIN(QUANT_DEFAULT);
HL_PIN(QUANT_LINEAR8);
HL_PIN(QUANT_LOG8);
HL_PIN(QUANT_SQRT8);
HL_PIN(QUANT_MAX);
HL_PIN(SELECT_DEFAULT);
HL_PIN(SELECT_AREA);
HL_PIN(SELECT_UNWEIGHTED);
HL_PIN(SELECT_TRANSPORT);

/* the public header names the row parameters' struct without its layout */
_Static_assert(sizeof(struct hl_row_quant) == 8, "hl_row_quant: two floats per vertex");
