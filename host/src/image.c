/* image.c - linear RGB images, tone mapping and image files.
 *
 * .exr goes to exr_io.c (linear); .png is written here by a small encoder:
 * 8-bit RGB, adaptive per-row filtering, a zlib stream compressed by the
 * deflate encoder in this file (LZ77 with hash chains, dynamic/fixed
 * Huffman or stored blocks), with CRC-32 and Adler-32 computed here. Every file is written to
 * "<path>.tmp.<pid>" and renamed onto path when complete; on failure the
 * temporary file is removed and path is left as it was.
 * Depends on: exr_io.c, POSIX rename/unlink/getpid.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "exr_io.h"
#include "hl_internal.h"

hl_result hl_image_create(hl_context *ctx, uint32_t width, uint32_t height, hl_image **out)
{
    if (!out) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_image_create: out is NULL");
    *out = NULL;
    if (width < 1 || height < 1 || width > HL_EXR_MAX_SIDE || height > HL_EXR_MAX_SIDE ||
        (uint64_t)width * height > HL_EXR_MAX_PIXELS)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "image size %u x %u is outside 1..%u per side and %llu pixels", width, height,
                       HL_EXR_MAX_SIDE, (unsigned long long)HL_EXR_MAX_PIXELS);
    hl_image *img = hl_calloc(ctx, 1, sizeof *img, "image");
    if (!img) return HL_ERR_OUT_OF_MEMORY;
    img->rgb = hl_calloc(ctx, 3 * (size_t)width * height, sizeof(float), "image pixels");
    if (!img->rgb) {
        free(img);
        return HL_ERR_OUT_OF_MEMORY;
    }
    img->width = width;
    img->height = height;
    *out = img;
    return HL_OK;
}

void hl_image_destroy(hl_image *img)
{
    if (!img) return;
    free(img->rgb);
    free(img);
}

uint8_t hl_tonemap_srgb8(float linear, float exposure_ev)
{
    double x = (double)linear * exp2((double)exposure_ev);
    if (!(x > 0.0)) return 0; /* also NaN */
    if (x >= 1.0) return 255;
    double y = x < 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
    double code = floor(y * 255.0 + 0.5);
    return (uint8_t)(code < 0.0 ? 0.0 : code > 255.0 ? 255.0 : code);
}

/* ---------------------------------------------------------------- PNG */

/* CRC-32 table (PNG, ISO 3309, reflected polynomial 0xEDB88320). Built
 * per file written, so that nothing global is shared between threads. */
static void crc_init(uint32_t table[256])
{
    for (uint32_t n = 0; n < 256; n++) {
        uint32_t c = n;
        for (int k = 0; k < 8; k++) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        table[n] = c;
    }
}

/* Running CRC-32: start with 0xFFFFFFFF, finish with ~. */
static uint32_t crc_update(const uint32_t table[256], uint32_t c, const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++) c = table[(c ^ p[i]) & 0xFFu] ^ (c >> 8);
    return c;
}

static void put_be32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

/* A PNG being written: IDAT bytes are collected in buf and flushed as one
 * chunk whenever it fills. */
typedef struct png_writer {
    FILE *f;
    int failed;
    uint8_t *buf;
    size_t used, cap;
    uint32_t adler_a, adler_b;
    uint32_t crc_table[256];
} png_writer;

static void write_chunk(png_writer *w, const char type[4], const uint8_t *data, uint32_t len)
{
    uint8_t head[8], tail[4];
    put_be32(head, len);
    memcpy(head + 4, type, 4);
    uint32_t c = crc_update(w->crc_table, 0xFFFFFFFFu, head + 4, 4);
    c = crc_update(w->crc_table, c, data, len);
    put_be32(tail, ~c);
    if (fwrite(head, 1, 8, w->f) != 8 || (len && fwrite(data, 1, len, w->f) != len) ||
        fwrite(tail, 1, 4, w->f) != 4)
        w->failed = 1;
}

static void idat_put(png_writer *w, const uint8_t *p, size_t n)
{
    while (n) {
        size_t take = w->cap - w->used < n ? w->cap - w->used : n;
        memcpy(w->buf + w->used, p, take);
        w->used += take;
        p += take;
        n -= take;
        if (w->used == w->cap) {
            write_chunk(w, "IDAT", w->buf, (uint32_t)w->used);
            w->used = 0;
        }
    }
}

/* Adler-32 of the uncompressed data, kept as two running sums mod 65521. */
static void adler_update(png_writer *w, const uint8_t *p, size_t n)
{
    uint32_t a = w->adler_a, b = w->adler_b;
    while (n) {
        size_t k = n < 5552 ? n : 5552; /* largest run without overflow */
        n -= k;
        while (k--) {
            a += *p++;
            b += a;
        }
        a %= 65521u;
        b %= 65521u;
    }
    w->adler_a = a;
    w->adler_b = b;
}

/* ------------------------------------------------ deflate (RFC 1951)
 *
 * A streaming compressor: input is appended to a buffer of DF_BUF bytes;
 * LZ77 with hash chains over 3-byte sequences (32 KiB window, bounded
 * chain walk, lazy matching) turns it into literal/length/distance
 * symbols, which are written as blocks of whichever is smallest: dynamic
 * Huffman codes (limited to 15 bits), the fixed codes, or stored bytes.
 * Memory is fixed (about 0.6 MB) whatever the image size. Positions in
 * the hash tables are indices into buf; when buf is full its oldest part
 * is dropped (a multiple of the window, so that prev[] stays indexed by
 * position mod window) and the tables are shifted to match. */

#define DF_WBITS 15
#define DF_WSIZE (1 << DF_WBITS)   /* window; distances are < DF_WSIZE */
#define DF_WMASK (DF_WSIZE - 1)
#define DF_BUF (8 * DF_WSIZE)      /* input buffer */
#define DF_HBITS 15
#define DF_HSIZE (1 << DF_HBITS)
#define DF_MIN_MATCH 3
#define DF_MAX_MATCH 258
#define DF_LOOKAHEAD (DF_MAX_MATCH + DF_MIN_MATCH + 1) /* kept ahead until the end */
#define DF_MAX_CHAIN 16   /* candidates looked at per position */
#define DF_GOOD 8         /* past a lazy match this long, look at a quarter as many */
#define DF_NICE 128       /* a match this long ends the search */
#define DF_LAZY 16        /* a match this long is taken without a lazy look */
#define DF_SYMS (1 << 15) /* symbols per block at most */
#define DF_OUT 16384      /* compressed bytes gathered before idat_put */
#define DF_NLL 286        /* literal/length codes used */
#define DF_NDIST 30
#define DF_NCL 19         /* code length codes */

static const uint16_t len_base[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,  15,  17,  19,  23, 27,
                                      31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258};
static const uint8_t len_extra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                      2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
static const uint16_t dist_base[30] = {1,   2,   3,   4,   5,   7,    9,    13,   17,   25,   33,   49,   65,    97,    129,
                                       193, 257, 385, 513, 769, 1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
static const uint8_t dist_extra[30] = {0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6,
                                       6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};
/* Order in which code length code lengths are sent. */
static const uint8_t cl_order[DF_NCL] = {16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15};

typedef struct deflater {
    png_writer *w;
    uint8_t *buf;            /* DF_BUF bytes of input */
    int32_t *head, *prev;    /* DF_HSIZE hash heads, DF_WSIZE chain links; -1 = none */
    uint16_t *sym_ll;        /* literal byte, or match length */
    uint16_t *sym_dist;      /* 0 for a literal, else the distance */
    uint8_t *out;            /* DF_OUT compressed bytes */
    size_t fill, pos;        /* bytes in buf; next position to look at */
    size_t block_start;      /* first byte of buf covered by the pending symbols */
    size_t emitted;          /* bytes covered by symbols so far */
    size_t nsym, nout;
    int have_prev;           /* lazy: a match/literal at pos - 1 is waiting */
    uint32_t prev_len, prev_dist;
    uint64_t bits;
    unsigned nbits;
    uint32_t freq_ll[DF_NLL], freq_dist[DF_NDIST];
    uint8_t len_code[DF_MAX_MATCH + 1]; /* length -> code - 257 */
    uint8_t dist_lo[513];               /* distance 1..512 -> code */
    uint8_t dist_hi[128];               /* (distance - 1) >> 8 for 513..32768 -> code */
} deflater;

static void df_put_bits(deflater *d, uint32_t v, unsigned n)
{
    d->bits |= (uint64_t)v << d->nbits;
    d->nbits += n;
    while (d->nbits >= 8) {
        d->out[d->nout++] = (uint8_t)d->bits;
        d->bits >>= 8;
        d->nbits -= 8;
        if (d->nout == DF_OUT) {
            idat_put(d->w, d->out, d->nout);
            d->nout = 0;
        }
    }
}

static void df_align(deflater *d)
{
    if (d->nbits & 7u) df_put_bits(d, 0, 8 - (d->nbits & 7u));
}

static uint32_t dist_code(const deflater *d, uint32_t dist)
{
    return dist <= 512 ? d->dist_lo[dist] : d->dist_hi[(dist - 1) >> 8];
}

static int df_init(deflater *d, hl_context *ctx, png_writer *w)
{
    memset(d, 0, sizeof *d);
    d->w = w;
    d->buf = hl_malloc(ctx, DF_BUF, "deflate buffer");
    d->head = d->buf ? hl_malloc(ctx, DF_HSIZE * sizeof(int32_t), "deflate hash") : NULL;
    d->prev = d->head ? hl_malloc(ctx, DF_WSIZE * sizeof(int32_t), "deflate chains") : NULL;
    d->sym_ll = d->prev ? hl_malloc(ctx, DF_SYMS * sizeof(uint16_t), "deflate symbols") : NULL;
    d->sym_dist = d->sym_ll ? hl_malloc(ctx, DF_SYMS * sizeof(uint16_t), "deflate symbols") : NULL;
    d->out = d->sym_dist ? hl_malloc(ctx, DF_OUT, "deflate output") : NULL;
    if (!d->out) return 0;
    for (size_t i = 0; i < DF_HSIZE; i++) d->head[i] = -1;
    for (size_t i = 0; i < DF_WSIZE; i++) d->prev[i] = -1;
    for (unsigned c = 0; c < 29; c++) {
        unsigned top = c == 28 ? 258u : len_base[c] + (1u << len_extra[c]) - 1u;
        for (unsigned l = len_base[c]; l <= top; l++) d->len_code[l] = (uint8_t)c;
    }
    for (unsigned c = 0; c < 30; c++) {
        unsigned top = dist_base[c] + (1u << dist_extra[c]) - 1u;
        for (unsigned x = dist_base[c]; x <= top; x++) {
            if (x <= 512)
                d->dist_lo[x] = (uint8_t)c;
            else
                d->dist_hi[(x - 1) >> 8] = (uint8_t)c;
        }
    }
    return 1;
}

static void df_free(deflater *d)
{
    free(d->buf);
    free(d->head);
    free(d->prev);
    free(d->sym_ll);
    free(d->sym_dist);
    free(d->out);
}

/* ---- Huffman code construction */

typedef struct hnode {
    uint32_t weight;
    int32_t parent;
} hnode;

/* Code lengths (at most limit bits) for n symbols with the given
 * frequencies; unused symbols get 0. The code is always complete: with
 * fewer than two symbols used, symbols 0 and 1 are filled in. Huffman's
 * construction (two queues over the symbols sorted by frequency) gives
 * the depths; if any exceeds limit, the length counts are clamped and
 * then repaired until the Kraft sum is exactly 1 again (each step moves
 * one leaf up from the deepest level and splits a shallower one). The
 * lengths are then handed out shortest first to the most frequent. */
static void huff_lengths(const uint32_t *freq, unsigned n, unsigned limit, uint8_t *len)
{
    uint16_t sym[DF_NLL];
    hnode node[2 * DF_NLL];
    unsigned m = 0;
    for (unsigned s = 0; s < n; s++) {
        len[s] = 0;
        if (freq[s]) sym[m++] = (uint16_t)s;
    }
    for (unsigned s = 0; m < 2; s++) {
        if (!freq[s]) sym[m++] = (uint16_t)s; /* complete the code: two symbols of length 1 */
    }
    /* Insertion sort by (frequency, symbol); n <= 286. A forced symbol
     * counts as frequency 1. */
#define HF(s) (freq[s] ? freq[s] : 1u)
    for (unsigned i = 1; i < m; i++) {
        uint16_t s = sym[i];
        unsigned j = i;
        while (j > 0 && HF(sym[j - 1]) > HF(s)) {
            sym[j] = sym[j - 1];
            j--;
        }
        sym[j] = s;
    }
    for (unsigned i = 0; i < m; i++) node[i] = (hnode){HF(sym[i]), -1};
#undef HF
    /* Leaves are node[0..m), internal nodes node[m..2m-1) in the order
     * made, which is also nondecreasing weight. */
    unsigned leaf = 0, inner = m, next = m;
    while (next < 2 * m - 1) {
        unsigned pick[2];
        for (int k = 0; k < 2; k++) {
            if (leaf < m && (inner >= next || node[leaf].weight <= node[inner].weight))
                pick[k] = leaf++;
            else
                pick[k] = inner++;
        }
        node[next].weight = node[pick[0]].weight + node[pick[1]].weight;
        node[next].parent = -1;
        node[pick[0]].parent = node[pick[1]].parent = (int32_t)next;
        next++;
    }
    /* Depths, root first (parents come after their children). */
    uint32_t depth[2 * DF_NLL];
    depth[2 * m - 2] = 0;
    for (unsigned i = 2 * m - 2; i-- > 0;) depth[i] = depth[node[i].parent] + 1;
    unsigned count[32] = {0};
    for (unsigned i = 0; i < m; i++) count[depth[i] > limit ? limit : depth[i]]++;
    uint64_t kraft = 0; /* in units of 2^-limit */
    for (unsigned l = 1; l <= limit; l++) kraft += (uint64_t)count[l] << (limit - l);
    while (kraft > ((uint64_t)1 << limit)) {
        count[limit]--;
        for (unsigned l = limit - 1; l > 0; l--) {
            if (count[l]) {
                count[l]--;
                count[l + 1] += 2;
                break;
            }
        }
        kraft--;
    }
    /* sym[] is sorted by increasing frequency: longest codes first. */
    unsigned i = 0;
    for (unsigned l = limit; l > 0; l--)
        for (unsigned k = 0; k < count[l]; k++) len[sym[i++]] = (uint8_t)l;
}

/* Canonical codes (RFC 1951 3.2.2), stored bit-reversed for LSB-first
 * output. */
static void huff_codes(const uint8_t *len, unsigned n, uint16_t *code)
{
    unsigned count[16] = {0}, next[16];
    for (unsigned s = 0; s < n; s++) count[len[s]]++;
    count[0] = 0;
    unsigned c = 0;
    for (unsigned l = 1; l < 16; l++) {
        c = (c + count[l - 1]) << 1;
        next[l] = c;
    }
    for (unsigned s = 0; s < n; s++) {
        unsigned l = len[s];
        if (!l) {
            code[s] = 0;
            continue;
        }
        unsigned v = next[l]++, r = 0;
        for (unsigned k = 0; k < l; k++) r |= ((v >> k) & 1u) << (l - 1 - k);
        code[s] = (uint16_t)r;
    }
}

/* Run-length coding of the code lengths (symbols 0..18; 16 repeats the
 * previous length 3..6 times, 17 and 18 give 3..10 and 11..138 zeros).
 * rle[] gets symbol | extra value << 8. Returns the count. */
static unsigned rle_lengths(const uint8_t *lens, unsigned n, uint16_t *rle, uint32_t *freq)
{
    unsigned k = 0;
    for (unsigned i = 0; i < n;) {
        unsigned v = lens[i], run = 1;
        while (i + run < n && lens[i + run] == v) run++;
        i += run;
        if (v == 0) {
            while (run >= 11) {
                unsigned r = run > 138 ? 138 : run;
                rle[k++] = (uint16_t)(18u | (r - 11u) << 8);
                freq[18]++;
                run -= r;
            }
            if (run >= 3) {
                rle[k++] = (uint16_t)(17u | (run - 3u) << 8);
                freq[17]++;
                run = 0;
            }
        } else {
            rle[k++] = (uint16_t)v;
            freq[v]++;
            run--;
            while (run >= 3) {
                unsigned r = run > 6 ? 6 : run;
                rle[k++] = (uint16_t)(16u | (r - 3u) << 8);
                freq[16]++;
                run -= r;
            }
        }
        while (run--) {
            rle[k++] = (uint16_t)v;
            freq[v]++;
        }
    }
    return k;
}

/* Bits for the pending symbols and end of block under the given codes. */
static uint64_t block_bits(const deflater *d, const uint8_t *ll_len, const uint8_t *dist_len)
{
    uint64_t b = 0;
    for (unsigned s = 0; s < DF_NLL; s++) {
        b += (uint64_t)d->freq_ll[s] * ll_len[s];
        if (s > 256) b += (uint64_t)d->freq_ll[s] * len_extra[s - 257];
    }
    for (unsigned s = 0; s < DF_NDIST; s++) b += (uint64_t)d->freq_dist[s] * (dist_len[s] + dist_extra[s]);
    return b;
}

static void write_symbols(deflater *d, const uint8_t *ll_len, const uint16_t *ll_code, const uint8_t *dist_len,
                          const uint16_t *dist_code_)
{
    for (size_t i = 0; i < d->nsym; i++) {
        uint32_t x = d->sym_ll[i], dist = d->sym_dist[i];
        if (!dist) {
            df_put_bits(d, ll_code[x], ll_len[x]);
            continue;
        }
        unsigned lc = d->len_code[x], dc = dist_code(d, dist);
        df_put_bits(d, ll_code[257 + lc], ll_len[257 + lc]);
        if (len_extra[lc]) df_put_bits(d, x - len_base[lc], len_extra[lc]);
        df_put_bits(d, dist_code_[dc], dist_len[dc]);
        if (dist_extra[dc]) df_put_bits(d, dist - dist_base[dc], dist_extra[dc]);
    }
    df_put_bits(d, ll_code[256], ll_len[256]);
}

/* Writes the pending symbols (covering buf[block_start, emitted)) as one
 * block, in the smallest of the three forms. */
static void df_flush_block(deflater *d, int final)
{
    d->freq_ll[256] = 1; /* end of block */
    uint8_t ll_len[DF_NLL], dist_len[DF_NDIST], cl_len[DF_NCL];
    uint16_t ll_code[DF_NLL], dist_codes[DF_NDIST], cl_code[DF_NCL];

    /* Dynamic codes and their header. */
    huff_lengths(d->freq_ll, DF_NLL, 15, ll_len);
    huff_lengths(d->freq_dist, DF_NDIST, 15, dist_len);
    unsigned hlit = DF_NLL, hdist = DF_NDIST;
    while (hlit > 257 && !ll_len[hlit - 1]) hlit--;
    while (hdist > 1 && !dist_len[hdist - 1]) hdist--;
    uint8_t lens[DF_NLL + DF_NDIST];
    memcpy(lens, ll_len, hlit);
    memcpy(lens + hlit, dist_len, hdist);
    uint16_t rle[DF_NLL + DF_NDIST];
    uint32_t cl_freq[DF_NCL] = {0};
    unsigned nrle = rle_lengths(lens, hlit + hdist, rle, cl_freq);
    huff_lengths(cl_freq, DF_NCL, 7, cl_len);
    unsigned hclen = DF_NCL;
    while (hclen > 4 && !cl_len[cl_order[hclen - 1]]) hclen--;
    uint64_t dyn = 3 + 5 + 5 + 4 + 3 * (uint64_t)hclen;
    for (unsigned s = 0; s < DF_NCL; s++) dyn += (uint64_t)cl_freq[s] * cl_len[s];
    dyn += 2 * (uint64_t)cl_freq[16] + 3 * (uint64_t)cl_freq[17] + 7 * (uint64_t)cl_freq[18];
    dyn += block_bits(d, ll_len, dist_len);

    /* Fixed codes: all 288 + 32 symbols take part in the canonical
     * assignment, although 286, 287, 30 and 31 never occur. */
    uint8_t fll_len[288], fdist_len[32];
    for (unsigned s = 0; s < 288; s++) fll_len[s] = s < 144 ? 8 : s < 256 ? 9 : s < 280 ? 7 : 8;
    for (unsigned s = 0; s < 32; s++) fdist_len[s] = 5;
    uint64_t fixed = 3 + block_bits(d, fll_len, fdist_len);

    /* Stored: header, padding to a byte, LEN/NLEN per 65535 bytes. */
    size_t raw = d->emitted - d->block_start;
    uint64_t pieces = raw ? (raw + 65534) / 65535 : 1;
    uint64_t stored = pieces * (3 + 7 + 32) + 8 * (uint64_t)raw;

    if (stored < dyn && stored < fixed) {
        const uint8_t *p = d->buf + d->block_start;
        do {
            size_t take = raw < 65535 ? raw : 65535;
            raw -= take;
            df_put_bits(d, (final && !raw) ? 1u : 0u, 3); /* BFINAL, BTYPE 00 */
            df_align(d);
            df_put_bits(d, (uint32_t)take | (uint32_t)(~take & 0xFFFFu) << 16, 32);
            for (size_t i = 0; i < take; i++) df_put_bits(d, p[i], 8);
            p += take;
        } while (raw);
    } else if (fixed <= dyn) {
        df_put_bits(d, (final ? 1u : 0u) | 1u << 1, 3);
        uint16_t fll_code[288], fdist_code[32];
        huff_codes(fll_len, 288, fll_code);
        huff_codes(fdist_len, 32, fdist_code);
        write_symbols(d, fll_len, fll_code, fdist_len, fdist_code);
    } else {
        df_put_bits(d, (final ? 1u : 0u) | 2u << 1, 3);
        df_put_bits(d, hlit - 257, 5);
        df_put_bits(d, hdist - 1, 5);
        df_put_bits(d, hclen - 4, 4);
        for (unsigned i = 0; i < hclen; i++) df_put_bits(d, cl_len[cl_order[i]], 3);
        huff_codes(cl_len, DF_NCL, cl_code);
        for (unsigned i = 0; i < nrle; i++) {
            unsigned s = rle[i] & 0xFFu, extra = rle[i] >> 8;
            df_put_bits(d, cl_code[s], cl_len[s]);
            if (s >= 16) df_put_bits(d, extra, s == 16 ? 2 : s == 17 ? 3 : 7);
        }
        huff_codes(ll_len, DF_NLL, ll_code);
        huff_codes(dist_len, DF_NDIST, dist_codes);
        write_symbols(d, ll_len, ll_code, dist_len, dist_codes);
    }
    d->nsym = 0;
    d->block_start = d->emitted;
    memset(d->freq_ll, 0, sizeof d->freq_ll);
    memset(d->freq_dist, 0, sizeof d->freq_dist);
}

static void df_literal(deflater *d, uint8_t c)
{
    d->sym_ll[d->nsym] = c;
    d->sym_dist[d->nsym++] = 0;
    d->freq_ll[c]++;
    d->emitted++;
}

static void df_match(deflater *d, uint32_t len, uint32_t dist)
{
    d->sym_ll[d->nsym] = (uint16_t)len;
    d->sym_dist[d->nsym++] = (uint16_t)dist;
    d->freq_ll[257 + d->len_code[len]]++;
    d->freq_dist[dist_code(d, dist)]++;
    d->emitted += len;
}

/* Enters position p (3 bytes must be in buf) into the hash chains. */
static void df_insert(deflater *d, size_t p)
{
    const uint8_t *s = d->buf + p;
    uint32_t h = ((uint32_t)s[0] << 16 | (uint32_t)s[1] << 8 | s[2]) * 2654435761u >> (32 - DF_HBITS);
    d->prev[p & DF_WMASK] = d->head[h];
    d->head[h] = (int32_t)p;
}

/* Longest match for position p (already inserted) against earlier data
 * at distance 1..DF_WSIZE-1, longer than at_least; 0 when none. */
static uint32_t df_longest(const deflater *d, size_t p, uint32_t at_least, uint32_t *dist)
{
    size_t avail = d->fill - p;
    uint32_t max = avail < DF_MAX_MATCH ? (uint32_t)avail : DF_MAX_MATCH;
    if (max < DF_MIN_MATCH || at_least >= max) return 0;
    const uint8_t *s = d->buf + p;
    uint32_t best = at_least < DF_MIN_MATCH - 1 ? DF_MIN_MATCH - 1 : at_least, found = 0;
    int32_t cand = d->prev[p & DF_WMASK];
    int chain = at_least >= DF_GOOD ? DF_MAX_CHAIN / 4 : DF_MAX_CHAIN;
    for (; chain > 0 && cand >= 0; chain--) {
        size_t c = (size_t)cand;
        if (c >= p || p - c >= DF_WSIZE) break;
        const uint8_t *t = d->buf + c;
        if (t[best] == s[best] && t[0] == s[0] && t[1] == s[1]) {
            uint32_t l = 2;
            while (l < max && t[l] == s[l]) l++;
            if (l > best) {
                best = l;
                found = l;
                *dist = (uint32_t)(p - c);
                if (l >= DF_NICE || l >= max) break;
            }
        }
        cand = d->prev[c & DF_WMASK];
    }
    return found;
}

/* Turns buffered input into symbols, up to DF_LOOKAHEAD bytes before
 * the end of the buffer, or all of it when final (lazy matching: a match
 * found at p is held back while p + 1 is tried for a longer one). */
static void df_process(deflater *d, int final)
{
    size_t limit = final ? d->fill : (d->fill > DF_LOOKAHEAD ? d->fill - DF_LOOKAHEAD : 0);
    while (d->pos < limit) {
        if (d->nsym + 2 > DF_SYMS) df_flush_block(d, 0);
        size_t p = d->pos;
        if (p + DF_MIN_MATCH <= d->fill) df_insert(d, p);
        uint32_t len = 0, dist = 0;
        if (!d->have_prev || d->prev_len < DF_LAZY)
            len = df_longest(d, p, d->have_prev ? d->prev_len : 0, &dist);
        if (d->have_prev && d->prev_len >= DF_MIN_MATCH && len <= d->prev_len) {
            /* The match at p - 1 stands; it covers p .. p - 1 + prev_len. */
            df_match(d, d->prev_len, d->prev_dist);
            size_t end = p - 1 + d->prev_len;
            for (size_t q = p + 1; q < end && q + DF_MIN_MATCH <= d->fill; q++) df_insert(d, q);
            d->pos = end;
            d->have_prev = 0;
            continue;
        }
        if (d->have_prev) df_literal(d, d->buf[p - 1]);
        d->have_prev = 1;
        d->prev_len = len;
        d->prev_dist = dist;
        d->pos = p + 1;
    }
    if (final && d->have_prev) {
        if (d->nsym + 1 > DF_SYMS) df_flush_block(d, 0);
        if (d->prev_len >= DF_MIN_MATCH) {
            df_match(d, d->prev_len, d->prev_dist);
            d->pos = d->pos - 1 + d->prev_len;
        } else {
            df_literal(d, d->buf[d->pos - 1]);
        }
        d->have_prev = 0;
    }
}

/* Makes room in a full buffer: the pending symbols are written out (the
 * stored form needs their bytes), then all but the last window or more
 * before pos is dropped, in multiples of the window. */
static void df_slide(deflater *d)
{
    df_flush_block(d, 0);
    size_t keep_from = d->pos - 1 < d->block_start ? d->pos - 1 : d->block_start;
    if (keep_from < DF_WSIZE) return;
    size_t shift = (keep_from - DF_WSIZE) / DF_WSIZE * DF_WSIZE;
    if (!shift) return;
    memmove(d->buf, d->buf + shift, d->fill - shift);
    d->fill -= shift;
    d->pos -= shift;
    d->block_start -= shift;
    d->emitted -= shift;
    for (size_t i = 0; i < DF_HSIZE; i++) d->head[i] = d->head[i] >= (int32_t)shift ? d->head[i] - (int32_t)shift : -1;
    for (size_t i = 0; i < DF_WSIZE; i++) d->prev[i] = d->prev[i] >= (int32_t)shift ? d->prev[i] - (int32_t)shift : -1;
}

static void df_feed(deflater *d, const uint8_t *p, size_t n)
{
    while (n) {
        if (d->fill == DF_BUF) {
            df_process(d, 0);
            df_slide(d);
        }
        size_t take = DF_BUF - d->fill < n ? DF_BUF - d->fill : n;
        memcpy(d->buf + d->fill, p, take);
        d->fill += take;
        p += take;
        n -= take;
    }
}

static void df_finish(deflater *d)
{
    df_process(d, 1);
    df_flush_block(d, 1);
    df_align(d);
    if (d->nout) idat_put(d->w, d->out, d->nout);
    d->nout = 0;
}

/* ---------------------------------------------------- PNG row filters */

/* Filters row cur (n bytes, 3 per pixel) against the row above, up (zeros
 * for the first row), with filter type t into out[0] (type) and out[1..n].
 * Returns the sum of the filtered bytes taken as signed values, the usual
 * estimate of how well a row will compress. */
static uint64_t filter_row(unsigned t, const uint8_t *cur, const uint8_t *up, size_t n, uint8_t *out)
{
    out[0] = (uint8_t)t;
    uint8_t *o = out + 1;
    size_t first = n < 3 ? n : 3; /* the first pixel has no left neighbour */
    switch (t) {
    case 0: memcpy(o, cur, n); break;
    case 1:
        memcpy(o, cur, first);
        for (size_t i = 3; i < n; i++) o[i] = (uint8_t)(cur[i] - cur[i - 3]);
        break;
    case 2:
        for (size_t i = 0; i < n; i++) o[i] = (uint8_t)(cur[i] - up[i]);
        break;
    case 3:
        for (size_t i = 0; i < first; i++) o[i] = (uint8_t)(cur[i] - (up[i] >> 1));
        for (size_t i = 3; i < n; i++) o[i] = (uint8_t)(cur[i] - ((cur[i - 3] + up[i]) >> 1));
        break;
    default: /* Paeth; with a = c = 0 it predicts b */
        for (size_t i = 0; i < first; i++) o[i] = (uint8_t)(cur[i] - up[i]);
        for (size_t i = 3; i < n; i++) {
            int a = cur[i - 3], b = up[i], c = up[i - 3];
            int pa = abs(b - c), pb = abs(a - c), pc = abs(a + b - 2 * c);
            int pred = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
            o[i] = (uint8_t)(cur[i] - pred);
        }
        break;
    }
    uint64_t sum = 0;
    for (size_t i = 0; i < n; i++) {
        int v = (int8_t)o[i];
        sum += (uint64_t)(v < 0 ? -v : v);
    }
    return sum;
}

/* Writes img as PNG to the open file f: 8-bit RGB, each row filtered with
 * the type whose output has the smallest sum of absolute values, the
 * whole filtered image one zlib stream cut into IDAT chunks of 1 MiB. */
static hl_result png_write(hl_context *ctx, const hl_image *img, FILE *f, float exposure_ev,
                           const char *path)
{
    png_writer w = {.f = f, .cap = (size_t)1 << 20, .adler_a = 1, .adler_b = 0};
    crc_init(w.crc_table);
    size_t n = 3 * (size_t)img->width;
    uint8_t *rows = hl_malloc(ctx, 2 * n + 2 * (n + 1), "PNG rows");
    deflater *d = hl_calloc(ctx, 1, sizeof *d, "deflate state");
    w.buf = hl_malloc(ctx, w.cap, "PNG chunk buffer");
    int ok = rows && d && w.buf && df_init(d, ctx, &w);
    if (!ok) {
        if (d) df_free(d);
        free(d);
        free(rows);
        free(w.buf);
        return HL_ERR_OUT_OF_MEMORY;
    }
    uint8_t *cur = rows, *up = rows + n, *best = rows + 2 * n, *trial = best + n + 1;
    memset(up, 0, n);

    static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    if (fwrite(sig, 1, 8, f) != 8) w.failed = 1;
    uint8_t ihdr[13];
    put_be32(ihdr, img->width);
    put_be32(ihdr + 4, img->height);
    ihdr[8] = 8;  /* bit depth */
    ihdr[9] = 2;  /* colour type: RGB */
    ihdr[10] = 0; /* deflate */
    ihdr[11] = 0; /* adaptive filtering, a type byte per row */
    ihdr[12] = 0; /* no interlace */
    write_chunk(&w, "IHDR", ihdr, sizeof ihdr);

    /* zlib header: CM = 8, CINFO = 7 (32K window), FLEVEL = 2 (default),
     * FCHECK so that the 16-bit value is a multiple of 31, no dictionary. */
    static const uint8_t zhead[2] = {0x78, 0x9C};
    idat_put(&w, zhead, 2);
    for (uint32_t y = 0; y < img->height && !w.failed; y++) {
        const float *src = img->rgb + 3 * (size_t)y * img->width;
        for (size_t i = 0; i < n; i++) cur[i] = hl_tonemap_srgb8(src[i], exposure_ev);
        uint64_t best_cost = UINT64_MAX;
        for (unsigned t = 0; t < 5; t++) {
            uint64_t cost = filter_row(t, cur, up, n, trial);
            if (cost < best_cost) {
                best_cost = cost;
                uint8_t *x = best;
                best = trial;
                trial = x;
            }
        }
        adler_update(&w, best, n + 1);
        df_feed(d, best, n + 1);
        uint8_t *x = up;
        up = cur;
        cur = x;
    }
    df_finish(d);
    uint8_t adler[4];
    put_be32(adler, (w.adler_b << 16) | w.adler_a);
    idat_put(&w, adler, 4);
    if (w.used) write_chunk(&w, "IDAT", w.buf, (uint32_t)w.used);
    write_chunk(&w, "IEND", NULL, 0);
    df_free(d);
    free(d);
    free(rows);
    free(w.buf);
    if (w.failed) {
        int e = errno;
        return hl_fail(ctx, HL_ERR_IO, "%s: cannot write PNG data: %s", path, strerror(e));
    }
    return HL_OK;
}

/* ---------------------------------------------------------------- saving */

static int has_ext(const char *path, const char *ext)
{
    size_t n = strlen(path), k = strlen(ext);
    return n > k && strcasecmp(path + n - k, ext) == 0;
}

hl_result hl_image_save(hl_context *ctx, const hl_image *img, const char *path, float exposure_ev)
{
    if (!img || !img->rgb || img->width < 1 || img->height < 1)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_image_save: no image to write");
    if (!path || !*path) return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "hl_image_save: no path given");
    int exr = has_ext(path, ".exr"), png = has_ext(path, ".png");
    if (!exr && !png)
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: unknown image type (the name must end in .exr or .png)", path);
    if (png && !isfinite(exposure_ev))
        return hl_fail(ctx, HL_ERR_INVALID_ARGUMENT, "%s: exposure %g is not finite", path,
                       (double)exposure_ev);

    size_t n = strlen(path);
    char *tmp = hl_malloc(ctx, n + 32, "temporary file name");
    if (!tmp) return HL_ERR_OUT_OF_MEMORY;
    snprintf(tmp, n + 32, "%s.tmp.%ld", path, (long)getpid());

    /* Create the temporary file here for both formats, so that an
     * unwritable place is reported with the system's reason. */
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        int e = errno;
        hl_result r = hl_fail(ctx, HL_ERR_IO, "%s: cannot create %s: %s", path, tmp, strerror(e));
        free(tmp);
        return r;
    }
    hl_result r = HL_OK;
    if (png) {
        r = png_write(ctx, img, f, exposure_ev, path);
        int e = fflush(f) != 0 ? errno : hl_sync_fd(fileno(f));
        if (e && r == HL_OK) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write %s: %s", path, tmp, strerror(e));
        if (fclose(f) != 0 && r == HL_OK) {
            int e = errno;
            r = hl_fail(ctx, HL_ERR_IO, "%s: cannot close %s: %s", path, tmp, strerror(e));
        }
    } else {
        fclose(f);
        r = hl_exr_write_rgb_(ctx, tmp, img->width, img->height, img->rgb);
        /* on disk before the rename, as the PNG and the PLY are */
        int fd = r == HL_OK ? open(tmp, O_RDONLY) : -1;
        int e = r != HL_OK ? 0 : fd < 0 ? errno : hl_sync_fd(fd);
        if (e) r = hl_fail(ctx, HL_ERR_IO, "%s: cannot write %s: %s", path, tmp, strerror(e));
        if (fd >= 0) close(fd);
    }
    if (r == HL_OK && rename(tmp, path) != 0) {
        int e = errno;
        r = hl_fail(ctx, HL_ERR_IO, "%s: cannot rename %s onto it: %s", path, tmp, strerror(e));
    }
    if (r != HL_OK) unlink(tmp);
    free(tmp);
    return r;
}
