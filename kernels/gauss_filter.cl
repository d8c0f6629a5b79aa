// Gauss filter (paper Eq. 24): P'(t) = integral over [t - h, t + h] of P(tau) N(tau - t; 0, h/3).
// Discretised as a correlation with TAPS = 2 HALF + 1 weights dt N(j dt; 0, h/3), |j| <= HALF.
// A work item owns 32 consecutive outputs in two float16 accumulators: per tap, two unaligned
// vector loads and two vector FMAs (measured on PoCL: 16x one output per work item). The input
// is zero-padded (pad_rows: HALF bins before, HALF + 32 after), so the loop has no bounds
// checks, and TAPS is a build option, so its trip count is a compile-time constant.
//
// Build options: -D HALF=<taps on each side> -D TAPS_SPACE=__constant|__global

#define TAPS (2 * HALF + 1)

// Rows are processed in groups (row0 = the group's first) when the padded copy of all rows
// would not fit in one device allocation.
__kernel void pad_rows(__global const float *src,  // [n_rows][n_bins]
                       const int n_bins,
                       const int row0,
                       __global float *padded)     // [group][n_bins + 2 HALF + 32]
{
    const int j = get_global_id(0);
    const int row = get_global_id(1);
    const int width = get_global_size(0);
    const int k = j - HALF;
    padded[row * width + j] = (k >= 0 && k < n_bins) ? src[(row0 + row) * n_bins + k] : 0.0f;
}

__kernel void gauss_filter(__global const float *padded,  // [group][n_bins + 2 HALF + 32]
                           TAPS_SPACE const float *taps,   // [TAPS]
                           const int n_bins,
                           const int row0,
                           __global float *out)            // [n_rows][n_bins]
{
    const int k = get_global_id(0) * 32;
    const int row = get_global_id(1);
    __global const float *src = padded + row * (n_bins + 2 * HALF + 32) + k;
    float16 lo = (float16)(0.0f), hi = (float16)(0.0f);
    for (int j = 0; j < TAPS; ++j) {
        const float16 w = (float16)(taps[j]);
        lo = fma(vload16(0, src + j), w, lo);
        hi = fma(vload16(0, src + j + 16), w, hi);
    }
    __global float *dst = out + (row0 + row) * n_bins + k;
    if (k + 32 <= n_bins) {
        vstore16(lo, 0, dst);
        vstore16(hi, 0, dst + 16);
    } else {  // the record's last, partial block
        float tail[32];
        vstore16(lo, 0, tail);
        vstore16(hi, 0, tail + 16);
        for (int j = 0; k + j < n_bins; ++j) dst[j] = tail[j];
    }
}
