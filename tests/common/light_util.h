/* light_util.h - helpers of the lighting stages' tests (tests/maps,
 * tests/relight): contexts, a small transport made by `haarlight
 * precompute` from data/bunny_lowres.obj, 2:1 environments with a sun, and
 * the chain of lighting Haar, selection and dot products compared with
 * their plain-C twins (lighting_chain: the selection alone, or with the
 * dot products that use it).
 * Depends on: hl_test.h, cl_backend.h, geom.h, half.h, lighting.h,
 * twins.h, HL_BIN, HL_REPO_DATA, HL_TMP.
 */
#ifndef HL_TEST_LIGHT_UTIL_H
#define HL_TEST_LIGHT_UTIL_H

#include <unistd.h>

static inline hl_context *ctx_of(hl_backend b)
{
    hl_context_desc d = {.backend = b, .cl_platform = -1, .cl_device = -1};
    hl_context *c = NULL;
    char err[4096];
    if (hl_context_create(&d, &c, err, sizeof err) != HL_OK) fprintf(stderr, "context: %s\n", err);
    return c;
}

/* A small transport made here: data/bunny_lowres.obj with a ground. */
static inline const char *make_transport(const char *name, const char *extra)
{
    static char path[1024];
    char cmd[4096];
    /* named by the process too: ctest runs the select and relight cases
       at once, and two precomputes of one name lock each other out */
    snprintf(path, sizeof path, "%s/%ld_%s", hl_test_env("HL_TMP", "/tmp"), (long)getpid(), name);
    snprintf(cmd, sizeof cmd, "'%s' precompute '%s/bunny_lowres.obj' --ground --ground-res 12 -C 32 -N 32 -q %s -o '%s'",
             hl_test_env("HL_BIN", "haarlight"), hl_test_env("HL_REPO_DATA", "data"), extra, path);
    if (system(cmd) != 0) {
        fprintf(stderr, "failed: %s\n", cmd);
        return NULL;
    }
    return path;
}

/* A 2:1 environment: a soft gradient plus an optional one-pixel sun, every
 * pixel times scale. */
static inline hl_env *make_env_scaled(hl_context *ctx, uint32_t W, int sun_x, int sun_y, float sun, float scale)
{
    uint32_t H = W / 2;
    float *rgb = malloc((size_t)W * H * 12);
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++) {
            float *p = rgb + 3 * ((size_t)y * W + x);
            p[0] = 0.2f + 0.5f * (float)y / (float)H;
            p[1] = 0.3f + 0.2f * (float)x / (float)W;
            p[2] = 0.9f - 0.6f * (float)y / (float)H;
        }
    if (sun > 0) for (int c = 0; c < 3; c++) rgb[3 * ((size_t)sun_y * W + sun_x) + c] = sun;
    for (size_t i = 0; i < (size_t)W * H * 3; i++) rgb[i] *= scale;
    hl_env *e = NULL;
    if (hl_env_create(ctx, W, H, rgb, &e, NULL) != HL_OK) fprintf(stderr, "%s\n", hl_context_last_error(ctx));
    free(rgb);
    return e;
}

static inline hl_env *make_env(hl_context *ctx, uint32_t W, int sun_x, int sun_y, float sun)
{
    return make_env_scaled(ctx, W, sun_x, sun_y, sun, 1.0f);
}


/* The dot products' work-items share the kept column entries evenly (the
 * kernel waits for the largest share): on a CPU device the tiles are dealt
 * to one range per core. Checked where every range gets at least 48 tiles
 * (on this mesh: up to 2 ranges), since a few dealt tiles need not share
 * evenly. */
static inline void check_balance(const hl_cl_light *l, const uint32_t *bits, uint32_t nverts)
{
    uint32_t n = hl_cl_light_ranges(l);
    double *per = malloc(n * sizeof *per), total = 0.0, most = 0.0;
    if (!per) return;
    hl_cl_light_kept_entries(l, bits, per);
    for (uint32_t r = 0; r < n; r++) {
        total += per[r];
        most = fmax(most, per[r]);
    }
    if (n > 1 && (nverts + 15) / 16 / n >= 48) {
        printf("kept entries over %u ranges: largest %.0f, mean %.1f\n", n, most, total / n);
        hl_check_error("largest range's kept entries over the mean, minus 1", most / (total / n) - 1.0, 0.03);
    } else if (n > 1) {
        printf("kept entries over %u ranges: balance not checked (fewer than 48 tiles a range)\n", n);
    }
    free(per);
}

/* The ranges that take the tile walk for the kept slots in bits (the rest
 * into *by_column). */
static inline uint32_t count_walks(const hl_cl_light *l, const uint32_t *bits, uint32_t *by_column)
{
    uint32_t n = hl_cl_light_ranges(l), tiles = 0;
    double *per = malloc(n * sizeof *per);
    if (!per) return 0;
    double kept = hl_cl_light_kept_entries(l, bits, per);
    for (uint32_t r = 0; r < n; r++) {
        int t = hl_cl_light_tile_walk(l, r, per[r], (uint32_t)kept);
        tiles += t;
        *by_column += !t;
    }
    free(per);
    return tiles;
}

/* Haar of 3 rows, selection and (dots) the dot products: OpenCL equals C
 * exactly given identical inputs. Without dots it stops at the selection
 * (select.twin); relight.twin goes on to the dot products, which take the
 * selection as their input. */
static inline void lighting_chain(int dots)
{
    hl_context *cl = ctx_of(HL_BACKEND_OPENCL), *ref = ctx_of(HL_BACKEND_REFERENCE);
    hl_transport *t = NULL;
    int gpu = -1; /* the relighters' shape (HL_DEVICE_SHAPE: the test's ctest name says which) */
    uint32_t walks[2] = {0, 0}; /* ranges walked by tile, by column */
    uint64_t words[2] = {0, 0}; /* the tile walk's words: without and with testing the bits */
    /* the selection reads the lighting only: one transport's geometry will
       do for it, the dot products read both quantisation schemes (the
       second with 48 terms a vertex, sparser tiles) */
    for (int scheme = 0; scheme < (dots ? 2 : 1); scheme++) {
        const char *path = make_transport("light_b.hlt", scheme ? "--quant linear8 --terms 48" : "--quant log8");
        HL_CHECK(path && hl_transport_load(ref, path, &t) == HL_OK, "transport");
        if (!t || !cl) return;
        hl_geom *g = NULL;
        hl_light_geom *lg = NULL;
        hl_geom_create(ref, t->info.N, t->info.C, &g);
        hl_light_geom_create(ref, g, &lg);
        const uint32_t V = t->info.vertex_count, nc = g->ncoef;
        float *alb = malloc((size_t)V * 16);
        /* the first scheme with one albedo for all (the device holds one),
           the second with an albedo a vertex */
        for (uint32_t v = 0; v < V; v++) {
            for (int c = 0; c < 3; c++)
                alb[4 * v + c] = scheme ? t->mesh->albedo[3 * v + c] * (0.5f + (float)((v * 7 + c) % 11) / 20.0f)
                                        : t->mesh->albedo[c];
            alb[4 * v + 3] = 0;
        }
        hl_cl_light *l = NULL;
        HL_CHECK(hl_cl_light_create(cl, g, lg, t, alb, &l) == HL_OK, "%s", hl_context_last_error(cl));
        HL_CHECK(l && hl_cl_light_one_albedo(l) == !scheme, "scheme %d: one albedo for all %d", scheme,
                 l ? hl_cl_light_one_albedo(l) : -1);
        if (l) {
            gpu = hl_cl_light_gpu_shape(l);
            const char *want = getenv("HL_DEVICE_SHAPE");
            if (want && (!strcmp(want, "gpu") || !strcmp(want, "cpu")))
                HL_CHECK(gpu == !strcmp(want, "gpu"), "HL_DEVICE_SHAPE=%s, but the relighter runs the %s shape", want,
                         gpu ? "GPU" : "CPU");
            printf("%s shape: the selection as %s, the dot products over %u ranges\n", gpu ? "GPU" : "CPU",
                   hl_cl_light_select_as_group(l) ? "one work-group" : "one work-item", hl_cl_light_ranges(l));
            /* the GPU shape's own kernels ran: the selection as a group
               (PoCL takes its 256 work-items), and more than one range of
               512 positions, the last one short */
            if (gpu) HL_CHECK(hl_cl_light_select_as_group(l) && hl_cl_light_ranges(l) > 1 && V % 512 != 0,
                              "the GPU shape's group selection and several ranges, the last one short");
        }
        const char *pass = getenv("HL_TEST_SUM_TILES");
        if (pass && l) {
            /* the tile walk's passes made short: every range takes several */
            const uint32_t per = (uint32_t)atoi(pass), least = (V + HL_TILE - 1) / HL_TILE / hl_cl_light_ranges(l);
            printf("tile walk: %u tiles a pass, at least %u tiles a range\n", per, least);
            HL_CHECK(per > 0 && least > per, "the ranges (%u tiles and up) must take more than one pass of %u", least, per);
        }
        hl_env *env = make_env(ref, 512, 100, 60, 3e4f);
        float *cells = NULL, *Lp = malloc((size_t)nc * 12), *Lp2 = malloc((size_t)nc * 12);
        float *wa = malloc((size_t)nc * 12), *wb = malloc((size_t)nc * 12);
        hl_env_to_cells(ref, env, lg->wc, lg->hc, &cells);
        hl_ref_env2para(cells, lg->wc, lg->tap_start, lg->taps, 5, 0.25f, nc, Lp);
        memcpy(Lp2, Lp, (size_t)nc * 12);
        for (int c = 0; c < 3; c++) hl_ref_haar(g, Lp + (size_t)c * nc, wa + (size_t)c * nc);
        HL_CHECK(hl_cl_light_stage_haar(l, Lp2, wb) == HL_OK, "haar");
        double hw = 0.0, hs = 0.0;
        for (size_t k = 0; k < 3 * (size_t)nc; k++) { hw = fmax(hw, fabs((double)wa[k] - wb[k])); hs = fmax(hs, fabs(wa[k])); }
        hl_check_error("Haar of R, G, B: OpenCL vs C (relative to max)", hw / hs, 1e-6);
        float *sa = malloc((size_t)nc * 16), *sb = malloc((size_t)nc * 16), *Ba = malloc((size_t)V * 16), *Bb = malloc((size_t)V * 16);
        uint8_t *ua = malloc(g->nblocks), *ub = malloc(g->nblocks);
        uint32_t *ka = malloc((size_t)nc / 8), *kb = malloc((size_t)nc / 8);
        hl_ref_key *keys = malloc((size_t)nc * sizeof *keys);
        static const uint32_t Ms[] = {1, 25, 200, 1000, HL_TERMS_ALL};
        for (uint32_t sel = HL_SELECT_AREA; sel <= HL_SELECT_UNWEIGHTED; sel++)
            for (size_t m = 0; m < 5; m++) {
                hl_select_params sp = {Ms[m], sel, {0, 0}};
                float *w = sel == HL_SELECT_AREA ? lg->area : NULL;
                float *ones = NULL;
                if (!w) { ones = malloc((size_t)nc * 4); for (uint32_t i = 0; i < nc; i++) ones[i] = 1.0f; w = ones; }
                hl_cl_light_set_weights(l, w);
                hl_select_result ra = hl_ref_select(wa, nc, w, sp, sa, ua, ka, g->nblocks, keys), rb;
                HL_CHECK(hl_cl_light_stage_select(l, wa, sp, sb, ub, kb, &rb) == HL_OK, "select");
                int same = !memcmp(sa, sb, (size_t)nc * 16) && !memcmp(ua, ub, g->nblocks) && !memcmp(ka, kb, nc / 8) && ra.kept == rb.kept &&
                           ra.blocks_used == rb.blocks_used && ra.energy_kept == rb.energy_kept && ra.energy_total == rb.energy_total;
                HL_CHECK(same, "selection M=%u scheme %u: OpenCL differs from C", Ms[m], sel);
                HL_CHECK(ra.kept == (Ms[m] < nc ? Ms[m] : ra.kept), "kept %u of M=%u", ra.kept, Ms[m]);
                if (!dots) {
                    free(ones);
                    continue;
                }
                /* dot products: the twin skips nothing */
                for (uint32_t v = 0; v < V; v++) {
                    hl_ref_relight(t->entries + 2 * t->row_offset[v], t->block_counts + (size_t)v * g->nblocks,
                                   t->row_quant[v], t->info.quant, v, g->nblocks, sa, alb + 4 * v, 0, Ba + 4 * v);
                }
                HL_CHECK(hl_cl_light_stage_relight(l, sa, ka, Bb) == HL_OK, "relight");
                uint32_t diff = 0;
                for (uint32_t v = 0; v < V; v++) diff += memcmp(Ba + 4 * v, Bb + 4 * v, 12) != 0;
                printf("%s, %s, M=%u: kept %u, %u of %u blocks, energy kept %.6f; %u of %u vertices differ\n",
                       scheme ? "linear8" : "log8", sel == HL_SELECT_AREA ? "area" : "unweighted", Ms[m], ra.kept,
                       ra.blocks_used, g->nblocks, ra.energy_total > 0 ? ra.energy_kept / ra.energy_total : 1.0, diff, V);
                HL_CHECK(diff == 0, "dot products: OpenCL must equal C bit for bit");
                walks[0] += count_walks(l, ka, &walks[1]);
                uint64_t wd = 0, wm = 0;
                HL_CHECK(hl_cl_light_tile_words(l, ka, &wd, &wm) == HL_OK, "%s", hl_context_last_error(cl));
                words[0] += wd;
                words[1] += wm;
                if (Ms[m] == 200) check_balance(l, ka, V);
                free(ones);
            }
        free(sa); free(sb); free(Ba); free(Bb); free(ua); free(ub); free(ka); free(kb); free(keys);
        free(Lp); free(Lp2); free(wa); free(wb); free(alb);
        hl_free_big(cells);
        hl_env_destroy(env);
        hl_cl_light_destroy(l);
        hl_light_geom_destroy(lg);
        hl_geom_destroy(g);
        hl_transport_destroy(t);
        t = NULL;
    }
    /* both of the kernel's walks were compared with the twin: the first
       transport's tiles are full enough for the tile walk, the second
       (48 terms a vertex) mostly takes the column walk */
    /* the GPU shape has one walk, a work-item a position: nothing to count */
    if (dots && gpu != 1) {
        printf("ranges walked by tile: %u, by column: %u\n", walks[0], walks[1]);
        HL_CHECK(walks[0] > 0 && walks[1] > 0, "both walks of the dot products tested");
        printf("tile walk words: %llu where every slot holds every tile, %llu testing the bits\n",
               (unsigned long long)words[0], (unsigned long long)words[1]);
        HL_CHECK(words[0] > 0 && words[1] > 0, "both ways of the tile walk tested");
    }
    hl_context_destroy(cl);
    hl_context_destroy(ref);
}

#endif
