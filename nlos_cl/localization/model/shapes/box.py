"""The closed target: an upright box (cuboid), for objects whose sides the wall also sees.

Parameters (one row): centre x, y, z (m), width w (across the front face), height h, depth d
(along the front face's normal), yaw (the front face's normal, n = (cos yaw, sin yaw, 0)). The
centre is the box's own centre (its bounding-box centre when upright), not its front face's.
Depth 0 is the plate (`model.plate`) with the same centre, size and yaw: the families
are nested, so one test (nlos_cl.localization.model.policy.criteria.accepts) decides between them.

A box of depth d shows the wall its front face and, unless the wall sees it exactly head on, a
side face, and the face below or above when it is off the spots' height: a plate fits such a
histogram with the wrong onset-to-tail shape and lands on the visible surface, in a minimum that
depends on small details (a mirrored scene found another one). Only the faces that can be lit
and seen are cut into cells: whether a flat face sees a point is the same for all its points
(the sign of n . (q - c_face)), so this culling is exact; the forward model's cosines would
zero the others anyway, at full cost.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ....core.geometry import Facets
from . import plate

NAMES = ("x", "y", "z", "width", "height", "depth", "yaw")
N_PARAMS = len(NAMES)
X, Y, Z, WIDTH, HEIGHT, DEPTH, YAW = range(N_PARAMS)  # where each parameter sits in a row
LOWER = np.array([-np.inf, 0.05, -np.inf, 0.04, 0.04, 0.0, -np.inf])
UPPER = np.array([np.inf, np.inf, np.inf, 3.0, 3.0, 3.0, np.inf])
STEPS = np.array([2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 4e-3])  # as the plate's (see plate.py)
X_SCALE = np.array([0.05, 0.05, 0.05, 0.1, 0.1, 0.1, 0.1])
DEPTH_CELLS = 8  # cells along the depth; across and up use the plate's lattice
CLOSED = True  # a closed shape: fitted from the plate's starts (policy.closed)
UP = plate.UP


def faces(p):
    """The six faces of box p: (centre, u edge, v edge, outward normal), u and v full edges."""
    x, y, z, w, h, d, yaw = (float(v) for v in p)
    c = np.array([x, y, z])
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    a = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    return [(c + 0.5 * d * n, w * a, h * UP, n), (c - 0.5 * d * n, w * a, h * UP, -n),
            (c + 0.5 * w * a, d * n, h * UP, a), (c - 0.5 * w * a, d * n, h * UP, -a),
            (c + 0.5 * h * UP, w * a, d * n, UP), (c - 0.5 * h * UP, w * a, d * n, -UP)]


def _lattices(lattice):
    nu, nv = lattice
    d = getattr(lattice, "depth_cells", None) or DEPTH_CELLS  # a plate.Lattice's, for counts
    return [(nu, nv), (nu, nv), (d, nv), (d, nv), (nu, d), (nu, d)]


def seen(centre, normal, spots, laser) -> bool:
    """Can the face be lit by the laser spot and seen from at least one wall spot? (Paired
    layouts, a laser spot per detector: lit and seen by one pair.)"""
    seen_by = (spots - centre) @ normal > 0
    if np.ndim(laser) == 2:
        return bool(np.any(((laser - centre) @ normal > 0) & seen_by))
    return bool(normal @ (laser - centre) > 0 and np.any(seen_by))


def shown(p, spots, laser) -> list[bool]:
    """Per face of box p (faces' order): is it lit by the laser spot and seen by a wall spot?"""
    spots, laser = np.asarray(spots, float), np.asarray(laser, float)
    return [seen(c, n, spots, laser) for c, _, _, n in faces(p)]


def face_cells(p, lattice, spots=None, laser=None) -> list:
    """Per face of box p (only those lit and seen, when spots and laser are given): Facets of
    its cell centres and the cells' two edge vectors (each (F, 3))."""
    parts = []
    keep = shown(p, spots, laser) if spots is not None else [True] * 6
    for (c, u, v, n), (nu, nv), ok in zip(faces(p), _lattices(lattice), keep):
        if not ok:
            continue
        fu, fv = _fractions(nu, nv)
        centres = (c + fu * u + fv * v).reshape(-1, 3)
        count = len(centres)
        area = abs(float(np.linalg.norm(_cross(u, v)))) / (nu * nv)
        parts.append((Facets(centres, np.ascontiguousarray(np.broadcast_to(n, (count, 3))),
                             np.full(count, area)),
                      (np.broadcast_to(u / nu, (count, 3)), np.broadcast_to(v / nv, (count, 3)))))
    if not parts:  # nothing visible: one zero-area cell keeps the shapes valid
        zero = np.zeros((1, 3))
        parts = [(Facets(np.asarray(p[:3], float)[None], zero, np.zeros(1)), (zero, zero))]
    return parts


@functools.lru_cache(maxsize=16)
def _fractions(nu, nv):
    """The cells' centres along a face's u and v edges as fractions of them, (nu, 1, 1) and
    (1, nv, 1): the same for every face of a lattice (made once)."""
    fu = ((np.arange(nu) + 0.5) / nu - 0.5)[:, None, None]
    fv = ((np.arange(nv) + 0.5) / nv - 0.5)[None, :, None]
    fu.flags.writeable = fv.flags.writeable = False
    return fu, fv


def _cross(u, v) -> np.ndarray:
    """np.cross of two 3-vectors, the same products and differences (bit for bit) without
    its axis handling (a sixth of building a box's cells, which a fit does for every row)."""
    return np.array([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                     u[0] * v[1] - u[1] * v[0]])


def pieces(p, lattice):
    """Every face of box p, none culled, each a piece with its own pulse blur: (Facets,
    edges, blur share) per face (model.host_shapes culls them itself; see model_facets)."""
    share = plate.flat_share(lattice)
    return [(cells, edges, share) for cells, edges in face_cells(p, lattice)]


def box_cells(p, lattice, spots=None, laser=None):
    """Cells of the faces of box p (only those lit and seen, when spots and laser are given):
    Facets of the cell centres, and the cells' two edge vectors (each (F, 3))."""
    parts = face_cells(p, lattice, spots, laser)
    cells = Facets(*(np.concatenate([getattr(f, k) for f, _ in parts])
                     for k in ("centres", "normals", "areas")))
    return cells, tuple(np.concatenate([e[i] for _, e in parts]) for i in range(2))


def box_facets(p, lattice=(10, 20)) -> Facets:
    """Facets of every face of box p (no culling): for simulating the model itself."""
    return box_cells(p, lattice)[0]


def model_facets(p, lattice, spots, laser) -> list:
    """What the forward calls see of box p: plate.cell_model of each visible face, one part
    (facets, blur, shift) per face. One blur for all faces over-blurred the front: it is half
    the cells' mean path variance, and a side face seen edge-on has cells of 10-100x the
    front's variance, so the front's pulse was widened by ~3 % of its width and the fit
    preferred a box of 0.29 m depth to the true 0.75 m (closed draw 8, noise-free)."""
    return [plate.cell_model(cells, edges, spots, laser, plate.flat_share(lattice))
            for cells, edges in face_cells(p, lattice, spots, laser)]


def from_plate(q, depth) -> np.ndarray:
    """The box of the given depth behind plate q: same front face, centre d / 2 behind it."""
    x, y, z, w, h, yaw = (float(v) for v in q)
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    c = np.array([x, y, z]) - 0.5 * depth * n
    return np.array([c[0], c[1], c[2], w, h, depth, yaw])


def front_of(p) -> np.ndarray:
    """The front face of closed shape p (box, ellipsoid, cylinder, capsule: same parameters)
    as a plate row (x, y, z, width, height, yaw): `from_plate`'s inverse."""
    p = np.asarray(p, float)
    front = p[:3] + 0.5 * p[DEPTH] * normal_of(p)
    return np.array([*front, p[WIDTH], p[HEIGHT], p[YAW]])


def rounder_sizes(w, h, d) -> list:
    """(across, up, along) sections of a rounder start from a fit of this size (policy.closed's
    round_rows): none for the box, whose flat face's depth is not its curvature."""
    return []


def extent(p) -> np.ndarray:
    """Size along the box's own axes: (across, up, along the normal) = (w, h, d)."""
    return np.array([float(p[WIDTH]), float(p[HEIGHT]), float(p[DEPTH])])


def normal_of(p) -> np.ndarray:
    return np.array([math.cos(p[YAW]), math.sin(p[YAW]), 0.0])
