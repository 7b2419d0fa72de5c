/* env_layout.h - light-probe layouts resampled to equirectangular maps
 * (env_layout.c). */
#ifndef HL_ENV_LAYOUT_H
#define HL_ENV_LAYOUT_H

#include <stdint.h>

#include "haarlight.h"

/* The layout a size implies: 2:1 equirectangular, 1:1 angular map, 4:3
 * horizontal cross, 3:4 vertical cross; HL_LAYOUT_AUTO for none. */
hl_env_layout hl_env_layout_of_size_(uint32_t w, uint32_t h);

/* A layout's name and shape, for messages. */
const char *hl_env_layout_name_(hl_env_layout layout);

/* Resamples w x h pixels of src (3 floats each, finite and >= 0) laid out
 * as layout (angular or a cross) onto a new equirectangular map of
 * *ow x *oh pixels (*out, malloc'ed). HL_ERR_FORMAT (naming path) when
 * the size is not the layout's. */
hl_result hl_env_resample_layout_(hl_context *ctx, const char *path, hl_env_layout layout, uint32_t w, uint32_t h,
                                  const float *src, uint32_t *ow, uint32_t *oh, float **out);

#endif
