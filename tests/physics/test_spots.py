"""Finite laser and detector spots (Setup(finite_spots=True)): the disk quadrature and the
signal against a dense integration over both disks."""
import numpy as np
import pytest

import nlos_cl as nl
from conftest import window_around


def test_disk_rule_integrates_degree_five_exactly():
    setup = nl.paper_setup(finite_spots=True)
    lasers, wl, offsets, wd = setup.spot_samples()
    radius = setup.detected_spot_diameter_m / 2
    assert wl.sum() == pytest.approx(1) and wd.sum() == pytest.approx(1)
    assert np.all(offsets[:, 1] == 0) and np.all(lasers[:, 1] == 0)  # on the wall
    x, z = offsets[:, 0] / radius, offsets[:, 2] / radius
    # means over the unit disk: x^2 1/4, x^4 1/8, x^2 z^2 1/24, odd moments 0
    for f, mean in ((x ** 2, 1 / 4), (x ** 4, 1 / 8), (x ** 2 * z ** 2, 1 / 24), (x ** 3, 0),
                    (x * z ** 2, 0)):
        assert (wd * f).sum() == pytest.approx(mean, abs=1e-15)
    point = nl.paper_setup().spot_samples()
    assert len(point[0]) == 1 and point[1][0] == 1 and not point[2].any()


def facet_scene(finite, laser_d=0.07, det_d=0.1):
    setup = nl.paper_setup(finite_spots=finite, laser_spot_diameter_m=laser_d,
                           detected_spot_diameter_m=det_d,
                           detector_spots=[[-0.5, 0, 0], [-1.0, 0, 0.2]])
    mesh = nl.rectangle(0.004, 0.004, centre=(0.6, 0.9, 0.1), normal=(-0.3, -1, 0), cell_m=0.01)
    return nl.Scene(setup, nl.Target(mesh), 0.01)


def dense_disk_energy(scene, n=4000):
    """Eq. 19 for one small facet, averaged over uniformly random points of both disks."""
    setup, f = scene.setup, scene.facets()
    rng = np.random.default_rng(0)
    def disk(diameter):
        r, a = diameter / 2 * np.sqrt(rng.random(n)), rng.random(n) * 2 * np.pi
        return np.stack([r * np.cos(a), np.zeros(n), r * np.sin(a)], 1)
    lasers = setup.laser_spot + disk(setup.laser_spot_diameter_m)
    out = []
    for spot in setup.detector_spots:
        spots = spot + disk(setup.detected_spot_diameter_m)
        total = 0.0
        for c, nrm, area in zip(f.centres, f.normals, f.areas):
            v1, v2 = c - lasers, spots - c
            r1, r2 = np.linalg.norm(v1, axis=1), np.linalg.norm(v2, axis=1)
            g = (v1[:, 1] / r1) * (-(v1 @ nrm) / r1) * ((v2 @ nrm) / r2) * (v2[:, 1] / r2)
            total += area * np.mean(g / (r1 * r2) ** 2)
        out.append(total)
    return np.array(out)


def test_finite_spot_energy_matches_a_dense_disk_integral(runtime):
    fin, pt = facet_scene(True), facet_scene(False)
    axis = window_around(fin.setup, fin.target.mesh, 10e-12, margin_m=0.3)
    e_fin = nl.simulate(fin, axis, backend=runtime).histograms().data.sum(axis=1)
    e_pt = nl.simulate(pt, axis, backend=runtime).histograms().data.sum(axis=1)
    dense = dense_disk_energy(fin, 40000)
    ratio = (e_fin / e_pt) / (dense / dense_disk_energy(facet_scene(False, 1e-9, 1e-9), 10))
    np.testing.assert_allclose(ratio, 1.0, atol=2e-3)  # Monte Carlo error of 40000 samples


def test_finite_spots_spread_the_onset_by_the_disks_path_span(reference):
    fin, pt = facet_scene(True), facet_scene(False)
    axis = window_around(fin.setup, fin.target.mesh, 5e-12, margin_m=0.3)
    h_fin = nl.simulate(fin, axis, backend=reference).histograms().data
    h_pt = nl.simulate(pt, axis, backend=reference).histograms().data
    c = fin.facets().centres.mean(axis=0)
    for d, spot in enumerate(fin.setup.detector_spots):
        lead = lambda h: np.argmax(h > 0.02 * h.max())  # noqa: E731
        earlier_m = (lead(h_pt[d]) - lead(h_fin[d])) * axis.dt_s * nl.SPEED_OF_LIGHT
        # the disks' nearest points shorten the path by up to the radii times the in-wall
        # components of the unit directions to the facet; the 7-point rule reaches 0.816 of it
        u1, u2 = c - fin.setup.laser_spot, c - spot
        most = sum(r * np.hypot(u[0], u[2]) / np.linalg.norm(u)
                   for r, u in ((0.035, u1), (0.05, u2)))
        assert 0.4 * most < earlier_m < most + 0.003


def test_tiny_disks_give_the_point_spot_signal(reference):
    a, b = facet_scene(True, 1e-6, 1e-6), facet_scene(False, 1e-6, 1e-6)
    axis = window_around(a.setup, a.target.mesh, 10e-12, margin_m=0.3)
    ha = nl.simulate(a, axis, backend=reference).histograms().data
    hb = nl.simulate(b, axis, backend=reference).histograms().data
    np.testing.assert_allclose(ha, hb, rtol=0, atol=1e-6 * hb.max())
