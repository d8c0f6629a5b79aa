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
