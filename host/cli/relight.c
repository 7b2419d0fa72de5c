/* relight.c - `haarlight relight`: a transport file under an environment
 * to vertex colours (PLY) or a rendered image (EXR, PNG).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static const char *const usage_relight =
    "usage: haarlight relight SCENE.hlt (--env ENV.exr | --sky) -o OUT [options]\n"
    "\n"
    "Relights a transport file from `haarlight precompute` under an environment.\n"
    "OUT by extension: .ply (mesh with per-vertex colours), .exr (linear image),\n"
    ".png (tone-mapped image). Images are rendered headless with Embree.\n"
    "\n"
    "lighting:\n"
    "  --env ENV.exr        equirectangular OpenEXR (any compression, DWAB included)\n"
    "  --sky                the built-in procedural sun and sky (the default without --env)\n"
    "  --sun-elevation DEG  sun height above the horizon (default 35)\n"
    "  --sun-azimuth DEG    sun direction: +X turned about +Y by DEG (default 0)\n"
    "  --sun-size DEG       sun angular diameter (default 2)\n"
    "  --rotate DEG         turn the environment about +Y (Blender's world Z rotation)\n"
    "  --terms M|all        lighting wavelet terms kept (default 200)\n"
    "  --select area|unweighted|transport\n"
    "                       how the terms are chosen (default area: |L_i| x support area)\n"
    "output:\n"
    "  --exposure EV        scale by 2^EV before tone mapping (PNG, 8-bit PLY; default:\n"
    "                       automatic: the 90th percentile of vertex luminance to 0.8)\n"
    "  --ply8               PLY with tone-mapped 8-bit colours instead of linear floats\n"
    "  --size WxH           image size (default 960x720)\n"
    "  --fov DEG            vertical field of view (default 35)\n"
    "  --eye X,Y,Z --target X,Y,Z --up X,Y,Z\n"
    "                       camera (default: frames the object automatically)\n"
    "  --no-background      black instead of the environment behind the object\n"
    "running:\n"
    "  --device cl|ref|cl:P:D   OpenCL device (default: first), or the plain-C reference\n"
    "  --threads T          host threads (rendering, reference)\n"
    "  -q, --quiet          print nothing but errors\n";

static const char *ext_of(const char *path)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    return dot && (!slash || dot > slash) ? dot : "";
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Exposure that puts the 90th percentile of vertex luminance (ground
 * included) at 0.8: sunlit surfaces stay just below white and the sky's
 * soft shadows keep their gradations. */
static float auto_exposure(const hl_mesh *m, const float *rgb)
{
    uint32_t n = m->vertex_count;
    float *y = malloc((size_t)n * sizeof *y);
    if (!y) return 0.0f;
    for (uint32_t v = 0; v < n; v++) y[v] = hl_luminance(rgb[3 * (size_t)v], rgb[3 * (size_t)v + 1], rgb[3 * (size_t)v + 2]);
    qsort(y, n, sizeof *y, cmp_float);
    float p90 = y[(size_t)n * 9 / 10];
    free(y);
    if (!(p90 > 0.0f) || !isfinite(p90)) return 0.0f;
    float ev = log2f(0.8f / p90);
    return ev < -64.0f ? -64.0f : ev > 64.0f ? 64.0f : ev;
}

int cmd_relight(int argc, char **argv)
{
    const char *usage = usage_relight;
    const char *scene = NULL, *env_path = NULL, *out = NULL;
    hl_context_desc cd = {.cl_platform = -1, .cl_device = -1};
    hl_sky_desc sky = {0};
    hl_relight_desc rd = {0};
    hl_camera_desc cam = {0};
    float exposure = 0.0f;
    int exposure_set = 0;
    int ply8 = 0, no_bg = 0, want_sky = 0;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
#define NEED() do { if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a); v = argv[++i]; } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage, stdout); return 0; }
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED(); out = v; }
        else if (!strcmp(a, "--env")) { NEED(); env_path = v; }
        else if (!strcmp(a, "--sky")) want_sky = 1;
        else if (!strcmp(a, "--sun-elevation")) {
            NEED();
            if (!parse_float(v, &sky.sun_elevation_deg) || fabsf(sky.sun_elevation_deg) > 90.0f)
                return usage_error(usage, "--sun-elevation %s: expected -90 to 90 degrees", v);
            if (sky.sun_elevation_deg == 0.0f) sky.sun_elevation_deg = 1e-3f;
            want_sky = 1;
        } else if (!strcmp(a, "--sun-azimuth")) {
            NEED();
            if (!parse_float(v, &sky.sun_azimuth_deg)) return usage_error(usage, "--sun-azimuth %s: expected degrees", v);
            want_sky = 1;
        } else if (!strcmp(a, "--sun-size")) {
            NEED();
            if (!parse_float(v, &sky.sun_size_deg) || !(sky.sun_size_deg > 0.0f && sky.sun_size_deg <= 90.0f))
                return usage_error(usage, "--sun-size %s: expected (0, 90] degrees", v);
            want_sky = 1;
        } else if (!strcmp(a, "--rotate")) {
            NEED();
            if (!parse_float(v, &rd.rotate_deg)) return usage_error(usage, "--rotate %s: expected degrees", v);
        } else if (!strcmp(a, "--terms")) {
            NEED();
            if (!strcmp(v, "all")) rd.terms = HL_TERMS_ALL;
            else if (!parse_u32(v, &rd.terms) || rd.terms < 1)
                return usage_error(usage, "--terms %s: expected M >= 1 or `all`", v);
        } else if (!strcmp(a, "--select")) {
            NEED();
            if (!strcmp(v, "area")) rd.select = HL_SELECT_AREA;
            else if (!strcmp(v, "unweighted")) rd.select = HL_SELECT_UNWEIGHTED;
            else if (!strcmp(v, "transport")) rd.select = HL_SELECT_TRANSPORT;
            else return usage_error(usage, "--select %s: expected area, unweighted or transport", v);
        } else if (!strcmp(a, "--exposure")) {
            NEED();
            if (!parse_float(v, &exposure) || fabsf(exposure) > 64.0f) return usage_error(usage, "--exposure %s: expected EV in [-64, 64]", v);
            exposure_set = 1;
        } else if (!strcmp(a, "--ply8")) ply8 = 1;
        else if (!strcmp(a, "--no-background")) no_bg = 1;
        else if (!strcmp(a, "--size")) {
            NEED();
            char tail;
            if (sscanf(v, "%ux%u%c", &cam.width, &cam.height, &tail) != 2 || cam.width < 1 || cam.height < 1 ||
                cam.width > 16384 || cam.height > 16384)
                return usage_error(usage, "--size %s: expected WxH, each 1 to 16384", v);
        } else if (!strcmp(a, "--fov")) {
            NEED();
            if (!parse_float(v, &cam.fov_deg) || !(cam.fov_deg > 0.0f && cam.fov_deg < 180.0f))
                return usage_error(usage, "--fov %s: expected (0, 180) degrees", v);
        } else if (!strcmp(a, "--eye")) { NEED(); if (!parse_vec3(v, cam.eye)) return usage_error(usage, "--eye %s: expected X,Y,Z", v); }
        else if (!strcmp(a, "--target")) { NEED(); if (!parse_vec3(v, cam.target)) return usage_error(usage, "--target %s: expected X,Y,Z", v); }
        else if (!strcmp(a, "--up")) { NEED(); if (!parse_vec3(v, cam.up)) return usage_error(usage, "--up %s: expected X,Y,Z", v); }
        else if (!strcmp(a, "--device")) {
            NEED();
            if (!parse_device(v, &cd)) return usage_error(usage, "--device %s: expected cl, ref or cl:PLATFORM:DEVICE", v);
        } else if (!strcmp(a, "--threads")) {
            NEED();
            uint32_t t;
            if (!parse_u32(v, &t) || t < 1 || t > 256) return usage_error(usage, "--threads %s: expected 1 to 256", v);
            cd.threads = (int)t;
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) cd.quiet = 1;
        else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (!scene) scene = a;
        else return usage_error(usage, "unexpected argument %s", a);
#undef NEED
    }
    if (!scene) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (!out) return usage_error(usage, "%s", "no output given (-o OUT.ply|.exr|.png)");
    if (env_path && want_sky) return usage_error(usage, "%s", "--env and the sky options contradict each other");
    const char *ext = ext_of(out);
    int is_ply = !strcmp(ext, ".ply"), is_img = !strcmp(ext, ".exr") || !strcmp(ext, ".png");
    if (!is_ply && !is_img) return usage_error(usage, "output %s: expected a .ply, .exr or .png name", out);

    char err[4096];
    hl_context *ctx = NULL;
    if (hl_context_create(&cd, &ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 1;
    }
    hl_transport *t = NULL;
    hl_env *env = NULL;
    hl_relighter *rl = NULL;
    hl_image *img = NULL;
    float *rgb = NULL;
    hl_env_stats es = {0, 0};
    hl_relight_stats st;
    hl_result r = hl_transport_load(ctx, scene, &t);
    if (r == HL_OK) r = env_path ? hl_env_load(ctx, env_path, &env, &es) : hl_env_create_sky(ctx, &sky, &env);
    if (r == HL_OK && !cd.quiet && (es.nonfinite_pixels || es.negative_pixels))
        fprintf(stderr, "%s: %llu pixels with NaN or Inf set to 0, %llu pixels with negative values clamped to 0\n", env_path,
                (unsigned long long)es.nonfinite_pixels, (unsigned long long)es.negative_pixels);
    if (r == HL_OK) r = hl_relighter_create(ctx, t, &rl);
    if (r == HL_OK) r = hl_relighter_set_env(rl, env);
    if (r == HL_OK) {
        rgb = malloc((size_t)t->info.vertex_count * 12);
        if (!rgb) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r == HL_OK) r = hl_relighter_run(rl, &rd, rgb, &st);
    if (r == HL_OK && !cd.quiet)
        fprintf(stderr,
                "relit %s under %s on %s: %u lighting terms keep %.4f%% of the lighting energy "
                "(error bound %.4g per unit albedo); %.0f%% of blocks skipped; %.2f ms\n",
                scene, env_path ? env_path : "the procedural sky", hl_context_device_name(ctx), st.terms_kept,
                100.0 * st.energy_kept, st.error_bound, 100.0 * st.blocks_skipped, 1e3 * st.seconds);
    if (r == HL_OK && !exposure_set) {
        exposure = auto_exposure(t->mesh, rgb);
        if (!cd.quiet && (ply8 || !strcmp(ext, ".png"))) fprintf(stderr, "exposure: %+.2f EV (automatic)\n", (double)exposure);
    }
    if (r == HL_OK && is_ply) r = hl_mesh_save_ply(ctx, t->mesh, rgb, out, ply8, exposure);
    if (r == HL_OK && is_img) r = hl_render(ctx, t->mesh, rgb, no_bg ? NULL : env, rd.rotate_deg, &cam, &img);
    if (r == HL_OK && is_img) r = hl_image_save(ctx, img, out, exposure);
    if (r == HL_OK && !cd.quiet) fprintf(stderr, "wrote %s\n", out);
    int rc = r == HL_OK ? 0 : cli_fail(ctx, r);
    free(rgb);
    hl_image_destroy(img);
    hl_relighter_destroy(rl);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    hl_context_destroy(ctx);
    return rc;
}
