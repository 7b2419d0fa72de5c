/* msm_basis.cl - the basis images of moment shadow maps (Peters and Klein
 * 2015), one row of one light's depth map per work-item: per texel the
 * four powers of x = 2 z - 1 (x, x^2, x^3, x^4) and the coverage c = 1 for a
 * caster's texel, 0 for an empty one, interleaved by texel (5 planes, as
 * csm.h's layout with P = 5), each plane's row sum (for its mean,
 * csm_sat.cl), and the four powers again in zsc for the evaluation's
 * texel-by-texel boxes (msm_eval.cl; the tables overwrite img; there
 * c is x < 1). The coverage takes the empty texels' mass out of the
 * moment problem (msm_eval.cl). Depth is shifted to [-1, 1] so that the moments are centred: the
 * Hankel matrix of a distribution on [-1, 1] is better conditioned in
 * float than on [0, 1], whose moments all crowd near the same value.
 * Geometry's depths are scaled by kb = 1 - HL_MSM_FAR_BAND, so that an
 * empty texel (z = 1, x = 1) lies a band behind every caster: a receiver
 * beyond the far plane (a ground under the casters) is put in that band
 * (msm_eval.cl), away from the empty texels' large mass, which the bound
 * would otherwise let light leak towards.
 * Twin: host/src/dynamic/twins/msm_basis.c.
 * Depends on: hl_shared.h (FP_CONTRACT off, so the twin rounds alike).
 */

__kernel void hl_msm_basis(__global const float *depth, uint R, float kb, uint nrows, __global float *img,
                           __global float *rowsum, __global float *zsc)
{
    size_t gid = get_global_id(0);
    if (gid >= nrows) return;
    uint light = (uint)(gid / R), row = (uint)(gid % R);
    size_t plane = (size_t)R * R, at = (size_t)light * plane + (size_t)row * R;
    __global const float *z_row = depth + at;
    __global float *o = img + at * 5, *t4 = zsc + at * 4;
    float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f, a3 = 0.0f, a4 = 0.0f;
    for (uint i = 0; i < R; i++) {
        float z = z_row[i], x = z >= 1.0f ? 1.0f : 2.0f * (z * kb) - 1.0f;
        float x2 = x * x, x3 = x2 * x, x4 = x2 * x2, c = z >= 1.0f ? 0.0f : 1.0f;
        o[5 * i] = x;
        o[5 * i + 1] = x2;
        o[5 * i + 2] = x3;
        o[5 * i + 3] = x4;
        o[5 * i + 4] = c;
        t4[4 * i] = x;
        t4[4 * i + 1] = x2;
        t4[4 * i + 2] = x3;
        t4[4 * i + 3] = x4;
        a0 += x;
        a1 += x2;
        a2 += x3;
        a3 += x4;
        a4 += c;
    }
    __global float *rs = rowsum + (size_t)light * 5 * R + row;
    rs[0] = a0;
    rs[R] = a1;
    rs[2 * (size_t)R] = a2;
    rs[3 * (size_t)R] = a3;
    rs[4 * (size_t)R] = a4;
}
