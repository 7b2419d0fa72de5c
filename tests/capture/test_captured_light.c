/* test_captured_light.c - the relighter lit by surroundings
 * (hl_relighter_set_surroundings: the capture in env2para's place, then
 * Haar, selection and the dot products), suite "captured_light", on the
 * bunny on its ground (data/bunny_lowres.obj, coarse settings).
 *
 * captured_light.twin        the OpenCL relighter against the plain-C
 *                            reference with surroundings, over an
 *                            environment and over black, all terms and
 *                            200: the same colours.
 * captured_light.reuse       a run with nothing changed does no work
 *                            (stats.reused); moving the surroundings
 *                            relights, and moving them back gives the
 *                            first colours bit for bit.
 * captured_light.crosscheck  the same surroundings captured, and rendered
 *                            into an equirectangular EXR file that is
 *                            loaded the ordinary way: vertex colours agree.
 * captured_light.motion      a small bright lamp carried around the bunny
 *                            puts the bunny's shadow on the ground on the
 *                            side opposite the lamp, wherever it is.
 * captured_light.bad         no lighting at all, and surroundings taken
 *                            away, get clear errors.
 * captured_light.reference   the near-field references (relight
 *                            --reference): exact against Lambert's formula
 *                            where nothing hides the lamp, and 0 where a
 *                            dark panel of the surroundings hides it from
 *                            the vertex (the capture point still sees it:
 *                            centre lights those vertices); a lamp 1000
 *                            times as far and as large gives exact = centre;
 *                            the relit colours against centre and discrete.
 * captured_light.probes      more than one capture point
 *                            (hl_relighter_set_probes): every vertex's
 *                            weights sum to 1, no more points than asked; a
 *                            far lamp needs one, and gives the colours of
 *                            no probes bit for bit; a near lamp's error
 *                            against the exact reference falls; OpenCL
 *                            against the reference, colours into a device
 *                            buffer, and bad counts and tolerances.
 *
 * Depends on: haarlight_core, the haarlight command (HL_BIN) for the
 * transport, an OpenCL device (PoCL).
 */
#include <stdint.h>
#include <string.h>

#include "haarlight_tools.h"
#include <unistd.h>

#include "capture.h"
#include "capture_util.h"
#include "hl_internal.h"
#include "hl_test.h"
#include "cl_backend.h"
#include "lighting.h"

/* The bunny on a ground of res x res quads: its transport, made once per
 * test process and ground resolution. */
static hl_transport *bunny(hl_context *ctx, int res)
{
    char path[1024], cmd[4096];
    snprintf(path, sizeof path, "%s/captured_light.%ld.%d.hlt", hl_test_env("HL_TMP", "/tmp"), (long)getpid(), res);
    if (access(path, R_OK) != 0) {
        snprintf(cmd, sizeof cmd, "'%s' precompute '%s/bunny_lowres.obj' --ground --ground-res %d -C 32 -N 32 -q -o '%s'",
                 hl_test_env("HL_BIN", "haarlight"), hl_test_env("HL_REPO_DATA", "data"), res, path);
        if (system(cmd) != 0) {
            fprintf(stderr, "failed: %s\n", cmd);
            return NULL;
        }
    }
    hl_transport *t = NULL;
    return hl_transport_load(ctx, path, &t) == HL_OK ? t : NULL;
}

/* The object's bounding box (the vertices before the ground). */
static void object_box(const hl_mesh *m, double c[3], double *half_diag)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v = 0; v < m->object_vertex_count; v++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], m->positions[3 * v + a]);
            hi[a] = fmax(hi[a], m->positions[3 * v + a]);
        }
    double d2 = 0.0;
    for (int a = 0; a < 3; a++) {
        c[a] = 0.5 * (lo[a] + hi[a]);
        d2 += (hi[a] - lo[a]) * (hi[a] - lo[a]);
    }
    *half_diag = 0.5 * sqrt(d2);
}

/* An OpenCL context and the bunny's transport (ground res x res) with the
 * object's box; NULL, after a failed check, when either is missing. */
static hl_transport *cl_bunny(hl_context **cl, int res, double c[3], double *hd)
{
    *cl = hl_test_cl_context(0);
    HL_CHECK(*cl != NULL, "an OpenCL device is needed");
    hl_transport *t = *cl ? bunny(*cl, res) : NULL;
    HL_CHECK(!*cl || t != NULL, "transport");
    if (t) object_box(t->mesh, c, hd);
    else {
        hl_context_destroy(*cl);
        *cl = NULL;
    }
    return t;
}

/* An axis-aligned emissive (or dark) box of half side h about c. */
static void add_box(soup *s, const double c[3], double h, const float e[3])
{
    for (int f = 0; f < 6; f++) {
        int ax = f / 2;
        double q[3] = {c[0], c[1], c[2]}, u[3] = {0, 0, 0}, v[3] = {0, 0, 0};
        q[ax] += f % 2 ? -h : h;
        u[(ax + 1) % 3] = h;
        v[(ax + 2) % 3] = h;
        add_quad(s, q, u, v, e);
    }
}

/* A lamp box at azimuth az (radians about +Y, 0 on +X), elevation el,
 * distance dist from c; a dark wall and a coloured panel further out. */
static void lamp_scene(soup *s, const double c[3], double size, double az, double el, double dist, int extras)
{
    static const float lamp[3] = {60.0f, 45.0f, 30.0f}, dark[3] = {0, 0, 0}, panel[3] = {0.4f, 1.5f, 0.6f};
    s->n = 0;
    const double p[3] = {c[0] + dist * cos(el) * cos(az), c[1] + dist * sin(el), c[2] + dist * cos(el) * sin(az)};
    add_box(s, p, 0.08 * size, lamp);
    if (!extras) return;
    const double wc[3] = {c[0] - 3.0 * size, c[1] + 0.5 * size, c[2]}, wu[3] = {0, size, 0}, wv[3] = {0, 0, 1.5 * size};
    add_quad(s, wc, wu, wv, dark);
    const double pc[3] = {c[0] + 0.5 * size, c[1] + 0.3 * size, c[2] + 3.0 * size}, pu[3] = {size, 0, 0},
                 pv[3] = {0, 0.7 * size, 0};
    add_quad(s, pc, pu, pv, panel);
}

static hl_surroundings *surroundings_of(hl_context *ctx, const soup *s)
{
    hl_surroundings *sur = NULL;
    if (hl_surroundings_create(ctx, s->pos, s->em, s->n, &sur) != HL_OK) {
        fprintf(stderr, "hl_surroundings_create: %s\n", hl_context_last_error(ctx));
        return NULL;
    }
    return sur;
}

/* Vertex colours (3 per vertex) of r with desc terms, or NULL. */
static float *colours(hl_context *ctx, hl_relighter *r, const hl_transport *t, uint32_t terms, hl_relight_stats *st)
{
    float *rgb = malloc((size_t)t->info.vertex_count * 12);
    hl_relight_desc d = {0};
    d.terms = terms;
    hl_relight_stats dummy;
    if (hl_relighter_run(r, &d, rgb, st ? st : &dummy) != HL_OK) {
        fprintf(stderr, "hl_relighter_run: %s\n", hl_context_last_error(ctx));
        free(rgb);
        return NULL;
    }
    return rgb;
}


/* A 2:1 environment: a soft gradient, times scale. */
static hl_env *gradient_env(hl_context *ctx, uint32_t W, float scale)
{
    uint32_t H = W / 2;
    float *rgb = malloc((size_t)W * H * 12);
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            float *p = rgb + 3 * ((size_t)y * W + x);
            p[0] = scale * (0.2f + 0.5f * (float)y / (float)H);
            p[1] = scale * (0.3f + 0.2f * (float)x / (float)W);
            p[2] = scale * (0.9f - 0.6f * (float)y / (float)H);
        }
    hl_env *env = NULL;
    hl_env_create(ctx, W, H, rgb, &env, NULL);
    free(rgb);
    return env;
}

/* ================================================================ twin */

static void case_twin(void)
{
    hl_context *cl = hl_test_cl_context(0), *ref = hl_test_ref_context(0);
    HL_CHECK(cl != NULL, "an OpenCL device is needed");
    hl_transport *tc = cl ? bunny(cl, 12) : NULL, *tr = bunny(ref, 12);
    HL_CHECK(tr && (!cl || tc), "transport");
    if (!cl || !tc || !tr) { hl_context_destroy(ref); hl_context_destroy(cl); return; }
    double c[3], hd;
    object_box(tr->mesh, c, &hd);
    static soup s;
    lamp_scene(&s, c, 2.0 * hd, 0.6, 0.7, 3.0 * hd, 1);
    hl_surroundings *sc = surroundings_of(cl, &s), *sr = surroundings_of(ref, &s);
    hl_relighter *rc = NULL, *rr = NULL;
    HL_CHECK(sc && sr && hl_relighter_create(cl, tc, &rc) == HL_OK && hl_relighter_create(ref, tr, &rr) == HL_OK,
             "relighters");
    hl_env *ec = gradient_env(cl, 256, 0.5f), *er = gradient_env(ref, 256, 0.5f);
    const size_t n = (size_t)tr->info.vertex_count * 3;
    for (int withenv = 0; rc && rr && withenv < 2; withenv++) {
        if (withenv) HL_CHECK(hl_relighter_set_env(rc, ec) == HL_OK && hl_relighter_set_env(rr, er) == HL_OK, "env");
        HL_CHECK(hl_relighter_set_surroundings(rc, sc) == HL_OK && hl_relighter_set_surroundings(rr, sr) == HL_OK,
                 "set_surroundings: %s", hl_context_last_error(cl));
        static const uint32_t Ms[] = {HL_TERMS_ALL, 200};
        for (int k = 0; k < 2; k++) {
            float *a = colours(ref, rr, tr, Ms[k], NULL), *b = colours(cl, rc, tc, Ms[k], NULL);
            HL_CHECK(a && b, "runs");
            if (a && b) {
                char what[160];
                snprintf(what, sizeof what, "surroundings over %s, M=%s: OpenCL vs reference colours (relative to max)",
                         withenv ? "an environment" : "black", k ? "200" : "all");
                /* as hl.relight.twin: float sums in another order */
                hl_check_error(what, hl_test_rel_diff(a, b, n), 1e-4);
            }
            free(a);
            free(b);
        }
    }
    hl_env_destroy(ec);
    hl_env_destroy(er);
    hl_relighter_destroy(rc);
    hl_relighter_destroy(rr);
    hl_surroundings_destroy(sc);
    hl_surroundings_destroy(sr);
    hl_transport_destroy(tc);
    hl_transport_destroy(tr);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* =============================================================== reuse */

static void case_reuse(void)
{
    hl_context *cl = NULL;
    double c[3], hd;
    hl_transport *t = cl_bunny(&cl, 12, c, &hd);
    if (!t) return;
    static soup s;
    lamp_scene(&s, c, 2.0 * hd, 0.3, 0.6, 3.0 * hd, 1);
    hl_surroundings *sur = surroundings_of(cl, &s);
    hl_relighter *r = NULL;
    HL_CHECK(sur && hl_relighter_create(cl, t, &r) == HL_OK && hl_relighter_set_surroundings(r, sur) == HL_OK,
             "relighter: %s", hl_context_last_error(cl));
    const size_t n = (size_t)t->info.vertex_count * 3;
    hl_relight_stats s1, s2, s3, s4;
    float *a = r ? colours(cl, r, t, 0, &s1) : NULL, *b = r ? colours(cl, r, t, 0, &s2) : NULL;
    HL_CHECK(a && b && !s1.reused && s2.reused, "unchanged surroundings: reused %d then %d", a ? s1.reused : -1,
             b ? s2.reused : -1);
    /* the lamp carried a quarter turn about the object's vertical axis */
    const float q[12] = {0, 0, 1, (float)(c[0] - c[2]), 0, 1, 0, 0, -1, 0, 0, (float)(c[2] + c[0])};
    const float id[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    HL_CHECK(sur && hl_surroundings_set_transform(sur, 0, q) == HL_OK, "set_transform: %s", hl_context_last_error(cl));
    float *m = r ? colours(cl, r, t, 0, &s3) : NULL;
    HL_CHECK(m && !s3.reused, "moved surroundings must relight (reused %d)", m ? s3.reused : -1);
    if (a && m) {
        double d = hl_test_rel_diff(a, m, n);
        printf("moved lamp: colours change by %.3g of the brightest\n", d);
        HL_CHECK(d > 0.05, "a lamp carried a quarter turn changed the colours by only %.3g", d);
    }
    HL_CHECK(sur && hl_surroundings_set_transform(sur, 0, id) == HL_OK, "set_transform back");
    float *back = r ? colours(cl, r, t, 0, &s4) : NULL;
    HL_CHECK(back && !s4.reused, "moved back must relight");
    if (a && back) {
        HL_CHECK(!memcmp(a, back, n * 4), "moved back: colours differ from the first run");
        hl_check_error("moved back: against the first run (bitwise, max abs)", hl_test_rel_diff(a, back, n), 0.0);
    }
    free(a); free(b); free(m); free(back);
    hl_relighter_destroy(r);
    hl_surroundings_destroy(sur);
    hl_transport_destroy(t);
    hl_context_destroy(cl);
}

/* ========================================================== crosscheck */

static void case_crosscheck(void)
{
    hl_context *cl = NULL;
    double c[3], hd;
    hl_transport *t = cl_bunny(&cl, 12, c, &hd);
    if (!t) return;
    const float o[3] = {(float)c[0], (float)c[1], (float)c[2]};
    static soup s;
    lamp_scene(&s, c, 2.0 * hd, 2.2, 0.5, 3.0 * hd, 1);
    /* a bigger soft lamp too, so that not all the light is one box */
    static const float warm[3] = {3.0f, 2.0f, 1.2f};
    const double bc[3] = {c[0] + 0.5 * hd, c[1] + 4.0 * hd, c[2] - 1.0 * hd}, bu[3] = {1.5 * hd, 0, 0},
                 bv[3] = {0, 0, 1.5 * hd};
    add_quad(&s, bc, bu, bv, warm);
    static const float sky[3] = {0.3f, 0.4f, 0.6f};
    const uint32_t W = 1024, H = 512;
    /* the ordinary path: the surroundings over the sky rendered into an
       equirectangular EXR, loaded like any map */
    float *px = render_equirect(&s, o, W, H, sky), *flat = malloc((size_t)W * H * 12);
    for (size_t i = 0; i < (size_t)W * H; i++) memcpy(flat + 3 * i, sky, 12);
    hl_image img = {W, H, px};
    const char *exr = hl_test_tmp_path("captured_light_xc.exr");
    hl_env *env = NULL, *skyenv = NULL;
    HL_CHECK(hl_image_save(cl, &img, exr, 0.0f) == HL_OK && hl_env_load(cl, exr, &env, NULL) == HL_OK,
             "the EXR: %s", hl_context_last_error(cl));
    HL_CHECK(hl_env_create(cl, W, H, flat, &skyenv, NULL) == HL_OK, "sky");
    hl_surroundings *sur = surroundings_of(cl, &s);
    hl_relighter *re = NULL, *rc = NULL;
    HL_CHECK(env && skyenv && sur && hl_relighter_create(cl, t, &re) == HL_OK && hl_relighter_create(cl, t, &rc) == HL_OK &&
                 hl_relighter_set_env(re, env) == HL_OK && hl_relighter_set_env(rc, skyenv) == HL_OK &&
                 hl_relighter_set_surroundings(rc, sur) == HL_OK,
             "relighters: %s", hl_context_last_error(cl));
    const uint32_t V = t->info.vertex_count;
    float *a = rc ? colours(cl, re, t, HL_TERMS_ALL, NULL) : NULL, *b = rc ? colours(cl, rc, t, HL_TERMS_ALL, NULL) : NULL;
    HL_CHECK(a && b, "runs");
    if (a && b) {
        /* luminance-free: every channel against the brightest vertex's,
           and the mean over vertices against the mean colour */
        double m = 0.0, sd = 0.0, sa = 0.0;
        for (size_t i = 0; i < (size_t)V * 3; i++) {
            m = fmax(m, a[i]);
            sd += fabs((double)a[i] - b[i]);
            sa += a[i];
        }
        double worst = hl_test_rel_diff(a, b, (size_t)V * 3);
        printf("%u vertices; brightest channel %.4g\n", V, m);
        /* Both paths see the same surroundings; they differ where an edge
           cuts a paraboloid texel: the capture weights the texel's rays
           exactly, the EXR path averages equirectangular cells (1024 x 512,
           3 x 3 samples each) over the texel's taps. At N = 32 a texel is
           about 5.6 degrees; the lamp box is a few texels wide, so an edge
           error of half a texel on a few texels of a light that gives most
           of the light bounds the worst vertex near 2%. */
        hl_check_error("N=32 surroundings captured vs rendered into an EXR: worst vertex channel (of the brightest)",
                       worst, 0.02);
        hl_check_error("N=32 surroundings captured vs rendered into an EXR: mean |difference| (of the mean)", sd / sa, 0.005);
    }
    free(a); free(b); free(px); free(flat);
    unlink(exr);
    hl_relighter_destroy(re);
    hl_relighter_destroy(rc);
    hl_surroundings_destroy(sur);
    hl_env_destroy(env);
    hl_env_destroy(skyenv);
    hl_transport_destroy(t);
    hl_context_destroy(cl);
}

/* ============================================================== motion */

static void case_motion(void)
{
    hl_context *cl = NULL;
    double c[3], hd;
    hl_transport *t = cl_bunny(&cl, 40, c, &hd);
    if (!t) return;
    const hl_mesh *me = t->mesh;
    const uint32_t V = me->vertex_count, V0 = me->object_vertex_count;
    hl_relighter *r = NULL;
    HL_CHECK(hl_relighter_create(cl, t, &r) == HL_OK, "relighter");
    double prev[2] = {0, 0};
    const int steps = 8;
    double worst = 0.0;
    for (int k = 0; r && k < steps; k++) {
        const double az = 2.0 * HL_PI * k / steps + 0.2;
        static soup s;
        lamp_scene(&s, c, 2.0 * hd, az, 0.75, 3.0 * hd, 0);
        hl_surroundings *sur = surroundings_of(cl, &s);
        float *rgb = sur && hl_relighter_set_surroundings(r, sur) == HL_OK ? colours(cl, r, t, 0, NULL) : NULL;
        HL_CHECK(rgb != NULL, "lamp at %.0f degrees", az * 180.0 / HL_PI);
        if (!rgb) { hl_surroundings_destroy(sur); continue; }
        /* the ground's lit level: its brightest decile's mean (the lamp is
           one direction from the capture point, so the open ground is
           evenly lit); shadowed: below half of it */
        uint32_t ng = V - V0;
        float *gy = malloc((size_t)ng * 4);
        for (uint32_t v = V0; v < V; v++) gy[v - V0] = rgb[3 * v] + rgb[3 * v + 1] + rgb[3 * v + 2];
        float lit = 0.0f;
        for (uint32_t i = 0; i < ng; i++) lit = fmaxf(lit, gy[i]);
        double sx = 0.0, sz = 0.0;
        uint32_t ns = 0;
        for (uint32_t v = V0; v < V; v++) {
            if (gy[v - V0] >= 0.5f * lit) continue;
            sx += me->positions[3 * v] - c[0];
            sz += me->positions[3 * v + 2] - c[2];
            ns++;
        }
        free(gy);
        double shadow_az = atan2(sz, sx), want = az + HL_PI;
        double d = fabs(remainder(shadow_az - want, 2.0 * HL_PI));
        printf("lamp at %5.1f deg: %u of %u ground vertices in shadow, their centre at %6.1f deg (opposite: %6.1f), off by %.1f deg\n",
               fmod(az * 180.0 / HL_PI, 360.0), ns, ng, fmod(shadow_az * 180.0 / HL_PI + 360.0, 360.0),
               fmod(want * 180.0 / HL_PI, 360.0), d * 180.0 / HL_PI);
        HL_CHECK(ns >= 5, "lamp at %.0f degrees: only %u ground vertices in shadow", az * 180.0 / HL_PI, ns);
        if (d > worst) worst = d;
        /* the shadow moved with the lamp */
        if (k > 0) HL_CHECK(sx * prev[0] + sz * prev[1] < 0.95 * sqrt((sx * sx + sz * sz) * (prev[0] * prev[0] + prev[1] * prev[1])),
                            "the shadow did not move from the last lamp position");
        prev[0] = sx;
        prev[1] = sz;
        free(rgb);
        hl_surroundings_destroy(sur);
    }
    /* The shadow of a bunny is not symmetric about the lamp's azimuth,
       but its centre lies within 30 degrees of the opposite direction. */
    hl_check_error("shadow centre against the direction opposite the lamp (radians)", worst, 30.0 * HL_PI / 180.0);
    hl_relighter_destroy(r);
    hl_transport_destroy(t);
    hl_context_destroy(cl);
}

/* ================================================================= bad */

static void case_bad(void)
{
    hl_context *ref = hl_test_ref_context(0);
    hl_transport *t = bunny(ref, 12);
    HL_CHECK(t != NULL, "transport");
    if (!t) { hl_context_destroy(ref); return; }
    hl_relighter *r = NULL;
    HL_CHECK(hl_relighter_create(ref, t, &r) == HL_OK, "relighter");
    float *rgb = malloc((size_t)t->info.vertex_count * 12);
    hl_result res = hl_relighter_run(r, NULL, rgb, NULL);
    const char *msg = hl_context_last_error(ref);
    HL_CHECK(res == HL_ERR_INVALID_ARGUMENT && msg && strstr(msg, "surroundings"),
             "no lighting at all: %s (%s)", hl_result_string(res), msg ? msg : "");
    printf("no lighting: %s\n", msg ? msg : "");
    double c[3], hd;
    object_box(t->mesh, c, &hd);
    static soup s;
    lamp_scene(&s, c, 2.0 * hd, 0.0, 0.5, 3.0 * hd, 0);
    hl_surroundings *sur = surroundings_of(ref, &s);
    HL_CHECK(sur && hl_relighter_set_surroundings(r, sur) == HL_OK && hl_relighter_run(r, NULL, rgb, NULL) == HL_OK,
             "surroundings alone light the object");
    for (size_t i = 0; i < (size_t)t->info.vertex_count * 3; i++)
        if (!(rgb[i] >= 0.0f && isfinite(rgb[i]))) {
            HL_CHECK(0, "vertex %zu: colour %g", i / 3, (double)rgb[i]);
            break;
        }
    HL_CHECK(hl_relighter_set_surroundings(r, NULL) == HL_OK, "taking them away");
    res = hl_relighter_run(r, NULL, rgb, NULL);
    HL_CHECK(res == HL_ERR_INVALID_ARGUMENT, "surroundings taken away, no environment: %s", hl_result_string(res));
    free(rgb);
    hl_relighter_destroy(r);
    hl_surroundings_destroy(sur);
    hl_transport_destroy(t);
    hl_context_destroy(ref);
}

/* ============================================================ reference */

/* Lambert's formula: the irradiance at p (unit normal n) from a convex
 * polygon of radiance 1 wholly above p's horizon. */
static double lambert(const double p[3], const double n[3], const double P[][3], int np)
{
    double s = 0.0;
    for (int k = 0; k < np; k++) {
        double a[3], b[3], la = 0.0, lb = 0.0;
        for (int x = 0; x < 3; x++) {
            a[x] = P[k][x] - p[x];
            b[x] = P[(k + 1) % np][x] - p[x];
            la += a[x] * a[x];
            lb += b[x] * b[x];
        }
        la = sqrt(la);
        lb = sqrt(lb);
        double g[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        double lg = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]), d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb);
        double th = acos(d > 1.0 ? 1.0 : d < -1.0 ? -1.0 : d);
        s += th * (g[0] * n[0] + g[1] * n[1] + g[2] * n[2]) / lg;
    }
    return 0.5 * fabs(s);
}

static double rel_l2(const float *a, const float *ref, size_t n3)
{
    double num = 0.0, den = 0.0;
    for (size_t i = 0; i < n3; i++) {
        num += ((double)a[i] - ref[i]) * ((double)a[i] - ref[i]);
        den += (double)ref[i] * ref[i];
    }
    return den > 0.0 ? sqrt(num / den) : 0.0;
}

static void case_reference(void)
{
    hl_context *ref = hl_test_ref_context(0);
    hl_transport *t = bunny(ref, 24);
    HL_CHECK(t != NULL, "transport");
    if (!t) { hl_context_destroy(ref); return; }
    const hl_mesh *m = t->mesh;
    const uint32_t nv = m->vertex_count, no = m->object_vertex_count;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v = 0; v < no; v++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], m->positions[3 * v + a]);
            hi[a] = fmax(hi[a], m->positions[3 * v + a]);
        }
    /* a square lamp (half side 0.5) 4 above the object's top, over the
       ground vertex nearest 3 beyond its +X side: a ray from a ground
       vertex beyond that side to it never enters the object's box */
    uint32_t below = no;
    double bd = INFINITY;
    for (uint32_t v = no; v < nv; v++) {
        const double dx = m->positions[3 * v] - (hi[0] + 3.0), dz = m->positions[3 * v + 2] - 0.5 * (lo[2] + hi[2]);
        if (dx * dx + dz * dz < bd) {
            bd = dx * dx + dz * dz;
            below = v;
        }
    }
    const double lc[3] = {m->positions[3 * below], hi[1] + 4.0, m->positions[3 * below + 2]}, lu[3] = {0.5, 0, 0},
                 lv[3] = {0, 0, 0.5};
    const float Le[3] = {30.0f, 20.0f, 10.0f}, dark[3] = {0, 0, 0};
    const double P[4][3] = {{lc[0] - 0.5, lc[1], lc[2] - 0.5}, {lc[0] + 0.5, lc[1], lc[2] - 0.5},
                            {lc[0] + 0.5, lc[1], lc[2] + 0.5}, {lc[0] - 0.5, lc[1], lc[2] + 0.5}};
    static soup s;
    s.n = 0;
    add_quad(&s, lc, lu, lv, Le);
    /* a dark panel 2 above the ground under the lamp, 1.2 a side of its
       centre: it hides the whole lamp from the ground within 1.3 of the
       point below the lamp (0.3 is tested) and none of it beyond 1.5 (4
       is), and not from the capture point, whose rays to the lamp rise
       above it */
    const double gy = m->positions[3 * below + 1], pc[3] = {lc[0], gy + 2.0, lc[2]}, pu[3] = {1.2, 0, 0},
                 pv[3] = {0, 0, 1.2};
    add_quad(&s, pc, pu, pv, dark);
    hl_surroundings *sur = surroundings_of(ref, &s);
    float *ex = malloc((size_t)nv * 12), *ce = malloc((size_t)nv * 12), *di = malloc((size_t)nv * 12),
          *rl = malloc((size_t)nv * 12);
    HL_CHECK(sur && ex && ce && di && rl, "setup");
    if (!sur || !ex || !ce || !di || !rl) goto done;
    double sec = 0.0;
    HL_CHECK(hl_bench_capture_ref(ref, t, sur, HL_CAPTURE_REF_EXACT, 32, ex, &sec) == HL_OK, "exact: %s",
             hl_context_last_error(ref));
    printf("exact reference, %u vertices, 32 x 32 points a triangle: %.2f s\n", nv, sec);
    HL_CHECK(hl_bench_capture_ref(ref, t, sur, HL_CAPTURE_REF_CENTRE, 32, ce, NULL) == HL_OK, "centre");
    /* open: ground vertices beyond the object's +X side, away from the panel's shadow */
    double worst = 0.0, worst_hidden = 0.0, least_centre = INFINITY;
    uint32_t open = 0, hidden = 0;
    for (uint32_t v = no; v < nv; v++) {
        const float *x = m->positions + 3 * (size_t)v;
        const double p[3] = {x[0], x[1], x[2]}, n[3] = {m->normals[3 * v], m->normals[3 * v + 1], m->normals[3 * v + 2]};
        const double dx = p[0] - lc[0], dz = p[2] - lc[2];
        if (p[0] > hi[0] + 0.5 && (fabs(dx) > 4.0 || fabs(dz) > 4.0)) {
            const double E = lambert(p, n, P, 4);
            for (int c = 0; c < 3; c++) {
                const double want = m->albedo[3 * v + c] * Le[c] * E / HL_PI;
                worst = fmax(worst, fabs(ex[3 * v + c] - want) / want);
            }
            open++;
        }
        if (fabs(dx) < 0.3 && fabs(dz) < 0.3) {
            for (int c = 0; c < 3; c++) {
                worst_hidden = fmax(worst_hidden, fabs(ex[3 * v + c]));
                least_centre = fmin(least_centre, ce[3 * v + c]);
            }
            hidden++;
        }
    }
    printf("%u ground vertices see the whole lamp, %u none of it\n", open, hidden);
    HL_CHECK(open > 50 && hidden > 0, "too few vertices to test (%u open, %u hidden)", open, hidden);
    hl_check_error("exact against Lambert's formula where nothing hides the lamp (relative)", worst, 2e-3);
    hl_check_error("exact where the panel hides the lamp from the vertex (absolute)", worst_hidden, 0.0);
    printf("centre there (the capture point sees the lamp past the panel): at least %.4g\n", least_centre);
    /* the lamp seen from the capture point, about 0.005 sr at 0.74 of the
       normal there: blue 0.8 x 10 x 0.0037 / pi = 0.0094 */
    HL_CHECK(least_centre > 0.005, "centre: the capture point's view lights the hidden vertices");

    /* the relighter against the references (all terms, N = C = 32) */
    hl_relighter *r = NULL;
    hl_relight_desc d = {.terms = HL_TERMS_ALL, .select = HL_SELECT_DEFAULT};
    HL_CHECK(hl_relighter_create(ref, t, &r) == HL_OK && hl_relighter_set_surroundings(r, sur) == HL_OK &&
                 hl_relighter_run(r, &d, rl, NULL) == HL_OK,
             "relight");
    HL_CHECK(hl_bench_capture_ref(ref, t, sur, HL_CAPTURE_REF_DISCRETE, 0, di, NULL) == HL_OK, "discrete");
    const double e_cd = rel_l2(di, ce, 3 * (size_t)nv), e_dr = rel_l2(rl, di, 3 * (size_t)nv),
                 e_ex = rel_l2(ce, ex, 3 * (size_t)nv);
    printf("relative L2: centre against exact (parallax) %.4f, discrete against centre (N = C = 32) %.4f, relit (all "
           "terms) against discrete %.4f\n", e_ex, e_cd, e_dr);
    /* a lamp 1 across about 11 away is 5 degrees, less than a texel
       (about 7 degrees at N = 32): 8.2% measured */
    hl_check_error("discrete against centre (relative L2; the resolution at N = C = 32)", e_cd, 0.12);
    hl_check_error("relit, all terms, against discrete (relative L2; the transport's codes)", e_dr, 0.03);
    hl_relighter_destroy(r);

    /* the lamp 1000 times as far along the same direction from the capture
       point, 1000 times as large (the same solid angle there), no panel:
       every vertex sees it from nearly the capture point's direction */
    double cpt[3], hd;
    object_box(m, cpt, &hd);
    double fc[3], fu[3] = {500.0, 0, 0}, fv[3] = {0, 0, 500.0};
    for (int a = 0; a < 3; a++) fc[a] = cpt[a] + 1000.0 * (lc[a] - cpt[a]);
    s.n = 0;
    add_quad(&s, fc, fu, fv, Le);
    hl_surroundings_destroy(sur);
    sur = surroundings_of(ref, &s);
    HL_CHECK(sur && hl_bench_capture_ref(ref, t, sur, HL_CAPTURE_REF_EXACT, 32, ex, NULL) == HL_OK &&
                 hl_bench_capture_ref(ref, t, sur, HL_CAPTURE_REF_CENTRE, 32, ce, NULL) == HL_OK,
             "far lamp");
    const double e_far = rel_l2(ce, ex, 3 * (size_t)nv);
    printf("near lamp: centre against exact %.4f\n", e_ex);
    hl_check_error("far lamp: centre against exact (relative L2)", e_far, 0.01);
    HL_CHECK(e_ex > 10.0 * e_far, "the near lamp's parallax (%.4f) well above the far lamp's (%.4f)", e_ex, e_far);
done:
    free(ex);
    free(ce);
    free(di);
    free(rl);
    hl_surroundings_destroy(sur);
    hl_transport_destroy(t);
    hl_context_destroy(ref);
}

/* ============================================================== probes */

/* A square lamp of half side h, radiance Le, 4 above the object's top
 * and 3 beyond its +X side (as case_reference's, with no panel). */
static void near_lamp(soup *s, const hl_mesh *m, double h, double far)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v = 0; v < m->object_vertex_count; v++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], m->positions[3 * v + a]);
            hi[a] = fmax(hi[a], m->positions[3 * v + a]);
        }
    const double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    const double lc0[3] = {hi[0] + 3.0, hi[1] + 4.0, c[2]};
    double lc[3], lu[3] = {far * h, 0, 0}, lv[3] = {0, 0, far * h};
    for (int a = 0; a < 3; a++) lc[a] = c[a] + far * (lc0[a] - c[a]);
    static const float Le[3] = {30.0f, 20.0f, 10.0f};
    s->n = 0;
    add_quad(s, lc, lu, lv, Le);
}

static void case_probes(void)
{
    hl_context *ref = hl_test_ref_context(0);
    hl_transport *t = bunny(ref, 24);
    HL_CHECK(t != NULL, "transport");
    if (!t) { hl_context_destroy(ref); return; }
    const hl_mesh *m = t->mesh;
    const uint32_t nv = m->vertex_count;
    static soup s;
    near_lamp(&s, m, 0.5, 1.0);
    hl_surroundings *sur = surroundings_of(ref, &s);
    float *ex = malloc((size_t)nv * 12), *c1 = malloc((size_t)nv * 12), *cp = malloc((size_t)nv * 12);
    hl_relighter *r = NULL;
    HL_CHECK(sur && ex && c1 && cp && hl_relighter_create(ref, t, &r) == HL_OK &&
                 hl_relighter_set_surroundings(r, sur) == HL_OK,
             "setup");
    if (!sur || !ex || !c1 || !cp || !r) goto done;

    /* the layout: the weights of every vertex sum to 1, at most the
       points asked, one point the object's centre */
    const float *pos = NULL, *em = NULL;
    HL_CHECK(hl_surroundings_triangles(sur, &pos, &em) == HL_OK, "triangles");
    hl_capture_scene cs = {.positions = pos, .emission = em, .triangle_count = hl_surroundings_triangle_count(sur)};
    float centre[3];
    hl_object_centre(m, centre);
    static const uint32_t asks[] = {1, 8, 32};
    double last_bound = INFINITY;
    for (int k = 0; k < 3; k++) {
        hl_probe_set ps;
        HL_CHECK(hl_probe_set_build(ref, m->positions, nv, centre, -1.0, &cs, asks[k], 2.0 / t->info.N, &ps) == HL_OK,
                 "probes");
        double *sum = calloc(nv, sizeof *sum), worst = 0.0;
        for (uint32_t p = 0; ps.start && p < ps.count; p++)
            for (uint32_t e = ps.start[p]; e < ps.start[p + 1]; e++) sum[ps.vert[e]] += ps.weight[e];
        for (uint32_t v = 0; v < nv; v++) worst = fmax(worst, fabs(sum[v] - 1.0));
        printf("%u points asked: %u placed, parallax bound %.3g rad (one point: %.3g), %u weights\n", asks[k],
               ps.count, ps.worst_ratio, ps.single_ratio, ps.start ? ps.start[ps.count] : 0u);
        HL_CHECK(ps.count >= 1 && ps.count <= asks[k], "%u points for %u asked", ps.count, asks[k]);
        HL_CHECK(asks[k] == 1 || ps.count == asks[k], "a near lamp spends the budget (%u of %u)", ps.count, asks[k]);
        if (k == 0) {
            /* one point: the object's centre, the bound alone (no lists) */
            HL_CHECK(!memcmp(ps.points, centre, 12) && !ps.start && ps.worst_ratio == ps.single_ratio,
                     "one point: the object's centre and its bound");
        } else {
            hl_check_error("each vertex's weights sum to 1 (max abs)", worst, 1e-6);
        }
        if (k == 2) HL_CHECK(ps.worst_ratio < last_bound, "32 points bound the parallax below 8 points (%g, %g)",
                             ps.worst_ratio, last_bound);
        last_bound = ps.worst_ratio;
        free(sum);
        hl_probe_set_free(&ps);
    }

    /* a near lamp: the exact reference against one point and 32 */
    hl_relight_desc d = {.terms = HL_TERMS_ALL, .select = HL_SELECT_DEFAULT};
    hl_relight_stats st1, stp;
    double sec = 0.0;
    HL_CHECK(hl_bench_capture_ref(ref, t, sur, HL_CAPTURE_REF_EXACT, 16, ex, &sec) == HL_OK, "exact: %s",
             hl_context_last_error(ref));
    HL_CHECK(hl_relighter_run(r, &d, c1, &st1) == HL_OK, "one point: %s", hl_context_last_error(ref));
    HL_CHECK(hl_relighter_set_probes(r, 32, 0.0) == HL_OK, "set_probes");
    HL_CHECK(hl_relighter_run(r, &d, cp, &stp) == HL_OK, "32 points: %s", hl_context_last_error(ref));
    const double e1 = rel_l2(c1, ex, 3 * (size_t)nv), ep = rel_l2(cp, ex, 3 * (size_t)nv);
    printf("near lamp, relative L2 against exact: one point %.4f (bound %.3g), %u points %.4f (bound %.3g)\n", e1,
           st1.parallax, stp.probes, ep, stp.parallax);
    HL_CHECK(st1.probes == 1 && stp.probes == 32, "points used: %u and %u", st1.probes, stp.probes);
    /* the one point's error is nearly all parallax (case_reference), and
       32 points divide the bound by more than 4 */
    HL_CHECK(ep < 0.5 * e1, "32 points: %.4f not below half of one point's %.4f", ep, e1);
    for (size_t i = 0; i < 3 * (size_t)nv; i++)
        if (!(cp[i] >= 0.0f && isfinite(cp[i]))) {
            HL_CHECK(0, "blended colour %zu is %g", i, (double)cp[i]);
            break;
        }

    /* the same lamp 1000 times as far and as large: one point is enough,
       and it is the relighter's own (the same bytes as without probes) */
    hl_surroundings_destroy(sur);
    near_lamp(&s, m, 0.5, 1000.0);
    sur = surroundings_of(ref, &s);
    HL_CHECK(sur && hl_relighter_set_surroundings(r, sur) == HL_OK, "far lamp");
    HL_CHECK(hl_relighter_set_probes(r, 1, 0.0) == HL_OK && hl_relighter_run(r, &d, c1, &st1) == HL_OK, "far, 1");
    HL_CHECK(hl_relighter_set_probes(r, 32, 0.0) == HL_OK && hl_relighter_run(r, &d, cp, &stp) == HL_OK, "far, 32");
    printf("far lamp: %u point(s) of 32, bound %.3g rad (tolerance 2 / N = %.3g)\n", stp.probes, stp.parallax,
           2.0 / t->info.N);
    HL_CHECK(stp.probes == 1, "a far lamp took %u points", stp.probes);
    hl_check_error("far lamp, 32 asked: against no probes (max abs)", hl_test_rel_diff(c1, cp, 3 * (size_t)nv), 0.0);

    /* bad counts and tolerances */
    HL_CHECK(hl_relighter_set_probes(r, 0, 0.0) == HL_ERR_INVALID_ARGUMENT, "0 points");
    HL_CHECK(hl_relighter_set_probes(r, HL_PROBES_MAX + 1, 0.0) == HL_ERR_INVALID_ARGUMENT, "257 points");
    HL_CHECK(strstr(hl_context_last_error(ref), "1 to 256") != NULL, "the range named: %s", hl_context_last_error(ref));
    HL_CHECK(hl_relighter_set_probes(r, 8, NAN) == HL_ERR_INVALID_ARGUMENT, "NaN tolerance");
    HL_CHECK(hl_relighter_set_probes(r, 8, -1.0) == HL_ERR_INVALID_ARGUMENT, "negative tolerance");

    /* OpenCL against the reference with 8 points, and the colours into
       a device buffer equal to those read back */
    hl_context *cl = hl_test_cl_context(0);
    HL_CHECK(cl != NULL, "an OpenCL device is needed");
    hl_transport *tc = cl ? bunny(cl, 24) : NULL;
    hl_relighter *rc = NULL;
    hl_surroundings *sc = NULL;
    near_lamp(&s, m, 0.5, 1.0);
    hl_surroundings_destroy(sur);
    sur = surroundings_of(ref, &s);
    if (cl && tc) sc = surroundings_of(cl, &s);
    HL_CHECK(sc && sur && hl_relighter_create(cl, tc, &rc) == HL_OK && hl_relighter_set_surroundings(rc, sc) == HL_OK &&
                 hl_relighter_set_probes(rc, 8, 0.0) == HL_OK && hl_relighter_set_surroundings(r, sur) == HL_OK &&
                 hl_relighter_set_probes(r, 8, 0.0) == HL_OK,
             "OpenCL relighter");
    if (rc) {
        hl_relight_desc d2 = {.terms = 200};
        HL_CHECK(hl_relighter_run(r, &d2, c1, NULL) == HL_OK && hl_relighter_run(rc, &d2, cp, &stp) == HL_OK, "runs");
        HL_CHECK(stp.probes == 8, "8 points: %u", stp.probes);
        hl_check_error("8 points, M = 200: OpenCL vs reference colours (relative to max)",
                       hl_test_rel_diff(c1, cp, 3 * (size_t)nv), 1e-4);
        void *buf = NULL;
        float *b4 = malloc((size_t)nv * 16);
        HL_CHECK(b4 && hl_cl_buffer(cl, (size_t)nv * 16, &buf) == HL_OK, "buffer");
        HL_CHECK(buf && hl_relighter_run_into(rc, &d2, buf, 0, NULL) == HL_OK &&
                     hl_cl_buffer_read(cl, buf, (size_t)nv * 16, b4) == HL_OK,
                 "into a buffer: %s", hl_context_last_error(cl));
        size_t diff = 0;
        for (uint32_t v = 0; v < nv && b4; v++) diff += memcmp(b4 + 4 * (size_t)v, cp + 3 * (size_t)v, 12) != 0;
        printf("colours into a device buffer: %zu of %u vertices differ from those read back\n", diff, nv);
        HL_CHECK(diff == 0, "the device buffer's colours");
        if (buf) hl_cl_buffer_release(cl, buf);
        free(b4);
    }
    hl_relighter_destroy(rc);
    hl_surroundings_destroy(sc);
    hl_transport_destroy(tc);
    hl_context_destroy(cl);
done:
    free(ex);
    free(c1);
    free(cp);
    hl_relighter_destroy(r);
    hl_surroundings_destroy(sur);
    hl_transport_destroy(t);
    hl_context_destroy(ref);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"twin", case_twin},         {"reuse", case_reuse}, {"crosscheck", case_crosscheck},
                                         {"motion", case_motion},     {"bad", case_bad},     {"reference", case_reference},
                                         {"probes", case_probes},     {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
