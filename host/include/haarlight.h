/* haarlight.h - public API of the haarlight relighting engine.
 *
 * Purpose: precomputed radiance transfer with nonlinear Haar wavelet
 * approximation. This header is the catalogue: context, meshes, transport
 * parameters, precomputation and transport files.
 *
 * Conventions:
 *   - Every fallible function returns hl_result and hands objects back
 *     through out-parameters. The message for the last failure is kept on
 *     the context (hl_context_last_error).
 *   - create/destroy for objects, load/save for files, query for facts.
 *     destroy(NULL) does nothing.
 *   - Descriptor structs: zero means "use the default"; each field's
 *     default is listed above the struct.
 *   - A context is not thread safe; use one per thread.
 */
#ifndef HAARLIGHT_H
#define HAARLIGHT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The functions of the shared library (libhaarlight.so); everything else
 * in it is hidden. */
#if defined(__GNUC__) && defined(HL_BUILDING_LIBRARY)
#define HL_API __attribute__((visibility("default")))
#else
#define HL_API
#endif

/* ---------------------------------------------------------------- results */

typedef enum hl_result {
    HL_OK = 0,
    HL_ERR_INVALID_ARGUMENT, /* impossible option or parameter */
    HL_ERR_OUT_OF_MEMORY,    /* host or device allocation failed */
    HL_ERR_IO,               /* file could not be opened, read or written */
    HL_ERR_FORMAT,           /* file is malformed, truncated or corrupt */
    HL_ERR_MESH,             /* mesh has invalid geometry */
    HL_ERR_OPENCL,           /* an OpenCL call or kernel build failed */
    HL_ERR_EMBREE,           /* Embree reported an error */
    HL_ERR_UNSUPPORTED,      /* valid request this build or device cannot do */
    HL_ERR_INTERRUPTED,      /* the user interrupted a long operation */
    HL_RESULT_COUNT
} hl_result;

/* Short fixed description of a result code; never NULL. */
HL_API const char *hl_result_string(hl_result r);

/* ---------------------------------------------------------------- context */

typedef enum hl_backend {
    HL_BACKEND_DEFAULT = 0, /* OpenCL */
    HL_BACKEND_OPENCL,
    HL_BACKEND_REFERENCE    /* plain-C twins of every kernel */
} hl_backend;

/* hl_context_desc fields and defaults:
 *   backend        HL_BACKEND_DEFAULT (OpenCL)
 *   cl_platform    -1: first platform with a device (index otherwise)
 *   cl_device      -1: first device of that platform (index otherwise)
 *   threads        0: one per online core (host ray casting and reference)
 *   kernel_dir     NULL: kernels embedded in the binary; else a folder that
 *                  holds the .cl files (the HL_KERNEL_DIR environment
 *                  variable has the same effect)
 *   quiet          0: progress on stderr when it is a terminal
 *   cl_properties  NULL; else extra OpenCL context properties, name/value
 *                  pairs ending in 0, added after CL_CONTEXT_PLATFORM (the
 *                  viewer passes CL_GL_CONTEXT_KHR and CL_GLX_DISPLAY_KHR
 *                  to share buffers with its OpenGL context). A device that
 *                  refuses them fails hl_context_create with the reason.
 *   device_memory  0: the device's global memory; else the most device
 *                  memory, in bytes, that the context's buffers may hold at
 *                  once (the HL_DEVICE_MEMORY environment variable, a byte
 *                  count with an optional K, M or G suffix, sets it when
 *                  this is 0). A job that needs more is refused with
 *                  HL_ERR_OUT_OF_MEMORY before the device is asked.
 */
typedef struct hl_context_desc {
    hl_backend backend;
    int cl_platform;
    int cl_device;
    int threads;
    const char *kernel_dir;
    int quiet;
    const intptr_t *cl_properties;
    uint64_t device_memory;
} hl_context_desc;

typedef struct hl_context hl_context;

/* Creates a context. With the OpenCL backend the device is opened and the
 * kernels are built here; on failure *out is NULL and, when err/err_size
 * are given, the message is copied there. */
HL_API hl_result hl_context_create(const hl_context_desc *desc, hl_context **out,
                            char *err, size_t err_size);
HL_API void hl_context_destroy(hl_context *ctx);
/* Cancellation. hl_context_cancel asks the long work running on ctx to
 * stop: the ray casting and the chunks of hl_precompute (which keeps its
 * .partial file for --resume), hl_render's pixel chunks and the viewer's
 * loop poll the flag between units of work and return
 * HL_ERR_INTERRUPTED. Work already finished is not undone, and a call
 * that does not poll (loading, relighting once) runs to its end. The flag
 * stays set for the rest of the context's life, so later long calls on
 * ctx fail at once with HL_ERR_INTERRUPTED; NULL is ignored.
 * Async-signal-safe and thread safe: it does nothing but store to a
 * lock-free atomic int in ctx (the build refuses a target where atomic_int
 * is not lock-free), so a SIGINT handler may call it, provided ctx is not
 * being destroyed meanwhile. hl_context_cancelled returns 1 once the
 * context was cancelled, else 0 (also for NULL). */
HL_API void hl_context_cancel(hl_context *ctx);
HL_API int hl_context_cancelled(const hl_context *ctx);
/* Reads a byte count: digits with an optional K, M or G suffix (powers of
 * 1024). Returns 1 and sets *out when the whole string is one, at least 1
 * and below 2^63; 0 otherwise. */
HL_API int hl_parse_bytes(const char *s, uint64_t *out);
/* Message of the last failure on this context ("" when none). */
HL_API const char *hl_context_last_error(const hl_context *ctx);
/* Human-readable name of the compute device ("reference (plain C)" or the
 * OpenCL platform and device names). */
HL_API const char *hl_context_device_name(const hl_context *ctx);
HL_API hl_backend hl_context_backend(const hl_context *ctx);
/* 1 when the context's OpenCL device lists the extension (e.g.
 * "cl_khr_gl_sharing"); 0 otherwise and on the reference backend. */
HL_API int hl_context_device_has_extension(const hl_context *ctx, const char *name);
HL_API int hl_context_threads(const hl_context *ctx);
/* Turns the context's notes and progress on stderr off (1) or on (0). */
HL_API void hl_context_set_quiet(hl_context *ctx, int quiet);
HL_API int hl_context_quiet(const hl_context *ctx);

/* Prints the OpenCL platforms and devices to the given FILE* (void* to keep
 * stdio out of this header). Works without a context. */
HL_API hl_result hl_list_devices(void *file, char *err, size_t err_size);

/* ---------------------------------------------------------------- meshes */

/* A triangle mesh as the engine uses it: welded, with one smooth normal and
 * one albedo per vertex. Arrays are owned by the mesh. Vertices in
 * [object_vertex_count, vertex_count) belong to the added ground plane. */
typedef struct hl_mesh {
    uint32_t vertex_count;
    uint32_t triangle_count;
    uint32_t object_vertex_count;
    float *positions; /* 3 * vertex_count */
    float *normals;   /* 3 * vertex_count, unit length */
    float *albedo;    /* 3 * vertex_count, linear RGB */
    uint32_t *indices;/* 3 * triangle_count */
} hl_mesh;

/* hl_mesh_load_desc fields and defaults:
 *   albedo        {0,0,0}: 0.8 grey; used where the file gives none: no
 *                 material base colour or texture, no vertex colours.
 *                 A file's albedo is its material's base-colour factor
 *                 times its base-colour texture (averaged around each
 *                 vertex, in linear light) times its vertex colours
 *                 (docs/MATERIALS.md)
 *   up_axis       0 or 'y': file is +Y up; 'z': file is +Z up (rotated so
 *                 that +Z becomes +Y)
 *   keep_winding  0: a closed mesh whose winding points inward is flipped;
 *                 1: never flip
 */
typedef struct hl_mesh_load_desc {
    float albedo[3];
    int up_axis;
    int keep_winding;
} hl_mesh_load_desc;

/* What loading did to the file's mesh. */
typedef struct hl_mesh_stats {
    uint32_t file_vertices;       /* vertices as the importer gave them */
    uint32_t file_triangles;
    uint32_t merged_vertices;     /* removed by welding equal positions */
    uint32_t unreferenced_vertices;
    uint32_t degenerate_triangles;/* dropped: repeated index or zero area */
    int had_normals;              /* 1 if the file's normals were used */
    int had_colors;               /* 1 if vertex colours went into the albedo */
    int flipped;                  /* 1 if the winding was reversed */
} hl_mesh_stats;

/* Loads OBJ, PLY, glTF and anything else the importer reads. Errors name
 * the file and the problem (HL_ERR_IO, HL_ERR_FORMAT, HL_ERR_MESH). */
HL_API hl_result hl_mesh_load(hl_context *ctx, const char *path,
                       const hl_mesh_load_desc *desc, hl_mesh **out,
                       hl_mesh_stats *stats);

/* Builds a mesh from arrays (copied). normals may be NULL (computed),
 * albedo may be NULL (constant). Validates like hl_mesh_load. */
HL_API hl_result hl_mesh_create(hl_context *ctx, uint32_t vertex_count,
                         const float *positions, const float *normals,
                         const float *albedo, uint32_t triangle_count,
                         const uint32_t *indices, hl_mesh **out);

/* hl_ground_desc fields and defaults:
 *   resolution    0: 96 quads across the uniform middle square (below)
 *   margin        how far the plane extends beyond the footprint on every
 *                 side, in units of the footprint's larger extent (at most
 *                 64). 0: far enough to hold the shadow of the object's
 *                 top under a light 15 degrees above the horizon (height /
 *                 tan 15 degrees), and at least 0.75. The grid is uniform
 *                 out to 0.75 (resolution quads across that square) and
 *                 graded beyond it, each cell 1.25 x the one before
 *   albedo        {0,0,0}: grey, the object's mean albedo (over its
 *                 vertices and the three channels)
 */
typedef struct hl_ground_desc {
    uint32_t resolution;
    float margin;
    float albedo[3];
} hl_ground_desc;

/* Appends a finely tessellated ground plane, +Y normal, at the mesh's lowest
 * point, sized to its footprint and height. */
HL_API hl_result hl_mesh_add_ground(hl_context *ctx, hl_mesh *mesh,
                             const hl_ground_desc *desc);

/* Length of the bounding-box diagonal (scale for ray offsets). */
HL_API float hl_mesh_query_diagonal(const hl_mesh *mesh);

HL_API void hl_mesh_destroy(hl_mesh *mesh);

/* ---------------------------------------------------------------- transport */

/* Truncation rules (hl_precompute_desc.rule). The library and its kernels
 * share these values with host/src/core/hl_shared.h, which repeats them
 * for the OpenCL programs; host/src/tools/public_pins.c asserts that the
 * two agree. */
#define HL_TRUNC_DEFAULT 0u
#define HL_TRUNC_ALL 1u    /* keep every non-zero coefficient */
#define HL_TRUNC_TOPK 2u   /* keep the K largest |T_i| */
#define HL_TRUNC_ENERGY 3u /* keep the fewest holding (1 - eps) of the energy,
                              at most K when K > 0 */

/* Quantisation schemes for the 8-bit stored value (hl_precompute_desc.quant). */
#define HL_QUANT_DEFAULT 0u
#define HL_QUANT_LINEAR8 1u /* linear between the row's min and max kept value */
#define HL_QUANT_LOG8 2u    /* sign bit + 7-bit log magnitude */
#define HL_QUANT_SQRT8 3u   /* sign bit + 7 bits uniform in sqrt(|v| / max kept |v|)
                               (the default) */
#define HL_QUANT_MAX 3u

/* Selection of the lighting terms (hl_relight_desc.select): priority of
 * coefficient i is |Y_i| times a weight, Y the luminance coefficient. */
#define HL_SELECT_DEFAULT 0u
#define HL_SELECT_AREA 1u        /* weight: solid angle of i's support */
#define HL_SELECT_UNWEIGHTED 2u  /* weight 1 */
#define HL_SELECT_TRANSPORT 3u   /* weight: mean |T_i| over the vertices */

/* Per-vertex dequantisation parameters: a layout private to the library
 * and its kernels (hl_shared.h), opaque here. */
struct hl_row_quant;

/* hl_precompute_desc fields and defaults:
 *   N             0: 64 (paraboloid map side, power of two, 8..256)
 *   C             0: 64 (cubemap face side, 4..512)
 *   supersample   0: 1 ray per cube texel (S gives S x S rays, S <= 15)
 *   rule          HL_TRUNC_DEFAULT: energy rule
 *   K             0: no cap (top-K rule: required, >= 1 unless keep none)
 *   eps           0: 1e-5 of the row's energy may be dropped (energy rule)
 *   quant         HL_QUANT_DEFAULT: the scheme the bench measured best
 *   ray_offset    0: robust: each vertex's ray origin moves along its normal
 *                 by 2^-16 of the larger of its largest coordinate
 *                 magnitude and its longest edge; else a fraction of the
 *                 bounding-box diagonal, in (0, 0.1)
 *   chunk         0: 1024 vertices per chunk
 *   resume        0: start afresh; 1: continue from out_path + ".partial",
 *                 which an interrupted run leaves (same parameters and mesh
 *                 required; the result is the same bytes as an unbroken run)
 */
typedef struct hl_precompute_desc {
    uint32_t N;
    uint32_t C;
    uint32_t supersample;
    uint32_t rule;
    uint32_t K;
    float eps;
    uint32_t quant;
    float ray_offset;
    uint32_t chunk;
    int resume;
    uint32_t basis;    /* HL_TRANSPORT_BASIS_*: 0 the paraboloid Haar */
    uint32_t sh_order; /* spherical harmonics: order L (bands 0..L-1); 0: 20 */
    uint32_t cube_side; /* cube-face Haar: the faces' side C' (a power of two,
                           6 C'^2 <= 2 N^2, dividing C); 0: the largest such */
    uint32_t bounces;     /* diffuse interreflection bounces (0 to HL_MAX_BOUNCES;
                             0: direct light, the file's bytes as before) */
    uint32_t bounce_rays; /* rays per vertex of each bounce's gather (0: 256) */
    uint32_t bounce_terms;/* most terms of a hit vertex's row the gather reads,
                             the largest kept (0: 512; HL_TERMS_ALL: every one) */
    const char *direct_rows; /* with bounces: start them from this finished
                                direct transport (of the same mesh and options,
                                e.g. merged from shards) instead of casting the
                                direct rays; needed to shard the bounces */
    int keep_floats;      /* also write out_path + ".values", the kept terms
                             as floats, for a later direct_rows: the bounces
                             then start from them, not from the 8-bit codes */
} hl_precompute_desc;

/* Counters and timings of one precompute. */
typedef struct hl_precompute_stats {
    uint64_t rays_cast;       /* occlusion rays traced (by this run, when resumed) */
    uint64_t rays_culled;     /* directions skipped: below the horizon (same) */
    uint64_t coefficients_kept;
    double seconds_rays;      /* wall time inside ray casting */
    double seconds_kernels;   /* wall time waiting for the kernel stages */
    double seconds_total;
    double seconds_bounces;   /* --bounces: the bounce phase (within the total) */
} hl_precompute_stats;

/* The basis of a transport's rows (hl_transport_info.basis). Haar: the
 * paraboloid wavelets in the 2 N^2 slots. SH: real spherical harmonics up
 * to order L (k = l^2 + l + m in slot k, slots from L^2 on empty), the
 * relighter projecting the lighting alike (host/FORMAT.md). */
#define HL_TRANSPORT_BASIS_HAAR 0u
#define HL_TRANSPORT_BASIS_SH 1u
/* Cube-face Haar (the 2003 paper's layout): each of the six faces of side
 * C' in the orthonormal non-standard Haar, coefficient face C'^2 + Mallat
 * position in slot k, slots from 6 C'^2 on empty; sh_order holds C'. */
#define HL_TRANSPORT_BASIS_CUBE 2u
#define HL_DEFAULT_SH_ORDER 20u

/* Most interreflection bounces a precompute bakes. */
#define HL_MAX_BOUNCES 16u
#define HL_DEFAULT_BOUNCE_RAYS 256u
#define HL_DEFAULT_BOUNCE_TERMS 512u /* docs/BOUNCES.md: 256 left the Stanford bunny above 2% under studio and the sky */

/* The transport file format version this build writes and reads. */
#define HL_TRANSPORT_VERSION 2u

/* Header of a transport file: every parameter and count. See
 * docs in host/FORMAT.md. */
typedef struct hl_transport_info {
    uint32_t version;
    uint32_t N, C, supersample;
    uint32_t rule, K;
    float eps;
    uint32_t quant;
    float ray_offset;             /* relative to the diagonal */
    uint32_t vertex_count;
    uint32_t object_vertex_count;
    uint32_t triangle_count;
    uint32_t block_count;         /* per vertex: ceil(2 N^2 / 256) */
    uint64_t coefficients_kept;   /* total non-zeros stored */
    uint64_t rays_cast;
    uint64_t rays_culled;
    uint32_t basis;               /* HL_TRANSPORT_BASIS_* */
    uint32_t sh_order;            /* spherical harmonics: L, slots 0..L^2-1; cube-face
                                     Haar: the faces' side C', slots 0..6 C'^2-1; else 0 */
    uint32_t bounces;             /* diffuse interreflection bounces baked into the
                                     rows (precompute --bounces), with the albedo of
                                     the file's mesh; 0: direct light only */
    uint32_t channels;            /* rows a vertex: 1 (0 taken as 1), one row for
                                     R, G and B; 3, bounces off coloured surfaces:
                                     a plane of V rows per channel, R's, then G's,
                                     then B's (docs/BOUNCES.md) */
} hl_transport_info;

/* A transport file in memory. Row v's entries are
 * entries[2*row_offset[v] .. 2*row_offset[v+1]), in pairs (index in block,
 * quantised value), ordered by block then index; block_counts[v*block_count
 * + b] says how many belong to block b. There are R = vertex_count x
 * channels rows: row c V + v is vertex v's for channel c when channels is 3
 * (hl_transport_rows). */
typedef struct hl_transport {
    hl_transport_info info;
    hl_mesh *mesh;
    struct hl_row_quant *row_quant; /* R */
    uint16_t *block_counts;    /* R * block_count */
    uint64_t *row_offset;      /* R + 1, derived on load */
    uint8_t *entries;          /* 2 * coefficients_kept */
} hl_transport;

/* The rows of a transport: vertex_count, or 3 vertex_count for coloured
 * bounces (channels 3). */
static inline uint32_t hl_transport_rows(const hl_transport_info *i)
{
    return i->vertex_count * (i->channels == 3 ? 3u : 1u);
}

/* Runs the whole precomputation on the context's device and writes the
 * transport file atomically: rows go to out_path + ".partial", renamed onto
 * out_path when complete. An interrupted run (HL_ERR_INTERRUPTED) keeps the
 * partial file for desc->resume; any other failure removes it. The mesh
 * must already carry any ground plane. stats may be NULL. */
HL_API hl_result hl_precompute(hl_context *ctx, const hl_mesh *mesh,
                        const hl_precompute_desc *desc, const char *out_path,
                        hl_precompute_stats *stats);

/* Reads a transport file; every size is bounded before allocation and
 * every section's checksum is verified. */
HL_API hl_result hl_transport_load(hl_context *ctx, const char *path,
                            hl_transport **out);
HL_API void hl_transport_destroy(hl_transport *t);

/* Dequantises row v's kept coefficients into a dense row of 2 N^2
 * floats (zero elsewhere): vertex v's, or with channels 3, v < 3
 * vertex_count, vertex v mod vertex_count's for channel v / vertex_count. */
HL_API void hl_transport_query_row(const hl_transport *t, uint32_t v, float *dense);

/* The same row as the dot products add it (both backends): each term
 * dequantised, then rounded to half precision at a per-row power-of-two
 * scale (within 2^-11 of the term, or 2^-24 of the row's largest
 * magnitude), and scaled back. */
HL_API void hl_transport_query_terms(const hl_transport *t, uint32_t v, float *dense);

/* ---------------------------------------------------------------- environments */

/* An equirectangular environment: linear RGB radiance, width x height
 * pixels (height = width / 2), row 0 = +Y, read exactly as docs/CONVENTIONS.md says:
 * direction w -> u = 0.5 + atan2(w.z, w.x) / 2pi, v = acos(w.y) / pi. */
typedef struct hl_env {
    uint32_t width, height;
    float *rgb; /* 3 * width * height, row-major, never NaN, Inf or < 0 */
} hl_env;

/* The largest radiance an environment may hold. The transforms sum and
 * scale it (a Haar coefficient reaches N times a texel, up to 256x), so
 * far larger values would overflow float; maps with a channel above this
 * are refused (HL_ERR_FORMAT) rather than relit to Inf or NaN. */
#define HL_MAX_RADIANCE 1e30f

/* What loading repaired. */
typedef struct hl_env_stats {
    uint64_t nonfinite_pixels; /* pixels with a NaN or Inf channel, set to 0 */
    uint64_t negative_pixels;  /* pixels with a channel < 0, clamped to 0 */
} hl_env_stats;

/* Reads an environment map: a Radiance .hdr (RGBE, run-length or flat,
 * the header's EXPOSURE divided out; decoded by stb_image behind the
 * project's own header and truncation checks, see host/src/io/hdr_io.c),
 * or else an OpenEXR (any compression the OpenEXR library reads, DWAB
 * included; float channels at full precision where OpenEXRCore decodes
 * the file, see host/src/io/exr_io.c). The layout comes from the size:
 * 2:1 equirectangular, 1:1 angular map, 4:3 or 3:4 cube cross (the last
 * three resampled to equirectangular, see hl_env_load_layout); other
 * sizes are refused. So are maps that hold a channel above
 * HL_MAX_RADIANCE, and tiled or multi-part float files with a value that
 * half floats cannot hold (HL_ERR_FORMAT). NaN/Inf channels are set to 0
 * and negative ones clamped, and stats says how many pixels were
 * affected. Errors name the file. */
HL_API hl_result hl_env_load(hl_context *ctx, const char *path, hl_env **out, hl_env_stats *stats);

/* How a map file lays out the sphere (docs/CONVENTIONS.md, "Map layouts";
 * every layout is resampled onto the equirectangular grid on loading). */
typedef enum hl_env_layout {
    HL_LAYOUT_AUTO = 0,   /* from the size: 2:1, 1:1, 4:3 or 3:4 */
    HL_LAYOUT_EQUIRECT,   /* latitude-longitude, 2:1 */
    HL_LAYOUT_ANGULAR,    /* Debevec's angular light probe, 1:1 */
    HL_LAYOUT_CROSS_H,    /* horizontal cube cross, 4:3 */
    HL_LAYOUT_CROSS_V     /* vertical cube cross, 3:4 */
} hl_env_layout;

/* hl_env_load with the layout given (HL_LAYOUT_AUTO: hl_env_load's
 * choice by size). A file whose size is not its layout's is refused
 * (HL_ERR_FORMAT, naming the file and the sizes each layout takes). */
HL_API hl_result hl_env_load_layout(hl_context *ctx, const char *path, hl_env_layout layout, hl_env **out,
                             hl_env_stats *stats);

/* hl_sky_desc fields and defaults (a procedural sun and sky):
 *   sun_elevation_deg  0: 35 degrees above the horizon (use -90..90;
 *                      exactly 0 means the default, pass 1e-3 for the horizon)
 *   sun_azimuth_deg    0: sun towards +X rotated by this about +Y (as
 *                      --rotate turns an environment)
 *   sun_size_deg       0: 2 degrees angular diameter
 *   sun_irradiance     0: 8 (irradiance from the sun on a surface facing it,
 *                      against pi for a white sky of radiance 1: a real HDR
 *                      case, the disc is thousands of times the sky)
 *   sky_zenith / sky_horizon  {0,0,0}: a blue zenith fading to a pale
 *                      horizon (linear RGB radiance)
 *   ground             {0,0,0}: dark grey-brown below the horizon
 *   width              0: 1024 (height = width / 2)
 */
typedef struct hl_sky_desc {
    float sun_elevation_deg;
    float sun_azimuth_deg;
    float sun_size_deg;
    float sun_irradiance;
    float sky_zenith[3];
    float sky_horizon[3];
    float ground[3];
    uint32_t width;
} hl_sky_desc;

HL_API hl_result hl_env_create_sky(hl_context *ctx, const hl_sky_desc *desc, hl_env **out);

/* Builds an environment from a copy of rgb (3 * width * height floats),
 * repairing like hl_env_load. width must be 2 * height, height >= 1. */
HL_API hl_result hl_env_create(hl_context *ctx, uint32_t width, uint32_t height, const float *rgb,
                        hl_env **out, hl_env_stats *stats);

/* Radiance seen in direction w (need not be unit) with the content turned
 * by rotate_deg about +Y (docs/CONVENTIONS.md): nearest pixel. */
HL_API void hl_env_query(const hl_env *env, const float w[3], float rotate_deg, float rgb[3]);
/* The same, bilinear between pixel centres (for display). */
HL_API void hl_env_query_smooth(const hl_env *env, const float w[3], float rotate_deg, float rgb[3]);

HL_API void hl_env_destroy(hl_env *env);

/* ---------------------------------------------------------------- relighting */

/* Relights a transport under environments: environment to paraboloid
 * (with rotation), Haar, selection of the M most important lighting terms,
 * and the sparse dot products, on the context's device. Holds the
 * transport on the device; one per transport. Not thread safe. */
typedef struct hl_relighter hl_relighter;

/* hl_relight_desc fields and defaults:
 *   terms       0: 200 lighting terms; HL_TERMS_ALL keeps every one
 *   select      HL_SELECT_DEFAULT: transport-weighted (HL_SELECT_TRANSPORT)
 *   rotate_deg  0: the environment as stored (docs/CONVENTIONS.md's --rotate)
 *   keep_negative  0: each colour channel is clamped at zero (truncated
 *               lighting and transport can sum to slightly below zero
 *               where the exact answer is dark); 1: the sums as they are,
 *               for measuring what the clamp changes
 */
#define HL_TERMS_ALL 0xffffffffu
typedef struct hl_relight_desc {
    uint32_t terms;
    uint32_t select;
    float rotate_deg;
    int keep_negative;
} hl_relight_desc;

typedef struct hl_relight_stats {
    uint32_t terms_kept;          /* lighting terms actually kept */
    double energy_kept;           /* fraction of the lighting's (luminance)
                                     wavelet energy the kept terms hold */
    double error_bound;           /* |B - B_M| <= this for every vertex and
                                     albedo 1 (Cauchy-Schwarz: max over
                                     vertices of |T_v| times |L - L_M|),
                                     in luminance units of radiance */
    double blocks_skipped;        /* fraction of 256-blocks whose detail
                                     slots keep no lighting term (the dot
                                     products skip every slot not kept) */
    int negative_counted;         /* 1: the next two were measured (not
                                     for colours written into a device
                                     buffer, which are not read back) */
    uint32_t negative_vertices;   /* vertices with a channel below zero
                                     before the clamp */
    double most_negative;         /* the lowest channel before the clamp,
                                     over the brightest channel of all
                                     vertices (<= 0) */
    double seconds;               /* wall time of this lighting change */
    int reused;                   /* 1: nothing changed, no work was done */
    uint32_t probes;              /* surroundings: the capture points used
                                     (hl_relighter_set_probes); 0 without */
    double parallax;              /* surroundings: the bound of how far (in
                                     radians) an emitter may lie from where
                                     a vertex's capture point sees it:
                                     asin(r / d), r the farthest a vertex
                                     a point serves may be, d the point's
                                     nearest emitter; pi / 2 (no bound)
                                     where d <= r */
} hl_relight_stats;

HL_API hl_result hl_relighter_create(hl_context *ctx, const hl_transport *t, hl_relighter **out);
/* Takes a new environment (resampled once here; rotations are cheap). The
 * environment is copied, the caller keeps ownership. */
HL_API hl_result hl_relighter_set_env(hl_relighter *r, const hl_env *env);
/* Vertex colours (3 floats per vertex: outgoing radiance, albedo
 * included) for the current environment. Repeating the same settings
 * does no work (stats->reused). */
HL_API hl_result hl_relighter_run(hl_relighter *r, const hl_relight_desc *desc, float *vertex_rgb,
                           hl_relight_stats *stats);
HL_API void hl_relighter_destroy(hl_relighter *r);

/* ---------------------------------------------------- captured lighting */

/* Surroundings: triangles around the object that give light (an emissive
 * material) or hide what lies behind them (no emission: dark). The
 * relighter renders them, as seen from the object's centre, into its
 * paraboloid lighting at every lighting change (kernels/capture), in
 * place of the environment where they cover it; the environment (or
 * black, with none set) lights what they leave open.
 * Limit: the capture is from one point, so surroundings close to a large
 * object light all of it as if from its centre. */
typedef struct hl_surroundings hl_surroundings;

/* Loads any file assimp reads. Each triangle's emitted radiance is its
 * material's emissive colour times its emissive strength (glTF's
 * KHR_materials_emissive_strength; 1 without it); every node that holds
 * triangles is a rigid body, named as in the file, moved by the file's
 * first node animation (as hl_dynamic_create_from_file). Errors name the
 * file (HL_ERR_IO, HL_ERR_FORMAT, HL_ERR_MESH): no triangles, non-finite
 * positions, negative or non-finite emission. Any number of triangles:
 * the capture's memory and time grow with them (docs/CAPTURE.md). */
HL_API hl_result hl_surroundings_load(hl_context *ctx, const char *path, hl_surroundings **out);
/* From arrays (copied): one body "surroundings", no animation.
 * positions: 9 floats per triangle (three corners); emission: 3 per
 * triangle (RGB radiance, >= 0; both sides emit). */
HL_API hl_result hl_surroundings_create(hl_context *ctx, const float *positions, const float *emission,
                                        uint32_t triangle_count, hl_surroundings **out);
HL_API void hl_surroundings_destroy(hl_surroundings *s);

HL_API uint32_t hl_surroundings_triangle_count(const hl_surroundings *s);
/* Bodies, their names (NULL out of range), whether a body emits, and the
 * animation's time range in seconds (both 0 without one). */
HL_API uint32_t hl_surroundings_body_count(const hl_surroundings *s);
HL_API const char *hl_surroundings_body_name(const hl_surroundings *s, uint32_t body);
HL_API int hl_surroundings_body_emits(const hl_surroundings *s, uint32_t body);
HL_API void hl_surroundings_time_range(const hl_surroundings *s, double *start, double *end);

/* Poses the surroundings at time t (seconds, finite, >= 0; clamped to the
 * animation's keys) and gives body its program transform xf (row-major
 * 3x4 [R | t], rigid as hl_dynamic_set_transform asks, applied after the
 * animation, replacing an earlier one). */
HL_API hl_result hl_surroundings_set_time(hl_surroundings *s, double t);
HL_API hl_result hl_surroundings_set_transform(hl_surroundings *s, uint32_t body, const float xf[12]);
/* Places the whole file in the scene, as a root node over it would:
 * x -> shift + scale Ry(yaw_deg) x, the turn about +Y (+X towards -Z for
 * a positive angle), after the file's own nodes and animation and before
 * the bodies' program transforms. scale finite and > 0, the others
 * finite, else HL_ERR_INVALID_ARGUMENT naming the bad value; replaces an
 * earlier placement (default: none). */
HL_API hl_result hl_surroundings_set_placement(hl_surroundings *s, const float shift[3], float scale, float yaw_deg);
/* The triangles in world space at the current time and transforms:
 * 9 floats per triangle and 3 of emission, owned by s, valid until the
 * next call on s. */
HL_API hl_result hl_surroundings_triangles(hl_surroundings *s, const float **positions, const float **emission);

/* Lights the relighter from s (NULL: the environment alone again). s is
 * read at every hl_relighter_run and must outlive its use; a run in which
 * the triangles (as hl_surroundings_triangles gives them) and the
 * environment are unchanged since the last run costs nothing
 * (stats->reused). The environment is optional with surroundings (none:
 * black where they leave the sphere open); rotate_deg turns the
 * environment only. The capture point is the centre of the bounding box
 * of the transport's object (its ground left out). */
HL_API hl_result hl_relighter_set_surroundings(hl_relighter *r, hl_surroundings *s);
/* Near surroundings seen from more than one point: up to max_probes
 * capture points (1 to 256; 1, the default, is the one capture point
 * above), placed over the transport's vertices where an emitter is near,
 * until every point's parallax bound (hl_relight_stats.parallax) is at
 * most tol radians (0: 2 / N, about a paraboloid texel). Each run then
 * captures and relights once a point and blends each vertex's colours
 * smoothly over the points near it (docs/CAPTURE.md): the cost is the
 * points' count times a run's. The points follow the surroundings as
 * they move. */
HL_API hl_result hl_relighter_set_probes(hl_relighter *r, uint32_t max_probes, double tol);

/* ---------------------------------------------------------------- images */

typedef struct hl_image {
    uint32_t width, height;
    float *rgb; /* 3 * width * height, linear, row 0 at the top */
} hl_image;

HL_API hl_result hl_image_create(hl_context *ctx, uint32_t width, uint32_t height, hl_image **out);
HL_API void hl_image_destroy(hl_image *img);

/* Writes by extension: .exr linear 32-bit float RGB (ZIP), .png 8-bit
 * tone-mapped (scale by 2^exposure_ev, then the sRGB transfer curve).
 * Atomic: written to a temporary name and renamed. */
HL_API hl_result hl_image_save(hl_context *ctx, const hl_image *img, const char *path, float exposure_ev);

/* Linear radiance to an 8-bit sRGB code after scaling by 2^exposure_ev. */
HL_API uint8_t hl_tonemap_srgb8(float linear, float exposure_ev);

/* ---------------------------------------------------------------- rendering */

/* hl_camera_desc fields and defaults:
 *   width, height    0: 960 x 720
 *   fov_deg          0: 35 degrees vertical
 *   eye, target      all zero: framed automatically: looking at the object's
 *                    bounding-box centre from the front (+Z side), a little
 *                    above, far enough that the whole object (ground plane
 *                    excluded) fits with a margin
 *   up               {0,0,0}: +Y
 *   nearest_background  0: the environment behind the object is filtered
 *                    bilinearly; 1: nearest pixel (exact map values)
 */
typedef struct hl_camera_desc {
    uint32_t width, height;
    float fov_deg;
    float eye[3], target[3], up[3];
    int nearest_background;
} hl_camera_desc;

/* Renders the mesh with per-vertex linear RGB colours (3 per vertex),
 * interpolated with barycentrics, from Embree primary rays; pixels that
 * miss show the environment (may be NULL: black) turned by rotate_deg. */
HL_API hl_result hl_render(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                    const hl_env *background, float rotate_deg, const hl_camera_desc *camera,
                    hl_image **out);

/* A mesh's textured surface: the base-colour textures of the file the
 * mesh was loaded from, and each triangle's texture coordinates, so that
 * pictures shade each pixel with the texture's albedo there
 * (docs/MATERIALS.md). */
typedef struct hl_surface hl_surface;

/* Loads path again with desc (as the mesh was loaded or precomputed: the
 * same keep_winding) and keeps its textured surface. mesh's object (its
 * vertices and triangles before any ground) must have the file's mesh's
 * triangles, corner for corner, wherever they lie: otherwise
 * HL_ERR_INVALID_ARGUMENT naming path. A
 * file without textures gives a surface without any
 * (hl_surface_texture_count 0), which pictures the vertex colours. */
HL_API hl_result hl_surface_load(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc,
                                 const hl_mesh *mesh, hl_surface **out);
HL_API uint32_t hl_surface_texture_count(const hl_surface *surface);
/* The surface's triangles (the first of the mesh's, or all of a dynamic
 * mesh's, ground included; 0 for NULL), and triangle t's texture (-1:
 * none; uv and base then hold zeros and the untextured base), its
 * corners' texture coordinates (u, v, v up) and base colours (the
 * material's factor x the vertex colour, linear); uv and base may be
 * NULL. HL_ERR_INVALID_ARGUMENT out of range. */
HL_API uint32_t hl_surface_triangle_count(const hl_surface *surface);
HL_API hl_result hl_surface_triangle(const hl_surface *surface, uint32_t t, int32_t *texture, float uv[6],
                                     float base[9]);
/* Texture k's pixels: width x height x 3 bytes, sRGB-encoded, row 0 at the
 * top (v = 1); NULL out of range. Owned by the surface. */
HL_API const uint8_t *hl_surface_texture(const hl_surface *surface, uint32_t k, uint32_t *width, uint32_t *height);
HL_API void hl_surface_destroy(hl_surface *surface);

/* hl_render with a textured surface (NULL: exactly hl_render): a pixel
 * of a textured triangle shows the albedo there (the base colour times
 * the texture at the pixel's texture coordinates) times the irradiance
 * interpolated from the vertices (vertex_rgb over the vertex's albedo).
 * Other triangles, and the ground, show the interpolated colours. */
HL_API hl_result hl_render_surface(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                                   const hl_surface *surface, const hl_env *background, float rotate_deg,
                                   const hl_camera_desc *camera, hl_image **out);

/* Writes the mesh as binary PLY with per-vertex colours: float red, green,
 * blue (linear radiance) by default, or 8-bit tone-mapped uchar colours
 * when tonemapped8 is set (exposure_ev then applies). Atomic. */
HL_API hl_result hl_mesh_save_ply(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                           const char *path, int tonemapped8, float exposure_ev);

/* Writes the mesh as binary glTF 2.0 (.glb) through assimp's exporter:
 * positions, normals, COLOR_0 the linear colours (alpha 1) and COLOR_1
 * the same tone-mapped for display (2^exposure_ev, then the sRGB curve, in
 * [0, 1]). Colours must be finite and >= 0. Atomic. */
HL_API hl_result hl_mesh_save_glb(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb, const char *path,
                           float exposure_ev);
/* The same keeping a textured surface's textures (hl_surface_load; NULL:
 * exactly hl_mesh_save_glb): the textured triangles become primitives
 * with unlit materials whose base-colour texture is the file's own PNG
 * or JPEG, embedded, and whose COLOR_0 is the base colour times the
 * irradiance, so that any glTF viewer's base colour x texture x COLOR_0
 * is the relit radiance at each pixel (docs/MATERIALS.md). */
HL_API hl_result hl_mesh_save_glb_surface(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                                          const hl_surface *surface, const char *path, float exposure_ev);

/* ---------------------------------------------------------------- viewer support
 *
 * What the interactive viewer (viewer/, `haarlight view`) needs so that it
 * shows exactly what hl_render and `haarlight relight` produce.
 */

/* The pinhole camera that hl_render uses for (mesh, desc), automatic
 * framing included: the eye, the point looked at, a right-handed unit
 * basis (right = forward x up), and the tangents of half the vertical and
 * horizontal fields of view. Pixel (x, y), row 0 at the top, is seen along
 * forward + sx tan_half_x right + sy tan_half_y up with
 * sx = 2 (x + 0.5) / width - 1 and sy = 1 - 2 (y + 0.5) / height. */
typedef struct hl_camera_view {
    uint32_t width, height;
    float eye[3], target[3];
    float forward[3], right[3], up[3];
    float tan_half_y, tan_half_x;
} hl_camera_view;

/* Fails like hl_render on an impossible camera (HL_ERR_INVALID_ARGUMENT). */
HL_API hl_result hl_camera_query_view(hl_context *ctx, const hl_mesh *mesh, const hl_camera_desc *desc,
                               hl_camera_view *out);

/* The automatic exposure of `haarlight relight` (EV, in [-64, 64]): puts the
 * 90th percentile of the object's vertex luminance at 0.8: vertices
 * [0, object_vertex_count), the ground left out (every vertex when the
 * mesh has no ground), so that a ground that outnumbers the object, lit
 * or shadowed, does not set it; 0 when those colours are all black or
 * memory runs out. */
HL_API float hl_exposure_auto(const hl_mesh *mesh, const float *vertex_rgb);


/* ---------------------------------------------------------------- dynamic scenes
 *
 * The second relighting method (Annen et al., SIGGRAPH 2008): no
 * precompute, so bodies may move between frames. The environment is split
 * into area lights; the K strongest each get an orthographic shadow map
 * filtered as a moment shadow map (the default) or a convolution shadow
 * map (order M), whose width follows the average blocker depth; the
 * rest are folded into one unshadowed spherical-harmonic term. Each
 * vertex is shaded diffusely,
 *     B = albedo / pi * (sum_k V_k E_k(n) + ambient(n)),
 * E_k the light's exact irradiance on the vertex normal. The visibility
 * V_k approximates the exact one: with moments, light leaks where a
 * receiver lies behind casters of several depths; with CSM, blockers
 * nearer a receiver than about 0.75/M of the casters' depth range (5% at
 * M = 16) are not seen; with both, nor those nearer than the
 * receiver-plane bias at grazing light. A flat body with every other
 * body on one side of it (a ground) stays out of the shadow maps; what
 * it hides is taken from its plane. Cost per frame grows with K x R^2
 * (maps and tables, times M for CSM) and K x vertices (evaluation, times
 * M for CSM).
 */

typedef struct hl_dynamic hl_dynamic;

/* hl_dynamic_desc fields and defaults (all zero: the defaults):
 *   shadow_res   R: shadow map size, a multiple of 16 from 16 to 1024
 *                (0: 128)
 *   order        M: convolution shadow map order, 4..16 (0: 16)
 *   shadow       the filterable shadow map: HL_DYNAMIC_SHADOW_MOMENTS (the
 *                default, 0 gives it unless order is set: four moments of
 *                depth and the coverage, Peters and Klein 2015; order is
 *                then unused) or HL_DYNAMIC_SHADOW_CSM (the Fourier series
 *                of order M; 0 with order set gives it)
 *   sharp        the sharp lights (up to 4, the strongest, whose filter is
 *                under 4 texels of a map of shadow_res: a sun):
 *                HL_DYNAMIC_SHARP_RAYS (Embree occlusion rays from every
 *                vertex, 5 a vertex and 16 in a penumbra; the default with
 *                moments), HL_DYNAMIC_SHARP_MAPS (finer shadow maps of
 *                sharp_res) or HL_DYNAMIC_SHARP_OFF (the maps of the rest;
 *                the default with CSM)
 *   sharp_res    the sharp lights' map size with HL_DYNAMIC_SHARP_MAPS, a
 *                multiple of 16 from shadow_res to 1024 (0: 4 x shadow_res,
 *                at most 1024). Given above shadow_res with the default
 *                sharp, it asks for the maps; equal to it, for none
 */
#define HL_DYNAMIC_SHADOW_DEFAULT 0u
#define HL_DYNAMIC_SHADOW_CSM 1u
#define HL_DYNAMIC_SHADOW_MOMENTS 2u
#define HL_DYNAMIC_SHARP_DEFAULT 0u
#define HL_DYNAMIC_SHARP_RAYS 1u
#define HL_DYNAMIC_SHARP_MAPS 2u
#define HL_DYNAMIC_SHARP_OFF 3u
typedef struct hl_dynamic_desc {
    uint32_t shadow_res;
    uint32_t order;
    uint32_t shadow;
    uint32_t sharp_res;
    uint32_t sharp;
} hl_dynamic_desc;

/* A dynamic scene from a mesh (copied): body "object", and with ground
 * set the plane hl_mesh_add_ground would add (default desc) as body
 * "ground"; a mesh that already carries a ground gives it as "ground".
 * desc may be NULL. */
HL_API hl_result hl_dynamic_create_from_mesh(hl_context *ctx, const hl_mesh *mesh, int ground,
                                             const hl_dynamic_desc *desc, hl_dynamic **out);
/* hl_dynamic_create_from_file's flags (its `ground` argument, where 1,
 * HL_DYNAMIC_GROUND, asks for a ground, as it always has). */
#define HL_DYNAMIC_GROUND 1
#define HL_DYNAMIC_REST_POSE 2 /* the file's animation not followed: its nodes
                                  as stored, skinned meshes in their bind
                                  pose, morph targets at their base */
/* A dynamic scene from a file: every node of the file that holds
 * triangles is a rigid body, named as in the file, moving by the file's
 * first node animation (an animation that is not rigid is refused, the
 * message naming HL_DYNAMIC_REST_POSE); with HL_DYNAMIC_REST_POSE, still,
 * the nodes as stored. With HL_DYNAMIC_GROUND, body "ground" besides: a
 * file that has an animation (and no HL_DYNAMIC_REST_POSE) keeps its
 * bodies and animation, the ground lying under their whole motion
 * (hl_mesh_add_ground's rule on their bounds over the animation); any
 * other file is loaded as one mesh (hl_mesh_load) and given a ground, as
 * hl_dynamic_create_from_mesh, body "object" and "ground". */
HL_API hl_result hl_dynamic_create_from_file(hl_context *ctx, const char *path, int ground,
                                             const hl_dynamic_desc *desc, hl_dynamic **out);
/* The same with the ground's options (NULL: the defaults) where
 * HL_DYNAMIC_GROUND asks for one. */
HL_API hl_result hl_dynamic_create_from_file_ground(hl_context *ctx, const char *path, int ground,
                                                    const hl_dynamic_desc *desc, const hl_ground_desc *gd,
                                                    hl_dynamic **out);
HL_API void hl_dynamic_destroy(hl_dynamic *d);

/* Bodies, their names (NULL out of range) and the animation's time range
 * in seconds (both 0 without one). */
HL_API uint32_t hl_dynamic_body_count(const hl_dynamic *d);
HL_API const char *hl_dynamic_body_name(const hl_dynamic *d, uint32_t body);
HL_API void hl_dynamic_time_range(const hl_dynamic *d, double *start, double *end);

/* Moves the first body of that name by a world-space translation (finite),
 * applied after its animation, replacing an earlier move. An unknown name
 * fails (HL_ERR_INVALID_ARGUMENT) with a message listing the bodies. */
HL_API hl_result hl_dynamic_move(hl_dynamic *d, const char *body, const float translate[3]);
/* The general form of hl_dynamic_move: the body (by index) gets the
 * world-space rigid transform xf (row-major 3x4, [R | t]; x' = R x + t)
 * applied after its animation, replacing an earlier move. R must be a
 * rotation within 1e-4 (no scale, shear or mirror) and xf finite, else
 * HL_ERR_INVALID_ARGUMENT; R is re-orthonormalised. */
HL_API hl_result hl_dynamic_set_transform(hl_dynamic *d, uint32_t body, const float xf[12]);
/* The vertices of body in hl_dynamic_mesh: first and count (bodies are
 * contiguous, in body order). HL_ERR_INVALID_ARGUMENT out of range. */
HL_API hl_result hl_dynamic_body_vertices(const hl_dynamic *d, uint32_t body, uint32_t *first, uint32_t *count);

/* What hl_dynamic_set_env made of the environment. */
typedef struct hl_dynamic_lights {
    uint32_t lights_made;   /* area lights the split made */
    uint32_t lights_kept;   /* the strongest K, each with a shadow map */
    uint32_t folded;        /* the rest, in the unshadowed SH9 term */
    double folded_share;    /* their share of the map's energy (luminance) */
    double seconds;
} hl_dynamic_lights;

/* Splits env (not kept: it may be destroyed after) into area lights:
 * lights = K kept (>= 1), split_threshold the growth threshold of the
 * split (a light grows while a ring adds more than this share of the
 * light's energy so far; 0: the default, 0.1; else in (0, 1)), the map
 * turned by rotate_deg about +Y as relight's --rotate.
 * info may be NULL. */
HL_API hl_result hl_dynamic_set_env(hl_dynamic *d, const hl_env *env, int32_t lights, float split_threshold,
                                    float rotate_deg, hl_dynamic_lights *info);

/* Per-stage seconds of one frame and what it skipped. */
typedef struct hl_dynamic_stats {
    uint32_t vertices, lights;
    uint32_t shadowed;            /* lights that got a shadow map */
    uint32_t skipped_horizon;     /* below every vertex's horizon */
    uint32_t skipped_negligible;  /* under 1e-4 of the map's energy: unshadowed */
    uint32_t batches;             /* batches of lights within the memory budget */
    uint32_t maps_kept;           /* shadowed lights whose maps were the last
                                     frame's (one batch, the same lights, no
                                     body drawn in them moved), or whose
                                     traced visibility was (no body moved):
                                     not made again */
    double folded_share;          /* as hl_dynamic_lights */
    double t_irradiance, t_shadow_maps, t_csm_build, t_csm_eval, t_shading, t_total;
    int reused; /* nothing moved and the lights are the same: the last
                   frame's colours, at no cost (the rest of st is 0) */
    uint32_t shadow_res;          /* the map size */
    uint32_t sharp_mode;          /* HL_DYNAMIC_SHARP_RAYS, _MAPS or _OFF */
    uint32_t sharp, sharp_res;    /* shadowed lights taken by rays or by maps
                                     of sharp_res (0 with rays or off) */
    uint64_t sharp_rays;          /* rays cast for them this frame */
    double t_sharp_rays;          /* their rays and sums, within t_total */
    uint32_t covered;             /* ground vertices under a body resting on
                                     the ground (inside its solid): dark */
    uint32_t enclosed;            /* vertices inside their body's own closed
                                     parts: dark */
} hl_dynamic_stats;

/* One frame at time t (seconds, finite, >= 0; clamped to the animation's
 * keys): *rgb_out points at 3 linear floats per vertex of
 * hl_dynamic_mesh (>= 0; owned by d, valid until the next render or
 * destroy). Needs hl_dynamic_set_env first. st may be NULL. */
HL_API hl_result hl_dynamic_render(hl_dynamic *d, double t, float **rgb_out, hl_dynamic_stats *st);

/* The bodies merged in world space as of the last render (before it: at
 * rest, time 0): positions, normals, albedo, indices; the ground last
 * (object_vertex_count: the vertices before it). For hl_mesh_save_ply,
 * hl_mesh_save_glb and hl_render; owned by d. */
HL_API const hl_mesh *hl_dynamic_mesh(const hl_dynamic *d);

/* The textured surface of hl_dynamic_mesh where the file's bodies have
 * textures (a file moved body by body: its animation followed); NULL
 * otherwise, and for a file loaded as one mesh, whose surface
 * hl_surface_load gives. Owned by d. */
HL_API const hl_surface *hl_dynamic_surface(const hl_dynamic *d);

#ifdef __cplusplus
}
#endif
#endif
