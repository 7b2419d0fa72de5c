/* csm_sat.cl - summed-area tables of the convolution shadow maps' basis
 * planes: each plane's mean from its row sums (hl_csm_sat_mean), then an
 * inclusive prefix sum of every row, minus the plane's mean, and of every
 * column (hl_csm_sat_scan, one work-group of L lanes per line: each lane
 * sums a run of R / L values in order, the L run sums are scanned in a
 * tree in local memory, and each lane adds its run's offset). Subtracting
 * the mean keeps the tables' values near zero for float (DYNAMIC.md,
 * precision); the evaluation adds mean x area back.
 * Twin: host/src/dynamic/twins/csm_sat.c (the same additions in the same
 * order). Depends on: hl_shared.h (FP_CONTRACT off).
 */

__kernel void hl_csm_sat_mean(__global const float *rowsum, uint R, uint nplanes, __global float *mean)
{
    size_t p = get_global_id(0);
    if (p >= nplanes) return;
    __global const float *r = rowsum + p * R;
    float s = 0.0f;
    for (uint i = 0; i < R; i++) s += r[i];
    mean[p] = s / ((float)R * (float)R);
}

/* Group g scans line (g / P) % R of plane g % P of light g / (P R) (so
 * neighbouring groups share cache lines of the interleaved planes):
 * elements base + i * step, base = light * P * R * R + line * line_step +
 * plane. mean: subtracted first when sub is 1 (rows), not when 0
 * (columns). part: 2 L floats. */
__kernel void hl_csm_sat_scan(__global float *buf, __global const float *mean, uint R, uint P, uint step,
                              uint line_step, uint sub, __local float *part)
{
    uint g = (uint)get_group_id(0), l = (uint)get_local_id(0), L = (uint)get_local_size(0);
    uint plane = g % P, line = (g / P) % R, light = g / (P * R);
    __global float *b = buf + (size_t)light * P * R * R + (size_t)line * line_step + plane;
    float m = sub ? mean[(size_t)light * P + plane] : 0.0f;
    uint run = R / L, i0 = l * run;
    float acc = 0.0f;
    for (uint i = i0; i < i0 + run; i++) {
        acc += b[(size_t)i * step] - m;
        b[(size_t)i * step] = acc;
    }
    __local float *a = part, *t = part + L;
    a[l] = acc;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint off = 1; off < L; off <<= 1) {
        float v = a[l];
        if (l >= off) v = a[l - off] + v;
        t[l] = v;
        barrier(CLK_LOCAL_MEM_FENCE);
        __local float *x = a;
        a = t;
        t = x;
    }
    if (l > 0) {
        float o = a[l - 1];
        for (uint i = i0; i < i0 + run; i++) b[(size_t)i * step] += o;
    }
}
