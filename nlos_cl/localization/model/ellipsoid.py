"""The curved closed target: an upright ellipsoid, for objects without flat faces (a ball, a
head and shoulders), which neither a plate nor a box reproduces.

Parameters as the box's (`nlos_cl.localization.model.box`): centre x, y, z, width (2 x the semi-axis
across), height (2 x the vertical one), depth (2 x the one along n), yaw of n. The surface is
cut into a fixed lattice of cells in azimuth x polar angle (fixed counts: continuous in the
sizes); each cell is a facet at its centre with the surface's normal there, its area and its
two edge vectors (the surface's tangents times the cell's angles), so the plate's cell
statistics (`plate.cell_model`) carry its spread of paths. Cells turned away from the laser
spot or from every wall spot are dropped before the forward call (their cosines would zero
them anyway, at full cost); a cell at the terminator goes to zero weight continuously.
"""
from __future__ import annotations

import math

import numpy as np

from ...core.geometry import Facets
from . import box, plate

NAMES, N_PARAMS, YAW = box.NAMES, box.N_PARAMS, box.YAW
LOWER = np.array([-np.inf, 0.05, -np.inf, 0.04, 0.04, 0.04, -np.inf])
UPPER = box.UPPER
STEPS, X_SCALE = box.STEPS, box.X_SCALE
# azimuth x polar angle (the lattice argument is for plates and boxes), and the share of the
# cells' mean path variance the shared pulse blur carries (plate.cell_model). A curved
# surface's cells range from facing the spots (small path variance) to grazing (large): one
# blur of half the mean variance widened the front's pulse, as one blur for all of a box's
# faces had. Against 1 cm-facet meshes (tests/test_model_depth.py), L2 per detector: a 0.7 m
# sphere on (32, 16) cells with share 0.5 was 6.4-6.8 % off, (64, 32) with 0.05 0.2 %; a
# 0.6 m cylinder (cylinder.SIDE_CELLS) against one cut into 5 mm cells 5.2-6.2 % -> 0.16 %.
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
    x, y, z, w, h, d, yaw = (float(v) for v in p)
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    a = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    sa, sc, sb = 0.5 * w, 0.5 * h, 0.5 * d  # across, up, along n
    n_az, n_po = cells
    d_az, d_po = 2 * math.pi / n_az, math.pi / n_po
    az, po = np.meshgrid((np.arange(n_az) + 0.5) * d_az, (np.arange(n_po) + 0.5) * d_po,
                         indexing="ij")
    az, po = az.reshape(-1, 1), po.reshape(-1, 1)
    s_po, c_po, s_az, c_az = np.sin(po), np.cos(po), np.sin(az), np.cos(az)
    # each cell's facet at its patch's mean position (chord_mean: the mean of sin and cos over
    # a cell of angle step is the centre's times sinc(step / 2))
    k_az, k_po = chord_mean(d_az), chord_mean(d_po)
    centres = np.array([x, y, z]) + k_po * (k_az * (sb * s_po * c_az * n + sa * s_po * s_az * a)
                                            + sc * c_po * plate.UP)
    e_az = (-sb * s_po * s_az * n + sa * s_po * c_az * a) * d_az
    e_po = (sb * c_po * c_az * n + sa * c_po * s_az * a - sc * s_po * plate.UP) * d_po
    normals = s_po * c_az / sb * n + s_po * s_az / sa * a + c_po / sc * plate.UP
    return lit_cells(centres, normals, e_az, e_po, spots, laser)


def lit_cells(centres, normals, e_u, e_v, spots=None, laser=None):
    """Facets (unit normals, area |e_u x e_v|) and edges of the cells that the laser spot
    lights and at least one wall spot sees (all cells when spots is None)."""
    normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    areas = np.linalg.norm(np.cross(e_u, e_v), axis=1)
    keep = np.ones(len(centres), bool)
    if spots is not None:
        spots, laser = np.asarray(spots, float), np.asarray(laser, float)
        seen = np.einsum("fk,dfk->df", normals, spots[:, None] - centres[None]) > 0
        if laser.ndim == 2:  # paired: lit and seen by one (laser, detector) pair
            lit = np.einsum("fk,dfk->df", normals, laser[:, None] - centres[None]) > 0
            keep = np.any(lit & seen, axis=0)
        else:
            keep = (np.einsum("fk,fk->f", normals, laser - centres) > 0) & np.any(seen, axis=0)
        if not keep.any():
            keep[0] = True  # one cell keeps the shapes valid (its weight is zero)
    return (Facets(centres[keep], np.ascontiguousarray(normals[keep]), areas[keep]),
            (np.ascontiguousarray(e_u[keep]), np.ascontiguousarray(e_v[keep])))


def ellipsoid_facets(p, cells=CELLS) -> Facets:
    """Facets of the whole ellipsoid p (no culling): for simulating the model itself."""
    return ellipsoid_cells(p, cells=cells)[0]


def model_facets(p, lattice, spots, laser):
    """What the forward call sees of ellipsoid p: as plate.model_facets, over the lit cells."""
    cells, edges = ellipsoid_cells(p, spots, laser)
    return plate.cell_model(cells, edges, spots, laser, CURVED_BLUR_SHARE)


def from_plate(q, depth) -> np.ndarray:
    """The ellipsoid whose front reaches plate q's face: centre depth / 2 behind it."""
    return box.from_plate(q, depth)


extent, normal_of = box.extent, box.normal_of
