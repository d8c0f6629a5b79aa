"""How far the paper's argmax scatters from frame to frame, measured on the data: the
measurement noise of a tracker whose estimator gives no covariance.

The argmax has no covariance, and a fixed sigma fits one capture but not another: 0.05 m
suits the paper's scene (1 ps bins), while the consumer-nlos walk (16 zones, 250 ps bins) jumps
~0.3 m between frames and, at 0.05 m, its one walker became 9-29 track ids (0.25 m: one id
for all 475 frames). So the sigma is estimated from consecutive frames: the second difference
x[k+1] - 2 x[k] + x[k-1] of a smooth path is the noise's (variance 6 sigma^2; a walker's own
acceleration adds ~a dt^2, 5 mm at 14 fps), taken robustly (1.4826 x MAD) per axis, over
WINDOWS runs of consecutive frames spread over the sequence: the scatter depends on where the
target is (the walk's windows: 0.08-0.37 m), so the largest window's largest axis is the sigma
(loose gates cost smoothing; tight ones break a track into many), never below `floor`."""
from __future__ import annotations

import math

import numpy as np

from ..core.stats import unique_sorted

FRAMES = 12  # consecutive frames per window (~0.03 s each on the walk)
WINDOWS = 4  # windows spread over the sequence


def sequence_scatter(seq, grid, *, h_s: float, floor: float = 0.05, backend=None) -> float:
    """argmax_scatter over WINDOWS runs of FRAMES consecutive frames of a sequence: the
    largest."""
    n = len(seq)
    starts = unique_sorted(np.linspace(0, max(n - FRAMES, 0), WINDOWS).astype(int))
    return max(argmax_scatter([seq[k].histograms for k in range(a, min(n, a + FRAMES))], grid,
                              h_s=h_s, floor=floor, backend=backend) for a in starts)


def argmax_scatter(frames, grid, *, h_s: float, floor: float = 0.05, backend=None,
                   log_mode=None) -> float:
    """The per-axis sigma (m) of the paper's argmax over consecutive `frames`
    (HistogramSets of one layout, in time order); `floor` where fewer than 5 hold a target."""
    from ..core.tuning import auto_log_mode
    from ..localization.filter import GaussFilter
    from ..localization.locator import Locator
    from ..ops.signals import as_signals
    frames = list(frames)[:FRAMES]
    if len(frames) < 5:
        return floor
    layout = frames[0].layout
    log_mode = auto_log_mode(layout.n_detectors) if log_mode is None else log_mode
    gauss = GaussFilter(h_s, layout.time_axis, backend=backend)
    # coarse to fine: the same cell as every other search, without "auto"'s exhaustive trials
    # (on the walk's 3.5 M cells, 16 of the 48 frames at ~0.1 s each: 4 s of a 5 s start-up)
    locator = Locator(layout, grid, estimator="paper", log_mode=log_mode, backend=backend,
                      search="coarse_to_fine")
    positions = []
    for h in frames:
        loc = locator(gauss(as_signals(h, backend)))
        positions.append(loc.position if loc.detected else np.full(3, np.nan))
    x = np.array(positions)
    second = x[2:] - 2 * x[1:-1] + x[:-2]
    second = second[np.all(np.isfinite(second), axis=1)]
    if len(second) < 3:
        return floor
    sd = 1.4826 * np.median(np.abs(second - np.median(second, axis=0)), axis=0) / math.sqrt(6)
    return max(floor, float(np.max(sd)))
