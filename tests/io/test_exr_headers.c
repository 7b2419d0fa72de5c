/* test_exr_headers.c - hostile OpenEXR headers (suite "exr_headers").
 *
 * exr_headers.hostile  headers written byte by byte that made OpenEXR's C++
 *                      reader allocate gigabytes: far data windows, chunk
 *                      tables beyond the file, tiny tiles, huge chunks and
 *                      attributes, a bad second part; each refused with the
 *                      reason, loaded in a child under a 1 GiB address-space
 *                      limit whose peak RSS stays under 100 MB; sound maps
 *                      still load there.
 * Depends on: haarlight_core (reference backend only),
 * tests/common/{env_util,exr_build}.h, fork/wait4/setrlimit,
 * HL_TEST_FIXTURES (tests/data).
 */
#define _POSIX_C_SOURCE 200809L
#define _DEFAULT_SOURCE /* wait4 */
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_test.h"
#include "env_util.h"

#include "exr_build.h"

#define EB_FAR ((int64_t)(1 << 30) - 2)

/* The hostile shapes. Each writes a whole file into b. */
static void shape_minimal(exr_bytes *b) /* 85 bytes, like the fuzzer's file */
{
    eb_start(b, 0);
    eb_channels(b, 1, EB_HALF);
    eb_box(b, "dataWindow", -EB_FAR, -EB_FAR, EB_FAR, EB_FAR);
    eb_u8(b, 0);
}
static void shape_full_far(exr_bytes *b)
{
    eb_start(b, 0);
    eb_required(b, 3, EB_HALF, EB_ZIP, -EB_FAR, -EB_FAR, EB_FAR, EB_FAR);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
static void shape_full_tall(exr_bytes *b) /* one column of 2^31 - 3 rows */
{
    eb_start(b, 0);
    eb_required(b, 3, EB_HALF, EB_NONE, 0, -EB_FAR, 0, EB_FAR);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
static void shape_table_beyond_file(exr_bytes *b) /* 8192 x 4096, one row a chunk */
{
    eb_start(b, 0);
    eb_required(b, 3, EB_HALF, EB_NONE, 0, 0, 8191, 4095);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
static void shape_tiny_tiles(exr_bytes *b) /* 4096 x 2048 in tiles of 1 x 1 */
{
    eb_start(b, EB_TILED);
    eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 4095, 2047);
    eb_tiles(b, 1, 1, 0);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
static void shape_tiny_tiles_mipmap(exr_bytes *b) /* and with every mip level */
{
    eb_start(b, EB_TILED);
    eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 2047, 1023);
    eb_tiles(b, 1, 1, 1);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
static void shape_wide_channels(exr_bytes *b) /* 64 float channels, 65536 x 32: one PIZ chunk of 512 MiB */
{
    eb_start(b, 0);
    eb_required(b, 64, EB_FLOAT, EB_PIZ, 0, 0, 65535, 31);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
/* A sound 16 x 8 header, then one attribute that claims 2^31 - 1 bytes. */
static void huge_attribute(exr_bytes *b, const char *name, const char *type)
{
    eb_start(b, 0);
    eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
    eb_attr(b, name, type, INT32_MAX);
    eb_put(b, "abc", 3);
    eb_zeros(b, 16);
}
static void shape_huge_string(exr_bytes *b) { huge_attribute(b, "comments", "string"); }
static void shape_huge_floatvector(exr_bytes *b) { huge_attribute(b, "weights", "floatvector"); }
static void shape_huge_opaque(exr_bytes *b) { huge_attribute(b, "payload", "rawbytes"); }
/* Multi-part: a sound first part, then one as far out as shape_full_far. */
static void shape_second_part(exr_bytes *b)
{
    eb_start(b, EB_MULTIPART);
    eb_part(b, "sound", 0, 0, 15, 7, 1);
    eb_part(b, "far", -EB_FAR, -EB_FAR, EB_FAR, EB_FAR, (2 * EB_FAR + 1 + 15) / 16);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
static void shape_chunk_count(exr_bytes *b) /* a chunkCount of 2^30 for one 16 x 8 chunk */
{
    eb_start(b, EB_MULTIPART);
    eb_part(b, "one", 0, 0, 15, 7, 1 << 30);
    eb_u8(b, 0);
    eb_zeros(b, 64);
}
static void shape_many_attributes(exr_bytes *b) /* 20000 int attributes: 410 KB */
{
    char name[16];
    eb_start(b, 0);
    eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
    for (int i = 0; i < 20000; i++) {
        snprintf(name, sizeof name, "n%05d", i);
        eb_attr(b, name, "int", 4);
        eb_i32(b, i);
    }
    eb_u8(b, 0);
    eb_zeros(b, 64);
}

/* AddressSanitizer maps terabytes of shadow memory: an address-space
 * limit cannot be set under it (the core may be built with it while this
 * file is not, so its runtime is looked for too). */
#if defined(__SANITIZE_ADDRESS__)
#define HL_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define HL_TEST_ASAN 1
#endif
#endif
#ifndef HL_TEST_ASAN
#define HL_TEST_ASAN 0
#endif
extern void __asan_init(void) __attribute__((weak));

typedef struct child_load {
    int ok;          /* the child reported a result */
    hl_result r;     /* hl_env_load's code */
    char msg[1536];  /* and message */
    double rss_mb;   /* the child's peak resident set */
    double seconds;  /* wall time of the child */
} child_load;

/* Loads path in a forked child under an address-space limit (0: none),
 * and reports its result, message and peak RSS (wait4's rusage). */
static child_load load_in_child(const char *path, rlim_t limit)
{
    child_load out;
    memset(&out, 0, sizeof out);
    int fds[2];
    if (pipe(fds) != 0) {
        HL_CHECK(0, "pipe: %s", strerror(errno));
        return out;
    }
    fflush(stdout);
    fflush(stderr);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        if (limit) {
            struct rlimit rl = {limit, limit};
            if (setrlimit(RLIMIT_AS, &rl) != 0) _exit(3);
        }
        hl_context *ctx = make_ctx();
        hl_env *env = NULL;
        hl_env_stats st;
        int32_t code = (int32_t)hl_env_load(ctx, path, &env, &st);
        const char *m = hl_context_last_error(ctx);
        size_t n = strlen(m);
        if (write(fds[1], &code, sizeof code) != (ssize_t)sizeof code || write(fds[1], m, n) != (ssize_t)n) _exit(4);
        hl_env_destroy(env);
        hl_context_destroy(ctx);
        _exit(0);
    }
    close(fds[1]);
    if (pid < 0) {
        close(fds[0]);
        HL_CHECK(0, "fork: %s", strerror(errno));
        return out;
    }
    int32_t code = 0;
    size_t got = 0;
    ssize_t k = read(fds[0], &code, sizeof code);
    if (k == (ssize_t)sizeof code) {
        while (got + 1 < sizeof out.msg && (k = read(fds[0], out.msg + got, sizeof out.msg - 1 - got)) > 0)
            got += (size_t)k;
        out.ok = 1;
    }
    out.msg[got] = '\0';
    close(fds[0]);
    int status = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    if (wait4(pid, &status, 0, &ru) != pid) HL_CHECK(0, "wait4: %s", strerror(errno));
    clock_gettime(CLOCK_MONOTONIC, &t1);
    out.seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    out.rss_mb = (double)ru.ru_maxrss / 1024.0; /* kilobytes on Linux */
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        HL_CHECK(0, "%s: the loading child %s %d", path, WIFSIGNALED(status) ? "was killed by signal" : "exited with",
                 WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
        out.ok = 0;
    }
    out.r = (hl_result)code;
    return out;
}

static void test_hostile_headers(void)
{
    static const struct {
        const char *name;
        void (*make)(exr_bytes *);
        const char *why; /* the refusal says this */
    } shapes[] = {
        {"minimal_far_window", shape_minimal, "attribute not found"},
        {"full_header_far_window", shape_full_far, "2147483645 x 2147483645 pixels"},
        {"full_header_tall_window", shape_full_tall, "1 x 2147483645 pixels"},
        {"chunk_table_beyond_file", shape_table_beyond_file, "offset table"},
        {"tiny_tiles", shape_tiny_tiles, "tiles of 1 x 1 pixels"},
        {"tiny_tiles_mipmap", shape_tiny_tiles_mipmap, "tiles of 1 x 1 pixels"},
        {"wide_chunk_many_channels", shape_wide_channels, "decodes to 536870912 bytes"},
        {"string_attribute_2gib", shape_huge_string, "'comments'"},
        {"floatvector_attribute_2gib", shape_huge_floatvector, "'weights'"},
        {"opaque_attribute_2gib", shape_huge_opaque, "'payload'"},
        {"second_part_far_window", shape_second_part, "part 1: data window"},
        {"chunk_count_2_30", shape_chunk_count, "chunk count"},
        {"many_attributes", shape_many_attributes, "attributes and channels"},
    };
    const rlim_t limit = HL_TEST_ASAN || __asan_init ? 0 : (rlim_t)1 << 30;
    const double rss_limit_mb = 100.0;
    if (limit)
        printf("each load runs in a child limited to %llu MiB of address space\n",
               (unsigned long long)(limit >> 20));
    else
        printf("AddressSanitizer: no address-space limit on the children\n");

    char dir[512], path[1024];
    scratch(dir, sizeof dir, "hostile_headers");
    double worst_rss = 0.0;
    const char *worst = "";
    for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) {
        exr_bytes b = {NULL, 0, 0};
        shapes[i].make(&b);
        snprintf(path, sizeof path, "%s/%s.exr", dir, shapes[i].name);
        write_bytes(path, b.p, b.n);
        if (i == 0) HL_CHECK(b.n == 85, "%s: %zu bytes, expected 85", shapes[i].name, b.n);
        free(b.p);
        child_load c = load_in_child(path, limit);
        printf("%-27s %6zu bytes: %s, peak RSS %.1f MB, %.3f s: %s\n", shapes[i].name, b.n,
               c.ok ? hl_result_string(c.r) : "no result", c.rss_mb, c.seconds, c.msg);
        HL_CHECK(c.ok && c.r == HL_ERR_FORMAT, "%s: %s, expected %s", shapes[i].name,
                 c.ok ? hl_result_string(c.r) : "no result", hl_result_string(HL_ERR_FORMAT));
        HL_CHECK(strstr(c.msg, path) != NULL, "%s: the message does not name the file: %s", shapes[i].name, c.msg);
        HL_CHECK(strstr(c.msg, shapes[i].why) != NULL, "%s: the message does not say \"%s\": %s", shapes[i].name,
                 shapes[i].why, c.msg);
        if (c.rss_mb > worst_rss) {
            worst_rss = c.rss_mb;
            worst = shapes[i].name;
        }
    }
    printf("worst: %s\n", worst);
    hl_check_error("hostile headers: peak RSS of the loading child (MB)", worst_rss, rss_limit_mb);

    /* The same harness loads sound maps: through OpenEXRCore (a float map
       of this writer) and through the C++ reader (a tiled float map). */
    hl_context *ctx = make_ctx();
    hl_image *img = NULL;
    HL_CHECK(hl_image_create(ctx, 16, 8, &img) == HL_OK, "hl_image_create: %s", hl_context_last_error(ctx));
    snprintf(path, sizeof path, "%s/sound_16x8.exr", dir);
    if (img) {
        HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_OK, "save %s: %s", path, hl_context_last_error(ctx));
        hl_image_destroy(img);
    }
    hl_context_destroy(ctx);
    char tiled[1024];
    snprintf(tiled, sizeof tiled, "%s/float_tiled.exr", hl_test_env("HL_TEST_FIXTURES", "tests/data"));
    const char *sound[2] = {path, tiled};
    for (int k = 0; k < 2; k++) {
        child_load c = load_in_child(sound[k], limit);
        printf("sound map %s: %s, peak RSS %.1f MB, %.3f s %s\n", sound[k], c.ok ? hl_result_string(c.r) : "no result",
               c.rss_mb, c.seconds, c.msg);
        HL_CHECK(c.ok && c.r == HL_OK, "%s: not loaded: %s", sound[k], c.msg);
    }
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"hostile", test_hostile_headers},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
