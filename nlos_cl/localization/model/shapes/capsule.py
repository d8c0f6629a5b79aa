"""An upright capsule: an elliptic cylinder whose ends are half-ellipsoids, for people (and
rounded posts, sacks, bollards), whose top and bottom curve away as a cylinder's flat caps
do not.

Why: a person simulated as a capsule mesh (0.4-0.6 m across, 1.5-1.9 m tall) and seen by
three wall spots was fitted by the box, ellipsoid and cylinder families as a wide, shallow
shape (0.9-1.6 m across, 0.1-0.3 m deep: scenario draws 3, 5, 70, 85): its centre 0.2-0.4 m
short of the person's. Noiseless, the best cylinder left 8.7 % of the data's energy
(cost 1.26e8 against the plate's 1.45e9), where the same cylinder fitted a cylinder mesh to
1e-4 of it (docs/model-estimator.md, "Persons").

Parameters as the box's (`nlos_cl.localization.model.shapes.box`): centre x, y, z, width
(2 x the semi-axis across), height (overall, end to end), depth (2 x the semi-axis along n),
yaw of n. Each end is a half-ellipsoid of the cross-section's semi-axes and a vertical
semi-axis of their geometric mean (a round section's radius), at most half the height; the
side is what is left between them (no side where the ends meet: an ellipsoid). The cells are
the cylinder's side and the ellipsoid's lattice over half the polar range per end.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from . import box, cylinder, ellipsoid, plate

NAMES, N_PARAMS, YAW = box.NAMES, box.N_PARAMS, box.YAW
CLOSED = True
LOWER, UPPER, STEPS, X_SCALE = ellipsoid.LOWER, box.UPPER, box.STEPS, box.X_SCALE
# (azimuth, polar) cells per end: the ellipsoid's (64, 32) over half the polar range
END_CELLS = (64, 16)


def end_height(w, h, d) -> float:
    """The vertical semi-axis of each end: the section's mean radius sqrt(sa sb), at most
    half the height."""
    return min(0.5 * math.sqrt(w * d), 0.5 * h)


@functools.lru_cache(maxsize=8)
def _end_angles(n_az, n_po, upper):
    """sin and cos of an end's cells' polar and azimuth angles (F,), and the two steps: polar
    0..pi/2 from the top (upper) or pi/2..pi."""
    d_az, d_po = 2 * math.pi / n_az, 0.5 * math.pi / n_po
    start = 0.0 if upper else 0.5 * math.pi
    az, po = np.meshgrid((np.arange(n_az) + 0.5) * d_az, start + (np.arange(n_po) + 0.5) * d_po,
                         indexing="ij")
    az, po = az.reshape(-1), po.reshape(-1)
    out = (np.sin(po), np.cos(po), np.sin(az), np.cos(az))
    for v in out:
        v.flags.writeable = False  # shared by every call
    return (*out, d_az, d_po)


def _end(centre, turn, sa, sb, sc, upper):
    """Cell centres, normals and edge vectors of one half-ellipsoid end (as
    ellipsoid._surface, over its half of the polar range)."""
    s_po, c_po, s_az, c_az, d_az, d_po = _end_angles(*END_CELLS, upper)
    k_az, k_po = ellipsoid.chord_mean(d_az), ellipsoid.chord_mean(d_po)
    local = np.stack([k_po * k_az * sb * s_po * c_az, k_po * k_az * sa * s_po * s_az,
                      k_po * sc * c_po], axis=1)
    centres = local @ turn + centre
    e_az = np.stack([-sb * s_po * s_az, sa * s_po * c_az, np.zeros_like(s_po)], axis=1) @ turn
    e_po = np.stack([sb * c_po * c_az, sa * c_po * s_az, -sc * s_po], axis=1) @ turn
    normals = np.stack([s_po * c_az / sb, s_po * s_az / sa, c_po / sc], axis=1) @ turn
    return centres, normals, e_az * d_az, e_po * d_po


def _surface(p):
    """Cell centres, normals and the two edge vectors of capsule p (side, top, bottom). The
    side keeps its cells where the ends meet (zero height, zero area): the same cell count
    for every row."""
    x, y, z, w, h, d, yaw = (float(v) for v in p)
    c = np.array([x, y, z])
    turn = ellipsoid.frame(yaw)
    n, a = turn[0], turn[1]
    sa, sb, sc = 0.5 * w, 0.5 * d, end_height(w, h, d)
    side = max(h - 2.0 * sc, 0.0)
    up = 0.5 * side * plate.UP
    parts = [cylinder._side(c, n, a, sa, sb, side, *cylinder.SIDE_CELLS),
             _end(c + up, turn, sa, sb, sc, True), _end(c - up, turn, sa, sb, sc, False)]
    return tuple(np.concatenate([q[i] for q in parts]) for i in range(4))


def capsule_cells(p, spots=None, laser=None):
    """Cells of capsule p (only those lit and seen, when spots and laser are given): Facets
    of the cell centres and the cells' two edge vectors (each (F, 3))."""
    return ellipsoid.lit_cells(*_surface(p), spots, laser)


def pieces(p, lattice=None):
    """Every cell of capsule p, none culled, as the pieces that share one pulse blur (one):
    as ellipsoid.pieces."""
    cells, edges = ellipsoid.unit_cells(*_surface(p))
    return [(cells, edges, ellipsoid.CURVED_BLUR_SHARE)]


def capsule_facets(p):
    """Facets of the whole capsule p (no culling): for simulating the model itself."""
    return capsule_cells(p)[0]


def model_facets(p, lattice, spots, laser):
    """What the forward call sees of capsule p: as plate.model_facets, over the lit cells."""
    cells, edges = capsule_cells(p, spots, laser)
    return plate.cell_model(cells, edges, spots, laser, ellipsoid.CURVED_BLUR_SHARE)


rounder_sizes = cylinder.rounder_sizes
extent, normal_of = box.extent, box.normal_of
