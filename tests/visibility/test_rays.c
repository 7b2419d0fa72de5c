/* test_rays.c - the visibility rays' origin offset (host/src/visibility/
 * rays.c), suite "rays".
 *
 * rays.offset  a thin slab, a contact and a crease closer to the receiver
 *              than 1e-3 of the diagonal: the robust default offset against
 *              Lambert's exact B at three scales (the old default must fail
 *              there), and no acne on planes and boxes far from the origin,
 *              turned or not.
 * rays.step    a receiver at the foot of a box's face (a concave edge of
 *              faces that share no vertex): B = 1/2, not 0.
 *
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

/* ---------------------------------------------------------------- ray offset */

/* A mesh being built for the ray-offset scenes: positions and normals in
 * unit scale, scaled by `scale` when made. */
typedef struct mesh_build {
    uint32_t nv, nt;
    float P[3 * 2048], Nn[3 * 2048];
    uint32_t I[3 * 4096];
} mesh_build;

static uint32_t mb_vertex(mesh_build *b, double x, double y, double z, double nx, double ny, double nz)
{
    const double p[3] = {x, y, z}, n[3] = {nx, ny, nz};
    for (int q = 0; q < 3; q++) {
        b->P[3 * b->nv + q] = (float)p[q];
        b->Nn[3 * b->nv + q] = (float)n[q];
    }
    return b->nv++;
}

static void mb_tri(mesh_build *b, uint32_t a, uint32_t c, uint32_t d)
{
    b->I[3 * b->nt] = a, b->I[3 * b->nt + 1] = c, b->I[3 * b->nt + 2] = d;
    b->nt++;
}

/* A quad a b c d (counter-clockwise seen from its normal's side) as a fan
 * of four triangles about its centre, which gets normal n: the vertex the
 * checks look at when the quad holds the receiver. Returns the centre. */
static uint32_t mb_quad_fan(mesh_build *b, const double c[4][3], const double n[3])
{
    double m[3] = {0, 0, 0};
    uint32_t v[4];
    for (int k = 0; k < 4; k++) {
        v[k] = mb_vertex(b, c[k][0], c[k][1], c[k][2], n[0], n[1], n[2]);
        for (int q = 0; q < 3; q++) m[q] += c[k][q] / 4.0;
    }
    uint32_t centre = mb_vertex(b, m[0], m[1], m[2], n[0], n[1], n[2]);
    for (int k = 0; k < 4; k++) mb_tri(b, centre, v[k], v[(k + 1) % 4]);
    return centre;
}

/* An axis-aligned closed box [lo, hi], outward winding and normals. */
static void mb_box(mesh_build *b, const double lo[3], const double hi[3])
{
    for (int axis = 0; axis < 3; axis++)
        for (int side = 0; side < 2; side++) {
            const int u = (axis + 1) % 3, w = (axis + 2) % 3;
            double n[3] = {0, 0, 0}, c[4][3];
            n[axis] = side ? 1.0 : -1.0;
            const double pos = side ? hi[axis] : lo[axis];
            /* corners in (u, w) order, counter-clockwise about +axis */
            const double uw[4][2] = {{lo[u], lo[w]}, {hi[u], lo[w]}, {hi[u], hi[w]}, {lo[u], hi[w]}};
            for (int k = 0; k < 4; k++) {
                const int kk = side ? k : 3 - k;
                c[k][axis] = pos;
                c[k][u] = uw[kk][0];
                c[k][w] = uw[kk][1];
            }
            mb_quad_fan(b, c, n);
        }
}

/* Point or direction x (as mb_vertex stored it) turned by rot (row-major
 * 3 x 3, NULL: none) and times scale. */
static void mb_place(const float x[3], const double *rot, double scale, double out[3])
{
    for (int r = 0; r < 3; r++) {
        out[r] = rot ? 0.0 : (double)x[r] * scale;
        if (rot)
            for (int c = 0; c < 3; c++) out[r] += rot[3 * r + c] * (double)x[c] * scale;
    }
}

static hl_mesh *mb_mesh(hl_context *ctx, const mesh_build *b, double scale, const double *rot)
{
    float *P = xmalloc((size_t)b->nv * 12), *Nn = xmalloc((size_t)b->nv * 12);
    for (uint32_t i = 0; i < b->nv; i++) {
        double p[3], n[3];
        mb_place(b->P + 3 * i, rot, scale, p);
        mb_place(b->Nn + 3 * i, rot, 1.0, n);
        for (int q = 0; q < 3; q++) P[3 * i + q] = (float)p[q], Nn[3 * i + q] = (float)n[q];
    }
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_create(ctx, b->nv, P, Nn, NULL, b->nt, b->I, &m);
    free(P);
    free(Nn);
    if (r != HL_OK) {
        fprintf(stderr, "hl_mesh_create: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    return m;
}

/* The mesh vertex that mb_mesh made of the builder's vertex at p with
 * normal n (both given in unit scale, unturned). */
static uint32_t find_vertex(const hl_mesh *m, const double p[3], const double n[3], double scale, const double *rot)
{
    const float pf[3] = {(float)p[0], (float)p[1], (float)p[2]}, nf[3] = {(float)n[0], (float)n[1], (float)n[2]};
    double pw[3], nw[3];
    mb_place(pf, rot, scale, pw);
    mb_place(nf, rot, 1.0, nw);
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        const float *q = m->positions + 3 * (size_t)v, *nn = m->normals + 3 * (size_t)v;
        int same = 1;
        for (int k = 0; k < 3; k++) same &= q[k] == (float)pw[k] && fabs(nn[k] - nw[k]) < 1e-6;
        if (same) return v;
    }
    fprintf(stderr, "vertex not found\n");
    exit(1);
}

/* A thin slab, a contact and a crease, each with a receiver vertex closer
 * to other geometry than the old default offset (1e-3 of the bounding-box
 * diagonal), and far more than the robust one:
 *   slab     a receiver (normal +Y) under a closed slab 2 x 2e-4 x 2 that
 *            hovers 2e-4 above it; the slab's underside hides all but a
 *            grazing band
 *   contact  the centre of a unit cube's underside (normal -Y) resting
 *            2e-4 above an 8 x 8 ground: the ground hides almost all
 *   crease   a vertex 0.01 from the apex of a 10 degree V-groove (normal
 *            +Y), the other wall 1.76e-3 across
 * The exact B (white light, albedo 1) is 1 minus the Lambert form factor
 * of the one occluding polygon, wholly above the receiver's horizon. */
typedef struct offset_scene {
    const char *name;
    mesh_build b;
    double rp[3], rn[3]; /* the receiver */
    double poly[3 * 4];  /* the occluder */
} offset_scene;

static void make_offset_scenes(offset_scene *sc)
{
    const double g = 2e-4, t = 2e-4, r = 1e-5;
    /* slab */
    offset_scene *s = &sc[0];
    memset(s, 0, sizeof *s);
    s->name = "thin slab";
    mb_vertex(&s->b, 0, 0, 0, 0, 1, 0);
    mb_vertex(&s->b, 0, 0, r, 0, 1, 0);
    mb_vertex(&s->b, r, 0, 0, 0, 1, 0);
    mb_tri(&s->b, 0, 1, 2);
    mb_box(&s->b, (const double[3]){-1, g, -1}, (const double[3]){1, g + t, 1});
    const double slab[12] = {-1, g, -1, 1, g, -1, 1, g, 1, -1, g, 1};
    memcpy(s->poly, slab, sizeof slab);
    s->rp[0] = s->rp[1] = s->rp[2] = 0.0, s->rn[0] = 0, s->rn[1] = 1, s->rn[2] = 0;
    /* contact: the cube's underside is a fan about its centre */
    s = &sc[1];
    memset(s, 0, sizeof *s);
    s->name = "contact";
    mb_box(&s->b, (const double[3]){-0.5, g, -0.5}, (const double[3]){0.5, g + 1.0, 0.5});
    const double ground[4][3] = {{-4, 0, -4}, {-4, 0, 4}, {4, 0, 4}, {4, 0, -4}};
    mb_quad_fan(&s->b, ground, (const double[3]){0, 1, 0});
    for (int k = 0; k < 4; k++) memcpy(s->poly + 3 * k, ground[k], sizeof ground[k]);
    s->rp[0] = 0, s->rp[1] = g, s->rp[2] = 0, s->rn[0] = 0, s->rn[1] = -1, s->rn[2] = 0;
    /* crease: wall A (y = 0) as a fan about the receiver, wall B turned
       10 degrees about the apex line (the z axis) */
    s = &sc[2];
    memset(s, 0, sizeof *s);
    s->name = "crease";
    const double sx = 0.01, L = 2.0, th = 10.0 * PI / 180.0;
    const double A[4][3] = {{0, 0, -L}, {0, 0, L}, {1, 0, L}, {1, 0, -L}};
    uint32_t a[4], rv = mb_vertex(&s->b, sx, 0, 0, 0, 1, 0);
    for (int k = 0; k < 4; k++) a[k] = mb_vertex(&s->b, A[k][0], A[k][1], A[k][2], 0, 1, 0);
    /* the receiver on wall A's edge x = sx: fan to the corners */
    mb_tri(&s->b, rv, a[0], a[1]);
    mb_tri(&s->b, rv, a[1], a[2]);
    mb_tri(&s->b, rv, a[2], a[3]);
    mb_tri(&s->b, rv, a[3], a[0]);
    const double Bw[4][3] = {{0, 0, -L}, {cos(th), sin(th), -L}, {cos(th), sin(th), L}, {0, 0, L}};
    const double nb[3] = {sin(th), -cos(th), 0};
    uint32_t bq[4];
    for (int k = 0; k < 4; k++) bq[k] = mb_vertex(&s->b, Bw[k][0], Bw[k][1], Bw[k][2], nb[0], nb[1], nb[2]);
    mb_tri(&s->b, bq[0], bq[1], bq[2]);
    mb_tri(&s->b, bq[0], bq[2], bq[3]);
    for (int k = 0; k < 4; k++) memcpy(s->poly + 3 * k, Bw[k], sizeof Bw[k]);
    s->rp[0] = sx, s->rp[1] = 0, s->rp[2] = 0, s->rn[0] = 0, s->rn[1] = 1, s->rn[2] = 0;
}

/* B of one vertex (white light, albedo 1) from its Embree visibility. */
static double vertex_B(hl_context *ctx, hl_rt *rt, const hl_geom *g, const hl_mesh *m, uint32_t v, uint32_t S,
                       float offset, const float *L, const float *WL)
{
    uint8_t *vis = xmalloc(g->ncube);
    if (hl_rt_visibility(rt, g, m, v, 1, S, offset, vis, NULL) != HL_OK) {
        fprintf(stderr, "hl_rt_visibility: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    double direct;
    double B = stages_B(g, vis, S, m->normals + 3 * (size_t)v, L, WL, &direct, NULL);
    free(vis);
    return B;
}

/* B of one vertex (white light, albedo 1) from rays that start on the
 * vertex itself and skip its own triangles (hl_rt_occluded_from_vertex,
 * bench's continuous reference): the cosine-weighted hemisphere on a
 * latitude-longitude grid of 1024 x 512 cells, in double. */
static double vertex_B_own(hl_context *ctx, hl_rt *rt, const hl_mesh *m, uint32_t v)
{
    const uint32_t W = 1024, H = 512;
    const float *n = m->normals + 3 * (size_t)v;
    float *dir = xmalloc((size_t)W * H * 12);
    double *w = xmalloc((size_t)W * H * sizeof *w);
    uint8_t *occ = xmalloc((size_t)W * H);
    uint32_t cnt = 0;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            const double th = PI * (y + 0.5) / H, ph = 2.0 * PI * (x + 0.5) / W;
            const double d[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
            const double c = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
            if (c <= 0.0) continue;
            for (int q = 0; q < 3; q++) dir[3 * (size_t)cnt + q] = (float)d[q];
            w[cnt++] = c * 2.0 * PI / W * (cos(PI * y / H) - cos(PI * (y + 1) / H)) / PI;
        }
    if (hl_rt_occluded_from_vertex(rt, v, cnt, dir, occ) != HL_OK) {
        fprintf(stderr, "hl_rt_occluded_from_vertex: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    double B = 0.0;
    for (uint32_t i = 0; i < cnt; i++) B += occ[i] ? 0.0 : w[i];
    free(dir);
    free(w);
    free(occ);
    return B;
}

/* Rays of vertex v in texels wholly above its horizon (centre more than
 * two texel widths up) that something blocked. */
static uint32_t blocked_above(hl_context *ctx, hl_rt *rt, const hl_geom *g, const hl_mesh *m, uint32_t v)
{
    uint8_t *vis = xmalloc(g->ncube);
    if (hl_rt_visibility(rt, g, m, v, 1, 1, 0.0f, vis, NULL) != HL_OK) {
        fprintf(stderr, "hl_rt_visibility: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    const float *n = m->normals + 3 * (size_t)v;
    uint32_t blocked = 0;
    for (uint32_t c = 0; c < g->ncube; c++) {
        const float *d = g->cube_dirs + 4 * (size_t)c;
        float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if ((d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) / len > 4.0f / (float)g->C) blocked += vis[c] == 0;
    }
    free(vis);
    return blocked;
}

/* The cases' turn: 37 degrees about (1, 2, 3), so that no face of an
 * axis-aligned box stays normal to an axis (Rodrigues' formula). */
static void test_turn(double turn[9])
{
    double ax[3] = {1, 2, 3}, an = 37.0 * PI / 180.0, c = cos(an), s1 = sin(an);
    normalize3(ax);
    const double x = ax[0], y = ax[1], z = ax[2];
    const double R9[9] = {c + x * x * (1 - c),     x * y * (1 - c) - z * s1, x * z * (1 - c) + y * s1,
                          y * x * (1 - c) + z * s1, c + y * y * (1 - c),     y * z * (1 - c) - x * s1,
                          z * x * (1 - c) - y * s1, z * y * (1 - c) + x * s1, c + z * z * (1 - c)};
    memcpy(turn, R9, sizeof R9);
}

static void case_ray_offset(void)
{
    hl_context *ctx = make_ctx();
    char what[256];
    const uint32_t R = 64, S = 4;
    hl_geom *g = make_geom(ctx, R, R);
    float *L = xmalloc((size_t)g->ncoef * sizeof *L), *WL = xmalloc((size_t)g->ncoef * sizeof *WL);
    unit_light(g, L);
    haar_of(g, L, WL);
    /* the discretisation at C = N = 64, S = 4 of a polygon edge: the cap
       case's bound sin(2 alpha) / (pi N) at its worst, plus 3 sigma */
    const double tol = 0.01;
    offset_scene *sc = xcalloc(3, sizeof *sc);
    make_offset_scenes(sc);
    static const double scales[3] = {1e-3, 1.0, 1e4};
    double worst_new = 0.0, least_old = INFINITY;
    for (int k = 0; k < 3; k++)
        for (int is = 0; is < 3; is++) {
            const double scale = scales[is];
            hl_mesh *m = mb_mesh(ctx, &sc[k].b, scale, NULL);
            hl_rt *rt = NULL;
            if (hl_rt_create_filtered(ctx, m, &rt) != HL_OK) exit(1);
            const uint32_t v = find_vertex(m, sc[k].rp, sc[k].rn, scale, NULL);
            double poly[12], o[3];
            for (int q = 0; q < 12; q++) poly[q] = sc[k].poly[q] * scale;
            for (int q = 0; q < 3; q++) o[q] = (double)m->positions[3 * (size_t)v + q];
            const double exact = 1.0 - polygon_form_factor(poly, 4, o, sc[k].rn);
            const float old_offset = 1e-3f * hl_mesh_query_diagonal(m);
            const double B_new = vertex_B(ctx, rt, g, m, v, S, 0.0f, L, WL);
            const double B_old = vertex_B(ctx, rt, g, m, v, S, old_offset, L, WL);
            printf("ray offset, %-9s x %g: exact B %.6f; robust offset (%.3g) B %.6f, error %+.3g; old default "
                   "(%.3g) B %.6f, error %+.3g\n",
                   sc[k].name, scale, exact, (double)hl_rt_robust_offset(rt, v), B_new, B_new - exact,
                   (double)old_offset, B_old, B_old - exact);
            snprintf(what, sizeof what, "ray offset, %s x %g: robust offset |B - exact|", sc[k].name, scale);
            hl_check_error(what, fabs(B_new - exact), tol);
            /* bench's continuous reference, which has no offset at all */
            const double B_own = vertex_B_own(ctx, rt, m, v);
            printf("ray offset, %-9s x %g: rays from the vertex itself (its own triangles skipped) B %.6f, "
                   "error %+.3g\n", sc[k].name, scale, B_own, B_own - exact);
            snprintf(what, sizeof what, "ray offset, %s x %g: rays from the vertex itself |B - exact|", sc[k].name,
                     scale);
            hl_check_error(what, fabs(B_own - exact), tol);
            worst_new = fmax(worst_new, fabs(B_new - exact));
            least_old = fmin(least_old, fabs(B_old - exact));
            hl_rt_destroy(rt);
            hl_mesh_destroy(m);
        }
    /* End to end: hl_precompute's default is the robust offset (the
       contact scene at unit scale, through the transport file) */
    {
        char path[1024];
        snprintf(path, sizeof path, "%s/analytic_offset_%ld.hlt", hl_test_env("HL_TMP", "."), (long)getpid());
        hl_mesh *m = mb_mesh(ctx, &sc[1].b, 1.0, NULL);
        const uint32_t v = find_vertex(m, sc[1].rp, sc[1].rn, 1.0, NULL);
        double o[3];
        for (int q = 0; q < 3; q++) o[q] = (double)m->positions[3 * (size_t)v + q];
        const double exact = 1.0 - polygon_form_factor(sc[1].poly, 4, o, sc[1].rn);
        hl_precompute_desc d = {.N = R, .C = R, .supersample = S, .rule = HL_TRUNC_ALL};
        hl_transport *t = NULL;
        hl_result r = hl_precompute(ctx, m, &d, path, NULL);
        if (r == HL_OK) r = hl_transport_load(ctx, path, &t);
        HL_CHECK(r == HL_OK, "precompute: %s", hl_context_last_error(ctx));
        remove(path);
        if (t) {
            float *dense = xmalloc((size_t)g->ncoef * sizeof *dense);
            hl_transport_query_row(t, v, dense);
            const double B = dot_ff(dense, WL, g->ncoef);
            printf("ray offset, contact through hl_precompute's default (file offset %g): B %.6f, exact %.6f\n",
                   (double)t->info.ray_offset, B, exact);
            hl_check_error("ray offset, contact through hl_precompute's default: |B - exact|", fabs(B - exact), tol);
            HL_CHECK(t->info.ray_offset == 0.0f, "the file must record the robust offset as 0");
            free(dense);
            hl_transport_destroy(t);
        }
        hl_mesh_destroy(m);
    }
    /* the scenes must tell the two apart, or they test nothing */
    printf("ray offset: worst error with the robust offset %.3g, least with the old default %.3g\n", worst_new,
           least_old);
    snprintf(what, sizeof what, "ray offset: the old default's least error (%.3g) must exceed the tolerance "
             "(the scenes show its leak)", least_old);
    hl_check_error(what, least_old > tol ? 0.0 : 1.0, 0.0);

    /* No self-shadowing (acne) with the robust offset: a tessellated plane
     * and, on its own, a closed box, far from the origin, at every scale,
     * as built and turned 37 degrees about (1, 2, 3) (faces that no axis
     * is normal to): no ray of a vertex inside a face may be blocked above
     * its horizon. (Origins exactly on the vertices block 4e5 such rays.) */
    uint32_t acne = 0, checked = 0;
    static const double shifts[3] = {0.0, 100.0, 1e4};
    double turn[9];
    test_turn(turn);
    for (int is = 0; is < 3; is++)
        for (int ish = 0; ish < 3; ish++)
            for (int shape = 0; shape < 4; shape++) {
                const double *rot = shape >= 2 ? turn : NULL;
                mesh_build *b = xcalloc(1, sizeof *b);
                const double sh = shifts[ish];
                if (shape % 2 == 0)
                    for (int i = 0; i < 6; i++)
                        for (int j = 0; j < 6; j++) {
                            const double x0 = sh - 1.0 + i / 3.0, z0 = -1.0 + j / 3.0, x1 = x0 + 1 / 3.0,
                                         z1 = z0 + 1 / 3.0;
                            const double c[4][3] = {{x0, 0, z0}, {x0, 0, z1}, {x1, 0, z1}, {x1, 0, z0}};
                            mb_quad_fan(b, c, (const double[3]){0, 1, 0});
                        }
                else
                    mb_box(b, (const double[3]){sh - 0.5, 3.0, -0.5}, (const double[3]){sh + 0.5, 4.0, 0.5});
                hl_mesh *m = mb_mesh(ctx, b, scales[is], rot);
                hl_rt *rt = NULL;
                if (hl_rt_create(ctx, m, &rt) != HL_OK) exit(1);
                uint32_t here = 0;
                /* the fans' centres: every fifth vertex made (four corners,
                   then the centre), whose normal is its face's */
                for (uint32_t i = 4; i < b->nv; i += 5) {
                    const double p[3] = {b->P[3 * i], b->P[3 * i + 1], b->P[3 * i + 2]};
                    const double n[3] = {b->Nn[3 * i], b->Nn[3 * i + 1], b->Nn[3 * i + 2]};
                    here += blocked_above(ctx, rt, g, m, find_vertex(m, p, n, scales[is], rot));
                    checked++;
                }
                printf("ray offset, acne: %s%s %g from the origin, x %g: %u rays above the horizon blocked\n",
                       shape % 2 ? "box" : "plane", rot ? " (turned)" : "", sh * scales[is], scales[is], here);
                acne += here;
                hl_rt_destroy(rt);
                hl_mesh_destroy(m);
                free(b);
            }
    snprintf(what, sizeof what, "ray offset, acne: rays above the horizon blocked at %u face vertices", checked);
    hl_check_error(what, (double)acne, 0.0);
    free(sc);
    free(L);
    free(WL);
    hl_geom_destroy(g);
    hl_context_destroy(ctx);
}

/* A receiver at the foot of a step: a ground vertex (normal +Y) on the
 * bottom edge of a closed box's +X face, the box over x < 0. The face and
 * the ground share no vertex (their normals differ, as at the truck's
 * door recess and window trim), and the offset along +Y runs in the
 * face's plane, so every ray met the face at t = 0 and B was 0. The box
 * hides exactly the half of the hemisphere with x < 0 (a ray into it is
 * inside the box at once and leaves through its far side): B = 1/2, at
 * three scales, as built and turned 37 degrees about (1, 2, 3), through
 * the offset rays and the rays from the vertex itself. */
static void case_ray_step(void)
{
    hl_context *ctx = make_ctx();
    char what[256];
    const uint32_t R = 64, S = 4;
    hl_geom *g = make_geom(ctx, R, R);
    float *L = xmalloc((size_t)g->ncoef * sizeof *L), *WL = xmalloc((size_t)g->ncoef * sizeof *WL);
    unit_light(g, L);
    haar_of(g, L, WL);
    const double tol = 0.01, exact = 0.5, Lz = 2.0;
    mesh_build *b = xcalloc(1, sizeof *b);
    const uint32_t rv = mb_vertex(b, 0, 0, 0, 0, 1, 0);
    const double A[4][3] = {{0, 0, -Lz}, {0, 0, Lz}, {2, 0, Lz}, {2, 0, -Lz}};
    uint32_t a[4];
    for (int k = 0; k < 4; k++) a[k] = mb_vertex(b, A[k][0], A[k][1], A[k][2], 0, 1, 0);
    mb_tri(b, rv, a[1], a[2]);
    mb_tri(b, rv, a[2], a[3]);
    mb_tri(b, rv, a[3], a[0]);
    mb_box(b, (const double[3]){-1.0, 0.0, -1.0}, (const double[3]){0.0, 0.3, 1.0});
    double turn[9];
    test_turn(turn);
    static const double scales[3] = {1e-3, 1.0, 1e4};
    for (int is = 0; is < 3; is++)
        for (int t = 0; t < 2; t++) {
            const double *rot = t ? turn : NULL;
            hl_mesh *m = mb_mesh(ctx, b, scales[is], rot);
            hl_rt *rt = NULL;
            if (hl_rt_create_filtered(ctx, m, &rt) != HL_OK) exit(1);
            const uint32_t v = find_vertex(m, (const double[3]){0, 0, 0}, (const double[3]){0, 1, 0}, scales[is], rot);
            const double B = vertex_B(ctx, rt, g, m, v, S, 0.0f, L, WL), B_own = vertex_B_own(ctx, rt, m, v);
            printf("ray step%s x %g: exact B %.6f; robust offset B %.6f, error %+.3g; from the vertex itself B %.6f, "
                   "error %+.3g\n", rot ? " (turned)" : "", scales[is], exact, B, B - exact, B_own, B_own - exact);
            snprintf(what, sizeof what, "ray step%s x %g: robust offset |B - exact|", rot ? " (turned)" : "", scales[is]);
            hl_check_error(what, fabs(B - exact), tol);
            snprintf(what, sizeof what, "ray step%s x %g: from the vertex itself |B - exact|", rot ? " (turned)" : "",
                     scales[is]);
            hl_check_error(what, fabs(B_own - exact), tol);
            hl_rt_destroy(rt);
            hl_mesh_destroy(m);
        }
    free(b);
    free(L);
    free(WL);
    hl_geom_destroy(g);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"offset", case_ray_offset},
        {"step", case_ray_step},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
