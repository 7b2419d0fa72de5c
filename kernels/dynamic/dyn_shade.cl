/* dyn_shade.cl - the dynamic frame's receivers on the device, where the
 * host takes them light by light on the reference backend
 * (host/src/dynamic/dyn_frame.c): a group of a batch's lights at once,
 * over every receiver, with nothing read back but the sums at the end.
 *
 * Entry j of a group is split light ks[j]; its pack of the map
 * (HL_DYN_LF floats at lf + j HL_DYN_LF), its blocks for the flat bodies
 * (HL_DYN_FL at fl + j HL_DYN_FL). Work-item j N + v takes receiver v of
 * entry j. A receiver the light does not reach (E_k = 0 in every
 * channel) gets u = NaN in uvd, and the later stages pass it by, as the
 * host's compaction leaves it out. The same formulas as the host's
 * (hl_dyn_receiver, hl_dyn_flat_one in hl_shared.h) and the same
 * additions in the same order (each receiver's lights in group order),
 * so the same sums bit for bit.
 * Twin: host/src/dynamic/dyn_frame.c (prepare_light, flat_occlusion,
 * finish_light, the negligible lights of irradiance()).
 */
#pragma OPENCL FP_CONTRACT OFF

/* Receiver v of entry j in its map: (u, v, d) and its plane (rpl,
 * HL_DYN_RPL floats), or u = NaN where the light does not reach it.
 * zmin: each batch map's nearest depth (hl_csm_zmin), kbs: entry j's
 * batch map. */
kernel void hl_dyn_prepare(global const float *E, global const uint *ks, global const uint *kbs, uint N, uint nl,
                           global const float *wpos, global const float *wnrm, global const uint *body,
                           global const float *lf, global const float *zmin, global float *uvd, global float *rpl)
{
    const size_t id = get_global_id(0);
    if (id >= (size_t)nl * N) return;
    const uint j = (uint)(id / N), v = (uint)(id % N);
    global const float *e = E + ((size_t)ks[j] * N + v) * 3;
    global float *o = uvd + 3 * id;
    if (!(e[0] > 0.0f || e[1] > 0.0f || e[2] > 0.0f)) {
        o[0] = NAN;
        o[1] = 0.0f;
        o[2] = 0.0f;
        return;
    }
    const float p[3] = {wpos[3 * v], wpos[3 * v + 1], wpos[3 * v + 2]};
    const float n[3] = {wnrm[3 * v], wnrm[3 * v + 1], wnrm[3 * v + 2]};
    float r[3], pl[HL_DYN_RPL];
    hl_dyn_receiver(lf + (size_t)j * HL_DYN_LF, zmin[kbs[j]], p, n, body[v], r, pl);
    o[0] = r[0];
    o[1] = r[1];
    o[2] = r[2];
    for (uint i = 0; i < HL_DYN_RPL; i++) rpl[HL_DYN_RPL * id + i] = pl[i];
}

/* The flat rectangles (nflat of them, fb; bodies flat_body) out of entry
 * j's map, on its receivers' visibility V, in body order. */
kernel void hl_dyn_flat(global const float *uvd, uint N, uint nl, global const float *lf, global const float *fl,
                        global const float *fb, global const uint *flat_body, uint nflat, global const float *wpos,
                        global const float *wnrm, global float *V)
{
    const size_t id = get_global_id(0);
    if (id >= (size_t)nl * N || isnan(uvd[3 * id])) return;
    const uint j = (uint)(id / N), v = (uint)(id % N);
    const uint mask = as_uint(lf[(size_t)j * HL_DYN_LF + 15]);
    if (!mask) return;
    const float x[3] = {wpos[3 * v], wpos[3 * v + 1], wpos[3 * v + 2]};
    const float n[3] = {wnrm[3 * v], wnrm[3 * v + 1], wnrm[3 * v + 2]};
    float vis = V[id];
    for (uint b = 0; b < nflat; b++)
        if ((mask >> flat_body[b]) & 1u)
            vis = hl_dyn_flat_one(fl + (size_t)j * HL_DYN_FL, fb + (size_t)b * HL_DYN_FB, x, n, v, vis);
    V[id] = vis;
}

/* acc += V E over the group's entries in order, at receiver v. */
kernel void hl_dyn_accumulate(global const float *uvd, global const float *V, global const float *E,
                              global const uint *ks, uint N, uint nl, global float *acc)
{
    const uint v = (uint)get_global_id(0);
    if (v >= N) return;
    float a0 = acc[3 * v], a1 = acc[3 * v + 1], a2 = acc[3 * v + 2];
    for (uint j = 0; j < nl; j++) {
        const size_t id = (size_t)j * N + v;
        if (isnan(uvd[3 * id])) continue;
        global const float *e = E + ((size_t)ks[j] * N + v) * 3;
        const float w = V[id];
        a0 += w * e[0];
        a1 += w * e[1];
        a2 += w * e[2];
    }
    acc[3 * v] = a0;
    acc[3 * v + 1] = a1;
    acc[3 * v + 2] = a2;
}

/* acc += E_k for the listed lights (those too faint for a shadow map),
 * in list order, at receiver v. */
kernel void hl_dyn_add_lights(global const float *E, global const uint *list, uint count, uint N, global float *acc)
{
    const uint v = (uint)get_global_id(0);
    if (v >= N) return;
    for (uint i = 0; i < count; i++) {
        global const float *e = E + ((size_t)list[i] * N + v) * 3;
        acc[3 * v] += e[0];
        acc[3 * v + 1] += e[1];
        acc[3 * v + 2] += e[2];
    }
}
