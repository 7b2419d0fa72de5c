/* haar.cl - orthonormal non-standard 2D Haar of both paraboloid maps.
 * One work-item per row of 2 N^2 values. Averages are compacted in place
 * (row-major order never overwrites an unread input); details go straight
 * to their slots. Twin: host/src/maps/twins/haar.c.
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_haar(global float *T, global float *coef, global const uint *slot_of_mallat,
                    uint N, uint nrows)
{
    uint v = get_global_id(0);
    if (v >= nrows) return;
    size_t nn = (size_t)N * N;
    for (uint map = 0; map < 2; map++) {
        global float *x = T + (size_t)v * 2 * nn + map * nn;
        global float *o = coef + (size_t)v * 2 * nn + map * nn;
        for (uint s = N; s >= 2; s /= 2) {
            uint h = s / 2;
            for (uint i = 0; i < h; i++)
                for (uint j = 0; j < h; j++) {
                    float a = x[(2 * i) * N + 2 * j], b = x[(2 * i) * N + 2 * j + 1];
                    float c = x[(2 * i + 1) * N + 2 * j], d = x[(2 * i + 1) * N + 2 * j + 1];
                    o[slot_of_mallat[i * N + j + h]] = (a - b + c - d) * 0.5f;
                    o[slot_of_mallat[(i + h) * N + j]] = (a + b - c - d) * 0.5f;
                    o[slot_of_mallat[(i + h) * N + j + h]] = (a - b - c + d) * 0.5f;
                    x[i * N + j] = (a + b + c + d) * 0.5f;
                }
        }
        o[slot_of_mallat[0]] = x[0];
    }
}
