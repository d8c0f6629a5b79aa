"""The Poisson linear factors by blocks (likelihood.Problem._poisson_linear) against the
plain einsum over the full basis they replaced: the same Newton steps, so the same factors to
rounding (1e-10 relative; observed ~1e-14), on one and on many detectors."""
from types import SimpleNamespace

import numpy as np
import pytest

from nlos_cl.localization.model.likelihood import Problem


def full_basis_newton(problem, cols, iters=12):
    obs = problem.obs
    basis = np.concatenate([cols, np.eye(len(obs.y))[:, :, None] * obs.valid[None]], axis=0)
    phi = Problem._poisson_start(problem, cols)
    for _ in range(iters):
        lam = np.maximum(np.tensordot(phi, basis, 1), 1e-12)
        grad = np.tensordot(basis, (obs.y / lam - 1.0) * obs.valid, ((1, 2), (0, 1)))
        hess = np.einsum("idn,jdn,dn->ij", basis, basis, obs.valid * obs.y / lam ** 2)
        hess += 1e-9 * np.trace(hess) / len(hess) * np.eye(len(hess))
        new = np.maximum(phi + np.linalg.solve(hess, grad), 1e-12 * np.maximum(phi, 1e-6))
        if np.allclose(new, phi, rtol=1e-9, atol=0):
            return new
        phi = new
    return phi


@pytest.mark.parametrize("n_det, k", [(3, 1), (40, 2), (16, 3)])
def test_block_newton_matches_the_full_basis(n_det, k):
    rng = np.random.default_rng(n_det + k)
    n = 180
    cols = rng.random((k, n_det, n)) * np.exp(-((np.arange(n) - 90) / 15.0) ** 2)
    valid = rng.random((n_det, n)) > 0.1
    y = rng.poisson(4.0 * cols.sum(axis=0) + 0.2).astype(np.float64)
    problem = SimpleNamespace(obs=SimpleNamespace(y=y, valid=valid, mode="poisson"))
    problem._poisson_start = lambda c: Problem._poisson_start(problem, c)
    got = Problem._poisson_linear(problem, cols)
    want = full_basis_newton(problem, cols)
    assert np.allclose(got, want, rtol=1e-10, atol=0)
