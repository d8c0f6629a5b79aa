"""How a facet's pulse lands in the time bins: the forward operation's host side of paper
Eq. 22-23 (the Gaussian pulse integrated over each bin with erf), for both of its ways.

erf (kernels/forward.cl pulse_bins, and the NumPy twin here): every bin within REACH_SIGMAS of
a facet's path gets that facet's erf difference. Exact for any pulse; its work is facets x the
bins within reach, and it needs no memory beyond the path and weight rows.

deposit (deposit + resolve + convolve): each facet's weight split between sub-bins of at most
sigma / SUB_BINS_PER_SIGMA, then one correlation with the bin-integrated pulse. Its buffers
grow as bin / sigma (sub-bins per bin) and its taps as sigma / bin: a 1 fs pulse on 1 ps bins
needs 56,600 sub-bins per bin (3 GB on the paper's scene), a 1 ms pulse 5e9 taps. `binning`
keeps the deposit to the pulses it is fast for and gives the others to erf, so memory is
bounded by the facets and the time axis whatever the pulse.
"""
from __future__ import annotations

import functools
import math

import numpy as np

REACH_SIGMAS = 6.0  # a facet's pulse is cut off 6 sigma from its centre: 2e-9 of its energy
SUB_BINS_PER_SIGMA = 24  # deposit: sub-bins of at most sigma / 24 (linear deposit error ~1e-4)
_PAIRS_PER_BLOCK = 1 << 22  # the twin works on blocks of this many (facet, bin) pairs
# The deposit's range: at most 64 sub-bins per bin (a pulse sigma of >= 0.375 bin) and 4097
# taps per phase (a sigma of <= ~340 bins). The paper's 70 ps pulse on 1 ps to 10 ps bins uses
# 1 to 8 sub-bins and 363 to 39 taps; outside the range erf is both exact and cheaper (a short
# pulse reaches ~3 bins, so each facet costs ~2 erf blocks).
MAX_SUB_BINS = 64
MAX_TAPS = 4097


def deposit_sizes(step_m: float, sigma_path_m: float) -> tuple[int, int]:
    """(sub-bins per bin OS, taps half-width T) of the deposit for bins of `step_m` of path."""
    os_ = max(1, int(math.ceil(step_m * SUB_BINS_PER_SIGMA / sigma_path_m)))
    return os_, int(math.ceil(REACH_SIGMAS * sigma_path_m / step_m)) + 1


def binning(method: str, step_m: float, sigma_path_m: float) -> str:
    """The method that runs: "deposit" where asked and within its range, else "erf"."""
    if method != "deposit":
        return method
    os_, half = deposit_sizes(step_m, sigma_path_m)
    return "deposit" if os_ <= MAX_SUB_BINS and 2 * half + 1 <= MAX_TAPS else "erf"


def pulse_bins(path, weight, edge0, dpath, sigma_path, n_bins):
    """hist[d, k] = sum_f w[d, f] (erf(z_{k+1}) - erf(z_k)); each facet touches only the bins
    within REACH_SIGMAS of its path and on the axis (work = facets x at most n_bins + 1, via
    np.bincount), so neither a pulse far shorter than a bin nor one longer than the axis costs
    more than the axis."""
    from scipy.special import erf
    hist = np.zeros((path.shape[0], n_bins))
    reach = REACH_SIGMAS * sigma_path
    inv = 1.0 / (math.sqrt(2.0) * sigma_path)
    for d in range(path.shape[0]):
        lit = weight[d] > 0
        s, w = path[d, lit], weight[d, lit]
        reach_bins = int(math.ceil(2 * reach / dpath[d])) + 2
        # each facet's bins within reach, clipped to the axis: [first, end) of at most window
        start = np.floor((s - reach - edge0[d]) / dpath[d])  # float64: no overflow
        first = np.clip(start, 0, n_bins).astype(np.int64)
        end = np.clip(start + reach_bins, 0, n_bins).astype(np.int64)
        window = min(reach_bins, n_bins + 1)
        block = max(1, _PAIRS_PER_BLOCK // window)
        for lo in range(0, s.size, block):  # bounds memory, not a per-facet loop
            sl = slice(lo, lo + block)
            bins = first[sl, None] + np.arange(window)
            low_edge = edge0[d] + bins * dpath[d] - s[sl, None]
            e = erf(np.concatenate([low_edge, low_edge[:, -1:] + dpath[d]], axis=1) * inv)
            contrib = w[sl, None] * np.diff(e, axis=1)
            ok = bins < end[sl, None]
            hist[d] += np.bincount(bins[ok], contrib[ok], minlength=n_bins)
    return hist


def deposit_plan(span, total, edge0, dpath, sigma_path, n_bins):
    """Per detector: sub-bins per bin (OS), taps per phase (SPAN = 2 T + 1), the window of
    bins that can receive light [first, first + count) (first on a multiple of 16), the
    deposit's base path (T bins before the window), and the fixed-point scale (2^40 / the
    detector's weight sum: no sum can overflow 64 bits, each facet keeps ~1e-12 of it)."""
    step = float(np.max(dpath))
    os_, half = deposit_sizes(step, sigma_path)
    reach = REACH_SIGMAS * sigma_path
    lit = np.isfinite(span[:, 0])
    lo = np.where(lit, np.floor((span[:, 0] - reach - edge0) / dpath) - 1, 0)
    hi = np.where(lit, np.ceil((span[:, 1] + reach - edge0) / dpath) + 2, 0)
    first = (np.clip(lo, 0, n_bins) // 16 * 16).astype(np.int64)
    count = np.maximum(np.clip(hi, 0, n_bins) - first, 0).astype(np.int64)
    base = edge0 + (first - half) * dpath
    scale = np.where(total > 0, 2.0 ** 40 / np.where(total > 0, total, 1.0), 1.0)
    return os_, half, first, count, base, scale


@functools.lru_cache(maxsize=64)
def deposit_taps(os_, half, dpath, sigma_path) -> np.ndarray:
    """(OS, 2 T + 1): taps[p][t], twice the pulse energy that a unit weight at the centre of
    sub-bin phase p, t bins into the deposit window, puts into the bin (float64 erf).
    A few hundred values, cached (a model fit asks for the same table ~100 times) and
    computed with nlos_cl.core.erf: SciPy's import (~0.1 s) would dominate a one-shot `locate`."""
    from ..core.erf import erf
    dsub = dpath / os_
    p = np.arange(os_)[:, None]
    t = np.arange(2 * half + 1)[None, :]
    edge = lambda k: ((half - t + k) * os_ - p - 0.5) * dsub  # noqa: E731
    inv = 1.0 / (math.sqrt(2.0) * sigma_path)
    taps = erf(edge(1) * inv) - erf(edge(0) * inv)
    taps.flags.writeable = False
    return taps
