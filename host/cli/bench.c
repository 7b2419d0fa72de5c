/* bench.c - `haarlight bench`: error against run time.
 *
 * For every transport file, environment, selection scheme and number of
 * lighting terms M: the relative L2 and maximum error of the vertex colours
 * against two references, the median time of a full lighting change on the
 * OpenCL device and on the reference, and the transport's size. At M = 200
 * under the first environment, a speed summary per file: changes per
 * second, and the dot products alone against the device's read bandwidth,
 * measured in alternating rounds; and at M = all, subnormal lighting's time
 * against normal lighting's, on both backends. The
 * references, on a fixed subset of vertices spread over the mesh:
 *   exact:      untruncated, unquantised transport (recomputed here from
 *               the rays) dotted with untruncated lighting, in float64;
 *   continuous: the original equirectangular map integrated directly,
 *               one Embree ray per map pixel, cast from the vertex itself
 *               with its own triangles skipped (no ray offset);
 *               independent of N and C and of the precompute's offset;
 * and for a file with bounces (precompute --bounces B) the exact reference
 * becomes the bounced one: the direct exact light of every vertex, then B
 * gathers in float64 with each channel's albedo on rays of its own
 * (--bounce-rays; hl_bench_ref_bounced), the continuous reference and
 * banding not measured for it (they are direct light only).
 * Writes bench.md, bench.csv and bench.svg (gnuplot) to the output folder.
 *
 * This file holds the options and the measuring phases; the references
 * and the device probes are the library's (haarlight_tools.h), and the
 * files are written by bench_out.c.
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

static const char *const usage_bench =
    "usage: haarlight bench SCENE.hlt [SCENE2.hlt ...] [--env ENV.exr ...] [--sky] [options]\n"
    "\n"
    "Error against run time. For each file, environment, selection scheme and M,\n"
    "reports the error against the exact discrete result (untruncated, unquantised\n"
    "transport and lighting, float64) and against a converged continuous result\n"
    "(the map integrated directly with Embree visibility), and the median time of\n"
    "a full lighting change (environment to paraboloid, Haar, selection, dot\n"
    "products, the colours readable on the host as the viewer takes them) on the\n"
    "OpenCL device and on the reference (the latter under the first environment:\n"
    "its time does not depend on the map). All files must come from the same\n"
    "mesh, N, C and albedo (e.g. different --quant, --energy or --bounces). A file\n"
    "with bounces is measured against the exact reference with the same bounces\n"
    "(see --bounce-rays); bench.md and bench.csv say which reference each file has.\n"
    "At M = 200 under the first environment it also gives each file's lighting\n"
    "changes per second, the time of taking a new map (resampling it onto the cell\n"
    "grid and uploading it), and the dot products' time against the device's read\n"
    "bandwidth (7 rounds of each, alternating; the fraction pairs each round's two),\n"
    "and the time of a change at M = all under the first map made subnormal against it.\n"
    "\n"
    "  --layout L           how the --env maps are laid out: auto (by size), equirect,\n"
    "                       angular, cross-h or cross-v\n"
    "  --env ENV.exr        an environment, OpenEXR or .hdr (repeat for more); --sky adds\n"
    "                       the procedural sky\n"
    "  -o, --output DIR     where bench.md, bench.csv, bench.gp and bench.svg go (default\n"
    "                       bench-out; each is written whole or not at all)\n"
    "  --terms LIST         M values, comma-separated (default 25,50,100,200,500,1000,2000,all)\n"
    "  --select LIST        transport,area,unweighted (default all three; the plot shows\n"
    "                       the first)\n"
    "  --vertices K         vertices for the exact reference (default 1024; all if fewer)\n"
    "  --continuous K       vertices for the continuous reference (default 96)\n"
    "  --bounce-rays K      for a file with bounces (precompute --bounces B): rays a vertex\n"
    "                       of each bounce of its exact reference (default 1024; must be 4\n"
    "                       or more). That reference is the direct exact light of every\n"
    "                       vertex, then B gathers in float64 with each channel's own\n"
    "                       albedo, on rays of its own (about a precompute's direct rays\n"
    "                       for the first part, K rays a vertex a bounce for the rest);\n"
    "                       bench.md gives its own noise. The continuous reference and\n"
    "                       banding are direct light only: not measured for such a file,\n"
    "                       and --image refuses it\n"
    "  --reps R             timed lighting changes per setting on OpenCL (default 15)\n"
    "  --ref-reps R         timed lighting changes per setting on the reference (default 3)\n"
    "  --no-ref-timing      skip timing the plain-C reference\n"
    "  --no-banding         skip the banding measure (it casts the rays of every ground\n"
    "                       vertex once)\n"
    "  --image              also errors in image space: each setting's picture from the\n"
    "                       default camera against the picture of every vertex's exact\n"
    "                       colours (relative L2 and Sobolev H1), and the popping under\n"
    "                       the first map turning one pixel column a frame (computes the\n"
    "                       exact transport of every vertex: about a precompute's rays)\n"
    "  --image-frames F     frames of the turning map (default 16; 1: no popping measure)\n"
    "  --image-size WxH     the pictures' size (default 320x240)\n"
    "  --surroundings FILE  also time lighting captured from these surroundings (a mesh\n"
    "                       file whose emissive materials give light): changes per second\n"
    "                       at M = 200 with every body turned a further half degree about\n"
    "                       +Y each time (a new capture each change), an unchanged frame,\n"
    "                       and the capture alone against the dot products alone\n"
    "  --probes N           with --surroundings: up to N capture points, as relight's\n"
    "                       --probes (each change then captures and relights once a point)\n"
    CLI_USAGE_SURROUNDINGS_TRANSFORM
    "  --device cl:P:D      OpenCL device (default: the first, or HL_OPENCL_DEVICE=P:D;\n"
    "                       HL_DEVICE_SHAPE=cpu|gpu forces the kernels' shape)\n"
    "  --device-memory SIZE most device memory to use, e.g. 512M (default: the device's;\n"
    "                       also HL_DEVICE_MEMORY)\n";

#define MAX_REF_REPS 100
#define MAX_REPS 1000

typedef struct bench_opts {
    const char *files[BENCH_MAX_FILES], *outdir;
    int nfiles, nenvs, want_sky, ref_timing, banding_on;
    uint32_t terms[BENCH_MAX_TERMS], nterms, selects[3], nsel;
    uint32_t K, K2, reps, ref_reps, bounce_rays;
    const char *surroundings;
    uint32_t probes;
    float place[5];
    int place_set;
    int image;
    uint32_t image_frames, image_w, image_h;
    hl_context_desc cd;
    hl_env_layout layout;
} bench_opts;

/* Everything one run holds. */
typedef struct bench {
    bench_opts o;
    bench_env envs[BENCH_MAX_ENVS];
    hl_context *cl, *ref;
    hl_transport *t[BENCH_MAX_FILES];
    hl_bench_ref *br;
    uint32_t V, K, K2, gside;
    uint32_t *idx, *idx2;
    float *B, *Braw;
    bench_out out;
    int nseries;
    double ref_ms[BENCH_MAX_FILES][3][BENCH_MAX_TERMS];
    bench_speed speed[BENCH_MAX_FILES];
    hl_surroundings *sur;
} bench;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double bench_median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n ? v[n / 2] : 0.0;
}
#define median bench_median

/* ---------------------------------------------------------------- options */

/* --terms and --select: comma-separated lists. Return 0 when fine, else
 * the usage error's exit code. */
static int parse_terms(const char *usage, const char *v, bench_opts *o)
{
    o->nterms = 0;
    char buf[512];
    snprintf(buf, sizeof buf, "%s", v);
    for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
        if (o->nterms == BENCH_MAX_TERMS) return usage_error(usage, "%s", "at most 16 values of M");
        if (!strcmp(tok, "all")) o->terms[o->nterms++] = HL_TERMS_ALL;
        else if (!parse_u32(tok, &o->terms[o->nterms]) || o->terms[o->nterms] < 1) return usage_error(usage, "--terms: bad value %s", tok);
        else o->nterms++;
    }
    if (!o->nterms) return usage_error(usage, "--terms %s: no values", v);
    return 0;
}

static int parse_selects(const char *usage, const char *v, bench_opts *o)
{
    o->nsel = 0;
    char buf[256];
    snprintf(buf, sizeof buf, "%s", v);
    for (char *tok = strtok(buf, ","); tok && o->nsel < 3; tok = strtok(NULL, ",")) {
        if (!parse_select(tok, &o->selects[o->nsel++])) return usage_error(usage, "--select: unknown scheme %s", tok);
    }
    if (!o->nsel) return usage_error(usage, "--select %s: no values", v);
    return 0;
}

/* Options; returns -1 to go on, else the exit code. */
static int parse_bench(int argc, char **argv, bench *b)
{
    const char *usage = usage_bench;
    bench_opts *o = &b->o;
    *o = (bench_opts){.outdir = "bench-out", .ref_timing = 1, .banding_on = 1,
                      .terms = {25, 50, 100, 200, 500, 1000, 2000, HL_TERMS_ALL}, .nterms = 8,
                      .selects = {HL_SELECT_TRANSPORT, HL_SELECT_AREA, HL_SELECT_UNWEIGHTED}, .nsel = 3,
                      .K = 1024, .K2 = 96, .reps = 15, .ref_reps = 3, .bounce_rays = 1024,
                      .image_frames = 16, .image_w = 320, .image_h = 240,
                      .cd = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .quiet = 1}};
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
        int e = 0;
#define NEED() do { if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a); v = argv[++i]; } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage, stdout); return 0; }
        else if (!strcmp(a, "--layout")) { NEED(); if (!parse_layout(v, &o->layout)) return usage_error(usage, "--layout %s: expected auto, equirect, angular, cross-h or cross-v", v); }
        else if (!strcmp(a, "--env")) {
            NEED();
            if (o->nenvs == BENCH_MAX_ENVS) return usage_error(usage, "%s", "at most 16 environments");
            b->envs[o->nenvs].path = v;
            b->envs[o->nenvs++].name = bench_base_name(v);
        } else if (!strcmp(a, "--sky")) o->want_sky = 1;
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED(); o->outdir = v; }
        else if (!strcmp(a, "--terms")) { NEED(); if ((e = parse_terms(usage, v, o))) return e; }
        else if (!strcmp(a, "--select")) { NEED(); if ((e = parse_selects(usage, v, o))) return e; }
        else if (!strcmp(a, "--vertices")) { NEED(); if (!parse_u32(v, &o->K) || o->K < 1 || o->K > 65536) return usage_error(usage, "--vertices %s: expected 1 to 65536", v); }
        else if (!strcmp(a, "--bounce-rays")) { NEED(); if (!parse_u32(v, &o->bounce_rays) || o->bounce_rays < 4 || o->bounce_rays > 1048576) return usage_error(usage, "--bounce-rays %s: expected 4 to 1048576 rays a vertex", v); }
        else if (!strcmp(a, "--continuous")) { NEED(); if (!parse_u32(v, &o->K2) || o->K2 > 4096) return usage_error(usage, "--continuous %s: expected 0 to 4096", v); }
        else if (!strcmp(a, "--reps")) { NEED(); if (!parse_u32(v, &o->reps) || o->reps < 1 || o->reps > MAX_REPS) return usage_error(usage, "--reps %s: expected 1 to 1000", v); }
        else if (!strcmp(a, "--ref-reps")) { NEED(); if (!parse_u32(v, &o->ref_reps) || o->ref_reps < 1 || o->ref_reps > MAX_REF_REPS) return usage_error(usage, "--ref-reps %s: expected 1 to 100", v); }
        else if (!strcmp(a, "--no-ref-timing")) o->ref_timing = 0;
        else if (!strcmp(a, "--no-banding")) o->banding_on = 0;
        else if (!strcmp(a, "--surroundings")) { NEED(); o->surroundings = v; }
        else if (!strcmp(a, "--surroundings-transform")) { NEED(); if (!cli_parse_placement(usage, v, o->place)) return 2; o->place_set = 1; }
        else if (!strcmp(a, "--probes")) { NEED(); if (!parse_u32(v, &o->probes) || o->probes < 1 || o->probes > 256) return usage_error(usage, "--probes %s: expected a whole number of capture points from 1 to 256", v); }
        else if (!strcmp(a, "--image")) o->image = 1;
        else if (!strcmp(a, "--image-frames")) { NEED(); if (!parse_u32(v, &o->image_frames) || o->image_frames < 1 || o->image_frames > 256) return usage_error(usage, "--image-frames %s: expected 1 to 256", v); }
        else if (!strcmp(a, "--image-size")) { NEED(); if (!cli_parse_size(v, &o->image_w, &o->image_h) || o->image_w < 8 || o->image_h < 8 || o->image_w > 4096 || o->image_h > 4096) return usage_error(usage, "--image-size %s: expected WxH, 8 to 4096 each", v); }
        else if (!strcmp(a, "--device-memory")) {
            NEED();
            if (!parse_device_memory(v, &o->cd)) return usage_error(usage, "--device-memory %s: expected a byte count such as 512M or 2G", v);
        } else if (!strcmp(a, "--device")) {
            NEED();
            if (!parse_device(v, &o->cd) || o->cd.backend != HL_BACKEND_OPENCL) return usage_error(usage, "--device %s: expected cl or cl:PLATFORM:DEVICE", v);
        } else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (o->nfiles == BENCH_MAX_FILES) return usage_error(usage, "%s", "at most 8 transport files");
        else o->files[o->nfiles++] = a;
#undef NEED
    }
    if (!o->nfiles) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (o->place_set && !o->surroundings) return usage_error(usage, "%s", "--surroundings-transform needs --surroundings");
    if (o->probes && !o->surroundings) return usage_error(usage, "%s", "--probes needs --surroundings");
    if (o->want_sky || o->nenvs == 0) {
        if (o->nenvs == BENCH_MAX_ENVS) return usage_error(usage, "%s", "at most 16 environments");
        b->envs[o->nenvs].name = "sky";
        b->envs[o->nenvs++].path = NULL;
    }
    return -1;
}

/* ---------------------------------------------------------------- references */

/* The transport files (one mesh, N and C), the environments and the
 * references' tables. */
static hl_result load(bench *b)
{
    const bench_opts *o = &b->o;
    hl_result r = HL_OK;
    for (int f = 0; f < o->nfiles && r == HL_OK; f++) {
        r = hl_transport_load(b->ref, o->files[f], &b->t[f]);
        const hl_transport *t0 = b->t[0], *tf = b->t[f];
        if (r == HL_OK && f > 0 &&
            (tf->info.N != t0->info.N || tf->info.C != t0->info.C || tf->info.vertex_count != t0->info.vertex_count ||
             memcmp(tf->mesh->positions, t0->mesh->positions, (size_t)t0->info.vertex_count * 12) != 0))
            r = hl_tools_fail(b->ref, HL_ERR_INVALID_ARGUMENT, "%s: not the same mesh, N and C as %s", o->files[f], o->files[0]);
        /* the exact colours are the first file's albedo times its rows
           (and its bounces): another albedo would be measured against
           the wrong colours */
        if (r == HL_OK && f > 0 && memcmp(tf->mesh->albedo, t0->mesh->albedo, (size_t)t0->info.vertex_count * 12) != 0)
            r = hl_tools_fail(b->ref, HL_ERR_INVALID_ARGUMENT, "%s: not the same albedo as %s (bench them in separate runs)",
                              o->files[f], o->files[0]);
        if (r == HL_OK && o->image && b->t[f]->info.bounces)
            r = hl_tools_fail(b->ref, HL_ERR_INVALID_ARGUMENT,
                              "--image: %s has %u bounces, and the image errors have a direct-light reference only", o->files[f],
                              b->t[f]->info.bounces);
    }
    for (int e = 0; e < o->nenvs && r == HL_OK; e++) {
        hl_sky_desc sky = {0};
        bench_env *en = &b->envs[e];
        r = en->path ? cli_env_load(b->ref, en->path, b->o.layout, &en->env, 0) : hl_env_create_sky(b->ref, &sky, &en->env);
    }
    if (r == HL_OK) r = hl_bench_ref_create(b->ref, b->t[0], &b->br);
    if (r == HL_OK && o->surroundings) r = hl_surroundings_load(b->ref, o->surroundings, &b->sur);
    if (r == HL_OK && o->surroundings && o->place_set) r = hl_surroundings_set_placement(b->sur, o->place, o->place[3], o->place[4]);
    return r;
}

/* The side of the ground grid (hl_mesh_add_ground: (res + 1)^2 vertices
 * after the object's, row-major), or 0 when there is none to measure. */
static uint32_t ground_side(const hl_transport_info *in)
{
    const uint32_t G = in->vertex_count - in->object_vertex_count;
    uint32_t n = (uint32_t)sqrt((double)G);
    while ((uint64_t)n * n > G) n--;
    while ((uint64_t)(n + 1) * (n + 1) <= G) n++;
    return (uint64_t)n * n == G && n >= 3 ? n : 0;
}

/* The bounced exact reference of the sampled vertices, for every bounce
 * count up to the files' largest (one run of hl_bench_ref_bounced gives
 * them all), kept for the counts some file has. */
static hl_result bounced_references(bench *b)
{
    uint32_t Bmax = 0, K = b->K;
    for (int f = 0; f < b->o.nfiles; f++)
        if (b->t[f]->info.bounces > Bmax) Bmax = b->t[f]->info.bounces;
    if (!Bmax) {
        if (b->o.bounce_rays != 1024)
            fprintf(stderr, "bench: --bounce-rays: no file has bounces, so its reference is direct light only\n");
        return HL_OK;
    }
    const int nenvs = b->o.nenvs;
    if (Bmax > HL_MAX_BOUNCES)
        return hl_tools_fail(b->ref, HL_ERR_INVALID_ARGUMENT, "a file with %u bounces (at most %u)", Bmax, HL_MAX_BOUNCES);
    fprintf(stderr, "bench: bounced exact reference: %u bounces, %u rays a vertex a bounce, direct light of all %u vertices first\n",
            Bmax, b->o.bounce_rays, b->V);
    double **out = calloc((size_t)(Bmax + 1) * nenvs, sizeof *out);
    double *own = calloc((size_t)(Bmax + 1) * nenvs, sizeof *own), *bound = calloc((size_t)(Bmax + 1) * nenvs, sizeof *bound);
    hl_result r = out && own && bound ? HL_OK : hl_tools_fail(b->ref, HL_ERR_OUT_OF_MEMORY, "out of memory");
    for (size_t i = 0; i < (size_t)(Bmax + 1) * nenvs && r == HL_OK; i++)
        if (!(out[i] = calloc((size_t)K * 3, sizeof(double))))
            r = hl_tools_fail(b->ref, HL_ERR_OUT_OF_MEMORY, "out of memory for the bounced reference");
    const hl_env *envs[BENCH_MAX_ENVS];
    for (int e = 0; e < nenvs; e++) envs[e] = b->envs[e].env;
    const double t0 = hl_tools_now();
    if (r == HL_OK) r = hl_bench_ref_bounced(b->br, b->idx, K, Bmax, b->o.bounce_rays, envs, nenvs, 1, out, own, bound);
    if (r == HL_OK) fprintf(stderr, "bench: bounced exact reference: %.1f s\n", hl_tools_now() - t0);
    for (uint32_t B = 1; B <= Bmax && r == HL_OK; B++) {
        int wanted = 0;
        for (int f = 0; f < b->o.nfiles; f++) wanted |= b->t[f]->info.bounces == B;
        for (int e = 0; e < nenvs && wanted; e++) {
            bench_env *en = &b->envs[e];
            en->exact_b[B] = out[(size_t)B * nenvs + e];
            out[(size_t)B * nenvs + e] = NULL;
            en->noise_own[B] = own[(size_t)B * nenvs + e];
            en->noise_bound[B] = bound[(size_t)B * nenvs + e];
            fprintf(stderr, "bench: bounced reference after %u bounce%s under %s: its own noise %.3f%% (bound %.3f%%) of its L2\n",
                    B, B == 1 ? "" : "s", en->name, 100 * en->noise_own[B], 100 * en->noise_bound[B]);
        }
    }
    for (size_t i = 0; out && i < (size_t)(Bmax + 1) * nenvs; i++) free(out[i]);
    free(out);
    free(own);
    free(bound);
    return r;
}

/* The exact and continuous colours of the sampled vertices under every
 * environment, the exact colours of the ground for banding, and the
 * bounced references. */
static hl_result references(bench *b)
{
    const hl_transport_info *in = &b->t[0]->info;
    const int nenvs = b->o.nenvs;
    b->V = in->vertex_count;
    b->K = b->o.K > b->V ? b->V : b->o.K;
    b->K2 = b->o.K2 > b->K ? b->K : b->o.K2;
    const uint32_t V = b->V, K = b->K, K2 = b->K2;
    b->idx = malloc((size_t)K * 4);
    b->idx2 = malloc((size_t)(K2 ? K2 : 1) * 4);
    if (!b->idx || !b->idx2) return hl_tools_fail(b->ref, HL_ERR_OUT_OF_MEMORY, "out of memory");
    for (uint32_t k = 0; k < K; k++) b->idx[k] = (uint32_t)((uint64_t)k * V / K);
    for (uint32_t k = 0; k < K2; k++) b->idx2[k] = b->idx[(uint64_t)k * K / K2];
    fprintf(stderr, "bench: exact transport of %u vertices, continuous reference on %u\n", K, K2);
    const hl_env *envs[BENCH_MAX_ENVS];
    double *exact[BENCH_MAX_ENVS], *cont[BENCH_MAX_ENVS];
    for (int e = 0; e < nenvs; e++) {
        envs[e] = b->envs[e].env;
        exact[e] = b->envs[e].exact = calloc((size_t)K * 3, sizeof(double));
        cont[e] = b->envs[e].cont = calloc((size_t)(K2 ? K2 : 1) * 3, sizeof(double));
        if (!exact[e] || !cont[e]) return hl_tools_fail(b->ref, HL_ERR_OUT_OF_MEMORY, "out of memory for the references");
    }
    hl_result r = hl_bench_ref_colours(b->br, b->idx, K, b->idx2, K2, envs, nenvs, exact, cont);
    b->gside = b->o.banding_on ? ground_side(in) : 0;
    if (r == HL_OK && b->gside) {
        fprintf(stderr, "bench: exact colours of the %u x %u ground, for banding\n", b->gside, b->gside);
        double *ground[BENCH_MAX_ENVS] = {0};
        r = hl_bench_ref_ground(b->br, ground);
        for (int e = 0; e < nenvs; e++) b->envs[e].ground = ground[e];
    }
    if (r == HL_OK) r = bounced_references(b);
    return r;
}

/* ---------------------------------------------------------------- errors */

/* Relative L2 and max error of B (3 per vertex, picked by idx) against ref. */
static void errors(const float *B, const uint32_t *idx, uint32_t n, const double *ref, double *l2, double *mx)
{
    double se = 0.0, sr = 0.0, me = 0.0, mr = 0.0;
    for (uint32_t k = 0; k < n; k++)
        for (int c = 0; c < 3; c++) {
            double d = (double)B[3 * (size_t)idx[k] + c] - ref[3 * k + c];
            se += d * d;
            sr += ref[3 * k + c] * ref[3 * k + c];
            me = fmax(me, fabs(d));
            mr = fmax(mr, fabs(ref[3 * k + c]));
        }
    *l2 = sr > 0 ? sqrt(se / sr) : sqrt(se);
    *mx = mr > 0 ? me / mr : me;
}

/* Banding: contour bands are steps of the error that run on for many
 * grid cells, so the measure is the RMS of the 5-point Laplacian of the
 * ground's luminance error after a 5 x 5 box average (which leaves such
 * steps and takes out noise from cell to cell, which the eye forgives),
 * over the RMS of the exact luminance, on the grid points at least three
 * cells from the edge. A smooth error (a little too bright everywhere)
 * adds almost nothing. */
#define BAND_R 2
static double banding(const float *B, uint32_t first, uint32_t n, const double *exact)
{
    if (n < 2 * BAND_R + 3) return NAN;
    double *err = malloc((size_t)n * n * sizeof *err), *avg = malloc((size_t)n * n * sizeof *avg);
    if (!err || !avg) {
        free(err);
        free(avg);
        return NAN;
    }
    for (size_t g = 0; g < (size_t)n * n; g++) {
        const float *b = B + 3 * ((size_t)first + g);
        const double *x = exact + 3 * g;
        err[g] = hl_tools_luminance(b[0], b[1], b[2]) - (0.2126 * x[0] + 0.7152 * x[1] + 0.0722 * x[2]);
    }
    for (uint32_t j = BAND_R; j + BAND_R < n; j++)
        for (uint32_t i = BAND_R; i + BAND_R < n; i++) {
            double sum = 0.0;
            for (int dj = -BAND_R; dj <= BAND_R; dj++)
                for (int di = -BAND_R; di <= BAND_R; di++) sum += err[(size_t)(j + dj) * n + (i + di)];
            avg[(size_t)j * n + i] = sum / ((2 * BAND_R + 1) * (2 * BAND_R + 1));
        }
    double se = 0.0, sr = 0.0;
    for (uint32_t j = BAND_R + 1; j + BAND_R + 1 < n; j++)
        for (uint32_t i = BAND_R + 1; i + BAND_R + 1 < n; i++) {
            const size_t g = (size_t)j * n + i;
            const double lap = avg[g - 1] + avg[g + 1] + avg[g - n] + avg[g + n] - 4.0 * avg[g];
            const double *x = exact + 3 * g, y = 0.2126 * x[0] + 0.7152 * x[1] + 0.0722 * x[2];
            se += lap * lap;
            sr += y * y;
        }
    free(err);
    free(avg);
    return sr > 0 ? sqrt(se / sr) : NAN;
}

/* ---------------------------------------------------------------- measuring */

/* The relighters of one file: OpenCL, and the reference when timed. */
typedef struct file_relighters {
    int f;
    hl_relighter *rc, *rr;
    double bytes; /* the transport's size */
} file_relighters;

/* The median time of reps lighting changes at d's settings, a new
 * rotation each time (so each is a new lighting): change k turns the map
 * by base_deg + 1e-3 (k + k0) degrees. A change ends with the colours
 * readable on the host as the viewer takes them (hl_view_run4: 4 floats a
 * vertex, mapped where the device's memory is the host's), not copied
 * into 3 floats a vertex, which on the 2M vertex terrain adds 4 to 5 ms
 * (docs/SCALE.md). */
static hl_result time_changes(hl_relighter *rl, hl_relight_desc d, uint32_t reps, float base_deg, uint32_t k0,
                              double *median_s)
{
    double times[MAX_REPS];
    hl_relight_stats st;
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < reps && r == HL_OK; k++) {
        const float *rgba = NULL;
        d.rotate_deg = base_deg + 1e-3f * (float)(k + k0);
        r = hl_view_run4(rl, &d, &rgba, &st);
        times[k] = st.seconds;
    }
    if (r == HL_OK) *median_s = median(times, (int)reps);
    return r;
}

/* One row of bench.csv and bench.md (and the plot's series): file f under
 * environment e with selection s and M = terms[mi]. */
static hl_result bench_row(bench *b, const file_relighters *fr, int e, uint32_t s, uint32_t mi)
{
    const bench_opts *o = &b->o;
    const int f = fr->f;
    const hl_transport_info *fi = &b->t[f]->info;
    const bench_env *en = &b->envs[e];
    hl_relight_desc d = {.terms = o->terms[mi], .select = o->selects[s]};
    hl_relight_stats st;
    double cl_s = 0.0, ref_s = 0.0;
    hl_result r = time_changes(fr->rc, d, o->reps, 0.0f, 1, &cl_s);
    double cl_ms = 1e3 * cl_s;
    /* the reference's time does not depend on the map: timed on the first */
    if (r == HL_OK && fr->rr && e == 0) {
        r = time_changes(fr->rr, d, o->ref_reps, 0.5f, 0, &ref_s);
        if (r == HL_OK) b->ref_ms[f][s][mi] = 1e3 * ref_s;
    }
    hl_relight_desc raw = d;
    raw.keep_negative = 1;
    if (r == HL_OK) r = hl_relighter_run(fr->rc, &raw, b->Braw, NULL);
    if (r == HL_OK) r = hl_relighter_run(fr->rc, &d, b->B, &st);
    if (r != HL_OK) return r;
    double l2e, mxe, l2u, mxu, l2c = NAN, mxc = NAN;
    /* a bounced file against the reference with its bounces; the
       continuous and banding references are direct light only */
    const uint32_t nb = fi->bounces;
    const double *exact = nb ? en->exact_b[nb] : en->exact;
    errors(b->B, b->idx, b->K, exact, &l2e, &mxe);
    errors(b->Braw, b->idx, b->K, exact, &l2u, &mxu);
    const double band = b->gside && !nb ? banding(b->B, fi->object_vertex_count, b->gside, en->ground) : NAN;
    if (b->K2 && !nb) errors(b->B, b->idx2, b->K2, en->cont, &l2c, &mxc);
    char refname[96];
    bench_ref_name(refname, sizeof refname, nb, o->bounce_rays);
    double rms = fr->rr ? b->ref_ms[f][s][mi] : NAN;
    const char *name = bench_base_name(o->files[f]), *sel = select_name(o->selects[s]);
    char mstr[16];
    if (o->terms[mi] == HL_TERMS_ALL) snprintf(mstr, sizeof mstr, "all");
    else snprintf(mstr, sizeof mstr, "%u", o->terms[mi]);
    FILE *csv = b->out.f[BENCH_CSV], *md = b->out.f[BENCH_MD];
    fprintf(csv, "%s,%s,%.1f,%.0f,%s,%s,%s,%u,%.8f,%.6g,%.4f,%.6g,%.6g,%.6g,%.6g,%.4f,%.2f,%.6g,%.6g,%u,%.6g,\"%s\",%.6g\n",
            name, fi->quant == HL_QUANT_LOG8 ? "log8" : fi->quant == HL_QUANT_SQRT8 ? "sqrt8" : "linear8",
            (double)fi->coefficients_kept / b->V, fr->bytes, en->name, sel, mstr, st.terms_kept, st.energy_kept,
            st.error_bound, st.blocks_skipped, l2e, mxe, l2c, mxc, cl_ms, rms, l2u, mxu, st.negative_vertices, band, refname,
            nb ? en->noise_bound[nb] : 0.0);
    char refcell[32] = "not timed";
    if (fr->rr) snprintf(refcell, sizeof refcell, "%.1f", rms);
    /* a bounced file's continuous and banding cells: no such reference */
    char bandcell[32] = "n/a (bounced)", l2ccell[32] = "n/a (bounced)", mxccell[32] = "n/a (bounced)";
    if (!nb) {
        snprintf(bandcell, sizeof bandcell, "%.4f", band);
        snprintf(l2ccell, sizeof l2ccell, "%.3f%%", 100 * l2c);
        snprintf(mxccell, sizeof mxccell, "%.3f%%", 100 * mxc);
    }
    fprintf(md, "| %s | %s | %s | %s | %u | %.6f | %.3g | %.0f%% | %.3f%% | %.3f%% | %.3f%% | %u | %s | %s | %s | %.3f | %s | %.1f |\n",
            name, en->name, sel, mstr, st.terms_kept, st.energy_kept, st.error_bound, 100 * st.blocks_skipped,
            100 * l2e, 100 * mxe, 100 * l2u, st.negative_vertices, bandcell, l2ccell, mxccell, cl_ms, refcell,
            fr->bytes / 1e6);
    if (o->selects[s] == o->selects[0]) fprintf(b->out.f[BENCH_GP], "%.5f %.6g %s\n", cl_ms, l2e, mstr);
    fflush(csv);
    fflush(md);
    return HL_OK;
}

/* Every selection scheme and M for file fr->f under environment e: one
 * series of the plot. */
static hl_result bench_env_rows(bench *b, const file_relighters *fr, int e)
{
    const bench_opts *o = &b->o;
    fprintf(stderr, "bench: %s under %s\n", bench_base_name(o->files[fr->f]), b->envs[e].name);
    hl_result r = hl_relighter_set_env(fr->rc, b->envs[e].env);
    if (r == HL_OK && fr->rr && e == 0) r = hl_relighter_set_env(fr->rr, b->envs[e].env);
    if (r == HL_OK && fr->f == 0 && e == 0) r = hl_relighter_run(fr->rc, NULL, b->B, NULL); /* PoCL compiles lazily */
    FILE *gp = b->out.f[BENCH_GP];
    fprintf(gp, "$s%d << EOD\n", b->nseries);
    for (uint32_t s = 0; s < o->nsel && r == HL_OK; s++)
        for (uint32_t mi = 0; mi < o->nterms && r == HL_OK; mi++) r = bench_row(b, fr, e, s, mi);
    fprintf(gp, "EOD\n");
    b->nseries++;
    return r;
}

/* The speed summary of one file: a new map, full lighting changes at
 * M = 200 with the default selection under the first environment, then
 * the dot products alone and the read bandwidth in alternating rounds:
 * each fraction pairs two measurements taken a moment apart, so that a
 * slow spell of the machine slows both. */
static hl_result bench_speed_of(bench *b, const file_relighters *fr)
{
    const uint32_t reps = b->o.reps;
    bench_speed *sp = &b->speed[fr->f];
    /* a new map: resampled onto the cell grid on the host and uploaded
       (what a change of map costs before its lighting change) */
    double newmap[BENCH_NEWMAP_REPS];
    const uint32_t nnew = reps < BENCH_NEWMAP_REPS ? reps : BENCH_NEWMAP_REPS;
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < nnew && r == HL_OK; k++) {
        double t0 = hl_tools_now();
        r = hl_relighter_set_env(fr->rc, b->envs[0].env);
        newmap[k] = hl_tools_now() - t0;
    }
    sp->newmap = r == HL_OK ? median(newmap, (int)nnew) : 0.0;
    hl_relight_desc d = {.terms = 200, .select = HL_SELECT_DEFAULT, .rotate_deg = 0.25f};
    double change = 0.0;
    if (r == HL_OK) r = time_changes(fr->rc, d, reps, 0.25f, 0, &change);
    sp->rate = r == HL_OK ? 1.0 / change : 0.0;
    double dots[BENCH_ROUNDS], bws[BENCH_ROUNDS], frac[BENCH_ROUNDS];
    sp->bytes = 0.0;
    if (r == HL_OK) r = hl_bench_bytes_read(fr->rc, &sp->bytes);
    for (int k = 0; k < BENCH_ROUNDS && r == HL_OK; k++) {
        r = hl_bench_read_bandwidth(b->cl, (size_t)256 << 20, 3, &bws[k]);
        if (r == HL_OK) r = hl_bench_time_dots(fr->rc, 20, &dots[k]);
        frac[k] = r == HL_OK && dots[k] > 0 && bws[k] > 0 ? sp->bytes / dots[k] / bws[k] : 0.0;
    }
    if (r == HL_OK) {
        sp->dot = median(dots, BENCH_ROUNDS);
        sp->bw = median(bws, BENCH_ROUNDS);
        sp->frac[0] = median(frac, BENCH_ROUNDS); /* sorts */
        sp->frac[1] = frac[0];
        sp->frac[2] = frac[BENCH_ROUNDS - 1];
    }
    return r;
}

/* Subnormal lighting against normal lighting: the median time of taking
 * a new map and relighting at M = all, under map and under map scaled so
 * that its brightest channel is 1e-38 (every pixel subnormal in float, or
 * zero), the two alternating, with a new rotation each time. Sums of
 * subnormal terms can be slow on some processors; the ratio shows whether
 * they are here. Leaves r without an environment. */
static hl_result subnormal_times(hl_context *ctx, hl_relighter *r, const hl_env *map, uint32_t reps, float *B,
                                 double *tn, double *ts)
{
    const size_t n = (size_t)map->width * map->height * 3;
    float *px = malloc(n * sizeof *px), mx = 0.0f;
    double *t[2] = {malloc(reps * sizeof(double)), malloc(reps * sizeof(double))};
    const hl_env *env[2] = {map, NULL};
    hl_env *sub = NULL;
    hl_result res = px && t[0] && t[1] ? HL_OK : hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    if (res == HL_OK) {
        for (size_t i = 0; i < n; i++) mx = fmaxf(mx, map->rgb[i]);
        double s = mx > 0.0f ? 1e-38 / mx : 0.0;
        for (size_t i = 0; i < n; i++) px[i] = (float)(map->rgb[i] * s);
        res = hl_env_create(ctx, map->width, map->height, px, &sub, NULL);
        env[1] = sub;
    }
    for (uint32_t i = 0; i < reps && res == HL_OK; i++)
        for (int k = 0; k < 2 && res == HL_OK; k++) {
            hl_relight_desc d = {.terms = HL_TERMS_ALL, .select = HL_SELECT_DEFAULT, .rotate_deg = 1e-3f * (float)(i + 1)};
            double t0 = hl_tools_now();
            res = hl_relighter_set_env(r, env[k]);
            if (res == HL_OK) res = hl_relighter_run(r, &d, B, NULL);
            t[k][i] = hl_tools_now() - t0;
        }
    if (res == HL_OK) {
        *tn = median(t[0], (int)reps);
        *ts = median(t[1], (int)reps);
    }
    hl_env_destroy(sub);
    free(t[0]);
    free(t[1]);
    free(px);
    return res;
}

/* Subnormal lighting of one file, on both backends. */
static hl_result bench_subnormal(bench *b, const file_relighters *fr)
{
    hl_result r = HL_OK;
    for (int k = 0; k < 2 && r == HL_OK; k++) {
        hl_relighter *rb = k ? fr->rr : fr->rc;
        double *ms = b->speed[fr->f].sub_ms[k];
        ms[0] = ms[1] = NAN;
        if (!rb) continue;
        fprintf(stderr, "bench: %s: subnormal lighting on %s\n", bench_base_name(b->o.files[fr->f]),
                k ? "the reference" : "OpenCL");
        double tn = 0, ts = 0;
        r = subnormal_times(k ? b->ref : b->cl, rb, b->envs[0].env, k ? 3 : b->o.reps, b->B, &tn, &ts);
        ms[0] = 1e3 * tn;
        ms[1] = 1e3 * ts;
    }
    return r;
}

/* Everything measured on transport file f. */
static hl_result bench_file(bench *b, int f)
{
    file_relighters fr = {.f = f};
    /* the columns from the file's rows, the loaded entries freed first
       (so never held beside them), unless the reference relighter or the
       image errors want the entries after */
    hl_result r = b->o.ref_timing || b->o.image ? hl_relighter_create(b->cl, b->t[f], &fr.rc)
                                                : hl_relighter_create_from_file(b->cl, b->t[f], b->o.files[f], &fr.rc);
    if (r == HL_OK && b->o.ref_timing) r = hl_relighter_create(b->ref, b->t[f], &fr.rr);
    if (r != HL_OK) {
        hl_relighter_destroy(fr.rc);
        return r;
    }
    char pre[1100];
    snprintf(pre, sizeof pre, "bench: %s: ", b->o.files[f]);
    cli_device_memory(pre, fr.rc, b->o.files[f], b->V, 1);
    const hl_transport_info *fi = &b->t[f]->info;
    fr.bytes = 2.0 * (double)fi->coefficients_kept + (double)b->V * (8 + 2.0 * fi->block_count);
    for (int e = 0; e < b->o.nenvs && r == HL_OK; e++) r = bench_env_rows(b, &fr, e);
    if (r == HL_OK) r = bench_speed_of(b, &fr);
    if (r == HL_OK && b->sur) r = bench_capture(fr.rc, b->sur, b->o.probes, b->o.reps, b->B, &b->speed[f]);
    if (r == HL_OK) r = bench_subnormal(b, &fr);
    hl_relighter_destroy(fr.rc);
    hl_relighter_destroy(fr.rr);
    return r;
}

/* ---------------------------------------------------------------- the command */

static void bench_free(bench *b)
{
    free(b->B);
    free(b->Braw);
    free(b->idx);
    free(b->idx2);
    for (int e = 0; e < b->o.nenvs; e++) {
        hl_env_destroy(b->envs[e].env);
        free(b->envs[e].exact);
        free(b->envs[e].cont);
        free(b->envs[e].ground);
        for (uint32_t B = 0; B <= HL_MAX_BOUNCES; B++) free(b->envs[e].exact_b[B]);
    }
    for (int f = 0; f < b->o.nfiles; f++) hl_transport_destroy(b->t[f]);
    hl_bench_ref_destroy(b->br);
    hl_surroundings_destroy(b->sur);
    cli_unwatch();
    hl_context_destroy(b->cl);
    hl_context_destroy(b->ref);
    free(b);
}

/* References, the outputs' headings, then every file's rows and speed,
 * then the summary. Returns the first failure. */
static hl_result bench_measure(bench *b)
{
    hl_result r = references(b);
    bench_out_names(&b->out, b->o.outdir);
    if (r == HL_OK)
        r = bench_out_open(&b->out, b->ref, b->cl, &b->t[0]->info, b->K, b->K2, b->o.reps, b->o.ref_reps);
    if (r == HL_OK) {
        uint32_t nb[BENCH_MAX_FILES];
        for (int f = 0; f < b->o.nfiles; f++) nb[f] = b->t[f]->info.bounces;
        bench_out_references(&b->out, b->o.files, nb, b->o.nfiles, b->o.bounce_rays, b->envs, b->o.nenvs);
    }
    b->B = malloc((size_t)b->V * 12);
    b->Braw = malloc((size_t)b->V * 12);
    if (r == HL_OK && (!b->B || !b->Braw))
        r = hl_tools_fail(b->ref, HL_ERR_OUT_OF_MEMORY, "out of memory for %u vertex colours", b->V);
    if (r == HL_OK) r = bench_out_open_plot(&b->out, b->ref);
    for (int f = 0; f < b->o.nfiles && r == HL_OK; f++) r = bench_file(b, f);
    if (r == HL_OK) {
        bench_run run = {b->o.files, b->o.nfiles, b->envs, b->o.nenvs, b->o.terms, b->o.nterms, b->o.selects[0],
                         b->o.reps, b->speed};
        bench_out_summary(&b->out, &run);
    }
    if (r == HL_OK && b->o.image) {
        bench_image_in in = {b->cl, b->ref, b->br, b->t, b->o.files, b->o.nfiles, b->envs, b->o.nenvs, b->o.terms,
                             b->o.nterms, b->o.selects[0], b->o.image_frames, b->o.image_w, b->o.image_h};
        r = bench_image(&in, b->out.f[BENCH_MD]);
    }
    return r;
}

int cmd_bench(int argc, char **argv)
{
    bench *b = calloc(1, sizeof *b);
    if (!b) {
        fprintf(stderr, "haarlight: out of memory\n");
        return 1;
    }
    int u = parse_bench(argc, argv, b);
    if (u >= 0) {
        free(b);
        return u;
    }
    if (!cli_make_dir(b->o.outdir)) {
        free(b);
        return 1;
    }
    if (!cli_context_pair(&b->o.cd, &b->cl, &b->ref)) {
        free(b);
        return 1;
    }
    cli_watch(b->cl, b->ref);
    hl_result r = load(b);
    int rc = r != HL_OK ? cli_fail(b->ref, r) : bench_out_finish(&b->out, bench_measure(b), b->cl, b->ref);
    bench_free(b);
    return rc;
}
