"""Bin-level facts of a measured capture: photon counts or processed floats, dead and hot TDC
bins (masked by their neighbours' mean), and the SPAD's pile-up (Coates' correction)."""
from __future__ import annotations

import warnings

import numpy as np

from ...core.errors import require

# A hot bin stands this many sigma above both neighbours in every histogram (Poisson sigma of
# the larger neighbour for counts, the row's robust step noise for floats): a hidden return is
# never one bin wide in every histogram at once, a TDC's faulty code is.
HOT_SIGMA = 6.0
# A dead bin is zero in every histogram while its neighbours together hold at least this many
# counts (so that all zeros by chance have probability below e^-20).
DEAD_MIN_COUNTS = 20.0
# "In every histogram" means something only with several: in one histogram a hot bin and a
# one-bin return cannot be told apart, so fewer than this many are not checked.
HOT_MIN_HISTOGRAMS = 4


def are_counts(data: np.ndarray) -> bool:
    """Integral and >= 0 in every bin: photon counts (Poisson), not processed floats."""
    return bool(np.all(data >= 0) and np.all(data == np.round(data)))


def dead_bins(data: np.ndarray, counts: bool) -> np.ndarray:
    """Bins zero in every histogram where both neighbours are not (see DEAD_MIN_COUNTS; for
    floats: both neighbours nonzero in at least half the histograms)."""
    zero = ~np.any(data != 0, axis=0)
    zero[[0, -1]] = False  # a record's ends have one neighbour: a gate edge, not a dead bin
    k = np.flatnonzero(zero)
    if not k.size:
        return k
    left, right = np.abs(data[:, k - 1]), np.abs(data[:, k + 1])
    if counts:
        ok = (left.sum(axis=0) >= DEAD_MIN_COUNTS) & (right.sum(axis=0) >= DEAD_MIN_COUNTS)
    else:
        ok = ((left > 0) & (right > 0)).mean(axis=0) >= 0.5
    return k[ok]


def hot_bins(data: np.ndarray, counts: bool) -> np.ndarray:
    """Bins above both neighbours by HOT_SIGMA sigma in every histogram."""
    if data.shape[1] < 3 or data.shape[0] < HOT_MIN_HISTOGRAMS:
        return np.zeros(0, dtype=int)
    centre = data[:, 1:-1]
    near = np.maximum(data[:, :-2], data[:, 2:])
    if counts:
        sigma = np.sqrt(np.maximum(near, 1.0))
    else:  # a row's noise: the median absolute step where it has data (robust to peaks)
        steps = np.abs(np.diff(data, axis=1))
        steps = np.where(steps > 0, steps, np.nan)
        with warnings.catch_warnings():  # an all-zero row (a gated histogram) has no steps
            warnings.simplefilter("ignore", RuntimeWarning)
            step = np.nan_to_num(np.nanmedian(steps, axis=1, keepdims=True)) * 1.4826
        sigma = np.maximum(step, 1e-9 * np.abs(data).max(axis=1, keepdims=True) + 1e-300)
    hot = np.all(centre - near > HOT_SIGMA * sigma, axis=0)
    return np.flatnonzero(hot) + 1


def mask_bins(data: np.ndarray, bins) -> np.ndarray:
    """A copy with `bins` replaced by the mean of the nearest unmasked bin on each side."""
    out = np.array(data, dtype=np.float64)
    bins = np.asarray(sorted(set(int(b) for b in bins)), dtype=int)
    if not bins.size:
        return out
    good = np.setdiff1d(np.arange(out.shape[1]), bins)
    for b in bins:
        lo, hi = good[good < b], good[good > b]
        sides = [s for s in (lo[-1:] if lo.size else [], hi[:1] if hi.size else []) if len(s)]
        out[:, b] = np.mean([out[:, s[0]] for s in sides], axis=0) if sides else 0.0
    return out


def coates(data: np.ndarray, pulses: int) -> tuple[np.ndarray, int]:
    """Coates (1968): the photons per bin a SPAD that stops at its first photon would have
    counted without pile-up, N lambda_k with lambda_k = -ln(1 - n_k / (N - sum_{j<k} n_j)),
    for `pulses` N laser pulses. Returns (corrected, bins saturated: every remaining pulse
    fired there, where lambda is infinite and one remaining pulse's worth is used instead)."""
    n = np.asarray(data, dtype=np.float64)
    remaining = pulses - (np.cumsum(n, axis=1) - n)  # pulses still armed at bin k
    worst = float((pulses - n.sum(axis=1)).min())
    require(worst >= 0, "pulses", f"{pulses} is fewer than the photons counted in one "
            f"histogram ({int(pulses - worst)}), so these are not first-photon counts of "
            f"{pulses} pulses", "pass the number of laser pulses (frames) the histograms "
            "were accumulated over")
    saturated = (n >= remaining) & (n > 0)
    ratio = np.where(remaining > 0, n / np.maximum(remaining, 1e-300), 0.0)
    ratio = np.where(saturated, remaining / (remaining + 1.0), ratio)
    return -pulses * np.log1p(-ratio), int(saturated.sum())
