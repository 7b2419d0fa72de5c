/* bounce.c - the bounce phase of precompute --bounces (bounce.h).
 *
 * Horner's form keeps one set of rows in memory: S_0 = T_0 and
 * S_b = T_0 + W S_(b-1), where W is one gather, so S_B = T_0 + W T_0 +
 * ... + W^B T_0 without storing each bounce. The gather reads the
 * bounce_terms largest terms of each S_(b-1) row (indirect light is an
 * average of many rows, so the small terms of each weigh little:
 * docs/BOUNCES.md measures it), held in four bytes a term
 * (hl_bounce_src: a 16-bit slot and a binary16); T_0 itself is added whole, as the floats
 * of the direct file's values file (values_file.h) where it has one, a
 * chunk at a time, else decoded from its codes. Each chunk's K
 * directions a vertex are cast again every bounce (they depend on the
 * vertex alone), so that no bounce holds every vertex's hits. The last
 * S_B goes through the precompute's own truncation, with every direct
 * term kept, and quantisation (the direct stages' kernels, or their
 * twins) into the file.
 * Depends on: bounce.h, rays.h (Embree), geom.h and twins.h (truncation,
 * quantisation), transport_file.h (the writer), cl_internal.h (the
 * gather kernel), core.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bounce.h"
#include "cl_internal.h"
#include "geom.h"
#include "haarlight_tools.h"
#include "mesh_ops.h"
#include "precompute.h"
#include "rays.h"
#include "transport_file.h"
#include "transport_layout.h"
#include "twins.h"
#include "values_file.h"

/* One bounce's state, shared by the threads of a chunk. */
typedef struct bounce_run {
    hl_context *ctx;
    const hl_transport *t;
    /* t's rows a chunk at a time (t holds no entries: they stay in the
       file, at eoff of descriptor efd): entries [ve0, ..) in ebuf, and
       their floats (values_file.h) in vbuf; no reader: decoded from the
       codes */
    const char *direct_path, *out_path;
    int efd;
    uint64_t eoff;
    uint8_t *ebuf;
    size_t ecap;
    hl_vfile_reader *vr;
    float *vbuf;
    size_t vcap;
    uint64_t ve0;
    int values_checked;
    const hl_mesh *m;
    const hl_geom *g;
    uint32_t V, K, G, R, B;
    float *rho;
    /* the chunk's rays, cast again each bounce (the same rays: they
       depend on the vertex alone), so that no bounce holds every
       vertex's: R x K hits and their scratch */
    hl_rt *rt;
    uint32_t *prim;     /* R x K */
    float *uv;          /* R x K x 2 */
    float *org, *dir, *huv;
    hl_bounce_src cur;  /* S_(b-1), capped */
    int wide;           /* slots of 32 bits (ncoef above 65536) */
    /* the next rows (only where another bounce follows): their counts
       and scales, every vertex's; their terms a chunk's (R x G strided,
       start unused), appended to the spill file nfd as each chunk ends
       and read back into cur after the bounce, so that two sets of
       capped rows are never in memory at once */
    uint32_t *ncnt;
    hl_bounce_src next;
    int nfd;
    uint64_t nend;
    float *dense;       /* R x ncoef: the chunk's gathers */
    /* the last bounce: the chunk's rows for the writer */
    hl_trunc_params tp;
    hl_row_quant *rq;
    uint16_t *bc;
    uint8_t *entries;
    uint32_t *nnz;
    /* a chunk's job */
    uint32_t first, count, last;
    atomic_uint next_row;
    atomic_int oom;
    /* the device's gather, and its truncation and codes of the last
       bounce (the direct stages' kernels, PIPE_ROWS rows a launch) */
    cl_kernel k;
    hl_cl_pipe *pipe;
    hl_trunc_result *tr; /* R */
    cl_mem d_start, d_slot, d_val, d_scale, d_idx, d_rho, d_prim, d_uv, d_out;
} bounce_run;

/* --------------------------------------------------------- rows */

/* The direct row of vertex v of t, added into dense: its floats where
 * the values file gave them, else decoded from its codes (en and tval:
 * the chunk's entries and floats, from entry e0 on). */
static void add_direct_row(const hl_transport *t, const uint8_t *en, const float *tval, uint64_t e0, uint32_t v,
                           float *dense)
{
    const uint32_t nb = t->info.block_count;
    const hl_row_quant q = t->row_quant[v];
    uint64_t e = t->row_offset[v];
    for (uint32_t b = 0; b < nb; b++)
        for (uint32_t k = 0; k < t->block_counts[(size_t)v * nb + b]; k++, e++) {
            const uint32_t slot = b * HL_BLOCK + en[2 * (e - e0)];
            dense[slot] += tval ? tval[e - e0]
                                : hl_dequant(t->info.quant, en[2 * (e - e0) + 1], q.a, q.b, hl_dither_key(v, slot));
        }
}

/* The last truncation of vertex v's row (dense, S_B) under the energy
 * rule: tr, lowered where needed so that every term the direct file kept
 * stays. The direct rows already lost their share of the energy, so the
 * rule on S_B alone would drop about as much again (on a surface with no
 * bounces, 213 of a row's terms would become 205); keeping the direct
 * slots makes a row without bounces come back byte for byte, and costs
 * the terms of rows where a bounce cancels a direct term. An energy
 * rule's cap K still holds. */
static hl_trunc_result keep_direct_slots(const hl_transport *t, const uint8_t *en, uint64_t e0, uint32_t v,
                                         const float *dense, uint32_t ncoef, uint32_t K, hl_trunc_result tr)
{
    const uint32_t nb = t->info.block_count;
    uint32_t low = UINT32_MAX;
    uint64_t e = t->row_offset[v];
    for (uint32_t b = 0; b < nb; b++)
        for (uint32_t k = 0; k < t->block_counts[(size_t)v * nb + b]; k++, e++) {
            const uint32_t key = hl_key(dense[b * HL_BLOCK + en[2 * (e - e0)]]);
            if (key && key < low) low = key;
        }
    if (low == UINT32_MAX || low > tr.thresh) return tr; /* all kept already */
    hl_trunc_result w = {.thresh = low - 1, .ties = 0};
    for (uint32_t s = 0; s < ncoef; s++) w.count += hl_key(dense[s]) > w.thresh;
    return K && w.count > K ? tr : w;
}

/* The k-th largest of x[0 .. n) (k from 0), x reordered. */
static float kth_largest(float *x, uint32_t n, uint32_t k)
{
    int64_t lo = 0, hi = (int64_t)n - 1;
    while (lo < hi) {
        const float p = x[lo + (hi - lo) / 2];
        int64_t i = lo, j = hi;
        while (i <= j) {
            while (x[i] > p) i++;
            while (x[j] < p) j--;
            if (i <= j) {
                const float s = x[i];
                x[i++] = x[j];
                x[j--] = s;
            }
        }
        if ((int64_t)k <= j) hi = j;
        else if ((int64_t)k >= i) lo = i;
        else return x[k];
    }
    return x[k];
}

/* The G largest terms of dense (ties by slot order) into slot/val, in
 * slot order; returns their count. mag: ncoef scratch. */
static uint32_t cap_row(const float *dense, uint32_t ncoef, uint32_t G, float *mag, uint32_t *slot, float *val)
{
    uint32_t n = 0;
    for (uint32_t s = 0; s < ncoef; s++)
        if (dense[s] != 0.0f) mag[n++] = fabsf(dense[s]);
    float thr = 0.0f;
    uint32_t ties = UINT32_MAX;
    if (n > G) {
        thr = kth_largest(mag, n, G - 1);
        uint32_t above = 0;
        for (uint32_t i = 0; i < n; i++) above += mag[i] > thr;
        ties = G - above;
    }
    uint32_t c = 0;
    for (uint32_t s = 0; s < ncoef && c < G; s++) {
        const float a = fabsf(dense[s]);
        if (dense[s] == 0.0f || a < thr || (a == thr && n > G && ties == 0)) continue;
        if (n > G && a == thr) ties--;
        slot[c] = s;
        val[c++] = dense[s];
    }
    return c;
}

/* A binary16 of x, rounded to nearest, ties to even (|x| < 65520); below
 * the least normal one, 2^-14, zero (the gather's decoding reads normal
 * binary16s alone: hl_bounce_src). */
static uint16_t float_to_half(float x)
{
    uint32_t a;
    memcpy(&a, &x, 4);
    const uint16_t sign = (uint16_t)((a >> 16) & 0x8000u);
    a &= 0x7fffffffu;
    if (a < 0x38800000u) { /* x 2^24 rounded: 1024 (2^-14) or a subnormal */
        const uint16_t m = (uint16_t)lrintf(fabsf(x) * 16777216.0f);
        return m >= 0x400u ? (uint16_t)(sign | 0x400u) : 0;
    }
    const uint32_t m = a & 0x7fffffu, rem = m & 0x1fffu;
    uint32_t h = (((a >> 23) - 112u) << 10) | (m >> 13);
    if (rem > 0x1000u || (rem == 0x1000u && (h & 1u))) h++; /* a carry moves into the exponent, as it should */
    return (uint16_t)(sign | h);
}

void hl_bounce_encode(uint32_t n, const uint32_t *slot, const float *val, uint16_t *slot16, uint32_t *slot32,
                      uint16_t *half, float *scale)
{
    float top = 0.0f;
    for (uint32_t i = 0; i < n; i++) top = fmaxf(top, fabsf(val[i]));
    int e = 0;
    (void)frexpf(top, &e); /* top in [2^(e-1), 2^e) */
    const int zero = !(top >= 0x1p-100f);
    /* the largest term into [2^14, 2^15), so that terms down to 2^-28 of
       it keep the binary16's 11 significant bits */
    *scale = zero ? 1.0f : ldexpf(1.0f, e - 15);
    const float inv = zero ? 0.0f : ldexpf(1.0f, 15 - e); /* exact: a power of two */
    for (uint32_t i = 0; i < n; i++) {
        if (slot16) slot16[i] = (uint16_t)slot[i];
        else slot32[i] = slot[i];
        half[i] = float_to_half(val[i] * inv);
    }
}

/* Row v's terms (n, in slot and val) encoded into src from term at on. */
static void put_row(hl_bounce_src *src, size_t at, uint32_t v, uint32_t n, const uint32_t *slot, const float *val)
{
    hl_bounce_encode(n, slot, val, src->slot16 ? src->slot16 + at : NULL, src->slot32 ? src->slot32 + at : NULL,
                     src->val + at, src->scale + v);
}

/* The chunk [first, first + count)'s next rows packed and appended to
 * the spill file: its slots, then its values. */
static hl_result spill_chunk(bounce_run *u, uint32_t first, uint32_t count)
{
    const size_t sb = u->wide ? 4 : 2;
    char *ns = u->wide ? (char *)u->next.slot32 : (char *)u->next.slot16;
    size_t at = 0;
    for (uint32_t i = 0; i < count; i++) {
        const size_t n = u->ncnt[first + i], from = (size_t)i * u->G;
        memmove(ns + at * sb, ns + from * sb, n * sb);
        memmove(u->next.val + at, u->next.val + from, n * 2);
        at += n;
    }
    if (hl_tf_pwrite_all(u->nfd, ns, at * sb, u->nend) || hl_tf_pwrite_all(u->nfd, u->next.val, at * 2, u->nend + at * sb))
        return hl_fail(u->ctx, HL_ERR_IO, "cannot write the next bounce's rows beside %s: %s", u->out_path,
                       strerror(errno));
    u->nend += at * (sb + 2);
    return HL_OK;
}

/* The spilled next rows read back into cur (CSR), chunk by chunk as
 * they were written. */
static hl_result unspill(bounce_run *u)
{
    const size_t sb = u->wide ? 4 : 2;
    char *cs = u->wide ? (char *)u->cur.slot32 : (char *)u->cur.slot16;
    uint64_t off = 0;
    uint32_t at = 0;
    for (uint32_t first = 0; first < u->V; first += u->R) {
        const uint32_t count = u->V - first < u->R ? u->V - first : u->R;
        const uint32_t at0 = at;
        for (uint32_t v = first; v < first + count; v++) {
            u->cur.start[v] = at;
            at += u->ncnt[v];
        }
        const size_t n = at - at0;
        const int k = hl_tf_pread_all(u->nfd, cs + (size_t)at0 * sb, n * sb, off);
        const int k2 = k ? k : hl_tf_pread_all(u->nfd, u->cur.val + at0, n * 2, off + n * sb);
        if (k || k2)
            return hl_fail(u->ctx, HL_ERR_IO, "cannot read back the next bounce's rows beside %s: %s", u->out_path,
                           (k ? k : k2) < 0 ? strerror(errno) : "the file shrank");
        off += n * (sb + 2);
    }
    u->cur.start[u->V] = at;
    memcpy(u->cur.scale, u->next.scale, (size_t)u->V * 4);
    u->nend = 0;
    return HL_OK;
}

/* The spill file of the next rows: in out_path's directory (where the
 * output goes there is room for it; /tmp may be memory), unlinked at
 * once so that nothing is left behind, however the run ends. */
static hl_result spill_open(bounce_run *u)
{
    const char *slash = strrchr(u->out_path, '/');
    const size_t dn = slash ? (size_t)(slash - u->out_path) + 1 : 0;
    char *tmpl = malloc(dn + 32);
    if (!tmpl) return hl_fail(u->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory");
    memcpy(tmpl, u->out_path, dn);
    strcpy(tmpl + dn, ".haarlight-bounce-XXXXXX");
    u->nfd = mkstemp(tmpl);
    const int e = errno;
    if (u->nfd >= 0) unlink(tmpl);
    hl_result r = HL_OK;
    if (u->nfd < 0)
        r = hl_fail(u->ctx, HL_ERR_IO, "cannot make a scratch file for the bounces in the directory of %s: %s",
                    u->out_path, strerror(e));
    free(tmpl);
    return r;
}

/* --------------------------------------------------------- samples */

void hl_bounce_dirs(const hl_mesh *m, uint32_t v, uint32_t key, uint32_t K, float *dir)
{
    const float *n = m->normals + 3 * (size_t)v;
    /* a tangent frame (Duff et al. 2017) */
    const float sg = n[2] >= 0.0f ? 1.0f : -1.0f, a = -1.0f / (sg + n[2]), b = n[0] * n[1] * a;
    const float t1[3] = {1.0f + sg * n[0] * n[0] * a, sg * b, -sg * n[0]}, t2[3] = {b, sg + n[1] * n[1] * a, -n[1]};
    uint32_t S = (uint32_t)sqrt((double)K);
    if (S * S != K) S = 0;
    for (uint32_t k = 0; k < K; k++) {
        const uint32_t h1 = hl_dither_key(key, 2 * k), h2 = hl_dither_key(key, 2 * k + 1);
        const double j1 = (h1 >> 8) * (1.0 / 16777216.0), j2 = (h2 >> 8) * (1.0 / 16777216.0);
        const double u1 = S ? ((k % S) + j1) / S : (k + j1) / K, u2 = S ? ((k / S) + j2) / S : j2;
        const double r = sqrt(u1), ph = 2.0 * HL_PI * u2, z = sqrt(fmax(0.0, 1.0 - u1));
        const double x = r * cos(ph), y = r * sin(ph);
        for (int c = 0; c < 3; c++) dir[3 * k + c] = (float)(x * t1[c] + y * t2[c] + z * n[c]);
    }
}

hl_result hl_bounce_cast(hl_rt *rt, const hl_mesh *m, const uint32_t *list, uint32_t first, uint32_t count, uint32_t K,
                         uint32_t salt, float *org, float *dir, uint32_t *prim, float *hu, float *hv)
{
    for (uint32_t i = 0; i < count; i++) {
        const uint32_t v = list ? list[first + i] : first + i;
        const float *p = m->positions + 3 * (size_t)v, *n = m->normals + 3 * (size_t)v;
        const float off = hl_rt_robust_offset(rt, v);
        hl_bounce_dirs(m, v, v ^ salt, K, dir + (size_t)i * K * 3);
        for (uint32_t k = 0; k < K; k++)
            for (int c = 0; c < 3; c++) org[((size_t)i * K + k) * 3 + c] = hl_rt_origin_coord(p[c], n[c], off);
    }
    hl_result r = hl_rt_trace_primary(rt, count * K, org, dir, prim, hu, hv);
    for (size_t q = 0; q < (size_t)count * K && r == HL_OK; q++) {
        if (prim[q] == HL_BOUNCE_MISS) continue;
        const uint32_t *c = m->indices + 3 * (size_t)prim[q];
        const float w0 = 1.0f - hu[q] - hv[q];
        float dot = 0.0f;
        for (int a = 0; a < 3; a++)
            dot += (w0 * m->normals[3 * (size_t)c[0] + a] + hu[q] * m->normals[3 * (size_t)c[1] + a] +
                    hv[q] * m->normals[3 * (size_t)c[2] + a]) *
                   dir[3 * q + a];
        if (!(dot < 0.0f)) prim[q] = HL_BOUNCE_MISS;
    }
    return r;
}

/* The hits of the chunk's vertices [first, first + count), K each. */
static hl_result cast_hits(bounce_run *u, uint32_t first, uint32_t count)
{
    const size_t RK = (size_t)u->R * u->K;
    hl_result r = hl_bounce_cast(u->rt, u->m, NULL, first, count, u->K, 0, u->org, u->dir, u->prim, u->huv, u->huv + RK);
    for (size_t q = 0; q < (size_t)count * u->K && r == HL_OK; q++) {
        u->uv[2 * q] = u->huv[q];
        u->uv[2 * q + 1] = u->huv[RK + q];
    }
    return r;
}

/* --------------------------------------------------------- the device */

/* Rows a launch of the last bounce's truncation and codes: their
 * buffers (a few of ncoef floats a row) stay small beside the gathers'. */
#define PIPE_ROWS 256u

static hl_result device_open(bounce_run *u)
{
    hl_context *ctx = u->ctx;
    cl_int e;
    const char *kname = u->wide ? "hl_bounce_gather_wide" : "hl_bounce_gather";
    u->k = clCreateKernel(ctx->cl->program, kname, &e);
    if (e != CL_SUCCESS) return hl_fail(ctx, HL_ERR_OPENCL, "OpenCL: the kernel %s: %s", kname, hl_cl_err_name(e));
    const size_t cap = (size_t)u->V * u->G, sb = u->wide ? 4 : 2;
    /* a device in host memory reads the rows where they are
       (device_rows), with no copy of its own */
    if (!ctx->cl->host_memory) {
        TRY(hl_cl_make_buf(ctx, &u->d_start, CL_MEM_READ_ONLY, ((size_t)u->V + 1) * 4, NULL, "the bounce rows"));
        TRY(hl_cl_make_buf(ctx, &u->d_slot, CL_MEM_READ_ONLY, cap * sb + 4, NULL, "the bounce rows"));
        TRY(hl_cl_make_buf(ctx, &u->d_val, CL_MEM_READ_ONLY, cap * 2 + 4, NULL, "the bounce rows"));
        TRY(hl_cl_make_buf(ctx, &u->d_scale, CL_MEM_READ_ONLY, (size_t)u->V * 4 + 4, NULL, "the bounce rows"));
    }
    TRY(hl_cl_make_buf(ctx, &u->d_idx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, (size_t)u->m->triangle_count * 12,
                       u->m->indices, "the triangles"));
    TRY(hl_cl_make_buf(ctx, &u->d_rho, CL_MEM_READ_ONLY, (size_t)u->V * 4, NULL, "the albedo"));
    TRY(hl_cl_make_buf(ctx, &u->d_prim, CL_MEM_READ_ONLY, (size_t)u->R * u->K * 4, NULL, "the bounce hits"));
    TRY(hl_cl_make_buf(ctx, &u->d_uv, CL_MEM_READ_ONLY, (size_t)u->R * u->K * 8, NULL, "the bounce hits"));
    u->tr = hl_alloc_big(ctx, (size_t)u->R * sizeof *u->tr, "truncation results");
    if (!u->tr) return HL_ERR_OUT_OF_MEMORY;
    TRY(hl_cl_pipe_create(ctx, u->g, u->R < PIPE_ROWS ? u->R : PIPE_ROWS, &u->pipe));
    return hl_cl_make_buf(ctx, &u->d_out, CL_MEM_WRITE_ONLY, (size_t)u->R * u->g->ncoef * 4, NULL, "the gathers");
}

static void device_close(bounce_run *u)
{
    hl_cl_pipe_destroy(u->pipe);
    hl_free_big(u->tr);
    if (!u->ctx->cl) return;
    if (u->k) clReleaseKernel(u->k);
    cl_mem *m[] = {&u->d_start, &u->d_slot, &u->d_val, &u->d_scale, &u->d_idx, &u->d_rho, &u->d_prim, &u->d_uv, &u->d_out};
    for (size_t i = 0; i < sizeof m / sizeof *m; i++) hl_cl_release_buf(u->ctx->cl, m[i]);
}

/* The channel's albedo onto the device, once a channel. */
static hl_result device_albedo(bounce_run *u)
{
    CL_TRY(u->ctx, clEnqueueWriteBuffer(u->ctx->cl->queue, u->d_rho, CL_TRUE, 0, (size_t)u->V * 4, u->rho, 0, NULL, NULL),
           "uploading the albedo");
    return HL_OK;
}

/* A device in host memory: the rows' buffers let go before the host
 * writes the next rows into their memory. */
static void device_rows_release(bounce_run *u)
{
    if (!u->k || !u->ctx->cl->host_memory) return;
    hl_cl_release_buf(u->ctx->cl, &u->d_start);
    hl_cl_release_buf(u->ctx->cl, &u->d_slot);
    hl_cl_release_buf(u->ctx->cl, &u->d_val);
    hl_cl_release_buf(u->ctx->cl, &u->d_scale);
}

/* The rows of S_(b-1) onto the device, once a bounce: copied, or (a
 * device in host memory) buffers over the host's own arrays, made anew
 * each bounce after the host wrote them. */
static hl_result device_rows(bounce_run *u)
{
    cl_command_queue q = u->ctx->cl->queue;
    const size_t n = u->cur.start[u->V], sb = u->wide ? 4 : 2;
    void *slot = u->wide ? (void *)u->cur.slot32 : (void *)u->cur.slot16;
    if (u->ctx->cl->host_memory) {
        device_rows_release(u);
        const cl_mem_flags f = CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR;
        TRY(hl_cl_make_buf(u->ctx, &u->d_start, f, ((size_t)u->V + 1) * 4, u->cur.start, "the bounce rows"));
        TRY(hl_cl_make_buf(u->ctx, &u->d_slot, f, n * sb + 4, slot, "the bounce rows"));
        TRY(hl_cl_make_buf(u->ctx, &u->d_val, f, n * 2 + 4, u->cur.val, "the bounce rows"));
        return hl_cl_make_buf(u->ctx, &u->d_scale, f, (size_t)u->V * 4 + 4, u->cur.scale, "the bounce rows");
    }
    CL_TRY(u->ctx, clEnqueueWriteBuffer(q, u->d_start, CL_FALSE, 0, ((size_t)u->V + 1) * 4, u->cur.start, 0, NULL, NULL),
           "uploading the bounce rows");
    CL_TRY(u->ctx, clEnqueueWriteBuffer(q, u->d_scale, CL_FALSE, 0, (size_t)u->V * 4, u->cur.scale, 0, NULL, NULL),
           "uploading the bounce rows");
    if (n) {
        CL_TRY(u->ctx, clEnqueueWriteBuffer(q, u->d_slot, CL_FALSE, 0, n * sb, slot, 0, NULL, NULL),
               "uploading the bounce rows");
        CL_TRY(u->ctx, clEnqueueWriteBuffer(q, u->d_val, CL_FALSE, 0, n * 2, u->cur.val, 0, NULL, NULL),
               "uploading the bounce rows");
    }
    return HL_OK;
}

/* The chunk's gathers into u->dense on the device. */
static hl_result device_gather(bounce_run *u)
{
    hl_context *ctx = u->ctx;
    cl_command_queue q = ctx->cl->queue;
    const size_t ns = (size_t)u->count * u->K;
    CL_TRY(ctx, clEnqueueWriteBuffer(q, u->d_prim, CL_FALSE, 0, ns * 4, u->prim, 0, NULL, NULL),
           "uploading the bounce hits");
    CL_TRY(ctx, clEnqueueWriteBuffer(q, u->d_uv, CL_FALSE, 0, ns * 8, u->uv, 0, NULL, NULL),
           "uploading the bounce hits");
    cl_uint K = u->K, nc = u->g->ncoef, count = u->count;
#define SETARG(i, v) CL_TRY(ctx, clSetKernelArg(u->k, i, sizeof(v), &(v)), "clSetKernelArg (hl_bounce_gather)")
    SETARG(0, u->d_start);
    SETARG(1, u->d_slot);
    SETARG(2, u->d_val);
    SETARG(3, u->d_scale);
    SETARG(4, u->d_idx);
    SETARG(5, u->d_rho);
    SETARG(6, u->d_prim);
    SETARG(7, u->d_uv);
    SETARG(8, K);
    SETARG(9, nc);
    SETARG(10, count);
    SETARG(11, u->d_out);
#undef SETARG
    /* the device's fixed group size, so the kernel builds once per device */
    size_t local = ctx->cl->wg ? ctx->cl->wg : 1, global = ((size_t)u->count + local - 1) / local * local;
    CL_TRY(ctx, clEnqueueNDRangeKernel(q, u->k, 1, NULL, &global, &local, 0, NULL, NULL), "hl_bounce_gather");
    CL_TRY(ctx, clEnqueueReadBuffer(q, u->d_out, CL_TRUE, 0, (size_t)u->count * u->g->ncoef * 4, u->dense, 0, NULL, NULL),
           "reading the gathers");
    return HL_OK;
}

/* The last bounce's rows of the chunk (S_B in u->dense) truncated and
 * coded by the direct stages' kernels, the direct terms kept between
 * the two (keep_direct_slots): the twins' bytes. */
static hl_result device_code(bounce_run *u)
{
    const uint32_t nc = u->g->ncoef, nb = u->g->nblocks;
    for (uint32_t off = 0; off < u->count; off += PIPE_ROWS) {
        const uint32_t n = u->count - off < PIPE_ROWS ? u->count - off : PIPE_ROWS;
        float *rows = u->dense + (size_t)off * nc;
        TRY(hl_cl_pipe_truncate(u->pipe, n, rows, u->tp, u->tr + off));
        if (u->tp.rule == HL_TRUNC_ENERGY)
            for (uint32_t i = 0; i < n; i++)
                u->tr[off + i] = keep_direct_slots(u->t, u->ebuf, u->ve0, u->first + off + i, rows + (size_t)i * nc, nc,
                                                   u->tp.K, u->tr[off + i]);
        TRY(hl_cl_pipe_quantize(u->pipe, n, u->first + off, rows, u->tr + off, u->t->info.quant, u->rq + off,
                                u->bc + (size_t)off * nb, u->entries + (size_t)off * nc * 2, u->nnz + off));
    }
    return HL_OK;
}

/* --------------------------------------------------------- a chunk */

/* After the gather of the chunk's vertex i: S_b = T_0 + the gather, then
 * capped into the next rows, or (the last bounce) truncated and quantised
 * for the file. With ref set the gather is made here (the twin). */
static void *chunk_worker(void *arg)
{
    bounce_run *u = arg;
    const hl_geom *g = u->g;
    const int ref = u->k == NULL;
    float *mag = malloc((size_t)g->ncoef * 4), *cval = malloc((size_t)u->G * 4 + 4);
    uint32_t *cslot = malloc((size_t)u->G * 4 + 4);
    hl_ref_key *keys = malloc((size_t)g->ncoef * sizeof *keys);
    const int ok = mag && cval && cslot && keys;
    if (!ok) atomic_store(&u->oom, 1);
    for (;;) {
        const uint32_t i = atomic_fetch_add(&u->next_row, 1u);
        if (i >= u->count || !ok) break;
        const uint32_t v = u->first + i;
        float *dense = u->dense + (size_t)i * g->ncoef;
        if (ref)
            hl_ref_bounce_gather(&u->cur, u->m->indices, u->rho, u->prim + (size_t)i * u->K,
                                 u->uv + (size_t)i * u->K * 2, u->K, g->ncoef, dense);
        add_direct_row(u->t, u->ebuf, u->vr ? u->vbuf : NULL, u->ve0, v, dense);
        if (!u->last) {
            u->ncnt[v] = cap_row(dense, g->ncoef, u->G, mag, cslot, cval);
            put_row(&u->next, (size_t)i * u->G, v, u->ncnt[v], cslot, cval);
        } else if (ref) { /* on the device: device_code, after */
            hl_trunc_result tr = hl_ref_truncate(g, dense, u->tp, keys);
            if (u->tp.rule == HL_TRUNC_ENERGY)
                tr = keep_direct_slots(u->t, u->ebuf, u->ve0, v, dense, g->ncoef, u->tp.K, tr);
            u->nnz[i] = hl_ref_quantize(g, dense, tr, u->t->info.quant, v, &u->rq[i], u->bc + (size_t)i * g->nblocks,
                                        u->entries + (size_t)i * g->ncoef * 2);
        }
    }
    free(mag);
    free(cval);
    free(cslot);
    free(keys);
    return NULL;
}

/* The direct rows of vertices [first, first + count): their entries into
 * u->ebuf and their floats into u->vbuf. */
static hl_result load_direct(bounce_run *u, uint32_t first, uint32_t count)
{
    const uint64_t e0 = u->t->row_offset[first], n = u->t->row_offset[first + count] - e0;
    if (n > u->ecap) {
        uint8_t *b = realloc(u->ebuf, (size_t)n * 2);
        if (!b) return hl_fail(u->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the direct rows");
        u->ebuf = b;
        u->ecap = (size_t)n;
    }
    if (u->vr && n > u->vcap) {
        float *b = realloc(u->vbuf, (size_t)n * 4);
        if (!b) return hl_fail(u->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the direct rows' floats");
        u->vbuf = b;
        u->vcap = (size_t)n;
    }
    u->ve0 = e0;
    const int k = hl_tf_pread_all(u->efd, u->ebuf, (size_t)n * 2, u->eoff + 2 * e0);
    if (k)
        return hl_fail(u->ctx, HL_ERR_IO, "%s: cannot read its entries: %s", u->direct_path,
                       k < 0 ? strerror(errno) : "the file shrank");
    return u->vr ? hl_vfile_read(u->ctx, u->vr, e0, (size_t)n, u->vbuf) : HL_OK;
}

static hl_result run_chunk(bounce_run *u, uint32_t first, uint32_t count, int last)
{
    TRY(load_direct(u, first, count));
    TRY(cast_hits(u, first, count));
    u->first = first;
    u->count = count;
    u->last = last;
    atomic_store(&u->next_row, 0u);
    atomic_store(&u->oom, 0);
    if (u->k) TRY(device_gather(u));
    hl_run_threads(u->ctx->threads, chunk_worker, u);
    if (atomic_load(&u->oom)) return hl_fail(u->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the bounce's scratch");
    if (!last) return spill_chunk(u, first, count);
    return u->k ? device_code(u) : HL_OK;
}

/* --------------------------------------------------------- the phase */

hl_result hl_bounce_check_albedo(hl_context *ctx, const hl_mesh *m)
{
    for (uint32_t v = 0; v < m->vertex_count; v++)
        for (int c = 0; c < 3; c++) {
            const float a = m->albedo ? m->albedo[3 * (size_t)v + c] : HL_DEFAULT_ALBEDO;
            if (!(a >= 0.0f && a <= 1.0f))
                return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                               "--bounces: vertex %u has albedo %g in channel %d; every albedo must be in [0, 1] "
                               "(light would grow with each bounce)", v, (double)a, c);
        }
    return HL_OK;
}

uint32_t hl_bounce_channels(const hl_mesh *m)
{
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        const float *a = m->albedo + 3 * (size_t)v;
        if (a[0] != a[1] || a[0] != a[2]) return 3;
    }
    return 1;
}

/* The bounce albedo of channel c: each vertex's albedo there (the same
 * in every channel where the file has one row a vertex). */
static void bounce_albedo(bounce_run *u, int c)
{
    for (uint32_t v = 0; v < u->V; v++) u->rho[v] = u->m->albedo[3 * (size_t)v + c];
}

static hl_result alloc_run(bounce_run *u)
{
    hl_context *ctx = u->ctx;
    const size_t VG = (size_t)u->V * u->G, nc = u->g->ncoef;
    u->rho = hl_alloc_big(ctx, (size_t)u->V * 4, "the albedo");
    const size_t RK = (size_t)u->R * u->K;
    u->prim = hl_alloc_big(ctx, RK * 4, "the bounce hits");
    u->uv = hl_alloc_big(ctx, RK * 8, "the bounce hits");
    u->org = hl_alloc_big(ctx, RK * 12, "the bounce rays");
    u->dir = hl_alloc_big(ctx, RK * 12, "the bounce rays");
    u->huv = hl_alloc_big(ctx, RK * 8, "the bounce hits");
    u->cur.start = hl_alloc_big(ctx, ((size_t)u->V + 1) * 4, "the bounce rows");
    /* the next rows only where a bounce is followed by another */
    const int next = u->B >= 2;
    hl_bounce_src *rows[2] = {&u->cur, next ? &u->next : NULL};
    int rows_ok = u->cur.start != NULL;
    for (int r = 0; r < 2 && rows[r]; r++) {
        const size_t terms = r ? (size_t)u->R * u->G : VG; /* the next rows: a chunk's */
        if (u->wide) rows[r]->slot32 = hl_alloc_big(ctx, terms * 4 + 4, "the bounce rows");
        else rows[r]->slot16 = hl_alloc_big(ctx, terms * 2 + 4, "the bounce rows");
        rows[r]->val = hl_alloc_big(ctx, terms * 2 + 4, "the bounce rows");
        rows[r]->scale = hl_alloc_big(ctx, (size_t)u->V * 4 + 4, "the bounce rows");
        rows_ok = rows_ok && (rows[r]->slot16 || rows[r]->slot32) && rows[r]->val && rows[r]->scale;
    }
    u->ncnt = next ? hl_alloc_big(ctx, (size_t)u->V * 4, "the bounce rows") : NULL;
    u->dense = hl_alloc_big(ctx, (size_t)u->R * nc * 4, "the gathers");
    u->rq = hl_alloc_big(ctx, (size_t)u->R * sizeof *u->rq, "quantisation parameters");
    u->bc = hl_alloc_big(ctx, (size_t)u->R * u->g->nblocks * 2, "block counts");
    u->entries = hl_alloc_big(ctx, (size_t)u->R * nc * 2, "entries");
    u->nnz = hl_alloc_big(ctx, (size_t)u->R * 4, "entry counts");
    u->cur.V = u->V;
    return u->rho && u->prim && u->uv && u->org && u->dir && u->huv && rows_ok && (!next || u->ncnt) &&
                   u->dense && u->rq && u->bc && u->entries && u->nnz
               ? HL_OK
               : HL_ERR_OUT_OF_MEMORY;
}

static void free_run(bounce_run *u)
{
    void *p[] = {u->rho,          u->prim,        u->uv,          u->org,        u->dir,         u->huv,
                 u->cur.start,    u->cur.slot16,  u->cur.slot32,  u->cur.val,    u->cur.scale,   u->ncnt,
                 u->next.slot16,  u->next.slot32, u->next.val,    u->next.scale, u->dense,       u->rq,
                 u->bc,           u->entries,     u->nnz};
    for (size_t i = 0; i < sizeof p / sizeof *p; i++) hl_free_big(p[i]);
    device_close(u);
}

/* S_0 = T_0 capped: the direct rows as the first gather reads them,
 * straight into cur. */
static hl_result first_rows(bounce_run *u)
{
    float *dense = malloc((size_t)u->g->ncoef * 4), *mag = malloc((size_t)u->g->ncoef * 4);
    float *cval = malloc((size_t)u->G * 4 + 4);
    uint32_t *cslot = malloc((size_t)u->G * 4 + 4);
    if (!dense || !mag || !cval || !cslot) {
        free(dense);
        free(mag);
        free(cval);
        free(cslot);
        return hl_fail(u->ctx, HL_ERR_OUT_OF_MEMORY, "out of memory for the bounce rows");
    }
    hl_result r = HL_OK;
    uint32_t at = 0;
    for (uint32_t first = 0; first < u->V && r == HL_OK; first += u->R) {
        const uint32_t count = u->V - first < u->R ? u->V - first : u->R;
        r = load_direct(u, first, count);
        if (r == HL_OK && u->vr && !u->values_checked)
            r = hl_vfile_check(u->ctx, u->vr, u->direct_path, u->t, first, count, u->ebuf, u->vbuf);
        for (uint32_t v = first; v < first + count && r == HL_OK; v++) {
            memset(dense, 0, (size_t)u->g->ncoef * 4);
            add_direct_row(u->t, u->ebuf, u->vr ? u->vbuf : NULL, u->ve0, v, dense);
            u->cur.start[v] = at;
            const uint32_t n = cap_row(dense, u->g->ncoef, u->G, mag, cslot, cval);
            put_row(&u->cur, at, v, n, cslot, cval);
            at += n;
        }
    }
    u->cur.start[u->V] = at;
    u->values_checked = u->vr != NULL;
    free(dense);
    free(mag);
    free(cval);
    free(cslot);
    return r;
}

/* Channel c's bounces (of channels): S_1 .. S_B gathered with its albedo
 * over every vertex, the last one over [lo, hi) only, truncated, coded
 * and appended to w; *kept gets its coefficients. */
static hl_result bounce_channel(bounce_run *u, const hl_precompute_desc *d, hl_tfile_writer *w, uint32_t c,
                                uint32_t channels, uint32_t lo, uint32_t hi, uint64_t *kept)
{
    static const char *const cname[3] = {" (red)", " (green)", " (blue)"};
    hl_context *ctx = u->ctx;
    bounce_albedo(u, (int)c);
    hl_result r = u->k ? device_albedo(u) : HL_OK;
    if (r == HL_OK) r = first_rows(u);
    for (uint32_t b = 1; b <= d->bounces && r == HL_OK; b++) {
        const double tb = hl_now();
        const int last = b == d->bounces;
        if (u->k) r = device_rows(u);
        u->nend = 0;
        const uint32_t from = last ? lo : 0, to = last ? hi : u->V;
        for (uint32_t first = from; first < to && r == HL_OK; first += u->R) {
            const uint32_t count = to - first < u->R ? to - first : u->R;
            r = run_chunk(u, first, count, last);
            if (r == HL_OK && last) {
                r = hl_tfile_writer_append(w, count, u->rq, u->bc, u->entries, (size_t)u->g->ncoef * 2, u->nnz);
                for (uint32_t i = 0; i < count; i++) *kept += u->nnz[i];
            }
            if (r == HL_OK && hl_context_cancelled(ctx)) r = HL_ERR_INTERRUPTED;
        }
        device_rows_release(u);
        if (r == HL_OK && !last) r = unspill(u);
        if (r == HL_OK && !ctx->quiet)
            fprintf(stderr, "precompute: bounce %u/%u%s: %u vertices x %u rays, the %u largest terms of each hit row, %.1f s\n",
                    b, d->bounces, channels == 3 ? cname[c] : "", last ? hi - lo : u->V, u->K, u->G, hl_now() - tb);
    }
    return r;
}

hl_result hl_bounce_file(hl_context *ctx, const hl_precompute_desc *d, const hl_mesh *mesh, const char *direct_path,
                         uint32_t shard_index, uint32_t shard_count, const char *out_path, double *seconds,
                         uint64_t *kept_out)
{
    const double t0 = hl_now();
    hl_transport *t = NULL;
    uint64_t eoff = 0;
    /* the entries stay in the file, read a chunk of rows at a time */
    hl_result r = hl_transport_load_streamed(ctx, direct_path, &t, &eoff);
    if (r != HL_OK) return r;
    const hl_transport_info *ti = &t->info;
    if (ti->vertex_count != mesh->vertex_count || ti->triangle_count != mesh->triangle_count ||
        memcmp(t->mesh->positions, mesh->positions, (size_t)mesh->vertex_count * 12) ||
        ti->N != d->N || ti->C != d->C || ti->supersample != d->supersample || ti->quant != d->quant ||
        ti->basis != d->basis || ti->rule != d->rule || ti->K != d->K || ti->ray_offset != d->ray_offset ||
        (d->rule == HL_TRUNC_ENERGY && ti->eps != d->eps)) {
        hl_transport_destroy(t);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       d->direct_rows ? "%s: its direct rows are of another mesh or other options than this run's (the "
                                        "same mesh, --ground and options as its precompute are needed)"
                                      : "%s: its direct rows are of another mesh or other options than this run's "
                                        "(removed: run again without --resume)",
                       direct_path);
    }
    if (ti->bounces) {
        const uint32_t held = ti->bounces; /* ti goes with t */
        hl_transport_destroy(t);
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: already holds %u bounces; the bounces start from direct rows",
                       direct_path, held);
    }
    hl_vfile_reader *vr = NULL;
    r = hl_vfile_open(ctx, direct_path, t, &vr);
    if (r != HL_OK) {
        hl_transport_destroy(t);
        return r;
    }
    if (!vr && !ctx->quiet)
        fprintf(stderr,
                "precompute: warning: no %s.values: the bounces start from the direct rows' 8-bit codes, so the direct "
                "light is coded twice (precompute the direct rows with --keep-floats to keep their floats)\n",
                direct_path);
    bounce_run u = {.ctx = ctx, .t = t, .direct_path = direct_path, .out_path = out_path, .eoff = eoff, .vr = vr,
                    .m = t->mesh, .V = t->info.vertex_count, .B = d->bounces, .nfd = -1};
    u.efd = open(direct_path, O_RDONLY | O_CLOEXEC);
    if (u.efd < 0) {
        const int e = errno;
        hl_vfile_close(vr);
        hl_transport_destroy(t);
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot open: %s", direct_path, strerror(e));
    }
    u.K = d->bounce_rays ? d->bounce_rays : HL_DEFAULT_BOUNCE_RAYS;
    u.G = d->bounce_terms == HL_TERMS_ALL ? 2 * t->info.N * t->info.N
          : d->bounce_terms                ? d->bounce_terms
                                           : HL_DEFAULT_BOUNCE_TERMS;
    if (u.G > 2 * t->info.N * t->info.N) u.G = 2 * t->info.N * t->info.N;
    u.R = d->chunk && d->chunk < u.V ? d->chunk : (u.V < HL_DEFAULT_CHUNK ? u.V : HL_DEFAULT_CHUNK);
    /* 16-bit slots wherever they reach (N up to 128); HL_TEST_BOUNCE_WIDE=1
       forces the 32-bit ones, so that small tests cover them too */
    const char *tw = getenv("HL_TEST_BOUNCE_WIDE");
    u.wide = 2ull * t->info.N * t->info.N > 65536u || (tw && strcmp(tw, "1") == 0);
    hl_geom *g = NULL;
    hl_tfile_writer *w = NULL;
    r = hl_geom_create(ctx, t->info.N, t->info.C, &g);
    u.g = g;
    if (r == HL_OK) r = alloc_run(&u);
    if (r == HL_OK && u.B >= 2) r = spill_open(&u);
    if (r == HL_OK) r = hl_bounce_check_albedo(ctx, t->mesh);
    if (r == HL_OK) r = hl_rt_create(ctx, t->mesh, &u.rt);
    /* a shard gathers its own vertices' last bounce, but the bounces
       before it for every vertex (each reads rows from anywhere) */
    uint32_t lo = 0, hi = u.V;
    if (shard_count) hl_shard_range(u.V, shard_index, shard_count, &lo, &hi);
    if (r == HL_OK && ctx->backend == HL_BACKEND_OPENCL) r = device_open(&u);
    hl_transport_info info = t->info;
    info.bounces = d->bounces;
    /* a row a channel only where some surface is coloured: grey bounces
       are the same in every channel */
    info.channels = hl_bounce_channels(t->mesh);
    info.coefficients_kept = 0;
    u.tp = hl_precompute_trunc_params(d);
    /* the direct rays' counters once, in shard 0, so that the shards
       merged carry the direct file's as one run does */
    if (shard_count && shard_index) info.rays_cast = info.rays_culled = 0;
    if (r == HL_OK) r = hl_tfile_writer_open_shard(ctx, out_path, &info, t->mesh, shard_index, shard_count, &w);
    uint64_t kept = 0;
    /* each channel's bounces alone (its rows are a plane of the file),
       from the same rays */
    for (uint32_t c = 0; c < info.channels && r == HL_OK; c++)
        r = bounce_channel(&u, d, w, c, info.channels, lo, hi, &kept);
    if (r == HL_OK) {
        info.coefficients_kept = kept;
        r = hl_tfile_writer_finish(w, &info);
        w = NULL;
    }
    if (w) hl_tfile_writer_abort(w);
    if (r == HL_ERR_INTERRUPTED)
        hl_fail(ctx, r, "interrupted in the bounces: %s not written (the direct rows stay in %s)", out_path, direct_path);
    free_run(&u);
    hl_rt_destroy(u.rt);
    hl_vfile_close(vr);
    close(u.efd);
    if (u.nfd >= 0) close(u.nfd);
    free(u.vbuf);
    free(u.ebuf);
    hl_geom_destroy(g);
    hl_transport_destroy(t);
    if (seconds) *seconds = hl_now() - t0;
    if (kept_out) *kept_out = kept;
    return r;
}
