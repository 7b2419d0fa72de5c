/* test_dyn_irradiance.c - the dynamic method's per-vertex irradiance
 * (kernels/dynamic/dyn_irradiance.cl, twin
 * host/src/dynamic/twins/dyn_irradiance.c, module
 * host/src/dynamic/irradiance.c), suite "dyn_irradiance". The lights come
 * from the shared maps (HL_TEST_DATA/envmaps; exit 77 where missing).
 *
 * dyn_irradiance.twin       the OpenCL module against the twin on the
 *                           module's own tables, per element, on four maps
 *                           (F = 8, 32, 64, both split rules); the
 *                           reference backend end to end; each new split
 *                           replaces the tables.
 * dyn_irradiance.exact      the twin against area_lights.c's
 *                           hl_area_light_irradiance and
 *                           hl_light_split_ambient (double sums) on random
 *                           normals, normals across each light's horizon
 *                           and axis normals, under both split rules and
 *                           F = 8, 32, 64.
 * dyn_irradiance.bad_input  NaN and Inf normals (the module refuses them;
 *                           the twin gives E = 0, the ambient NaN for NaN),
 *                           N = 0, missing arrays, a split of no lights,
 *                           a malformed split.
 * timing                    not a ctest case (it asserts nothing): the
 *                           module on the OpenCL device and on the
 *                           reference backend against the host loop of
 *                           dyn_frame.c, 11k normals x 32 lights
 *                           (argument "timing"; "timing N K [MESH]" for
 *                           others, MESH's normals for random ones).
 * Depends on: irradiance.h, area_lights.h, hl_test.h.
 */
#include <float.h>
#include <time.h>

#include "area_lights.h"
#include "hl_test.h"
#include "irradiance.h"

#define PI 3.14159265358979323846

static void random_unit(float n[3])
{
    for (;;) {
        double v[3], l = 0.0;
        for (int k = 0; k < 3; k++) {
            v[k] = 2.0 * hl_rng_unit() - 1.0;
            l += v[k] * v[k];
        }
        if (l > 1e-4 && l <= 1.0) {
            l = sqrt(l);
            for (int k = 0; k < 3; k++) n[k] = (float)(v[k] / l);
            return;
        }
    }
}

/* A unit normal at angle acos(c) from unit d, about a random axis. */
static void normal_at(const float d[3], double c, float n[3])
{
    float r[3];
    double p[3], l;
    do {
        random_unit(r);
        double rd = r[0] * d[0] + r[1] * d[1] + r[2] * d[2];
        for (int k = 0; k < 3; k++) p[k] = r[k] - rd * d[k];
        l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    } while (l < 1e-3);
    double s = sqrt(fmax(0.0, 1.0 - c * c)), m = 0.0, q[3];
    for (int k = 0; k < 3; k++) {
        q[k] = c * d[k] + s * p[k] / l;
        m += q[k] * q[k];
    }
    for (int k = 0; k < 3; k++) n[k] = (float)(q[k] / sqrt(m));
}

/* Normals: the six axes, 30 in coordinate planes (a zero component: a
 * face's gs or gt exactly 0), `nr` random, and per light `per` across its
 * horizon (n . dir uniform in (-sin extent, sin extent)). Returns count. */
static uint32_t make_normals(const hl_light_split *s, uint32_t nr, uint32_t per, float **out)
{
    uint32_t n = 36 + nr + per * s->count, i = 0;
    float *v = malloc((size_t)n * 12);
    for (int a = 0; a < 6; a++, i++) {
        v[3 * i] = v[3 * i + 1] = v[3 * i + 2] = 0.0f;
        v[3 * i + a % 3] = a < 3 ? 1.0f : -1.0f;
    }
    for (int a = 0; a < 30; a++, i++) {
        random_unit(v + 3 * i);
        v[3 * i + a % 3] = 0.0f;
        float l = sqrtf(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
        for (int k = 0; k < 3; k++) v[3 * i + k] /= l;
    }
    for (uint32_t r = 0; r < nr; r++, i++) random_unit(v + 3 * i);
    for (uint32_t k = 0; k < s->count; k++) {
        const hl_area_light *l = &s->lights[k];
        double se = l->extent < 0.5 * PI ? sin((double)l->extent) : 1.0;
        for (uint32_t r = 0; r < per; r++, i++) normal_at(l->dir, (2.0 * hl_rng_unit() - 1.0) * se, v + 3 * i);
    }
    *out = v;
    return n;
}

static const char *const g_maps[] = {"city", "sunset", "interior", "studio"};
enum { NMAPS = 4 };

/* The shared map `name`, or NULL (skip marked) where HL_TEST_DATA lacks it. */
static hl_env *load_map(hl_context *ctx, const char *name)
{
    const char *data = hl_test_env("HL_TEST_DATA", NULL);
    char path[1024];
    if (data) snprintf(path, sizeof path, "%s/envmaps/%s.exr", data, name);
    FILE *probe = data ? fopen(path, "rb") : NULL;
    if (!probe) {
        hl_test_skip_missing(data ? path : "HL_TEST_DATA");
        return NULL;
    }
    fclose(probe);
    hl_env *env = NULL;
    hl_env_stats st;
    if (hl_env_load(ctx, path, &env, &st) != HL_OK) {
        HL_CHECK(0, "%s: %s", path, hl_context_last_error(ctx));
        return NULL;
    }
    return env;
}

static hl_light_split *make_split(hl_context *ctx, const hl_env *env, hl_split_rule rule, uint32_t F, int32_t K)
{
    hl_light_split_params p;
    hl_light_split_defaults(&p);
    p.rule = rule;
    if (rule == HL_SPLIT_OF_MAP) p.threshold = HL_LIGHTS_DEFAULT_THRESHOLD;
    if (F) p.face_res = F;
    p.lights = K;
    hl_light_split *s = NULL;
    if (hl_area_lights_split(ctx, env, &p, &s) != HL_OK) HL_CHECK(0, "split: %s", hl_context_last_error(ctx));
    return s;
}

static double energy_of(const hl_light_split *s, uint32_t k, int c)
{
    return fmax((double)s->lights[k].energy[c], 1e-30);
}

/* ---------------------------------------------------------------- twin */

/* The module's output (E, amb, any for normals nv) against the twin on
 * its tables: worst difference over the light's (folded) energy, and the
 * count of elements not bit-identical. */
static void against_twin(const hl_dyn_irr *m, const hl_light_split *s, const float *nv, uint32_t n, const float *E,
                         const float *amb, const uint8_t *any, double *worst, double *worst_amb, uint64_t *differ,
                         uint64_t *total)
{
    const hl_dyn_irr_tables *t = hl_dyn_irr_get_tables(m);
    for (uint32_t k = 0; k < t->K; k++) {
        int lit = 0;
        for (uint32_t v = 0; v < n; v++) {
            float e[3];
            lit |= hl_ref_dyn_irr_light(t->lf + HL_DYN_IRR_LF * k, t->lu + HL_DYN_IRR_LU * k, t->mom, t->pre,
                                        nv + 3 * v, e);
            const float *g = E + 3 * ((size_t)k * n + v);
            for (int c = 0; c < 3; c++) {
                *worst = fmax(*worst, fabs((double)g[c] - e[c]) / energy_of(s, k, c));
                *differ += memcmp(&g[c], &e[c], 4) != 0;
                ++*total;
            }
        }
        HL_CHECK(any[k] == lit, "light %u: any = %d from the module, %d from the twin", k, any[k], lit);
    }
    for (uint32_t v = 0; v < n; v++) {
        float a[3];
        hl_ref_dyn_irr_ambient(t->sh, nv + 3 * v, a);
        for (int c = 0; c < 3; c++) {
            *worst_amb = fmax(*worst_amb, fabs((double)a[c] - amb[3 * v + c]) / fmax(s->stats.folded_energy[c], 1e-30));
            *differ += memcmp(&a[c], &amb[3 * v + c], 4) != 0;
            ++*total;
        }
    }
}

static void case_twin(void)
{
    hl_context *ctx = hl_test_cl_context(0), *ref = hl_test_ref_context(2);
    if (!ctx) { HL_CHECK(0, "no OpenCL context"); return; }
    double worst = 0.0, worst_amb = 0.0, worst_ref = 0.0;
    uint64_t differ = 0, total = 0;
    hl_dyn_irr *m = NULL, *mr = NULL;
    for (int i = 0; i < NMAPS; i++) {
        hl_env *env = load_map(ref, g_maps[i]);
        if (!env) break;
        static const uint32_t Fs[NMAPS] = {32, 64, 8, 32};
        hl_light_split *s = make_split(ref, env, i % 2 ? HL_SPLIT_OF_MAP : HL_SPLIT_OF_LIGHT, Fs[i], 32);
        hl_env_destroy(env);
        if (!s) break;
        /* the first map creates the modules, the others replace their tables */
        hl_result r = m ? hl_dyn_irr_set_split(m, s) : hl_dyn_irr_create(ctx, s, &m);
        HL_CHECK(r == HL_OK, "%s: %s", g_maps[i], hl_context_last_error(ctx));
        r = mr ? hl_dyn_irr_set_split(mr, s) : hl_dyn_irr_create(ref, s, &mr);
        HL_CHECK(r == HL_OK, "%s: %s", g_maps[i], hl_context_last_error(ref));
        float *nv = NULL;
        uint32_t n = make_normals(s, 3000 + 1000 * (uint32_t)i, 100, &nv), K = s->count;
        float *E = malloc((size_t)K * n * 12), *Er = malloc((size_t)K * n * 12);
        float *amb = malloc((size_t)n * 12), *ambr = malloc((size_t)n * 12);
        uint8_t any[HL_LIGHTS_MAX_FACE], anyr[HL_LIGHTS_MAX_FACE];
        if (m && mr && hl_dyn_irr_run(m, nv, n, E, amb, any) == HL_OK &&
            hl_dyn_irr_run(mr, nv, n, Er, ambr, anyr) == HL_OK) {
            against_twin(m, s, nv, n, E, amb, any, &worst, &worst_amb, &differ, &total);
            for (size_t j = 0; j < (size_t)K * n * 3; j++)
                worst_ref = fmax(worst_ref, fabs((double)E[j] - Er[j]) / energy_of(s, (uint32_t)(j / (3 * (size_t)n)), (int)(j % 3)));
            HL_CHECK(memcmp(any, anyr, K) == 0, "%s: any differs between the backends", g_maps[i]);
            printf("%s (%s rule, F = %u): %u lights, %u normals\n", g_maps[i], i % 2 ? "map" : "light", s->F, K, n);
        } else {
            HL_CHECK(0, "%s: run failed: %s / %s", g_maps[i], hl_context_last_error(ctx), hl_context_last_error(ref));
        }
        free(nv); free(E); free(Er); free(amb); free(ambr);
        hl_light_split_destroy(s);
    }
    if (total) {
        printf("elements not bit-identical between kernel and twin: %llu of %llu\n", (unsigned long long)differ,
               (unsigned long long)total);
        /* The same float operations in the same order with FP_CONTRACT
         * off and correctly rounded division: PoCL gives the twin's bits.
         * A device that divides within its 2.5 ulp or flushes denormals
         * may move a run's end by one texel whose corner is within
         * rounding of the horizon (its n . m is then within rounding of
         * 0) or round a sum differently: 2^-20 of the light's energy is
         * 16 times float's epsilon and far below any visible change. */
        hl_check_error("E_k, kernel vs twin on the same tables, over the light's energy", worst, 1.0 / (1 << 20));
        hl_check_error("ambient, kernel vs twin, over the folded energy", worst_amb, 1.0 / (1 << 20));
        hl_check_error("E_k, OpenCL module vs reference backend end to end, over the light's energy", worst_ref,
                       1.0 / (1 << 20));
    }
    hl_dyn_irr_destroy(m);
    hl_dyn_irr_destroy(mr);
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

/* ---------------------------------------------------------------- exact */

typedef struct exact_err {
    double light, amb, rel_big; /* over energy, over folded energy, over E where E > 1% of energy */
    uint64_t straddle, checked;
} exact_err;

static void exact_one(hl_context *ref, const hl_light_split *s, exact_err *x)
{
    hl_dyn_irr *m = NULL;
    if (hl_dyn_irr_create(ref, s, &m) != HL_OK) { HL_CHECK(0, "%s", hl_context_last_error(ref)); return; }
    const hl_dyn_irr_tables *t = hl_dyn_irr_get_tables(m);
    float *nv = NULL;
    uint32_t n = make_normals(s, 400, 60, &nv);
    for (uint32_t v = 0; v < n; v++) {
        const float *nn = nv + 3 * v;
        for (uint32_t k = 0; k < s->count; k++) {
            const hl_area_light *l = &s->lights[k];
            float e[3], h[3];
            hl_ref_dyn_irr_light(t->lf + HL_DYN_IRR_LF * k, t->lu + HL_DYN_IRR_LU * k, t->mom, t->pre, nn, e);
            hl_area_light_irradiance(s, k, nn, h);
            float nd = nn[0] * l->dir[0] + nn[1] * l->dir[1] + nn[2] * l->dir[2];
            x->straddle += fabsf(nd) < sinf(l->extent);
            for (int c = 0; c < 3; c++) {
                double d = fabs((double)e[c] - h[c]);
                x->light = fmax(x->light, d / energy_of(s, k, c));
                if (h[c] > 0.01 * energy_of(s, k, c)) x->rel_big = fmax(x->rel_big, d / h[c]);
                x->checked++;
            }
        }
        float a[3], b[3];
        hl_ref_dyn_irr_ambient(t->sh, nn, a);
        hl_light_split_ambient(s, nn, b);
        for (int c = 0; c < 3; c++)
            x->amb = fmax(x->amb, fabs((double)a[c] - b[c]) / fmax(s->stats.folded_energy[c], 1e-30));
    }
    free(nv);
    hl_dyn_irr_destroy(m);
}

static void case_exact(void)
{
    hl_context *ref = hl_test_ref_context(2);
    exact_err x = {0};
    static const uint32_t Fs[] = {8, 32, 64};
    for (int i = 0; i < NMAPS && !hl_test_skipped; i++) {
        hl_env *env = load_map(ref, g_maps[i]);
        if (!env) break;
        for (int r = 0; r < 2; r++)
            for (int f = 0; f < 3; f++) {
                hl_light_split *s = make_split(ref, env, r ? HL_SPLIT_OF_MAP : HL_SPLIT_OF_LIGHT, Fs[f], 32);
                if (s) exact_one(ref, s, &x);
                hl_light_split_destroy(s);
            }
        hl_env_destroy(env);
    }
    if (x.checked) {
        printf("exact: %llu light-normal pairs across a horizon, %llu values checked\n",
               (unsigned long long)x.straddle, (unsigned long long)x.checked);
        HL_CHECK(x.straddle > 10000, "too few normals across a horizon: %llu", (unsigned long long)x.straddle);
        /* float against double sums: a straddling light adds up to F row
         * runs and a few cut texels a row in float, each sum within 2^-24
         * of the light's energy, the dot products 3 terms each: at
         * F = 64 about 200 roundings of at most 2^-24 energy, 1.2e-5; the
         * wholly-above case is the host's own float formula */
        hl_check_error("exact: twin E_k against hl_area_light_irradiance, over the light's energy", x.light, 1.2e-5);
        printf("exact: where E_k > 1%% of the light's energy, worst relative error %.3g\n", x.rel_big);
        /* 9 float products and sums, each term within a few times the
         * folded energy: about 20 roundings of 2^-24 */
        hl_check_error("exact: twin ambient against hl_light_split_ambient, over the folded energy", x.amb, 2e-6);
    }
    hl_context_destroy(ref);
}

/* ---------------------------------------------------------------- bad input */

static void bad_input_backend(hl_context *ctx, const hl_light_split *s, const char *name)
{
    hl_dyn_irr *m = NULL;
    HL_CHECK(hl_dyn_irr_create(ctx, s, &m) == HL_OK, "%s: %s", name, hl_context_last_error(ctx));
    if (!m) return;
    const uint32_t K = s->count;
    float nv[9] = {0, 1, 0, 0, 0, 1, 1, 0, 0}, E[3 * 3 * 64], amb[9];
    uint8_t any[64];
    memset(any, 7, sizeof any);
    for (int bad = 0; bad < 3; bad++) {
        float saved = nv[4];
        nv[4] = bad == 0 ? NAN : bad == 1 ? INFINITY : -INFINITY;
        hl_result r = hl_dyn_irr_run(m, nv, 3, E, amb, any);
        const char *msg = hl_context_last_error(ctx);
        HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && strstr(msg, "receiver 1"), "%s: a %g normal: %d, %s", name,
                 (double)nv[4], (int)r, msg);
        nv[4] = saved;
    }
    printf("%s: a non-finite normal: \"%s\"\n", name, hl_context_last_error(ctx));
    E[0] = 42.0f;
    memset(any, 7, sizeof any);
    HL_CHECK(hl_dyn_irr_run(m, nv, 0, E, amb, any) == HL_OK, "%s: N = 0: %s", name, hl_context_last_error(ctx));
    int zeros = 1;
    for (uint32_t k = 0; k < K; k++) zeros &= any[k] == 0;
    HL_CHECK(zeros && E[0] == 42.0f, "%s: N = 0 must report no light and write no E", name);
    HL_CHECK(hl_dyn_irr_run(m, NULL, 3, E, amb, any) == HL_ERR_INVALID_ARGUMENT, "%s: no normals accepted", name);
    HL_CHECK(hl_dyn_irr_run(m, nv, 3, NULL, amb, any) == HL_ERR_INVALID_ARGUMENT, "%s: no E accepted", name);
    HL_CHECK(hl_dyn_irr_run(m, nv, 3, E, NULL, NULL) == HL_OK, "%s: ambient and any are optional: %s", name,
             hl_context_last_error(ctx));
    HL_CHECK(hl_dyn_irr_set_split(m, NULL) == HL_ERR_INVALID_ARGUMENT, "%s: a NULL split accepted", name);
    /* a split of no kept lights: the ambient alone, E may be NULL */
    hl_light_split none = *s;
    none.count = 0;
    HL_CHECK(hl_dyn_irr_set_split(m, &none) == HL_OK, "%s: no lights: %s", name, hl_context_last_error(ctx));
    float a2[9];
    HL_CHECK(hl_dyn_irr_run(m, nv, 3, NULL, a2, any) == HL_OK, "%s: no lights: %s", name, hl_context_last_error(ctx));
    for (int v = 0; v < 3; v++) {
        float h[3];
        hl_light_split_ambient(s, nv + 3 * v, h);
        for (int c = 0; c < 3; c++)
            HL_CHECK(fabs((double)a2[3 * v + c] - h[c]) <= 2e-6 * s->stats.folded_energy[c],
                     "%s: no lights: ambient %g, host %g", name, (double)a2[3 * v + c], (double)h[c]);
    }
    /* a rectangle off its face: refused, and the module then holds none */
    hl_light_split bad = *s;
    hl_area_light *ls = malloc(s->total * sizeof *ls);
    memcpy(ls, s->lights, s->total * sizeof *ls);
    ls[0].x1 = s->F + 1;
    bad.lights = ls;
    hl_result r = hl_dyn_irr_set_split(m, &bad);
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && strstr(hl_context_last_error(ctx), "light 0"),
             "%s: a malformed split: %d, %s", name, (int)r, hl_context_last_error(ctx));
    HL_CHECK(hl_dyn_irr_run(m, nv, 3, E, amb, any) == HL_ERR_INVALID_ARGUMENT, "%s: ran after a failed set_split",
             name);
    HL_CHECK(hl_dyn_irr_set_split(m, s) == HL_OK, "%s: %s", name, hl_context_last_error(ctx));
    HL_CHECK(hl_dyn_irr_run(m, nv, 3, E, amb, any) == HL_OK, "%s: %s", name, hl_context_last_error(ctx));
    free(ls);
    hl_dyn_irr *m2 = NULL;
    HL_CHECK(hl_dyn_irr_create(ctx, NULL, &m2) == HL_ERR_INVALID_ARGUMENT && !m2, "%s: created without a split", name);
    HL_CHECK(hl_dyn_irr_create(ctx, s, NULL) == HL_ERR_INVALID_ARGUMENT, "%s: no output pointer accepted", name);
    hl_dyn_irr_destroy(m);
}

static void case_bad_input(void)
{
    hl_context *ref = hl_test_ref_context(2), *ctx = hl_test_cl_context(0);
    hl_env *env = load_map(ref, "city");
    hl_light_split *s = env ? make_split(ref, env, HL_SPLIT_OF_LIGHT, 0, 32) : NULL;
    if (s) {
        HL_CHECK(s->count <= 64, "the test's arrays hold 64 lights");
        bad_input_backend(ref, s, "reference");
        if (ctx) bad_input_backend(ctx, s, "OpenCL");
        else HL_CHECK(0, "no OpenCL context");
        /* the twin at non-finite normals: E = 0, and for a NaN normal a
           NaN ambient as hl_light_split_ambient's. hl_area_light_irradiance
           cannot be asked: at a NaN normal it converts NaN to an index
           (area_lights.c, texel_edge) and crashes, and an Inf normal gets
           Inf where the light is wholly above; the module refuses both. */
        hl_dyn_irr *m = NULL;
        HL_CHECK(hl_dyn_irr_create(ref, s, &m) == HL_OK, "%s", hl_context_last_error(ref));
        const hl_dyn_irr_tables *t = hl_dyn_irr_get_tables(m);
        float nn[5][3] = {{NAN, 0, 1}, {0, NAN, NAN}, {NAN, NAN, NAN}, {INFINITY, 0, 0}, {0, -INFINITY, 0}};
        int zero = 1, amb_nan = 1;
        for (int i = 0; i < 5; i++) {
            for (uint32_t k = 0; k < s->count; k++) {
                float e[3];
                int lit = hl_ref_dyn_irr_light(t->lf + HL_DYN_IRR_LF * k, t->lu + HL_DYN_IRR_LU * k, t->mom, t->pre,
                                               nn[i], e);
                zero &= !lit && e[0] == 0.0f && e[1] == 0.0f && e[2] == 0.0f;
            }
            float a[3], b[3];
            hl_ref_dyn_irr_ambient(t->sh, nn[i], a);
            hl_light_split_ambient(s, nn[i], b);
            for (int c = 0; c < 3 && i < 3; c++) amb_nan &= isnan(a[c]) && isnan(b[c]);
        }
        HL_CHECK(zero, "twin at NaN and Inf normals: E must be 0 and unlit");
        HL_CHECK(amb_nan, "twin at NaN normals: ambient must be NaN, as hl_light_split_ambient's");
        hl_dyn_irr_destroy(m);
        hl_light_split_destroy(s);
    }
    hl_env_destroy(env);
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

/* ---------------------------------------------------------------- timing */

static double median(double *v, int n)
{
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j] < v[j - 1]; j--) {
            double t = v[j]; v[j] = v[j - 1]; v[j - 1] = t;
        }
    return v[n / 2];
}

/* Milliseconds between a and b. */
static double ms_of(struct timespec a, struct timespec b)
{
    return (double)(b.tv_sec - a.tv_sec) * 1e3 + (double)(b.tv_nsec - a.tv_nsec) * 1e-6;
}

/* Median of reps runs of the module on ctx: wall and process CPU time
 * (all threads, PoCL's included) in ms. The machine may be shared, so the
 * CPU time tells the work done where the wall time tells the wait. */
static void time_module(hl_context *ctx, const hl_light_split *s, const float *nv, uint32_t N, float *E, float *amb,
                        uint8_t *any, int reps, double *wall, double *cpu, double *kern)
{
    hl_dyn_irr *m = NULL;
    *wall = *cpu = *kern = -1.0;
    if (hl_dyn_irr_create(ctx, s, &m) != HL_OK) { printf("%s\n", hl_context_last_error(ctx)); return; }
    double tw[16], tc[16], tk[16];
    hl_dyn_irr_run(m, nv, N, E, amb, any); /* warm: buffers made */
    for (int r = 0; r < reps; r++) {
        struct timespec a, b, ca, cb;
        clock_gettime(CLOCK_MONOTONIC, &a);
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ca);
        hl_dyn_irr_run(m, nv, N, E, amb, any);
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &cb);
        clock_gettime(CLOCK_MONOTONIC, &b);
        tw[r] = ms_of(a, b);
        tc[r] = ms_of(ca, cb);
        hl_dyn_irr_times(m, &tk[r], NULL);
        tk[r] *= 1e3;
    }
    hl_dyn_irr_destroy(m);
    *wall = median(tw, reps);
    *cpu = median(tc, reps);
    *kern = median(tk, reps);
}

/* N normals: the mesh's at path, evenly subsampled (or repeated), or
 * random unit ones where path is NULL; NULL on failure. */
static float *timing_normals(hl_context *ctx, const char *path, uint32_t N)
{
    float *nv = malloc((size_t)N * 12);
    if (!path) {
        for (uint32_t v = 0; v < N; v++) random_unit(nv + 3 * v);
        return nv;
    }
    hl_mesh *mesh = NULL;
    hl_mesh_stats ms;
    if (hl_mesh_load(ctx, path, NULL, &mesh, &ms) != HL_OK) {
        fprintf(stderr, "%s\n", hl_context_last_error(ctx));
        free(nv);
        return NULL;
    }
    for (uint32_t v = 0; v < N; v++)
        memcpy(nv + 3 * v, mesh->normals + 3 * ((uint64_t)v * mesh->vertex_count / N), 12);
    printf("normals of %s (%u vertices)\n", path, mesh->vertex_count);
    hl_mesh_destroy(mesh);
    return nv;
}

static void run_timing(uint32_t N, int32_t K, const char *mesh)
{
    hl_context *ref = hl_test_ref_context(0), *ctx = hl_test_cl_context(0);
    hl_env *env = load_map(ref, "city");
    hl_light_split *s = env ? make_split(ref, env, HL_SPLIT_OF_LIGHT, 0, K) : NULL;
    if (!s) return;
    float *nv = timing_normals(ref, mesh, N), *E = malloc((size_t)s->count * N * 12), *amb = malloc((size_t)N * 12);
    uint8_t any[HL_LIGHTS_MAX_FACE * 6];
    if (!nv) exit(1);
    enum { REPS = 9 };
    double host[REPS], host_cpu[REPS], w, c, kt;
    for (int r = 0; r < REPS; r++) { /* dyn_frame.c's irradiance(): one thread */
        struct timespec a, b, ca, cb;
        clock_gettime(CLOCK_MONOTONIC, &a);
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ca);
        for (uint32_t v = 0; v < N; v++) hl_light_split_ambient(s, nv + 3 * v, amb + 3 * v);
        for (uint32_t k = 0; k < s->count; k++)
            for (uint32_t v = 0; v < N; v++) hl_area_light_irradiance(s, k, nv + 3 * v, E + 3 * ((size_t)k * N + v));
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cb);
        clock_gettime(CLOCK_MONOTONIC, &b);
        host[r] = ms_of(a, b);
        host_cpu[r] = ms_of(ca, cb);
    }
    uint64_t straddle = 0;
    for (uint32_t k = 0; k < s->count; k++)
        for (uint32_t v = 0; v < N; v++) {
            const float *n = nv + 3 * v, *d = s->lights[k].dir;
            straddle += fabsf(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) < sinf(s->lights[k].extent);
        }
    printf("city.exr, %u lights, %u %s normals (%.1f%% of pairs across a horizon); medians of %d runs\n", s->count,
           N, mesh ? "mesh" : "random unit", 100.0 * (double)straddle / ((double)N * s->count), REPS);
    printf("host loop (area_lights.c, 1 thread):            wall %8.2f ms, CPU %8.2f ms\n", median(host, REPS),
           median(host_cpu, REPS));
    time_module(ref, s, nv, N, E, amb, any, REPS, &w, &c, &kt);
    printf("module, reference backend (%d threads):          wall %8.2f ms, CPU %8.2f ms (twins %.2f ms)\n",
           hl_context_threads(ref), w, c, kt);
    if (ctx) {
        time_module(ctx, s, nv, N, E, amb, any, REPS, &w, &c, &kt);
        printf("module, OpenCL, transfers included:              wall %8.2f ms, CPU %8.2f ms (kernels %.2f ms)\n", w,
               c, kt);
    }
    free(nv); free(E); free(amb);
    hl_light_split_destroy(s);
    hl_env_destroy(env);
    hl_context_destroy(ctx);
    hl_context_destroy(ref);
}

int main(int argc, char **argv)
{
    if (argc >= 2 && strcmp(argv[1], "timing") == 0) {
        char *end1 = NULL, *end2 = NULL;
        long N = argc > 2 ? strtol(argv[2], &end1, 10) : 11000, K = argc > 3 ? strtol(argv[3], &end2, 10) : 32;
        if (N < 1 || N > 10000000 || K < 1 || K > 1000 || (end1 && *end1) || (end2 && *end2) || argc > 5) {
            fprintf(stderr, "usage: %s timing [N (1..10^7, default 11000) [K (1..1000, default 32) [MESH]]]\n"
                    "  N normals (random unit ones, or MESH's evenly subsampled) x K lights of city.exr\n", argv[0]);
            return 2;
        }
        run_timing((uint32_t)N, (int32_t)K, argc > 4 ? argv[4] : NULL);
        return hl_test_skipped ? HL_TEST_SKIP : 0;
    }
    static const hl_test_case cases[] = {
        {"twin", case_twin}, {"exact", case_exact}, {"bad_input", case_bad_input}, {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
