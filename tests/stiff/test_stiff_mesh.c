/* test_stiff_mesh.c - numerical stability under extreme meshes (suite
 * "stiff_mesh"). Each case runs both backends, asserts that no output is
 * NaN or Inf and that the two agree, and checks the colours against the
 * float64 reference and bounds described in tests/stiff/test_stiff_light.c.
 *
 * Cases (ctest hl.stiff_mesh.<case>; `test_stiff_mesh all` runs them in
 * turn):
 *   scale          the scene at 1e-6 and 1e6, and 2e5 and 1e6 away from
 *                  the origin: the unit scene's rays from the same
 *                  origins, colours within what those allow
 *   shape          zero-area triangles, duplicate vertices, zero normals
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

/* ================================================================ mesh scale and shape */

/* Where rays.c starts the rays of a vertex, along one axis: p + n offset,
 * the nearest float on the far side of the surface. Returns the distance
 * from p (exact: o and p are neighbouring floats). */
static double origin_shift(float p, float n, float offset)
{
    double want = (double)p + (double)n * offset;
    float o = (float)want;
    if (n > 0.0f && (double)o < want) o = nextafterf(o, INFINITY);
    if (n < 0.0f && (double)o > want) o = nextafterf(o, -INFINITY);
    return fabs((double)o - p);
}

/* Visibility rows of mesh m, one ray per cube texel, each vertex with its
 * own offset along its normal (offsets NULL: all `offset`). */
static uint8_t *visibility(const hl_mesh *m, const hl_geom *g, float offset, const float *offsets)
{
    hl_rt *rt = NULL;
    uint8_t *vis = need(malloc((size_t)m->vertex_count * g->ncube));
    hl_result r = hl_rt_create(ref_ctx(), m, &rt);
    for (uint32_t v = 0; r == HL_OK && v < m->vertex_count; v += offsets ? 1 : m->vertex_count)
        r = hl_rt_visibility(rt, g, m, v, offsets ? 1 : m->vertex_count, 1, offsets ? offsets[v] : offset,
                             vis + (size_t)v * g->ncube, NULL);
    HL_CHECK(r == HL_OK, "rays: %s", hl_context_last_error(ref_ctx()));
    hl_rt_destroy(rt);
    return vis;
}

/* The small scene at 1e-6 and 1e6, and 1e6 and 2e5 away from the origin.
 * Ray offsets are 1e-3 of the diagonal, under the spacing of the
 * coordinates out there (1/16 at 1e6, 1/64 at 2e5), where rays.c keeps
 * the origin one float off the surface rather than on it.
 *   Rays: the same as the unit scene's from the same origins (the unit
 *   scene traced with each vertex's own offset, the distance its origin
 *   has from the surface in the far scene; the normals are axis-aligned,
 *   so that is one number). The unit coordinates are multiples of 1/4, so
 *   translated copies are exact and the rays must agree exactly; scaled
 *   copies round, and a ray through an edge may tip: at most 1e-4 of them.
 *   Colours: |B - B_unit| at most what the differing rays make of the
 *   unquantised transport (|sum_i (raw_i - raw_unit_i) L_i|), plus the
 *   8-bit quantisation of both rows and the float bounds. */
static void case_scale(void)
{
    static const struct { const char *name; double scale, shift[3]; } sc[] = {
        {"unit", 1.0, {0, 0, 0}},
        {"scale 1e-6", 1e-6, {0, 0, 0}},
        {"scale 1e6", 1e6, {0, 0, 0}},
        {"shifted +1e6 x", 1.0, {1e6, 0, 0}},
        {"shifted +1e6 x, y, z", 1.0, {1e6, 1e6, 1e6}},
        {"shifted +2e5 x, y, z", 1.0, {2e5, 2e5, 2e5}},
    };
    const int ns = sizeof sc / sizeof sc[0];
    const uint32_t N = 16, C = 32;
    hl_geom *g = NULL;
    HL_CHECK(hl_geom_create(ref_ctx(), N, C, &g) == HL_OK, "geometry");
    hl_sky_desc sky = {.width = 256};
    hl_env *env = NULL;
    HL_CHECK(hl_env_create_sky(ref_ctx(), &sky, &env) == HL_OK, "sky");
    hl_mesh *m0 = NULL;
    float *rgb0 = NULL;
    sample *S0 = NULL;
    for (int s = 0; s < ns && g && env; s++) {
        case_begin("scale: %s", sc[s].name);
        hl_mesh *m = scene_mesh(sc[s].scale, sc[s].shift);
        hl_precompute_desc d = {.N = N, .C = C, .rule = HL_TRUNC_ALL};
        char name[48];
        snprintf(name, sizeof name, "scale_%d", s);
        rig rg;
        if (m && rig_open(&rg, precompute_both(m, &d, name))) {
            if (rig_run(&rg, env, HL_TERMS_ALL, sc[s].name)) {
                const uint32_t V = rg.V;
                float *raw = raw_rows(rg.t[1]);
                lighting L;
                lighting_make(&L, hl_relighter_tables(rg.r[1]), env);
                sample *S = samples_make(rg.t[1], &L, raw);
                if (s == 0) {
                    m0 = m, m = NULL;
                    rgb0 = need(malloc((size_t)V * 12));
                    memcpy(rgb0, rg.rgb[1], (size_t)V * 12);
                    S0 = S, S = NULL;
                } else if (m0 && V == m0->vertex_count) {
                    /* the rays, against the unit scene's from the same origins */
                    const float off = 1e-3f * hl_mesh_query_diagonal(m);
                    float *offs = need(malloc((size_t)V * 4));
                    for (uint32_t v = 0; v < V; v++) {
                        int k = 0;
                        while (k < 2 && m->normals[3 * (size_t)v + k] == 0.0f) k++;
                        offs[v] = (float)(origin_shift(m->positions[3 * (size_t)v + k], m->normals[3 * (size_t)v + k], off) /
                                          sc[s].scale);
                    }
                    uint8_t *vis = visibility(m, g, off, NULL), *vis0 = visibility(m0, g, 0.0f, offs);
                    size_t dt = 0, open = 0;
                    for (size_t i = 0; i < (size_t)V * g->ncube; i++) {
                        dt += vis[i] != vis0[i];
                        open += vis0[i] != 0;
                    }
                    char w[200];
                    int exact = sc[s].scale == 1.0;
                    snprintf(w, sizeof w, "%s: rays that differ from the unit scene's from the same origins (of %zu open)",
                             sc[s].name, open);
                    hl_check_error(w, (double)dt, exact ? 0.0 : 1e-4 * (double)V * g->ncube);
                    /* the colours */
                    double worst = 0.0, e_at = 0.0, b_at = 0.0, rel = 0.0;
                    for (uint32_t v = 0; v < V; v++)
                        for (int c = 0; c < 3; c++) {
                            const size_t i = 3 * (size_t)v + c;
                            const double a = m->albedo[i];
                            const float B = rg.rgb[1][i], B0 = rgb0[i];
                            double bound = a * fabs(S[i].ref_raw - S0[i].ref_raw) + a * (S[i].quant + S0[i].quant) +
                                           bound_accumulation(S + i, a, B) + bound_haar(S + i, a, L.norm[c], N) +
                                           bound_accumulation(S0 + i, a, B0) + bound_haar(S0 + i, a, L.norm[c], N);
                            double e = fabs((double)B - B0);
                            rel = fmax(rel, e / fabs((double)B0));
                            if (!(e / bound <= worst)) worst = e / bound, e_at = e, b_at = bound;
                        }
                    printf("%s: %zu rays differ from the unit scene's; largest relative colour difference %.3g; worst "
                           "|B - B_unit| %.4g where the bound is %.4g\n",
                           sc[s].name, dt, rel, e_at, b_at);
                    snprintf(w, sizeof w, "%s: |B - B_unit| / (differing rays + quantisation of both + rounding)", sc[s].name);
                    hl_check_error(w, worst, 1.0);
                    free(vis);
                    free(vis0);
                    free(offs);
                }
                free(S);
                free(raw);
                lighting_free(&L);
            }
            rig_close(&rg);
        }
        hl_mesh_destroy(m);
        case_end();
    }
    free(S0);
    free(rgb0);
    hl_mesh_destroy(m0);
    hl_env_destroy(env);
    hl_geom_destroy(g);
}

/* Zero-area triangles (collinear and repeated corners), duplicate
 * vertices and zero (and NaN) normals, built in memory and read from an
 * OBJ: they load, every normal is a unit vector, and the precompute and
 * the relight give finite colours on both backends. */
static void case_shape(void)
{
    /* a floor quad, a tent over it, and the trouble */
    static const float P[] = {
        -1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1,            /* 0-3 floor */
        -0.5f, 0.2f, 0, 0.5f, 0.2f, 0, 0, 0.6f, 0,         /* 4-6 tent */
        -0.5f, 0.2f, 0, 0.5f, 0.2f, 0,                     /* 7-8 duplicates of 4, 5 */
        0, 0.2f, 0.5f, 0, 0.4f, 0.5f, 0, 0.6f, 0.5f,       /* 9-11 collinear */
        0.5f, 0.2f, 0.5f,                                  /* 12 */
    };
    static const float Nn[] = {
        0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0,                /* zero normals at 1 and 3 */
        0, 0, 1, 0, 0, 1, 0, 0, 0,                         /* zero at 6 */
        0, 0, 1, 0, 0, 1,
        0, 0, 0, NAN, NAN, NAN, 1, 0, 0,                   /* zero, NaN */
        0, 0, 0,
    };
    static const uint32_t I[] = {
        0, 2, 1, 0, 3, 2,          /* floor */
        4, 5, 6, 8, 7, 6,          /* tent, front and back through the duplicates */
        9, 10, 11,                 /* zero area: collinear */
        4, 4, 5,                   /* repeated corner */
        12, 12, 12,                /* a point */
        7, 5, 6,                   /* duplicate-only triangle */
        9, 12, 10,
    };
    const uint32_t nv = sizeof P / 12, nt = sizeof I / 12;
    const uint32_t W = 128;
    float *px = pixels_const(W, 1.0f);
    for (int c = 0; c < 3; c++) px[3 * (20 * (size_t)W + 40) + c] = 1e5f;
    hl_env *env = env_of(W, px);
    for (int src = 0; src < 2; src++) {
        case_begin("shape: %s", src ? "OBJ file" : "hl_mesh_create");
        hl_mesh *m = NULL;
        hl_mesh_stats st = {0};
        hl_result r;
        if (src == 0) {
            r = hl_mesh_create(ref_ctx(), nv, P, Nn, NULL, nt, I, &m);
        } else {
            const char *path = hl_test_tmp_path("stiff_shape.obj");
            FILE *f = fopen(path, "w");
            for (uint32_t v = 0; f && v < nv; v++) fprintf(f, "v %.9g %.9g %.9g\n", P[3 * v], P[3 * v + 1], P[3 * v + 2]);
            for (uint32_t v = 0; f && v < nv; v++) fprintf(f, "vn %.9g %.9g %.9g\n", Nn[3 * v], Nn[3 * v + 1], Nn[3 * v + 2]);
            for (uint32_t t = 0; f && t < nt; t++)
                fprintf(f, "f %u//%u %u//%u %u//%u\n", I[3 * t] + 1, I[3 * t] + 1, I[3 * t + 1] + 1, I[3 * t + 1] + 1,
                        I[3 * t + 2] + 1, I[3 * t + 2] + 1);
            if (f) fclose(f);
            r = hl_mesh_load(ref_ctx(), path, NULL, &m, &st);
            printf("OBJ: %u file vertices, %u triangles; merged %u, degenerate %u, unreferenced %u, normals %d\n",
                   st.file_vertices, st.file_triangles, st.merged_vertices, st.degenerate_triangles,
                   st.unreferenced_vertices, st.had_normals);
            remove(path);
        }
        HL_CHECK(r == HL_OK, "load: %s", hl_context_last_error(ref_ctx()));
        if (m) {
            double worst = 0.0;
            for (uint32_t v = 0; v < m->vertex_count; v++) {
                const float *n = m->normals + 3 * (size_t)v;
                double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
                if (!(fabs(len - 1.0) <= worst)) worst = fabs(len - 1.0);
            }
            printf("%u vertices, %u triangles kept of %u\n", m->vertex_count, m->triangle_count, nt);
            hl_check_error("| |n| - 1 | over the normals (NaN fails)", worst, 4.0 * FLT_EPSILON);
            HL_CHECK(m->triangle_count <= nt - 3, "the three zero-area triangles must be dropped");
            hl_precompute_desc d = {.N = 16, .C = 16};
            rig g;
            if (rig_open(&g, precompute_both(m, &d, src ? "shape_obj" : "shape_mem"))) {
                if (env) rig_run(&g, env, HL_TERMS_ALL, "odd shapes");
                rig_close(&g);
            }
        }
        hl_mesh_destroy(m);
        case_end();
    }
    hl_env_destroy(env);
    free(px);
}

static const hl_test_case stiff_cases[] = {
    {"scale", case_scale},
    {"shape", case_shape},
    {NULL, NULL},
};

int main(int argc, char **argv) { return stiff_main(argc, argv, stiff_cases); }
