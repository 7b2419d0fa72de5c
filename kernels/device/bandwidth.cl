/* bandwidth.cl - the device's read bandwidth, the limit the dot products
 * are measured against. Each work-item sums its own contiguous chunk with
 * 64-byte vector loads into two independent sums (the shape that reads
 * fastest on PoCL's CPU device; one uint4 sum read 10-25% slower here) and
 * writes one word, so the result cannot be optimised away. per_item is
 * even (counted in float16).
 */
kernel void hl_read_bandwidth(global const float16 *buf, ulong per_item, global float *out)
{
    size_t i = get_global_id(0);
    global const float16 *p = buf + i * per_item;
    float16 a = (float16)(0.0f), b = (float16)(0.0f);
    for (ulong k = 0; k < per_item; k += 2) {
        a += p[k];
        b += p[k + 1];
    }
    a += b;
    out[i] = a.s0 + a.s5 + a.sa + a.sf;
}
