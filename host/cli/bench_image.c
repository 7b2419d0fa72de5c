/* bench_image.c - `haarlight bench --image`: errors in image space, as the
 * 2003 paper measured them, and temporal stability under a turning map.
 *
 * For every transport file, environment and M (the first selection
 * scheme): the picture from the default camera (black background, so that
 * only the object and its ground count) of the relit colours against the
 * picture of the exact colours of every vertex (untruncated, unquantised
 * transport and lighting in float64): the relative L2 error, and the
 * relative Sobolev H1 error, which adds the gradients' error (forward
 * differences between neighbouring pixels), so that noise and banding
 * weigh more than a smooth offset. Then, under the first environment
 * turned by one pixel column a frame: the mean frame-to-frame change of
 * the relit picture beyond the exact picture's own change,
 * mean |(A[k+1] - A[k]) - (R[k+1] - R[k])| over mean |R[k]|: the popping
 * the paper warns of when the kept terms change.
 *
 * Depends on: the public API and haarlight_tools.h (the exact reference),
 * cli.h.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "haarlight_tools.h"

/* Vertices whose exact transport is held at once: 4096 rows of 2 N^2
 * floats, 128 MiB at N = 64. */
#define IMAGE_BATCH 4096u

/* Sums over a picture pair: |e|^2, |r|^2 and their gradients' (e = a - r;
 * forward differences in x and y, each pair inside the picture). */
typedef struct img_sums {
    double e2, r2, ge2, gr2;
} img_sums;

static img_sums compare(const hl_image *a, const hl_image *r)
{
    img_sums s = {0, 0, 0, 0};
    const uint32_t W = r->width, H = r->height;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                const size_t i = 3 * ((size_t)y * W + x) + (size_t)c;
                const double e = (double)a->rgb[i] - r->rgb[i];
                s.e2 += e * e;
                s.r2 += (double)r->rgb[i] * r->rgb[i];
                if (x + 1 < W) {
                    const size_t j = i + 3;
                    const double ge = e - ((double)a->rgb[j] - r->rgb[j]), gr = (double)r->rgb[i] - r->rgb[j];
                    s.ge2 += ge * ge;
                    s.gr2 += gr * gr;
                }
                if (y + 1 < H) {
                    const size_t j = i + 3 * (size_t)W;
                    const double ge = e - ((double)a->rgb[j] - r->rgb[j]), gr = (double)r->rgb[i] - r->rgb[j];
                    s.ge2 += ge * ge;
                    s.gr2 += gr * gr;
                }
            }
    return s;
}

/* |(a1 - a0) - (r1 - r0)|^2, |r1 - r0|^2 and |r0|^2 over the picture. */
static void change(const hl_image *a0, const hl_image *a1, const hl_image *r0, const hl_image *r1, double *d2,
                   double *rd2, double *r02)
{
    *d2 = *rd2 = *r02 = 0.0;
    const size_t n = (size_t)r0->width * r0->height * 3;
    for (size_t i = 0; i < n; i++) {
        const double dr = (double)r1->rgb[i] - r0->rgb[i], d = ((double)a1->rgb[i] - a0->rgb[i]) - dr;
        *d2 += d * d;
        *rd2 += dr * dr;
        *r02 += (double)r0->rgb[i] * r0->rgb[i];
    }
}

/* env turned by k pixel columns (an exact turn of an equirectangular map). */
static hl_result turned(hl_context *ctx, const hl_env *env, uint32_t k, hl_env **out)
{
    const uint32_t W = env->width, H = env->height;
    float *rgb = malloc((size_t)W * H * 12);
    if (!rgb) return HL_ERR_OUT_OF_MEMORY;
    for (uint32_t y = 0; y < H; y++)
        for (uint32_t x = 0; x < W; x++)
            memcpy(rgb + 3 * ((size_t)y * W + (x + k) % W), env->rgb + 3 * ((size_t)y * W + x), 12);
    hl_result r = hl_env_create(ctx, W, H, rgb, out, NULL);
    free(rgb);
    return r;
}

/* The picture of per-vertex colours (doubles when d is set, else floats). */
static hl_result picture(const bench_image_in *in, const hl_transport *t, const double *d, const float *f, float *tmp,
                         hl_image **out)
{
    const uint32_t V = t->info.vertex_count;
    if (d)
        for (size_t i = 0; i < (size_t)V * 3; i++) tmp[i] = (float)d[i];
    hl_camera_desc cam = {.width = in->width, .height = in->height};
    return hl_render(in->ref, t->mesh, d ? tmp : f, NULL, 0.0f, &cam, out);
}

static void print_m(char *s, size_t n, uint32_t M)
{
    if (M == HL_TERMS_ALL) snprintf(s, n, "all");
    else snprintf(s, n, "%u", M);
}

/* The exact pictures: exact[e] under environment e, then frames - 1 turns
 * of the first. */
static hl_result exact_pictures(const bench_image_in *in, const hl_env *const *envs, int n, float *tmp,
                                hl_image **exact)
{
    const hl_transport *t = in->t[0];
    const uint32_t V = t->info.vertex_count;
    uint32_t *idx = malloc((size_t)V * 4);
    double **col = calloc((size_t)n, sizeof *col);
    hl_result r = idx && col ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    for (int e = 0; e < n && r == HL_OK; e++)
        if (!(col[e] = malloc((size_t)V * 3 * sizeof(double)))) r = HL_ERR_OUT_OF_MEMORY;
    for (uint32_t v = 0; idx && v < V; v++) idx[v] = v;
    fprintf(stderr, "bench: --image: exact transport of all %u vertices under %d maps\n", V, n);
    double **at = calloc((size_t)n, sizeof *at);
    if (r == HL_OK && !at) r = HL_ERR_OUT_OF_MEMORY;
    /* in batches: the exact rows of a batch are held whole (ncoef floats
       each) */
    for (uint32_t v0 = 0; v0 < V && r == HL_OK; v0 += IMAGE_BATCH) {
        const uint32_t nb = V - v0 < IMAGE_BATCH ? V - v0 : IMAGE_BATCH;
        for (int e = 0; e < n; e++) at[e] = col[e] + (size_t)v0 * 3;
        r = hl_bench_ref_colours(in->br, idx + v0, nb, NULL, 0, envs, n, at, NULL);
    }
    free(at);
    for (int e = 0; e < n && r == HL_OK; e++) r = picture(in, t, col[e], NULL, tmp, &exact[e]);
    for (int e = 0; col && e < n; e++) free(col[e]);
    free(col);
    free(idx);
    return r;
}

/* Image errors of file f: one row per environment and M, then the
 * popping per M under the turning first map (envs[nenvs ..] its turns). */
static hl_result file_rows(const bench_image_in *in, int f, const hl_env *const *envs, hl_image **exact, float *tmp,
                           FILE *md)
{
    const hl_transport *t = in->t[f];
    hl_relighter *rl = NULL;
    hl_result r = hl_relighter_create(in->cl, t, &rl);
    const char *name = bench_base_name(in->files[f]);
    for (int e = 0; e < in->nenvs && r == HL_OK; e++) {
        r = hl_relighter_set_env(rl, envs[e]);
        for (uint32_t m = 0; m < in->nterms && r == HL_OK; m++) {
            hl_relight_desc d = {.terms = in->terms[m], .select = in->select};
            hl_image *img = NULL;
            r = hl_relighter_run(rl, &d, tmp, NULL);
            if (r == HL_OK) r = picture(in, t, NULL, tmp, tmp + (size_t)t->info.vertex_count * 3, &img);
            if (r != HL_OK) break;
            img_sums s = compare(img, exact[e]);
            hl_image_destroy(img);
            char ms[16];
            print_m(ms, sizeof ms, in->terms[m]);
            const double l2 = s.r2 > 0 ? sqrt(s.e2 / s.r2) : 0.0, h1 = s.r2 + s.gr2 > 0 ? sqrt((s.e2 + s.ge2) / (s.r2 + s.gr2)) : 0.0;
            fprintf(md, "| %s | %s | %s | %.3f%% | %.3f%% |\n", name, in->envs[e].name, ms, 100 * l2, 100 * h1);
            printf("bench: %s under %s, M = %s: image L2 %.3f%%, H1 %.3f%%\n", name, in->envs[e].name, ms, 100 * l2,
                   100 * h1);
        }
    }
    hl_relighter_destroy(rl);
    return r;
}

static hl_result popping_rows(const bench_image_in *in, int f, const hl_env *const *envs, hl_image **exact, float *tmp,
                              FILE *md)
{
    const hl_transport *t = in->t[f];
    const uint32_t F = in->frames;
    hl_relighter *rl = NULL;
    hl_image **a = calloc(F, sizeof *a);
    hl_result r = a ? hl_relighter_create(in->cl, t, &rl) : HL_ERR_OUT_OF_MEMORY;
    const char *name = bench_base_name(in->files[f]);
    for (uint32_t m = 0; m < in->nterms && r == HL_OK; m++) {
        hl_relight_desc d = {.terms = in->terms[m], .select = in->select};
        for (uint32_t k = 0; k < F && r == HL_OK; k++) {
            r = hl_relighter_set_env(rl, envs[k ? in->nenvs + (int)k - 1 : 0]);
            if (r == HL_OK) r = hl_relighter_run(rl, &d, tmp, NULL);
            hl_image_destroy(a[k]);
            a[k] = NULL;
            if (r == HL_OK) r = picture(in, t, NULL, tmp, tmp + (size_t)t->info.vertex_count * 3, &a[k]);
        }
        if (r != HL_OK) break;
        double pop = 0.0, own = 0.0, norm = 0.0;
        for (uint32_t k = 0; k + 1 < F; k++) {
            const hl_image *r0 = exact[k ? in->nenvs + (int)k - 1 : 0], *r1 = exact[in->nenvs + (int)k];
            double d2, rd2, r02;
            change(a[k], a[k + 1], r0, r1, &d2, &rd2, &r02);
            pop += sqrt(d2);
            own += sqrt(rd2);
            norm += sqrt(r02);
        }
        char ms[16];
        print_m(ms, sizeof ms, in->terms[m]);
        const double p = norm > 0 ? pop / norm : 0.0, o = norm > 0 ? own / norm : 0.0;
        fprintf(md, "| %s | %s | %.4f%% | %.4f%% |\n", name, ms, 100 * p, 100 * o);
        printf("bench: %s under %s turning, M = %s: frame-to-frame change beyond the exact one %.4f%% (the exact "
               "change itself %.4f%%)\n", name, in->envs[0].name, ms, 100 * p, 100 * o);
    }
    for (uint32_t k = 0; a && k < F; k++) hl_image_destroy(a[k]);
    free(a);
    hl_relighter_destroy(rl);
    return r;
}

hl_result bench_image(const bench_image_in *in, FILE *md)
{
    const int n = in->nenvs + (int)in->frames - 1;
    const hl_env **envs = calloc((size_t)n, sizeof *envs);
    hl_env **made = calloc(in->frames, sizeof *made);
    hl_image **exact = calloc((size_t)n, sizeof *exact);
    const uint32_t V = in->t[0]->info.vertex_count;
    float *tmp = malloc((size_t)V * 24);
    hl_result r = envs && made && exact && tmp ? HL_OK : HL_ERR_OUT_OF_MEMORY;
    for (int e = 0; r == HL_OK && e < in->nenvs; e++) envs[e] = in->envs[e].env;
    for (uint32_t k = 1; r == HL_OK && k < in->frames; k++) {
        r = turned(in->ref, in->envs[0].env, k, &made[k]);
        envs[in->nenvs + (int)k - 1] = made[k];
    }
    if (r == HL_OK) r = exact_pictures(in, envs, n, tmp, exact);
    if (r == HL_OK) {
        fprintf(md, "\n## Image-space errors (`--image`)\n\n"
                    "The picture from the default camera (%u x %u, black background) of the relit colours against\n"
                    "the picture of every vertex's exact colours (untruncated, unquantised transport and lighting,\n"
                    "float64), %s selection: relative L2, and relative Sobolev H1 (the same with the gradients'\n"
                    "error added: forward differences between neighbouring pixels).\n\n"
                    "| file | env | M | L2 | H1 |\n|---|---|---|---|---|\n",
                in->width, in->height, select_name(in->select));
    }
    for (int f = 0; f < in->nfiles && r == HL_OK; f++) r = file_rows(in, f, envs, exact, tmp, md);
    if (r == HL_OK && in->frames > 1)
        fprintf(md, "\n## Temporal stability under a turning map\n\n"
                    "%s turned one pixel column (%.3f degrees) a frame, %u frames: the mean over frames of\n"
                    "|(A[k+1] - A[k]) - (R[k+1] - R[k])|, the relit pictures' change beyond the exact pictures',\n"
                    "over the mean |R[k]|; and the exact change itself, |R[k+1] - R[k]|, on the same scale.\n\n"
                    "| file | M | change beyond the exact | exact change |\n|---|---|---|---|\n",
                in->envs[0].name, 360.0 / in->envs[0].env->width, in->frames);
    for (int f = 0; f < in->nfiles && r == HL_OK && in->frames > 1; f++) r = popping_rows(in, f, envs, exact, tmp, md);
    for (int e = 0; exact && e < n; e++) hl_image_destroy(exact[e]);
    for (uint32_t k = 0; made && k < in->frames; k++) hl_env_destroy(made[k]);
    free(exact);
    free(made);
    free(envs);
    free(tmp);
    return r;
}
