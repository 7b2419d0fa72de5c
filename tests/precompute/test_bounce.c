/* test_bounce.c - diffuse interreflection baked into the transport
 * (precompute --bounces, host/src/precompute/bounce.c), suite "bounce".
 *
 * bounce.cavity   a sphere of radius 1 seen from inside (normals inward)
 *                 with a round opening of form factor f: under a uniform
 *                 map of radiance L every inner point has
 *                 B_B = rho L f sum_(k=0..B) (rho (1 - f))^k,
 *                 for B = 0, 1, 2, 8 and rho = 0.5, 0.9 (tolerances
 *                 derived below, printed with the errors).
 * bounce.furnace  the same with albedo 1 and a wider opening: the mean
 *                 rises towards L with every bounce, every vertex with it.
 * bounce.twin     the OpenCL gather against its plain-C twin: the two
 *                 bounced files byte for byte (the same rays, the
 *                 kernel's sums bit for bit the twin's), with the rows'
 *                 16-bit slots and with the 32-bit ones forced
 *                 (HL_TEST_BOUNCE_WIDE), which give the same bytes too;
 *                 no direct rows' file and no scratch file of the next
 *                 rows left behind.
 * bounce.half     the gather's rows' binary16 values (hl_bounce_encode):
 *                 each value the nearest normal binary16 times its row's
 *                 scale (ties to even), within 2^-11 of itself down to
 *                 2^-28 of the row's largest, those below the least
 *                 normal binary16 zero; a row below 2^-100 all zeros;
 *                 the decoding (hl_half_to_float) exact on every normal
 *                 binary16 against a decoding of its fields.
 * bounce.colour   a coloured albedo: a row a channel; each channel's rows
 *                 byte for byte those of a grey bake with that channel's
 *                 albedo, and relit the same bit for bit (both backends);
 *                 the OpenCL and reference files byte for byte.
 * bounce.shards   the bounces sharded as a second phase from a direct
 *                 file that was itself sharded with --keep-floats and
 *                 merged (its floats with it): the bytes of one run
 *                 (B = 1 and 2, three coloured planes); bad direct files
 *                 refused.
 * bounce.floats   the direct rows' floats between the phases: on a flat
 *                 grid, whose bounces are exactly zero (every ray
 *                 leaves), the bounced rows are the direct file's byte
 *                 for byte; from the 8-bit codes alone (no values file)
 *                 they are not. Bad values files (truncated, damaged, of
 *                 other rows) and a direct file damaged in its entries
 *                 refused, naming the file.
 * bounce.bad      an albedo above 1, too many bounces, --bounces with a
 *                 shard but no direct rows: clear errors, no file.
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL).
 */
#define _POSIX_C_SOURCE 200809L /* strdup */
#include <glob.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "bounce.h"
#include "cavity_mesh.h"
#include "haarlight_tools.h"
#include "hl_test.h"
#include "precompute.h"

#define RINGS HL_CAVITY_RINGS
#define SEGS HL_CAVITY_SEGS
#define RAYS 64u

/* The cavity (cavity_mesh.h) with a grey albedo rho. */
static hl_mesh *cavity(hl_context *ctx, double theta0, float rho)
{
    const float g[3] = {rho, rho, rho};
    return hl_test_cavity(ctx, theta0, g);
}

/* How many bytes files pa and pb differ in (SIZE_MAX when either is
 * unreadable or their sizes differ); their sizes into *na, *nb. */
static size_t bytes_differ(const char *pa, const char *pb, size_t *na, size_t *nb)
{
    uint8_t *a = hl_test_read_file(pa, na), *b = hl_test_read_file(pb, nb);
    size_t diff = a && b && *na == *nb ? 0 : SIZE_MAX;
    for (size_t i = 0; diff != SIZE_MAX && i < *na; i++) diff += a[i] != b[i];
    free(a);
    free(b);
    return diff;
}

/* The transport of m with B bounces at path, its colours under a uniform
 * white map of radiance 1 (all terms) into rgb (3 a vertex). */
static int bake_and_relight(hl_context *ctx, const hl_mesh *m, uint32_t B, uint32_t terms, const char *path, float *rgb)
{
    hl_precompute_desc d = {.N = 32, .C = 32, .bounces = B, .bounce_rays = RAYS, .bounce_terms = terms};
    if (hl_precompute(ctx, m, &d, path, NULL) != HL_OK) {
        fprintf(stderr, "precompute: %s\n", hl_context_last_error(ctx));
        return 0;
    }
    hl_transport *t = NULL;
    hl_relighter *r = NULL;
    hl_env *env = NULL;
    float *white = malloc(64 * 32 * 12);
    for (int i = 0; i < 64 * 32 * 3; i++) white[i] = 1.0f;
    hl_relight_desc rd = {.terms = HL_TERMS_ALL};
    int ok = hl_transport_load(ctx, path, &t) == HL_OK && t->info.bounces == B &&
             hl_env_create(ctx, 64, 32, white, &env, NULL) == HL_OK && hl_relighter_create(ctx, t, &r) == HL_OK &&
             hl_relighter_set_env(r, env) == HL_OK && hl_relighter_run(r, &rd, rgb, NULL) == HL_OK;
    if (!ok) fprintf(stderr, "relight: %s\n", hl_context_last_error(ctx));
    free(white);
    hl_relighter_destroy(r);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    return ok;
}

/* Mean and relative spread (standard deviation over mean) of the inner
 * vertices' green channel: rings 2 and on (the rim's two rings see the
 * opening's polygon edge at a grazing angle). */
static void inner_stats(const float *rgb, double *mean, double *spread)
{
    double s = 0.0, s2 = 0.0;
    uint32_t n = 0;
    for (uint32_t v = 2 * SEGS; v < RINGS * SEGS + 1; v++, n++) {
        s += rgb[3 * v + 1];
        s2 += (double)rgb[3 * v + 1] * rgb[3 * v + 1];
    }
    *mean = s / n;
    *spread = sqrt(fmax(0.0, s2 / n - *mean * *mean)) / *mean;
}

static double series(double q, uint32_t B)
{
    double s = 0.0, p = 1.0;
    for (uint32_t k = 0; k <= B; k++, p *= q) s += p;
    return s;
}

static double series_slope(double q, uint32_t B)
{
    double s = 0.0, p = 1.0;
    for (uint32_t k = 1; k <= B; k++, p *= q) s += k * p;
    return s;
}

static void case_cavity(void)
{
    hl_context *ctx = hl_test_ref_context(0);
    const double f = 0.1, theta0 = acos(1.0 - 2.0 * f); /* cap area 2 pi (1 - cos) = 4 pi f */
    static const float rhos[2] = {0.5f, 0.9f};
    static const uint32_t Bs[4] = {0, 1, 2, 8};
    const uint32_t nv = RINGS * SEGS + 1, ninner = nv - 2 * SEGS;
    float *rgb = malloc((size_t)nv * 12);
    for (int ri = 0; ri < 2; ri++) {
        const double rho = rhos[ri];
        hl_mesh *m = cavity(ctx, theta0, rhos[ri]);
        HL_CHECK(m != NULL, "the cavity mesh");
        if (!m) continue;
        double m0 = 0.0, sp0 = 0.0;
        for (int bi = 0; bi < 4; bi++) {
            const uint32_t B = Bs[bi];
            char path[64];
            snprintf(path, sizeof path, "cavity_%d_%u.hlt", ri, B);
            if (!bake_and_relight(ctx, m, B, HL_TERMS_ALL, hl_test_tmp_path(path), rgb)) {
                HL_CHECK(0, "bake rho %.1f B %u", rho, B);
                continue;
            }
            double mean, spread;
            inner_stats(rgb, &mean, &spread);
            const double want = rho * f * series(rho * (1.0 - f), B);
            printf("rho %.1f, B = %u: inner mean %.5f, exact %.5f (spread %.3f%%)\n", rho, B, mean, want,
                   100.0 * spread);
            if (B == 0) {
                /* the direct rows: the opening's edge falls across
                   texels of 2 pi / (4 N) radians at the paraboloid's rim,
                   about 5.6 degrees at N = 32; an edge of length l
                   (radians) through texels of width w misplaces at most
                   half a texel's strip, l w / 2, of the opening's solid
                   angle Omega: the opening, 2 theta0 = 73.7 degrees
                   across from its far side, l = pi 2 theta0 / 2 (a
                   circle's half seen edge-on and half face-on), so
                   l w / (2 Omega) with Omega = 4 pi f / 2 (the opening as
                   a disc seen from the far side) is 4.8%; the polygon's
                   48 sides add 0.3% */
                hl_check_error("B = 0: inner mean against rho L f (relative)", fabs(mean - want) / want, 0.051);
                m0 = mean, sp0 = spread;
                continue;
            }
            /* the bounces against the direct light of the same file
               (its own error cancels): B_B / B_0 = S(q), q = rho (1 - f'),
               f' = B_0 / (rho L) the form factor as the direct rows have
               it. The error of the ratio: the fraction of each vertex's
               RAYS rays that stay inside, a binomial of standard
               deviation sqrt(f (1 - f) / RAYS) per vertex and that over
               sqrt(ninner) for the mean, 4 of those; times
               rho S'(q) / S(q) for the series; plus the spread of B_0
               over the vertices the rays hit (a mean over other points
               than the inner vertices' mean), the share (S - 1) / S of
               B_B that the bounces make; plus the final rows' 8-bit
               codes, whose dither averages out in the mean but whose
               magnitude step (1 / 127 of the largest term) we allow once */
            const double fm = m0 / rho, q = rho * (1.0 - fm), S = series(q, B);
            const double sampling = 4.0 * sqrt(fm * (1.0 - fm) / RAYS / ninner) * rho * series_slope(q, B) / S;
            const double tol = sampling + sp0 * (S - 1.0) / S + 1.0 / 127.0;
            char what[160];
            snprintf(what, sizeof what, "rho %.1f, B = %u: B_B / B_0 against the series (relative)", rho, B);
            hl_check_error(what, fabs(mean / m0 - S) / S, tol);
        }
        hl_mesh_destroy(m);
    }
    free(rgb);
    hl_context_destroy(ctx);
}

static void case_furnace(void)
{
    hl_context *ctx = hl_test_ref_context(0);
    const double f = 0.3, theta0 = acos(1.0 - 2.0 * f);
    hl_mesh *m = cavity(ctx, theta0, 1.0f);
    const uint32_t nv = RINGS * SEGS + 1;
    static const uint32_t Bs[4] = {0, 1, 4, 12};
    float *prev = malloc((size_t)nv * 12), *rgb = malloc((size_t)nv * 12);
    double last = 0.0, worst_drop = 0.0;
    for (int bi = 0; m && bi < 4; bi++) {
        char path[64];
        snprintf(path, sizeof path, "furnace_%u.hlt", Bs[bi]);
        if (!bake_and_relight(ctx, m, Bs[bi], 0, hl_test_tmp_path(path), rgb)) {
            HL_CHECK(0, "bake B %u", Bs[bi]);
            break;
        }
        double mean, spread;
        inner_stats(rgb, &mean, &spread);
        printf("albedo 1, B = %2u: inner mean %.4f (L = 1; the series %.4f)\n", Bs[bi], mean,
               f * series(1.0 - f, Bs[bi]));
        HL_CHECK(mean > last, "B = %u: the mean %.5f did not rise from %.5f", Bs[bi], mean, last);
        HL_CHECK(mean <= 1.0 + 1.0 / 127.0, "B = %u: the mean %.5f passes L", Bs[bi], mean);
        for (uint32_t v = 0; bi > 0 && v < nv; v++) worst_drop = fmax(worst_drop, prev[3 * v + 1] - rgb[3 * v + 1]);
        last = mean;
        memcpy(prev, rgb, (size_t)nv * 12);
    }
    /* each file's own 8-bit codes: a vertex may read up to a step of its
       row's largest term (1 / 127 of a value below 1) under the last */
    hl_check_error("no vertex falls from one bounce count to the next (absolute)", worst_drop, 1.0 / 127.0);
    HL_CHECK(last > 0.95, "12 bounces of albedo 1 reach %.4f of L (the series: %.4f)", last, f * series(0.7, 12));
    free(prev);
    free(rgb);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void case_twin(void)
{
    hl_context *ref = hl_test_ref_context(0), *cl = hl_test_cl_context(0);
    HL_CHECK(cl != NULL, "an OpenCL device is needed");
    if (!cl) { hl_context_destroy(ref); return; }
    hl_mesh *m = cavity(ref, acos(1.0 - 2.0 * 0.2), 0.7f);
    char *p[2][2]; /* [wide][OpenCL] */
    hl_precompute_desc d = {.N = 16, .C = 16, .bounces = 2, .bounce_rays = 16};
    for (int wide = 0; wide < 2; wide++) {
        setenv("HL_TEST_BOUNCE_WIDE", wide ? "1" : "0", 1);
        for (int c = 0; c < 2; c++) {
            char name[64];
            snprintf(name, sizeof name, "bounce_%s%s.hlt", c ? "cl" : "ref", wide ? "_wide" : "");
            p[wide][c] = strdup(hl_test_tmp_path(name));
            hl_context *x = c ? cl : ref;
            HL_CHECK(m && hl_precompute(x, m, &d, p[wide][c], NULL) == HL_OK, "%s: %s", name, hl_context_last_error(x));
        }
        size_t na = 0, nb = 0, diff = bytes_differ(p[wide][0], p[wide][1], &na, &nb);
        printf("%s slots: bounced files of %zu and %zu bytes, %zu bytes differ\n", wide ? "32-bit" : "16-bit", na, nb,
               diff);
        HL_CHECK(diff == 0, "the OpenCL and reference bounced files differ (%s slots)", wide ? "32-bit" : "16-bit");
    }
    unsetenv("HL_TEST_BOUNCE_WIDE");
    size_t na = 0, nb = 0, diff = bytes_differ(p[0][1], p[1][1], &na, &nb);
    printf("16-bit against 32-bit slots: %zu bytes differ\n", diff);
    HL_CHECK(diff == 0, "the slots' width changed the bounced file");
    char direct[1200];
    snprintf(direct, sizeof direct, "%s.direct.hlt", p[0][0]);
    HL_CHECK(access(direct, F_OK) != 0, "the direct rows' file %s was left behind", direct);
    /* the next rows' scratch file (B = 2 spills them) is gone too */
    char pat[1200];
    const char *slash = strrchr(p[0][0], '/');
    snprintf(pat, sizeof pat, "%.*s.haarlight-bounce-*", slash ? (int)(slash - p[0][0]) + 1 : 0, p[0][0]);
    glob_t gl;
    const int found = glob(pat, 0, NULL, &gl) == 0 ? (int)gl.gl_pathc : 0;
    if (found) globfree(&gl);
    HL_CHECK(found == 0, "%d scratch files %s left behind", found, pat);
    for (int i = 0; i < 4; i++) free(p[i / 2][i % 2]);
    hl_mesh_destroy(m);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* The rows of plane c of a (3 planes, each of b's vertex count) against
 * the one plane of b: how many rows differ in parameters, counts or
 * entries. */
static uint32_t plane_differs(const hl_transport *a, uint32_t c, const hl_transport *b)
{
    const uint32_t V = b->info.vertex_count, nb = b->info.block_count;
    uint32_t bad = 0;
    for (uint32_t v = 0; v < V; v++) {
        const uint32_t ra = c * V + v;
        const uint64_t na = a->row_offset[ra + 1] - a->row_offset[ra], nbv = b->row_offset[v + 1] - b->row_offset[v];
        bad += na != nbv || memcmp(&a->row_quant[ra], &b->row_quant[v], sizeof b->row_quant[v]) ||
               memcmp(a->block_counts + (size_t)ra * nb, b->block_counts + (size_t)v * nb, (size_t)nb * 2) ||
               memcmp(a->entries + 2 * a->row_offset[ra], b->entries + 2 * b->row_offset[v], 2 * (size_t)na);
    }
    return bad;
}

/* A map with colour and direction in it: a bright warm patch, a blue
 * gradient, a dim floor. */
static hl_env *coloured_map(hl_context *ctx)
{
    const uint32_t W = 64, H = 32;
    float *px = malloc((size_t)W * H * 12);
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            float *q = px + 3 * ((size_t)y * W + x);
            const int sun = x >= 10 && x < 14 && y >= 6 && y < 10;
            q[0] = sun ? 40.0f : 0.2f + 0.02f * (float)x;
            q[1] = sun ? 30.0f : 0.3f;
            q[2] = sun ? 10.0f : 1.2f - 0.03f * (float)y;
        }
    hl_env *env = NULL;
    if (hl_env_create(ctx, W, H, px, &env, NULL) != HL_OK) fprintf(stderr, "map: %s\n", hl_context_last_error(ctx));
    free(px);
    return env;
}

static void case_colour(void)
{
    hl_context *ref = hl_test_ref_context(0), *cl = hl_test_cl_context(0);
    HL_CHECK(cl != NULL, "an OpenCL device is needed");
    if (!cl) { hl_context_destroy(ref); return; }
    /* red, a green that varies over the vertices, little blue */
    hl_mesh *m = cavity(ref, acos(1.0 - 2.0 * 0.2), 0.9f);
    for (uint32_t v = 0; m && v < m->vertex_count; v++) {
        m->albedo[3 * v + 1] = 0.3f + 0.05f * (float)((v * 37u) % 11u);
        m->albedo[3 * v + 2] = 0.2f;
    }
    hl_precompute_desc d = {.N = 16, .C = 16, .bounces = 2, .bounce_rays = 16};
    const char *pc = strdup(hl_test_tmp_path("bounce_colour.hlt")), *pk = strdup(hl_test_tmp_path("bounce_colour_cl.hlt"));
    HL_CHECK(m && hl_precompute(ref, m, &d, pc, NULL) == HL_OK, "reference: %s", hl_context_last_error(ref));
    HL_CHECK(m && hl_precompute(cl, m, &d, pk, NULL) == HL_OK, "OpenCL: %s", hl_context_last_error(cl));
    size_t na = 0, nk = 0, diff = bytes_differ(pc, pk, &na, &nk);
    printf("coloured bounced files: %zu and %zu bytes, %zu bytes differ\n", na, nk, diff);
    HL_CHECK(diff == 0, "the OpenCL and reference coloured files differ");
    hl_transport *tc = NULL;
    HL_CHECK(hl_transport_load(ref, pc, &tc) == HL_OK, "load: %s", hl_context_last_error(ref));
    HL_CHECK(tc && tc->info.channels == 3 && hl_transport_rows(&tc->info) == 3 * m->vertex_count,
             "a coloured albedo gives a row a channel (channels %u)", tc ? tc->info.channels : 0);
    hl_env *env = coloured_map(ref);
    hl_relight_desc rd = {.terms = 60};
    const size_t V = m ? m->vertex_count : 0;
    float *rgb_c = malloc(V * 12), *rgb_g = malloc(V * 12), *rgb_k = malloc(V * 12);
    /* the coloured file relit, on both backends */
    hl_relighter *rc = NULL, *rk = NULL;
    HL_CHECK(tc && env && hl_relighter_create(ref, tc, &rc) == HL_OK && hl_relighter_set_env(rc, env) == HL_OK &&
                 hl_relighter_run(rc, &rd, rgb_c, NULL) == HL_OK,
             "relight (reference): %s", hl_context_last_error(ref));
    HL_CHECK(tc && env && hl_relighter_create(cl, tc, &rk) == HL_OK && hl_relighter_set_env(rk, env) == HL_OK &&
                 hl_relighter_run(rk, &rd, rgb_k, NULL) == HL_OK,
             "relight (OpenCL): %s", hl_context_last_error(cl));
    double worst_k = 0.0;
    for (size_t i = 0; rc && rk && i < 3 * V; i++) worst_k = fmax(worst_k, fabs((double)rgb_c[i] - rgb_k[i]));
    printf("coloured file, OpenCL against the reference: worst %.3g (tolerance 0)\n", worst_k);
    HL_CHECK(worst_k == 0.0, "the backends' colours differ by %g", worst_k);
    /* each channel against a grey bake with that channel's albedo */
    double tint[3] = {0, 0, 0};
    for (int c = 0; c < 3 && tc; c++) {
        hl_mesh *mg = cavity(ref, acos(1.0 - 2.0 * 0.2), 0.5f);
        for (uint32_t v = 0; v < mg->vertex_count; v++)
            for (int k = 0; k < 3; k++) mg->albedo[3 * v + k] = m->albedo[3 * v + c];
        char pg[64];
        snprintf(pg, sizeof pg, "bounce_grey%d.hlt", c);
        const char *path = hl_test_tmp_path(pg);
        hl_transport *tg = NULL;
        hl_relighter *rg = NULL;
        HL_CHECK(hl_precompute(ref, mg, &d, path, NULL) == HL_OK && hl_transport_load(ref, path, &tg) == HL_OK,
                 "grey bake: %s", hl_context_last_error(ref));
        if (!tg) {
            hl_mesh_destroy(mg);
            continue;
        }
        HL_CHECK(tg->info.channels == 1, "a grey albedo keeps a row a vertex");
        const uint32_t bad = plane_differs(tc, (uint32_t)c, tg);
        printf("channel %d: %u of %zu rows differ from the grey bake's (tolerance 0)\n", c, bad, V);
        HL_CHECK(bad == 0, "channel %d's rows are not the grey bake's", c);
        HL_CHECK(hl_relighter_create(ref, tg, &rg) == HL_OK && hl_relighter_set_env(rg, env) == HL_OK &&
                     hl_relighter_run(rg, &rd, rgb_g, NULL) == HL_OK,
                 "relight grey: %s", hl_context_last_error(ref));
        double worst = 0.0;
        for (size_t v = 0; rc && v < V; v++) {
            worst = fmax(worst, fabs((double)rgb_c[3 * v + c] - rgb_g[3 * v + c]));
            tint[c] += rgb_c[3 * v + c];
        }
        printf("channel %d: relit against the grey bake's, worst %.3g (tolerance 0)\n", c, worst);
        HL_CHECK(worst == 0.0, "channel %d relights differently from the grey bake", c);
        hl_relighter_destroy(rg);
        hl_transport_destroy(tg);
        hl_mesh_destroy(mg);
    }
    /* the point of it: the red light multiplies inside the red cavity */
    printf("inner means, red : green : blue = %.4f : %.4f : %.4f\n", tint[0] / (double)V, tint[1] / (double)V, tint[2] / (double)V);
    hl_relighter_destroy(rc);
    hl_relighter_destroy(rk);
    free(rgb_c);
    free(rgb_g);
    free(rgb_k);
    hl_env_destroy(env);
    hl_transport_destroy(tc);
    free((void *)pc);
    free((void *)pk);
    hl_mesh_destroy(m);
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* The bounces sharded as a second phase (hl_precompute_desc.direct_rows
 * with a shard, then merge) against one run, byte for byte: B = 1 (each
 * shard casts its own vertices' rays) and B = 2 (every vertex's, for the
 * first bounce), a coloured albedo (three planes to merge). */
static void case_shards(void)
{
    hl_context *ctx = hl_test_cl_context(0);
    HL_CHECK(ctx != NULL, "an OpenCL device is needed");
    if (!ctx) return;
    hl_mesh *m = cavity(ctx, acos(1.0 - 2.0 * 0.2), 0.8f);
    for (uint32_t v = 0; m && v < m->vertex_count; v++) m->albedo[3 * v + 2] = 0.3f + 0.04f * (float)(v % 7u);
    /* the direct rows in 2 shards with their floats, merged */
    const char *direct = strdup(hl_test_tmp_path("bounce_direct.hlt"));
    hl_precompute_desc d0 = {.N = 16, .C = 16, .keep_floats = 1};
    char dpart[2][1200];
    const char *dparts[2] = {dpart[0], dpart[1]};
    for (uint32_t i = 0; i < 2 && m; i++) {
        snprintf(dpart[i], sizeof dpart[i], "%s%u", hl_test_tmp_path("bounce_dpart.hlt"), i);
        HL_CHECK(hl_precompute_shard(ctx, m, &d0, i, 2, dpart[i], NULL) == HL_OK, "direct shard %u: %s", i,
                 hl_context_last_error(ctx));
    }
    hl_merge_stats ms = {0};
    HL_CHECK(m && hl_transport_merge(ctx, direct, dparts, 2, &ms) == HL_OK, "direct merge: %s", hl_context_last_error(ctx));
    HL_CHECK(ms.values == 1, "the direct shards' floats were not merged");
    printf("direct rows: 2 shards with their floats, merged (values file written: %d)\n", ms.values);
    for (uint32_t B = 1; B <= 2 && m; B++) {
        hl_precompute_desc d = {.N = 16, .C = 16, .bounces = B, .bounce_rays = 16};
        char one[1200], merged[1200], part[3][1200];
        snprintf(one, sizeof one, "%s", hl_test_tmp_path("bounce_one.hlt"));
        snprintf(merged, sizeof merged, "%s", hl_test_tmp_path("bounce_merged.hlt"));
        HL_CHECK(hl_precompute(ctx, m, &d, one, NULL) == HL_OK, "one run: %s", hl_context_last_error(ctx));
        d.direct_rows = direct;
        const char *parts[3];
        for (uint32_t i = 0; i < 3; i++) {
            char name[64];
            snprintf(name, sizeof name, "bounce_part%u.hlt", i);
            snprintf(part[i], sizeof part[i], "%s", hl_test_tmp_path(name));
            parts[i] = part[i];
            HL_CHECK(hl_precompute_shard(ctx, m, &d, i, 3, part[i], NULL) == HL_OK, "shard %u: %s", i,
                     hl_context_last_error(ctx));
        }
        HL_CHECK(hl_transport_merge(ctx, merged, parts, 3, NULL) == HL_OK, "merge: %s", hl_context_last_error(ctx));
        size_t na = 0, nb = 0, diff = bytes_differ(one, merged, &na, &nb);
        printf("B = %u: one run %zu bytes, 3 shards merged %zu bytes, %zu bytes differ (tolerance 0)\n", B, na, nb, diff);
        HL_CHECK(diff == 0, "B = %u: the merged shards differ from one run", B);
        /* a whole run's bounces from the direct file: the same bytes too */
        HL_CHECK(hl_precompute(ctx, m, &d, merged, NULL) == HL_OK, "from the direct rows: %s", hl_context_last_error(ctx));
        diff = bytes_differ(one, merged, &na, &nb);
        printf("B = %u: a whole run from the direct rows, %zu bytes differ (tolerance 0)\n", B, diff);
        HL_CHECK(diff == 0, "B = %u: the bounces from the direct rows differ from one run", B);
        /* a shard file is no transport, and the direct file stays */
        hl_transport *t = NULL;
        HL_CHECK(hl_transport_load(ctx, part[0], &t) != HL_OK, "a shard loaded as a transport");
        HL_CHECK(access(direct, F_OK) == 0, "the given direct rows were removed");
    }
    /* direct rows that already hold bounces, or of another mesh */
    hl_precompute_desc d = {.N = 16, .C = 16, .bounces = 1, .bounce_rays = 16, .direct_rows = direct};
    const char *bounced = hl_test_tmp_path("bounce_one.hlt");
    d.direct_rows = bounced;
    HL_CHECK(hl_precompute(ctx, m, &d, hl_test_tmp_path("bounce_x.hlt"), NULL) == HL_ERR_INVALID_ARGUMENT,
             "bounces from a bounced file taken");
    printf("from a bounced file: %s\n", hl_context_last_error(ctx));
    hl_mesh *other = cavity(ctx, acos(1.0 - 2.0 * 0.3), 0.8f);
    d.direct_rows = direct;
    HL_CHECK(hl_precompute(ctx, other, &d, hl_test_tmp_path("bounce_x.hlt"), NULL) == HL_ERR_INVALID_ARGUMENT,
             "another mesh's direct rows taken");
    printf("another mesh: %s\n", hl_context_last_error(ctx));
    hl_mesh_destroy(other);
    free((void *)direct);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* A flat n x n grid in y = 0, normals +y, albedo 0.8: no ray from it
 * comes back to it. */
static hl_mesh *flat_grid(hl_context *ctx, uint32_t n)
{
    const uint32_t nv = n * n, nt = 2 * (n - 1) * (n - 1);
    float *p = malloc((size_t)nv * 12), *nr = malloc((size_t)nv * 12), *a = malloc((size_t)nv * 12);
    uint32_t *ix = malloc((size_t)nt * 12), t = 0;
    hl_mesh *m = NULL;
    if (p && nr && a && ix) {
        for (uint32_t v = 0; v < nv; v++) {
            p[3 * v] = (float)(v % n) / (float)(n - 1) - 0.5f, p[3 * v + 1] = 0.0f;
            p[3 * v + 2] = (float)(v / n) / (float)(n - 1) - 0.5f;
            nr[3 * v] = 0.0f, nr[3 * v + 1] = 1.0f, nr[3 * v + 2] = 0.0f;
            a[3 * v] = a[3 * v + 1] = a[3 * v + 2] = 0.8f;
        }
        for (uint32_t j = 0; j + 1 < n; j++)
            for (uint32_t i = 0; i + 1 < n; i++) {
                const uint32_t v = j * n + i;
                ix[3 * t] = v, ix[3 * t + 1] = v + n, ix[3 * t + 2] = v + 1, t++;
                ix[3 * t] = v + 1, ix[3 * t + 1] = v + n, ix[3 * t + 2] = v + n + 1, t++;
            }
        if (hl_mesh_create(ctx, nv, p, nr, a, nt, ix, &m) != HL_OK) fprintf(stderr, "grid: %s\n", hl_context_last_error(ctx));
    }
    free(p);
    free(nr);
    free(a);
    free(ix);
    return m;
}

/* The bounced rows of m from the direct rows at direct, at out: how many
 * rows differ from the direct file's (UINT32_MAX on failure). */
static uint32_t bounced_differs(hl_context *ctx, const hl_mesh *m, const char *direct, const char *out)
{
    hl_precompute_desc d = {.N = 16, .C = 16, .bounces = 1, .bounce_rays = 16, .direct_rows = direct};
    hl_transport *td = NULL, *tb = NULL;
    uint32_t diff = UINT32_MAX;
    if (hl_precompute(ctx, m, &d, out, NULL) == HL_OK && hl_transport_load(ctx, direct, &td) == HL_OK &&
        hl_transport_load(ctx, out, &tb) == HL_OK && tb->info.channels <= 1)
        diff = plane_differs(tb, 0, td);
    if (diff == UINT32_MAX)
        fprintf(stderr, "bounces: %s\n", hl_context_last_error(ctx));
    hl_transport_destroy(td);
    hl_transport_destroy(tb);
    return diff;
}

/* Writes the values file path from its bytes b (n of them) after f
 * changed its floats, with the checksum made good again. */
static int write_values(const char *path, uint8_t *b, size_t n, void (*f)(float *, size_t))
{
    if (n < 32) return 0;
    f((float *)(void *)(b + 32), (n - 32) / 4);
    const uint32_t crc = (uint32_t)crc32(0L, b + 32, (uInt)(n - 32));
    for (int i = 0; i < 4; i++) b[24 + i] = (uint8_t)(crc >> (8 * i));
    FILE *fp = fopen(path, "wb");
    const int ok = fp && fwrite(b, 1, n, fp) == n;
    if (fp) fclose(fp);
    return ok;
}

static void scale_floats(float *v, size_t n)
{
    for (size_t i = 0; i < n; i++) v[i] *= 1.5f;
}

static void case_floats(void)
{
    hl_context *ctx = hl_test_cl_context(0);
    HL_CHECK(ctx != NULL, "an OpenCL device is needed");
    if (!ctx) return;
    hl_mesh *m = flat_grid(ctx, 12);
    char direct[1200], values[1300], out[1200];
    snprintf(direct, sizeof direct, "%s", hl_test_tmp_path("bounce_flat_direct.hlt"));
    snprintf(values, sizeof values, "%s.values", direct);
    snprintf(out, sizeof out, "%s", hl_test_tmp_path("bounce_flat.hlt"));
    hl_precompute_desc d0 = {.N = 16, .C = 16, .keep_floats = 1};
    HL_CHECK(m && hl_precompute(ctx, m, &d0, direct, NULL) == HL_OK, "direct: %s", hl_context_last_error(ctx));
    HL_CHECK(access(values, F_OK) == 0, "--keep-floats wrote no %s", values);
    size_t nvb = 0;
    uint8_t *vb = hl_test_read_file(values, &nvb);
    const uint32_t V = m ? m->vertex_count : 0;
    uint32_t diff = m ? bounced_differs(ctx, m, direct, out) : UINT32_MAX;
    printf("flat grid, %u vertices: the bounced rows from the floats, %u differ from the direct file's (tolerance 0)\n", V,
           diff);
    HL_CHECK(diff == 0, "no bounces, yet the bounced rows are not the direct rows");
    unlink(values);
    diff = m ? bounced_differs(ctx, m, direct, out) : UINT32_MAX;
    printf("the same from the 8-bit codes alone: %u of %u rows differ (the direct light coded twice)\n", diff, V);
    HL_CHECK(diff != UINT32_MAX && diff > 0, "the codes alone gave the direct rows back: the floats are not needed");
    /* bad values files: refused, naming the file; no output */
    hl_precompute_desc d = {.N = 16, .C = 16, .bounces = 1, .bounce_rays = 16, .direct_rows = direct};
    const char *what[3] = {"truncated", "damaged", "of other rows"};
    for (int k = 0; k < 3 && vb && nvb > 40; k++) {
        uint8_t *b = malloc(nvb);
        memcpy(b, vb, nvb);
        FILE *fp = fopen(values, "wb");
        if (fp && k == 0) fwrite(b, 1, nvb - 4, fp);
        if (fp && k == 1) {
            b[nvb - 3] ^= 0x40;
            fwrite(b, 1, nvb, fp);
        }
        if (fp) fclose(fp);
        if (k == 2) write_values(values, b, nvb, scale_floats);
        free(b);
        unlink(out);
        const hl_result r = hl_precompute(ctx, m, &d, out, NULL);
        printf("values %s: %s\n", what[k], hl_context_last_error(ctx));
        HL_CHECK(r == HL_ERR_FORMAT, "a values file %s was taken", what[k]);
        HL_CHECK(strstr(hl_context_last_error(ctx), ".values") != NULL, "the error does not name the values file");
        HL_CHECK(access(out, F_OK) != 0, "a file was written from values %s", what[k]);
    }
    /* a direct file damaged in its entries (which the bounces read a chunk
       at a time, not loaded): refused before anything is written */
    unlink(values);
    size_t nd = 0;
    uint8_t *db = hl_test_read_file(direct, &nd);
    char damaged[1300];
    snprintf(damaged, sizeof damaged, "%s.damaged.hlt", direct);
    if (db && nd > 64) {
        db[nd - 7] ^= 0x10; /* the entries section ends the file */
        FILE *fp = fopen(damaged, "wb");
        if (fp) fwrite(db, 1, nd, fp), fclose(fp);
        d.direct_rows = damaged;
        unlink(out);
        const hl_result r = hl_precompute(ctx, m, &d, out, NULL);
        printf("direct rows damaged: %s\n", hl_context_last_error(ctx));
        HL_CHECK(r == HL_ERR_FORMAT && strstr(hl_context_last_error(ctx), "checksum") != NULL,
                 "damaged direct rows taken (%d)", (int)r);
        HL_CHECK(access(out, F_OK) != 0, "a file was written from damaged direct rows");
        d.direct_rows = direct;
    }
    free(db);
    /* a new direct file without --keep-floats removes the older floats */
    HL_CHECK(m && hl_precompute(ctx, m, &(hl_precompute_desc){.N = 16, .C = 16}, direct, NULL) == HL_OK, "direct: %s",
             hl_context_last_error(ctx));
    HL_CHECK(access(values, F_OK) != 0, "an older run's %s stayed beside a new direct file", values);
    free(vb);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* The binary16 next to h on the side away from zero (up) or towards it. */
static double half_step(uint16_t h, int up)
{
    const uint16_t mag = h & 0x7fffu;
    if (!up && mag == 0) return 0.0;
    const uint16_t n = (uint16_t)((h & 0x8000u) | (up ? mag + 1u : mag - 1u));
    return hl_half_to_float(n);
}

static void case_half(void)
{
    enum { N = 4000 };
    uint32_t slot[N];
    float val[N];
    uint16_t s16[N], half[N];
    uint32_t s32[N];
    uint64_t x = 0x9e3779b97f4a7c15ull;
    for (int row = 0; row < 6; row++) {
        /* a row's values over 40 binary orders below its largest, some
           exactly between two binary16s, at scales from 1e-25 to 1e20 */
        const double top = pow(10.0, -25.0 + 9.0 * row);
        for (int i = 0; i < N; i++) {
            x = x * 6364136223846793005ull + 1442695040888963407ull;
            const double u = (double)(x >> 11) / 9007199254740992.0;
            double v = top * pow(2.0, -40.0 * u);
            if (i % 7 == 0) { /* a tie: 12 significant bits, the last set */
                int e;
                const double fr = frexp(v, &e);
                v = ldexp((floor(fr * 2048.0) + 0.5) / 2048.0, e);
            }
            val[i] = (float)((x >> 3) & 1 ? -v : v);
            slot[i] = (uint32_t)i;
        }
        val[0] = (float)top;
        float scale = 0.0f;
        hl_bounce_encode(N, slot, val, s16, NULL, half, &scale);
        hl_bounce_encode(N, slot, val, NULL, s32, half, &scale);
        double worst_rel = 0.0, worst_near = 0.0;
        int slots_bad = 0, ties_odd = 0, ties = 0;
        for (int i = 0; i < N; i++) {
            slots_bad += s16[i] != slot[i] || s32[i] != slot[i];
            if (i % 7 == 0 && i && fabs(val[i]) >= ldexp(scale, -14)) { /* a tie among normal binary16s: to even */
                ties++;
                ties_odd += half[i] & 1;
            }
            const double got = (double)hl_half_to_float(half[i]) * scale, want = val[i];
            /* the nearest: neither neighbour is closer */
            const double lo = half_step(half[i], 0) * scale, hi = half_step(half[i], 1) * scale;
            const double e = fabs(got - want);
            if (fabs(want) < ldexp(scale, -14)) { /* below the normal binary16s: zero, or the least one if nearer */
                if (half[i] & 0x7fffu && (half[i] & 0x7fffu) != 0x400u) worst_near = fmax(worst_near, e);
            } else if (fabs(lo - want) < e || fabs(hi - want) < e)
                worst_near = fmax(worst_near, e);
            if (fabs(want) >= ldexp(top, -28)) worst_rel = fmax(worst_rel, e / fabs(want));
        }
        printf("row of largest %.0e: scale %g, worst relative error %.3g (down to 2^-28 of the largest)\n", top,
               (double)scale, worst_rel);
        HL_CHECK(slots_bad == 0, "%d slots changed", slots_bad);
        HL_CHECK(ties > 0 && ties_odd == 0, "%d of %d ties rounded to an odd binary16", ties_odd, ties);
        hl_check_error("a value against its binary16 times the scale (relative)", worst_rel, ldexp(1.0, -11));
        hl_check_error("a value off by more than to a closer binary16", worst_near, 0.0);
    }
    /* every normal binary16 (and zero) decoded exactly */
    int bad = 0;
    for (uint32_t h = 0; h < 0x10000u; h++) {
        const uint32_t e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
        if (e == 31 || (e == 0 && m)) continue;
        const double want = (h & 0x8000u ? -1.0 : 1.0) * (e ? ldexp(1.0 + m / 1024.0, (int)e - 15) : 0.0);
        bad += (double)hl_half_to_float((uint16_t)h) != want;
    }
    HL_CHECK(bad == 0, "%d binary16s decoded wrong", bad);
    /* a row too small for a normal scale: zeros */
    val[0] = 1e-31f;
    val[1] = -3e-32f;
    float scale = 0.0f;
    half[0] = half[1] = 1;
    hl_bounce_encode(2, slot, val, s16, NULL, half, &scale);
    HL_CHECK(half[0] == 0 && half[1] == 0 && scale == 1.0f, "a row of 1e-31 kept as %u, %u at scale %g", half[0],
             half[1], (double)scale);
}

static void case_bad(void)
{
    hl_context *ctx = hl_test_ref_context(0);
    hl_mesh *m = cavity(ctx, 0.6, 0.5f);
    const char *p = hl_test_tmp_path("bounce_bad.hlt");
    hl_precompute_desc d = {.N = 16, .C = 16, .bounces = HL_MAX_BOUNCES + 1};
    HL_CHECK(hl_precompute(ctx, m, &d, p, NULL) == HL_ERR_INVALID_ARGUMENT, "17 bounces taken");
    printf("17 bounces: %s\n", hl_context_last_error(ctx));
    d.bounces = 1;
    HL_CHECK(hl_precompute_shard(ctx, m, &d, 0, 2, p, NULL) == HL_ERR_INVALID_ARGUMENT,
             "a bounced shard without direct rows taken");
    printf("a shard: %s\n", hl_context_last_error(ctx));
    /* an albedo above 1: each bounce would add more light than it took */
    for (uint32_t v = 0; v < m->vertex_count; v++) m->albedo[3 * v] = 1.5f;
    HL_CHECK(hl_precompute(ctx, m, &d, p, NULL) == HL_ERR_INVALID_ARGUMENT, "albedo 1.5 taken");
    printf("albedo 1.5: %s\n", hl_context_last_error(ctx));
    HL_CHECK(strstr(hl_context_last_error(ctx), "albedo") != NULL, "the error names the albedo");
    HL_CHECK(access(p, F_OK) != 0, "a file was written");
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"cavity", case_cavity}, {"furnace", case_furnace}, {"twin", case_twin},
        {"colour", case_colour}, {"shards", case_shards}, {"floats", case_floats}, {"half", case_half}, {"bad", case_bad}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
