/* test_mesh_bad.c - bad mesh input, refused with a message and no crash
 * (suite "mesh_bad"): non-finite positions, bad indices, no faces, files
 * that are no mesh, lying counts, missing and empty files, bad arguments,
 * scenes that place no mesh or too many vertices, and an import that runs
 * out of memory.
 * Contexts use the reference backend, so no OpenCL device is needed.
 * Depends on: haarlight_core, tests/common/mesh_util.h, HL_TMP,
 * fork/setrlimit.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_internal.h"
#include "hl_test.h"
#include "mesh_util.h"

/* ---------------------------------------------------------------- bad input */

static void test_bad_nan(void)
{
    hl_context *ctx = make_ctx();
    const char *cases[][2] = {
        {"mesh_bad_nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n"},
        {"mesh_bad_inf.obj", "v 0 0 0\nv 1 0 -inf\nv 0 1 0\nf 1 2 3\n"},
        {"mesh_bad_huge.obj", "v 0 0 0\nv 1 0 0\nv 0 1e50 0\nf 1 2 3\n"},
        {"mesh_bad_nan_colour.obj", "v 0 0 0 1 1 1\nv 1 0 0 1 nan 1\nv 0 1 0 1 1 1\nf 1 2 3\n"},
        {"mesh_bad_text_coord.obj", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        const char *path = tmp_path(cases[i][0]);
        write_text(path, cases[i][1]);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, i < 4 ? HL_ERR_MESH : HL_ERR_FORMAT);
        HL_CHECK(m == NULL, "no mesh on failure");
        if (i == 0) HL_CHECK(strstr(hl_context_last_error(ctx), "non-finite") != NULL, "says what is wrong");
    }
    hl_context_destroy(ctx);
}

static void test_bad_index(void)
{
    hl_context *ctx = make_ctx();
    const char *cases[][2] = {
        {"mesh_bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n"},
        {"mesh_bad_negative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n"},
        {"mesh_bad_zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"},
        {"mesh_bad_normal_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n"},
        {"mesh_bad_huge_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n"},
        {"mesh_bad_index.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                               "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        const char *path = tmp_path(cases[i][0]);
        write_text(path, cases[i][1]);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        if (i == 3 && r == HL_OK) {
            /* assimp accepts a bad normal index; what comes out must
             * still be usable: finite unit normals */
            double worst = 0.0;
            for (uint32_t v = 0; v < m->vertex_count; v++) {
                const float *n = m->normals + 3 * v;
                double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
                worst = isfinite(len) ? fmax(worst, fabs(len - 1.0)) : INFINITY;
            }
            hl_check_error("bad normal index: normal length", worst, 1e-6);
            hl_mesh_destroy(m);
            continue;
        }
        /* the importer reports bad indices (HL_ERR_FORMAT); the builder
         * catches any it lets through (HL_ERR_MESH) */
        expect_failure(ctx, path, r, HL_OK);
        HL_CHECK(r == HL_ERR_FORMAT || r == HL_ERR_MESH, "%s: got %s", path, hl_result_string(r));
    }
    hl_context_destroy(ctx);
}

static void test_bad_no_faces(void)
{
    hl_context *ctx = make_ctx();
    const char *cases[][2] = {
        {"mesh_no_faces.obj", "# only vertices\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"},
        {"mesh_only_lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\nf 1 2\n"},
        {"mesh_no_faces.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                              "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        const char *path = tmp_path(cases[i][0]);
        write_text(path, cases[i][1]);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, i < 2 ? HL_ERR_MESH : HL_OK);
    }
    hl_context_destroy(ctx);
}

/* PLY and OFF files whose counts claim more than the file holds: assimp
 * would make room for all of it first (gigabytes from a few hundred bytes,
 * or minutes of filling in zeros), so they are refused before it reads
 * them, quickly and with the reason. The same layouts with honest counts,
 * in both binary byte orders and with a blank line in ASCII, load. */
static void put_u32(unsigned char *p, uint32_t v, int big)
{
    for (int k = 0; k < 4; k++) p[big ? 3 - k : k] = (unsigned char)(v >> (8 * k));
}

/* A binary PLY of one triangle; the face list's count is `count`. */
static size_t binary_ply(unsigned char *buf, int big, uint32_t count)
{
    int n = snprintf((char *)buf, 512,
                     "ply\nformat binary_%s_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n",
                     big ? "big" : "little");
    static const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 0, -1};
    size_t at = (size_t)n;
    for (int i = 0; i < 9; i++) {
        uint32_t bits;
        memcpy(&bits, &xyz[i], 4);
        put_u32(buf + at, bits, big);
        at += 4;
    }
    put_u32(buf + at, count, big);
    at += 4;
    for (uint32_t i = 0; i < 3; i++, at += 4) put_u32(buf + at, i, big);
    return at;
}

/* Loads path, which must be refused (HL_ERR_FORMAT, naming the file) with
 * why in the message; the time taken goes into *slowest. */
static void refused_with(hl_context *ctx, const char *path, const char *why, double *slowest)
{
    hl_mesh *m = NULL;
    double t0 = hl_now();
    hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
    *slowest = fmax(*slowest, hl_now() - t0);
    expect_failure(ctx, path, r, HL_ERR_FORMAT);
    HL_CHECK(strstr(hl_context_last_error(ctx), why) != NULL, "%s: the message does not say \"%s\"", path, why);
    hl_mesh_destroy(m);
}

/* Loads path, which must give one triangle. */
static void one_triangle(hl_context *ctx, const char *path)
{
    hl_mesh *m = NULL;
    HL_CHECK(load(ctx, path, NULL, &m, NULL) == HL_OK && m && m->triangle_count == 1,
             "%s: an honest triangle must load", path);
    hl_mesh_destroy(m);
}

static void test_bad_counts(void)
{
    hl_context *ctx = make_ctx();
    static const char head[] = "ply\nformat ascii 1.0\nelement vertex %s\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                               "0 0 0\n1 0 0\n0 0 -1\n%s\n";
    const struct {
        const char *name, *vertices, *face;
        const char *why;
    } ascii[] = {
        {"mesh_ply_list.ply", "3", "300000000 0 1 2", "a list of 300000000 values"},
        {"mesh_ply_list_digits.ply", "3", "34444444444444444444444444444444 0 1 2", "a list of"},
        {"mesh_ply_elements.ply", "300000000", "3 0 1 2", "300000000 \"vertex\" elements"},
        {"mesh_ply_short.ply", "5", "3 0 1 2", "the file ends after"},
    };
    char text[1024];
    double slowest = 0.0;
    for (size_t k = 0; k < sizeof ascii / sizeof ascii[0]; k++) {
        snprintf(text, sizeof text, head, ascii[k].vertices, ascii[k].face);
        const char *path = tmp_path(ascii[k].name);
        write_text(path, text);
        refused_with(ctx, path, ascii[k].why, &slowest);
    }
    unsigned char bin[1024];
    for (int big = 0; big < 2; big++) {
        const char *path = tmp_path(big ? "mesh_ply_list_be.ply" : "mesh_ply_list_le.ply");
        write_file(path, bin, binary_ply(bin, big, 300000000u));
        refused_with(ctx, path, "a list of 300000000 values", &slowest);
        write_file(path, bin, binary_ply(bin, big, 3u)); /* honest: loads */
        one_triangle(ctx, path);
    }
    /* honest ASCII, a blank line between the vertices and the face */
    snprintf(text, sizeof text, head, "3", "\n3 0 1 2");
    const char *path = tmp_path("mesh_ply_honest.ply");
    write_text(path, text);
    one_triangle(ctx, path);
    /* OFF: vertex and face counts beyond the lines that follow */
    static const char *const off[][2] = {{"mesh_off_vertices.off", "OFF\n300000000 1 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2\n"},
                                         {"mesh_off_faces.off", "# a comment\nOFF\n3 300000000 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2\n"},
                                         {"mesh_off_headerless.off", "3000000000 1 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2\n"}};
    for (size_t k = 0; k < sizeof off / sizeof off[0]; k++) {
        const char *opath = tmp_path(off[k][0]);
        write_text(opath, off[k][1]);
        refused_with(ctx, opath, "lines follow", &slowest);
    }
    /* under a glTF name: assimp would offer it to its OFF reader when the
       glTF one turns it down */
    const char *gpath = tmp_path("mesh_off_named_glb.glb");
    write_text(gpath, "OFF\n3 300000000 0\n0 0 0\n");
    refused_with(ctx, gpath, "not a binary glTF file", &slowest);
    const char *opath = tmp_path("mesh_off_honest.off");
    write_text(opath, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 0 -1\n3 0 1 2"); /* no final line end */
    one_triangle(ctx, opath);
    /* not a time limit: assimp took seconds to minutes on these */
    printf("slowest refusal: %.3f s\n", slowest);
    hl_context_destroy(ctx);
}

static void test_bad_not_mesh(void)
{
    hl_context *ctx = make_ctx();
    /* Deterministic pseudo-random bytes under several extensions, and
     * plain text. */
    unsigned char junk[4096];
    uint32_t x = 12345;
    for (size_t i = 0; i < sizeof junk; i++) {
        x = x * 1664525u + 1013904223u;
        junk[i] = (unsigned char)(x >> 24);
    }
    const char *bin[] = {"mesh_random.obj", "mesh_random.bin", "mesh_random.ply", "mesh_random.stl",
                         "mesh_random.gltf"};
    for (size_t i = 0; i < sizeof bin / sizeof *bin; i++) {
        const char *path = tmp_path(bin[i]);
        write_file(path, junk, sizeof junk);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_OK);
        hl_mesh_destroy(m);
    }
    const char *txt[] = {"mesh_text.obj", "mesh_text.txt"};
    for (size_t i = 0; i < sizeof txt / sizeof *txt; i++) {
        const char *path = tmp_path(txt[i]);
        write_text(path, "This is a shopping list, not a mesh.\nEggs\nMilk\n");
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_ERR_FORMAT);
        hl_mesh_destroy(m);
    }
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- scenes
 * Files whose scene assimp 5.2's post-processing aborts, throws or
 * overruns on: they must be refused before it runs (see load_assimp). */

/* Writes a binary glTF: the JSON, then `bin` as its buffer 0. */
static void write_glb(const char *path, const char *json, const void *bin, size_t bin_size)
{
    size_t jpad = (strlen(json) + 3) & ~(size_t)3, bpad = (bin_size + 3) & ~(size_t)3;
    size_t total = 12 + 8 + jpad + 8 + bpad;
    unsigned char *b = calloc(1, total);
    if (!b) {
        fprintf(stderr, "out of memory for %s\n", path);
        exit(1);
    }
    memcpy(b, "glTF", 4);
    put_u32(b + 4, 2, 0);
    put_u32(b + 8, (uint32_t)total, 0);
    put_u32(b + 12, (uint32_t)jpad, 0);
    memcpy(b + 16, "JSON", 4);
    memset(b + 20, ' ', jpad);
    memcpy(b + 20, json, strlen(json));
    put_u32(b + 20 + jpad, (uint32_t)bpad, 0);
    memcpy(b + 24 + jpad, "BIN\0", 4);
    memcpy(b + 28 + jpad, bin, bin_size);
    write_file(path, b, total);
    free(b);
}

/* A binary glTF with one mesh of `nv` vertices on a grid and one triangle
 * (vertices 0, 1 and 256 when nv > 256, else 0, 1, 2), placed by `copies`
 * nodes, the children of the scene's one root node. */
static void write_instanced_glb(const char *path, uint32_t nv, uint32_t copies)
{
    size_t bin_size = (size_t)nv * 12 + 12;
    unsigned char *bin = malloc(bin_size);
    size_t cap = 1024 + (size_t)copies * 24;
    char *json = malloc(cap);
    if (!bin || !json) {
        fprintf(stderr, "out of memory for %s\n", path);
        exit(1);
    }
    for (uint32_t i = 0; i < nv; i++) {
        const float xyz[3] = {(float)(i % 256) / 256.0f, (float)(i / 256) / 256.0f, 0.0f};
        for (int k = 0; k < 3; k++) {
            uint32_t bits;
            memcpy(&bits, &xyz[k], 4);
            put_u32(bin + 12 * (size_t)i + 4 * (size_t)k, bits, 0);
        }
    }
    const uint32_t tri[3] = {0, 1, nv > 256 ? 256 : 2};
    for (int k = 0; k < 3; k++) put_u32(bin + (size_t)nv * 12 + 4 * (size_t)k, tri[k], 0);
    size_t n = (size_t)snprintf(json, cap, "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
                                           "\"nodes\":[{\"children\":[");
    for (uint32_t c = 1; c <= copies; c++) n += (size_t)snprintf(json + n, cap - n, "%s%u", c > 1 ? "," : "", c);
    n += (size_t)snprintf(json + n, cap - n, "]}");
    for (uint32_t c = 1; c <= copies; c++) n += (size_t)snprintf(json + n, cap - n, ",{\"mesh\":0}");
    snprintf(json + n, cap - n,
             "],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}],"
             "\"buffers\":[{\"byteLength\":%zu}],"
             "\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu},{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":12}],"
             "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\","
             "\"min\":[0,0,0],\"max\":[1,1,0]},{\"bufferView\":1,\"componentType\":5125,\"count\":3,\"type\":\"SCALAR\"}]}",
             bin_size, (size_t)nv * 12, (size_t)nv * 12, nv);
    write_glb(path, json, bin, bin_size);
    free(json);
    free(bin);
}

/* Loads path, which must be refused with `code`, naming the file, with
 * why in the message. */
static void refused_because(hl_context *ctx, const char *path, hl_result code, const char *why)
{
    hl_mesh *m = NULL;
    hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
    expect_failure(ctx, path, r, code);
    HL_CHECK(strstr(hl_context_last_error(ctx), why) != NULL, "%s: the message does not say \"%s\"", path, why);
    hl_mesh_destroy(m);
}

/* A scene in which no node references a mesh: assimp's
 * PretransformVertices throws "No output meshes", and the C API's
 * aiApplyPostProcessing then released the deleted scene again (a
 * segfault, first seen on AC/nosurfaces.ac of assimp-testmodels). AC3D:
 * an object with vertices and no surfaces becomes a mesh of points that
 * no node holds, at the top level or inside a world object. glTF: a mesh
 * whose only node is outside the scene, loaded through a skin's joints.
 * The same files with a surface, or with the node in the scene, load. */
static void test_bad_no_placed_mesh(void)
{
    hl_context *ctx = make_ctx();
    static const char verts[] = "numvert 3\n0 0 0\n1 0 0\n0 1 0\n";
    static const char surf[] = "numsurf 1\nSURF 0x10\nmat 0\nrefs 3\n0 0 0\n1 0 0\n2 0 0\n";
    char text[512];
    const char *ac = tmp_path("mesh_no_surfaces.ac");
    snprintf(text, sizeof text, "AC3Db\nOBJECT poly\n%skids 0\n", verts);
    write_text(ac, text);
    refused_because(ctx, ac, HL_ERR_MESH, "no mesh is placed in the scene");
    const char *ac_world = tmp_path("mesh_no_surfaces_world.ac");
    snprintf(text, sizeof text, "AC3Db\nOBJECT world\nkids 1\nOBJECT poly\n%skids 0\n", verts);
    write_text(ac_world, text);
    refused_because(ctx, ac_world, HL_ERR_MESH, "no mesh is placed in the scene");
    const char *ac_ok = tmp_path("mesh_one_surface.ac");
    snprintf(text, sizeof text, "AC3Db\nOBJECT world\nkids 1\nOBJECT poly\n%s%skids 0\n", verts, surf);
    write_text(ac_ok, text);
    one_triangle(ctx, ac_ok);

    static const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    unsigned char bin[36];
    for (int i = 0; i < 9; i++) {
        uint32_t bits;
        memcpy(&bits, &xyz[i], 4);
        put_u32(bin + 4 * i, bits, 0);
    }
    static const char gltf[] =
        "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[%s]}],"
        "\"nodes\":[{\"name\":\"empty\"},{\"name\":\"holder\",\"mesh\":0}],\"skins\":[{\"joints\":[1]}],"
        "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],\"buffers\":[{\"byteLength\":36}],"
        "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],\"accessors\":[{\"bufferView\":0,\"componentType\":5126,"
        "\"count\":3,\"type\":\"VEC3\",\"min\":[0,0,0],\"max\":[1,1,0]}]}";
    const char *glb = tmp_path("mesh_unplaced.glb");
    snprintf(text, sizeof text, gltf, "0");
    write_glb(glb, text, bin, sizeof bin);
    refused_because(ctx, glb, HL_ERR_MESH, "no mesh is placed in the scene");
    const char *glb_ok = tmp_path("mesh_placed.glb");
    snprintf(text, sizeof text, gltf, "0,1");
    write_glb(glb_ok, text, bin, sizeof bin);
    one_triangle(ctx, glb_ok);
    hl_context_destroy(ctx);
}

/* One mesh of 65535 vertices placed by 65538 nodes: more than 2^32
 * vertices once placed. assimp's PretransformVertices adds them up in 32
 * bits, allocates the wrapped (small) count and copies past it (heap
 * corruption from a 2 MB file). Refused before it runs, quickly; the same
 * mesh placed twice loads. */
static void test_bad_placed_overflow(void)
{
    hl_context *ctx = make_ctx();
    const char *path = tmp_path("mesh_placed_2e32.glb");
    write_instanced_glb(path, 65535, 65538);
    double t0 = hl_now();
    refused_because(ctx, path, HL_ERR_MESH, "more than 2^32 vertices");
    printf("refused in %.3f s\n", hl_now() - t0);
    const char *ok = tmp_path("mesh_placed_twice.glb");
    write_instanced_glb(ok, 65535, 2);
    hl_mesh *m = NULL;
    hl_mesh_stats st;
    HL_CHECK(load(ctx, ok, NULL, &m, &st) == HL_OK && m, "%s: a mesh placed twice must load", ok);
    if (m) {
        print_stats("placed twice", m, &st);
        /* two copies of 65535 vertices, all but the triangle's unused; the
           copies coincide, so their vertices weld and both triangles stay */
        HL_CHECK(st.file_vertices == 2 * 65535u && st.file_triangles == 2, "placed twice: file counts");
        HL_CHECK(m->vertex_count == 3 && m->triangle_count == 2, "placed twice: %u vertices, %u triangles",
                 m->vertex_count, m->triangle_count);
    }
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

#if defined(__SANITIZE_ADDRESS__)
#define MESH_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MESH_TEST_ASAN 1
#endif
#endif

/* A mesh placed by 12000 nodes: 786 million vertices, under 2^32, so it
 * gets to assimp's steps, which need about 10 GB for it. With the address
 * space limited to 1 GiB more than the process has, the allocation fails
 * inside PretransformVertices; the load must come back refused as out of
 * memory (aiApplyPostProcessing's failure path crashed on it). Run in a
 * child process, which takes the limit. Not under AddressSanitizer, whose
 * shadow memory needs more address space than any such limit. */
static void test_bad_import_memory(void)
{
#ifdef MESH_TEST_ASAN
    printf("SKIP: an AddressSanitizer build cannot run under an address-space limit\n");
#else
    const char *path = tmp_path("mesh_placed_10gb.glb");
    write_instanced_glb(path, 65535, 12000);
    fflush(stdout);
    pid_t pid = fork();
    HL_CHECK(pid >= 0, "fork failed");
    if (pid == 0) {
        long pages = 0, page = sysconf(_SC_PAGESIZE);
        FILE *f = fopen("/proc/self/statm", "r");
        if (!f || fscanf(f, "%ld", &pages) != 1 || page <= 0) _exit(3);
        fclose(f);
        rlim_t lim = (rlim_t)pages * (rlim_t)page + ((rlim_t)1 << 30);
        struct rlimit rl;
        if (getrlimit(RLIMIT_AS, &rl) != 0) _exit(3);
        if (rl.rlim_cur == RLIM_INFINITY || rl.rlim_cur > lim) rl.rlim_cur = lim;
        if (setrlimit(RLIMIT_AS, &rl) != 0) _exit(3);
        hl_context *ctx = make_ctx();
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        const char *msg = hl_context_last_error(ctx);
        printf("  %s -> %s: %s\n", path, hl_result_string(r), msg);
        fflush(stdout);
        int ok = r == HL_ERR_OUT_OF_MEMORY && strstr(msg, path) && strstr(msg, "out of memory");
        hl_mesh_destroy(m);
        hl_context_destroy(ctx);
        _exit(ok ? 0 : 1);
    }
    int status = 0;
    HL_CHECK(waitpid(pid, &status, 0) == pid, "waitpid failed");
    if (WIFSIGNALED(status))
        HL_CHECK(0, "the load under a memory limit was killed by signal %d", WTERMSIG(status));
    else
        HL_CHECK(WEXITSTATUS(status) == 0, "the load under a memory limit: child exit %d (1: not refused as out of "
                 "memory, 3: could not set the limit)", WEXITSTATUS(status));
#endif
}

static void test_bad_missing(void)
{
    hl_context *ctx = make_ctx();
    const char *names[] = {"mesh_does_not_exist.obj", "mesh_does_not_exist.ply"};
    for (size_t i = 0; i < 2; i++) {
        const char *path = tmp_path(names[i]);
        remove(path);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_ERR_IO);
    }
    const char *dir = hl_test_env("HL_TMP", "/tmp");
    hl_mesh *m = NULL;
    expect_failure(ctx, dir, hl_mesh_load(ctx, dir, NULL, &m, NULL), HL_ERR_IO);
    hl_context_destroy(ctx);
}

static void test_bad_empty(void)
{
    hl_context *ctx = make_ctx();
    const char *names[] = {"mesh_empty.obj", "mesh_empty.ply"};
    for (size_t i = 0; i < 2; i++) {
        const char *path = tmp_path(names[i]);
        write_file(path, "", 0);
        hl_mesh *m = NULL;
        hl_result r = hl_mesh_load(ctx, path, NULL, &m, NULL);
        expect_failure(ctx, path, r, HL_ERR_FORMAT);
    }
    const char *path = tmp_path("mesh_blank.obj");
    write_text(path, "\n\n   \n# nothing\n");
    hl_mesh *m = NULL;
    expect_failure(ctx, path, hl_mesh_load(ctx, path, NULL, &m, NULL), HL_ERR_FORMAT);
    hl_context_destroy(ctx);
}

static void test_bad_args(void)
{
    hl_context *ctx = make_ctx();
    hl_mesh *m = NULL;
    HL_CHECK(hl_mesh_load(ctx, NULL, NULL, &m, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL path");
    const char *path = tmp_path("mesh_args.obj");
    write_text(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    HL_CHECK(hl_mesh_load(ctx, path, NULL, NULL, NULL) == HL_ERR_INVALID_ARGUMENT, "NULL out");
    hl_mesh_load_desc d = {0};
    d.up_axis = 'x';
    hl_result r = hl_mesh_load(ctx, path, &d, &m, NULL);
    printf("  up 'x' -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT && m == NULL, "up axis x");
    d.up_axis = 0;
    d.albedo[0] = 1.5f;
    r = hl_mesh_load(ctx, path, &d, &m, NULL);
    printf("  albedo 1.5 -> %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, "albedo out of range");
    d.albedo[0] = 0.25f;
    d.albedo[1] = 0.5f;
    d.albedo[2] = 0.75f;
    hl_mesh_stats s;
    HL_CHECK(hl_mesh_load(NULL, path, &d, &m, &s) == HL_OK, "a NULL context is allowed");
    if (m) HL_CHECK(m->albedo[0] == 0.25f && m->albedo[1] == 0.5f && m->albedo[2] == 0.75f, "constant albedo");
    hl_mesh_destroy(m);
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"nan", test_bad_nan},
        {"index", test_bad_index},
        {"no_faces", test_bad_no_faces},
        {"not_mesh", test_bad_not_mesh},
        {"counts", test_bad_counts},
        {"missing", test_bad_missing},
        {"empty", test_bad_empty},
        {"no_placed_mesh", test_bad_no_placed_mesh},
        {"placed_overflow", test_bad_placed_overflow},
        {"import_memory", test_bad_import_memory},
        {"args", test_bad_args},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
