"""The warm fit's solver variables (model.width_vectors.WidthVectors): each plate's (width, yaw) stepped
as its width vector. The map and its Jacobians are checked against each other and against
finite differences; a fit in them reaches the optimum of a fit in (width, yaw), and on the
stream bench's valley frame (a noise draw whose fit from the previous draw's plate crawled
along the width-yaw valley) it gets there in fewer model calls."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization.model import ModelEstimator
from nlos_cl.localization.model.shapes import plate
from nlos_cl.localization.model.solve.fit import _Objective, fit
from nlos_cl.localization.model.solve.width_vectors import WidthVectors

ROWS = np.array([[4.0, 2.0, 0.0, 0.31, 1.55, -3.12], [2.5, 3.0, 0.2, 0.5, 0.8, 0.7]])


class _Problem:  # what _Objective reads of a problem before any evaluation
    shape = plate


def _variables():
    free = np.array([True, True, False, True, True, True])
    obj = _Objective(_Problem(), ROWS, free)
    return WidthVectors.of(obj), obj.start()[0]


def test_the_map_round_trips_and_its_jacobians_are_inverse_and_exact():
    v, theta = _variables()
    assert len(v.pairs) == 2  # both plates: width and yaw free
    phi = v.to_phi(theta)
    np.testing.assert_allclose(v.to_theta(phi), theta, atol=1e-12)
    for w, a in v.pairs:  # e = w (-sin a, cos a): |e| is the width
        assert np.isclose(np.hypot(phi[w], phi[a]), theta[w])
    np.testing.assert_allclose(v.dtheta_dphi(phi) @ v.dphi_dtheta(theta), np.eye(len(theta)),
                               atol=1e-12)
    step = 1e-6  # central differences of to_theta: error ~ step^2
    numeric = np.stack([(v.to_theta(phi + step * e) - v.to_theta(phi - step * e)) / (2 * step)
                        for e in np.eye(len(phi))], axis=1)
    np.testing.assert_allclose(v.dtheta_dphi(phi), numeric, atol=1e-8)


def test_the_yaw_stays_within_pi_of_its_start_and_the_width_in_its_bounds():
    v, theta = _variables()
    w, a = v.pairs[0]
    phi = v.to_phi(theta)
    turned = phi.copy()  # the same vector a full turn on: the yaw does not wrap to +pi
    assert abs(v.to_theta(turned)[a] - theta[a]) < 1e-12
    shrunk = phi.copy()
    shrunk[[w, a]] *= 1e-3  # |e| below the lower bound: the model sees the bound
    assert v.to_theta(shrunk)[w] == plate.LOWER[plate.WIDTH]


def test_no_pair_no_variables():
    held_yaw = np.array([True, True, False, True, True, False])
    assert WidthVectors.of(_Objective(_Problem(), ROWS, held_yaw)) is None


@pytest.fixture(scope="module")
def valley():
    """The stream bench's frames (simulation.stream: the paper's scene, 3 x 4,096 bins, 10 dB,
    noise seed 0): copy 2 fitted from copy 1's fitted plate, the case that crawled."""
    from nlos_cl.simulation.stream import stream_frames
    from nlos_cl.localization.filter import GaussFilter
    from nlos_cl.ops.signals import upload
    rt = nl.resolve_backend(None)
    clean, frames = stream_frames(rt)
    gauss, est = GaussFilter(time_axis=clean.time_axis), ModelEstimator()

    def observed(i):
        raw = upload(frames[i], rt)
        scored = nl.localization.estimate.Scored(rt, None, nl.Grid(), False, 3, gauss(raw), raw)
        return est.problem(est.observation(scored), rt)
    return observed(2), np.array([[3.9955, 2.0171, 0.0, 0.2499, 1.5174, -3.2367]])


def test_a_fit_in_width_vectors_goes_down_the_valley_in_fewer_calls(valley):
    problem, start = valley
    free = np.array([True, True, False, True, True, True])
    from nlos_cl.localization.model.policy.warm import WARM_ATOL, WARM_TAU
    runs = {}
    for vectors in (False, True):
        calls = problem.calls
        result = fit(problem, start, free, 30, tau=WARM_TAU, atol=WARM_ATOL,
                     width_vectors=vectors)
        runs[vectors] = (result, problem.calls - calls)
    (old, old_calls), (new, new_calls) = runs[False], runs[True]
    # both stop once a step would gain < WARM_ATOL of cost (chi^2 / 2): the same optimum on
    # that scale (see below)
    assert (new.cost - old.cost) / 2 < 2 * WARM_ATOL, (new.cost, old.cost)
    assert new_calls < old_calls, (new_calls, old_calls)
    # and, given all the calls it wants, the (width, yaw) fit ends where the vectors did: the
    # centre within 2 mm (its sd ~1 cm), the cost within 2 atol of the solver's cost (chi^2 /
    # 2; FitResult.cost is chi^2): atol bounds the best gain the Jacobian in hand predicts
    # (model.lm), which after a short step is one step old (measured here: 0.010 of cost
    # left; 25 model calls against 70)
    long = fit(problem, start, free, 200, tau=WARM_TAU, atol=1e-4)
    np.testing.assert_allclose(long.params[0, :2], new.params[0, :2], atol=2e-3)
    assert (new.cost - long.cost) / 2 < 2 * WARM_ATOL
