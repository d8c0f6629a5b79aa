"""Mutual shadowing of K >= 2 model plates: plate j's points lose the weight of the rays
(laser spot O -> point, point -> detector spot) that cross another plate i, as the simulator's
occlusion (physics/visibility.py) takes them out of the data.

Each plate is an opaque rectangle of known centre, size and yaw, so the test is analytic: where
the ray P -> T (T = O or a spot) meets plate i's plane, at H = P + t (T - P), the ray is blocked
when 0 < t < 1 and H lies inside the rectangle (|u| < w/2 along its width, |v| < h/2 along
its height). Either side blocks (the simulator's any-hit test is two-sided).

Smooth, for finite-difference Jacobians. A hard 0/1 test at the shadowed plate's points makes
the cost a staircase in the occluder's position (2 mm steps would see it jump or not at all).
Here each of the three conditions is a linear ramp, 0 -> 1 across the edge, that spans one cell
of the *shadowed* plate (its larger cell edge, `cell_m`) on that plate: on the occluder's plane
the ramp is (1 - t) cell_m wide (H moves by (1 - t) dP when the point moves by dP), and the
t-ramp (a point just behind the occluder's plane, where plates cross) is cell_m of distance
along the ray. A ramp as wide as the points' period (2 Gauss points a cell per axis) makes the
shadowed weight a piecewise-linear function of a shadow edge's position with a constant slope
between the lattice's kinks, and a symmetric ramp keeps the shadowed area of a sharp edge
unchanged (no bias). Plate i's blocking is inside_u inside_v inside_t; several occluders
multiply their (1 - blocking).

The cell statistics (pull-in, blur, shift: model.plate.cell_model) stay the unshadowed plate's:
second order, and they keep a Jacobian's frozen statistics valid.

Bounding test (`occluders_of`): plate i can shadow plate j only if (1) plate i's bounding
sphere comes within reach of the capsule from j's bounding sphere to a wall point (O or a
spot), and (2) plate i's rectangle, grown by the ramps' reach, meets the pyramid from j's
rectangle to that wall point, grown by the t-ramp's (a separating-axis test, `_meets_pyramid`):
every ray j's points send to that wall point lies in the pyramid, so an occluder outside it
blocks none. Both tests are widened by MARGIN_M, so that a finite-difference step of either
plate (2 mm, 4 mrad) cannot move a ray into a ramp. Outside them every ramp is exactly 0, so
an occluder left out changes no bit: one target, or targets apart, give the numbers they gave
before shadows were modelled. Test (2) is what makes that common: on crossing draw 1 the
spheres' test (1) held in every warm frame (8 wall points in a circle: capsules fan out over
the plates' half-space) while no point of either plate was ever shadowed, and every Jacobian
and covariance paid the shadowed path: the moved plate's shadowed neighbours re-simulated,
and central differences where analytic derivatives hold (docs/model-estimator.md).
"""
from __future__ import annotations

import math

import numpy as np

from ....core.constants import TINY
from ..shapes import box, plate

# The bounding test's slack beyond the ramps' reach: the most a finite-difference step moves a
# plate's points or edges (2 mm steps; 4 mrad of yaw on a 3 m plate's 1.5 m half-width: 6 mm)
MARGIN_M = 0.01


def cell_size(rows, lattice) -> np.ndarray:
    """(B,) the larger cell edge of each plate row on `lattice` (nu across, nv up): the ramp's
    width on the shadowed plate."""
    rows = np.atleast_2d(rows)
    return np.maximum(rows[:, plate.WIDTH] / lattice[0], rows[:, plate.HEIGHT] / lattice[1])


def _half_diagonal(row) -> float:
    """Half the diagonal of plate row `row`'s rectangle: its bounding sphere's radius."""
    return 0.5 * math.hypot(row[plate.WIDTH], row[plate.HEIGHT])


def can_shadow(occluder, shadowed, laser, spots, lattice) -> bool:
    """Can plate row `occluder` block any ray between plate row `shadowed` and O or a spot?
    Conservative: False means every ray misses it by more than the ramps reach."""
    occluder, shadowed = np.asarray(occluder, float), np.asarray(shadowed, float)
    ends = np.vstack([np.reshape(laser, (1, 3)), np.asarray(spots, float)])  # (E, 3)
    start = shadowed[:3]
    reach = float(_half_diagonal(occluder) + _half_diagonal(shadowed)
                  + cell_size(shadowed, lattice)[0] + MARGIN_M)
    seg = ends - start  # the capsule's axes, start -> wall point
    along = np.clip((occluder[:3] - start) @ seg.T / np.maximum(
        np.einsum("ek,ek->e", seg, seg), TINY), 0.0, 1.0)
    nearest = start + along[:, None] * seg
    near = np.linalg.norm(occluder[:3] - nearest, axis=1) < reach
    return bool(near.any()) and _meets_pyramid(occluder, shadowed, ends[near], lattice)


def _corners(row, grow) -> np.ndarray:
    """(4, 3) the corners of plate row `row`'s rectangle, each half-side grown by `grow`."""
    yaw = float(row[plate.YAW])
    across = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    hw, hh = 0.5 * float(row[plate.WIDTH]) + grow, 0.5 * float(row[plate.HEIGHT]) + grow
    signs = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])  # in cyclic order
    return np.asarray(row[:3], float) + signs[:, :1] * hw * across + signs[:, 1:] * hh * plate.UP


def _meets_pyramid(occluder, shadowed, ends, lattice) -> bool:
    """Can any ray from plate `shadowed`'s points to a wall point of `ends` (E, 3) meet a ramp
    of plate `occluder` (model.shadow's `_blocked`)? Conservative (True when unsure).

    What `_blocked` can make nonzero, for a ray P -> T of length L, with c the shadowed plate's
    cell edge (`cell_size`): its crossing H = P + t (T - P) of the occluder's plane with
    t > -c / 2L and t < 1 + c / 2L (the t-ramp), so H lies within c / 2 of the segment, and
    |u|, |v| below the half-sides plus (1 - t) c / 2 <= c (for L >= c / 2). P lies on the
    shadowed rectangle, so the segment lies in the pyramid conv(rectangle, T). Hence: the
    occluder's rectangle grown by c + MARGIN_M (a step may move it that far) against the
    pyramid of the shadowed rectangle grown by MARGIN_M (a step may move its points that far;
    the pyramid then moves no farther than its base) and then by a ball of c / 2 (+ 0.1 mm: a
    size step changes c by 2 mm / lattice), by the separating-axis theorem over both solids'
    face normals and their edges' cross products (any axis that separates proves they miss;
    axes beyond the complete set only make the test tighter)."""
    if not len(ends):
        return False
    cell = float(cell_size(shadowed, lattice)[0])
    base = _corners(shadowed, MARGIN_M)  # (4, 3)
    half = _half_diagonal(shadowed) + MARGIN_M
    if np.sqrt(((ends - shadowed[:3]) ** 2).sum(axis=1)).min() - half < cell:
        return True  # a wall point almost on the plate: the bounds above need L >= c / 2
    quad = _corners(occluder, cell + MARGIN_M)  # (4, 3)
    grow = 0.5 * cell + 1e-4  # the ball around the pyramid
    lateral = ends[:, None, :] - base[None]  # (E, 4, 3): the pyramid's lateral edges
    a_j, a_i = base[0] - base[1], quad[0] - quad[1]  # each plate's width direction
    n_j, n_i = np.array([a_j[1], -a_j[0], 0.0]), np.array([a_i[1], -a_i[0], 0.0])  # a x UP
    fixed = np.stack([n_j, n_i, a_j, a_i, plate.UP, np.cross(a_j, a_i)])  # (6, 3)
    # the side faces (base edge x lateral edge), edge x edge (a_i, UP x lateral) and, for a
    # flat pyramid (T in the base's plane), n_j x lateral: one cross product
    firsts = np.concatenate([np.roll(base, -1, axis=0) - base, np.broadcast_to(a_i, (4, 3)),
                             np.broadcast_to(plate.UP, (4, 3)), np.broadcast_to(n_j, (4, 3))])
    axes = np.concatenate([np.broadcast_to(fixed, (len(ends), 6, 3)),
                           np.cross(firsts[None], np.tile(lateral, (1, 4, 1)))], axis=1)
    norm = np.sqrt((axes * axes).sum(axis=2))  # (E, A); the axes are not normalised: the
    # ball's reach along one is grow |axis|
    on_base = axes @ base.T  # (E, A, 4)
    on_apex = (axes * ends[:, None, :]).sum(axis=2)  # (E, A)
    p_max = np.maximum(on_base.max(axis=2), on_apex) + grow * norm
    p_min = np.minimum(on_base.min(axis=2), on_apex) - grow * norm
    on_quad = axes @ quad.T  # (E, A, 4)
    apart = (p_max < on_quad.min(axis=2)) | (on_quad.max(axis=2) < p_min)
    apart &= norm > 1e-12  # a degenerate axis separates nothing
    return bool((~apart.any(axis=1)).any())  # some wall point's pyramid meets the occluder


def plate_rows(params) -> np.ndarray:
    """(K, 6) the plates this model reads for targets `params` (K, 6 plate or 7 closed-shape
    parameters): a plate itself, a closed shape its front face (box.front_of), which blocks
    rays as a plate does and bounds the rays its sides send (only roughly: an occluder that
    only a side's rays would meet is left out)."""
    rows = np.asarray(params, np.float64)
    rows = rows.reshape(len(rows), -1)
    if rows.shape[1] == plate.N_PARAMS:
        return rows
    return np.array([box.front_of(r) for r in rows]).reshape(len(rows), plate.N_PARAMS)


def occluders_of(params, laser, spots, lattice) -> list[np.ndarray]:
    """Per plate row of params (K, 6): the indices of the other plates that can shadow it
    (`can_shadow`); all empty for one plate. The last REMEMBER answers are kept: a fit asks
    again at the same rows (its residual, then its Jacobian and covariance there: half of a
    two-target tracker's calls, ~0.25 ms each)."""
    params = np.reshape(np.asarray(params, np.float64), (-1, plate.N_PARAMS))
    laser, spots = np.asarray(laser, np.float64), np.asarray(spots, np.float64)
    key = (params.tobytes(), laser.tobytes(), spots.tobytes(), spots.shape, tuple(lattice))
    which = _REMEMBERED.pop(key, None)
    if which is None:
        which = tuple(tuple(i for i in range(len(params)) if i != j and
                            can_shadow(params[i], params[j], laser, spots, lattice))
                      for j in range(len(params)))
    _REMEMBERED[key] = which  # most recently used last
    while len(_REMEMBERED) > REMEMBER:
        _REMEMBERED.pop(next(iter(_REMEMBERED)))
    return [np.array(w, int) for w in which]


REMEMBER = 16  # occluders_of's answers kept (a pure function of its inputs)
_REMEMBERED: dict = {}


HIDDEN_LATTICE = (12, 12)  # points a plate's hidden share is taken over (`hidden_shares`)


def hidden_shares(params, laser, spots) -> np.ndarray:
    """(K,) per plate row of params (K, 6), the share of its paths (laser spot -> point ->
    detector spot, over a HIDDEN_LATTICE of its points and every spot, unweighted) that the
    other plates block: 0 where none can (`occluders_of`). What a tracker reads to learn a
    target's size only from frames where it was seen whole (nlos_cl.tracking.warm)."""
    params = np.reshape(np.asarray(params, float), (-1, plate.N_PARAMS))
    out = np.zeros(len(params))
    # (the occluders as HIDDEN_LATTICE's ramps reach: wider than a model lattice's)
    for k, which in enumerate(occluders_of(params, laser, spots, HIDDEN_LATTICE)):
        if len(which):
            points = plate.plate_facets(params[k], HIDDEN_LATTICE).centres
            cell = cell_size(params[k], HIDDEN_LATTICE)[0]
            out[k] = 1.0 - float(visible(points, laser, spots, params[which], cell).mean())
    return out


def _ramp(distance, width):
    """0 -> 1 linearly over `width` centred on distance 0 (inside: distance > 0)."""
    return np.clip(0.5 + distance / width, 0.0, 1.0)


def _blocked(points, ends, occluder, cell_m):
    """(E, M) how much plate row `occluder` blocks each ray points (M, 3) -> ends (E, 3).
    The ray's components along the occluder's normal n, its width a and up are differences of
    the ends' and the points' (no (E, M, 3) temporaries; a crossing frame's warm fit spent a
    quarter of its time here), and the ramps are built in place."""
    centre, half_w, half_h = occluder[:3], 0.5 * occluder[plate.WIDTH], \
        0.5 * occluder[plate.HEIGHT]
    yaw = occluder[plate.YAW]
    nx, ny = np.cos(yaw), np.sin(yaw)  # upright: the normal has no z
    frame = np.array([[nx, ny, 0.0], [-ny, nx, 0.0], [0.0, 0.0, 1.0]])  # n, a, up
    p_n, p_a, p_z = frame @ points.T  # (M,) each
    e_n, e_a, e_z = frame @ ends.T  # (E,) each
    c_n, c_a, c_z = frame @ centre
    towards = e_n[:, None] - p_n[None]  # the ray's component along n
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(towards != 0.0, (c_n - p_n)[None] / towards, -1.0)
    np.clip(t, -1e3, 1e3, out=t)  # near-parallel rays: far outside, and no inf * 0
    u = e_a[:, None] - p_a[None]
    u *= t
    u += (p_a - c_a)[None]
    v = e_z[:, None] - p_z[None]
    v *= t
    v += (p_z - c_z)[None]
    length = (ends * ends).sum(axis=1)[:, None] - 2.0 * (ends @ points.T)
    length += (points * points).sum(axis=1)[None]
    np.sqrt(np.maximum(length, 0.0, out=length), out=length)
    edge = 1.0 - t  # one shadowed cell, seen on the occluder
    np.maximum(edge, 0.0, out=edge)
    edge *= cell_m
    np.maximum(edge, 1e-12, out=edge)
    inside = _ramp_in_place(half_w - np.abs(u, out=u), edge)
    inside *= _ramp_in_place(half_h - np.abs(v, out=v), edge)
    along = np.minimum(t, 1.0 - t)
    along *= length
    inside *= _ramp_in_place(along, cell_m)  # crossing between P and T
    return inside


def _ramp_in_place(distance, width):
    """`_ramp`, overwriting `distance` (an array of its own)."""
    distance /= width
    distance += 0.5
    return np.clip(distance, 0.0, 1.0, out=distance)


def visible(points, laser, spots, occluders, cell_m) -> np.ndarray:
    """(D, M) the share of each point's weight that reaches detector d past the occluder rows
    (K', 6): the laser leg's and the detector leg's unblocked shares, multiplied. points
    (M, 3) of one plate whose larger cell edge is cell_m."""
    ends = np.vstack([np.reshape(laser, (1, 3)), np.asarray(spots, float)])
    share = np.ones((len(ends), len(points)))
    for occluder in np.reshape(occluders, (-1, plate.N_PARAMS)):
        share *= 1.0 - _blocked(points, ends, occluder, float(cell_m))
    return share[1:] * share[0]


def shade(weight, points, rows, occluders, lattice, laser, spots) -> np.ndarray:
    """weight (D, B, M) of B plate rows' points (B, M, 3) times each plate's `visible` share
    past its occluders (a list of B (K', 6) arrays; None or empty: unshadowed, unchanged)."""
    if occluders is None:
        return weight
    cells = cell_size(rows, lattice)
    for b, occ in enumerate(occluders):
        if occ is not None and len(occ):
            weight[:, b] *= visible(points[b], laser, spots, occ, cells[b])
    return weight
