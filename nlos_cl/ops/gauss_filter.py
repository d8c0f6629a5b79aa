"""gauss_filter (kernels/gauss_filter.cl): the paper's Gauss filter, Eq. 24.

P'(t) = integral over [t - h, t + h] of P(tau) N(tau - t; 0, h/3), discretised as a correlation
with the taps below (zero outside the record). Signature (both backends):
gauss_filter(signal (rows, n_bins), taps, taps_space=None, method=None) -> (rows, n_bins).

method: "direct" (the kernel: work per bin grows with the taps), "fft" (overlap-add FFT,
SciPy's oaconvolve on the host: only for CPU devices, whose buffers are host memory, so the
round trip is two memory copies), or None: "fft" on a CPU device from FFT_MIN_TAPS taps,
"direct" otherwise. The crossover was measured on the 2-core CPU (PoCL 3.1): 131 taps direct
1.1 ms vs FFT round trip 1.4 ms, 1,301 taps 13.7 ms vs 6.1 ms (3 x 60,000 bins). VkFFT
(pyvkfft) would keep the FFT on the device: see docs/results/performance/performance.md for why it
is not used.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.constants import PAPER_H_S
from .base import Example, Operation

OUTPUTS_PER_ITEM = 32  # two float16 accumulators per work item (gauss_filter.cl)
FFT_MIN_TAPS = 400  # from here a CPU device filters by FFT (measured crossover: ~170-400)


# The default window spans at least this many bins each side (sigma 2/3 of a bin): the paper's
# 0.65 ns is narrower than one bin of a 1 ns TDC (the VL53L1X's bins are 1.33 ns), where it
# would only rescale the data and was refused; the filter's job, noise averaged over the pulse's
# scale, then falls to a few bins. Not 3: a 250 ps TDC (the consumer-nlos walk) would leave the
# paper's window for 0.75 ns, and its track split in two; at 1-1.5 ns bins 1-3 bins located
# alike (median 0.10-0.18 m, 9 draws: the model at coarse bins, not the window, limits them).
MIN_WINDOW_BINS = 2


def filter_window(dt_s: float, h_s: float | None = None) -> float:
    """The Gauss filter's window h for bins of dt_s: `h_s` where given; by default the paper's
    0.65 ns or MIN_WINDOW_BINS bins, whichever is wider."""
    return float(h_s) if h_s is not None else max(PAPER_H_S, MIN_WINDOW_BINS * float(dt_s))


def gauss_taps(h_s: float, dt_s: float) -> np.ndarray:
    """The discretised filter: dt N(j dt; 0, h/3) for |j| <= floor(h / dt)."""
    half = int(math.floor(h_s / dt_s + 1e-9))
    sigma = h_s / 3.0
    j = np.arange(-half, half + 1) * dt_s
    return dt_s / (math.sqrt(2.0 * math.pi) * sigma) * np.exp(-0.5 * (j / sigma) ** 2)


def numpy(signal, taps, taps_space=None, method=None):
    """out[k] = sum_j signal[k + j - half] taps[j], zero outside the record. (taps_space only
    says where the kernel keeps the taps: the result does not depend on it.)"""
    from scipy.ndimage import correlate1d
    return correlate1d(np.asarray(signal, dtype=np.float64), np.asarray(taps, dtype=np.float64),
                       axis=-1, mode="constant", cval=0.0)


def _fft(rt, signal, taps, out):
    """Overlap-add FFT on the host (CPU devices): zero outside the record, as the kernel."""
    from scipy.signal import oaconvolve
    host = signal.get(rt.queue)
    kernel = np.asarray(taps, np.float32)[None, ::-1]  # a correlation: the reversed taps
    result = oaconvolve(host, kernel, mode="same", axes=1).astype(np.float32)
    if out is None:
        return rt.from_numpy(result)
    out.set(result, queue=rt.queue)
    return out


def opencl(rt, signal, taps, taps_space=None, method=None, out=None):
    if method is None:
        method = "fft" if taps_space is None and len(taps) >= FFT_MIN_TAPS and rt.on_cpu \
            else "direct"
    if method == "fft":
        return _fft(rt, signal, taps, out)
    n_rows, n_bins = signal.shape
    half = (len(taps) - 1) // 2
    if taps_space is None:  # __constant where the device has room for the taps
        fits = 4 * len(taps) <= rt.device.max_constant_buffer_size
        taps_space = "__constant" if fits else "__global"
    defines = dict(HALF=half, TAPS_SPACE=taps_space)
    pad_kernel = rt.kernel("gauss_filter", "pad_rows", **defines)
    filter_kernel = rt.kernel("gauss_filter", "gauss_filter", **defines)
    taps_buf = rt.constant(taps)
    # Zero margins: HALF bins before, HALF + a block after (the last block reads past the end).
    width = n_bins + 2 * half + OUTPUTS_PER_ITEM
    out = out if out is not None else rt.empty(signal.shape)
    for r0, r1 in rt.groups(n_rows, 4 * width, "a zero-padded histogram row"):
        padded = rt.empty((r1 - r0, width))
        rt.run(pad_kernel, (width, r1 - r0), signal, np.int32(n_bins), np.int32(r0), padded)
        rt.run(filter_kernel, (-(-n_bins // OUTPUTS_PER_ITEM), r1 - r0), padded, taps_buf,
               np.int32(n_bins), np.int32(r0), out)
    return out


def _inputs(rows, n_bins, half_bins, dt_s=1e-12, seed=1, taps_space=None, method=None):
    rng = np.random.default_rng(seed)
    k = np.arange(n_bins)
    data = rng.standard_normal((rows, n_bins)) + 5 * np.exp(-0.5 * ((k - n_bins / 2) / 80) ** 2)
    taps = gauss_taps(half_bins * dt_s, dt_s)
    # float32 inputs on both sides: the twin then measures only the kernel's arithmetic
    data = data.astype(np.float32)
    return lambda backend: (backend.from_numpy(data), taps, taps_space, method)


def examples(size):
    if size == "bench":
        return [Example(f"paper: 3 x 60,000 bins, h = 0.65 ns at 1 ps, {m}",
                        _inputs(3, 60_000, 650, method=m), 1e-5, work=3 * 60_000 * 1301,
                        unit="FMA" if m == "direct" else "")
                for m in ("direct", "fft")] + [
                Example("SPAD array: 1024 x 4096 bins, h = 0.65 ns at 10 ps, direct",
                        _inputs(1024, 4096, 65), 1e-5, work=1024 * 4096 * 131, unit="FMA")]
    if size == "tiny":  # whole 32-bin blocks, a short record, a window longer than the record
        return [Example("128 bins, 7 taps", _inputs(2, 128, 3), 1e-5),
                Example("10 bins, 7 taps", _inputs(2, 10, 3), 1e-5),
                Example("40 bins, 61 taps", _inputs(2, 40, 30), 1e-5),
                Example("taps in __global memory", _inputs(2, 100, 3, taps_space="__global"),
                        1e-5),
                Example("3 rows in groups of 2", _inputs(3, 100, 3), 1e-5,
                        max_alloc_bytes=2 * 4 * (100 + 6 + OUTPUTS_PER_ITEM))]
    return [Example(f"3 x 5000 bins, {2 * h + 1} taps", _inputs(3, 5000, h), 1e-5)
            for h in (1, 7, 650, 1500)] + [
            Example(f"3 x 5000 bins, {2 * h + 1} taps, {m}", _inputs(3, 5000, h, method=m), 1e-5)
            for h, m in ((650, "direct"), (7, "fft"))]


OP = Operation(
    "gauss_filter", "gauss_filter", opencl, numpy, examples,
    tolerance_note="1e-5 of the peak: a float32 FMA chain of N taps errs ~sqrt(N) 6e-8 "
    "(N = 1301: 2e-6); a float32 FFT errs ~log2(n) 6e-8 of the row's energy; both sides get "
    "the same float32 input.",
    bound="FMA (two unaligned 16-float loads per two 16-float FMAs)")
