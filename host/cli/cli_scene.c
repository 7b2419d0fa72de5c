/* cli_scene.c - the options that `relight` and `view` share: lighting
 * terms and selection, rotation, the built-in sky's sun, the camera, the
 * exposure and the device, and the surroundings (--surroundings, --time;
 * for the commands that set accept_surroundings). One parser, so that
 * both commands read them alike and say the same thing about a bad value.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

void cli_scene_opts_init(cli_scene_opts *o)
{
    memset(o, 0, sizeof *o);
    o->cd.cl_platform = -1;
    o->cd.cl_device = -1;
}

hl_result cli_camera_complete(hl_context *ctx, const hl_mesh *mesh, cli_scene_opts *o)
{
    if (o->eye_set == o->target_set) return HL_OK;
    hl_camera_desc autod = o->cam;
    memset(autod.eye, 0, sizeof autod.eye);
    memset(autod.target, 0, sizeof autod.target);
    hl_camera_view av;
    hl_result r = hl_camera_query_view(ctx, mesh, &autod, &av);
    if (r != HL_OK) return r;
    for (int k = 0; k < 3; k++) {
        if (o->eye_set) o->cam.target[k] = av.target[k];
        else o->cam.eye[k] = o->cam.target[k] + (av.eye[k] - av.target[k]);
    }
    return HL_OK;
}

int cli_parse_size(const char *s, uint32_t *w, uint32_t *h)
{
    char tail;
    return sscanf(s, "%ux%u%c", w, h, &tail) == 2 && *w >= 1 && *h >= 1 && *w <= 16384 && *h <= 16384;
}

int cli_scene_opt(int argc, char **argv, int *i, const char *usage, cli_scene_opts *o)
{
    const char *a = argv[*i], *v = NULL;
    static const char *const with_value[] = {
        "--sun-elevation", "--sun-azimuth", "--sun-size", "--rotate", "--terms", "--select", "--exposure",
        "--size", "--fov", "--eye", "--target", "--up", "--device", "--device-memory", "--threads", "--layout", NULL};
    int known = 0;
    for (int k = 0; with_value[k]; k++) known |= !strcmp(a, with_value[k]);
    int surr = o->accept_surroundings &&
               (!strcmp(a, "--surroundings") || !strcmp(a, "--time") || !strcmp(a, "--surroundings-transform") ||
                !strcmp(a, "--probes"));
    if (surr) {
        if (*i + 1 >= argc) return -usage_error(usage, "option %s needs a value", a);
        v = argv[++*i];
        if (!strcmp(a, "--surroundings")) o->surroundings = v;
        else if (!strcmp(a, "--surroundings-transform")) {
            if (!cli_parse_placement(usage, v, o->place)) return -2;
            o->place_set = 1;
        } else if (!strcmp(a, "--probes")) {
            if (!parse_u32(v, &o->probes) || o->probes < 1 || o->probes > 256)
                return -usage_error(usage, "--probes %s: expected a whole number of capture points from 1 to 256", v);
            o->probes_set = 1;
        } else {
            char *end = NULL;
            o->time = strtod(v, &end);
            if (end == v || *end || !isfinite(o->time) || o->time < 0.0)
                return -usage_error(usage, "--time %s: expected seconds, a finite number >= 0", v);
            o->time_set = 1;
        }
        return 1;
    }
    if (known) {
        if (*i + 1 >= argc) return -usage_error(usage, "option %s needs a value", a);
        v = argv[++*i];
    }
    if (!strcmp(a, "--sun-elevation")) {
        if (!parse_float(v, &o->sky.sun_elevation_deg) || fabsf(o->sky.sun_elevation_deg) > 90.0f)
            return -usage_error(usage, "--sun-elevation %s: expected -90 to 90 degrees", v);
        if (o->sky.sun_elevation_deg == 0.0f) o->sky.sun_elevation_deg = 1e-3f; /* 0 means the default */
        o->sky_set = 1;
    } else if (!strcmp(a, "--sun-azimuth")) {
        if (!parse_float(v, &o->sky.sun_azimuth_deg)) return -usage_error(usage, "--sun-azimuth %s: expected degrees", v);
        o->sky_set = 1;
    } else if (!strcmp(a, "--sun-size")) {
        if (!parse_float(v, &o->sky.sun_size_deg) || !(o->sky.sun_size_deg > 0.0f && o->sky.sun_size_deg <= 90.0f))
            return -usage_error(usage, "--sun-size %s: expected (0, 90] degrees", v);
        o->sky_set = 1;
    } else if (!strcmp(a, "--layout")) {
        if (!parse_layout(v, &o->layout))
            return -usage_error(usage, "--layout %s: expected auto, equirect, angular, cross-h or cross-v", v);
    } else if (!strcmp(a, "--rotate")) {
        if (!parse_float(v, &o->rd.rotate_deg)) return -usage_error(usage, "--rotate %s: expected degrees", v);
    } else if (!strcmp(a, "--terms")) {
        if (!strcmp(v, "all")) o->rd.terms = HL_TERMS_ALL;
        else if (!parse_u32(v, &o->rd.terms) || o->rd.terms < 1)
            return -usage_error(usage, "--terms %s: expected M >= 1 or `all`", v);
    } else if (!strcmp(a, "--select")) {
        if (!parse_select(v, &o->rd.select))
            return -usage_error(usage, "--select %s: expected area, unweighted or transport", v);
    } else if (!strcmp(a, "--exposure")) {
        if (!parse_float(v, &o->exposure) || fabsf(o->exposure) > 64.0f)
            return -usage_error(usage, "--exposure %s: expected EV in [-64, 64]", v);
        o->exposure_set = 1;
    } else if (!strcmp(a, "--size")) {
        if (!cli_parse_size(v, &o->cam.width, &o->cam.height))
            return -usage_error(usage, "--size %s: expected WxH, each 1 to 16384", v);
    } else if (!strcmp(a, "--fov")) {
        if (!parse_float(v, &o->cam.fov_deg) || !(o->cam.fov_deg > 0.0f && o->cam.fov_deg < 180.0f))
            return -usage_error(usage, "--fov %s: expected (0, 180) degrees", v);
    } else if (!strcmp(a, "--eye") || !strcmp(a, "--target") || !strcmp(a, "--up")) {
        float *dst = a[2] == 'e' ? o->cam.eye : a[2] == 't' ? o->cam.target : o->cam.up;
        char fmt[64];
        snprintf(fmt, sizeof fmt, "%s %%s: expected X,Y,Z", a); /* a is one of the three names */
        if (!parse_vec3(v, dst)) return -usage_error(usage, fmt, v);
        if (a[2] == 'e') o->eye_set = 1;
        if (a[2] == 't') o->target_set = 1;
    } else if (!strcmp(a, "--device")) {
        if (!parse_device(v, &o->cd)) return -usage_error(usage, "--device %s: expected cl, ref or cl:PLATFORM:DEVICE", v);
    } else if (!strcmp(a, "--device-memory")) {
        if (!parse_device_memory(v, &o->cd)) return -usage_error(usage, "--device-memory %s: expected a byte count such as 512M or 2G", v);
    } else if (!strcmp(a, "--threads")) {
        uint32_t t;
        if (!parse_u32(v, &t) || t < 1 || t > 256) return -usage_error(usage, "--threads %s: expected 1 to 256", v);
        o->cd.threads = (int)t;
    } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
        o->cd.quiet = 1;
    } else {
        return 0;
    }
    return 1;
}

int cli_parse_placement(const char *usage, const char *v, float place[5])
{
    static const char *const part[5] = {"TX", "TY", "TZ", "SCALE", "YAW"};
    const char *p = v;
    for (int k = 0; k < 5; k++) {
        char *end = NULL;
        double x = strtod(p, &end);
        if (end == p || (k < 4 && *end != ',') || (k == 4 && *end)) {
            usage_error(usage, "--surroundings-transform %s: expected TX,TY,TZ,SCALE,YAW, five numbers (a shift, a "
                        "uniform scale > 0, degrees about +Y)", v);
            return 0;
        }
        char msg[160];
        if (!isfinite(x) || !isfinite((float)x)) {
            snprintf(msg, sizeof msg, "--surroundings-transform %%s: %s is not a finite number", part[k]);
            usage_error(usage, msg, v);
            return 0;
        }
        if (k == 3 && !(x > 0.0 && (float)x > 0.0f)) {
            snprintf(msg, sizeof msg, "--surroundings-transform %%s: SCALE %g must be a number > 0", x);
            usage_error(usage, msg, v);
            return 0;
        }
        place[k] = (float)x;
        p = end + 1;
    }
    return 1;
}

hl_result cli_surroundings_load(hl_context *ctx, const cli_scene_opts *o, hl_surroundings **out, int quiet)
{
    *out = NULL;
    if (!o->surroundings) return HL_OK;
    hl_surroundings *s = NULL;
    hl_result r = hl_surroundings_load(ctx, o->surroundings, &s);
    if (r == HL_OK && o->place_set) r = hl_surroundings_set_placement(s, o->place, o->place[3], o->place[4]);
    if (r == HL_OK) r = hl_surroundings_set_time(s, o->time);
    if (r != HL_OK) {
        hl_surroundings_destroy(s);
        return r;
    }
    if (!quiet) {
        uint32_t nb = hl_surroundings_body_count(s), ne = 0;
        for (uint32_t b = 0; b < nb; b++) ne += hl_surroundings_body_emits(s, b) != 0;
        double t0 = 0.0, t1 = 0.0;
        hl_surroundings_time_range(s, &t0, &t1);
        fprintf(stderr, "surroundings %s: %u triangles, %u of %u bodies emitting", o->surroundings,
                hl_surroundings_triangle_count(s), ne, nb);
        if (t1 > t0) {
            double used = o->time < t0 ? t0 : o->time > t1 ? t1 : o->time;
            fprintf(stderr, "; animation %g to %g s, posed at %g s%s\n", t0, t1, used,
                    used == o->time ? "" : o->time < t0 ? " (held at the first key)" : " (held at the last key)");
        } else
            fprintf(stderr, "; no animation%s\n", o->time_set ? " (--time has nothing to move)" : "");
        if (ne == 0) fprintf(stderr, "surroundings %s: no body emits: they only hide the environment\n", o->surroundings);
    }
    *out = s;
    return HL_OK;
}

void cli_probes_report(const hl_relight_stats *st, uint32_t N, uint32_t asked)
{
    const double deg = 180.0 / 3.14159265358979323846;
    char bound[96];
    if (st->parallax < 0.5 * 3.14159265358979323846)
        snprintf(bound, sizeof bound, "%.2g degrees", st->parallax * deg);
    else snprintf(bound, sizeof bound, "90 degrees (an emitter as near as the vertices a point serves)");
    fprintf(stderr, "capture points: %u of %u; parallax up to %s (a texel: %.2g to %.2g degrees)\n", st->probes, asked,
            bound, 2.0 / N * deg, 4.0 / N * deg);
    /* past a few texels the one point's shadows and fall-off are off */
    if (asked == 1 && !(st->parallax <= 8.0 / N))
        fprintf(stderr, "capture points: an emitter is near enough for the capture point's view of it to differ "
                "from the vertices'; --probes 32 follows it (docs/CAPTURE.md)\n");
}
