/* capture.h - lighting captured from the scene: the surroundings of an
 * object (triangles, each emitting a radiance or dark) seen from one point,
 * rendered straight into the dual-paraboloid lighting the relighter's
 * env2para stage writes (same layout, same meaning: three planes R, G, B
 * of 2 N^2 texels, each the mean radiance over its texel), so it can take
 * that stage's place. On the OpenCL device (kernels/capture/capture.cl)
 * or, on the reference backend, through the plain-C twin on the
 * context's threads.
 */
#ifndef HL_CAPTURE_H
#define HL_CAPTURE_H

#include "hl_internal.h"

/* Rays per side of the whole paraboloid (N S) when the caller gives S = 0:
 * S = max(1, 256 / N), so the sub-sample grid is the same at every N
 * (sub-cells at most 4 / 256 radians wide) and a capture costs
 * 2 x 256^2 rays whatever N. Measured (tests/capture, capture.energy): a
 * square light's energy within 0.24% at N = 64 (S = 4) and 128 (S = 2),
 * 1.3% at N S = 64 and 15% at N S = 16 (edges along the grid); S = 8 at
 * N = 64 gains nothing (0.24%) for 4 times the rays. */
#define HL_CAPTURE_DEFAULT_NS 256u
/* Most rays per texel side: 16 x 16 rays already resolve an edge to
 * 1/16 texel, finer than the map path's own cells (0.4 texel); the
 * default reaches it at N = 16 (and stops there at N = 8, N S = 128). */
#define HL_CAPTURE_MAX_S 16u
/* The S a capture of resolution N uses for S = 0. */
static inline uint32_t hl_capture_default_s(uint32_t N)
{
    uint32_t S = N >= HL_CAPTURE_DEFAULT_NS ? 1u : HL_CAPTURE_DEFAULT_NS / N;
    return S > HL_CAPTURE_MAX_S ? HL_CAPTURE_MAX_S : S;
}
/* Farthest a corner may lie from the capture point along an axis:
 * Moller-Trumbore's determinant is a product of three such lengths, and
 * stays finite in float (3.4e38) below 1e12 each. */
#define HL_CAPTURE_MAX_DIST 1e12
/* Candidates a texel lists (HL_CAPTURE_LIST in the kernel, 1 KiB of
 * private memory); a texel whose cone meets more traces its rays through
 * the hierarchy. */
#define HL_CAPTURE_LIST 256u
/* A texel whose tile lists more triangles than this lists none of its
 * own and traces every ray through the hierarchy: past it the listing
 * costs more than the rays it spares (measured in docs/CAPTURE.md). */
#define HL_CAPTURE_SCAN 2048u
/* Triangles a leaf of the hierarchy holds at most (but where the centres
 * cannot be told apart or the tree is HL_CAPTURE_STACK deep). */
#define HL_CAPTURE_LEAF 4u
/* Floats per texel of the cone table (two float4 in the kernel). */
#define HL_CAPTURE_CONE_FLOATS 8u
/* Tiles per side of each map: a texel looks for candidates only among its
 * tile's, which the host lists at every capture (128 tiles x triangles
 * tests; at N = 64 a tile is 8 x 8 texels, about 30 degrees). */
#define HL_CAPTURE_TILES 8u
#define HL_CAPTURE_NTILES (2u * HL_CAPTURE_TILES * HL_CAPTURE_TILES)
/* Radians added to a texel's cone (as in the kernel): more than the float
 * error of the acos of a dot product near 1 (about sqrt(2 * 2^-24) =
 * 3.5e-4), so a cull is never wrong and the hits are those of testing
 * every triangle. */
#define HL_CAPTURE_CONE_MARGIN 4e-3f
/* A texel whose cone lies inside one triangle's view by this much more
 * (radians) takes that triangle's radiance for every ray without casting
 * them, when every other candidate lies behind the triangle's plane: far
 * more than the float error of Moller-Trumbore's edge tests on a ray that
 * far inside, so the rays would have hit it. */
#define HL_CAPTURE_COVER_MARGIN 4e-3
/* "Behind the plane" allows a corner this far in front (relative to the
 * plane's distance): a neighbour sharing an edge has corners on the plane,
 * which float rounding puts either side. Only triangles within this of
 * coplanar and overlapping (z-fighting, arbitrary either way) can then
 * differ from casting the rays. */
#define HL_CAPTURE_PLANE_TOL 1e-5f

typedef struct hl_capture_scene {
    const float *positions; /* 9 per triangle: three corners, world space */
    const float *emission;  /* 3 per triangle: emitted RGB radiance, >= 0
                               (0: a dark occluder); both sides emit */
    uint32_t triangle_count;
    float center[3];        /* the capture point (the object's centre) */
    /* What the surroundings leave open: NULL for black, or a lighting map
       in the same layout (3 x 2 N^2, e.g. env2para's output for an
       environment), whose texel value lights the share of the texel's
       rays that hit nothing. */
    const float *fallback_L;
} hl_capture_scene;

typedef struct hl_capture hl_capture;

/* A capture of resolution N (a power of two, 8 to 256, as the transport's)
 * with S x S rays per texel (0: HL_CAPTURE_DEFAULT_NS / N, at least 1
 * and at most HL_CAPTURE_MAX_S), on ctx's backend. */
hl_result hl_capture_create(hl_context *ctx, uint32_t N, uint32_t S, hl_capture **out);
/* Renders scene into L (3 x 2 N^2 floats). Checks the scene first: NaN or
 * infinite positions or centre, negative or non-finite radiance, no
 * triangles, a bad fallback map. */
hl_result hl_capture_run(hl_capture *c, const hl_capture_scene *scene, float *L);
/* hl_capture_run's checks of scene for maps of ncoef texels a plane (the
 * relighter makes them where it takes the triangles, to name the file). */
hl_result hl_capture_check(hl_context *ctx, uint32_t ncoef, const hl_capture_scene *scene);
/* As hl_capture_run on the OpenCL backend, with the maps in device
 * memory (cl_mem of 3 x 2 N^2 floats): the fallback lighting from env_mem
 * (NULL: black; scene->fallback_L must be NULL), the capture into L_mem.
 * Enqueued only: the caller waits on the context's queue (a blocking read
 * or clFinish) before the next call on c, whose triangles the upload
 * reads until then. */
hl_result hl_capture_enqueue(hl_capture *c, const hl_capture_scene *scene, void *env_mem, void *L_mem);
/* What the capture holds now (host and device bytes: the triangles, the
 * hierarchy, the lists, the tables and maps) and how many triangles its
 * last run packed. */
void hl_capture_usage(const hl_capture *c, uint32_t *triangles, size_t *host_bytes, size_t *device_bytes);
void hl_capture_destroy(hl_capture *c);

/* What a texel of the capture reads, as the kernel's arguments: the
 * packed triangles (HL_CAPTURE_FLOATS each, in fours: v0 - centre,
 * v1 - v0, v2 - v0, emitted RGB, the bounding cone seen from the centre:
 * unit axis and half-angle, 4 for every direction, then its cosine and
 * sine; the plane: unit normal away from the centre and distance; the
 * three edges' planes through the centre: unit normals into the
 * triangle's view, all 0 where the triangle is seen edge-on), the texel
 * table, the tiles' lists and the hierarchy (hl_capture_accel). */
typedef struct hl_capture_tables {
    const float *tris;
    uint32_t ntris;
    const float *cones;
    const uint32_t *tile_start, *tile_list;
    const float *nodes;
    const uint32_t *links, *order;
} hl_capture_tables;

/* The twin (twins/capture.c): texel j of the map, env_L NULL for black.
 * use_cones 0 tests every triangle with every ray, no list, cover or
 * hierarchy (the test's brute force, which the others must equal). */
void hl_ref_capture_texel(const hl_capture_tables *tb, uint32_t N, uint32_t S, const float *env_L, int use_cones,
                          uint32_t j, float *L);
/* The texel table of resolution N with S x S rays a texel
 * (HL_CAPTURE_CONE_FLOATS per texel, 2 N^2 texels): the cone holding the
 * texel (the paraboloid map takes circles to circles, so the cap through
 * its farthest corner holds all of it), as unit axis, then 0 where none
 * of the texel is in the disc, 1 where some of its rays are, 2 where it
 * touches the disc but none of its rays do (a sliver of the rim); the
 * half-angle's cosine and sine (HL_CAPTURE_CONE_MARGIN added), the sine of
 * the half-angle plus HL_CAPTURE_COVER_MARGIN (2 where that passes a
 * right angle), and the half-angle. In double, rounded once. */
void hl_capture_texel_cones(uint32_t N, uint32_t S, float *cones);
/* The tiles' cones (HL_CAPTURE_CONE_FLOATS each, HL_CAPTURE_NTILES), as
 * the texels'. */
void hl_capture_tile_cones(uint32_t N, float *cones);
/* The hierarchy over the packed triangles and the tiles' candidate
 * lists, remade at every capture (capture_bvh.c). The arrays grow and are
 * kept for the next build. */
typedef struct hl_capture_accel {
    uint32_t ntris, nnodes;
    float *nodes;     /* HL_CAPTURE_NODE_FLOATS a node (hl_shared.h) */
    uint32_t *links;  /* 2 a node: (first, count) a leaf, (second child, 0) */
    uint32_t *order;  /* the leaves' triangles, ntris */
    /* tile k's candidates are tile_list[tile_start[k] .. tile_start[k + 1]),
       ascending: the triangles that can be hit by a ray of the tile's cone
       (hl_capture_meets; a tile's cone holds its texels' cones, so a
       texel's candidates are among its tile's) */
    uint32_t tile_start[HL_CAPTURE_NTILES + 1];
    uint32_t *tile_list;
    float *box;       /* scratch, 6 a triangle: its padded box */
    uint32_t room_tris;
    size_t room_list;
} hl_capture_accel;

/* Builds a's hierarchy over ntris packed triangles (boxes padded, binned
 * surface-area splits, at most HL_CAPTURE_LEAF a leaf, depth below
 * HL_CAPTURE_STACK) and the tiles' lists from tile_cones. 0: out of
 * memory (a keeps what it had). */
int hl_capture_accel_build(hl_capture_accel *a, const float *tris, uint32_t ntris, const float *tile_cones);
/* Bytes a holds (its arrays' room). */
size_t hl_capture_accel_bytes(const hl_capture_accel *a);
void hl_capture_accel_free(hl_capture_accel *a);

/* Whether packed triangle T can be hit by a ray of the cone c (a texel's
 * or a tile's, HL_CAPTURE_CONE_FLOATS): their bounding cones meet, and c
 * does not lie wholly outside one of T's edge planes (T seen edge-on has
 * normals 0: never outside). The kernel makes the same float tests. */
static inline int hl_capture_meets(const float *T, const float *c)
{
    const float *cone = T + 16, *cs = T + 20, *en = T + 28;
    /* the cones meet when the axes' angle is at most alpha + beta: their
       dot product at least cos(alpha + beta), no acos per pair */
    float dot = c[0] * cone[0] + c[1] * cone[1] + c[2] * cone[2];
    if (!(cone[3] + c[7] >= 3.14159265f || dot >= cs[0] * c[4] - cs[1] * c[5])) return 0;
    for (int k = 0; k < 3; k++)
        if (c[0] * en[4 * k] + c[1] * en[4 * k + 1] + c[2] * en[4 * k + 2] < -c[6]) return 0;
    return 1;
}
/* Packs scene's triangles into tris (HL_CAPTURE_FLOATS each) as the
 * kernel and the twin read them; the scene must have passed the checks. */
void hl_capture_pack(const hl_capture_scene *scene, float *tris);

/* Capture points for near surroundings (capture_probes.c): the
 * transport's vertices split as a k-d tree, the cell whose probe (its
 * box's centre) has the largest parallax bound first, until every bound
 * is within tol or max_probes are placed. The bound of a probe serving
 * points within rho of it, with the nearest emitting triangle at d, is
 * asin(rho / d) radians (pi / 2 where d <= rho, 0 where nothing emits):
 * how far apart a vertex and its probe may see an emitter point. Each vertex's colour is the sum over the probes listing it of
 * weight x its colour under that probe's capture; a vertex's weights sum
 * to 1 and depend only on its distances to the probes
 * ((1 - (r / (1.5 rho_k))^2)^2, normalised), so they are continuous over
 * the mesh. One probe (nothing near enough to split for, or max_probes
 * 1) is centre itself, weight 1 for every vertex, and no lists are
 * made (start, vert and weight stay NULL). */
/* Most capture points a relighter takes (hl_relighter_set_probes). */
#define HL_PROBES_MAX 256u
typedef struct hl_probe_set {
    uint32_t count;
    float *points;        /* 3 a probe */
    double *radius;       /* its cell's half-diagonal (at least 1e-6 of the largest) */
    uint32_t *start;      /* count + 1: probe k lists vert[start[k] .. start[k + 1]) */
    uint32_t *vert;
    float *weight;        /* beside vert */
    double worst_ratio;   /* the largest bound over the probes (radians) */
    double single_ratio;  /* the bound of one probe at centre serving every vertex */
} hl_probe_set;

hl_result hl_probe_set_build(hl_context *ctx, const float *pos, uint32_t V, const float centre[3], double reach,
                             const hl_capture_scene *s, uint32_t max_probes, double tol, hl_probe_set *out);
/* The farthest of the V vertices from centre (hl_probe_set_build's
 * reach; a negative reach there computes it). */
double hl_probe_reach(const float *pos, uint32_t V, const float centre[3]);
void hl_probe_set_free(hl_probe_set *p);
/* The distance from p to the nearest emitting triangle of s (infinite
 * when none emits). */
double hl_probe_nearest_emitter(const hl_capture_scene *s, const double p[3]);

#endif
