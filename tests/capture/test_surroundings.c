/* test_surroundings.c - the surroundings the capture renders
 * (host/src/capture/surroundings.c, surroundings_gltf.c, on the dynamic
 * scene's loader with keep_triangles), suite "surroundings". Each case
 * writes its own .gltf (surr_gltf.h) under HL_TMP, named by the process.
 *
 * surroundings.emissive   a quad whose material has an emissive factor
 *                         and KHR_materials_emissive_strength, plus a
 *                         degenerate sliver on it: every triangle kept,
 *                         in file order, each with factor x strength, at
 *                         its node's translation; a second material
 *                         without strength gives its factor; asking for
 *                         the triangles twice gives the same bytes; the
 *                         same file as .glb gives the same radiance.
 * surroundings.dark       a box with no material and one with a zero
 *                         emissive factor: radiance 0, bodies not emitting.
 * surroundings.animation  translation keys (0, 1, 3 s) sampled at 0, 0.5,
 *                         1, 2, 3 and 5 s (clamped) against the linear
 *                         interpolation; a child of a node turned by
 *                         rotation keys about +Y against its circle; the
 *                         time range; bad times refused.
 * surroundings.transform  a program transform (a quarter turn and a
 *                         shift) applied after the animation, on a file
 *                         and on arrays; a scaling one and a body out of
 *                         range refused; the file's placement (shift,
 *                         scale, turn about +Y) between the animation and
 *                         P, and bad placements refused naming the value.
 * surroundings.bad        missing and truncated files, negative emission
 *                         (arrays and glTF strength), a NaN corner (file
 *                         and arrays): each refused with the file or arrays
 *                         named; 20,000 triangles (file and arrays), past
 *                         the 4096 the capture once took, are taken.
 * surroundings.example    data/surroundings/lamp_orbit.gltf: 44 triangles,
 *                         3 bodies, the lamp alone emitting 120 x its warm
 *                         factor, its centre on its circle (radius 8,
 *                         height 9) at +X at 0 s, -X at 2 s, +X at 4 s.
 *                         (hl.surroundings.example_file checks the file is
 *                         what tests/tools/make_surroundings writes.)
 *
 * Depends on: haarlight_core (public surroundings API), hl_test.h,
 * surr_gltf.h, HL_TMP, HL_REPO_DATA.
 */
#include <math.h>
#include <stdint.h>
#include <unistd.h>

#include "hl_test.h"
#include "surr_gltf.h"

/* Float positions and radiances that go in exactly (surr_gltf.h writes
 * %.9g) and are moved only by exact or double-rounded arithmetic: a
 * translation is exact, so 1e-6 is float rounding of the transform. */
#define POS_TOL 1e-6
/* A slerped rotation goes through sines and cosines in double then float:
 * about 1e-7 relative on coordinates of size 2. */
#define ROT_TOL 2e-6
/* Radiance factor x strength is one float product (exact for these). */
#define EMIT_TOL 1e-6
#define SURR_PI 3.14159265358979323846

static char *tmp_name(const char *base)
{
    static char buf[4][1024];
    static int next = 0;
    char *b = buf[next++ & 3];
    char name[256];
    snprintf(name, sizeof name, "surr_%ld_%s", (long)getpid(), base);
    snprintf(b, 1024, "%s", hl_test_tmp_path(name));
    return b;
}

/* The unit quad in the XY plane, [0,1]^2 at z = 0, as two triangles, and
 * a sliver with two equal corners (degenerate: the mesh builder would
 * drop it). */
static const float QUAD[27] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 1, 1, 0};

static double max_err(const float *a, const float *b, size_t n)
{
    double w = 0.0;
    for (size_t i = 0; i < n; i++) w = fmax(w, isnan(a[i]) || isnan(b[i]) ? INFINITY : fabs((double)a[i] - b[i]));
    return w;
}

/* The .gltf at src (surr_gltf.h's: one buffer, a base64 data URI at its
 * end) as a .glb at dst: the JSON without the URI, padded with spaces,
 * and the buffer decoded into the BIN chunk. Returns 0 on success. */
static int to_glb(const char *src, const char *dst)
{
    static char text[1 << 20];
    static unsigned char bin[1 << 20];
    static const char key[] = ",\"uri\":\"data:application/octet-stream;base64,";
    FILE *f = fopen(src, "rb");
    if (!f) return -1;
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    char *u = strstr(text, key), *q = u ? strchr(u + sizeof key - 1, '"') : NULL;
    if (!q) return -1;
    size_t nb = 0;
    uint32_t acc = 0;
    int bits = 0;
    for (const char *c = u + sizeof key - 1; c < q && *c != '='; c++) {
        const char *a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        acc = acc << 6 | (uint32_t)(strchr(a, *c) - a);
        if ((bits += 6) >= 8) bin[nb++] = (unsigned char)(acc >> (bits -= 8));
    }
    memmove(u, q + 1, strlen(q + 1) + 1); /* the JSON without the URI */
    n = strlen(text);
    while (n > 0 && (text[n - 1] == '\n')) n--;
    while (n % 4) text[n++] = ' ';
    while (nb % 4) bin[nb++] = 0;
    const uint32_t head[5] = {0x46546C67u, 2u, (uint32_t)(12 + 8 + n + 8 + nb), (uint32_t)n, 0x4E4F534Au};
    const uint32_t bhead[2] = {(uint32_t)nb, 0x004E4942u}; /* "glTF", "JSON", "BIN\0" */
    f = fopen(dst, "wb");
    if (!f) return -1;
    int ok = fwrite(head, 4, 5, f) == 5 && fwrite(text, 1, n, f) == n && fwrite(bhead, 4, 2, f) == 2 &&
             fwrite(bin, 1, nb, f) == nb;
    return fclose(f) == 0 && ok ? 0 : -1;
}

static hl_surroundings *load_ok(hl_context *ctx, const char *path)
{
    hl_surroundings *s = NULL;
    hl_result r = hl_surroundings_load(ctx, path, &s);
    HL_CHECK(r == HL_OK, "load %s: %s", path, hl_context_last_error(ctx));
    return s;
}

static void test_emissive(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sgf_scene sc = {0};
    sc.nmaterials = 2;
    sc.material[0] = (sgf_material){"lamp", {1.0f, 0.5f, 0.25f}, 40.0f};
    sc.material[1] = (sgf_material){"dim", {0.75f, 0.5f, 0.125f}, NAN};
    sc.nnodes = 2;
    sc.node[0] = (sgf_node){.name = "lamp", .parent = -1, .tris = QUAD, .ntris = 3, .material = 0, .t = {0, 2, -3}};
    sc.node[1] = (sgf_node){.name = "dim", .parent = -1, .tris = QUAD, .ntris = 2, .material = 1, .t = {5, 0, 0}};
    const char *path = tmp_name("emissive.gltf");
    HL_CHECK(sgf_write(&sc, path) == 0, "cannot write %s", path);
    float want_p[45], want_e[15];
    for (int t = 0; t < 5; t++)
        for (int k = 0; k < 9; k++) want_p[9 * t + k] = QUAD[9 * (t % 3) + k] + sc.node[t < 3 ? 0 : 1].t[k % 3];
    for (int t = 0; t < 5; t++)
        for (int c = 0; c < 3; c++)
            want_e[3 * t + c] = t < 3 ? sc.material[0].emissive[c] * 40.0f : sc.material[1].emissive[c];
    hl_surroundings *s = load_ok(ctx, path);
    if (s) {
        HL_CHECK(hl_surroundings_triangle_count(s) == 5, "%u triangles, expected 5 (the sliver kept)",
                 hl_surroundings_triangle_count(s));
        HL_CHECK(hl_surroundings_body_count(s) == 2, "%u bodies", hl_surroundings_body_count(s));
        HL_CHECK(hl_surroundings_body_name(s, 0) && !strcmp(hl_surroundings_body_name(s, 0), "lamp"), "body 0 name");
        HL_CHECK(hl_surroundings_body_emits(s, 0) && hl_surroundings_body_emits(s, 1), "both bodies emit");
        const float *p = NULL, *e = NULL, *p2 = NULL, *e2 = NULL;
        HL_CHECK(hl_surroundings_triangles(s, &p, &e) == HL_OK, "%s", hl_context_last_error(ctx));
        if (p && e) {
            hl_check_error("emissive: world corners against the node translation", max_err(p, want_p, 45), POS_TOL);
            hl_check_error("emissive: radiance = factor x strength per triangle", max_err(e, want_e, 15), EMIT_TOL);
        }
        HL_CHECK(hl_surroundings_triangles(s, &p2, &e2) == HL_OK && p2 == p && e2 == e,
                 "asking twice gives the same arrays");
        hl_surroundings_destroy(s);
    }
    const char *glb = tmp_name("emissive.glb");
    HL_CHECK(to_glb(path, glb) == 0, "cannot write %s", glb);
    s = load_ok(ctx, glb);
    if (s) {
        const float *p = NULL, *e = NULL;
        HL_CHECK(hl_surroundings_triangles(s, &p, &e) == HL_OK && hl_surroundings_triangle_count(s) == 5, "glb");
        if (e) hl_check_error("emissive: the same scene as .glb, radiance", max_err(e, want_e, 15), EMIT_TOL);
        hl_surroundings_destroy(s);
    }
    remove(glb);
    remove(path);
    hl_context_destroy(ctx);
}

static void test_dark(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    float box[12 * 9];
    uint32_t n = 0;
    sgf_box(box, &n, (const float[3]){0, 0, 0}, (const float[3]){1, 2, 3});
    sgf_scene sc = {0};
    sc.nmaterials = 1;
    sc.material[0] = (sgf_material){"black", {0, 0, 0}, 5.0f};
    sc.nnodes = 2;
    sc.node[0] = (sgf_node){.name = "bare", .parent = -1, .tris = box, .ntris = n, .material = -1};
    sc.node[1] = (sgf_node){.name = "black", .parent = -1, .tris = box, .ntris = n, .material = 0, .t = {0, 0, 9}};
    const char *path = tmp_name("dark.gltf");
    HL_CHECK(sgf_write(&sc, path) == 0, "cannot write %s", path);
    hl_surroundings *s = load_ok(ctx, path);
    if (s) {
        const float *p = NULL, *e = NULL;
        HL_CHECK(hl_surroundings_triangle_count(s) == 24, "%u triangles", hl_surroundings_triangle_count(s));
        HL_CHECK(!hl_surroundings_body_emits(s, 0) && !hl_surroundings_body_emits(s, 1), "no body emits");
        HL_CHECK(hl_surroundings_triangles(s, &p, &e) == HL_OK, "%s", hl_context_last_error(ctx));
        float zero[72] = {0};
        if (e) hl_check_error("dark: radiance of occluders", max_err(e, zero, 72), 0.0);
        hl_surroundings_destroy(s);
    }
    remove(path);
    hl_context_destroy(ctx);
}

/* The first corner of triangle t at time time. */
static void corner_at(hl_surroundings *s, double time, uint32_t t, float out[3])
{
    const float *p = NULL, *e = NULL;
    out[0] = out[1] = out[2] = NAN;
    if (hl_surroundings_set_time(s, time) != HL_OK || hl_surroundings_triangles(s, &p, &e) != HL_OK) return;
    memcpy(out, p + 9 * (size_t)t, 3 * sizeof(float));
}

static void test_animation(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sgf_scene sc = {0};
    sc.nmaterials = 1;
    sc.material[0] = (sgf_material){"lamp", {1, 1, 1}, 100.0f};
    sc.nnodes = 3;
    sgf_node *a = &sc.node[0], *orbit = &sc.node[1], *moon = &sc.node[2];
    *a = (sgf_node){.name = "slider", .parent = -1, .tris = QUAD, .ntris = 2, .material = 0};
    a->kt = (sgf_keys){3, {0, 1, 3}, {{0, 0, 0}, {2, 0, 0}, {2, 4, 0}}};
    *orbit = (sgf_node){.name = "orbit", .parent = -1};
    const float h = (float)sin(SURR_PI / 4), c = (float)cos(SURR_PI / 4); /* a quarter turn: half-angle 45 degrees */
    orbit->kr = (sgf_keys){2, {0, 1}, {{0, 0, 0, 1}, {0, h, 0, c}}};
    *moon = (sgf_node){.name = "moon", .parent = 1, .tris = QUAD, .ntris = 2, .material = 0, .t = {2, 0, 0}};
    const char *path = tmp_name("anim.gltf");
    HL_CHECK(sgf_write(&sc, path) == 0, "cannot write %s", path);
    hl_surroundings *s = load_ok(ctx, path);
    if (!s) { hl_context_destroy(ctx); return; }
    double t0 = -1, t1 = -1;
    hl_surroundings_time_range(s, &t0, &t1);
    HL_CHECK(t0 == 0.0 && t1 == 3.0, "time range %g to %g, expected 0 to 3", t0, t1);
    static const double times[6] = {0, 0.5, 1, 2, 3, 5};
    static const float want[6][3] = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 2, 0}, {2, 4, 0}, {2, 4, 0}};
    double worst = 0.0, worst_rot = 0.0;
    for (int i = 0; i < 6; i++) {
        float got[3];
        corner_at(s, times[i], 0, got);
        worst = fmax(worst, max_err(got, want[i], 3));
        /* the moon (triangles 2, 3) turned about +Y by 90 deg x min(t, 1):
           (x, 0, 0) -> (x cos a, 0, -x sin a) */
        double ang = SURR_PI / 2 * fmin(times[i], 1.0);
        const float wm[3] = {(float)(2 * cos(ang)), 0.0f, (float)(-2 * sin(ang))};
        corner_at(s, times[i], 2, got);
        worst_rot = fmax(worst_rot, max_err(got, wm, 3));
    }
    hl_check_error("animation: translation keys at 0, 0.5, 1, 2, 3 and 5 s (clamped)", worst, POS_TOL);
    hl_check_error("animation: a child of rotation keys on its circle", worst_rot, ROT_TOL);
    HL_CHECK(hl_surroundings_set_time(s, -1.0) == HL_ERR_INVALID_ARGUMENT, "a negative time is refused");
    HL_CHECK(hl_surroundings_set_time(s, NAN) == HL_ERR_INVALID_ARGUMENT, "a NaN time is refused");
    HL_CHECK(hl_surroundings_set_time(s, INFINITY) == HL_ERR_INVALID_ARGUMENT, "an infinite time is refused");
    hl_surroundings_destroy(s);
    remove(path);
    hl_context_destroy(ctx);
}

/* A quarter turn about +Y, (x, y, z) -> (z, y, -x), then (0, 1, 0). */
static const float QUARTER[12] = {0, 0, 1, 0, 0, 1, 0, 1, -1, 0, 0, 0};

static double transformed_err(hl_surroundings *s, const float *local, uint32_t ntris, const float shift[3])
{
    const float *p = NULL, *e = NULL;
    if (hl_surroundings_set_transform(s, 0, QUARTER) != HL_OK || hl_surroundings_triangles(s, &p, &e) != HL_OK)
        return INFINITY;
    double w = 0.0;
    for (uint32_t v = 0; v < 3 * ntris; v++) {
        const float *q = local + 3 * (size_t)v;
        const float x = q[0] + shift[0], y = q[1] + shift[1], z = q[2] + shift[2];
        const float want[3] = {z, y + 1.0f, -x};
        w = fmax(w, max_err(p + 3 * (size_t)v, want, 3));
    }
    return w;
}

static void test_transform(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sgf_scene sc = {0};
    sc.nmaterials = 1;
    sc.material[0] = (sgf_material){"lamp", {1, 1, 1}, 10.0f};
    sc.nnodes = 1;
    sc.node[0] = (sgf_node){.name = "lamp", .parent = -1, .tris = QUAD, .ntris = 2, .material = 0};
    sc.node[0].kt = (sgf_keys){2, {0, 2}, {{0, 0, 0}, {4, 0, 0}}};
    const char *path = tmp_name("xf.gltf");
    HL_CHECK(sgf_write(&sc, path) == 0, "cannot write %s", path);
    hl_surroundings *s = load_ok(ctx, path);
    if (s) {
        HL_CHECK(hl_surroundings_set_time(s, 1.0) == HL_OK, "set_time");
        hl_check_error("transform: P after the animation (file, t = 1 s)",
                       transformed_err(s, QUAD, 2, (const float[3]){2, 0, 0}), POS_TOL);
        const float scale[12] = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0};
        HL_CHECK(hl_surroundings_set_transform(s, 0, scale) == HL_ERR_INVALID_ARGUMENT, "a scaling transform is refused");
        HL_CHECK(hl_surroundings_set_transform(s, 1, QUARTER) == HL_ERR_INVALID_ARGUMENT, "body 1 of 1 is refused");
        /* the placement (--surroundings-transform): shift + 2.5 Ry(90) x
           over the animated file, before P, as a root node would be */
        const float shift[3] = {1, -2, 3};
        HL_CHECK(hl_surroundings_set_placement(s, shift, 2.5f, 90.0f) == HL_OK, "placement: %s", hl_context_last_error(ctx));
        const float *p = NULL, *e = NULL;
        double w = INFINITY;
        if (hl_surroundings_set_transform(s, 0, QUARTER) == HL_OK && hl_surroundings_triangles(s, &p, &e) == HL_OK) {
            w = 0.0;
            for (uint32_t v = 0; v < 6; v++) {
                const float ax = QUAD[3 * v] + 2.0f, ay = QUAD[3 * v + 1], az = QUAD[3 * v + 2];
                const float want[3] = {3.0f - 2.5f * ax, -1.0f + 2.5f * ay, -(1.0f + 2.5f * az)};
                w = fmax(w, max_err(p + 3 * (size_t)v, want, 3));
            }
        }
        hl_check_error("transform: placement after the animation, before P (file, t = 1 s)", w, 10 * POS_TOL);
        static const struct { float sh, scale, yaw; const char *word; } bad[] = {
            {0, 0.0f, 0, "scale"}, {0, -1.0f, 0, "scale"}, {0, NAN, 0, "scale"}, {0, INFINITY, 0, "scale"},
            {NAN, 1.0f, 0, "shift"}, {INFINITY, 1.0f, 0, "shift"}, {0, 1.0f, NAN, "turn"}};
        for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
            const float sh[3] = {0, bad[k].sh, 0};
            hl_result r = hl_surroundings_set_placement(s, sh, bad[k].scale, bad[k].yaw);
            const char *msg = hl_context_last_error(ctx);
            HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && msg && strstr(msg, bad[k].word),
                     "placement %g %g %g: not refused for its %s (%s)", (double)bad[k].sh, (double)bad[k].scale,
                     (double)bad[k].yaw, bad[k].word, msg ? msg : "");
            printf("transform: placement refused: %s\n", msg ? msg : "");
        }
        hl_surroundings_destroy(s);
    }
    remove(path);
    const float em[6] = {1, 2, 3, 4, 5, 6};
    HL_CHECK(hl_surroundings_create(ctx, QUAD, em, 2, &s) == HL_OK, "create: %s", hl_context_last_error(ctx));
    if (s) {
        HL_CHECK(hl_surroundings_body_count(s) == 1 && !strcmp(hl_surroundings_body_name(s, 0), "surroundings"),
                 "one body \"surroundings\"");
        double t0 = -1, t1 = -1;
        hl_surroundings_time_range(s, &t0, &t1);
        HL_CHECK(t0 == 0.0 && t1 == 0.0, "no animation: range %g to %g", t0, t1);
        hl_check_error("transform: P on arrays", transformed_err(s, QUAD, 2, (const float[3]){0, 0, 0}), POS_TOL);
        const float *p = NULL, *e = NULL;
        HL_CHECK(hl_surroundings_triangles(s, &p, &e) == HL_OK, "triangles");
        if (e) hl_check_error("transform: arrays' emission copied", max_err(e, em, 6), 0.0);
        hl_surroundings_destroy(s);
    }
    hl_context_destroy(ctx);
}

/* r must be a failure whose message names what. */
static void expect_fail(hl_context *ctx, hl_result r, const char *what, const char *case_name)
{
    const char *msg = hl_context_last_error(ctx);
    HL_CHECK(r != HL_OK, "%s: accepted", case_name);
    HL_CHECK(r == HL_OK || (msg && strstr(msg, what)), "%s: the message \"%s\" does not name %s", case_name,
             msg ? msg : "", what);
    printf("%s: refused (%s): %s\n", case_name, hl_result_string(r), msg ? msg : "");
}

static void bad_files(hl_context *ctx)
{
    hl_surroundings *s = NULL;
    const char *missing = tmp_name("missing.gltf");
    expect_fail(ctx, hl_surroundings_load(ctx, missing, &s), missing, "missing file");
    sgf_scene sc = {0};
    sc.nmaterials = 1;
    sc.material[0] = (sgf_material){"lamp", {1, 1, 1}, 10.0f};
    sc.nnodes = 1;
    sc.node[0] = (sgf_node){.name = "lamp", .parent = -1, .tris = QUAD, .ntris = 2, .material = 0};
    const char *cut = tmp_name("cut.gltf");
    if (sgf_write(&sc, cut) == 0) {
        FILE *f = fopen(cut, "rb");
        char buf[4096];
        size_t n = f ? fread(buf, 1, sizeof buf, f) : 0;
        if (f) fclose(f);
        f = fopen(cut, "wb");
        if (f) { fwrite(buf, 1, n / 2, f); fclose(f); }
        expect_fail(ctx, hl_surroundings_load(ctx, cut, &s), cut, "truncated file");
        remove(cut);
    }
    sc.material[0].strength = -2.0f;
    const char *neg = tmp_name("neg.gltf");
    if (sgf_write(&sc, neg) == 0) expect_fail(ctx, hl_surroundings_load(ctx, neg, &s), neg, "negative glTF strength");
    remove(neg);
    sc.material[0].strength = 10.0f;
    float nanq[18];
    memcpy(nanq, QUAD, sizeof nanq);
    nanq[4] = NAN;
    sc.node[0].tris = nanq;
    const char *np = tmp_name("nan.gltf");
    if (sgf_write(&sc, np) == 0) expect_fail(ctx, hl_surroundings_load(ctx, np, &s), np, "NaN corner in a file");
    remove(np);
}

static void test_bad(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_surroundings *s = NULL;
    bad_files(ctx);
    const uint32_t many = 20000; /* no cap (once 4096) */
    float *soup = calloc((size_t)many * 9, sizeof(float)), *em = calloc((size_t)many * 3, sizeof(float));
    if (!soup || !em) { HL_CHECK(0, "out of memory"); return; }
    for (uint32_t t = 0; t < many; t++) memcpy(soup + 9 * (size_t)t, QUAD, 9 * sizeof(float));
    sgf_scene sc = {0};
    sc.nnodes = 1;
    sc.node[0] = (sgf_node){.name = "many", .parent = -1, .tris = soup, .ntris = many, .material = -1};
    const char *mp = tmp_name("many.gltf");
    if (sgf_write(&sc, mp) == 0) {
        s = load_ok(ctx, mp);
        HL_CHECK(hl_surroundings_triangle_count(s) == many, "a file of %u triangles gives %u", many,
                 hl_surroundings_triangle_count(s));
        hl_surroundings_destroy(s);
    }
    remove(mp);
    HL_CHECK(hl_surroundings_create(ctx, soup, em, many, &s) == HL_OK, "%u triangles from arrays are taken: %s", many,
             hl_context_last_error(ctx));
    hl_surroundings_destroy(s);
    s = NULL;
    s = NULL;
    em[4] = -1.0f;
    expect_fail(ctx, hl_surroundings_create(ctx, soup, em, 2, &s), "surroundings from arrays", "negative emission");
    em[4] = INFINITY;
    expect_fail(ctx, hl_surroundings_create(ctx, soup, em, 2, &s), "surroundings from arrays", "infinite emission");
    em[4] = 0.0f;
    soup[10] = NAN;
    expect_fail(ctx, hl_surroundings_create(ctx, soup, em, 2, &s), "surroundings from arrays", "NaN corner");
    expect_fail(ctx, hl_surroundings_create(ctx, soup, em, 0, &s), "no triangles", "no triangles");
    HL_CHECK(s == NULL, "nothing made on failure");
    free(soup);
    free(em);
    hl_context_destroy(ctx);
}

/* The mean of the lamp's corners (triangles 0..7, an octahedron about its
 * centre) at time t. */
static void lamp_centre(hl_surroundings *s, double t, float c[3])
{
    const float *p = NULL, *e = NULL;
    c[0] = c[1] = c[2] = NAN;
    if (hl_surroundings_set_time(s, t) != HL_OK || hl_surroundings_triangles(s, &p, &e) != HL_OK) return;
    double m[3] = {0, 0, 0};
    for (int v = 0; v < 24; v++)
        for (int k = 0; k < 3; k++) m[k] += p[3 * v + k] / 24.0;
    for (int k = 0; k < 3; k++) c[k] = (float)m[k];
}

static void test_example(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    char path[1024];
    snprintf(path, sizeof path, "%s/surroundings/lamp_orbit.gltf", hl_test_env("HL_REPO_DATA", "data"));
    hl_surroundings *s = load_ok(ctx, path);
    if (!s) { hl_context_destroy(ctx); return; }
    HL_CHECK(hl_surroundings_triangle_count(s) == 44 && hl_surroundings_body_count(s) == 3, "%u triangles, %u bodies",
             hl_surroundings_triangle_count(s), hl_surroundings_body_count(s));
    int emitting = 0;
    for (uint32_t b = 0; b < hl_surroundings_body_count(s); b++) emitting += hl_surroundings_body_emits(s, b);
    HL_CHECK(emitting == 1 && hl_surroundings_body_emits(s, 0) && !strcmp(hl_surroundings_body_name(s, 0), "lamp"),
             "the lamp alone emits");
    const float *p = NULL, *e = NULL;
    HL_CHECK(hl_surroundings_triangles(s, &p, &e) == HL_OK, "triangles");
    const float warm[3] = {120.0f, 120.0f * 0.85f, 120.0f * 0.6f};
    double we = 0.0;
    for (int t = 0; e && t < 8; t++) we = fmax(we, max_err(e + 3 * t, warm, 3) / 120.0);
    hl_check_error("example: the lamp's radiance, relative", we, EMIT_TOL);
    static const float want[3][3] = {{8, 9, 0}, {-8, 9, 0}, {8, 9, 0}};
    double wp = 0.0;
    for (int i = 0; i < 3; i++) {
        float c[3];
        lamp_centre(s, 2.0 * i, c);
        wp = fmax(wp, max_err(c, want[i], 3));
    }
    hl_check_error("example: the lamp's centre at 0, 2 and 4 s", wp, 10 * ROT_TOL);
    hl_surroundings_destroy(s);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"emissive", test_emissive}, {"dark", test_dark},
                                         {"animation", test_animation}, {"transform", test_transform},
                                         {"bad", test_bad}, {"example", test_example}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
