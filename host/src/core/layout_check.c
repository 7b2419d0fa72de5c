/* layout_check.c - pins the host/kernel shared layouts (hl_shared.h). */
#include <stddef.h>

#include "hl_internal.h"

_Static_assert(sizeof(hl_c2p_entry) == 16, "hl_c2p_entry must be 16 bytes");
_Static_assert(offsetof(hl_c2p_entry, index) == 12, "hl_c2p_entry.index at 12");
_Static_assert(sizeof(hl_row_quant) == 8, "hl_row_quant must be 8 bytes");
_Static_assert(sizeof(hl_trunc_result) == 16, "hl_trunc_result must be 16 bytes");
_Static_assert(sizeof(hl_trunc_params) == 16, "hl_trunc_params must be 16 bytes");
_Static_assert(sizeof(float) == 4, "float must be 32-bit IEEE");
_Static_assert(sizeof(hl_env_tap) == 16, "hl_env_tap must be 16 bytes");
_Static_assert(sizeof(hl_select_params) == 16, "hl_select_params must be 16 bytes");
_Static_assert(sizeof(hl_select_result) == 32, "hl_select_result must be 32 bytes");
