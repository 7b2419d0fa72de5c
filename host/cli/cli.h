/* cli.h - helpers shared by the haarlight subcommands (option parsing,
 * contexts, Ctrl-C, errors), the commands' entry points, and the
 * interfaces between bench.c and bench_out.c. Sees the library through
 * haarlight.h (and its .c files through haarlight_tools.h) only. */
#ifndef HL_CLI_H
#define HL_CLI_H

#include <stdint.h>
#include <stdio.h>

#include "haarlight.h"

/* Prints "haarlight: <fmt with arg>" and the usage; returns 2. */
int usage_error(const char *usage, const char *fmt, const char *arg);
/* Strict parsers: the whole string must be a number in range. */
int parse_u32(const char *s, uint32_t *out);
int parse_float(const char *s, float *out);
int parse_device(const char *s, hl_context_desc *cd);
/* --device-memory SIZE: a byte count (hl_parse_bytes) into cd. */
int parse_device_memory(const char *s, hl_context_desc *cd);
/* "x,y,z" of finite numbers. */
int parse_vec3(const char *s, float v[3]);
/* --sharp: "rays", "maps" or "off" to HL_DYNAMIC_SHARP_*; 0 when none. */
int parse_sharp(const char *s, uint32_t *out);
/* "transport", "area" or "unweighted" to HL_SELECT_*; 0 when none. */
int parse_select(const char *s, uint32_t *out);
/* auto, equirect, angular, cross-h or cross-v. */
int parse_layout(const char *s, hl_env_layout *out);
/* HL_SELECT_* to its name (HL_SELECT_DEFAULT: "transport"). */
const char *select_name(uint32_t scheme);
/* An OpenCL context from cl_desc and a reference context beside it (for
 * comparing the two); prints the error and returns 0 on failure. */
int cli_context_pair(const hl_context_desc *cl_desc, hl_context **cl, hl_context **ref);
/* Ctrl-C (SIGINT) and SIGTERM cancel the contexts watched (main.c): a
 * command watches the one or two contexts its long work runs on (b may be
 * NULL) once they are created, and unwatches them before destroying them. */
void cli_watch(hl_context *a, hl_context *b);
void cli_unwatch(void);
/* A command's context, watched (cli_watch); prints the error and returns
 * NULL when it cannot be made. */
hl_context *cli_context(const hl_context_desc *cd);
/* The extension of path's file name, from its last dot ("" when none). */
const char *cli_ext_of(const char *path);
/* Makes the folder dir unless it exists; prints why and returns 0 when
 * it cannot. */
int cli_make_dir(const char *dir);
/* Prints on stderr, after prefix, what the device holds for relighter rl
 * against the bytes of its file scene (docs/MEMORY.md), its columns
 * (cols) and the parts they run in. */
void cli_device_memory(const char *prefix, hl_relighter *rl, const char *scene, uint32_t V, int cols);
/* Prints the context's last error; returns the exit code for r. */
int cli_fail(hl_context *ctx, hl_result r);
/* hl_env_load, then (unless quiet) a line on stderr saying how many
 * pixels were repaired, when any were. */
hl_result cli_env_load(hl_context *ctx, const char *path, hl_env_layout layout, hl_env **out, int quiet);

/* Options shared by `relight` and `view` (cli_scene.c). */
typedef struct cli_scene_opts {
    hl_context_desc cd;
    hl_relight_desc rd;
    hl_sky_desc sky;
    hl_camera_desc cam;
    float exposure;
    int exposure_set;
    int sky_set;    /* a --sun-* option was given */
    int eye_set;    /* --eye was given */
    int target_set; /* --target was given */
    hl_env_layout layout; /* --layout */
    /* Set by a command before parsing when it takes --surroundings and
     * --time (relight); elsewhere they are unknown options. */
    int accept_surroundings;
    const char *surroundings; /* --surroundings FILE, or NULL */
    double time;              /* --time T, seconds (default 0) */
    int time_set;
    /* --surroundings-transform TX,TY,TZ,SCALE,YAW (checked when parsed) */
    float place[5];
    int place_set;
    /* --probes N (1 to HL_PROBES_MAX, default 1) */
    uint32_t probes;
    int probes_set;
} cli_scene_opts;

void cli_scene_opts_init(cli_scene_opts *o);
/* If argv[*i] is a shared option, reads it and its value (advancing *i)
 * and returns 1; returns 0 when it is not one, and -2 after printing the
 * usage error for a bad value (exit code 2). */
int cli_scene_opt(int argc, char **argv, int *i, const char *usage, cli_scene_opts *o);
/* Completes a camera given in part: --eye alone looks at the object's
 * centre (the automatic framing's target), --target alone is seen from the
 * automatic framing's offset. Fails like hl_camera_query_view. */
hl_result cli_camera_complete(hl_context *ctx, const hl_mesh *mesh, cli_scene_opts *o);
/* Parses --surroundings-transform's value into place (shift, scale,
 * turn about +Y in degrees); 0 after printing the usage error that names
 * the option and the bad part. */
int cli_parse_placement(const char *usage, const char *v, float place[5]);
/* Loads o->surroundings (when given) placed by --surroundings-transform and posed at o->time, and (unless quiet)
 * prints what it holds: triangles, emitting bodies, the animation's range
 * and the time used. *out stays NULL without --surroundings. */
hl_result cli_surroundings_load(hl_context *ctx, const cli_scene_opts *o, hl_surroundings **out, int quiet);
/* Prints the capture points a run with surroundings used and their
 * parallax bound (stats of hl_relighter_run), and with one point whose
 * bound passes a few texels of the N paraboloid, how to follow it. */
void cli_probes_report(const hl_relight_stats *st, uint32_t N, uint32_t asked);
/* "WxH", each side 1 to 16384. */
int cli_parse_size(const char *s, uint32_t *w, uint32_t *h);

/* Help lines of the shared options, for the commands' usage texts. */
#define CLI_USAGE_SKY                                                                     \
    "  --sun-elevation DEG  sun height above the horizon (default 35)\n"                  \
    "  --sun-azimuth DEG    sun direction: +X turned about +Y by DEG (default 0)\n"       \
    "  --sun-size DEG       sun angular diameter (default 2)\n"
#define CLI_USAGE_LAYOUT                                                                  \
    "  --layout L           how --env maps lay out the sphere: auto (by size: 2:1, 1:1,\n" \
    "                       4:3, 3:4), equirect, angular (light probe), cross-h, cross-v\n"
#define CLI_USAGE_LIGHTING                                                                \
    "  --rotate DEG         turn the environment about +Y (Blender's world Z rotation)\n" \
    "  --terms M|all        lighting wavelet terms kept (default 200)\n"                  \
    "  --select transport|area|unweighted\n"                                              \
    "                       how the terms are chosen: |L_i| x mean |T_i| over the vertices\n" \
    "                       (the default), x support area, or x 1\n"
#define CLI_USAGE_SURROUNDINGS                                                            \
    "  --surroundings FILE  light from surroundings: any mesh file assimp reads (glTF, FBX,\n" \
    "                       OBJ, ...), any number of triangles; emissive materials give\n" \
    "                       light (emissive colour x intensity, or x glTF's emissive\n" \
    "                       strength), the others are dark and hide what lies behind\n" \
    "                       them. They are seen from the centre of the object's\n"        \
    "                       bounding box (ground left out), so surroundings close to a\n" \
    "                       large object light all of it as if from its centre, unless\n" \
    "                       --probes says otherwise. Directions they leave open are lit\n" \
    "                       by --env or --sky if given, else black; --rotate turns only\n" \
    "                       the environment. They light the object but are not drawn in\n" \
    "                       images\n"                                                   \
    "  --probes N           capture the surroundings from up to N points (1 to 256; default\n" \
    "                       1), placed where an emitter is near the vertices, and blend\n" \
    "                       each vertex's colours over the points near it: near lamps'\n" \
    "                       fall-off and shadow directions follow; each point costs a\n" \
    "                       capture and a relight. No point is added once every point\n" \
    "                       sees its emitters within 2 / (the transport's N) radians of\n" \
    "                       where its vertices see them\n"                              \
    "  --time T             seconds into the surroundings' own node animation (default 0;\n" \
    "                       held at the first or last key outside its range)\n"         \
    CLI_USAGE_SURROUNDINGS_TRANSFORM
#define CLI_USAGE_SURROUNDINGS_TRANSFORM                                                  \
    "  --surroundings-transform TX,TY,TZ,SCALE,YAW\n"                                    \
    "                       place the surroundings file: scale it uniformly by SCALE\n"  \
    "                       (> 0), turn it YAW degrees about +Y (+X towards -Z), then\n" \
    "                       shift it by TX,TY,TZ, as a root node over the file would\n"  \
    "                       (its animation included; default 0,0,0,1,0)\n"
#define CLI_USAGE_CAMERA                                                                  \
    "  --size WxH           image size (default 960x720)\n"                              \
    "  --fov DEG            vertical field of view (default 35)\n"                       \
    "  --eye X,Y,Z --target X,Y,Z --up X,Y,Z\n"                                          \
    "                       camera (default: frames the object automatically; --eye\n"   \
    "                       alone looks at the object's centre)\n"
#define CLI_USAGE_RUNNING                                                                 \
    "  --device cl|ref|cl:P:D   OpenCL device (default: the first, or HL_OPENCL_DEVICE=P:D),\n" \
    "                       or the plain-C reference; HL_DEVICE_SHAPE=cpu|gpu forces the\n" \
    "                       kernels' shape (default: the device's type)\n" \
    "  --device-memory SIZE most device memory to use, e.g. 512M or 2G (default: the\n"   \
    "                       device's; also HL_DEVICE_MEMORY); a job needing more is refused\n" \
    "  --threads T          host threads (rendering, reference)\n"                       \
    "  -q, --quiet          print nothing but errors\n"

int cmd_relight(int argc, char **argv);
int cmd_relight_dynamic(int argc, char **argv);
int cmd_check(int argc, char **argv);
int cmd_bench(int argc, char **argv);
int cmd_bench_dynamic(int argc, char **argv);

/* ---------------------------------------------------------------- bench
 * `haarlight bench` in two files: bench.c measures (options, references,
 * timings), bench_out.c writes (bench.md, bench.csv, bench.gp, the plot).
 */

#define BENCH_MAX_FILES 8
#define BENCH_MAX_ENVS 16
#define BENCH_MAX_TERMS 16
#define BENCH_NEWMAP_REPS 15 /* at most, for the time of taking a new map */
/* rounds of (read bandwidth, dot products) for the speed summary */
#define BENCH_ROUNDS 7
/* subnormal lighting may take at most this many times the normal time */
#define BENCH_SUBNORMAL_LIMIT 2.0

typedef struct bench_env {
    const char *name, *path;
    hl_env *env;
    double *exact;  /* K x 3 */
    double *cont;   /* K2 x 3 */
    double *ground; /* exact B of each ground vertex (G x 3), for banding */
    /* with a bounced file: the bounced exact reference after b bounces
       (K x 3, b from 1; NULL where no file has b bounces) and its own
       noise relative to its L2 norm (hl_bench_ref_bounced) */
    double *exact_b[HL_MAX_BOUNCES + 1];
    double noise_own[HL_MAX_BOUNCES + 1], noise_bound[HL_MAX_BOUNCES + 1];
} bench_env;

/* The speed summary of one transport file. */
typedef struct bench_speed {
    double rate;       /* lighting changes per second at M = 200 */
    double newmap;     /* seconds to take a new map */
    double dot, bytes, bw;
    double frac[3];    /* median, least, most */
    double sub_ms[2][2]; /* [OpenCL, reference][normal, subnormal] */
    /* with --surroundings (bench_capture.c; cap_triangles 0: not measured) */
    uint32_t cap_triangles;
    double cap_rate;     /* lighting changes per second, each a new capture */
    double cap_same;     /* seconds of a run in which nothing changed */
    double cap_ms, cap_dot_ms, cap_ratio; /* capture alone, dots alone, their ratio (medians) */
    uint32_t cap_probes; /* capture points of the last change (--probes) */
} bench_speed;

/* The goal of lighting captured from surroundings: changes per second with
 * a new capture each, at M = 200 (and the capture cheaper than the dot
 * products). */
#define BENCH_CAPTURE_GOAL 200.0

/* `bench --image` (bench_image.c): what it measures on. */
typedef struct bench_image_in {
    hl_context *cl, *ref;
    struct hl_bench_ref *br;     /* the references of t[0] */
    hl_transport *const *t;
    const char *const *files;
    int nfiles;
    const bench_env *envs;
    int nenvs;
    const uint32_t *terms;
    uint32_t nterms, select;
    uint32_t frames;             /* pictures under the turning first map (1: none) */
    uint32_t width, height;
} bench_image_in;
/* Image-space errors and temporal stability, as sections of md (and lines
 * on stdout). */
hl_result bench_image(const bench_image_in *in, FILE *md);

/* The median of v (sorts it). */
double bench_median(double *v, int n);
/* `bench --surroundings`: rc lit by sur (then by its environment alone
 * again), into sp's cap_* fields; B: room for the colours. */
hl_result bench_capture(hl_relighter *rc, hl_surroundings *sur, uint32_t probes, uint32_t reps, float *B,
                        bench_speed *sp);

/* The output files: written as NAME.tmp.PID, renamed when complete. */
enum { BENCH_CSV, BENCH_MD, BENCH_GP, BENCH_OUTS };
typedef struct bench_out {
    const char *dir;
    char tmp[BENCH_OUTS][1200];
    FILE *f[BENCH_OUTS];
} bench_out;

/* What the run measured, for the summary and the plot. */
typedef struct bench_run {
    const char *const *files;
    int nfiles;
    const bench_env *envs;
    int nenvs;
    const uint32_t *terms;
    uint32_t nterms;
    uint32_t first_select;
    uint32_t reps;
    const bench_speed *speed;
} bench_run;

const char *bench_base_name(const char *path);
/* The files' temporary names in dir; nothing is opened yet. */
void bench_out_names(bench_out *o, const char *dir);
/* Opens bench.csv and bench.md and writes their headings (the md heading
 * states the figures in `in`, K, K2 and the repetitions); failures are
 * recorded on ref. */
hl_result bench_out_open(bench_out *o, hl_context *ref, hl_context *cl, const hl_transport_info *in, uint32_t K,
                         uint32_t K2, uint32_t reps, uint32_t ref_reps);
/* The name of the exact reference a file of B bounces is measured
 * against: "exact (direct)" or "exact (direct + B bounces, R rays)". */
void bench_ref_name(char *buf, size_t n, uint32_t B, uint32_t rays);
/* Under the heading of bench.md: which reference each file is measured
 * against and, for the bounced ones, the reference's own noise per map
 * (from envs[e].noise_own and noise_bound); then the rows' table heading. */
void bench_out_references(bench_out *o, const char *const *files, const uint32_t *bounces, int nfiles,
                          uint32_t rays, const bench_env *envs, int nenvs);
/* Opens bench.gp (the plot's script, its series written as they come). */
hl_result bench_out_open_plot(bench_out *o, hl_context *ref);
/* The speed and subnormal tables (bench.md and stdout) and the plot's
 * script. */
void bench_out_summary(bench_out *o, const bench_run *run);
/* Closes the files and renames them into place (when r is HL_OK, else
 * removes them), then draws the plot; returns the command's exit code. */
int bench_out_finish(bench_out *o, hl_result r, hl_context *cl, hl_context *ref);
/* Runs gnuplot on DIR/STEM.gp in DIR (no shell, so any folder name
 * works), its output to stderr, and renames DIR/STEM.svg into place when
 * it succeeds. Returns the exit status for the command: 0 also when
 * gnuplot is not installed (the tables stand without the plot), 1 when it
 * fails. `bench`, `bench-dynamic` and `bench-basis` draw with it. */
int bench_plot(const char *dir, const char *stem, int *plotted);

/* ---------------------------------------------------------------- bench-dynamic
 * `haarlight bench-dynamic`: bench_dynamic.c measures, bench_out.c
 * writes (bench_dyn_write) into the same bench_out files.
 */

enum { BD_PRT, BD_DYNAMIC, BD_LIGHTS, BD_TRACED };
/* The dynamic method's speed goal, printed as measured (not a test):
 * 10 frames per second, and 3 times the traced method's speed at equal or
 * lower error. */
#define BD_GOAL_FPS_V 10.0
#define BD_GOAL_RATIO_V 3.0
/* One measured row: a method at a setting under one map, at rest
 * (moving 0) or moved. */
typedef struct bd_row {
    int env, moving, method;
    uint32_t K, M, S;      /* K lights; M: PRT terms (0: all) or CSM order; S: traced rays a light */
    double l2, mx;         /* relative L2 and max against the exact reference */
    double l2_lights;      /* against the K-lights reference (NAN: not measured) */
    double ms;             /* median time a frame (NAN: not timed) */
    double stage[7];       /* dynamic: irradiance, shadow maps, CSM build, CSM
                              evaluation, shading, total, the sharp lights'
                              rays (within the total); traced: BVH, rays'
                              set-up, occlusion, shading (ms, medians) */
    uint32_t maps_kept;    /* dynamic: the most shadow maps a timed frame kept
                              (bench-dynamic refuses any but 0) */
} bd_row;

/* What bench_dyn_write needs besides the rows. */
typedef struct bd_report {
    const bench_env *envs;
    int nenvs;
    const bd_row *rows;
    uint32_t nrows;
    const char *scene, *device;
    uint32_t vertices, object_vertices, R, Rs, reps, traced_reps, goal_K, goal_M; /* Rs: the sharp lights' (0: none) */
    int sharp_rays; /* some frame took its sharp lights by rays */
    double move[3];        /* the moved frames' translation of the object */
    double ref_seconds;    /* the exact reference's time on the first map */
    char load[2][48];      /* the host's load averages at the start and end */
} bd_report;

/* bench.md, bench.csv and bench.gp of bench-dynamic (already opened),
 * with each map's verdicts on stdout too. */
void bench_dyn_write(bench_out *o, const bd_report *rep);

#endif
