"""The parametric target: an upright, one-sided rectangular plate.

Parameters (one row of a float64 vector): centre x, y, z (m), width w and height h (m), yaw
(the horizontal angle of the plate's normal, radians: n = (cos yaw, sin yaw, 0)). Why a plate:
with a Lambertian target and third-order light only, what the wall sees of any object is its
surface facing the wall spots, and an upright plate of free size and yaw is the smallest
family whose histograms have the right onset, width and decay. Its centre is the centre of
the visible surface: for a closed object (a box, a person) that lies in front of the object's
own centre by up to half its depth (docs/model-estimator.md).

The plate is cut into a fixed nu x nv lattice of facets (the count does not change with the
size, so the model is continuous in w and h); each facet's spread of path lengths is carried
by widening the pulse in the forward call (`blur_m`), so coarse facets leave no comb.
"""
from __future__ import annotations

import math

import numpy as np

from ..geometry import Facets

NAMES = ("x", "y", "z", "width", "height", "yaw")
LOWER = np.array([-np.inf, 0.05, -np.inf, 0.04, 0.04, -np.inf])
UPPER = np.array([np.inf, np.inf, np.inf, 3.0, 3.0, np.inf])
N_PARAMS = len(NAMES)
UP = np.array([0.0, 0.0, 1.0])


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


def blur_m(p, lattice, facets, spots, laser) -> float:
    """Standard deviation (m of path) of the paths inside one facet: the path's gradient
    (r1 + r2)' = (c - O) / r1 + (c - spot) / r2 times the facet's size along each edge, as a
    uniform spread (size / sqrt 12), in quadrature, averaged over facets and detectors."""
    yaw = float(p[5])
    across = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    c = facets.centres
    g1 = (c - laser) / np.linalg.norm(c - laser, axis=1, keepdims=True)
    to_spots = c[None] - np.asarray(spots)[:, None]
    g = g1[None] + to_spots / np.linalg.norm(to_spots, axis=2, keepdims=True)
    du, dv = p[3] / lattice[0], p[4] / lattice[1]
    var = ((g @ across) * du) ** 2 + (g[..., 2] * dv) ** 2
    return math.sqrt(float(var.mean()) / 12.0)


def facing(centre, laser) -> float:
    """The yaw that turns a plate at `centre` to face the laser spot."""
    d = np.asarray(laser, float) - np.asarray(centre, float)
    return math.atan2(d[1], d[0])


def height_observable(spots, laser, tol=1e-6) -> bool:
    """Height (and the rotation about the wall spots' line) is observable only when the laser
    spot and the detector spots do not all lie on one straight line."""
    pts = np.vstack([np.asarray(laser, float)[None], np.asarray(spots, float)])
    diffs = pts[1:] - pts[0]
    if len(diffs) < 2:
        return False
    s = np.linalg.svd(diffs, compute_uv=False)
    return bool(s[1] > tol * max(s[0], 1e-12))


def extent(p) -> np.ndarray:
    """Size along the plate's own axes: (across, up, along the normal) = (w, h, 0)."""
    return np.array([float(p[3]), float(p[4]), 0.0])


def normal_of(p) -> np.ndarray:
    return np.array([math.cos(p[5]), math.sin(p[5]), 0.0])
