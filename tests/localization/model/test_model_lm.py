"""nlos_cl.localization.model.solve.lm, the in-house bounded Levenberg-Marquardt that replaced SciPy's
`least_squares` in the model fit (its import was ~0.25 s of a one-shot `nlos-cl locate`):
the same optimum as SciPy's 'trf' on synthetic and real model problems, bounds never left,
max_nfev never exceeded, bad options named."""
import math

import numpy as np
import pytest
from scipy.optimize import least_squares as scipy_least_squares
from scipy.optimize import lsq_linear

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.localization.model.forward import data
from nlos_cl.localization.model.shapes import plate
from nlos_cl.localization.model.shapes.lattices import GAUSS_LATTICE
from nlos_cl.localization.model.solve.fit import _Objective, fit
from nlos_cl.localization.model.forward.likelihood import Problem
from nlos_cl.localization.model.solve.lm import least_squares

TIGHT = dict(ftol=1e-12, xtol=1e-12, gtol=1e-12)
T = np.linspace(0.0, 4.0, 40)
Y = 2.5 * np.exp(-1.3 * T) + 0.5 + 0.01 * np.random.default_rng(0).standard_normal(40)


def rosenbrock(x):
    return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])


def rosenbrock_jac(x):
    return np.array([[-20.0 * x[0], 10.0], [-1.0, 0.0]])


def decay(p):
    return p[0] * np.exp(-p[1] * T) + p[2] - Y


class Recorder:
    """fun, recording every point it is evaluated at."""

    def __init__(self, fun):
        self.fun, self.points = fun, []

    def __call__(self, x):
        self.points.append(np.array(x, dtype=float))
        return self.fun(x)


# Both solvers run to 1e-12 tolerances on well-conditioned problems, so both land on the optimum
# to ~sqrt(1e-12) of its scale or better: 1e-6 separates "same optimum" from "another point".
SAME_X = 1e-6
SYNTHETIC = [  # (name, fun, jac, x0, bounds)
    ("rosenbrock", rosenbrock, rosenbrock_jac, [-1.2, 1.0], (-np.inf, np.inf)),
    ("rosenbrock, optimum on a bound", rosenbrock, rosenbrock_jac, [-1.2, 1.0],
     ([-2.0, -2.0], [0.5, 2.0])),
    ("rosenbrock, start on the far side", rosenbrock, rosenbrock_jac, [2.0, 2.0],
     ([1.5, -np.inf], [3.0, 10.0])),
    ("decay, numerical Jacobian", decay, None, [1.0, 1.0, 0.0], (-np.inf, np.inf)),
    ("decay, rate held at its lower bound", decay, None, [2.0, 2.0, 0.0],
     ([0.0, 1.5, 0.0], [10.0, 10.0, 10.0])),
]


@pytest.mark.parametrize("name, fun, jac, x0, bounds", SYNTHETIC, ids=[c[0] for c in SYNTHETIC])
def test_same_optimum_as_scipy_and_bounds_respected(name, fun, jac, x0, bounds):
    ref = scipy_least_squares(fun, x0, jac=jac or "2-point", bounds=bounds, method="trf",
                              **TIGHT)
    rec = Recorder(fun)
    sol = least_squares(rec, x0, jac=jac, bounds=bounds, **TIGHT)
    assert np.allclose(sol.x, ref.x, atol=SAME_X, rtol=0), (sol.x, ref.x)
    assert sol.cost == pytest.approx(0.5 * float(sol.fun @ sol.fun))
    lo, hi = (np.broadcast_to(b, len(x0)) for b in bounds)
    assert all(np.all(p >= lo) and np.all(p <= hi) for p in rec.points)
    assert sol.status in (1, 2, 3, 4)


@pytest.mark.parametrize("truth", [(4.0, 2.0), (1.0, 5.0), (-2.0, 0.5)])
def test_ellipse_point_problem_as_scipy_solves_it(truth):
    """The start finder's problem (nlos_cl.localization.model.policy.starts.ellipse_point, which still calls SciPy):
    the point in front of the wall whose paths laser -> point -> spot match measured paths,
    numerical Jacobian, y >= 0.05: the same point from the same starts."""
    laser, spots = np.array([0.0, 0.0]), np.array([[-0.5, 0.0], [-1.0, 0.0], [-1.5, 0.0]])
    c = np.array(truth)
    paths = np.linalg.norm(c - laser) + np.linalg.norm(spots - c, axis=1) + [0.002, -0.001, 0.0]

    def res(v):
        return np.linalg.norm(v - laser) + np.linalg.norm(spots - v, axis=1) - paths
    for v0 in ([0.5 * paths[0], 0.7 * paths[0]], [0.9 * paths[0], 0.3 * paths[0]]):
        ref = scipy_least_squares(res, v0, bounds=([-np.inf, 0.05], np.inf), method="trf")
        sol = least_squares(res, v0, bounds=([-np.inf, 0.05], np.inf))
        # Default tolerances (1e-8): a solver that stops on the gradient (|J^T r| <= gtol) or
        # on the cost (a relative drop <= ftol) is within gtol / lam or sqrt(2 ftol cost / lam)
        # of the optimum, lam the least eigenvalue of J^T J; two such solvers at most twice
        # that apart. Seen from three spots on a line, (4, 2) is weakly curved (lam 2.5e-3):
        # 8e-6 m (SciPy 1.17 vs ours 9.5e-7 apart here, 1.0e-6 with NumPy 2.5 / another SciPy);
        # the others 2.6e-6 and 1.2e-6 m.
        lam = float(np.linalg.eigvalsh(ref.jac.T @ ref.jac).min())
        apart = 2 * max(1e-8 / lam, math.sqrt(2e-8 * ref.cost / lam))
        assert np.allclose(sol.x, ref.x, atol=apart, rtol=0), (sol.x, ref.x, apart)


@pytest.mark.parametrize("seed", range(6))
def test_box_constrained_linear_problems_match_bvls(seed):
    """Random linear least squares in a box (some bounds active at the optimum, some not):
    the exact box-constrained optimum from SciPy's BVLS."""
    rng = np.random.default_rng(seed)
    a, b = rng.standard_normal((30, 5)), rng.standard_normal(30) * 3
    lo, hi = -rng.uniform(0.05, 0.5, 5), rng.uniform(0.05, 0.5, 5)
    exact = lsq_linear(a, b, bounds=(lo, hi), method="bvls").x
    sol = least_squares(lambda x: a @ x - b, np.zeros(5), jac=lambda x: a, bounds=(lo, hi),
                        **TIGHT)
    assert np.allclose(sol.x, exact, atol=SAME_X, rtol=0), (sol.x, exact)
    assert np.any(np.isclose(exact, lo) | np.isclose(exact, hi))  # the box matters here


@pytest.mark.parametrize("max_nfev", [1, 2, 5])
def test_max_nfev_counts_residual_calls_and_is_never_exceeded(max_nfev):
    rec = Recorder(rosenbrock)
    sol = least_squares(rec, [-1.2, 1.0], jac=rosenbrock_jac, max_nfev=max_nfev)
    assert len(rec.points) == sol.nfev <= max_nfev
    assert sol.status == 0 and "maximum number" in sol.message


def test_x_scale_is_a_change_of_variables():
    """Solving f(x) with x_scale s reaches the optimum of f(s u) solved in u: the same point."""
    s = np.array([100.0, 0.01, 1.0])
    scaled = least_squares(lambda u: decay(s * u), np.array([1.0, 1.0, 0.0]) / s, **TIGHT)
    sol = least_squares(decay, [1.0, 1.0, 0.0], x_scale=s, **TIGHT)
    assert np.allclose(sol.x, s * scaled.x, atol=SAME_X, rtol=0)


@pytest.mark.parametrize("kwargs, field", [
    (dict(bounds=([1.0, 0.0], [0.0, 1.0])), "bounds"),
    (dict(x_scale=[1.0, 0.0]), "x_scale"),
    (dict(max_nfev=0), "max_nfev"),
])
def test_bad_options_name_the_field(kwargs, field):
    with pytest.raises(InputError, match=f"^{field}:.*Fix:"):
        least_squares(rosenbrock, [0.5, 0.5], **kwargs)


def test_a_one_residual_jacobian_may_be_one_dimensional():
    sol = least_squares(lambda x: np.array([x[0] + x[1] - 3.0]), [0.0, 0.0],
                        jac=lambda x: np.array([1.0, 1.0]), **TIGHT)
    assert sol.x.sum() == pytest.approx(3.0, abs=1e-9)


def test_bad_start_names_x0():
    with pytest.raises(InputError, match="^x0:"):
        least_squares(rosenbrock, [math.nan, 0.0])


# ------------------------------------------------------------------ real model fits
def _paper_problem(seed):
    position, size = (3.0, 2.0, 0.0), (0.3, 1.6)
    mesh = nl.rectangle(size[0], size[1], centre=position, normal=(-1, 0, 0), cell_m=0.01)
    scene = nl.Scene(nl.paper_setup(), nl.Target(mesh), 0.01, truth=position)
    clean = nl.simulate(scene, nl.default_time_axis(scene.setup, 10e-12))
    noisy = nl.add_noise(clean, 10, seed)
    obs = data.gaussian_observation(clean.layout, nl.gauss_filter(noisy).histograms().data,
                                    noisy.histograms().data)
    return Problem(obs, clean.backend, GAUSS_LATTICE), np.array([*position, *size, math.pi])


def _scipy_fit(problem, params0, free, max_nfev):
    """fit() as it was, through SciPy's 'trf': the reference."""
    obj = _Objective(problem, params0, free)
    lo, hi = (np.tile(b, len(obj.base))[obj.free] for b in (plate.LOWER, plate.UPPER))
    sol = scipy_least_squares(obj.residual, obj.base.reshape(-1)[obj.free], jac=obj.jac,
                              bounds=(lo, hi), method="trf", ftol=1e-7, xtol=1e-5,
                              x_scale=np.tile(plate.X_SCALE, len(obj.base))[obj.free],
                              max_nfev=max_nfev)
    r = obj.residual(sol.x)
    return obj.full(sol.x), float(r @ r)


@pytest.mark.parametrize("seed, offset", [(0, (0.04, -0.03, 0.0, 0.1, -0.2, 0.15)),
                                          (1, (-0.05, 0.05, 0.0, -0.05, 0.3, -0.2))])
def test_model_fit_reaches_scipys_optimum(seed, offset):
    problem, truth = _paper_problem(seed)
    free = np.array([True, True, False, True, True, True])  # collinear spots: z unobservable
    start = (truth + np.array(offset))[None]
    ref_params, ref_cost = _scipy_fit(problem, start, free, 60)
    ours = fit(problem, start, free, max_nfev=60)
    # Both solvers stop where their forward-difference gradient (2 mm, 4 mrad steps) vanishes,
    # which sits off the true optimum by the differences' truncation error, a different amount
    # along each solver's path: on seed 1 the two ends differ by 0.012 in cost (6.7e-5 of it),
    # 0.7 mm in width, 1.2 mrad in yaw, on a smooth valley. The cost is -2 log L, so "the same
    # optimum" is said in sd: not worse by more than 0.1 (two points within 0.3 sd along the
    # worst-determined direction), and the centre (what the estimator reports) within 0.1 sd.
    assert ours.cost <= ref_cost + 0.1, (ours.cost, ref_cost)
    sd = np.sqrt(np.diag(np.linalg.inv(_hessian(problem, ours, free))))[:2]
    assert np.all(np.abs(ours.params[0, :2] - ref_params[0, :2]) < 0.1 * sd)
    assert ours.nfev <= 60
    lo, hi = plate.LOWER, plate.UPPER
    assert np.all(ours.params[0] >= lo) and np.all(ours.params[0] <= hi)


def test_fits_in_lockstep_give_each_fit_its_own_answer():
    """fit_together (the short fits of model.select.best_of) runs several fits with their
    model calls batched (HostProblem.column_batch): each fit's path and answer are the ones
    it takes alone. Batched plates are summed in another order, so the numbers may differ in
    the last bits (1e-12 m here), not in any decision of the solver (same nfev)."""
    from nlos_cl.localization.model.forward.batch import HostProblem
    from nlos_cl.localization.model.solve.lockstep import fit_together
    problem, truth = _paper_problem(2)
    host = HostProblem(problem.obs, GAUSS_LATTICE)
    free = np.array([True, True, False, True, True, True])
    starts = [(truth + np.array(d))[None] for d in
              [(0.04, -0.03, 0, 0.1, -0.2, 0.15), (-0.05, 0.05, 0, -0.05, 0.3, -0.2),
               (0.02, 0.06, 0, 0.0, 0.1, 0.4)]]
    calls = []
    batch = host.column_batch
    host.column_batch = lambda *a, **k: calls.append(len(a[0])) or batch(*a, **k)
    together = fit_together(host, starts, free, 6)
    n_together = len(calls)
    alone = [fit(host, s, free, 6) for s in starts]
    assert n_together < len(calls) - n_together  # fewer model calls in lockstep
    for a, b in zip(together, alone):
        np.testing.assert_allclose(a.params, b.params, rtol=0, atol=1e-9)
        assert a.nfev == b.nfev and a.cost == pytest.approx(b.cost, rel=1e-9)


def _hessian(problem, result, free):
    """J'J of the profiled residual at the fit (Gauss-Newton: the inverse covariance of the
    free parameters, for the scale of 'the same optimum')."""
    obj = _Objective(problem, result.params, free)
    j = obj.jac(result.params.reshape(-1)[obj.free])
    return j.T @ j


def test_table_erf_matches_math_erf():
    """nlos_cl.core.erf (SciPy-free, for the host model) against math.erf: within 1e-13 absolute
    (its cubic Hermite bound is ~1e-14), odd, and 1 beyond the table."""
    from nlos_cl.core.erf import erf
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.uniform(-9, 9, 50_000), rng.normal(0, 0.5, 20_000),
                        [0.0, 1e-12, 5.999, 6.0, 6.5, 40.0]])
    ref = np.array([math.erf(v) for v in x])
    assert np.max(np.abs(erf(x) - ref)) < 1e-13
    assert np.array_equal(erf(-x), -erf(x))
    assert erf(np.array([[0.5]])).shape == (1, 1)


def test_atol_stops_on_the_best_gain_the_jacobian_allows(monkeypatch):
    """With atol the solver stops once the Gauss-Newton step of the Jacobian at x (or, after
    a short accepted step, of the Jacobian in hand) would gain < atol: no trial step is
    evaluated, and no Jacobian made, only to learn that the fit is done; the cost it leaves
    is within the atol scale of the optimum, and fewer calls than the plain test (the gain
    of the step just tried, after evaluating it) take."""
    from nlos_cl.localization.model.solve import lm
    jacs = []

    def jac(x):
        jacs.append(x)
        h = 1e-7
        return np.stack([(decay(x + h * e) - decay(x)) / h for e in np.eye(3)], axis=1)
    ref = least_squares(decay, [1.0, 1.0, 0.0], jac=jac, **TIGHT)
    atol = 1e-4 * ref.cost
    runs = {}
    for best in (False, True):
        with monkeypatch.context() as m:
            if not best:  # the plain test alone
                m.setattr(lm, "_best_gain", lambda *args: math.inf)
            jacs.clear()
            sol = least_squares(decay, [1.0, 1.0, 0.0], jac=jac, atol=atol)
            runs[best] = (sol, len(jacs))
    (plain, plain_jacs), (sol, sol_jacs) = runs[False], runs[True]
    assert sol.status == 5  # (the plain run went on until ftol)
    assert sol_jacs + sol.nfev < plain_jacs + plain.nfev
    assert sol.cost - ref.cost < atol and plain.cost - ref.cost < 2 * atol
    assert np.array_equal(sol.jac_x, sol.x)  # stopped at the Jacobian's point
