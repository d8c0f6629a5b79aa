"""A model fit checked against what it claims, before it is reported (the rule: "a misfit
reported in warnings with a fallback to the paper's estimate, never a silent 0.5 m answer").

Checks, each a claim the fit makes about itself that the data or the paper's argmax can
contradict (thresholds and their reasons: core/tuning.py):
- size: no dimension beyond MAX_EXTENT_M (a wide plate fitted as a 2 x 3 m box);
- paths: each detector's ellipse path through the fitted centre within the fitted diagonal +
  2 ARGMAX_MARGIN_M of the path through the paper's argmax, which lies on the target's
  visible surface (the fit went to another basin). Paths, not positions: with collinear spots
  the argmax slides along its ridge (1.4 m from an 0.8 x 1.2 m plate's centre in
  tests/localization/model/test_model_estimator.py) while its paths stay right.
One target: a fit that fails one is replaced by the paper's argmax (no covariance: a tracker
uses its fallback sigma) and the reason is warned. Several targets: the paper's argmax gives
one position only, on one of them, so the paths check is skipped and a target failing the
others is kept and warned about.
- misfit, and depth unseen or signal unexplained: a closed shape (box, ellipsoid, cylinder, capsule)
  whose Birge ratio is above MISFIT_BIRGE AND whose depth these spots cannot tell
  (depth.unseen_note) OR that leaves more than 1 - EXPLAINED_MIN of the signal unexplained
  (the share of the no-target cost its fit leaves: likelihood.Problem.null_cost): the closed
  shape was tried because the plate missed the data, missed it too, and its centre lies a
  guessed depth behind the surface (CC-SOCR as one laser and N detectors by reciprocity: plate
  Birge 320-450, an ellipsoid or box centre 0.24-0.40 m behind the "4", depth sd 0.30-0.52 m
  or, with the amplitudes converged, sd 0.08 m and 19-27 % of the signal unexplained, where
  the argmax is on it).
A Birge ratio above MISFIT_BIRGE alone is warned about but not replaced: closed shapes fitted
to nearly noise-free boxes reach 1,238 (and 60 dB simulations 1,300-10,000) with the centre
right, their depth seen and under 1e-4 of the signal unexplained, so the ratio alone does not
say the position is wrong."""
from __future__ import annotations

import numpy as np

from ....core.errors import warn
from ....core.tuning import ARGMAX_MARGIN_M, EXPLAINED_MIN, MAX_EXTENT_M, MISFIT_BIRGE
from ...estimate import LEFTOVER, LocatedTarget
from ...region import line_direction, unseen_axis


def doubt(target: LocatedTarget, paper_position, spots, lasers) -> str | None:
    """Why this fitted target's position should not be believed, or None. paper_position:
    None where the argmax belongs to no one target (several fitted: it is on one of them)."""
    fit, extent = target.fit, target.extent_m
    if fit is None:
        return None
    if extent is not None and float(np.max(extent)) > MAX_EXTENT_M:
        size = " x ".join(f"{v:.2f}" for v in extent if v > 0)
        return (f"the fitted {fit.shape} is {size} m, larger than the {MAX_EXTENT_M} m any "
                "target is expected to be")
    seen = fit.diagnostics or {}
    if closed_centre_guessed(fit.shape, seen):
        ratio, left = seen["misfit_ratio"], 1.0 - (seen.get("explained") or 0.0)
        why = ("these spots cannot tell its depth" if seen.get("depth_unseen") else
               f"it leaves {100 * left:.0f} % of the signal unexplained")
        return (f"the fitted {fit.shape} does not explain the data (residual {ratio:.0f} times "
                f"the noise's, above {MISFIT_BIRGE:.0f}) and {why}, so its centre is a guess "
                "behind the surface")
    if paper_position is None:
        return None
    reach = float(np.linalg.norm(extent if extent is not None else 0.0)) + 2 * ARGMAX_MARGIN_M
    apart = float(np.max(np.abs(_paths(target.position, spots, lasers)
                                - _paths(paper_position, spots, lasers))))
    if apart > reach:
        return (f"its ellipse paths differ from the paper's argmax's by up to {apart:.2f} m, "
                f"more than its fitted size allows ({reach:.2f} m)")
    return None


def fit_checks(chosen, result, free, cov_all, info) -> dict:
    """What `doubt` reads from a fit's diagnostics (model.estimator reports them; model.subset
    asks before it refits on every detector): misfit_ratio (the Birge ratio, or counts'
    deviance per degree of freedom, as criteria.misfit), explained (the share of the
    no-target cost the fit removes, 1 - cost / Problem.null_cost) and depth_unseen (one
    target whose depth these spots cannot tell: depth.unseen_note)."""
    from .depth import unseen_note
    from .criteria import misfit as misfit_of
    return {"misfit_ratio": misfit_of(chosen, result, free, info)[1],
            "explained": explained_share(chosen, result),
            "depth_unseen": len(result.params) == 1 and
            unseen_note(chosen.shape, result, cov_all, info) is not None}


def explained_share(problem, result) -> float | None:
    """The share of the no-target cost (Problem.null_cost) the fit removes; None where the
    data hold no cost to remove."""
    null = problem.null_cost()
    return 1.0 - result.cost / null if null > 0 else None


def leftover_note(problem, result, targets) -> str | None:
    """Where the fit's residual still holds a return (the locator's detection test, at its
    false-alarm rate, on the residual in noise units): what it may be and how to look for it;
    None where the residual is noise. Gaussian noise only (the counts' Pearson residuals are
    not Gaussian at a few counts a bin). A one-target fit to two plates' capture left one plate
    unexplained without a word (docs/scenes/two_squares.yaml: residual statistic 285 against
    its threshold 39), while plate captures at 0-30 dB leave 2-4. On random draws with the
    default K = 1 (reproduce draws' families, indices 0-10/12): said on 11 of 11 multi draws
    (2-3 plates), 0 of 11 `one` and 0 of 13 `closed` draws, 7 of 13 `mismatch` draws (the model
    lacks their pulse, tail, BRDF or background), the two mismatch failures among them."""
    from ...detection import detect
    obs = problem.obs
    if obs.mode != "gauss":
        return None
    cols = problem.columns(result.params)
    z = (obs.y - problem.mean(cols, result.linear)) / obs.noise[:, None]
    if not detect(np.where(obs.valid, z, 0.0)).detected:
        return None
    more = ("look for more targets with targets='auto' (nlos-cl: --targets auto)"
            if targets != "auto" else "no further target passed the model selection")
    return (f"{LEFTOVER} (the detection's test on "
            "the fit's residual): another target, or light the model does not describe (a "
            f"shape, reflectance, background or instrument tail); {more}")


def closed_centre_guessed(shape: str, checks: dict) -> bool:
    """A closed shape whose misfit ratio is above MISFIT_BIRGE and whose depth is unseen or
    that explains less than EXPLAINED_MIN of the signal (`fit_checks`' fields): `doubt`
    replaces it with the argmax."""
    ratio, explained = checks.get("misfit_ratio"), checks.get("explained")
    return shape != "plate" and ratio is not None and ratio > MISFIT_BIRGE and (
        bool(checks.get("depth_unseen")) or (explained is not None and explained < EXPLAINED_MIN))


def misfit(target: LocatedTarget) -> str | None:
    """The misfit warning: the Birge ratio, or for counts (no Birge ratio) the deviance per
    degree of freedom the estimator reports as misfit_ratio, above MISFIT_BIRGE."""
    fit = target.fit
    ratio = None if fit is None else fit.birge_ratio
    if fit is not None and ratio is None:
        ratio = (fit.diagnostics or {}).get("misfit_ratio")
    if ratio is None or ratio <= MISFIT_BIRGE:
        return None
    name = "Birge ratio" if fit.birge_ratio is not None else "deviance per degree of freedom"
    return (f"the fit does not explain the data ({name} {ratio:.0f} > {MISFIT_BIRGE:.0f}: the "
            "residual is that many times the noise's variance)")


def unfittable_line(spots, laser) -> str | None:
    """Why the fit cannot take collinear spots whose line is along neither x nor z (the
    unobservable azimuth about the line then mixes x and z: no one axis to hold, as z is for
    a line along x and x for one along z), or None. The region's rule (region.unseen_axis)."""
    pts = np.vstack([np.asarray(laser, float).reshape(-1, 3), np.asarray(spots, float)])
    if line_direction(pts) is None or unseen_axis(pts) is not None:
        return None
    return ("the wall spots lie on a line along neither x nor z: the rotation about it is "
            "unobservable and the model fit (which holds z for spots along x, x for spots "
            "along z) cannot hold it; reporting the paper's argmax on the search region's "
            "plane")


def _paths(point, spots, lasers) -> np.ndarray:
    point = np.asarray(point, dtype=np.float64)
    return np.linalg.norm(point - lasers, axis=-1) + np.linalg.norm(point - spots, axis=-1)


def checked(located: list, paper_position: np.ndarray, spots, lasers) -> list:
    """The targets, with a doubtful single fit replaced by the paper's argmax (warned)."""
    spots = np.asarray(spots, dtype=np.float64)
    lasers = np.broadcast_to(np.asarray(lasers, dtype=np.float64), spots.shape)
    argmax = paper_position if len(located) == 1 else None
    reasons = [doubt(t, argmax, spots, lasers) for t in located]
    if len(located) == 1 and reasons[0]:
        message = (f"model fit rejected: {reasons[0]}; reporting the paper's argmax instead "
                   "(its position is the target's nearest surface, not its centre)")
        warn(message)
        rejected = located[0].fit
        return [LocatedTarget(np.array(paper_position, dtype=np.float64), details={
            "model": "paper's argmax (model fit rejected)", "fallback": reasons[0],
            "rejected_fit": rejected.as_dict(), "warnings": [message]})]
    for k, (target, reason) in enumerate(zip(located, reasons)):
        reason = reason or misfit(target)
        if reason:
            warn(f"model fit, target {k + 1} of {len(located)}: {reason}; it is reported, but "
                 "doubtful")
    return located
