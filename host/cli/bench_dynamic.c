/* bench_dynamic.c - `haarlight bench-dynamic`: error against time for
 * both relighting methods on one transport file's mesh (with its ground):
 *   at rest:  wavelet PRT at M terms against the dynamic method at K
 *             lights and order M;
 *   moved:    the object lifted and pushed sideways, where PRT cannot
 *             follow: the dynamic method against per-vertex Embree rays
 *             towards each of the K lights, S a light (the traced method);
 * every colour against the exact reference (each vertex integrating the
 * whole map with Embree visibility on the geometry as it is), and the
 * moved frames also against the K-lights reference (the same K lights
 * with traced visibility), which separates the light split's error from
 * the shadow maps'. This file holds the options and the measuring; the
 * references and the traced method are the library's (haarlight_tools.h,
 * "bench-dynamic"), the files are written by bench_out.c.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>

#include "cli.h"
#include "haarlight_tools.h"

/* Dynamic settings (K:M) and traced S values a run takes: a handful is a
 * readable table and plot. */
#define BD_MAX_SETTINGS 8
#define BD_MAX_SAMPLES 8
#define BD_MAX_REPS 100
/* K of a setting at most: each kept light costs a shadow map a frame, so
 * 4096 (seconds a frame at R = 256) is past anything worth timing. */
#define BD_MAX_K 4096u
/* The moved frames: the object lifted by 0.3 of its height and pushed
 * half its width along +X, as test_dyn_reference's accuracy run, so it
 * casts its shadow away from where it stood and PRT's transport is void. */
#define BD_LIFT 0.3
#define BD_SIDEWAYS 0.5
/* The nudge along +X that makes each timed frame a new one (a frame with
 * nothing moved is the last one again, at no cost, and one where only the
 * ground moved keeps its shadow maps): 1e-6 of the scene's diagonal a
 * frame, far below anything the shading sees. The object is a caster, so
 * every map is made again. */
#define BD_NUDGE 1e-6

static const char *const usage_bd =
    "usage: haarlight bench-dynamic SCENE.hlt [--env ENV.exr ...] [--sky] [options]\n"
    "\n"
    "Error against time for both relighting methods on the mesh of SCENE.hlt (made with\n"
    "--ground, so the object has a ground to shadow). At rest: wavelet PRT (SCENE.hlt at\n"
    "M terms) and the dynamic method (K lights, order M). Moved (the object lifted by 0.3\n"
    "of its height and pushed half its width along +X, which PRT cannot follow): the\n"
    "dynamic method and the traced method (per vertex, S Embree rays towards each of the\n"
    "K lights, stratified over its energy; BVH rebuilt each frame). Errors are relative\n"
    "L2 over every vertex against the exact result (each vertex integrates the whole map,\n"
    "resampled on a cube of 64^2 a face, with Embree visibility on the geometry as it\n"
    "is); moved frames also against the same K lights with traced visibility, which\n"
    "separates the light split's error from the shadow maps'. Times are medians of\n"
    "frames that are really computed (the object nudged by 1e-6 of the scene's diagonal\n"
    "each: every shadow map made again), with the dynamic method's split by stage.\n"
    "Writes bench.md, bench.csv, bench.gp and bench.svg (gnuplot) to the output\n"
    "folder, and says per map which method wins at equal error and whether the\n"
    "dynamic method at the goal setting makes 10 frames per second and 3 times the\n"
    "traced method's speed at equal or lower error.\n"
    "\n"
    "  --env ENV.exr        an environment, OpenEXR or .hdr (repeat for more); --sky adds\n"
    "                       the procedural sky (the default without --env)\n"
    "  --layout L           how the --env maps are laid out: auto (by size), equirect,\n"
    "                       angular, cross-h or cross-v\n"
    "  -o, --output DIR     where the files go (default bench-dynamic-out; each is\n"
    "                       written whole or not at all)\n"
    "  --terms LIST         PRT terms M, comma-separated (default 50,100,200,500,1000,all)\n"
    "  --settings LIST      dynamic K:M pairs, comma-separated, M an order of CSM (4 to 16)\n"
    "                       or \"moments\" for the moment shadow maps (at most 8); the\n"
    "                       first with K = 32 and the default representation (moments),\n"
    "                       else the first, is the goal setting. Default by --shadow\n"
    "  --shadow S           which representations the default settings take: both (the\n"
    "                       default: 32:moments,16:moments,8:moments,32:16,16:16,8:16,\n"
    "                       32:8,32:4), moments (32:moments,16:moments,8:moments) or csm\n"
    "                       (8:16,16:16,32:16,32:8,32:4)\n"
    "  --samples LIST       traced rays a light S, comma-separated, 1 to 1024 (default\n"
    "                       1,4,16; at most 8), at every K of the settings\n"
    "  --shadow-res R       shadow map size, a multiple of 16 from 16 to 1024 (default 128,\n"
    "                       relight-dynamic's, where the speed goal is stated)\n"
    "  --sharp MODE         the sharp lights (a sun), as relight-dynamic's: rays (the\n"
    "                       default with moments), maps (of --sharp-res) or off (the\n"
    "                       default with CSM)\n"
    "  --sharp-res RS       the sharp lights' map size with --sharp maps, as\n"
    "                       relight-dynamic's (default 4 R, at most 1024; given alone, it\n"
    "                       asks for the maps)\n"
    "  --reps R             timed frames per PRT and dynamic row (default 5, 1 to 100)\n"
    "  --traced-reps R      timed frames per traced row (default 3, 1 to 100)\n"
    "  --device cl|ref|cl:P:D   the device both methods run on (default: OpenCL's first, or\n"
    "                       HL_OPENCL_DEVICE=P:D; HL_DEVICE_SHAPE=cpu|gpu forces the shape)\n"
    "  --device-memory SIZE most device memory to use, e.g. 512M\n";

typedef struct bd_opts {
    const char *file, *outdir;
    int nenvs, want_sky;
    uint32_t terms[BENCH_MAX_TERMS], nterms;
    uint32_t K[BD_MAX_SETTINGS], M[BD_MAX_SETTINGS], nset;
    uint32_t S[BD_MAX_SAMPLES], nS;
    uint32_t R, Rs, sharp, reps, treps;
    hl_context_desc cd;
    hl_env_layout layout;
} bd_opts;

/* Rows at most: per map, PRT terms, and at rest and moved the settings,
 * plus per K the K-lights reference and the traced S values. */
#define BD_MAX_ROWS (BENCH_MAX_ENVS * (BENCH_MAX_TERMS + 2 * BD_MAX_SETTINGS + BD_MAX_SETTINGS * (1 + BD_MAX_SAMPLES)))

typedef struct bd {
    bd_opts o;
    bench_env envs[BENCH_MAX_ENVS];
    hl_context *ctx;
    hl_transport *t;
    hl_relighter *rl;
    hl_dynamic *dyn[BD_MAX_SETTINGS]; /* one per distinct order */
    uint32_t dyn_M[BD_MAX_SETTINGS], ndyn;
    uint32_t V, goal;                 /* goal: index of the goal setting */
    float *exact, *B, *lights[BD_MAX_SETTINGS]; /* lights: per setting's K */
    float base[3], nudge;             /* the object's translation now */
    float moved[3];                   /* the moved frames' translation */
    uint32_t sharp_res;               /* the sharp lights' map size a frame used (0: none) */
    int sharp_rays;                   /* a frame took its sharp lights by rays */
    double ref_seconds;
    bd_row rows[BD_MAX_ROWS];
    uint32_t nrows;
    bench_out out;
} bd;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, uint32_t n)
{
    qsort(v, n, sizeof *v, cmp_double);
    return n ? v[n / 2] : NAN;
}

/* ---------------------------------------------------------------- options */

/* A comma-separated list of numbers (K:M pairs when M is not NULL) into
 * a (and m); returns 0 or the usage error's exit code. */
static int parse_list(const char *opt, const char *v, uint32_t max, uint32_t lo, uint32_t hi, uint32_t *a, uint32_t *m,
                      uint32_t *n)
{
    char buf[512], *save = NULL;
    snprintf(buf, sizeof buf, "%s", v);
    *n = 0;
    for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        if (*n == max) return usage_error(usage_bd, "%s: at most 8 values", opt);
        char *colon = m ? strchr(tok, ':') : NULL;
        if (m && !colon) return usage_error(usage_bd, "%s: expected K:M pairs such as 32:16", opt);
        if (colon) *colon = '\0';
        char msg[160];
        snprintf(msg, sizeof msg, "%s: %s is not a whole number from %u to %u", opt, tok, lo, hi);
        if (!parse_u32(tok, &a[*n]) || a[*n] < lo || a[*n] > hi) return usage_error(usage_bd, "%s", msg);
        snprintf(msg, sizeof msg, "%s: order %s, expected 4 to 16 or moments", opt, colon ? colon + 1 : "");
        /* K:moments: the moment shadow maps, kept as order 0 in the rows */
        if (colon && !strcmp(colon + 1, "moments")) m[*n] = 0;
        else if (colon && (!parse_u32(colon + 1, &m[*n]) || m[*n] < 4 || m[*n] > 16)) return usage_error(usage_bd, "%s", msg);
        (*n)++;
    }
    return *n ? 0 : usage_error(usage_bd, "%s: no values", opt);
}

static int parse_terms_list(const char *v, bd_opts *o)
{
    char buf[512], *save = NULL;
    snprintf(buf, sizeof buf, "%s", v);
    o->nterms = 0;
    for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        if (o->nterms == BENCH_MAX_TERMS) return usage_error(usage_bd, "%s", "--terms: at most 16 values");
        uint32_t *t = &o->terms[o->nterms++];
        if (!strcmp(tok, "all")) *t = HL_TERMS_ALL;
        else if (!parse_u32(tok, t) || *t < 1) return usage_error(usage_bd, "--terms: bad value %s", tok);
    }
    return o->nterms ? 0 : usage_error(usage_bd, "--terms %s: no values", v);
}

/* Options; returns -1 to go on, else the exit code. */
static int parse_bd(int argc, char **argv, bd *b)
{
    bd_opts *o = &b->o;
    *o = (bd_opts){.outdir = "bench-dynamic-out", .terms = {50, 100, 200, 500, 1000, HL_TERMS_ALL}, .nterms = 6,
                   .K = {8, 16, 32, 32, 32}, .M = {16, 16, 16, 8, 4}, .nset = 5, .S = {1, 4, 16}, .nS = 3,
                   .R = 128, .reps = 5, .treps = 3,
                   .cd = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .quiet = 1}};
    int settings_given = 0, shadow = 0; /* 0 both, 1 csm, 2 moments */
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
        int e = 0;
#define NEED() do { if (i + 1 >= argc) return usage_error(usage_bd, "option %s needs a value", a); v = argv[++i]; } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage_bd, stdout); return 0; }
        else if (!strcmp(a, "--layout")) { NEED(); if (!parse_layout(v, &o->layout)) return usage_error(usage_bd, "--layout %s: expected auto, equirect, angular, cross-h or cross-v", v); }
        else if (!strcmp(a, "--env")) {
            NEED();
            if (o->nenvs == BENCH_MAX_ENVS - 1) return usage_error(usage_bd, "%s", "at most 15 environments");
            b->envs[o->nenvs].path = v;
            b->envs[o->nenvs++].name = bench_base_name(v);
        } else if (!strcmp(a, "--sky")) o->want_sky = 1;
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED(); o->outdir = v; }
        else if (!strcmp(a, "--terms")) { NEED(); if ((e = parse_terms_list(v, o))) return e; }
        else if (!strcmp(a, "--settings")) { NEED(); settings_given = 1; if ((e = parse_list("--settings", v, BD_MAX_SETTINGS, 1, BD_MAX_K, o->K, o->M, &o->nset))) return e; }
        else if (!strcmp(a, "--shadow")) {
            NEED();
            if (!strcmp(v, "both")) shadow = 0;
            else if (!strcmp(v, "moments")) shadow = 2;
            else if (!strcmp(v, "csm")) shadow = 1;
            else return usage_error(usage_bd, "--shadow %s: expected both, moments or csm", v);
        }
        else if (!strcmp(a, "--samples")) { NEED(); if ((e = parse_list("--samples", v, BD_MAX_SAMPLES, 1, HL_BENCH_TRACED_MAX_S, o->S, NULL, &o->nS))) return e; }
        else if (!strcmp(a, "--shadow-res")) { NEED(); if (!parse_u32(v, &o->R) || o->R < 16 || o->R > 1024 || o->R % 16) return usage_error(usage_bd, "--shadow-res %s: expected a multiple of 16 from 16 to 1024", v); }
        else if (!strcmp(a, "--sharp-res")) { NEED(); if (!parse_u32(v, &o->Rs) || o->Rs < 16 || o->Rs > 1024 || o->Rs % 16) return usage_error(usage_bd, "--sharp-res %s: expected a multiple of 16 from 16 to 1024", v); }
        else if (!strcmp(a, "--sharp")) { NEED(); if (!parse_sharp(v, &o->sharp)) return usage_error(usage_bd, "--sharp %s: expected rays, maps or off", v); }
        else if (!strcmp(a, "--reps")) { NEED(); if (!parse_u32(v, &o->reps) || o->reps < 1 || o->reps > BD_MAX_REPS) return usage_error(usage_bd, "--reps %s: expected 1 to 100", v); }
        else if (!strcmp(a, "--traced-reps")) { NEED(); if (!parse_u32(v, &o->treps) || o->treps < 1 || o->treps > BD_MAX_REPS) return usage_error(usage_bd, "--traced-reps %s: expected 1 to 100", v); }
        else if (!strcmp(a, "--device-memory")) { NEED(); if (!parse_device_memory(v, &o->cd)) return usage_error(usage_bd, "--device-memory %s: expected a byte count such as 512M or 2G", v); }
        else if (!strcmp(a, "--device")) { NEED(); if (!parse_device(v, &o->cd)) return usage_error(usage_bd, "--device %s: expected cl, ref or cl:PLATFORM:DEVICE", v); }
        else if (a[0] == '-' && a[1]) return usage_error(usage_bd, "unknown option %s", a);
        else if (o->file) return usage_error(usage_bd, "%s", "one SCENE.hlt only");
        else o->file = a;
#undef NEED
    }
    if (!o->file) return usage_error(usage_bd, "%s", "no SCENE.hlt given");
    if (settings_given && shadow)
        return usage_error(usage_bd, "%s", "--shadow picks the default settings: give it or --settings, not both");
    if (!settings_given && shadow != 1) { /* moments first: the default representation */
        static const uint32_t mk[8] = {32, 16, 8, 32, 16, 8, 32, 32}, mm[8] = {0, 0, 0, 16, 16, 16, 8, 4};
        o->nset = shadow == 2 ? 3 : 8;
        memcpy(o->K, mk, sizeof mk);
        memcpy(o->M, mm, sizeof mm);
    }
    if (o->want_sky || o->nenvs == 0) {
        b->envs[o->nenvs].name = "sky";
        b->envs[o->nenvs++].path = NULL;
    }
    b->goal = 0;
    for (uint32_t k = o->nset; k-- > 0;)
        if (o->K[k] == 32 && o->M[k] == 0) b->goal = k;
    return -1;
}

/* ---------------------------------------------------------------- set-up */

/* The dynamic scene of order M (one per distinct order of the settings). */
static hl_dynamic *dyn_of(const bd *b, uint32_t M)
{
    for (uint32_t k = 0; k < b->ndyn; k++)
        if (b->dyn_M[k] == M) return b->dyn[k];
    return NULL;
}

/* The transport, the maps, the PRT relighter, one dynamic scene per
 * order, checked to hold the transport's vertices in its order. */
static hl_result load(bd *b)
{
    const bd_opts *o = &b->o;
    hl_result r = hl_transport_load(b->ctx, o->file, &b->t);
    for (int e = 0; e < o->nenvs && r == HL_OK; e++) {
        hl_sky_desc sky = {0};
        bench_env *en = &b->envs[e];
        r = en->path ? cli_env_load(b->ctx, en->path, o->layout, &en->env, 0) : hl_env_create_sky(b->ctx, &sky, &en->env);
    }
    if (r == HL_OK) r = hl_relighter_create(b->ctx, b->t, &b->rl);
    const hl_mesh *tm = r == HL_OK ? b->t->mesh : NULL;
    if (tm && tm->object_vertex_count == tm->vertex_count)
        fprintf(stderr, "bench-dynamic: %s has no ground: the dynamic scene gets the default one, PRT none\n", o->file);
    for (uint32_t k = 0; k < o->nset && r == HL_OK; k++) {
        if (dyn_of(b, o->M[k])) continue;
        hl_dynamic_desc dd = {.shadow_res = o->R, .order = o->M[k],
                              .shadow = o->M[k] ? HL_DYNAMIC_SHADOW_CSM : HL_DYNAMIC_SHADOW_MOMENTS, .sharp_res = o->Rs,
                              .sharp = o->sharp};
        r = hl_dynamic_create_from_mesh(b->ctx, tm, 1, &dd, &b->dyn[b->ndyn]);
        if (r != HL_OK) break;
        b->dyn_M[b->ndyn++] = o->M[k];
        const hl_mesh *dm = hl_dynamic_mesh(b->dyn[b->ndyn - 1]);
        double worst = 0.0;
        for (size_t i = 0; dm->vertex_count == tm->vertex_count && i < 3 * (size_t)tm->vertex_count; i++)
            worst = fmax(worst, fabs((double)dm->positions[i] - tm->positions[i]));
        if (dm->vertex_count != tm->vertex_count || worst > 1e-6 * (1.0 + hl_mesh_query_diagonal(tm)))
            r = hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT,
                              "%s: the dynamic scene's vertices (%u) are not the transport's (%u) in its order; "
                              "make the transport with --ground", o->file, dm->vertex_count, tm->vertex_count);
    }
    b->V = tm ? tm->vertex_count : 0;
    const size_t n = 3 * (size_t)b->V * sizeof(float);
    if (r == HL_OK && !((b->exact = malloc(n)) && (b->B = malloc(n))))
        r = hl_tools_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %u vertex colours", b->V);
    for (uint32_t k = 0; k < o->nset && r == HL_OK; k++)
        if (!(b->lights[k] = malloc(n))) r = hl_tools_fail(b->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    return r;
}

/* The object's translation base + (nudge, 0, 0) in every dynamic scene. */
static hl_result place(bd *b, const float base[3], float nudge)
{
    memcpy(b->base, base, sizeof b->base);
    b->nudge = nudge;
    const float tr[3] = {base[0] + nudge, base[1], base[2]};
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < b->ndyn && r == HL_OK; k++) r = hl_dynamic_move(b->dyn[k], "object", tr);
    return r;
}

/* ---------------------------------------------------------------- errors */

/* Relative L2 over every vertex and channel, and the worst difference
 * over the brightest reference value. */
static void errors(const float *B, const float *ref, uint32_t V, double *l2, double *mx)
{
    double se = 0, sr = 0, me = 0, mr = 0;
    for (size_t i = 0; i < 3 * (size_t)V; i++) {
        double d = (double)B[i] - ref[i];
        se += d * d, sr += (double)ref[i] * ref[i];
        me = fmax(me, fabs(d)), mr = fmax(mr, fabs((double)ref[i]));
    }
    *l2 = sr > 0 ? sqrt(se / sr) : sqrt(se);
    *mx = mr > 0 ? me / mr : me;
}

static bd_row *new_row(bd *b, int e, int moving, int method, uint32_t K, uint32_t M, uint32_t S)
{
    bd_row *w = &b->rows[b->nrows++];
    *w = (bd_row){.env = e, .moving = moving, .method = method, .K = K, .M = M, .S = S, .l2_lights = NAN, .ms = NAN};
    for (int k = 0; k < 6; k++) w->stage[k] = NAN;
    return w;
}

/* ---------------------------------------------------------------- measuring */

/* The PRT rows under map e at rest: the median of reps full lighting
 * changes (a new rotation of 1e-3 degree each), the error at rotation 0. */
static hl_result prt_rows(bd *b, int e)
{
    hl_result r = hl_relighter_set_env(b->rl, b->envs[e].env);
    if (r == HL_OK) r = hl_relighter_run(b->rl, NULL, b->B, NULL); /* PoCL compiles lazily */
    for (uint32_t mi = 0; mi < b->o.nterms && r == HL_OK; mi++) {
        hl_relight_desc d = {.terms = b->o.terms[mi], .select = HL_SELECT_DEFAULT};
        double t[BD_MAX_REPS];
        hl_relight_stats st;
        for (uint32_t k = 0; k < b->o.reps && r == HL_OK; k++) {
            d.rotate_deg = 1e-3f * (float)(k + 1);
            r = hl_relighter_run(b->rl, &d, b->B, &st);
            t[k] = st.seconds;
        }
        d.rotate_deg = 0.0f;
        if (r == HL_OK) r = hl_relighter_run(b->rl, &d, b->B, NULL);
        if (r != HL_OK) break;
        bd_row *w = new_row(b, e, 0, BD_PRT, 0, b->o.terms[mi] == HL_TERMS_ALL ? 0 : b->o.terms[mi], 0);
        errors(b->B, b->exact, b->V, &w->l2, &w->mx);
        w->ms = 1e3 * median(t, b->o.reps);
    }
    return r;
}

/* Setting k's frame at the current place: reps timed frames, each nudged
 * a little further, then the frame at the place itself into b->B. */
static hl_result dyn_frame(bd *b, uint32_t k, bd_row *w)
{
    hl_dynamic *d = dyn_of(b, b->o.M[k]);
    float *rgb = NULL;
    hl_dynamic_stats st;
    double t[7][BD_MAX_REPS], wall[BD_MAX_REPS];
    const float base[3] = {b->base[0], b->base[1], b->base[2]};
    const hl_mesh *m = hl_dynamic_mesh(d);
    const float step = (float)(BD_NUDGE * hl_mesh_query_diagonal(m));
    hl_result r = hl_dynamic_set_env(d, b->envs[w->env].env, (int32_t)b->o.K[k], 0.0f, 0.0f, NULL);
    if (r == HL_OK) r = hl_dynamic_render(d, 0.0, &rgb, &st); /* compiles, allocates */
    for (uint32_t i = 0; i < b->o.reps && r == HL_OK; i++) {
        r = place(b, base, step * (float)(i + 1));
        double t0 = hl_tools_now();
        if (r == HL_OK) r = hl_dynamic_render(d, 0.0, &rgb, &st);
        wall[i] = hl_tools_now() - t0;
        if (r == HL_OK && st.reused) r = hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT, "bench-dynamic: a timed frame was reused");
        /* the nudge moves a caster, so every map is made again: a kept
           one would time a frame that skipped the maps and their build */
        if (r == HL_OK && st.maps_kept > w->maps_kept) w->maps_kept = st.maps_kept;
        if (r == HL_OK && st.sharp && st.sharp_res > b->sharp_res) b->sharp_res = st.sharp_res;
        if (r == HL_OK && st.sharp && st.sharp_mode == HL_DYNAMIC_SHARP_RAYS) b->sharp_rays = 1;
        if (r == HL_OK && st.maps_kept)
            r = hl_tools_fail(b->ctx, HL_ERR_INVALID_ARGUMENT, "bench-dynamic: a timed frame kept %u shadow maps",
                              st.maps_kept);
        const double s[7] = {st.t_irradiance, st.t_shadow_maps, st.t_csm_build, st.t_csm_eval,
                             st.t_shading,   st.t_total,      st.t_sharp_rays};
        for (int c = 0; c < 7; c++) t[c][i] = s[c];
    }
    if (r == HL_OK) r = place(b, base, 0.0f);
    if (r == HL_OK) r = hl_dynamic_render(d, 0.0, &rgb, &st);
    if (r != HL_OK) return r;
    memcpy(b->B, rgb, 3 * (size_t)b->V * sizeof(float));
    errors(b->B, b->exact, b->V, &w->l2, &w->mx);
    w->ms = 1e3 * median(wall, b->o.reps);
    for (int c = 0; c < 7; c++) w->stage[c] = 1e3 * median(t[c], b->o.reps);
    return HL_OK;
}

/* The exact reference at the current place under map e, on the first
 * dynamic scene after a frame there (the reference takes the bodies of
 * the last frame). */
static hl_result exact_here(bd *b, int e)
{
    float *rgb = NULL;
    double s = 0;
    hl_result r = hl_dynamic_set_env(b->dyn[0], b->envs[e].env, (int32_t)b->o.K[0], 0.0f, 0.0f, NULL);
    if (r == HL_OK) r = hl_dynamic_render(b->dyn[0], 0.0, &rgb, NULL);
    if (r == HL_OK) r = hl_bench_dyn_exact(b->dyn[0], b->envs[e].env, b->exact, &s);
    if (e == 0 && b->ref_seconds == 0) b->ref_seconds = s;
    return r;
}

/* Whether setting k is the first with its K (the K-lights reference and
 * the traced rows are made once per K). */
static int first_of_K(const bd *b, uint32_t k)
{
    for (uint32_t i = 0; i < k; i++)
        if (b->o.K[i] == b->o.K[k]) return 0;
    return 1;
}

static uint32_t index_of_K(const bd *b, uint32_t K)
{
    uint32_t i = 0;
    while (b->o.K[i] != K) i++;
    return i;
}

/* Moved, per distinct K: the K-lights reference and the traced rows. */
static hl_result traced_rows(bd *b, int e, uint32_t k)
{
    hl_dynamic *d = b->dyn[0];
    float *rgb = NULL;
    const uint32_t K = b->o.K[k];
    hl_result r = hl_dynamic_set_env(d, b->envs[e].env, (int32_t)K, 0.0f, 0.0f, NULL);
    if (r == HL_OK) r = hl_dynamic_render(d, 0.0, &rgb, NULL);
    double s = 0;
    if (r == HL_OK) r = hl_bench_dyn_lights(d, b->lights[k], &s);
    if (r != HL_OK) return r;
    bd_row *w = new_row(b, e, 1, BD_LIGHTS, K, 0, 0);
    errors(b->lights[k], b->exact, b->V, &w->l2, &w->mx);
    w->l2_lights = 0.0;
    w->ms = 1e3 * s;
    for (uint32_t si = 0; si < b->o.nS && r == HL_OK; si++) {
        double t[5][BD_MAX_REPS];
        hl_bench_traced_times tt = {0};
        for (uint32_t i = 0; i < b->o.treps && r == HL_OK; i++) {
            r = hl_bench_dyn_traced(d, b->o.S[si], b->B, &tt);
            const double v[5] = {tt.t_build, tt.t_rays, tt.t_trace, tt.t_shade, tt.seconds};
            for (int c = 0; c < 5; c++) t[c][i] = v[c];
        }
        if (r != HL_OK) break;
        w = new_row(b, e, 1, BD_TRACED, K, 0, b->o.S[si]);
        errors(b->B, b->exact, b->V, &w->l2, &w->mx);
        double dummy;
        errors(b->B, b->lights[k], b->V, &w->l2_lights, &dummy);
        for (int c = 0; c < 4; c++) w->stage[c] = 1e3 * median(t[c], b->o.treps);
        w->ms = 1e3 * median(t[4], b->o.treps);
        fprintf(stderr, "bench-dynamic:   traced K %u S %u: %.2f%% in %.1f ms\n", K, b->o.S[si], 100 * w->l2, w->ms);
    }
    return r;
}

/* Everything under map e: at rest (exact, PRT, dynamic), then moved
 * (exact, per K the K-lights reference and the traced method, dynamic). */
static hl_result bench_env_all(bd *b, int e)
{
    const bench_env *en = &b->envs[e];
    const float rest[3] = {0, 0, 0};
    fprintf(stderr, "bench-dynamic: %s at rest: exact reference\n", en->name);
    hl_result r = place(b, rest, 0.0f);
    if (r == HL_OK) r = exact_here(b, e);
    if (r == HL_OK) fprintf(stderr, "bench-dynamic: %s at rest: PRT\n", en->name);
    if (r == HL_OK) r = prt_rows(b, e);
    for (uint32_t k = 0; k < b->o.nset && r == HL_OK; k++) {
        bd_row *w = new_row(b, e, 0, BD_DYNAMIC, b->o.K[k], b->o.M[k], 0);
        r = dyn_frame(b, k, w);
        if (r == HL_OK) fprintf(stderr, "bench-dynamic:   dynamic K %u %s%.0u: %.2f%% in %.1f ms\n", w->K, w->M ? "M " : "moments", w->M, 100 * w->l2, w->ms);
    }
    /* moved: lifted and pushed sideways, by the object's own size */
    const hl_mesh *m = hl_dynamic_mesh(b->dyn[0]);
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; r == HL_OK && i < m->object_vertex_count; i++)
        for (int c = 0; c < 3; c++) lo[c] = fminf(lo[c], m->positions[3 * i + c]), hi[c] = fmaxf(hi[c], m->positions[3 * i + c]);
    float *moved = b->moved;
    moved[0] = (float)(BD_SIDEWAYS * (hi[0] - lo[0])), moved[1] = (float)(BD_LIFT * (hi[1] - lo[1])), moved[2] = 0.0f;
    if (r == HL_OK) fprintf(stderr, "bench-dynamic: %s moved by (%.3g, %.3g, 0): exact reference\n", en->name, moved[0], moved[1]);
    if (r == HL_OK) r = place(b, moved, 0.0f);
    if (r == HL_OK) r = exact_here(b, e);
    for (uint32_t k = 0; k < b->o.nset && r == HL_OK; k++)
        if (first_of_K(b, k)) r = traced_rows(b, e, k);
    for (uint32_t k = 0; k < b->o.nset && r == HL_OK; k++) {
        bd_row *w = new_row(b, e, 1, BD_DYNAMIC, b->o.K[k], b->o.M[k], 0);
        r = dyn_frame(b, k, w);
        double dummy;
        if (r == HL_OK) errors(b->B, b->lights[index_of_K(b, w->K)], b->V, &w->l2_lights, &dummy);
        if (r == HL_OK) fprintf(stderr, "bench-dynamic:   moved dynamic K %u %s%.0u: %.2f%% in %.1f ms\n", w->K, w->M ? "M " : "moments", w->M, 100 * w->l2, w->ms);
    }
    if (r == HL_OK) r = place(b, rest, 0.0f);
    return r;
}

/* ---------------------------------------------------------------- the command */

static void bd_free(bd *b)
{
    for (int e = 0; e < b->o.nenvs; e++) hl_env_destroy(b->envs[e].env);
    for (uint32_t k = 0; k < b->ndyn; k++) hl_dynamic_destroy(b->dyn[k]);
    for (uint32_t k = 0; k < BD_MAX_SETTINGS; k++) free(b->lights[k]);
    free(b->exact);
    free(b->B);
    hl_relighter_destroy(b->rl);
    hl_transport_destroy(b->t);
    cli_unwatch();
    hl_context_destroy(b->ctx);
    free(b);
}

/* The host's 1, 5 and 15 minute load averages (other work on the same
 * cores slows every timing), or "unknown". */
static void load_average(char *buf, size_t n)
{
    FILE *f = fopen("/proc/loadavg", "r");
    double a[3];
    if (f && fscanf(f, "%lf %lf %lf", &a[0], &a[1], &a[2]) == 3) snprintf(buf, n, "%.2f, %.2f, %.2f", a[0], a[1], a[2]);
    else snprintf(buf, n, "unknown");
    if (f) fclose(f);
}

/* Opens the three files under their temporary names. */
static hl_result open_outs(bd *b)
{
    bench_out_names(&b->out, b->o.outdir);
    for (int k = 0; k < BENCH_OUTS; k++)
        if (!(b->out.f[k] = fopen(b->out.tmp[k], "w")))
            return hl_tools_fail(b->ctx, HL_ERR_IO, "%s: cannot write: %s", b->out.tmp[k], strerror(errno));
    return HL_OK;
}

static hl_result bd_measure(bd *b)
{
    char load0[48], load1[48];
    load_average(load0, sizeof load0);
    hl_result r = open_outs(b);
    for (int e = 0; e < b->o.nenvs && r == HL_OK; e++) r = bench_env_all(b, e);
    if (r == HL_OK) {
        const hl_mesh *m = b->t->mesh;
        bd_report rep = {.envs = b->envs, .nenvs = b->o.nenvs, .rows = b->rows, .nrows = b->nrows,
                         .scene = bench_base_name(b->o.file), .device = hl_context_device_name(b->ctx),
                         .vertices = m->vertex_count, .object_vertices = m->object_vertex_count, .R = b->o.R, .Rs = b->sharp_res, .sharp_rays = b->sharp_rays,
                         .reps = b->o.reps, .traced_reps = b->o.treps, .goal_K = b->o.K[b->goal],
                         .goal_M = b->o.M[b->goal], .ref_seconds = b->ref_seconds,
                         .move = {b->moved[0], b->moved[1], b->moved[2]}};
        load_average(load1, sizeof load1);
        memcpy(rep.load[0], load0, sizeof load0);
        memcpy(rep.load[1], load1, sizeof load1);
        bench_dyn_write(&b->out, &rep);
    }
    return r;
}

int cmd_bench_dynamic(int argc, char **argv)
{
    bd *b = calloc(1, sizeof *b);
    if (!b) {
        fprintf(stderr, "haarlight: out of memory\n");
        return 1;
    }
    int u = parse_bd(argc, argv, b);
    if (u >= 0) {
        free(b);
        return u;
    }
    if (!cli_make_dir(b->o.outdir)) {
        free(b);
        return 1;
    }
    char err[4096];
    if (hl_context_create(&b->o.cd, &b->ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        free(b);
        return 1;
    }
    cli_watch(b->ctx, b->ctx);
    hl_result r = load(b);
    int rc = r != HL_OK ? cli_fail(b->ctx, r) : bench_out_finish(&b->out, bd_measure(b), b->ctx, b->ctx);
    bd_free(b);
    return rc;
}
