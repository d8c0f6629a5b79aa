"""row_stats (kernels/row_stats.cl): per histogram row, (max, mean of squares). The score
normalises by the max; the noise is set from the mean square. row_stats(signal) -> (rows, 2)."""
from __future__ import annotations

import numpy as np

from .base import Example, Operation


def numpy(signal):
    signal = np.asarray(signal, np.float64)
    return np.stack([signal.max(axis=1), np.mean(signal ** 2, axis=1)], axis=1)


def opencl(rt, signal, out=None):
    stats = out if out is not None else rt.empty((signal.shape[0], 2))
    rt.run(rt.kernel("row_stats", "row_stats"), (signal.shape[0],), signal,
           np.int32(signal.shape[1]), stats)
    return stats


def examples(size):
    rows, n = (2, 37) if size == "tiny" else (4, 3000)
    data = np.abs(np.random.default_rng(2).standard_normal((rows, n))).astype(np.float32)
    return [Example(f"{rows} x {n} bins", lambda be: (be.from_numpy(data),), 1e-5)]


OP = Operation("row_stats", "row_stats", opencl, numpy, examples,
               tolerance_note="1e-5 relative: a sequential float32 sum of 3000 squares errs "
               "~sqrt(3000) 6e-8 = 3e-6.", bound="bandwidth")
