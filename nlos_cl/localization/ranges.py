"""Range only: where a capture has ONE confocal spot (Keyhole imaging: the laser and the SPAD
look through one opening at one wall spot), the locator cannot place a target (one ellipsoid
fits every point on it) but the range from the spot is observed: half the hidden path at the
centroid of the Gauss-filtered histogram's main lobe (paper Eq. 24's filter, then
measured.lobe.lobe_centroid: the run of bins around the peak above half of it). The peak of an
extended target's return jumps between its brightest parts (Keyhole's letters: up to 0.1 m of
range as the stage moves); the lobe's centroid follows its middle (Keyhole Y: RMS against the
stage 0.026 -> 0.011 m)."""
from __future__ import annotations

import numpy as np

from ..core.errors import require
from ..core.histograms import HistogramSet
from .api import gauss_filter


def is_single_confocal(histograms) -> bool:
    """One histogram whose laser spot is its detection spot: what confocal_range measures."""
    return isinstance(histograms, HistogramSet) and histograms.n_detectors == 1 and bool(
        np.allclose(histograms.laser_spots, histograms.detector_spots))


def confocal_range(histograms: HistogramSet, h_s: float | None = None, *, backend=None) -> float:
    """The range (m) from a single confocal spot to the middle of its strongest return."""
    return detected_range(histograms, h_s, backend=backend, detect_target=False)[0]


def detected_range(histograms: HistogramSet, h_s: float | None = None, *, backend=None,
                   detect_target: bool = True) -> tuple:
    """(range m, Detection or None): confocal_range, where the frame's detection (the
    locator's test, over the whole record, with the unfiltered row's noise where the record has
    no bins free of signal) finds a return; NaN where it finds none (noise, or an empty
    record), whose strongest bin is no target's."""
    require(is_single_confocal(histograms), "histograms",
            "range-only location needs one confocal histogram (laser spot = detection spot)",
            "pass a frame of a single-spot confocal capture, or locate a wider one")
    from .detection import detect, raw_floor_of
    from .measured.lobe import lobe_centroid
    filtered = gauss_filter(histograms, h_s, backend=backend)
    rows = filtered.histograms().data
    found = detect(rows, raw=raw_floor_of(histograms, filtered)) if detect_target else None
    if found is not None and not found.detected:
        return float("nan"), found
    y = rows[0]
    path = np.interp(lobe_centroid(y), np.arange(len(y)), histograms.hidden_path_axis()[0])
    return 0.5 * float(path), found


def confocal_ranges(frames, h_s: float | None = None, *, backend=None) -> np.ndarray:
    """confocal_range of each frame: HistogramSets, or (t_s, HistogramSet, ...) tuples."""
    sets = [f[1] if isinstance(f, tuple) else f for f in frames]
    return np.array([confocal_range(h, h_s, backend=backend) for h in sets])


def range_rules(frames, h_s: float | None = None) -> dict:
    """A diagnosis: each frame's range (m) by other rules on the same Gauss-filtered return:
    its peak, and the half-height crossings of its main lobe (the near edge, `leading`, and
    the far one, `trailing`). A letter beside the grid's centre moves them apart: where each
    rule sits on the letter is another lateral place."""
    out = {"peak": [], "leading": [], "trailing": []}
    for _, h in frames:
        y = gauss_filter(h, h_s).histograms().data[0].astype(np.float64)
        half_path = 0.5 * h.hidden_path_axis()[0]
        k = int(np.argmax(y))
        half = 0.5 * y[k]
        lo = k - int(np.argmax(y[k::-1] <= half))  # the first bin at or below half, each side
        hi = k + int(np.argmax(y[k:] <= half))
        at = lambda a, b: a + (half - y[a]) / (y[b] - y[a]) * (b - a)  # noqa: E731
        for name, place in (("peak", k), ("leading", at(lo, lo + 1)), ("trailing", at(hi - 1, hi))):
            out[name].append(float(np.interp(place, np.arange(len(y)), half_path)))
    return {k: np.array(v) for k, v in out.items()}
