/* bandwidth.cl - the device's read bandwidth, the limit the dot products
 * are measured against. Each work-item sums its own contiguous chunk with
 * 64-byte vector loads into two independent sums (the shape that reads
 * fastest on PoCL's CPU device; one uint4 sum read 10-25% slower here) and
 * writes one word, so the result cannot be optimised away. per_item is
 * even (counted in float16). The CPU shape's probe.
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

/* The GPU shape's probe: at each step neighbouring work-items read
 * neighbouring float4s (work-item i reads i, i + n, i + 2n, ... of count,
 * n the launch's work-items), with enough work-items to fill the device,
 * the pattern a GPU's memory reads fastest; two sums, as above. */
kernel void hl_read_bandwidth_grid(global const float4 *buf, ulong count, global float *out)
{
    const size_t i = get_global_id(0), n = get_global_size(0);
    float4 a = (float4)(0.0f), b = (float4)(0.0f);
    ulong k = i;
    for (; k + n < count; k += 2 * n) {
        a += buf[k];
        b += buf[k + n];
    }
    if (k < count) a += buf[k];
    a += b;
    out[i] = a.x + a.y + a.z + a.w;
}
