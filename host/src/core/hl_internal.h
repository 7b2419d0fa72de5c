/* hl_internal.h - private declarations shared by the library's modules.
 *
 * Not installed. Holds the context layout, the error helper and the
 * internal interfaces between modules (geometry tables, stage runners,
 * third-party wrappers). Each third-party header is included by one file
 * (OpenCL's by device/cl_internal.h, for the files that talk to the
 * device); the rest of the library sees only the opaque types below.
 * Core depends on nothing above it: this header names the device only as
 * an incomplete struct.
 */
#ifndef HL_INTERNAL_H
#define HL_INTERNAL_H

#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "haarlight.h"
#include "hl_shared.h" /* the layouts the library shares with its kernels */

struct hl_cl; /* device/cl_internal.h */

struct hl_context {
    hl_backend backend;
    int threads;
    int quiet;
    char kernel_dir[1024];
    char device_name[256];
    char err[4096];
    struct hl_cl *cl; /* NULL for the reference backend */
    /* Set by hl_context_cancel, polled by the long loops. An atomic_int,
     * not a volatile sig_atomic_t: a signal handler may store to it only
     * because it is lock-free (C11 7.14.1.1; asserted below), and being
     * atomic it is also seen by the worker threads that poll it, which
     * volatile does not promise. */
    atomic_int cancelled;
};

#if ATOMIC_INT_LOCK_FREE != 2
#error "hl_context_cancel needs a lock-free atomic_int to be async-signal-safe"
#endif

/* Records a formatted message on ctx (may be NULL) and returns code. */
hl_result hl_fail(hl_context *ctx, hl_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* malloc/calloc that record HL_ERR_OUT_OF_MEMORY naming what was wanted. */
void *hl_malloc(hl_context *ctx, size_t bytes, const char *what);
void *hl_calloc(hl_context *ctx, size_t count, size_t size, const char *what);
/* Large arrays: 64-byte aligned, huge pages advised. Free with hl_free_big. */
void *hl_alloc_big(hl_context *ctx, size_t bytes, const char *what);
void hl_free_big(void *p);
/* Gives the whole pages inside [p, p + bytes) of an hl_alloc_big block
 * back to the system: their contents are lost (they read as zero), the
 * block stays valid and is still freed with hl_free_big. */
void hl_release_pages(void *p, size_t bytes);

#define HL_PI 3.14159265358979323846

/* Runs fn(arg) on `threads` threads (the caller's among them) and waits
 * for all; fewer if threads cannot be created. */
void hl_run_threads(int threads, void *(*fn)(void *), void *arg);

/* Monotonic wall clock in seconds. */
double hl_now(void);

/* fsync(fd), for output about to be renamed into place: 0, or the errno.
 * A file system that cannot sync (EINVAL, EROFS) counts as synced. */
int hl_sync_fd(int fd);

/* The end of an atomic write by a library that writes to a name (OpenEXR,
 * assimp): with r the writer's result, tmp (a finished file) is synced
 * and renamed onto path; on any failure tmp is removed. Returns r or the
 * failure, which names path. */
hl_result hl_publish_tmp(hl_context *ctx, const char *tmp, const char *path, hl_result r);

/* What hl_mesh_build_ may take and give besides the arrays:
 *   corner_tex  NULL, or 9 floats a triangle: a texture's average around
 *               each corner (io/material.h), multiplied into the colours
 *               after averaging over the corners that meet at each welded
 *               vertex, weighted by their triangles' areas;
 *   tri_origin  NULL, or room for triangle_count numbers: triangle t of
 *               the mesh (before any flip of the winding, which swaps
 *               corners 1 and 2) was input triangle tri_origin[t]. */
typedef struct hl_mesh_extra {
    const float *corner_tex;
    uint32_t *tri_origin;
} hl_mesh_extra;

/* mesh.c: validates raw arrays (name appears in errors), welds equal
 * positions, drops degenerate triangles and unreferenced vertices, computes
 * missing normals, orients closed meshes. colors and extra may be NULL. */
hl_result hl_mesh_build_(hl_context *ctx, const char *name, uint32_t vertex_count,
                         const float *positions, const float *normals, const float *colors,
                         const hl_mesh_extra *extra, uint32_t triangle_count, const uint32_t *indices,
                         const hl_mesh_load_desc *desc, hl_mesh **out, hl_mesh_stats *stats);

/* What of a file's motion a mesh load leaves behind (hl_mesh_load bakes
 * the nodes as stored, skinned meshes in their bind pose, morph targets
 * at their base): its animations, and its meshes with bones or morph
 * targets. */
typedef struct hl_mesh_motion {
    uint32_t animations, skinned, morphing;
} hl_mesh_motion;
/* mesh_import.c: hl_mesh_load, and the file's motion into *motion (zeros
 * on failure). */
hl_result hl_mesh_load_motion_(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, hl_mesh **out,
                               hl_mesh_stats *stats, hl_mesh_motion *motion);
/* The file's motion alone, from one validating parse (no mesh built, no
 * texture read); the same errors as a load's for a file it refuses. */
hl_result hl_mesh_probe_motion_(hl_context *ctx, const char *path, hl_mesh_motion *motion);
/* The same, and with surf the mesh's textured surface (io/material.h). */
hl_result hl_mesh_load_surface_(hl_context *ctx, const char *path, const hl_mesh_load_desc *desc, hl_mesh **out,
                                hl_mesh_stats *stats, hl_mesh_motion *motion, hl_surface **surf);

#endif
