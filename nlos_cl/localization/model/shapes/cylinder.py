"""An upright elliptic cylinder, for tall rounded objects (a person, a post, a bin), which a
box's corners and an ellipsoid's tapering ends both misdescribe.

Parameters as the box's (`nlos_cl.localization.model.shapes.box`): centre x, y, z, width (2 x the semi-axis
across), height, depth (2 x the semi-axis along n), yaw of n. The side is cut into a fixed
lattice of cells (azimuth x height), each cap into rings x sectors; a cell is a facet at its
centre with the surface's normal, its area and its two edge vectors, so the plate's cell
statistics (`plate.cell_model`) carry its spread of paths. Cells turned away from the laser
spot or from every wall spot are dropped before the forward call (as in `ellipsoid`).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from . import box, ellipsoid, plate

NAMES, N_PARAMS, YAW = box.NAMES, box.N_PARAMS, box.YAW
CLOSED = True
LOWER, UPPER, STEPS, X_SCALE = ellipsoid.LOWER, box.UPPER, box.STEPS, box.X_SCALE
# (azimuth, height) and (azimuth, rings): the azimuth is what the accuracy needs (the side is
# flat in height); the blur as the ellipsoid's (ellipsoid.CURVED_BLUR_SHARE, where measured).
SIDE_CELLS, CAP_CELLS = (64, 16), (64, 4)


def side_cells(c, n, a, sa, sb, h, n_az, n_h):
    """Cell centres, normals and edge vectors of the side of height h (the capsule's too)."""
    d_az, d_h = 2 * math.pi / n_az, h / n_h
    cos_az, sin_az, zz = _side_lattice(n_az, n_h)
    zz = zz * h
    k = ellipsoid.chord_mean(d_az)  # the cells' facets at their patches' mean positions
    centres = c + k * (sb * cos_az * n + sa * sin_az * a) + zz * plate.UP
    e_az = (-sb * sin_az * n + sa * cos_az * a) * d_az
    e_z = np.broadcast_to(plate.UP * d_h, e_az.shape)
    normals = cos_az / sb * n + sin_az / sa * a
    return centres, normals, e_az, e_z


def _cap(c, n, a, sa, sb, up, n_az, n_r):
    d_az, d_r = 2 * math.pi / n_az, 1.0 / n_r
    cos_az, sin_az, rr = _cap_lattice(n_az, n_r)
    radial = sb * cos_az * n + sa * sin_az * a
    centres = c + rr * radial
    e_az = rr * (-sb * sin_az * n + sa * cos_az * a) * d_az
    e_r = radial * d_r
    return centres, np.broadcast_to(up, centres.shape), e_az, e_r


@functools.lru_cache(maxsize=8)
def _side_lattice(n_az, n_h):
    """The side's cells' cos and sin of azimuth and height as a fraction of h, each (F, 1):
    the same for every cylinder (made once; every row's surface read them anew before)."""
    d_az = 2 * math.pi / n_az
    az, zz = np.meshgrid((np.arange(n_az) + 0.5) * d_az, (np.arange(n_h) + 0.5) / n_h - 0.5,
                         indexing="ij")
    return _frozen(np.cos(az), np.sin(az), zz)


@functools.lru_cache(maxsize=8)
def _cap_lattice(n_az, n_r):
    """A cap's cells' cos and sin of azimuth and radius as a fraction of the rim, (F, 1)."""
    d_az, d_r = 2 * math.pi / n_az, 1.0 / n_r
    az, rr = np.meshgrid((np.arange(n_az) + 0.5) * d_az, (np.arange(n_r) + 0.5) * d_r,
                         indexing="ij")
    return _frozen(np.cos(az), np.sin(az), rr)


def _frozen(*arrays):
    out = tuple(v.reshape(-1, 1) for v in arrays)
    for v in out:
        v.flags.writeable = False  # shared by every call
    return out


def _surface(p):
    """Cell centres, normals and the two edge vectors of cylinder p (side, top, bottom)."""
    x, y, z, w, h, d, yaw = (float(v) for v in p)
    c = np.array([x, y, z])
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    a = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    sa, sb = 0.5 * w, 0.5 * d
    parts = [side_cells(c, n, a, sa, sb, h, *SIDE_CELLS),
             _cap(c + 0.5 * h * plate.UP, n, a, sa, sb, plate.UP, *CAP_CELLS),
             _cap(c - 0.5 * h * plate.UP, n, a, sa, sb, -plate.UP, *CAP_CELLS)]
    return tuple(np.concatenate([q[i] for q in parts]) for i in range(4))


def rounder_sizes(w, h, d) -> list:
    """A rounder start's (across, up, along) from a fit of size (w, h, d): across and along
    the normal both sqrt(w d), the height kept (policy.closed_search.round_rows)."""
    m = math.sqrt(w * d)
    return [(m, h, m)]


# cylinder_cells(p, spots, laser): the lit and seen cells (Facets, edges); pieces(p): every
# cell, one blur; cylinder_facets(p): the whole surface (to simulate the model); model_facets:
# what the forward call sees (as plate.model_facets)
cylinder_cells, pieces, cylinder_facets, model_facets = ellipsoid.curved_members(_surface)
extent, normal_of = box.extent, box.normal_of
