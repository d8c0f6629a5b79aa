// Tiny kernels that measure this device's own limits, for the benchmark's "fraction of limit".
// Each work item runs independent float8 chains for ITERS iterations; the result is written so
// the compiler cannot drop the work.
//
// Build options: -D ITERS=<iterations>

#ifndef ITERS
#define ITERS 1
#endif

// 8 independent float8 exp chains: exp is throughput-bound, not latency-bound, with 8 in flight.
__kernel void exp_probe(__global float *out, const float a)
{
    float8 x0 = (float8)(a) + (float8)(0, 1, 2, 3, 4, 5, 6, 7) * 1e-3f;
    float8 x1 = x0 + 0.1f, x2 = x0 + 0.2f, x3 = x0 + 0.3f;
    float8 x4 = x0 + 0.4f, x5 = x0 + 0.5f, x6 = x0 + 0.6f, x7 = x0 + 0.7f;
    for (int i = 0; i < ITERS; ++i) {  // exp(-x) stays in (0, 1): no overflow, no denormals
        x0 = exp(-x0); x1 = exp(-x1); x2 = exp(-x2); x3 = exp(-x3);
        x4 = exp(-x4); x5 = exp(-x5); x6 = exp(-x6); x7 = exp(-x7);
    }
    const float8 s = x0 + x1 + x2 + x3 + x4 + x5 + x6 + x7;
    out[get_global_id(0)] = s.s0 + s.s1 + s.s2 + s.s3 + s.s4 + s.s5 + s.s6 + s.s7;
}

// 12 independent float8 FMA chains: enough to cover the FMA latency (an array of chains, or
// fewer, measured half of this on PoCL).
__kernel void fma_probe(__global float *out, const float a)
{
    float8 x0 = (float8)(a), x1 = x0 + 1, x2 = x0 + 2, x3 = x0 + 3, x4 = x0 + 4, x5 = x0 + 5;
    float8 x6 = x0 + 6, x7 = x0 + 7, x8 = x0 + 8, x9 = x0 + 9, x10 = x0 + 10, x11 = x0 + 11;
    const float8 m = (float8)(0.999f), c = (float8)(1e-3f);
    for (int i = 0; i < ITERS; ++i) {
        x0 = fma(x0, m, c); x1 = fma(x1, m, c); x2 = fma(x2, m, c); x3 = fma(x3, m, c);
        x4 = fma(x4, m, c); x5 = fma(x5, m, c); x6 = fma(x6, m, c); x7 = fma(x7, m, c);
        x8 = fma(x8, m, c); x9 = fma(x9, m, c); x10 = fma(x10, m, c); x11 = fma(x11, m, c);
    }
    const float8 s = x0 + x1 + x2 + x3 + x4 + x5 + x6 + x7 + x8 + x9 + x10 + x11;
    out[get_global_id(0)] = s.s0 + s.s1 + s.s2 + s.s3 + s.s4 + s.s5 + s.s6 + s.s7;
}

__kernel void copy_probe(__global const float4 *src, __global float4 *dst)
{
    const size_t i = get_global_id(0);
    dst[i] = src[i];
}
