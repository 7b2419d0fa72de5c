/* test_shard.c - a precompute spread over machines (suite "shard"):
 * hl_precompute_shard (precompute --shard I/N) and hl_transport_merge
 * (haarlight merge), on tests/data/teapot_lowres.obj (529 vertices) with
 * N = 16 and small chunks, so each case takes seconds.
 *
 * shard.split     hl_shard_range: contiguous ranges covering [0, V), each
 *                 non-empty, lengths differing by at most one, for many V, N.
 * shard.four      4 shards merged (given out of order) equal one run byte for
 *                 byte; so do
 * shard.three     3 (uneven: 176, 176, 177 vertices) and
 * shard.one       1.
 * shard.refusals  every refusal of merge, each naming the file and leaving
 *                 no output: missing, repeated, other mesh (other counts, and
 *                 one vertex moved), other options (N, eps), other shard count,
 *                 a whole .hlt, a .partial, garbage, truncated, corrupt
 *                 header, rows, entries or mesh, a missing file, the output
 *                 among the shards; the loader refuses a shard; impossible
 *                 shard arguments.
 * shard.resume    a shard interrupted part-way (its context cancelled once
 *                 its checkpoint holds 8 vertices) keeps its .partial; resuming
 *                 it as another shard or as a whole run is refused; resumed
 *                 with other chunks it writes the bytes of an unbroken shard.
 *                 The same for a whole run (resumed as a shard: refused).
 * shard.cli       the real commands: four `haarlight precompute --shard`
 *                 runs (default device) and `haarlight merge` equal one
 *                 `precompute`; exit codes 2 for usage errors, 1 for refusals.
 *
 * Temporary files are HL_TMP/shard-PID-*, removed at the end of each case.
 * Depends on: haarlight_core (haarlight_tools.h, transport_layout.h for the
 * header offsets), tests/data, HL_BIN (the command), pthreads.
 */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "haarlight_tools.h"
#include "hl_test.h"
#include "transport_layout.h"

#define MAX_SHARDS 8

static const char *tmp_name(const char *fmt, ...)
{
    static char b[32][1024];
    static int k = 0;
    char name[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(name, sizeof name, fmt, ap);
    va_end(ap);
    char *p = b[k++ & 31];
    snprintf(p, 1024, "%s/shard-%d-%s", hl_test_env("HL_TMP", "/tmp"), (int)getpid(), name);
    return p;
}

static const char *fixture(const char *name)
{
    static char p[2][1024];
    static int k = 0;
    char *b = p[k++ & 1];
    snprintf(b, 1024, "%s/%s", hl_test_env("HL_TEST_FIXTURES", "tests/data"), name);
    return b;
}

static int write_all(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    int ok = fwrite(data, 1, n, f) == n;
    return fclose(f) == 0 && ok;
}

/* Byte-compares two files, printing their sizes and the first difference. */
static int same_bytes(const char *a, const char *b)
{
    size_t na, nb;
    uint8_t *x = hl_test_read_file(a, &na), *y = hl_test_read_file(b, &nb);
    size_t diff = 0, first = (size_t)-1;
    for (size_t i = 0; x && y && i < na && i < nb; i++)
        if (x[i] != y[i]) {
            if (!diff) first = i;
            diff++;
        }
    printf("%s (%zu bytes) against %s (%zu bytes): %zu bytes differ", a, na, b, nb, diff);
    if (diff) printf(", the first at %zu", first);
    printf("\n");
    int same = x && y && na == nb && diff == 0;
    free(x);
    free(y);
    return same;
}

static int exists(const char *path) { return access(path, F_OK) == 0; }

static hl_mesh *load(hl_context *ctx, const char *name)
{
    hl_mesh *m = NULL;
    if (hl_mesh_load(ctx, fixture(name), NULL, &m, NULL) != HL_OK)
        fprintf(stderr, "cannot load %s: %s\n", name, hl_context_last_error(ctx));
    return m;
}

static hl_precompute_desc small_desc(void)
{
    hl_precompute_desc d = {.N = 16, .C = 16, .chunk = 64};
    return d;
}

/* Shard i of n of mesh into path. */
static int shard(hl_context *ctx, const hl_mesh *m, hl_precompute_desc d, uint32_t i, uint32_t n, const char *path)
{
    hl_result r = hl_precompute_shard(ctx, m, &d, i, n, path, NULL);
    if (r != HL_OK) fprintf(stderr, "shard %u/%u: %s\n", i, n, hl_context_last_error(ctx));
    return r == HL_OK;
}

/* ---------------------------------------------------------------- cases */

static void case_split(void)
{
    const uint32_t Vs[] = {1, 2, 3, 7, 529, 1000003, UINT32_MAX};
    uint64_t checked = 0, bad = 0;
    for (size_t k = 0; k < sizeof Vs / sizeof Vs[0]; k++) {
        uint32_t V = Vs[k], top = V < 200 ? V : 200;
        for (uint32_t n = 1; n <= top; n++) {
            uint32_t prev_end = 0, lo = UINT32_MAX, hi = 0;
            for (uint32_t i = 0; i < n; i++) {
                uint32_t f, e;
                hl_shard_range(V, i, n, &f, &e);
                bad += f != prev_end || e <= f;
                if (e - f < lo) lo = e - f;
                if (e - f > hi) hi = e - f;
                prev_end = e;
            }
            bad += prev_end != V || hi - lo > 1;
            checked++;
        }
    }
    uint32_t f, e;
    hl_shard_range(10, 3, 3, &f, &e);
    bad += f != 0 || e != 0; /* an impossible shard is empty */
    printf("%llu splits checked, %llu faults\n", (unsigned long long)checked, (unsigned long long)bad);
    HL_CHECK(bad == 0, "every split must be contiguous, cover [0, V), be non-empty and even to one vertex");
}

/* One run, then n shards written in reverse order and merged in a
 * rotated order: the same bytes. */
static void compare_sharded(uint32_t n)
{
    hl_context *ctx = hl_test_ref_context(0);
    hl_mesh *m = load(ctx, "teapot_lowres.obj");
    HL_CHECK(m != NULL, "teapot");
    if (!m) return;
    const char *whole = tmp_name("whole.hlt"), *merged = tmp_name("merged.hlt"), *paths[MAX_SHARDS], *order[MAX_SHARDS];
    hl_precompute_desc d = small_desc();
    HL_CHECK(hl_precompute(ctx, m, &d, whole, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    int ok = 1;
    for (uint32_t i = n; i-- > 0;) {
        paths[i] = tmp_name("s%u.shard", i);
        hl_precompute_desc ds = d;
        ds.chunk = 50 + 7 * i; /* chunks never line up with the shards' edges */
        ok &= shard(ctx, m, ds, i, n, paths[i]);
        uint32_t f, e;
        hl_shard_range(m->vertex_count, i, n, &f, &e);
        printf("shard %u of %u: vertices [%u, %u)\n", i, n, f, e);
    }
    for (uint32_t i = 0; i < n; i++) order[i] = paths[(i + 1) % n];
    hl_merge_stats st;
    HL_CHECK(ok, "the shards must be written");
    hl_result r = ok ? hl_transport_merge(ctx, merged, order, n, &st) : HL_ERR_INVALID_ARGUMENT;
    HL_CHECK(r == HL_OK, "merge: %s", hl_context_last_error(ctx));
    if (r == HL_OK) {
        printf("merged %u shards: %u vertices, %llu coefficients, %llu bytes read, %llu written\n", st.shards,
               st.vertices, (unsigned long long)st.coefficients_kept, (unsigned long long)st.bytes_read,
               (unsigned long long)st.bytes_written);
        HL_CHECK(same_bytes(whole, merged), "%u shards merged must equal one run byte for byte", n);
        hl_transport *t = NULL;
        HL_CHECK(hl_transport_load(ctx, merged, &t) == HL_OK, "the merged file must load: %s", hl_context_last_error(ctx));
        hl_transport_destroy(t);
    }
    char partial[1100];
    snprintf(partial, sizeof partial, "%s.partial", merged);
    HL_CHECK(!exists(partial), "merge left %s", partial);
    for (uint32_t i = 0; i < n; i++) remove(paths[i]);
    remove(whole);
    remove(merged);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static void case_four(void) { compare_sharded(4); }
static void case_three(void) { compare_sharded(3); }
static void case_one(void) { compare_sharded(1); }

/* Merges list (count files) into out expecting failure code, a message
 * naming name and holding needle, and no output left. */
static void refused(hl_context *ctx, const char *what, const char *out, const char **list, uint32_t count,
                    hl_result code, const char *name, const char *needle)
{
    hl_result r = hl_transport_merge(ctx, out, list, count, NULL);
    const char *msg = hl_context_last_error(ctx);
    printf("%s: result %d: %s\n", what, (int)r, msg);
    HL_CHECK(r == code, "%s: expected result %d, got %d", what, (int)code, (int)r);
    HL_CHECK(strstr(msg, name) != NULL, "%s: the message must name %s", what, name);
    HL_CHECK(strstr(msg, needle) != NULL, "%s: the message must say \"%s\"", what, needle);
    char partial[1100];
    snprintf(partial, sizeof partial, "%s.partial", out);
    HL_CHECK(!exists(out) && !exists(partial), "%s: output or partial file left", what);
}

/* A copy of shard src at dst with byte `at` xor-ed by x (or cut to `cut`
 * bytes when cut > 0). */
static void damaged_copy(const char *src, const char *dst, size_t at, uint8_t x, size_t cut)
{
    size_t n;
    uint8_t *p = hl_test_read_file(src, &n);
    if (p && at < n) p[at] ^= x;
    HL_CHECK(p && write_all(dst, p, cut ? cut : n), "cannot write %s", dst);
    free(p);
}

static void refusals_damaged(hl_context *ctx, const char *out, const char **s, const char *whole)
{
    const char *bad = tmp_name("bad.shard"), *list[4] = {s[0], s[1], bad, s[3]};
    size_t n;
    uint8_t *p = hl_test_read_file(s[2], &n);
    tf_header h;
    if (p) hl_tf_header_decode(p, &h);
    free(p);
    HL_CHECK(p != NULL, "read %s", s[2]);
    if (!p) return;
    damaged_copy(s[2], bad, 0, 0, n / 2);
    refused(ctx, "truncated to half", out, list, 4, HL_ERR_FORMAT, bad, "truncated");
    damaged_copy(s[2], bad, 0, 0, 100);
    refused(ctx, "truncated inside the header", out, list, 4, HL_ERR_FORMAT, bad, "truncated");
    damaged_copy(s[2], bad, H_RAYS_CAST, 1, 0);
    refused(ctx, "header byte flipped", out, list, 4, HL_ERR_FORMAT, bad, "header");
    damaged_copy(s[2], bad, h.sec[SEC_ROWS].offset + 1, 0x10, 0); /* a row's parameter a */
    refused(ctx, "row table byte flipped", out, list, 4, HL_ERR_FORMAT, bad, "row table");
    damaged_copy(s[2], bad, n - 1, 0x01, 0); /* the last entry's value */
    refused(ctx, "entries byte flipped", out, list, 4, HL_ERR_FORMAT, bad, "entries");
    const char *bad0 = tmp_name("bad0.shard"), *list0[4] = {bad0, s[1], s[2], s[3]};
    damaged_copy(s[0], bad0, TF_HEADER_SIZE + 5, 0x01, 0); /* the first shard's mesh, which merge copies */
    refused(ctx, "mesh byte flipped", out, list0, 4, HL_ERR_FORMAT, bad0, "mesh section");
    size_t k;
    uint8_t *q = hl_test_read_file(s[0], &k); /* a shard's bytes under the magic of an unfinished file */
    if (q) memcpy(q, TF_PARTIAL_MAGIC, 8);
    HL_CHECK(q && write_all(bad0, q, k), "write %s", bad0);
    free(q);
    refused(ctx, "a .partial", out, list0, 4, HL_ERR_INVALID_ARGUMENT, bad0, "unfinished");
    uint8_t junk[1000];
    for (size_t i = 0; i < sizeof junk; i++) junk[i] = (uint8_t)hl_rng_next();
    HL_CHECK(write_all(bad0, junk, sizeof junk), "write %s", bad0);
    refused(ctx, "garbage", out, list0, 4, HL_ERR_FORMAT, bad0, "not a shard");
    const char *wl[5] = {s[0], s[1], s[2], s[3], whole};
    refused(ctx, "a whole .hlt", out, wl, 5, HL_ERR_INVALID_ARGUMENT, whole, "whole transport file");
    remove(bad);
    remove(bad0);
}

/* Shards of other meshes and options, each as shard 1 of 4 with the others. */
static void refusals_other(hl_context *ctx, const char *out, const char **s, hl_mesh *m)
{
    const char *o = tmp_name("other.shard"), *list[4] = {s[0], o, s[2], s[3]};
    hl_precompute_desc d = small_desc();
    d.N = 8;
    if (shard(ctx, m, d, 1, 4, o)) refused(ctx, "other N", out, list, 4, HL_ERR_INVALID_ARGUMENT, o, "N (-N) differs");
    d = small_desc();
    d.eps = 1e-3f;
    if (shard(ctx, m, d, 1, 4, o)) refused(ctx, "other eps", out, list, 4, HL_ERR_INVALID_ARGUMENT, o, "eps");
    d = small_desc();
    if (shard(ctx, m, d, 1, 3, o)) refused(ctx, "other shard count", out, list, 4, HL_ERR_INVALID_ARGUMENT, o, "shard count");
    m->positions[3 * 100 + 1] += 1e-3f; /* the same counts, another mesh */
    if (shard(ctx, m, d, 1, 4, o)) refused(ctx, "one vertex moved", out, list, 4, HL_ERR_INVALID_ARGUMENT, o, "the mesh");
    m->positions[3 * 100 + 1] -= 1e-3f;
    hl_mesh *bunny = NULL;
    char bp[1024];
    snprintf(bp, sizeof bp, "%s/bunny_lowres.obj", hl_test_env("HL_REPO_DATA", "data"));
    HL_CHECK(hl_mesh_load(ctx, bp, NULL, &bunny, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    if (bunny && shard(ctx, bunny, d, 1, 4, o))
        refused(ctx, "another mesh", out, list, 4, HL_ERR_INVALID_ARGUMENT, o, "vertex count differs");
    hl_mesh_destroy(bunny);
    remove(o);
}

static void case_refusals(void)
{
    hl_context *ctx = hl_test_ref_context(0);
    hl_mesh *m = load(ctx, "teapot_lowres.obj");
    HL_CHECK(m != NULL, "teapot");
    if (!m) return;
    const char *s[4], *whole = tmp_name("whole.hlt"), *out = tmp_name("out.hlt");
    hl_precompute_desc d = small_desc();
    int ok = hl_precompute(ctx, m, &d, whole, NULL) == HL_OK;
    for (uint32_t i = 0; i < 4; i++) ok &= shard(ctx, m, d, i, 4, s[i] = tmp_name("s%u.shard", i));
    HL_CHECK(ok, "setup: %s", hl_context_last_error(ctx));
    remove(out);
    const char *missing[3] = {s[0], s[1], s[3]}, *only[1] = {s[2]}, *dup[5] = {s[0], s[1], s[1], s[2], s[3]};
    refused(ctx, "one missing", out, missing, 3, HL_ERR_INVALID_ARGUMENT, s[0], "shard 2 missing");
    refused(ctx, "three missing", out, only, 1, HL_ERR_INVALID_ARGUMENT, s[2], "shards 0, 1, 3 missing");
    refused(ctx, "repeated", out, dup, 5, HL_ERR_INVALID_ARGUMENT, s[1], "both shard 1 of 4");
    const char *nofile = tmp_name("none.shard"), *nf[4] = {s[0], s[1], nofile, s[3]};
    refused(ctx, "a missing file", out, nf, 4, HL_ERR_IO, nofile, "cannot open");
    refusals_damaged(ctx, out, s, whole);
    refusals_other(ctx, out, s, m);
    /* the output among the shards: refused, and the shard left as it was */
    size_t before, after;
    uint8_t *a = hl_test_read_file(s[1], &before);
    hl_result r = hl_transport_merge(ctx, s[1], s, 4, NULL);
    uint8_t *b = hl_test_read_file(s[1], &after);
    printf("output is a shard: result %d: %s\n", (int)r, hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && strstr(hl_context_last_error(ctx), "one of the shards"),
             "the output among the shards must be refused");
    HL_CHECK(a && b && before == after && !memcmp(a, b, before), "a refused merge changed a shard");
    free(a);
    free(b);
    /* the loader and the precompute */
    hl_transport *t = NULL;
    r = hl_transport_load(ctx, s[1], &t);
    printf("load of a shard: result %d: %s\n", (int)r, hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_FORMAT && t == NULL && strstr(hl_context_last_error(ctx), "haarlight merge"),
             "hl_transport_load must refuse a shard and say to merge");
    hl_transport_destroy(t);
    HL_CHECK(hl_precompute_shard(ctx, m, &d, 4, 4, out, NULL) == HL_ERR_INVALID_ARGUMENT, "shard 4 of 4 accepted");
    HL_CHECK(hl_precompute_shard(ctx, m, &d, 0, m->vertex_count + 1, out, NULL) == HL_ERR_INVALID_ARGUMENT,
             "more shards than vertices accepted");
    printf("impossible shard: %s\n", hl_context_last_error(ctx));
    HL_CHECK(!exists(out), "an impossible shard wrote %s", out);
    for (int i = 0; i < 4; i++) remove(s[i]);
    remove(whole);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- resume */

typedef struct watch {
    const char *partial;
    hl_context *ctx;
    uint32_t at; /* cancel once the checkpoint holds this many vertices */
    atomic_int stop;
    uint32_t seen;
} watch;

/* Polls the partial file's checkpoint (H_APPENDED) and cancels the run
 * once it has reached w->at vertices. */
static void *watcher(void *arg)
{
    watch *w = arg;
    const struct timespec nap = {0, 200000};
    while (!atomic_load(&w->stop)) {
        FILE *f = fopen(w->partial, "rb");
        uint8_t h[TF_HEADER_SIZE];
        if (f) {
            if (fread(h, 1, sizeof h, f) == sizeof h && !memcmp(h, TF_PARTIAL_MAGIC, 8) &&
                get_u32(h + H_HEADER_CRC) == crc_update(0, h, H_HEADER_CRC) && get_u32(h + H_APPENDED) >= w->at) {
                w->seen = get_u32(h + H_APPENDED);
                hl_context_cancel(w->ctx);
                fclose(f);
                return NULL;
            }
            fclose(f);
        }
        nanosleep(&nap, NULL);
    }
    return NULL;
}

/* Shard index of count (count 0: a whole run) cancelled once its
 * checkpoint holds 8 vertices, refused as the other kind of run, then
 * resumed with other chunks: the bytes of an unbroken run (with floats:
 * its values file's too). */
static void interrupt_and_resume(hl_context *ctx, const hl_mesh *m, uint32_t index, uint32_t count, int floats)
{
    /* C = 64 and one thread: about 20 ms a chunk of 8, so the watcher,
       polling every 0.2 ms, stops the run long before its last chunk */
    hl_precompute_desc d = {.N = 16, .C = 64, .chunk = 8, .keep_floats = floats};
    const char *ref = tmp_name("ref.%u", count), *res = tmp_name("res.%u", count);
    char partial[1100];
    snprintf(partial, sizeof partial, "%s.partial", res);
    remove(partial);
    HL_CHECK(shard(ctx, m, d, index, count, ref), "unbroken run");
    hl_context *c1 = hl_test_ref_context(1);
    watch w = {.partial = partial, .ctx = c1, .at = 8};
    atomic_init(&w.stop, 0);
    pthread_t th;
    pthread_create(&th, NULL, watcher, &w);
    hl_result r = hl_precompute_shard(c1, m, &d, index, count, res, NULL);
    atomic_store(&w.stop, 1);
    pthread_join(th, NULL);
    printf("shard %u/%u interrupted at a checkpoint of %u vertices: result %d: %s\n", index, count, w.seen, (int)r,
           hl_context_last_error(c1));
    hl_context_destroy(c1);
    HL_CHECK(r == HL_ERR_INTERRUPTED, "the cancelled run must stop with HL_ERR_INTERRUPTED (got %d)", (int)r);
    HL_CHECK(!exists(res) && exists(partial), "an interrupted run must leave only its .partial");
    size_t n;
    uint8_t *p = hl_test_read_file(partial, &n);
    uint32_t kept = p && n >= TF_HEADER_SIZE ? get_u32(p + H_APPENDED) : 0;
    free(p);
    uint32_t f = 0, e = m->vertex_count;
    if (count) hl_shard_range(m->vertex_count, index, count, &f, &e);
    printf("the .partial holds %u of the run's %u vertices\n", kept, e - f);
    HL_CHECK(kept >= 8 && kept < e - f, "the interruption must fall inside the run");
    /* another shard, or a whole run for a shard's and the other way
       round, must not take this partial file */
    hl_precompute_desc dr = d;
    dr.resume = 1;
    uint32_t oi = count ? (index + 1) % count : 0, oc = count ? count : 2;
    r = hl_precompute_shard(ctx, m, &dr, oi, oc, res, NULL);
    printf("resume as shard %u/%u: result %d: %s\n", oi, oc, (int)r, hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_FORMAT && strstr(hl_context_last_error(ctx), count ? "another shard" : "whole run"),
             "resume as another shard");
    if (count) {
        r = hl_precompute(ctx, m, &dr, res, NULL);
        printf("resume as a whole run: result %d: %s\n", (int)r, hl_context_last_error(ctx));
        HL_CHECK(r == HL_ERR_FORMAT && strstr(hl_context_last_error(ctx), "made for a shard"), "resume as a whole run");
    }
    HL_CHECK(exists(partial), "a refused resume removed the partial file");
    dr.chunk = 50;
    r = hl_precompute_shard(ctx, m, &dr, index, count, res, NULL);
    HL_CHECK(r == HL_OK, "resume: %s", hl_context_last_error(ctx));
    HL_CHECK(same_bytes(ref, res), "a resumed run must equal an unbroken one byte for byte");
    HL_CHECK(!exists(partial), "the partial file must be gone after the resumed run finished");
    if (floats) {
        char vref[1100], vres[1100], vpart[1200];
        snprintf(vref, sizeof vref, "%s.values", ref);
        snprintf(vres, sizeof vres, "%s.values", res);
        snprintf(vpart, sizeof vpart, "%s.partial", vres);
        printf("with --keep-floats: the resumed values file %s the unbroken run's\n",
               same_bytes(vref, vres) ? "equals" : "differs from");
        HL_CHECK(same_bytes(vref, vres), "a resumed run's floats must equal an unbroken one's byte for byte");
        HL_CHECK(!exists(vpart), "the values' partial file must be gone after the resumed run finished");
        remove(vref);
        remove(vres);
    }
    remove(ref);
    remove(res);
}

static void case_resume(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    hl_mesh *m = load(ctx, "teapot_lowres.obj");
    HL_CHECK(m != NULL, "teapot");
    if (!m) return;
    interrupt_and_resume(ctx, m, 1, 3, 0);
    interrupt_and_resume(ctx, m, 0, 0, 0);
    interrupt_and_resume(ctx, m, 1, 3, 1);
    interrupt_and_resume(ctx, m, 0, 0, 1);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- cli */

/* Runs the command line (fmt) with stderr into err; its exit status. */
static int run(const char *err, const char *fmt, ...)
{
    char cmd[8192];
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    snprintf(cmd + k, sizeof cmd - (size_t)k, " 2>'%s' >/dev/null", err);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static int file_has(const char *path, const char *needle)
{
    size_t n;
    uint8_t *p = hl_test_read_file(path, &n);
    int has = p && (p[n] = 0, strstr((const char *)p, needle) != NULL);
    free(p);
    return has;
}

static void expect_rc(const char *what, int rc, int want, const char *err, const char *needle)
{
    printf("%s: exit %d\n", what, rc);
    HL_CHECK(rc == want, "%s: exit %d, expected %d", what, rc, want);
    HL_CHECK(!needle || file_has(err, needle), "%s: stderr must say \"%s\"", what, needle);
}

static void case_cli(void)
{
    const char *bin = hl_test_env("HL_BIN", "haarlight"), *mesh = fixture("teapot_lowres.obj");
    const char *err = tmp_name("err.txt"), *whole = tmp_name("whole.hlt"), *merged = tmp_name("merged.hlt");
    const char *s[4], *x = tmp_name("x.hlt");
    expect_rc("precompute", run(err, "'%s' precompute '%s' -o '%s' -N 16 -C 16 -q", bin, mesh, whole), 0, err, NULL);
    for (int i = 0; i < 4; i++) {
        s[i] = tmp_name("cli%d.shard", i);
        expect_rc("precompute --shard",
                  run(err, "'%s' precompute '%s' --shard %d/4 -o '%s' -N 16 -C 16 --chunk 50 -q", bin, mesh, i, s[i]), 0,
                  err, NULL);
    }
    expect_rc("merge", run(err, "'%s' merge -o '%s' '%s' '%s' '%s' '%s'", bin, merged, s[3], s[1], s[0], s[2]), 0, err,
              NULL);
    HL_CHECK(same_bytes(whole, merged), "merge of the four --shard runs must equal one precompute");
    expect_rc("merge, a shard missing", run(err, "'%s' merge -o '%s' '%s' '%s' '%s'", bin, x, s[0], s[1], s[3]), 1, err,
              "shard 2 missing");
    expect_rc("merge, no -o", run(err, "'%s' merge '%s'", bin, s[0]), 2, err, "no output");
    expect_rc("merge, no shards", run(err, "'%s' merge -o '%s'", bin, x), 2, err, "no SHARD");
    expect_rc("merge --help", run(err, "'%s' merge --help | grep -q 'usage: haarlight merge'", bin), 0, err, NULL);
    expect_rc("--help lists merge", run(err, "'%s' --help | grep -q '  merge -o'", bin), 0, err, NULL);
    const char *bad[] = {"4/4", "1", "a/2", "0/0", "-1/2", "1/2/3"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        expect_rc(bad[i], run(err, "'%s' precompute '%s' --shard '%s' -o '%s' -q", bin, mesh, bad[i], x), 2, err, "--shard");
    expect_rc("more shards than vertices", run(err, "'%s' precompute '%s' --shard 0/600 -o '%s' -q -N 16 -C 16", bin, mesh, x),
              1, err, "529 vertices");
    expect_rc("info on a shard", run(err, "'%s' info '%s'", bin, s[0]), 1, err, "haarlight merge");
    expect_rc("bench-precompute --shard", run(err, "'%s' bench-precompute '%s' --shard 0/2", bin, mesh), 2, err, "--shard");
    HL_CHECK(!exists(x), "a refused command wrote %s", x);
    for (int i = 0; i < 4; i++) remove(s[i]);
    remove(whole);
    remove(merged);
    remove(err);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"split", case_split},       {"four", case_four},     {"three", case_three}, {"one", case_one},
        {"refusals", case_refusals}, {"resume", case_resume}, {"cli", case_cli},     {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
