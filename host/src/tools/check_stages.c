/* check_stages.c - `haarlight check`'s comparisons: every OpenCL stage
 * against its plain-C twin on identical inputs, the precompute stages on
 * a sample of a transport's vertices (their rays re-cast) and the lighting
 * stages on all of them, with the worst difference per stage.
 *
 * Depends on the OpenCL backend (cl_backend.h), the twins (twins.h), the
 * ray caster (rays.h), the precompute's parameters (precompute.h) and the
 * lighting tables (lighting.h). The command prints what this reports.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cl_backend.h"
#include "cube.h"
#include "haarlight_tools.h"
#include "lighting.h"
#include "precompute.h"
#include "rays.h"
#include "sh.h"
#include "twins.h"

struct hl_stage_check {
    hl_context *ref;
    const hl_transport *t;
    hl_geom *g;
    hl_light_geom *lg;
    hl_ref_key *keys; /* scratch of hl_ref_truncate and hl_ref_select */
    uint32_t checked; /* vertices the precompute stages ran on */
    /* the file's basis: spherical harmonics (the rows' and the lighting's
       projections) or cube-face Haar (the face texels' taps); neither for
       paraboloid Haar */
    float *shT, *shL;
    uint32_t sh_stride, sh_count;
    hl_cube_tables *cube;
};

hl_result hl_stage_check_create(hl_context *ref, const hl_transport *t, hl_stage_check **out)
{
    *out = NULL;
    hl_stage_check *c = hl_calloc(ref, 1, sizeof *c, "the stage check");
    if (!c) return HL_ERR_OUT_OF_MEMORY;
    c->ref = ref;
    c->t = t;
    hl_result r = hl_geom_create(ref, t->info.N, t->info.C, &c->g);
    if (r == HL_OK) r = hl_light_geom_create(ref, c->g, &c->lg);
    if (r == HL_OK) {
        c->keys = malloc((size_t)c->g->ncoef * sizeof *c->keys);
        if (!c->keys) r = hl_fail(ref, HL_ERR_OUT_OF_MEMORY, "out of memory for the stage check");
    }
    const uint32_t word = t->info.sh_order; /* SH: the order; cube-face Haar: the side */
    if (r == HL_OK && t->info.basis == HL_TRANSPORT_BASIS_SH) {
        c->sh_stride = hl_sh_stride(word);
        c->sh_count = hl_sh_count(word);
        r = hl_sh_matrix(ref, t->info.N, word, 1, &c->shT);
        if (r == HL_OK) r = hl_sh_matrix(ref, t->info.N, word, 0, &c->shL);
    }
    if (r == HL_OK && t->info.basis == HL_TRANSPORT_BASIS_CUBE)
        r = hl_cube_tables_create(ref, word, t->info.C, c->lg->wc, c->lg->hc, &c->cube);
    if (r != HL_OK) {
        hl_stage_check_destroy(c);
        return r;
    }
    *out = c;
    return HL_OK;
}

void hl_stage_check_destroy(hl_stage_check *c)
{
    if (!c) return;
    free(c->keys);
    hl_free_big(c->shT);
    hl_free_big(c->shL);
    hl_cube_tables_destroy(c->cube);
    hl_light_geom_destroy(c->lg);
    hl_geom_destroy(c->g);
    free(c);
}

/* Worst difference of b from a, relative to a's largest magnitude. */
static double rel_worst(const float *a, const float *b, size_t n)
{
    double w = 0.0, s = 0.0;
    for (size_t i = 0; i < n; i++) s = fmax(s, fabs(a[i]));
    for (size_t i = 0; i < n; i++) w = fmax(w, fabs((double)a[i] - b[i]));
    return s > 0 ? w / s : w;
}

static void put(hl_check_report_fn report, void *user, int *ok, hl_check_row row)
{
    *ok &= row.worst <= row.tolerance && row.mismatches == 0;
    report(user, &row);
}

/* ---------------------------------------------------------------- precompute stages */

/* Both sides' rows for K sampled vertices: a for the twins, b for the
 * device (c is the twin's Haar input, which it overwrites). */
typedef struct pre_rows {
    uint32_t K, nc, nb;
    uint8_t *vis;
    float *n4, *Ta, *Tb, *Tc, *ca, *cb;
    hl_trunc_result *tra, *trb;
    hl_row_quant *rqa, *rqb;
    uint16_t *bca, *bcb;
    uint8_t *ea, *eb;
    uint32_t *na, *nbb, *idx;
} pre_rows;

static void pre_free(pre_rows *p)
{
    free(p->vis); free(p->n4); free(p->Ta); free(p->Tb); free(p->Tc); free(p->ca); free(p->cb); free(p->tra);
    free(p->trb); free(p->rqa); free(p->rqb); free(p->bca); free(p->bcb); free(p->ea); free(p->eb); free(p->na);
    free(p->nbb); free(p->idx);
}

static hl_result pre_alloc(hl_stage_check *c, uint32_t K, pre_rows *p)
{
    const uint32_t nc = c->g->ncoef, nb = c->g->nblocks;
    memset(p, 0, sizeof *p);
    p->K = K;
    p->nc = nc;
    p->nb = nb;
    p->vis = malloc((size_t)K * c->g->ncube);
    p->n4 = malloc((size_t)K * 16), p->Ta = malloc((size_t)K * nc * 4), p->Tb = malloc((size_t)K * nc * 4);
    p->Tc = malloc((size_t)K * nc * 4), p->ca = malloc((size_t)K * nc * 4), p->cb = malloc((size_t)K * nc * 4);
    p->tra = malloc(K * sizeof *p->tra), p->trb = malloc(K * sizeof *p->trb);
    p->rqa = malloc(K * sizeof *p->rqa), p->rqb = malloc(K * sizeof *p->rqb);
    p->bca = malloc((size_t)K * nb * 2), p->bcb = malloc((size_t)K * nb * 2);
    p->ea = calloc((size_t)K * nc, 2), p->eb = calloc((size_t)K * nc, 2);
    p->na = malloc(K * 4), p->nbb = malloc(K * 4), p->idx = malloc(K * 4);
    if (!p->vis || !p->n4 || !p->Ta || !p->Tb || !p->Tc || !p->ca || !p->cb || !p->tra || !p->trb || !p->rqa ||
        !p->rqb || !p->bca || !p->bcb || !p->ea || !p->eb || !p->na || !p->nbb || !p->idx)
        return hl_fail(c->ref, HL_ERR_OUT_OF_MEMORY, "out of memory for %u vertices' precompute stages (%.1f GB); "
                       "try fewer --vertices", K, 5.0 * 4.0 * (double)K * nc / 1e9);
    return HL_OK;
}

/* The sampled vertices' normals and visibility, spread evenly over the mesh. */
static hl_result pre_rays(hl_stage_check *c, pre_rows *p)
{
    const hl_transport *t = c->t;
    const uint32_t V = t->info.vertex_count;
    hl_rt *rt = NULL;
    hl_result r = hl_rt_create(c->ref, t->mesh, &rt);
    for (uint32_t i = 0; r == HL_OK && i < p->K; i++) {
        p->idx[i] = (uint32_t)((uint64_t)i * V / p->K);
        memcpy(p->n4 + 4 * i, t->mesh->normals + 3 * (size_t)p->idx[i], 12);
        p->n4[4 * i + 3] = 0.0f;
        r = hl_rt_visibility(rt, c->g, t->mesh, p->idx[i], 1, t->info.supersample,
                             t->info.ray_offset * hl_mesh_query_diagonal(t->mesh), p->vis + (size_t)i * c->g->ncube,
                             NULL);
    }
    hl_rt_destroy(rt);
    return r;
}

/* Quantisation and packing compared, then the twin's rows against the
 * rows the file stores; each row as its vertex, one at a time on the
 * device: sqrt8's dither depends on the vertex, and the sampled ones are
 * apart. */
static hl_result pre_quantize(hl_stage_check *c, hl_cl_pipe *pipe, pre_rows *p, hl_check_report_fn report, void *user,
                              int *ok)
{
    const hl_transport *t = c->t;
    const uint32_t K = p->K, nc = p->nc, nb = p->nb, quant = t->info.quant;
    hl_result r = HL_OK;
    for (uint32_t i = 0; i < K; i++)
        p->na[i] = hl_ref_quantize(c->g, p->ca + (size_t)i * nc, p->tra[i], quant, p->idx[i], &p->rqa[i],
                                   p->bca + (size_t)i * nb, p->ea + (size_t)i * nc * 2);
    for (uint32_t i = 0; i < K && r == HL_OK; i++)
        r = hl_cl_pipe_quantize(pipe, 1, p->idx[i], p->ca + (size_t)i * nc, p->tra + i, quant, p->rqb + i,
                                p->bcb + (size_t)i * nb, p->eb + (size_t)i * nc * 2, p->nbb + i);
    if (r != HL_OK) return r;
    uint64_t mm = 0, stored = 0;
    for (uint32_t i = 0; i < K; i++) {
        mm += !(p->na[i] == p->nbb[i] && !memcmp(&p->rqa[i], &p->rqb[i], 8) &&
                !memcmp(p->bca + (size_t)i * nb, p->bcb + (size_t)i * nb, nb * 2u) &&
                !memcmp(p->ea + (size_t)i * nc * 2, p->eb + (size_t)i * nc * 2, 2 * (size_t)p->na[i]));
        /* the file's own row for this vertex, made by precompute */
        uint32_t v = p->idx[i];
        stored += !(t->row_offset[v + 1] - t->row_offset[v] == p->na[i] && !memcmp(&t->row_quant[v], &p->rqa[i], 8) &&
                    !memcmp(t->block_counts + (size_t)v * nb, p->bca + (size_t)i * nb, nb * 2u) &&
                    !memcmp(t->entries + 2 * t->row_offset[v], p->ea + (size_t)i * nc * 2, 2 * (size_t)p->na[i]));
    }
    put(report, user, ok, (hl_check_row){"quantize+pack (integers)", 0.0, 0.0, mm, K});
    /* a bounced file holds T_0 plus its bounces, which these stages do not make */
    if (!t->info.bounces) put(report, user, ok, (hl_check_row){"rows stored in the file", 0.0, 0.0, stored, K});
    return HL_OK;
}

/* The paraboloid rows (cube2para) and their Haar transform or, in an SH
 * file, their projection onto harmonics, each from the twin's output of
 * the stage before. */
static hl_result pre_paraboloid(hl_stage_check *c, hl_cl_pipe *pipe, pre_rows *p, float scale,
                                hl_check_report_fn report, void *user, int *ok)
{
    const uint32_t K = p->K, nc = p->nc;
    for (uint32_t i = 0; i < K; i++)
        hl_ref_cube2para(c->g, p->vis + (size_t)i * c->g->ncube, scale, p->n4 + 4 * i, p->Ta + (size_t)i * nc);
    hl_result r = hl_cl_pipe_cube2para(pipe, K, p->vis, scale, p->n4, p->Tb);
    if (r != HL_OK) return r;
    put(report, user, ok, (hl_check_row){"cube2para (float)", rel_worst(p->Ta, p->Tb, (size_t)K * nc), 1e-5, 0,
                                         (uint64_t)K * nc});
    memcpy(p->Tc, p->Ta, (size_t)K * nc * 4);
    if (c->shT) {
        for (uint32_t i = 0; i < K; i++)
            hl_ref_sh_project_rows(p->Tc + (size_t)i * nc, nc, c->shT, c->sh_stride, c->sh_count, p->ca + (size_t)i * nc);
        r = hl_cl_pipe_set_sh(pipe, c->shT, c->sh_stride, c->sh_count);
        if (r == HL_OK) r = hl_cl_pipe_sh_project(pipe, K, p->Ta, p->cb);
    } else {
        for (uint32_t i = 0; i < K; i++) hl_ref_haar(c->g, p->Tc + (size_t)i * nc, p->ca + (size_t)i * nc);
        r = hl_cl_pipe_haar(pipe, K, p->Ta, p->cb);
    }
    if (r != HL_OK) return r;
    put(report, user, ok, (hl_check_row){c->shT ? "sh projection (float)" : "haar (float)",
                                         rel_worst(p->ca, p->cb, (size_t)K * nc), 1e-5, 0, (uint64_t)K * nc});
    return HL_OK;
}

/* Cube-face Haar: the rows on the faces and their Haar transform, each
 * from the twin's output of the stage before. */
static hl_result pre_cube(hl_stage_check *c, hl_cl_pipe *pipe, pre_rows *p, float scale, hl_check_report_fn report,
                          void *user, int *ok)
{
    const uint32_t K = p->K, nc = p->nc, Cq = c->cube->Cq, nt = c->cube->ntex;
    for (uint32_t i = 0; i < K; i++)
        hl_cube_rows(c->g, Cq, p->vis + (size_t)i * c->g->ncube, scale, p->n4 + 4 * i, p->Ta + (size_t)i * nc);
    hl_result r = hl_cl_pipe_set_cube(pipe, Cq);
    if (r == HL_OK) r = hl_cl_pipe_cube_rows(pipe, K, p->vis, scale, p->n4, p->Tb);
    if (r != HL_OK) return r;
    double w = 0.0;
    for (uint32_t i = 0; i < K; i++)
        w = fmax(w, rel_worst(p->Ta + (size_t)i * nc, p->Tb + (size_t)i * nc, nt));
    put(report, user, ok, (hl_check_row){"cube face rows (float)", w, 1e-5, 0, (uint64_t)K * nt});
    memcpy(p->Tc, p->Ta, (size_t)K * nc * 4);
    for (uint32_t i = 0; i < K; i++) {
        hl_cube_haar(Cq, p->Tc + (size_t)i * nc, p->ca + (size_t)i * nc);
        memset(p->ca + (size_t)i * nc + nt, 0, (size_t)(nc - nt) * 4);
    }
    r = hl_cl_pipe_cube_haar(pipe, K, p->Ta, p->cb);
    if (r != HL_OK) return r;
    put(report, user, ok, (hl_check_row){"cube face haar (float)", rel_worst(p->ca, p->cb, (size_t)K * nc), 1e-5, 0,
                                         (uint64_t)K * nc});
    return HL_OK;
}

/* The rows and their transform (pre_paraboloid or pre_cube), then
 * truncation and quantisation, each from the twin's output of the stage
 * before, so that both sides get identical inputs. */
static hl_result pre_stages(hl_stage_check *c, hl_cl_pipe *pipe, pre_rows *p, hl_check_report_fn report, void *user,
                            int *ok)
{
    const hl_transport_info *in = &c->t->info;
    const uint32_t K = p->K, nc = p->nc;
    hl_precompute_desc pd = {.N = in->N, .C = in->C, .supersample = in->supersample, .rule = in->rule, .K = in->K,
                             .eps = in->eps, .quant = in->quant, .ray_offset = in->ray_offset};
    if (pd.rule == HL_TRUNC_ENERGY && pd.eps == 0.0f) pd.eps = HL_DEFAULT_EPS;
    hl_trunc_params tp = hl_precompute_trunc_params(&pd);
    float scale = (float)(1.0 / (HL_PI * in->supersample * in->supersample));
    hl_result r = c->cube ? pre_cube(c, pipe, p, scale, report, user, ok) : pre_paraboloid(c, pipe, p, scale, report, user, ok);
    if (r != HL_OK) return r;
    for (uint32_t i = 0; i < K; i++) p->tra[i] = hl_ref_truncate(c->g, p->ca + (size_t)i * nc, tp, c->keys);
    r = hl_cl_pipe_truncate(pipe, K, p->ca, tp, p->trb);
    if (r != HL_OK) return r;
    uint64_t mm = 0;
    for (uint32_t i = 0; i < K; i++) mm += memcmp(&p->tra[i], &p->trb[i], 12) != 0;
    put(report, user, ok, (hl_check_row){"truncate (integers)", 0.0, 0.0, mm, K});
    return pre_quantize(c, pipe, p, report, user, ok);
}

hl_result hl_stage_check_precompute(hl_stage_check *c, hl_context *cl, uint32_t vertices, hl_check_report_fn report,
                                    void *user, int *ok)
{
    const uint32_t K = vertices > c->t->info.vertex_count ? c->t->info.vertex_count : vertices;
    c->checked = K;
    pre_rows p;
    hl_cl_pipe *pipe = NULL;
    hl_result r = pre_alloc(c, K, &p);
    if (r == HL_OK) r = hl_cl_pipe_create(cl, c->g, K, &pipe);
    if (r == HL_OK) r = pre_rays(c, &p);
    if (r == HL_OK) r = pre_stages(c, pipe, &p, report, user, ok);
    hl_cl_pipe_destroy(pipe);
    pre_free(&p);
    return r;
}

/* ---------------------------------------------------------------- lighting stages */

/* Both sides' lighting: a for the twins, b for the device. */
typedef struct light_bufs {
    float *cells, *alb, *La, *Lb, *wa, *wb, *sa, *sb, *Ba, *Bb, *wsel;
    uint8_t *ua, *ub;
    uint32_t *ka, *kb;
} light_bufs;

static void light_free(light_bufs *b)
{
    hl_free_big(b->cells);
    free(b->alb); free(b->La); free(b->Lb); free(b->wa); free(b->wb); free(b->sa); free(b->sb); free(b->Ba);
    free(b->Bb); free(b->wsel); free(b->ua); free(b->ub); free(b->ka); free(b->kb);
}

static hl_result light_alloc(hl_stage_check *c, light_bufs *b)
{
    const uint32_t V = c->t->info.vertex_count, nc = c->g->ncoef, nb = c->g->nblocks;
    memset(b, 0, sizeof *b);
    b->alb = malloc((size_t)V * 16), b->La = malloc((size_t)nc * 12), b->Lb = malloc((size_t)nc * 12);
    b->wa = malloc((size_t)nc * 12), b->wb = malloc((size_t)nc * 12), b->sa = malloc((size_t)nc * 16);
    b->sb = malloc((size_t)nc * 16);
    b->Ba = malloc((size_t)V * 16), b->Bb = malloc((size_t)V * 16), b->wsel = malloc((size_t)nc * 4);
    b->ua = malloc(nb), b->ub = malloc(nb);
    b->ka = malloc((size_t)nc / 8), b->kb = malloc((size_t)nc / 8);
    if (!b->alb || !b->La || !b->Lb || !b->wa || !b->wb || !b->sa || !b->sb || !b->Ba || !b->Bb || !b->wsel ||
        !b->ua || !b->ub || !b->ka || !b->kb)
        return hl_fail(c->ref, HL_ERR_OUT_OF_MEMORY, "out of memory for the lighting stages");
    for (uint32_t v = 0; v < V; v++) {
        memcpy(b->alb + 4 * (size_t)v, c->t->mesh->albedo + 3 * (size_t)v, 12);
        b->alb[4 * (size_t)v + 3] = 0.0f;
    }
    return HL_OK;
}

/* The device's lighting stages, set up with the environment's cells and
 * the selection weights (the latter made by the twin side). */
static hl_result light_device(hl_stage_check *c, hl_context *cl, const hl_env *env, uint32_t select, light_bufs *b,
                              hl_cl_light **light)
{
    hl_result r = hl_env_to_cells(c->ref, env, c->lg->wc, c->lg->hc, &b->cells);
    if (r == HL_OK) r = hl_cl_light_create(cl, c->g, c->lg, c->t, b->alb, light);
    if (r == HL_OK) r = hl_cl_light_set_cells(*light, b->cells);
    if (r == HL_OK && c->shL) r = hl_cl_light_set_sh(*light, c->shL, c->sh_stride, c->sh_count);
    if (r == HL_OK && c->cube)
        r = hl_cl_light_set_cube(*light, c->cube->Cq, c->cube->tap_start, c->cube->taps, c->cube->ntaps);
    if (r == HL_OK) r = hl_selection_weights(c->ref, c->t, c->lg, select, b->wsel);
    if (r == HL_OK) r = hl_cl_light_set_weights(*light, b->wsel);
    return r;
}

/* The dot products on every vertex, from the twin's selection. */
static hl_result light_dots(hl_stage_check *c, hl_cl_light *light, light_bufs *b, hl_check_report_fn report,
                            void *user, int *ok)
{
    const hl_transport *t = c->t;
    const uint32_t V = t->info.vertex_count, nb = c->g->nblocks;
    for (uint32_t v = 0; v < V; v++)
        hl_ref_relight(t->entries + 2 * t->row_offset[v], t->block_counts + (size_t)v * nb, t->row_quant[v],
                       t->info.quant, v, nb, b->sa, b->alb + 4 * (size_t)v, 0, b->Ba + 4 * (size_t)v);
    hl_result r = hl_cl_light_stage_relight(light, b->sa, b->ka, b->Bb);
    if (r != HL_OK) return r;
    double w = 0.0, s = 0.0;
    for (uint32_t v = 0; v < V; v++)
        for (int k = 0; k < 3; k++) {
            s = fmax(s, fabs(b->Ba[4 * (size_t)v + k]));
            w = fmax(w, fabs((double)b->Ba[4 * (size_t)v + k] - b->Bb[4 * (size_t)v + k]));
        }
    put(report, user, ok, (hl_check_row){"relight dot products", s > 0 ? w / s : w, 1e-5, 0, (uint64_t)V * 3});
    return HL_OK;
}

/* A cube-face file's lighting: each face texel's mean radiance and the
 * faces' Haar, on the device in one go (hl_cl_light_stage_cube) against
 * the twins. */
static hl_result light_cube(hl_stage_check *c, hl_cl_light *light, uint32_t s0, float f, light_bufs *b,
                            hl_check_report_fn report, void *user, int *ok)
{
    const uint32_t nc = c->g->ncoef;
    hl_cube_lighting_haar(c->cube, b->cells, s0, f, nc, b->La, b->wa);
    hl_result r = hl_cl_light_stage_cube(light, s0, f, b->wb);
    if (r != HL_OK) return r;
    put(report, user, ok, (hl_check_row){"cube faces + haar of the lighting", rel_worst(b->wa, b->wb, (size_t)nc * 3),
                                         1e-5, 0, (uint64_t)nc * 3});
    return HL_OK;
}

/* Environment to paraboloid and the lighting's Haar transform (or its
 * harmonics, or a cube-face file's own lighting stages), then the
 * selection, each from the twin's output of the stage before. */
static hl_result light_stages(hl_stage_check *c, hl_cl_light *light, const hl_relight_desc *rd, light_bufs *b,
                              hl_check_report_fn report, void *user, int *ok, hl_select_result *sra)
{
    const hl_light_geom *lg = c->lg;
    const uint32_t nc = c->g->ncoef, nb = c->g->nblocks;
    uint32_t s0 = 0;
    float f = 0.0f;
    hl_rotation_to_shift(rd->rotate_deg, lg->wc, &s0, &f);
    hl_result r = HL_OK;
    if (c->cube) {
        r = light_cube(c, light, s0, f, b, report, user, ok);
    } else {
        hl_ref_env2para(b->cells, lg->wc, lg->tap_start, lg->taps, s0, f, nc, b->La);
        r = hl_cl_light_stage_env2para(light, s0, f, b->Lb);
        if (r != HL_OK) return r;
        put(report, user, ok, (hl_check_row){"env2para (float)", rel_worst(b->La, b->Lb, (size_t)nc * 3), 1e-5, 0,
                                             (uint64_t)nc * 3});
        memcpy(b->Lb, b->La, (size_t)nc * 12);
        if (c->shL) {
            for (int k = 0; k < 3; k++)
                hl_ref_sh_project_rows(b->La + (size_t)k * nc, nc, c->shL, c->sh_stride, c->sh_count,
                                       b->wa + (size_t)k * nc);
            r = hl_cl_light_stage_sh(light, b->Lb, b->wb);
        } else {
            r = hl_cl_light_stage_haar(light, b->Lb, b->wb);
            for (int k = 0; k < 3; k++) hl_ref_haar(c->g, b->La + (size_t)k * nc, b->wa + (size_t)k * nc);
        }
        if (r == HL_OK)
            put(report, user, ok, (hl_check_row){c->shL ? "sh projection of the lighting" : "haar of the lighting",
                                                 rel_worst(b->wa, b->wb, (size_t)nc * 3), 1e-5, 0, (uint64_t)nc * 3});
    }
    if (r != HL_OK) return r;
    hl_select_params sp = {rd->terms, rd->select, {0, 0}};
    hl_select_result srb;
    *sra = hl_ref_select(b->wa, nc, b->wsel, sp, b->sa, b->ua, b->ka, nb, c->keys);
    r = hl_cl_light_stage_select(light, b->wa, sp, b->sb, b->ub, b->kb, &srb);
    if (r != HL_OK) return r;
    uint64_t mm = 0;
    for (uint32_t i = 0; i < nc; i++) mm += memcmp(b->sa + 4 * i, b->sb + 4 * i, 16) != 0;
    mm += memcmp(b->ua, b->ub, nb) != 0 || memcmp(b->ka, b->kb, nc / 8) != 0 || sra->kept != srb.kept;
    put(report, user, ok, (hl_check_row){"select (kept terms)", 0.0, 0.0, mm, nc});
    return light_dots(c, light, b, report, user, ok);
}

hl_result hl_stage_check_lighting(hl_stage_check *c, hl_context *cl, const hl_env *env, const hl_relight_desc *rd,
                                  hl_check_report_fn report, void *user, int *ok, hl_check_summary *summary)
{
    light_bufs b;
    hl_cl_light *light = NULL;
    hl_select_result sra;
    hl_result r = light_alloc(c, &b);
    if (r == HL_OK) r = light_device(c, cl, env, rd->select, &b, &light);
    if (r == HL_OK) r = light_stages(c, light, rd, &b, report, user, ok, &sra);
    if (r == HL_OK) {
        summary->terms_kept = sra.kept;
        summary->coefficients = c->g->ncoef;
        summary->energy_percent = sra.energy_total > 0 ? 100.0 * sra.energy_kept / sra.energy_total : 100.0;
        summary->blocks_used = sra.blocks_used;
        summary->blocks = c->g->nblocks;
        summary->precompute_vertices = c->checked;
        summary->vertices = c->t->info.vertex_count;
    }
    hl_cl_light_destroy(light);
    light_free(&b);
    return r;
}
