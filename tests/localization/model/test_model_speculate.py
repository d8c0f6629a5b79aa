"""model.fit's `speculate`: a one-target fit on a batching problem evaluates each residual's
plate in one host call with the stepped plates of its forward-difference Jacobian, and the
Jacobian the solver then asks for at that point costs no call. Checked: the same fit (the
stepped plates are the same columns, in a bigger batch), fewer host calls, and the kept
Jacobian is the one a separate call gives."""
import numpy as np
import pytest

from nlos_cl.localization.model.forward.batch import HostProblem
from nlos_cl.localization.model.solve.fit import _Objective, fit
from nlos_cl.localization.model.forward.likelihood import Problem

from test_model_derivatives import ROW, scene_observation

FREE = np.array([True, True, False, True, True, True])


@pytest.fixture(scope="module")
def obs(runtime):
    return scene_observation(runtime)


class _Counted(HostProblem):
    """A HostProblem that counts its column_batch calls (each one host pass or a few)."""

    batch_calls = 0

    def column_batch(self, rows, like=None, occluders=None):
        self.batch_calls += 1
        return super().column_batch(rows, like, occluders)


def _warm_fit(obs, speculate):
    problem = _Counted(obs)
    start = ROW + np.array([0.03, -0.02, 0.0, 0.04, -0.05, 0.06])  # a warm start's miss
    return problem, fit(problem, start[None], FREE, 20, tau=1e-6, atol=0.05,
                        width_vectors=True, keep_jacobian=True, speculate=speculate)


def test_the_same_fit_in_fewer_host_calls(obs):
    plain_problem, plain = _warm_fit(obs, False)
    spec_problem, spec = _warm_fit(obs, True)
    # the stepped plates are the same columns, summed in a larger batch: the answers agree
    # to the sums' last bits, far below the fit's own tolerance (atol 0.05 of chi^2 / 2)
    np.testing.assert_allclose(spec.params, plain.params, atol=1e-9)
    assert spec.cost == pytest.approx(plain.cost, rel=1e-9)
    assert spec.nfev == plain.nfev
    # each Jacobian at a residual's point came with it: calls ~ residuals, not twice that
    assert spec_problem.batch_calls < plain_problem.batch_calls
    assert spec_problem.batch_calls <= spec.nfev + 1
    (at_plain, jac_plain), (at_spec, jac_spec) = plain.jacobian, spec.jacobian
    np.testing.assert_allclose(at_spec, at_plain, atol=1e-9)
    np.testing.assert_allclose(jac_spec, jac_plain, rtol=1e-7, atol=1e-7 * np.abs(jac_plain).max())


def test_only_one_target_on_a_batching_problem_speculates(obs):
    host = HostProblem(obs)
    assert _Objective(host, ROW[None], FREE, speculate=True).speculate
    assert not _Objective(host, ROW[None], FREE).speculate  # off unless asked
    two = np.stack([ROW, ROW + np.array([1.0, 1.0, 0, 0, 0, 0])])
    assert not _Objective(host, two, FREE, speculate=True).speculate  # shadows: stepped_columns
    assert not Problem.batched  # the device's Problem: one forward call per plate anyway
    assert not _Objective(Problem(obs, None), ROW[None], FREE, speculate=True).speculate
