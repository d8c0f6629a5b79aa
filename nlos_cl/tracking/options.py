"""The Tracker's options in groups (its roles, estimator, motion and background, are injected
as objects): how a frame's estimate becomes a measurement (`MeasurementNoise`), how tracks are
gated, born, confirmed and ended (`TrackRules`), and how each frame is searched (`SearchPlan`).

    Tracker(layout, grid, estimator="model", motion=Interacting(),
            noise=MeasurementNoise(max_birge_ratio=2.0), rules=TrackRules(max_misses=8))
"""
from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass(frozen=True)
class MeasurementNoise:
    """fallback_sigma_m: a measurement's sd where the estimator gives no covariance (the paper's
    argmax; track_sequence measures it on the sequence); min_sigma_m: a floor under every sd;
    max_sigma_m, max_birge_ratio: measurements with a larger sd, or a fit missing the data by
    more, are screened out (None: not screened)."""
    fallback_sigma_m: float = 0.05
    min_sigma_m: float = 0.002
    max_sigma_m: float | None = 0.5
    max_birge_ratio: float | None = None


@dataclass(frozen=True)
class TrackRules:
    """gate_probability: the gates' chi-square probability; confirm: (m, n), confirmed after m
    hits in the first n frames; max_misses: a confirmed track ends after more misses in a row;
    max_history: states kept per track (None: all); reacquire: a lost track may be re-found
    (tracking.recovery)."""
    gate_probability: float = 0.999
    confirm: tuple = (2, 3)
    max_misses: int = 5
    max_history: int | None = None
    reacquire: bool = True


@dataclass(frozen=True)
class SearchPlan:
    """search: the Locator's search ('auto', coarse to fine where it pays); gated_search: while
    every target is followed, search only a box holding the tracks' gates (tracking.gated);
    warm_start: the model estimator starts from the tracks' plates (tracking.warm); log_mode:
    sum of logs or product of the detectors' likelihoods (None: by the number of detectors)."""
    search: str = "auto"
    gated_search: bool = True
    warm_start: bool = True
    log_mode: bool | None = None


GROUPS = {"noise": MeasurementNoise, "rules": TrackRules, "plan": SearchPlan}


def grouped(**flat) -> dict:
    """Flat option names (a config file's: max_birge_ratio, max_misses, warm_start, ...) as the
    Tracker's groups: {'noise': MeasurementNoise(...), 'rules': ..., 'plan': ...}, only the
    groups named."""
    from ..core.errors import group_holding, require
    by_group: dict = {}
    for name, value in flat.items():
        arg = group_holding(name, GROUPS)
        require(arg is not None, f"tracker.{name}", "is not a tracker option",
                f"use one of {sorted(f.name for g in GROUPS.values() for f in fields(g))}")
        by_group.setdefault(arg, {})[name] = value
    return {arg: GROUPS[arg](**values) for arg, values in by_group.items()}
