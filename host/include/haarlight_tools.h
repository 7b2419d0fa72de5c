/* haarlight_tools.h - what the haarlight command's own tools need beyond
 * the public API: `check` (every OpenCL stage against its plain-C twin),
 * `bench` and `bench-precompute` (references, probes of the device and of
 * Embree), `info` (the transport report) and the viewer (colours written
 * straight into an OpenGL buffer).
 *
 * Not for general use: these are measuring instruments, their figures are
 * for reports, and they may change with the engine. They take and return
 * the public types, opaque handles and plain structs of numbers; the
 * kernels' layouts stay inside the library (host/src/tools/ implements
 * this header on top of the private modules).
 */
#ifndef HAARLIGHT_TOOLS_H
#define HAARLIGHT_TOOLS_H

#include <stddef.h>
#include <stdint.h>

#include "haarlight.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- common */

/* Records a failure on ctx as the library's own (the message a command
 * then prints with hl_context_last_error) and returns code. */
hl_result hl_tools_fail(hl_context *ctx, hl_result code, const char *fmt, ...)
#ifdef __GNUC__
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* The library's monotonic wall clock, in seconds. */
double hl_tools_now(void);

/* hl_mesh_load, and what of the file's motion the mesh leaves behind
 * (it holds the nodes as stored, skinned meshes in their bind pose, morph
 * targets at their base): motion[0] the file's animations, [1] its
 * skinned meshes, [2] its meshes with morph targets (zeros on failure). */
hl_result hl_tools_mesh_load(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, hl_mesh **out,
                             hl_mesh_stats *stats, uint32_t motion[3]);
/* The file posed at t seconds of its first (rigid) animation, its bodies
 * merged into one mesh (welded again, their albedo kept), for a
 * precompute of that pose; the animation's name into anim. A file
 * without an animation, or whose animation is not rigid, is refused,
 * naming the file. */
hl_result hl_tools_mesh_load_at(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, double t,
                                hl_mesh **out, char *anim, size_t anim_size);

/* Luminance of linear Rec.709 RGB, in float exactly as the library and
 * its kernels compute it. */
float hl_tools_luminance(float r, float g, float b);

/* `haarlight info`: parameters, counts, per-vertex statistics, ray
 * counters and sizes of a loaded transport, printed to file (a FILE *);
 * path is only printed (and its size queried), it may be NULL. */
void hl_tools_transport_report(const hl_transport *t, const char *path, void *file);

/* ---------------------------------------------------------------- check */

/* One stage compared: the worst difference (relative to the largest
 * magnitude for float stages) against its tolerance, and the rows or
 * values that differ out of those compared. */
typedef struct hl_check_row {
    const char *stage;
    double worst, tolerance;
    uint64_t mismatches, of;
} hl_check_row;

/* Called with each stage's row as soon as it is compared. */
typedef void (*hl_check_report_fn)(void *user, const hl_check_row *row);

/* What the lighting stages selected, for the closing summary. */
typedef struct hl_check_summary {
    uint32_t terms_kept, coefficients; /* kept of all lighting terms */
    double energy_percent;             /* of the lighting's energy */
    uint32_t blocks_used, blocks;
    uint32_t precompute_vertices;      /* checked in the precompute stages */
    uint32_t vertices;                 /* all, checked in the lighting stages */
} hl_check_summary;

/* The tables of a transport's N and C, made on ref (the reference
 * context) before any stage runs. */
typedef struct hl_stage_check hl_stage_check;
hl_result hl_stage_check_create(hl_context *ref, const hl_transport *t, hl_stage_check **out);
void hl_stage_check_destroy(hl_stage_check *c);

/* The precompute stages (cube to paraboloid, Haar, truncation,
 * quantisation and packing, and the rows the file stores) on `vertices`
 * vertices spread over the mesh, their rays re-cast, on cl against the
 * twins on ref; one row per stage to report. *ok is cleared when a stage
 * differs. */
hl_result hl_stage_check_precompute(hl_stage_check *c, hl_context *cl, uint32_t vertices, hl_check_report_fn report,
                                    void *user, int *ok);

/* The lighting stages (environment to paraboloid, Haar, selection, dot
 * products) under env with rd's terms, selection and rotation, on every
 * vertex; run after hl_stage_check_precompute. */
hl_result hl_stage_check_lighting(hl_stage_check *c, hl_context *cl, const hl_env *env, const hl_relight_desc *rd,
                                  hl_check_report_fn report, void *user, int *ok, hl_check_summary *summary);

/* ---------------------------------------------------------------- bench */

/* The benchmark's references for transports of one mesh, N and C (the
 * first one's), made on a reference context: Embree scenes, the paraboloid
 * and lighting tables, and the untruncated lighting of each environment. */
typedef struct hl_bench_ref hl_bench_ref;
hl_result hl_bench_ref_create(hl_context *ctx, const hl_transport *t, hl_bench_ref **out);
void hl_bench_ref_destroy(hl_bench_ref *b);

/* For n vertices idx, the colours (3 doubles per vertex) under each of
 * the nenvs environments:
 *   exact[e] (may not be NULL): untruncated, unquantised transport,
 *     recomputed from the rays, dotted with untruncated lighting in
 *     float64;
 *   cont[e] (for the first n_cont of idx2; skipped when n_cont is 0): the
 *     map integrated directly, one Embree ray per map pixel cast from the
 *     vertex itself with its own triangles skipped (no ray offset).
 * The environments' lighting is kept for hl_bench_ref_ground. */
hl_result hl_bench_ref_colours(hl_bench_ref *b, const uint32_t *idx, uint32_t n, const uint32_t *idx2, uint32_t n_cont,
                               const hl_env *const *envs, int nenvs, double *const *exact, double *const *cont);

/* The exact colours (as above) of every ground vertex, in order, under
 * each environment given to hl_bench_ref_colours: ground[e] gets 3
 * doubles per ground vertex (allocated here; the caller frees them). */
hl_result hl_bench_ref_ground(hl_bench_ref *b, double **ground);

/* The bounced exact reference of the n vertices idx (docs/BOUNCES.md, "The
 * bounced reference in bench"), for B bounces (1 to HL_MAX_BOUNCES) of
 * diffuse interreflection with the mesh's per-channel albedo (each in
 * [0, 1], else HL_ERR_INVALID_ARGUMENT), under each of the nenvs maps:
 * E_0 = every vertex's untruncated row dotted with the untruncated
 * lighting in float64 (no albedo), then F_b(x) = (1 / K) sum_k rho_c(y_k)
 * F_(b-1)(y_k), F_0 = E_0, over K cosine-weighted rays of x (fresh rays
 * each bounce; the precompute's origin and back-face rule; rho and F
 * interpolated over the hit triangle), every vertex for b < B, the subset
 * for b = B. exact[b nenvs + e] for b = 0 .. B (3 n doubles each, the
 * caller's) gets rho_c(x) (F_0 + ... + F_b)(x): b = 0 is the direct exact
 * reference. noise_own and noise_bound ((B + 1) nenvs doubles, may be NULL)
 * get the reference's own Monte Carlo noise relative to its L2 norm over
 * the subset: the gathers' standard errors at the subset (root sum of
 * squares over the bounces), and a bound that adds the noise each gather
 * reads from the bounce before (no cancellation assumed). Progress on
 * stderr when progress is set. */
hl_result hl_bench_ref_bounced(hl_bench_ref *b, const uint32_t *idx, uint32_t n, uint32_t B, uint32_t K,
                               const hl_env *const *envs, int nenvs, int progress, double *const *exact,
                               double *noise_own, double *noise_bound);

/* Probes of the OpenCL device a relighter runs on (HL_ERR_UNSUPPORTED on
 * the reference backend): the bytes the dot products read for the last
 * selection, the mean time of the dot-product kernel alone over reps
 * launches on the current lighting, and the device's read bandwidth
 * (median of reps passes over `bytes`). */
hl_result hl_bench_bytes_read(hl_relighter *r, double *bytes);
hl_result hl_bench_time_dots(hl_relighter *r, uint32_t reps, double *seconds);
hl_result hl_bench_read_bandwidth(hl_context *ctx, size_t bytes, uint32_t reps, double *bytes_per_s);
/* The mean time of the capture of the relighter's surroundings alone (the
 * stage that takes env2para's place; hl_relighter_set_surroundings and
 * one run first) over reps launches. */
hl_result hl_bench_time_capture(hl_relighter *r, uint32_t reps, double *seconds);
/* What the capture of the relighter's surroundings costs, on either
 * backend (after a run with surroundings): the triangles it captured, the
 * bytes it holds on the host and on the device (its packed triangles,
 * hierarchy, lists, tables and maps), and the mean time of one capture
 * alone over reps (the triangles packed, the hierarchy built, the kernel
 * or the twin run; uploads included). */
typedef struct hl_capture_cost {
    uint32_t triangles;
    size_t host_bytes, device_bytes;
    double seconds;
} hl_capture_cost;
hl_result hl_bench_capture_cost(hl_relighter *r, uint32_t reps, hl_capture_cost *cost);

/* References for lighting captured from surroundings (capture_refs.c):
 * per vertex of t's mesh, what `relight` writes (albedo / pi times the
 * irradiance, 3 floats a vertex) under s as posed now, no environment:
 *   HL_CAPTURE_REF_EXACT:    rays from each vertex (offset as the
 *       precompute's) to K x K stratified points on every emitting
 *       triangle, occluded by the object, its ground and every triangle of
 *       the surroundings; no capture point, map or truncation;
 *   HL_CAPTURE_REF_CENTRE:   the same points seen from the capture point
 *       (directions, solid angles, hidden where the surroundings hide them
 *       from there), each direction cast from the vertex against the
 *       object and ground: a capture of unlimited resolution with an exact
 *       transport (exact - centre: the one capture point's parallax);
 *   HL_CAPTURE_REF_DISCRETE: the untruncated, unquantised transport at the
 *       file's N, C and supersampling dotted with the untruncated capture
 *       (centre - discrete: the resolution; discrete - relit: the
 *       transport's truncation and codes and the lighting's M); K unused.
 * K: 1 to HL_CAPTURE_REF_MAX_K, at most HL_CAPTURE_REF_MAX_POINTS points
 * in all. seconds (may be NULL): the call's wall time. */
enum { HL_CAPTURE_REF_EXACT = 1, HL_CAPTURE_REF_CENTRE = 2, HL_CAPTURE_REF_DISCRETE = 3 };
#define HL_CAPTURE_REF_MAX_K 256u
#define HL_CAPTURE_REF_MAX_POINTS (1u << 22)
hl_result hl_bench_capture_ref(hl_context *ctx, const hl_transport *t, hl_surroundings *s, int kind, uint32_t K,
                               float *rgb, double *seconds);

/* `bench-precompute`: d with its defaults filled in and checked (errors
 * name the option), then Embree's raw occlusion rate (rays/s) on the rays
 * the precompute casts for the listed vertices, `rounds` times. */
hl_result hl_bench_precompute_resolve(hl_context *ctx, hl_precompute_desc *d);
hl_result hl_bench_raw_ray_rates(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *resolved,
                                 const uint32_t *verts, uint32_t nverts, uint32_t rounds, double *rays_per_s);

/* ---------------------------------------------------------------- bench-dynamic */

/* On a dynamic scene's bodies as they were at its last hl_dynamic_render
 * (at rest before the first; a move takes effect at the next render),
 * colours into rgb, 3 floats per vertex of hl_dynamic_mesh, on d's
 * context's threads:
 *   exact:  each vertex integrates the whole of env (its cube resampling at
 *           face 64, one ray a texel) with Embree visibility against every
 *           body; env should be the map given to hl_dynamic_set_env, at
 *           rotation 0;
 *   lights: the K lights d keeps with traced visibility (each the share
 *           of its energy in texels whose rays are open), the folded
 *           ambient unshadowed, as the frame shades it;
 *   traced: the simplest rival a user could write: per vertex, S Embree
 *           rays stratified over each kept light's rectangle, V_k the
 *           open share of those above the horizon, E_k and the ambient as
 *           the frame's; everything (the scene's BVH too) rebuilt per call
 *           as after any move. S: 1 to 1024.
 * seconds: the call's wall time (may be NULL). */
hl_result hl_bench_dyn_exact(hl_dynamic *d, const hl_env *env, float *rgb, double *seconds);
hl_result hl_bench_dyn_lights(hl_dynamic *d, float *rgb, double *seconds);

/* The traced method's time by stage, seconds: the world mesh and Embree's
 * BVH, the rays' directions and origins, the occlusion rays, the shading;
 * and the rays cast. */
typedef struct hl_bench_traced_times {
    double seconds, t_build, t_rays, t_trace, t_shade;
    uint64_t rays;
} hl_bench_traced_times;
hl_result hl_bench_dyn_traced(hl_dynamic *d, uint32_t S, float *rgb, hl_bench_traced_times *times);
/* The largest S hl_bench_dyn_traced takes (dyn_traced.h says why). */
#define HL_BENCH_TRACED_MAX_S 1024u

/* ---------------------------------------------------------------- viewer */

/* hl_relighter_run with the colours left in the relighter: *rgba points
 * at 4 floats per vertex (the fourth: the lowest channel before the clamp,
 * or 0), valid until the next run or destroy. */
hl_result hl_view_run4(hl_relighter *r, const hl_relight_desc *desc, const float **rgba, hl_relight_stats *stats);

/* The context properties that share buffers with a GLX context (for
 * hl_context_desc.cl_properties): CL_GL_CONTEXT_KHR, CL_GLX_DISPLAY_KHR,
 * then 0. */
void hl_view_glx_properties(void *glx_context, void *x_display, intptr_t props[5]);

/* An OpenGL buffer object seen by a context created with those
 * properties; the dot products can write colours into it. Release it
 * before the GL buffer and the GL context go. */
typedef struct hl_gl_colours hl_gl_colours;
hl_result hl_view_gl_colours_create(hl_context *ctx, unsigned gl_buffer, hl_gl_colours **out);
void hl_view_gl_colours_destroy(hl_gl_colours *c);

/* hl_relighter_run with the colours (4 floats per vertex, as
 * hl_view_run4's) written into the GL buffer, which is acquired from
 * OpenGL around the dot products (the caller has finished its GL work on
 * it: glFinish). Nothing is copied to the host. */
hl_result hl_view_run_gl(hl_relighter *r, const hl_relight_desc *desc, hl_gl_colours *c, hl_relight_stats *stats);

/* ---------------------------------------------------------------- shards */

/* A precompute spread over machines: shard i of n (n >= 1, i < n, n at
 * most the vertex count) computes the vertices [*first, *end) that this
 * gives: contiguous, lengths differing by at most one, from V, i and n
 * alone. */
void hl_shard_range(uint32_t vertex_count, uint32_t index, uint32_t count, uint32_t *first, uint32_t *end);

/* hl_precompute for shard shard_index of shard_count only: writes a shard
 * file at out_path (the whole mesh, then the rows of the shard's vertices;
 * a magic of its own, so hl_transport_load refuses it and names the
 * shard). Resumes like a whole run (desc->resume: the .partial must be of
 * the same shard). shard_count 0 is hl_precompute itself. */
hl_result hl_precompute_shard(hl_context *ctx, const hl_mesh *mesh, const hl_precompute_desc *desc,
                              uint32_t shard_index, uint32_t shard_count, const char *out_path,
                              hl_precompute_stats *stats);

/* What a merge did. */
typedef struct hl_merge_stats {
    uint32_t shards, vertices;
    uint64_t coefficients_kept;
    uint64_t bytes_read, bytes_written;
    double seconds;
    int values; /* 1: every shard had its floats (precompute --keep-floats),
                   joined into out_path + ".values" */
} hl_merge_stats;

/* Joins the shard files (any order) of one sharded precompute into the
 * transport file out_path, byte for byte the file one unsharded run with
 * the same mesh and options writes; atomically (out_path + ".partial",
 * renamed when complete; nothing is left on failure). Streams: it holds a
 * few MiB of buffers, never a whole shard or the mesh. Refuses, naming the
 * file: a file that is not a shard (a whole transport file, an unfinished
 * .partial, anything else); shards of different meshes, options or shard
 * counts; a missing or repeated shard; a truncated or corrupt shard (every
 * checksum and row is checked); out_path being one of the shards.
 * HL_ERR_INVALID_ARGUMENT, HL_ERR_FORMAT or HL_ERR_IO; HL_ERR_INTERRUPTED
 * when ctx is cancelled. stats may be NULL. */
hl_result hl_transport_merge(hl_context *ctx, const char *out_path, const char *const *shard_paths, uint32_t count,
                             hl_merge_stats *stats);

/* ---- relighter memory ---- */

/* hl_relighter_create for callers that keep the transport for its mesh
 * only (`haarlight relight`): t must have been loaded from path by
 * hl_transport_load. On the OpenCL backend the relighter reads t's entries
 * once (the error bound, the selection weights), then frees them
 * (t->entries becomes NULL: hl_transport_query_row and the like must not
 * be called on t afterwards, on failure too) and builds its columns from
 * rows read from path again, so the entries and the columns are never in
 * memory together; once the columns are built it frees t's block counts
 * and row offsets too (NULL after). Refuses a path whose header does not describe t or
 * whose entries' checksum is not that of t's. On the reference backend
 * (which relights from the entries) it is hl_relighter_create. */
hl_result hl_relighter_create_from_file(hl_context *ctx, hl_transport *t, const char *path, hl_relighter **out);

/* hl_relighter_create for one or a few lighting changes (`haarlight
 * relight`): on the OpenCL backend its dot products walk t's rows as
 * loaded (t must outlive it) instead of columns laid out first, the same
 * colours bit for bit. Creation costs no layout (seconds on a big mesh)
 * and the device holds the file's own bytes, but each lighting change
 * reads every kept block of every row: for many changes (view, bench)
 * use hl_relighter_create. Where one buffer (or what the device memory
 * limit leaves, less 64 MiB) cannot hold the entries, it is
 * hl_relighter_create_from_file with path (hl_relighter_create when path
 * is NULL). */
hl_result hl_relighter_create_once(hl_context *ctx, hl_transport *t, const char *path, hl_relighter **out);

/* What a relighter holds on its device: all its buffers (device_bytes;
 * the capture of surroundings' own not included), of which the transport
 * columns (column_bytes, counted whole: with parts > 1 they wait in host
 * memory and the device holds one part at a time, unless resident), and
 * the parts its dot products run in (1: all the columns at once; 0 on the
 * reference backend, which holds nothing on a device). resident: the
 * parts are all on the device, each in buffers of its own (no single
 * buffer could hold them). See docs/MEMORY.md. */
typedef struct hl_relighter_memory {
    uint64_t device_bytes;
    uint64_t column_bytes;
    uint32_t parts;
    uint32_t resident;
} hl_relighter_memory;
hl_result hl_relighter_memory_use(const hl_relighter *r, hl_relighter_memory *m);

/* ---------------------------------------------------------------- bench-basis */

/* The exact rows and lighting of hl_bench_ref_colours, as they are:
 * untruncated, unquantised transport of the n vertices idx (the same rays
 * and cube-to-paraboloid step), n rows of 2 N^2 floats each: texel values
 * T_j = V_j max(0, n . w_j) dw_j / pi in texel order (map N^2 + row N +
 * col; texel may be NULL) and their Haar coefficients in slot order (haar
 * may be NULL); and env's lighting at rotation 0, R, G, B planes of 2 N^2:
 * texel means of the radiance (Lp, may be NULL) and their Haar
 * coefficients (Lw, may be NULL). */
hl_result hl_bench_ref_rows(hl_bench_ref *b, const uint32_t *idx, uint32_t n, float *texel, float *haar);
hl_result hl_bench_ref_lighting(hl_bench_ref *b, const hl_env *env, float *Lp, float *Lw);
/* The relighter's selection weights of a scheme (HL_SELECT_AREA,
 * _UNWEIGHTED or _TRANSPORT: mean |T_i| over the transport's stored rows),
 * 2 N^2 floats in slot order. */
hl_result hl_bench_ref_weights(hl_bench_ref *b, uint32_t scheme, float *w);

/* The bases `bench-basis` compares, each with the lighting cut to M terms
 * (the 2003 paper's comparison):
 *   HAAR:           the paraboloid Haar wavelets, the M lighting terms of
 *                   largest |luminance| (nonlinear, unweighted);
 *   HAAR_AREA:      the same, largest |luminance| x the solid angle of the
 *                   wavelet's support (the relighter's --select area);
 *   HAAR_TRANSPORT: largest |luminance| x mean |T_i| over the vertices
 *                   (the relighter's default, --select transport);
 *   SH:             real spherical harmonics, the first M in band order
 *                   (k = l^2 + l + m: linear, as Sloan et al. use them);
 *   SH_NONLINEAR:   spherical harmonics, the M of largest |luminance|;
 *   CUBE, CUBE_AREA, CUBE_TRANSPORT: Haar wavelets over the six faces of a
 *                   cube (the paper's layout, cube/cube.h), selected as
 *                   HAAR, HAAR_AREA and HAAR_TRANSPORT (the transport
 *                   weights: mean |T_i| over the sampled vertices' exact
 *                   rows, as no file holds cube rows). */
typedef enum hl_basis {
    HL_BASIS_HAAR,
    HL_BASIS_HAAR_AREA,
    HL_BASIS_HAAR_TRANSPORT,
    HL_BASIS_SH,
    HL_BASIS_SH_NONLINEAR,
    HL_BASIS_CUBE,
    HL_BASIS_CUBE_AREA,
    HL_BASIS_CUBE_TRANSPORT,
    HL_BASIS_COUNT
} hl_basis;
/* "haar", "haar-area", "haar-transport", "sh", "sh-nonlinear",
 * "cube-haar", "cube-haar-area", "cube-haar-transport". */
const char *hl_basis_name(hl_basis basis);

/* The exact rows of n vertices (idx) of t in texels and in Haar
 * coefficients, on the paraboloid and on the cube faces of side cube_side
 * (0: hl_basis_bench_default_cube_side), and their projection onto the
 * spherical harmonics of sh_order (1 to 32: sh_order^2 functions) by the
 * texels' exact integrals (the transport as the piecewise-constant
 * function T_j / Omega_j); made on a reference context's threads. */
typedef struct hl_basis_bench hl_basis_bench;
/* How the cube rows are made from the visibility texels:
 *   SHARED: the paraboloid rows' own pieces (the footprint table's
 *           max(0, n . m) per part of a paraboloid texel in a cube texel),
 *           grouped by cube texel: the same products, so under a constant
 *           map both give the same colours to float precision; but a cube
 *           texel's pieces are the sub-samples whose centres fell in it, so
 *           its footprint is only that close (11% rms of its moment at
 *           C = 64);
 *   OWN:    each visibility texel's clamped cosine integrated over its own
 *           footprint (cube/cube.h, hl_cube_rows_exact). */
typedef enum hl_cube_rows_mode { HL_CUBE_ROWS_SHARED, HL_CUBE_ROWS_OWN } hl_cube_rows_mode;
hl_result hl_basis_bench_create_ex(hl_context *ctx, const hl_transport *t, const uint32_t *idx, uint32_t n,
                                   uint32_t sh_order, uint32_t cube_side, hl_cube_rows_mode cube_rows,
                                   hl_basis_bench **out);
/* hl_basis_bench_create_ex with the default cube side and SHARED rows. */
hl_result hl_basis_bench_create(hl_context *ctx, const hl_transport *t, const uint32_t *idx, uint32_t n,
                                uint32_t sh_order, hl_basis_bench **out);
/* The default cube side for paraboloids of side N on a visibility cube of
 * side C: N / 2 (6 (N/2)^2 = 0.75 of the paraboloids' 2 N^2 texels, the
 * power of two nearest N / sqrt 3, which would match them), halved until
 * it divides C; 0 when no power of two from 2 does (then the cube bases
 * have no terms). */
uint32_t hl_basis_bench_default_cube_side(uint32_t N, uint32_t C);
/* The cube side in use. */
uint32_t hl_basis_bench_cube_side(const hl_basis_bench *b);
void hl_basis_bench_destroy(hl_basis_bench *b);
/* The terms a basis has: 2 N^2, 6 cube_side^2 or sh_order^2. */
uint32_t hl_basis_bench_count(const hl_basis_bench *b, hl_basis basis);
/* Takes env (at rotation 0) as the lighting, in every basis; *exact then
 * points at the n vertices' exact colours (3 doubles each, albedo
 * included; as hl_bench_ref_colours's), valid until the next call. */
hl_result hl_basis_bench_set_env(hl_basis_bench *b, const hl_env *env, const double **exact);
/* The exact colours of a basis's own discretization (after set_env): the
 * cube's rows dotted with its whole lighting for the cube bases (they
 * differ from the paraboloid's where a texel holds both light and a
 * shadow's edge: the two grids cut the sphere differently), else the
 * paraboloid's (the harmonics project its texels). NULL before set_env,
 * and for the cube bases when they have no terms. */
const double *hl_basis_bench_exact(const hl_basis_bench *b, hl_basis basis);
/* bench_refs.c's continuous reference (env integrated directly, a ray per
 * map pixel from the vertex itself: no grid at all) of the n2 sampled
 * vertices k n / n2, k < n2, into cont (3 doubles each); env must be the
 * one set last. */
hl_result hl_basis_bench_continuous(hl_basis_bench *b, const hl_env *env, uint32_t n2, double *cont);
/* The colours (3 doubles a vertex, albedo included, not clamped) with the
 * lighting cut to M terms of basis (1 to hl_basis_bench_count) and the
 * transport whole. HAAR with every term sums the same products in the
 * same order as the exact colours, so it gives them bit for bit. */
hl_result hl_basis_bench_colours(hl_basis_bench *b, hl_basis basis, uint32_t M, double *rgb);

/* Equal bytes. A row of K stored entries costs, as the transport file
 * stores it (host/FORMAT.md), 8 bytes of record, 2 bytes per 256-slot
 * block of the basis's terms and 2 bytes per entry:
 * 8 + 2 ceil(count / 256) + 2 K. hl_basis_bench_entries gives the K that
 * fits `bytes` (0 to count). */
uint32_t hl_basis_bench_entries(const hl_basis_bench *b, hl_basis basis, uint32_t bytes);
/* hl_basis_bench_colours with each row first cut to the entries that fit
 * `bytes` per vertex: the Haar bases keep each row's K coefficients of
 * largest magnitude, the harmonics the first K in band order. */
hl_result hl_basis_bench_colours_bytes(hl_basis_bench *b, hl_basis basis, uint32_t M, uint32_t bytes, double *rgb);

/* The time of one lighting change, in seconds: the lighting transform
 * (the texel means of the current map to the basis's coefficients: the
 * paraboloid or cube Haar transform, or the projection on the harmonics),
 * the selection of M terms, and the M-term dot products of the n sampled
 * vertices' whole rows times vertex_count / n. Each part the least of
 * `reps` runs on one thread. */
typedef struct hl_basis_time { double transform, select, dots; } hl_basis_time;
hl_result hl_basis_bench_time(hl_basis_bench *b, hl_basis basis, uint32_t M, uint32_t reps, hl_basis_time *out);

#ifdef __cplusplus
}
#endif
#endif
