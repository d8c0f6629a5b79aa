"""Can these spots see how deep a target is? A probe of the fitted plate against boxes behind it.

A plate that explains the data is the visible surface of whatever is there: a plate, or the
front of a closed object whose sides the spots see too faintly to tell. Two questions, each
answered with a few forward calls and no fit:

- Would a box behind the plate explain the data better? Boxes of depth PROBE_DEPTHS x the
  plate's width, same front face, amplitude refitted (a 0.30 m deep box behind a 0.77 m wide
  front beat its plate by 12 kappa at 0.25 x the width, and lost to it at 0.5 and 1 x, where
  the plate's other parameters, held, no longer match): if one costs less than the plate, the
  closed shapes are worth fitting even though the plate passed the misfit test (that test has
  little power against this one alternative: a box seen mostly face-on left a plate at Birge
  ratio 1.7 under a limit of 1.9, where the box's BIC gain was 21).
- Could the data tell the plate from such a box at all? The box's amplitude-refitted distance
  from the plate's own fitted mean, in noise units (chi^2 / kappa, as the BIC's), gives the
  depth's sd to first order: sd = d / sqrt(dchi2). Above DEPTH_SD_LIMIT_M the centre along the
  normal is not determined by these spots, and the answer says so (`DEPTH_WARNING`).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..shapes import box, plate

PROBE_DEPTHS = (0.25, 0.5, 1.0)  # times the plate's width: a box's depth is of the order of its width
MIN_PROBE_M = 0.1
DEPTH_SD_LIMIT_M = 0.2  # the centre's sd along the normal is half of it: the goal's 0.10 m
DEPTH_WARNING = ("the spots see only the front of target {k}: if it is a closed object, its "
                 "centre lies behind the found surface by half its depth, which these spots "
                 "cannot measure (depth sd {sd}); spots farther apart see its sides")


def probe(problem, plate_result, kappa: float) -> dict:
    """{box_better: a box behind the plate costs less on the data (by more than kappa, one
    unit of chi^2 in the BIC's units: noise alone puts a faint side's box below the plate half
    the time), depth_sd_m: the depth's sd predicted at a box as deep as the plate is wide,
    depth_probe_m: that depth}. The sd holds the plate's other parameters fixed, so it is a
    lower bound: a plate's position and yaw can absorb part of a side's signal."""
    from ..forward.host_shapes import shape_problem
    from ..forward.likelihood import Problem
    q = np.asarray(plate_result.params[0], float)
    width = max(float(q[plate.WIDTH]), MIN_PROBE_M)
    # Which faces a box behind the plate shows does not depend on its depth; where it shows
    # only its front, its histograms are the plate's: nothing to evaluate
    faces = _visible(box.from_plate(q, width), problem.obs)
    if len(faces) == 1:
        return {"box_better": False, "depth_sd_m": math.inf, "depth_probe_m": width,
                "probe_box_cost": plate_result.cost}
    boxes = shape_problem(problem, box)
    on_host = problem.plates_on_host and all(abs(f[3][2]) < 1e-12 for f in faces)
    # the plate and the boxes through one model (host plates, or the device's box model, whose
    # depth-0 box is the plate): the comparison must not carry the two models' difference
    depths = [0.0] + [share * width for share in PROBE_DEPTHS]
    by_depth = _face_plates(problem, q, depths) if on_host else \
        [boxes.columns(box.from_plate(q, d)[None]) for d in depths]  # host: one call for all
    plate_cols = by_depth[0]
    plate_lin = problem.linear(plate_cols)
    r = problem.residual(plate_cols, plate_lin)
    plate_cost = float(r @ r)
    as_data = Problem(replace(problem.obs, y=problem.mean(plate_cols, plate_lin)),
                      problem.backend, problem.lattice)
    best, dchi2 = math.inf, 0.0
    for cols in by_depth[1:]:
        r = problem.residual(cols, problem.linear(cols))
        best = min(best, float(r @ r))
        r = as_data.residual(cols, as_data.linear(cols))
        dchi2 = float(r @ r) / kappa  # the last probe: the deepest, depth = width
    sd = width / math.sqrt(dchi2) if dchi2 > 0 else math.inf
    problem.calls += boxes.calls
    return {"box_better": best < plate_cost - kappa, "depth_sd_m": sd, "depth_probe_m": width,
            "probe_box_cost": best}


def depth_sds(problem, result, kappa: float) -> list:
    """Per plate of a fit of K >= 2 plates, the depth's sd these spots predict, as `probe`'s
    (a box as deep as the plate is wide against the plate, amplitudes refitted), the other
    plates' columns held at the fit's; inf where such a box shows only its front. Read by the
    answer's notes (DEPTH_WARNING): a person among several targets fitted as a plate on its
    front (scenario draws 15, 57: 0.16-0.25 m from its centre) was reported with no notice."""
    from ..forward.host_shapes import shape_problem
    from ..forward.likelihood import Problem
    params = np.asarray(result.params, float)
    cols = problem.columns(params)
    lin = problem.linear(cols)
    as_data = Problem(replace(problem.obs, y=problem.mean(cols, lin)), problem.backend,
                      problem.lattice)
    out, boxes = [], None
    for k, q in enumerate(params):
        width = max(float(q[plate.WIDTH]), MIN_PROBE_M)
        faces = _visible(box.from_plate(q, width), problem.obs)
        if len(faces) == 1:
            out.append(math.inf)
            continue
        moved = np.array(cols, float)
        if problem.plates_on_host and all(abs(f[3][2]) < 1e-12 for f in faces):
            front, deep = _face_plates(problem, q, [0.0, width])
            moved[k] += deep[0] - front[0]  # its sides, beside its (shadowed) front
        else:
            boxes = boxes or shape_problem(problem, box)
            moved[k] = boxes.columns(box.from_plate(q, width)[None])[0]
        r = as_data.residual(moved, as_data.linear(moved))
        dchi2 = float(r @ r) / kappa
        out.append(width / math.sqrt(dchi2) if dchi2 > 0 else math.inf)
    return out


def _visible(p, obs) -> list:
    """Box p's faces (centre, u, v, normal) that the laser spot lights and a wall spot sees."""
    return [f for f, ok in zip(box.faces(p), box.shown(p, obs.spots, obs.laser)) if ok]


def _face_plates(problem, q, depths) -> list:
    """Per depth, (1, D, n): the box of that depth behind plate q, its visible faces (all
    upright) as plates on the host, summed; every depth's faces in one call: the front is q
    itself (remembered from its fit), each side a plate across the depth (the device's
    forward op per face cost ~8 ms of a 50 ms paper-scene locate; one host call per depth
    ~0.7 ms each). The same box as box.model_facets up to the lattice across the depth
    (tests/localization/model/test_model_depth.py)."""
    rows, owner, front = [q], [-1], plate.normal_of(q)  # owner: the depth a row is a side of
    for k, depth in enumerate(depths):
        if depth > 0:
            sides = [[*c, np.linalg.norm(u), np.linalg.norm(v), math.atan2(n[1], n[0])]
                     for c, u, v, n in _visible(box.from_plate(q, depth), problem.obs)
                     if not np.allclose(n, front)]
            rows += sides
            owner += [k] * len(sides)
    cols, owner = problem.column_batch(np.array(rows, float)), np.array(owner)
    return [(cols[0] + cols[owner == k].sum(axis=0))[None] for k in range(len(depths))]


# A plate whose misfit rules the closed shapes out (policy.closed.beyond_closed): not tried.
SKIPPED_WARNING = ("the depth of target {k} was not found: the plate leaves {left:.0f} % of the "
                   "signal unexplained (misfit {ratio:.0f}), more than a closed shape may and "
                   "still be reported, so none was fitted; if it is a closed object, its "
                   "centre lies behind the found surface")
CLOSED_WARNING = ("the depth of target {k} is poorly determined (sd {sd:.2f} m): its centre is "
                  "uncertain by half that along its normal")


# A plate kept after the closed shapes were tried: the plate missed the data or the depth
# probe found a box behind it cheaper, and no closed fit did better (they missed it: on
# mitransient renders of closed draws 155 and 192 a box 0.21 and 0.28 m behind, with no notice).
NOT_FOUND_WARNING = ("the depth of target {k} was not found: {why}, but no closed shape fitted "
                     "better; if it is a closed object, its centre lies behind the found "
                     "surface")


def unseen_note(shape, result, cov_all, info, k: int = 0) -> str | None:
    """The answer's notice where these spots cannot tell how deep target k is, else None: a
    plate whose probe predicts a depth sd above DEPTH_SD_LIMIT_M, a plate kept though the
    closed shapes were tried (NOT_FOUND_WARNING), or a closed shape whose fitted depth has
    such an sd (the larger of the Laplace one and the depth profile's)."""
    if not shape.CLOSED:  # the plate: its depth probe and whether closed shapes were tried
        sd = info.get("depth_sd_m")
        if sd is not None and sd > DEPTH_SD_LIMIT_M:
            return DEPTH_WARNING.format(k=k + 1, sd=_metres(sd))
        if info.get("closed_skipped_left") is not None:
            return SKIPPED_WARNING.format(k=k + 1, left=100 * info["closed_skipped_left"],
                                          ratio=info.get("plate_birge_ratio") or 0.0)
        if info.get("closed_tried"):
            why = ("a box behind the plate explained the data better (the depth probe)"
                   if info.get("box_probe_better") else "the plate does not explain the data")
            return NOT_FOUND_WARNING.format(k=k + 1, why=why)
        return None
    n = shape.N_PARAMS
    sd = math.sqrt(max(float(cov_all[k * n + box.DEPTH, k * n + box.DEPTH]), 0.0))
    sd = max(sd, float(info.get("depth_profile_sd_m", 0.0)))  # closed.depth_profile's secants
    return CLOSED_WARNING.format(k=k + 1, sd=sd) if sd > DEPTH_SD_LIMIT_M else None


# A target whose centre's sd exceeds this along some direction (the largest principal sd of
# its 3 x 3 covariance) is reported with UNCERTAIN_WARNING: an error of 1.5 sds is then past
# 0.15 m. A faint far plate among brighter targets trades size for position (scenario draw
# 41: a 0.28 x 0.89 m plate 5 m out fitted 1.42 x 1.43 m, 0.40 m off, sds 0.17 / 0.12 / 0.13
# m, and no word of it).
POSITION_SD_LIMIT_M = 0.1
UNCERTAIN_WARNING = ("the position of target {k} is poorly determined (sd {sd:.2f} m along its "
                     "least certain direction): the data constrain it weakly (a faint or "
                     "partly seen target)")


def several_unseen_note(info, k: int, at: int) -> str | None:
    """DEPTH_WARNING for plate k of a fit of several, reported as target at + 1, where its
    `depth_sds` (info's DEPTH_SDS_KEY) is above DEPTH_SD_LIMIT_M, else None."""
    sds = info.get(DEPTH_SDS_KEY)
    if sds is None or sds[k] <= DEPTH_SD_LIMIT_M:
        return None
    return DEPTH_WARNING.format(k=at + 1, sd=_metres(sds[k]))


DEPTH_SDS_KEY = "depth_sds_m"  # diagnostics: per plate of several, `depth_sds`


def uncertain_note(centre_cov, k: int) -> str | None:
    """UNCERTAIN_WARNING for the k-th reported target (0-based) whose centre covariance
    (3, 3) has a principal sd above POSITION_SD_LIMIT_M, else None. Axes held by the layout
    (infinite variance: their own warning) are left out."""
    c = np.asarray(centre_cov, float)
    seen = np.isfinite(np.diag(c))
    if not seen.any():
        return None
    sd = math.sqrt(max(float(np.linalg.eigvalsh(c[np.ix_(seen, seen)]).max()), 0.0))
    return UNCERTAIN_WARNING.format(k=k + 1, sd=sd) if sd > POSITION_SD_LIMIT_M else None


def _metres(sd: float) -> str:
    if math.isfinite(sd):
        return f"{sd:.2f} m"
    return "unbounded: no side of such a box is lit and seen"
