/* ply_out.c - a coloured mesh as binary little-endian PLY.
 *
 * Per vertex: float x y z, float nx ny nz, then red green blue, either
 * float linear radiance (the names MeshLab and Blender read as float
 * colours) or uchar tone-mapped sRGB codes. Faces: property list uchar int
 * vertex_indices. Bytes are assembled explicitly in little-endian order,
 * whatever the host. The file is written to <path>.tmp.<pid> and renamed
 * into place only when complete; on failure the temporary is removed.
 *
 * Dependencies: hl_internal.h (errors, allocation), hl_tonemap_srgb8,
 * libc, POSIX (getpid; fsync through hl_sync_fd).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "hl_internal.h"

/* Bytes buffered before each fwrite. */
#define HL_PLY_BUFFER (1u << 20)

typedef struct ply_writer {
    FILE *f;
    unsigned char *buf;
    size_t len;
    int err; /* errno of the first failure, 0 while all is well */
} ply_writer;

static void pw_flush(ply_writer *w)
{
    if (w->err || w->len == 0) {
        w->len = 0;
        return;
    }
    errno = 0;
    if (fwrite(w->buf, 1, w->len, w->f) != w->len) w->err = errno ? errno : EIO;
    w->len = 0;
}

static void pw_bytes(ply_writer *w, const void *p, size_t n)
{
    const unsigned char *s = p;
    while (n > 0) {
        if (w->len == HL_PLY_BUFFER) pw_flush(w);
        size_t room = HL_PLY_BUFFER - w->len;
        size_t k = n < room ? n : room;
        memcpy(w->buf + w->len, s, k);
        w->len += k;
        s += k;
        n -= k;
    }
}

static void pw_u32(ply_writer *w, uint32_t x)
{
    unsigned char b[4] = {(unsigned char)(x & 0xffu), (unsigned char)((x >> 8) & 0xffu),
                          (unsigned char)((x >> 16) & 0xffu), (unsigned char)(x >> 24)};
    pw_bytes(w, b, 4);
}

static void pw_f32(ply_writer *w, float f)
{
    uint32_t x;
    memcpy(&x, &f, 4);
    pw_u32(w, x);
}

static hl_result check_mesh(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                            const char *path, int tonemapped8, float exposure_ev)
{
    if (!path || !*path) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "PLY output: no path given");
    if (!mesh) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: mesh is NULL", path);
    if (!vertex_rgb) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: vertex colours are NULL", path);
    if ((mesh->vertex_count && (!mesh->positions || !mesh->normals)) ||
        (mesh->triangle_count && !mesh->indices))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: mesh has no position, normal or index array",
                       path);
    /* Indices are written as PLY int. */
    if (mesh->vertex_count > (uint32_t)INT32_MAX)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: %u vertices do not fit PLY int indices", path,
                       mesh->vertex_count);
    for (size_t i = 0; i < 3 * (size_t)mesh->triangle_count; i++)
        if (mesh->indices[i] >= mesh->vertex_count)
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: triangle %zu refers to vertex %u of %u", path,
                           i / 3, mesh->indices[i], mesh->vertex_count);
    for (size_t i = 0; i < 3 * (size_t)mesh->vertex_count; i++)
        if (!isfinite(vertex_rgb[i]))
            return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                           "%s: colour of vertex %zu (counting from 0) is not finite (channel %zu = %g)",
                           path, i / 3, i % 3, (double)vertex_rgb[i]);
    if (tonemapped8 && !isfinite(exposure_ev))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: exposure %g EV is not finite", path,
                       (double)exposure_ev);
    return HL_OK;
}

hl_result hl_mesh_save_ply(hl_context *ctx, const hl_mesh *mesh, const float *vertex_rgb,
                           const char *path, int tonemapped8, float exposure_ev)
{
    hl_result r = check_mesh(ctx, mesh, vertex_rgb, path, tonemapped8, exposure_ev);
    if (r != HL_OK) return r;

    size_t tlen = strlen(path) + 32;
    char *tmp = hl_malloc(ctx, tlen, "PLY temporary file name");
    if (!tmp) return HL_ERR_OUT_OF_MEMORY;
    snprintf(tmp, tlen, "%s.tmp.%ld", path, (long)getpid());

    ply_writer w = {0};
    w.buf = hl_malloc(ctx, HL_PLY_BUFFER, "PLY output buffer");
    if (!w.buf) {
        free(tmp);
        return HL_ERR_OUT_OF_MEMORY;
    }
    errno = 0;
    w.f = fopen(tmp, "wb");
    if (!w.f) {
        int e = errno ? errno : EIO;
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot create temporary file %s: %s", path, tmp, strerror(e));
        free(w.buf);
        free(tmp);
        return r;
    }

    char header[512];
    const char *ctype = tonemapped8 ? "uchar" : "float";
    int hn = snprintf(header, sizeof header,
                      "ply\n"
                      "format binary_little_endian 1.0\n"
                      "comment haarlight %s\n"
                      "element vertex %u\n"
                      "property float x\nproperty float y\nproperty float z\n"
                      "property float nx\nproperty float ny\nproperty float nz\n"
                      "property %s red\nproperty %s green\nproperty %s blue\n"
                      "element face %u\n"
                      "property list uchar int vertex_indices\n"
                      "end_header\n",
                      tonemapped8 ? "tone-mapped sRGB colours" : "linear radiance colours",
                      mesh->vertex_count, ctype, ctype, ctype, mesh->triangle_count);
    pw_bytes(&w, header, (size_t)hn);

    for (uint32_t v = 0; v < mesh->vertex_count; v++) {
        for (int k = 0; k < 3; k++) pw_f32(&w, mesh->positions[3 * (size_t)v + k]);
        for (int k = 0; k < 3; k++) pw_f32(&w, mesh->normals[3 * (size_t)v + k]);
        if (tonemapped8) {
            unsigned char c[3];
            for (int k = 0; k < 3; k++) c[k] = hl_tonemap_srgb8(vertex_rgb[3 * (size_t)v + k], exposure_ev);
            pw_bytes(&w, c, 3);
        } else {
            for (int k = 0; k < 3; k++) pw_f32(&w, vertex_rgb[3 * (size_t)v + k]);
        }
    }
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        unsigned char three = 3;
        pw_bytes(&w, &three, 1);
        for (int k = 0; k < 3; k++) pw_u32(&w, mesh->indices[3 * (size_t)t + k]);
    }
    pw_flush(&w);
    if (!w.err) {
        errno = 0;
        if (fflush(w.f) != 0) w.err = errno ? errno : EIO;
    }
    if (!w.err) w.err = hl_sync_fd(fileno(w.f));
    errno = 0;
    if (fclose(w.f) != 0 && !w.err) w.err = errno ? errno : EIO;
    free(w.buf);
    if (w.err) {
        remove(tmp);
        r = hl_fail(ctx, HL_ERR_IO, "%s: writing %s failed: %s", path, tmp, strerror(w.err));
        free(tmp);
        return r;
    }
    errno = 0;
    if (rename(tmp, path) != 0) {
        int e = errno ? errno : EIO;
        remove(tmp);
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot rename %s into place: %s", path, tmp, strerror(e));
        free(tmp);
        return r;
    }
    free(tmp);
    return HL_OK;
}
