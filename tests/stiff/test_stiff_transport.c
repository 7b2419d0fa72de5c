/* test_stiff_transport.c - numerical stability of the transport at
 * extreme sizes and truncations (suite "stiff_transport"). Each case runs
 * both backends, asserts that no output is NaN or Inf and that the two
 * agree, and checks the colours against the float64 reference and bounds
 * described in tests/stiff/test_stiff_light.c.
 *
 * Cases (ctest hl.stiff_transport.<case>; `test_stiff_transport all` runs
 * them in turn):
 *   resolution     (N, C) over 8 .. 256: white furnace per N
 *   truncation     K = 0 (keeps nothing; the CLI refuses --terms 0), K = 1
 *                  (min == max quantises exactly), K = all (every non-zero)
 *   zero_transport vertices inside a closed box and facing down onto the
 *                  ground: empty rows, a = b = 0, colours exactly 0
 *   accumulation   rows of up to 2 N^2 terms at N = 128 and 256 against
 *                  double sums
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL), HL_TMP, HL_BIN,
 * tests/common/stiff_{scene,reference}.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <float.h>
#include <stdarg.h>
#include <stdint.h>
#include <sys/stat.h>

#include "exr_io.h"
#include "geom.h"
#include "hl_test.h"
#include "lighting.h"
#include "rays.h"
#include "twins.h"
#include "stiff_scene.h"
#include "stiff_reference.h"

/* ================================================================ resolution */

/* White furnace through the whole pipeline for (N, C) pairs, every
 * coefficient kept, log8: the open quad (albedo 1) under a constant 1
 * gives B = 1. On the unquantised transport the tolerance is the table's
 * first moments, 1 / N^2 (hl.analytic.furnace: normal +Y and C even, so no
 * part straddles the horizon); the stored rows add their 8-bit
 * quantisation, sum |L_i| q_i, and the float bounds. */
static void case_resolution(void)
{
    static const uint32_t NC[][2] = {{8, 8}, {16, 16}, {32, 32}, {64, 64}, {128, 128}, {256, 256}, {256, 8}, {8, 256}};
    hl_mesh *m = quad_mesh();
    float *px = pixels_const(64, 1.0f);
    hl_env *env = env_of(64, px);
    for (size_t k = 0; k < sizeof NC / sizeof NC[0]; k++) {
        const uint32_t N = NC[k][0], C = NC[k][1];
        case_begin("resolution: N=%u C=%u", N, C);
        double t0 = hl_now();
        hl_precompute_desc d = {.N = N, .C = C, .rule = HL_TRUNC_ALL};
        char name[64], what[96];
        snprintf(name, sizeof name, "res_%u_%u", N, C);
        snprintf(what, sizeof what, "N=%u C=%u", N, C);
        rig g;
        if (env && rig_open(&g, precompute_both(m, &d, name))) {
            if (rig_run(&g, env, HL_TERMS_ALL, what)) {
                float *raw = raw_rows(g.t[1]);
                reference R;
                reference_make(&R, &g, env, raw);
                check_both(what, &g, &R, 1);
                double worst = 0.0, tol_at = 0.0, err_at = 0.0, quant_at = 0.0, raw_worst = 0.0;
                for (uint32_t v = 0; v < g.V; v++)
                    for (int c = 0; c < 3; c++) {
                        const sample *s = R.S + 3 * (size_t)v + c;
                        float B = g.rgb[1][3 * (size_t)v + c];
                        double tol = 1.0 / ((double)N * N) + s->quant + bound_accumulation(s, 1.0, B) +
                                     bound_haar(s, 1.0, R.L.norm[c], N);
                        double e = fabs(B - 1.0);
                        raw_worst = fmax(raw_worst, fabs(s->ref_raw - 1.0));
                        if (e / tol > worst) worst = e / tol, tol_at = tol, err_at = e, quant_at = s->quant;
                    }
                char w[160];
                snprintf(w, sizeof w, "%s: furnace on the unquantised transport, |B - 1|", what);
                hl_check_error(w, raw_worst, 1.0 / ((double)N * N));
                printf("%s: furnace worst |B - 1| %.4g, tolerance 1/N^2 %.4g + quantisation %.4g + rounding = %.4g\n",
                       what, err_at, 1.0 / ((double)N * N), quant_at, tol_at);
                snprintf(w, sizeof w, "%s: furnace |B - 1| / tolerance", what);
                hl_check_error(w, worst, 1.0);
                const hl_row_quant q0 = g.t[1]->row_quant[0];
                printf("%s: vertex 0 keeps %llu coefficients, |v| from %.3g to %.3g (%.1f octaves over 127 log8 steps)\n",
                       what, (unsigned long long)(g.t[1]->row_offset[1] - g.t[1]->row_offset[0]), (double)q0.a,
                       (double)q0.b, log2((double)q0.b / q0.a));
                free(raw);
                reference_free(&R);
            }
            rig_close(&g);
        }
        printf("%s: %.2f s\n", what, hl_now() - t0);
        case_end();
    }
    hl_env_destroy(env);
    free(px);
    hl_mesh_destroy(m);
}

/* K = 0, 1 and all. The API's top-K rule with K = 0 keeps nothing (as
 * haarlight.h says: "required, >= 1 unless keep none"): an empty but valid
 * file whose colours are all 0; the CLI refuses --terms 0. K = 1 leaves
 * one value per row, min == max, which both schemes store exactly. K =
 * all keeps exactly the non-zero coefficients. */
static void case_truncation(void)
{
    hl_mesh *m = scene_mesh(1.0, no_shift);
    const uint32_t W = 256;
    float *px = pixels_const(W, 1.0f);
    for (int c = 0; c < 3; c++) px[3 * (30 * (size_t)W + 77) + c] = 1e4f;
    hl_env *env = env_of(W, px);
    float *raw = NULL;

    case_begin("truncation: K=0 through the API");
    {
        hl_precompute_desc d = {.N = 16, .C = 16, .rule = HL_TRUNC_TOPK, .K = 0};
        rig g;
        if (rig_open(&g, precompute_both(m, &d, "k0"))) {
            printf("K=0: %llu coefficients kept of %u vertices\n", (unsigned long long)g.t[1]->info.coefficients_kept, g.V);
            HL_CHECK(g.t[1]->info.coefficients_kept == 0, "K=0 must keep nothing");
            if (env && rig_run(&g, env, HL_TERMS_ALL, "K=0")) {
                size_t nz = 0;
                for (int b = 0; b < 2; b++)
                    for (size_t i = 0; i < (size_t)g.V * 3; i++) nz += g.rgb[b][i] != 0.0f;
                hl_check_error("K=0: non-zero colours", (double)nz, 0.0);
                printf("K=0: energy kept %g, bound %g\n", g.st[1].energy_kept, g.st[1].error_bound);
            }
            rig_close(&g);
        }
    }
    case_end();

    case_begin("truncation: K=0 through the CLI");
    {
        const char *obj = hl_test_tmp_path("stiff_k0.obj"), *out = hl_test_tmp_path("stiff_k0_cli.hlt");
        const char *log = hl_test_tmp_path("stiff_k0.log");
        FILE *f = fopen(obj, "w");
        if (f) {
            fputs("v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\nf 1 4 3\n", f);
            fclose(f);
        }
        char cmd[4096];
        remove(out);
        snprintf(cmd, sizeof cmd, "'%s' precompute '%s' --terms 0 -o '%s' > '%s' 2>&1", hl_test_env("HL_BIN", "haarlight"),
                 obj, out, log);
        int rc = system(cmd);
        char msg[1024] = "";
        f = fopen(log, "r");
        if (f) {
            msg[fread(msg, 1, sizeof msg - 1, f)] = '\0';
            fclose(f);
        }
        struct stat sb;
        msg[strcspn(msg, "\n")] = '\0';
        printf("--terms 0: exit %d, message: %s\n", rc, msg);
        HL_CHECK(rc != 0 && strstr(msg, "--terms") && stat(out, &sb) != 0,
                 "the CLI must refuse --terms 0, name the option and write nothing");
        remove(obj);
        remove(log);
    }
    case_end();

    for (int q = 0; q < 2; q++) {
        const uint32_t scheme = q ? HL_QUANT_LINEAR8 : HL_QUANT_LOG8;
        const char *qn = q ? "linear8" : "log8";
        case_begin("truncation: K=1, %s", qn);
        hl_precompute_desc d = {.N = 16, .C = 16, .rule = HL_TRUNC_TOPK, .K = 1, .quant = scheme};
        char name[32];
        snprintf(name, sizeof name, "k1_%s", qn);
        rig g;
        if (rig_open(&g, precompute_both(m, &d, name))) {
            const uint32_t nc = 2 * 16 * 16;
            if (!raw) raw = raw_rows(g.t[1]);
            float *row = need(malloc(nc * 4));
            size_t bad = 0;
            for (uint32_t v = 0; v < g.V; v++) {
                /* the largest |raw| (first in slot order on ties) */
                uint32_t best = 0;
                for (uint32_t i = 1; i < nc; i++)
                    if (hl_key(raw[(size_t)v * nc + i]) > hl_key(raw[(size_t)v * nc + best])) best = i;
                hl_transport_query_row(g.t[1], v, row);
                hl_row_quant rq = g.t[1]->row_quant[v];
                float want = raw[(size_t)v * nc + best];
                for (uint32_t i = 0; i < nc; i++) bad += memcmp(row + i, i == best ? &want : &(float){0.0f}, 4) != 0;
                bad += scheme == HL_QUANT_LOG8 ? (rq.a != fabsf(want) || rq.b != fabsf(want)) : (rq.a != want || rq.b != want);
            }
            char w[128];
            snprintf(w, sizeof w, "K=1 %s: stored values (and a, b) not exactly the largest coefficient", qn);
            hl_check_error(w, (double)bad, 0.0);
            free(row);
            if (env) rig_run(&g, env, HL_TERMS_ALL, name);
            rig_close(&g);
        }
        case_end();

        case_begin("truncation: K=all, %s", qn);
        hl_precompute_desc da = {.N = 16, .C = 16, .rule = HL_TRUNC_ALL, .quant = scheme};
        snprintf(name, sizeof name, "kall_%s", qn);
        if (rig_open(&g, precompute_both(m, &da, name))) {
            const uint32_t nc = 2 * 16 * 16;
            uint64_t nonzero = 0;
            size_t wrong = 0;
            for (uint32_t v = 0; v < g.V; v++) {
                uint64_t nz = 0;
                for (uint32_t i = 0; i < nc; i++) nz += raw[(size_t)v * nc + i] != 0.0f;
                nonzero += nz;
                wrong += nz != g.t[1]->row_offset[v + 1] - g.t[1]->row_offset[v];
            }
            printf("K=all %s: %llu kept, %llu non-zero coefficients\n", qn,
                   (unsigned long long)g.t[1]->info.coefficients_kept, (unsigned long long)nonzero);
            hl_check_error("K=all: rows whose kept count is not their non-zero count", (double)wrong, 0.0);
            if (env && rig_run(&g, env, HL_TERMS_ALL, name)) {
                reference R;
                reference_make(&R, &g, env, raw);
                check_both(name, &g, &R, 1);
                reference_free(&R);
            }
            rig_close(&g);
        }
        case_end();
    }
    free(raw);
    hl_env_destroy(env);
    free(px);
    hl_mesh_destroy(m);
}

/* ================================================================ degenerate transport */

/* A triangle inside a closed box sees nothing; a triangle facing straight
 * down just above a wide ground sees only the ground. Their rows are
 * empty (a = b = 0 in both schemes) and their colours exactly 0. */
static void case_zero_transport(void)
{
    builder b = builder_new(64, 64);
    add_grid(&b, 4, 8.0, 0.0);
    /* closed box, 8 shared corners, wound outward, y in [0.5, 1.5] */
    const uint32_t c0 = b.nv;
    for (int i = 0; i < 8; i++) add_vertex(&b, i & 1 ? 0.5 : -0.5, i & 2 ? 1.5 : 0.5, i & 4 ? 0.5 : -0.5, 0, 0, 0);
    static const uint32_t faces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    for (int f = 0; f < 6; f++) {
        add_tri(&b, c0 + faces[f][0], c0 + faces[f][1], c0 + faces[f][2]);
        add_tri(&b, c0 + faces[f][0], c0 + faces[f][2], c0 + faces[f][3]);
    }
    /* inside: normal +Y; outside, 0.05 above the ground: normal -Y */
    const uint32_t in0 = b.nv;
    add_vertex(&b, -0.1, 1.0, -0.1, 0, 0, 0);
    add_vertex(&b, -0.1, 1.0, 0.1, 0, 0, 0);
    add_vertex(&b, 0.1, 1.0, -0.1, 0, 0, 0);
    add_tri(&b, in0, in0 + 1, in0 + 2);
    add_vertex(&b, 4.0, 0.05, 4.0, 0, 0, 0);
    add_vertex(&b, 4.2, 0.05, 4.0, 0, 0, 0);
    add_vertex(&b, 4.0, 0.05, 4.2, 0, 0, 0);
    add_tri(&b, in0 + 3, in0 + 4, in0 + 5);
    hl_mesh *m = build_mesh(&b, 1.0, no_shift, 0);
    builder_free(&b);
    if (!m) return;
    /* find them again: normals come from the winding */
    uint32_t dark[6], nd = 0;
    for (uint32_t v = 0; v < m->vertex_count && nd < 6; v++) {
        const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v;
        if ((p[1] == 1.0f && fabsf(p[0]) < 0.2f && n[1] == 1.0f) || (p[1] == 0.05f && n[1] == -1.0f)) dark[nd++] = v;
    }
    HL_CHECK(nd == 6, "found %u of the 6 dark vertices (normals +Y inside, -Y above the ground)", nd);
    const uint32_t W = 256;
    float *px = pixels_const(W, 1.0f);
    for (int c = 0; c < 3; c++) px[3 * (30 * (size_t)W + 77) + c] = 1e5f;
    hl_env *env = env_of(W, px);
    for (int q = 0; q < 2; q++) {
        const uint32_t scheme = q ? HL_QUANT_LINEAR8 : HL_QUANT_LOG8;
        for (int rule = 0; rule < 2; rule++) {
            const char *qn = q ? "linear8" : "log8", *rn = rule ? "all" : "energy";
            case_begin("zero_transport: %s, rule %s", qn, rn);
            hl_precompute_desc d = {.N = 16, .C = 16, .rule = rule ? HL_TRUNC_ALL : HL_TRUNC_ENERGY, .quant = scheme};
            char name[48];
            snprintf(name, sizeof name, "zero_%s_%s", qn, rn);
            rig g;
            if (rig_open(&g, precompute_both(m, &d, name))) {
                float *raw = raw_rows(g.t[1]);
                size_t nonzero_raw = 0, stored = 0, ab = 0, lit = 0;
                const uint32_t nc = 2 * 16 * 16;
                for (uint32_t k = 0; k < nd; k++) {
                    uint32_t v = dark[k];
                    for (uint32_t i = 0; i < nc; i++) nonzero_raw += raw[(size_t)v * nc + i] != 0.0f;
                    stored += g.t[1]->row_offset[v + 1] - g.t[1]->row_offset[v];
                    ab += g.t[1]->row_quant[v].a != 0.0f || g.t[1]->row_quant[v].b != 0.0f;
                }
                hl_check_error("dark vertices: non-zero unquantised coefficients (every ray blocked)", (double)nonzero_raw, 0.0);
                hl_check_error("dark vertices: stored entries", (double)stored, 0.0);
                hl_check_error("dark vertices: a, b not both 0 (min == max == 0)", (double)ab, 0.0);
                if (env && rig_run(&g, env, HL_TERMS_ALL, name)) {
                    for (int bk = 0; bk < 2; bk++)
                        for (uint32_t k = 0; k < nd; k++)
                            for (int c = 0; c < 3; c++) lit += g.rgb[bk][3 * (size_t)dark[k] + c] != 0.0f;
                    hl_check_error("dark vertices: non-zero colours (both backends)", (double)lit, 0.0);
                }
                free(raw);
                rig_close(&g);
            }
            case_end();
        }
    }
    hl_env_destroy(env);
    free(px);
    hl_mesh_destroy(m);
}

/* ================================================================ accumulation */

/* Long rows: every coefficient kept at N = 128 and 256 (the box's walls
 * face sideways, so their rows fill both maps) under a noisy map whose
 * Haar coefficients are all non-zero. The float sums against double sums
 * of the same float products: the rigorous gamma_n bound, and the
 * statistical one, 4 u sqrt(n) sum |T_i L_i|, which independent roundings
 * meet with a wide margin. */
static void case_accumulation(void)
{
    static const uint32_t Ns[] = {128, 256};
    hl_mesh *m = scene_mesh(1.0, no_shift);
    for (int k = 0; k < 2; k++) {
        const uint32_t N = Ns[k], W = 8 * N;
        case_begin("accumulation: N=%u", N);
        double t0 = hl_now();
        hl_precompute_desc d = {.N = N, .C = 8, .rule = HL_TRUNC_ALL};
        char name[32];
        snprintf(name, sizeof name, "accum_%u", N);
        rig g;
        float *px = need(malloc((size_t)W * (W / 2) * 12));
        for (size_t i = 0; i < (size_t)W * (W / 2) * 3; i++) px[i] = (float)(2.0 * rng_unit());
        hl_env *env = env_of(W, px);
        if (env && rig_open(&g, precompute_both(m, &d, name))) {
            if (rig_run(&g, env, HL_TERMS_ALL, name)) {
                reference R;
                reference_make(&R, &g, env, NULL);
                check_both(name, &g, &R, 0);
                double worst = 0.0, e_at = 0.0, b_at = 0.0;
                uint32_t longest = 0;
                for (uint32_t v = 0; v < g.V; v++)
                    for (int c = 0; c < 3; c++) {
                        const sample *s = R.S + 3 * (size_t)v + c;
                        double a = g.t[1]->mesh->albedo[3 * (size_t)v + c];
                        float B = g.rgb[1][3 * (size_t)v + c];
                        double bound = a * 4.0 * U_F32 * sqrt((double)s->n) * s->abs_sum + U_F32 * fabs((double)B);
                        double e = fabs(B - a * s->ref_f);
                        if (s->n > longest) longest = s->n;
                        if (e / bound > worst) worst = e / bound, e_at = e, b_at = bound;
                    }
                printf("%s: longest row %u terms of %u; worst error %.4g where 4 u sqrt(n) sum|T L| is %.4g\n", name,
                       longest, R.L.nc, e_at, b_at);
                hl_check_error("float sum vs double sum / (4 u sqrt(n) sum |T_i L_i| + u |B|)", worst, 1.0);
                reference_free(&R);
            }
            rig_close(&g);
        }
        hl_env_destroy(env);
        free(px);
        printf("%s: %.2f s\n", name, hl_now() - t0);
        case_end();
    }
    hl_mesh_destroy(m);
}

static const hl_test_case stiff_cases[] = {
    {"resolution", case_resolution},
    {"truncation", case_truncation},
    {"zero_transport", case_zero_transport},
    {"accumulation", case_accumulation},
    {NULL, NULL},
};

int main(int argc, char **argv) { return stiff_main(argc, argv, stiff_cases); }
