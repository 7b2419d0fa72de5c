/* test_viewer.c - compares a viewer capture with `haarlight relight`'s
 * picture of the same scene, camera and size.
 *
 *   test_viewer compare VIEW.exr RELIGHT.exr EV
 *
 * Both files are linear float EXR written by hl_image_save; each
 * value is tone-mapped with hl_tonemap_srgb8 at EV, exactly as both
 * commands write their PNG, and the 8-bit codes are compared. Pixels on
 * silhouettes may legitimately differ (the rasteriser and Embree decide a
 * pixel centre that lies on an edge independently), so the checks are on
 * the mean difference and on how many pixels differ visibly, and every
 * tolerance and measured value is printed.
 */
#include "exr_io.h"
#include "hl_test.h"

/* Mean |difference| over all channel values, in 8-bit codes. Interpolation
 * order, half-float targets and float-vs-double direction maths move codes
 * by 1 here and there; a wrong camera or map convention gives tens. */
#define TOL_MEAN_CODES 0.25
/* Pixels whose largest channel difference exceeds VISIBLE_CODES. */
#define VISIBLE_CODES 8
#define TOL_VISIBLE_FRACTION 0.005
/* Largest difference allowed away from edges: a pixel whose 3 x 3
 * neighbourhood in the relight picture varies by less than FLAT_CODES. */
#define FLAT_CODES 4
#define TOL_FLAT_MAX_CODES 2

static int compare(const char *view_path, const char *relight_path, float ev)
{
    hl_context *ctx = hl_test_ref_context(1);
    uint32_t w1, h1, w2, h2;
    float *a = NULL, *b = NULL;
    if (hl_exr_read_rgb_(ctx, view_path, 0, &w1, &h1, &a) != HL_OK ||
        hl_exr_read_rgb_(ctx, relight_path, 0, &w2, &h2, &b) != HL_OK) {
        fprintf(stderr, "FAIL: %s\n", hl_context_last_error(ctx));
        hl_context_destroy(ctx);
        return 3; /* unreadable: not the same as "the pictures differ" (1) */
    }
    HL_CHECK(w1 == w2 && h1 == h2, "sizes differ: viewer %u x %u, relight %u x %u", w1, h1, w2, h2);
    if (w1 == w2 && h1 == h2) {
        size_t n = (size_t)w1 * h1;
        uint8_t *ca = malloc(3 * n), *cb = malloc(3 * n);
        HL_CHECK(ca && cb, "out of memory");
        if (ca && cb) {
            for (size_t i = 0; i < 3 * n; i++) {
                ca[i] = hl_tonemap_srgb8(a[i], ev);
                cb[i] = hl_tonemap_srgb8(b[i], ev);
            }
            double sum = 0.0;
            size_t visible = 0, flat = 0;
            int worst = 0, worst_flat = 0;
            for (uint32_t y = 0; y < h1; y++)
                for (uint32_t x = 0; x < w1; x++) {
                    size_t p = (size_t)y * w1 + x;
                    int d = 0, spread = 0;
                    for (int c = 0; c < 3; c++) {
                        int e = abs((int)ca[3 * p + c] - (int)cb[3 * p + c]);
                        sum += e;
                        d = e > d ? e : d;
                        int lo = 255, hi = 0;
                        for (int dy = -1; dy <= 1; dy++)
                            for (int dx = -1; dx <= 1; dx++) {
                                long yy = (long)y + dy, xx = (long)x + dx;
                                if (yy < 0 || xx < 0 || yy >= (long)h1 || xx >= (long)w1) continue;
                                int q = cb[3 * ((size_t)yy * w1 + (size_t)xx) + c];
                                lo = q < lo ? q : lo;
                                hi = q > hi ? q : hi;
                            }
                        spread = hi - lo > spread ? hi - lo : spread;
                    }
                    worst = d > worst ? d : worst;
                    visible += d > VISIBLE_CODES;
                    if (spread < FLAT_CODES) {
                        flat++;
                        worst_flat = d > worst_flat ? d : worst_flat;
                    }
                }
            printf("compared %u x %u pixels at EV %+.2f: largest difference %d codes anywhere\n", w1, h1, (double)ev,
                   worst);
            hl_check_error("mean |difference| per channel (8-bit codes)", sum / (3.0 * (double)n), TOL_MEAN_CODES);
            char what[160];
            snprintf(what, sizeof what, "fraction of pixels differing by more than %d codes", VISIBLE_CODES);
            hl_check_error(what, (double)visible / (double)n, TOL_VISIBLE_FRACTION);
            snprintf(what, sizeof what, "largest difference on the %zu pixels away from edges (codes)", flat);
            hl_check_error(what, worst_flat, TOL_FLAT_MAX_CODES);
        }
        free(ca);
        free(cb);
    }
    free(a);
    free(b);
    hl_context_destroy(ctx);
    return hl_test_failures ? 1 : 0;
}

int main(int argc, char **argv)
{
    float ev;
    if (argc == 5 && !strcmp(argv[1], "compare") && sscanf(argv[4], "%f", &ev) == 1)
        return compare(argv[2], argv[3], ev);
    fprintf(stderr, "usage: %s compare VIEW.exr RELIGHT.exr EV\n", argv[0]);
    return 2;
}
