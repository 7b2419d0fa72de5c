/* geom.c - paraboloid and cube maps, solid angles, the cube-to-paraboloid
 * footprint table and the Haar slot order. Plain C, no third-party code.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geom.h"

/* Subsamples per side of a paraboloid texel when splitting its footprint
 * across cube texels; enough to put each part's area within a percent. */
#define HL_C2P_SUB 8
/* Strips for the rim texels' in-disc solid angle (inner integral exact). */
#define HL_RIM_STRIPS 512

void hl_para_texel_dir(uint32_t N, int map, uint32_t col, uint32_t row, float d[3])
{
    double s = -1.0 + (col + 0.5) * 2.0 / N;
    double t = -1.0 + (row + 0.5) * 2.0 / N;
    double r2 = s * s + t * t, k = 1.0 / (1.0 + r2);
    d[0] = (float)(2.0 * s * k);
    d[1] = (float)((map == 0 ? 1.0 : -1.0) * (1.0 - r2) * k);
    d[2] = (float)(2.0 * t * k);
}

void hl_dir_to_para(const float d[3], int *map, float *s, float *t)
{
    double len = sqrt((double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2]);
    double x = d[0] / len, y = d[1] / len, z = d[2] / len;
    *map = y >= 0.0 ? 0 : 1;
    double k = 1.0 / (1.0 + fabs(y));
    *s = (float)(x * k);
    *t = (float)(z * k);
}

/* F of docs/CONVENTIONS.md: Omega of [0,s]x[0,t] (signed) for rectangles in the disc. */
static double omega_F(double s, double t)
{
    double a = sqrt(1.0 + s * s), b = sqrt(1.0 + t * t);
    return 2.0 * (s / a * atan(t / a) + t / b * atan(s / b));
}

/* Integral over t in [t0,t1] of 4 / (a2 + t^2)^2 dt. */
static double strip_integral(double a2, double t0, double t1)
{
    double a = sqrt(a2);
    double F1 = t1 / (2.0 * a2 * (a2 + t1 * t1)) + atan(t1 / a) / (2.0 * a2 * a);
    double F0 = t0 / (2.0 * a2 * (a2 + t0 * t0)) + atan(t0 / a) / (2.0 * a2 * a);
    return 4.0 * (F1 - F0);
}

double hl_para_rect_omega(double s0, double s1, double t0, double t1)
{
    /* nearest and farthest points of the rectangle from the origin */
    double ns = s0 > 0 ? s0 : (s1 < 0 ? s1 : 0), nt = t0 > 0 ? t0 : (t1 < 0 ? t1 : 0);
    double fs = fabs(s0) > fabs(s1) ? s0 : s1, ft = fabs(t0) > fabs(t1) ? t0 : t1;
    if (ns * ns + nt * nt >= 1.0) return 0.0;
    if (fs * fs + ft * ft <= 1.0)
        return omega_F(s1, t1) - omega_F(s0, t1) - omega_F(s1, t0) + omega_F(s0, t0);
    /* rim: exact in t, midpoint in s */
    double sum = 0.0, h = (s1 - s0) / HL_RIM_STRIPS;
    for (int k = 0; k < HL_RIM_STRIPS; k++) {
        double s = s0 + (k + 0.5) * h;
        double lim2 = 1.0 - s * s;
        if (lim2 <= 0.0) continue;
        double lim = sqrt(lim2);
        double a = t0 > -lim ? t0 : -lim, b = t1 < lim ? t1 : lim;
        if (b > a) sum += strip_integral(1.0 + s * s, a, b) * h;
    }
    return sum;
}

void hl_cube_face_dir(int face, float sc, float tc, float d[3])
{
    switch (face) {
    case 0: d[0] = 1.0f; d[1] = -tc; d[2] = -sc; break;
    case 1: d[0] = -1.0f; d[1] = -tc; d[2] = sc; break;
    case 2: d[0] = sc; d[1] = 1.0f; d[2] = tc; break;
    case 3: d[0] = sc; d[1] = -1.0f; d[2] = -tc; break;
    case 4: d[0] = sc; d[1] = -tc; d[2] = 1.0f; break;
    default: d[0] = -sc; d[1] = -tc; d[2] = -1.0f; break;
    }
}

uint32_t hl_dir_to_cube(const float d[3], uint32_t C)
{
    float ax = fabsf(d[0]), ay = fabsf(d[1]), az = fabsf(d[2]);
    int face;
    float sc, tc, ma;
    if (ax >= ay && ax >= az) {
        ma = ax; tc = -d[1];
        if (d[0] >= 0) { face = 0; sc = -d[2]; } else { face = 1; sc = d[2]; }
    } else if (ay >= az) {
        ma = ay; sc = d[0];
        if (d[1] >= 0) { face = 2; tc = d[2]; } else { face = 3; tc = -d[2]; }
    } else {
        ma = az; tc = -d[1];
        if (d[2] >= 0) { face = 4; sc = d[0]; } else { face = 5; sc = -d[0]; }
    }
    float u = (sc / ma + 1.0f) * 0.5f * (float)C, v = (tc / ma + 1.0f) * 0.5f * (float)C;
    int col = (int)floorf(u), row = (int)floorf(v);
    if (col < 0) col = 0;
    if (row < 0) row = 0;
    if (col >= (int)C) col = (int)C - 1;
    if (row >= (int)C) row = (int)C - 1;
    return (uint32_t)face * C * C + (uint32_t)row * C + (uint32_t)col;
}

/* Slot within one map of the coefficient at Mallat position (row, col). */
static uint32_t mallat_slot(uint32_t N, uint32_t row, uint32_t col)
{
    if (N < 16) return row * N + col; /* both maps fit one block */
    uint32_t T = N / 16;
    if (row < T && col < T) return (row * T + col) * HL_BLOCK; /* coarse: slot 0 */
    uint32_t m = row > col ? row : col, s = 2;
    while (s <= m) s *= 2; /* s/2 <= max(row, col) < s */
    uint32_t h = s / 2, type, i, j;
    if (row < h) { type = 0; i = row; j = col - h; }
    else if (col < h) { type = 1; i = row - h; j = col; }
    else { type = 2; i = row - h; j = col - h; }
    uint32_t w = 2 * N / s;     /* support side in texels: 16, 8, 4 or 2 */
    uint32_t n = 16 / w;        /* nodes per tile side at this level */
    uint32_t L = w == 16 ? 0 : w == 8 ? 1 : w == 4 ? 2 : 3;
    static const uint32_t level_base[4] = {0, 1, 5, 21};
    uint32_t tile = (i / n) * T + (j / n);
    uint32_t local = level_base[L] + (i % n) * n + (j % n);
    return tile * HL_BLOCK + 1 + 3 * local + type;
}

void hl_geom_support(uint32_t N, uint32_t row, uint32_t col, uint32_t *r0, uint32_t *c0, uint32_t *w)
{
    if (row == 0 && col == 0) { /* the scaling coefficient */
        *r0 = *c0 = 0;
        *w = N;
        return;
    }
    uint32_t m = row > col ? row : col, s = 2;
    while (s <= m) s *= 2;
    uint32_t h = s / 2;
    uint32_t i = row >= h ? row - h : row, j = col >= h ? col - h : col;
    *w = 2 * N / s;
    *r0 = i * *w;
    *c0 = j * *w;
}

static void build_cube_dirs(hl_geom *g)
{
    uint32_t C = g->C;
    for (int f = 0; f < 6; f++)
        for (uint32_t r = 0; r < C; r++)
            for (uint32_t c = 0; c < C; c++) {
                float d[3];
                hl_cube_face_dir(f, 2.0f * ((float)c + 0.5f) / (float)C - 1.0f,
                                 2.0f * ((float)r + 0.5f) / (float)C - 1.0f, d);
                float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                float *o = g->cube_dirs + 4 * ((size_t)f * C * C + r * C + c);
                o[0] = d[0] / l; o[1] = d[1] / l; o[2] = d[2] / l; o[3] = 0.0f;
            }
}

typedef struct c2p_acc { uint32_t cube; double m[3], w; } c2p_acc;

/* Splits each paraboloid texel's footprint into sub-samples, groups them by
 * the cube texel they fall in, and scales the group's first moment so the
 * texel's parts add up to its exact solid angle. */
static hl_result build_c2p(hl_context *ctx, hl_geom *g)
{
    const uint32_t N = g->N, Q = HL_C2P_SUB;
    size_t cap = (size_t)g->ncoef * 4 + 1024, n = 0;
    g->c2p = hl_malloc(ctx, cap * sizeof *g->c2p, "the cube-to-paraboloid table");
    if (!g->c2p) return HL_ERR_OUT_OF_MEMORY;
    c2p_acc acc[HL_C2P_SUB * HL_C2P_SUB];
    const double h = 2.0 / N;
    for (int map = 0; map < 2; map++)
        for (uint32_t row = 0; row < N; row++)
            for (uint32_t col = 0; col < N; col++) {
                uint32_t j = (uint32_t)map * N * N + row * N + col;
                g->c2p_start[j] = (uint32_t)n;
                double s0 = -1.0 + col * h, t0 = -1.0 + row * h;
                double om = hl_para_rect_omega(s0, s0 + h, t0, t0 + h);
                g->omega[j] = (float)om;
                if (om <= 0.0) continue;
                int na = 0;
                double wsum = 0.0;
                for (uint32_t a = 0; a < Q; a++)
                    for (uint32_t b = 0; b < Q; b++) {
                        double s = s0 + (b + 0.5) * h / Q, t = t0 + (a + 0.5) * h / Q;
                        double r2 = s * s + t * t;
                        if (r2 > 1.0) continue;
                        double k = 1.0 / (1.0 + r2), dw = 4.0 * k * k;
                        float d[3] = {(float)(2 * s * k), (float)((map ? -1 : 1) * (1 - r2) * k), (float)(2 * t * k)};
                        uint32_t cube = hl_dir_to_cube(d, g->C);
                        int e = 0;
                        while (e < na && acc[e].cube != cube) e++;
                        if (e == na) { memset(&acc[e], 0, sizeof acc[e]); acc[e].cube = cube; na++; }
                        for (int q = 0; q < 3; q++) acc[e].m[q] += d[q] * dw;
                        acc[e].w += dw;
                        wsum += dw;
                    }
                if (na == 0) {
                    /* a sliver of the rim that no sub-sample hit: use the
                       in-disc point nearest the texel centre (the centre
                       itself lies outside, in the other hemisphere) */
                    double cs = s0 + 0.5 * h, ct = t0 + 0.5 * h, r = sqrt(cs * cs + ct * ct);
                    double k = (1.0 - 1e-7) / r, s = cs * k, t = ct * k, r2 = s * s + t * t, q = 1.0 / (1.0 + r2);
                    float d[3] = {(float)(2 * s * q), (float)((map ? -1 : 1) * (1 - r2) * q), (float)(2 * t * q)};
                    acc[0].cube = hl_dir_to_cube(d, g->C);
                    for (int c = 0; c < 3; c++) acc[0].m[c] = d[c];
                    acc[0].w = wsum = 1.0;
                    na = 1;
                }
                if (n + (size_t)na > cap) {
                    cap *= 2;
                    hl_c2p_entry *p = realloc(g->c2p, cap * sizeof *p);
                    if (!p) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory growing the cube-to-paraboloid table");
                    g->c2p = p;
                }
                /* ascending cube index: the order both table forms add in */
                for (int x = 1; x < na; x++)
                    for (int y = x; y > 0 && acc[y - 1].cube > acc[y].cube; y--) {
                        c2p_acc tmp = acc[y];
                        acc[y] = acc[y - 1];
                        acc[y - 1] = tmp;
                    }
                double scale = om / wsum;
                for (int e = 0; e < na; e++) {
                    hl_c2p_entry *o = &g->c2p[n++];
                    o->mx = (float)(acc[e].m[0] * scale);
                    o->my = (float)(acc[e].m[1] * scale);
                    o->mz = (float)(acc[e].m[2] * scale);
                    o->index = acc[e].cube;
                }
            }
    g->c2p_start[g->ncoef] = (uint32_t)n;
    g->nentries = (uint32_t)n;
    /* the same entries by cube texel (a stable counting sort keeps them in
       paraboloid-texel order within a cube texel) */
    g->p2c_start = hl_calloc(ctx, (size_t)g->ncube + 1, sizeof(uint32_t), "the transposed table");
    g->p2c = hl_malloc(ctx, n * sizeof *g->p2c, "the transposed table");
    if (!g->p2c_start || !g->p2c) return HL_ERR_OUT_OF_MEMORY;
    for (size_t e = 0; e < n; e++) g->p2c_start[g->c2p[e].index + 1]++;
    for (uint32_t c = 0; c < g->ncube; c++) g->p2c_start[c + 1] += g->p2c_start[c];
    uint32_t *fill = hl_malloc(ctx, (size_t)g->ncube * sizeof(uint32_t), "the transposed table");
    if (!fill) return HL_ERR_OUT_OF_MEMORY;
    memcpy(fill, g->p2c_start, (size_t)g->ncube * sizeof(uint32_t));
    for (uint32_t j = 0; j < g->ncoef; j++)
        for (uint32_t e = g->c2p_start[j]; e < g->c2p_start[j + 1]; e++) {
            hl_c2p_entry t = g->c2p[e];
            uint32_t c = t.index;
            t.index = j;
            g->p2c[fill[c]++] = t;
        }
    free(fill);
    return HL_OK;
}

hl_result hl_geom_create(hl_context *ctx, uint32_t N, uint32_t C, hl_geom **out)
{
    *out = NULL;
    if (N < 8 || N > 256 || (N & (N - 1)))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "N = %u: the paraboloid resolution must be a power of two from 8 to 256", N);
    if (C < 4 || C > 512)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "C = %u: the cubemap resolution must be from 4 to 512", C);
    hl_geom *g = hl_calloc(ctx, 1, sizeof *g, "geometry tables");
    if (!g) return HL_ERR_OUT_OF_MEMORY;
    g->N = N;
    g->C = C;
    g->ncoef = 2 * N * N;
    g->nblocks = (g->ncoef + HL_BLOCK - 1) / HL_BLOCK;
    g->ncube = 6 * C * C;
    g->cube_dirs = hl_malloc(ctx, (size_t)g->ncube * 4 * sizeof(float), "cube directions");
    g->omega = hl_malloc(ctx, (size_t)g->ncoef * sizeof(float), "texel solid angles");
    g->c2p_start = hl_malloc(ctx, ((size_t)g->ncoef + 1) * sizeof(uint32_t), "table rows");
    g->slot_of_mallat = hl_malloc(ctx, (size_t)N * N * sizeof(uint32_t), "Haar slot order");
    hl_result r = HL_ERR_OUT_OF_MEMORY;
    if (g->cube_dirs && g->omega && g->c2p_start && g->slot_of_mallat) {
        build_cube_dirs(g);
        for (uint32_t row = 0; row < N; row++)
            for (uint32_t col = 0; col < N; col++) g->slot_of_mallat[row * N + col] = mallat_slot(N, row, col);
        r = build_c2p(ctx, g);
    }
    if (r != HL_OK) {
        hl_geom_destroy(g);
        return r;
    }
    *out = g;
    return HL_OK;
}

void hl_geom_destroy(hl_geom *g)
{
    if (!g) return;
    free(g->cube_dirs);
    free(g->omega);
    free(g->c2p_start);
    free(g->c2p);
    free(g->p2c_start);
    free(g->p2c);
    free(g->slot_of_mallat);
    free(g);
}
