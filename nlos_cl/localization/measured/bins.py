"""Bin-level facts of a measured capture: photon counts or processed floats, dead and hot TDC
bins (masked by their neighbours' mean), and the SPAD's pile-up (Coates' correction)."""
from __future__ import annotations

import warnings

import numpy as np

from ...core.constants import TINY
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


# Histograms a pass of hot_bins reads: a bin is hot only if it is in every histogram, so the
# bins still in question after a pass are the only ones the next pass reads (CC-SOCR's
# 4,096 x 1,024 counts: 0.65 s -> one pass of 256 rows, ~6 ms; the same bins).
ROWS_A_PASS = 256


def dead_bins(data: np.ndarray, counts: bool) -> np.ndarray:
    """Bins zero in every histogram where both neighbours are not (see DEAD_MIN_COUNTS; for
    floats: both neighbours nonzero in at least half the histograms)."""
    zero = ~np.any(data != 0, axis=0)
    zero[[0, -1]] = False  # a record's ends have one neighbour: a gate edge, not a dead bin
    k = np.flatnonzero(zero)
    if not k.size:
        return k
    if counts:  # each column's counts once (a gated CC-SOCR record has 825 empty bins of
        # 1,024: gathering both neighbours' columns of 4,096 histograms took ~0.1 s)
        total = np.abs(data).sum(axis=0)
        return k[(total[k - 1] >= DEAD_MIN_COUNTS) & (total[k + 1] >= DEAD_MIN_COUNTS)]
    left, right = np.abs(data[:, k - 1]), np.abs(data[:, k + 1])
    return k[((left > 0) & (right > 0)).mean(axis=0) >= 0.5]


def hot_bins(data: np.ndarray, counts: bool) -> np.ndarray:
    """Bins above both neighbours by HOT_SIGMA sigma in every histogram."""
    if data.shape[1] < 3 or data.shape[0] < HOT_MIN_HISTOGRAMS:
        return np.zeros(0, dtype=int)
    k = np.arange(1, data.shape[1] - 1)
    for at in range(0, len(data), ROWS_A_PASS):
        if not k.size:
            break
        rows = data[at:at + ROWS_A_PASS]
        centre = rows[:, k]
        near = np.maximum(rows[:, k - 1], rows[:, k + 1])
        k = k[np.all(centre - near > HOT_SIGMA * _sigma(rows, near, counts), axis=0)]
    return k


def _sigma(rows, near, counts):
    """A bin's noise: Poisson's of its larger neighbour (counts), else its row's robust step
    noise (the median absolute step where the row has data: robust to peaks)."""
    if counts:
        return np.sqrt(np.maximum(near, 1.0))
    steps = np.abs(np.diff(rows, axis=1))
    steps = np.where(steps > 0, steps, np.nan)
    with warnings.catch_warnings():  # an all-zero row (a gated histogram) has no steps
        warnings.simplefilter("ignore", RuntimeWarning)
        step = np.nan_to_num(np.nanmedian(steps, axis=1, keepdims=True)) * 1.4826
    return np.maximum(step, 1e-9 * np.abs(rows).max(axis=1, keepdims=True) + TINY)


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
    ratio = np.where(remaining > 0, n / np.maximum(remaining, TINY), 0.0)
    ratio = np.where(saturated, remaining / (remaining + 1.0), ratio)
    return -pulses * np.log1p(-ratio), int(saturated.sum())
