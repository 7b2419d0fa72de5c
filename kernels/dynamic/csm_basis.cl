/* csm_basis.cl - the basis images of convolution shadow maps, one row of
 * one light's depth map per work-item: z, S_k = sin(c_k z), C_k =
 * cos(c_k z) (k = 1..M), z S_k, z C_k (k = 1..Mb), interleaved by texel
 * as host/src/dynamic/csm.h says, each plane's row sum (for the
 * plane's mean, csm_sat.cl), and per texel (z, sin(c1 z), cos(c1 z), 0)
 * for the evaluation's texel-by-texel boxes (csm_eval.cl). c_k = (2k - 1) c1: the odd multiples come from one
 * sine and cosine by rotating through 2 c1 z (6 flops a term instead of
 * two library calls; the drift is a few ulps per step, measured in
 * test_csm_basis.c). Twin: host/src/dynamic/twins/csm_basis.c.
 * Depends on: hl_shared.h (FP_CONTRACT off, so the twin rounds alike).
 */

/* the most planes of one light: 2 M + 2 Mb + 1 with M, Mb <= 16 */
#define HL_CSM_BASIS_MAX_PLANES 65

__kernel void hl_csm_basis(__global const float *depth, uint R, uint M, uint Mb, float c1,
                           uint nrows, __global float *img, __global float *rowsum, __global float *zsc)
{
    size_t gid = get_global_id(0);
    if (gid >= nrows) return;
    uint light = (uint)(gid / R), row = (uint)(gid % R);
    uint P = 2 * M + 2 * Mb + 1;
    size_t plane = (size_t)R * R;
    __global const float *z_row = depth + (size_t)light * plane + (size_t)row * R;
    __global float *out = img + ((size_t)light * plane + (size_t)row * R) * P;
    __global float *t4 = zsc + ((size_t)light * plane + (size_t)row * R) * 4;
    float acc[HL_CSM_BASIS_MAX_PLANES];
    for (uint p = 0; p < P; p++) acc[p] = 0.0f;
    for (uint i = 0; i < R; i++) {
        float z = z_row[i];
        float ph = c1 * z;
        float s = sin(ph), c = cos(ph);
        /* rotation by 2 c1 z: (2k+1) c1 z = (2k-1) c1 z + 2 c1 z */
        float rs = 2.0f * s * c, rc = c * c - s * s;
        __global float *o = out + (size_t)i * P;
        t4[4 * i] = z;
        t4[4 * i + 1] = s;
        t4[4 * i + 2] = c;
        t4[4 * i + 3] = 0.0f;
        o[0] = z;
        acc[0] += z;
        for (uint k = 0; k < M; k++) {
            o[1 + 2 * k] = s;
            o[2 + 2 * k] = c;
            acc[1 + 2 * k] += s;
            acc[2 + 2 * k] += c;
            if (k < Mb) {
                float zs = z * s, zc = z * c;
                o[1 + 2 * M + 2 * k] = zs;
                o[2 + 2 * M + 2 * k] = zc;
                acc[1 + 2 * M + 2 * k] += zs;
                acc[2 + 2 * M + 2 * k] += zc;
            }
            float s2 = s * rc + c * rs, c2 = c * rc - s * rs;
            s = s2;
            c = c2;
        }
    }
    __global float *rs_out = rowsum + (size_t)light * P * R + row;
    for (uint p = 0; p < P; p++) rs_out[(size_t)p * R] = acc[p];
}
