/* test_env_layout.c - light-probe layouts (suite "env_layout").
 *
 * A smooth environment whose colour says where it looks (red towards +X,
 * green +Y, blue +Z) is drawn here into an angular map and both cube
 * crosses, from the pixel-to-direction formulas of docs/CONVENTIONS.md
 * written out independently of the loader (which maps directions to
 * pixels). Cases: orientation (each loaded layout matches the function
 * at every equirectangular pixel: a face or axis in the wrong place
 * costs most of a channel), energy (a small bright lobe keeps its energy
 * through each layout), explicit (--layout's choice is honoured, and a
 * size that is not the layout's is refused naming the file), relight (the
 * bunny on its ground relit under each layout and under the same map as
 * equirectangular EXR agree).
 * Depends on: haarlight.h (hl_env_load_layout, hl_image_save), hl_test.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hl_test.h"
#include "relight_compare.h"

#define PI 3.14159265358979323846

/* The test environment; lobe adds a bright spot of about 0.02 sr. */
static void env_fn(const double d[3], int lobe, float rgb[3])
{
    for (int c = 0; c < 3; c++) rgb[c] = (float)(0.25 + 0.75 * fmax(0.0, d[c]));
    if (lobe) {
        static const double a[3] = {0.48, 0.6, -0.64}; /* unit */
        const double c = d[0] * a[0] + d[1] * a[1] + d[2] * a[2];
        if (c > 0.99) for (int k = 0; k < 3; k++) rgb[k] += 500.0f;
    }
}

/* Angular map pixel -> direction: centre +X, right +Z, up +Y, radius
 * a / pi for the angle a from +X. 0 outside the disc. */
static int angular_dir(uint32_t D, uint32_t x, uint32_t y, double d[3])
{
    const double u = 2.0 * (x + 0.5) / D - 1.0, v = 1.0 - 2.0 * (y + 0.5) / D, r = hypot(u, v);
    if (r > 1.0) return 0;
    const double a = PI * r, s = r > 0 ? sin(a) / r : 0.0;
    d[0] = cos(a);
    d[1] = v * s;
    d[2] = u * s;
    return 1;
}

/* Cross pixel -> direction, face by face (centre, right, up), from the
 * table in docs/CONVENTIONS.md. */
typedef struct tface { int col, row; double f[3], r[3], u[3]; } tface;
static const tface TH[6] = {{1, 1, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}},  {0, 1, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}},
                            {2, 1, {0, 0, 1}, {-1, 0, 0}, {0, 1, 0}}, {3, 1, {-1, 0, 0}, {0, 0, -1}, {0, 1, 0}},
                            {1, 0, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}}, {1, 2, {0, -1, 0}, {0, 0, 1}, {1, 0, 0}}};
static const tface TV[6] = {{1, 1, {1, 0, 0}, {0, 0, 1}, {0, 1, 0}},  {0, 1, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}},
                            {2, 1, {0, 0, 1}, {-1, 0, 0}, {0, 1, 0}}, {1, 3, {-1, 0, 0}, {0, 0, 1}, {0, -1, 0}},
                            {1, 0, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}}, {1, 2, {0, -1, 0}, {0, 0, 1}, {1, 0, 0}}};

static int cross_dir(const tface *faces, uint32_t F, uint32_t x, uint32_t y, double d[3])
{
    for (int i = 0; i < 6; i++) {
        const tface *t = &faces[i];
        if (x / F != (uint32_t)t->col || y / F != (uint32_t)t->row) continue;
        const double s = 2.0 * (x % F + 0.5) / F - 1.0, v = 1.0 - 2.0 * (y % F + 0.5) / F;
        double n = 0.0;
        for (int k = 0; k < 3; k++) {
            d[k] = t->f[k] + s * t->r[k] + v * t->u[k];
            n += d[k] * d[k];
        }
        for (int k = 0; k < 3; k++) d[k] /= sqrt(n);
        return 1;
    }
    return 0;
}

/* Equirectangular pixel -> direction (docs/CONVENTIONS.md). */
static int equirect_dir(uint32_t w, uint32_t h, uint32_t x, uint32_t y, double d[3])
{
    const double th = PI * (y + 0.5) / h, ph = 2.0 * PI * ((x + 0.5) / w - 0.5);
    d[0] = sin(th) * cos(ph);
    d[1] = cos(th);
    d[2] = sin(th) * sin(ph);
    return 1;
}

/* Draws the environment in layout L (0 equirectangular, 1 angular, 2
 * horizontal cross, 3 vertical cross) at about `res` pixels a face or
 * disc and saves it. */
static const char *draw(hl_context *ctx, int L, uint32_t res, int lobe, const char *name)
{
    /* an angular map of diameter 4 res has the pixel angle of a cube face
       of res (pi / 2 / res), and so has an equirectangular map 4 res wide */
    static const uint32_t W[4] = {4, 4, 4, 3}, H[4] = {2, 4, 3, 4};
    const uint32_t w = W[L] * res, h = H[L] * res;
    hl_image img = {w, h, calloc((size_t)w * h * 3, sizeof(float))};
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            double d[3];
            const int in = L == 0   ? equirect_dir(w, h, x, y, d)
                           : L == 1 ? angular_dir(w, x, y, d)
                                    : cross_dir(L == 2 ? TH : TV, res, x, y, d);
            if (in) env_fn(d, lobe, img.rgb + 3 * ((size_t)y * w + x));
        }
    const char *path = hl_test_tmp_path(name);
    HL_CHECK(hl_image_save(ctx, &img, path, 0.0f) == HL_OK, "save %s: %s", path, hl_context_last_error(ctx));
    free(img.rgb);
    return path;
}

static void pixel_dir(const hl_env *e, uint32_t i, uint32_t j, double d[3]) { equirect_dir(e->width, e->height, i, j, d); }

static const char *const NAMES[4] = {"equirectangular map", "angular map", "horizontal cross", "vertical cross"};

static void case_orientation(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    for (int L = 1; L <= 3; L++) {
        const char *path = draw(ctx, L, 96, 0, "layout_orient.exr");
        hl_env *e = NULL;
        HL_CHECK(hl_env_load(ctx, path, &e, NULL) == HL_OK && e, "%s: %s", NAMES[L], hl_context_last_error(ctx));
        if (!e) continue;
        double worst = 0.0;
        for (uint32_t j = 0; j < e->height; j++)
            for (uint32_t i = 0; i < e->width; i++) {
                double d[3];
                float want[3];
                pixel_dir(e, i, j, d);
                env_fn(d, 0, want);
                for (int c = 0; c < 3; c++) worst = fmax(worst, fabs((double)e->rgb[3 * ((size_t)j * e->width + i) + c] - want[c]));
            }
        char what[128];
        snprintf(what, sizeof what, "%s at every equirectangular pixel (a misplaced face or axis: about 0.75)", NAMES[L]);
        /* the colour changes by at most 0.75 a radian; a sample is within
           half a diagonal of a source pixel's centre, and an output
           pixel's average within half a diagonal of its own centre */
        const double src_px = PI / 2.0 / 96.0, out_px = PI / e->height;
        hl_check_error(what, worst, 0.75 * 0.71 * (src_px + out_px));
        hl_env_destroy(e);
    }
    hl_context_destroy(ctx);
}

static double energy(const hl_env *e, double *lobe_part)
{
    double all = 0.0, lobe = 0.0;
    for (uint32_t j = 0; j < e->height; j++) {
        const double om = (2.0 * PI / e->width) * (cos(PI * j / e->height) - cos(PI * (j + 1.0) / e->height));
        for (uint32_t i = 0; i < e->width; i++) {
            const float *p = e->rgb + 3 * ((size_t)j * e->width + i);
            all += p[0] * om;
            if (p[0] > 2.0f) lobe += (p[0] - 1.0) * om;
        }
    }
    *lobe_part = lobe;
    return all;
}

static void case_energy(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    /* the lobe's energy: 500 over the cap c > 0.99, 2 pi (1 - 0.99) sr */
    const double want = 500.0 * 2.0 * PI * 0.01;
    for (int L = 1; L <= 3; L++) {
        const char *path = draw(ctx, L, 128, 1, "layout_energy.exr");
        hl_env *e = NULL;
        HL_CHECK(hl_env_load(ctx, path, &e, NULL) == HL_OK && e, "%s: %s", NAMES[L], hl_context_last_error(ctx));
        if (!e) continue;
        double lobe = 0.0;
        energy(e, &lobe);
        char what[128];
        snprintf(what, sizeof what, "%s: the lobe's energy, relative", NAMES[L]);
        /* the cap covers about 40 source pixels: its rim's pixels land
           whole on one side or the other, a few percent of the whole */
        hl_check_error(what, fabs(lobe - want) / want, 0.05);
        hl_env_destroy(e);
    }
    hl_context_destroy(ctx);
}

static void case_explicit(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    const char *angular = draw(ctx, 1, 64, 0, "layout_explicit.exr");
    hl_env *a = NULL, *b = NULL;
    HL_CHECK(hl_env_load_layout(ctx, angular, HL_LAYOUT_ANGULAR, &a, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_env_load(ctx, angular, &b, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(a && b && a->width == b->width && !memcmp(a->rgb, b->rgb, (size_t)a->width * a->height * 12),
             "an angular map by name and by size differ");
    hl_env_destroy(a);
    hl_env_destroy(b);
    const hl_env_layout wrong[3] = {HL_LAYOUT_EQUIRECT, HL_LAYOUT_CROSS_H, HL_LAYOUT_CROSS_V};
    for (int k = 0; k < 3; k++) {
        hl_env *e = NULL;
        const hl_result r = hl_env_load_layout(ctx, angular, wrong[k], &e, NULL);
        const char *msg = hl_context_last_error(ctx);
        HL_CHECK(r == HL_ERR_FORMAT && !e && strstr(msg, angular), "a square map as layout %d: %d (%s)", (int)wrong[k], (int)r, msg);
        printf("refused as expected: %s\n", msg);
        hl_env_destroy(e);
    }
    hl_context_destroy(ctx);
}

/* The same scene under the same sky with a sun-like lobe, once from an
 * equirectangular EXR and once from each layout. */
static void case_relight(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    hl_transport *t = compare_scene(ctx);
    HL_CHECK(t != NULL, "the comparison scene");
    float *want = NULL;
    for (int L = 0; t && L <= 3; L++) {
        const char *path = draw(ctx, L, 64, 1, "layout_relight.exr");
        hl_env *e = NULL;
        HL_CHECK(hl_env_load(ctx, path, &e, NULL) == HL_OK && e, "%s: %s", NAMES[L], hl_context_last_error(ctx));
        float *rgb = e ? compare_relight(ctx, t, e) : NULL;
        hl_env_destroy(e);
        if (L == 0) {
            want = rgb;
            continue;
        }
        char what[160];
        snprintf(what, sizeof what, "vertex colours under the %s against the equirectangular EXR (relative to the brightest)",
                 NAMES[L]);
        /* both maps hold the same function to about a pixel's worth of its
           gradient (hl.env_layout.orientation) and the lobe's energy to a
           few percent of itself (.energy), a few percent of the light */
        if (rgb && want) hl_check_error(what, compare_worst(want, rgb, 3 * (size_t)t->info.vertex_count), 0.03);
        free(rgb);
    }
    free(want);
    hl_transport_destroy(t);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"orientation", case_orientation}, {"energy", case_energy},
                                         {"explicit", case_explicit},       {"relight", case_relight},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
