"""A warm fit that spends its whole budget (warm_nfev) and still misses the data is continued
from where it stopped (model.policy.warm.CONTINUE_NFEV) before the cold fit is asked for:
docs/scenes/walk.yaml's frame 1 (a plate moved 0.1 m from a start with no velocity yet)
stopped 0.05 m short after 10 evaluations and went cold (1.6 s CPU, the closed search) for
the plate the continued fit finds in 3 more. No timings: evaluations and forward calls."""
import warnings

import numpy as np
import pytest
from conftest import circle_frame

import nlos_cl as nl
from nlos_cl.localization.estimate import Prior
from nlos_cl.localization.model import ModelEstimator

GRID = nl.Grid.from_ranges(x=(1.5, 4.5), y=(0.5, 3.5), step_m=0.02)


@pytest.fixture(scope="module")
def walk_frame(runtime):
    """(scored, cold answer): walk.yaml's 0.3 x 1.6 m plate at (3, 1.6), 8 spots, 10 dB."""
    return circle_frame(runtime, nl.rectangle(0.3, 1.6, centre=(3.0, 1.6, 0.0), cell_m=0.02),
                        GRID, seed=3)


def test_a_warm_fit_out_of_budget_is_continued_not_refitted_cold(walk_frame):
    scored, cold = walk_frame
    assert cold.fit.shape == "plate"
    row = np.array(cold.fit.values())
    behind = row.copy()
    behind[1] -= 0.1  # where the plate was a frame (0.1 s at 1 m/s) before
    estimator = ModelEstimator(targets=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        warm = estimator.estimate(scored, Prior(behind[None], misfit=cold.fit.birge_ratio))
    start = warm.targets[0].fit.warm_start
    assert start.used and start.nfev > estimator.warm_nfev  # continued past its budget
    found = warm.targets[0]
    sd = np.sqrt(np.diag(cold.covariance)[:2])
    assert np.all(np.abs(found.position[:2] - cold.position[:2]) < 2 * sd)
