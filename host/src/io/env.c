/* env.c - equirectangular environments: loading, repair, procedural sky
 * and direction queries.
 *
 * The mapping is that of docs/CONVENTIONS.md: a direction w
 * reads u = 0.5 + atan2(w.z, w.x) / 2pi, v = acos(w.y) / pi, row 0 = +Y.
 * Every pixel that leaves this file is finite, >= 0 and <= HL_MAX_RADIANCE:
 * NaN/Inf channels become 0 and negative ones are clamped, and the counts
 * are reported; maps brighter than that are refused.
 * Depends on: exr_io.c and hdr_io.c for the file formats (OpenEXR, Radiance
 * .hdr), env_layout.c for light-probe layouts.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exr_io.h"
#include "env_layout.h"
#include "hdr_io.h"
#include "hl_internal.h"

/* Sets NaN/Inf and negative channels to 0 and counts the pixels touched;
 * refuses a map with a channel above HL_MAX_RADIANCE (what names it). */
static hl_result repair(hl_context *ctx, const char *what, float *rgb, size_t pixels, hl_env_stats *stats)
{
    uint64_t nonfinite = 0, negative = 0, bright = 0;
    float brightest = 0.0f;
    for (size_t i = 0; i < pixels; i++) {
        int bad = 0, neg = 0, big = 0;
        for (int c = 0; c < 3; c++) {
            float x = rgb[3 * i + (size_t)c];
            if (!isfinite(x)) {
                rgb[3 * i + (size_t)c] = 0.0f;
                bad = 1;
            } else if (x < 0.0f) {
                rgb[3 * i + (size_t)c] = 0.0f;
                neg = 1;
            } else if (x > HL_MAX_RADIANCE) {
                big = 1;
                if (x > brightest) brightest = x;
            }
        }
        nonfinite += (uint64_t)bad;
        negative += (uint64_t)neg;
        bright += (uint64_t)big;
    }
    if (stats) {
        stats->nonfinite_pixels = nonfinite;
        stats->negative_pixels = negative;
    }
    if (bright)
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: %llu pixel%s brighter than %g (up to %g); the transforms would overflow float: "
                       "scale the lighting down", what, (unsigned long long)bright, bright == 1 ? " is" : "s are",
                       (double)HL_MAX_RADIANCE, (double)brightest);
    return HL_OK;
}

static hl_result wrap(hl_context *ctx, uint32_t width, uint32_t height, float *rgb, hl_env **out)
{
    hl_env *env = hl_calloc(ctx, 1, sizeof *env, "environment");
    if (!env) {
        free(rgb);
        return HL_ERR_OUT_OF_MEMORY;
    }
    env->width = width;
    env->height = height;
    env->rgb = rgb;
    *out = env;
    return HL_OK;
}

/* The format comes from the file's first bytes, not its name: a Radiance
 * header, or anything else for OpenEXR (whose reader names a bad magic). */
static hl_result read_map(hl_context *ctx, const char *path, uint32_t *w, uint32_t *h, float **rgb)
{
    uint8_t head[16] = {0};
    size_t n = 0;
    FILE *f = fopen(path, "rb");
    if (f) {
        n = fread(head, 1, sizeof head, f);
        fclose(f);
    }
    if (hl_hdr_sniff_(head, n)) return hl_hdr_read_rgb_(ctx, path, w, h, rgb);
    return hl_exr_read_rgb_(ctx, path, 0, w, h, rgb);
}

hl_result hl_env_load_layout(hl_context *ctx, const char *path, hl_env_layout layout, hl_env **out,
                             hl_env_stats *stats)
{
    if (stats) memset(stats, 0, sizeof *stats);
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_env_load: out is NULL");
    *out = NULL;
    if (!path || !*path) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_env_load: no path given");
    if ((int)layout < HL_LAYOUT_AUTO || (int)layout > HL_LAYOUT_CROSS_V)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_env_load: unknown layout %d", (int)layout);
    uint32_t w, h;
    float *rgb;
    hl_result r = read_map(ctx, path, &w, &h, &rgb);
    if (r != HL_OK) return r;
    const hl_env_layout found = hl_env_layout_of_size_(w, h);
    if (layout == HL_LAYOUT_AUTO) layout = found;
    if (layout == HL_LAYOUT_AUTO || (layout == HL_LAYOUT_EQUIRECT && found != layout))
        r = hl_fail(ctx, HL_ERR_FORMAT,
                    "%s: %u x %u pixels is not an equirectangular map (width must be 2 x height)%s", path, w, h,
                    layout == HL_LAYOUT_AUTO ? ", an angular map (1:1, at least 8 x 8) or a cube cross (4:3 or 3:4)" : "");
    /* repaired before any resampling, so that averages stay finite */
    if (r == HL_OK) r = repair(ctx, path, rgb, (size_t)w * h, stats);
    if (r == HL_OK && layout != HL_LAYOUT_EQUIRECT) {
        float *eq = NULL;
        r = hl_env_resample_layout_(ctx, path, layout, w, h, rgb, &w, &h, &eq);
        free(rgb);
        rgb = eq;
    }
    if (r != HL_OK) {
        free(rgb);
        return r;
    }
    return wrap(ctx, w, h, rgb, out);
}

hl_result hl_env_load(hl_context *ctx, const char *path, hl_env **out, hl_env_stats *stats)
{
    return hl_env_load_layout(ctx, path, HL_LAYOUT_AUTO, out, stats);
}

hl_result hl_env_create(hl_context *ctx, uint32_t width, uint32_t height, const float *rgb,
                        hl_env **out, hl_env_stats *stats)
{
    if (stats) memset(stats, 0, sizeof *stats);
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_env_create: out is NULL");
    *out = NULL;
    if (!rgb) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_env_create: rgb is NULL");
    if (height < 1 || width != 2 * height || width > HL_EXR_MAX_SIDE ||
        (uint64_t)width * height > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "hl_env_create: %u x %u is not an equirectangular size (width = 2 x height, "
                       "1 <= height, width <= %u)", width, height, HL_EXR_MAX_SIDE);
    size_t n = 3 * (size_t)width * height;
    float *copy = hl_malloc(ctx, n * sizeof(float), "environment pixels");
    if (!copy) return HL_ERR_OUT_OF_MEMORY;
    memcpy(copy, rgb, n * sizeof(float));
    hl_result r = repair(ctx, "environment", copy, (size_t)width * height, stats);
    if (r != HL_OK) {
        free(copy);
        return r;
    }
    return wrap(ctx, width, height, copy, out);
}

/* Map coordinates (u, v) of direction w with the rotation applied, or 0
 * when w is no direction. */
static int env_uv(const float w[3], float rotate_deg, double *u, double *v)
{
    double x = w[0], y = w[1], z = w[2];
    double len = sqrt(x * x + y * y + z * z);
    if (!(len > 0.0) || !isfinite(len)) return 0;
    *u = 0.5 + atan2(z, x) / (2.0 * HL_PI);
    if (rotate_deg != 0.0f && isfinite(rotate_deg)) *u += (double)rotate_deg / 360.0;
    *u -= floor(*u);
    double ct = y / len;
    if (ct > 1.0) ct = 1.0;
    if (ct < -1.0) ct = -1.0;
    *v = acos(ct) / HL_PI;
    return 1;
}

void hl_env_query(const hl_env *env, const float w[3], float rotate_deg, float rgb[3])
{
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    double u, v;
    if (!env || !env->rgb || !w || !env_uv(w, rotate_deg, &u, &v)) return; /* no direction: black */
    double col = floor(u * (double)env->width), row = floor(v * (double)env->height);
    uint32_t i = col < 0.0 ? 0u : col >= (double)env->width ? env->width - 1 : (uint32_t)col;
    uint32_t j = row < 0.0 ? 0u : row >= (double)env->height ? env->height - 1 : (uint32_t)row;
    const float *p = env->rgb + 3 * ((size_t)j * env->width + i);
    rgb[0] = p[0];
    rgb[1] = p[1];
    rgb[2] = p[2];
}

void hl_env_query_smooth(const hl_env *env, const float w[3], float rotate_deg, float rgb[3])
{
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    double u, v;
    if (!env || !env->rgb || !w || !env_uv(w, rotate_deg, &u, &v)) return;
    const uint32_t W = env->width, H = env->height;
    /* between pixel centres: wrap across the seam, clamp at the poles */
    double x = u * W - 0.5, y = v * H - 0.5, fx = x - floor(x), fy = y - floor(y);
    long x0 = (long)floor(x), y0 = (long)floor(y);
    uint32_t xa = (uint32_t)((x0 % (long)W + (long)W) % (long)W), xb = (xa + 1) % W;
    uint32_t ya = y0 < 0 ? 0u : (uint32_t)y0, yb = y0 + 1 >= (long)H ? H - 1 : (uint32_t)(y0 + 1);
    if (ya >= H) ya = H - 1;
    for (int c = 0; c < 3; c++) {
        double a = env->rgb[3 * ((size_t)ya * W + xa) + c], b = env->rgb[3 * ((size_t)ya * W + xb) + c];
        double d = env->rgb[3 * ((size_t)yb * W + xa) + c], e = env->rgb[3 * ((size_t)yb * W + xb) + c];
        rgb[c] = (float)((a + (b - a) * fx) * (1.0 - fy) + (d + (e - d) * fx) * fy);
    }
}

void hl_env_destroy(hl_env *env)
{
    if (!env) return;
    free(env->rgb);
    free(env);
}

/* ---------------------------------------------------------------- sky */

static void pixel_dir(double phi, double ct, double out[3])
{
    double st = sqrt(fmax(0.0, 1.0 - ct * ct));
    out[0] = st * cos(phi);
    out[1] = ct;
    out[2] = st * sin(phi);
}

/* Adds the sun disc (direction s, angular radius rad, radiance L) to rgb:
 * each pixel gets L times the fraction of its solid angle inside the disc.
 * Pixels wholly inside or outside are decided from the pixel's angular
 * extent; the rest are supersampled on an equal-area grid (equal steps in
 * u and in cos(theta)). The covered solid angles are then scaled so that
 * they add up to the disc's exact 2pi(1 - cos rad), which keeps the
 * energy right even for a disc smaller than a pixel. */
static hl_result add_sun(hl_context *ctx, float *rgb, uint32_t W, uint32_t H, const double s[3],
                         double rad, const double L[3])
{
    const double dphi = 2.0 * HL_PI / W, dtheta = HL_PI / H;
    const double cos_rad = cos(rad);
    const double theta_s = acos(fmax(-1.0, fmin(1.0, s[1])));
    const double phi_s = atan2(s[2], s[0]);
    /* Row range: theta in [theta_s - rad, theta_s + rad], one row margin. */
    double t0 = theta_s - rad, t1 = theta_s + rad;
    int64_t j0 = (int64_t)floor(t0 / dtheta) - 1, j1 = (int64_t)floor(t1 / dtheta) + 1;
    if (j0 < 0) j0 = 0;
    if (j1 > (int64_t)H - 1) j1 = (int64_t)H - 1;
    /* Column range: all when the disc holds a pole, else the azimuth
     * half-width asin(sin rad / sin theta_s), one column margin. */
    int64_t i0 = 0, i1 = (int64_t)W - 1;
    int all_cols = t0 <= 0.0 || t1 >= HL_PI;
    if (!all_cols) {
        double sr = sin(rad) / sin(theta_s);
        double half = sr >= 1.0 ? HL_PI : asin(sr);
        double uc = 0.5 + phi_s / (2.0 * HL_PI);
        i0 = (int64_t)floor((uc - half / (2.0 * HL_PI)) * W) - 1;
        i1 = (int64_t)floor((uc + half / (2.0 * HL_PI)) * W) + 1;
        if (i1 - i0 + 1 >= (int64_t)W) {
            i0 = 0;
            i1 = (int64_t)W - 1;
        }
    }
    size_t rows = (size_t)(j1 - j0 + 1), cols = (size_t)(i1 - i0 + 1);
    double *cover = hl_calloc(ctx, rows * cols, sizeof(double), "sun coverage");
    if (!cover) return HL_ERR_OUT_OF_MEMORY;

    double total = 0.0;
    for (int64_t j = j0; j <= j1; j++) {
        double ta = HL_PI * (double)j / H, tb = HL_PI * (double)(j + 1) / H;
        double ca = cos(ta), cb = cos(tb);
        double omega = dphi * (ca - cb);
        double ctc = cos(HL_PI * ((double)j + 0.5) / H);
        /* Largest distance from the pixel centre to a point of the pixel,
         * bounded by a path along the meridian (dtheta / 2) then along a
         * parallel (sin theta dphi / 2). */
        double smax = (ta <= 0.5 * HL_PI && tb >= 0.5 * HL_PI) ? 1.0 : fmax(sin(ta), sin(tb));
        double reach = 0.5 * dtheta + 0.5 * dphi * smax;
        /* Subsamples: about 40 across the disc's radius on each axis. */
        double sv = ceil(40.0 * dtheta / rad), su = ceil(40.0 * dphi * smax / rad);
        int Sv = sv < 8.0 ? 8 : sv > 256.0 ? 256 : (int)sv;
        int Su = su < 8.0 ? 8 : su > 256.0 ? 256 : (int)su;
        for (int64_t ii = i0; ii <= i1; ii++) {
            int64_t i = ((ii % (int64_t)W) + (int64_t)W) % (int64_t)W;
            double phic = dphi * ((double)i + 0.5) - HL_PI, d[3];
            pixel_dir(phic, ctc, d);
            double ang = acos(fmax(-1.0, fmin(1.0, d[0] * s[0] + d[1] * s[1] + d[2] * s[2])));
            double frac;
            if (ang + reach <= rad) {
                frac = 1.0;
            } else if (ang - reach >= rad) {
                frac = 0.0;
            } else {
                long hits = 0;
                for (int b = 0; b < Sv; b++) {
                    double ct = ca - (ca - cb) * ((double)b + 0.5) / Sv;
                    double st = sqrt(fmax(0.0, 1.0 - ct * ct));
                    for (int a = 0; a < Su; a++) {
                        double phi = dphi * ((double)i + ((double)a + 0.5) / Su) - HL_PI;
                        double dot = st * cos(phi) * s[0] + ct * s[1] + st * sin(phi) * s[2];
                        hits += dot >= cos_rad;
                    }
                }
                frac = (double)hits / ((double)Su * Sv);
            }
            cover[(size_t)(j - j0) * cols + (size_t)(ii - i0)] = frac * omega;
            total += frac * omega;
        }
    }
    double exact = 2.0 * HL_PI * (1.0 - cos_rad);
    if (!(exact > 0.0)) exact = HL_PI * rad * rad;
    if (!(total > 0.0)) {
        /* Nothing sampled (a vanishing disc): put it all in the pixel that
         * holds the sun's direction. */
        double u = 0.5 + phi_s / (2.0 * HL_PI);
        u -= floor(u);
        uint32_t i = (uint32_t)fmin((double)W - 1, floor(u * W));
        uint32_t j = (uint32_t)fmin((double)H - 1, floor(theta_s / dtheta));
        double omega = dphi * (cos(HL_PI * j / H) - cos(HL_PI * (j + 1) / H));
        for (int c = 0; c < 3; c++)
            rgb[3 * ((size_t)j * W + i) + (size_t)c] += (float)(L[c] * exact / omega);
        free(cover);
        return HL_OK;
    }
    double scale = exact / total;
    for (int64_t j = j0; j <= j1; j++) {
        double omega = dphi * (cos(HL_PI * (double)j / H) - cos(HL_PI * (double)(j + 1) / H));
        for (int64_t ii = i0; ii <= i1; ii++) {
            double cov = cover[(size_t)(j - j0) * cols + (size_t)(ii - i0)];
            if (cov <= 0.0) continue;
            size_t i = (size_t)(((ii % (int64_t)W) + (int64_t)W) % (int64_t)W);
            double f = cov * scale / omega;
            for (int c = 0; c < 3; c++) rgb[3 * ((size_t)j * W + i) + (size_t)c] += (float)(L[c] * f);
        }
    }
    free(cover);
    return HL_OK;
}

static int colour_ok(const float c[3])
{
    for (int k = 0; k < 3; k++)
        if (!isfinite(c[k]) || c[k] < 0.0f) return 0;
    return 1;
}

static int colour_zero(const float c[3]) { return c[0] == 0.0f && c[1] == 0.0f && c[2] == 0.0f; }

hl_result hl_env_create_sky(hl_context *ctx, const hl_sky_desc *desc, hl_env **out)
{
    static const float def_zenith[3] = {0.20f, 0.38f, 0.85f};
    static const float def_horizon[3] = {0.85f, 0.90f, 1.00f};
    static const float def_ground[3] = {0.12f, 0.10f, 0.08f};
    hl_sky_desc d;
    memset(&d, 0, sizeof d);
    if (desc) d = *desc;
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_env_create_sky: out is NULL");
    *out = NULL;
    if (d.sun_elevation_deg == 0.0f) d.sun_elevation_deg = 35.0f;
    if (d.sun_size_deg == 0.0f) d.sun_size_deg = 2.0f;
    if (d.sun_irradiance == 0.0f) d.sun_irradiance = 8.0f;
    if (d.width == 0) d.width = 1024;
    if (colour_zero(d.sky_zenith)) memcpy(d.sky_zenith, def_zenith, sizeof def_zenith);
    if (colour_zero(d.sky_horizon)) memcpy(d.sky_horizon, def_horizon, sizeof def_horizon);
    if (colour_zero(d.ground)) memcpy(d.ground, def_ground, sizeof def_ground);

    if (!(d.sun_elevation_deg >= -90.0f && d.sun_elevation_deg <= 90.0f))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "sky: sun elevation %g degrees is outside -90..90",
                       (double)d.sun_elevation_deg);
    if (!isfinite(d.sun_azimuth_deg))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "sky: sun azimuth %g is not a number of degrees",
                       (double)d.sun_azimuth_deg);
    if (!(d.sun_size_deg > 0.0f && d.sun_size_deg <= 90.0f))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "sky: sun size %g degrees is outside (0, 90]",
                       (double)d.sun_size_deg);
    if (!(d.sun_irradiance > 0.0f) || !isfinite(d.sun_irradiance))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "sky: sun irradiance %g must be positive and finite",
                       (double)d.sun_irradiance);
    if (!colour_ok(d.sky_zenith) || !colour_ok(d.sky_horizon) || !colour_ok(d.ground))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "sky: colours must be finite and >= 0");
    if (d.width < 4 || d.width % 2 != 0 || d.width > HL_EXR_MAX_SIDE)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "sky: width %u must be even and in 4..%u",
                       d.width, HL_EXR_MAX_SIDE);

    uint32_t W = d.width, H = d.width / 2;
    float *rgb = hl_malloc(ctx, sizeof(float) * 3 * (size_t)W * H, "sky pixels");
    if (!rgb) return HL_ERR_OUT_OF_MEMORY;
    for (uint32_t j = 0; j < H; j++) {
        double elev = 0.5 * HL_PI - HL_PI * ((double)j + 0.5) / H; /* pixel centre */
        float c[3];
        if (elev >= 0.0) {
            double t = sqrt(sin(elev)); /* quick rise from the horizon colour */
            for (int k = 0; k < 3; k++)
                c[k] = (float)((double)d.sky_horizon[k] + t * ((double)d.sky_zenith[k] - (double)d.sky_horizon[k]));
        } else {
            memcpy(c, d.ground, sizeof c);
        }
        for (uint32_t i = 0; i < W; i++) memcpy(rgb + 3 * ((size_t)j * W + i), c, sizeof c);
    }

    /* Sun direction: R_y(azimuth) applied to (cos e, sin e, 0), with
     * R_y(a)(x, y, z) = (x cos a + z sin a, y, -x sin a + z cos a). */
    double e = (double)d.sun_elevation_deg * HL_PI / 180.0;
    double a = (double)d.sun_azimuth_deg * HL_PI / 180.0;
    double s[3] = {cos(e) * cos(a), sin(e), -cos(e) * sin(a)};
    double rad = 0.5 * (double)d.sun_size_deg * HL_PI / 180.0;
    /* Irradiance of a uniform disc of radiance L on a surface facing it:
     * L pi sin^2(rad). The sun is white. */
    double Ls = (double)d.sun_irradiance / (HL_PI * sin(rad) * sin(rad));
    double L[3] = {Ls, Ls, Ls};
    hl_result r = add_sun(ctx, rgb, W, H, s, rad, L);
    if (r == HL_OK) r = repair(ctx, "sky", rgb, (size_t)W * H, NULL); /* too bright a sun or sky */
    if (r != HL_OK) {
        free(rgb);
        return r;
    }
    return wrap(ctx, W, H, rgb, out);
}
