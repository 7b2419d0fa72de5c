/* test_ply_out.c - hl_mesh_save_ply: binary PLY with colours, read back
 * here, and the atomic write (suite "ply_out").
 *
 * ply_out.roundtrip  positions, colours and faces read back as written.
 * ply_out.atomic     no file or temporary left after a failure, an
 *                    existing file untouched.
 * Depends on: haarlight_core (reference backend), tests/common/render_util.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_test.h"
#include "render_util.h"

/* ---------------------------------------------------------------- PLY */

typedef struct ply_data {
    uint32_t nv, nf;
    int uchar_colour;
    float *vf;        /* nv x 9: x y z nx ny nz r g b (float colours) */
    unsigned char *vc;/* nv x 3 (uchar colours) */
    uint32_t *idx;    /* nf x 3 */
} ply_data;

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static float lef(const unsigned char *p)
{
    uint32_t x = le32(p);
    float f;
    memcpy(&f, &x, 4);
    return f;
}

/* Reads our PLY back, checking the header line by line. 0 on failure. */
static int read_ply(const char *path, ply_data *out)
{
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s: %s\n", path, strerror(errno));
        return 0;
    }
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc((size_t)size + 1);
    size_t got = fread(buf, 1, (size_t)size, f);
    fclose(f);
    buf[got] = 0;
    const char *end = strstr((const char *)buf, "end_header\n");
    if (!end) {
        fprintf(stderr, "%s: no end_header\n", path);
        free(buf);
        return 0;
    }
    size_t hlen = (size_t)(end - (const char *)buf) + strlen("end_header\n");
    char *hdr = malloc(hlen + 1);
    memcpy(hdr, buf, hlen);
    hdr[hlen] = 0;
    /* Expected lines, comments skipped; %s is the colour type. */
    const char *want[] = {"ply", "format binary_little_endian 1.0", "element vertex %u", "property float x",
                          "property float y", "property float z", "property float nx", "property float ny",
                          "property float nz", "property %s red", "property %s green", "property %s blue",
                          "element face %u", "property list uchar int vertex_indices", "end_header"};
    int ok = 1, li = 0;
    char ctype[3][16] = {"", "", ""};
    for (char *line = strtok(hdr, "\n"); line && ok; line = strtok(NULL, "\n")) {
        if (strncmp(line, "comment", 7) == 0) continue;
        if (li >= (int)(sizeof want / sizeof want[0])) {
            ok = 0;
            break;
        }
        const char *w = want[li];
        if (strcmp(w, "element vertex %u") == 0) ok = sscanf(line, "element vertex %u", &out->nv) == 1;
        else if (strcmp(w, "element face %u") == 0) ok = sscanf(line, "element face %u", &out->nf) == 1;
        else if (strstr(w, "%s")) {
            char nm[16];
            ok = sscanf(line, "property %15s %15s", ctype[li - 9], nm) == 2;
            const char *names[3] = {"red", "green", "blue"};
            ok = ok && strcmp(nm, names[li - 9]) == 0;
        } else
            ok = strcmp(line, w) == 0;
        if (!ok) fprintf(stderr, "%s: header line \"%s\" is not \"%s\"\n", path, line, w);
        li++;
    }
    free(hdr);
    if (ok && li != (int)(sizeof want / sizeof want[0])) ok = 0;
    if (ok && !(strcmp(ctype[0], ctype[1]) == 0 && strcmp(ctype[1], ctype[2]) == 0 &&
                (strcmp(ctype[0], "float") == 0 || strcmp(ctype[0], "uchar") == 0))) {
        fprintf(stderr, "%s: colour types %s %s %s\n", path, ctype[0], ctype[1], ctype[2]);
        ok = 0;
    }
    if (!ok) {
        free(buf);
        return 0;
    }
    out->uchar_colour = strcmp(ctype[0], "uchar") == 0;
    size_t vsize = out->uchar_colour ? 27 : 36;
    size_t body = (size_t)out->nv * vsize + (size_t)out->nf * 13;
    if (got - hlen != body) {
        fprintf(stderr, "%s: body is %zu bytes, want %zu\n", path, got - hlen, body);
        free(buf);
        return 0;
    }
    const unsigned char *p = buf + hlen;
    out->vf = malloc((size_t)out->nv * 9 * sizeof(float));
    out->vc = malloc((size_t)out->nv * 3 + 1);
    out->idx = malloc((size_t)out->nf * 3 * sizeof(uint32_t) + 1);
    for (uint32_t v = 0; v < out->nv; v++) {
        for (int k = 0; k < 6; k++, p += 4) out->vf[9 * (size_t)v + k] = lef(p);
        if (out->uchar_colour)
            for (int k = 0; k < 3; k++) out->vc[3 * (size_t)v + k] = *p++;
        else
            for (int k = 0; k < 3; k++, p += 4) out->vf[9 * (size_t)v + 6 + k] = lef(p);
    }
    for (uint32_t t = 0; t < out->nf && ok; t++) {
        if (*p++ != 3) {
            fprintf(stderr, "%s: face %u has %u corners\n", path, t, (unsigned)p[-1]);
            ok = 0;
        }
        for (int k = 0; k < 3; k++, p += 4) out->idx[3 * (size_t)t + k] = le32(p);
    }
    free(buf);
    return ok;
}

static void free_ply(ply_data *d)
{
    free(d->vf);
    free(d->vc);
    free(d->idx);
}

static float *random_colours(uint32_t n)
{
    float *c = malloc(3 * (size_t)n * sizeof(float));
    for (size_t i = 0; i < 3 * (size_t)n; i++)
        c[i] = (float)((double)(hl_rng_next() >> 11) / 9007199254740992.0 * 4.0); /* [0, 4) */
    c[0] = 0.0f;
    c[1] = 1.0f;
    return c;
}

static void ply_roundtrip(void)
{
    hl_context *ctx = make_ctx();
    hl_mesh *m = load_bunny(ctx);
    float *c = random_colours(m->vertex_count);
    const char *pf = tmp_path("render_bunny_float.ply");
    const char *pu = tmp_path("render_bunny_u8.ply");
    remove(pf);
    remove(pu);
    const float ev = -1.5f;
    hl_result r = hl_mesh_save_ply(ctx, m, c, pf, 0, 0.0f);
    HL_CHECK(r == HL_OK, "float PLY: %s", hl_context_last_error(ctx));
    r = hl_mesh_save_ply(ctx, m, c, pu, 1, ev);
    HL_CHECK(r == HL_OK, "uchar PLY: %s", hl_context_last_error(ctx));

    for (int variant = 0; variant < 2; variant++) {
        ply_data d;
        int ok = read_ply(variant ? pu : pf, &d);
        HL_CHECK(ok, "cannot read back %s", variant ? pu : pf);
        if (!ok) continue;
        HL_CHECK(d.uchar_colour == variant, "colour type wrong");
        HL_CHECK(d.nv == m->vertex_count && d.nf == m->triangle_count, "counts %u/%u, want %u/%u", d.nv, d.nf,
                 m->vertex_count, m->triangle_count);
        if (d.nv != m->vertex_count || d.nf != m->triangle_count) {
            free_ply(&d);
            continue;
        }
        size_t bad_pos = 0, bad_col = 0, bad_idx = 0;
        for (uint32_t v = 0; v < d.nv; v++) {
            for (int k = 0; k < 3; k++) {
                if (memcmp(&d.vf[9 * (size_t)v + k], &m->positions[3 * (size_t)v + k], 4) != 0 ||
                    memcmp(&d.vf[9 * (size_t)v + 3 + k], &m->normals[3 * (size_t)v + k], 4) != 0)
                    bad_pos++;
                if (variant) {
                    if (d.vc[3 * (size_t)v + k] != hl_tonemap_srgb8(c[3 * (size_t)v + k], ev)) bad_col++;
                } else if (memcmp(&d.vf[9 * (size_t)v + 6 + k], &c[3 * (size_t)v + k], 4) != 0) {
                    bad_col++;
                }
            }
        }
        for (size_t i = 0; i < 3 * (size_t)d.nf; i++)
            if (d.idx[i] != m->indices[i]) bad_idx++;
        printf("%s PLY: %u vertices, %u faces; mismatches: %zu position/normal, %zu colour, %zu index\n",
               variant ? "uchar" : "float", d.nv, d.nf, bad_pos, bad_col, bad_idx);
        HL_CHECK(bad_pos == 0 && bad_col == 0 && bad_idx == 0, "values differ (exact comparison)");
        free_ply(&d);
    }
    HL_CHECK(no_temp_left(hl_test_env("HL_TMP", "/tmp"), "render_bunny"), "temporary files left");
    free(c);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

static int exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

static void ply_atomic(void)
{
    hl_context *ctx = make_ctx();
    hl_mesh *m = load_bunny(ctx);
    float *c = random_colours(m->vertex_count);
    const char *tmpdir = hl_test_env("HL_TMP", "/tmp");
    char tmpname[1200];

    /* A folder that does not exist. */
    const char *p1 = tmp_path("render_no_such_dir/out.ply");
    hl_result r = hl_mesh_save_ply(ctx, m, c, p1, 0, 0.0f);
    expect_bad(ctx, r, HL_ERR_IO, "missing folder", "render_no_such_dir");
    HL_CHECK(strstr(hl_context_last_error(ctx), strerror(ENOENT)) != NULL, "message lacks strerror");
    HL_CHECK(!exists(p1), "file created");

    /* The target is a folder: writing succeeds, the rename fails; the
     * temporary must be gone. */
    const char *p2 = tmp_path("render_target_is_dir");
    mkdir(p2, 0755);
    char inner[1200];
    snprintf(inner, sizeof inner, "%s/keep", p2);
    FILE *f = fopen(inner, "w");
    if (f) fclose(f);
    r = hl_mesh_save_ply(ctx, m, c, p2, 0, 0.0f);
    expect_bad(ctx, r, HL_ERR_IO, "target is a folder", "render_target_is_dir");
    snprintf(tmpname, sizeof tmpname, "%s.tmp.%ld", p2, (long)getpid());
    HL_CHECK(!exists(tmpname), "temporary %s left behind", tmpname);

    /* A write error half way: file size limit below the file's size. */
    const char *p3 = tmp_path("render_fsize.ply");
    remove(p3);
    struct rlimit old;
    getrlimit(RLIMIT_FSIZE, &old);
    struct rlimit lim = old;
    lim.rlim_cur = 4096;
    signal(SIGXFSZ, SIG_IGN);
    if (setrlimit(RLIMIT_FSIZE, &lim) == 0) {
        r = hl_mesh_save_ply(ctx, m, c, p3, 0, 0.0f);
        setrlimit(RLIMIT_FSIZE, &old);
        expect_bad(ctx, r, HL_ERR_IO, "file size limit", strerror(EFBIG));
        HL_CHECK(!exists(p3), "partial file at the target");
        snprintf(tmpname, sizeof tmpname, "%s.tmp.%ld", p3, (long)getpid());
        HL_CHECK(!exists(tmpname), "temporary %s left behind", tmpname);
    } else {
        printf("SKIP write-error check: setrlimit failed: %s\n", strerror(errno));
    }

    /* NaN colour: refused before any file is touched; an existing file
     * stays as it was. */
    const char *p4 = tmp_path("render_nan.ply");
    f = fopen(p4, "w");
    if (f) {
        fputs("old", f);
        fclose(f);
    }
    c[3 * 17 + 2] = NAN;
    r = hl_mesh_save_ply(ctx, m, c, p4, 0, 0.0f);
    expect_bad(ctx, r, HL_ERR_INVALID_ARGUMENT, "NaN colour", "vertex 17");
    c[3 * 17 + 2] = 0.25f;
    c[3 * 3] = -INFINITY;
    r = hl_mesh_save_ply(ctx, m, c, p4, 1, 0.0f);
    expect_bad(ctx, r, HL_ERR_INVALID_ARGUMENT, "-Inf colour (uchar)", "vertex 3");
    struct stat st;
    HL_CHECK(stat(p4, &st) == 0 && st.st_size == 3, "existing file was changed");
    HL_CHECK(no_temp_left(tmpdir, "render_"), "temporary files left");
    free(c);
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"roundtrip", ply_roundtrip},
        {"atomic", ply_atomic},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
