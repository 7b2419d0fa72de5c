/* test_mesh.c - the mesh module: loading, clean-up, orientation, normals,
 * ground plane and bad input.
 *
 * Data-dependent cases read the shared meshes from $HL_TEST_DATA/meshes
 * and skip (exit 0, with a message) when that folder is missing; the
 * synthetic cases write their small files into $HL_TMP and always run.
 * Expected counts come from the shared data README's mesh checks.
 * Contexts use the reference backend, so no OpenCL device is needed.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_internal.h"
#include "hl_test.h"

/* ---------------------------------------------------------------- helpers */

static hl_context *make_ctx(void) { return hl_test_ref_context(1); }

static char path_buf[8][1024];
static int path_next = 0;

/* Rotating buffers so a test can hold several paths at once. */
static const char *data_path(const char *name)
{
    char *b = path_buf[path_next++ & 7];
    snprintf(b, 1024, "%s/meshes/%s", hl_test_env("HL_TEST_DATA", "../shared/data"), name);
    return b;
}

static const char *tmp_path(const char *name) { return hl_test_tmp_path(name); }

static int have_data(void)
{
    FILE *f = fopen(data_path("bunny.obj"), "rb");
    if (!f) {
        printf("SKIP: shared data not found at %s (set HL_TEST_DATA)\n", data_path(""));
        return 0;
    }
    fclose(f);
    return 1;
}

static void write_file(const char *path, const void *bytes, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(bytes, 1, n, f) != n) {
        fprintf(stderr, "cannot write %s\n", path);
        exit(1);
    }
    fclose(f);
}

static void write_text(const char *path, const char *text) { write_file(path, text, strlen(text)); }

static void print_stats(const char *what, const hl_mesh *m, const hl_mesh_stats *s)
{
    printf("%s: file %u v / %u f -> %u v / %u f; merged %u, unreferenced %u, degenerate %u, normals %d, colours %d, flipped %d\n",
           what, s->file_vertices, s->file_triangles, m->vertex_count, m->triangle_count, s->merged_vertices,
           s->unreferenced_vertices, s->degenerate_triangles, s->had_normals, s->had_colors, s->flipped);
}

/* Signed volume of the object's triangles (ground excluded). */
static double mesh_volume(const hl_mesh *m)
{
    double vol = 0.0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *f = m->indices + 3 * (size_t)t;
        if (f[0] >= m->object_vertex_count) continue;
        const float *a = m->positions + 3 * (size_t)f[0], *b = m->positions + 3 * (size_t)f[1],
                    *c = m->positions + 3 * (size_t)f[2];
        vol += ((double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
    }
    return vol;
}

static void face_normal(const hl_mesh *m, uint32_t t, double n[3])
{
    const uint32_t *f = m->indices + 3 * (size_t)t;
    const float *a = m->positions + 3 * (size_t)f[0], *b = m->positions + 3 * (size_t)f[1],
                *c = m->positions + 3 * (size_t)f[2];
    double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (l > 0) for (int k = 0; k < 3; k++) n[k] /= l;
}

/* Structural sanity of any mesh: finite positions, unit finite normals,
 * albedo in [0, 1], indices in range. Returns the worst |length - 1|. */
static double check_sane(const char *what, const hl_mesh *m)
{
    double worst = 0.0;
    int bad_pos = 0, bad_nrm = 0, bad_alb = 0, bad_idx = 0;
    for (size_t v = 0; v < m->vertex_count; v++) {
        const float *p = m->positions + 3 * v, *n = m->normals + 3 * v, *a = m->albedo + 3 * v;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) bad_pos++;
        if (!isfinite(n[0]) || !isfinite(n[1]) || !isfinite(n[2])) {
            bad_nrm++;
            continue;
        }
        double l = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (fabs(l - 1.0) > worst) worst = fabs(l - 1.0);
        for (int k = 0; k < 3; k++)
            if (!(a[k] >= 0.0f && a[k] <= 1.0f)) bad_alb++;
    }
    for (size_t i = 0; i < 3 * (size_t)m->triangle_count; i++)
        if (m->indices[i] >= m->vertex_count) bad_idx++;
    HL_CHECK(bad_pos == 0, "%s: %d non-finite positions", what, bad_pos);
    HL_CHECK(bad_nrm == 0, "%s: %d non-finite normals", what, bad_nrm);
    HL_CHECK(bad_alb == 0, "%s: %d albedo values outside [0,1]", what, bad_alb);
    HL_CHECK(bad_idx == 0, "%s: %d indices out of range", what, bad_idx);
    HL_CHECK(m->object_vertex_count <= m->vertex_count, "%s: object_vertex_count too large", what);
    return worst;
}

/* Fraction of triangles whose geometric normal agrees (dot > 0) with the
 * mean of their vertex normals: ~1 when normals follow the winding. */
static double winding_agreement(const hl_mesh *m)
{
    uint32_t agree = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        double n[3], s[3] = {0, 0, 0};
        face_normal(m, t, n);
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) s[k] += m->normals[3 * (size_t)m->indices[3 * (size_t)t + c] + k];
        if (n[0] * s[0] + n[1] * s[1] + n[2] * s[2] > 0) agree++;
    }
    return m->triangle_count ? (double)agree / m->triangle_count : 0.0;
}

static void bbox(const hl_mesh *m, uint32_t from, uint32_t to, float lo[3], float hi[3])
{
    for (int k = 0; k < 3; k++) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (size_t v = from; v < to; v++)
        for (int k = 0; k < 3; k++) {
            float p = m->positions[3 * v + k];
            if (p < lo[k]) lo[k] = p;
            if (p > hi[k]) hi[k] = p;
        }
}

/* The load must fail with `code` (or any failure when code is HL_OK) and
 * the message must name the file. */
static void expect_failure(hl_context *ctx, const char *path, hl_result got, hl_result code)
{
    const char *msg = hl_context_last_error(ctx);
    printf("  %s -> %s: %s\n", path, hl_result_string(got), msg);
    HL_CHECK(got != HL_OK, "%s: loading should fail", path);
    if (code != HL_OK) HL_CHECK(got == code, "%s: expected %s, got %s", path, hl_result_string(code), hl_result_string(got));
    HL_CHECK(strstr(msg, path) != NULL, "%s: message does not name the file: %s", path, msg);
}

static hl_result load(hl_context *ctx, const char *path, const hl_mesh_load_desc *d, hl_mesh **m, hl_mesh_stats *s)
{
    hl_result r = hl_mesh_load(ctx, path, d, m, s);
    if (r != HL_OK) fprintf(stderr, "load %s: %s\n", path, hl_context_last_error(ctx));
    return r;
}

/* ---------------------------------------------------------------- data cases */

static void test_bunny(void)
{
    if (!have_data()) return;
    hl_context *ctx = make_ctx();
    hl_mesh *m = NULL;
    hl_mesh_stats s;
    HL_CHECK(load(ctx, data_path("bunny.obj"), NULL, &m, &s) == HL_OK, "load");
    if (m) {
        print_stats("bunny", m, &s);
        /* assimp gives one vertex per face corner and drops the file's
         * 1,113 unreferenced vertices; welding must bring back the
         * README's 34,834 referenced vertices. */
        HL_CHECK(s.file_triangles == 69451, "file triangles %u", s.file_triangles);
        HL_CHECK(s.merged_vertices == s.file_vertices - 34834, "merged %u of %u", s.merged_vertices, s.file_vertices);
        HL_CHECK(s.degenerate_triangles == 0, "degenerate %u", s.degenerate_triangles);
        HL_CHECK(m->vertex_count == 34834 && m->object_vertex_count == 34834, "vertices %u", m->vertex_count);
        HL_CHECK(m->triangle_count == 69451, "triangles %u", m->triangle_count);
        HL_CHECK(!s.flipped && !s.had_normals && !s.had_colors, "flags");
        float lo[3], hi[3], elo[3] = {-0.09469f, 0.032987f, -0.061874f}, ehi[3] = {0.061009f, 0.187321f, 0.0588f};
        bbox(m, 0, m->vertex_count, lo, hi);
        double worst = 0.0;
        for (int k = 0; k < 3; k++) worst = fmax(worst, fmax(fabs(lo[k] - elo[k]), fabs(hi[k] - ehi[k])));
        hl_check_error("bunny bounding box vs README", worst, 1e-6);
        double aerr = 0.0;
        for (size_t i = 0; i < 3 * (size_t)m->vertex_count; i++) aerr = fmax(aerr, fabs(m->albedo[i] - 0.8f));
        hl_check_error("bunny default albedo 0.8", aerr, 0.0);
        hl_check_error("bunny diagonal", fabs(hl_mesh_query_diagonal(m) -
                       sqrt(pow(ehi[0] - elo[0], 2) + pow(ehi[1] - elo[1], 2) + pow(ehi[2] - elo[2], 2))), 1e-6);
        check_sane("bunny", m);
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void test_teapot(void)
{
    if (!have_data()) return;
    hl_context *ctx = make_ctx();
    hl_mesh *m = NULL;
    hl_mesh_stats s;
    HL_CHECK(load(ctx, data_path("teapot.obj"), NULL, &m, &s) == HL_OK, "load");
    if (m) {
        print_stats("teapot", m, &s);
        /* the README: 3,644 file vertices of which 403 repeat a position */
        HL_CHECK(s.file_triangles == 6320, "file counts");
        HL_CHECK(m->vertex_count == 3644 - 403, "vertices %u", m->vertex_count);
        HL_CHECK(m->triangle_count == 6320, "triangles %u", m->triangle_count);
        HL_CHECK(!s.flipped, "an open mesh is never flipped");
        /* Welded seams: no two output vertices share a position. */
        uint32_t dup = 0;
        for (uint32_t a = 0; a < m->vertex_count && dup == 0; a++)
            for (uint32_t b = a + 1; b < m->vertex_count; b++)
                if (memcmp(m->positions + 3 * (size_t)a, m->positions + 3 * (size_t)b, 12) == 0) dup++;
        HL_CHECK(dup == 0, "positions still duplicated after welding");
        hl_check_error("teapot normal length", check_sane("teapot", m), 1e-6);
        double agree = winding_agreement(m);
        printf("teapot: %.4f of triangles agree with their vertex normals\n", agree);
        HL_CHECK(agree > 0.99, "normals disagree with the winding");
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void test_horse_up_z(void)
{
    if (!have_data()) return;
    hl_context *ctx = make_ctx();
    hl_mesh_load_desc d = {0};
    d.up_axis = 'z';
    hl_mesh *m = NULL;
    hl_mesh_stats s;
    HL_CHECK(load(ctx, data_path("horse.obj"), &d, &m, &s) == HL_OK, "load");
    if (m) {
        print_stats("horse", m, &s);
        HL_CHECK(m->vertex_count == 48485 && m->triangle_count == 96966, "counts");
        HL_CHECK(s.flipped == 1, "the inward horse must be flipped");
        double vol = mesh_volume(m);
        printf("horse: signed volume after loading %.6g\n", vol);
        HL_CHECK(vol > 0.0, "signed volume %g should be positive", vol);
        /* +Z up: file z becomes y, file y becomes -z. */
        float lo[3], hi[3];
        bbox(m, 0, m->vertex_count, lo, hi);
        double worst = 0.0;
        float elo[3] = {-0.042003002f, -0.076418f, -0.091670506f}, ehi[3] = {0.042003002f, 0.076418005f, 0.0916705f};
        for (int k = 0; k < 3; k++) worst = fmax(worst, fmax(fabs(lo[k] - elo[k]), fabs(hi[k] - ehi[k])));
        hl_check_error("horse bounding box after the z-up turn", worst, 0.0);
        /* Outward normals: on average they point away from the centre. */
        double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])}, out = 0.0;
        for (size_t v = 0; v < m->vertex_count; v++)
            for (int k = 0; k < 3; k++) out += m->normals[3 * v + k] * (m->positions[3 * v + k] - c[k]);
        HL_CHECK(out > 0.0, "normals point inward on average");
        double agree = winding_agreement(m);
        printf("horse: %.5f of triangles agree with their vertex normals\n", agree);
        HL_CHECK(agree > 0.99, "normals disagree with the winding");
        hl_check_error("horse normal length", check_sane("horse", m), 1e-6);
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void test_horse_keep_winding(void)
{
    if (!have_data()) return;
    hl_context *ctx = make_ctx();
    hl_mesh_load_desc d = {0};
    d.up_axis = 'z';
    d.keep_winding = 1;
    hl_mesh *m = NULL;
    hl_mesh_stats s;
    HL_CHECK(load(ctx, data_path("horse.obj"), &d, &m, &s) == HL_OK, "load");
    if (m) {
        double vol = mesh_volume(m);
        printf("horse (keep winding): flipped %d, signed volume %.6g\n", s.flipped, vol);
        HL_CHECK(!s.flipped && vol < 0.0, "keep_winding must leave the inward winding");
        HL_CHECK(winding_agreement(m) > 0.99, "computed normals must follow the kept winding");
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void test_normals(void)
{
    if (!have_data()) return;
    const char *names[] = {"bunny.obj", "bunny_lowres.obj", "teapot.obj", "teapot_lowres.obj",
                           "armadillo.obj", "horse.obj", "dragon_res2.obj"};
    hl_context *ctx = make_ctx();
    double worst = 0.0;
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        hl_mesh *m = NULL;
        hl_mesh_stats s;
        hl_mesh_load_desc d = {0};
        if (strcmp(names[i], "horse.obj") == 0) d.up_axis = 'z';
        HL_CHECK(load(ctx, data_path(names[i]), &d, &m, &s) == HL_OK, "load %s", names[i]);
        if (!m) continue;
        print_stats(names[i], m, &s);
        double w = check_sane(names[i], m);
        double agree = winding_agreement(m);
        printf("%s: normal length error %.3g, %.5f of triangles agree with their vertex normals\n", names[i], w,
               agree);
        /* dragon_res2 has back-to-back flaps, where some disagreement is
         * unavoidable; the rest should agree almost everywhere. */
        HL_CHECK(agree > 0.97, "%s: normals disagree with the winding", names[i]);
        if (strcmp(names[i], "bunny_lowres.obj") == 0 || strcmp(names[i], "armadillo.obj") == 0)
            HL_CHECK(!s.flipped && mesh_volume(m) > 0, "%s: closed outward mesh must stay as it is", names[i]);
        worst = fmax(worst, w);
        hl_mesh_destroy(m);
    }
    hl_check_error("normal length over all shared meshes", worst, 1e-6);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- ground */

static void check_ground(const char *what, hl_mesh *m, uint32_t res, double margin)
{
    uint32_t ov = m->vertex_count, ot = m->triangle_count;
    float lo[3], hi[3];
    bbox(m, 0, ov, lo, hi);
    double mean[3] = {0, 0, 0};
    for (size_t v = 0; v < ov; v++)
        for (int k = 0; k < 3; k++) mean[k] += (double)m->albedo[3 * v + k] / ov;
    float diag0 = hl_mesh_query_diagonal(m);
    hl_ground_desc gd = {0};
    gd.resolution = res == 96 ? 0 : res;
    gd.margin = margin == 0.75 ? 0.0f : (float)margin;
    hl_result r = hl_mesh_add_ground(NULL, m, &gd);
    HL_CHECK(r == HL_OK, "%s: add ground", what);
    if (r != HL_OK) return;
    HL_CHECK(m->object_vertex_count == ov, "%s: object_vertex_count %u", what, m->object_vertex_count);
    HL_CHECK(m->vertex_count == ov + (res + 1) * (res + 1), "%s: vertex count %u", what, m->vertex_count);
    HL_CHECK(m->triangle_count == ot + 2 * res * res, "%s: triangle count %u", what, m->triangle_count);
    double nerr = 0.0, yerr = 0.0, aerr = 0.0, gerr = 0.0;
    for (size_t v = ov; v < m->vertex_count; v++) {
        const float *n = m->normals + 3 * v;
        nerr = fmax(nerr, fabs(n[0]) + fabs(n[1] - 1.0) + fabs(n[2]));
        yerr = fmax(yerr, fabs(m->positions[3 * v + 1] - lo[1]));
        for (int k = 0; k < 3; k++) aerr = fmax(aerr, fabs(m->albedo[3 * v + k] - mean[k]));
    }
    uint32_t ground_tris = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *f = m->indices + 3 * (size_t)t;
        int g = f[0] >= ov, g1 = f[1] >= ov, g2 = f[2] >= ov;
        HL_CHECK(g == g1 && g == g2, "%s: triangle %u mixes ground and object", what, t);
        if (!g) continue;
        ground_tris++;
        double n[3];
        face_normal(m, t, n);
        gerr = fmax(gerr, 1.0 - n[1]);
    }
    HL_CHECK(ground_tris == 2 * res * res, "%s: ground triangles %u", what, ground_tris);
    hl_check_error("ground vertex normals == +Y", nerr, 0.0);
    hl_check_error("ground y == mesh min y", yerr, 0.0);
    hl_check_error("ground albedo == mean object albedo", aerr, 1e-6);
    hl_check_error("ground triangle geometric normals (1 - n.y)", gerr, 1e-9);
    /* Covers the footprint plus margin x larger extent on every side. */
    float glo[3], ghi[3];
    bbox(m, ov, m->vertex_count, glo, ghi);
    double ext = fmax(hi[0] - lo[0], hi[2] - lo[2]), cover = 0.0;
    cover = fmax(cover, glo[0] - (lo[0] - margin * ext));
    cover = fmax(cover, (hi[0] + margin * ext) - ghi[0]);
    cover = fmax(cover, glo[2] - (lo[2] - margin * ext));
    cover = fmax(cover, (hi[2] + margin * ext) - ghi[2]);
    hl_check_error("ground coverage shortfall (relative to extent)", fmax(cover, 0.0) / ext, 1e-6);
    HL_CHECK(hl_mesh_query_diagonal(m) > diag0, "%s: diagonal should grow with the ground", what);
    check_sane(what, m);
    HL_CHECK(hl_mesh_add_ground(NULL, m, NULL) == HL_ERR_INVALID_ARGUMENT, "%s: a second ground must be refused", what);
}

static void test_ground(void)
{
    hl_context *ctx = make_ctx();
    /* Synthetic: a tetrahedron, always available. */
    const float p[] = {0, 1, 0, -1, 0, -1, 1, 0, -1, 0, 0.5f, 1};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
    const float alb[] = {0.2f, 0.4f, 0.6f, 0.4f, 0.4f, 0.4f, 0.6f, 0.4f, 0.2f, 0.2f, 0.2f, 0.2f};
    hl_mesh *m = NULL;
    HL_CHECK(hl_mesh_create(ctx, 4, p, NULL, alb, 4, idx, &m) == HL_OK, "create: %s", hl_context_last_error(ctx));
    if (m) check_ground("tetrahedron ground 7, margin 0.5", m, 7, 0.5);
    hl_mesh_destroy(m);
    m = NULL;
    HL_CHECK(hl_mesh_create(ctx, 4, p, NULL, NULL, 4, idx, &m) == HL_OK, "create");
    if (m) {
        hl_ground_desc gd = {0};
        gd.resolution = 100000;
        hl_result r = hl_mesh_add_ground(ctx, m, &gd);
        printf("  huge resolution -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
        HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && m->object_vertex_count == m->vertex_count, "huge resolution");
        gd.resolution = 4;
        gd.margin = -1.0f;
        HL_CHECK(hl_mesh_add_ground(ctx, m, &gd) == HL_ERR_INVALID_ARGUMENT, "negative margin");
        gd.margin = 0.0f;
        gd.albedo[0] = 0.3f;
        gd.albedo[1] = 0.5f;
        gd.albedo[2] = 0.7f;
        HL_CHECK(hl_mesh_add_ground(ctx, m, &gd) == HL_OK, "explicit ground albedo");
        const float *a = m->albedo + 3 * (size_t)(m->vertex_count - 1);
        HL_CHECK(a[0] == 0.3f && a[1] == 0.5f && a[2] == 0.7f, "ground albedo %g %g %g", a[0], a[1], a[2]);
    }
    hl_mesh_destroy(m);
    HL_CHECK(hl_mesh_add_ground(ctx, NULL, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL mesh");

    if (have_data()) {
        m = NULL;
        hl_mesh_stats s;
        HL_CHECK(load(ctx, data_path("bunny.obj"), NULL, &m, &s) == HL_OK, "load bunny");
        if (m) check_ground("bunny default ground", m, 96, 0.75);
        hl_mesh_destroy(m);
    }
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- synthetic */

static void test_ply(void)
{
    hl_context *ctx = make_ctx();
    /* A quad in y = 0 (triangulated by the importer), one unreferenced
     * vertex, colours as bytes. The quad winds so its normal is +Y. */
    const char *ply =
        "ply\nformat ascii 1.0\ncomment haarlight mesh test\nelement vertex 5\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0 255 0 0\n1 0 0 0 255 0\n0 0 1 0 0 255\n1 0 1 255 255 255\n5 5 5 1 2 3\n"
        "4 0 2 3 1\n";
    const char *path = tmp_path("mesh_colours.ply");
    write_text(path, ply);
    hl_mesh *m = NULL;
    hl_mesh_stats s;
    HL_CHECK(load(ctx, path, NULL, &m, &s) == HL_OK, "load ply");
    if (m) {
        print_stats("ply", m, &s);
        HL_CHECK(s.had_colors == 1, "colours should be used");
        HL_CHECK(s.file_vertices == 5 && s.file_triangles == 2, "file counts");
        HL_CHECK(m->vertex_count == 4 && m->triangle_count == 2 && s.unreferenced_vertices == 1, "counts");
        const float expect[4][6] = {{0, 0, 0, 1, 0, 0}, {1, 0, 0, 0, 1, 0}, {0, 0, 1, 0, 0, 1}, {1, 0, 1, 1, 1, 1}};
        double worst = 0.0;
        int found = 0;
        for (uint32_t v = 0; v < m->vertex_count; v++)
            for (int e = 0; e < 4; e++)
                if (memcmp(m->positions + 3 * (size_t)v, expect[e], 12) == 0) {
                    found++;
                    for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(m->albedo[3 * v + k] - expect[e][3 + k]));
                }
        HL_CHECK(found == 4, "found %d of 4 vertices", found);
        hl_check_error("ply colour -> albedo", worst, 1e-6);
        double nerr = 0.0;
        for (uint32_t v = 0; v < m->vertex_count; v++)
            nerr = fmax(nerr, fabs(m->normals[3 * v]) + fabs(m->normals[3 * v + 1] - 1.0) + fabs(m->normals[3 * v + 2]));
        hl_check_error("ply normals == +Y", nerr, 1e-6);
        check_sane("ply", m);
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void test_create(void)
{
    hl_context *ctx = make_ctx();
    /* Inward tetrahedron: every face wound clockwise seen from outside. */
    const float p[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    const uint32_t inward[] = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
    hl_mesh *m = NULL;
    HL_CHECK(hl_mesh_create(ctx, 4, p, NULL, NULL, 4, inward, &m) == HL_OK, "create");
    if (m) {
        double vol = mesh_volume(m);
        printf("tetrahedron: volume %.6g after create (input was %.6g)\n", vol, -1.0 / 6.0);
        hl_check_error("tetrahedron volume after flip", fabs(vol - 1.0 / 6.0), 1e-12);
        HL_CHECK(winding_agreement(m) == 1.0, "normals must follow the flipped winding");
        hl_check_error("tetrahedron normal length", check_sane("tetrahedron", m), 1e-6);
    }
    hl_mesh_destroy(m);

    /* A cube as 24 split vertices plus degenerate faces: welding gives 8,
     * the degenerate faces go, the closed result keeps outward winding. */
    float cube[24 * 3];
    uint32_t ci[14 * 3];
    const int faces[6][4][3] = {
        {{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}},
        {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}}, {{0, 1, 0}, {0, 1, 1}, {1, 1, 1}, {1, 1, 0}},
        {{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}}};
    for (int f = 0; f < 6; f++) {
        for (int c = 0; c < 4; c++)
            for (int k = 0; k < 3; k++) cube[3 * (4 * f + c) + k] = (float)faces[f][c][k];
        uint32_t b = (uint32_t)(4 * f);
        uint32_t q[6] = {b, b + 1, b + 2, b, b + 2, b + 3};
        memcpy(ci + 6 * f, q, sizeof q);
    }
    uint32_t degen[6] = {0, 0, 1, /* repeated index */ 0, 1, 8 /* 8 welds onto 0: repeated after welding */};
    memcpy(ci + 36, degen, sizeof degen);
    m = NULL;
    HL_CHECK(hl_mesh_create(ctx, 24, cube, NULL, NULL, 14, ci, &m) == HL_OK, "cube: %s", hl_context_last_error(ctx));
    if (m) {
        printf("cube: %u vertices, %u triangles, volume %.6g\n", m->vertex_count, m->triangle_count, mesh_volume(m));
        HL_CHECK(m->vertex_count == 8 && m->triangle_count == 12, "cube counts");
        hl_check_error("cube volume", fabs(mesh_volume(m) - 1.0), 1e-12);
        double out = 1.0;
        for (uint32_t v = 0; v < 8; v++) {
            double d = 0;
            for (int k = 0; k < 3; k++) d += m->normals[3 * v + k] * (m->positions[3 * v + k] - 0.5);
            out = fmin(out, d);
        }
        HL_CHECK(out > 0.0, "cube normals must point outward");
        check_sane("cube", m);
    }
    hl_mesh_destroy(m);

    /* Supplied normals and albedo: normalised, zero normals replaced,
     * albedo clamped. One triangle in y = 0 wound towards +Y. */
    const float tp[] = {0, 0, 0, 0, 0, 1, 1, 0, 0};
    const float tn[] = {0, 2, 0, 0, 0, 0, NAN, 0, 0};
    const float ta[] = {0.5f, 0.5f, 0.5f, 2.0f, -1.0f, 0.25f, 0, 0, 0};
    const uint32_t ti[] = {0, 1, 2};
    m = NULL;
    HL_CHECK(hl_mesh_create(ctx, 3, tp, tn, ta, 1, ti, &m) == HL_OK, "triangle: %s", hl_context_last_error(ctx));
    if (m) {
        double nerr = 0.0;
        for (int v = 0; v < 3; v++)
            nerr = fmax(nerr, fabs(m->normals[3 * v]) + fabs(m->normals[3 * v + 1] - 1.0) + fabs(m->normals[3 * v + 2]));
        hl_check_error("supplied / fallback normals == +Y", nerr, 1e-6);
        HL_CHECK(m->albedo[3] == 1.0f && m->albedo[4] == 0.0f && m->albedo[5] == 0.25f, "albedo clamp");
    }
    hl_mesh_destroy(m);

    /* Bad arrays: message names "<memory>" and the culprit. */
    const float nanp[] = {0, 0, 0, 1, 0, 0, 0, NAN, 1};
    hl_result r = hl_mesh_create(ctx, 3, nanp, NULL, NULL, 1, ti, &m);
    printf("  NaN -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_MESH && m == NULL && strstr(hl_context_last_error(ctx), "<memory>") &&
             strstr(hl_context_last_error(ctx), "vertex 2"), "NaN position");
    const uint32_t oor[] = {0, 1, 3};
    r = hl_mesh_create(ctx, 3, tp, NULL, NULL, 1, oor, &m);
    printf("  index -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_MESH && strstr(hl_context_last_error(ctx), "face 0") &&
             strstr(hl_context_last_error(ctx), "vertex 3"), "index out of range");
    const float line[] = {0, 0, 0, 1, 1, 1, 2, 2, 2};
    r = hl_mesh_create(ctx, 3, line, NULL, NULL, 1, ti, &m);
    printf("  collinear -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_MESH, "all-degenerate mesh");
    r = hl_mesh_create(ctx, 0, NULL, NULL, NULL, 0, NULL, &m);
    HL_CHECK(r == HL_ERR_MESH && strstr(hl_context_last_error(ctx), "<memory>"), "empty mesh");
    r = hl_mesh_create(ctx, 3, NULL, NULL, NULL, 1, ti, &m);
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, "NULL positions");

    hl_mesh_destroy(NULL);
    HL_CHECK(hl_mesh_query_diagonal(NULL) == 0.0f, "diagonal of NULL");
    hl_context_destroy(ctx);
}

static void test_obj_features(void)
{
    hl_context *ctx = make_ctx();
    /* CRLF, comments, groups, texture coordinates, normals, colours,
     * polygons, negative indices, a line element. */
    const char *obj =
        "# test\r\nmtllib none.mtl\r\no thing\r\ng part\r\ns 1\r\n"
        "v 0 0 0 1 0 0\r\nv 1 0 0 0 1 0\r\nv 1 0 1 0 0 1\r\nv 0 0 1 0.5 0.5 0.5\r\nv 0.5 0 1.5 2 -1 0.5\r\n"
        "vt 0 0\r\nvt 1 0\r\nvn 0 3 0\r\nusemtl x\r\n"
        "f 1/1/1 4/2/1 5//1 3/1/1 2//-1\r\n"
        "l 1 2\r\n";
    const char *path = tmp_path("mesh_features.obj");
    write_text(path, obj);
    hl_mesh *m = NULL;
    hl_mesh_stats s;
    HL_CHECK(load(ctx, path, NULL, &m, &s) == HL_OK, "load");
    if (m) {
        print_stats("features", m, &s);
        HL_CHECK(m->vertex_count == 5 && m->triangle_count == 3, "pentagon -> 3 triangles");
        HL_CHECK(s.had_normals && s.had_colors, "normals and colours should be used");
        double nerr = 0.0;
        for (uint32_t v = 0; v < m->vertex_count; v++)
            nerr = fmax(nerr, fabs(m->normals[3 * v]) + fabs(m->normals[3 * v + 1] - 1.0) + fabs(m->normals[3 * v + 2]));
        hl_check_error("file normals normalised", nerr, 1e-7);
        /* vertex 5's colour (2, -1, 0.5) is clamped to (1, 0, 0.5) */
        int clamped = 0;
        for (uint32_t v = 0; v < m->vertex_count; v++)
            clamped += m->albedo[3 * v] == 1.0f && m->albedo[3 * v + 1] == 0.0f && m->albedo[3 * v + 2] == 0.5f;
        HL_CHECK(clamped == 1, "colour clamp: %d vertices with (1, 0, 0.5)", clamped);
        HL_CHECK(winding_agreement(m) == 1.0, "fan triangles keep the polygon's winding");
    }
    hl_mesh_destroy(m);

    /* +Z up: (x, y, z) -> (x, z, -y). Closed outward tetrahedron in z-up. */
    const char *zup = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0.25 0.25 2\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n";
    path = tmp_path("mesh_zup.obj");
    write_text(path, zup);
    hl_mesh_load_desc d = {0};
    d.up_axis = 'Z';
    m = NULL;
    HL_CHECK(load(ctx, path, &d, &m, &s) == HL_OK, "load z-up");
    if (m) {
        const float e[] = {0.25f, 2.0f, -0.25f};
        HL_CHECK(memcmp(m->positions + 9, e, 12) == 0, "z-up vertex 4 -> (%g %g %g)", m->positions[9],
                 m->positions[10], m->positions[11]);
        HL_CHECK(!s.flipped && mesh_volume(m) > 0, "an outward mesh stays outward after the turn");
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* The same pyramid as OBJ and as PLY must give the same welded mesh. */
static int cmp_pos(const void *a, const void *b)
{
    const float *p = a, *q = b;
    for (int k = 0; k < 3; k++)
        if (p[k] != q[k]) return p[k] < q[k] ? -1 : 1;
    return 0;
}

static void test_obj_vs_ply(void)
{
    hl_context *ctx = make_ctx();
    const char *obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\nf 1 2 3 4\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n";
    const char *ply = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 5\nproperty list uchar int vertex_indices\nend_header\n"
                      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n4 0 1 2 3\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4\n";
    const char *po = tmp_path("mesh_pyramid.obj");
    write_text(po, obj);
    char pp[1024];
    snprintf(pp, sizeof pp, "%s", tmp_path("mesh_pyramid.ply"));
    write_text(pp, ply);
    hl_mesh *a = NULL, *b = NULL;
    hl_mesh_stats sa, sb;
    HL_CHECK(load(ctx, po, NULL, &a, &sa) == HL_OK, "OBJ load");
    HL_CHECK(load(ctx, pp, NULL, &b, &sb) == HL_OK, "PLY load");
    if (a && b) {
        print_stats("obj", a, &sa);
        print_stats("ply", b, &sb);
        HL_CHECK(a->vertex_count == 5 && b->vertex_count == 5, "welded counts %u %u", a->vertex_count, b->vertex_count);
        HL_CHECK(a->triangle_count == 6 && b->triangle_count == 6, "triangles %u %u", a->triangle_count, b->triangle_count);
        if (a->vertex_count == b->vertex_count) {
            size_t n = a->vertex_count;
            qsort(a->positions, n, 12, cmp_pos);
            qsort(b->positions, n, 12, cmp_pos);
            double worst = 0.0;
            for (size_t i = 0; i < 3 * n; i++) worst = fmax(worst, fabs(a->positions[i] - b->positions[i]));
            hl_check_error("OBJ vs PLY positions", worst, 0.0);
        }
    }
    hl_mesh_destroy(a);
    hl_mesh_destroy(b);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- bad input */

static void test_bad_nan(void)
{
    hl_context *ctx = make_ctx();
    const char *cases[][2] = {
        {"mesh_bad_nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n"},
        {"mesh_bad_inf.obj", "v 0 0 0\nv 1 0 -inf\nv 0 1 0\nf 1 2 3\n"},
        {"mesh_bad_huge.obj", "v 0 0 0\nv 1 0 0\nv 0 1e50 0\nf 1 2 3\n"},
        {"mesh_bad_nan_colour.obj", "v 0 0 0 1 1 1\nv 1 0 0 1 nan 1\nv 0 1 0 1 1 1\nf 1 2 3\n"},
        {"mesh_bad_text_coord.obj", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        const char *path = tmp_path(cases[i][0]);
        write_text(path, cases[i][1]);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, i < 4 ? HL_ERR_MESH : HL_ERR_FORMAT);
        HL_CHECK(m == NULL, "no mesh on failure");
        if (i == 0) HL_CHECK(strstr(hl_context_last_error(ctx), "non-finite") != NULL, "says what is wrong");
    }
    hl_context_destroy(ctx);
}

static void test_bad_index(void)
{
    hl_context *ctx = make_ctx();
    const char *cases[][2] = {
        {"mesh_bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n"},
        {"mesh_bad_negative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n"},
        {"mesh_bad_zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"},
        {"mesh_bad_normal_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n"},
        {"mesh_bad_huge_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n"},
        {"mesh_bad_index.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                               "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        const char *path = tmp_path(cases[i][0]);
        write_text(path, cases[i][1]);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        if (i == 3 && r == HL_OK) {
            /* assimp accepts a bad normal index; what comes out must
             * still be usable: finite unit normals */
            double worst = 0.0;
            for (uint32_t v = 0; v < m->vertex_count; v++) {
                const float *n = m->normals + 3 * v;
                double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
                worst = isfinite(len) ? fmax(worst, fabs(len - 1.0)) : INFINITY;
            }
            hl_check_error("bad normal index: normal length", worst, 1e-6);
            hl_mesh_destroy(m);
            continue;
        }
        /* the importer reports bad indices (HL_ERR_FORMAT); the builder
         * catches any it lets through (HL_ERR_MESH) */
        expect_failure(ctx, path, r, HL_OK);
        HL_CHECK(r == HL_ERR_FORMAT || r == HL_ERR_MESH, "%s: got %s", path, hl_result_string(r));
    }
    hl_context_destroy(ctx);
}

static void test_bad_no_faces(void)
{
    hl_context *ctx = make_ctx();
    const char *cases[][2] = {
        {"mesh_no_faces.obj", "# only vertices\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"},
        {"mesh_only_lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\nf 1 2\n"},
        {"mesh_no_faces.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                              "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        const char *path = tmp_path(cases[i][0]);
        write_text(path, cases[i][1]);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, i < 2 ? HL_ERR_MESH : HL_OK);
    }
    hl_context_destroy(ctx);
}

/* PLY and OFF files whose counts claim more than the file holds: assimp
 * would make room for all of it first (gigabytes from a few hundred bytes,
 * or minutes of filling in zeros), so they are refused before it reads
 * them, quickly and with the reason. The same layouts with honest counts,
 * in both binary byte orders and with a blank line in ASCII, load. */
static void put_u32(unsigned char *p, uint32_t v, int big)
{
    for (int k = 0; k < 4; k++) p[big ? 3 - k : k] = (unsigned char)(v >> (8 * k));
}

/* A binary PLY of one triangle; the face list's count is `count`. */
static size_t binary_ply(unsigned char *buf, int big, uint32_t count)
{
    int n = snprintf((char *)buf, 512,
                     "ply\nformat binary_%s_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n",
                     big ? "big" : "little");
    static const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 0, -1};
    size_t at = (size_t)n;
    for (int i = 0; i < 9; i++) {
        uint32_t bits;
        memcpy(&bits, &xyz[i], 4);
        put_u32(buf + at, bits, big);
        at += 4;
    }
    put_u32(buf + at, count, big);
    at += 4;
    for (uint32_t i = 0; i < 3; i++, at += 4) put_u32(buf + at, i, big);
    return at;
}

/* Loads path, which must be refused (HL_ERR_FORMAT, naming the file) with
 * why in the message; the time taken goes into *slowest. */
static void refused_with(hl_context *ctx, const char *path, const char *why, double *slowest)
{
    hl_mesh *m = NULL;
    double t0 = hl_now();
    hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
    *slowest = fmax(*slowest, hl_now() - t0);
    expect_failure(ctx, path, r, HL_ERR_FORMAT);
    HL_CHECK(strstr(hl_context_last_error(ctx), why) != NULL, "%s: the message does not say \"%s\"", path, why);
    hl_mesh_destroy(m);
}

/* Loads path, which must give one triangle. */
static void one_triangle(hl_context *ctx, const char *path)
{
    hl_mesh *m = NULL;
    HL_CHECK(load(ctx, path, NULL, &m, NULL) == HL_OK && m && m->triangle_count == 1,
             "%s: an honest triangle must load", path);
    hl_mesh_destroy(m);
}

static void test_bad_counts(void)
{
    hl_context *ctx = make_ctx();
    static const char head[] = "ply\nformat ascii 1.0\nelement vertex %s\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                               "0 0 0\n1 0 0\n0 0 -1\n%s\n";
    const struct {
        const char *name, *vertices, *face;
        const char *why;
    } ascii[] = {
        {"mesh_ply_list.ply", "3", "300000000 0 1 2", "a list of 300000000 values"},
        {"mesh_ply_list_digits.ply", "3", "34444444444444444444444444444444 0 1 2", "a list of"},
        {"mesh_ply_elements.ply", "300000000", "3 0 1 2", "300000000 \"vertex\" elements"},
        {"mesh_ply_short.ply", "5", "3 0 1 2", "the file ends after"},
    };
    char text[1024];
    double slowest = 0.0;
    for (size_t k = 0; k < sizeof ascii / sizeof ascii[0]; k++) {
        snprintf(text, sizeof text, head, ascii[k].vertices, ascii[k].face);
        const char *path = tmp_path(ascii[k].name);
        write_text(path, text);
        refused_with(ctx, path, ascii[k].why, &slowest);
    }
    unsigned char bin[1024];
    for (int big = 0; big < 2; big++) {
        const char *path = tmp_path(big ? "mesh_ply_list_be.ply" : "mesh_ply_list_le.ply");
        write_file(path, bin, binary_ply(bin, big, 300000000u));
        refused_with(ctx, path, "a list of 300000000 values", &slowest);
        write_file(path, bin, binary_ply(bin, big, 3u)); /* honest: loads */
        one_triangle(ctx, path);
    }
    /* honest ASCII, a blank line between the vertices and the face */
    snprintf(text, sizeof text, head, "3", "\n3 0 1 2");
    const char *path = tmp_path("mesh_ply_honest.ply");
    write_text(path, text);
    one_triangle(ctx, path);
    /* OFF: vertex and face counts beyond the lines that follow */
    static const char *const off[][2] = {{"mesh_off_vertices.off", "OFF\n300000000 1 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2\n"},
                                         {"mesh_off_faces.off", "# a comment\nOFF\n3 300000000 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2\n"},
                                         {"mesh_off_headerless.off", "3000000000 1 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2\n"}};
    for (size_t k = 0; k < sizeof off / sizeof off[0]; k++) {
        const char *opath = tmp_path(off[k][0]);
        write_text(opath, off[k][1]);
        refused_with(ctx, opath, "lines follow", &slowest);
    }
    /* under a glTF name: assimp would offer it to its OFF reader when the
       glTF one turns it down */
    const char *gpath = tmp_path("mesh_off_named_glb.glb");
    write_text(gpath, "OFF\n3 300000000 0\n0 0 0\n");
    refused_with(ctx, gpath, "not a binary glTF file", &slowest);
    const char *opath = tmp_path("mesh_off_honest.off");
    write_text(opath, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2"); /* no final line end */
    one_triangle(ctx, opath);
    /* not a time limit: assimp took seconds to minutes on these */
    printf("slowest refusal: %.3f s\n", slowest);
    hl_context_destroy(ctx);
}

static void test_bad_not_mesh(void)
{
    hl_context *ctx = make_ctx();
    /* Deterministic pseudo-random bytes under several extensions, and
     * plain text. */
    unsigned char junk[4096];
    uint32_t x = 12345;
    for (size_t i = 0; i < sizeof junk; i++) {
        x = x * 1664525u + 1013904223u;
        junk[i] = (unsigned char)(x >> 24);
    }
    const char *bin[] = {"mesh_random.obj", "mesh_random.bin", "mesh_random.ply", "mesh_random.stl",
                         "mesh_random.gltf"};
    for (size_t i = 0; i < sizeof bin / sizeof *bin; i++) {
        const char *path = tmp_path(bin[i]);
        write_file(path, junk, sizeof junk);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_OK);
        hl_mesh_destroy(m);
    }
    const char *txt[] = {"mesh_text.obj", "mesh_text.txt"};
    for (size_t i = 0; i < sizeof txt / sizeof *txt; i++) {
        const char *path = tmp_path(txt[i]);
        write_text(path, "This is a shopping list, not a mesh.\nEggs\nMilk\n");
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_ERR_FORMAT);
        hl_mesh_destroy(m);
    }
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- scenes
 * Files whose scene assimp 5.2's post-processing aborts, throws or
 * overruns on: they must be refused before it runs (see load_assimp). */

/* Writes a binary glTF: the JSON, then `bin` as its buffer 0. */
static void write_glb(const char *path, const char *json, const void *bin, size_t bin_size)
{
    size_t jpad = (strlen(json) + 3) & ~(size_t)3, bpad = (bin_size + 3) & ~(size_t)3;
    size_t total = 12 + 8 + jpad + 8 + bpad;
    unsigned char *b = calloc(1, total);
    if (!b) {
        fprintf(stderr, "out of memory for %s\n", path);
        exit(1);
    }
    memcpy(b, "glTF", 4);
    put_u32(b + 4, 2, 0);
    put_u32(b + 8, (uint32_t)total, 0);
    put_u32(b + 12, (uint32_t)jpad, 0);
    memcpy(b + 16, "JSON", 4);
    memset(b + 20, ' ', jpad);
    memcpy(b + 20, json, strlen(json));
    put_u32(b + 20 + jpad, (uint32_t)bpad, 0);
    memcpy(b + 24 + jpad, "BIN\0", 4);
    memcpy(b + 28 + jpad, bin, bin_size);
    write_file(path, b, total);
    free(b);
}

/* A binary glTF with one mesh of `nv` vertices on a grid and one triangle
 * (vertices 0, 1 and 256 when nv > 256, else 0, 1, 2), placed by `copies`
 * nodes, the children of the scene's one root node. */
static void write_instanced_glb(const char *path, uint32_t nv, uint32_t copies)
{
    size_t bin_size = (size_t)nv * 12 + 12;
    unsigned char *bin = malloc(bin_size);
    size_t cap = 1024 + (size_t)copies * 24;
    char *json = malloc(cap);
    if (!bin || !json) {
        fprintf(stderr, "out of memory for %s\n", path);
        exit(1);
    }
    for (uint32_t i = 0; i < nv; i++) {
        const float xyz[3] = {(float)(i % 256) / 256.0f, (float)(i / 256) / 256.0f, 0.0f};
        for (int k = 0; k < 3; k++) {
            uint32_t bits;
            memcpy(&bits, &xyz[k], 4);
            put_u32(bin + 12 * (size_t)i + 4 * (size_t)k, bits, 0);
        }
    }
    const uint32_t tri[3] = {0, 1, nv > 256 ? 256 : 2};
    for (int k = 0; k < 3; k++) put_u32(bin + (size_t)nv * 12 + 4 * (size_t)k, tri[k], 0);
    size_t n = (size_t)snprintf(json, cap, "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
                                           "\"nodes\":[{\"children\":[");
    for (uint32_t c = 1; c <= copies; c++) n += (size_t)snprintf(json + n, cap - n, "%s%u", c > 1 ? "," : "", c);
    n += (size_t)snprintf(json + n, cap - n, "]}");
    for (uint32_t c = 1; c <= copies; c++) n += (size_t)snprintf(json + n, cap - n, ",{\"mesh\":0}");
    snprintf(json + n, cap - n,
             "],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}],"
             "\"buffers\":[{\"byteLength\":%zu}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu},{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":12}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\","
             "\"min\":[0,0,0],\"max\":[1,1,0]},{\"bufferView\":1,\"componentType\":5125,\"count\":3,\"type\":\"SCALAR\"}]}",
             bin_size, (size_t)nv * 12, (size_t)nv * 12, nv);
    write_glb(path, json, bin, bin_size);
    free(json);
    free(bin);
}

/* Loads path, which must be refused with `code`, naming the file, with
 * why in the message. */
static void refused_because(hl_context *ctx, const char *path, hl_result code, const char *why)
{
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
    expect_failure(ctx, path, r, code);
    HL_CHECK(strstr(hl_context_last_error(ctx), why) != NULL, "%s: the message does not say \"%s\"", path, why);
    hl_mesh_destroy(m);
}

/* A scene in which no node references a mesh: assimp's
 * PretransformVertices throws "No output meshes", and the C API's
 * aiApplyPostProcessing then released the deleted scene again (a
 * segfault, first seen on AC/nosurfaces.ac of assimp-testmodels). AC3D:
 * an object with vertices and no surfaces becomes a mesh of points that
 * no node holds, at the top level or inside a world object. glTF: a mesh
 * whose only node is outside the scene, loaded through a skin's joints.
 * The same files with a surface, or with the node in the scene, load. */
static void test_bad_no_placed_mesh(void)
{
    hl_context *ctx = make_ctx();
    static const char verts[] = "numvert 3\n0 0 0\n1 0 0\n0 1 0\n";
    static const char surf[] = "numsurf 1\nSURF 0x10\nmat 0\nrefs 3\n0 0 0\n1 0 0\n2 0 0\n";
    char text[512];
    const char *ac = tmp_path("mesh_no_surfaces.ac");
    snprintf(text, sizeof text, "AC3Db\nOBJECT poly\n%skids 0\n", verts);
    write_text(ac, text);
    refused_because(ctx, ac, HL_ERR_MESH, "no mesh is placed in the scene");
    const char *ac_world = tmp_path("mesh_no_surfaces_world.ac");
    snprintf(text, sizeof text, "AC3Db\nOBJECT world\nkids 1\nOBJECT poly\n%skids 0\n", verts);
    write_text(ac_world, text);
    refused_because(ctx, ac_world, HL_ERR_MESH, "no mesh is placed in the scene");
    const char *ac_ok = tmp_path("mesh_one_surface.ac");
    snprintf(text, sizeof text, "AC3Db\nOBJECT world\nkids 1\nOBJECT poly\n%s%skids 0\n", verts, surf);
    write_text(ac_ok, text);
    one_triangle(ctx, ac_ok);

    static const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    unsigned char bin[36];
    for (int i = 0; i < 9; i++) {
        uint32_t bits;
        memcpy(&bits, &xyz[i], 4);
        put_u32(bin + 4 * i, bits, 0);
    }
    static const char gltf[] =
        "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[%s]}],"
        "\"nodes\":[{\"name\":\"empty\"},{\"name\":\"holder\",\"mesh\":0}],\"skins\":[{\"joints\":[1]}],"
        "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],\"buffers\":[{\"byteLength\":36}],"
        "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],\"accessors\":[{\"bufferView\":0,\"componentType\":5126,"
        "\"count\":3,\"type\":\"VEC3\",\"min\":[0,0,0],\"max\":[1,1,0]}]}";
    const char *glb = tmp_path("mesh_unplaced.glb");
    snprintf(text, sizeof text, gltf, "0");
    write_glb(glb, text, bin, sizeof bin);
    refused_because(ctx, glb, HL_ERR_MESH, "no mesh is placed in the scene");
    const char *glb_ok = tmp_path("mesh_placed.glb");
    snprintf(text, sizeof text, gltf, "0,1");
    write_glb(glb_ok, text, bin, sizeof bin);
    one_triangle(ctx, glb_ok);
    hl_context_destroy(ctx);
}

/* One mesh of 65535 vertices placed by 65538 nodes: more than 2^32
 * vertices once placed. assimp's PretransformVertices adds them up in 32
 * bits, allocates the wrapped (small) count and copies past it (heap
 * corruption from a 2 MB file). Refused before it runs, quickly; the same
 * mesh placed twice loads. */
static void test_bad_placed_overflow(void)
{
    hl_context *ctx = make_ctx();
    const char *path = tmp_path("mesh_placed_2e32.glb");
    write_instanced_glb(path, 65535, 65538);
    double t0 = hl_now();
    refused_because(ctx, path, HL_ERR_MESH, "more than 2^32 vertices");
    printf("refused in %.3f s\n", hl_now() - t0);
    const char *ok = tmp_path("mesh_placed_twice.glb");
    write_instanced_glb(ok, 65535, 2);
    hl_mesh *m = NULL;
    hl_mesh_stats st;
    HL_CHECK(load(ctx, ok, NULL, &m, &st) == HL_OK && m, "%s: a mesh placed twice must load", ok);
    if (m) {
        print_stats("placed twice", m, &st);
        /* two copies of 65535 vertices, all but the triangle's unused; the
           copies coincide, so their vertices weld and both triangles stay */
        HL_CHECK(st.file_vertices == 2 * 65535u && st.file_triangles == 2, "placed twice: file counts");
        HL_CHECK(m->vertex_count == 3 && m->triangle_count == 2, "placed twice: %u vertices, %u triangles",
                 m->vertex_count, m->triangle_count);
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

#if defined(__SANITIZE_ADDRESS__)
#define MESH_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MESH_TEST_ASAN 1
#endif
#endif

/* A mesh placed by 12000 nodes: 786 million vertices, under 2^32, so it
 * gets to assimp's steps, which need about 10 GB for it. With the address
 * space limited to 1 GiB more than the process has, the allocation fails
 * inside PretransformVertices; the load must come back refused as out of
 * memory (aiApplyPostProcessing's failure path crashed on it). Run in a
 * child process, which takes the limit. Not under AddressSanitizer, whose
 * shadow memory needs more address space than any such limit. */
static void test_bad_import_memory(void)
{
#ifdef MESH_TEST_ASAN
    printf("SKIP: an AddressSanitizer build cannot run under an address-space limit\n");
#else
    const char *path = tmp_path("mesh_placed_10gb.glb");
    write_instanced_glb(path, 65535, 12000);
    fflush(stdout);
    pid_t pid = fork();
    HL_CHECK(pid >= 0, "fork failed");
    if (pid == 0) {
        long pages = 0, page = sysconf(_SC_PAGESIZE);
        FILE *f = fopen("/proc/self/statm", "r");
        if (!f || fscanf(f, "%ld", &pages) != 1 || page <= 0) _exit(3);
        fclose(f);
        rlim_t lim = (rlim_t)pages * (rlim_t)page + ((rlim_t)1 << 30);
        struct rlimit rl;
        if (getrlimit(RLIMIT_AS, &rl) != 0) _exit(3);
        if (rl.rlim_cur == RLIM_INFINITY || rl.rlim_cur > lim) rl.rlim_cur = lim;
        if (setrlimit(RLIMIT_AS, &rl) != 0) _exit(3);
        hl_context *ctx = make_ctx();
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        const char *msg = hl_context_last_error(ctx);
        printf("  %s -> %s: %s\n", path, hl_result_string(r), msg);
        fflush(stdout);
        int ok = r == HL_ERR_OUT_OF_MEMORY && strstr(msg, path) && strstr(msg, "out of memory");
        hl_mesh_destroy(m);
        hl_context_destroy(ctx);
        _exit(ok ? 0 : 1);
    }
    int status = 0;
    HL_CHECK(waitpid(pid, &status, 0) == pid, "waitpid failed");
    if (WIFSIGNALED(status))
        HL_CHECK(0, "the load under a memory limit was killed by signal %d", WTERMSIG(status));
    else
        HL_CHECK(WEXITSTATUS(status) == 0, "the load under a memory limit: child exit %d (1: not refused as out of "
                 "memory, 3: could not set the limit)", WEXITSTATUS(status));
#endif
}

static void test_bad_missing(void)
{
    hl_context *ctx = make_ctx();
    const char *names[] = {"mesh_does_not_exist.obj", "mesh_does_not_exist.ply"};
    for (size_t i = 0; i < 2; i++) {
        const char *path = tmp_path(names[i]);
        remove(path);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_ERR_IO);
    }
    const char *dir = hl_test_env("HL_TMP", "/tmp");
    hl_mesh *m = NULL;
    expect_failure(ctx, dir, hl_mesh_load(ctx, dir, NULL, &m, NULL), HL_ERR_IO);
    hl_context_destroy(ctx);
}

static void test_bad_empty(void)
{
    hl_context *ctx = make_ctx();
    const char *names[] = {"mesh_empty.obj", "mesh_empty.ply"};
    for (size_t i = 0; i < 2; i++) {
        const char *path = tmp_path(names[i]);
        write_file(path, "", 0);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_ERR_FORMAT);
    }
    const char *path = tmp_path("mesh_blank.obj");
    write_text(path, "\n\n   \n# nothing\n");
    hl_mesh *m = NULL;
    expect_failure(ctx, path, hl_mesh_load(ctx, path, NULL, &m, NULL), HL_ERR_FORMAT);
    hl_context_destroy(ctx);
}

static void test_bad_args(void)
{
    hl_context *ctx = make_ctx();
    hl_mesh *m = NULL;
    HL_CHECK(hl_mesh_load(ctx, NULL, NULL, &m, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL path");
    const char *path = tmp_path("mesh_args.obj");
    write_text(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    HL_CHECK(hl_mesh_load(ctx, path, NULL, NULL, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL out");
    hl_mesh_load_desc d = {0};
    d.up_axis = 'x';
    hl_result r = hl_mesh_load(ctx, path, &d, &m, NULL);
    printf("  up 'x' -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && m == NULL, "up axis x");
    d.up_axis = 0;
    d.albedo[0] = 1.5f;
    r = hl_mesh_load(ctx, path, &d, &m, NULL);
    printf("  albedo 1.5 -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, "albedo out of range");
    d.albedo[0] = 0.25f;
    d.albedo[1] = 0.5f;
    d.albedo[2] = 0.75f;
    hl_mesh_stats s;
    HL_CHECK(hl_mesh_load(NULL, path, &d, &m, &s) == HL_OK, "a NULL context is allowed");
    if (m) HL_CHECK(m->albedo[0] == 0.25f && m->albedo[1] == 0.5f && m->albedo[2] == 0.75f, "constant albedo");
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"bunny", test_bunny},
        {"teapot", test_teapot},
        {"horse_up_z", test_horse_up_z},
        {"horse_keep_winding", test_horse_keep_winding},
        {"normals", test_normals},
        {"ground", test_ground},
        {"ply", test_ply},
        {"create", test_create},
        {"obj_features", test_obj_features},
        {"obj_vs_ply", test_obj_vs_ply},
        {"bad_nan", test_bad_nan},
        {"bad_index", test_bad_index},
        {"bad_no_faces", test_bad_no_faces},
        {"bad_not_mesh", test_bad_not_mesh},
        {"bad_counts", test_bad_counts},
        {"bad_missing", test_bad_missing},
        {"bad_empty", test_bad_empty},
        {"bad_no_placed_mesh", test_bad_no_placed_mesh},
        {"bad_placed_overflow", test_bad_placed_overflow},
        {"bad_import_memory", test_bad_import_memory},
        {"bad_args", test_bad_args},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
