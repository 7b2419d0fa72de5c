/* scene_anim.c - how a dynamic scene moves: sampling the chosen
 * animation's channels (linear positions, shorter-arc slerp rotations,
 * clamped at the ends), composing the node hierarchy into each body's
 * rigid world transform, the program's transforms, and world bounds.
 * Reading the chosen animation from assimp's scene is here too, with the
 * check that it keeps every body rigid.
 *
 * Depends on: scene.h, hl_internal.h (errors, allocation), assimp's scene
 * types (anim.h), libm.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <assimp/scene.h>

#include "scene.h"

/* Above this cosine between two rotation keys slerp's weights divide by a
 * sine near 0 (1e-12 of cosine is about 1.4e-6 rad); normalised linear
 * interpolation is then exact to well below float precision. */
#define DYN_SLERP_LINEAR_DOT (1.0 - 1e-12)
/* The polar iteration stops when an update moves no entry by more than
 * this (double rounding keeps it from reaching 0), or after the cap: the
 * Newton iteration converges quadratically, so 60 is never reached for a
 * matrix whose condition number a float mesh can have. */
#define DYN_POLAR_TOL 1e-15
#define DYN_POLAR_MAX_ITER 60
/* assimp's convention where a file gives 0 ticks per second: its own
 * viewer (AnimEvaluator) plays such an animation at 25 ticks a second. */
#define DYN_DEFAULT_TICKS_PER_SECOND 25.0
/* Scaling keys equal to this relative difference count as one constant
 * scale (exporters write float noise); anything more changes over time. */
#define DYN_SCALE_TOL 1e-6
/* Rotation keys whose |cos| of half the angle between them is above this
 * are one rotation (about 3e-4 rad apart: exporter noise, not motion). */
#define DYN_SAME_ROT_DOT (1.0 - 1e-8)

/* ---------------------------------------------------------------- 3x3 and 3x4 algebra */

static void mat3_mul(const double a[9], const double b[9], double o[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) o[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
}

static double det3(const double a[9])
{
    return a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6]);
}

int hl_dyn_inv3_(const double a[9], double o[9])
{
    double d = det3(a);
    if (!(fabs(d) > 0.0) || !isfinite(d)) return 0;
    double c[9] = {a[4] * a[8] - a[5] * a[7], a[2] * a[7] - a[1] * a[8], a[1] * a[5] - a[2] * a[4],
                   a[5] * a[6] - a[3] * a[8], a[0] * a[8] - a[2] * a[6], a[2] * a[3] - a[0] * a[5],
                   a[3] * a[7] - a[4] * a[6], a[1] * a[6] - a[0] * a[7], a[0] * a[4] - a[1] * a[3]};
    for (int k = 0; k < 9; k++) o[k] = c[k] / d;
    return 1;
}

/* The linear part of a 3x4 as a 3x3, and back. */
static void lin_of(const double x[12], double l[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) l[3 * i + j] = x[4 * i + j];
}

void hl_dyn_xf_mul_(const double a[12], const double b[12], double o[12])
{
    double r[12];
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 4; j++)
            r[4 * i + j] = a[4 * i] * b[j] + a[4 * i + 1] * b[4 + j] + a[4 * i + 2] * b[8 + j];
        r[4 * i + 3] += a[4 * i + 3];
    }
    memcpy(o, r, sizeof r);
}

static void quat_to_mat(const double q[4], double m[9])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    m[0] = 1 - 2 * (y * y + z * z); m[1] = 2 * (x * y - w * z);     m[2] = 2 * (x * z + w * y);
    m[3] = 2 * (x * y + w * z);     m[4] = 1 - 2 * (x * x + z * z); m[5] = 2 * (y * z - w * x);
    m[6] = 2 * (x * z - w * y);     m[7] = 2 * (y * z + w * x);     m[8] = 1 - 2 * (x * x + y * y);
}

void hl_dyn_xf_from_trsq_(const double t[3], const double q[4], const double s[3], double o[12])
{
    double m[9];
    quat_to_mat(q, m);
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) o[4 * i + j] = m[3 * i + j] * s[j];
        o[4 * i + 3] = t[i];
    }
}

/* Rotation matrix to unit quaternion (w first), by the largest of the
 * four squared components so no division is by a small number. */
static void mat_to_quat(const double m[9], double q[4])
{
    double tr = m[0] + m[4] + m[8];
    if (tr > 0.0) {
        double s = 2.0 * sqrt(1.0 + tr);
        q[0] = 0.25 * s; q[1] = (m[7] - m[5]) / s; q[2] = (m[2] - m[6]) / s; q[3] = (m[3] - m[1]) / s;
    } else if (m[0] > m[4] && m[0] > m[8]) {
        double s = 2.0 * sqrt(1.0 + m[0] - m[4] - m[8]);
        q[0] = (m[7] - m[5]) / s; q[1] = 0.25 * s; q[2] = (m[1] + m[3]) / s; q[3] = (m[2] + m[6]) / s;
    } else if (m[4] > m[8]) {
        double s = 2.0 * sqrt(1.0 + m[4] - m[0] - m[8]);
        q[0] = (m[2] - m[6]) / s; q[1] = (m[1] + m[3]) / s; q[2] = 0.25 * s; q[3] = (m[5] + m[7]) / s;
    } else {
        double s = 2.0 * sqrt(1.0 + m[8] - m[0] - m[4]);
        q[0] = (m[3] - m[1]) / s; q[1] = (m[2] + m[6]) / s; q[2] = (m[5] + m[7]) / s; q[3] = 0.25 * s;
    }
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; k++) q[k] /= n;
}

int hl_dyn_decompose_(const double L[9], double q[4], double s[3])
{
    double d = det3(L);
    if (!(fabs(d) > 0.0) || !isfinite(d)) return 0;
    double r[9];
    for (int j = 0; j < 3; j++) {
        s[j] = sqrt(L[j] * L[j] + L[3 + j] * L[3 + j] + L[6 + j] * L[6 + j]);
        if (j == 0 && d < 0.0) s[0] = -s[0]; /* a mirror goes into the scale */
        for (int i = 0; i < 3; i++) r[3 * i + j] = L[3 * i + j] / s[j];
    }
    mat_to_quat(r, q);
    return 1;
}

int hl_dyn_polar_(const double L[9], double Q[9], double K[9])
{
    double inv[9];
    memcpy(Q, L, 9 * sizeof(double));
    /* Newton's iteration Q <- (Q + Q^-T) / 2 (Higham 1986) converges to
       the orthogonal factor, proper or not as det L. */
    for (int it = 0; it < DYN_POLAR_MAX_ITER; it++) {
        if (!hl_dyn_inv3_(Q, inv)) return 0;
        double moved = 0.0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double n = 0.5 * (Q[3 * i + j] + inv[3 * j + i]);
                moved = fmax(moved, fabs(n - Q[3 * i + j]));
                Q[3 * i + j] = n;
            }
        if (moved <= DYN_POLAR_TOL) break;
    }
    if (det3(Q) < 0.0) /* Q F with F = diag(-1, 1, 1): the mirror goes to K */
        for (int i = 0; i < 3; i++) Q[3 * i] = -Q[3 * i];
    double qt[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) qt[3 * i + j] = Q[3 * j + i];
    mat3_mul(qt, L, K);
    for (int k = 0; k < 9; k++)
        if (!isfinite(K[k])) return 0;
    return 1;
}

/* ---------------------------------------------------------------- sampling */

/* The segment of the n sorted times that holds t: i with t_i <= t <
 * t_{i+1} (so t_{i+1} > t_i), or -1 before the first key and n - 1 from
 * the last key on. */
static int64_t segment(const double *times, uint32_t n, double t)
{
    if (t < times[0]) return -1;
    uint32_t lo = 0, hi = n; /* first index with times[k] > t lies in (lo, hi] */
    while (hi - lo > 1) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (times[mid] > t) hi = mid;
        else lo = mid;
    }
    return lo;
}

static void sample_pos(const dyn_channel *c, double t, double out[3])
{
    int64_t i = segment(c->pos_t, c->npos, t);
    if (i < 0 || i >= (int64_t)c->npos - 1) {
        memcpy(out, c->pos + 3 * (i < 0 ? 0 : i), 3 * sizeof(double));
        return;
    }
    double f = (t - c->pos_t[i]) / (c->pos_t[i + 1] - c->pos_t[i]);
    const double *a = c->pos + 3 * i, *b = a + 3;
    for (int k = 0; k < 3; k++) out[k] = a[k] + f * (b[k] - a[k]);
}

static void sample_rot(const dyn_channel *c, double t, double out[4])
{
    int64_t i = segment(c->rot_t, c->nrot, t);
    if (i < 0 || i >= (int64_t)c->nrot - 1) {
        memcpy(out, c->rot + 4 * (i < 0 ? 0 : i), 4 * sizeof(double));
        return;
    }
    double f = (t - c->rot_t[i]) / (c->rot_t[i + 1] - c->rot_t[i]);
    const double *a = c->rot + 4 * i;
    double b[4], d = 0.0;
    for (int k = 0; k < 4; k++) d += a[k] * c->rot[4 * (i + 1) + k];
    /* q and -q are the same rotation: take the one on the shorter arc */
    double sign = d < 0.0 ? -1.0 : 1.0;
    for (int k = 0; k < 4; k++) b[k] = sign * c->rot[4 * (i + 1) + k];
    d = fabs(d);
    double wa = 1.0 - f, wb = f;
    if (d < DYN_SLERP_LINEAR_DOT) {
        double th = acos(d), s = sin(th);
        wa = sin((1.0 - f) * th) / s;
        wb = sin(f * th) / s;
    }
    double n = 0.0;
    for (int k = 0; k < 4; k++) {
        out[k] = wa * a[k] + wb * b[k];
        n += out[k] * out[k];
    }
    n = sqrt(n);
    for (int k = 0; k < 4; k++) out[k] /= n;
}

void hl_dyn_node_local_(const dyn_node *n, double t, double out[12])
{
    if (!n->has_channel) {
        memcpy(out, n->rest, 12 * sizeof(double));
        return;
    }
    double p[3], q[4];
    if (n->ch.npos) sample_pos(&n->ch, t, p);
    else memcpy(p, n->rest_t, sizeof p);
    if (n->ch.nrot) sample_rot(&n->ch, t, q);
    else memcpy(q, n->rest_q, sizeof q);
    hl_dyn_xf_from_trsq_(p, q, n->scale, out);
}

/* ---------------------------------------------------------------- composing */

void hl_dyn_compose_(hl_dyn_scene *s, double t, hl_dyn_object *out)
{
    double turn[12] = {0}, up[12];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) turn[4 * i + j] = s->up[3 * i + j];
    hl_dyn_xf_mul_(s->place, turn, up);
    for (uint32_t k = 0; k < s->nnodes; k++) {
        const dyn_node *n = &s->nodes[k];
        double local[12], *w = s->world + 12 * (size_t)k;
        hl_dyn_node_local_(n, t, local);
        hl_dyn_xf_mul_(n->parent < 0 ? up : s->world + 12 * (size_t)n->parent, local, w);
        if (n->body < 0) continue;
        dyn_body *b = &s->bodies[n->body];
        /* P acts in world space on this node and, through w, on its children */
        hl_dyn_xf_mul_(b->P, w, w);
        if (!out) continue;
        hl_dyn_object *o = &out[n->body];
        o->pos = b->pos;
        o->normal = b->normal;
        o->nverts = b->nverts;
        o->tri = b->tri;
        o->ntris = b->ntris;
        double l[9], r[9];
        lin_of(w, l);
        mat3_mul(l, b->kinv, r); /* the rigid part: world K^-1 */
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < 3; j++) o->xf[4 * i + j] = (float)r[3 * i + j];
            o->xf[4 * i + 3] = (float)w[4 * i + 3];
        }
    }
}

static hl_result check_time(hl_dyn_scene *s, double t)
{
    if (!isfinite(t) || t < 0.0)
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: time %g s is not a finite number >= 0", s->name, t);
    return HL_OK;
}

hl_result hl_dyn_scene_at(hl_dyn_scene *s, double t, hl_dyn_object *out)
{
    if (!s || !out) return hl_fail(s ? s->ctx : NULL, HL_ERR_INVALID_ARGUMENT, "hl_dyn_scene_at: scene and out are required");
    hl_result r = check_time(s, t);
    if (r != HL_OK) return r;
    hl_dyn_compose_(s, t, out);
    return HL_OK;
}

hl_result hl_dyn_scene_bounds(hl_dyn_scene *s, double t, float lo[3], float hi[3])
{
    if (!s || !lo || !hi) return hl_fail(s ? s->ctx : NULL, HL_ERR_INVALID_ARGUMENT, "hl_dyn_scene_bounds: scene, lo and hi are required");
    hl_result r = check_time(s, t);
    if (r != HL_OK) return r;
    hl_dyn_object *o = hl_malloc(s->ctx, s->nbodies * sizeof *o, "the scene's bodies");
    if (!o) return HL_ERR_OUT_OF_MEMORY;
    hl_dyn_compose_(s, t, o);
    double l[3] = {INFINITY, INFINITY, INFINITY}, h[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t b = 0; b < s->nbodies; b++)
        for (uint32_t v = 0; v < o[b].nverts; v++) {
            const float *p = o[b].pos + 3 * (size_t)v;
            for (int i = 0; i < 3; i++) {
                const float *x = o[b].xf + 4 * i;
                double w = (double)x[0] * p[0] + (double)x[1] * p[1] + (double)x[2] * p[2] + x[3];
                l[i] = fmin(l[i], w);
                h[i] = fmax(h[i], w);
            }
        }
    free(o);
    for (int i = 0; i < 3; i++) {
        lo[i] = (float)l[i];
        hi[i] = (float)h[i];
    }
    return HL_OK;
}

/* ---------------------------------------------------------------- the program's transforms */

static hl_result body_arg(const hl_dyn_scene *s, uint32_t body, const char *fn)
{
    if (!s) return hl_fail(NULL, HL_ERR_INVALID_ARGUMENT, "%s: no scene", fn);
    if (body >= s->nbodies)
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: %s: body %u out of range (%u bodies)", s->name, fn, body,
                       s->nbodies);
    return HL_OK;
}

hl_result hl_dyn_scene_set_placement(hl_dyn_scene *s, const double m[12])
{
    if (!s || !m) return hl_fail(s ? s->ctx : NULL, HL_ERR_INVALID_ARGUMENT, "hl_dyn_scene_set_placement: scene and m are required");
    for (int i = 0; i < 12; i++)
        if (!isfinite(m[i]))
            return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: placement entry %d is not finite (%g)", s->name, i, m[i]);
    memcpy(s->place, m, sizeof s->place);
    return HL_OK;
}

hl_result hl_dyn_scene_set_transform(hl_dyn_scene *s, uint32_t body, const float xf[12])
{
    hl_result r = body_arg(s, body, "hl_dyn_scene_set_transform");
    if (r != HL_OK) return r;
    if (!xf) return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: hl_dyn_scene_set_transform: no transform", s->name);
    double x[12], l[9], q[9], k[9];
    for (int i = 0; i < 12; i++) {
        x[i] = xf[i];
        if (!isfinite(x[i]))
            return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: body \"%s\": transform entry %d is not finite (%g)",
                           s->name, s->nodes[s->bodies[body].node].name, i, x[i]);
    }
    lin_of(x, l);
    double worst = fabs(det3(l) - 1.0);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = l[i] * l[j] + l[3 + i] * l[3 + j] + l[6 + i] * l[6 + j] - (i == j ? 1.0 : 0.0);
            worst = fmax(worst, fabs(d));
        }
    if (!(worst <= HL_DYN_RIGID_TOL) || !hl_dyn_polar_(l, q, k))
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT,
                       "%s: body \"%s\": the transform is not rigid (R^T R - I or det R - 1 off by %g, more than %g)",
                       s->name, s->nodes[s->bodies[body].node].name, worst, HL_DYN_RIGID_TOL);
    double *P = s->bodies[body].P;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) P[4 * i + j] = q[3 * i + j];
        P[4 * i + 3] = x[4 * i + 3];
    }
    return HL_OK;
}

hl_result hl_dyn_scene_set_pose(hl_dyn_scene *s, uint32_t body, const double translate[3], const double axis[3],
                                double angle)
{
    hl_result r = body_arg(s, body, "hl_dyn_scene_set_pose");
    if (r != HL_OK) return r;
    const char *name = s->nodes[s->bodies[body].node].name;
    double t[3] = {0, 0, 0}, q[4] = {1, 0, 0, 0}, one[3] = {1, 1, 1};
    if (translate) memcpy(t, translate, sizeof t);
    if (!isfinite(angle) || !isfinite(t[0]) || !isfinite(t[1]) || !isfinite(t[2]))
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: body \"%s\": pose with a non-finite angle or translation",
                       s->name, name);
    if (angle != 0.0) {
        double len = axis ? sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]) : 0.0;
        if (!(len > 0.0) || !isfinite(len))
            return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: body \"%s\": rotation axis is zero or not finite",
                           s->name, name);
        double sh = sin(0.5 * angle) / len;
        q[0] = cos(0.5 * angle);
        for (int k = 0; k < 3; k++) q[k + 1] = axis[k] * sh;
    }
    hl_dyn_xf_from_trsq_(t, q, one, s->bodies[body].P);
    return HL_OK;
}

void hl_dyn_scene_get_transform(const hl_dyn_scene *s, uint32_t body, float xf[12])
{
    if (!s || body >= s->nbodies || !xf) return;
    for (int k = 0; k < 12; k++) xf[k] = (float)s->bodies[body].P[k];
}

/* ---------------------------------------------------------------- the animation */

static char *copy_name(hl_context *ctx, const char *str)
{
    size_t n = strlen(str) + 1;
    char *d = hl_malloc(ctx, n, "the animation's name");
    if (d) memcpy(d, str, n);
    return d;
}

typedef struct name_ix {
    const char *name;
    uint32_t ix;
} name_ix;

static int name_ix_cmp(const void *a, const void *b)
{
    const name_ix *x = a, *y = b;
    int c = strcmp(x->name, y->name);
    return c ? c : (x->ix > y->ix) - (x->ix < y->ix);
}

/* The first node (depth-first) named name, or -1; sorted by name_ix_cmp. */
static int64_t find_sorted(const name_ix *v, uint32_t n, const char *name)
{
    uint32_t lo = 0, hi = n;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (strcmp(v[mid].name, name) < 0) lo = mid + 1;
        else hi = mid;
    }
    return lo < n && strcmp(v[lo].name, name) == 0 ? (int64_t)v[lo].ix : -1;
}

static hl_result choose_animation(hl_dyn_scene *s, const struct aiScene *as, const hl_dyn_scene_desc *d,
                                  const struct aiAnimation **out)
{
    *out = NULL;
    unsigned na = as->mAnimations ? as->mNumAnimations : 0;
    if (d->animation_name) {
        for (unsigned a = 0; a < na; a++)
            if (as->mAnimations[a] && strcmp(as->mAnimations[a]->mName.data, d->animation_name) == 0) {
                *out = as->mAnimations[a];
                return HL_OK;
            }
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: no animation is named \"%s\" (the file has %u)", s->name,
                       d->animation_name, na);
    }
    if (d->animation == HL_DYN_NO_ANIMATION || (d->animation == 0 && na == 0)) return HL_OK;
    if (d->animation < 0 || (unsigned)d->animation >= na)
        return hl_fail(s->ctx, HL_ERR_INVALID_ARGUMENT, "%s: animation %d out of range (the file has %u)", s->name,
                       d->animation, na);
    *out = as->mAnimations[d->animation];
    return *out ? HL_OK : hl_fail(s->ctx, HL_ERR_FORMAT, "%s: animation %d is missing", s->name, d->animation);
}

/* Key times in seconds: finite, never going back. */
static hl_result key_time(hl_dyn_scene *s, const dyn_node *n, const char *kind, uint32_t k, double ticks, double tps,
                          const double *prev, double *out)
{
    *out = ticks / tps;
    if (!isfinite(ticks) || !isfinite(*out))
        return hl_fail(s->ctx, HL_ERR_FORMAT, "%s: node \"%s\": %s key %u has a non-finite time", s->name, n->name,
                       kind, k);
    if (prev && *out < *prev)
        return hl_fail(s->ctx, HL_ERR_FORMAT, "%s: node \"%s\": %s key %u goes back in time (%g s after %g s)",
                       s->name, n->name, kind, k, *out, *prev);
    return HL_OK;
}

/* Copies one channel's position and rotation keys into node n and its
 * constant scale; refuses changing scale and non-finite keys. */
static hl_result load_channel(hl_dyn_scene *s, dyn_node *n, const struct aiNodeAnim *c, double tps)
{
    hl_context *ctx = s->ctx;
    dyn_channel *ch = &n->ch;
    n->has_channel = 1;
    if ((c->mNumPositionKeys && !c->mPositionKeys) || (c->mNumRotationKeys && !c->mRotationKeys) ||
        (c->mNumScalingKeys && !c->mScalingKeys))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\": the animation channel lacks its key arrays", s->name,
                       n->name);
    ch->npos = c->mNumPositionKeys;
    ch->nrot = c->mNumRotationKeys;
    ch->pos_t = hl_malloc(ctx, (ch->npos + 1) * sizeof(double), "position keys");
    ch->pos = hl_malloc(ctx, (ch->npos + 1) * 3 * sizeof(double), "position keys");
    ch->rot_t = hl_malloc(ctx, (ch->nrot + 1) * sizeof(double), "rotation keys");
    ch->rot = hl_malloc(ctx, (ch->nrot + 1) * 4 * sizeof(double), "rotation keys");
    if (!ch->pos_t || !ch->pos || !ch->rot_t || !ch->rot) return HL_ERR_OUT_OF_MEMORY;
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < ch->npos && r == HL_OK; k++) {
        const struct aiVectorKey *key = &c->mPositionKeys[k];
        r = key_time(s, n, "position", k, key->mTime, tps, k ? &ch->pos_t[k - 1] : NULL, &ch->pos_t[k]);
        double v[3] = {key->mValue.x, key->mValue.y, key->mValue.z};
        if (r == HL_OK && !(isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2])))
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\": position key %u is not finite (%g, %g, %g)", s->name,
                        n->name, k, v[0], v[1], v[2]);
        memcpy(ch->pos + 3 * (size_t)k, v, sizeof v);
    }
    for (uint32_t k = 0; k < ch->nrot && r == HL_OK; k++) {
        const struct aiQuatKey *key = &c->mRotationKeys[k];
        r = key_time(s, n, "rotation", k, key->mTime, tps, k ? &ch->rot_t[k - 1] : NULL, &ch->rot_t[k]);
        double q[4] = {key->mValue.w, key->mValue.x, key->mValue.y, key->mValue.z};
        double len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (r == HL_OK && (!isfinite(len) || !(len > 0.0)))
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\": rotation key %u is not a rotation (%g, %g, %g, %g)",
                        s->name, n->name, k, q[0], q[1], q[2], q[3]);
        for (int i = 0; i < 4; i++) ch->rot[4 * (size_t)k + i] = q[i] / len;
    }
    for (uint32_t k = 0; k < c->mNumScalingKeys && r == HL_OK; k++) {
        const struct aiVectorKey *key = &c->mScalingKeys[k];
        double t;
        r = key_time(s, n, "scaling", k, key->mTime, tps, NULL, &t);
        double v[3] = {key->mValue.x, key->mValue.y, key->mValue.z};
        if (r == HL_OK && !(isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]) && v[0] * v[1] * v[2] != 0.0))
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: node \"%s\": scaling key %u is not finite or zero (%g, %g, %g)",
                        s->name, n->name, k, v[0], v[1], v[2]);
        if (r != HL_OK) break;
        if (k == 0) memcpy(n->scale, v, sizeof v);
        for (int i = 0; i < 3; i++)
            if (fabs(v[i] - n->scale[i]) > DYN_SCALE_TOL * fabs(n->scale[i]))
                r = hl_fail(ctx, HL_ERR_MESH,
                            "%s: node \"%s\": the animation is not rigid: its scaling keys change over time "
                            "((%g, %g, %g) at key 0, (%g, %g, %g) at key %u)" HL_DYN_REST_POSE_HINT,
                            s->name, n->name, n->scale[0], n->scale[1], n->scale[2], v[0], v[1], v[2], k);
    }
    for (uint32_t k = 0; k < ch->npos && r == HL_OK; k++) {
        s->t_start = fmin(s->t_start, ch->pos_t[k]);
        s->t_end = fmax(s->t_end, ch->pos_t[k]);
    }
    for (uint32_t k = 0; k < ch->nrot && r == HL_OK; k++) {
        s->t_start = fmin(s->t_start, ch->rot_t[k]);
        s->t_end = fmax(s->t_end, ch->rot_t[k]);
    }
    return r;
}

/* The chosen animation: node channels only (mesh and morph channels move
 * vertices), a usable tick rate, each channel on the first node of its
 * name; channels naming no node are ignored, as assimp's own evaluator
 * does. */
static hl_result load_animation(hl_dyn_scene *s, const struct aiAnimation *a)
{
    hl_context *ctx = s->ctx;
    if (a->mNumMeshChannels || a->mNumMorphMeshChannels)
        return hl_fail(ctx, HL_ERR_MESH,
                       "%s: animation \"%s\" is not rigid: it has %u mesh and %u morph-target channels (only whole "
                       "nodes may move)" HL_DYN_REST_POSE_HINT, s->name, a->mName.data, a->mNumMeshChannels, a->mNumMorphMeshChannels);
    double tps = a->mTicksPerSecond;
    if (tps == 0.0) tps = DYN_DEFAULT_TICKS_PER_SECOND;
    if (!(tps > 0.0) || !isfinite(tps))
        return hl_fail(ctx, HL_ERR_FORMAT, "%s: animation \"%s\" has %g ticks per second", s->name, a->mName.data,
                       a->mTicksPerSecond);
    s->anim_name = copy_name(ctx, a->mName.data);
    name_ix *v = hl_malloc(ctx, s->nnodes * sizeof *v, "the node names");
    if (!s->anim_name || !v) {
        free(v);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t k = 0; k < s->nnodes; k++) v[k] = (name_ix){s->nodes[k].name, k};
    qsort(v, s->nnodes, sizeof *v, name_ix_cmp);
    s->t_start = INFINITY;
    s->t_end = -INFINITY;
    hl_result r = HL_OK;
    for (unsigned c = 0; c < a->mNumChannels && r == HL_OK; c++) {
        const struct aiNodeAnim *na = a->mChannels ? a->mChannels[c] : NULL;
        if (!na) {
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: animation \"%s\": channel %u is missing", s->name, a->mName.data, c);
            break;
        }
        int64_t k = find_sorted(v, s->nnodes, na->mNodeName.data);
        if (k < 0) continue;
        if (s->nodes[k].has_channel)
            r = hl_fail(ctx, HL_ERR_FORMAT, "%s: animation \"%s\": two channels move node \"%s\"", s->name,
                        a->mName.data, s->nodes[k].name);
        else r = load_channel(s, &s->nodes[k], na, tps);
    }
    free(v);
    if (!(s->t_start <= s->t_end)) s->t_start = s->t_end = 0.0; /* no keys at all */
    return r;
}

/* Whether a channel's rotation keys are all one rotation. */
static int rotates(const dyn_node *n)
{
    for (uint32_t k = 1; k < n->ch.nrot; k++) {
        const double *a = n->ch.rot, *b = n->ch.rot + 4 * (size_t)k;
        if (fabs(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]) < DYN_SAME_ROT_DOT) return 1;
    }
    return 0;
}

/* Whether node n's local linear part is a rotation times a uniform scale
 * (then it commutes with the rotations below it). */
static int similarity(const dyn_node *n)
{
    double l[9];
    if (n->has_channel) {
        double m = fmax(fabs(n->scale[0]), fmax(fabs(n->scale[1]), fabs(n->scale[2])));
        for (int i = 0; i < 3; i++)
            if (fabs(fabs(n->scale[i]) - m) > DYN_SCALE_TOL * m) return 0;
        return 1;
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) l[3 * i + j] = n->rest[4 * i + j];
    double g[9], m = 0.0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            g[3 * i + j] = l[i] * l[j] + l[3 + i] * l[3 + j] + l[6 + i] * l[6 + j];
            m = fmax(m, fabs(g[3 * i + j]));
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (fabs(g[3 * i + j] - (i == j ? g[0] : 0.0)) > DYN_SCALE_TOL * m) return 0;
    return 1;
}

/* The bodies' world transforms stay rigid when no node whose rotation
 * changes hangs below a node that scales unevenly (or shears): such a
 * scale does not commute with the rotation, so the product shears over
 * time. Only nodes with a body at or below them matter. */
hl_result hl_dyn_check_rigid_(hl_dyn_scene *s)
{
    uint32_t nn = s->nnodes;
    unsigned char *below = hl_calloc(s->ctx, nn, 1, "the rigidity check");
    unsigned char *uneven = hl_calloc(s->ctx, nn, 1, "the rigidity check");
    if (!below || !uneven) {
        free(below);
        free(uneven);
        return HL_ERR_OUT_OF_MEMORY;
    }
    for (uint32_t k = nn; k-- > 0;) { /* children come after their parent */
        if (s->nodes[k].triangles) below[k] = 1;
        if (below[k] && s->nodes[k].parent >= 0) below[s->nodes[k].parent] = 1;
    }
    hl_result r = HL_OK;
    for (uint32_t k = 0; k < nn && r == HL_OK; k++) {
        const dyn_node *n = &s->nodes[k];
        int p = n->parent;
        int above = p >= 0 && uneven[p];
        uneven[k] = (unsigned char)(above || !similarity(n));
        if (above && below[k] && n->has_channel && rotates(n)) {
            int32_t q = p;
            while (s->nodes[q].parent >= 0 && uneven[s->nodes[q].parent]) q = s->nodes[q].parent;
            r = hl_fail(s->ctx, HL_ERR_MESH,
                        "%s: node \"%s\": the animation is not rigid: the node rotates under node \"%s\", which "
                        "scales unevenly, so the geometry below it shears" HL_DYN_REST_POSE_HINT, s->name, n->name,
                        s->nodes[q].name);
        }
    }
    free(below);
    free(uneven);
    return r;
}

hl_result hl_dyn_load_animation_(hl_dyn_scene *s, const struct aiScene *as, const hl_dyn_scene_desc *d)
{
    const struct aiAnimation *a = NULL;
    hl_result r = choose_animation(s, as, d, &a);
    if (r == HL_OK && a) r = load_animation(s, a);
    return r;
}
