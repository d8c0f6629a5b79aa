"""How far the paper's argmax scatters from frame to frame, measured on the data: the
measurement noise of a tracker whose estimator gives no covariance.

The argmax has no covariance, and a fixed sigma fits one capture but not another: 0.05 m
suits the paper's scene (1 ps bins), while the consumer-nlos walk (16 zones, 250 ps bins) jumps
~0.2 m between frames and, at 0.05 m, its one walker became 9-29 track ids. So the sigma is
estimated from consecutive frames: the second difference x[k+1] - 2 x[k] + x[k-1] of a smooth
path is the noise's (variance 6 sigma^2; a walker's own acceleration adds ~a dt^2, 5 mm at
14 fps), taken robustly (1.4826 x MAD) per axis over WINDOWS runs of FRAMES consecutive frames
spread over the sequence, the windows' second differences pooled; the largest axis is the
sigma, never below `floor`.

Pooled, not the largest window's: the argmax's errors are heavy-tailed (the walk: 15-20 % of
frames beyond 3 robust sigma on two axes, 6 % on the wall), and a 12-frame window's MAD moves
with them (the walk: the largest of 4 windows 0.49 m, of 8 0.90 m). The largest window
gave 0.49 m and a track that lagged its walker (0.19 m from the authors' particle filter,
median); pooled, 0.15 m and 0.10 m, the same one track id (it breaks below ~0.11 m: 2 ids at
0.10). The tails are left to the gate (a wrong answer outside it is a miss). A probabilistic
data association update (a measurement weighed by its probability of being the target's, the
rest clutter over the region) was tried with this sigma and dropped: 0.099 -> 0.098 m, jitter
0.025 -> 0.027 m: the gate already keeps the far outliers out."""
from __future__ import annotations

import math

import numpy as np

from ..core.stats import unique_sorted

FRAMES = 12  # consecutive frames per window (~0.03 s each on the walk)
# windows spread over the sequence: 8 x 10 second differences pooled. The walk's sigma from
# 4 windows was 0.25 m, from 8 0.15 and 16 0.18 (all 473: 0.16): a MAD of 40 samples per
# axis, and the largest axis taken, reads high. 8: 2.4 s of the walk's start-up (4: 1.3 s).
WINDOWS = 8


def sequence_scatter(seq, grid, *, h_s: float | None, floor: float = 0.05, backend=None) -> float:
    """The argmax's per-axis sigma (m) over WINDOWS runs of FRAMES consecutive frames of a
    sequence, their second differences pooled (the module docstring)."""
    n = len(seq)
    starts = unique_sorted(np.linspace(0, max(n - FRAMES, 0), WINDOWS).astype(int))
    second = [_second_differences([seq[k].histograms for k in range(a, min(n, a + FRAMES))],
                                  grid, h_s=h_s, backend=backend) for a in starts]
    return robust_sigma(np.concatenate(second), floor)


def argmax_scatter(frames, grid, *, h_s: float | None, floor: float = 0.05, backend=None,
                   log_mode=None) -> float:
    """The per-axis sigma (m) of the paper's argmax over consecutive `frames`
    (HistogramSets of one layout, in time order; the first FRAMES); `floor` where fewer than 5
    hold a target."""
    return robust_sigma(_second_differences(frames, grid, h_s=h_s, backend=backend,
                                             log_mode=log_mode), floor)


def robust_sigma(second: np.ndarray, floor: float) -> float:
    """The largest axis's 1.4826 MAD / sqrt(6) of second differences (k, axes); `floor` where
    fewer than 3."""
    if len(second) < 3:
        return floor
    sd = 1.4826 * np.median(np.abs(second - np.median(second, axis=0)), axis=0) / math.sqrt(6)
    return max(floor, float(np.max(sd)))


def _second_differences(frames, grid, *, h_s: float | None, backend=None, log_mode=None):
    """(k, 3): x[k+1] - 2 x[k] + x[k-1] of the paper's argmax over the first FRAMES `frames`
    where three consecutive frames hold a target (none where fewer than 5 frames are given)."""
    from ..core.tuning import auto_log_mode
    from ..localization.filter import GaussFilter
    from ..localization.locator import Locator
    from ..ops.signals import as_signals
    frames = list(frames)[:FRAMES]
    if len(frames) < 5:
        return np.zeros((0, 3))
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
    return second[np.all(np.isfinite(second), axis=1)]
