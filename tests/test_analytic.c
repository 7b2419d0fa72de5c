/* test_analytic.c - the maths of docs/CONVENTIONS.md against closed forms
 * (suites "haar", "geom", "analytic").
 *
 * haar.roundtrip   hl_ref_haar then an inverse written here from the step
 *                  formulas (double, level by level through hl_geom_slot).
 * haar.parseval    dot products and norms survive the transform.
 * haar.slots       the slot order is a permutation; 256-blocks are spatial
 *                  16x16 tiles plus one coarse coefficient (delta images).
 * geom.solid_angle texel solid angles sum to 4 pi; interior texels against
 *                  a Simpson double integral, rim texels against an
 *                  independent polar-coordinate integral.
 * geom.mapping     paraboloid and cube texel centres round-trip; the cube
 *                  faces follow the OpenGL table (re-derived here).
 * geom.table       the cube-to-paraboloid table's first moments.
 * analytic.furnace unoccluded vertex, L = 1: B = 1, directly, from the table
 *                  in double, and through the Haar domain.
 * analytic.cap     spherical cap occluder: B = cos^2(alpha), end to end
 *                  through Embree, hl_precompute and the transport file,
 *                  and with analytic visibility through the plain-C stages.
 * analytic.ray_offset  a thin slab, a contact and a crease closer to the
 *                  receiver than 1e-3 of the diagonal: the robust default
 *                  offset against Lambert's exact B at three scales (the
 *                  old default must fail there), and no acne on planes and
 *                  boxes far from the origin, turned or not.
 *
 * Every check prints its tolerance and worst error (hl_check_error).
 * Depends on: haarlight_core (reference backend only; no OpenCL device).
 */
#define _POSIX_C_SOURCE 200809L
#include <float.h>
#include <stdint.h>
#include <unistd.h>

#include "hl_test.h"
#include "rays.h"
#include "twins.h"

#define PI 3.14159265358979323846

/* ---------------------------------------------------------------- helpers */

static uint64_t rng_next(void) { return hl_rng_next(); }
static double rng_unit(void) { return (double)(rng_next() >> 11) * (1.0 / 9007199254740992.0); }
static float rng_float(double lo, double hi) { return (float)(lo + (hi - lo) * rng_unit()); }

static void *xmalloc(size_t n)
{
    void *p = malloc(n ? n : 1);
    if (!p) {
        fprintf(stderr, "out of memory (%zu bytes)\n", n);
        exit(1);
    }
    return p;
}
static void *xcalloc(size_t n, size_t s)
{
    void *p = calloc(n ? n : 1, s ? s : 1);
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    return p;
}

static hl_context *make_ctx(void) { return hl_test_ref_context(0); }

static hl_geom *make_geom(hl_context *ctx, uint32_t N, uint32_t C)
{
    hl_geom *g = NULL;
    if (hl_geom_create(ctx, N, C, &g) != HL_OK) {
        fprintf(stderr, "hl_geom_create(N=%u, C=%u): %s\n", N, C, hl_context_last_error(ctx));
        exit(1);
    }
    return g;
}

static uint32_t ilog2u(uint32_t n)
{
    uint32_t l = 0;
    while ((1u << l) < n) l++;
    return l;
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static double norm3(const double a[3]) { return sqrt(dot3(a, a)); }

/* Forward transform of in (kept) through hl_ref_haar (which destroys its input). */
static void haar_of(const hl_geom *g, const float *in, float *coef)
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
static void inverse_haar(const hl_geom *g, const float *coef, double *x)
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

static double dot_ff(const float *a, const float *b, size_t n)
{
    double s = 0.0;
    for (size_t i = 0; i < n; i++) s += (double)a[i] * (double)b[i];
    return s;
}

/* ================================================================ haar */

static void case_roundtrip(void)
{
    hl_context *ctx = make_ctx();
    static const uint32_t Ns[] = {8, 16, 64, 256};
    for (size_t k = 0; k < sizeof Ns / sizeof Ns[0]; k++) {
        uint32_t N = Ns[k];
        hl_geom *g = make_geom(ctx, N, 4);
        float *x = xmalloc((size_t)g->ncoef * sizeof *x), *coef = xmalloc((size_t)g->ncoef * sizeof *coef);
        double *y = xmalloc((size_t)g->ncoef * sizeof *y);
        /* Random data everywhere, outside the disc too, with a positive
         * offset so the averages grow by 2 per level (the harder case for
         * rounding). */
        double xmax = 0.0;
        for (uint32_t i = 0; i < g->ncoef; i++) {
            x[i] = rng_float(-0.5, 1.5);
            xmax = fmax(xmax, fabs((double)x[i]));
        }
        for (uint32_t i = 0; i < g->ncoef; i++) coef[i] = NAN; /* every slot must be written */
        haar_of(g, x, coef);
        inverse_haar(g, coef, y);
        double worst = 0.0;
        for (uint32_t i = 0; i < g->ncoef; i++) {
            double e = fabs(y[i] - (double)x[i]);
            if (!(e <= worst)) worst = e; /* NaN (an unwritten slot) sticks */
        }
        /* Each level rounds three float additions and a halving; the
         * inverse (exact in double) carries each level's error down at the
         * same scale, so the error is a few ulps of max|x| per level. */
        double tol = 4.0 * FLT_EPSILON * ilog2u(N);
        char what[96];
        snprintf(what, sizeof what, "N=%u inverse(haar(x)) - x, relative to max|x|", N);
        hl_check_error(what, worst / xmax, tol);
        free(x);
        free(coef);
        free(y);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

static void case_parseval(void)
{
    hl_context *ctx = make_ctx();
    static const uint32_t Ns[] = {8, 16, 64, 256};
    for (size_t k = 0; k < sizeof Ns / sizeof Ns[0]; k++) {
        uint32_t N = Ns[k];
        hl_geom *g = make_geom(ctx, N, 4);
        size_t n = g->ncoef;
        float *x = xmalloc(n * sizeof *x), *y = xmalloc(n * sizeof *y);
        float *wx = xmalloc(n * sizeof *wx), *wy = xmalloc(n * sizeof *wy);
        double worst_dot = 0.0, worst_norm = 0.0;
        for (int trial = 0; trial < 4; trial++) {
            for (size_t i = 0; i < n; i++) {
                /* trial 0,1: zero-mean; 2,3: positive (transport-like) */
                x[i] = trial < 2 ? rng_float(-1, 1) : rng_float(0, 1);
                y[i] = trial < 2 ? rng_float(-1, 1) : rng_float(0, 2);
            }
            haar_of(g, x, wx);
            haar_of(g, y, wy);
            double nx = sqrt(dot_ff(x, x, n)), ny = sqrt(dot_ff(y, y, n));
            double e = fabs(dot_ff(x, y, n) - dot_ff(wx, wy, n)) / (nx * ny);
            if (!(e <= worst_dot)) worst_dot = e;
            e = fabs(sqrt(dot_ff(wx, wx, n)) - nx) / nx;
            if (!(e <= worst_norm)) worst_norm = e;
        }
        /* Every coefficient is within a few ulps x log2 N of its exact value
         * relative to the vector's scale (see roundtrip), so by
         * Cauchy-Schwarz the dot product is within that times ||x|| ||y||:
         * 4 * 2^-23 * 8 = 3.8e-6 at N = 256; the random-walk sum of the
         * independent roundings sits far lower. 1e-6 (the brief's figure)
         * leaves ample room for that and no room for a wrong coefficient. */
        char what[96];
        snprintf(what, sizeof what, "N=%u |x.y - Wx.Wy| / (|x||y|)", N);
        hl_check_error(what, worst_dot, 1e-6);
        snprintf(what, sizeof what, "N=%u | |Wx| - |x| | / |x|", N);
        hl_check_error(what, worst_norm, 1e-6);
        free(x);
        free(y);
        free(wx);
        free(wy);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

/* A delta at texel (r, c) of map m must give exactly 3 log2 N + 1 non-zero
 * coefficients (three details per level plus the scaling one), each in the
 * 256-block of the 16x16 tile holding (r, c) or in a coarse slot (slot %
 * 256 == 0). Returns the number of violations. */
static long delta_check(const hl_geom *g, int m, uint32_t r, uint32_t c, float *img, float *coef)
{
    const uint32_t N = g->N;
    memset(img, 0, (size_t)g->ncoef * sizeof *img);
    img[(size_t)m * N * N + r * N + c] = 1.0f;
    haar_of(g, img, coef);
    uint32_t expect_block = (uint32_t)m * N * N / HL_BLOCK + (r / 16) * (N / 16) + c / 16;
    long bad = 0;
    uint32_t nz = 0;
    for (uint32_t s = 0; s < g->ncoef; s++) {
        if (coef[s] == 0.0f) continue;
        nz++;
        if (s / HL_BLOCK != expect_block && s % HL_BLOCK != 0) bad++;
    }
    if (nz != 3 * ilog2u(N) + 1) bad++;
    return bad;
}

static void case_slots(void)
{
    hl_context *ctx = make_ctx();
    for (uint32_t N = 8; N <= 256; N *= 2) {
        hl_geom *g = make_geom(ctx, N, 4);
        uint8_t *seen = xcalloc(g->ncoef, 1);
        long bad = 0;
        for (int m = 0; m < 2; m++)
            for (uint32_t r = 0; r < N; r++)
                for (uint32_t c = 0; c < N; c++) {
                    uint32_t s = hl_geom_slot(g, m, r, c);
                    if (s >= g->ncoef || seen[s]++) bad++;
                }
        char what[128];
        snprintf(what, sizeof what, "N=%u slots out of range or repeated (of %u)", N, g->ncoef);
        hl_check_error(what, (double)bad, 0.0);
        free(seen);
        if (N >= 16) {
            /* Coarse coefficients (support larger than a tile): exactly one
             * per block, at the block's slot 0. */
            uint32_t T = N / 16;
            long badc = 0;
            for (int m = 0; m < 2; m++)
                for (uint32_t r = 0; r < N; r++)
                    for (uint32_t c = 0; c < N; c++) {
                        int coarse = r < T && c < T;
                        if (coarse != (hl_geom_slot(g, m, r, c) % HL_BLOCK == 0)) badc++;
                    }
            snprintf(what, sizeof what, "N=%u coarse coefficients not alone at slot 0 of a block", N);
            hl_check_error(what, (double)badc, 0.0);

            /* Delta images: every texel for N <= 64, a sample above (each
             * detail coefficient of a tile is hit by any delta inside its
             * support, so the full sweep covers every slot). */
            float *img = xmalloc((size_t)g->ncoef * sizeof *img), *coef = xmalloc((size_t)g->ncoef * sizeof *coef);
            long badd = 0, tested = 0;
            for (int m = 0; m < 2; m++)
                for (uint32_t r = 0; r < N; r++)
                    for (uint32_t c = 0; c < N; c++) {
                        if (N > 64 && (rng_next() % (N * N / 512)) != 0 && !(r % 16 == 15 && c % 16 == 15))
                            continue;
                        badd += delta_check(g, m, r, c, img, coef);
                        tested++;
                    }
            snprintf(what, sizeof what, "N=%u delta images (%ld) with coefficients outside their tile's block", N,
                     tested);
            hl_check_error(what, (double)badd, 0.0);
            free(img);
            free(coef);
        }
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

/* ================================================================ geom */

static double para_density(double s, double t)
{
    double q = 1.0 + s * s + t * t;
    return 4.0 / (q * q);
}

/* Composite Simpson, n (even) intervals per side, of the density over a
 * rectangle wholly inside the disc. */
static double simpson_rect(double s0, double s1, double t0, double t1, int n)
{
    double hs = (s1 - s0) / n, ht = (t1 - t0) / n, sum = 0.0;
    for (int a = 0; a <= n; a++) {
        double wa = (a == 0 || a == n) ? 1.0 : (a % 2 ? 4.0 : 2.0);
        for (int b = 0; b <= n; b++) {
            double wb = (b == 0 || b == n) ? 1.0 : (b % 2 ? 4.0 : 2.0);
            sum += wa * wb * para_density(s0 + a * hs, t0 + b * ht);
        }
    }
    return sum * hs * ht / 9.0;
}

/* The same solid angle for a rectangle not containing the origin, clipped
 * by the unit disc, in polar coordinates: the radial integral is exact,
 * integral of 4 r / (1 + r^2)^2 dr = [-2 / (1 + r^2)], so only the angle
 * is sampled (midpoint, M samples). Independent of the library's
 * Cartesian strips. */
static double polar_rect(double s0, double s1, double t0, double t1, int M)
{
    double sc = 0.5 * (s0 + s1), tc = 0.5 * (t0 + t1), th_c = atan2(tc, sc);
    double lo = 0.0, hi = 0.0;
    const double cs[4][2] = {{s0, t0}, {s1, t0}, {s0, t1}, {s1, t1}};
    for (int k = 0; k < 4; k++) {
        double d = atan2(sc * cs[k][1] - tc * cs[k][0], sc * cs[k][0] + tc * cs[k][1]);
        lo = fmin(lo, d);
        hi = fmax(hi, d);
    }
    double h = (hi - lo) / M, sum = 0.0;
    for (int k = 0; k < M; k++) {
        double th = th_c + lo + (k + 0.5) * h, c = cos(th), s = sin(th);
        double a = 0.0, b = INFINITY;
        if (fabs(c) > 1e-300) {
            double u = s0 / c, v = s1 / c;
            a = fmax(a, fmin(u, v));
            b = fmin(b, fmax(u, v));
        } else if (!(s0 <= 0.0 && 0.0 <= s1)) continue;
        if (fabs(s) > 1e-300) {
            double u = t0 / s, v = t1 / s;
            a = fmax(a, fmin(u, v));
            b = fmin(b, fmax(u, v));
        } else if (!(t0 <= 0.0 && 0.0 <= t1)) continue;
        b = fmin(b, 1.0);
        if (b > a) sum += 2.0 / (1.0 + a * a) - 2.0 / (1.0 + b * b);
    }
    return sum * h;
}

static void case_solid_angle(void)
{
    hl_context *ctx = make_ctx();
    for (uint32_t N = 8; N <= 256; N *= 2) {
        hl_geom *g = make_geom(ctx, N, 4);
        double sum = 0.0;
        for (uint32_t j = 0; j < g->ncoef; j++) sum += g->omega[j];
        char what[128];
        snprintf(what, sizeof what, "N=%u sum of omega = %.9f vs 4 pi, relative", N, sum);
        hl_check_error(what, fabs(sum - 4.0 * PI) / (4.0 * PI), 1e-4); /* docs/CONVENTIONS.md */

        /* The table stores hl_para_rect_omega per texel (float) and zero
         * for texels wholly outside the disc. */
        double worst_st = 0.0;
        long nonzero_out = 0;
        const double h = 2.0 / N;
        for (int m = 0; m < 2; m++)
            for (uint32_t r = 0; r < N; r++)
                for (uint32_t c = 0; c < N; c++) {
                    double s0 = -1.0 + c * h, t0 = -1.0 + r * h;
                    double ns = fmin(fabs(s0), fabs(s0 + h)), nt = fmin(fabs(t0), fabs(t0 + h));
                    double om = g->omega[(size_t)m * N * N + r * N + c];
                    if (ns * ns + nt * nt >= 1.0 && om != 0.0) nonzero_out++;
                    double e = fabs(om - hl_para_rect_omega(s0, s0 + h, t0, t0 + h));
                    worst_st = fmax(worst_st, e / (h * h));
                }
        snprintf(what, sizeof what, "N=%u texels wholly outside the disc with omega != 0", N);
        hl_check_error(what, (double)nonzero_out, 0.0);
        /* float storage of a double: half an ulp of omega <= h^2 * 4 */
        snprintf(what, sizeof what, "N=%u stored omega vs hl_para_rect_omega, per h^2", N);
        hl_check_error(what, worst_st, 4.0 * FLT_EPSILON);

        /* Interior texels: closed form against Simpson (64 intervals a side;
         * the density is smooth, Simpson's error ~ (h/64)^4 f'''' is below
         * 1e-12 relative). The closed form subtracts F values of order 1, so
         * double rounding costs ~1e-16 / (h^2) relative: 1e-11 at N = 256. */
        double worst_in = 0.0, worst_rim = 0.0;
        int n_in = 0, n_rim = 0;
        for (uint32_t r = 0; r < N; r++)
            for (uint32_t c = 0; c < N; c++) {
                double s0 = -1.0 + c * h, t0 = -1.0 + r * h, s1 = s0 + h, t1 = t0 + h;
                double fs = fmax(fabs(s0), fabs(s1)), ft = fmax(fabs(t0), fabs(t1));
                double ns = fmin(fabs(s0), fabs(s1)), nt = fmin(fabs(t0), fabs(t1));
                int inside = fs * fs + ft * ft <= 1.0, outside = ns * ns + nt * nt >= 1.0;
                if (outside) continue;
                if (inside) {
                    if (N > 16 && rng_next() % (N / 8) != 0) continue; /* sample */
                    double ref = simpson_rect(s0, s1, t0, t1, 64);
                    worst_in = fmax(worst_in, fabs(hl_para_rect_omega(s0, s1, t0, t1) - ref) / ref);
                    n_in++;
                } else {
                    if (N > 64 && rng_next() % 4 != 0) continue;
                    double ref = polar_rect(s0, s1, t0, t1, 20000);
                    worst_rim = fmax(worst_rim, fabs(hl_para_rect_omega(s0, s1, t0, t1) - ref) / (h * h));
                    n_rim++;
                }
            }
        snprintf(what, sizeof what, "N=%u interior texels (%d): closed form vs Simpson, relative", N, n_in);
        hl_check_error(what, worst_in, 1e-9);
        /* Rim texels: the library integrates t exactly and s by a 512-strip
         * midpoint rule; where the circle is tangent to a strip edge the
         * integrand has a square-root kink, so its error is O(strip^1.5)
         * relative to the texel: (1/512)^1.5 = 8.6e-5 at worst; the polar
         * reference (20000 angles, kinks only at corners) is far tighter.
         * Scaled by h^2 (the full texel's weight at the rim is ~h^2), so
         * slivers are judged by the same absolute yardstick. */
        snprintf(what, sizeof what, "N=%u rim texels (%d): library vs polar integral, per h^2", N, n_rim);
        hl_check_error(what, worst_rim, 1e-4);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

/* OpenGL cube-map selection (OpenGL 4.6 table 8.19), re-derived here: major
 * axis, then sc, tc, then s = (sc / |ma| + 1) / 2 and t likewise. */
static uint32_t gl_dir_to_texel(const double d[3], uint32_t C)
{
    double ax = fabs(d[0]), ay = fabs(d[1]), az = fabs(d[2]), sc, tc, ma;
    int face;
    if (ax >= ay && ax >= az) {
        face = d[0] >= 0 ? 0 : 1;
        ma = ax;
        sc = d[0] >= 0 ? -d[2] : d[2];
        tc = -d[1];
    } else if (ay >= az) {
        face = d[1] >= 0 ? 2 : 3;
        ma = ay;
        sc = d[0];
        tc = d[1] >= 0 ? d[2] : -d[2];
    } else {
        face = d[2] >= 0 ? 4 : 5;
        ma = az;
        sc = d[2] >= 0 ? d[0] : -d[0];
        tc = -d[1];
    }
    double s = (sc / ma + 1.0) * 0.5 * C, t = (tc / ma + 1.0) * 0.5 * C;
    uint32_t col = (uint32_t)fmin(fmax(floor(s), 0.0), C - 1.0), row = (uint32_t)fmin(fmax(floor(t), 0.0), C - 1.0);
    return (uint32_t)face * C * C + row * C + col;
}

static void case_mapping(void)
{
    hl_context *ctx = make_ctx();
    char what[128];
    static const uint32_t Ns[] = {8, 16, 64, 256};
    for (size_t k = 0; k < sizeof Ns / sizeof Ns[0]; k++) {
        uint32_t N = Ns[k];
        double worst_len = 0.0, worst_st = 0.0, worst_formula = 0.0;
        long bad_map = 0, count = 0;
        for (int m = 0; m < 2; m++)
            for (uint32_t r = 0; r < N; r++)
                for (uint32_t c = 0; c < N; c++) {
                    double s = -1.0 + (c + 0.5) * 2.0 / N, t = -1.0 + (r + 0.5) * 2.0 / N, r2 = s * s + t * t;
                    if (r2 >= 1.0) continue;
                    count++;
                    float d[3];
                    hl_para_texel_dir(N, m, c, r, d);
                    double dd[3] = {d[0], d[1], d[2]};
                    worst_len = fmax(worst_len, fabs(norm3(dd) - 1.0));
                    /* docs/CONVENTIONS.md: d = (2s, +/-(1 - r^2), 2t) / (1 + r^2) */
                    double ex[3] = {2 * s / (1 + r2), (m ? -1 : 1) * (1 - r2) / (1 + r2), 2 * t / (1 + r2)};
                    for (int q = 0; q < 3; q++) worst_formula = fmax(worst_formula, fabs(dd[q] - ex[q]));
                    int mb;
                    float sb, tb;
                    hl_dir_to_para(d, &mb, &sb, &tb);
                    if (mb != m) bad_map++;
                    worst_st = fmax(worst_st, fmax(fabs(sb - s), fabs(tb - t)));
                }
        /* a float unit vector: a few ulps */
        snprintf(what, sizeof what, "N=%u paraboloid texel directions (%ld): | |d| - 1 |", N, count);
        hl_check_error(what, worst_len, 4.0 * FLT_EPSILON);
        snprintf(what, sizeof what, "N=%u paraboloid direction vs docs/CONVENTIONS.md formula (double)", N);
        hl_check_error(what, worst_formula, 2.0 * FLT_EPSILON);
        snprintf(what, sizeof what, "N=%u directions mapped back to the wrong map", N);
        hl_check_error(what, (double)bad_map, 0.0);
        /* the brief's figure; the float round trip is ~1e-7 */
        snprintf(what, sizeof what, "N=%u hl_dir_to_para(texel dir) - texel centre (s, t)", N);
        hl_check_error(what, worst_st, 1e-5);
    }

    /* Face order +X -X +Y -Y +Z -Z: the face centre directions. */
    static const float axes[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    double worst_face = 0.0;
    for (int f = 0; f < 6; f++) {
        float d[3];
        hl_cube_face_dir(f, 0.0f, 0.0f, d);
        for (int q = 0; q < 3; q++) worst_face = fmax(worst_face, fabs((double)d[q] - axes[f][q]));
    }
    hl_check_error("cube face centre directions vs +X -X +Y -Y +Z -Z", worst_face, 0.0);

    static const uint32_t Cs[] = {4, 16, 64, 128};
    for (size_t k = 0; k < sizeof Cs / sizeof Cs[0]; k++) {
        uint32_t C = Cs[k];
        hl_geom *g = make_geom(ctx, 8, C);
        double worst_len = 0.0;
        long bad_lib = 0, bad_gl = 0;
        for (uint32_t i = 0; i < g->ncube; i++) {
            const float *d = g->cube_dirs + 4 * (size_t)i;
            double dd[3] = {d[0], d[1], d[2]};
            worst_len = fmax(worst_len, fabs(norm3(dd) - 1.0));
            if (hl_dir_to_cube(d, C) != i) bad_lib++;
            if (gl_dir_to_texel(dd, C) != i) bad_gl++;
        }
        snprintf(what, sizeof what, "C=%u cube texel directions: | |d| - 1 |", C);
        hl_check_error(what, worst_len, 4.0 * FLT_EPSILON);
        snprintf(what, sizeof what, "C=%u cube texel centres not mapped back by hl_dir_to_cube (of %u)", C, g->ncube);
        hl_check_error(what, (double)bad_lib, 0.0);
        snprintf(what, sizeof what, "C=%u cube texel centres not at their OpenGL-table texel", C);
        hl_check_error(what, (double)bad_gl, 0.0);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

static void case_table(void)
{
    hl_context *ctx = make_ctx();
    static const uint32_t NC[][2] = {{8, 8}, {16, 16}, {64, 64}, {32, 128}, {128, 32}};
    char what[128];
    for (size_t k = 0; k < sizeof NC / sizeof NC[0]; k++) {
        uint32_t N = NC[k][0], C = NC[k][1];
        hl_geom *g = make_geom(ctx, N, C);
        double worst_rel = 0.0, worst_dir = 0.0, total[3] = {0, 0, 0};
        long bad_idx = 0, wrong_hemi = 0, empty = 0;
        double wrong_omega = 0.0;
        for (uint32_t j = 0; j < g->ncoef; j++) {
            int map = j >= N * N;
            double sum_abs = 0.0;
            if (g->omega[j] > 0.0f && g->c2p_start[j + 1] == g->c2p_start[j]) empty++;
            for (uint32_t e = g->c2p_start[j]; e < g->c2p_start[j + 1]; e++) {
                const hl_c2p_entry *c = &g->c2p[e];
                double m[3] = {c->mx, c->my, c->mz}, len = norm3(m);
                sum_abs += len;
                for (int q = 0; q < 3; q++) total[q] += m[q];
                if (c->index >= g->ncube) {
                    bad_idx++;
                    continue;
                }
                /* a part's moment lies in its map's hemisphere */
                if ((map ? -m[1] : m[1]) < 0.0) {
                    wrong_hemi++;
                    wrong_omega += len;
                }
                /* ... and points into its cube texel: within the texel's
                 * angular radius of its centre, at most atan(sqrt2 / C)
                 * (at the face centre; smaller elsewhere) */
                const float *d = g->cube_dirs + 4 * (size_t)c->index;
                double dd[3] = {d[0], d[1], d[2]};
                double ang = acos(fmin(1.0, dot3(m, dd) / len)) / atan(sqrt(2.0) / C);
                worst_dir = fmax(worst_dir, ang);
            }
            if (g->omega[j] > 0.0f) worst_rel = fmax(worst_rel, fabs(sum_abs - g->omega[j]) / g->omega[j]);
        }
        snprintf(what, sizeof what, "N=%u C=%u entries with a cube index out of range", N, C);
        hl_check_error(what, (double)bad_idx, 0.0);
        snprintf(what, sizeof what, "N=%u C=%u texels with omega > 0 and no entries", N, C);
        hl_check_error(what, (double)empty, 0.0);
        snprintf(what, sizeof what, "N=%u C=%u entries whose moment is in the other map's hemisphere (their |m| sum %.3g sr)",
                 N, C, wrong_omega);
        hl_check_error(what, (double)wrong_hemi, 0.0);
        snprintf(what, sizeof what, "N=%u C=%u entry moment angle from its cube texel centre / atan(sqrt2/C)", N, C);
        hl_check_error(what, worst_dir, 1.0);
        /* |m| = |integral of w| <= omega of the part, and a part of angular
         * size delta loses ~delta^2/12 of it: at most ~1% for N = 8 texels
         * (delta ~ 0.35 rad). 2% (the brief's figure) bounds that. */
        snprintf(what, sizeof what, "N=%u C=%u per texel |sum |m| - omega| / omega", N, C);
        hl_check_error(what, worst_rel, 0.02);
        /* The first moment of the whole sphere is zero. Each texel's moments
         * are 8x8 midpoint sums rescaled to its exact omega; the brief's
         * 1e-4 * 4 pi bounds their quadrature and float storage. */
        snprintf(what, sizeof what, "N=%u C=%u |sum of all m| / (4 pi)", N, C);
        hl_check_error(what, norm3(total) / (4.0 * PI), 1e-4);
        /* The transposed table (by cube texel) holds the same entries. */
        long bad_t = g->p2c_start[g->ncube] != g->nentries;
        for (uint32_t c = 0; c < g->ncube && !bad_t; c++)
            for (uint32_t e = g->p2c_start[c]; e < g->p2c_start[c + 1]; e++) {
                const hl_c2p_entry *t = &g->p2c[e];
                int found = 0;
                if (t->index < g->ncoef)
                    for (uint32_t f = g->c2p_start[t->index]; f < g->c2p_start[t->index + 1]; f++) {
                        const hl_c2p_entry *u = &g->c2p[f];
                        if (u->index == c && u->mx == t->mx && u->my == t->my && u->mz == t->mz) found = 1;
                    }
                if (!found) bad_t++;
            }
        snprintf(what, sizeof what, "N=%u C=%u transposed-table entries not in the table", N, C);
        hl_check_error(what, (double)bad_t, 0.0);
        hl_geom_destroy(g);
    }
    hl_context_destroy(ctx);
}

/* ================================================================ analytic */

/* L = 1 on every texel with a solid angle (texels outside the disc are 0). */
static void unit_light(const hl_geom *g, float *L)
{
    for (uint32_t j = 0; j < g->ncoef; j++) L[j] = g->omega[j] > 0.0f ? 1.0f : 0.0f;
}

static void normalize3(double v[3])
{
    double l = norm3(v);
    for (int q = 0; q < 3; q++) v[q] /= l;
}

static void case_furnace(void)
{
    hl_context *ctx = make_ctx();
    /* 20 normals: the six axes, the eight cube diagonals, six random */
    double normals[20][3];
    int nn = 0;
    for (int q = 0; q < 3; q++)
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            normals[nn][0] = normals[nn][1] = normals[nn][2] = 0.0;
            normals[nn][q] = sgn;
            nn++;
        }
    for (int a = -1; a <= 1; a += 2)
        for (int b = -1; b <= 1; b += 2)
            for (int c = -1; c <= 1; c += 2) {
                normals[nn][0] = a;
                normals[nn][1] = b;
                normals[nn][2] = c;
                normalize3(normals[nn++]);
            }
    while (nn < 20) {
        double v[3] = {rng_unit() * 2 - 1, rng_unit() * 2 - 1, rng_unit() * 2 - 1};
        if (norm3(v) < 0.1 || norm3(v) > 1.0) continue;
        normalize3(v);
        memcpy(normals[nn++], v, sizeof v);
    }

    static const uint32_t Rs[] = {16, 32, 64, 128};
    double err_of[4] = {0, 0, 0, 0};
    char what[160];
    for (size_t k = 0; k < 4; k++) {
        uint32_t R = Rs[k];
        hl_geom *g = make_geom(ctx, R, R);
        uint8_t *vis = xmalloc(g->ncube);
        memset(vis, 1, g->ncube); /* S = 1: every texel one unoccluded ray */
        float *T = xmalloc((size_t)g->ncoef * sizeof *T), *L = xmalloc((size_t)g->ncoef * sizeof *L);
        float *WT = xmalloc((size_t)g->ncoef * sizeof *WT), *WL = xmalloc((size_t)g->ncoef * sizeof *WL);
        unit_light(g, L);
        haar_of(g, L, WL);
        double worst_a = 0.0, worst_b = 0.0, worst_c = 0.0, worst_y = 0.0, worst_over = 0.0;
        for (int i = 0; i < nn; i++) {
            const double *n = normals[i];
            float nf[3] = {(float)n[0], (float)n[1], (float)n[2]};
            hl_ref_cube2para(g, vis, (float)(1.0 / PI), nf, T);
            double Bf = dot_ff(T, L, g->ncoef);
            /* (a) the same sum in double straight from the table */
            double Bd = 0.0;
            for (uint32_t e = 0; e < g->nentries; e++) {
                const hl_c2p_entry *c = &g->c2p[e];
                double w = (double)nf[0] * c->mx + (double)nf[1] * c->my + (double)nf[2] * c->mz;
                if (w > 0.0) Bd += w;
            }
            Bd /= PI;
            worst_a = fmax(worst_a, fabs(Bf - Bd));
            /* (b) against the exact 1 */
            worst_b = fmax(worst_b, fabs(Bd - 1.0));
            worst_over = fmax(worst_over, Bd - 1.0);
            if (fabs(n[1]) == 1.0) worst_y = fmax(worst_y, fabs(Bd - 1.0));
            /* (c) through the Haar domain */
            haar_of(g, T, WT);
            worst_c = fmax(worst_c, fabs(dot_ff(WT, WL, g->ncoef) - Bf) / Bf);
        }
        err_of[k] = worst_b;
        /* (a) Each T_j sums a few float products n.m (3 products, 2 adds,
         * then a float accumulation and the 1/pi scale): ~5 ulps of
         * |m| per entry. Summed over the sphere (sum |m| ~ 4 pi, over pi
         * = 4) the worst aligned case is 4 * 5 * 2^-24 = 1.2e-6; roundings
         * are independent, so 1e-6 holds with a wide margin. */
        snprintf(what, sizeof what, "C=N=%u (a) |sum T_j L_j - table sum in double| over 20 normals", R);
        hl_check_error(what, worst_a, 1e-6);
        /* (c) Parseval, as haar.parseval: 1e-6 relative */
        snprintf(what, sizeof what, "C=N=%u (c) |WT.WL - sum T_j L_j| / B", R);
        hl_check_error(what, worst_c, 1e-6);
        /* Normals +/-Y: the maps split at the horizon and so do the cube
         * rows (C even), so no table part straddles it and no clamp loses
         * anything. What is left is the table's first moments: each comes
         * from the part's in-disc 8x8 sub-samples, rescaled to the exact
         * omega. At the rim the sub-samples' centroid can sit half a
         * sub-cell, 1/(8N) in r, off the true one, and y changes by 1 per
         * unit r there; rim texels hold at most 2 pi (2 sqrt2 / N) sr, so
         * |B - 1| <= 2 pi 2 sqrt2 / N / (8N) / pi = 0.71 / N^2. The interior
         * midpoint error, ~(1/(4N))^2 / 24 relative, is far smaller:
         * tolerance 1 / N^2 (3.9e-3 at N = 16, 2.4e-4 at 64). */
        double tol_y = 1.0 / ((double)R * R);
        snprintf(what, sizeof what, "C=N=%u (b) |B - 1| for normals +/-Y (no part straddles the horizon)", R);
        hl_check_error(what, worst_y, tol_y);
        /* Clamping per part can only lose energy: B <= 1 up to the same
         * first-moment error. */
        snprintf(what, sizeof what, "C=N=%u (b) B - 1 (must not exceed 1 beyond the moment error)", R);
        hl_check_error(what, worst_over, tol_y);
        printf("C=N=%u (b) |B - 1| worst over 20 normals: %.4g\n", R, worst_b);
        free(vis);
        free(T);
        free(L);
        free(WT);
        free(WL);
        hl_geom_destroy(g);
    }
    /* (b) The remaining error: a part straddling the horizon contributes
     * max(0, n.m) instead of the integral of max(0, n.w), losing the
     * smaller of its two lobes. For a part of angular size delta with the
     * horizon at a uniformly random offset u, the loss is delta min(u,
     * delta - u)^2 / 2, on average delta^3 / 24; about 2 pi / delta parts
     * line the horizon, so the expected |B - 1| is (2 pi / delta)(delta^3 /
     * 24) / pi = delta^2 / 12. Parts are at most a face-centre cube texel's
     * diagonal (the paraboloid texels at the rim are no larger when N = C),
     * delta = 2 sqrt2 / C: tolerance 8 / (12 C^2) = 1.6e-4 at C = 64. */
    hl_check_error("C=N=64 (b) |B - 1| worst over 20 normals, bound 2/(3 C^2)", err_of[2],
                   2.0 / (3.0 * 64.0 * 64.0));
    int shrinks = err_of[1] < err_of[0] && err_of[2] < err_of[1] && err_of[3] < err_of[2];
    printf("(b) |B - 1| at C=N=16/32/64/128: %.4g %.4g %.4g %.4g; ratios %.2f %.2f %.2f\n", err_of[0], err_of[1],
           err_of[2], err_of[3], err_of[0] / err_of[1], err_of[1] / err_of[2], err_of[2] / err_of[3]);
    hl_check_error("(b) furnace error not shrinking at every step of C=N = 16, 32, 64, 128", shrinks ? 0.0 : 1.0, 0.0);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- cap */

/* Form factor of a spherical polygon (Lambert): the occluded cosine-weighted
 * solid angle over pi, seen from o with normal n, of the closed polygon P
 * (K vertices): (1 / 2 pi) sum_i Theta_i (n . Gamma_i), Theta_i the angle
 * between successive vertex directions, Gamma_i the unit normal of their
 * great circle. Exact for a polygon wholly above the horizon. */
static double polygon_form_factor(const double *P, int K, const double o[3], const double n[3])
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

#define CAP_SEGMENTS 512
#define CAP_RINGS 8
#define RECEIVER_SIZE 1e-5f

/* Receiver triangle (vertices 0..2, vertex 0 at the origin, normal +Y) and
 * a cap of radius 1 about +Y out to polar angle alpha, circumscribed: the
 * rim's 512 vertices sit at polar angle alpha' with tan alpha' = tan alpha /
 * cos(pi / 512), so each rim edge's great-circle arc (what the edge hides,
 * seen from the origin) touches the circle alpha at its midpoint and the
 * hidden region contains the cap. Seen from the origin only the rim
 * polygon matters (each facet hides the spherical triangle of its corners),
 * so 8 rings are enough to make the cap a real mesh; more rings would only
 * add vertices to precompute. rim gets the rim positions (3 * 512). */
static hl_mesh *cap_mesh(hl_context *ctx, double alpha, double *rim)
{
    const uint32_t S = CAP_SEGMENTS, R = CAP_RINGS;
    const uint32_t V = 4 + R * S, Tn = 1 + S + 2 * S * (R - 1);
    float *P = xmalloc((size_t)V * 3 * sizeof *P), *Nn = xmalloc((size_t)V * 3 * sizeof *Nn);
    uint32_t *I = xmalloc((size_t)Tn * 3 * sizeof *I);
    const float rs = RECEIVER_SIZE;
    const float rec[3][3] = {{0, 0, 0}, {0, 0, rs}, {rs, 0, 0}}; /* (b-a) x (c-a) = +Y */
    for (int v = 0; v < 3; v++)
        for (int q = 0; q < 3; q++) {
            P[3 * v + q] = rec[v][q];
            Nn[3 * v + q] = q == 1 ? 1.0f : 0.0f;
        }
    P[9] = 0.0f, P[10] = 1.0f, P[11] = 0.0f; /* pole */
    const double alpha_rim = atan(tan(alpha) / cos(PI / S));
    for (uint32_t k = 1; k <= R; k++)
        for (uint32_t i = 0; i < S; i++) {
            double th = alpha_rim * k / R, ph = 2.0 * PI * i / S;
            float *p = P + 3 * (4 + (k - 1) * S + i);
            p[0] = (float)(sin(th) * cos(ph));
            p[1] = (float)cos(th);
            p[2] = (float)(sin(th) * sin(ph));
            if (k == R)
                for (int q = 0; q < 3; q++) rim[3 * i + q] = p[q];
        }
    for (uint32_t v = 3; v < V; v++) /* outward radial normals */
        for (int q = 0; q < 3; q++) Nn[3 * v + q] = P[3 * v + q];
    uint32_t t = 0;
    I[t++] = 0, I[t++] = 1, I[t++] = 2;
    for (uint32_t i = 0; i < S; i++) {
        I[t++] = 3;
        I[t++] = 4 + (i + 1) % S;
        I[t++] = 4 + i;
    }
    for (uint32_t k = 1; k < R; k++)
        for (uint32_t i = 0; i < S; i++) {
            uint32_t a = 4 + (k - 1) * S + i, b = 4 + (k - 1) * S + (i + 1) % S;
            uint32_t c = a + S, d = b + S;
            I[t++] = a, I[t++] = b, I[t++] = d;
            I[t++] = a, I[t++] = d, I[t++] = c;
        }
    hl_mesh *mesh = NULL;
    hl_result r = hl_mesh_create(ctx, V, P, Nn, NULL, Tn, I, &mesh);
    free(P);
    free(Nn);
    free(I);
    if (r != HL_OK) {
        fprintf(stderr, "hl_mesh_create: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    return mesh;
}

/* Index of the vertex at the origin with normal +Y. */
static uint32_t find_receiver(const hl_mesh *m)
{
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v;
        if (p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f && n[1] == 1.0f) return v;
    }
    fprintf(stderr, "receiver vertex not found\n");
    exit(1);
}

/* B of a visibility row through the plain-C stages: cube2para (scale
 * 1 / (pi S^2)), then the dot product with WL in the Haar domain; *direct
 * gets sum_j T_j L_j, coef_out (may be NULL) the coefficients. */
static double stages_B(const hl_geom *g, const uint8_t *vis, uint32_t S, const float n[3], const float *L,
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

/* Cube face coordinates to a direction, OpenGL table, in double. */
static void gl_face_dir(int f, double sc, double tc, double d[3])
{
    switch (f) {
    case 0: d[0] = 1; d[1] = -tc; d[2] = -sc; break;
    case 1: d[0] = -1; d[1] = -tc; d[2] = sc; break;
    case 2: d[0] = sc; d[1] = 1; d[2] = tc; break;
    case 3: d[0] = sc; d[1] = -1; d[2] = -tc; break;
    case 4: d[0] = sc; d[1] = -tc; d[2] = 1; break;
    default: d[0] = -sc; d[1] = -tc; d[2] = -1; break;
    }
}

/* Gauss-Legendre, 5 points on [-1, 1]. */
static const double gl5_x[5] = {-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831,
                                0.9061798459386640};
static const double gl5_w[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665,
                                0.2369268850561891};

/* First moment, integral of w dw, over the face rectangle [sc0, sc0 + h] x
 * [tc0, tc0 + h] of face f: dw = dsc dtc / (1 + sc^2 + tc^2)^(3/2) and
 * w = d / |d|, so the integrand is d / (1 + sc^2 + tc^2)^2, smooth: 5x5
 * Gauss-Legendre is exact to ~1e-12 for h <= 1/8. */
static void face_rect_moment(int f, double sc0, double tc0, double h, double M[3])
{
    M[0] = M[1] = M[2] = 0.0;
    for (int a = 0; a < 5; a++)
        for (int b = 0; b < 5; b++) {
            double sc = sc0 + h * 0.5 * (gl5_x[a] + 1.0), tc = tc0 + h * 0.5 * (gl5_x[b] + 1.0), d[3];
            gl_face_dir(f, sc, tc, d);
            double q = 1.0 + sc * sc + tc * tc, w = gl5_w[a] * gl5_w[b] * h * h * 0.25 / (q * q);
            for (int k = 0; k < 3; k++) M[k] += d[k] * w;
        }
}

/* Visibility counts of the exact cap (polar angle < alpha about +Y, seen
 * from the origin) for the S x S sub-rays of each cube texel, at the
 * directions rays.c casts (face coordinates offset by ((a + 0.5) / S - 0.5)
 * * 2 / C). near[i] = 1 where a sub-ray lies within 1e-4 rad of the rim:
 * there the mesh (a circumscribed polygon seen from a point ~2e-5 above the
 * origin, off by at most ~4e-5 rad) may legitimately disagree. B_disc gets
 * the exact B of these samples: each sub-ray stands for its sub-cell, whose
 * cosine-weighted solid angle (about +Y) is integrated exactly. */
static void cap_vis(const hl_geom *g, uint32_t S, double alpha, uint8_t *vis, uint8_t *near, double *B_disc)
{
    const uint32_t C = g->C;
    double acc = 0.0;
    for (uint32_t i = 0; i < g->ncube; i++) {
        int f = (int)(i / (C * C));
        uint32_t row = (i / C) % C, col = i % C, cnt = 0;
        near[i] = 0;
        for (uint32_t a = 0; a < S; a++)
            for (uint32_t b = 0; b < S; b++) {
                double h = 2.0 / ((double)C * S);
                double sc0 = -1.0 + 2.0 * col / C + b * h, tc0 = -1.0 + 2.0 * row / C + a * h, d[3];
                gl_face_dir(f, sc0 + 0.5 * h, tc0 + 0.5 * h, d);
                double polar = acos(d[1] / norm3(d));
                if (fabs(polar - alpha) < 1e-4) near[i] = 1;
                if (polar < alpha) continue;
                cnt++;
                double M[3];
                face_rect_moment(f, sc0, tc0, h, M);
                if (M[1] > 0.0) acc += M[1]; /* no sub-cell straddles y = 0 (C S even) */
            }
        vis[i] = (uint8_t)cnt;
    }
    *B_disc = acc / PI;
}

static void case_cap(void)
{
    hl_context *ctx = make_ctx();
    const char *tmp = hl_test_env("HL_TMP", ".");
    char what[220];

    /* Self-check of the Lambert reference: a 65536-gon inscribed in the
     * circle alpha = 45 deg gives sin^2 alpha to its polygon error
     * ~ sin^2 alpha (pi/K)^2 ~ 1e-9. */
    {
        const int K = 65536;
        double *P = xmalloc((size_t)K * 3 * sizeof *P), o[3] = {0, 0, 0}, n[3] = {0, 1, 0}, al = PI / 4;
        for (int i = 0; i < K; i++) {
            double ph = 2 * PI * i / K;
            P[3 * i] = sin(al) * cos(ph), P[3 * i + 1] = cos(al), P[3 * i + 2] = sin(al) * sin(ph);
        }
        hl_check_error("Lambert reference: 65536-gon vs sin^2(45 deg)",
                       fabs(polygon_form_factor(P, K, o, n) - 0.5), 1e-8);
        free(P);
    }

    static const double alphas_deg[3] = {30, 45, 60};
    static const uint32_t Rs[3] = {16, 32, 64};
    static const uint32_t quants[3] = {HL_QUANT_LINEAR8, HL_QUANT_LOG8, HL_QUANT_SQRT8};
    static const uint32_t Ss[2] = {1, 4};
    const float ray_offset = 1e-5f; /* of the diagonal: see below */
    double err[2][3][3]; /* [S index][alpha][resolution]: Embree, unquantised */
    for (int ia = 0; ia < 3; ia++) {
        const double adeg = alphas_deg[ia], alpha = adeg * PI / 180.0, exact = cos(alpha) * cos(alpha);
        double rim[3 * CAP_SEGMENTS];
        hl_mesh *mesh = cap_mesh(ctx, alpha, rim);
        uint32_t rv = find_receiver(mesh);
        const float nrm[3] = {0.0f, 1.0f, 0.0f};
        /* The rays start at the receiver plus the offset along the normal
         * (rays.c). With offset 1e-5 of the diagonal (~2e-5) the shift
         * changes B by ~sin(2 alpha) sin(alpha) 2e-5, and a receiver of side
         * 1e-5 is never hit by the near-horizon rays that rays.c still casts
         * (they reach y = 0 at least offset / (1.5 / C) = 2e-4 away). */
        const float offset = ray_offset * hl_mesh_query_diagonal(mesh);
        const double o[3] = {0.0, (double)offset, 0.0}, ny[3] = {0, 1, 0};
        double B_poly = 1.0 - polygon_form_factor(rim, CAP_SEGMENTS, o, ny);
        printf("alpha=%2.0f: cos^2 alpha = %.6f; exact B of the mesh from the ray origin %.6f (polygon + offset "
               "error %+.3g)\n",
               adeg, exact, B_poly, B_poly - exact);
        /* The circumscribed 512-gon hides a band of angular width at most
         * alpha' - alpha ~ sin(2 alpha)/2 (pi/512)^2/2 ~ 9.4e-6 rad, costing
         * ~2 sin(alpha) cos(alpha) * that in B, plus the offset's ~2e-5:
         * both below 3e-5; 1e-4 bounds them. */
        snprintf(what, sizeof what, "alpha=%.0f polygon + ray offset |B_mesh - cos^2 alpha|", adeg);
        hl_check_error(what, fabs(B_poly - exact), 1e-4);

        hl_rt *rt = NULL;
        if (hl_rt_create(ctx, mesh, &rt) != HL_OK) {
            fprintf(stderr, "hl_rt_create: %s\n", hl_context_last_error(ctx));
            exit(1);
        }
        for (int ir = 0; ir < 3; ir++) {
            const uint32_t R = Rs[ir];
            hl_geom *g = make_geom(ctx, R, R);
            float *L = xmalloc((size_t)g->ncoef * sizeof *L), *WL = xmalloc((size_t)g->ncoef * sizeof *WL);
            float *coef = xmalloc((size_t)g->ncoef * sizeof *coef), *dense = xmalloc((size_t)g->ncoef * sizeof *dense);
            uint8_t *vis = xmalloc(g->ncube), *vis_a = xmalloc(g->ncube), *near = xmalloc(g->ncube);
            unit_light(g, L);
            haar_of(g, L, WL);
            double B_e1 = 0.0;

            for (int is = 0; is < 2; is++) {
                const uint32_t S = Ss[is];
                /* Embree visibility of the receiver, exactly as the
                 * precompute casts it */
                hl_vis_counts vc = {0, 0};
                if (hl_rt_visibility(rt, g, mesh, rv, 1, S, offset, vis, &vc) != HL_OK) {
                    fprintf(stderr, "hl_rt_visibility: %s\n", hl_context_last_error(ctx));
                    exit(1);
                }
                double B_disc;
                cap_vis(g, S, alpha, vis_a, near, &B_disc);
                long differ = 0;
                for (uint32_t c = 0; c < g->ncube; c++)
                    if (g->cube_dirs[4 * (size_t)c + 1] > -1.5f / (float)R && vis_a[c] != vis[c] && !near[c])
                        differ++;
                snprintf(what, sizeof what,
                         "alpha=%.0f C=N=%u S=%u cube texels where Embree and the exact cap disagree (off the rim)",
                         adeg, R, S);
                hl_check_error(what, (double)differ, 0.0);

                double direct_e, B_e = stages_B(g, vis, S, nrm, L, WL, &direct_e, S == 1 ? coef : NULL);
                double direct_a, B_a = stages_B(g, vis_a, S, nrm, L, WL, &direct_a, NULL);
                if (S == 1) B_e1 = B_e;
                err[is][ia][ir] = fabs(B_e - exact);
                printf("alpha=%2.0f C=N=%2u S=%u: Embree B = %.6f (|B - cos^2| = %.3g), exact-cap visibility "
                       "B = %.6f, exact B of those point samples %.6f (sampling error %+.3g, stages error %+.3g)\n",
                       adeg, R, S, B_e, err[is][ia][ir], B_a, B_disc, B_disc - B_poly, B_a - B_disc);
                /* Haar-domain dot vs direct sum: Parseval, 1e-6 relative */
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u S=%u |WT.WL - sum T L| / B", adeg, R, S);
                hl_check_error(what, fmax(fabs(B_e - direct_e) / direct_e, fabs(B_a - direct_a) / direct_a), 1e-6);
                /* The stages (the area filter) against the exact weights of
                 * the samples they were given. The table resolves each
                 * paraboloid texel's split among cube texels on an 8x8
                 * sub-grid: along a visibility edge it misplaces at most half
                 * a sub-cell, (2/N)/16 in (s, t), i.e. <= 1/(4N) rad (the map
                 * stretches angles by at most 2). The edge is a staircase on
                 * the cube grid, at most 4/pi times the rim circle's 2 pi
                 * sin(alpha), and weighted by cos(alpha) / pi: bound
                 * 8 sin(alpha) / (4N) cos(alpha) / pi = sin(2 alpha) / (pi N)
                 * (4.97e-3 at N = 64, alpha = 45). */
                double tol_stage = sin(2.0 * alpha) / (PI * R);
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u S=%u stages vs exact B of the same samples", adeg,
                         R, S);
                hl_check_error(what, fabs(B_a - B_disc), tol_stage);
            }

            /* End to end: hl_precompute -> file -> hl_transport_query_row */
            for (int iq = 0; iq < 3; iq++) {
                const char *qn = quants[iq] == HL_QUANT_LOG8 ? "log8" : quants[iq] == HL_QUANT_SQRT8 ? "sqrt8" : "linear8";
                char path[1024];
                snprintf(path, sizeof path, "%s/analytic_cap_%d_%u_%s_%ld.hlt", tmp, (int)adeg, R, qn,
                         (long)getpid());
                hl_precompute_desc d = {0};
                d.N = R;
                d.C = R;
                d.rule = HL_TRUNC_ALL;
                d.quant = quants[iq];
                d.ray_offset = ray_offset;
                hl_result r = hl_precompute(ctx, mesh, &d, path, NULL);
                HL_CHECK(r == HL_OK, "hl_precompute: %s", hl_context_last_error(ctx));
                hl_transport *t = NULL;
                if (r == HL_OK) r = hl_transport_load(ctx, path, &t);
                HL_CHECK(r == HL_OK, "hl_transport_load: %s", hl_context_last_error(ctx));
                remove(path);
                if (r != HL_OK) continue;
                HL_CHECK(t->info.N == R && t->info.C == R && t->info.vertex_count == mesh->vertex_count,
                         "transport header N=%u C=%u V=%u", t->info.N, t->info.C, t->info.vertex_count);
                hl_transport_query_row(t, rv, dense);
                double B_q = dot_ff(dense, WL, g->ncoef);
                /* The file's row must be exactly the quantisation (formulas
                 * of hl_shared.h, this row's a and b) of the coefficients the
                 * stages give for the same Embree visibility, with a and b the
                 * row's min and max kept value (|value| for log8). */
                hl_row_quant rq = t->row_quant[rv];
                double worst_bits = 0.0, bound = 0.0;
                float lo = INFINITY, hi = -INFINITY;
                for (uint32_t i = 0; i < g->ncoef; i++) {
                    if (coef[i] == 0.0f) {
                        worst_bits = fmax(worst_bits, fabs((double)dense[i]));
                        continue;
                    }
                    float v = quants[iq] != HL_QUANT_LINEAR8 ? fabsf(coef[i]) : coef[i];
                    lo = fminf(lo, v);
                    hi = fmaxf(hi, v);
                    uint32_t code = hl_quant(quants[iq], coef[i], rq.a, rq.b, hl_dither_key(rv, i));
                    float want = hl_dequant(quants[iq], code, rq.a, rq.b, hl_dither_key(rv, i));
                    worst_bits = fmax(worst_bits, fabs((double)dense[i] - want));
                    /* the scheme's own worst step: linear8, half of
                     * (b - a) / 255; log8, half of (key span) / 127 float keys
                     * plus one for the dequantiser's rounding, a key being at
                     * most 2^-23 of the value; sqrt8, sqrt(|v| / b) rounded to a
                     * 127th: b (2 sqrt(|v| / b) + 1/254) / 254, plus a few
                     * units in the last place of b for the float rounding */
                    double step = quants[iq] == HL_QUANT_LOG8
                                      ? fabs((double)coef[i]) *
                                            (((double)hl_key(rq.b) - hl_key(rq.a)) / 254.0 + 1.0) * ldexp(1.0, -23)
                                  : quants[iq] == HL_QUANT_SQRT8
                                      ? rq.b * (2.0 * sqrt(fabs((double)coef[i]) / rq.b) + 1.0 / 254.0) / 254.0 +
                                            8.0 * ldexp((double)rq.b, -24)
                                      : ((double)rq.b - rq.a) / 510.0;
                    bound += fabs((double)WL[i]) * step;
                }
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u %s: file row vs quantised stage coefficients", adeg,
                         R, qn);
                hl_check_error(what, worst_bits, 0.0);
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u %s: row a, b vs min, max kept", adeg, R, qn);
                hl_check_error(what, fmax(fabs((double)rq.a - lo), fabs((double)rq.b - hi)), 0.0);
                printf("alpha=%2.0f C=N=%2u %-7s: file B = %.6f, |B - cos^2| = %.3g, quantisation error %+.3g "
                       "(a=%.3g b=%.3g)\n",
                       adeg, R, qn, B_q, fabs(B_q - exact), B_q - B_e1, (double)rq.a, (double)rq.b);
                snprintf(what, sizeof what, "alpha=%.0f C=N=%u %s: |B_file - B_unquantised| vs the scheme's step bound",
                         adeg, R, qn);
                hl_check_error(what, fabs(B_q - B_e1), bound);
                hl_transport_destroy(t);
            }
            free(L);
            free(WL);
            free(coef);
            free(dense);
            free(vis);
            free(vis_a);
            free(near);
            hl_geom_destroy(g);
        }
        hl_rt_destroy(rt);
        hl_mesh_destroy(mesh);
    }

    /* Discretisation. Visibility is a point sample per sub-ray; each of the
     * ~4 C S sin(alpha) sub-cells the rim crosses is wrong by (indicator -
     * covered fraction) of its weight w = (2/(C S))^2 cos(alpha) / pi (an
     * upper bound: the face Jacobian only lowers it), standard deviation
     * <= 0.41 w for a uniform fraction. The cap is symmetric under the 8
     * symmetries of the +Y face, so these errors come in identical groups
     * of 8: sigma = sqrt(8 * 4 C S sin(alpha)) * 0.41 w. Add the stages'
     * bound above; tolerance = 3 sigma + sin(2 alpha) / (pi N). */
    for (int is = 0; is < 2; is++) {
        const uint32_t S = Ss[is];
        double worst16 = 0.0, worst64 = 0.0;
        for (int ia = 0; ia < 3; ia++) {
            const double alpha = alphas_deg[ia] * PI / 180.0, C = 64.0;
            double w = (2.0 / (C * S)) * (2.0 / (C * S)) * cos(alpha) / PI;
            double sigma = sqrt(8.0 * 4.0 * C * S * sin(alpha)) * 0.41 * w;
            double tol = 3.0 * sigma + sin(2.0 * alpha) / (PI * C);
            snprintf(what, sizeof what, "alpha=%.0f C=N=64 S=%u Embree, unquantised |B - cos^2 alpha|",
                     alphas_deg[ia], S);
            hl_check_error(what, err[is][ia][2], tol);
            printf("alpha=%2.0f S=%u |B - cos^2| at C=N=16/32/64: %.3g %.3g %.3g\n", alphas_deg[ia], S,
                   err[is][ia][0], err[is][ia][1], err[is][ia][2]);
            worst16 = fmax(worst16, err[is][ia][0]);
            worst64 = fmax(worst64, err[is][ia][2]);
            /* With 4x4 rays per texel the sampling error no longer
             * dominates, and each alpha must improve from 16 to 64. */
            if (S > 1) {
                snprintf(what, sizeof what, "alpha=%.0f S=%u error at C=N=64 (%.3g) not below that at 16 (%.3g)",
                         alphas_deg[ia], S, err[is][ia][2], err[is][ia][0]);
                hl_check_error(what, err[is][ia][2] < err[is][ia][0] ? 0.0 : 1.0, 0.0);
            }
        }
        /* With one ray per texel the point-sampling error of one alpha is
         * an aliasing pattern of the rim against the grid, not monotone in
         * C (alpha = 30: the samples at C = 64 are those of C = 16, S = 4,
         * and miss by +2.2e-3, more than C = 16, S = 1); over the three
         * alphas it must shrink. */
        snprintf(what, sizeof what, "S=%u worst over alpha: error at C=N=64 (%.3g) not below that at 16 (%.3g)", S,
                 worst64, worst16);
        hl_check_error(what, worst64 < worst16 ? 0.0 : 1.0, 0.0);
    }
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- ray offset */

/* A mesh being built for the ray-offset scenes: positions and normals in
 * unit scale, scaled by `scale` when made. */
typedef struct mesh_build {
    uint32_t nv, nt;
    float P[3 * 2048], Nn[3 * 2048];
    uint32_t I[3 * 4096];
} mesh_build;

static uint32_t mb_vertex(mesh_build *b, double x, double y, double z, double nx, double ny, double nz)
{
    const double p[3] = {x, y, z}, n[3] = {nx, ny, nz};
    for (int q = 0; q < 3; q++) {
        b->P[3 * b->nv + q] = (float)p[q];
        b->Nn[3 * b->nv + q] = (float)n[q];
    }
    return b->nv++;
}

static void mb_tri(mesh_build *b, uint32_t a, uint32_t c, uint32_t d)
{
    b->I[3 * b->nt] = a, b->I[3 * b->nt + 1] = c, b->I[3 * b->nt + 2] = d;
    b->nt++;
}

/* A quad a b c d (counter-clockwise seen from its normal's side) as a fan
 * of four triangles about its centre, which gets normal n: the vertex the
 * checks look at when the quad holds the receiver. Returns the centre. */
static uint32_t mb_quad_fan(mesh_build *b, const double c[4][3], const double n[3])
{
    double m[3] = {0, 0, 0};
    uint32_t v[4];
    for (int k = 0; k < 4; k++) {
        v[k] = mb_vertex(b, c[k][0], c[k][1], c[k][2], n[0], n[1], n[2]);
        for (int q = 0; q < 3; q++) m[q] += c[k][q] / 4.0;
    }
    uint32_t centre = mb_vertex(b, m[0], m[1], m[2], n[0], n[1], n[2]);
    for (int k = 0; k < 4; k++) mb_tri(b, centre, v[k], v[(k + 1) % 4]);
    return centre;
}

/* An axis-aligned closed box [lo, hi], outward winding and normals. */
static void mb_box(mesh_build *b, const double lo[3], const double hi[3])
{
    for (int axis = 0; axis < 3; axis++)
        for (int side = 0; side < 2; side++) {
            const int u = (axis + 1) % 3, w = (axis + 2) % 3;
            double n[3] = {0, 0, 0}, c[4][3];
            n[axis] = side ? 1.0 : -1.0;
            const double pos = side ? hi[axis] : lo[axis];
            /* corners in (u, w) order, counter-clockwise about +axis */
            const double uw[4][2] = {{lo[u], lo[w]}, {hi[u], lo[w]}, {hi[u], hi[w]}, {lo[u], hi[w]}};
            for (int k = 0; k < 4; k++) {
                const int kk = side ? k : 3 - k;
                c[k][axis] = pos;
                c[k][u] = uw[kk][0];
                c[k][w] = uw[kk][1];
            }
            mb_quad_fan(b, c, n);
        }
}

/* Point or direction x (as mb_vertex stored it) turned by rot (row-major
 * 3 x 3, NULL: none) and times scale. */
static void mb_place(const float x[3], const double *rot, double scale, double out[3])
{
    for (int r = 0; r < 3; r++) {
        out[r] = rot ? 0.0 : (double)x[r] * scale;
        if (rot)
            for (int c = 0; c < 3; c++) out[r] += rot[3 * r + c] * (double)x[c] * scale;
    }
}

static hl_mesh *mb_mesh(hl_context *ctx, const mesh_build *b, double scale, const double *rot)
{
    float *P = xmalloc((size_t)b->nv * 12), *Nn = xmalloc((size_t)b->nv * 12);
    for (uint32_t i = 0; i < b->nv; i++) {
        double p[3], n[3];
        mb_place(b->P + 3 * i, rot, scale, p);
        mb_place(b->Nn + 3 * i, rot, 1.0, n);
        for (int q = 0; q < 3; q++) P[3 * i + q] = (float)p[q], Nn[3 * i + q] = (float)n[q];
    }
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_create(ctx, b->nv, P, Nn, NULL, b->nt, b->I, &m);
    free(P);
    free(Nn);
    if (r != HL_OK) {
        fprintf(stderr, "hl_mesh_create: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    return m;
}

/* The mesh vertex that mb_mesh made of the builder's vertex at p with
 * normal n (both given in unit scale, unturned). */
static uint32_t find_vertex(const hl_mesh *m, const double p[3], const double n[3], double scale, const double *rot)
{
    const float pf[3] = {(float)p[0], (float)p[1], (float)p[2]}, nf[3] = {(float)n[0], (float)n[1], (float)n[2]};
    double pw[3], nw[3];
    mb_place(pf, rot, scale, pw);
    mb_place(nf, rot, 1.0, nw);
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        const float *q = m->positions + 3 * (size_t)v, *nn = m->normals + 3 * (size_t)v;
        int same = 1;
        for (int k = 0; k < 3; k++) same &= q[k] == (float)pw[k] && fabs(nn[k] - nw[k]) < 1e-6;
        if (same) return v;
    }
    fprintf(stderr, "vertex not found\n");
    exit(1);
}

/* A thin slab, a contact and a crease, each with a receiver vertex closer
 * to other geometry than the old default offset (1e-3 of the bounding-box
 * diagonal), and far more than the robust one:
 *   slab     a receiver (normal +Y) under a closed slab 2 x 2e-4 x 2 that
 *            hovers 2e-4 above it; the slab's underside hides all but a
 *            grazing band
 *   contact  the centre of a unit cube's underside (normal -Y) resting
 *            2e-4 above an 8 x 8 ground: the ground hides almost all
 *   crease   a vertex 0.01 from the apex of a 10 degree V-groove (normal
 *            +Y), the other wall 1.76e-3 across
 * The exact B (white light, albedo 1) is 1 minus the Lambert form factor
 * of the one occluding polygon, wholly above the receiver's horizon. */
typedef struct offset_scene {
    const char *name;
    mesh_build b;
    double rp[3], rn[3]; /* the receiver */
    double poly[3 * 4];  /* the occluder */
} offset_scene;

static void make_offset_scenes(offset_scene *sc)
{
    const double g = 2e-4, t = 2e-4, r = 1e-5;
    /* slab */
    offset_scene *s = &sc[0];
    memset(s, 0, sizeof *s);
    s->name = "thin slab";
    mb_vertex(&s->b, 0, 0, 0, 0, 1, 0);
    mb_vertex(&s->b, 0, 0, r, 0, 1, 0);
    mb_vertex(&s->b, r, 0, 0, 0, 1, 0);
    mb_tri(&s->b, 0, 1, 2);
    mb_box(&s->b, (const double[3]){-1, g, -1}, (const double[3]){1, g + t, 1});
    const double slab[12] = {-1, g, -1, 1, g, -1, 1, g, 1, -1, g, 1};
    memcpy(s->poly, slab, sizeof slab);
    s->rp[0] = s->rp[1] = s->rp[2] = 0.0, s->rn[0] = 0, s->rn[1] = 1, s->rn[2] = 0;
    /* contact: the cube's underside is a fan about its centre */
    s = &sc[1];
    memset(s, 0, sizeof *s);
    s->name = "contact";
    mb_box(&s->b, (const double[3]){-0.5, g, -0.5}, (const double[3]){0.5, g + 1.0, 0.5});
    const double ground[4][3] = {{-4, 0, -4}, {-4, 0, 4}, {4, 0, 4}, {4, 0, -4}};
    mb_quad_fan(&s->b, ground, (const double[3]){0, 1, 0});
    for (int k = 0; k < 4; k++) memcpy(s->poly + 3 * k, ground[k], sizeof ground[k]);
    s->rp[0] = 0, s->rp[1] = g, s->rp[2] = 0, s->rn[0] = 0, s->rn[1] = -1, s->rn[2] = 0;
    /* crease: wall A (y = 0) as a fan about the receiver, wall B turned
       10 degrees about the apex line (the z axis) */
    s = &sc[2];
    memset(s, 0, sizeof *s);
    s->name = "crease";
    const double sx = 0.01, L = 2.0, th = 10.0 * PI / 180.0;
    const double A[4][3] = {{0, 0, -L}, {0, 0, L}, {1, 0, L}, {1, 0, -L}};
    uint32_t a[4], rv = mb_vertex(&s->b, sx, 0, 0, 0, 1, 0);
    for (int k = 0; k < 4; k++) a[k] = mb_vertex(&s->b, A[k][0], A[k][1], A[k][2], 0, 1, 0);
    /* the receiver on wall A's edge x = sx: fan to the corners */
    mb_tri(&s->b, rv, a[0], a[1]);
    mb_tri(&s->b, rv, a[1], a[2]);
    mb_tri(&s->b, rv, a[2], a[3]);
    mb_tri(&s->b, rv, a[3], a[0]);
    const double Bw[4][3] = {{0, 0, -L}, {cos(th), sin(th), -L}, {cos(th), sin(th), L}, {0, 0, L}};
    const double nb[3] = {sin(th), -cos(th), 0};
    uint32_t bq[4];
    for (int k = 0; k < 4; k++) bq[k] = mb_vertex(&s->b, Bw[k][0], Bw[k][1], Bw[k][2], nb[0], nb[1], nb[2]);
    mb_tri(&s->b, bq[0], bq[1], bq[2]);
    mb_tri(&s->b, bq[0], bq[2], bq[3]);
    for (int k = 0; k < 4; k++) memcpy(s->poly + 3 * k, Bw[k], sizeof Bw[k]);
    s->rp[0] = sx, s->rp[1] = 0, s->rp[2] = 0, s->rn[0] = 0, s->rn[1] = 1, s->rn[2] = 0;
}

/* B of one vertex (white light, albedo 1) from its Embree visibility. */
static double vertex_B(hl_context *ctx, hl_rt *rt, const hl_geom *g, const hl_mesh *m, uint32_t v, uint32_t S,
                       float offset, const float *L, const float *WL)
{
    uint8_t *vis = xmalloc(g->ncube);
    if (hl_rt_visibility(rt, g, m, v, 1, S, offset, vis, NULL) != HL_OK) {
        fprintf(stderr, "hl_rt_visibility: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    double direct;
    double B = stages_B(g, vis, S, m->normals + 3 * (size_t)v, L, WL, &direct, NULL);
    free(vis);
    return B;
}

/* B of one vertex (white light, albedo 1) from rays that start on the
 * vertex itself and skip its own triangles (hl_rt_occluded_from_vertex,
 * bench's continuous reference): the cosine-weighted hemisphere on a
 * latitude-longitude grid of 1024 x 512 cells, in double. */
static double vertex_B_own(hl_context *ctx, hl_rt *rt, const hl_mesh *m, uint32_t v)
{
    const uint32_t W = 1024, H = 512;
    const float *n = m->normals + 3 * (size_t)v;
    float *dir = xmalloc((size_t)W * H * 12);
    double *w = xmalloc((size_t)W * H * sizeof *w);
    uint8_t *occ = xmalloc((size_t)W * H);
    uint32_t cnt = 0;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            const double th = PI * (y + 0.5) / H, ph = 2.0 * PI * (x + 0.5) / W;
            const double d[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
            const double c = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
            if (c <= 0.0) continue;
            for (int q = 0; q < 3; q++) dir[3 * (size_t)cnt + q] = (float)d[q];
            w[cnt++] = c * 2.0 * PI / W * (cos(PI * y / H) - cos(PI * (y + 1) / H)) / PI;
        }
    if (hl_rt_occluded_from_vertex(rt, v, cnt, dir, occ) != HL_OK) {
        fprintf(stderr, "hl_rt_occluded_from_vertex: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    double B = 0.0;
    for (uint32_t i = 0; i < cnt; i++) B += occ[i] ? 0.0 : w[i];
    free(dir);
    free(w);
    free(occ);
    return B;
}

/* Rays of vertex v in texels wholly above its horizon (centre more than
 * two texel widths up) that something blocked. */
static uint32_t blocked_above(hl_context *ctx, hl_rt *rt, const hl_geom *g, const hl_mesh *m, uint32_t v)
{
    uint8_t *vis = xmalloc(g->ncube);
    if (hl_rt_visibility(rt, g, m, v, 1, 1, 0.0f, vis, NULL) != HL_OK) {
        fprintf(stderr, "hl_rt_visibility: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    const float *n = m->normals + 3 * (size_t)v;
    uint32_t blocked = 0;
    for (uint32_t c = 0; c < g->ncube; c++) {
        const float *d = g->cube_dirs + 4 * (size_t)c;
        float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if ((d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) / len > 4.0f / (float)g->C) blocked += vis[c] == 0;
    }
    free(vis);
    return blocked;
}

static void case_ray_offset(void)
{
    hl_context *ctx = make_ctx();
    char what[256];
    const uint32_t R = 64, S = 4;
    hl_geom *g = make_geom(ctx, R, R);
    float *L = xmalloc((size_t)g->ncoef * sizeof *L), *WL = xmalloc((size_t)g->ncoef * sizeof *WL);
    unit_light(g, L);
    haar_of(g, L, WL);
    /* the discretisation at C = N = 64, S = 4 of a polygon edge: the cap
       case's bound sin(2 alpha) / (pi N) at its worst, plus 3 sigma */
    const double tol = 0.01;
    offset_scene *sc = xcalloc(3, sizeof *sc);
    make_offset_scenes(sc);
    static const double scales[3] = {1e-3, 1.0, 1e4};
    double worst_new = 0.0, least_old = INFINITY;
    for (int k = 0; k < 3; k++)
        for (int is = 0; is < 3; is++) {
            const double scale = scales[is];
            hl_mesh *m = mb_mesh(ctx, &sc[k].b, scale, NULL);
            hl_rt *rt = NULL;
            if (hl_rt_create_filtered(ctx, m, &rt) != HL_OK) exit(1);
            const uint32_t v = find_vertex(m, sc[k].rp, sc[k].rn, scale, NULL);
            double poly[12], o[3];
            for (int q = 0; q < 12; q++) poly[q] = sc[k].poly[q] * scale;
            for (int q = 0; q < 3; q++) o[q] = (double)m->positions[3 * (size_t)v + q];
            const double exact = 1.0 - polygon_form_factor(poly, 4, o, sc[k].rn);
            const float old_offset = 1e-3f * hl_mesh_query_diagonal(m);
            const double B_new = vertex_B(ctx, rt, g, m, v, S, 0.0f, L, WL);
            const double B_old = vertex_B(ctx, rt, g, m, v, S, old_offset, L, WL);
            printf("ray offset, %-9s x %g: exact B %.6f; robust offset (%.3g) B %.6f, error %+.3g; old default "
                   "(%.3g) B %.6f, error %+.3g\n",
                   sc[k].name, scale, exact, (double)hl_rt_robust_offset(rt, v), B_new, B_new - exact,
                   (double)old_offset, B_old, B_old - exact);
            snprintf(what, sizeof what, "ray offset, %s x %g: robust offset |B - exact|", sc[k].name, scale);
            hl_check_error(what, fabs(B_new - exact), tol);
            /* bench's continuous reference, which has no offset at all */
            const double B_own = vertex_B_own(ctx, rt, m, v);
            printf("ray offset, %-9s x %g: rays from the vertex itself (its own triangles skipped) B %.6f, "
                   "error %+.3g\n", sc[k].name, scale, B_own, B_own - exact);
            snprintf(what, sizeof what, "ray offset, %s x %g: rays from the vertex itself |B - exact|", sc[k].name,
                     scale);
            hl_check_error(what, fabs(B_own - exact), tol);
            worst_new = fmax(worst_new, fabs(B_new - exact));
            least_old = fmin(least_old, fabs(B_old - exact));
            hl_rt_destroy(rt);
            hl_mesh_destroy(m);
        }
    /* End to end: hl_precompute's default is the robust offset (the
       contact scene at unit scale, through the transport file) */
    {
        char path[1024];
        snprintf(path, sizeof path, "%s/analytic_offset_%ld.hlt", hl_test_env("HL_TMP", "."), (long)getpid());
        hl_mesh *m = mb_mesh(ctx, &sc[1].b, 1.0, NULL);
        const uint32_t v = find_vertex(m, sc[1].rp, sc[1].rn, 1.0, NULL);
        double o[3];
        for (int q = 0; q < 3; q++) o[q] = (double)m->positions[3 * (size_t)v + q];
        const double exact = 1.0 - polygon_form_factor(sc[1].poly, 4, o, sc[1].rn);
        hl_precompute_desc d = {.N = R, .C = R, .supersample = S, .rule = HL_TRUNC_ALL};
        hl_transport *t = NULL;
        hl_result r = hl_precompute(ctx, m, &d, path, NULL);
        if (r == HL_OK) r = hl_transport_load(ctx, path, &t);
        HL_CHECK(r == HL_OK, "precompute: %s", hl_context_last_error(ctx));
        remove(path);
        if (t) {
            float *dense = xmalloc((size_t)g->ncoef * sizeof *dense);
            hl_transport_query_row(t, v, dense);
            const double B = dot_ff(dense, WL, g->ncoef);
            printf("ray offset, contact through hl_precompute's default (file offset %g): B %.6f, exact %.6f\n",
                   (double)t->info.ray_offset, B, exact);
            hl_check_error("ray offset, contact through hl_precompute's default: |B - exact|", fabs(B - exact), tol);
            HL_CHECK(t->info.ray_offset == 0.0f, "the file must record the robust offset as 0");
            free(dense);
            hl_transport_destroy(t);
        }
        hl_mesh_destroy(m);
    }
    /* the scenes must tell the two apart, or they test nothing */
    printf("ray offset: worst error with the robust offset %.3g, least with the old default %.3g\n", worst_new,
           least_old);
    snprintf(what, sizeof what, "ray offset: the old default's least error (%.3g) must exceed the tolerance "
             "(the scenes show its leak)", least_old);
    hl_check_error(what, least_old > tol ? 0.0 : 1.0, 0.0);

    /* No self-shadowing (acne) with the robust offset: a tessellated plane
     * and, on its own, a closed box, far from the origin, at every scale,
     * as built and turned 37 degrees about (1, 2, 3) (faces that no axis
     * is normal to): no ray of a vertex inside a face may be blocked above
     * its horizon. (Origins exactly on the vertices block 4e5 such rays.) */
    uint32_t acne = 0, checked = 0;
    static const double shifts[3] = {0.0, 100.0, 1e4};
    double turn[9];
    {
        double ax[3] = {1, 2, 3}, an = 37.0 * PI / 180.0, c = cos(an), s1 = sin(an);
        normalize3(ax);
        const double x = ax[0], y = ax[1], z = ax[2];
        const double R9[9] = {c + x * x * (1 - c),     x * y * (1 - c) - z * s1, x * z * (1 - c) + y * s1,
                              y * x * (1 - c) + z * s1, c + y * y * (1 - c),     y * z * (1 - c) - x * s1,
                              z * x * (1 - c) - y * s1, z * y * (1 - c) + x * s1, c + z * z * (1 - c)};
        memcpy(turn, R9, sizeof turn);
    }
    for (int is = 0; is < 3; is++)
        for (int ish = 0; ish < 3; ish++)
            for (int shape = 0; shape < 4; shape++) {
                const double *rot = shape >= 2 ? turn : NULL;
                mesh_build *b = xcalloc(1, sizeof *b);
                const double sh = shifts[ish];
                if (shape % 2 == 0)
                    for (int i = 0; i < 6; i++)
                        for (int j = 0; j < 6; j++) {
                            const double x0 = sh - 1.0 + i / 3.0, z0 = -1.0 + j / 3.0, x1 = x0 + 1 / 3.0,
                                         z1 = z0 + 1 / 3.0;
                            const double c[4][3] = {{x0, 0, z0}, {x0, 0, z1}, {x1, 0, z1}, {x1, 0, z0}};
                            mb_quad_fan(b, c, (const double[3]){0, 1, 0});
                        }
                else
                    mb_box(b, (const double[3]){sh - 0.5, 3.0, -0.5}, (const double[3]){sh + 0.5, 4.0, 0.5});
                hl_mesh *m = mb_mesh(ctx, b, scales[is], rot);
                hl_rt *rt = NULL;
                if (hl_rt_create(ctx, m, &rt) != HL_OK) exit(1);
                uint32_t here = 0;
                /* the fans' centres: every fifth vertex made (four corners,
                   then the centre), whose normal is its face's */
                for (uint32_t i = 4; i < b->nv; i += 5) {
                    const double p[3] = {b->P[3 * i], b->P[3 * i + 1], b->P[3 * i + 2]};
                    const double n[3] = {b->Nn[3 * i], b->Nn[3 * i + 1], b->Nn[3 * i + 2]};
                    here += blocked_above(ctx, rt, g, m, find_vertex(m, p, n, scales[is], rot));
                    checked++;
                }
                printf("ray offset, acne: %s%s %g from the origin, x %g: %u rays above the horizon blocked\n",
                       shape % 2 ? "box" : "plane", rot ? " (turned)" : "", sh * scales[is], scales[is], here);
                acne += here;
                hl_rt_destroy(rt);
                hl_mesh_destroy(m);
                free(b);
            }
    snprintf(what, sizeof what, "ray offset, acne: rays above the horizon blocked at %u face vertices", checked);
    hl_check_error(what, (double)acne, 0.0);
    free(sc);
    free(L);
    free(WL);
    hl_geom_destroy(g);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"roundtrip", case_roundtrip}, {"parseval", case_parseval}, {"slots", case_slots},
        {"solid_angle", case_solid_angle}, {"mapping", case_mapping}, {"table", case_table},
        {"furnace", case_furnace}, {"cap", case_cap}, {"ray_offset", case_ray_offset}, {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
