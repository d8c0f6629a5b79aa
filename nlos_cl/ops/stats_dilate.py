"""stats_dilate (kernels/max_filter.cl): row_stats and max_filter's short-window dilation in
one launch, for the fused coarse-to-fine search (nlos_cl/search.py), where every launch saved
is a share of a frame.

stats_dilate(signal (rows, n_bins), half) -> (stats (rows, 2) as row_stats, dilated (rows,
n_bins + 2 half) as max_filter), for windows 2 half + 1 <= max_filter.DIRECT_MAX_WINDOW bins.
The stats come from row_stats.cl's loop, operation for operation (scores computed with either
are bit-identical: tests/localization/test_search.py compares them exactly).
"""
from __future__ import annotations

import numpy as np

from . import max_filter, row_stats
from .base import Example, Operation, relative_error


def numpy(signal, half):
    return row_stats.numpy(signal), max_filter.numpy(signal, half)


def opencl(rt, signal, half, out=None):
    n_rows, n_bins = signal.shape
    half, width = int(half), 2 * int(half) + 1
    if width > max_filter.DIRECT_MAX_WINDOW:
        raise ValueError(f"stats_dilate: a window of {width} bins is longer than "
                         f"{max_filter.DIRECT_MAX_WINDOW}; use row_stats and max_filter")
    shape = (n_rows, n_bins + 2 * half)
    if out is None or isinstance(out[1], np.ndarray) or out[1].shape != shape \
            or out[0].shape != (n_rows, 2):
        out = (rt.empty((n_rows, 2)), rt.empty(shape))
    blocks = -(-shape[1] // width)
    rt.run(rt.kernel("max_filter", "stats_dilate"), (blocks + 1, n_rows), signal,
           np.int32(n_bins), np.int32(half), np.int32(blocks), *out)
    return out


def _error(device, twin) -> float:
    """row_stats' relative error on the stats (a float32 sum); the dilation must be exact."""
    if not np.array_equal(device[1], twin[1]):
        return float("inf")
    return relative_error(device[0], twin[0])


def _inputs(rows, n_bins, half, seed=3):
    data = np.random.default_rng(seed).standard_normal((rows, n_bins)).astype(np.float32)
    data[:, : n_bins // 4] -= 5.0  # all negative: the zeros past the record must win there
    return lambda be: (be.from_numpy(data), half)


def examples(size):
    if size == "tiny":  # a partial last block, a window longer than the row
        return [Example("2 x 50 bins, half 3", _inputs(2, 50, 3), 1e-5, _error),
                Example("2 x 9 bins, half 6", _inputs(2, 9, 6), 1e-5, _error)]
    return [Example("3 x 4096 bins, half 16 (a stream frame)", _inputs(3, 4096, 16), 1e-5,
                    _error, work=3 * 4096, unit="bins")]


OP = Operation(
    "stats_dilate", "max_filter", opencl, numpy, examples,
    tolerance_note="stats: row_stats' 1e-5 (a sequential float32 sum); dilation: exact.",
    bound="launches (one per frame instead of two)")
