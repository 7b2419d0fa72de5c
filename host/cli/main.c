/* main.c - the `haarlight` command line.
 *
 * Subcommands: precompute, info, devices, bench-precompute; relight, check
 * and bench (relight.c, check.c, bench.c); merge (merge.c); bench-basis
 * (bench_basis.c); view (viewer/,
 * when built). Usage errors
 * exit 2, failures exit 1 with a message naming the file and the problem.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "haarlight.h"
#include "haarlight_tools.h"
#ifdef HL_HAVE_VIEWER
#include "viewer.h"
#endif

static const char *const usage_main =
    "usage: haarlight COMMAND [options]\n"
    "\n"
    "commands:\n"
    "  precompute MESH -o SCENE.hlt   mesh to compressed wavelet transport (--shard I/N: one\n"
    "                                 part of a run spread over machines)\n"
    "  merge -o SCENE.hlt SHARD...    join the shards of precompute --shard into SCENE.hlt\n"
    "  info SCENE.hlt                 what a transport file holds\n"
    "  devices                        list OpenCL platforms and devices\n"
    "  relight SCENE.hlt -o OUT       relight under an environment: .ply, .glb, .exr or .png\n"
    "  relight-dynamic MESH|SCENE -o OUT  no precompute: moving bodies, area-light shadows\n"
    "  view SCENE.hlt                 interactive relighting in a window (GLFW viewer)\n"
    "  check SCENE.hlt                OpenCL stages against the plain-C reference\n"
    "  bench SCENE.hlt --env ENV.exr  error against run time for M, selection and quantisation\n"
    "  bench-dynamic SCENE.hlt        error against time of PRT, the dynamic method and traced rays\n"
    "  bench-basis SCENE.hlt -o DIR   lighting error of paraboloid Haar against spherical harmonics\n"
    "  bench-precompute MESH          time the precompute against Embree's raw rate\n"
    "\n"
    "`haarlight COMMAND --help` lists a command's options; `haarlight --version`\n"
    "prints the version.\n";

static const char *const usage_precompute =
    "usage: haarlight precompute MESH -o SCENE.hlt [options]\n"
    "\n"
    "Reads MESH (OBJ, PLY, glTF, ... through assimp; MESH.gz, as mesh.obj.gz, is read\n"
    "as it is), casts visibility rays with Embree, and writes per-vertex sparse\n"
    "quantised Haar (or, with --basis sh, spherical-harmonic; with --basis cube-haar,\n"
    "cube-face Haar) transport.\n"
    "\n"
    "mesh:\n"
    "  --ground             add a finely tessellated ground plane under the object\n"
    "  --ground-res R       ground quads across its uniform middle (default 96)\n"
    "  --ground-size S      the ground's side, S x the object's footprint (1 < S <= 129;\n"
    "                       default: the shadow of the object's top under a sun 15\n"
    "                       degrees high falls on it, at least 2.5); graded beyond 2.5\n"
    "  --albedo R[,G,B]     albedo where the file gives none: no material colour or\n"
    "                       texture, no vertex colours (default 0.8)\n"
    "  --ground-albedo R[,G,B]  the ground's albedo, each in [0, 1] (implies --ground;\n"
    "                       default: grey at the object's mean albedo)\n"
    "  --up y|z             the file's up axis (default y)\n"
    "  --keep-winding       never flip an inward-facing closed mesh\n"
    "  --time T             an animated file posed at T seconds of its (rigid) animation,\n"
    "                       as relight-dynamic --time T shows it (default: the rest pose,\n"
    "                       the nodes as stored)\n"
    "sampling:\n"
    "  -C, --cube C         cubemap face resolution (default 64)\n"
    "  -N, --para N         paraboloid map resolution, power of two 8..256 (default 64)\n"
    "  --supersample S      S x S rays per cube texel, 1..15 (default 1)\n"
    "  --ray-offset F|robust  ray origin offset along the normal: a fraction of the bbox\n"
    "                       diagonal, or robust (the default: 2^-16 of the larger of the\n"
    "                       vertex's coordinates and its longest edge, at any scale)\n"
    "interreflection:\n"
    "  --bounces B          bake B bounces of diffuse interreflection off the object and\n"
    "                       its ground into the rows (0 to 16; default 0, direct light,\n"
    "                       the bytes as before). A second phase after the direct rows,\n"
    "                       which it keeps in SCENE.hlt.direct.hlt until the end. The\n"
    "                       bounces carry the mesh's albedo (every albedo must be in\n"
    "                       [0, 1]); where some surface is coloured the file holds a\n"
    "                       row a vertex and channel (three times the rows, and a third\n"
    "                       of the relighting speed); relight is unchanged\n"
    "  --bounce-rays K      cosine-weighted rays a vertex for the bounces (default 256)\n"
    "  --bounce-terms G|all the largest G terms of each hit vertex's row that a bounce\n"
    "                       reads (default 512), held for every vertex: 4 bytes a term\n"
    "                       (6 at -N 256), 2 KB a vertex at the default; with B >= 2\n"
    "                       the next bounce's rows go to a scratch file beside -o\n"
    "  --direct-rows FILE   with --bounces: start the bounces from FILE, a finished\n"
    "                       transport of the same mesh and options without bounces (as\n"
    "                       merged from shards), instead of casting the direct rays;\n"
    "                       with --shard I/N, the last bounce of shard I's vertices only\n"
    "                       (the bounces before it of every vertex), and merge joins the\n"
    "                       shards into the bytes of one run. The bounces start from\n"
    "                       FILE.values where it exists (--keep-floats), else from the\n"
    "                       8-bit codes (the direct light then coded twice; a warning)\n"
    "  --keep-floats        without --bounces: also write SCENE.hlt.values, the kept\n"
    "                       terms as the floats they were coded from (4 bytes a term),\n"
    "                       for a later --bounces --direct-rows SCENE.hlt; merge joins\n"
    "                       the shards' (docs/BOUNCES.md)\n"
    "truncation (per vertex):\n"
    "  --energy EPS         keep the fewest coefficients holding 1-EPS of the energy\n"
    "                       (the default rule, EPS = 1e-5)\n"
    "  --terms K            keep the K largest; with --energy, cap the count at K\n"
    "  --terms all          keep every non-zero coefficient\n"
    "basis:\n"
    "  --basis haar|sh|cube-haar  the rows' basis: haar, the paraboloid Haar wavelets\n"
    "                       (default); sh, real spherical harmonics of the cell-integrated\n"
    "                       rows, coefficient k = l^2 + l + m in slot k; cube-haar, Haar\n"
    "                       wavelets over the six faces of a cube (the 2003 paper's layout),\n"
    "                       face f's coefficients in slots f C'^2 .. (f + 1) C'^2 - 1;\n"
    "                       relight, bench and view then take the lighting into the same\n"
    "                       basis (a cube-haar file cannot be relit under --surroundings)\n"
    "  --sh-order L         with --basis sh: bands 0..L-1, L^2 coefficients, 1..32 with\n"
    "                       L^2 <= 2 N^2 (default 20: 400 coefficients)\n"
    "  --cube-side C'       with --basis cube-haar: the faces' side, a power of two that\n"
    "                       divides -C, with 6 C'^2 <= 2 N^2 (default the largest such:\n"
    "                       32 at N = C = 64)\n"
    "quantisation:\n"
    "  --quant sqrt8|log8|linear8  8-bit scheme (default sqrt8: sign + 7 bits uniform in\n"
    "                       the square root of |v| over the row's largest; log8: sign +\n"
    "                       log magnitude; linear8: linear between the row's min and max)\n"
    "running:\n"
    "  --device cl|ref|cl:P:D   OpenCL device (default: the first, or HL_OPENCL_DEVICE=P:D),\n"
    "                       or the plain-C reference; HL_DEVICE_SHAPE=cpu|gpu forces the\n"
    "                       kernels' shape (default: the device's type)\n"
    "  --device-memory SIZE most device memory to use, e.g. 512M or 2G (default: the\n"
    "                       device's; also HL_DEVICE_MEMORY); a job needing more is refused\n"
    "  --threads T          host threads for rays and the reference (default: all cores)\n"
    "  --chunk V            vertices per chunk; bounds memory (default 1024)\n"
    "  --resume             continue an interrupted run from SCENE.hlt.partial (Ctrl-C,\n"
    "                       or a killed process, leaves it); same mesh and options\n"
    "                       (and --shard) required, and the result is the same bytes\n"
    "  --shard I/N          compute only shard I of N (0 <= I < N, N at most the vertex\n"
    "                       count): the I-th of N contiguous, equal (to one vertex)\n"
    "                       ranges of vertices; -o then names a shard file, which\n"
    "                       relight and info refuse. `haarlight merge -o SCENE.hlt`\n"
    "                       with all N shards (same mesh and options) writes the\n"
    "                       same bytes as one run without --shard\n"
    "  -q, --quiet          no progress lines (on a terminal, one line rewritten in\n"
    "                       place; elsewhere, as in a batch job's log, one every 30 s)\n";

/* The contexts of the running command, for the SIGINT and SIGTERM
 * handler: it may run at any moment, so it reads them through lock-free
 * atomics (the only objects besides volatile sig_atomic_t that C11 lets a
 * handler touch). pending remembers a signal that came before the command
 * had a context, so that the context is cancelled as soon as it is
 * watched and the long work stops as it always did. */
static _Atomic(hl_context *) watched[2];
static volatile sig_atomic_t pending;

#if ATOMIC_POINTER_LOCK_FREE != 2
#error "the signal handler needs lock-free atomic pointers"
#endif

static void on_sigint(int sig)
{
    (void)sig;
    pending = 1;
    for (int i = 0; i < 2; i++) hl_context_cancel(atomic_load(&watched[i]));
}

void cli_watch(hl_context *a, hl_context *b)
{
    atomic_store(&watched[0], a);
    atomic_store(&watched[1], b);
    if (pending) { /* after the stores: a signal in between reaches them either way */
        hl_context_cancel(a);
        hl_context_cancel(b);
    }
}

void cli_unwatch(void)
{
    atomic_store(&watched[0], NULL);
    atomic_store(&watched[1], NULL);
}

/* Options shared by precompute and bench-precompute. */
typedef struct pre_opts {
    const char *mesh, *out;
    int ground;
    int time_set;
    double time; /* --time T */
    hl_ground_desc gd;
    hl_mesh_load_desc ld;
    hl_precompute_desc pd;
    hl_context_desc cd;
    int terms_set, energy_set, terms_all, sh_order_set, cube_side_set;
    float ground_albedo[3]; /* --ground-albedo */
    int ground_albedo_set, bounce_opt_set;
    uint32_t shard_index, shard_count; /* --shard I/N; count 0 when not given */
} pre_opts;

/* Defined in merge.c and bench_basis.c (cli.h is the helpers' header). */
int cmd_merge(int argc, char **argv);
int cmd_bench_basis(int argc, char **argv);

/* "I/N" with 0 <= I < N: 1, or 0 when malformed. */
static int parse_shard(const char *v, uint32_t *index, uint32_t *count)
{
    const char *slash = strchr(v, '/');
    char a[16];
    size_t k = slash ? (size_t)(slash - v) : 0;
    if (!slash || k == 0 || k >= sizeof a) return 0;
    memcpy(a, v, k);
    a[k] = 0;
    return parse_u32(a, index) && parse_u32(slash + 1, count) && *count >= 1 && *index < *count;
}

#define NEED_ARG()                                                                   \
    do {                                                                             \
        if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a);  \
        v = argv[++i];                                                               \
    } while (0)

/* The mesh options of argv[*i] (reading its value, advancing *i): 1 when
 * it was one, 0 when not, 2 after a usage error. */
static int pre_mesh_opt(int argc, char **argv, int *ip, const char *usage, pre_opts *o)
{
    int i = *ip;
    const char *a = argv[i], *v = NULL;
    if (!strcmp(a, "--ground")) o->ground = 1;
    else if (!strcmp(a, "--time")) {
        NEED_ARG();
        float t;
        if (!parse_float(v, &t) || !isfinite(t) || t < 0.0f)
            return usage_error(usage, "--time %s: expected seconds, finite and >= 0", v);
        o->time = t;
        o->time_set = 1;
    } else if (!strcmp(a, "--ground-size")) {
        NEED_ARG();
        float gs;
        if (!parse_float(v, &gs) || !(gs > 1.0f) || !(gs <= 129.0f))
            return usage_error(usage, "--ground-size %s: expected a size above 1 and at most 129 (x the footprint)", v);
        o->gd.margin = 0.5f * (gs - 1.0f);
        o->ground = 1;
    } else if (!strcmp(a, "--ground-res")) {
        NEED_ARG();
        if (!parse_u32(v, &o->gd.resolution) || o->gd.resolution < 1 || o->gd.resolution > 4096)
            return usage_error(usage, "--ground-res %s: expected 1 to 4096", v);
        o->ground = 1;
    } else if (!strcmp(a, "--albedo")) {
        NEED_ARG();
        float c[3];
        int n = sscanf(v, "%f,%f,%f", &c[0], &c[1], &c[2]);
        if (n == 1) c[1] = c[2] = c[0];
        if ((n != 1 && n != 3) || !(c[0] >= 0 && c[0] <= 1 && c[1] >= 0 && c[1] <= 1 && c[2] >= 0 && c[2] <= 1))
            return usage_error(usage, "--albedo %s: expected R or R,G,B in [0, 1]", v);
        if (c[0] == 0 && c[1] == 0 && c[2] == 0)
            return usage_error(usage, "--albedo %s: an all-black albedo would make every vertex black", v);
        memcpy(o->ld.albedo, c, sizeof c);
        memcpy(o->gd.albedo, c, sizeof c);
    } else if (!strcmp(a, "--ground-albedo")) {
        NEED_ARG();
        float c[3];
        char tail;
        int n = sscanf(v, "%f,%f,%f%c", &c[0], &c[1], &c[2], &tail);
        if (n == 1) c[1] = c[2] = c[0];
        if ((n != 1 && n != 3) || !(c[0] >= 0 && c[0] <= 1 && c[1] >= 0 && c[1] <= 1 && c[2] >= 0 && c[2] <= 1))
            return usage_error(usage, "--ground-albedo %s: expected R or R,G,B, each a number in [0, 1]", v);
        if (c[0] == 0 && c[1] == 0 && c[2] == 0)
            return usage_error(usage, "--ground-albedo %s: an all-black ground is not taken (use a small value)", v);
        memcpy(o->ground_albedo, c, sizeof c);
        o->ground_albedo_set = 1;
        o->ground = 1;
    } else if (!strcmp(a, "--up")) {
        NEED_ARG();
        if (strcmp(v, "y") && strcmp(v, "z")) return usage_error(usage, "--up %s: expected y or z", v);
        o->ld.up_axis = v[0];
    } else if (!strcmp(a, "--keep-winding")) o->ld.keep_winding = 1;
    else return 0;
    *ip = i;
    return 1;
}

/* The sampling, truncation and quantisation options, as pre_mesh_opt. */
static int pre_transport_opt(int argc, char **argv, int *ip, const char *usage, pre_opts *o)
{
    int i = *ip;
    const char *a = argv[i], *v = NULL;
    if (!strcmp(a, "-C") || !strcmp(a, "--cube")) {
        NEED_ARG();
        if (!parse_u32(v, &o->pd.C) || o->pd.C < 4 || o->pd.C > 512)
            return usage_error(usage, "-C %s: the cubemap resolution must be 4 to 512", v);
    } else if (!strcmp(a, "-N") || !strcmp(a, "--para")) {
        NEED_ARG();
        if (!parse_u32(v, &o->pd.N) || o->pd.N < 8 || o->pd.N > 256 || (o->pd.N & (o->pd.N - 1)))
            return usage_error(usage, "-N %s: the paraboloid resolution must be a power of two from 8 to 256", v);
    } else if (!strcmp(a, "--supersample")) {
        NEED_ARG();
        if (!parse_u32(v, &o->pd.supersample) || o->pd.supersample < 1 || o->pd.supersample > 15)
            return usage_error(usage, "--supersample %s: expected 1 to 15", v);
    } else if (!strcmp(a, "--ray-offset")) {
        NEED_ARG();
        if (!strcmp(v, "robust")) o->pd.ray_offset = 0.0f;
        else if (!parse_float(v, &o->pd.ray_offset) || !(o->pd.ray_offset > 0 && o->pd.ray_offset < 0.1f))
            return usage_error(usage, "--ray-offset %s: expected `robust` or a number in (0, 0.1)", v);
    } else if (!strcmp(a, "--bounces")) {
        NEED_ARG();
        if (!parse_u32(v, &o->pd.bounces) || o->pd.bounces > HL_MAX_BOUNCES)
            return usage_error(usage, "--bounces %s: expected a whole number from 0 to 16", v);
    } else if (!strcmp(a, "--direct-rows")) {
        NEED_ARG();
        o->pd.direct_rows = v;
    } else if (!strcmp(a, "--keep-floats")) {
        o->pd.keep_floats = 1;
    } else if (!strcmp(a, "--bounce-rays")) {
        NEED_ARG();
        if (!parse_u32(v, &o->pd.bounce_rays) || o->pd.bounce_rays < 1 || o->pd.bounce_rays > 4096)
            return usage_error(usage, "--bounce-rays %s: expected 1 to 4096 rays a vertex", v);
        o->bounce_opt_set = 1;
    } else if (!strcmp(a, "--bounce-terms")) {
        NEED_ARG();
        if (!strcmp(v, "all")) o->pd.bounce_terms = HL_TERMS_ALL;
        else if (!parse_u32(v, &o->pd.bounce_terms) || o->pd.bounce_terms < 1)
            return usage_error(usage, "--bounce-terms %s: expected a count >= 1 or `all`", v);
        o->bounce_opt_set = 1;
    } else if (!strcmp(a, "--energy")) {
        NEED_ARG();
        if (!parse_float(v, &o->pd.eps) || !(o->pd.eps > 0 && o->pd.eps < 1))
            return usage_error(usage, "--energy %s: expected a fraction in (0, 1)", v);
        o->energy_set = 1;
    } else if (!strcmp(a, "--terms")) {
        NEED_ARG();
        if (!strcmp(v, "all")) o->terms_all = 1;
        else if (!parse_u32(v, &o->pd.K) || o->pd.K < 1)
            return usage_error(usage, "--terms %s: expected a count >= 1 or `all`", v);
        o->terms_set = 1;
    } else if (!strcmp(a, "--quant")) {
        NEED_ARG();
        if (!strcmp(v, "sqrt8")) o->pd.quant = HL_QUANT_SQRT8;
        else if (!strcmp(v, "log8")) o->pd.quant = HL_QUANT_LOG8;
        else if (!strcmp(v, "linear8")) o->pd.quant = HL_QUANT_LINEAR8;
        else return usage_error(usage, "--quant %s: expected sqrt8, log8 or linear8", v);
    } else if (!strcmp(a, "--basis")) {
        NEED_ARG();
        if (!strcmp(v, "haar")) o->pd.basis = HL_TRANSPORT_BASIS_HAAR;
        else if (!strcmp(v, "sh")) o->pd.basis = HL_TRANSPORT_BASIS_SH;
        else if (!strcmp(v, "cube-haar")) o->pd.basis = HL_TRANSPORT_BASIS_CUBE;
        else return usage_error(usage, "--basis %s: expected haar, sh or cube-haar", v);
    } else if (!strcmp(a, "--cube-side")) {
        NEED_ARG();
        uint32_t q = 0;
        if (!parse_u32(v, &q) || q < 2 || q > 512 || (q & (q - 1)))
            return usage_error(usage, "--cube-side %s: expected a power of two from 2 to 512", v);
        o->pd.cube_side = q;
        o->cube_side_set = 1;
    } else if (!strcmp(a, "--sh-order")) {
        NEED_ARG();
        if (!parse_u32(v, &o->pd.sh_order) || o->pd.sh_order < 1 || o->pd.sh_order > 32)
            return usage_error(usage, "--sh-order %s: expected 1 to 32", v);
        o->sh_order_set = 1;
    } else return 0;
    *ip = i;
    return 1;
}

/* The running options, as pre_mesh_opt. */
static int pre_running_opt(int argc, char **argv, int *ip, const char *usage, pre_opts *o)
{
    int i = *ip;
    const char *a = argv[i], *v = NULL;
    if (!strcmp(a, "--device")) {
        NEED_ARG();
        if (!parse_device(v, &o->cd)) return usage_error(usage, "--device %s: expected cl, ref or cl:PLATFORM:DEVICE", v);
    } else if (!strcmp(a, "--device-memory")) {
        NEED_ARG();
        if (!parse_device_memory(v, &o->cd)) return usage_error(usage, "--device-memory %s: expected a byte count such as 512M or 2G", v);
    } else if (!strcmp(a, "--threads")) {
        NEED_ARG();
        uint32_t t;
        if (!parse_u32(v, &t) || t < 1 || t > 256) return usage_error(usage, "--threads %s: expected 1 to 256", v);
        o->cd.threads = (int)t;
    } else if (!strcmp(a, "--chunk")) {
        NEED_ARG();
        if (!parse_u32(v, &o->pd.chunk) || o->pd.chunk < 1 || o->pd.chunk > (1u << 20))
            return usage_error(usage, "--chunk %s: expected 1 to 1048576", v);
    } else if (!strcmp(a, "--resume")) o->pd.resume = 1;
    else if (!strcmp(a, "--shard")) {
        NEED_ARG();
        if (!parse_shard(v, &o->shard_index, &o->shard_count))
            return usage_error(usage, "--shard %s: expected I/N with 0 <= I < N, as 3/8", v);
    }
    else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) o->cd.quiet = 1;
    else return 0;
    *ip = i;
    return 1;
}

static int parse_pre(int argc, char **argv, const char *usage, pre_opts *o)
{
    memset(o, 0, sizeof *o);
    o->cd.cl_platform = -1;
    o->cd.cl_device = -1;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
        int k;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage, stdout); exit(0); }
        else if (!strcmp(a, "-o") || !strcmp(a, "--output")) { NEED_ARG(); o->out = v; }
        else if ((k = pre_mesh_opt(argc, argv, &i, usage, o)) || (k = pre_transport_opt(argc, argv, &i, usage, o)) ||
                 (k = pre_running_opt(argc, argv, &i, usage, o))) {
            if (k != 1) return k;
        } else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (!o->mesh) o->mesh = a;
        else return usage_error(usage, "unexpected argument %s", a);
    }
    if (!o->mesh) return usage_error(usage, "%s", "no MESH given");
    if (o->ground_albedo_set) memcpy(o->gd.albedo, o->ground_albedo, sizeof o->ground_albedo);
    if (o->bounce_opt_set && !o->pd.bounces)
        return usage_error(usage, "%s", "--bounce-rays and --bounce-terms need --bounces B (B >= 1)");
    if (o->pd.keep_floats && o->pd.bounces)
        return usage_error(usage, "%s", "--keep-floats is for the direct rows of a later --bounces --direct-rows run; "
                                        "--bounces keeps the floats between its own phases");
    if (o->pd.direct_rows && !o->pd.bounces)
        return usage_error(usage, "%s", "--direct-rows needs --bounces B (B >= 1): only the bounces start from it");
    if (o->pd.bounces && o->shard_count && !o->pd.direct_rows)
        return usage_error(usage, "%s",
                           "--bounces with --shard: the bounces need every vertex's direct rows; shard and merge the "
                           "precompute without --bounces, then run --bounces B --direct-rows MERGED.hlt --shard I/N");
    if (o->pd.direct_rows && o->pd.resume)
        return usage_error(usage, "%s", "--resume with --direct-rows: the bounces from a direct file start over "
                                        "(there is nothing to resume)");
    if (o->terms_all && o->energy_set) return usage_error(usage, "%s", "--terms all and --energy contradict each other");
    if (o->sh_order_set && o->pd.basis != HL_TRANSPORT_BASIS_SH)
        return usage_error(usage, "%s", "--sh-order needs --basis sh");
    if (o->cube_side_set && o->pd.basis != HL_TRANSPORT_BASIS_CUBE)
        return usage_error(usage, "%s", "--cube-side needs --basis cube-haar");
    if (o->pd.basis == HL_TRANSPORT_BASIS_CUBE && !o->cube_side_set) {
        const uint32_t N = o->pd.N ? o->pd.N : 64, C = o->pd.C ? o->pd.C : 64;
        if (!hl_basis_bench_default_cube_side(N, C)) {
            char why[96];
            snprintf(why, sizeof why, "no cube side from 2 to N / 2 = %u divides -C %u", N / 2, C);
            return usage_error(usage, "--basis cube-haar: %s", why);
        }
    }
    if (o->pd.basis == HL_TRANSPORT_BASIS_CUBE && o->cube_side_set) {
        const uint32_t q = o->pd.cube_side, N = o->pd.N ? o->pd.N : 64, C = o->pd.C ? o->pd.C : 64;
        if (6 * q * q > 2 * N * N || C % q) {
            char why[96];
            snprintf(why, sizeof why, "%u (%u coefficients) with -N %u (%u slots) and -C %u", q, 6 * q * q, N,
                     2 * N * N, C);
            return usage_error(usage, "--cube-side %s: 6 C'^2 must be at most 2 N^2 and C' must divide C", why);
        }
    }
    if (o->pd.basis == HL_TRANSPORT_BASIS_SH) {
        uint32_t L = o->pd.sh_order ? o->pd.sh_order : HL_DEFAULT_SH_ORDER, N = o->pd.N ? o->pd.N : 64;
        if (L * L > 2 * N * N) {
            char why[96];
            snprintf(why, sizeof why, "%u (%u coefficients) with -N %u (%u slots)", L, L * L, N, 2 * N * N);
            return usage_error(usage, "--sh-order %s: L^2 must be at most 2 N^2", why);
        }
    }
    if (o->terms_all) o->pd.rule = HL_TRUNC_ALL;
    else if (o->terms_set && !o->energy_set) o->pd.rule = HL_TRUNC_TOPK;
    else o->pd.rule = HL_TRUNC_ENERGY;
    return 0;
}

static hl_result load_scene(hl_context *ctx, pre_opts *o, hl_mesh **mesh)
{
    hl_mesh_stats ms;
    uint32_t motion[3];
    if (o->time_set) {
        char anim[256];
        hl_result r = hl_tools_mesh_load_at(ctx, o->mesh, &o->ld, o->time, mesh, anim, sizeof anim);
        if (r != HL_OK) {
            if (r == HL_ERR_MESH || r == HL_ERR_INVALID_ARGUMENT) /* no animation, or one not rigid */
                fprintf(stderr, "precompute: without --time, the file's rest pose is baked (its nodes as stored, "
                                "skinned meshes in their bind pose); that is what --rest-pose names here\n");
            return r;
        }
        fprintf(stderr, "precompute: %s posed at %g s of its animation%s%s%s: %u vertices, %u triangles\n", o->mesh,
                o->time, anim[0] ? " \"" : " (unnamed)", anim, anim[0] ? "\"" : "", (*mesh)->vertex_count,
                (*mesh)->triangle_count);
        memset(motion, 0, sizeof motion);
        memset(&ms, 0, sizeof ms);
        ms.had_normals = 1;
    } else {
        hl_result r = hl_tools_mesh_load(ctx, o->mesh, &o->ld, mesh, &ms, motion);
        if (r != HL_OK) return r;
    }
    hl_result r = HL_OK;
    /* the pose baked, said even with -q: a transport of an animated file
       is of one pose, not of its motion */
    if (motion[0] || motion[1] || motion[2])
        fprintf(stderr,
                "precompute: %s has %u animation%s%s%s: the transport is of its rest pose, the nodes as stored%s%s "
                "(relight-dynamic follows a rigid animation)\n",
                o->mesh, motion[0], motion[0] == 1 ? "" : "s", motion[1] ? ", skinned meshes" : "",
                motion[2] ? ", morph targets" : "", motion[1] ? ", skinned meshes in their bind pose" : "",
                motion[2] ? ", morph targets at their base" : "");
    if (!o->cd.quiet) {
        fprintf(stderr, "mesh %s: %u vertices, %u triangles", o->mesh, (*mesh)->vertex_count, (*mesh)->triangle_count);
        if (ms.merged_vertices)
            fprintf(stderr, " (welded from the importer's %u vertices)", ms.file_vertices);
        if (ms.unreferenced_vertices) fprintf(stderr, ", %u unreferenced vertices dropped", ms.unreferenced_vertices);
        if (ms.degenerate_triangles) fprintf(stderr, ", %u degenerate triangles dropped", ms.degenerate_triangles);
        if (!ms.had_normals) fprintf(stderr, ", smooth normals computed");
        if (ms.flipped) fprintf(stderr, ", inward winding flipped");
        fputc('\n', stderr);
    }
    if (o->ground) {
        r = hl_mesh_add_ground(ctx, *mesh, &o->gd);
        if (r == HL_OK && !o->cd.quiet)
            fprintf(stderr, "ground plane: %u vertices added\n", (*mesh)->vertex_count - (*mesh)->object_vertex_count);
    }
    return r;
}


static int cmd_precompute(int argc, char **argv)
{
    pre_opts o;
    int u = parse_pre(argc, argv, usage_precompute, &o);
    if (u) return u;
    if (!o.out) return usage_error(usage_precompute, "%s", "no output given (-o SCENE.hlt)");
    hl_context *ctx = cli_context(&o.cd);
    if (!ctx) return 1;
    hl_mesh *mesh = NULL;
    hl_result r = load_scene(ctx, &o, &mesh);
    hl_precompute_stats st;
    if (r == HL_OK) {
        if (!o.cd.quiet) fprintf(stderr, "device: %s\n", hl_context_device_name(ctx));
        r = hl_precompute_shard(ctx, mesh, &o.pd, o.shard_index, o.shard_count, o.out, &st);
    }
    int rc = 0;
    uint32_t first = 0, end = mesh ? mesh->vertex_count : 0;
    if (o.shard_count) hl_shard_range(end, o.shard_index, o.shard_count, &first, &end);
    if (r != HL_OK) rc = cli_fail(ctx, r);
    else if (!o.cd.quiet) {
        uint64_t dirs = st.rays_cast + st.rays_culled;
        if (o.shard_count)
            fprintf(stderr, "shard %u of %u: vertices %u..%u of %u (join all %u with haarlight merge)\n",
                    o.shard_index, o.shard_count, first, end - 1, mesh->vertex_count, o.shard_count);
        fprintf(stderr,
                "wrote %s: %u vertices, %.1f coefficients kept per vertex\n"
                "rays: %llu cast, %llu culled below the horizon (%.1f%%)\n"
                "time: %.2f s total, %.2f s casting rays (%.1f Mrays/s), %.2f s waiting for the stages\n",
                o.out, end - first, (double)st.coefficients_kept / (end - first),
                (unsigned long long)st.rays_cast, (unsigned long long)st.rays_culled,
                dirs ? 100.0 * (double)st.rays_culled / (double)dirs : 0.0, st.seconds_total, st.seconds_rays,
                st.seconds_rays > 0 ? (double)st.rays_cast / st.seconds_rays * 1e-6 : 0.0, st.seconds_kernels);
        if (o.pd.bounces)
            fprintf(stderr, "bounces: %u, %.2f s of the total\n", o.pd.bounces, st.seconds_bounces);
    }
    hl_mesh_destroy(mesh);
    cli_unwatch();
    hl_context_destroy(ctx);
    return rc;
}

static int cmd_info(int argc, char **argv)
{
    if (argc != 1 || !strcmp(argv[0], "--help") || !strcmp(argv[0], "-h")) {
        fputs("usage: haarlight info SCENE.hlt\n\nPrints the parameters, counts and savings recorded in a transport file.\n",
              argc == 1 ? stdout : stderr);
        return argc == 1 ? 0 : 2;
    }
    hl_context_desc cd = {.backend = HL_BACKEND_REFERENCE};
    hl_context *ctx = NULL;
    char err[512];
    if (hl_context_create(&cd, &ctx, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 1;
    }
    hl_transport *t = NULL;
    hl_result r = hl_transport_load(ctx, argv[0], &t);
    int rc = 0;
    if (r != HL_OK) rc = cli_fail(ctx, r);
    else hl_tools_transport_report(t, argv[0], stdout);
    hl_transport_destroy(t);
    hl_context_destroy(ctx);
    return rc;
}

static int cmd_devices(int argc, char **argv)
{
    if (argc > 0) {
        fputs("usage: haarlight devices\n\nLists OpenCL platforms and devices and the --device value for each.\n",
              strcmp(argv[0], "--help") ? stderr : stdout);
        return strcmp(argv[0], "--help") ? 2 : 0;
    }
    char err[512];
    if (hl_list_devices(stdout, err, sizeof err) != HL_OK) {
        fprintf(stderr, "haarlight: %s\n", err);
        return 1;
    }
    printf("reference: plain C on the host   (--device ref)\n");
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The precompute benchmark's table: every figure as a ratio to its limit. */
static void print_precompute_bench(const pre_opts *o, hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *d,
                                   const hl_precompute_stats *st, double raw, uint32_t nsample)
{
    double rate = (double)st->rays_cast / st->seconds_rays;
    double per_vertex_seed = 30.0 * 60.0 / 40000.0; /* seed report: 30 min for 40k vertices */
    printf("# precompute benchmark\n\n"
           "mesh: %s%s, %u vertices; N = %u, C = %u, supersample %u; device: %s; %d threads\n\n",
           o->mesh, o->ground ? " + ground" : "", mesh->vertex_count, d->N, d->C, d->supersample,
           hl_context_device_name(ctx), hl_context_threads(ctx));
    printf("| figure | value | limit or target | ratio |\n|---|---|---|---|\n");
    printf("| ray casting | %.2f s, %.1f Mrays/s | Embree raw rtcOccluded16 on the same rays: %.1f Mrays/s (median of 5, %u vertices) | %.2f of raw (target >= 0.80) |\n",
           st->seconds_rays, rate * 1e-6, raw * 1e-6, nsample, rate / raw);
    printf("| waiting for the stages | %.2f s | | |\n", st->seconds_kernels);
    printf("| total | %.2f s | ray-casting time %.2f s | %.2f x (target <= 1.30) |\n", st->seconds_total,
           st->seconds_rays, st->seconds_total / st->seconds_rays);
    printf("| total | %.2f s | 30 s | %.2f of the budget |\n", st->seconds_total, st->seconds_total / 30.0);
    printf("| rays | %llu cast, %llu culled (%.1f%%) | | |\n", (unsigned long long)st->rays_cast,
           (unsigned long long)st->rays_culled, 100.0 * (double)st->rays_culled / (double)(st->rays_cast + st->rays_culled));
    printf("| coefficients kept | %.1f per vertex | %u slots | %.4f |\n", (double)st->coefficients_kept / mesh->vertex_count,
           2 * d->N * d->N, (double)st->coefficients_kept / mesh->vertex_count / (2.0 * d->N * d->N));
    printf("| seed report | 30 min for 40k vertices = %.1f ms/vertex | this run: %.3f ms/vertex | %.0f x faster |\n",
           per_vertex_seed * 1e3, st->seconds_total / mesh->vertex_count * 1e3,
           per_vertex_seed / (st->seconds_total / mesh->vertex_count));
}

static const char *const usage_bench_precompute =
    "usage: haarlight bench-precompute MESH [precompute options]\n"
    "\n"
    "Precomputes MESH once (into -o FILE, default a temporary file that is removed),\n"
    "then measures Embree's raw occlusion rate on the same rays for up to 512 vertices\n"
    "(median of 5 passes) in the same run, and prints the precompute's figures as\n"
    "ratios to their limits: ray casting against the raw rate, the time left to the\n"
    "device stages. It takes precompute's mesh, sampling, truncation and running\n"
    "options (haarlight precompute --help), but not --resume or --shard: it times a\n"
    "whole run.\n";

/* Precompute once, then Embree's raw rate on the same rays (median of 5),
 * both in this run, and every figure as a ratio to its limit. */
static int cmd_bench_precompute(int argc, char **argv)
{
    pre_opts o;
    int u = parse_pre(argc, argv, usage_bench_precompute, &o);
    if (u) return u;
    if (o.pd.resume) return usage_error(usage_bench_precompute, "%s", "--resume: bench-precompute times a whole run");
    if (o.shard_count) return usage_error(usage_bench_precompute, "%s", "--shard: bench-precompute times a whole run");
    char tmp[256];
    if (!o.out) {
        snprintf(tmp, sizeof tmp, "/tmp/haarlight-bench-%d.hlt", (int)getpid());
        o.out = tmp;
    }
    hl_context *ctx = cli_context(&o.cd);
    if (!ctx) return 1;
    hl_mesh *mesh = NULL;
    hl_precompute_stats st;
    double rates[5];
    hl_result r = load_scene(ctx, &o, &mesh);
    if (r == HL_OK) r = hl_precompute(ctx, mesh, &o.pd, o.out, &st);
    hl_precompute_desc d = o.pd;
    if (r == HL_OK) r = hl_bench_precompute_resolve(ctx, &d);
    uint32_t nsample = mesh && mesh->vertex_count < 512 ? mesh->vertex_count : 512, verts[512];
    for (uint32_t i = 0; i < nsample; i++) verts[i] = (uint32_t)((uint64_t)i * mesh->vertex_count / nsample);
    if (r == HL_OK) r = hl_bench_raw_ray_rates(ctx, mesh, &d, verts, nsample, 5, rates);
    int rc = 0;
    if (r != HL_OK) rc = cli_fail(ctx, r);
    else {
        qsort(rates, 5, sizeof rates[0], cmp_double);
        print_precompute_bench(&o, ctx, mesh, &d, &st, rates[2], nsample);
    }
    if (o.out == tmp) remove(tmp);
    hl_mesh_destroy(mesh);
    cli_unwatch();
    hl_context_destroy(ctx);
    return rc;
}

int main(int argc, char **argv)
{
    signal(SIGINT, on_sigint);
    signal(SIGTERM, on_sigint);
    if (argc < 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        fputs(usage_main, argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("haarlight %s\n", HL_VERSION);
        return 0;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "precompute")) return cmd_precompute(argc - 2, argv + 2);
    if (!strcmp(cmd, "info")) return cmd_info(argc - 2, argv + 2);
    if (!strcmp(cmd, "merge")) return cmd_merge(argc - 2, argv + 2);
    if (!strcmp(cmd, "devices")) return cmd_devices(argc - 2, argv + 2);
    if (!strcmp(cmd, "relight")) return cmd_relight(argc - 2, argv + 2);
    if (!strcmp(cmd, "relight-dynamic")) return cmd_relight_dynamic(argc - 2, argv + 2);
    if (!strcmp(cmd, "view")) {
#ifdef HL_HAVE_VIEWER
        return cmd_view(argc - 2, argv + 2);
#else
        fprintf(stderr, "haarlight: view: this haarlight was built without the viewer; it needs GLFW 3.3 and OpenGL "
                        "(Debian: libglfw3-dev, libgl1-mesa-dev), then configure with -DHL_WITH_VIEWER=ON\n");
        return 1;
#endif
    }
    if (!strcmp(cmd, "check")) return cmd_check(argc - 2, argv + 2);
    if (!strcmp(cmd, "bench")) return cmd_bench(argc - 2, argv + 2);
    if (!strcmp(cmd, "bench-dynamic")) return cmd_bench_dynamic(argc - 2, argv + 2);
    if (!strcmp(cmd, "bench-basis")) return cmd_bench_basis(argc - 2, argv + 2);
    if (!strcmp(cmd, "bench-precompute")) return cmd_bench_precompute(argc - 2, argv + 2);
    fprintf(stderr, "haarlight: unknown command %s\n\n%s", cmd, usage_main);
    return 2;
}
