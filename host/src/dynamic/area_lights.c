/* area_lights.c - the environment split into area lights (DYNAMIC.md
 * sections 1 and 2, after Annen et al. 2008).
 *
 * The map is resampled onto six F x F cube faces by area: each map pixel
 * is cut into S x S latitude-longitude sub-cells whose solid angle and
 * first moment (the integral of w dw) have closed forms, and each sub-cell
 * goes whole to the cube texel holding its centre, so the cube keeps the
 * map's energy exactly (to double rounding) and each texel its moment.
 * Each face is then split greedily into rectangles (seeds by radiance
 * luminance, rings grown against the map's energy as DYNAMIC.md says, or
 * against the light's own, hl_split_rule), the lights sorted by luminance
 * of energy, the K strongest kept and the rest projected onto 9 spherical
 * harmonics (an unshadowed term).
 *
 * Plain C on the host, no kernel: the split runs once per environment or
 * rotation, is sequential and greedy, and its output is small (tens of
 * lights), so a device would gain nothing.
 * Depends on: area_lights.h, dynamic.h, core (hl_fail, hl_malloc), libm.
 */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "area_lights.h"
#include "hl_internal.h"

/* Sub-cells per narrowest cube texel width, along each axis. 4: a
 * sub-cell is at most a quarter of a texel, so the texels' share of a
 * map pixel that straddles their edge is right to a quarter texel; the
 * map's energy is kept exactly whatever S is. */
#define HL_LIGHTS_SUB_PER_TEXEL 4.0
/* Most sub-cells per pixel side: bounds the work (W H S^2 sub-cells) for
 * tiny maps on fine cubes, where a pixel covers many texels. 64. */
#define HL_LIGHTS_MAX_SUB 64u

/* Luminance of linear Rec.709 RGB, as hl_luminance (hl_shared.h), in
 * double for the sums. */
static double lum3(const double *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }
static double lum3f(const float *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

void hl_light_split_defaults(hl_light_split_params *p)
{
    /* the light-relative rule: the map-relative one of DYNAMIC.md grows
       the bright lights into whole faces and leaves a sun inside a face
       (HL_LIGHTS_DEFAULT_THRESHOLD's numbers), and a shadow's sharpness
       comes from its light's extent */
    p->face_res = HL_LIGHTS_DEFAULT_FACE;
    p->threshold = HL_LIGHTS_DEFAULT_THRESHOLD_OF_LIGHT;
    p->lights = HL_LIGHTS_DEFAULT_KEEP;
    p->rule = HL_SPLIT_OF_LIGHT;
    p->rotate_deg = 0.0f;
}

/* A point (s, t) in [-1, 1]^2 of a face, unnormalised: the same mapping as
 * geom.c's hl_cube_face_dir (OpenGL order +X -X +Y -Y +Z -Z), in double. */
static void face_point(uint32_t face, double s, double t, double d[3])
{
    switch (face) {
    case 0: d[0] = 1.0; d[1] = -t; d[2] = -s; break;
    case 1: d[0] = -1.0; d[1] = -t; d[2] = s; break;
    case 2: d[0] = s; d[1] = 1.0; d[2] = t; break;
    case 3: d[0] = s; d[1] = -1.0; d[2] = -t; break;
    case 4: d[0] = s; d[1] = -t; d[2] = 1.0; break;
    default: d[0] = -s; d[1] = -t; d[2] = -1.0; break;
    }
}

static void normalise(double d[3])
{
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (l > 0.0)
        for (int i = 0; i < 3; i++) d[i] /= l;
}

/* The cube texel holding direction d (the inverse of face_point). */
static uint32_t texel_of(const double d[3], uint32_t F)
{
    double ax = fabs(d[0]), ay = fabs(d[1]), az = fabs(d[2]), s, t, m;
    uint32_t face;
    if (ax >= ay && ax >= az) {
        m = ax; t = -d[1];
        if (d[0] >= 0) { face = 0; s = -d[2]; } else { face = 1; s = d[2]; }
    } else if (ay >= az) {
        m = ay; s = d[0];
        if (d[1] >= 0) { face = 2; t = d[2]; } else { face = 3; t = -d[2]; }
    } else {
        m = az; t = -d[1];
        if (d[2] >= 0) { face = 4; s = d[0]; } else { face = 5; s = -d[0]; }
    }
    double h = 0.5 * F / m, cs = floor(s * h + 0.5 * F), ct = floor(t * h + 0.5 * F);
    uint32_t col = cs < 0 ? 0 : cs >= F ? F - 1 : (uint32_t)cs;
    uint32_t row = ct < 0 ? 0 : ct >= F ? F - 1 : (uint32_t)ct;
    return face * F * F + row * F + col;
}

/* Solid angle of the face region [0, x] x [0, y] seen from the cube's
 * centre at distance 1 (signed): atan(x y / sqrt(1 + x^2 + y^2)). */
static double face_area(double x, double y) { return atan2(x * y, sqrt(1.0 + x * x + y * y)); }

void hl_light_sh9(const double w[3], double y[9])
{
    const double x = w[0], yy = w[1], z = w[2];
    const double c0 = 0.5 * sqrt(1.0 / HL_PI), c1 = sqrt(3.0 / (4.0 * HL_PI)), c2 = sqrt(15.0 / (4.0 * HL_PI)),
                 c20 = sqrt(5.0 / (16.0 * HL_PI)), c22 = sqrt(15.0 / (16.0 * HL_PI));
    y[0] = c0;
    y[1] = c1 * yy; y[2] = c1 * z; y[3] = c1 * x;
    y[4] = c2 * x * yy; y[5] = c2 * yy * z; y[6] = c20 * (3.0 * z * z - 1.0); y[7] = c2 * x * z;
    y[8] = c22 * (x * x - yy * yy);
}

/* ---------------------------------------------------------------- checks */

static hl_result check_params(hl_context *ctx, const hl_light_split_params *p)
{
    if (!p) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "area lights: no parameters given");
    if (p->face_res < HL_LIGHTS_MIN_FACE || p->face_res > HL_LIGHTS_MAX_FACE)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "area lights: cube face resolution %u is outside %u..%u",
                       p->face_res, HL_LIGHTS_MIN_FACE, HL_LIGHTS_MAX_FACE);
    if (!(p->threshold > 0.0f && p->threshold < 1.0f))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "--split-threshold %g: must be above 0 and below 1 (the share of the map's energy a "
                       "ring must add for a light to grow)", (double)p->threshold);
    if (p->rule != HL_SPLIT_OF_MAP && p->rule != HL_SPLIT_OF_LIGHT)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "area lights: unknown split rule %d", (int)p->rule);
    if (p->lights < 0)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--lights %d: must be 0 (keep all) or a positive count",
                       (int)p->lights);
    if (!isfinite(p->rotate_deg))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "--rotate %g: must be a finite angle in degrees",
                       (double)p->rotate_deg);
    return HL_OK;
}

static hl_result check_env(hl_context *ctx, const hl_env *env)
{
    if (!env || !env->rgb || env->height == 0 || env->width != 2 * env->height)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "area lights: the environment must be a 2:1 map with pixels");
    size_t n = (size_t)env->width * env->height * 3, bad = 0, first = 0;
    for (size_t i = 0; i < n; i++) {
        float x = env->rgb[i];
        if (!(isfinite(x) && x >= 0.0f)) {
            if (!bad) first = i;
            bad++;
        }
    }
    if (bad) {
        size_t px = first / 3;
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "area lights: the environment has %zu channel%s that %s not finite and >= 0 (first: pixel "
                       "(%zu, %zu) channel %zu = %g); radiance must be finite and non-negative",
                       bad, bad == 1 ? "" : "s", bad == 1 ? "is" : "are", px % env->width, px / env->width,
                       first % 3, (double)env->rgb[first]);
    }
    return HL_OK;
}

/* ---------------------------------------------------------------- resampling */

/* Per sub-row of the map (H S): solid-angle factor, the sin^2 and sin cos
 * integrals over theta, and the centre's sin and cos. */
typedef struct sub_row { double dz, is2, isc, st, ct; } sub_row;
/* Per sub-column (W S, in destination order): the integrals of cos and
 * sin over phi, the centre's cos and sin, and the source pixel column. */
typedef struct sub_col { double icos, isin, cp, sp; uint32_t src; } sub_col;

/* The rotation as a shift of the map by s0 whole columns plus a fraction
 * f, as relight's --rotate does it (light_tables.c's
 * hl_rotation_to_shift): destination column i' shows source column
 * (i' + s0) mod W moved left by f. Whole shifts so give bit-identical
 * sub-cells to a map whose columns were turned. */
static void rotation_shift(float rotate_deg, uint32_t W, uint32_t *s0, double *f)
{
    double s = fmod((double)rotate_deg / 360.0 * W, (double)W);
    if (s < 0) s += W;
    double w = floor(s);
    *s0 = (uint32_t)w % W;
    *f = s - w;
}

static void sub_tables(uint32_t W, uint32_t H, uint32_t S, float rotate_deg, sub_row *rows, sub_col *cols)
{
    for (uint32_t r = 0; r < H * S; r++) {
        double ta = HL_PI * ((double)r / S) / H, tb = HL_PI * ((double)(r + 1) / S) / H, d = tb - ta;
        double tm = 0.5 * (ta + tb);
        rows[r].dz = 2.0 * sin(tm) * sin(0.5 * d);           /* cos ta - cos tb */
        rows[r].is2 = 0.5 * d - 0.5 * cos(ta + tb) * sin(d); /* integral of sin^2 */
        rows[r].isc = 0.5 * sin(ta + tb) * sin(d);           /* integral of sin cos */
        rows[r].st = sin(tm);
        rows[r].ct = cos(tm);
    }
    uint32_t s0;
    double f;
    rotation_shift(rotate_deg, W, &s0, &f);
    const double dphi = 2.0 * HL_PI / ((double)W * S);
    for (uint32_t i = 0; i < W; i++)
        for (uint32_t a = 0; a < S; a++) {
            double x = (double)i + (double)a / S - f; /* left edge, in pixels */
            double pa = 2.0 * HL_PI * (x / W - 0.5), pm = pa + 0.5 * dphi;
            sub_col *c = cols + (size_t)i * S + a;
            c->icos = 2.0 * cos(pm) * sin(0.5 * dphi); /* sin pb - sin pa */
            c->isin = 2.0 * sin(pm) * sin(0.5 * dphi); /* cos pa - cos pb */
            c->cp = cos(pm);
            c->sp = sin(pm);
            c->src = (i + s0) % W;
        }
}

/* Adds a run of sub-cells of one sub-row R that fell in texel t: a holds
 * per channel the sums of L, L icos and L isin, which the row's factors
 * turn into energy and moment. */
static void flush_run(uint32_t t, const double *a, const sub_row *R, double dphi, double *energy, double *moment)
{
    for (int c = 0; c < 3; c++) {
        energy[3 * (size_t)t + c] += a[3 * c] * dphi * R->dz;
        moment[9 * (size_t)t + 3 * c] += R->is2 * a[3 * c + 1];
        moment[9 * (size_t)t + 3 * c + 1] += R->isc * dphi * a[3 * c];
        moment[9 * (size_t)t + 3 * c + 2] += R->is2 * a[3 * c + 2];
    }
}

/* Adds every sub-cell's energy (3) and moment (9) to its cube texel. Along
 * a sub-row the solid angle and the theta integrals are constant, so runs
 * of sub-cells in one texel are summed first. */
static void resample(const hl_env *env, uint32_t F, uint32_t S, const sub_row *rows, const sub_col *cols,
                     double *energy, double *moment)
{
    const uint32_t W = env->width, H = env->height;
    const double dphi = 2.0 * HL_PI / ((double)W * S);
    for (uint32_t r = 0; r < H * S; r++) {
        const sub_row *R = rows + r;
        const float *line = env->rgb + (size_t)(r / S) * W * 3;
        uint32_t cur = UINT32_MAX;
        double a[9] = {0};
        for (uint32_t q = 0; q < W * S; q++) {
            const sub_col *C = cols + q;
            const float *L = line + (size_t)C->src * 3;
            if (L[0] == 0.0f && L[1] == 0.0f && L[2] == 0.0f) continue;
            double d[3] = {R->st * C->cp, R->ct, R->st * C->sp};
            uint32_t t = texel_of(d, F);
            if (t != cur) {
                if (cur != UINT32_MAX) flush_run(cur, a, R, dphi, energy, moment);
                memset(a, 0, sizeof a);
                cur = t;
            }
            for (int c = 0; c < 3; c++) {
                double l = L[c];
                a[3 * c] += l;
                a[3 * c + 1] += l * C->icos;
                a[3 * c + 2] += l * C->isin;
            }
        }
        if (cur != UINT32_MAX) flush_run(cur, a, R, dphi, energy, moment);
    }
}

/* ---------------------------------------------------------------- the split */

typedef struct rect { uint32_t face, x0, y0, x1, y1; } rect;

/* Whether texels (x, y0..y1-1) (vertical) or (x0..x1-1, y) are all free,
 * and their luminance energy. */
static int strip_free(const uint8_t *taken, const double *ye, uint32_t F, uint32_t x0, uint32_t y0, uint32_t x1,
                      uint32_t y1, double *sum)
{
    for (uint32_t y = y0; y < y1; y++)
        for (uint32_t x = x0; x < x1; x++) {
            if (taken[y * F + x]) return 0;
            *sum += ye[y * F + x];
        }
    return 1;
}

/* Grows the rectangle seeded at (sx, sy) one ring at a time while the ring
 * adds more than thr of luminance energy (every ring where thr < 0), or,
 * with of_light, more than t times the light's energy so far. A side that
 * would leave the face or meet a taken texel stops for good (taken texels
 * stay taken, so it could never grow again); the other sides go on. Each
 * ring's strips are checked in the order left, right, top, bottom, the
 * later ones spanning the earlier ones' growth, so the corners are checked
 * once. A ring below the threshold is not added. */
static rect grow(uint8_t *taken, const double *ye, uint32_t F, uint32_t sx, uint32_t sy, double thr, int of_light,
                 double t)
{
    uint32_t x0 = sx, x1 = sx + 1, y0 = sy, y1 = sy + 1;
    double have = ye[sy * F + sx];
    int open[4] = {1, 1, 1, 1};
    taken[sy * F + sx] = 1;
    for (;;) {
        uint32_t nx0 = x0, nx1 = x1, ny0 = y0, ny1 = y1;
        double add = 0.0;
        if (open[0] && !(x0 > 0 && strip_free(taken, ye, F, x0 - 1, y0, x0, y1, &add))) open[0] = 0;
        if (open[0]) nx0 = x0 - 1;
        if (open[1] && !(x1 < F && strip_free(taken, ye, F, x1, y0, x1 + 1, y1, &add))) open[1] = 0;
        if (open[1]) nx1 = x1 + 1;
        if (open[2] && !(y0 > 0 && strip_free(taken, ye, F, nx0, y0 - 1, nx1, y0, &add))) open[2] = 0;
        if (open[2]) ny0 = y0 - 1;
        if (open[3] && !(y1 < F && strip_free(taken, ye, F, nx0, y1, nx1, y1 + 1, &add))) open[3] = 0;
        if (open[3]) ny1 = y1 + 1;
        if (!(open[0] || open[1] || open[2] || open[3])) break;
        /* a light of no energy yet is black, as all that is left of its
           face (its seed was the brightest): it takes every ring */
        if (of_light ? !(have <= 0.0 || add > t * have) : !(thr < 0.0 || add > thr)) break;
        have += add;
        for (uint32_t y = ny0; y < ny1; y++)
            for (uint32_t x = nx0; x < nx1; x++) taken[y * F + x] = 1;
        x0 = nx0; x1 = nx1; y0 = ny0; y1 = ny1;
    }
    rect r = {0, x0, y0, x1, y1};
    return r;
}

/* A sort key and the index it belongs to (qsort has no context). */
typedef struct keyed { double key; uint32_t i; } keyed;
static int by_key_desc(const void *a, const void *b)
{
    const keyed *p = a, *q = b;
    if (p->key != q->key) return p->key > q->key ? -1 : 1;
    return p->i < q->i ? -1 : p->i > q->i; /* ties: index order, so the split is deterministic */
}

/* Splits every face; returns the rectangles (*n of them) or NULL. */
static rect *split_faces(hl_context *ctx, const hl_light_split *s, double thr, int of_light, double tr, uint32_t *n)
{
    const uint32_t F = s->F, T = F * F;
    rect *rs = hl_malloc(ctx, (size_t)6 * T * sizeof *rs, "area lights");
    uint8_t *taken = hl_calloc(ctx, T, 1, "area lights");
    double *ye = hl_malloc(ctx, (size_t)T * sizeof(double), "area lights");
    keyed *order = hl_malloc(ctx, (size_t)T * sizeof *order, "area lights");
    *n = 0;
    if (!rs || !taken || !ye || !order) {
        free(rs); free(taken); free(ye); free(order);
        return NULL;
    }
    for (uint32_t face = 0; face < 6; face++) {
        memset(taken, 0, T);
        for (uint32_t t = 0; t < T; t++) {
            ye[t] = lum3f(s->texel_energy + 3 * ((size_t)face * T + t));
            order[t].key = lum3f(s->texel_radiance + 3 * ((size_t)face * T + t));
            order[t].i = t;
        }
        /* seeds: the brightest radiance luminance first */
        qsort(order, T, sizeof *order, by_key_desc);
        for (uint32_t k = 0; k < T; k++) {
            uint32_t t = order[k].i;
            if (taken[t]) continue;
            rect r = grow(taken, ye, F, t % F, t / F, thr, of_light, tr);
            r.face = face;
            rs[(*n)++] = r;
        }
    }
    free(taken); free(ye); free(order);
    return rs;
}

/* Fills light l from its rectangle: sums over its texels, centroid, cone. */
static void fill_light(const hl_light_split *s, rect r, hl_area_light *l)
{
    const uint32_t F = s->F;
    double e[3] = {0, 0, 0}, m[9] = {0}, om = 0.0, g[3] = {0, 0, 0};
    for (uint32_t y = r.y0; y < r.y1; y++)
        for (uint32_t x = r.x0; x < r.x1; x++) {
            size_t t = (size_t)r.face * F * F + y * F + x;
            for (int c = 0; c < 3; c++) e[c] += s->texel_energy[3 * t + c];
            for (int k = 0; k < 9; k++) m[k] += s->texel_moment[9 * t + k];
            om += s->texel_omega[y * F + x];
            for (int k = 0; k < 3; k++) g[k] += s->texel_omega[y * F + x] * s->texel_dir[3 * t + k];
        }
    /* centroid: luminance-weighted moment; a black light takes its
       geometric centre instead */
    double d[3];
    for (int k = 0; k < 3; k++) d[k] = 0.2126 * m[k] + 0.7152 * m[3 + k] + 0.0722 * m[6 + k];
    if (!(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > 0.0)) memcpy(d, g, sizeof d);
    /* spread: for directions of small angles (x, y) about the mean,
       1 - |mean| = (var x + var y) / 2, and a uniform square of
       half-side a has var = a^2 / 3 per axis */
    double lum = 0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2], mlen = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    double wsum = lum > 0.0 ? lum : om, rbar = wsum > 0.0 ? mlen / wsum : 1.0;
    if (!(lum > 0.0)) rbar = om > 0.0 ? sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) / om : 1.0;
    l->spread = (float)atan(sqrt(3.0 * fmax(1.0 - rbar, 0.0)));
    normalise(d);
    double cosmin = 1.0;
    for (int k = 0; k < 4; k++) {
        double cx = (double)(k & 1 ? r.x1 : r.x0), cy = (double)(k & 2 ? r.y1 : r.y0), p[3];
        face_point(r.face, 2.0 * cx / F - 1.0, 2.0 * cy / F - 1.0, p);
        normalise(p);
        double c = d[0] * p[0] + d[1] * p[1] + d[2] * p[2];
        if (c < cosmin) cosmin = c;
    }
    for (int k = 0; k < 3; k++) l->dir[k] = (float)d[k];
    l->extent = (float)acos(fmax(-1.0, fmin(1.0, cosmin)));
    l->omega = (float)om;
    for (int c = 0; c < 3; c++) {
        l->energy[c] = (float)e[c];
        l->radiance[c] = (float)(om > 0.0 ? e[c] / om : 0.0);
        for (int k = 0; k < 3; k++) l->evec[c][k] = (float)m[3 * c + k];
    }
    l->face = r.face; l->x0 = r.x0; l->y0 = r.y0; l->x1 = r.x1; l->y1 = r.y1;
}

/* ---------------------------------------------------------------- building */

/* The per-texel geometry: one face's solid angles, every centre. */
static void texel_geometry(hl_light_split *s)
{
    const uint32_t F = s->F;
    for (uint32_t y = 0; y < F; y++)
        for (uint32_t x = 0; x < F; x++) {
            double a = 2.0 * x / F - 1.0, b = 2.0 * (x + 1) / F - 1.0, c = 2.0 * y / F - 1.0,
                   e = 2.0 * (y + 1) / F - 1.0;
            s->texel_omega[y * F + x] = face_area(b, e) - face_area(a, e) - face_area(b, c) + face_area(a, c);
            for (uint32_t face = 0; face < 6; face++) {
                double d[3];
                face_point(face, 2.0 * (x + 0.5) / F - 1.0, 2.0 * (y + 0.5) / F - 1.0, d);
                normalise(d);
                float *o = s->texel_dir + 3 * ((size_t)face * F * F + y * F + x);
                for (int k = 0; k < 3; k++) o[k] = (float)d[k];
            }
        }
}

/* Resamples env onto the cube: texel energy, moment, radiance. */
static hl_result build_cube(hl_context *ctx, const hl_env *env, float rotate_deg, hl_light_split *s)
{
    const uint32_t F = s->F, W = env->width, H = env->height;
    const size_t n = (size_t)6 * F * F;
    /* S from the narrowest texel (a face corner, about 2 / (3 F) radians)
       against the widest pixel (pi / H radians, at the equator) */
    double want = ceil(HL_LIGHTS_SUB_PER_TEXEL * (HL_PI / H) / (2.0 / (3.0 * F)));
    uint32_t S = want < 1.0 ? 1u : want > HL_LIGHTS_MAX_SUB ? HL_LIGHTS_MAX_SUB : (uint32_t)want;
    s->stats.subsamples = S;
    sub_row *rows = hl_malloc(ctx, (size_t)H * S * sizeof *rows, "area lights: map rows");
    sub_col *cols = hl_malloc(ctx, (size_t)W * S * sizeof *cols, "area lights: map columns");
    double *e = hl_calloc(ctx, n * 12, sizeof(double), "area lights: cube texels");
    if (!rows || !cols || !e) {
        free(rows); free(cols); free(e);
        return HL_ERR_OUT_OF_MEMORY;
    }
    sub_tables(W, H, S, rotate_deg, rows, cols);
    resample(env, F, S, rows, cols, e, e + 3 * n);
    for (size_t t = 0; t < n; t++) {
        double om = s->texel_omega[t % ((size_t)F * F)];
        for (int c = 0; c < 3; c++) {
            s->texel_energy[3 * t + (size_t)c] = (float)e[3 * t + (size_t)c];
            s->texel_radiance[3 * t + (size_t)c] = (float)(e[3 * t + (size_t)c] / om);
        }
        for (int k = 0; k < 9; k++) s->texel_moment[9 * t + (size_t)k] = (float)e[3 * n + 9 * t + (size_t)k];
    }
    for (int c = 0; c < 3; c++) {
        double tot = 0.0;
        for (size_t t = 0; t < n; t++) tot += e[3 * t + (size_t)c];
        s->stats.total_energy[c] = tot;
    }
    free(rows); free(cols); free(e);
    return HL_OK;
}

/* Sorts the lights by luminance energy, keeps K, projects the rest. */
static hl_result fold(hl_context *ctx, hl_light_split *s, rect *rs, uint32_t K)
{
    const uint32_t n = s->total, F = s->F;
    keyed *order = hl_malloc(ctx, (size_t)n * sizeof *order, "area lights");
    uint32_t *rank = hl_malloc(ctx, (size_t)n * sizeof *rank, "area lights");
    hl_area_light *tmp = hl_malloc(ctx, (size_t)n * sizeof *tmp, "area lights");
    if (!order || !rank || !tmp) {
        free(order); free(rank); free(tmp);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t i = 0; i < n; i++) {
        order[i].key = lum3f(s->lights[i].energy);
        order[i].i = i;
    }
    qsort(order, n, sizeof *order, by_key_desc);
    for (uint32_t i = 0; i < n; i++) {
        tmp[i] = s->lights[order[i].i];
        rank[order[i].i] = i;
    }
    memcpy(s->lights, tmp, (size_t)n * sizeof *tmp);
    for (uint32_t i = 0; i < n; i++) {
        rect r = rs[i];
        for (uint32_t y = r.y0; y < r.y1; y++)
            for (uint32_t x = r.x0; x < r.x1; x++) s->owner[(size_t)r.face * F * F + y * F + x] = rank[i];
    }
    s->count = (K == 0 || K > n) ? n : K;
    double sh[9][3] = {{0}}, fe[3] = {0, 0, 0};
    for (size_t t = 0; t < (size_t)6 * F * F; t++) {
        if (s->owner[t] < s->count) continue;
        double w[3] = {s->texel_dir[3 * t], s->texel_dir[3 * t + 1], s->texel_dir[3 * t + 2]}, y[9];
        hl_light_sh9(w, y);
        for (int c = 0; c < 3; c++) {
            double e = s->texel_energy[3 * t + (size_t)c];
            fe[c] += e;
            for (int k = 0; k < 9; k++) sh[k][c] += e * y[k];
        }
    }
    for (int k = 0; k < 9; k++)
        for (int c = 0; c < 3; c++) s->ambient_sh[k][c] = (float)sh[k][c];
    s->stats.lights_before = n;
    s->stats.folded = n - s->count;
    double tot = lum3(s->stats.total_energy);
    s->stats.folded_share = tot > 0.0 ? lum3(fe) / tot : 0.0;
    memcpy(s->stats.folded_energy, fe, sizeof fe);
    free(order); free(rank); free(tmp);
    return HL_OK;
}

static hl_result split_all(hl_context *ctx, const hl_env *env, const hl_light_split_params *p, hl_light_split *s)
{
    const size_t n = (size_t)6 * s->F * s->F;
    s->texel_energy = hl_malloc(ctx, n * 3 * sizeof(float), "area lights: cube texels");
    s->texel_moment = hl_malloc(ctx, n * 9 * sizeof(float), "area lights: cube texels");
    s->texel_radiance = hl_malloc(ctx, n * 3 * sizeof(float), "area lights: cube texels");
    s->texel_dir = hl_malloc(ctx, n * 3 * sizeof(float), "area lights: cube texels");
    s->owner = hl_malloc(ctx, n * sizeof(uint32_t), "area lights: cube texels");
    s->texel_omega = hl_malloc(ctx, (size_t)s->F * s->F * sizeof(double), "area lights: cube texels");
    s->row_moment = hl_malloc(ctx, (size_t)6 * s->F * (s->F + 1) * 9 * sizeof(double), "area lights: cube rows");
    if (!s->texel_energy || !s->texel_moment || !s->texel_radiance || !s->texel_dir || !s->owner || !s->texel_omega ||
        !s->row_moment)
        return HL_ERR_OUT_OF_MEMORY;
    memset(s->owner, 0xFF, n * sizeof(uint32_t)); /* no light yet */
    texel_geometry(s);
    hl_result res = build_cube(ctx, env, p->rotate_deg, s);
    if (res != HL_OK) return res;
    for (size_t row = 0; row < (size_t)6 * s->F; row++) { /* the stored float moments, summed in double */
        double *P = s->row_moment + row * (s->F + 1) * 9;
        for (int k = 0; k < 9; k++) P[k] = 0.0;
        for (uint32_t x = 0; x < s->F; x++)
            for (int k = 0; k < 9; k++) P[9 * (x + 1) + k] = P[9 * x + k] + s->texel_moment[9 * (row * s->F + x) + k];
    }
    /* a black map has nothing to tell regions apart: every ring is added,
       one light a face */
    double tot = lum3(s->stats.total_energy), thr = tot > 0.0 ? (double)p->threshold * tot : -1.0;
    uint32_t nr = 0;
    rect *rs = split_faces(ctx, s, thr, p->rule == HL_SPLIT_OF_LIGHT, (double)p->threshold, &nr);
    if (!rs) return HL_ERR_OUT_OF_MEMORY;
    s->total = nr;
    s->lights = hl_calloc(ctx, nr, sizeof *s->lights, "area lights");
    if (!s->lights) {
        free(rs);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t i = 0; i < nr; i++) fill_light(s, rs[i], &s->lights[i]);
    res = fold(ctx, s, rs, (uint32_t)p->lights);
    free(rs);
    return res;
}

hl_result hl_area_lights_split(hl_context *ctx, const hl_env *env, const hl_light_split_params *p,
                               hl_light_split **out)
{
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "area lights: no output given");
    *out = NULL;
    double t0 = hl_now();
    hl_result res = check_params(ctx, p);
    if (res == HL_OK) res = check_env(ctx, env);
    if (res != HL_OK) return res;
    hl_light_split *s = hl_calloc(ctx, 1, sizeof *s, "area lights");
    if (!s) return HL_ERR_OUT_OF_MEMORY;
    static atomic_uint_fast64_t serials;
    s->serial = atomic_fetch_add(&serials, 1u) + 1u;
    s->F = p->face_res;
    s->stats.texels_per_face = s->F * s->F;
    res = split_all(ctx, env, p, s);
    if (res != HL_OK) {
        hl_light_split_destroy(s);
        return res;
    }
    s->stats.seconds = hl_now() - t0;
    *out = s;
    return HL_OK;
}

void hl_light_split_destroy(hl_light_split *s)
{
    if (!s) return;
    free(s->lights);
    free(s->texel_energy);
    free(s->texel_moment);
    free(s->texel_radiance);
    free(s->texel_dir);
    free(s->owner);
    free(s->texel_omega);
    free(s->row_moment);
    free(s);
}

/* ---------------------------------------------------------------- irradiance */

void hl_area_light_irradiance_ref(const hl_light_split *s, uint32_t k, const float n[3], float rgb[3])
{
    const hl_area_light *l = &s->lights[k];
    const uint32_t F = s->F;
    double acc[3] = {0, 0, 0};
    for (uint32_t y = l->y0; y < l->y1; y++)
        for (uint32_t x = l->x0; x < l->x1; x++) {
            const float *m = s->texel_moment + 9 * ((size_t)l->face * F * F + y * F + x);
            for (int c = 0; c < 3; c++) {
                double d = (double)n[0] * m[3 * c] + (double)n[1] * m[3 * c + 1] + (double)n[2] * m[3 * c + 2];
                if (d > 0.0) acc[c] += d;
            }
        }
    for (int c = 0; c < 3; c++) rgb[c] = (float)acc[c];
}

/* The first texel index x with s_x = 2 x / F - 1 >= v (ceil) or the last
 * with s_x <= v (floor), clamped to [lo, hi]; v may be huge. */
static uint32_t texel_edge(double v, uint32_t F, int up, uint32_t lo, uint32_t hi)
{
    double x = (v + 1.0) * 0.5 * F;
    x = up ? ceil(x) : floor(x);
    return x <= lo ? lo : x >= hi ? hi : (uint32_t)x;
}

/* The texel sum of light l on n, one row at a time. On a face,
 * n . face_point(s, t) = g0 + gs s + gt t; in row y its least value over
 * the row's two t edges is lo + gs s, its largest hi + gs s. Texels whose
 * corners are all above are one run [a0, a1), those all below another;
 * the run above is summed from the prefix sums, the rest one by one. A
 * texel put in a run by rounding has a corner within rounding of the
 * horizon, so its n . moment is 0 to that rounding either way. */
static void straddle_sum(const hl_light_split *s, const hl_area_light *l, const float n[3], double acc[3])
{
    const uint32_t F = s->F;
    double o[3], e[3], f[3], g0 = 0.0, gs = 0.0, gt = 0.0;
    face_point(l->face, 0.0, 0.0, o);
    face_point(l->face, 1.0, 0.0, e);
    face_point(l->face, 0.0, 1.0, f);
    for (int k = 0; k < 3; k++) {
        g0 += n[k] * o[k];
        gs += n[k] * (e[k] - o[k]);
        gt += n[k] * (f[k] - o[k]);
    }
    for (uint32_t y = l->y0; y < l->y1; y++) {
        double t0 = 2.0 * y / F - 1.0, t1 = 2.0 * (y + 1) / F - 1.0;
        double lo = g0 + (gt > 0 ? gt * t0 : gt * t1), hi = g0 + (gt > 0 ? gt * t1 : gt * t0);
        uint32_t a0 = l->x0, a1 = l->x0, b0 = l->x0, b1 = l->x0; /* runs above and below */
        if (gs == 0.0) {
            if (lo >= 0.0) a1 = l->x1;
            else if (hi <= 0.0) b1 = l->x1;
        } else if (gs > 0.0) { /* above: s_x >= -lo / gs; below: s_(x+1) <= -hi / gs */
            a0 = texel_edge(-lo / gs, F, 1, l->x0, l->x1), a1 = l->x1;
            b1 = texel_edge(-hi / gs, F, 0, l->x0 + 1, l->x1 + 1) - 1;
        } else { /* above: s_(x+1) <= -lo / gs; below: s_x >= -hi / gs */
            a1 = texel_edge(-lo / gs, F, 0, l->x0 + 1, l->x1 + 1) - 1;
            b0 = texel_edge(-hi / gs, F, 1, l->x0, l->x1), b1 = l->x1;
        }
        if (a1 < a0) a1 = a0;
        if (b1 < b0) b1 = b0;
        const double *P = s->row_moment + ((size_t)l->face * F + y) * (F + 1) * 9;
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) acc[c] += n[k] * (P[9 * a1 + 3 * c + k] - P[9 * a0 + 3 * c + k]);
        for (uint32_t x = l->x0; x < l->x1; x++) {
            if (x >= a0 && x < a1) x = a1; /* skip the runs */
            if (x >= b0 && x < b1) x = b1;
            if (x >= a0 && x < a1) x = a1;
            if (x >= l->x1) break;
            const float *m = s->texel_moment + 9 * ((size_t)l->face * F * F + y * F + x);
            for (int c = 0; c < 3; c++) {
                double d = (double)n[0] * m[3 * c] + (double)n[1] * m[3 * c + 1] + (double)n[2] * m[3 * c + 2];
                if (d > 0.0) acc[c] += d;
            }
        }
    }
}

void hl_area_light_irradiance(const hl_light_split *s, uint32_t k, const float n[3], float rgb[3])
{
    const hl_area_light *l = &s->lights[k];
    if (!isfinite(n[0]) || !isfinite(n[1]) || !isfinite(n[2])) { /* the row walk would index with NaN */
        rgb[0] = rgb[1] = rgb[2] = 0.0f;
        return;
    }
    /* the cone of half-angle extent about dir is wholly above n's horizon
       when angle(n, dir) + extent <= 90 degrees (a cone wider than a
       hemisphere never is) */
    float nd = n[0] * l->dir[0] + n[1] * l->dir[1] + n[2] * l->dir[2];
    float se = l->extent < (float)(0.5 * HL_PI) ? sinf(l->extent) : 2.0f;
    if (nd >= se) {
        for (int c = 0; c < 3; c++) {
            float e = n[0] * l->evec[c][0] + n[1] * l->evec[c][1] + n[2] * l->evec[c][2];
            rgb[c] = e > 0.0f ? e : 0.0f;
        }
    } else if (nd <= -se) {
        rgb[0] = rgb[1] = rgb[2] = 0.0f;
    } else {
        double acc[3] = {0, 0, 0};
        straddle_sum(s, l, n, acc);
        for (int c = 0; c < 3; c++) rgb[c] = acc[c] > 0.0 ? (float)acc[c] : 0.0f;
    }
}

void hl_light_split_ambient(const hl_light_split *s, const float n[3], float rgb[3])
{
    static const double A[9] = {HL_PI, 2.0 * HL_PI / 3.0, 2.0 * HL_PI / 3.0, 2.0 * HL_PI / 3.0, HL_PI / 4.0,
                                HL_PI / 4.0, HL_PI / 4.0, HL_PI / 4.0, HL_PI / 4.0};
    double w[3] = {n[0], n[1], n[2]}, y[9];
    hl_light_sh9(w, y);
    for (int c = 0; c < 3; c++) {
        double e = 0.0;
        for (int k = 0; k < 9; k++) e += A[k] * s->ambient_sh[k][c] * y[k];
        rgb[c] = (float)e;
    }
}

void hl_light_split_ambient_ref(const hl_light_split *s, const float n[3], float rgb[3])
{
    double acc[3] = {0, 0, 0};
    for (size_t t = 0; t < (size_t)6 * s->F * s->F; t++) {
        if (s->owner[t] < s->count) continue;
        const float *w = s->texel_dir + 3 * t;
        double d = (double)n[0] * w[0] + (double)n[1] * w[1] + (double)n[2] * w[2];
        if (d <= 0.0) continue;
        for (int c = 0; c < 3; c++) acc[c] += d * s->texel_energy[3 * t + (size_t)c];
    }
    for (int c = 0; c < 3; c++) rgb[c] = (float)acc[c];
}
