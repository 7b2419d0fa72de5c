/* cube_haar.cl - Haar over the six faces of a cube (precompute --basis
 * cube-haar): the visibility cube's transport regrouped onto the face
 * texels of side Cq, and the faces' orthonormal non-standard Haar.
 * Twins: host/src/cube/cube.c (hl_cube_rows, hl_cube_haar), the same
 * sums in the same order, so the files match the reference backend's.
 */
#pragma OPENCL FP_CONTRACT OFF

/* One vertex's face texels: T[q] = scale * the sum over the visibility
 * texels c inside q (in ascending c) of the sum over c's footprint-table
 * parts e (start/ent: grouped by cube texel) of vis[c] max(0, n . m_e),
 * the products cube2para adds up by paraboloid texel. A cube texel of
 * side Cq spans C / Cq visibility texels a side. One work-item per row;
 * out rows of stride floats, texels 0 .. 6 Cq^2 - 1 written. */
kernel void hl_cube_face_rows(global const uchar *vis, uint C, uint Cq, float scale, global const float4 *normals,
                              global const uint *start, global const hl_c2p_entry *ent, uint stride,
                              global float *T, uint nverts)
{
    uint v = get_global_id(0);
    if (v >= nverts) return;
    uint ncube = 6u * C * C, ntex = 6u * Cq * Cq, r = C / Cq;
    float4 n = normals[v];
    global const uchar *row = vis + (size_t)v * ncube;
    global float *out = T + (size_t)v * stride;
    for (uint q = 0; q < ntex; q++) out[q] = 0.0f;
    for (uint c = 0; c < ncube; c++) {
        uint vv = row[c];
        if (!vv) continue;
        uint f = c / (C * C), y = (c / C) % C, x = c % C;
        float acc = 0.0f;
        for (uint e = start[c]; e < start[c + 1]; e++) {
            hl_c2p_entry t = ent[e];
            float w = n.x * t.mx + n.y * t.my + n.z * t.mz;
            if (w > 0.0f) acc += (float)vv * w;
        }
        out[f * Cq * Cq + (y / r) * Cq + x / r] += acc;
    }
    for (uint q = 0; q < ntex; q++) out[q] *= scale;
}

/* One face of one row per work-item (face = id % 6): the face's texels
 * in rows of in_stride floats (destroyed: the averages are compacted in
 * place) to its coefficients in rows of out_stride floats, in the Mallat
 * layout; face 0's work-item also zeroes the row's slots from 6 Cq^2 on,
 * which the basis leaves empty. */
kernel void hl_cube_face_haar(global float *T, uint in_stride, global float *coef, uint out_stride, uint Cq,
                              uint nrows)
{
    uint id = get_global_id(0), v = id / 6u, f = id % 6u;
    if (v >= nrows) return;
    size_t nn = (size_t)Cq * Cq;
    hl_haar_square(T + (size_t)v * in_stride + f * nn, coef + (size_t)v * out_stride + f * nn, 0, Cq); /* Mallat */
    if (f == 0)
        for (size_t k = 6 * nn; k < out_stride; k++) coef[(size_t)v * out_stride + k] = 0.0f;
}
