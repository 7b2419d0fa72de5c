/* test_area_lights.c - the environment split into area lights
 * (host/src/dynamic/area_lights.c), suite "area_lights"; cases run under
 * both split rules where it costs little.
 *   energy         lights plus the folded term, and the cube alone, hold the map's energy
 *                  (data/city.exr, one-pixel suns); prints time, light count, energy spread.
 *   energy_shared  the same on the eight shared maps (exit 77 where HL_TEST_DATA is missing).
 *   cover          every cube texel in exactly one light; texel geometry against geom.c.
 *   sun            a one-pixel sun becomes a one-texel light with its energy and direction.
 *   irradiance     fast E_k(n) against the texel sum (random normals and normals across each
 *                  light's horizon); a constant map against pi; SH9 against its texel sum.
 *   rotation       a turn by whole columns equals the split of the turned map bit for bit; a
 *                  fractional turn moves the sun where hl_env_query sees it.
 *   bad_input      bad parameters and NaN/Inf/negative maps fail, naming the option.
 * Every check prints its tolerance and worst error (hl_check_error).
 * Depends on: haarlight_core, area_lights.h, geom.h (hl_dir_to_cube and hl_cube_face_dir, an
 * independent face mapping), lighting.h (relight's rotation), HL_REPO_DATA, HL_TEST_DATA (optional).
 */
#include <stdint.h>

#include "area_lights.h"
#include "geom.h"
#include "hl_test.h"
#include "lighting.h" /* hl_rotation_to_shift: how relight turns a map */

#define PI 3.14159265358979323846

static double lum(const double *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }
static double lumf(const float *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

static hl_context *make_ctx(void) { return hl_test_ref_context(0); }
static void die(hl_context *ctx, const char *what)
{
    fprintf(stderr, "%s: %s\n", what, hl_context_last_error(ctx));
    exit(1);
}

/* docs/CONVENTIONS.md: pixel row j's solid angle and a (u, v) direction. */
static double pixel_omega(uint32_t W, uint32_t H, uint32_t j)
{
    return (2.0 * PI / W) * (cos(PI * j / H) - cos(PI * (j + 1) / H));
}
static void dir_of_uv(double u, double v, double w[3])
{
    double phi = 2.0 * PI * (u - 0.5), theta = PI * v;
    w[0] = sin(theta) * cos(phi); w[1] = cos(theta); w[2] = sin(theta) * sin(phi);
}

/* An environment from rgb (freed here); exits on failure. */
static hl_env *make_env(hl_context *ctx, uint32_t W, uint32_t H, float *rgb)
{
    hl_env *env = NULL;
    hl_env_stats st;
    hl_result r = hl_env_create(ctx, W, H, rgb, &env, &st);
    free(rgb);
    if (r != HL_OK) exit(1);
    return env;
}

static void map_energy(const hl_env *env, double e[3])
{
    e[0] = e[1] = e[2] = 0.0;
    for (uint32_t j = 0; j < env->height; j++) {
        double om = pixel_omega(env->width, env->height, j);
        for (uint32_t i = 0; i < env->width; i++)
            for (int c = 0; c < 3; c++) e[c] += om * env->rgb[3 * ((size_t)j * env->width + i) + (size_t)c];
    }
}

static hl_env *load_city(hl_context *ctx)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/city.exr", hl_test_env("HL_REPO_DATA", "data"));
    hl_env *env = NULL;
    hl_env_stats st;
    if (hl_env_load(ctx, path, &env, &st) != HL_OK) die(ctx, path);
    return env;
}

/* The rule split() uses; cases run under both where it costs little. */
static hl_split_rule g_rule = HL_SPLIT_OF_MAP;
static const char *rule_name(void) { return g_rule == HL_SPLIT_OF_MAP ? "of map" : "of light"; }

/* t: 0 the rule's default; for HL_SPLIT_OF_LIGHT a t given for the other
 * rule is scaled by 100 (1e-3 -> 0.1, the two defaults). */
static hl_light_split *split(hl_context *ctx, const hl_env *env, uint32_t F, float t, int32_t K, float rot)
{
    hl_light_split_params p;
    hl_light_split_defaults(&p);
    p.rule = g_rule;
    if (F) p.face_res = F;
    if (g_rule == HL_SPLIT_OF_LIGHT)
        p.threshold = t > 0.0f ? fminf(0.9f, 100.0f * t) : HL_LIGHTS_DEFAULT_THRESHOLD_OF_LIGHT;
    else
        p.threshold = t > 0.0f ? t : HL_LIGHTS_DEFAULT_THRESHOLD;
    p.lights = K;
    p.rotate_deg = rot;
    hl_light_split *s = NULL;
    if (hl_area_lights_split(ctx, env, &p, &s) != HL_OK) die(ctx, "split");
    return s;
}

/* A dim sky of radiance sky with a one-pixel sun of radiance Ls at the
 * pixel holding direction d, moved to a neighbour whose four corners fall
 * in one cube texel of resolution F (so the sun is a one-texel light). */
static hl_env *sun_env(hl_context *ctx, uint32_t W, uint32_t H, const double d[3], float sky, float Ls, uint32_t F,
                       uint32_t *si, uint32_t *sj)
{
    double u = 0.5 + atan2(d[2], d[0]) / (2.0 * PI), v = acos(d[1] / sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
    v /= PI;
    int i0 = (int)floor(u * W), j0 = (int)floor(v * H), found = 0;
    for (int r = 0; r < 3 && !found; r++)
        for (int dj = -r; dj <= r && !found; dj++)
            for (int di = -r; di <= r && !found; di++) {
                int i = (i0 + di + (int)W) % (int)W, j = j0 + dj;
                if (j < 0 || j >= (int)H) continue;
                uint32_t t[4];
                for (int k = 0; k < 4; k++) {
                    double w[3];
                    dir_of_uv((i + (k & 1)) / (double)W, (j + (k >> 1)) / (double)H, w);
                    float wf[3] = {(float)w[0], (float)w[1], (float)w[2]};
                    t[k] = hl_dir_to_cube(wf, F);
                }
                if (t[0] == t[1] && t[0] == t[2] && t[0] == t[3]) { *si = (uint32_t)i; *sj = (uint32_t)j; found = 1; }
            }
    if (!found) {
        fprintf(stderr, "no pixel wholly inside one texel of F = %u near (%g, %g, %g)\n", F, d[0], d[1], d[2]);
        exit(1);
    }
    float *rgb = malloc(sizeof(float) * 3 * W * H);
    for (size_t k = 0; k < (size_t)W * H; k++) {
        rgb[3 * k] = sky; rgb[3 * k + 1] = 1.5f * sky; rgb[3 * k + 2] = 2.0f * sky;
    }
    float *p = rgb + 3 * ((size_t)*sj * W + *si);
    p[0] = Ls; p[1] = 0.9f * Ls; p[2] = 0.7f * Ls;
    return make_env(ctx, W, H, rgb);
}

/* Three sun directions: texel centres on the +X, +Y and -Z faces at F. */
static void sun_dir(int k, uint32_t F, double d[3])
{
    static const int face[3] = {0, 2, 5}, col[3] = {16, 10, 5}, row[3] = {16, 20, 25};
    float f[3];
    uint32_t c = (uint32_t)col[k] * F / 32, r = (uint32_t)row[k] * F / 32;
    hl_cube_face_dir(face[k], 2.0f * ((float)c + 0.5f) / (float)F - 1.0f, 2.0f * ((float)r + 0.5f) / (float)F - 1.0f,
                     f);
    for (int i = 0; i < 3; i++) d[i] = f[i];
}

/* ---------------------------------------------------------------- energy */

/* Lights plus folded, and the cube texels alone, against the map (per
 * channel, relative): worst of both into *worst. */
static void energy_of(const hl_env *env, const hl_light_split *s, const char *what, double *worst)
{
    double m[3], l[3] = {0, 0, 0}, cube[3] = {0, 0, 0};
    map_energy(env, m);
    for (uint32_t k = 0; k < s->count; k++)
        for (int c = 0; c < 3; c++) l[c] += s->lights[k].energy[c];
    for (int c = 0; c < 3; c++) l[c] += s->stats.folded_energy[c];
    for (size_t t = 0; t < (size_t)6 * s->F * s->F; t++)
        for (int c = 0; c < 3; c++) cube[c] += s->texel_energy[3 * t + (size_t)c];
    for (int c = 0; c < 3; c++) {
        double e[3] = {l[c], cube[c], s->stats.total_energy[c]};
        for (int k = 0; k < 3; k++)
            if (!(fabs(e[k] - m[c]) / m[c] <= *worst)) *worst = fabs(e[k] - m[c]) / m[c]; /* NaN too */
        if (!(*worst <= 1e-4))
            printf("  %s channel %d: map %.9g, lights+folded %.9g, cube %.9g\n", what, c, m[c], l[c], cube[c]);
    }
}

/* How many of the lights (strongest first) hold 90% of the luminance. */
static uint32_t lights_for(const hl_light_split *s, double share)
{
    double tot = lum(s->stats.total_energy), acc = 0.0;
    for (uint32_t k = 0; k < s->total; k++) {
        acc += lumf(s->lights[k].energy);
        if (acc >= share * tot) return k + 1;
    }
    return s->total;
}

static void report(const char *name, const hl_light_split *s)
{
    printf("%s: F %u, S %u, %u lights made (%u hold 90%%, %u hold 99%% of the luminance energy), %u kept, %u folded "
           "(%.3f%% of the energy), strongest light %u x %u texels, split %.1f ms\n",
           name, s->F, s->stats.subsamples, s->total, lights_for(s, 0.9), lights_for(s, 0.99), s->count,
           s->stats.folded, 100.0 * s->stats.folded_share, s->lights[0].x1 - s->lights[0].x0,
           s->lights[0].y1 - s->lights[0].y0, 1e3 * s->stats.seconds);
}

/* Energy tolerance: 1e-4 relative (the brief's); the sums are in double
 * and the lights' energies floats (2^-24 each), so 1e-6 is expected. */
#define ENERGY_TOL 1e-4

static void case_energy(void)
{
    hl_context *ctx = make_ctx();
    double worst = 0.0;
    hl_env *city = load_city(ctx);
    /* the defaults under both rules, timed on the third run (the first
       pays the page faults); then F = 2, 7 and 64 */
    static const uint32_t Fs[] = {0, 0, 0, 0, 0, 0, 2, 7, 64};
    for (int run = 0; run < 9; run++) {
        g_rule = run >= 3 && run < 6 ? HL_SPLIT_OF_LIGHT : HL_SPLIT_OF_MAP;
        hl_light_split *s = split(ctx, city, Fs[run], 0.0f, HL_LIGHTS_DEFAULT_KEEP, 0.0f);
        char name[128];
        snprintf(name, sizeof name, "city.exr at the defaults, rule %s", rule_name());
        if (run == 2 || run == 5) report(name, s);
        energy_of(city, s, "city", &worst);
        hl_light_split_destroy(s);
    }
    hl_env_destroy(city);
    for (int k = 0; k < 3; k++) {
        double d[3];
        uint32_t si, sj;
        sun_dir(k, 32, d);
        hl_env *env = sun_env(ctx, 256, 128, d, 0.05f, 1e5f, 32, &si, &sj);
        hl_light_split *s = split(ctx, env, 32, 0.0f, 1, 0.0f);
        energy_of(env, s, "sun", &worst);
        if (k == 0) report("sun map 256 x 128", s);
        hl_light_split_destroy(s); hl_env_destroy(env);
    }
    hl_check_error("energy: lights + folded term, cube texels, against the map, per channel (relative)", worst,
                   ENERGY_TOL);
    hl_context_destroy(ctx);
}

static void case_energy_shared(void)
{
    static const char *names[] = {"city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset"};
    const char *data = hl_test_env("HL_TEST_DATA", NULL);
    char path[1024];
    if (data) snprintf(path, sizeof path, "%s/envmaps/city.exr", data);
    FILE *probe = data ? fopen(path, "rb") : NULL;
    if (!probe) {
        if (data) snprintf(path, sizeof path, "%s/envmaps", data);
        hl_test_skip_missing(data ? path : "HL_TEST_DATA");
        return;
    }
    fclose(probe);
    hl_context *ctx = make_ctx();
    double worst = 0.0;
    for (size_t k = 0; k < 8; k++) {
        snprintf(path, sizeof path, "%s/envmaps/%s.exr", data, names[k]);
        hl_env *env = NULL;
        hl_env_stats st;
        if (hl_env_load(ctx, path, &env, &st) != HL_OK) {
            HL_CHECK(0, "%s: %s", path, hl_context_last_error(ctx));
            continue;
        }
        for (int r = 0; r < 2; r++) {
            g_rule = r ? HL_SPLIT_OF_LIGHT : HL_SPLIT_OF_MAP;
            hl_light_split *s = split(ctx, env, 0, 0.0f, HL_LIGHTS_DEFAULT_KEEP, 0.0f);
            char name[128];
            snprintf(name, sizeof name, "%s, rule %s", names[k], rule_name());
            energy_of(env, s, names[k], &worst);
            report(name, s);
            hl_light_split_destroy(s);
        }
        hl_env_destroy(env);
    }
    hl_check_error("energy_shared: lights + folded term against the map, per channel (relative)", worst, ENERGY_TOL);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- cover */

/* Every texel painted once, owner's rectangle holds it, areas add up. */
static double cover_errors(const hl_light_split *s)
{
    const uint32_t F = s->F;
    const size_t n = (size_t)6 * F * F;
    uint32_t *paint = calloc(n, sizeof *paint);
    double bad = 0.0, area = 0.0;
    for (uint32_t k = 0; k < s->total; k++) {
        const hl_area_light *l = &s->lights[k];
        if (l->face > 5 || l->x0 >= l->x1 || l->y0 >= l->y1 || l->x1 > F || l->y1 > F) { bad += 1.0; continue; }
        area += (double)(l->x1 - l->x0) * (l->y1 - l->y0);
        for (uint32_t y = l->y0; y < l->y1; y++)
            for (uint32_t x = l->x0; x < l->x1; x++) {
                size_t t = (size_t)l->face * F * F + y * F + x;
                bad += (paint[t]++ != 0) + (s->owner[t] != k); /* painted twice, or not its owner's */
            }
    }
    for (size_t t = 0; t < n; t++) bad += paint[t] == 0; /* in no light */
    if (area != (double)n) bad += 1.0;
    free(paint);
    return bad;
}

static void case_cover(void)
{
    hl_context *ctx = make_ctx();
    hl_env *city = load_city(ctx);
    double bad = 0.0, geo = 0.0, om = 0.0;
    static const uint32_t Fs[] = {2, 7, 32, 64};
    static const float ts[] = {0.3f, 1e-2f, 1e-3f, 1e-5f};
    for (size_t a = 0; a < 8; a++)
        for (size_t b = 0; b < 4; b++) {
            g_rule = a < 4 ? HL_SPLIT_OF_MAP : HL_SPLIT_OF_LIGHT;
            hl_light_split *s = split(ctx, city, Fs[a % 4], ts[b], 0, 0.0f);
            bad += cover_errors(s);
            const uint32_t F = s->F;
            double sum = 0.0;
            for (uint32_t t = 0; t < F * F; t++) sum += 6.0 * s->texel_omega[t];
            if (fabs(sum - 4.0 * PI) > om) om = fabs(sum - 4.0 * PI);
            for (uint32_t t = 0; t < 6 * F * F; t++) { /* centres: the same as geom.c's mapping */
                float d[3];
                uint32_t f = t / (F * F), r = (t / F) % F, c = t % F;
                hl_cube_face_dir((int)f, 2.0f * ((float)c + 0.5f) / (float)F - 1.0f,
                                 2.0f * ((float)r + 0.5f) / (float)F - 1.0f, d);
                float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                for (int k = 0; k < 3; k++) {
                    double e = fabs(d[k] / l - s->texel_dir[3 * t + (uint32_t)k]);
                    if (e > geo) geo = e;
                }
            }
            hl_light_split_destroy(s);
        }
    hl_env_destroy(city);
    hl_check_error("cover: texels outside exactly one light or its owner, overlaps, bad rectangles (count)", bad, 0.0);
    /* float directions from geom.c: a few ulps of 1 */
    hl_check_error("cover: texel centre directions against hl_cube_face_dir (OpenGL face order)", geo, 1e-6);
    hl_check_error("cover: six faces' closed-form texel solid angles against 4 pi", om, 1e-12);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- sun */

static double angle(const float a[3], const double b[3])
{
    double lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    double c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / lb;
    double x[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    return atan2(sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / lb, c);
}

/* The sun of sun_env at (si, sj) in a W x H map turned by rot: checks the
 * strongest light is one texel at the sun with its energy. */
static int check_sun(const hl_light_split *s, const hl_env *env, uint32_t si, uint32_t sj, double rot, double *dir_err,
                     double *dir_tol, double *e_err, double *spread_err)
{
    const uint32_t W = env->width, H = env->height;
    const float *Ls = env->rgb + 3 * ((size_t)sj * W + si), *Lsky = env->rgb;
    double d[3], a = rot * PI / 180.0;
    dir_of_uv((si + 0.5) / W, (sj + 0.5) / H, d);
    double r[3] = {d[0] * cos(a) + d[2] * sin(a), d[1], -d[0] * sin(a) + d[2] * cos(a)};
    const hl_area_light *l = &s->lights[0];

    /* the sun's centroid lies in its pixel: within half the pixel's
       diagonal (pi / H a side at most) of its centre; the sky in the
       texel pulls it by sky / sun energy times the texel's size */
    double tol = 0.5 * sqrt(2.0) * PI / H + 1e-4, err = angle(l->dir, r);
    if (err / tol > *dir_err / *dir_tol) { *dir_err = err; *dir_tol = tol; }
    double om = pixel_omega(W, H, sj);
    for (int c = 0; c < 3; c++) {
        /* the light is the sun plus the sky of its texel (sub-cells of
           other pixels, at most twice the texel's solid angle) */
        double sun = Ls[c] * om, sky = 2.0 * Lsky[c] * l->omega;
        double e = fabs(l->energy[c] - (sun + Lsky[c] * (l->omega - om))) / (sky + 1e-6 * sun);
        if (e > *e_err) *e_err = e;
    }
    /* the spread is the sun's own size, not its texel's: at most the
       pixel's side (pi / H), where the texel's cone is at least 1.4 of
       its side; the sky's 0.05 against 1e5 adds nothing measurable */
    double sp = l->spread / (PI / H);
    if (sp > *spread_err) *spread_err = sp;
    return l->x1 - l->x0 == 1 && l->y1 - l->y0 == 1; /* one texel */
}

static void case_sun(void)
{
    hl_context *ctx = make_ctx();
    double dir_err = 0.0, dir_tol = 1.0, e_err = 0.0, spread_err = 0.0;
    int single = 0;
    static const uint32_t Fs[] = {16, 32, 64};
    for (size_t f = 0; f < 6; f++)
        for (int k = 0; k < 3; k++) {
            g_rule = f < 3 ? HL_SPLIT_OF_MAP : HL_SPLIT_OF_LIGHT;
            double d[3];
            uint32_t si, sj;
            sun_dir(k, Fs[f % 3], d);
            /* pixels of 22.5 / F degrees: a face corner's texel (about
               38 / F degrees) holds one */
            hl_env *env = sun_env(ctx, 16 * Fs[f % 3], 8 * Fs[f % 3], d, 0.05f, 1e5f, Fs[f % 3], &si, &sj);
            hl_light_split *s = split(ctx, env, Fs[f % 3], 0.0f, 8, 0.0f);
            single += check_sun(s, env, si, sj, 0.0, &dir_err, &dir_tol, &e_err, &spread_err);
            hl_light_split_destroy(s); hl_env_destroy(env);
        }
    hl_check_error("sun: cases where the strongest light is not one texel", 18 - single, 0.0);
    hl_check_error("sun: light direction against the sun pixel's centre (radians; tolerance: half the pixel's "
                   "diagonal + 1e-4)", dir_err, dir_tol);
    hl_check_error("sun: light energy minus the sun's and its texel's sky, over twice the texel's sky + 1e-6 of "
                   "the sun", e_err, 1.0);
    hl_check_error("sun: the light's spread over the sun pixel's side", spread_err, 1.0);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- irradiance */

static double urand(void) { return (double)(hl_rng_next() >> 11) * (1.0 / 9007199254740992.0); }

static void random_unit(float n[3])
{
    double z = 2.0 * urand() - 1.0, a = 2.0 * PI * urand(), r = sqrt(fmax(0.0, 1.0 - z * z));
    n[0] = (float)(r * cos(a)); n[1] = (float)z; n[2] = (float)(r * sin(a));
}

/* A unit normal at cos angle c from dir, about a random axis. */
static void normal_at(const float dir[3], double c, float n[3])
{
    float q[3];
    random_unit(q);
    double p = q[0] * dir[0] + q[1] * dir[1] + q[2] * dir[2], t[3], l = 0.0, s = sqrt(fmax(0.0, 1.0 - c * c));
    for (int k = 0; k < 3; k++) { t[k] = q[k] - p * dir[k]; l += t[k] * t[k]; }
    l = sqrt(l);
    for (int k = 0; k < 3; k++) n[k] = (float)(c * dir[k] + s * t[k] / l);
}

/* The fast irradiance against the texel sum over every light of s:
 * worst error over the light's energy; counts the straddling normals. */
static double fast_vs_ref(const hl_light_split *s, int per_light, uint64_t *straddle)
{
    double worst = 0.0;
    for (uint32_t k = 0; k < s->total; k++) {
        const hl_area_light *l = &s->lights[k];
        double se = sin(l->extent);
        for (int i = 0; i < per_light; i++) {
            float n[3], a[3], b[3];
            if (i % 3 == 0) random_unit(n);
            else /* about the cone's tangent to the horizon */
                normal_at(l->dir, (i % 3 == 1 ? 1.0 : -1.0) * se * (0.9 + 0.2 * urand()), n);
            float nd = n[0] * l->dir[0] + n[1] * l->dir[1] + n[2] * l->dir[2];
            if (fabs(nd) < se) (*straddle)++;
            hl_area_light_irradiance(s, k, n, a);
            hl_area_light_irradiance_ref(s, k, n, b);
            for (int c = 0; c < 3; c++) {
                double e = fabs((double)a[c] - b[c]) / fmax(l->energy[c], 1e-30);
                if (e > worst || !(e == e)) worst = e;
            }
        }
    }
    return worst;
}

/* A constant map of 1: the sum of every light's fast irradiance is pi.
 * The texel sum clamps each texel's moment as a whole, so a texel across
 * the horizon is off by at most its energy times sin(delta), delta the
 * angle from its centre to its farthest sub-cell (its corner plus a
 * sub-cell diagonal): the tolerance is that sum for each normal. */
static void furnace(hl_context *ctx, uint32_t F, double *worst_ratio, double *worst_err)
{
    const uint32_t W = 128, H = 64;
    float *rgb = malloc(sizeof(float) * 3 * W * H);
    for (size_t k = 0; k < (size_t)3 * W * H; k++) rgb[k] = 1.0f;
    hl_env *env = make_env(ctx, W, H, rgb);
    hl_light_split *s = split(ctx, env, F, 1e-3f, 0, 0.0f);
    const size_t nt = (size_t)6 * F * F;
    double *sd = malloc(nt * sizeof *sd), sub = sqrt(2.0) * PI / ((double)H * s->stats.subsamples);
    for (size_t t = 0; t < nt; t++) { /* sin delta of each texel */
        uint32_t f = (uint32_t)(t / (F * F)), r = (uint32_t)(t / F) % F, c = (uint32_t)(t % F);
        double cmin = 1.0;
        for (int k = 0; k < 4; k++) {
            float p[3];
            hl_cube_face_dir((int)f, 2.0f * (float)(c + (k & 1)) / (float)F - 1.0f,
                             2.0f * (float)(r + (k >> 1)) / (float)F - 1.0f, p);
            double lp = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
            const float *w = s->texel_dir + 3 * t;
            double cc = (p[0] * w[0] + p[1] * w[1] + p[2] * w[2]) / lp;
            if (cc < cmin) cmin = cc;
        }
        sd[t] = sin(fmin(0.5 * PI, acos(fmin(1.0, cmin)) + sub));
    }
    for (int i = 0; i < 200; i++) {
        float n[3], e[3];
        random_unit(n);
        double sum = 0.0, tol = 1e-5 * PI; /* float sums */
        for (uint32_t k = 0; k < s->total; k++) {
            hl_area_light_irradiance(s, k, n, e);
            sum += e[1];
        }
        for (size_t t = 0; t < nt; t++) {
            const float *w = s->texel_dir + 3 * t;
            if (fabs(n[0] * w[0] + n[1] * w[1] + n[2] * w[2]) < sd[t]) tol += s->texel_energy[3 * t + 1] * sd[t];
        }
        double err = fabs(sum - PI);
        if (err / tol > *worst_ratio) *worst_ratio = err / tol;
        if (err > *worst_err) *worst_err = err;
    }
    free(sd); hl_light_split_destroy(s);
    hl_env_destroy(env);
}

/* The clamped cosine's residual after band 2: max over c of
 * |max(0, c) - (1/4 + c/2 + 5/32 (3c^2 - 1))| (3/32, at c = 0). */
static double sh_residual(void)
{
    double m = 0.0;
    for (int i = 0; i <= 20000; i++) {
        double c = -1.0 + i / 10000.0, k2 = 0.25 + 0.5 * c + 5.0 / 32.0 * (3.0 * c * c - 1.0);
        m = fmax(m, fabs(fmax(0.0, c) - k2));
    }
    return m;
}

static void case_irradiance(void)
{
    hl_context *ctx = make_ctx();
    hl_env *city = load_city(ctx);
    uint64_t straddle = 0;
    double worst = 0.0;
    static const uint32_t Fs[] = {8, 32};
    for (size_t f = 0; f < 4; f++) {
        g_rule = f < 2 ? HL_SPLIT_OF_MAP : HL_SPLIT_OF_LIGHT;
        hl_light_split *s = split(ctx, city, Fs[f % 2], 0.0f, 0, 0.0f);
        double w = fast_vs_ref(s, Fs[f % 2] == 8 ? 300 : 30, &straddle);
        if (w > worst) worst = w;
        hl_light_split_destroy(s);
    }
    g_rule = HL_SPLIT_OF_MAP;
    printf("irradiance: %llu normals across a light's horizon\n", (unsigned long long)straddle);
    HL_CHECK(straddle > 1000, "too few normals across a horizon: %llu", (unsigned long long)straddle);
    /* n . evec and the texel sum agree where the light is wholly above
       (float sums: evec rounded once, the moments each, 2^-24) */
    hl_check_error("irradiance: fast E_k(n) against the texel sum, over the light's energy", worst, 1e-5);
    double ratio = 0.0;
    for (int r = 0; r < 2; r++) {
        g_rule = r ? HL_SPLIT_OF_LIGHT : HL_SPLIT_OF_MAP;
        for (uint32_t F = 8; F <= 32; F *= 4) {
            double ferr = 0.0;
            furnace(ctx, F, &ratio, &ferr);
            printf("irradiance: constant map of 1, F %u, rule %s: sum of the lights against pi: worst error %.3g "
                   "(%.3g relative)\n", F, rule_name(), ferr, ferr / PI);
        }
    }
    g_rule = HL_SPLIT_OF_MAP;
    hl_check_error("irradiance: constant map, error over its bound (texels across the horizon)", ratio, 1.0);

    /* the folded term: SH9 against its discrete texel sum */
    const double res = sh_residual();
    hl_light_split *s = split(ctx, city, 0, 0.0f, HL_LIGHTS_DEFAULT_KEEP, 0.0f);
    double over = 0.0, rel_ref = 0.0, rms = 0.0, mean = 0.0, kern = 0.0;
    const int NN = 2000;
    for (int i = 0; i < NN; i++) {
        float n[3], a[3], b[3];
        double k2[3] = {0, 0, 0}; /* addition theorem: SH9 of folded deltas is sum e_j K2(n . w_j) */
        random_unit(n);
        hl_light_split_ambient(s, n, a);
        hl_light_split_ambient_ref(s, n, b);
        for (size_t t = 0; t < (size_t)6 * s->F * s->F; t++) {
            const float *w = s->texel_dir + 3 * t;
            double c = n[0] * w[0] + n[1] * w[1] + n[2] * w[2], k = 0.25 + 0.5 * c + 5.0 / 32.0 * (3.0 * c * c - 1.0);
            for (int ch = 0; ch < 3 && s->owner[t] >= s->count; ch++) k2[ch] += k * s->texel_energy[3 * t + (size_t)ch];
        }
        for (int c = 0; c < 3; c++) {
            double e = fabs((double)a[c] - b[c]), fe = s->stats.folded_energy[c];
            kern = fmax(kern, fabs(a[c] - k2[c]) / fe);
            over = fmax(over, e / fe);
            rms += e * e;
            mean += b[c];
            rel_ref = fmax(rel_ref, e / fmax(b[c], 1e-30));
        }
    }
    printf("ambient: %u lights folded, %.3f%% of the energy; SH9 against the texel sum: rms %.3g of the mean "
           "irradiance, worst %.3g of the irradiance at that normal\n",
           s->stats.folded, 100.0 * s->stats.folded_share, sqrt(rms / (3.0 * NN)) / (mean / (3.0 * NN)), rel_ref);
    /* float: 27 coefficients and 9 terms rounded, each within 2^-24 of the folded energy */
    hl_check_error("ambient: SH9 term against sum e_j K2(n . w_j), K2 the band-2 clamped cosine, over the folded "
                   "energy", kern, 1e-5);
    /* each texel's error is at most its energy times the kernel's residual */
    hl_check_error("ambient: SH9 folded term against its texel sum, over the folded energy (bound: the clamped "
                   "cosine's band-2 residual)", over, res + 1e-6);
    hl_light_split_destroy(s); hl_env_destroy(city);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- rotation */

static hl_env *turn_columns(hl_context *ctx, const hl_env *env, uint32_t k)
{
    const uint32_t W = env->width, H = env->height;
    float *rgb = malloc(sizeof(float) * 3 * W * H);
    for (uint32_t j = 0; j < H; j++)
        for (uint32_t i = 0; i < W; i++)
            memcpy(rgb + 3 * ((size_t)j * W + i), env->rgb + 3 * ((size_t)j * W + (i + k) % W), 3 * sizeof(float));
    return make_env(ctx, W, H, rgb);
}

/* Differences between two splits (count of unequal bytes' fields). */
static double split_diff(const hl_light_split *a, const hl_light_split *b)
{
    if (a->total != b->total || a->count != b->count || a->F != b->F) return 1e30;
    const size_t n = (size_t)6 * a->F * a->F;
    double d = 0.0;
    d += memcmp(a->lights, b->lights, a->total * sizeof *a->lights) != 0;
    d += memcmp(a->texel_energy, b->texel_energy, 3 * n * sizeof(float)) != 0;
    d += memcmp(a->texel_moment, b->texel_moment, 9 * n * sizeof(float)) != 0;
    d += memcmp(a->owner, b->owner, n * sizeof(uint32_t)) != 0;
    d += memcmp(a->ambient_sh, b->ambient_sh, sizeof a->ambient_sh) != 0;
    return d;
}

static void case_rotation(void)
{
    hl_context *ctx = make_ctx();
    hl_env *city = load_city(ctx);
    double diff = 0.0;
    /* turns of whole columns of 1024: 360 k / 1024 degrees, exact floats */
    static const int ks[] = {3, 128, -300};
    for (int i = 0; i < 3; i++) {
        g_rule = i == 1 ? HL_SPLIT_OF_LIGHT : HL_SPLIT_OF_MAP;
        float deg = (float)(360.0 * ks[i] / 1024.0), f;
        uint32_t s0; /* the relighter's own shift for --rotate deg */
        hl_rotation_to_shift(deg, 1024, &s0, &f);
        HL_CHECK(f == 0.0f && s0 == (uint32_t)((ks[i] + 1024) % 1024), "relight's shift %u + %g", s0, (double)f);
        hl_env *turned = turn_columns(ctx, city, s0);
        hl_light_split *a = split(ctx, city, 0, 0.0f, HL_LIGHTS_DEFAULT_KEEP, deg);
        hl_light_split *b = split(ctx, turned, 0, 0.0f, HL_LIGHTS_DEFAULT_KEEP, 0.0f);
        double d = split_diff(a, b);
        if (d > 0) printf("  rotate %g: %u / %u lights, differences %g\n", (double)deg, a->total, b->total, d);
        diff += d;
        hl_light_split_destroy(a); hl_light_split_destroy(b);
        hl_env_destroy(turned);
    }
    g_rule = HL_SPLIT_OF_MAP;
    hl_env_destroy(city);
    hl_check_error("rotation: split turned by whole columns against the split of the turned map (unequal arrays)",
                   diff, 0.0);

    /* a fractional turn: the sun goes to R_y(deg) d, where hl_env_query
       (the relighter's convention) also sees it */
    double dir_err = 0.0, dir_tol = 1.0, e_err = 0.0, q_err = 0.0, ign = 0.0;
    static const double rots[] = {30.3, -123.45, 271.0};
    for (int k = 0; k < 3; k++) {
        double d[3], pd[3], a = rots[k] * PI / 180.0;
        uint32_t si, sj;
        sun_dir(k, 32, d);
        hl_env *env = sun_env(ctx, 256, 128, d, 0.05f, 1e5f, 32, &si, &sj);
        hl_light_split *s = split(ctx, env, 32, 0.0f, 8, (float)rots[k]);
        /* turned, the sun pixel may straddle texels: its direction is
           checked, its energy below over all its lights */
        check_sun(s, env, si, sj, rots[k], &dir_err, &dir_tol, &ign, &ign);
        dir_of_uv((si + 0.5) / 256.0, (sj + 0.5) / 128.0, pd);
        float c[3], w[3] = {(float)(pd[0] * cos(a) + pd[2] * sin(a)), (float)pd[1],
                            (float)(-pd[0] * sin(a) + pd[2] * cos(a))};
        hl_env_query(env, w, (float)rots[k], c);
        q_err = fmax(q_err, fabs(c[0] - 1e5) / 1e5);
        double sun = 1e5 * pixel_omega(256, 128, sj), got = 0.0;
        for (uint32_t i = 0; i < s->total; i++)
            if (s->lights[i].energy[0] > 0.05 * sun) got += s->lights[i].energy[0];
        e_err = fmax(e_err, fabs(got - sun) / sun);
        hl_light_split_destroy(s); hl_env_destroy(env);
    }
    hl_check_error("rotation: hl_env_query turned by the same angle sees the sun at R_y(deg) d (relative)", q_err, 0.0);
    hl_check_error("rotation: turned sun's light direction against R_y(deg) d (radians; half the pixel's diagonal "
                   "+ 1e-4)", dir_err, dir_tol);
    /* the sun's lights also hold the sky of their texels: at most a 3 x 3
       block of about 0.0037 sr at 0.05, against 1e5 times the pixel's
       6e-4 sr: 3e-5 */
    hl_check_error("rotation: turned sun's energy in its lights (relative)", e_err, 1e-4);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- bad input */

/* Expects the split to fail with HL_ERR_INVALID_ARGUMENT, *out NULL, and
 * a message holding want (NULL: any). */
static void expect_fail(hl_context *ctx, const hl_env *env, const hl_light_split_params *p, const char *want,
                        const char *what, int *bad)
{
    hl_light_split *s = (hl_light_split *)(uintptr_t)1;
    hl_result r = hl_area_lights_split(ctx, env, p, &s);
    const char *msg = hl_context_last_error(ctx);
    int ok = r == HL_ERR_INVALID_ARGUMENT && s == NULL && (!want || strstr(msg, want));
    printf("%s: %s: %s\n", what, hl_result_string(r), msg);
    if (!ok) {
        (*bad)++;
        HL_CHECK(0, "%s: code %s, out %s, message '%s' (wanted '%s')", what, hl_result_string(r),
                 s ? "set" : "NULL", msg, want ? want : "");
    }
    if (r == HL_OK && s) hl_light_split_destroy(s);
}

static void case_bad_input(void)
{
    hl_context *ctx = make_ctx();
    const uint32_t W = 32, H = 16;
    float *rgb = malloc(sizeof(float) * 3 * W * H);
    for (size_t k = 0; k < (size_t)3 * W * H; k++) rgb[k] = 0.5f;
    hl_env env = {W, H, rgb}; /* built by hand: hl_env_create would repair the NaN */
    hl_light_split_params d, p;
    hl_light_split_defaults(&d);
    int bad = 0;
    p = d; p.face_res = 0;                 expect_fail(ctx, &env, &p, "resolution", "F = 0", &bad);
    p = d; p.face_res = 1;                 expect_fail(ctx, &env, &p, "resolution", "F = 1", &bad);
    p = d; p.face_res = HL_LIGHTS_MAX_FACE + 1; expect_fail(ctx, &env, &p, "resolution", "F too large", &bad);
    p = d; p.threshold = 0.0f;             expect_fail(ctx, &env, &p, "--split-threshold", "t = 0", &bad);
    p = d; p.threshold = 1.0f;             expect_fail(ctx, &env, &p, "--split-threshold", "t = 1", &bad);
    p = d; p.threshold = -0.1f;            expect_fail(ctx, &env, &p, "--split-threshold", "t < 0", &bad);
    p = d; p.threshold = NAN;              expect_fail(ctx, &env, &p, "--split-threshold", "t NaN", &bad);
    p = d; p.lights = -1;                  expect_fail(ctx, &env, &p, "--lights", "K = -1", &bad);
    p = d; p.rule = (hl_split_rule)7;      expect_fail(ctx, &env, &p, "rule", "unknown rule", &bad);
    p = d; p.rotate_deg = INFINITY;        expect_fail(ctx, &env, &p, "--rotate", "rotate Inf", &bad);
    expect_fail(ctx, &env, NULL, NULL, "no parameters", &bad);
    expect_fail(ctx, NULL, &d, "environment", "no environment", &bad);
    hl_env odd = {W, H + 1, rgb};
    expect_fail(ctx, &odd, &d, "2:1", "not 2:1", &bad);
    rgb[3 * 37 + 1] = NAN;       expect_fail(ctx, &env, &d, "pixel (5, 1) channel 1", "a NaN pixel", &bad);
    rgb[3 * 37 + 1] = INFINITY;  expect_fail(ctx, &env, &d, "not finite", "an Inf pixel", &bad);
    rgb[3 * 37 + 1] = -1e-3f;    expect_fail(ctx, &env, &d, "non-negative", "a negative pixel", &bad);
    rgb[3 * 37 + 1] = 0.5f;

    /* the edges of the valid range work, and a black map too */
    hl_light_split *s = NULL;
    p = d; p.face_res = HL_LIGHTS_MIN_FACE; p.threshold = 0.999f; p.lights = 1000000;
    HL_CHECK(hl_area_lights_split(ctx, &env, &p, &s) == HL_OK, "edge parameters: %s", hl_context_last_error(ctx));
    if (s) HL_CHECK(s->count == s->total && s->stats.folded == 0, "K above the count keeps all");
    hl_light_split_destroy(s); s = NULL;
    for (size_t k = 0; k < (size_t)3 * W * H; k++) rgb[k] = 0.0f;
    HL_CHECK(hl_area_lights_split(ctx, &env, &d, &s) == HL_OK, "black map: %s", hl_context_last_error(ctx));
    if (s) {
        HL_CHECK(s->total == 6, "black map: %u lights, expected one a face", s->total);
        HL_CHECK(cover_errors(s) == 0.0, "black map: cover");
        float n[3] = {0, 1, 0}, e[3];
        hl_area_light_irradiance(s, 0, n, e);
        HL_CHECK(e[0] == 0.0f && e[1] == 0.0f && e[2] == 0.0f, "black map: light irradiance not 0");
        hl_light_split_ambient(s, n, e);
        HL_CHECK(e[0] == 0.0f, "black map: ambient not 0");
    }
    hl_light_split_destroy(s); free(rgb);
    hl_check_error("bad_input: bad parameters or maps accepted, or without a clear message (count)", bad, 0.0);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"energy", case_energy}, {"energy_shared", case_energy_shared}, {"cover", case_cover}, {"sun", case_sun},
        {"irradiance", case_irradiance}, {"rotation", case_rotation}, {"bad_input", case_bad_input}, {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
