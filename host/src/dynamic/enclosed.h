/* enclosed.h - a rigid body's vertices that lie inside its own closed
 * parts (a part modelled inside another, a pin through a hole): every ray
 * over such a vertex's hemisphere meets the inside of the body, so it
 * gets no light at all, however the body moves. The dynamic frame makes
 * them black (dyn_frame.c), where its shadow maps' biases let light
 * through the thin shell around them (DYNAMIC.md, section 5).
 * Depends on: dynamic.h, visibility's rays.h (Embree), core.
 */
#ifndef HL_ENCLOSED_H
#define HL_ENCLOSED_H

#include <stdint.h>

#include "dynamic.h"
#include "hl_internal.h"

/* Rays a vertex casts: the 26 directions of a 3 x 3 x 3 grid's cells
 * around the centre, those at least this cosine above the vertex's
 * horizon (9 to 17 of them), and its normal; where all of them meet the
 * body from behind, HL_ENCLOSED_CONFIRM directions of a Fibonacci
 * sphere (about 20 degrees apart; some 120 above the horizon) confirm
 * it, so that an opening the first rays missed (the Utah teapot's
 * spout) is seen. */
#define HL_ENCLOSED_MIN_COS 0.1f
#define HL_ENCLOSED_CONFIRM 256u
/* A shell met nearer than this many ray offsets (rays.c's robust
 * offset) does not enclose: it is the other side of a sheet modelled
 * with both sides, or a face coincident with the vertex's own. */
#define HL_ENCLOSED_MIN_GAP 16.0
/* A body's winding is trusted when at least this share of its triangles
 * turn their winding's normal the way their vertex normals point: a back
 * face is told by the winding, and a body modelled with faces both ways
 * (double-sided materials) would show "insides" everywhere. */
#define HL_ENCLOSED_WINDING_SHARE 0.99

/* out (o->nverts bytes): 1 where the vertex is enclosed: each of its
 * rays of both sets, from the robust offset along its normal, first
 * meets a triangle of the body from behind (by the winding). A body without
 * normals, or whose winding is not trusted, has none. *count gets how
 * many. */
hl_result hl_dyn_enclosed(hl_context *ctx, const hl_dyn_object *o, uint8_t *out, uint32_t *count);

#endif
