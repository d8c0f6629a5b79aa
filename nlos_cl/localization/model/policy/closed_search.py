"""The closed shapes' search for one target (box, ellipsoid, cylinder, capsule), pooled in
three stages:

1. each family's best starts, by one forward call each (the plate's lattice of depths, yaws
   and widths, and sizes at the centroid start: `box_rows`), POOL_PLATE_STARTS from around
   the plate and POOL_CENTRE_STARTS from the centroid, each fitted SHORT_NFEV evaluations;
2. each family still in the race (PRUNE_RATIO) fitted short again from what the best fit of any family found (its front face
   at CROSS_DEPTHS) and from rounder sections of its own and that best fit (`round_rows`),
   the best STAGE2_KEEP of those starts fitted SHORT_NFEV evaluations;
3. one fit to convergence per family in the race, from its cheapest short fit; the best
   family's once more from its rounder sections and deeper fronts (`_polished`).

Why: the cascade it replaces fitted every start group, cross-seeded start and rounder start of
every family to convergence (~11 long fits of up to 90 evaluations, ~22 short ones, per
target): 43 of a counts draw's 50 s. The long fits are what cost; a short fit already tells
the basins apart (measured on the draws: docs/model-estimator.md, "The closed shapes' search").
"""
from __future__ import annotations

import numpy as np

from ..shapes import box, plate
from ..shapes.shape import CLOSED_SHAPES
from ..solve.fit import fit
from ..solve.lockstep import fit_together
from ..solve.records import ShapeFit
from . import starts

BOX_DEPTHS = (0.1, 0.3, 0.6)  # m: starts behind the fitted plate's face
BOX_YAWS = np.radians([-35.0, 0.0, 35.0])  # a box seen corner-on: the plate's yaw is between
BOX_WIDTHS = (1.0, 0.6)  # times the plate's width (the plate spans both visible faces)
CENTRE_SIZES = ((0.3, 0.3, 0.3), (0.6, 0.6, 0.6), (0.4, 1.7, 0.3))  # (w, h, d) m, at centres
# The closed fits get this many times final_nfev: from starts 0.3 m off, a cylinder on a
# capsule still lowered its cost 40-fold between 30 and 90 evaluations.
CLOSED_NFEV = 3
SHORT_NFEV = 6  # as select.best_of's short fits
POOL_PLATE_STARTS = 2  # a family's starts from around the plate ...
POOL_CENTRE_STARTS = 1  # ... and from the centroid start (a sphere the plate missed by 0.5 m)
STAGE2_KEEP = 2
# A family whose best short fit costs more than this many times the best family's goes no
# further (its short fit is its answer, never the chosen one): on high-SNR data a wrong family
# stays tens to thousands of times costlier (a sphere: box 20,799, cylinder 19,635,
# ellipsoid 170); where noise dominates every cost, all stay in.
PRUNE_RATIO = 3.0
CROSS_DEPTHS = (0.3, 0.6)  # m behind the best closed fit's front face
# The best fit's own depth as a start, at least this: a box of depth 0 is the plate, whose
# starts every family has already had (the ellipsoid's lower bound is 0.04 m)
MIN_CROSS_DEPTH_M = 0.05


def box_rows(q, centres=(), laser=None) -> np.ndarray:
    """Closed-shape starts around a fitted plate q (depths behind its face, yaws, narrower
    widths; none if q is None) and, facing the laser spot, at each of `centres`."""
    rows = []
    for behind in BOX_DEPTHS if q is not None else ():
        for dyaw in BOX_YAWS:
            for scale in BOX_WIDTHS:
                p = np.array(q, float)
                p[plate.WIDTH], p[plate.YAW] = p[plate.WIDTH] * scale, p[plate.YAW] + dyaw
                rows.append(box.from_plate(p, behind))
    for c in centres:
        for w, h, behind in CENTRE_SIZES:
            rows.append(box.from_plate([*c[:3], w, h, plate.facing(c, laser)], behind))
    return np.array(rows).reshape(-1, box.N_PARAMS)


def round_rows(p, shape) -> list:
    """Starts with closed fit p's front face and the rounder sections the shape asks for
    (`rounder_sizes`: none for the box; across and along the normal sqrt(w d) for the curved
    ones, and for the ellipsoid also all three axes cbrt(w h d)). Round targets stall in
    elongated minima: a 0.79 m cylinder seen by a 30-spot SPAD patch was fitted 1.17 x 0.58 m
    across (Birge ratio 8.3, centre 0.15 m off) and a 0.92 m sphere as a 1.07 x 1.04 x 0.75 m
    ellipsoid (Birge 34, 0.08 m off); from rounder starts the fits reach 5 and 3 mm."""
    p = np.asarray(p, float)
    sizes = shape.rounder_sizes(*(float(v) for v in p[box.WIDTH:box.DEPTH + 1]))
    front = box.front_of(p)
    return [box.from_plate([*front[:3], across, up, front[plate.YAW]], along)
            for across, up, along in sizes]


def cross_rows(best) -> list:
    """The best closed fit's front face at its own depth and at CROSS_DEPTHS: where the plate
    had gone wide to absorb a side, every start around it missed the box, while the ellipsoid
    had found the front face (one draw's box: cost 274,405 from the plate's starts, 2,708
    from the ellipsoid's front with the right depth)."""
    front = box.front_of(best)
    depths = (max(float(best[box.DEPTH]), MIN_CROSS_DEPTH_M), *CROSS_DEPTHS)
    return [box.from_plate(front, d) for d in depths]


def search(problem, plate_result, free, final_nfev, atol=None) -> list[ShapeFit]:
    """Each closed family (CLOSED_SHAPES) fitted to the data of plate problem `problem`
    from the pooled stages above: [ShapeFit per family], in CLOSED_SHAPES' order. The plate's
    problem counts every forward call made for it (the caller's take_calls)."""
    from ..forward.host_shapes import shape_problem
    problems = [shape_problem(problem, shape) for shape in CLOSED_SHAPES]
    free_closed = closed_free(free)
    q = plate_result.params[0]
    centres = starts.start_centres(problem.obs, None, plate.Held.of(free, q))
    around, at_centres = box_rows(q), box_rows(None, centres, problem.obs.laser)
    first = [_short(p, starts.best_starts(p, around, keep=POOL_PLATE_STARTS)
                    + starts.best_starts(p, at_centres, keep=POOL_CENTRE_STARTS), free_closed)
             for p in problems]
    lowest = min((r for rs in first for r in rs), key=lambda r: r.cost)
    best, out = lowest.params[0], []
    for closed, shorts in zip(problems, first):
        own = min(shorts, key=lambda r: r.cost)
        if own.cost > PRUNE_RATIO * lowest.cost:  # out of the race: its short fit stands
            out.append(ShapeFit(closed, own, free_closed))
            continue
        rows = cross_rows(best) + round_rows(own.params[0], closed.shape) + (
            [] if np.array_equal(best, own.params[0]) else round_rows(best, closed.shape))
        more = _short(closed, starts.best_starts(closed, np.array(rows), keep=STAGE2_KEEP),
                      free_closed)
        start = min([own, *more], key=lambda r: (not _plausible(r), r.cost))
        result = fit(closed, start.params, free_closed, CLOSED_NFEV * final_nfev, atol=atol)
        out.append(ShapeFit(closed, result, free_closed))
    return _polished(out, final_nfev, atol)


def _polished(fits, final_nfev, atol) -> list[ShapeFit]:
    """The best family's fit again to convergence from its rounder sections and its front at
    CROSS_DEPTHS (the best of those starts by one call), kept where it costs less: a closed
    object's far side is seen faintly, and the cost along its depth is flat, so where the fit
    stops in that valley depends on where it came from (a sphere's ellipsoid: the same cost
    within 0.4, its centre 0.004 or 0.08 m off)."""
    k = min(range(len(fits)), key=lambda i: fits[i].result.cost)
    closed, result, free_closed = fits[k]
    p = result.params[0]
    rows = round_rows(p, closed.shape) + cross_rows(p)[1:]
    start = starts.best_starts(closed, np.array(rows), keep=1)[0]
    again = fit(closed, start[None], free_closed, CLOSED_NFEV * final_nfev, atol=atol)
    if again.cost < result.cost:
        fits[k] = ShapeFit(closed, again, free_closed)
    return fits


def closed_free(free) -> np.ndarray:
    """A plate's free mask (6,) as the closed shapes' (7,): the depth free too."""
    return np.insert(np.asarray(free, bool), box.DEPTH, True)


def _short(problem, rows, free) -> list:
    return fit_together(problem, [np.asarray(r, float)[None] for r in rows], free, SHORT_NFEV)


def _plausible(result) -> bool:
    return starts.plausible(result.linear, len(result.params))
