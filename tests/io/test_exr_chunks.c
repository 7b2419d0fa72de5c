/* test_exr_chunks.c - hostile OpenEXR chunks (suite "exr_chunks").
 *
 * exr_chunks.hostile  sound headers with broken chunks written byte by
 *                     byte: zeroed or far offset tables, no data, packed
 *                     sizes beyond the file, a short uncompressed chunk, tile
 *                     entries at other tiles in one-level, mipmap and ripmap
 *                     files, a bad second part, an entry into the offset
 *                     tables, ZIP data that decompresses short of its chunk
 *                     in a scanline map, a tile and a first part; each
 *                     refused naming the part and the chunk, or the rows;
 *                     the sound maps they came from load exactly, and so
 *                     does one of three half channels with one not read.
 * Depends on: haarlight_core (reference backend only), zlib (ZIP chunks),
 * tests/common/{env_util,exr_build}.h, HL_TEST_FIXTURES (tests/data).
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include "haarlight.h"
#include "hl_test.h"
#include "env_util.h"

#include "exr_build.h"

/* ---------------------------------------------------------------- hostile_chunks */

/* Sound 16 x 8 maps written byte by byte, uncompressed half R, G, B, so
 * that every chunk can be placed and broken by hand. Pixel (x, y) channel c
 * (0: R) is (x + 16 y + 1) (c + 1) / 64, exact in half. */
static float chunk_value(int x, int y, int c) { return (float)((x + 16 * y + 1) * (c + 1)) / 64.0f; }

/* v: a normal float that half holds exactly. */
static unsigned half_bits(float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    return ((u >> 16) & 0x8000u) | ((((u >> 23) & 0xffu) - 112u) << 10) | ((u >> 13) & 0x3ffu);
}

/* Rows y of columns x0..x0+w-1, as an uncompressed chunk stores them:
   each row holds B, then G, then R (the channels' sorted order). */
static void eb_pixels(exr_bytes *b, int x0, int w, int y0, int h)
{
    for (int y = y0; y < y0 + h; y++)
        for (int c = 2; c >= 0; c--)
            for (int x = x0; x < x0 + w; x++) {
                unsigned bits = half_bits(chunk_value(x, y, c));
                eb_u8(b, bits & 255u);
                eb_u8(b, bits >> 8);
            }
}

static void put_u64(uint8_t *p, uint64_t v)
{
    for (int k = 0; k < 8; k++) p[k] = (uint8_t)(v >> (8 * k));
}

static void put_u32(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; k++) p[k] = (uint8_t)(v >> (8 * k));
}

/* Where a written file keeps its offset tables and chunks. */
typedef struct chunk_file {
    exr_bytes b;
    size_t table[2];     /* byte where each part's offset table starts */
    size_t chunk[2][32]; /* byte where each chunk (its header) starts */
    int tile[32][4];     /* tiled: each chunk's tile x, y and level x, y */
    int tiles;
} chunk_file;

/* One part (parts == 1) of 16 x 8, or two: 16 x 8 and 16 x rows1. One row
 * a chunk, 96 bytes; the first chunk of part 0 holds first_bytes of them
 * (and says so). The tables point at the chunks. */
static void cf_scanline(chunk_file *cf, int parts, int rows1, int first_bytes)
{
    exr_bytes *b = &cf->b;
    const int rows[2] = {8, rows1};
    eb_start(b, parts > 1 ? EB_MULTIPART : 0);
    if (parts == 1) {
        eb_required(b, 3, EB_HALF, EB_NONE, 0, 0, 15, 7);
        eb_u8(b, 0);
    } else {
        eb_part_compressed(b, "map", EB_NONE, 0, 0, 15, 7, 8);
        eb_part_compressed(b, "other", EB_NONE, 0, 0, 15, rows1 - 1, rows1);
        eb_u8(b, 0);
    }
    for (int p = 0; p < parts; p++) {
        cf->table[p] = b->n;
        eb_zeros(b, 8 * (size_t)rows[p]);
    }
    for (int p = 0; p < parts; p++)
        for (int y = 0; y < rows[p]; y++) {
            cf->chunk[p][y] = b->n;
            if (parts > 1) eb_i32(b, p);
            eb_i32(b, y);
            int bytes = p == 0 && y == 0 ? first_bytes : 96;
            eb_i32(b, bytes);
            size_t at = b->n;
            eb_pixels(b, 0, 16, y, 1);
            b->n = at + (size_t)bytes; /* a short chunk keeps only its first bytes */
        }
    for (int p = 0; p < parts; p++)
        for (int y = 0; y < rows[p]; y++) put_u64(b->p + cf->table[p] + 8 * (size_t)y, cf->chunk[p][y]);
}

/* 16 x 8 in 8 x 8 tiles, rounded down: one level (mode 0: two tiles),
 * mipmap levels (1: 16 x 8 to 1 x 1, six tiles) or ripmap levels (2: 5 x 4
 * levels, 24 tiles), in the table's order. Pixel (x, y) of every level
 * holds chunk_value(x, y, c). */
static void cf_tiled(chunk_file *cf, unsigned mode)
{
    exr_bytes *b = &cf->b;
    const int nlx = mode ? 5 : 1, nly = mode == 2 ? 4 : mode ? 5 : 1;
    eb_start(b, EB_TILED);
    eb_required(b, 3, EB_HALF, EB_NONE, 0, 0, 15, 7);
    eb_tiles(b, 8, 8, mode);
    eb_u8(b, 0);
    cf->tiles = 0;
    for (int ly = 0; ly < nly; ly++)
        for (int lx = 0; lx < nlx; lx++) {
            if (mode != 2 && lx != ly) continue;
            int lw = 16 >> lx > 0 ? 16 >> lx : 1, lh = 8 >> ly > 0 ? 8 >> ly : 1;
            for (int ty = 0; ty < (lh + 7) / 8; ty++)
                for (int tx = 0; tx < (lw + 7) / 8; tx++) {
                    int *t = cf->tile[cf->tiles++];
                    t[0] = tx, t[1] = ty, t[2] = lx, t[3] = ly;
                }
        }
    cf->table[0] = b->n;
    eb_zeros(b, 8 * (size_t)cf->tiles);
    for (int i = 0; i < cf->tiles; i++) {
        const int *t = cf->tile[i];
        int lw = 16 >> t[2] > 0 ? 16 >> t[2] : 1, lh = 8 >> t[3] > 0 ? 8 >> t[3] : 1;
        int w = lw - 8 * t[0] < 8 ? lw - 8 * t[0] : 8, h = lh - 8 * t[1] < 8 ? lh - 8 * t[1] : 8;
        cf->chunk[0][i] = b->n;
        for (int k = 0; k < 4; k++) eb_i32(b, t[k]);
        eb_i32(b, w * h * 3 * 2);
        eb_pixels(b, 8 * t[0], w, 8 * t[1], h);
    }
    for (int i = 0; i < cf->tiles; i++) put_u64(b->p + cf->table[0] + 8 * (size_t)i, cf->chunk[0][i]);
}

/* The chunk index of a tile of cf_tiled. */
static int cf_tile_index(const chunk_file *cf, int tx, int ty, int lx, int ly)
{
    for (int i = 0; i < cf->tiles; i++)
        if (cf->tile[i][0] == tx && cf->tile[i][1] == ty && cf->tile[i][2] == lx && cf->tile[i][3] == ly) return i;
    fprintf(stderr, "no tile (%d, %d) level (%d, %d)\n", tx, ty, lx, ly);
    exit(1);
}

static void cf_tiled_one(chunk_file *cf) { cf_tiled(cf, 0); }
static void cf_tiled_mipmap(chunk_file *cf) { cf_tiled(cf, 1); }
static void cf_tiled_ripmap(chunk_file *cf) { cf_tiled(cf, 2); }

/* A ZIP chunk's packed size and data, as OpenEXR stores n bytes of pixels
 * (raw, in eb_pixels' order): the bytes split into the even ones, then the
 * odd ones; each then stored as its difference from the one before plus
 * 128 (mod 256); then deflated (zlib). Only the first keep of the n
 * transformed bytes go into the stream: a sound zlib stream that
 * decompresses to keep bytes, short of the chunk when keep < n. */
static void eb_zip_chunk(exr_bytes *b, const uint8_t *raw, size_t n, size_t keep)
{
    uint8_t *t = malloc(n);
    uLongf packed = compressBound((uLong)n);
    uint8_t *z = malloc(packed);
    if (!t || !z) {
        fprintf(stderr, "out of memory building a test file\n");
        exit(1);
    }
    for (size_t i = 0; i < n; i++) t[i % 2 ? (n + 1) / 2 + i / 2 : i / 2] = raw[i];
    for (size_t i = n; i-- > 1;) t[i] = (uint8_t)(t[i] - t[i - 1] + 128u);
    if (compress2(z, &packed, t, (uLong)keep, 9) != Z_OK) {
        fprintf(stderr, "zlib cannot compress a test chunk\n");
        exit(1);
    }
    eb_i32(b, (int64_t)packed);
    eb_put(b, z, packed);
    free(t);
    free(z);
}

/* The 16 x 8 map in ZIP chunks, laid out as layout says: 0 one scanline
 * part (one chunk: a ZIP chunk has 16 rows), 1 one tiled part of two 8 x 8
 * tiles, 2 two scanline parts (one chunk each). The first chunk
 * decompresses to only keep bytes when keep > 0 (eb_zip_chunk). */
static void cf_zip(chunk_file *cf, int layout, size_t keep)
{
    exr_bytes *b = &cf->b, raw = {NULL, 0, 0};
    const int chunks = layout == 0 ? 1 : 2;
    eb_start(b, layout == 1 ? EB_TILED : layout == 2 ? EB_MULTIPART : 0);
    if (layout == 2) {
        eb_part_compressed(b, "map", EB_ZIP, 0, 0, 15, 7, 1);
        eb_part_compressed(b, "other", EB_ZIP, 0, 0, 15, 7, 1);
    } else {
        eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
        if (layout == 1) eb_tiles(b, 8, 8, 0);
    }
    eb_u8(b, 0);
    const size_t table = b->n; /* both parts' tables, one entry each, are adjacent */
    eb_zeros(b, 8 * (size_t)chunks);
    for (int i = 0; i < chunks; i++) {
        put_u64(b->p + table + 8 * (size_t)i, b->n);
        raw.n = 0;
        if (layout == 1) {
            for (int k = 0; k < 4; k++) eb_i32(b, k == 0 ? i : 0); /* tile (i, 0), level (0, 0) */
            eb_pixels(&raw, 8 * i, 8, 0, 8);
        } else {
            if (layout == 2) eb_i32(b, i); /* the part */
            eb_i32(b, 0);                  /* the first row */
            eb_pixels(&raw, 0, 16, 0, 8);
        }
        eb_zip_chunk(b, raw.p, raw.n, i == 0 && keep > 0 ? keep : raw.n);
    }
    free(raw.p);
}
/* The uncompressed scanline map with its R channel renamed Z (still sorted
 * last): three half channels, B and G read, Z not (R reads 0). The shape
 * of a fuzzer's file on which OpenEXRCore 3.1.5 wrote the unread channel
 * through a NULL pointer once half files went to it. */
static void cf_unread_third_channel(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    /* the magic and version, "channels", "chlist", the size, B and G */
    const size_t r = 8 + sizeof "channels" + sizeof "chlist" + 4 + 2 * (2 + 16);
    if (cf->b.n <= r || cf->b.p[r] != 'R' || cf->b.p[r + 1] != 0) {
        fprintf(stderr, "no R channel at byte %zu of the test map\n", r);
        exit(1);
    }
    cf->b.p[r] = 'Z';
}
static void cf_zip_scanline(chunk_file *cf) { cf_zip(cf, 0, 0); }
static void cf_zip_tiled(chunk_file *cf) { cf_zip(cf, 1, 0); }
static void cf_zip_two_parts(chunk_file *cf) { cf_zip(cf, 2, 0); }

/* A 16 x 8 ZIP header (one chunk of 16 rows) and its offset table of one
 * zero entry: the shape of regress/env/openexr-zip-chunk-without-data. */
static void hc_zip_zeroed_table(chunk_file *cf)
{
    eb_start(&cf->b, 0);
    eb_required(&cf->b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
    eb_u8(&cf->b, 0);
    eb_zeros(&cf->b, 8);
}
/* The same header, the table pointing at a chunk header that declares
 * 700 bytes of ZIP data, and 16 of them. */
static void hc_zip_packed_beyond_file(chunk_file *cf)
{
    exr_bytes *b = &cf->b;
    eb_start(b, 0);
    eb_required(b, 3, EB_HALF, EB_ZIP, 0, 0, 15, 7);
    eb_u8(b, 0);
    size_t table = b->n;
    eb_zeros(b, 8);
    put_u64(b->p + table, b->n);
    eb_i32(b, 0);
    eb_i32(b, 700);
    eb_zeros(b, 16);
}
/* The uncompressed map's header and zeroed table, no chunk data at all. */
static void hc_zeroed_table(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    cf->b.n = cf->chunk[0][0];
    memset(cf->b.p + cf->table[0], 0, 64);
}
/* Every entry a little past the end of the file. */
static void hc_offsets_past_end(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    for (int y = 0; y < 8; y++) put_u64(cf->b.p + cf->table[0] + 8 * (size_t)y, cf->b.n + 16 * (size_t)y);
}
/* Only the last chunk is bad: the file ends 10 bytes before its data does. */
static void hc_last_chunk_truncated(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    cf->b.n -= 10;
}
/* Only the last chunk is bad: its entry is zero. */
static void hc_last_entry_zeroed(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    put_u64(cf->b.p + cf->table[0] + 8 * 7, 0);
}
/* The first chunk declares more data than there is to the end of the file. */
static void hc_packed_beyond_file(chunk_file *cf)
{
    cf_scanline(cf, 1, 0, 96);
    put_u32(cf->b.p + cf->chunk[0][0] + 4, (uint32_t)(cf->b.n - cf->chunk[0][0]));
}
/* An uncompressed chunk that holds 48 of its 96 bytes. */
static void hc_short_uncompressed(chunk_file *cf) { cf_scanline(cf, 1, 0, 48); }
/* Tiled: the second tile's entry points at the first tile. */
static void hc_tile_entry(chunk_file *cf)
{
    cf_tiled(cf, 0);
    put_u64(cf->b.p + cf->table[0] + 8 * (size_t)cf_tile_index(cf, 1, 0, 0, 0), cf->chunk[0][0]);
}
/* Tiled: the last tile's entry points past the end of the file. */
static void hc_last_tile_past_end(chunk_file *cf)
{
    cf_tiled(cf, 0);
    put_u64(cf->b.p + cf->table[0] + 8 * (size_t)cf_tile_index(cf, 1, 0, 0, 0), cf->b.n + 1000);
}
/* Mipmap: the last level's tile declares no data. */
static void hc_mipmap_last_tile_empty(chunk_file *cf)
{
    cf_tiled(cf, 1);
    put_u32(cf->b.p + cf->chunk[0][cf_tile_index(cf, 0, 0, 4, 4)] + 16, 0);
}
/* Ripmap: level (1, 1)'s tile entry points at the tile of level (0, 1)
 * (OpenEXRCore 3.1 cannot look these tiles up: checked by exr_io.c). */
static void hc_ripmap_tile_entry(chunk_file *cf)
{
    cf_tiled(cf, 2);
    put_u64(cf->b.p + cf->table[0] + 8 * (size_t)cf_tile_index(cf, 0, 0, 1, 1),
            cf->chunk[0][cf_tile_index(cf, 0, 0, 0, 1)]);
}
/* Two parts: part 0 sound, one entry of part 1 zero. */
static void hc_second_part_entry(chunk_file *cf)
{
    cf_scanline(cf, 2, 8, 96);
    put_u64(cf->b.p + cf->table[1] + 8 * 3, 0);
}
/* Two parts: part 0's first entry points into part 1's offset table,
 * whose two entries (0 and 96) read there as a sound chunk header: part 0,
 * row 0, 96 bytes. Past part 0's own table, so OpenEXRCore's bound alone
 * lets it through. */
static void hc_entry_into_tables(chunk_file *cf)
{
    cf_scanline(cf, 2, 2, 96);
    put_u64(cf->b.p + cf->table[1], 0);
    put_u64(cf->b.p + cf->table[1] + 8, 96);
    put_u64(cf->b.p + cf->table[0], cf->table[1]);
}

/* ZIP chunks whose data is a sound zlib stream that decompresses to fewer
 * bytes than the chunk's pixels: 100 of the 768 of a scanline map's one
 * chunk, 100 of the 384 of a tiled map's first tile, and 100 of the 768 of
 * the first part's chunk in a file of two parts. The C++ reader loads all
 * three without an error (the rest of the pixels from its uninitialised
 * buffer). */
static void hc_zip_short(chunk_file *cf) { cf_zip(cf, 0, 100); }
static void hc_zip_tile_short(chunk_file *cf) { cf_zip(cf, 1, 100); }
static void hc_zip_part_short(chunk_file *cf) { cf_zip(cf, 2, 100); }

static void test_hostile_chunks(void)
{
    static const struct {
        const char *name;
        void (*make)(chunk_file *);
        const char *chunk, *why; /* the refusal names the chunk and says why */
    } shapes[] = {
        {"zip_zeroed_table_no_data", hc_zip_zeroed_table, "part 0, chunk of rows 0..7", "points at byte 0, inside the header"},
        {"zip_packed_size_beyond_file", hc_zip_packed_beyond_file, "part 0, chunk of rows 0..7", "packed size 700"},
        {"zeroed_table_no_data", hc_zeroed_table, "part 0, chunk of rows 0..0", "points at byte 0, inside the header"},
        {"offsets_past_end", hc_offsets_past_end, "part 0, chunk of rows 0..0", "but the file ends"},
        {"packed_size_beyond_file", hc_packed_beyond_file, "part 0, chunk of rows 0..0", "packed"},
        {"last_chunk_truncated", hc_last_chunk_truncated, "part 0, chunk of rows 7..7", "packed size 96"},
        {"last_entry_zeroed", hc_last_entry_zeroed, "part 0, chunk of rows 7..7", "points at byte 0, inside the header"},
        {"uncompressed_chunk_short", hc_short_uncompressed, "part 0, chunk of rows 0..0", "holds 48"},
        {"tile_entry_at_other_tile", hc_tile_entry, "part 0, tile (1, 0) level (0, 0)", "tile x coordinate"},
        {"last_tile_past_end", hc_last_tile_past_end, "part 0, tile (1, 0) level (0, 0)", "but the file ends"},
        {"mipmap_last_tile_empty", hc_mipmap_last_tile_empty, "part 0, tile (0, 0) level (4, 4)", "packed size"},
        {"ripmap_tile_entry_at_other_level", hc_ripmap_tile_entry, "part 0, tile (0, 0) level (1, 1)",
         "says tile (0, 0) level (0, 1)"},
        {"second_part_entry_zeroed", hc_second_part_entry, "part 1, chunk of rows 3..3", "points at byte 0, inside the header"},
        {"entry_into_offset_tables", hc_entry_into_tables, "part 0, chunk of rows 0..0",
         "inside the header and offset tables"},
        {"zip_chunk_decompresses_short", hc_zip_short, "pixel data in rows 0..7", "of ZIP data for 768 bytes of pixels"},
        {"zip_tile_decompresses_short", hc_zip_tile_short, "part 0, tile (0, 0) level (0, 0)",
         "of ZIP data for 384 bytes of pixels"},
        {"zip_first_part_decompresses_short", hc_zip_part_short, "part 0, chunk of rows 0..7",
         "of ZIP data for 768 bytes of pixels"},
    };
    hl_context *ctx = make_ctx();
    char dir[512], path[1024];
    scratch(dir, sizeof dir, "hostile_chunks");
    int refused = 0;
    for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) {
        chunk_file cf;
        memset(&cf, 0, sizeof cf);
        shapes[i].make(&cf);
        snprintf(path, sizeof path, "%s/%s.exr", dir, shapes[i].name);
        write_bytes(path, cf.b.p, cf.b.n);
        free(cf.b.p);
        char what[128];
        snprintf(what, sizeof what, "%s (%zu bytes)", shapes[i].name, cf.b.n);
        hl_result r = expect_refused(ctx, path, HL_ERR_FORMAT, what);
        const char *msg = hl_context_last_error(ctx);
        int named = strstr(msg, shapes[i].chunk) != NULL, said = strstr(msg, shapes[i].why) != NULL;
        HL_CHECK(named, "%s: the message does not name \"%s\": %s", shapes[i].name, shapes[i].chunk, msg);
        HL_CHECK(said, "%s: the message does not say \"%s\": %s", shapes[i].name, shapes[i].why, msg);
        refused += r == HL_ERR_FORMAT && named && said;
    }
    printf("hostile chunks refused with the chunk and the reason: %d of %zu\n", refused,
           sizeof shapes / sizeof shapes[0]);

    /* The sound maps these were made from load, every value exact (the
       multi-part one reads its part 0; the one without R reads 0 there);
       so do the float fixtures. */
    static const struct {
        const char *name;
        void (*make)(chunk_file *);
    } sound[] = {{"sound_scanline", NULL},
                 {"sound_two_parts", NULL},
                 {"sound_tiled", cf_tiled_one},
                 {"sound_tiled_mipmap", cf_tiled_mipmap},
                 {"sound_tiled_ripmap", cf_tiled_ripmap},
                 {"sound_zip", cf_zip_scanline},
                 {"sound_zip_tiled", cf_zip_tiled},
                 {"sound_zip_two_parts", cf_zip_two_parts},
                 {"sound_unread_third_channel", cf_unread_third_channel}};
    double worst = 0.0;
    for (size_t i = 0; i < sizeof sound / sizeof sound[0]; i++) {
        chunk_file cf;
        memset(&cf, 0, sizeof cf);
        if (sound[i].make) sound[i].make(&cf);
        else cf_scanline(&cf, i == 0 ? 1 : 2, 8, 96);
        snprintf(path, sizeof path, "%s/%s.exr", dir, sound[i].name);
        write_bytes(path, cf.b.p, cf.b.n);
        free(cf.b.p);
        hl_env *env = NULL;
        hl_env_stats st;
        hl_result r = hl_env_load(ctx, path, &env, &st);
        HL_CHECK(r == HL_OK, "%s: not loaded: %s", path, hl_context_last_error(ctx));
        if (r != HL_OK) continue;
        double w = 0.0;
        HL_CHECK(env->width == 16 && env->height == 8, "%s: %u x %u", path, env->width, env->height);
        for (int y = 0; y < 8 && env->width == 16 && env->height == 8; y++)
            for (int x = 0; x < 16; x++)
                for (int c = 0; c < 3; c++) {
                    double want = c == 0 && sound[i].make == cf_unread_third_channel ? 0.0 : chunk_value(x, y, c);
                    w = fmax(w, fabs((double)env->rgb[3 * (16 * y + x) + c] - want));
                }
        printf("%s (%zu bytes): loaded, worst |value - written| %g\n", sound[i].name, cf.b.n, w);
        worst = fmax(worst, w);
        hl_env_destroy(env);
    }
    hl_check_error("sound maps written byte by byte: |value - written|", worst, 0.0);
    const char *fixtures[2] = {"float_scanline_sun.exr", "float_tiled.exr"};
    for (int k = 0; k < 2; k++) {
        snprintf(path, sizeof path, "%s/%s", hl_test_env("HL_TEST_FIXTURES", "tests/data"), fixtures[k]);
        hl_env *env = NULL;
        hl_env_stats st;
        hl_result r = hl_env_load(ctx, path, &env, &st);
        printf("fixture %s: %s\n", path, r == HL_OK ? "loaded" : hl_context_last_error(ctx));
        HL_CHECK(r == HL_OK, "%s: not loaded: %s", path, hl_context_last_error(ctx));
        hl_env_destroy(env);
    }
    hl_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"hostile", test_hostile_chunks},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
