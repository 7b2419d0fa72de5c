/* surr_gltf.h - writes small glTF 2.0 surroundings (one .gltf JSON file,
 * its buffer embedded as a base64 data URI): nodes in a hierarchy, each
 * holding a triangle soup with a material or nothing, static translation
 * and rotation, LINEAR translation and rotation keys (one animation,
 * "move"), materials with an emissive factor and, optionally,
 * KHR_materials_emissive_strength. For the surroundings tests
 * (test_surroundings.c) and the example's generator
 * (tests/tools/make_surroundings.c). Every number goes in as a float, so
 * the file holds it exactly.
 *
 * Depends on: libc, libm.
 */
#ifndef HL_TEST_SURR_GLTF_H
#define HL_TEST_SURR_GLTF_H

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SGF_MAX_NODES 16
#define SGF_MAX_KEYS 32

typedef struct sgf_keys {
    int n;                   /* 0: no channel */
    float t[SGF_MAX_KEYS];   /* seconds */
    float v[SGF_MAX_KEYS][4]; /* translation xyz, or rotation x y z w */
} sgf_keys;

typedef struct sgf_material {
    const char *name;
    float emissive[3];       /* glTF's emissiveFactor */
    float strength;          /* NaN: no KHR_materials_emissive_strength */
} sgf_material;

typedef struct sgf_node {
    const char *name;
    int parent;              /* -1: a root */
    const float *tris;       /* 9 floats a triangle, or NULL: no mesh */
    uint32_t ntris;
    int material;            /* -1: none */
    float t[3], r[4];        /* r: x y z w; all zero: identity */
    sgf_keys kt, kr;
} sgf_node;

typedef struct sgf_scene {
    int nnodes, nmaterials;
    sgf_node node[SGF_MAX_NODES];
    sgf_material material[SGF_MAX_NODES];
} sgf_scene;

typedef struct sgf_text {
    char *s;
    size_t n, cap;
} sgf_text;

static void sgf_printf(sgf_text *j, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void sgf_printf(sgf_text *j, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int k = vsnprintf(j->s ? j->s + j->n : NULL, j->s ? j->cap - j->n : 0, fmt, ap);
        va_end(ap);
        if (k < 0) exit(1);
        if (j->s && j->n + (size_t)k < j->cap) { j->n += (size_t)k; return; }
        j->cap = (j->cap + (size_t)k + 1) * 2;
        j->s = realloc(j->s, j->cap);
        if (!j->s) { fprintf(stderr, "surr_gltf: out of memory\n"); exit(1); }
    }
}

/* Floats appended to the buffer; returns their byte offset. */
static size_t sgf_put(unsigned char **buf, size_t *n, const float *v, size_t count)
{
    size_t off = *n;
    *buf = realloc(*buf, *n + count * sizeof(float) + 1);
    if (!*buf) { fprintf(stderr, "surr_gltf: out of memory\n"); exit(1); }
    memcpy(*buf + *n, v, count * sizeof(float));
    *n += count * sizeof(float);
    return off;
}

/* An accessor (and its buffer view) of count elements of type
 * ("SCALAR", "VEC3", "VEC4") at off; min and max for POSITION (finite
 * values only, as a NaN cannot be written in JSON). */
static void sgf_accessor(sgf_text *acc, sgf_text *views, int *na, size_t off, size_t count, const char *type, int comps,
                         const float *v, int minmax)
{
    sgf_printf(views, "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}", *na ? "," : "", off,
               count * (size_t)comps * sizeof(float));
    sgf_printf(acc, "%s{\"bufferView\":%d,\"componentType\":5126,\"count\":%zu,\"type\":\"%s\"", *na ? "," : "", *na,
               count, type);
    if (minmax) {
        float lo[4] = {0}, hi[4] = {0};
        for (int c = 0; c < comps; c++) {
            lo[c] = INFINITY;
            hi[c] = -INFINITY;
            for (size_t i = 0; i < count; i++) {
                float x = v[(size_t)comps * i + (size_t)c];
                if (isfinite(x)) { lo[c] = fminf(lo[c], x); hi[c] = fmaxf(hi[c], x); }
            }
            if (!isfinite(lo[c])) lo[c] = hi[c] = 0.0f;
        }
        sgf_printf(acc, ",\"min\":[%.9g,%.9g,%.9g],\"max\":[%.9g,%.9g,%.9g]", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
    }
    sgf_printf(acc, "}");
    (*na)++;
}

static void sgf_base64(sgf_text *j, const unsigned char *p, size_t n)
{
    static const char a[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0) | (i + 2 < n ? p[i + 2] : 0);
        sgf_printf(j, "%c%c%c%c", a[v >> 18 & 63], a[v >> 12 & 63], i + 1 < n ? a[v >> 6 & 63] : '=',
                   i + 2 < n ? a[v & 63] : '=');
    }
}

static void sgf_materials(sgf_text *j, const sgf_scene *sc)
{
    int strength = 0;
    for (int m = 0; m < sc->nmaterials; m++) strength |= !isnan(sc->material[m].strength);
    if (strength) sgf_printf(j, "\"extensionsUsed\":[\"KHR_materials_emissive_strength\"],");
    sgf_printf(j, "\"materials\":[");
    for (int m = 0; m < sc->nmaterials; m++) {
        const sgf_material *mt = &sc->material[m];
        sgf_printf(j, "%s{\"name\":\"%s\",\"emissiveFactor\":[%.9g,%.9g,%.9g]", m ? "," : "", mt->name,
                   mt->emissive[0], mt->emissive[1], mt->emissive[2]);
        if (!isnan(mt->strength))
            sgf_printf(j, ",\"extensions\":{\"KHR_materials_emissive_strength\":{\"emissiveStrength\":%.9g}}",
                       mt->strength);
        sgf_printf(j, "}");
    }
    sgf_printf(j, "],");
}

/* Writes sc to path; returns 0, or -1 when the file cannot be written. */
static int sgf_write(const sgf_scene *sc, const char *path)
{
    sgf_text j = {0}, acc = {0}, views = {0}, nodes = {0}, meshes = {0}, chans = {0}, samps = {0};
    unsigned char *buf = NULL;
    size_t nbuf = 0;
    int na = 0, nm = 0, nch = 0;
    for (int k = 0; k < sc->nnodes; k++) {
        const sgf_node *n = &sc->node[k];
        sgf_printf(&nodes, "%s{\"name\":\"%s\"", k ? "," : "", n->name);
        if (n->tris) {
            size_t off = sgf_put(&buf, &nbuf, n->tris, 9 * (size_t)n->ntris);
            sgf_printf(&meshes, "%s{\"primitives\":[{\"attributes\":{\"POSITION\":%d}", nm ? "," : "", na);
            if (n->material >= 0) sgf_printf(&meshes, ",\"material\":%d", n->material);
            sgf_printf(&meshes, "}]}");
            sgf_accessor(&acc, &views, &na, off, 3 * (size_t)n->ntris, "VEC3", 3, n->tris, 1);
            sgf_printf(&nodes, ",\"mesh\":%d", nm++);
        }
        if (n->t[0] != 0.0f || n->t[1] != 0.0f || n->t[2] != 0.0f)
            sgf_printf(&nodes, ",\"translation\":[%.9g,%.9g,%.9g]", n->t[0], n->t[1], n->t[2]);
        if (n->r[0] != 0.0f || n->r[1] != 0.0f || n->r[2] != 0.0f || n->r[3] != 0.0f)
            sgf_printf(&nodes, ",\"rotation\":[%.9g,%.9g,%.9g,%.9g]", n->r[0], n->r[1], n->r[2], n->r[3]);
        int first = 1;
        for (int c = 0; c < sc->nnodes; c++)
            if (sc->node[c].parent == k) {
                sgf_printf(&nodes, "%s%d", first ? ",\"children\":[" : ",", c);
                first = 0;
            }
        sgf_printf(&nodes, "%s}", first ? "" : "]");
        for (int path = 0; path < 2; path++) {
            const sgf_keys *ks = path ? &n->kr : &n->kt;
            if (!ks->n) continue;
            int comps = path ? 4 : 3;
            float vals[SGF_MAX_KEYS * 4];
            for (int i = 0; i < ks->n; i++) memcpy(vals + comps * i, ks->v[i], (size_t)comps * sizeof(float));
            size_t to = sgf_put(&buf, &nbuf, ks->t, (size_t)ks->n);
            sgf_accessor(&acc, &views, &na, to, (size_t)ks->n, "SCALAR", 1, NULL, 0);
            size_t vo = sgf_put(&buf, &nbuf, vals, (size_t)(ks->n * comps));
            sgf_accessor(&acc, &views, &na, vo, (size_t)ks->n, path ? "VEC4" : "VEC3", comps, NULL, 0);
            sgf_printf(&samps, "%s{\"input\":%d,\"output\":%d,\"interpolation\":\"LINEAR\"}", nch ? "," : "", na - 2,
                       na - 1);
            sgf_printf(&chans, "%s{\"sampler\":%d,\"target\":{\"node\":%d,\"path\":\"%s\"}}", nch ? "," : "", nch, k,
                       path ? "rotation" : "translation");
            nch++;
        }
    }
    sgf_printf(&j, "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[");
    int first = 1;
    for (int k = 0; k < sc->nnodes; k++)
        if (sc->node[k].parent < 0) {
            sgf_printf(&j, "%s%d", first ? "" : ",", k);
            first = 0;
        }
    sgf_printf(&j, "]}],\"nodes\":[%s],\"meshes\":[%s],", nodes.s, meshes.s ? meshes.s : "");
    sgf_materials(&j, sc);
    if (nch) sgf_printf(&j, "\"animations\":[{\"name\":\"move\",\"channels\":[%s],\"samplers\":[%s]}],", chans.s, samps.s);
    sgf_printf(&j, "\"accessors\":[%s],\"bufferViews\":[%s],\"buffers\":[{\"byteLength\":%zu,"
                   "\"uri\":\"data:application/octet-stream;base64,",
               acc.s ? acc.s : "", views.s ? views.s : "", nbuf);
    sgf_base64(&j, buf, nbuf);
    sgf_printf(&j, "\"}]}\n");
    FILE *f = fopen(path, "wb");
    int ok = f && fwrite(j.s, 1, j.n, f) == j.n;
    if (f && fclose(f) != 0) ok = 0;
    free(j.s); free(acc.s); free(views.s); free(nodes.s); free(meshes.s); free(chans.s); free(samps.s);
    free(buf);
    return ok ? 0 : -1;
}

/* Appends the 12 triangles of an axis-aligned box (centre c, half sizes
 * h) to tris at triangle *n. */
static void sgf_box(float *tris, uint32_t *n, const float c[3], const float h[3])
{
    static const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    float v[8][3];
    for (int i = 0; i < 8; i++)
        for (int a = 0; a < 3; a++) v[i][a] = c[a] + ((i >> (2 - a)) & 1 ? h[a] : -h[a]);
    for (int q = 0; q < 6; q++) {
        const int tri[2][3] = {{quads[q][0], quads[q][1], quads[q][2]}, {quads[q][0], quads[q][2], quads[q][3]}};
        for (int t = 0; t < 2; t++, (*n)++)
            for (int k = 0; k < 3; k++) memcpy(tris + 9 * (size_t)*n + 3 * k, v[tri[t][k]], sizeof v[0]);
    }
}

#endif
