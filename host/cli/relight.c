/* relight.c - `haarlight relight`: a transport file under an environment,
 * or lit by surroundings captured around it (with or without an
 * environment), to vertex colours (PLY, glTF) or a rendered image (EXR,
 * PNG).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "cli.h"
#include "haarlight_tools.h"

static const char *const usage_relight =
    "usage: haarlight relight SCENE.hlt (--env ENV.exr | --sky) -o OUT [options]\n"
    "       haarlight relight SCENE.hlt --surroundings FILE [--surroundings-transform ...] [--time T]\n"
    "                         [--env ENV.exr | --sky]\n"
    "                         -o OUT [options]\n"
    "\n"
    "Relights a transport file from `haarlight precompute` under an environment, or\n"
    "lit by surroundings (a lamp, walls) captured around the object.\n"
    "OUT by extension: .ply (mesh with per-vertex colours), .glb (binary glTF 2.0: linear\n"
    "colours in COLOR_0, tone-mapped ones in COLOR_1), .exr (linear image),\n"
    ".png (tone-mapped image). Images are rendered headless with Embree.\n"
    "\n"
    "lighting:\n"
    "  --env ENV.exr|.hdr   equirectangular OpenEXR (any compression, DWAB included) or\n"
    "                       Radiance .hdr (run-length or flat)\n"
    "  --sky                the built-in procedural sun and sky (the default without --env\n"
    "                       and --surroundings)\n"
    CLI_USAGE_SKY
    CLI_USAGE_SURROUNDINGS
    CLI_USAGE_LAYOUT
    CLI_USAGE_LIGHTING
    "output:\n"
    "  --exposure EV        scale by 2^EV before tone mapping (PNG, 8-bit PLY; default:\n"
    "                       automatic: the object's 90th percentile of vertex\n"
    "                       luminance to 0.8, the ground left out)\n"
    "  --ply8               PLY with tone-mapped 8-bit colours instead of linear floats\n"
    CLI_USAGE_CAMERA
    "  --no-background      black instead of the environment behind the object\n"
    "  --textures MODEL     keep MODEL's base-colour textures: in images each pixel is the\n"
    "                       texture's albedo there times the irradiance interpolated from\n"
    "                       the vertices; a .glb embeds them, COLOR_0 then the base colour\n"
    "                       times the irradiance where textured.\n"
    "                       MODEL is the file SCENE.hlt was precomputed from (checked\n"
    "                       triangle for triangle)\n"
    "  --keep-winding       as given to precompute, for reading MODEL\n"
    "reference (with --surroundings, no --env or --sky):\n"
    "  --reference R        write a reference instead of the relit colours (same exposure)\n"
    "                       and print the relit colours' relative L2 error against it\n"
    "                       (all vertices, the object's, the ground's): exact, rays from\n"
    "                       each vertex to points on every emitting triangle, occluded by\n"
    "                       the object, ground and surroundings; centre, the same points\n"
    "                       seen from the capture point (exact - centre: its parallax);\n"
    "                       discrete, the untruncated transport dotted with the\n"
    "                       untruncated capture (centre - discrete: the resolution)\n"
    "  --reference-points K K x K points on each emitting triangle (default 32)\n"
    "running:\n"
    CLI_USAGE_RUNNING;

/* Relative L2 error of a against ref over vertices [v0, v1), in percent. */
static double rel_l2(const float *a, const float *ref, uint32_t v0, uint32_t v1)
{
    double num = 0.0, den = 0.0;
    for (size_t i = 3 * (size_t)v0; i < 3 * (size_t)v1; i++) {
        const double e = (double)a[i] - ref[i];
        num += e * e;
        den += (double)ref[i] * ref[i];
    }
    return den > 0.0 ? 100.0 * sqrt(num / den) : 0.0;
}

/* --reference: the reference's colours replace *rgb (freed), after the
 * relit colours' error against them is printed. */
static hl_result swap_in_reference(hl_context *ctx, const hl_transport *t, hl_surroundings *surr, int kind, uint32_t K,
                                   int quiet, float **rgb)
{
    const uint32_t nv = t->info.vertex_count, no = t->mesh->object_vertex_count ? t->mesh->object_vertex_count : nv;
    float *ref = malloc((size_t)nv * 12);
    if (!ref) return hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's colours");
    double sec = 0.0;
    hl_result r = hl_bench_capture_ref(ctx, t, surr, kind, K, ref, &sec);
    if (r != HL_OK) {
        free(ref);
        return r;
    }
    if (!quiet) {
        char what[64];
        if (kind == HL_CAPTURE_REF_DISCRETE) snprintf(what, sizeof what, "discrete");
        else snprintf(what, sizeof what, "%s, %u x %u points a triangle", kind == HL_CAPTURE_REF_EXACT ? "exact" : "centre", K, K);
        fprintf(stderr, "reference (%s) in %.1f s; the relit colours' relative L2 error against it: %.2f%%", what, sec,
                rel_l2(*rgb, ref, 0, nv));
        if (no < nv)
            fprintf(stderr, " (the object's %u vertices %.2f%%, the ground's %u %.2f%%)", no, rel_l2(*rgb, ref, 0, no),
                    nv - no, rel_l2(*rgb, ref, no, nv));
        fputc('\n', stderr);
    }
    free(*rgb);
    *rgb = ref;
    return HL_OK;
}

int cmd_relight(int argc, char **argv)
{
    const char *usage = usage_relight;
    const char *scene = NULL, *env_path = NULL, *out = NULL, *textures = NULL;
    hl_mesh_load_desc md;
    memset(&md, 0, sizeof md);
    cli_scene_opts o;
    cli_scene_opts_init(&o);
    o.accept_surroundings = 1;
    int ply8 = 0, no_bg = 0, want_sky = 0, reference = 0;
    uint32_t ref_points = 32;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        int k = cli_scene_opt(argc, argv, &i, usage, &o);
        if (k < 0) return -k;
        if (k) continue;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage, stdout); return 0; }
        else if (!strcmp(a, "--reference") || !strcmp(a, "--reference-points")) {
            if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a);
            const char *v = argv[++i];
            if (!strcmp(a, "--reference")) {
                if (!strcmp(v, "exact")) reference = HL_CAPTURE_REF_EXACT;
                else if (!strcmp(v, "centre") || !strcmp(v, "center")) reference = HL_CAPTURE_REF_CENTRE;
                else if (!strcmp(v, "discrete")) reference = HL_CAPTURE_REF_DISCRETE;
                else return usage_error(usage, "--reference %s: expected exact, centre or discrete", v);
            } else {
                char *end = NULL;
                unsigned long k = strtoul(v, &end, 10);
                if (!end || *end || end == v || k < 1 || k > HL_CAPTURE_REF_MAX_K)
                    return usage_error(usage, "--reference-points %s: expected a whole number from 1 to 256", v);
                ref_points = (uint32_t)k;
            }
        } else if (!strcmp(a, "-o") || !strcmp(a, "--output") || !strcmp(a, "--env") || !strcmp(a, "--textures")) {
            if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a);
            if (!strcmp(a, "--env")) env_path = argv[++i];
            else if (!strcmp(a, "--textures")) textures = argv[++i];
            else out = argv[++i];
        } else if (!strcmp(a, "--keep-winding")) md.keep_winding = 1; else if (!strcmp(a, "--sky")) want_sky = 1;
        else if (!strcmp(a, "--ply8")) ply8 = 1;
        else if (!strcmp(a, "--no-background")) no_bg = 1;
        else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (!scene) scene = a;
        else return usage_error(usage, "unexpected argument %s", a);
    }
    hl_context_desc cd = o.cd;
    hl_relight_desc rd = o.rd;
    float exposure = o.exposure;
    want_sky |= o.sky_set;
    if (!scene) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (!out) return usage_error(usage, "%s", "no output given (-o OUT.ply|.glb|.exr|.png)");
    if (env_path && want_sky) return usage_error(usage, "%s", "--env and the sky options contradict each other");
    if (o.time_set && !o.surroundings) return usage_error(usage, "%s", "--time needs --surroundings");
    if (o.place_set && !o.surroundings) return usage_error(usage, "%s", "--surroundings-transform needs --surroundings");
    if (reference && !o.surroundings) return usage_error(usage, "%s", "--reference needs --surroundings");
    if (o.probes_set && !o.surroundings) return usage_error(usage, "%s", "--probes needs --surroundings");
    if (reference && (env_path || want_sky))
        return usage_error(usage, "%s", "--reference integrates the surroundings' emitters alone: drop --env and the sky options");
    /* without --surroundings the sky is the default; with them, no map: black where they leave open */
    int use_env = env_path || want_sky || !o.surroundings;
    const char *ext = cli_ext_of(out);
    int is_ply = !strcasecmp(ext, ".ply"), is_glb = !strcasecmp(ext, ".glb"),
        is_img = !strcasecmp(ext, ".exr") || !strcasecmp(ext, ".png");
    if (!is_ply && !is_glb && !is_img) return usage_error(usage, "output %s: expected a .ply, .glb, .exr or .png name", out);
    if (textures && !is_img && !is_glb)
        return usage_error(usage, "--textures: for images (.png, .exr) and .glb only, not %s", out);
    if (md.keep_winding && !textures) return usage_error(usage, "%s", "--keep-winding goes with --textures");

    hl_context *ctx = cli_context(&cd);
    if (!ctx) return 1;
    hl_transport *t = NULL;
    hl_env *env = NULL;
    hl_relighter *rl = NULL;
    hl_image *img = NULL;
    hl_surroundings *surr = NULL;
    hl_surface *surface = NULL;
    float *rgb = NULL;
    hl_relight_stats st;
    const double t_load = hl_tools_now();
    hl_result r = hl_transport_load(ctx, scene, &t);
    const double t_built = hl_tools_now();
    if (r == HL_OK && !cd.quiet)
        fprintf(stderr, "loaded %s: %u vertices in %.2f s\n", scene, t->info.vertex_count, t_built - t_load);
    /* the references integrate direct light only: against a bounced file
       they would count the bounces as error */
    if (r == HL_OK && reference && t->info.bounces) {
        fprintf(stderr, "haarlight: relight: --reference: %s holds %u bounce%s of interreflection, and the "
                "references are of direct light only; relight a file precomputed without --bounces\n", scene,
                t->info.bounces, t->info.bounces == 1 ? "" : "s");
        hl_transport_destroy(t);
        cli_unwatch();
        hl_context_destroy(ctx);
        return 2;
    }
    if (r == HL_OK && !cd.quiet && t->info.bounces)
        fprintf(stderr, "%s: direct light and %u bounce%s of interreflection, baked with the albedo stored in the "
                "file (%s)\n", scene, t->info.bounces, t->info.bounces == 1 ? "" : "s",
                t->info.channels == 3 ? "coloured: a row a channel" : "grey");
    /* the textures change the albedo the picture shows, not the one the
       bounces were baked with */
    if (r == HL_OK && t->info.bounces && textures)
        fprintf(stderr, "%s: warning: --textures shows %s's texture albedo, but the bounces were baked with the "
                "albedo stored in the file (per vertex), so the light they carry keeps that albedo's colour\n", scene,
                textures);
    if (r == HL_OK && use_env)
        r = env_path ? cli_env_load(ctx, env_path, o.layout, &env, cd.quiet) : hl_env_create_sky(ctx, &o.sky, &env);
    if (r == HL_OK) r = cli_surroundings_load(ctx, &o, &surr, cd.quiet);
    if (r == HL_OK && textures) r = hl_surface_load(ctx, textures, &md, t->mesh, &surface);
    if (r == HL_OK && textures && !cd.quiet)
        fprintf(stderr, "textures: %u from %s%s\n", hl_surface_texture_count(surface), textures,
                hl_surface_texture_count(surface) ? "" : " (it has none: the picture shows the vertex colours)");
    const double t_rl = hl_tools_now();
    /* one lighting change: the rows as loaded, no column layout (or, for
       a transport too big for one device buffer, the columns built from
       the file, the loaded entries freed) */
    if (r == HL_OK) r = hl_relighter_create_once(ctx, t, scene, &rl);
    if (r == HL_OK && !cd.quiet)
        fprintf(stderr, "relighter ready in %.2f s (%s)\n", hl_tools_now() - t_rl,
                t->entries ? "the rows as loaded" : "the transport laid out for the device");
    if (r == HL_OK && !cd.quiet) cli_device_memory("", rl, scene, t->info.vertex_count, !t->entries);
    if (r == HL_OK && env) r = hl_relighter_set_env(rl, env);
    if (r == HL_OK && surr) r = hl_relighter_set_surroundings(rl, surr);
    if (r == HL_OK && surr && o.probes_set) r = hl_relighter_set_probes(rl, o.probes, 0.0);
    if (r == HL_OK) {
        rgb = malloc((size_t)t->info.vertex_count * 12);
        if (!rgb) r = HL_ERR_OUT_OF_MEMORY;
    }
    if (r == HL_OK) r = hl_relighter_run(rl, &rd, rgb, &st);
    char under[1200];
    const char *map = env_path ? env_path : env ? "the procedural sky" : NULL;
    if (surr) snprintf(under, sizeof under, "the surroundings %s at %g s, open directions %s", o.surroundings, o.time,
                       map ? map : "black");
    else snprintf(under, sizeof under, "%s", map ? map : "?");
    if (r == HL_OK && !cd.quiet)
        fprintf(stderr,
                "relit %s under %s on %s: %u lighting terms keep %.4f%% of the lighting energy "
                "(error bound %.4g per unit albedo); %.0f%% of blocks skipped; %.2f ms\n",
                scene, under, hl_context_device_name(ctx), st.terms_kept,
                100.0 * st.energy_kept, st.error_bound, 100.0 * st.blocks_skipped, 1e3 * st.seconds);
    if (r == HL_OK && !cd.quiet && st.negative_vertices)
        fprintf(stderr, "negative light: %u of %u vertices summed below zero and were clamped to 0 (the most negative "
                "channel was %.3g%% of the brightest)\n", st.negative_vertices, t->info.vertex_count,
                100.0 * st.most_negative);
    if (r == HL_OK && surr && !cd.quiet) cli_probes_report(&st, t->info.N, o.probes_set ? o.probes : 1);
    if (r == HL_OK && surr && !cd.quiet) {
        /* what the surroundings cost: memory and time grow with their
           triangles (no cap), so say both */
        hl_capture_cost cc;
        hl_result rc2 = hl_bench_capture_cost(rl, 3, &cc);
        if (rc2 == HL_OK)
            fprintf(stderr, "capture: %u triangles, %.2f MiB on the host and %.2f MiB on the device, %.2f ms a capture "
                    "(mean of 3 more)\n", cc.triangles, (double)cc.host_bytes / 1048576.0,
                    (double)cc.device_bytes / 1048576.0, 1e3 * cc.seconds);
        else
            r = rc2;
    }
    /* the colours are out: the device's columns go before the picture's
       render (Embree, the image) is made, so the two never add up */
    hl_relighter_destroy(rl);
    rl = NULL;
    if (r == HL_OK && !o.exposure_set) {
        exposure = hl_exposure_auto(t->mesh, rgb);
        if (!cd.quiet && (ply8 || is_glb || !strcasecmp(ext, ".png"))) fprintf(stderr, "exposure: %+.2f EV (automatic)\n", (double)exposure);
    }
    if (r == HL_OK && reference) r = swap_in_reference(ctx, t, surr, reference, ref_points, cd.quiet, &rgb);
    if (r == HL_OK && is_ply) r = hl_mesh_save_ply(ctx, t->mesh, rgb, out, ply8, exposure);
    if (r == HL_OK && is_glb) r = hl_mesh_save_glb_surface(ctx, t->mesh, rgb, surface, out, exposure);
    if (r == HL_OK && is_img) r = cli_camera_complete(ctx, t->mesh, &o);
    if (r == HL_OK && is_img)
        r = hl_render_surface(ctx, t->mesh, rgb, surface, no_bg ? NULL : env, rd.rotate_deg, &o.cam, &img);
    if (r == HL_OK && is_img) r = hl_image_save(ctx, img, out, exposure);
    if (r == HL_OK && !cd.quiet) fprintf(stderr, "wrote %s\n", out);
    int rc = r == HL_OK ? 0 : cli_fail(ctx, r);
    free(rgb);
    hl_image_destroy(img);
    hl_relighter_destroy(rl);
    hl_surroundings_destroy(surr);
    hl_surface_destroy(surface);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    cli_unwatch();
    hl_context_destroy(ctx);
    return rc;
}
