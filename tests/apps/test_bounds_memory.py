"""Issue 24: memory is bounded in every input and no input hangs. Each class of hostile input
is refused up front (InputError naming the field) or runs bounded: pulses far shorter than a
bin or longer than the axis, huge spot, frame, run and target counts, scenes of many targets,
a --scheduler that is not Dask, maps and videos of huge regions, and the memory budget itself
(NLOS_CL_MEMORY_LIMIT, ulimit -v)."""
import argparse
import socket
import subprocess
import sys
import threading

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core import limits
from nlos_cl.ops import forward, pulse

from conftest import window_around


def refused(field, call, *args, **kw):
    with pytest.raises(nl.InputError) as info:
        call(*args, **kw)
    text = str(info.value)
    assert text.startswith(field) and "Fix:" in text and "\n" not in text, text
    return text


# ------------------------------------------------------------------ the memory budget

def test_memory_limit_follows_the_environment_variable(monkeypatch):
    monkeypatch.setenv(limits.MEMORY_LIMIT_ENV, "1.5M")
    assert limits.memory_limit() == int(1.5 * 2**20)
    text = refused("grid", limits.require_memory, "grid", 2**21, "a test map", "smaller")
    assert "set by NLOS_CL_MEMORY_LIMIT" in text
    monkeypatch.setenv(limits.MEMORY_LIMIT_ENV, "lots")
    refused("NLOS_CL_MEMORY_LIMIT", limits.memory_limit)
    monkeypatch.delenv(limits.MEMORY_LIMIT_ENV)
    assert 0 < limits.memory_limit()


def test_memory_limit_respects_an_address_space_limit():
    code = "from nlos_cl.core.limits import _budget; print(*_budget(), sep='|')"
    out = subprocess.run(["bash", "-c", f"ulimit -v 2000000; {sys.executable} -c \"{code}\""],
                         capture_output=True, text=True, timeout=60, check=True).stdout
    budget, why = out.strip().split("|")
    assert int(budget) < 2000000 * 1024 // 2 and "ulimit -v" in why


# ------------------------------------------------------------------ pulses

def small_scene(fwhm_s):
    return nl.paper_scene(facet_size_m=0.05, pulse=nl.Pulse(fwhm_s=fwhm_s))


def test_deposit_runs_only_where_its_buffers_stay_small():
    step = nl.SPEED_OF_LIGHT * 1e-12  # 1 ps bins
    assert pulse.binning("deposit", step, nl.SPEED_OF_LIGHT * 29.7e-12) == "deposit"
    for sigma_s in (1e-15, 1e-9):  # 56,600 sub-bins per bin; 7,200 taps
        assert pulse.binning("deposit", step, nl.SPEED_OF_LIGHT * sigma_s) == "erf"
    assert pulse.binning("erf", step, nl.SPEED_OF_LIGHT * 29.7e-12) == "erf"


@pytest.mark.parametrize("fwhm_s", [1e-15, 0.2e-15])
def test_a_pulse_far_shorter_than_a_bin_is_bin_integrated_exactly(runtime, reference, fwhm_s):
    scene = small_scene(fwhm_s)
    axis = window_around(scene.setup, scene.target.mesh, 2e-12)
    args = forward.scene_inputs(scene, axis)
    device = runtime.to_numpy(runtime.call("forward", *args, "deposit")[0])
    twin = reference.call("forward", *args, "deposit")[0]
    # Each facet puts 2 w into the bin holding its path (erf differences of 0 or 2), so the
    # energies agree, and so does where it lands, but for facets whose float32 path (~1e-6 m,
    # far more than sigma) lies on a bin edge: they may move one bin, or at a 15-bin block's
    # edge (rounded once per block) count 0 or 2 times. Allow two facets' energy per detector.
    facets = args[0]
    _, weight = forward.facet_paths(facets.centres, facets.normals, facets.areas, args[1],
                                    args[2])
    one_facet = 2.0 * weight.max(axis=1)
    assert np.all(np.abs(device.sum(axis=1) - twin.sum(axis=1)) <= 2 * one_facet)
    assert np.all(np.abs(np.cumsum(device - twin, axis=1)).max(axis=1) <= 2 * one_facet)
    assert np.all(one_facet < 0.01 * twin.sum(axis=1))  # so the check has teeth


def test_a_pulse_longer_than_the_axis_costs_the_axis_in_the_twin():
    sigma, n_bins = 1e5, 50  # 100 km of path on a 50 bin axis: 1.2e7 bins of reach
    path, weight = np.array([[10.0, 10.4]]), np.array([[1.0, 2.0]])
    hist = pulse.pulse_bins(path, weight, np.array([9.0]), np.array([0.03]), sigma, n_bins)
    from scipy.special import erf
    edges = 9.0 + 0.03 * np.arange(n_bins + 1)
    want = sum(w * np.diff(erf((edges - s) / (np.sqrt(2) * sigma))) for s, w in
               zip(path[0], weight[0]))
    np.testing.assert_allclose(hist[0], want, rtol=1e-9)


def test_simulate_refuses_a_pulse_longer_than_the_time_axis(reference):
    refused("setup.pulse.fwhm_s", nl.simulate, small_scene(1e-3), backend=reference)


def test_the_forward_model_splits_detectors_to_fit_the_budget(runtime, monkeypatch):
    scene = small_scene(70e-12)
    axis = window_around(scene.setup, scene.target.mesh, 10e-12)
    args = forward.scene_inputs(scene, axis)
    whole = runtime.to_numpy(runtime.call("forward", *args)[0])
    n_pad = -(-args[0].count // forward.FACET_CHUNK) * forward.FACET_CHUNK
    method, passes = forward.plan_passes(runtime, 3, n_pad, axis.n_bins, args[5], args[4],
                                          "deposit")
    assert method == "deposit" and passes == [(0, 3)]
    os_, half = pulse.deposit_sizes(float(np.max(args[4])), args[5])
    one_detector = 8 * n_pad + 12 * os_ * (axis.n_bins + 2 * half + 32)
    monkeypatch.setenv(limits.MEMORY_LIMIT_ENV, str(one_detector))
    assert forward.plan_passes(runtime, 3, n_pad, axis.n_bins, args[5], args[4],
                                "deposit")[1] == [(0, 1), (1, 2), (2, 3)]
    np.testing.assert_array_equal(runtime.to_numpy(runtime.call("forward", *args)[0]), whole)
    monkeypatch.setenv(limits.MEMORY_LIMIT_ENV, str(one_detector // 2))
    refused("facet_size_m", runtime.call, "forward", *args)


def test_photon_jitter_is_bounded_and_exact():
    from scipy.ndimage import gaussian_filter1d

    from nlos_cl.physics.noise import _jitter
    signal = np.random.default_rng(1).random((2, 2000))
    axis = nl.TimeAxis(0.0, 1e-12, 2000)
    for sigma in (3.0, 400.0, 1999.0):  # direct, then FFT
        np.testing.assert_allclose(_jitter(signal, sigma, axis),
                                   gaussian_filter1d(signal, sigma, axis=1, mode="constant"),
                                   rtol=1e-7, atol=1e-12)
    refused("photon_counter.jitter_s", _jitter, signal, 1e9, axis)


# ------------------------------------------------------------------ counts

def test_wall_spot_counts_are_capped_before_any_array():
    refused("line.count", nl.layouts.line, [0, 0, 0], [-1, 0, 0], 10**9)
    refused("circle.count", nl.layouts.circle, [0, 0, 0], 1.0, 10**9)
    refused("spad_patch.counts", nl.layouts.spad_patch, [0, 0, 0], (100_000, 100_000))
    assert len(nl.layouts.line([0, 0, 0], [-1, 0, 0], 1000)) == 1000


def test_sequence_frame_counts_are_capped(reference):
    from nlos_cl.tracking import MovingTarget, Trajectory, simulate_sequence
    moving = MovingTarget(nl.Target(nl.rectangle()), Trajectory([0, 1], [[3, 2, 0], [4, 2, 0]]))
    refused("n_frames", simulate_sequence, nl.paper_setup(), moving, n_frames=10**8, fps=10,
            backend=reference)
    refused("fps", simulate_sequence, nl.paper_setup(), moving, n_frames=10, fps=1e-310,
            backend=reference)


def test_fitted_targets_are_capped_by_what_the_histograms_determine():
    limits.require_targets("targets", 6, n_histograms=3)
    refused("targets", limits.require_targets, "targets", 7, n_histograms=3)
    refused("--targets", limits.require_targets, "--targets", limits.MAX_TARGETS + 1)


@pytest.mark.parametrize("argv, field", [
    (["simulate", "s.yaml", "--out", "x.h5", "--frames", "100000000"], "frames"),
    (["simulate", "s.yaml", "--out", "x.h5", "--frames", "2", "--fps", "1e-310"], "fps"),
    (["locate", "c.h5", "--targets", "50"], "targets"),
    (["locate", "c.h5", "--targets", "100000"], "targets"),
    (["track", "s.h5", "--targets", "1000"], "targets"),
    (["track", "s.h5", "--accel", "1e300"], "accel")])
def test_cli_ranges(argv, field, capsys):
    from nlos_cl.apps.cli import parser
    with pytest.raises(SystemExit) as info:
        parser().parse_args(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(err) == 1 and f" {field}: must be" in err[0]


def test_a_study_of_too_many_runs_is_refused_before_any_scene(tmp_path):
    from nlos_cl.sweep import sweep
    study = {"scene": {"targets": [{"shape": "rectangle", "position": [4, 2, 0]}]},
             "axes": [{"path": "targets[0].position[0]", "name": "x",
                       "range": {"start": 2, "stop": 4, "num": 100_000}},
                      {"path": "targets[0].position[1]", "name": "y",
                       "range": {"start": 2, "stop": 4, "num": 100_000}}], "seeds": 100}
    text = refused("study", sweep, study, tmp_path / "out", workers=0, progress=False)
    assert "1,000,000,000,000 runs" in text


def test_a_scene_of_too_many_targets_is_refused():
    targets = [nl.Target(nl.rectangle(0.1, 0.1, centre=(1 + 0.2 * i, 2, 0), cell_m=0.1))
               for i in range(limits.MAX_SCENE_TARGETS + 1)]
    refused("scene.more_targets", nl.Scene, nl.paper_setup(), targets[0],
            more_targets=tuple(targets[1:]))


def test_many_targets_visibility_is_one_pass_and_matches_per_target():
    from nlos_cl.physics.visibility import any_hit_brute, scene_visibility, visibility
    setup = nl.paper_setup(detector_spots=[[-0.3, 0, 0.0], [0.3, 0, 0.0]])
    meshes = [nl.rectangle(0.6, 0.6, centre=(0.0, 1.0, 0.0), normal=(0, -1, 0), cell_m=0.05),
              nl.box((0.2, 0.2, 0.2), (0.1, 1.8, 0.0), 0.05),
              nl.rectangle(0.3, 0.3, centre=(0.5, 2.5, 0.2), normal=(0, -1, 0), cell_m=0.05)]
    scene = nl.Scene(setup, nl.Target(meshes[0]), 0.05,
                     more_targets=tuple(nl.Target(m) for m in meshes[1:]))
    facets = [scene.facets(i) for i in range(3)]
    joint = scene_visibility(facets, setup.laser_spot, setup.detector_spots, meshes,
                             caster=any_hit_brute)
    for i in range(3):
        own = visibility(facets[i], setup.laser_spot, setup.detector_spots, meshes, i,
                         caster=any_hit_brute)
        np.testing.assert_array_equal(joint[i], own)
        np.testing.assert_array_equal(scene.visibility(i), own)  # embree, cached for all
    assert not joint[1].all() and joint[0].any()  # the plate shadows the box


# ------------------------------------------------------------------ scheduler, maps, video

def test_a_scheduler_that_is_not_dask_is_one_line_in_seconds(monkeypatch):
    from nlos_cl.sweep import engine
    monkeypatch.setattr(engine, "CONNECT_S", 0.5)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    held = []
    threading.Thread(target=lambda: held.append(server.accept()), daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        assert "is not a Dask scheduler" in refused("--scheduler", engine._probe, address)
        server.close()
        refused("--scheduler", engine._probe, address)  # nothing listens: refused, at once
    finally:
        server.close()
        for conn, _ in held:
            conn.close()


def test_a_map_of_a_huge_region_is_refused_before_locating(tmp_path):
    from nlos_cl.apps.locate_map import check_map_path as _check_map_path
    args = argparse.Namespace(map=str(tmp_path / "m.npz"), force=False, step=0.001,
                              region=[-30, 30, -0.001, 0.001, 0.001, 30])
    refused("--region", _check_map_path, args)


def test_the_video_map_is_pooled_to_what_the_figure_shows():
    from nlos_cl.apps.track_video import MAX_PIXELS, pooled, pooled_shape
    scores = np.random.default_rng(2).random((2500, 3001))
    scores[1234, 2999] = 5.0
    small = pooled(scores)
    assert small.shape == pooled_shape(scores.shape) and max(small.shape) <= MAX_PIXELS
    assert small.max() == 5.0 and small.min() >= 0.0
    assert pooled(scores[:100, :100]).shape == (100, 100)  # small maps as they are
