/* test_mesh.c - the mesh module on small meshes written here (suite
 * "mesh"): ground plane, PLY, meshes from memory, OBJ features, OBJ and
 * PLY alike, and the coarse teapot committed in tests/data.
 * Contexts use the reference backend, so no OpenCL device is needed.
 * Depends on: haarlight_core, tests/common/mesh_util.h, HL_TMP,
 * HL_TEST_FIXTURES (tests/data).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_internal.h"
#include "hl_test.h"
#include "mesh_util.h"

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
    /* the default ground under a tall tetrahedron (8 x as high as wide)
       and under a flat one (its shadow nearer than 0.75 x its extent) */
    const float ys[2] = {8.0f, 0.05f};
    for (int k = 0; k < 2; k++) {
        float q[12];
        for (int i = 0; i < 12; i++) q[i] = i % 3 == 1 ? p[i] * ys[k] : p[i];
        HL_CHECK(hl_mesh_create(ctx, 4, q, NULL, NULL, 4, idx, &m) == HL_OK, "create: %s", hl_context_last_error(ctx));
        if (m) check_ground_default(k ? "flat tetrahedron" : "tall tetrahedron", m);
        hl_mesh_destroy(m);
        m = NULL;
    }
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

/* The coarse Utah teapot of tests/data (public domain, so committed; the
 * shared data README's counts: 792 vertices of which 263 repeat a
 * position, 992 faces), through the same checks as mesh_shared.teapot. */
static void test_teapot_lowres(void)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/teapot_lowres.obj", hl_test_env("HL_TEST_FIXTURES", "tests/data"));
    hl_context *ctx = make_ctx();
    check_teapot(ctx, "teapot_lowres", path, 992, 792 - 263);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"ground", test_ground},
        {"ply", test_ply},
        {"create", test_create},
        {"obj_features", test_obj_features},
        {"obj_vs_ply", test_obj_vs_ply},
        {"teapot_lowres", test_teapot_lowres},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
