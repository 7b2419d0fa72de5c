/* relight_compare.h - one scene relit under two maps, for tests that
 * check a map format or layout against the same map as equirectangular
 * EXR: the bunny on its ground (data/bunny_lowres.obj, coarse settings),
 * relit on the plain-C reference with the default terms.
 * Depends on: hl_test.h, the haarlight command (HL_BIN), HL_REPO_DATA.
 */
#ifndef HL_TEST_RELIGHT_COMPARE_H
#define HL_TEST_RELIGHT_COMPARE_H

#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "hl_test.h"

/* The scene's transport, made once per test process with the command. */
static inline hl_transport *compare_scene(hl_context *ctx)
{
    static char path[1024];
    if (!path[0]) {
        char cmd[4096];
        snprintf(path, sizeof path, "%s/relight_compare.%ld.hlt", hl_test_env("HL_TMP", "/tmp"), (long)getpid());
        snprintf(cmd, sizeof cmd, "'%s' precompute '%s/bunny_lowres.obj' --ground --ground-res 12 -C 16 -N 32 --device ref -q -o '%s'",
                 hl_test_env("HL_BIN", "haarlight"), hl_test_env("HL_REPO_DATA", "data"), path);
        if (system(cmd) != 0) {
            fprintf(stderr, "failed: %s\n", cmd);
            return NULL;
        }
    }
    hl_transport *t = NULL;
    return hl_transport_load(ctx, path, &t) == HL_OK ? t : NULL;
}

/* Vertex colours of t under env (malloc'ed, 3 per vertex), or NULL. */
static inline float *compare_relight(hl_context *ctx, const hl_transport *t, const hl_env *env)
{
    hl_relighter *r = NULL;
    float *rgb = malloc((size_t)t->info.vertex_count * 3 * sizeof *rgb);
    hl_relight_desc d = {0};
    const int ok = rgb && hl_relighter_create(ctx, t, &r) == HL_OK && hl_relighter_set_env(r, env) == HL_OK &&
                   hl_relighter_run(r, &d, rgb, NULL) == HL_OK;
    hl_relighter_destroy(r);
    if (!ok) {
        fprintf(stderr, "relight: %s\n", hl_context_last_error(ctx));
        free(rgb);
        return NULL;
    }
    return rgb;
}

/* Worst difference of b from a over all channels, relative to a's
 * brightest channel. */
static inline double compare_worst(const float *a, const float *b, size_t n)
{
    double most = 0.0, worst = 0.0;
    for (size_t i = 0; i < n; i++) most = most > a[i] ? most : a[i];
    for (size_t i = 0; i < n; i++) {
        const double d = (double)a[i] - b[i];
        worst = worst > (d < 0 ? -d : d) ? worst : (d < 0 ? -d : d);
    }
    return most > 0.0 ? worst / most : worst;
}

#endif
