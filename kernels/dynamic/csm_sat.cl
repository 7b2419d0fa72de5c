/* csm_sat.cl - summed-area tables of the convolution shadow maps' basis
 * planes: each plane's mean from its row sums (hl_csm_sat_mean), then an
 * inclusive prefix sum of every row, minus the plane's mean, and of every
 * column (hl_csm_sat_scan, one work-group of L lanes per line of all
 * planes: each lane sums a run of R / L values in order, the L run sums
 * are scanned in a tree in local memory, and each lane adds its run's
 * offset). Subtracting
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

/* the most planes of one light: 2 M + 2 Mb + 1 with M, Mb <= 16 */
#define HL_CSM_SAT_MAX_PLANES 65

/* Group g scans line g % R of light g / R, all P planes at once (a
 * texel's P values are contiguous, and one group a line keeps the groups
 * few: PoCL pays for each): element i of plane p at base + i * step + p,
 * base = light * P * R * R + line * line_step. Each plane is scanned as
 * one line of R values would be alone (its own run sums, tree and offsets),
 * so the twin can scan plane by plane. mean: subtracted first when sub is
 * 1 (rows), not when 0 (columns). part: 2 L P floats. */
__kernel void hl_csm_sat_scan(__global float *buf, __global const float *mean, uint R, uint P, uint step,
                              uint line_step, uint sub, __local float *part)
{
    uint g = (uint)get_group_id(0), l = (uint)get_local_id(0), L = (uint)get_local_size(0);
    uint line = g % R, light = g / R;
    __global float *b = buf + (size_t)light * P * R * R + (size_t)line * line_step;
    __global const float *m = mean + (size_t)light * P;
    uint run = R / L, i0 = l * run;
    float acc[HL_CSM_SAT_MAX_PLANES];
    for (uint p = 0; p < P; p++) acc[p] = 0.0f;
    for (uint i = i0; i < i0 + run; i++) {
        __global float *e = b + (size_t)i * step;
        for (uint p = 0; p < P; p++) {
            acc[p] += e[p] - (sub ? m[p] : 0.0f);
            e[p] = acc[p];
        }
    }
    __local float *a = part, *t = part + L * P;
    for (uint p = 0; p < P; p++) a[l * P + p] = acc[p];
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint off = 1; off < L; off <<= 1) {
        for (uint p = 0; p < P; p++) {
            float v = a[l * P + p];
            if (l >= off) v = a[(l - off) * P + p] + v;
            t[l * P + p] = v;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        __local float *x = a;
        a = t;
        t = x;
    }
    if (l > 0) {
        for (uint i = i0; i < i0 + run; i++) {
            __global float *e = b + (size_t)i * step;
            for (uint p = 0; p < P; p++) e[p] += a[(l - 1) * P + p];
        }
    }
}
