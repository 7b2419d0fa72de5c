/* viewer_scene.c - writes the animated scene the viewer's dynamic_anim
 * case plays: a ground quad (node "ground", 6 x 6) and a cube "Box"
 * (corners at +-1) resting on it, whose translation keys slide it from
 * x = -2 at 0 s to x = +2 at 2 s.
 *
 *   viewer_scene OUT.gltf
 *
 * Depends on: tests/dynamic/scene_gen.h (the glTF writer of the scene
 * tests), libc.
 */
#include "../dynamic/scene_gen.h"

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: viewer_scene OUT.gltf\n");
        return 2;
    }
    sg_scene sc;
    memset(&sc, 0, sizeof sc);
    sc.nnodes = 2;
    /* named "ground" so that the viewer never drags it */
    sc.node[0] = (sg_node){.name = "ground", .parent = -1, .mesh = SG_GROUND, .has_s = 1, .s = {6, 1, 6}};
    sc.node[1] = (sg_node){.name = "Box", .parent = -1, .mesh = SG_CUBE, .has_t = 1, .t = {-2, 1, 0}};
    sc.node[1].kt = (sg_keys){2, {0, 2}, {{-2, 1, 0}, {2, 1, 0}}};
    if (sg_write_gltf(argv[1], &sc) != 0) {
        fprintf(stderr, "viewer_scene: cannot write %s\n", argv[1]);
        return 1;
    }
    return 0;
}
