"""Detection before location: is there any target signal in a frame at all?

Every estimator returns a position, even for pure noise. `detect` tests each filtered row's
highest value inside the bins a target in the search region can reach against that row's own
noise floor, and combines the rows:

- noise: the row's median and 1.4826 x MAD (robust: a target's pulse covers a small share of
  a row), from the bins no target in the region can reach where there are enough of them;
  else, where the unfiltered row is at hand and its noise is white from bin to bin, from
  the raw row (`RawFloor`: its first differences' MAD, through the filter's taps, and a low
  quantile for the level), which a signal covering the whole row cannot inflate (a gated or
  short record: a 0.7 m plate filling a 4 ns record stood 2.4 of the whole row's sigma, and
  over 5 of its own bin noise); else from the whole row;
- per row, the p-value of its peak z under "noise only": the smaller of the union bound over the
  window's samples (n Q(z), exact as a bound for any correlation) and Rice's formula for the
  expected number of up-crossings of a smooth Gaussian process (n / 2 pi x sigma(dx) / sigma(x)
  x exp(-z^2 / 2), from the row's own first differences, so any filter and any correlation
  length are measured rather than assumed). Both are upper bounds in practice, so the rate of
  false alarms is at most the nominal one;
- Fisher's combination, -2 sum ln p ~ chi^2 with 2 D degrees of freedom under no target, and
  detected where it exceeds the (1 - false_alarm) quantile.
The false-alarm rate is measured on pure-noise frames in tests/localization/test_detection.py.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.constants import TINY
from ..core.grid import Grid
from ..core.histograms import HistogramSet
from ..core.stats import chi2_quantile, median
from ..ops.gauss_filter import gauss_taps
from ..ops.signals import Signals

FALSE_ALARM = 1e-3  # nominal rate of "target" said on pure noise, per frame
MAD_TO_SIGMA = 1.4826
MIN_FREE_SAMPLES = 200  # independent unreachable samples needed before they alone set the floor
STRIDE_SAMPLES = 1024  # robust statistics on at most this many evenly strided samples a row
SAMPLE_BUDGET = 1 << 19  # ... and on at most this many in all (4,096 rows: 128 a row)


# RawFloor: the unfiltered rows' noise where it is white from bin to bin. White noise's
# differences over 1 and over LAG bins have the same spread; noise smoothed over a few bins (a
# resampled or pre-filtered record) has smaller steps than jumps: sigma(d1) / sigma(d4) = 0.5 for
# a 5-bin box, 0.71 for a 2-bin one. Below WHITE_RATIO the filtered rows' own floor is kept;
# above it the spread comes from the LAG-bin differences and is widened by the lag-1
# correlation the ratio shows (1 + 2 rho, rho = 1 - ratio^2), so a mild correlation cannot
# make the floor low. Spreads are mean absolute values: a median of whole-number counts'
# differences moves in steps (Poisson(20) rows' floor came out 6 % low, and 9 in 10 noise
# frames said "target"). The lags assume a signal smooth over LAG bins: coarser bins, where a
# return changes from bin to bin, read as not white and keep the old floor.
LAG = 4
WHITE_RATIO = 0.85  # sigma(d1) / sigma(d4): 1 white (+-0.09 on 128 samples)
MIN_LEVELS = 16  # fewer distinct raw values among the samples (sparse counts): not Gaussian
ABS_TO_SIGMA = math.sqrt(math.pi / 2.0)  # sigma / mean |x| of a zero-mean Gaussian


@dataclass(frozen=True)
class RawFloor:
    """Per row, the filtered rows' noise as the unfiltered rows give it: sigma, sigma(dx) /
    sigma(x), and `usable` where the raw noise is white and Gaussian enough to say so; the
    level is each filtered row's own mean away from its edges (`half`: the taps' half width),
    so only the spread, which a smooth signal cannot inflate, comes from the raw rows.
    Sparse photon counts (`poisson`: whole numbers with few levels, too skewed for a Gaussian
    floor) are tested against their own Poisson law instead: each row's mean count `rate`, and
    log E exp(theta x filtered count) / rate on the `theta` grid (`log_mgf`), for a Chernoff
    bound. `to_rows`: the filtered rows' units per count."""

    sigma: np.ndarray
    ratio: float
    samples: int
    usable: np.ndarray
    half: int
    poisson: np.ndarray
    rate: np.ndarray
    theta: np.ndarray
    log_mgf: np.ndarray
    to_rows: float = 1.0


def raw_floor(raw: np.ndarray, taps: np.ndarray, scale: float = 1.0) -> RawFloor:
    """The noise of rows filtered by `taps` (a correlation, as ops.gauss_filter) from the
    unfiltered rows `raw` (D, n), in raw units: the bins' sigma (from LAG-bin differences,
    widened as the comment above says) x ||taps||, and the ratio of white noise through the
    taps; `scale`: counts per raw unit (Signals.scale_w), for the Poisson test. Strided
    samples, as detect's (bounded work on any record)."""
    n_rows, n = raw.shape
    per_row = max(128, min(STRIDE_SAMPLES, SAMPLE_BUDGET // n_rows))
    at = np.arange(0, max(n - LAG, 1), max(1, (n - LAG) // per_row))
    x0, x1, xl = (raw[:, np.minimum(at + k, n - 1)].astype(np.float64) for k in (0, 1, LAG))
    first, jump = np.mean(np.abs(x1 - x0), axis=1), np.mean(np.abs(xl - x0), axis=1)
    ratio_1 = first / np.where(jump > 0, jump, 1.0)
    levels = 1 + np.count_nonzero(np.diff(np.sort(x0, axis=1), axis=1), axis=1)
    usable = (first > 0) & (ratio_1 >= WHITE_RATIO) & (levels >= MIN_LEVELS) & (n > 4 * LAG)
    widen = np.sqrt(np.maximum(1.0, 1.0 + 2.0 * (1.0 - ratio_1 ** 2)))
    taps = np.asarray(taps, np.float64)
    gain = math.sqrt(float(np.dot(taps, taps)))
    steps = np.diff(taps)  # the taps padded with zeros: their end steps count too
    ratio = math.sqrt(float(np.dot(steps, steps)) + taps[0] ** 2 + taps[-1] ** 2) / gain
    sigma_bin = ABS_TO_SIGMA * jump / math.sqrt(2.0) * widen
    counts = x0 * scale
    poisson = np.all((counts >= 0) & (counts == np.round(counts)), axis=1) & \
        (levels < MIN_LEVELS)
    rate = np.mean(raw, axis=1, dtype=np.float64) * scale if poisson.any() else \
        np.zeros(n_rows)  # the whole row: strided samples can miss every one of sparse counts
    theta = np.geomspace(1e-3, 60.0, 96) / max(float(taps.max()), TINY)
    log_mgf = np.expm1(theta[:, None] * taps[None, :]).sum(axis=1)
    return RawFloor(sigma_bin * gain * scale, ratio, int(at.size), usable, taps.size // 2,
                    poisson, rate, theta, log_mgf)


def raw_floor_of(raw, filtered: Signals):
    """A callable giving the detection's floor from the unfiltered frame (read only if asked),
    or None where there is none or the filter that made `filtered` is not known."""
    if raw is None or filtered.filtered_h_s is None:
        return None
    axis = filtered.layout.time_axis

    def floor():
        if isinstance(raw, HistogramSet):
            values, scale = raw.data, 1.0
        else:
            values, scale = raw.values(), raw.scale_w
        if values.shape != filtered.shape:
            return None
        found = raw_floor(values, gauss_taps(filtered.filtered_h_s, axis.dt_s), scale)
        to_rows = 1.0 / filtered.scale_w  # watts (or counts) to the filtered rows' units
        return replace(found, sigma=found.sigma * to_rows, to_rows=to_rows)
    return floor


@dataclass(frozen=True)
class Detection:
    """detected: the frame holds target signal at the false-alarm rate `false_alarm`;
    statistic: Fisher's -2 sum ln p over rows (threshold: its chi^2 quantile); peak_z: each
    row's highest value in the reachable window, in units of its noise floor."""

    detected: bool
    statistic: float
    threshold: float
    false_alarm: float
    peak_z: tuple

    def as_dict(self) -> dict:
        return {"detected": self.detected, "statistic": round(self.statistic, 3),
                "threshold": round(self.threshold, 3), "false_alarm": self.false_alarm,
                "peak_z_median": round(median(self.peak_z), 3) if self.peak_z else None}

    @property
    def message(self) -> str:
        return (f"no target signal: the strongest peaks are {median(self.peak_z):.1f} noise "
                f"sigma (median over {len(self.peak_z)} histograms), which noise alone reaches "
                f"(Fisher statistic {self.statistic:.1f} <= {self.threshold:.1f}, false-alarm "
                f"rate {self.false_alarm:g}); the position is the argmax of noise")


def reachable_bins(layout, grid: Grid | None) -> np.ndarray:
    """(D, 2) first and last bin each row's target in the grid's box can reach: paths from
    dist(laser, box) + dist(spot, box) (a lower bound) to the box's farthest corner's path."""
    axis = layout.path_axis()
    if grid is None:
        return np.tile([0, axis.n_bins - 1], (layout.n_detectors, 1))
    lo, hi = _box(grid)
    spots = np.asarray(layout.detector_spots, dtype=np.float64)
    lasers = np.broadcast_to(np.asarray(layout.laser_spot, dtype=np.float64), spots.shape)
    near = _distance_to_box(lasers, lo, hi) + _distance_to_box(spots, lo, hi)
    corners = np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T
    far = np.max(np.linalg.norm(corners[None] - lasers[:, None], axis=2)
                 + np.linalg.norm(corners[None] - spots[:, None], axis=2), axis=1)
    first = np.floor((near - axis.start_m) / axis.step_m)
    last = np.ceil((far - axis.start_m) / axis.step_m)
    return np.clip(np.stack([first, last], axis=1), 0, axis.n_bins - 1).astype(np.int64)


def detect(rows: np.ndarray, window: np.ndarray | None = None,
           false_alarm: float = FALSE_ALARM, raw=None) -> Detection:
    """Test filtered rows (D, n_bins) for target signal; window (D, 2): each row's reachable
    first and last bin (default: the whole row); raw: a RawFloor, or a callable giving one (or
    None), asked only where some row has too few unreachable bins for its floor. Vectorised
    over rows: 4,096 x 1,024 bins in ~0.1 s."""
    rows = np.asarray(rows)  # float32 from a device: the samples are taken in float64
    n_rows, n = rows.shape
    window = np.tile([0, n - 1], (n_rows, 1)) if window is None else np.asarray(window)
    first, last = window[:, :1], window[:, 1:]
    per_row = max(128, min(STRIDE_SAMPLES, SAMPLE_BUDGET // n_rows))
    at = np.arange(0, n - 1, max(1, (n - 1) // per_row))
    values = rows[:, at].astype(np.float64)
    steps = rows[:, at + 1].astype(np.float64) - values
    outside = (at[None, :] < first) | (at[None, :] > last)
    floor = _floor(values, steps, np.ones_like(outside), n)  # the whole row
    free = _floor(values, steps, outside, (first + n - 1 - last)[:, 0])
    use_free = free[3] >= MIN_FREE_SAMPLES
    given = None
    if raw is not None and not use_free.all():
        given = raw() if callable(raw) else raw
        floor = _with_raw(given, floor, use_free, values, at, n)
    centre, sigma, ratio, dof = (np.where(use_free, f, w) for f, w in zip(free, floor))
    peak = _window_peaks(rows, first[:, 0], last[:, 0])
    # a floor that is exactly constant on most samples (MAD 0: a noise-free simulation) makes
    # any peak above it certain; a row constant throughout (dead, all zero) says nothing
    live = (sigma > 0) | (peak > centre)
    exact = live & ~(sigma > 0)
    z = np.where(sigma > 0, (peak - centre) / np.where(sigma > 0, sigma, 1.0), 0.0)
    shrink = (z > 0) & (dof > 1)  # exp(-z_t^2 / 2) = (1 + z^2 / n)^(-(n - 1) / 2)
    z = np.where(shrink, np.sqrt(np.maximum(dof - 1, 0)
                                 * np.log1p(np.minimum(z, 1e150) ** 2 / np.maximum(dof, 1))), z)
    n_window = (last - first + 1)[:, 0]
    union = n_window * 0.5 * _erfc(z / math.sqrt(2.0))
    rice = n_window / (2.0 * math.pi) * ratio * np.exp(-0.5 * np.minimum(z, 40.0) ** 2)
    p = np.where(exact, 0.0, np.minimum(union, rice + union / n_window))
    z = np.where(exact, np.inf, z)
    if given is not None:
        live, p, z = _poisson(given, ~use_free, peak, n_window, live, p, z)
    p = np.clip(p, TINY, 1.0)[live]
    statistic = float(-2.0 * np.sum(np.log(p)))
    threshold = _threshold(false_alarm, 2 * max(int(p.size), 1))
    return Detection(bool(p.size) and statistic > threshold, statistic, threshold, false_alarm,
                     tuple(np.round(z[live], 3).tolist()))


def _with_raw(given: RawFloor | None, floor, use_free, values, at, n):
    """The whole-row floor, replaced by the raw rows' where they are usable: the level is the
    row's mean inside its edges (the filter's zero padding lowers them), the spread the raw
    rows', widened by that mean's own error (k independent samples: sqrt(1 + 1 / k))."""
    if given is None:
        return floor
    inner = (at >= given.half) & (at <= n - 1 - given.half)
    if inner.sum() < 3:
        inner = np.ones_like(inner)
    mean = values[:, inner].mean(axis=1)
    k = max(1.0, (at[inner][-1] - at[inner][0] + 1) * given.ratio / math.sqrt(math.pi))
    sigma = given.sigma * math.sqrt(1.0 + 1.0 / k)
    ok = given.usable & ~use_free
    raw = (mean, sigma, np.full(len(mean), given.ratio), np.full(len(mean), float(given.samples)))
    return tuple(np.where(ok, r, w) for r, w in zip(raw, floor))


def _poisson(given: RawFloor, rows, peak, n_window, live, p, z):
    """Sparse counts' rows (`given.poisson` among `rows`): p = min(1, n_window x the Chernoff
    bound exp(min over theta of rate x log_mgf - theta x peak)) on the filtered peak in counts
    (a bound for any rate and filter, where the Gaussian tail is not one); z the Gaussian z of
    the same exponent."""
    pois = given.poisson & rows
    if not pois.any():
        return live, p, z
    counts = peak[pois] / given.to_rows
    exponent = np.min(given.rate[pois, None] * given.log_mgf[None, :]
                      - given.theta[None, :] * counts[:, None], axis=1)
    exponent = np.minimum(exponent, 0.0)  # the bound at theta -> 0 is 1
    p, z, live = p.copy(), z.copy(), live.copy()
    p[pois] = np.minimum(1.0, n_window[pois] * np.exp(exponent))
    z[pois] = np.sqrt(-2.0 * exponent)
    live[pois] = (given.rate[pois] > 0) | (counts > 0)
    return live, p, z


@functools.lru_cache(maxsize=64)
def _threshold(false_alarm: float, dof: int) -> float:
    return chi2_quantile(1.0 - false_alarm, dof)


_erfc = np.vectorize(math.erfc, otypes=[float])


def _floor(values: np.ndarray, steps: np.ndarray, mask: np.ndarray, count):
    """Per row, from the samples where `mask`: median, robust sigma (1.4826 x MAD), sigma(dx) /
    sigma(x), and the
    independent samples the floor rests on (count x sigma(dx) / (sigma(x) sqrt(pi)) for a
    smooth row, at most count and the samples taken; 0 where fewer than 3 are masked)."""
    enough = mask.sum(axis=1) >= 3
    mask = mask | ~enough[:, None]  # too few samples: computed on all, and given no weight
    centre, sigma = _robust(values, mask)
    _, sigma_step = _robust(steps, mask)
    ratio = np.where(sigma > 0, sigma_step / np.where(sigma > 0, sigma, 1.0), 0.0)
    dof = np.minimum(count * np.minimum(1.0, ratio / math.sqrt(math.pi)), mask.sum(axis=1))
    return centre, sigma, ratio, np.where(enough, dof, 0.0)


def _robust(sample: np.ndarray, mask: np.ndarray):
    """Per row, the median and 1.4826 x MAD of the masked samples. Sort-based: nanmedian
    loops over rows in Python."""
    centre = _masked_median(sample, mask)
    return centre, MAD_TO_SIGMA * _masked_median(np.abs(sample - centre[:, None]), mask)


def _masked_median(sample: np.ndarray, mask: np.ndarray) -> np.ndarray:
    ordered = np.sort(np.where(mask, sample, np.inf), axis=1)
    k = np.maximum(mask.sum(axis=1), 1)[:, None]
    lo = np.take_along_axis(ordered, (k - 1) // 2, axis=1)
    hi = np.take_along_axis(ordered, k // 2, axis=1)
    return 0.5 * (lo + hi)[:, 0]


def _window_peaks(rows: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Each row's maximum over its own window [first, last]."""
    # Few rows, or long ones: slices (no (D, n) temporary; a 1,024 x 60,000-bin SPAD record
    # 6 ms against the mask's 0.1-0.6 s, most of it a float64 copy's page faults)
    if rows.shape[0] <= 64 or rows.shape[1] >= 1024:
        return np.array([float(np.max(r[a:b + 1])) for r, a, b in zip(rows, first, last)])
    bins = np.arange(rows.shape[1])[None, :]
    inside = (bins >= first[:, None]) & (bins <= last[:, None])
    return np.max(np.where(inside, rows, -np.inf), axis=1)


def _box(grid: Grid):
    origin, step, shape = np.array(grid.origin), np.array(grid.step), np.array(grid.shape)
    return origin, origin + step * (shape - 1)


def _distance_to_box(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points - np.clip(points, lo, hi), axis=1)
