"""The nonlinear fit (bounded Levenberg-Marquardt, model.lm) of K targets, the linear
factors profiled out at every step (variable projection), and the covariance of the result.

The target's shape is the problem's `shape` module (default model.plate): its N_PARAMS,
LOWER, UPPER, STEPS and X_SCALE are read from there, so a new shape needs no edit here.
Finite-difference steps are absolute (STEPS: 2 mm, 4 mrad for the plate): the forward kernel
works in float32, so relative steps (~1e-8) would differentiate rounding noise. A Jacobian
column re-simulates only the target whose parameter moved, and, where K >= 2 plates can shadow
each other (model.shadow, HostProblem only), the targets the moved one can shadow.

Covariance. AWGN: the sandwich (J'J)^-1 J' C J (J'J)^-1 of weighted least squares on filtered
samples whose noise correlation C comes from the filter's taps (no free factor), times the
Birge ratio max(1, RSS / E[RSS]) where E[RSS] = tr((I - H) C): when the model does not explain
the data to within the noise, the covariance grows by the measured excess. Photon counts: the
inverse Fisher information of the Poisson likelihood. Both include the linear factors.

Jacobians and covariances tell `column_batch` which row each moved plate steps from (`like`);
the host's HostProblem then evaluates the moved plates with the unmoved plate's cell
statistics (nlos_cl.localization.model.batch):
derivatives at frozen blur and shift, within 0.2 % of the exact ones per column and per sd
(tests/test_tracking_warm.py), for half the work of a column. Residuals are always exact, so
the fitted parameters do not depend on it beyond the solver's tolerance.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import plate
from .lm import least_squares

JAC_UPDATE = "full"  # not "broyden": it took more forward calls here (nlos_cl.localization.model.lm)

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


def shape_of(problem):
    """The target model's module: the problem's `shape`, else the plate."""
    return getattr(problem, "shape", plate)


class _Objective:
    """Residual and Jacobian of the profiled problem over the free parameters."""

    def __init__(self, problem, params0, free, prior=None):
        self.problem, self.shape = problem, shape_of(problem)
        self.base = np.array(params0, dtype=np.float64).reshape(-1, self.shape.N_PARAMS)
        self.free = np.tile(np.asarray(free, bool), len(self.base))
        self.steps = np.tile(self.shape.STEPS, len(self.base))[self.free]
        self._key, self._cols, self._lin = None, None, None
        # the prior's residuals (theta[at] - mean) / sd, over the free parameters it bounds
        self.at, self.mean, self.sd = _prior_terms(prior, self.base.shape, self.free)

    def prior_residual(self, theta):
        return (np.asarray(theta)[self.at] - self.mean) / self.sd

    def full(self, theta):
        p = self.base.reshape(-1).copy()
        p[self.free] = theta
        return p.reshape(self.base.shape)

    def _eval(self, theta):
        key = np.asarray(theta).tobytes()
        if key != self._key:
            cols = self.problem.columns(self.full(theta))
            self._lin = self.problem.linear(cols, self._warm(cols))
            self._key, self._cols = key, cols
        return self._cols, self._lin

    def _warm(self, cols):
        lin = self._lin
        return lin if lin is not None and len(lin) == len(cols) + self.problem.obs.y.shape[0] \
            else None

    def residual(self, theta):
        cols, lin = self._eval(theta)
        r = self.problem.residual(cols, lin)
        return np.concatenate([r, self.prior_residual(theta)]) if self.at.size else r

    def jac(self, theta, stepped=None):
        """Forward differences along every free parameter; the moved targets' histograms in
        one `column_batch` (what `column` computes, column by column), and with shadows those
        of the targets each moved one can shadow (`stepped_columns`), or `stepped` if given."""
        cols, lin = self._eval(theta)
        if stepped is None:
            stepped = stepped_columns(self.problem, self.full(theta), cols, self.moves(theta))
        base = self.problem.residual(cols, lin)
        out = [(self.problem.residual(moved, self.problem.linear(moved, lin)) - base) / step
               for moved, step in zip(stepped, self.steps)]
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

    def column(self, theta, j):
        """Forward difference along free parameter j: one forward call, only the target whose
        parameter moved is re-simulated (and, with shadows, those it can shadow)."""
        cols, lin = self._eval(theta)
        k, i = divmod(int(np.flatnonzero(self.free)[j]), self.shape.N_PARAMS)
        full = self.full(theta)
        p = full[k].copy()
        p[i] += self.steps[j]
        if shadowed_by(self.problem, full) is not None:
            moved = stepped_columns(self.problem, full, cols, [(k, p)])[0]
        else:
            moved = cols.copy()
            moved[k] = self.problem.column(p)
        r = self.problem.residual(moved, self.problem.linear(moved, lin))
        col = (r - self.problem.residual(cols, lin)) / self.steps[j]
        return np.concatenate([col, (self.at == j) / self.sd]) if self.at.size else col


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
    from .batch import HostProblem
    if not ANALYTIC or type(problem) is not HostProblem or \
            shadowed_by(problem, params) is not None:
        return None
    from .derivatives import column_derivatives
    return column_derivatives(problem, np.asarray(params, np.float64))


# The covariance from analytic derivatives where the problem has them (host plates; within
# 0.1 % of central differences: tests/test_model_derivatives.py): exact, in the time of the
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
    if not getattr(problem, "shadows", False) or len(params) < 2:
        return None
    from .shadow import occluders_of
    which = occluders_of(params, problem.obs.laser, problem.obs.spots, problem.lattice)
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


def fit(problem, params0, free, max_nfev=30, tau=None, atol=None, prior=None) -> FitResult:
    """Least squares from params0 (K, N_PARAMS) over the parameters marked in `free`
    (N_PARAMS,). tau, atol: model.lm's (tau None: its default; atol None: off). prior: None,
    or (mean, sd), each (K, N_PARAMS) (sd inf: no prior on that parameter): a Gaussian prior
    on the parameters, its residuals (p - mean) / sd minimised with the data's (a MAP fit)."""
    obj = _Objective(problem, params0, free, prior)
    shape, k = obj.shape, len(obj.base)
    lo, hi = (np.tile(b, k)[obj.free] for b in (shape.LOWER, shape.UPPER))
    theta0 = np.clip(obj.base.reshape(-1)[obj.free], lo + 1e-6, hi - 1e-6)
    sol = least_squares(obj.residual, theta0, jac=obj.jac, bounds=(lo, hi),
                        x_scale=np.tile(shape.X_SCALE, k)[obj.free], max_nfev=max_nfev,
                        ftol=1e-7, xtol=1e-5, jac_update=JAC_UPDATE, jac_column=obj.column,
                        atol=atol, **({} if tau is None else {"tau": tau}))
    cols, lin = obj._eval(sol.x)
    r = problem.residual(cols, lin)
    pr = obj.prior_residual(sol.x)
    return FitResult(obj.full(sol.x), lin, float(r @ r), int(r.size), int(sol.nfev),
                     prior=prior if obj.at.size else None, prior_cost=float(pr @ pr))


def _mean_jacobian(problem, params, lin, free):
    """d mu / d (free target parameters, linear factors): (D, n, P). Analytic where
    `analytic_derivatives` has them (host plates that cannot shadow each other), else central
    differences."""
    steps = shape_of(problem).STEPS
    which = [(k, i) for k in range(len(params)) for i in np.flatnonzero(free)]
    slopes = analytic_derivatives(problem, params)
    if slopes is not None:
        cols = problem.columns(params)
        blocks = [lin[k] * slopes[k, i] for k, i in which]
    elif shadowed_by(problem, params) is not None:
        blocks, cols = _shadowed_blocks(problem, params, lin, which, steps)
    else:
        rows = [p.copy() for p in params]  # the targets, then hi, lo, parameter after parameter
        like = list(params)  # the row each one steps from
        for k, i in which:
            for sign in (1.0, -1.0):
                rows.append(params[k].copy())
                rows[-1][i] += sign * steps[i]
                like.append(params[k])
        evaluated = problem.column_batch(np.array(rows), np.array(like))
        cols, moved = evaluated[:len(params)], evaluated[len(params):]
        blocks = [lin[k] * (moved[2 * n] - moved[2 * n + 1]) / (2 * steps[i])
                  for n, (k, i) in enumerate(which)]
    blocks.extend(cols)
    if problem.obs.mode == "poisson":
        n_det = problem.obs.y.shape[0]
        blocks.extend(np.eye(n_det)[:, :, None] * problem.obs.valid[None])
    return cols, np.stack(blocks, axis=-1)


def _shadowed_blocks(problem, params, lin, which, steps):
    """`_mean_jacobian`'s derivative blocks where targets shadow each other: moving target k
    changes the columns of the targets it shadows too, so d mu = sum_j a_j d(column j)."""
    cols = problem.columns(params)
    moves = []
    for k, i in which:
        for sign in (1.0, -1.0):
            row = params[k].copy()
            row[i] += sign * steps[i]
            moves.append((k, row))
    moved = stepped_columns(problem, params, cols, moves)
    amp = np.asarray(lin[:len(params)])
    return [np.tensordot(amp, moved[2 * n] - moved[2 * n + 1], 1) / (2 * steps[i])
            for n, (k, i) in enumerate(which)], list(cols)


def _correlated_terms(obs, j):
    """J^T C J and trace(C) for the correlation C of the weighted residuals, which is block
    diagonal (one Toeplitz block per detector: the filter correlates a detector's samples, not
    two detectors'), summed block by block: a 1,024-detector patch never builds the dense
    (samples x samples) matrix (93,184^2 floats, 65 GiB)."""
    idx = np.arange(obs.n)
    toeplitz = obs.rho[np.abs(idx[:, None] - idx[None, :])]
    meat, trace, at = np.zeros((j.shape[1], j.shape[1])), 0.0, 0
    for v in obs.valid:  # j's rows are the valid samples, detector after detector
        block = toeplitz[np.ix_(v, v)]
        rows = j[at:at + len(block)]
        meat += rows.T @ block @ rows
        trace += float(np.trace(block))
        at += len(block)
    return meat, trace


def _scaled_pinv(a) -> np.ndarray:
    """Pseudo-inverse of a normal matrix whose columns differ by many orders of magnitude
    (metres, radians, amplitudes in any unit): equilibrated first, so that pinv's relative
    cut-off drops only real degeneracies, not small units."""
    s = np.sqrt(np.maximum(np.diag(a), 1e-300))
    return np.linalg.pinv(a / np.outer(s, s)) / np.outer(s, s)


def covariance(problem, result: FitResult, free) -> tuple[np.ndarray, dict]:
    """Covariance of every target parameter (K*N_PARAMS square; inf on fixed ones) and
    diagnostics."""
    obs, params = problem.obs, result.params
    cols, jmu = _mean_jacobian(problem, params, result.linear, free)
    mu = problem.mean(cols, result.linear)
    n_free = int(np.count_nonzero(free)) * len(params)
    # a MAP fit's prior adds its precision to the information (model.fit's `prior`)
    precision = np.zeros(jmu.shape[-1])
    at, _, sd = _prior_terms(result.prior, params.shape, np.tile(np.asarray(free, bool),
                                                                 len(params)))
    precision[at] = 1.0 / sd ** 2  # the free target parameters come first, as in _prior_terms
    if obs.mode == "gauss":
        j = (jmu / obs.noise[:, None, None])[obs.valid]
        meat, trace = _correlated_terms(obs, j)
        inv = _scaled_pinv(j.T @ j + np.diag(precision))
        cov = inv @ (meat + np.diag(precision)) @ inv
        r = ((obs.y - mu) / obs.noise[:, None])[obs.valid]
        expected = float(trace - np.trace(inv @ meat))
        birge = float(r @ r) / max(expected, 1.0)
        cov = cov * max(1.0, birge)
        info = {"birge_ratio": birge}
    else:
        lam = np.maximum(mu, 1e-12)[obs.valid]
        j = jmu[obs.valid]
        cov = _scaled_pinv(j.T @ (j / lam[:, None]) + np.diag(precision))
        info = {"deviance": result.cost, "n_bins": int(obs.valid.sum())}
    full = np.full((params.size, params.size), np.inf)
    mask = np.tile(np.asarray(free, bool), len(params))
    full[np.ix_(mask, mask)] = cov[:n_free, :n_free]
    n = shape_of(problem).N_PARAMS
    for k in np.flatnonzero(np.asarray(result.linear[:len(params)]) <= 0):
        # amplitude 0 (held at the bound: the data want none of this target): its parameters'
        # derivatives are 0, so pinv gave them a variance of 0, not the infinity they have
        full[k * n:(k + 1) * n, :] = np.inf
        full[:, k * n:(k + 1) * n] = np.inf
    return full, info


def centre_covariance(cov_all, k, shape=plate) -> np.ndarray:
    """The (x, y, z) block of target k (rows of shape.N_PARAMS parameters, x, y, z first); an
    unobservable (fixed) axis has infinite variance and no correlation with the others."""
    s = slice(k * shape.N_PARAMS, k * shape.N_PARAMS + 3)
    c = np.array(cov_all[s, s], dtype=np.float64)
    fixed = ~np.isfinite(np.diag(c))
    c[fixed, :] = 0.0
    c[:, fixed] = 0.0
    c[fixed, fixed] = np.inf
    return c
