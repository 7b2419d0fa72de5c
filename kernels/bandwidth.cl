/* bandwidth.cl - the device's read bandwidth, the limit the dot products
 * are measured against. Each work-item sums its own contiguous chunk with
 * vector loads (the shape that reaches memory speed on PoCL's CPU device)
 * and writes one word, so the result cannot be optimised away.
 */
kernel void hl_read_bandwidth(global const uint4 *buf, ulong per_item, global uint *out)
{
    size_t i = get_global_id(0);
    global const uint4 *p = buf + i * per_item;
    uint4 acc = (uint4)(0u);
    for (ulong k = 0; k < per_item; k++) acc += p[k];
    out[i] = acc.x ^ acc.y ^ acc.z ^ acc.w;
}
