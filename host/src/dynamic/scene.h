/* scene.h - dynamic scenes: several rigid bodies and how they move
 * (scene.c: loading through assimp and the built-in scene; scene_anim.c:
 * sampling the file's node animation, composing the hierarchy, motion set
 * by the program, bounds).
 *
 * A body is one node of the file that holds meshes: its meshes merged,
 * welded and given normals by the shared mesh builder (kept as they are
 * with keep_triangles, below), in the node's own
 * coordinates with the static scale of its world transform baked in (the
 * stretch K of the polar decomposition M = Q K of its world matrix at
 * the animation's first key time, or at rest without one; for a node
 * under parents without scale that is the node's own scale; a mirror
 * goes into K, with the winding reversed). Its world transform at time t
 * is then rigid: xf = world(t) K^-1. Bodies are numbered in depth-first
 * order of the nodes and named as the importer names the node (assimp
 * 5.2 names an unnamed glTF node "nodes[N]" and adds a node "ROOT" above
 * a glTF scene's several roots).
 *
 * Motion:
 * - the file's node animation (one chosen at load): position keys
 *   linear, rotation keys slerp on the shorter arc (so a key pair more
 *   than half a turn apart turns the short way), scaling keys constant
 *   (a constant scale is baked like a static one), clamped:
 *   before a channel's first key it holds the first key, after its last
 *   key the last (the file's pre/post states are not used). Key times are
 *   ticks / ticks-per-second, 25 ticks a second where the file gives 0
 *   (the default of assimp's own viewer). Step and cubic-spline curves
 *   are sampled as linear (assimp 5.2 does not say which a key has).
 * - the program's transform P of a body (default identity), a rigid
 *   transform in world space applied after the animation:
 *   world = P world_anim(t), and the nodes under the body's node move
 *   with it.
 * Refused: bones (skinning) or mesh/morph channels with an animation
 * (a skinned file loads in its bind pose with HL_DYN_NO_ANIMATION; each
 * refusal says so, HL_DYN_REST_POSE_HINT),
 * scaling keys that change over time, a rotating node under a
 * non-uniformly scaled one (that shears), non-finite keys or node
 * transforms, key times that go backwards, a scene without triangles.
 *
 * A scene is not safe to use from two threads at once (hl_dyn_scene_at
 * writes the scene's scratch). It keeps the context it was made with for
 * its errors: destroy the scene before the context.
 *
 * Depends on: dynamic.h (hl_dyn_object), haarlight.h (hl_mesh,
 * hl_mesh_load_desc, hl_ground_desc), hl_internal.h.
 */
#ifndef HL_DYN_SCENE_H
#define HL_DYN_SCENE_H

#include <stdint.h>

#include "dynamic.h"
#include "hl_internal.h"
#include "material.h"

typedef struct hl_dyn_scene hl_dyn_scene;

/* desc.animation: the rest pose, no animation. */
#define HL_DYN_NO_ANIMATION (-1)
/* What every refusal of an animation that cannot be followed ends with:
 * the option that loads the file without it. */
#define HL_DYN_REST_POSE_HINT                                                                                          \
    "; --rest-pose (HL_DYNAMIC_REST_POSE) loads the file without its animation: its nodes as stored, skinned "     \
    "meshes in their bind pose, morph targets at their base"


/* hl_dyn_scene_desc fields and defaults (all zero: the defaults):
 *   mesh            per body, as hl_mesh_load: albedo where the file gives
 *                   none (io/material.h), up axis ('z' turns the whole scene
 *                   so that +Z becomes +Y), keep_winding
 *   animation       0: the first (the rest pose if the file has none);
 *                   k: the k-th (counting from 0); HL_DYN_NO_ANIMATION
 *   animation_name  NULL, or the name of the animation to use (overrides
 *                   animation)
 *   keep_triangles  1: each body holds its node's triangles as the file
 *                   gives them, in file order, three vertices of its own
 *                   each (tri 0 1 2, 3 4 5, ...), none welded or dropped,
 *                   no normals and no albedo (NULL), with the file
 *                   mesh each came from (hl_dyn_scene_body_tri_mesh) and
 *                   that mesh's emission (hl_dyn_scene_mesh_emission):
 *                   what the surroundings need to keep each triangle's
 *                   light on it (host/src/capture/surroundings.c)
 */
typedef struct hl_dyn_scene_desc {
    hl_mesh_load_desc mesh;
    int animation;
    const char *animation_name;
    int keep_triangles;
} hl_dyn_scene_desc;

/* Loads any file assimp reads as a scene of rigid bodies, with the
 * defaults above. Errors name the file (HL_ERR_IO, HL_ERR_FORMAT,
 * HL_ERR_MESH, HL_ERR_INVALID_ARGUMENT). */
hl_result hl_dyn_scene_load(hl_context *ctx, const char *path, hl_dyn_scene **out);
hl_result hl_dyn_scene_load_desc(hl_context *ctx, const char *path, const hl_dyn_scene_desc *desc,
                                 hl_dyn_scene **out);

/* The built-in scene: body 0 "object", the mesh's object (its vertices
 * before object_vertex_count), and, when ground is not NULL, body 1
 * "ground", the plane hl_mesh_add_ground would append with that desc (same
 * extent, resolution, height and albedo), as a body of its own. A mesh
 * that already carries a ground gives it as body 1 (ground must then be
 * NULL). Both start at the identity; there is no animation. */
hl_result hl_dyn_scene_from_mesh(hl_context *ctx, const hl_mesh *mesh, const hl_ground_desc *ground,
                                 hl_dyn_scene **out);

/* A scene of one body named body_name, at the identity without
 * animation, holding count triangles (9 floats each, copied) as
 * keep_triangles keeps them, all from mesh 0 (no emission of its own);
 * name is the scene's, for messages. Corners are not checked here. */
hl_result hl_dyn_scene_from_triangles(hl_context *ctx, const char *name, const char *body_name,
                                      const float *positions, uint32_t count, hl_dyn_scene **out);

void hl_dyn_scene_destroy(hl_dyn_scene *scene);

/* ------------------------------------------------------------ queries */

uint32_t hl_dyn_scene_body_count(const hl_dyn_scene *scene);
/* The node's name as the importer gave it (NULL for a body out of range). */
const char *hl_dyn_scene_body_name(const hl_dyn_scene *scene, uint32_t body);
/* Linear RGB albedo, 3 per vertex of the body (the hl_dyn_object's). */
const float *hl_dyn_scene_body_albedo(const hl_dyn_scene *scene, uint32_t body);
/* The body whose node is the nearest ancestor of this body's node, or -1. */
int32_t hl_dyn_scene_body_parent(const hl_dyn_scene *scene, uint32_t body);
/* With keep_triangles: the index of the file's mesh (assimp's, in the
 * file's order) each of the body's triangles came from (NULL otherwise or
 * out of range), and the number of the file's meshes. */
const uint32_t *hl_dyn_scene_body_tri_mesh(const hl_dyn_scene *scene, uint32_t body);
uint32_t hl_dyn_scene_mesh_count(const hl_dyn_scene *scene);
/* With keep_triangles: mesh m's material's emissive colour
 * (AI_MATKEY_COLOR_EMISSIVE, 0 without one) times its emissive intensity
 * (AI_MATKEY_EMISSIVE_INTENSITY, 1 without one), RGB, as the file has it
 * (not checked); NULL otherwise or out of range. */
const float *hl_dyn_scene_mesh_emission(const hl_dyn_scene *scene, uint32_t mesh);
/* The first body of that name (in depth-first order of the nodes), or -1. */
int32_t hl_dyn_scene_find(const hl_dyn_scene *scene, const char *name);
/* The chosen animation's name (NULL for none) and its key range in
 * seconds (both 0 for none): outside [start, end] every body is clamped. */
const char *hl_dyn_scene_animation(const hl_dyn_scene *scene, double *start, double *end);

/* ------------------------------------------------------------ motion */

/* Every body at time t (seconds, finite and >= 0; the part of an
 * animation before 0 s, which some formats write, is not sampled): out[b] for b <
 * body_count, pos/normal/tri pointing at the scene's arrays (valid until
 * it is destroyed) and xf its rigid world transform. */
hl_result hl_dyn_scene_at(hl_dyn_scene *scene, double t, hl_dyn_object *out);

/* The world bounding box of every body's vertices at time t. */
hl_result hl_dyn_scene_bounds(hl_dyn_scene *scene, double t, float lo[3], float hi[3]);
/* Appends body "ground" (a root node of its own, still): the plane
 * hl_mesh_add_ground (desc may be NULL) would put under the bodies' world
 * bounds over the whole animation (64 times from its start to its end;
 * once without one), with their mean albedo. */
hl_result hl_dyn_scene_add_ground(hl_dyn_scene *scene, const hl_ground_desc *desc);

/* The program's transform P of a body (row-major 3x4 like
 * hl_dyn_object.xf): finite and rigid (|R^T R - I| and |det R - 1| within
 * HL_DYN_RIGID_TOL), else HL_ERR_INVALID_ARGUMENT; the stored rotation is
 * re-orthonormalised. */
hl_result hl_dyn_scene_set_transform(hl_dyn_scene *scene, uint32_t body, const float xf[12]);
/* Places the whole file: m (row-major 3x4, finite; the caller checks its
 * shape) acts on every root node after the up-axis turn, so before the
 * program's transforms, as a root node of the file would. It may scale,
 * so the bodies' xf are then not rigid: for the surroundings, which pose
 * triangles by xf and nothing else. */
hl_result hl_dyn_scene_set_placement(hl_dyn_scene *scene, const double m[12]);
/* P as the rotation of angle radians about axis (any length but zero;
 * ignored when angle is 0) then the translation. */
hl_result hl_dyn_scene_set_pose(hl_dyn_scene *scene, uint32_t body, const double translate[3],
                                const double axis[3], double angle);
void hl_dyn_scene_get_transform(const hl_dyn_scene *scene, uint32_t body, float xf[12]);

/* How far from rigid a transform handed in by the program may be: float
 * matrices built from angles carry about 1e-7 of error per entry; 1e-4
 * lets them through and still refuses any real scale or shear. */
#define HL_DYN_RIGID_TOL 1e-4

/* ------------------------------------------------ internals (scene*.c) */

/* One channel of the chosen animation, times in seconds; scale is
 * constant (checked), so it is baked in the node's local matrix. */
typedef struct dyn_channel {
    uint32_t npos, nrot;
    double *pos_t, *pos;   /* npos times, 3 npos values */
    double *rot_t, *rot;   /* nrot times, 4 nrot values (w, x, y, z), unit */
} dyn_channel;

/* A node of the file's hierarchy, in depth-first order (parents first). */
typedef struct dyn_node {
    char *name;
    int32_t parent;        /* node index, -1 for the root */
    int32_t body;          /* body index, -1 where it holds no geometry */
    int triangles;         /* 1 if its meshes hold a triangle (it will be a body) */
    double rest[12];       /* local affine transform, row-major 3x4 */
    /* with a channel: local(t) = T(t) R(t) S; T, R and S default to the
       rest transform's own where the channel has no such keys */
    int has_channel;
    dyn_channel ch;
    double rest_t[3], rest_q[4], scale[3];
} dyn_node;

typedef struct dyn_body {
    float *pos, *normal, *albedo;
    uint32_t *tri;
    uint32_t nverts, ntris;
    uint32_t node;
    double kinv[9];        /* inverse of the baked stretch K */
    double P[12];          /* the program's transform */
    uint32_t *tri_mesh;    /* keep_triangles: the file mesh of each triangle */
    struct hl_surface *surf; /* its triangles' textures, UVs and bases, or NULL
                                (io/material.h; the textures are the scene's) */
} dyn_body;

struct hl_dyn_scene {
    hl_context *ctx;
    char *name;            /* the file, for messages */
    uint32_t nnodes, nbodies;
    dyn_node *nodes;
    dyn_body *bodies;
    double up[9];          /* the up-axis turn applied to the root */
    double place[12];      /* hl_dyn_scene_set_placement: after up */
    char *anim_name;       /* NULL: no animation */
    double t_start, t_end;
    double *world;         /* scratch: 12 per node */
    uint32_t nmeshes;      /* keep_triangles: the file's meshes */
    float *mesh_emission;  /* keep_triangles: 3 per file mesh */
    hl_materials mats;     /* the textures of the bodies' surfaces (none: count 0) */
};

struct aiScene;
/* scene_anim.c: the animation desc chooses, its channels copied onto the
 * nodes (times in seconds, checked finite and in order, scale constant). */
hl_result hl_dyn_load_animation_(hl_dyn_scene *s, const struct aiScene *as, const hl_dyn_scene_desc *d);
/* scene_anim.c: refuses a rotating node under an uneven scale. */
hl_result hl_dyn_check_rigid_(hl_dyn_scene *s);
/* scene_anim.c: the local transform of node n at time t into out. */
void hl_dyn_node_local_(const dyn_node *n, double t, double out[12]);
/* scene_anim.c: every node's world affine transform (scene->world) and
 * every body's xf at time t (t checked by the caller). */
void hl_dyn_compose_(hl_dyn_scene *scene, double t, hl_dyn_object *out);
/* scene_anim.c: 3x4 affine helpers (row-major, double). */
void hl_dyn_xf_mul_(const double a[12], const double b[12], double out[12]);
void hl_dyn_xf_from_trsq_(const double t[3], const double q[4], const double s[3], double out[12]);
/* Splits a linear part into rotation q (unit, w first) and scale s so that
 * L = R(q) diag(s) where L is such; returns 0 when L is singular. */
int hl_dyn_decompose_(const double L[9], double q[4], double s[3]);
/* Polar decomposition L = Q K with Q a proper rotation (K takes any
 * mirror); returns 0 when L is singular or not finite. */
int hl_dyn_polar_(const double L[9], double Q[9], double K[9]);
int hl_dyn_inv3_(const double a[9], double out[9]);

#endif
