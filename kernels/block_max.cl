// Per row, the maximum of each run of BLOCK consecutive bins (the last run may be shorter):
// out[row][b] = max(x[b BLOCK .. min((b + 1) BLOCK, n_bins) - 1]). Coarse-to-fine search
// (nlos_cl/localization/search.py) bounds its coarse cells on a record far longer than its
// window by dilating these block maxima (max_filter over blocks) instead of every bin: one read
// of the record instead of max_filter's two passes over it and its widened copy. Exact (a
// maximum rounds nothing). Build option: -D BLOCK=<bins per block> (a fixed loop: vectorized).

__kernel void block_max(__global const float *src, const int n_bins, const int n_blocks,
                        __global float *out)
{
    const int b = get_global_id(0), row = get_global_id(1);
    const int k0 = b * BLOCK;
    __global const float *x = src + row * n_bins + k0;
    float run = -INFINITY;
    if (k0 + BLOCK <= n_bins) {
        for (int j = 0; j < BLOCK; ++j) run = fmax(run, x[j]);
    } else {  // the row's last, partial block
        for (int j = 0; j < n_bins - k0; ++j) run = fmax(run, x[j]);
    }
    out[row * n_blocks + b] = run;
}
