from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.ops.backend import NumpyBackend
from nlos_cl.ops.opencl_backend import get_runtime

C = nl.SPEED_OF_LIGHT
TESTS = Path(__file__).resolve().parent

# Tests of 10 s or more on the 2-core CI machine (full suite, 2026-12-06): `-m "not slow"` for
# a quick pass. By test function (every parametrization), measured seconds beside each.
SLOW = {
    "test_95_percent_region_covers_the_truth_90_to_98_percent_of_the_time",  # 35
    "test_notebook_runs",  # 26 (tracking.ipynb)
    "test_a_basin_the_lobe_search_finds_is_fitted_lambertian",  # 24 (alone, 2026-12-07)
    "test_a_short_crossing_run_writes_its_section",  # 19
    "test_two_runs_give_bit_identical_positions",  # 18
    "test_two_targets_keep_their_identities_through_a_crossing",  # 15
    "test_a_cached_plan_gives_each_frame_its_own_answer",  # 15
    "test_confocal_scan_depth_matches_a_backprojection",  # 14
    "test_counts_draw_165s_box_is_found_by_racing_the_filtered_frames_closed_fits",  # 14
    "test_draws_in_worker_processes_are_those_of_one_process",  # 12
    "test_quick_run_writes_every_section",  # 11
    "test_auto_finds_both_squares",  # 11
}
DEVICE_FIXTURES = {"runtime", "device_runtime"}


def pytest_collection_modifyitems(config, items):
    """The markers, by class rather than by hand: `device` where a test takes a runtime
    fixture (directly or through another fixture), `realdata` for tests/realdata/, `slow`
    from SLOW."""
    for item in items:
        if DEVICE_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.device)
        if TESTS / "realdata" in Path(item.path).parents:
            item.add_marker(pytest.mark.realdata)
        if getattr(item, "originalname", item.name) in SLOW:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def runtime():
    """The default device (PYOPENCL_CTX, else the best found)."""
    return get_runtime()


def _device_specs():
    from nlos_cl.device.devices import list_devices
    entries = list_devices()
    return [f"{e.platform_index}:{e.device_index}" for e in entries] or [None]


def _device_label(spec):
    from nlos_cl.device.devices import list_devices
    for e in list_devices():
        if spec == f"{e.platform_index}:{e.device_index}":
            return f"{spec}-{e.platform.name.split()[0]}"
    return str(spec)


@pytest.fixture(scope="session", params=_device_specs(), ids=_device_label)
def device_runtime(request):
    """Every OpenCL device this machine has, in turn (as pyopencl's own suite does): CI makes
    PoCL and Intel's CPU runtime visible together, so kernel tests run on both."""
    return get_runtime(request.param)


@pytest.fixture(scope="session")
def reference():
    return NumpyBackend()


def window_around(setup, target_mesh, dt_s, margin_m=0.5):
    """A time axis covering every hidden path the target can produce, plus a margin."""
    pts = target_mesh.vertices
    r1 = np.linalg.norm(pts - setup.laser_spot, axis=1)
    paths = r1[None, :] + np.linalg.norm(pts[None] - setup.detector_spots[:, None], axis=2)
    lo, hi = paths.min() - margin_m, paths.max() + margin_m
    t0 = (2 * setup.device_distance_m + lo) / C + setup.pulse.peak_delay_s
    return nl.TimeAxis(t0, dt_s, int(np.ceil((hi - lo) / (C * dt_s))))


def facing_rectangle(position, size=0.3, cell=0.01):
    """A square target at `position` turned towards the middle of the paper's wall spots."""
    p = np.asarray(position, float)
    normal = np.array([-0.75, 0.0, 0.0]) - p
    normal[2] = 0.0
    return nl.rectangle(size, size, centre=p, normal=normal, cell_m=cell)


def paper_frame(runtime, snr_db=10.0, seed=3, truth=(4.0, 2.0, 0.0)):
    """(filtered, raw) of one noisy frame of the paper's 0.3 x 1.6 m plate at `truth`."""
    mesh = nl.rectangle(0.3, 1.6, centre=truth)
    raw = nl.add_noise(nl.simulate(nl.Scene(nl.paper_setup(), nl.Target(mesh), truth=truth),
                                   backend=runtime), snr_db, seed=seed)
    return nl.gauss_filter(raw), raw


def circle_frame(runtime, mesh, grid, seed, snr_db=10.0):
    """A model-ready frame of `mesh` (2 cm cells) seen by 8 spots on a 0.5 m circle about
    (-1, 0, 0), 10 ps bins: (Scored over `grid`, its cold one-target model answer)."""
    import warnings

    from nlos_cl.localization.estimate import Scored
    from nlos_cl.localization.model import ModelEstimator
    from nlos_cl.physics import layouts
    setup = nl.paper_setup(detector_spots=layouts.circle((-1.0, 0.0, 0.0), 0.5, 8))
    scene = nl.Scene(setup, nl.Target(mesh), 0.02)
    raw = nl.add_noise(nl.simulate(scene, nl.default_time_axis(setup, 10e-12),
                                   backend=runtime), snr_db, seed=seed)
    filtered = nl.gauss_filter(raw)
    scores = nl.Locator(filtered, grid, estimator="model").scores(filtered)
    scored = Scored(filtered.backend, scores, grid, False, filtered.n_detectors, filtered, raw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return scored, ModelEstimator(targets=1).estimate(scored).targets[0]


def model_observation(filtered, raw):
    """The model estimator's Observation of a frame, handed over without a score map."""
    from nlos_cl.localization.estimate import Scored
    from nlos_cl.localization.model import ModelEstimator
    return ModelEstimator().observation(Scored(filtered.backend, None, nl.Grid(), False,
                                               filtered.n_detectors, filtered, raw))


@pytest.fixture(scope="session")
def walk_file(tmp_path_factory):
    """12 frames (10 fps, 10 dB) of a plate walking 1.1 m on the paper's setup, as a file."""
    from nlos_cl.tracking import MovingTarget, Trajectory, simulate_sequence
    setup = nl.paper_setup()
    walk = Trajectory([0, 1.2], [[3, 1.5, 0], [3.5, 2.5, 0]])
    target = MovingTarget(nl.Target(nl.rectangle(centre=walk.at(0), cell_m=0.03)), walk)
    frames = simulate_sequence(setup, target, n_frames=12, fps=10, noise=nl.AWGN(10), seed=0,
                               facet_size_m=0.03, time_axis=nl.default_time_axis(setup, 1e-11))
    return nl.write_sequence(tmp_path_factory.mktemp("walk") / "walk.h5", frames)


@pytest.fixture(scope="session")
def squares_capture():
    """squares_capture(positions, seed): 0.3 m squares at `positions` seen by 8 spots on a
    0.5 m circle, 10 ps bins, 10 dB (docs/scenes/two_squares.yaml's setup), as histograms."""
    def make(positions, seed):
        from nlos_cl.physics import layouts
        setup = nl.paper_setup(detector_spots=layouts.circle((-1.0, 0.0, 0.0), 0.5, 8))
        targets = [nl.Target(nl.rectangle(centre=p, width_m=0.3, height_m=0.3,
                                          normal=(-1.0, -0.6, 0.0), cell_m=0.02))
                   for p in positions]
        scene = nl.Scene(setup, targets[0], 0.02, more_targets=tuple(targets[1:]))
        return nl.add_noise(nl.simulate(scene, nl.default_time_axis(setup, 10e-12)), 10.0,
                            seed=seed).histograms()
    return make
