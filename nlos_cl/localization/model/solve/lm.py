"""A small bounded Levenberg-Marquardt least-squares solver: SciPy's `least_squares` minus
its import (scipy.optimize: ~0.25 s, a quarter of the one-shot `nlos-cl locate` 1 s
budget) and minus the Jacobian SciPy evaluates after its last step (n forward calls).

    sol = least_squares(fun, x0, jac=jac, bounds=(lo, hi), x_scale=s, ftol=1e-7, xtol=1e-5,
                        max_nfev=30)

Same meaning as SciPy's: minimise 0.5 |fun(x)|^2 subject to lo <= x <= hi; `x_scale`: work in
the variables x / x_scale (a unit step there is "one typical change"); ftol: stop when an
accepted step lowers the cost by < ftol * cost (with a model ratio > 0.25); xtol: stop when
|dx| < xtol (xtol + |x|); gtol: stop when the projected scaled gradient's largest component is
< gtol; max_nfev: residual evaluations, the Jacobian's not counted (as SciPy's "trf").

The method (Madsen, Nielsen & Tingleff, "Methods for non-linear least squares problems",
2004, Alg. 3.16 and 3.15): damped Gauss-Newton steps (J'J + mu I) h = -J'r in scaled
variables, mu updated from the gain ratio (Nielsen's rule); bounds by projection: the step is
clipped into the box and a variable held at a bound by its gradient is left out of the solve
(projected LM, Kanzow, Yamashita & Fukushima 2004). A new Jacobian after every accepted step:
rank-one (Broyden) updates (MNT Alg. 3.15) take more forward calls on the model fit (the
one-shot capture's fits 105-115 against 85-86).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ....core.errors import require

EPS = np.finfo(np.float64).eps
ACCEPT = 1e-3  # gain ratio above which a step is taken (MNT: any gain; a little more is safer)
# Initial damping relative to max diag(J'J). 1e-4 finds SciPy's trf answers on 8 frames (0.3 x
# 1.6 m plates at y = 1 m, 10 dB) where MNT's 1e-6's near-Gauss-Newton first step jumped basins
# on 4 (0.19-0.50 m off); a decade of margin from 1e-5, the smallest value that found all 8.
TAU = 1e-4
MESSAGES = {0: "the maximum number of function evaluations is exceeded",
            1: "gtol termination condition is satisfied",
            2: "ftol termination condition is satisfied",
            3: "xtol termination condition is satisfied",
            4: "both ftol and xtol termination conditions are satisfied",
            5: "atol termination condition is satisfied"}


@dataclass
class LMResult:
    x: np.ndarray
    fun: np.ndarray  # residual at x
    cost: float  # 0.5 |fun(x)|^2, as SciPy reports it
    nfev: int  # residual evaluations
    njev: int  # Jacobian evaluations
    status: int  # 0 max_nfev, 1 gtol, 2 ftol, 3 xtol, 4 ftol and xtol, 5 atol
    # the last Jacobian the solver was given and the point it was taken at (x itself, or
    # the point before the last accepted step, which gets none)
    jac: np.ndarray | None = None
    jac_x: np.ndarray | None = None

    @property
    def message(self) -> str:
        return MESSAGES[self.status]


def least_squares(fun, x0, jac=None, bounds=(-np.inf, np.inf), x_scale=1.0, ftol=1e-8,
                  xtol=1e-8, gtol=1e-8, max_nfev=None, diff_step=None, tau=TAU, atol=None,
                  best_gain=True) -> LMResult:
    """Bounded least squares by Levenberg-Marquardt (see the module's docstring). `jac`:
    callable x -> (m, n), or None for forward differences of step `diff_step` (absolute, (n,)
    or scalar; default sqrt(eps) max(1, |x|)). tau:
    the initial damping relative to max diag(J'J) (TAU; smaller for a start known to be in the
    minimum's basin, e.g. a tracker's warm start). atol: stop when a step's predicted cost
    decrease is below atol (absolute; None: off): the step just tried; or the best step the
    Jacobian at x allows (its Gauss-Newton step: no trial step is evaluated); or, after a
    short accepted step (one that promised < 2 atol), the next one as the Jacobian in hand
    predicts it (no Jacobian is made only to learn that the fit is done); best_gain=False:
    the step just tried alone. Where the cost is chi^2 / 2 that is a
    statistical scale: a step that cannot lower chi^2 by 2 atol moves no parameter by more
    than ~sqrt(2 atol) of its sd, while finite-difference Jacobians leave ~1e-4 of cost that
    the relative ftol waits for in vain (rejected steps until max_nfev)."""
    solver = solve(x0, bounds, x_scale, ftol, xtol, gtol, max_nfev, tau, atol, best_gain)
    diff = _diff_steps(np.atleast_1d(np.asarray(x0, dtype=np.float64)), diff_step)
    hi = np.broadcast_to(np.asarray(bounds[1], dtype=np.float64), diff.shape)

    def column(x, j, r):  # forward differences use the residual at hand (r): no extra call
        return _fd_column(fun, x, r, j, diff[j], hi[j])

    def serve(request):
        kind, x = request[0], request[1]
        if kind == "fun":
            return fun(x)
        if jac is not None:
            return np.atleast_2d(np.asarray(jac(x), dtype=np.float64))
        return np.stack([column(x, j, request[2]) for j in range(len(x))], axis=1)
    return drive(solver, serve)


def drive(solver, serve) -> LMResult:
    """Run a `solve` generator to its result, answering each of its requests with serve."""
    return drive_together([solver], lambda asked: [serve(request) for _, request in asked])[0]


def drive_together(solvers, serve_all) -> list:
    """Run several `solve` generators in lockstep, their pending requests answered together
    by serve_all([(index, request), ...]) -> [answer, ...] (e.g. one batched model call for
    every fit's trial point): each solver sees exactly the answers it would alone."""
    results = [None] * len(solvers)
    pending = {}
    for i, solver in enumerate(solvers):
        try:
            pending[i] = next(solver)
        except StopIteration as done:
            results[i] = done.value
    while pending:
        asked = list(pending.items())
        answers = list(serve_all(asked))  # outside the try: not the solvers' StopIteration
        for (i, _), answer in zip(asked, answers):
            try:
                pending[i] = solvers[i].send(answer)
            except StopIteration as done:
                results[i] = done.value
                del pending[i]
    return results


def solve(x0, bounds=(-np.inf, np.inf), x_scale=1.0, ftol=1e-8, xtol=1e-8, gtol=1e-8,
          max_nfev=None, tau=TAU, atol=None, best_gain=True):
    """`least_squares` as a generator: it yields requests and is sent their answers, then
    returns its LMResult. Requests: ("fun", x) the residual at x; ("jac", x, r) the
    Jacobian at x (r: the residual there)."""
    x0, lo, hi, scale, max_nfev = _inputs(x0, bounds, x_scale, max_nfev)
    s = _State(np.clip(x0, lo, hi), lo, hi, scale)
    s.r = yield from s.evaluate(s.x, first=True)
    s.tau, s.atol = float(tau), atol
    s.best_gain = bool(best_gain) and atol is not None  # the atol test on the Jacobian's gain
    s.jac, s.jac_x = (yield ("jac", s.x, s.r)), s.x
    s.njev += 1
    status = None
    while status is None:
        status = s.gradient_converged(gtol)
        if status is None and s.nfev >= max_nfev:
            status = 0
        if status is None:
            status = yield from _iterate(s, ftol, xtol, max_nfev)
    return LMResult(s.x, s.r, 0.5 * float(s.r @ s.r), s.nfev, s.njev, status, s.jac, s.jac_x)


class _State:
    """The current point, its residual and Jacobian, the damping, and the call counts."""

    def __init__(self, x, lo, hi, scale):
        self.x, self.lo, self.hi, self.scale = x, lo, hi, scale
        self.r, self.nfev = None, 0
        self.jac, self.jac_x, self.mu, self.nu = None, None, None, 2.0
        self.njev = 0

    def evaluate(self, x, first=False):
        r = np.atleast_1d(np.asarray((yield ("fun", x)), dtype=np.float64))
        self.nfev = 1 if first else self.nfev + 1
        require(bool(np.all(np.isfinite(r))) or not first, "x0",
                "the residual is not finite at the start", "start inside the model's domain")
        return r

    def free(self, g):
        """Variables not held at a bound by their gradient (a descent step would leave)."""
        at_lo = (self.x <= self.lo) & (g > 0)
        at_hi = (self.x >= self.hi) & (g < 0)
        return ~(at_lo | at_hi)

    def gradient_converged(self, gtol):
        # the Jacobian in scaled variables and the gradient, kept for _iterate, which follows
        self.js = self.jac * self.scale
        self.g = g = self.js.T @ self.r
        free = self.free(g)
        return 1 if not free.any() or np.max(np.abs(g[free])) < gtol else None


def _iterate(s, ftol, xtol, max_nfev):
    """Damped steps from s.x until one lowers the cost (then update the Jacobian) or a
    termination test holds; returns the status or None to go on. (s.js, s.g: from
    s.gradient_converged, called just before with the same point and Jacobian.)"""
    js, g = s.js, s.g
    a = js.T @ js
    free = s.free(g)
    if s.mu is None:
        s.mu = s.tau * max(float(np.max(np.diag(a))), EPS)
    if s.best_gain and _best_gain(a, g, free) < s.atol:
        return 5  # the Jacobian at x says no step can gain atol: no trial step
    cost = 0.5 * float(s.r @ s.r)
    while s.nfev < max_nfev:
        h = _damped_step(a, g, s.mu, free)
        x_new = np.clip(s.x + s.scale * h, s.lo, s.hi)
        h = (x_new - s.x) / s.scale  # the step actually taken, after projection
        predicted = -(g @ h + 0.5 * h @ a @ h)
        r_new = yield from s.evaluate(x_new)
        new_cost = 0.5 * float(r_new @ r_new) if np.all(np.isfinite(r_new)) else np.inf
        actual = cost - new_cost
        ratio = actual / predicted if predicted > 0 else -1.0
        status = _termination(actual, cost, x_new - s.x, s.x, ratio, ftol, xtol)
        if status is None and s.atol is not None and predicted < s.atol:
            status = 5
        if ratio > ACCEPT:
            s.mu *= max(1.0 / 3.0, 1.0 - (2.0 * ratio - 1.0) ** 3)
            s.nu = 2.0
            if status is None and s.best_gain and predicted < 2.0 * s.atol and \
                    _best_gain(a, js.T @ r_new, free) < s.atol:
                status = 5  # a short step, and the Jacobian in hand says the next gains < atol
            # no Jacobian where the loop ends anyway (SciPy computes one: n forward calls)
            yield from _take(s, x_new, r_new, status is None and s.nfev < max_nfev)
            return status
        s.mu *= s.nu
        s.nu *= 2.0
        if status is not None:
            return status
    return 0


def _take(s, x_new, r_new, need_jacobian):
    """Move to x_new, and ask for the Jacobian there if the fit goes on."""
    s.x, s.r = x_new, r_new
    if need_jacobian:
        s.jac, s.jac_x = (yield ("jac", s.x, s.r)), s.x
        s.njev += 1


def _best_gain(a, g, free):
    """The most a step can lower the cost on the quadratic model (A = J'J, gradient g, both
    scaled): g' A^-1 g / 2 over the free variables, the Gauss-Newton step's gain (A nudged
    by 1e-12 of its largest diagonal, so that a singular A still solves)."""
    h = _damped_step(a, g, 1e-12 * max(float(np.max(np.diag(a))), EPS), free)
    return -0.5 * float(g @ h)


def _fd_column(fun, x, r0, j, step, hi_j):
    """Forward difference along x[j] (stepping inward at an upper bound); r0 = fun(x)."""
    moved = x.copy()
    h = step if x[j] + step <= hi_j else -step
    moved[j] += h
    return (np.asarray(fun(moved), dtype=np.float64) - r0) / h


def _damped_step(a, g, mu, free):
    """Solve (A + mu I) h = -g over the free variables; zero on the others."""
    if free.all():  # the usual case, without the index arrays (the same numbers)
        m = a.copy()
        m.flat[::len(g) + 1] += mu
        return np.linalg.solve(m, -g)
    h = np.zeros_like(g)
    idx = np.flatnonzero(free)
    if idx.size:
        m = a[np.ix_(idx, idx)] + mu * np.eye(idx.size)
        h[idx] = np.linalg.solve(m, -g[idx])
    return h


def _termination(actual, cost, dx, x, ratio, ftol, xtol):
    """SciPy's test: ftol on the cost's drop (with a trusted model), xtol on the step."""
    f_ok = actual < ftol * cost and ratio > 0.25
    x_ok = math.sqrt(float(dx @ dx)) < xtol * (xtol + math.sqrt(float(x @ x)))  # 2-norms
    return 4 if f_ok and x_ok else 2 if f_ok else 3 if x_ok else None


def _diff_steps(x0, diff_step):
    if diff_step is None:
        return np.sqrt(EPS) * np.maximum(1.0, np.abs(x0))
    return np.broadcast_to(np.asarray(diff_step, dtype=np.float64), x0.shape).copy()


def _inputs(x0, bounds, x_scale, max_nfev):
    x0 = np.atleast_1d(np.asarray(x0, dtype=np.float64))
    require(x0.ndim == 1 and np.all(np.isfinite(x0)), "x0", "must be a finite vector",
            "pass a 1-D array of finite starting values")
    lo, hi = (np.broadcast_to(np.asarray(b, dtype=np.float64), x0.shape).copy() for b in bounds)
    require(bool(np.all(lo < hi)), "bounds", "every lower bound must be below its upper bound",
            "pass (lo, hi) with lo < hi elementwise")
    scale = np.broadcast_to(np.asarray(x_scale, dtype=np.float64), x0.shape).copy()
    require(bool(np.all(np.isfinite(scale) & (scale > 0))), "x_scale",
            "must be positive and finite", "pass a typical change per variable, e.g. 0.05")
    max_nfev = 100 * x0.size if max_nfev is None else int(max_nfev)
    require(max_nfev >= 1, "max_nfev", f"must be >= 1, got {max_nfev}", "pass e.g. 30")
    return x0, lo, hi, scale, max_nfev
