/* assimp_guard.h - refusing input that would crash, hang or exhaust
 * assimp 5.2 before it sees it (assimp_guard.c). Private to
 * mesh_import.c, which calls the file guard before the first import and
 * the scene guard between the raw import and the one with post-processing
 * (load_assimp there gives the order and why).
 *
 * Depends on: hl_internal.h (hl_fail); assimp's scene types, declared
 * here only by name.
 */
#ifndef HL_ASSIMP_GUARD_H
#define HL_ASSIMP_GUARD_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "hl_internal.h"

struct aiScene;

/* The file guards, in this order: PLY (header and body walk), binary and
 * JSON glTF (lengths, and a .glb or .gltf name on another kind of file),
 * OFF (counts against the lines that follow). f is open at the start of
 * path, file_size bytes; it is rewound between guards and left anywhere.
 * Returns 0, or 1 with the problem in msg (msg_size bytes). */
int hl_assimp_file_problem_(const char *path, FILE *f, uint64_t file_size, char *msg, size_t msg_size);

/* The scene guard: what assimp 5.2's Triangulate and PretransformVertices
 * steps need of the raw (validated) scene s. HL_OK when they can run; else
 * HL_ERR_FORMAT, HL_ERR_MESH or HL_ERR_OUT_OF_MEMORY with a message naming
 * path. */
hl_result hl_raw_scene_problem_(hl_context *ctx, const char *path, const struct aiScene *s);

#endif
