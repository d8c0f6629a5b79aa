"""Which measurement belongs to which track: screening, then gated assignment.

Screening (per frame, before any track is looked at):
- a measurement whose position sd exceeds `max_sigma_m` along some measured axis says nothing
  useful about where a target is (a spare plate fitted to noise reports sd of metres): dropped;
  so is one with no measured axis at all (a plate held at amplitude 0: every variance infinite);
- a measurement from a fit that does not explain the frame (the model estimator's Birge ratio,
  residual variance / the noise's, above `max_birge_ratio`: a wrong local minimum, or a scene
  beyond the model) is dropped; estimators that report no Birge ratio are not screened;
- two measurements each inside the other's gate are one target fitted twice (two plates
  on the same spot, which a two-target fit does when the targets are close or in a degenerate
  minimum): merged into one, with the information-weighted mean and the mean covariance (the
  same data, so no more information than one of them). While two or more tracks are alive a
  merged pair is not used at all: a fit asked for two targets that puts both on one spot could
  not separate them, and the spot is then often neither (two plates midway between two targets
  0.5 m apart explain 8 spots' data as well as the truth does); with one track it is that
  track's target, fitted twice.

One object, one track: plate fits that touch (model.policy.criteria.object_labels: neither
apart nor SURFACES_APART_M behind one another) are one object's faces or light, e.g. a person
fitted as a thin plate on his front and a wide one on the broad late light of his body
(scenario clutter draw 80). Where one of them is paired with a track, or none is and they are
free, the object's other plates start no track of their own: they ride with the paired or the
brightest plate as its track's extra plates (`objects`), which its warm fits carry. The
tracker groups so only while it counts its targets ('auto') and no live track missed.

Assignment: squared Mahalanobis distance of each measurement to each track's predicted
position, chi-square gate at `gate_probability`, SciPy's linear_sum_assignment. Where two or
more tracks share their gated measurements and there are fewer measurements than tracks (one
blob for two targets at a crossing), the measurements cannot be told apart: none of those
tracks is updated (they coast on their velocity) and the measurements start no track.
"""
from __future__ import annotations

import numpy as np

from ..core.stats import unique_sorted
from . import depth, kalman

BIG = 1e12


def screen(measurements, *, max_sigma_m, max_birge_ratio, gate_probability) -> list:
    """The measurements worth pairing (see the module docstring)."""
    kept = []
    for m in measurements:
        fit = getattr(m.source, "fit", None)  # a model fit's typed result, or None
        birge = None if fit is None else fit.birge_ratio
        if max_birge_ratio is not None and birge is not None and birge > max_birge_ratio:
            continue
        if not len(m.axes):  # every variance infinite (a plate the data want none of)
            continue
        if max_sigma_m is not None and len(m.axes) and \
                np.linalg.eigvalsh(m.R).max() > max_sigma_m ** 2:
            continue
        kept.append(m)
    return _merge(kept, gate_probability)


def _merge(measurements, gate_probability):
    out = list(measurements)
    i = 0
    while i < len(out):
        for j in range(i + 1, len(out)):
            a, b = out[i], out[j]
            if list(a.axes) != list(b.axes) or not len(a.axes):
                continue
            d = a.z - b.z  # each inside the other's own gate (a vague one is no duplicate)
            d2 = max(d @ np.linalg.solve(a.R, d), d @ np.linalg.solve(b.R, d))
            if d2 <= kalman.gate_threshold(gate_probability, len(a.axes)):
                out[i] = _mean(a, b)
                del out[j]
                break
        else:
            i += 1
    return out


def _mean(a, b):
    Ia, Ib = np.linalg.inv(a.R), np.linalg.inv(b.R)
    z = np.linalg.solve(Ia + Ib, Ia @ a.z + Ib @ b.z)
    position = a.position.copy()
    position[a.axes] = z
    return kalman.Measurement(a.axes, z, 0.5 * (a.R + b.R), position, a.source, merged=True)


def associate(tracks, measurements, gate_probability, wall=None):
    """(track, measurement) pairs, and the measurements free to start tracks; a pair's
    measurement is its track's centre (tracking.depth.centred: wall, the wall spots' centroid)."""
    if len(tracks) >= 2:  # a merged pair cannot tell which target it is (see the docstring)
        measurements = [m for m in measurements if not m.merged]
    if not tracks or not measurements:
        return [], list(measurements)
    from scipy.optimize import linear_sum_assignment
    cost = np.full((len(tracks), len(measurements)), BIG)
    # each track sees a plate as its centre (tracking.depth: a closed object's behind it)
    seen = [[depth.centred(tr, m, wall) for m in measurements] for tr in tracks]
    for i, tr in enumerate(tracks):
        for j, m in enumerate(seen[i]):
            d2 = kalman.gate_distance2(tr.state, tr.covariance, tr.predicted_modes, m)
            if d2 <= kalman.gate_threshold(gate_probability, len(m.axes)):
                cost[i, j] = d2
    empty = np.array([], int)
    blocked = _unresolved(cost < BIG) if len(tracks) >= 2 else (empty, empty)
    cost[blocked[0], :] = BIG
    rows, cols = linear_sum_assignment(cost)
    pairs = [(tracks[i], seen[i][j]) for i, j in zip(rows, cols) if cost[i, j] < BIG]
    used = {id(measurements[j]) for i, j in zip(rows, cols) if cost[i, j] < BIG} | \
        {id(measurements[j]) for j in blocked[1]}
    return pairs, [m for m in measurements if id(m) not in used]


def objects(pairs, free, carried=(), screened=()) -> tuple[list, dict]:
    """(the free measurements less the other plates of an object whose head is paired or
    free, {id(head measurement): [the object's other plate rows]}): see the module docstring.
    Where two paired plates touch (two tracks' targets side by side) nothing changes.
    carried: the tracks whose extra plates this frame's fit counted (a fit of as many targets
    as the tracks' plates, warm or cold, not 'auto'); a plate of it that no track took is one
    of those extras moved off (no new target: births come from 'auto' fits), and rides with
    the nearest of them; so does a plate of it screened out (`screened`: a vague one still
    holds light the next fit must explain)."""
    from ..localization.model.policy.criteria import object_labels
    paired_ids = {id(m) for _, m in pairs}
    members = [m for m in [m for _, m in pairs] + list(free) if plate_row(m) is not None]
    groups: dict = {}
    for m, g in zip(members, object_labels([plate_row(m) for m in members])):
        groups.setdefault(g, []).append(m)
    riders, extras = set(), {}
    for group in groups.values():
        heads = [m for m in group if id(m) in paired_ids]
        if len(group) < 2 or len(heads) > 1:
            continue
        head = heads[0] if heads else max(group, key=brightness)
        others = [m for m in group if m is not head]
        extras[id(head)] = [plate_row(m) for m in others]
        riders |= {id(m) for m in others}
    carriers = {id(tr) for tr in carried}
    heads = [(tr, m) for tr, m in pairs if id(tr) in carriers]
    for m in list(free) + list(screened):
        if id(m) not in riders and heads and plate_row(m) is not None:
            _, head = min(heads, key=lambda h: np.linalg.norm(h[1].position - m.position))
            extras.setdefault(id(head), []).append(plate_row(m))
            riders.add(id(m))
    return [m for m in free if id(m) not in riders], extras


def same_object(a, b) -> bool:
    """Are measurements a and b plate fits of one object (they touch)?"""
    from ..localization.model.policy.criteria import object_labels
    rows = [plate_row(a), plate_row(b)]
    return rows[0] is not None and rows[1] is not None and len(set(object_labels(rows))) == 1


def count_objects(measurements) -> int:
    """How many objects the measurements are (touching plate fits count once)."""
    from ..localization.model.policy.criteria import object_labels
    rows = [plate_row(m) for m in measurements]
    plates = [r for r in rows if r is not None]
    return len(rows) - len(plates) + (len(set(object_labels(plates))) if plates else 0)


def plate_row(m):
    """The plate row (x, y, z, width, height, yaw) of a measurement's model fit (a closed
    shape's without its depth), or None (no fit, a merged pair)."""
    fit = getattr(m.source, "fit", None)
    if m.merged or fit is None:
        return None
    values = fit.values()
    if fit.shape == "plate":
        return values[:6]
    return values[[0, 1, 2, 3, 4, 6]] if len(values) == 7 else None  # x y z w h depth yaw


def brightness(m) -> float:
    """A plate fit's amplitude x area: the light it returns, up to its distance's factor."""
    fit = m.source.fit
    return float(fit.amplitude) * float(fit.values()[3]) * float(fit.values()[4])


def _unresolved(gated):
    """(track rows, measurement columns) of the gate graph's connected groups that hold two
    or more tracks but fewer measurements than tracks."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components
    n_t, n_m = gated.shape
    adjacency = np.zeros((n_t + n_m, n_t + n_m), bool)
    adjacency[:n_t, n_t:] = gated
    _, label = connected_components(csr_matrix(adjacency), directed=False)
    rows, cols = [], []
    for group in unique_sorted(label):
        t = np.flatnonzero(label[:n_t] == group)
        m = np.flatnonzero(label[n_t:] == group)
        if len(t) >= 2 and len(m) < len(t):
            rows += list(t)
            cols += list(m)
    return np.array(rows, int), np.array(cols, int)
