/* maths_util.h - helpers shared by the closed-form tests (tests/maps,
 * tests/analytic, tests/visibility): a random generator over hl_rng_next,
 * allocation that exits, a geometry maker, vector helpers, the Haar
 * transform of a kept input and an inverse written from the step formulas,
 * unit lighting, the form factor of a spherical polygon, and B of a
 * visibility row through the plain-C stages.
 * Depends on: hl_test.h, twins.h (the plain-C stages), geom.h.
 */
#ifndef HL_TEST_MATHS_UTIL_H
#define HL_TEST_MATHS_UTIL_H

#define PI 3.14159265358979323846

/* ---------------------------------------------------------------- helpers */

static inline uint64_t rng_next(void) { return hl_rng_next(); }
static inline double rng_unit(void) { return (double)(rng_next() >> 11) * (1.0 / 9007199254740992.0); }
static inline float rng_float(double lo, double hi) { return (float)(lo + (hi - lo) * rng_unit()); }

static inline void *xmalloc(size_t n)
{
    void *p = malloc(n ? n : 1);
    if (!p) {
        fprintf(stderr, "out of memory (%zu bytes)\n", n);
        exit(1);
    }
    return p;
}
static inline void *xcalloc(size_t n, size_t s)
{
    void *p = calloc(n ? n : 1, s ? s : 1);
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    return p;
}

static inline hl_context *make_ctx(void) { return hl_test_ref_context(0); }

static inline hl_geom *make_geom(hl_context *ctx, uint32_t N, uint32_t C)
{
    hl_geom *g = NULL;
    if (hl_geom_create(ctx, N, C, &g) != HL_OK) {
        fprintf(stderr, "hl_geom_create(N=%u, C=%u): %s\n", N, C, hl_context_last_error(ctx));
        exit(1);
    }
    return g;
}

static inline uint32_t ilog2u(uint32_t n)
{
    uint32_t l = 0;
    while ((1u << l) < n) l++;
    return l;
}

static inline double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline double norm3(const double a[3]) { return sqrt(dot3(a, a)); }

/* Forward transform of in (kept) through hl_ref_haar (which destroys its input). */
static inline void haar_of(const hl_geom *g, const float *in, float *coef)
{
    float *T = xmalloc((size_t)g->ncoef * sizeof *T);
    memcpy(T, in, (size_t)g->ncoef * sizeof *T);
    hl_ref_haar(g, T, coef);
    free(T);
}

/* Inverse of the step of docs/CONVENTIONS.md, written from the formulas and
 * not from haar_ref.c: avg = (a+b+c+d)/2, H = (a-b+c-d)/2 at Mallat (i, j+h),
 * V = (a+b-c-d)/2 at (i+h, j), D = (a-b-c+d)/2 at (i+h, j+h), where a, b, c,
 * d are (2i,2j), (2i,2j+1), (2i+1,2j), (2i+1,2j+1). Solving the 4x4 system
 * (it is its own inverse): a = (avg+H+V+D)/2, b = (avg-H+V-D)/2,
 * c = (avg+H-V-D)/2, d = (avg-H-V+D)/2. In double, so only the forward
 * transform's float rounding shows. x: both maps, row-major, stride N. */
static inline void inverse_haar(const hl_geom *g, const float *coef, double *x)
{
    const uint32_t N = g->N;
    double *avg = xmalloc((size_t)N * N * sizeof *avg), *next = xmalloc((size_t)N * N * sizeof *next);
    for (int m = 0; m < 2; m++) {
        avg[0] = coef[hl_geom_slot(g, m, 0, 0)];
        for (uint32_t h = 1; h < N; h *= 2) {
            for (uint32_t i = 0; i < h; i++)
                for (uint32_t j = 0; j < h; j++) {
                    double A = avg[i * N + j];
                    double H = coef[hl_geom_slot(g, m, i, j + h)];
                    double V = coef[hl_geom_slot(g, m, i + h, j)];
                    double D = coef[hl_geom_slot(g, m, i + h, j + h)];
                    next[(2 * i) * N + 2 * j] = (A + H + V + D) * 0.5;
                    next[(2 * i) * N + 2 * j + 1] = (A - H + V - D) * 0.5;
                    next[(2 * i + 1) * N + 2 * j] = (A + H - V - D) * 0.5;
                    next[(2 * i + 1) * N + 2 * j + 1] = (A - H - V + D) * 0.5;
                }
            double *s = avg;
            avg = next;
            next = s;
        }
        memcpy(x + (size_t)m * N * N, avg, (size_t)N * N * sizeof *x);
    }
    free(avg);
    free(next);
}

static inline double dot_ff(const float *a, const float *b, size_t n)
{
    double s = 0.0;
    for (size_t i = 0; i < n; i++) s += (double)a[i] * (double)b[i];
    return s;
}


/* L = 1 on every texel with a solid angle (texels outside the disc are 0). */
static inline void unit_light(const hl_geom *g, float *L)
{
    for (uint32_t j = 0; j < g->ncoef; j++) L[j] = g->omega[j] > 0.0f ? 1.0f : 0.0f;
}

static inline void normalize3(double v[3])
{
    double l = norm3(v);
    for (int q = 0; q < 3; q++) v[q] /= l;
}


/* Form factor of a spherical polygon (Lambert): the occluded cosine-weighted
 * solid angle over pi, seen from o with normal n, of the closed polygon P
 * (K vertices): (1 / 2 pi) sum_i Theta_i (n . Gamma_i), Theta_i the angle
 * between successive vertex directions, Gamma_i the unit normal of their
 * great circle. Exact for a polygon wholly above the horizon. */
static inline double polygon_form_factor(const double *P, int K, const double o[3], const double n[3])
{
    double sum = 0.0;
    for (int i = 0; i < K; i++) {
        const double *a = P + 3 * i, *b = P + 3 * ((i + 1) % K);
        double u[3] = {a[0] - o[0], a[1] - o[1], a[2] - o[2]}, v[3] = {b[0] - o[0], b[1] - o[1], b[2] - o[2]};
        normalize3(u);
        normalize3(v);
        double x[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double len = norm3(x);
        if (len == 0.0) continue;
        sum += atan2(len, dot3(u, v)) * dot3(n, x) / len;
    }
    return fabs(sum) / (2.0 * PI);
}

/* B of a visibility row through the plain-C stages: cube2para (scale
 * 1 / (pi S^2)), then the dot product with WL in the Haar domain; *direct
 * gets sum_j T_j L_j, coef_out (may be NULL) the coefficients. */
static inline double stages_B(const hl_geom *g, const uint8_t *vis, uint32_t S, const float n[3], const float *L,
                       const float *WL, double *direct, float *coef_out)
{
    float *T = xmalloc((size_t)g->ncoef * sizeof *T), *coef = xmalloc((size_t)g->ncoef * sizeof *coef);
    hl_ref_cube2para(g, vis, (float)(1.0 / (PI * S * S)), n, T);
    *direct = dot_ff(T, L, g->ncoef);
    hl_ref_haar(g, T, coef);
    double B = dot_ff(coef, WL, g->ncoef);
    if (coef_out) memcpy(coef_out, coef, (size_t)g->ncoef * sizeof *coef);
    free(T);
    free(coef);
    return B;
}

#endif
