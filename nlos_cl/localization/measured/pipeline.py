"""Measured-data processing of one HistogramSet, every step reported: bins (counts or floats,
dead and hot bins masked), pile-up (Coates, with `pulses`), time zero from the direct return,
the instrument response, background subtraction, and the first-bounce gate.

The order is the data's: pile-up acts on raw first-photon counts; dead and hot bins are masked
before a hot bin can pose as a direct return; the direct return is measured before the
background is subtracted (a target-free capture holds the same wall return and would cancel
it); the gate and the corrected time zero apply to the result. Nothing is tuned to one
dataset: every threshold is a named constant in direct.py or bins.py with its reason.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...core.constants import FWHM_PER_SIGMA, PAPER_H_S
from ...core.errors import require
from ...core.stats import median, unique_sorted
from ...core.histograms import HistogramSet
from ...core.paths import TimeAxis
from . import bins as binfacts
from .direct import SEARCH_M, DirectReturn, expected_bins, find_direct_return
from .response import fit_exgauss, tail_tau

# The file's time zero is trusted while the direct return's peak is within this many bins of
# where it belongs (a parabola's peak on Poisson counts wanders ~0.1-0.5 bin; a bin or two is
# the TDC's own rounding).
SHIFT_TOLERANCE_BINS = 2.0
# Full 8-, 12-, 16- and 32-bit counters: a direct return reaching one is clipped (Keyhole's
# direct_after peaks at 65,535).
SATURATED_COUNTS = {2.0 ** b - 1 for b in (8, 12, 16, 32)}


@dataclass(frozen=True)
class Processed:
    """The processed set, the Gauss filter window the direct return suggests (h = 3 sigma, the
    sigma of a Gaussian as wide at half height; None where it was not measured), the report."""

    histograms: HistogramSet
    h_from_response_s: float | None
    report: dict


def _r(x, digits=6):
    return None if x is None else float(f"{float(x):.{digits}g}")


def process_measured(hist: HistogramSet, *, background: HistogramSet | None = None,
                     negatives: str = "keep", pulses: int | None = None,
                     calibrated: bool = False) -> Processed:
    """Run the steps on one set (a laser point); `background` a target-free set of the same
    layout; `pulses` the laser pulses per histogram (Coates; None: off); `calibrated`: a path
    calibration follows, which fixes time zero itself (the t0 correction is then reported only).
    """
    require(pulses is None or (isinstance(pulses, (int, np.integer)) and not
                               isinstance(pulses, bool) and pulses > 0), "pulses",
            f"must be a positive count of laser pulses per histogram, got {pulses!r}",
            "pass e.g. pulses=1000000, or leave it out (no pile-up correction)")
    report = {}
    data, counts = hist.data, binfacts.are_counts(hist.data)
    bg = None if background is None else background.data
    report["pile_up"], data, bg = _pile_up(data, bg, counts, pulses)
    report["bins"], data, bg = _bins(hist, data, bg, counts)
    staged = replace(hist, data=data)
    direct, seen = find_direct_return(staged)
    report["time_zero"], shift = _time_zero(hist, direct, seen, calibrated)
    report["instrument_response"], h_resp = _response(hist, direct, counts)
    report["background"], staged = _background(staged, background, bg, negatives)
    report["first_bounce_gate"], staged = _gate(staged, direct)
    if shift:
        axis = hist.time_axis
        staged = replace(staged, time_axis=TimeAxis(axis.t0_s - shift * axis.dt_s, axis.dt_s,
                                                    axis.n_bins))
    return Processed(staged, h_resp, report)


def _pile_up(data, bg, counts, pulses):
    if pulses is None:
        return ({"applied": False, "why": "off by default: pass pulses (the laser pulses "
                 "each histogram was accumulated over) for Coates' correction"}, data, bg)
    require(counts, "pulses", "pile-up correction needs photon counts, and these histograms "
            "are processed floats (not all integral and >= 0)", "leave pulses out for "
            "processed data")
    data, saturated = binfacts.coates(data, int(pulses))
    note = {"applied": True, "method": "Coates", "pulses": int(pulses),
            "saturated_bins": saturated}
    if bg is not None:
        require(binfacts.are_counts(bg), "background", "holds processed floats, the capture "
                "photon counts, so one pile-up correction cannot apply to both",
                "pass the background as recorded (counts), or leave pulses out")
        bg, note["background_saturated_bins"] = binfacts.coates(bg, int(pulses))
    return note, data, bg


def _bins(hist, data, bg, counts):
    """Dead and hot bins masked alike in signal and background; a hot bin where the direct
    return belongs is left to the direct-return step (a one-bin wall return is not a fault)."""
    dead = binfacts.dead_bins(data, counts)
    hot = binfacts.hot_bins(data, counts)
    search = SEARCH_M / float(hist.path_axis().step_m[0])
    expected = expected_bins(hist)
    near_direct = np.array([bool(np.any(np.abs(b - expected) <= search)) for b in hot], bool)
    left, hot = hot[near_direct], hot[~near_direct]
    masked = unique_sorted(np.concatenate([dead, hot]))
    note = {"kind": "counts" if counts else "floats",
            "kind_why": ("every bin integral and >= 0: photon counts (Poisson)" if counts else
                         "not all bins integral and >= 0: processed floats"),
            "dead": dead.tolist(), "hot": hot.tolist(),
            "masked": "by their neighbours' mean" if masked.size else "none"}
    if left.size:
        note["hot_left_as_direct_return"] = left.tolist()
    if masked.size:
        data = binfacts.mask_bins(data, masked)
        bg = None if bg is None else binfacts.mask_bins(bg, masked)
    return note, data, bg


def _time_zero(hist, direct: DirectReturn | None, seen: str, calibrated: bool):
    """(report, t0 shift in bins to apply: 0 for none)."""
    axis = hist.time_axis
    note = {"t0_s_file": axis.t0_s, "expected_path_m": _r(median(
        np.linalg.norm(hist.laser_spots - hist.detector_spots, axis=1)))}
    if direct is None:
        return {**note, "direct_return": seen, "action": "kept the file's t0"}, 0.0
    rows = direct.shifts_bins
    shift = median(rows)
    q1, q3 = np.percentile(rows, [25, 75])
    note.update(direct_return="found", histograms=int(rows.size),
                peak_shift_bins=_r(shift, 4), shift_spread_bins=_r(q3 - q1, 4),
                peak_shift_s=_r(shift * axis.dt_s))
    if direct.truncated:
        note["truncated"] = ("the peak is the record's first bin: the rise came before the "
                             "record, so the true peak may be earlier")
    if abs(shift) <= SHIFT_TOLERANCE_BINS:
        return {**note, "action": f"kept the file's t0: the peak is within "
                f"{SHIFT_TOLERANCE_BINS:g} bins of where it belongs"}, 0.0
    if direct.truncated and shift > 0:
        return {**note, "action": "kept the file's t0: a cut-off peak only bounds it"}, 0.0
    if calibrated:
        return {**note, "action": "kept: the path calibration given fixes time zero"}, 0.0
    return {**note, "action": f"corrected t0 by {-shift * axis.dt_s:+.4g} s "
            f"({-shift:+.3g} bins)", "t0_s_used": axis.t0_s - shift * axis.dt_s}, shift


def _response(hist, direct: DirectReturn | None, counts: bool):
    """(report, h = 3 sigma_fwhm in s, or None)."""
    dt = hist.time_axis.dt_s
    if direct is None:
        return {"measured": False, "why": "no direct return to measure it on"}, None
    p, y = direct.origin + direct.peak, direct.profile
    if direct.truncated or direct.fwhm_bins is None:
        tau = tail_tau(y, p)
        return {"measured": "tail only", "why": "the rise is cut off by the record's start",
                "tau_s": _r(None if tau is None else tau * dt), "fit": "log-linear tail"}, None
    fwhm = direct.fwhm_bins
    lo = max(0, p - max(10, int(3 * fwhm)))
    hi = max(direct.origin + direct.end, p + 5)
    t = np.arange(lo, hi) + 0.0
    seg = y[lo:hi]
    weights = 1.0 / np.sqrt(np.maximum(seg, 1.0)) if counts else np.ones_like(seg)
    floor0 = median(y[lo:max(lo + 1, p - int(2 * fwhm))])
    start = (max(float(seg.sum() - floor0 * seg.size), 1e-30), p - 0.2 * fwhm,
             max(0.3, 0.35 * fwhm), max(0.5, 0.5 * fwhm), floor0)
    fit = fit_exgauss(t, seg, weights, start)
    sigma_eff = fwhm * dt / FWHM_PER_SIGMA
    note = {"measured": True, "fwhm_s": _r(fwhm * dt), "sigma_fwhm_s": _r(sigma_eff),
            "fit": "exGaussian" if fit is not None else "failed (FWHM only)"}
    top = float(hist.data.max())
    if counts and top in SATURATED_COUNTS:
        note["saturated"] = (f"the histograms reach {int(top)} counts, a full counter: "
                             "the peak is clipped and its widths are upper bounds")
    if fit is not None:
        note.update(sigma_s=_r(fit.sigma * dt), tau_s=_r(fit.tau * dt),
                    converged=fit.converged)
    h = max(3.0 * sigma_eff, dt)  # the filter needs at least one bin
    note["h_from_response_s"] = _r(h)
    return note, h


def _background(staged, background, bg, negatives):
    if background is None:
        return {"applied": False, "why": "none given (pass background=, --background: a "
                "capture without the target)"}, staged
    from ..background import subtract_background
    out = subtract_background(staged, replace(background, data=bg), negatives=negatives)
    return {"applied": True, "negatives": negatives}, out


def _gate(staged, direct: DirectReturn | None):
    """Zero every histogram's bins before its direct return's end."""
    if direct is None:
        return {"applied": False, "why": "no direct return in the record"}, staged
    ends = np.clip(np.round(direct.expected).astype(int) + direct.end, 0, staged.time_axis.n_bins)
    data = np.array(staged.data)
    data[np.arange(data.shape[1])[None, :] < ends[:, None]] = 0.0
    axis = staged.path_axis()
    end_m = median(axis.start_m + ends * axis.step_m)  # hidden path where data resume
    return {"applied": True, "bins": int(median(ends)), "path_m": _r(end_m, 4),
            "why": direct.why_end,
            "hides": f"hidden paths below ~{end_m:.3g} m (objects within ~{end_m / 2:.3g} m "
                     "of the wall)"}, replace(staged, data=data, allow_negative=True)


def pooled_h(processed: list) -> float | None:
    """One instrument, one window: the median of the sets' measured h (None if none)."""
    hs = [p.h_from_response_s for p in processed if p.h_from_response_s is not None]
    return median(hs) if hs else None


def process_capture(sets: list, backgrounds: list | None, *, negatives: str = "keep",
                    pulses: int | None = None, h_s: float | None = None,
                    calibrated: bool = False) -> tuple[list, list, float, str]:
    """Every laser point's set processed: (sets, reports, the Gauss filter's h, where h came
    from). h: the caller's where given; else 3 sigma of the direct return's width, pooled over
    the laser points (one instrument); else the filter's default for the bins (the paper's
    0.65 ns, or 2 bins where they are coarser: ops.gauss_filter.filter_window)."""
    from ...ops.gauss_filter import filter_window
    backgrounds = [None] * len(sets) if backgrounds is None else backgrounds
    done = [process_measured(h, background=b, negatives=negatives, pulses=pulses,
                             calibrated=calibrated) for h, b in zip(sets, backgrounds)]
    measured = pooled_h(done)
    if h_s is not None:
        h, source = float(h_s), "given"
    elif measured is not None:
        h, source = measured, "the direct return: 3 x its FWHM / 2.355 (the paper's sigma = h / 3)"
    else:
        h = filter_window(sets[0].time_axis.dt_s)
        source = ("the paper's 0.65 ns" if h == PAPER_H_S else "2 bins (the paper's 0.65 ns is "
                  "under 2 bins)") + " (no direct return to measure the response on)"
    for p in done:
        p.report["instrument_response"].update(h_s=_r(h), h_source=source)
    return [p.histograms for p in done], [p.report for p in done], h, source
