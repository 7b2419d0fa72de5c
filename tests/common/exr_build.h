/* exr_build.h - OpenEXR files written byte by byte (tests/io's hostile
 * header and chunk tests): a growing byte buffer, little-endian numbers,
 * attributes, the required header attributes, tile descriptions, parts.
 * Depends on: hl_test.h.
 */
#ifndef HL_TEST_EXR_BUILD_H
#define HL_TEST_EXR_BUILD_H

/* OpenEXR bytes written field by field (little-endian), for headers no
 * library would write. */
typedef struct exr_bytes {
    uint8_t *p;
    size_t n, cap;
} exr_bytes;

static inline void eb_put(exr_bytes *b, const void *src, size_t n)
{
    if (b->n + n > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->n + n) cap *= 2;
        uint8_t *p = realloc(b->p, cap);
        if (!p) {
            fprintf(stderr, "out of memory building a test file\n");
            exit(1);
        }
        b->p = p;
        b->cap = cap;
    }
    memcpy(b->p + b->n, src, n);
    b->n += n;
}

static inline void eb_u8(exr_bytes *b, unsigned v)
{
    uint8_t c = (uint8_t)v;
    eb_put(b, &c, 1);
}

static inline void eb_i32(exr_bytes *b, int64_t v)
{
    uint32_t u = (uint32_t)v;
    for (int k = 0; k < 4; k++) eb_u8(b, (u >> (8 * k)) & 255u);
}

static inline void eb_f32(exr_bytes *b, float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    eb_i32(b, u);
}

static inline void eb_str(exr_bytes *b, const char *s) { eb_put(b, s, strlen(s) + 1); }

static inline void eb_zeros(exr_bytes *b, size_t n)
{
    for (size_t i = 0; i < n; i++) eb_u8(b, 0);
}

/* An attribute's name, type and declared size; the value follows. */
static inline void eb_attr(exr_bytes *b, const char *name, const char *type, int64_t size)
{
    eb_str(b, name);
    eb_str(b, type);
    eb_i32(b, size);
}

enum { EB_TILED = 0x200, EB_MULTIPART = 0x1000 };
enum { EB_HALF = 1, EB_FLOAT = 2 };
enum { EB_NONE = 0, EB_ZIP = 3, EB_PIZ = 4 };

/* Magic number, then version 2 with flags. */
static inline void eb_start(exr_bytes *b, unsigned flags)
{
    static const uint8_t magic[4] = {0x76, 0x2f, 0x31, 0x01};
    eb_put(b, magic, sizeof magic);
    eb_i32(b, 2 | (int64_t)flags);
}

/* "channels": n channels of pixel type t, named (sorted, as the format
 * wants) B, G, R when n is 3, R when n is 1, else c00000, c00001, ... */
static inline void eb_channels(exr_bytes *b, int n, int t)
{
    static const char *const rgb[3] = {"B", "G", "R"};
    const int letters = n == 1 || n == 3;
    char name[16];
    eb_attr(b, "channels", "chlist", (int64_t)n * (16 + (letters ? 2 : 7)) + 1);
    for (int i = 0; i < n; i++) {
        snprintf(name, sizeof name, "c%05d", i);
        eb_str(b, letters ? rgb[3 - n + i] : name);
        eb_i32(b, t);
        eb_zeros(b, 4); /* pLinear, reserved */
        eb_i32(b, 1);   /* x and y sampling */
        eb_i32(b, 1);
    }
    eb_u8(b, 0);
}

static inline void eb_box(exr_bytes *b, const char *name, int64_t x0, int64_t y0, int64_t x1, int64_t y1)
{
    eb_attr(b, name, "box2i", 16);
    eb_i32(b, x0);
    eb_i32(b, y0);
    eb_i32(b, x1);
    eb_i32(b, y1);
}

/* Every attribute a part must have, with a 16 x 8 display window. */
static inline void eb_required(exr_bytes *b, int channels, int type, unsigned compression, int64_t x0, int64_t y0,
                        int64_t x1, int64_t y1)
{
    eb_channels(b, channels, type);
    eb_attr(b, "compression", "compression", 1);
    eb_u8(b, compression);
    eb_box(b, "dataWindow", x0, y0, x1, y1);
    eb_box(b, "displayWindow", 0, 0, 15, 7);
    eb_attr(b, "lineOrder", "lineOrder", 1);
    eb_u8(b, 0);
    eb_attr(b, "pixelAspectRatio", "float", 4);
    eb_f32(b, 1.0f);
    eb_attr(b, "screenWindowCenter", "v2f", 8);
    eb_f32(b, 0.0f);
    eb_f32(b, 0.0f);
    eb_attr(b, "screenWindowWidth", "float", 4);
    eb_f32(b, 1.0f);
}

static inline void eb_tiles(exr_bytes *b, uint32_t w, uint32_t h, unsigned mode)
{
    eb_attr(b, "tiles", "tiledesc", 9);
    eb_i32(b, w);
    eb_i32(b, h);
    eb_u8(b, mode);
}

/* Corners far outside any image, yet inside what both OpenEXR readers
 * accept (|corner| < 2^30 - 1): 2^31 - 3 rows and columns. */
static inline void eb_part_compressed(exr_bytes *b, const char *name, unsigned compression, int64_t x0, int64_t y0,
                               int64_t x1, int64_t y1, int64_t chunks)
{
    eb_required(b, 3, EB_HALF, compression, x0, y0, x1, y1);
    eb_attr(b, "name", "string", (int64_t)strlen(name));
    eb_put(b, name, strlen(name));
    eb_attr(b, "type", "string", 13);
    eb_put(b, "scanlineimage", 13);
    eb_attr(b, "chunkCount", "int", 4);
    eb_i32(b, chunks);
    eb_u8(b, 0);
}
static inline void eb_part(exr_bytes *b, const char *name, int64_t x0, int64_t y0, int64_t x1, int64_t y1, int64_t chunks)
{
    eb_part_compressed(b, name, EB_ZIP, x0, y0, x1, y1, chunks);
}

#endif
