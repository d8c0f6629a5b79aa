"""How many targets `locate_capture` reports when the caller gives no number (the default):
one, and more where the data hold separate objects (`one_or_more`).

The one-target fit runs first (its cost, and its answer on every capture of one target). It
sees a window around its target's return (model.forward.data: down to 3 % of each row's
peak, 6 noise sds), so a farther target, 1/r^4 fainter, is often outside it: scenario draws
9, 41, 63 held a lit target 2-3 m behind the found one whose return the fit never saw, and
nothing was said. So the rows beyond what the found target can return (its farthest path,
plus the window's margin) are tested too (`beyond`: the detection's test, localization.
detection, at its false-alarm rate); where they hold a return, that is warned in the words
of the fit's own residual test (model.policy.sanity.leftover_note, LEFTOVER).

Where either test fires, the frame is fitted again with the model selection's 'auto' (a plate
more only where the BIC says the data hold it, up to 3), on a window that reaches the return
found beyond (`reaching`), and that answer is reported where its plates are separate
objects (`apart`: each farther from every other than their half-diagonals plus 0.2 m, or
their surfaces more than 0.5 m apart: an occluder in front of the target it half hides).
Where some of 'auto's plates touch (a closed target's faces) and others lie apart from them,
the one-target answer is kept for the object it found and the plates apart from that object
are added (`added`): draw 89's person took two touching plates and its far box a third. Plates
that all touch may be one object's faces or light the model does not describe (a background,
a tail): the first answer then stands, with the warning.
"""
from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np

# how the fit's residual test's warning begins (localization.estimate)
from .estimate import LEFTOVER

BEYOND_NOTE = (f"{LEFTOVER} (the detection's test on the rows beyond the paths the found "
               "target(s) can return from): a farther target, or light the model does not "
               "describe (a tail or background)")
MARGIN_M = 0.35  # past a target's farthest path, as the fit's window (data.gaussian_observation)
PEAK_Z = 3.0  # a row's peak beyond, in its noise sds, that says where the return is


def one_or_more(est, located):
    """The default answer for one laser point: `located(estimator)` with `est` (the one-target
    model fit, probed beyond its window: `probing`), then `more_if_separate`. Other
    estimators (the paper's, for paired captures) as they are."""
    probe = probing(est)
    point = located(probe)
    reach = getattr(probe, "reach_m", None)
    return more_if_separate(point, lambda k: located(reaching(k, reach)))


def more_if_separate(point, relocate):
    """`point` (a PointLocation of one target), or the 'auto' answer `relocate('auto')` gives
    where the residual held a return and 'auto' found separate objects (module docstring);
    `relocate(targets)` locates the same laser point with the model estimator fitting
    `targets`."""
    if point.internal.estimator != "model" or not any(
            str(w).startswith(LEFTOVER) for w in point.warnings):
        return point
    again = relocate("auto")
    fits = [getattr(t, "fit", None) for t in again.internal.targets]
    if len(fits) < 2 or any(f is None for f in fits):
        return point
    params = np.array([_front(f) for f in fits])
    if apart(params):
        return again
    return added(point, again, params)


def _front(fit) -> np.ndarray:
    """A fitted target's returning surface as a plate row: the plate, or a closed shape's front
    face (several closed targets: model.policy.closed_many)."""
    if fit.shape == "plate":
        return fit.values()
    from .model.shapes import box
    return box.front_of(fit.values())


def apart(params) -> bool:
    """Do the plates (rows x, y, z, width, height, yaw) lie apart: every two farther from each
    other than their half-diagonals plus criteria.APART_GAP_M (criteria.separate), or their
    surfaces' nearest points farther apart than criteria.SURFACES_APART_M (an occluder 0.8 m
    in front of the target it half hides: scenario draw 95)? Two faces of one box, or a plate
    and a delayed background's plate close behind it, still touch."""
    from .model.policy.criteria import objects
    return objects(params) == len(params)


def added(point, again, params):
    """`point` with those of `again`'s plates (`params`, in its targets' order) that are apart
    from every plate touching the one-target answer's object, or `point` where none is: the
    object found keeps its one-target fit (a closed shape where it is one), the others come
    from 'auto'. Each added target's fit is of all plates jointly."""
    from .model.policy.criteria import object_labels
    first = np.asarray(point.internal.targets[0].position, float)
    labels = object_labels(params)
    seen = {labels[int(np.argmin(np.linalg.norm(params[:, :3] - first, axis=1)))]}
    keep = []
    for j, label in enumerate(labels):  # one plate an object, the first in 'auto's order
        if label not in seen:
            seen.add(label)
            keep.append(j)
    if not keep:
        return point
    targets = list(point.internal.targets) + [again.internal.targets[j] for j in keep]
    return replace(point, internal=replace(point.internal, targets=targets))


def probing(est):
    """`est` where it is the default one-target model fit, as one that also tests the rows
    beyond its window (`beyond`), keeping the reach it found (`reach_m`); else `est`."""
    model, probe, _ = _estimators()
    if type(est) is not model or est.targets != 1:
        return est
    return probe()


def reaching(targets, reach_m):
    """The model fit of `targets`, on a window widened to `reach_m` past its own where the
    rows beyond held a return (`beyond`), else the plain one."""
    model, _, wide = _estimators()
    est = model(targets=targets) if not reach_m else wide(reach_m, targets=targets)
    # its one-target answers are dropped (more_if_separate keeps separate objects only), so
    # the glossy lobe's search (model.policy.lobe) on them was lost time: a 64-spot glossy
    # patch's second pass spent as long on it as the first
    est.lobe_search = False
    return est


def beyond(scored, obs, targets, false_alarm: float | None = None) -> float | None:
    """Does each row hold a return beyond the farthest path the found `targets` (with their
    fitted extents) or the fit's window `obs` reach, plus MARGIN_M and the filtered pulse?
    The detection's test (localization.detection.detect) on those bins of the filtered rows;
    a Gaussian observation only (counts are left to the fit's own test). Returns how far
    past the window the fit must reach to see that return (m), or None."""
    from .detection import FALSE_ALARM, detect
    if obs.mode != "gauss":
        return None
    rows = scored.host_rows if scored.host_rows is not None else scored.signals.values()
    axis = scored.signals.layout.path_axis()
    end = obs.path0 + obs.dpath * (obs.n - 1)
    far = end.copy()
    for t in targets:
        far = np.maximum(far, _farthest(t, obs.laser, obs.spots))
    first = np.ceil((far + MARGIN_M + 3 * obs.sigma0_m - axis.centre0_m) / axis.step_m)
    first = first.astype(np.int64)
    live = first < axis.n_bins - 1
    if live.sum() == 0:
        return None
    window = np.stack([first[live], np.full(int(live.sum()), axis.n_bins - 1)], axis=1)
    found = detect(np.asarray(rows)[live], window, FALSE_ALARM if false_alarm is None
                   else false_alarm)
    if not found.detected:
        return None
    z = np.asarray(found.peak_z, float)
    peaks = np.array([first[d] + int(np.argmax(np.asarray(rows[d])[first[d]:]))
                      for d in np.flatnonzero(live)])
    past = axis.centre0_m[live] + axis.step_m[live] * peaks - end[live]
    # where the return is: the rows whose peak stands out (a row of noise peaks anywhere)
    strong = past[z >= PEAK_Z] if len(z) == len(past) and (z >= PEAK_Z).any() else past
    return float(np.max(strong)) + MARGIN_M


def _farthest(target, laser, spots) -> np.ndarray:
    """(D,) the longest hidden path to any corner of the target's fitted box (its position
    where it has no extent)."""
    from .shadow import box_of
    box = box_of(target) if getattr(target, "fit", None) is not None else None
    centre = np.asarray(target.position, float)
    corners = centre[None]
    if box is not None:
        c, axes, half = box[0], box[1], 0.5 * np.asarray(target.extent_m, float)
        signs = np.array([[a, b, e] for a in (-1, 1) for b in (-1, 1) for e in (-1, 1)])
        corners = c + (signs * half) @ axes
    return (np.linalg.norm(corners[None] - np.asarray(laser, float).reshape(1, 1, 3), axis=2)
            + np.linalg.norm(corners[None] - np.asarray(spots, float)[:, None], axis=2)
            ).max(axis=1)


@functools.cache
def _estimators():
    """(ModelEstimator, the probing one-target fit, the widened fit): defined on first use
    (model.estimator imports this module's LEFTOVER)."""
    from ..core.errors import warn
    from .model import ModelEstimator
    from .model.forward import data

    class Probing(ModelEstimator):
        """The default one-target fit, which also tests the rows beyond its window."""

        reach_m = None

        def observation(self, scored):
            self._obs = super().observation(scored)
            return self._obs

        def estimate(self, scored, prior=None, *, start=None):
            out = super().estimate(scored, prior, start=start)
            obs = getattr(self, "_obs", None)
            fitted = [t for t in out.targets if getattr(t, "fit", None) is not None]
            self.reach_m = None if obs is None or not fitted else beyond(scored, obs, fitted)
            if self.reach_m is not None:
                warn(BEYOND_NOTE)
            return out

    class Reaching(ModelEstimator):
        """The model fit on a window widened by `reach_m` at either end (the data's margin).
        Widened at the far end only (tried), the refit cost 1.1-3.3x less CPU on the
        8 scenario draws where `beyond` fires, but answered worse on 5: 111 passed and failed
        (its shadowed plate lost), 103's person 0.38 -> 5.9 m (a sliver 0.1 m from the wall,
        4.4 m up), 89's far box lost, 63 and 105's far targets 1.1 -> 1.8 and 0.6 -> 2.5 m;
        better on one (23); so it is centred."""

        def __init__(self, reach_m, **options):
            super().__init__(**options)
            self.reach_m = float(reach_m)

        def observation(self, scored):
            obs = super().observation(scored)
            if obs.mode != "gauss":
                return obs
            layout = scored.signals.layout
            filtered = scored.host_rows if scored.host_rows is not None else \
                scored.signals.values()
            raw = None if scored.raw is None else scored.raw.values()
            scale = 1.0 if raw is None else scored.raw.scale_w / scored.signals.scale_w
            return data.gaussian_observation(
                layout, filtered, raw, h_s=self.window_s(scored), pulse_sigma_s=self.pulse_sigma_s,
                margin_m=MARGIN_M + self.reach_m, frac=data.window_frac(self.targets),
                raw_scale=scale)

    return ModelEstimator, Probing, Reaching
