"""Every kernel against its float64 NumPy twin on the same inputs.

Tolerances (float32 kernel vs float64 twin), all relative to the largest value of the output:
- forward 1e-3: paths of ~10 m round to ~1e-6 m in float32, a shift of 1e-4 of the pulse sigma
  (8.9 mm); the kernel takes each bin's edges from one base so widths are exact; OpenCL allows
  erf 16 ulp (~1e-6 absolute) against the erf difference of a 1 ps bin (~0.03): 4e-5. Measured
  ~1e-5; the tolerance keeps a 10x margin over the worst case.
- gauss_filter 1e-5: a float32 fma chain of N taps errs ~sqrt(N) * 6e-8 (N = 1301: 2e-6).
- ellipse_score 1e-3 on smooth (filtered) signals: the fractional bin index of a ~10 m path is
  off by ~0.003 bin in float32; times the filtered signal's slope per bin (< 0.05 of the peak)
  that is 1.5e-4 per detector.
"""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.ops import add_awgn, gauss_filter, row_stats
from nlos_cl.ops.gauss_filter import gauss_taps
from conftest import window_around


def rel_err(a, b):
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / np.abs(b).max())


SCENES = {
    "paper-2cm-1ps": (lambda: nl.paper_scene(facet_size_m=0.02), 1e-12),
    "paper-1cm-50ps": (lambda: nl.paper_scene(), 50e-12),
    "box-10ps": (lambda: nl.Scene(nl.paper_setup(), nl.Target(nl.box((0.4, 0.3, 0.5),
                                                                     (2.5, 3.0, 0.2))), 0.02), 10e-12),
    "sphere-4det-10ps": (lambda: nl.Scene(
        nl.paper_setup(detector_spots=[[-0.5, 0, 0], [0.5, 0, 0.3], [-1, 0, -0.4], [1.2, 0, 0]]),
        nl.Target(nl.sphere(0.25, (1.0, 2.5, 0.5))), 0.02), 10e-12),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_forward_matches_twin(name, device_runtime, reference):
    make, dt = SCENES[name]
    scene = make()
    axis = window_around(scene.setup, scene.target.mesh, dt)
    dev = nl.simulate(scene, axis, backend=device_runtime)
    twin = nl.simulate(scene, axis, backend=reference)
    assert dev.scale_w == twin.scale_w
    a, b = dev.histograms().data, twin.histograms().data
    assert b.max() > 0
    assert rel_err(a, b) < 1e-3


def test_facet_path_range_matches_twin(device_runtime, reference):
    scene = nl.paper_scene(facet_size_m=0.02)
    facets = scene.facets()
    args = (facets, scene.setup.detector_spots, scene.setup.laser_spot,
            np.zeros(3), np.full(3, 3e-4), 0.0089, 100)
    _, span_dev = device_runtime.forward(*args)
    _, span_ref = reference.forward(*args)
    np.testing.assert_allclose(span_dev, span_ref, atol=1e-5)  # float32 paths of ~10 m


@pytest.mark.parametrize("h_bins", [1, 7.5, 650, 1500])
def test_gauss_filter_matches_twin(h_bins, device_runtime):
    rng = np.random.default_rng(1)
    data = rng.standard_normal((3, 5000)) + 5 * np.exp(-0.5 * ((np.arange(5000) - 2500) / 80) ** 2)
    taps = gauss_taps(h_bins * 1e-12, 1e-12)
    out = device_runtime.to_numpy(device_runtime.gauss_filter(device_runtime.from_numpy(data), taps))
    twin = gauss_filter.numpy(data.astype(np.float32), taps)
    assert rel_err(out, twin) < 1e-5


def test_gauss_filter_taps_follow_eq24():
    taps = gauss_taps(0.65e-9, 10e-12)
    assert len(taps) == 2 * 65 + 1
    sigma = 0.65e-9 / 3
    assert taps[65] == pytest.approx(10e-12 / (np.sqrt(2 * np.pi) * sigma))
    # truncated at 3 sigma: the weights hold 99.73 % of the Gaussian
    assert taps.sum() == pytest.approx(0.9973, abs=2e-3)


def test_row_stats_and_awgn_match_twin(device_runtime):
    rng = np.random.default_rng(2)
    signal = np.abs(rng.standard_normal((4, 3000))).astype(np.float32)
    dev_signal = device_runtime.from_numpy(signal)
    normal = device_runtime.standard_normal(signal.shape, seed=5)
    stats = device_runtime.to_numpy(device_runtime.row_stats(dev_signal))
    np.testing.assert_allclose(stats, row_stats.numpy(signal.astype(np.float64)), rtol=1e-5)
    noisy = device_runtime.to_numpy(device_runtime.add_awgn(dev_signal, normal, 10.0))
    twin = add_awgn.numpy(signal.astype(np.float64), device_runtime.to_numpy(normal), 10.0)
    assert rel_err(noisy, twin) < 1e-5


def test_device_noise_is_standard_normal_and_seeded(device_runtime):
    a = device_runtime.to_numpy(device_runtime.standard_normal((3, 60000), seed=7))
    b = device_runtime.to_numpy(device_runtime.standard_normal((3, 60000), seed=7))
    c = device_runtime.to_numpy(device_runtime.standard_normal((3, 60000), seed=8))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert abs(a.mean()) < 0.01 and abs(a.std() - 1) < 0.01


@pytest.fixture(scope="module")
def filtered_paper(device_runtime):
    scene = nl.paper_scene(facet_size_m=0.02)
    axis = nl.TimeAxis(2 * 20 / nl.SPEED_OF_LIGHT, 10e-12, 6000)
    return nl.gauss_filter(nl.simulate(scene, axis, backend=device_runtime)).histograms()


GRIDS = {
    "plane": nl.Grid.from_ranges(x=(0, 6), y=(0.01, 6), step_m=0.02),
    "volume": nl.Grid((3.0, 1.0, -0.5), (0.05, 0.05, 0.05), (41, 41, 21)),
}


@pytest.mark.parametrize("log_mode", [False, True])
@pytest.mark.parametrize("grid_name", sorted(GRIDS))
def test_ellipse_score_matches_twin(filtered_paper, grid_name, log_mode, device_runtime,
                                    reference):
    grid = GRIDS[grid_name]
    maps = [nl.locate(filtered_paper, grid, log_mode=log_mode, return_map=True, backend=be,
                      estimator="paper")
            for be in (device_runtime, reference)]
    a, b = maps[0].score_map, maps[1].score_map
    assert a.shape == (grid.shape[2], grid.shape[1], grid.shape[0])
    if log_mode:  # log units: an absolute error, per detector 1e-3 relative -> 1e-3 in the log
        lit = b > np.log(1e-4) * 3
        assert np.abs(a - b)[lit].max() < 3e-3
    else:
        assert rel_err(a, b) < 1e-3
    assert np.linalg.norm(maps[0].position - maps[1].position) <= max(grid.step)


def test_argmax_first_maximum_wins(device_runtime, reference):
    score = np.zeros((1, 50, 70), np.float32)
    score[0, 10, 5] = score[0, 30, 60] = 3.0  # a tie: the lower flat index must win
    score[0, 40, 1] = 2.0
    dev = device_runtime.from_numpy(score)
    assert device_runtime.argmax(dev) == reference.argmax(score) == (10 * 70 + 5, 3.0)
