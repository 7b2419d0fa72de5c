/* hl_test.h - tiny assertion helpers for the ctest suites.
 *
 * A test executable takes the case name as argv[1] and dispatches to one
 * function. A case that cannot run here (optional data missing) calls
 * hl_test_skip_missing and exits 77, which ctest's SKIP_RETURN_CODE
 * reports as skipped. Every numeric check prints its tolerance and the worst error
 * it saw, so a passing log still tells how close it came.
 */
#ifndef HL_TEST_H
#define HL_TEST_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "haarlight.h"

static int hl_test_failures = 0;

#define HL_CHECK(cond, ...)                                                   \
    do {                                                                      \
        if (!(cond)) {                                                        \
            fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);              \
            fprintf(stderr, __VA_ARGS__);                                     \
            fputc('\n', stderr);                                              \
            hl_test_failures++;                                               \
        }                                                                     \
    } while (0)

/* Prints "what: worst error E, tolerance T" and fails when E > T or E is
 * not a number. */
static inline void hl_check_error(const char *what, double worst, double tol)
{
    int ok = worst <= tol;
    printf("%s: worst error %.4g, tolerance %.4g: %s\n", what, worst, tol, ok ? "ok" : "FAIL");
    if (!ok) hl_test_failures++;
}

/* max |a - b| over max |a| (max |a - b| where a is all zero); a NaN
 * difference makes the result NaN, which no tolerance accepts. */
static inline double hl_test_rel_diff(const float *a, const float *b, size_t n)
{
    double w = 0.0, m = 0.0;
    for (size_t i = 0; i < n; i++) {
        double e = fabs((double)a[i] - b[i]);
        if (!(e <= w)) w = e;
        m = fmax(m, fabs((double)a[i]));
    }
    return m > 0.0 ? w / m : w;
}

/* The exit code of a skipped case (SKIP_RETURN_CODE in tests/CMakeLists.txt). */
#define HL_TEST_SKIP 77
static int hl_test_skipped = 0;

/* Marks the running case skipped because folder is missing: the optional
 * shared data (HL_SHARED_DATA at configure time, HL_TEST_DATA at run
 * time) that a clone of the repository does not have. */
static inline void hl_test_skip_missing(const char *folder)
{
    printf("skipped: %s not found (set HL_SHARED_DATA to the shared data folder when configuring, "
           "or HL_TEST_DATA when running)\n", folder);
    hl_test_skipped = 1;
}

typedef struct hl_test_case {
    const char *name;
    void (*fn)(void);
} hl_test_case;

/* Runs the case named argv[1]; returns the process exit code. */
static inline int hl_test_main(int argc, char **argv, const hl_test_case *cases)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s CASE\ncases:", argv[0]);
        for (const hl_test_case *c = cases; c->name; c++) fprintf(stderr, " %s", c->name);
        fputc('\n', stderr);
        return 2;
    }
    for (const hl_test_case *c = cases; c->name; c++) {
        if (strcmp(c->name, argv[1]) == 0) {
            c->fn();
            if (hl_test_skipped && !hl_test_failures) {
                printf("%s: skipped\n", c->name);
                return HL_TEST_SKIP;
            }
            printf("%s: %s\n", c->name, hl_test_failures ? "FAILED" : "passed");
            return hl_test_failures ? 1 : 0;
        }
    }
    fprintf(stderr, "unknown case %s\n", argv[1]);
    return 2;
}

/* splitmix64: a deterministic generator for test data, the same on every
 * platform. Each test executable has its own state. */
static uint64_t hl_rng_state = 0x9E3779B97F4A7C15ull;
static inline uint64_t hl_rng_next(void)
{
    uint64_t z = (hl_rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* CRC-32 (IEEE), bit by bit: an independent check of the files' own
 * table-driven checksums. */
static inline uint32_t hl_test_crc32(const uint8_t *p, size_t n)
{
    uint32_t c = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++) c = (c & 1u) ? (c >> 1) ^ 0xEDB88320u : c >> 1;
    }
    return ~c;
}

/* Environment helpers: shared data folder, scratch folder, CLI binary. */
static inline const char *hl_test_env(const char *name, const char *fallback)
{
    const char *v = getenv(name);
    return v && *v ? v : fallback;
}

/* A plain-C reference context (no OpenCL needed); exits on failure. */
static inline hl_context *hl_test_ref_context(int threads)
{
    hl_context_desc d = {.backend = HL_BACKEND_REFERENCE, .quiet = 1, .threads = threads};
    hl_context *ctx = NULL;
    char err[512];
    if (hl_context_create(&d, &ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "cannot create a reference context: %s\n", err);
        exit(1);
    }
    return ctx;
}

/* A uniform double in [0, 1) from hl_rng_next. */
static inline double hl_rng_unit(void) { return (double)(hl_rng_next() >> 11) / 9007199254740992.0; }

/* The default OpenCL device's context, quiet, with `threads` host threads
 * (0: the default); NULL (with the reason on stderr) where there is none. */
static inline hl_context *hl_test_cl_context(int threads)
{
    hl_context_desc d = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .quiet = 1, .threads = threads};
    hl_context *ctx = NULL;
    char err[4096];
    if (hl_context_create(&d, &ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "OpenCL context: %s\n", err);
        return NULL;
    }
    return ctx;
}

/* The folder named by environment variable var (dflt when unset), then
 * name, in one of 16 rotating buffers, so a test can hold several. */
static inline const char *hl_test_path_in(const char *var, const char *dflt, const char *name)
{
    static char buf[16][1024];
    static int next = 0;
    char *b = buf[next++ & 15];
    snprintf(b, 1024, "%s/%s", hl_test_env(var, dflt), name);
    return b;
}

/* HL_TMP/name. */
static inline const char *hl_test_tmp_path(const char *name) { return hl_test_path_in("HL_TMP", "/tmp", name); }

/* The repository's data folder (HL_REPO_DATA)/name. */
static inline const char *hl_test_data_path(const char *name) { return hl_test_path_in("HL_REPO_DATA", "data", name); }

/* The whole file (malloc'ed, one spare byte), its size in *n; NULL when it
 * cannot be read (*n then 0). */
static inline uint8_t *hl_test_read_file(const char *path, size_t *n)
{
    *n = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *p = len >= 0 ? malloc((size_t)len + 1) : NULL;
    if (p && fread(p, 1, (size_t)len, f) != (size_t)len) {
        free(p);
        p = NULL;
    }
    fclose(f);
    if (p) *n = (size_t)len;
    return p;
}

#endif
