"""Static returns learned from the sequence itself: furniture, the wall's own
return, a target that never moves. `track_sequence` subtracts, by default, what every frame
holds: per bin, the QUANTILE of frames spread over the whole sequence, raised by the noise's
own offset at that quantile (quantile_offset: for that many frames, sigma from frame-to-frame
differences), so that
a static return is removed without bias and a mover, which reaches a given bin in fewer than
nine frames in ten, is kept; a bin counts as static only where its spread over the frames
(10 % to 75 % quantile) is the noise's and no mover fills a bin within the detection filter's
window of it (a lingering mover's wings), and sequences.tracker_for subtracts it only where it
holds a return one frame's detection would see (learned_background). Without it the tracker locked onto the brightest static object
(docs/scenes/walk.yaml: a walker past a box, median error 2.05 m, no warning). The median
would not do: the consumer-nlos walker (4 x 4 zones, 250 ps bins) stays in half the frames'
bins, so the median held half his energy, and the track lost 0.05 m to the authors' particle
filter and split in two.

The quantile of K frames adds ~0.3 of one frame's noise to every frame (K = 32), the price of
needing no option and no target-free capture. A sequence of fewer than MIN_FRAMES frames, or
one whose frames do not fit BUDGET_BYTES that many times, is tracked without it (the running
mean, `running_mean=`, serves streams)."""
from __future__ import annotations

from statistics import NormalDist

import numpy as np

from ..core.histograms import HistogramSet
from ..core.stats import row_median
from ..localization.detection import MAD_TO_SIGMA

_NORMAL = NormalDist()
MIN_FRAMES = 10  # from 10 frames the quantile lies at or above the second lowest frame, so one
# frame's noise cannot set it alone. Was 24 (a 12-frame walk of a 1.6 m plate: its learned
# "static" return made the fits 30x slower) until the spread and wing tests below kept such a
# walk's light out: the scenario suite's 12-frame clutter sequences then had their furniture
# tracked as targets (draw 8: a track 5.7 m off the movers; 64, 80: two tracks for one mover)
QUANTILE = 0.1
SPREAD_QUANTILE = 0.75  # a bin is static where QUANTILE..SPREAD_QUANTILE spans the noise alone:
SPREAD_Z = 1.9560  # Phi^-1(0.75) - Phi^-1(0.1) sigma, plus 8 / sqrt(frames) for the quantiles' error
WING_WINDOWS = 1.0  # _wings: the filter windows (h) a mover's wings reach
STRONG_Z = 5.0  # a wing bin this far above the row's level (frame sigma) is a static return
DENSE_WINDOWS = 0.25  # _dense: the window, in filter windows, where a lone bin is noise
BUDGET_BYTES = 512 * 2 ** 20  # the frames stacked for the quantiles (float64)


def static_background(frames: list) -> HistogramSet | None:
    """What every one of `frames` (HistogramSets spread over a sequence, one layout) holds, bin
    by bin (the module doc), or None where there are too few of them within the budget."""
    learned = static_returns(frames)
    return None if learned is None else learned[0]


def static_returns(frames: list) -> tuple | None:
    """static_background's set and each row's frame noise sigma (D,), from frame-to-frame
    differences: what holds_target measures the learned returns against."""
    if len(frames) < MIN_FRAMES:
        return None
    fit = BUDGET_BYTES // max(frames[0].data.size * 8, 1)
    if fit < MIN_FRAMES:
        return None
    picks = np.unique(np.linspace(0, len(frames) - 1, min(len(frames), fit)).astype(int))
    stack = np.stack([np.asarray(frames[int(i)].data, dtype=np.float64) for i in picks])
    # per row, sigma from frame-to-frame differences at each bin (static returns cancel, a
    # mover adds to a minority of them): the MAD of differences / sqrt 2
    steps = np.abs(np.diff(stack, axis=0)).transpose(1, 0, 2).reshape(stack.shape[1], -1)
    sigma = MAD_TO_SIGMA * row_median(steps, overwrite=True) / np.sqrt(2.0)
    low, upper = np.quantile(stack, [QUANTILE, SPREAD_QUANTILE], axis=0)
    # static where the bin holds the same return in (nearly) every frame: its spread between
    # the two quantiles is the noise's (1.95 sigma), not a mover's that comes and goes (a slow
    # plate on a 12-frame walk fills some bins in 11 frames of 12: their low quantile held it,
    # and the model fits of what was left took 20 s for 0.3 s)
    still = (upper - low) <= (SPREAD_Z + 8.0 / np.sqrt(len(picks))) * sigma[:, None]
    learned = low + quantile_offset(len(picks)) * sigma[:, None]
    dt_s = frames[0].layout.time_axis.dt_s
    still = ~_dense(~still, dt_s)
    # a wing is sub-noise light (~1 frame sigma a bin): a bin STRONG_Z sigma above the row's
    # level is a static return's, kept (a box beside a plate's path, draw 112: its cut front,
    # 25 sigma a bin, was left in two rows and every fit missed it, Birge 577)
    strong = (learned - np.median(learned, axis=1, keepdims=True)) > STRONG_Z * sigma[:, None]
    still &= ~(_wings(still, dt_s) & ~strong)
    # where nothing is static, the row's ambient floor (its static bins' median), not 0: a
    # step there was a return the fits could not explain (walk.yaml, the wings dropped around
    # the walker: 3 frames of 15-60 s, closed shapes fitted after the warm fit missed)
    floor = np.array([np.median(r[k]) if k.any() else 0.0 for r, k in zip(learned, still)])
    return frames[0].with_data(np.where(still, learned, floor[:, None])), sigma


def quantile_offset(n: int) -> float:
    """How far below the noise's mean the QUANTILE of n frames of Gaussian noise lies, in sigma
    (NumPy's linear interpolation between order statistics, each at Blom's mean): 1.28 for
    many frames, 1.06 for 10 (the large-sample 1.28 left 0.2 sigma in every bin of a short
    sequence)."""
    h = (n - 1) * QUANTILE
    lo = int(np.floor(h))
    # the standard library's normal quantile: scipy.stats took ~1 s to import, a third of
    # `nlos-cl track`'s start-up on a 40-frame walk
    order = [_NORMAL.inv_cdf((i + 0.625) / (n + 0.25)) for i in (lo, min(lo + 1, n - 1))]
    return float(-((1.0 - (h - lo)) * order[0] + (h - lo) * order[1]))


def learned_background(frames: list, grid) -> HistogramSet | None:
    """What track_sequence subtracts by default: the static returns of `frames` where they
    hold a return (holds_target, against the frames' own noise), else None."""
    learned = static_returns(frames)
    if learned is None or not holds_target(learned[0], grid, frame_sigma=learned[1]):
        return None
    return learned[0] if leaves_movers(frames, learned[0], grid) else None


def leaves_movers(frames: list, learned: HistogramSet, grid) -> bool:
    """Do `frames` less the learned returns still hold a target (the detection) in at least
    half of those that held one? A mover that keeps its distance to most spots (walking
    across them) holds its return in the same bins in every frame, which no per-bin test can
    tell from furniture: learned, it was subtracted whole (scenario draw 80: a person walking
    1.1 m across the wall, no frame left with a target, exit 3)."""
    from ..localization.api import gauss_filter
    from ..localization.detection import detect, raw_floor_of, reachable_bins
    window = reachable_bins(learned.layout, grid)

    def seen(frame) -> bool:
        filtered = gauss_filter(frame)
        return detect(filtered.values(), window, raw=raw_floor_of(frame, filtered)).detected
    held = [f for f in frames if seen(f)]
    left = sum(seen(f.with_data(f.data - learned.data)) for f in held)
    return 2 * left >= len(held)


def _dense(moving: np.ndarray, dt_s: float) -> np.ndarray:
    """The bins that fail the spread test with another within the DENSE_WINDOWS filter window
    around them: a mover's return spans a pulse; a lone bin past the threshold is the noise's
    (a few a row at 1 ps bins), and its wings cut the static return around it out (the
    paper's plate standing still, 1 ps bins: a third of one row left in every frame). Not
    half the window: a lingering mover fails the test in sparse bins, which then kept their
    wings (crossing draw 3 learned the crossing plates' light)."""
    from scipy.ndimage import uniform_filter1d

    from ..ops.gauss_filter import filter_window
    size = int(DENSE_WINDOWS * filter_window(dt_s) / dt_s)
    if size < 2:
        return moving
    return moving & (uniform_filter1d(moving.astype(np.float32), size, axis=1) * size > 1.5)


def _wings(still: np.ndarray, dt_s: float) -> np.ndarray:
    """Bins within WING_WINDOWS of the detection filter's window h of a bin a mover fills: a
    mover that lingers (two crossing targets turning) holds its return's sub-noise wings there
    in nearly every frame, so their quantile passed the spread test and held ~2-4 frame sigma
    of the movers' own light (filtered), which the fits then missed. A static return that
    close to a lingering mover is dropped with them: keeping bins high above the noise there
    kept a bright mover's wings too (crossing draw 11: up to 10 frame sigma, filtered)."""
    from scipy.ndimage import binary_dilation

    from ..ops.gauss_filter import filter_window
    half = int(WING_WINDOWS * filter_window(dt_s) / dt_s)
    if half < 1 or still.all():
        return np.zeros_like(still)
    return binary_dilation(~still, structure=np.ones((1, 2 * half + 1), bool)) & still


def holds_target(background: HistogramSet, grid, frame_sigma=None) -> bool:
    """Does the learned background itself hold a target's return (a static object, or a target
    that stood still)? The detection before location, on the background as a frame; with
    `frame_sigma` (each row's frame noise, static_returns'), also a return one frame's
    detection would see (above_frame_noise)."""
    from ..localization.api import gauss_filter
    from ..localization.detection import detect, raw_floor_of, reachable_bins
    window = reachable_bins(background.layout, grid)
    filtered = gauss_filter(background)
    rows = filtered.values()  # as stored: scale_w watts a unit
    if frame_sigma is not None and not above_frame_noise(
            rows * filtered.scale_w, window, frame_sigma, background.layout.time_axis.dt_s):
        return False
    return detect(rows, window, raw=raw_floor_of(background, filtered)).detected


def above_frame_noise(filtered, window, frame_sigma, dt_s: float) -> bool:
    """Is some row of the learned return, Gauss-filtered as the detection filters a frame
    (`filtered`: holds_target's rows, in the background's units, W), above the FRAME's noise at the detection's false-alarm
    rate (Bonferroni over the window's independent filter widths)? The background's own floor
    is the quantile's sampling noise (~0.3 of a frame's) and exact zeros, against which the
    sub-noise wings of two crossing targets that linger in some bins (crossing draw 1: ~2
    frame sigma, filtered) were "a return": subtracted, they made every warm fit miss (3-5 s a
    frame for 0.08 s)."""
    from ..localization.detection import FALSE_ALARM
    from ..ops.gauss_filter import filter_window, gauss_taps
    taps = gauss_taps(filter_window(dt_s), dt_s)
    noise = np.asarray(frame_sigma, np.float64) * np.sqrt(np.sum(taps ** 2))
    first, last = np.asarray(window, int).T
    samples = max(1.0, float(np.sum(last - first + 1)) / len(taps))
    z_limit = -_NORMAL.inv_cdf(FALSE_ALARM / samples)  # the upper tail's point, by symmetry
    for row, lo, hi, s in zip(filtered, first, last, noise):
        if hi >= lo and s > 0 and (row[lo:hi + 1].max() - np.median(row)) > z_limit * s:
            return True
    return False


# A confirmed track is a static one (furniture, or a target standing still), reported apart
# from the movers, where its last STILL_FRAMES positions all lie within STILL_M of their median
# (a walker at 1 m/s and 10 frames/s moves 0.5 m in five frames; a still plate's track
# scatters by its measurement noise, ~0.01-0.05 m). The short sequences that learn no static
# returns (fewer than MIN_FRAMES) are where furniture gets tracks of its own.
STILL_FRAMES = 5
STILL_M = 0.1


def holds_still(track) -> bool:
    """Has this confirmed track stayed in place over its last STILL_FRAMES frames?"""
    if track.status != "confirmed" or len(track.history) < STILL_FRAMES:
        return False
    last = np.array([h[2:5] for h in list(track.history)[-STILL_FRAMES:]], float)
    return bool(np.all(np.linalg.norm(last - np.median(last, axis=0), axis=1) <= STILL_M))
