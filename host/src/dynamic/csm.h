/* csm.h - convolution shadow maps (Annen et al. EGSR 2007) with the filter
 * width from the average blocker depth (Annen et al. SIGGRAPH 2008), and
 * moment shadow maps (Peters and Klein 2015) in the same module: the
 * module's API, its named constants and the plain-C twins of its kernels
 * (kernels/dynamic/csm_basis.cl, csm_sat.cl, csm_eval.cl, msm_basis.cl,
 * msm_eval.cl).
 *
 * The shadow test f(d, z) = [z >= d] is expanded as
 *     f ~= 1/2 + sum_k s_k (2 / (h c_k)) sin(c_k (z - d)),  c_k = pi (2k - 1) / h
 * a square wave of period 2h in t = z - d. DYNAMIC.md's h = 1 (period 2)
 * is wrong at |t| = 1 (f = 1/2 at d = 0, z = 1: a receiver on the near
 * plane under empty texels), so h = HL_CSM_HALF_PERIOD > 1 keeps the
 * second jump, at |t| = h, out of t in [-1, 1] (test_csm_basis.c, series).
 *
 * Images of one light: P = 2M + 2Mb + 1 planes of R x R floats,
 * interleaved by texel (texel (i, j) holds its P values at
 * ((j R + i) P + p), so one table corner is one run of P floats):
 *   p = 0                                   z
 *   p = 1 + 2 (k - 1), 2 + 2 (k - 1)        S_k = sin(c_k z), C_k = cos(c_k z), k = 1..M
 *   p = 1 + 2M + 2 (k - 1), 2 + 2M + 2 (k - 1)  z S_k, z C_k, k = 1..Mb (blocker search)
 * Each plane becomes a summed-area table of its values minus the plane's
 * mean (the mean is kept beside it).
 *
 * Depends on: hl_internal.h (core), dynamic.h (hl_shadow_frame).
 */
#ifndef HL_CSM_H
#define HL_CSM_H

#include <stddef.h>
#include <stdint.h>

#include "dynamic.h"
#include "hl_internal.h"

/* ---- constants (each: default and reason) ---- */

/* Order limits: below 4 the transition band (about 1.6 / M each side of
 * z = d) covers most of the depth range; above 16 the image count (and
 * memory) outgrows what a frame can afford (DYNAMIC.md section 4). */
#define HL_CSM_M_MIN 4u
#define HL_CSM_M_MAX 16u
#define HL_CSM_M_DEFAULT 16u
/* Map sizes: a multiple of HL_CSM_SCAN_LANES, 16 to 1024. The tables'
 * rounding grows as R^2 (worst box-sum error 0.006 at R = 256, 0.039 at
 * 512: test_csm_sat.c, precision); at 1024 about 0.16, which a 9 x 9 box
 * (the smallest read from the tables) turns into 2e-3 of each basis value;
 * beyond that the tables would need tiles or wider floats. */
#define HL_CSM_R_MIN 16u
#define HL_CSM_R_MAX 1024u
/* Lanes of one prefix-sum work-group (kernel and twin alike: the twin
 * repeats the lanes' order of additions so both round the same). Each
 * lane sums a contiguous run of R / 16 values (at most 64), then the 16
 * partial sums are scanned in 4 tree steps: short sequential runs keep
 * the rounding down, and 16 lanes fill a CPU core's vector. */
#define HL_CSM_SCAN_LANES 16u
/* Half-period h of the square wave (see the top): 1.25 keeps the second
 * jump 0.25 beyond |t| = 1; at M = 16 that leaves 0.004 of error at
 * |t| = 1, where h = 1 gives 0.5 (test_csm_basis.c, series). Larger h
 * widens the transition at t = 0 in proportion. */
#define HL_CSM_HALF_PERIOD 1.25f
/* Damping s_k = exp(-alpha (k/M)^2): alpha = 1 is the best of 0, 0.5, 1,
 * 2, 4 by the worst error outside the band |z - d| < 1.6 / M over M = 4,
 * 8, 16 (test_csm_basis.c, series: 0.035, against 0.054 undamped and 0.059
 * at alpha = 2); it cuts the Gibbs overshoot from 0.09 to 0.013 at
 * M = 16 and 0.004 at M = 8. */
#define HL_CSM_ALPHA 1.0f
/* Receiver depth bias against self-shadowing: d' = d - bias, bias =
 * HL_CSM_BIAS_M / M (normalised depth): the smooth test reaches 0.9998 at
 * t = 1/16 for M = 16, 0.993 at 1/8 for M = 8, 0.977 at 1/4 for M = 4, so
 * a lit surface that is itself in the map is not shadowed by its own
 * texels, nor taken for a blocker (1 - f below HL_CSM_BLOCKER_EPS)
 * (test_csm_eval.c, plane: acne). The price: a blocker less than about
 * 3/4 of the bias in front of a receiver is not seen (contact). */
#define HL_CSM_BIAS_M 1.0f
/* A search region whose blocker fraction (box average of 1 - f) is below
 * this has no blocker: fully lit. Above the series' residual for lit
 * texels (under 0.011 at M = 16, 0.014 at M = 8 outside the band), and a
 * fiftieth of the region: a blocker that small casts no visible shadow. */
#define HL_CSM_BLOCKER_EPS 0.02f
/* Smallest filter half-width, texels: half a texel, a one-texel box, the
 * map's own resolution (a narrower box only interpolates one texel). */
#define HL_CSM_MIN_HALF_WIDTH 0.5f
/* Boxes of half-width up to 4 texels (9 x 9 texels at most) are summed
 * texel by texel, the series evaluated per texel from its z, sin(c1 z)
 * and cos(c1 z) (kept beside the tables, 4 floats a texel): a
 * table's corner difference carries about eps x 1e4 = 1e-3 of rounding at
 * R = 256 (test_csm_sat.c), which a box of a few texels would turn into
 * 1e-3..1e-4 of noise in each basis value, and V would not be monotone
 * across a narrow penumbra. At 4 texels the tables' noise is below 1e-4
 * per value, and the direct sum's cost (81 texels x M terms) is still
 * near the tables' (16 reads x 6M + 1 planes). */
#define HL_CSM_DIRECT_HALF 4.0f
/* Contact-leak exponent V^p, p = 1 + A exp(-B (d - z_avg)): A = 30
 * (Annen's thesis) darkens V = 0.9 to 0.04 at contact. B = 20, chosen in
 * test_csm_eval.c (contact) as the largest of 5, 10, 15, 20 that keeps
 * receivers 3/4 of the bias to 0.03 beyond it behind a blocker dark
 * (V < 0.05; 0.037 at B = 20): the largest bends a penumbra further from
 * its blocker least (p - 1 = 0.55 at d - z_avg = 0.2, 0.01 at 0.4; B = 10
 * gives 4.1 and 0.55). */
#define HL_CSM_LEAK_A 30.0f
#define HL_CSM_LEAK_B 20.0f

/* ---- moment shadow maps (Peters and Klein 2015), the lighter form ----
 *
 * The same module holds either representation (hl_csm_create_rep): for
 * moments P = 5 planes, the moments x, x^2, x^3, x^4 of x = 2 z - 1 and
 * the coverage (1 for a caster's texel, 0 for an empty one),
 * interleaved by texel, with the same mean-subtracted summed-area tables
 * (csm_sat.cl); zsc holds each texel's four moments (msm_basis.cl). The
 * visibility is msm_eval.cl's (DYNAMIC.md section 3b). */
/* DEFAULT (0) is resolved by the frame (dyn_frame.h, HL_FRAME_DEFAULT_SHADOW);
 * the module itself takes CSM or MOMENTS. */
typedef enum hl_shadow_rep { HL_SHADOW_REP_DEFAULT = 0, HL_SHADOW_REP_CSM = 1, HL_SHADOW_REP_MOMENTS = 2 } hl_shadow_rep;
#define HL_MSM_PLANES 5u
/* Moment bias alpha: the moments are blended with weight alpha towards
 * the uniform distribution's on [-1, 1], (0, 1/3, 0, 1/5), whose Hankel
 * matrix has smallest eigenvalue 0.079, so the blended matrix's is at
 * least 0.079 alpha. That must exceed the moments' rounding, or the
 * Cholesky sees a matrix that is not positive definite: the worst box
 * average's error from the float tables, measured in test_msm.c
 * (precision), times a margin; see the value's note in msm.c's
 * hl_msm_params. Peters and Klein's 3e-5 is for 16-bit moments (rounding
 * 1.5e-5) on [0, 1]. Larger alpha leaks more light (the bound loosens). */
#define HL_MSM_ALPHA 1e-4f
/* Receiver depth bias (normalised depth): the bound is a sharp step at
 * the receiver when the moments are exact, so the bias only has to cover
 * the moments' rounding and alpha's spread, not the Fourier series' band
 * (CSM's 1/M = 0.0625); the receiver-plane bias (hl_dyn_receiver) covers
 * the receiver's own slope. Chosen in test_dyn_reference accuracy. */
#define HL_MSM_BIAS 0.005f
/* Light-leak reduction: V below this is taken as 0 and V rescaled
 * (V - l) / (1 - l). 0: off. */
#define HL_MSM_LBR 0.1f
/* The contact exponent V^p, p = 1 + A exp(-B (d - z_avg)), as CSM's; A = 0
 * turns it off. */
#define HL_MSM_LEAK_A 0.0f
#define HL_MSM_LEAK_B 20.0f
/* The far band: casters' depths z map to x = 2 z (1 - band) - 1 and
 * empty texels to x = 1, so the band (1 - band, 1] of z' = (x + 1) / 2
 * holds no caster; receivers beyond the far plane (the ground under the
 * bodies) are put at its middle, 1 - band / 2. Without it they sat at
 * 1 - bias, just in front of the empty texels' mass at 1, and the bound
 * let light leak from that mass through the bodies' contact shadows
 * (test_dyn_reference accuracy: the ground near the bunny). */
#define HL_MSM_FAR_BAND 0.125f
/* The small boxes' per-texel test (msm_eval.cl, hl_msm_count; DYNAMIC.md
 * section 3b): boxes of half-width up to HL_CSM_DIRECT_HALF texels test
 * each texel's caster against the receiver's tangent plane there, less
 * HL_MSM_TEXEL_BIAS times the plane's depth change across a texel
 * (|dz/du| + |dz/dv|) and HL_MSM_TEXEL_FLOOR texels' width, with no
 * constant depth bias (HL_MSM_SMALL_BIAS), in place of the bound with
 * HL_MSM_BIAS and the receiver-plane bias's worst corner, which left
 * blockers nearer than those biases unseen (layered parts, contact).
 * Half a texel is the most a plane's own texel centres differ from it;
 * the floor covers what the plane does not: a body out of the map (no
 * plane given) beside a wall standing on it, and the facets around a
 * smoothed normal (BoxAnimated under the sky 2.70% without it, 2.06%
 * with; the bunny's table: 0.5 texel on the sky and the maps chosen).
 * HL_MSM_PER_TEXEL: 0 off, 1 on, 2 on with the leak reduction applied to
 * the count as to the bound (chosen: no row of the bunny's table worse,
 * where 1 made forest worse). Where the large search box finds no
 * blocker, a near search of HL_MSM_NEAR_HALF texels (0: none) looks
 * texel by texel (1 to 4 measured the same). */
#define HL_MSM_PER_TEXEL 2.0f
#define HL_MSM_TEXEL_BIAS 0.5f
#define HL_MSM_SMALL_BIAS 0.0f
#define HL_MSM_NEAR_HALF 1.0f
#define HL_MSM_TEXEL_FLOOR 0.5f
/* floats of msm_eval.cl's parameter block */
#define HL_MSM_PRM_FLOATS 17u

/* planes of one light */
static inline uint32_t hl_csm_planes(uint32_t M, uint32_t Mb) { return 2 * M + 2 * Mb + 1; }
/* bytes of one light on the device: tables, depth map, texel phases
 * (4 floats a texel), row sums and means */
size_t hl_csm_bytes_per_light(uint32_t R, uint32_t M, uint32_t Mb);

/* ---- module API ---- */

typedef struct hl_csm hl_csm;

/* Creates a module for maps of R x R texels, order M (4..16; 0: 16) and
 * blocker-search order Mb (4..M; 0: M), holding up to K_max lights at once
 * (one batch). Mb = 8 under M = 16 saves about a fifth of the build and
 * of the memory (49 planes, not 65) and 5 to 20% of the evaluation on
 * PoCL, but its wider band misses blockers within 1/8 of the receiver:
 * against Mb = 16, V moves by 0.01 on average and 0.13 to 0.37 at the
 * 99th percentile on a scene of square blockers; hence the default
 * Mb = M. On an OpenCL context the batch lives on the device between
 * hl_csm_build and hl_csm_visibility; on the reference backend in host
 * memory (the twins). Fails (HL_ERR_OUT_OF_MEMORY) when a batch does not
 * fit the device memory limit: choose K_max with hl_csm_batch_fit, then
 * build and evaluate the lights K_max at a time (18.4 MB a light at
 * R = 256, M = Mb = 16: 32 lights would need 589 MB). */
hl_result hl_csm_create(hl_context *ctx, uint32_t R, uint32_t M, uint32_t Mb, uint32_t K_max, hl_csm **out);
/* hl_csm_create for either representation (M and Mb are checked and kept
 * for CSM only; moments take 4 planes whatever they are). */
hl_result hl_csm_create_rep(hl_context *ctx, hl_shadow_rep rep, uint32_t R, uint32_t M, uint32_t Mb, uint32_t K_max,
                            hl_csm **out);
size_t hl_csm_bytes_per_light_rep(hl_shadow_rep rep, uint32_t R, uint32_t M, uint32_t Mb);
uint32_t hl_csm_batch_fit_rep(hl_shadow_rep rep, uint32_t R, uint32_t M, uint32_t Mb, uint64_t bytes);
hl_shadow_rep hl_csm_rep(const hl_csm *c);
/* The most lights a batch can hold within `bytes` (at least 1). */
uint32_t hl_csm_batch_fit(uint32_t R, uint32_t M, uint32_t Mb, uint64_t bytes);
void hl_csm_destroy(hl_csm *c);

/* Basis images and summed-area tables of K (<= K_max) maps of R x R
 * normalised depths (K R^2 floats, light after light, row-major). Depths
 * above 1 count as 1 (nothing blocks); NaN, Inf or negative depths fail. */
hl_result hl_csm_build(hl_csm *c, const float *depth, uint32_t K);

/* For the tests: hl_csm_build stopped after stage `upto` (1: basis planes
 * and plane means, 2: and the row sums, 3: all: the tables), and a copy of
 * light k's planes (P R^2 floats, interleaved as above), means (P) and,
 * when zsc is not NULL, texels' (z, sin, cos, 0) (4 R^2) from the device
 * or the host. */
enum { HL_CSM_UPTO_BASIS = 1, HL_CSM_UPTO_ROWS = 2, HL_CSM_UPTO_ALL = 3 };
hl_result hl_csm_build_upto(hl_csm *c, const float *depth, uint32_t K, int upto);
hl_result hl_csm_read_planes(hl_csm *c, uint32_t k, float *planes, float *means, float *zsc);
/* module sizes (after defaults): R, M, Mb, planes per light */
void hl_csm_sizes(const hl_csm *c, uint32_t *R, uint32_t *M, uint32_t *Mb, uint32_t *P);

/* Visibility of light k (< K of the last build) at n receivers: uvd holds
 * 3 floats each (texel coordinates u, v, continuous, texel (i, j) covering
 * [i, i+1) x [j, j+1), and normalised depth d, as hl_dyn_receiver gives).
 * theta: the light's angular half-extent (radians, [0, pi/2)); f its
 * frame (width, height, depth_range; f->R must equal the module's R).
 * A receiver outside the map is taken at the map's nearest edge; depths
 * above 1 count as 1 (the far plane), below the map's nearest depth are
 * lit. V gets n values in [0, 1]; zavg, when not NULL, gets the average
 * blocker depth (-1 where no blocker was found). */
hl_result hl_csm_visibility(hl_csm *c, uint32_t k, float theta, const hl_shadow_frame *f, const float *uvd, uint32_t n,
                            float *V, float *zavg);

/* Several lights of the last build at once: entry j (of nl) is light
 * ks[j], half-extent thetas[j], frame frames[j], at receivers start[j] ..
 * start[j + 1] - 1 (start: nl + 1 of them, rising) of uvd, V and zavg
 * (may be NULL), each indexed by the receiver as uvd is. The same values
 * as hl_csm_visibility light by light, but on the device one upload, one
 * launch and one read-back for all of them (a frame's round trips were
 * one a light). rpl: the receivers' planes (HL_DYN_RPL floats each,
 * hl_dyn_receiver; the moments' small boxes read them), indexed as uvd;
 * NULL: planes facing the light at uvd's depths. hl_csm_visibility
 * passes NULL. */
hl_result hl_csm_visibility_batch(hl_csm *c, uint32_t nl, const uint32_t *ks, const float *thetas,
                                  const hl_shadow_frame *const *frames, const float *uvd, const float *rpl,
                                  const uint32_t *start, float *V, float *zavg);


/* On an OpenCL context, hl_csm_build of maps already in device memory
 * (depth, a cl_mem of K R^2 floats, as hl_shadow_maps_render leaves them
 * with no host array: depths in [0, 1], not checked again); each map's
 * nearest depth is found on the device (hl_csm_zmin) and kept there too. */
hl_result hl_csm_build_on_device(hl_csm *c, void *depth, uint32_t K);
/* The device frame's evaluation (dyn_frame.c): entries 0 .. nl - 1 of a
 * group, entry j light ks[j] of the last build with half-extent thetas[j]
 * and frame frames[j], each at N receivers: uvd and V are cl_mems of
 * nl N 3 and nl N floats, entry j's receiver v at j N + v, as
 * hl_dyn_prepare leaves uvd (u = NaN: not reached, V not written), rpl
 * a cl_mem of their planes, nl N HL_DYN_RPL floats (moments need it; CSM
 * does not read it).
 * Enqueued, not waited for. */
hl_result hl_csm_eval_grid(hl_csm *c, uint32_t nl, const uint32_t *ks, const float *thetas,
                           const hl_shadow_frame *const *frames, void *uvd, void *rpl, uint32_t N, void *V);
/* The device buffer (a cl_mem) of each map's nearest depth, K floats, as
 * the last hl_csm_build_on_device found them. */
void *hl_csm_zmin_buffer(const hl_csm *c);

/* ---- twins (kernels/dynamic/csm_*.cl), one work-item each ---- */

/* Eval parameters of one light, computed on the host for both sides. */
typedef struct hl_csm_eval_params {
    uint32_t R, M, Mb;
    float zmin;      /* the map's smallest depth: z_near of the search */
    float su, sv;    /* texels per unit of normalised depth behind a
                        blocker: depth_range tan(theta) R / width (height) */
    float bias, bias_b; /* receiver depth bias of the filter (1/M) and the
                           search (1/Mb) */
    float eps, wmin, leak_a, leak_b;
    float c1;        /* c_1 = pi / h */
    float direct_half; /* boxes up to this half-width (texels) are summed
                          texel by texel */
    float coef[HL_CSM_M_MAX];  /* s_k 2 / (h c_k), order M */
    float coefb[HL_CSM_M_MAX]; /* the same with s_k over Mb */
} hl_csm_eval_params;

void hl_csm_params(hl_csm_eval_params *p, uint32_t R, uint32_t M, uint32_t Mb, float zmin, float su, float sv);

/* hl_csm_basis: one row of one map (depth: the light's R x R map) to its
 * texels' P values (img: the light's interleaved planes), each plane's
 * row sum (rowsum[plane * R + row]) and the texels' (z, sin(c1 z),
 * cos(c1 z), 0) (zsc, 4 R^2 floats a light). c1 = pi / h. */
void hl_ref_csm_basis(const float *depth, uint32_t R, uint32_t M, uint32_t Mb, float c1, uint32_t row, float *img,
                      float *rowsum, float *zsc);
/* hl_csm_sat_mean: a plane's mean from its R row sums. */
float hl_ref_csm_sat_mean(const float *rowsum, uint32_t R);
/* hl_csm_sat_scan: inclusive prefix sum of one line of R values at
 * base[i * step], minus `sub` first (0 for the column pass), in
 * HL_CSM_SCAN_LANES runs and a tree over the runs' sums. */
void hl_ref_csm_sat_scan(float *base, size_t step, uint32_t R, float sub);
/* hl_csm_eval_one (csm_eval.cl): one receiver (u, v, d) against one light's tables, means
 * and texels' (z, sin(c1 z), cos(c1 z), 0) (zsc); out[0] = V, out[1] =
 * z_avg or -1. */
void hl_ref_csm_eval(const float *sat, const float *mean, const float *zsc, const hl_csm_eval_params *p,
                     const float uvd[3], float out[2]);

/* ---- moment twins (kernels/dynamic/msm_*.cl) ---- */

typedef struct hl_msm_eval_params {
    uint32_t R;
    float zmin, su, sv; /* as hl_csm_eval_params */
    float bias, eps, wmin, alpha, leak_a, leak_b, lbr, direct_half;
    float kb; /* 1 - HL_MSM_FAR_BAND */
    /* the small boxes' per-texel test (msm_eval.cl, hl_msm_count): on
       above 0 (above 1: with the leak reduction too), the bias in texels
       along the plane, the near search's half-width (texels, 0: none),
       the constant depth bias there, and one of HL_MSM_TEXEL_FLOOR texels
       (normalised depth: that many texels' width) */
    float ptex, tbias, near_half, sbias, tfloor;
} hl_msm_eval_params;

/* texel: the map's texel in normalised depth (hl_shadow_frame_texel),
 * the unit of the per-texel floor */
void hl_msm_params(hl_msm_eval_params *p, uint32_t R, float zmin, float su, float sv, float texel);
/* hl_msm_basis: one row of one map to its texels' four moments (img and
 * zsc, 4 floats a texel) and each plane's row sum (rowsum[plane R + row]). */
void hl_ref_msm_basis(const float *depth, uint32_t R, float kb, uint32_t row, float *img, float *rowsum, float *zsc);
/* The Hamburger 4MSM bound (msm_eval.cl, hl_msm_bound): the least
 * shadowed share of moments m at receiver xf (x = 2 z - 1) after the
 * blend alpha; wb and xb (may be NULL) the blocker weight and mean x. */
float hl_ref_msm_bound(const float m[4], float xf, float alpha, float *wb, float *xb);
/* hl_msm_eval_one: out[0] = V, out[1] = z_avg or -1. rpl: the
 * receiver's plane (HL_DYN_RPL floats, hl_dyn_receiver), or NULL for a
 * plane facing the light at uvd's depth. */
void hl_ref_msm_eval(const float *sat, const float *mean, const float *zsc, const hl_msm_eval_params *p,
                     const float uvd[3], const float *rpl, float out[2]);

#endif
