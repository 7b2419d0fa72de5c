/* A program that uses haarlight through its installed public API only:
 * bakes a small ground with a block on it, relights it under the built-in
 * sun and sky, and prints two vertices' colours. */
#include <stdio.h>
#include <haarlight.h>

int main(void)
{
    static const float pos[] = {-2, 0, -2, 2, 0, -2, 2, 0, 2, -2, 0, 2,   /* ground */
                                -.5f, 1, -.5f, .5f, 1, -.5f, .5f, 1, .5f, -.5f, 1, .5f}; /* roof */
    static const uint32_t tri[] = {0, 2, 1, 0, 3, 2, 4, 6, 5, 4, 7, 6};
    hl_context_desc cd = {.backend = HL_BACKEND_REFERENCE, .quiet = 1};
    hl_precompute_desc pd = {.N = 16, .C = 16};
    hl_context *ctx;
    hl_mesh *mesh;
    hl_transport *t;
    hl_env *sky;
    hl_relighter *r;
    char err[256];
    float rgb[8 * 3];
    if (hl_context_create(&cd, &ctx, err, sizeof err) != HL_OK) return fprintf(stderr, "%s\n", err), 1;
    if (hl_mesh_create(ctx, 8, pos, NULL, NULL, 4, tri, &mesh) != HL_OK ||
        hl_precompute(ctx, mesh, &pd, "example.hlt", NULL) != HL_OK || hl_transport_load(ctx, "example.hlt", &t) != HL_OK ||
        hl_env_create_sky(ctx, &(hl_sky_desc){0}, &sky) != HL_OK || hl_relighter_create(ctx, t, &r) != HL_OK ||
        hl_relighter_set_env(r, sky) != HL_OK || hl_relighter_run(r, &(hl_relight_desc){0}, rgb, NULL) != HL_OK)
        return fprintf(stderr, "haarlight: %s\n", hl_context_last_error(ctx)), 1;
    printf("ground corner %.4f %.4f %.4f, roof %.4f %.4f %.4f\n", rgb[0], rgb[1], rgb[2], rgb[12], rgb[13], rgb[14]);
    hl_relighter_destroy(r), hl_env_destroy(sky), hl_transport_destroy(t), hl_mesh_destroy(mesh);
    hl_context_destroy(ctx);
    return 0;
}
