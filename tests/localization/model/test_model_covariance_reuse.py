"""The covariance from the solver's last Jacobian (model.covariance's `reuse`, the tracker's
warm fits): the algebra is exact (an exact profiled Jacobian gives the exact covariance and
Birge ratio), the solver's own forward differences come within their truncation error, and
where the Jacobian is not the solution's it is not used. No timings."""
from dataclasses import replace

import numpy as np
import pytest

from nlos_cl.localization.model.solve import covariance as cov_module, fit

from nlos_cl.localization.model.shapes import plate
from nlos_cl.localization.model.forward.batch import HostProblem
from nlos_cl.localization.model.solve.covariance import covariance

from test_model_derivatives import ROW, scene_observation  # every parameter observable

FREE = np.ones(plate.N_PARAMS, bool)


@pytest.fixture(scope="module")
def fitted(runtime):
    host = HostProblem(scene_observation(runtime))
    return host, fit.fit(host, ROW[None], FREE, 30, keep_jacobian=True)


def _sds(c):
    return np.sqrt(np.diag(c))


def test_an_exact_profiled_jacobian_gives_the_exact_covariance(fitted):
    """The profiled residuals' Jacobian -(I - P_A) J_theta (whitened; from the analytic
    derivatives, projected here by least squares) in place of the solver's: the target
    parameters' covariance and the Birge ratio as the full sandwich gives them, to rounding
    (1e-8: pinv of an equilibrated 7 x 7 normal matrix, float64)."""
    host, result = fitted
    obs = host.obs
    cols, jmu = cov_module._mean_jacobian(host, result.params, result.linear, FREE)
    whitened = (jmu / obs.noise[:, None, None])[obs.valid]
    j_theta, a = whitened[:, :plate.N_PARAMS], whitened[:, plate.N_PARAMS:]
    assert_reuse_is_exact(host, result, cols, j_theta, a)


def assert_reuse_is_exact(host, result, cols, j_theta, profiled):
    """covariance(reuse=True) from the exact profiled Jacobian -(I - P) j_theta (P: the
    projection on the `profiled` columns, whitened) equals the full sandwich's: 1e-8 on the
    covariance, 1e-10 on the Birge ratio."""
    projected = j_theta - profiled @ np.linalg.lstsq(profiled, j_theta, rcond=None)[0]
    exact_jacobian = replace(result, jacobian=(result.params, -projected), columns=cols)
    got, got_info = covariance(host, exact_jacobian, FREE, reuse=True)
    want, want_info = covariance(host, result, FREE)
    assert np.allclose(got, want, rtol=1e-8, atol=0)
    assert got_info["birge_ratio"] == pytest.approx(want_info["birge_ratio"], rel=1e-10)


def test_the_solvers_jacobian_is_within_its_truncation_error(fitted):
    """The solver's forward differences (2 mm, 4 mrad; the moved plate at the unmoved one's
    cell statistics) against the analytic derivatives: each sd within 6 %. A forward
    difference's relative error is ~h f'' / (2 f'), h / (2 sigma) for a pulse of width sigma:
    2 mm against the filtered pulse's ~2.5 cm of path, ~4 %; measured here and on the stream
    bench's frames 0.2-5.4 %. The Birge ratio (residuals exact, only the hat matrix's trace
    approximate) within 0.1 %."""
    host, result = fitted
    assert result.jacobian is not None
    got, got_info = covariance(host, result, FREE, reuse=True)
    want, want_info = covariance(host, result, FREE)
    assert not np.allclose(got, want, rtol=1e-8)  # the reused Jacobian was used
    assert np.allclose(_sds(got), _sds(want), rtol=0.06, atol=0), (_sds(got), _sds(want))
    assert got_info["birge_ratio"] == pytest.approx(want_info["birge_ratio"], rel=1e-3)


def test_a_jacobian_far_from_the_solution_is_not_used(fitted):
    """A Jacobian taken more than REUSE_MOVE (whitened residual norm) from the solution, none
    at all, or an amplitude at its bound of 0: the covariance computes its own derivatives,
    bit for bit the one without `reuse`."""
    host, result = fitted
    want, _ = covariance(host, result, FREE)
    at, jac = result.jacobian
    far = at.copy()
    far[0, 1] += 0.05  # 5 cm in depth: many sds
    for changed in (replace(result, jacobian=(far, jac)), replace(result, jacobian=None),
                    replace(result, linear=np.zeros_like(result.linear))):
        assert np.array_equal(covariance(host, changed, FREE, reuse=True)[0],
                              covariance(host, changed, FREE)[0], equal_nan=True)
    assert np.array_equal(covariance(host, replace(result, jacobian=(far, jac)), FREE,
                                     reuse=True)[0], want)
