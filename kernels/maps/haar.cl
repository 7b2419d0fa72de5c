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
        hl_haar_square(T + (size_t)v * 2 * nn + map * nn, coef + (size_t)v * 2 * nn + map * nn, slot_of_mallat, N);
    }
}
