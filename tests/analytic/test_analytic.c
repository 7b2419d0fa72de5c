/* test_analytic.c - two scenes with known answers, end to end (suite
 * "analytic").
 *
 * analytic.furnace unoccluded vertex, L = 1: B = 1, directly, from the table
 *                  in double, and through the Haar domain.
 * analytic.cap     spherical cap occluder: B = cos^2(alpha), end to end
 *                  through Embree, hl_precompute and the transport file,
 *                  and with analytic visibility through the plain-C stages.
 *
 * Every check prints its tolerance and worst error (hl_check_error).
 * Depends on: haarlight_core (reference backend only; no OpenCL device),
 * tests/common/maths_util.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <float.h>
#include <stdint.h>
#include <unistd.h>

#include "hl_test.h"
#include "rays.h"
#include "twins.h"
#include "maths_util.h"

/* ================================================================ analytic */

static void case_furnace(void)
{
    hl_context *ctx = make_ctx();
    /* 20 normals: the six axes, the eight cube diagonals, six random */
    double normals[20][3];
    int nn = 0;
    for (int q = 0; q < 3; q++)
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            normals[nn][0] = normals[nn][1] = normals[nn][2] = 0.0;
            normals[nn][q] = sgn;
            nn++;
        }
    for (int a = -1; a <= 1; a += 2)
        for (int b = -1; b <= 1; b += 2)
            for (int c = -1; c <= 1; c += 2) {
                normals[nn][0] = a;
                normals[nn][1] = b;
                normals[nn][2] = c;
                normalize3(normals[nn++]);
            }
    while (nn < 20) {
        double v[3] = {rng_unit() * 2 - 1, rng_unit() * 2 - 1, rng_unit() * 2 - 1};
        if (norm3(v) < 0.1 || norm3(v) > 1.0) continue;
        normalize3(v);
        memcpy(normals[nn++], v, sizeof v);
    }

    static const uint32_t Rs[] = {16, 32, 64, 128};
    double err_of[4] = {0, 0, 0, 0};
    char what[160];
    for (size_t k = 0; k < 4; k++) {
        uint32_t R = Rs[k];
        hl_geom *g = make_geom(ctx, R, R);
        uint8_t *vis = xmalloc(g->ncube);
        memset(vis, 1, g->ncube); /* S = 1: every texel one unoccluded ray */
        float *T = xmalloc((size_t)g->ncoef * sizeof *T), *L = xmalloc((size_t)g->ncoef * sizeof *L);
        float *WT = xmalloc((size_t)g->ncoef * sizeof *WT), *WL = xmalloc((size_t)g->ncoef * sizeof *WL);
        unit_light(g, L);
        haar_of(g, L, WL);
        double worst_a = 0.0, worst_b = 0.0, worst_c = 0.0, worst_y = 0.0, worst_over = 0.0;
        for (int i = 0; i < nn; i++) {
            const double *n = normals[i];
            float nf[3] = {(float)n[0], (float)n[1], (float)n[2]};
            hl_ref_cube2para(g, vis, (float)(1.0 / PI), nf, T);
            double Bf = dot_ff(T, L, g->ncoef);
            /* (a) the same sum in double straight from the table */
            double Bd = 0.0;
            for (uint32_t e = 0; e < g->nentries; e++) {
                const hl_c2p_entry *c = &g->c2p[e];
                double w = (double)nf[0] * c->mx + (double)nf[1] * c->my + (double)nf[2] * c->mz;
                if (w > 0.0) Bd += w;
            }
            Bd /= PI;
            worst_a = fmax(worst_a, fabs(Bf - Bd));
            /* (b) against the exact 1 */
            worst_b = fmax(worst_b, fabs(Bd - 1.0));
            worst_over = fmax(worst_over, Bd - 1.0);
            if (fabs(n[1]) == 1.0) worst_y = fmax(worst_y, fabs(Bd - 1.0));
            /* (c) through the Haar domain */
            haar_of(g, T, WT);
            worst_c = fmax(worst_c, fabs(dot_ff(WT, WL, g->ncoef) - Bf) / Bf);
        }
        err_of[k] = worst_b;
        /* (a) Each T_j sums a few float products n.m (3 products, 2 adds,
         * then a float accumulation and the 1/pi scale): ~5 ulps of
         * |m| per entry. Summed over the sphere (sum |m| ~ 4 pi, over pi
         * = 4) the worst aligned case is 4 * 5 * 2^-24 = 1.2e-6; roundings
         * are independent, so 1e-6 holds with a wide margin. */
        snprintf(what, sizeof what, "C=N=%u (a) |sum T_j L_j - table sum in double| over 20 normals", R);
        hl_check_error(what, worst_a, 1e-6);
        /* (c) Parseval, as haar.parseval: 1e-6 relative */
        snprintf(what, sizeof what, "C=N=%u (c) |WT.WL - sum T_j L_j| / B", R);
        hl_check_error(what, worst_c, 1e-6);
        /* Normals +/-Y: the maps split at the horizon and so do the cube
         * rows (C even), so no table part straddles it and no clamp loses
         * anything. What is left is the table's first moments: each comes
         * from the part's in-disc 8x8 sub-samples, rescaled to the exact
         * omega. At the rim the sub-samples' centroid can sit half a
         * sub-cell, 1/(8N) in r, off the true one, and y changes by 1 per
         * unit r there; rim texels hold at most 2 pi (2 sqrt2 / N) sr, so
         * |B - 1| <= 2 pi 2 sqrt2 / N / (8N) / pi = 0.71 / N^2. The interior
         * midpoint error, ~(1/(4N))^2 / 24 relative, is far smaller:
         * tolerance 1 / N^2 (3.9e-3 at N = 16, 2.4e-4 at 64). */
        double tol_y = 1.0 / ((double)R * R);
        snprintf(what, sizeof what, "C=N=%u (b) |B - 1| for normals +/-Y (no part straddles the horizon)", R);
        hl_check_error(what, worst_y, tol_y);
        /* Clamping per part can only lose energy: B <= 1 up to the same
         * first-moment error. */
        snprintf(what, sizeof what, "C=N=%u (b) B - 1 (must not exceed 1 beyond the moment error)", R);
        hl_check_error(what, worst_over, tol_y);
        printf("C=N=%u (b) |B - 1| worst over 20 normals: %.4g\n", R, worst_b);
        free(vis);
        free(T);
        free(L);
        free(WT);
        free(WL);
        hl_geom_destroy(g);
    }
    /* (b) The remaining error: a part straddling the horizon contributes
     * max(0, n.m) instead of the integral of max(0, n.w), losing the
     * smaller of its two lobes. For a part of angular size delta with the
     * horizon at a uniformly random offset u, the loss is delta min(u,
     * delta - u)^2 / 2, on average delta^3 / 24; about 2 pi / delta parts
     * line the horizon, so the expected |B - 1| is (2 pi / delta)(delta^3 /
     * 24) / pi = delta^2 / 12. Parts are at most a face-centre cube texel's
     * diagonal (the paraboloid texels at the rim are no larger when N = C),
     * delta = 2 sqrt2 / C: tolerance 8 / (12 C^2) = 1.6e-4 at C = 64. */
    hl_check_error("C=N=64 (b) |B - 1| worst over 20 normals, bound 2/(3 C^2)", err_of[2],
                   2.0 / (3.0 * 64.0 * 64.0));
    int shrinks = err_of[1] < err_of[0] && err_of[2] < err_of[1] && err_of[3] < err_of[2];
    printf("(b) |B - 1| at C=N=16/32/64/128: %.4g %.4g %.4g %.4g; ratios %.2f %.2f %.2f\n", err_of[0], err_of[1],
           err_of[2], err_of[3], err_of[0] / err_of[1], err_of[1] / err_of[2], err_of[2] / err_of[3]);
    hl_check_error("(b) furnace error not shrinking at every step of C=N = 16, 32, 64, 128", shrinks ? 0.0 : 1.0, 0.0);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- cap */


#define CAP_SEGMENTS 512
#define CAP_RINGS 8
#define RECEIVER_SIZE 1e-5f

/* Receiver triangle (vertices 0..2, vertex 0 at the origin, normal +Y) and
 * a cap of radius 1 about +Y out to polar angle alpha, circumscribed: the
 * rim's 512 vertices sit at polar angle alpha' with tan alpha' = tan alpha /
 * cos(pi / 512), so each rim edge's great-circle arc (what the edge hides,
 * seen from the origin) touches the circle alpha at its midpoint and the
 * hidden region contains the cap. Seen from the origin only the rim
 * polygon matters (each facet hides the spherical triangle of its corners),
 * so 8 rings are enough to make the cap a real mesh; more rings would only
 * add vertices to precompute. rim gets the rim positions (3 * 512). */
static hl_mesh *cap_mesh(hl_context *ctx, double alpha, double *rim)
{
    const uint32_t S = CAP_SEGMENTS, R = CAP_RINGS;
    const uint32_t V = 4 + R * S, Tn = 1 + S + 2 * S * (R - 1);
    float *P = xmalloc((size_t)V * 3 * sizeof *P), *Nn = xmalloc((size_t)V * 3 * sizeof *Nn);
    uint32_t *I = xmalloc((size_t)Tn * 3 * sizeof *I);
    const float rs = RECEIVER_SIZE;
    const float rec[3][3] = {{0, 0, 0}, {0, 0, rs}, {rs, 0, 0}}; /* (b-a) x (c-a) = +Y */
    for (int v = 0; v < 3; v++)
        for (int q = 0; q < 3; q++) {
            P[3 * v + q] = rec[v][q];
            Nn[3 * v + q] = q == 1 ? 1.0f : 0.0f;
        }
    P[9] = 0.0f, P[10] = 1.0f, P[11] = 0.0f; /* pole */
    const double alpha_rim = atan(tan(alpha) / cos(PI / S));
    for (uint32_t k = 1; k <= R; k++)
        for (uint32_t i = 0; i < S; i++) {
            double th = alpha_rim * k / R, ph = 2.0 * PI * i / S;
            float *p = P + 3 * (4 + (k - 1) * S + i);
            p[0] = (float)(sin(th) * cos(ph));
            p[1] = (float)cos(th);
            p[2] = (float)(sin(th) * sin(ph));
            if (k == R)
                for (int q = 0; q < 3; q++) rim[3 * i + q] = p[q];
        }
    for (uint32_t v = 3; v < V; v++) /* outward radial normals */
        for (int q = 0; q < 3; q++) Nn[3 * v + q] = P[3 * v + q];
    uint32_t t = 0;
    I[t++] = 0, I[t++] = 1, I[t++] = 2;
    for (uint32_t i = 0; i < S; i++) {
        I[t++] = 3;
        I[t++] = 4 + (i + 1) % S;
        I[t++] = 4 + i;
    }
    for (uint32_t k = 1; k < R; k++)
        for (uint32_t i = 0; i < S; i++) {
            uint32_t a = 4 + (k - 1) * S + i, b = 4 + (k - 1) * S + (i + 1) % S;
            uint32_t c = a + S, d = b + S;
            I[t++] = a, I[t++] = b, I[t++] = d;
            I[t++] = a, I[t++] = d, I[t++] = c;
        }
    hl_mesh *mesh = NULL;
    hl_result r = hl_mesh_create(ctx, V, P, Nn, NULL, Tn, I, &mesh);
    free(P);
    free(Nn);
    free(I);
    if (r != HL_OK) {
        fprintf(stderr, "hl_mesh_create: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    return mesh;
}

/* Index of the vertex at the origin with normal +Y. */
static uint32_t find_receiver(const hl_mesh *m)
{
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v;
        if (p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f && n[1] == 1.0f) return v;
    }
    fprintf(stderr, "receiver vertex not found\n");
    exit(1);
}

/* Cube face coordinates to a direction, OpenGL table, in double. */
static void gl_face_dir(int f, double sc, double tc, double d[3])
{
    switch (f) {
    case 0: d[0] = 1; d[1] = -tc; d[2] = -sc; break;
    case 1: d[0] = -1; d[1] = -tc; d[2] = sc; break;
    case 2: d[0] = sc; d[1] = 1; d[2] = tc; break;
    case 3: d[0] = sc; d[1] = -1; d[2] = -tc; break;
    case 4: d[0] = sc; d[1] = -tc; d[2] = 1; break;
    default: d[0] = -sc; d[1] = -tc; d[2] = -1; break;
    }
}

/* Gauss-Legendre, 5 points on [-1, 1]. */
static const double gl5_x[5] = {-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831,
                                0.9061798459386640};
static const double gl5_w[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665,
                                0.2369268850561891};

/* First moment, integral of w dw, over the face rectangle [sc0, sc0 + h] x
 * [tc0, tc0 + h] of face f: dw = dsc dtc / (1 + sc^2 + tc^2)^(3/2) and
 * w = d / |d|, so the integrand is d / (1 + sc^2 + tc^2)^2, smooth: 5x5
 * Gauss-Legendre is exact to ~1e-12 for h <= 1/8. */
static void face_rect_moment(int f, double sc0, double tc0, double h, double M[3])
{
    M[0] = M[1] = M[2] = 0.0;
    for (int a = 0; a < 5; a++)
        for (int b = 0; b < 5; b++) {
            double sc = sc0 + h * 0.5 * (gl5_x[a] + 1.0), tc = tc0 + h * 0.5 * (gl5_x[b] + 1.0), d[3];
            gl_face_dir(f, sc, tc, d);
            double q = 1.0 + sc * sc + tc * tc, w = gl5_w[a] * gl5_w[b] * h * h * 0.25 / (q * q);
            for (int k = 0; k < 3; k++) M[k] += d[k] * w;
        }
}

/* Visibility counts of the exact cap (polar angle < alpha about +Y, seen
 * from the origin) for the S x S sub-rays of each cube texel, at the
 * directions rays.c casts (face coordinates offset by ((a + 0.5) / S - 0.5)
 * * 2 / C). near[i] = 1 where a sub-ray lies within 1e-4 rad of the rim:
 * there the mesh (a circumscribed polygon seen from a point ~2e-5 above the
 * origin, off by at most ~4e-5 rad) may legitimately disagree. B_disc gets
 * the exact B of these samples: each sub-ray stands for its sub-cell, whose
 * cosine-weighted solid angle (about +Y) is integrated exactly. */
static void cap_vis(const hl_geom *g, uint32_t S, double alpha, uint8_t *vis, uint8_t *near, double *B_disc)
{
    const uint32_t C = g->C;
    double acc = 0.0;
    for (uint32_t i = 0; i < g->ncube; i++) {
        int f = (int)(i / (C * C));
        uint32_t row = (i / C) % C, col = i % C, cnt = 0;
        near[i] = 0;
        for (uint32_t a = 0; a < S; a++)
            for (uint32_t b = 0; b < S; b++) {
                double h = 2.0 / ((double)C * S);
                double sc0 = -1.0 + 2.0 * col / C + b * h, tc0 = -1.0 + 2.0 * row / C + a * h, d[3];
                gl_face_dir(f, sc0 + 0.5 * h, tc0 + 0.5 * h, d);
                double polar = acos(d[1] / norm3(d));
                if (fabs(polar - alpha) < 1e-4) near[i] = 1;
                if (polar < alpha) continue;
                cnt++;
                double M[3];
                face_rect_moment(f, sc0, tc0, h, M);
                if (M[1] > 0.0) acc += M[1]; /* no sub-cell straddles y = 0 (C S even) */
            }
        vis[i] = (uint8_t)cnt;
    }
    *B_disc = acc / PI;
}

static void case_cap(void)
{
    hl_context *ctx = make_ctx();
    const char *tmp = hl_test_env("HL_TMP", ".");
    char what[220];

    /* Self-check of the Lambert reference: a 65536-gon inscribed in the
     * circle alpha = 45 deg gives sin^2 alpha to its polygon error
     * ~ sin^2 alpha (pi/K)^2 ~ 1e-9. */
    {
        const int K = 65536;
        double *P = xmalloc((size_t)K * 3 * sizeof *P), o[3] = {0, 0, 0}, n[3] = {0, 1, 0}, al = PI / 4;
        for (int i = 0; i < K; i++) {
            double ph = 2 * PI * i / K;
            P[3 * i] = sin(al) * cos(ph), P[3 * i + 1] = cos(al), P[3 * i + 2] = sin(al) * sin(ph);
        }
        hl_check_error("Lambert reference: 65536-gon vs sin^2(45 deg)",
                       fabs(polygon_form_factor(P, K, o, n) - 0.5), 1e-8);
        free(P);
    }

    static const double alphas_deg[3] = {30, 45, 60};
    static const uint32_t Rs[3] = {16, 32, 64};
    static const uint32_t quants[3] = {HL_QUANT_LINEAR8, HL_QUANT_LOG8, HL_QUANT_SQRT8};
    static const uint32_t Ss[2] = {1, 4};
    const float ray_offset = 1e-5f; /* of the diagonal: see below */
    double err[2][3][3]; /* [S index][alpha][resolution]: Embree, unquantised */
    for (int ia = 0; ia < 3; ia++) {
        const double adeg = alphas_deg[ia], alpha = adeg * PI / 180.0, exact = cos(alpha) * cos(alpha);
        double rim[3 * CAP_SEGMENTS];
        hl_mesh *mesh = cap_mesh(ctx, alpha, rim);
        uint32_t rv = find_receiver(mesh);
        const float nrm[3] = {0.0f, 1.0f, 0.0f};
        /* The rays start at the receiver plus the offset along the normal
         * (rays.c). With offset 1e-5 of the diagonal (~2e-5) the shift
         * changes B by ~sin(2 alpha) sin(alpha) 2e-5, and a receiver of side
         * 1e-5 is never hit by the near-horizon rays that rays.c still casts
         * (they reach y = 0 at least offset / (1.5 / C) = 2e-4 away). */
        const float offset = ray_offset * hl_mesh_query_diagonal(mesh);
        const double o[3] = {0.0, (double)offset, 0.0}, ny[3] = {0, 1, 0};
        double B_poly = 1.0 - polygon_form_factor(rim, CAP_SEGMENTS, o, ny);
        printf("alpha=%2.0f: cos^2 alpha = %.6f; exact B of the mesh from the ray origin %.6f (polygon + offset "
               "error %+.3g)\n",
               adeg, exact, B_poly, B_poly - exact);
        /* The circumscribed 512-gon hides a band of angular width at most
         * alpha' - alpha ~ sin(2 alpha)/2 (pi/512)^2/2 ~ 9.4e-6 rad, costing
         * ~2 sin(alpha) cos(alpha) * that in B, plus the offset's ~2e-5:
         * both below 3e-5; 1e-4 bounds them. */
        snprintf(what, sizeof what, "alpha=%.0f polygon + ray offset |B_mesh - cos^2 alpha|", adeg);
        hl_check_error(what, fabs(B_poly - exact), 1e-4);

        hl_rt *rt = NULL;
        if (hl_rt_create(ctx, mesh, &rt) != HL_OK) {
            fprintf(stderr, "hl_rt_create: %s\n", hl_context_last_error(ctx));
            exit(1);
        }
        for (int ir = 0; ir < 3; ir++) {
            const uint32_t R = Rs[ir];
            hl_geom *g = make_geom(ctx, R, R);
            float *L = xmalloc((size_t)g->ncoef * sizeof *L), *WL = xmalloc((size_t)g->ncoef * sizeof *WL);
            float *coef = xmalloc((size_t)g->ncoef * sizeof *coef), *dense = xmalloc((size_t)g->ncoef * sizeof *dense);
            uint8_t *vis = xmalloc(g->ncube), *vis_a = xmalloc(g->ncube), *near = xmalloc(g->ncube);
            unit_light(g, L);
            haar_of(g, L, WL);
            double B_e1 = 0.0;

            for (int is = 0; is < 2; is++) {
                const uint32_t S = Ss[is];
                /* Embree visibility of the receiver, exactly as the
                 * precompute casts it */
                hl_vis_counts vc = {0, 0};
                if (hl_rt_visibility(rt, g, mesh, rv, 1, S, offset, vis, &vc) != HL_OK) {
                    fprintf(stderr, "hl_rt_visibility: %s\n", hl_context_last_error(ctx));
                    exit(1);
                }
                double B_disc;
                cap_vis(g, S, alpha, vis_a, near, &B_disc);
                long differ = 0;
                for (uint32_t c = 0; c < g->ncube; c++)
                    if (g->cube_dirs[4 * (size_t)c + 1] > -1.5f / (float)R && vis_a[c] != vis[c] && !near[c])
                        differ++;
                snprintf(what, sizeof what,
                         "alpha=%.0f C=N=%u S=%u cube texels where Embree and the exact cap disagree (off the rim)",
                         adeg, R, S);
                hl_check_error(what, (double)differ, 0.0);

                double direct_e, B_e = stages_B(g, vis, S, nrm, L, WL, &direct_e, S == 1 ? coef : NULL);
                double direct_a, B_a = stages_B(g, vis_a, S, nrm, L, WL, &direct_a, NULL);
                if (S == 1) B_e1 = B_e;
                err[is][ia][ir] = fabs(B_e - exact);
                printf("alpha=%2.0f C=N=%2u S=%u: Embree B = %.6f (|B - cos^2| = %.3g), exact-cap visibility "
                       "B = %.6f, exact B of those point samples %.6f (sampling error %+.3g, stages error %+.3g)\n",
                       adeg, R, S, B_e, err[is][ia][ir], B_a, B_disc, B_disc - B_poly, B_a - B_disc);
                /* Haar-domain dot vs direct sum: Parseval, 1e-6 relative */
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u S=%u |WT.WL - sum T L| / B", adeg, R, S);
                hl_check_error(what, fmax(fabs(B_e - direct_e) / direct_e, fabs(B_a - direct_a) / direct_a), 1e-6);
                /* The stages (the area filter) against the exact weights of
                 * the samples they were given. The table resolves each
                 * paraboloid texel's split among cube texels on an 8x8
                 * sub-grid: along a visibility edge it misplaces at most half
                 * a sub-cell, (2/N)/16 in (s, t), i.e. <= 1/(4N) rad (the map
                 * stretches angles by at most 2). The edge is a staircase on
                 * the cube grid, at most 4/pi times the rim circle's 2 pi
                 * sin(alpha), and weighted by cos(alpha) / pi: bound
                 * 8 sin(alpha) / (4N) cos(alpha) / pi = sin(2 alpha) / (pi N)
                 * (4.97e-3 at N = 64, alpha = 45). */
                double tol_stage = sin(2.0 * alpha) / (PI * R);
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u S=%u stages vs exact B of the same samples", adeg,
                         R, S);
                hl_check_error(what, fabs(B_a - B_disc), tol_stage);
            }

            /* End to end: hl_precompute -> file -> hl_transport_query_row */
            for (int iq = 0; iq < 3; iq++) {
                const char *qn = quants[iq] == HL_QUANT_LOG8 ? "log8" : quants[iq] == HL_QUANT_SQRT8 ? "sqrt8" : "linear8";
                char path[1024];
                snprintf(path, sizeof path, "%s/analytic_cap_%d_%u_%s_%ld.hlt", tmp, (int)adeg, R, qn,
                         (long)getpid());
                hl_precompute_desc d = {0};
                d.N = R;
                d.C = R;
                d.rule = HL_TRUNC_ALL;
                d.quant = quants[iq];
                d.ray_offset = ray_offset;
                hl_result r = hl_precompute(ctx, mesh, &d, path, NULL);
                HL_CHECK(r == HL_OK, "hl_precompute: %s", hl_context_last_error(ctx));
                hl_transport *t = NULL;
                if (r == HL_OK) r = hl_transport_load(ctx, path, &t);
                HL_CHECK(r == HL_OK, "hl_transport_load: %s", hl_context_last_error(ctx));
                remove(path);
                if (r != HL_OK) continue;
                HL_CHECK(t->info.N == R && t->info.C == R && t->info.vertex_count == mesh->vertex_count,
                         "transport header N=%u C=%u V=%u", t->info.N, t->info.C, t->info.vertex_count);
                hl_transport_query_row(t, rv, dense);
                double B_q = dot_ff(dense, WL, g->ncoef);
                /* The file's row must be exactly the quantisation (formulas
                 * of hl_shared.h, this row's a and b) of the coefficients the
                 * stages give for the same Embree visibility, with a and b the
                 * row's min and max kept value (|value| for log8). */
                hl_row_quant rq = t->row_quant[rv];
                double worst_bits = 0.0, bound = 0.0;
                float lo = INFINITY, hi = -INFINITY;
                for (uint32_t i = 0; i < g->ncoef; i++) {
                    if (coef[i] == 0.0f) {
                        worst_bits = fmax(worst_bits, fabs((double)dense[i]));
                        continue;
                    }
                    float v = quants[iq] != HL_QUANT_LINEAR8 ? fabsf(coef[i]) : coef[i];
                    lo = fminf(lo, v);
                    hi = fmaxf(hi, v);
                    uint32_t code = hl_quant(quants[iq], coef[i], rq.a, rq.b, hl_dither_key(rv, i));
                    float want = hl_dequant(quants[iq], code, rq.a, rq.b, hl_dither_key(rv, i));
                    worst_bits = fmax(worst_bits, fabs((double)dense[i] - want));
                    /* the scheme's own worst step: linear8, half of
                     * (b - a) / 255; log8, half of (key span) / 127 float keys
                     * plus one for the dequantiser's rounding, a key being at
                     * most 2^-23 of the value; sqrt8, sqrt(|v| / b) rounded to a
                     * 127th: b (2 sqrt(|v| / b) + 1/254) / 254, plus a few
                     * units in the last place of b for the float rounding */
                    double step = quants[iq] == HL_QUANT_LOG8
                                      ? fabs((double)coef[i]) *
                                            (((double)hl_key(rq.b) - hl_key(rq.a)) / 254.0 + 1.0) * ldexp(1.0, -23)
                                  : quants[iq] == HL_QUANT_SQRT8
                                      ? rq.b * (2.0 * sqrt(fabs((double)coef[i]) / rq.b) + 1.0 / 254.0) / 254.0 +
                                            8.0 * ldexp((double)rq.b, -24)
                                      : ((double)rq.b - rq.a) / 510.0;
                    bound += fabs((double)WL[i]) * step;
                }
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u %s: file row vs quantised stage coefficients", adeg,
                         R, qn);
                hl_check_error(what, worst_bits, 0.0);
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u %s: row a, b vs min, max kept", adeg, R, qn);
                hl_check_error(what, fmax(fabs((double)rq.a - lo), fabs((double)rq.b - hi)), 0.0);
                printf("alpha=%2.0f C=N=%2u %-7s: file B = %.6f, |B - cos^2| = %.3g, quantisation error %+.3g "
                       "(a=%.3g b=%.3g)\n",
                       adeg, R, qn, B_q, fabs(B_q - exact), B_q - B_e1, (double)rq.a, (double)rq.b);
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u %s: |B_file - B_unquantised| vs the scheme's step bound",
                         adeg, R, qn);
                hl_check_error(what, fabs(B_q - B_e1), bound);
                hl_transport_destroy(t);
            }
            free(L);
            free(WL);
            free(coef);
            free(dense);
            free(vis);
            free(vis_a);
            free(near);
            hl_geom_destroy(g);
        }
        hl_rt_destroy(rt);
        hl_mesh_destroy(mesh);
    }

    /* Discretisation. Visibility is a point sample per sub-ray; each of the
     * ~4 C S sin(alpha) sub-cells the rim crosses is wrong by (indicator -
     * covered fraction) of its weight w = (2/(C S))^2 cos(alpha) / pi (an
     * upper bound: the face Jacobian only lowers it), standard deviation
     * <= 0.41 w for a uniform fraction. The cap is symmetric under the 8
     * symmetries of the +Y face, so these errors come in identical groups
     * of 8: sigma = sqrt(8 * 4 C S sin(alpha)) * 0.41 w. Add the stages'
     * bound above; tolerance = 3 sigma + sin(2 alpha) / (pi N). */
    for (int is = 0; is < 2; is++) {
        const uint32_t S = Ss[is];
        double worst16 = 0.0, worst64 = 0.0;
        for (int ia = 0; ia < 3; ia++) {
            const double alpha = alphas_deg[ia] * PI / 180.0, C = 64.0;
            double w = (2.0 / (C * S)) * (2.0 / (C * S)) * cos(alpha) / PI;
            double sigma = sqrt(8.0 * 4.0 * C * S * sin(alpha)) * 0.41 * w;
            double tol = 3.0 * sigma + sin(2.0 * alpha) / (PI * C);
            snprintf(what, sizeof what, "alpha=%.0f C=N=64 S=%u Embree, unquantised |B - cos^2 alpha|",
                     alphas_deg[ia], S);
            hl_check_error(what, err[is][ia][2], tol);
            printf("alpha=%2.0f S=%u |B - cos^2| at C=N=16/32/64: %.3g %.3g %.3g\n", alphas_deg[ia], S,
                   err[is][ia][0], err[is][ia][1], err[is][ia][2]);
            worst16 = fmax(worst16, err[is][ia][0]);
            worst64 = fmax(worst64, err[is][ia][2]);
            /* With 4x4 rays per texel the sampling error no longer
             * dominates, and each alpha must improve from 16 to 64. */
            if (S > 1) {
                snprintf(what, sizeof what, "alpha=%.0f S=%u error at C=N=64 (%.3g) not below that at 16 (%.3g)",
                         alphas_deg[ia], S, err[is][ia][2], err[is][ia][0]);
                hl_check_error(what, err[is][ia][2] < err[is][ia][0] ? 0.0 : 1.0, 0.0);
            }
        }
        /* With one ray per texel the point-sampling error of one alpha is
         * an aliasing pattern of the rim against the grid, not monotone in
         * C (alpha = 30: the samples at C = 64 are those of C = 16, S = 4,
         * and miss by +2.2e-3, more than C = 16, S = 1); over the three
         * alphas it must shrink. */
        snprintf(what, sizeof what, "S=%u worst over alpha: error at C=N=64 (%.3g) not below that at 16 (%.3g)", S,
                 worst64, worst16);
        hl_check_error(what, worst64 < worst16 ? 0.0 : 1.0, 0.0);
    }
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"furnace", case_furnace},
        {"cap", case_cap},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
