/* sh.c - real spherical harmonics about +Y (sh.h), Gauss-Legendre rules,
 * and the integrals of the harmonics over the paraboloid maps' texels.
 *
 * Depends on core (threads, allocation) and libm; the paraboloid layout
 * is docs/CONVENTIONS.md's (as maps/geom.c: col along s, row along t).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sh.h"

/* sqrt 2, the factor of the m != 0 real harmonics (SH_SQRT2 is not C11) */
#define SH_SQRT2 1.41421356237309504880

/* Newton steps for a Gauss-Legendre node: from the asymptotic guess it
 * converges in 3 to 5 steps; the loop stops at 1e-15 before this cap. */
#define SH_NEWTON_STEPS 100

int hl_sh_tables_init(hl_sh_tables *tab, uint32_t order)
{
    if (order < 1 || order > HL_SH_MAX_ORDER) return 0;
    memset(tab, 0, sizeof *tab);
    tab->order = order;
    const uint32_t M = HL_SH_MAX_ORDER;
    /* P~_m^m = -sqrt((2m + 1) / 2m) sin(theta) P~_{m-1}^{m-1}, P~_0^0 = 1 / sqrt(4 pi);
       kept divided by sin^m theta, the sine's powers come from (x + i z)^m */
    tab->mm[0] = 1.0 / sqrt(4.0 * HL_PI);
    for (uint32_t m = 1; m < order; m++) tab->mm[m] = -sqrt((2.0 * m + 1.0) / (2.0 * m)) * tab->mm[m - 1];
    /* P~_l^m = a (y P~_{l-1}^m - b P~_{l-2}^m), with
       a = sqrt((4 l^2 - 1) / (l^2 - m^2)), b = sqrt(((l - 1)^2 - m^2) / (4 (l - 1)^2 - 1)) */
    for (uint32_t m = 0; m < order; m++)
        for (uint32_t l = m + 1; l < order; l++) {
            double L = l, mm = m;
            tab->a[l * M + m] = sqrt((4.0 * L * L - 1.0) / (L * L - mm * mm));
            tab->b[l * M + m] = sqrt(((L - 1.0) * (L - 1.0) - mm * mm) / (4.0 * (L - 1.0) * (L - 1.0) - 1.0));
        }
    return 1;
}

void hl_sh_eval(const hl_sh_tables *tab, const double d[3], double *Y)
{
    const uint32_t n = tab->order, M = HL_SH_MAX_ORDER;
    const double x = d[0], y = d[1], z = d[2];
    double cr = 1.0, ci = 0.0; /* (x + i z)^m = sin^m theta e^{i m phi} */
    for (uint32_t m = 0; m < n; m++) {
        if (m > 0) {
            double r = cr * x - ci * z;
            ci = cr * z + ci * x;
            cr = r;
        }
        const double fc = m ? SH_SQRT2 * cr : 1.0, fs = SH_SQRT2 * ci;
        double p2 = 0.0, p1 = tab->mm[m]; /* P~_{l-2}^m, P~_{l-1}^m (over sin^m) */
        for (uint32_t l = m; l < n; l++) {
            double p;
            if (l == m) p = p1;
            else {
                p = tab->a[l * M + m] * (y * p1 - tab->b[l * M + m] * p2);
                p2 = p1;
                p1 = p;
            }
            const uint32_t k = l * l + l;
            Y[k + m] = p * fc;
            if (m) Y[k - m] = p * fs;
        }
    }
}

void hl_sh_gauss(uint32_t Q, double *x, double *w)
{
    for (uint32_t i = 0; i < Q; i++) {
        double u = cos(HL_PI * (i + 0.75) / (Q + 0.5)), dp = 1.0;
        for (int it = 0; it < SH_NEWTON_STEPS; it++) {
            double p0 = 1.0, p1 = u; /* P_0, P_1, then up to P_Q */
            for (uint32_t k = 2; k <= Q; k++) {
                double p = ((2.0 * k - 1.0) * u * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p;
            }
            dp = Q * (u * p1 - p0) / (u * u - 1.0);
            double du = p1 / dp;
            u -= du;
            if (fabs(du) < 1e-15) break;
        }
        x[i] = u;
        w[i] = 2.0 / ((1.0 - u * u) * dp * dp);
    }
}

/* Sorts the few breakpoints (insertion). */
static void sort_small(double *v, int n)
{
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j] < v[j - 1]; j--) {
            double t = v[j];
            v[j] = v[j - 1];
            v[j - 1] = t;
        }
}

uint32_t hl_sh_texel_points(uint32_t N, int map, uint32_t col, uint32_t row, uint32_t Q, double *pts)
{
    const double h = 2.0 / N, s0 = -1.0 + col * h, t0 = -1.0 + row * h, s1 = s0 + h, t1 = t0 + h;
    const double ns = s0 > 0 ? s0 : (s1 < 0 ? s1 : 0), nt = t0 > 0 ? t0 : (t1 < 0 ? t1 : 0);
    if (ns * ns + nt * nt >= 1.0) return 0;
    /* The outer variable u is the one whose centre is nearer 0: along it
       the rim's limit sqrt(1 - u^2) stays far from its branch point. */
    const int swap = fabs(s0 + s1) > fabs(t0 + t1);
    const double a0 = swap ? t0 : s0, a1 = swap ? t1 : s1, b0 = swap ? s0 : t0, b1 = swap ? s1 : t1;
    /* cuts where the rim crosses the inner edges: sqrt(1 - u^2) = |b| */
    double cut[2 + 4];
    int nc = 0;
    cut[nc++] = a0;
    const double bs[2] = {b0, b1};
    for (int i = 0; i < 2; i++) {
        double r = 1.0 - bs[i] * bs[i];
        if (r <= 0.0) continue;
        r = sqrt(r);
        if (r > a0 && r < a1) cut[nc++] = r;
        if (-r > a0 && -r < a1) cut[nc++] = -r;
    }
    cut[nc++] = a1;
    sort_small(cut, nc);
    double gx[HL_SH_MAX_QUAD], gw[HL_SH_MAX_QUAD];
    hl_sh_gauss(Q, gx, gw);
    const double ysign = map == 0 ? 1.0 : -1.0;
    uint32_t n = 0;
    for (int p = 0; p + 1 < nc; p++) {
        const double p0 = cut[p], p1 = cut[p + 1], hu = 0.5 * (p1 - p0);
        if (hu <= 0.0) continue;
        for (uint32_t i = 0; i < Q; i++) {
            const double u = p0 + hu * (gx[i] + 1.0), c = sqrt(fmax(0.0, 1.0 - u * u));
            const double lo = fmax(b0, -c), hi = fmin(b1, c), hv = 0.5 * (hi - lo);
            if (hv <= 0.0) continue;
            for (uint32_t j = 0; j < Q; j++) {
                const double v = lo + hv * (gx[j] + 1.0);
                const double s = swap ? v : u, t = swap ? u : v, r2 = s * s + t * t, k = 1.0 / (1.0 + r2);
                double *o = pts + 4 * (size_t)n++;
                o[0] = 2.0 * s * k;
                o[1] = ysign * (1.0 - r2) * k;
                o[2] = 2.0 * t * k;
                o[3] = gw[i] * hu * gw[j] * hv * 4.0 * k * k;
            }
        }
    }
    return n;
}

/* The texel integrals, texels handed out one at a time to the threads. */
typedef struct sh_job {
    uint32_t N, Q, count;
    const hl_sh_tables *tab;
    double *Ybar;
    atomic_uint next;
    atomic_int failed;
} sh_job;

static void *sh_worker(void *arg)
{
    sh_job *J = arg;
    const uint32_t ntex = 2 * J->N * J->N, cnt = J->count;
    double *pts = malloc((size_t)HL_SH_MAX_PIECES * J->Q * J->Q * 4 * sizeof(double));
    double *Y = malloc((size_t)cnt * sizeof(double));
    if (!pts || !Y) {
        atomic_store(&J->failed, 1);
        free(pts);
        free(Y);
        return NULL;
    }
    for (;;) {
        const uint32_t j = atomic_fetch_add(&J->next, 1u);
        if (j >= ntex) break;
        const int map = (int)(j / (J->N * J->N));
        const uint32_t row = (j / J->N) % J->N, col = j % J->N;
        const uint32_t np = hl_sh_texel_points(J->N, map, col, row, J->Q, pts);
        double *out = J->Ybar + (size_t)j * cnt;
        memset(out, 0, (size_t)cnt * sizeof(double));
        for (uint32_t p = 0; p < np; p++) {
            hl_sh_eval(J->tab, pts + 4 * (size_t)p, Y);
            const double w = pts[4 * (size_t)p + 3];
            for (uint32_t k = 0; k < cnt; k++) out[k] += w * Y[k];
        }
    }
    free(pts);
    free(Y);
    return NULL;
}

hl_result hl_sh_texel_integrals(hl_context *ctx, uint32_t N, uint32_t order, uint32_t Q, double **out)
{
    *out = NULL;
    hl_sh_tables *tab = hl_malloc(ctx, sizeof *tab, "spherical-harmonic tables");
    if (!tab) return HL_ERR_OUT_OF_MEMORY;
    if (!hl_sh_tables_init(tab, order) || Q < 1 || Q > HL_SH_MAX_QUAD || N < 2 || N > 4096) {
        free(tab);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "spherical harmonics: order %u (1 to %u), %u quadrature points (1 to %u), N %u", order,
                       HL_SH_MAX_ORDER, Q, HL_SH_MAX_QUAD, N);
    }
    sh_job J = {.N = N, .Q = Q, .count = hl_sh_count(order), .tab = tab};
    atomic_init(&J.next, 0u);
    atomic_init(&J.failed, 0);
    J.Ybar = hl_alloc_big(ctx, (size_t)2 * N * N * J.count * sizeof(double), "the texels' harmonic integrals");
    if (!J.Ybar) {
        free(tab);
        return HL_ERR_OUT_OF_MEMORY;
    }
    hl_run_threads(ctx && ctx->threads > 0 ? ctx->threads : 1, sh_worker, &J);
    free(tab);
    if (atomic_load(&J.failed)) {
        hl_free_big(J.Ybar);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the texels' harmonic integrals");
    }
    *out = J.Ybar;
    return HL_OK;
}

void hl_sh_project(const double *Ybar, uint32_t ntex, uint32_t count, const float *L, size_t stride, double *l)
{
    memset(l, 0, (size_t)count * sizeof(double));
    for (uint32_t j = 0; j < ntex; j++) {
        const double v = L[(size_t)j * stride];
        if (v == 0.0) continue;
        const double *y = Ybar + (size_t)j * count;
        for (uint32_t k = 0; k < count; k++) l[k] += v * y[k];
    }
}

hl_result hl_sh_matrix(hl_context *ctx, uint32_t N, uint32_t order, int per_solid_angle, float **out)
{
    *out = NULL;
    double *Ybar = NULL;
    hl_result r = hl_sh_texel_integrals(ctx, N, order, HL_SH_QUAD, &Ybar);
    if (r != HL_OK) return r;
    const uint32_t ns = hl_sh_count(order), stride = hl_sh_stride(order), ntex = 2 * N * N;
    float *Y = hl_alloc_big(ctx, (size_t)ntex * stride * sizeof(float), "the spherical-harmonic projection");
    if (!Y) {
        hl_free_big(Ybar);
        return HL_ERR_OUT_OF_MEMORY;
    }
    const double s4pi = sqrt(4.0 * HL_PI);
    for (uint32_t j = 0; j < ntex; j++) {
        const double *y = Ybar + (size_t)j * ns, om = s4pi * y[0];
        float *o = Y + (size_t)j * stride;
        memset(o, 0, (size_t)stride * sizeof(float));
        /* a texel outside the disc has no footprint: its row stays zero */
        if (per_solid_angle && !(om > 0.0)) continue;
        const double scale = per_solid_angle ? 1.0 / om : 1.0;
        for (uint32_t k = 0; k < ns; k++) o[k] = (float)(y[k] * scale);
    }
    hl_free_big(Ybar);
    *out = Y;
    return HL_OK;
}

void hl_sh_rotate_y(uint32_t order, double angle, double *c)
{
    for (uint32_t l = 1; l < order; l++)
        for (uint32_t m = 1; m <= l; m++) {
            const uint32_t k = l * l + l;
            const double cs = c[k + m], sn = c[k - m], ca = cos(m * angle), sa = sin(m * angle);
            /* cos(m (phi - a)) = cos m phi cos m a + sin m phi sin m a, and so on */
            c[k + m] = cs * ca - sn * sa;
            c[k - m] = cs * sa + sn * ca;
        }
}
