/* test_transport_file.c - transport file writer and reader (suite
 * "transport_file").
 *
 * Cases: roundtrip (bit-exact write/load for N = 8 and 64, both quant
 * schemes, several append patterns, query_row against a hand dequant),
 * atomic (no file or temporary after abort or failure, existing files
 * untouched, unwritable paths named), truncated (every prefix refused).
 * Depends on: haarlight_core (reference backend only),
 * tests/common/transport_synth.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#include "hl_test.h"
#include "transport_file.h"
#include "transport_synth.h"

/* ---------------------------------------------------------------- cases */

static void case_roundtrip(void)
{
    hl_context *ctx = make_ctx();
    static const uint32_t Ns[] = {8, 64};
    static const uint32_t quants[] = {HL_QUANT_LINEAR8, HL_QUANT_LOG8, HL_QUANT_SQRT8};
    static const uint32_t pattern_a[] = {1, 0, 3, 7, 2, 16};
    static const uint32_t pattern_b[] = {1000};
    for (int ni = 0; ni < 2; ni++)
        for (int qi = 0; qi < 3; qi++) {
            synth s;
            synth_make(&s, Ns[ni], quants[qi], 37, 50);
            char what[64], pa[512], pb[512];
            snprintf(what, sizeof what, "N=%u quant=%u", Ns[ni], quants[qi]);
            tmp_path(pa, sizeof pa, "file_roundtrip_a.hlt");
            tmp_path(pb, sizeof pb, "file_roundtrip_b.hlt");
            hl_result r = synth_write(ctx, pa, &s, pattern_a, 6);
            HL_CHECK(r == HL_OK, "%s: write: %s", what, hl_context_last_error(ctx));
            r = synth_write(ctx, pb, &s, pattern_b, 1);
            HL_CHECK(r == HL_OK, "%s: write in one append: %s", what, hl_context_last_error(ctx));

            hl_transport *t = NULL;
            r = hl_transport_load(ctx, pa, &t);
            HL_CHECK(r == HL_OK, "%s: load: %s", what, hl_context_last_error(ctx));
            if (t) {
                synth_compare(t, &s, what);
                if (ni == 1 && qi == 0) hl_transport_describe(t, pa, stdout);
            }
            hl_transport_destroy(t);

            /* Append pattern must not change a byte; the header CRC must be
             * the IEEE CRC-32 this test computes bit by bit. */
            uint8_t *fa = NULL, *fb = NULL;
            size_t na = 0, nb = 0;
            HL_CHECK(read_file(pa, &fa, &na) == 0 && read_file(pb, &fb, &nb) == 0, "%s: reread", what);
            HL_CHECK(na == nb && fa && fb && memcmp(fa, fb, na) == 0, "%s: append pattern changed the bytes", what);
            if (fa && na >= F_HEADER_SIZE) {
                HL_CHECK(memcmp(fa, "HLTRANS1", 8) == 0, "%s: magic", what);
                HL_CHECK(rd32(fa + F_HEADER_CRC) == hl_test_crc32(fa, F_HEADER_CRC), "%s: header CRC", what);
                HL_CHECK(rd64(fa + F_FILE_SIZE) == na, "%s: file_size field", what);
                HL_CHECK(rd64(fa + F_ENTRIES_SIZE) == 2 * s.total, "%s: entries_size field", what);
                uint64_t eo = rd64(fa + F_ENTRIES_OFFSET);
                HL_CHECK(rd32(fa + F_ENTRIES_CRC) == hl_test_crc32(fa + eo, (size_t)(2 * s.total)),
                         "%s: entries CRC", what);
            }
            printf("%s: %zu bytes, %llu coefficients\n", what, na, (unsigned long long)s.total);
            free(fa);
            free(fb);
            remove(pa);
            remove(pb);
            synth_free(&s);
        }
    hl_context_destroy(ctx);
}

static void case_atomic(void)
{
    hl_context *ctx = make_ctx();
    char dir[512], path[600], bad[600];
    tmp_path(dir, sizeof dir, "file_atomic");
    mkdir(dir, 0777);
    snprintf(path, sizeof path, "%s/out.hlt", dir);
    remove(path);
    synth s;
    synth_make(&s, 16, HL_QUANT_LINEAR8, 9, 4);
    /* abort with no previous file: nothing at all remains */
    hl_tfile_writer *w = NULL;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &s.info, &s.mesh, &w) == HL_OK, "open: %s", hl_context_last_error(ctx));
    HL_CHECK(hl_tfile_writer_append(w, 4, s.rq, s.counts, s.entries, s.stride, s.nnz) == HL_OK, "append");
    HL_CHECK(count_prefixed(dir, "out.hlt") == 1, "temporary file should exist while writing");
    hl_tfile_writer_abort(w);
    HL_CHECK(!file_exists(path), "aborted write left %s", path);
    HL_CHECK(count_prefixed(dir, "out.hlt") == 0, "aborted write left a temporary file");
    hl_tfile_writer_abort(NULL);

    /* an existing file survives an aborted and a failed rewrite */
    static const uint32_t all[] = {100};
    HL_CHECK(synth_write(ctx, path, &s, all, 1) == HL_OK, "write: %s", hl_context_last_error(ctx));
    uint8_t *before = NULL, *after = NULL;
    size_t nbefore = 0, nafter = 0;
    HL_CHECK(read_file(path, &before, &nbefore) == 0, "read");
    synth s2;
    synth_make(&s2, 16, HL_QUANT_LOG8, 9, 4);
    HL_CHECK(hl_tfile_writer_open(ctx, path, &s2.info, &s2.mesh, &w) == HL_OK, "reopen");
    HL_CHECK(hl_tfile_writer_append(w, 9, s2.rq, s2.counts, s2.entries, s2.stride, s2.nnz) == HL_OK, "append");
    hl_tfile_writer_abort(w);
    HL_CHECK(read_file(path, &after, &nafter) == 0 && nafter == nbefore && memcmp(before, after, nbefore) == 0,
             "aborted write changed the existing file");
    free(after);
    after = NULL;
    HL_CHECK(hl_tfile_writer_open(ctx, path, &s2.info, &s2.mesh, &w) == HL_OK, "reopen");
    HL_CHECK(hl_tfile_writer_append(w, 5, s2.rq, s2.counts, s2.entries, s2.stride, s2.nnz) == HL_OK, "append");
    hl_result r = hl_tfile_writer_finish(w, NULL); /* 4 vertices missing */
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, "early finish gave %d", (int)r);
    printf("early finish: %s\n", hl_context_last_error(ctx));
    HL_CHECK(read_file(path, &after, &nafter) == 0 && nafter == nbefore && memcmp(before, after, nbefore) == 0,
             "failed finish changed the existing file");
    HL_CHECK(count_prefixed(dir, "out.hlt") == 1, "failed finish left a temporary file");
    free(after);
    after = NULL;

    /* a finished rewrite replaces the file */
    HL_CHECK(synth_write(ctx, path, &s2, all, 1) == HL_OK, "rewrite: %s", hl_context_last_error(ctx));
    HL_CHECK(read_file(path, &after, &nafter) == 0 && (nafter != nbefore || memcmp(before, after, nbefore) != 0),
             "finished rewrite did not replace the file");
    HL_CHECK(count_prefixed(dir, "out.hlt") == 1, "finished rewrite left a temporary file");
    free(before);
    free(after);

    /* unwritable destination: a missing directory */
    snprintf(bad, sizeof bad, "%s/no_such_dir/out.hlt", dir);
    w = (hl_tfile_writer *)1;
    r = hl_tfile_writer_open(ctx, bad, &s.info, &s.mesh, &w);
    const char *msg = hl_context_last_error(ctx);
    printf("missing directory: %s\n", msg);
    HL_CHECK(r == HL_ERR_IO, "missing directory gave %d", (int)r);
    HL_CHECK(w == NULL, "failed open must clear *out");
    HL_CHECK(strstr(msg, bad) != NULL, "message should name %s", bad);
    HL_CHECK(strstr(msg, strerror(ENOENT)) != NULL, "message should carry strerror");

    /* loading a missing file is an I/O error naming it */
    hl_transport *t = (hl_transport *)1;
    r = hl_transport_load(ctx, bad, &t);
    HL_CHECK(r == HL_ERR_IO && t == NULL && strstr(hl_context_last_error(ctx), bad), "load of missing file: %d %s",
             (int)r, hl_context_last_error(ctx));
    remove(path);
    rmdir(dir);
    synth_free(&s);
    synth_free(&s2);
    hl_context_destroy(ctx);
}


static void case_truncated(void)
{
    hl_context *ctx = make_ctx();
    char path[512], cut[512];
    tmp_path(path, sizeof path, "file_trunc_src.hlt");
    tmp_path(cut, sizeof cut, "file_trunc.hlt");
    synth s;
    small_file(ctx, path, &s);
    uint8_t *data = NULL;
    size_t size = 0;
    HL_CHECK(read_file(path, &data, &size) == 0, "read");
    int refused = 0, named = 0;
    for (size_t len = 0; len < size; len++) {
        write_file(cut, data, len);
        hl_transport *t = NULL;
        hl_result r = hl_transport_load(ctx, cut, &t);
        if (r == HL_ERR_FORMAT && t == NULL) refused++;
        else HL_CHECK(0, "length %zu of %zu: result %d", len, size, (int)r);
        if (strstr(hl_context_last_error(ctx), "truncated")) named++;
        if (len == 0 || len == 100 || len == size - 1) printf("length %zu: %s\n", len, hl_context_last_error(ctx));
        hl_transport_destroy(t);
    }
    printf("%d of %zu truncations refused, %d say \"truncated\"\n", refused, size, named);
    HL_CHECK((size_t)named == size, "every truncation should be reported as truncated");
    /* trailing bytes are refused too */
    uint8_t *longer = calloc(size + 3, 1);
    memcpy(longer, data, size);
    write_file(cut, longer, size + 3);
    hl_transport *t = NULL;
    HL_CHECK(hl_transport_load(ctx, cut, &t) == HL_ERR_FORMAT, "trailing data accepted");
    hl_transport_destroy(t);
    free(longer);
    free(data);
    remove(cut);
    remove(path);
    synth_free(&s);
    hl_context_destroy(ctx);
}

/* Loads bytes via a file; returns the result and the error message. */
int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"roundtrip", case_roundtrip},
        {"atomic", case_atomic},
        {"truncated", case_truncated},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
