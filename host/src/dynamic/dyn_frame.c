/* dyn_frame.c - one frame of the dynamic method: receivers to world
 * space, each kept light's exact irradiance (area_lights.c), a shadow map
 * and a convolution shadow map per light that matters (shadow_map.c,
 * csm.c) in batches that fit the memory budget, and the diffuse sum
 *     B = albedo / pi * (sum_k V_k E_k + ambient).
 * On an OpenCL context E_k, the maps' evaluation and the sums stay on
 * the device (irradiance.h, dyn_shade.cl), else they run as plain C, their
 * twin; the product with the albedo is the host's. The shadow maps and
 * the CSM module live in the frame state across frames, so a frame with
 * one body moved costs its set_transform and re-render; and when all the
 * shadowed lights fit in one batch, a frame whose lights are the last
 * frame's and in which no body drawn in the maps moved (a flat ground
 * left out of them may have) keeps the maps and their tables and only
 * evaluates them at the receivers again (maps_still_hold).
 * Depends on: dyn_frame.h (area_lights.h, shadow_map.h, csm.h), core,
 * cl_internal.h (the device memory left, for the batch size).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"
#include "dyn_frame.h"
#include "enclosed.h"
#include "irradiance.h"
#include "sharp_rays.h"

/* The shadow maps of one size, for a batch of Kb lights: the maps of
 * most lights (tier 0, R) or of the sharp ones (tier 1, R_sharp > R;
 * dyn_frame.h). Each tier keeps its maps across frames on its own. */
typedef struct hl_frame_tier {
    uint32_t R, Kb;
    hl_shadow_maps *sm;
    hl_csm *csm;
    float *depth;              /* Kb R R, the host's frame only */
    hl_shadow_frame *frames;   /* Kb */
    float (*dirs)[3];          /* Kb */
    uint32_t n, *list;         /* this frame's lights of the tier (cap of them) */
    /* the maps kept (DYNAMIC.md, the frame): while keep_n > 0, sm and csm
       hold the maps and tables of the last frame, made in one batch for
       its lights keep_list (keep_n <= Kb) of split keep_serial in the
       directions dirs, with the bodies at keep_xf (12 a body); 0 after a
       frame that failed, so that nothing half made is taken */
    uint32_t keep_n;
    uint64_t keep_serial;
    uint32_t *keep_list, *keep_mask; /* Kb each; keep_mask: this frame's skip masks */
    float *keep_xf;
} hl_frame_tier;

struct hl_frame_state {
    hl_context *ctx;
    uint32_t nobj, N;          /* bodies, receivers (all their vertices) */
    uint32_t *vstart, *nverts; /* per body */
    float *xf;                 /* 12 per body, as last rendered */
    uint32_t M, Mb, max_lights;
    float min_share;
    hl_frame_tier tier[2];
    uint32_t ntier;            /* 2 where the sharp lights get finer maps */
    float *wpos, *wnrm, *acc;  /* 3 N each */
    float *E;                  /* 3 N per kept light */
    /* the compacted receivers of a group of a batch's lights, one light's
       after another (hl_csm_visibility_batch); room for group lights of
       N receivers each */
    uint32_t group;
    float *cpos, *uvd, *rpl, *V; /* 3, 3, HL_DYN_RPL, 1 a receiver */
    uint32_t *idx;             /* its vertex */
    uint32_t *gstart, *gks;    /* group + 1, group: each light's first receiver, its batch map */
    float *gtheta;             /* group: each light's filter half-extent */
    const hl_shadow_frame **gframe; /* group */
    uint32_t *shadow_list;     /* max_lights */
    hl_dyn_irr *irr;           /* the irradiance kernel, its tables of */
    uint64_t irr_serial;       /* this split (hl_light_split.serial) */
    uint8_t *any;              /* max_lights: some receiver gets light */
    uint32_t *body;            /* N: each receiver's body */
    /* the packs the shared formulas read (hl_shared.h): per group light
       its map (HL_DYN_LF) and, for the flat bodies, its blocks
       (HL_DYN_FL); per flat rectangle left out of maps its plane
       (HL_DYN_FB), nflat of them, bodies flat_body */
    float *lf, *fl, *fb;
    uint32_t nflat, *flat_body;
    /* the device frame (kernels/dynamic/dyn_shade.cl): E_k and the sums
       stay on the device from the irradiance to the end of the frame, the
       shadow maps from the rasteriser to the evaluation */
    int on_device;
    cl_kernel kprep, kflat, kacc, kadd;
    cl_mem wpos_d, body_d, lf_d, fl_d, fb_d, flatb_d, uvd_d, rpl_d, V_d, ks_d, kbs_d, list_d;
    uint32_t *list; /* max_lights: the negligible lights */
    /* the receivers of flat bodies under another body's contact faces
       (contact_cover): 1 where dark; valid while cover_ok */
    uint8_t *covered;
    uint32_t ncovered;
    uint8_t *enclosed; /* N: inside the body's own closed parts (enclosed.h) */
    uint32_t nenclosed;
    int cover_ok;
    float *ctri; size_t ctri_cap; /* the contact triangles in a plane's axes, 6 floats each */
    /* the sharp lights by rays (HL_SHARP_RAYS): this frame's nray lights
       ray_list, their visibility Vs (N each) and, on the device, their
       E_k read back (Es, 3 N each); Vs still holds while ray_keep: made
       for split ray_serial's lights ray_list with no body moved since */
    hl_sharp_mode sharp;
    hl_sharp_rays *sr;
    uint32_t nray, ray_list[HL_FRAME_SHARP_MAX], ray_keep_n, ray_keep_list[HL_FRAME_SHARP_MAX];
    float ray_keep_dir[HL_FRAME_SHARP_MAX][3];
    uint64_t ray_serial;
    float *Vs, *Es;
};

/* Linear Rec.709 luminance, as area_lights.c ranks its lights by. */
static const double HL_FRAME_LUM[3] = {0.2126, 0.7152, 0.0722};
static double lum3(const double *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

void hl_frame_to_world(const hl_dyn_object *o, float *pos, float *nrm)
{
    const float *x = o->xf;
    for (uint32_t v = 0; v < o->nverts; v++) {
        const float *p = o->pos + 3 * (size_t)v;
        for (int r = 0; r < 3; r++)
            pos[3 * (size_t)v + r] = x[4 * r] * p[0] + x[4 * r + 1] * p[1] + x[4 * r + 2] * p[2] + x[4 * r + 3];
        float n[3] = {0, 1, 0};
        if (o->normal) {
            const float *m = o->normal + 3 * (size_t)v;
            for (int r = 0; r < 3; r++) n[r] = x[4 * r] * m[0] + x[4 * r + 1] * m[1] + x[4 * r + 2] * m[2];
            float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (l > 0.0f) for (int r = 0; r < 3; r++) n[r] /= l;
        }
        memcpy(nrm + 3 * (size_t)v, n, sizeof n);
    }
}

static void release_device(hl_frame_state *st)
{
    struct hl_cl *cl = st->ctx->cl;
    if (!cl) return;
    cl_mem *all[] = {&st->wpos_d, &st->body_d, &st->lf_d, &st->fl_d,   &st->fb_d,
                     &st->flatb_d, &st->uvd_d, &st->rpl_d, &st->V_d,    &st->ks_d, &st->kbs_d, &st->list_d};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) hl_cl_release_buf(cl, all[i]);
    cl_kernel ks[] = {st->kprep, st->kflat, st->kacc, st->kadd};
    for (size_t i = 0; i < 4; i++)
        if (ks[i]) clReleaseKernel(ks[i]);
}

void hl_frame_state_destroy(hl_frame_state *st)
{
    if (!st) return;
    release_device(st);
    free(st->list);
    free(st->covered); free(st->ctri); free(st->enclosed);
    hl_sharp_rays_destroy(st->sr);
    hl_free_big(st->Vs); hl_free_big(st->Es);
    for (int i = 0; i < 2; i++) {
        hl_frame_tier *t = &st->tier[i];
        free(t->keep_list); free(t->keep_mask); free(t->keep_xf); free(t->list);
        hl_shadow_maps_destroy(t->sm);
        hl_csm_destroy(t->csm);
        hl_free_big(t->depth);
        free(t->frames); free(t->dirs);
    }
    free(st->vstart); free(st->nverts); free(st->xf);
    free(st->wpos); free(st->wnrm); free(st->acc); hl_free_big(st->E);
    free(st->cpos); free(st->uvd); free(st->rpl); free(st->V); free(st->idx); free(st->shadow_list);
    free(st->gstart); free(st->gks); free(st->gtheta); free(st->gframe);
    free(st->body); free(st->lf); free(st->fl); free(st->fb); free(st->flat_body);
    hl_dyn_irr_destroy(st->irr);
    free(st->any);
    free(st);
}

static hl_result check_settings(hl_context *ctx, hl_frame_settings *s, uint32_t max_lights)
{
    if (s->R == 0) s->R = HL_SHADOW_DEFAULT_R;
    if (s->M == 0) s->M = HL_CSM_M_DEFAULT;
    if (s->Mb == 0) s->Mb = s->M;
    if (s->budget == 0) s->budget = HL_FRAME_DEFAULT_BUDGET;
    if (s->min_share < 0.0f) s->min_share = HL_FRAME_MIN_SHARE;
    if (s->shadow == HL_SHADOW_REP_DEFAULT) s->shadow = HL_FRAME_DEFAULT_SHADOW;
    if (s->shadow != HL_SHADOW_REP_CSM && s->shadow != HL_SHADOW_REP_MOMENTS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic frame: shadow representation %d is not csm (1) or moments (2) (--shadow)",
                       (int)s->shadow);
    if (!(s->min_share < 1.0f)) /* NaN too */
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic frame: negligible share %g is not in [0, 1)",
                       (double)s->min_share);
    if (s->M < HL_CSM_M_MIN || s->M > HL_CSM_M_MAX)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic frame: order M = %u is outside %u..%u (--order)", s->M,
                       HL_CSM_M_MIN, HL_CSM_M_MAX);
    if (s->R < HL_CSM_R_MIN || s->R > HL_CSM_R_MAX || s->R % HL_CSM_SCAN_LANES)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "dynamic frame: shadow map size %u is not a multiple of %u from %u to %u (--shadow-res)", s->R,
                       HL_CSM_SCAN_LANES, HL_CSM_R_MIN, HL_CSM_R_MAX);
    if (s->R_sharp && (s->R_sharp < s->R || s->R_sharp > HL_CSM_R_MAX || s->R_sharp % HL_CSM_SCAN_LANES))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "dynamic frame: sharp lights' map size %u is not a multiple of %u from the map size %u to %u "
                       "(--sharp-res)", s->R_sharp, HL_CSM_SCAN_LANES, s->R, HL_CSM_R_MAX);
    /* a finer size given asks for the maps; the map size itself, for one
       size for all */
    if (s->sharp == HL_SHARP_DEFAULT)
        s->sharp = s->R_sharp > s->R                    ? HL_SHARP_MAPS
                   : s->R_sharp == s->R                 ? HL_SHARP_OFF
                   : s->shadow == HL_SHADOW_REP_MOMENTS ? HL_SHARP_RAYS
                                                        : HL_SHARP_OFF;
    if (s->sharp != HL_SHARP_RAYS && s->sharp != HL_SHARP_MAPS && s->sharp != HL_SHARP_OFF)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "dynamic frame: sharp lights' mode %d is not rays (1), maps (2) or off (3) (--sharp)", (int)s->sharp);
    if (s->sharp != HL_SHARP_MAPS && s->R_sharp > s->R)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "dynamic frame: a sharp lights' map size (%u, --sharp-res) is for their maps (--sharp maps) only",
                       s->R_sharp);
    if (s->sharp != HL_SHARP_MAPS) s->R_sharp = s->R;
    else if (s->R_sharp == 0)
        s->R_sharp = s->R * HL_FRAME_SHARP_SCALE < HL_CSM_R_MAX ? s->R * HL_FRAME_SHARP_SCALE : HL_CSM_R_MAX;
    if (max_lights == 0) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic frame: at least one light is needed");
    return HL_OK;
}

/* Whether the frame's receivers run on the device (dyn_shade.cl), as on
 * any OpenCL device: on a GPU the host's light-by-light work and its
 * transfers would hold up the card, and on PoCL's 2 cores the device
 * frame took 145 to 165 ms of evaluation against 207 to 211 on the host
 * (the low-resolution bunny, R = 256; the same at R = 128). The host's
 * (the reference backend's) is its twin: HL_TEST_DYN_FRAME=host runs it
 * on an OpenCL context for the tests. */
static int frame_on_device(hl_context *ctx)
{
    if (!ctx->cl) return 0;
    const char *t = getenv("HL_TEST_DYN_FRAME");
    return !(t && !strcmp(t, "host"));
}

static hl_result create_device(hl_frame_state *st)
{
    hl_context *ctx = st->ctx;
    struct hl_cl *cl = ctx->cl;
    cl_int e;
    const char *names[4] = {"hl_dyn_prepare", "hl_dyn_flat", "hl_dyn_accumulate", "hl_dyn_add_lights"};
    cl_kernel *ks[4] = {&st->kprep, &st->kflat, &st->kacc, &st->kadd};
    for (int i = 0; i < 4; i++) {
        *ks[i] = clCreateKernel(cl->program, names[i], &e);
        CL_TRY(ctx, e, names[i]);
    }
    const size_t N = st->N, g = st->group, n3 = 3 * N * 4;
#define DB(m, fl, bytes, init, what) TRY(hl_cl_make_buf(ctx, &st->m, fl, bytes, init, what))
    DB(wpos_d, CL_MEM_READ_ONLY, n3, NULL, "the receivers' positions");
    DB(body_d, CL_MEM_READ_ONLY, N * 4, st->body, "the receivers' bodies");
    DB(lf_d, CL_MEM_READ_ONLY, g * HL_DYN_LF * 4, NULL, "the lights' maps");
    DB(fl_d, CL_MEM_READ_ONLY, g * HL_DYN_FL * 4, NULL, "the lights' blocks");
    DB(fb_d, CL_MEM_READ_ONLY, (size_t)st->nobj * HL_DYN_FB * 4, NULL, "the flat bodies");
    DB(flatb_d, CL_MEM_READ_ONLY, (size_t)st->nobj * 4, NULL, "the flat bodies");
    DB(uvd_d, CL_MEM_READ_WRITE, g * n3, NULL, "the receivers in the maps");
    DB(rpl_d, CL_MEM_READ_WRITE, g * N * HL_DYN_RPL * 4, NULL, "the receivers' planes");
    DB(V_d, CL_MEM_READ_WRITE, g * N * 4, NULL, "the receivers' visibility");
    DB(ks_d, CL_MEM_READ_ONLY, g * 4, NULL, "a group's lights");
    DB(kbs_d, CL_MEM_READ_ONLY, g * 4, NULL, "a group's maps");
    DB(list_d, CL_MEM_READ_ONLY, (size_t)st->max_lights * 4, NULL, "the negligible lights");
#undef DB
    return HL_OK;
}

/* Tier t's maps of size R for up to cap lights a batch (the fewer of
 * that and what the budget holds), with the frame's device buffers or
 * host arrays beside. */
static hl_result tier_create(hl_frame_state *st, hl_frame_tier *t, const hl_dyn_object *objects, uint32_t R,
                             uint32_t cap, const hl_frame_settings *s)
{
    hl_context *ctx = st->ctx;
    t->R = R;
    TRY(hl_shadow_maps_create(ctx, objects, st->nobj, R, s->method, &t->sm));
    /* a flat ground under the bodies stays out of the maps that it cannot
       shadow: finer texels and depths for the casters (shadow_map.h) */
    hl_shadow_maps_skip_planes(t->sm, 1);
    uint64_t budget = s->budget;
    if (ctx->cl && ctx->cl->limit > ctx->cl->used) { /* after the shadow maps' buffers */
        uint64_t left = (uint64_t)((double)(ctx->cl->limit - ctx->cl->used) * HL_FRAME_DEVICE_SHARE);
        if (left < budget) budget = left;
    }
    uint32_t fit = hl_csm_batch_fit_rep(s->shadow, R, s->M, s->Mb, budget);
    t->Kb = fit < cap ? fit : cap;
    TRY(hl_csm_create_rep(ctx, s->shadow, R, s->M, s->Mb, t->Kb, &t->csm));
    if (!st->on_device) t->depth = hl_alloc_big(ctx, t->Kb * (size_t)R * R * sizeof(float), "the shadow maps of a batch");
    t->frames = malloc(t->Kb * sizeof *t->frames);
    t->dirs = malloc(t->Kb * sizeof *t->dirs);
    t->list = malloc(cap * sizeof *t->list);
    t->keep_list = malloc(t->Kb * sizeof *t->keep_list), t->keep_mask = malloc(t->Kb * sizeof *t->keep_mask);
    t->keep_xf = malloc(st->nobj * 12 * sizeof *t->keep_xf);
    if ((!st->on_device && !t->depth) || !t->frames || !t->dirs || !t->list || !t->keep_list || !t->keep_mask ||
        !t->keep_xf)
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the dynamic frame's shadow maps (%u lights of %u^2)",
                       t->Kb, R);
    return HL_OK;
}

hl_result hl_frame_state_create(hl_context *ctx, const hl_dyn_object *objects, uint32_t nobj, uint32_t max_lights,
                                const hl_frame_settings *settings, hl_frame_state **out)
{
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_frame_state_create: no output pointer");
    *out = NULL;
    hl_frame_settings s = {0};
    s.min_share = -1.0f;
    if (settings) s = *settings;
    hl_result r = check_settings(ctx, &s, max_lights);
    if (r != HL_OK) return r;
    if (!objects || nobj == 0) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic frame: no bodies");
    uint64_t N = 0;
    for (uint32_t b = 0; b < nobj; b++) N += objects[b].nverts;
    if (N == 0 || N > UINT32_MAX / 3)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "dynamic frame: %llu vertices (1 to %u)", (unsigned long long)N,
                       UINT32_MAX / 3);
    hl_frame_state *st = hl_calloc(ctx, 1, sizeof *st, "the dynamic frame");
    if (!st) return HL_ERR_OUT_OF_MEMORY;
    st->ctx = ctx;
    st->nobj = nobj;
    st->N = (uint32_t)N;
    st->M = s.M, st->Mb = s.Mb, st->min_share = s.min_share;
    st->max_lights = max_lights;
    /* the maps and E_k on the host only where the host takes the
       receivers; the device frame keeps them on the device */
    st->on_device = frame_on_device(ctx);
    st->sharp = s.sharp;
    st->ntier = s.sharp == HL_SHARP_MAPS && s.R_sharp > s.R ? 2 : 1;
    r = tier_create(st, &st->tier[0], objects, s.R, max_lights, &s);
    if (r == HL_OK && st->ntier == 2)
        r = tier_create(st, &st->tier[1], objects, s.R_sharp,
                        max_lights < HL_FRAME_SHARP_MAX ? max_lights : HL_FRAME_SHARP_MAX, &s);
    if (r != HL_OK) { hl_frame_state_destroy(st); return r; }
    const uint32_t Kb = st->tier[0].Kb > st->tier[1].Kb ? st->tier[0].Kb : st->tier[1].Kb;
    size_t n3 = 3 * (size_t)N;
    st->vstart = malloc(nobj * sizeof *st->vstart);
    st->nverts = malloc(nobj * sizeof *st->nverts);
    st->xf = malloc(nobj * 12 * sizeof *st->xf);
    if (!st->on_device) st->E = hl_alloc_big(ctx, max_lights * n3 * 4, "the lights' irradiance at the vertices");
    st->wpos = malloc(n3 * 4), st->wnrm = malloc(n3 * 4), st->acc = malloc(n3 * 4);
    st->group = (uint32_t)(HL_FRAME_GROUP_RECEIVERS / N > 1 ? HL_FRAME_GROUP_RECEIVERS / N : 1);
    if (st->group > Kb) st->group = Kb;
    /* tests: fewer lights a group, so that a small scene takes several */
    const char *tg = getenv("HL_TEST_FRAME_GROUP");
    if (tg && strtoul(tg, NULL, 10) > 0 && strtoul(tg, NULL, 10) < st->group) st->group = (uint32_t)strtoul(tg, NULL, 10);
    if (!st->on_device) { /* the host's receivers */
        const size_t gn = (size_t)st->group * N;
        st->cpos = malloc(3 * gn * 4), st->uvd = malloc(3 * gn * 4), st->V = malloc(gn * 4);
        st->rpl = malloc(HL_DYN_RPL * gn * 4);
        st->idx = malloc(gn * 4), st->gstart = malloc(((size_t)st->group + 1) * 4);
    }
    st->gks = malloc((size_t)st->group * 4);
    st->gtheta = malloc((size_t)st->group * 4), st->gframe = malloc((size_t)st->group * sizeof *st->gframe);
    st->body = malloc((size_t)N * 4);
    st->lf = malloc((size_t)st->group * HL_DYN_LF * 4), st->fl = malloc((size_t)st->group * HL_DYN_FL * 4);
    st->fb = malloc((size_t)nobj * HL_DYN_FB * 4), st->flat_body = malloc((size_t)nobj * 4);
    st->list = malloc((size_t)max_lights * 4);
    st->shadow_list = malloc(max_lights * sizeof *st->shadow_list);
    st->any = malloc(max_lights ? max_lights : 1);
    st->covered = calloc((size_t)N, 1);
    st->enclosed = calloc((size_t)N, 1);
    if (!st->covered || !st->enclosed || !st->vstart || !st->nverts || !st->xf || !st->wpos || !st->wnrm || !st->acc ||
        (!st->on_device && (!st->E || !st->cpos || !st->uvd || !st->rpl || !st->V || !st->idx || !st->gstart)) ||
        !st->shadow_list || !st->any || !st->gks || !st->gtheta || !st->gframe || !st->body || !st->lf || !st->fl || !st->fb ||
        !st->flat_body || !st->list) {
        hl_frame_state_destroy(st);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the dynamic frame (%u vertices, %u lights)",
                       (uint32_t)N, max_lights);
    }
    uint32_t at = 0;
    for (uint32_t b = 0; b < nobj; b++) {
        st->vstart[b] = at;
        st->nverts[b] = objects[b].nverts;
        memcpy(st->xf + 12 * (size_t)b, objects[b].xf, 12 * sizeof(float));
        for (uint32_t v = 0; v < objects[b].nverts; v++) st->body[at + v] = b;
        at += objects[b].nverts;
    }
    for (uint32_t b = 0; b < nobj && r == HL_OK; b++) {
        uint32_t n = 0;
        hl_flat_body f;
        if (hl_shadow_maps_flat(st->tier[0].sm, b, &f)) continue; /* one plane encloses nothing */
        r = hl_dyn_enclosed(ctx, &objects[b], st->enclosed + st->vstart[b], &n);
        st->nenclosed += n;
    }
    if (r == HL_OK && st->sharp == HL_SHARP_RAYS) {
        const uint32_t nr = max_lights < HL_FRAME_SHARP_MAX ? max_lights : HL_FRAME_SHARP_MAX;
        st->Vs = hl_alloc_big(ctx, (size_t)nr * N * 4, "the sharp lights' visibility");
        if (st->on_device) st->Es = hl_alloc_big(ctx, (size_t)nr * 3 * N * 4, "the sharp lights' irradiance");
        r = !st->Vs || (st->on_device && !st->Es) ? HL_ERR_OUT_OF_MEMORY
                                                  : hl_sharp_rays_create(ctx, objects, nobj, &st->sr);
    }
    if (r == HL_OK && st->on_device) r = create_device(st);
    if (r != HL_OK) {
        hl_frame_state_destroy(st);
        return r;
    }
    *out = st;
    return HL_OK;
}

#define FARG(k, i, v) CL_TRY(ctx, clSetKernelArg(k, i, sizeof(v), &(v)), "clSetKernelArg")


/* Stage "irradiance": receivers to world, ambient into acc, each kept
 * light's E_k; lights below every horizon skipped, negligible ones added
 * to acc unshadowed, the rest listed for shadow maps (*count of them). */
static hl_result irradiance(hl_frame_state *st, const hl_dyn_object *objects, const hl_light_split *split,
                            hl_frame_stats *fs, uint32_t *count)
{
    const uint32_t N = st->N;
    for (uint32_t b = 0; b < st->nobj; b++)
        hl_frame_to_world(&objects[b], st->wpos + 3 * (size_t)st->vstart[b], st->wnrm + 3 * (size_t)st->vstart[b]);
    /* on the device (irradiance.h): the ambient straight into acc, each
       kept light's E_k and whether it reaches any receiver */
    hl_result r = HL_OK;
    if (!st->irr) r = hl_dyn_irr_create(st->ctx, split, &st->irr);
    else if (split->serial != st->irr_serial) r = hl_dyn_irr_set_split(st->irr, split);
    if (r != HL_OK) return r;
    st->irr_serial = split->serial;
    r = st->on_device ? hl_dyn_irr_run_kept(st->irr, st->wnrm, N, st->any)
                      : hl_dyn_irr_run(st->irr, st->wnrm, N, st->E, st->acc, st->any);
    if (r != HL_OK) return r;
    double total = lum3(split->stats.total_energy);
    uint32_t nshadow = 0, nneg = 0;
    for (uint32_t k = 0; k < split->count; k++) {
        const float *le = split->lights[k].energy;
        double lk[3] = {le[0], le[1], le[2]};
        if (!st->any[k]) {
            fs->skipped_horizon++;
        } else if (total > 0.0 && lum3(lk) < (double)st->min_share * total) {
            fs->skipped_negligible++;
            st->list[nneg++] = k;
            for (size_t i = 0; !st->on_device && i < 3 * (size_t)N; i++) st->acc[i] += st->E[(size_t)k * 3 * N + i];
        } else {
            st->shadow_list[nshadow++] = k;
        }
    }
    *count = nshadow;
    if (!st->on_device) return HL_OK;
    /* the receivers' positions for the later stages (their normals are
       the irradiance's), and the negligible lights added
       to the sums (the ambient) as the host adds them */
    hl_context *ctx = st->ctx;
    cl_command_queue q = ctx->cl->queue;
    CL_TRY(ctx, clEnqueueWriteBuffer(q, st->wpos_d, CL_FALSE, 0, (size_t)N * 12, st->wpos, 0, NULL, NULL), "upload");
    if (nneg) {
        void *E, *acc;
        hl_dyn_irr_device_bufs(st->irr, &E, &acc, NULL);
        cl_mem Em = E, am = acc;
        cl_uint n = nneg, nn = N;
        CL_TRY(ctx, clEnqueueWriteBuffer(q, st->list_d, CL_TRUE, 0, (size_t)nneg * 4, st->list, 0, NULL, NULL), "upload");
        FARG(st->kadd, 0, Em); FARG(st->kadd, 1, st->list_d); FARG(st->kadd, 2, n); FARG(st->kadd, 3, nn);
        FARG(st->kadd, 4, am);
        TRY(hl_cl_launch(ctx, st->kadd, N, 0, "hl_dyn_add_lights"));
    }
    CL_TRY(ctx, clFinish(q), "the irradiance");
    return HL_OK;
}

/* The light's blocks for the flat bodies' occlusion into its pack (hl_shared.h, HL_DYN_FL):
 * its texels in at most HL_FRAME_FLAT_BLOCKS^2 blocks, each block's
 * luminance moment and its unit direction; with the light's direction,
 * the sine of its extent and its corner texels' directions. */
static void pack_flat_light(const hl_light_split *split, const hl_area_light *L, float *fl)
{
    const uint32_t F = split->F, w = L->x1 - L->x0, h = L->y1 - L->y0;
    const uint32_t bx = w < HL_FRAME_FLAT_BLOCKS ? w : HL_FRAME_FLAT_BLOCKS;
    const uint32_t by = h < HL_FRAME_FLAT_BLOCKS ? h : HL_FRAME_FLAT_BLOCKS;
    memset(fl, 0, HL_DYN_FL * sizeof *fl);
    memcpy(fl, L->dir, 3 * sizeof *fl);
    fl[3] = L->extent < 0.5f * (float)HL_PI ? sinf(L->extent) : 2.0f;
    for (int c = 0; c < 4; c++) {
        uint32_t cx = c & 1 ? L->x1 - 1 : L->x0, cy = c & 2 ? L->y1 - 1 : L->y0;
        memcpy(fl + 4 + 3 * c, split->texel_dir + 3 * ((size_t)L->face * F * F + (size_t)cy * F + cx), 3 * sizeof *fl);
    }
    uint32_t n = 0;
    for (uint32_t j = 0; j < by; j++)
        for (uint32_t i = 0; i < bx; i++) {
            double m[3] = {0, 0, 0};
            for (uint32_t y = L->y0 + j * h / by; y < L->y0 + (j + 1) * h / by; y++)
                for (uint32_t x = L->x0 + i * w / bx; x < L->x0 + (i + 1) * w / bx; x++) {
                    const float *t = split->texel_moment + 9 * ((size_t)L->face * F * F + (size_t)y * F + x);
                    for (int c = 0; c < 3; c++)
                        for (int k = 0; k < 3; k++) m[k] += HL_FRAME_LUM[c] * t[3 * c + k];
                }
            double len = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
            if (!(len > 0.0)) continue;
            float *b = fl + 20 + 6 * (size_t)n++;
            for (int k = 0; k < 3; k++) b[k] = (float)m[k], b[3 + k] = (float)(m[k] / len);
        }
    memcpy(fl + 16, &n, 4);
}

/* The flat rectangles that maps may leave out (shadow_map.h), at their
 * current transforms, into st->fb and st->flat_body (hl_shared.h,
 * HL_DYN_FB): a flat body that does not fill its extent is only left out
 * for lights on the others' side, where it takes nothing. */
static void pack_flat_bodies(hl_frame_state *st)
{
    st->nflat = 0;
    for (uint32_t o = 0; o < st->nobj && o < 32; o++) {
        hl_flat_body f;
        if (!hl_shadow_maps_flat(st->tier[0].sm, o, &f) || !f.rect) continue;
        float *b = st->fb + (size_t)st->nflat * HL_DYN_FB;
        memset(b, 0, HL_DYN_FB * sizeof *b);
        memcpy(b, f.n, 12), memcpy(b + 3, f.p, 12), memcpy(b + 6, f.u, 12), memcpy(b + 9, f.v, 12);
        b[12] = f.lo[0], b[13] = f.lo[1], b[14] = f.hi[0], b[15] = f.hi[1];
        memcpy(b + 16, &st->vstart[o], 4);
        memcpy(b + 17, &st->nverts[o], 4);
        st->flat_body[st->nflat++] = o;
    }
}

/* Tier t's batch light kb's map as its receivers read it (hl_shared.h,
 * HL_DYN_LF), with the filter's half-extent theta. */
static void pack_map(const hl_frame_tier *t, uint32_t kb, const float dir[3], float theta, float *lf)
{
    const hl_shadow_frame *f = &t->frames[kb];
    memset(lf, 0, HL_DYN_LF * sizeof *lf);
    hl_shadow_frame_pack(f, lf);
    lf[16] = tanf(theta);
    lf[17] = hl_shadow_frame_texel(f);
    /* a test hook: HL_TEST_RPB=a,b scales the receiver-plane bias's two
       terms (hl_dyn_receiver), the filter's (a) and the texels' (b); 0,0
       is no receiver-plane bias (DYNAMIC.md, section 6, real assets) */
    const char *tr = getenv("HL_TEST_RPB");
    float a = 1.0f, b = 1.0f;
    if (tr && sscanf(tr, "%f,%f", &a, &b) == 2) lf[16] *= a, lf[17] *= b;
    memcpy(lf + 18, dir, 3 * sizeof *lf);
}

/* The filter's half-extent of split light k: it follows how the light's
 * energy spreads, not the cone that holds its rectangle (DYNAMIC.md,
 * section 5). */
static float filter_theta(const hl_light_split *split, uint32_t k)
{
    float theta = split->lights[k].spread;
    if (!(theta >= 0.0f)) theta = 0.0f;
    return theta > HL_FRAME_MAX_THETA ? HL_FRAME_MAX_THETA : theta;
}

/* Group entry j is tier t's batch map kb of split light k: its filter
 * half-extent, frame and packs (its blocks only where there are flat
 * bodies). */
static void pack_entry(hl_frame_state *st, const hl_frame_tier *t, const hl_light_split *split, uint32_t j, uint32_t kb,
                       uint32_t k)
{
    st->gks[j] = kb;
    st->gtheta[j] = filter_theta(split, k);
    st->gframe[j] = &t->frames[kb];
    pack_map(t, kb, split->lights[k].dir, st->gtheta[j], st->lf + (size_t)j * HL_DYN_LF);
    if (st->nflat) pack_flat_light(split, &split->lights[k], st->fl + (size_t)j * HL_DYN_FL);
}

/* The flat rectangles out of group entry j's map, in body order, on its
 * n receivers from place base (hl_dyn_flat_one). */
static void flat_occlusion(hl_frame_state *st, uint32_t j, size_t base, uint32_t n)
{
    const hl_shadow_frame *f = st->gframe[j];
    const float *cpos = st->cpos + 3 * base, *fl = st->fl + (size_t)j * HL_DYN_FL;
    const uint32_t *idx = st->idx + base;
    float *V = st->V + base;
    for (uint32_t b = 0; b < st->nflat; b++) {
        if (!(f->skip_mask >> st->flat_body[b] & 1u)) continue;
        const float *fb = st->fb + (size_t)b * HL_DYN_FB;
        for (uint32_t i = 0; i < n; i++)
            V[i] = hl_dyn_flat_one(fl, fb, cpos + 3 * (size_t)i, st->wnrm + 3 * (size_t)idx[i], idx[i], V[i]);
    }
}

/* The receivers batch light kb (split light k) reaches, compacted from
 * place base of the group's arrays: their positions (cpos), vertices
 * (idx) and coordinates in its map, moved towards the light by the
 * receiver-plane bias (uvd, hl_dyn_receiver), and their planes (rpl); its packs, filter
 * half-extent and frame into group entry j. Returns how many. */
static uint32_t prepare_light(hl_frame_state *st, const hl_frame_tier *t, const hl_light_split *split, uint32_t kb,
                              uint32_t k, size_t base, uint32_t j)
{
    const float *E = st->E + (size_t)k * 3 * st->N;
    float *cpos = st->cpos + 3 * base, *uvd = st->uvd + 3 * base, *lf = st->lf + (size_t)j * HL_DYN_LF;
    float *rpl = st->rpl + HL_DYN_RPL * base;
    uint32_t *idx = st->idx + base, n = 0;
    for (uint32_t v = 0; v < st->N; v++) {
        const float *e = E + 3 * (size_t)v;
        if (e[0] > 0.0f || e[1] > 0.0f || e[2] > 0.0f) {
            memcpy(cpos + 3 * (size_t)n, st->wpos + 3 * (size_t)v, 3 * sizeof(float));
            idx[n++] = v;
        }
    }
    pack_entry(st, t, split, j, kb, k);
    const float *map = t->depth + (size_t)kb * t->R * t->R;
    float zmin = 1.0f;
    for (size_t i = 0; i < (size_t)t->R * t->R; i++) zmin = fminf(zmin, map[i]);
    for (uint32_t i = 0; i < n; i++)
        hl_dyn_receiver(lf, zmin, cpos + 3 * (size_t)i, st->wnrm + 3 * (size_t)idx[i], st->body[idx[i]],
                        uvd + 3 * (size_t)i, rpl + HL_DYN_RPL * (size_t)i);
    return n;
}

/* Group entry j's visibility (split light k; its n receivers from place
 * base), with the flat bodies left out of its map, added to acc as V E. */
static void finish_light(hl_frame_state *st, uint32_t j, uint32_t k, size_t base, uint32_t n)
{
    const float *E = st->E + (size_t)k * 3 * st->N;
    if (st->gframe[j]->skip_mask) flat_occlusion(st, j, base, n);
    const uint32_t *idx = st->idx + base;
    const float *V = st->V + base;
    for (uint32_t i = 0; i < n; i++) {
        size_t v = idx[i];
        for (int c = 0; c < 3; c++) st->acc[3 * v + (size_t)c] += V[i] * E[3 * v + (size_t)c];
    }
}

/* The K lights of the batch built last (split lights list[0 .. K - 1]):
 * their receivers prepared, their visibility in groups of st->group
 * lights (one call of hl_csm_visibility_batch each: on the device one
 * launch and one read-back), added to acc. */
static hl_result shade_batch(hl_frame_state *st, const hl_frame_tier *t, const hl_light_split *split,
                             const uint32_t *list, uint32_t K)
{
    for (uint32_t i0 = 0; i0 < K; i0 += st->group) {
        const uint32_t nl = K - i0 < st->group ? K - i0 : st->group;
        st->gstart[0] = 0;
        for (uint32_t j = 0; j < nl; j++)
            st->gstart[j + 1] = st->gstart[j] + prepare_light(st, t, split, i0 + j, list[i0 + j], st->gstart[j], j);
        hl_result r = hl_csm_visibility_batch(t->csm, nl, st->gks, st->gtheta, st->gframe, st->uvd, st->rpl, st->gstart,
                                              st->V, NULL);
        if (r != HL_OK) return r;
        for (uint32_t j = 0; j < nl; j++)
            finish_light(st, j, list[i0 + j], st->gstart[j], st->gstart[j + 1] - st->gstart[j]);
    }
    return HL_OK;
}

/* shade_batch on the device (dyn_shade.cl): for each group of the batch
 * built last, the lights' packs uploaded, then the receivers in the maps,
 * their visibility (hl_csm_eval_grid), the flat bodies and the sums, all
 * enqueued; one wait at the end, for the stage's time. */
static hl_result shade_batch_device(hl_frame_state *st, const hl_frame_tier *t, const hl_light_split *split,
                                    const uint32_t *list, uint32_t K)
{
    hl_context *ctx = st->ctx;
    cl_command_queue q = ctx->cl->queue;
    void *E, *acc, *nrm;
    hl_dyn_irr_device_bufs(st->irr, &E, &acc, &nrm); /* the normals as the irradiance took them */
    cl_mem Em = E, am = acc, wnrm = nrm;
    const cl_uint N = st->N, nflat = st->nflat;
    for (uint32_t i0 = 0; i0 < K; i0 += st->group) {
        const cl_uint nl = K - i0 < st->group ? K - i0 : st->group;
        for (uint32_t j = 0; j < nl; j++) pack_entry(st, t, split, j, i0 + j, list[i0 + j]);
        /* blocking: the next group rewrites these host arrays */
        CL_TRY(ctx, clEnqueueWriteBuffer(q, st->lf_d, CL_TRUE, 0, (size_t)nl * HL_DYN_LF * 4, st->lf, 0, NULL, NULL), "upload");
        if (nflat)
            CL_TRY(ctx, clEnqueueWriteBuffer(q, st->fl_d, CL_TRUE, 0, (size_t)nl * HL_DYN_FL * 4, st->fl, 0, NULL, NULL),
                   "upload");
        CL_TRY(ctx, clEnqueueWriteBuffer(q, st->ks_d, CL_TRUE, 0, (size_t)nl * 4, list + i0, 0, NULL, NULL), "upload");
        CL_TRY(ctx, clEnqueueWriteBuffer(q, st->kbs_d, CL_TRUE, 0, (size_t)nl * 4, st->gks, 0, NULL, NULL), "upload");
        void *zm = hl_csm_zmin_buffer(t->csm);
        cl_mem zmin = zm;
        FARG(st->kprep, 0, Em); FARG(st->kprep, 1, st->ks_d); FARG(st->kprep, 2, st->kbs_d); FARG(st->kprep, 3, N);
        FARG(st->kprep, 4, nl); FARG(st->kprep, 5, st->wpos_d); FARG(st->kprep, 6, wnrm);
        FARG(st->kprep, 7, st->body_d); FARG(st->kprep, 8, st->lf_d); FARG(st->kprep, 9, zmin);
        FARG(st->kprep, 10, st->uvd_d); FARG(st->kprep, 11, st->rpl_d);
        TRY(hl_cl_launch(ctx, st->kprep, (size_t)nl * N, 0, "hl_dyn_prepare"));
        TRY(hl_csm_eval_grid(t->csm, nl, st->gks, st->gtheta, st->gframe, st->uvd_d, st->rpl_d, N, st->V_d));
        if (nflat) {
            FARG(st->kflat, 0, st->uvd_d); FARG(st->kflat, 1, N); FARG(st->kflat, 2, nl); FARG(st->kflat, 3, st->lf_d);
            FARG(st->kflat, 4, st->fl_d); FARG(st->kflat, 5, st->fb_d); FARG(st->kflat, 6, st->flatb_d);
            FARG(st->kflat, 7, nflat); FARG(st->kflat, 8, st->wpos_d); FARG(st->kflat, 9, wnrm);
            FARG(st->kflat, 10, st->V_d);
            TRY(hl_cl_launch(ctx, st->kflat, (size_t)nl * N, 0, "hl_dyn_flat"));
        }
        FARG(st->kacc, 0, st->uvd_d); FARG(st->kacc, 1, st->V_d); FARG(st->kacc, 2, Em); FARG(st->kacc, 3, st->ks_d);
        FARG(st->kacc, 4, N); FARG(st->kacc, 5, nl); FARG(st->kacc, 6, am);
        TRY(hl_cl_launch(ctx, st->kacc, N, 0, "hl_dyn_accumulate"));
    }
    CL_TRY(ctx, clFinish(q), "the shadow maps' evaluation");
    return HL_OK;
}

/* Whether tier t's sm and csm still hold this frame's maps: the last
 * frame's one batch (keep_n lights) of the same split, the same lights in
 * the same directions (exactly: a map is fitted to its direction), each
 * map leaving out the same flat bodies, and no body that a map draws
 * moved since the maps were made. A flat body left out of every map may
 * have moved: the evaluation, which runs every frame, takes it where it
 * is now. With several batches nothing is kept: each batch renders into
 * the same buffers, so at the end of a frame they hold its last batch
 * only. */
static int maps_still_hold(hl_frame_tier *t, const hl_dyn_object *objects, uint32_t nobj, const hl_light_split *split,
                           uint32_t keep_n)
{
    const uint32_t n = t->n;
    if (!keep_n || n != keep_n || split->serial != t->keep_serial || memcmp(t->keep_list, t->list, n * sizeof *t->list))
        return 0;
    for (uint32_t i = 0; i < n; i++)
        if (memcmp(t->dirs[i], split->lights[t->list[i]].dir, 3 * sizeof(float))) return 0;
    /* a moved flat body can change which maps leave it out (a ground
       lifted through a body): then a map would draw other bodies */
    hl_shadow_maps_skip_masks(t->sm, (const float(*)[3])t->dirs, n, t->keep_mask);
    uint32_t drawn = 0;
    for (uint32_t i = 0; i < n; i++) {
        if (t->keep_mask[i] != t->frames[i].skip_mask) return 0;
        drawn |= ~t->keep_mask[i];
    }
    for (uint32_t b = 0; b < nobj; b++)
        if ((b >= 32 || drawn >> b & 1u) && memcmp(t->keep_xf + 12 * (size_t)b, objects[b].xf, 12 * sizeof(float)))
            return 0;
    return 1;
}

/* Whether split light k is sharp: its filter at a blocker a map's width
 * away, tan(theta) R texels of half-width in a map of tier 0's size R,
 * is under HL_FRAME_SHARP_TEXELS (dyn_frame.h). */
static int light_is_sharp(const hl_light_split *split, uint32_t k, uint32_t R)
{
    return tanf(filter_theta(split, k)) * (float)R < HL_FRAME_SHARP_TEXELS;
}

/* Tier t's lights of the frame: its batches of maps rendered and built
 * (unless they still hold), evaluated and added to acc. */
static hl_result render_tier(hl_frame_state *st, hl_frame_tier *t, const hl_dyn_object *objects,
                             const hl_light_split *split, uint32_t keep_n, hl_frame_stats *fs)
{
    double t0 = hl_now();
    const int kept = maps_still_hold(t, objects, st->nobj, split, keep_n);
    fs->t_shadow_maps += hl_now() - t0;
    hl_result r = HL_OK;
    for (uint32_t b0 = 0; b0 < t->n && r == HL_OK; b0 += t->Kb) {
        uint32_t K = t->n - b0 < t->Kb ? t->n - b0 : t->Kb;
        double a = hl_now(), b;
        if (!kept) {
            for (uint32_t i = 0; i < K; i++) memcpy(t->dirs[i], split->lights[t->list[b0 + i]].dir, 3 * sizeof(float));
            /* on the device the maps stay there for the build */
            r = hl_shadow_maps_render(t->sm, (const float(*)[3])t->dirs, K, st->on_device ? NULL : t->depth, t->frames);
            b = hl_now(), fs->t_shadow_maps += b - a, a = b;
            if (r == HL_OK && st->on_device) r = hl_csm_build_on_device(t->csm, hl_shadow_maps_device_depth(t->sm), K);
            else if (r == HL_OK) r = hl_csm_build(t->csm, t->depth, K);
            b = hl_now(), fs->t_csm_build += b - a, a = b;
        }
        if (r == HL_OK)
            r = st->on_device ? shade_batch_device(st, t, split, t->list + b0, K) : shade_batch(st, t, split, t->list + b0, K);
        fs->t_csm_eval += hl_now() - a;
        fs->batches++;
    }
    if (r != HL_OK) return r;
    if (kept) fs->maps_kept += t->n;
    if (t->n && t->n <= t->Kb) { /* one batch: its maps stay for the next frame */
        t->keep_n = t->n;
        t->keep_serial = split->serial;
        memcpy(t->keep_list, t->list, t->n * sizeof *t->keep_list);
        if (!kept) memcpy(t->keep_xf, st->xf, 12 * (size_t)st->nobj * sizeof(float));
    }
    return HL_OK;
}

/* The sharp lights by rays (HL_SHARP_RAYS): each one's visibility at
 * every receiver it reaches (sharp_rays.h), unless the last frame's still
 * holds (the same split, lights and directions, and no body moved: keep_n
 * of them), added to acc as V E. On the device E_k is read back and acc
 * was, so both frames add it here, in the same order. */
static hl_result sharp_by_rays(hl_frame_state *st, const hl_light_split *split, uint32_t keep_n, hl_frame_stats *fs)
{
    const double t0 = hl_now();
    const size_t N = st->N;
    int kept = keep_n == st->nray && split->serial == st->ray_serial &&
               !memcmp(st->ray_keep_list, st->ray_list, st->nray * sizeof *st->ray_list);
    for (uint32_t i = 0; kept && i < st->nray; i++)
        kept = !memcmp(st->ray_keep_dir[i], split->lights[st->ray_list[i]].dir, 3 * sizeof(float));
    for (uint32_t i = 0; i < st->nray; i++) {
        const uint32_t k = st->ray_list[i];
        const float *E = st->E ? st->E + (size_t)k * 3 * N : st->Es + (size_t)i * 3 * N;
        if (st->on_device) {
            void *Ed, *accd, *nrmd;
            hl_dyn_irr_device_bufs(st->irr, &Ed, &accd, &nrmd);
            cl_mem Em = Ed;
            CL_TRY(st->ctx, clEnqueueReadBuffer(st->ctx->cl->queue, Em, CL_TRUE, (size_t)k * N * 12, N * 12, (void *)E, 0,
                                                NULL, NULL), "the sharp lights' irradiance");
        }
        float *V = st->Vs + (size_t)i * N;
        if (kept) fs->maps_kept++;
        else {
            uint64_t n = 0;
            TRY(hl_sharp_rays_visibility(st->sr, st->wpos, st->wnrm, E, split->lights[k].dir, filter_theta(split, k), V, &n));
            fs->sharp_rays += n;
        }
        for (size_t v = 0; v < N; v++)
            for (int c = 0; c < 3; c++) st->acc[3 * v + (size_t)c] += V[v] * E[3 * v + (size_t)c];
    }
    st->ray_keep_n = st->nray;
    st->ray_serial = split->serial;
    memcpy(st->ray_keep_list, st->ray_list, st->nray * sizeof *st->ray_list);
    for (uint32_t i = 0; i < st->nray; i++) memcpy(st->ray_keep_dir[i], split->lights[st->ray_list[i]].dir, 3 * sizeof(float));
    fs->t_sharp_rays = hl_now() - t0;
    return HL_OK;
}

static hl_result check_frame(hl_frame_state *st, const hl_dyn_object *objects, uint32_t nobj, const float *const *albedo,
                             const hl_light_split *split, float *const *rgb)
{
    hl_context *ctx = st->ctx;
    if (!objects || !albedo || !split || !rgb)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_frame_render: a NULL argument");
    if (nobj != st->nobj)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_frame_render: %u bodies, the frame state has %u", nobj,
                       st->nobj);
    for (uint32_t b = 0; b < nobj; b++) {
        if (objects[b].nverts != st->nverts[b])
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_frame_render: body %u has %u vertices, not %u", b,
                           objects[b].nverts, st->nverts[b]);
        if (!albedo[b] || !rgb[b])
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_frame_render: no albedo or output for body %u", b);
    }
    if (split->count > st->max_lights)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_frame_render: %u lights, the frame state holds %u",
                       split->count, st->max_lights);
    return HL_OK;
}

/* Whether (a, b) lies in 2-D triangle t (6 floats), edges included. */
static int in_tri(const float *t, double a, double b)
{
    const double d1 = (t[2] - t[0]) * (b - t[1]) - (t[3] - t[1]) * (a - t[0]);
    const double d2 = (t[4] - t[2]) * (b - t[3]) - (t[5] - t[3]) * (a - t[2]);
    const double d3 = (t[0] - t[4]) * (b - t[5]) - (t[1] - t[5]) * (a - t[4]);
    return (d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0) || (d1 <= 0.0 && d2 <= 0.0 && d3 <= 0.0);
}

/* Whether (a, b) lies in one of the n contact triangles ct. */
static int in_any(const float *ct, size_t n, double a, double b)
{
    for (size_t i = 0; i < n; i++) {
        const float *t = ct + 6 * i;
        if (a < fmin(t[0], fmin(t[2], t[4])) || a > fmax(t[0], fmax(t[2], t[4])) ||
            b < fmin(t[1], fmin(t[3], t[5])) || b > fmax(t[1], fmax(t[3], t[5])))
            continue;
        if (in_tri(t, a, b)) return 1;
    }
    return 0;
}

/* The receivers of the flat bodies left out of the maps that lie under
 * another body's contact faces, into st->covered: triangles of the other
 * bodies within HL_FRAME_CONTACT_TOL of the scene's extent of the flat
 * body's plane whose normals (the vertices' mean) face into it. Such a
 * face is the underside of a solid resting on the plane, so a receiver
 * of the plane inside it is inside that solid: every ray from it meets
 * the solid, and it gets no light at all, where a shadow map's filter
 * box reaches past the solid's silhouette and lets some through
 * (DYNAMIC.md, section 5). A receiver counts when it and the four points
 * the tolerance away along the plane's axes all lie in contact
 * triangles, so one on the footprint's rim stays lit. */
static hl_result contact_cover(hl_frame_state *st, const hl_dyn_object *objects)
{
    memset(st->covered, 0, st->N);
    st->ncovered = 0;
    if (!st->nflat) return HL_OK;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < st->N; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], st->wpos[3 * i + k]), hi[k] = fmax(hi[k], st->wpos[3 * i + k]);
    const double tol = HL_FRAME_CONTACT_TOL * sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                                   (hi[2] - lo[2]) * (hi[2] - lo[2]));
    for (uint32_t f = 0; f < st->nflat; f++) {
        const float *fb = st->fb + (size_t)f * HL_DYN_FB;
        const uint32_t g = st->flat_body[f], g0 = st->vstart[g], gn = st->nverts[g];
        const float *gnrm = st->wnrm + 3 * (size_t)g0;
        /* the plane's side its receivers face */
        const double up = gnrm[0] * fb[0] + gnrm[1] * fb[1] + gnrm[2] * fb[2] >= 0.0 ? 1.0 : -1.0;
        size_t nct = 0;
        for (uint32_t b = 0; b < st->nobj; b++) {
            if (b == g) continue;
            const float *P = st->wpos + 3 * (size_t)st->vstart[b], *Nn = st->wnrm + 3 * (size_t)st->vstart[b];
            /* a body no vertex of which touches the plane has no contact face */
            int near = 0;
            for (uint32_t v = 0; v < st->nverts[b] && !near; v++) {
                const float *x = P + 3 * (size_t)v;
                near = fabs((x[0] - fb[3]) * fb[0] + (x[1] - fb[4]) * fb[1] + (x[2] - fb[5]) * fb[2]) <= tol;
            }
            if (!near) continue;
            for (uint32_t t = 0; t < objects[b].ntris; t++) {
                const uint32_t *tv = objects[b].tri + 3 * (size_t)t;
                double uv[6], nd = 0.0;
                int on = 1;
                for (int c = 0; c < 3 && on; c++) {
                    const float *x = P + 3 * (size_t)tv[c], *nv = Nn + 3 * (size_t)tv[c];
                    const double q[3] = {x[0] - fb[3], x[1] - fb[4], x[2] - fb[5]};
                    on = fabs(q[0] * fb[0] + q[1] * fb[1] + q[2] * fb[2]) <= tol;
                    uv[2 * c] = q[0] * fb[6] + q[1] * fb[7] + q[2] * fb[8];
                    uv[2 * c + 1] = q[0] * fb[9] + q[1] * fb[10] + q[2] * fb[11];
                    nd += up * (nv[0] * fb[0] + nv[1] * fb[1] + nv[2] * fb[2]);
                }
                if (!on || !(nd < -1.5)) continue; /* the mean normal's cosine below -0.5 */
                if (nct == st->ctri_cap) {
                    size_t cap = st->ctri_cap ? 2 * st->ctri_cap : 64;
                    float *c = realloc(st->ctri, cap * 6 * sizeof *c);
                    if (!c) return hl_fail(st->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for %zu contact faces", cap);
                    st->ctri = c, st->ctri_cap = cap;
                }
                for (int c = 0; c < 6; c++) st->ctri[6 * nct + (size_t)c] = (float)uv[c];
                nct++;
            }
        }
        if (!nct) continue;
        double blo[2] = {INFINITY, INFINITY}, bhi[2] = {-INFINITY, -INFINITY};
        for (size_t i = 0; i < 3 * nct; i++)
            for (int k = 0; k < 2; k++)
                blo[k] = fmin(blo[k], st->ctri[2 * i + (size_t)k]), bhi[k] = fmax(bhi[k], st->ctri[2 * i + (size_t)k]);
        for (uint32_t v = 0; v < gn; v++) {
            const float *x = st->wpos + 3 * ((size_t)g0 + v);
            const double q[3] = {x[0] - fb[3], x[1] - fb[4], x[2] - fb[5]};
            const double a = q[0] * fb[6] + q[1] * fb[7] + q[2] * fb[8], b = q[0] * fb[9] + q[1] * fb[10] + q[2] * fb[11];
            if (a - tol < blo[0] || a + tol > bhi[0] || b - tol < blo[1] || b + tol > bhi[1]) continue;
            if (in_any(st->ctri, nct, a, b) && in_any(st->ctri, nct, a - tol, b) && in_any(st->ctri, nct, a + tol, b) &&
                in_any(st->ctri, nct, a, b - tol) && in_any(st->ctri, nct, a, b + tol)) {
                st->covered[g0 + v] = 1;
                st->ncovered++;
            }
        }
    }
    return HL_OK;
}

hl_result hl_frame_render(hl_frame_state *st, const hl_dyn_object *objects, uint32_t nobj, const float *const *albedo,
                          const hl_light_split *split, float *const *rgb, hl_frame_stats *stats)
{
    if (!st) return HL_ERR_INVALID_ARGUMENT;
    /* the maps are trusted again only when their tier's part of this
       frame ends well: an error may leave them half rendered or built */
    uint32_t keep_n[2];
    for (uint32_t i = 0; i < 2; i++) keep_n[i] = st->tier[i].keep_n, st->tier[i].keep_n = 0;
    uint32_t ray_keep_n = st->ray_keep_n;
    st->ray_keep_n = 0;
    hl_result r = check_frame(st, objects, nobj, albedo, split, rgb);
    if (r != HL_OK) return r;
    hl_frame_stats fs = {0};
    fs.receivers = st->N;
    fs.lights = split->count;
    fs.batch_lights = st->tier[0].Kb;
    fs.R = st->tier[0].R;
    fs.R_sharp = st->ntier == 2 ? st->tier[1].R : 0;
    double t0 = hl_now(), t = t0, t1;
    uint32_t nshadow = 0;
    r = irradiance(st, objects, split, &fs, &nshadow);
    if (r != HL_OK) return r;
    t1 = hl_now(), fs.t_irradiance = t1 - t, t = t1;
    for (uint32_t b = 0; b < nobj && r == HL_OK; b++) {
        float *old = st->xf + 12 * (size_t)b;
        if (memcmp(old, objects[b].xf, 12 * sizeof(float)) == 0) continue;
        st->cover_ok = 0;
        ray_keep_n = 0;
        for (uint32_t i = 0; i < st->ntier && r == HL_OK; i++) r = hl_shadow_maps_set_transform(st->tier[i].sm, b, objects[b].xf);
        if (r == HL_OK && st->sr) r = hl_sharp_rays_set_transform(st->sr, b, objects[b].xf);
        if (r == HL_OK) memcpy(old, objects[b].xf, 12 * sizeof(float));
    }
    pack_flat_bodies(st);
    if (r == HL_OK && !st->cover_ok) r = contact_cover(st, objects);
    if (r == HL_OK) st->cover_ok = 1;
    if (r == HL_OK && st->on_device && st->nflat) {
        hl_context *ctx = st->ctx;
        CL_TRY(ctx, clEnqueueWriteBuffer(ctx->cl->queue, st->fb_d, CL_FALSE, 0, (size_t)st->nflat * HL_DYN_FB * 4, st->fb, 0,
                                         NULL, NULL), "upload");
        CL_TRY(ctx, clEnqueueWriteBuffer(ctx->cl->queue, st->flatb_d, CL_FALSE, 0, (size_t)st->nflat * 4, st->flat_body, 0,
                                         NULL, NULL), "upload");
    }
    fs.t_shadow_maps += hl_now() - t;
    /* the sharp lights (the strongest first, as the split ranks them) to
       the rays or to tier 1 while there is room, the rest to tier 0 */
    hl_frame_tier *t0r = &st->tier[0], *t1r = &st->tier[1];
    t0r->n = t1r->n = 0;
    st->nray = 0;
    const uint32_t ray_cap = st->max_lights < HL_FRAME_SHARP_MAX ? st->max_lights : HL_FRAME_SHARP_MAX;
    for (uint32_t i = 0; i < nshadow; i++) {
        const uint32_t k = st->shadow_list[i];
        const int sharp = st->sharp != HL_SHARP_OFF && light_is_sharp(split, k, t0r->R);
        if (sharp && st->sr && st->nray < ray_cap) st->ray_list[st->nray++] = k;
        else if (sharp && st->ntier == 2 && t1r->n < t1r->Kb) t1r->list[t1r->n++] = k;
        else t0r->list[t0r->n++] = k;
    }
    for (uint32_t i = 0; i < st->ntier && r == HL_OK; i++) r = render_tier(st, &st->tier[i], objects, split, keep_n[i], &fs);
    if (r == HL_OK && st->on_device) { /* the sums, once */
        void *E, *acc;
        hl_dyn_irr_device_bufs(st->irr, &E, &acc, NULL);
        r = hl_cl_buffer_read(st->ctx, acc, (size_t)st->N * 12, st->acc);
    }
    if (r == HL_OK && st->nray) r = sharp_by_rays(st, split, ray_keep_n, &fs);
    if (r != HL_OK) return r;
    fs.shadowed = nshadow;
    fs.sharp_mode = st->sharp;
    fs.sharp = st->sr ? st->nray : t1r->n;
    t = hl_now();
    const float inv_pi = (float)(1.0 / 3.14159265358979323846);
    for (uint32_t b = 0; b < nobj; b++) {
        const float *acc = st->acc + 3 * (size_t)st->vstart[b];
        /* the folded lights' SH9 term can dip below 0 at some normals
           when their light is directional; light is never negative */
        for (size_t i = 0; i < 3 * (size_t)st->nverts[b]; i++) rgb[b][i] = albedo[b][i] * inv_pi * fmaxf(acc[i], 0.0f);
        const uint8_t *cov = st->covered + st->vstart[b], *enc = st->enclosed + st->vstart[b];
        for (size_t i = 0; (st->ncovered || st->nenclosed) && i < st->nverts[b]; i++)
            if (cov[i] || enc[i]) rgb[b][3 * i] = rgb[b][3 * i + 1] = rgb[b][3 * i + 2] = 0.0f;
    }
    fs.covered = st->ncovered;
    fs.enclosed = st->nenclosed;
    t1 = hl_now();
    fs.t_shading = t1 - t;
    fs.t_total = t1 - t0;
    if (stats) *stats = fs;
    return HL_OK;
}
