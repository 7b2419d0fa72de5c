/* mesh_util.h - helpers of the mesh tests (tests/io): a reference
 * context, paths into the optional shared meshes (have_data skips the case,
 * exit 77, where they are missing) and HL_TMP, file writing, statistics,
 * volume, normals and winding checks, bounding boxes, expected failures,
 * the checks of a teapot tessellation, and those of a ground plane added
 * to a mesh.
 * Depends on: hl_test.h, hl_internal.h, HL_TEST_DATA, HL_TMP.
 */
#ifndef HL_TEST_MESH_UTIL_H
#define HL_TEST_MESH_UTIL_H

/* ---------------------------------------------------------------- helpers */

static inline hl_context *make_ctx(void) { return hl_test_ref_context(1); }

static char path_buf[8][1024];
static int path_next = 0;

/* Rotating buffers so a test can hold several paths at once. */
static inline const char *data_path(const char *name)
{
    char *b = path_buf[path_next++ & 7];
    snprintf(b, 1024, "%s/meshes/%s", hl_test_env("HL_TEST_DATA", "../shared/data"), name);
    return b;
}

static inline const char *tmp_path(const char *name) { return hl_test_tmp_path(name); }

static inline int have_data(void)
{
    FILE *f = fopen(data_path("bunny.obj"), "rb");
    if (!f) {
        hl_test_skip_missing(data_path(""));
        return 0;
    }
    fclose(f);
    return 1;
}

static inline void write_file(const char *path, const void *bytes, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(bytes, 1, n, f) != n) {
        fprintf(stderr, "cannot write %s\n", path);
        exit(1);
    }
    fclose(f);
}

static inline void write_text(const char *path, const char *text) { write_file(path, text, strlen(text)); }

static inline void print_stats(const char *what, const hl_mesh *m, const hl_mesh_stats *s)
{
    printf("%s: file %u v / %u f -> %u v / %u f; merged %u, unreferenced %u, degenerate %u, normals %d, colours %d, flipped %d\n",
           what, s->file_vertices, s->file_triangles, m->vertex_count, m->triangle_count, s->merged_vertices,
           s->unreferenced_vertices, s->degenerate_triangles, s->had_normals, s->had_colors, s->flipped);
}

/* Signed volume of the object's triangles (ground excluded). */
static inline double mesh_volume(const hl_mesh *m)
{
    double vol = 0.0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *f = m->indices + 3 * (size_t)t;
        if (f[0] >= m->object_vertex_count) continue;
        const float *a = m->positions + 3 * (size_t)f[0], *b = m->positions + 3 * (size_t)f[1],
                    *c = m->positions + 3 * (size_t)f[2];
        vol += ((double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
    }
    return vol;
}

static inline void face_normal(const hl_mesh *m, uint32_t t, double n[3])
{
    const uint32_t *f = m->indices + 3 * (size_t)t;
    const float *a = m->positions + 3 * (size_t)f[0], *b = m->positions + 3 * (size_t)f[1],
                *c = m->positions + 3 * (size_t)f[2];
    double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (l > 0) for (int k = 0; k < 3; k++) n[k] /= l;
}

/* Structural sanity of any mesh: finite positions, unit finite normals,
 * albedo in [0, 1], indices in range. Returns the worst |length - 1|. */
static inline double check_sane(const char *what, const hl_mesh *m)
{
    double worst = 0.0;
    int bad_pos = 0, bad_nrm = 0, bad_alb = 0, bad_idx = 0;
    for (size_t v = 0; v < m->vertex_count; v++) {
        const float *p = m->positions + 3 * v, *n = m->normals + 3 * v, *a = m->albedo + 3 * v;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) bad_pos++;
        if (!isfinite(n[0]) || !isfinite(n[1]) || !isfinite(n[2])) {
            bad_nrm++;
            continue;
        }
        double l = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (fabs(l - 1.0) > worst) worst = fabs(l - 1.0);
        for (int k = 0; k < 3; k++)
            if (!(a[k] >= 0.0f && a[k] <= 1.0f)) bad_alb++;
    }
    for (size_t i = 0; i < 3 * (size_t)m->triangle_count; i++)
        if (m->indices[i] >= m->vertex_count) bad_idx++;
    HL_CHECK(bad_pos == 0, "%s: %d non-finite positions", what, bad_pos);
    HL_CHECK(bad_nrm == 0, "%s: %d non-finite normals", what, bad_nrm);
    HL_CHECK(bad_alb == 0, "%s: %d albedo values outside [0,1]", what, bad_alb);
    HL_CHECK(bad_idx == 0, "%s: %d indices out of range", what, bad_idx);
    HL_CHECK(m->object_vertex_count <= m->vertex_count, "%s: object_vertex_count too large", what);
    return worst;
}

/* Fraction of triangles whose geometric normal agrees (dot > 0) with the
 * mean of their vertex normals: ~1 when normals follow the winding. */
static inline double winding_agreement(const hl_mesh *m)
{
    uint32_t agree = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        double n[3], s[3] = {0, 0, 0};
        face_normal(m, t, n);
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) s[k] += m->normals[3 * (size_t)m->indices[3 * (size_t)t + c] + k];
        if (n[0] * s[0] + n[1] * s[1] + n[2] * s[2] > 0) agree++;
    }
    return m->triangle_count ? (double)agree / m->triangle_count : 0.0;
}

static inline void bbox(const hl_mesh *m, uint32_t from, uint32_t to, float lo[3], float hi[3])
{
    for (int k = 0; k < 3; k++) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (size_t v = from; v < to; v++)
        for (int k = 0; k < 3; k++) {
            float p = m->positions[3 * v + k];
            if (p < lo[k]) lo[k] = p;
            if (p > hi[k]) hi[k] = p;
        }
}

/* The load must fail with `code` (or any failure when code is HL_OK) and
 * the message must name the file. */
static inline void expect_failure(hl_context *ctx, const char *path, hl_result got, hl_result code)
{
    const char *msg = hl_context_last_error(ctx);
    printf("  %s -> %s: %s\n", path, hl_result_string(got), msg);
    HL_CHECK(got != HL_OK, "%s: loading should fail", path);
    if (code != HL_OK) HL_CHECK(got == code, "%s: expected %s, got %s", path, hl_result_string(code), hl_result_string(got));
    HL_CHECK(strstr(msg, path) != NULL, "%s: message does not name the file: %s", path, msg);
}

static inline hl_result load(hl_context *ctx, const char *path, const hl_mesh_load_desc *d, hl_mesh **m, hl_mesh_stats *s)
{
    hl_result r = hl_mesh_load(ctx, path, d, m, s);
    if (r != HL_OK) fprintf(stderr, "load %s: %s\n", path, hl_context_last_error(ctx));
    return r;
}


/* A Utah teapot tessellation (the shared data README): tris file
 * triangles, welded to vertices (the file's vertices less those that repeat
 * a position), no position left twice, unit normals that follow the
 * winding. what names it in the output. */
static inline void check_teapot(hl_context *ctx, const char *what, const char *path, uint32_t tris, uint32_t vertices)
{
    hl_mesh *m = NULL;
    hl_mesh_stats s;
    HL_CHECK(load(ctx, path, NULL, &m, &s) == HL_OK, "load");
    if (m) {
        print_stats(what, m, &s);
        HL_CHECK(s.file_triangles == tris, "file counts");
        HL_CHECK(m->vertex_count == vertices, "vertices %u", m->vertex_count);
        HL_CHECK(m->triangle_count == tris, "triangles %u", m->triangle_count);
        HL_CHECK(!s.flipped, "an open mesh is never flipped");
        /* Welded seams: no two output vertices share a position. */
        uint32_t dup = 0;
        for (uint32_t a = 0; a < m->vertex_count && dup == 0; a++)
            for (uint32_t b = a + 1; b < m->vertex_count; b++)
                if (memcmp(m->positions + 3 * (size_t)a, m->positions + 3 * (size_t)b, 12) == 0) dup++;
        HL_CHECK(dup == 0, "positions still duplicated after welding");
        char label[128];
        snprintf(label, sizeof label, "%s normal length", what);
        hl_check_error(label, check_sane(what, m), 1e-6);
        double agree = winding_agreement(m);
        printf("%s: %.4f of triangles agree with their vertex normals\n", what, agree);
        HL_CHECK(agree > 0.99, "normals disagree with the winding");
    }
    hl_mesh_destroy(m);
}

/* ---------------------------------------------------------------- ground */

static inline void check_ground(const char *what, hl_mesh *m, uint32_t res, double margin)
{
    uint32_t ov = m->vertex_count, ot = m->triangle_count;
    float lo[3], hi[3];
    bbox(m, 0, ov, lo, hi);
    double mean[3] = {0, 0, 0};
    for (size_t v = 0; v < ov; v++)
        for (int k = 0; k < 3; k++) mean[k] += (double)m->albedo[3 * v + k] / ov;
    float diag0 = hl_mesh_query_diagonal(m);
    hl_ground_desc gd = {0};
    gd.resolution = res == 96 ? 0 : res;
    gd.margin = (float)margin; /* given: at most 0.75 keeps the grid uniform */
    hl_result r = hl_mesh_add_ground(NULL, m, &gd);
    HL_CHECK(r == HL_OK, "%s: add ground", what);
    if (r != HL_OK) return;
    HL_CHECK(m->object_vertex_count == ov, "%s: object_vertex_count %u", what, m->object_vertex_count);
    HL_CHECK(m->vertex_count == ov + (res + 1) * (res + 1), "%s: vertex count %u", what, m->vertex_count);
    HL_CHECK(m->triangle_count == ot + 2 * res * res, "%s: triangle count %u", what, m->triangle_count);
    double nerr = 0.0, yerr = 0.0, aerr = 0.0, gerr = 0.0;
    for (size_t v = ov; v < m->vertex_count; v++) {
        const float *n = m->normals + 3 * v;
        nerr = fmax(nerr, fabs(n[0]) + fabs(n[1] - 1.0) + fabs(n[2]));
        yerr = fmax(yerr, fabs(m->positions[3 * v + 1] - lo[1]));
        for (int k = 0; k < 3; k++) aerr = fmax(aerr, fabs(m->albedo[3 * v + k] - (mean[0] + mean[1] + mean[2]) / 3.0));
    }
    uint32_t ground_tris = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *f = m->indices + 3 * (size_t)t;
        int g = f[0] >= ov, g1 = f[1] >= ov, g2 = f[2] >= ov;
        HL_CHECK(g == g1 && g == g2, "%s: triangle %u mixes ground and object", what, t);
        if (!g) continue;
        ground_tris++;
        double n[3];
        face_normal(m, t, n);
        gerr = fmax(gerr, 1.0 - n[1]);
    }
    HL_CHECK(ground_tris == 2 * res * res, "%s: ground triangles %u", what, ground_tris);
    hl_check_error("ground vertex normals == +Y", nerr, 0.0);
    hl_check_error("ground y == mesh min y", yerr, 0.0);
    hl_check_error("ground albedo == grey at the mean object albedo", aerr, 1e-6);
    hl_check_error("ground triangle geometric normals (1 - n.y)", gerr, 1e-9);
    /* Covers the footprint plus margin x larger extent on every side. */
    float glo[3], ghi[3];
    bbox(m, ov, m->vertex_count, glo, ghi);
    double ext = fmax(hi[0] - lo[0], hi[2] - lo[2]), cover = 0.0;
    cover = fmax(cover, glo[0] - (lo[0] - margin * ext));
    cover = fmax(cover, (hi[0] + margin * ext) - ghi[0]);
    cover = fmax(cover, glo[2] - (lo[2] - margin * ext));
    cover = fmax(cover, (hi[2] + margin * ext) - ghi[2]);
    hl_check_error("ground coverage shortfall (relative to extent)", fmax(cover, 0.0) / ext, 1e-6);
    HL_CHECK(hl_mesh_query_diagonal(m) > diag0, "%s: diagonal should grow with the ground", what);
    check_sane(what, m);
    HL_CHECK(hl_mesh_add_ground(NULL, m, NULL) == HL_ERR_INVALID_ARGUMENT, "%s: a second ground must be refused", what);
}

/* The default ground (hl_ground_desc all zero): it reaches the shadow of
 * the object's top under a light 15 degrees high at every azimuth (and
 * 0.75 x the extent at least), its middle square (the footprint plus
 * 0.75 x its extent) is the uniform grid of 96 quads, and beyond it each
 * cell is at most 1.25 x the one before. */
static inline void check_ground_default(const char *what, hl_mesh *m)
{
    uint32_t ov = m->vertex_count;
    float lo[3], hi[3];
    bbox(m, 0, ov, lo, hi);
    HL_CHECK(hl_mesh_add_ground(NULL, m, NULL) == HL_OK, "%s: add the default ground", what);
    if (m->vertex_count == ov) return;
    const double ext = fmax(hi[0] - lo[0], hi[2] - lo[2]), H = hi[1] - lo[1];
    const double reach = fmax(0.75 * ext, H / tan(15.0 * 3.14159265358979323846 / 180.0));
    float glo[3], ghi[3];
    bbox(m, ov, m->vertex_count, glo, ghi);
    double short_by = fmax(fmax(glo[0] - (lo[0] - reach), (hi[0] + reach) - ghi[0]),
                           fmax(glo[2] - (lo[2] - reach), (hi[2] + reach) - ghi[2]));
    printf("%s: height %.4g, extent %.4g: the ground reaches %.4g beyond the footprint (%.4g needed), %u vertices\n", what,
           H, ext, fmin(fmin(lo[0] - glo[0], ghi[0] - hi[0]), fmin(lo[2] - glo[2], ghi[2] - hi[2])), reach,
           m->vertex_count - ov);
    hl_check_error("default ground's shortfall from the 15-degree shadow (relative to extent)", fmax(short_by, 0.0) / ext,
                   1e-6);
    /* the grid's x coordinates: the first row of the ground */
    uint32_t n = 0;
    while (ov + n < m->vertex_count && m->positions[3 * (size_t)(ov + n) + 2] == m->positions[3 * (size_t)ov + 2]) n++;
    HL_CHECK((uint64_t)n * n == m->vertex_count - ov, "%s: a square grid of %u x %u", what, n, n);
    const float *x = m->positions + 3 * (size_t)ov;
    const double step = ext * 2.5 / 96.0, inner_lo = 0.5 * (lo[0] + hi[0]) - 1.25 * ext;
    double uni = 0.0, growth = 0.0;
    for (uint32_t i = 1; i < n; i++) {
        const double a = x[3 * (i - 1)], b = x[3 * i], w = b - a;
        if (a >= inner_lo - 1e-6 * ext && b <= inner_lo + 2.5 * ext + 1e-6 * ext) uni = fmax(uni, fabs(w - step) / step);
        else if (i > 1 && i + 1 < n) { /* outer cells against their inner neighbours */
            const double prev = b < inner_lo ? x[3 * (i + 1)] - b : a - x[3 * (i - 2)];
            growth = fmax(growth, w / prev);
        }
    }
    hl_check_error("default ground: the middle square's cells against 2.5 x extent / 96 (relative)", uni, 1e-4);
    printf("default ground: largest growth from one cell to the next %.4f\n", growth);
    HL_CHECK(growth <= 1.25 + 1e-3, "%s: cells grow by %g from one to the next (at most 1.25)", what, growth);
    check_sane(what, m);
}

#endif
