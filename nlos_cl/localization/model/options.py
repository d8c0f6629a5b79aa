"""The model estimator's options: the instrument the model assumes (`Instrument`), the fits'
evaluation budgets (`FitBudget`), and the checks of what a user passes (ModelEstimator's
constructor: one line naming the field, and the group an old option name lives in now)."""
from __future__ import annotations

from dataclasses import dataclass

from ...core.constants import DEFAULT_JITTER_S, PAPER_PULSE_FWHM_S
from ...core.errors import require

MODEL_ON = ("auto", "host", "kernel", "device")


@dataclass(frozen=True)
class Instrument:
    """What the model assumes of the instrument: the laser pulse's FWHM and the detector's
    timing jitter (s), both Gaussian (the paper's 70 ps pulse; a SPAD's 30 ps)."""
    pulse_fwhm_s: float = PAPER_PULSE_FWHM_S
    jitter_s: float = DEFAULT_JITTER_S


@dataclass(frozen=True)
class FitBudget:
    """Residual evaluations (Jacobians not counted) the fits may take: `final_nfev` a cold
    fit's final fit (closed shapes get policy.closed.CLOSED_NFEV times it), `warm_nfev` a
    warm-started one (policy.warm: a tracked frame)."""
    final_nfev: int = 30
    warm_nfev: int = 10


def check_options(targets, likelihood, closed, model_on) -> None:
    """The estimator's choices, each checked where it enters (one line naming the field)."""
    require(targets == "auto" or (isinstance(targets, int) and targets >= 1), "targets",
            f"must be a positive integer or 'auto', got {targets!r}", "pass e.g. 1 or 'auto'")
    require(likelihood in ("auto", "gauss", "poisson"), "likelihood",
            f"must be 'auto', 'gauss' or 'poisson', got {likelihood!r}", "pick one")
    require(closed in ("auto", True, False), "closed", f"must be 'auto', True or False, got "
            f"{closed!r}", "pass 'auto' (a box where one plate misses the data), True or "
            "False")
    require(model_on in MODEL_ON, "model_on", f"must be one of {MODEL_ON}, got "
            f"{model_on!r}", "pass 'auto' (host for small problems), 'host', 'kernel' or 'device'")


# Where the options grouped since live (ModelEstimator's **moved: refused with the fix).
GROUPS = {"instrument": Instrument, "budget": FitBudget}


def model_reflectance(value):
    """None for Lambertian (any BRDF value: the amplitude absorbs it), else the model."""
    if value is None:
        return None
    from ...physics.reflectance import Lambertian, as_reflectance
    require(isinstance(value, (int, float)) or hasattr(value, "scale"), "reflectance",
            f"must be None, a Lambertian BRDF number or a reflectance model, got {value!r}",
            "pass e.g. nl.Retroreflective(retro=0.7, width_rad=0.005, diffuse=0.2)")
    model = as_reflectance(value)
    return None if isinstance(model, Lambertian) else model
