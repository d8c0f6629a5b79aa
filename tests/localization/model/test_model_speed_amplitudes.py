"""model.solve.amplitudes (issue 58): the counts' Newton solves of a Jacobian's stepped
columns run together, each member as likelihood._poisson_newton runs it alone: the same
optima to rounding (1e-12 relative), whichever step each member stops at (a warm member in
3, a cold one in ~20, one whose amplitude runs off at its last finite point)."""
from types import SimpleNamespace

import numpy as np
import pytest

from nlos_cl.localization.model.forward.likelihood import _poisson_newton
from nlos_cl.localization.model.solve import amplitudes
from nlos_cl.localization.model.solve.fit import _Objective


def _counts(n_det=16, n=316, k=1, seed=7):
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    cols = (rng.random((k, n_det, 1)) + 0.5) * np.exp(-((t - 150 - 20 * np.arange(k)[:, None,
                                                          None]) / 6.0) ** 2)
    valid = np.ones((n_det, n)) * (t >= 20)
    y = (rng.poisson(300.0 * cols.sum(axis=0) + 2.0) * valid).astype(np.float64)
    phi = np.concatenate([np.full(k, 250.0), np.full(n_det, 1.5)])
    return y, valid, cols, phi


@pytest.mark.parametrize("k", [1, 2])
def test_members_reach_their_own_optima_whatever_step_they_stop_at(k):
    y, valid, cols, phi = _counts(k=k)
    y[3] = 0.0  # a detector that counted nothing: its background's entry is the ridge alone
    t = np.arange(y.shape[1])
    far = np.exp(-((t - 5) / 1.0) ** 2)[None, None].repeat(len(y), 1).repeat(k, 0)
    stepped = np.stack([cols * 1.001, cols, cols * 0.97, far])  # warm, at, further, far off
    starts = np.stack([phi, phi, np.concatenate([phi[:k], np.full(len(y), 1e-3)]),
                       np.concatenate([np.full(k, 1e-6), phi[k:]])])  # the third: cold
    got = amplitudes.poisson_newton_many(y, valid, stepped, starts.copy(), 40)
    steps = []
    for member, (cols_m, phi_m) in enumerate(zip(stepped, starts)):
        want = _poisson_newton(y, valid, cols_m, phi_m.copy(), 40)
        assert np.allclose(got[member], want, rtol=1e-12, atol=0), member
        steps.append(next(n for n in range(1, 41) if np.array_equal(
            _poisson_newton(y, valid, cols_m, phi_m.copy(), n), want)))
    assert len(set(steps)) >= 3  # the members stop at different steps


def test_a_fits_jacobian_is_the_one_column_at_a_time_jacobian(monkeypatch):
    """_Objective.jac with the stepped amplitudes and residuals formed together and one by
    one (as before, and as Gaussian data and late copies still are): the same Jacobian to
    1e-9 of its largest entry."""
    y, valid, cols, _ = _counts()
    obs = SimpleNamespace(y=y, valid=valid.astype(bool), mode="poisson", late=None)
    plate_like = SimpleNamespace(N_PARAMS=2, STEPS=np.array([1e-3, 1e-3]),
                                 LOWER=np.array([-9.0, -9.0]), UPPER=np.array([9.0, 9.0]),
                                 X_SCALE=np.ones(2))
    from nlos_cl.localization.model.forward.likelihood import Problem

    class Shifted(Problem):  # a column that moves and widens with its two parameters
        def columns(self, params):
            (x, s), t = np.reshape(params, (-1, 2))[0], np.arange(y.shape[1])
            return (cols[0, :, :1] * np.exp(-((t - 150 - x) / (6.0 + s)) ** 2))[None]

        def column_batch(self, rows, like=None, occluders=None):
            return np.stack([self.columns(r)[0] for r in rows])

    problem = Shifted(obs, None, shape=plate_like)
    obj = _Objective(problem, np.array([[0.4, 0.2]]), np.ones(2, bool))
    together = obj.jac(np.array([0.4, 0.2]))
    from nlos_cl.localization.model.solve import fit
    monkeypatch.setattr(fit, "stepped_residuals", lambda p, stepped, lin: [  # as before
        p.residual(moved, p.linear(moved, lin)) for moved in stepped])
    obj = _Objective(problem, np.array([[0.4, 0.2]]), np.ones(2, bool))
    alone = obj.jac(np.array([0.4, 0.2]))
    assert np.abs(together).max() > 0
    assert np.allclose(together, alone, rtol=0, atol=1e-9 * np.abs(alone).max())
