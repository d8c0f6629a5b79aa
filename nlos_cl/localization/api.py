"""The functional API of the locate layer: Gauss filter, Gauss fit and locate, each a thin
wrapper that builds a plan (nlos_cl.localization.filter, nlos_cl.localization.locator) and calls it once.
For a stream of frames build the plans yourself and call them per frame."""
from __future__ import annotations

from ..core.constants import PAPER_H_S
from ..core.grid import Grid
from ..ops.signals import Signals, as_signals
from .estimate import Location
from .filter import GaussFilter
from .locator import Locator


def gauss_filter(signals, h_s: float = PAPER_H_S, *, backend=None) -> Signals:
    """Paper Eq. 24: a Gaussian of sigma = h / 3 over the window [t - h, t + h]."""
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


def locate(signals, grid: Grid | None = None, *, log_mode: bool = False,
           return_map: bool = False, estimator=None, raw=None, backend=None,
           search: str = "coarse_to_fine", signal_width_m: float | None = None) -> Location:
    """Score every grid cell by the signals at its ellipse path |c - O| + |c - spot| per
    detector, combine (product, or sum of logs when log_mode), and estimate the position
    (default: the model estimator, which fits a target to the histograms; "paper": the paper's
    argmax, refined with a parabola per axis). `raw`: the unfiltered
    signals, for estimators that fit a model to the histograms. search: "coarse_to_fine"
    (default: the same argmax cell as "exhaustive" for a fraction of the work; see `Locator`)
    or "exhaustive"; signal_width_m: the filtered signal's width in path metres (speed only)."""
    sig = as_signals(signals, backend)
    plan = Locator(sig.layout, grid, estimator=estimator, log_mode=log_mode, search=search,
                   signal_width_m=signal_width_m)
    return plan(sig, raw=raw, return_map=return_map)
