/* test_shadow_raster.c - orthographic shadow maps of rigid objects
 * (kernels/dynamic/shadow_raster.cl, its twin host/src/dynamic/twins/
 * shadow_raster.c, the module shadow_map.c and visibility/instances.c),
 * suite "shadow_raster".
 *
 * twin       the OpenCL rasteriser against its twin, bunny and ground,
 *            several lights, before and after a motion: bit-identical.
 * analytic   two tilted squares: depth at texel centres against the
 *            ray-plane intersection in double; centres outside are empty;
 *            all three ways (OpenCL, twin, Embree). Then the coverage
 *            rule on a square whose edges pass exactly through centres.
 * embree     rasteriser against Embree rays on the bunny and ground:
 *            the texels that differ are few and lie on projected edges.
 * motion     a rigid motion by hl_shadow_maps_set_transform against the
 *            vertices moved by hand, both methods; Embree builds no BVH.
 * frame      fitted frames hold every vertex, depths in (0, 1), for +Y,
 *            -Y, the horizon and random lights; the border ring is empty.
 * bad_input  clear errors for impossible objects, transforms, R, lights.
 *
 * Every check prints its tolerance and worst error (hl_check_error).
 * Depends on: haarlight_core, shadow_map.h, shadow_scene.h, HL_REPO_DATA
 * (bunny_lowres). The flat-body cases are test_shadow_skip.c's.
 */
#include <float.h>
#include <stdint.h>

#include "hl_test.h"
#include "hl_internal.h"
#include "shadow_map.h"
#include "shadow_scene.h"

/* ================================================================= twin */

static void twin_compare(const char *what, const float *a, const float *b, size_t n)
{
    size_t mism, cov;
    double worst;
    compare_maps(a, b, n, &mism, &worst, &cov);
    char w[128];
    /* Same float operations in the same order, contraction off, and the
       program asks for correctly rounded division where the device has it
       (PoCL does): the maps must be bit-identical. */
    snprintf(w, sizeof w, "%s: depth, OpenCL vs twin", what);
    hl_check_error(w, worst, 0.0);
    snprintf(w, sizeof w, "%s: texels covered by one only", what);
    hl_check_error(w, (double)mism, 0.0);
    HL_CHECK(cov > n / 10, "%s: only %zu of %zu texels covered", what, cov, n);
}

static void case_twin(void)
{
    hl_context *cl = hl_test_cl_context(2), *ref = ref_ctx();
    HL_CHECK(cl != NULL, "no OpenCL device");
    scene s;
    if (!cl || !scene_load(ref, &s)) { HL_CHECK(0, "setup failed"); hl_context_destroy(cl); hl_context_destroy(ref); return; }
    enum { K = 8 };
    float dirs[K][3];
    light_dirs(dirs, K);
    size_t n = (size_t)K * R_TEST * R_TEST;
    float *a = malloc(n * 4), *b = malloc(n * 4);
    hl_shadow_maps *sc = NULL, *sr = NULL;
    HL_CHECK(hl_shadow_maps_create(cl, s.obj, 2, R_TEST, HL_SHADOW_RASTER, &sc) == HL_OK, "%s", hl_context_last_error(cl));
    HL_CHECK(hl_shadow_maps_create(ref, s.obj, 2, R_TEST, HL_SHADOW_RASTER, &sr) == HL_OK, "%s", hl_context_last_error(ref));
    if (sc && sr) {
        HL_CHECK(hl_shadow_maps_render(sc, (const float(*)[3])dirs, K, a, NULL) == HL_OK, "%s", hl_context_last_error(cl));
        HL_CHECK(hl_shadow_maps_render(sr, (const float(*)[3])dirs, K, b, NULL) == HL_OK, "%s", hl_context_last_error(ref));
        twin_compare("bunny and ground, 8 lights", a, b, n);
        const double axis[3] = {0.0, 1.0, 0.0}, t[3] = {0.05, 0.0, -0.02};
        float xf[12];
        make_xf(axis, 0.9, t, xf);
        HL_CHECK(hl_shadow_maps_set_transform(sc, 0, xf) == HL_OK, "%s", hl_context_last_error(cl));
        HL_CHECK(hl_shadow_maps_set_transform(sr, 0, xf) == HL_OK, "%s", hl_context_last_error(ref));
        HL_CHECK(hl_shadow_maps_render(sc, (const float(*)[3])dirs, K, a, NULL) == HL_OK, "%s", hl_context_last_error(cl));
        HL_CHECK(hl_shadow_maps_render(sr, (const float(*)[3])dirs, K, b, NULL) == HL_OK, "%s", hl_context_last_error(ref));
        twin_compare("bunny turned and moved", a, b, n);
        /* the ground left out of the maps it cannot shadow: the masks
           travel to the kernel as bits in the frame's last float */
        hl_shadow_maps_skip_planes(sc, 1);
        hl_shadow_maps_skip_planes(sr, 1);
        HL_CHECK(hl_shadow_maps_render(sc, (const float(*)[3])dirs, K, a, NULL) == HL_OK, "%s", hl_context_last_error(cl));
        HL_CHECK(hl_shadow_maps_render(sr, (const float(*)[3])dirs, K, b, NULL) == HL_OK, "%s", hl_context_last_error(ref));
        twin_compare("flat ground left out", a, b, n);
    }
    hl_shadow_maps_destroy(sc); hl_shadow_maps_destroy(sr); free(a); free(b); scene_free(&s); hl_context_destroy(cl);
    hl_context_destroy(ref);
}

/* ============================================================= analytic */

/* Two squares, each two triangles of side 2 h in its own x-z plane: a
 * small one tilted above a larger one. */
typedef struct square { float pos[12]; uint32_t tri[6]; } square;

static void make_square(square *q, float h)
{
    const float p[12] = {-h, 0, -h, h, 0, -h, h, 0, h, -h, 0, h};
    const uint32_t t[6] = {0, 1, 2, 0, 2, 3};
    memcpy(q->pos, p, sizeof p);
    memcpy(q->tri, t, sizeof t);
}

/* The world point of texel (i, j)'s centre, in double. */
static void texel_centre(const hl_shadow_frame *f, uint32_t i, uint32_t j, double *c)
{
    double fx = ((double)i + 0.5) / f->R * f->width, fy = ((double)j + 0.5) / f->R * f->height;
    for (int k = 0; k < 3; k++) c[k] = (double)f->origin[k] + fx * f->right[k] + fy * f->up[k];
}

/* Depth of the first square hit along the texel's ray, 1 for none, or -1
 * where a centre lies within 0.01 texel of a square's edge (skipped). */
static double square_depth(const hl_shadow_frame *f, const hl_dyn_object *o, const float *h, int nsq, uint32_t i, uint32_t j)
{
    double c[3], best = 1.0;
    texel_centre(f, i, j, c);
    for (int q = 0; q < nsq; q++) {
        const float *x = o[q].xf;
        double P[3] = {x[3], x[7], x[11]}, n[3] = {x[1], x[5], x[9]}, e1[3] = {x[0], x[4], x[8]}, e2[3] = {x[2], x[6], x[10]};
        double fn = 0, pn = 0;
        for (int k = 0; k < 3; k++) { fn += f->toward_far[k] * n[k]; pn += (P[k] - c[k]) * n[k]; }
        double s = pn / fn, a = 0, b = 0;
        for (int k = 0; k < 3; k++) {
            double hk = c[k] + s * f->toward_far[k] - P[k];
            a += hk * e1[k];
            b += hk * e2[k];
        }
        double tol = 0.01 * f->width / f->R / fabs(fn), m = fmax(fabs(a), fabs(b));
        if (fabs(m - h[q]) < tol) return -1.0;
        if (m < h[q]) best = fmin(best, s / f->depth_range);
    }
    return best;
}

static void analytic_one(hl_context *ctx, hl_shadow_method m, const char *name, const hl_dyn_object *o, const float *h,
                         const float (*dirs)[3], uint32_t K)
{
    hl_shadow_frame fr[8];
    float *d = render(ctx, o, 2, m, dirs, K, fr);
    HL_CHECK(d != NULL, "%s: render failed", name);
    if (!d) return;
    double worst = 0.0;
    size_t inside = 0, outside = 0, wrong_empty = 0;
    for (uint32_t k = 0; k < K; k++)
        for (uint32_t j = 0; j < R_TEST; j++)
            for (uint32_t i = 0; i < R_TEST; i++) {
                double want = square_depth(&fr[k], o, h, 2, i, j);
                float got = d[((size_t)k * R_TEST + j) * R_TEST + i];
                if (want < 0.0) continue;
                if (want >= 1.0) {
                    outside++;
                    if (got != HL_SHADOW_EMPTY) wrong_empty++;
                    continue;
                }
                inside++;
                double e = fabs((double)got - want);
                if (!(e <= worst)) worst = e;
            }
    char w[160];
    /* A vertex's depth goes through about eight float roundings of values
       up to the scene's size (transform, frame subtraction, dot product,
       scale), each half an ulp of the normalised depth or less, and the
       interpolation a few more: 8 epsilon (measured: about 2.3). */
    snprintf(w, sizeof w, "%s: depth at %zu covered centres against the ray-plane hit", name, inside);
    hl_check_error(w, worst, 8.0 * FLT_EPSILON);
    snprintf(w, sizeof w, "%s: of %zu centres outside both squares, not empty", name, outside);
    hl_check_error(w, (double)wrong_empty, 0.0);
    HL_CHECK(inside > 1000 && outside > 1000, "%s: %zu inside, %zu outside: the scene misses the maps", name, inside, outside);
    free(d);
}

/* The coverage rule on exact numbers: a square of side 2 seen from +Y in
 * a frame of 1/64 texels shifted by half a texel, so its four edges and
 * its diagonal pass exactly through texel centres. The top-left rule
 * covers the left column (x = 64.5) and the top row (y = 192.5), not the
 * right and bottom ones: 128 x 128 texels, and no hole on the diagonal
 * the two triangles share. Embree's tie rule is its own: only its
 * interior (no hole on the diagonal) is checked. */
static void edge_rule(hl_context *ctx, hl_shadow_method m, const char *name)
{
    square q;
    make_square(&q, 1.0f);
    hl_dyn_object o = {.pos = q.pos, .nverts = 4, .tri = q.tri, .ntris = 2};
    memcpy(o.xf, XF_ID, 48);
    const float lo = -2.0078125f; /* -2 - half a texel of 1/64 */
    hl_shadow_frame f = {.origin = {lo, 1.0f, lo}, .right = {1, 0, 0}, .up = {0, 0, 1}, .toward_far = {0, -1, 0},
                         .width = 4.0f, .height = 4.0f, .depth_range = 2.0f, .R = R_TEST};
    hl_shadow_maps *sm = NULL;
    float *d = malloc((size_t)R_TEST * R_TEST * 4);
    HL_CHECK(hl_shadow_maps_create(ctx, &o, 1, R_TEST, m, &sm) == HL_OK, "%s", hl_context_last_error(ctx));
    if (sm && hl_shadow_maps_render_in(sm, &f, 1, d) == HL_OK) {
        size_t count = 0, rule = 0, holes = 0;
        for (uint32_t j = 0; j < R_TEST; j++)
            for (uint32_t i = 0; i < R_TEST; i++) {
                int cov = d[(size_t)j * R_TEST + i] < HL_SHADOW_EMPTY;
                count += (size_t)cov;
                int want = i >= 64 && i <= 191 && j >= 65 && j <= 192;
                rule += (size_t)(cov != want);
                if (i > 64 && i < 192 && j > 64 && j < 192) holes += (size_t)!cov;
            }
        char w[160];
        snprintf(w, sizeof w, "%s: uncovered centres inside the square (the shared diagonal among them)", name);
        hl_check_error(w, (double)holes, 0.0);
        printf("%s: %zu centres covered (128 x 128 = 16384 under the top-left rule)\n", name, count);
        if (m == HL_SHADOW_RASTER) {
            snprintf(w, sizeof w, "%s: centres against the top-left rule", name);
            hl_check_error(w, (double)rule, 0.0);
        }
    } else
        HL_CHECK(0, "%s: %s", name, hl_context_last_error(ctx));
    hl_shadow_maps_destroy(sm); free(d);
}

static void case_analytic(void)
{
    square a, b;
    make_square(&a, 1.0f);
    make_square(&b, 2.0f);
    const float h[2] = {1.0f, 2.0f};
    hl_dyn_object o[2] = {{.pos = a.pos, .nverts = 4, .tri = a.tri, .ntris = 2},
                          {.pos = b.pos, .nverts = 4, .tri = b.tri, .ntris = 2}};
    const double ax[3] = {1, 0, 0}, az[3] = {0.0, 0.6, 0.8}, ta[3] = {0.3, 1.0, -0.2}, tb[3] = {0, 0, 0};
    make_xf(ax, 0.5, ta, o[0].xf);
    make_xf(az, 0.2, tb, o[1].xf);
    float dirs[4][3] = {{0, 1, 0}, {0, -1, 0}, {0.3f, 0.9f, 0.3f}, {0.2f, -0.3f, -0.93f}};
    for (int k = 0; k < 4; k++) unit3(dirs[k]);
    hl_context *ref = ref_ctx(), *cl = hl_test_cl_context(2);
    analytic_one(ref, HL_SHADOW_RASTER, "twin", o, h, (const float(*)[3])dirs, 4);
    analytic_one(ref, HL_SHADOW_EMBREE, "Embree", o, h, (const float(*)[3])dirs, 4);
    HL_CHECK(cl != NULL, "no OpenCL device");
    if (cl) analytic_one(cl, HL_SHADOW_RASTER, "OpenCL", o, h, (const float(*)[3])dirs, 4);
    edge_rule(ref, HL_SHADOW_RASTER, "edge rule, twin");
    edge_rule(ref, HL_SHADOW_EMBREE, "edge rule, Embree");
    if (cl) edge_rule(cl, HL_SHADOW_RASTER, "edge rule, OpenCL");
    hl_context_destroy(cl); hl_context_destroy(ref);
}

/* ================================================================ embree */

/* Distance in texels from texel (i, j)'s centre to the nearest projected
 * triangle edge of the objects (world positions in double). */
static double edge_distance(const hl_shadow_frame *f, const hl_dyn_object *o, uint32_t nobj, uint32_t i, uint32_t j)
{
    double px = (double)i + 0.5, py = (double)j + 0.5, best = INFINITY;
    for (uint32_t q = 0; q < nobj; q++)
        for (uint32_t t = 0; t < o[q].ntris; t++) {
            double v[3][2];
            for (int k = 0; k < 3; k++) {
                const float *p = o[q].pos + 3 * (size_t)o[q].tri[3 * (size_t)t + k], *x = o[q].xf;
                double w[3], r = 0, u = 0;
                for (int c = 0; c < 3; c++) w[c] = (double)x[4 * c] * p[0] + (double)x[4 * c + 1] * p[1] + (double)x[4 * c + 2] * p[2] + x[4 * c + 3] - f->origin[c];
                for (int c = 0; c < 3; c++) { r += w[c] * f->right[c]; u += w[c] * f->up[c]; }
                v[k][0] = r / f->width * f->R;
                v[k][1] = u / f->height * f->R;
            }
            for (int k = 0; k < 3; k++) {
                const double *a = v[k], *b = v[(k + 1) % 3];
                double dx = b[0] - a[0], dy = b[1] - a[1], L = dx * dx + dy * dy;
                double s = L > 0 ? ((px - a[0]) * dx + (py - a[1]) * dy) / L : 0.0;
                s = s < 0 ? 0 : s > 1 ? 1 : s;
                double ex = a[0] + s * dx - px, ey = a[1] + s * dy - py;
                best = fmin(best, sqrt(ex * ex + ey * ey));
            }
        }
    return best;
}

/* Depths closer than this agree: 1e-4 of the depth range is ~1000 times
 * either method's rounding and far below any gap the next stage sees. */
#define DEPTH_AGREE 1e-4

static void case_embree(void)
{
    hl_context *ref = ref_ctx();
    scene s;
    if (!scene_load(ref, &s)) { HL_CHECK(0, "setup failed"); hl_context_destroy(ref); return; }
    enum { K = 6 };
    float dirs[K][3];
    light_dirs(dirs, K);
    hl_shadow_frame fr[K], fe[K];
    float *a = render(ref, s.obj, 2, HL_SHADOW_RASTER, (const float(*)[3])dirs, K, fr);
    float *b = render(ref, s.obj, 2, HL_SHADOW_EMBREE, (const float(*)[3])dirs, K, fe);
    HL_CHECK(a && b, "render failed");
    if (a && b) {
        HL_CHECK(memcmp(fr, fe, sizeof fr) == 0, "the two methods fitted different frames");
        size_t differ = 0, covered = 0;
        double worst_dist = 0.0, worst_depth = 0.0;
        for (uint32_t k = 0; k < K; k++)
            for (uint32_t j = 0; j < R_TEST; j++)
                for (uint32_t i = 0; i < R_TEST; i++) {
                    size_t x = ((size_t)k * R_TEST + j) * R_TEST + i;
                    if (a[x] < HL_SHADOW_EMPTY || b[x] < HL_SHADOW_EMPTY) covered++;
                    double e = fabs((double)a[x] - (double)b[x]);
                    if (e <= DEPTH_AGREE) { worst_depth = fmax(worst_depth, e); continue; }
                    differ++;
                    worst_dist = fmax(worst_dist, edge_distance(&fr[k], s.obj, 2, i, j));
                }
        double frac = covered ? (double)differ / (double)covered : 1.0;
        printf("raster vs Embree: %zu of %zu covered texels differ by more than %g\n", differ, covered, DEPTH_AGREE);
        hl_check_error("raster vs Embree: depth where both agree within 1e-4", worst_depth, DEPTH_AGREE);
        /* a centre the two methods classify differently lies on a
           projected edge to within both methods' rounding (coordinates of
           a few hundred texels carry ~1e-5 texel of error) */
        hl_check_error("raster vs Embree: distance (texels) of a differing centre from a projected edge", worst_dist, 1e-3);
        /* measured 0; a handful per million allows centres on edges */
        hl_check_error("raster vs Embree: fraction of covered texels that differ", frac, 1e-4);
        HL_CHECK(covered > (size_t)K * R_TEST * R_TEST / 10, "only %zu texels covered", covered);
    }
    free(a); free(b); scene_free(&s); hl_context_destroy(ref);
}

/* ================================================================ motion */

/* Object 0 of s moved by xf with hl_shadow_maps_set_transform, against a
 * fresh module whose object 0 has its vertices moved by hand (in double)
 * and the identity, both rendered into the first module's frames. */
static void motion_one(hl_context *ctx, hl_shadow_method m, scene *s, const float *xf, const char *what, double tol_depth,
                       double tol_frac)
{
    enum { K = 6 };
    float dirs[K][3];
    light_dirs(dirs, K);
    size_t n = (size_t)K * R_TEST * R_TEST;
    float *a = malloc(n * 4), *b = malloc(n * 4);
    hl_shadow_frame fr[K];
    hl_shadow_maps *sa = NULL, *sb = NULL;
    HL_CHECK(hl_shadow_maps_create(ctx, s->obj, 2, R_TEST, m, &sa) == HL_OK, "%s", hl_context_last_error(ctx));
    uint64_t builds0 = 0, commits0 = 0, builds1 = 0, commits1 = 0;
    if (sa) {
        HL_CHECK(hl_shadow_maps_render(sa, (const float(*)[3])dirs, K, a, fr) == HL_OK, "%s", hl_context_last_error(ctx));
        hl_shadow_maps_embree_counts(sa, &builds0, &commits0);
        HL_CHECK(hl_shadow_maps_set_transform(sa, 0, xf) == HL_OK, "%s", hl_context_last_error(ctx));
        HL_CHECK(hl_shadow_maps_render(sa, (const float(*)[3])dirs, K, a, fr) == HL_OK, "%s", hl_context_last_error(ctx));
        hl_shadow_maps_embree_counts(sa, &builds1, &commits1);
    }
    hl_dyn_object moved[2] = {s->obj[0], s->obj[1]};
    float *p = malloc((size_t)s->obj[0].nverts * 12);
    for (uint32_t v = 0; v < s->obj[0].nverts; v++)
        for (int c = 0; c < 3; c++) {
            const float *q = s->obj[0].pos + 3 * (size_t)v;
            p[3 * v + c] = (float)((double)xf[4 * c] * q[0] + (double)xf[4 * c + 1] * q[1] + (double)xf[4 * c + 2] * q[2] +
                                   (double)xf[4 * c + 3]);
        }
    moved[0].pos = p;
    memcpy(moved[0].xf, XF_ID, 48);
    HL_CHECK(hl_shadow_maps_create(ctx, moved, 2, R_TEST, m, &sb) == HL_OK, "%s", hl_context_last_error(ctx));
    if (sa && sb) {
        HL_CHECK(hl_shadow_maps_render_in(sb, fr, K, b) == HL_OK, "%s", hl_context_last_error(ctx));
        size_t mism, cov;
        double worst;
        compare_maps(a, b, n, &mism, &worst, &cov);
        char w[160];
        snprintf(w, sizeof w, "%s: depth, moved by transform vs by hand", what);
        hl_check_error(w, worst, tol_depth);
        snprintf(w, sizeof w, "%s: fraction of texels covered by one only", what);
        hl_check_error(w, (double)mism / (double)n, tol_frac);
        HL_CHECK(cov > n / 10, "%s: only %zu texels covered", what, cov);
    }
    if (m == HL_SHADOW_EMBREE) {
        /* one BVH per object at creation, none since; one top-level
           commit at creation and one for the motion */
        printf("%s: object BVH builds %llu before the motion, %llu after; top-level commits %llu, %llu\n", what,
               (unsigned long long)builds0, (unsigned long long)builds1, (unsigned long long)commits0,
               (unsigned long long)commits1);
        HL_CHECK(builds0 == 2 && builds1 == 2, "%s: the motion rebuilt an object's BVH", what);
        HL_CHECK(commits0 == 1 && commits1 == 2, "%s: top-level commits %llu, %llu (want 1, 2)", what,
                 (unsigned long long)commits0, (unsigned long long)commits1);
    }
    hl_shadow_maps_destroy(sa); hl_shadow_maps_destroy(sb); free(p); free(a); free(b);
}

static void case_motion(void)
{
    hl_context *ref = ref_ctx();
    scene s;
    if (!scene_load(ref, &s)) { HL_CHECK(0, "setup failed"); hl_context_destroy(ref); return; }
    /* A quarter turn about +Y with exact entries: by hand and by the
       kernel, each coordinate is one coordinate plus the translation,
       rounded once, so the rasteriser must match bit for bit. */
    const float quarter[12] = {0, 0, 1, 0.0625f, 0, 1, 0, 0.03125f, -1, 0, 0, -0.046875f};
    motion_one(ref, HL_SHADOW_RASTER, &s, quarter, "raster, quarter turn", 0.0, 0.0);
    /* Any rotation: the two vertex sets differ by float rounding (~1e-7
       of the scene), which a steep triangle (seen nearly edge-on) turns
       into a larger depth change at a centre (measured 3.2e-6), and a
       centre within ~1e-5 texel of a silhouette may change sides. */
    const double axis[3] = {0.26726124191, 0.53452248382, 0.80178372573}, t[3] = {0.02, 0.01, -0.03};
    float xf[12];
    make_xf(axis, 0.7, t, xf);
    motion_one(ref, HL_SHADOW_RASTER, &s, xf, "raster, any rotation", 1e-5, 1e-4);
    motion_one(ref, HL_SHADOW_EMBREE, &s, quarter, "Embree, quarter turn", 1e-5, 1e-4);
    motion_one(ref, HL_SHADOW_EMBREE, &s, xf, "Embree, any rotation", 1e-5, 1e-4);
    hl_context *cl = hl_test_cl_context(2);
    HL_CHECK(cl != NULL, "no OpenCL device");
    if (cl) motion_one(cl, HL_SHADOW_RASTER, &s, xf, "OpenCL raster, any rotation", 1e-5, 1e-4);
    hl_context_destroy(cl); scene_free(&s); hl_context_destroy(ref);
}

/* ================================================================= frame */

/* The fit is tight: the corners of the objects' own boxes, moved to
 * world space, span exactly R - 2 margin texels along the wider axis and
 * sit centred. Returns the worst error in texels. */
static double box_span_error(const hl_shadow_frame *f, const hl_dyn_object *o, uint32_t nobj)
{
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (uint32_t q = 0; q < nobj; q++) {
        double bl[3] = {INFINITY, INFINITY, INFINITY}, bh[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t v = 0; v < o[q].nverts; v++)
            for (int c = 0; c < 3; c++) {
                bl[c] = fmin(bl[c], o[q].pos[3 * (size_t)v + c]);
                bh[c] = fmax(bh[c], o[q].pos[3 * (size_t)v + c]);
            }
        for (int corner = 0; corner < 8; corner++) {
            double p[3] = {corner & 1 ? bh[0] : bl[0], corner & 2 ? bh[1] : bl[1], corner & 4 ? bh[2] : bl[2]}, w[3];
            const float *x = o[q].xf;
            for (int c = 0; c < 3; c++) w[c] = x[4 * c] * p[0] + x[4 * c + 1] * p[1] + x[4 * c + 2] * p[2] + x[4 * c + 3] - f->origin[c];
            double tx = (w[0] * f->right[0] + w[1] * f->right[1] + w[2] * f->right[2]) / f->width * f->R;
            double ty = (w[0] * f->up[0] + w[1] * f->up[1] + w[2] * f->up[2]) / f->height * f->R;
            lo[0] = fmin(lo[0], tx); hi[0] = fmax(hi[0], tx);
            lo[1] = fmin(lo[1], ty); hi[1] = fmax(hi[1], ty);
        }
    }
    double span = fmax(hi[0] - lo[0], hi[1] - lo[1]), R = f->R;
    double e = fabs(span - (R - 2.0 * HL_SHADOW_MARGIN_TEXELS));
    for (int a = 0; a < 2; a++) e = fmax(e, fabs(0.5 * (lo[a] + hi[a]) - 0.5 * R)); /* centred */
    return e;
}

static void case_frame(void)
{
    hl_context *ref = ref_ctx();
    scene s;
    if (!scene_load(ref, &s)) { HL_CHECK(0, "setup failed"); hl_context_destroy(ref); return; }
    const double axis[3] = {0.6, 0.0, 0.8}, t[3] = {0.1, 0.05, -0.05};
    make_xf(axis, 0.4, t, s.obj[0].xf);
    enum { K = 10 };
    float dirs[K][3];
    light_dirs(dirs, K);
    const float extra[4][3] = {{1, 1e-4f, 0}, {0, -0.01f, 1}, {1e-7f, 1, 0}, {0, 0, -1}};
    for (int k = 0; k < 4; k++) { memcpy(dirs[4 + k], extra[k], 12); unit3(dirs[4 + k]); }
    hl_shadow_frame fr[K];
    float *d = render(ref, s.obj, 2, HL_SHADOW_RASTER, (const float(*)[3])dirs, K, fr);
    HL_CHECK(d != NULL, "render failed");
    double basis = 0.0, outside = 0.0, depth_out = 0.0, span_err = 0.0;
    size_t border = 0;
    const double margin = HL_SHADOW_MARGIN_TEXELS, inset = 5e-4;
    for (uint32_t k = 0; d && k < K; k++) {
        const hl_shadow_frame *f = &fr[k];
        const float *ax[3] = {f->right, f->up, f->toward_far};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                double dot = 0;
                for (int c = 0; c < 3; c++) dot += (double)ax[a][c] * ax[b][c];
                basis = fmax(basis, fabs(dot - (a == b)));
            }
        for (int c = 0; c < 3; c++) basis = fmax(basis, fabs((double)f->toward_far[c] + dirs[k][c]));
        HL_CHECK(f->width == f->height && f->R == R_TEST && f->depth_range > 0, "frame %u: width %g height %g R %u", k,
                 (double)f->width, (double)f->height, f->R);
        for (uint32_t q = 0; q < 2; q++)
            for (uint32_t v = 0; v < s.obj[q].nverts; v++) {
                const float *p = s.obj[q].pos + 3 * (size_t)v, *x = s.obj[q].xf;
                double w[3], pr[3] = {0, 0, 0};
                for (int c = 0; c < 3; c++)
                    w[c] = (double)x[4 * c] * p[0] + (double)x[4 * c + 1] * p[1] + (double)x[4 * c + 2] * p[2] + x[4 * c + 3] - f->origin[c];
                for (int a = 0; a < 3; a++)
                    for (int c = 0; c < 3; c++) pr[a] += w[c] * ax[a][c];
                double tx = pr[0] / f->width * R_TEST, ty = pr[1] / f->height * R_TEST, dz = pr[2] / f->depth_range;
                outside = fmax(outside, fmax(fmax(margin - tx, tx - (R_TEST - margin)), fmax(margin - ty, ty - (R_TEST - margin))));
                depth_out = fmax(depth_out, fmax(inset - dz, dz - (1.0 - inset)));
            }
        span_err = fmax(span_err, box_span_error(f, s.obj, 2));
        const float *m = d + (size_t)k * R_TEST * R_TEST;
        for (uint32_t i = 0; i < R_TEST; i++)
            border += (m[i] != HL_SHADOW_EMPTY) + (m[(size_t)(R_TEST - 1) * R_TEST + i] != HL_SHADOW_EMPTY) +
                      (m[(size_t)i * R_TEST] != HL_SHADOW_EMPTY) + (m[(size_t)i * R_TEST + R_TEST - 1] != HL_SHADOW_EMPTY);
    }
    hl_check_error("frames: orthonormal basis, toward_far = -dir", basis, 1e-6);
    /* the frame is stored in float: its origin carries ~1e-7 of the
       scene's size, ~3e-5 texel at R = 256 */
    hl_check_error("frames: texels by which a vertex leaves the margin", fmax(outside, 0.0), 1e-3);
    hl_check_error("frames: vertex depth outside [5e-4, 1 - 5e-4]", fmax(depth_out, 0.0), 0.0);
    hl_check_error("frames: the boxes' span against R - 2 margin texels, centred (texels)", span_err, 1e-3);
    hl_check_error("frames: covered texels on the border ring", (double)border, 0.0);
    free(d); scene_free(&s); hl_context_destroy(ref);
}

/* ============================================================= bad input */

/* The call failed with HL_ERR_INVALID_ARGUMENT and a message naming key. */
static void expect_error(hl_context *ctx, hl_result r, const char *what, const char *key)
{
    const char *msg = hl_context_last_error(ctx);
    printf("%s: %s\n", what, r == HL_OK ? "accepted" : msg);
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && strstr(msg, key), "%s: result %d, message \"%s\" (want \"%s\")", what, (int)r,
             msg, key);
}

static void case_bad_input(void)
{
    hl_context *ref = ref_ctx();
    square q;
    make_square(&q, 1.0f);
    hl_dyn_object o = {.pos = q.pos, .nverts = 4, .tri = q.tri, .ntris = 2}, b;
    memcpy(o.xf, XF_ID, 48);
    hl_shadow_maps *sm = NULL;
    float pos[12];
    uint32_t tri[6];
#define CREATE(obj, n, R) hl_shadow_maps_create(ref, obj, n, R, HL_SHADOW_RASTER, &sm)
    expect_error(ref, CREATE(&o, 1, 0), "R = 0", "R = 0");
    expect_error(ref, CREATE(&o, 1, 5000), "R = 5000", "R = 5000");
    expect_error(ref, CREATE(NULL, 1, 64), "no objects", "no objects");
    expect_error(ref, CREATE(&o, 0, 64), "zero objects", "no objects");
    b = o; b.ntris = 0;
    expect_error(ref, CREATE(&b, 1, 64), "no triangles", "no triangles");
    b = o; memcpy(pos, q.pos, 48); pos[4] = NAN; b.pos = pos;
    expect_error(ref, CREATE(&b, 1, 64), "NaN vertex", "not finite");
    pos[4] = INFINITY;
    expect_error(ref, CREATE(&b, 1, 64), "infinite vertex", "not finite");
    b = o; memcpy(tri, q.tri, 24); tri[5] = 4; b.tri = tri;
    expect_error(ref, CREATE(&b, 1, 64), "index out of range", "names vertex 4");
    b = o; b.xf[3] = NAN;
    expect_error(ref, CREATE(&b, 1, 64), "NaN transform", "non-finite");
    b = o; b.xf[0] = 1.01f;
    expect_error(ref, CREATE(&b, 1, 64), "scaled transform", "not orthonormal");
    b = o; b.xf[1] = 0.1f;
    expect_error(ref, CREATE(&b, 1, 64), "sheared transform", "not orthonormal");
    b = o; b.xf[0] = -1.0f;
    expect_error(ref, CREATE(&b, 1, 64), "reflection", "reflection");
    b = o; b.pos = NULL;
    expect_error(ref, CREATE(&b, 1, 64), "no position array", "no position array");
    expect_error(ref, hl_shadow_maps_create(ref, &o, 1, 64, (hl_shadow_method)7, &sm), "unknown method", "unknown method");
    HL_CHECK(sm == NULL, "a failed create left a module");
#undef CREATE
    HL_CHECK(hl_shadow_maps_create(ref, &o, 1, 64, HL_SHADOW_RASTER, &sm) == HL_OK, "%s", hl_context_last_error(ref));
    if (sm) {
        float depth[64 * 64 * 2];
        const float good[2][3] = {{0, 1, 0}, {1, 0, 0}};
        float bad[2][3] = {{0, 1, 0}, {0, 2, 0}};
        expect_error(ref, hl_shadow_maps_render(sm, (const float(*)[3])bad, 2, depth, NULL), "direction of length 2",
                     "not a unit vector");
        bad[1][0] = NAN;
        expect_error(ref, hl_shadow_maps_render(sm, (const float(*)[3])bad, 2, depth, NULL), "NaN direction",
                     "not a unit vector");
        expect_error(ref, hl_shadow_maps_render(sm, good, 0, depth, NULL), "no lights", "no lights");
        expect_error(ref, hl_shadow_maps_render(sm, good, 2, NULL, NULL), "no depth array", "no depth array");
        float xf[12];
        memcpy(xf, XF_ID, 48);
        expect_error(ref, hl_shadow_maps_set_transform(sm, 1, xf), "object 1 of 1", "object 1 of 1");
        xf[5] = 2.0f;
        expect_error(ref, hl_shadow_maps_set_transform(sm, 0, xf), "scaling motion", "not orthonormal");
        xf[5] = INFINITY;
        expect_error(ref, hl_shadow_maps_set_transform(sm, 0, xf), "infinite motion", "non-finite");
        hl_shadow_frame fr = {.R = 32, .width = 1, .height = 1, .depth_range = 1};
        expect_error(ref, hl_shadow_maps_render_in(sm, &fr, 1, depth), "frame of another R", "not usable");
        /* still usable after the refusals */
        HL_CHECK(hl_shadow_maps_render(sm, good, 2, depth, NULL) == HL_OK, "%s", hl_context_last_error(ref));
        size_t cov = 0;
        for (size_t i = 0; i < 64 * 64; i++) cov += depth[i] < HL_SHADOW_EMPTY;
        HL_CHECK(cov > 1000, "the square seen from above covers %zu texels", cov);
    }
    hl_shadow_maps_destroy(sm); hl_context_destroy(ref);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"twin", case_twin},     {"analytic", case_analytic}, {"embree", case_embree},
                                         {"motion", case_motion}, {"frame", case_frame},       {"bad_input", case_bad_input},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
