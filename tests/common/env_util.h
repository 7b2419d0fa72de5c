/* env_util.h - helpers of the environment and image tests (tests/io):
 * a reference context, scratch folders and files, the map directions of
 * docs/CONVENTIONS.md written out here, pixel solid angles, an
 * environment whose pixels tell their index.
 * Depends on: hl_test.h, POSIX dirent/stat, HL_TMP.
 */
#ifndef HL_TEST_ENV_UTIL_H
#define HL_TEST_ENV_UTIL_H

#define PI 3.14159265358979323846

/* ---------------------------------------------------------------- helpers */

static inline hl_context *make_ctx(void) { return hl_test_ref_context(0); }

static inline const char *tmp_dir(void) { return hl_test_env("HL_TMP", "/tmp"); }

/* A fresh, empty scratch folder HL_TMP/env_<name>. */
static inline void scratch(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/env_%s", tmp_dir(), name);
    DIR *d = opendir(out);
    if (d) {
        struct dirent *e;
        char p[1024];
        while ((e = readdir(d))) {
            if (e->d_name[0] == '.') continue;
            snprintf(p, sizeof p, "%s/%s", out, e->d_name);
            chmod(p, 0755);
            unlink(p);
        }
        closedir(d);
    }
    mkdir(out, 0755);
}

/* Number of entries in a folder other than . and .. */
static inline int dir_entries(const char *path, const char *must_not_contain)
{
    DIR *d = opendir(path);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        n++;
        if (must_not_contain && strstr(e->d_name, must_not_contain))
            HL_CHECK(0, "%s: leftover %s", path, e->d_name);
    }
    closedir(d);
    return n;
}

static inline int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static inline void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f) {
        HL_CHECK(0, "cannot create %s", path);
        return;
    }
    if (n) HL_CHECK(fwrite(p, 1, n, f) == n, "cannot write %s", path);
    fclose(f);
}

static inline uint8_t *read_bytes(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    *n = 0;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *p = malloc(len > 0 ? (size_t)len : 1);
    if (p && len > 0 && fread(p, 1, (size_t)len, f) != (size_t)len) {
        free(p);
        p = NULL;
    }
    fclose(f);
    if (p) *n = (size_t)len;
    return p;
}

/* docs/CONVENTIONS.md, "going the other way". */
static inline void dir_of_uv(double u, double v, float w[3])
{
    double phi = 2.0 * PI * (u - 0.5), theta = PI * v;
    w[0] = (float)(sin(theta) * cos(phi));
    w[1] = (float)cos(theta);
    w[2] = (float)(sin(theta) * sin(phi));
}

/* Right-handed rotation about +Y. */
static inline void rot_y(double deg, const float in[3], float out[3])
{
    double a = deg * PI / 180.0, c = cos(a), s = sin(a);
    double x = in[0], y = in[1], z = in[2];
    out[0] = (float)(x * c + z * s);
    out[1] = (float)y;
    out[2] = (float)(-x * s + z * c);
}

static inline double pixel_omega(uint32_t W, uint32_t H, uint32_t j)
{
    return (2.0 * PI / W) * (cos(PI * j / H) - cos(PI * (j + 1) / H));
}

/* An environment whose pixel (i, j) holds (i, j, 7). */
static inline hl_env *index_env(hl_context *ctx, uint32_t W, uint32_t H)
{
    float *rgb = malloc(sizeof(float) * 3 * W * H);
    for (uint32_t j = 0; j < H; j++)
        for (uint32_t i = 0; i < W; i++) {
            float *p = rgb + 3 * ((size_t)j * W + i);
            p[0] = (float)i;
            p[1] = (float)j;
            p[2] = 7.0f;
        }
    hl_env *env = NULL;
    hl_env_stats st;
    hl_result r = hl_env_create(ctx, W, H, rgb, &env, &st);
    free(rgb);
    if (r != HL_OK) {
        fprintf(stderr, "hl_env_create: %s\n", hl_context_last_error(ctx));
        exit(1);
    }
    return env;
}

/* Queries env at w and checks that it reads pixel (i, j). */
static inline int expect_pixel(const hl_env *env, float x, float y, float z, float rot, int i, int j, const char *what)
{
    float w[3] = {x, y, z}, c[3];
    hl_env_query(env, w, rot, c);
    int ok = (i < 0 || c[0] == (float)i) && c[1] == (float)j && c[2] == 7.0f; /* i < 0: any column */
    HL_CHECK(ok, "%s: direction (%g, %g, %g) rotate %g read pixel (%g, %g), expected (%d, %d)", what,
             (double)x, (double)y, (double)z, (double)rot, (double)c[0], (double)c[1], i, j);
    return ok;
}


/* Loads path and expects failure with want (0: any error code) and a
 * message that names the file. Returns the code. */
static inline hl_result expect_refused(hl_context *ctx, const char *path, hl_result want, const char *what)
{
    hl_env *env = (hl_env *)(uintptr_t)1;
    hl_env_stats st;
    hl_result r = hl_env_load(ctx, path, &env, &st);
    const char *msg = hl_context_last_error(ctx);
    HL_CHECK(r != HL_OK, "%s: loaded without error", what);
    HL_CHECK(env == NULL, "%s: out not cleared on failure", what);
    if (r == HL_OK) hl_env_destroy(env);
    if (want != HL_OK) HL_CHECK(r == want, "%s: code %s, expected %s", what, hl_result_string(r), hl_result_string(want));
    HL_CHECK(strstr(msg, path) != NULL, "%s: message does not name the file: %s", what, msg);
    printf("%s: %s: %s\n", what, hl_result_string(r), msg);
    return r;
}

#endif
