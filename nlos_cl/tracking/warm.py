"""Warm starts for the model estimator inside the Tracker: the prior provider.

Where each of the K targets the estimator fits is followed by a confirmed track whose last
measurement was a model fit (a plate, or a closed shape: then every row in that family,
`prior`), the next frame's fit starts from those rows moved to the tracks' predicted positions
(a localization.estimate.Prior, `Locator(..., prior=...)`, then
`ModelEstimator.estimate(scored, prior)`, nlos_cl.localization.model.policy.warm): only the final fit
runs, ~30 model evaluations on the host instead of ~150 forward calls. Two fallbacks to the
cold (full) fit: the estimator's own (the warm fit misses the data: Birge ratio above its
99.9 % point), and the tracker's (a warm-fitted position outside every start track's gate: the
fit found another basin, or the track is wrong; either way the frame is fitted from its data
alone too, and the fit with the lower cost is kept: `better`). The estimator keeps no
per-frame state: the prior travels with the call.
"""
from __future__ import annotations

import numpy as np

from ..core.tuning import HIDDEN_SHARE
from ..localization.estimate import Prior, capabilities_of
from . import association, depth, kalman


def can_start(estimator, fixed: bool = False) -> bool:
    """Does the tracker warm-start this estimator? Where it says it can
    (`Capabilities.warm_start`: the model estimator with a fixed number of targets); fixed:
    as it says with a fixed number (a tracker choosing the number per frame fixes it on the
    frames it warm-starts: tracking.births)."""
    targets = getattr(estimator, "targets", None)
    if not fixed or targets != "auto":
        return capabilities_of(estimator).warm_start
    estimator.targets = 1
    try:
        return capabilities_of(estimator).warm_start
    finally:
        estimator.targets = targets


def plate_of(measurement):
    """The fitted row behind a measurement (a plate's 6 parameters, or a closed shape's 7), or
    None (another model, a merged pair, an estimator without a typed fit)."""
    fit = getattr(measurement.source, "fit", None)
    if measurement.merged or fit is None:
        return None
    from ..localization.model.shapes.shape import SHAPES  # (the paper tracker never gets here)
    if fit.shape not in SHAPES:
        return None
    return fit.values()


def keep(track, measurement, extra=()) -> None:
    """The track's warm start from its paired measurement: the fitted row and its shape
    (`model`), where the centre lies from it (tracking.depth), the object's
    other plates (`extra`: rows of touching plates fitted with it, tracking.association), and
    the misfit of the cold fit behind it where one ran this frame (a warm fit's own is not: a
    floor that followed the accepted warm fits would climb frame by frame)."""
    track.plate = plate_of(measurement)
    fit = getattr(measurement.source, "fit", None)
    track.model = fit.shape if track.plate is not None else "plate"
    track.offset = depth.offset(track, measurement)  # the centre behind it (tracking.depth)
    depth.learn(track, measurement)
    track.extra = [np.array(r, float) for r in extra]  # counted in the next fit's targets
    # the ratio the warm fit's misfit test reads: the Birge ratio, or counts' deviance per
    # degree of freedom (ModelFit.birge_ratio is None for counts)
    ratio = (fit.diagnostics or {}).get("misfit_ratio", fit.birge_ratio) \
        if track.plate is not None else None
    if ratio is None:
        return
    warm_start = fit.warm_start
    if warm_start is None or warm_start.reason:  # cold, or the cold fit ran and cost more
        track.misfit = float(ratio)
        track.late = bool(fit.diagnostics.get("late_kept"))


# A size prior's sd relative to the remembered size, beside the remembered sizes' own scatter:
# a rigid target keeps its size; 5 % lets a plate model of a non-rigid one (a person turning)
# follow. It acts only on a plate the others hide by more than tuning.HIDDEN_SHARE at that
# size (model.warm.size_prior). In the fit it weighs less than this sd says: the whitened chi^2
# of correlated filtered samples counts the data's information ~kappa times (kappa ~7.5 at
# three samples a filter sigma), so the prior acts like an sd ~sqrt(kappa) = 2.7x wider.
SIZE_REL_SD = 0.05


def remember(track, measurement, extra=()) -> None:
    """After pairing: the track's warm-start plate, and its size where the fit saw the plate
    whole (ModelFit.hidden_share <= tuning.HIDDEN_SHARE, taken at the remembered size where that is
    larger: a partly hidden plate fits smaller, model.warm.size_prior). A track's first plate
    seeds the memory whatever it hid (a target hidden from its first frame keeps the size it
    was found with, not the one it shrinks to frame by frame from warm starts: crossing draw
    34, 0.056 -> 0.019 m RMS); the first size seen whole replaces the seed."""
    keep(track, measurement, extra)
    if track.plate is None:
        return
    hidden = measurement.source.fit.hidden_share
    size = track.plate[3:5].copy()
    if hidden is not None and hidden <= HIDDEN_SHARE:
        if track.size_seeded:
            track.sizes.clear()
            track.size_seeded = False
        track.sizes.append(size)
    elif not track.sizes:
        track.sizes.append(size)
        track.size_seeded = True


def size_of(track):
    """(size (2,), sd (2,)) the track's remembered plate size, or None (none remembered)."""
    if not track.sizes:
        return None
    sizes = np.array(track.sizes)
    mean = sizes.mean(axis=0)
    return mean, np.sqrt((SIZE_REL_SD * mean) ** 2 + sizes.var(axis=0))


def starters(predictions, targets: int, tentative: bool = False) -> list | None:
    """The predictions of the confirmed tracks with a plate (tentative: and of the tentative
    ones, as a tracker counting its targets warm-starts them: tracking.births), if they hold
    exactly `targets` plates, their extra ones counted (else None: no warm start)."""
    kinds = ("confirmed", "tentative") if tentative else ("confirmed",)
    ready = [p for p in predictions if p.track.status in kinds and p.track.plate is not None]
    return ready if plates(p.track for p in ready) == targets else None


def plates(tracks) -> int:
    """How many plates the tracks' warm fits hold: each track's, and its object's extra ones."""
    return sum(1 + len(getattr(t, "extra", ())) for t in tracks)


def prior(starters) -> Prior:
    """The start tracks' last plates, their centres moved to the predicted positions (z too
    where the track is 3D; a 2D track keeps the plate's own height), and the tracks'
    remembered sizes and their sd (`size_of`; inf: none remembered), which the estimator uses
    for a plate the others partly hide (Prior.size), and the largest of their cold fits'
    misfits (Prior.misfit; None where a track has none), the rows as last fitted (tried where
    the prediction misses: Prior.measured) and whether a cold fit kept late copies."""
    family = next((p.track.model for p in starters if p.track.model != "plate"), None)
    rows, measured, size, size_sd = [], [], [], []
    for p in starters:
        tr, x = p.track, p.x
        row = in_family(tr.plate, tr.model, family)
        measured.append(row.copy())
        shift = np.zeros(3) if tr.offset is None else tr.offset  # centre - plate
        row[:tr.dims] = x[:tr.dims] - shift[:tr.dims]
        rows.append(row)
        known = size_of(tr) or (row[3:5], np.full(2, np.inf))
        size.append(known[0])
        size_sd.append(known[1])
        for extra in tr.extra:  # the object's other plates move with it
            extra = in_family(extra, "plate", family)
            measured.append(extra.copy())
            moved = extra.copy()
            moved[:tr.dims] += row[:tr.dims] - tr.plate[:tr.dims]
            rows.append(moved)
            size.append(extra[3:5])
            size_sd.append(np.full(2, np.inf))
    misfits = [p.track.misfit for p in starters]
    floor = None if None in misfits else max(misfits)
    return Prior(np.array(rows), np.array(size), np.array(size_sd), floor, family,
                 np.array(measured), any(p.track.late for p in starters))


def in_family(row, model, family) -> np.ndarray:
    """A copy of a track's row (of `model`) as a row of `family` (None: plates): a plate
    among closed targets at the family's least depth; closed families share parameters."""
    row = np.array(row, float)
    if family is None or model != "plate":
        return row
    from ..localization.model.shapes import box
    from ..localization.model.shapes.shape import SHAPES
    return box.from_plate(row, float(SHAPES[family].LOWER[box.DEPTH]))


def outside_gates(measurements, predictions, gate_probability, wall=None) -> bool:
    """Is some warm-fitted measurement outside the gate of every start track, and no plate of
    an object whose other plate lies inside one (a track's extra plate)? (Each track sees a
    plate as its centre: tracking.depth.centred, wall the wall spots' centroid.)"""
    def inside(m):
        gate = kalman.gate_threshold(gate_probability, len(m.axes))
        return any(kalman.gate_distance2(p.x, p.P, p.modes, depth.centred(p.track, m, wall))
                   <= gate for p in predictions)
    warm = [m for m in measurements if _warm_fitted(m)]
    held = [m for m in warm if inside(m)]
    held_ids = {id(m) for m in held}
    return any(not any(association.same_object(m, h) for h in held)
               for m in warm if id(m) not in held_ids)


def _warm_fitted(m) -> bool:
    """A warm fit's measurement with a measured axis (a plate held at amplitude 0 says
    nothing of where)."""
    fit = getattr(m.source, "fit", None)
    return fit is not None and fit.warm_start is not None and fit.warm_start.used \
        and bool(len(m.axes))


def better(warm_located, cold_located):
    """Of two fits of one frame, (Location, measurements) each, the one with the lower cost
    (chi^2 of the whole frame, FitResult.cost; the same data and number of plates): a cold fit that lands
    in a worse basin than the warm one does not replace it. A fit without a cost loses."""
    def cost(located):
        fits = [getattr(m.source, "fit", None) for m in located[1]]
        costs = [f.cost for f in fits if f is not None and f.cost is not None]
        return min(costs) if costs else np.inf
    return warm_located if cost(warm_located) < cost(cold_located) else cold_located

