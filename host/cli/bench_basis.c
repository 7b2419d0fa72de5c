/* bench_basis.c - `haarlight bench-basis`: the paraboloid Haar wavelets
 * against real spherical harmonics on one transport's exact rows, the
 * lighting cut to M terms (the 2003 paper's comparison): basis.md and
 * basis.csv, written under temporary names and renamed when complete.
 *
 * Depends on the public API and haarlight_tools.h (hl_basis_bench_*),
 * and cli.h's helpers.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "haarlight_tools.h"

int cmd_bench_basis(int argc, char **argv);

/* At most this many maps and term counts: as `bench`. */
#define BB_MAX_ENVS 16
#define BB_MAX_TERMS 16
/* The term count of the one-line summary: the paper's headline figure. */
#define BB_HEADLINE_M 200u
/* "all" in --terms: every term of each basis. */
#define BB_ALL 0u
/* Vertices by default: on the bunny with its ground (N = 64) 256 take
 * about 3 s for nine maps, and 1024 move no figure by 0.7 of a point. */
#define BB_DEFAULT_VERTICES 256u
/* Order by default: 20, 400 harmonics, so that 200 terms is half of them
 * and "200 terms" means the same count in both bases. */
#define BB_DEFAULT_ORDER 20u

static const char *const usage =
    "usage: haarlight bench-basis SCENE.hlt --env ENV.exr ... [--sky] -o DIR [options]\n"
    "\n"
    "Compares bases for the lighting on the exact transport of sampled vertices\n"
    "(untruncated, unquantised, recomputed from the rays as `bench`'s exact\n"
    "reference): the paraboloid Haar wavelets keeping the M lighting terms of\n"
    "largest |luminance| (haar), of largest |luminance| x support solid angle\n"
    "(haar-area) or x mean |T_i| over all vertices (haar-transport, the relighter's\n"
    "default), and real spherical harmonics keeping the first M in band order (sh,\n"
    "linear) or the M of largest |luminance| (sh-nonlinear); the transport is kept\n"
    "whole, and both it and the lighting are projected exactly from their texels.\n"
    "Writes DIR/basis.md and DIR/basis.csv: per map, basis and M, the relative L2\n"
    "and max errors of the colours (clamped at zero, as every output) against the\n"
    "exact ones; and per map the L2 of every basis at M = 200, also on stdout.\n"
    "\n"
    "  --env ENV.exr        an environment, OpenEXR or .hdr (repeat, at most 16 maps)\n"
    "  --sky                add the procedural sky (the default when no --env)\n"
    CLI_USAGE_LAYOUT
    "  --vertices K         vertices spread over the mesh (default 256; all if fewer)\n"
    "  --terms LIST         comma-separated term counts M, or all (default\n"
    "                       25,50,100,200,400); a count larger than a basis has is\n"
    "                       left out of that basis's rows\n"
    "  --sh-order L         spherical harmonics of bands 0 .. L-1, L^2 terms, 1 to 32\n"
    "                       (default 20: 400 terms)\n"
    "  -o, --output DIR     where basis.md and basis.csv go (made if missing)\n"
    "  --threads T          host threads (default: all cores)\n"
    "  -q, --quiet          no progress lines (the lines at M = 200 still go to stdout)\n";

typedef struct bb_opts {
    const char *file, *outdir;
    const char *env_paths[BB_MAX_ENVS];
    int nenvs, sky, quiet;
    uint32_t K, order, terms[BB_MAX_TERMS], nterms;
    hl_env_layout layout;
    int threads;
} bb_opts;

/* "25,50,all": 1 or 0 when malformed. */
static int parse_terms(const char *v, bb_opts *o)
{
    char buf[256];
    if (strlen(v) >= sizeof buf) return 0;
    strcpy(buf, v);
    o->nterms = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        uint32_t m;
        if (o->nterms == BB_MAX_TERMS) return 0;
        if (!strcmp(tok, "all")) m = BB_ALL;
        else if (!parse_u32(tok, &m) || m < 1) return 0;
        o->terms[o->nterms++] = m;
    }
    return o->nterms > 0;
}

/* -1 to go on, or the exit code. */
static int parse(int argc, char **argv, bb_opts *o)
{
    /* the default counts: whole bands of order 5, 10 and 20 (25, 100, 400),
       and the paper's 200 with 50 between */
    *o = (bb_opts){.K = BB_DEFAULT_VERTICES, .order = BB_DEFAULT_ORDER, .nterms = 5, .terms = {25, 50, 100, 200, 400},
                   .layout = HL_LAYOUT_AUTO};
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
#define NEED()                                                                         \
    do {                                                                               \
        if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a);    \
        v = argv[++i];                                                                 \
    } while (0)
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) { fputs(usage, stdout); return 0; }
        else if (!strcmp(a, "--env")) {
            NEED();
            if (o->nenvs == BB_MAX_ENVS) return usage_error(usage, "%s", "at most 16 environments");
            o->env_paths[o->nenvs++] = v;
        } else if (!strcmp(a, "--sky")) o->sky = 1;
        else if (!strcmp(a, "--layout")) { NEED(); if (!parse_layout(v, &o->layout)) return usage_error(usage, "--layout %s: expected auto, equirect, angular, cross-h or cross-v", v); }
        else if (!strcmp(a, "--vertices")) { NEED(); if (!parse_u32(v, &o->K) || o->K < 1 || o->K > 65536) return usage_error(usage, "--vertices %s: expected 1 to 65536", v); }
        else if (!strcmp(a, "--terms")) { NEED(); if (!parse_terms(v, o)) return usage_error(usage, "--terms %s: expected at most 16 counts of 1 or more, or all, separated by commas", v); }
        else if (!strcmp(a, "--sh-order")) { NEED(); if (!parse_u32(v, &o->order) || o->order < 1 || o->order > 32) return usage_error(usage, "--sh-order %s: expected 1 to 32", v); }
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED(); o->outdir = v; }
        else if (!strcmp(a, "--threads")) { NEED(); uint32_t t; if (!parse_u32(v, &t) || t < 1 || t > 64) return usage_error(usage, "--threads %s: expected 1 to 64", v); o->threads = (int)t; }
        else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) o->quiet = 1;
        else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (o->file) return usage_error(usage, "one SCENE.hlt only (%s is a second)", a);
        else o->file = a;
#undef NEED
    }
    if (!o->file) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (!o->outdir) return usage_error(usage, "%s", "no output folder given (-o DIR)");
    if (o->sky || o->nenvs == 0) {
        if (o->nenvs == BB_MAX_ENVS) return usage_error(usage, "%s", "at most 16 environments");
        o->env_paths[o->nenvs++] = NULL;
    }
    return -1;
}

/* A map's name in the table: its file name without the extension. */
static void env_name(const char *path, char *out, size_t n)
{
    if (!path) { snprintf(out, n, "sky"); return; }
    snprintf(out, n, "%s", bench_base_name(path));
    char *dot = strrchr(out, '.');
    if (dot && dot != out) *dot = 0;
}

/* Relative L2 and max of the colours clamped at zero (as every output
 * is) against the exact ones, and the L2 before the clamp. */
static void errors(const double *c, const double *e, uint32_t n, double out[3])
{
    double se = 0.0, su = 0.0, sr = 0.0, me = 0.0, mr = 0.0;
    for (uint32_t i = 0; i < 3 * n; i++) {
        const double d = fmax(c[i], 0.0) - e[i], u = c[i] - e[i];
        se += d * d, su += u * u, sr += e[i] * e[i];
        me = fmax(me, fabs(d)), mr = fmax(mr, fabs(e[i]));
    }
    out[0] = sr > 0 ? sqrt(se / sr) : sqrt(se);
    out[1] = mr > 0 ? me / mr : me;
    out[2] = sr > 0 ? sqrt(su / sr) : sqrt(su);
}

/* The two output files under temporary names. */
typedef struct bb_files {
    char tmp[2][1200], final[2][1200];
    FILE *f[2]; /* md, csv */
} bb_files;

static hl_result files_open(bb_files *fs, hl_context *ctx, const char *dir)
{
    static const char *const names[2] = {"basis.md", "basis.csv"};
    memset(fs, 0, sizeof *fs);
    for (int k = 0; k < 2; k++) {
        snprintf(fs->final[k], sizeof fs->final[k], "%s/%s", dir, names[k]);
        snprintf(fs->tmp[k], sizeof fs->tmp[k], "%s/%s.tmp.%ld", dir, names[k], (long)getpid());
        fs->f[k] = fopen(fs->tmp[k], "w");
        if (!fs->f[k]) return hl_tools_fail(ctx, HL_ERR_IO, "%s: cannot write: %s", fs->tmp[k], strerror(errno));
    }
    return HL_OK;
}

/* Closes the files and renames them into place when r is HL_OK, else
 * removes them. */
static hl_result files_finish(bb_files *fs, hl_context *ctx, hl_result r)
{
    for (int k = 0; k < 2; k++) {
        if (!fs->f[k]) continue;
        int bad = ferror(fs->f[k]) || fflush(fs->f[k]) != 0 || fsync(fileno(fs->f[k])) != 0;
        if (fclose(fs->f[k]) != 0) bad = 1;
        fs->f[k] = NULL;
        if (r == HL_OK && bad) r = hl_tools_fail(ctx, HL_ERR_IO, "%s: cannot write: %s", fs->tmp[k], strerror(errno));
    }
    for (int k = 0; k < 2 && r == HL_OK; k++)
        if (rename(fs->tmp[k], fs->final[k]) != 0)
            r = hl_tools_fail(ctx, HL_ERR_IO, "%s: cannot write: %s", fs->final[k], strerror(errno));
    if (r != HL_OK)
        for (int k = 0; k < 2; k++) unlink(fs->tmp[k]);
    return r;
}

static void md_heading(FILE *md, const bb_opts *o, const hl_transport_info *in, uint32_t K)
{
    fprintf(md, "# Lighting bases: paraboloid Haar against spherical harmonics\n\n"
                "`%s`: %u vertices, N = %u, C = %u. Exact colours on %u vertices spread over the mesh:\n"
                "untruncated, unquantised transport recomputed from the rays, dotted with the untruncated\n"
                "lighting in float64. Each basis cuts the LIGHTING to M terms and keeps the transport whole:\n"
                "haar keeps the M paraboloid Haar terms of largest |luminance| (nonlinear), haar-area those of\n"
                "largest |luminance| x the solid angle of the wavelet's support, haar-transport x the mean\n"
                "|T_i| over all the transport's vertices (the relighter's default selection); sh keeps the\n"
                "first M real spherical harmonics in band order (linear; order %u: %u terms), sh-nonlinear\n"
                "the M harmonics of largest |luminance|. Both maps are projected exactly from their texels (the\n"
                "texels' integrals of each harmonic). L2 is relative to the exact colours' L2 norm and max to\n"
                "the brightest, on the colours clamped at zero as every output is; \"unclamped\" is the L2\n"
                "before the clamp.\n\n",
            bench_base_name(o->file), in->vertex_count, in->N, in->C, K, o->order, o->order * o->order);
    fprintf(md, "| map | basis | M | L2 | max | L2 unclamped |\n|---|---|---:|---:|---:|---:|\n");
}

/* One map: every basis at every M it has, rows in both files; the L2 at
 * BB_HEADLINE_M into head (NAN where a basis has fewer terms). */
static hl_result measure_env(hl_basis_bench *bb, const hl_env *env, const char *name, const bb_opts *o, uint32_t K,
                             bb_files *fs, double *rgb, double head[HL_BASIS_COUNT])
{
    const double *exact = NULL;
    hl_result r = hl_basis_bench_set_env(bb, env, &exact);
    for (int b = 0; b < HL_BASIS_COUNT && r == HL_OK; b++) {
        const uint32_t count = hl_basis_bench_count(bb, (hl_basis)b);
        head[b] = NAN;
        for (uint32_t i = 0; i < o->nterms && r == HL_OK; i++) {
            const uint32_t M = o->terms[i] == BB_ALL ? count : o->terms[i];
            int seen = 0; /* "all" may repeat a count given */
            for (uint32_t q = 0; q < i; q++) seen |= (o->terms[q] == BB_ALL ? count : o->terms[q]) == M;
            if (M > count || seen) continue;
            double e[3];
            r = hl_basis_bench_colours(bb, (hl_basis)b, M, rgb);
            if (r != HL_OK) break;
            errors(rgb, exact, K, e);
            fprintf(fs->f[0], "| %s | %s | %u | %.4f%% | %.4f%% | %.4f%% |\n", name, hl_basis_name((hl_basis)b), M,
                    100 * e[0], 100 * e[1], 100 * e[2]);
            fprintf(fs->f[1], "%s,%s,%u,%.9g,%.9g,%.9g\n", name, hl_basis_name((hl_basis)b), M, e[0], e[1], e[2]);
        }
        if (r == HL_OK && BB_HEADLINE_M <= count) {
            double e[3];
            r = hl_basis_bench_colours(bb, (hl_basis)b, BB_HEADLINE_M, rgb);
            if (r == HL_OK) errors(rgb, exact, K, e), head[b] = e[0];
        }
    }
    return r;
}

/* The environments, the comparison and both files. */
static hl_result run(hl_context *ctx, const bb_opts *o, hl_transport *t, bb_files *fs)
{
    const uint32_t V = t->info.vertex_count, K = o->K > V ? V : o->K;
    uint32_t *idx = malloc((size_t)K * 4);
    double *rgb = malloc((size_t)K * 3 * sizeof(double)), head[BB_MAX_ENVS][HL_BASIS_COUNT];
    char names[BB_MAX_ENVS][256];
    hl_env *envs[BB_MAX_ENVS] = {0};
    hl_basis_bench *bb = NULL;
    hl_result r = idx && rgb ? HL_OK : hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    for (uint32_t k = 0; k < K && r == HL_OK; k++) idx[k] = (uint32_t)((uint64_t)k * V / K);
    for (int e = 0; e < o->nenvs && r == HL_OK; e++) {
        hl_sky_desc sky = {0};
        env_name(o->env_paths[e], names[e], sizeof names[e]);
        r = o->env_paths[e] ? cli_env_load(ctx, o->env_paths[e], o->layout, &envs[e], o->quiet)
                            : hl_env_create_sky(ctx, &sky, &envs[e]);
    }
    if (r == HL_OK && !o->quiet)
        fprintf(stderr, "bench-basis: exact transport of %u vertices, spherical harmonics of order %u\n", K, o->order);
    if (r == HL_OK) r = hl_basis_bench_create(ctx, t, idx, K, o->order, &bb);
    if (r == HL_OK) r = files_open(fs, ctx, o->outdir);
    if (r == HL_OK) {
        md_heading(fs->f[0], o, &t->info, K);
        fprintf(fs->f[1], "map,basis,terms,l2,max,l2_unclamped\n");
    }
    for (int e = 0; e < o->nenvs && r == HL_OK; e++) {
        if (!o->quiet) fprintf(stderr, "bench-basis: %s\n", names[e]);
        r = measure_env(bb, envs[e], names[e], o, K, fs, rgb, head[e]);
    }
    if (r == HL_OK) {
        fprintf(fs->f[0], "\n## At %u terms\n\n| map |", BB_HEADLINE_M);
        for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(fs->f[0], " %s L2 |", hl_basis_name((hl_basis)b));
        fprintf(fs->f[0], "\n|---|");
        for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(fs->f[0], "---:|");
        fprintf(fs->f[0], "\n");
        for (int e = 0; e < o->nenvs; e++) {
            const double *h = head[e];
            fprintf(fs->f[0], "| %s |", names[e]);
            for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(fs->f[0], " %.2f%% |", 100 * h[b]);
            fprintf(fs->f[0], "\n");
            printf("%s: at %u terms, wavelet L2 %.2f%% (area-weighted %.2f%%, transport-weighted %.2f%%) against "
                   "spherical harmonics %.2f%% (nonlinear %.2f%%)\n",
                   names[e], BB_HEADLINE_M, 100 * h[HL_BASIS_HAAR], 100 * h[HL_BASIS_HAAR_AREA],
                   100 * h[HL_BASIS_HAAR_TRANSPORT], 100 * h[HL_BASIS_SH], 100 * h[HL_BASIS_SH_NONLINEAR]);
        }
        if (o->order * o->order < BB_HEADLINE_M)
            fprintf(fs->f[0], "\n(nan: the harmonics of order %u have fewer than %u terms.)\n", o->order, BB_HEADLINE_M);
    }
    hl_basis_bench_destroy(bb);
    for (int e = 0; e < o->nenvs; e++) hl_env_destroy(envs[e]);
    free(idx);
    free(rgb);
    return r;
}

int cmd_bench_basis(int argc, char **argv)
{
    bb_opts o;
    int u = parse(argc, argv, &o);
    if (u >= 0) return u;
    hl_context_desc cd = {.backend = HL_BACKEND_REFERENCE, .threads = o.threads, .quiet = 1};
    char err[4096];
    hl_context *ctx = NULL;
    if (hl_context_create(&cd, &ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 1;
    }
    cli_watch(ctx, NULL);
    hl_transport *t = NULL;
    bb_files fs;
    memset(&fs, 0, sizeof fs);
    hl_result r = hl_transport_load(ctx, o.file, &t);
    if (r == HL_OK && !cli_make_dir(o.outdir)) r = HL_ERR_IO;
    int rc = r == HL_ERR_IO && t ? 1 : 0; /* cli_make_dir has printed why */
    if (r == HL_OK) r = run(ctx, &o, t, &fs);
    if (r == HL_OK || fs.f[0] || fs.f[1]) r = files_finish(&fs, ctx, r);
    if (r == HL_OK) {
        if (!o.quiet) fprintf(stderr, "bench-basis: wrote %s/basis.md and basis.csv\n", o.outdir);
    } else if (!rc) rc = cli_fail(ctx, r);
    hl_transport_destroy(t);
    cli_unwatch();
    hl_context_destroy(ctx);
    return rc;
}
