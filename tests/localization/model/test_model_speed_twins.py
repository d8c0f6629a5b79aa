"""Issue 58's rewrites of the host model's primitives against the forms they replace: the cell
statistics' in-place paths against the forward op's float64 twin (ops.forward.facet_paths),
and the deposit's split, which computes t and the rows for the kept points only, against its
definition over all points."""
import math

import numpy as np

from nlos_cl.localization.model.forward import deposit
from nlos_cl.localization.model.shapes import plate
from nlos_cl.ops.forward import facet_paths


def _plate_points():
    p = np.array([0.3, 2.0, 0.1, 0.6, 0.9, -0.2])  # edge-on: some spots behind it
    cells = plate.plate_facets(p, (8, 12))
    return cells, plate._gauss_points(cells, plate.plate_edges(p, (8, 12), cells.count),
                                      np.ones(cells.count))


def test_cell_paths_are_the_forward_twins_one_laser_and_paired():
    rng = np.random.default_rng(3)
    spots = np.c_[rng.uniform(-1, 1, 7), np.zeros(7), rng.uniform(-1, 1, 7)]
    _, points = _plate_points()
    for laser in (np.array([0.1, 0.0, 0.2]), 0.9 * spots):
        want_path, want_weight = facet_paths(points.centres, points.normals, points.areas,
                                             spots, laser)
        path, weight = plate._point_paths(points, spots, laser)
        assert np.allclose(path, want_path, rtol=1e-14, atol=0)
        assert np.allclose(weight, want_weight, rtol=1e-13, atol=0)
        assert np.array_equal(weight > 0, want_weight > 0)  # the same points face both legs
        assert 0 < np.mean(weight > 0) < 1  # some of this plate's points face away


def test_split_keeps_the_points_and_rows_of_its_definition():
    rng = np.random.default_rng(4)
    n_det, n_b, n_pts, n_bins, os_ = 3, 4, 50, 20, 5
    dpath = np.array([0.01, 0.012, 0.011])
    edge0, sigma = rng.uniform(3.0, 3.1, (n_b, n_det)), rng.uniform(0.01, 0.02, n_b)
    path = rng.uniform(2.9, 3.4, (n_det, n_b, n_pts))  # some outside the window
    weight = np.where(rng.random(path.shape) < 0.7, rng.random(path.shape), 0.0)
    got = deposit.split(path, weight, edge0, dpath, sigma, n_bins, os_)
    pad = math.ceil(deposit.REACH_SIGMAS * sigma.max() / dpath.min()) + 1
    length = (n_bins + 2 * pad) * os_
    u = (path - (edge0.T - pad * dpath[:, None])[:, :, None]) * (os_ / dpath)[:, None, None]
    u -= 0.5
    j = np.floor(u)
    ok = (weight > 0) & (j >= 0) & (j < length - 1)
    row = (np.arange(n_det * n_b).reshape(n_det, n_b, 1) * length + j.astype(np.int64))[ok]
    assert got.pad == pad and got.shape == (n_det, n_b, n_bins + 2 * pad, os_)
    assert np.array_equal(got.ok, ok) and ok.any() and not ok.all()
    assert np.array_equal(got.row, row) and np.array_equal(got.t, (u - j)[ok])
