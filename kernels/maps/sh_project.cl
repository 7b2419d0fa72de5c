/* sh_project.cl - rows of paraboloid texels projected onto real spherical
 * harmonics: out[v][k] = sum_j in[v][j] Y[j][k] for k < nsh, a dense
 * product with the (2 N^2 x stride) matrix Y (host/src/sh/sh.h,
 * hl_sh_matrix: the texels' harmonic integrals, divided by each texel's
 * solid angle for transport rows). The slots from nsh on are not written:
 * the caller zeroes them (they stay empty in the 2 N^2 slot space).
 * Twin: host/src/maps/twins/sh_project.c.
 *
 * One work-item per HL_SH_ROWS rows and four consecutive coefficients:
 * the four are one float4 of a matrix row (stride is a multiple of 4,
 * the padding zero), so neighbouring work-items read neighbouring memory,
 * and each matrix element read serves HL_SH_ROWS rows (the lighting's
 * three colour planes in one work-item: the matrix is read once a
 * lighting change, not three times). Zero texels (below a vertex's
 * horizon) add nothing. Each row's sum runs over j in order, as the
 * twin's.
 */
#pragma OPENCL FP_CONTRACT OFF

#define HL_SH_ROWS 4u

kernel void hl_sh_project_rows(global const float *in, uint ncoef, global const float4 *Y, uint stride, uint nsh,
                               global float *out, uint nrows)
{
    uint id = get_global_id(0), q = stride / 4u;
    uint v0 = id / q * HL_SH_ROWS, b = id % q;
    if (v0 >= nrows) return;
    const uint n = min(HL_SH_ROWS, nrows - v0);
    global const float *x = in + (size_t)v0 * ncoef;
    float4 acc[HL_SH_ROWS];
    for (uint r = 0; r < HL_SH_ROWS; r++) acc[r] = (float4)(0.0f);
    for (uint j = 0; j < ncoef; j++) {
        float4 y = Y[(size_t)j * q + b];
        for (uint r = 0; r < n; r++) {
            float t = x[(size_t)r * ncoef + j];
            if (t != 0.0f) acc[r] += t * y;
        }
    }
    uint k = 4u * b;
    for (uint r = 0; r < n; r++) {
        global float *o = out + (size_t)(v0 + r) * ncoef;
        if (k < nsh) o[k] = acc[r].x;
        if (k + 1u < nsh) o[k + 1u] = acc[r].y;
        if (k + 2u < nsh) o[k + 2u] = acc[r].z;
        if (k + 3u < nsh) o[k + 3u] = acc[r].w;
    }
}
