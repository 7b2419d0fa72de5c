/* test_gz.c - gzipped meshes (suite "gz"): hl_mesh_load on NAME.EXT.gz
 * through gz_read.c and assimp's from-memory import.
 *
 * gz.same       teapot_lowres.obj gzipped here with zlib (one member, and
 *               two members as `cat a.gz b.gz` makes) loads into the same
 *               mesh as the plain file, array for array, bit for bit.
 * gz.truncated  the .gz cut short at several places: HL_ERR_FORMAT naming
 *               the file and saying truncated or corrupt.
 * gz.garbage    random bytes, and plain text, named .obj.gz: HL_ERR_FORMAT
 *               naming the file and saying it is not gzip.
 * gz.corrupt    one byte flipped in the compressed body or the trailer's
 *               checksum: HL_ERR_FORMAT naming the file.
 * gz.cap        hl_gz_read_file refuses more than its cap (one byte less
 *               than the data) and reads exactly the cap.
 * gz.names      mesh.gz (no inner extension), an inner extension assimp
 *               does not read, a missing file: refused, naming the file.
 * gz.dragon     the shared dragon_full.obj.gz (skipped without the shared
 *               data) loads: its vertex and triangle counts, and the time.
 *
 * Temporary files are HL_TMP/gz-PID-*, so parallel runs do not collide.
 * Depends on: haarlight_core (hl_mesh_load, gz_read.h), zlib.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "gz_read.h"
#include "hl_test.h"

static const char *tmp_name(const char *what)
{
    static char b[4][1024];
    static int k = 0;
    char *p = b[k++ & 3];
    snprintf(p, 1024, "%s/gz-%d-%s", hl_test_env("HL_TMP", "/tmp"), (int)getpid(), what);
    return p;
}

static const char *teapot_path(void)
{
    static char p[1024];
    snprintf(p, sizeof p, "%s/teapot_lowres.obj", hl_test_env("HL_TEST_FIXTURES", "tests/data"));
    return p;
}

static int write_all(const char *path, const void *data, size_t n, const char *mode)
{
    FILE *f = fopen(path, mode);
    if (!f) return 0;
    int ok = fwrite(data, 1, n, f) == n;
    return fclose(f) == 0 && ok;
}

/* Gzips data[0, n) into path with zlib's gz* writer; mode "wb" or "ab"
 * (appending makes a second member). */
static int gzip_to(const char *path, const uint8_t *data, size_t n, const char *mode)
{
    gzFile g = gzopen(path, mode);
    if (!g) return 0;
    int ok = gzwrite(g, data, (unsigned)n) == (int)n;
    return gzclose(g) == Z_OK && ok;
}

static int same_mesh(const hl_mesh *a, const hl_mesh *b)
{
    if (a->vertex_count != b->vertex_count || a->triangle_count != b->triangle_count ||
        a->object_vertex_count != b->object_vertex_count)
        return 0;
    size_t v3 = 3 * (size_t)a->vertex_count * sizeof(float);
    return !memcmp(a->positions, b->positions, v3) && !memcmp(a->normals, b->normals, v3) &&
           !memcmp(a->albedo, b->albedo, v3) &&
           !memcmp(a->indices, b->indices, 3 * (size_t)a->triangle_count * sizeof(uint32_t));
}

/* Loads path expecting failure code with the message naming path and
 * holding needle. */
static void expect_refused(hl_context *ctx, const char *what, const char *path, hl_result code, const char *needle)
{
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
    const char *msg = hl_context_last_error(ctx);
    printf("%s: result %d: %s\n", what, (int)r, msg);
    HL_CHECK(r == code && m == NULL, "%s: expected result %d, got %d", what, (int)code, (int)r);
    HL_CHECK(strstr(msg, path) != NULL, "%s: the message must name %s", what, path);
    HL_CHECK(strstr(msg, needle) != NULL, "%s: the message must say \"%s\"", what, needle);
    hl_mesh_destroy(m);
}

static void case_same(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    size_t n = 0;
    uint8_t *obj = hl_test_read_file(teapot_path(), &n);
    HL_CHECK(obj != NULL, "cannot read %s", teapot_path());
    const char *one = tmp_name("one.obj.gz"), *two = tmp_name("two.OBJ.GZ");
    HL_CHECK(obj && gzip_to(one, obj, n, "wb"), "cannot write %s", one);
    /* two members, split mid-line */
    HL_CHECK(obj && gzip_to(two, obj, n / 2, "wb") && gzip_to(two, obj + n / 2, n - n / 2, "ab"), "cannot write %s", two);
    hl_mesh *plain = NULL, *a = NULL, *b = NULL;
    hl_mesh_stats sp, sa;
    HL_CHECK(hl_mesh_load(ctx, teapot_path(), NULL, &plain, &sp) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_mesh_load(ctx, one, NULL, &a, &sa) == HL_OK, "%s", hl_context_last_error(ctx));
    HL_CHECK(hl_mesh_load(ctx, two, NULL, &b, NULL) == HL_OK, "%s", hl_context_last_error(ctx));
    if (plain && a && b) {
        printf("plain: %u vertices, %u triangles (%u from the importer); one member: %u, %u; two members: %u, %u\n",
               plain->vertex_count, plain->triangle_count, sp.file_vertices, a->vertex_count, a->triangle_count,
               b->vertex_count, b->triangle_count);
        HL_CHECK(plain->vertex_count > 0 && plain->triangle_count > 0, "the plain teapot is empty");
        HL_CHECK(same_mesh(plain, a), "the gzipped teapot must load bit for bit as the plain one");
        HL_CHECK(same_mesh(plain, b), "the two-member gzip must load bit for bit as the plain one");
        HL_CHECK(sp.file_vertices == sa.file_vertices && sp.merged_vertices == sa.merged_vertices &&
                     sp.had_normals == sa.had_normals,
                 "the load statistics must agree");
    }
    hl_mesh_destroy(plain);
    hl_mesh_destroy(a);
    hl_mesh_destroy(b);
    remove(one);
    remove(two);
    free(obj);
    hl_context_destroy(ctx);
}

static void case_truncated(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    size_t n = 0, gzn = 0;
    uint8_t *obj = hl_test_read_file(teapot_path(), &n);
    const char *full = tmp_name("full.obj.gz"), *cut = tmp_name("cut.obj.gz");
    HL_CHECK(obj && gzip_to(full, obj, n, "wb"), "cannot write %s", full);
    uint8_t *gz = hl_test_read_file(full, &gzn);
    HL_CHECK(gz && gzn > 100, "cannot read back %s", full);
    /* inside the header, inside the body, and without the 8-byte trailer */
    const size_t keep[] = {5, gzn / 2, gzn - 8, gzn - 1};
    for (size_t k = 0; gz && k < sizeof keep / sizeof keep[0]; k++) {
        HL_CHECK(write_all(cut, gz, keep[k], "wb"), "cannot write %s", cut);
        char what[64];
        snprintf(what, sizeof what, "cut to %zu of %zu bytes", keep[k], gzn);
        expect_refused(ctx, what, cut, HL_ERR_FORMAT, "truncated");
    }
    remove(full);
    remove(cut);
    free(obj);
    free(gz);
    hl_context_destroy(ctx);
}

static void case_garbage(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    const char *g = tmp_name("garbage.obj.gz");
    uint8_t junk[4096];
    for (size_t i = 0; i < sizeof junk; i++) junk[i] = (uint8_t)hl_rng_next();
    junk[0] = 0x1f; /* not even the magic: one byte of it */
    HL_CHECK(write_all(g, junk, sizeof junk, "wb"), "cannot write %s", g);
    expect_refused(ctx, "random bytes", g, HL_ERR_FORMAT, "not gzip");
    size_t n = 0;
    uint8_t *obj = hl_test_read_file(teapot_path(), &n);
    HL_CHECK(obj && write_all(g, obj, n, "wb"), "cannot write %s", g);
    expect_refused(ctx, "a plain OBJ named .obj.gz", g, HL_ERR_FORMAT, "not gzip");
    HL_CHECK(write_all(g, "", 0, "wb"), "cannot write %s", g);
    expect_refused(ctx, "an empty file", g, HL_ERR_FORMAT, "empty");
    remove(g);
    free(obj);
    hl_context_destroy(ctx);
}

static void case_corrupt(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    size_t n = 0, gzn = 0;
    uint8_t *obj = hl_test_read_file(teapot_path(), &n);
    const char *full = tmp_name("c.obj.gz"), *bad = tmp_name("bad.obj.gz");
    HL_CHECK(obj && gzip_to(full, obj, n, "wb"), "cannot write %s", full);
    uint8_t *gz = hl_test_read_file(full, &gzn);
    /* the body, and the trailer's CRC-32 */
    const size_t at[] = {gzn / 3, gzn - 6};
    for (size_t k = 0; gz && k < 2; k++) {
        gz[at[k]] ^= 0x5a;
        HL_CHECK(write_all(bad, gz, gzn, "wb"), "cannot write %s", bad);
        gz[at[k]] ^= 0x5a;
        char what[64];
        snprintf(what, sizeof what, "byte %zu of %zu flipped", at[k], gzn);
        expect_refused(ctx, what, bad, HL_ERR_FORMAT, "gzip");
    }
    remove(full);
    remove(bad);
    free(obj);
    free(gz);
    hl_context_destroy(ctx);
}

static void case_cap(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    size_t n = 0;
    uint8_t *obj = hl_test_read_file(teapot_path(), &n);
    const char *p = tmp_name("cap.obj.gz");
    HL_CHECK(obj && gzip_to(p, obj, n, "wb"), "cannot write %s", p);
    uint8_t *data = NULL;
    size_t got = 0;
    hl_result r = hl_gz_read_file(ctx, p, (uint64_t)n - 1, &data, &got);
    printf("cap %zu for %zu bytes: result %d: %s\n", n - 1, n, (int)r, hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_FORMAT && data == NULL && strstr(hl_context_last_error(ctx), p) &&
                 strstr(hl_context_last_error(ctx), "more than"),
             "one byte over the cap must be refused, naming the file");
    r = hl_gz_read_file(ctx, p, (uint64_t)n, &data, &got);
    printf("cap %zu: result %d, %zu bytes\n", n, (int)r, got);
    HL_CHECK(r == HL_OK && got == n && data && !memcmp(data, obj, n) && data[n] == 0,
             "exactly the cap must be read whole, with a terminating 0");
    free(data);
    remove(p);
    free(obj);
    hl_context_destroy(ctx);
}

static void case_names(void)
{
    hl_context *ctx = hl_test_ref_context(1);
    size_t n = 0;
    uint8_t *obj = hl_test_read_file(teapot_path(), &n);
    const char *noext = tmp_name("mesh.gz"), *unknown = tmp_name("mesh.notaformat.gz"), *missing = tmp_name("none.obj.gz");
    HL_CHECK(obj && gzip_to(noext, obj, n, "wb") && gzip_to(unknown, obj, n, "wb"), "cannot write the files");
    remove(missing);
    expect_refused(ctx, "no inner extension", noext, HL_ERR_FORMAT, "extension before .gz");
    expect_refused(ctx, "unknown inner extension", unknown, HL_ERR_FORMAT, ".notaformat");
    expect_refused(ctx, "missing file", missing, HL_ERR_IO, "cannot open");
    HL_CHECK(hl_gz_is_gz_name("a.obj.gz") && hl_gz_is_gz_name("A.PLY.GZ") && !hl_gz_is_gz_name("a.obj") &&
                 !hl_gz_is_gz_name(".gz") && !hl_gz_is_gz_name("a.tgz"),
             "hl_gz_is_gz_name");
    remove(noext);
    remove(unknown);
    free(obj);
    hl_context_destroy(ctx);
}

static void case_dragon(void)
{
    char path[1024];
    const char *data = hl_test_env("HL_TEST_DATA", "../shared/data");
    snprintf(path, sizeof path, "%s/meshes/dragon_full.obj.gz", data);
    if (access(path, R_OK) != 0) {
        hl_test_skip_missing(path);
        return;
    }
    hl_context *ctx = hl_test_ref_context(0);
    hl_mesh *m = NULL;
    hl_mesh_stats st;
    double t0 = hl_now();
    hl_result r = hl_mesh_load(ctx, path, NULL, &m, &st);
    double t = hl_now() - t0;
    HL_CHECK(r == HL_OK, "%s", hl_context_last_error(ctx));
    if (m) {
        printf("%s: %u vertices, %u triangles (importer: %u vertices, %u triangles; %u degenerate dropped) in %.2f s\n",
               path, m->vertex_count, m->triangle_count, st.file_vertices, st.file_triangles, st.degenerate_triangles, t);
        /* the counts this file gave when it was unzipped by hand (scale notes) */
        HL_CHECK(m->vertex_count == 435545, "dragon_full: %u vertices, expected 435545", m->vertex_count);
        HL_CHECK(m->triangle_count > 800000, "dragon_full: only %u triangles", m->triangle_count);
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"same", case_same},       {"truncated", case_truncated}, {"garbage", case_garbage},
        {"corrupt", case_corrupt}, {"cap", case_cap},             {"names", case_names},
        {"dragon", case_dragon},   {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
