"""block_max (kernels/block_max.cl): the maximum of each run of `block` bins of every row.

block_max(signal (rows, n_bins), block) -> (rows, ceil(n_bins / block)); the last run may be
shorter. Coarse-to-fine search (nlos_cl/localization/search.py) dilates these (max_filter over
blocks) to bound its coarse cells where the window spans hundreds of bins (1 ps SPAD records),
reading the record once instead of running max_filter's two passes over it.
"""
from __future__ import annotations

import numpy as np

from .base import Example, Operation


def numpy(signal, block):
    x = np.asarray(signal, np.float64)
    block = int(block)
    n_blocks = -(-x.shape[1] // block)
    padded = np.full((x.shape[0], n_blocks * block), -np.inf)
    padded[:, :x.shape[1]] = x
    return padded.reshape(x.shape[0], n_blocks, block).max(axis=2)


def opencl(rt, signal, block, out=None):
    n_rows, n_bins = signal.shape
    block = int(block)
    n_blocks = -(-n_bins // block)
    shape = (n_rows, n_blocks)
    out = out if out is not None and out.shape == shape else rt.empty(shape)
    rt.run(rt.kernel("block_max", "block_max", BLOCK=block), (n_blocks, n_rows), signal,
           np.int32(n_bins), np.int32(n_blocks), out)
    return out


def _inputs(rows, n_bins, block, seed=4):
    data = np.random.default_rng(seed).standard_normal((rows, n_bins)).astype(np.float32)
    data[:, : n_bins // 3] -= 5.0  # all negative there: no zero may stand in for a bin
    return lambda be: (be.from_numpy(data), block)


def examples(size):
    if size == "bench":
        return [Example("SPAD array: 1024 x 16,384 bins, blocks of 41", _inputs(1024, 16_384, 41),
                        0.0, work=1024 * 16_384, unit="bins")]
    if size == "tiny":  # a partial last block, a block longer than the row, one bin a block
        return [Example("2 x 50 bins, blocks of 7", _inputs(2, 50, 7), 0.0),
                Example("2 x 5 bins, blocks of 8", _inputs(2, 5, 8), 0.0),
                Example("2 x 9 bins, blocks of 1", _inputs(2, 9, 1), 0.0)]
    return [Example(f"3 x 60,000 bins, blocks of {b}", _inputs(3, 60_000, b), 0.0)
            for b in (1, 16, 41, 83)] + [Example("1024 x 4096 bins, blocks of 37",
                                                _inputs(1024, 4096, 37), 0.0)]


OP = Operation(
    "block_max", "block_max", opencl, numpy, examples,
    tolerance_note="exact: a maximum rounds nothing, so device and twin agree bit for bit.",
    bound="bandwidth (one read per bin)")
