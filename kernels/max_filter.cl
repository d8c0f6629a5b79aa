// Running maximum over a window of 2 reach + 1 bins, per row, zero outside the record, over
// the record widened by `reach` bins on both sides (the maximum reaches that far):
// out[j] = max(x[k - reach .. k + reach]) for k = j - reach, x = 0 outside. Coarse-to-fine
// scoring (nlos_cl/search.py) scores a coarse grid with these rows to bound every cell of a
// coarse cell's block from above.
//
// van Herk / Gil-Werman: each row is cut into blocks of W = 2 reach + 1 bins (values past the
// record are 0); block_scans writes every block's prefix and suffix maxima, then any window is
// max(suffix at its first bin, prefix at its last bin): 3 comparisons per bin whatever HALF.
// Exact (max rounds nothing), deterministic, no atomics.

__kernel void block_scans(__global const float *src,  // [rows][n_bins]
                          const int n_bins, const int reach, const int padded,
                          const int row0,             // the group's first row (row groups)
                          __global float *prefix,     // [group][padded]: padded = blocks * W
                          __global float *suffix)
{
    const int w = 2 * reach + 1;
    const int b = get_global_id(0), row = get_global_id(1);
    const int k0 = b * w;
    __global const float *x = src + (row0 + row) * n_bins;
    __global float *p = prefix + row * padded, *s = suffix + row * padded;
    float run = -INFINITY;
    for (int j = 0; j < w; ++j) {
        const int k = k0 + j;
        run = fmax(run, k < n_bins ? x[k] : 0.0f);
        p[k] = run;
    }
    run = -INFINITY;
    for (int j = w - 1; j >= 0; --j) {
        const int k = k0 + j;
        run = fmax(run, k < n_bins ? x[k] : 0.0f);
        s[k] = run;
    }
}

__kernel void window_max(__global const float *prefix, __global const float *suffix,
                         const int n_bins, const int reach, const int padded,
                         const int row0,
                         __global float *out)          // [rows][n_bins + 2 reach]
{
    const int j = get_global_id(0), row = get_global_id(1);
    const int lo = j - 2 * reach, hi = j;
    const float left = lo >= 0 ? suffix[row * padded + lo] : 0.0f;
    const float right = hi < padded ? prefix[row * padded + hi] : 0.0f;
    out[(row0 + row) * (n_bins + 2 * reach) + j] = fmax(left, right);
}

// Short windows (2 reach + 1 <= 65 bins, nlos_cl/ops/max_filter.py): one launch. Block b of a
// row holds the W = 2 reach + 1 outputs j0 = b W .. j0 + W - 1: output j0 + t is the maximum of
// x[j0 - 2 reach + t .. j0 - 1] (a suffix maximum of the 2 reach bins left of the block, kept
// in private memory) and x[j0 .. j0 + t] (a running prefix maximum): about two loads per
// output, the same values as the two passes above (a maximum rounds nothing).
inline void dilate_block(__global const float *x, const int n_bins, const int reach,
                         const int b, __global float *o)
{
    const int w = 2 * reach + 1, n_out = n_bins + 2 * reach;
    const int j0 = b * w;
    float left[64];  // left[t]: max of x[j0 - 2 reach + t .. j0 - 1], 0 outside the record
    float run = -INFINITY;
    for (int t = 2 * reach - 1; t >= 0; --t) {
        const int k = j0 - 2 * reach + t;
        run = fmax(run, (k >= 0 && k < n_bins) ? x[k] : 0.0f);
        left[t] = run;
    }
    run = -INFINITY;
    for (int t = 0; t < w && j0 + t < n_out; ++t) {
        const int k = j0 + t;
        run = fmax(run, k < n_bins ? x[k] : 0.0f);
        o[k] = t < 2 * reach ? fmax(left[t], run) : run;
    }
}

__kernel void window_direct(__global const float *src,  // [rows][n_bins]
                            const int n_bins, const int reach,
                            __global float *out)        // [rows][n_bins + 2 reach]
{
    const int b = get_global_id(0), row = get_global_id(1);
    dilate_block(src + row * n_bins, n_bins, reach, b, out + row * (n_bins + 2 * reach));
}

// stats_dilate (nlos_cl/ops/stats_dilate.py): row_stats and the short-window dilation in one
// launch, for the fused coarse-to-fine search. Work items 0 .. blocks - 1 of a row dilate as
// window_direct; item `blocks` computes the row's (max, mean of squares) with row_stats.cl's
// loop, operation for operation, so the scores match scoring with row_stats bit for bit.
__kernel void stats_dilate(__global const float *src, const int n_bins, const int reach,
                           const int blocks, __global float2 *stats, __global float *out)
{
    const int b = get_global_id(0), row = get_global_id(1);
    __global const float *x = src + row * n_bins;
    if (b < blocks) {
        dilate_block(x, n_bins, reach, b, out + row * (n_bins + 2 * reach));
        return;
    }
    float peak = -INFINITY, sq = 0.0f;
    for (int k = 0; k < n_bins; ++k) {
        peak = fmax(peak, x[k]);
        sq = fma(x[k], x[k], sq);
    }
    stats[row] = (float2)(peak, sq / (float)n_bins);
}
