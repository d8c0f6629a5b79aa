"""What the fit compares with the forward model: per detector a window of samples around the
signal, their hidden-path bins, the noise level, and which likelihood applies.

Gaussian (AWGN) data are compared after the paper's Gauss filter (sigma_f = h / 3), sampled
every sigma_f / 3: the model is the forward model with the pulse widened by the filter (widths
added in quadrature), so a coarse facet lattice is smooth enough. The filtered noise is
correlated; `rho` is its correlation between samples j apart (from the filter's taps), which the
covariance (model.covariance) uses. Photon counts are compared bin by bin with a Poisson
likelihood; the model is widened by the detector's timing jitter instead.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ....core.constants import DEFAULT_JITTER_S, PAPER_H_S, PAPER_PULSE_SIGMA_S, TINY
from ....core.errors import require
from ....core.stats import median, row_median
from ....ops.gauss_filter import gauss_taps
from ...measured.gated import gate_bounds, in_gate
from .blocks import block_maxima, first_above

MAD = 1.4826  # MAD -> standard deviation for Gaussian noise




@dataclass(frozen=True)
class Observation:
    mode: str  # "gauss" (AWGN, filtered samples) or "poisson" (photon counts per bin)
    spots: np.ndarray  # (D, 3)
    laser: np.ndarray  # (3,), or (D, 3): each detector's own (paired and confocal layouts)
    edge0: np.ndarray  # (D,) hidden path at the first model bin's lower edge
    dpath: np.ndarray  # (D,) model bin width (m of path)
    y: np.ndarray  # (D, n) data
    valid: np.ndarray  # (D, n) bool: inside the record
    sigma0_m: float  # the model's pulse width (m of path) before the facets' blur
    noise: np.ndarray  # (D,) noise std of one sample (gauss), or ones
    rho: np.ndarray  # (n,) noise correlation at lag j (gauss), or [1, 0, 0, ...]
    path0: np.ndarray  # (D,) path at the centre of sample 0
    # The forward call integrates the pulse over each model bin (dpath wide), which widens it
    # by a box of variance dpath^2 / 12; gauss samples are the filtered 1-bin record read at a
    # point (a box of one record bin), so the model pulse's variance is reduced by the
    # difference (m^2). 0 for counts (model bins are the TDC bins).
    box_excess_m2: float = 0.0
    # the late copies' kernels (forward.late.BANK: an IRF tail, light that bounced once more)
    # the Gaussian likelihood adds to every target's column; None: none (forward.late)
    late: tuple | None = None

    @property
    def n(self) -> int:
        return self.y.shape[1]

    def detectors(self, rows) -> "Observation":
        """The same observation on a subset of detectors (rows)."""
        from dataclasses import replace
        laser = self.laser[rows] if self.laser.ndim == 2 else self.laser
        return replace(self, spots=self.spots[rows], laser=laser, edge0=self.edge0[rows],
                       dpath=self.dpath[rows], y=self.y[rows], valid=self.valid[rows],
                       noise=self.noise[rows], path0=self.path0[rows])

    def centres(self) -> np.ndarray:
        return self.path0[:, None] + self.dpath[:, None] * np.arange(self.n)[None, :]


# The rows' medians and MADs (floors, noise) are taken over at most ~this many samples in
# all, every k-th bin of each row beyond it: a 1,024 x 60,000-bin SPAD record's full-row
# medians cost ~3 s, and 4,000 samples a row put a MAD within ~2 % of the row's noise level.
# Every frame of up to 64 detectors x 60,000 bins (the draws, the paper's scene, the captures
# read so far) uses every bin, as before: their answers are unchanged.
MEDIAN_BUDGET = 4_000_000
WINDOW_ROWS = 64  # rows per pass of signal_windows (bounded temporaries)
WINDOW_BLOCK = 1024  # bins per block of signal_windows' maxima (NumPy reduces long blocks fastest)


def _stride(rows) -> int:
    return max(1, -(-int(np.size(rows)) // MEDIAN_BUDGET))  # the ceiling: within the budget


def _every(rows) -> np.ndarray:
    """Every k-th bin of each row: at most ~MEDIAN_BUDGET samples in all (a view)."""
    return rows[:, ::_stride(rows)]


def _adjacent_steps(rows) -> np.ndarray:
    """Differences of adjacent bins, at most ~MEDIAN_BUDGET in all: np.diff(rows, axis=1),
    or, beyond the budget, the pairs (k, k + 1) every k-th bin."""
    step = _stride(rows)
    return rows[:, 1::step] - rows[:, :-1:step]


def _mad_std(rows) -> np.ndarray:
    med = row_median(rows)
    return MAD * row_median(np.abs(rows - med[:, None]), overwrite=True)


TRUNCATED_SD = 0.98655  # sd of a Gaussian cut at +-3 sigma, in sigma


def full_gauss_taps(h_s, dt_s, reach=5.0):
    """The filter's Gaussian (sigma = h / 3) out to `reach` sigma, summing to 1."""
    sigma = h_s / 3.0
    half = int(math.ceil(reach * sigma / dt_s))
    t = np.arange(-half, half + 1) * dt_s
    taps = np.exp(-0.5 * (t / sigma) ** 2)
    return taps / taps.sum()


# The window's floor, a fraction of each row's peak (it bounds the window of noise-free data).
# One target: its main lobe, 3 %; the tail below carries more model error than signal (closed
# shapes on 40 draws: spheres 0.015 -> 0.05 m, a cylinder 0.015 -> 0.10 m at 0.3 %). Several
# targets: 0.3 %, or a target 2.4x farther than the strongest (1/r^4: 2-11 % of its peak) is
# cut out of the window and the fit cannot see it (a plate 8.3 m off).
ONE_TARGET_FRAC, TARGETS_FRAC = 0.03, 0.003


def window_frac(targets) -> float:
    """The window's floor for a fit of `targets` (an int or 'auto')."""
    return ONE_TARGET_FRAC if targets == 1 else TARGETS_FRAC


def signal_windows(filtered, noise, margin_bins, frac=ONE_TARGET_FRAC, n_sigma=6.0):
    """Per detector (first, last) bin of the signal: where the filtered row exceeds both
    n_sigma noise and `frac` of its peak, widened by margin_bins."""
    floors = row_median(_every(filtered))  # photon counts sit on a dark/ambient floor
    out = np.empty((len(filtered), 2), np.int64)
    for at in range(0, len(filtered), WINDOW_ROWS):
        # rows - floor > t as rows > t + floor: no float64 copy of the rows; one pass over
        # the rows for the maxima of blocks of WINDOW_BLOCK bins (the peak, and which blocks
        # hold a bin above), then only the first and last such block read bin by bin (a
        # 1,024 x 60,042-bin SPAD record: 78 -> ~30 ms; the same bins)
        rows, floor = filtered[at:at + WINDOW_ROWS], floors[at:at + WINDOW_ROWS]
        blocks = block_maxima(rows, WINDOW_BLOCK)
        level = np.maximum(n_sigma * np.asarray(noise[at:at + WINDOW_ROWS]),
                           frac * (blocks.max(axis=1) - floor)) + floor
        hot = blocks > level[:, None]
        found = hot.any(axis=1)
        first = first_above(rows, level, hot.argmax(axis=1), WINDOW_BLOCK)
        last = first_above(rows, level, hot.shape[1] - 1 - hot[:, ::-1].argmax(axis=1),
                           WINDOW_BLOCK, from_end=True)
        if not found.all():  # none above: the peak
            first[~found] = rows[~found].argmax(axis=1)
        last = np.where(found, last, first)
        out[at:at + WINDOW_ROWS] = np.stack([first - margin_bins, last + margin_bins], axis=1)
    return out


MIN_FLOOR_BINS = 64  # bins outside the signal a row needs for its floor to be estimated
FLOOR_SIGNIFICANCE = 5.0  # standard errors a level must stand clear of 0 to be taken off
MEDIAN_SE = 1.2533  # a median's standard error over a mean's, for Gaussian noise


def row_floors(filtered, windows, noise, kappa=1.0) -> np.ndarray:
    """Per row, the level the signal sits on (ambient light, dark counts, an offset left by
    processing): the median of the row's bins outside its signal window, which no target's
    pulse reaches; taken as 0 where it does not stand FLOOR_SIGNIFICANCE standard errors clear
    of 0, or where fewer than MIN_FLOOR_BINS lie outside. noise: each row's noise sd; kappa:
    how many bins one independent sample spans ((sum of taps)^2 / sum of taps^2 for filtered
    white noise), so the median of N bins has the standard error
    MEDIAN_SE noise sqrt(kappa / N). Untested, the level of zero-mean noise (up to 0.45 noise
    sd) was taken off as a pedestal, and fits of two plates went metres off (multi draw 60:
    2.8 m; a crossing's track lost). Ambient rows stand 13-30 sd clear (mismatch draws)."""
    n_bins = filtered.shape[1]
    step = _stride(filtered)
    out = np.zeros(len(filtered))
    for d, (row, (lo, hi)) in enumerate(zip(filtered, windows)):
        outside = np.concatenate([row[:max(lo, 0)], row[min(hi + 1, n_bins):]])[::step]
        if outside.size < MIN_FLOOR_BINS:
            continue
        level = median(outside)
        se = MEDIAN_SE * float(noise[d]) * math.sqrt(kappa / outside.size)
        if abs(level) > FLOOR_SIGNIFICANCE * se:
            out[d] = level
    return out


def _filtered_at(raw, idx, taps) -> np.ndarray:
    """raw filtered with `taps` (centred, zero outside the record) at the bins idx (D, n,
    ascending), one detector at a time over the stretch it needs (a gather of every window at
    once is D x n x taps: 1.6 GB and 6 s for 1,024 detectors)."""
    from numpy.lib.stride_tricks import as_strided
    half, n_bins = (len(taps) - 1) // 2, raw.shape[1]
    out = np.empty(idx.shape)
    for d, row in enumerate(raw):
        lo, hi = int(idx[d, 0]) - half, int(idx[d, -1]) + half + 1
        seg = row[max(lo, 0):min(hi, n_bins)]
        if lo < 0 or hi > n_bins:  # zeros outside the record
            seg = np.pad(seg, (max(0, -lo), max(0, hi - n_bins)))
        # every window of the stretch as a strided view (sliding_window_view's checks and the
        # pad cost more than the product on a warm frame's 3 detectors)
        windows = as_strided(seg, (len(seg) - len(taps) + 1, len(taps)), seg.strides * 2,
                             writeable=False)
        out[d] = windows[idx[d] - idx[d, 0]] @ taps
    return out


@functools.lru_cache(maxsize=64)
def _noise_correlation(h_s, dt_s, paper_filter: bool, n: int, stride: int) -> np.ndarray:
    """(n,) the filtered white noise's correlation between samples j x stride bins apart, for
    the paper's filter (paper_filter) or ours out to 5 sigma; read-only, made once per
    (filter, samples, stride): a tracker's frames share it (80 dot products were 80 us of a
    ~10 ms frame)."""
    taps = gauss_taps(h_s, dt_s) if paper_filter else full_gauss_taps(h_s, dt_s)
    rho = np.array([np.dot(taps[:len(taps) - g], taps[g:]) if g < len(taps) else 0.0
                    for g in np.arange(n) * stride]) / float(np.sum(taps ** 2))
    rho.flags.writeable = False
    return rho


def _starts(windows, n_samples, stride, n_bins):
    """First bin of each detector's sample window, kept inside the record where possible."""
    span = (n_samples - 1) * stride
    mid = (windows[:, 0] + windows[:, 1]) // 2
    return np.clip(mid - span // 2, 0, max(n_bins - 1 - span, 0))


def gaussian_observation(layout, filtered, raw, *, h_s=PAPER_H_S, pulse_sigma_s=PAPER_PULSE_SIGMA_S,
                         margin_m=0.35, frac=ONE_TARGET_FRAC, raw_scale=1.0) -> Observation:
    """Filtered samples around the signal. `filtered`: (D, N) host rows after the Gauss filter
    of window `h_s`; `raw`: the same frame unfiltered (or None: the filtered rows are used),
    one unit of it `raw_scale` units of the filtered rows (each Signals' scale_w: the floors
    measured on the filtered rows come off samples filtered from raw)."""
    axis, paths = layout.time_axis, layout.path_axis()
    a = layout.calibration.a_m_per_s
    # From raw data we filter ourselves, with the Gaussian out to 5 sigma (the model's shape
    # exactly); the paper's filter stops at 3 sigma, which narrows it (variance x 0.973).
    taps = gauss_taps(h_s, axis.dt_s) if raw is None else full_gauss_taps(h_s, axis.dt_s)
    stride = max(1, int(round(h_s / 9.0 / axis.dt_s)))
    sigma_f = a * h_s / 3.0 * (TRUNCATED_SD if raw is None else 1.0)
    # The filtered noise is correlated over ~h / dt bins: every 8th bin holds the same
    # information for its MAD at an eighth of the cost (1,024 rows x 60,000 bins: 2 s).
    f_noise = _mad_std(_every(filtered[:, ::8]))
    margin = int(math.ceil((margin_m + 3 * sigma_f) / (a * axis.dt_s)))
    wins = signal_windows(filtered, f_noise, margin, frac)
    n = int(math.ceil((wins[:, 1] - wins[:, 0]).max() / stride)) + 1
    k0 = _starts(wins, n, stride, axis.n_bins)
    idx = k0[:, None] + stride * np.arange(n)[None, :]
    valid = (idx >= 0) & (idx < axis.n_bins)
    idx = np.clip(idx, 0, axis.n_bins - 1)
    paper_taps = gauss_taps(h_s, axis.dt_s)  # the filter the rows passed (raw: ours, alike)
    floors = row_floors(filtered, wins, f_noise, float(paper_taps.sum() ** 2
                                                       / np.sum(paper_taps ** 2)))
    if raw is None:
        y, noise = np.take_along_axis(filtered, idx, axis=1), f_noise
    else:
        y = _filtered_at(raw, idx, taps) * raw_scale
        white = _mad_std(_adjacent_steps(raw)) / math.sqrt(2.0) * raw_scale
        noise = white * math.sqrt(float(np.sum(taps ** 2)))
    rho = _noise_correlation(h_s, axis.dt_s, raw is None, n, stride)
    dpath = paths.step_m * stride
    path0 = paths.centre0_m + paths.step_m * k0
    return Observation("gauss", layout.detector_spots, layout.laser_spot, path0 - 0.5 * dpath,
                       dpath, np.where(valid, y - floors[:, None], 0.0), valid,
                       math.hypot(a * pulse_sigma_s, sigma_f),
                       # noise-free data: float32 rounding is the floor
                       np.maximum(noise, 1e-5 * float(np.abs(y).max()) + TINY),
                       rho, path0, float(np.mean(dpath ** 2 - paths.step_m ** 2)) / 12.0)


# Photon counts are summed over groups of adjacent bins up to the model pulse's sigma over
# COUNTS_BINS_PER_SIGMA (a sum of Poisson counts is Poisson: the likelihood stays exact, and the
# model integrates the pulse over the wider bin). A bin of sigma / 3 widens the pulse's
# variance by 1/108 (under 0.5 % of its width); a 4 ps record of a 42 ps model pulse (LCT's
# scans) is fitted on a third of the samples, a 10 ps one (the draws' counts) unchanged.
COUNTS_BINS_PER_SIGMA = 3.0


def counts_group(sigma0_m: float, step_m) -> int:
    """Record bins summed into one model bin for counts: the most that stay within
    sigma0 / COUNTS_BINS_PER_SIGMA of path (1 where one bin is that wide already)."""
    return max(1, int(sigma0_m / (COUNTS_BINS_PER_SIGMA * float(np.max(step_m)))))


def poisson_observation(layout, counts, filtered, *, pulse_sigma_s=PAPER_PULSE_SIGMA_S, jitter_s=DEFAULT_JITTER_S,
                        margin_m=0.35, frac=ONE_TARGET_FRAC) -> Observation:
    """Photon counts per model bin around the signal (windows found on the filtered rows):
    `counts_group` record bins summed into each, a group valid where all its bins are inside
    the record and its gate (localization.measured.gated)."""
    axis, paths = layout.time_axis, layout.path_axis()
    a = layout.calibration.a_m_per_s
    step = a * axis.dt_s
    sigma0 = a * math.hypot(pulse_sigma_s, jitter_s)
    group = counts_group(sigma0, paths.step_m)
    wins = signal_windows(filtered, _mad_std(_every(filtered)), int(math.ceil(margin_m / step)),
                          frac)
    n = -(-int((wins[:, 1] - wins[:, 0]).max() + 1) // group)
    k0 = _starts(wins, n * group, 1, axis.n_bins)
    idx = k0[:, None] + np.arange(n * group)[None, :]
    inside = (idx >= 0) & (idx < axis.n_bins) & in_gate(idx, gate_bounds(counts))
    y = np.where(inside, np.take_along_axis(counts, np.clip(idx, 0, axis.n_bins - 1), axis=1),
                 0.0).reshape(len(counts), n, group).sum(axis=2)
    valid = inside.reshape(len(counts), n, group).all(axis=2)
    rho = np.zeros(n)
    rho[0] = 1.0
    dpath = paths.step_m * group
    edge0 = paths.start_m + paths.step_m * k0
    return Observation("poisson", layout.detector_spots, layout.laser_spot, edge0, dpath,
                       np.where(valid, y, 0.0), valid, sigma0, np.ones(len(counts)), rho,
                       edge0 + 0.5 * dpath)


COUNTS_PROBE = 4096  # values looks_like_counts reads first


def looks_like_counts(values, scale=1.0) -> bool:
    """Non-negative whole numbers (values x scale: the upload's scale undone): photon counts.
    (Samples first: floats fail on the first COUNTS_PROBE values, then on a strided sample,
    without a pass over a whole SPAD record: a 1,024 x 60,042 record's strided sample alone
    took ~0.1 s.)"""
    v = np.asarray(values)
    for part in (v.flat[:COUNTS_PROBE], _every(v) if v.ndim == 2 else v, v):
        part = part * scale
        if not (part.min() >= 0 and np.allclose(part, np.round(part), atol=1e-3)):
            return False
    return bool(v.max() * scale >= 1)


def observation(scored, likelihood: str, *, h_s: float, pulse_sigma_s: float, jitter_s: float,
                frac: float = ONE_TARGET_FRAC):
    """A scored frame as the fit sees it: a Gauss observation of the filtered data, or (counts
    in `raw`, likelihood 'poisson' or 'auto') a Poisson one."""
    layout = scored.signals.layout
    # read as stored (float32 from a device), once: a SPAD record's float64 copies cost ~1 s
    filtered = scored.host_rows if scored.host_rows is not None else \
        scored.signals.values()
    raw = None if scored.raw is None else scored.raw.values()
    mode = likelihood
    if mode == "auto":
        mode = "poisson" if raw is not None and looks_like_counts(
            raw, scored.raw.scale_w) else "gauss"
    if mode == "poisson":
        require(raw is not None, "raw", "the Poisson likelihood needs the photon counts",
                "pass raw=counts to locate")
        return poisson_observation(layout, raw * scored.raw.scale_w, filtered,
                                   pulse_sigma_s=pulse_sigma_s, jitter_s=jitter_s, frac=frac)
    raw_scale = 1.0 if raw is None else scored.raw.scale_w / scored.signals.scale_w
    return gaussian_observation(layout, filtered, raw, h_s=h_s, pulse_sigma_s=pulse_sigma_s,
                                frac=frac, raw_scale=raw_scale)
