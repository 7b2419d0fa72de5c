/* material.h - albedo from a file's materials, as assimp reads them:
 * the base-colour factor times the base-colour texture (glTF), or the
 * diffuse colour and texture (OBJ/MTL, FBX, Collada), times the vertex
 * colours where the mesh has them.
 *
 * The per-vertex albedo the engine shades with is split in two parts so
 * that the mesh builder can weld and average them:
 *   - the base (factor x vertex colour), per file vertex, which is also a
 *     welding key, so a seam between two materials or two colours stays;
 *   - the texture's average around each triangle corner (hat-weighted over
 *     the triangle, in linear light), which the builder averages over the
 *     corners meeting at a welded vertex, weighted by their areas: the
 *     texture's average over the vertex's neighbourhood, continuous across
 *     UV seams.
 *
 * A material that sets nothing (white, no texture: what assimp gives a
 * glTF primitive without a material, or "DefaultMaterial" for OBJ and PLY)
 * counts as no material: the mesh's albedo is then the load's constant
 * (--albedo, default 0.8), or its vertex colours.
 *
 * Depends on: assimp's C structures, hl_internal.h, stb_image (decoding
 * PNG and JPEG; Debian's libstb).
 */
#ifndef HL_MATERIAL_H
#define HL_MATERIAL_H

#include <stdint.h>

#include <assimp/scene.h>

#include "hl_internal.h"

/* Largest texture decoded: 8,192 x 8,192 pixels (stored as 8-bit RGB, so
 * 192 MiB), and at most 32,768 on a side. Larger is an error. */
#define HL_TEXTURE_MAX_PIXELS (8192ull * 8192ull)
#define HL_TEXTURE_MAX_SIDE 32768u
/* Largest texture file read into memory. */
#define HL_TEXTURE_MAX_FILE_BYTES (512ull << 20)

typedef struct hl_texture {
    char *name;   /* as the material names it, for messages */
    uint32_t w, h;
    uint8_t *rgb; /* w * h * 3 bytes, sRGB-encoded, row 0 at the top */
    /* the file's own bytes when it is a PNG or a JPEG (glTF's two image
       formats), so that a .glb written from the mesh can embed it as it
       was; NULL otherwise */
    uint8_t *file;
    size_t file_size;
    const char *format; /* "png", "jpg" or NULL */
} hl_texture;

typedef struct hl_material {
    float factor[3]; /* linear, clamped to [0, 1] */
    int32_t tex;     /* index into textures, -1 without */
    uint32_t uv;     /* the texture's UV channel */
    int given;       /* 0: sets nothing (see above) */
} hl_material;

typedef struct hl_materials {
    uint32_t count; /* = the scene's mNumMaterials */
    hl_material *mat;
    uint32_t ntex;
    hl_texture *tex;
    uint32_t uv_missing; /* textured meshes without the texture's UVs (warned) */
    uint32_t left_out;   /* base-colour textures not found or not decodable (warned) */
} hl_materials;

/* A mesh's textured surface, for pictures that keep the texture sharp
 * (haarlight.h, hl_surface_load): per triangle of the mesh's object, in
 * the mesh's order and winding, the texture's UVs at its corners, its
 * texture (-1: none) and its base (factor x vertex colour) at each
 * corner. Owns the materials and their textures. */
struct hl_surface {
    uint32_t triangle_count;
    float *uv;   /* 6 a triangle */
    int32_t *tex;
    float *base; /* 9 a triangle */
    hl_materials mats;
};

/* su's per-triangle arrays for ntri triangles, zeroed (the failure
 * recorded when out of memory); hl_surface_arrays_free_ frees them alone
 * (hl_surface_destroy frees the surface whole). */
hl_result hl_surface_arrays_(hl_context *ctx, hl_surface *su, uint32_t ntri);
void hl_surface_arrays_free_(hl_surface *su);

/* Builds a surface: su's arrays (by input triangle) get triangle t's
 * texture, corner UVs and bases from face af of am; with mirror, corners
 * 1 and 2 swap places, as a mirrored node's triangles are stored. */
void hl_surface_face_(const hl_materials *mats, const struct aiMesh *am, const struct aiFace *af,
                      const float fallback[3], hl_surface *su, size_t t, int mirror);
/* The surface of a built mesh of ntri triangles from in (by input
 * triangle) and the builder's origins (hl_mesh_extra), corners 1 and 2
 * swapped where the builder flipped the winding; no materials (the
 * caller gives them). */
hl_result hl_surface_finish_(hl_context *ctx, const hl_surface *in, const uint32_t *origin, uint32_t ntri,
                             int flipped, hl_surface **out);

/* Reads the materials the scene's meshes use and decodes their base-colour
 * textures (external files relative to path's folder, or embedded).
 * Errors name path, the material and the texture: a base-colour texture
 * that is unreadable, damaged or of absurd size, a non-finite factor. A
 * base-colour texture that is not found, or in a format the decoder does
 * not read, is left out with a warning (the factor alone), and so are
 * missing textures the engine does not use (normal, roughness, ...). */
hl_result hl_materials_read_(hl_context *ctx, const char *path, const struct aiScene *s, hl_materials *out);
void hl_materials_free_(hl_materials *m);

/* 1 when any mesh of s takes its albedo from the file (a given material
 * or vertex colours): the builder then gets per-vertex bases. */
int hl_materials_any_given_(const hl_materials *m, const struct aiScene *s);

/* 1 when any mesh of s has a base-colour texture and its UVs: the
 * builder then gets per-corner texture averages. */
int hl_materials_textured_(const hl_materials *m, const struct aiScene *s);

/* 1 when any mesh of s has vertex colours. */
int hl_materials_any_colors_(const struct aiScene *s);

/* One line on stderr (unless ctx is quiet) saying where the albedo came
 * from, when it came from the file's materials. */
void hl_materials_note_(hl_context *ctx, const char *path, const hl_materials *m);

/* The base of vertex v of mesh am into out[3]: the material's factor
 * (fallback where the material sets nothing and the mesh has no colours)
 * times the vertex colour, clamped to [0, 1]. */
void hl_material_vertex_base_(const hl_materials *m, const struct aiMesh *am, size_t v, const float fallback[3],
                              float out[3]);

/* The texture's hat-weighted average around each corner of face f of am
 * into out[9] (linear light); 1 everywhere when am's material has no
 * texture. */
void hl_material_face_tex_(const hl_materials *m, const struct aiMesh *am, const struct aiFace *f, float out[9]);

/* The texture's bilinear value at (u, v) (assimp's convention: v = 0 at
 * the image's bottom), repeating, linear light. */
void hl_texture_sample_(const hl_texture *t, float u, float v, float rgb[3]);

#endif
