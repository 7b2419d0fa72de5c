/* stiff_scene.h - the scenes and runs of the stiff-input tests
 * (tests/stiff): scenarios counted as cases, the two backends' contexts,
 * meshes built in memory, precompute on both backends (files compared
 * byte for byte), and a rig that relights on both.
 * Depends on: hl_test.h, exr_io.h, geom.h, lighting.h, rays.h, twins.h,
 * an OpenCL device (PoCL), HL_TMP.
 */
#ifndef HL_TEST_STIFF_SCENE_H
#define HL_TEST_STIFF_SCENE_H

#define U_F32 5.9604644775390625e-08     /* 2^-24, float unit roundoff */
#define SUB_HALF 7.0064923216240854e-46  /* 2^-150, half the least subnormal */

/* ---------------------------------------------------------------- cases */

/* Every scenario counts as one case of the suite (both backends run in
 * it); hl_test_failures tells whether it passed. */
static int cases_run, cases_failed, case_mark;
static char case_label[200];

static inline void case_begin(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(case_label, sizeof case_label, fmt, ap);
    va_end(ap);
    case_mark = hl_test_failures;
    printf("== %s\n", case_label);
}

static inline void case_end(void)
{
    int bad = hl_test_failures != case_mark;
    cases_run++;
    cases_failed += bad;
    printf("== %s: %s\n", case_label, bad ? "FAILED" : "passed");
}

/* The test cannot go on without its memory. */
static inline void *need(void *p)
{
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    return p;
}

static inline size_t count_nonfinite(const float *x, size_t n)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++) k += !isfinite(x[i]);
    return k;
}

/* ---------------------------------------------------------------- contexts */

static hl_context *contexts[2]; /* 0: OpenCL, 1: the plain-C reference */
static const char *const backend_name[2] = {"OpenCL", "reference"};

static inline hl_context *ctx_for(int b)
{
    if (!contexts[b]) {
        hl_context_desc d = {.backend = b ? HL_BACKEND_REFERENCE : HL_BACKEND_OPENCL,
                             .cl_platform = -1, .cl_device = -1, .quiet = 1};
        char err[4096];
        if (hl_context_create(&d, &contexts[b], err, sizeof err) != HL_OK) {
            fprintf(stderr, "cannot create the %s context: %s\n", backend_name[b], err);
            exit(1);
        }
    }
    return contexts[b];
}

static inline hl_context *ref_ctx(void) { return ctx_for(1); }

/* ---------------------------------------------------------------- meshes */

/* Appends an n x n grid of quads over [-half, half]^2 at height y, normal
 * +Y, to the arrays (3 floats per vertex, 3 indices per triangle). */
typedef struct builder {
    double *p;
    float *n;
    uint32_t *idx;
    uint32_t nv, nt;
} builder;

static inline void add_vertex(builder *b, double x, double y, double z, float nx, float ny, float nz)
{
    double *p = b->p + 3 * (size_t)b->nv;
    float *n = b->n + 3 * (size_t)b->nv;
    p[0] = x, p[1] = y, p[2] = z;
    n[0] = nx, n[1] = ny, n[2] = nz;
    b->nv++;
}

static inline void add_tri(builder *b, uint32_t i, uint32_t j, uint32_t k)
{
    uint32_t *t = b->idx + 3 * (size_t)b->nt++;
    t[0] = i, t[1] = j, t[2] = k;
}

static inline void add_grid(builder *b, uint32_t n, double half, double y)
{
    uint32_t first = b->nv, row = n + 1;
    for (uint32_t j = 0; j <= n; j++)
        for (uint32_t i = 0; i <= n; i++)
            add_vertex(b, -half + 2.0 * half * i / n, y, -half + 2.0 * half * j / n, 0, 1, 0);
    /* (a, c, b): (c - a) x (b - a) = +Z x +X = +Y */
    for (uint32_t j = 0; j < n; j++)
        for (uint32_t i = 0; i < n; i++) {
            uint32_t a = first + j * row + i;
            add_tri(b, a, a + row, a + 1);
            add_tri(b, a + 1, a + row, a + row + 1);
        }
}

/* A box of half-size h about c with one flat normal per face (24
 * vertices), wound outward. */
static inline void add_box(builder *b, const double c[3], double h)
{
    for (int k = 0; k < 3; k++)
        for (int s = -1; s <= 1; s += 2) {
            int u = (k + 1) % 3, v = (k + 2) % 3; /* e_u x e_v = e_k */
            static const int cu[4] = {-1, 1, 1, -1}, cv[4] = {-1, -1, 1, 1};
            uint32_t first = b->nv;
            for (int q = 0; q < 4; q++) {
                int qq = s > 0 ? q : 3 - q;
                double p[3];
                p[k] = c[k] + s * h;
                p[u] = c[u] + cu[qq] * h;
                p[v] = c[v] + cv[qq] * h;
                float nn[3] = {0, 0, 0};
                nn[k] = (float)s;
                add_vertex(b, p[0], p[1], p[2], nn[0], nn[1], nn[2]);
            }
            add_tri(b, first, first + 1, first + 2);
            add_tri(b, first, first + 2, first + 3);
        }
}

static inline hl_mesh *build_mesh(const builder *b, double scale, const double shift[3], int with_normals)
{
    float *P = need(malloc((size_t)b->nv * 12));
    for (uint32_t i = 0; i < 3 * b->nv; i++) P[i] = (float)(b->p[i] * scale + shift[i % 3]);
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_create(ref_ctx(), b->nv, P, with_normals ? b->n : NULL, NULL, b->nt, b->idx, &m);
    HL_CHECK(r == HL_OK, "mesh: %s", hl_context_last_error(ref_ctx()));
    free(P);
    return m;
}

static inline builder builder_new(uint32_t max_vertices, uint32_t max_triangles)
{
    builder b = {need(malloc((size_t)max_vertices * 3 * sizeof(double))), need(malloc((size_t)max_vertices * 12)),
                 need(malloc((size_t)max_triangles * 12)), 0, 0};
    return b;
}

static inline void builder_free(builder *b)
{
    free(b->p);
    free(b->n);
    free(b->idx);
}

/* The small scene: a 4 x 4 ground of 8 x 8 quads at y = 0 and a unit box
 * floating 0.25 above it (105 vertices). Its coordinates are multiples of
 * 1/4, so a copy 1e6 away (float spacing 1/16 there) is exact. */
static const double no_shift[3] = {0, 0, 0};

static inline hl_mesh *scene_mesh(double scale, const double shift[3])
{
    builder b = builder_new(81 + 24, 128 + 12);
    add_grid(&b, 8, 2.0, 0.0);
    const double c[3] = {0.0, 0.75, 0.0};
    add_box(&b, c, 0.5);
    hl_mesh *m = build_mesh(&b, scale, shift, 1);
    builder_free(&b);
    return m;
}

/* One open quad, normal +Y, albedo 1 (the white furnace). */
static inline hl_mesh *quad_mesh(void)
{
    const float P[12] = {-1, 0, -1, 1, 0, -1, 1, 0, 1, -1, 0, 1};
    const float Nn[12] = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    const float A[12] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};
    const uint32_t I[6] = {0, 2, 1, 0, 3, 2};
    hl_mesh *m = NULL;
    HL_CHECK(hl_mesh_create(ref_ctx(), 4, P, Nn, A, 2, I, &m) == HL_OK, "quad: %s", hl_context_last_error(ref_ctx()));
    return m;
}

/* ---------------------------------------------------------------- precompute */

/* 1 when the two files hold the same bytes; *size gets the first's. */
static inline int same_bytes(const char *pa, const char *pb, size_t *size)
{
    FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
    int same = fa && fb;
    *size = 0;
    while (same) {
        char x[4096], y[4096];
        size_t na = fread(x, 1, sizeof x, fa), nb = fread(y, 1, sizeof y, fb);
        same = na == nb && memcmp(x, y, na) == 0;
        *size += na;
        if (na < sizeof x) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

/* Precomputes on both backends into HL_TMP/stiff_<name>.hlt; the files
 * must be byte-identical. Returns that path (one static buffer) or NULL. */
static inline const char *precompute_both(const hl_mesh *m, const hl_precompute_desc *d, const char *name)
{
    static char path[2][1024];
    if (!m) return NULL;
    for (int b = 0; b < 2; b++) {
        snprintf(path[b], sizeof path[b], "%s/stiff_%s%s.hlt", hl_test_env("HL_TMP", "/tmp"), name, b ? "" : "_cl");
        hl_result r = hl_precompute(ctx_for(b), m, d, path[b], NULL);
        HL_CHECK(r == HL_OK, "%s precompute of %s: %s", backend_name[b], name, hl_context_last_error(ctx_for(b)));
        if (r != HL_OK) return NULL;
    }
    size_t n = 0;
    int same = same_bytes(path[0], path[1], &n);
    printf("%s: OpenCL and reference transport files %s (%zu bytes)\n", name, same ? "identical" : "DIFFER", n);
    HL_CHECK(same, "%s: the backends' transport files differ", name);
    remove(path[0]);
    return path[1];
}

/* ---------------------------------------------------------------- relighting */

/* One transport relit on both backends. */
typedef struct rig {
    hl_transport *t[2];
    hl_relighter *r[2];
    uint32_t V;
    float *rgb[2];
    hl_relight_stats st[2];
} rig;

static inline void rig_close(rig *g)
{
    for (int b = 0; b < 2; b++) {
        hl_relighter_destroy(g->r[b]);
        hl_transport_destroy(g->t[b]);
        free(g->rgb[b]);
    }
    memset(g, 0, sizeof *g);
}

static inline int rig_open(rig *g, const char *path)
{
    memset(g, 0, sizeof *g);
    if (!path) return 0;
    for (int b = 0; b < 2; b++) {
        hl_context *c = ctx_for(b);
        hl_result r = hl_transport_load(c, path, &g->t[b]);
        if (r == HL_OK) r = hl_relighter_create(c, g->t[b], &g->r[b]);
        HL_CHECK(r == HL_OK, "%s: %s", backend_name[b], hl_context_last_error(c));
        if (r != HL_OK) {
            rig_close(g);
            return 0;
        }
    }
    g->V = g->t[1]->info.vertex_count;
    g->rgb[0] = need(malloc((size_t)g->V * 12));
    g->rgb[1] = need(malloc((size_t)g->V * 12));
    return 1;
}

/* Relights env with `terms` terms on both backends. Every colour and
 * statistic must be finite, and the backends must agree bit for bit
 * (colours, terms kept, energy kept, bound, blocks skipped). The colours
 * kept for the accuracy checks are the sums before the clamp at zero
 * (keep_negative), which the bounds are about; the clamped colours every
 * output gets must be exactly those sums clamped. */
static inline int rig_run_sel(rig *g, const hl_env *env, uint32_t terms, uint32_t select, const char *what)
{
    hl_relight_desc d = {.terms = terms, .select = select, .keep_negative = 1}, dc = d;
    dc.keep_negative = 0;
    char w[320];
    float *clamped = need(malloc((size_t)g->V * 12));
    for (int b = 0; b < 2; b++) {
        hl_result r = hl_relighter_set_env(g->r[b], env);
        if (r == HL_OK) r = hl_relighter_run(g->r[b], &dc, clamped, NULL);
        if (r == HL_OK) r = hl_relighter_run(g->r[b], &d, g->rgb[b], &g->st[b]);
        HL_CHECK(r == HL_OK, "%s, %s: %s", what, backend_name[b], hl_context_last_error(ctx_for(b)));
        if (r != HL_OK) {
            free(clamped);
            return 0;
        }
        size_t off = 0;
        for (size_t i = 0; i < (size_t)g->V * 3; i++) {
            const float x = g->rgb[b][i], want = x > 0.0f ? x : 0.0f;
            off += memcmp(&clamped[i], &want, 4) != 0;
        }
        snprintf(w, sizeof w, "%s, %s: clamped colours that are not the sums clamped at zero", what, backend_name[b]);
        hl_check_error(w, (double)off, 0.0);
        const hl_relight_stats *s = &g->st[b];
        size_t bad = count_nonfinite(g->rgb[b], (size_t)g->V * 3) + !isfinite(s->energy_kept) +
                     !isfinite(s->error_bound) + !isfinite(s->blocks_skipped);
        snprintf(w, sizeof w, "%s, %s: NaN or Inf among %u colours and the statistics", what, backend_name[b], 3 * g->V);
        hl_check_error(w, (double)bad, 0.0);
    }
    const hl_relight_stats *a = &g->st[0], *b = &g->st[1];
    size_t diff = a->terms_kept != b->terms_kept || memcmp(&a->energy_kept, &b->energy_kept, 8) != 0 ||
                  memcmp(&a->error_bound, &b->error_bound, 8) != 0 || a->blocks_skipped != b->blocks_skipped;
    for (size_t i = 0; i < (size_t)g->V * 3; i++) diff += memcmp(g->rgb[0] + i, g->rgb[1] + i, 4) != 0;
    snprintf(w, sizeof w, "%s: colours and statistics where OpenCL and the reference differ in any bit", what);
    hl_check_error(w, (double)diff, 0.0);
    free(clamped);
    return 1;
}

static inline int rig_run(rig *g, const hl_env *env, uint32_t terms, const char *what)
{
    return rig_run_sel(g, env, terms, HL_SELECT_DEFAULT, what);
}

#endif
