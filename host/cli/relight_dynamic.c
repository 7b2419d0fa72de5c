/* relight_dynamic.c - `haarlight relight-dynamic`: a mesh or a scene of
 * rigid bodies under an environment with the dynamic method (area lights
 * and convolution shadow maps, no precompute), at a time and with bodies
 * moved, to vertex colours (PLY, glTF) or a rendered image (EXR, PNG).
 * Sees the library through haarlight.h (the "dynamic scenes" section).
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "cli.h"
#include "haarlight_tools.h"

/* --move options one run takes: a scene with more bodies to move is a
 * job for the API, not the command line. */
#define DYN_MAX_MOVES 64
/* --lights default: the library's (area_lights.h), 32, which the paper's
 * costs are quoted at; every kept light costs a shadow map a frame. */
#define DYN_DEFAULT_LIGHTS 32

static const char *const usage_dyn =
    "usage: haarlight relight-dynamic (MESH | SCENE) (--env ENV.exr | --sky) -o OUT [options]\n"
    "\n"
    "Relights a mesh or a scene of rigid bodies with the dynamic method (Annen et al.\n"
    "2008), with no precompute: the environment is split into area lights, the K\n"
    "strongest each get a shadow map filtered as a moment shadow map (the default) or\n"
    "a convolution shadow map of order M (--shadow csm), the rest are folded into one\n"
    "unshadowed spherical-harmonic term, and every vertex is shaded diffusely. Every node of the file that holds triangles is a body,\n"
    "moving by the file's first animation (one that is not rigid, skinned or morphing,\n"
    "is refused: --rest-pose). OUT by extension: .ply, .glb, .exr or .png, as\n"
    "`haarlight relight`.\n"
    "\n"
    "Limits: the visibility approximates the exact one (filtered shadow test, filter\n"
    "width from the average blocker depth and the light's spread). On the bunny with\n"
    "its ground under eight HDR maps and the sky it is 1.6 to 3.7% (relative L2) from\n"
    "the exact result at rest and 1.2 to 2.7% with the bunny moved with moments (CSM:\n"
    "2.0 to 4.1% and 1.5 to 3.4%); --reference exact prints it for a frame. Moments\n"
    "leak light where a receiver lies behind casters of several depths (a tenth of it\n"
    "is cut off); CSM misses blockers closer to a receiver than about 0.75/M of the\n"
    "casters' depth range. A flat body with the others on one side (a ground) stays\n"
    "out of the shadow maps, and what it hides is worked out from its plane. Light\n"
    "beyond the K kept lights casts no shadow. Each kept light costs a shadow map and\n"
    "5 filtered images of R x R texels a frame with moments (4M + 1 with CSM: 4.6 MB a\n"
    "light at R = 128, M = 16, processed in batches); a sharp light (a sun) instead\n"
    "costs 5 Embree rays a vertex, 16 in its penumbra (--sharp).\n"
    "\n"
    "scene:\n"
    "  --ground             a ground plane under the object (body \"ground\"). A file with\n"
    "                       an animation keeps its bodies and motion, the ground under\n"
    "                       the whole motion; any other is loaded as one mesh, body\n"
    "                       \"object\", as `precompute --ground` loads it\n"
    "  --ground-size S      --ground with its side S x the footprint (1 < S <= 129;\n"
    "                       default: it holds the shadow of the top under a sun 15\n"
    "                       degrees high)\n"
    "  (textures: a file's base-colour textures stay sharp in images, per pixel, and are\n"
    "   embedded in a .glb; docs/MATERIALS.md)\n"
    "  --rest-pose          the file's animation not followed: its nodes as stored, skinned\n"
    "                       meshes in their bind pose, morph targets at their base\n"
    "  --time T             seconds into the animation (default 0; clamped to its keys)\n"
    "  --move BODY:X,Y,Z    translate the body named BODY (world units), repeatable\n"
    "lighting:\n"
    "  --env ENV.exr|.hdr   equirectangular OpenEXR or Radiance .hdr\n"
    "  --sky                the built-in procedural sun and sky (the default without --env)\n"
    CLI_USAGE_SKY
    CLI_USAGE_LAYOUT
    "  --rotate DEG         turn the environment about +Y\n"
    "  --lights K           area lights with shadows, K >= 1 (default 32); the cost of a\n"
    "                       frame grows in proportion\n"
    "  --split-threshold T  a light grows while a ring adds more than T of its own\n"
    "                       energy so far, 0 < T < 1 (default 0.1)\n"
    "  --shadow-res R       shadow map size, a multiple of 16 from 16 to 1024 (default 128)\n"
    "  --sharp MODE         the sharp lights (a sun: a light whose filter is under 4\n"
    "                       texels of an R map), up to 4 of them, the strongest: rays\n"
    "                       (Embree occlusion rays from every vertex over the light's\n"
    "                       spread, 5 a vertex and 16 in a penumbra; the default with\n"
    "                       moments), maps (shadow maps of --sharp-res) or off (maps of\n"
    "                       R as the rest; the default with CSM)\n"
    "  --sharp-res RS       the sharp lights' map size with --sharp maps (given alone, it\n"
    "                       asks for them), a multiple of 16 from R to 1024 (default 4 R,\n"
    "                       at most 1024). RS = R: one size for all (--sharp off)\n"
    "  --order M            convolution shadow map order, 4 to 16 (default 16): lower is\n"
    "                       cheaper (memory and time in proportion) with softer, leakier\n"
    "                       shadows; CSM only (given alone, it asks for CSM)\n"
    "  --shadow S           the filterable shadow map: moments (the default: moment\n"
    "                       shadow maps, Peters and Klein 2015, four powers of the depth\n"
    "                       and the coverage a texel, the blocker depth from the same\n"
    "                       moments) or csm (convolution shadow maps, 4M + 1 images a\n"
    "                       light, about 3 times the frame time); docs/DYNAMIC.md\n"
    "output:\n"
    "  --reference R        write a reference instead of the frame, and print the frame's\n"
    "                       relative L2 error against it: exact (each vertex integrates\n"
    "                       the whole map, cube texels of 64^2 a face, with Embree rays\n"
    "                       against every body; seconds, not milliseconds) or lights (the\n"
    "                       same K lights with traced visibility: the light split's own\n"
    "                       error). Not with --rotate\n"
    "  --diff DIFF          with --reference, also write the frame minus the reference:\n"
    "                       4 x the mean of the three channels' difference, red where\n"
    "                       the frame is brighter, blue where darker, at the frame's\n"
    "                       exposure (DIFF by extension: .ply, .glb, .exr or .png; a\n"
    "                       picture has no textures and a black background)\n"
    "  --exposure EV        scale by 2^EV before tone mapping (default: automatic)\n"
    "  --ply8               PLY with tone-mapped 8-bit colours instead of linear floats\n"
    CLI_USAGE_CAMERA
    "  --no-background      black instead of the environment behind the object\n"
    "running:\n"
    CLI_USAGE_RUNNING;

typedef struct dyn_opts {
    const char *scene, *env, *out, *diff;
    int ground, rest_pose, sky, ply8, no_bg;
    float ground_margin; /* --ground-size S: (S - 1) / 2; 0 the default */
    int reference; /* 0: the frame; 1: exact; 2: K lights traced */
    float time, threshold;
    uint32_t lights, R, Rs, M, nmoves, sharp;
    int shadow; /* 0: unset (CSM), 1: csm, 2: moments */
    char *move_name[DYN_MAX_MOVES];
    float move[DYN_MAX_MOVES][3];
} dyn_opts;

/* BODY:X,Y,Z, the name up to the last ':' */
static int parse_move(const char *v, dyn_opts *d)
{
    const char *colon = strrchr(v, ':');
    if (!colon || colon == v || d->nmoves >= DYN_MAX_MOVES) return 0;
    float t[3];
    if (!parse_vec3(colon + 1, t)) return 0;
    size_t n = (size_t)(colon - v);
    char *name = malloc(n + 1);
    if (!name) return 0;
    memcpy(name, v, n);
    name[n] = 0;
    d->move_name[d->nmoves] = name;
    memcpy(d->move[d->nmoves++], t, sizeof t);
    return 1;
}

/* The command's own options; 1 taken, 0 not one of them, -2 usage error. */
static int dyn_opt(int argc, char **argv, int *i, dyn_opts *d)
{
    const char *a = argv[*i], *v = NULL;
    static const char *const with_value[] = {"-o",     "--output",          "--env",        "--time", "--move",
                                             "--lights", "--split-threshold", "--shadow-res", "--sharp-res", "--sharp", "--order",
                                             "--reference", "--ground-size", "--shadow", "--diff", NULL};
    for (int k = 0; with_value[k]; k++)
        if (!strcmp(a, with_value[k])) {
            if (*i + 1 >= argc) return -usage_error(usage_dyn, "option %s needs a value", a);
            v = argv[++*i];
        }
    if (!strcmp(a, "-o") || !strcmp(a, "--output")) d->out = v;
    else if (!strcmp(a, "--diff")) d->diff = v;
    else if (!strcmp(a, "--env")) d->env = v;
    else if (!strcmp(a, "--sky")) d->sky = 1;
    else if (!strcmp(a, "--ground")) d->ground = 1;
    else if (!strcmp(a, "--ground-size")) {
        float gs;
        if (!parse_float(v, &gs) || !(gs > 1.0f) || !(gs <= 129.0f))
            return -usage_error(usage_dyn, "--ground-size %s: expected a size above 1 and at most 129 (x the footprint)", v);
        d->ground_margin = 0.5f * (gs - 1.0f);
        d->ground = 1;
    } else if (!strcmp(a, "--rest-pose")) d->rest_pose = 1;
    else if (!strcmp(a, "--ply8")) d->ply8 = 1;
    else if (!strcmp(a, "--no-background")) d->no_bg = 1;
    else if (!strcmp(a, "--time")) {
        if (!parse_float(v, &d->time) || !(d->time >= 0.0f) || !isfinite(d->time))
            return -usage_error(usage_dyn, "--time %s: expected seconds, finite and >= 0", v);
    } else if (!strcmp(a, "--move")) {
        if (!parse_move(v, d)) return -usage_error(usage_dyn, "--move %s: expected BODY:X,Y,Z (at most 64 moves)", v);
    } else if (!strcmp(a, "--lights")) {
        if (!parse_u32(v, &d->lights) || d->lights < 1 || d->lights > INT32_MAX)
            return -usage_error(usage_dyn, "--lights %s: expected K >= 1", v);
    } else if (!strcmp(a, "--split-threshold")) {
        if (!parse_float(v, &d->threshold) || !(d->threshold > 0.0f && d->threshold < 1.0f))
            return -usage_error(usage_dyn, "--split-threshold %s: expected 0 < T < 1", v);
    } else if (!strcmp(a, "--shadow-res")) {
        if (!parse_u32(v, &d->R) || d->R < 16 || d->R > 1024 || d->R % 16)
            return -usage_error(usage_dyn, "--shadow-res %s: expected a multiple of 16 from 16 to 1024", v);
    } else if (!strcmp(a, "--sharp-res")) {
        if (!parse_u32(v, &d->Rs) || d->Rs < 16 || d->Rs > 1024 || d->Rs % 16)
            return -usage_error(usage_dyn, "--sharp-res %s: expected a multiple of 16 from 16 to 1024", v);
    } else if (!strcmp(a, "--sharp")) {
        if (!parse_sharp(v, &d->sharp)) return -usage_error(usage_dyn, "--sharp %s: expected rays, maps or off", v);
    } else if (!strcmp(a, "--reference")) {
        if (!strcmp(v, "exact")) d->reference = 1;
        else if (!strcmp(v, "lights")) d->reference = 2;
        else return -usage_error(usage_dyn, "--reference %s: expected exact or lights", v);
    } else if (!strcmp(a, "--shadow")) {
        if (!strcmp(v, "csm")) d->shadow = 1;
        else if (!strcmp(v, "moments")) d->shadow = 2;
        else return -usage_error(usage_dyn, "--shadow %s: expected csm or moments", v);
    } else if (!strcmp(a, "--order")) {
        if (!parse_u32(v, &d->M) || d->M < 4 || d->M > 16)
            return -usage_error(usage_dyn, "--order %s: expected 4 to 16", v);
    } else return 0;
    return 1;
}

static int parse_args(int argc, char **argv, dyn_opts *d, cli_scene_opts *o)
{
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage_dyn, stdout); return 0; }
        if (!strcmp(a, "--terms") || !strcmp(a, "--select")) /* relight's wavelet options */
            return usage_error(usage_dyn, "%s is an option of `haarlight relight`, not of relight-dynamic", a);
        int k = dyn_opt(argc, argv, &i, d);
        if (k < 0) return -k;
        if (k) continue;
        k = cli_scene_opt(argc, argv, &i, usage_dyn, o);
        if (k < 0) return -k;
        if (k) continue;
        if (a[0] == '-' && a[1]) return usage_error(usage_dyn, "unknown option %s", a);
        if (d->scene) return usage_error(usage_dyn, "unexpected argument %s", a);
        d->scene = a;
    }
    d->sky |= o->sky_set;
    if (!d->scene) return usage_error(usage_dyn, "%s", "no MESH or SCENE given");
    if (!d->out) return usage_error(usage_dyn, "%s", "no output given (-o OUT.ply|.glb|.exr|.png)");
    if (d->env && d->sky) return usage_error(usage_dyn, "%s", "--env and the sky options contradict each other");
    if (d->M && d->shadow == 2)
        return usage_error(usage_dyn, "%s", "--order is the CSM's order: --shadow moments takes four moments, no order");
    if (d->Rs && d->sharp && d->sharp != HL_DYNAMIC_SHARP_MAPS)
        return usage_error(usage_dyn, "%s", "--sharp-res is the sharp lights' map size: it takes --sharp maps");
    if (d->reference && o->rd.rotate_deg != 0.0f)
        return usage_error(usage_dyn, "%s", "--reference integrates the map as given: drop --rotate");
    if (d->diff && !d->reference)
        return usage_error(usage_dyn, "%s", "--diff is the frame minus a reference: give --reference exact or lights");
    if (d->diff && !strcmp(d->diff, d->out))
        return usage_error(usage_dyn, "--diff %s: the same file as the output", d->diff);
    const char *outs[2] = {d->out, d->diff};
    for (int k = 0; k < 2 && outs[k]; k++) {
        const char *ext = cli_ext_of(outs[k]);
        if (strcasecmp(ext, ".ply") && strcasecmp(ext, ".glb") && strcasecmp(ext, ".exr") && strcasecmp(ext, ".png"))
            return usage_error(usage_dyn, k ? "--diff %s: expected a .ply, .glb, .exr or .png name"
                                            : "output %s: expected a .ply, .glb, .exr or .png name", outs[k]);
    }
    return -1; /* go on */
}

static void report(const char *scene, const char *env, hl_context *ctx, const hl_dynamic_lights *li,
                   const hl_dynamic_stats *st, const char *rep)
{
    char sharp[96] = "";
    if (st->sharp && st->sharp_mode == HL_DYNAMIC_SHARP_RAYS)
        snprintf(sharp, sizeof sharp, " (%u sharp by %llu rays in %.1f ms, the rest at %u^2)", st->sharp,
                 (unsigned long long)st->sharp_rays, 1e3 * st->t_sharp_rays, st->shadow_res);
    else if (st->sharp)
        snprintf(sharp, sizeof sharp, " (%u sharp at %u^2, the rest at %u^2)", st->sharp, st->sharp_res, st->shadow_res);
    fprintf(stderr,
            "relit %s under %s on %s: %u vertices; lights %u kept of %u (%u folded, %.2f%% of the energy), "
            "%u shadowed%s, %u skipped below every horizon, %u negligible; %u batch(es), %u shadow maps kept; "
            "%u ground vertices under a body, %u inside their body; "
            "split %.1f ms, irradiance %.1f ms, shadow maps %.1f ms, %s build %.1f ms, %s eval %.1f ms, "
            "shading %.1f ms; frame %.1f ms\n",
            scene, env ? env : "the procedural sky", hl_context_device_name(ctx), st->vertices, li->lights_kept,
            li->lights_made, li->folded, 100.0 * li->folded_share, st->shadowed, sharp, st->skipped_horizon,
            st->skipped_negligible, st->batches, st->maps_kept, st->covered, st->enclosed, 1e3 * li->seconds, 1e3 * st->t_irradiance, 1e3 * st->t_shadow_maps,
            rep, 1e3 * st->t_csm_build, rep, 1e3 * st->t_csm_eval, 1e3 * st->t_shading, 1e3 * st->t_total);
}

/* --reference: the reference's colours of the frame's geometry in *ref,
 * the frame's relative L2 error against them printed, and *rgb pointed
 * at them so that they are what is written. */
static hl_result swap_in_reference(hl_context *ctx, hl_dynamic *dy, const hl_env *env, int which, int quiet,
                                   float **rgb, float **ref)
{
    const hl_mesh *mesh = hl_dynamic_mesh(dy);
    size_t n = 3 * (size_t)mesh->vertex_count;
    *ref = malloc(n * sizeof(float));
    if (!*ref) return hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's colours");
    double sec = 0.0, num = 0.0, den = 0.0;
    hl_result r = which == 1 ? hl_bench_dyn_exact(dy, env, *ref, &sec) : hl_bench_dyn_lights(dy, *ref, &sec);
    if (r != HL_OK) return r;
    for (size_t i = 0; i < n; i++) {
        double e = (double)(*rgb)[i] - (*ref)[i];
        num += e * e;
        den += (double)(*ref)[i] * (*ref)[i];
    }
    if (!quiet)
        fprintf(stderr, "reference (%s) in %.1f s; the frame's relative L2 error against it: %.2f%%\n",
                which == 1 ? "exact" : "the K lights traced", sec, den > 0.0 ? 100.0 * sqrt(num / den) : 0.0);
    *rgb = *ref;
    return HL_OK;
}

/* --diff: the frame minus the reference, a colour a vertex (see the
 * usage), written to d->diff by its extension. */
static hl_result write_diff(hl_context *ctx, const dyn_opts *d, cli_scene_opts *o, const hl_mesh *mesh,
                            const float *frame, const float *ref, float exposure)
{
    const float gain = 4.0f;
    size_t nv = mesh->vertex_count;
    float *c = malloc(3 * nv * sizeof(float));
    if (!c) return hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the difference's colours");
    for (size_t v = 0; v < nv; v++) {
        const float *f = frame + 3 * v, *r = ref + 3 * v;
        float s = gain * (((f[0] - r[0]) + (f[1] - r[1])) + (f[2] - r[2])) / 3.0f;
        if (!isfinite(s)) s = 0.0f; /* never reached: both are finite; no output holds a NaN */
        c[3 * v] = fmaxf(s, 0.0f);
        c[3 * v + 1] = 0.0f;
        c[3 * v + 2] = fmaxf(-s, 0.0f);
    }
    const char *ext = cli_ext_of(d->diff);
    hl_result r;
    hl_image *img = NULL;
    if (!strcasecmp(ext, ".ply")) r = hl_mesh_save_ply(ctx, mesh, c, d->diff, d->ply8, exposure);
    else if (!strcasecmp(ext, ".glb")) r = hl_mesh_save_glb_surface(ctx, mesh, c, NULL, d->diff, exposure);
    else {
        r = cli_camera_complete(ctx, mesh, o);
        if (r == HL_OK) r = hl_render_surface(ctx, mesh, c, NULL, NULL, 0.0f, &o->cam, &img);
        if (r == HL_OK) r = hl_image_save(ctx, img, d->diff, exposure);
    }
    if (r == HL_OK && !o->cd.quiet) fprintf(stderr, "wrote %s (the frame minus the reference)\n", d->diff);
    hl_image_destroy(img);
    free(c);
    return r;
}

/* Loads, moves, lights, renders and writes; the exit code. */
static int run(const dyn_opts *d, cli_scene_opts *o)
{
    hl_context *ctx = cli_context(&o->cd);
    if (!ctx) return 1;
    hl_dynamic *dy = NULL;
    hl_env *env = NULL;
    hl_image *img = NULL;
    float *rgb = NULL, *ref = NULL, *frame = NULL, exposure = o->exposure;
    /* --order alone asks for the CSM it is the order of */
    const int csm = d->shadow == 1 || (d->shadow == 0 && d->M);
    hl_dynamic_desc desc = {d->R, d->M, csm ? HL_DYNAMIC_SHADOW_CSM : HL_DYNAMIC_SHADOW_MOMENTS, d->Rs, d->sharp};
    hl_dynamic_lights li;
    hl_dynamic_stats st;
    int rc = 0;
    const int flags = (d->ground ? HL_DYNAMIC_GROUND : 0) | (d->rest_pose ? HL_DYNAMIC_REST_POSE : 0);
    const hl_ground_desc gd = {.margin = d->ground_margin};
    hl_result r = hl_dynamic_create_from_file_ground(ctx, d->scene, flags, &desc, &gd, &dy);
    for (uint32_t m = 0; r == HL_OK && m < d->nmoves; m++) {
        if (hl_dynamic_move(dy, d->move_name[m], d->move[m]) != HL_OK) {
            fprintf(stderr, "haarlight: --move: %s\n", hl_context_last_error(ctx));
            rc = 2;
            break;
        }
    }
    if (rc == 0) {
        if (r == HL_OK)
            r = d->env ? cli_env_load(ctx, d->env, o->layout, &env, o->cd.quiet) : hl_env_create_sky(ctx, &o->sky, &env);
        if (r == HL_OK)
            r = hl_dynamic_set_env(dy, env, d->lights ? (int32_t)d->lights : DYN_DEFAULT_LIGHTS, d->threshold,
                                   o->rd.rotate_deg, &li);
        if (r == HL_OK) r = hl_dynamic_render(dy, (double)d->time, &rgb, &st);
        if (r == HL_OK && !o->cd.quiet) report(d->scene, d->env, ctx, &li, &st, csm ? "CSM" : "moments");
        /* the frame's exposure, so that a reference and its frame look alike */
        if (r == HL_OK && !o->exposure_set) exposure = hl_exposure_auto(hl_dynamic_mesh(dy), rgb);
        frame = rgb;
        if (r == HL_OK && d->reference) r = swap_in_reference(ctx, dy, env, d->reference, o->cd.quiet, &rgb, &ref);
        const hl_mesh *mesh = dy ? hl_dynamic_mesh(dy) : NULL;
        const char *ext = cli_ext_of(d->out);
        int is_ply = !strcasecmp(ext, ".ply"), is_glb = !strcasecmp(ext, ".glb"), is_img = !is_ply && !is_glb;
        if (r == HL_OK && is_ply) r = hl_mesh_save_ply(ctx, mesh, rgb, d->out, d->ply8, exposure);

        /* the textures stay sharp in pictures and are embedded in a .glb:
           the bodies' own surface for a file moved body by body, else the
           file's as one mesh */
        hl_surface *loaded = NULL;
        const hl_surface *surface = dy ? hl_dynamic_surface(dy) : NULL;
        if (r == HL_OK && (is_img || is_glb) && !surface) {
            int quiet = o->cd.quiet;
            hl_context_set_quiet(ctx, 1);
            if (hl_surface_load(ctx, d->scene, NULL, mesh, &loaded) != HL_OK) loaded = NULL;
            hl_context_set_quiet(ctx, quiet);
            surface = loaded;
        }
        if (r == HL_OK && (is_img || is_glb) && !o->cd.quiet && hl_surface_texture_count(surface))
            fprintf(stderr, "textures: %u, per pixel\n", hl_surface_texture_count(surface));
        if (r == HL_OK && is_glb) r = hl_mesh_save_glb_surface(ctx, mesh, rgb, surface, d->out, exposure);
        if (r == HL_OK && is_img) r = cli_camera_complete(ctx, mesh, o);
        if (r == HL_OK && is_img)
            r = hl_render_surface(ctx, mesh, rgb, surface, d->no_bg ? NULL : env, o->rd.rotate_deg, &o->cam, &img);
        hl_surface_destroy(loaded);
        if (r == HL_OK && is_img) r = hl_image_save(ctx, img, d->out, exposure);
        if (r == HL_OK && !o->cd.quiet) fprintf(stderr, "wrote %s\n", d->out);
        if (r == HL_OK && d->diff) r = write_diff(ctx, d, o, mesh, frame, ref, exposure);
        rc = r == HL_OK ? 0 : cli_fail(ctx, r);
    }
    hl_image_destroy(img);
    free(ref);
    hl_env_destroy(env);
    hl_dynamic_destroy(dy);
    cli_unwatch();
    hl_context_destroy(ctx);
    return rc;
}

int cmd_relight_dynamic(int argc, char **argv)
{
    dyn_opts d;
    memset(&d, 0, sizeof d);
    cli_scene_opts o;
    cli_scene_opts_init(&o);
    int rc = parse_args(argc, argv, &d, &o);
    if (rc < 0) rc = run(&d, &o);
    for (uint32_t m = 0; m < d.nmoves; m++) free(d.move_name[m]);
    return rc;
}
