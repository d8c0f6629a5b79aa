"""select.best_of (the first plate's search: finish_misfit) looks past its best short fit where
that one's final fit misses the data: a short fit ranks basins by where a few evaluations got,
and at high SNR the right basin can descend slower (scenario bins draw 36: an oblique plate in
counts, 0.35 m -> 2 mm). The rule on canned fits (which fits run, which final is kept); the
draw: tests/apps/test_scenario_draws.py."""
from types import SimpleNamespace

import numpy as np

from nlos_cl.localization.model.policy import select
from nlos_cl.localization.model.solve.fit import FitResult

N = 1000  # residuals: a cost of ~N explains the data, 10 N misses it
R = select.FINISH_RATIO


def _result(tag, cost):
    return FitResult(np.array([[float(tag)] * 6]), np.array([1.0]), float(cost), N, 6)


def _run(monkeypatch, shorts, finals, more=None, finish_misfit=True):
    """best_of with short fits `shorts` ((tag, cost), best first), which SHORT_NFEV more
    evaluations take to `more[tag]` and a final fit to `finals[tag]`: (the kept final's cost,
    what ran: ('more', tags) for a batch of continued short fits, a tag for a final fit)."""
    ran, batches = [], []
    monkeypatch.setattr(select.starts, "best_starts", lambda *a, **k: [0] * len(shorts))

    def together(problem, rows, free, nfev):
        if not batches:
            batches.append(1)
            return [_result(t, c) for t, c in shorts]
        tags = [int(r[0][0]) for r in rows]
        ran.append(("more", tags))
        return [_result(t, more[t]) for t in tags]

    def fit(problem, params, free, nfev, atol=None):
        tag = int(params[0][0])
        ran.append(tag)
        return _result(tag, finals[tag])
    monkeypatch.setattr(select, "fit_together", together)
    monkeypatch.setattr(select, "fit", fit)
    problem = SimpleNamespace(obs=SimpleNamespace(mode="gauss", rho=np.zeros(1)))
    kept = select.best_of(problem, np.zeros((3, 6)), np.ones(6, bool), 30,
                          finish_misfit=finish_misfit)
    return kept.cost, ran


SHORTS = [(1, 5 * N), (2, 6 * N), (3, 7 * N)]


def test_a_final_fit_that_explains_the_data_ends_the_search(monkeypatch):
    assert _run(monkeypatch, SHORTS, {1: N}) == (N, [1])


def test_a_basin_far_cheaper_after_a_few_more_evaluations_is_finished(monkeypatch):
    # 36's case: the first final misses by far; the second short fit drops past it
    cost, ran = _run(monkeypatch, SHORTS, {1: 50 * N, 2: 0.9 * N},
                     more={2: 50 * N / (2 * R), 3: 40 * N})
    assert (cost, ran) == (0.9 * N, [1, ("more", [2, 3]), 2])


def test_cheaper_basins_that_are_not_far_cheaper_leave_the_first(monkeypatch):
    # a closed target's plate: other plate basins a few times cheaper are not better seeds
    cost, ran = _run(monkeypatch, SHORTS, {1: 50 * N}, more={2: 50 * N / R * 1.01, 3: 8 * N})
    assert (cost, ran) == (50 * N, [1, ("more", [2, 3])])


def test_a_finished_basin_that_ends_dearer_is_not_kept(monkeypatch):
    cost, ran = _run(monkeypatch, SHORTS, {1: 50 * N, 3: 60 * N},
                     more={2: 40 * N, 3: 50 * N / (2 * R)})
    assert (cost, ran) == (50 * N, [1, ("more", [2, 3]), 3])


def test_other_searches_finish_only_their_best_short_fit(monkeypatch):
    assert _run(monkeypatch, SHORTS, {1: 50 * N}, finish_misfit=False) == (50 * N, [1])


def test_an_implausible_final_fit_gives_way_to_the_next_plausible_one(monkeypatch):
    monkeypatch.setattr(select, "_plausible", lambda r: r.cost != 0.5 * N)  # 1's final
    for finish in (True, False):
        assert _run(monkeypatch, SHORTS[:2], {1: 0.5 * N, 2: 40 * N},
                    finish_misfit=finish) == (40 * N, [1, 2])
