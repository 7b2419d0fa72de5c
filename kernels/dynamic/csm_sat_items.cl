/* csm_sat_items.cl - the GPU shape's scan of the summed-area tables:
 * hl_csm_sat_scan's result (csm_sat.cl) bit for bit, with a work-item a
 * lane and plane instead of a lane for all the planes.
 *
 * A group takes one line of one light and HL_CSM_SAT_CHUNK of its planes,
 * HL_CSM_SCAN_LANES lanes each (group size lanes x chunk, the plane
 * fastest, so that at each step the group reads a texel's planes in one
 * run). Each plane is scanned exactly as csm_sat.cl scans it: each lane
 * sums its run of R / lanes values in order (minus the plane's mean when
 * sub is 1), the lanes' run sums are scanned in the same tree in local
 * memory, and each lane adds the sum of the runs before its own. part:
 * 2 lanes x chunk floats.
 * Twin: host/src/dynamic/twins/csm_sat.c.
 */

__kernel void hl_csm_sat_scan_items(__global float *buf, __global const float *mean, uint R, uint P, uint step,
                                    uint line_step, uint sub, uint chunk, __local float *part)
{
    const uint lid = (uint)get_local_id(0), L = (uint)get_local_size(0) / chunk;
    const uint pc = lid % chunk, l = lid / chunk, nchunks = (P + chunk - 1) / chunk;
    const uint g = (uint)get_group_id(0), lineall = g / nchunks, p = (g % nchunks) * chunk + pc;
    const uint line = lineall % R, light = lineall / R;
    const int live = p < P;
    __global float *b = buf + (size_t)light * P * R * R + (size_t)line * line_step;
    const float m = live && sub ? mean[(size_t)light * P + p] : 0.0f;
    const uint run = R / L, i0 = l * run;
    float acc = 0.0f;
    for (uint i = i0; live && i < i0 + run; i++) {
        __global float *e = b + (size_t)i * step + p;
        acc += *e - (sub ? m : 0.0f);
        *e = acc;
    }
    __local float *a = part, *t = part + L * chunk;
    a[l * chunk + pc] = acc;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint off = 1; off < L; off <<= 1) {
        float v = a[l * chunk + pc];
        if (l >= off) v = a[(l - off) * chunk + pc] + v;
        t[l * chunk + pc] = v;
        barrier(CLK_LOCAL_MEM_FENCE);
        __local float *x = a;
        a = t;
        t = x;
    }
    if (l > 0 && live) {
        const float off = a[(l - 1) * chunk + pc];
        for (uint i = i0; i < i0 + run; i++) b[(size_t)i * step + p] += off;
    }
}
