/* stiff_reference.h - the float64 references and error bounds of the
 * stiff-input tests (tests/stiff; the bounds are derived in
 * tests/stiff/test_stiff_light.c's opening comment): geometries per N, the
 * double Haar transform, the lighting as the plain-C stages make it,
 * quantisation errors, per-vertex samples and their bounds, environments,
 * and stiff_main, which runs one case or all and frees what they shared.
 * Depends on: stiff_scene.h.
 */
#ifndef HL_TEST_STIFF_REFERENCE_H
#define HL_TEST_STIFF_REFERENCE_H

/* ---------------------------------------------------------------- references */

static inline uint32_t log2_of(uint32_t N)
{
    uint32_t l = 0;
    while ((1u << l) < N) l++;
    return l;
}

/* Slot order and solid angles depend on N only: one small-C geometry per N. */
static hl_geom *geom_cache[9];

static inline const hl_geom *geom_of(uint32_t N)
{
    const uint32_t l = log2_of(N);
    if (!geom_cache[l] && hl_geom_create(ref_ctx(), N, 4, &geom_cache[l]) != HL_OK) {
        fprintf(stderr, "geometry N=%u: %s\n", N, hl_context_last_error(ref_ctx()));
        exit(1);
    }
    return geom_cache[l];
}

/* The orthonormal non-standard Haar transform from its definition, in
 * double: the coefficient at Mallat position (row, col) of a map is 1 / w
 * times the signed sum of the texels of its w x w support. The scaling
 * coefficient (0, 0) adds them all; a detail at level h (the power of two
 * with h <= max(row, col) < 2h) subtracts the right half of its support
 * when col >= h, the bottom half when row >= h, and so the top-right and
 * bottom-left quarters when both (docs/CONVENTIONS.md: (a-b+c-d)/2, (a+b-c-d)/2 and
 * (a-b-c+d)/2 at (i, j+h), (i+h, j), (i+h, j+h), applied level by level). */
static inline void haar_double(const hl_geom *g, const float *in, double *out)
{
    const uint32_t N = g->N;
    for (int map = 0; map < 2; map++) {
        const float *x = in + (size_t)map * N * N;
        for (uint32_t row = 0; row < N; row++)
            for (uint32_t col = 0; col < N; col++) {
                uint32_t r0, c0, w, m = row > col ? row : col, h = 1;
                hl_geom_support(N, row, col, &r0, &c0, &w);
                while (2 * h <= m) h *= 2;
                const int by_col = m > 0 && col >= h, by_row = m > 0 && row >= h;
                double sum = 0.0;
                for (uint32_t r = r0; r < r0 + w; r++)
                    for (uint32_t c = c0; c < c0 + w; c++) {
                        int neg = (by_col && c >= c0 + w / 2) ^ (by_row && r >= r0 + w / 2);
                        sum += neg ? -(double)x[(size_t)r * N + c] : (double)x[(size_t)r * N + c];
                    }
                out[hl_geom_slot(g, map, row, col)] = sum / w;
            }
    }
}

/* The lighting as the plain-C stages make it (rotation 0): paraboloid
 * texels Lp, their float Haar Lw, and the double Haar Ld; 3 planes each. */
typedef struct lighting {
    uint32_t N, nc;
    float *Lp, *Lw;
    double *Ld;
    double norm[3]; /* |Lp|_2 per channel */
} lighting;

static inline void lighting_make(lighting *L, const hl_light_geom *lg, const hl_env *env)
{
    const hl_geom *g = geom_of(lg->N);
    const size_t nc = g->ncoef;
    L->N = g->N;
    L->nc = g->ncoef;
    L->Lp = need(malloc(nc * 12));
    L->Lw = need(malloc(nc * 12));
    L->Ld = need(malloc(nc * 3 * sizeof(double)));
    float *cells = NULL, *tmp = need(malloc(nc * 4));
    if (hl_env_to_cells(ref_ctx(), env, lg->wc, lg->hc, &cells) != HL_OK) {
        fprintf(stderr, "cells: %s\n", hl_context_last_error(ref_ctx()));
        exit(1);
    }
    hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, 0, 0.0f, g->ncoef, L->Lp);
    for (int c = 0; c < 3; c++) {
        memcpy(tmp, L->Lp + c * nc, nc * 4);
        hl_ref_haar(g, tmp, L->Lw + c * nc);
        haar_double(g, L->Lp + c * nc, L->Ld + c * nc);
        double s = 0.0;
        for (size_t j = 0; j < nc; j++) s += (double)L->Lp[c * nc + j] * L->Lp[c * nc + j];
        L->norm[c] = sqrt(s);
    }
    hl_free_big(cells);
    free(tmp);
}

static inline void lighting_free(lighting *L)
{
    free(L->Lp);
    free(L->Lw);
    free(L->Ld);
}

/* The lighting's energy over the sphere, sum_j L_j Omega_j (channel c). */
static inline double lighting_energy(const lighting *L, int c)
{
    const hl_geom *g = geom_of(L->N);
    double e = 0.0;
    for (uint32_t j = 0; j < L->nc; j++) e += (double)L->Lp[(size_t)c * L->nc + j] * g->omega[j];
    return e;
}

/* Worst error of one stored value against the unquantised one. linear8:
 * half a step (b - a) / 255, plus the float rounding of the decode (four
 * operations on values up to max(|a|, |b|)) and of the encode's x + 0.5.
 * log8: the key is on a grid of step keys from bits(a), rounded to the
 * nearest (step / 2 + 1 keys) or capped at the last point (at most 126
 * keys below bits(b)); a key is at most 2^-23 of the value. sqrt8: s =
 * sqrt(m / b) is rounded to a 127th, so |m - b s'^2| <= b (2 s + 1/254)
 * / 254, plus the float rounding of the thresholds and the decode (a few
 * units in the last place of b). A value not stored (0) is off by itself. */
static inline double quant_error(uint32_t scheme, hl_row_quant q, float raw, float stored)
{
    if (stored == 0.0f) return fabs((double)raw);
    if (scheme == HL_QUANT_LOG8) {
        double keys = hl_log8_step(q.a, q.b) / 2.0 + 127.0;
        return fmax(fabs((double)raw), fabs((double)stored)) * keys * ldexp(1.0, -23);
    }
    if (scheme == HL_QUANT_SQRT8) {
        double sq = sqrt(fabs((double)raw) / q.b);
        return q.b * (2.0 * sq + 1.0 / 254.0) / 254.0 + 8.0 * U_F32 * q.b;
    }
    return ((double)q.b - q.a) / 510.0 * (1.0 + 1e-4) + 4.0 * U_F32 * fmax(fabs((double)q.a), fabs((double)q.b));
}

/* Per vertex and channel: the double references and the sizes the bounds
 * need (albedo not included). */
typedef struct sample {
    double ref;     /* sum T_i Ld_i */
    double ref_f;   /* sum T_i Lw_i: the library's own float lighting */
    double ref_raw; /* sum raw_i Ld_i: the unquantised transport */
    double abs_sum; /* sum |T_i Lw_i| */
    double quant;   /* sum |Ld_i| q_i */
    double t1, t2;  /* |T|_1, |T|_2 */
    uint32_t n;     /* stored terms */
} sample;

static inline sample *samples_make(const hl_transport *t, const lighting *L, const float *raw)
{
    const uint32_t V = t->info.vertex_count, nc = L->nc;
    sample *S = calloc((size_t)V * 3, sizeof *S);
    float *row = need(malloc((size_t)nc * 4)), *code = need(malloc((size_t)nc * 4));
    if (!S) exit(1);
    for (uint32_t v = 0; v < V; v++) {
        hl_transport_query_terms(t, v, row);
        hl_transport_query_row(t, v, code);
        double t1 = 0.0, t2 = 0.0;
        uint32_t n = 0;
        for (uint32_t i = 0; i < nc; i++)
            if (row[i] != 0.0f) {
                t1 += fabs((double)row[i]);
                t2 += (double)row[i] * row[i];
                n++;
            }
        for (int c = 0; c < 3; c++) {
            sample *s = S + 3 * (size_t)v + c;
            const float *lw = L->Lw + (size_t)c * nc;
            const double *ld = L->Ld + (size_t)c * nc;
            s->t1 = t1;
            s->t2 = sqrt(t2);
            s->n = n;
            for (uint32_t i = 0; i < nc; i++) {
                if (row[i] != 0.0f) {
                    s->ref += (double)row[i] * ld[i];
                    s->ref_f += (double)row[i] * lw[i];
                    s->abs_sum += fabs((double)row[i] * lw[i]);
                }
                if (raw) {
                    float x = raw[(size_t)v * nc + i];
                    s->ref_raw += (double)x * ld[i];
                    s->quant += fabs(ld[i]) * (quant_error(t->info.quant, t->row_quant[v], x, code[i]) +
                                                fabs((double)code[i] - row[i]));
                }
            }
        }
    }
    free(row);
    free(code);
    return S;
}

static inline double gamma_n(uint32_t n) { return n * U_F32 / (1.0 - n * U_F32); }

/* Bound (b): accumulation and albedo product, subnormal floor included. */
static inline double bound_accumulation(const sample *s, double albedo, float B)
{
    return albedo * (gamma_n(s->n) * s->abs_sum + 2.0 * s->n * SUB_HALF) + U_F32 * fabs((double)B) + SUB_HALF;
}

/* Bound (a): the float Haar transform of the lighting. */
static inline double bound_haar(const sample *s, double albedo, double lnorm, uint32_t N)
{
    const double levels = log2_of(N);
    return albedo * (s->t2 * 6.0 * U_F32 * levels * lnorm * (1.0 + 1e-4) + s->t1 * 6.0 * levels * SUB_HALF);
}

/* Checks colours against B_ref (and against the unquantised transport
 * when samples carry it). Prints the worst error with the bound at that
 * point; the check is the worst ratio of error to bound. */
static inline void check_colours(const char *what, const hl_transport *t, const lighting *L, const sample *S,
                          const float *rgb, int with_raw)
{
    const uint32_t V = t->info.vertex_count;
    double worst[3] = {0, 0, 0}, err_at[3] = {0, 0, 0}, bound_at[3] = {0, 0, 0}, worst_rel = 0.0, rel_ref = 0.0;
    uint32_t rel_v = 0;
    for (uint32_t v = 0; v < V; v++)
        for (int c = 0; c < 3; c++) {
            const sample *s = S + 3 * (size_t)v + c;
            const double a = t->mesh->albedo[3 * (size_t)v + c];
            const float B = rgb[3 * (size_t)v + c];
            const double acc = bound_accumulation(s, a, B), haar = bound_haar(s, a, L->norm[c], L->N);
            const double e[3] = {fabs(B - a * s->ref_f), fabs(B - a * s->ref), fabs(B - a * s->ref_raw)};
            const double bd[3] = {acc, acc + haar, acc + haar + a * s->quant};
            for (int k = 0; k < (with_raw ? 3 : 2); k++) {
                double ratio = e[k] / bd[k];
                if (!(ratio <= worst[k])) {
                    worst[k] = ratio;
                    err_at[k] = e[k];
                    bound_at[k] = bd[k];
                }
            }
            if (fabs(s->ref) > 0 && e[1] / fabs(a * s->ref) > worst_rel) {
                worst_rel = e[1] / fabs(a * s->ref);
                rel_ref = a * s->ref;
                rel_v = v;
            }
        }
    static const char *const kind[3] = {
        "vs its own float lighting in double (accumulation)",
        "vs B_ref (lighting Haar + accumulation)",
        "vs the unquantised transport (+ 8-bit quantisation)"};
    for (int k = 0; k < (with_raw ? 3 : 2); k++) {
        char w[400];
        printf("%s %s: worst error %.4g where the bound is %.4g\n", what, kind[k], err_at[k], bound_at[k]);
        snprintf(w, sizeof w, "%s %s, error / bound", what, kind[k]);
        hl_check_error(w, worst[k], 1.0);
    }
    printf("%s: largest relative error %.3g (vertex %u, B_ref %.4g)\n", what, worst_rel, rel_v, rel_ref);
}

/* Unquantised, untruncated rows of every vertex (V x 2N^2), recomputed from
 * the rays by the plain-C stages exactly as the precompute computes them. */
static inline float *raw_rows(const hl_transport *t)
{
    const hl_transport_info *in = &t->info;
    hl_geom *g = NULL;
    hl_rt *rt = NULL;
    if (hl_geom_create(ref_ctx(), in->N, in->C, &g) != HL_OK || hl_rt_create(ref_ctx(), t->mesh, &rt) != HL_OK) {
        fprintf(stderr, "raw rows: %s\n", hl_context_last_error(ref_ctx()));
        exit(1);
    }
    const uint32_t V = in->vertex_count, nc = g->ncoef;
    uint8_t *vis = need(malloc((size_t)V * g->ncube));
    float *out = need(malloc((size_t)V * nc * 4)), *T = need(malloc((size_t)nc * 4));
    const float off = in->ray_offset * hl_mesh_query_diagonal(t->mesh);
    const float scale = (float)(1.0 / (HL_PI * in->supersample * in->supersample));
    HL_CHECK(hl_rt_visibility(rt, g, t->mesh, 0, V, in->supersample, off, vis, NULL) == HL_OK, "rays");
    for (uint32_t v = 0; v < V; v++) {
        hl_ref_cube2para(g, vis + (size_t)v * g->ncube, scale, t->mesh->normals + 3 * (size_t)v, T);
        hl_ref_haar(g, T, out + (size_t)v * nc);
    }
    free(vis);
    free(T);
    hl_rt_destroy(rt);
    hl_geom_destroy(g);
    return out;
}

/* The references for one lighting of a rig's transport. */
typedef struct reference {
    lighting L;
    sample *S;
} reference;

static inline void reference_make(reference *R, const rig *g, const hl_env *env, const float *raw)
{
    lighting_make(&R->L, hl_relighter_tables(g->r[1]), env);
    R->S = samples_make(g->t[1], &R->L, raw);
}

static inline void reference_free(reference *R)
{
    free(R->S);
    lighting_free(&R->L);
}

/* check_colours for both backends. */
static inline void check_both(const char *what, const rig *g, const reference *R, int with_raw)
{
    for (int b = 0; b < 2; b++) {
        char w[256];
        snprintf(w, sizeof w, "%s, %s", what, backend_name[b]);
        check_colours(w, g->t[b], &R->L, R->S, g->rgb[b], with_raw);
    }
}

/* The small scene precomputed on both backends (N, C, truncation rule,
 * the rest default) and opened on both; NULL when that fails (and then
 * nothing is held). */
static inline hl_mesh *open_scene(rig *g, uint32_t N, uint32_t C, uint32_t rule, const char *name)
{
    hl_precompute_desc d = {.N = N, .C = C, .rule = rule};
    hl_mesh *m = scene_mesh(1.0, no_shift);
    if (rig_open(g, precompute_both(m, &d, name))) return m;
    hl_mesh_destroy(m);
    return NULL;
}

static inline void close_scene(rig *g, hl_mesh *m)
{
    rig_close(g);
    hl_mesh_destroy(m);
}

/* ---------------------------------------------------------------- environments */

static inline hl_env *env_of(uint32_t W, const float *px)
{
    hl_env *e = NULL;
    hl_env_stats st;
    hl_result r = hl_env_create(ref_ctx(), W, W / 2, px, &e, &st);
    HL_CHECK(r == HL_OK, "environment %ux%u: %s", W, W / 2, hl_context_last_error(ref_ctx()));
    return e;
}

static inline float *pixels_const(uint32_t W, float value)
{
    size_t n = (size_t)W * (W / 2) * 3;
    float *px = need(malloc(n * 4));
    for (size_t i = 0; i < n; i++) px[i] = value;
    return px;
}

/* A light smaller than a texel keeps its energy: each cell's parts are
 * exact radially and within the 16-ray quadrature in longitude, 0.2% at
 * worst (lighting.c); 0.5% leaves room and no room for the 6.5% that
 * point-sampled parts lost near the horizon. */
#define ENERGY_TOL 0.005

static inline double rng_unit(void) { return (double)(hl_rng_next() >> 11) * (1.0 / 9007199254740992.0); }

/* Solid angle of pixel row y of an equirectangular map W x W/2. */
static inline double pixel_omega(uint32_t W, uint32_t y)
{
    const uint32_t H = W / 2;
    return 2.0 * HL_PI / W * (cos(HL_PI * y / H) - cos(HL_PI * (y + 1) / H));
}


/* ---------------------------------------------------------------- main */

static inline void cleanup(void)
{
    for (int b = 0; b < 2; b++) hl_context_destroy(contexts[b]);
    for (int l = 0; l < 9; l++) hl_geom_destroy(geom_cache[l]);
}

/* Runs the case named argv[1], or all of them in turn with "all". */
static inline int stiff_main(int argc, char **argv, const hl_test_case *stiff_cases)
{
    int rc;
    if (argc >= 2 && strcmp(argv[1], "all") == 0) {
        for (const hl_test_case *c = stiff_cases; c->name; c++) c->fn();
        rc = hl_test_failures ? 1 : 0;
    } else {
        rc = hl_test_main(argc, argv, stiff_cases);
    }
    if (cases_run)
        printf("stiff%s%s: %d cases, %s\n", argc >= 2 ? " " : "", argc >= 2 ? argv[1] : "", cases_run,
               cases_failed ? "some FAILED" : "all passed");
    if (cases_failed) printf("stiff: %d of %d cases failed\n", cases_failed, cases_run);
    cleanup();
    return rc;
}

#endif
