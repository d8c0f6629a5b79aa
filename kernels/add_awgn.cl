// Additive white Gaussian noise at a signal-to-noise ratio relative to each row's measured
// power (MATLAB's awgn(x, snr, 'measured')): out = x + n * sqrt(mean(x^2) / snr_linear).
__kernel void add_awgn(__global const float *signal, __global const float *normal,
                       __global const float2 *stats, const float inv_snr_linear,
                       const int n_bins, __global float *out)
{
    const int k = get_global_id(0);
    const int row = get_global_id(1);
    if (k >= n_bins) return;
    const int i = row * n_bins + k;
    out[i] = fma(normal[i], sqrt(stats[row].y * inv_snr_linear), signal[i]);
}
