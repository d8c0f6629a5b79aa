"""Warm starts of closed shapes (model.policy.warm.closed_warm_fit, Prior.shape / .late): a
tracked box or person is warm-fitted in its own family, with the late copies its cold fit
kept, instead of from a plate that misses a closed object's data (every such frame went
cold: 3-8 s a frame on 2 cores). No timings: forward-call counts."""
import warnings

import numpy as np
import pytest
from conftest import circle_frame

import nlos_cl as nl
from nlos_cl.localization.estimate import Prior
from nlos_cl.localization.model import ModelEstimator

GRID = nl.Grid.from_ranges(x=(1.5, 4.5), y=(1.0, 4.0), step_m=0.02)


@pytest.fixture(scope="module")
def box_frame(runtime):
    """(scored, cold answer) of a 0.5 x 0.5 x 1 m box 2.6 m out, 8 spots on a 0.5 m circle."""
    return circle_frame(runtime, nl.box((0.5, 0.5, 1.0), centre=(2.8, 2.6, 0.0), cell_m=0.02),
                        GRID, seed=1)


def _warm(scored, prior):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ModelEstimator(targets=1).estimate(scored, prior).targets[0]


def test_a_closed_target_is_warm_fitted_in_its_family(box_frame):
    scored, cold = box_frame
    assert cold.fit.shape in ("box", "ellipsoid", "cylinder")  # the data ask for depth
    late = bool(cold.fit.diagnostics.get("late_kept"))
    row = np.array(cold.fit.values())
    near = row + np.array([0.02, -0.02, 0, 0, 0, 0, 0])
    warm = _warm(scored, Prior(near[None], shape=cold.fit.shape, misfit=cold.fit.birge_ratio,
                               late=late))
    assert warm.fit.warm_start.used and warm.fit.shape == cold.fit.shape
    sd = np.sqrt(np.diag(cold.covariance)[:2])
    assert np.all(np.abs(warm.position[:2] - cold.position[:2]) < 2 * sd)
    assert warm.fit.timings_s["forward_calls"] < cold.fit.timings_s["forward_calls"] / 5
    # the same start as a plate (the tracker's old warm start) misses and goes cold
    front = np.array([*row[:3], row[3], row[4], row[6]])
    as_plate = _warm(scored, Prior(front[None], misfit=cold.fit.birge_ratio))
    assert not as_plate.fit.warm_start.used


def test_closed_start_rows_are_checked(box_frame):
    scored, _ = box_frame
    with pytest.raises(nl.InputError, match="start"):
        _warm(scored, Prior(np.ones((1, 6)), shape="cylinder"))  # a plate's row for a cylinder
    with pytest.raises(nl.InputError, match="start"):
        _warm(scored, Prior(np.ones((1, 7)), shape="sphere"))  # no such family
