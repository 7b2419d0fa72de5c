/* cube2para.cl - cubemap visibility to dual-paraboloid transport.
 * One work-item per vertex walks its own rows (the shape PoCL's CPU device
 * runs at memory speed). Twin: host/src/ref/cube2para_ref.c.
 *   T[v][j] = scale * sum_e vis[v][e.cube] * max(0, n_v . m_e)
 */
#pragma OPENCL FP_CONTRACT OFF

kernel void hl_cube2para(global const uchar *vis, uint ncube, float scale,
                         global const float4 *normals,
                         global const uint *start, global const hl_c2p_entry *ent,
                         uint ncoef, global float *T, uint nverts)
{
    uint v = get_global_id(0);
    if (v >= nverts) return;
    float4 n = normals[v];
    global const uchar *row = vis + (size_t)v * ncube;
    global float *out = T + (size_t)v * ncoef;
    uint e = start[0];
    for (uint j = 0; j < ncoef; j++) {
        uint end = start[j + 1];
        float acc = 0.0f;
        for (; e < end; e++) {
            hl_c2p_entry c = ent[e];
            uint vv = row[c.cube];
            if (!vv) continue;
            float w = n.x * c.mx + n.y * c.my + n.z * c.mz;
            if (w > 0.0f) acc += (float)vv * w;
        }
        out[j] = acc * scale;
    }
}
