"""The forward operation's device passes (ops/forward.py `opencl`): how the detectors are
grouped under the device's memory, and which kernels bin a group's light: the exact erf
(`pulse_bins`), the windowed deposit (`deposit` with atomics or `deposit_rows`, then `resolve`
and `convolve`) after `facet_paths`, or the fused deposit (`deposit_direct`, then `convolve`)
for short windows on many detectors of a CPU device."""
from __future__ import annotations

import math

import numpy as np

from .pulse import REACH_SIGMAS, binning, deposit_plan, deposit_sizes, deposit_taps

FACET_CHUNK = 64  # facets per culling chunk in the kernel
BLOCK = 15  # bins per work item in pulse_bins (BLOCK in forward.cl)


# The deposit's scatter into 64-bit fixed-point sub-bins: 32-bit atomics across facets
# (`deposit`), or one work item per detector (`deposit_rows`: no atomics, the same integer
# sums, bit-identical) for >= ROWS_MIN_DETECTORS detectors in a pass on a CPU device (oclgrind
# is one too) with <= ROWS_MAX_FACETS facets a detector. PoCL, 2 cores, ms of deposit, atomic
# -> rows: a 1,024-spot SPAD patch's model columns (1,536 points) 24 -> 15 (a locate 2.42 ->
# 2.22 s), its simulate at 4,800 / 19,200 / 76,800 facets 326 -> 236, 1,640 -> 1,209, 4,138
# -> 3,025; the bench's detailed box (137,664 facets, 32 spots) 46 -> 65. Only speed differs.
# A GPU keeps the atomics (not measured: no GPU this session).
ROWS_MIN_DETECTORS, ROWS_MAX_FACETS = 16, 1000


def deposit_kernel(rt, n_detectors: int, n_facets: int) -> str:
    rows = n_detectors >= ROWS_MIN_DETECTORS and n_facets <= ROWS_MAX_FACETS * n_detectors
    return "deposit_rows" if rows and rt.on_cpu else "deposit"


def plan_passes(rt, n_det, n_pad, n_bins, sigma_path, dpath, method):
    """(method, detector groups): the deposit only where its sub-bins fit one device buffer,
    else erf; a pass's path and weight rows under the device's largest allocation (max_alloc
    _bytes), and its buffers together (with the deposit's sub-bins) under the memory budget
    (core.limits: on a CPU device they are host memory)."""
    from ..core.limits import memory_limit, require_memory
    method, total_row = binning(method, float(np.max(dpath)), sigma_path), 8 * n_pad
    if method == "deposit":
        os_, half = deposit_sizes(float(np.max(dpath)), sigma_path)
        padded = n_bins + 2 * half + 32  # the most the deposit window can need
        if 4 * os_ * padded > rt.device.max_mem_alloc_size:
            method = "erf"
        else:
            total_row += 12 * os_ * padded
    require_memory("facet_size_m", total_row, f"the forward model of {n_pad} facets for one "
                   "detector", "use larger facets (facet_size_m) or fewer bins")
    per = max(1, memory_limit() // total_row)
    return method, [(a, min(a + per, d1)) for d0, d1 in rt.groups(
        n_det, 4 * n_pad, "facet paths of one detector") for a in range(d0, d1, per)]


def erf_bins(rt, defines, group, edge0, dpath, sigma_path, n_bins, hist):
    path, weight, ranges, n_chunks, d0, d1 = group
    axis = rt.constant(np.stack([edge0, dpath], axis=1))
    rt.run(rt.kernel("forward", "pulse_bins", **defines), (-(-n_bins // BLOCK), d1 - d0), path,
           weight, ranges, np.int32(n_chunks), axis,
           np.float32(1.0 / (math.sqrt(2.0) * sigma_path)), np.float32(REACH_SIGMAS * sigma_path),
           np.int32(n_bins), np.int32(d0), hist)


def deposit_bins(rt, defines, group, span, total, edge0, dpath, sigma_path, n_bins, hist):
    path, weight, _, n_chunks, d0, d1 = group
    os_, half, first, count, base, scale = deposit_plan(span, total, edge0[d0:d1], dpath[d0:d1],
                                                        sigma_path, n_bins)
    n = d1 - d0
    padded = int(count.max(initial=0)) + 2 * half + 32
    taps = rt.constant(deposit_taps(os_, half, float(np.max(dpath)), sigma_path))
    win = rt.constant(np.stack([base, os_ / dpath[d0:d1], scale, np.zeros(n)], axis=1))
    wnd = rt.constant(np.stack([first, count], axis=1), np.int32)
    kw = dict(defines, OS=os_, SPAN=2 * half + 1)
    low, high = rt.empty((n, os_, padded), np.uint32), rt.empty((n, os_, padded), np.uint32)
    from ..device.runtime import cl
    for buf in (low, high):
        cl.enqueue_fill_buffer(rt.queue, buf.data, np.uint32(0), 0, buf.nbytes)
    kernel = deposit_kernel(rt, n, path.shape[1])
    items = (n,) if kernel == "deposit_rows" else (path.shape[1], n)
    rt.run(rt.kernel("forward", kernel, **kw), items, path, weight, np.int32(path.shape[1]),
           win, np.int32(padded), np.int32(0), low, high)
    dep = rt.empty((n, os_, padded))
    rt.run(rt.kernel("forward", "resolve", **kw), (os_ * padded, n), low, high, win,
           np.int32(padded), np.int32(0), dep)
    rt.run(rt.kernel("forward", "convolve", **kw), (-(-n_bins // 16), n), dep, taps, wnd,
           np.int32(padded), np.int32(n_bins), np.int32(d0), hist)


# The fused deposit (`deposit_direct`: paths, weights and the split in one pass, float sums in
# each detector's own sub-bins over the whole axis): on a CPU device, for >= ROWS_MIN_DETECTORS
# detectors whose sub-bin row is at most DIRECT_ROW_BYTES (a model fit's columns, ~100 bins;
# a full record's axis keeps the windowed deposit, whose buffers follow the light), Lambertian
# and unmasked. PoCL, 2 cores: a 1,024-spot SPAD patch's model column (1,536 facets, 91 bins)
# 17-27 -> 3.6 ms (facet_paths 10 ms and deposit_rows 13 ms of it before).
DIRECT_ROW_BYTES = 64 * 1024


def _direct_row(n_bins, dpath, sigma_path) -> tuple[int, int, int]:
    """(sub-bins per bin OS, taps half-width T, bins of a detector's row): the fused deposit's
    row covers the whole axis and T bins each side, plus convolve's 16-bin blocks' overrun."""
    os_, half = deposit_sizes(float(np.max(dpath)), sigma_path)
    return os_, half, n_bins + 2 * half + 32


def direct(rt, n_det, n_bins, sigma_path, dpath, reflectance, visible) -> bool:
    """Whether a pass of `n_det` detectors takes the fused deposit."""
    os_, _, padded = _direct_row(n_bins, dpath, sigma_path)
    lambertian = reflectance is None or not reflectance.kernel_defines()  # no lobe factor
    return (rt.on_cpu and lambertian and visible is None and n_det >= ROWS_MIN_DETECTORS
            and 4 * os_ * padded <= DIRECT_ROW_BYTES)


def direct_bins(rt, facets, spots_buf, lasers, is_paired, passes, edge0, dpath, sigma_path,
                n_bins, hist):
    """The fused deposit and the convolution, pass by pass; returns the (D, 2) path spans."""
    from ..device.runtime import cl
    n16 = -(-facets.count // 16) * 16
    rows = np.zeros((7, n16), np.float32)  # structure of arrays; padding: area 0, normal 0
    rows[0:3, :facets.count] = facets.centres.T
    rows[3:6, :facets.count] = facets.normals.T
    rows[6, :facets.count] = facets.areas
    rows = rt.from_numpy(rows)
    os_, half, padded = _direct_row(n_bins, dpath, sigma_path)
    n_det = len(edge0)
    win = rt.constant(np.stack([edge0 - half * dpath, os_ / dpath, np.zeros(n_det),
                                np.zeros(n_det)], axis=1))
    taps = rt.constant(deposit_taps(os_, half, float(np.max(dpath)), sigma_path))
    kw = dict(CHUNK=FACET_CHUNK, OS=os_, SPAN=2 * half + 1,
              **(dict(PAIRED=1) if is_paired else {}))
    spans = []
    for d0, d1 in passes:
        n = d1 - d0
        dep, span = rt.empty((n, os_, padded)), rt.empty((n, 2))
        cl.enqueue_fill_buffer(rt.queue, dep.data, np.float32(0), 0, dep.nbytes)
        rt.run(rt.kernel("forward", "deposit_direct", **kw), (n,), rows, np.int32(n16),
               spots_buf, lasers, np.int32(d0), win, np.int32(padded), dep, span)
        wnd = rt.constant(np.stack([np.zeros(n), np.full(n, n_bins)], axis=1), np.int32)
        rt.run(rt.kernel("forward", "convolve", **kw), (-(-n_bins // 16), n), dep, taps, wnd,
               np.int32(padded), np.int32(n_bins), np.int32(d0), hist)
        spans.append(rt.to_numpy(span))
    return np.concatenate(spans)
