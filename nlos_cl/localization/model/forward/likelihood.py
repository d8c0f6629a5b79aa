"""The model's histograms for K targets (plates, or one box), the linear factors solved in
closed form, and the residuals whose sum of squares is -2 log-likelihood (up to a constant).

Gaussian (AWGN): mu = sum_k a_k m_k + a slow background per detector (model.forward.nuisance:
a constant and a ramp), and where the observation has them (obs.late) each column's late
copies sum_j b_kj G_j m_k (model.forward.late: an IRF tail, delayed broad light); (a, b >= 0,
background) by weighted least squares (noise std per detector); residual (y - mu) / noise.
Poisson (photon counts): lambda = sum_k a_k m_k + b_d (b_d: dark and ambient counts per bin,
per detector) + the late copies as above; all >= 0 maximise the Poisson likelihood (Newton);
residual = signed deviance residual, so the sum of squares is the deviance.
"""
from __future__ import annotations

import math

import numpy as np

from ....core.constants import TINY
from ....core.stats import deviance_residuals
from ..shapes import plate
from . import late, nuisance

MAX_ENUMERATED = 6  # targets; beyond, projected coordinate descent
# The counts' amplitudes are iterated to convergence (1e-9 relative), so that a fit's cost is
# a function of its parameters alone. A background started below its best level (a row whose
# first and last bins are gated zeros starts at the 1e-3 floor) climbs by Newton's doubling,
# 20-35 iterations to CC-SOCR's levels; at 12 a tenth of the calls returned amplitudes still
# climbing, and which closed shape won turned on the calls made before.
NEWTON_ITERS = 40
BOUND_SHARE = 0.1  # of its value, where a parameter's Newton step would cross 0


def nonnegative_lstsq(gram, rhs, free=None) -> np.ndarray:
    """argmin_{a >= 0} a'Ga - 2 a'r for the normal equations (G = A'A, r = A'b). `free`: the
    unconstrained solution where the caller has it from A itself (lstsq on A, not on G, whose
    condition number is A's squared: nearly collinear plates), returned unchanged when >= 0.
    Otherwise, for K <= MAX_ENUMERATED every support is tried (2^K - 1 solves of <= K x K;
    SciPy's nnls costs a one-shot locate its import); larger K by coordinate descent."""
    k = len(rhs)
    if free is not None and np.all(free >= 0):
        return free
    scale = np.sqrt(np.maximum(np.diag(gram), TINY))  # equilibrated: amplitudes of any unit
    g, r = gram / np.outer(scale, scale), rhs / scale
    free = np.linalg.lstsq(g, r, rcond=None)[0]
    if np.all(free >= 0):
        return free / scale
    best, best_cost = np.zeros(k), 0.0
    if k <= MAX_ENUMERATED:
        for mask in range(1, 2 ** k):
            s = [i for i in range(k) if mask >> i & 1]
            a_s = np.linalg.lstsq(g[np.ix_(s, s)], r[s], rcond=None)[0]
            if np.all(a_s >= 0):
                a = np.zeros(k)
                a[s] = a_s
                cost = float(a @ g @ a - 2.0 * a @ r)
                if cost < best_cost:
                    best, best_cost = a, cost
        return best / scale
    a = np.maximum(free, 0.0)
    for _ in range(200):
        for i in range(k):
            a[i] = max(0.0, a[i] + (r[i] - g[i] @ a) / max(g[i, i], TINY))
    return a / scale


def take_calls(problem, other) -> None:
    """Count `other`'s forward calls and their time as `problem`'s (the estimator's timings
    report one problem's): added there, taken off `other`."""
    problem.calls, problem.model_s = problem.calls + other.calls, problem.model_s + other.model_s
    other.calls, other.model_s = 0, 0.0


class Problem:
    """Evaluates the forward model for parameter rows (K, shape.N_PARAMS) on `backend`.
    `shape`: the target model's module (model.plate or .box): its model_facets, and
    the N_PARAMS, STEPS, X_SCALE, LOWER, UPPER the fit reads.

    No shadows (`shadows` False): every target's column is computed alone, so where one of K
    targets hides part of another from O or a spot, this model still sees all of it. The
    forward op takes occlusion only as a (D, F) bool mask, and a hard mask makes the cost a
    staircase in the targets' positions; model.batch.HostProblem models the plates' shadows
    smoothly (model.shadow) and is the problem to use where K >= 2 plates may shadow."""

    shadows = False  # HostProblem: True
    plates_on_host = False  # HostProblem: True (coarser lattices, analytic derivatives)
    # column_batch evaluates its rows in one call (the host's models): model.fit speculates
    batched = False
    # the closed shapes' model on the host (model.host_shapes.shape_problem): the estimator
    # sets it where its model_on and the layout allow
    closed_on_host = False
    # the Gaussian likelihood's background terms per detector (nuisance.ORDER; None: none)
    background_order = nuisance.ORDER

    def __init__(self, obs, backend, lattice=(16, 24), shape=plate, reflectance=None):
        # a plate.Lattice (its blur share with it) kept as it is; a plain pair as a tuple
        self.obs, self.backend = obs, backend
        self.lattice = lattice if isinstance(lattice, plate.Lattice) else tuple(lattice)
        self.shape, self.reflectance = shape, reflectance  # None: Lambertian
        self.calls = 0
        self.model_s = 0.0
        self._weighted_y = None  # y / noise, flat: the amplitudes' right-hand side

    def column(self, p) -> np.ndarray:
        """(D, n) histograms of one target, unit amplitude (forward op on the backend)."""
        import time
        t = time.perf_counter()
        obs = self.obs
        parts = self.shape.model_facets(p, self.lattice, obs.spots, obs.laser)
        out = 0.0
        # a shape gives one (facets, blur, shift) or a list of them (a box: one per face, each
        # its own pulse blur), one forward call each
        for facets, blur, shift in parts if isinstance(parts, list) else [parts]:
            sigma = math.sqrt(obs.sigma0_m ** 2 + blur ** 2 - obs.box_excess_m2)
            hist, _ = self.backend.call("forward", facets, obs.spots, obs.laser,
                                        obs.edge0 - shift, obs.dpath, sigma, obs.n,
                                        self.reflectance)
            out = out + np.asarray(self.backend.to_numpy(hist), dtype=np.float64)
        self.calls += 1
        self.model_s += time.perf_counter() - t
        return np.where(obs.valid, out, 0.0)

    def columns(self, params) -> np.ndarray:
        return np.stack([self.column(p) for p in np.reshape(params, (-1, self.shape.N_PARAMS))])

    def column_batch(self, rows, like=None, occluders=None) -> np.ndarray:
        """(B, D, n): `column` of each parameter row, in order (one forward call each here;
        model.batch.HostProblem evaluates them all in one host call). like: the rows
        each one is a small step from (a Jacobian's), which a problem may use to share work
        between them (HostProblem: their cell statistics); here every row is exact.
        occluders: shadowing rows per row, which only a problem with `shadows` models."""
        if occluders is not None and any(o is not None and len(o) for o in occluders):
            raise NotImplementedError("this Problem models no shadows (shadows=False): "
                                      "use model.batch.HostProblem for shadowed plates")
        return np.stack([self.column(p) for p in rows])

    def occluders(self, params):
        """Per target row, the rows that shadow it: None here (see `shadows`)."""
        return None

    # ------------------------------------------------------------------ linear factors
    def linear(self, cols, warm=None) -> np.ndarray:
        """Closed-form linear factors for the columns (K, D, n)."""
        if self.obs.mode == "gauss":
            return self._gauss_linear(cols)
        return self._poisson_linear(cols, warm)

    def background(self):
        """The Gaussian rows' background basis (nuisance.Background, on the rows that support
        it: nuisance.supported), or None (counts, background_order None, or no row supports
        it: the fit as without terms, at its cost); made once per problem."""
        if self.obs.mode != "gauss" or self.background_order is None:
            return None
        key = self.background_order
        if getattr(self, "_background_key", None) != key:
            rows = nuisance.supported(self.obs)
            self._background = nuisance.Background(self.obs.valid, key, rows) \
                if rows.any() else None
            self._background_key = key
        return self._background

    def copies(self, cols):
        """(K, J, D, n) the late copies of columns (K, D, n), or None (late.copies_of)."""
        return late.copies_of(self, cols)

    def split(self, lin, k: int):
        """(amplitudes (K,), background coefficients, late amplitudes (K, J)) of K targets'
        linear factors (late.split)."""
        return late.split(self.obs, lin, k)

    def scaled(self, k: int, n_targets: int, x, lin) -> np.ndarray:
        """(D, n): what a change x (D, n) of target k's column (of n_targets) changes the mean
        by: its amplitude times x, and its late copies' amplitudes times x's copies."""
        amp, _, b = self.split(lin, n_targets)
        out = amp[k] * x
        if b.size and np.any(b[k] > 0):
            out = out + np.tensordot(b[k], self.copies(np.asarray(x)[None])[0], 1)
        return out

    def _gauss_linear(self, cols):
        """Weighted least squares for the amplitudes, each >= 0: a target reflects light, it
        does not absorb it. Unconstrained, two overlapping plates of opposite signs sculpted
        one target's signal (5 of 13 failed three-target draws held a negative amplitude).
        With a background (`background`) the amplitudes are solved on the rows with its basis
        projected out, then its coefficients (either sign: what the floor subtraction left,
        and a ramp) from what they leave: [a, c.ravel()], c (p, D) in data units; with late
        copies (`copies`) their amplitudes (>= 0) with the a's, after them: [a, c, b.ravel()]."""
        bg = self.background()
        w = (1.0 / self.obs.noise)[None, :, None]
        extra = self.copies(cols)
        both = cols if extra is None else \
            np.concatenate([cols, late.capped(cols, extra, self.obs.late)])
        weighted = both * w if bg is None else bg.project(both * w)
        a_mat = weighted.reshape(len(both), -1)
        if self._weighted_y is None:
            y = self.obs.y * w[0]
            self._weighted_y = (y if bg is None else bg.project(y)).reshape(-1)
        b = self._weighted_y
        if extra is not None:
            amp = late.uncapped(late.nnls(a_mat, b), len(cols), self.obs.late)
            both = np.concatenate([cols, extra.reshape((-1,) + cols.shape[1:])])
        elif len(cols) == 1:  # one column: the projection, >= 0 (lstsq's number, 0.1 ms less)
            norm2 = float(a_mat[0] @ a_mat[0])
            amp = np.array([max(float(a_mat[0] @ b), 0.0) / norm2 if norm2 > 0 else 0.0])
        else:
            amp, *_ = np.linalg.lstsq(a_mat.T, b, rcond=None)
            if not np.all(amp >= 0):
                amp = nonnegative_lstsq(a_mat @ a_mat.T, a_mat @ b, amp)
        k = len(cols)
        if bg is None:
            return amp
        rest = self.obs.y - np.tensordot(amp, both, 1)
        return np.concatenate([amp[:k], bg.coefficients(rest).reshape(-1), amp[k:]])

    def _poisson_linear(self, cols, warm=None, iters=NEWTON_ITERS):
        """Newton on (a_1..a_K, b_1..b_D) of the Poisson log-likelihood, kept >= 0. The
        backgrounds' basis rows are each one detector's indicator, so the gradient and the
        Hessian are built by blocks (a-a, a-b, diagonal b-b) rather than one einsum over
        (K + D)^2 x D x n: the same numbers, and a 64-detector frame's call 12 ms -> ~0.3 ms
        (a 256-spot SPAD patch's fit spent 70 of its 84 s in that einsum)."""
        extra = late.copies_of(self, cols)
        if extra is not None:  # late copies (forward.late): solved with the amplitudes
            return late.poisson_linear(self.obs, cols, extra, warm, self._poisson_start,
                                       self.obs.late)
        phi = self._poisson_start(cols) if warm is None else np.array(warm, float)
        return _poisson_newton(self.obs.y, self.obs.valid.astype(np.float64), cols, phi, iters)

    def _poisson_start(self, cols):
        obs, k = self.obs, len(cols)
        edge = np.concatenate([obs.y[:, :5], obs.y[:, -5:]], axis=1)
        b = np.maximum(edge.mean(axis=1), 1e-3)
        excess = max(float(np.sum(np.maximum(obs.y - b[:, None], 0) * obs.valid)), 1.0)
        a = np.full(k, excess / max(float(cols.sum()), TINY) / k)
        return np.concatenate([a, b])

    # ------------------------------------------------------------------ residuals
    def mean(self, cols, lin) -> np.ndarray:
        k = len(cols)
        _, coef, b = self.split(lin, k)
        if self.obs.mode == "poisson":
            mu = np.tensordot(lin[:k], cols, 1) + coef[:, None] * self.obs.valid
        else:
            mu = lin[0] * cols[0] if k == 1 else np.tensordot(lin[:k], cols, 1)
            bg = self.background()
            if bg is not None and coef.size:
                mu = mu + bg.fitted(np.reshape(coef, (bg.p, -1)))
        if b.size and np.any(b > 0):
            mu = mu + np.einsum("kj,kjdn->dn", b, self.copies(cols))
        return mu

    def residual(self, cols, lin) -> np.ndarray:
        obs, mu = self.obs, self.mean(cols, lin)
        if obs.mode == "gauss":
            r = (obs.y - mu) / obs.noise[:, None]
        else:
            r = deviance_residuals(obs.y, np.maximum(mu, 1e-12))
        return r[obs.valid]

    def null_cost(self) -> float:
        """The cost with no target: each detector's background alone at its best (Gaussian:
        zero where it has none; counts: the mean count of its valid bins). What a fit's
        explained share (1 - cost / this) is measured against."""
        obs = self.obs
        if obs.mode == "gauss":
            bg, y = self.background(), obs.y / obs.noise[:, None]
            return float(np.sum((y if bg is None else bg.project(y))[obs.valid] ** 2))
        valid = obs.valid.astype(np.float64)
        b = np.sum(obs.y * valid, axis=1) / np.maximum(valid.sum(axis=1), 1.0)
        return float(np.sum(self.residual(np.zeros((0,) + obs.y.shape), b) ** 2))

    def cost(self, params) -> float:
        cols = self.columns(params)
        r = self.residual(cols, self.linear(cols))
        return float(r @ r)


def _poisson_newton(y, valid, cols, phi, iters):
    """Problem._poisson_linear's Newton iterations from phi (a, then b per detector). Written
    for the per-call cost of one target's small fits (a (1, 16, 316) call ~85 us an
    iteration): valid is 0 / 1, so y valid is formed once and the weights need no second mask;
    the finiteness test reads the row sums (a non-finite weight or residual reaches its row's
    sum: w >= 0, r >= -1); the same numbers as the straightforward form, bit for bit, in 0.6
    of its time (tests/localization/model/test_model_poisson.py). A step past zero stops at BOUND_SHARE of
    the value; an entry converges relatively (1e-9) or once its step moves the expected counts by
    under 1e-9 of those observed (calls that ran to a cap of 43 iterations converge so in 7-11,
    to the same counts within 1e-16 of the total)."""
    k = len(cols)
    flat = cols.reshape(k, -1)
    yv = y * valid
    lam = np.empty(np.shape(y))
    # counts a unit of each parameter adds over the valid bins, and the counts observed: a
    # parameter whose step moves the expectation by under 1e-9 of them has converged (one
    # heading for its bound at 0 never does so relatively)
    scale = np.concatenate([flat @ np.reshape(valid, -1), np.sum(valid, axis=1)])
    total = float(np.sum(yv)) + 1.0
    for _ in range(iters):
        # a column that barely overlaps the counts (a start candidate far off) can send
        # its amplitude off without bound: the iteration stops at the last finite phi
        # (its cost then rejects the candidate) instead of overflowing (CC-SOCR's
        # 4 points as one laser: "overflow encountered in square" in the answer's warnings)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            np.dot(phi[:k], flat, out=lam.reshape(-1))
            lam += phi[k:, None] * valid
            np.maximum(lam, 1e-12, out=lam)
            r = yv / lam
            w = yv / (lam * lam)
            r -= valid
        h_bb, g_b = np.sum(w, axis=1), np.sum(r, axis=1)
        if not (np.all(np.isfinite(h_bb)) and np.all(np.isfinite(g_b))):
            break
        h_aa = (flat * w.reshape(-1)) @ flat.T
        h_ab = np.einsum("kdn,dn->kd", cols, w)
        diag = np.diag_indices(k)
        h_aa[diag] += _ridge(h_aa[diag])
        h_bb += _ridge(h_bb)  # the backgrounds' block is diagonal
        g_a = flat @ r.reshape(-1)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            step = _arrow_solve(h_aa, h_ab, h_bb, g_a, g_b)
        # a step past 0 stops at a tenth of the value instead (BOUND_SHARE): from 1e-12 of it,
        # a background overshot from 0.1 took ~40 doublings to climb back to 0.04
        new = np.maximum(phi + step, BOUND_SHARE * phi)
        if not np.all(np.isfinite(new)):
            break
        moved = np.abs(new - phi)
        done = np.all((moved <= 1e-9 * np.abs(phi)) | (moved * scale <= 1e-9 * total))
        phi = new
        if done:
            break
    return phi


def _ridge(diagonal) -> np.ndarray:
    """The Newton step's damping on one block's diagonal: 1e-9 of each entry (so of each
    parameter's own scale), or of a thousandth of the block's mean where an entry is ~0 (a
    detector that counted nothing, a column all zero). One ridge common to both blocks (1e-9
    of the mean diagonal) is 18 times a plate's amplitude entry where its columns are small
    numbers against the backgrounds' (1e-9 against 35): the amplitude creeps 5 % an
    iteration."""
    return 1e-9 * np.maximum(diagonal, 1e-3 * float(np.mean(diagonal))) + TINY


def _arrow_solve(h_aa, h_ab, h_bb, g_a, g_b) -> np.ndarray:
    """The Newton step of [[h_aa, h_ab], [h_ab^T, diag(h_bb)]] x = [g_a, g_b]: the backgrounds
    eliminated (Schur complement of their diagonal block), O(K^2 D) instead of the dense
    (K + D)^3 solve, which cost 1,024 reciprocal CC-SOCR points ~10 ms a call (0.3 G flops)
    and 4,096 points ~0.5 s (23 G flops) a call."""
    scaled = h_ab / h_bb  # (K, D): h_ab diag(h_bb)^-1
    step_a = np.linalg.solve(h_aa - scaled @ h_ab.T, g_a - scaled @ g_b)
    return np.concatenate([step_a, (g_b - h_ab.T @ step_a) / h_bb])
