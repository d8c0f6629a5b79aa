// Per row: (max, mean of squares). One work item per row, a sequential (deterministic) sum.
__kernel void row_stats(__global const float *data, const int n_bins, __global float2 *stats)
{
    const int row = get_global_id(0);
    __global const float *x = data + row * n_bins;
    float peak = -INFINITY, sq = 0.0f;
    for (int k = 0; k < n_bins; ++k) {
        peak = fmax(peak, x[k]);
        sq = fma(x[k], x[k], sq);
    }
    stats[row] = (float2)(peak, sq / (float)n_bins);
}
