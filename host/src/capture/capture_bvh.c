/* capture_bvh.c - the capture's bounding-volume hierarchy over the packed
 * triangles and the tiles' candidate lists, both made on the host at
 * every capture (the surroundings move between captures) and read by the
 * kernel and its twin: a texel whose list overflows, or whose tile holds
 * too many triangles to list, and the rim's single rays, trace the
 * hierarchy (hl_capture_trace, hl_shared.h) instead of testing every
 * triangle. A flat array walked with a small stack: what OpenCL 1.2
 * kernels can traverse (no recursion, no pointers).
 * Depends on: capture.h, libm, libc (qsort).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"

/* Bins per axis of the surface-area split: 16 lose little against a full
 * sweep and keep the build linear at each level. */
#define BVH_BINS 16
/* A triangle's box is padded by this much of its largest coordinate plus
 * this much of its extent: hundreds of times the rounding of the hit
 * point Moller-Trumbore computes in float (a few ulp of the coordinates),
 * so a ray that hits the triangle enters the box, also after the box is
 * rounded to float and the slabs are computed in float. */
#define BVH_PAD_REL 1e-5
#define BVH_PAD_EXT 1e-4
/* Taken off the cosine a node's cone must reach in the tiles' listing
 * (double on the host): far more than its rounding; a loose node costs
 * only tests. */
#define BVH_COS_MARGIN 1e-9

/* min and max without libm's NaN rules (no NaN reaches here: the scene
 * was checked finite), which the compiler inlines */
#define MIN2(a, b) ((a) < (b) ? (a) : (b))
#define MAX2(a, b) ((a) > (b) ? (a) : (b))

typedef struct builder {
    hl_capture_accel *a;
    const float *cen; /* 3 a triangle: the centre of its box */
} builder;

static double area_of(const double lo[3], const double hi[3])
{
    double e[3];
    for (int k = 0; k < 3; k++) e[k] = hi[k] > lo[k] ? hi[k] - lo[k] : 0.0;
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
}

/* The node over order[lo, hi) at depth, and below it; returns its index.
 * Nodes are numbered depth first, so a node's first child follows it. */
static uint32_t build(builder *b, uint32_t lo, uint32_t hi, uint32_t depth)
{
    hl_capture_accel *a = b->a;
    const uint32_t node = a->nnodes++, n = hi - lo;
    float *nd = a->nodes + HL_CAPTURE_NODE_FLOATS * (size_t)node;
    double cmin[3] = {INFINITY, INFINITY, INFINITY}, cmax[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int k = 0; k < 3; k++) {
        nd[k] = INFINITY;
        nd[4 + k] = -INFINITY;
    }
    nd[3] = nd[7] = 0.0f;
    for (uint32_t e = lo; e < hi; e++) {
        const uint32_t i = a->order[e];
        const float *bx = a->box + 6 * (size_t)i, *c = b->cen + 3 * (size_t)i;
        for (int k = 0; k < 3; k++) {
            nd[k] = MIN2(nd[k], bx[k]);
            nd[4 + k] = MAX2(nd[4 + k], bx[3 + k]);
            cmin[k] = MIN2(cmin[k], c[k]);
            cmax[k] = MAX2(cmax[k], c[k]);
        }
    }
    uint32_t *ln = a->links + 2 * (size_t)node;
    ln[0] = lo;
    ln[1] = n;
    /* the traversal's stack holds one node a level above the leaf */
    if (n <= HL_CAPTURE_LEAF || depth + 1 >= HL_CAPTURE_STACK) return node;
    /* the cheapest split of the centres' bins, by surface area */
    int best_axis = -1, best_bin = 0;
    double best_cost = INFINITY;
    for (int ax = 0; ax < 3; ax++) {
        const double ext = cmax[ax] - cmin[ax];
        if (!(ext > 0.0) || !isfinite(ext)) continue; /* (finite: the bin index below is never NaN) */
        const double scale = BVH_BINS / ext;
        uint32_t cnt[BVH_BINS] = {0};
        double blo[BVH_BINS][3], bhi[BVH_BINS][3];
        for (int k = 0; k < BVH_BINS; k++)
            for (int q = 0; q < 3; q++) {
                blo[k][q] = INFINITY;
                bhi[k][q] = -INFINITY;
            }
        for (uint32_t e = lo; e < hi; e++) {
            const uint32_t i = a->order[e];
            int k = (int)((b->cen[3 * (size_t)i + ax] - cmin[ax]) * scale);
            k = k < 0 ? 0 : k >= BVH_BINS ? BVH_BINS - 1 : k;
            cnt[k]++;
            const float *bx = a->box + 6 * (size_t)i;
            for (int q = 0; q < 3; q++) {
                blo[k][q] = MIN2(blo[k][q], bx[q]);
                bhi[k][q] = MAX2(bhi[k][q], bx[3 + q]);
            }
        }
        /* right[k]: the bins k+1 and above */
        double rarea[BVH_BINS], rlo[3] = {INFINITY, INFINITY, INFINITY}, rhi[3] = {-INFINITY, -INFINITY, -INFINITY};
        uint32_t rcnt[BVH_BINS], rc = 0;
        for (int k = BVH_BINS - 1; k > 0; k--) {
            rc += cnt[k];
            for (int q = 0; q < 3; q++) {
                rlo[q] = MIN2(rlo[q], blo[k][q]);
                rhi[q] = MAX2(rhi[q], bhi[k][q]);
            }
            rarea[k - 1] = area_of(rlo, rhi);
            rcnt[k - 1] = rc;
        }
        double llo[3] = {INFINITY, INFINITY, INFINITY}, lhi[3] = {-INFINITY, -INFINITY, -INFINITY};
        uint32_t lc = 0;
        for (int k = 0; k < BVH_BINS - 1; k++) {
            lc += cnt[k];
            for (int q = 0; q < 3; q++) {
                llo[q] = MIN2(llo[q], blo[k][q]);
                lhi[q] = MAX2(lhi[q], bhi[k][q]);
            }
            if (lc == 0 || rcnt[k] == 0) continue;
            const double cost = lc * area_of(llo, lhi) + rcnt[k] * rarea[k];
            if (cost < best_cost) {
                best_cost = cost;
                best_axis = ax;
                best_bin = k;
            }
        }
    }
    if (best_axis < 0) return node; /* every centre the same: one leaf */
    const double scale = BVH_BINS / (cmax[best_axis] - cmin[best_axis]);
    uint32_t mid = lo;
    for (uint32_t e = lo; e < hi; e++) {
        const uint32_t i = a->order[e];
        int k = (int)((b->cen[3 * (size_t)i + best_axis] - cmin[best_axis]) * scale);
        k = k < 0 ? 0 : k >= BVH_BINS ? BVH_BINS - 1 : k;
        if (k <= best_bin) {
            a->order[e] = a->order[mid];
            a->order[mid++] = i;
        }
    }
    build(b, lo, mid, depth + 1);
    const uint32_t right = build(b, mid, hi, depth + 1);
    ln = a->links + 2 * (size_t)node; /* the same array: nothing is reallocated while building */
    ln[0] = right;
    ln[1] = 0;
    return node;
}

/* Whether a ray of the cone c (HL_CAPTURE_CONE_FLOATS: unit axis, the
 * half-angle's cosine and sine in c[4], c[5]) can enter node box nd: the
 * cone around the box's bounding sphere meets c, or the sphere holds the
 * origin. In cosines (both half-angles below a right angle, so the sum
 * is below pi), in double: far finer than the margins the tile's cone
 * and the padded boxes already carry. */
static int node_meets(const float *nd, const float *c)
{
    double m[3], r2 = 0.0, d2 = 0.0, dot = 0.0;
    for (int k = 0; k < 3; k++) {
        m[k] = 0.5 * ((double)nd[k] + nd[4 + k]);
        const double h = 0.5 * ((double)nd[4 + k] - nd[k]);
        r2 += h * h;
        d2 += m[k] * m[k];
        dot += m[k] * c[k];
    }
    if (d2 <= r2 || c[4] <= 0.0f) return 1; /* (a cone past a right angle: never pruned) */
    const double sa = sqrt(r2 / d2), ca = sqrt(1.0 - r2 / d2);
    return dot / sqrt(d2) >= ca * c[4] - sa * c[5] - BVH_COS_MARGIN;
}

static int cmp_u32(const void *x, const void *y)
{
    const uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
    return (a > b) - (a < b);
}

/* Appends v to the tile list, growing it; 0: out of memory. */
static int push_list(hl_capture_accel *a, size_t *n, uint32_t v)
{
    if (*n == a->room_list) {
        size_t room = a->room_list ? 2 * a->room_list : 1024;
        uint32_t *p = realloc(a->tile_list, room * sizeof *p);
        if (!p) return 0;
        a->tile_list = p;
        a->room_list = room;
    }
    a->tile_list[(*n)++] = v;
    return 1;
}

int hl_capture_accel_build(hl_capture_accel *a, const float *tris, uint32_t ntris, const float *tile_cones)
{
    if (ntris > a->room_tris) {
        /* at most 2 n - 1 nodes: every leaf holds a triangle */
        float *nodes = realloc(a->nodes, (size_t)2 * ntris * HL_CAPTURE_NODE_FLOATS * sizeof(float));
        if (nodes) a->nodes = nodes;
        uint32_t *links = realloc(a->links, (size_t)2 * ntris * 2 * sizeof(uint32_t));
        if (links) a->links = links;
        uint32_t *order = realloc(a->order, (size_t)ntris * sizeof(uint32_t));
        if (order) a->order = order;
        float *box = realloc(a->box, (size_t)ntris * 9 * sizeof(float)); /* and the centres after */
        if (box) a->box = box;
        if (!nodes || !links || !order || !box) return 0;
        a->room_tris = ntris;
    }
    float *cen = a->box + 6 * (size_t)ntris;
    for (uint32_t i = 0; i < ntris; i++) {
        const float *T = tris + HL_CAPTURE_FLOATS * (size_t)i;
        double lo[3], hi[3], ext = 0.0, mag = 0.0;
        for (int k = 0; k < 3; k++) {
            /* the corners as the pack rounded them */
            const double c0 = T[k], c1 = (double)T[k] + T[4 + k], c2 = (double)T[k] + T[8 + k];
            lo[k] = fmin(c0, fmin(c1, c2));
            hi[k] = fmax(c0, fmax(c1, c2));
            ext = fmax(ext, hi[k] - lo[k]);
            mag = fmax(mag, fmax(fabs(lo[k]), fabs(hi[k])));
        }
        const double pad = BVH_PAD_REL * mag + BVH_PAD_EXT * ext + 1e-30;
        float *bx = a->box + 6 * (size_t)i;
        for (int k = 0; k < 3; k++) {
            bx[k] = (float)(lo[k] - pad);
            bx[3 + k] = (float)(hi[k] + pad);
            cen[3 * (size_t)i + k] = (float)(0.5 * (lo[k] + hi[k]));
        }
        a->order[i] = i;
    }
    a->ntris = ntris;
    a->nnodes = 0;
    builder b = {a, cen};
    if (ntris) build(&b, 0, ntris, 0);
    /* each tile: the nodes its cone can enter, their triangles it meets */
    size_t n = 0;
    uint32_t stack[2 * HL_CAPTURE_STACK + 2];
    for (uint32_t k = 0; k < HL_CAPTURE_NTILES; k++) {
        const float *tc = tile_cones + HL_CAPTURE_CONE_FLOATS * (size_t)k;
        a->tile_start[k] = (uint32_t)n;
        uint32_t sp = 0;
        if (ntris) stack[sp++] = 0;
        while (sp) {
            const uint32_t node = stack[--sp];
            if (!node_meets(a->nodes + HL_CAPTURE_NODE_FLOATS * (size_t)node, tc)) continue;
            const uint32_t *ln = a->links + 2 * (size_t)node;
            if (ln[1] == 0) {
                stack[sp++] = ln[0];
                stack[sp++] = node + 1;
                continue;
            }
            for (uint32_t e = ln[0]; e < ln[0] + ln[1]; e++) {
                const uint32_t i = a->order[e];
                if (hl_capture_meets(tris + HL_CAPTURE_FLOATS * (size_t)i, tc) && !push_list(a, &n, i)) return 0;
            }
        }
        /* ascending, as a texel lists them: ties go to the lower index */
        if (n > a->tile_start[k]) /* the list may be unallocated yet: no qsort of a NULL base */
            qsort(a->tile_list + a->tile_start[k], n - a->tile_start[k], sizeof(uint32_t), cmp_u32);
    }
    a->tile_start[HL_CAPTURE_NTILES] = (uint32_t)n;
    return 1;
}

size_t hl_capture_accel_bytes(const hl_capture_accel *a)
{
    return (size_t)a->room_tris * (2 * HL_CAPTURE_NODE_FLOATS * 4 + 2 * 2 * 4 + 4 + 9 * 4) + a->room_list * 4;
}

void hl_capture_accel_free(hl_capture_accel *a)
{
    free(a->nodes);
    free(a->links);
    free(a->order);
    free(a->box);
    free(a->tile_list);
    memset(a, 0, sizeof *a);
}
