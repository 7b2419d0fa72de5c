/* test_render.c - hl_render: Embree primary rays, camera, background
 * (suite "render").
 *
 * The renderer shoots one ray through each pixel centre, so these tests
 * rebuild the same pinhole camera here in double precision and compare
 * against analytic answers. Meshes come from $HL_REPO_DATA
 * (bunny_lowres.obj) or are built in memory; scratch files go to $HL_TMP.
 * Contexts use the reference backend, so no OpenCL device is needed.
 * Depends on: haarlight_core, tests/common/render_util.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_test.h"
#include "render_util.h"

/* ---------------------------------------------------------------- cases */

/* Every pixel is exactly the constant colour or black; auto framing
 * puts the bunny in the frame, roughly centred, at a sensible size, and
 * ignores the ground plane (same object pixels with and without it). */
static void constant_colour(void)
{
    hl_context *ctx = make_ctx();
    hl_mesh *m = load_bunny(ctx);
    const float col[3] = {0.2f, 0.4f, 0.6f};
    float *c = constant_colours(m->vertex_count, col[0], col[1], col[2]);
    hl_camera_desc cam = {0};
    cam.width = 160;
    cam.height = 120;
    hl_image *img = NULL;
    hl_result r = hl_render(ctx, m, c, NULL, 0.0f, &cam, &img);
    HL_CHECK(r == HL_OK, "render failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    HL_CHECK(img->width == 160 && img->height == 120, "image is %u x %u", img->width, img->height);

    size_t covered = 0, other = 0;
    long x0 = 1 << 30, x1 = -1, y0 = 1 << 30, y1 = -1;
    unsigned char *mask = calloc((size_t)img->width * img->height, 1);
    for (uint32_t y = 0; y < img->height; y++)
        for (uint32_t x = 0; x < img->width; x++) {
            const float *p = img->rgb + 3 * ((size_t)y * img->width + x);
            if (p[0] == col[0] && p[1] == col[1] && p[2] == col[2]) {
                covered++;
                mask[(size_t)y * img->width + x] = 1;
                if ((long)x < x0) x0 = x;
                if ((long)x > x1) x1 = x;
                if ((long)y < y0) y0 = y;
                if ((long)y > y1) y1 = y;
            } else if (!(p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f)) {
                other++;
            }
        }
    double npix = (double)img->width * img->height;
    double frac = (double)covered / npix;
    printf("coverage %.3f of the frame; object pixels span x %ld..%ld, y %ld..%ld; %zu pixels neither colour nor black\n",
           frac, x0, x1, y0, y1, other);
    HL_CHECK(other == 0, "%zu pixels are neither the colour nor black", other);
    HL_CHECK(frac >= 0.10 && frac <= 0.80, "object covers %.3f of the frame (want 0.10..0.80)", frac);
    HL_CHECK(x0 > 0 && y0 > 0 && x1 < (long)img->width - 1 && y1 < (long)img->height - 1,
             "object touches the frame's edge");
    double cx = 0.5 * (double)(x0 + x1 + 1) / img->width - 0.5;
    double cy = 0.5 * (double)(y0 + y1 + 1) / img->height - 0.5;
    hl_check_error("object's pixel box centre offset from the image centre (fraction of the frame)",
                   fmax(fabs(cx), fabs(cy)), 0.15);

    /* The same with a ground plane: the framing ignores it, and the eye is
     * above it, so the object's pixels are the same. */
    hl_image *img2 = NULL;
    r = hl_mesh_add_ground(ctx, m, NULL);
    HL_CHECK(r == HL_OK, "add ground failed: %s", hl_context_last_error(ctx));
    float *c2 = constant_colours(m->vertex_count, 0.05f, 0.05f, 0.05f);
    memcpy(c2, c, 3 * (size_t)m->object_vertex_count * sizeof(float));
    r = hl_render(ctx, m, c2, NULL, 0.0f, &cam, &img2);
    HL_CHECK(r == HL_OK, "render with ground failed: %s", hl_context_last_error(ctx));
    if (r == HL_OK) {
        size_t differ = 0, ground = 0;
        for (size_t i = 0; i < (size_t)img2->width * img2->height; i++) {
            const float *p = img2->rgb + 3 * i;
            int obj = p[0] == col[0] && p[1] == col[1] && p[2] == col[2];
            if (p[0] == 0.05f && p[1] == 0.05f && p[2] == 0.05f) ground++;
            if (obj != mask[i]) differ++;
        }
        printf("with ground: %zu ground pixels, %zu object pixels differ from the render without it\n", ground,
               differ);
        HL_CHECK(ground > 0, "the ground plane is not visible");
        hl_check_error("object pixels changed by adding the ground (fraction of object pixels)",
                       (double)differ / (double)(covered ? covered : 1), 0.005);
    }
    hl_image_destroy(img2);
    free(c2);
    free(mask);
    hl_image_destroy(img);
    free(c);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* One big triangle facing the camera with red, green and blue corners:
 * every hit pixel sums to 1 over its channels and equals the analytic
 * barycentric interpolation at its centre ray. */
static void barycentric(void)
{
    hl_context *ctx = make_ctx();
    const float pos[9] = {-2.0f, -1.5f, 0.0f, 2.0f, -1.5f, 0.0f, 0.0f, 2.0f, 0.0f};
    const uint32_t idx[3] = {0, 1, 2};
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_create(ctx, 3, pos, NULL, NULL, 1, idx, &m);
    HL_CHECK(r == HL_OK, "mesh create failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    /* Colour each vertex by which corner it is (the mesh may reorder). */
    double corner[3][3];
    float c[9] = {0};
    for (uint32_t v = 0; v < 3; v++) {
        int which = -1;
        for (int k = 0; k < 3; k++)
            if (m->positions[3 * v] == pos[3 * k] && m->positions[3 * v + 1] == pos[3 * k + 1]) which = k;
        HL_CHECK(which >= 0, "vertex %u is not a corner", v);
        if (which < 0) exit(1);
        c[3 * v + which] = 1.0f;
        for (int k = 0; k < 3; k++) corner[which][k] = pos[3 * which + k];
    }
    hl_camera_desc cam = {0};
    cam.width = 200;
    cam.height = 150;
    cam.fov_deg = 60.0f;
    cam.eye[2] = 5.0f;
    hl_image *img = NULL;
    r = hl_render(ctx, m, c, NULL, 0.0f, &cam, &img);
    HL_CHECK(r == HL_OK, "render failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    tcam t = make_tcam(&cam);

    double worst_sum = 0.0, worst_bary = 0.0;
    size_t hits = 0, interior = 0, missing = 0;
    for (uint32_t y = 0; y < img->height; y++)
        for (uint32_t x = 0; x < img->width; x++) {
            const float *p = img->rgb + 3 * ((size_t)y * img->width + x);
            /* Analytic: intersect the centre ray with the plane z = 0. */
            double d[3];
            tcam_dir(&t, x + 0.5, y + 0.5, d);
            double s = -t.eye[2] / d[2];
            double q[2] = {t.eye[0] + s * d[0], t.eye[1] + s * d[1]};
            const double *a = corner[0], *b = corner[1], *e = corner[2];
            double det = (b[0] - a[0]) * (e[1] - a[1]) - (e[0] - a[0]) * (b[1] - a[1]);
            double l1 = ((q[0] - a[0]) * (e[1] - a[1]) - (e[0] - a[0]) * (q[1] - a[1])) / det;
            double l2 = ((b[0] - a[0]) * (q[1] - a[1]) - (q[0] - a[0]) * (b[1] - a[1])) / det;
            double l0 = 1.0 - l1 - l2;
            int hit = !(p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f);
            if (hit) {
                hits++;
                double sum = (double)p[0] + p[1] + p[2];
                if (fabs(sum - 1.0) > worst_sum) worst_sum = fabs(sum - 1.0);
            }
            /* Well inside the triangle: must be hit and match. */
            if (l0 > 0.01 && l1 > 0.01 && l2 > 0.01) {
                interior++;
                if (!hit) {
                    missing++;
                    continue;
                }
                double want[3] = {l0, l1, l2};
                for (int k = 0; k < 3; k++)
                    if (fabs(p[k] - want[k]) > worst_bary) worst_bary = fabs(p[k] - want[k]);
            }
        }
    printf("%zu hit pixels, %zu well inside the triangle\n", hits, interior);
    HL_CHECK(interior > 1000, "only %zu pixels inside the triangle", interior);
    HL_CHECK(missing == 0, "%zu pixels well inside the triangle were missed", missing);
    hl_check_error("r + g + b - 1 over hit pixels", worst_sum, 1e-5);
    hl_check_error("colour against analytic barycentrics at pixel centres", worst_bary, 1e-4);

    /* Projected points: the centroid and points near each corner. */
    double worst_pt = 0.0;
    const double bary[4][3] = {{1.0 / 3, 1.0 / 3, 1.0 / 3}, {0.8, 0.1, 0.1}, {0.1, 0.8, 0.1}, {0.1, 0.1, 0.8}};
    for (int i = 0; i < 4; i++) {
        double P[3] = {0, 0, 0};
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++) P[k] += bary[i][j] * corner[j][k];
        double px, py;
        tcam_project(&t, P, &px, &py);
        const float *p = img->rgb + 3 * ((size_t)floor(py) * img->width + (size_t)floor(px));
        /* The pixel centre is within half a pixel of the point: allow the
         * colour's change over that distance (gradient ~ 1/ (triangle
         * size in pixels ~ 100)). */
        for (int k = 0; k < 3; k++)
            if (fabs(p[k] - bary[i][k]) > worst_pt) worst_pt = fabs(p[k] - bary[i][k]);
    }
    hl_check_error("colour at 4 projected points against their barycentrics (within half a pixel)", worst_pt,
                   0.02);
    hl_image_destroy(img);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* A camera that sees no geometry shows the environment: a constant one
 * exactly, and a 4 x 2 one by the docs/CONVENTIONS.md mapping (+X at u = 0.5). */
static void background(void)
{
    hl_context *ctx = make_ctx();
    hl_mesh *m = load_bunny(ctx);
    float *c = constant_colours(m->vertex_count, 1.0f, 1.0f, 1.0f);
    float env_rgb[3 * 8 * 4];
    for (int i = 0; i < 8 * 4; i++) {
        env_rgb[3 * i] = 0.3f;
        env_rgb[3 * i + 1] = 0.5f;
        env_rgb[3 * i + 2] = 0.7f;
    }
    hl_env *env = NULL;
    hl_result r = hl_env_create(ctx, 8, 4, env_rgb, &env, NULL);
    HL_CHECK(r == HL_OK, "env create failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    hl_camera_desc cam = {0};
    cam.width = 64;
    cam.height = 48;
    cam.eye[2] = 100.0f;
    cam.target[2] = 200.0f; /* looking +Z, away from the bunny at the origin */
    hl_image *img = NULL;
    r = hl_render(ctx, m, c, env, 37.0f, &cam, &img);
    HL_CHECK(r == HL_OK, "render failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    size_t wrong = 0;
    for (size_t i = 0; i < (size_t)img->width * img->height; i++)
        if (img->rgb[3 * i] != 0.3f || img->rgb[3 * i + 1] != 0.5f || img->rgb[3 * i + 2] != 0.7f) wrong++;
    HL_CHECK(wrong == 0, "%zu pixels differ from the constant environment", wrong);
    hl_image_destroy(img);
    hl_env_destroy(env);

    /* 4 x 2 map, colour (column, row) = ((col + 1) / 4, row, 0.5): columns
     * cover u in [0, .25) -X..-Z, [.25, .5) -Z..+X, [.5, .75) +X..+Z,
     * [.75, 1) +Z..-X; row 0 is y > 0. */
    float e4[3 * 8];
    for (int row = 0; row < 2; row++)
        for (int col = 0; col < 4; col++) {
            float *p = e4 + 3 * (row * 4 + col);
            p[0] = (float)(col + 1) / 4.0f;
            p[1] = (float)row;
            p[2] = 0.5f;
        }
    r = hl_env_create(ctx, 4, 2, e4, &env, NULL);
    HL_CHECK(r == HL_OK, "env create failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    /* Far from the bunny (diagonal ~ 0.2..2), looking along +X and -X with
     * a 60 degree square view: only the two columns beside the view
     * direction show. Looking +X, image right is +Z (right = fwd x up). */
    struct {
        float dir;
        float rotate;
        int left_col, right_col;
    } views[3] = {{+1.0f, 0.0f, 1, 2}, {-1.0f, 0.0f, 3, 0}, {+1.0f, 90.0f, 2, 3}};
    /* Third: content turned +90 about +Y (what was at +Z is now at +X):
     * looking +X reads the file at u + 0.25, the columns beside +Z. */
    for (int vi = 0; vi < 3; vi++) {
        hl_camera_desc cv = {0};
        cv.width = 64;
        cv.height = 64;
        cv.fov_deg = 60.0f;
        cv.nearest_background = 1; /* exact map values */
        cv.eye[0] = 100.0f * views[vi].dir;
        cv.target[0] = 200.0f * views[vi].dir;
        img = NULL;
        r = hl_render(ctx, m, c, env, views[vi].rotate, &cv, &img);
        HL_CHECK(r == HL_OK, "render failed: %s", hl_context_last_error(ctx));
        if (r != HL_OK) exit(1);
        wrong = 0;
        for (uint32_t y = 0; y < img->height; y++)
            for (uint32_t x = 0; x < img->width; x++) {
                int col = x < img->width / 2 ? views[vi].left_col : views[vi].right_col;
                int row = y < img->height / 2 ? 0 : 1;
                const float *p = img->rgb + 3 * ((size_t)y * img->width + x);
                if (p[0] != e4[3 * (row * 4 + col)] || p[1] != e4[3 * (row * 4 + col) + 1] ||
                    p[2] != e4[3 * (row * 4 + col) + 2])
                    wrong++;
            }
        printf("view %s, rotate %g: left half column %d, right half column %d: %zu pixels wrong\n",
               views[vi].dir > 0 ? "+X" : "-X", (double)views[vi].rotate, views[vi].left_col,
               views[vi].right_col, wrong);
        HL_CHECK(wrong == 0, "%zu pixels show the wrong part of the environment", wrong);
        hl_image_destroy(img);
    }
    hl_env_destroy(env);
    free(c);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* Explicit eye, target and up: a small square on the view axis lands on
 * the image centre; squares displaced along the camera's right and up
 * land right of and below it, where the pinhole model says. */
static void explicit_camera(void)
{
    hl_context *ctx = make_ctx();
    hl_camera_desc cam = {0};
    cam.width = 121;
    cam.height = 91;
    cam.fov_deg = 40.0f;
    cam.eye[0] = 1.0f;
    cam.eye[1] = 2.0f;
    cam.eye[2] = 3.0f;
    cam.target[0] = -0.5f;
    cam.target[1] = 0.3f;
    cam.target[2] = -1.0f;
    cam.up[0] = 0.1f;
    cam.up[1] = 1.0f;
    tcam t = make_tcam(&cam);
    double dist = 4.0; /* along the view axis */
    double side = 0.08, off_r = 0.6, off_u = -0.43;
    double centres[3][3];
    for (int k = 0; k < 3; k++) {
        centres[0][k] = t.eye[k] + dist * t.f[k];
        centres[1][k] = centres[0][k] + off_r * t.r[k];
        centres[2][k] = centres[0][k] + off_u * t.u[k];
    }
    float pos[3 * 12];
    uint32_t idx[3 * 6];
    for (int q = 0; q < 3; q++) {
        const double sx[4] = {-1, 1, 1, -1}, sy[4] = {-1, -1, 1, 1};
        for (int v = 0; v < 4; v++)
            for (int k = 0; k < 3; k++)
                pos[3 * (4 * q + v) + k] =
                    (float)(centres[q][k] + side * (sx[v] * t.r[k] + sy[v] * t.u[k]));
        const uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
        for (int i = 0; i < 6; i++) idx[6 * q + i] = (uint32_t)(4 * q) + tri[i];
    }
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_create(ctx, 12, pos, NULL, NULL, 6, idx, &m);
    HL_CHECK(r == HL_OK, "mesh create failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    /* Colour by nearest square: red on axis, green right, blue down. */
    float *c = calloc(3 * (size_t)m->vertex_count, sizeof(float));
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        int best = 0;
        double bd = INFINITY;
        for (int q = 0; q < 3; q++) {
            double d = 0;
            for (int k = 0; k < 3; k++) d += pow(m->positions[3 * v + k] - centres[q][k], 2);
            if (d < bd) {
                bd = d;
                best = q;
            }
        }
        c[3 * v + best] = 1.0f;
    }
    hl_image *img = NULL;
    r = hl_render(ctx, m, c, NULL, 0.0f, &cam, &img);
    HL_CHECK(r == HL_OK, "render failed: %s", hl_context_last_error(ctx));
    if (r != HL_OK) exit(1);
    /* Expected pixels: those whose centre ray (this file's camera, in
     * double) meets the square; centres within 1e-4 of the square's
     * half-side from an edge are left out as ambiguous. */
    double worst = 0.0, worst_proj = 0.0;
    size_t mismatched = 0, ambiguous = 0;
    const char *names[3] = {"on-axis", "right", "down"};
    for (int q = 0; q < 3; q++) {
        double sx = 0, sy = 0, ax = 0, ay = 0;
        size_t n = 0, na = 0;
        for (uint32_t y = 0; y < img->height; y++)
            for (uint32_t x = 0; x < img->width; x++) {
                int got = img->rgb[3 * ((size_t)y * img->width + x) + q] == 1.0f;
                double d[3], X[3];
                tcam_dir(&t, x + 0.5, y + 0.5, d); /* d . f = 1: the plane is at s = dist */
                for (int k = 0; k < 3; k++) X[k] = t.eye[k] + dist * d[k] - centres[q][k];
                double a = fabs(X[0] * t.r[0] + X[1] * t.r[1] + X[2] * t.r[2]);
                double b = fabs(X[0] * t.u[0] + X[1] * t.u[1] + X[2] * t.u[2]);
                double edge = fmax(a, b) - side;
                int want = edge < 0.0;
                if (fabs(edge) < 1e-4 * side) {
                    ambiguous++;
                } else if (got != want) {
                    mismatched++;
                }
                if (got) {
                    sx += x + 0.5;
                    sy += y + 0.5;
                    n++;
                }
                if (want) {
                    ax += x + 0.5;
                    ay += y + 0.5;
                    na++;
                }
            }
        double px, py;
        tcam_project(&t, centres[q], &px, &py);
        HL_CHECK(n > 4 && na > 4, "%s square covers %zu pixels (%zu expected)", names[q], n, na);
        if (!n || !na) continue;
        double mx = sx / (double)n, my = sy / (double)n;
        double amx = ax / (double)na, amy = ay / (double)na;
        printf("%s square: %zu pixels (%zu expected), centroid (%.3f, %.3f), expected (%.3f, %.3f), "
               "projected centre (%.3f, %.3f)\n",
               names[q], n, na, mx, my, amx, amy, px, py);
        worst = fmax(worst, fmax(fabs(mx - amx), fabs(my - amy)));
        worst_proj = fmax(worst_proj, fmax(fabs(mx - px), fabs(my - py)));
        if (q == 0) {
            HL_CHECK(fabs(px - cam.width / 2.0) < 1e-6 && fabs(py - cam.height / 2.0) < 1e-6,
                     "test camera disagrees: axis point at (%g, %g)", px, py);
            const float *p = img->rgb + 3 * ((size_t)(cam.height / 2) * cam.width + cam.width / 2);
            HL_CHECK(p[0] == 1.0f && p[1] == 0.0f && p[2] == 0.0f, "centre pixel is (%g, %g, %g), not red",
                     (double)p[0], (double)p[1], (double)p[2]);
        }
        if (q == 1) HL_CHECK(px > cam.width / 2.0 + 10, "right square is not right of the centre");
        if (q == 2) HL_CHECK(py > cam.height / 2.0 + 10, "negative-up square is not below the centre");
    }
    printf("%zu pixels differ from the expected squares, %zu ambiguous left out\n", mismatched, ambiguous);
    HL_CHECK(mismatched == 0, "%zu pixels differ from the expected squares", mismatched);
    hl_check_error("square pixel centroids against the expected pixel sets (pixels)", worst, 1e-9);
    /* Sampling a 5 x 5 pixel square moves its centroid by up to half a
     * pixel from the projected centre. */
    hl_check_error("square pixel centroids against their projected centres (pixels)", worst_proj, 0.5 + 1e-6);
    hl_image_destroy(img);
    free(c);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void bad_args(void)
{
    hl_context *ctx = make_ctx();
    hl_mesh *m = load_bunny(ctx);
    float *c = constant_colours(m->vertex_count, 0.5f, 0.5f, 0.5f);
    static hl_image dummy;
    hl_image *img = &dummy; /* must come back NULL */
    hl_camera_desc cam = {0};
    cam.width = 32;
    cam.height = 24;

    expect_bad(ctx, hl_render(ctx, NULL, c, NULL, 0, &cam, &img), HL_ERR_INVALID_ARGUMENT, "NULL mesh", "mesh");
    HL_CHECK(img == NULL, "output not cleared on failure");
    expect_bad(ctx, hl_render(ctx, m, NULL, NULL, 0, &cam, &img), HL_ERR_INVALID_ARGUMENT, "NULL colours",
               "colour");
    HL_CHECK(hl_render(ctx, m, c, NULL, 0, &cam, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL out accepted");
    HL_CHECK(hl_render(NULL, m, c, NULL, 0, &cam, &img) == HL_ERR_INVALID_ARGUMENT, "NULL context accepted");

    hl_camera_desc b = cam;
    b.width = 16385;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "width 16385", "16385");
    b = cam;
    b.height = 100000;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "height 100000", "100000");
    b = cam;
    b.fov_deg = 180.0f;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "fov 180", "field of view");
    b.fov_deg = -10.0f;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "fov -10", "field of view");
    b.fov_deg = NAN;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "fov NaN", "field of view");
    b = cam;
    b.eye[1] = NAN;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "eye NaN", "not finite");
    b = cam;
    b.eye[2] = 3.0f;
    b.up[0] = INFINITY;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "up Inf", "not finite");
    b = cam;
    b.target[2] = -INFINITY;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "target -Inf",
               "not finite");
    b = cam;
    b.eye[0] = b.target[0] = 1.0f;
    b.eye[1] = b.target[1] = 2.0f;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "eye == target",
               "same point");
    b = cam;
    b.eye[1] = 5.0f; /* looking straight down -Y with the default up +Y */
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "up parallel to view",
               "parallel");
    b = cam;
    b.eye[2] = 5.0f;
    b.up[2] = -3.0f; /* up along the view direction -Z */
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &b, &img), HL_ERR_INVALID_ARGUMENT, "up along view",
               "parallel");
    expect_bad(ctx, hl_render(ctx, m, c, NULL, NAN, &cam, &img), HL_ERR_INVALID_ARGUMENT, "rotation NaN",
               "rotation");
    c[3 * 5 + 1] = INFINITY;
    expect_bad(ctx, hl_render(ctx, m, c, NULL, 0, &cam, &img), HL_ERR_INVALID_ARGUMENT, "Inf colour",
               "vertex 5");
    c[3 * 5 + 1] = 0.5f;
    HL_CHECK(img == NULL, "output not cleared on failure");

    /* A NULL camera means all defaults (960 x 720, framed). */
    hl_result r = hl_render(ctx, m, c, NULL, 0, NULL, &img);
    HL_CHECK(r == HL_OK && img && img->width == 960 && img->height == 720, "default camera: %s",
             hl_context_last_error(ctx));
    hl_image_destroy(img);

    expect_bad(ctx, hl_mesh_save_ply(ctx, NULL, c, tmp_path("render_bad.ply"), 0, 0), HL_ERR_INVALID_ARGUMENT,
               "PLY NULL mesh", "mesh");
    expect_bad(ctx, hl_mesh_save_ply(ctx, m, NULL, tmp_path("render_bad.ply"), 0, 0), HL_ERR_INVALID_ARGUMENT,
               "PLY NULL colours", "colour");
    expect_bad(ctx, hl_mesh_save_ply(ctx, m, c, NULL, 0, 0), HL_ERR_INVALID_ARGUMENT, "PLY NULL path", "path");
    expect_bad(ctx, hl_mesh_save_ply(ctx, m, c, tmp_path("render_bad.ply"), 1, NAN), HL_ERR_INVALID_ARGUMENT,
               "PLY NaN exposure", "exposure");
    free(c);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* hl_exposure_auto: the object's 90th percentile of luminance (the ground
 * left out) goes to 0.8, whatever the ground holds; without a ground,
 * every vertex counts. */
static void exposure_auto(void)
{
    enum { NO = 20, NG = 180 };
    static float pos[3 * (NO + NG)], rgb[3 * (NO + NG)];
    hl_mesh m = {.vertex_count = NO + NG, .object_vertex_count = NO, .positions = pos};
    /* object: grey levels 0.1, 0.2, ..., 2.0 (the 90th percentile, sorted
       index 18 of 20, is 1.9); ground: far brighter, then black */
    for (int v = 0; v < NO; v++) rgb[3 * v] = rgb[3 * v + 1] = rgb[3 * v + 2] = 0.1f * (float)(v + 1);
    double worst = 0.0;
    for (int g = 0; g < 2; g++) {
        for (int v = NO; v < NO + NG; v++) rgb[3 * v] = rgb[3 * v + 1] = rgb[3 * v + 2] = g ? 0.0f : 50.0f;
        double ev = hl_exposure_auto(&m, rgb), want = log2(0.8 / 1.9);
        printf("ground %s: %+.4f EV (want %+.4f)\n", g ? "black" : "at 50", ev, want);
        worst = fmax(worst, fabs(ev - want));
    }
    hl_check_error("the object's 90th percentile to 0.8, any ground (EV)", worst, 1e-5);
    /* no ground: every vertex, the ground's 50s included */
    for (int v = NO; v < NO + NG; v++) rgb[3 * v] = rgb[3 * v + 1] = rgb[3 * v + 2] = 50.0f;
    m.object_vertex_count = NO + NG;
    double ev = hl_exposure_auto(&m, rgb);
    hl_check_error("no ground: every vertex (EV)", fabs(ev - log2(0.8 / 50.0)), 1e-5);
    /* an all-black object: 0 */
    for (int v = 0; v < NO; v++) rgb[3 * v] = rgb[3 * v + 1] = rgb[3 * v + 2] = 0.0f;
    m.object_vertex_count = NO;
    HL_CHECK(hl_exposure_auto(&m, rgb) == 0.0f, "black object: %g", (double)hl_exposure_auto(&m, rgb));
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"constant_colour", constant_colour},
        {"barycentric", barycentric},
        {"background", background},
        {"explicit_camera", explicit_camera},
        {"bad_args", bad_args},
        {"exposure_auto", exposure_auto},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
