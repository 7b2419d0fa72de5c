/* bench_basis.c - `haarlight bench-basis`: the paraboloid Haar wavelets,
 * the Haar wavelets over the six cube faces and real spherical harmonics
 * on one transport's exact rows, the lighting cut to M terms (the 2003
 * paper's comparison), the rows whole and cut to equal bytes, and the time
 * of a lighting change in each: basis.md, basis.csv and basis.gp, written
 * under temporary names and renamed when complete, then basis.svg drawn by
 * bench_out.c's gnuplot runner.
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

/* At most this many maps, term counts and byte budgets: as `bench`. */
#define BB_MAX_ENVS 16
#define BB_MAX_TERMS 16
#define BB_MAX_BYTES 16
/* The term count of the one-line summary, the equal-bytes table and the
 * plot's bytes panel: the paper's headline figure. */
#define BB_HEADLINE_M 200u
/* "all" in --terms: every term of each basis. */
#define BB_ALL 0u
/* Vertices by default: on the bunny with its ground (N = 64) 256 take
 * a few seconds for nine maps, and 1024 move no figure by 0.7 of a point. */
#define BB_DEFAULT_VERTICES 256u
/* Order by default: 20, 400 harmonics, so that 200 terms is half of them
 * and "200 terms" means the same count in both bases. */
#define BB_DEFAULT_ORDER 20u
/* Runs of each timing, the least kept: the host is shared, and the least
 * is the run least disturbed. */
#define BB_DEFAULT_REPS 5u
/* The byte budgets by default, per vertex: on the bunny with its ground
 * at N = 64 the file's paraboloid rows hold 1759 entries on average at the
 * default --energy 1e-5, 3.59 kB; the budgets run from a fourteenth of
 * that to above it, so each basis is seen both starved and nearly whole. */
#define BB_DEFAULT_BUDGETS {250, 500, 1000, 2000, 4000}
#define BB_DEFAULT_NBUDGETS 5
/* Errors below this are drawn at it on the plot's logarithmic axes (the
 * whole rows at all terms give 0). */
#define BB_PLOT_FLOOR 1e-7

static const char *const usage =
    "usage: haarlight bench-basis SCENE.hlt --env ENV.exr ... [--sky] -o DIR [options]\n"
    "\n"
    "Compares three bases for the lighting on the exact transport of sampled\n"
    "vertices (untruncated, unquantised, recomputed from the rays as `bench`'s exact\n"
    "reference): the paraboloid Haar wavelets, the Haar wavelets over the six faces\n"
    "of a cube (the 2003 paper's layout; the same rays' transport regrouped onto the\n"
    "faces' texels) and real spherical harmonics. The Haar bases keep the M lighting\n"
    "terms of largest |luminance| (haar, cube-haar), of largest |luminance| x support\n"
    "solid angle (haar-area, cube-haar-area) or x mean |T_i| (haar-transport, the\n"
    "relighter's default, over all the file's rows; cube-haar-transport, over the\n"
    "sampled rows); the harmonics keep the first M in band order (sh, linear) or the\n"
    "M of largest |luminance| (sh-nonlinear). The transport is kept whole, and also\n"
    "cut to equal bytes per vertex (8 + 2 per 256-term block + 2 per entry, as the\n"
    "transport file stores a row: the Haar rows keep their largest entries, the\n"
    "harmonics their first). Each setting's time of one lighting change is measured\n"
    "on this host's plain-C path: the lighting transform (Haar, cube Haar or the\n"
    "projection on the harmonics), the selection and the M-term dot products of the\n"
    "sampled vertices, scaled to the transport's vertex count (one thread; the least\n"
    "of the runs). Writes DIR/basis.md, DIR/basis.csv, DIR/basis.gp and, with\n"
    "gnuplot, DIR/basis.svg: per map, basis, M and budget the relative L2 and max\n"
    "errors of the colours (clamped at zero, as every output) against the\n"
    "paraboloid's exact ones, and the L2 against the basis's own grid's (l2_own:\n"
    "the cube's for the cube bases; the gap between the two grids is reported as\n"
    "the cube floor); per map the L2 of every basis at M = 200, also on stdout.\n"
    "\n"
    "  --env ENV.exr        an environment, OpenEXR or .hdr (repeat, at most 16 maps)\n"
    "  --sky                add the procedural sky (the default when no --env)\n"
    CLI_USAGE_LAYOUT
    "  --vertices K         vertices spread over the mesh (default 256; all if fewer)\n"
    "  --terms LIST         comma-separated term counts M, or all (default\n"
    "                       25,50,100,200,400); a count larger than a basis has is\n"
    "                       left out of that basis's rows\n"
    "  --bytes LIST         comma-separated budgets in bytes per vertex, 1 to 1000000\n"
    "                       (default 250,500,1000,2000,4000)\n"
    "  --sh-order L         spherical harmonics of bands 0 .. L-1, L^2 terms, 1 to 32\n"
    "                       (default 20: 400 terms)\n"
    "  --cube-side Q        the cube faces' side in texels: a power of two from 2 to\n"
    "                       512 that divides the transport's C (default N/2, halved\n"
    "                       until it divides C: 6 (N/2)^2 terms against the\n"
    "                       paraboloids' 2 N^2)\n"
    "  --cube-rows shared|own  how the cube rows come from the visibility texels:\n"
    "                       shared (default) groups the paraboloid rows' own pieces\n"
    "                       by cube texel (under a constant map both give the same\n"
    "                       colours to float precision, but a cube texel's pieces\n"
    "                       only approximate its footprint); own integrates each\n"
    "                       visibility texel's clamped cosine over its footprint\n"
    "  --continuous K2      also compare both grids' exact colours (every term) with\n"
    "                       `bench`'s continuous reference, a ray per map pixel, on K2\n"
    "                       of the vertices (default 0: not)\n"
    "  --reps R             runs of each timing, 1 to 100 (default 5)\n"
    "  -o, --output DIR     where the files go (made if missing)\n"
    "  --threads T          host threads for the rays and the references (default:\n"
    "                       all cores; the timings run on one)\n"
    "  -q, --quiet          no progress lines (the lines at M = 200 still go to stdout)\n";

typedef struct bb_opts {
    const char *file, *outdir;
    int argc;
    char **argv;     /* the options as given, for basis.md */
    const char *env_paths[BB_MAX_ENVS];
    int nenvs, sky, quiet;
    uint32_t K, K2, order, cube, cube_rows, reps, terms[BB_MAX_TERMS], nterms, bytes[BB_MAX_BYTES], nbytes;
    hl_env_layout layout;
    int threads;
} bb_opts;

/* "25,50,all" into out (all: BB_ALL when allow_all): 1, or 0 when
 * malformed or a count is outside [lo, hi]. */
static int parse_list(const char *v, uint32_t *out, uint32_t *n, uint32_t lo, uint32_t hi, int allow_all)
{
    char buf[256];
    if (strlen(v) >= sizeof buf) return 0;
    strcpy(buf, v);
    *n = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        uint32_t m;
        if (*n == BB_MAX_TERMS) return 0;
        if (allow_all && !strcmp(tok, "all")) m = BB_ALL;
        else if (!parse_u32(tok, &m) || m < lo || m > hi) return 0;
        out[(*n)++] = m;
    }
    return *n > 0;
}

/* -1 to go on, or the exit code. */
static int parse(int argc, char **argv, bb_opts *o)
{
    /* the default counts: whole bands of order 5, 10 and 20 (25, 100, 400),
       and the paper's 200 with 50 between */
    *o = (bb_opts){.argc = argc, .argv = argv, .K = BB_DEFAULT_VERTICES, .order = BB_DEFAULT_ORDER, .reps = BB_DEFAULT_REPS, .nterms = 5,
                   .terms = {25, 50, 100, 200, 400}, .nbytes = BB_DEFAULT_NBUDGETS, .bytes = BB_DEFAULT_BUDGETS,
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
        else if (!strcmp(a, "--terms")) { NEED(); if (!parse_list(v, o->terms, &o->nterms, 1, UINT32_MAX, 1)) return usage_error(usage, "--terms %s: expected at most 16 counts of 1 or more, or all, separated by commas", v); }
        else if (!strcmp(a, "--bytes")) { NEED(); if (!parse_list(v, o->bytes, &o->nbytes, 1, 1000000, 0)) return usage_error(usage, "--bytes %s: expected at most 16 budgets of 1 to 1000000 bytes, separated by commas", v); }
        else if (!strcmp(a, "--sh-order")) { NEED(); if (!parse_u32(v, &o->order) || o->order < 1 || o->order > 32) return usage_error(usage, "--sh-order %s: expected 1 to 32", v); }
        else if (!strcmp(a, "--cube-side")) { NEED(); if (!parse_u32(v, &o->cube) || o->cube < 2 || o->cube > 512 || (o->cube & (o->cube - 1))) return usage_error(usage, "--cube-side %s: expected a power of two from 2 to 512", v); }
        else if (!strcmp(a, "--cube-rows")) { NEED(); if (!strcmp(v, "shared")) o->cube_rows = HL_CUBE_ROWS_SHARED; else if (!strcmp(v, "own")) o->cube_rows = HL_CUBE_ROWS_OWN; else return usage_error(usage, "--cube-rows %s: expected shared or own", v); }
        else if (!strcmp(a, "--continuous")) { NEED(); if (!parse_u32(v, &o->K2) || o->K2 > 65536) return usage_error(usage, "--continuous %s: expected 0 to 65536", v); }
        else if (!strcmp(a, "--reps")) { NEED(); if (!parse_u32(v, &o->reps) || o->reps < 1 || o->reps > 100) return usage_error(usage, "--reps %s: expected 1 to 100", v); }
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

/* The three output files under temporary names. */
enum { BB_MD, BB_CSV, BB_GP, BB_FILES };
typedef struct bb_files {
    char tmp[BB_FILES][1200], final[BB_FILES][1200];
    FILE *f[BB_FILES];
} bb_files;

static hl_result files_open(bb_files *fs, hl_context *ctx, const char *dir)
{
    static const char *const names[BB_FILES] = {"basis.md", "basis.csv", "basis.gp"};
    memset(fs, 0, sizeof *fs);
    for (int k = 0; k < BB_FILES; k++) {
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
    for (int k = 0; k < BB_FILES; k++) {
        if (!fs->f[k]) continue;
        int bad = ferror(fs->f[k]) || fflush(fs->f[k]) != 0 || fsync(fileno(fs->f[k])) != 0;
        if (fclose(fs->f[k]) != 0) bad = 1;
        fs->f[k] = NULL;
        if (r == HL_OK && bad) r = hl_tools_fail(ctx, HL_ERR_IO, "%s: cannot write: %s", fs->tmp[k], strerror(errno));
    }
    for (int k = 0; k < BB_FILES && r == HL_OK; k++)
        if (rename(fs->tmp[k], fs->final[k]) != 0)
            r = hl_tools_fail(ctx, HL_ERR_IO, "%s: cannot write: %s", fs->final[k], strerror(errno));
    if (r != HL_OK)
        for (int k = 0; k < BB_FILES; k++) unlink(fs->tmp[k]);
    return r;
}

/* What was measured, for the summary tables and the plot. */
typedef struct bb_results {
    uint32_t M[HL_BASIS_COUNT][BB_MAX_TERMS];  /* each basis's counts (0: left out) */
    double l2[BB_MAX_ENVS][HL_BASIS_COUNT][BB_MAX_TERMS];   /* whole rows */
    double ms[BB_MAX_ENVS][HL_BASIS_COUNT][BB_MAX_TERMS][3]; /* transform, select, dots */
    double l2b[BB_MAX_ENVS][HL_BASIS_COUNT][BB_MAX_BYTES];  /* at BB_HEADLINE_M, rows cut to bytes,
                                                               against the basis's own exact colours */
    double floor[BB_MAX_ENVS];  /* the cube's exact colours against the paraboloid's (L2) */
    double cont[BB_MAX_ENVS][2]; /* the paraboloid's and the cube's exact colours against the
                                    continuous reference (L2; --continuous) */
    uint32_t entries[HL_BASIS_COUNT][BB_MAX_BYTES];
    double head[BB_MAX_ENVS][HL_BASIS_COUNT];                /* whole rows at BB_HEADLINE_M */
} bb_results;

static void md_heading(FILE *md, const bb_opts *o, const hl_transport_info *in, uint32_t K, uint32_t Cq)
{
    fprintf(md, "# Lighting bases: paraboloid Haar, cube-face Haar and spherical harmonics\n\n"
                "`%s`: %u vertices, N = %u, C = %u. Exact colours on %u vertices spread over the mesh:\n"
                "untruncated, unquantised transport recomputed from the rays, dotted with the untruncated\n"
                "lighting in float64. Each basis cuts the LIGHTING to M terms. haar keeps the M paraboloid Haar\n"
                "terms (%u) of largest |luminance| (nonlinear), haar-area those of largest |luminance| x the solid\n"
                "angle of the wavelet's support, haar-transport x the mean |T_i| over all the transport's\n"
                "vertices (the relighter's default selection). cube-haar, cube-haar-area and cube-haar-transport\n"
                "do the same with the Haar wavelets over the six faces of a cube of side %u (%u terms; the\n"
                "transport weights from the sampled vertices' rows). sh keeps the first M real spherical\n"
                "harmonics in band order (linear; order %u: %u terms), sh-nonlinear the M of largest\n"
                "|luminance|. The maps are projected exactly from their texels. L2 is relative to the exact\n"
                "colours' L2 norm and max to the brightest, on the colours clamped at zero as every output is;\n"
                "\"unclamped\" is the L2 before the clamp. The exact colours are the paraboloid's; basis.csv's\n"
                "l2_own measures each basis against its own grid's exact colours instead (the cube's rows\n"
                "dotted with its whole lighting: the two grids differ where a texel holds both light and a\n"
                "shadow's edge).\n\n"
                "Equal bytes: a row of K entries costs 8 + 2 ceil(terms / 256) + 2 K bytes, as the transport\n"
                "file stores it (host/FORMAT.md); under a budget the Haar rows keep their K largest entries and\n"
                "the harmonics their first K. Time: one lighting change on this host's plain-C path (lighting\n"
                "transform of the texel means, selection, M-term dot products of the sampled vertices scaled\n"
                "to all %u), one thread, the least of %u runs.\n\n",
            bench_base_name(o->file), in->vertex_count, in->N, in->C, K, 2 * in->N * in->N, Cq, 6 * Cq * Cq,
            o->order, o->order * o->order, in->vertex_count, o->reps);
    if (!Cq) fprintf(md, "(No power of two from 2 divides C = %u: the cube bases are left out.)\n\n", in->C);
    fprintf(md, "Made by `haarlight bench-basis");
    for (int i = 0; i < o->argc; i++) fprintf(md, " %s", o->argv[i]);
    fprintf(md, "` (cube rows: %s).\n\n", o->cube_rows == HL_CUBE_ROWS_OWN ? "own footprints" : "shared pieces");
}

/* The paraboloid's and the cube's exact colours of the n2 vertices k K /
 * n2 against the continuous reference: L2 into out[0], out[1]. */
static hl_result continuous(hl_context *ctx, hl_basis_bench *bb, const hl_env *env, uint32_t K, uint32_t n2,
                            double out[2])
{
    double *cont = malloc((size_t)n2 * 3 * sizeof(double)), *sub = malloc((size_t)n2 * 3 * sizeof(double));
    hl_result r = cont && sub ? hl_basis_bench_continuous(bb, env, n2, cont)
                              : hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the continuous reference");
    for (int f = 0; f < 2 && r == HL_OK; f++) {
        const double *ex = hl_basis_bench_exact(bb, f ? HL_BASIS_CUBE : HL_BASIS_HAAR);
        double er[3] = {NAN, NAN, NAN};
        for (uint32_t k = 0; k < n2 && ex; k++)
            for (int c = 0; c < 3; c++) sub[3 * k + c] = ex[3 * ((uint64_t)k * K / n2) + c];
        if (ex) errors(sub, cont, n2, er);
        out[f] = er[0];
    }
    free(cont);
    free(sub);
    return r;
}

/* One map: every basis at every M it has, whole and cut to each budget,
 * rows into the CSV; the figures into res. */
static hl_result measure_env(hl_context *ctx, hl_basis_bench *bb, const hl_env *env, const char *name,
                             const bb_opts *o, uint32_t K, bb_files *fs, double *rgb, bb_results *res, int e)
{
    const double *exact = NULL;
    hl_result r = hl_basis_bench_set_env(bb, env, &exact);
    res->floor[e] = res->cont[e][0] = res->cont[e][1] = NAN;
    if (r == HL_OK && hl_basis_bench_exact(bb, HL_BASIS_CUBE)) {
        double er[3];
        errors(hl_basis_bench_exact(bb, HL_BASIS_CUBE), exact, K, er);
        res->floor[e] = er[0];
    }
    if (r == HL_OK && o->K2) r = continuous(ctx, bb, env, K, o->K2 < K ? o->K2 : K, res->cont[e]);
    for (int b = 0; b < HL_BASIS_COUNT && r == HL_OK; b++) {
        const hl_basis basis = (hl_basis)b;
        const uint32_t count = hl_basis_bench_count(bb, basis);
        const double *own = count ? hl_basis_bench_exact(bb, basis) : exact;
        res->head[e][b] = NAN;
        for (uint32_t i = 0; i < o->nterms && r == HL_OK; i++) {
            const uint32_t M = o->terms[i] == BB_ALL ? count : o->terms[i];
            int seen = 0; /* "all" may repeat a count given */
            for (uint32_t q = 0; q < i; q++) seen |= (o->terms[q] == BB_ALL ? count : o->terms[q]) == M;
            res->M[b][i] = M > count || seen ? 0 : M;
            if (!res->M[b][i]) continue;
            double er[3], eo[3];
            hl_basis_time tm;
            r = hl_basis_bench_colours(bb, basis, M, rgb);
            if (r == HL_OK) r = hl_basis_bench_time(bb, basis, M, o->reps, &tm);
            if (r != HL_OK) break;
            errors(rgb, exact, K, er);
            errors(rgb, own, K, eo);
            res->l2[e][b][i] = er[0];
            res->ms[e][b][i][0] = 1e3 * tm.transform, res->ms[e][b][i][1] = 1e3 * tm.select;
            res->ms[e][b][i][2] = 1e3 * tm.dots;
            fprintf(fs->f[BB_CSV], "%s,%s,%u,whole,%u,%.9g,%.9g,%.9g,%.9g,%.6g\n", name, hl_basis_name(basis), M, count,
                    er[0], er[1], er[2], eo[0], 1e3 * (tm.transform + tm.select + tm.dots));
            for (uint32_t j = 0; j < o->nbytes && r == HL_OK; j++) {
                r = hl_basis_bench_colours_bytes(bb, basis, M, o->bytes[j], rgb);
                if (r != HL_OK) break;
                errors(rgb, exact, K, er);
                errors(rgb, own, K, eo);
                fprintf(fs->f[BB_CSV], "%s,%s,%u,%u,%u,%.9g,%.9g,%.9g,%.9g,\n", name, hl_basis_name(basis), M,
                        o->bytes[j], hl_basis_bench_entries(bb, basis, o->bytes[j]), er[0], er[1], er[2], eo[0]);
            }
        }
        if (r == HL_OK && BB_HEADLINE_M <= count) {
            double er[3];
            r = hl_basis_bench_colours(bb, basis, BB_HEADLINE_M, rgb);
            if (r == HL_OK) errors(rgb, exact, K, er), res->head[e][b] = er[0];
        }
        for (uint32_t j = 0; j < o->nbytes && r == HL_OK; j++) {
            double er[3] = {NAN, NAN, NAN};
            res->entries[b][j] = hl_basis_bench_entries(bb, basis, o->bytes[j]);
            if (BB_HEADLINE_M <= count) r = hl_basis_bench_colours_bytes(bb, basis, BB_HEADLINE_M, o->bytes[j], rgb);
            if (r == HL_OK && BB_HEADLINE_M <= count) errors(rgb, own, K, er);
            res->l2b[e][b][j] = er[0];
        }
    }
    return r;
}

/* The median of the n values v (sorted in place). */
static double median(double *v, int n)
{
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j - 1] > v[j]; j--) {
            const double t = v[j];
            v[j] = v[j - 1], v[j - 1] = t;
        }
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The geometric mean over the maps of errors (each at least
 * BB_PLOT_FLOOR, so that exact results stay on a log axis). */
static double geo_mean(const double *v, int n, size_t stride)
{
    double s = 0.0;
    for (int e = 0; e < n; e++) s += log(fmax(v[(size_t)e * stride], BB_PLOT_FLOOR));
    return exp(s / n);
}

/* The summary tables of basis.md, the lines on stdout and the plot's
 * script. */
static void write_summary(bb_files *fs, const bb_opts *o, uint32_t K, char names[][256], const bb_results *res,
                          const double *ms_tot)
{
    FILE *md = fs->f[BB_MD], *gp = fs->f[BB_GP];
    const int ne = o->nenvs;
    fprintf(md, "## At %u terms, whole rows\n\nL2 against the paraboloid's exact colours. \"cube floor\": the cube's own "
                "exact colours (every term) against them.\n\n| map |", BB_HEADLINE_M);
    for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(md, " %s |", hl_basis_name((hl_basis)b));
    fprintf(md, " cube floor |\n|---|");
    for (int b = 0; b <= HL_BASIS_COUNT; b++) fprintf(md, "---:|");
    fprintf(md, "\n");
    for (int e = 0; e < ne; e++) {
        fprintf(md, "| %s |", names[e]);
        for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(md, " %.2f%% |", 100 * res->head[e][b]);
        fprintf(md, " %.2f%% |\n", 100 * res->floor[e]);
        printf("%s: at %u terms, wavelet L2 %.2f%% (area-weighted %.2f%%, transport-weighted %.2f%%), cube-face "
               "wavelets %.2f%% (%.2f%%, %.2f%%), spherical harmonics %.2f%% (nonlinear %.2f%%)\n",
               names[e], BB_HEADLINE_M, 100 * res->head[e][HL_BASIS_HAAR], 100 * res->head[e][HL_BASIS_HAAR_AREA],
               100 * res->head[e][HL_BASIS_HAAR_TRANSPORT], 100 * res->head[e][HL_BASIS_CUBE],
               100 * res->head[e][HL_BASIS_CUBE_AREA], 100 * res->head[e][HL_BASIS_CUBE_TRANSPORT],
               100 * res->head[e][HL_BASIS_SH], 100 * res->head[e][HL_BASIS_SH_NONLINEAR]);
    }
    if (o->order * o->order < BB_HEADLINE_M)
        fprintf(md, "\n(nan: the harmonics of order %u have fewer than %u terms.)\n", o->order, BB_HEADLINE_M);
    if (o->K2) {
        fprintf(md, "\n## The grids against the continuous reference\n\nL2 of each grid's exact colours (every term) against "
                    "`bench`'s continuous reference (a ray per map pixel from the vertex itself, no grid) on %u of the "
                    "vertices.\n\n| map | paraboloid | cube |\n|---|---:|---:|\n", o->K2 < o->K ? o->K2 : o->K);
        for (int e = 0; e < ne; e++)
            fprintf(md, "| %s | %.2f%% | %.2f%% |\n", names[e], 100 * res->cont[e][0], 100 * res->cont[e][1]);
    }

    fprintf(md, "\n## Equal bytes, at %u terms\n\nL2 with each row cut to the budget (bytes per vertex), against each "
                "basis's own exact colours (the cube's for the cube bases, so that its floor above is not counted); in "
                "brackets the entries a row keeps.\n\n| map | bytes |", BB_HEADLINE_M);
    for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(md, " %s |", hl_basis_name((hl_basis)b));
    fprintf(md, "\n|---|---:|");
    for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(md, "---:|");
    fprintf(md, "\n");
    for (int e = 0; e < ne; e++)
        for (uint32_t j = 0; j < o->nbytes; j++) {
            fprintf(md, "| %s | %u |", names[e], o->bytes[j]);
            for (int b = 0; b < HL_BASIS_COUNT; b++) fprintf(md, " %.2f%% (%u) |", 100 * res->l2b[e][b][j], res->entries[b][j]);
            fprintf(md, "\n");
        }

    fprintf(md, "\n## Time of one lighting change\n\nMilliseconds on this host, the median over the maps: the lighting "
                "transform, the selection, the dot products (scaled to every vertex) and their sum.\n\n"
                "| basis | M | transform | selection | dot products | total |\n|---|---:|---:|---:|---:|---:|\n");
    for (int b = 0; b < HL_BASIS_COUNT; b++)
        for (uint32_t i = 0; i < o->nterms; i++) {
            if (!res->M[b][i]) continue;
            double part[4][BB_MAX_ENVS];
            for (int e = 0; e < ne; e++) {
                for (int q = 0; q < 3; q++) part[q][e] = res->ms[e][b][i][q];
                part[3][e] = ms_tot[((size_t)e * HL_BASIS_COUNT + b) * BB_MAX_TERMS + i];
            }
            fprintf(md, "| %s | %u |", hl_basis_name((hl_basis)b), res->M[b][i]);
            for (int q = 0; q < 4; q++) fprintf(md, " %.3f |", median(part[q], ne));
            fprintf(md, "\n");
        }

    /* the plot: the geometric mean over the maps against terms, time and
       bytes, a line per basis; the file's name in the title without the
       quotes that would end gnuplot's string */
    char title[256];
    snprintf(title, sizeof title, "%s", bench_base_name(o->file));
    for (char *c = title; *c; c++)
        if (*c == '\'' || *c == '\\') *c = '_';
    fprintf(gp, "# in this folder: gnuplot -e \"set output 'basis.svg'\" basis.gp\n");
    for (int b = 0; b < HL_BASIS_COUNT; b++) {
        fprintf(gp, "$t%d << EOD\n", b);
        for (uint32_t i = 0; i < o->nterms; i++)
            if (res->M[b][i]) fprintf(gp, "%u %.6g\n", res->M[b][i], geo_mean(&res->l2[0][b][i], ne, sizeof res->l2[0] / sizeof(double)));
        fprintf(gp, "EOD\n$s%d << EOD\n", b);
        for (uint32_t i = 0; i < o->nterms; i++)
            if (res->M[b][i]) {
                double v[BB_MAX_ENVS];
                for (int e = 0; e < ne; e++) v[e] = ms_tot[((size_t)e * HL_BASIS_COUNT + b) * BB_MAX_TERMS + i];
                fprintf(gp, "%.6g %.6g\n", median(v, ne), geo_mean(&res->l2[0][b][i], ne, sizeof res->l2[0] / sizeof(double)));
            }
        fprintf(gp, "EOD\n$b%d << EOD\n", b);
        for (uint32_t j = 0; j < o->nbytes; j++)
            if (!isnan(res->l2b[0][b][j]))
                fprintf(gp, "%u %.6g\n", o->bytes[j], geo_mean(&res->l2b[0][b][j], ne, sizeof res->l2b[0] / sizeof(double)));
        fprintf(gp, "EOD\n");
    }
    fprintf(gp, "set terminal svg size 1320,520 dynamic font 'sans,11' noenhanced\n"
                "set logscale xy\nset grid\nset key bottom left font ',9'\n"
                "set ylabel 'relative L2, geometric mean over %d maps'\n"
                "set multiplot layout 1,3 title 'Lighting bases on %s, %u vertices'\n",
            ne, title, K);
    static const char *const panel[3][3] = {{"t", "terms M (whole rows)", "error against terms"},
                                            {"s", "ms per lighting change, plain C (median over maps)", "error against time"},
                                            {"b", "bytes per vertex", "equal bytes, M = 200, against own exact"}};
    for (int p = 0; p < 3; p++) {
        /* only the series with points (a basis may have no terms, or none
           of the counts asked), and a blank panel when none has any:
           gnuplot refuses a plot with no valid point */
        int any = 0;
        fprintf(gp, "set title '%s'\nset xlabel '%s'\n", panel[p][2], panel[p][1]);
        for (int b = 0; b < HL_BASIS_COUNT; b++) {
            int has = 0;
            for (uint32_t i = 0; p < 2 && i < o->nterms; i++) has |= res->M[b][i] != 0;
            for (uint32_t j = 0; p == 2 && j < o->nbytes; j++) has |= !isnan(res->l2b[0][b][j]);
            if (!has) continue;
            fprintf(gp, "%s$%s%d using 1:2 with linespoints pt %d ps 0.6 title '%s'", any ? ", \\\n     " : "plot ",
                    panel[p][0], b, b + 4, hl_basis_name((hl_basis)b));
            any = 1;
        }
        if (!any) fprintf(gp, "set label 1 'no data' at graph 0.5, graph 0.5 center\nplot [1:10] [1e-7:1] 2 notitle\nunset label 1");
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
}

/* Every setting at whole rows, in basis.md after the summaries. */
static void write_full(FILE *md, const bb_opts *o, char names[][256], const bb_results *res, const double *ms_tot)
{
    fprintf(md, "\n## Every setting, whole rows\n\n| map | basis | M | L2 | ms |\n|---|---|---:|---:|---:|\n");
    for (int e = 0; e < o->nenvs; e++)
        for (int b = 0; b < HL_BASIS_COUNT; b++)
            for (uint32_t i = 0; i < o->nterms; i++)
                if (res->M[b][i])
                    fprintf(md, "| %s | %s | %u | %.4f%% | %.3f |\n", names[e], hl_basis_name((hl_basis)b), res->M[b][i],
                            100 * res->l2[e][b][i], ms_tot[((size_t)e * HL_BASIS_COUNT + b) * BB_MAX_TERMS + i]);
    fprintf(md, "\nbasis.csv holds every setting, the rows cut to each budget included, with the max and unclamped errors.\n");
}

/* The environments, the comparison and the files. */
static hl_result run(hl_context *ctx, const bb_opts *o, hl_transport *t, bb_files *fs)
{
    const uint32_t V = t->info.vertex_count, K = o->K > V ? V : o->K;
    uint32_t *idx = malloc((size_t)K * 4);
    double *rgb = malloc((size_t)K * 3 * sizeof(double));
    double *ms_tot = calloc((size_t)BB_MAX_ENVS * HL_BASIS_COUNT * BB_MAX_TERMS, sizeof(double));
    bb_results *res = calloc(1, sizeof *res);
    char names[BB_MAX_ENVS][256];
    hl_env *envs[BB_MAX_ENVS] = {0};
    hl_basis_bench *bb = NULL;
    hl_result r = idx && rgb && ms_tot && res ? HL_OK : hl_tools_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    for (uint32_t k = 0; k < K && r == HL_OK; k++) idx[k] = (uint32_t)((uint64_t)k * V / K);
    for (int e = 0; e < o->nenvs && r == HL_OK; e++) {
        hl_sky_desc sky = {0};
        env_name(o->env_paths[e], names[e], sizeof names[e]);
        r = o->env_paths[e] ? cli_env_load(ctx, o->env_paths[e], o->layout, &envs[e], o->quiet)
                            : hl_env_create_sky(ctx, &sky, &envs[e]);
    }
    if (r == HL_OK) r = hl_basis_bench_create_ex(ctx, t, idx, K, o->order, o->cube, (hl_cube_rows_mode)o->cube_rows, &bb);
    if (r == HL_OK && !o->quiet)
        fprintf(stderr, "bench-basis: exact transport of %u vertices; paraboloids N = %u, cube faces of side %u, "
                        "spherical harmonics of order %u\n", K, t->info.N, hl_basis_bench_cube_side(bb), o->order);
    if (r == HL_OK) r = files_open(fs, ctx, o->outdir);
    if (r == HL_OK) {
        md_heading(fs->f[BB_MD], o, &t->info, K, hl_basis_bench_cube_side(bb));
        fprintf(fs->f[BB_CSV], "map,basis,terms,bytes,entries,l2,max,l2_unclamped,l2_own,ms\n");
    }
    for (int e = 0; e < o->nenvs && r == HL_OK; e++) {
        if (!o->quiet) fprintf(stderr, "bench-basis: %s\n", names[e]);
        r = measure_env(ctx, bb, envs[e], names[e], o, K, fs, rgb, res, e);
        for (int b = 0; b < HL_BASIS_COUNT && r == HL_OK; b++)
            for (uint32_t i = 0; i < o->nterms; i++)
                ms_tot[((size_t)e * HL_BASIS_COUNT + b) * BB_MAX_TERMS + i] =
                    res->ms[e][b][i][0] + res->ms[e][b][i][1] + res->ms[e][b][i][2];
    }
    if (r == HL_OK) {
        write_summary(fs, o, K, names, res, ms_tot);
        write_full(fs->f[BB_MD], o, names, res, ms_tot);
    }
    hl_basis_bench_destroy(bb);
    for (int e = 0; e < o->nenvs; e++) hl_env_destroy(envs[e]);
    free(idx);
    free(rgb);
    free(ms_tot);
    free(res);
    return r;
}

int cmd_bench_basis(int argc, char **argv)
{
    bb_opts o;
    int u = parse(argc, argv, &o);
    if (u >= 0) return u;
    hl_context_desc cd = {.backend = HL_BACKEND_REFERENCE, .threads = o.threads, .quiet = 1};
    hl_context *ctx = cli_context(&cd);
    if (!ctx) return 1;
    hl_transport *t = NULL;
    bb_files fs;
    memset(&fs, 0, sizeof fs);
    int rc = 0;
    hl_result r = hl_transport_load(ctx, o.file, &t);
    if (r == HL_OK && o.cube && t->info.C % o.cube) {
        fprintf(stderr, "haarlight: bench-basis: --cube-side %u: does not divide %s's cube side C = %u\n", o.cube, o.file,
                t->info.C);
        rc = 2;
    }
    /* the bases are compared on rows recast from the mesh: direct light */
    if (r == HL_OK && t->info.bounces && !o.quiet)
        fprintf(stderr, "bench-basis: %s holds %u bounce%s; the bases are compared on its mesh's direct transport, "
                "without them\n", o.file, t->info.bounces, t->info.bounces == 1 ? "" : "s");
    if (r == HL_OK && !rc && !cli_make_dir(o.outdir)) rc = 1; /* cli_make_dir has printed why */
    if (r == HL_OK && !rc) r = run(ctx, &o, t, &fs);
    if (!rc && (r == HL_OK || fs.f[0] || fs.f[1] || fs.f[2])) r = files_finish(&fs, ctx, r);
    if (!rc && r == HL_OK) {
        int plotted = 0;
        rc = bench_plot(o.outdir, "basis", &plotted);
        if (!o.quiet)
            fprintf(stderr, "bench-basis: wrote %s/basis.md, basis.csv and basis.gp%s\n", o.outdir,
                    plotted ? " and basis.svg" : " (no plot)");
    } else if (!rc) rc = cli_fail(ctx, r);
    hl_transport_destroy(t);
    cli_unwatch();
    hl_context_destroy(ctx);
    return rc;
}
