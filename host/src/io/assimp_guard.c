/* assimp_guard.c - refusing input that would crash, hang, corrupt or
 * exhaust assimp 5.2, before it gets to it. One concern: the guards, each
 * with why it exists; mesh_import.c does the import itself.
 *
 * Hostile files that would hang, abort, corrupt or exhaust assimp 5.2
 * itself (a PLY header without end_header or with an element declared
 * twice, PLY elements or lists, or OFF counts, larger than the file can
 * hold, a binary glTF whose lengths exceed the file, a .glb or .gltf name
 * on another kind of file) are refused before it reads them
 * (hl_assimp_file_problem_), and scenes its post-processing would abort,
 * throw or overrun on (faces without indices, no mesh placed by the node
 * tree, counts past 32 bits once placed) before that runs
 * (hl_raw_scene_problem_).
 *
 * Dependencies: assimp_guard.h, assimp's scene types (Debian
 * libassimp-dev 5.2), hl_internal.h, POSIX fseeko/ftello, strncasecmp.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/types.h>

#include <assimp/scene.h>

#include "assimp_guard.h"

/* Writes the problem into msg; returns 1. */
static int problem(char *msg, size_t msg_size, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, msg_size, fmt, ap);
    va_end(ap);
    return 1;
}

/* ---------------------------------------------------------------- PLY */

/* A PLY file that assimp 5.2 mishandles badly enough to hang, corrupt
 * memory or exhaust it, checked before it reads the file:
 * - its reader never returns from a header without an end_header line (it
 *   keeps asking for the next line at the end of the file);
 * - it sizes its arrays from the first element of a name and overruns them
 *   when the name is declared again;
 * - it makes room for every element the header declares, and for every
 *   value a list's count gives, before it reads them, filling in zeros
 *   where the file has none: a 150-byte file whose face list claims 3e8
 *   values took 4.7 GB, one that declares 3e8 vertices ran for minutes.
 * So the header is read up to end_header, and the body walked as assimp
 * reads it (ASCII: one element per line; binary: the declared types, in
 * either byte order; only elements whose names assimp knows have a count):
 * every element must fit in what is left of the file, and every list in
 * its line (ASCII) or in the bytes left (binary). Files that do not start
 * with the PLY magic ("ply", any case, as assimp checks it) are left
 * alone. */

enum { PLY_MAX_ELEMENTS = 32, PLY_MAX_PROPS = 64 };

typedef struct ply_prop {
    uint8_t list;       /* a list: count_size bytes of count, then values */
    uint8_t size;       /* bytes of one value */
    uint8_t count_size; /* bytes of a list's count */
} ply_prop;

typedef struct ply_elem {
    char name[64];
    uint64_t count;
    int nprops;
    ply_prop props[PLY_MAX_PROPS];
} ply_elem;

/* Bytes of a PLY scalar type; 0 for a name assimp does not know (such a
 * property ends its element's list of properties, in assimp and here). */
static int ply_type_size(const char *t)
{
    static const struct {
        const char *name;
        int size;
    } types[] = {{"char", 1},  {"int8", 1},  {"uchar", 1}, {"uint8", 1},   {"short", 2},  {"int16", 2},
                 {"ushort", 2}, {"uint16", 2}, {"int", 4},   {"int32", 4},   {"uint", 4},   {"uint32", 4},
                 {"float", 4},  {"float32", 4}, {"double", 8}, {"float64", 8}};
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (strcmp(t, types[i].name) == 0) return types[i].size;
    return 0;
}

/* A header line, ended by \n, \r or \r\n (the rest of a longer line is
 * dropped), so that a binary body starts right after it. Returns 0 at the
 * end of the file. */
static int ply_header_line(FILE *f, char *buf, size_t size)
{
    size_t n = 0;
    int c;
    while ((c = getc(f)) != EOF && c != '\n' && c != '\r')
        if (n + 1 < size) buf[n++] = (char)c;
    buf[n] = '\0';
    if (c == '\r') {
        int d = getc(f);
        if (d != '\n' && d != EOF) ungetc(d, f);
    }
    return c != EOF || n > 0;
}

/* v with the decimal digit c appended, saturated. */
static uint64_t ply_digit(uint64_t v, int c)
{
    return v > (UINT64_MAX - 9) / 10 ? UINT64_MAX : v * 10 + (uint64_t)(c - '0');
}

/* The value of a count's leading digits, saturated; 0 without any (as
 * assimp reads a count). */
static uint64_t ply_digits(const char *s)
{
    uint64_t v = 0;
    for (; *s >= '0' && *s <= '9'; s++) v = ply_digit(v, *s);
    return v;
}

/* assimp's TokenMatch: the token, then a space, a tab, a form feed or the
 * line's end. Returns what follows it, or NULL. (A vertical tab after
 * end_header, say, and assimp reads on for ever.) */
static const char *ply_match(const char *s, const char *token)
{
    size_t n = strlen(token);
    if (strncmp(s, token, n) != 0) return NULL;
    char c = s[n];
    return c == '\0' || c == ' ' || c == '\t' || c == '\f' ? s + n : NULL;
}

/* The next token of an ASCII line: 1 with the value of its leading digits
 * (saturated; 0 without any, as assimp's parse of a count gives), 0 at the
 * end of the line (consumed), -1 at the end of the file, -2 at a control
 * byte (not text). */
static int ply_token(FILE *f, uint64_t *value)
{
    int c;
    do c = getc(f);
    while (c == ' ' || c == '\t' || c == '\v' || c == '\f');
    if (c == EOF) return -1;
    if (c == '\n' || c == '\r') {
        if (c == '\r') {
            int d = getc(f);
            if (d != '\n' && d != EOF) ungetc(d, f);
        }
        return 0;
    }
    uint64_t v = 0;
    int digits = 1;
    for (; c != EOF && c != ' ' && c != '\t' && c != '\v' && c != '\f' && c != '\n' && c != '\r'; c = getc(f)) {
        if (c < 0x20 || c == 0x7f) return -2; /* a control byte: not text (assimp splits lines at a NUL) */
        if (digits && c >= '0' && c <= '9') v = ply_digit(v, c);
        else digits = 0;
    }
    if (c != EOF) ungetc(c, f);
    *value = v;
    return 1;
}

/* A control byte in an ASCII body: assimp's reader and this walk would
 * split its lines differently (a 381-byte file made assimp allocate 7 GB
 * for a count the walk had read on another line), so such a body is not
 * read at all. */
static int ply_not_text(char *msg, size_t msg_size, const char *element, uint64_t i)
{
    return problem(msg, msg_size, "PLY ASCII body: \"%s\" element %llu holds a control byte, which is not text",
                   element, (unsigned long long)i);
}

static int ply_walk_ascii(FILE *f, const ply_elem *el, int nel, char *msg, size_t msg_size)
{
    for (int e = 0; e < nel; e++)
        for (uint64_t i = 0; i < el[e].count; i++) {
            uint64_t v = 0;
            int t;
            while ((t = ply_token(f, &v)) == 0) continue; /* blank lines */
            if (t == -2) return ply_not_text(msg, msg_size, el[e].name, i);
            if (t < 0)
                return problem(msg, msg_size, "PLY header declares %llu \"%s\" elements, but the file ends after %llu",
                                (unsigned long long)el[e].count, el[e].name, (unsigned long long)i);
            /* v holds the line's first token */
            for (int p = 0; p < el[e].nprops && t > 0; p++) {
                if (p > 0) t = ply_token(f, &v);
                if (t <= 0 || !el[e].props[p].list) continue;
                uint64_t n = v, k = 0;
                for (; k < n && (t = ply_token(f, &v)) > 0; k++) continue;
                if (t == -2) return ply_not_text(msg, msg_size, el[e].name, i);
                if (k < n)
                    return problem(msg, msg_size, "PLY \"%s\" element %llu: a list of %llu values, but its line "
                                    "holds only %llu", el[e].name, (unsigned long long)i, (unsigned long long)n,
                                    (unsigned long long)k);
            }
            while (t > 0) t = ply_token(f, &v); /* the rest of the line */
            if (t == -2) return ply_not_text(msg, msg_size, el[e].name, i);
        }
    return 0;
}

/* A little reader over the binary body that knows how many bytes are left. */
typedef struct ply_reader {
    FILE *f;
    uint64_t left;
} ply_reader;

static int ply_skip(ply_reader *r, uint64_t n)
{
    if (n > r->left) return 0;
    r->left -= n;
    return n == 0 || fseeko(r->f, (off_t)n, SEEK_CUR) == 0;
}

static int ply_count(ply_reader *r, int size, int big_endian, uint64_t *out)
{
    unsigned char b[8];
    if ((uint64_t)size > r->left || fread(b, 1, (size_t)size, r->f) != (size_t)size) return 0;
    r->left -= (uint64_t)size;
    uint64_t v = 0;
    for (int k = 0; k < size; k++) v |= (uint64_t)b[big_endian ? size - 1 - k : k] << (8 * k);
    *out = v; /* a negative count reads huge, as assimp's conversion makes it */
    return 1;
}

static int ply_walk_binary(FILE *f, uint64_t left, int big_endian, const ply_elem *el, int nel, char *msg,
                           size_t msg_size)
{
    ply_reader r = {f, left};
    for (int e = 0; e < nel; e++) {
        uint64_t fixed = 0;
        int lists = 0;
        for (int p = 0; p < el[e].nprops; p++) {
            lists |= el[e].props[p].list;
            fixed += el[e].props[p].size;
        }
        if (!lists) {
            /* fixed-size elements: all at once (count <= file size, fixed <= 512) */
            if (el[e].count * fixed > r.left || !ply_skip(&r, el[e].count * fixed))
                return problem(msg, msg_size, "PLY header declares %llu \"%s\" elements of %llu bytes, but %llu "
                                "bytes are left", (unsigned long long)el[e].count, el[e].name,
                                (unsigned long long)fixed, (unsigned long long)r.left);
            continue;
        }
        for (uint64_t i = 0; i < el[e].count; i++)
            for (int p = 0; p < el[e].nprops; p++) {
                const ply_prop *pp = &el[e].props[p];
                uint64_t n = 1;
                if (pp->list && !ply_count(&r, pp->count_size, big_endian, &n))
                    return problem(msg, msg_size, "PLY \"%s\" element %llu: the file ends in it", el[e].name,
                                    (unsigned long long)i);
                if (n > r.left / pp->size || !ply_skip(&r, n * pp->size))
                    return problem(msg, msg_size, "PLY \"%s\" element %llu: %s %llu values of %d bytes, but %llu "
                                    "bytes are left", el[e].name, (unsigned long long)i,
                                    pp->list ? "a list of" : "a value:", (unsigned long long)n, pp->size,
                                    (unsigned long long)r.left);
            }
    }
    return 0;
}

/* Returns 0, or 1 with the problem in msg. */
static int ply_problem(FILE *f, uint64_t file_size, char *msg, size_t msg_size)
{
    char line[256];
    if (!ply_header_line(f, line, sizeof line) || (line[0] | 0x20) != 'p' || (line[1] | 0x20) != 'l' ||
        (line[2] | 0x20) != 'y')
        return 0;
    ply_elem *el = calloc(PLY_MAX_ELEMENTS, sizeof *el);
    if (!el) return problem(msg, msg_size, "out of memory for the PLY header");
    /* format: 0 ASCII, 1 little, 2 big endian; open: the lines that follow
       are properties of el[nel - 1] (1), of an element assimp counts as
       empty (2), or not properties (0) */
    int nel = 0, format = -1, bad = 0, ended = 0, open = 0;
    for (int lineno = 1; !bad && ply_header_line(f, line, sizeof line); lineno++) {
        char word[16], a[64], b[64], c[64], d[64];
        int fields = sscanf(line, " %15s %63s %63s %63s %63s", word, a, b, c, d);
        if (fields < 1) continue;
        const char *w = line + strspn(line, " \t"), *r;
        if (ply_match(w, "end_header")) {
            ended = 1;
            break;
        }
        if (lineno == 1 && strcmp(word, "format") == 0 && fields >= 2) {
            /* as assimp tells them, from the line after the magic only:
               "binary_" then "big" in any case is big endian, anything
               else after "binary_" little endian */
            format = strcmp(a, "ascii") == 0            ? 0
                     : strncmp(a, "binary_", 7) != 0    ? -1
                     : strncasecmp(a + 7, "big", 3) == 0 ? 2
                                                         : 1;
        } else if ((r = ply_match(w, "element")) != NULL) {
            /* assimp reads a count only after the names it knows; any
               other element has none (its properties are still read) */
            static const char *const known[] = {"vertex", "face", "tristrips", "edge", "material"};
            r += strspn(r, " \t");
            const char *name = NULL, *q = NULL;
            for (size_t k = 0; !name && k < sizeof known / sizeof known[0]; k++)
                if ((q = ply_match(r, known[k])) != NULL) name = known[k];
            open = ply_match(r, "TextureFile") ? 0 : 2; /* a texture element has no properties */
            if (!name) continue;
            for (int i = 0; i < nel; i++)
                if (strcmp(el[i].name, name) == 0)
                    bad = problem(msg, msg_size, "PLY header declares element \"%s\" twice", name);
            if (bad) break;
            if (nel == PLY_MAX_ELEMENTS) {
                bad = problem(msg, msg_size, "PLY header declares more than %d elements", PLY_MAX_ELEMENTS);
                break;
            }
            unsigned long long n = ply_digits(q + strspn(q, " \t"));
            if (n > file_size)
                bad = problem(msg, msg_size, "PLY header declares %llu \"%s\" elements in a file of %llu bytes", n,
                              name, (unsigned long long)file_size);
            snprintf(el[nel].name, sizeof el[nel].name, "%s", name);
            el[nel++].count = n;
            open = 1;
        } else if (ply_match(w, "comment")) {
            continue; /* skipped, inside an element's properties or not */
        } else if (ply_match(w, "property") && fields >= 3 && open) {
            ply_prop p = {0, 0, 0};
            if (strcmp(a, "list") == 0) {
                p.list = 1;
                p.count_size = (uint8_t)(fields >= 4 ? ply_type_size(b) : 0);
                p.size = (uint8_t)(fields >= 4 ? ply_type_size(c) : 0);
            } else {
                p.size = (uint8_t)ply_type_size(a);
            }
            if (!p.size || (p.list && !p.count_size)) {
                open = 0; /* a type assimp does not know ends the list */
                continue;
            }
            if (open == 2) continue; /* an element without a count */
            ply_elem *e = &el[nel - 1];
            if (e->nprops == PLY_MAX_PROPS) {
                bad = problem(msg, msg_size, "PLY element \"%s\" has more than %d properties", e->name,
                              PLY_MAX_PROPS);
                break;
            }
            e->props[e->nprops++] = p;
        } else {
            /* as in assimp, an element's properties are the lines right
               after it: any other line ends them */
            open = 0;
        }
    }
    if (!bad && !ended) bad = problem(msg, msg_size, "PLY header has no end_header line (truncated or corrupt)");
    /* a format assimp does not know: it refuses the header itself */
    if (!bad && format == 0) bad = ply_walk_ascii(f, el, nel, msg, msg_size);
    if (!bad && format > 0) {
        off_t at = ftello(f);
        if (at >= 0 && (uint64_t)at <= file_size)
            bad = ply_walk_binary(f, file_size - (uint64_t)at, format == 2, el, nel, msg, msg_size);
    }
    free(el);
    return bad;
}

/* ---------------------------------------------------------------- OFF */

/* Whether path ends in ext (any case). */
static int has_ext(const char *path, const char *ext)
{
    size_t n = strlen(path), k = strlen(ext);
    return n >= k && strcasecmp(path + n - k, ext) == 0;
}

/* assimp 5.2's OFF reader allocates the vertex and face arrays at the
 * counts its header gives before it reads a line: a few bytes declaring
 * 3e8 vertices or faces took 3.5 to 4.7 GB and 15 s before it failed.
 * Its header is read here as assimp reads it (comment lines skipped, the
 * prefixes ST, C, N, 4 and n, then "OFF", which may be missing, then an
 * optional dimension, the vertex and face counts as 32-bit counts), and
 * each count must fit in the lines that follow. Applies to names ending
 * in .off (any case), which assimp gives to that reader, and to any file
 * that starts with the OFF magic, which it falls back to that reader for
 * when the reader its name picks fails. */

/* assimp's NextToken: skips spaces, line ends and lines starting with #. */
static const char *off_next(const char *c, const char *end)
{
    for (;;) {
        while (c < end && (*c == ' ' || *c == '\t' || *c == '\n' || *c == '\r' || *c == '\f' || *c == '\v')) c++;
        if (c >= end || *c != '#') return c;
        while (c < end && *c != '\n' && *c != '\r') c++;
    }
}

/* assimp's strtoul10: leading digits, wrapping as an unsigned int. */
static uint32_t off_count(const char **c, const char *end)
{
    uint32_t v = 0;
    for (; *c < end && **c >= '0' && **c <= '9'; (*c)++) v = v * 10u + (uint32_t)(**c - '0');
    return v;
}

static int off_problem(const char *path, FILE *f, char *msg, size_t msg_size)
{
    const int named = has_ext(path, ".off");
    char head[4096];
    size_t got = fread(head, 1, sizeof head, f);
    const char *c = off_next(head, head + got), *end = head + got;
    int dimension = 0, magic = 0;
    /* assimp's tests, each asking for one more character than it reads */
    if (end - c > 2 && c[0] == 'S' && c[1] == 'T') c += 2;
    if (end - c > 1 && c[0] == 'C') c++;
    if (end - c > 1 && c[0] == 'N') c++;
    if (end - c > 1 && c[0] == '4') c++;
    if (end - c > 1 && c[0] == 'n') dimension = 1, c++;
    if (end - c > 3 && c[0] == 'O' && c[1] == 'F' && c[2] == 'F') c += 3, magic = 1;
    /* under another name, assimp still falls back to this reader when the
       file starts with the OFF magic */
    if (!named && !magic) return 0;
    c = off_next(c, end);
    if (dimension) {
        off_count(&c, end);
        c = off_next(c, end);
    }
    uint32_t nv = off_count(&c, end);
    c = off_next(c, end);
    uint32_t nf = off_count(&c, end);
    if (c >= end && got == sizeof head) return 0; /* a header longer than 4 KB: assimp's own errors */
    /* the lines after the counts */
    uint64_t lines = 0;
    for (const char *q = c; q < end; q++) lines += *q == '\n';
    char buf[65536];
    size_t k;
    while ((k = fread(buf, 1, sizeof buf, f)) > 0)
        for (size_t i = 0; i < k; i++) lines += buf[i] == '\n';
    lines++; /* a last line without its line end */
    if (nv > lines || nf > lines)
        return problem(msg, msg_size, "OFF header declares %u vertices and %u faces, but only %llu lines follow", nv, nf,
                       (unsigned long long)lines);
    return 0;
}

/* glTF. A binary one (magic "glTF", versions 1 and 2): assimp 5.2
 * allocates and zero-fills the first chunk at the length its header gives
 * before reading it, so a file of a few hundred bytes could claim
 * gigabytes; the total length in the header and the first chunk (from
 * byte 20) must fit in the file. A .glb or .gltf name on a file that is
 * not glTF: assimp's glTF reader turns it down, and assimp then offers the
 * file to every reader it has by its content (an OFF header under a .glb
 * name took 4.8 GB), so it is refused; a .glb must start with the magic, a
 * .gltf (JSON) with "{" after any spaces. Returns 0, or 1 with the problem
 * in msg. */
static int gltf_problem(const char *path, FILE *f, uint64_t file_size, char *msg, size_t msg_size)
{
    unsigned char h[16];
    size_t got = fread(h, 1, sizeof h, f);
    if (got >= 4 && memcmp(h, "glTF", 4) == 0) {
        if (got < sizeof h) return 0; /* assimp's own error */
        uint32_t word[2];
        for (int i = 0; i < 2; i++)
            word[i] = (uint32_t)h[8 + 4 * i] | (uint32_t)h[9 + 4 * i] << 8 | (uint32_t)h[10 + 4 * i] << 16 |
                      (uint32_t)h[11 + 4 * i] << 24;
        if (word[0] > file_size || (uint64_t)word[1] + 20 > file_size)
            return problem(msg, msg_size,
                           "binary glTF header gives a length of %u bytes and a first chunk of %u bytes, "
                           "but the file has %llu bytes", word[0], word[1], (unsigned long long)file_size);
        return 0;
    }
    if (has_ext(path, ".glb")) return problem(msg, msg_size, "not a binary glTF file (it does not start with \"glTF\")");
    if (!has_ext(path, ".gltf")) return 0;
    rewind(f);
    int c;
    do c = getc(f);
    while (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == 0xEF || c == 0xBB || c == 0xBF); /* BOM */
    if (c == '{') return 0;
    return problem(msg, msg_size, "not a glTF file (JSON starting with \"{\")");
}

/* ---------------------------------------------------------------- scene */

/* What assimp 5.2's post-processing needs of the raw scene, read from its
 * sources (TriangulateProcess.cpp, PretransformVertices.cpp, Assimp.cpp,
 * BaseProcess.cpp) and checked on Debian's libassimp 5.2.5, which is built
 * with its ai_asserts on. PretransformVertices runs before Triangulate.
 * - A face without indices: the scene preprocessor flags it as a polygon,
 *   and Triangulate then finds no polygon to split and aborts the process
 *   (ai_assert numOut != mNumFaces). A polygon's indices are read
 *   unchecked too.
 * - No mesh placed in the scene: PretransformVertices makes one output
 *   mesh per material and vertex format out of the meshes the node tree
 *   (from mRootNode) references, those with faces and vertices, and throws
 *   "No output meshes" when there is none. An AC3D object with vertices
 *   and no surfaces gives such a scene (a mesh of points that no node
 *   references), and so does a glTF mesh that only a node outside the
 *   scene holds (the node loaded through a skin's joints).
 * - Counts past 32 bits: PretransformVertices adds up the vertices and
 *   faces of every node's meshes in unsigned int, and Triangulate its
 *   output faces; a mesh placed by many nodes wraps the sum, the arrays
 *   come out small and the copies run past them (a 2 MB glTF placing a
 *   65535-vertex mesh 65538 times corrupts the heap).
 * - A mesh with a vertex or face count but no array: the validation lets
 *   it through when the scene has any flag set, and both steps copy from
 *   the array.
 * Cameras and lights are looked up by name in the node tree
 * (PretransformVertices' ai_assert on FindNode); the validation of the raw
 * import already refuses one without a node of its name ("has no
 * corresponding node in the scene graph"), so that case never gets here.
 * hl_raw_scene_problem_ checks the meshes (scene_meshes_problem), then the
 * node tree (scene_nodes_problem). */

/* The meshes of the raw scene: arrays present for their counts, every face
 * with indices, and a polygon's indices in range. out_faces[m] gets mesh
 * m's faces as Triangulate will output them (1 for a point, line or
 * triangle, n - 2 for an n-gon). */
static hl_result scene_meshes_problem(hl_context *ctx, const char *path, const struct aiScene *s,
                                      uint64_t *out_faces)
{
    for (unsigned m = 0; m < s->mNumMeshes; m++) {
        const struct aiMesh *am = s->mMeshes[m];
        if ((am->mNumVertices && !am->mVertices) || (am->mNumFaces && !am->mFaces))
            return hl_fail(ctx, HL_ERR_FORMAT, "%s: mesh %u (counting from 0) has %u vertices and %u faces but "
                           "not their arrays", path, m, am->mNumVertices, am->mNumFaces);
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            const struct aiFace *af = &am->mFaces[f];
            if (af->mNumIndices == 0 || !af->mIndices)
                return hl_fail(ctx, HL_ERR_FORMAT, "%s: mesh %u face %u (counting from 0) has no vertex indices",
                               path, m, f);
            out_faces[m] += af->mNumIndices <= 3 ? 1 : af->mNumIndices - 2;
            if (af->mNumIndices <= 3) continue; /* the builder checks triangles' indices */
            for (unsigned k = 0; k < af->mNumIndices; k++)
                if (af->mIndices[k] >= am->mNumVertices)
                    return hl_fail(ctx, HL_ERR_MESH,
                                   "%s: mesh %u face %u (counting from 0) refers to vertex %u, out of range "
                                   "(%u vertices)", path, m, f, af->mIndices[k], am->mNumVertices);
        }
    }
    return HL_OK;
}

/* What the node tree places in the scene. */
typedef struct scene_placement {
    const uint64_t *out_faces; /* per mesh, from scene_meshes_problem */
    unsigned char *referenced; /* per mesh: a node references it */
    unsigned placed;           /* references to meshes the steps keep */
    unsigned nreferenced;      /* meshes referenced at all */
} scene_placement;

/* The node tree, depth first with a stack of its own (as deep as the file
 * makes it): every node's arrays present, its meshes in range, and the
 * vertices and faces it places within 32 bits; the sums count every
 * reference, as the steps do. Fills in pl. */
static hl_result scene_nodes_problem(hl_context *ctx, const char *path, const struct aiScene *s,
                                     scene_placement *pl)
{
    size_t top = 0, cap = 64;
    uint64_t placed_vertices = 0, placed_faces = 0;
    hl_result r = HL_OK;
    const struct aiNode **stack = malloc(cap * sizeof *stack);
    if (!stack) return hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory checking the scene", path);
    stack[top++] = s->mRootNode;
    while (top > 0 && r == HL_OK) {
        const struct aiNode *nd = stack[--top];
        if ((nd->mNumMeshes && !nd->mMeshes) || (nd->mNumChildren && !nd->mChildren)) {
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\" has no array for its meshes or children", path,
                        nd->mName.data);
            break;
        }
        for (unsigned i = 0; i < nd->mNumMeshes && r == HL_OK; i++) {
            unsigned m = nd->mMeshes[i];
            if (m >= s->mNumMeshes) {
                r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\" refers to mesh %u, out of range (%u meshes)",
                            path, nd->mName.data, m, s->mNumMeshes);
                break;
            }
            const struct aiMesh *am = s->mMeshes[m];
            pl->nreferenced += !pl->referenced[m];
            pl->referenced[m] = 1;
            if (am->mNumFaces && am->mNumVertices && am->mMaterialIndex < s->mNumMaterials) pl->placed++;
            placed_vertices += am->mNumVertices;
            placed_faces += pl->out_faces[m];
        }
        if (r == HL_OK && (placed_vertices > UINT32_MAX || placed_faces > UINT32_MAX))
            r = hl_fail(ctx, HL_ERR_MESH, "%s: its nodes place meshes of more than 2^32 %s in the scene (meshes "
                        "placed by many nodes)", path, placed_vertices > UINT32_MAX ? "vertices" : "faces");
        for (unsigned c = nd->mNumChildren; r == HL_OK && c-- > 0;) {
            if (!nd->mChildren[c]) {
                r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\" has a null child", path, nd->mName.data);
                break;
            }
            if (top == cap) {
                const struct aiNode **grown =
                    cap < SIZE_MAX / 2 / sizeof *stack ? realloc(stack, 2 * cap * sizeof *stack) : NULL;
                if (!grown) {
                    r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory checking the scene", path);
                    break;
                }
                stack = grown;
                cap *= 2;
            }
            stack[top++] = nd->mChildren[c];
        }
    }
    free(stack);
    return r;
}

hl_result hl_raw_scene_problem_(hl_context *ctx, const char *path, const struct aiScene *s)
{
    if (s->mNumMeshes == 0) return hl_fail(ctx, HL_ERR_FORMAT, "%s: the file holds no mesh", path);
    uint64_t *out_faces = calloc(s->mNumMeshes, sizeof *out_faces);
    unsigned char *referenced = calloc(s->mNumMeshes, 1);
    scene_placement pl = {out_faces, referenced, 0, 0};
    hl_result r = HL_OK;
    if (!out_faces || !referenced) r = hl_fail(ctx, HL_ERR_OUT_OF_MEMORY, "%s: out of memory checking the scene", path);
    if (r == HL_OK) r = scene_meshes_problem(ctx, path, s, out_faces);
    if (r == HL_OK && !s->mRootNode) r = hl_fail(ctx, HL_ERR_FORMAT, "%s: the scene has no root node", path);
    if (r == HL_OK) r = scene_nodes_problem(ctx, path, s, &pl);
    if (r == HL_OK && pl.placed == 0)
        r = pl.nreferenced == 0
                ? hl_fail(ctx, HL_ERR_MESH, "%s: no mesh is placed in the scene: no node of its scene graph "
                          "references its %u mesh%s", path, s->mNumMeshes, s->mNumMeshes == 1 ? "" : "es")
                : hl_fail(ctx, HL_ERR_MESH, "%s: no mesh is placed in the scene: the %u mesh%s its nodes "
                          "reference %s no material", path, pl.nreferenced, pl.nreferenced == 1 ? "" : "es",
                          pl.nreferenced == 1 ? "has" : "have");
    free(referenced);
    free(out_faces);
    return r;
}

/* ---------------------------------------------------------------- all files */

int hl_assimp_file_problem_(const char *path, FILE *f, uint64_t file_size, char *msg, size_t msg_size)
{
    int bad = ply_problem(f, file_size, msg, msg_size);
    if (!bad) {
        rewind(f);
        bad = gltf_problem(path, f, file_size, msg, msg_size);
    }
    if (!bad) {
        rewind(f);
        bad = off_problem(path, f, msg, msg_size);
    }
    return bad;
}
