/* exr_io.c - OpenEXR reading and writing; the only file that includes
 * OpenEXR headers.
 *
 * Two of the library's C interfaces, because neither does everything on
 * Debian 12 (OpenEXR 3.1.5):
 * - OpenEXRCore (openexr.h) decodes half and 32-bit float channels to
 *   float exactly, and checks every chunk's data as it decodes it (a ZIP
 *   chunk must decompress to exactly its size), but cannot decode
 *   DWAA/DWAB, which the shared environments use, and decodes B44 blocks
 *   at a chunk's edges wrongly.
 * - The C wrapper of the C++ library (ImfCRgbaFile.h) decodes every
 *   compression, DWAB included, but only through half floats (a float
 *   channel comes back rounded to 11 significant bits, any value beyond
 *   +-65504 as infinite), and takes a ZIP chunk that decompresses to fewer
 *   bytes than it holds without an error, filling the rest of its pixels
 *   from its own uninitialised buffer.
 * So OpenEXRCore reads every file it can decode (read_core): one scanline
 * part, R, G, B or Y half or float, not subsampled, no chroma, not DWA,
 * and not B44 unless a channel read is float (B44 stores float channels
 * uncompressed). The wrapper reads the rest (read_wrapper): DWA, several
 * parts (it reads part 0), tiles (level 0), subsampled, chroma or integer
 * channels, B44 of half channels. Half values are the same either way
 * (both convert exactly). DWA loses nothing through halves either: its
 * lossy coder stores float R, G, B and Y through halves already (a 1e5
 * written to a float DWAB file reads back as 64704, here and with OpenEXR
 * 3.5's own Python reader). A float file that reaches the wrapper for
 * another reason (tiled, several parts) could hold values the halves
 * cannot, so any infinity in it is refused rather than passed on. Images
 * are written with OpenEXRCore as 32-bit float RGB, ZIP-compressed.
 * Every header is parsed by OpenEXRCore first, and refused unless it is
 * sound and its sizes fit the file, before either decoder sees it: the C++
 * library trusts the header when it opens a file (a string attribute that
 * claims 2 GiB gets 2 GiB; a data window of 2^31 rows gets per-row tables
 * of that length), and OpenEXRCore checks attribute sizes against the file
 * but not what a data window or tile size asks for (check_parts). Then
 * every chunk of every part is checked without decoding: its offset-table
 * entry, its header and that its data lies in the file (check_chunks), as
 * the C++ reader turns a chunk that is not there into garbage pixels
 * without an error. Before the wrapper decodes a file, OpenEXRCore decodes
 * every chunk the wrapper will and throws the pixels away (check_decodes),
 * so that data that decompresses short is refused there too; not for DWA
 * (OpenEXRCore cannot decode it) nor B44 (the C++ reader refuses short B44
 * data itself). A DWA chunk whose own counts are short of its blocks is
 * still not caught (see check_decodes).
 * The wrapper catches every C++ exception and returns 0, with the text in
 * ImfErrorMessage(); OpenEXRCore's messages go to a handler that keeps the
 * last one. The wrapper's pixels are read in strips so that its temporary
 * half buffer stays small.
 * Depends on: libOpenEXR-3_1 and libOpenEXRCore-3_1 (through the
 * hl_openexr CMake target).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <ImfCRgbaFile.h>
#include <openexr.h>

#include "exr_io.h"
#include "hl_internal.h"

/* Rows per strip: about 4 Mi pixels (32 MiB of halves), whole DWAB chunks
 * of 256 rows when the image is narrow enough. */
static uint32_t strip_rows(uint32_t width)
{
    uint32_t rows = (uint32_t)((1u << 22) / width);
    if (rows > 256) rows = 256;
    return rows ? rows : 1;
}

static const char *imf_message(void)
{
    const char *m = ImfErrorMessage();
    return m && *m ? m : "unknown OpenEXR error";
}

/* Pointer that maps pixel (x0, y0) of the data window to first. The
 * library addresses base + x * xStride + y * yStride (in pixels). */
static ImfRgba *frame_base(ImfRgba *first, int64_t x0, int64_t y0, uint32_t width)
{
    intptr_t offset = (intptr_t)(x0 + y0 * (int64_t)width) * (intptr_t)sizeof(ImfRgba);
    return (ImfRgba *)(void *)((intptr_t)(void *)first - offset);
}

/* Opens the file ourselves first so that "cannot open" (HL_ERR_IO) and
 * "not an OpenEXR file" (HL_ERR_FORMAT) get precise messages before the
 * library sees it. */
static hl_result check_file(hl_context *ctx, const char *path, uint64_t *size)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        int e = errno;
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot open environment map: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode))
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot read environment map: not a regular file", path);
    FILE *f = fopen(path, "rb");
    if (!f) {
        int e = errno;
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot open environment map: %s", path, strerror(e));
    }
    unsigned char magic[4];
    size_t got = fread(magic, 1, sizeof magic, f);
    int read_error = ferror(f);
    fclose(f);
    if (read_error)
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot read environment map", path);
    if (got == 0)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not an OpenEXR file: the file is empty", path);
    if (got < sizeof magic)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: not an OpenEXR file: only %zu bytes", path, got);
    if (magic[0] != 0x76 || magic[1] != 0x2f || magic[2] != 0x31 || magic[3] != 0x01)
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: not an OpenEXR file: bad magic number %02x %02x %02x %02x at byte 0",
                       path, magic[0], magic[1], magic[2], magic[3]);
    *size = (uint64_t)st.st_size;
    return HL_OK;
}

/* The data window's size, bounded before anything is allocated. part
 * prefixes the message ("" or "part N: "). */
static hl_result window_size(hl_context *ctx, const char *path, const char *part, unsigned flags, int xmin,
                             int ymin, int xmax, int ymax, uint32_t *width, uint32_t *height)
{
    int64_t w64 = (int64_t)xmax - (int64_t)xmin + 1;
    int64_t h64 = (int64_t)ymax - (int64_t)ymin + 1;
    if (w64 < 1 || h64 < 1 || w64 > (int64_t)HL_EXR_MAX_SIDE || h64 > (int64_t)HL_EXR_MAX_SIDE ||
        (uint64_t)w64 * (uint64_t)h64 > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: %sdata window (%d,%d)-(%d,%d) gives a size of %lld x %lld pixels, "
                       "outside 1..%u per side and %llu pixels in all",
                       path, part, xmin, ymin, xmax, ymax, (long long)w64, (long long)h64,
                       HL_EXR_MAX_SIDE, (unsigned long long)HL_EXR_MAX_PIXELS);
    uint32_t w = (uint32_t)w64, h = (uint32_t)h64;
    if ((flags & HL_EXR_REQUIRE_2TO1) && w != 2 * h)
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: %u x %u pixels is not an equirectangular map (width must be 2 x height)",
                       path, w, h);
    *width = w;
    *height = h;
    return HL_OK;
}

/* OpenEXRCore reports through a handler: it keeps the last message in
 * the context's user data. */
typedef struct core_msg {
    char text[256];
} core_msg;

static void core_error(exr_const_context_t f, exr_result_t code, const char *msg)
{
    void *ud = NULL;
    if (exr_get_user_data(f, &ud) == EXR_ERR_SUCCESS && ud)
        snprintf(((core_msg *)ud)->text, sizeof((core_msg *)ud)->text, "%s",
                 msg ? msg : exr_get_default_error_message(code));
}

static const char *core_text(const core_msg *m, exr_result_t rv)
{
    return m->text[0] ? m->text : exr_get_default_error_message(rv);
}

/* A context initializer whose messages go to m. */
static exr_context_initializer_t core_init(core_msg *m)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = core_error;
    init.user_data = m;
    return init;
}

/* The channels read: R, G and B (a missing one reads 0), or Y alone (grey). */
enum { CH_R, CH_G, CH_B, CH_Y, CH_COUNT };
static const char *const channel_names[CH_COUNT] = {"R", "G", "B", "Y"};

static int channel_of(const char *name)
{
    for (int k = 0; name && k < CH_COUNT; k++)
        if (strcmp(name, channel_names[k]) == 0) return k;
    return -1;
}

/* What OpenEXRCore's header parse (no decoding) says of the file. */
typedef struct exr_layout {
    int any_float;          /* an R, G, B or Y channel is 32-bit float */
    int grey;               /* Y is read, as grey; R, G and B are not */
    exr_compression_t comp; /* part 0's compression */
    const char *reason;     /* why read_core does not read it (NULL: it does:
                               one scanline part, R/G/B/Y half or float, not
                               subsampled, no chroma, not DWA, not B44 with
                               only half R/G/B/Y) */
} exr_layout;

/* Y is grey when there is no R, G or B; beside them it wins only where no
 * R, G, B or Y channel is float: the C++ library's RGBA interface reads
 * any file with Y as luminance and drops R, G and B, and half files were
 * read by it before OpenEXRCore read them (they load as they did), while
 * OpenEXRCore has read float ones as RGB since it read float files.
 * B44 with only half R/G/B/Y stays with the wrapper: OpenEXRCore 3.1.5
 * decodes the B44 blocks at a chunk's edges wrongly (the last row of a
 * 130 x 65 map, every pixel of a 2 x 1 one, or "unable to decompress");
 * B44 leaves float channels uncompressed, so float files are not
 * affected, and went to OpenEXRCore before. */
static int probe(exr_context_t f, exr_layout *lay)
{
    int parts = 0;
    exr_storage_t st;
    const exr_attr_chlist_t *cl = NULL;
    memset(lay, 0, sizeof *lay);
    if (exr_get_count(f, &parts) != EXR_ERR_SUCCESS || exr_get_storage(f, 0, &st) != EXR_ERR_SUCCESS ||
        exr_get_compression(f, 0, &lay->comp) != EXR_ERR_SUCCESS ||
        exr_get_channels(f, 0, &cl) != EXR_ERR_SUCCESS || !cl)
        return 0;
    int rgb = 0, y = 0, odd = 0;
    for (int i = 0; i < cl->num_channels; i++) {
        const exr_attr_chlist_entry_t *e = &cl->entries[i];
        if (e->name.str && (strcmp(e->name.str, "RY") == 0 || strcmp(e->name.str, "BY") == 0)) odd = 1;
        int k = channel_of(e->name.str);
        if (k < 0) continue;
        if (k == CH_Y) y = 1;
        else rgb = 1;
        if (e->pixel_type == EXR_PIXEL_FLOAT) lay->any_float = 1;
        else if (e->pixel_type != EXR_PIXEL_HALF) odd = 1;
        if (e->x_sampling != 1 || e->y_sampling != 1) odd = 1;
    }
    lay->grey = y && (!rgb || !lay->any_float);
    const int b44 = lay->comp == EXR_COMPRESSION_B44 || lay->comp == EXR_COMPRESSION_B44A;
    lay->reason = parts != 1                                       ? "a file of several parts"
                  : st != EXR_STORAGE_SCANLINE                     ? "a tiled or deep file"
                  : lay->comp == EXR_COMPRESSION_DWAA ||
                    lay->comp == EXR_COMPRESSION_DWAB              ? "DWA compression"
                  : !rgb && !y                                     ? "no R, G, B or Y channel"
                  : odd                                            ? "subsampled, chroma or integer channels"
                  : b44 && !lay->any_float                         ? "B44 compression of half channels"
                                                                   : NULL;
    return 1;
}

/* a * b, or UINT64_MAX where that overflows. */
static uint64_t mul_sat(uint64_t a, uint64_t b)
{
    return b && a > UINT64_MAX / b ? UINT64_MAX : a * b;
}

/* Every part of a header OpenEXRCore accepted, bounded against the file
 * before any reader allocates for it: the C++ reader sizes its offset
 * tables, per-row tables and chunk buffers from the header when the file
 * is opened, and OpenEXRCore its offset table when the first chunk is
 * read. A chunk table the file cannot hold, or a chunk larger than any map
 * needs, is refused; so are deep parts and headers of more attributes and
 * channels than HL_EXR_MAX_HEADER_ENTRIES. */
static hl_result check_parts(hl_context *ctx, const char *path, exr_const_context_t f, const core_msg *msg,
                             uint64_t file_size)
{
    int parts = 0;
    exr_result_t rv = exr_get_count(f, &parts);
    if (rv != EXR_ERR_SUCCESS || parts < 1)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path,
                       rv != EXR_ERR_SUCCESS ? core_text(msg, rv) : "no parts");
    uint64_t table_bytes = 0, entries = 0;
    for (int p = 0; p < parts; p++) {
        char part[32] = "";
        if (parts > 1) snprintf(part, sizeof part, "part %d: ", p);
        exr_storage_t st;
        exr_attr_box2i_t dw;
        const exr_attr_chlist_t *cl = NULL;
        int32_t chunks = 0, attrs = 0, lines = 1;
        uint32_t tw = 0, th = 0;
        rv = exr_get_storage(f, p, &st);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_data_window(f, p, &dw);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_channels(f, p, &cl);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_chunk_count(f, p, &chunks);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_attribute_count(f, p, &attrs);
        if (rv == EXR_ERR_SUCCESS && st == EXR_STORAGE_SCANLINE) rv = exr_get_scanlines_per_chunk(f, p, &lines);
        if (rv == EXR_ERR_SUCCESS && st == EXR_STORAGE_TILED) rv = exr_get_tile_descriptor(f, p, &tw, &th, NULL, NULL);
        if (rv != EXR_ERR_SUCCESS || !cl)
            return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s%s", path, part,
                           core_text(msg, rv != EXR_ERR_SUCCESS ? rv : EXR_ERR_MISSING_REQ_ATTR));
        if (st != EXR_STORAGE_SCANLINE && st != EXR_STORAGE_TILED)
            return hl_fail(ctx, HL_ERR_FORMAT, "%s: %sdeep data (several samples per pixel), not an image", path,
                           part);
        uint32_t w = 0, h = 0;
        hl_result r = window_size(ctx, path, part, 0, dw.min.x, dw.min.y, dw.max.x, dw.max.y, &w, &h);
        if (r != HL_OK) return r;

        /* A chunk as decoded: its pixels times the bytes of all channels
           (subsampling ignored: an upper bound). */
        uint64_t pixel_bytes = 0;
        for (int c = 0; c < cl->num_channels; c++)
            pixel_bytes += cl->entries[c].pixel_type == EXR_PIXEL_HALF ? 2u : 4u;
        uint64_t cw = st == EXR_STORAGE_TILED ? tw : w, ch = st == EXR_STORAGE_TILED ? th : (uint64_t)lines;
        uint64_t chunk_bytes = mul_sat(cw * ch, pixel_bytes); /* cw, ch < 2^32 */
        if (chunk_bytes > HL_EXR_MAX_CHUNK_BYTES)
            return hl_fail(ctx, HL_ERR_FORMAT,
                           "%s: %sa %s of %llu x %llu pixels with %d channels (%llu bytes a pixel) decodes to "
                           "%llu bytes, more than the %llu any map needs",
                           path, part, st == EXR_STORAGE_TILED ? "tile" : "chunk", (unsigned long long)cw,
                           (unsigned long long)ch, cl->num_channels, (unsigned long long)pixel_bytes,
                           (unsigned long long)chunk_bytes, (unsigned long long)HL_EXR_MAX_CHUNK_BYTES);
        if (chunks < 1)
            return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s%d chunks", path, part, chunks);

        /* Each chunk has its 8-byte entry in the offset table and a header
           in front of its data: the part number in a multi-part file, then
           the first row (scanlines) or the tile's four coordinates, then
           the data size. */
        uint64_t chunk_header = (parts > 1 ? 4u : 0u) + (st == EXR_STORAGE_TILED ? 20u : 8u);
        table_bytes += (uint64_t)chunks * (8u + chunk_header);
        if (table_bytes > file_size)
            return hl_fail(ctx, HL_ERR_FORMAT,
                           "%s: %s%d chunks (%s of %llu x %llu pixels in a %u x %u data window) need at least "
                           "%llu bytes of offset table and chunk headers%s, but the file has %llu bytes",
                           path, part, chunks, st == EXR_STORAGE_TILED ? "tiles" : "rows", (unsigned long long)cw,
                           (unsigned long long)ch, w, h, (unsigned long long)table_bytes,
                           p > 0 ? " with the parts before" : "", (unsigned long long)file_size);
        entries += (uint64_t)attrs + (uint64_t)cl->num_channels;
    }
    if (entries > HL_EXR_MAX_HEADER_ENTRIES)
        return hl_fail(ctx, HL_ERR_FORMAT,
                       "%s: the header has %llu attributes and channels in %d part%s, more than the %u a map "
                       "needs",
                       path, (unsigned long long)entries, parts, parts == 1 ? "" : "s", HL_EXR_MAX_HEADER_ENTRIES);
    return HL_OK;
}

/* Opens path at the first chunk offset table, and says where that is and
 * whether the version field marks the file multi-part (each chunk then
 * begins with its part number). OpenEXRCore has parsed the header
 * strictly already but does not say where it ends (3.1 has no call for
 * it), so it is walked again here: an attribute is a name and a type
 * (NUL-terminated), a 4-byte size and that many bytes; an empty name ends
 * a header, and in a multi-part file an empty header ends the list. */
static hl_result open_tables(hl_context *ctx, const char *path, uint64_t file_size, FILE **out, uint64_t *start,
                             int *multipart)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        int e = errno;
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot open environment map: %s", path, strerror(e));
    }
    unsigned char head[8];
    int ok = fread(head, 1, sizeof head, fp) == sizeof head, ended = 0;
    *multipart = ok && (head[5] & 0x10) != 0; /* bit 12 of the little-endian version field */
    uint64_t pos = sizeof head;
    while (ok) {
        uint64_t name = 0;
        int c;
        while ((c = getc(fp)) > 0) name++;
        pos += name + 1;
        if (c == EOF) {
            ok = 0;
            break;
        }
        if (name == 0) {
            if (!*multipart || ended) break;
            ended = 1;
            continue;
        }
        ended = 0;
        while ((c = getc(fp)) > 0) pos++;
        unsigned char sz[4];
        if (c == EOF || fread(sz, 1, sizeof sz, fp) != sizeof sz) {
            ok = 0;
            break;
        }
        uint32_t size = (uint32_t)sz[0] | (uint32_t)sz[1] << 8 | (uint32_t)sz[2] << 16 | (uint32_t)sz[3] << 24;
        pos += 1 + sizeof sz + size;
        ok = size <= INT32_MAX && pos <= file_size && fseek(fp, (long)size, SEEK_CUR) == 0;
    }
    if (!ok) {
        fclose(fp);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: it does not end inside the file", path);
    }
    *out = fp;
    *start = pos;
    return HL_OK;
}

/* The walk over every chunk, in the order of the offset tables. */
typedef struct chunk_walk {
    FILE *fp;             /* at the next entry of the offset tables */
    uint64_t tables_end;  /* the byte after the last part's table */
    uint64_t file_size;
    uint64_t leader;      /* bytes of a chunk's header in this part */
} chunk_walk;

/* The next entry of the offset tables (0 at a read error: the tables fit
 * in the file, so only an I/O error gets there). */
static uint64_t next_entry(chunk_walk *w)
{
    unsigned char e[8];
    uint64_t entry = 0;
    if (fread(e, 1, sizeof e, w->fp) != sizeof e) return 0;
    for (int k = 7; k >= 0; k--) entry = entry << 8 | e[k];
    return entry;
}

/* What is wrong with a chunk ("" when nothing): its entry in the offset
 * table must point past every part's table (Core bounds it by its own
 * part's table only) with room for the chunk's header; OpenEXRCore (rv, ci:
 * what exr_read_*_chunk_info said of it) must accept its header and see it
 * where the entry says; and its data must be there: not empty, inside the
 * file and, uncompressed, all of it (the C++ reader takes a short
 * uncompressed chunk and copies whatever its buffer held beyond it). */
static void chunk_fault(const chunk_walk *w, uint64_t entry, exr_result_t rv, const exr_chunk_info_t *ci,
                        const core_msg *msg, char *why, size_t n)
{
    why[0] = '\0';
    if (entry < w->tables_end)
        snprintf(why, n, "its offset-table entry points at byte %llu, inside the header and offset tables "
                 "(bytes 0..%llu)", (unsigned long long)entry, (unsigned long long)(w->tables_end - 1));
    else if (entry > w->file_size || w->file_size - entry < w->leader)
        snprintf(why, n, "its offset-table entry points at byte %llu, but the file ends at byte %llu "
                 "(a chunk header there needs %llu bytes)", (unsigned long long)entry,
                 (unsigned long long)w->file_size, (unsigned long long)w->leader);
    else if (rv != EXR_ERR_SUCCESS)
        snprintf(why, n, "%s", core_text(msg, rv));
    else if (ci->data_offset != entry + w->leader)
        snprintf(why, n, "its data is read at byte %llu, not after its header at byte %llu",
                 (unsigned long long)ci->data_offset, (unsigned long long)entry);
    else if (ci->packed_size == 0 && ci->unpacked_size > 0)
        snprintf(why, n, "no data (a packed size of 0 for %llu bytes of pixels)",
                 (unsigned long long)ci->unpacked_size);
    else if (ci->packed_size > w->file_size - ci->data_offset)
        snprintf(why, n, "%llu bytes of data at byte %llu end beyond the file's %llu bytes",
                 (unsigned long long)ci->packed_size, (unsigned long long)ci->data_offset,
                 (unsigned long long)w->file_size);
    else if (ci->compression == EXR_COMPRESSION_NONE && ci->packed_size != ci->unpacked_size)
        snprintf(why, n, "an uncompressed chunk of %llu bytes of pixels holds %llu",
                 (unsigned long long)ci->unpacked_size, (unsigned long long)ci->packed_size);
}

/* exr_read_tile_chunk_info for a ripmap tile at a level y above 0, which
 * OpenEXRCore 3.1 looks up in the wrong table entry (before the row of
 * levels it counts only the levels left of this one, so it refuses sound
 * ripmaps): the tile's header at entry is read and checked here the same
 * way (part, tile and level, 0 < packed size <= unpacked size). want:
 * tile x, tile y, level x, level y. */
static exr_result_t ripmap_tile_info(chunk_walk *w, uint64_t entry, int part, int multipart, const int want[4],
                                     uint64_t unpacked, exr_compression_t comp, exr_chunk_info_t *ci, core_msg *msg)
{
    unsigned char b[24];
    const size_t n = (size_t)w->leader;
    off_t back = ftello(w->fp);
    int ok = back >= 0 && fseeko(w->fp, (off_t)entry, SEEK_SET) == 0 && fread(b, 1, n, w->fp) == n;
    if (back < 0 || fseeko(w->fp, back, SEEK_SET) != 0) ok = 0;
    if (!ok) {
        snprintf(msg->text, sizeof msg->text, "cannot read the chunk header at byte %llu", (unsigned long long)entry);
        return EXR_ERR_READ_IO;
    }
    int32_t v[6];
    for (size_t k = 0; k < n / 4; k++)
        v[k] = (int32_t)((uint32_t)b[4 * k] | (uint32_t)b[4 * k + 1] << 8 | (uint32_t)b[4 * k + 2] << 16 |
                         (uint32_t)b[4 * k + 3] << 24);
    const int32_t *t = v + (multipart ? 1 : 0);
    if (multipart && v[0] != part) {
        snprintf(msg->text, sizeof msg->text, "its chunk header says part %d", (int)v[0]);
        return EXR_ERR_BAD_CHUNK_LEADER;
    }
    if (t[0] != want[0] || t[1] != want[1] || t[2] != want[2] || t[3] != want[3]) {
        snprintf(msg->text, sizeof msg->text, "its chunk header says tile (%d, %d) level (%d, %d)", (int)t[0],
                 (int)t[1], (int)t[2], (int)t[3]);
        return EXR_ERR_BAD_CHUNK_LEADER;
    }
    if (t[4] < 0 || (uint64_t)t[4] > unpacked) {
        snprintf(msg->text, sizeof msg->text, "its packed size %d is not within 0..%llu, its pixels' bytes",
                 (int)t[4], (unsigned long long)unpacked);
        return EXR_ERR_BAD_CHUNK_LEADER;
    }
    memset(ci, 0, sizeof *ci);
    ci->start_x = want[0];
    ci->start_y = want[1];
    ci->level_x = (uint8_t)want[2];
    ci->level_y = (uint8_t)want[3];
    ci->type = (uint8_t)EXR_STORAGE_TILED;
    ci->compression = (uint8_t)comp;
    ci->data_offset = entry + n;
    ci->packed_size = (uint64_t)t[4];
    ci->unpacked_size = unpacked;
    return EXR_ERR_SUCCESS;
}

/* Every chunk of every part, before any decoder runs: its entry in the
 * offset table, its header and its data's extent (chunk_fault), without
 * decoding. OpenEXRCore reads and checks each chunk's header against the
 * part and the file (exr_read_scanline_chunk_info for each chunk's first
 * row, exr_read_tile_chunk_info for each tile of each level; see
 * ripmap_tile_info for the exception); the tables are read here too, in
 * the same order. Any fault refuses the file, naming the part, the chunk
 * and the reason: the C++ reader decodes a ZIP chunk of size 0
 * "successfully" into pixels no one wrote, and rebuilds a table it finds
 * broken by scanning the file (Core is not let do the same:
 * EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION). Every part is checked,
 * not only part 0, the one decoded: the C++ reader reads every part's
 * table when it opens a multi-part file and, if one entry is out of range,
 * rebuilds all of them, part 0's included. Cost: a read of a few bytes a
 * chunk, and check_parts has bounded the chunk count by the file's size
 * (tile levels that hold more tiles than the part has chunks are refused
 * before they are walked). */
static hl_result check_chunks(hl_context *ctx, const char *path, exr_const_context_t f, core_msg *msg,
                              uint64_t file_size)
{
    chunk_walk w = {NULL, 0, file_size, 0};
    int parts = 0, multipart = 0;
    hl_result r = open_tables(ctx, path, file_size, &w.fp, &w.tables_end, &multipart);
    if (r != HL_OK) return r;
    exr_result_t rv = exr_get_count(f, &parts);
    for (int p = 0; rv == EXR_ERR_SUCCESS && p < parts; p++) {
        int32_t chunks = 0;
        rv = exr_get_chunk_count(f, p, &chunks);
        w.tables_end += 8u * (uint64_t)(chunks > 0 ? chunks : 0);
    }
    if (rv != EXR_ERR_SUCCESS)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, core_text(msg, rv));
    else if (w.tables_end > file_size)
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: the chunk offset tables end at byte %llu, beyond the file's %llu",
                    path, (unsigned long long)w.tables_end, (unsigned long long)file_size);

    char why[320];
    for (int p = 0; r == HL_OK && p < parts; p++) {
        exr_storage_t st;
        exr_attr_box2i_t dw;
        exr_compression_t comp;
        const exr_attr_chlist_t *cl = NULL;
        int32_t chunks = 0, lines = 1;
        rv = exr_get_storage(f, p, &st);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_data_window(f, p, &dw);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_chunk_count(f, p, &chunks);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_compression(f, p, &comp);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_channels(f, p, &cl);
        if (rv == EXR_ERR_SUCCESS && st == EXR_STORAGE_SCANLINE) rv = exr_get_scanlines_per_chunk(f, p, &lines);
        if (rv == EXR_ERR_SUCCESS && (!cl || lines < 1)) rv = EXR_ERR_INVALID_ATTR;
        if (rv != EXR_ERR_SUCCESS) {
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: part %d: %s", path, p,
                        core_text(msg, rv));
            break;
        }
        exr_chunk_info_t ci;
        if (st == EXR_STORAGE_SCANLINE) {
            w.leader = (multipart ? 4u : 0u) + 8u; /* [part], first row, packed size */
            for (int64_t y = dw.min.y; r == HL_OK && y <= (int64_t)dw.max.y; y += lines) {
                int64_t last = y + lines - 1 < (int64_t)dw.max.y ? y + lines - 1 : (int64_t)dw.max.y;
                uint64_t entry = next_entry(&w);
                msg->text[0] = '\0';
                rv = exr_read_scanline_chunk_info(f, p, (int)y, &ci);
                chunk_fault(&w, entry, rv, &ci, msg, why, sizeof why);
                if (why[0])
                    r = hl_fail(ctx, HL_ERR_FORMAT, "%s: part %d, chunk of rows %lld..%lld: %s", path, p,
                                (long long)y, (long long)last, why);
            }
            continue;
        }
        /* Tiled (check_parts refused deep parts), in the table's order:
           level by level (rows of levels for ripmaps), each row by row. */
        w.leader = (multipart ? 4u : 0u) + 20u; /* [part], tile x, y, level x, y, packed size */
        uint32_t tw = 0, th = 0;
        exr_tile_level_mode_t mode = EXR_TILE_ONE_LEVEL;
        int32_t nlx = 0, nly = 0;
        rv = exr_get_tile_descriptor(f, p, &tw, &th, &mode, NULL);
        if (rv == EXR_ERR_SUCCESS) rv = exr_get_tile_levels(f, p, &nlx, &nly);
        if (rv == EXR_ERR_SUCCESS && (tw < 1 || th < 1)) rv = EXR_ERR_INVALID_ATTR;
        if (rv != EXR_ERR_SUCCESS) {
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: part %d: %s", path, p,
                        core_text(msg, rv));
            break;
        }
        uint64_t pixel_bytes = 0;
        for (int c = 0; c < cl->num_channels; c++)
            pixel_bytes += cl->entries[c].pixel_type == EXR_PIXEL_HALF ? 2u : 4u;
        int64_t seen = 0;
        for (int ly = 0; r == HL_OK && ly < nly; ly++)
            for (int lx = 0; r == HL_OK && lx < nlx; lx++) {
                if (mode != EXR_TILE_RIPMAP_LEVELS && lx != ly) continue;
                int32_t lw = 0, lh = 0;
                msg->text[0] = '\0';
                rv = exr_get_level_sizes(f, p, lx, ly, &lw, &lh);
                if (rv != EXR_ERR_SUCCESS || lw < 1 || lh < 1) {
                    r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: part %d, level (%d, %d): %s",
                                path, p, lx, ly, core_text(msg, rv != EXR_ERR_SUCCESS ? rv : EXR_ERR_INVALID_ATTR));
                    break;
                }
                int64_t nx = ((int64_t)lw + tw - 1) / tw, ny = ((int64_t)lh + th - 1) / th;
                seen += nx * ny;
                if (seen > chunks) {
                    r = hl_fail(ctx, HL_ERR_FORMAT, "%s: part %d: its tile levels hold more tiles than its %d chunks",
                                path, p, chunks);
                    break;
                }
                for (int64_t ty = 0; r == HL_OK && ty < ny; ty++)
                    for (int64_t tx = 0; r == HL_OK && tx < nx; tx++) {
                        uint64_t entry = next_entry(&w);
                        msg->text[0] = '\0';
                        rv = EXR_ERR_SUCCESS; /* an entry out of bounds is refused first */
                        memset(&ci, 0, sizeof ci);
                        if (mode != EXR_TILE_RIPMAP_LEVELS || ly == 0) {
                            rv = exr_read_tile_chunk_info(f, p, (int)tx, (int)ty, lx, ly, &ci);
                        } else if (entry >= w.tables_end && entry <= file_size && file_size - entry >= w.leader) {
                            const int want[4] = {(int)tx, (int)ty, lx, ly};
                            int64_t cw = (int64_t)lw - tx * tw < (int64_t)tw ? (int64_t)lw - tx * tw : (int64_t)tw;
                            int64_t chh = (int64_t)lh - ty * th < (int64_t)th ? (int64_t)lh - ty * th : (int64_t)th;
                            rv = ripmap_tile_info(&w, entry, p, multipart, want, (uint64_t)(cw * chh) * pixel_bytes,
                                                  comp, &ci, msg);
                        }
                        chunk_fault(&w, entry, rv, &ci, msg, why, sizeof why);
                        if (why[0])
                            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: part %d, tile (%lld, %lld) level (%d, %d): %s", path,
                                        p, (long long)tx, (long long)ty, lx, ly, why);
                    }
            }
        if (r == HL_OK && seen != chunks)
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: part %d: its tile levels hold %lld tiles, not its %d chunks", path,
                        p, (long long)seen, chunks);
    }
    fclose(w.fp);
    return r;
}

/* " (N bytes of ZIP data for M bytes of pixels)" for a chunk OpenEXRCore
 * read the header of, else "". */
static void chunk_sizes(char *out, size_t n, const exr_chunk_info_t *ci)
{
    static const char *const names[] = {"uncompressed", "RLE",  "ZIPS", "ZIP",  "PIZ",
                                        "PXR24",        "B44",  "B44A", "DWAA", "DWAB"};
    out[0] = '\0';
    if (ci->unpacked_size > 0 && ci->compression < sizeof names / sizeof names[0])
        snprintf(out, n, " (%llu bytes of %s data for %llu bytes of pixels)", (unsigned long long)ci->packed_size,
                 names[ci->compression], (unsigned long long)ci->unpacked_size);
}

/* Decodes one chunk (ci) of part p with OpenEXRCore and throws the pixels
 * away: no channel is unpacked, but the data is read and decompressed,
 * and OpenEXRCore checks that it decompresses to exactly the chunk's
 * size. */
static exr_result_t test_decode(exr_const_context_t f, int p, const exr_chunk_info_t *ci, exr_decode_pipeline_t *dec,
                                int *inited)
{
    exr_result_t rv = *inited ? exr_decoding_update(f, p, ci, dec) : exr_decoding_initialize(f, p, ci, dec);
    if (rv != EXR_ERR_SUCCESS) return rv;
    *inited = 1;
    for (int c = 0; c < dec->channel_count; c++) dec->channels[c].decode_to_ptr = NULL;
    rv = exr_decoding_choose_default_routines(f, p, dec);
    return rv == EXR_ERR_SUCCESS ? exr_decoding_run(f, p, dec) : rv;
}

/* Every chunk the wrapper decodes (part 0's; in a tiled part, the tiles of
 * level (0, 0)), decoded by OpenEXRCore first (test_decode), for the one
 * fault check_chunks cannot see without decoding: data that decompresses
 * to fewer bytes than the chunk holds. The C++ reader takes a short ZIP or
 * ZIPS chunk without an error and fills the rest of its pixels from its
 * own uninitialised buffer (RLE, PXR24 and B44 it refuses itself). Not
 * for B44, whose edge blocks OpenEXRCore 3.1 decodes wrongly (it would
 * refuse sound files), nor DWA, which it cannot decode: the C++ reader
 * checks that DWA's DC and AC data decompress to the counts in the chunk,
 * but not that those counts cover the chunk's blocks, and decodes a chunk
 * whose counts are short from its uninitialised buffer without an error;
 * catching that would mean parsing DWA's channel rules here, which is not
 * done. Cost: a second decompression of every chunk the wrapper reads
 * (no unpacking). */
static hl_result check_decodes(hl_context *ctx, const char *path, exr_const_context_t f, core_msg *msg)
{
    exr_storage_t st;
    exr_attr_box2i_t dw;
    int32_t lines = 1, lw = 0, lh = 0;
    uint32_t tw = 0, th = 0;
    exr_result_t rv = exr_get_storage(f, 0, &st);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_data_window(f, 0, &dw);
    if (rv == EXR_ERR_SUCCESS && st == EXR_STORAGE_SCANLINE) rv = exr_get_scanlines_per_chunk(f, 0, &lines);
    if (rv == EXR_ERR_SUCCESS && st == EXR_STORAGE_TILED) rv = exr_get_tile_descriptor(f, 0, &tw, &th, NULL, NULL);
    if (rv == EXR_ERR_SUCCESS && st == EXR_STORAGE_TILED) rv = exr_get_level_sizes(f, 0, 0, 0, &lw, &lh);
    if (rv == EXR_ERR_SUCCESS && (lines < 1 || (st == EXR_STORAGE_TILED && (tw < 1 || th < 1 || lw < 1 || lh < 1))))
        rv = EXR_ERR_INVALID_ATTR;
    if (rv != EXR_ERR_SUCCESS)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: part 0: %s", path, core_text(msg, rv));

    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int inited = 0;
    hl_result r = HL_OK;
    char sizes[96];
    exr_chunk_info_t ci;
    if (st == EXR_STORAGE_SCANLINE) {
        for (int64_t y = dw.min.y; r == HL_OK && y <= (int64_t)dw.max.y; y += lines) {
            int64_t last = y + lines - 1 < (int64_t)dw.max.y ? y + lines - 1 : (int64_t)dw.max.y;
            memset(&ci, 0, sizeof ci);
            msg->text[0] = '\0';
            rv = exr_read_scanline_chunk_info(f, 0, (int)y, &ci);
            if (rv == EXR_ERR_SUCCESS) rv = test_decode(f, 0, &ci, &dec, &inited);
            if (rv != EXR_ERR_SUCCESS) {
                chunk_sizes(sizes, sizeof sizes, &ci);
                r = hl_fail(ctx, HL_ERR_FORMAT,
                            "%s: part 0, chunk of rows %lld..%lld: corrupt or truncated pixel data%s: %s", path,
                            (long long)y, (long long)last, sizes, core_text(msg, rv));
            }
        }
    } else {
        int64_t nx = ((int64_t)lw + tw - 1) / tw, ny = ((int64_t)lh + th - 1) / th;
        for (int64_t ty = 0; r == HL_OK && ty < ny; ty++)
            for (int64_t tx = 0; r == HL_OK && tx < nx; tx++) {
                memset(&ci, 0, sizeof ci);
                msg->text[0] = '\0';
                rv = exr_read_tile_chunk_info(f, 0, (int)tx, (int)ty, 0, 0, &ci);
                if (rv == EXR_ERR_SUCCESS) rv = test_decode(f, 0, &ci, &dec, &inited);
                if (rv != EXR_ERR_SUCCESS) {
                    chunk_sizes(sizes, sizeof sizes, &ci);
                    r = hl_fail(ctx, HL_ERR_FORMAT,
                                "%s: part 0, tile (%lld, %lld) level (0, 0): corrupt or truncated pixel data%s: %s",
                                path, (long long)tx, (long long)ty, sizes, core_text(msg, rv));
                }
            }
    }
    if (inited) exr_decoding_destroy(f, &dec);
    return r;
}

/* Reads a file that probe() passed, as float, chunk by chunk. */
static hl_result read_core(hl_context *ctx, const char *path, unsigned flags, exr_context_t f, const core_msg *msg,
                           int grey, uint32_t *width, uint32_t *height, float **rgb)
{
    exr_attr_box2i_t dw;
    int32_t spc = 0;
    exr_result_t rv = exr_get_data_window(f, 0, &dw);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(f, 0, &spc);
    if (rv != EXR_ERR_SUCCESS || spc < 1)
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, core_text(msg, rv));
    uint32_t w, h;
    hl_result r = window_size(ctx, path, "", flags, dw.min.x, dw.min.y, dw.max.x, dw.max.y, &w, &h);
    if (r != HL_OK) return r;
    float *out = hl_calloc(ctx, 3 * (size_t)w * h, sizeof(float), "environment pixels");
    float *unread = hl_malloc(ctx, sizeof(float) * (size_t)w * (size_t)spc, "OpenEXR unread channel rows");
    if (!out || !unread) {
        free(out);
        free(unread);
        return HL_ERR_OUT_OF_MEMORY;
    }

    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    int inited = 0, chosen = 0;
    int64_t y = dw.min.y, first = 0, last = 0;
    for (; r == HL_OK && y <= (int64_t)dw.max.y; y += spc) {
        exr_chunk_info_t ci;
        memset(&ci, 0, sizeof ci);
        first = y - dw.min.y;
        last = first + spc - 1 < (int64_t)h - 1 ? first + spc - 1 : (int64_t)h - 1;
        rv = exr_read_scanline_chunk_info(f, 0, (int)y, &ci);
        if (rv == EXR_ERR_SUCCESS) {
            rv = inited ? exr_decoding_update(f, 0, &ci, &dec) : exr_decoding_initialize(f, 0, &ci, &dec);
            if (rv == EXR_ERR_SUCCESS) inited = 1;
        }
        if (rv == EXR_ERR_SUCCESS &&
            (ci.start_y < dw.min.y || (int64_t)ci.start_y - dw.min.y + ci.height > (int64_t)h || ci.width != (int32_t)w))
            rv = EXR_ERR_CORRUPT_CHUNK;
        /* Every channel is decoded somewhere: those not read go to a scratch
           row buffer. OpenEXRCore 3.1.5 picks its fast half-to-float
           routines (three or four interleaved channels) by the channels it
           writes, then writes every channel, through a NULL pointer for one
           left out (a fuzzer's B, G and one more half channel crashed it). */
        for (int c = 0; rv == EXR_ERR_SUCCESS && c < dec.channel_count; c++) {
            exr_coding_channel_info_t *ch = &dec.channels[c];
            int k = channel_of(ch->channel_name);
            int slot = grey ? (k == CH_Y ? 0 : -1) : (k == CH_Y ? -1 : k);
            if (slot < 0) {
                ch->decode_to_ptr = (uint8_t *)unread;
                ch->user_pixel_stride = (int32_t)sizeof(float);
                ch->user_line_stride = (int32_t)sizeof(float) * (int32_t)w;
            } else {
                ch->decode_to_ptr = (uint8_t *)(out + 3 * (size_t)(ci.start_y - dw.min.y) * w + (size_t)slot);
                ch->user_pixel_stride = 3 * (int32_t)sizeof(float);
                ch->user_line_stride = 3 * (int32_t)sizeof(float) * (int32_t)w;
            }
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
        }
        /* the routines suit every chunk: the channels' types and strides stay */
        if (rv == EXR_ERR_SUCCESS && !chosen) {
            rv = exr_decoding_choose_default_routines(f, 0, &dec);
            chosen = 1;
        }
        if (rv == EXR_ERR_SUCCESS) rv = exr_decoding_run(f, 0, &dec);
        if (rv != EXR_ERR_SUCCESS) {
            char sizes[96];
            chunk_sizes(sizes, sizeof sizes, &ci);
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: corrupt or truncated pixel data in rows %lld..%lld%s: %s", path,
                        (long long)first, (long long)last, sizes, core_text(msg, rv));
        }
    }
    if (inited) exr_decoding_destroy(f, &dec);
    free(unread);
    if (r != HL_OK) {
        free(out);
        return r;
    }
    if (grey)
        for (size_t i = 0; i < (size_t)w * h; i++) out[3 * i + 1] = out[3 * i + 2] = out[3 * i];
    *width = w;
    *height = h;
    *rgb = out;
    return HL_OK;
}

/* Reads any file the C++ library can, through half floats. A non-NULL
 * float_why marks a file whose float channels may hold values the halves
 * cannot (they come back infinite), and says why it is read this way: any
 * infinity is then refused. */
static hl_result read_wrapper(hl_context *ctx, const char *path, unsigned flags, const char *float_why,
                              uint32_t *width, uint32_t *height, float **rgb)
{
    ImfInputFile *in = ImfOpenInputFile(path);
    if (!in) return hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, imf_message());

    int xmin = 0, ymin = 0, xmax = -1, ymax = -1;
    ImfHeaderDataWindow(ImfInputHeader(in), &xmin, &ymin, &xmax, &ymax);
    uint32_t w, h;
    hl_result r = window_size(ctx, path, "", flags, xmin, ymin, xmax, ymax, &w, &h);
    if (r != HL_OK) {
        ImfCloseInputFile(in);
        return r;
    }
    int channels = ImfInputChannels(in);
    if ((channels & (IMF_WRITE_RGB | IMF_WRITE_Y)) == 0) {
        ImfCloseInputFile(in);
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: no R, G, B or Y channel to read", path);
    }

    uint32_t rows = strip_rows(w);
    float *out = hl_malloc(ctx, sizeof(float) * 3 * (size_t)w * h, "environment pixels");
    ImfRgba *strip = hl_calloc(ctx, (size_t)w * rows, sizeof(ImfRgba), "OpenEXR scanline strip");
    if (!out || !strip) {
        free(out);
        free(strip);
        ImfCloseInputFile(in);
        return HL_ERR_OUT_OF_MEMORY;
    }
    uint64_t infinite = 0;
    for (uint32_t y0 = 0; y0 < h; y0 += rows) {
        uint32_t n = h - y0 < rows ? h - y0 : rows;
        int first = (int)((int64_t)ymin + y0), last = (int)((int64_t)ymin + y0 + n - 1);
        if (!ImfInputSetFrameBuffer(in, frame_base(strip, xmin, first, w), 1, w) ||
            !ImfInputReadPixels(in, first, last)) {
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: corrupt or truncated pixel data in rows %u..%u: %s",
                        path, y0, y0 + n - 1, imf_message());
            break;
        }
        for (size_t i = 0; i < (size_t)n * w; i++) {
            float *o = out + 3 * ((size_t)y0 * w + i);
            o[0] = ImfHalfToFloat(strip[i].r);
            o[1] = ImfHalfToFloat(strip[i].g);
            o[2] = ImfHalfToFloat(strip[i].b);
            infinite += (uint64_t)(isinf(o[0]) || isinf(o[1]) || isinf(o[2]));
        }
    }
    free(strip);
    ImfCloseInputFile(in);
    if (r == HL_OK && float_why && infinite)
        r = hl_fail(ctx, HL_ERR_FORMAT,
                    "%s: %llu pixel%s infinite or beyond +-65504 as read: its 32-bit float channels are in %s, "
                    "which this build's OpenEXR (3.1) reads only through half floats, so such values are lost; "
                    "save the map as one scanline part with ZIP or PIZ compression", path,
                    (unsigned long long)infinite, infinite == 1 ? " is" : "s are", float_why);
    if (r != HL_OK) {
        free(out);
        return r;
    }
    *width = w;
    *height = h;
    *rgb = out;
    return HL_OK;
}

hl_result hl_exr_read_rgb_(hl_context *ctx, const char *path, unsigned flags,
                           uint32_t *width, uint32_t *height, float **rgb)
{
    *width = *height = 0;
    *rgb = NULL;
    uint64_t file_size = 0;
    hl_result r = check_file(ctx, path, &file_size);
    if (r != HL_OK) return r;

    /* OpenEXRCore parses the header first, bounding every attribute by the
       file's size (the C++ reader does not: a string attribute claiming
       2 GiB gets 2 GiB). Strict: required attributes must be there. A
       complaint it only reports (a chunkCount that disagrees, an attribute
       it skips) refuses the file too. */
    core_msg msg = {{0}};
    exr_context_initializer_t init = core_init(&msg);
    init.flags |= EXR_CONTEXT_FLAG_STRICT_HEADER | EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    exr_context_t f = NULL;
    exr_result_t rv = exr_start_read(&f, path, &init);
    if (rv != EXR_ERR_SUCCESS || msg.text[0])
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path, core_text(&msg, rv));
    if (r == HL_OK) r = check_parts(ctx, path, f, &msg, file_size);
    if (r == HL_OK) r = check_chunks(ctx, path, f, &msg, file_size);
    exr_layout lay = {0, 0, 0, NULL};
    if (r == HL_OK && !probe(f, &lay))
        r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: %s", path,
                    core_text(&msg, EXR_ERR_MISSING_REQ_ATTR));
    if (r != HL_OK) {
        if (f) exr_finish(&f);
        return r;
    }
    /* Only now does a decoder see the file: OpenEXRCore where it can
       decode it (probe: one scanline part, R/G/B/Y half or float, not
       subsampled, no chroma, not DWA, not B44 of half channels), exactly
       and checking every chunk's decompressed size; else the C++ wrapper,
       after OpenEXRCore has decoded every chunk it will (check_decodes)
       except for DWA and B44, which OpenEXRCore 3.1.5 cannot decode
       (rightly). */
    const int core = !lay.reason;
    const int dwa = lay.comp == EXR_COMPRESSION_DWAA || lay.comp == EXR_COMPRESSION_DWAB;
    const int b44 = lay.comp == EXR_COMPRESSION_B44 || lay.comp == EXR_COMPRESSION_B44A;
    if (core) r = read_core(ctx, path, flags, f, &msg, lay.grey, width, height, rgb);
    else if (!dwa && !b44) r = check_decodes(ctx, path, f, &msg);
    exr_finish(&f);
    if (core || r != HL_OK) return r;
    return read_wrapper(ctx, path, flags, lay.any_float && !dwa ? lay.reason : NULL, width, height, rgb);
}

hl_result hl_exr_write_rgb_(hl_context *ctx, const char *path, uint32_t width,
                            uint32_t height, const float *rgb)
{
    if (width < 1 || height < 1 || width > HL_EXR_MAX_SIDE || height > HL_EXR_MAX_SIDE ||
        (uint64_t)width * height > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: cannot write a %u x %u OpenEXR image",
                       path, width, height);
    core_msg msg = {{0}};
    exr_context_initializer_t init = core_init(&msg);
    exr_context_t f = NULL;
    int part = 0;
    int32_t spc = 0;
    exr_result_t rv = exr_start_write(&f, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS) rv = exr_add_part(f, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(f, part, (int32_t)width, (int32_t)height, EXR_COMPRESSION_ZIP);
    for (int c = CH_R; rv == EXR_ERR_SUCCESS && c <= CH_B; c++)
        rv = exr_add_channel(f, part, channel_names[c], EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(f);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(f, part, &spc);
    if (rv == EXR_ERR_SUCCESS && spc < 1) rv = EXR_ERR_INVALID_ARGUMENT;
    hl_result r = HL_OK;
    if (rv != EXR_ERR_SUCCESS)
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot create OpenEXR file: %s", path, core_text(&msg, rv));

    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int inited = 0, chosen = 0;
    for (uint32_t y = 0; r == HL_OK && y < height; y += (uint32_t)spc) {
        exr_chunk_info_t ci;
        rv = exr_write_scanline_chunk_info(f, part, (int)y, &ci);
        if (rv == EXR_ERR_SUCCESS) {
            rv = inited ? exr_encoding_update(f, part, &ci, &enc) : exr_encoding_initialize(f, part, &ci, &enc);
            if (rv == EXR_ERR_SUCCESS) inited = 1;
        }
        for (int c = 0; rv == EXR_ERR_SUCCESS && c < enc.channel_count; c++) {
            exr_coding_channel_info_t *ch = &enc.channels[c];
            int k = channel_of(ch->channel_name);
            ch->encode_from_ptr = (const uint8_t *)(rgb + 3 * (size_t)y * width + (size_t)(k < 0 ? 0 : k));
            ch->user_pixel_stride = 3 * (int32_t)sizeof(float);
            ch->user_line_stride = 3 * (int32_t)sizeof(float) * (int32_t)width;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
        }
        if (rv == EXR_ERR_SUCCESS && !chosen) {
            rv = exr_encoding_choose_default_routines(f, part, &enc);
            chosen = 1;
        }
        if (rv == EXR_ERR_SUCCESS) rv = exr_encoding_run(f, part, &enc);
        if (rv != EXR_ERR_SUCCESS) {
            uint32_t last = y + (uint32_t)spc - 1 < height - 1 ? y + (uint32_t)spc - 1 : height - 1;
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write OpenEXR rows %u..%u: %s", path, y, last,
                        core_text(&msg, rv));
        }
    }
    if (inited) exr_encoding_destroy(f, &enc);
    if (f) {
        rv = exr_finish(&f);
        if (rv != EXR_ERR_SUCCESS && r == HL_OK)
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot finish OpenEXR file: %s", path, core_text(&msg, rv));
    }
    return r;
}
