/* cube2para.cl - cubemap visibility to dual-paraboloid transport.
 * Each work-item does HL_C2P_ROWS vertices at once, so the table (about
 * 0.8 MB at N = C = 64, more than a core's L2) is read once per group of
 * rows rather than once per row. It scatters from the cube texels that
 * have visibility in any of its rows, so texels below every horizon cost a
 * few byte reads. Within a paraboloid texel the parts arrive in ascending
 * cube order, as in the twin's gather, and the zero terms added for rows
 * without visibility leave the sums unchanged, so rounding is identical.
 * Twin: host/src/maps/twins/cube2para.c.
 *   T[v][j] = scale * sum_e vis[v][e.cube] * max(0, n_v . m_e)
 */
#pragma OPENCL FP_CONTRACT OFF

#ifndef HL_C2P_ROWS
#define HL_C2P_ROWS 4
#endif

kernel void hl_cube2para(global const uchar *vis, uint ncube, float scale,
                         global const float4 *normals,
                         global const uint *start, global const hl_c2p_entry *ent,
                         uint ncoef, global float *T, uint nverts)
{
    uint v0 = get_global_id(0) * HL_C2P_ROWS;
    if (v0 >= nverts) return;
    uint nr = min((uint)HL_C2P_ROWS, nverts - v0);
    float4 n[HL_C2P_ROWS];
    for (uint r = 0; r < HL_C2P_ROWS; r++) n[r] = r < nr ? normals[v0 + r] : (float4)(0.0f);
    global const uchar *row = vis + (size_t)v0 * ncube;
    global float *out = T + (size_t)v0 * ncoef;
    for (uint j = 0; j < nr * ncoef; j++) out[j] = 0.0f;
    for (uint c = 0; c < ncube; c++) {
        if ((c & 3u) == 0 && c + 4 <= ncube) {
            /* skip 4 texels at once where no row sees anything (the
               culled half of the sphere is all zeros) */
            uint word = 0;
            for (uint r = 0; r < nr; r++) word |= as_uint(vload4(0, row + (size_t)r * ncube + c));
            if (!word) { c += 3; continue; }
        }
        float fv[HL_C2P_ROWS];
        uint any = 0;
        for (uint r = 0; r < HL_C2P_ROWS; r++) {
            uint vv = r < nr ? row[(size_t)r * ncube + c] : 0u;
            fv[r] = (float)vv;
            any |= vv;
        }
        if (!any) continue;
        uint end = start[c + 1];
        for (uint e = start[c]; e < end; e++) {
            hl_c2p_entry t = ent[e];
            for (uint r = 0; r < nr; r++) {
                float w = n[r].x * t.mx + n[r].y * t.my + n[r].z * t.mz;
                out[(size_t)r * ncoef + t.index] += fv[r] * fmax(w, 0.0f);
            }
        }
    }
    for (uint j = 0; j < nr * ncoef; j++) out[j] *= scale;
}
