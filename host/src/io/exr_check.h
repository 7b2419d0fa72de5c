/* exr_check.h - the strict checks of an OpenEXR file that run before any
 * decoder allocates for it (exr_check.c), and the OpenEXRCore message
 * plumbing they share with exr_io.c. Private to exr_io.c and exr_check.c,
 * the only files that include OpenEXR headers.
 *
 * Depends on: OpenEXRCore (openexr.h, through the hl_openexr CMake
 * target), hl_internal.h (hl_fail).
 */
#ifndef HL_EXR_CHECK_H
#define HL_EXR_CHECK_H

#include <stdint.h>
#include <stdio.h>

#include <openexr.h>

#include "hl_internal.h"

/* OpenEXRCore reports through a handler: it keeps the last message in
 * the context's user data. */
typedef struct core_msg {
    char text[256];
} core_msg;

static inline void core_error(exr_const_context_t f, exr_result_t code, const char *msg)
{
    void *ud = NULL;
    if (exr_get_user_data(f, &ud) == EXR_ERR_SUCCESS && ud)
        snprintf(((core_msg *)ud)->text, sizeof((core_msg *)ud)->text, "%s",
                 msg ? msg : exr_get_default_error_message(code));
}

static inline const char *core_text(const core_msg *m, exr_result_t rv)
{
    return m->text[0] ? m->text : exr_get_default_error_message(rv);
}

/* A context initializer whose messages go to m. */
static inline exr_context_initializer_t core_init(core_msg *m)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = core_error;
    init.user_data = m;
    return init;
}

/* The data window's size, bounded (HL_EXR_MAX_SIDE, HL_EXR_MAX_PIXELS and,
 * with HL_EXR_REQUIRE_2TO1 in flags, 2:1) before anything is allocated.
 * part prefixes the message ("" or "part N: "). */
hl_result hl_exr_window_size_(hl_context *ctx, const char *path, const char *part, unsigned flags, int xmin,
                              int ymin, int xmax, int ymax, uint32_t *width, uint32_t *height);

/* The three checks, in the order hl_exr_read_rgb_ runs them; each returns
 * HL_OK or refuses the file (HL_ERR_FORMAT, HL_ERR_IO where it cannot be
 * read) with a message naming the part and the chunk. f was opened with a
 * strict header parse and its messages going to msg. */

/* Every part's header bounded against the file (file_size bytes). */
hl_result hl_exr_check_parts_(hl_context *ctx, const char *path, exr_const_context_t f, const core_msg *msg,
                              uint64_t file_size);
/* Every chunk of every part: its offset-table entry, header and extent. */
hl_result hl_exr_check_chunks_(hl_context *ctx, const char *path, exr_const_context_t f, core_msg *msg,
                               uint64_t file_size);
/* Every chunk of part 0 decoded and thrown away (not for DWA or B44). */
hl_result hl_exr_check_decodes_(hl_context *ctx, const char *path, exr_const_context_t f, core_msg *msg);

/* " (N bytes of ZIP data for M bytes of pixels)" for a chunk OpenEXRCore
 * read the header of, else "". */
void hl_exr_chunk_sizes_(char *out, size_t n, const exr_chunk_info_t *ci);

#endif
