"""Range only: where a capture has ONE confocal spot (Keyhole imaging: the laser and the SPAD
look through one opening at one wall spot), the locator cannot place a target (one ellipsoid
fits every point on it) but the range from the spot is observed: half the hidden path at the
Gauss-filtered histogram's peak (paper Eq. 24's filter; sub-bin by a parabola through the peak
and its two neighbours)."""
from __future__ import annotations

import numpy as np

from ..core.constants import PAPER_H_S
from ..core.errors import require
from ..core.histograms import HistogramSet
from .api import gauss_filter


def confocal_range(histograms: HistogramSet, h_s: float = PAPER_H_S, *, backend=None) -> float:
    """The range (m) from a single confocal spot to the strongest return."""
    require(isinstance(histograms, HistogramSet) and histograms.n_detectors == 1
            and np.allclose(histograms.laser_spots, histograms.detector_spots), "histograms",
            "range-only location needs one confocal histogram (laser spot = detection spot)",
            "pass a frame of a single-spot confocal capture, or locate a wider one")
    y = gauss_filter(histograms, h_s, backend=backend).histograms().data[0]
    k = int(np.clip(np.argmax(y), 1, len(y) - 2))
    a, b, c = y[k - 1:k + 2]
    curvature = a - 2 * b + c
    frac = 0.5 * (a - c) / curvature if curvature < 0 else 0.0
    path = np.interp(k + frac, np.arange(len(y)), histograms.hidden_path_axis()[0])
    return 0.5 * float(path)


def confocal_ranges(frames, h_s: float = PAPER_H_S, *, backend=None) -> np.ndarray:
    """confocal_range of each frame: HistogramSets, or (t_s, HistogramSet, ...) tuples."""
    sets = [f[1] if isinstance(f, tuple) else f for f in frames]
    return np.array([confocal_range(h, h_s, backend=backend) for h in sets])
