/* mesh_ops.c - the geometry algorithms behind the mesh builder: welding
 * by hashed bit patterns, the closed-and-consistent edge test and signed
 * volume that decide orientation, smooth normals, and the albedo rule
 * shared with the ground plane.
 *
 * Depends on: mesh_ops.h, hl_internal.h (errors, allocation), libc, libm.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_ops.h"

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

/* Zero albedo means the fallback; anything else must be a reflectance. */
hl_result hl_mesh_resolve_albedo_(hl_context *ctx, const char *name, const float *in, float fallback, float *outv)
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
uint32_t hl_mesh_weld_(hl_context *ctx, const weld_key *k, uint32_t n, uint32_t *remap, uint32_t *rep)
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
int hl_mesh_closed_and_consistent_(hl_context *ctx, const uint32_t *idx, uint32_t tris)
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
double hl_mesh_signed_volume_(const float *pos, const uint32_t *idx, uint32_t tris, const double *center)
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
hl_result hl_mesh_smooth_normals_(hl_context *ctx, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t tris,
                                  float *nrm)
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
        hl_tri_cross(pos + 3 * (size_t)f[0], pos + 3 * (size_t)f[1], pos + 3 * (size_t)f[2], n);
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
            hl_tri_cross(pos + 3 * (size_t)f[0], pos + 3 * (size_t)f[1], pos + 3 * (size_t)f[2], n);
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

