"""Several targets where one is far weaker than the others (issue 22): non-negative amplitudes,
a sample window that keeps a target at 1 % of the peak, starts from the residual's
backprojection, and 'auto' keeping a weak target that lies apart from the others.

The frame: three 0.26-0.39 m plates seen from 6 spots on a 0.4 m circle at 12 dB, the far one
(2.63, 4.38) 2.4x as far as the near one: it returns 2-11 % of the near one's peak and 1/430
of its energy (the scene of a random draw of `reproduce draws`, multi index 11, where one
plate was 8.3 m off). With this noise seed and only 3 residual starts, the far plate was
1.8 m off; with 8 (select.RESIDUAL_STARTS), 8 of 8 seeds within 0.12 m (sd ~0.075 m)."""
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.model.forward.data import TARGETS_FRAC, signal_windows
from nlos_cl.localization.model.forward.likelihood import nonnegative_lstsq
from nlos_cl.localization.model.policy.criteria import separate
from nlos_cl.localization.model.policy.starts import MAX_AMPLITUDE_RATIO, plausible

# what the draws' scenes read of `reproduce draws`' full settings: facet size and time bin
DRAWS_SETTINGS = SimpleNamespace(facet_m=0.01, dt_s=1e-12)

SPOTS = [[-0.880, 0.0, -0.932], [-0.343, 0.0, -0.711], [-0.266, 0.0, -0.135],
         [-0.726, 0.0, 0.219], [-1.263, 0.0, -0.002], [-1.340, 0.0, -0.577]]
PLATES = (((2.626, 4.384, 0.167), 0.387, 0.317, 19.97),
          ((-1.241, 1.829, -0.154), 0.259, 0.273, -24.54),
          ((-2.371, 2.114, 0.454), 0.349, 0.349, -20.94))


def _plate(centre, width, height, yaw_deg):
    """An upright plate turned yaw_deg from facing the wall (normal -y)."""
    a = np.radians(yaw_deg)
    normal = (np.sin(a), -np.cos(a), 0.0)
    return nl.Target(nl.rectangle(width, height, centre=centre, normal=normal, cell_m=0.01))


@pytest.fixture(scope="module")
def frame():
    setup = nl.paper_setup(detector_spots=SPOTS)
    first, *rest = [_plate(*p) for p in PLATES]
    scene = nl.Scene(setup, first, truth=PLATES[0][0], more_targets=tuple(rest))
    clean = nl.simulate(scene, nl.default_time_axis(setup, 1e-12)).histograms()
    return nl.add_noise(clean, 12.0, seed=4).histograms()


def _errors(found) -> list[float]:
    return sorted(min(np.linalg.norm(np.subtract(f, p[0])) for f in found) for p in PLATES)


@pytest.mark.parametrize("targets", [3, "auto"])
def test_the_weak_far_plate_is_found(frame, targets):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loc = nl.locate_capture(frame, targets=targets).points[0].location
    found = [t.position for t in loc.targets]
    assert len(found) == 3
    # each truth has a fitted plate near it: the two near ones within 0.02 m, the far one
    # (1/430 of the energy; its sd is ~0.075 m along x) within 0.15 m
    errors = _errors(found)
    assert errors[1] < 0.02 and errors[2] < 0.15
    assert all(t.fit.amplitude > 0 for t in loc.targets)


def test_the_window_keeps_a_target_at_one_percent_of_the_peak_when_there_are_several():
    row = np.zeros(4000)
    row[1000:1010] = 100.0  # the strong target
    row[3000:3010] = 1.0  # 1 % of its peak, far above the noise
    (first, last), = signal_windows(row[None], np.array([0.01]), margin_bins=5,
                                    frac=TARGETS_FRAC)
    assert first <= 995 and last >= 3014
    (first, last), = signal_windows(row[None], np.array([0.01]), margin_bins=5)
    assert last < 1100  # one target: its main lobe (ONE_TARGET_FRAC)


@pytest.mark.parametrize("k", [1, 2, 3, 5, 8])
def test_nonnegative_amplitudes_match_scipy_nnls(k):
    from scipy.optimize import nnls
    rng = np.random.default_rng(k)
    for _ in range(50):
        a = rng.normal(size=(k, 40)) * rng.uniform(1e-3, 1e3, size=(k, 1))  # any units
        b = rng.normal(size=40)
        got = nonnegative_lstsq(a @ a.T, a @ b)
        ref = nnls(a.T, b)[0]
        assert np.all(got >= 0)
        cost = lambda x: float(np.sum((a.T @ x - b) ** 2))  # noqa: E731
        # both are exact solvers of the same convex problem: equal optimum to rounding (the
        # enumeration up to 6 targets); coordinate descent (8) to 1e-9 of the cost
        assert cost(got) <= cost(ref) * (1 + 1e-9) + 1e-12


def test_plates_that_touch_are_not_separate_objects():
    face = [0.0, 3.0, 0.0, 0.6, 0.6, 0.0]
    side = [0.35, 3.3, 0.0, 0.6, 0.6, 1.57]  # a box's second face, corner to corner
    far = [2.0, 4.0, 0.0, 0.4, 0.4, 0.0]
    assert not separate([face, side])
    assert separate([face, far])
    assert not separate([face, far, side])


def test_amplitudes_of_one_frame_stay_within_a_ratio_of_reflectances():
    ratio = MAX_AMPLITUDE_RATIO
    assert plausible([1.0, 0.5 * ratio], 2)
    assert not plausible([1.0, 2.0 * ratio], 2)
    assert plausible([0.0, 1.0, 3.0], 3)  # a zero amplitude is the fit's report, not this test
    assert plausible([5.0, 1e9, 2.0], 1)  # one target, then the backgrounds (Poisson): no ratio


# `reproduce draws` multi scenes, simulated and noised as the draws are (regression cases: the
# same scenes with nl.add_noise's noise were found by the greedy search alone).
# 60: two plates 3.7 m apart, 7 spots on a 0.35 m circle, 10.2 dB: the greedy search's one
# plate, fitted to both targets' signals, ran off to a 0.04 x 1.8 m sliver costing 10^4 x the
# truth's, and the second plate died at amplitude 0: both 2.4 m off.
# 55: three plates, 7 spots, 6.9 dB: one plate spread into a 3.0 x 0.04 m sliver 1 m from its
# target (re-seating each plate in turn reached it only once the re-added plate kept its
# place in the order: before, the same plate was dropped twice and the sliver never).
@pytest.mark.parametrize("index", [60, 55])
def test_a_plate_the_joint_fit_left_dead_or_misplaced_is_reseated_from_the_residual(index):
    from nlos_cl.simulation.draws import families, scenes
    d = families.draw("multi", index, master_seed=2201)
    frame = scenes.noisy(scenes.simulate(d, DRAWS_SETTINGS)[0], d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loc = nl.locate_capture(frame, targets=len(d["targets"])).points[0].location
    found = [t.position for t in loc.targets]
    errors = sorted(min(np.linalg.norm(np.subtract(f, t["centre"])) for f in found)
                    for t in d["targets"])
    assert errors[-1] < 0.02, errors
    assert all(t.fit.birge_ratio < 1.5 for t in loc.targets)  # the fit explains the data


def test_dead_plates_are_those_at_zero_amplitude_or_a_negligible_share_of_the_energy():
    from nlos_cl.localization.model.solve.fit import FitResult
    from nlos_cl.localization.model.policy.criteria import DEAD_SHARE, dead_plates

    class Columns:  # three plates' columns: unit energy each
        def columns(self, params):
            return np.ones((len(params), 2, 5)) / np.sqrt(10.0)

    params = np.zeros((3, 6))
    alive = FitResult(params, np.array([1.0, 0.5, 0.05]), 0.0, 10, 0)
    assert not dead_plates(Columns(), alive).any()  # 1/400 of the energy is a far target
    zero = FitResult(params, np.array([1.0, 0.0, 0.5]), 0.0, 10, 0)
    assert dead_plates(Columns(), zero).tolist() == [False, True, False]
    faint = FitResult(params, np.array([1.0, 0.5 * np.sqrt(DEAD_SHARE), 0.5]), 0.0, 10, 0)
    assert dead_plates(Columns(), faint).tolist() == [False, True, False]
