/* sh.h - real spherical harmonics about +Y, and their integrals over the
 * paraboloid maps' texels (the projection of a cell-integrated map).
 *
 * Order n means the bands l = 0 .. n-1: n^2 functions, index
 * k = l^2 + l + m (-l <= m <= l), as Sloan, Kautz and Snyder (2002) count
 * them ("order 20": 400 coefficients). The polar axis is +Y, the
 * project's up (docs/CONVENTIONS.md); the azimuth is phi = atan2(z, x), the
 * equirectangular map's, so a turn of the map about +Y mixes only the
 * (m, -m) pairs of each band:
 *   Y_l0  = P~_l^0(y)
 *   Y_lm  = sqrt 2 P~_l^m(y) cos(m phi)      m > 0
 *   Y_l-m = sqrt 2 P~_l^m(y) sin(m phi)      m > 0
 * with P~ the associated Legendre functions normalised so that the Y are
 * orthonormal on the sphere, Condon-Shortley phase included (Y_11 =
 * -sqrt(3 / 4 pi) x), evaluated by the standard normalised three-term
 * recurrences in double (no factorials: stable to order 32 and beyond).
 *
 * Depends on core (hl_internal.h) and maps/geom.h (the paraboloid texels).
 */
#ifndef HL_SH_H
#define HL_SH_H

#include "hl_internal.h"

/* The largest order the tables hold: 32 (1024 coefficients) is more than
 * any comparison here asks for (20) and keeps the tables a few KiB. */
#define HL_SH_MAX_ORDER 32u

/* Gauss-Legendre points per dimension of each piece of a texel's
 * footprint (hl_sh_texel_points). Measured at order 20 (hl.sh.convergence,
 * worst error of a texel's mean of Y_lm against Q = 16, in units of
 * sqrt((2l + 1) / 4 pi) >= |Y_lm|): Q = 4, 6, 8 give 2.6e-7, 3.5e-12,
 * 8e-15 at N = 32 and 1.5e-9, 2.6e-14, 1.3e-14 at N = 64. 10 keeps a margin
 * for order 32 and N = 16 at 1.6 times the work of 8. */
#define HL_SH_QUAD 10u

/* Most Gauss-Legendre points one piece may use per dimension. */
#define HL_SH_MAX_QUAD 32u

/* Most pieces a rim texel's footprint is cut into (the disc's rim may
 * cross the texel's two inner edges, twice each on the outer axis). */
#define HL_SH_MAX_PIECES 5u

/* The recurrence coefficients of one order, computed once. */
typedef struct hl_sh_tables {
    uint32_t order;
    double a[HL_SH_MAX_ORDER * HL_SH_MAX_ORDER]; /* [l * MAX + m] */
    double b[HL_SH_MAX_ORDER * HL_SH_MAX_ORDER];
    double mm[HL_SH_MAX_ORDER];                 /* P~_m^m / sin^m theta */
} hl_sh_tables;

/* order^2: the coefficient count of an order. */
static inline uint32_t hl_sh_count(uint32_t order) { return order * order; }

/* Fills the tables of an order (1 .. HL_SH_MAX_ORDER; 0 when out of
 * range, else 1). */
int hl_sh_tables_init(hl_sh_tables *tab, uint32_t order);

/* Y_k(d) for k < order^2 into Y; d of unit length. */
void hl_sh_eval(const hl_sh_tables *tab, const double d[3], double *Y);

/* Q Gauss-Legendre nodes and weights on [-1, 1] (1 <= Q <= HL_SH_MAX_QUAD). */
void hl_sh_gauss(uint32_t Q, double *x, double *w);

/* The quadrature of texel (col, row) of paraboloid map `map` (N x N, as
 * geom.h) over its footprint on the sphere: points, 4 doubles each (unit
 * direction, weight = the paraboloid's solid-angle factor 4 / (1 + s^2 +
 * t^2)^2 times the Gauss weights), over the part of the texel inside the
 * unit disc only. A texel wholly inside is one Q x Q tensor rule; a rim
 * texel is cut where the rim crosses its edges so that every piece is
 * smooth, each piece Q x Q, the inner limits following the rim. pts:
 * room for HL_SH_MAX_PIECES * Q * Q points. Returns the point count (0
 * outside the disc). */
uint32_t hl_sh_texel_points(uint32_t N, int map, uint32_t col, uint32_t row, uint32_t Q, double *pts);

/* Ybar[j * order^2 + k] = integral of Y_k over texel j (j = map N^2 +
 * row N + col, geom.h's texel order) by hl_sh_texel_points with Q points,
 * on ctx's threads. *out: 2 N^2 order^2 doubles (hl_free_big). */
hl_result hl_sh_texel_integrals(hl_context *ctx, uint32_t N, uint32_t order, uint32_t Q, double **out);

/* l_k = sum_j L_j Ybar_jk for the ntex texels of values L (stride apart):
 * the exact projection of the map whose texel j holds the mean L_j. */
void hl_sh_project(const double *Ybar, uint32_t ntex, uint32_t count, const float *L, size_t stride, double *l);

/* Rotates coefficients c (order^2) in place for a turn of the function
 * about +Y by `angle` radians, from +X towards +Z: f'(theta, phi) =
 * f(theta, phi - angle), phi = atan2(z, x) growing by angle (the
 * project's --rotate turns the other way, right-handed). */
void hl_sh_rotate_y(uint32_t order, double angle, double *c);

/* The row stride of hl_sh_matrix: order^2 rounded up to a multiple of 4
 * (the device reads four coefficients at a time). */
static inline uint32_t hl_sh_stride(uint32_t order) { return (hl_sh_count(order) + 3u) & ~3u; }

/* The matrix of the relight pipeline's projection (kernels/maps/
 * sh_project.cl): Y[j * stride + k], j < 2 N^2, k < order^2 (the padding
 * columns zero), in float, from the integrals of hl_sh_texel_integrals
 * with HL_SH_QUAD points, rounded once. per_solid_angle 0: Ybar_jk (a
 * lighting map of texel means projects to l_k = sum_j L_j Ybar_jk); 1:
 * Ybar_jk / Omega_j, Omega_j = sqrt(4 pi) Ybar_j0 the same quadrature's
 * solid angle, 0 outside the disc (a transport row T_j stands for the
 * function T_j / Omega_j). *out: hl_free_big. */
hl_result hl_sh_matrix(hl_context *ctx, uint32_t N, uint32_t order, int per_solid_angle, float **out);

#endif
