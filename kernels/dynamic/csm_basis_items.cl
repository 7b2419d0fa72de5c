/* csm_basis_items.cl - the GPU shape's basis images of convolution shadow
 * maps: hl_csm_basis's outputs (csm_basis.cl) bit for bit, a work-item a
 * texel instead of a work-item a row, and the row sums by a second
 * launch, a work-item a row and plane.
 *
 * hl_csm_basis_texels computes one texel's values exactly as csm_basis.cl
 * computes them inside its row (nothing in a texel's values depends on
 * another texel). hl_csm_basis_rowsums adds a row's values of one plane
 * in texel order, as csm_basis.cl's running sums add them, reading them
 * back from the planes (neighbouring work-items take neighbouring planes
 * of a texel: neighbouring addresses).
 * Twin: host/src/dynamic/twins/csm_basis.c.
 */

__kernel void hl_csm_basis_texels(__global const float *depth, uint R, uint M, uint Mb, float c1, uint ntexels,
                                  __global float *img, __global float *zsc)
{
    size_t gid = get_global_id(0);
    if (gid >= ntexels) return;
    uint P = 2 * M + 2 * Mb + 1;
    float z = depth[gid];
    float ph = c1 * z;
    float s = sin(ph), c = cos(ph);
    float rs = 2.0f * s * c, rc = c * c - s * s;
    __global float *o = img + gid * P, *t4 = zsc + gid * 4;
    t4[0] = z;
    t4[1] = s;
    t4[2] = c;
    t4[3] = 0.0f;
    o[0] = z;
    for (uint k = 0; k < M; k++) {
        o[1 + 2 * k] = s;
        o[2 + 2 * k] = c;
        if (k < Mb) {
            o[1 + 2 * M + 2 * k] = z * s;
            o[2 + 2 * M + 2 * k] = z * c;
        }
        float s2 = s * rc + c * rs, c2 = c * rc - s * rs;
        s = s2;
        c = c2;
    }
}

/* Work-item (light, row, plane), the plane fastest: rowsum[light P R +
 * plane R + row], the sum of the row's values in that plane. */
__kernel void hl_csm_basis_rowsums(__global const float *img, uint R, uint P, uint nitems, __global float *rowsum)
{
    size_t gid = get_global_id(0);
    if (gid >= nitems) return;
    uint p = (uint)(gid % P), line = (uint)(gid / P), light = line / R, row = line % R;
    __global const float *v = img + ((size_t)line * R) * P + p;
    float acc = 0.0f;
    for (uint i = 0; i < R; i++) acc += v[(size_t)i * P];
    rowsum[(size_t)light * P * R + (size_t)p * R + row] = acc;
}
