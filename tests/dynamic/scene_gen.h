/* scene_gen.h - writes small animated scenes as glTF 2.0 (one .gltf
 * JSON file, its buffer embedded as a base64 data URI) for the scene
 * tests: up to SG_MAX_NODES nodes, each holding a unit cube (8 vertices,
 * 12 triangles, corners at +-1), a ground quad (4 vertices, 2 triangles,
 * y = 0, x and z in [-1, 1]) or nothing, with static TRS and LINEAR
 * translation / rotation / scale keys; optionally a skin or a morph
 * target with a weights channel, to make non-rigid files. Every number
 * the test compares goes in as a float, so the file holds it exactly.
 *
 * Depends on: libc, libm (isinf).
 */
#ifndef HL_TEST_SCENE_GEN_H
#define HL_TEST_SCENE_GEN_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SG_MAX_NODES 8
#define SG_MAX_KEYS 8

enum { SG_NONE = 0, SG_CUBE = 1, SG_GROUND = 2 };

typedef struct sg_keys {
    int n;                       /* 0: no channel for this path */
    float t[SG_MAX_KEYS];        /* seconds */
    float v[SG_MAX_KEYS][4];     /* translation/scale xyz, rotation x y z w (glTF order) */
} sg_keys;

typedef struct sg_node {
    const char *name;
    int parent;                  /* -1: a root */
    int mesh;                    /* SG_NONE, SG_CUBE, SG_GROUND */
    int has_t, has_r, has_s;
    float t[3], r[4], s[3];      /* r: x y z w */
    sg_keys kt, kr, ks;
} sg_node;

typedef struct sg_scene {
    int nnodes;
    sg_node node[SG_MAX_NODES];
    const char *anim_name;       /* NULL: "move" */
    int skin;                    /* the first cube node gets a skin, jointed to node skin - 1 */
    int morph;                   /* the cube mesh gets a morph target and a weights channel on node 0 */
} sg_scene;

/* ---------------------------------------------------------------- bytes */

typedef struct sg_buf {
    unsigned char *p;
    size_t n, cap;
} sg_buf;

static void sg_put(sg_buf *b, const void *src, size_t n)
{
    while (b->n + n + 4 > b->cap) {
        b->cap = b->cap ? 2 * b->cap : 1024;
        b->p = realloc(b->p, b->cap);
        if (!b->p) { fprintf(stderr, "scene_gen: out of memory\n"); exit(1); }
    }
    memcpy(b->p + b->n, src, n);
    b->n += n;
    while (b->n % 4) b->p[b->n++] = 0; /* accessors stay 4-byte aligned */
}

typedef struct sg_json {
    char *s;
    size_t n, cap;
} sg_json;

static void sg_printf(sg_json *j, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
#include <stdarg.h>
static void sg_printf(sg_json *j, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int w = vsnprintf(j->s ? j->s + j->n : NULL, j->s ? j->cap - j->n : 0, fmt, ap);
        va_end(ap);
        if (w < 0) exit(1);
        if (j->s && j->n + (size_t)w < j->cap) {
            j->n += (size_t)w;
            return;
        }
        j->cap = (j->cap + (size_t)w + 1) * 2;
        j->s = realloc(j->s, j->cap);
        if (!j->s) exit(1);
    }
}

static void sg_base64(sg_json *j, const unsigned char *p, size_t n)
{
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0) | (i + 2 < n ? p[i + 2] : 0);
        char q[5] = {tab[v >> 18 & 63], tab[v >> 12 & 63], i + 1 < n ? tab[v >> 6 & 63] : '=', i + 2 < n ? tab[v & 63] : '=', 0};
        sg_printf(j, "%s", q);
    }
}

/* ---------------------------------------------------------------- accessors */

typedef struct sg_acc {
    size_t offset, bytes;
    int count, ctype;            /* 5126 float, 5123 unsigned short, 5125 unsigned int */
    const char *type;            /* SCALAR, VEC3, VEC4 */
    float min[4], max[4];
    int minmax;                  /* components of min/max to write, 0: none */
} sg_acc;

typedef struct sg_state {
    sg_buf bin;
    sg_acc acc[64];
    int nacc;
} sg_state;

static int sg_add(sg_state *st, const void *data, size_t bytes, int count, int ctype, const char *type, int minmax)
{
    sg_acc *a = &st->acc[st->nacc];
    memset(a, 0, sizeof *a);
    a->offset = st->bin.n;
    a->bytes = bytes;
    a->count = count;
    a->ctype = ctype;
    a->type = type;
    sg_put(&st->bin, data, bytes);
    if (minmax) { /* glTF requires min/max on POSITION and animation inputs */
        const float *f = data;
        a->minmax = minmax;
        for (int c = 0; c < minmax; c++) {
            a->min[c] = a->max[c] = f[c];
            for (int i = 1; i < count; i++) {
                float x = f[i * minmax + c];
                if (x < a->min[c]) a->min[c] = x;
                if (x > a->max[c]) a->max[c] = x;
            }
        }
    }
    return st->nacc++;
}

/* ---------------------------------------------------------------- the file */

static void sg_float_list(sg_json *j, const float *v, int n)
{
    /* JSON has no infinity: 1e39 overflows the reader's float to one */
    for (int i = 0; i < n; i++)
        if (isinf(v[i])) sg_printf(j, "%s%s", i ? "," : "", v[i] > 0 ? "1e39" : "-1e39");
        else sg_printf(j, "%s%.9g", i ? "," : "", (double)v[i]);
}

/* Writes one sampler/channel pair per animated path into the JSON, the
 * keys into st; returns how many channels were written after *first. */
static void sg_channels(sg_state *st, sg_json *samplers, sg_json *channels, int node, const char *path,
                        const sg_keys *k, int comps, int *count)
{
    if (k->n == 0) return;
    float vals[SG_MAX_KEYS * 4];
    for (int i = 0; i < k->n; i++)
        for (int c = 0; c < comps; c++) vals[i * comps + c] = k->v[i][c];
    int in = sg_add(st, k->t, (size_t)k->n * 4, k->n, 5126, "SCALAR", 1);
    int out = sg_add(st, vals, (size_t)(k->n * comps) * 4, k->n, 5126, comps == 4 ? "VEC4" : "VEC3", 0);
    sg_printf(samplers, "%s{\"input\":%d,\"output\":%d,\"interpolation\":\"LINEAR\"}", *count ? "," : "", in, out);
    sg_printf(channels, "%s{\"sampler\":%d,\"target\":{\"node\":%d,\"path\":\"%s\"}}", *count ? "," : "", *count,
              node, path);
    (*count)++;
}

static void sg_meshes(sg_state *st, sg_json *j, const sg_scene *sc)
{
    static const float cube[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                     {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
    static const uint16_t cube_idx[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                          3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
    static const float quad[4][3] = {{-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1}};
    static const uint16_t quad_idx[6] = {0, 2, 1, 0, 3, 2};
    int cp = sg_add(st, cube, sizeof cube, 8, 5126, "VEC3", 3);
    int ci = sg_add(st, cube_idx, sizeof cube_idx, 36, 5123, "SCALAR", 0);
    int qp = sg_add(st, quad, sizeof quad, 4, 5126, "VEC3", 3);
    int qi = sg_add(st, quad_idx, sizeof quad_idx, 6, 5123, "SCALAR", 0);
    char extra[256] = "";
    if (sc->skin) {
        static const uint16_t joints[8][4] = {{0}};
        static const float weights[8][4] = {{1, 0, 0, 0}, {1, 0, 0, 0}, {1, 0, 0, 0}, {1, 0, 0, 0},
                                            {1, 0, 0, 0}, {1, 0, 0, 0}, {1, 0, 0, 0}, {1, 0, 0, 0}};
        int ja = sg_add(st, joints, sizeof joints, 8, 5123, "VEC4", 0);
        int wa = sg_add(st, weights, sizeof weights, 8, 5126, "VEC4", 0);
        snprintf(extra, sizeof extra, ",\"JOINTS_0\":%d,\"WEIGHTS_0\":%d", ja, wa);
    }
    char targets[128] = "";
    if (sc->morph) {
        static const float d[8][3] = {{0, 1, 0}, {0, 1, 0}, {0, 1, 0}, {0, 1, 0},
                                      {0, 1, 0}, {0, 1, 0}, {0, 1, 0}, {0, 1, 0}};
        int ta = sg_add(st, d, sizeof d, 8, 5126, "VEC3", 3);
        snprintf(targets, sizeof targets, ",\"targets\":[{\"POSITION\":%d}]", ta);
    }
    sg_printf(j, "\"meshes\":[{\"name\":\"cube\",\"primitives\":[{\"attributes\":{\"POSITION\":%d%s},\"indices\":%d%s}]%s},"
                 "{\"name\":\"ground\",\"primitives\":[{\"attributes\":{\"POSITION\":%d},\"indices\":%d}]}],",
              cp, extra, ci, targets, sc->morph ? ",\"weights\":[0]" : "", qp, qi);
}

static void sg_nodes(sg_json *j, const sg_scene *sc)
{
    sg_printf(j, "\"nodes\":[");
    for (int i = 0; i < sc->nnodes; i++) {
        const sg_node *n = &sc->node[i];
        sg_printf(j, "%s{\"name\":\"%s\"", i ? "," : "", n->name);
        if (n->mesh) sg_printf(j, ",\"mesh\":%d", n->mesh - 1);
        int first_cube = 1;
        for (int k = 0; k < i; k++) first_cube &= sc->node[k].mesh != SG_CUBE;
        if (sc->skin && n->mesh == SG_CUBE && first_cube) sg_printf(j, ",\"skin\":0");
        if (n->has_t) { sg_printf(j, ",\"translation\":["); sg_float_list(j, n->t, 3); sg_printf(j, "]"); }
        if (n->has_r) { sg_printf(j, ",\"rotation\":["); sg_float_list(j, n->r, 4); sg_printf(j, "]"); }
        if (n->has_s) { sg_printf(j, ",\"scale\":["); sg_float_list(j, n->s, 3); sg_printf(j, "]"); }
        int nc = 0;
        for (int c = 0; c < sc->nnodes; c++)
            if (sc->node[c].parent == i) sg_printf(j, "%s%d", nc++ ? "," : ",\"children\":[", c);
        if (nc) sg_printf(j, "]");
        sg_printf(j, "}");
    }
    sg_printf(j, "],\"scenes\":[{\"nodes\":[");
    int nr = 0;
    for (int i = 0; i < sc->nnodes; i++)
        if (sc->node[i].parent < 0) sg_printf(j, "%s%d", nr++ ? "," : "", i);
    sg_printf(j, "]}],\"scene\":0,");
}

/* Writes sc to path; returns 0 on success. */
static int sg_write_gltf(const char *path, const sg_scene *sc)
{
    sg_state st;
    memset(&st, 0, sizeof st);
    sg_json j = {0}, samplers = {0}, channels = {0};
    sg_printf(&j, "{\"asset\":{\"version\":\"2.0\",\"generator\":\"haarlight scene_gen\"},");
    int has_mesh = 0;
    for (int i = 0; i < sc->nnodes; i++) has_mesh |= sc->node[i].mesh != SG_NONE;
    if (has_mesh) sg_meshes(&st, &j, sc);
    sg_nodes(&j, sc);
    if (sc->skin) {
        /* the joint's inverse bind matrix is the identity */
        static const float ibm[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        int a = sg_add(&st, ibm, sizeof ibm, 1, 5126, "MAT4", 0);
        sg_printf(&j, "\"skins\":[{\"joints\":[%d],\"inverseBindMatrices\":%d}],", sc->skin - 1, a);
    }
    int count = 0;
    sg_printf(&samplers, "%s", "");
    sg_printf(&channels, "%s", "");
    for (int i = 0; i < sc->nnodes; i++) {
        sg_channels(&st, &samplers, &channels, i, "translation", &sc->node[i].kt, 3, &count);
        sg_channels(&st, &samplers, &channels, i, "rotation", &sc->node[i].kr, 4, &count);
        sg_channels(&st, &samplers, &channels, i, "scale", &sc->node[i].ks, 3, &count);
    }
    if (sc->morph) {
        static const float t[2] = {0, 1}, w[2] = {0, 1};
        int in = sg_add(&st, t, sizeof t, 2, 5126, "SCALAR", 1);
        int out = sg_add(&st, w, sizeof w, 2, 5126, "SCALAR", 0);
        sg_printf(&samplers, "%s{\"input\":%d,\"output\":%d,\"interpolation\":\"LINEAR\"}", count ? "," : "", in, out);
        sg_printf(&channels, "%s{\"sampler\":%d,\"target\":{\"node\":0,\"path\":\"weights\"}}", count ? "," : "",
                  count);
        count++;
    }
    if (count)
        sg_printf(&j, "\"animations\":[{\"name\":\"%s\",\"samplers\":[%s],\"channels\":[%s]}],",
                  sc->anim_name ? sc->anim_name : "move", samplers.s, channels.s);
    if (st.nacc) {
        sg_printf(&j, "\"accessors\":[");
        for (int a = 0; a < st.nacc; a++) {
            const sg_acc *c = &st.acc[a];
            sg_printf(&j, "%s{\"bufferView\":%d,\"componentType\":%d,\"count\":%d,\"type\":\"%s\"", a ? "," : "", a,
                      c->ctype, c->count, c->type);
            if (c->minmax) {
                sg_printf(&j, ",\"min\":[");
                sg_float_list(&j, c->min, c->minmax);
                sg_printf(&j, "],\"max\":[");
                sg_float_list(&j, c->max, c->minmax);
                sg_printf(&j, "]");
            }
            sg_printf(&j, "}");
        }
        sg_printf(&j, "],\"bufferViews\":[");
        for (int a = 0; a < st.nacc; a++)
            sg_printf(&j, "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}", a ? "," : "", st.acc[a].offset,
                      st.acc[a].bytes);
        sg_printf(&j, "],\"buffers\":[{\"byteLength\":%zu,\"uri\":\"data:application/octet-stream;base64,", st.bin.n);
        sg_base64(&j, st.bin.p, st.bin.n);
        sg_printf(&j, "\"}],");
    }
    j.s[j.n - 1] = '}'; /* the last comma closes the object */
    FILE *f = fopen(path, "wb");
    int bad = !f || fwrite(j.s, 1, j.n, f) != j.n;
    if (f && fclose(f) != 0) bad = 1;
    free(j.s);
    free(samplers.s);
    free(channels.s);
    free(st.bin.p);
    return bad;
}

#endif
