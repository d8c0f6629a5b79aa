"""The parametric target: an upright, one-sided rectangular plate.

Parameters (one row of a float64 vector): centre x, y, z (m), width w and height h (m), yaw
(the horizontal angle of the plate's normal, radians: n = (cos yaw, sin yaw, 0)). Why a plate:
with a Lambertian target and third-order light only, what the wall sees of any object is its
surface facing the wall spots, and an upright plate of free size and yaw is the smallest
family whose histograms have the right onset, width and decay. Its centre is the centre of
the visible surface: for a closed object (a box, a person) that lies in front of the object's
own centre by up to half its depth (docs/model-estimator.md).

The plate is cut into a fixed nu x nv lattice of cells (the count does not change with the
size, so the model is continuous in w and h); each cell's spread of path lengths is carried
by Gauss points and a widened pulse in the forward call (`model_facets`), so coarse cells
leave no comb and no bias.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ....core.constants import TINY
from ....core.geometry import Facets, distance
from ....core.stats import unique_sorted

NAMES = ("x", "y", "z", "width", "height", "yaw")
LOWER = np.array([-np.inf, 0.05, -np.inf, 0.04, 0.04, -np.inf])
UPPER = np.array([np.inf, np.inf, np.inf, 3.0, 3.0, np.inf])
N_PARAMS = len(NAMES)
X, Y, Z, WIDTH, HEIGHT, YAW = range(N_PARAMS)  # where each parameter sits in a row
# Finite-difference steps, absolute (the forward kernel is float32: relative ~1e-8 steps would
# differentiate rounding), and the parameters' typical scales (model.fit reads both).
STEPS = np.array([2e-3, 2e-3, 2e-3, 2e-3, 2e-3, 4e-3])
X_SCALE = np.array([0.05, 0.05, 0.05, 0.1, 0.1, 0.1])
UP = np.array([0.0, 0.0, 1.0])
CLOSED = False  # an open surface: the front the spots see, no depth
WIDTH_VECTORS = True  # the solver may step its (width, yaw) pairs as vectors (solve.width_vectors)


def plate_facets(p, lattice=(10, 20)) -> Facets:
    """Facets of the plate p = (x, y, z, w, h, yaw) on a nu x nv lattice (centres of cells)."""
    nu, nv = lattice
    x, y, z, w, h, yaw = (float(v) for v in p)
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    across = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    u = ((np.arange(nu) + 0.5) / nu - 0.5) * w
    v = ((np.arange(nv) + 0.5) / nv - 0.5) * h
    uu, vv = np.meshgrid(u, v, indexing="ij")
    centres = (np.array([x, y, z]) + uu.reshape(-1, 1) * across + vv.reshape(-1, 1) * UP)
    normals = np.broadcast_to(normal, centres.shape)
    areas = np.full(len(centres), w * h / (nu * nv))
    return Facets(centres, np.ascontiguousarray(normals), areas)


def several_facets(params, lattice=(10, 20)) -> list[Facets]:
    return [plate_facets(p, lattice) for p in np.reshape(params, (-1, N_PARAMS))]


GAUSS_2 = 0.5 / math.sqrt(3.0)  # 2-point Gauss-Legendre nodes on a unit edge, +-0.2887
# The share of a cell's mean path variance carried by the shared pulse blur, for filtered data:
# the value their draws were judged with (1/4 there moved 6 of 120 Gaussian draws by > 5 mm,
# three each way: no comb to remove where the filter is 5x wider than a cell's range of paths).
BLUR_SHARE = 0.5
# Photon counts (unfiltered: the pulse alone) take COUNTS_BLUR_SHARE, carried by the problem's
# `Lattice` (model.lattices.lattice_for). 1/4 puts the points of a cell of mean variance at
# +-1/4 of its edges (keep sqrt(3)/2): the midpoints of a 2 x 2 sub-lattice, a comb whose first
# harmonic (period: one cell's range of paths) cancels. At 1/2 they sit at +-0.20 and that
# harmonic survives where a cell spans a few pulse widths: a 0.95 m plate was modelled 9 % off
# and 2 % at 1/4, on the same 16 cells across (tests/localization/model/test_model_cell_comb.py).
COUNTS_BLUR_SHARE = 0.25


class Lattice(tuple):
    """A plate lattice (nu cells across, nv up) that also carries its flat cells' blur share
    and a box's cells along its depth (None: box.DEPTH_CELLS): `nu, nv = lattice` reads it as
    the plain pair; `flat_share(lattice)` the share."""

    def __new__(cls, nu, nv, blur_share=BLUR_SHARE, depth_cells=None):
        out = super().__new__(cls, (int(nu), int(nv)))
        out.blur_share = float(blur_share)
        out.depth_cells = None if depth_cells is None else int(depth_cells)
        return out

    def __getnewargs__(self):  # pickle and copy rebuild it whole (a tuple's args: the pair)
        return self[0], self[1], self.blur_share, self.depth_cells

    def __repr__(self):
        return (f"Lattice({self[0]}, {self[1]}, blur_share={self.blur_share}, "
                f"depth_cells={self.depth_cells})")


def flat_share(lattice) -> float:
    """The blur share of a lattice's flat cells (plates, box faces): its own, or BLUR_SHARE
    for a plain (nu, nv) pair."""
    return getattr(lattice, "blur_share", BLUR_SHARE)


STAT_SPOTS = 32  # the cells' path statistics from at most this many spots (an affine fit over
# the spots carries the shift to the others: it varies smoothly, by ~10 % of its ~0.1 mm
# across a 0.9 m SPAD patch, so the fit's error is ~1e-3 mm; 1,024 spots cost 150 ms a call)


def plate_edges(p, lattice, count):
    """Per cell of plate p, its two edge vectors (across, up), each (count, 3)."""
    yaw = float(p[YAW])
    across = np.array([-math.sin(yaw), math.cos(yaw), 0.0]) * (float(p[WIDTH]) / lattice[0])
    up = UP * (float(p[HEIGHT]) / lattice[1])
    return np.broadcast_to(across, (count, 3)), np.broadcast_to(up, (count, 3))


def _gauss_points(cells, edges, scale):
    """Each cell's 2 x 2 Gauss points, their offsets from the centre times `scale` (F,);
    edges: the cells' two edge vectors, each (F, 3)."""
    # (+-g eu) + (+-g ev) is +-(g eu + g ev) or +-(g eu - g ev) exactly (a sign is exact),
    # so the four points are the centre -+ two offsets: the same numbers with 2 of 8 products
    eu, ev = edges
    scale = np.asarray(scale, float)[:, None]
    gu, gv = GAUSS_2 * eu, GAUSS_2 * ev
    both, apart = scale * (gu + gv), scale * (gu - gv)
    c, n_f = cells.centres, len(cells.centres)
    pts = np.empty((4, n_f, 3))  # (-, -), (-, +), (+, -), (+, +)
    np.subtract(c, both, out=pts[0])
    np.subtract(c, apart, out=pts[1])
    np.add(c, apart, out=pts[2])
    np.add(c, both, out=pts[3])
    return Facets(pts.reshape(-1, 3), np.ascontiguousarray(np.tile(cells.normals, (4, 1))),
                  np.tile(cells.areas, 4) / 4.0)


def model_facets(p, lattice, spots, laser):
    """What the forward call sees of plate p: point facets, the pulse blur (m of path) they
    share, and a path shift per detector (D,) to add to every facet's path (`cell_model`)."""
    cells = plate_facets(p, lattice)
    return cell_model(cells, plate_edges(p, lattice, cells.count), spots, laser,
                      flat_share(lattice))


def cell_model(cells, edges, spots, laser, blur_share=None):
    """Point facets, shared blur and per-detector shift for rectangular cells (centres,
    normals, areas; `edges` their two edge vectors). blur_share: BLUR_SHARE unless given.

    The forward call puts each facet's pulse at its path and spreads it by one width for all
    facets, but a lattice cell spans a range of paths, and that range differs from cell to
    cell (the path's gradient along the plate varies) and its mean is not the centre's path
    (the path is convex, the weight 1 / r^2 x cosines varies across the cell). On the 10 x 20
    lattice of a 1.6 m plate the mean is ~0.1 mm of path off, as large as a 10 dB frame's range
    error; a single width for every cell biases a 1 m square by ~1 cm. So: from each cell's
    2 x 2 Gauss points (exact for the first and second order over a uniform cell; float64
    twin ops.forward.facet_paths) its weighted mean path m_df and variance v_df; the shared
    blur carries BLUR_SHARE of the mean cell variance (it keeps the sum smooth where cells are
    large); each cell is then 4 points at its Gauss points pulled in by s_f = sqrt(1 - blur^2
    / v_f) so that points + blur have the cell's own variance; the shift restores the part
    (1 - s_f^2) of the cell's mean-path offset that the pulled-in points no longer carry."""
    keep, blur2, shift = cell_statistics(cells, edges, spots, laser, blur_share)
    return _gauss_points(cells, edges, keep), math.sqrt(blur2), shift


def cell_statistics(cells, edges, spots, laser, blur_share=None):
    """`cell_model`'s numbers: per cell how far its Gauss points are pulled in, keep (F,);
    the shared blur^2 (m^2 of path); the path shift per detector (D,)."""
    spots, laser = np.asarray(spots, float), np.asarray(laser, float)
    some = unique_sorted(np.linspace(0, len(spots) - 1, min(len(spots), STAT_SPOTS)).round()
                     ).astype(int)
    paired = laser.ndim == 2
    mean, centre, var_df, wsum = _cell_stats(cells, edges, spots[some],
                                             laser[some] if paired else laser)
    var_f = (var_df * wsum).sum(axis=0) / np.maximum(wsum.sum(axis=0), TINY)  # (F,)
    lit = wsum.sum(axis=0) > 0
    share = BLUR_SHARE if blur_share is None else blur_share
    blur2 = share * float(np.mean(var_f[lit])) if lit.any() else 0.0
    keep = np.sqrt(np.clip(1.0 - blur2 / np.maximum(var_f, TINY), 0.0, 1.0))
    lost = (1.0 - keep ** 2)[None] * (mean - centre) * wsum
    shift = lost.sum(axis=1) / np.maximum(wsum.sum(axis=1), TINY)
    if len(some) < len(spots):  # affine in the spot's position, least squares over `some`
        basis = np.hstack([np.ones((len(spots), 1)), spots - spots.mean(axis=0)]
                          + ([laser - laser.mean(axis=0)] if paired else []))
        coef, *_ = np.linalg.lstsq(basis[some], shift, rcond=None)
        shift = basis @ coef
    return keep, blur2, shift


def _cell_stats(cells, edges, spots, laser):
    """Per (spot, cell): weighted mean path over the cell's Gauss points, the centre's path,
    the weighted variance, and the summed weight."""
    n_f = len(cells.centres)
    full = _gauss_points(cells, edges, np.ones(n_f))
    path, weight = _point_paths(full, spots, laser)
    path, weight = path.reshape(len(path), 4, n_f), weight.reshape(len(weight), 4, n_f)
    wsum = weight.sum(axis=1)  # (D, F)
    safe = np.maximum(wsum, TINY)
    mean = (weight * path).sum(axis=1) / safe
    path -= mean[:, None]
    path *= path
    path *= weight
    var_df = path.sum(axis=1) / safe
    # the centre's path alone (its weight is not read): ops.forward.facet_paths' r1 + r2
    lasers = np.reshape(laser, (-1, 1, 3))  # (1 or D, 1, 3)
    centre = distance(cells.centres[None], lasers) + distance(  # np.linalg.norm's numbers,
        spots[:, None], cells.centres[None])  # component by component
    return mean, centre, var_df, wsum


def _point_paths(facets, spots, laser):
    """ops.forward.facet_paths' path r1 + r2 and Lambertian weight (D, F), component by
    component and in place (no (D, F, 3) temporaries; cell statistics were a quarter of a
    closed shape's model): the same numbers to the last bits of their products."""
    from ....core.geometry import spot_legs
    lasers = np.reshape(laser, (-1, 1, 3))  # (1 or D, 1, 3)
    p, nrm = facets.centres, facets.normals
    v1x, v1y, v1z = (p[None, :, k] - lasers[..., k] for k in range(3))  # O -> point
    r1sq = v1x * v1x + v1y * v1y + v1z * v1z
    front = -(nrm[:, 0] * v1x + nrm[:, 1] * v1y + nrm[:, 2] * v1z)  # r1 cos_b1
    np.maximum(front, 0.0, out=front)
    front *= np.abs(v1y)  # r1 cos_a1
    front *= facets.areas
    front /= r1sq
    front /= r1sq
    v2x, v2y, v2z, r2sq = spot_legs(p[:, 0], p[:, 1], p[:, 2], spots)  # point -> spot
    v2x, v2y, v2z, r2sq = v2x[:, 0], v2y[:, 0], v2z[:, 0], r2sq[:, 0]  # (D, F)
    weight = nrm[:, 0] * v2x + nrm[:, 1] * v2y + nrm[:, 2] * v2z  # r2 cos_a2
    np.maximum(weight, 0.0, out=weight)
    weight *= np.abs(v2y)  # r2 cos_b2
    weight *= front
    weight /= r2sq
    weight /= r2sq
    path = np.sqrt(r2sq, out=r2sq)
    path += np.sqrt(r1sq)
    return path, weight


def facing(centre, laser) -> float:
    """The yaw that turns a plate at `centre` to face the laser spot (the mean of a paired
    layout's spots)."""
    d = np.asarray(laser, float).reshape(-1, 3).mean(axis=0) - np.asarray(centre, float)
    return math.atan2(d[1], d[0])


@dataclass(frozen=True)
class Held:
    """The centre coordinate a fit holds because the spots cannot see it: `axis` 2 (z) for
    spots and laser on a line along x, 0 (x) for a line along z, None where the spots see all
    three (region.unseen_axis). `at`: the search region's middle; its coordinate on `axis` is
    the value held, its others where the centroid search starts."""

    axis: int | None = None
    at: tuple = (0.0, 0.0, 0.0)

    @property
    def value(self) -> float:
        return float(self.at[self.axis]) if self.axis is not None else math.nan

    def free_axes(self) -> list[int]:
        """The centre's axes (of x, y, z) the fit moves."""
        return [i for i in range(3) if i != self.axis]

    def put(self, point) -> np.ndarray:
        """A copy of `point` (..., 3 or more) with the held axis at its value."""
        out = np.array(point, dtype=np.float64)
        if self.axis is not None:
            out[..., self.axis] = self.value
        return out

    def free_mask(self) -> np.ndarray:
        """The plate's free-parameter mask (N_PARAMS,): all but the held axis."""
        free = np.ones(N_PARAMS, bool)
        if self.axis is not None:
            free[self.axis] = False
        return free

    @staticmethod
    def of(free, at) -> Held:
        """The Held a fit's free mask implies (x or z fixed), with `at` as the point."""
        axis = next((i for i in (2, 0) if not free[i]), None)
        return Held(axis, tuple(float(v) for v in np.asarray(at, float)[:3]))


def height_observable(spots, laser, tol=1e-6) -> bool:
    """Height (and the rotation about the wall spots' line) is observable only when the laser
    spot and the detector spots do not all lie on one straight line."""
    pts = np.vstack([np.asarray(laser, float).reshape(-1, 3), np.asarray(spots, float)])
    diffs = pts[1:] - pts[0]
    if len(diffs) < 2:
        return False
    s = np.linalg.svd(diffs, compute_uv=False)
    return bool(s[1] > tol * max(s[0], 1e-12))


def extent(p) -> np.ndarray:
    """Size along the plate's own axes: (across, up, along the normal) = (w, h, 0)."""
    return np.array([float(p[WIDTH]), float(p[HEIGHT]), 0.0])


def normal_of(p) -> np.ndarray:
    return np.array([math.cos(p[YAW]), math.sin(p[YAW]), 0.0])
