"""The causal Cramer-Rao bound (nlos_cl.tracking.bounds) against the straight line's closed
form and against Monte Carlo fits of a circle."""
import numpy as np
import pytest

from nlos_cl.core.errors import InputError
from nlos_cl.localization.model.solve.lm import least_squares
from nlos_cl.tracking.bounds import causal_bound, circle, line

T = np.arange(50) * 0.1
UNIT = np.broadcast_to(np.eye(2), (50, 2, 2))


def test_line_bound_is_the_least_squares_endpoint_variance():
    """A line fitted to k + 1 equally spaced unit-variance points: the fitted end point's
    variance is (4k + 2) / ((k + 1)(k + 2)) per axis; one point cannot fix a line."""
    bound = causal_bound(line, (3, 1.5, 0.2, 0.3), T, UNIT)
    assert np.all(np.isinf(bound[0]))
    k = np.arange(1, 50)
    expected = (4 * k + 2) / ((k + 1) * (k + 2))
    np.testing.assert_allclose(bound[1:, 0, 0], expected, rtol=1e-6)
    np.testing.assert_allclose(bound[1:, 1, 1], expected, rtol=1e-6)
    np.testing.assert_allclose(bound[1:, 0, 1], 0, atol=1e-9)


def test_circle_bound_matches_monte_carlo_fits():
    """Frame 15 of a quarter circle (r = 1.5 m, 0.47 m/s, 10 fps) measured with 1 cm noise:
    the variance of 400 nonlinear least-squares fits of frames 0..15 against the bound. The
    sample variance's relative sd is sqrt(2 / 400) = 7 % per axis; 25 % is > 3 sd of the sum."""
    truth = np.array([2.0, 3.0, 1.5, 0.0, np.pi / 10])
    sigma, k = 0.01, 15
    bound = causal_bound(circle, truth, T, sigma ** 2 * UNIT)[k]
    rng = np.random.default_rng(4)
    t = T[:k + 1]
    clean = circle(truth, t)
    ends = []
    for _ in range(400):
        y = clean + sigma * rng.standard_normal(clean.shape)
        fit = least_squares(lambda p: (circle(p, t) - y).ravel(), truth, ftol=1e-12,
                            xtol=1e-12)
        ends.append(circle(fit.x, t[-1:])[0])
    measured = np.cov(np.array(ends).T)
    assert np.trace(measured) == pytest.approx(np.trace(bound), rel=0.25)
    assert np.trace(bound) < sigma ** 2 * 2  # better than one frame's measurement


def test_a_frame_without_measurement_adds_nothing():
    cov = np.array(UNIT)
    cov[7] = np.nan
    with_gap = causal_bound(line, (0, 0, 1, 1), T, cov)
    without = causal_bound(line, (0, 0, 1, 1), np.delete(T, 7), np.delete(UNIT, 7, axis=0))
    np.testing.assert_allclose(with_gap[8:], without[7:], rtol=1e-9)


def test_covariances_of_the_wrong_shape_are_refused():
    with pytest.raises(InputError, match="covariances"):
        causal_bound(line, (0, 0, 1, 1), T, np.ones((49, 2, 2)))
