"""max_filter (kernels/max_filter.cl): a running maximum along each row, zero outside it.

max_filter(signal (rows, n_bins), half) -> (rows, n_bins + 2 half): the record widened by
`half` bins on each side, out[k + half] = max of signal[k - half .. k + half], with
signal = 0 outside the record.
Coarse-to-fine scoring (nlos_cl/search.py) scores a coarse grid with these rows: a cell whose
path lies within `half` bins of a coarse cell's path scores at most what the coarse cell scores
on the dilated rows, so whole blocks of cells can be ruled out without scoring them.
"""
from __future__ import annotations

import numpy as np

from .base import Example, Operation

# Windows up to this many bins: one launch (window_direct, ~2 loads per output, the block's
# left context in 64 floats of private memory); longer ones: the two passes, 3 per bin.
DIRECT_MAX_WINDOW = 65


def numpy(signal, half):
    from scipy.ndimage import maximum_filter1d
    half = int(half)
    wide = np.pad(np.asarray(signal, np.float64), ((0, 0), (half, half)))
    return maximum_filter1d(wide, size=2 * half + 1, axis=-1, mode="constant", cval=0.0)


def opencl(rt, signal, half, out=None):
    n_rows, n_bins = signal.shape
    half = int(half)
    width = 2 * half + 1
    n_blocks = -(-n_bins // width)
    padded = n_blocks * width
    shape = (n_rows, n_bins + 2 * half)
    out = out if out is not None and out.shape == shape else rt.empty(shape)
    if width <= DIRECT_MAX_WINDOW:
        rt.run(rt.kernel("max_filter", "window_direct"), (-(-shape[1] // width), n_rows), signal,
               np.int32(n_bins), np.int32(half), out)
        return out
    for r0, r1 in rt.groups(n_rows, 8 * padded, "a row's prefix and suffix maxima"):
        prefix, suffix = rt.empty((r1 - r0, padded)), rt.empty((r1 - r0, padded))
        common = (np.int32(n_bins), np.int32(half), np.int32(padded), np.int32(r0))
        rt.run(rt.kernel("max_filter", "block_scans"), (n_blocks, r1 - r0), signal, *common,
               prefix, suffix)
        rt.run(rt.kernel("max_filter", "window_max"), (shape[1], r1 - r0), prefix, suffix,
               *common, out)
    return out


def _inputs(rows, n_bins, half, seed=2):
    data = np.random.default_rng(seed).standard_normal((rows, n_bins)).astype(np.float32)
    data[:, : n_bins // 4] -= 5.0  # all negative: the zeros past the record must win there
    return lambda be: (be.from_numpy(data), half)


def examples(size):
    if size == "bench":
        return [Example("SPAD array: 1024 x 4096 bins, half 24", _inputs(1024, 4096, 24), 0.0,
                        work=1024 * 4096, unit="bins")]
    if size == "tiny":  # direct windows; two passes: a partial last block, a window longer
        # than the row, row groups
        return [Example("2 x 50 bins, half 3 (direct)", _inputs(2, 50, 3), 0.0),
                Example("2 x 9 bins, half 6 (direct)", _inputs(2, 9, 6), 0.0),
                Example("2 x 150 bins, half 40", _inputs(2, 150, 40), 0.0),
                Example("2 x 30 bins, half 40", _inputs(2, 30, 40), 0.0),
                Example("3 rows in groups of 2", _inputs(3, 200, 33), 0.0,
                        max_alloc_bytes=2 * 8 * 201)]
    return [Example(f"3 x 60,000 bins, half {h}", _inputs(3, 60_000, h), 0.0)
            for h in (1, 16, 140)] + [Example("1024 x 4096 bins, half 24", _inputs(1024, 4096, 24),
                                          0.0)]


OP = Operation(
    "max_filter", "max_filter", opencl, numpy, examples,
    tolerance_note="exact: a maximum rounds nothing, so device and twin agree bit for bit.",
    bound="bandwidth (3 reads and 3 writes per bin)")
