/* make_terrain.c - writes a finely tessellated displaced terrain as a
 * binary PLY, a mesh of any size for measuring the precompute and the
 * relight at scale (millions of vertices; not committed: made when
 * needed).
 *
 *   make_terrain OUT.ply SIDE     SIDE x SIDE vertices (2 to 46341), so
 *                                 SIDE 1415 gives 2,002,225 vertices and
 *                                 3,998,792 triangles
 *
 * The ground spans [-1, 1] in x and z; its height is a sum of a few sine
 * ridges and bumps (amplitude 0.25 in all), smooth at any SIDE, so that
 * the terrain shadows itself at every scale: ridges hide the low sun,
 * valleys see a narrow sky. The same SIDE always gives the same bytes.
 *
 * Depends on: libc, libm.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The largest side: SIDE^2 vertices must fit a uint32 index (and the
 * project's meshes). */
#define TERRAIN_MAX_SIDE 46341u

static float height(double x, double z)
{
    /* ridges across the ground and round bumps: a terrain with valleys
       and crests at several scales */
    double h = 0.12 * sin(3.1 * x + 0.7 * z) + 0.06 * sin(7.3 * z - 2.1 * x) + 0.04 * cos(13.7 * x + 11.3 * z);
    h += 0.03 * exp(-40.0 * ((x - 0.3) * (x - 0.3) + (z + 0.2) * (z + 0.2)));
    return (float)h;
}

int main(int argc, char **argv)
{
    char *end = NULL;
    unsigned long side = argc == 3 ? strtoul(argv[2], &end, 10) : 0;
    if (argc != 3 || !end || *end || side < 2 || side > TERRAIN_MAX_SIDE) {
        fprintf(stderr, "usage: make_terrain OUT.ply SIDE (2 to %u)\n", TERRAIN_MAX_SIDE);
        return 2;
    }
    const uint32_t n = (uint32_t)side;
    const uint64_t nv = (uint64_t)n * n, nt = 2ull * (n - 1) * (n - 1);
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp", argv[1]);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        perror(tmp);
        return 1;
    }
    fprintf(f, "ply\nformat binary_little_endian 1.0\nelement vertex %llu\nproperty float x\nproperty float y\n"
               "property float z\nelement face %llu\nproperty list uchar uint vertex_indices\nend_header\n",
            (unsigned long long)nv, (unsigned long long)nt);
    for (uint32_t r = 0; r < n; r++)
        for (uint32_t c = 0; c < n; c++) {
            const double x = -1.0 + 2.0 * c / (n - 1), z = -1.0 + 2.0 * r / (n - 1);
            const float p[3] = {(float)x, height(x, z), (float)z};
            fwrite(p, 4, 3, f);
        }
    for (uint32_t r = 0; r + 1 < n; r++)
        for (uint32_t c = 0; c + 1 < n; c++) {
            /* counter-clockwise seen from above (+Y): the normals point up */
            const uint32_t a = r * n + c, b = a + 1, d = a + n, e = d + 1;
            unsigned char three = 3;
            const uint32_t t1[3] = {a, d, b}, t2[3] = {b, d, e};
            fwrite(&three, 1, 1, f);
            fwrite(t1, 4, 3, f);
            fwrite(&three, 1, 1, f);
            fwrite(t2, 4, 3, f);
        }
    if (ferror(f) | fclose(f) || rename(tmp, argv[1]) != 0) {
        perror(argv[1]);
        remove(tmp);
        return 1;
    }
    printf("%s: %llu vertices, %llu triangles\n", argv[1], (unsigned long long)nv, (unsigned long long)nt);
    return 0;
}
