/* test_cube.c - Haar wavelets over the six cube faces (host/src/cube) and
 * bench-basis's cube bases (haarlight_tools.h):
 *   transform  the forward transform then its inverse gives the texels back,
 *              and keeps the sum of squares (Parseval), Cq = 2, 8, 32;
 *              one basis function's coefficients are a unit vector
 *   taps       each face texel's taps add up to its exact solid angle (the
 *              quadrature in azimuth), and all of them to 4 pi; a constant
 *              map gives every texel its value
 *   rows       the own-footprint cube rows' quadrature: each visibility
 *              texel's solid angle, an unshadowed vertex's row summing to
 *              1, the same row grouped on two face sides
 *   constant   bench-basis under a constant map: the cube Haar at every
 *              term, under each selection, and at the 6 face scaling terms
 *              alone gives the exact (paraboloid) colours; SH rows cut to
 *              12 bytes (the first harmonic) do too; cube rows cut to 12
 *              bytes (no entry) give black; the byte counts
 *   halfspace  light from a half-space (x, y or z > 0): every grid splits
 *              exactly along the plane, so the cube at every term gives
 *              the paraboloid's exact colours (its faces' orientation)
 *   bad        cube sides that are no power of two, too large, or do not
 *              divide C are refused, with the reason; with C = 9 (no
 *              power of two divides it) the cube bases have no terms and
 *              the others go on
 */
#define _POSIX_C_SOURCE 200809L
#include <unistd.h>

#include "hl_test.h"
#include "haarlight_tools.h"
#include "cube.h"

/* A repeatable pseudo-random number in [-1, 1). */
static double rnd(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return (*s >> 8) / 8388608.0 - 1.0;
}

static void t_transform(void)
{
    static const uint32_t sides[] = {2, 8, 32};
    for (int k = 0; k < 3; k++) {
        const uint32_t Cq = sides[k], n = 6 * Cq * Cq;
        float *x = malloc((size_t)n * 4), *y = malloc((size_t)n * 4), *c = malloc((size_t)n * 4);
        uint32_t s = 12345u + Cq;
        double sx = 0.0, sc = 0.0, worst = 0.0, big = 0.0;
        for (uint32_t i = 0; i < n; i++) x[i] = (float)rnd(&s), sx += (double)x[i] * x[i], big = fmax(big, fabsf(x[i]));
        memcpy(y, x, (size_t)n * 4);
        hl_cube_haar(Cq, y, c);
        for (uint32_t i = 0; i < n; i++) sc += (double)c[i] * c[i];
        hl_cube_haar_inverse(Cq, c, y);
        for (uint32_t i = 0; i < n; i++) worst = fmax(worst, fabs((double)y[i] - x[i]));
        char what[128];
        snprintf(what, sizeof what, "Cq = %u: inverse of the forward transform against the texels (relative)", Cq);
        hl_check_error(what, worst / big, 1e-6);
        snprintf(what, sizeof what, "Cq = %u: Parseval, sum of squares of the coefficients against the texels' (relative)", Cq);
        hl_check_error(what, fabs(sc - sx) / sx, 1e-6);
        /* a single coefficient's inverse is a basis function: forward gives
           the unit vector back */
        double unit_err = 0.0;
        for (uint32_t j = 0; j < n; j += n / 7 + 1) {
            memset(c, 0, (size_t)n * 4);
            c[j] = 1.0f;
            hl_cube_haar_inverse(Cq, c, y);
            double norm = 0.0;
            for (uint32_t i = 0; i < n; i++) norm += (double)y[i] * y[i];
            hl_cube_haar(Cq, y, c);
            for (uint32_t i = 0; i < n; i++) unit_err = fmax(unit_err, fabs(c[i] - (i == j ? 1.0 : 0.0)));
            unit_err = fmax(unit_err, fabs(norm - 1.0));
        }
        snprintf(what, sizeof what, "Cq = %u: basis functions of unit norm, transformed back to unit vectors", Cq);
        hl_check_error(what, unit_err, 1e-6);
        free(x), free(y), free(c);
    }
}

static void t_taps(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    /* the cell grids of N = 16 and N = 64 (lighting.h: 8N x 4N) */
    static const uint32_t cases[][3] = {{8, 16, 128}, {32, 64, 512}, {64, 64, 512}};
    for (int k = 0; k < 3; k++) {
        const uint32_t Cq = cases[k][0], C = cases[k][1], wc = cases[k][2], hc = wc / 2;
        hl_cube_tables *ct = NULL;
        hl_result r = hl_cube_tables_create(ctx, Cq, C, wc, hc, &ct);
        HL_CHECK(r == HL_OK, "tables Cq = %u: %s", Cq, hl_context_last_error(ctx));
        if (r != HL_OK) continue;
        double worst = 0.0, tot = 0.0, om = 0.0;
        for (uint32_t q = 0; q < ct->ntex; q++) {
            worst = fmax(worst, fabs(ct->tap_total[q] - ct->omega[q]) / ct->omega[q]);
            tot += ct->tap_total[q], om += ct->omega[q];
        }
        char what[160];
        /* only the +-Y faces' grid lines fall between the azimuth
           quadrature's rays: held to the paraboloid taps' figure, 0.2% */
        snprintf(what, sizeof what, "Cq = %u, %u x %u cells: each texel's taps against its exact solid angle (relative)",
                 Cq, wc, hc);
        hl_check_error(what, worst, 2e-3);
        snprintf(what, sizeof what, "Cq = %u: all taps against 4 pi, and the texels' exact solid angles against 4 pi", Cq);
        hl_check_error(what, fmax(fabs(tot - 4 * HL_PI), fabs(om - 4 * HL_PI)) / (4 * HL_PI), 1e-12);
        float *cells = malloc((size_t)wc * hc * 16), *L = malloc((size_t)ct->ntex * 12);
        for (size_t i = 0; i < (size_t)wc * hc; i++)
            cells[4 * i] = 0.7f, cells[4 * i + 1] = 1.3f, cells[4 * i + 2] = 0.2f, cells[4 * i + 3] = 0.0f;
        hl_cube_lighting(ct, cells, L);
        double ce = 0.0, wsum = 0.0;
        uint32_t most = 0;
        for (uint32_t q = 0; q < ct->ntex; q++) {
            const uint32_t nt = ct->tap_start[q + 1] - ct->tap_start[q];
            double s = 0.0;
            for (uint32_t e = ct->tap_start[q]; e < ct->tap_start[q + 1]; e++) s += ct->taps[e].weight;
            most = nt > most ? nt : most;
            wsum = fmax(wsum, fabs(s - 1.0) / nt);
            for (int c = 0; c < 3; c++) ce = fmax(ce, fabs(L[(size_t)c * ct->ntex + q] - cells[c]) / cells[c]);
        }
        /* the weights are floats (each within 2^-24 relative) and the twin
           adds them in float: n taps, at most 2 n 2^-24 */
        snprintf(what, sizeof what, "Cq = %u: each texel's float tap weights' sum against 1, per tap", Cq);
        hl_check_error(what, wsum, 0x1p-24);
        snprintf(what, sizeof what, "Cq = %u: a constant map's texel means against its value (relative; %u taps at most)",
                 Cq, most);
        hl_check_error(what, ce, 2.0 * most * 0x1p-24);
        free(cells), free(L);
        hl_cube_tables_destroy(ct);
    }
    hl_context_destroy(ctx);
}

/* The own-footprint rows' quadrature (4 x 4 points a visibility texel, as
 * bench-basis uses it): each texel's points add up to its closed-form
 * solid angle; an unshadowed vertex's row adds up to 1 (the clamped
 * cosine over the hemisphere, over pi), the texels the horizon cuts
 * integrated by points on each side; and the same products grouped two
 * ways (Cq = C and Cq = C / 4) add up alike. */
static void t_rows(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    static const uint32_t sides[] = {16, 64};
    for (int k = 0; k < 2; k++) {
        const uint32_t C = sides[k];
        hl_cube_quad *cq = NULL;
        hl_result r = hl_cube_quad_create(ctx, C, 4, &cq);
        HL_CHECK(r == HL_OK, "quadrature C = %u: %s", C, hl_context_last_error(ctx));
        if (r != HL_OK) continue;
        double worst = 0.0;
        const double h = 2.0 / C;
        for (uint32_t c = 0; c < 6 * C * C; c++) {
            const uint32_t row = (c / C) % C, col = c % C;
            double om = 0.0;
            for (uint32_t p = 0; p < 16; p++) {
                const float *m = cq->m + ((size_t)c * 16 + p) * 3;
                om += sqrt((double)m[0] * m[0] + (double)m[1] * m[1] + (double)m[2] * m[2]);
            }
            const double ex = hl_cube_rect_omega(-1.0 + col * h, -1.0 + (col + 1) * h, -1.0 + row * h, -1.0 + (row + 1) * h);
            worst = fmax(worst, fabs(om - ex) / ex);
        }
        char what[160];
        snprintf(what, sizeof what, "C = %u: each texel's 4 x 4 points against its closed-form solid angle (relative)", C);
        hl_check_error(what, worst, 1e-6);
        uint8_t *vis = malloc((size_t)6 * C * C);
        float *T = malloc((size_t)6 * C * C * 4), *T4 = malloc((size_t)6 * C * C * 4);
        memset(vis, 1, (size_t)6 * C * C);
        static const float normals[4][3] = {{0, 1, 0}, {1, 0, 0}, {0.6f, 0.0f, 0.8f}, {0.48f, 0.6f, 0.64f}};
        double wsum = 0.0, wgroup = 0.0;
        for (int q = 0; q < 4; q++) {
            double s = 0.0, s4 = 0.0;
            hl_cube_rows_exact(cq, C, vis, (float)(1.0 / HL_PI), normals[q], T);
            hl_cube_rows_exact(cq, C / 4, vis, (float)(1.0 / HL_PI), normals[q], T4);
            for (uint32_t i = 0; i < 6 * C * C; i++) s += T[i];
            for (uint32_t i = 0; i < 6 * (C / 4) * (C / 4); i++) s4 += T4[i];
            wsum = fmax(wsum, fabs(s - 1.0)), wgroup = fmax(wgroup, fabs(s4 - s));
        }
        /* the horizon's texels hold a kink, integrated to about the
           texel's area squared, h^4 in all; the float sums add 1e-6 */
        snprintf(what, sizeof what, "C = %u: an unshadowed vertex's row sum against 1 (4 normals)", C);
        hl_check_error(what, wsum, h * h * h * h + 1e-6);
        snprintf(what, sizeof what, "C = %u: the row grouped on faces of side C / 4 against side C", C);
        hl_check_error(what, wgroup, 1e-6);
        free(vis), free(T), free(T4);
        hl_cube_quad_destroy(cq);
    }
    hl_context_destroy(ctx);
}

/* The tiny bunny on its ground (N = 16, cube side C) and a constant map. */
typedef struct fixture {
    hl_context *ctx;
    hl_mesh *mesh;
    hl_transport *t;
    hl_env *env;
    hl_basis_bench *bb; /* 64 vertices spread over the mesh, harmonics of order 4 */
} fixture;

static hl_result fixture_open(fixture *f, uint32_t C)
{
    char mesh_path[1024], path[1024], err[512];
    memset(f, 0, sizeof *f);
    snprintf(mesh_path, sizeof mesh_path, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    snprintf(path, sizeof path, "%s/cube_%ld.hlt", hl_test_env("HL_TMP", "/tmp"), (long)getpid());
    hl_context_desc cd = {.backend = HL_BACKEND_REFERENCE, .quiet = 1};
    hl_mesh_load_desc ld = {{0.8f, 0.6f, 0.4f}, 'y', 0};
    hl_precompute_desc d = {0};
    d.N = 16, d.C = C;
    hl_result r = hl_context_create(&cd, &f->ctx, err, sizeof err);
    if (r != HL_OK) return fprintf(stderr, "%s\n", err), r;
    r = hl_mesh_load(f->ctx, mesh_path, &ld, &f->mesh, NULL);
    if (r == HL_OK) r = hl_precompute(f->ctx, f->mesh, &d, path, NULL);
    if (r == HL_OK) r = hl_transport_load(f->ctx, path, &f->t);
    remove(path);
    float *rgb = calloc(64 * 32 * 3, sizeof(float));
    for (int i = 0; i < 64 * 32 * 3; i++) rgb[i] = i % 3 == 0 ? 0.7f : i % 3 == 1 ? 1.3f : 0.2f;
    if (r == HL_OK) r = hl_env_create(f->ctx, 64, 32, rgb, &f->env, NULL);
    free(rgb);
    uint32_t idx[64];
    for (uint32_t k = 0; k < 64 && r == HL_OK; k++) idx[k] = (uint32_t)((uint64_t)k * f->t->info.vertex_count / 64);
    if (r == HL_OK) r = hl_basis_bench_create(f->ctx, f->t, idx, 64, 4, &f->bb);
    HL_CHECK(r == HL_OK, "set-up: %s", f->ctx ? hl_context_last_error(f->ctx) : "no context");
    return r;
}

static void fixture_close(fixture *f)
{
    hl_basis_bench_destroy(f->bb);
    hl_env_destroy(f->env);
    hl_transport_destroy(f->t);
    hl_mesh_destroy(f->mesh);
    hl_context_destroy(f->ctx);
}

static void t_constant(void)
{
    fixture f;
    hl_result r = fixture_open(&f, 16);
    hl_basis_bench *bb = f.bb;
    const double *exact = NULL;
    if (r == HL_OK) r = hl_basis_bench_set_env(bb, f.env, &exact);
    if (r == HL_OK) {
        double c[64 * 3], big = 0.0, all = 0.0, six = 0.0, bytes = 0.0;
        const uint32_t Cq = hl_basis_bench_cube_side(bb), n = hl_basis_bench_count(bb, HL_BASIS_CUBE);
        HL_CHECK(Cq == 8 && n == 384, "default cube side %u (%u terms), expected 8 (384) for N = C = 16", Cq, n);
        for (int i = 0; i < 64 * 3; i++) big = fmax(big, fabs(exact[i]));
        for (hl_basis b = HL_BASIS_CUBE; b <= HL_BASIS_CUBE_TRANSPORT; b++) {
            r = hl_basis_bench_colours(bb, b, n, c);
            HL_CHECK(r == HL_OK, "%s at every term: %s", hl_basis_name(b), hl_context_last_error(f.ctx));
            for (int i = 0; i < 64 * 3 && r == HL_OK; i++) all = fmax(all, fabs(c[i] - exact[i]));
        }
        /* a constant map has only the six faces' scaling coefficients */
        r = hl_basis_bench_colours(bb, HL_BASIS_CUBE, 6, c);
        HL_CHECK(r == HL_OK, "cube at 6 terms: %s", hl_context_last_error(f.ctx));
        for (int i = 0; i < 64 * 3 && r == HL_OK; i++) six = fmax(six, fabs(c[i] - exact[i]));
        /* rows cut to bytes: SH's first harmonic alone (8 + 2 + 2 = 12
           bytes) and cube rows cut to nothing (8 + 2 x 2 bytes) */
        const uint32_t K = hl_basis_bench_entries(bb, HL_BASIS_CUBE, 1024);
        HL_CHECK(K == 384, "1024 bytes hold %u cube entries, expected all 384", K);
        HL_CHECK(hl_basis_bench_entries(bb, HL_BASIS_CUBE, 14) == 1, "14 bytes hold %u cube entries, expected 1",
                 hl_basis_bench_entries(bb, HL_BASIS_CUBE, 14));
        r = hl_basis_bench_colours_bytes(bb, HL_BASIS_SH, 16, 12, c);
        for (int i = 0; i < 64 * 3 && r == HL_OK; i++) bytes = fmax(bytes, fabs(c[i] - exact[i]));
        double none = 0.0;
        if (r == HL_OK) r = hl_basis_bench_colours_bytes(bb, HL_BASIS_CUBE, 6, 12, c);
        for (int i = 0; i < 64 * 3 && r == HL_OK; i++) none = fmax(none, fabs(c[i]));
        HL_CHECK(none == 0.0, "cube rows cut to 12 bytes (no entry) give light %g", none);
        HL_CHECK(r == HL_OK, "%s", hl_context_last_error(f.ctx));
        HL_CHECK(big > 0.1, "the exact colours are dark (%g)", big);
        /* the cube and paraboloid rows add the same float products in
           another order: float precision (about 1e-7 relative) */
        hl_check_error("constant map: cube Haar at all 384 terms, each selection, against the exact colours (relative)",
                       all / big, 1e-6);
        hl_check_error("constant map: cube Haar at the 6 face scaling terms against the exact colours (relative)",
                       six / big, 1e-6);
        hl_check_error("constant map: SH, rows cut to 12 bytes (the first harmonic), against the exact colours (relative)",
                       bytes / big, 1e-6);
        HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_CUBE, 385, c) == HL_ERR_INVALID_ARGUMENT, "385 cube terms accepted");
        HL_CHECK(hl_basis_bench_entries(bb, HL_BASIS_HAAR, 12) == 0, "12 bytes hold paraboloid entries");
        HL_CHECK(hl_basis_bench_entries(bb, HL_BASIS_SH, 1 << 20) == 16, "a large budget holds more than 16 harmonics");
    }
    fixture_close(&f);
}

/* Light from one half-space (x > 0, y > 0 or z > 0; W x H pixels, W a
 * multiple of 4 and H even so that the pixels' edges follow the planes):
 * the cells, the paraboloid texels (the horizon and s, t = 0) and the cube
 * texels (the faces' middle lines and edges) all split exactly along the
 * plane, so the cube at every term gives the exact colours again; a
 * face or a paraboloid turned or mirrored would not. */
static void t_halfspace(void)
{
    fixture f;
    hl_result r = fixture_open(&f, 16);
    hl_basis_bench *bb = f.bb;
    const uint32_t W = 64, H = 32;
    float *rgb = malloc((size_t)W * H * 12);
    for (int axis = 0; axis < 3 && r == HL_OK; axis++) {
        for (uint32_t y = 0; y < H; y++)
            for (uint32_t x = 0; x < W; x++) {
                const double th = HL_PI * (y + 0.5) / H, ph = 2.0 * HL_PI * ((x + 0.5) / W - 0.5);
                const double d[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
                for (int c = 0; c < 3; c++) rgb[3 * ((size_t)y * W + x) + c] = d[axis] > 0 ? 1.0f + 0.5f * (float)c : 0.0f;
            }
        hl_env *env = NULL;
        const double *exact = NULL;
        double c[64 * 3], big = 0.0, worst = 0.0;
        r = hl_env_create(f.ctx, W, H, rgb, &env, NULL);
        if (r == HL_OK) r = hl_basis_bench_set_env(bb, env, &exact);
        if (r == HL_OK) r = hl_basis_bench_colours(bb, HL_BASIS_CUBE, hl_basis_bench_count(bb, HL_BASIS_CUBE), c);
        for (int i = 0; i < 64 * 3 && r == HL_OK; i++) big = fmax(big, fabs(exact[i])), worst = fmax(worst, fabs(c[i] - exact[i]));
        HL_CHECK(r == HL_OK, "%s", hl_context_last_error(f.ctx));
        HL_CHECK(big > 0.1, "the exact colours are dark (%g)", big);
        char what[128];
        snprintf(what, sizeof what, "light from %c > 0: cube Haar at every term against the exact colours (relative)",
                 "xyz"[axis]);
        hl_check_error(what, worst / big, 1e-6);
        hl_env_destroy(env);
    }
    free(rgb);
    fixture_close(&f);
}

static void t_bad(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    static const uint32_t bad[][2] = {{3, 16}, {1, 16}, {1024, 1024}, {32, 48}, {16, 24}};
    for (int k = 0; k < 5; k++) {
        hl_cube_tables *ct = NULL;
        hl_result r = hl_cube_tables_create(ctx, bad[k][0], bad[k][1], 128, 64, &ct);
        HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && !ct, "cube side %u on C = %u accepted", bad[k][0], bad[k][1]);
        HL_CHECK(strstr(hl_context_last_error(ctx), "power of two") != NULL, "the reason is not given: %s",
                 hl_context_last_error(ctx));
        printf("cube side %u on C = %u: %s\n", bad[k][0], bad[k][1], hl_context_last_error(ctx));
    }
    hl_context_destroy(ctx);
    fixture f;
    hl_basis_bench *bb = NULL;
    uint32_t idx[4] = {0, 1, 2, 3};
    hl_result r = fixture_open(&f, 16);
    HL_CHECK(r == HL_OK, "set-up");
    if (r == HL_OK) {
        r = hl_basis_bench_create_ex(f.ctx, f.t, idx, 4, 4, 32, HL_CUBE_ROWS_SHARED, &bb);
        HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && !bb, "cube side 32 on C = 16 accepted");
        printf("bench-basis, cube side 32 on C = 16: %s\n", hl_context_last_error(f.ctx));
        HL_CHECK(hl_basis_bench_default_cube_side(64, 64) == 32, "default cube side for N = C = 64");
        HL_CHECK(hl_basis_bench_default_cube_side(64, 48) == 16, "default cube side for N = 64, C = 48");
        HL_CHECK(hl_basis_bench_default_cube_side(16, 9) == 0, "default cube side for C = 9");
    }
    hl_basis_bench_destroy(bb);
    bb = NULL;
    fixture_close(&f);
    /* C = 9: no cube side divides it; the other bases go on without the
       cube (the fixture's comparison) */
    r = fixture_open(&f, 9);
    bb = f.bb;
    const double *exact = NULL;
    if (r == HL_OK) r = hl_basis_bench_set_env(bb, f.env, &exact);
    HL_CHECK(r == HL_OK, "C = 9: %s", f.ctx ? hl_context_last_error(f.ctx) : "no context");
    if (r == HL_OK) {
        double c[64 * 3];
        HL_CHECK(hl_basis_bench_count(bb, HL_BASIS_CUBE) == 0 && !hl_basis_bench_exact(bb, HL_BASIS_CUBE),
                 "C = 9: the cube has terms");
        HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_CUBE, 1, c) == HL_ERR_INVALID_ARGUMENT, "C = 9: cube colours given");
        HL_CHECK(hl_basis_bench_colours(bb, HL_BASIS_HAAR, 512, c) == HL_OK, "C = 9: %s", hl_context_last_error(f.ctx));
        printf("C = 9: the cube bases have no terms, the paraboloid's 512\n");
    }
    fixture_close(&f);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {{"transform", t_transform}, {"taps", t_taps}, {"rows", t_rows},
                                         {"constant", t_constant},   {"halfspace", t_halfspace},
                                         {"bad", t_bad},
                                         {NULL, NULL}};
    return hl_test_main(argc, argv, cases);
}
