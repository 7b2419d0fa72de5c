/* test_scene.c - dynamic scenes of rigid bodies (host/src/dynamic/scene.c
 * and scene_anim.c), suite "scene". The files are glTF 2.0 written by
 * scene_gen.h; expected transforms are computed here from the keys the
 * generator wrote, with a slerp of its own (q0 (q0^-1 q1)^f through the
 * axis and angle), not the library's formula.
 *
 * scene.load     bodies, names, vertex counts, baked static scale, the
 *                hierarchy, the rest pose, the animation by name, +Z up.
 * scene.anim     at key times, between keys, clamped before and after,
 *                the child following its parent (animated and moved by
 *                the program).
 * scene.rigid    R^T R = I and det R = 1 over the whole animation.
 * scene.builtin  the bunny and its ground as two bodies; moving the bunny
 *                changes only its transform.
 * scene.bad      skin, morph target, no mesh, NaN keys, changing scale,
 *                rotation under an uneven scale, bad times and transforms,
 *                hostile files: each refused with a message naming it.
 * scene.ground   an animated file with a ground (hl_dynamic_create_from_file,
 *                HL_DYNAMIC_GROUND) keeps its bodies and animation, the
 *                ground under the whole motion; a skinned one is refused
 *                naming --rest-pose and loads with HL_DYNAMIC_REST_POSE; a
 *                still one is one body "object" and "ground"; `precompute`
 *                says which pose it baked.
 *
 * Depends on: haarlight_core, scene.h, scene_gen.h, hl_test.h, HL_TMP,
 * HL_REPO_DATA.
 */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "haarlight_tools.h"
#include "hl_test.h"
#include "scene.h"
#include "scene_gen.h"

/* Transforms come out as float: entries up to ~5 in size carry about
 * 5 x 2^-24 = 3e-7 of rounding, and the keys' times pass through assimp's
 * float milliseconds; 1e-5 covers both with margin and still catches a
 * wrong key, segment or arc (those are off by 1e-2 or more here). */
#define XF_TOL 1e-5
/* R^T R - I and det - 1 of a float rotation: a few float roundings of
 * entries at most 1. */
#define RIGID_TOL 1e-6

/* ---------------------------------------------------------------- quaternions (x y z w, as glTF) */

static void q_mul(const double a[4], const double b[4], double o[4])
{
    double r[4] = {a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1],
                   a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0],
                   a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3],
                   a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]};
    memcpy(o, r, sizeof r);
}

/* q0 (q0^-1 q1)^f on the shorter arc. */
static void q_slerp_ref(const double q0[4], const double q1[4], double f, double o[4])
{
    double inv[4] = {-q0[0], -q0[1], -q0[2], q0[3]}, d[4];
    q_mul(inv, q1, d);
    if (d[3] < 0) for (int k = 0; k < 4; k++) d[k] = -d[k];
    double vn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    double ang = 2.0 * atan2(vn, d[3]);
    double p[4] = {0, 0, 0, 1};
    if (vn > 0) {
        double s = sin(0.5 * f * ang) / vn;
        p[0] = d[0] * s; p[1] = d[1] * s; p[2] = d[2] * s;
        p[3] = cos(0.5 * f * ang);
    }
    q_mul(q0, p, o);
}

static void q_axis(double x, double y, double z, double deg, float q[4])
{
    double n = sqrt(x * x + y * y + z * z), h = 0.5 * deg * HL_PI / 180.0;
    q[0] = (float)(x / n * sin(h)); q[1] = (float)(y / n * sin(h)); q[2] = (float)(z / n * sin(h));
    q[3] = (float)cos(h);
}

/* ---------------------------------------------------------------- the reference */

/* 3x4 affine, row-major, double. */
static void xf_mul(const double a[12], const double b[12], double o[12])
{
    double r[12];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 4; j++)
            r[4 * i + j] = a[4 * i] * b[j] + a[4 * i + 1] * b[4 + j] + a[4 * i + 2] * b[8 + j] + (j == 3 ? a[4 * i + 3] : 0);
    memcpy(o, r, sizeof r);
}

static void key_lerp(const sg_keys *k, int comps, double t, double *out)
{
    if (t <= k->t[0]) { for (int c = 0; c < comps; c++) out[c] = k->v[0][c]; return; }
    if (t >= k->t[k->n - 1]) { for (int c = 0; c < comps; c++) out[c] = k->v[k->n - 1][c]; return; }
    int i = 0;
    while (!(t >= k->t[i] && t < k->t[i + 1])) i++;
    double f = (t - k->t[i]) / ((double)k->t[i + 1] - k->t[i]);
    if (comps == 3) {
        for (int c = 0; c < 3; c++) out[c] = k->v[i][c] + f * ((double)k->v[i + 1][c] - k->v[i][c]);
        return;
    }
    double a[4], b[4];
    for (int c = 0; c < 4; c++) { a[c] = k->v[i][c]; b[c] = k->v[i + 1][c]; }
    q_slerp_ref(a, b, f, out);
}

/* Node n's local matrix at t: T R S from keys, else the static values. */
static void ref_local(const sg_node *n, double t, double o[12])
{
    double T[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, S[3] = {1, 1, 1};
    if (n->has_t) for (int c = 0; c < 3; c++) T[c] = n->t[c];
    if (n->has_r) for (int c = 0; c < 4; c++) q[c] = n->r[c];
    if (n->has_s) for (int c = 0; c < 3; c++) S[c] = n->s[c];
    if (n->kt.n) key_lerp(&n->kt, 3, t, T);
    if (n->kr.n) key_lerp(&n->kr, 4, t, q);
    double qn = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double x = q[0] / qn, y = q[1] / qn, z = q[2] / qn, w = q[3] / qn;
    double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                   2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                   2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)};
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) o[4 * i + j] = R[3 * i + j] * S[j];
        o[4 * i + 3] = T[i];
    }
}

/* The world matrix of node n, and the product of the scales on its path
 * (the stretch the library bakes: every scale here is diagonal and only
 * leaves scale unevenly). */
static void ref_world(const sg_scene *sc, int n, double t, double o[12], double K[3])
{
    double l[12];
    ref_local(&sc->node[n], t, l);
    double k[3] = {1, 1, 1};
    if (sc->node[n].has_s) for (int c = 0; c < 3; c++) k[c] = sc->node[n].s[c];
    if (sc->node[n].parent >= 0) {
        double p[12], kp[3];
        ref_world(sc, sc->node[n].parent, t, p, kp);
        xf_mul(p, l, o);
        for (int c = 0; c < 3; c++) K[c] = k[c] * kp[0]; /* parents' scales are uniform here */
    } else {
        memcpy(o, l, sizeof l);
        memcpy(K, k, sizeof k);
    }
}

/* The expected rigid xf of node n's body: world K^-1. */
static void ref_xf(const sg_scene *sc, int n, double t, double o[12])
{
    double K[3];
    ref_world(sc, n, t, o, K);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) o[4 * i + j] /= K[j];
}

/* ---------------------------------------------------------------- the test scene */

/* Ground: the quad scaled (4, 1, 4). Pivot: no mesh, moves. Cube: under
 * Pivot, moves and turns (its last key is written as -q, so the shorter
 * arc needs the sign flip). Lid: under Cube, scaled 0.5, tilts. */
static void main_scene(sg_scene *sc)
{
    memset(sc, 0, sizeof *sc);
    sc->nnodes = 4;
    sg_node *g = &sc->node[0], *p = &sc->node[1], *c = &sc->node[2], *l = &sc->node[3];
    *g = (sg_node){.name = "Ground", .parent = -1, .mesh = SG_GROUND, .has_s = 1, .s = {4, 1, 4}};
    *p = (sg_node){.name = "Pivot", .parent = -1};
    p->kt = (sg_keys){3, {0, 1, 2}, {{0, 0, 0}, {2, 0, 0}, {2, 0, 2}}};
    *c = (sg_node){.name = "Cube", .parent = 1, .mesh = SG_CUBE, .has_t = 1, .t = {0, 1, 0}};
    c->kt = (sg_keys){3, {0.5f, 1.5f, 2.5f}, {{0, 1, 0}, {0, 2, 0}, {1, 2, 0}}};
    c->kr.n = 3;
    c->kr.t[0] = 0.5f; c->kr.t[1] = 1.5f; c->kr.t[2] = 3.0f;
    q_axis(0, 1, 0, 0, c->kr.v[0]);
    q_axis(0, 1, 0, 90, c->kr.v[1]);
    q_axis(1, 1, 0, 200, c->kr.v[2]);
    for (int k = 0; k < 4; k++) c->kr.v[2][k] = -c->kr.v[2][k];
    *l = (sg_node){.name = "Lid", .parent = 2, .mesh = SG_CUBE, .has_t = 1, .t = {0, 1.5f, 0}, .has_s = 1,
                   .s = {0.5f, 0.5f, 0.5f}};
    l->kr.n = 2;
    l->kr.t[0] = 0; l->kr.t[1] = 2;
    q_axis(1, 0, 0, 0, l->kr.v[0]);
    q_axis(1, 0, 0, 60, l->kr.v[1]);
}

static hl_dyn_scene *load_gen(hl_context *ctx, const sg_scene *sc, const char *file)
{
    const char *path = hl_test_tmp_path(file);
    if (sg_write_gltf(path, sc)) { HL_CHECK(0, "cannot write %s", path); return NULL; }
    hl_dyn_scene *s = NULL;
    hl_result r = hl_dyn_scene_load(ctx, path, &s);
    HL_CHECK(r == HL_OK, "load %s: %s", path, hl_context_last_error(ctx));
    return s;
}

static double xf_diff(const float *a, const double *b)
{
    double w = 0;
    for (int k = 0; k < 12; k++) w = fmax(w, fabs((double)a[k] - b[k]));
    return isnan(w) ? INFINITY : w;
}

/* ---------------------------------------------------------------- cases */

static void case_load(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sg_scene sc;
    main_scene(&sc);
    hl_dyn_scene *s = load_gen(ctx, &sc, "scene_main.gltf");
    if (!s) { hl_context_destroy(ctx); return; }
    uint32_t nb = hl_dyn_scene_body_count(s);
    HL_CHECK(nb == 3, "%u bodies, expected 3 (Ground, Cube, Lid; Pivot holds no mesh)", nb);
    static const char *names[3] = {"Ground", "Cube", "Lid"};
    static const uint32_t nv[3] = {4, 8, 8}, nt[3] = {2, 12, 12};
    static const int parent[3] = {-1, -1, 1};
    static const double half[3][3] = {{4, 0, 4}, {1, 1, 1}, {0.5, 0.5, 0.5}}; /* baked half-extents */
    hl_dyn_object o[3];
    HL_CHECK(hl_dyn_scene_at(s, 0.0, o) == HL_OK, "%s", hl_context_last_error(ctx));
    double worst = 0;
    for (uint32_t b = 0; b < nb && b < 3; b++) {
        const char *nm = hl_dyn_scene_body_name(s, b);
        printf("body %u: \"%s\", %u vertices, %u triangles, parent body %d\n", b, nm ? nm : "(null)", o[b].nverts,
               o[b].ntris, hl_dyn_scene_body_parent(s, b));
        HL_CHECK(nm && strcmp(nm, names[b]) == 0, "body %u is \"%s\", expected \"%s\"", b, nm, names[b]);
        HL_CHECK(hl_dyn_scene_find(s, names[b]) == (int32_t)b, "find(%s) = %d", names[b], hl_dyn_scene_find(s, names[b]));
        HL_CHECK(o[b].nverts == nv[b] && o[b].ntris == nt[b], "body %s: %u v %u t", names[b], o[b].nverts, o[b].ntris);
        HL_CHECK(hl_dyn_scene_body_parent(s, b) == parent[b], "body %s: parent %d", names[b], hl_dyn_scene_body_parent(s, b));
        HL_CHECK(o[b].normal != NULL && hl_dyn_scene_body_albedo(s, b) != NULL, "body %s lacks normals or albedo", names[b]);
        for (uint32_t v = 0; v < o[b].nverts; v++)
            for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(fabs((double)o[b].pos[3 * v + k]) - half[b][k]));
    }
    hl_check_error("baked static scale: |vertex| - half extent", worst, 0.0);
    HL_CHECK(hl_dyn_scene_find(s, "Pivot") == -1 && hl_dyn_scene_find(s, "nope") == -1, "find of a node without body");
    double t0, t1;
    const char *an = hl_dyn_scene_animation(s, &t0, &t1);
    printf("animation \"%s\", keys from %g s to %g s\n", an ? an : "(none)", t0, t1);
    HL_CHECK(an && strcmp(an, "move") == 0, "animation name %s", an ? an : "(none)");
    hl_check_error("animation key range (0 s to 3 s)", fmax(fabs(t0), fabs(t1 - 3.0)), 1e-9);
    hl_dyn_scene_destroy(s);
    /* the rest pose on request */
    hl_dyn_scene_desc d = {.animation = HL_DYN_NO_ANIMATION};
    HL_CHECK(hl_dyn_scene_load_desc(ctx, hl_test_tmp_path("scene_main.gltf"), &d, &s) == HL_OK, "%s",
             hl_context_last_error(ctx));
    if (s) {
        HL_CHECK(hl_dyn_scene_animation(s, NULL, NULL) == NULL, "rest pose has an animation");
        HL_CHECK(hl_dyn_scene_at(s, 5.0, o) == HL_OK, "%s", hl_context_last_error(ctx));
        double e[12];
        sg_scene rest = sc;
        for (int n = 0; n < rest.nnodes; n++) rest.node[n].kt.n = rest.node[n].kr.n = 0;
        ref_xf(&rest, 2, 0, e);
        hl_check_error("rest pose: Cube at the node's static transform", xf_diff(o[1].xf, e), XF_TOL);
        hl_dyn_scene_destroy(s);
    }
    /* a mirroring scale: the body stays rigid, its world vertices are the
       mirrored quad and its (open) winding still faces +Y */
    sg_scene mir;
    memset(&mir, 0, sizeof mir);
    mir.nnodes = 1;
    mir.node[0] = (sg_node){.name = "Mirror", .parent = -1, .mesh = SG_GROUND, .has_s = 1, .s = {2, 1, -3}};
    s = load_gen(ctx, &mir, "scene_mirror.gltf");
    if (s) {
        HL_CHECK(hl_dyn_scene_at(s, 0.0, o) == HL_OK, "%s", hl_context_last_error(ctx));
        const float *x = o[0].xf;
        double wm = 0, det = (double)x[0] * ((double)x[5] * x[10] - (double)x[6] * x[9]) -
                             (double)x[1] * ((double)x[4] * x[10] - (double)x[6] * x[8]) +
                             (double)x[2] * ((double)x[4] * x[9] - (double)x[5] * x[8]);
        wm = fabs(det - 1.0);
        for (uint32_t v = 0; v < o[0].nverts; v++) {
            const float *p = o[0].pos + 3 * v, *n = o[0].normal + 3 * v;
            double w[3], wn[3];
            for (int i = 0; i < 3; i++) {
                w[i] = x[4 * i] * p[0] + x[4 * i + 1] * p[1] + x[4 * i + 2] * p[2] + x[4 * i + 3];
                wn[i] = x[4 * i] * n[0] + x[4 * i + 1] * n[1] + x[4 * i + 2] * n[2];
            }
            wm = fmax(wm, fmax(fabs(fabs(w[0]) - 2), fmax(fabs(w[1]), fabs(fabs(w[2]) - 3))));
            wm = fmax(wm, fmax(fabs(wn[0]), fmax(fabs(wn[1] - 1), fabs(wn[2]))));
        }
        hl_check_error("mirror scale (2, 1, -3): det, world corners, world normal +Y", wm, XF_TOL);
        hl_dyn_scene_destroy(s);
    }
    /* the animation chosen by name */
    d = (hl_dyn_scene_desc){.animation_name = "move"};
    HL_CHECK(hl_dyn_scene_load_desc(ctx, hl_test_tmp_path("scene_main.gltf"), &d, &s) == HL_OK, "%s",
             hl_context_last_error(ctx));
    HL_CHECK(s && hl_dyn_scene_animation(s, NULL, NULL) && strcmp(hl_dyn_scene_animation(s, NULL, NULL), "move") == 0,
             "animation by name");
    hl_dyn_scene_destroy(s);
    s = NULL;
    /* +Z up: the whole scene turns by (x, y, z) -> (x, z, -y) */
    d = (hl_dyn_scene_desc){.mesh = {.up_axis = 'z'}};
    HL_CHECK(hl_dyn_scene_load_desc(ctx, hl_test_tmp_path("scene_main.gltf"), &d, &s) == HL_OK, "%s",
             hl_context_last_error(ctx));
    if (s) {
        const double turn[12] = {1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0};
        double worst_z = 0, e[12], te[12];
        for (double t = 0; t <= 3.5; t += 0.25) {
            HL_CHECK(hl_dyn_scene_at(s, t, o) == HL_OK, "%s", hl_context_last_error(ctx));
            ref_xf(&sc, 3, t, e);
            xf_mul(turn, e, te);
            worst_z = fmax(worst_z, xf_diff(o[2].xf, te));
        }
        hl_check_error("up axis z: Lid = turn x its +Y-up transform", worst_z, XF_TOL);
        hl_dyn_scene_destroy(s);
    }
    hl_context_destroy(ctx);
}

static void case_anim(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sg_scene sc;
    main_scene(&sc);
    hl_dyn_scene *s = load_gen(ctx, &sc, "scene_anim.gltf");
    if (!s) { hl_context_destroy(ctx); return; }
    static const int node_of[3] = {0, 2, 3};
    hl_dyn_object o[3];
    struct { const char *what; double t[6]; int n; } groups[] = {
        {"at key times", {0.5, 1.0, 1.5, 2.0, 2.5, 3.0}, 6},
        {"between keys", {0.25, 0.8, 1.2, 1.77, 2.3, 2.9}, 6},
        {"clamped before the first key and after the last", {0.0, 0.1, 3.5, 10.0, 1e6}, 5},
    };
    for (size_t g = 0; g < sizeof groups / sizeof groups[0]; g++) {
        double worst = 0;
        for (int i = 0; i < groups[g].n; i++) {
            double t = groups[g].t[i];
            HL_CHECK(hl_dyn_scene_at(s, t, o) == HL_OK, "%s", hl_context_last_error(ctx));
            for (int b = 0; b < 3; b++) {
                double e[12];
                ref_xf(&sc, node_of[b], t, e);
                worst = fmax(worst, xf_diff(o[b].xf, e));
            }
        }
        hl_check_error(groups[g].what, worst, XF_TOL);
    }
    /* the keys themselves: at t = 1.5 the Pivot is halfway (2, 0, 1) and
       the Cube at its key 1: translation (0, 2, 0), 90 degrees about Y */
    HL_CHECK(hl_dyn_scene_at(s, 1.5, o) == HL_OK, "%s", hl_context_last_error(ctx));
    const double key1[12] = {0, 0, 1, 2, 0, 1, 0, 2, -1, 0, 0, 1};
    hl_check_error("Cube at t = 1.5 s equals its key 1 after the Pivot", xf_diff(o[1].xf, key1), XF_TOL);
    /* after the last key: the last key, -q read as q */
    HL_CHECK(hl_dyn_scene_at(s, 7.0, o) == HL_OK, "%s", hl_context_last_error(ctx));
    double e[12];
    sg_scene last = sc;
    last.node[2].kr.n = last.node[2].kt.n = 0;
    last.node[2].has_r = 1;
    memcpy(last.node[2].r, sc.node[2].kr.v[2], sizeof last.node[2].r);
    last.node[2].t[0] = 1; last.node[2].t[1] = 2; last.node[2].t[2] = 0;
    ref_xf(&last, 2, 7.0, e);
    hl_check_error("Cube after the last key holds it", xf_diff(o[1].xf, e), XF_TOL);
    /* the child follows: the Lid is the Cube's xf times its local */
    double worst = 0;
    for (double t = 0; t <= 3.5; t += 0.125) {
        HL_CHECK(hl_dyn_scene_at(s, t, o) == HL_OK, "%s", hl_context_last_error(ctx));
        double cube[12], lid_local[12], lid[12];
        for (int k = 0; k < 12; k++) cube[k] = o[1].xf[k];
        ref_local(&sc.node[3], t, lid_local);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) lid_local[4 * i + j] /= 0.5; /* the Lid's baked scale */
        xf_mul(cube, lid_local, lid);
        worst = fmax(worst, xf_diff(o[2].xf, lid));
    }
    hl_check_error("Lid = Cube x Lid's local over the animation", worst, XF_TOL);
    /* the program moves the Cube: the Lid follows, the Ground does not */
    hl_dyn_object before[3];
    HL_CHECK(hl_dyn_scene_at(s, 1.2, before) == HL_OK, "%s", hl_context_last_error(ctx));
    const double tr[3] = {0.5, 3, -1}, ax[3] = {0, 0, 1};
    HL_CHECK(hl_dyn_scene_set_pose(s, 1, tr, ax, 0.3) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dyn_scene_at(s, 1.2, o) == HL_OK, "%s", hl_context_last_error(ctx));
    float P[12];
    hl_dyn_scene_get_transform(s, 1, P);
    double Pd[12], bc[12], bl[12], ec[12], el[12];
    for (int k = 0; k < 12; k++) { Pd[k] = P[k]; bc[k] = before[1].xf[k]; bl[k] = before[2].xf[k]; }
    xf_mul(Pd, bc, ec);
    xf_mul(Pd, bl, el);
    double eg[12];
    for (int k = 0; k < 12; k++) eg[k] = before[0].xf[k];
    double wmove = fmax(xf_diff(o[1].xf, ec), xf_diff(o[2].xf, el));
    hl_check_error("program's pose: Cube and Lid move by P", wmove, XF_TOL);
    hl_check_error("program's pose: Ground unchanged", xf_diff(o[0].xf, eg), 0.0);
    hl_dyn_scene_destroy(s);
    /* a uniform scale on the Pivot scales its children's offsets and is
       baked into their vertices (Cube 2, Lid 2 x 0.5) */
    sg_scene big = sc;
    big.node[1].has_s = 1;
    big.node[1].s[0] = big.node[1].s[1] = big.node[1].s[2] = 2;
    s = load_gen(ctx, &big, "scene_anim_scaled.gltf");
    if (s) {
        double wb = 0;
        for (double t = 0; t <= 3.5; t += 0.125) {
            HL_CHECK(hl_dyn_scene_at(s, t, o) == HL_OK, "%s", hl_context_last_error(ctx));
            for (int b = 0; b < 3; b++) {
                double e[12];
                ref_xf(&big, node_of[b], t, e);
                wb = fmax(wb, xf_diff(o[b].xf, e));
            }
        }
        hl_check_error("Pivot scaled 2: every body over the animation", wb, XF_TOL);
        double half = 0;
        for (uint32_t v = 0; v < o[1].nverts; v++) half = fmax(half, fabs((double)o[1].pos[3 * v]));
        hl_check_error("Pivot scaled 2: the Cube's baked half extent is 2", fabs(half - 2.0), 0.0);
        hl_dyn_scene_destroy(s);
    }
    hl_context_destroy(ctx);
}

static void case_rigid(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sg_scene sc;
    main_scene(&sc);
    hl_dyn_scene *s = load_gen(ctx, &sc, "scene_rigid.gltf");
    if (!s) { hl_context_destroy(ctx); return; }
    const double ax[3] = {1, 2, 3}, tr[3] = {1, 1, 1};
    HL_CHECK(hl_dyn_scene_set_pose(s, 0, tr, ax, 2.0) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_dyn_object o[3];
    double worst = 0, wdet = 0;
    for (int i = 0; i <= 400; i++) {
        HL_CHECK(hl_dyn_scene_at(s, i * 0.01, o) == HL_OK, "%s", hl_context_last_error(ctx));
        for (int b = 0; b < 3; b++) {
            const float *x = o[b].xf;
            for (int p = 0; p < 3; p++)
                for (int q = 0; q < 3; q++) {
                    double d = (double)x[p] * x[q] + (double)x[4 + p] * x[4 + q] + (double)x[8 + p] * x[8 + q];
                    worst = fmax(worst, fabs(d - (p == q)));
                }
            double det = (double)x[0] * ((double)x[5] * x[10] - (double)x[6] * x[9]) -
                         (double)x[1] * ((double)x[4] * x[10] - (double)x[6] * x[8]) +
                         (double)x[2] * ((double)x[4] * x[9] - (double)x[5] * x[8]);
            wdet = fmax(wdet, fabs(det - 1.0));
        }
    }
    hl_check_error("|R^T R - I| over 0..4 s, every body", worst, RIGID_TOL);
    hl_check_error("|det R - 1| over 0..4 s, every body", wdet, RIGID_TOL);
    /* world bounds at a time: the Ground's baked 8 x 8 quad, moved */
    float lo[3], hi[3];
    HL_CHECK(hl_dyn_scene_set_pose(s, 0, NULL, NULL, 0.0) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dyn_scene_bounds(s, 0.0, lo, hi) == HL_OK, "%s", hl_context_last_error(ctx));
    printf("bounds at 0 s: (%g %g %g) - (%g %g %g)\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
    /* at 0 s the Cube (corners +-1 about (0, 1, 0)) and the Lid lie inside the ground's x/z and the Lid reaches y = 3 */
    double wb = fmax(fmax(fabs(lo[0] + 4), fabs(hi[0] - 4)), fmax(fabs(lo[2] + 4), fabs(hi[2] - 4)));
    wb = fmax(wb, fmax(fabs(lo[1]), fabs(hi[1] - 3.0)));
    hl_check_error("world bounds at 0 s", wb, XF_TOL);
    hl_dyn_scene_destroy(s);
    hl_context_destroy(ctx);
}

static void case_builtin(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    char path[1024];
    snprintf(path, sizeof path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    hl_mesh *m = NULL, *mg = NULL;
    HL_CHECK(hl_mesh_load(ctx, path, NULL, &m, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_mesh_load(ctx, path, NULL, &mg, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!m || !mg) { hl_mesh_destroy(m); hl_mesh_destroy(mg); hl_context_destroy(ctx); return; }
    hl_ground_desc gd = {0};
    HL_CHECK(hl_mesh_add_ground(ctx, mg, &gd) == HL_OK, "%s", hl_context_last_error(ctx));
    hl_dyn_scene *s = NULL;
    HL_CHECK(hl_dyn_scene_from_mesh(ctx, m, &gd, &s) == HL_OK, "%s", hl_context_last_error(ctx));
    if (!s) { hl_mesh_destroy(m); hl_mesh_destroy(mg); hl_context_destroy(ctx); return; }
    HL_CHECK(hl_dyn_scene_body_count(s) == 2, "%u bodies", hl_dyn_scene_body_count(s));
    hl_dyn_object o[2], o2[2];
    HL_CHECK(hl_dyn_scene_at(s, 0.0, o) == HL_OK, "%s", hl_context_last_error(ctx));
    printf("bunny: %u vertices %u triangles; ground: %u vertices %u triangles\n", o[0].nverts, o[0].ntris,
           o[1].nverts, o[1].ntris);
    uint32_t gv = mg->vertex_count - mg->object_vertex_count, gt = mg->triangle_count - m->triangle_count;
    HL_CHECK(o[0].nverts == m->vertex_count && o[0].ntris == m->triangle_count, "object counts");
    HL_CHECK(o[1].nverts == gv && o[1].ntris == gt, "ground counts %u %u, hl_mesh_add_ground %u %u", o[1].nverts,
             o[1].ntris, gv, gt);
    HL_CHECK(hl_dyn_scene_find(s, "object") == 0 && hl_dyn_scene_find(s, "ground") == 1, "names");
    /* the ground body is what hl_mesh_add_ground appends, bit for bit */
    double worst = 0;
    for (uint32_t v = 0; v < gv && o[1].nverts == gv; v++)
        for (int k = 0; k < 3; k++) {
            worst = fmax(worst, fabs((double)o[1].pos[3 * v + k] - mg->positions[3 * (mg->object_vertex_count + v) + k]));
            worst = fmax(worst, fabs((double)hl_dyn_scene_body_albedo(s, 1)[3 * v + k] -
                                     mg->albedo[3 * (mg->object_vertex_count + v) + k]));
        }
    for (uint32_t t = 0; t < 3 * gt && o[1].ntris == gt; t++)
        worst = fmax(worst, fabs((double)o[1].tri[t] - ((double)mg->indices[3 * (size_t)m->triangle_count + t] -
                                                        mg->object_vertex_count)));
    for (uint32_t v = 0; v < 3 * m->vertex_count; v++) worst = fmax(worst, fabs((double)o[0].pos[v] - m->positions[v]));
    hl_check_error("bodies vs the mesh and hl_mesh_add_ground (positions, albedo, indices)", worst, 0.0);
    /* lift the bunny and carry it across: only its transform changes */
    float lift[12] = {0, 0, 1, 0.3f, 0, 1, 0, 0.2f, -1, 0, 0, -0.1f};
    HL_CHECK(hl_dyn_scene_set_transform(s, 0, lift) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_dyn_scene_at(s, 2.5, o2) == HL_OK, "%s", hl_context_last_error(ctx));
    static const float id[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    double wid = 0, wl = 0;
    for (int k = 0; k < 12; k++) {
        wid = fmax(wid, fabs((double)o2[1].xf[k] - id[k]) + fabs((double)o[0].xf[k] - id[k]));
        wl = fmax(wl, fabs((double)o2[0].xf[k] - lift[k]));
    }
    hl_check_error("ground (and the bunny before) at the identity", wid, 0.0);
    hl_check_error("the bunny's xf is the one set", wl, 0.0);
    HL_CHECK(o2[0].pos == o[0].pos && o2[1].pos == o[1].pos && o2[0].tri == o[0].tri, "arrays moved");
    hl_dyn_scene_destroy(s);
    /* a mesh that already carries its ground gives the same two bodies */
    HL_CHECK(hl_dyn_scene_from_mesh(ctx, mg, &gd, &s) != HL_OK, "a second ground was accepted");
    HL_CHECK(hl_dyn_scene_from_mesh(ctx, mg, NULL, &s) == HL_OK, "%s", hl_context_last_error(ctx));
    if (s) {
        HL_CHECK(hl_dyn_scene_at(s, 0.0, o2) == HL_OK, "%s", hl_context_last_error(ctx));
        HL_CHECK(o2[1].nverts == gv && o2[0].nverts == m->vertex_count, "split of a grounded mesh");
        hl_dyn_scene_destroy(s);
    }
    HL_CHECK(hl_dyn_scene_from_mesh(ctx, m, NULL, &s) == HL_OK && hl_dyn_scene_body_count(s) == 1, "no ground");
    hl_dyn_scene_destroy(s);
    hl_mesh_destroy(m);
    hl_mesh_destroy(mg);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- bad input */

static int bad_seen = 0, bad_wrong = 0;

/* r must be code with a message holding want (and the file's name). */
static void expect(hl_context *ctx, hl_result r, hl_result code, const char *want, const char *file)
{
    const char *msg = hl_context_last_error(ctx);
    bad_seen++;
    printf("  %s -> %d: %s\n", file ? file : "-", (int)r, msg);
    int ok = r == code && strstr(msg, want) && (!file || strstr(msg, file));
    if (!ok) {
        bad_wrong++;
        HL_CHECK(0, "expected code %d and \"%s\" naming %s, got %d: %s", (int)code, want, file ? file : "-", (int)r, msg);
    }
}

static void expect_load(hl_context *ctx, const sg_scene *sc, const char *name, hl_result code, const char *want)
{
    const char *path = hl_test_tmp_path(name);
    if (sg_write_gltf(path, sc)) { HL_CHECK(0, "cannot write %s", path); return; }
    hl_dyn_scene *s = NULL;
    expect(ctx, hl_dyn_scene_load(ctx, path, &s), code, want, name);
    HL_CHECK(s == NULL, "a scene came back from a failed load");
    hl_dyn_scene_destroy(s);
}

/* The lowest y and the x, z extent of the bodies but the last at time t
 * (world positions from each body's xf). */
static void moving_bounds(hl_dyn_scene *s, double t, double lo[3], double hi[3])
{
    const uint32_t nb = hl_dyn_scene_body_count(s);
    hl_dyn_object *o = calloc(nb, sizeof *o);
    if (!o || hl_dyn_scene_at(s, t, o) != HL_OK) { HL_CHECK(0, "scene at %g", t); free(o); return; }
    for (uint32_t b = 0; b + 1 < nb; b++)
        for (uint32_t v = 0; v < o[b].nverts; v++)
            for (int i = 0; i < 3; i++) {
                const float *x = o[b].xf + 4 * i, *p = o[b].pos + 3 * (size_t)v;
                double w = (double)x[0] * p[0] + (double)x[1] * p[1] + (double)x[2] * p[2] + x[3];
                lo[i] = fmin(lo[i], w), hi[i] = fmax(hi[i], w);
            }
    free(o);
}

/* precompute --time T: hl_tools_mesh_load_at poses the file at T, its
 * bodies merged: the mesh's bounds are the scene's bounds at T, at two
 * times that differ; a still file is refused. */
static void case_posed(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sg_scene sc;
    main_scene(&sc);
    const char *path = hl_test_tmp_path("scene_posed.gltf");
    HL_CHECK(sg_write_gltf(path, &sc) == 0, "cannot write %s", path);
    hl_dyn_scene *s = NULL;
    HL_CHECK(hl_dyn_scene_load(ctx, path, &s) == HL_OK, "%s", hl_context_last_error(ctx));
    const double times[2] = {0.75, 2.25};
    double worst = 0.0;
    float moved = 0.0f, prev_hi[3] = {0, 0, 0};
    for (int k = 0; s && k < 2; k++) {
        hl_mesh *m = NULL;
        char anim[64];
        hl_result r = hl_tools_mesh_load_at(ctx, path, NULL, times[k], &m, anim, sizeof anim);
        HL_CHECK(r == HL_OK, "posed at %g: %s", times[k], hl_context_last_error(ctx));
        if (!m) continue;
        float lo[3], hi[3], mlo[3] = {INFINITY, INFINITY, INFINITY}, mhi[3] = {-INFINITY, -INFINITY, -INFINITY};
        hl_dyn_scene_bounds(s, times[k], lo, hi);
        for (uint32_t v = 0; v < m->vertex_count; v++)
            for (int i = 0; i < 3; i++)
                mlo[i] = fminf(mlo[i], m->positions[3 * v + i]), mhi[i] = fmaxf(mhi[i], m->positions[3 * v + i]);
        for (int i = 0; i < 3; i++) worst = fmax(worst, fmax(fabs(mlo[i] - lo[i]), fabs(mhi[i] - hi[i])));
        if (k) for (int i = 0; i < 3; i++) moved = fmaxf(moved, fabsf(mhi[i] - prev_hi[i])); /* the floor stays */
        memcpy(prev_hi, mhi, sizeof mhi);
        hl_mesh_destroy(m);
    }
    hl_check_error("posed mesh's bounds against the scene's at the same time", worst, 1e-5);
    HL_CHECK(moved > 0.5f, "the two poses differ by %g only", (double)moved);
    hl_dyn_scene_destroy(s);
    /* a still file has nothing to pose */
    sc.node[1].kt.n = sc.node[2].kt.n = sc.node[2].kr.n = sc.node[3].kr.n = 0;
    const char *still = hl_test_tmp_path("scene_still.gltf");
    HL_CHECK(sg_write_gltf(still, &sc) == 0, "cannot write %s", still);
    hl_mesh *m = NULL;
    char anim[64];
    hl_result r = hl_tools_mesh_load_at(ctx, still, NULL, 1.0, &m, anim, sizeof anim);
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && !m && strstr(hl_context_last_error(ctx), still), "still file: %d %s",
             (int)r, hl_context_last_error(ctx));
    printf("refused as expected: %s\n", hl_context_last_error(ctx));
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void case_ground(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sg_scene sc;
    main_scene(&sc);
    sc.node[0].mesh = SG_NONE; /* no floor of the file's own: the moving Cube and Lid */
    const char *path = hl_test_tmp_path("scene_ground.gltf");
    HL_CHECK(sg_write_gltf(path, &sc) == 0, "cannot write %s", path);
    /* the scene with its ground, as hl_dynamic_create_from_file makes it */
    hl_dyn_scene *s = NULL;
    HL_CHECK(hl_dyn_scene_load(ctx, path, &s) == HL_OK && hl_dyn_scene_add_ground(s, NULL) == HL_OK, "%s",
             hl_context_last_error(ctx));
    if (s) {
        const uint32_t nb = hl_dyn_scene_body_count(s);
        HL_CHECK(nb == 3 && !strcmp(hl_dyn_scene_body_name(s, nb - 1), "ground"), "%u bodies, the last \"%s\"", nb,
                 hl_dyn_scene_body_name(s, nb - 1));
        double t0 = 0, t1 = 0;
        hl_dyn_scene_animation(s, &t0, &t1);
        /* the ground at the motion's lowest point and around its whole
           footprint, at the 64 times it was sized at and between them */
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int k = 0; k < 127; k++) moving_bounds(s, t0 + (t1 - t0) * k / 126.0, lo, hi);
        hl_dyn_object *o = calloc(nb, sizeof *o);
        hl_dyn_scene_at(s, t0, o);
        const hl_dyn_object *g = &o[nb - 1];
        double glo[3] = {INFINITY, INFINITY, INFINITY}, ghi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t v = 0; v < g->nverts; v++)
            for (int i = 0; i < 3; i++) glo[i] = fmin(glo[i], g->pos[3 * v + i]), ghi[i] = fmax(ghi[i], g->pos[3 * v + i]);
        printf("motion over %g..%g s: x %.3f..%.3f, y from %.3f, z %.3f..%.3f; ground x %.3f..%.3f, y %.3f, z %.3f..%.3f\n",
               t0, t1, lo[0], hi[0], lo[1], lo[2], hi[2], glo[0], ghi[0], glo[1], glo[2], ghi[2]);
        HL_CHECK(t1 > t0, "the animation was kept");
        hl_check_error("ground height against the motion's lowest point", fabs(glo[1] - lo[1]), 1e-5);
        HL_CHECK(glo[0] < lo[0] && ghi[0] > hi[0] && glo[2] < lo[2] && ghi[2] > hi[2],
                 "the ground covers the footprint of the whole motion");
        HL_CHECK(g->xf[0] == 1.0f && g->xf[5] == 1.0f && g->xf[10] == 1.0f && g->xf[3] == 0.0f && g->xf[7] == 0.0f,
                 "the ground stays where it was made");
        free(o);
        hl_dyn_scene_destroy(s);
    }
    /* the public API: the animated file keeps its bodies, a still one is
       one mesh "object" with its ground */
    hl_dynamic *d = NULL;
    HL_CHECK(hl_dynamic_create_from_file(ctx, path, HL_DYNAMIC_GROUND, NULL, &d) == HL_OK, "%s", hl_context_last_error(ctx));
    double a = 0, b = 0;
    hl_dynamic_time_range(d, &a, &b);
    HL_CHECK(d && hl_dynamic_body_count(d) == 3 && b > a, "animated with ground: %u bodies, time %g..%g",
             hl_dynamic_body_count(d), a, b);
    hl_dynamic_destroy(d);
    d = NULL;
    HL_CHECK(hl_dynamic_create_from_file(ctx, path, HL_DYNAMIC_GROUND | HL_DYNAMIC_REST_POSE, NULL, &d) == HL_OK, "%s",
             hl_context_last_error(ctx));
    HL_CHECK(d && hl_dynamic_body_count(d) == 2 && !strcmp(hl_dynamic_body_name(d, 0), "object"),
             "rest pose with ground: one mesh and its ground");
    hl_dynamic_destroy(d);
    d = NULL;
    /* skinned: refused naming the option, loaded with it */
    main_scene(&sc);
    sc.skin = 2;
    const char *skin = hl_test_tmp_path("scene_ground_skin.gltf");
    HL_CHECK(sg_write_gltf(skin, &sc) == 0, "cannot write %s", skin);
    hl_result r = hl_dynamic_create_from_file(ctx, skin, HL_DYNAMIC_GROUND, NULL, &d);
    printf("skinned, with ground: %s\n", hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_MESH && strstr(hl_context_last_error(ctx), "--rest-pose"), "the refusal names --rest-pose");
    hl_dynamic_destroy(d);
    d = NULL;
    HL_CHECK(hl_dynamic_create_from_file(ctx, skin, HL_DYNAMIC_REST_POSE, NULL, &d) == HL_OK, "%s",
             hl_context_last_error(ctx));
    hl_dynamic_destroy(d);
    /* precompute says which pose it baked */
    char cmd[4096], out[1024] = "";
    const char *err = hl_test_tmp_path("scene_ground_precompute.txt");
    snprintf(cmd, sizeof cmd, "'%s' precompute '%s' -C 8 -N 8 -q -o '%s.hlt' 2>'%s'", hl_test_env("HL_BIN", "haarlight"),
             path, path, err);
    HL_CHECK(system(cmd) == 0, "failed: %s", cmd);
    FILE *f = fopen(err, "r");
    if (f) {
        size_t n = fread(out, 1, sizeof out - 1, f);
        out[n] = 0;
        fclose(f);
    }
    printf("precompute said: %s", out);
    HL_CHECK(strstr(out, "1 animation") && strstr(out, "rest pose"), "precompute names the pose it baked");
    hl_context_destroy(ctx);
}

static void write_raw(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(p, 1, n, f) != n) { HL_CHECK(0, "cannot write %s", path); }
    if (f) fclose(f);
}

static void case_bad(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    sg_scene sc;
    /* skinned: the Cube gets a skin jointed to the Pivot */
    main_scene(&sc);
    sc.skin = 2;
    expect_load(ctx, &sc, "scene_skin.gltf", HL_ERR_MESH, "skinned");
    {
        hl_dyn_scene_desc d = {.animation = HL_DYN_NO_ANIMATION};
        hl_dyn_scene *bind = NULL;
        HL_CHECK(hl_dyn_scene_load_desc(ctx, hl_test_tmp_path("scene_skin.gltf"), &d, &bind) == HL_OK,
                 "skinned file without its animation: %s", hl_context_last_error(ctx));
        hl_dyn_scene_destroy(bind);
    }
    /* a morph target with its weights channel */
    main_scene(&sc);
    sc.node[0].mesh = SG_CUBE;
    sc.morph = 1;
    expect_load(ctx, &sc, "scene_morph.gltf", HL_ERR_MESH, "morph");
    /* no mesh at all */
    main_scene(&sc);
    for (int n = 0; n < sc.nnodes; n++) sc.node[n].mesh = SG_NONE;
    expect_load(ctx, &sc, "scene_empty.gltf", HL_ERR_FORMAT, "no mesh");
    /* NaN in a position key, a rotation key, a key time */
    main_scene(&sc);
    sc.node[2].kt.v[1][0] = NAN;
    expect_load(ctx, &sc, "scene_nan_pos.gltf", HL_ERR_FORMAT, "not finite");
    main_scene(&sc);
    sc.node[2].kr.v[1][3] = NAN;
    expect_load(ctx, &sc, "scene_nan_rot.gltf", HL_ERR_FORMAT, "not a rotation");
    main_scene(&sc);
    sc.node[1].kt.t[1] = NAN;
    expect_load(ctx, &sc, "scene_nan_time.gltf", HL_ERR_FORMAT, "time");
    /* a static transform that is not finite */
    main_scene(&sc);
    sc.node[3].t[1] = INFINITY;
    expect_load(ctx, &sc, "scene_inf_node.gltf", HL_ERR_FORMAT, "non-finite");
    /* scaling keys that change */
    main_scene(&sc);
    sc.node[2].ks = (sg_keys){2, {0, 1}, {{1, 1, 1}, {2, 2, 2}}};
    expect_load(ctx, &sc, "scene_scale.gltf", HL_ERR_MESH, "scaling keys change");
    /* constant scaling keys are fine */
    main_scene(&sc);
    sc.node[2].ks = (sg_keys){2, {0, 1}, {{1, 1, 1}, {1, 1, 1}}};
    {
        hl_dyn_scene *s = load_gen(ctx, &sc, "scene_scale_const.gltf");
        HL_CHECK(s != NULL, "constant scaling keys refused");
        hl_dyn_scene_destroy(s);
    }
    /* the Cube turns under a Pivot scaled (1, 3, 1): it would shear */
    main_scene(&sc);
    sc.node[1].has_s = 1;
    sc.node[1].s[0] = 1; sc.node[1].s[1] = 3; sc.node[1].s[2] = 1;
    expect_load(ctx, &sc, "scene_shear.gltf", HL_ERR_MESH, "shears");
    /* hostile files meet the existing guards */
    const char *txt = hl_test_tmp_path("scene_notjson.gltf");
    write_raw(txt, "solid x\nendsolid x\n", 19);
    hl_dyn_scene *s = NULL;
    expect(ctx, hl_dyn_scene_load(ctx, txt, &s), HL_ERR_FORMAT, "not a glTF file", "scene_notjson.gltf");
    const unsigned char glb[20] = {'g', 'l', 'T', 'F', 2, 0, 0, 0, 0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0, 0, 'J', 'S', 'O', 'N'};
    const char *gp = hl_test_tmp_path("scene_hostile.glb");
    write_raw(gp, glb, sizeof glb);
    expect(ctx, hl_dyn_scene_load(ctx, gp, &s), HL_ERR_FORMAT, "binary glTF header", "scene_hostile.glb");
    expect(ctx, hl_dyn_scene_load(ctx, hl_test_tmp_path("scene_missing.gltf"), &s), HL_ERR_IO, "cannot open",
           "scene_missing.gltf");
    /* bad times and transforms on a good scene */
    main_scene(&sc);
    s = load_gen(ctx, &sc, "scene_bad_args.gltf");
    if (s) {
        hl_dyn_object o[3];
        expect(ctx, hl_dyn_scene_at(s, NAN, o), HL_ERR_INVALID_ARGUMENT, "time", "scene_bad_args.gltf");
        expect(ctx, hl_dyn_scene_at(s, -0.5, o), HL_ERR_INVALID_ARGUMENT, "time", "scene_bad_args.gltf");
        expect(ctx, hl_dyn_scene_at(s, INFINITY, o), HL_ERR_INVALID_ARGUMENT, "time", "scene_bad_args.gltf");
        float L[12];
        expect(ctx, hl_dyn_scene_bounds(s, NAN, L, L + 3), HL_ERR_INVALID_ARGUMENT, "time", "scene_bad_args.gltf");
        float scaled[12] = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0}, mirror[12] = {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        float nan_xf[12] = {1, 0, 0, NAN, 0, 1, 0, 0, 0, 0, 1, 0};
        expect(ctx, hl_dyn_scene_set_transform(s, 1, scaled), HL_ERR_INVALID_ARGUMENT, "not rigid", "Cube");
        expect(ctx, hl_dyn_scene_set_transform(s, 1, mirror), HL_ERR_INVALID_ARGUMENT, "not rigid", "Cube");
        expect(ctx, hl_dyn_scene_set_transform(s, 1, nan_xf), HL_ERR_INVALID_ARGUMENT, "not finite", "Cube");
        expect(ctx, hl_dyn_scene_set_transform(s, 7, scaled), HL_ERR_INVALID_ARGUMENT, "out of range", NULL);
        const double zero[3] = {0, 0, 0};
        expect(ctx, hl_dyn_scene_set_pose(s, 1, NULL, zero, 1.0), HL_ERR_INVALID_ARGUMENT, "axis", "Cube");
        hl_dyn_scene_destroy(s);
    }
    hl_dyn_scene_desc d = {.animation = 3};
    expect(ctx, hl_dyn_scene_load_desc(ctx, hl_test_tmp_path("scene_bad_args.gltf"), &d, &s), HL_ERR_INVALID_ARGUMENT,
           "animation 3 out of range", "scene_bad_args.gltf");
    d = (hl_dyn_scene_desc){.animation_name = "jump"};
    expect(ctx, hl_dyn_scene_load_desc(ctx, hl_test_tmp_path("scene_bad_args.gltf"), &d, &s), HL_ERR_INVALID_ARGUMENT,
           "no animation is named \"jump\"", "scene_bad_args.gltf");
    hl_check_error("bad inputs not refused as expected (count)", bad_wrong, 0.0);
    printf("%d bad inputs tried\n", bad_seen);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"load", case_load}, {"anim", case_anim}, {"rigid", case_rigid},
        {"builtin", case_builtin}, {"bad", case_bad}, {"ground", case_ground}, {"posed", case_posed}, {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
