"""The functional API of the locate layer: Gauss filter, Gauss fit and locate, each a thin
wrapper around a plan (nlos_cl.localization.filter, nlos_cl.localization.locator).

`locate` keeps its Locator plans in a small LRU cache (`PLANS`, PLAN_CACHE entries, as pyvkfft
keeps FFT plans), so a stream of frames through nl.locate builds its plan once and then costs
what a built Locator costs. A plan is keyed by what it fixes: the layout's content (the time
axis, spots and calibration, never the truth: frames read from a file or uploaded from the host
come with a new but equal Layout each, so identity would miss every frame), the grid, the
estimator (a name, or the object itself: an object may carry settings a name does not show),
log mode, search, signal width and the backend object (the plan's buffers live on it)."""
from __future__ import annotations

import threading
import warnings
from collections import OrderedDict

import numpy as np

from ..core.grid import Grid
from ..core.tuning import PLAN_CACHE
from ..ops.signals import Signals, as_signals
from .estimate import Location
from .filter import GaussFilter, looks_unfiltered
from .locator import Locator


def gauss_filter(signals, h_s: float | None = None, *, backend=None) -> Signals:
    """Paper Eq. 24: a Gaussian of sigma = h / 3 over the window [t - h, t + h]; h_s None: the
    paper's 0.65 ns, or 2 bins where the bins are coarser (ops.gauss_filter.filter_window)."""
    sig = as_signals(signals, backend)
    return GaussFilter(h_s, sig.layout.time_axis)(sig)


def gauss_fit(signals, *, backend=None):
    """Paper Eq. 25 baseline: a converged least-squares Gaussian per whole histogram (SciPy,
    on the host). Returns the fitted curves on the same backend, and the fit parameters."""
    from .gauss_fit import fit_gaussians
    sig = as_signals(signals, backend)
    values = sig.backend.to_numpy(sig.handle)
    centres = sig.layout.time_axis.centres()
    fit = fit_gaussians(values, centres)
    return sig.derive(sig.backend.from_numpy(fit.curves(centres))), fit


UNFILTERED_WARNING = (
    "signals: these rows still hold the bin-to-bin noise the paper's Gauss filter removes, so "
    "they were located after nl.gauss_filter (h = 0.65 ns), with themselves as `raw`; to say "
    "what they are, pass nl.gauss_filter(histograms) and raw=histograms")


def locate(signals, grid: Grid | None = None, *, log_mode: bool = False,
           return_map: bool = False, estimator=None, raw=None, backend=None,
           search: str = "coarse_to_fine", signal_width_m: float | None = None,
           detect: bool = True) -> Location:
    """Score every grid cell by the signals at its ellipse path |c - O| + |c - spot| per
    detector, combine (product, or sum of logs when log_mode), and estimate the position
    (default: the model estimator, which fits a target to the histograms; "paper": the paper's
    argmax, refined with a parabola per axis; "mean": the likelihood's mean and covariance over
    the grid, localization.posterior). `raw`: the unfiltered
    signals, for estimators that fit a model to the histograms. search: "coarse_to_fine"
    (default: the same argmax cell as "exhaustive" for a fraction of the work; see `Locator`)
    or "exhaustive"; signal_width_m: the filtered signal's width in path metres (speed only);
    detect: first test the frame for any target signal (a Location with `detected` False and no
    targets where there is none; see Locator). Signals given without `raw` that still hold the
    histograms' white bin-to-bin noise (filter.looks_unfiltered: the histograms themselves,
    passed where the filtered ones belong) are Gauss-filtered here first and serve as `raw`,
    with a warning: the argmax and the model both assume filtered signals (unfiltered 10 dB
    frames of the paper's scene were located 5-9 cm off, some with a misleading warning)."""
    sig = as_signals(signals, backend)
    if raw is None and looks_unfiltered(sig):  # the histograms themselves: filter them first
        warnings.warn(UNFILTERED_WARNING, stacklevel=2)
        sig, raw = gauss_filter(sig), sig
    key = _plan_key(sig, grid, estimator, log_mode, search, signal_width_m)
    plan = PLANS.take(key, sig.backend, estimator)
    if plan is None:
        plan = Locator(sig.layout, grid, estimator=estimator, log_mode=log_mode, search=search,
                       signal_width_m=signal_width_m)
    location = plan(sig, raw=raw, return_map=return_map, detect=detect)
    PLANS.give(key, plan, sig.backend)  # only after a call that worked
    return location


def _bytes(values) -> bytes:
    return np.ascontiguousarray(values, dtype=np.float64).tobytes()


def _plan_key(sig: Signals, grid, estimator, log_mode, search, signal_width_m):
    """What fixes a Locator, hashable; None where it cannot be (the call builds its own plan)."""
    lay = sig.layout
    cal = lay.calibration
    layout = (lay.time_axis, _bytes(lay.detector_spots), _bytes(lay.laser_spot),
              float(cal.a_m_per_s), _bytes(cal.offsets(lay.n_detectors)))
    named = estimator is None or isinstance(estimator, str)
    key = (layout, grid, estimator if named else ("object", id(estimator)), bool(log_mode),
           search, signal_width_m, id(sig.backend))
    try:
        hash(key)
    except TypeError:  # e.g. a signal width given as an array
        return None
    return key


class PlanCache:
    """The most recently used Locator plans, at most `size`. A plan is taken out while a call
    uses it (its buffers are per call), so two threads never share one: a second caller with
    the same key builds its own, and the later one given back stays."""

    def __init__(self, size: int = PLAN_CACHE):
        self.size = int(size)
        self._plans = OrderedDict()  # key -> (plan, backend)
        self._lock = threading.Lock()

    def take(self, key, backend, estimator):
        """The plan for `key`, removed from the cache; None if there is none."""
        if key is None:
            return None
        with self._lock:
            entry = self._plans.pop(key, None)
        if entry is None:
            return None
        plan, held = entry
        # the entry holds the backend and the estimator alive, so their ids in the key are
        # theirs alone: these checks only restate that
        named = estimator is None or isinstance(estimator, str)
        return plan if held is backend and (named or plan.estimator is estimator) else None

    def give(self, key, plan, backend) -> None:
        """Keep `plan` as the most recently used; drop the least recently used beyond size."""
        if key is None or self.size < 1:
            return
        with self._lock:
            self._plans[key] = (plan, backend)
            self._plans.move_to_end(key)
            while len(self._plans) > self.size:
                self._plans.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._plans.clear()

    def __len__(self) -> int:
        return len(self._plans)


PLANS = PlanCache()
