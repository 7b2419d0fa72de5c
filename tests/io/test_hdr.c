/* test_hdr.c - Radiance .hdr environments (suite "hdr").
 *
 * Cases: read (run-length and flat files written here with an RGBE
 * encoder of the test's own give back their values to RGBE's precision,
 * and values RGBE holds exactly come back exactly), exposure (EXPOSURE
 * divides the pixels), same_as_exr (the same map as .hdr and as float EXR
 * loads alike, and lights the bunny on its ground alike), bad (truncated pixels, a foreign magic, XYZE, another
 * orientation, no end of header, a size beyond the file, a shape no
 * layout has: each a
 * clear error naming the file, never a map).
 * Depends on: haarlight.h (hl_env_load, hl_image_save), hl_test.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hl_test.h"
#include "relight_compare.h"

/* RGBE of one pixel, as Radiance writes it: the shared exponent of the
 * largest channel, mantissas truncated to 8 bits. */
static void rgbe_of(const float c[3], uint8_t out[4])
{
    float m = c[0] > c[1] ? c[0] : c[1];
    if (c[2] > m) m = c[2];
    if (m < 1e-32f) {
        memset(out, 0, 4);
        return;
    }
    int e;
    const float f = frexpf(m, &e) * 256.0f / m;
    for (int k = 0; k < 3; k++) out[k] = (uint8_t)(c[k] * f);
    out[3] = (uint8_t)(e + 128);
}

/* Writes w x h pixels; rle: new-style run-length scanlines (runs of equal
 * bytes as runs, the rest as literals), else flat. extra: header lines. */
static void write_hdr(const char *path, uint32_t w, uint32_t h, const float *rgb, int rle, const char *extra,
                      const char *res_line)
{
    FILE *f = fopen(path, "wb");
    if (!f) { perror(path); exit(1); }
    fprintf(f, "#?RADIANCE\n%sFORMAT=32-bit_rle_rgbe\n\n", extra ? extra : "");
    if (res_line) fputs(res_line, f);
    else fprintf(f, "-Y %u +X %u\n", h, w);
    uint8_t *line = malloc((size_t)w * 4);
    for (uint32_t y = 0; y < h; y++) {
        for (uint32_t x = 0; x < w; x++) rgbe_of(rgb + 3 * ((size_t)y * w + x), line + 4 * x);
        if (!rle) {
            fwrite(line, 4, w, f);
            continue;
        }
        const uint8_t head[4] = {2, 2, (uint8_t)(w >> 8), (uint8_t)(w & 255)};
        fwrite(head, 1, 4, f);
        for (int c = 0; c < 4; c++) {
            uint32_t x = 0;
            while (x < w) {
                uint32_t run = 1;
                while (x + run < w && run < 127 && line[4 * (x + run) + c] == line[4 * x + c]) run++;
                if (run >= 3) {
                    fputc((int)(128 + run), f);
                    fputc(line[4 * x + c], f);
                    x += run;
                    continue;
                }
                uint32_t lit = 0;
                while (x + lit < w && lit < 128) {
                    const uint32_t at = x + lit;
                    if (at + 2 < w && line[4 * at + c] == line[4 * (at + 1) + c] && line[4 * at + c] == line[4 * (at + 2) + c]) break;
                    lit++;
                }
                if (lit == 0) lit = 1;
                fputc((int)lit, f);
                for (uint32_t i = 0; i < lit; i++) fputc(line[4 * (x + i) + c], f);
                x += lit;
            }
        }
    }
    free(line);
    fclose(f);
}

/* A map with smooth sky, a flat run, and a bright sun: runs and literals. */
static float *test_map(uint32_t w, uint32_t h)
{
    float *rgb = malloc((size_t)w * h * 3 * sizeof *rgb);
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            float *p = rgb + 3 * ((size_t)y * w + x);
            const float s = 0.2f + (float)x / (float)w + 0.5f * (float)y / (float)h;
            p[0] = s;
            p[1] = y > h / 2 ? 0.25f : s * 0.5f;
            p[2] = (float)(hl_rng_next() % 1000) / 250.0f;
        }
    float *sun = rgb + 3 * ((size_t)(h / 4) * w + w / 3);
    sun[0] = 40000.0f;
    sun[1] = 30000.0f;
    sun[2] = 20000.0f;
    return rgb;
}

static hl_context *ctx_ref(void) { return hl_test_ref_context(1); }

/* Worst error of a loaded map against rgb, relative to each pixel's
 * largest channel (RGBE's precision is 2^-8 of it). */
static double worst_relative(const hl_env *e, const float *rgb, size_t pixels)
{
    double worst = 0.0;
    for (size_t i = 0; i < pixels; i++) {
        const float *a = rgb + 3 * i, *b = e->rgb + 3 * i;
        double m = fmax(a[0], fmax(a[1], a[2]));
        for (int k = 0; k < 3 && m > 0; k++) worst = fmax(worst, fabs((double)a[k] - b[k]) / m);
    }
    return worst;
}

static void case_read(void)
{
    hl_context *ctx = ctx_ref();
    const uint32_t w = 256, h = 128;
    float *rgb = test_map(w, h);
    for (int rle = 0; rle < 2; rle++) {
        const char *path = hl_test_tmp_path(rle ? "hdr_rle.hdr" : "hdr_flat.hdr");
        write_hdr(path, w, h, rgb, rle, NULL, NULL);
        hl_env *e = NULL;
        hl_result r = hl_env_load(ctx, path, &e, NULL);
        HL_CHECK(r == HL_OK && e, "%s: %s", path, hl_context_last_error(ctx));
        if (!e) continue;
        HL_CHECK(e->width == w && e->height == h, "size %u x %u", e->width, e->height);
        hl_check_error(rle ? "run-length .hdr against the map (relative to the pixel's largest channel)"
                           : "flat .hdr against the map (relative to the pixel's largest channel)",
                       worst_relative(e, rgb, (size_t)w * h), 1.0 / 128.0);
        hl_env_destroy(e);
    }
    /* values RGBE holds exactly (8-bit mantissas under a shared exponent) */
    for (size_t i = 0; i < (size_t)w * h * 3; i++) rgb[i] = (float)((i * 37) % 256) / 64.0f;
    for (size_t i = 0; i < (size_t)w * h; i++) rgb[3 * i] = 3.9375f; /* largest channel: exponent 2 */
    const char *path = hl_test_tmp_path("hdr_exact.hdr");
    write_hdr(path, w, h, rgb, 1, NULL, NULL);
    hl_env *e = NULL;
    HL_CHECK(hl_env_load(ctx, path, &e, NULL) == HL_OK && e, "exact: %s", hl_context_last_error(ctx));
    if (e) {
        double worst = 0.0;
        for (size_t i = 0; i < (size_t)w * h * 3; i++) worst = fmax(worst, fabs((double)e->rgb[i] - rgb[i]));
        hl_check_error("values RGBE holds exactly", worst, 0.0);
        hl_env_destroy(e);
    }
    free(rgb);
    hl_context_destroy(ctx);
}

static void case_exposure(void)
{
    hl_context *ctx = ctx_ref();
    const uint32_t w = 64, h = 32;
    float *rgb = test_map(w, h);
    const char *plain = hl_test_tmp_path("hdr_plain.hdr"), *exposed = hl_test_tmp_path("hdr_exposed.hdr");
    write_hdr(plain, w, h, rgb, 1, NULL, NULL);
    for (size_t i = 0; i < (size_t)w * h * 3; i++) rgb[i] *= 4.0f; /* as a writer with EXPOSURE=4 would */
    write_hdr(exposed, w, h, rgb, 1, "EXPOSURE=2\nEXPOSURE=2.0\n", NULL);
    hl_env *a = NULL, *b = NULL;
    HL_CHECK(hl_env_load(ctx, plain, &a, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_env_load(ctx, exposed, &b, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    if (a && b) {
        double worst = 0.0;
        for (size_t i = 0; i < (size_t)w * h * 3; i++) worst = fmax(worst, fabs((double)a->rgb[i] - b->rgb[i]));
        /* scaling by a power of two moves only the exponent: exact */
        hl_check_error("EXPOSURE=2 twice divides the pixels by 4", worst, 0.0);
    }
    hl_env_destroy(a);
    hl_env_destroy(b);
    free(rgb);
    hl_context_destroy(ctx);
}

static void case_same_as_exr(void)
{
    hl_context *ctx = ctx_ref();
    const uint32_t w = 128, h = 64;
    float *rgb = test_map(w, h);
    const char *hdr = hl_test_tmp_path("hdr_same.hdr"), *exr = hl_test_tmp_path("hdr_same.exr");
    write_hdr(hdr, w, h, rgb, 1, NULL, NULL);
    hl_image img = {w, h, rgb};
    HL_CHECK(hl_image_save(ctx, &img, exr, 0.0f) == HL_OK, "write %s: %s", exr, hl_context_last_error(ctx));
    hl_env *a = NULL, *b = NULL;
    HL_CHECK(hl_env_load(ctx, hdr, &a, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_env_load(ctx, exr, &b, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    if (a && b) hl_check_error(".hdr against the float EXR of the same map (relative to the pixel's largest channel)",
                               worst_relative(a, b->rgb, (size_t)w * h), 1.0 / 128.0);
    /* the same scene lit by both: a colour is a sum of pixels times
       non-negative transport, so it keeps the pixels' 2^-7, and the
       selection of the lighting terms differs only where two terms tie */
    hl_transport *t = compare_scene(ctx);
    HL_CHECK(t != NULL, "the comparison scene");
    float *ca = t && a ? compare_relight(ctx, t, a) : NULL, *cb = t && b ? compare_relight(ctx, t, b) : NULL;
    if (ca && cb)
        hl_check_error("vertex colours under the .hdr against the EXR (relative to the brightest)",
                       compare_worst(cb, ca, 3 * (size_t)t->info.vertex_count), 1.0 / 128.0);
    free(ca);
    free(cb);
    hl_transport_destroy(t);
    hl_env_destroy(a);
    hl_env_destroy(b);
    free(rgb);
    hl_context_destroy(ctx);
}

/* path must be refused with HL_ERR_FORMAT and a message holding the
 * file's name and needle. */
static void expect_refused(hl_context *ctx, const char *path, const char *needle)
{
    hl_env *e = NULL;
    const hl_result r = hl_env_load(ctx, path, &e, NULL);
    const char *msg = hl_context_last_error(ctx);
    HL_CHECK(r == HL_ERR_FORMAT && !e, "%s: expected a format error, got %d", path, (int)r);
    HL_CHECK(strstr(msg, path) && strstr(msg, needle), "%s: message \"%s\" lacks the file or \"%s\"", path, msg, needle);
    printf("refused as expected: %s\n", msg);
    hl_env_destroy(e);
}

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f) { perror(path); exit(1); }
    fwrite(p, 1, n, f);
    fclose(f);
}

static void case_bad(void)
{
    hl_context *ctx = ctx_ref();
    const uint32_t w = 64, h = 32;
    float *rgb = test_map(w, h);
    for (int rle = 0; rle < 2; rle++) {
        const char *good = hl_test_tmp_path("hdr_good.hdr"), *cut = hl_test_tmp_path(rle ? "hdr_cut_rle.hdr" : "hdr_cut_flat.hdr");
        write_hdr(good, w, h, rgb, rle, NULL, NULL);
        FILE *f = fopen(good, "rb");
        uint8_t *all = malloc(1 << 20);
        const size_t n = fread(all, 1, 1 << 20, f);
        fclose(f);
        /* cut in the last scanline, then in the middle */
        write_bytes(cut, all, n - 10);
        expect_refused(ctx, cut, "truncated");
        write_bytes(cut, all, n / 2);
        expect_refused(ctx, cut, "truncated");
        free(all);
    }
    const char *p = hl_test_tmp_path("hdr_bad.hdr");
    write_bytes(p, "#?RADIANCEX\n\n-Y 1 +X 2\n", 23);
    expect_refused(ctx, p, "not a Radiance"); /* a magic line with more after it */
    write_hdr(p, w, h, rgb, 1, "FORMAT=32-bit_rle_xyze\n", NULL);
    expect_refused(ctx, p, "xyze");
    write_hdr(p, w, h, rgb, 1, NULL, "+Y 32 +X 64\n");
    expect_refused(ctx, p, "orientation");
    write_hdr(p, w, h, rgb, 1, NULL, "-Y 32 +X\n");
    expect_refused(ctx, p, "resolution line");
    write_hdr(p, w, h, rgb, 1, "EXPOSURE=-1\n", NULL);
    expect_refused(ctx, p, "EXPOSURE");
    write_bytes(p, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n", 33);
    expect_refused(ctx, p, "header");
    write_hdr(p, w, h, rgb, 1, NULL, "-Y 2000 +X 4000\n");
    expect_refused(ctx, p, "truncated");
    write_hdr(p, w, h, rgb, 1, NULL, "-Y 100000 +X 200000\n");
    expect_refused(ctx, p, "size");
    free(rgb);
    rgb = test_map(60, 40); /* 3:2: no layout has that shape */
    write_hdr(p, 60, 40, rgb, 1, NULL, NULL);
    expect_refused(ctx, p, "cube cross");
    free(rgb);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"read", case_read}, {"exposure", case_exposure}, {"same_as_exr", case_same_as_exr}, {"bad", case_bad}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
