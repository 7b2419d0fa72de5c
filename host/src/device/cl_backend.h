/* cl_backend.h - the library's only view of OpenCL: the OpenCL headers
 * are included by cl_internal.h, which only the files that talk to the
 * device include; everything else calls the functions declared here.
 *
 * hl_cl owns the platform, device, queue, program and kernels of a context.
 * Stage runners take host arrays and return host arrays, so callers never
 * see cl_mem. Errors carry the cl_int name and, for builds, the build log.
 *
 * Where they are defined, by stage:
 *   device/cl_device.c, cl_program.c   hl_cl_create, hl_cl_destroy
 *   device/cl_buffers.c, cl_gl.c       buffers, OpenGL sharing
 *   device/cl_probe.c                  hl_cl_read_bandwidth
 *   precompute/cl_pipe.c               hl_cl_pipe_*
 *   relight/cl_relight.c, cl_columns.c hl_cl_light_* (run and stages)
 *   relight/cl_light_probe.c           hl_cl_light_* (bench probes)
 * The declarations name other stages' types only as incomplete structs, so
 * this header depends on core alone.
 */
#ifndef HL_CL_BACKEND_H
#define HL_CL_BACKEND_H

#include "hl_internal.h"

struct hl_geom;

/* device_memory: the most device memory the context may hold (0: the
 * device's global memory). */
hl_result hl_cl_create(hl_context *ctx, int platform, int device, const intptr_t *properties,
                       uint64_t device_memory);
void hl_cl_destroy(struct hl_cl *cl);



/* Device buffers for running the precompute stages on up to max_rows rows
 * at a time. Two input/output slots let the host fill one while the device
 * works on the other. */
typedef struct hl_cl_pipe hl_cl_pipe;

/* Host side of one chunk. Arrays hold max_rows rows: vis ncube bytes,
 * normals4 4 floats, tr 1, rq 1, bc nblocks, entries 2 ncoef bytes, nnz 1
 * per row. They must stay valid from submit until wait returns. */
typedef struct hl_chunk_buf {
    uint8_t *vis;
    float *normals4;
    hl_trunc_result *tr;
    hl_row_quant *rq;
    uint16_t *bc;
    uint8_t *entries;
    uint32_t *nnz;
    float *coef;    /* NULL, or ncoef a row: the coefficients coded (for the
                       values file, values_file.h) */
    uint32_t first; /* the chunk's first vertex (sqrt8's dither depends on it) */
} hl_chunk_buf;

hl_result hl_cl_pipe_create(hl_context *ctx, const struct hl_geom *g, uint32_t max_rows,
                            hl_cl_pipe **out);
void hl_cl_pipe_destroy(hl_cl_pipe *p);

/* Enqueues upload, the four stages and the read-back for `rows` rows of
 * io, and returns without waiting. */
hl_result hl_cl_pipe_submit(hl_cl_pipe *p, int slot, uint32_t rows, float vis_scale,
                            hl_trunc_params tp, uint32_t scheme, const hl_chunk_buf *io);
/* Waits until the outputs of slot's last submit are in host memory. */
hl_result hl_cl_pipe_wait(hl_cl_pipe *p, int slot);

/* Single stages, blocking, on host arrays (tests and `haarlight check`). */
hl_result hl_cl_pipe_cube2para(hl_cl_pipe *p, uint32_t rows, const uint8_t *vis,
                               float scale, const float *normals4, float *T);
hl_result hl_cl_pipe_haar(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef);
/* Spherical harmonics in Haar's place (submit and hl_cl_pipe_sh_project):
 * Y as hl_sh_matrix makes it (ncoef x stride floats, count = order^2),
 * uploaded once. */
hl_result hl_cl_pipe_set_sh(hl_cl_pipe *p, const float *Y, uint32_t stride, uint32_t count);
hl_result hl_cl_pipe_sh_project(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef);
/* Cube-face Haar of side Cq in the place of cube2para and Haar (submit):
 * the rows on the faces (hl_cl_pipe_cube_rows: T's first 6 Cq^2 floats of
 * each ncoef) and their Haar (hl_cl_pipe_cube_haar: slots 0 .. 6 Cq^2 - 1,
 * the others zero); twins hl_cube_rows and hl_cube_haar (cube/cube.h). */
hl_result hl_cl_pipe_set_cube(hl_cl_pipe *p, uint32_t Cq);
hl_result hl_cl_pipe_cube_rows(hl_cl_pipe *p, uint32_t rows, const uint8_t *vis, float scale,
                               const float *normals4, float *T);
hl_result hl_cl_pipe_cube_haar(hl_cl_pipe *p, uint32_t rows, const float *T, float *coef);
hl_result hl_cl_pipe_truncate(hl_cl_pipe *p, uint32_t rows, const float *coef,
                              hl_trunc_params tp, hl_trunc_result *tr);
/* Row v is vertex first + v (sqrt8's dither). */
hl_result hl_cl_pipe_quantize(hl_cl_pipe *p, uint32_t rows, uint32_t first, const float *coef,
                              const hl_trunc_result *tr, uint32_t scheme,
                              hl_row_quant *rq, uint16_t *bc, uint8_t *entries,
                              uint32_t *nnz);
/* ---- lighting: environment cells to vertex colours ---- */

struct hl_light_geom;
typedef struct hl_cl_light hl_cl_light;

/* Uploads the transport (entries, offsets, counts, parameters) and albedo
 * (4 floats per vertex) once; tables from g and lg. */
hl_result hl_cl_light_create(hl_context *ctx, const struct hl_geom *g, const struct hl_light_geom *lg,
                             const hl_transport *t, const float *albedo4, hl_cl_light **out);
/* Where a transport that no longer holds its entries (t->entries NULL)
 * has them: the file it was loaded from, open at fd, its entries section
 * at offset. */
typedef struct hl_row_source {
    const char *path;
    int fd;
    uint64_t offset;
} hl_row_source;
/* hl_cl_light_create reading the rows through src where t->entries is
 * NULL (src may be NULL otherwise). */
hl_result hl_cl_light_create_from(hl_context *ctx, const struct hl_geom *g, const struct hl_light_geom *lg,
                                  const hl_transport *t, const hl_row_source *src, const float *albedo4,
                                  hl_cl_light **out);
/* hl_cl_light_create with no columns: the dot products walk t's rows as
 * loaded (kernels/relight/relight_rows.cl; the same colours bit for bit),
 * which t must keep for the light's life. For one or a few lighting
 * changes: nothing is laid out, but each change reads every kept block
 * of every row. */
hl_result hl_cl_light_create_rows(hl_context *ctx, const struct hl_geom *g, const struct hl_light_geom *lg,
                                  const hl_transport *t, const float *albedo4, hl_cl_light **out);
void hl_cl_light_destroy(hl_cl_light *l);
hl_result hl_cl_light_set_cells(hl_cl_light *l, const float *cells4);
hl_result hl_cl_light_set_weights(hl_cl_light *l, const float *weight);
/* keep 1: the dot products leave negative sums as they are (measuring
 * what the clamp at zero changes); 0, the default: clamped. */
void hl_cl_light_keep_negative(hl_cl_light *l, int keep);
/* The next lighting changes take their paraboloid lighting from cap's
 * capture of scene (both kept by the caller until the last such change),
 * lit where it leaves the sphere open by the environment (with_env) or
 * black; cap NULL: from the environment again. */
struct hl_capture;
struct hl_capture_scene;
hl_result hl_cl_light_set_capture(hl_cl_light *l, struct hl_capture *cap, const struct hl_capture_scene *scene,
                                  int with_env);
/* A lighting change in one submission: env2para, Haar of R, G, B,
 * selection, dot products; *B4 points at the colours, 4 floats per
 * vertex, valid until the next call that enqueues work on l (or its
 * destruction): l's colour buffer mapped for reading, which on a CPU
 * device is its own memory, read in place. */
hl_result hl_cl_light_run(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp, const float **B4,
                          hl_select_result *res);
/* The last colours again, as hl_cl_light_run gave them (mapped anew
 * where something has run since). */
hl_result hl_cl_light_colours(hl_cl_light *l, const float **B4);
/* The clamp's tally of the colours hl_cl_light_run last gave (joined from
 * the work-items' tallies read back with them): the vertices with a
 * channel below zero before the clamp, the lowest such channel (0 if
 * none) and the brightest channel written. */
void hl_cl_light_clamp_tally(const hl_cl_light *l, uint32_t *negative, float *lowest, float *brightest);
/* As hl_cl_light_run, but the colours (4 floats per vertex) go to out, a
 * cl_mem of this context holding at least that many bytes, and nothing is
 * read back but the selection's result. With gl set, out came from
 * hl_cl_gl_buffer and is acquired from OpenGL around the dot products and
 * released after them (the caller has finished its GL work on it: glFinish). */
hl_result hl_cl_light_run_into(hl_cl_light *l, uint32_t s0, float f, hl_select_params sp, void *out, int gl,
                               hl_select_result *res);
/* Writes rgba4 (4 floats per vertex, the host's) into out as
 * hl_cl_light_run_into would have left it, acquiring it from OpenGL
 * around the write with gl set; returns once OpenGL may draw from it. */
hl_result hl_cl_light_write_colours(hl_cl_light *l, const float *rgba4, void *out, int gl);
/* A cl_mem (returned as void *) over the OpenGL buffer object gl_buffer
 * (clCreateFromGLBuffer, write only); needs a context created with the GL
 * context's properties. hl_cl_mem_release frees such handles. */
hl_result hl_cl_gl_buffer(hl_context *ctx, unsigned gl_buffer, void **out);
/* The context properties that share buffers with a GLX context (for
 * hl_context_desc.cl_properties): CL_GL_CONTEXT_KHR, CL_GLX_DISPLAY_KHR,
 * then 0. */
void hl_cl_glx_properties(void *glx_context, void *x_display, intptr_t props[5]);
/* A plain device buffer of bytes (tests of hl_cl_light_run_into), counted
 * against the context's device memory limit; hl_cl_buffer_release frees it. */
hl_result hl_cl_buffer(hl_context *ctx, size_t bytes, void **out);
hl_result hl_cl_buffer_read(hl_context *ctx, void *mem, size_t bytes, void *dst);
void hl_cl_buffer_release(hl_context *ctx, void *mem);
void hl_cl_mem_release(void *mem);
/* Single stages, blocking (tests and `haarlight check`). */
hl_result hl_cl_light_stage_env2para(hl_cl_light *l, uint32_t s0, float f, float *Lp);
hl_result hl_cl_light_stage_haar(hl_cl_light *l, const float *Lp, float *Lw);
/* A spherical-harmonic transport: the lighting is projected by Y
 * (hl_sh_matrix, not per solid angle; ncoef x stride floats, count =
 * order^2) in Haar's place; hl_cl_light_stage_sh runs that stage alone. */
hl_result hl_cl_light_set_sh(hl_cl_light *l, const float *Y, uint32_t stride, uint32_t count);
hl_result hl_cl_light_stage_sh(hl_cl_light *l, const float *Lp, float *Lw);
/* A cube-face Haar transport of side Cq: the lighting is each face
 * texel's mean radiance (env2para's kernels on the cube's taps, tap_start
 * 6 Cq^2 + 1 rows of ntaps hl_env_tap, cube/cube.h's hl_cube_tables) and
 * then the faces' Haar into slots 0 .. 6 Cq^2 - 1, zeros elsewhere;
 * hl_cl_light_stage_cube runs the lighting stages up to Lw alone. */
hl_result hl_cl_light_set_cube(hl_cl_light *l, uint32_t Cq, const uint32_t *tap_start, const hl_env_tap *taps,
                               uint32_t ntaps);
hl_result hl_cl_light_stage_cube(hl_cl_light *l, uint32_t s0, float f, float *Lw);
hl_result hl_cl_light_stage_select(hl_cl_light *l, const float *Lw, hl_select_params sp, float *Lsel4,
                                   uint8_t *used, uint32_t *bits, hl_select_result *res);
hl_result hl_cl_light_stage_relight(hl_cl_light *l, const float *Lsel4, const uint32_t *bits, float *B4);

/* The dot-product kernel alone on the current lighting, mean of reps
 * launches queued together. */
/* The capture alone (after a lighting change that captured), mean over
 * reps launches. */
hl_result hl_cl_light_time_capture(hl_cl_light *l, uint32_t reps, double *seconds);
hl_result hl_cl_light_time_relight(hl_cl_light *l, uint32_t reps, double *seconds);
/* The dot products' work-items (ranges of tiles), and the column entries
 * each would walk for the kept slots in bits (per_range: one per range);
 * returns the number of kept slots. */
uint32_t hl_cl_light_ranges(const hl_cl_light *l);
/* Whether the device holds one albedo for all (every vertex has the same). */
int hl_cl_light_one_albedo(const hl_cl_light *l);
double hl_cl_light_kept_entries(const hl_cl_light *l, const uint32_t *bits, double *per_range);
/* Whether the relighter runs the GPU shape's dot products
 * (kernels/relight/relight_items.cl: a work-item a position, no walks). */
int hl_cl_light_gpu_shape(const hl_cl_light *l);
/* Whether its selection runs as one work-group (select_group.cl, the GPU
 * shape where the device takes it) rather than one work-item. */
int hl_cl_light_select_as_group(const hl_cl_light *l);
/* Whether range rg takes the tile walk rather than the column walk
 * (kernels/relight/relight.cl) when `kept` kept slots hold `entries` of its column
 * entries. */
int hl_cl_light_tile_walk(const hl_cl_light *l, uint32_t rg, double entries, uint32_t kept);
/* Of the tile walk's words for the kept slots in bits (a group of
 * HL_TILE_GROUP kept slots over 32 tiles of a range that takes the tile
 * walk), those where every slot holds every tile, walked without testing
 * the bits, and the rest. Needs the columns in one part. */
hl_result hl_cl_light_tile_words(hl_cl_light *l, const uint32_t *bits, uint64_t *dense, uint64_t *mixed);
/* Bytes the dot-product kernel reads and writes for the last selection
 * (each byte once: what stays in cache is not counted twice). */
hl_result hl_cl_light_bytes_read(hl_cl_light *l, double *bytes);
/* Relight in parts (host/src/relight/cl_parts.c): the parts the dot
 * products run in (1: all the columns on the device at once); the device
 * bytes the columns of the relighter's cut take all at once (entries,
 * starts, tile bits, ranges); and the device memory a context's
 * buffers hold now (counted against its limit). */
uint32_t hl_cl_light_parts(const hl_cl_light *l);
/* 1 where the parts each have buffers of their own, uploaded once (the
 * device holds all the columns, but not in one allocation). */
int hl_cl_light_parts_resident(const hl_cl_light *l);
uint64_t hl_cl_light_column_bytes(const hl_cl_light *l);
uint64_t hl_cl_memory_used(const hl_context *ctx);
/* The largest buffer the context could make now: the device's largest
 * allocation, within what its memory limit leaves (hl_cl_memory_free:
 * UINT64_MAX when there is no limit). */
uint64_t hl_cl_largest_buffer(const hl_context *ctx);
uint64_t hl_cl_memory_free(const hl_context *ctx);
/* The bytes of all the relighter's device buffers (cl_light_probe.c). */
uint64_t hl_cl_light_device_bytes(const hl_cl_light *l);
/* The device's read bandwidth: median of reps passes over `bytes`. */
hl_result hl_cl_read_bandwidth(hl_context *ctx, size_t bytes, uint32_t reps, double *bytes_per_s);

#endif
