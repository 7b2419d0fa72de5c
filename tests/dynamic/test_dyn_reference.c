/* test_dyn_reference.c - the exact reference of the dynamic method
 * (host/src/dynamic/dyn_reference.c), suite "dyn_reference".
 *
 * dyn_reference.furnace     a lone ground grid under a constant map of
 *                           radiance 1: B = albedo.
 * dyn_reference.unoccluded  a lone ground under the sky: the exact
 *                           reference equals the unshadowed frame sum
 *                           within the SH9 ambient's error, the K-lights
 *                           reference equals it to float rounding.
 * dyn_reference.occluded    a ground with a quad floating above it under
 *                           an overhead sun and a sky: against the sky
 *                           alone, vertices under the quad get none of
 *                           the sun, those outside all of it.
 * dyn_reference.traced     the traced method (dyn_traced.h): unoccluded
 *                           it equals the K-lights reference; under the
 *                           quad its error against it falls 4 times from
 *                           S = 1 to 64; one thread gives the same bits.
 * accuracy [S [MAP]]        not a ctest case (prints, asserts nothing; it
 *                           takes minutes): the bunny on its ground at
 *                           K = 32, R = 256, M = 16 under the eight shared
 *                           maps and the sky, the frame and the K-lights
 *                           reference against the exact one (relative
 *                           L2), at rest and moved; S: rays a texel
 *                           side (0: the default), MAP: that map only.
 * convergence MAP [S [F]]   not a ctest case: the exact reference at F
 *                           (32) and S (1) against 2 S and against 2 F.
 * Depends on: dyn_reference.h, dyn_frame.h, scene.h, area_lights.h,
 * hl_test.h, HL_REPO_DATA (bunny_lowres.obj), HL_TEST_DATA (envmaps).
 */
#include <float.h>

#include "dyn_frame.h"
#include "dyn_reference.h"
#include "dyn_traced.h"
#include "dyn_util.h"
#include "hl_test.h"
#include "scene.h"

#define PI_D 3.14159265358979323846

enum { GRID = 24 }; /* quads a side of the test grounds */

typedef struct grid {
    float *pos, *nrm, *alb, *rgb, *rgb2;
    uint32_t *tri;
    uint32_t nv, nt;
} grid;

/* A (GRID + 1)^2 ground over [-1, 1]^2 at y = 0, facing +Y, albedo 0.5. */
static void grid_make(grid *g)
{
    g->nv = (GRID + 1) * (GRID + 1), g->nt = 2 * GRID * GRID;
    g->pos = malloc(g->nv * 12), g->nrm = malloc(g->nv * 12), g->alb = malloc(g->nv * 12);
    g->rgb = malloc(g->nv * 12), g->rgb2 = malloc(g->nv * 12);
    g->tri = malloc(g->nt * 12);
    for (uint32_t j = 0; j <= GRID; j++)
        for (uint32_t i = 0; i <= GRID; i++) {
            uint32_t v = j * (GRID + 1) + i;
            float p[3] = {(float)i / GRID * 2 - 1, 0.0f, (float)j / GRID * 2 - 1}, up[3] = {0, 1, 0};
            memcpy(g->pos + 3 * v, p, 12), memcpy(g->nrm + 3 * v, up, 12);
            g->alb[3 * v] = g->alb[3 * v + 1] = g->alb[3 * v + 2] = 0.5f;
        }
    uint32_t t = 0;
    for (uint32_t j = 0; j < GRID; j++)
        for (uint32_t i = 0; i < GRID; i++) {
            uint32_t a = j * (GRID + 1) + i, b = a + 1, c = a + GRID + 1, d = c + 1;
            uint32_t q[6] = {a, c, b, b, c, d};
            memcpy(g->tri + 3 * t, q, 24), t += 2;
        }
}

static void grid_free(grid *g)
{
    free(g->pos); free(g->nrm); free(g->alb); free(g->rgb); free(g->rgb2); free(g->tri);
}

static hl_dyn_object grid_object(const grid *g)
{
    hl_dyn_object o = {g->pos, g->nrm, g->nv, g->tri, g->nt, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
    return o;
}

/* ------------------------------------------------------------ furnace */

static void case_furnace(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    enum { W = 64, H = 32 };
    float *ones = malloc(W * H * 12);
    for (int i = 0; i < W * H * 3; i++) ones[i] = 1.0f;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ctx, W, H, ones, &env, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    grid g;
    grid_make(&g);
    hl_dyn_object o = grid_object(&g);
    const float *albs[1] = {g.alb};
    float *outs[1] = {g.rgb};
    hl_dyn_ref_stats st = {0};
    hl_result r = env ? hl_dyn_reference_exact(ctx, &o, 1, albs, env, 0, 0, outs, &st) : HL_ERR_INVALID_ARGUMENT;
    HL_CHECK(r == HL_OK, "%s", hl_context_last_error(ctx));
    double worst = 0;
    for (uint32_t i = 0; r == HL_OK && i < 3 * g.nv; i++) worst = fmax(worst, fabs(g.rgb[i] - g.alb[i]) / g.alb[i]);
    printf("%u vertices, %llu rays (%llu culled) in %.3f s\n", st.vertices, (unsigned long long)st.rays_cast,
           (unsigned long long)st.rays_culled, st.seconds);
    /* F is even, so the horizon of +Y runs along texel edges: the texel
       sum is the cosine integral exactly, up to float sums of the map's
       resampled energy (4e-8 of it) over 3 F^2 texels */
    hl_check_error("furnace: |B - albedo| / albedo", worst, 1e-5);
    grid_free(&g);
    hl_env_destroy(env);
    free(ones);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ unoccluded */

static void case_unoccluded(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    hl_sky_desc sd = {0};
    sd.width = 512;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create_sky(ctx, &sd, &env) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_light_split *s = env ? split_of(ctx, env, HL_LIGHTS_DEFAULT_KEEP) : NULL;
    grid g;
    grid_make(&g);
    hl_dyn_object o = grid_object(&g);
    const float *albs[1] = {g.alb};
    float *outs[1] = {g.rgb}, *outs2[1] = {g.rgb2};
    int ok = s && hl_dyn_reference_exact(ctx, &o, 1, albs, env, 0, 0, outs, NULL) == HL_OK &&
             hl_dyn_reference_lights(ctx, &o, 1, albs, s, 0, outs2, NULL) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    double worst_exact = 0, worst_lights = 0, sh_err = 0;
    for (uint32_t v = 0; ok && v < g.nv; v++) {
        const float *n = g.nrm + 3 * v;
        float a[3], aref[3], E[3];
        hl_light_split_ambient(s, n, a);
        hl_light_split_ambient_ref(s, n, aref);
        double sum[3] = {a[0], a[1], a[2]};
        for (uint32_t k = 0; k < s->count; k++) {
            hl_area_light_irradiance(s, k, n, E);
            for (int c = 0; c < 3; c++) sum[c] += E[c];
        }
        for (int c = 0; c < 3; c++) {
            double want = g.alb[3 * v + c] / PI_D * sum[c];
            sh_err = fmax(sh_err, fabs(a[c] - aref[c]) / sum[c]);
            worst_exact = fmax(worst_exact, fabs(g.rgb[3 * v + c] - want) / want);
            worst_lights = fmax(worst_lights, fabs(g.rgb2[3 * v + c] - want) / want);
        }
    }
    /* the exact sum differs from the frame's by the SH9 ambient's error
       (measured here against its texel sum: ambient_ref) and by folded
       texels taken at their centre rather than their moment (1e-3: a
       texel's centroid is within a fraction of its 3.6 degrees) */
    printf("SH9 ambient against its texel sum: %.4g of the irradiance\n", sh_err);
    hl_check_error("unoccluded: exact against the unshadowed frame sum", worst_exact, sh_err + 1e-3);
    /* every V_k = 1: the same sum as the frame's, in double then float */
    hl_check_error("unoccluded: K-lights reference against the unshadowed frame sum", worst_lights, 1e-5);
    grid_free(&g);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ occluded */

/* Sun half-angle (radians) about +Y: 1.5 degrees, inside the central
 * texels of the +Y face (3.6 degrees each at F = 32, 1.8 at 64). */
#define SUN_HALF 0.0262
#define SUN_L 2000.0f /* its radiance */
#define SKY_L 0.2f    /* the sky's radiance */
#define QUAD_Y 0.5f   /* the floating quad's height */
#define QUAD_HALF 0.4f

/* The map of the case: the sky, and with sun the sun about +Y; Esun, the
 * sun's irradiance on +Y from the pixels (with sun). */
static float *occluded_map(int W, int H, int sun, double *Esun)
{
    float *map = malloc((size_t)W * H * 12);
    *Esun = 0;
    for (int j = 0; j < H; j++) {
        double th = PI_D * (j + 0.5) / H, om = 2 * PI_D / W * (cos(PI_D * j / H) - cos(PI_D * (j + 1) / H));
        for (int i = 0; i < W; i++) {
            float L = sun && th < SUN_HALF ? SUN_L : SKY_L;
            for (int c = 0; c < 3; c++) map[3 * ((size_t)j * W + i) + c] = L;
            if (sun && th < SUN_HALF) *Esun += L * om * cos(th);
        }
    }
    return map;
}

static void case_occluded(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    enum { W = 1024, H = 512 };
    double Esun = 0, none;
    float *map = occluded_map(W, H, 1, &Esun), *skymap = occluded_map(W, H, 0, &none);
    hl_env *env = NULL, *sky = NULL;
    HL_CHECK(hl_env_create(ctx, W, H, map, &env, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_env_create(ctx, W, H, skymap, &sky, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    grid g;
    grid_make(&g);
    /* the quad: two triangles over [-QUAD_HALF, QUAD_HALF]^2 at QUAD_Y */
    float qp[12] = {-QUAD_HALF, QUAD_Y, -QUAD_HALF, QUAD_HALF, QUAD_Y, -QUAD_HALF,
                    -QUAD_HALF, QUAD_Y, QUAD_HALF,  QUAD_HALF, QUAD_Y, QUAD_HALF};
    float qn[12] = {0, -1, 0, 0, -1, 0, 0, -1, 0, 0, -1, 0}, qa[12], qrgb[12], qrgb2[12];
    for (int i = 0; i < 12; i++) qa[i] = 0.5f;
    uint32_t qt[6] = {0, 1, 2, 1, 3, 2};
    hl_dyn_object o[2] = {grid_object(&g), {qp, qn, 4, qt, 2, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}}};
    const float *albs[2] = {g.alb, qa};
    float *outs[2] = {g.rgb, qrgb}, *outs2[2] = {g.rgb2, qrgb2};
    int ok = env && sky && hl_dyn_reference_exact(ctx, o, 2, albs, env, 0, 0, outs, NULL) == HL_OK &&
             hl_dyn_reference_exact(ctx, o, 2, albs, sky, 0, 0, outs2, NULL) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    /* the sun's part of E: E under the map less E under the sky alone;
       under the quad (|x|, |z| <= 0.3) none of it, outside (beyond 0.55,
       clear of the quad's edge by the sun's and a texel's slant at 0.5
       height) all of it */
    double under = 0, outside = 0;
    uint32_t nin = 0, nout = 0;
    for (uint32_t v = 0; ok && v < g.nv; v++) {
        float x = g.pos[3 * v], z = g.pos[3 * v + 2];
        double sun = (g.rgb[3 * v + 1] - (double)g.rgb2[3 * v + 1]) * PI_D / g.alb[3 * v + 1];
        if (fabsf(x) <= 0.3f && fabsf(z) <= 0.3f) under = fmax(under, fabs(sun) / Esun), nin++;
        if (fabsf(x) >= 0.55f || fabsf(z) >= 0.55f) outside = fmax(outside, fabs(sun - Esun) / Esun), nout++;
    }
    printf("sun %.4g on +Y; %u vertices under the quad, %u outside\n", Esun, nin, nout);
    HL_CHECK(nin > 0 && nout > 0, "no vertex under or outside the quad");
    /* float rounding of E (the sun is 6 times the sky's irradiance here) */
    hl_check_error("occluded: the sun's part under the quad, / sun", under, 1e-5);
    /* the cube's sun is the map's energy (4e-8) times the cosine over its
       texels, against the pixels' centres here: within 1 - cos(1.5 deg)
       = 3.4e-4 of each other */
    hl_check_error("occluded: the sun's part outside the quad against the sun, / sun", outside, 4e-4);
    grid_free(&g);
    hl_env_destroy(env);
    hl_env_destroy(sky);
    free(map);
    free(skymap);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ traced */

/* Relative L2 of a against b over n floats. */
static double rel_l2_n(const float *a, const float *b, size_t n)
{
    double se = 0, sr = 0;
    for (size_t i = 0; i < n; i++) se += ((double)a[i] - b[i]) * ((double)a[i] - b[i]), sr += (double)b[i] * b[i];
    return sr > 0 ? sqrt(se / sr) : sqrt(se);
}

/* The traced method (dyn_traced.h): unoccluded it is the K-lights sum;
 * under the floating quad it converges on the K-lights reference as S
 * grows; its result does not depend on the threads; bad S is refused. */
static void case_traced(void)
{
    hl_context *ctx = hl_test_ref_context(2), *ctx1 = hl_test_ref_context(1);
    enum { W = 1024, H = 512 };
    double Esun = 0;
    float *map = occluded_map(W, H, 1, &Esun);
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ctx, W, H, map, &env, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_light_split *s = env ? split_of(ctx, env, 8) : NULL;
    grid g;
    grid_make(&g);
    float qp[12] = {-QUAD_HALF, QUAD_Y, -QUAD_HALF, QUAD_HALF, QUAD_Y, -QUAD_HALF,
                    -QUAD_HALF, QUAD_Y, QUAD_HALF,  QUAD_HALF, QUAD_Y, QUAD_HALF};
    float qn[12] = {0, -1, 0, 0, -1, 0, 0, -1, 0, 0, -1, 0}, qa[12], qrgb[12];
    for (int i = 0; i < 12; i++) qa[i] = 0.5f;
    uint32_t qt[6] = {0, 1, 2, 1, 3, 2};
    hl_dyn_object o[2] = {grid_object(&g), {qp, qn, 4, qt, 2, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}}};
    const float *albs[2] = {g.alb, qa};
    float *outs[2] = {g.rgb, qrgb}, *outs2[2] = {g.rgb2, qrgb};
    const size_t n = 3 * (size_t)g.nv;
    float *t1 = malloc(n * 4), *t64 = malloc(n * 4);
    HL_CHECK(s && t1 && t64, "no split or out of memory");
    /* the ground alone: every V_k = 1 in both */
    hl_dyn_traced_stats st = {0};
    int ok = hl_dyn_reference_lights(ctx, o, 1, albs, s, 0, outs2, NULL) == HL_OK &&
             hl_dyn_traced(ctx, o, 1, albs, s, 4, outs, &st) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    double worst = 0;
    for (size_t i = 0; i < n; i++) worst = fmax(worst, fabs(g.rgb[i] - (double)g.rgb2[i]) / g.rgb2[i]);
    printf("unoccluded: %u vertices, %u lights, S %u: %llu rays, %llu below the horizon, %.3f s\n", st.vertices,
           st.lights, st.S, (unsigned long long)st.rays_cast, (unsigned long long)st.rays_below, st.seconds);
    HL_CHECK(st.rays_cast > 0 && st.rays_cast + st.rays_below == (uint64_t)g.nv * s->count * 4, "ray counts");
    /* the same double sum, rounded to float once each */
    hl_check_error("traced unoccluded against the K-lights reference", worst, 1e-5);
    /* with the quad: S = 1 and S = 64 against the reference */
    outs[0] = t1;
    ok = hl_dyn_reference_lights(ctx, o, 2, albs, s, 0, outs2, NULL) == HL_OK &&
         hl_dyn_traced(ctx, o, 2, albs, s, 1, outs, NULL) == HL_OK;
    outs[0] = t64;
    ok = ok && hl_dyn_traced(ctx, o, 2, albs, s, 64, outs, NULL) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    double e1 = rel_l2_n(t1, g.rgb2, n), e64 = rel_l2_n(t64, g.rgb2, n);
    printf("occluded: relative L2 against the K-lights reference: S 1 %.4g, S 64 %.4g\n", e1, e64);
    /* stratified sampling: the penumbra's noise falls at least as 1 / sqrt S,
       8 times from 1 to 64; half of that is asked */
    hl_check_error("traced S 64 error / S 1 error", e64 / fmax(e1, 1e-30), 0.25);
    /* one thread: the same bits (jitter hashed from vertex, light, sample) */
    outs[0] = t1;
    ok = hl_dyn_traced(ctx1, o, 2, albs, s, 64, outs, NULL) == HL_OK;
    HL_CHECK(ok && memcmp(t1, t64, n * 4) == 0, "traced: 1 and 2 threads differ");
    HL_CHECK(hl_dyn_traced(ctx, o, 2, albs, s, 0, outs, NULL) == HL_ERR_INVALID_ARGUMENT, "S = 0 accepted");
    HL_CHECK(hl_dyn_traced(ctx, o, 2, albs, s, HL_DYNTRACED_MAX_S + 1, outs, NULL) == HL_ERR_INVALID_ARGUMENT,
             "S over the limit accepted");
    free(t1);
    free(t64);
    grid_free(&g);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    free(map);
    hl_context_destroy(ctx);
    hl_context_destroy(ctx1);
}

/* ------------------------------------------------------------ accuracy */

/* Relative L2 over all vertices and channels of both bodies. */
static double rel_l2(float *const *a, float *const *ref, const hl_dyn_object *o, uint32_t nobj)
{
    double num = 0, den = 0;
    for (uint32_t b = 0; b < nobj; b++)
        for (size_t i = 0; i < 3 * (size_t)o[b].nverts; i++) {
            double d = (double)a[b][i] - ref[b][i];
            num += d * d, den += (double)ref[b][i] * ref[b][i];
        }
    return den > 0 ? sqrt(num / den) : 0.0;
}

/* sum (a - ref) / sum ref over both bodies and channels: > 0 where the
 * frame leaks light on the whole, < 0 where it over-darkens. */
static double rel_bias(float *const *a, float *const *ref, const hl_dyn_object *o, uint32_t nobj)
{
    double num = 0, den = 0;
    for (uint32_t b = 0; b < nobj; b++)
        for (size_t i = 0; i < 3 * (size_t)o[b].nverts; i++) num += (double)a[b][i] - ref[b][i], den += ref[b][i];
    return den > 0 ? num / den : 0.0;
}

/* Relative L2 over the ground's (body 1) vertices farther from the
 * bunny's world box, in x or z, than a quarter of its height: away from
 * contact (the ground reaches about one bunny height past the box). */
static double rel_l2_far(float *const *a, float *const *ref, const hl_dyn_object *o, const float lo[3], const float hi[3])
{
    double num = 0, den = 0, h = 0.25 * (hi[1] - lo[1]);
    float *pos = malloc((size_t)o[1].nverts * 12), *nrm = malloc((size_t)o[1].nverts * 12);
    if (!pos || !nrm) { free(pos), free(nrm); return 0.0; }
    hl_frame_to_world(&o[1], pos, nrm);
    for (uint32_t v = 0; v < o[1].nverts; v++) {
        const float *p = pos + 3 * v;
        if (p[0] > lo[0] - h && p[0] < hi[0] + h && p[2] > lo[2] - h && p[2] < hi[2] + h) continue;
        for (int c = 0; c < 3; c++) {
            double d = (double)a[1][3 * v + c] - ref[1][3 * v + c];
            num += d * d, den += (double)ref[1][3 * v + c] * ref[1][3 * v + c];
        }
    }
    free(pos), free(nrm);
    return den > 0 ? sqrt(num / den) : 0.0;
}

/* Relative L2 of body b alone. */
static double rel_l2_body(float *const *a, float *const *ref, const hl_dyn_object *o, uint32_t b)
{
    return rel_l2(a + b, ref + b, o + b, 1);
}

/* One map: the frame, the exact and the K-lights references at rest and
 * moved (lifted 0.3 of the bunny's height, sideways half its width). The
 * frame state st (made once: a fresh one pays PoCL's first-frame cost)
 * takes up to HL_LIGHTS_DEFAULT_KEEP lights. */
/* HL_TEST_ACCURACY_CACHE=DIR: the references of each map and pose kept
 * in DIR and read back on the next run (the same S), so that settings can
 * be compared without tracing them again. 1: read, 0: not there. */
static int cache_io(const char *name, int moved, uint32_t S, const hl_dyn_object *obj, float *const *ex, float *const *li,
                    int write)
{
    const char *dir = getenv("HL_TEST_ACCURACY_CACHE");
    if (!dir) return 0;
    char path[1024];
    snprintf(path, sizeof path, "%s/%s-%d-S%u.ref", dir, name, moved, S);
    FILE *f = fopen(path, write ? "wb" : "rb");
    if (!f) return 0;
    int ok = 1;
    for (uint32_t b = 0; b < 2; b++) {
        size_t n = 3 * (size_t)obj[b].nverts;
        ok = ok && (write ? fwrite(ex[b], 4, n, f) == n && fwrite(li[b], 4, n, f) == n
                          : fread(ex[b], 4, n, f) == n && fread(li[b], 4, n, f) == n);
    }
    fclose(f);
    return ok;
}

static void accuracy_map(hl_context *ctx, hl_frame_state *const *sts, const char *const *st_names, uint32_t nst,
                         const char *name, const hl_env *env, hl_dyn_object *obj,
                         const float *const *alb, float *const *fr, float *const *ex, float *const *li, uint32_t S)
{
    hl_light_split *s = split_of(ctx, env, HL_LIGHTS_DEFAULT_KEEP);
    if (!s) return;
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (uint32_t v = 0; v < obj[0].nverts; v++)
        for (int c = 0; c < 3; c++) lo[c] = fminf(lo[c], obj[0].pos[3 * v + c]), hi[c] = fmaxf(hi[c], obj[0].pos[3 * v + c]);
    const float x0 = obj[0].xf[3], y0 = obj[0].xf[7];
    for (int moved = 0; moved < 2; moved++) {
        obj[0].xf[3] = x0 + (moved ? 0.5f * (hi[0] - lo[0]) : 0.0f);
        obj[0].xf[7] = y0 + (moved ? 0.3f * (hi[1] - lo[1]) : 0.0f);
        hl_frame_stats fs;
        hl_dyn_ref_stats es = {0}, ls;
        int ok = 1;
        if (!cache_io(name, moved, S, obj, ex, li, 0)) {
            ok = hl_dyn_reference_exact(ctx, obj, 2, alb, env, 0, S, ex, &es) == HL_OK &&
                 hl_dyn_reference_lights(ctx, obj, 2, alb, s, S, li, &ls) == HL_OK;
            if (ok) cache_io(name, moved, S, obj, ex, li, 1);
        }
        if (!ok) { printf("%s: %s\n", name, hl_context_last_error(ctx)); break; }
        for (uint32_t q = 0; q < nst; q++) {
        if (hl_frame_render(sts[q], obj, 2, alb, s, fr, &fs) != HL_OK) { printf("%s: %s\n", name, hl_context_last_error(ctx)); break; }
        float wlo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, whi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
        for (uint32_t v = 0; v < obj[0].nverts; v++)
            for (int c = 0; c < 3; c++) {
                const float *x = obj[0].xf + 4 * c, *p = obj[0].pos + 3 * v;
                float w = x[0] * p[0] + x[1] * p[1] + x[2] * p[2] + x[3];
                wlo[c] = fminf(wlo[c], w), whi[c] = fmaxf(whi[c], w);
            }
        printf("| %-9s | %-7s | %-5s | %4.1f%% | %6.2f%% | %+6.2f%% | %6.2f%% | %6.2f%% | %6.2f%% | %6.2f%% | %6.2f%% | %6.2f%% | %4.0f ms "
               "| %.1f s, %.0fM rays |\n",
               name, st_names[q], moved ? "moved" : "rest", 100 * s->stats.folded_share, 100 * rel_l2(fr, ex, obj, 2),
               100 * rel_bias(fr, ex, obj, 2),
               100 * rel_l2_body(fr, ex, obj, 0), 100 * rel_l2_body(fr, ex, obj, 1), 100 * rel_l2_far(fr, ex, obj, wlo, whi),
               100 * rel_l2(li, ex, obj, 2),
               100 * rel_l2_body(li, ex, obj, 0), 100 * rel_l2_body(li, ex, obj, 1), 1e3 * fs.t_total, es.seconds,
               1e-6 * (double)es.rays_cast);
        fflush(stdout);
        }
    }
    obj[0].xf[3] = x0, obj[0].xf[7] = y0;
    hl_light_split_destroy(s);
}

static void accuracy(uint32_t S, const char *only)
{
    static const char *maps[] = {"city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"};
    hl_context *ctx = hl_test_cl_context(0);
    if (!ctx) ctx = hl_test_ref_context(2);
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    hl_mesh *mesh = NULL;
    hl_dyn_scene *scene = NULL;
    hl_dyn_object obj[2];
    hl_ground_desc gd = {0};
    if (hl_mesh_load(ctx, path, NULL, &mesh, NULL) != HL_OK || hl_dyn_scene_from_mesh(ctx, mesh, &gd, &scene) != HL_OK ||
        hl_dyn_scene_at(scene, 0.0, obj) != HL_OK) {
        printf("the bunny: %s\n", hl_context_last_error(ctx));
        hl_context_destroy(ctx);
        return;
    }
    const float *alb[2];
    float *fr[2], *ex[2], *li[2];
    for (uint32_t b = 0; b < 2; b++) {
        alb[b] = hl_dyn_scene_body_albedo(scene, b);
        fr[b] = malloc((size_t)obj[b].nverts * 12), ex[b] = malloc((size_t)obj[b].nverts * 12);
        li[b] = malloc((size_t)obj[b].nverts * 12);
    }
    printf("bunny + ground, %u + %u vertices, K = %d, R = %u, M = %u, exact at F = %u, S = %u, K-lights "
           "at S = %u; relative L2 against the exact reference\n", obj[0].nverts, obj[1].nverts, HL_LIGHTS_DEFAULT_KEEP,
           HL_SHADOW_DEFAULT_R, HL_CSM_M_DEFAULT, HL_DYNREF_DEFAULT_FACE, S ? S : HL_DYNREF_DEFAULT_S,
           S ? S : HL_DYNREF_LIGHTS_DEFAULT_S);
    printf("| map | shadow | bunny | folded | frame | frame bias | frame: bunny | frame: ground | frame: far ground | K-lights | K-lights: bunny | "
           "K-lights: ground | frame time | exact time |\n");
    /* HL_TEST_SHADOW: csm (the default), moments or both, one row each */
    const char *want = getenv("HL_TEST_SHADOW");
    hl_frame_state *sts[2] = {NULL, NULL}, *st = NULL;
    const char *st_names[2];
    uint32_t nst = 0;
    for (int rep = 0; rep < 2; rep++) {
        const char *nm = rep ? "moments" : "csm";
        if (want ? strcmp(want, "both") && strcmp(want, nm) : rep) continue;
        hl_frame_settings set = {.min_share = -1.0f, .shadow = rep ? HL_SHADOW_REP_MOMENTS : HL_SHADOW_REP_CSM};
        if (hl_frame_state_create(ctx, obj, 2, HL_LIGHTS_DEFAULT_KEEP, &set, &sts[nst]) != HL_OK)
            printf("the frame state: %s\n", hl_context_last_error(ctx));
        else st_names[nst++] = nm;
    }
    st = nst ? sts[0] : NULL;
    for (size_t m = 0; st && m <= sizeof maps / sizeof *maps; m++) {
        const char *name = m < sizeof maps / sizeof *maps ? maps[m] : "sky";
        if (only && strcmp(only, name)) continue;
        hl_env *env = NULL;
        if (m < sizeof maps / sizeof *maps) {
            snprintf(path, sizeof path, "%s/envmaps/%s.exr", hl_test_env("HL_TEST_DATA", ""), maps[m]);
            if (hl_env_load(ctx, path, &env, NULL) != HL_OK) { printf("%s: skipped (%s)\n", maps[m], path); continue; }
        } else {
            hl_sky_desc sd = {0};
            sd.width = 512;
            if (hl_env_create_sky(ctx, &sd, &env) != HL_OK) continue;
        }
        accuracy_map(ctx, sts, st_names, nst, name, env, obj, alb, fr, ex, li, S);
        hl_env_destroy(env);
    }
    for (uint32_t q = 0; q < nst; q++) hl_frame_state_destroy(sts[q]);
    for (int b = 0; b < 2; b++) free(fr[b]), free(ex[b]), free(li[b]);
    hl_dyn_scene_destroy(scene);
    hl_mesh_destroy(mesh);
    hl_context_destroy(ctx);
}

/* The exact reference's own error: F and S against 2 S and against 2 F,
 * on the bunny at rest under MAP. */
static void convergence(const char *map, uint32_t S, uint32_t F)
{
    hl_context *ctx = hl_test_ref_context(2);
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    hl_mesh *mesh = NULL;
    hl_dyn_scene *scene = NULL;
    hl_dyn_object obj[2];
    hl_ground_desc gd = {0};
    hl_env *env = NULL;
    if (hl_mesh_load(ctx, path, NULL, &mesh, NULL) != HL_OK || hl_dyn_scene_from_mesh(ctx, mesh, &gd, &scene) != HL_OK ||
        hl_dyn_scene_at(scene, 0.0, obj) != HL_OK) {
        printf("the bunny: %s\n", hl_context_last_error(ctx));
        return;
    }
    snprintf(path, sizeof path, "%s/envmaps/%s.exr", hl_test_env("HL_TEST_DATA", ""), map);
    if (hl_env_load(ctx, path, &env, NULL) != HL_OK) printf("%s: %s\n", path, hl_context_last_error(ctx));
    const float *alb[2];
    float *a[2], *b4[2], *f64[2];
    for (uint32_t b = 0; b < 2; b++) {
        alb[b] = hl_dyn_scene_body_albedo(scene, b);
        a[b] = malloc((size_t)obj[b].nverts * 12), b4[b] = malloc((size_t)obj[b].nverts * 12);
        f64[b] = malloc((size_t)obj[b].nverts * 12);
    }
    hl_dyn_ref_stats s1, s4, s64;
    if (env && hl_dyn_reference_exact(ctx, obj, 2, alb, env, F, S, a, &s1) == HL_OK &&
        hl_dyn_reference_exact(ctx, obj, 2, alb, env, F, 2 * S, b4, &s4) == HL_OK &&
        hl_dyn_reference_exact(ctx, obj, 2, alb, env, 2 * F, S, f64, &s64) == HL_OK)
        printf("%s: F %u S %u (%.1f s) against F %u S %u (%.1f s): %.3f%%, against F %u S %u (%.1f s): %.3f%% "
               "relative L2\n", map, F, S, s1.seconds, F, 2 * S, s4.seconds, 100 * rel_l2(a, b4, obj, 2), 2 * F, S, s64.seconds,
               100 * rel_l2(a, f64, obj, 2));
    for (int b = 0; b < 2; b++) free(a[b]), free(b4[b]), free(f64[b]);
    hl_env_destroy(env);
    hl_dyn_scene_destroy(scene);
    hl_mesh_destroy(mesh);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    if (argc > 2 && !strcmp(argv[1], "convergence")) {
        convergence(argv[2], argc > 3 ? (uint32_t)strtoul(argv[3], NULL, 10) : 1,
                    argc > 4 ? (uint32_t)strtoul(argv[4], NULL, 10) : HL_DYNREF_DEFAULT_FACE);
        return 0;
    }
    if (argc > 1 && !strcmp(argv[1], "accuracy")) {
        accuracy(argc > 2 ? (uint32_t)strtoul(argv[2], NULL, 10) : 0, argc > 3 ? argv[3] : NULL);
        return 0;
    }
    static const hl_test_case cases[] = {{"furnace", case_furnace},
                                         {"unoccluded", case_unoccluded},
                                         {"occluded", case_occluded},
                                         {"traced", case_traced},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
