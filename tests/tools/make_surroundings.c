/* make_surroundings.c - writes data/surroundings/lamp_orbit.gltf, the
 * example surroundings for `haarlight relight --surroundings`: a small
 * bright lamp carried once around the bunny of data/bunny_lowres.obj on
 * its ground, and three dark occluders further out.
 *
 * Re-make the file (from the repository root, after building):
 *   build-s/tests/make_surroundings data/surroundings/lamp_orbit.gltf
 * (the binary lies in the build folder's tests/; any build folder).
 *
 * The bunny (precompute data/bunny_lowres.obj --ground) spans x -4.96 to
 * 4.95, y 0 to 9.65, z -3.73 to 3.81: its centre, the capture point, is
 * near (0, 4.83, 0), and its ground reaches 0.75 x its larger extent
 * (7.5) beyond the footprint, to about |x| 12.4, |z| 11.3.
 *
 * Depends on: tests/capture/surr_gltf.h, libm.
 */
#include <math.h>
#include <stdio.h>

#include "surr_gltf.h"

/* The lamp's circle: radius 8 (1.6 x the bunny's half-width, so it
 * clears the ears and tail), at height 9 (near the top of the bunny, so
 * the shadow falls on the ground on the far side, about 9 from the
 * centre, inside the ground's 12). */
#define LAMP_RADIUS 8.0f
#define LAMP_HEIGHT 9.0f
/* An octahedron of this circumradius: about 0.7 square units seen from
 * the bunny, 0.009 sr at 9 units. */
#define LAMP_SIZE 0.6f
/* Radiance: a warm white times the strength. 120 x 0.009 sr gives about
 * 1.1 of irradiance at the bunny, a sky's worth, so one lamp lights it. */
#define LAMP_STRENGTH 120.0f
/* One turn in LAMP_PERIOD seconds, keyed every eighth of a turn (45
 * degrees apart: slerp takes the short way between keys less than half a
 * turn apart, so the lamp goes round in one direction). */
#define LAMP_PERIOD 4.0f
#define LAMP_KEYS 9

static const double PI = 3.14159265358979323846;

static void octahedron(float *tris, float r)
{
    const float v[6][3] = {{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
    const int f[8][3] = {{0, 2, 4}, {4, 2, 1}, {1, 2, 5}, {5, 2, 0}, {4, 3, 0}, {1, 3, 4}, {5, 3, 1}, {0, 3, 5}};
    for (int t = 0; t < 8; t++)
        for (int k = 0; k < 3; k++) memcpy(tris + 9 * t + 3 * k, v[f[t][k]], sizeof v[0]);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s OUT.gltf\n", argv[0]);
        return 2;
    }
    static float lamp[8 * 9], walls[3 * 12 * 9];
    octahedron(lamp, LAMP_SIZE);
    uint32_t nw = 0;
    /* a wall behind the bunny and two pillars, outside the lamp's circle
       (so they never hide it from the centre) and partly over the ground */
    sgf_box(walls, &nw, (const float[3]){0, 6, -16}, (const float[3]){12, 6, 0.5f});
    sgf_box(walls, &nw, (const float[3]){14, 5, 10}, (const float[3]){1, 5, 1});
    sgf_box(walls, &nw, (const float[3]){-13, 5, 11}, (const float[3]){1, 5, 1});
    sgf_scene sc = {0};
    sc.nmaterials = 2;
    sc.material[0] = (sgf_material){"lamp", {1.0f, 0.85f, 0.6f}, LAMP_STRENGTH};
    sc.material[1] = (sgf_material){"occluder", {0, 0, 0}, NAN};
    sc.nnodes = 4;
    sc.node[0] = (sgf_node){.name = "orbit", .parent = -1};
    sgf_keys *k = &sc.node[0].kr;
    k->n = LAMP_KEYS;
    for (int i = 0; i < LAMP_KEYS; i++) {
        double a = 2 * PI * i / (LAMP_KEYS - 1); /* about +Y: (x, y, z, w) = (0, sin a/2, 0, cos a/2) */
        k->t[i] = LAMP_PERIOD * (float)i / (LAMP_KEYS - 1);
        k->v[i][0] = 0.0f;
        k->v[i][1] = (float)sin(a / 2);
        k->v[i][2] = 0.0f;
        k->v[i][3] = (float)cos(a / 2);
    }
    sc.node[1] = (sgf_node){.name = "lamp", .parent = 0, .tris = lamp, .ntris = 8, .material = 0,
                            .t = {LAMP_RADIUS, LAMP_HEIGHT, 0}};
    sc.node[2] = (sgf_node){.name = "wall", .parent = -1, .tris = walls, .ntris = 12, .material = 1};
    sc.node[3] = (sgf_node){.name = "pillars", .parent = -1, .tris = walls + 12 * 9, .ntris = 24, .material = 1};
    if (sgf_write(&sc, argv[1]) != 0) {
        fprintf(stderr, "make_surroundings: cannot write %s\n", argv[1]);
        return 1;
    }
    return 0;
}
