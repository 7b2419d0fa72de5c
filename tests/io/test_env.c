/* test_env.c - environments (suite "env").
 *
 * Cases: convention (pins docs/CONVENTIONS.md: landmarks, every pixel centre, the
 * rotation sense), solid_angle (the pixel solid angles add up to 4pi and
 * match a numerical integral), load_shared (the eight shared maps against
 * the numbers in shared/data/README.md; skipped, exit 77, where that
 * optional folder is missing), bad_files (missing, empty, random,
 * truncated, bit-flipped, not 2:1, a folder: a non-OK code naming the file,
 * no crash; the truncated and flipped copies are of data/city.exr),
 * nan_repair (NaN/Inf/negative channels zeroed and counted),
 * float_files (32-bit float maps from another writer: exact where
 * OpenEXRCore reads them, suns beyond the half range refused where only
 * half floats can be had, 1e31 refused),
 * sky (sun energy, irradiance and direction for several sizes, elevations
 * and azimuths).
 * Depends on: haarlight_core (reference backend only), tests/common/env_util.h,
 * HL_TEST_DATA (optional), HL_REPO_DATA, HL_TEST_FIXTURES (tests/data).
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_test.h"
#include "env_util.h"

/* ---------------------------------------------------------------- convention */

static void test_convention(void)
{
    hl_context *ctx = make_ctx();
    const uint32_t W = 64, H = 32;
    hl_env *env = index_env(ctx, W, H);
    int c = (int)W / 2, m = (int)H / 2;

    /* Landmarks of docs/CONVENTIONS.md. */
    expect_pixel(env, 1, 0, 0, 0, c, m, "+X is u = 0.5, the image centre");
    expect_pixel(env, 5, 0, 0, 0, c, m, "+X, not unit length");
    expect_pixel(env, 0, 0, -1, 0, (int)W / 4, m, "-Z is u = 0.25");
    expect_pixel(env, 0, 0, 1, 0, 3 * (int)W / 4, m, "+Z is u = 0.75");
    expect_pixel(env, -1, 0, 0, 0, 0, m, "-X is the seam (z = +0)");
    expect_pixel(env, -1, 0, -0.0f, 0, 0, m, "-X is the seam (z = -0)");
    expect_pixel(env, 0, 1, 0, 0, c, 0, "+Y is row 0");
    expect_pixel(env, 0, -1, 0, 0, c, (int)H - 1, "-Y is the last row");
    /* Which side of each landmark is which: u grows with atan2(z, x). */
    expect_pixel(env, 1, 0, 1e-3f, 0, c, m, "just past +X towards +Z");
    expect_pixel(env, 1, 0, -1e-3f, 0, c - 1, m, "just before +X (towards -Z)");
    expect_pixel(env, -1, 0, 1e-3f, 0, (int)W - 1, m, "just before the seam from +Z");
    expect_pixel(env, -1, 0, -1e-3f, 0, 0, m, "just after the seam towards -Z");
    expect_pixel(env, 1, 1e-3f, 0, 0, c, m - 1, "just above the horizon");
    expect_pixel(env, 1, -1e-3f, 0, 0, c, m, "just below the horizon");

    /* Every pixel centre reads its own pixel. */
    int bad = 0;
    for (uint32_t j = 0; j < H; j++)
        for (uint32_t i = 0; i < W; i++) {
            float w[3], q[3];
            dir_of_uv((i + 0.5) / W, (j + 0.5) / H, w);
            hl_env_query(env, w, 0.0f, q);
            bad += q[0] != (float)i || q[1] != (float)j;
        }
    HL_CHECK(bad == 0, "%d pixel centres read another pixel", bad);

    /* Rotation: --rotate 90 shows the +X pixel at R_y(90)(+X) = -Z. */
    float px[3] = {1, 0, 0}, seen[3];
    rot_y(90.0, px, seen);
    HL_CHECK(fabsf(seen[0]) < 1e-6f && fabsf(seen[1]) < 1e-6f && fabsf(seen[2] + 1.0f) < 1e-6f,
             "R_y(90)(+X) = (%g, %g, %g), expected -Z", (double)seen[0], (double)seen[1], (double)seen[2]);
    expect_pixel(env, 0, 0, -1, 90.0f, c, m, "rotate 90: the +X feature appears at -Z");
    expect_pixel(env, 1, 0, 0, 90.0f, 3 * (int)W / 4, m, "rotate 90: +X shows what was stored at +Z");
    expect_pixel(env, 1, 0, 0, -90.0f, (int)W / 4, m, "rotate -90: +X shows what was stored at -Z");
    expect_pixel(env, 0, 0, 1, 90.0f, 0, m, "rotate 90: +Z shows what was stored at -X");
    expect_pixel(env, 1, 0, 0, 180.0f, 0, m, "rotate 180: +X shows the seam");
    expect_pixel(env, 1, 0, 0, 360.0f + 90.0f, 3 * (int)W / 4, m, "rotate 450 = rotate 90");
    expect_pixel(env, 0, 1, 0, 123.0f, -1, 0, "rotation keeps +Y in row 0");
    expect_pixel(env, 0, -1, 0, -77.0f, -1, (int)H - 1, "rotation keeps -Y in the last row");

    /* A feature stored at direction d appears at R_y(DEG) d, any DEG. */
    bad = 0;
    for (int k = 0; k < 2000; k++) {
        uint32_t i = (uint32_t)(hl_rng_next() % W), j = (uint32_t)(hl_rng_next() % H);
        float deg = (float)((double)(hl_rng_next() >> 11) / 9007199254740992.0 * 1440.0 - 720.0);
        float d[3], q[3], col[3];
        dir_of_uv((i + 0.5) / W, (j + 0.5) / H, d);
        rot_y(deg, d, q);
        hl_env_query(env, q, deg, col);
        if (col[0] != (float)i || col[1] != (float)j) {
            if (bad++ < 5)
                fprintf(stderr, "pixel (%u, %u) rotated by %g read (%g, %g)\n", i, j, (double)deg,
                        (double)col[0], (double)col[1]);
        }
    }
    HL_CHECK(bad == 0, "%d of 2000 rotated pixel centres read another pixel", bad);

    /* No direction: black, no crash. */
    float zero[3] = {0, 0, 0}, nanw[3] = {NAN, 0, 1}, out[3] = {1, 1, 1};
    hl_env_query(env, zero, 0.0f, out);
    HL_CHECK(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f, "zero direction is not black");
    hl_env_query(env, nanw, 0.0f, out);
    HL_CHECK(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f, "NaN direction is not black");

    hl_env_destroy(env);
    hl_env_destroy(NULL);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- solid_angle */

static void test_solid_angle(void)
{
    static const uint32_t widths[] = {2, 4, 64, 1024, 4096};
    double worst = 0.0, worst_row = 0.0;
    for (size_t k = 0; k < sizeof widths / sizeof widths[0]; k++) {
        uint32_t W = widths[k], H = W / 2;
        double sum = 0.0;
        for (uint32_t j = 0; j < H; j++) {
            double om = pixel_omega(W, H, j);
            sum += W * om;
            /* Against a numerical integral of sin(theta) dtheta dphi over
             * the pixel (Simpson, 64 intervals). */
            if (j % 7 == 0) {
                double a = PI * j / H, b = PI * (j + 1) / H, s = 0.0;
                for (int t = 0; t <= 64; t++) {
                    double wgt = (t == 0 || t == 64) ? 1.0 : (t % 2 ? 4.0 : 2.0);
                    s += wgt * sin(a + (b - a) * t / 64.0);
                }
                s *= (b - a) / (3.0 * 64.0) * (2.0 * PI / W);
                double e = fabs(s - om) / om;
                if (e > worst_row) worst_row = e;
            }
        }
        double e = fabs(sum - 4.0 * PI) / (4.0 * PI);
        if (e > worst) worst = e;
    }
    hl_check_error("sum of pixel solid angles against 4 pi (relative)", worst, 1e-12);
    hl_check_error("pixel solid angle against a numerical integral (relative)", worst_row, 1e-6);
}

/* ---------------------------------------------------------------- load_shared */

static double lum(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

static void test_load_shared(void)
{
    /* shared/data/README.md, section 1. */
    static const struct {
        const char *name;
        uint64_t neg_px;
        double mean_omega;
    } files[] = {
        {"city", 299, 0.960},    {"courtyard", 1188, 0.766}, {"forest", 784, 0.542},
        {"interior", 5053, 1.050}, {"night", 596, 0.196},    {"studio", 3, 0.337},
        {"sunrise", 570, 0.698}, {"sunset", 5, 0.498},
    };
    const char *data = hl_test_env("HL_TEST_DATA", NULL);
    char path[1024];
    if (data) snprintf(path, sizeof path, "%s/envmaps/city.exr", data);
    if (!data || !file_exists(path)) {
        if (data) snprintf(path, sizeof path, "%s/envmaps", data);
        hl_test_skip_missing(data ? path : "HL_TEST_DATA");
        return;
    }
    hl_context *ctx = make_ctx();
    double worst_mean = 0.0;
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++) {
        snprintf(path, sizeof path, "%s/envmaps/%s.exr", data, files[k].name);
        hl_env *env = NULL;
        hl_env_stats st = {99, 99};
        double t0 = (double)clock();
        hl_result r = hl_env_load(ctx, path, &env, &st);
        double ms = ((double)clock() - t0) * 1000.0 / CLOCKS_PER_SEC;
        HL_CHECK(r == HL_OK, "%s: %s", path, hl_context_last_error(ctx));
        if (r != HL_OK) continue;
        HL_CHECK(env->width == 1024 && env->height == 512, "%s: %u x %u, expected 1024 x 512", path,
                 env->width, env->height);
        HL_CHECK(st.nonfinite_pixels == 0, "%s: %llu non-finite pixels, README says none", path,
                 (unsigned long long)st.nonfinite_pixels);
        HL_CHECK(st.negative_pixels == files[k].neg_px, "%s: %llu negative pixels, README says %llu", path,
                 (unsigned long long)st.negative_pixels, (unsigned long long)files[k].neg_px);
        uint32_t W = env->width, H = env->height;
        double num = 0.0, den = 0.0, best = -1.0;
        uint32_t bi = 0, bj = 0;
        size_t bad = 0;
        for (uint32_t j = 0; j < H; j++) {
            double s = sin(PI * (j + 0.5) / H);
            for (uint32_t i = 0; i < W; i++) {
                const float *p = env->rgb + 3 * ((size_t)j * W + i);
                for (int c = 0; c < 3; c++) bad += !isfinite(p[c]) || p[c] < 0.0f;
                double y = lum(p);
                num += s * y;
                den += s;
                if (y > best) {
                    best = y;
                    bi = i;
                    bj = j;
                }
            }
        }
        HL_CHECK(bad == 0, "%s: %zu channels still NaN, Inf or negative after loading", path, bad);
        double mean = num / den, e = fabs(mean - files[k].mean_omega) / files[k].mean_omega;
        if (e > worst_mean) worst_mean = e;
        printf("%-9s %ux%u neg %llu mean Y(omega) %.4f (README %.3f) brightest (%u,%u) Y %.1f, %.0f ms\n",
               files[k].name, W, H, (unsigned long long)st.negative_pixels, mean, files[k].mean_omega, bi,
               bj, best, ms);
        if (strcmp(files[k].name, "city") == 0)
            HL_CHECK(bi == 614 && bj == 120, "city.exr: brightest pixel at (%u,%u), README says (614,120)", bi, bj);
        hl_env_destroy(env);
    }
    hl_check_error("mean luminance (sin-theta weighted) against README (relative)", worst_mean, 0.01);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- bad_files */

/* Saves img to path and expects hl_env_load to refuse it, saying why. */
static void save_and_refuse(hl_context *ctx, const hl_image *img, const char *path, const char *what, const char *why)
{
    HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_OK, "save %s: %s", path, hl_context_last_error(ctx));
    expect_refused(ctx, path, HL_ERR_FORMAT, what);
    HL_CHECK(strstr(hl_context_last_error(ctx), why) != NULL, "%s: the message does not say \"%s\": %s", what, why,
             hl_context_last_error(ctx));
}

static void test_bad_files(void)
{
    hl_context *ctx = make_ctx();
    char dir[512], path[1024];
    scratch(dir, sizeof dir, "bad_files");

    snprintf(path, sizeof path, "%s/does_not_exist.exr", dir);
    expect_refused(ctx, path, HL_ERR_IO, "missing file");

    expect_refused(ctx, dir, HL_ERR_IO, "a folder");

    snprintf(path, sizeof path, "%s/empty.exr", dir);
    write_bytes(path, "", 0);
    expect_refused(ctx, path, HL_ERR_FORMAT, "empty file");

    uint8_t junk[4096];
    for (size_t i = 0; i < sizeof junk; i++) junk[i] = (uint8_t)hl_rng_next();
    snprintf(path, sizeof path, "%s/random.exr", dir);
    write_bytes(path, junk, sizeof junk);
    expect_refused(ctx, path, HL_ERR_FORMAT, "random bytes");
    /* Random bytes behind a valid magic number and version reach the
     * library's own header parser. */
    static const uint8_t magic[8] = {0x76, 0x2f, 0x31, 0x01, 0x02, 0x00, 0x00, 0x00};
    memcpy(junk, magic, sizeof magic);
    snprintf(path, sizeof path, "%s/random_magic.exr", dir);
    write_bytes(path, junk, sizeof junk);
    expect_refused(ctx, path, HL_ERR_FORMAT, "random bytes after the EXR magic");

    /* A valid EXR that is not 2:1, written by our own writer. */
    hl_image *img = NULL;
    HL_CHECK(hl_image_create(ctx, 6, 4, &img) == HL_OK, "hl_image_create 6x4");
    if (img) {
        snprintf(path, sizeof path, "%s/six_by_four.exr", dir);
        save_and_refuse(ctx, img, path, "valid EXR of 6 x 4", "6 x 4");
        hl_image_destroy(img);
    }

    /* Truncated and corrupted copies of a DWAB map: data/city.exr, a copy
     * of the shared envmaps/city.exr (CC0) committed with the repository. */
    const char *data = hl_test_env("HL_REPO_DATA", "data");
    char src[1024];
    if (data) snprintf(src, sizeof src, "%s/city.exr", data);
    size_t n = 0;
    uint8_t *bytes = data ? read_bytes(src, &n) : NULL;
    if (!bytes || n < 1000) {
        printf("bad_files: no data/city.exr; truncation and corruption skipped\n");
    } else {
        const size_t cuts[] = {4, 8, 100, 300, 1000, n / 4, n / 2, n - 1000, n - 1};
        for (size_t k = 0; k < sizeof cuts / sizeof cuts[0]; k++) {
            snprintf(path, sizeof path, "%s/city_cut_%zu.exr", dir, cuts[k]);
            write_bytes(path, bytes, cuts[k]);
            char what[64];
            snprintf(what, sizeof what, "city.exr cut to %zu of %zu bytes", cuts[k], n);
            expect_refused(ctx, path, HL_ERR_FORMAT, what);
            unlink(path);
        }
        /* Byte flips: the library may or may not notice a flip inside
         * compressed pixels; either way no crash, and what loads is
         * finite and >= 0. */
        snprintf(path, sizeof path, "%s/city_flipped.exr", dir);
        int refused = 0, loaded = 0;
        for (int k = 0; k < 40; k++) {
            size_t at = k < 20 ? (size_t)(hl_rng_next() % 400) : (size_t)(hl_rng_next() % n);
            uint8_t old = bytes[at];
            bytes[at] ^= (uint8_t)(1u + hl_rng_next() % 255u);
            write_bytes(path, bytes, n);
            bytes[at] = old;
            hl_env *env = NULL;
            hl_env_stats st;
            hl_result r = hl_env_load(ctx, path, &env, &st);
            if (r == HL_OK) {
                loaded++;
                size_t bad = 0;
                for (size_t i = 0; i < 3 * (size_t)env->width * env->height; i++)
                    bad += !isfinite(env->rgb[i]) || env->rgb[i] < 0.0f;
                HL_CHECK(bad == 0, "flip at byte %zu: %zu bad values", at, bad);
                HL_CHECK(env->width == 2 * env->height, "flip at byte %zu: %u x %u loaded", at, env->width,
                         env->height);
                hl_env_destroy(env);
            } else {
                refused++;
                HL_CHECK(strstr(hl_context_last_error(ctx), path) != NULL, "flip at byte %zu: message: %s", at,
                         hl_context_last_error(ctx));
            }
        }
        printf("40 single-byte corruptions of city.exr: %d refused, %d loaded (finite, >= 0)\n", refused, loaded);
        unlink(path);
        free(bytes);
    }

    /* Arguments. */
    hl_env *env = NULL;
    HL_CHECK(hl_env_load(ctx, NULL, &env, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL path accepted");
    HL_CHECK(hl_env_load(ctx, "", &env, NULL) == HL_ERR_INVALID_ARGUMENT, "empty path accepted");
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- nan_repair */

static void test_nan_repair(void)
{
    hl_context *ctx = make_ctx();
    const uint32_t W = 8, H = 4;
    float rgb[3 * 8 * 4];
    for (size_t i = 0; i < 3 * W * H; i++) rgb[i] = 0.25f + (float)i;
    rgb[0] = NAN;                /* pixel 0: NaN red */
    rgb[3 + 1] = INFINITY;       /* pixel 1: +Inf green */
    rgb[6 + 2] = -INFINITY;      /* pixel 2: -Inf blue */
    rgb[9 + 0] = -0.5f;          /* pixel 3: negative red */
    rgb[12 + 0] = NAN;           /* pixel 4: NaN red and negative blue */
    rgb[12 + 2] = -1.0f;
    rgb[15 + 1] = -0.0f;         /* pixel 5: -0 is not negative */
    rgb[18 + 0] = -1e-30f;       /* pixel 6: three tiny negatives */
    rgb[18 + 1] = -1e-30f;
    rgb[18 + 2] = -1e-30f;
    hl_env *env = NULL;
    hl_env_stats st = {99, 99};
    hl_result r = hl_env_create(ctx, W, H, rgb, &env, &st);
    HL_CHECK(r == HL_OK, "hl_env_create: %s", hl_context_last_error(ctx));
    if (r != HL_OK) return;
    HL_CHECK(st.nonfinite_pixels == 4, "non-finite pixels %llu, expected 4", (unsigned long long)st.nonfinite_pixels);
    HL_CHECK(st.negative_pixels == 3, "negative pixels %llu, expected 3", (unsigned long long)st.negative_pixels);
    int changed = 0, wrong = 0;
    for (size_t i = 0; i < 3 * W * H; i++) {
        float in = rgb[i], out = env->rgb[i];
        int repair = !isfinite(in) || in < 0.0f;
        /* Repaired channels are +0; the rest, -0 included, are untouched. */
        if (repair ? (out != 0.0f || signbit(out)) : memcmp(&in, &out, sizeof in) != 0) wrong++;
        changed += repair;
    }
    HL_CHECK(wrong == 0, "%d channels repaired wrongly", wrong);
    HL_CHECK(changed == 9, "%d channels needed repair, expected 9", changed);
    HL_CHECK(rgb[0] != rgb[0], "the caller's array was modified");
    /* A query on a repaired pixel is finite. */
    float w[3], q[3];
    dir_of_uv(0.5 / W, 0.5 / H, w);
    hl_env_query(env, w, 0.0f, q);
    HL_CHECK(q[0] == 0.0f && q[1] == rgb[1] && q[2] == rgb[2], "query of pixel 0 gave (%g, %g, %g)", (double)q[0],
             (double)q[1], (double)q[2]);
    hl_env_destroy(env);

    /* Sizes and arguments. */
    env = NULL;
    HL_CHECK(hl_env_create(ctx, 8, 8, rgb, &env, NULL) == HL_ERR_INVALID_ARGUMENT, "8 x 8 accepted");
    HL_CHECK(hl_env_create(ctx, 0, 0, rgb, &env, NULL) == HL_ERR_INVALID_ARGUMENT, "0 x 0 accepted");
    HL_CHECK(hl_env_create(ctx, 8, 4, NULL, &env, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL pixels accepted");
    HL_CHECK(env == NULL, "out set on failure");
    float one[6] = {1, 2, 3, 4, 5, 6};
    HL_CHECK(hl_env_create(ctx, 2, 1, one, &env, NULL) == HL_OK, "2 x 1 refused: %s", hl_context_last_error(ctx));
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- float_files */

/* The fixtures of tests/data/make_float_exr.py, written by another OpenEXR
 * writer: 32 x 16 float maps, pixel (x, y) = (x + 32 y) 0.001234567 (1, 2,
 * 3) rounded to float, and a sun at (20, 10). */
static float fixture_value(uint32_t x, uint32_t y, int c, const float sun[3])
{
    if (x == 20 && y == 10) return sun[c];
    return (float)(((double)x + 32.0 * y) * 0.001234567 * (c + 1.0));
}

/* Over the fixture's channels: the number not bit-equal to the written
 * floats (*differ) and the worst |got - want| / (|want| + 2^-14). */
static double fixture_worst(const hl_env *env, const float sun[3], size_t *differ)
{
    double worst = 0.0;
    *differ = 0;
    for (uint32_t y = 0; y < 16; y++)
        for (uint32_t x = 0; x < 32; x++)
            for (int c = 0; c < 3; c++) {
                float want = fixture_value(x, y, c, sun), got = env->rgb[3 * ((size_t)y * 32 + x) + (size_t)c];
                *differ += memcmp(&want, &got, sizeof want) != 0;
                worst = fmax(worst, fabs((double)got - want) / (fabs((double)want) + 0x1p-14));
            }
    return worst;
}

static void test_float_files(void)
{
    hl_context *ctx = make_ctx();
    const char *dir = hl_test_env("HL_TEST_FIXTURES", "tests/data");
    char path[1024];
    static const float big[3] = {1e5f, 2e5f, 3e5f}, mid[3] = {3e4f, 2e4f, 1e4f};

    /* A scanline float file: every value exactly, the sun beyond the half
       range included (read with OpenEXRCore). */
    snprintf(path, sizeof path, "%s/float_scanline_sun.exr", dir);
    hl_env *env = NULL;
    hl_env_stats st = {99, 99};
    hl_result r = hl_env_load(ctx, path, &env, &st);
    HL_CHECK(r == HL_OK, "%s: %s", path, hl_context_last_error(ctx));
    if (env) {
        size_t differ = 0;
        fixture_worst(env, big, &differ);
        printf("float scanline file: sun read as (%g, %g, %g); %llu pixels repaired\n",
               (double)env->rgb[3 * (10 * 32 + 20)], (double)env->rgb[3 * (10 * 32 + 20) + 1],
               (double)env->rgb[3 * (10 * 32 + 20) + 2],
               (unsigned long long)(st.nonfinite_pixels + st.negative_pixels));
        hl_check_error("float scanline file: channels not equal to the written floats", (double)differ, 0.0);
        HL_CHECK(st.nonfinite_pixels == 0 && st.negative_pixels == 0, "pixels repaired in a clean file");
        hl_env_destroy(env);
    }

    /* A tiled float file is read through half floats: within half's
       precision when the values fit... */
    snprintf(path, sizeof path, "%s/float_tiled.exr", dir);
    env = NULL;
    r = hl_env_load(ctx, path, &env, &st);
    HL_CHECK(r == HL_OK, "%s: %s", path, hl_context_last_error(ctx));
    if (env) {
        size_t differ = 0;
        double worst = fixture_worst(env, mid, &differ);
        hl_check_error("tiled float file, through half: |a - b| / (|a| + 2^-14)", worst, 0x1p-11);
        hl_env_destroy(env);
    }
    /* ...and refused, naming the file and the reason, when the halves
       cannot hold them: the sun would otherwise be lost. */
    snprintf(path, sizeof path, "%s/float_tiled_sun.exr", dir);
    expect_refused(ctx, path, HL_ERR_FORMAT, "tiled float file with a sun beyond the half range");
    HL_CHECK(strstr(hl_context_last_error(ctx), "65504") && strstr(hl_context_last_error(ctx), "tiled"),
             "the refusal does not say why: %s", hl_context_last_error(ctx));

    /* Beyond the float transforms' limit from a file: refused by value. */
    char scratch_dir[512];
    scratch(scratch_dir, sizeof scratch_dir, "float_files");
    hl_image *img = NULL;
    HL_CHECK(hl_image_create(ctx, 8, 4, &img) == HL_OK, "hl_image_create: %s", hl_context_last_error(ctx));
    if (img) {
        img->rgb[4] = 1e31f;
        snprintf(path, sizeof path, "%s/too_bright.exr", scratch_dir);
        save_and_refuse(ctx, img, path, "a channel of 1e31 in a float file", "brighter than");
        hl_image_destroy(img);
    }
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- sky */

static hl_env *sky(hl_context *ctx, float elev, float az, float size, float irr)
{
    hl_sky_desc d = {.sun_elevation_deg = elev, .sun_azimuth_deg = az, .sun_size_deg = size, .sun_irradiance = irr};
    hl_env *env = NULL;
    hl_result r = hl_env_create_sky(ctx, &d, &env);
    HL_CHECK(r == HL_OK, "sky elev %g az %g size %g: %s", (double)elev, (double)az, (double)size,
             hl_context_last_error(ctx));
    return env;
}

static void test_sky(void)
{
    hl_context *ctx = make_ctx();
    static const float sizes[] = {0.1f, 0.5f, 2.0f, 5.0f};
    static const float elevs[] = {35.0f, 1e-3f, 60.0f, 89.9f, -20.0f};
    static const float azs[] = {0.0f, 90.0f, 217.0f};
    const float E = 8.0f;
    double worst_energy = 0.0, worst_irr = 0.0, worst_dir = 0.0;
    int bad_values = 0;
    for (size_t a = 0; a < sizeof sizes / sizeof sizes[0]; a++)
        for (size_t b = 0; b < sizeof elevs / sizeof elevs[0]; b++)
            for (size_t c = 0; c < sizeof azs / sizeof azs[0]; c++) {
                if (c > 0 && b > 1) continue; /* every azimuth at two elevations */
                float el = elevs[b], az = azs[c], sz = sizes[a];
                hl_env *e1 = sky(ctx, el, az, sz, E), *e2 = sky(ctx, el, az, sz, 2.0f * E);
                if (!e1 || !e2) {
                    hl_env_destroy(e1);
                    hl_env_destroy(e2);
                    continue;
                }
                uint32_t W = e1->width, H = e1->height;
                HL_CHECK(W == 1024 && H == 512, "default sky size %u x %u", W, H);
                double er = el * PI / 180.0, ar = az * PI / 180.0;
                double s[3] = {cos(er) * cos(ar), sin(er), -cos(er) * sin(ar)};
                double energy = 0.0, irr = 0.0, m[3] = {0, 0, 0};
                for (uint32_t j = 0; j < H; j++) {
                    double om = pixel_omega(W, H, j);
                    for (uint32_t i = 0; i < W; i++) {
                        size_t p = 3 * ((size_t)j * W + i);
                        for (int k = 0; k < 3; k++)
                            bad_values += !isfinite(e2->rgb[p + (size_t)k]) || e2->rgb[p + (size_t)k] < 0.0f;
                        /* The sun alone: the sky is the same in both. */
                        double sun = (double)e2->rgb[p] - (double)e1->rgb[p];
                        if (sun == 0.0) continue;
                        float w[3];
                        dir_of_uv((i + 0.5) / W, (j + 0.5) / H, w);
                        double cosang = w[0] * s[0] + w[1] * s[1] + w[2] * s[2];
                        energy += sun * om;
                        irr += sun * om * (cosang > 0.0 ? cosang : 0.0);
                        for (int k = 0; k < 3; k++) m[k] += sun * om * w[k];
                    }
                }
                double ee = fabs(energy - E) / E, ei = fabs(irr - E) / E;
                double ml = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
                double dot = (m[0] * s[0] + m[1] * s[1] + m[2] * s[2]) / ml;
                double ang = acos(dot > 1.0 ? 1.0 : dot) * 180.0 / PI;
                if (ee > worst_energy) worst_energy = ee;
                if (ei > worst_irr) worst_irr = ei;
                if (ang > worst_dir) worst_dir = ang;
                if (ee > 0.01 || ei > 0.01 || ang > 0.36)
                    fprintf(stderr, "size %g elev %g az %g: energy %.5g irradiance %.5g direction off %.3g deg\n",
                            (double)sz, (double)el, (double)az, energy, irr, ang);
                /* The pixel that holds the sun's direction carries sun. */
                float sw[3] = {(float)s[0], (float)s[1], (float)s[2]}, q1[3], q2[3];
                hl_env_query(e1, sw, 0.0f, q1);
                hl_env_query(e2, sw, 0.0f, q2);
                HL_CHECK(q2[0] > q1[0], "size %g elev %g az %g: no sun at the sun's direction", (double)sz,
                         (double)el, (double)az);
                hl_env_destroy(e1);
                hl_env_destroy(e2);
            }
    HL_CHECK(bad_values == 0, "%d sky channels NaN, Inf or negative", bad_values);
    hl_check_error("sun energy sum(L dw) against sun_irradiance (relative)", worst_energy, 0.01);
    hl_check_error("sun irradiance on a surface facing it (relative)", worst_irr, 0.01);
    hl_check_error("sun direction: energy centroid against requested (degrees)", worst_dir, 0.36);

    /* Defaults: 1024 wide, sun at 35 degrees towards +X; sky above ground. */
    hl_env *d = NULL;
    HL_CHECK(hl_env_create_sky(ctx, NULL, &d) == HL_OK, "default sky: %s", hl_context_last_error(ctx));
    if (d) {
        HL_CHECK(d->width == 1024 && d->height == 512, "default sky %u x %u", d->width, d->height);
        float up[3] = {0, 1, 0}, down[3] = {0, -1, 0}, hor[3] = {0, 0.01f, 1}, sun[3], c0[3], c1[3], c2[3], c3[3];
        float e = (float)(35.0 * PI / 180.0);
        sun[0] = cosf(e);
        sun[1] = sinf(e);
        sun[2] = 0.0f;
        hl_env_query(d, up, 0.0f, c0);
        hl_env_query(d, down, 0.0f, c1);
        hl_env_query(d, hor, 0.0f, c2);
        hl_env_query(d, sun, 0.0f, c3);
        HL_CHECK(c0[2] > c0[0], "zenith is not blue: (%g, %g, %g)", (double)c0[0], (double)c0[1], (double)c0[2]);
        HL_CHECK(lum(c2) > lum(c1), "horizon not brighter than the ground");
        HL_CHECK(c3[0] > 1000.0f * c2[0], "no sun at 35 degrees towards +X: %g", (double)c3[0]);
        hl_env_destroy(d);
    }
    /* Refusals. */
    hl_sky_desc bad = {.sun_elevation_deg = 95.0f};
    HL_CHECK(hl_env_create_sky(ctx, &bad, &d) == HL_ERR_INVALID_ARGUMENT, "elevation 95 accepted");
    bad = (hl_sky_desc){.sun_size_deg = -1.0f};
    HL_CHECK(hl_env_create_sky(ctx, &bad, &d) == HL_ERR_INVALID_ARGUMENT, "size -1 accepted");
    bad = (hl_sky_desc){.sun_irradiance = NAN};
    HL_CHECK(hl_env_create_sky(ctx, &bad, &d) == HL_ERR_INVALID_ARGUMENT, "irradiance NaN accepted");
    bad = (hl_sky_desc){.width = 1023};
    HL_CHECK(hl_env_create_sky(ctx, &bad, &d) == HL_ERR_INVALID_ARGUMENT, "odd width accepted");
    bad = (hl_sky_desc){.ground = {-1, 0, 0}};
    HL_CHECK(hl_env_create_sky(ctx, &bad, &d) == HL_ERR_INVALID_ARGUMENT, "negative ground accepted");
    HL_CHECK(d == NULL, "out set on failure");
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"convention", test_convention},
        {"solid_angle", test_solid_angle},
        {"load_shared", test_load_shared},
        {"bad_files", test_bad_files},
        {"nan_repair", test_nan_repair},
        {"sky", test_sky},
        {"float_files", test_float_files},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
