/* check.c - `haarlight check`: every OpenCL stage against its plain-C twin
 * on a transport file's own mesh and an environment, with the worst
 * difference per stage. Each stage gets identical inputs on both sides.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_backend.h"
#include "cli.h"
#include "lighting.h"
#include "precompute.h"
#include "rays.h"
#include "twins.h"

static const char *const usage_check =
    "usage: haarlight check SCENE.hlt [--env ENV.exr | --sky] [options]\n"
    "\n"
    "Runs every OpenCL stage and its plain-C twin on the same inputs and prints\n"
    "the worst difference per stage: the precompute stages on a sample of the\n"
    "file's vertices (re-casting their rays), then the lighting stages. Exits 1\n"
    "if a float stage differs by more than 1e-5 (relative) or an integer stage\n"
    "differs at all.\n"
    "\n"
    "  --env ENV.exr      environment (default: the procedural sky)\n"
    "  --sky              the procedural sky\n"
    "  --terms M|all      lighting terms (default 200)\n"
    "  --select S         selection weights: transport (default, as relight), area\n"
    "                     or unweighted\n"
    "  --rotate DEG       environment rotation (default 0)\n"
    "  --vertices K       precompute stages on K vertices spread over the mesh (default 64)\n"
    "  --device cl:P:D    OpenCL device to check (default: the first)\n"
    "  --device-memory SIZE  most device memory to use, e.g. 512M (default: the device's;\n"
    "                     also HL_DEVICE_MEMORY)\n";

typedef struct row_report { const char *stage; double worst; double tol; uint64_t mismatches; uint64_t of; } row_report;

static int report(const row_report *r)
{
    int ok = r->worst <= r->tol && r->mismatches == 0;
    printf("| %-26s | %11.3g | %9.3g | %10llu of %-9llu | %s |\n", r->stage, r->worst, r->tol,
           (unsigned long long)r->mismatches, (unsigned long long)r->of, ok ? "ok" : "DIFFERS");
    return ok;
}

static double rel_worst(const float *a, const float *b, size_t n)
{
    double w = 0.0, s = 0.0;
    for (size_t i = 0; i < n; i++) s = fmax(s, fabs(a[i]));
    for (size_t i = 0; i < n; i++) w = fmax(w, fabs((double)a[i] - b[i]));
    return s > 0 ? w / s : w;
}

int cmd_check(int argc, char **argv)
{
    const char *usage = usage_check, *scene = NULL, *env_path = NULL;
    hl_context_desc cd = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .quiet = 1};
    hl_relight_desc rd = {0};
    uint32_t K = 64;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = NULL;
#define NEED() do { if (i + 1 >= argc) return usage_error(usage, "option %s needs a value", a); v = argv[++i]; } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { fputs(usage, stdout); return 0; }
        else if (!strcmp(a, "--env")) { NEED(); env_path = v; }
        else if (!strcmp(a, "--sky")) env_path = NULL;
        else if (!strcmp(a, "--terms")) {
            NEED();
            if (!strcmp(v, "all")) rd.terms = HL_TERMS_ALL;
            else if (!parse_u32(v, &rd.terms) || rd.terms < 1) return usage_error(usage, "--terms %s: expected M >= 1 or `all`", v);
        } else if (!strcmp(a, "--select")) {
            NEED();
            if (!parse_select(v, &rd.select))
                return usage_error(usage, "--select %s: expected transport, area or unweighted", v);
        } else if (!strcmp(a, "--rotate")) { NEED(); if (!parse_float(v, &rd.rotate_deg)) return usage_error(usage, "--rotate %s: expected degrees", v); }
        else if (!strcmp(a, "--vertices")) { NEED(); if (!parse_u32(v, &K) || K < 1 || K > 100000) return usage_error(usage, "--vertices %s: expected 1 to 100000", v); }
        else if (!strcmp(a, "--device-memory")) {
            NEED();
            if (!parse_device_memory(v, &cd)) return usage_error(usage, "--device-memory %s: expected a byte count such as 512M or 2G", v);
        } else if (!strcmp(a, "--device")) {
            NEED();
            if (!parse_device(v, &cd) || cd.backend != HL_BACKEND_OPENCL) return usage_error(usage, "--device %s: expected cl or cl:PLATFORM:DEVICE", v);
        } else if (a[0] == '-' && a[1]) return usage_error(usage, "unknown option %s", a);
        else if (!scene) scene = a;
        else return usage_error(usage, "unexpected argument %s", a);
#undef NEED
    }
    if (!scene) return usage_error(usage, "%s", "no SCENE.hlt given");
    if (!rd.terms) rd.terms = 200;
    if (!rd.select) rd.select = HL_SELECT_TRANSPORT;
    hl_context *cl = NULL, *ref = NULL;
    if (!cli_context_pair(&cd, &cl, &ref)) return 1;
    cli_watch(cl, ref);
    hl_transport *t = NULL;
    hl_env *env = NULL;
    hl_geom *g = NULL;
    hl_light_geom *lg = NULL;
    hl_rt *rt = NULL;
    hl_cl_pipe *pipe = NULL;
    hl_cl_light *light = NULL;
    hl_sky_desc sky = {0};
    hl_result r = hl_transport_load(ref, scene, &t);
    if (r == HL_OK) r = env_path ? cli_env_load(ref, env_path, &env, 0) : hl_env_create_sky(ref, &sky, &env);
    if (r == HL_OK) r = hl_geom_create(ref, t->info.N, t->info.C, &g);
    if (r == HL_OK) r = hl_light_geom_create(ref, g, &lg);
    if (r != HL_OK) {
        int rc = cli_fail(ref, r);
        hl_transport_destroy(t);
        hl_env_destroy(env);
        hl_geom_destroy(g);
        cli_unwatch();
        hl_context_destroy(cl);
        hl_context_destroy(ref);
        return rc;
    }
    const hl_transport_info *in = &t->info;
    const uint32_t V = in->vertex_count, nc = g->ncoef, nb = g->nblocks;
    if (K > V) K = V;
    printf("# check: %s on %s against the plain-C reference\n\n", scene, hl_context_device_name(cl));
    printf("| stage                      | worst diff  | tolerance | mismatches           | result |\n");
    printf("|----------------------------|-------------|-----------|----------------------|--------|\n");
    int all_ok = 1;

    /* precompute stages on K vertices */
    hl_precompute_desc pd = {.N = in->N, .C = in->C, .supersample = in->supersample, .rule = in->rule, .K = in->K,
                             .eps = in->eps, .quant = in->quant, .ray_offset = in->ray_offset};
    if (pd.rule == HL_TRUNC_ENERGY && pd.eps == 0.0f) pd.eps = HL_DEFAULT_EPS;
    hl_trunc_params tp = hl_precompute_trunc_params(&pd);
    float scale = (float)(1.0 / (HL_PI * in->supersample * in->supersample));
    uint8_t *vis = malloc((size_t)K * g->ncube);
    float *n4 = malloc((size_t)K * 16), *Ta = malloc((size_t)K * nc * 4), *Tb = malloc((size_t)K * nc * 4);
    float *Tc = malloc((size_t)K * nc * 4), *ca = malloc((size_t)K * nc * 4), *cb = malloc((size_t)K * nc * 4);
    hl_trunc_result *tra = malloc(K * sizeof *tra), *trb = malloc(K * sizeof *trb);
    hl_row_quant *rqa = malloc(K * sizeof *rqa), *rqb = malloc(K * sizeof *rqb);
    uint16_t *bca = malloc((size_t)K * nb * 2), *bcb = malloc((size_t)K * nb * 2);
    uint8_t *ea = calloc((size_t)K * nc, 2), *eb = calloc((size_t)K * nc, 2);
    uint32_t *na = malloc(K * 4), *nbb = malloc(K * 4), *idx = malloc(K * 4);
    hl_ref_key *keys = malloc((size_t)nc * sizeof *keys); /* scratch of hl_ref_truncate and hl_ref_select */
    if (!vis || !n4 || !Ta || !Tb || !Tc || !ca || !cb || !tra || !trb || !rqa || !rqb || !bca || !bcb || !ea || !eb ||
        !na || !nbb || !idx || !keys)
        r = hl_fail(ref, HL_ERR_OUT_OF_MEMORY, "out of memory for %u vertices' precompute stages (%.1f GB); "
                    "try fewer --vertices", K, 5.0 * 4.0 * (double)K * nc / 1e9);
    if (r == HL_OK) r = hl_rt_create(ref, t->mesh, &rt);
    if (r == HL_OK) r = hl_cl_pipe_create(cl, g, K, &pipe);
    for (uint32_t i = 0; r == HL_OK && i < K; i++) {
        idx[i] = (uint32_t)((uint64_t)i * V / K);
        memcpy(n4 + 4 * i, t->mesh->normals + 3 * (size_t)idx[i], 12);
        n4[4 * i + 3] = 0.0f;
        r = hl_rt_visibility(rt, g, t->mesh, idx[i], 1, in->supersample, in->ray_offset * hl_mesh_query_diagonal(t->mesh),
                             vis + (size_t)i * g->ncube, NULL);
    }
    if (r == HL_OK) {
        for (uint32_t i = 0; i < K; i++) hl_ref_cube2para(g, vis + (size_t)i * g->ncube, scale, n4 + 4 * i, Ta + (size_t)i * nc);
        r = hl_cl_pipe_cube2para(pipe, K, vis, scale, n4, Tb);
    }
    if (r == HL_OK) {
        all_ok &= report(&(row_report){"cube2para (float)", rel_worst(Ta, Tb, (size_t)K * nc), 1e-5, 0, (uint64_t)K * nc});
        memcpy(Tc, Ta, (size_t)K * nc * 4);
        for (uint32_t i = 0; i < K; i++) hl_ref_haar(g, Tc + (size_t)i * nc, ca + (size_t)i * nc);
        r = hl_cl_pipe_haar(pipe, K, Ta, cb);
    }
    if (r == HL_OK) {
        all_ok &= report(&(row_report){"haar (float)", rel_worst(ca, cb, (size_t)K * nc), 1e-5, 0, (uint64_t)K * nc});
        for (uint32_t i = 0; i < K; i++) tra[i] = hl_ref_truncate(g, ca + (size_t)i * nc, tp, keys);
        r = hl_cl_pipe_truncate(pipe, K, ca, tp, trb);
    }
    if (r == HL_OK) {
        uint64_t mm = 0;
        for (uint32_t i = 0; i < K; i++) mm += memcmp(&tra[i], &trb[i], 12) != 0;
        all_ok &= report(&(row_report){"truncate (integers)", 0.0, 0.0, mm, K});
        /* each row as its vertex, one at a time on the device: sqrt8's
           dither depends on the vertex, and the sampled ones are apart */
        for (uint32_t i = 0; i < K; i++)
            na[i] = hl_ref_quantize(g, ca + (size_t)i * nc, tra[i], in->quant, idx[i], &rqa[i], bca + (size_t)i * nb,
                                    ea + (size_t)i * nc * 2);
        for (uint32_t i = 0; i < K && r == HL_OK; i++)
            r = hl_cl_pipe_quantize(pipe, 1, idx[i], ca + (size_t)i * nc, tra + i, in->quant, rqb + i,
                                    bcb + (size_t)i * nb, eb + (size_t)i * nc * 2, nbb + i);
    }
    if (r == HL_OK) {
        uint64_t mm = 0, stored = 0;
        for (uint32_t i = 0; i < K; i++) {
            mm += !(na[i] == nbb[i] && !memcmp(&rqa[i], &rqb[i], 8) && !memcmp(bca + (size_t)i * nb, bcb + (size_t)i * nb, nb * 2u) &&
                    !memcmp(ea + (size_t)i * nc * 2, eb + (size_t)i * nc * 2, 2 * (size_t)na[i]));
            /* the file's own row for this vertex, made by precompute */
            uint32_t v = idx[i];
            stored += !(t->row_offset[v + 1] - t->row_offset[v] == na[i] && !memcmp(&t->row_quant[v], &rqa[i], 8) &&
                        !memcmp(t->block_counts + (size_t)v * nb, bca + (size_t)i * nb, nb * 2u) &&
                        !memcmp(t->entries + 2 * t->row_offset[v], ea + (size_t)i * nc * 2, 2 * (size_t)na[i]));
        }
        all_ok &= report(&(row_report){"quantize+pack (integers)", 0.0, 0.0, mm, K});
        all_ok &= report(&(row_report){"rows stored in the file", 0.0, 0.0, stored, K});
    }
    hl_cl_pipe_destroy(pipe);

    /* lighting stages */
    float *cells = NULL, *alb = malloc((size_t)V * 16), *La = malloc((size_t)nc * 12), *Lb = malloc((size_t)nc * 12);
    float *wa = malloc((size_t)nc * 12), *wb = malloc((size_t)nc * 12), *sa = malloc((size_t)nc * 16), *sb = malloc((size_t)nc * 16);
    float *Ba = malloc((size_t)V * 16), *Bb = malloc((size_t)V * 16), *wsel = malloc((size_t)nc * 4);
    uint8_t *ua = malloc(nb), *ub = malloc(nb);
    uint32_t *ka = malloc((size_t)nc / 8), *kb = malloc((size_t)nc / 8);
    if (r == HL_OK && (!alb || !La || !Lb || !wa || !wb || !sa || !sb || !Ba || !Bb || !wsel || !ua || !ub || !ka || !kb))
        r = hl_fail(ref, HL_ERR_OUT_OF_MEMORY, "out of memory for the lighting stages");
    for (uint32_t v = 0; r == HL_OK && v < V; v++) {
        memcpy(alb + 4 * (size_t)v, t->mesh->albedo + 3 * (size_t)v, 12);
        alb[4 * (size_t)v + 3] = 0.0f;
    }
    if (r == HL_OK) r = hl_env_to_cells(ref, env, lg->wc, lg->hc, &cells);
    if (r == HL_OK) r = hl_cl_light_create(cl, g, lg, t, alb, &light);
    if (r == HL_OK) r = hl_cl_light_set_cells(light, cells);
    if (r == HL_OK) r = hl_selection_weights(ref, t, lg, rd.select, wsel);
    if (r == HL_OK) r = hl_cl_light_set_weights(light, wsel);
    uint32_t s0 = 0;
    float f = 0.0f;
    hl_rotation_to_shift(rd.rotate_deg, lg->wc, &s0, &f);
    if (r == HL_OK) {
        hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, s0, f, nc, La);
        r = hl_cl_light_stage_env2para(light, s0, f, Lb);
    }
    if (r == HL_OK) {
        all_ok &= report(&(row_report){"env2para (float)", rel_worst(La, Lb, (size_t)nc * 3), 1e-5, 0, (uint64_t)nc * 3});
        memcpy(Lb, La, (size_t)nc * 12);
        r = hl_cl_light_stage_haar(light, Lb, wb);
        for (int c = 0; c < 3; c++) hl_ref_haar(g, La + (size_t)c * nc, wa + (size_t)c * nc);
    }
    hl_select_params sp = {rd.terms, rd.select, {0, 0}};
    hl_select_result sra, srb;
    if (r == HL_OK) {
        all_ok &= report(&(row_report){"haar of the lighting", rel_worst(wa, wb, (size_t)nc * 3), 1e-5, 0, (uint64_t)nc * 3});
        sra = hl_ref_select(wa, nc, wsel, sp, sa, ua, ka, nb, keys);
        r = hl_cl_light_stage_select(light, wa, sp, sb, ub, kb, &srb);
    }
    if (r == HL_OK) {
        uint64_t mm = 0;
        for (uint32_t i = 0; i < nc; i++) mm += memcmp(sa + 4 * i, sb + 4 * i, 16) != 0;
        mm += memcmp(ua, ub, nb) != 0 || memcmp(ka, kb, nc / 8) != 0 || sra.kept != srb.kept;
        all_ok &= report(&(row_report){"select (kept terms)", 0.0, 0.0, mm, nc});
        for (uint32_t v = 0; v < V; v++)
            hl_ref_relight(t->entries + 2 * t->row_offset[v], t->block_counts + (size_t)v * nb, t->row_quant[v], in->quant, v, nb, sa,
                           alb + 4 * (size_t)v, 0, Ba + 4 * (size_t)v);
        r = hl_cl_light_stage_relight(light, sa, ka, Bb);
    }
    if (r == HL_OK) {
        double w = 0.0, s = 0.0;
        for (uint32_t v = 0; v < V; v++)
            for (int c = 0; c < 3; c++) {
                s = fmax(s, fabs(Ba[4 * (size_t)v + c]));
                w = fmax(w, fabs((double)Ba[4 * (size_t)v + c] - Bb[4 * (size_t)v + c]));
            }
        all_ok &= report(&(row_report){"relight dot products", s > 0 ? w / s : w, 1e-5, 0, (uint64_t)V * 3});
        printf("\n%u of %u lighting terms kept (%s selection, %.4f%% of the energy), %u of %u blocks used; %u vertices\n"
               "checked in the precompute stages, all %u in the lighting stages.\n",
               sra.kept, nc,
               select_name(rd.select), sra.energy_total > 0 ? 100.0 * sra.energy_kept / sra.energy_total : 100.0, sra.blocks_used, nb, K, V);
    }
    int rc = r != HL_OK ? cli_fail(r == HL_OK ? NULL : (hl_context_last_error(cl)[0] ? cl : ref), r) : (all_ok ? 0 : 1);
    if (r == HL_OK && !all_ok) fprintf(stderr, "haarlight: the OpenCL device and the reference differ\n");
    hl_cl_light_destroy(light);
    hl_free_big(cells);
    free(alb); free(La); free(Lb); free(wa); free(wb); free(sa); free(sb); free(Ba); free(Bb); free(wsel); free(ua); free(ub); free(ka); free(kb);
    free(vis); free(n4); free(Ta); free(Tb); free(Tc); free(ca); free(cb); free(tra); free(trb); free(rqa); free(rqb);
    free(bca); free(bcb); free(ea); free(eb); free(na); free(nbb); free(idx); free(keys);
    hl_rt_destroy(rt);
    hl_light_geom_destroy(lg);
    hl_geom_destroy(g);
    hl_env_destroy(env);
    hl_transport_destroy(t);
    cli_unwatch();
    hl_context_destroy(cl);
    hl_context_destroy(ref);
    return rc;
}
