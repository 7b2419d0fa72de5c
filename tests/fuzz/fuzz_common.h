/* fuzz_common.h - what the libFuzzer targets share: one quiet reference
 * context, the input written to a scratch file (the loaders take paths),
 * and the invariant check that aborts so libFuzzer records the input.
 *
 * The scratch file is $HL_FUZZ_TMP, else $TMPDIR, else /tmp, named
 * hl-fuzz-<pid><suffix>, so parallel fuzzing processes never share one. It
 * is removed after each input.
 */
#ifndef HL_FUZZ_COMMON_H
#define HL_FUZZ_COMMON_H

#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_test.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Aborts (a crash libFuzzer saves) when an API invariant is broken, after
 * HL_CHECK has printed where and why. */
#define FUZZ_REQUIRE(cond, ...)                                                  \
    do {                                                                         \
        HL_CHECK(cond, __VA_ARGS__);                                             \
        if (hl_test_failures) abort();                                           \
    } while (0)

/* The plain-C reference context, made once; it lives for the process. */
static inline hl_context *fuzz_context(void)
{
    static hl_context *ctx = NULL;
    if (!ctx) ctx = hl_test_ref_context(1);
    return ctx;
}

/* Writes data to this process's scratch file ending in suffix and returns
 * its path (a static buffer). A scratch file that cannot be written is a
 * broken setup, not a finding: it aborts with the reason. */
static inline const char *fuzz_write_input(const uint8_t *data, size_t size, const char *suffix)
{
    static char path[1024];
    const char *dir = getenv("HL_FUZZ_TMP");
    if (!dir || !*dir) dir = getenv("TMPDIR");
    if (!dir || !*dir) dir = "/tmp";
    snprintf(path, sizeof path, "%s/hl-fuzz-%ld%s", dir, (long)getpid(), suffix);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0) {
        fprintf(stderr, "fuzz: cannot create %s: %s\n", path, strerror(errno));
        abort();
    }
    size_t done = 0;
    while (done < size) {
        ssize_t k = write(fd, data + done, size - done);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) {
            fprintf(stderr, "fuzz: cannot write %s: %s\n", path, strerror(errno));
            abort();
        }
        done += (size_t)k;
    }
    if (close(fd) != 0) {
        fprintf(stderr, "fuzz: cannot write %s: %s\n", path, strerror(errno));
        abort();
    }
    return path;
}

/* A load must fail with a real error code, or succeed with an object.
 * HL_FUZZ_VERBOSE=1 prints each result and message (to see what a seed or
 * a crashing input does). */
static inline void fuzz_check_result(hl_result r, const void *obj)
{
    static int verbose = -1;
    if (verbose < 0) verbose = getenv("HL_FUZZ_VERBOSE") && atoi(getenv("HL_FUZZ_VERBOSE")) > 0;
    if (verbose)
        fprintf(stderr, "fuzz: %s%s%s\n", hl_result_string(r), r == HL_OK ? "" : ": ",
                r == HL_OK ? "" : hl_context_last_error(fuzz_context()));
    FUZZ_REQUIRE(r >= HL_OK && r < HL_RESULT_COUNT, "result code %d is not an hl_result", (int)r);
    FUZZ_REQUIRE((r == HL_OK) == (obj != NULL), "result %s but the object is %s", hl_result_string(r),
                 obj ? "set" : "NULL");
    if (r != HL_OK)
        FUZZ_REQUIRE(hl_context_last_error(fuzz_context())[0] != '\0', "result %s with no message",
                     hl_result_string(r));
}

static inline int fuzz_finite3(const float *p) { return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]); }

/* What every mesh a loader returns keeps: at least one triangle, indices
 * in range, finite positions, normals and albedo. */
static inline void fuzz_check_mesh(const hl_mesh *m)
{
    FUZZ_REQUIRE(m->vertex_count >= 1, "a mesh with no vertices");
    FUZZ_REQUIRE(m->object_vertex_count <= m->vertex_count, "object_vertex_count %u > vertex_count %u",
                 m->object_vertex_count, m->vertex_count);
    for (size_t i = 0; i < 3 * (size_t)m->triangle_count; i++)
        FUZZ_REQUIRE(m->indices[i] < m->vertex_count, "index %u at %zu is not below %u", m->indices[i], i,
                     m->vertex_count);
    for (size_t v = 0; v < m->vertex_count; v++) {
        FUZZ_REQUIRE(fuzz_finite3(m->positions + 3 * v), "vertex %zu: position not finite", v);
        FUZZ_REQUIRE(fuzz_finite3(m->normals + 3 * v), "vertex %zu: normal not finite", v);
        FUZZ_REQUIRE(fuzz_finite3(m->albedo + 3 * v), "vertex %zu: albedo not finite", v);
    }
}

#endif
