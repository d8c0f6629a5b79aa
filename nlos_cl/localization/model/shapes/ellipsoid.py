"""The curved closed target: an upright ellipsoid, for objects without flat faces (a ball, a
head and shoulders), which neither a plate nor a box reproduces.

Parameters as the box's (`nlos_cl.localization.model.shapes.box`): centre x, y, z, width (2 x the semi-axis
across), height (2 x the vertical one), depth (2 x the one along n), yaw of n. The surface is
cut into a fixed lattice of cells in azimuth x polar angle (fixed counts: continuous in the
sizes); each cell is a facet at its centre with the surface's normal there, its area and its
two edge vectors (the surface's tangents times the cell's angles), so the plate's cell
statistics (`plate.cell_model`) carry its spread of paths. Cells turned away from the laser
spot or from every wall spot are dropped before the forward call (their cosines would zero
them anyway, at full cost); a cell at the terminator goes to zero weight continuously.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ....core.geometry import Facets
from . import box, plate

NAMES, N_PARAMS, YAW = box.NAMES, box.N_PARAMS, box.YAW
LOWER = np.array([-np.inf, 0.05, -np.inf, 0.04, 0.04, 0.04, -np.inf])
UPPER = box.UPPER
STEPS, X_SCALE = box.STEPS, box.X_SCALE
# azimuth x polar angle (the lattice argument is for plates and boxes), and the share of the
# cells' mean path variance the shared pulse blur carries (plate.cell_model). A curved
# surface's cells range from facing the spots (small path variance) to grazing (large): one
# blur of half the mean variance widened the front's pulse, as one blur for all of a box's
# faces had. Against 1 cm-facet meshes (tests/localization/model/test_model_depth.py), L2 per detector: a 0.7 m
# sphere on (32, 16) cells with share 0.5 was 6.4-6.8 % off, (64, 32) with 0.05 0.2 %; a
# 0.6 m cylinder (cylinder.SIDE_CELLS) against one cut into 5 mm cells 5.2-6.2 % -> 0.16 %.
CLOSED = True
CELLS = (64, 32)
CURVED_BLUR_SHARE = 0.05


def chord_mean(step: float) -> float:
    """sin(step/2) / (step/2): the mean of cos(t) over a cell of angle `step` centred on t=0.
    A curved cell's points lie behind its centre's tangent plane (by up to r step^2 / 8);
    scaling the radial offset by this puts the cell's facet at the patch's mean position.
    On 32 x 16 cells it lowered the cost at the truth of a 0.39 m cylinder against its 1 cm-
    facet mesh by a third (Birge ratio 34 -> 24); the lattice's fineness did the rest."""
    half = 0.5 * step
    return math.sin(half) / half


def ellipsoid_cells(p, spots=None, laser=None, cells=CELLS):
    """Cells of ellipsoid p (only those lit and seen, when spots and laser are given): Facets
    of the cell centres and the cells' two edge vectors (each (F, 3))."""
    return lit_cells(*_surface(p, cells), spots, laser)


def pieces(p, lattice=None):
    """Every cell of ellipsoid p, none culled, as the pieces that share one pulse blur: one
    (Facets, edges, blur share) (model.host_shapes culls them itself)."""
    return curved_pieces(_surface(p, CELLS))


def curved_pieces(surface):
    """A curved shape's `pieces` from its cells' (centres, normals, e_u, e_v): one piece,
    every cell, the curved surfaces' blur share."""
    cells, edges = unit_cells(*surface)
    return [(cells, edges, CURVED_BLUR_SHARE)]


def _surface(p, cells):
    """Cell centres, (unnormalised) normals and the two edge vectors of ellipsoid p: each
    built in the shape's own frame (along n, across, up) and turned once (a fit builds ~10
    surfaces per Jacobian: 0.45 -> ~0.1 ms each)."""
    x, y, z, w, h, d, yaw = (float(v) for v in p)
    return surface_cells(np.array([x, y, z]), frame(yaw), 0.5 * w, 0.5 * d, 0.5 * h,
                         cell_angles(tuple(cells)))


def surface_cells(centre, turn, sa, sb, sc, angles):
    """Cell centres, normals and edge vectors of the ellipsoid surface of semi-axes sa
    (across), sb (along n), sc (up) about `centre`, over the cells of `angles`
    (`cell_angles`: the whole surface, or a polar band of it: the capsule's ends)."""
    s_po, c_po, s_az, c_az, d_az, d_po = angles
    # each cell's facet at its patch's mean position (chord_mean: the mean of sin and cos over
    # a cell of angle step is the centre's times sinc(step / 2))
    k_az, k_po = chord_mean(d_az), chord_mean(d_po)
    local = np.stack([k_po * k_az * sb * s_po * c_az, k_po * k_az * sa * s_po * s_az,
                      k_po * sc * c_po], axis=1)
    centres = local @ turn + centre
    e_az = np.stack([-sb * s_po * s_az, sa * s_po * c_az, np.zeros_like(s_po)], axis=1) @ turn
    e_po = np.stack([sb * c_po * c_az, sa * c_po * s_az, -sc * s_po], axis=1) @ turn
    normals = np.stack([s_po * c_az / sb, s_po * s_az / sa, c_po / sc], axis=1) @ turn
    return centres, normals, e_az * d_az, e_po * d_po


def frame(yaw) -> np.ndarray:
    """Rows n, a (across), up: local (along n, across, up) coordinates @ frame = world."""
    return np.array([[math.cos(yaw), math.sin(yaw), 0.0], [-math.sin(yaw), math.cos(yaw), 0.0],
                     [0.0, 0.0, 1.0]])


@functools.lru_cache(maxsize=8)
def cell_angles(cells, polar=(0.0, math.pi)):
    """sin and cos of the cells' polar and azimuth angles (F,) and the two steps: `cells`
    (azimuth, polar) over the polar range `polar` (the whole surface by default)."""
    n_az, n_po = cells
    d_az, d_po = 2 * math.pi / n_az, (polar[1] - polar[0]) / n_po
    az, po = np.meshgrid((np.arange(n_az) + 0.5) * d_az,
                         polar[0] + (np.arange(n_po) + 0.5) * d_po, indexing="ij")
    az, po = az.reshape(-1), po.reshape(-1)
    out = (np.sin(po), np.cos(po), np.sin(az), np.cos(az))
    for v in out:
        v.flags.writeable = False  # shared by every call
    return (*out, d_az, d_po)


def lit_cells(centres, normals, e_u, e_v, spots=None, laser=None):
    """Facets (unit normals, area |e_u x e_v|) and edges of the cells that the laser spot
    lights and at least one wall spot sees (all cells when spots is None)."""
    cells, edges = unit_cells(centres, normals, e_u, e_v)
    if spots is None:
        return cells, edges
    keep = lit_mask(cells.centres, cells.normals, spots, laser)
    if not keep.any():
        keep[0] = True  # one cell keeps the shapes valid (its weight is zero)
    return culled(cells, edges, keep)


def culled(cells, edges, keep):
    """(cells, edges) of the cells `keep` selects (given back as they are where it keeps all:
    a box's lit faces, copied for nothing before)."""
    if keep.dtype == bool:
        if keep.all():
            return cells, edges
        keep = np.flatnonzero(keep)  # np.take of rows: ~1/7 of a boolean mask's gather
    return (Facets(cells.centres.take(keep, axis=0), cells.normals.take(keep, axis=0),
                   cells.areas.take(keep)), tuple(e.take(keep, axis=0) for e in edges))


def lit_mask(centres, normals, spots, laser) -> np.ndarray:
    """(F,) bool: the cells (unit normals) the laser spot lights and a wall spot sees; paired
    layouts (laser (D, 3)): lit and seen by one (laser, detector) pair. On a flat face every
    cell gets its face's answer (n . (q - c) is one number over the face): box.seen."""
    spots, laser = np.asarray(spots, float), np.asarray(laser, float)
    if laser.ndim == 1:  # n . (spot - c) component by component: no (D, F, 3) temporaries
        (nx, ny, nz), (cx, cy, cz) = normals.T, centres.T
        s = spots[:, :, None]
        facing = nx * (s[:, 0] - cx)
        facing += ny * (s[:, 1] - cy)
        facing += nz * (s[:, 2] - cz)
        return (np.einsum("fk,fk->f", normals, laser - centres) > 0) & np.any(facing > 0, axis=0)
    seen = np.einsum("fk,dfk->df", normals, spots[:, None] - centres[None]) > 0
    if laser.ndim == 2:
        lit = np.einsum("fk,dfk->df", normals, laser[:, None] - centres[None]) > 0
        return np.any(lit & seen, axis=0)
    return (np.einsum("fk,fk->f", normals, laser - centres) > 0) & np.any(seen, axis=0)


def unit_cells(centres, normals, e_u, e_v):
    """Facets of cells (normals made unit, areas |e_u x e_v|) and their edges, none culled."""
    # component by component: np.linalg.norm's and np.cross's numbers, bit for bit, without
    # their axis handling (a third of building a closed shape's cells, which a fit does for
    # every row it evaluates)
    normals = normals / _length(normals[:, 0], normals[:, 1], normals[:, 2])[:, None]
    (ux, uy, uz), (vx, vy, vz) = e_u.T, e_v.T
    areas = _length(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx)
    return (Facets(np.ascontiguousarray(centres), np.ascontiguousarray(normals), areas),
            (np.ascontiguousarray(e_u), np.ascontiguousarray(e_v)))


def _length(x, y, z) -> np.ndarray:
    """|(x, y, z)| of vectors given by their components (each (F,))."""
    out = x * x
    out += y * y
    out += z * z
    return np.sqrt(out, out=out)


def ellipsoid_facets(p, cells=CELLS) -> Facets:
    """Facets of the whole ellipsoid p (no culling): for simulating the model itself."""
    return ellipsoid_cells(p, cells=cells)[0]


def model_facets(p, lattice, spots, laser):
    """What the forward call sees of ellipsoid p: as plate.model_facets, over the lit cells."""
    return curved_model(*ellipsoid_cells(p, spots, laser), spots, laser)


def curved_members(surface_of):
    """(cells, pieces, facets, model_facets): a curved shape's members from `surface_of(p)`,
    its cells' (centres, normals, e_u, e_v) (the cylinder's and the capsule's; as
    ellipsoid_cells, pieces, ellipsoid_facets and model_facets above)."""
    def cells(p, spots=None, laser=None):
        return lit_cells(*surface_of(p), spots, laser)

    def pieces(p, lattice=None):
        return curved_pieces(surface_of(p))

    def facets(p):
        return cells(p)[0]

    def model_facets(p, lattice, spots, laser):
        return curved_model(*cells(p, spots, laser), spots, laser)
    return cells, pieces, facets, model_facets


def curved_model(cells, edges, spots, laser):
    """What the forward call sees of a curved shape's lit cells (plate.cell_model at the
    curved surfaces' blur share)."""
    return plate.cell_model(cells, edges, spots, laser, CURVED_BLUR_SHARE)


def rounder_sizes(w, h, d) -> list:
    """Rounder starts' (across, up, along) from a fit of size (w, h, d): across and along the
    normal both sqrt(w d) (the height kept), and all three axes cbrt(w h d) (round targets
    stall in elongated minima: policy.closed_search.round_rows)."""
    m, g = math.sqrt(w * d), (w * h * d) ** (1 / 3)
    return [(m, h, m), (g, g, g)]


def from_plate(q, depth) -> np.ndarray:
    """The ellipsoid whose front reaches plate q's face: centre depth / 2 behind it."""
    return box.from_plate(q, depth)


extent, normal_of = box.extent, box.normal_of
