/* bench_out.c - what `haarlight bench` writes: bench.csv and bench.md
 * (their headings here, their rows from bench.c), the speed and subnormal
 * summaries, bench.gp and the SVG gnuplot draws from it; and the same
 * files of `haarlight bench-dynamic` (its table, verdicts and plot, from
 * the rows bench_dynamic.c measured). Every file is written under a
 * temporary name and renamed when complete.
 *
 * Depends on the public API, haarlight_tools.h (failures recorded on a
 * context) and POSIX (fork and exec of gnuplot).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cli.h"
#include "haarlight_tools.h"

static const char *const out_names[BENCH_OUTS] = {"bench.csv", "bench.md", "bench.gp"};

const char *bench_base_name(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

static void out_path(char *buf, size_t n, const char *dir, const char *name, int tmp)
{
    if (tmp) snprintf(buf, n, "%s/%s.tmp.%ld", dir, name, (long)getpid());
    else snprintf(buf, n, "%s/%s", dir, name);
}

void bench_out_names(bench_out *o, const char *dir)
{
    memset(o, 0, sizeof *o);
    o->dir = dir;
    for (int k = 0; k < BENCH_OUTS; k++) out_path(o->tmp[k], sizeof o->tmp[k], dir, out_names[k], 1);
}

static void md_heading(FILE *md, hl_context *cl, const hl_transport_info *in, uint32_t K, uint32_t K2, uint32_t reps,
                       uint32_t ref_reps)
{
    const uint32_t V = in->vertex_count;
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
            V, in->object_vertex_count, V - in->object_vertex_count, in->N, in->C, hl_context_device_name(cl),
            hl_context_threads(cl), K, K2, reps, ref_reps, V);
}

hl_result bench_out_open(bench_out *o, hl_context *ref, hl_context *cl, const hl_transport_info *in, uint32_t K,
                         uint32_t K2, uint32_t reps, uint32_t ref_reps)
{
    o->f[BENCH_CSV] = fopen(o->tmp[BENCH_CSV], "w");
    if (!o->f[BENCH_CSV]) return hl_tools_fail(ref, HL_ERR_IO, "%s: cannot write: %s", o->tmp[BENCH_CSV], strerror(errno));
    o->f[BENCH_MD] = fopen(o->tmp[BENCH_MD], "w");
    if (!o->f[BENCH_MD]) return hl_tools_fail(ref, HL_ERR_IO, "%s: cannot write: %s", o->tmp[BENCH_MD], strerror(errno));
    fprintf(o->f[BENCH_CSV], "file,quant,coef_per_vertex,transport_bytes,env,select,M,kept,energy_kept,error_bound,blocks_skipped,"
                             "l2_exact,max_exact,l2_continuous,max_continuous,cl_ms,ref_ms,l2_exact_unclamped,max_exact_unclamped,"
                             "negative_vertices,banding,reference,reference_noise\n");
    md_heading(o->f[BENCH_MD], cl, in, K, K2, reps, ref_reps);
    return HL_OK;
}

void bench_ref_name(char *buf, size_t n, uint32_t B, uint32_t rays)
{
    if (B) snprintf(buf, n, "exact (direct + %u bounce%s, %u rays)", B, B == 1 ? "" : "s", rays);
    else snprintf(buf, n, "exact (direct)");
}

void bench_out_references(bench_out *o, const char *const *files, const uint32_t *bounces, int nfiles,
                          uint32_t rays, const bench_env *envs, int nenvs)
{
    FILE *md = o->f[BENCH_MD];
    int any = 0;
    fprintf(md, "References: ");
    for (int f = 0; f < nfiles; f++) {
        char name[96];
        bench_ref_name(name, sizeof name, bounces[f], rays);
        fprintf(md, "%s%s against %s", f ? "; " : "", bench_base_name(files[f]), name);
        any |= bounces[f] > 0;
    }
    fprintf(md, ".\n\n");
    if (any) {
        fprintf(md, "The bounced reference: the direct exact light of every vertex (no albedo), then each bounce\n"
                    "gathered in float64 from %u cosine-weighted rays a vertex, fresh for each bounce, with each\n"
                    "channel's own albedo (every vertex for the bounces before the last, the measured ones for the\n"
                    "last); the colour is the albedo times the sum of the bounces (docs/BOUNCES.md). Its continuous\n"
                    "and banding columns are not measured (those references are direct light only). Its own noise,\n"
                    "relative to its L2 norm over the measured vertices: the gathers' standard errors, and a bound\n"
                    "that adds the noise each gather reads from the bounce before:\n\n| bounces | ", rays);
        for (int e = 0; e < nenvs; e++) fprintf(md, "%s | ", envs[e].name);
        fprintf(md, "\n|---|");
        for (int e = 0; e < nenvs; e++) fprintf(md, "---|");
        fprintf(md, "\n");
        for (uint32_t B = 1; B <= HL_MAX_BOUNCES; B++) {
            if (!envs[0].exact_b[B]) continue;
            fprintf(md, "| %u | ", B);
            for (int e = 0; e < nenvs; e++)
                fprintf(md, "%.3f%% (bound %.3f%%) | ", 100 * envs[e].noise_own[B], 100 * envs[e].noise_bound[B]);
            fprintf(md, "\n");
        }
        fprintf(md, "\n");
    }
    fprintf(md, "| file | env | select | M | kept | energy kept | bound | blocks skipped | L2 exact | max exact | L2 unclamped | clamped | banding | L2 cont. | max cont. | OpenCL ms | ref ms | MB |\n"
                "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
}

hl_result bench_out_open_plot(bench_out *o, hl_context *ref)
{
    o->f[BENCH_GP] = fopen(o->tmp[BENCH_GP], "w");
    if (!o->f[BENCH_GP]) return hl_tools_fail(ref, HL_ERR_IO, "%s: cannot write: %s", o->tmp[BENCH_GP], strerror(errno));
    fprintf(o->f[BENCH_GP], "# in this folder: gnuplot -e \"set output 'bench.svg'\" bench.gp\n");
    return HL_OK;
}

/* ---------------------------------------------------------------- summary */

static void speed_table(FILE *md, const bench_run *run)
{
    fprintf(md, "\n## Speed at M = 200 (%s selection, the default), %s\n\n", select_name(HL_SELECT_TRANSPORT),
            run->envs[0].name);
    fprintf(md, "Lighting changes per second: the median of %u full changes. A new map: resampling it onto the\n"
                "cell grid on the host and uploading it, before its lighting change (median of %u). Then %d\n"
                "rounds, each the device's read bandwidth (a kernel reading 256 MiB, held as the transport columns\n"
                "are, with huge pages advised on a CPU device; median of 3 passes) and the dot products alone (mean\n"
                "of 20 launches); the fraction is the bytes they read over their time over the bandwidth of the\n"
                "same round. Medians over the rounds, and the fraction's range.\n\n", run->reps,
            run->reps < BENCH_NEWMAP_REPS ? run->reps : BENCH_NEWMAP_REPS, BENCH_ROUNDS);
    fprintf(md, "| file | lighting changes per second | new map | dot products alone | bytes they read | read bandwidth | "
                "fraction of read bandwidth | range |\n|---|---|---|---|---|---|---|---|\n");
    for (int f = 0; f < run->nfiles; f++) {
        const bench_speed *s = &run->speed[f];
        fprintf(md, "| %s | %.0f | %.2f ms | %.3f ms | %.1f MB | %.1f GB/s | %.2f | %.2f to %.2f |\n",
                bench_base_name(run->files[f]), s->rate, 1e3 * s->newmap, 1e3 * s->dot, s->bytes * 1e-6,
                s->bw * 1e-9, s->frac[0], s->frac[1], s->frac[2]);
    }
}

/* `bench --surroundings`: lighting captured from them, against its goal. */
static void capture_table(FILE *md, const bench_run *run)
{
    if (!run->speed[0].cap_triangles) return;
    fprintf(md, "\n## Lighting captured from surroundings, M = 200, over %s\n\n"
                "Lighting changes per second where each change is a new capture (every body of the surroundings\n"
                "turned a further half degree about +Y): the median of %u. An unchanged frame: a run in which\n"
                "nothing moved (median of %u). Then %d rounds of the capture alone and the dot products alone\n"
                "(means of 20 launches each); medians over the rounds. Goal: %.0f changes per second, and the\n"
                "capture cheaper than the dot products.\n\n"
                "| file | triangles | capture points | changes per second | goal | unchanged frame | capture alone | "
                "dot products alone | capture / dot products |\n|---|---|---|---|---|---|---|---|---|\n",
            run->envs[0].name, run->reps, run->reps, BENCH_ROUNDS, BENCH_CAPTURE_GOAL);
    for (int f = 0; f < run->nfiles; f++) {
        const bench_speed *s = &run->speed[f];
        const char *met = s->cap_rate >= BENCH_CAPTURE_GOAL ? "met" : "not met";
        fprintf(md, "| %s | %u | %u | %.0f | %s | %.1f us | %.3f ms | %.3f ms | %.2f |\n", bench_base_name(run->files[f]),
                s->cap_triangles, s->cap_probes, s->cap_rate, met, 1e6 * s->cap_same, s->cap_ms, s->cap_dot_ms, s->cap_ratio);
        printf("bench: %s: %.0f lighting changes/s with a new capture of %u triangles from %u point(s) each (goal %.0f: %s); "
               "unchanged frame %.1f us; capture %.3f ms against dot products %.3f ms (%.2f)\n",
               bench_base_name(run->files[f]), s->cap_rate, s->cap_triangles, s->cap_probes, BENCH_CAPTURE_GOAL, met,
               1e6 * s->cap_same, s->cap_ms, s->cap_dot_ms, s->cap_ratio);
    }
}

static void subnormal_table(FILE *md, const bench_run *run)
{
    fprintf(md, "\n## Subnormal lighting\n\n"
                "A new map and a full lighting change at M = all under %s scaled so that its brightest channel is\n"
                "1e-38 (every pixel subnormal in float, or zero), against the same under %s itself, alternating;\n"
                "medians of %u changes on OpenCL and 3 on the reference. The limit is %g times the normal map's\n"
                "time, measured in the same run.\n\n"
                "| file | device | normal | subnormal | ratio | limit | |\n|---|---|---|---|---|---|---|\n",
            run->envs[0].name, run->envs[0].name, run->reps, BENCH_SUBNORMAL_LIMIT);
    for (int f = 0; f < run->nfiles; f++)
        for (int b = 0; b < 2; b++) {
            const double *ms = run->speed[f].sub_ms[b];
            if (isnan(ms[0])) continue;
            double ratio = ms[1] / ms[0];
            const char *verdict = ratio <= BENCH_SUBNORMAL_LIMIT ? "within" : "over";
            const char *name = bench_base_name(run->files[f]);
            fprintf(md, "| %s | %s | %.2f ms | %.2f ms | %.2f | %g | %s |\n", name, b ? "reference" : "OpenCL", ms[0],
                    ms[1], ratio, BENCH_SUBNORMAL_LIMIT, verdict);
            printf("bench: %s: subnormal lighting on %s: %.2f ms against %.2f ms = %.2f of normal (limit %g: %s)\n",
                   name, b ? "the reference" : "OpenCL", ms[1], ms[0], ratio, BENCH_SUBNORMAL_LIMIT, verdict);
        }
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

/* One panel per transport file, a line per environment (the series
 * $s<file * nenvs + env> written by bench.c). */
static void plot_script(FILE *gp, const bench_run *run)
{
    char mlist[48], m0[16], m1[16];
    const uint32_t last = run->terms[run->nterms - 1];
    snprintf(m0, sizeof m0, "%u", run->terms[0]);
    if (last == HL_TERMS_ALL) snprintf(m1, sizeof m1, "all");
    else snprintf(m1, sizeof m1, "%u", last);
    if (run->nterms > 1) snprintf(mlist, sizeof mlist, "%s ... %s", m0, m1);
    else snprintf(mlist, sizeof mlist, "%s", m0);
    /* no "set output": plot() names it, so that the SVG, too, is
       written under a temporary name (the script's first line says how
       to run it by hand) */
    fprintf(gp, "set terminal svg size %d,560 dynamic font 'sans,11' noenhanced\n", 420 * run->nfiles + 60);
    fprintf(gp, "set logscale xy\nset grid\nset key bottom left font ',9'\n"
                "set xlabel 'time per lighting change, OpenCL (ms)'\n"
                "set ylabel 'relative L2 error vs exact discrete'\n"
                "set multiplot layout 1,%d title 'Error against run time, %s selection, M = %s'\n",
            run->nfiles, select_name(run->first_select), mlist);
    for (int f = 0; f < run->nfiles; f++) {
        fprintf(gp, "set title ");
        gp_string(gp, bench_base_name(run->files[f]));
        fprintf(gp, "\nplot ");
        for (int e = 0; e < run->nenvs; e++) {
            fprintf(gp, "%s$s%d using 1:2 with linespoints pt 7 ps 0.5 title ", e ? ", \\\n     " : "",
                    f * run->nenvs + e);
            gp_string(gp, run->envs[e].name);
        }
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
    fprintf(gp, "\n");
}

void bench_out_summary(bench_out *o, const bench_run *run)
{
    FILE *md = o->f[BENCH_MD];
    speed_table(md, run);
    capture_table(md, run);
    subnormal_table(md, run);
    fprintf(md, "\nFor comparison: the 2003 paper relit 160k vertices at 3.5 to 9.8 Hz for 200 to 40 terms on a 2.8 GHz P4,\n"
                "and reported 2.2%% error with 200 wavelet terms (13.4%% with 200 spherical-harmonic terms) on its hardest\n"
                "scene; the seed report relit 40k vertices at 3 fps.\n");
    for (int f = 0; f < run->nfiles; f++) {
        const bench_speed *s = &run->speed[f];
        printf("bench: %s: %.0f lighting changes/s at M = 200 (a new map first: %.2f ms); dot products %.3f ms for "
               "%.1f MB = %.2f (%.2f to %.2f) of the read bandwidth (%.1f GB/s)\n",
               bench_base_name(run->files[f]), s->rate, 1e3 * s->newmap, 1e3 * s->dot, s->bytes * 1e-6, s->frac[0],
               s->frac[1], s->frac[2], s->bw * 1e-9);
    }
    plot_script(o->f[BENCH_GP], run);
}

/* ---------------------------------------------------------------- finishing */

/* cli.h; gnuplot's output goes to stderr. */
int bench_plot(const char *dir, const char *stem, int *plotted)
{
    char tmp[300], set[340], gp[300];
    snprintf(tmp, sizeof tmp, "%s.svg.tmp.%ld", stem, (long)getpid());
    snprintf(gp, sizeof gp, "%s.gp", stem);
    snprintf(set, sizeof set, "set output '%s'", tmp);
    *plotted = 0;
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid == 0) {
        if (chdir(dir) != 0) _exit(126);
        dup2(2, 1);
        execlp("gnuplot", "gnuplot", "-e", set, gp, (char *)NULL);
        _exit(127);
    }
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid) {
        fprintf(stderr, "haarlight: bench: cannot run gnuplot: %s\n", strerror(errno));
        return 1;
    }
    char from[1200], to[1200];
    snprintf(from, sizeof from, "%s/%s", dir, tmp);
    snprintf(to, sizeof to, "%s/%s.svg", dir, stem);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 127) {
        fprintf(stderr, "bench: gnuplot is not installed (apt-get install gnuplot-nox): %s not drawn\n", to);
        unlink(from);
        return 0;
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "haarlight: bench: gnuplot failed on %s/%s: %s not drawn\n", dir, gp, to);
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

int bench_out_finish(bench_out *o, hl_result r, hl_context *cl, hl_context *ref)
{
    for (int k = 0; k < BENCH_OUTS; k++)
        if (o->f[k] && fclose(o->f[k]) != 0 && r == HL_OK)
            r = hl_tools_fail(ref, HL_ERR_IO, "%s: cannot write: %s", o->tmp[k], strerror(errno));
    char final[1200];
    for (int k = 0; k < BENCH_OUTS && r == HL_OK; k++) {
        out_path(final, sizeof final, o->dir, out_names[k], 0);
        if (rename(o->tmp[k], final) != 0) r = hl_tools_fail(ref, HL_ERR_IO, "%s: cannot write: %s", final, strerror(errno));
    }
    if (r != HL_OK) {
        for (int k = 0; k < BENCH_OUTS; k++) unlink(o->tmp[k]);
        return cli_fail(hl_context_last_error(cl)[0] ? cl : ref, r);
    }
    int plotted = 0, rc = bench_plot(o->dir, "bench", &plotted);
    const char *d = o->dir;
    if (plotted) printf("bench: wrote %s/bench.md, %s/bench.csv and %s/bench.svg\n", d, d, d);
    else printf("bench: wrote %s/bench.md and %s/bench.csv (no plot)\n", d, d);
    return rc;
}

/* ---------------------------------------------------------------- bench-dynamic */

static const char *const bd_method_names[] = {"PRT", "dynamic", "K-lights ref", "traced"};

/* Where a row's time goes, in words. */
static void bd_split(char *buf, size_t n, const bd_row *w)
{
    buf[0] = '\0';
    if (w->method == BD_DYNAMIC)
        snprintf(buf, n,
                 "irradiance %.1f, shadow maps %.1f, %s build %.1f, %s eval %.1f, sharp rays %.1f, shading %.1f "
                 "(frame %.1f; shadow maps kept %u)",
                 w->stage[0], w->stage[1], w->M ? "CSM" : "moments", w->stage[2], w->M ? "CSM" : "moments", w->stage[3],
                 w->stage[6], w->stage[4], w->stage[5], w->maps_kept);
    else if (w->method == BD_TRACED)
        snprintf(buf, n, "BVH %.1f, rays %.1f, occlusion %.1f, shading %.1f", w->stage[0], w->stage[1], w->stage[2],
                 w->stage[3]);
}

/* A dynamic row's representation: "M 16" for CSM of order 16, "moments"
 * for the moment shadow maps (M 0 in the rows). */
static const char *bd_dyn_m(uint32_t M, char *buf, size_t n)
{
    if (M == 0) return "moments";
    snprintf(buf, n, "M %u", M);
    return buf;
}

static void bd_setting(char *buf, size_t n, const bd_row *w)
{
    char mb[16];
    if (w->method == BD_PRT && w->M == 0) snprintf(buf, n, "M all");
    else if (w->method == BD_PRT) snprintf(buf, n, "M %u", w->M);
    else if (w->method == BD_DYNAMIC) snprintf(buf, n, "K %u, %s", w->K, bd_dyn_m(w->M, mb, sizeof mb));
    else if (w->method == BD_LIGHTS) snprintf(buf, n, "K %u", w->K);
    else snprintf(buf, n, "K %u, S %u", w->K, w->S);
}

static void bd_tables(FILE *md, FILE *csv, const bd_report *rep)
{
    char sharp[96] = "";
    if (rep->Rs) snprintf(sharp, sizeof sharp, ", the sharp lights' %u^2 (relight-dynamic --sharp-res)", rep->Rs);
    else if (rep->sharp_rays) snprintf(sharp, sizeof sharp, ", the sharp lights by rays (relight-dynamic --sharp)");
    fprintf(md, "# Error against time: PRT, the dynamic method and traced rays\n\n"
                "Scene: %s, %u vertices (%u object, %u ground). Device: %s. Shadow maps %u^2%s.\n"
                "Errors: relative L2 over every vertex and channel, and the worst vertex over the brightest, against\n"
                "the exact result (each vertex integrates the whole map, resampled on a cube of 64^2 texels a face,\n"
                "with Embree visibility on the geometry as it is; %.1f s under the first map); moved frames also\n"
                "against the K-lights reference (the same K lights with ray-traced visibility, the folded rest\n"
                "unshadowed: what the light split alone leaves). Moved: the object translated by (%.3g, %.3g, %.3g),\n"
                "0.3 of its height up and half its width along +X. Times: PRT, the median of %u full lighting changes;\n"
                "dynamic, the median of %u frames, each really computed (the object nudged by 1e-6 of the scene's\n"
                "diagonal), split by stage in ms (medians of each); traced, the median of %u calls, everything\n"
                "rebuilt as after any move (world mesh and BVH, rays, occlusion, shading); the K-lights reference,\n"
                "one call. Times in ms. Load average of the host (/proc/loadavg) at the start: %s; at the end: %s.\n\n",
            rep->scene, rep->vertices, rep->object_vertices, rep->vertices - rep->object_vertices, rep->device, rep->R,
            sharp, rep->ref_seconds, rep->move[0], rep->move[1], rep->move[2], rep->reps, rep->reps, rep->traced_reps, rep->load[0],
            rep->load[1]);
    fprintf(md, "| env | frames | method | setting | L2 exact | max exact | L2 vs K-lights | ms | frames/s | where the time goes (ms) |\n"
                "|---|---|---|---|---|---|---|---|---|---|\n");
    fprintf(csv, "env,frames,method,K,M,S,l2_exact,max_exact,l2_klights,ms,dyn_irradiance_ms,dyn_shadow_maps_ms,"
                 "dyn_csm_build_ms,dyn_csm_eval_ms,dyn_shading_ms,dyn_frame_ms,dyn_sharp_rays_ms,traced_bvh_ms,traced_rays_ms,"
                 "traced_occlusion_ms,traced_shading_ms\n");
    for (uint32_t i = 0; i < rep->nrows; i++) {
        const bd_row *w = &rep->rows[i];
        char set[48], split[200], lk[32] = "";
        bd_setting(set, sizeof set, w);
        bd_split(split, sizeof split, w);
        if (!isnan(w->l2_lights)) snprintf(lk, sizeof lk, "%.2f%%", 100 * w->l2_lights);
        fprintf(md, "| %s | %s | %s | %s | %.2f%% | %.2f%% | %s | %.1f | %.1f | %s |\n", rep->envs[w->env].name,
                w->moving ? "moved" : "rest", bd_method_names[w->method], set, 100 * w->l2, 100 * w->mx, lk, w->ms,
                1e3 / w->ms, split);
        const int dy = w->method == BD_DYNAMIC, tr = w->method == BD_TRACED;
        fprintf(csv, "%s,%s,%s,%u,%u,%u,%.6g,%.6g,%.6g,%.4g", rep->envs[w->env].name, w->moving ? "moved" : "rest",
                bd_method_names[w->method], w->K, w->M, w->S, w->l2, w->mx, w->l2_lights, w->ms);
        for (int c = 0; c < 7; c++) fprintf(csv, ",%.4g", dy ? w->stage[c] : NAN);
        for (int c = 0; c < 4; c++) fprintf(csv, ",%.4g", tr ? w->stage[c] : NAN);
        fprintf(csv, "\n");
    }
}

static const bd_row *bd_find(const bd_report *rep, int e, int moving, int method, uint32_t K, uint32_t M)
{
    for (uint32_t i = 0; i < rep->nrows; i++) {
        const bd_row *w = &rep->rows[i];
        if (w->env == e && w->moving == moving && w->method == method && w->K == K && w->M == M) return w;
    }
    return NULL;
}

/* The time a curve (rows of one method, in order of cost) needs to reach
 * error target: interpolated in log-log between the last row above it
 * and the first at or below it; *at: that first row (NULL: none reaches
 * it; *cheapest: it is the curve's first, so the time is an upper
 * bound). NAN when none does. */
static double bd_time_at(const bd_report *rep, int e, int moving, int method, uint32_t K, double target,
                         const bd_row **at, int *cheapest)
{
    const bd_row *prev = NULL;
    *at = NULL;
    *cheapest = 0;
    for (uint32_t i = 0; i < rep->nrows; i++) {
        const bd_row *w = &rep->rows[i];
        if (w->env != e || w->moving != moving || w->method != method || (K && w->K != K)) continue;
        if (w->l2 <= target) {
            *at = w;
            *cheapest = !prev;
            if (!prev || prev->l2 <= w->l2 || w->l2 <= 0) return w->ms;
            double f = (log(target) - log(prev->l2)) / (log(w->l2) - log(prev->l2));
            return exp(log(prev->ms) + f * (log(w->ms) - log(prev->ms)));
        }
        prev = w;
    }
    return NAN;
}

/* The goal setting's representation against the other's at the same K
 * (moments against CSM at its highest order measured, or CSM against
 * moments), at rest and moved: which is nearer the exact result, and
 * which is faster, by how much. Printed after the map's verdicts. */
static void bd_rep_against(FILE *md, const bd_report *rep, int e, const bd_row *g, const bd_row *gm)
{
    const bd_row *o = NULL, *om = NULL;
    for (uint32_t i = 0; i < rep->nrows; i++) {
        const bd_row *w = &rep->rows[i];
        if (w->env != e || w->method != BD_DYNAMIC || w->K != rep->goal_K || (w->M == 0) == (rep->goal_M == 0)) continue;
        if (!w->moving && (!o || (w->M > o->M))) o = w;
        if (w->moving && (!om || (w->M > om->M))) om = w;
    }
    if (!o || !om) return;
    char gn[24], on[24];
    snprintf(gn, sizeof gn, rep->goal_M ? "CSM at M %u" : "moments", rep->goal_M);
    snprintf(on, sizeof on, o->M ? "CSM at M %u" : "moments", o->M);
    const bd_row *ours[2] = {g, gm}, *theirs[2] = {o, om};
    fprintf(md, "  %s against %s (K %u):", gn, on, rep->goal_K);
    for (int m = 0; m < 2; m++) {
        const bd_row *a = ours[m], *b = theirs[m];
        fprintf(md, "%s %s %.2f%% in %.1f ms against %.2f%% in %.1f ms, %s nearer by %.2f points and %s %.2f times faster",
                m ? ";" : "", m ? "moved" : "at rest", 100 * a->l2, a->ms, 100 * b->l2, b->ms, a->l2 <= b->l2 ? gn : on,
                100 * fabs(a->l2 - b->l2), a->ms <= b->ms ? gn : on, a->ms <= b->ms ? b->ms / a->ms : a->ms / b->ms);
    }
    fprintf(md, ".\n");
}

/* Per map: who wins at rest (PRT at the dynamic goal's error) and moved
 * (the traced method at it), and the goal's verdicts. */
static void bd_verdicts(FILE *md, const bd_report *rep)
{
    fprintf(md, "\n## Who wins, and the speed goal (%.0f frames/s; %.0f times the traced method at equal error)\n\n",
            BD_GOAL_FPS_V, BD_GOAL_RATIO_V);
    for (int e = 0; e < rep->nenvs; e++) {
        const char *name = rep->envs[e].name;
        const bd_row *g = bd_find(rep, e, 0, BD_DYNAMIC, rep->goal_K, rep->goal_M);
        const bd_row *gm = bd_find(rep, e, 1, BD_DYNAMIC, rep->goal_K, rep->goal_M);
        if (!g || !gm) continue;
        const bd_row *at = NULL;
        char line[3][600], mname[16], gmb[16];
        const char *gmn = bd_dyn_m(rep->goal_M, gmb, sizeof gmb);
        int cheap = 0;
        double tp = bd_time_at(rep, e, 0, BD_PRT, 0, g->l2, &at, &cheap);
        if (at && at->M) snprintf(mname, sizeof mname, "%u", at->M);
        else snprintf(mname, sizeof mname, "all");
        if (at)
            snprintf(line[0], sizeof line[0], "at rest, PRT reaches the dynamic method's %.2f%% (K %u, %s: %.1f ms) %s %.2f ms (%s: M %s, %.2f%%): %s, %.1f times %s",
                     100 * g->l2, g->K, gmn, g->ms, cheap ? "in at most" : "at about", tp,
                     cheap ? "its cheapest row is already below" : "first at or below", mname, 100 * at->l2,
                     tp < g->ms ? "PRT wins" : cheap ? "undecided (fewer terms would be cheaper)" : "the dynamic method wins",
                     tp < g->ms ? g->ms / tp : tp / g->ms, tp < g->ms ? "faster" : "the dynamic method's time");
        else
            snprintf(line[0], sizeof line[0], "at rest, no PRT row reaches the dynamic method's %.2f%% (K %u, %s: %.1f ms): the dynamic method wins on error",
                     100 * g->l2, g->K, gmn, g->ms);
        double tt = bd_time_at(rep, e, 1, BD_TRACED, rep->goal_K, gm->l2, &at, &cheap);
        if (at && cheap && at->S == 1) /* S = 1 is the least the traced method can cast */
            snprintf(line[1], sizeof line[1], "moved, the traced method (K %u) is below the dynamic method's %.2f%% (%.1f ms) at its least, S 1: %.2f%% in %.1f ms: dynamic : traced speed %.2f",
                     rep->goal_K, 100 * gm->l2, gm->ms, 100 * at->l2, at->ms, tt / gm->ms);
        else if (at)
            snprintf(line[1], sizeof line[1], "moved, the traced method (K %u) reaches the dynamic method's %.2f%% (%.1f ms) %s %.1f ms (%s: S %u, %.2f%% in %.1f ms): dynamic : traced speed %s%.2f",
                     rep->goal_K, 100 * gm->l2, gm->ms, cheap ? "in at most" : "at about", tt,
                     cheap ? "its cheapest row is already below" : "interpolated in log-log; first at or below", at->S,
                     100 * at->l2, at->ms, cheap ? "at most " : "", tt / gm->ms);
        else {
            /* the traced rays tend to the K-lights reference as S grows:
               where that is above the frame, no S reaches it */
            const bd_row *kl = bd_find(rep, e, 1, BD_LIGHTS, rep->goal_K, 0);
            char why[160] = "";
            if (kl && kl->l2 > gm->l2)
                snprintf(why, sizeof why, " (as S grows it tends to the K-lights reference, %.2f%% from exact: no S reaches it)",
                         100 * kl->l2);
            snprintf(line[1], sizeof line[1], "moved, no traced row (K %u) reaches the dynamic method's %.2f%% (%.1f ms): the dynamic method wins on error at every S measured%s",
                     rep->goal_K, 100 * gm->l2, gm->ms, why);
        }
        const double fps = 1e3 / g->ms, ratio = tt / gm->ms;
        const int bound = at && cheap && at->S > 1; /* ratio only an upper bound */
        char rtext[160];
        if (!at) snprintf(rtext, sizeof rtext, "the traced method does not reach its error at the S measured");
        else
            snprintf(rtext, sizeof rtext, "%s%.2f times the traced method's speed at equal error, goal %.0f: %s",
                     bound ? "at most " : "", ratio, BD_GOAL_RATIO_V,
                     ratio < BD_GOAL_RATIO_V ? "below" : bound ? "undecided" : "at or above");
        snprintf(line[2], sizeof line[2], "goal: %.1f frames/s at rest (K %u, R %u, %s: %.1f ms), goal %.0f: %s; %s",
                 fps, rep->goal_K, rep->R, gmn, g->ms, BD_GOAL_FPS_V, fps >= BD_GOAL_FPS_V ? "at or above" : "below",
                 rtext);
        fprintf(md, "- **%s**: %s.\n  %s.\n  %s. Where the time goes (ms), at rest: irradiance %.1f, shadow maps %.1f, "
                    "%s build %.1f, %s eval %.1f, sharp rays %.1f, shading %.1f; moved: %.1f, %.1f, %.1f, %.1f, %.1f, "
                    "%.1f.\n",
                name, line[0], line[1], line[2], g->stage[0], g->stage[1], rep->goal_M ? "CSM" : "moments", g->stage[2],
                rep->goal_M ? "CSM" : "moments", g->stage[3], g->stage[6], g->stage[4],
                gm->stage[0], gm->stage[1], gm->stage[2], gm->stage[3], gm->stage[6], gm->stage[4]);
        printf("bench-dynamic: %s: %s\nbench-dynamic: %s: %s\nbench-dynamic: %s: %s\n", name, line[0], name, line[1], name,
               line[2]);
        bd_rep_against(md, rep, e, g, gm);
    }
}

/* Curves of the plot at most: per map at rest PRT and one per order, and
 * moved one per order, the K-lights reference and one per K (at most 8
 * settings each), for 16 maps. */
#define BD_MAX_SERIES (16 * (1 + 8 + 8 + 1 + 8))

/* One data block per curve: (map, rest or moved, method, group), group
 * the order M for the dynamic method and K for the traced one. */
static void bd_plot(FILE *gp, const bd_report *rep)
{
    fprintf(gp, "# in this folder: gnuplot -e \"set output 'bench.svg'\" bench.gp\n");
    int nb = 0;
    static char titles[BD_MAX_SERIES][64];
    static int panel[BD_MAX_SERIES];
    static const char *colour[BD_MAX_SERIES];
    for (uint32_t i = 0; i < rep->nrows && nb < BD_MAX_SERIES; i++) {
        const bd_row *w = &rep->rows[i];
        const uint32_t grp = w->method == BD_DYNAMIC ? w->M : w->method == BD_TRACED ? w->K : 0;
        int seen = 0;
        for (uint32_t j = 0; j < i && !seen; j++) {
            const bd_row *x = &rep->rows[j];
            seen = x->env == w->env && x->moving == w->moving && x->method == w->method &&
                   (x->method == BD_DYNAMIC ? x->M : x->method == BD_TRACED ? x->K : 0) == grp;
        }
        if (seen) continue;
        fprintf(gp, "$b%d << EOD\n", nb);
        for (uint32_t j = i; j < rep->nrows; j++) {
            const bd_row *x = &rep->rows[j];
            if (x->env == w->env && x->moving == w->moving && x->method == w->method &&
                (x->method == BD_DYNAMIC ? x->M : x->method == BD_TRACED ? x->K : 0) == grp)
                fprintf(gp, "%.5g %.6g\n", x->ms, x->l2);
        }
        fprintf(gp, "EOD\n");
        if (w->method == BD_PRT) snprintf(titles[nb], sizeof titles[nb], "PRT (M terms)");
        else if (w->method == BD_DYNAMIC && grp == 0) snprintf(titles[nb], sizeof titles[nb], "dynamic, moments (K)");
        else if (w->method == BD_DYNAMIC) snprintf(titles[nb], sizeof titles[nb], "dynamic, CSM order %u (K)", grp);
        else if (w->method == BD_TRACED) snprintf(titles[nb], sizeof titles[nb], "traced, K %u (S)", grp);
        else snprintf(titles[nb], sizeof titles[nb], "K-lights reference (K)");
        /* a method's curves in one family of colours on every panel: PRT
           violet, dynamic greens by order, traced reds by K, the
           K-lights reference black */
        static const char *const greens[] = {"#006400", "#2e8b57", "#6b8e23"}, *const reds[] = {"#ff8c00", "#d02020", "#8b0000"};
        colour[nb] = w->method == BD_PRT ? "#9400d3" : w->method == BD_LIGHTS ? "#000000"
                     : w->method == BD_DYNAMIC ? greens[grp >= 16 ? 0 : grp >= 8 ? 1 : 2]
                                               : reds[grp >= 32 ? 2 : grp >= 16 ? 1 : 0];
        panel[nb++] = 2 * w->env + w->moving;
    }
    fprintf(gp, "set terminal svg size %d,860 dynamic font 'sans,11' noenhanced\n", 380 * rep->nenvs + 60);
    fprintf(gp, "set logscale xy\nset grid\nset key top right font ',8'\n"
                "set xlabel 'time per frame (ms)'\nset ylabel 'relative L2 error vs exact'\n"
                "set multiplot layout 2,%d columnsfirst title ", rep->nenvs);
    char title[300];
    snprintf(title, sizeof title, "Error against time: %s", rep->scene);
    gp_string(gp, title);
    fprintf(gp, "\n");
    for (int p = 0; p < 2 * rep->nenvs; p++) {
        char title[200];
        snprintf(title, sizeof title, "%s, %s", rep->envs[p / 2].name, p % 2 ? "moved" : "at rest");
        fprintf(gp, "set title ");
        gp_string(gp, title);
        fprintf(gp, "\nplot ");
        int first = 1;
        for (int k = 0; k < nb; k++) {
            if (panel[k] != p) continue;
            fprintf(gp, "%s$b%d using 1:2 with linespoints pt 7 ps 0.6 lc rgb '%s' title ", first ? "" : ", \\\n     ", k,
                    colour[k]);
            gp_string(gp, titles[k]);
            first = 0;
        }
        if (first) fprintf(gp, "NaN notitle");
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
}

void bench_dyn_write(bench_out *o, const bd_report *rep)
{
    bd_tables(o->f[BENCH_MD], o->f[BENCH_CSV], rep);
    bd_verdicts(o->f[BENCH_MD], rep);
    bd_plot(o->f[BENCH_GP], rep);
}
