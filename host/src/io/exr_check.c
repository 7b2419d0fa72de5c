/* exr_check.c - the strict checks of an OpenEXR file before any decoder
 * allocates for it or reads its pixels: its header, with OpenEXRCore's
 * strict parse, then every part's sizes, every chunk's offset-table entry,
 * header and extent, and (for the files the C++ wrapper will read) every
 * chunk decoded once and thrown away. One concern: refusing files that
 * OpenEXR 3.1.5 would mishandle; exr_io.c reads and writes the pixels.
 *
 * Every header is parsed by OpenEXRCore first, and refused unless it is
 * sound and its sizes fit the file, before either decoder sees it: the C++
 * library trusts the header when it opens a file (a string attribute that
 * claims 2 GiB gets 2 GiB; a data window of 2^31 rows gets per-row tables
 * of that length), and OpenEXRCore checks attribute sizes against the file
 * but not what a data window or tile size asks for (hl_exr_check_parts_).
 * Then every chunk of every part is checked without decoding: its
 * offset-table entry, its header and that its data lies in the file
 * (hl_exr_check_chunks_), as the C++ reader turns a chunk that is not
 * there into garbage pixels without an error. Before the wrapper decodes a
 * file, OpenEXRCore decodes every chunk the wrapper will and throws the
 * pixels away (hl_exr_check_decodes_), so that data that decompresses
 * short is refused there too; not for DWA (OpenEXRCore cannot decode it)
 * nor B44 (the C++ reader refuses short B44 data itself). A DWA chunk
 * whose own counts are short of its blocks is still not caught (see
 * hl_exr_check_decodes_).
 *
 * Depends on: exr_check.h, exr_io.h (the limits), OpenEXRCore
 * (libOpenEXRCore-3_1, through the hl_openexr CMake target),
 * hl_internal.h (hl_fail), POSIX fseeko/ftello.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>

#include <openexr.h>

#include "exr_check.h"
#include "exr_io.h"

hl_result hl_exr_window_size_(hl_context *ctx, const char *path, const char *part, unsigned flags, int xmin,
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
hl_result hl_exr_check_parts_(hl_context *ctx, const char *path, exr_const_context_t f, const core_msg *msg,
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
        hl_result r = hl_exr_window_size_(ctx, path, part, 0, dw.min.x, dw.min.y, dw.max.x, dw.max.y, &w, &h);
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
/* The walk over every chunk, in the order of the offset tables. */
typedef struct chunk_walk {
    hl_context *ctx;
    const char *path;
    exr_const_context_t f;
    core_msg *msg;
    int multipart;        /* each chunk begins with its part number */
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

/* The chunks of scanline part p, one every `lines` rows of its data
 * window dw. */
static hl_result scanline_chunks(chunk_walk *w, int p, const exr_attr_box2i_t *dw, int32_t lines)
{
    char why[320];
    exr_chunk_info_t ci;
    hl_result r = HL_OK;
    w->leader = (w->multipart ? 4u : 0u) + 8u; /* [part], first row, packed size */
    for (int64_t y = dw->min.y; r == HL_OK && y <= (int64_t)dw->max.y; y += lines) {
        int64_t last = y + lines - 1 < (int64_t)dw->max.y ? y + lines - 1 : (int64_t)dw->max.y;
        uint64_t entry = next_entry(w);
        w->msg->text[0] = '\0';
        exr_result_t rv = exr_read_scanline_chunk_info(w->f, p, (int)y, &ci);
        chunk_fault(w, entry, rv, &ci, w->msg, why, sizeof why);
        if (why[0])
            r = hl_fail(w->ctx, HL_ERR_FORMAT, "%s: part %d, chunk of rows %lld..%lld: %s", w->path, p,
                        (long long)y, (long long)last, why);
    }
    return r;
}

/* The tiles of tiled part p (hl_exr_check_parts_ refused deep parts), in
 * the table's order: level by level (rows of levels for ripmaps), each row
 * by row. chunks is the part's chunk count, comp its compression and cl its
 * channels. */
static hl_result tiled_chunks(chunk_walk *w, int p, int32_t chunks, exr_compression_t comp,
                              const exr_attr_chlist_t *cl)
{
    const char *path = w->path;
    exr_const_context_t f = w->f;
    core_msg *msg = w->msg;
    char why[320];
    exr_chunk_info_t ci;
    hl_result r = HL_OK;
    w->leader = (w->multipart ? 4u : 0u) + 20u; /* [part], tile x, y, level x, y, packed size */
    uint32_t tw = 0, th = 0;
    exr_tile_level_mode_t mode = EXR_TILE_ONE_LEVEL;
    int32_t nlx = 0, nly = 0;
    exr_result_t rv = exr_get_tile_descriptor(f, p, &tw, &th, &mode, NULL);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_tile_levels(f, p, &nlx, &nly);
    if (rv == EXR_ERR_SUCCESS && (tw < 1 || th < 1)) rv = EXR_ERR_INVALID_ATTR;
    if (rv != EXR_ERR_SUCCESS)
        return hl_fail(w->ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: part %d: %s", path, p,
                       core_text(msg, rv));
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
            if (rv != EXR_ERR_SUCCESS || lw < 1 || lh < 1)
                return hl_fail(w->ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: part %d, level (%d, %d): %s",
                               path, p, lx, ly, core_text(msg, rv != EXR_ERR_SUCCESS ? rv : EXR_ERR_INVALID_ATTR));
            int64_t nx = ((int64_t)lw + tw - 1) / tw, ny = ((int64_t)lh + th - 1) / th;
            seen += nx * ny;
            if (seen > chunks)
                return hl_fail(w->ctx, HL_ERR_FORMAT, "%s: part %d: its tile levels hold more tiles than its %d chunks",
                               path, p, chunks);
            for (int64_t ty = 0; r == HL_OK && ty < ny; ty++)
                for (int64_t tx = 0; r == HL_OK && tx < nx; tx++) {
                    uint64_t entry = next_entry(w);
                    msg->text[0] = '\0';
                    rv = EXR_ERR_SUCCESS; /* an entry out of bounds is refused first */
                    memset(&ci, 0, sizeof ci);
                    if (mode != EXR_TILE_RIPMAP_LEVELS || ly == 0) {
                        rv = exr_read_tile_chunk_info(f, p, (int)tx, (int)ty, lx, ly, &ci);
                    } else if (entry >= w->tables_end && entry <= w->file_size && w->file_size - entry >= w->leader) {
                        const int want[4] = {(int)tx, (int)ty, lx, ly};
                        int64_t cw = (int64_t)lw - tx * tw < (int64_t)tw ? (int64_t)lw - tx * tw : (int64_t)tw;
                        int64_t chh = (int64_t)lh - ty * th < (int64_t)th ? (int64_t)lh - ty * th : (int64_t)th;
                        rv = ripmap_tile_info(w, entry, p, w->multipart, want, (uint64_t)(cw * chh) * pixel_bytes,
                                              comp, &ci, msg);
                    }
                    chunk_fault(w, entry, rv, &ci, msg, why, sizeof why);
                    if (why[0])
                        r = hl_fail(w->ctx, HL_ERR_FORMAT, "%s: part %d, tile (%lld, %lld) level (%d, %d): %s", path,
                                    p, (long long)tx, (long long)ty, lx, ly, why);
                }
        }
    if (r == HL_OK && seen != chunks)
        r = hl_fail(w->ctx, HL_ERR_FORMAT, "%s: part %d: its tile levels hold %lld tiles, not its %d chunks", path,
                    p, (long long)seen, chunks);
    return r;
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
 * chunk, and hl_exr_check_parts_ has bounded the chunk count by the file's
 * size (tile levels that hold more tiles than the part has chunks are
 * refused before they are walked). The walk is split by storage:
 * scanline_chunks and tiled_chunks. */
hl_result hl_exr_check_chunks_(hl_context *ctx, const char *path, exr_const_context_t f, core_msg *msg,
                               uint64_t file_size)
{
    chunk_walk w = {ctx, path, f, msg, 0, NULL, 0, file_size, 0};
    int parts = 0;
    hl_result r = open_tables(ctx, path, file_size, &w.fp, &w.tables_end, &w.multipart);
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
        if (rv != EXR_ERR_SUCCESS)
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: cannot read OpenEXR header: part %d: %s", path, p,
                        core_text(msg, rv));
        else if (st == EXR_STORAGE_SCANLINE)
            r = scanline_chunks(&w, p, &dw, lines);
        else
            r = tiled_chunks(&w, p, chunks, comp, cl);
    }
    fclose(w.fp);
    return r;
}

void hl_exr_chunk_sizes_(char *out, size_t n, const exr_chunk_info_t *ci)
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
 * fault hl_exr_check_chunks_ cannot see without decoding: data that
 * decompresses to fewer bytes than the chunk holds. The C++ reader takes a short ZIP or
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
hl_result hl_exr_check_decodes_(hl_context *ctx, const char *path, exr_const_context_t f, core_msg *msg)
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
                hl_exr_chunk_sizes_(sizes, sizeof sizes, &ci);
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
                    hl_exr_chunk_sizes_(sizes, sizeof sizes, &ci);
                    r = hl_fail(ctx, HL_ERR_FORMAT,
                                "%s: part 0, tile (%lld, %lld) level (0, 0): corrupt or truncated pixel data%s: %s",
                                path, (long long)tx, (long long)ty, sizes, core_text(msg, rv));
                }
            }
    }
    if (inited) exr_decoding_destroy(f, &dec);
    return r;
}
