"""simulate -> 10 dB noise -> Gauss filter -> locate recovers known positions."""
import numpy as np
import pytest

import nlos_cl as nl
from conftest import facing_rectangle

GRID = nl.Grid()  # the paper's search plane: x in [0, 6], y in (0, 6], 1 cm


@pytest.fixture(scope="module")
def paper_signals(runtime):
    return nl.simulate(nl.paper_scene(), backend=runtime)


@pytest.mark.parametrize("seed", range(5))
def test_paper_scene_located_within_5cm_at_10db(paper_signals, seed):
    loc = nl.locate(nl.gauss_filter(nl.add_noise(paper_signals, 10.0, seed)), GRID,
                    estimator="paper")
    assert loc.error_m < 0.05, loc.position


# Near-grazing positions (x >= 4, y ~ 1, where all ellipses meet at shallow angles) carry a
# systematic 0.05-0.06 m bias for a 0.3 m target: see test_paper_5x5_grid_within_paper_tolerance.
@pytest.mark.parametrize("position", [(2.0, 3.0, 0.0), (4.5, 3.5, 0.0), (1.0, 4.5, 0.0)])
def test_small_target_elsewhere_located_within_5cm(runtime, position):
    scene = nl.Scene(nl.paper_setup(), nl.Target(facing_rectangle(position)), 0.01,
                     truth=position)
    signals = nl.simulate(scene, backend=runtime)
    errors = [nl.locate(nl.gauss_filter(nl.add_noise(signals, 10.0, seed)), GRID,
                        estimator="paper").error_m
              for seed in range(5)]
    assert max(errors) < 0.05, errors


def test_reference_backend_runs_the_same_pipeline(reference, runtime):
    scene = nl.paper_scene(facet_size_m=0.02)
    axis = nl.TimeAxis(2 * 20 / nl.SPEED_OF_LIGHT + 28e-9, 10e-12, 900)
    grid = nl.Grid.from_ranges(x=(3, 5), y=(1, 3), step_m=0.01)
    locs = [nl.locate(nl.gauss_filter(nl.simulate(scene, axis, backend=be)), grid,
                      estimator="paper")
            for be in (runtime, reference)]
    assert np.linalg.norm(locs[0].position - locs[1].position) < 0.005
    assert locs[0].error_m < 0.05


def test_measured_style_histograms_locate(runtime):
    """Host data in watts (~1e-20 W), uploaded: normalisation keeps float32 in range."""
    sim = nl.simulate(nl.paper_scene(), backend=runtime).histograms()
    tiny = sim.with_data(sim.data * 1e-7)
    loc = nl.locate(nl.gauss_filter(tiny, backend=runtime), GRID, estimator="paper")
    assert loc.error_m < 0.05


def test_sum_of_logs_mode_locates_with_many_detectors(runtime):
    spots = [[x, 0.0, z] for x in np.linspace(-1.5, -0.3, 8) for z in (-0.3, 0.3)]
    setup = nl.paper_setup(detector_spots=spots)
    scene = nl.Scene(setup, nl.Target(nl.rectangle()), 0.01, truth=(4.0, 2.0, 0.0))
    signals = nl.gauss_filter(nl.add_noise(nl.simulate(scene, backend=runtime), 10.0, 1))
    loc = nl.locate(signals, GRID, log_mode=True, estimator="paper")
    assert loc.error_m < 0.05


def test_paper_5x5_grid_within_paper_tolerance(runtime):
    """Paper Fig. 10 setting with a 0.3 m square target: the paper's filter reaches mean
    0.0684 m and max < 0.12 m; we must do at least as well (measured: mean 0.022, max 0.061)."""
    errors = []
    for x in range(1, 6):
        for y in range(1, 6):
            pos = (float(x), float(y), 0.0)
            scene = nl.Scene(nl.paper_setup(), nl.Target(facing_rectangle(pos)), 0.01, truth=pos)
            noisy = nl.add_noise(nl.simulate(scene, backend=runtime), 10.0, seed=x * 10 + y)
            errors.append(nl.locate(nl.gauss_filter(noisy), GRID, estimator="paper").error_m)
    assert np.mean(errors) <= 0.0684 and max(errors) < 0.12, errors
