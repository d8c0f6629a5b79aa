"""The Poisson linear factors by blocks (likelihood.Problem._poisson_linear: the backgrounds'
diagonal block eliminated) against the plain einsum and dense solve over the full basis they
replaced: the same Newton steps, so the same factors to rounding (1e-10 relative; observed
~1e-14), on one and on many detectors."""
from types import SimpleNamespace

import numpy as np
import pytest

from nlos_cl.localization.model.forward.likelihood import (BOUND_SHARE, NEWTON_ITERS, Problem,
                                                   _arrow_solve, _poisson_newton)


def _damping(diagonal):
    """likelihood._ridge, written out: 1e-9 of each diagonal entry, or of a thousandth of its
    block's mean where the entry is ~0."""
    return 1e-9 * np.maximum(diagonal, 1e-3 * diagonal.mean()) + 1e-300


def _converged(new, phi, basis, y, valid):
    """Every entry moved by <= 1e-9 of itself, or moved the expected counts (its basis row's
    sum over the valid bins times the move) by <= 1e-9 of the counts observed (+ 1)."""
    moved = np.abs(new - phi)
    counts = moved * np.sum(basis * valid[None], axis=(1, 2))
    return np.all((moved <= 1e-9 * np.abs(phi)) |
                  (counts <= 1e-9 * (np.sum(y * valid) + 1.0)))


def full_basis_newton(problem, cols, iters=NEWTON_ITERS):
    obs = problem.obs
    basis = np.concatenate([cols, np.eye(len(obs.y))[:, :, None] * obs.valid[None]], axis=0)
    phi = Problem._poisson_start(problem, cols)
    for _ in range(iters):
        lam = np.maximum(np.tensordot(phi, basis, 1), 1e-12)
        grad = np.tensordot(basis, (obs.y / lam - 1.0) * obs.valid, ((1, 2), (0, 1)))
        hess = np.einsum("idn,jdn,dn->ij", basis, basis, obs.valid * obs.y / lam ** 2)
        d = np.diag(hess).copy()  # the damping: 1e-9 of each entry, per block (a, then b)
        for block in (slice(0, len(cols)), slice(len(cols), None)):
            hess[block, block] += np.diag(_damping(d[block]))
        new = np.maximum(phi + np.linalg.solve(hess, grad), BOUND_SHARE * phi)
        if _converged(new, phi, basis, obs.y, obs.valid):
            return new
        phi = new
    return phi


@pytest.mark.parametrize("n_det, k, zero_row", [(3, 1, False), (40, 2, False), (16, 3, False),
                                                (24, 1, True)])
def test_block_newton_matches_the_full_basis(n_det, k, zero_row):
    """Also with a detector that counted nothing (a CC-SOCR scan point): its background's
    Hessian entry is only the ridge, which the backgrounds' elimination divides by."""
    rng = np.random.default_rng(n_det + k)
    n = 180
    cols = rng.random((k, n_det, n)) * np.exp(-((np.arange(n) - 90) / 15.0) ** 2)
    valid = rng.random((n_det, n)) > 0.1
    y = rng.poisson(4.0 * cols.sum(axis=0) + 0.2).astype(np.float64)
    if zero_row:
        y[n_det // 2] = 0.0
    problem = SimpleNamespace(obs=SimpleNamespace(y=y, valid=valid, mode="poisson"))
    problem._poisson_start = lambda c: Problem._poisson_start(problem, c)
    got = Problem._poisson_linear(problem, cols)
    want = full_basis_newton(problem, cols)
    assert np.allclose(got, want, rtol=1e-10, atol=0)


def plain_block_newton(y, valid, cols, phi, iters):
    """The block Newton as first written (stop 49), each mask and test spelt out: what
    likelihood._poisson_newton's fused form must reproduce bit for bit."""
    k = len(cols)
    flat = cols.reshape(k, -1)
    for _ in range(iters):
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            lam = np.maximum(np.tensordot(phi[:k], cols, 1) + phi[k:, None] * valid, 1e-12)
            r = (y / lam - 1.0) * valid
            w = valid * y / lam ** 2
        if not (np.all(np.isfinite(w)) and np.all(np.isfinite(r))):
            break
        h_aa = (flat * w.reshape(-1)) @ flat.T
        h_ab = np.einsum("kdn,dn->kd", cols, w * valid)
        h_bb = np.sum(w * valid, axis=1)
        h_aa[np.diag_indices(k)] += _damping(np.diag(h_aa).copy())
        h_bb = h_bb + _damping(h_bb)
        g_a, g_b = flat @ r.reshape(-1), np.sum(r * valid, axis=1)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            step = _arrow_solve(h_aa, h_ab, h_bb, g_a, g_b)
        new = np.maximum(phi + step, BOUND_SHARE * phi)
        if not np.all(np.isfinite(new)):
            break
        basis = np.concatenate([cols, np.eye(len(y))[:, :, None] * valid[None]], axis=0)
        if _converged(new, phi, basis, y, valid):
            return new
        phi = new
    return phi


@pytest.mark.parametrize("case", ["warm", "cold", "far_column", "zero_row"])
def test_fused_newton_is_the_plain_form_bit_for_bit(case):
    """Also from a cold start (backgrounds climbing from 1e-3, the 12-iteration cap) and with
    a column far from the counts (its amplitude runs off: the finiteness stop)."""
    rng = np.random.default_rng(7)
    n_det, n = 16, 316
    t = np.arange(n)
    cols = (rng.random((1, n_det, 1)) + 0.5) * np.exp(-((t - 150) / 6.0) ** 2)
    valid = np.ones((n_det, n)) * (t >= 20)
    y = rng.poisson(300.0 * cols[0] + 2.0) * valid
    phi = np.concatenate([[250.0], np.full(n_det, 1.5)])
    if case == "cold":
        phi[1:] = 1e-3
    if case == "far_column":
        cols = np.exp(-((t - 5) / 1.0) ** 2)[None, None].repeat(n_det, 1) + 0.0
        phi[0] = 1e-6
    if case == "zero_row":
        y[3] = 0.0
    got = _poisson_newton(y, valid, cols, phi.copy(), 12)
    want = plain_block_newton(y, valid, cols, phi.copy(), 12)
    assert np.array_equal(got, want)


@pytest.mark.parametrize("n_det, p", [(3, 4), (40, 8), (16, 7)])
def test_poisson_information_is_the_full_matrix_with_backgrounds_profiled(n_det, p):
    """model.covariance._poisson_information (the Schur complement of the per-detector
    backgrounds' diagonal block) against the inverse of the full Fisher matrix with one dense
    column per background, as the covariance had built it: the target block of the inverse
    to 1e-9 relative (both float64; observed ~1e-13), with invalid bins and a detector without
    any valid bin."""
    from nlos_cl.localization.model.solve.covariance import _poisson_information
    rng = np.random.default_rng(n_det + p)
    n = 150
    valid = rng.random((n_det, n)) > 0.1
    valid[-1] = False  # no valid bin: no background to profile
    mu = 0.5 + 3 * rng.random((n_det, n))
    jmu = rng.standard_normal((n_det, n, p))
    obs = SimpleNamespace(valid=valid)
    backgrounds = np.eye(n_det)[:, :, None] * valid[None]  # (D, n, D)
    full_j = np.concatenate([jmu, backgrounds.transpose(1, 2, 0)], axis=2)[valid]
    lam = mu[valid]
    full = full_j.T @ (full_j / lam[:, None])
    want = np.linalg.pinv(full)[:p, :p]
    got = np.linalg.inv(_poisson_information(obs, mu, jmu))
    assert np.allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())


def test_cold_amplitudes_are_converged_so_a_cost_is_a_function_of_its_parameters():
    """Rows whose first and last bins are gated zeros (CC-SOCR) start their background at the
    1e-3 floor and climb by Newton's doubling: the amplitudes from that cold start must be the
    likelihood's stationary point, the same as from a start at the answer, so a fit's cost
    does not depend on which call came before (with 12 iterations they were not: 20 counts a
    bin is 15 doublings away)."""
    rng = np.random.default_rng(11)
    n_det, n = 6, 316
    t = np.arange(n)
    cols = np.exp(-((t - 150) / 8.0) ** 2)[None, None].repeat(n_det, 1) * \
        (1.0 + 0.1 * np.arange(n_det))[None, :, None]
    y = rng.poisson(400.0 * cols[0] + 20.0).astype(np.float64)
    y[:, :8] = y[:, -8:] = 0.0  # gated: counted as zero photons
    valid = np.ones((n_det, n), bool)
    problem = SimpleNamespace(obs=SimpleNamespace(y=y, valid=valid, mode="poisson"))
    problem._poisson_start = lambda c: Problem._poisson_start(problem, c)
    cold = Problem._poisson_linear(problem, cols)
    assert np.all(cold[1:] > 15.0)  # climbed from 1e-3
    again = Problem._poisson_linear(problem, cols, warm=cold)
    assert np.allclose(again, cold, rtol=1e-8, atol=0)
    lam = cold[0] * cols[0] + cold[1:, None]
    assert np.allclose(np.sum(y / lam - 1.0, axis=1), 0.0, atol=1e-6 * n)  # d/db = 0


def test_a_column_in_small_units_converges_as_fast_as_one_in_counts():
    """The Newton step's damping is per parameter: a plate's column of ~1e-8 per bin (its
    amplitude ~5e7, simulated counts) against backgrounds of ~2 counts a bin. A ridge common
    to both blocks was 18 times the amplitude's Hessian entry there: the amplitude crept 5 %
    an iteration. The same problem in counts-sized units converges in the same iterations."""
    rng = np.random.default_rng(5)
    n_det, n = 7, 91
    t = np.arange(n)
    shape = np.exp(-((t - 45) / 4.0) ** 2)[None].repeat(n_det, 0) * \
        (1 + 0.2 * np.arange(n_det))[:, None]
    y = rng.poisson(500.0 * shape + 2.0).astype(np.float64)
    valid = np.ones((n_det, n))
    iterations = []
    for unit in (1.0, 1e-8):
        cols = (shape * unit)[None]
        phi = np.concatenate([[1.3 * 500.0 / unit], np.full(n_det, 1.0)])
        for i in range(1, 41):
            new = _poisson_newton(y, valid, cols, phi, 1)
            if np.all(np.abs(new - phi) <= 1e-9 * np.abs(phi)):
                break
            phi = new
        iterations.append(i)
        lam = phi[0] * cols[0] + phi[1:, None]
        assert abs(np.sum((y / lam - 1.0) * cols[0]) * phi[0]) < 1e-6 * y.sum()  # d/da = 0
    assert iterations[1] == iterations[0] <= 10, iterations


def test_a_step_past_zero_does_not_throw_a_background_twelve_orders_down():
    """Low counts (a weak SPAD patch: ~380 photons over 769 bins a detector): a background
    started at 0.1 whose best level is ~0.04 is overshot past 0 by the first step. Stopped at
    BOUND_SHARE of its value it converges in a few iterations (from 1e-12 of it, as before
    stop 50, it took ~40 doublings, past the cap); a column that explains nothing has its
    amplitude at the bound, and stops once its moves no longer change the expected counts."""
    rng = np.random.default_rng(33)
    n_det, n = 8, 769
    t = np.arange(n)
    cols = np.exp(-((t - 400) / 6.0) ** 2)[None, None].repeat(n_det, 1) * 1e-3
    y = rng.poisson(cols[0] * 3.5e5 + 0.04).astype(np.float64)
    valid = np.ones((n_det, n))
    phi = np.concatenate([[3.7e5], np.full(n_det, 0.1)])
    steps = []
    for start in (phi, np.concatenate([[3.7e5], np.full(n_det, 1e-3)])):
        p = _poisson_newton(y, valid, cols, start.copy(), NEWTON_ITERS)
        # the iterations it took: the fewest that give the same answer
        steps.append(next(m for m in range(1, NEWTON_ITERS + 1)
                          if np.array_equal(_poisson_newton(y, valid, cols, start.copy(), m), p)))
        lam = p[0] * cols[0] + p[1:, None]
        assert np.allclose(np.sum(y / lam - 1.0, axis=1), 0.0, atol=1e-6 * n)  # d/db = 0
    assert max(steps) <= 15, steps
    empty = np.concatenate([cols, np.exp(-((t - 100) / 6.0) ** 2)[None, None].repeat(n_det, 1)])
    y_empty = y.copy()
    y_empty[:, 60:140] = 0.0  # nothing where the second column is
    got = _poisson_newton(y_empty, valid, empty, np.concatenate([[3.7e5, 5.0], phi[1:]]),
                          NEWTON_ITERS)
    assert got[1] * empty[1].sum() < 1e-6 * y_empty.sum()  # its counts ~0: at the bound
