/* sh_project.cl - rows of paraboloid texels projected onto real spherical
 * harmonics: out[v][k] = sum_j in[v][j] Y[j][k] for k < nsh, a dense
 * product with the (2 N^2 x stride) matrix Y (host/src/sh/sh.h,
 * hl_sh_matrix: the texels' harmonic integrals, divided by each texel's
 * solid angle for transport rows). The slots from nsh on are not written:
 * the caller zeroes them (they stay empty in the 2 N^2 slot space).
 * Twin: host/src/maps/twins/sh_project.c.
 *
 * One work-item per row and four consecutive coefficients: the four are
 * one float4 of a matrix row (stride is a multiple of 4, the padding
 * zero), so neighbouring work-items read neighbouring memory, and zero
 * texels (below a vertex's horizon) are skipped. The sum runs over j in
 * order, as the twin's.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_sh_project_rows(global const float *in, uint ncoef, global const float4 *Y, uint stride, uint nsh,
                               global float *out, uint nrows)
{
    uint id = get_global_id(0), q = stride / 4u;
    uint v = id / q, b = id - v * q;
    if (v >= nrows) return;
    global const float *x = in + (size_t)v * ncoef;
    float4 acc = (float4)(0.0f);
    for (uint j = 0; j < ncoef; j++) {
        float t = x[j];
        if (t == 0.0f) continue;
        acc += t * Y[(size_t)j * q + b];
    }
    global float *o = out + (size_t)v * ncoef;
    uint k = 4u * b;
    if (k < nsh) o[k] = acc.x;
    if (k + 1u < nsh) o[k + 1u] = acc.y;
    if (k + 2u < nsh) o[k + 2u] = acc.z;
    if (k + 3u < nsh) o[k + 3u] = acc.w;
}
