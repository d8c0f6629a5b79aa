"""The interacting multiple model (motion.Interacting; kalman.predict_modes, update_modes):
its mixing against a loop-by-loop reference, the single-model limit, and what it is for: as
smooth as a quiet model on a straight path, as quick as a loud one after a turn."""
import numpy as np
import pytest
from test_tracking_kalman import _layout

import nlos_cl as nl
from nlos_cl.localization.estimate import LocatedTarget
from nlos_cl.tracking import ConstantVelocity, Interacting, Tracker, kalman


def _step_all(motion, positions, sigma, dt=0.1):
    tr = Tracker(_layout(), estimator="paper", motion=motion)
    out = []
    for k, p in enumerate(positions):
        (track,) = tr.step([LocatedTarget(np.r_[p, 0.0], np.diag([sigma ** 2] * 2 + [np.inf]))],
                           dt * k)
        out.append(track.position[:2].copy())
    return np.array(out), track


def test_mixing_matches_a_loop_reference():
    rng = np.random.default_rng(3)
    n, M = 4, 3
    mu = rng.dirichlet(np.ones(M))
    x = rng.normal(size=(M, n))
    A = rng.normal(size=(M, n, n))
    P = A @ A.transpose(0, 2, 1) + np.eye(n)
    pi = rng.dirichlet(np.ones(M), size=M)  # rows sum to 1
    F = ConstantVelocity.transition(0.1, 2)
    Q = rng.uniform(0.1, 1) * np.eye(n)[None] * np.array([1.0, 2.0, 3.0])[:, None, None]
    got = kalman.predict_modes(kalman.Modes(mu, x, P), F, Q, pi)
    for j in range(M):  # Bar-Shalom, Li & Kirubarajan (2001) eq. 11.6.6-11.6.10, term by term
        c = sum(pi[i, j] * mu[i] for i in range(M))
        w = [pi[i, j] * mu[i] / c for i in range(M)]
        x0 = sum(w[i] * x[i] for i in range(M))
        P0 = sum(w[i] * (P[i] + np.outer(x[i] - x0, x[i] - x0)) for i in range(M))
        assert got.mu[j] == pytest.approx(c, rel=1e-12)
        np.testing.assert_allclose(got.x[j], F @ x0, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.P[j], F @ P0 @ F.T + Q[j], rtol=1e-12, atol=1e-12)
    xc, Pc = got.combined()
    np.testing.assert_allclose(xc, sum(got.mu[j] * got.x[j] for j in range(M)), atol=1e-12)
    spread = sum(got.mu[j] * np.outer(got.x[j] - xc, got.x[j] - xc) for j in range(M))
    np.testing.assert_allclose(Pc, sum(got.mu[j] * got.P[j] for j in range(M)) + spread,
                               atol=1e-12)


def test_identical_modes_are_the_single_model():
    # modes that do not differ cannot be told apart: the IMM is the Kalman filter (to rounding)
    rng = np.random.default_rng(0)
    k = np.arange(40)
    path = np.c_[2 + 0.05 * k, 1 + 0.02 * k] + 0.02 * rng.normal(size=(40, 2))
    one, _ = _step_all(ConstantVelocity(accel_sigma=0.3), path, 0.02)
    motion = Interacting(accel_sigmas=(0.3, 0.3), stay_s=(5.0, 1.0))
    two, track = _step_all(motion, path, 0.02)
    np.testing.assert_allclose(two, one, atol=1e-9)
    # no evidence either way: the mode probabilities are the Markov chain's alone
    mu = motion.initial_modes
    for _ in range(39):
        mu = motion.switching(0.1).T @ mu
    assert track.modes.mu == pytest.approx(mu, rel=1e-9)


def _u_turn(t):
    """x of a 1 m/s target that reverses its x velocity over 1 s from t = 3 s (2 m/s^2)."""
    vx = np.clip(1 - 2 * (t - 3), -1, 1)
    return np.concatenate([[0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * np.diff(t))])


def test_smooth_when_steady_and_quick_after_a_turn():
    # 10 frames/s, 3 cm errors; measured (seed 1): straight frames 10-29 RMS quiet 0.016 m,
    # loud 0.028, IMM 0.017; the turn's frames 30-49 quiet 0.049, loud 0.025, IMM 0.026
    rng = np.random.default_rng(1)
    t = 0.1 * np.arange(60)
    truth = np.c_[_u_turn(t), 1 + 0.2 * t]
    z = truth + 0.03 * rng.normal(size=truth.shape)
    err = {}
    for name, motion in {"quiet": ConstantVelocity(0.05), "loud": ConstantVelocity(0.5),
                         "imm": Interacting(accel_sigmas=(0.05, 0.5))}.items():
        est, _ = _step_all(motion, z, 0.03)
        e = np.linalg.norm(est - truth, axis=1)
        err[name] = (np.sqrt(np.mean(e[10:30] ** 2)), np.sqrt(np.mean(e[30:50] ** 2)))
    steady, turn = 0, 1
    assert err["imm"][steady] < 0.7 * err["loud"][steady]  # straight: near the quiet model
    assert err["imm"][turn] < 0.7 * err["quiet"][turn]  # the turn: near the loud model


def test_manoeuvre_mode_takes_over_at_the_turn():
    t = 0.1 * np.arange(50)
    truth = np.c_[_u_turn(t), np.ones_like(t)]
    tr = Tracker(_layout(), estimator="paper", motion=Interacting())
    mu = []
    for k, p in enumerate(truth):
        (track,) = tr.step([LocatedTarget(np.r_[p, 0.0], np.diag([1e-4, 1e-4, np.inf]))], t[k])
        mu.append(np.nan if track.modes is None else track.modes.mu[1])  # None: at birth
    assert max(mu[20:30]) < 0.2  # straight: steady
    assert max(mu[30:40]) > 0.8  # the reversal: manoeuvring
    assert mu[-1] < 0.2  # straight again: steady


@pytest.mark.parametrize("kw, field", [({"accel_sigmas": (0.5,)}, "motion.accel_sigmas"),
                                       ({"stay_s": (1.0, 0.0)}, "motion.stay_s"),
                                       ({"stay_s": (1.0, 2.0, 3.0)}, "motion.stay_s"),
                                       ({"initial_speed_sigma": -1}, "motion.initial_speed_sigma")])
def test_bad_interacting_options(kw, field):
    with pytest.raises(nl.InputError, match=field):
        Interacting(**kw)


def test_a_state_set_from_outside_restarts_the_modes():
    motion = Interacting()
    t = 0.1 * np.arange(40)
    tr = Tracker(_layout(), estimator="paper", motion=motion)
    for k in range(40):
        (track,) = tr.step([LocatedTarget(np.r_[_u_turn(t)[k], 1.0, 0.0],
                                          np.diag([1e-4, 1e-4, np.inf]))], t[k])
    assert kalman.track_modes(track, motion) is track.modes  # the filter's own state
    track.state[:2] += (0.4, 0.45)  # edited in place (a re-acquisition replaces it whole)
    fresh = kalman.track_modes(track, motion)
    assert fresh is not track.modes
    np.testing.assert_array_equal(fresh.mu, motion.initial_modes)
    np.testing.assert_array_equal(fresh.x, [track.state, track.state])
