"""Issue 58's exact rewrites of the closed shapes' host model against the forms they replace,
bit for bit (tolerance 0: the fits' paths turn on the last bits of a Jacobian): the box's cell
centres and area from remembered lattice fractions and a hand-written cross product, the
cylinder's cells from remembered sines and cosines, and a group of pieces deposited one after
another (deposit.split's `seg`) instead of padded to the largest piece."""
import math

import numpy as np

from nlos_cl.localization.model.forward import deposit
from nlos_cl.localization.model.shapes import box, cylinder, ellipsoid, plate

ROWS = np.array([[4.0, 2.0, -0.45, 0.5, 0.7, 0.4, np.pi + 0.6],
                 [1.3, 3.1, 0.2, 0.21, 1.7, 0.9, 2.0], [-0.7, 1.2, 0.0, 2.2, 0.3, 0.05, -1.0]])


def _old_face_cells(p, lattice):
    """box.face_cells before (every face, np.cross and the lattice built per call)."""
    parts = []
    for (c, u, v, n), (nu, nv) in zip(box.faces(p), box._lattices(lattice)):
        su = ((np.arange(nu) + 0.5) / nu - 0.5)[:, None, None] * u
        sv = ((np.arange(nv) + 0.5) / nv - 0.5)[None, :, None] * v
        centres = (c + su + sv).reshape(-1, 3)
        area = abs(float(np.linalg.norm(np.cross(u, v)))) / (nu * nv)
        parts.append((centres, area))
    return parts


def test_box_cells_are_the_old_ones_bit_for_bit():
    for p in ROWS:
        for lattice in ((16, 24), (10, 20)):
            got = box.face_cells(p, lattice)
            for (cells, _), (centres, area) in zip(got, _old_face_cells(p, lattice)):
                assert np.array_equal(cells.centres, centres)
                assert np.array_equal(cells.areas, np.full(len(centres), area))


def _old_cylinder_surface(p):
    """cylinder._surface before (sines and cosines of the lattice taken per call)."""
    x, y, z, w, h, d, yaw = (float(v) for v in p)
    c, up = np.array([x, y, z]), plate.UP
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    a = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    sa, sb = 0.5 * w, 0.5 * d
    (n_az, n_h), (_, n_r) = cylinder.SIDE_CELLS, cylinder.CAP_CELLS
    d_az, d_h = 2 * math.pi / n_az, h / n_h
    az, zz = np.meshgrid((np.arange(n_az) + 0.5) * d_az, ((np.arange(n_h) + 0.5) / n_h - 0.5)
                         * h, indexing="ij")
    az, zz = az.reshape(-1, 1), zz.reshape(-1, 1)
    k = ellipsoid.chord_mean(d_az)
    side = (c + k * (sb * np.cos(az) * n + sa * np.sin(az) * a) + zz * up,
            np.cos(az) / sb * n + np.sin(az) / sa * a,
            (-sb * np.sin(az) * n + sa * np.cos(az) * a) * d_az,
            np.broadcast_to(up * d_h, (len(az), 3)))
    caps = []
    for centre, face_up in ((c + 0.5 * h * up, up), (c - 0.5 * h * up, -up)):
        az, rr = np.meshgrid((np.arange(n_az) + 0.5) * d_az, (np.arange(n_r) + 0.5) / n_r,
                             indexing="ij")
        az, rr = az.reshape(-1, 1), rr.reshape(-1, 1)
        caps.append((centre + rr * (sb * np.cos(az) * n + sa * np.sin(az) * a),
                     np.broadcast_to(face_up, (len(az), 3)),
                     rr * (-sb * np.sin(az) * n + sa * np.cos(az) * a) * d_az,
                     (sb * np.cos(az) * n + sa * np.sin(az) * a) / n_r))
    return tuple(np.concatenate([q[i] for q in [side] + caps]) for i in range(4))


def test_cylinder_cells_are_the_old_ones_bit_for_bit():
    for p in ROWS:
        for got, want in zip(cylinder._surface(p), _old_cylinder_surface(p)):
            assert np.array_equal(got, want)


def test_pieces_one_after_another_deposit_as_padded_bit_for_bit():
    """deposit_bins of pieces of different sizes, padded to the largest (zero-area points:
    zero weight, skipped) and one after another with `seg`: the same histograms."""
    rng = np.random.default_rng(5)
    n_det, sizes, n_bins, os_ = 3, [40, 17, 29], 30, 7
    dpath = np.array([0.01, 0.012, 0.011])
    edge0, sigma = rng.uniform(3.0, 3.1, (len(sizes), n_det)), rng.uniform(0.01, 0.02, 3)
    paths = [rng.uniform(2.9, 3.5, (n_det, m)) for m in sizes]
    weights = [rng.uniform(0.0, 1.0, (n_det, m)) * (rng.random((n_det, m)) > 0.2)
               for m in sizes]
    padded_path = np.full((n_det, len(sizes), max(sizes)), 3.2)
    padded_weight = np.zeros_like(padded_path)
    for b, (pth, wgt) in enumerate(zip(paths, weights)):
        padded_path[:, b, :sizes[b]], padded_weight[:, b, :sizes[b]] = pth, wgt
    want = deposit.deposit_bins(padded_path, padded_weight, edge0, dpath, sigma, n_bins, os_)
    got = deposit.deposit_bins(np.concatenate(paths, axis=1), np.concatenate(weights, axis=1),
                               edge0, dpath, sigma, n_bins, os_, seg=np.array(sizes))
    assert np.abs(want).max() > 0
    assert np.array_equal(got, want)
