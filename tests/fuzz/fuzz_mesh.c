/* fuzz_mesh.c - libFuzzer target for mesh import (hl_mesh_load: assimp,
 * then the builder's validation, welding, orientation and normals).
 *
 * Input: one selector byte, then the file. The selector picks the scratch
 * file's extension (byte % 6: .obj .ply .off .stl .gltf .glb), since assimp
 * chooses its importer by extension first; the seeds use '0'..'5'. The up
 * axis ('z' when the selector's bit 7 is set) exercises the rotation too.
 *
 * On success the mesh must keep what haarlight.h promises for a loaded
 * mesh: at least one triangle, no repeated index in a triangle, indices in
 * range, finite positions, unit normals, albedo in [0, 1], no ground, and
 * stats that account for every vertex and triangle of the file.
 */
#include "fuzz_common.h"

static const char *const extensions[] = {".obj", ".ply", ".off", ".stl", ".gltf", ".glb"};
#define EXTENSION_COUNT (sizeof extensions / sizeof extensions[0])

static void check_loaded(const hl_mesh *m, const hl_mesh_stats *st)
{
    fuzz_check_mesh(m);
    FUZZ_REQUIRE(m->triangle_count >= 1, "a loaded mesh with no triangle");
    FUZZ_REQUIRE(m->object_vertex_count == m->vertex_count, "a loaded mesh with %u ground vertices",
                 m->vertex_count - m->object_vertex_count);
    for (size_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *f = m->indices + 3 * t;
        FUZZ_REQUIRE(f[0] != f[1] && f[1] != f[2] && f[0] != f[2], "triangle %zu repeats a vertex", t);
    }
    for (size_t v = 0; v < m->vertex_count; v++) {
        const float *n = m->normals + 3 * v, *a = m->albedo + 3 * v;
        double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        FUZZ_REQUIRE(fabs(len - 1.0) < 1e-3, "vertex %zu: normal length %g", v, len);
        for (int k = 0; k < 3; k++)
            FUZZ_REQUIRE(a[k] >= 0.0f && a[k] <= 1.0f, "vertex %zu: albedo %g outside [0, 1]", v, (double)a[k]);
    }
    uint64_t removed = (uint64_t)st->merged_vertices + st->unreferenced_vertices;
    FUZZ_REQUIRE(removed <= st->file_vertices && st->file_vertices - removed == m->vertex_count,
                 "stats: %u file vertices - %u merged - %u unreferenced != %u", st->file_vertices,
                 st->merged_vertices, st->unreferenced_vertices, m->vertex_count);
    FUZZ_REQUIRE(st->degenerate_triangles <= st->file_triangles &&
                     st->file_triangles - st->degenerate_triangles == m->triangle_count,
                 "stats: %u file triangles - %u degenerate != %u", st->file_triangles, st->degenerate_triangles,
                 m->triangle_count);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    hl_context *ctx = fuzz_context();
    const char *path = fuzz_write_input(data + 1, size - 1, extensions[data[0] % EXTENSION_COUNT]);
    hl_mesh_load_desc desc = {.up_axis = (data[0] & 0x80) ? 'z' : 'y'};
    hl_mesh *m = NULL;
    hl_mesh_stats st;
    hl_result r = hl_mesh_load(ctx, path, &desc, &m, &st);
    unlink(path);
    fuzz_check_result(r, m);
    if (m) check_loaded(m, &st);
    hl_mesh_destroy(m);
    return 0;
}
