"""add_awgn (kernels/add_awgn.cl): white Gaussian noise at snr_db below each row's measured
power (mean of squares over the whole record: MATLAB's awgn(x, snr, 'measured')).
add_awgn(signal, normal draws, snr_db) -> noisy signal. The draws come from the backend's
seeded generator (`standard_normal`), so both sides can be given the same ones."""
from __future__ import annotations

import numpy as np

from .base import Example, Operation


def numpy(signal, normal, snr_db):
    signal = np.asarray(signal, np.float64)
    power = np.mean(signal ** 2, axis=1, keepdims=True)
    return signal + np.asarray(normal, np.float64) * np.sqrt(power / 10.0 ** (snr_db / 10.0))


def opencl(rt, signal, normal, snr_db, out=None):
    from .row_stats import opencl as row_stats
    n_rows, n_bins = signal.shape
    stats = row_stats(rt, signal)
    out = out if out is not None else rt.empty(signal.shape)
    rt.run(rt.kernel("add_awgn", "add_awgn"), (n_bins, n_rows), signal, normal, stats,
           np.float32(10.0 ** (-snr_db / 10.0)), np.int32(n_bins), out)
    return out


def examples(size):
    rows, n = (2, 37) if size == "tiny" else (4, 3000)
    rng = np.random.default_rng(2)
    data = np.abs(rng.standard_normal((rows, n))).astype(np.float32)
    normal = rng.standard_normal((rows, n)).astype(np.float32)
    return [Example(f"{rows} x {n} bins at 10 dB",
                    lambda be: (be.from_numpy(data), be.from_numpy(normal), 10.0), 1e-5)]


OP = Operation("add_awgn", "add_awgn", opencl, numpy, examples,
               tolerance_note="1e-5 of the peak: the row power is a float32 sum (3e-6) and one "
               "FMA per bin.", bound="bandwidth")
