/* capture_refs.c - references for lighting captured from surroundings
 * (`haarlight relight --surroundings FILE --reference KIND`), per vertex
 * of a transport's mesh, the quantity `relight` writes (albedo / pi times
 * the irradiance):
 *   exact:    rays from each vertex (offset as the precompute offsets
 *             them) to K x K stratified points on every emitting triangle
 *             of the surroundings, occluded by the object, its ground and
 *             every triangle of the surroundings; each point weighted by
 *             its area, both cosines and 1 / d^2 (both sides emit, as in
 *             the capture). No capture point, no map, no truncation.
 *   centre:   the same points seen from the capture point instead (their
 *             directions and solid angles from there, hidden where the
 *             surroundings hide them from there), each direction then
 *             cast from the vertex against the object and ground only:
 *             what a capture of unlimited resolution and an exact
 *             transport would give. exact - centre is the parallax of the
 *             one capture point.
 *   discrete: the untruncated, unquantised transport (recomputed from
 *             the rays at the file's N, C and supersampling, as bench's
 *             exact reference) dotted with the untruncated capture (its
 *             N, default rays a texel), in float64. centre - discrete is
 *             the resolution of the capture and of the transport;
 *             discrete - relit, the transport's truncation and 8-bit codes
 *             and the lighting's truncation to M terms.
 *
 * Depends on the ray caster (rays.h), the capture (capture.h), the
 * capture point (lighting.h) and bench_refs.c's exact rows.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "haarlight_tools.h"
#include "lighting.h"
#include "rays.h"

/* Rays traced together: bounds the batch's memory (about 40 bytes a ray). */
#define CREF_BATCH_RAYS (1u << 20)
/* A shadow ray stops this fraction of its length short of the point on
 * the light, so that the light's own triangle is not taken for an
 * occluder. */
#define CREF_SHORT 1e-4f

/* A fixed jitter in [0, 1) for stratum (i, a, b), coordinate k. */
static float jitter(uint32_t i, uint32_t a, uint32_t b, uint32_t k)
{
    uint32_t x = i * 0x9E3779B1u ^ (a + 0x7F4A7C15u) * 0x85EBCA77u ^ (b + 0x165667B1u) * 0xC2B2AE3Du ^ k * 0x27D4EB2Fu;
    x ^= x >> 16;
    x *= 0x7FEB352Du;
    x ^= x >> 15;
    x *= 0x846CA68Bu;
    x ^= x >> 16;
    return (float)(x >> 8) * (1.0f / 16777216.0f);
}

/* The points on the emitting triangles: position, unit normal, area
 * weight, radiance. */
typedef struct cref_points {
    uint32_t n;
    float *q, *nrm, *dA, *Le;
} cref_points;

static void points_free(cref_points *p)
{
    free(p->q);
    free(p->nrm);
    free(p->dA);
    free(p->Le);
}

/* K x K points a emitting triangle, stratified over the triangle by the
 * area-preserving map (sqrt u1, u2), jittered within their strata. */
static hl_result make_points(hl_context *ctx, const float *pos, const float *em, uint32_t ntris, uint32_t K,
                             cref_points *p)
{
    memset(p, 0, sizeof *p);
    uint32_t ne = 0;
    for (uint32_t i = 0; i < ntris; i++)
        if (em[3 * (size_t)i] > 0.0f || em[3 * (size_t)i + 1] > 0.0f || em[3 * (size_t)i + 2] > 0.0f) ne++;
    const uint64_t n = (uint64_t)ne * K * K;
    if (n > HL_CAPTURE_REF_MAX_POINTS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "reference: %u emitting triangles x %u x %u points is more than %u points: fewer points a side",
                       ne, K, K, HL_CAPTURE_REF_MAX_POINTS);
    p->q = malloc((n ? n : 1) * 12);
    p->nrm = malloc((n ? n : 1) * 12);
    p->dA = malloc((n ? n : 1) * 4);
    p->Le = malloc((n ? n : 1) * 12);
    if (!p->q || !p->nrm || !p->dA || !p->Le) {
        points_free(p);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's %llu points", (unsigned long long)n);
    }
    for (uint32_t i = 0; i < ntris; i++) {
        const float *e = em + 3 * (size_t)i, *c = pos + 9 * (size_t)i;
        if (!(e[0] > 0.0f || e[1] > 0.0f || e[2] > 0.0f)) continue;
        double e1[3], e2[3], m[3];
        for (int a = 0; a < 3; a++) {
            e1[a] = (double)c[3 + a] - c[a];
            e2[a] = (double)c[6 + a] - c[a];
        }
        m[0] = e1[1] * e2[2] - e1[2] * e2[1];
        m[1] = e1[2] * e2[0] - e1[0] * e2[2];
        m[2] = e1[0] * e2[1] - e1[1] * e2[0];
        const double lm = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
        if (!(lm > 0.0)) continue; /* no area, no light */
        const float w = (float)(0.5 * lm / ((double)K * K));
        for (uint32_t a = 0; a < K; a++)
            for (uint32_t b = 0; b < K; b++) {
                const double u1 = ((double)a + jitter(i, a, b, 0)) / K, u2 = ((double)b + jitter(i, a, b, 1)) / K, su = sqrt(u1);
                const uint32_t k = p->n++;
                for (int x = 0; x < 3; x++) {
                    p->q[3 * (size_t)k + x] = (float)(c[x] + su * (1.0 - u2) * e1[x] + su * u2 * e2[x]);
                    p->nrm[3 * (size_t)k + x] = (float)(m[x] / lm);
                    p->Le[3 * (size_t)k + x] = e[x];
                }
                p->dA[k] = w;
            }
    }
    return HL_OK;
}

/* A mesh for Embree of the transport's mesh (may be NULL) followed by the
 * surroundings' triangles (ntris may be 0), each with corners of its own. */
static hl_result join_mesh(hl_context *ctx, const hl_mesh *m, const float *pos, uint32_t ntris, hl_mesh *out)
{
    memset(out, 0, sizeof *out);
    const uint32_t mv = m ? m->vertex_count : 0, mt = m ? m->triangle_count : 0;
    out->vertex_count = mv + 3 * ntris;
    out->triangle_count = mt + ntris;
    out->positions = malloc(((size_t)out->vertex_count + 1) * 12);
    out->indices = malloc(((size_t)out->triangle_count + 1) * 12);
    if (!out->positions || !out->indices) {
        free(out->positions);
        free(out->indices);
        return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's scene");
    }
    if (m) {
        memcpy(out->positions, m->positions, (size_t)mv * 12);
        memcpy(out->indices, m->indices, (size_t)mt * 12);
    }
    memcpy(out->positions + 3 * (size_t)mv, pos, (size_t)ntris * 36);
    for (uint32_t i = 0; i < 3 * ntris; i++) out->indices[3 * (size_t)mt + i] = mv + i;
    return HL_OK;
}

static void join_free(hl_mesh *m)
{
    free(m->positions);
    free(m->indices);
}

/* The rays of a batch: origins, directions, segments, results, and for
 * each ray its vertex and point. */
typedef struct cref_batch {
    float *org, *dir, *tn, *tf;
    uint8_t *occ;
    uint32_t *vtx, *pt;
    float *w; /* the ray's weight: cos at the vertex x the point's solid angle */
} cref_batch;

static void batch_free(cref_batch *b)
{
    free(b->org);
    free(b->dir);
    free(b->tn);
    free(b->tf);
    free(b->occ);
    free(b->vtx);
    free(b->pt);
    free(b->w);
}

static hl_result batch_alloc(hl_context *ctx, cref_batch *b)
{
    const size_t n = CREF_BATCH_RAYS;
    b->org = malloc(n * 12);
    b->dir = malloc(n * 12);
    b->tn = malloc(n * 4);
    b->tf = malloc(n * 4);
    b->occ = malloc(n);
    b->vtx = malloc(n * 4);
    b->pt = malloc(n * 4);
    b->w = malloc(n * 4);
    if (b->org && b->dir && b->tn && b->tf && b->occ && b->vtx && b->pt && b->w) return HL_OK;
    batch_free(b);
    return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's rays");
}

/* Traces the batch's n rays and adds each open one's weight times its
 * point's radiance to its vertex's irradiance E (3 doubles a vertex). */
static hl_result batch_flush(hl_rt *rt, cref_batch *b, uint32_t n, const cref_points *p, double *E, int segments)
{
    if (!n) return HL_OK;
    hl_result r = hl_rt_trace_occluded_seg(rt, n, b->org, b->dir, b->tn, segments ? b->tf : NULL, b->occ);
    for (uint32_t i = 0; i < n && r == HL_OK; i++) {
        if (b->occ[i]) continue;
        const float *Le = p->Le + 3 * (size_t)b->pt[i];
        for (int c = 0; c < 3; c++) E[3 * (size_t)b->vtx[i] + c] += (double)b->w[i] * Le[c];
    }
    return r;
}

/* The offset origin of vertex v's rays, as rays.c makes it. */
static void vertex_origin(const hl_rt *rt, const hl_mesh *m, uint32_t v, float o[3])
{
    const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v, d = hl_rt_robust_offset(rt, v);
    for (int a = 0; a < 3; a++) o[a] = hl_rt_origin_coord(p[a], n[a], d);
}

/* exact: every point from every vertex, through the joined scene. */
static hl_result ref_exact(hl_context *ctx, const hl_mesh *m, const float *pos, uint32_t ntris, const cref_points *p,
                           double *E)
{
    hl_mesh j;
    hl_rt *rt = NULL;
    cref_batch b = {0};
    hl_result r = join_mesh(ctx, m, pos, ntris, &j);
    if (r != HL_OK) return r;
    r = hl_rt_create(ctx, &j, &rt);
    if (r == HL_OK) r = batch_alloc(ctx, &b);
    uint32_t n = 0;
    for (uint32_t v = 0; v < m->vertex_count && r == HL_OK; v++) {
        float o[3];
        vertex_origin(rt, m, v, o);
        const float *x = m->positions + 3 * (size_t)v, *nv = m->normals + 3 * (size_t)v, off = hl_rt_robust_offset(rt, v);
        for (uint32_t k = 0; k < p->n && r == HL_OK; k++) {
            const float *q = p->q + 3 * (size_t)k, *ne = p->nrm + 3 * (size_t)k;
            const double w[3] = {(double)q[0] - x[0], (double)q[1] - x[1], (double)q[2] - x[2]};
            const double d2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2], d = sqrt(d2);
            const double cv = (w[0] * nv[0] + w[1] * nv[1] + w[2] * nv[2]) / d;
            if (!(cv > 0.0) || !(d > 0.0)) continue;
            const double ce = fabs(w[0] * ne[0] + w[1] * ne[1] + w[2] * ne[2]) / d;
            double len = 0.0;
            for (int a = 0; a < 3; a++) {
                b.org[3 * (size_t)n + a] = o[a];
                b.dir[3 * (size_t)n + a] = q[a] - o[a];
                len += (double)b.dir[3 * (size_t)n + a] * b.dir[3 * (size_t)n + a];
            }
            b.tn[n] = (float)(off / sqrt(len));
            b.tf[n] = 1.0f - CREF_SHORT;
            b.vtx[n] = v;
            b.pt[n] = k;
            b.w[n] = (float)(cv * ce * p->dA[k] / d2);
            if (++n == CREF_BATCH_RAYS) {
                r = batch_flush(rt, &b, n, p, E, 1);
                n = 0;
            }
        }
    }
    if (r == HL_OK) r = batch_flush(rt, &b, n, p, E, 1);
    batch_free(&b);
    hl_rt_destroy(rt);
    join_free(&j);
    return r;
}

/* centre: the points' directions and solid angles from the capture point
 * c, hidden where the surroundings hide them from c; each cast from every
 * vertex against the object and ground only. */
static hl_result ref_centre(hl_context *ctx, const hl_mesh *m, const float *pos, uint32_t ntris, const float c[3],
                            const cref_points *p, double *E)
{
    hl_mesh js;
    hl_rt *rs = NULL, *rm = NULL;
    cref_batch b = {0};
    float *dir = malloc(((size_t)p->n + 1) * 12), *om = malloc(((size_t)p->n + 1) * 4);
    hl_result r = dir && om ? HL_OK : hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's directions");
    if (r == HL_OK) r = join_mesh(ctx, NULL, pos, ntris, &js);
    if (r != HL_OK) {
        free(dir);
        free(om);
        return r;
    }
    r = hl_rt_create(ctx, &js, &rs);
    if (r == HL_OK) r = hl_rt_create(ctx, m, &rm);
    if (r == HL_OK) r = batch_alloc(ctx, &b);
    /* which points the capture point sees, in batches */
    uint32_t kept = 0;
    for (uint32_t k0 = 0; k0 < p->n && r == HL_OK; k0 += CREF_BATCH_RAYS) {
        const uint32_t nb = p->n - k0 < CREF_BATCH_RAYS ? p->n - k0 : CREF_BATCH_RAYS;
        for (uint32_t i = 0; i < nb; i++) {
            for (int a = 0; a < 3; a++) {
                b.org[3 * (size_t)i + a] = c[a];
                b.dir[3 * (size_t)i + a] = p->q[3 * ((size_t)k0 + i) + a] - c[a];
            }
            b.tn[i] = 0.0f;
            b.tf[i] = 1.0f - CREF_SHORT;
        }
        r = hl_rt_trace_occluded_seg(rs, nb, b.org, b.dir, b.tn, b.tf, b.occ);
        for (uint32_t i = 0; i < nb && r == HL_OK; i++) {
            const uint32_t k = k0 + i;
            const float *q = p->q + 3 * (size_t)k, *ne = p->nrm + 3 * (size_t)k;
            const double w[3] = {(double)q[0] - c[0], (double)q[1] - c[1], (double)q[2] - c[2]};
            const double d2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2], d = sqrt(d2);
            if (b.occ[i] || !(d > 0.0)) {
                om[k] = 0.0f;
                continue;
            }
            for (int a = 0; a < 3; a++) dir[3 * (size_t)k + a] = (float)(w[a] / d);
            om[k] = (float)(fabs(w[0] * ne[0] + w[1] * ne[1] + w[2] * ne[2]) / d * p->dA[k] / d2);
            kept++;
        }
    }
    uint32_t n = 0;
    for (uint32_t v = 0; v < m->vertex_count && r == HL_OK && kept; v++) {
        float o[3];
        vertex_origin(rm, m, v, o);
        const float *nv = m->normals + 3 * (size_t)v, off = hl_rt_robust_offset(rm, v);
        for (uint32_t k = 0; k < p->n && r == HL_OK; k++) {
            if (om[k] == 0.0f) continue;
            const float *d = dir + 3 * (size_t)k;
            const float cv = d[0] * nv[0] + d[1] * nv[1] + d[2] * nv[2];
            if (!(cv > 0.0f)) continue;
            memcpy(b.org + 3 * (size_t)n, o, 12);
            memcpy(b.dir + 3 * (size_t)n, d, 12);
            b.tn[n] = off;
            b.vtx[n] = v;
            b.pt[n] = k;
            b.w[n] = cv * om[k];
            if (++n == CREF_BATCH_RAYS) {
                r = batch_flush(rm, &b, n, p, E, 0);
                n = 0;
            }
        }
    }
    if (r == HL_OK) r = batch_flush(rm, &b, n, p, E, 0);
    batch_free(&b);
    hl_rt_destroy(rs);
    hl_rt_destroy(rm);
    join_free(&js);
    free(dir);
    free(om);
    return r;
}

/* discrete: the exact rows dotted with the untruncated capture. */
static hl_result ref_discrete(hl_context *ctx, const hl_transport *t, const float *pos, const float *em, uint32_t ntris,
                              const float c[3], float *rgb)
{
    const hl_mesh *m = t->mesh;
    const uint32_t N = t->info.N, nc = 2 * N * N, chunk = 64;
    hl_capture *cap = NULL;
    hl_bench_ref *b = NULL;
    float *L = malloc((size_t)nc * 12), *rows = malloc((size_t)chunk * nc * 4);
    uint32_t *idx = malloc(chunk * 4);
    hl_result r = L && rows && idx ? HL_OK : hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the discrete reference");
    if (r == HL_OK) r = hl_capture_create(ctx, N, 0, &cap);
    hl_capture_scene sc = {pos, em, ntris, {c[0], c[1], c[2]}, NULL};
    if (r == HL_OK) r = hl_capture_run(cap, &sc, L);
    if (r == HL_OK) r = hl_bench_ref_create(ctx, t, &b);
    for (uint32_t v0 = 0; v0 < m->vertex_count && r == HL_OK; v0 += chunk) {
        const uint32_t nb = m->vertex_count - v0 < chunk ? m->vertex_count - v0 : chunk;
        for (uint32_t i = 0; i < nb; i++) idx[i] = v0 + i;
        r = hl_bench_ref_rows(b, idx, nb, rows, NULL);
        for (uint32_t i = 0; i < nb && r == HL_OK; i++)
            for (int ch = 0; ch < 3; ch++) {
                const float *row = rows + (size_t)i * nc, *l = L + (size_t)ch * nc;
                double s = 0.0;
                for (uint32_t j = 0; j < nc; j++) s += (double)row[j] * l[j];
                rgb[3 * ((size_t)v0 + i) + ch] = (float)(s * m->albedo[3 * ((size_t)v0 + i) + ch]);
            }
    }
    hl_bench_ref_destroy(b);
    hl_capture_destroy(cap);
    free(L);
    free(rows);
    free(idx);
    return r;
}

hl_result hl_bench_capture_ref(hl_context *ctx, const hl_transport *t, hl_surroundings *s, int kind, uint32_t K,
                               float *rgb, double *seconds)
{
    const double t0 = hl_tools_now();
    if (!t || !s || !rgb || kind < HL_CAPTURE_REF_EXACT || kind > HL_CAPTURE_REF_DISCRETE)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "reference: a transport, surroundings, a kind and an output are required");
    if (kind != HL_CAPTURE_REF_DISCRETE && (K < 1 || K > HL_CAPTURE_REF_MAX_K))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "reference: %u points a side of each emitting triangle: 1 to %u", K,
                       HL_CAPTURE_REF_MAX_K);
    const hl_mesh *m = t->mesh;
    const float *pos, *em;
    hl_result r = hl_surroundings_triangles(s, &pos, &em);
    if (r != HL_OK) return r;
    const uint32_t ntris = hl_surroundings_triangle_count(s);
    float c[3];
    hl_object_centre(m, c);
    if (kind == HL_CAPTURE_REF_DISCRETE) {
        r = ref_discrete(ctx, t, pos, em, ntris, c, rgb);
    } else {
        cref_points p;
        double *E = calloc((size_t)m->vertex_count * 3 + 1, sizeof *E);
        r = E ? make_points(ctx, pos, em, ntris, K, &p)
              : hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the reference's irradiance");
        if (r == HL_OK) {
            r = kind == HL_CAPTURE_REF_EXACT ? ref_exact(ctx, m, pos, ntris, &p, E) : ref_centre(ctx, m, pos, ntris, c, &p, E);
            points_free(&p);
        }
        for (size_t i = 0; i < 3 * (size_t)m->vertex_count && r == HL_OK; i++)
            rgb[i] = (float)(E[i] * m->albedo[i] / HL_PI);
        free(E);
    }
    if (seconds) *seconds = hl_tools_now() - t0;
    return r;
}
