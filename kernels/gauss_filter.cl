// Gauss filter (paper Eq. 24): P'(t) = integral over [t - h, t + h] of P(tau) N(tau - t; 0, h/3).
// Discretised as a correlation with TAPS = 2 HALF + 1 weights dt N(j dt; 0, h/3), |j| <= HALF.
// TAPS is a build option so the loop has a compile-time trip count: PoCL then vectorizes across
// work items. The input is zero-padded by HALF bins on both sides (pad_rows), so the inner loop
// has no bounds checks.
//
// Build options: -D HALF=<taps on each side> -D TAPS_SPACE=__constant|__global

#define TAPS (2 * HALF + 1)

__kernel void pad_rows(__global const float *src,  // [n_rows][n_bins]
                       const int n_bins,
                       __global float *padded)     // [n_rows][n_bins + 2 HALF]
{
    const int j = get_global_id(0);
    const int row = get_global_id(1);
    const int width = n_bins + 2 * HALF;
    if (j >= width) return;
    const int k = j - HALF;
    padded[row * width + j] = (k >= 0 && k < n_bins) ? src[row * n_bins + k] : 0.0f;
}

__kernel void gauss_filter(__global const float *padded,  // [n_rows][n_bins + 2 HALF]
                           TAPS_SPACE const float *taps,   // [TAPS]
                           const int n_bins,
                           __global float *out)            // [n_rows][n_bins]
{
    const int k = get_global_id(0);
    const int row = get_global_id(1);
    if (k >= n_bins) return;
    __global const float *src = padded + row * (n_bins + 2 * HALF) + k;
    float acc = 0.0f;
    for (int j = 0; j < TAPS; ++j)
        acc = fma(src[j], taps[j], acc);
    out[row * n_bins + k] = acc;
}
