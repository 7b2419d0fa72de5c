/* fuzz_env.c - libFuzzer target for the environment loader (hl_env_load:
 * OpenEXR through OpenEXRCore or the C wrapper of the C++ library, then
 * the repair of NaN, Inf and negative pixels).
 *
 * On success the map must keep what haarlight.h promises: 2:1, every
 * channel finite and >= 0, repair counts no larger than the pixel count,
 * and direction queries that stay inside the pixels.
 */
#include "fuzz_common.h"

static void check_env(const hl_env *env, const hl_env_stats *st)
{
    FUZZ_REQUIRE(env->height >= 1 && env->width == 2 * env->height, "%u x %u is not 2:1", env->width,
                 env->height);
    size_t pixels = (size_t)env->width * env->height;
    for (size_t i = 0; i < 3 * pixels; i++)
        FUZZ_REQUIRE(isfinite(env->rgb[i]) && env->rgb[i] >= 0.0f, "channel %zu is %g", i, (double)env->rgb[i]);
    FUZZ_REQUIRE(st->nonfinite_pixels <= pixels && st->negative_pixels <= pixels,
                 "stats: %llu non-finite and %llu negative pixels of %zu", (unsigned long long)st->nonfinite_pixels,
                 (unsigned long long)st->negative_pixels, pixels);
    /* The poles, the seam and a turned map: nearest and bilinear. */
    static const float dirs[][3] = {{0, 1, 0}, {0, -1, 0}, {-1, 0, 0}, {1, 0, 1e-7f}, {0.3f, -0.2f, -0.9f}};
    for (size_t d = 0; d < sizeof dirs / sizeof dirs[0]; d++) {
        float rgb[3];
        hl_env_query(env, dirs[d], 0.0f, rgb);
        FUZZ_REQUIRE(fuzz_finite3(rgb), "query %zu is not finite", d);
        hl_env_query_smooth(env, dirs[d], 137.0f, rgb);
        FUZZ_REQUIRE(fuzz_finite3(rgb), "smooth query %zu is not finite", d);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    hl_context *ctx = fuzz_context();
    const char *path = fuzz_write_input(data, size, ".exr");
    hl_env *env = NULL;
    hl_env_stats st;
    hl_result r = hl_env_load(ctx, path, &env, &st);
    unlink(path);
    fuzz_check_result(r, env);
    if (env) check_env(env, &st);
    hl_env_destroy(env);
    return 0;
}
