/* test_parts.c - the dot products in parts (host/src/relight/cl_parts.c),
 * suite "parts".
 *
 * parts.quarter  a relighter whose device memory limit leaves its columns
 *                about a quarter of what they need runs in parts and
 *                gives the colours of an unlimited one, bit for bit
 *                (tolerance 0), read back or left on the device, over
 *                several lighting changes (the part buffers reused),
 *                and the same count of clamped vertices (the ranges'
 *                tallies joined over the parts);
 *                hl_relighter_memory_use reports the parts and the
 *                device bytes (those the context counts, when unlimited).
 * parts.refused  a limit that leaves the columns nothing is refused with
 *                a message naming the limit, not a crash.
 * parts.from_file  hl_relighter_create_from_file: the entries freed, the
 *                columns built from rows read from the file again, whole
 *                and in parts, give the same colours bit for bit; a file
 *                other than the transport's, or the same file with an
 *                entry changed (checksums made to match), is refused,
 *                and the transport keeps its entries.
 * parts.rows     hl_relighter_create_once: the dot products on the rows
 *                as loaded (relight_rows.cl) give the colours of the
 *                columns bit for bit, the device holding the entries and
 *                no columns, the transport keeping its entries; under a
 *                device memory limit too small for the entries it builds
 *                the columns from the file instead, in parts, with the
 *                same colours.
 * parts.resident  a device whose largest allocation (HL_TEST_MAX_ALLOC)
 *                is a quarter of the columns but whose memory holds them
 *                all: parts with buffers of their own, uploaded once,
 *                all of the columns on the device, the same colours bit
 *                for bit, from the file and from loaded entries.
 * parts.both     a device memory limit that holds 3/4 of the columns
 *                and a largest allocation of a quarter (as PoCL gives
 *                when the page cache holds a big file): parts uploaded
 *                in turn whose shared buffers each fit the largest
 *                allocation, the same colours bit for bit.
 *
 * Depends on: haarlight_core, an OpenCL device (PoCL),
 * tests/common/light_util.h.
 */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include <stdint.h>
#include <stdlib.h>

#include "cl_backend.h"
#include "haarlight_tools.h"
#include "geom.h"
#include "hl_test.h"
#include "lighting.h"
#include "twins.h"
#include "light_util.h"
#include "mesh_util.h"

static hl_context *ctx_limited(uint64_t bytes)
{
    hl_context_desc d = {.backend = HL_BACKEND_OPENCL, .cl_platform = -1, .cl_device = -1, .device_memory = bytes,
                         .quiet = 1};
    hl_context *c = NULL;
    char err[4096];
    if (hl_context_create(&d, &c, err, sizeof err) != HL_OK) fprintf(stderr, "context: %s\n", err);
    return c;
}

/* The device memory an unlimited relighter of t holds (*used) and of that
 * its columns (*cols); 0 when it could not be made. */
static int measure(const hl_transport *t, uint64_t *used, uint64_t *cols)
{
    hl_context *ctx = ctx_of(HL_BACKEND_OPENCL);
    hl_relighter *r = NULL;
    int ok = ctx && hl_relighter_create(ctx, t, &r) == HL_OK;
    HL_CHECK(ok, "unlimited relighter: %s", ctx ? hl_context_last_error(ctx) : "no context");
    if (ok) {
        *used = hl_cl_memory_used(ctx);
        *cols = hl_cl_light_column_bytes(hl_relighter_device(r));
        hl_relighter_memory m;
        HL_CHECK(hl_relighter_memory_use(r, &m) == HL_OK, "memory use");
        /* the context holds the relighter's buffers alone */
        HL_CHECK(m.parts == 1 && m.column_bytes == *cols && m.device_bytes == *used,
                 "unlimited: 1 part (got %u), columns %llu (%llu), device %llu (the context holds %llu)", m.parts,
                 (unsigned long long)m.column_bytes, (unsigned long long)*cols, (unsigned long long)m.device_bytes,
                 (unsigned long long)*used);
    }
    hl_relighter_destroy(r);
    hl_context_destroy(ctx);
    return ok;
}

static void case_quarter(void)
{
    const char *path = make_transport("parts_q.hlt", "");
    hl_context *ref_ctx = ctx_of(HL_BACKEND_OPENCL);
    hl_transport *t = NULL;
    HL_CHECK(path && ref_ctx && hl_transport_load(ref_ctx, path, &t) == HL_OK, "transport");
    uint64_t used = 0, cols = 0;
    if (!t || !measure(t, &used, &cols)) return;
    /* everything else as before; the columns a quarter of their bytes */
    const uint64_t limit = used - cols + cols / 4;
    printf("unlimited: %.2f MiB of device memory, columns %.2f MiB; limit %.2f MiB\n", (double)used / 1048576.0,
           (double)cols / 1048576.0, (double)limit / 1048576.0);
    hl_context *lim = ctx_limited(limit);
    hl_relighter *a = NULL, *b = NULL;
    HL_CHECK(hl_relighter_create(ref_ctx, t, &a) == HL_OK, "%s", hl_context_last_error(ref_ctx));
    HL_CHECK(lim && hl_relighter_create(lim, t, &b) == HL_OK, "limited relighter: %s",
             lim ? hl_context_last_error(lim) : "no context");
    if (!a || !b) goto done;
    const uint32_t parts = hl_cl_light_parts(hl_relighter_device(b));
    printf("limited: %u parts, %.2f MiB of device memory in use\n", parts, (double)hl_cl_memory_used(lim) / 1048576.0);
    HL_CHECK(parts >= 4, "a quarter of the column memory must take at least 4 parts, got %u", parts);
    HL_CHECK(hl_cl_memory_used(lim) <= limit, "the limit is kept");
    hl_relighter_memory m;
    HL_CHECK(hl_relighter_memory_use(b, &m) == HL_OK && m.parts == parts && m.device_bytes <= limit &&
                 m.device_bytes < used - cols / 2,
             "limited: %u parts, device %llu bytes of a %llu limit", m.parts, (unsigned long long)m.device_bytes,
             (unsigned long long)limit);
    const uint32_t V = t->info.vertex_count;
    /* a sun bright enough against the sky that truncation drives some sums
       below zero, so the clamp's tallies have something to count */
    hl_env *env = make_env(ref_ctx, 256, 70, 30, 5e6f), *env2 = make_env(lim, 256, 70, 30, 5e6f);
    HL_CHECK(hl_relighter_set_env(a, env) == HL_OK && hl_relighter_set_env(b, env2) == HL_OK, "set env");
    float *ca = malloc((size_t)V * 12), *cb = malloc((size_t)V * 12), *b4 = malloc((size_t)V * 16);
    void *buf = NULL;
    HL_CHECK(hl_cl_buffer(ref_ctx, (size_t)V * 16, &buf) == HL_OK, "colour buffer");
    uint64_t diff = 0, clamped = 0;
    double worst = 0.0;
    hl_relight_stats sa, sb;
    for (int k = 0; k < 4; k++) {
        /* few and all terms: both walks of the kernel */
        hl_relight_desc d = {.terms = k == 3 ? HL_TERMS_ALL : 40u + 90u * (uint32_t)k, .rotate_deg = 17.0f * (float)k};
        HL_CHECK(hl_relighter_run(a, &d, ca, &sa) == HL_OK, "%s", hl_context_last_error(ref_ctx));
        HL_CHECK(hl_relighter_run(b, &d, cb, &sb) == HL_OK, "%s", hl_context_last_error(lim));
        HL_CHECK(sa.terms_kept == sb.terms_kept, "same selection");
        /* the clamp's tally, joined over the parts' ranges */
        HL_CHECK(sa.negative_vertices == sb.negative_vertices && sa.most_negative == sb.most_negative,
                 "clamped: %u vertices, lowest %g of the brightest, in parts %u, %g", sa.negative_vertices,
                 sa.most_negative, sb.negative_vertices, sb.most_negative);
        clamped += sb.negative_vertices;
        for (size_t i = 0; i < (size_t)V * 3; i++) {
            diff += memcmp(&ca[i], &cb[i], 4) != 0;
            worst = fmax(worst, fabs((double)ca[i] - cb[i]));
        }
    }
    /* colours left on the device: a buffer of the limited context */
    void *bufb = NULL;
    hl_relight_desc d = {.terms = 150, .rotate_deg = 5.0f};
    HL_CHECK(hl_relighter_run(a, &d, ca, &sa) == HL_OK, "run");
    HL_CHECK(hl_cl_buffer(lim, (size_t)V * 16, &bufb) == HL_OK, "%s", hl_context_last_error(lim));
    HL_CHECK(bufb && hl_relighter_run_into(b, &d, bufb, 0, &sb) == HL_OK, "%s", hl_context_last_error(lim));
    HL_CHECK(bufb && hl_cl_buffer_read(lim, bufb, (size_t)V * 16, b4) == HL_OK, "read");
    for (size_t v = 0; v < V; v++)
        for (int c = 0; c < 3; c++) {
            diff += memcmp(&b4[4 * v + c], &ca[3 * v + c], 4) != 0;
            worst = fmax(worst, fabs((double)b4[4 * v + c] - ca[3 * v + c]));
        }
    printf("parts: %u vertices x 3 colours x 5 lighting changes, %llu words differ, worst |difference| %g "
           "(tolerance 0: bit-identical); %llu clamped vertices counted alike in parts\n", V,
           (unsigned long long)diff, worst, (unsigned long long)clamped);
    HL_CHECK(diff == 0, "%llu words differ between the relight in parts and the whole one", (unsigned long long)diff);
    HL_CHECK(clamped > 0, "no vertex was clamped: the tallies' check in parts tests nothing");
    if (bufb) hl_cl_buffer_release(lim, bufb);
    hl_cl_buffer_release(ref_ctx, buf);
    free(ca);
    free(cb);
    free(b4);
    hl_env_destroy(env);
    hl_env_destroy(env2);
done:
    hl_relighter_destroy(a);
    hl_relighter_destroy(b);
    hl_transport_destroy(t);
    hl_context_destroy(lim);
    hl_context_destroy(ref_ctx);
}

static void case_refused(void)
{
    const char *path = make_transport("parts_r.hlt", "");
    hl_context *c0 = ctx_of(HL_BACKEND_OPENCL);
    hl_transport *t = NULL;
    HL_CHECK(path && c0 && hl_transport_load(c0, path, &t) == HL_OK, "transport");
    uint64_t used = 0, cols = 0;
    if (!t || !measure(t, &used, &cols)) return;
    /* everything but the columns: nothing left for them */
    hl_context *lim = ctx_limited(used - cols);
    hl_relighter *r = NULL;
    hl_result res = lim ? hl_relighter_create(lim, t, &r) : HL_ERR_OPENCL;
    const char *msg = lim ? hl_context_last_error(lim) : "";
    printf("refused: %s\n", msg);
    HL_CHECK(res == HL_ERR_OUT_OF_MEMORY && !r, "a limit with no room for the columns must be refused (got %d)",
             (int)res);
    HL_CHECK(strstr(msg, "device memory limit") && strstr(msg, "--device-memory") && strstr(msg, "transport columns"),
             "the message names the limit, its option and the columns: %s", msg);
    hl_relighter_destroy(r);
    hl_transport_destroy(t);
    hl_context_destroy(lim);
    hl_context_destroy(c0);
}

/* Colours of relighter r under env at two settings into out (2 V 3 floats). */
static int colours(hl_context *ctx, hl_relighter *r, float *out, uint32_t V)
{
    hl_env *env = make_env(ctx, 256, 40, 20, 5e3f);
    int ok = env && hl_relighter_set_env(r, env) == HL_OK;
    for (int k = 0; ok && k < 2; k++) {
        hl_relight_desc d = {.terms = k ? HL_TERMS_ALL : 120u, .rotate_deg = 29.0f * (float)k};
        ok = hl_relighter_run(r, &d, out + (size_t)k * V * 3, NULL) == HL_OK;
    }
    HL_CHECK(ok, "relight: %s", hl_context_last_error(ctx));
    hl_env_destroy(env);
    return ok;
}

static void put_le32(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; k++) p[k] = (uint8_t)(v >> 8 * k);
}

static void case_from_file(void)
{
    const char *p = make_transport("parts_f.hlt", "");
    char path[1024];
    snprintf(path, sizeof path, "%s", p ? p : "");
    const char *other = make_transport("parts_g.hlt", "--quant linear8");
    hl_context *ctx = ctx_of(HL_BACKEND_OPENCL);
    hl_transport *t = NULL, *t2 = NULL, *t3 = NULL, *t4 = NULL;
    HL_CHECK(p && other && ctx && hl_transport_load(ctx, path, &t) == HL_OK && hl_transport_load(ctx, path, &t2) == HL_OK &&
                 hl_transport_load(ctx, path, &t3) == HL_OK && hl_transport_load(ctx, path, &t4) == HL_OK,
             "transports");
    uint64_t used = 0, cols = 0;
    if (!t || !t2 || !t3 || !t4 || !measure(t, &used, &cols)) return;
    const uint32_t V = t->info.vertex_count;
    float *ca = malloc((size_t)V * 24), *cb = malloc((size_t)V * 24), *cc = malloc((size_t)V * 24);
    hl_context *lim = ctx_limited(used - cols + cols / 4);
    hl_relighter *a = NULL, *b = NULL, *c = NULL, *d = NULL;
    HL_CHECK(hl_relighter_create(ctx, t, &a) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_relighter_create_from_file(ctx, t2, path, &b) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(lim && hl_relighter_create_from_file(lim, t3, path, &c) == HL_OK, "limited: %s",
             lim ? hl_context_last_error(lim) : "no context");
    HL_CHECK(t->entries && !t2->entries && !t3->entries, "only the relighters from the file drop the entries");
    HL_CHECK(!c || hl_cl_light_parts(hl_relighter_device(c)) >= 4, "the limited one runs in parts");
    uint64_t diff = 0;
    if (a && b && c && colours(ctx, a, ca, V) && colours(ctx, b, cb, V) && colours(lim, c, cc, V))
        for (size_t i = 0; i < (size_t)V * 6; i++) diff += (memcmp(&ca[i], &cb[i], 4) != 0) + (memcmp(&ca[i], &cc[i], 4) != 0);
    printf("from the file: %u vertices x 3 colours x 2 settings, whole and in parts: %llu words differ "
           "(tolerance 0: bit-identical)\n", V, (unsigned long long)diff);
    HL_CHECK(diff == 0, "%llu words differ from the relighter that kept its entries", (unsigned long long)diff);
    /* another transport's file: refused before anything is freed */
    hl_result res = hl_relighter_create_from_file(ctx, t4, other, &d);
    const char *msg = hl_context_last_error(ctx);
    printf("other file: %s\n", msg);
    HL_CHECK(res == HL_ERR_FORMAT && !d && strstr(msg, other), "a file other than the transport's is refused, naming it");
    HL_CHECK(t4->entries != NULL, "a refused transport keeps its entries");
    /* the same file with one code changed and its checksums made to
       match: the header still describes t4, the entries' checksum (taken
       on the context's threads) does not */
    char changed[1100];
    snprintf(changed, sizeof changed, "%s.changed.hlt", path);
    size_t n = 0;
    uint8_t *f = hl_test_read_file(path, &n);
    HL_CHECK(f && n > 192, "read %s", path);
    if (f && n > 192) {
        /* host/FORMAT.md: the entries' offset and size at 128 and 136,
           their CRC at 152, the header's (over bytes 0..187) at 188 */
        uint64_t eo = 0, es = 0;
        for (int k = 7; k >= 0; k--) eo = eo << 8 | f[128 + k], es = es << 8 | f[136 + k];
        HL_CHECK(eo + es <= n && es >= 2, "the entries section lies in the file");
        f[eo + 1] ^= 1u; /* the first entry's code */
        put_le32(f + 152, hl_test_crc32(f + eo, (size_t)es));
        put_le32(f + 188, hl_test_crc32(f, 188));
        write_file(changed, f, n);
        res = hl_relighter_create_from_file(ctx, t4, changed, &d);
        msg = hl_context_last_error(ctx);
        printf("changed entries: %s\n", msg);
        HL_CHECK(res == HL_ERR_FORMAT && !d && strstr(msg, "changed since"), "a file whose entries changed is refused");
        HL_CHECK(t4->entries != NULL, "a refused transport keeps its entries");
        remove(changed);
    }
    free(f);
    free(ca);
    free(cb);
    free(cc);
    hl_relighter_destroy(a);
    hl_relighter_destroy(b);
    hl_relighter_destroy(c);
    hl_relighter_destroy(d);
    hl_transport_destroy(t);
    hl_transport_destroy(t2);
    hl_transport_destroy(t3);
    hl_transport_destroy(t4);
    hl_context_destroy(lim);
    hl_context_destroy(ctx);
}

/* Three loads of one transport (a relighter each, the first made whole
 * with hl_relighter_create as the reference), the colours of each. */
typedef struct trio {
    char path[1024];
    hl_context *ctx;
    hl_transport *t[3];
    hl_relighter *r[3];
    hl_context *rctx[3]; /* the context each relighter was made on */
    float *c[3];
    uint32_t V;
    uint64_t used, cols; /* an unlimited relighter's device bytes, columns' */
} trio;

static int trio_open(trio *x, const char *name)
{
    memset(x, 0, sizeof *x);
    const char *p = make_transport(name, "");
    snprintf(x->path, sizeof x->path, "%s", p ? p : "");
    x->ctx = ctx_of(HL_BACKEND_OPENCL);
    int ok = p && x->ctx;
    for (int i = 0; ok && i < 3; i++) ok = hl_transport_load(x->ctx, x->path, &x->t[i]) == HL_OK;
    HL_CHECK(ok, "transports");
    if (!ok || !measure(x->t[0], &x->used, &x->cols)) return 0;
    x->V = x->t[0]->info.vertex_count;
    for (int i = 0; i < 3; i++) x->c[i] = malloc((size_t)x->V * 24);
    x->rctx[0] = x->ctx;
    HL_CHECK(hl_relighter_create(x->ctx, x->t[0], &x->r[0]) == HL_OK, "%s", hl_context_last_error(x->ctx));
    return x->r[0] != NULL;
}

/* Words of relighters 1 and 2's colours that differ from relighter 0's
 * (UINT64_MAX when one is missing or failed). */
static uint64_t trio_diff(trio *x)
{
    uint64_t diff = 0;
    for (int i = 0; i < 3; i++)
        if (!x->r[i] || !x->c[i] || !colours(x->rctx[i], x->r[i], x->c[i], x->V)) return UINT64_MAX;
    for (size_t i = 0; i < (size_t)x->V * 6; i++)
        diff += (memcmp(&x->c[0][i], &x->c[1][i], 4) != 0) + (memcmp(&x->c[0][i], &x->c[2][i], 4) != 0);
    return diff;
}

static void trio_close(trio *x)
{
    for (int i = 0; i < 3; i++) hl_relighter_destroy(x->r[i]);
    for (int i = 0; i < 3; i++) {
        hl_transport_destroy(x->t[i]);
        free(x->c[i]);
    }
    /* each context once: relighters 1 and 2 may share one */
    if (x->rctx[1] && x->rctx[1] != x->ctx) hl_context_destroy(x->rctx[1]);
    if (x->rctx[2] && x->rctx[2] != x->ctx && x->rctx[2] != x->rctx[1]) hl_context_destroy(x->rctx[2]);
    hl_context_destroy(x->ctx);
}

static void case_rows(void)
{
    trio x;
    if (!trio_open(&x, "parts_rows.hlt")) {
        trio_close(&x);
        return;
    }
    const uint64_t entry_bytes = 2 * x.t[0]->info.coefficients_kept;
    x.rctx[1] = x.ctx;
    x.rctx[2] = ctx_limited(x.used - x.cols + x.cols / 4); /* less than the entries take */
    HL_CHECK(hl_relighter_create_once(x.ctx, x.t[1], x.path, &x.r[1]) == HL_OK, "rows: %s", hl_context_last_error(x.ctx));
    HL_CHECK(x.rctx[2] && hl_relighter_create_once(x.rctx[2], x.t[2], x.path, &x.r[2]) == HL_OK, "limited: %s",
             x.rctx[2] ? hl_context_last_error(x.rctx[2]) : "no context");
    hl_relighter_memory mb = {0}, mc = {0};
    HL_CHECK(x.r[1] && hl_relighter_memory_use(x.r[1], &mb) == HL_OK && x.r[2] &&
                 hl_relighter_memory_use(x.r[2], &mc) == HL_OK,
             "memory use");
    printf("rows: device %llu bytes (entries %llu, columns %llu); limited: %u parts, device %llu bytes\n",
           (unsigned long long)mb.device_bytes, (unsigned long long)entry_bytes, (unsigned long long)mb.column_bytes,
           mc.parts, (unsigned long long)mc.device_bytes);
    HL_CHECK(mb.device_bytes >= entry_bytes && mb.column_bytes < x.cols / 4 && x.t[1]->entries,
             "the rows relighter holds the entries, not the columns, and the transport keeps them");
    HL_CHECK(mc.parts >= 4 && !x.t[2]->entries, "under the limit: columns from the file, in parts");
    const uint64_t diff = trio_diff(&x);
    printf("rows and the limited fallback: %u vertices x 3 colours x 2 settings: %llu words differ from the columns "
           "(tolerance 0: bit-identical)\n", x.V, (unsigned long long)diff);
    HL_CHECK(diff == 0, "%llu words differ from the columns", (unsigned long long)diff);
    trio_close(&x);
}

/* Relighters 1 and 2 (from loaded entries, from the file) on one context
 * whose largest allocation is a quarter of the columns, and (memory_too)
 * whose device memory holds only 3/4 of them: resident parts, or parts
 * uploaded in turn; the same colours as one buffer, bit for bit. */
static void capped(const char *name, int memory_too)
{
    trio x;
    if (!trio_open(&x, name)) {
        trio_close(&x);
        return;
    }
    char cap[32];
    snprintf(cap, sizeof cap, "%llu", (unsigned long long)(x.cols / 4));
    setenv("HL_TEST_MAX_ALLOC", cap, 1);
    hl_context *small = memory_too ? ctx_limited(x.used - x.cols + x.cols / 4 * 3) : ctx_of(HL_BACKEND_OPENCL);
    unsetenv("HL_TEST_MAX_ALLOC");
    const char *what = memory_too ? "3/4 of the columns' memory and a largest allocation of" : "a largest allocation of";
    x.rctx[1] = small;
    x.rctx[2] = small;
    HL_CHECK(small && hl_relighter_create(small, x.t[1], &x.r[1]) == HL_OK, "%s %s bytes: %s", what, cap,
             small ? hl_context_last_error(small) : "no context");
    HL_CHECK(small && hl_relighter_create_from_file(small, x.t[2], x.path, &x.r[2]) == HL_OK, "from the file: %s",
             small ? hl_context_last_error(small) : "no context");
    for (int k = 1; k < 3; k++) {
        hl_relighter_memory m;
        HL_CHECK(x.r[k] && hl_relighter_memory_use(x.r[k], &m) == HL_OK, "memory use");
        if (!x.r[k]) continue;
        printf("%s %s bytes (columns %llu): %u parts, resident %u, device %llu bytes (unlimited %llu)\n", what, cap,
               (unsigned long long)x.cols, m.parts, m.resident, (unsigned long long)m.device_bytes,
               (unsigned long long)x.used);
        HL_CHECK(m.parts >= 4 && m.resident == !memory_too, "a quarter of the columns a buffer: at least 4 parts, %s",
                 memory_too ? "uploaded in turn" : "resident");
        HL_CHECK(memory_too || m.device_bytes >= x.cols, "the device holds all the columns");
    }
    const uint64_t diff = trio_diff(&x);
    printf("%s parts: %u vertices x 3 colours x 2 settings, from entries and from the file: %llu words differ "
           "(tolerance 0: bit-identical)\n", memory_too ? "both limits," : "resident", x.V, (unsigned long long)diff);
    HL_CHECK(diff == 0, "%llu words differ from the relighter in one buffer", (unsigned long long)diff);
    trio_close(&x);
}

static void case_resident(void) { capped("parts_res.hlt", 0); }

static void case_both(void) { capped("parts_both.hlt", 1); }

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"quarter", case_quarter},
        {"refused", case_refused},
        {"from_file", case_from_file},
        {"resident", case_resident},
        {"rows", case_rows},
        {"both", case_both},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
