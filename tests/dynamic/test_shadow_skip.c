/* test_shadow_skip.c - flat bodies left out of the shadow maps
 * (host/src/dynamic/shadow_map.c, hl_shadow_maps_skip_planes and
 * hl_shadow_maps_flat), suite "shadow_skip".
 *
 * planes     which lights leave the ground out (above it and below it,
 *            not on its horizon), the map then the bunny's alone to the
 *            bit, the ground's plane and extent in world space; also with
 *            the ground turned over, and kept with bodies on both sides;
 *            a triangle (not filling its extent) kept for lights below;
 *            a turned body whose box dips below the ground, not its
 *            vertices (the ground still left out);
 *            the Embree path draws every body.
 *
 * Every check prints its tolerance and worst error (hl_check_error).
 * Depends on: haarlight_core, shadow_map.h, shadow_scene.h, HL_REPO_DATA.
 */
#include <float.h>
#include <stdint.h>

#include "hl_test.h"
#include "shadow_map.h"
#include "shadow_scene.h"

/* Flat bodies out of the maps (hl_shadow_maps_skip_planes): with the
 * bunny on one side of the ground, the ground is left out for lights
 * above it and below it (the caller works out what it hides from the
 * plane), and kept for a light on its horizon; the bunny never; the
 * frame then is the bunny's own fit and the map the bunny's alone, to
 * the bit. The ground's plane in world space holds its corners and its
 * area. The same with the ground turned upside down (its own normal
 * -Y). With a second bunny under the ground, the ground stays in every
 * map. The Embree path draws every body. */
static void skip_one(hl_context *ctx, scene *s, const char *what)
{
    enum { K = 4 };
    float dirs[K][3];
    light_dirs(dirs, K); /* +Y, -Y, grazing from above, the horizon */
    const uint32_t want[K] = {2u, 2u, 2u, 0u};
    hl_shadow_maps *sm = NULL, *alone = NULL;
    hl_shadow_frame fr[K];
    size_t n = (size_t)K * R_TEST * R_TEST;
    float *a = malloc(n * 4), *b = malloc(n * 4);
    HL_CHECK(hl_shadow_maps_create(ctx, s->obj, 2, R_TEST, HL_SHADOW_RASTER, &sm) == HL_OK &&
             hl_shadow_maps_create(ctx, s->obj, 1, R_TEST, HL_SHADOW_RASTER, &alone) == HL_OK,
             "%s", hl_context_last_error(ctx));
    if (sm && alone) {
        hl_shadow_maps_skip_planes(sm, 1);
        HL_CHECK(hl_shadow_maps_render(sm, (const float(*)[3])dirs, K, a, fr) == HL_OK, "%s", hl_context_last_error(ctx));
        uint32_t wrong = 0;
        for (int k = 0; k < K; k++) wrong += fr[k].skip_mask != want[k];
        HL_CHECK(wrong == 0, "%s: masks %u %u %u %u, expected 2 2 2 0", what, fr[0].skip_mask, fr[1].skip_mask,
                 fr[2].skip_mask, fr[3].skip_mask);
        /* light 0: the bunny's own frame and map */
        hl_shadow_frame own;
        HL_CHECK(hl_shadow_maps_render(alone, (const float(*)[3])dirs, 1, b, &own) == HL_OK, "%s", hl_context_last_error(ctx));
        HL_CHECK(own.width == fr[0].width && own.depth_range == fr[0].depth_range &&
                 !memcmp(own.origin, fr[0].origin, 12), "%s: the frame is not the bunny's own fit (width %g against %g)",
                 what, (double)fr[0].width, (double)own.width);
        size_t mism, cov;
        double worst;
        compare_maps(a, b, (size_t)R_TEST * R_TEST, &mism, &worst, &cov);
        char w[160];
        snprintf(w, sizeof w, "%s: light +Y, depth against the bunny alone", what);
        hl_check_error(w, worst, 0.0);
        snprintf(w, sizeof w, "%s: light +Y, texels covered by one only", what);
        hl_check_error(w, (double)mism, 0.0);
    }
    /* the plane: the ground's corners on it, inside its extent, which
       has the ground's area */
    hl_flat_body fb;
    HL_CHECK(sm && hl_shadow_maps_flat(sm, 1, &fb) && fb.rect && !hl_shadow_maps_flat(sm, 0, &fb),
             "%s: flat bodies (the ground a filled rectangle, the bunny not flat)", what);
    if (sm && hl_shadow_maps_flat(sm, 1, &fb)) {
        const uint32_t nn = GROUND_N + 1, corner[4] = {0, GROUND_N, nn * GROUND_N, nn * nn - 1};
        double off = 0, out = 0, side = 0;
        for (int c = 0; c < 4; c++) {
            float w[3];
            const float *x = s->obj[1].xf, *p = s->obj[1].pos + 3 * (size_t)corner[c];
            for (int k = 0; k < 3; k++) w[k] = x[4 * k] * p[0] + x[4 * k + 1] * p[1] + x[4 * k + 2] * p[2] + x[4 * k + 3];
            double q[3] = {w[0] - fb.p[0], w[1] - fb.p[1], w[2] - fb.p[2]};
            off = fmax(off, fabs(q[0] * fb.n[0] + q[1] * fb.n[1] + q[2] * fb.n[2]));
            double a = q[0] * fb.u[0] + q[1] * fb.u[1] + q[2] * fb.u[2], b2 = q[0] * fb.v[0] + q[1] * fb.v[1] + q[2] * fb.v[2];
            out = fmax(out, fmax(fmax(fb.lo[0] - a, a - fb.hi[0]), fmax(fb.lo[1] - b2, b2 - fb.hi[1])));
        }
        side = s->gpos[3 * (size_t)GROUND_N] - s->gpos[0]; /* the ground's side along x */
        char w[160];
        snprintf(w, sizeof w, "%s: ground corners off its plane, world units", what);
        hl_check_error(w, off, 1e-5 * side);
        snprintf(w, sizeof w, "%s: ground corners outside its extent, world units", what);
        hl_check_error(w, fmax(out, 0.0), 1e-5 * side);
        snprintf(w, sizeof w, "%s: extent's area over the ground's, minus 1", what);
        hl_check_error(w, fabs((fb.hi[0] - fb.lo[0]) * (fb.hi[1] - fb.lo[1]) / (side * side) - 1.0), 1e-5);
    }
    hl_shadow_maps_destroy(sm);
    hl_shadow_maps_destroy(alone);
    free(a);
    free(b);
}

/* A flat body that does not fill its extent (the ground's half, one
 * triangle): left out for a light above it, where it hides nothing from
 * the bunny, but kept in the map for a light below it, since what it hides
 * could not be taken from its extent. */
static void skip_triangle(hl_context *ctx, scene *s)
{
    const float *g = s->gpos;
    const uint32_t nn = GROUND_N + 1;
    float tri_pos[9];
    memcpy(tri_pos, g, 12);
    memcpy(tri_pos + 3, g + 3 * (size_t)GROUND_N, 12);
    memcpy(tri_pos + 6, g + 3 * (size_t)(nn * GROUND_N), 12);
    uint32_t tri_idx[3] = {0, 2, 1};
    hl_dyn_object two[2] = {s->obj[0], {.pos = tri_pos, .nverts = 3, .tri = tri_idx, .ntris = 1}};
    memcpy(two[1].xf, XF_ID, 48);
    float dirs[2][3] = {{0, 1, 0}, {0, -1, 0}}, *d = malloc((size_t)2 * R_TEST * R_TEST * 4);
    hl_shadow_frame fr[2];
    hl_shadow_maps *sm = NULL;
    hl_flat_body fb;
    HL_CHECK(hl_shadow_maps_create(ctx, two, 2, R_TEST, HL_SHADOW_RASTER, &sm) == HL_OK, "%s",
             hl_context_last_error(ctx));
    if (sm) {
        hl_shadow_maps_skip_planes(sm, 1);
        HL_CHECK(hl_shadow_maps_flat(sm, 1, &fb) && !fb.rect, "a triangle taken for a filled rectangle");
        HL_CHECK(hl_shadow_maps_render(sm, (const float(*)[3])dirs, 2, d, fr) == HL_OK, "%s", hl_context_last_error(ctx));
        HL_CHECK(fr[0].skip_mask == 2u && fr[1].skip_mask == 0u,
                 "triangle ground: masks %u (light above, expected 2) and %u (below, expected 0)", fr[0].skip_mask,
                 fr[1].skip_mask);
    }
    hl_shadow_maps_destroy(sm);
    free(d);
}

/* Maps of n bodies for the K test lights, flat bodies left out where they
 * may be: the frames into fr (d: K maps of scratch); NULL, reported, on
 * failure. */
static hl_shadow_maps *render_skipping(hl_context *ctx, const hl_dyn_object *bodies, uint32_t n, float (*dirs)[3],
                                       uint32_t K, float *d, hl_shadow_frame *fr)
{
    hl_shadow_maps *sm = NULL;
    HL_CHECK(hl_shadow_maps_create(ctx, bodies, n, R_TEST, HL_SHADOW_RASTER, &sm) == HL_OK, "%s",
             hl_context_last_error(ctx));
    if (!sm) return NULL;
    hl_shadow_maps_skip_planes(sm, 1);
    light_dirs(dirs, K);
    const int ok = hl_shadow_maps_render(sm, (const float(*)[3])dirs, K, d, fr) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    if (!ok) {
        hl_shadow_maps_destroy(sm);
        return NULL;
    }
    return sm;
}

/* A bunny above the ground and one below: the ground separates bodies,
 * so it stays in every map. */
static void skip_straddle(hl_context *ctx, scene *s)
{
    hl_dyn_object three[3] = {s->obj[0], s->obj[1], s->obj[0]};
    const double ax[3] = {0, 1, 0}, t[3] = {0, -10.0 * (double)(s->gpos[3 * (size_t)GROUND_N] - s->gpos[0]), 0};
    make_xf(ax, 0.0, t, three[2].xf);
    enum { K = 4 };
    float dirs[K][3], *d = malloc((size_t)K * R_TEST * R_TEST * 4);
    hl_shadow_frame fr[K];
    hl_shadow_maps *sm = render_skipping(ctx, three, 3, dirs, K, d, fr);
    if (sm) {
        uint32_t any = 0;
        for (int k = 0; k < K; k++) any |= fr[k].skip_mask;
        HL_CHECK(any == 0, "a ground between two bodies was left out (masks %u %u %u %u)", fr[0].skip_mask,
                 fr[1].skip_mask, fr[2].skip_mask, fr[3].skip_mask);
    }
    hl_shadow_maps_destroy(sm);
    free(d);
}

/* A turned body resting on the ground: an octahedron of radius r turned
 * 45 degrees about Z, on one of its edges. Its own box, turned with it,
 * dips r / sqrt 2 below the ground, its vertices do not: the side
 * test takes the vertices, so the ground is left out for lights above and
 * below it, as for a body whose box rests on it (CesiumMilkTruck's
 * wheels, whose boxes kept the ground in every map). */
static void skip_turned(hl_context *ctx, scene *s)
{
    const float r = 0.25f * (s->gpos[3 * (size_t)GROUND_N] - s->gpos[0]);
    float opos[18] = {r, 0, 0, -r, 0, 0, 0, r, 0, 0, -r, 0, 0, 0, r, 0, 0, -r};
    uint32_t otri[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
    hl_dyn_object two[2] = {{.pos = opos, .nverts = 6, .tri = otri, .ntris = 8}, s->obj[1]};
    const float cx = 0.5f * (s->gpos[0] + s->gpos[3 * (size_t)GROUND_N]);
    const double ax[3] = {0, 0, 1}, t[3] = {cx, (double)s->gpos[1] + r * sqrt(0.5), 0.5 * (s->gpos[2] + s->gpos[3 * (size_t)(GROUND_N + 1) * GROUND_N + 2])};
    make_xf(ax, 0.25 * 3.14159265358979323846, t, two[0].xf);
    enum { K = 4 };
    float dirs[K][3], *d = malloc((size_t)K * R_TEST * R_TEST * 4);
    hl_shadow_frame fr[K];
    hl_shadow_maps *sm = render_skipping(ctx, two, 2, dirs, K, d, fr);
    if (sm) {
        HL_CHECK(fr[0].skip_mask == 2u && fr[1].skip_mask == 2u && fr[2].skip_mask == 2u && fr[3].skip_mask == 0u,
                 "turned octahedron on the ground: masks %u %u %u %u, expected 2 2 2 0", fr[0].skip_mask,
                 fr[1].skip_mask, fr[2].skip_mask, fr[3].skip_mask);
        /* light +Y: the octahedron's own fit, not the ground's */
        hl_shadow_maps *alone = NULL;
        hl_shadow_frame own;
        HL_CHECK(hl_shadow_maps_create(ctx, two, 1, R_TEST, HL_SHADOW_RASTER, &alone) == HL_OK &&
                 hl_shadow_maps_render(alone, (const float(*)[3])dirs, 1, d, &own) == HL_OK, "%s",
                 hl_context_last_error(ctx));
        HL_CHECK(own.width == fr[0].width && own.depth_range == fr[0].depth_range,
                 "turned octahedron: the +Y map is %g wide, the octahedron's own fit %g", (double)fr[0].width,
                 (double)own.width);
        hl_shadow_maps_destroy(alone);
    }
    hl_shadow_maps_destroy(sm);
    free(d);
}

static void case_skip(void)
{
    hl_context *ctx = ref_ctx();
    scene s;
    if (!scene_load(ctx, &s)) { HL_CHECK(0, "setup failed"); hl_context_destroy(ctx); return; }
    skip_one(ctx, &s, "ground");
    skip_straddle(ctx, &s);
    skip_triangle(ctx, &s);
    skip_turned(ctx, &s);
    /* the ground upside down in its own coordinates, (x, -y, 2 cz - z),
       put back in place by its transform: a half turn about X, then z
       moved by 2 cz */
    float cz = 0.5f * (s.gpos[2] + s.gpos[3 * (size_t)(GROUND_N + 1) * (GROUND_N + 1) - 1]);
    for (size_t v = 0; v < s.obj[1].nverts; v++) {
        s.gpos[3 * v + 1] = -s.gpos[3 * v + 1];
        s.gpos[3 * v + 2] = 2.0f * cz - s.gpos[3 * v + 2];
    }
    const double ax[3] = {1, 0, 0}, t[3] = {0, 0, 2.0 * cz};
    make_xf(ax, 3.14159265358979323846, t, s.obj[1].xf);
    skip_one(ctx, &s, "ground turned over");
    /* Embree: every body drawn */
    hl_shadow_maps *sm = NULL;
    float dir[1][3] = {{0, 1, 0}}, *d = malloc((size_t)R_TEST * R_TEST * 4);
    hl_shadow_frame fr;
    HL_CHECK(hl_shadow_maps_create(ctx, s.obj, 2, R_TEST, HL_SHADOW_EMBREE, &sm) == HL_OK, "%s", hl_context_last_error(ctx));
    if (sm) {
        hl_shadow_maps_skip_planes(sm, 1);
        HL_CHECK(hl_shadow_maps_render(sm, (const float(*)[3])dir, 1, d, &fr) == HL_OK && fr.skip_mask == 0,
                 "Embree left a body out (mask %u)", fr.skip_mask);
    }
    hl_shadow_maps_destroy(sm);
    free(d);
    scene_free(&s);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"planes", case_skip}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
