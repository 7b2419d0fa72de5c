/* test_image.c - images written and tone mapped (suite "image").
 *
 * image.io       EXR round trip, bit for bit; PNG inflated and unfiltered
 *                here (a small inflater of its own) and compared with
 *                hl_tonemap_srgb8; PNG compression ratios; refused
 *                extensions, unwritable places, no temporary files left.
 * image.tonemap  known sRGB codes and exposure.
 * Depends on: haarlight_core (reference backend only),
 * tests/common/env_util.h.
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>

#include "haarlight.h"
#include "hl_test.h"
#include "env_util.h"

/* ---------------------------------------------------------------- image_io */

static uint32_t be32(const uint8_t *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }


/* ---- A small inflater (RFC 1950/1951) for the PNG checks: stored, fixed
 * and dynamic blocks, every read bounds-checked; a failure sets err. */
typedef struct inflater {
    const uint8_t *in;
    size_t n, pos; /* pos in bits */
    uint8_t *out;
    size_t cap, got;
    int err;
    const char *why;
} inflater;

typedef struct huff {
    uint16_t count[16];  /* codes of each length */
    uint16_t symbol[320]; /* symbols in canonical order */
} huff;

static uint32_t inf_bits(inflater *s, unsigned k)
{
    uint32_t v = 0;
    for (unsigned i = 0; i < k; i++) {
        if (s->pos >= 8 * s->n) {
            s->err = 1;
            s->why = "input ends inside a block";
            return 0;
        }
        v |= (uint32_t)(s->in[s->pos >> 3] >> (s->pos & 7) & 1u) << i;
        s->pos++;
    }
    return v;
}

/* Builds the decoding table; 0 for an over-subscribed set, or an
 * incomplete one other than a single code of length 1. */
static int huff_build(huff *h, const uint8_t *len, unsigned n)
{
    memset(h->count, 0, sizeof h->count);
    for (unsigned s = 0; s < n; s++) h->count[len[s]]++;
    uint16_t offs[16];
    int left = 1, used = (int)(n - h->count[0]);
    for (unsigned l = 1; l < 16; l++) {
        left = 2 * left - h->count[l];
        if (left < 0) return 0;
    }
    if (left > 0 && used != 1) return 0;
    offs[1] = 0;
    for (unsigned l = 1; l < 15; l++) offs[l + 1] = (uint16_t)(offs[l] + h->count[l]);
    for (unsigned s = 0; s < n; s++)
        if (len[s]) h->symbol[offs[len[s]]++] = (uint16_t)s;
    return 1;
}

/* One symbol, reading a bit at a time (codes are MSB first). */
static int huff_decode(inflater *s, const huff *h)
{
    int code = 0, first = 0, index = 0;
    for (unsigned l = 1; l < 16; l++) {
        code |= (int)inf_bits(s, 1);
        int c = h->count[l];
        if (code - first < c) return h->symbol[index + code - first];
        index += c;
        first = (first + c) << 1;
        code <<= 1;
    }
    s->err = 1;
    s->why = "invalid Huffman code";
    return -1;
}

static void inf_codes(inflater *s, const huff *lit, const huff *dist, int *counts)
{
    static const uint16_t lbase[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,  15,  17,  19,  23, 27,
                                       31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258};
    static const uint8_t lext[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
    static const uint16_t dbase[30] = {1,   2,   3,   4,   5,   7,    9,    13,   17,   25,   33,   49,   65,    97,    129,
                                       193, 257, 385, 513, 769, 1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
    static const uint8_t dext[30] = {0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};
    for (;;) {
        int sym = huff_decode(s, lit);
        if (s->err) return;
        if (sym < 256) {
            if (s->got >= s->cap) break;
            s->out[s->got++] = (uint8_t)sym;
            counts[0]++;
            continue;
        }
        if (sym == 256) return;
        sym -= 257;
        if (sym >= 29) break;
        size_t len = lbase[sym] + inf_bits(s, lext[sym]);
        int ds = huff_decode(s, dist);
        if (s->err) return;
        if (ds >= 30) break;
        size_t d = dbase[ds] + inf_bits(s, dext[ds]);
        if (d > s->got || s->got + len > s->cap) break;
        for (size_t i = 0; i < len; i++, s->got++) s->out[s->got] = s->out[s->got - d];
        counts[1]++;
    }
    s->err = 1;
    s->why = "bad length/distance, or output beyond the image";
}

/* Inflates the raw deflate data in[0..n) into out (cap bytes). Returns the
 * byte offset just after the last block, or 0 with why set. blocks[t]
 * counts blocks of type t; syms[0], syms[1] literals and matches. */
static size_t inflate_raw(const uint8_t *in, size_t n, uint8_t *out, size_t cap, size_t *got, int blocks[3],
                          int syms[2], const char **why)
{
    inflater s = {.in = in, .n = n, .out = out, .cap = cap};
    int final = 0;
    while (!final && !s.err) {
        final = (int)inf_bits(&s, 1);
        unsigned type = inf_bits(&s, 2);
        if (s.err) break;
        if (type == 0) {
            s.pos = (s.pos + 7) & ~(size_t)7;
            size_t p = s.pos >> 3;
            if (p + 4 > n) {
                s.err = 1;
                s.why = "stored block header cut off";
                break;
            }
            uint32_t len = in[p] | (uint32_t)in[p + 1] << 8, nlen = in[p + 2] | (uint32_t)in[p + 3] << 8;
            if ((len ^ 0xFFFFu) != nlen || p + 4 + len > n || s.got + len > cap) {
                s.err = 1;
                s.why = "bad stored block";
                break;
            }
            memcpy(out + s.got, in + p + 4, len);
            s.got += len;
            s.pos = 8 * (p + 4 + len);
        } else if (type == 1 || type == 2) {
            uint8_t len[320];
            huff lit, dist;
            unsigned nlit = 288, ndist = 30;
            if (type == 1) {
                for (unsigned i = 0; i < 288; i++) len[i] = i < 144 ? 8 : i < 256 ? 9 : i < 280 ? 7 : 8;
                for (unsigned i = 0; i < 32; i++) len[288 + i] = 5; /* 30 and 31 unused but coded */
                ndist = 32;
            } else {
                static const uint8_t order[19] = {16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15};
                nlit = inf_bits(&s, 5) + 257;
                ndist = inf_bits(&s, 5) + 1;
                unsigned ncode = inf_bits(&s, 4) + 4;
                uint8_t cl[19] = {0};
                for (unsigned i = 0; i < ncode; i++) cl[order[i]] = (uint8_t)inf_bits(&s, 3);
                huff clh;
                if (s.err || nlit > 286 || ndist > 30 || !huff_build(&clh, cl, 19)) {
                    s.err = 1;
                    s.why = s.why ? s.why : "bad dynamic header";
                    break;
                }
                unsigned i = 0;
                while (i < nlit + ndist && !s.err) {
                    int sym = huff_decode(&s, &clh);
                    if (sym < 16) {
                        if (sym >= 0) len[i++] = (uint8_t)sym;
                        continue;
                    }
                    unsigned rep = sym == 16 ? 3 + inf_bits(&s, 2) : sym == 17 ? 3 + inf_bits(&s, 3) : 11 + inf_bits(&s, 7);
                    if ((sym == 16 && i == 0) || i + rep > nlit + ndist) {
                        s.err = 1;
                        s.why = "bad code length repeat";
                        break;
                    }
                    uint8_t v = sym == 16 ? len[i - 1] : 0;
                    while (rep--) len[i++] = v;
                }
                if (s.err) break;
                memmove(len + 288, len + nlit, ndist);
                for (unsigned k = nlit; k < 288; k++) len[k] = 0;
                if (!len[256]) {
                    s.err = 1;
                    s.why = "no end-of-block code";
                    break;
                }
            }
            if (!huff_build(&lit, len, nlit) || !huff_build(&dist, len + 288, ndist)) {
                s.err = 1;
                s.why = "bad Huffman code lengths";
                break;
            }
            inf_codes(&s, &lit, &dist, syms);
        } else {
            s.err = 1;
            s.why = "block type 3";
        }
        if (!s.err) blocks[type]++;
    }
    *got = s.got;
    *why = s.why;
    return s.err ? 0 : (s.pos + 7) >> 3;
}

static int paeth_ref(int a, int b, int c)
{
    int p = a + b - c, pa = abs(p - a), pb = abs(p - b), pc = abs(p - c);
    return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

/* Decodes a PNG of 8-bit RGB, no interlace (what our writer makes) into
 * *rgb, undoing all five row filters. Returns 0 and reports on anything
 * else. */
static int png_decode(const uint8_t *f, size_t n, uint32_t *w, uint32_t *h, uint8_t **rgb)
{
    static const uint8_t sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    *rgb = NULL;
    if (n < 8 || memcmp(f, sig, 8) != 0) {
        HL_CHECK(0, "PNG signature");
        return 0;
    }
    uint8_t *z = malloc(n);
    size_t zn = 0, pos = 8;
    int seen_end = 0, seen_hdr = 0;
    while (pos + 12 <= n && !seen_end) {
        uint32_t len = be32(f + pos);
        if (pos + 12 + (size_t)len > n) break;
        const uint8_t *type = f + pos + 4, *data = f + pos + 8;
        HL_CHECK(hl_test_crc32(type, 4 + (size_t)len) == be32(data + len), "chunk %.4s: bad CRC", (const char *)type);
        if (memcmp(type, "IHDR", 4) == 0) {
            HL_CHECK(len == 13 && data[8] == 8 && data[9] == 2 && data[10] == 0 && data[11] == 0 && data[12] == 0,
                     "IHDR is not 8-bit RGB, deflate, filter method 0, no interlace");
            *w = be32(data);
            *h = be32(data + 4);
            seen_hdr = 1;
        } else if (memcmp(type, "IDAT", 4) == 0) {
            memcpy(z + zn, data, len);
            zn += len;
        } else if (memcmp(type, "IEND", 4) == 0) {
            seen_end = 1;
        }
        pos += 12 + (size_t)len;
    }
    HL_CHECK(seen_hdr && seen_end && pos == n, "PNG chunk structure (header %d, end %d, %zu of %zu bytes)", seen_hdr,
             seen_end, pos, n);
    if (!seen_hdr || zn < 6) {
        HL_CHECK(0, "no header or zlib stream too short (%zu bytes)", zn);
        free(z);
        return 0;
    }
    HL_CHECK((z[0] & 15) == 8 && (z[0] >> 4) <= 7 && ((unsigned)z[0] * 256u + z[1]) % 31u == 0 && !(z[1] & 32),
             "zlib header %02x %02x", z[0], z[1]);
    size_t stride = 1 + 3 * (size_t)*w, raw_n = (size_t)*h * stride, got = 0;
    uint8_t *raw = malloc(raw_n + 1);
    int blocks[3] = {0, 0, 0}, syms[2] = {0, 0};
    const char *why = NULL;
    size_t end = inflate_raw(z + 2, zn - 2, raw, raw_n, &got, blocks, syms, &why);
    HL_CHECK(end > 0, "inflate: %s (after %zu of %zu bytes)", why ? why : "?", got, raw_n);
    HL_CHECK(end == 0 || (got == raw_n && 2 + end + 4 == zn), "zlib stream: %zu of %zu bytes, end at %zu of %zu",
             got, raw_n, 2 + end, zn);
    uint32_t a = 1, b = 0;
    for (size_t i = 0; i < got; i++) {
        a = (a + raw[i]) % 65521u;
        b = (b + a) % 65521u;
    }
    if (end > 0 && 2 + end + 4 <= zn) HL_CHECK(be32(z + 2 + end) == (b << 16 | a), "Adler-32 mismatch");
    int ftypes[5] = {0, 0, 0, 0, 0};
    *rgb = calloc(3 * (size_t)*w * *h + 1, 1);
    for (uint32_t y = 0; y < *h && got == raw_n; y++) {
        const uint8_t *r = raw + (size_t)y * stride;
        uint8_t *o = *rgb + 3 * (size_t)y * *w;
        const uint8_t *up = y ? o - 3 * (size_t)*w : NULL;
        if (r[0] > 4) {
            HL_CHECK(0, "row %u filter type %d", y, r[0]);
            got = 0;
            break;
        }
        ftypes[r[0]]++;
        for (size_t i = 0; i < 3 * (size_t)*w; i++) {
            int A = i >= 3 ? o[i - 3] : 0, B = up ? up[i] : 0, C = up && i >= 3 ? up[i - 3] : 0, pred;
            switch (r[0]) {
            case 0: pred = 0; break;
            case 1: pred = A; break;
            case 2: pred = B; break;
            case 3: pred = (A + B) / 2; break;
            default: pred = paeth_ref(A, B, C); break;
            }
            o[i] = (uint8_t)(r[1 + i] + pred);
        }
    }
    printf("PNG %u x %u: %zu bytes (%.2f%% of %zu raw); blocks stored %d fixed %d dynamic %d; %d literals, %d "
           "matches; row filters %d/%d/%d/%d/%d\n",
           *w, *h, n, 100.0 * (double)n / (double)(raw_n ? raw_n : 1), raw_n, blocks[0], blocks[1], blocks[2], syms[0],
           syms[1], ftypes[0], ftypes[1], ftypes[2], ftypes[3], ftypes[4]);
    free(raw);
    free(z);
    return got == raw_n && end > 0;
}

static float rnd_value(void)
{
    double u = (double)(hl_rng_next() >> 11) / 9007199254740992.0;
    switch (hl_rng_next() % 4) {
    case 0: return (float)u;                      /* [0, 1) */
    case 1: return (float)(u * 1.2);              /* around white */
    case 2: return (float)(u * u * u * 0.01);     /* dark, sRGB toe */
    default: return (float)exp(u * 20.0 - 12.0);  /* HDR, 6e-6 .. 3e3 */
    }
}

/* Saves img as PNG at path, decodes the file and compares every sample
 * with hl_tonemap_srgb8. Returns the file size; *seconds (if given) gets
 * the time hl_image_save took. */
static size_t png_check(hl_context *ctx, const hl_image *img, const char *path, float ev, double *seconds)
{
    uint32_t W = img->width, H = img->height;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    HL_CHECK(hl_image_save(ctx, img, path, ev) == HL_OK, "save %s: %s", path, hl_context_last_error(ctx));
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (seconds) *seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    size_t n = 0;
    uint8_t *file = read_bytes(path, &n), *px = NULL;
    uint32_t pw = 0, ph = 0;
    if (file && png_decode(file, n, &pw, &ph, &px)) {
        HL_CHECK(pw == W && ph == H, "PNG size %u x %u, expected %u x %u", pw, ph, W, H);
        int diff = 0;
        for (size_t i = 0; i < 3 * (size_t)W * H && pw == W && ph == H; i++)
            diff += px[i] != hl_tonemap_srgb8(img->rgb[i], ev);
        HL_CHECK(diff == 0, "%u x %u: %d PNG samples differ from hl_tonemap_srgb8", W, H, diff);
    } else {
        HL_CHECK(0, "%s: cannot decode", path);
    }
    free(px);
    free(file);
    return file ? n : 0;
}

static void test_image_io(void)
{
    hl_context *ctx = make_ctx();
    char dir[512], path[1024];
    scratch(dir, sizeof dir, "image_io");

    /* EXR round trip through hl_env_load (2:1). */
    hl_image *img = NULL;
    HL_CHECK(hl_image_create(ctx, 96, 48, &img) == HL_OK, "hl_image_create: %s", hl_context_last_error(ctx));
    if (!img) return;
    HL_CHECK(img->rgb[0] == 0.0f && img->rgb[3 * 96 * 48 - 1] == 0.0f, "new image not zeroed");
    for (size_t i = 0; i < 3 * 96 * 48; i++) img->rgb[i] = rnd_value();
    img->rgb[0] = 1e6f; /* beyond half floats: kept (the file holds 32-bit floats) */
    img->rgb[1] = 65504.0f;
    img->rgb[2] = 0.0f;
    snprintf(path, sizeof path, "%s/round.exr", dir);
    HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_OK, "save %s: %s", path, hl_context_last_error(ctx));
    hl_env *env = NULL;
    hl_env_stats st;
    HL_CHECK(hl_env_load(ctx, path, &env, &st) == HL_OK, "load %s: %s", path, hl_context_last_error(ctx));
    if (env) {
        HL_CHECK(env->width == 96 && env->height == 48, "round trip size %u x %u", env->width, env->height);
        size_t differ = 0;
        for (size_t i = 0; i < 3 * 96 * 48; i++) differ += memcmp(&img->rgb[i], &env->rgb[i], sizeof(float)) != 0;
        printf("EXR round trip: 1e6 -> %g\n", (double)env->rgb[0]);
        hl_check_error("EXR (float) round trip: channels not bit-equal", (double)differ, 0.0);
        hl_env_destroy(env);
    }
    hl_image_destroy(img);

    /* PNG: every image is written, read back with the decoder above and
     * compared sample by sample with hl_tonemap_srgb8. */
    int png_files = 0;
    /* Noise, small and large enough for several blocks and IDAT chunks. */
    static const uint32_t sizes[][2] = {{1, 1}, {5, 3}, {300, 250}, {1500, 400}};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        uint32_t W = sizes[k][0], H = sizes[k][1];
        img = NULL;
        HL_CHECK(hl_image_create(ctx, W, H, &img) == HL_OK, "hl_image_create %u x %u", W, H);
        if (!img) continue;
        for (size_t i = 0; i < 3 * (size_t)W * H; i++) img->rgb[i] = rnd_value();
        if (W * H > 1) {
            img->rgb[3] = NAN;
            img->rgb[4] = -1.0f;
            img->rgb[5] = INFINITY;
        }
        snprintf(path, sizeof path, "%s/image_%ux%u.png", dir, W, H);
        png_check(ctx, img, path, k % 2 ? 1.5f : -0.5f, NULL);
        png_files++;
        hl_image_destroy(img);
    }
    /* Smooth, odd-sized, flat and render-like images. */
    static const struct {
        uint32_t w, h;
        int kind; /* 0 gradient, 1 gradient + noise, 2 flat, 3 render-like, 4 uniformly random codes */
    } smooth[] = {{512, 256, 0}, {333, 77, 1}, {1, 1, 0}, {700, 300, 2}, {960, 720, 3}, {400, 300, 4}};
    for (size_t k = 0; k < sizeof smooth / sizeof smooth[0]; k++) {
        uint32_t W = smooth[k].w, H = smooth[k].h;
        img = NULL;
        HL_CHECK(hl_image_create(ctx, W, H, &img) == HL_OK, "hl_image_create %u x %u", W, H);
        if (!img) continue;
        for (uint32_t y = 0; y < H; y++) {
            for (uint32_t x = 0; x < W; x++) {
                float *p = img->rgb + 3 * ((size_t)y * W + x);
                double u = (x + 0.5) / W, v = (y + 0.5) / H;
                for (int c = 0; c < 3; c++) p[c] = (float)(0.9 * u * (1.0 - 0.3 * c) + 0.1 * v * c);
                if (smooth[k].kind == 1) {
                    for (int c = 0; c < 3; c++) p[c] *= (float)(0.85 + 0.3 * (double)(hl_rng_next() >> 11) * 0x1p-53);
                } else if (smooth[k].kind == 2) {
                    p[0] = p[1] = p[2] = 0.25f;
                } else if (smooth[k].kind == 4) {
                    /* Incompressible: every 8-bit code equally likely. */
                    for (int c = 0; c < 3; c++)
                        p[c] = (float)pow(((double)(hl_rng_next() % 256) / 255.0 + 0.055) / 1.055, 2.4);
                } else if (smooth[k].kind == 3) {
                    /* Sky, a ground plane and a lit sphere, with a little
                     * sampling noise. */
                    double sx = (u - 0.5) / 0.22, sy = (v - 0.55) / 0.3, r2 = sx * sx + sy * sy;
                    double e[3];
                    if (r2 < 1.0) {
                        double nz = sqrt(1.0 - r2), ndl = 0.5 * -sx + 0.6 * -sy + 0.62 * nz;
                        double lum = 0.05 + 0.9 * (ndl > 0.0 ? ndl : 0.0);
                        e[0] = 0.8 * lum, e[1] = 0.35 * lum, e[2] = 0.2 * lum;
                    } else if (v > 0.6) {
                        double shade = ((int)(u * 12.0) + (int)(v * 20.0)) % 2 ? 0.35 : 0.25;
                        e[0] = e[1] = e[2] = shade * (0.6 + 0.4 * v);
                    } else {
                        e[0] = 0.3 + 0.2 * v, e[1] = 0.45 + 0.2 * v, e[2] = 0.9 - 0.2 * v;
                    }
                    for (int c = 0; c < 3; c++)
                        p[c] = (float)(e[c] * (0.98 + 0.04 * (double)(hl_rng_next() >> 11) * 0x1p-53));
                }
            }
        }
        snprintf(path, sizeof path, "%s/smooth_%ux%u.png", dir, W, H);
        double seconds = 0.0;
        size_t bytes = png_check(ctx, img, path, 0.0f, &seconds);
        png_files++;
        double ratio = bytes ? 3.0 * W * H / (double)bytes : 0.0;
        printf("  %u x %u (%s): %zu bytes, %.2f : 1 against the %zu bytes of RGB, written in %.3f s\n", W, H,
               (const char *[]){"gradient", "gradient + noise", "flat", "render-like", "random codes"}[smooth[k].kind],
               bytes, ratio,
               (size_t)3 * W * H, seconds);
        if (smooth[k].kind == 0 && W == 512)
            HL_CHECK(ratio >= 3.0, "smooth 512 x 256 gradient compresses only %.2f : 1, expected 3 : 1 or better", ratio);
        if (smooth[k].kind == 2) HL_CHECK(ratio >= 100.0, "flat image compresses only %.1f : 1", ratio);
        /* Stored blocks: incompressible data grows by little more than the
         * 5 bytes per 64 KiB block, the filter bytes and the PNG chunks. */
        if (smooth[k].kind == 4)
            HL_CHECK(bytes <= (size_t)H * (1 + 3 * (size_t)W) * 1001 / 1000 + 100,
                     "random codes: %zu bytes, more than stored blocks would take", bytes);
        /* Generous: about 0.1 s optimised, but the tests also run unoptimised. */
        if (smooth[k].kind == 3) HL_CHECK(seconds < 5.0, "960 x 720 PNG took %.2f s", seconds);
        hl_image_destroy(img);
    }
    /* Overwriting an existing file works and leaves no temporary. */
    img = NULL;
    HL_CHECK(hl_image_create(ctx, 4, 2, &img) == HL_OK, "hl_image_create 4 x 2");
    snprintf(path, sizeof path, "%s/image_5x3.png", dir);
    HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_OK, "overwrite %s: %s", path, hl_context_last_error(ctx));
    int entries = dir_entries(dir, ".tmp.");
    HL_CHECK(entries == 1 + png_files, "%s holds %d files, expected %d", dir, entries, 1 + png_files);

    /* Refusals: extension, unwritable places. Nothing may be left. */
    snprintf(path, sizeof path, "%s/picture.jpg", dir);
    hl_result r = hl_image_save(ctx, img, path, 0.0f);
    HL_CHECK(r == HL_ERR_INVALID_ARGUMENT, ".jpg: %s", hl_result_string(r));
    HL_CHECK(strstr(hl_context_last_error(ctx), path) != NULL, ".jpg message does not name the path: %s",
             hl_context_last_error(ctx));
    HL_CHECK(!file_exists(path), ".jpg file created");
    snprintf(path, sizeof path, "%s/noext", dir);
    HL_CHECK(hl_image_save(ctx, img, path, 0.0f) == HL_ERR_INVALID_ARGUMENT, "no extension accepted");
    static const char *const kinds[] = {"png", "exr"};
    for (int k = 0; k < 2; k++) {
        snprintf(path, sizeof path, "%s/no_such_folder/out.%s", dir, kinds[k]);
        r = hl_image_save(ctx, img, path, 0.0f);
        HL_CHECK(r == HL_ERR_IO, "missing folder (.%s): %s", kinds[k], hl_result_string(r));
        HL_CHECK(strstr(hl_context_last_error(ctx), path) != NULL, "message does not name the path: %s",
                 hl_context_last_error(ctx));
        printf("unwritable: %s: %s\n", hl_result_string(r), hl_context_last_error(ctx));
        /* A path whose folder is a regular file (fails even for root). */
        snprintf(path, sizeof path, "%s/round.exr/out.%s", dir, kinds[k]);
        r = hl_image_save(ctx, img, path, 0.0f);
        HL_CHECK(r == HL_ERR_IO, "folder is a file (.%s): %s", kinds[k], hl_result_string(r));
    }
    if (geteuid() != 0) {
        char ro[600];
        snprintf(ro, sizeof ro, "%s/readonly", dir);
        mkdir(ro, 0755);
        chmod(ro, 0555);
        for (int k = 0; k < 2; k++) {
            snprintf(path, sizeof path, "%s/out.%s", ro, kinds[k]);
            r = hl_image_save(ctx, img, path, 0.0f);
            HL_CHECK(r == HL_ERR_IO, "read-only folder (.%s): %s", kinds[k], hl_result_string(r));
        }
        HL_CHECK(dir_entries(ro, NULL) == 0, "read-only folder not empty");
        chmod(ro, 0755);
        rmdir(ro);
    } else {
        printf("running as root: read-only folder check skipped (the missing-folder checks stand in)\n");
    }
    entries = dir_entries(dir, ".tmp.");
    HL_CHECK(entries == 1 + png_files, "%s holds %d files after the refusals, expected %d", dir, entries,
             1 + png_files);
    HL_CHECK(hl_image_save(ctx, NULL, path, 0.0f) == HL_ERR_INVALID_ARGUMENT, "NULL image accepted");
    hl_image_destroy(img);

    img = NULL;
    HL_CHECK(hl_image_create(ctx, 0, 5, &img) == HL_ERR_INVALID_ARGUMENT && img == NULL, "0 x 5 image accepted");
    HL_CHECK(hl_image_create(ctx, 70000, 5, &img) == HL_ERR_INVALID_ARGUMENT, "70000 wide image accepted");
    hl_image_destroy(NULL);
    hl_context_destroy(ctx);
}

/* ---------------------------------------------------------------- tonemap */

static int srgb_ref(double x)
{
    if (!(x > 0.0)) return 0;
    if (x >= 1.0) return 255;
    double y = x < 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
    return (int)floor(y * 255.0 + 0.5);
}

static void test_tonemap(void)
{
    static const struct {
        float x, ev;
        int code;
    } known[] = {
        {0.0f, 0.0f, 0},       {1.0f, 0.0f, 255},     {0.5f, 0.0f, 188},      {0.18f, 0.0f, 118},
        {0.0031308f, 0.0f, 10}, {0.0031307f, 0.0f, 10}, {0.0031309f, 0.0f, 10}, {0.001f, 0.0f, 3},
        {0.25f, 1.0f, 188},    {1.0f, -1.0f, 188},    {0.5f, 1.0f, 255},      {2.0f, 0.0f, 255},
        {-1.0f, 0.0f, 0},      {NAN, 0.0f, 0},        {INFINITY, 0.0f, 255},  {-INFINITY, 0.0f, 0},
        {1e-30f, 0.0f, 0},     {0.0625f, 3.0f, 188},
    };
    for (size_t k = 0; k < sizeof known / sizeof known[0]; k++) {
        int got = hl_tonemap_srgb8(known[k].x, known[k].ev);
        HL_CHECK(got == known[k].code, "tonemap(%g, ev %g) = %d, expected %d", (double)known[k].x, (double)known[k].ev,
                 got, known[k].code);
    }
    /* Both sides of the boundary agree with the curve, which is continuous
     * there: 12.92 x = 1.055 x^(1/2.4) - 0.055 at x = 0.0031308 to 1e-7. */
    double lin = 12.92 * 0.0031308, pw = 1.055 * pow(0.0031308, 1.0 / 2.4) - 0.055;
    hl_check_error("sRGB curve continuity at 0.0031308", fabs(lin - pw), 1e-6);

    /* A sweep against the formula written here, and monotonicity. */
    int mismatches = 0, prev = 0, nonmono = 0;
    for (int i = 0; i <= 200000; i++) {
        float x = (float)i / 160000.0f;
        int got = hl_tonemap_srgb8(x, 0.0f), want = srgb_ref((double)x);
        mismatches += got != want;
        nonmono += got < prev;
        prev = got;
    }
    HL_CHECK(mismatches == 0, "%d of 200001 codes differ from the reference curve", mismatches);
    HL_CHECK(nonmono == 0, "tone curve not monotonic (%d steps down)", nonmono);
    /* Exposure +1 doubles: tonemap(x, ev + 1) == tonemap(2x, ev). */
    int exp_bad = 0;
    for (int i = 0; i < 5000; i++) {
        float x = (float)i / 4000.0f;
        exp_bad += hl_tonemap_srgb8(x, 1.0f) != hl_tonemap_srgb8(2.0f * x, 0.0f);
        exp_bad += hl_tonemap_srgb8(x, -2.0f) != hl_tonemap_srgb8(0.25f * x, 0.0f);
    }
    HL_CHECK(exp_bad == 0, "%d exposure mismatches", exp_bad);
}

int main(int argc, char **argv)
{
    static const hl_test_case cases[] = {
        {"io", test_image_io},
        {"tonemap", test_tonemap},
        {NULL, NULL},
    };
    return hl_test_main(argc, argv, cases);
}
