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
 *               independent of N and C and of the precompute's offset.
 * Writes bench.md, bench.csv and bench.svg (gnuplot) to the output folder.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cl_backend.h"
#include "cli.h"
#include "lighting.h"
#include "precompute.h"
#include "rays.h"
#include "twins.h"

static const char *const usage_bench =
    "usage: haarlight bench SCENE.hlt [SCENE2.hlt ...] [--env ENV.exr ...] [--sky] [options]\n"
    "\n"
    "Error against run time. For each file, environment, selection scheme and M,\n"
    "reports the error against the exact discrete result (untruncated, unquantised\n"
    "transport and lighting, float64) and against a converged continuous result\n"
    "(the map integrated directly with Embree visibility), and the median time of\n"
    "a full lighting change (environment to paraboloid, Haar, selection, dot\n"
    "products, read-back) on the OpenCL device and on the reference (the latter\n"
    "under the first environment: its time does not depend on the map). All files\n"
    "must come from the same mesh, N and C (e.g. different --quant or --energy).\n"
    "At M = 200 under the first environment it also gives each file's lighting\n"
    "changes per second, the time of taking a new map (resampling it onto the cell\n"
    "grid and uploading it), and the dot products' time against the device's read\n"
    "bandwidth (7 rounds of each, alternating; the fraction pairs each round's two),\n"
    "and the time of a change at M = all under the first map made subnormal against it.\n"
    "\n"
    "  --env ENV.exr        an environment (repeat for more); --sky adds the procedural sky\n"
    "  -o, --output DIR     where bench.md, bench.csv, bench.gp and bench.svg go (default\n"
    "                       bench-out; each is written whole or not at all)\n"
    "  --terms LIST         M values, comma-separated (default 25,50,100,200,500,1000,2000,all)\n"
    "  --select LIST        transport,area,unweighted (default all three; the plot shows\n"
    "                       the first)\n"
    "  --vertices K         vertices for the exact reference (default 1024; all if fewer)\n"
    "  --continuous K       vertices for the continuous reference (default 96)\n"
    "  --reps R             timed lighting changes per setting on OpenCL (default 15)\n"
    "  --ref-reps R         timed lighting changes per setting on the reference (default 3)\n"
    "  --no-ref-timing      skip timing the plain-C reference\n"
    "  --no-banding         skip the banding measure (it casts the rays of every ground\n"
    "                       vertex once)\n"
    "  --device cl:P:D      OpenCL device\n"
    "  --device-memory SIZE most device memory to use, e.g. 512M (default: the device's;\n"
    "                       also HL_DEVICE_MEMORY)\n";

#define MAX_FILES 8
#define MAX_ENVS 16
#define MAX_TERMS 16
#define MAX_REF_REPS 100
#define NEWMAP_REPS 15 /* at most, for the time of taking a new map */

typedef struct env_case {
    const char *name, *path;
    hl_env *env;
    double *exact;  /* K x 3 */
    double *cont;   /* K2 x 3 */
    double *ground; /* exact B of each ground vertex (G x 3), for banding */
} env_case;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* rounds of (read bandwidth, dot products) for the speed summary */
#define BENCH_ROUNDS 7
/* subnormal lighting may take at most this many times the normal time */
#define SUBNORMAL_LIMIT 2.0

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n ? v[n / 2] : 0.0;
}

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
        err[g] = hl_luminance(b[0], b[1], b[2]) - (0.2126 * x[0] + 0.7152 * x[1] + 0.0722 * x[2]);
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

/* The exact B (untruncated, unquantised transport, float64 sums) of every
 * ground vertex under each environment's full lighting Lw_all (nenvs x 3
 * x nc), rays cast in batches. */
static hl_result ground_exact(hl_context *ctx, hl_rt *rt, const hl_geom *g, const hl_mesh *m,
                              const hl_transport_info *in, float off, const float *Lw_all, env_case *envs,
                              int nenvs)
{
    const uint32_t first = in->object_vertex_count, G = in->vertex_count - first, nc = g->ncoef, batch = 128;
    uint8_t *vis = malloc((size_t)batch * g->ncube);
    float *T = malloc((size_t)nc * 4), *row = malloc((size_t)nc * 4);
    hl_result r = vis && T && row ? HL_OK : hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the ground rows");
    for (int e = 0; e < nenvs && r == HL_OK; e++) {
        envs[e].ground = calloc((size_t)G * 3, sizeof(double));
        if (!envs[e].ground) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the ground's exact colours");
    }
    const float scale = (float)(1.0 / (HL_PI * in->supersample * in->supersample));
    for (uint32_t b0 = 0; b0 < G && r == HL_OK; b0 += batch) {
        const uint32_t nb = G - b0 < batch ? G - b0 : batch;
        r = hl_rt_visibility(rt, g, m, first + b0, nb, in->supersample, off, vis, NULL);
        for (uint32_t k = 0; k < nb && r == HL_OK; k++) {
            const uint32_t v = first + b0 + k;
            hl_ref_cube2para(g, vis + (size_t)k * g->ncube, scale, m->normals + 3 * (size_t)v, T);
            hl_ref_haar(g, T, row);
            for (int e = 0; e < nenvs; e++)
                for (int c = 0; c < 3; c++) {
                    const float *l = Lw_all + ((size_t)e * 3 + c) * nc;
                    double sum = 0.0;
                    for (uint32_t i = 0; i < nc; i++) sum += (double)row[i] * l[i];
                    envs[e].ground[3 * ((size_t)b0 + k) + c] = sum * m->albedo[3 * (size_t)v + c];
                }
        }
    }
    free(vis);
    free(T);
    free(row);
    return r;
}

static const char *base_name(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

/* Untruncated lighting of env at rotation 0: R, G, B planes of Haar
 * coefficients in slot order. */
static hl_result full_lighting(hl_context *ctx, const hl_geom *g, const hl_light_geom *lg, const hl_env *env, float *Lw)
{
    float *cells = NULL, *Lp = malloc((size_t)g->ncoef * 12);
    if (!Lp) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    hl_result r = hl_env_to_cells(ctx, env, lg->wc, lg->hc, &cells);
    if (r == HL_OK) {
        hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, 0, 0.0f, g->ncoef, Lp);
        for (int c = 0; c < 3; c++) hl_ref_haar(g, Lp + (size_t)c * g->ncoef, Lw + (size_t)c * g->ncoef);
    }
    hl_free_big(cells);
    free(Lp);
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
    hl_result res = px && t[0] && t[1] ? HL_OK : hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
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
            double t0 = hl_now();
            res = hl_relighter_set_env(r, env[k]);
            if (res == HL_OK) res = hl_relighter_run(r, &d, B, NULL);
            t[k][i] = hl_now() - t0;
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

/* The continuous reference: sum over map pixels of L V max(0, n.w) dw / pi
 * for each of the K2 vertices, one occlusion ray per pixel from the vertex
 * itself (hl_rt_occluded_from_vertex). */
static hl_result continuous(hl_context *ctx, hl_rt *rt, const hl_mesh *m, const uint32_t *idx2, uint32_t K2,
                            const hl_env *env, double *out)
{
    const uint32_t W = env->width, H = env->height;
    const size_t np = (size_t)W * H;
    float *dir = malloc(np * 12);
    uint8_t *occ = malloc(np);
    uint32_t *pix = malloc(np * 4);
    if (!dir || !occ || !pix) {
        free(dir); free(occ); free(pix);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the continuous reference");
    }
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < K2 && r == HL_OK; k++) {
        const uint32_t v = idx2[k];
        const float *n = m->normals + 3 * (size_t)v;
        uint32_t cnt = 0;
        for (uint32_t y = 0; y < H; y++) {
            double th = HL_PI * (y + 0.5) / H;
            for (uint32_t x = 0; x < W; x++) {
                double ph = 2.0 * HL_PI * ((x + 0.5) / W - 0.5);
                float d[3] = {(float)(sin(th) * cos(ph)), (float)cos(th), (float)(sin(th) * sin(ph))};
                if (d[0] * n[0] + d[1] * n[1] + d[2] * n[2] <= 0.0f) continue;
                for (int c = 0; c < 3; c++) dir[3 * (size_t)cnt + c] = d[c];
                pix[cnt++] = y * W + x;
            }
        }
        /* rays from the vertex itself, its own triangles skipped: no
           offset, so the precompute's offset cannot hide its own errors */
        r = hl_rt_occluded_from_vertex(rt, v, cnt, dir, occ);
        double acc[3] = {0, 0, 0};
        for (uint32_t i = 0; i < cnt && r == HL_OK; i++) {
            if (occ[i]) continue;
            uint32_t y = pix[i] / W;
            double om = 2.0 * HL_PI / W * (cos(HL_PI * y / H) - cos(HL_PI * (y + 1) / H));
            const float *d = dir + 3 * (size_t)i;
            double cosn = (double)d[0] * n[0] + (double)d[1] * n[1] + (double)d[2] * n[2];
            for (int c = 0; c < 3; c++) acc[c] += env->rgb[3 * (size_t)pix[i] + c] * cosn * om;
        }
        for (int c = 0; c < 3; c++) out[3 * k + c] = acc[c] / HL_PI * m->albedo[3 * (size_t)v + c];
    }
    free(dir); free(occ); free(pix);
    return r;
}

/* The outputs: written as NAME.tmp.PID, renamed when complete. */
enum { OUT_CSV, OUT_MD, OUT_GP, OUT_COUNT };
static const char *const out_names[OUT_COUNT] = {"bench.csv", "bench.md", "bench.gp"};

static void out_path(char *buf, size_t n, const char *dir, const char *name, int tmp)
{
    if (tmp) snprintf(buf, n, "%s/%s.tmp.%ld", dir, name, (long)getpid());
    else snprintf(buf, n, "%s/%s", dir, name);
}

/* A gnuplot string literal: single quotes, a quote inside doubled. */
static void gp_string(FILE *gp, const char *s)
{
    fputc('\'', gp);
    for (; *s; s++) {
        if (*s == '\'') fputc('\'', gp);
        fputc(*s, gp);
    }
    fputc('\'', gp);
}

/* Runs gnuplot on DIR/bench.gp in DIR (no shell, so any folder name
 * works), its output to stderr, and renames the SVG into place when it
 * succeeds. Returns the exit status for the command: 0 also when gnuplot
 * is not installed (the tables stand without the plot), 1 when it fails. */
static int plot(const char *dir, int *plotted)
{
    char tmp[64], set[96];
    snprintf(tmp, sizeof tmp, "bench.svg.tmp.%ld", (long)getpid());
    snprintf(set, sizeof set, "set output '%s'", tmp);
    *plotted = 0;
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid == 0) {
        if (chdir(dir) != 0) _exit(126);
        dup2(2, 1);
        execlp("gnuplot", "gnuplot", "-e", set, "bench.gp", (char *)NULL);
        _exit(127);
    }
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid) {
        fprintf(stderr, "haarlight: bench: cannot run gnuplot: %s\n", strerror(errno));
        return 1;
    }
    char from[1200], to[1200];
    snprintf(from, sizeof from, "%s/%s", dir, tmp);
    snprintf(to, sizeof to, "%s/bench.svg", dir);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 127) {
        fprintf(stderr, "bench: gnuplot is not installed (apt-get install gnuplot-nox): %s not drawn\n", to);
        unlink(from);
        return 0;
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "haarlight: bench: gnuplot failed on %s/bench.gp: %s not drawn\n", dir, to);
        unlink(from);
        return 1;
    }
    if (rename(from, to) != 0) {
        fprintf(stderr, "haarlight: bench: %s: cannot write: %s\n", to, strerror(errno));
        unlink(from);
        return 1;
    }
    *plotted = 1;
    return 0;
}

int cmd_bench(int argc, char **argv)
{
    const char *usage = usage_bench, *files[MAX_FILES], *outdir = "bench-out";
    int nfiles = 0, nenvs = 0, want_sky = 0, ref_timing = 1, banding_on = 1;
    env_case envs[MAX_ENVS];
    memset(envs, 0, sizeof envs);
    uint32_t terms[MAX_TERMS] = {25, 50, 100, 200, 500, 1000, 2000, HL_TERMS_ALL}, nterms = 8;
    uint32_t selects[3] = {HL_SELECT_TRANSPORT, HL_SELECT_AREA, HL_SELECT_UNWEIGHTED}, nsel = 3;
    uint32_t K = 1024, K2 = 96, reps = 15, ref_reps = 3;
    hl_context_desc cd = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .quiet = 1};
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
#define NEED() do { if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a); v = argv[++i]; } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage, stdout); return 0; }
        else if (!strcmp(a, "--env")) {
            NEED();
            if (nenvs == MAX_ENVS) return usage_error(usage, "%s", "at most 16 environments");
            envs[nenvs].path = v;
            envs[nenvs++].name = base_name(v);
        } else if (!strcmp(a, "--sky")) want_sky = 1;
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED(); outdir = v; }
        else if (!strcmp(a, "--terms")) {
            NEED();
            nterms = 0;
            char buf[512];
            snprintf(buf, sizeof buf, "%s", v);
            for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
                if (nterms == MAX_TERMS) return usage_error(usage, "%s", "at most 16 values of M");
                if (!strcmp(tok, "all")) terms[nterms++] = HL_TERMS_ALL;
                else if (!parse_u32(tok, &terms[nterms]) || terms[nterms] < 1) return usage_error(usage, "--terms: bad value %s", tok);
                else nterms++;
            }
            if (!nterms) return usage_error(usage, "--terms %s: no values", v);
        } else if (!strcmp(a, "--select")) {
            NEED();
            nsel = 0;
            char buf[256];
            snprintf(buf, sizeof buf, "%s", v);
            for (char *tok = strtok(buf, ","); tok && nsel < 3; tok = strtok(NULL, ",")) {
                if (!parse_select(tok, &selects[nsel++])) return usage_error(usage, "--select: unknown scheme %s", tok);
            }
            if (!nsel) return usage_error(usage, "--select %s: no values", v);
        } else if (!strcmp(a, "--vertices")) { NEED(); if (!parse_u32(v, &K) || K < 1 || K > 65536) return usage_error(usage, "--vertices %s: expected 1 to 65536", v); }
        else if (!strcmp(a, "--continuous")) { NEED(); if (!parse_u32(v, &K2) || K2 > 4096) return usage_error(usage, "--continuous %s: expected 0 to 4096", v); }
        else if (!strcmp(a, "--reps")) { NEED(); if (!parse_u32(v, &reps) || reps < 1 || reps > 1000) return usage_error(usage, "--reps %s: expected 1 to 1000", v); }
        else if (!strcmp(a, "--ref-reps")) { NEED(); if (!parse_u32(v, &ref_reps) || ref_reps < 1 || ref_reps > MAX_REF_REPS) return usage_error(usage, "--ref-reps %s: expected 1 to 100", v); }
        else if (!strcmp(a, "--no-ref-timing")) ref_timing = 0;
        else if (!strcmp(a, "--no-banding")) banding_on = 0;
        else if (!strcmp(a, "--device-memory")) {
            NEED();
            if (!parse_device_memory(v, &cd)) return usage_error(usage, "--device-memory %s: expected a byte count such as 512M or 2G", v);
        } else if (!strcmp(a, "--device")) {
            NEED();
            if (!parse_device(v, &cd) || cd.backend != HL_BACKEND_OPENCL) return usage_error(usage, "--device %s: expected cl or cl:PLATFORM:DEVICE", v);
        } else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (nfiles == MAX_FILES) return usage_error(usage, "%s", "at most 8 transport files");
        else files[nfiles++] = a;
#undef NEED
    }
    if (!nfiles) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (want_sky || nenvs == 0) {
        if (nenvs == MAX_ENVS) return usage_error(usage, "%s", "at most 16 environments");
        envs[nenvs].name = "sky";
        envs[nenvs++].path = NULL;
    }
    if (mkdir(outdir, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "haarlight: %s: cannot create the output folder: %s\n", outdir, strerror(errno));
        return 1;
    }

    hl_context *cl = NULL, *ref = NULL;
    if (!cli_context_pair(&cd, &cl, &ref)) return 1;
    cli_watch(cl, ref);
    hl_transport *t[MAX_FILES] = {0};
    hl_geom *g = NULL;
    hl_light_geom *lg = NULL;
    hl_rt *rt = NULL;
    hl_result r = HL_OK;
    for (int f = 0; f < nfiles && r == HL_OK; f++) {
        r = hl_transport_load(ref, files[f], &t[f]);
        if (r == HL_OK && f > 0 &&
            (t[f]->info.N != t[0]->info.N || t[f]->info.C != t[0]->info.C || t[f]->info.vertex_count != t[0]->info.vertex_count ||
             memcmp(t[f]->mesh->positions, t[0]->mesh->positions, (size_t)t[0]->info.vertex_count * 12) != 0))
            r = hl_fail(ref, HL_ERR_INVALID_ARGUMENT, "%s: not the same mesh, N and C as %s", files[f], files[0]);
    }
    for (int e = 0; e < nenvs && r == HL_OK; e++) {
        hl_sky_desc sky = {0};
        r = envs[e].path ? cli_env_load(ref, envs[e].path, &envs[e].env, 0) : hl_env_create_sky(ref, &sky, &envs[e].env);
    }
    if (r == HL_OK) r = hl_geom_create(ref, t[0]->info.N, t[0]->info.C, &g);
    if (r == HL_OK) r = hl_light_geom_create(ref, g, &lg);
    if (r == HL_OK) r = hl_rt_create_filtered(ref, t[0]->mesh, &rt);
    if (r != HL_OK) {
        int rc = cli_fail(ref, r);
        for (int f = 0; f < nfiles; f++) hl_transport_destroy(t[f]);
        for (int e = 0; e < nenvs; e++) hl_env_destroy(envs[e].env);
        hl_geom_destroy(g);
        hl_light_geom_destroy(lg);
        cli_unwatch();
        hl_context_destroy(cl);
        hl_context_destroy(ref);
        return rc;
    }
    const hl_transport_info *in = &t[0]->info;
    const hl_mesh *m = t[0]->mesh;
    const uint32_t V = in->vertex_count, nc = g->ncoef, nb = g->nblocks;
    if (K > V) K = V;
    if (K2 > K) K2 = K;
    uint32_t *idx = malloc((size_t)K * 4), *idx2 = malloc((size_t)(K2 ? K2 : 1) * 4);
    for (uint32_t k = 0; k < K; k++) idx[k] = (uint32_t)((uint64_t)k * V / K);
    for (uint32_t k = 0; k < K2; k++) idx2[k] = idx[(uint64_t)k * K / K2];
    const float off = in->ray_offset * hl_mesh_query_diagonal(m);

    /* raw transport of the K vertices: rays, then the untruncated stages */
    fprintf(stderr, "bench: exact transport of %u vertices, continuous reference on %u\n", K, K2);
    float *raw = malloc((size_t)K * nc * 4), *T = malloc((size_t)nc * 4);
    uint8_t *vis = malloc(g->ncube);
    const float scale = (float)(1.0 / (HL_PI * in->supersample * in->supersample));
    for (uint32_t k = 0; k < K && r == HL_OK; k++) {
        r = hl_rt_visibility(rt, g, m, idx[k], 1, in->supersample, off, vis, NULL);
        hl_ref_cube2para(g, vis, scale, m->normals + 3 * (size_t)idx[k], T);
        hl_ref_haar(g, T, raw + (size_t)k * nc);
    }
    free(vis);
    free(T);
    float *Lw_all = malloc((size_t)nenvs * nc * 12);
    if (r == HL_OK && !Lw_all) r = hl_fail(ref, HL_ERR_OUT_OF_MEMORY, "out of memory for the lighting");
    for (int e = 0; e < nenvs && r == HL_OK; e++) {
        float *Lw = Lw_all + (size_t)e * nc * 3;
        envs[e].exact = calloc((size_t)K * 3, sizeof(double));
        envs[e].cont = calloc((size_t)(K2 ? K2 : 1) * 3, sizeof(double));
        r = full_lighting(ref, g, lg, envs[e].env, Lw);
        for (uint32_t k = 0; k < K && r == HL_OK; k++)
            for (int c = 0; c < 3; c++) {
                double s = 0.0;
                const float *row = raw + (size_t)k * nc, *l = Lw + (size_t)c * nc;
                for (uint32_t i = 0; i < nc; i++) s += (double)row[i] * l[i];
                envs[e].exact[3 * k + c] = s * m->albedo[3 * (size_t)idx[k] + c];
            }
        if (r == HL_OK && K2) r = continuous(ref, rt, m, idx2, K2, envs[e].env, envs[e].cont);
    }
    free(raw);
    const uint32_t gside = banding_on ? ground_side(in) : 0;
    if (r == HL_OK && gside) {
        fprintf(stderr, "bench: exact colours of the %u x %u ground, for banding\n", gside, gside);
        r = ground_exact(ref, rt, g, m, in, off, Lw_all, envs, nenvs);
    }

    /* the outputs, under temporary names until they are complete */
    char tmp[OUT_COUNT][1200];
    for (int o = 0; o < OUT_COUNT; o++) out_path(tmp[o], sizeof tmp[o], outdir, out_names[o], 1);
    FILE *csv = r == HL_OK ? fopen(tmp[OUT_CSV], "w") : NULL;
    if (r == HL_OK && !csv) r = hl_fail(ref, HL_ERR_IO, "%s: cannot write: %s", tmp[OUT_CSV], strerror(errno));
    FILE *md = r == HL_OK ? fopen(tmp[OUT_MD], "w") : NULL;
    if (r == HL_OK && !md) r = hl_fail(ref, HL_ERR_IO, "%s: cannot write: %s", tmp[OUT_MD], strerror(errno));
    if (r == HL_OK) {
        fprintf(csv, "file,quant,coef_per_vertex,transport_bytes,env,select,M,kept,energy_kept,error_bound,blocks_skipped,"
                     "l2_exact,max_exact,l2_continuous,max_continuous,cl_ms,ref_ms,l2_exact_unclamped,max_exact_unclamped,"
                     "negative_vertices,banding\n");
        fprintf(md, "# Error against run time\n\n"
                    "Mesh: %u vertices (%u object, %u ground); N = %u, C = %u. Device: %s; %d host threads.\n"
                    "Errors are over %u vertices spread over the mesh (exact: untruncated, unquantised transport and\n"
                    "lighting in float64) and %u of them (continuous: the map integrated directly, one Embree ray per\n"
                    "pixel from the vertex itself, its own triangles skipped, no ray offset). L2 is relative to the reference's L2 norm; max is the worst vertex relative to the\n"
                    "brightest. Times are the median of %u full lighting changes (environment to paraboloid, Haar,\n"
                    "selection, dot products, read-back of all vertex colours) on OpenCL, and of %u on the reference\n"
                    "(under the first map only: its time does not depend on the map). Colours below zero are\n"
                    "clamped to 0, as every output is; \"unclamped\" is the L2 error of the sums before that\n"
                    "clamp, and \"clamped\" counts the vertices it changed (of all %u). \"Banding\" is the RMS of the\n"
                    "5-point Laplacian of the ground's luminance error against its exact colours (every ground\n"
                    "vertex) after a 5 x 5 box average, over the RMS of the exact luminance: contour steps\n"
                    "along the ground raise it, noise from cell to cell hardly does.\n\n",
                V, in->object_vertex_count, V - in->object_vertex_count, in->N, in->C, hl_context_device_name(cl), hl_context_threads(cl),
                K, K2, reps, ref_reps, V);
        fprintf(md, "| file | env | select | M | kept | energy kept | bound | blocks skipped | L2 exact | max exact | L2 unclamped | clamped | banding | L2 cont. | max cont. | OpenCL ms | ref ms | MB |\n"
                    "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    }
    float *B = malloc((size_t)V * 12), *Braw = malloc((size_t)V * 12);
    if (r == HL_OK && (!B || !Braw)) r = hl_fail(ref, HL_ERR_OUT_OF_MEMORY, "out of memory for %u vertex colours", V);
    double ref_ms[MAX_FILES][3][MAX_TERMS];
    double summary_rate[MAX_FILES], summary_dot[MAX_FILES], summary_bytes[MAX_FILES], summary_bw[MAX_FILES];
    double summary_newmap[MAX_FILES];
    double summary_frac[MAX_FILES][3]; /* median, least, most */
    double sub_ms[MAX_FILES][2][2];     /* [file][OpenCL, reference][normal, subnormal] */
    /* series for the plot: per file and environment, the first selection scheme */
    FILE *gp = NULL;
    if (r == HL_OK) {
        gp = fopen(tmp[OUT_GP], "w");
        if (!gp) r = hl_fail(ref, HL_ERR_IO, "%s: cannot write: %s", tmp[OUT_GP], strerror(errno));
        else fprintf(gp, "# in this folder: gnuplot -e \"set output 'bench.svg'\" bench.gp\n");
    }
    int nseries = 0;
    for (int f = 0; f < nfiles && r == HL_OK; f++) {
        hl_relighter *rc = NULL, *rr = NULL;
        r = hl_relighter_create(cl, t[f], &rc);
        if (r == HL_OK && ref_timing) r = hl_relighter_create(ref, t[f], &rr);
        if (r != HL_OK) { hl_relighter_destroy(rc); break; }
        const hl_transport_info *fi = &t[f]->info;
        double bytes = 2.0 * (double)fi->coefficients_kept + (double)V * (8 + 2.0 * nb);
        for (int e = 0; e < nenvs && r == HL_OK; e++) {
            fprintf(stderr, "bench: %s under %s\n", base_name(files[f]), envs[e].name);
            r = hl_relighter_set_env(rc, envs[e].env);
            if (r == HL_OK && rr && e == 0) r = hl_relighter_set_env(rr, envs[e].env);
            if (r == HL_OK && f == 0 && e == 0) r = hl_relighter_run(rc, NULL, B, NULL); /* PoCL compiles lazily */
            fprintf(gp, "$s%d << EOD\n", nseries);
            for (uint32_t s = 0; s < nsel && r == HL_OK; s++)
                for (uint32_t mi = 0; mi < nterms && r == HL_OK; mi++) {
                    hl_relight_desc d = {.terms = terms[mi], .select = selects[s]};
                    hl_relight_stats st;
                    double times[1000];
                    for (uint32_t k = 0; k < reps && r == HL_OK; k++) {
                        d.rotate_deg = 1e-3f * (float)(k + 1); /* a new lighting each time */
                        r = hl_relighter_run(rc, &d, B, &st);
                        times[k] = st.seconds;
                    }
                    double cl_ms = 1e3 * median(times, (int)reps);
                    /* the reference's time does not depend on the map: timed on the first */
                    if (r == HL_OK && rr && e == 0) {
                        double ref_t[MAX_REF_REPS];
                        for (uint32_t k = 0; k < ref_reps && r == HL_OK; k++) {
                            d.rotate_deg = 0.5f + 1e-3f * (float)k;
                            r = hl_relighter_run(rr, &d, B, &st);
                            ref_t[k] = st.seconds;
                        }
                        if (r == HL_OK) ref_ms[f][s][mi] = 1e3 * median(ref_t, (int)ref_reps);
                    }
                    d.rotate_deg = 0.0f;
                    hl_relight_desc raw = d;
                    raw.keep_negative = 1;
                    if (r == HL_OK) r = hl_relighter_run(rc, &raw, Braw, NULL);
                    if (r == HL_OK) r = hl_relighter_run(rc, &d, B, &st);
                    if (r != HL_OK) break;
                    double l2e, mxe, l2u, mxu, l2c = NAN, mxc = NAN;
                    errors(B, idx, K, envs[e].exact, &l2e, &mxe);
                    errors(Braw, idx, K, envs[e].exact, &l2u, &mxu);
                    const double band = gside ? banding(B, in->object_vertex_count, gside, envs[e].ground)
                                                             : NAN;
                    if (K2) errors(B, idx2, K2, envs[e].cont, &l2c, &mxc);
                    double rms = rr ? ref_ms[f][s][mi] : NAN;
                    char mstr[16];
                    if (terms[mi] == HL_TERMS_ALL) snprintf(mstr, sizeof mstr, "all");
                    else snprintf(mstr, sizeof mstr, "%u", terms[mi]);
                    fprintf(csv, "%s,%s,%.1f,%.0f,%s,%s,%s,%u,%.8f,%.6g,%.4f,%.6g,%.6g,%.6g,%.6g,%.4f,%.2f,%.6g,%.6g,%u,%.6g\n",
                            base_name(files[f]), fi->quant == HL_QUANT_LOG8 ? "log8" : fi->quant == HL_QUANT_SQRT8 ? "sqrt8" : "linear8",
                            (double)fi->coefficients_kept / V, bytes, envs[e].name, select_name(selects[s]), mstr,
                            st.terms_kept, st.energy_kept, st.error_bound, st.blocks_skipped, l2e, mxe, l2c, mxc, cl_ms,
                            rms, l2u, mxu, st.negative_vertices, band);
                    char refcell[32] = "not timed";
                    if (rr) snprintf(refcell, sizeof refcell, "%.1f", rms);
                    fprintf(md, "| %s | %s | %s | %s | %u | %.6f | %.3g | %.0f%% | %.3f%% | %.3f%% | %.3f%% | %u | %.4f | %.3f%% | %.3f%% | %.3f | %s | %.1f |\n",
                            base_name(files[f]), envs[e].name, select_name(selects[s]), mstr, st.terms_kept, st.energy_kept,
                            st.error_bound, 100 * st.blocks_skipped, 100 * l2e, 100 * mxe, 100 * l2u,
                            st.negative_vertices, band, 100 * l2c, 100 * mxc, cl_ms, refcell, bytes / 1e6);
                    if (selects[s] == selects[0]) fprintf(gp, "%.5f %.6g %s\n", cl_ms, l2e, mstr);
                    fflush(csv);
                    fflush(md);
                }
            fprintf(gp, "EOD\n");
            nseries++;
        }
        /* a new map: resampled onto the cell grid on the host and uploaded
           (what a change of map costs before its lighting change) */
        double newmap[NEWMAP_REPS];
        const uint32_t nnew = reps < NEWMAP_REPS ? reps : NEWMAP_REPS;
        for (uint32_t k = 0; k < nnew && r == HL_OK; k++) {
            double t0 = hl_now();
            r = hl_relighter_set_env(rc, envs[0].env);
            newmap[k] = hl_now() - t0;
        }
        summary_newmap[f] = r == HL_OK ? median(newmap, (int)nnew) : 0.0;
        /* full lighting changes, then the dot products alone, at M = 200 with
           the default selection, under the first environment */
        hl_relight_desc d = {.terms = 200, .select = HL_SELECT_DEFAULT, .rotate_deg = 0.25f};
        double times[1000];
        for (uint32_t k = 0; k < reps && r == HL_OK; k++) {
            d.rotate_deg = 0.25f + 1e-3f * (float)k;
            hl_relight_stats st;
            r = hl_relighter_run(rc, &d, B, &st);
            times[k] = st.seconds;
        }
        summary_rate[f] = r == HL_OK ? 1.0 / median(times, (int)reps) : 0.0;
        /* the dot products alone and the read bandwidth, in alternating
           rounds: each fraction pairs two measurements taken a moment
           apart, so that a slow spell of the machine slows both */
        double dots[BENCH_ROUNDS], bws[BENCH_ROUNDS], frac[BENCH_ROUNDS];
        summary_bytes[f] = 0.0;
        if (r == HL_OK) r = hl_cl_light_bytes_read(hl_relighter_device(rc), &summary_bytes[f]);
        for (int k = 0; k < BENCH_ROUNDS && r == HL_OK; k++) {
            r = hl_cl_read_bandwidth(cl, (size_t)256 << 20, 3, &bws[k]);
            if (r == HL_OK) r = hl_cl_light_time_relight(hl_relighter_device(rc), 20, &dots[k]);
            frac[k] = r == HL_OK && dots[k] > 0 && bws[k] > 0 ? summary_bytes[f] / dots[k] / bws[k] : 0.0;
        }
        if (r == HL_OK) {
            summary_dot[f] = median(dots, BENCH_ROUNDS);
            summary_bw[f] = median(bws, BENCH_ROUNDS);
            summary_frac[f][0] = median(frac, BENCH_ROUNDS); /* sorts */
            summary_frac[f][1] = frac[0];
            summary_frac[f][2] = frac[BENCH_ROUNDS - 1];
        }
        /* subnormal lighting, on both backends */
        for (int b = 0; b < 2 && r == HL_OK; b++) {
            hl_relighter *rb = b ? rr : rc;
            sub_ms[f][b][0] = sub_ms[f][b][1] = NAN;
            if (!rb) continue;
            fprintf(stderr, "bench: %s: subnormal lighting on %s\n", base_name(files[f]), b ? "the reference" : "OpenCL");
            double tn = 0, ts = 0;
            r = subnormal_times(b ? ref : cl, rb, envs[0].env, b ? 3 : reps, B, &tn, &ts);
            sub_ms[f][b][0] = 1e3 * tn;
            sub_ms[f][b][1] = 1e3 * ts;
        }
        hl_relighter_destroy(rc);
        hl_relighter_destroy(rr);
    }
    if (r == HL_OK) {
        fprintf(md, "\n## Speed at M = 200 (%s selection, the default), %s\n\n", select_name(HL_SELECT_TRANSPORT),
                envs[0].name);
        fprintf(md, "Lighting changes per second: the median of %u full changes. A new map: resampling it onto the\n"
                    "cell grid on the host and uploading it, before its lighting change (median of %u). Then %d\n"
                    "rounds, each the device's read bandwidth (a kernel reading 256 MiB, held as the transport columns\n"
                    "are, with huge pages advised on a CPU device; median of 3 passes) and the dot products alone (mean\n"
                    "of 20 launches); the fraction is the bytes they read over their time over the bandwidth of the\n"
                    "same round. Medians over the rounds, and the fraction's range.\n\n", reps,
                reps < NEWMAP_REPS ? reps : NEWMAP_REPS, BENCH_ROUNDS);
        fprintf(md, "| file | lighting changes per second | new map | dot products alone | bytes they read | read bandwidth | "
                    "fraction of read bandwidth | range |\n|---|---|---|---|---|---|---|---|\n");
        for (int f = 0; f < nfiles; f++)
            fprintf(md, "| %s | %.0f | %.2f ms | %.3f ms | %.1f MB | %.1f GB/s | %.2f | %.2f to %.2f |\n",
                    base_name(files[f]), summary_rate[f], 1e3 * summary_newmap[f], 1e3 * summary_dot[f],
                    summary_bytes[f] * 1e-6, summary_bw[f] * 1e-9, summary_frac[f][0], summary_frac[f][1],
                    summary_frac[f][2]);
        fprintf(md, "\n## Subnormal lighting\n\n"
                    "A new map and a full lighting change at M = all under %s scaled so that its brightest channel is\n"
                    "1e-38 (every pixel subnormal in float, or zero), against the same under %s itself, alternating;\n"
                    "medians of %u changes on OpenCL and 3 on the reference. The limit is %g times the normal map's\n"
                    "time, measured in the same run.\n\n"
                    "| file | device | normal | subnormal | ratio | limit | |\n|---|---|---|---|---|---|---|\n",
                envs[0].name, envs[0].name, reps, SUBNORMAL_LIMIT);
        for (int f = 0; f < nfiles; f++)
            for (int b = 0; b < 2; b++) {
                if (isnan(sub_ms[f][b][0])) continue;
                double ratio = sub_ms[f][b][1] / sub_ms[f][b][0];
                const char *verdict = ratio <= SUBNORMAL_LIMIT ? "within" : "over";
                fprintf(md, "| %s | %s | %.2f ms | %.2f ms | %.2f | %g | %s |\n", base_name(files[f]),
                        b ? "reference" : "OpenCL", sub_ms[f][b][0], sub_ms[f][b][1], ratio, SUBNORMAL_LIMIT, verdict);
                printf("bench: %s: subnormal lighting on %s: %.2f ms against %.2f ms = %.2f of normal (limit %g: %s)\n",
                       base_name(files[f]), b ? "the reference" : "OpenCL", sub_ms[f][b][1], sub_ms[f][b][0], ratio,
                       SUBNORMAL_LIMIT, verdict);
            }
        fprintf(md, "\nFor comparison: the 2003 paper relit 160k vertices at 3.5 to 9.8 Hz for 200 to 40 terms on a 2.8 GHz P4,\n"
                    "and reported 2.2%% error with 200 wavelet terms (13.4%% with 200 spherical-harmonic terms) on its hardest\n"
                    "scene; the seed report relit 40k vertices at 3 fps.\n");
        for (int f = 0; f < nfiles; f++)
            printf("bench: %s: %.0f lighting changes/s at M = 200 (a new map first: %.2f ms); dot products %.3f ms for "
                   "%.1f MB = %.2f (%.2f to %.2f) of the read bandwidth (%.1f GB/s)\n",
                   base_name(files[f]), summary_rate[f], 1e3 * summary_newmap[f], 1e3 * summary_dot[f],
                   summary_bytes[f] * 1e-6, summary_frac[f][0], summary_frac[f][1], summary_frac[f][2],
                   summary_bw[f] * 1e-9);
        /* one panel per transport file, a line per environment */
        char mlist[48], m0[16], m1[16];
        snprintf(m0, sizeof m0, "%u", terms[0]);
        if (terms[nterms - 1] == HL_TERMS_ALL) snprintf(m1, sizeof m1, "all");
        else snprintf(m1, sizeof m1, "%u", terms[nterms - 1]);
        if (nterms > 1) snprintf(mlist, sizeof mlist, "%s ... %s", m0, m1);
        else snprintf(mlist, sizeof mlist, "%s", m0);
        /* no "set output": plot() names it, so that the SVG, too, is
           written under a temporary name (the script's first line says how
           to run it by hand) */
        fprintf(gp, "set terminal svg size %d,560 dynamic font 'sans,11' noenhanced\n", 420 * nfiles + 60);
        fprintf(gp, "set logscale xy\nset grid\nset key bottom left font ',9'\n"
                    "set xlabel 'time per lighting change, OpenCL (ms)'\n"
                    "set ylabel 'relative L2 error vs exact discrete'\n"
                    "set multiplot layout 1,%d title 'Error against run time, %s selection, M = %s'\n",
                nfiles, select_name(selects[0]), mlist);
        for (int f = 0; f < nfiles; f++) {
            fprintf(gp, "set title ");
            gp_string(gp, base_name(files[f]));
            fprintf(gp, "\nplot ");
            for (int e = 0; e < nenvs; e++) {
                fprintf(gp, "%s$s%d using 1:2 with linespoints pt 7 ps 0.5 title ", e ? ", \\\n     " : "", f * nenvs + e);
                gp_string(gp, envs[e].name);
            }
            fprintf(gp, "\n");
        }
        fprintf(gp, "unset multiplot\n");
        fprintf(gp, "\n");
    }
    FILE *outs[OUT_COUNT] = {csv, md, gp};
    for (int o = 0; o < OUT_COUNT; o++)
        if (outs[o] && fclose(outs[o]) != 0 && r == HL_OK)
            r = hl_fail(ref, HL_ERR_IO, "%s: cannot write: %s", tmp[o], strerror(errno));
    int rc = 0, plotted = 0;
    char final[1200];
    for (int o = 0; o < OUT_COUNT && r == HL_OK; o++) {
        out_path(final, sizeof final, outdir, out_names[o], 0);
        if (rename(tmp[o], final) != 0) r = hl_fail(ref, HL_ERR_IO, "%s: cannot write: %s", final, strerror(errno));
    }
    if (r != HL_OK) {
        for (int o = 0; o < OUT_COUNT; o++) unlink(tmp[o]);
        rc = cli_fail(hl_context_last_error(cl)[0] ? cl : ref, r);
    } else {
        rc = plot(outdir, &plotted);
        if (plotted) printf("bench: wrote %s/bench.md, %s/bench.csv and %s/bench.svg\n", outdir, outdir, outdir);
        else printf("bench: wrote %s/bench.md and %s/bench.csv (no plot)\n", outdir, outdir);
    }
    free(B);
    free(Braw);
    free(Lw_all);
    free(idx);
    free(idx2);
    for (int e = 0; e < nenvs; e++) {
        hl_env_destroy(envs[e].env);
        free(envs[e].exact);
        free(envs[e].cont);
        free(envs[e].ground);
    }
    for (int f = 0; f < nfiles; f++) hl_transport_destroy(t[f]);
    hl_rt_destroy(rt);
    hl_light_geom_destroy(lg);
    hl_geom_destroy(g);
    cli_unwatch();
    hl_context_destroy(cl);
    hl_context_destroy(ref);
    return rc;
}
