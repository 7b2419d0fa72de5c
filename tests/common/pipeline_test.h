/* pipeline_test.h - what the suites of the bases through the real
 * pipeline share (test_sh_pipeline.c, test_cube_pipeline.c): the sqrt8
 * step of the error bounds, the bunny's transport made in a basis, a
 * relight, and the refusal of bad precompute options by the command and
 * by the library.
 * Depends on: hl_test.h, the public API; data/bunny_lowres.obj, HL_BIN.
 */
#ifndef HL_PIPELINE_TEST_H
#define HL_PIPELINE_TEST_H

#include <sys/wait.h>
#include <unistd.h>

#include "hl_test.h"

/* The most a sqrt8 code's decoded magnitude may differ from the value it
 * codes, as a fraction of the row's largest magnitude b (hl_shared.h):
 * s is off by at most half a step, 1/254, and s runs up to 127.5/127 with
 * the dither, so |s'^2 - s^2| <= (2 s + 1/254) / 254. */
static inline double pt_sqrt8_step(void) { return (2.0 * 127.5 / 127.0 + 1.0 / 254.0) / 254.0; }

static inline double pt_norm2(const double *x, uint32_t n)
{
    double s = 0.0;
    for (uint32_t k = 0; k < n; k++) s += x[k] * x[k];
    return sqrt(s);
}

/* Checks that files a and b hold the same bytes, printing what held. */
static inline void pt_check_same_file(const char *a, const char *b, const char *what)
{
    size_t na = 0, nb = 0;
    uint8_t *x = hl_test_read_file(a, &na), *y = hl_test_read_file(b, &nb);
    HL_CHECK(x && y && na == nb && memcmp(x, y, na) == 0, "%s: the files differ (%zu, %zu bytes)", what, na, nb);
    printf("%s: the files are equal (%zu bytes)\n", what, na);
    free(x);
    free(y);
}

/* The bunny (albedo 0.8 0.6 0.4) and its transport at path, made on ctx
 * with d. */
static inline hl_mesh *pt_scene(hl_context *ctx, const char *path, const hl_precompute_desc *d)
{
    hl_mesh_load_desc ld = {{0.8f, 0.6f, 0.4f}, 'y', 0};
    hl_mesh *mesh = NULL;
    HL_CHECK(hl_mesh_load(ctx, hl_test_data_path("bunny_lowres.obj"), &ld, &mesh, NULL) == HL_OK, "mesh: %s",
             hl_context_last_error(ctx));
    HL_CHECK(hl_precompute(ctx, mesh, d, path, NULL) == HL_OK, "precompute: %s", hl_context_last_error(ctx));
    return mesh;
}

/* Colours (3 floats a vertex) of t under env turned by deg, with M terms
 * (0: all) and a selection scheme (0: the default). */
static inline void pt_relight(hl_context *ctx, const hl_transport *t, const hl_env *env, uint32_t M, uint32_t select,
                              float deg, float *rgb)
{
    hl_relighter *r = NULL;
    HL_CHECK(hl_relighter_create(ctx, t, &r) == HL_OK, "relighter: %s", hl_context_last_error(ctx));
    HL_CHECK(hl_relighter_set_env(r, env) == HL_OK, "set env: %s", hl_context_last_error(ctx));
    hl_relight_desc rd = {.terms = M ? M : 2 * t->info.N * t->info.N, .select = select, .rotate_deg = deg};
    HL_CHECK(hl_relighter_run(r, &rd, rgb, NULL) == HL_OK, "run: %s", hl_context_last_error(ctx));
    hl_relighter_destroy(r);
}

/* Relights t under env with all its terms on ctx and checks the n
 * vertices idx against want (3 colours a vertex, bench-basis's; clamped
 * at zero here, as every output is) within each vertex's bound: every
 * stored coefficient off by at most a sqrt8 step of its row's b, the
 * dropped ones holding at most eps of |t|^2, and 1e-5 for the float sums;
 * tn[i] bounds vertex idx[i]'s row norm, l1 and l2 are each channel's
 * lighting norms. Prints the worst error over the bound (tolerance 1)
 * under `what`, and the relative L2. */
static inline void pt_check_against(hl_context *ctx, const hl_transport *t, const hl_mesh *mesh, const hl_env *env,
                                    const uint32_t *idx, uint32_t n, const double *want3, const double *tn,
                                    const double l1[3], const double l2[3], const char *what)
{
    float *rgb = malloc((size_t)t->info.vertex_count * 12);
    pt_relight(ctx, t, env, 0, 0, 0.0f, rgb);
    const double q = pt_sqrt8_step(), eps = t->info.eps;
    double worst = 0.0, e2 = 0.0, ref2 = 0.0;
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t v = idx[i];
        for (int ch = 0; ch < 3; ch++) {
            const double a = mesh->albedo[3 * (size_t)v + ch];
            const double bound = a * (q * t->row_quant[v].b * l1[ch] + sqrt(eps) * tn[i] * l2[ch] + 1e-5 * tn[i] * l1[ch]);
            const double want = fmax(0.0, want3[3 * i + ch]), err = fabs(rgb[3 * (size_t)v + ch] - want);
            if (bound > 0.0) worst = fmax(worst, err / bound);
            else HL_CHECK(err == 0.0, "vertex %u: %g where the bound is 0", v, err);
            e2 += err * err;
            ref2 += want * want;
        }
    }
    hl_check_error(what, worst, 1.0);
    printf("    (relative L2 over the %u vertices: %.3g)\n", n, sqrt(e2 / ref2));
    free(rgb);
}

/* Relights t under env (a constant map of radiance c) with M terms on
 * ctx and measures the colours against the exact ones, c albedo sums[v]:
 * the worst error over each vertex's bound (albedo times bound[v]; a
 * vertex with bound 0 must be exact) into *worst, the worst error
 * relative to the exact colour into *worst_rel. */
static inline void pt_constant_errors(hl_context *ctx, const hl_transport *t, const hl_mesh *mesh, const hl_env *env,
                                      uint32_t M, double c, const double *sums, const double *bound, float *rgb,
                                      double *worst, double *worst_rel)
{
    pt_relight(ctx, t, env, M, 0, 0.0f, rgb);
    *worst = *worst_rel = 0.0;
    for (uint32_t v = 0; v < t->info.vertex_count; v++)
        for (int ch = 0; ch < 3; ch++) {
            const double a = mesh->albedo[3 * (size_t)v + ch], want = c * a * sums[v];
            const double err = fabs(rgb[3 * (size_t)v + ch] - want);
            if (bound[v] > 0.0) *worst = fmax(*worst, err / (a * bound[v]));
            else HL_CHECK(err == 0.0, "vertex %u: %g where the exact colour is 0", v, err);
            if (want > 0.0) *worst_rel = fmax(*worst_rel, err / want);
        }
}

/* Runs `haarlight precompute BUNNY -q --device ref ARGS` into
 * HL_TMP/stem.hlt: its exit status, with stderr's text in err; checks
 * whether an output was written. */
static inline int pt_run_precompute(const char *args, const char *stem, int expect_output, char *err, size_t n)
{
    char name[128];
    snprintf(name, sizeof name, "%s.hlt", stem);
    const char *bin = hl_test_env("HL_BIN", "haarlight"), *out = hl_test_tmp_path(name);
    snprintf(name, sizeof name, "%s.txt", stem);
    const char *log = hl_test_tmp_path(name);
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "'%s' precompute '%s' -q --device ref %s -o '%s' 2>'%s' >/dev/null", bin,
             hl_test_data_path("bunny_lowres.obj"), args, out, log);
    int st = system(cmd);
    size_t k = 0;
    uint8_t *text = hl_test_read_file(log, &k);
    snprintf(err, n, "%.*s", (int)k, text ? (const char *)text : "");
    free(text);
    HL_CHECK((access(out, F_OK) == 0) == expect_output, "%s: an output was%s written", args, expect_output ? " not" : "");
    remove(out);
    remove(log);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Each of the n option sets must exit 2 with its needle on stderr. */
typedef struct pt_bad_option { const char *args, *needle; } pt_bad_option;
static inline void pt_refuse_options(const pt_bad_option *c, size_t n, const char *stem)
{
    char err[4096];
    for (size_t i = 0; i < n; i++) {
        int rc = pt_run_precompute(c[i].args, stem, 0, err, sizeof err);
        printf("%s: exit %d: %.*s\n", c[i].args, rc, (int)strcspn(err, "\n"), err);
        HL_CHECK(rc == 2, "%s: exit %d, expected 2", c[i].args, rc);
        HL_CHECK(strstr(err, c[i].needle) != NULL, "%s: stderr does not name \"%s\": %s", c[i].args, c[i].needle, err);
    }
}

/* hl_precompute must refuse each of the n descriptors on the bunny
 * (HL_ERR_INVALID_ARGUMENT) and write nothing at HL_TMP/stem.hlt. */
static inline void pt_library_refuses(const hl_precompute_desc *bad, size_t n, const char *stem)
{
    hl_context *ctx = hl_test_ref_context(0);
    hl_mesh_load_desc ld = {{0.8f, 0.8f, 0.8f}, 'y', 0};
    hl_mesh *mesh = NULL;
    HL_CHECK(hl_mesh_load(ctx, hl_test_data_path("bunny_lowres.obj"), &ld, &mesh, NULL) == HL_OK, "mesh");
    char name[128];
    snprintf(name, sizeof name, "%s.hlt", stem);
    const char *path = hl_test_tmp_path(name);
    for (size_t i = 0; i < n; i++) {
        hl_result r = hl_precompute(ctx, mesh, &bad[i], path, NULL);
        printf("library, basis %u order %u side %u, N %u C %u: %s\n", bad[i].basis, bad[i].sh_order, bad[i].cube_side,
               bad[i].N, bad[i].C, hl_context_last_error(ctx));
        HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, "descriptor %zu accepted (%d)", i, (int)r);
        HL_CHECK(access(path, F_OK) != 0, "descriptor %zu wrote a file", i);
    }
    hl_mesh_destroy(mesh);
    hl_context_destroy(ctx);
}

#endif
