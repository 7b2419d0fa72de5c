/* test_dyn_frame.c - one frame of the dynamic method
 * (host/src/dynamic/dyn_frame.c), suite "dyn_frame".
 *
 * dyn_frame.unshadowed   a lone ground grid under the sky: B equals
 *                        albedo / pi times the map's irradiance on +Y,
 *                        summed here from the map's pixels.
 * dyn_frame.motion       the bunny on its ground under the sky: the
 *                        darkening of the ground lies away from the sun
 *                        and its centroid follows the bunny's offset.
 * dyn_frame.twin         the frame on the OpenCL context against the
 *                        reference context.
 * dyn_frame.device       the device frame (kernels/dynamic/dyn_shade.cl)
 *                        against its twin, the host's receivers on the same
 *                        device (HL_TEST_DYN_FRAME=host): the bunny on its
 *                        ground at rest and moved, batches of 5 lights in
 *                        groups of 2 (HL_TEST_FRAME_GROUP), negligible
 *                        lights, the ground out of the maps: bit for bit.
 * dyn_frame.bad_input    every output finite and >= 0; bad settings and
 *                        mismatched frames refused.
 * dyn_frame.api          the public hl_dynamic_* functions: bodies, moves
 *                        (the merged mesh follows), refusals.
 * dyn_frame.cli          `haarlight relight-dynamic`: bad options exit 2,
 *                        a small run writes its PLY.
 * dyn_frame.file         a glTF file of two bodies, one animated: the
 *                        merged mesh at a time and after a move; the
 *                        command's --reference exact and --diff on it.
 * dyn_frame.keep         the shadow maps kept from the last frame, on the
 *                        device's receivers and the host's, moments and
 *                        CSM, and on the reference backend: kept when nothing moved or only the ground
 *                        did, made again when the bunny moved, the ground
 *                        went through it, the split changed or a frame
 *                        failed; each frame bit for bit a new frame
 *                        state's at the same positions. Several batches
 *                        keep nothing.
 * dyn_frame.sharp_rays   the sharp lights' rays (sharp_rays.h) under a
 *                        square over a grid against the plane's share of
 *                        free samples (tolerance 0); the bunny's frame with
 *                        the sun by rays nearer the lights traced than
 *                        with the sun in a map, host and device receivers
 *                        bit for bit.
 * timing [MIB [R]]       not a ctest case (asserts nothing): the bunny on
 *                        its ground at K = 32, R (default 256), M = 16, a
 *                        first frame, then 9 rounds of three: the bunny
 *                        nudged (every map made), the same again and the
 *                        ground nudged (the maps kept), and each kind's
 *                        median stages; MIB: the batch budget (0: the
 *                        default, HL_FRAME_DEFAULT_BUDGET).
 * Depends on: dyn_frame.h, scene.h, area_lights.h, hl_test.h,
 * scene_gen.h, HL_REPO_DATA (bunny_lowres.obj), HL_BIN.
 */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include <float.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#include "dyn_frame.h"
#include "dyn_reference.h"
#include "dyn_util.h"
#include "enclosed.h"
#include "haarlight_tools.h"
#include "hl_test.h"
#include "scene.h"
#include "scene_gen.h"
#include "sharp_rays.h"

#define PI_D 3.14159265358979323846


static double lum(const float *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

/* The sky of the tests: the sun at 35 degrees towards +X (the default). */
static hl_env *sky(hl_context *ctx)
{
    hl_sky_desc sd = {0};
    sd.width = 512;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create_sky(ctx, &sd, &env) == HL_OK, "%s", hl_context_last_error(ctx));
    return env;
}

/* Irradiance of the whole map on unit n, summed from its pixels:
 * radiance x the pixel's solid angle x max(0, n . w) at its centre. */
static void env_irradiance(const hl_env *env, const double n[3], double E[3])
{
    E[0] = E[1] = E[2] = 0;
    const uint32_t W = env->width, H = env->height;
    for (uint32_t j = 0; j < H; j++) {
        double th0 = PI_D * j / H, th1 = PI_D * (j + 1) / H, th = PI_D * (j + 0.5) / H;
        double omega = 2 * PI_D / W * (cos(th0) - cos(th1));
        for (uint32_t i = 0; i < W; i++) {
            double ph = 2 * PI_D * ((i + 0.5) / W - 0.5);
            double w[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
            double c = n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
            if (c <= 0) continue;
            const float *L = env->rgb + 3 * ((size_t)j * W + i);
            for (int k = 0; k < 3; k++) E[k] += L[k] * omega * c;
        }
    }
}

/* ------------------------------------------------------------ unshadowed */

enum { GRID = 24 }; /* quads a side of the lone ground */

static void case_unshadowed(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    const uint32_t nv = (GRID + 1) * (GRID + 1), nt = 2 * GRID * GRID;
    float *pos = malloc(nv * 12), *nrm = malloc(nv * 12), *alb = malloc(nv * 12), *rgb = malloc(nv * 12);
    uint32_t *tri = malloc(nt * 12), t = 0;
    for (uint32_t j = 0; j <= GRID; j++)
        for (uint32_t i = 0; i <= GRID; i++) {
            uint32_t v = j * (GRID + 1) + i;
            float p[3] = {(float)i / GRID * 2 - 1, 0.0f, (float)j / GRID * 2 - 1}, up[3] = {0, 1, 0};
            memcpy(pos + 3 * v, p, 12), memcpy(nrm + 3 * v, up, 12);
            alb[3 * v] = 0.8f, alb[3 * v + 1] = 0.6f, alb[3 * v + 2] = 0.4f;
        }
    for (uint32_t j = 0; j < GRID; j++)
        for (uint32_t i = 0; i < GRID; i++) {
            uint32_t a = j * (GRID + 1) + i, b = a + 1, c = a + GRID + 1, d = c + 1;
            uint32_t q[6] = {a, c, b, b, c, d}; /* counter-clockwise seen from +Y */
            memcpy(tri + 3 * t, q, 24), t += 2;
        }
    hl_dyn_object o = {pos, nrm, nv, tri, nt, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
    hl_env *env = sky(ctx);
    hl_light_split *s = env ? split_of(ctx, env, 32) : NULL;
    hl_frame_state *st = NULL;
    const float *albs[1] = {alb};
    float *outs[1] = {rgb};
    double n[3] = {0, 1, 0}, E[3];
    if (env) env_irradiance(env, n, E);
    /* min_share 0.05: the lights under 5% of the energy are shaded
     * unshadowed (the same sum here, since nothing blocks) */
    const float shares[2] = {-1.0f, 0.05f};
    for (int pass = 0; s && pass < 2; pass++) {
        hl_frame_settings set = {.min_share = shares[pass]};
        hl_frame_stats fs;
        HL_CHECK(hl_frame_state_create(ctx, &o, 1, s->count, &set, &st) == HL_OK, "%s", hl_context_last_error(ctx));
        if (!st) break;
        HL_CHECK(hl_frame_render(st, &o, 1, albs, s, outs, &fs) == HL_OK, "%s", hl_context_last_error(ctx));
        double worst = 0;
        for (uint32_t v = 0; v < nv; v++)
            for (int c = 0; c < 3; c++) {
                double want = alb[3 * v + c] / PI_D * E[c];
                worst = fmax(worst, fabs(rgb[3 * v + c] - want) / want);
            }
        /* lights below +Y's horizon counted here from their irradiance */
        uint32_t below = 0;
        for (uint32_t k = 0; k < s->count; k++) {
            float e[3], up[3] = {0, 1, 0};
            hl_area_light_irradiance(s, k, up, e);
            below += e[0] == 0.0f && e[1] == 0.0f && e[2] == 0.0f;
        }
        printf("min_share %g: lights %u, shadowed %u, below the horizon %u, negligible %u; folded share %.4f\n",
               (double)shares[pass], fs.lights, fs.shadowed, fs.skipped_horizon, fs.skipped_negligible,
               s->stats.folded_share);
        HL_CHECK(fs.skipped_horizon == below && fs.shadowed + fs.skipped_horizon + fs.skipped_negligible == fs.lights,
                 "counts: %u below the horizon (want %u), %u + %u + %u of %u", fs.skipped_horizon, below, fs.shadowed,
                 fs.skipped_horizon, fs.skipped_negligible, fs.lights);
        HL_CHECK(pass == 0 || fs.skipped_negligible > 0, "no light was negligible at min_share 0.05");
        /* The split conserves energy and each light's irradiance is exact
         * over its cube texels; what is left: the cube resampling of the
         * map (texels cut into subsamples, against this per-pixel sum),
         * the SH9 term of the folded share, and the smooth shadow test's
         * residual on a lit receiver (under 2e-4 at M = 16, csm.h's
         * bias), given the receiver-plane bias (dyn_frame.c) keeps the
         * plane from shadowing itself (without it: 7%). Measured 2.4e-4;
         * 1e-3 leaves room for other maps' cube resampling. */
        hl_check_error("B against albedo/pi x the map's irradiance on +Y, relative", worst, 1e-3);
        hl_frame_state_destroy(st);
        st = NULL;
    }
    hl_frame_state_destroy(st);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    free(pos); free(nrm); free(alb); free(rgb); free(tri);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ the bunny */

typedef struct bunny_scene {
    hl_mesh *mesh;
    hl_dyn_scene *scene;
    hl_dyn_object obj[2];
    const float *alb[2];
    float *rgb[2];
} bunny_scene;

static int bunny_open_ground(hl_context *ctx, bunny_scene *b, const hl_ground_desc *gdesc)
{
    memset(b, 0, sizeof *b);
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    /* the ground of 2.5 x the footprint (margin 0.75) that these cases
       were written for; the default one now reaches the shadow of a sun
       15 degrees high (3.7 x the bunny's height), a wider scene (below's
       error against the traced lights is 0.126 there: docs/DYNAMIC.md) */
    hl_ground_desc gd = {.margin = 0.75f};
    if (gdesc) gd = *gdesc;
    if (hl_mesh_load(ctx, path, NULL, &b->mesh, NULL) != HL_OK ||
        hl_dyn_scene_from_mesh(ctx, b->mesh, &gd, &b->scene) != HL_OK ||
        hl_dyn_scene_at(b->scene, 0.0, b->obj) != HL_OK) {
        HL_CHECK(0, "%s", hl_context_last_error(ctx));
        return 0;
    }
    for (int k = 0; k < 2; k++) {
        b->alb[k] = hl_dyn_scene_body_albedo(b->scene, (uint32_t)k);
        b->rgb[k] = malloc((size_t)b->obj[k].nverts * 12);
    }
    return 1;
}

static int bunny_open(hl_context *ctx, bunny_scene *b) { return bunny_open_ground(ctx, b, NULL); }

static void bunny_close(bunny_scene *b)
{
    free(b->rgb[0]); free(b->rgb[1]);
    hl_dyn_scene_destroy(b->scene);
    hl_mesh_destroy(b->mesh);
}

/* The centroid (x, z) of the ground's loss of luminance rgb against the
 * unshadowed ground: B0, one value (every ground normal is +Y), or per
 * vertex where B0v is given. */
static void loss_centroid(const bunny_scene *b, const float *rgb, double B0, const float *B0v, double c[2],
                          double *total)
{
    double sw = 0, sx = 0, sz = 0;
    const hl_dyn_object *g = &b->obj[1];
    for (uint32_t v = 0; v < g->nverts; v++) {
        double loss = (B0v ? lum(B0v + 3 * (size_t)v) : B0) - lum(rgb + 3 * (size_t)v);
        if (loss <= 0) continue;
        const float *p = g->pos + 3 * (size_t)v; /* the ground stays at the identity */
        sw += loss, sx += loss * p[0], sz += loss * p[2];
    }
    c[0] = sx / sw, c[1] = sz / sw;
    *total = sw;
}

static void case_motion(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    bunny_scene b;
    hl_env *env = sky(ctx);
    hl_light_split *s = env ? split_of(ctx, env, 16) : NULL;
    hl_frame_state *st = NULL;
    hl_frame_settings set = {.R = 256, .M = 16, .min_share = -1.0f};
    memset(&b, 0, sizeof b);
    /* a wider ground (margin 2, graded beyond 0.75; 192 quads across
       its middle square), so that the shadow stays on it when the bunny
       moves */
    hl_ground_desc wide = {.resolution = 192, .margin = 2.0f};
    if (!s || !bunny_open_ground(ctx, &b, &wide)) goto close;
    HL_CHECK(hl_frame_state_create(ctx, b.obj, 2, s->count, &set, &st) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!st) goto close;
    /* the unshadowed ground: albedo / pi (sum_k E_k + ambient) on +Y */
    float up[3] = {0, 1, 0}, E[3], sum[3];
    hl_light_split_ambient(s, up, sum);
    for (uint32_t k = 0; k < s->count; k++) {
        hl_area_light_irradiance(s, k, up, E);
        for (int c = 0; c < 3; c++) sum[c] += E[c];
    }
    for (int c = 0; c < 3; c++) sum[c] *= b.alb[1][c] / (float)PI_D;
    double B0 = lum(sum), c0[2], c1[2], l0, l1;
    float lo[3], hi[3];
    HL_CHECK(hl_dyn_scene_bounds(b.scene, 0.0, lo, hi) == HL_OK, "bounds");
    /* the bunny's footprint: its own bounds */
    float blo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, bhi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (uint32_t v = 0; v < b.obj[0].nverts; v++)
        for (int k = 0; k < 3; k++) {
            blo[k] = fminf(blo[k], b.obj[0].pos[3 * v + k]);
            bhi[k] = fmaxf(bhi[k], b.obj[0].pos[3 * v + k]);
        }
    /* the exact reference's ground: alone (its unshadowed self), then
       with the bunny at rest and moved (F = 16: the centroids of broad
       shadows need no finer directions) */
    size_t gbytes = (size_t)b.obj[1].nverts * 12;
    float *ex0 = malloc(gbytes), *ex1 = malloc(gbytes), *exg = malloc(gbytes), *exb = malloc((size_t)b.obj[0].nverts * 12);
    float *ex_rest[2] = {exb, ex0}, *ex_moved[2] = {exb, ex1}, *ex_alone[1] = {exg};
    double e0[2], e1[2], el0, el1;
    HL_CHECK(hl_dyn_reference_exact(ctx, &b.obj[1], 1, &b.alb[1], env, 16, 1, ex_alone, NULL) == HL_OK &&
             hl_dyn_reference_exact(ctx, b.obj, 2, b.alb, env, 16, 1, ex_rest, NULL) == HL_OK,
             "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    loss_centroid(&b, b.rgb[1], B0, NULL, c0, &l0);
    loss_centroid(&b, ex0, 0, exg, e0, &el0);
    /* sideways: across the sun's direction (+X), a third of the bunny's depth */
    double dz = 0.33 * (bhi[2] - blo[2]);
    double tr[3] = {0, 0, dz}, axis[3] = {0, 1, 0};
    HL_CHECK(hl_dyn_scene_set_pose(b.scene, 0, tr, axis, 0.0) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dyn_scene_at(b.scene, 0.0, b.obj) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_frame_stats fs;
    HL_CHECK(hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, &fs) == HL_OK, "%s", hl_context_last_error(ctx));
    loss_centroid(&b, b.rgb[1], B0, NULL, c1, &l1);
    HL_CHECK(hl_dyn_reference_exact(ctx, b.obj, 2, b.alb, env, 16, 1, ex_moved, NULL) == HL_OK, "%s",
             hl_context_last_error(ctx));
    loss_centroid(&b, ex1, 0, exg, e1, &el1);
    double bx = 0.5 * (blo[0] + bhi[0]);
    printf("loss centroid (%.4f, %.4f) -> (%.4f, %.4f), bunny moved by (0, %.4f), its centre x %.4f; total loss %.4g "
           "-> %.4g\n", c0[0], c0[1], c1[0], c1[1], dz, bx, l0, l1);
    printf("exact reference: (%.4f, %.4f) -> (%.4f, %.4f); total loss %.4g -> %.4g\n", e0[0], e0[1], e1[0], e1[1], el0,
           el1);
    /* The ground is one fixed vertex grid (cells of about 8% of the
     * offset) that samples the moved shadow at other places, and part of
     * a shadow may leave the ground: even the exact shadow's centroid
     * need not shift by exactly the offset (printed). The frame's must
     * shift as the exact one's does, within a quarter of a cell: 2% of
     * the offset, along z and across. */
    hl_check_error("frame's loss centroid shift along z against the exact reference's, relative to the offset",
                   fabs((c1[1] - c0[1]) - (e1[1] - e0[1])) / dz, 0.02);
    hl_check_error("frame's loss centroid shift along x against the exact reference's, relative to the offset",
                   fabs((c1[0] - c0[0]) - (e1[0] - e0[0])) / dz, 0.02);
    printf("exact reference's shift along z against the offset, relative (not asserted): %.4f\n",
           fabs((e1[1] - e0[1]) - dz) / dz);
    free(ex0); free(ex1); free(exg); free(exb);
    /* the sun is towards +X: the shadow falls towards -X of the bunny */
    HL_CHECK(c0[0] < bx && c1[0] < bx, "the darkening is not on the side away from the sun: x %.4f, %.4f vs %.4f",
             c0[0], c1[0], bx);
    printf("second frame (bunny moved): %.1f ms\n", 1e3 * fs.t_total);
close:
    hl_frame_state_destroy(st);
    bunny_close(&b);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* The bunny on its ground under a map bright below the horizon (1) and
 * dim above (0.2): the ground hides most of the lower light from the
 * bunny. The frame left the ground out of its maps and takes what it
 * hides from its plane, so the bunny's underside is as dark as the exact
 * reference's (F = 32) right down to the contact, where a shadow map's
 * depth bias would let the light through. */
static void case_below(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    enum { W = 128, H = 64 };
    float *px = malloc((size_t)W * H * 12);
    for (size_t i = 0; i < (size_t)W * H; i++)
        for (int c = 0; c < 3; c++) px[3 * i + c] = i / W >= H / 2 ? 1.0f : 0.2f;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ctx, W, H, px, &env, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    free(px);
    bunny_scene b;
    hl_light_split *s = env ? split_of(ctx, env, 32) : NULL;
    hl_frame_state *st = NULL;
    hl_frame_settings set = {.R = 256, .M = 16, .min_share = -1.0f};
    float *ex[2] = {NULL, NULL};
    if (!s || !bunny_open(ctx, &b)) goto close;
    HL_CHECK(hl_frame_state_create(ctx, b.obj, 2, s->count, &set, &st) == HL_OK &&
             hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    ex[0] = malloc((size_t)b.obj[0].nverts * 12), ex[1] = malloc((size_t)b.obj[1].nverts * 12);
    HL_CHECK(hl_dyn_reference_exact(ctx, b.obj, 2, b.alb, env, 32, 1, ex, NULL) == HL_OK, "%s",
             hl_context_last_error(ctx));
    double num = 0, den = 0, mean_f = 0, mean_e = 0;
    for (size_t i = 0; i < 3 * (size_t)b.obj[0].nverts; i++) {
        double e = (double)b.rgb[0][i] - ex[0][i];
        num += e * e, den += (double)ex[0][i] * ex[0][i];
        mean_f += b.rgb[0][i], mean_e += ex[0][i];
    }
    /* the same lights with traced visibility: what the light split
       alone leaves */
    float *kl[2] = {malloc((size_t)b.obj[0].nverts * 12), malloc((size_t)b.obj[1].nverts * 12)};
    HL_CHECK(hl_dyn_reference_lights(ctx, b.obj, 2, b.alb, s, 0, kl, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    double numk = 0, mean_k = 0, numf = 0, denk = 0;
    for (size_t i = 0; i < 3 * (size_t)b.obj[0].nverts; i++) {
        double e = (double)kl[0][i] - ex[0][i], g = (double)b.rgb[0][i] - kl[0][i];
        numk += e * e, mean_k += kl[0][i], numf += g * g, denk += (double)kl[0][i] * kl[0][i];
    }
    free(kl[0]); free(kl[1]);
    double nb = 3.0 * b.obj[0].nverts;
    printf("bunny's mean: frame %.4g, K lights traced %.4g, exact %.4g; relative L2 against the exact: frame "
           "%.4f, K lights traced %.4f (the split's own share)\n",
           mean_f / nb, mean_k / nb, mean_e / nb, sqrt(num / den), sqrt(numk / den));
    /* the shadows' part of the error: the frame against the same lights
       traced. With the ground in the maps its light leaked through the
       depth bias at the contact: 118%. What is left is the bunny's own
       shadows under lights as broad as these (whole half-faces), which
       the shadow maps blur: 7%; the table in DYNAMIC.md has 1 to 5% for
       the moved bunny under the shared maps */
    hl_check_error("bunny, relative L2 against the K lights traced", sqrt(numf / denk), 0.10);
    /* the contact itself: the bunny's vertices within 5% of its height of
       the ground, where a depth bias would let the lower light through */
    float lo = INFINITY, hi = -INFINITY;
    for (uint32_t v = 0; v < b.obj[0].nverts; v++) {
        lo = fminf(lo, b.obj[0].pos[3 * v + 1]);
        hi = fmaxf(hi, b.obj[0].pos[3 * v + 1]);
    }
    double low_f = 0, low_e = 0;
    uint32_t nlow = 0;
    for (uint32_t v = 0; v < b.obj[0].nverts; v++)
        if (b.obj[0].pos[3 * v + 1] < lo + 0.05f * (hi - lo)) {
            low_f += lum(b.rgb[0] + 3 * (size_t)v), low_e += lum(ex[0] + 3 * (size_t)v), nlow++;
        }
    printf("%u vertices at the contact: mean luminance frame %.4g, exact %.4g (the whole bunny's: %.4g)\n", nlow,
           low_f / nlow, low_e / nlow, mean_e / nb);
    /* a leak makes the contact brighter than the exact one; no brighter
       than it by more than the bunny's own error allows (10%, above). Darker
       it is (by a fifth: the texel blocks and the exact reference's rays
       leaving the lowest ring just under the plane), which the L2 above
       bounds */
    hl_check_error("at the contact, mean luminance over the exact reference's, minus 1, if brighter",
                   fmax(low_f / low_e - 1.0, 0.0), 0.10);
close:
    free(ex[0]); free(ex[1]);
    hl_frame_state_destroy(st);
    if (s) bunny_close(&b);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ twin */

/* The bunny's frame on ctx at K lights, R, M; rgb[b] filled. */
static int bunny_frame(hl_context *ctx, bunny_scene *b, const hl_env *env, int32_t K, uint32_t R, uint32_t M,
                       hl_frame_stats *fs)
{
    hl_light_split *s = split_of(ctx, env, K);
    hl_frame_state *st = NULL;
    hl_frame_settings set = {.R = R, .M = M, .min_share = -1.0f};
    int ok = s && hl_frame_state_create(ctx, b->obj, 2, s->count, &set, &st) == HL_OK &&
             hl_frame_render(st, b->obj, 2, b->alb, s, b->rgb, fs) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    hl_frame_state_destroy(st);
    hl_light_split_destroy(s);
    return ok;
}

static void case_twin(void)
{
    hl_context *ctx = hl_test_cl_context(2), *ref = hl_test_ref_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); hl_context_destroy(ref); return; }
    bunny_scene a, r;
    memset(&a, 0, sizeof a), memset(&r, 0, sizeof r);
    hl_env *env = sky(ctx);
    hl_frame_stats fa, fr;
    if (env && bunny_open(ctx, &a) && bunny_open(ref, &r) && bunny_frame(ctx, &a, env, 8, 128, 16, &fa) &&
        bunny_frame(ref, &r, env, 8, 128, 16, &fr)) {
        double top = 0, worst = 0, sum = 0;
        uint64_t n = 0;
        for (int k = 0; k < 2; k++)
            for (size_t i = 0; i < 3 * (size_t)a.obj[k].nverts; i++) top = fmax(top, a.rgb[k][i]);
        for (int k = 0; k < 2; k++)
            for (size_t i = 0; i < 3 * (size_t)a.obj[k].nverts; i++) {
                double d = fabs(a.rgb[k][i] - r.rgb[k][i]) / top;
                worst = fmax(worst, d), sum += d, n++;
            }
        printf("OpenCL %s: %.1f ms, reference: %.1f ms; mean difference %.3g of the brightest\n",
               hl_context_device_name(ctx), 1e3 * fa.t_total, 1e3 * fr.t_total, sum / (double)n);
        /* The maps agree texel for texel (the rasteriser's twin repeats
         * its arithmetic); the CSM tables differ by PoCL's sin and cos
         * against libm's summed over R^2 texels (csm_eval.twin measures
         * the module end to end only), so V may move by 1e-3 where a
         * filter box is read from the tables; times E_k / E_total of one
         * light that is at most that of the sun. 1e-3 of the brightest
         * colour (measured 9e-5). */
        hl_check_error("B, OpenCL vs reference backend, relative to the brightest", worst, 1e-3);
    }
    bunny_close(&a);
    bunny_close(&r);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

/* The bunny's two frames (at rest, then lifted and moved) on a new frame
 * state: batches of 5 lights at R = 64, lights under 2% of the energy
 * negligible; out[f] gets frame f's colours, both bodies. */
static int device_frames(hl_context *ctx, bunny_scene *b, const hl_light_split *s, float *out[2], hl_frame_stats *fs,
                         hl_shadow_rep shadow)
{
    /* a budget of 5 lights of the representation's */
    hl_frame_settings set = {.R = 64, .M = 16, .min_share = 0.02f, .shadow = shadow,
                             .budget = 5 * (uint64_t)hl_csm_bytes_per_light_rep(shadow, 64, 16, 16) + 1};
    hl_frame_state *st = NULL;
    int ok = hl_frame_state_create(ctx, b->obj, 2, s->count, &set, &st) == HL_OK;
    const hl_dyn_object rest = b->obj[0];
    for (int f = 0; ok && f < 2; f++) {
        if (f) b->obj[0].xf[3] += 0.7f, b->obj[0].xf[7] += 0.4f; /* lifted and pushed along x, world units */
        ok = hl_frame_render(st, b->obj, 2, b->alb, s, b->rgb, &fs[f]) == HL_OK;
        for (int k = 0; ok && k < 2; k++)
            memcpy(out[f] + (k ? 3 * (size_t)b->obj[0].nverts : 0), b->rgb[k], (size_t)b->obj[k].nverts * 12);
    }
    b->obj[0] = rest;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    hl_frame_state_destroy(st);
    return ok;
}

static void case_device(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    /* bright below the horizon (the ground hides it from the bunny: the
       flat bodies' occlusion) with a small sun above */
    enum { W = 128, H = 64 };
    float *px = malloc((size_t)W * H * 12);
    for (size_t i = 0; i < (size_t)W * H; i++)
        for (int c = 0; c < 3; c++) px[3 * i + c] = i / W >= H / 2 ? 1.0f : (i % W == 20 && i / W == 12) ? 400.0f : 0.2f;
    hl_env *env = NULL;
    HL_CHECK(hl_env_create(ctx, W, H, px, &env, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    free(px);
    bunny_scene b;
    hl_light_split *s = env && bunny_open(ctx, &b) ? split_of(ctx, env, 32) : NULL;
    for (int q = 0; s && q < 2; q++) {
        const hl_shadow_rep shadow = q ? HL_SHADOW_REP_MOMENTS : HL_SHADOW_REP_CSM;
        printf("%s:\n", q ? "moments" : "CSM");
        const size_t n = 3 * ((size_t)b.obj[0].nverts + b.obj[1].nverts);
        float *dev[2] = {malloc(n * 4), malloc(n * 4)}, *host[2] = {malloc(n * 4), malloc(n * 4)};
        hl_frame_stats fd[2], fh[2];
        setenv("HL_TEST_FRAME_GROUP", "2", 1);
        int ok = device_frames(ctx, &b, s, dev, fd, shadow);
        setenv("HL_TEST_DYN_FRAME", "host", 1);
        ok = ok && device_frames(ctx, &b, s, host, fh, shadow);
        unsetenv("HL_TEST_DYN_FRAME");
        unsetenv("HL_TEST_FRAME_GROUP");
        for (int f = 0; ok && f < 2; f++) {
            size_t diff = 0;
            double top = 0;
            for (size_t i = 0; i < n; i++) diff += memcmp(dev[f] + i, host[f] + i, 4) != 0, top = fmax(top, dev[f][i]);
            printf("%s frame: %u lights shadowed in %u batches of %u, %u negligible; device %.1f ms, host %.1f ms; "
                   "brightest %.3g\n", f ? "moved" : "rest", fd[f].shadowed, fd[f].batches, fd[f].batch_lights,
                   fd[f].skipped_negligible, 1e3 * fd[f].t_total, 1e3 * fh[f].t_total, top);
            HL_CHECK(fd[f].batches > 1 && fd[f].skipped_negligible > 0 && top > 0,
                     "the scene must take several batches and leave lights negligible");
            hl_check_error("colour floats that differ, device frame vs host (tolerance 0: bit for bit)", (double)diff, 0.0);
        }
        for (int f = 0; f < 2; f++) free(dev[f]), free(host[f]);
    }
    if (s) bunny_close(&b);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ keep */

/* Float values of n that differ bit for bit. */
static size_t floats_differ(const float *a, const float *b, size_t n)
{
    size_t d = 0;
    for (size_t i = 0; i < n; i++) d += memcmp(a + i, b + i, 4) != 0;
    return d;
}

/* Frame of st (both bodies' colours into out, the bunny first). */
static int keep_frame(hl_context *ctx, hl_frame_state *st, bunny_scene *b, const hl_light_split *s, float *out,
                      hl_frame_stats *fs)
{
    int ok = hl_frame_render(st, b->obj, 2, b->alb, s, b->rgb, fs) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    for (int k = 0; ok && k < 2; k++)
        memcpy(out + (k ? 3 * (size_t)b->obj[0].nverts : 0), b->rgb[k], (size_t)b->obj[k].nverts * 12);
    return ok;
}

/* One frame of st against what a new frame state gives at the same
 * positions and lights: the maps kept (want_kept: 1 every shadowed
 * light's, 0 none, 2 the maps but not the sharp lights' rays, which are
 * cast again when any body moved) and the colours bit for bit. */
static void keep_step(hl_context *ctx, hl_frame_state *st, bunny_scene *b, const hl_light_split *s,
                      const hl_frame_settings *set, const char *what, int want_kept, float *out, float *ref)
{
    const size_t n = 3 * ((size_t)b->obj[0].nverts + b->obj[1].nverts);
    hl_frame_stats fs, ff;
    hl_frame_state *fresh = NULL;
    int ok = keep_frame(ctx, st, b, s, out, &fs);
    ok = ok && hl_frame_state_create(ctx, b->obj, 2, s->count, set, &fresh) == HL_OK && keep_frame(ctx, fresh, b, s, ref, &ff);
    HL_CHECK(ok, "%s: %s", what, hl_context_last_error(ctx));
    hl_frame_state_destroy(fresh);
    if (!ok) return;
    const uint32_t by_rays = fs.sharp_mode == HL_SHARP_RAYS ? fs.sharp : 0;
    const uint32_t want = want_kept == 1 ? fs.shadowed : want_kept == 2 ? fs.shadowed - by_rays : 0;
    printf("  %s: %u lights shadowed (%u sharp) in %u batch(es), maps kept %u (want %u), fresh state's %u; shadow maps "
           "%.2f ms, build %.2f ms, eval %.2f ms, frame %.2f ms (fresh state: %.2f ms)\n",
           what, fs.shadowed, fs.sharp, fs.batches, fs.maps_kept, want, ff.maps_kept, 1e3 * fs.t_shadow_maps, 1e3 * fs.t_csm_build,
           1e3 * fs.t_csm_eval, 1e3 * fs.t_total, 1e3 * ff.t_total);
    /* one batch a map size: the sharp lights' finer maps are a batch of
       their own (dyn_frame.h); rays are none */
    HL_CHECK(fs.shadowed > 0 && fs.batches == 1u + (fs.sharp > 0 && fs.sharp_mode == HL_SHARP_MAPS) && ff.maps_kept == 0,
             "%s: the scene must take one batch of shadowed lights a map size", what);
    HL_CHECK(fs.maps_kept == want, "%s: %u maps kept, want %u", what, fs.maps_kept, want);
    char line[160];
    snprintf(line, sizeof line, "  %s: colour floats that differ from a new state's (tolerance 0: bit for bit)", what);
    hl_check_error(line, (double)floats_differ(out, ref, n), 0.0);
}

/* The rule of the kept maps on one path (device or host receivers) and
 * representation: the bunny on its ground under the sky, K = 8, R = 64. */
static void keep_path(hl_context *ctx, bunny_scene *b, const hl_env *env, hl_shadow_rep shadow)
{
    hl_frame_settings set = {.R = 64, .M = 16, .min_share = -1.0f, .shadow = shadow};
    hl_light_split_params rot;
    hl_light_split_defaults(&rot);
    rot.lights = 8, rot.rotate_deg = 40.0f;
    hl_light_split *s = split_of(ctx, env, 8), *same = split_of(ctx, env, 8), *turned = NULL;
    HL_CHECK(hl_area_lights_split(ctx, env, &rot, &turned) == HL_OK, "%s", hl_context_last_error(ctx));
    const size_t n = 3 * ((size_t)b->obj[0].nverts + b->obj[1].nverts);
    float *first = malloc(n * 4), *out = malloc(n * 4), *ref = malloc(n * 4);
    hl_frame_state *st = NULL;
    const hl_dyn_object rest[2] = {b->obj[0], b->obj[1]};
    float lo = INFINITY, hi = -INFINITY; /* the bunny's height */
    for (uint32_t v = 0; v < b->obj[0].nverts; v++) lo = fminf(lo, b->obj[0].pos[3 * v + 1]), hi = fmaxf(hi, b->obj[0].pos[3 * v + 1]);
    const float h = hi - lo;
    hl_frame_stats fs;
    if (!s || !same || !turned || hl_frame_state_create(ctx, b->obj, 2, s->count, &set, &st) != HL_OK) {
        HL_CHECK(0, "%s", hl_context_last_error(ctx));
        goto close;
    }
    /* (1) nothing changed: every map kept, the first frame's colours */
    keep_step(ctx, st, b, s, &set, "first frame", 0, first, ref);
    keep_frame(ctx, st, b, s, out, &fs);
    printf("  the same again: maps kept %u of %u shadowed\n", fs.maps_kept, fs.shadowed);
    HL_CHECK(fs.shadowed > 0 && fs.maps_kept == fs.shadowed, "nothing moved: %u maps kept of %u", fs.maps_kept, fs.shadowed);
    hl_check_error("  nothing moved: colour floats that differ from the first frame's (tolerance 0: bit for bit)",
                   (double)floats_differ(out, first, n), 0.0);
    /* (2) only the ground moved (slid along x and lowered): still out of
       every map, which are kept; its receivers are evaluated where they
       are now */
    b->obj[1].xf[3] += 0.2f * h, b->obj[1].xf[7] -= 0.02f * h;
    keep_step(ctx, st, b, s, &set, "ground moved", 2, out, ref);
    /* (3) the bunny moved: every map made again */
    b->obj[0].xf[3] += 0.1f * h, b->obj[0].xf[11] -= 0.05f * h;
    keep_step(ctx, st, b, s, &set, "bunny moved", 0, out, ref);
    keep_step(ctx, st, b, s, &set, "bunny moved, the same again", 1, out, ref);
    /* a flat body moved into the others (the ground lifted to the bunny's
       middle): the maps would no longer leave it out, so none is kept */
    b->obj[1].xf[7] = rest[1].xf[7] + 0.5f * h;
    keep_step(ctx, st, b, s, &set, "ground lifted through the bunny", 0, out, ref);
    b->obj[1] = rest[1];
    keep_step(ctx, st, b, s, &set, "ground back under the bunny", 0, out, ref);
    /* (4) another split: the same lights split again (its serial), and
       the map turned by 40 degrees */
    keep_step(ctx, st, b, same, &set, "the same map split again", 0, out, ref);
    keep_step(ctx, st, b, turned, &set, "the map turned", 0, out, ref);
    keep_step(ctx, st, b, turned, &set, "the map turned, the same again", 1, out, ref);
    /* a failed frame (a body scaled: not rigid) leaves nothing kept */
    b->obj[0].xf[0] = 2.0f;
    HL_CHECK(hl_frame_render(st, b->obj, 2, b->alb, turned, b->rgb, NULL) != HL_OK, "a scaled body was accepted");
    b->obj[0].xf[0] = rest[0].xf[0];
    keep_step(ctx, st, b, turned, &set, "after a failed frame", 0, out, ref);
close:
    b->obj[0] = rest[0], b->obj[1] = rest[1];
    hl_frame_state_destroy(st);
    free(first); free(out); free(ref);
    hl_light_split_destroy(s);
    hl_light_split_destroy(same);
    hl_light_split_destroy(turned);
}

static void case_keep(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    bunny_scene b;
    memset(&b, 0, sizeof b);
    hl_env *env = sky(ctx);
    if (env && bunny_open(ctx, &b)) {
        for (int path = 0; path < 2; path++)
            for (int q = 0; q < 2; q++) {
                printf("%s receivers, %s:\n", path ? "host" : "device", q ? "CSM" : "moments");
                if (path) setenv("HL_TEST_DYN_FRAME", "host", 1);
                keep_path(ctx, &b, env, q ? HL_SHADOW_REP_CSM : HL_SHADOW_REP_MOMENTS);
                unsetenv("HL_TEST_DYN_FRAME");
            }
        /* several batches (a budget of 3 lights): each renders into the
           same buffers, so nothing is kept even when nothing moved; but
           the sharp lights' maps, a batch of their own, are */
        hl_light_split *s = split_of(ctx, env, 8);
        hl_frame_settings set = {.R = 64, .min_share = -1.0f,
                                 .budget = 3 * (uint64_t)hl_csm_bytes_per_light_rep(HL_SHADOW_REP_MOMENTS, 64, 16, 16) + 1};
        hl_frame_state *st = NULL;
        hl_frame_stats fs[2];
        int ok = s && hl_frame_state_create(ctx, b.obj, 2, s->count, &set, &st) == HL_OK &&
                 hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, &fs[0]) == HL_OK &&
                 hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, &fs[1]) == HL_OK;
        HL_CHECK(ok, "%s", hl_context_last_error(ctx));
        if (ok) {
            printf("several batches: %u lights shadowed in %u batches, the same frame again kept %u maps (want the %u "
                   "sharp lights')\n", fs[1].shadowed, fs[1].batches, fs[1].maps_kept, fs[1].sharp);
            HL_CHECK(fs[1].batches > 2 && fs[1].sharp > 0 && fs[1].maps_kept == fs[1].sharp, "%u batches, %u maps kept",
                     fs[1].batches, fs[1].maps_kept);
        }
        hl_frame_state_destroy(st);
        hl_light_split_destroy(s);
    }
    bunny_close(&b);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
    /* the reference backend: maps and tables in host memory (the twins) */
    hl_context *ref = hl_test_ref_context(2);
    memset(&b, 0, sizeof b);
    env = sky(ref);
    if (env && bunny_open(ref, &b)) {
        printf("reference backend, moments:\n");
        keep_path(ref, &b, env, HL_SHADOW_REP_MOMENTS);
    }
    bunny_close(&b);
    hl_env_destroy(env);
    hl_context_destroy(ref);
}

/* ------------------------------------------------------------ sharp */

/* Frame of a new state with settings set (both bodies into out). */
static int sharp_frame(hl_context *ctx, bunny_scene *b, const hl_light_split *s, const hl_frame_settings *set,
                       float *out, hl_frame_stats *fs)
{
    hl_frame_state *st = NULL;
    int ok = hl_frame_state_create(ctx, b->obj, 2, s->count, set, &st) == HL_OK && keep_frame(ctx, st, b, s, out, fs);
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    hl_frame_state_destroy(st);
    return ok;
}

/* The sharp lights' finer maps (dyn_frame.h, HL_FRAME_SHARP_*) on one
 * path, the bunny on its ground under the sky: alone, its sun at R = 64
 * with R_sharp = 256 is the frame at R = 256 bit for bit (the same map in
 * the same kernels); among 8 lights the sharp ones are those whose filter
 * is under HL_FRAME_SHARP_TEXELS texels of a 64 map, and their finer maps
 * change the frame. */
static void sharp_path(hl_context *ctx, bunny_scene *b, const hl_env *env)
{
    const size_t n = 3 * ((size_t)b->obj[0].nverts + b->obj[1].nverts);
    float *x = malloc(n * 4), *y = malloc(n * 4);
    hl_light_split *one = split_of(ctx, env, 1), *eight = split_of(ctx, env, 8);
    hl_frame_settings fine = {.R = 64, .R_sharp = 256, .min_share = -1.0f, .shadow = HL_SHADOW_REP_MOMENTS,
                              .sharp = HL_SHARP_MAPS};
    hl_frame_settings all = fine, coarse = fine;
    all.R = 256, coarse.R_sharp = 64;
    all.sharp = coarse.sharp = HL_SHARP_OFF;
    hl_frame_stats fa, fb;
    if (one && eight && sharp_frame(ctx, b, one, &fine, x, &fa) && sharp_frame(ctx, b, one, &all, y, &fb)) {
        printf("  the sun alone: %u sharp at %u^2 (want 1 at 256), against one map size of 256 (%u sharp, want 0)\n",
               fa.sharp, fa.R_sharp, fb.sharp);
        HL_CHECK(fa.sharp == 1 && fa.R_sharp == 256 && fb.sharp == 0 && fb.R_sharp == 0, "the sun's map size");
        hl_check_error("  the sun alone at 64 with sharp 256 vs all at 256: colour floats that differ (tolerance 0)",
                       (double)floats_differ(x, y, n), 0.0);
    }
    if (one && eight && sharp_frame(ctx, b, eight, &fine, x, &fa) && sharp_frame(ctx, b, eight, &coarse, y, &fb)) {
        uint32_t want = 0;
        for (uint32_t k = 0; k < eight->count; k++)
            want += tanf(fminf(fmaxf(eight->lights[k].spread, 0.0f), HL_FRAME_MAX_THETA)) * 64.0f < HL_FRAME_SHARP_TEXELS;
        if (want > HL_FRAME_SHARP_MAX) want = HL_FRAME_SHARP_MAX;
        const size_t d = floats_differ(x, y, n);
        printf("  8 lights: %u sharp (want %u, at least 1), %u shadowed; %zu of %zu colour floats differ from one map "
               "size of 64\n", fa.sharp, want, fa.shadowed, d, n);
        HL_CHECK(fa.sharp == want && want >= 1 && fb.sharp == 0, "%u sharp lights, want %u", fa.sharp, want);
        HL_CHECK(d > 0, "the finer maps changed nothing");
    }
    hl_light_split_destroy(one);
    hl_light_split_destroy(eight);
    free(x), free(y);
}

static void case_sharp(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    bunny_scene b;
    memset(&b, 0, sizeof b);
    hl_env *env = sky(ctx);
    if (env && bunny_open(ctx, &b)) {
        for (int path = 0; path < 2; path++) {
            printf("%s receivers:\n", path ? "host" : "device");
            if (path) setenv("HL_TEST_DYN_FRAME", "host", 1);
            sharp_path(ctx, &b, env);
            unsetenv("HL_TEST_DYN_FRAME");
        }
        /* the defaults: rays with moments, one size with CSM; a finer
           size given asks for the maps */
        hl_light_split *s = split_of(ctx, env, 8);
        const size_t n = 3 * ((size_t)b.obj[0].nverts + b.obj[1].nverts);
        float *x = malloc(n * 4);
        hl_frame_settings m = {.R = 64, .min_share = -1.0f}, c = {.R = 64, .min_share = -1.0f, .shadow = HL_SHADOW_REP_CSM};
        hl_frame_settings cm = c;
        cm.R_sharp = 128;
        hl_frame_stats fm, fc, fcm;
        if (s && sharp_frame(ctx, &b, s, &m, x, &fm) && sharp_frame(ctx, &b, s, &c, x, &fc) &&
            sharp_frame(ctx, &b, s, &cm, x, &fcm)) {
            printf("defaults at R = 64: moments %u sharp, mode %d (want rays, %d), %llu rays; CSM %u sharp, mode %d (want "
                   "0, off %d); CSM with R_sharp 128: %u sharp at %u^2, mode %d (want maps, %d)\n",
                   fm.sharp, (int)fm.sharp_mode, (int)HL_SHARP_RAYS, (unsigned long long)fm.sharp_rays, fc.sharp,
                   (int)fc.sharp_mode, (int)HL_SHARP_OFF, fcm.sharp, fcm.R_sharp, (int)fcm.sharp_mode, (int)HL_SHARP_MAPS);
            HL_CHECK(fm.sharp > 0 && fm.sharp_mode == HL_SHARP_RAYS && fm.sharp_rays > 0 && fm.R_sharp == 0 &&
                         fc.sharp == 0 && fc.sharp_mode == HL_SHARP_OFF && fc.R_sharp == 0 && fcm.sharp > 0 &&
                         fcm.sharp_mode == HL_SHARP_MAPS && fcm.R_sharp == 128,
                     "the default sharp modes");
        }
        free(x);
        hl_light_split_destroy(s);
    }
    bunny_close(&b);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ contact */

enum { CT_G = 33 }; /* the ground's grid: CT_G x CT_G vertices over [-2, 2]^2 */

/* A unit cube (24 vertices, face normals, outward winding) standing on
 * y = 0 with its centre over (0, 0), or, flat, one upward quad on y = 0;
 * and the ground grid. */
static void contact_meshes(float *cpos, float *cnrm, uint32_t *ctri, uint32_t *ncv, uint32_t *nct, int flat, float *gpos,
                           float *gnrm, uint32_t *gtri)
{
    static const float fn[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    uint32_t nv = 0, nt = 0;
    for (int f = flat ? 2 : 0; f < (flat ? 3 : 6); f++) {
        /* two axes in the face, u x v = n */
        const float *n = fn[f];
        float u[3] = {n[1] != 0 ? 1.0f : 0.0f, n[1] == 0 ? 1.0f : 0.0f, 0.0f}, v[3];
        if (n[2] != 0) u[0] = 1.0f, u[1] = 0.0f;
        v[0] = n[1] * u[2] - n[2] * u[1], v[1] = n[2] * u[0] - n[0] * u[2], v[2] = n[0] * u[1] - n[1] * u[0];
        for (int c = 0; c < 4; c++) {
            const float a = (c & 1) ? 0.5f : -0.5f, b = (c & 2) ? 0.5f : -0.5f;
            for (int k = 0; k < 3; k++) {
                cpos[3 * nv + k] = (flat ? 0.0f : 0.5f * n[k]) + a * u[k] + b * v[k];
                cnrm[3 * nv + k] = n[k];
            }
            if (!flat) cpos[3 * nv + 1] += 0.5f; /* standing on y = 0 */
            nv++;
        }
        const uint32_t q = nv - 4, t[6] = {q, q + 1, q + 3, q, q + 3, q + 2};
        memcpy(ctri + 3 * nt, t, sizeof t);
        nt += 2;
    }
    *ncv = nv, *nct = nt;
    for (int j = 0; j < CT_G; j++)
        for (int i = 0; i < CT_G; i++) {
            float *p = gpos + 3 * (j * CT_G + i), *n = gnrm + 3 * (j * CT_G + i);
            p[0] = -2.0f + 4.0f * (float)i / (CT_G - 1), p[1] = 0.0f, p[2] = -2.0f + 4.0f * (float)j / (CT_G - 1);
            n[0] = 0.0f, n[1] = 1.0f, n[2] = 0.0f;
        }
    uint32_t k = 0;
    for (uint32_t j = 0; j + 1 < CT_G; j++)
        for (uint32_t i = 0; i + 1 < CT_G; i++) {
            const uint32_t a = j * CT_G + i, t[6] = {a, a + CT_G, a + 1, a + 1, a + CT_G, a + CT_G + 1};
            memcpy(gtri + 3 * k, t, sizeof t);
            k += 2;
        }
}

/* The ground's receivers under a body resting on it (dyn_frame.c,
 * contact_cover): a cube on a ground grid under the sky, K = 8. The grid
 * vertices strictly inside its footprint (7 x 7 at spacing 1/8: those on
 * its rim are not) are black in the frame, as in the exact reference,
 * and those on the rim and outside are not; lifted by 1% of its size, or
 * an upward quad lying on the ground instead, darkens none. */
static void case_contact(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    hl_env *env = sky(ctx);
    hl_light_split *s = env ? split_of(ctx, env, 8) : NULL;
    float cpos[72], cnrm[72], gpos[3 * CT_G * CT_G], gnrm[3 * CT_G * CT_G];
    uint32_t ctri[36], gtri[6 * (CT_G - 1) * (CT_G - 1)], ncv, nct;
    const size_t ng = (size_t)CT_G * CT_G;
    float *alb[2], *rgb[2], *ref[2];
    for (int k = 0; k < 2; k++) {
        const size_t n = k ? ng : 24;
        alb[k] = malloc(n * 12), rgb[k] = malloc(n * 12), ref[k] = malloc(n * 12);
        for (size_t i = 0; i < 3 * n; i++) alb[k][i] = 0.8f;
    }
    for (int pass = 0; s && pass < 3; pass++) {
        contact_meshes(cpos, cnrm, ctri, &ncv, &nct, pass == 2, gpos, gnrm, gtri);
        hl_dyn_object obj[2] = {{.pos = cpos, .normal = cnrm, .nverts = ncv, .tri = ctri, .ntris = nct,
                                 .xf = {1, 0, 0, 0, 0, 1, 0, pass == 1 ? 0.01f : 0.0f, 0, 0, 1, 0}},
                                {.pos = gpos, .normal = gnrm, .nverts = (uint32_t)ng, .tri = gtri,
                                 .ntris = 2 * (CT_G - 1) * (CT_G - 1), .xf = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}}};
        hl_frame_settings set = {.min_share = -1.0f};
        hl_frame_state *st = NULL;
        hl_frame_stats fs;
        int ok = hl_frame_state_create(ctx, obj, 2, s->count, &set, &st) == HL_OK &&
                 hl_frame_render(st, obj, 2, (const float *const *)alb, s, rgb, &fs) == HL_OK &&
                 hl_dyn_reference_exact(ctx, obj, 2, (const float *const *)alb, env, 0, 0, ref, NULL) == HL_OK;
        HL_CHECK(ok, "%s", hl_context_last_error(ctx));
        hl_frame_state_destroy(st);
        if (!ok) break;
        const char *what = pass == 0 ? "the cube on the ground" : pass == 1 ? "the cube lifted" : "a quad on the ground";
        const uint32_t want = pass == 0 ? 49 : 0;
        double top = 0, worst_in = 0, ref_in = 0, rim_min = INFINITY;
        uint32_t inside = 0;
        for (size_t i = 0; i < 3 * ng; i++) top = fmax(top, ref[1][i]);
        for (size_t v = 0; v < ng; v++) {
            const float x = fabsf(gpos[3 * v]), z = fabsf(gpos[3 * v + 2]);
            const double f = lum(rgb[1] + 3 * v), r = lum(ref[1] + 3 * v);
            if (x < 0.49f && z < 0.49f) {
                inside++;
                worst_in = fmax(worst_in, f / top);
                ref_in = fmax(ref_in, r / top);
            } else if (x < 0.51f && z < 0.51f) {
                rim_min = fmin(rim_min, f / top);
            }
        }
        printf("%s: %u ground vertices under it, %u dark (want %u); inside the footprint the brightest frame %.3g, exact "
               "%.3g of the brightest; on its rim the darkest frame %.3g\n", what, inside, fs.covered, want, worst_in,
               ref_in, rim_min);
        HL_CHECK(fs.covered == want, "%s: %u dark, want %u", what, fs.covered, want);
        if (pass == 0) {
            /* the exact reference's rays from inside meet the cube */
            hl_check_error("  the exact reference inside the footprint, of the brightest (tolerance 1e-6)", ref_in, 1e-6);
            hl_check_error("  the frame inside the footprint, of the brightest (tolerance 0)", worst_in, 0.0);
            HL_CHECK(rim_min > 0.0, "the footprint's rim went black");
        } else {
            HL_CHECK(worst_in > 0.0, "%s: the ground under it went black", what);
        }
    }
    for (int k = 0; k < 2; k++) free(alb[k]), free(rgb[k]), free(ref[k]);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ enclosed */

/* A cube of half-side h centred at (0, cy, 0) into pos/nrm/tri from
 * vertex nv and triangle nt (24 vertices, 12 triangles, outward normals;
 * flip: the winding reversed, the normals kept). */
static void cube_at(float *pos, float *nrm, uint32_t *tri, uint32_t *nv, uint32_t *nt, float h, float cy, int flip)
{
    static const float fn[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int f = 0; f < 6; f++) {
        const float *n = fn[f];
        /* u, v in the face with u x v = n */
        const float u[3] = {n[0] == 0 ? 1.0f : 0.0f, n[0] == 0 ? 0.0f : 1.0f, 0.0f};
        const float v[3] = {n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]};
        for (int c = 0; c < 4; c++) {
            const float a = (c & 1) ? h : -h, b = (c & 2) ? h : -h;
            for (int k = 0; k < 3; k++) pos[3 * *nv + k] = h * n[k] + a * u[k] + b * v[k], nrm[3 * *nv + k] = n[k];
            pos[3 * *nv + 1] += cy;
            (*nv)++;
        }
        const uint32_t q = *nv - 4;
        const uint32_t t[6] = {q, q + 1, q + 3, q, q + 3, q + 2}, tf[6] = {q, q + 3, q + 1, q, q + 2, q + 3};
        memcpy(tri + 3 * *nt, flip ? tf : t, sizeof t);
        *nt += 2;
    }
}

/* The vertices inside their body's own closed parts (enclosed.h): a
 * cube of half-side 0.25 inside one of half-side 1, one body, standing
 * on a ground: the inner cube's 24 vertices are enclosed and black in
 * the frame, as in the exact reference, and the outer's are not; with
 * the winding reversed (untrusted) none is, nor on a sheet modelled with
 * both sides (a quad and its reversed twin on the same four vertices'
 * positions). */
static void case_enclosed(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    float pos[3 * 48], nrm[3 * 48];
    uint32_t tri[3 * 24], nv = 0, nt = 0;
    uint8_t enc[48];
    uint32_t count = 0;
    /* the winding's directions: outer cube, inner cube */
    for (int pass = 0; pass < 2; pass++) {
        nv = nt = 0;
        cube_at(pos, nrm, tri, &nv, &nt, 1.0f, 1.0f, pass);
        cube_at(pos, nrm, tri, &nv, &nt, 0.25f, 1.0f, pass);
        hl_dyn_object o = {.pos = pos, .normal = nrm, .nverts = nv, .tri = tri, .ntris = nt,
                           .xf = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
        HL_CHECK(hl_dyn_enclosed(ctx, &o, enc, &count) == HL_OK, "%s", hl_context_last_error(ctx));
        uint32_t inner = 0, outer = 0;
        for (uint32_t v = 0; v < nv; v++) *(v < 24 ? &outer : &inner) += enc[v];
        printf("%s: %u enclosed, the inner cube's %u of 24 (want %u), the outer's %u (want 0)\n",
               pass ? "winding reversed" : "nested cubes", count, inner, pass ? 0u : 24u, outer);
        HL_CHECK(inner == (pass ? 0u : 24u) && outer == 0 && count == inner, "the enclosed vertices");
    }
    /* a two-sided sheet: never enclosed */
    {
        const float sp[24] = {-1, 0, -1, 1, 0, -1, -1, 0, 1, 1, 0, 1, -1, 0, -1, 1, 0, -1, -1, 0, 1, 1, 0, 1};
        const float sn[24] = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0, -1, 0, 0, -1, 0, 0, -1, 0};
        const uint32_t st[12] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6};
        hl_dyn_object o = {.pos = sp, .normal = sn, .nverts = 8, .tri = st, .ntris = 4,
                           .xf = {1, 0, 0, 0, 0, 1, 0, 0.5f, 0, 0, 1, 0}};
        HL_CHECK(hl_dyn_enclosed(ctx, &o, enc, &count) == HL_OK, "%s", hl_context_last_error(ctx));
        printf("a two-sided sheet: %u enclosed (want 0)\n", count);
        HL_CHECK(count == 0, "a sheet's vertices were enclosed");
    }
    /* the nested cubes on a ground in a frame, against the exact reference */
    nv = nt = 0;
    cube_at(pos, nrm, tri, &nv, &nt, 1.0f, 1.0f, 0);
    cube_at(pos, nrm, tri, &nv, &nt, 0.25f, 1.0f, 0);
    float gpos[3 * CT_G * CT_G], gnrm[3 * CT_G * CT_G], cp[72], cn[72];
    uint32_t gtri[6 * (CT_G - 1) * (CT_G - 1)], ct[36], a, b2;
    contact_meshes(cp, cn, ct, &a, &b2, 0, gpos, gnrm, gtri);
    for (size_t i = 0; i < 3 * (size_t)CT_G * CT_G; i++) gpos[i] *= 2.0f; /* the ground 8 wide */
    hl_env *env = sky(ctx);
    hl_light_split *s = env ? split_of(ctx, env, 8) : NULL;
    const size_t ng = (size_t)CT_G * CT_G;
    float *alb[2] = {malloc(48 * 12), malloc(ng * 12)}, *rgb[2] = {malloc(48 * 12), malloc(ng * 12)};
    float *ref[2] = {malloc(48 * 12), malloc(ng * 12)};
    for (int k = 0; k < 2; k++)
        for (size_t i = 0; i < 3 * (k ? ng : 48); i++) alb[k][i] = 0.8f;
    hl_dyn_object obj[2] = {{.pos = pos, .normal = nrm, .nverts = nv, .tri = tri, .ntris = nt,
                             .xf = {1, 0, 0, 0, 0, 1, 0, 0.5f, 0, 0, 1, 0}},
                            {.pos = gpos, .normal = gnrm, .nverts = (uint32_t)ng, .tri = gtri,
                             .ntris = 2 * (CT_G - 1) * (CT_G - 1), .xf = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}}};
    hl_frame_settings set = {.min_share = -1.0f};
    hl_frame_state *st = NULL;
    hl_frame_stats fs;
    int ok = s && hl_frame_state_create(ctx, obj, 2, s->count, &set, &st) == HL_OK &&
             hl_frame_render(st, obj, 2, (const float *const *)alb, s, rgb, &fs) == HL_OK &&
             hl_dyn_reference_exact(ctx, obj, 2, (const float *const *)alb, env, 0, 0, ref, NULL) == HL_OK;
    HL_CHECK(ok, "%s", hl_context_last_error(ctx));
    if (ok) {
        double top = 0, fin = 0, rin = 0, fout = INFINITY;
        for (size_t i = 0; i < 3 * ng; i++) top = fmax(top, ref[1][i]);
        for (uint32_t v = 0; v < nv; v++) {
            const double f = lum(rgb[0] + 3 * v) / top, r = lum(ref[0] + 3 * v) / top;
            if (v >= 24) fin = fmax(fin, f), rin = fmax(rin, r);
            else if (nrm[3 * v + 1] > 0.5f) fout = fmin(fout, f); /* the outer cube's top */
        }
        printf("in a frame: %u enclosed (want 24); the inner cube's brightest frame %.3g, exact %.3g of the brightest; "
               "the outer cube's top darkest %.3g\n", fs.enclosed, fin, rin, fout);
        HL_CHECK(fs.enclosed == 24 && fout > 0.0, "the frame's enclosed vertices");
        hl_check_error("  the exact reference on the inner cube, of the brightest (tolerance 1e-6)", rin, 1e-6);
        hl_check_error("  the frame on the inner cube, of the brightest (tolerance 0)", fin, 0.0);
    }
    hl_frame_state_destroy(st);
    for (int k = 0; k < 2; k++) free(alb[k]), free(rgb[k]), free(ref[k]);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ bad input */

#define EXPECT_FAIL(call, what)                                                    \
    do {                                                                           \
        hl_result r_ = (call);                                                     \
        HL_CHECK(r_ != HL_OK, "%s was accepted", what);                            \
        if (r_ != HL_OK) printf("refused %s: %s\n", what, hl_context_last_error(ctx)); \
    } while (0)

static void case_bad_input(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    bunny_scene b;
    memset(&b, 0, sizeof b);
    hl_env *env = sky(ctx);
    hl_light_split *s = env ? split_of(ctx, env, 4) : NULL;
    hl_frame_state *st = NULL;
    if (!s || !bunny_open(ctx, &b)) goto close;
    hl_frame_settings bad[] = {{.M = 3}, {.M = 17}, {.R = 100}, {.R = 8}, {.R = 2048}, {.M = 8, .Mb = 16},
                               {.R = 64, .R_sharp = 32}, {.R = 64, .R_sharp = 100}, {.R_sharp = 2048},
                               {.min_share = NAN}, {.min_share = 1.0f}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        char what[96];
        snprintf(what, sizeof what, "settings R %u sharp %u M %u Mb %u share %g", bad[i].R, bad[i].R_sharp, bad[i].M,
                 bad[i].Mb, (double)bad[i].min_share);
        EXPECT_FAIL(hl_frame_state_create(ctx, b.obj, 2, 4, &bad[i], &st), what);
    }
    EXPECT_FAIL(hl_frame_state_create(ctx, b.obj, 2, 0, NULL, &st), "no lights");
    EXPECT_FAIL(hl_frame_state_create(ctx, b.obj, 0, 4, NULL, &st), "no bodies");
    hl_frame_settings small = {.R = 64, .M = 8, .min_share = -1.0f};
    HL_CHECK(hl_frame_state_create(ctx, b.obj, 2, s->count, &small, &st) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!st) goto close;
    EXPECT_FAIL(hl_frame_render(st, b.obj, 1, b.alb, s, b.rgb, NULL), "one body of two");
    hl_dyn_object wrong[2] = {b.obj[0], b.obj[1]};
    wrong[1].nverts--;
    EXPECT_FAIL(hl_frame_render(st, wrong, 2, b.alb, s, b.rgb, NULL), "a body with another vertex count");
    EXPECT_FAIL(hl_frame_render(st, b.obj, 2, NULL, s, b.rgb, NULL), "no albedo");
    hl_frame_state *one = NULL;
    HL_CHECK(hl_frame_state_create(ctx, b.obj, 2, 1, &small, &one) == HL_OK, "%s", hl_context_last_error(ctx));
    if (s->count > 1) EXPECT_FAIL(hl_frame_render(one, b.obj, 2, b.alb, s, b.rgb, NULL), "more lights than the state holds");
    hl_frame_state_destroy(one);
    wrong[1] = b.obj[1];
    wrong[0].xf[0] = 2.0f; /* a scale: not rigid */
    EXPECT_FAIL(hl_frame_render(st, wrong, 2, b.alb, s, b.rgb, NULL), "a non-rigid transform");
    /* every output finite and >= 0 (nothing is clamped: V in [0, 1], E >= 0) */
    hl_frame_stats fs;
    HL_CHECK(hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, &fs) == HL_OK, "%s", hl_context_last_error(ctx));
    double worst = 0;
    uint64_t bad_values = 0;
    for (int k = 0; k < 2; k++)
        for (size_t i = 0; i < 3 * (size_t)b.obj[k].nverts; i++) {
            float x = b.rgb[k][i];
            if (!isfinite(x)) bad_values++;
            else if (x < 0) worst = fmax(worst, -x);
        }
    HL_CHECK(bad_values == 0, "%llu outputs not finite", (unsigned long long)bad_values);
    hl_check_error("most negative output", worst, 0.0);
close:
    hl_frame_state_destroy(st);
    bunny_close(&b);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ public API */

static void case_api(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    hl_mesh *m = NULL;
    hl_dynamic *d = NULL;
    hl_env *env = sky(ctx);
    hl_dynamic_desc bad = {.shadow_res = 0, .order = 3}, small = {.shadow_res = 64, .order = 8};
    float *rgb = NULL;
    HL_CHECK(hl_mesh_load(ctx, path, NULL, &m, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    EXPECT_FAIL(hl_dynamic_create_from_mesh(ctx, m, 1, &bad, &d), "order 3");
    HL_CHECK(hl_dynamic_create_from_mesh(ctx, m, 1, &small, &d) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!d || !env) goto done;
    HL_CHECK(hl_dynamic_body_count(d) == 2 && !strcmp(hl_dynamic_body_name(d, 0), "object") &&
             !strcmp(hl_dynamic_body_name(d, 1), "ground"), "bodies");
    EXPECT_FAIL(hl_dynamic_render(d, 0.0, &rgb, NULL), "a frame before an environment");
    EXPECT_FAIL(hl_dynamic_set_env(d, env, 0, 0.0f, 0.0f, NULL), "no lights");
    EXPECT_FAIL(hl_dynamic_set_env(d, env, 4, 1.5f, 0.0f, NULL), "split threshold 1.5");
    hl_dynamic_lights li;
    HL_CHECK(hl_dynamic_set_env(d, env, 4, 0.0f, 0.0f, &li) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(li.lights_kept == 4 && li.lights_kept + li.folded == li.lights_made, "lights %u kept, %u folded of %u",
             li.lights_kept, li.folded, li.lights_made);
    EXPECT_FAIL(hl_dynamic_move(d, "bunny", (float[3]){1, 0, 0}), "an unknown body");
    EXPECT_FAIL(hl_dynamic_move(d, "object", (float[3]){NAN, 0, 0}), "a NaN move");
    EXPECT_FAIL(hl_dynamic_render(d, -1.0, &rgb, NULL), "time -1");
    EXPECT_FAIL(hl_dynamic_render(d, NAN, &rgb, NULL), "time NaN");
    hl_dynamic_stats st;
    HL_CHECK(hl_dynamic_render(d, 0.0, &rgb, &st) == HL_OK, "%s", hl_context_last_error(ctx));
    const hl_mesh *w = hl_dynamic_mesh(d);
    HL_CHECK(w->vertex_count == st.vertices && w->vertex_count > m->vertex_count && w->object_vertex_count == m->vertex_count,
             "merged mesh: %u vertices (%u of the object), the frame %u", w->vertex_count, w->object_vertex_count,
             st.vertices);
    HL_CHECK(!st.reused && st.lights == 4, "the first frame is computed (reused %d, %u lights)", st.reused, st.lights);
    float *before = malloc((size_t)w->vertex_count * 12);
    memcpy(before, w->positions, (size_t)w->vertex_count * 12);
    /* nothing moved and the lights are the same: the same colours, no work */
    float *first = malloc((size_t)w->vertex_count * 12), *again = NULL;
    memcpy(first, rgb, (size_t)w->vertex_count * 12);
    HL_CHECK(hl_dynamic_render(d, 0.5, &again, &st) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(st.reused == 1 && st.lights == 0 && again && !memcmp(first, again, (size_t)w->vertex_count * 12),
             "a frame where nothing moved was recomputed (reused %d) or differs", st.reused);
    free(first);
    const float tr[3] = {0.3f, 0.0f, -0.2f};
    HL_CHECK(hl_dynamic_move(d, "object", tr) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dynamic_render(d, 0.0, &rgb, &st) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(!st.reused, "a frame after a move was not recomputed");
    /* the object's vertices moved by tr, the ground's not at all; the
     * colours finite and >= 0 */
    double worst = 0, neg = 0;
    uint64_t nonfinite = 0;
    for (uint32_t v = 0; v < w->vertex_count; v++)
        for (int k = 0; k < 3; k++) {
            float want = before[3 * v + k] + (v < w->object_vertex_count ? tr[k] : 0.0f);
            worst = fmax(worst, fabs(w->positions[3 * v + k] - want));
            if (!isfinite(rgb[3 * v + k])) nonfinite++;
            else neg = fmax(neg, -rgb[3 * v + k]);
        }
    /* one float addition of the translation: half an ulp of 8 */
    hl_check_error("merged positions after the move, absolute", worst, 1e-6);
    hl_check_error("most negative colour", neg, 0.0);
    HL_CHECK(nonfinite == 0, "%llu colours not finite", (unsigned long long)nonfinite);
    /* the general transform: a quarter turn about +Y through the origin
     * then tr; the body's vertex range is where the object's vertices are */
    uint32_t first_v = 99, count_v = 0;
    HL_CHECK(hl_dynamic_body_vertices(d, 0, &first_v, &count_v) == HL_OK && first_v == 0 &&
             count_v == w->object_vertex_count, "object's vertices: %u from %u", count_v, first_v);
    HL_CHECK(hl_dynamic_body_vertices(d, 2, &first_v, &count_v) != HL_OK, "body 2 of 2 accepted");
    EXPECT_FAIL(hl_dynamic_set_transform(d, 0, (float[12]){2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}), "a scaled transform");
    EXPECT_FAIL(hl_dynamic_set_transform(d, 5, (float[12]){1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}), "body 5");
    const float turn[12] = {0, 0, 1, tr[0], 0, 1, 0, tr[1], -1, 0, 0, tr[2]};
    HL_CHECK(hl_dynamic_set_transform(d, 0, turn) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dynamic_render(d, 0.0, &rgb, &st) == HL_OK && !st.reused, "%s", hl_context_last_error(ctx));
    worst = 0;
    for (uint32_t v = 0; v < w->object_vertex_count; v++) {
        const float *p = before + 3 * (size_t)v;
        float want[3] = {p[2] + tr[0], p[1] + tr[1], -p[0] + tr[2]};
        for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(w->positions[3 * v + k] - want[k]));
    }
    hl_check_error("positions after a quarter turn and tr, absolute", worst, 1e-5);
    free(before);
done:
    hl_dynamic_destroy(d);
    hl_mesh_destroy(m);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ command */

/* `haarlight relight-dynamic` (HL_BIN): bad options exit 2 with a
 * message, a small run on the reference device writes a PLY. */
static void case_cli(void)
{
    const char *bin = getenv("HL_BIN");
    if (!bin) { HL_CHECK(0, "HL_BIN is not set"); return; }
    char mesh[1024], cmd[4096];
    snprintf(mesh, sizeof mesh, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    const char *out = hl_test_tmp_path("dyn_frame_cli.ply");
    static const char *const bad[] = {"--lights 0", "--order 3", "--order 17", "--shadow-res 100", "--time -1",
                                      "--time nan", "--split-threshold 1", "--move nobody:1,0,0", "--terms 5",
                                      "--move object:1,0", "--reference truth", "--reference exact --rotate 10",
                                      "--diff d.ply", "--reference exact --diff d.txt", "--sharp sun",
                                      "--sharp-res 100", "--sharp rays --sharp-res 512", NULL};
    for (int i = 0; bad[i]; i++) {
        snprintf(cmd, sizeof cmd, "'%s' relight-dynamic '%s' --ground --device ref %s -o '%s' >/dev/null 2>&1", bin,
                 mesh, bad[i], out);
        int rc = system(cmd);
        HL_CHECK(WIFEXITED(rc) && WEXITSTATUS(rc) == 2, "%s: exit %d, not 2", bad[i], WEXITSTATUS(rc));
    }
    remove(out);
    snprintf(cmd, sizeof cmd, "'%s' relight-dynamic '%s' --ground --device ref --lights 3 --shadow-res 64 --order 8 "
             "--move object:0.2,0,0 -o '%s'", bin, mesh, out);
    int rc = system(cmd);
    HL_CHECK(WIFEXITED(rc) && WEXITSTATUS(rc) == 0, "a good run: exit %d", WEXITSTATUS(rc));
    FILE *f = fopen(out, "rb");
    HL_CHECK(f != NULL, "%s was not written", out);
    if (f) fclose(f);
}

/* ------------------------------------------------------------ a file */

/* The colours (r g b, floats) of a PLY as hl_mesh_save_ply writes it:
 * x y z nx ny nz r g b per vertex after the header. 0 on failure. */
static int ply_colours(const char *path, uint32_t nv, float *rgb)
{
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    char line[256];
    uint32_t n = 0;
    int ok = 0;
    while (fgets(line, sizeof line, f)) {
        if (sscanf(line, "element vertex %u", &n) == 1) continue;
        if (!strcmp(line, "end_header\n")) { ok = n == nv; break; }
    }
    for (uint32_t v = 0; ok && v < nv; v++) {
        float rec[9];
        ok = fread(rec, 4, 9, f) == 9; /* little-endian, as this machine */
        memcpy(rgb + 3 * (size_t)v, rec + 6, 12);
    }
    fclose(f);
    return ok;
}

/* relight-dynamic --reference exact --diff DIFF on path (the two-body
 * file at time 0, K 2, R 32, M 4): the PLY holds the exact reference of
 * that frame, not the frame, the printed error is the frame's against it,
 * and DIFF holds 4 x the channels' mean difference, red above, blue below. */
static void check_reference_run(const char *path, const char *ply, const char *log, const char *diff_ply)
{
    hl_context *ctx = hl_test_ref_context(2);
    hl_dynamic *d = NULL;
    hl_env *env = NULL;
    hl_sky_desc sd = {0}; /* the command's sky */
    HL_CHECK(hl_env_create_sky(ctx, &sd, &env) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_dynamic_desc desc = {32, 4, HL_DYNAMIC_SHADOW_CSM, 0, 0};
    float *frame = NULL, *exact = NULL, *file = NULL, *dc = NULL;
    if (hl_dynamic_create_from_file(ctx, path, 0, &desc, &d) != HL_OK || !env ||
        hl_dynamic_set_env(d, env, 2, 0.0f, 0.0f, NULL) != HL_OK || hl_dynamic_render(d, 0.0, &frame, NULL) != HL_OK) {
        HL_CHECK(0, "%s", hl_context_last_error(ctx));
        goto done;
    }
    uint32_t nv = hl_dynamic_mesh(d)->vertex_count;
    exact = malloc((size_t)nv * 12), file = malloc((size_t)nv * 12), dc = malloc((size_t)nv * 12);
    HL_CHECK(hl_bench_dyn_exact(d, env, exact, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(ply_colours(ply, nv, file), "%s: not a PLY of %u vertices", ply, nv);
    double worst = 0, num = 0, den = 0, diff = 0;
    for (size_t i = 0; i < 3 * (size_t)nv; i++) {
        worst = fmax(worst, fabs((double)file[i] - exact[i]) / fmax(fabs((double)exact[i]), 1e-6));
        num += ((double)frame[i] - exact[i]) * ((double)frame[i] - exact[i]);
        den += (double)exact[i] * exact[i];
        diff = fmax(diff, fabs((double)frame[i] - exact[i]));
    }
    /* the same rays on the same bodies: the same floats */
    hl_check_error("written reference against the exact reference made here, relative", worst, 1e-6);
    HL_CHECK(ply_colours(diff_ply, nv, dc), "%s: not a PLY of %u vertices", diff_ply, nv);
    double dworst = 0, dmax = 0;
    for (uint32_t v = 0; v < nv; v++) {
        const float *f = frame + 3 * v, *x = exact + 3 * v;
        double m = 4.0 * (((double)f[0] - x[0]) + ((double)f[1] - x[1]) + ((double)f[2] - x[2])) / 3.0;
        double want[3] = {fmax(m, 0.0), 0.0, fmax(-m, 0.0)};
        for (int k = 0; k < 3; k++) {
            dworst = fmax(dworst, fabs(dc[3 * v + k] - want[k]));
            dmax = fmax(dmax, want[k]);
        }
    }
    HL_CHECK(dmax > 0.0, "the frame and its reference differ nowhere");
    /* float sums in another order: a few ulps of the largest */
    hl_check_error("--diff colours against the frame minus the reference made here, relative to the largest",
                   dworst / fmax(dmax, 1e-30), 1e-5);
    HL_CHECK(diff > 0.0, "the written colours are the frame's, not the reference's");
    char line[4096];
    double printed = -1;
    FILE *f = fopen(log, "r");
    while (f && fgets(line, sizeof line, f)) {
        const char *at = strstr(line, "relative L2 error against it: ");
        if (at) printed = strtod(at + strlen("relative L2 error against it: "), NULL);
    }
    if (f) fclose(f);
    /* printed with two decimals */
    hl_check_error("printed error against the one computed here, percentage points",
                   fabs(printed - 100.0 * sqrt(num / den)), 0.006);
done:
    free(exact); free(file); free(dc);
    hl_dynamic_destroy(d);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* A glTF file of two bodies (scene_gen.h): a ground quad scaled to
 * 4 x 4 and a cube "Box" whose translation keys go from (0, 2, 0) at 0 s
 * to (2, 2, 0) at 2 s. Through the public API at t = 1 s, moved by
 * (0, 0, 1): the merged mesh holds the cube's corners at +-1 about
 * (1, 2, 1), the ground where it was. */
static void case_file(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    sg_scene sc;
    memset(&sc, 0, sizeof sc);
    sc.nnodes = 2;
    sc.node[0] = (sg_node){.name = "Floor", .parent = -1, .mesh = SG_GROUND, .has_s = 1, .s = {4, 1, 4}};
    sc.node[1] = (sg_node){.name = "Box", .parent = -1, .mesh = SG_CUBE, .has_t = 1, .t = {0, 2, 0}};
    sc.node[1].kt = (sg_keys){2, {0, 2}, {{0, 2, 0}, {2, 2, 0}}};
    const char *path = hl_test_tmp_path("dyn_frame_two_bodies.gltf");
    HL_CHECK(sg_write_gltf(path, &sc) == 0, "cannot write %s", path);
    hl_dynamic *d = NULL;
    hl_env *env = sky(ctx);
    hl_dynamic_desc small = {.shadow_res = 64, .order = 8};
    float *rgb = NULL;
    HL_CHECK(hl_dynamic_create_from_file(ctx, path, 0, &small, &d) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!d || !env) goto done;
    double t0, t1;
    hl_dynamic_time_range(d, &t0, &t1);
    HL_CHECK(hl_dynamic_body_count(d) == 2 && t0 == 0.0 && t1 == 2.0, "%u bodies, animation %g..%g s",
             hl_dynamic_body_count(d), t0, t1);
    HL_CHECK(hl_dynamic_set_env(d, env, 4, 0.0f, 0.0f, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dynamic_move(d, "Box", (float[3]){0, 0, 1}) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dynamic_render(d, 1.0, &rgb, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    const hl_mesh *w = hl_dynamic_mesh(d);
    double worst = 0;
    uint32_t cube = 0;
    for (uint32_t v = 0; v < w->vertex_count; v++) {
        const float *p = w->positions + 3 * v;
        if (p[1] < 0.5f) { /* the floor: y = 0, x and z at +-4 */
            worst = fmax(worst, fabs(p[1])), worst = fmax(worst, fabs(fabs(p[0]) - 4)), worst = fmax(worst, fabs(fabs(p[2]) - 4));
            continue;
        }
        cube++;
        const float c[3] = {1, 2, 1};
        for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(fabs(p[k] - c[k]) - 1));
    }
    HL_CHECK(cube == 8 && w->vertex_count == 12, "%u cube vertices of %u", cube, w->vertex_count);
    /* linear keys at their midpoint and a float translation: a few ulps */
    hl_check_error("merged positions at t = 1 s after the move, absolute", worst, 1e-5);
    /* the command on the same file: a time and a move */
    const char *bin = getenv("HL_BIN");
    if (bin) {
        char cmd[4096];
        snprintf(cmd, sizeof cmd, "'%s' relight-dynamic '%s' --device ref --lights 2 --shadow-res 32 --order 4 "
                 "--time 1.5 --move Box:0,0,1 -q -o '%s'", bin, path, hl_test_tmp_path("dyn_frame_two_bodies.ply"));
        int rc = system(cmd);
        HL_CHECK(WIFEXITED(rc) && WEXITSTATUS(rc) == 0, "relight-dynamic on the file: exit %d", WEXITSTATUS(rc));
        /* --reference: the exact reference written instead, the frame's
           error against it printed (12 vertices: cheap); both checked
           against the same frame and reference made here */
        const char *log = hl_test_tmp_path("dyn_frame_reference.txt");
        char ply[1024], dply[1024];
        snprintf(ply, sizeof ply, "%s", hl_test_tmp_path("dyn_frame_reference.ply"));
        snprintf(dply, sizeof dply, "%s", hl_test_tmp_path("dyn_frame_reference_diff.ply"));
        remove(dply);
        snprintf(cmd, sizeof cmd, "'%s' relight-dynamic '%s' --device ref --lights 2 --shadow-res 32 --order 4 "
                 "--reference exact -o '%s' --diff '%s' 2>'%s'", bin, path, ply, dply, log);
        rc = system(cmd);
        HL_CHECK(WIFEXITED(rc) && WEXITSTATUS(rc) == 0, "relight-dynamic --reference exact: exit %d", WEXITSTATUS(rc));
        check_reference_run(path, ply, log, dply);
    }
done:
    hl_dynamic_destroy(d);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ timing */

static double median_of(double *v, int n)
{
    for (int i = 1; i < n; i++)
        for (int k = i; k > 0 && v[k - 1] > v[k]; k--) {
            double t = v[k]; v[k] = v[k - 1], v[k - 1] = t;
        }
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static void timing(uint64_t budget, uint32_t R)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) return;
    bunny_scene b;
    hl_env *env = sky(ctx);
    hl_light_split *s = split_of(ctx, env, 32);
    hl_frame_state *st = NULL;
    hl_frame_settings set = {.R = R, .M = 16, .budget = budget, .min_share = -1.0f};
    /* HL_TEST_SHADOW=csm|moments: that representation, else the default */
    const char *rep = getenv("HL_TEST_SHADOW");
    set.shadow = !rep ? HL_SHADOW_REP_DEFAULT : !strcmp(rep, "moments") ? HL_SHADOW_REP_MOMENTS : HL_SHADOW_REP_CSM;
    if (!s || !bunny_open(ctx, &b) || hl_frame_state_create(ctx, b.obj, 2, s->count, &set, &st) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(ctx));
        return;
    }
    /* rounds of three kinds after the first frame: the bunny nudged by
       1e-6 of its height (a caster: every map made), the same again and
       the ground nudged (both keep the maps) */
    enum { ROUNDS = 9, KINDS = 3, STAGES = 6 };
    static const char *const kinds[KINDS] = {"bunny nudged", "same again", "ground nudged"};
    double t[KINDS][STAGES][ROUNDS];
    uint32_t kept[KINDS] = {0, 0, 0};
    float lo = INFINITY, hi = -INFINITY;
    for (uint32_t v = 0; v < b.obj[0].nverts; v++) lo = fminf(lo, b.obj[0].pos[3 * v + 1]), hi = fmaxf(hi, b.obj[0].pos[3 * v + 1]);
    const float nudge = 1e-6f * (hi - lo);
    int ok = 1;
    for (int f = -1; ok && f < ROUNDS * KINDS; f++) {
        const int kind = f < 0 ? -1 : f % KINDS, round = f < 0 ? 0 : f / KINDS;
        if (kind == 0) b.obj[0].xf[3] += nudge * (float)(round + 1);
        if (kind == 2) b.obj[1].xf[3] += nudge * (float)(round + 1);
        hl_frame_stats fs;
        ok = hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, &fs) == HL_OK;
        if (!ok) { fprintf(stderr, "%s\n", hl_context_last_error(ctx)); break; }
        printf("%s frame on %s: %u receivers, %u lights (%u shadowed, %u below every horizon, %u negligible), "
               "%u batch(es) of up to %u, %u shadow maps kept: total %.1f ms = irradiance %.1f + shadow maps %.1f + "
               "build %.1f + eval %.1f + shading %.2f\n",
               kind < 0 ? "first" : kinds[kind], hl_context_device_name(ctx), fs.receivers, fs.lights, fs.shadowed,
               fs.skipped_horizon, fs.skipped_negligible, fs.batches, fs.batch_lights, fs.maps_kept, 1e3 * fs.t_total,
               1e3 * fs.t_irradiance, 1e3 * fs.t_shadow_maps, 1e3 * fs.t_csm_build, 1e3 * fs.t_csm_eval,
               1e3 * fs.t_shading);
        if (kind < 0) continue;
        const double sv[STAGES] = {fs.t_total, fs.t_irradiance, fs.t_shadow_maps, fs.t_csm_build, fs.t_csm_eval, fs.t_shading};
        for (int c = 0; c < STAGES; c++) t[kind][c][round] = 1e3 * sv[c];
        if (fs.maps_kept > kept[kind]) kept[kind] = fs.maps_kept;
    }
    for (int k = 0; ok && k < KINDS; k++) {
        double m[STAGES];
        for (int c = 0; c < STAGES; c++) m[c] = median_of(t[k][c], ROUNDS);
        printf("median of %d %s frames (most maps kept %u): total %.1f ms = irradiance %.1f + shadow maps %.2f + "
               "build %.2f + eval %.1f + shading %.2f\n",
               ROUNDS, kinds[k], kept[k], m[0], m[1], m[2], m[3], m[4], m[5]);
    }
    hl_frame_state_destroy(st);
    bunny_close(&b);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

/* ------------------------------------------------------------ sharp_rays */

enum { SR_G = 41 }; /* the ground's grid: SR_G x SR_G vertices over [-2, 2]^2 */

/* The square light's samples blocked at ground point (x, z) by the
 * square [cx - 1, cx + 1] x [-1, 1] at height 1, worked out here by the
 * plane: a sample of offset (ox, oz) (the grid's centres, in units of
 * tan spread) meets the plane at (x + ta ox, z + ta oz). The offsets are
 * the same set whichever way the basis turns. */
static uint32_t sr_blocked(double x, double z, double cx, double ta)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < HL_SHARP_RAYS_GRID; i++)
        for (uint32_t j = 0; j < HL_SHARP_RAYS_GRID; j++) {
            const double ox = (2.0 * i + 1.0) / HL_SHARP_RAYS_GRID - 1.0, oz = (2.0 * j + 1.0) / HL_SHARP_RAYS_GRID - 1.0;
            n += fabs(x + ta * ox - cx) < 1.0 && fabs(z + ta * oz) < 1.0;
        }
    return n;
}

/* The sharp lights' rays alone (sharp_rays.h) on a ground grid under a
 * square at height 1, the light straight above with tan spread 0.22:
 * every receiver's V is the share of the 16 samples the plane leaves
 * free (tolerance 0), umbra, penumbra and full light all occur, a
 * receiver with E = 0 gets 0 and no ray, and the rays cast are 5 a lit
 * receiver and 16 more in a penumbra. Then the square moved by 0.5. */
static void rays_analytic(void)
{
    hl_context *ctx = hl_test_ref_context(2);
    const uint32_t ng = SR_G * SR_G, N = ng + 4;
    float *pos = malloc((size_t)N * 12), *nrm = malloc((size_t)N * 12), *E = malloc((size_t)N * 12), *V = malloc((size_t)N * 4);
    uint32_t *tri = malloc((size_t)(SR_G - 1) * (SR_G - 1) * 6 * 4);
    uint32_t nt = 0;
    for (uint32_t j = 0; j < SR_G; j++)
        for (uint32_t i = 0; i < SR_G; i++) {
            float *p = pos + 3 * (size_t)(j * SR_G + i);
            p[0] = -2.0f + 4.0f * (float)i / (SR_G - 1), p[1] = 0.0f, p[2] = -2.0f + 4.0f * (float)j / (SR_G - 1);
            if (i + 1 < SR_G && j + 1 < SR_G) {
                const uint32_t a = j * SR_G + i, q[6] = {a, a + SR_G, a + 1, a + 1, a + SR_G, a + SR_G + 1};
                memcpy(tri + 6 * (size_t)nt++, q, sizeof q);
            }
        }
    const float sq[12] = {-1, 1, -1, 1, 1, -1, 1, 1, 1, -1, 1, 1};
    const uint32_t sqt[6] = {0, 2, 1, 0, 3, 2};
    memcpy(pos + 3 * (size_t)ng, sq, sizeof sq);
    for (uint32_t v = 0; v < N; v++) nrm[3 * v] = 0.0f, nrm[3 * v + 1] = 1.0f, nrm[3 * v + 2] = 0.0f;
    for (size_t i = 0; i < 3 * (size_t)N; i++) E[i] = 1.0f;
    const uint32_t dark = 5 * SR_G + 7; /* a receiver the light does not reach */
    E[3 * dark] = E[3 * dark + 1] = E[3 * dark + 2] = 0.0f;
    hl_dyn_object o[2] = {{.pos = pos, .normal = nrm, .nverts = ng, .tri = tri, .ntris = 2 * nt},
                          {.pos = pos + 3 * (size_t)ng, .normal = nrm, .nverts = 4, .tri = sqt, .ntris = 2}};
    for (int b = 0; b < 2; b++) o[b].xf[0] = o[b].xf[5] = o[b].xf[10] = 1.0f;
    hl_sharp_rays *sr = NULL;
    HL_CHECK(hl_sharp_rays_create(ctx, o, 2, &sr) == HL_OK, "%s", hl_context_last_error(ctx));
    const float up[3] = {0.0f, 1.0f, 0.0f};
    const double ta = 0.22;
    for (int pass = 0; sr && pass < 2; pass++) {
        const double cx = pass ? 0.5 : 0.0;
        if (pass) {
            o[1].xf[3] = 0.5f;
            HL_CHECK(hl_sharp_rays_set_transform(sr, 1, o[1].xf) == HL_OK, "%s", hl_context_last_error(ctx));
            for (uint32_t v = ng; v < N; v++) pos[3 * v] = sq[3 * (v - ng)] + 0.5f; /* its world positions */
        }
        uint64_t rays = 0;
        HL_CHECK(hl_sharp_rays_visibility(sr, pos, nrm, E, up, (float)atan(ta), V, &rays) == HL_OK, "%s",
                 hl_context_last_error(ctx));
        double worst = 0.0;
        uint32_t umbra = 0, pen = 0, lit = 0;
        uint64_t want_rays = 0;
        for (uint32_t v = 0; v < ng; v++) {
            if (v == dark) continue;
            const uint32_t blk = sr_blocked(pos[3 * v], pos[3 * v + 2], cx, ta);
            const double want = 1.0 - blk / (double)(HL_SHARP_RAYS_GRID * HL_SHARP_RAYS_GRID);
            worst = fmax(worst, fabs(V[v] - want));
            umbra += blk == HL_SHARP_RAYS_GRID * HL_SHARP_RAYS_GRID, lit += blk == 0;
            pen += blk > 0 && blk < HL_SHARP_RAYS_GRID * HL_SHARP_RAYS_GRID;
        }
        for (uint32_t v = ng; v < N; v++) worst = fmax(worst, fabs(V[v] - 1.0)); /* the square's own: free */
        want_rays = 5ull * (N - 1) + (uint64_t)HL_SHARP_RAYS_GRID * HL_SHARP_RAYS_GRID * pen;
        printf("square at x = %.1f: %u ground receivers in its umbra, %u in its penumbra, %u lit; V at the unlit one "
               "%g (want 0); %llu rays (want %llu: 5 a lit receiver, 16 more in a penumbra)\n",
               cx, umbra, pen, lit, (double)V[dark], (unsigned long long)rays, (unsigned long long)want_rays);
        HL_CHECK(umbra > 0 && pen > 0 && lit > 0, "the grid must hold umbra, penumbra and light");
        HL_CHECK(V[dark] == 0.0f && rays == want_rays, "V %g at E = 0, %llu rays", (double)V[dark],
                 (unsigned long long)rays);
        hl_check_error("  V against the plane's share of free samples", worst, 0.0);
    }
    hl_sharp_rays_destroy(sr);
    free(pos); free(nrm); free(E); free(V); free(tri);
    hl_context_destroy(ctx);
}

/* Relative L2 of the bunny scene's colours a against b (both bodies). */
static double scene_l2(const bunny_scene *bs, float *const *a, float *const *b)
{
    double num = 0.0, den = 0.0;
    for (int k = 0; k < 2; k++)
        for (size_t i = 0; i < 3 * (size_t)bs->obj[k].nverts; i++) {
            const double d = (double)a[k][i] - b[k][i];
            num += d * d, den += (double)b[k][i] * b[k][i];
        }
    return den > 0.0 ? sqrt(num / den) : 0.0;
}

/* The bunny on its ground under the sky's sun alone (one light kept,
 * the rest folded and unshadowed; R = 64) against the same light with
 * traced visibility (hl_dyn_reference_lights): with the sun by rays the
 * frame is nearer than with the sun in a map of R (off) or of 4 R
 * (maps), on the device's receivers and the host's; and both receivers
 * give the same colours to the bit. */
static void rays_frame(void)
{
    hl_context *ctx = hl_test_cl_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    bunny_scene b;
    hl_env *env = sky(ctx);
    hl_light_split *s = env ? split_of(ctx, env, 1) : NULL;
    if (!s || !bunny_open(ctx, &b)) {
        hl_light_split_destroy(s);
        hl_env_destroy(env);
        hl_context_destroy(ctx);
        return;
    }
    const size_t n0 = 3 * (size_t)b.obj[0].nverts, n1 = 3 * (size_t)b.obj[1].nverts;
    float *kl[2] = {malloc(n0 * 4), malloc(n1 * 4)}, *fr[2] = {malloc(n0 * 4), malloc(n1 * 4)};
    float *dev = malloc((n0 + n1) * 4);
    HL_CHECK(hl_dyn_reference_lights(ctx, b.obj, 2, b.alb, s, 0, kl, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    const hl_sharp_mode modes[3] = {HL_SHARP_RAYS, HL_SHARP_OFF, HL_SHARP_MAPS};
    const char *names[3] = {"rays", "off", "maps of 4 R"};
    for (int path = 0; path < 2; path++) {
        if (path) setenv("HL_TEST_DYN_FRAME", "host", 1);
        double l2[3] = {0, 0, 0};
        for (int m = 0; m < 3; m++) {
            hl_frame_settings set = {.R = 64, .min_share = -1.0f, .sharp = modes[m]};
            hl_frame_state *st = NULL;
            hl_frame_stats fs;
            int ok = hl_frame_state_create(ctx, b.obj, 2, s->count, &set, &st) == HL_OK &&
                     hl_frame_render(st, b.obj, 2, b.alb, s, b.rgb, &fs) == HL_OK;
            HL_CHECK(ok, "%s", hl_context_last_error(ctx));
            hl_frame_state_destroy(st);
            if (!ok) continue;
            memcpy(fr[0], b.rgb[0], n0 * 4), memcpy(fr[1], b.rgb[1], n1 * 4);
            l2[m] = scene_l2(&b, fr, kl);
            printf("  %s receivers, sun %s: %u sharp, relative L2 against the lights traced %.4f\n", path ? "host" : "device",
                   names[m], fs.sharp, l2[m]);
            if (m == 0 && !path) memcpy(dev, fr[0], n0 * 4), memcpy(dev + n0, fr[1], n1 * 4);
            if (m == 0 && path) {
                size_t d = floats_differ(dev, fr[0], n0) + floats_differ(dev + n0, fr[1], n1);
                hl_check_error("  rays: colour floats where the host's receivers differ from the device's (tolerance 0)",
                               (double)d, 0.0);
            }
        }
        HL_CHECK(l2[0] < l2[1] && l2[0] < l2[2], "the sun by rays (%.4f) is not nearer the traced lights than a map (%.4f, %.4f)",
                 l2[0], l2[1], l2[2]);
        unsetenv("HL_TEST_DYN_FRAME");
    }
    free(kl[0]); free(kl[1]); free(fr[0]); free(fr[1]); free(dev);
    bunny_close(&b);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
}

static void case_sharp_rays(void)
{
    rays_analytic();
    rays_frame();
}

int main(int argc, char **argv)
{
    if (argc > 1 && !strcmp(argv[1], "timing")) { /* timing [BATCH_BUDGET_MIB [R]] */
        timing(argc > 2 ? (uint64_t)strtoull(argv[2], NULL, 10) << 20 : 0,
               argc > 3 ? (uint32_t)strtoul(argv[3], NULL, 10) : 256);
        return 0;
    }
    static const hl_test_case cases[] = {{"unshadowed", case_unshadowed}, {"motion", case_motion}, {"below", case_below},
                                         {"twin", case_twin}, {"device", case_device}, {"bad_input", case_bad_input},
                                         {"api", case_api},               {"cli", case_cli},
                                         {"file", case_file},             {"keep", case_keep},
                                         {"sharp", case_sharp},           {"contact", case_contact},
                                         {"enclosed", case_enclosed},     {"sharp_rays", case_sharp_rays},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
