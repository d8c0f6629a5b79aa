"""The nonlinear fit (bounded Levenberg-Marquardt, model.lm) of K targets, the linear
factors profiled out at every step (variable projection); the covariance of the result is
model.covariance's.

The target's shape is the problem's `shape` module (default model.plate): its N_PARAMS,
LOWER, UPPER, STEPS and X_SCALE are read from there, so a new shape needs no edit here.
Finite-difference steps are absolute (STEPS: 2 mm, 4 mrad for the plate): the forward kernel
works in float32, so relative steps (~1e-8) would differentiate rounding noise. A Jacobian
column re-simulates only the target whose parameter moved, and, where K >= 2 plates can shadow
each other (model.shadow, HostProblem only), the targets the moved one can shadow.

Jacobians (and model.covariance's derivatives) tell `column_batch` which row each moved plate steps from (`like`);
the host's HostProblem then evaluates the moved plates with the unmoved plate's cell
statistics (nlos_cl.localization.model.forward.batch):
derivatives at frozen blur and shift, within 0.2 % of the exact ones per column and per sd
(tests/tracking/test_tracking_warm.py), for half the work of a column. Residuals are always exact, so
the fitted parameters do not depend on it beyond the solver's tolerance.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .amplitudes import stepped_residuals
from .lm import drive, solve
from .width_vectors import WidthVectors


@dataclass
class FitResult:
    params: np.ndarray  # (K, N_PARAMS)
    linear: np.ndarray  # amplitudes (and backgrounds for Poisson)
    cost: float  # sum of squared residuals (= -2 log L + const)
    n_residuals: int
    nfev: int
    cov: np.ndarray | None = None  # (K*N, K*N) over all parameters (inf where fixed)
    # a Gaussian prior on parameters, (mean (K, N), sd (K, N); inf: none), or None: the fit
    # minimised cost + prior_cost; `cost` is the data's alone (Birge ratios, comparisons)
    prior: tuple | None = None
    prior_cost: float = 0.0
    # the solver's last Jacobian (forward differences of the profiled residuals, the prior's
    # rows below the data's) and the parameters (K, N) it was taken at: at or one accepted step
    # before `params`; None where it has none (model.covariance's `reuse`)
    jacobian: tuple | None = None
    columns: np.ndarray | None = None  # (K, D, n) the targets' columns at params, if kept


def shape_of(problem):
    """The target model's module (the problem's `shape`)."""
    return problem.shape


class _Objective:
    """Residual and Jacobian of the profiled problem over the free parameters."""

    def __init__(self, problem, params0, free, prior=None, speculate=False):
        self.problem, self.shape = problem, shape_of(problem)
        self.base = np.array(params0, dtype=np.float64).reshape(-1, self.shape.N_PARAMS)
        self.free = np.tile(np.asarray(free, bool), len(self.base))
        self.steps = np.tile(self.shape.STEPS, len(self.base))[self.free]
        self._key, self._cols, self._lin = None, None, None
        # fit's `speculate`: one target on a problem that evaluates a batch of rows in one call
        self.speculate = speculate and len(self.base) == 1 and problem.batched
        self._stepped = None  # (theta's key, its stepped columns) from the last such call
        # the prior's residuals (theta[at] - mean) / sd, over the free parameters it bounds
        self.at, self.mean, self.sd = _prior_terms(prior, self.base.shape, self.free)
        self.prior = prior if self.at.size else None

    def start(self):
        """(theta0, lo, hi): the start put inside the bounds, and the bounds."""
        shape, k = self.shape, len(self.base)
        lo, hi = (np.tile(b, k)[self.free] for b in (shape.LOWER, shape.UPPER))
        return np.clip(self.base.reshape(-1)[self.free], lo + 1e-6, hi - 1e-6), lo, hi

    def solver(self, max_nfev, tau=None, atol=None, variables=None, best_gain=True):
        """model.lm.solve over the free parameters, from the start put inside the bounds;
        variables: None, or a WidthVectors the solver works in instead; best_gain: lm's."""
        theta0, lo, hi = self.start()
        if variables is not None:
            theta0, (lo, hi) = variables.to_phi(theta0), variables.bounds(lo, hi)
        return solve(theta0, (lo, hi), np.tile(self.shape.X_SCALE, len(self.base))[self.free],
                     ftol=1e-7, xtol=1e-5, max_nfev=max_nfev,
                     atol=atol, best_gain=best_gain, **({} if tau is None else {"tau": tau}))

    def answer(self, request):
        """What the solver asks for (model.lm.solve): the residual or the Jacobian."""
        kind, theta = request[0], request[1]
        return self.residual(theta) if kind == "fun" else self.jac(theta)

    def result(self, sol, keep_jacobian: bool = False) -> FitResult:
        cols, lin = self._eval(sol.x)
        r, pr = self.problem.residual(cols, lin), self.prior_residual(sol.x)
        kept = keep_jacobian and sol.jac is not None
        return FitResult(self.full(sol.x), lin, float(r @ r), int(r.size), int(sol.nfev),
                         prior=self.prior, prior_cost=float(pr @ pr),
                         jacobian=(self.full(sol.jac_x), sol.jac) if kept else None,
                         columns=cols if kept else None)

    def prior_residual(self, theta):
        return (np.asarray(theta)[self.at] - self.mean) / self.sd

    def full(self, theta):
        p = self.base.reshape(-1).copy()
        p[self.free] = theta
        return p.reshape(self.base.shape)

    def _eval(self, theta, cols=None):
        """(columns, linear factors) at theta, kept for the next call at the same theta; cols:
        the columns there where the caller has them (model.lockstep's batches)."""
        key = np.asarray(theta).tobytes()
        if key != self._key:
            if cols is None:
                cols = self._with_steps(theta, key) if self.speculate else \
                    self.problem.columns(self.full(theta))
            self._lin = self.problem.linear(cols, self._warm(cols))
            self._key, self._cols = key, cols
        return self._cols, self._lin

    def _with_steps(self, theta, key):
        """The target's column at theta, its Jacobian's stepped plates (`moves`, each with
        theta's cell statistics, as `stepped_columns`) evaluated in the same call and kept."""
        full = self.full(theta)
        rows = np.array([full[0]] + [row for _, row in self.moves(theta)])
        out = self.problem.column_batch(rows, np.repeat(full[:1], len(rows), axis=0))
        self._stepped = (key, out[1:, None])
        return out[:1]

    def has_steps(self, theta) -> bool:
        """Are theta's stepped plates kept from its residual's call (`_with_steps`)?"""
        return self._stepped is not None and self._stepped[0] == np.asarray(theta).tobytes()

    def _warm(self, cols):
        lin, obs = self._lin, self.problem.obs
        n = len(cols) * (1 + len(getattr(obs, "late", None) or ()))  # amplitudes, late copies
        return lin if lin is not None and len(lin) == n + obs.y.shape[0] else None

    def residual(self, theta):
        cols, lin = self._eval(theta)
        r = self.problem.residual(cols, lin)
        return np.concatenate([r, self.prior_residual(theta)]) if self.at.size else r

    def jac(self, theta, stepped=None):
        """Forward differences along every free parameter; the moved targets' histograms in
        one `column_batch` (what `column` computes, column by column), and with shadows those
        of the targets each moved one can shadow (`stepped_columns`), or `stepped` if given."""
        cols, lin = self._eval(theta)
        if stepped is None and self.has_steps(theta):
            stepped = self._stepped[1]
        if stepped is None:
            stepped = stepped_columns(self.problem, self.full(theta), cols, self.moves(theta))
        base = self.problem.residual(cols, lin)
        out = [(r - base) / step for r, step in
               zip(stepped_residuals(self.problem, stepped, lin), self.steps)]
        return self._with_prior(np.stack(out, axis=1))

    def moves(self, theta):
        """(k, row) per free parameter: target k with that parameter stepped."""
        full, out = self.full(theta), []
        for f, step in zip(np.flatnonzero(self.free), self.steps):
            k, i = divmod(int(f), self.shape.N_PARAMS)
            out.append((k, full[k] + step * (np.arange(len(full[k])) == i)))
        return out

    def _with_prior(self, jac):
        """The data's Jacobian (rows: residuals) with the prior's rows below (exact: linear)."""
        if not self.at.size:
            return jac
        rows = np.zeros((self.at.size, jac.shape[1]))
        rows[np.arange(self.at.size), self.at] = 1.0 / self.sd
        return np.vstack([jac, rows])


def _prior_terms(prior, shape, free):
    """(indices into the free parameters, means, sds) of a prior (mean (K, N), sd (K, N),
    inf: none) on the free parameters; empty arrays without one."""
    if prior is None:
        return np.zeros(0, int), np.zeros(0), np.zeros(0)
    mean, sd = (np.broadcast_to(np.asarray(v, np.float64), shape).reshape(-1)[free]
                for v in prior)
    at = np.flatnonzero(np.isfinite(sd))
    return at, mean[at], sd[at]


def analytic_derivatives(problem, params):
    """(K, N_PARAMS, D, n) d(column)/d(parameter) of each target, analytic
    (model.derivatives, host plates only), or None: another problem, targets that can shadow
    each other (their derivatives are finite differences, `stepped_columns`), or ANALYTIC
    off."""
    if not ANALYTIC or not problem.plates_on_host or problem.paired or \
            shadowed_by(problem, params) is not None:
        return None
    from ..forward.derivatives import column_derivatives
    return column_derivatives(problem, np.asarray(params, np.float64))


# The covariance from analytic derivatives where the problem has them (host plates; within
# 0.1 % of central differences: tests/localization/model/test_model_derivatives.py): exact, in the time of the
# central differences they replace (tracker 17.5 vs 17.6 ms a frame, positions within
# 0.014 mm). The LM's Jacobian keeps forward differences: borrowing the unmoved plate's
# statistics they cost one deposit per parameter (5 plates 0.59 ms), the analytic derivative
# two (value and slope: 1.33 ms); with it the tracker went 17.5 -> 24.9 ms a frame (paper's
# scene, 3 spots, interleaved in one run).
ANALYTIC = True


def shadowed_by(problem, params):
    """Per target of params (K, N), the indices of the targets that can shadow it
    (model.shadow's bounding test), or None: one target, a problem without shadows
    (likelihood.Problem.shadows), or targets that cannot shadow each other."""
    if not problem.shadows or len(params) < 2:
        return None
    from ..forward.shadow import occluders_of, plate_rows  # closed shapes: front faces
    which = occluders_of(plate_rows(params), problem.obs.laser, problem.obs.spots,
                         problem.lattice)
    return which if any(len(w) for w in which) else None


def stepped_columns(problem, params, cols, moves) -> np.ndarray:
    """(len(moves), K, D, n): the K targets' columns with target k moved to `row`, for each
    (k, row) in moves; cols (K, D, n): the columns at params. The moved target's column is
    evaluated with params[k]'s cell statistics (`like`); with shadows (`shadowed_by`) so are
    those of the targets it can shadow (their own rows, shadowed by the moved one), the rest
    are cols' (where no shadow can fall, only the moved target is re-simulated)."""
    params = np.asarray(params, np.float64)
    shadowed = shadowed_by(problem, params)
    rows, like, occluders, where = [], [], [], []
    for m, (k, row) in enumerate(moves):
        moved = params.copy()
        moved[k] = row
        hit = [] if shadowed is None else [j for j, w in enumerate(shadowed) if k in w]
        for j in [k] + hit:
            rows.append(moved[j])
            like.append(params[j])
            occluders.append(None if shadowed is None else moved[shadowed[j]])
            where.append((m, j))
    evaluated = problem.column_batch(np.array(rows), np.array(like),
                                     **({} if shadowed is None else {"occluders": occluders}))
    out = np.repeat(np.asarray(cols)[None], len(moves), axis=0)
    for (m, j), col in zip(where, evaluated):
        out[m, j] = col
    return out


def fit(problem, params0, free, max_nfev=30, tau=None, atol=None, prior=None,
        keep_jacobian=False, width_vectors=False, best_gain=True, speculate=False) -> FitResult:
    """Least squares from params0 (K, N_PARAMS) over the parameters marked in `free`
    (N_PARAMS,). tau, atol: model.lm's (tau None: its default; atol None: off). prior: None,
    or (mean, sd), each (K, N_PARAMS) (sd inf: no prior on that parameter): a Gaussian prior
    on the parameters, its residuals (p - mean) / sd minimised with the data's (a MAP fit).
    keep_jacobian: the result keeps the solver's last Jacobian and the columns
    (FitResult.jacobian, .columns: model.covariance's `reuse`; a 1,024-spot fit's are MBs).
    width_vectors: the solver steps each plate's width and yaw as its width vector
    (`WidthVectors`; plates with both free); the result is in the shape's own parameters.
    best_gain: model.lm's (with atol: stop on the Jacobian's best gain too).
    speculate: one target on a batching problem (`Problem.batched`: the host's models, whose
    cost is mostly per call) evaluates each residual's plate in one call with its
    forward-difference Jacobian's stepped plates, kept for the Jacobian the solver asks next
    at that point (wasted where the step is rejected or the fit stops there; the answers are
    the same to the last bits of the batch's sums)."""
    obj = _Objective(problem, params0, free, prior, speculate)
    variables = WidthVectors.of(obj) if width_vectors else None
    if variables is None:
        return obj.result(drive(obj.solver(max_nfev, tau, atol, best_gain=best_gain),
                                obj.answer), keep_jacobian)

    def answer(request):  # the solver's phi asked in theta, the Jacobian by the chain rule
        theta = variables.to_theta(request[1])
        if request[0] == "fun":
            return obj.residual(theta)
        return obj.jac(theta) @ variables.dtheta_dphi(request[1])
    sol = drive(obj.solver(max_nfev, tau, atol, variables, best_gain), answer)
    if sol.jac is not None:  # the kept Jacobian back in theta, at its own point
        jac_x = variables.to_theta(sol.jac_x)
        sol = replace(sol, jac=sol.jac @ variables.dphi_dtheta(jac_x), jac_x=jac_x)
    return obj.result(replace(sol, x=variables.to_theta(sol.x)), keep_jacobian)
