"""What a model fit reports of one target, typed (lmfit's Parameter and MinimizerResult, reduced
to what nlos_cl's fits know): the named shape parameters with their bounds and whether they
were fitted, the Birge ratio, cost, evaluations, timings and the warm start. Consumers (the
tracker's screening and warm starts, the reports) read these fields; `as_dict()` is the JSON
view (`LocatedTarget.details`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# The per-target diagnostics other layers read, through ModelFit.hidden_share / hidden_sd_m.
HIDDEN_SHARE_KEY = "hidden_share"  # the share of its paths the other targets block
HIDDEN_SD_KEY = "hidden_sd_m"  # how far the hidden part could move the centre (m)


@dataclass(frozen=True)
class Parameter:
    """One shape parameter: value, bounds (the fit's box constraints), vary (False: held, e.g.
    the height with collinear wall spots) and its standard deviation where the fit gives one."""

    name: str
    value: float
    lower: float = -math.inf
    upper: float = math.inf
    vary: bool = True
    sd: float = math.nan


@dataclass(frozen=True)
class WarmStart:
    """A fit started from a prior (a tracker's prediction): whether its answer was used, or
    the cold fit replaced it (`reason`)."""

    used: bool
    birge_ratio: float
    nfev: int
    forward_calls: int
    moved_m: float
    reason: str = ""
    # where it started: "prior" (its rows), "prior, late copies" (Prior.late), "last fit"
    # (Prior.measured; with the late copies where the prior has them)
    start: str = "prior"


@dataclass(frozen=True)
class ModelFit:
    """One target of a model fit. shape: the Shape's name ('plate', 'box', 'ellipsoid',
    'cylinder'); model: how reports name it ('upright plate', ...). birge_ratio: residual
    variance / the noise's (Gauss likelihood; None for Poisson counts, whose fit reports a
    deviance in `diagnostics`). cost: chi^2 / 2 (or the deviance / 2) of the whole frame's fit.
    diagnostics: what the model selection tried (targets, closed shapes) and why."""

    shape: str
    model: str
    parameters: tuple[Parameter, ...]
    amplitude: float
    normal: np.ndarray
    likelihood: str
    cost: float
    n_residuals: int
    birge_ratio: float | None
    height_observable: bool
    timings_s: dict = field(default_factory=dict)
    targets_tried: tuple = ()
    warnings: tuple[str, ...] = ()
    warm_start: WarmStart | None = None
    diagnostics: dict = field(default_factory=dict)

    @property
    def hidden_share(self) -> float | None:
        """The share of this target's paths the other targets block (0.0 alone; None where
        unknown: several plates fitted without shadows); the tracker learns sizes only below
        tuning.HIDDEN_SHARE."""
        return self.diagnostics.get(HIDDEN_SHARE_KEY)

    @property
    def hidden_sd_m(self) -> float | None:
        """How far the hidden part could move the centre (m): the share x half the larger side;
        the tracker adds it to the measurement's noise. Not in the covariance (the data's)."""
        return self.diagnostics.get(HIDDEN_SD_KEY)

    def values(self) -> np.ndarray:
        """The parameters' values in the shape's order (a warm start's row)."""
        return np.array([p.value for p in self.parameters], dtype=np.float64)

    def __getitem__(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"{self.model} has no parameter {name!r}: "
                       f"{[p.name for p in self.parameters]}")

    def as_dict(self) -> dict:
        """The JSON view (the keys `LocatedTarget.details` has always had)."""
        out: dict[str, Any] = {"model": self.model, "params": {p.name: p.value for p in self.parameters},
               "normal": self.normal, "amplitude": self.amplitude,
               "likelihood": self.likelihood, "cost": self.cost,
               "n_residuals": self.n_residuals, "targets_tried": list(self.targets_tried),
               "height_observable": self.height_observable, "warnings": list(self.warnings),
               "timings_s": dict(self.timings_s)}
        if self.birge_ratio is not None:
            out["birge_ratio"] = self.birge_ratio
        out.update(self.diagnostics)
        if self.warm_start is not None:
            out["warm_start"] = dict(vars(self.warm_start))
            if not self.warm_start.reason:
                del out["warm_start"]["reason"]
        return out
