"""NumPy twins of the OpenCL kernels, in float64: same inputs, same outputs, same units.

Each function here mirrors one kernel in kernels/*.cl; `NumpyBackend` exposes them with the
same method signatures as the OpenCL `Runtime`, so the pipeline can run on either and the tests
can compare the two on identical inputs. They are vectorized (no Python loop over bins, cells or
facets) because they are also the baseline the benchmarks measure the kernels against.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import correlate1d
from scipy.special import erf

from .constants import LOG_FLOOR
from .histograms import Grid
from .scene import Facets

# A facet's pulse is cut off this many sigma from its centre: 2e-9 of its energy is dropped.
REACH_SIGMAS = 6.0
# Memory bound for the forward twin: it works on blocks of this many (facet, bin) pairs.
_PAIRS_PER_BLOCK = 1 << 22


def facet_paths(centres, normals, areas, spots, laser):
    """Twin of facet_paths: hidden path r1 + r2 and geometric weight per (detector, facet).

    weight = cos_a1 cos_b1 cos_a2 cos_b2 area / (r1^2 r2^2) (paper Eq. 19 without the constants),
    0 where the facet faces away from the laser spot O or from the detector spot.
    """
    v1 = centres - laser  # (F, 3) O -> facet
    r1 = np.linalg.norm(v1, axis=1)
    v2 = spots[:, None, :] - centres[None, :, :]  # (D, F, 3) facet -> spot
    r2 = np.linalg.norm(v2, axis=2)
    cos_b1 = -np.einsum("fk,fk->f", normals, v1) / r1
    cos_a2 = np.einsum("fk,dfk->df", normals, v2) / r2
    cos_a1 = np.abs(v1[:, 1]) / r1
    cos_b2 = np.abs(v2[:, :, 1]) / r2
    lit = (cos_b1 > 0)[None, :] & (cos_a2 > 0)
    weight = np.where(lit, cos_a1 * cos_b1 * cos_a2 * cos_b2 * areas / (r1 ** 2 * r2 ** 2), 0.0)
    return r1[None, :] + r2, weight


def pulse_bins(path, weight, edge0, dpath, sigma_path, n_bins):
    """Twin of pulse_bins: hist[d, k] = sum_f w[d, f] (erf(z_{k+1}) - erf(z_k)),
    z_k = (edge0[d] + k dpath[d] - path[d, f]) / (sqrt(2) sigma_path).

    Each facet touches only the bins within REACH_SIGMAS of its path, so the work is
    facets x (a fixed window of bins), accumulated with np.bincount.
    """
    n_det = path.shape[0]
    hist = np.zeros((n_det, n_bins))
    reach = REACH_SIGMAS * sigma_path
    inv = 1.0 / (math.sqrt(2.0) * sigma_path)
    for d in range(n_det):
        lit = weight[d] > 0
        s, w = path[d, lit], weight[d, lit]
        window = int(math.ceil(2 * reach / dpath[d])) + 2
        first = np.floor((s - reach - edge0[d]) / dpath[d]).astype(np.int64)
        block = max(1, _PAIRS_PER_BLOCK // window)
        for lo in range(0, s.size, block):  # bounds memory, not a per-facet loop
            sl = slice(lo, lo + block)
            bins = first[sl, None] + np.arange(window)
            low_edge = edge0[d] + bins * dpath[d] - s[sl, None]
            e = erf(np.concatenate([low_edge, low_edge[:, -1:] + dpath[d]], axis=1) * inv)
            contrib = w[sl, None] * np.diff(e, axis=1)
            ok = (bins >= 0) & (bins < n_bins)
            hist[d] += np.bincount(bins[ok], contrib[ok], minlength=n_bins)
    return hist


def path_range(path, weight):
    """(D, 2) min and max hidden path over the facets that contribute (inf, -inf if none)."""
    lit = weight > 0
    return np.stack([np.where(lit, path, np.inf).min(axis=1),
                     np.where(lit, path, -np.inf).max(axis=1)], axis=1)


def gauss_taps(h_s: float, dt_s: float) -> np.ndarray:
    """Weights of paper Eq. 24 on a bin grid: dt N(j dt; 0, h/3) for |j| <= floor(h / dt).

    Shared by both backends: it is the definition of the discretised filter.
    """
    half = int(math.floor(h_s / dt_s + 1e-9))
    sigma = h_s / 3.0
    j = np.arange(-half, half + 1) * dt_s
    return dt_s / (math.sqrt(2.0 * math.pi) * sigma) * np.exp(-0.5 * (j / sigma) ** 2)


def gauss_filter(data, taps):
    """Twin of gauss_filter: out[k] = sum_j data[k + j - half] taps[j], zero outside the record."""
    return correlate1d(np.asarray(data, dtype=np.float64), np.asarray(taps, dtype=np.float64),
                       axis=-1, mode="constant", cval=0.0)


def row_stats(data):
    """Twin of row_stats: (D, 2) per-row max and mean of squares."""
    return np.stack([data.max(axis=1), np.mean(data ** 2, axis=1)], axis=1)


def add_awgn(signal, normal, snr_db):
    """Twin of add_awgn: white Gaussian noise at snr_db below each row's measured power."""
    power = np.mean(signal ** 2, axis=1, keepdims=True)
    return signal + normal * np.sqrt(power / 10.0 ** (snr_db / 10.0))


def ellipse_score(signal, stats, spots, laser, path0, inv_dpath, grid: Grid,
                  log_mode=False, log_floor=LOG_FLOOR):
    """Twin of ellipse_score: (nz, ny, nx) joint likelihood of every grid cell."""
    cells = grid.cell_centres().reshape(-1, 3)
    r1 = np.linalg.norm(cells - laser, axis=1)
    n_bins = signal.shape[1]
    joint = np.zeros(len(cells)) if log_mode else np.ones(len(cells))
    for d in range(signal.shape[0]):  # a loop over detectors; cells are vectorized
        u = (r1 + np.linalg.norm(cells - spots[d], axis=1) - path0[d]) * inv_dpath[d]
        i0 = np.floor(u).astype(np.int64)
        t = u - i0
        padded = np.concatenate([[0.0], signal[d], [0.0]])  # 0 outside the record
        v0 = padded[np.clip(i0, -1, n_bins) + 1]
        v1 = padded[np.clip(i0 + 1, -1, n_bins) + 1]
        peak = stats[d, 0]
        v = np.maximum(v0 + t * (v1 - v0), 0.0) * (1.0 / peak) if peak > 0 else np.zeros_like(u)
        joint = joint + np.log(np.maximum(v, log_floor)) if log_mode else joint * v
    return joint.reshape(grid.shape[2], grid.shape[1], grid.shape[0])


class NumpyBackend:
    """The reference backend: every stage in float64 NumPy, same interface as Runtime."""

    name = "numpy-reference"

    def from_numpy(self, array):
        return np.array(array, dtype=np.float64)

    def to_numpy(self, handle):
        return np.array(handle, dtype=np.float64)

    def finish(self):
        """Nothing is queued: NumPy runs synchronously."""

    def simulate(self, facets: Facets, spots, laser, edge0, dpath, sigma_path, n_bins):
        path, weight = facet_paths(facets.centres, facets.normals, facets.areas, spots, laser)
        return pulse_bins(path, weight, edge0, dpath, sigma_path, n_bins), path_range(path, weight)

    def standard_normal(self, shape, seed):
        return np.random.default_rng(seed).standard_normal(shape)

    def add_awgn(self, signal, normal, snr_db):
        return add_awgn(signal, normal, snr_db)

    def gauss_filter(self, signal, taps):
        return gauss_filter(signal, taps)

    def row_stats(self, signal):
        return row_stats(signal)

    def ellipse_score(self, signal, stats, spots, laser, path0, inv_dpath, grid, log_mode,
                      log_floor):
        return ellipse_score(signal, stats, spots, laser, path0, inv_dpath, grid, log_mode,
                             log_floor)

    def argmax(self, score):
        flat = int(np.argmax(score))
        return flat, float(score.reshape(-1)[flat])

    def read_rows(self, score, iz, iy0, iy1):
        return np.array(score[iz, iy0:iy1], dtype=np.float64)
