"""Timing and the device's own limits, for `nlos-cl bench`.

Kernel times are medians of repeated runs after a warm-up (the first call, which builds the
programs, is reported separately). The limits (exp lanes/s, FMA/s, copy bytes/s) come from tiny
probe kernels (kernels/probes.cl) run right before each case, several times, so the fraction of
limit a row reports is taken against the machine as it was at that moment; their spread is
reported with them. Timings are reported, never asserted.
"""
from __future__ import annotations

import statistics
import time
import tracemalloc

import numpy as np

PROBE_REPEATS = 3


def timed(fn, repeats, finish) -> list[float]:
    """Wall time of fn() + finish(), `repeats` times."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        finish()
        times.append(time.perf_counter() - start)
    return times


def spread(times) -> tuple[float, float]:
    """(median, (max - min) / median): a run-to-run spread to print beside a median."""
    med = statistics.median(times)
    return med, (max(times) - min(times)) / med if med > 0 else 0.0


def measure_limits(rt, smoke=False) -> dict:
    """Probe kernels: exp lanes/s, FMA/s, copy bytes/s (read + write), each the best of a few
    repeats (the best is the least disturbed by other load), with the spread of the repeats."""
    iters = 64 if smoke else 512
    items = 4 * rt.device.max_compute_units * 256
    out = rt.empty((items,))
    limits = {}
    for key, name, per_iter in (("exp_per_s", "exp_probe", 64), ("fma_per_s", "fma_probe", 96)):
        kern = rt.kernel("probes", name, ITERS=iters)
        run = lambda: rt.run(kern, (items,), out, np.float32(0.5))  # noqa: E731
        times = timed(run, PROBE_REPEATS + 1, rt.finish)[1:]
        limits[key] = items * iters * per_iter / min(times)
        limits[key + "_spread"] = spread(times)[1]
    n = (1 << 18) if smoke else (1 << 22)  # float4s: 4 or 64 MiB per buffer
    src, dst = rt.empty((n, 4)), rt.empty((n, 4))
    kern = rt.kernel("probes", "copy_probe")
    times = timed(lambda: rt.run(kern, (n,), src, dst), PROBE_REPEATS + 1, rt.finish)[1:]
    limits["bytes_per_s"], limits["bytes_per_s_spread"] = 2 * 16 * n / min(times), spread(times)[1]
    return limits


PROBE_FOR_UNIT = {"erf lanes": ("exp_per_s", "exp"), "FMA": ("fma_per_s", "FMA"),
                  "bytes": ("bytes_per_s", "bandwidth")}


def fraction_of_limit(limits, work, unit, seconds) -> tuple[float, str]:
    """Achieved rate over the probe limit for that currency (NaN where no probe measures it)."""
    if unit not in PROBE_FOR_UNIT or not work:
        return float("nan"), ""
    key, name = PROBE_FOR_UNIT[unit]
    return work / seconds / limits[key], name


def time_pair(kernel_fn, twin_fn, finish, repeats=5, twin_repeats=3):
    """(kernel times, twin times, build seconds, peak host MiB). Host memory is traced on the
    warm-up and twin runs only: tracing taxes every Python allocation."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    first = timed(kernel_fn, 1, finish)[0]
    twin = timed(twin_fn, twin_repeats, lambda: None)
    peak = tracemalloc.get_traced_memory()[1] / 2 ** 20
    tracemalloc.stop()
    kernel = timed(kernel_fn, repeats, finish)
    return kernel, twin, max(first - statistics.median(kernel), 0.0), peak

