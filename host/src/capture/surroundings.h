/* surroundings.h - what surroundings.c (the public hl_surroundings_*)
 * needs from surroundings_gltf.c: glTF's emissive strength, which
 * assimp 5.2 does not read.
 *
 * Depends on: hl_internal.h.
 */
#ifndef HL_SURROUNDINGS_H
#define HL_SURROUNDINGS_H

#include <stdint.h>

#include "hl_internal.h"

/* A JSON document deeper than this is refused (no glTF nests near it;
 * it bounds the recursion of the skipper). */
#define HL_GLTF_MAX_DEPTH 64

/* For a glTF 2.0 file (.gltf text, or .glb's JSON chunk) that uses
 * KHR_materials_emissive_strength: strength[m] (nmeshes floats, set to 1
 * for every mesh first) becomes the emissiveStrength of the material of
 * the m-th primitive in the file's order (meshes, then their primitives),
 * which is the m-th mesh assimp 5.2 makes. Any other file leaves every
 * strength 1. Errors (naming path): the file cannot be read, its JSON is
 * malformed, the primitives are not nmeshes (so the order cannot be
 * trusted), a strength not a finite number >= 0, a material index out of
 * range. */
hl_result hl_gltf_emissive_strength_(hl_context *ctx, const char *path, uint32_t nmeshes, float *strength);

struct hl_surroundings;
/* The file the surroundings came from (or "surroundings from arrays"),
 * for messages. */
const char *hl_surroundings_name_(const struct hl_surroundings *s);

#endif
