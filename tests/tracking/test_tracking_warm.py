"""Warm-started model fits (nlos_cl.localization.model.policy.warm, nlos_cl.tracking.warm): the host model that
runs them against the forward operation, a warm estimate against the cold one on the same
frame, and both fallbacks (the estimator's misfit test, the tracker's gate). No timings."""
import warnings

import numpy as np
import pytest
from conftest import paper_frame

import nlos_cl as nl
from nlos_cl.localization.estimate import Prior, Scored
from nlos_cl.localization.fit_result import ModelFit, Parameter, WarmStart
from nlos_cl.localization.model import ModelEstimator
from nlos_cl.localization.model.forward.batch import CHUNK_ROWS, HostProblem
from nlos_cl.localization.model.forward.likelihood import Problem
from nlos_cl.tracking import Tracker, kalman, warm
from nlos_cl.tracking.options import SearchPlan

GRID = nl.Grid.from_ranges(x=(2, 6), y=(0.5, 4), step_m=0.02)
TRUTH = (4.0, 2.0, 0.0)


@pytest.fixture(scope="module")
def scored(runtime):
    """One 10 dB frame of the paper's scene, as a Locator hands it to the estimator."""
    filtered, raw = paper_frame(runtime, truth=TRUTH)
    locator = nl.Locator(filtered, GRID, estimator="model")
    scores = locator.scores(filtered)
    return Scored(filtered.backend, scores, GRID, False, filtered.n_detectors, filtered, raw)


def _estimate(scored, start=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # collinear spots: height unobservable
        return ModelEstimator().estimate(scored, start=start).targets[0]


@pytest.fixture(scope="module")
def cold(scored):
    return _estimate(scored)


def test_host_model_matches_the_forward_operation(scored, cold):
    est = ModelEstimator()
    obs = est.observation(scored)
    device = Problem(obs, scored.backend, est.lattice_for(obs))
    host = HostProblem(obs, est.lattice_for(obs))
    p = np.array(list(cold.details["params"].values()))
    rows = p + np.diag([0.01, -0.01, 0.0, 0.05, -0.1, 0.1])
    batch = host.column_batch(rows)
    for row, col in zip(rows, batch):
        ref = device.column(row)
        # the kernel's own tolerance against its float64 twin (ops/forward.py): 1e-3 of the peak
        assert np.abs(col - ref).max() <= 1e-3 * np.abs(ref).max()
        np.testing.assert_array_equal(col, host.column(row))  # a batch changes nothing


def test_a_batch_in_chunks_is_the_batch_evaluated_row_by_row(scored, cold):
    """More rows than one NumPy pass takes (batch.CHUNK_ROWS) give what each row alone gives."""
    est = ModelEstimator()
    obs = est.observation(scored)
    host = HostProblem(obs, est.lattice_for(obs))
    p = np.array(list(cold.details["params"].values()))
    rows = p + 0.01 * np.arange(CHUNK_ROWS + 3)[:, None] * np.array([1, -1, 0, 1, 1, 1])
    assert len(rows) > CHUNK_ROWS
    batch = host.column_batch(rows)
    for row, col in zip(rows, batch):
        np.testing.assert_array_equal(col, host.column(row))


def test_jacobian_plates_borrow_the_base_plate_statistics(scored, cold, monkeypatch):
    """column_batch(rows, like): each row with `like`'s cell statistics. Borrowing a row's own
    statistics changes nothing (bit for bit); the fit's Jacobian and covariance made that way
    (frozen blur, shift, pull-in) stay within 0.5 % of the exact ones per column, per sd
    (measured 0.16 % and 0.22 % on the stream bench's frame; this 2 mm / 4 mrad step moves the
    statistics by that much, what the exact derivative adds). Finite differences throughout
    (the covariance's analytic derivatives freeze the statistics too:
    tests/localization/model/test_model_derivatives.py)."""
    from nlos_cl.localization.model.solve import fit as model_fit
    from nlos_cl.localization.model.solve.covariance import covariance
    monkeypatch.setattr(model_fit, "ANALYTIC", False)
    est = ModelEstimator()
    obs = est.observation(scored)
    p = np.array(list(cold.details["params"].values()))
    rows = p + np.diag([0.01, -0.01, 0.0, 0.05, -0.1, 0.1])
    host = HostProblem(obs, est.lattice_for(obs))
    np.testing.assert_array_equal(host.column_batch(rows, like=rows), host.column_batch(rows))
    free = np.array([True, True, False, True, True, True])
    objective = model_fit._Objective(host, p[None], free)
    theta = p[free]
    borrowed = objective.jac(theta)
    result = model_fit.fit(host, p[None], free, 10)
    cov_borrowed = covariance(host, result, free)[0]
    own = HostProblem.column_batch  # the exact derivatives: every moved plate its own
    host.column_batch = lambda rows, like=None, **kw: own(host, rows, **kw)
    exact = objective.jac(theta)
    cov_exact = covariance(host, result, free)[0]
    err = np.linalg.norm(borrowed - exact, axis=0) / np.linalg.norm(exact, axis=0)
    assert err.max() <= 5e-3 and err.max() > 0  # > 0: the two paths did differ
    sd_b, sd_e = (np.sqrt(np.diag(c)[:6][free]) for c in (cov_borrowed, cov_exact))
    assert np.all(np.abs(sd_b / sd_e - 1) <= 5e-3)


def test_warm_start_agrees_with_the_cold_fit_within_its_sd(scored, cold):
    start = np.array(list(cold.details["params"].values()))
    start[:2] += (0.01, -0.01)  # a tracker's prediction is off by about this much
    w = _estimate(scored, start)
    assert w.details["warm_start"]["used"] and w.details["model"] == "upright plate"
    sd = np.sqrt(np.diag(cold.covariance)[:2])
    assert np.all(np.abs(w.position[:2] - cold.position[:2]) < sd), (w.position, cold.position)
    # and it carries the same calibrated covariance (sandwich x Birge ratio), not a default
    np.testing.assert_allclose(np.sqrt(np.diag(w.covariance)[:2]), sd, rtol=0.2)
    assert np.isinf(w.covariance[2, 2]) and "birge_ratio" in w.details
    assert "warm_start" not in cold.details  # a cold call is what it always was


def test_a_far_start_falls_back_to_the_cold_fit(scored, cold):
    start = np.array(list(cold.details["params"].values()))
    start[:2] += (0.5, 0.4)
    w = _estimate(scored, start)
    info = w.details["warm_start"]
    assert not info["used"] and "misses the data" in info["reason"]
    np.testing.assert_array_equal(w.position, cold.position)  # the cold fit, bit for bit
    np.testing.assert_array_equal(w.covariance, cold.covariance)


@pytest.fixture(scope="module")
def misfit_frame(runtime):
    """(scored, cold answer) of a frame the one-plate model cannot explain to the noise: the
    paper's plate and a 5 cm square beside it (Birge ratio ~12), as a learned background's
    residue or a person fitted as a plate leave data the cold fit misses too."""
    import trimesh
    mesh = trimesh.util.concatenate([nl.rectangle(0.3, 1.6, centre=TRUTH),
                                     nl.rectangle(0.05, 0.05, centre=(3.3, 2.9, 0.0))])
    raw = nl.add_noise(nl.simulate(nl.Scene(nl.paper_setup(), nl.Target(mesh), truth=TRUTH),
                                   backend=runtime), 10.0, seed=3)
    filtered = nl.gauss_filter(raw)
    scores = nl.Locator(filtered, GRID, estimator="model").scores(filtered)
    scored = Scored(filtered.backend, scores, GRID, False, filtered.n_detectors, filtered, raw)
    return scored, _estimate(scored)


def test_a_warm_fit_within_the_cold_fits_misfit_is_kept(misfit_frame):
    """Prior.misfit: the cold fit's Birge ratio is the model's floor on these data. Without it
    every such frame went cold and landed on the warm fit's answer (docs/scenes/walk.yaml);
    with it the warm fit is kept where it misses by no more than the floor, and a far start,
    in another basin, still falls back to the cold fit."""
    scored, cold = misfit_frame
    floor = cold.details["birge_ratio"]
    assert cold.details["model"] == "upright plate" and floor > 3  # misses the noise's test
    start = np.array(list(cold.details["params"].values()))
    near = start + np.array([0.01, -0.01, 0, 0, 0, 0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = ModelEstimator().estimate(scored, Prior(near[None])).targets[0]
        floored = ModelEstimator().estimate(scored, Prior(near[None], misfit=floor)).targets[0]
        far = ModelEstimator().estimate(scored, Prior((start + np.array(
            [0.5, 0.4, 0, 0, 0, 0]))[None], misfit=floor)).targets[0]
    assert not plain.details["warm_start"]["used"]  # the noise's test alone: cold
    assert floored.details["warm_start"]["used"] and "reason" not in floored.details[
        "warm_start"]
    sd = np.sqrt(np.diag(cold.covariance)[:2])
    assert np.all(np.abs(floored.position[:2] - cold.position[:2]) < sd)
    assert floored.fit.timings_s["forward_calls"] < cold.fit.timings_s["forward_calls"] / 5
    assert not far.details["warm_start"]["used"]
    np.testing.assert_array_equal(far.position, cold.position)


def test_the_warm_starts_are_tried_in_turn(monkeypatch):
    """policy.warm.warm_or_retry: the prior's rows, then with the late copies (Prior.late),
    then the last fit (Prior.measured, late copies kept), stopping at the first that explains
    the data; all missing, the cheapest miss is the cold fit's rival; every fit's calls
    counted."""
    from dataclasses import dataclass
    from types import SimpleNamespace as NS

    from nlos_cl.localization.model.policy import warm as policy

    @dataclass
    class Obs:
        late: object = None
    row = np.array([4.0, 2.0, 0.0, 0.3, 1.6, np.pi])
    tried, outcome = [], {}

    def fake(est, obs, rows, *args):
        tried.append((float(rows[0, 0]), obs.late is not None))
        cost = outcome.get(len(tried), 10.0 + len(tried))
        fitted = Fitted(NS(calls=5, model_s=0.1), Chosen(None, NS(cost=cost), None, None), [])
        info = {"used": cost < 1, "birge_ratio": 9.0, "nfev": 5, "forward_calls": 5,
                "moved_m": 0.0}
        return (fitted, info, None) if cost < 1 else (None, info, fitted)
    from nlos_cl.localization.model.solve.records import Chosen, Fitted
    monkeypatch.setattr(policy, "warm_fit", fake)
    est = ModelEstimator(targets=1)
    prior = Prior(row[None], late=True, measured=(row + [0.3, 0, 0, 0, 0, 0])[None])
    got, info, missed = policy.warm_or_retry(est, Obs(), prior, None, None)
    assert tried == [(4.0, False), (4.0, True), (4.3, True)] and got is None
    assert missed.result.cost == 11.0 and info["start"] == "prior"
    assert info["forward_calls"] == 15 and missed.problem.calls == 15
    tried.clear()
    outcome[2] = 0.5  # the late copies explain the data: the last fit is not tried
    got, info, _ = policy.warm_or_retry(est, Obs(), prior, None, None)
    assert len(tried) == 2 and info["start"] == "prior, late copies"
    assert got.problem.calls == 10


def test_a_track_keeps_the_misfit_of_its_cold_fits_only():
    """warm.keep: a cold fit's Birge ratio (or a warm fit kept after the cold one ran) is the
    track's floor; an accepted warm fit's is not (the floor would climb frame by frame);
    warm.prior carries the largest of the start tracks' floors, None where one has none."""
    from nlos_cl.tracking.track import Track

    def measured(birge, warm_start, counts=False):
        params = tuple(Parameter(n, v, -9.0, 9.0, True, 0.01) for n, v in
                       zip(("x", "y", "z", "width", "height", "yaw"),
                           (3.0, 2.0, 0.0, 0.3, 0.5, 3.1)))
        fit = ModelFit("plate", "upright plate", params, 1.0, np.zeros(3),
                       "poisson" if counts else "gauss", 0.0, 1, None if counts else birge,
                       True, warm_start=warm_start,
                       diagnostics={"misfit_ratio": birge} if counts else {})
        src = nl.LocatedTarget(np.array([3.0, 2.0, 0.0]), np.diag([1e-4] * 3), fit=fit)
        return kalman.measurement(src, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)
    a, b = (Track(i, np.zeros(4), np.eye(4), 0.0, status="confirmed") for i in (1, 2))
    warm.remember(a, measured(1.6, None))  # cold
    assert a.misfit == 1.6
    warm.remember(a, measured(1.8, WarmStart(True, 1.8, 4, 9, 0.01)))  # warm, kept
    assert a.misfit == 1.6
    warm.remember(a, measured(2.2, WarmStart(True, 2.2, 4, 9, 0.01, "the cold fit cost more")))
    assert a.misfit == 2.2
    warm.remember(b, measured(1.1, WarmStart(True, 1.1, 4, 9, 0.01)))  # no cold fit yet
    predictions = [kalman.Prediction(t, np.zeros(4), np.eye(4)) for t in (a, b)]
    assert b.misfit is None and warm.prior(predictions).misfit is None
    warm.remember(b, measured(1.3, None))
    assert warm.prior(predictions).misfit == 2.2
    warm.remember(b, measured(3.5, None, counts=True))  # counts: the deviance per dof
    assert b.misfit == 3.5 and warm.prior(predictions).misfit == 3.5


def test_a_closed_track_warm_starts_its_whole_frame_in_its_family():
    """warm.prior: where a track's last fit was a closed shape (a person's capsule), every row
    is a row of that family (Prior.shape), a plate track's at the family's least depth; a
    frame whose warm fit misses and whose cold fit returns plates reads the closed prior's
    sizes through their front faces (policy.warm.hidden_diagnostics: it raised ValueError,
    reshaping 14 numbers into plates of 6)."""
    from types import SimpleNamespace

    from nlos_cl.localization.model.policy.warm import hidden_diagnostics
    from nlos_cl.localization.model.shapes import box, capsule
    from nlos_cl.tracking.track import Track

    def measured(shape, values):
        names = ("x", "y", "z", "width", "height", "depth", "yaw")[:len(values)]
        if shape == "plate":
            names = ("x", "y", "z", "width", "height", "yaw")
        params = tuple(Parameter(n, v, -9.0, 9.0, True, 0.01) for n, v in zip(names, values))
        fit = ModelFit(shape, f"upright {shape}", params, 1.0, np.zeros(3), "gauss", 0.0, 1,
                       1.2, True, warm_start=None)
        src = nl.LocatedTarget(np.array(values[:3]), np.diag([1e-4] * 3), fit=fit)
        return kalman.measurement(src, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)
    person, wall = (Track(i, np.zeros(4), np.eye(4), 0.0, status="confirmed") for i in (1, 2))
    warm.remember(person, measured("capsule", (3.0, 2.0, 0.0, 0.5, 1.7, 0.5, 3.1)))
    warm.remember(wall, measured("plate", (1.0, 3.0, 0.0, 0.6, 0.8, 2.0)))
    assert (person.model, wall.model) == ("capsule", "plate")
    prior = warm.prior([kalman.Prediction(t, np.array([x, y, 0, 0]), np.eye(4))
                        for t, x, y in ((person, 3.1, 2.0), (wall, 1.0, 3.0))])
    assert prior.shape == "capsule" and prior.rows.shape == (2, 7)
    thin = box.from_plate([1.0, 3.0, 0.0, 0.6, 0.8, 2.0], float(capsule.LOWER[box.DEPTH]))
    np.testing.assert_allclose(prior.rows[1, 2:], thin[2:])  # at its predicted x, y
    assert prior.rows[0][0] == 3.1 and prior.measured.shape == (2, 7)
    plates = np.array([[3.0, 2.0, 0.0, 0.5, 1.7, 3.1], [1.0, 3.0, 0.0, 0.6, 0.8, 2.0]])
    problem = SimpleNamespace(shadows=True, obs=SimpleNamespace(
        laser=np.zeros(3), spots=np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.2]])))
    got = hidden_diagnostics(problem, SimpleNamespace(params=plates, prior=None), prior)
    assert len(got) == 2


def test_start_rows_are_checked(scored):
    with pytest.raises(nl.InputError, match="start"):
        ModelEstimator().estimate(scored, start=np.zeros((1, 5)))
    with pytest.raises(nl.InputError, match="start"):
        ModelEstimator(targets=2).estimate(scored, start=np.ones((1, 6)))


def _track(runtime, n_frames, tracker_options=None, meddle=None):
    from nlos_cl.tracking import MovingTarget, Trajectory, simulate_sequence
    setup = nl.paper_setup()
    walk = Trajectory([0, 1.0], [[3.5, 1.8, 0], [3.8, 2.2, 0]])
    target = MovingTarget(nl.Target(nl.rectangle(centre=walk.at(0), cell_m=0.03)), walk)
    frames = simulate_sequence(setup, target, n_frames=n_frames, fps=10, noise=nl.AWGN(10),
                               seed=1, facet_size_m=0.03, backend=runtime,
                               time_axis=nl.default_time_axis(setup, 1e-11))
    tracker, used = None, []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for fr in frames:
            tracker = tracker or Tracker(fr.signals, GRID, estimator="model",
                                         **(tracker_options or {}))
            if meddle is not None:
                meddle(tracker)
            tracker.update(fr.signals, fr.t_s)
            details = tracker.last_measurements[0].source.details
            used.append(details.get("warm_start", {}).get("used"))
            err = np.linalg.norm(tracker.last_measurements[0].position[:2] - fr.truths[0][:2])
            assert err < 0.05
    return tracker, used


def test_tracker_warm_starts_confirmed_tracks(runtime):
    _, used = _track(runtime, 5)
    assert used[:2] == [None, None]  # no confirmed track yet: cold, no start given
    assert all(used[2:])  # then each frame from the track's last plate, moved
    _, cold = _track(runtime, 3, {"plan": SearchPlan(warm_start=False)})
    assert cold == [None] * 3


def _push(also_the_fit):
    def push(tracker):  # a track whose state is 0.6 m off: its start lands in another basin
        for tr in tracker.tracks:
            if tr.status == "confirmed":
                tr.state[:2] += (0.4, 0.45)
                tr.covariance[:2, :2] = 1e-4 * np.eye(2)
                if also_the_fit:
                    tr.plate[:2] += (0.4, 0.45)
    return push


def test_tracker_falls_back_when_the_prediction_is_far_off(runtime):
    _, used = _track(runtime, 4, meddle=_push(also_the_fit=True))
    assert used[2:] == [False, False]  # tried, refused by the misfit test, fitted cold


def test_a_prediction_that_misses_is_retried_from_the_last_fit(runtime):
    """Prior.measured: a velocity learnt from a poor measurement sends the prediction out of
    the basin while the last fit lies within a frame's motion: tried from there before the
    cold fit."""
    tracker, used = _track(runtime, 3, meddle=_push(also_the_fit=False))
    assert used[2] is True  # (later frames: the pushed track's gate sends them cold)
    assert tracker.last_measurements[0].source.fit.warm_start.start == "last fit"


def test_the_gate_fallback_of_plate_tracks_fits_plates_only(runtime, monkeypatch):
    """A warm fit outside every gate is checked by a cold fit over the whole region; where
    every start track is a plate, that fit tries no closed shapes (warm.better compares the two
    fits' costs, which a closed shape's one more parameter would win alone), and the
    estimator's own setting is back after it."""
    seen = []
    locate, recheck = Tracker._locate, Tracker._recheck

    def spy(self, sig, prior, within=None):
        seen.append((self.estimator.closed, [t.model for t in self.tracks]))
        return locate(self, sig, prior, within)

    def checking(self, sig, starters):
        monkeypatch.setattr(Tracker, "_locate", spy)
        try:
            return recheck(self, sig, starters)
        finally:
            monkeypatch.setattr(Tracker, "_locate", locate)
    monkeypatch.setattr(Tracker, "_recheck", checking)
    tracker, _ = _track(runtime, 3, meddle=_push(also_the_fit=False))
    assert seen and all(closed is False and models == ["plate"] for closed, models in seen)
    assert tracker.estimator.closed == "auto"


def test_gate_fallback_sees_a_warm_fit_outside_every_gate():
    track = Tracker.__new__(Tracker)  # only the prediction tuple matters here
    x, P = np.array([3.0, 2.0, 0.1, 0.0]), np.diag([1e-4, 1e-4, 1e-2, 1e-2])
    near, far = ([3.005, 2.0, 0.0], [3.2, 2.0, 0.0])

    def measured(pos):
        fit = ModelFit("plate", "upright plate", (), 1.0, np.zeros(3), "gauss", 0.0, 1, 1.0, False,
                       warm_start=WarmStart(True, 1.0, 5, 5, 0.01))
        src = nl.LocatedTarget(np.array(pos), np.diag([1e-5, 1e-5, np.inf]), fit=fit)
        return kalman.measurement(src, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)
    assert not warm.outside_gates([measured(near)], [kalman.Prediction(track, x, P)], 0.999)
    assert warm.outside_gates([measured(far)], [kalman.Prediction(track, x, P)], 0.999)


def test_a_plate_the_data_want_none_of_has_no_information(scored, cold):
    """A second plate held at amplitude 0 (the non-negative bound) has zero derivatives; its
    parameters are unknown, so their variance is infinite, not the 0 a pseudo-inverse gives."""
    from nlos_cl.localization.model.solve.covariance import covariance
    from nlos_cl.localization.model.solve.fit import FitResult
    est = ModelEstimator()
    obs = est.observation(scored)
    host = HostProblem(obs, est.lattice_for(obs))
    first = np.array(list(cold.details["params"].values()))
    spare = np.array([-3.0, 0.5, 0.0, 0.3, 0.3, 0.0])  # beside the wall, far to the side
    params = np.stack([first, spare])
    cols = host.columns(params)
    lin = np.array([host.linear(cols[:1])[0], 0.0])
    r = host.residual(cols, lin)
    cov, _ = covariance(host, FitResult(params, lin, float(r @ r), r.size, 0),
                        np.array([True, True, False, True, True, True]))
    assert np.all(np.isinf(np.diag(cov)[6:]))
    assert np.all(np.isfinite(np.diag(cov)[[0, 1, 3, 4, 5]]))


def test_a_misfit_warm_fit_is_kept_where_the_cold_fit_costs_more(monkeypatch):
    """estimator._warm_or_cold: the warm fit misses the data, the cold fit runs, and the one of
    lower cost is the answer (with the cold fit's work counted and the reason said)."""
    from types import SimpleNamespace as NS

    from nlos_cl.localization.model import estimator
    from nlos_cl.localization.model.policy import warm
    from nlos_cl.localization.model.solve.records import Chosen, Fitted
    est = ModelEstimator()
    row = np.array([4.0, 2.0, 0.0, 0.3, 1.6, np.pi])

    def fitted(cost, calls):
        return Fitted(NS(calls=calls, model_s=0.1), Chosen(None, NS(cost=cost), None, None), [])
    info = {"used": False, "birge_ratio": 9.0, "nfev": 5, "forward_calls": 7, "moved_m": 0.01,
            "reason": "the warm fit misses the data"}
    for cold_cost, keep_warm in ((50.0, True), (5.0, False)):
        missed = fitted(10.0, 7)
        monkeypatch.setattr(warm, "warm_fit", lambda *a, **k: (None, dict(info), missed))
        monkeypatch.setattr(ModelEstimator, "_cold", lambda self, *a: fitted(cold_cost, 100))
        got, got_info = estimator._warm_or_cold(est, NS(backend=None), None, None, None, 0.0,
                                                Prior(row[None]), {})
        assert (got is missed) == keep_warm
        if keep_warm:
            assert got_info["used"] and "the cold fit cost more" in got_info["reason"]
            assert got.problem.calls == 107  # the cold fit's 100 evaluations counted
        else:
            assert not got_info["used"] and got.result.cost == 5.0
    seen = []  # the Prior's sizes reach the warm fit (model.warm.size_prior), checked
    monkeypatch.setattr(warm, "warm_fit", lambda *a, **k: seen.append(a) or
                        (None, dict(info), fitted(10.0, 7)))
    estimator._warm_or_cold(est, NS(backend=None), None, None, None, 0.0,
                            Prior(row[None], row[None, 3:5], np.full((1, 2), 0.02)), {})
    np.testing.assert_array_equal(seen[0][6][0], row[None, 3:5])
    np.testing.assert_array_equal(seen[0][6][1], np.full((1, 2), 0.02))


def test_a_track_learns_its_size_only_where_the_fit_saw_the_plate_whole():
    """warm.remember: a fit with hidden_share <= tuning.HIDDEN_SHARE adds its size, a
    partly hidden one (which fits small) does not, but a track's first plate seeds the memory
    (a target never seen whole keeps the size it was found with); warm.prior carries the mean
    size and its sd (5 % of it beside the sizes' own scatter), inf where no size is known."""
    from nlos_cl.tracking.track import Track

    def measured(width, hidden):
        params = tuple(Parameter(n, v, -9.0, 9.0, True, 0.01) for n, v in
                       zip(("x", "y", "z", "width", "height", "yaw"),
                           (3.0, 2.0, 0.0, width, 0.5, 3.1)))
        fit = ModelFit("plate", "upright plate", params, 1.0, np.zeros(3), "gauss", 0.0, 1, 1.0,
                       True, diagnostics={"hidden_share": hidden})
        src = nl.LocatedTarget(np.array([3.0, 2.0, 0.0]), np.diag([1e-4] * 3), fit=fit)
        return kalman.measurement(src, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)
    track = Track(1, np.array([3.0, 2.0, 0.0, 0.0]), np.eye(4) * 1e-4, 0.0, status="confirmed")
    warm.remember(track, measured(0.60, 0.30))  # the first plate seeds the memory...
    assert track.size_seeded
    for width, hidden in ((0.40, 0.0), (0.42, 0.05), (0.38, 0.0)):  # ...until one seen whole
        warm.remember(track, measured(width, hidden))
    assert not track.size_seeded
    warm.remember(track, measured(0.15, 0.45))  # half hidden: fitted small, not learnt
    warm.remember(track, measured(0.16, 0.06))  # just over HIDDEN_SHARE: not learnt
    warm.remember(track, measured(0.17, None))  # unknown (K >= 2 without shadows): not learnt
    assert track.plate[3] == 0.17  # still the next warm start's row
    size, sd = warm.size_of(track)
    np.testing.assert_allclose(size, [0.40, 0.5])
    np.testing.assert_allclose(sd[0], np.hypot(0.05 * 0.40, np.std([0.40, 0.42, 0.38])))
    prior = warm.prior([kalman.Prediction(track, np.array([3.1, 2.0, 0.0, 0.0]), np.eye(4))])
    np.testing.assert_allclose(prior.rows[0, :2], [3.1, 2.0])
    np.testing.assert_allclose(prior.size[0], [0.40, 0.5])
    assert prior.rows[0, 3] == 0.17  # the start row is the last plate's; the estimator decides
    born_hidden = Track(3, np.zeros(4), np.eye(4), 0.0, status="confirmed")
    warm.remember(born_hidden, measured(0.45, 0.3))
    warm.remember(born_hidden, measured(0.20, 0.3))  # shrinking in the shadow: not learnt
    np.testing.assert_allclose(np.array(born_hidden.sizes), [[0.45, 0.5]])
    fresh = Track(2, np.zeros(4), np.eye(4), 0.0, status="confirmed")
    warm.remember(fresh, measured(0.3, 0.0))
    fresh.sizes.clear()
    none = warm.prior([kalman.Prediction(fresh, np.zeros(4), np.eye(4))])
    assert np.isinf(none.size_sd).all()


def test_the_paper_tracker_never_imports_the_model_package():
    """warm.remember on a measurement without a plate fit (the paper's estimator) returns
    before anything of nlos_cl.localization.model is imported (a fresh interpreter)."""
    import subprocess
    import sys
    code = ("import sys, numpy as np, nlos_cl as nl\n"
            "from nlos_cl.tracking import kalman, warm\n"
            "from nlos_cl.tracking.track import Track\n"
            "src = nl.LocatedTarget(np.array([3.0, 2.0, 0.0]), np.eye(3) * 1e-4)\n"
            "m = kalman.measurement(src, 2, fallback_sigma_m=0.05, min_sigma_m=0.002)\n"
            "t = Track(1, np.zeros(4), np.eye(4), 0.0)\n"
            "warm.remember(t, m)\n"
            "assert t.plate is None and not t.sizes\n"
            "print('nlos_cl.localization.model' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"

