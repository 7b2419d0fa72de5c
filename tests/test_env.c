/* test_env.c - environments, images and tone mapping (suite "env").
 *
 * Cases: convention (pins docs/CONVENTIONS.md: landmarks, every pixel centre, the
 * rotation sense), solid_angle (the pixel solid angles add up to 4pi and
 * match a numerical integral), load_shared (the eight shared maps against
 * the numbers in shared/data/README.md), bad_files (missing, empty, random,
 * truncated, bit-flipped, not 2:1, a folder: a non-OK code naming the file,
 * no crash), nan_repair (NaN/Inf/negative channels zeroed and counted),
 * float_files (32-bit float maps from another writer: exact where
 * OpenEXRCore reads them, suns beyond the half range refused where only
 * half floats can be had, 1e31 refused), hostile_headers (headers written
 * byte by byte that made OpenEXR's C++ reader allocate gigabytes: far data
 * windows, chunk tables beyond the file, tiny tiles, huge chunks and
 * attributes, a bad second part; each refused with the reason, loaded in a
 * child under a 1 GiB address-space limit whose peak RSS stays under
 * 100 MB; sound maps still load there), hostile_chunks (sound headers
 * with broken chunks written byte by byte: zeroed or far offset tables, no
 * data, packed sizes beyond the file, a short uncompressed chunk, tile
 * entries at other tiles in one-level, mipmap and ripmap files, a bad
 * second part, an entry into the offset tables, ZIP data that
 * decompresses short of its chunk in a scanline map, a tile and a first
 * part; each refused naming the part and the chunk, or the rows; the
 * sound maps they came from load exactly, and so does one of three half
 * channels with one not read),
 * sky (sun energy, irradiance and direction for several sizes, elevations
 * and azimuths), image_io (EXR round trip, bit for bit, PNG inflated and unfiltered
 * here and compared with hl_tonemap_srgb8, PNG compression ratios,
 * refused extensions, unwritable places, no temporary files left),
 * tonemap (known sRGB codes and exposure).
 * Depends on: haarlight_core (reference backend only), zlib (ZIP chunks
 * written by hostile_chunks), POSIX dirent/stat, fork/wait4/setrlimit.
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
#include <zlib.h>

#include "haarlight.h"
#include "hl_test.h"

#define PI 3.14159265358979323846

/* ---------------------------------------------------------------- helpers */

static hl_context *make_ctx(void) { return hl_test_ref_context(0); }

static const char *tmp_dir(void) { return hl_test_env("HL_TMP", "/tmp"); }

/* A fresh, empty scratch folder HL_TMP/env_<name>. */
static void scratch(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/env_%s", tmp_dir(), name);
    DIR *d = opendir(out);
    if (d) {
        struct dirent *e;
        char p[1024];
        while ((e = readdir(d))) {
            if (e->d_name[0] == '.') continue;
            snprintf(p, sizeof p, "%s/%s", out, e->d_name);
            chmod(p, 0755);
            unlink(p);
        }
        closedir(d);
    }
    mkdir(out, 0755);
}

/* Number of entries in a folder other than . and .. */
static int dir_entries(const char *path, const char *must_not_contain)
{
    DIR *d = opendir(path);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        n++;
        if (must_not_contain && strstr(e->d_name, must_not_contain))
            HL_CHECK(0, "%s: leftover %s", path, e->d_name);
    }
    closedir(d);
    return n;
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f) {
        HL_CHECK(0, "cannot create %s", path);
        return;
    }
    if (n) HL_CHECK(fwrite(p, 1, n, f) == n, "cannot write %s", path);
    fclose(f);
}

static uint8_t *read_bytes(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    *n = 0;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *p = malloc(len > 0 ? (size_t)len : 1);
    if (p && len > 0 && fread(p, 1, (size_t)len, f) != (size_t)len) {
        free(p);
        p = NULL;
    }
    fclose(f);
    if (p) *n = (size_t)len;
    return p;
}

/* docs/CONVENTIONS.md, "going the other way". */
static void dir_of_uv(double u, double v, float w[3])
{
    double phi = 2.0 * PI * (u - 0.5), theta = PI * v;
    w[0] = (float)(sin(theta) * cos(phi));
    w[1] = (float)cos(theta);
    w[2] = (float)(sin(theta) * sin(phi));
}

/* Right-handed rotation about +Y. */
static void rot_y(double deg, const float in[3], float out[3])
{
    double a = deg * PI / 180.0, c = cos(a), s = sin(a);
    double x = in[0], y = in[1], z = in[2];
    out[0] = (float)(x * c + z * s);
    out[1] = (float)y;
    out[2] = (float)(-x * s + z * c);
}

static double pixel_omega(uint32_t W, uint32_t H, uint32_t j)
{
    return (2.0 * PI / W) * (cos(PI * j / H) - cos(PI * (j + 1) / H));
}

/* An environment whose pixel (i, j) holds (i, j, 7). */
static hl_env *index_env(hl_context *ctx, uint32_t W, uint32_t H)
{
    float *rgb = malloc(sizeof(float) * 3 * W * H);
    for (uint32_t j = 0; j < H; j++)
        for (uint32_t i = 0; i < W; i++) {
            float *p = rgb + 3 * ((size_t)j * W + i);
            p[0] = (float)i;
            p[1] = (float)j;
            p[2] = 7.0f;
        }
    hl_env *env = NULL;
    hl_env_stats st;
    hl_result r = hl_env_create(ctx, W, H, rgb, &env, &st);
    free(rgb);
    if (r != HL_OK) {
        fprintf(stderr, "hl_env_create: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    return env;
}

/* Queries env at w and checks that it reads pixel (i, j). */
static int expect_pixel(const hl_env *env, float x, float y, float z, float rot, int i, int j, const char *what)
{
    float w[3] = {x, y, z}, c[3];
    hl_env_query(env, w, rot, c);
    int ok = (i < 0 || c[0] == (float)i) && c[1] == (float)j && c[2] == 7.0f; /* i < 0: any column */
    HL_CHECK(ok, "%s: direction (%g, %g, %g) rotate %g read pixel (%g, %g), expected (%d, %d)", what,
             (double)x, (double)y, (double)z, (double)rot, (double)c[0], (double)c[1], i, j);
    return ok;
}

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
        printf("load_shared: HL_TEST_DATA has no envmaps; skipped\n");
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

/* Loads path and expects failure with want (0: any error code) and a
 * message that names the file. Returns the code. */
static hl_result expect_refused(hl_context *ctx, const char *path, hl_result want, const char *what)
{
    hl_env *env = (hl_env *)(uintptr_t)1;
    hl_env_stats st;
    hl_result r = hl_env_load(ctx, path, &env, &st);
    const char *msg = hl_context_last_error(ctx);
    HL_CHECK(r != HL_OK, "%s: loaded without error", what);
    HL_CHECK(env == NULL, "%s: out not cleared on failure", what);
    if (r == HL_OK) hl_env_destroy(env);
    if (want != HL_OK) HL_CHECK(r == want, "%s: code %s, expected %s", what, hl_result_string(r), hl_result_string(want));
    HL_CHECK(strstr(msg, path) != NULL, "%s: message does not name the file: %s", what, msg);
    printf("%s: %s: %s\n", what, hl_result_string(r), msg);
    return r;
}

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

    /* Truncated and corrupted copies of a shared (DWAB) map. */
    const char *data = hl_test_env("HL_TEST_DATA", NULL);
    char src[1024];
    if (data) snprintf(src, sizeof src, "%s/envmaps/city.exr", data);
    size_t n = 0;
    uint8_t *bytes = data ? read_bytes(src, &n) : NULL;
    if (!bytes || n < 1000) {
        printf("bad_files: no shared city.exr; truncation and corruption skipped\n");
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

/* ---------------------------------------------------------------- hostile_headers */

/* OpenEXR bytes written field by field (little-endian), for headers no
 * library would write. */
typedef struct exr_bytes {
    uint8_t *p;
    size_t n, cap;
} exr_bytes;

static void eb_put(exr_bytes *b, const void *src, size_t n)
{
    if (b->n + n > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->n + n) cap *= 2;
        uint8_t *p = realloc(b->p, cap);
        if (!p) {
            fprintf(stderr, "out of memory building a test file\n");
            exit(1);
        }
        b->p = p;
        b->cap = cap;
    }
    memcpy(b->p + b->n, src, n);
    b->n += n;
}

static void eb_u8(exr_bytes *b, unsigned v)
{
    uint8_t c = (uint8_t)v;
    eb_put(b, &c, 1);
}

static void eb_i32(exr_bytes *b, int64_t v)
{
    uint32_t u = (uint32_t)v;
    for (int k = 0; k < 4; k++) eb_u8(b, (u >> (8 * k)) & 255u);
}

static void eb_f32(exr_bytes *b, float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    eb_i32(b, u);
}

static void eb_str(exr_bytes *b, const char *s) { eb_put(b, s, strlen(s) + 1); }

static void eb_zeros(exr_bytes *b, size_t n)
{
    for (size_t i = 0; i < n; i++) eb_u8(b, 0);
}

/* An attribute's name, type and declared size; the value follows. */
static void eb_attr(exr_bytes *b, const char *name, const char *type, int64_t size)
{
    eb_str(b, name);
    eb_str(b, type);
    eb_i32(b, size);
}

enum { EB_TILED = 0x200, EB_MULTIPART = 0x1000 };
enum { EB_HALF = 1, EB_FLOAT = 2 };
enum { EB_NONE = 0, EB_ZIP = 3, EB_PIZ = 4 };

/* Magic number, then version 2 with flags. */
static void eb_start(exr_bytes *b, unsigned flags)
{
    static const uint8_t magic[4] = {0x76, 0x2f, 0x31, 0x01};
    eb_put(b, magic, sizeof magic);
    eb_i32(b, 2 | (int64_t)flags);
}

/* "channels": n channels of pixel type t, named (sorted, as the format
 * wants) B, G, R when n is 3, R when n is 1, else c00000, c00001, ... */
static void eb_channels(exr_bytes *b, int n, int t)
{
    static const char *const rgb[3] = {"B", "G", "R"};
    const int letters = n == 1 || n == 3;
    char name[16];
    eb_attr(b, "channels", "chlist", (int64_t)n * (16 + (letters ? 2 : 7)) + 1);
    for (int i = 0; i < n; i++) {
        snprintf(name, sizeof name, "c%05d", i);
        eb_str(b, letters ? rgb[3 - n + i] : name);
        eb_i32(b, t);
        eb_zeros(b, 4); /* pLinear, reserved */
        eb_i32(b, 1);   /* x and y sampling */
        eb_i32(b, 1);
    }
    eb_u8(b, 0);
}

static void eb_box(exr_bytes *b, const char *name, int64_t x0, int64_t y0, int64_t x1, int64_t y1)
{
    eb_attr(b, name, "box2i", 16);
    eb_i32(b, x0);
    eb_i32(b, y0);
    eb_i32(b, x1);
    eb_i32(b, y1);
}

/* Every attribute a part must have, with a 16 x 8 display window. */
static void eb_required(exr_bytes *b, int channels, int type, unsigned compression, int64_t x0, int64_t y0,
                        int64_t x1, int64_t y1)
{
    eb_channels(b, channels, type);
    eb_attr(b, "compression", "compression", 1);
    eb_u8(b, compression);
    eb_box(b, "dataWindow", x0, y0, x1, y1);
    eb_box(b, "displayWindow", 0, 0, 15, 7);
    eb_attr(b, "lineOrder", "lineOrder", 1);
    eb_u8(b, 0);
    eb_attr(b, "pixelAspectRatio", "float", 4);
    eb_f32(b, 1.0f);
    eb_attr(b, "screenWindowCenter", "v2f", 8);
    eb_f32(b, 0.0f);
    eb_f32(b, 0.0f);
    eb_attr(b, "screenWindowWidth", "float", 4);
    eb_f32(b, 1.0f);
}

static void eb_tiles(exr_bytes *b, uint32_t w, uint32_t h, unsigned mode)
{
    eb_attr(b, "tiles", "tiledesc", 9);
    eb_i32(b, w);
    eb_i32(b, h);
    eb_u8(b, mode);
}

/* Corners far outside any image, yet inside what both OpenEXR readers
 * accept (|corner| < 2^30 - 1): 2^31 - 3 rows and columns. */
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
static void eb_part_compressed(exr_bytes *b, const char *name, unsigned compression, int64_t x0, int64_t y0,
                               int64_t x1, int64_t y1, int64_t chunks)
{
    eb_required(b, 3, EB_HALF, compression, x0, y0, x1, y1);
    eb_attr(b, "name", "string", (int64_t)strlen(name));
    eb_put(b, name, strlen(name));
    eb_attr(b, "type", "string", 13);
    eb_put(b, "scanlineimage", 13);
    eb_attr(b, "chunkCount", "int", 4);
    eb_i32(b, chunks);
    eb_u8(b, 0);
}
static void eb_part(exr_bytes *b, const char *name, int64_t x0, int64_t y0, int64_t x1, int64_t y1, int64_t chunks)
{
    eb_part_compressed(b, name, EB_ZIP, x0, y0, x1, y1, chunks);
}
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

/* ---------------------------------------------------------------- hostile_chunks */

/* Sound 16 x 8 maps written byte by byte, uncompressed half R, G, B, so
 * that every chunk can be placed and broken by hand. Pixel (x, y) channel c
 * (0: R) is (x + 16 y + 1) (c + 1) / 64, exact in half. */
static float chunk_value(int x, int y, int c) { return (float)((x + 16 * y + 1) * (c + 1)) / 64.0f; }

/* v: a normal float that half holds exactly. */
static unsigned half_bits(float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    return ((u >> 16) & 0x8000u) | ((((u >> 23) & 0xffu) - 112u) << 10) | ((u >> 13) & 0x3ffu);
}

/* Rows y of columns x0..x0+w-1, as an uncompressed chunk stores them:
   each row holds B, then G, then R (the channels' sorted order). */
static void eb_pixels(exr_bytes *b, int x0, int w, int y0, int h)
{
    for (int y = y0; y < y0 + h; y++)
        for (int c = 2; c >= 0; c--)
            for (int x = x0; x < x0 + w; x++) {
                unsigned bits = half_bits(chunk_value(x, y, c));
                eb_u8(b, bits & 255u);
                eb_u8(b, bits >> 8);
            }
}

static void put_u64(uint8_t *p, uint64_t v)
{
    for (int k = 0; k < 8; k++) p[k] = (uint8_t)(v >> (8 * k));
}

static void put_u32(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; k++) p[k] = (uint8_t)(v >> (8 * k));
}

/* Where a written file keeps its offset tables and chunks. */
typedef struct chunk_file {
    exr_bytes b;
    size_t table[2];     /* byte where each part's offset table starts */
    size_t chunk[2][32]; /* byte where each chunk (its header) starts */
    int tile[32][4];     /* tiled: each chunk's tile x, y and level x, y */
    int tiles;
} chunk_file;

/* One part (parts == 1) of 16 x 8, or two: 16 x 8 and 16 x rows1. One row
 * a chunk, 96 bytes; the first chunk of part 0 holds first_bytes of them
 * (and says so). The tables point at the chunks. */
static void cf_scanline(chunk_file *cf, int parts, int rows1, int first_bytes)
{
    exr_bytes *b = &cf->b;
    const int rows[2] = {8, rows1};
    eb_start(b, parts > 1 ? EB_MULTIPART : 0);
    if (parts == 1) {
        eb_required(b, 3, EB_HALF, EB_NONE, 0, 0, 15, 7);
        eb_u8(b, 0);
    } else {
        eb_part_compressed(b, "map", EB_NONE, 0, 0, 15, 7, 8);
        eb_part_compressed(b, "other", EB_NONE, 0, 0, 15, rows1 - 1, rows1);
        eb_u8(b, 0);
    }
    for (int p = 0; p < parts; p++) {
        cf->table[p] = b->n;
        eb_zeros(b, 8 * (size_t)rows[p]);
    }
    for (int p = 0; p < parts; p++)
        for (int y = 0; y < rows[p]; y++) {
            cf->chunk[p][y] = b->n;
            if (parts > 1) eb_i32(b, p);
            eb_i32(b, y);
            int bytes = p == 0 && y == 0 ? first_bytes : 96;
            eb_i32(b, bytes);
            size_t at = b->n;
            eb_pixels(b, 0, 16, y, 1);
            b->n = at + (size_t)bytes; /* a short chunk keeps only its first bytes */
        }
    for (int p = 0; p < parts; p++)
        for (int y = 0; y < rows[p]; y++) put_u64(b->p + cf->table[p] + 8 * (size_t)y, cf->chunk[p][y]);
}

/* 16 x 8 in 8 x 8 tiles, rounded down: one level (mode 0: two tiles),
 * mipmap levels (1: 16 x 8 to 1 x 1, six tiles) or ripmap levels (2: 5 x 4
 * levels, 24 tiles), in the table's order. Pixel (x, y) of every level
 * holds chunk_value(x, y, c). */
static void cf_tiled(chunk_file *cf, unsigned mode)
{
    exr_bytes *b = &cf->b;
    const int nlx = mode ? 5 : 1, nly = mode == 2 ? 4 : mode ? 5 : 1;
    eb_start(b, EB_TILED);
    eb_required(b, 3, EB_HALF, EB_NONE, 0, 0, 15, 7);
    eb_tiles(b, 8, 8, mode);
    eb_u8(b, 0);
    cf->tiles = 0;
    for (int ly = 0; ly < nly; ly++)
        for (int lx = 0; lx < nlx; lx++) {
            if (mode != 2 && lx != ly) continue;
            int lw = 16 >> lx > 0 ? 16 >> lx : 1, lh = 8 >> ly > 0 ? 8 >> ly : 1;
            for (int ty = 0; ty < (lh + 7) / 8; ty++)
                for (int tx = 0; tx < (lw + 7) / 8; tx++) {
                    int *t = cf->tile[cf->tiles++];
                    t[0] = tx, t[1] = ty, t[2] = lx, t[3] = ly;
                }
        }
    cf->table[0] = b->n;
    eb_zeros(b, 8 * (size_t)cf->tiles);
    for (int i = 0; i < cf->tiles; i++) {
        const int *t = cf->tile[i];
        int lw = 16 >> t[2] > 0 ? 16 >> t[2] : 1, lh = 8 >> t[3] > 0 ? 8 >> t[3] : 1;
        int w = lw - 8 * t[0] < 8 ? lw - 8 * t[0] : 8, h = lh - 8 * t[1] < 8 ? lh - 8 * t[1] : 8;
        cf->chunk[0][i] = b->n;
        for (int k = 0; k < 4; k++) eb_i32(b, t[k]);
        eb_i32(b, w * h * 3 * 2);
        eb_pixels(b, 8 * t[0], w, 8 * t[1], h);
    }
    for (int i = 0; i < cf->tiles; i++) put_u64(b->p + cf->table[0] + 8 * (size_t)i, cf->chunk[0][i]);
}

/* The chunk index of a tile of cf_tiled. */
static int cf_tile_index(const chunk_file *cf, int tx, int ty, int lx, int ly)
{
    for (int i = 0; i < cf->tiles; i++)
        if (cf->tile[i][0] == tx && cf->tile[i][1] == ty && cf->tile[i][2] == lx && cf->tile[i][3] == ly) return i;
    fprintf(stderr, "no tile (%d, %d) level (%d, %d)\n", tx, ty, lx, ly);
    exit(1);
}

static void cf_tiled_one(chunk_file *cf) { cf_tiled(cf, 0); }
static void cf_tiled_mipmap(chunk_file *cf) { cf_tiled(cf, 1); }
static void cf_tiled_ripmap(chunk_file *cf) { cf_tiled(cf, 2); }

/* A ZIP chunk's packed size and data, as OpenEXR stores n bytes of pixels
 * (raw, in eb_pixels' order): the bytes split into the even ones, then the
 * odd ones; each then stored as its difference from the one before plus
 * 128 (mod 256); then deflated (zlib). Only the first keep of the n
 * transformed bytes go into the stream: a sound zlib stream that
 * decompresses to keep bytes, short of the chunk when keep < n. */
static void eb_zip_chunk(exr_bytes *b, const uint8_t *raw, size_t n, size_t keep)
{
    uint8_t *t = malloc(n);
    uLongf packed = compressBound((uLong)n);
    uint8_t *z = malloc(packed);
    if (!t || !z) {
        fprintf(stderr, "out of memory building a test file\n");
        exit(1);
    }
    for (size_t i = 0; i < n; i++) t[i % 2 ? (n + 1) / 2 + i / 2 : i / 2] = raw[i];
    for (size_t i = n; i-- > 1;) t[i] = (uint8_t)(t[i] - t[i - 1] + 128u);
    if (compress2(z, &packed, t, (uLong)keep, 9) != Z_OK) {
        fprintf(stderr, "zlib cannot compress a test chunk\n");
        exit(1);
    }
    eb_i32(b, (int64_t)packed);
    eb_put(b, z, packed);
    free(t);
    free(z);
}

/* The 16 x 8 map in ZIP chunks, laid out as layout says: 0 one scanline
 * part (one chunk: a ZIP chunk has 16 rows), 1 one tiled part of two 8 x 8
 * tiles, 2 two scanline parts (one chunk each). The first chunk
 * decompresses to only keep bytes when keep > 0 (eb_zip_chunk). */
static void cf_zip(chunk_file *cf, int layout, size_t keep)
{
    exr_bytes *b = &cf->b, raw = {NULL, 0, 0};
    const int chunks = layout == 0 ? 1 : 2;
    eb_start(b, layout == 1 ? EB_TILED : layout == 2 ? EB_MULTIPART : 0);
    if (layout == 2) {
        eb_part_compressed(b, "map", EB_ZIP, 0, 0, 15, 7, 1);
        eb_part_compressed(b, "other", EB_ZIP, 0, 0, 15, 7, 1);
    } else {
        eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
        if (layout == 1) eb_tiles(b, 8, 8, 0);
    }
    eb_u8(b, 0);
    const size_t table = b->n; /* both parts' tables, one entry each, are adjacent */
    eb_zeros(b, 8 * (size_t)chunks);
    for (int i = 0; i < chunks; i++) {
        put_u64(b->p + table + 8 * (size_t)i, b->n);
        raw.n = 0;
        if (layout == 1) {
            for (int k = 0; k < 4; k++) eb_i32(b, k == 0 ? i : 0); /* tile (i, 0), level (0, 0) */
            eb_pixels(&raw, 8 * i, 8, 0, 8);
        } else {
            if (layout == 2) eb_i32(b, i); /* the part */
            eb_i32(b, 0);                  /* the first row */
            eb_pixels(&raw, 0, 16, 0, 8);
        }
        eb_zip_chunk(b, raw.p, raw.n, i == 0 && keep > 0 ? keep : raw.n);
    }
    free(raw.p);
}
/* The uncompressed scanline map with its R channel renamed Z (still sorted
 * last): three half channels, B and G read, Z not (R reads 0). The shape
 * of a fuzzer's file on which OpenEXRCore 3.1.5 wrote the unread channel
 * through a NULL pointer once half files went to it. */
static void cf_unread_third_channel(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    /* the magic and version, "channels", "chlist", the size, B and G */
    const size_t r = 8 + sizeof "channels" + sizeof "chlist" + 4 + 2 * (2 + 16);
    if (cf->b.n <= r || cf->b.p[r] != 'R' || cf->b.p[r + 1] != 0) {
        fprintf(stderr, "no R channel at byte %zu of the test map\n", r);
        exit(1);
    }
    cf->b.p[r] = 'Z';
}
static void cf_zip_scanline(chunk_file *cf) { cf_zip(cf, 0, 0); }
static void cf_zip_tiled(chunk_file *cf) { cf_zip(cf, 1, 0); }
static void cf_zip_two_parts(chunk_file *cf) { cf_zip(cf, 2, 0); }

/* A 16 x 8 ZIP header (one chunk of 16 rows) and its offset table of one
 * zero entry: the shape of regress/env/openexr-zip-chunk-without-data. */
static void hc_zip_zeroed_table(chunk_file *cf)
{
    eb_start(&cf->b, 0);
    eb_required(&cf->b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
    eb_u8(&cf->b, 0);
    eb_zeros(&cf->b, 8);
}
/* The same header, the table pointing at a chunk header that declares
 * 700 bytes of ZIP data, and 16 of them. */
static void hc_zip_packed_beyond_file(chunk_file *cf)
{
    exr_bytes *b = &cf->b;
    eb_start(b, 0);
    eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
    eb_u8(b, 0);
    size_t table = b->n;
    eb_zeros(b, 8);
    put_u64(b->p + table, b->n);
    eb_i32(b, 0);
    eb_i32(b, 700);
    eb_zeros(b, 16);
}
/* The uncompressed map's header and zeroed table, no chunk data at all. */
static void hc_zeroed_table(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    cf->b.n = cf->chunk[0][0];
    memset(cf->b.p + cf->table[0], 0, 64);
}
/* Every entry a little past the end of the file. */
static void hc_offsets_past_end(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    for (int y = 0; y < 8; y++) put_u64(cf->b.p + cf->table[0] + 8 * (size_t)y, cf->b.n + 16 * (size_t)y);
}
/* Only the last chunk is bad: the file ends 10 bytes before its data does. */
static void hc_last_chunk_truncated(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    cf->b.n -= 10;
}
/* Only the last chunk is bad: its entry is zero. */
static void hc_last_entry_zeroed(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    put_u64(cf->b.p + cf->table[0] + 8 * 7, 0);
}
/* The first chunk declares more data than there is to the end of the file. */
static void hc_packed_beyond_file(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    put_u32(cf->b.p + cf->chunk[0][0] + 4, (uint32_t)(cf->b.n - cf->chunk[0][0]));
}
/* An uncompressed chunk that holds 48 of its 96 bytes. */
static void hc_short_uncompressed(chunk_file *cf) { cf_scanline(cf, 1, 0, 48); }
/* Tiled: the second tile's entry points at the first tile. */
static void hc_tile_entry(chunk_file *cf)
{
    cf_tiled(cf, 0);
    put_u64(cf->b.p + cf->table[0] + 8 * (size_t)cf_tile_index(cf, 1, 0, 0, 0), cf->chunk[0][0]);
}
/* Tiled: the last tile's entry points past the end of the file. */
static void hc_last_tile_past_end(chunk_file *cf)
{
    cf_tiled(cf, 0);
    put_u64(cf->b.p + cf->table[0] + 8 * (size_t)cf_tile_index(cf, 1, 0, 0, 0), cf->b.n + 1000);
}
/* Mipmap: the last level's tile declares no data. */
static void hc_mipmap_last_tile_empty(chunk_file *cf)
{
    cf_tiled(cf, 1);
    put_u32(cf->b.p + cf->chunk[0][cf_tile_index(cf, 0, 0, 4, 4)] + 16, 0);
}
/* Ripmap: level (1, 1)'s tile entry points at the tile of level (0, 1)
 * (OpenEXRCore 3.1 cannot look these tiles up: checked by exr_io.c). */
static void hc_ripmap_tile_entry(chunk_file *cf)
{
    cf_tiled(cf, 2);
    put_u64(cf->b.p + cf->table[0] + 8 * (size_t)cf_tile_index(cf, 0, 0, 1, 1),
            cf->chunk[0][cf_tile_index(cf, 0, 0, 0, 1)]);
}
/* Two parts: part 0 sound, one entry of part 1 zero. */
static void hc_second_part_entry(chunk_file *cf)
{
    cf_scanline(cf, 2, 8, 96);
    put_u64(cf->b.p + cf->table[1] + 8 * 3, 0);
}
/* Two parts: part 0's first entry points into part 1's offset table,
 * whose two entries (0 and 96) read there as a sound chunk header: part 0,
 * row 0, 96 bytes. Past part 0's own table, so OpenEXRCore's bound alone
 * lets it through. */
static void hc_entry_into_tables(chunk_file *cf)
{
    cf_scanline(cf, 2, 2, 96);
    put_u64(cf->b.p + cf->table[1], 0);
    put_u64(cf->b.p + cf->table[1] + 8, 96);
    put_u64(cf->b.p + cf->table[0], cf->table[1]);
}

/* ZIP chunks whose data is a sound zlib stream that decompresses to fewer
 * bytes than the chunk's pixels: 100 of the 768 of a scanline map's one
 * chunk, 100 of the 384 of a tiled map's first tile, and 100 of the 768 of
 * the first part's chunk in a file of two parts. The C++ reader loads all
 * three without an error (the rest of the pixels from its uninitialised
 * buffer). */
static void hc_zip_short(chunk_file *cf) { cf_zip(cf, 0, 100); }
static void hc_zip_tile_short(chunk_file *cf) { cf_zip(cf, 1, 100); }
static void hc_zip_part_short(chunk_file *cf) { cf_zip(cf, 2, 100); }

static void test_hostile_chunks(void)
{
    static const struct {
        const char *name;
        void (*make)(chunk_file *);
        const char *chunk, *why; /* the refusal names the chunk and says why */
    } shapes[] = {
        {"zip_zeroed_table_no_data", hc_zip_zeroed_table, "part 0, chunk of rows 0..7", "points at byte 0, inside the header"},
        {"zip_packed_size_beyond_file", hc_zip_packed_beyond_file, "part 0, chunk of rows 0..7", "packed size 700"},
        {"zeroed_table_no_data", hc_zeroed_table, "part 0, chunk of rows 0..0", "points at byte 0, inside the header"},
        {"offsets_past_end", hc_offsets_past_end, "part 0, chunk of rows 0..0", "but the file ends"},
        {"packed_size_beyond_file", hc_packed_beyond_file, "part 0, chunk of rows 0..0", "packed"},
        {"last_chunk_truncated", hc_last_chunk_truncated, "part 0, chunk of rows 7..7", "packed size 96"},
        {"last_entry_zeroed", hc_last_entry_zeroed, "part 0, chunk of rows 7..7", "points at byte 0, inside the header"},
        {"uncompressed_chunk_short", hc_short_uncompressed, "part 0, chunk of rows 0..0", "holds 48"},
        {"tile_entry_at_other_tile", hc_tile_entry, "part 0, tile (1, 0) level (0, 0)", "tile x coordinate"},
        {"last_tile_past_end", hc_last_tile_past_end, "part 0, tile (1, 0) level (0, 0)", "but the file ends"},
        {"mipmap_last_tile_empty", hc_mipmap_last_tile_empty, "part 0, tile (0, 0) level (4, 4)", "packed size"},
        {"ripmap_tile_entry_at_other_level", hc_ripmap_tile_entry, "part 0, tile (0, 0) level (1, 1)",
         "says tile (0, 0) level (0, 1)"},
        {"second_part_entry_zeroed", hc_second_part_entry, "part 1, chunk of rows 3..3", "points at byte 0, inside the header"},
        {"entry_into_offset_tables", hc_entry_into_tables, "part 0, chunk of rows 0..0",
         "inside the header and offset tables"},
        {"zip_chunk_decompresses_short", hc_zip_short, "pixel data in rows 0..7", "of ZIP data for 768 bytes of pixels"},
        {"zip_tile_decompresses_short", hc_zip_tile_short, "part 0, tile (0, 0) level (0, 0)",
         "of ZIP data for 384 bytes of pixels"},
        {"zip_first_part_decompresses_short", hc_zip_part_short, "part 0, chunk of rows 0..7",
         "of ZIP data for 768 bytes of pixels"},
    };
    hl_context *ctx = make_ctx();
    char dir[512], path[1024];
    scratch(dir, sizeof dir, "hostile_chunks");
    int refused = 0;
    for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) {
        chunk_file cf;
        memset(&cf, 0, sizeof cf);
        shapes[i].make(&cf);
        snprintf(path, sizeof path, "%s/%s.exr", dir, shapes[i].name);
        write_bytes(path, cf.b.p, cf.b.n);
        free(cf.b.p);
        char what[128];
        snprintf(what, sizeof what, "%s (%zu bytes)", shapes[i].name, cf.b.n);
        hl_result r = expect_refused(ctx, path, HL_ERR_FORMAT, what);
        const char *msg = hl_context_last_error(ctx);
        int named = strstr(msg, shapes[i].chunk) != NULL, said = strstr(msg, shapes[i].why) != NULL;
        HL_CHECK(named, "%s: the message does not name \"%s\": %s", shapes[i].name, shapes[i].chunk, msg);
        HL_CHECK(said, "%s: the message does not say \"%s\": %s", shapes[i].name, shapes[i].why, msg);
        refused += r == HL_ERR_FORMAT && named && said;
    }
    printf("hostile chunks refused with the chunk and the reason: %d of %zu\n", refused,
           sizeof shapes / sizeof shapes[0]);

    /* The sound maps these were made from load, every value exact (the
       multi-part one reads its part 0; the one without R reads 0 there);
       so do the float fixtures. */
    static const struct {
        const char *name;
        void (*make)(chunk_file *);
    } sound[] = {{"sound_scanline", NULL},
                 {"sound_two_parts", NULL},
                 {"sound_tiled", cf_tiled_one},
                 {"sound_tiled_mipmap", cf_tiled_mipmap},
                 {"sound_tiled_ripmap", cf_tiled_ripmap},
                 {"sound_zip", cf_zip_scanline},
                 {"sound_zip_tiled", cf_zip_tiled},
                 {"sound_zip_two_parts", cf_zip_two_parts},
                 {"sound_unread_third_channel", cf_unread_third_channel}};
    double worst = 0.0;
    for (size_t i = 0; i < sizeof sound / sizeof sound[0]; i++) {
        chunk_file cf;
        memset(&cf, 0, sizeof cf);
        if (sound[i].make) sound[i].make(&cf);
        else cf_scanline(&cf, i == 0 ? 1 : 2, 8, 96);
        snprintf(path, sizeof path, "%s/%s.exr", dir, sound[i].name);
        write_bytes(path, cf.b.p, cf.b.n);
        free(cf.b.p);
        hl_env *env = NULL;
        hl_env_stats st;
        hl_result r = hl_env_load(ctx, path, &env, &st);
        HL_CHECK(r == HL_OK, "%s: not loaded: %s", path, hl_context_last_error(ctx));
        if (r != HL_OK) continue;
        double w = 0.0;
        HL_CHECK(env->width == 16 && env->height == 8, "%s: %u x %u", path, env->width, env->height);
        for (int y = 0; y < 8 && env->width == 16 && env->height == 8; y++)
            for (int x = 0; x < 16; x++)
                for (int c = 0; c < 3; c++) {
                    double want = c == 0 && sound[i].make == cf_unread_third_channel ? 0.0 : chunk_value(x, y, c);
                    w = fmax(w, fabs((double)env->rgb[3 * (16 * y + x) + c] - want));
                }
        printf("%s (%zu bytes): loaded, worst |value - written| %g\n", sound[i].name, cf.b.n, w);
        worst = fmax(worst, w);
        hl_env_destroy(env);
    }
    hl_check_error("sound maps written byte by byte: |value - written|", worst, 0.0);
    const char *fixtures[2] = {"float_scanline_sun.exr", "float_tiled.exr"};
    for (int k = 0; k < 2; k++) {
        snprintf(path, sizeof path, "%s/%s", hl_test_env("HL_TEST_FIXTURES", "tests/data"), fixtures[k]);
        hl_env *env = NULL;
        hl_env_stats st;
        hl_result r = hl_env_load(ctx, path, &env, &st);
        printf("fixture %s: %s\n", path, r == HL_OK ? "loaded" : hl_context_last_error(ctx));
        HL_CHECK(r == HL_OK, "%s: not loaded: %s", path, hl_context_last_error(ctx));
        hl_env_destroy(env);
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

/* ---------------------------------------------------------------- image_io */

static uint32_t be32(const uint8_t *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }


/* ---- A small inflater (RFC 1950/1951) for the PNG checks: stored, fixed
 * and dynamic blocks, every read bounds-checked; a failure sets err. */
typedef struct inflater {
    const uint8_t *in;
    size_t n, pos; /* pos in bits */
    uint8_t *out;
    size_t cap, got;
    int err;
    const char *why;
} inflater;

typedef struct huff {
    uint16_t count[16];  /* codes of each length */
    uint16_t symbol[320]; /* symbols in canonical order */
} huff;

static uint32_t inf_bits(inflater *s, unsigned k)
{
    uint32_t v = 0;
    for (unsigned i = 0; i < k; i++) {
        if (s->pos >= 8 * s->n) {
            s->err = 1;
            s->why = "input ends inside a block";
            return 0;
        }
        v |= (uint32_t)(s->in[s->pos >> 3] >> (s->pos & 7) & 1u) << i;
        s->pos++;
    }
    return v;
}

/* Builds the decoding table; 0 for an over-subscribed set, or an
 * incomplete one other than a single code of length 1. */
static int huff_build(huff *h, const uint8_t *len, unsigned n)
{
    memset(h->count, 0, sizeof h->count);
    for (unsigned s = 0; s < n; s++) h->count[len[s]]++;
    uint16_t offs[16];
    int left = 1, used = (int)(n - h->count[0]);
    for (unsigned l = 1; l < 16; l++) {
        left = 2 * left - h->count[l];
        if (left < 0) return 0;
    }
    if (left > 0 && used != 1) return 0;
    offs[1] = 0;
    for (unsigned l = 1; l < 15; l++) offs[l + 1] = (uint16_t)(offs[l] + h->count[l]);
    for (unsigned s = 0; s < n; s++)
        if (len[s]) h->symbol[offs[len[s]]++] = (uint16_t)s;
    return 1;
}

/* One symbol, reading a bit at a time (codes are MSB first). */
static int huff_decode(inflater *s, const huff *h)
{
    int code = 0, first = 0, index = 0;
    for (unsigned l = 1; l < 16; l++) {
        code |= (int)inf_bits(s, 1);
        int c = h->count[l];
        if (code - first < c) return h->symbol[index + code - first];
        index += c;
        first = (first + c) << 1;
        code <<= 1;
    }
    s->err = 1;
    s->why = "invalid Huffman code";
    return -1;
}

static void inf_codes(inflater *s, const huff *lit, const huff *dist, int *counts)
{
    static const uint16_t lbase[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,  15,  17,  19,  23, 27,
                                       31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258};
    static const uint8_t lext[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
    static const uint16_t dbase[30] = {1,   2,   3,   4,   5,   7,    9,    13,   17,   25,   33,   49,   65,    97,    129,
                                       193, 257, 385, 513, 769, 1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
    static const uint8_t dext[30] = {0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};
    for (;;) {
        int sym = huff_decode(s, lit);
        if (s->err) return;
        if (sym < 256) {
            if (s->got >= s->cap) break;
            s->out[s->got++] = (uint8_t)sym;
            counts[0]++;
            continue;
        }
        if (sym == 256) return;
        sym -= 257;
        if (sym >= 29) break;
        size_t len = lbase[sym] + inf_bits(s, lext[sym]);
        int ds = huff_decode(s, dist);
        if (s->err) return;
        if (ds >= 30) break;
        size_t d = dbase[ds] + inf_bits(s, dext[ds]);
        if (d > s->got || s->got + len > s->cap) break;
        for (size_t i = 0; i < len; i++, s->got++) s->out[s->got] = s->out[s->got - d];
        counts[1]++;
    }
    s->err = 1;
    s->why = "bad length/distance, or output beyond the image";
}

/* Inflates the raw deflate data in[0..n) into out (cap bytes). Returns the
 * byte offset just after the last block, or 0 with why set. blocks[t]
 * counts blocks of type t; syms[0], syms[1] literals and matches. */
static size_t inflate_raw(const uint8_t *in, size_t n, uint8_t *out, size_t cap, size_t *got, int blocks[3],
                          int syms[2], const char **why)
{
    inflater s = {.in = in, .n = n, .out = out, .cap = cap};
    int final = 0;
    while (!final && !s.err) {
        final = (int)inf_bits(&s, 1);
        unsigned type = inf_bits(&s, 2);
        if (s.err) break;
        if (type == 0) {
            s.pos = (s.pos + 7) & ~(size_t)7;
            size_t p = s.pos >> 3;
            if (p + 4 > n) {
                s.err = 1;
                s.why = "stored block header cut off";
                break;
            }
            uint32_t len = in[p] | (uint32_t)in[p + 1] << 8, nlen = in[p + 2] | (uint32_t)in[p + 3] << 8;
            if ((len ^ 0xFFFFu) != nlen || p + 4 + len > n || s.got + len > cap) {
                s.err = 1;
                s.why = "bad stored block";
                break;
            }
            memcpy(out + s.got, in + p + 4, len);
            s.got += len;
            s.pos = 8 * (p + 4 + len);
        } else if (type == 1 || type == 2) {
            uint8_t len[320];
            huff lit, dist;
            unsigned nlit = 288, ndist = 30;
            if (type == 1) {
                for (unsigned i = 0; i < 288; i++) len[i] = i < 144 ? 8 : i < 256 ? 9 : i < 280 ? 7 : 8;
                for (unsigned i = 0; i < 32; i++) len[288 + i] = 5; /* 30 and 31 unused but coded */
                ndist = 32;
            } else {
                static const uint8_t order[19] = {16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15};
                nlit = inf_bits(&s, 5) + 257;
                ndist = inf_bits(&s, 5) + 1;
                unsigned ncode = inf_bits(&s, 4) + 4;
                uint8_t cl[19] = {0};
                for (unsigned i = 0; i < ncode; i++) cl[order[i]] = (uint8_t)inf_bits(&s, 3);
                huff clh;
                if (s.err || nlit > 286 || ndist > 30 || !huff_build(&clh, cl, 19)) {
                    s.err = 1;
                    s.why = s.why ? s.why : "bad dynamic header";
                    break;
                }
                unsigned i = 0;
                while (i < nlit + ndist && !s.err) {
                    int sym = huff_decode(&s, &clh);
                    if (sym < 16) {
                        if (sym >= 0) len[i++] = (uint8_t)sym;
                        continue;
                    }
                    unsigned rep = sym == 16 ? 3 + inf_bits(&s, 2) : sym == 17 ? 3 + inf_bits(&s, 3) : 11 + inf_bits(&s, 7);
                    if ((sym == 16 && i == 0) || i + rep > nlit + ndist) {
                        s.err = 1;
                        s.why = "bad code length repeat";
                        break;
                    }
                    uint8_t v = sym == 16 ? len[i - 1] : 0;
                    while (rep--) len[i++] = v;
                }
                if (s.err) break;
                memmove(len + 288, len + nlit, ndist);
                for (unsigned k = nlit; k < 288; k++) len[k] = 0;
                if (!len[256]) {
                    s.err = 1;
                    s.why = "no end-of-block code";
                    break;
                }
            }
            if (!huff_build(&lit, len, nlit) || !huff_build(&dist, len + 288, ndist)) {
                s.err = 1;
                s.why = "bad Huffman code lengths";
                break;
            }
            inf_codes(&s, &lit, &dist, syms);
        } else {
            s.err = 1;
            s.why = "block type 3";
        }
        if (!s.err) blocks[type]++;
    }
    *got = s.got;
    *why = s.why;
    return s.err ? 0 : (s.pos + 7) >> 3;
}

static int paeth_ref(int a, int b, int c)
{
    int p = a + b - c, pa = abs(p - a), pb = abs(p - b), pc = abs(p - c);
    return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

/* Decodes a PNG of 8-bit RGB, no interlace (what our writer makes) into
 * *rgb, undoing all five row filters. Returns 0 and reports on anything
 * else. */
static int png_decode(const uint8_t *f, size_t n, uint32_t *w, uint32_t *h, uint8_t **rgb)
{
    static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    *rgb = NULL;
    if (n < 8 || memcmp(f, sig, 8) != 0) {
        HL_CHECK(0, "PNG signature");
        return 0;
    }
    uint8_t *z = malloc(n);
    size_t zn = 0, pos = 8;
    int seen_end = 0, seen_hdr = 0;
    while (pos + 12 <= n && !seen_end) {
        uint32_t len = be32(f + pos);
        if (pos + 12 + (size_t)len > n) break;
        const uint8_t *type = f + pos + 4, *data = f + pos + 8;
        HL_CHECK(hl_test_crc32(type, 4 + (size_t)len) == be32(data + len), "chunk %.4s: bad CRC", (const char *)type);
        if (memcmp(type, "IHDR", 4) == 0) {
            HL_CHECK(len == 13 && data[8] == 8 && data[9] == 2 && data[10] == 0 && data[11] == 0 && data[12] == 0,
                     "IHDR is not 8-bit RGB, deflate, filter method 0, no interlace");
            *w = be32(data);
            *h = be32(data + 4);
            seen_hdr = 1;
        } else if (memcmp(type, "IDAT", 4) == 0) {
            memcpy(z + zn, data, len);
            zn += len;
        } else if (memcmp(type, "IEND", 4) == 0) {
            seen_end = 1;
        }
        pos += 12 + (size_t)len;
    }
    HL_CHECK(seen_hdr && seen_end && pos == n, "PNG chunk structure (header %d, end %d, %zu of %zu bytes)", seen_hdr,
             seen_end, pos, n);
    if (!seen_hdr || zn < 6) {
        HL_CHECK(0, "no header or zlib stream too short (%zu bytes)", zn);
        free(z);
        return 0;
    }
    HL_CHECK((z[0] & 15) == 8 && (z[0] >> 4) <= 7 && ((unsigned)z[0] * 256u + z[1]) % 31u == 0 && !(z[1] & 32),
             "zlib header %02x %02x", z[0], z[1]);
    size_t stride = 1 + 3 * (size_t)*w, raw_n = (size_t)*h * stride, got = 0;
    uint8_t *raw = malloc(raw_n + 1);
    int blocks[3] = {0, 0, 0}, syms[2] = {0, 0};
    const char *why = NULL;
    size_t end = inflate_raw(z + 2, zn - 2, raw, raw_n, &got, blocks, syms, &why);
    HL_CHECK(end > 0, "inflate: %s (after %zu of %zu bytes)", why ? why : "?", got, raw_n);
    HL_CHECK(end == 0 || (got == raw_n && 2 + end + 4 == zn), "zlib stream: %zu of %zu bytes, end at %zu of %zu",
             got, raw_n, 2 + end, zn);
    uint32_t a = 1, b = 0;
    for (size_t i = 0; i < got; i++) {
        a = (a + raw[i]) % 65521u;
        b = (b + a) % 65521u;
    }
    if (end > 0 && 2 + end + 4 <= zn) HL_CHECK(be32(z + 2 + end) == (b << 16 | a), "Adler-32 mismatch");
    int ftypes[5] = {0, 0, 0, 0, 0};
    *rgb = calloc(3 * (size_t)*w * *h + 1, 1);
    for (uint32_t y = 0; y < *h && got == raw_n; y++) {
        const uint8_t *r = raw + (size_t)y * stride;
        uint8_t *o = *rgb + 3 * (size_t)y * *w;
        const uint8_t *up = y ? o - 3 * (size_t)*w : NULL;
        if (r[0] > 4) {
            HL_CHECK(0, "row %u filter type %d", y, r[0]);
            got = 0;
            break;
        }
        ftypes[r[0]]++;
        for (size_t i = 0; i < 3 * (size_t)*w; i++) {
            int A = i >= 3 ? o[i - 3] : 0, B = up ? up[i] : 0, C = up && i >= 3 ? up[i - 3] : 0, pred;
            switch (r[0]) {
            case 0: pred = 0; break;
            case 1: pred = A; break;
            case 2: pred = B; break;
            case 3: pred = (A + B) / 2; break;
            default: pred = paeth_ref(A, B, C); break;
            }
            o[i] = (uint8_t)(r[1 + i] + pred);
        }
    }
    printf("PNG %u x %u: %zu bytes (%.2f%% of %zu raw); blocks stored %d fixed %d dynamic %d; %d literals, %d "
           "matches; row filters %d/%d/%d/%d/%d\n",
           *w, *h, n, 100.0 * (double)n / (double)(raw_n ? raw_n : 1), raw_n, blocks[0], blocks[1], blocks[2], syms[0],
           syms[1], ftypes[0], ftypes[1], ftypes[2], ftypes[3], ftypes[4]);
    free(raw);
    free(z);
    return got == raw_n && end > 0;
}

static float rnd_value(void)
{
    double u = (double)(hl_rng_next() >> 11) / 9007199254740992.0;
    switch (hl_rng_next() % 4) {
    case 0: return (float)u;                      /* [0, 1) */
    case 1: return (float)(u * 1.2);              /* around white */
    case 2: return (float)(u * u * u * 0.01);     /* dark, sRGB toe */
    default: return (float)exp(u * 20.0 - 12.0);  /* HDR, 6e-6 .. 3e3 */
    }
}

/* Saves img as PNG at path, decodes the file and compares every sample
 * with hl_tonemap_srgb8. Returns the file size; *seconds (if given) gets
 * the time hl_image_save took. */
static size_t png_check(hl_context *ctx, const hl_image *img, const char *path, float ev, double *seconds)
{
    uint32_t W = img->width, H = img->height;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    HL_CHECK(hl_image_save(ctx, img, path, ev) == HL_OK, "save %s: %s", path, hl_context_last_error(ctx));
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (seconds) *seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    size_t n = 0;
    uint8_t *file = read_bytes(path, &n), *px = NULL;
    uint32_t pw = 0, ph = 0;
    if (file && png_decode(file, n, &pw, &ph, &px)) {
        HL_CHECK(pw == W && ph == H, "PNG size %u x %u, expected %u x %u", pw, ph, W, H);
        int diff = 0;
        for (size_t i = 0; i < 3 * (size_t)W * H && pw == W && ph == H; i++)
            diff += px[i] != hl_tonemap_srgb8(img->rgb[i], ev);
        HL_CHECK(diff == 0, "%u x %u: %d PNG samples differ from hl_tonemap_srgb8", W, H, diff);
    } else {
        HL_CHECK(0, "%s: cannot decode", path);
    }
    free(px);
    free(file);
    return file ? n : 0;
}

static void test_image_io(void)
{
    hl_context *ctx = make_ctx();
    char dir[512], path[1024];
    scratch(dir, sizeof dir, "image_io");

    /* EXR round trip through hl_env_load (2:1). */
    hl_image *img = NULL;
    HL_CHECK(hl_image_create(ctx, 96, 48, &img) == HL_OK, "hl_image_create: %s", hl_context_last_error(ctx));
    if (!img) return;
    HL_CHECK(img->rgb[0] == 0.0f && img->rgb[3 * 96 * 48 - 1] == 0.0f, "new image not zeroed");
    for (size_t i = 0; i < 3 * 96 * 48; i++) img->rgb[i] = rnd_value();
    img->rgb[0] = 1e6f; /* beyond half floats: kept (the file holds 32-bit floats) */
    img->rgb[1] = 65504.0f;
    img->rgb[2] = 0.0f;
    snprintf(path, sizeof path, "%s/round.exr", dir);
    HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_OK, "save %s: %s", path, hl_context_last_error(ctx));
    hl_env *env = NULL;
    hl_env_stats st;
    HL_CHECK(hl_env_load(ctx, path, &env, &st) == HL_OK, "load %s: %s", path, hl_context_last_error(ctx));
    if (env) {
        HL_CHECK(env->width == 96 && env->height == 48, "round trip size %u x %u", env->width, env->height);
        size_t differ = 0;
        for (size_t i = 0; i < 3 * 96 * 48; i++) differ += memcmp(&img->rgb[i], &env->rgb[i], sizeof(float)) != 0;
        printf("EXR round trip: 1e6 -> %g\n", (double)env->rgb[0]);
        hl_check_error("EXR (float) round trip: channels not bit-equal", (double)differ, 0.0);
        hl_env_destroy(env);
    }
    hl_image_destroy(img);

    /* PNG: every image is written, read back with the decoder above and
     * compared sample by sample with hl_tonemap_srgb8. */
    int png_files = 0;
    /* Noise, small and large enough for several blocks and IDAT chunks. */
    static const uint32_t sizes[][2] = {{1, 1}, {5, 3}, {300, 250}, {1500, 400}};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        uint32_t W = sizes[k][0], H = sizes[k][1];
        img = NULL;
        HL_CHECK(hl_image_create(ctx, W, H, &img) == HL_OK, "hl_image_create %u x %u", W, H);
        if (!img) continue;
        for (size_t i = 0; i < 3 * (size_t)W * H; i++) img->rgb[i] = rnd_value();
        if (W * H > 1) {
            img->rgb[3] = NAN;
            img->rgb[4] = -1.0f;
            img->rgb[5] = INFINITY;
        }
        snprintf(path, sizeof path, "%s/image_%ux%u.png", dir, W, H);
        png_check(ctx, img, path, k % 2 ? 1.5f : -0.5f, NULL);
        png_files++;
        hl_image_destroy(img);
    }
    /* Smooth, odd-sized, flat and render-like images. */
    static const struct {
        uint32_t w, h;
        int kind; /* 0 gradient, 1 gradient + noise, 2 flat, 3 render-like, 4 uniformly random codes */
    } smooth[] = {{512, 256, 0}, {333, 77, 1}, {1, 1, 0}, {700, 300, 2}, {960, 720, 3}, {400, 300, 4}};
    for (size_t k = 0; k < sizeof smooth / sizeof smooth[0]; k++) {
        uint32_t W = smooth[k].w, H = smooth[k].h;
        img = NULL;
        HL_CHECK(hl_image_create(ctx, W, H, &img) == HL_OK, "hl_image_create %u x %u", W, H);
        if (!img) continue;
        for (uint32_t y = 0; y < H; y++) {
            for (uint32_t x = 0; x < W; x++) {
                float *p = img->rgb + 3 * ((size_t)y * W + x);
                double u = (x + 0.5) / W, v = (y + 0.5) / H;
                for (int c = 0; c < 3; c++) p[c] = (float)(0.9 * u * (1.0 - 0.3 * c) + 0.1 * v * c);
                if (smooth[k].kind == 1) {
                    for (int c = 0; c < 3; c++) p[c] *= (float)(0.85 + 0.3 * (double)(hl_rng_next() >> 11) * 0x1p-53);
                } else if (smooth[k].kind == 2) {
                    p[0] = p[1] = p[2] = 0.25f;
                } else if (smooth[k].kind == 4) {
                    /* Incompressible: every 8-bit code equally likely. */
                    for (int c = 0; c < 3; c++)
                        p[c] = (float)pow(((double)(hl_rng_next() % 256) / 255.0 + 0.055) / 1.055, 2.4);
                } else if (smooth[k].kind == 3) {
                    /* Sky, a ground plane and a lit sphere, with a little
                     * sampling noise. */
                    double sx = (u - 0.5) / 0.22, sy = (v - 0.55) / 0.3, r2 = sx * sx + sy * sy;
                    double e[3];
                    if (r2 < 1.0) {
                        double nz = sqrt(1.0 - r2), ndl = 0.5 * -sx + 0.6 * -sy + 0.62 * nz;
                        double lum = 0.05 + 0.9 * (ndl > 0.0 ? ndl : 0.0);
                        e[0] = 0.8 * lum, e[1] = 0.35 * lum, e[2] = 0.2 * lum;
                    } else if (v > 0.6) {
                        double shade = ((int)(u * 12.0) + (int)(v * 20.0)) % 2 ? 0.35 : 0.25;
                        e[0] = e[1] = e[2] = shade * (0.6 + 0.4 * v);
                    } else {
                        e[0] = 0.3 + 0.2 * v, e[1] = 0.45 + 0.2 * v, e[2] = 0.9 - 0.2 * v;
                    }
                    for (int c = 0; c < 3; c++)
                        p[c] = (float)(e[c] * (0.98 + 0.04 * (double)(hl_rng_next() >> 11) * 0x1p-53));
                }
            }
        }
        snprintf(path, sizeof path, "%s/smooth_%ux%u.png", dir, W, H);
        double seconds = 0.0;
        size_t bytes = png_check(ctx, img, path, 0.0f, &seconds);
        png_files++;
        double ratio = bytes ? 3.0 * W * H / (double)bytes : 0.0;
        printf("  %u x %u (%s): %zu bytes, %.2f : 1 against the %zu bytes of RGB, written in %.3f s\n", W, H,
               (const char *[]){"gradient", "gradient + noise", "flat", "render-like", "random codes"}[smooth[k].kind],
               bytes, ratio,
               (size_t)3 * W * H, seconds);
        if (smooth[k].kind == 0 && W == 512)
            HL_CHECK(ratio >= 3.0, "smooth 512 x 256 gradient compresses only %.2f : 1, expected 3 : 1 or better", ratio);
        if (smooth[k].kind == 2) HL_CHECK(ratio >= 100.0, "flat image compresses only %.1f : 1", ratio);
        /* Stored blocks: incompressible data grows by little more than the
         * 5 bytes per 64 KiB block, the filter bytes and the PNG chunks. */
        if (smooth[k].kind == 4)
            HL_CHECK(bytes <= (size_t)H * (1 + 3 * (size_t)W) * 1001 / 1000 + 100,
                     "random codes: %zu bytes, more than stored blocks would take", bytes);
        /* Generous: about 0.1 s optimised, but the tests also run unoptimised. */
        if (smooth[k].kind == 3) HL_CHECK(seconds < 5.0, "960 x 720 PNG took %.2f s", seconds);
        hl_image_destroy(img);
    }
    /* Overwriting an existing file works and leaves no temporary. */
    img = NULL;
    HL_CHECK(hl_image_create(ctx, 4, 2, &img) == HL_OK, "hl_image_create 4 x 2");
    snprintf(path, sizeof path, "%s/image_5x3.png", dir);
    HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_OK, "overwrite %s: %s", path, hl_context_last_error(ctx));
    int entries = dir_entries(dir, ".tmp.");
    HL_CHECK(entries == 1 + png_files, "%s holds %d files, expected %d", dir, entries, 1 + png_files);

    /* Refusals: extension, unwritable places. Nothing may be left. */
    snprintf(path, sizeof path, "%s/picture.jpg", dir);
    hl_result r = hl_image_save(ctx, img, path, 0.0f);
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, ".jpg: %s", hl_result_string(r));
    HL_CHECK(strstr(hl_context_last_error(ctx), path) != NULL, ".jpg message does not name the path: %s",
             hl_context_last_error(ctx));
    HL_CHECK(!file_exists(path), ".jpg file created");
    snprintf(path, sizeof path, "%s/noext", dir);
    HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_ERR_INVALID_ARGUMENT, "no extension accepted");
    static const char *const kinds[] = {"png", "exr"};
    for (int k = 0; k < 2; k++) {
        snprintf(path, sizeof path, "%s/no_such_folder/out.%s", dir, kinds[k]);
        r = hl_image_save(ctx, img, path, 0.0f);
        HL_CHECK(r == HL_ERR_IO, "missing folder (.%s): %s", kinds[k], hl_result_string(r));
        HL_CHECK(strstr(hl_context_last_error(ctx), path) != NULL, "message does not name the path: %s",
                 hl_context_last_error(ctx));
        printf("unwritable: %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
        /* A path whose folder is a regular file (fails even for root). */
        snprintf(path, sizeof path, "%s/round.exr/out.%s", dir, kinds[k]);
        r = hl_image_save(ctx, img, path, 0.0f);
        HL_CHECK(r == HL_ERR_IO, "folder is a file (.%s): %s", kinds[k], hl_result_string(r));
    }
    if (geteuid() != 0) {
        char ro[600];
        snprintf(ro, sizeof ro, "%s/readonly", dir);
        mkdir(ro, 0755);
        chmod(ro, 0555);
        for (int k = 0; k < 2; k++) {
            snprintf(path, sizeof path, "%s/out.%s", ro, kinds[k]);
            r = hl_image_save(ctx, img, path, 0.0f);
            HL_CHECK(r == HL_ERR_IO, "read-only folder (.%s): %s", kinds[k], hl_result_string(r));
        }
        HL_CHECK(dir_entries(ro, NULL) == 0, "read-only folder not empty");
        chmod(ro, 0755);
        rmdir(ro);
    } else {
        printf("running as root: read-only folder check skipped (the missing-folder checks stand in)\n");
    }
    entries = dir_entries(dir, ".tmp.");
    HL_CHECK(entries == 1 + png_files, "%s holds %d files after the refusals, expected %d", dir, entries,
             1 + png_files);
    HL_CHECK(hl_image_save(ctx, NULL, path, 0.0f) == HL_ERR_INVALID_ARGUMENT, "NULL image accepted");
    hl_image_destroy(img);

    img = NULL;
    HL_CHECK(hl_image_create(ctx, 0, 5, &img) == HL_ERR_INVALID_ARGUMENT && img == NULL, "0 x 5 image accepted");
    HL_CHECK(hl_image_create(ctx, 70000, 5, &img) == HL_ERR_INVALID_ARGUMENT, "70000 wide image accepted");
    hl_image_destroy(NULL);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- tonemap */

static int srgb_ref(double x)
{
    if (!(x > 0.0)) return 0;
    if (x >= 1.0) return 255;
    double y = x < 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
    return (int)floor(y * 255.0 + 0.5);
}

static void test_tonemap(void)
{
    static const struct {
        float x, ev;
        int code;
    } known[] = {
        {0.0f, 0.0f, 0},       {1.0f, 0.0f, 255},     {0.5f, 0.0f, 188},      {0.18f, 0.0f, 118},
        {0.0031308f, 0.0f, 10}, {0.0031307f, 0.0f, 10}, {0.0031309f, 0.0f, 10}, {0.001f, 0.0f, 3},
        {0.25f, 1.0f, 188},    {1.0f, -1.0f, 188},    {0.5f, 1.0f, 255},      {2.0f, 0.0f, 255},
        {-1.0f, 0.0f, 0},      {NAN, 0.0f, 0},        {INFINITY, 0.0f, 255},  {-INFINITY, 0.0f, 0},
        {1e-30f, 0.0f, 0},     {0.0625f, 3.0f, 188},
    };
    for (size_t k = 0; k < sizeof known / sizeof known[0]; k++) {
        int got = hl_tonemap_srgb8(known[k].x, known[k].ev);
        HL_CHECK(got == known[k].code, "tonemap(%g, ev %g) = %d, expected %d", (double)known[k].x, (double)known[k].ev,
                 got, known[k].code);
    }
    /* Both sides of the boundary agree with the curve, which is continuous
     * there: 12.92 x = 1.055 x^(1/2.4) - 0.055 at x = 0.0031308 to 1e-7. */
    double lin = 12.92 * 0.0031308, pw = 1.055 * pow(0.0031308, 1.0 / 2.4) - 0.055;
    hl_check_error("sRGB curve continuity at 0.0031308", fabs(lin - pw), 1e-6);

    /* A sweep against the formula written here, and monotonicity. */
    int mismatches = 0, prev = 0, nonmono = 0;
    for (int i = 0; i <= 200000; i++) {
        float x = (float)i / 160000.0f;
        int got = hl_tonemap_srgb8(x, 0.0f), want = srgb_ref((double)x);
        mismatches += got != want;
        nonmono += got < prev;
        prev = got;
    }
    HL_CHECK(mismatches == 0, "%d of 200001 codes differ from the reference curve", mismatches);
    HL_CHECK(nonmono == 0, "tone curve not monotonic (%d steps down)", nonmono);
    /* Exposure +1 doubles: tonemap(x, ev + 1) == tonemap(2x, ev). */
    int exp_bad = 0;
    for (int i = 0; i < 5000; i++) {
        float x = (float)i / 4000.0f;
        exp_bad += hl_tonemap_srgb8(x, 1.0f) != hl_tonemap_srgb8(2.0f * x, 0.0f);
        exp_bad += hl_tonemap_srgb8(x, -2.0f) != hl_tonemap_srgb8(0.25f * x, 0.0f);
    }
    HL_CHECK(exp_bad == 0, "%d exposure mismatches", exp_bad);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"convention", test_convention}, {"solid_angle", test_solid_angle}, {"load_shared", test_load_shared},
        {"bad_files", test_bad_files},   {"nan_repair", test_nan_repair},   {"sky", test_sky},
        {"image_io", test_image_io},     {"tonemap", test_tonemap},         {"float_files", test_float_files},
        {"hostile_headers", test_hostile_headers},
        {"hostile_chunks", test_hostile_chunks},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
