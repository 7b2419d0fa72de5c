/* relight.cl - vertex colours: B(v) = albedo(v) * sum_i T_i(v) L_i over the
 * kept lighting terms.
 *
 * The transport is held by column on the device (built on load from the
 * file's rows, see build_columns in host/src/relight/cl_columns.c). The device
 * holds the vertices in its own order (order[p]: the vertex at position p;
 * see vertex_order), positions grouped in tiles of HL_TILE and tiles in
 * ranges, one range per work-item (range_start: position boundaries, whole
 * tiles); albedo and back are in position order (the albedo one for all,
 * albedo_step 0, where every vertex has the same), colours go to their
 * vertices.
 *
 * For each range and slot the column lists the tiles in which at least one
 * vertex stores that slot, in tile order, each as one entry of ENTRY
 * words: the tile's HL_TILE terms as halves, decoded from the file's codes
 * on load and scaled by 2^-e per vertex (host/src/core/half.h; zero in
 * lanes whose vertex does not store the slot). Column (w, s) holds entries
 * col_start[w (ncoef + 1) + s] to the next start. Entry 0 is all zero.
 * For each range and slot, rel says which tiles the column holds, 32 tiles
 * a word: a bit a tile (x), and the column's entries before the word (y).
 * So the column holds tile t as entry y + (the set bits below t's) + 1; a
 * tile not held reads entry 0. (Two bits a slot and tile, where a 16-bit
 * entry number a slot and tile and a 4-byte head an entry took more.)
 * kept: a count, then the kept slots in ascending order (written by
 * hl_select).
 *
 * A work-item walks its range one of two ways (hl_tile_walk_pays in
 * hl_shared.h): by column (walk_columns, a few columns together) or by
 * tile (walk_tiles). Either
 * way each vertex adds its kept terms in ascending slot order, one fused
 * multiply-add per term and colour, as the twin does
 * (host/src/relight/twins/relight.c walks whole rows), and so rounds alike: zero
 * lanes and entry 0 add exact zeros (fma(0, l, s) = s). Then each
 * vertex's sums are scaled back by 2^e (back) and times the albedo.
 * Truncated lighting and transport can sum to a little below zero where
 * the exact answer is dark, and no output may hold negative light: each
 * channel is clamped at zero (unless keep_negative), and the fourth float
 * keeps the lowest channel before the clamp (0 when none was negative) so
 * the host can say how much was clamped.
 */
#pragma OPENCL FP_CONTRACT OFF

#define HL_CAT_(a, b) a##b
#define HL_CAT(a, b) HL_CAT_(a, b)
#define FV HL_CAT(float, HL_TILE)            /* float16 */
/* An entry's terms as floats. Where clang targets AVX-512 (PoCL on such
 * a CPU), as one vector of HL_TILE halves: one conversion instruction on
 * a 16-lane register, where PoCL's vload_half16 converts two halves of 8
 * and joins them (three); 0.25 ms of the dragon's 4.4 at M = 200
 * (docs/SCALE.md). The conversion is exact either way. */
#if defined(__clang__) && defined(__AVX512F__)
typedef __fp16 hl_halves __attribute__((ext_vector_type(HL_TILE)));
#define LOAD_TERMS(i, p) __builtin_convertvector(((global const hl_halves *)(p))[i], FV)
#else
#define LOAD_TERMS HL_CAT(vload_half, HL_TILE)
#endif
#define ENTRY (HL_TILE / 2u)                  /* words per column entry */

#if HL_TILE != 8 && HL_TILE != 16
#error "HL_TILE must be 8 or 16"
#endif

/* The tile walk: tiles whose sums (3 x 16 x 4 bytes each, 768 KB) wait
 * between passes (a whole number of words of tile bits), and the kept
 * slots it adds per pass over them: HL_TILE_GROUP (hl_shared.h). Each
 * pass reads each slot's entries for these tiles as one run, and the
 * longer the runs the better the reads stream: on the dragon at M = 200,
 * 3.57 ms at 4,096 tiles against 4.03 at 512 (96 KB, which the L2 cache
 * holds), and no faster at 8,192 or 16,384 (docs/SCALE.md). A whole
 * number of 32-tile words, so that no word is split between passes;
 * the walk takes any count (hl.relight.twin_passes builds it with 3). */
#ifndef HL_SUM_TILES
#define HL_SUM_TILES 4096
#endif

/* Both walks read HL_TILE_GROUP or HL_COL_GROUP columns at once, each a
 * run of entries, and the CPU's own prefetching kept too few of those
 * runs' lines coming: asking for each column's entries HL_AHEAD entries
 * (2 KB) ahead took the dragon's dot products at M = 200 from 3.7 to
 * 3.0 ms (16 entries ahead 3.55, 32 to 128 alike; docs/SCALE.md). A
 * prefetch is only a hint and never faults, so one past a column's or
 * the buffer's end does no harm. Where the compiler is not clang on
 * x86-64 there is none. */
#define HL_AHEAD 64u
#if defined(__clang__) && defined(__x86_64__)
#define HL_PREFETCH(p) __builtin_prefetch((const void *)(size_t)(p))
#else
#define HL_PREFETCH(p)
#endif

/* One entry's terms d of a kept slot with light l, added to a tile's sums. */
static inline void add_terms(FV d, float4 l, FV *r, FV *gr, FV *b)
{
    *r = fma(d, (FV)(l.x), *r);
    *gr = fma(d, (FV)(l.y), *gr);
    *b = fma(d, (FV)(l.z), *b);
}

/* The column walk: the kept slots in groups of HL_COL_GROUP, each group's
 * columns walked together, tile by tile through the tiles any of them
 * holds (their tile bits or-ed, 32 tiles a word), each such tile's sums
 * (planes of `range` floats in memory) loaded once, the group's terms
 * added in slot order (entry 0 for a slot the tile lacks) and stored once.
 * One slot at a time the sums were loaded and stored for every entry (6
 * vector loads and 6 stores besides the 6 multiply-adds), and those, not
 * the entries' bytes, set the time: groups of 4 take about three quarters
 * of it on the dragon at M = 200 (docs/SCALE.md). The last group's places past
 * the m kept slots hold no tiles and no light. */
#define HL_COL_GROUP 4
static void walk_columns(global const uint *col, global const uint *cs, global const uint2 *rw, uint tstride,
                         global const float4 *light, global const uint *kept, uint m, global float *acc, uint range)
{
    global FV *vr = (global FV *)acc, *vg = (global FV *)(acc + range), *vb = (global FV *)(acc + 2 * range);
    for (uint i = 0; i < range / HL_TILE; i++) vr[i] = vg[i] = vb[i] = (FV)(0.0f);
    for (uint j0 = 0; j0 < m; j0 += HL_COL_GROUP) {
        global const uint *e[HL_COL_GROUP], *end[HL_COL_GROUP];
        global const uint2 *bits[HL_COL_GROUP];
        float4 li[HL_COL_GROUP];
        for (uint g = 0; g < HL_COL_GROUP; g++) {
            const uint s = kept[1 + min(j0 + g, m - 1)], in = j0 + g < m;
            li[g] = in ? light[s] : (float4)(0.0f);
            e[g] = col + (size_t)cs[s] * ENTRY;
            end[g] = in ? col + (size_t)cs[s + 1] * ENTRY : e[g];
            bits[g] = rw + (size_t)s * tstride;
        }
        for (uint word = 0;; word++) {
            uint left = 0, x = 0, xg[HL_COL_GROUP];
            for (uint g = 0; g < HL_COL_GROUP; g++) left |= e[g] < end[g];
            if (!left) break;
            for (uint g = 0; g < HL_COL_GROUP; g++) {
                xg[g] = e[g] < end[g] ? bits[g][word].x : 0u;
                x |= xg[g];
            }
            for (; x; x &= x - 1u) {
                const uint low = x & (0u - x), tq = 32u * word + (31u - clz(low)); /* the lowest set bit's tile */
                FV r = vr[tq], gr = vg[tq], b = vb[tq];
#pragma unroll
                for (uint g = 0; g < HL_COL_GROUP; g++) {
                    const uint hit = xg[g] & low;
                    add_terms(LOAD_TERMS(0, (global const half *)(hit ? e[g] : col)), li[g], &r, &gr, &b);
                    e[g] += hit ? ENTRY : 0u;
                }
                vr[tq] = r;
                vg[tq] = gr;
                vb[tq] = b;
#pragma unroll
                for (uint g = 0; g < HL_COL_GROUP; g++) HL_PREFETCH(e[g] + HL_AHEAD * ENTRY);
            }
        }
    }
}

/* The tile walk over tiles t0 .. t0 + tn - 1: the kept slots in groups of
 * HL_TILE_GROUP, each group's terms added tile by tile into sums held in
 * registers; between groups the sums wait in `acc` (planes of tn tiles,
 * which stay in the cache). The tiles go a word of tile bits (32 tiles)
 * at a time: where every slot of the group holds every tile of the word,
 * as on a mesh whose tiles are nearly all full, each slot's entries for
 * the word lie one after another and are read without testing the bits
 * (about 15.6 instructions a slot and tile in PoCL's code against 24;
 * docs/SCALE.md). The sums come out the same either way: the same
 * multiply-adds in the same order. */
static void walk_tiles(global const uint *col, global const uint *cs, global const uint2 *rw, uint tstride,
                       global const float4 *light, global const uint *kept, uint m, global float *acc, uint t0,
                       uint tn)
{
    global FV *sr = (global FV *)acc, *sg = sr + tn, *sb = sg + tn;
    for (uint j0 = 0; j0 < m; j0 += HL_TILE_GROUP) {
        /* the group's slots; past the last kept one, the last again with
           no light, adding exact zeros */
        global const uint2 *row[HL_TILE_GROUP];
        global const uint *before[HL_TILE_GROUP];
        float4 li[HL_TILE_GROUP];
        for (uint g = 0; g < HL_TILE_GROUP; g++) {
            uint s = kept[1 + min(j0 + g, m - 1)];
            row[g] = rw + (size_t)s * tstride;
            before[g] = col + ((size_t)cs[s] - 1) * ENTRY; /* entry r at before + r ENTRY */
            li[g] = j0 + g < m ? light[s] : (float4)(0.0f);
        }
        for (uint t = 0; t < tn;) {
            /* the word's tiles t .. t + n - 1; per slot its tile bits and
               where the first tile it holds here has its terms */
            const uint tt = t0 + t, bit = tt & 31u, n = min(32u - bit, tn - t);
            const uint want = (n == 32u ? ~0u : (1u << n) - 1u) << bit;
            uint bits[HL_TILE_GROUP], all = want;
            global const uint *next[HL_TILE_GROUP];
#pragma unroll
            for (uint g = 0; g < HL_TILE_GROUP; g++) {
                uint2 rk = row[g][tt >> 5];
                bits[g] = rk.x;
                all &= rk.x;
                next[g] = before[g] + (size_t)(rk.y + popcount(rk.x & ((1u << bit) - 1u)) + 1u) * ENTRY;
            }
            const int dense = all == want;
            for (uint u = 0; u < n; u++) {
                FV r, gr, b;
                if (j0 == 0) r = gr = b = (FV)(0.0f);
                else { r = sr[t + u]; gr = sg[t + u]; b = sb[t + u]; }
                if (!(u & 1u)) { /* a 64-byte line holds two entries */
#pragma unroll
                    for (uint g = 0; g < HL_TILE_GROUP; g++)
                        HL_PREFETCH(next[g] + (dense ? u + HL_AHEAD : HL_AHEAD) * ENTRY);
                }
                if (dense) {
#pragma unroll
                    for (uint g = 0; g < HL_TILE_GROUP; g++)
                        add_terms(LOAD_TERMS(u, (global const half *)next[g]), li[g], &r, &gr, &b);
                } else {
#pragma unroll
                    for (uint g = 0; g < HL_TILE_GROUP; g++) {
                        uint hit = (bits[g] >> (bit + u)) & 1u;
                        global const uint *e = hit ? next[g] : col;
                        next[g] += hit ? ENTRY : 0u;
                        add_terms(LOAD_TERMS(0, (global const half *)e), li[g], &r, &gr, &b);
                    }
                }
                sr[t + u] = r; sg[t + u] = gr; sb[t + u] = b;
            }
            t += n;
        }
    }
}

/* The colours of positions p0 .. p1 - 1 from their sums (planes of n
 * floats from position p0), each added to the clamp's tally. Eight
 * positions at a time: the same operations as hl_colour_out and
 * hl_tally_add lane by lane, so the same colours and tally, for about 30
 * instructions a vertex fewer than one at a time (docs/SCALE.md); the
 * last few one at a time. */
static void put_colours(global const float *sums, uint n, uint p0, uint p1, global const float *back,
                        global const float4 *albedo, uint astep, global const uint *order, uint keep_negative,
                        global float4 *out, float *lo, float *hi, uint *neg)
{
    /* tallied in the loop's own variables, joined once after it: PoCL
       kept the caller's in memory, a load and store a vertex */
    float8 l8 = (float8)(0.0f), h8 = (float8)(0.0f);
    int8 k8 = (int8)(0);
    uint v = p0;
    for (; v + 8u <= p1; v += 8u) {
        const uint i = v - p0;
        const float8 bk = vload8(0, back + v);
        float8 ar, ag, ab;
        if (astep) {
            const float16 a0 = vload16(0, (global const float *)(albedo + v));
            const float16 a1 = vload16(0, (global const float *)(albedo + v + 4));
            ar = (float8)(a0.s048c, a1.s048c);
            ag = (float8)(a0.s159d, a1.s159d);
            ab = (float8)(a0.s26ae, a1.s26ae);
        } else {
            const float4 a = albedo[0];
            ar = (float8)(a.x);
            ag = (float8)(a.y);
            ab = (float8)(a.z);
        }
        float8 r = (vload8(0, sums + i) * bk) * ar;
        float8 g = (vload8(0, sums + n + i) * bk) * ag;
        float8 b = (vload8(0, sums + 2 * n + i) * bk) * ab;
        const float8 zero = (float8)(0.0f);
        float8 c = select(zero, r, r < zero);
        c = select(c, g, g < c);
        c = select(c, b, b < c);
        if (!keep_negative) {
            r = select(zero, r, r > zero);
            g = select(zero, g, g > zero);
            b = select(zero, b, b > zero);
        }
        const float8 m = select(r, g, g > r), top = select(m, b, b > m);
        l8 = select(l8, c, c < l8);
        h8 = select(h8, top, top > h8);
        k8 -= c < zero; /* true is -1 */
        /* each colour made from the lanes in registers: through a float
           array on the stack PoCL's code read 16 bytes across two stores
           it had just made, and waited on them (0.4 ms of the dragon's
           4.8 at M = 200, docs/SCALE.md) */
        const uint8 o = vload8(0, order + v);
        out[o.s0] = (float4)(r.s0, g.s0, b.s0, c.s0);
        out[o.s1] = (float4)(r.s1, g.s1, b.s1, c.s1);
        out[o.s2] = (float4)(r.s2, g.s2, b.s2, c.s2);
        out[o.s3] = (float4)(r.s3, g.s3, b.s3, c.s3);
        out[o.s4] = (float4)(r.s4, g.s4, b.s4, c.s4);
        out[o.s5] = (float4)(r.s5, g.s5, b.s5, c.s5);
        out[o.s6] = (float4)(r.s6, g.s6, b.s6, c.s6);
        out[o.s7] = (float4)(r.s7, g.s7, b.s7, c.s7);
    }
    float l = 0.0f, h = 0.0f, ls[8], hs[8];
    int ks[8];
    vstore8(l8, 0, ls);
    vstore8(h8, 0, hs);
    vstore8(k8, 0, ks);
    uint k = 0;
    for (uint j = 0; j < 8u; j++) {
        l = ls[j] < l ? ls[j] : l;
        h = hs[j] > h ? hs[j] : h;
        k += (uint)ks[j];
    }
    for (; v < p1; v++) {
        uint i = v - p0;
        const float4 c =
            hl_colour_out(((float4)(sums[i], sums[n + i], sums[2 * n + i], 0.0f) * back[v]) * albedo[v * astep], keep_negative);
        out[order[v]] = c;
        hl_tally_add(c, &l, &h, &k);
    }
    *lo = l < *lo ? l : *lo;
    *hi = h > *hi ? h : *hi;
    *neg += k;
}

/* tally[tally0 + w]: the clamp's tally of range w's vertices
 * (hl_tally_add; tally0, the part's first range when relit in parts). */
kernel void hl_relight(global const uint *col, global const uint *col_start, global const uint2 *rel, uint tstride,
                       global const uint *range_start, global const float *back, uint ncoef,
                       global const float4 *light, global const uint *kept, global const float4 *albedo,
                       global float *acc, global float4 *out, uint nverts, uint nranges, global const uint *order,
                       uint keep_negative, global float4 *tally, uint tally0, uint albedo_step)
{
    uint w = get_global_id(0);
    if (w >= nranges) return;
    const uint v0 = range_start[w], range = range_start[w + 1] - v0, nt = range / HL_TILE;
    const uint v1 = min(range_start[w + 1], nverts), m = kept[0];
    global const uint *cs = col_start + (size_t)w * (ncoef + 1);
    global float *ar = acc + (size_t)3 * v0;
    ulong entries = 0;
    for (uint j = 0; j < m; j++) entries += cs[kept[1 + j] + 1] - cs[kept[1 + j]];
    global const uint2 *rw = rel + (size_t)w * ncoef * tstride;
    float lo = 0.0f, hi = 0.0f;
    uint neg = 0;
    if (!hl_tile_walk_pays(entries, m, nt)) {
        walk_columns(col, cs, rw, tstride, light, kept, m, ar, range);
        put_colours(ar, range, v0, v1, back, albedo, albedo_step, order, keep_negative, out, &lo, &hi, &neg);
    } else {
        for (uint t0 = 0; t0 < nt; t0 += HL_SUM_TILES) {
            const uint tn = min((uint)HL_SUM_TILES, nt - t0), n = tn * HL_TILE, p0 = v0 + t0 * HL_TILE;
            walk_tiles(col, cs, rw, tstride, light, kept, m, ar, t0, tn);
            put_colours(ar, n, p0, min(p0 + n, v1), back, albedo, albedo_step, order, keep_negative, out, &lo, &hi, &neg);
        }
    }
    tally[tally0 + w] = (float4)(lo, hi, as_float(neg), 0.0f);
}
