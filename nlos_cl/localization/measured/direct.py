"""The wall's direct return in a measured capture: is there one, where is its peak against the
time axis the file declares, where does it end, and how wide is it.

Every histogram is looked at in hidden-path terms (PathAxis): the direct return's peak belongs
at the hidden path |laser spot - detection spot| (0 for a confocal capture; for a paired or
one-laser capture the shortest path over the wall), because nlos_cl's time axes put the pulse's
peak, not its onset, at hidden path 0 (PathCalibration.for_setup removes the peak delay, and
Eq. 26's calibration fits peak times). The histograms are summed aligned at that expected bin
(one profile with all the photons: per-histogram peaks of a few counts are noise), the profile
is searched near the expected bin, and per histogram the peak is refined for the spread.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.histograms import HistogramSet
from ...core.stats import median, unique_sorted

# How far (m of hidden path) from its expected place a direct return is looked for: 0.6 m is
# 2 ns, a generous error of a file's time zero; beyond it the strongest early peak is more
# likely a hidden return than the wall, and CC-SOCR's gated "4" (1.7-2 m) stays outside it.
SEARCH_M = 0.6
# The wall seen directly outshines every hidden return (LCT: ~1000x its "SU"); a peak less
# than DOMINANCE x the strongest bin after its own end is not taken for the wall.
DOMINANCE = 5.0
# A direct return is an instrument response: at most 1 ns (0.3 m of path) wide at half height.
MAX_FWHM_M = 0.3
# The return ends where its tail has fallen to this fraction of its peak (three decades; LCT's
# tail reaches it ~400 bins = 0.48 m of path after the peak, where upstream zeroes 600 bins),
# or to the level of the rest of the record, or MAX_TAIL_M after the peak, whichever is first.
GATE_FRACTION = 1e-3
MAX_TAIL_M = 1.0


@dataclass(frozen=True)
class DirectReturn:
    """What was found, in bins of the aligned profile (offset 0 = the expected bin)."""

    peak: int  # offset of the aligned profile's maximum
    end: int  # first offset after the return (gate everything before it)
    truncated: bool  # the peak is the record's first bin: its rise happened before the record
    fwhm_bins: float | None  # None where the rise is cut off
    shifts_bins: np.ndarray  # per histogram: refined peak bin - expected bin
    profile: np.ndarray  # the aligned sum, offsets -search .. n_bins
    origin: int  # index of offset 0 in `profile`
    expected: np.ndarray  # (N,) expected bin (float) per histogram
    why_end: str


def expected_bins(h: HistogramSet) -> np.ndarray:
    """(N,) the bin (fractional, bin 0's centre = 0) where each direct return's peak belongs."""
    axis = h.path_axis()
    path = np.linalg.norm(h.laser_spots - h.detector_spots, axis=1)
    return (path - axis.centre0_m) / axis.step_m


def aligned_sum(data: np.ndarray, shifts: np.ndarray, before: int) -> np.ndarray:
    """sum_d data[d, shifts[d] + o] for o = -before .. n_bins - 1 (zero outside the record):
    rows with the same integer shift are summed first (CC-SOCR: 4,096 rows, ~200 shifts)."""
    n_bins = data.shape[1]
    pad = int(max(0, shifts.max()))  # room for rows whose bin 0 lands before offset -before
    out = np.zeros(pad + before + n_bins + int(max(0, -shifts.min())))
    for s in unique_sorted(shifts):
        start = pad + before - int(s)  # where these rows' record bin 0 lands
        out[start:start + n_bins] += data[shifts == s].sum(axis=0)
    return out[pad:pad + before + n_bins]


def find_direct_return(h: HistogramSet) -> tuple[DirectReturn | None, str]:
    """(the direct return, what was seen), or (None, why there is none)."""
    data, step = h.data, float(h.path_axis().step_m[0])
    expected = expected_bins(h)
    shifts = np.round(expected).astype(int)
    search = max(2, int(round(SEARCH_M / step)))
    if np.all((shifts < -search) | (shifts > data.shape[1] + search)):
        return None, ("none: the expected direct-return bin lies outside the record for every "
                      "histogram (the time window starts after the wall bounce)")
    profile = aligned_sum(data, shifts, search)
    origin = search
    window = profile[:2 * search + 1]
    if not np.any(window > 0):
        return None, ("none: the record is empty within "
                      f"{SEARCH_M:g} m of hidden path of the expected direct-return bin "
                      f"(gated, or cropped upstream)")
    peak = int(np.argmax(window))
    first = origin - int(median(shifts))  # where the record starts (typical histogram)
    truncated = peak <= first
    if peak == len(window) - 1 or (peak == 0 and not truncated):
        return None, ("none: the strongest bin near the expected direct-return bin lies at "
                      "the search window's edge (the flank of a later return, not a peak)")
    end, why_end = _end_of(profile, peak, step)
    later = float(profile[end:].max()) if end < len(profile) else 0.0
    if profile[peak] < DOMINANCE * later:
        return None, (f"none: the early peak ({profile[peak]:.3g}) is not {DOMINANCE:g}x the "
                      f"strongest later bin ({later:.3g}), so it is not the wall's direct return")
    fwhm = None if truncated else _fwhm(profile, peak)
    half_right = _half_right(profile, peak)
    width_m = (fwhm if fwhm is not None else 2 * half_right) * step
    if width_m > MAX_FWHM_M:
        return None, (f"none: the early peak is {width_m:.3g} m of path wide at half height, "
                      f"more than an instrument response ({MAX_FWHM_M:g} m)")
    rows = _row_peaks(data, shifts + (peak - origin), max(2, int(np.ceil(half_right))))
    ret = DirectReturn(peak - origin, end - origin, bool(truncated), fwhm, rows - expected,
                       profile, origin, expected, why_end)
    return ret, "found"


def _end_of(profile: np.ndarray, peak: int, step: float) -> tuple[int, str]:
    """First index after `peak` where the (3-bin smoothed) profile has fallen to
    GATE_FRACTION of the peak or to the rest's median level, at most MAX_TAIL_M later."""
    top = float(profile[peak])
    smooth = np.convolve(profile, np.ones(3) / 3, mode="same")
    cap = min(len(profile), peak + 1 + max(3, int(round(MAX_TAIL_M / step))))
    rest = profile[cap:]
    level = median(rest) if rest.size else 0.0
    threshold = max(GATE_FRACTION * top, level)
    below = np.flatnonzero(smooth[peak + 1:cap] <= threshold)
    if below.size:
        why = (f"its tail fell to {GATE_FRACTION:g} of the peak" if threshold > level else
               "its tail fell to the level of the rest of the record")
        return peak + 1 + int(below[0]), why
    return cap, f"its tail had not faded {MAX_TAIL_M:g} m of path after the peak (capped)"


def _half_right(profile: np.ndarray, peak: int) -> float:
    """Bins from the peak to where the profile falls to half of it (interpolated)."""
    half = 0.5 * profile[peak]
    after = np.flatnonzero(profile[peak:] < half)
    if not after.size:
        return float(len(profile) - peak)
    k = peak + int(after[0])
    return k - peak - (half - profile[k]) / (profile[k - 1] - profile[k])


def _fwhm(profile: np.ndarray, peak: int) -> float | None:
    """Full width at half maximum (bins, interpolated), None where the rise is cut off."""
    half = 0.5 * profile[peak]
    before = np.flatnonzero(profile[:peak] < half)
    if not before.size:
        return None
    k = int(before[-1])
    left = k + (half - profile[k]) / (profile[k + 1] - profile[k])
    return _half_right(profile, peak) + (peak - left)


def _row_peaks(data: np.ndarray, centres: np.ndarray, half: int) -> np.ndarray:
    """Per histogram, the peak bin (parabola through 3 bins) within +-half of `centres`."""
    n, n_bins = data.shape
    offsets = np.arange(-half, half + 1)
    idx = np.clip(centres[:, None] + offsets[None, :], 0, n_bins - 1)
    rows = np.arange(n)[:, None]
    k = idx[np.arange(n), np.argmax(data[rows, idx], axis=1)]
    inner = np.clip(k, 1, n_bins - 2)
    m, c, p = data[np.arange(n), inner - 1], data[np.arange(n), inner], data[np.arange(n), inner + 1]
    curve = m - 2 * c + p
    offset = np.where(curve < 0, 0.5 * (m - p) / np.where(curve < 0, curve, 1.0), 0.0)
    return np.where(k == inner, inner + np.clip(offset, -0.5, 0.5), k).astype(np.float64)
