/* render_util.h - helpers of the render and PLY tests (tests/relight,
 * tests/io): a reference context, HL_TMP paths, data/bunny_lowres.obj,
 * constant colours, the renderer's pinhole camera rebuilt in double, and a
 * check that no temporary file is left.
 * Depends on: hl_test.h, POSIX dirent, HL_REPO_DATA, HL_TMP.
 */
#ifndef HL_TEST_RENDER_UTIL_H
#define HL_TEST_RENDER_UTIL_H

#define HL_TEST_PI 3.14159265358979323846

/* ---------------------------------------------------------------- helpers */

static inline hl_context *make_ctx(void) { return hl_test_ref_context(2); }

static inline const char *tmp_path(const char *name) { return hl_test_tmp_path(name); }

static inline hl_mesh *load_bunny(hl_context *ctx)
{
    char p[1024];
    snprintf(p, sizeof p, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_load(ctx, p, NULL, &m, NULL);
    if (r != HL_OK) {
        fprintf(stderr, "cannot load %s: %s\n", p, hl_context_last_error(ctx));
        exit(1);
    }
    return m;
}

static inline float *constant_colours(uint32_t n, float r, float g, float b)
{
    float *c = malloc(3 * (size_t)n * sizeof(float));
    for (uint32_t i = 0; i < n; i++) {
        c[3 * i] = r;
        c[3 * i + 1] = g;
        c[3 * i + 2] = b;
    }
    return c;
}

/* The renderer's camera, in double: basis and pixel-centre rays. */
typedef struct tcam {
    uint32_t w, h;
    double eye[3], f[3], r[3], u[3], th, tw;
} tcam;

static inline void norm3(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; k++) v[k] /= l;
}

static inline tcam make_tcam(const hl_camera_desc *c)
{
    tcam t;
    t.w = c->width;
    t.h = c->height;
    double up[3] = {c->up[0], c->up[1], c->up[2]};
    if (up[0] == 0 && up[1] == 0 && up[2] == 0) up[1] = 1;
    for (int k = 0; k < 3; k++) {
        t.eye[k] = c->eye[k];
        t.f[k] = (double)c->target[k] - c->eye[k];
    }
    norm3(t.f);
    t.r[0] = t.f[1] * up[2] - t.f[2] * up[1];
    t.r[1] = t.f[2] * up[0] - t.f[0] * up[2];
    t.r[2] = t.f[0] * up[1] - t.f[1] * up[0];
    norm3(t.r);
    t.u[0] = t.r[1] * t.f[2] - t.r[2] * t.f[1];
    t.u[1] = t.r[2] * t.f[0] - t.r[0] * t.f[2];
    t.u[2] = t.r[0] * t.f[1] - t.r[1] * t.f[0];
    t.th = tan(0.5 * c->fov_deg * HL_TEST_PI / 180.0);
    t.tw = t.th * t.w / t.h;
    return t;
}

static inline void tcam_dir(const tcam *t, double px, double py, double d[3])
{
    double sx = (2.0 * px / t->w - 1.0) * t->tw;
    double sy = (1.0 - 2.0 * py / t->h) * t->th;
    for (int k = 0; k < 3; k++) d[k] = t->f[k] + sx * t->r[k] + sy * t->u[k];
}

/* Continuous pixel coordinates (x right, y down, pixel centres at +0.5)
 * of a world point. */
static inline void tcam_project(const tcam *t, const double p[3], double *px, double *py)
{
    double d[3] = {p[0] - t->eye[0], p[1] - t->eye[1], p[2] - t->eye[2]};
    double z = d[0] * t->f[0] + d[1] * t->f[1] + d[2] * t->f[2];
    double x = (d[0] * t->r[0] + d[1] * t->r[1] + d[2] * t->r[2]) / z;
    double y = (d[0] * t->u[0] + d[1] * t->u[1] + d[2] * t->u[2]) / z;
    *px = (x / t->tw + 1.0) * 0.5 * t->w;
    *py = (1.0 - y / t->th) * 0.5 * t->h;
}

/* Only this process's temporaries (the writers name them NAME.tmp.PID):
 * other tests writing into the same folder at the same time have theirs. */
static inline int no_temp_left(const char *dir, const char *stem)
{
    DIR *d = opendir(dir);
    if (!d) return 1;
    int clean = 1;
    struct dirent *e;
    size_t n = strlen(stem);
    char mine[32];
    snprintf(mine, sizeof mine, ".tmp.%ld", (long)getpid());
    size_t nm = strlen(mine);
    while ((e = readdir(d))) {
        size_t len = strlen(e->d_name);
        if (strncmp(e->d_name, stem, n) == 0 && len > nm && strcmp(e->d_name + len - nm, mine) == 0) {
            fprintf(stderr, "temporary file left behind: %s/%s\n", dir, e->d_name);
            clean = 0;
        }
    }
    closedir(d);
    return clean;
}


static inline void expect_bad(hl_context *ctx, hl_result got, hl_result want, const char *what, const char *needle)
{
    const char *msg = hl_context_last_error(ctx);
    HL_CHECK(got == want, "%s: got %s, want %s", what, hl_result_string(got), hl_result_string(want));
    HL_CHECK(msg && *msg, "%s: no message", what);
    if (needle) HL_CHECK(msg && strstr(msg, needle), "%s: message \"%s\" lacks \"%s\"", what, msg, needle);
    printf("%s -> %s: %s\n", what, hl_result_string(got), msg);
}

#endif
