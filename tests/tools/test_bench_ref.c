/* test_bench_ref.c - the bounced exact reference of `haarlight bench`
 * (hl_bench_ref_bounced, host/src/tools/bench_refs.c), suite "bench_ref".
 *
 * bench_ref.cavity    a unit sphere seen from inside (normals inward) with
 *                     a round opening of form factor f, albedo
 *                     (0.9, 0.5, 0.2), under a uniform white map, B = 3,
 *                     every vertex measured. From a point on a sphere,
 *                     cosine-weighted rays land uniformly over the sphere's
 *                     area, a fraction 1 - f of them on the wall, so with
 *                     A_0 the area mean of the direct light E_0 over the
 *                     wall, every vertex has
 *                       E_B - E_0 = A_0 sum_(k=1..B) q_c^k,  q_c = rho_c (1 - f)
 *                     per channel (E_0 = L f everywhere gives the closed
 *                     form rho L f sum_(k=0..B) q^k; taking A_0 from the
 *                     reference's own E_0 leaves the direct grid's error
 *                     out). Checked per vertex and in the mean, with
 *                     tolerances derived from the rays (below); bounce 0
 *                     is the direct exact reference bit for bit; the
 *                     reported noise covers the errors seen.
 * bench_ref.mismatch  the reference detects a wrong bounce count: a grey
 *                     cavity baked with 2 bounces and relit with every term
 *                     lies far closer to the 2-bounce reference than to
 *                     the direct one, and the direct file far from the
 *                     2-bounce reference.
 *
 * Depends on: haarlight_core (the reference backend only).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cavity_mesh.h"
#include "haarlight_tools.h"
#include "hl_test.h"

#define PI 3.14159265358979323846

/* The sphere's rings and segments (cavity_mesh.h): within 0.1% of the
 * sphere's area. */
#define RINGS HL_CAVITY_RINGS
#define SEGS HL_CAVITY_SEGS
#define NV HL_CAVITY_VERTICES
#define KREF 1024u
#define BMAX 3u

/* The cavity of cavity_mesh.h, albedo rho. */
static hl_mesh *cavity(hl_context *ctx, double theta0, const float rho[3]) { return hl_test_cavity(ctx, theta0, rho); }

/* A uniform map of radiance 1. */
static hl_env *white_env(hl_context *ctx)
{
    float *w = malloc(64 * 32 * 12);
    hl_env *env = NULL;
    if (!w) return NULL;
    for (int i = 0; i < 64 * 32 * 3; i++) w[i] = 1.0f;
    if (hl_env_create(ctx, 64, 32, w, &env, NULL) != HL_OK) env = NULL;
    free(w);
    return env;
}

/* m baked with B bounces (K = 64, every term read) into path and loaded. */
static hl_transport *bake(hl_context *ctx, const hl_mesh *m, uint32_t B, const char *path)
{
    hl_precompute_desc d = {.N = 32, .C = 32, .bounces = B, .bounce_terms = HL_TERMS_ALL};
    hl_transport *t = NULL;
    if (hl_precompute(ctx, m, &d, path, NULL) != HL_OK || hl_transport_load(ctx, path, &t) != HL_OK) {
        fprintf(stderr, "bake: %s\n", hl_context_last_error(ctx));
        return NULL;
    }
    return t;
}

/* Each vertex's share of the mesh's area: a third of its triangles'. */
static void vertex_areas(const hl_mesh *m, double *A)
{
    memset(A, 0, (size_t)m->vertex_count * sizeof *A);
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *c = m->indices + 3 * (size_t)t;
        const float *p0 = m->positions + 3 * (size_t)c[0], *p1 = m->positions + 3 * (size_t)c[1],
                    *p2 = m->positions + 3 * (size_t)c[2];
        double e1[3], e2[3];
        for (int k = 0; k < 3; k++) e1[k] = p1[k] - p0[k], e2[k] = p2[k] - p0[k];
        const double x = e1[1] * e2[2] - e1[2] * e2[1], y = e1[2] * e2[0] - e1[0] * e2[2], z = e1[0] * e2[1] - e1[1] * e2[0];
        const double a = 0.5 * sqrt(x * x + y * y + z * z) / 3.0;
        for (int k = 0; k < 3; k++) A[c[k]] += a;
    }
}

static void case_cavity(void)
{
    hl_context *ctx = hl_test_ref_context(0);
    const double f = 0.1, theta0 = acos(1.0 - 2.0 * f); /* cap area 2 pi (1 - cos) = 4 pi f */
    const float rho[3] = {0.9f, 0.5f, 0.2f};
    hl_mesh *m = cavity(ctx, theta0, rho);
    hl_transport *t = m ? bake(ctx, m, 0, hl_test_tmp_path("bench_ref_cavity.hlt")) : NULL;
    hl_env *env = white_env(ctx);
    hl_bench_ref *br = NULL;
    HL_CHECK(t && env && hl_bench_ref_create(ctx, t, &br) == HL_OK, "setup: %s", hl_context_last_error(ctx));
    if (!br) goto done;
    uint32_t *idx = malloc(NV * 4);
    double *ex[BMAX + 1], *direct = malloc(NV * 24), cont_dummy[3], own[BMAX + 1], bound[BMAX + 1];
    double *A = malloc(NV * sizeof(double));
    for (uint32_t v = 0; v < NV; v++) idx[v] = v;
    for (uint32_t b = 0; b <= BMAX; b++) ex[b] = malloc(NV * 24);
    const hl_env *envs[1] = {env};
    double *dp[1] = {direct}, *cp[1] = {cont_dummy};
    HL_CHECK(hl_bench_ref_colours(br, idx, NV, NULL, 0, envs, 1, dp, cp) == HL_OK, "direct: %s", hl_context_last_error(ctx));
    const double t0 = hl_tools_now();
    hl_result r = hl_bench_ref_bounced(br, idx, NV, BMAX, KREF, envs, 1, 0, ex, own, bound);
    HL_CHECK(r == HL_OK, "bounced: %s", hl_context_last_error(ctx));
    printf("the bounced reference: %u vertices, %u bounces, %u rays: %.2f s\n", NV, BMAX, KREF, hl_tools_now() - t0);
    if (r != HL_OK) goto free_all;
    /* bounce 0 is the direct exact reference: the same rows and sums */
    size_t differ = 0;
    for (size_t i = 0; i < (size_t)NV * 3; i++) differ += ex[0][i] != direct[i];
    printf("bounce 0 against the direct exact reference: %zu of %u values differ\n", differ, NV * 3);
    HL_CHECK(differ == 0, "bounce 0 is not the direct exact reference");
    vertex_areas(m, A);
    double A0[3] = {0, 0, 0}, Asum = 0.0, sp0 = 0.0;
    for (uint32_t v = 0; v < NV; v++) {
        Asum += A[v];
        for (int c = 0; c < 3; c++) A0[c] += A[v] * ex[0][3 * v + c] / rho[c];
    }
    for (int c = 0; c < 3; c++) A0[c] /= Asum;
    for (uint32_t v = 0; v < NV; v++) {
        const double d = ex[0][3 * v + 1] / rho[1] / A0[1] - 1.0;
        sp0 += A[v] * d * d;
    }
    sp0 = sqrt(sp0 / Asum); /* the relative spread of E_0 over the wall's area */
    printf("E_0 over the wall: area mean %.5f (L f = %.5f), relative spread %.3f\n", A0[1], f, sp0);
    /* The tolerances, per channel and bounce count B, from the rays alone:
     *  - a bounce-b gather at a vertex averages KREF samples rho F_(b-1)(y),
     *    0 for the fraction f that escapes: with F_(b-1) spread by sp_(b-1)
     *    over the wall, the samples' variance is at most
     *    (rho A_(b-1))^2 (p (1 + sp^2) - p^2), p = 1 - f, A_(b-1) = A_0 q^(b-1),
     *    and the mean's that over KREF (independent rays: stratified ones
     *    have less); sp_0 as measured, then sp_b = sp_0 + 4 se_b / A_b (the
     *    structure of E_0 carried on, and the gather's noise);
     *  - each gather also reads the noise of the one before, at most
     *    rho p sd_(b-1) (Minkowski, no cancellation assumed), and the
     *    bounces' own noises add in quadrature (fresh rays each bounce);
     *  - per vertex 4.5 standard deviations (of 3 x 1153 normal draws one
     *    lies beyond 4.5 with probability 0.02; and the iid bound already
     *    exceeds the stratified rays' spread); for the mean over the NV
     *    vertices the same over sqrt(NV), as each vertex has its own rays;
     *  - geometry: the opening is a 48-gon inscribed in the circle,
     *    (48 / 2 pi) sin(2 pi / 48) = 0.99715 of its area, so f is 0.3%
     *    smaller; the facets lie within 0.1% of the sphere's area; and at
     *    a vertex the facets rise above the sphere's tangent plane by half
     *    the angle between neighbouring vertices, a = max(ring step,
     *    segment step) / 2, so the rays within a of the horizon leave
     *    through a facet from behind and add nothing (the precompute's rule
     *    too), a fraction sin^2 a of cosine-weighted rays (0.43% here; at
     *    48 x 96 the mean's deficit falls from 0.43% to 0.10%, as a^2): the
     *    fraction p that stays inside is off by at most
     *    d = 0.00285 f + 0.001 + sin^2 a, each q^k by k d / p relative. */
    const double a = 0.5 * fmax((PI - theta0) / RINGS, 2.0 * PI / SEGS);
    const double p = 1.0 - f, d = 0.00285 * f + 0.001 + sin(a) * sin(a);
    for (uint32_t B = 1; B <= BMAX; B++)
        for (int c = 0; c < 3; c++) {
            const double q = rho[c] * p;
            double want = 0.0, geo = 0.0, own2 = 0.0, up = 0.0, sd_prev = 0.0, sp = sp0;
            for (uint32_t k = 1; k <= B; k++) {
                const double Ak = A0[c] * pow(q, k - 1);
                want += A0[c] * pow(q, k);
                geo += A0[c] * pow(q, k) * k * d / p;
                const double se = rho[c] * Ak * sqrt(fmax(0.0, p * (1.0 + sp * sp) - p * p) / KREF);
                const double upk = rho[c] * p * sd_prev;
                own2 += se * se;
                up += upk;
                sd_prev = sqrt(se * se + upk * upk);
                sp = sp0 + 4.0 * se / (A0[c] * pow(q, k));
            }
            const double sd = sqrt(own2) + up, tol_v = 4.5 * sd + geo, tol_m = 4.5 * sd / sqrt((double)NV) + geo;
            double worst = 0.0, mean = 0.0;
            for (uint32_t v = 0; v < NV; v++) {
                const double ind = (ex[B][3 * v + c] - ex[0][3 * v + c]) / rho[c];
                worst = fmax(worst, fabs(ind - want));
                mean += ind / NV;
            }
            char what[200];
            snprintf(what, sizeof what,
                     "B = %u, channel %d (rho %.1f): E_B - E_0 = %.5f expected, each vertex (absolute)", B, c,
                     (double)rho[c], want);
            hl_check_error(what, worst, tol_v);
            snprintf(what, sizeof what, "B = %u, channel %d: the mean over the vertices %.5f (absolute)", B, c, mean);
            hl_check_error(what, fabs(mean - want), tol_m);
        }
    /* the noise it reports covers the errors' scatter: the relative L2 of
       each value's error less its channel's mean error (the geometry's
       part above is the same at every vertex to within its own small
       variation, and the mean is checked above), over the 3 NV values,
       within 1.5 times the reported bound (an rms of so many draws lies
       within a few percent of the deviation it estimates, and each
       vertex's deviation is estimated from 1024 rays, to about
       sqrt(2 / 1024) = 4%); and the noise is more than nothing */
    for (uint32_t B = 1; B <= BMAX; B++) {
        double se = 0.0, sr = 0.0, me[3] = {0, 0, 0};
        for (int pass = 0; pass < 2; pass++)
            for (uint32_t v = 0; v < NV; v++)
                for (int c = 0; c < 3; c++) {
                    double want = 0.0;
                    for (uint32_t k = 1; k <= B; k++) want += A0[c] * pow(rho[c] * p, k);
                    const double e = ex[B][3 * v + c] - ex[0][3 * v + c] - rho[c] * want;
                    if (pass == 0) {
                        me[c] += e / NV;
                        continue;
                    }
                    se += (e - me[c]) * (e - me[c]);
                    sr += ex[B][3 * v + c] * ex[B][3 * v + c];
                }
        const double l2 = sqrt(se / sr);
        char what[200];
        snprintf(what, sizeof what, "B = %u: relative L2 of the reference's scatter (own noise %.4f%%, bound %.4f%%)", B,
                 100 * own[B], 100 * bound[B]);
        hl_check_error(what, l2, 1.5 * bound[B]);
        HL_CHECK(own[B] > 0.0 && bound[B] >= own[B], "B = %u: noise %g, bound %g", B, own[B], bound[B]);
    }
free_all:
    for (uint32_t b = 0; b <= BMAX; b++) free(ex[b]);
    free(direct);
    free(idx);
    free(A);
done:
    hl_bench_ref_destroy(br);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* Relative L2 of rgb (every vertex) against ref. */
static double rel_l2(const float *rgb, const double *ref)
{
    double se = 0.0, sr = 0.0;
    for (uint32_t i = 0; i < NV * 3; i++) {
        se += (rgb[i] - ref[i]) * (rgb[i] - ref[i]);
        sr += ref[i] * ref[i];
    }
    return sqrt(se / sr);
}

static void case_mismatch(void)
{
    hl_context *ctx = hl_test_ref_context(0);
    const float rho[3] = {0.5f, 0.5f, 0.5f};
    hl_mesh *m = cavity(ctx, acos(1.0 - 2.0 * 0.1), rho);
    hl_transport *t0 = m ? bake(ctx, m, 0, hl_test_tmp_path("bench_ref_b0.hlt")) : NULL;
    hl_transport *t2 = m ? bake(ctx, m, 2, hl_test_tmp_path("bench_ref_b2.hlt")) : NULL;
    hl_env *env = white_env(ctx);
    hl_bench_ref *br = NULL;
    HL_CHECK(t0 && t2 && env && hl_bench_ref_create(ctx, t2, &br) == HL_OK, "setup: %s", hl_context_last_error(ctx));
    uint32_t *idx = malloc(NV * 4);
    double *ex[3];
    float *rgb0 = malloc(NV * 12), *rgb2 = malloc(NV * 12);
    for (uint32_t v = 0; v < NV; v++) idx[v] = v;
    for (int b = 0; b < 3; b++) ex[b] = malloc(NV * 24);
    const hl_env *envs[1] = {env};
    hl_relight_desc rd = {.terms = HL_TERMS_ALL};
    int ok = br && hl_bench_ref_bounced(br, idx, NV, 2, 256, envs, 1, 0, ex, NULL, NULL) == HL_OK;
    for (int k = 0; k < 2 && ok; k++) {
        hl_relighter *rl = NULL;
        ok = hl_relighter_create(ctx, k ? t2 : t0, &rl) == HL_OK && hl_relighter_set_env(rl, env) == HL_OK &&
             hl_relighter_run(rl, &rd, k ? rgb2 : rgb0, NULL) == HL_OK;
        hl_relighter_destroy(rl);
    }
    HL_CHECK(ok, "reference or relight: %s", hl_context_last_error(ctx));
    if (ok) {
        const double e22 = rel_l2(rgb2, ex[2]), e20 = rel_l2(rgb2, ex[0]), e02 = rel_l2(rgb0, ex[2]),
                     e00 = rel_l2(rgb0, ex[0]);
        printf("relative L2: the 2-bounce file against the 2-bounce reference %.3f%%, against the direct one %.3f%%; "
               "the direct file against the direct reference %.3f%%, against the 2-bounce one %.3f%%\n",
               100 * e22, 100 * e20, 100 * e00, 100 * e02);
        /* the bounces add (rho (1 - f)) + (rho (1 - f))^2 = 0.65 of the
           direct light, a third of the total: a reference that ignored
           them, or counted one too few (0.2 of the direct, 12% of the
           total), would put the file near the direct reference instead.
           A quarter of the gap leaves the file's own sampling (64 rays)
           and 8-bit codes room */
        hl_check_error("the 2-bounce file against its reference, over the same against the direct reference", e22 / e20,
                       0.25);
        hl_check_error("the direct file against its reference, over the same against the 2-bounce reference", e00 / e02,
                       0.25);
    }
    for (int b = 0; b < 3; b++) free(ex[b]);
    free(idx);
    free(rgb0);
    free(rgb2);
    hl_bench_ref_destroy(br);
    hl_env_destroy(env);
    hl_transport_destroy(t0);
    hl_transport_destroy(t2);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"cavity", case_cavity}, {"mismatch", case_mismatch}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
