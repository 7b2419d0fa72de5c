/* mesh.c - triangle meshes: the shared builder, ground plane and queries.
 *
 * Everything about meshes except reading files. hl_mesh_create and the
 * importers in mesh_import.c hand raw arrays to hl_mesh_build_, which
 * validates, welds vertices with equal positions (bit-identical, except
 * that -0 == +0), drops degenerate triangles and unreferenced vertices,
 * turns inward-wound closed meshes outward and computes smooth normals,
 * reporting every change in hl_mesh_stats.
 *
 * Dependencies: hl_internal.h (errors, allocation), libc, libm.
 * Mesh arrays are allocated with plain malloc and released with free, so a
 * mesh assembled by another module (the transport loader) can be handed to
 * hl_mesh_destroy as well.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hl_internal.h"

/* Built-in defaults (see the comments in haarlight.h). */
#define HL_DEFAULT_ALBEDO 0.8f
#define HL_GROUND_RESOLUTION 96u
#define HL_GROUND_MARGIN 0.75f
/* A ground finer than this would be a precompute of days; it is surely a
 * mistake, and bounding it keeps every count inside uint32. */
#define HL_GROUND_MAX_RESOLUTION 4096u
/* Triangles with area <= this x diagonal^2 are dropped (same rule as the
 * shared data README). */
#define HL_DEGENERATE_AREA 1e-12

/* ---------------------------------------------------------------- helpers */

static uint64_t next_pow2(uint64_t n)
{
    uint64_t p = 16;
    while (p < n) p <<= 1;
    return p;
}

/* Multiplicative mixing of 32-bit words; good enough for float bit
 * patterns, which cluster in their high bits. */
static uint64_t mix_word(uint64_t h, uint32_t w)
{
    h ^= w;
    h *= 0x9E3779B97F4A7C15ull;
    h ^= h >> 31;
    return h;
}

static uint64_t mix_final(uint64_t h)
{
    h ^= h >> 33;
    h *= 0xFF51AFD7ED558CCDull;
    h ^= h >> 33;
    h *= 0xC4CEB9FE1A85EC53ull;
    h ^= h >> 33;
    return h;
}

/* Bit pattern used for welding: -0 and +0 are the same point (the shared
 * teapot has both on its x = 0 seam), everything else must match bit for
 * bit. */
static uint32_t weld_bits(float f)
{
    uint32_t u;
    if (f == 0.0f) return 0u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static int is_finite3(const float *p)
{
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

/* Cross product of (b - a) and (c - a) in double: twice the area vector. */
static void tri_cross(const float *a, const float *b, const float *c, double *n)
{
    double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

/* Zero albedo means the default; anything else must be a reflectance. */
static hl_result resolve_albedo(hl_context *ctx, const char *name, const float *in,
                                float fallback, float *outv)
{
    if (in[0] == 0.0f && in[1] == 0.0f && in[2] == 0.0f) {
        outv[0] = outv[1] = outv[2] = fallback;
        return HL_OK;
    }
    for (int k = 0; k < 3; k++) {
        if (!(in[k] >= 0.0f && in[k] <= 1.0f))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "%s: albedo (%g, %g, %g) must lie in [0, 1]", name,
                           (double)in[0], (double)in[1], (double)in[2]);
        outv[k] = in[k];
    }
    return HL_OK;
}

/* ---------------------------------------------------------------- welding */

typedef struct weld_key {
    const float *pos, *nrm, *col; /* nrm/col may be NULL */
} weld_key;

static uint64_t weld_hash(const weld_key *k, uint32_t v)
{
    uint64_t h = 0x243F6A8885A308D3ull;
    for (int c = 0; c < 3; c++) h = mix_word(h, weld_bits(k->pos[3 * (size_t)v + c]));
    if (k->nrm)
        for (int c = 0; c < 3; c++) h = mix_word(h, weld_bits(k->nrm[3 * (size_t)v + c]));
    if (k->col)
        for (int c = 0; c < 3; c++) h = mix_word(h, weld_bits(k->col[3 * (size_t)v + c]));
    return mix_final(h);
}

static int weld_equal3(const float *a, const float *b)
{
    return weld_bits(a[0]) == weld_bits(b[0]) && weld_bits(a[1]) == weld_bits(b[1]) &&
           weld_bits(a[2]) == weld_bits(b[2]);
}

static int weld_equal(const weld_key *k, uint32_t a, uint32_t b)
{
    size_t sa = 3 * (size_t)a, sb = 3 * (size_t)b;
    if (!weld_equal3(k->pos + sa, k->pos + sb)) return 0;
    if (k->nrm && !weld_equal3(k->nrm + sa, k->nrm + sb)) return 0;
    if (k->col && !weld_equal3(k->col + sa, k->col + sb)) return 0;
    return 1;
}

/* remap[v] = welded id of vertex v; rep[w] = first vertex of welded id w.
 * Welded ids follow the order of first occurrence. Returns the id count,
 * or 0 after recording an allocation failure. */
static uint32_t weld(hl_context *ctx, const weld_key *k, uint32_t n, uint32_t *remap,
                     uint32_t *rep)
{
    uint64_t cap = next_pow2(2 * (uint64_t)n);
    if (cap > SIZE_MAX / sizeof(uint32_t)) {
        hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "vertex hash table for %u vertices is too large", n);
        return 0;
    }
    uint32_t *table = hl_malloc(ctx, (size_t)cap * sizeof *table, "the vertex welding table");
    if (!table) return 0;
    memset(table, 0xFF, (size_t)cap * sizeof *table);
    uint64_t mask = cap - 1;
    uint32_t count = 0;
    for (uint32_t v = 0; v < n; v++) {
        uint64_t slot = weld_hash(k, v) & mask;
        for (;;) {
            uint32_t w = table[slot];
            if (w == UINT32_MAX) {
                table[slot] = count;
                rep[count] = v;
                remap[v] = count++;
                break;
            }
            if (weld_equal(k, rep[w], v)) {
                remap[v] = w;
                break;
            }
            slot = (slot + 1) & mask;
        }
    }
    free(table);
    return count;
}

/* ------------------------------------------------------------ orientation */

/* 1 if every directed edge appears once and its reverse appears once:
 * closed, manifold and consistently wound, so the signed volume has a
 * meaning. 0 otherwise; -1 after an allocation failure. */
static int closed_and_consistent(hl_context *ctx, const uint32_t *idx, uint32_t tris)
{
    uint64_t n = 3 * (uint64_t)tris;
    uint64_t cap = next_pow2(2 * n);
    if (cap > SIZE_MAX / sizeof(uint64_t)) return 0; /* cannot tell; do not flip */
    uint64_t *table = hl_malloc(ctx, (size_t)cap * sizeof *table, "the edge table");
    if (!table) return -1;
    memset(table, 0xFF, (size_t)cap * sizeof *table); /* UINT64_MAX: a self-loop, never an edge */
    uint64_t mask = cap - 1;
    int ok = 1;
    for (uint64_t i = 0; i < n && ok; i++) {
        uint32_t a = idx[i], b = idx[i % 3 == 2 ? i - 2 : i + 1];
        uint64_t key = (uint64_t)a << 32 | b;
        uint64_t slot = mix_final(key) & mask;
        while (table[slot] != UINT64_MAX && table[slot] != key) slot = (slot + 1) & mask;
        if (table[slot] == key) ok = 0; /* same directed edge twice */
        table[slot] = key;
    }
    for (uint64_t i = 0; i < n && ok; i++) {
        uint32_t a = idx[i], b = idx[i % 3 == 2 ? i - 2 : i + 1];
        uint64_t key = (uint64_t)b << 32 | a;
        uint64_t slot = mix_final(key) & mask;
        while (table[slot] != UINT64_MAX && table[slot] != key) slot = (slot + 1) & mask;
        if (table[slot] != key) ok = 0; /* boundary or inconsistent winding */
    }
    free(table);
    return ok;
}

/* Signed volume about the bounding-box centre, which keeps the sum well
 * conditioned for meshes far from the origin. */
static double signed_volume(const float *pos, const uint32_t *idx, uint32_t tris,
                            const double *center)
{
    double vol = 0.0;
    for (size_t t = 0; t < tris; t++) {
        double p[3][3];
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++) p[c][k] = (double)pos[3 * (size_t)idx[3 * t + c] + k] - center[k];
        vol += p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1])
             - p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0])
             + p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]);
    }
    return vol / 6.0;
}

/* ---------------------------------------------------------------- normals */

/* Area-weighted smooth normals. Where the weighted sum cancels (back-to-back
 * flaps, needles) the normal of the largest adjacent face is used instead,
 * and +Y when even that is zero, so no normal is ever NaN. */
static hl_result smooth_normals(hl_context *ctx, const float *pos, uint32_t nv,
                                const uint32_t *idx, uint32_t tris, float *nrm)
{
    double *acc = hl_calloc(ctx, (size_t)nv * 5, sizeof(double), "normal accumulation");
    uint32_t *best = hl_malloc(ctx, (size_t)nv * sizeof(uint32_t), "normal fallback faces");
    if (!acc || !best) {
        free(acc);
        free(best);
        return HL_ERR_OUT_OF_MEMORY;
    }
    /* acc per vertex: sum x, y, z, sum of magnitudes, largest magnitude */
    memset(best, 0xFF, (size_t)nv * sizeof(uint32_t));
    for (uint32_t t = 0; t < tris; t++) {
        const uint32_t *f = idx + 3 * (size_t)t;
        double n[3];
        tri_cross(pos + 3 * (size_t)f[0], pos + 3 * (size_t)f[1], pos + 3 * (size_t)f[2], n);
        double m = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int c = 0; c < 3; c++) {
            double *a = acc + 5 * (size_t)f[c];
            a[0] += n[0];
            a[1] += n[1];
            a[2] += n[2];
            a[3] += m;
            if (m > a[4]) {
                a[4] = m;
                best[f[c]] = t;
            }
        }
    }
    for (uint32_t v = 0; v < nv; v++) {
        const double *a = acc + 5 * (size_t)v;
        double n[3] = {a[0], a[1], a[2]};
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(len > 1e-6 * a[3]) && best[v] != UINT32_MAX) {
            const uint32_t *f = idx + 3 * (size_t)best[v];
            tri_cross(pos + 3 * (size_t)f[0], pos + 3 * (size_t)f[1], pos + 3 * (size_t)f[2], n);
            len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        }
        if (!(len > 0.0) || !isfinite(len)) {
            n[0] = 0.0;
            n[1] = 1.0;
            n[2] = 0.0;
            len = 1.0;
        }
        for (int k = 0; k < 3; k++) nrm[3 * (size_t)v + k] = (float)(n[k] / len);
    }
    free(acc);
    free(best);
    return HL_OK;
}

/* ---------------------------------------------------------------- builder */

/* Shared by hl_mesh_create and the importers. name is used in messages.
 * normals and colors may be NULL. Vertex and face numbers in messages count
 * from 0, as in the arrays. */
hl_result hl_mesh_build_(hl_context *ctx, const char *name, uint32_t vertex_count,
                         const float *positions, const float *normals, const float *colors,
                         uint32_t triangle_count, const uint32_t *indices,
                         const hl_mesh_load_desc *desc, hl_mesh **out, hl_mesh_stats *stats)
{
    hl_mesh_load_desc d;
    memset(&d, 0, sizeof d);
    if (desc) d = *desc;
    if (!name) name = "<memory>";
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: no output mesh pointer given", name);
    *out = NULL;

    float const_albedo[3];
    hl_result r = resolve_albedo(ctx, name, d.albedo, HL_DEFAULT_ALBEDO, const_albedo);
    if (r != HL_OK) return r;
    int up_z;
    if (d.up_axis == 0 || d.up_axis == 'y' || d.up_axis == 'Y') up_z = 0;
    else if (d.up_axis == 'z' || d.up_axis == 'Z') up_z = 1;
    else return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: up axis %d is neither 'y' nor 'z'", name, d.up_axis);

    if (vertex_count == 0) return hl_fail(ctx, HL_ERR_MESH, "%s: mesh has no vertices", name);
    if (triangle_count == 0)
        return hl_fail(ctx, HL_ERR_MESH, "%s: mesh has %u vertices but no faces", name, vertex_count);
    if (!positions || !indices)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: positions or indices are NULL", name);

    for (uint32_t v = 0; v < vertex_count; v++) {
        const float *p = positions + 3 * (size_t)v;
        if (!is_finite3(p))
            return hl_fail(ctx, HL_ERR_MESH, "%s: vertex %u (counting from 0) has a non-finite coordinate (%g, %g, %g)",
                           name, v, (double)p[0], (double)p[1], (double)p[2]);
        if (colors && !is_finite3(colors + 3 * (size_t)v))
            return hl_fail(ctx, HL_ERR_MESH, "%s: vertex %u (counting from 0) has a non-finite colour (%g, %g, %g)",
                           name, v, (double)colors[3 * (size_t)v], (double)colors[3 * (size_t)v + 1],
                           (double)colors[3 * (size_t)v + 2]);
    }
    for (uint32_t t = 0; t < triangle_count; t++)
        for (int c = 0; c < 3; c++) {
            uint32_t i = indices[3 * (size_t)t + c];
            if (i >= vertex_count)
                return hl_fail(ctx, HL_ERR_MESH,
                               "%s: face %u (counting from 0) refers to vertex %u, out of range (%u vertices)",
                               name, t, i, vertex_count);
        }

    hl_mesh_stats st = {0};
    st.file_vertices = vertex_count;
    st.file_triangles = triangle_count;
    st.had_normals = normals != NULL;
    st.had_colors = colors != NULL;

    size_t nv = vertex_count, nt = triangle_count;
    hl_mesh *mesh = NULL;
    float *pos = NULL, *nrm = NULL;
    uint32_t *remap = NULL, *rep = NULL, *tri = NULL, *newid = NULL;
    r = HL_ERR_OUT_OF_MEMORY;

    /* Working copies in the engine's frame: +Z-up files turn so that +Z
     * becomes +Y; (x, y, z) -> (x, z, -y) is a proper rotation about +X. */
    pos = hl_malloc(ctx, nv * 3 * sizeof(float), "vertex positions");
    if (!pos) goto done;
    if (normals) {
        nrm = hl_malloc(ctx, nv * 3 * sizeof(float), "vertex normals");
        if (!nrm) goto done;
    }
    for (size_t v = 0; v < nv; v++) {
        const float *p = positions + 3 * v;
        float *q = pos + 3 * v;
        if (up_z) { q[0] = p[0]; q[1] = p[2]; q[2] = -p[1]; }
        else { q[0] = p[0]; q[1] = p[1]; q[2] = p[2]; }
        if (nrm) {
            const float *n = normals + 3 * v;
            float *m = nrm + 3 * v;
            if (up_z) { m[0] = n[0]; m[1] = n[2]; m[2] = -n[1]; }
            else { m[0] = n[0]; m[1] = n[1]; m[2] = n[2]; }
        }
    }

    /* Weld on position plus whatever attributes the caller supplied, so a
     * deliberate normal or colour seam survives. */
    remap = hl_malloc(ctx, nv * sizeof(uint32_t), "the vertex remap");
    rep = hl_malloc(ctx, nv * sizeof(uint32_t), "the welded vertices");
    if (!remap || !rep) goto done;
    weld_key key = {pos, nrm, colors};
    uint32_t welded = weld(ctx, &key, vertex_count, remap, rep);
    if (welded == 0) goto done;
    st.merged_vertices = vertex_count - welded;

    /* The degenerate-area threshold scales with the referenced geometry
     * only; a stray unreferenced vertex must not change which faces stay. */
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < 3 * nt; i++) {
        const float *p = pos + 3 * (size_t)rep[remap[indices[i]]];
        for (int k = 0; k < 3; k++) {
            if (p[k] < lo[k]) lo[k] = p[k];
            if (p[k] > hi[k]) hi[k] = p[k];
        }
    }
    double diag2 = 0.0;
    for (int k = 0; k < 3; k++) diag2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    double min_area2 = 2.0 * HL_DEGENERATE_AREA * diag2; /* |cross| is twice the area */

    tri = hl_malloc(ctx, nt * 3 * sizeof(uint32_t), "triangle indices");
    if (!tri) goto done;
    size_t kept = 0;
    for (size_t t = 0; t < nt; t++) {
        uint32_t a = remap[indices[3 * t]], b = remap[indices[3 * t + 1]], c = remap[indices[3 * t + 2]];
        if (a == b || b == c || a == c) continue;
        double n[3];
        tri_cross(pos + 3 * (size_t)rep[a], pos + 3 * (size_t)rep[b], pos + 3 * (size_t)rep[c], n);
        if (sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) <= min_area2) continue;
        tri[3 * kept] = a;
        tri[3 * kept + 1] = b;
        tri[3 * kept + 2] = c;
        kept++;
    }
    st.degenerate_triangles = (uint32_t)(nt - kept);
    if (kept == 0) {
        r = hl_fail(ctx, HL_ERR_MESH,
                    "%s: all %u faces are degenerate (repeated vertex or zero area), nothing is left",
                    name, triangle_count);
        goto done;
    }

    /* Compact: keep referenced welded vertices in first-occurrence order. */
    newid = hl_malloc(ctx, (size_t)welded * sizeof(uint32_t), "the vertex compaction");
    if (!newid) goto done;
    memset(newid, 0xFF, (size_t)welded * sizeof(uint32_t));
    for (size_t i = 0; i < 3 * kept; i++) newid[tri[i]] = 0;
    uint32_t used = 0;
    for (uint32_t w = 0; w < welded; w++)
        if (newid[w] != UINT32_MAX) {
            rep[used] = rep[w]; /* used <= w: overwriting in place is safe */
            newid[w] = used++;
        }
    for (size_t i = 0; i < 3 * kept; i++) tri[i] = newid[tri[i]];
    st.unreferenced_vertices = welded - used;

    mesh = hl_calloc(ctx, 1, sizeof *mesh, "the mesh");
    if (!mesh) goto done;
    mesh->vertex_count = used;
    mesh->object_vertex_count = used;
    mesh->triangle_count = (uint32_t)kept;
    mesh->positions = hl_malloc(ctx, (size_t)used * 3 * sizeof(float), "mesh positions");
    mesh->normals = hl_malloc(ctx, (size_t)used * 3 * sizeof(float), "mesh normals");
    mesh->albedo = hl_malloc(ctx, (size_t)used * 3 * sizeof(float), "mesh albedo");
    mesh->indices = hl_malloc(ctx, kept * 3 * sizeof(uint32_t), "mesh indices");
    if (!mesh->positions || !mesh->normals || !mesh->albedo || !mesh->indices) goto done;
    memcpy(mesh->indices, tri, kept * 3 * sizeof(uint32_t));
    for (size_t v = 0; v < used; v++) {
        memcpy(mesh->positions + 3 * v, pos + 3 * (size_t)rep[v], 3 * sizeof(float));
        for (int k = 0; k < 3; k++) {
            float a = colors ? colors[3 * (size_t)rep[v] + k] : const_albedo[k];
            mesh->albedo[3 * v + k] = a < 0.0f ? 0.0f : (a > 1.0f ? 1.0f : a);
        }
    }

    /* Orientation: only a closed, consistently wound mesh has an inside, so
     * only then can an inward winding be recognised and reversed. */
    int closed = closed_and_consistent(ctx, mesh->indices, mesh->triangle_count);
    if (closed < 0) goto done;
    if (closed && !d.keep_winding) {
        double center[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
        if (signed_volume(mesh->positions, mesh->indices, mesh->triangle_count, center) < 0.0) {
            for (size_t t = 0; t < kept; t++) {
                uint32_t s = mesh->indices[3 * t + 1];
                mesh->indices[3 * t + 1] = mesh->indices[3 * t + 2];
                mesh->indices[3 * t + 2] = s;
            }
            st.flipped = 1;
        }
    }

    /* Normals: the file's where usable, else smooth ones from the final
     * winding. File normals follow a flip, since they pointed the same
     * wrong way as the winding. */
    int need_smooth = nrm == NULL;
    if (nrm) {
        for (size_t v = 0; v < used; v++) {
            const float *n = nrm + 3 * (size_t)rep[v];
            double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
            float *o = mesh->normals + 3 * v;
            if (!(len > 1e-30) || !isfinite(len)) {
                o[0] = NAN; /* marks a vertex for the smooth fallback below */
                need_smooth = 1;
                continue;
            }
            double s = st.flipped ? -1.0 / len : 1.0 / len;
            for (int k = 0; k < 3; k++) o[k] = (float)(n[k] * s);
        }
    }
    if (need_smooth) {
        float *smooth = nrm ? hl_malloc(ctx, (size_t)used * 3 * sizeof(float), "smooth normals") : mesh->normals;
        if (!smooth) goto done;
        r = smooth_normals(ctx, mesh->positions, used, mesh->indices, mesh->triangle_count, smooth);
        if (r != HL_OK) {
            if (smooth != mesh->normals) free(smooth);
            goto done;
        }
        if (smooth != mesh->normals) {
            for (size_t v = 0; v < used; v++)
                if (isnan(mesh->normals[3 * v])) memcpy(mesh->normals + 3 * v, smooth + 3 * v, 3 * sizeof(float));
            free(smooth);
        }
    }

    if (stats) *stats = st;
    *out = mesh;
    mesh = NULL;
    r = HL_OK;
done:
    hl_mesh_destroy(mesh);
    free(pos);
    free(nrm);
    free(remap);
    free(rep);
    free(tri);
    free(newid);
    return r;
}

/* ---------------------------------------------------------------- public */

hl_result hl_mesh_create(hl_context *ctx, uint32_t vertex_count, const float *positions,
                         const float *normals, const float *albedo, uint32_t triangle_count,
                         const uint32_t *indices, hl_mesh **out)
{
    if (out) *out = NULL;
    if ((vertex_count && !positions) || (triangle_count && !indices))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "<memory>: positions or indices are NULL");
    return hl_mesh_build_(ctx, "<memory>", vertex_count, positions, normals, albedo, triangle_count,
                          indices, NULL, out, NULL);
}

hl_result hl_mesh_add_ground(hl_context *ctx, hl_mesh *mesh, const hl_ground_desc *desc)
{
    hl_ground_desc d = {0};
    if (desc) d = *desc;
    if (!mesh || mesh->object_vertex_count == 0 || !mesh->positions)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: the mesh is empty");
    if (mesh->object_vertex_count != mesh->vertex_count)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: the mesh already has one");
    uint32_t res = d.resolution ? d.resolution : HL_GROUND_RESOLUTION;
    float margin = d.margin != 0.0f ? d.margin : HL_GROUND_MARGIN;
    if (res > HL_GROUND_MAX_RESOLUTION)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: resolution %u exceeds %u", res,
                       HL_GROUND_MAX_RESOLUTION);
    if (!(margin > 0.0f) || !isfinite(margin))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: margin %g must be positive", (double)margin);

    uint32_t nv = mesh->vertex_count, nt = mesh->triangle_count;
    uint64_t gv = (uint64_t)(res + 1) * (res + 1), gt = 2 * (uint64_t)res * res;
    if (nv + gv > UINT32_MAX || nt + gt > UINT32_MAX)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "ground plane: %u x %u grid makes the mesh too large", res, res);

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double mean[3] = {0, 0, 0};
    for (size_t v = 0; v < nv; v++)
        for (int k = 0; k < 3; k++) {
            double p = mesh->positions[3 * v + k];
            if (p < lo[k]) lo[k] = p;
            if (p > hi[k]) hi[k] = p;
            mean[k] += mesh->albedo ? mesh->albedo[3 * v + k] : HL_DEFAULT_ALBEDO;
        }
    float albedo[3];
    float fallback[3] = {(float)(mean[0] / nv), (float)(mean[1] / nv), (float)(mean[2] / nv)};
    if (d.albedo[0] == 0.0f && d.albedo[1] == 0.0f && d.albedo[2] == 0.0f) {
        memcpy(albedo, fallback, sizeof albedo);
    } else {
        hl_result r = resolve_albedo(ctx, "ground plane", d.albedo, 0.0f, albedo);
        if (r != HL_OK) return r;
    }

    /* A square centred on the footprint: cells stay square, and it covers
     * the footprint plus margin x its larger extent on every side. */
    double ext = fmax(hi[0] - lo[0], hi[2] - lo[2]);
    if (!(ext > 0.0)) ext = fmax(hi[1] - lo[1], 1.0);
    double side = ext * (1.0 + 2.0 * margin);
    double cx = 0.5 * (lo[0] + hi[0]), cz = 0.5 * (lo[2] + hi[2]);
    double x0 = cx - 0.5 * side, z0 = cz - 0.5 * side, step = side / res;
    float y = (float)lo[1];

    size_t tv = (size_t)(nv + gv), tt = (size_t)(nt + gt);
    float *pos = hl_malloc(ctx, tv * 3 * sizeof(float), "ground positions");
    float *nrm = hl_malloc(ctx, tv * 3 * sizeof(float), "ground normals");
    float *alb = hl_malloc(ctx, tv * 3 * sizeof(float), "ground albedo");
    uint32_t *idx = hl_malloc(ctx, tt * 3 * sizeof(uint32_t), "ground indices");
    if (!pos || !nrm || !alb || !idx) {
        free(pos);
        free(nrm);
        free(alb);
        free(idx);
        return HL_ERR_OUT_OF_MEMORY;
    }
    memcpy(pos, mesh->positions, (size_t)nv * 3 * sizeof(float));
    memcpy(nrm, mesh->normals, (size_t)nv * 3 * sizeof(float));
    if (mesh->albedo) memcpy(alb, mesh->albedo, (size_t)nv * 3 * sizeof(float));
    else for (size_t i = 0; i < (size_t)nv * 3; i++) alb[i] = HL_DEFAULT_ALBEDO;
    memcpy(idx, mesh->indices, (size_t)nt * 3 * sizeof(uint32_t));

    uint32_t row = res + 1;
    for (uint32_t j = 0; j <= res; j++)
        for (uint32_t i = 0; i <= res; i++) {
            size_t v = nv + (size_t)j * row + i;
            /* The last row and column land exactly on the far edge. */
            pos[3 * v] = (float)(i == res ? x0 + side : x0 + step * i);
            pos[3 * v + 1] = y;
            pos[3 * v + 2] = (float)(j == res ? z0 + side : z0 + step * j);
            nrm[3 * v] = 0.0f;
            nrm[3 * v + 1] = 1.0f;
            nrm[3 * v + 2] = 0.0f;
            memcpy(alb + 3 * v, albedo, sizeof albedo);
        }
    /* (a, c, b) with a=(i,j), b=(i+1,j), c=(i,j+1): (c-a) x (b-a) = +Z x +X
     * = +Y, counter-clockwise seen from above. */
    size_t t = nt;
    for (uint32_t j = 0; j < res; j++)
        for (uint32_t i = 0; i < res; i++) {
            uint32_t a = nv + j * row + i, b = a + 1, c = a + row, e = c + 1;
            uint32_t *f = idx + 3 * t;
            f[0] = a; f[1] = c; f[2] = b;
            f[3] = b; f[4] = c; f[5] = e;
            t += 2;
        }

    free(mesh->positions);
    free(mesh->normals);
    free(mesh->albedo);
    free(mesh->indices);
    mesh->positions = pos;
    mesh->normals = nrm;
    mesh->albedo = alb;
    mesh->indices = idx;
    mesh->object_vertex_count = nv;
    mesh->vertex_count = (uint32_t)tv;
    mesh->triangle_count = (uint32_t)tt;
    return HL_OK;
}

float hl_mesh_query_diagonal(const hl_mesh *mesh)
{
    if (!mesh || !mesh->positions || mesh->vertex_count == 0) return 0.0f;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < mesh->vertex_count; v++)
        for (int k = 0; k < 3; k++) {
            double p = mesh->positions[3 * v + k];
            if (p < lo[k]) lo[k] = p;
            if (p > hi[k]) hi[k] = p;
        }
    double d2 = 0.0;
    for (int k = 0; k < 3; k++) d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    return (float)sqrt(d2);
}

void hl_mesh_destroy(hl_mesh *mesh)
{
    if (!mesh) return;
    free(mesh->positions);
    free(mesh->normals);
    free(mesh->albedo);
    free(mesh->indices);
    free(mesh);
}
