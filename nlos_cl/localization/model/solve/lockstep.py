"""Several model fits run in lockstep (`fit_together`): each is a model.lm.solve generator, and
at every round the fits' pending requests are answered together, every fit's trial plate in
one `column_batch` and every fit's Jacobian plates in another, so a round costs about one
batch where the fits one after another cost one call each (the host model's cost is mostly
per call: docs/results/performance/performance.md, "The host model's floor"). Each fit takes the path and reaches
the answer it would alone (batched plates are summed in another order: within 1e-12 m), on
Gaussian (filtered) data; photon counts are fitted one after another (`fit_together`).
Used by model.select.best_of's short fits: cold frames 7-11 % faster."""
from __future__ import annotations

import numpy as np

from .fit import FitResult, _Objective, fit
from .lm import drive_together


def fit_together(problem, starts, free, max_nfev=30) -> list[FitResult]:
    """model.fit.fit from each of `starts` (a list of (K, N_PARAMS) params0), the same
    answers, the fits run in lockstep. The fits run one after another where the problem models
    the shadows of K >= 2 plates (not batched here), and for photon counts: a plate's
    histograms depend on its batch in the last bits (the deposit's window is the batch's
    widest pulse), and the Poisson fit magnifies that (K = 2: 3.9 mm apart)."""
    objs = [_Objective(problem, p, free) for p in starts]
    if len(objs) < 2 or problem.obs.mode != "gauss" or (
            problem.shadows and len(objs[0].base) > 1):
        return [fit(problem, p, free, max_nfev) for p in starts]
    results = drive_together([o.solver(max_nfev) for o in objs],
                             lambda asked: _answers(problem, objs, asked))
    return [obj.result(sol) for obj, sol in zip(objs, results)]


def _answers(problem, objs, asked) -> list:
    """Answers to the fits' requests (model.lm.solve): the plates of points not evaluated yet
    in one column_batch, then the Jacobians' moved plates (each borrowing its unmoved plate's
    cell statistics, as _Objective.jac) in one."""
    fresh = [(i, r[1]) for i, r in asked if r[0] in ("fun", "jac")
             and objs[i]._key != np.asarray(r[1]).tobytes()]
    if fresh:
        rows = [objs[i].full(x) for i, x in fresh]
        cols = problem.column_batch(np.concatenate(rows))
        for (i, x), a, b in _spans(fresh, [len(r) for r in rows]):
            objs[i]._eval(x, cols[a:b])  # kept, as if the fit had evaluated x itself
    jacs = [(i, r[1]) for i, r in asked if r[0] == "jac"]
    stepped = {}
    if jacs:
        moves = [objs[i].moves(x) for i, x in jacs]
        rows = [row for m in moves for _, row in m]
        like = [objs[i].full(x)[k] for (i, x), m in zip(jacs, moves) for k, _ in m]
        evaluated = problem.column_batch(np.array(rows), np.array(like))
        for ((i, x), a, _), m in zip(_spans(jacs, [len(m) for m in moves]), moves):
            out = np.repeat(objs[i]._eval(x)[0][None], len(m), axis=0)  # no shadows: only
            for n, (k, _) in enumerate(m):  # the moved plate's column changes
                out[n, k] = evaluated[a + n]
            stepped[i] = objs[i].jac(x, stepped=out)
    return [stepped[i] if r[0] == "jac" else objs[i].answer(r) for i, r in asked]


def _spans(items, sizes):
    """(item, start, end) of consecutive blocks of the given sizes."""
    at = np.cumsum([0, *sizes])
    return [(item, int(a), int(b)) for item, a, b in zip(items, at[:-1], at[1:])]
