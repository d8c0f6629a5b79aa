// Small per-row helpers that keep the pipeline on the device.

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

// First stage of argmax: work item w scans cells [w * per_item, (w + 1) * per_item) and keeps
// the first maximum (strict >), so ties resolve to the lowest index on every device.
__kernel void argmax_partial(__global const float *score, const int n_cells, const int per_item,
                             __global float *best_value, __global int *best_index)
{
    const int w = get_global_id(0);
    const int start = w * per_item;
    const int stop = min(start + per_item, n_cells);
    float best = -INFINITY;
    int where = -1;
    for (int i = start; i < stop; ++i) {
        const float v = score[i];
        if (v > best) { best = v; where = i; }
    }
    best_value[w] = best;
    best_index[w] = where;
}
