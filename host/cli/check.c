/* check.c - `haarlight check`: every OpenCL stage against its plain-C twin
 * on a transport file's own mesh and an environment, with the worst
 * difference per stage. Each stage gets identical inputs on both sides.
 *
 * This file parses the options and prints the table; the comparisons are
 * the library's (haarlight_tools.h, host/src/tools/check_stages.c).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "haarlight_tools.h"

static const char *const usage_check =
    "usage: haarlight check SCENE.hlt [--env ENV.exr | --sky] [options]\n"
    "\n"
    "Runs every OpenCL stage and its plain-C twin on the same inputs and prints\n"
    "the worst difference per stage: the precompute stages on a sample of the\n"
    "file's vertices (re-casting their rays), then the lighting stages. Exits 1\n"
    "if a float stage differs by more than 1e-5 (relative) or an integer stage\n"
    "differs at all.\n"
    "\n"
    "  --env ENV.exr      environment, OpenEXR or .hdr (default: the procedural sky)\n"
    "  --layout L         auto (by size), equirect, angular, cross-h or cross-v\n"
    "  --sky              the procedural sky\n"
    "  --terms M|all      lighting terms (default 200)\n"
    "  --select S         selection weights: transport (default, as relight), area\n"
    "                     or unweighted\n"
    "  --rotate DEG       environment rotation (default 0)\n"
    "  --vertices K       precompute stages on K vertices spread over the mesh (default 64)\n"
    "  --device cl:P:D    OpenCL device to check (default: the first, or\n"
    "                     HL_OPENCL_DEVICE=P:D; HL_DEVICE_SHAPE=cpu|gpu forces the shape)\n"
    "  --device-memory SIZE  most device memory to use, e.g. 512M (default: the device's;\n"
    "                     also HL_DEVICE_MEMORY)\n";

typedef struct check_opts {
    const char *scene, *env_path;
    hl_env_layout layout;
    hl_context_desc cd;
    hl_relight_desc rd;
    uint32_t K;
} check_opts;

/* Options; returns -1 to go on, else the exit code. */
static int parse_check(int argc, char **argv, check_opts *o)
{
    const char *usage = usage_check;
    memset(o, 0, sizeof *o);
    o->cd = (hl_context_desc){.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .quiet = 1};
    o->K = 64;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
#define NEED() do { if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a); v = argv[++i]; } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage, stdout); return 0; }
        else if (!strcmp(a, "--env")) { NEED(); o->env_path = v; }
        else if (!strcmp(a, "--layout")) { NEED(); if (!parse_layout(v, &o->layout)) return usage_error(usage, "--layout %s: expected auto, equirect, angular, cross-h or cross-v", v); }
        else if (!strcmp(a, "--sky")) o->env_path = NULL;
        else if (!strcmp(a, "--terms")) {
            NEED();
            if (!strcmp(v, "all")) o->rd.terms = HL_TERMS_ALL;
            else if (!parse_u32(v, &o->rd.terms) || o->rd.terms < 1) return usage_error(usage, "--terms %s: expected M >= 1 or `all`", v);
        } else if (!strcmp(a, "--select")) {
            NEED();
            if (!parse_select(v, &o->rd.select))
                return usage_error(usage, "--select %s: expected transport, area or unweighted", v);
        } else if (!strcmp(a, "--rotate")) { NEED(); if (!parse_float(v, &o->rd.rotate_deg)) return usage_error(usage, "--rotate %s: expected degrees", v); }
        else if (!strcmp(a, "--vertices")) { NEED(); if (!parse_u32(v, &o->K) || o->K < 1 || o->K > 100000) return usage_error(usage, "--vertices %s: expected 1 to 100000", v); }
        else if (!strcmp(a, "--device-memory")) {
            NEED();
            if (!parse_device_memory(v, &o->cd)) return usage_error(usage, "--device-memory %s: expected a byte count such as 512M or 2G", v);
        } else if (!strcmp(a, "--device")) {
            NEED();
            if (!parse_device(v, &o->cd) || o->cd.backend != HL_BACKEND_OPENCL) return usage_error(usage, "--device %s: expected cl or cl:PLATFORM:DEVICE", v);
        } else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (!o->scene) o->scene = a;
        else return usage_error(usage, "unexpected argument %s", a);
#undef NEED
    }
    if (!o->scene) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (!o->rd.terms) o->rd.terms = 200;
    if (!o->rd.select) o->rd.select = HL_SELECT_TRANSPORT;
    return -1;
}

/* One row of the table (hl_check_report_fn). */
static void print_row(void *user, const hl_check_row *r)
{
    (void)user;
    int ok = r->worst <= r->tolerance && r->mismatches == 0;
    printf("| %-33s | %11.3g | %9.3g | %10llu of %-9llu | %s |\n", r->stage, r->worst, r->tolerance,
           (unsigned long long)r->mismatches, (unsigned long long)r->of, ok ? "ok" : "DIFFERS");
}

/* The table: the precompute stages, then the lighting stages, then what
 * the selection kept. Returns the first failure. */
static hl_result run_checks(const check_opts *o, hl_context *cl, hl_stage_check *chk, const hl_env *env, int *all_ok)
{
    printf("# check: %s on %s against the plain-C reference\n\n", o->scene, hl_context_device_name(cl));
    printf("| stage                             | worst diff  | tolerance | mismatches           | result |\n");
    printf("|-----------------------------------|-------------|-----------|----------------------|--------|\n");
    hl_check_summary s;
    hl_result r = hl_stage_check_precompute(chk, cl, o->K, print_row, NULL, all_ok);
    if (r == HL_OK) r = hl_stage_check_lighting(chk, cl, env, &o->rd, print_row, NULL, all_ok, &s);
    if (r == HL_OK)
        printf("\n%u of %u lighting terms kept (%s selection, %.4f%% of the energy), %u of %u blocks used; %u vertices\n"
               "checked in the precompute stages, all %u in the lighting stages.\n",
               s.terms_kept, s.coefficients, select_name(o->rd.select), s.energy_percent, s.blocks_used, s.blocks,
               s.precompute_vertices, s.vertices);
    return r;
}

int cmd_check(int argc, char **argv)
{
    check_opts o;
    int u = parse_check(argc, argv, &o);
    if (u >= 0) return u;
    hl_context *cl = NULL, *ref = NULL;
    if (!cli_context_pair(&o.cd, &cl, &ref)) return 1;
    cli_watch(cl, ref);
    hl_transport *t = NULL;
    hl_env *env = NULL;
    hl_stage_check *chk = NULL;
    hl_sky_desc sky = {0};
    hl_result r = hl_transport_load(ref, o.scene, &t);
    if (r == HL_OK) r = o.env_path ? cli_env_load(ref, o.env_path, o.layout, &env, 0) : hl_env_create_sky(ref, &sky, &env);
    if (r == HL_OK) r = hl_stage_check_create(ref, t, &chk);
    int rc, all_ok = 1;
    if (r != HL_OK) rc = cli_fail(ref, r); /* nothing printed yet */
    else {
        r = run_checks(&o, cl, chk, env, &all_ok);
        rc = r != HL_OK ? cli_fail(hl_context_last_error(cl)[0] ? cl : ref, r) : (all_ok ? 0 : 1);
        if (r == HL_OK && !all_ok) fprintf(stderr, "haarlight: the OpenCL device and the reference differ\n");
    }
    hl_stage_check_destroy(chk);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    cli_unwatch();
    hl_context_destroy(cl);
    hl_context_destroy(ref);
    return rc;
}
