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


def _end(centre, turn, sa, sb, sc, upper):
    """Cell centres, normals and edge vectors of one half-ellipsoid end: the ellipsoid's
    surface over the upper (polar 0..pi/2) or lower half of its polar range."""
    polar = (0.0, 0.5 * math.pi) if upper else (0.5 * math.pi, math.pi)
    return ellipsoid.surface_cells(centre, turn, sa, sb, sc,
                                   ellipsoid.cell_angles(END_CELLS, polar))


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
    parts = [cylinder.side_cells(c, n, a, sa, sb, side, *cylinder.SIDE_CELLS),
             _end(c + up, turn, sa, sb, sc, True), _end(c - up, turn, sa, sb, sc, False)]
    return tuple(np.concatenate([q[i] for q in parts]) for i in range(4))


# capsule_cells(p, spots, laser): the lit and seen cells (Facets, edges); pieces(p): every cell,
# one blur; capsule_facets(p): the whole surface (to simulate the model); model_facets: what
# the forward call sees (as plate.model_facets)
capsule_cells, pieces, capsule_facets, model_facets = ellipsoid.curved_members(_surface)
rounder_sizes = cylinder.rounder_sizes
extent, normal_of = box.extent, box.normal_of
