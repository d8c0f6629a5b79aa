"""Light that arrives after a target's direct return: the instrument response's
exponential tail and a delayed, broad interreflection ("fourth bounce") background. Both are a
causal, broad copy of the direct return, so each target's model column m_k gets copies
G_j m_k (G_j: convolution with one kernel of a fixed bank, unit mass), and the Gaussian
likelihood's mean becomes
    mu = sum_k (a_k m_k + sum_j b_kj G_j m_k) + background,   a_k, b_kj >= 0,
the b's solved with the amplitudes in the same non-negative least squares (profiled out: the
fit's parameters do not change). The bank (`BANK`, metres of path) spans what such light looks
like without knowing it: exponential tails of 50-400 ps (an IRF's) and Gaussian lobes of
0.1 m sd delayed 0.15-1.0 m (light that bounced once more: a non-negative mix of them is
any broad lobe in that range). The copies live on the observation (`Observation.late`: the
bank, or None), so every problem made for it (plates, closed shapes) carries them.

Kept only where the data ask for it (`with_late`): where the chosen fit misses the data, the
chosen shape (and, for a closed shape, the plate) is refitted with the copies, and the one
with the lowest BIC-like score is kept: cost in units of kappa (the noise correlation's
inflation) times the best candidate's Birge ratio, plus ln(N / kappa) per free parameter,
each active copy counted as one (`LATE_PENALTY` each). A fit that explains the data is left as
it is (clean one-target and closed draws keep their answers and their time).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ....core import progress
from ....core.constants import SPEED_OF_LIGHT, TINY
from ....core.stats import chi2_quantile
from ....core.tuning import SEARCH_DETECTORS

PS = 1e-12 * SPEED_OF_LIGHT  # m of path per ps
# ("exp", decay m) and ("lobe", delay m, sd m): the copies' kernels
BANK = tuple([("exp", tau * PS) for tau in (50.0, 100.0, 200.0, 400.0)] +
             [("lobe", d, 0.1) for d in (0.15, 0.3, 0.45, 0.6, 0.8, 1.0)])
FINE = 16  # kernel sub-samples per model sample (the column linear between samples)
# each active copy's parameters in the score, in units of ln(N / kappa) (the BIC's 1)
LATE_PENALTY = 1.0
# The most late light a target's return may carry, against its direct light, by kind (a joint
# budget: sum_j b_j / ratio_j <= a): an IRF's tail holds up to half the energy (b = a); light
# that bounced once more less (draws: 5-30 %; the range). Unbounded, the copies took
# 99.7 % of a sphere's light and a plate in front stood for it (background draw 4: 0.05 ->
# 0.32 m); with one cap of 1 for both, lobes took 31 % of a far sphere's light as its depth
# (IRF-tail draw 1, 3 collinear spots: 0.06 -> 0.32 m).
MAX_RATIO = {"exp": 1.0, "lobe": 0.5}
REFIT_NFEV_SCALE = 2  # the refits' evaluations, in the estimator's final_nfev
START_SHARE = 0.5  # counts: the copies' share of the light where their solve starts
# a copy is in use where its amplitude is above ACTIVE of its target's (the solves give exact
# zeros; a margin for rounding)
ACTIVE = 1e-9


def _density(spec, s) -> np.ndarray:
    if spec[0] == "exp":
        return np.exp(-s / spec[1]) / spec[1]
    _, delay, sd = spec
    return np.exp(-0.5 * ((s - delay) / sd) ** 2) / (sd * math.sqrt(2.0 * math.pi))


def kernel_weights(spec, dpath: float, n: int) -> np.ndarray:
    """(n,) weights of lags 0..n-1 samples: the kernel's mass over each fine step, split
    between the two samples around its delay (exact for a column linear between samples)."""
    s = (np.arange(n * FINE) + 0.5) / FINE  # delays in samples
    mass = _density(spec, s * dpath) * dpath / FINE
    j = np.floor(s).astype(int)
    f = s - j
    w = np.bincount(j, mass * (1.0 - f), n + 1) + np.bincount(j + 1, mass * f, n + 1)
    return w[:n]


class Copies:
    """The bank's kernels as spectra on an observation's sample grid (each detector its own
    dpath), and the causal copies of columns (`of`)."""

    def __init__(self, obs, bank=BANK):
        self.bank, n = tuple(bank), obs.n
        self.nfft = 1 << math.ceil(math.log2(max(2 * n, 2)))
        dpath = np.broadcast_to(np.asarray(obs.dpath, float), (len(obs.valid),))
        steps, which = np.unique(dpath, return_inverse=True)
        spectra = np.stack([np.stack([np.fft.rfft(kernel_weights(k, float(s), n), self.nfft)
                                      for k in self.bank]) for s in steps])  # (S, J, F)
        self.spectra = np.moveaxis(spectra[np.reshape(which, -1)], 0, 1)  # (J, D, F)
        self.valid, self.n = np.asarray(obs.valid, bool), n

    @property
    def j(self) -> int:
        return len(self.bank)

    def of(self, cols) -> np.ndarray:
        """(K, J, D, n): each column (K, D, n) convolved with each kernel, zero outside the
        valid samples (light before the window is not modelled: the window opens in the margin
        before any target's return)."""
        spec = np.fft.rfft(np.asarray(cols, float), self.nfft, axis=-1)
        out = np.fft.irfft(spec[:, None] * self.spectra[None], self.nfft, axis=-1)
        return np.where(self.valid, out[..., :self.n], 0.0)


def copies_of(problem, cols):
    """(K, J, D, n) the late copies of columns (K, D, n) on problem's observation, or None
    where it has none; the last call's kept (a fit asks linear, then residual, of the same)."""
    obs = problem.obs
    if getattr(obs, "late", None) is None:
        return None
    kept = getattr(problem, "_copies", None)
    if kept is not None and kept[0] is cols:
        return kept[1]
    if getattr(problem, "_late", None) is None:
        problem._late = Copies(obs, obs.late)
    out = problem._late.of(cols)
    problem._copies = (cols, out)
    return out


def split(obs, lin, k: int):
    """(amplitudes (K,), background coefficients (p * D,), late amplitudes (K, J)) of the
    Gaussian linear factors of K targets [a, c, b] (empty parts where there are none)."""
    lin = np.asarray(lin, float)
    j = 0 if getattr(obs, "late", None) is None else len(obs.late)
    end = len(lin) - k * j
    return lin[:k], lin[k:end], lin[end:].reshape(k, j)


def capped(cols, copies, bank=BANK) -> np.ndarray:
    """(K J, D, n) the columns the linear solve takes for the copies: G_j m_k + m_k / r_j
    (r_j: MAX_RATIO of the kernel's kind). With s_k >= 0 the amplitude of m_k alone,
    a_k = s_k + sum_j b_kj / r_j: every solution has sum_j b_kj / r_j <= a_k (the late light
    within its budget of the return's), and a non-negative least squares in (s, b) finds it."""
    k, j = copies.shape[:2]
    ratio = _ratios(bank)[None, :, None, None]
    return (copies + cols[:, None] / ratio).reshape((k * j,) + cols.shape[1:])


def uncapped(x, k: int, bank=BANK) -> np.ndarray:
    """[a, b.ravel()] from the solve's [s, b.ravel()] (`capped`)."""
    s, b = x[:k], x[k:].reshape(k, -1)
    return np.concatenate([s + (b / _ratios(bank)).sum(axis=1), x[k:]])


def poisson_linear(obs, cols, extra, warm, start, bank=BANK) -> np.ndarray:
    """Counts' linear factors [a, background (D,), b.ravel()] with the copies: the budget's
    columns (`capped`) with the targets' in the Poisson solve (forward.late_counts); from
    `start` (forward.likelihood's [amplitudes, backgrounds]) each copy begins at START_SHARE
    of the amplitude, spread over the bank inside its budget."""
    from . import late_counts
    k = len(cols)
    both = np.concatenate([cols, capped(cols, extra, bank)])
    if warm is None:
        phi = start(cols)
        b = np.outer(phi[:k], START_SHARE * _ratios(bank) / len(bank)).ravel()
        phi = np.concatenate([phi[:k] * (1.0 - START_SHARE), b, phi[k:]])
    else:  # [a, background, b] -> [s, b, background] (`uncapped` undone)
        warm = np.asarray(warm, float)
        b = warm[len(warm) - extra.shape[0] * extra.shape[1]:]
        s = warm[:k] - (b.reshape(k, -1) / _ratios(bank)).sum(axis=1)
        phi = np.concatenate([np.maximum(s, 0.0), b, warm[k:len(warm) - b.size]])
    phi = late_counts.solve(obs.y, obs.valid.astype(np.float64), both, phi)
    amp = uncapped(phi[:len(both)], k, bank)
    return np.concatenate([amp[:k], phi[len(both):], amp[k:]])


def _ratios(bank) -> np.ndarray:
    return np.array([MAX_RATIO[spec[0]] for spec in bank])


def nnls(a_mat, b) -> np.ndarray:
    """argmin_{x >= 0} |x A - b| for A (M, N) rows of columns: SciPy's Lawson-Hanson (a
    hand-written one gave the same optimum at 8-20x the time, 0.84 ms against 0.11 for 11
    columns of 700 samples, on every model evaluation that carries copies)."""
    from scipy.optimize import nnls as lawson_hanson
    return lawson_hanson(np.asarray(a_mat, float).T, np.asarray(b, float))[0]


def in_use(amp, late_amp) -> np.ndarray:
    """(K, J) bool: the copies in use (amplitude above ACTIVE of their target's)."""
    amp = np.asarray(amp, float).reshape(-1)
    return np.asarray(late_amp, float).reshape(len(amp), -1) > ACTIVE * amp[:, None]


def summary(amp, late_amp, bank=BANK) -> dict:
    """The fitted copies for the diagnostics: their share of the fitted light (the kernels have
    unit mass), the mean delay of the lobes' and the mean decay of the tails' part."""
    a = float(np.sum(amp))
    b = np.where(in_use(amp, late_amp), np.reshape(late_amp, (-1, len(bank))), 0.0).sum(axis=0)
    out = {"late_share": float(b.sum() / max(a + b.sum(), TINY)),
           "late_terms": int(np.count_nonzero(b > 0))}
    for kind, key, i in (("exp", "late_tail_decay_m", 1), ("lobe", "late_lobe_delay_m", 1)):
        on = np.array([k[0] == kind for k in bank])
        w = b[on]
        out[key.replace("_decay_m", "_share").replace("_delay_m", "_share")] = \
            float(w.sum() / max(a + b.sum(), TINY))
        if w.sum() > 0:
            out[key] = float(w @ np.array([k[i] for k in bank if k[0] == kind]) / w.sum())
    return out


def birge(problem, result, free, info) -> float:
    """The fit's Birge ratio (covariance's; counts: the deviance per degree of freedom), as
    policy.criteria.misfit reads it."""
    b = info.get("birge_ratio")
    if b is None:
        b = result.cost / max(result.n_residuals - int(np.count_nonzero(free)) - 1, 1)
    return float(b)


def misses(problem, result, cov_info, free=()) -> tuple[bool, float]:
    """(the fit misses the data, its Birge ratio): above the 99.9 % point of chi^2_nu / nu,
    nu = N / kappa (policy.criteria.misfit's test, which this room cannot import)."""
    n_eff = max(result.n_residuals / kappa(problem.obs), 2.0)
    b = birge(problem, result, free, cov_info)
    return b > chi2_quantile(0.999, n_eff) / n_eff, b


def _score(problem, result, free, n_late, scale) -> float:
    n_eff = max(result.n_residuals / kappa(problem.obs), 2.0)
    params = int(np.count_nonzero(free)) + len(result.params) + LATE_PENALTY * n_late
    return result.cost / scale + params * math.log(n_eff)


def kappa(obs) -> float:
    """The noise correlation's inflation tr(C^2) / tr(C) (policy.criteria's)."""
    return float(1.0 + 2.0 * np.sum(np.asarray(obs.rho)[1:] ** 2))


def active(problem, result) -> int:
    """The copies the fit uses (`in_use`)."""
    if getattr(problem.obs, "late", None) is None:
        return 0
    amp, _, b = problem.split(result.linear, len(result.params))
    return int(np.count_nonzero(in_use(amp, b)))


def with_late(est, chosen, plate, plates, solvers, smooth=None):
    """`chosen` (a one-target fit: problem, result, free, cov) or, where it misses the data
    and a fit with the late copies scores lower (module docstring), that fit: the plate
    `plate` = (params, free) refitted with the copies, then the estimator's plate-or-closed
    choice run on it (the closed shapes inherit the copies from the observation); cov.info
    says what was tried. plates: the frame's plates problem (it counts the refits'
    forward calls). solvers: (solve.fit.fit, solve.covariance.covariance,
    policy.subset.plate_or_closed), passed in: this room imports no solver; smooth: the
    latter's."""
    fit, covariance, cascade = solvers
    problem, result, free, cov = chosen
    if len(result.params) != 1 or getattr(problem.obs, "late", None) is not None:
        return chosen
    if len(plates.obs.spots) > SEARCH_DETECTORS:
        # not on every histogram of a scan: the counts' solve holds a dense Gram of the
        # backgrounds (LCT's 4,096: 72 least squares of 4,107 unknowns, 254 s CPU)
        cov.info.update(late_tried=False)
        return chosen
    missed, before = misses(problem, result, cov.info, free)
    if not missed:
        return chosen
    progress.stage("model fit: refitted with late copies of the light (an instrument tail, "
                   "broad returns)")
    p = est.problem(replace(plates.obs, late=BANK), plates.backend)
    params, plate_free = plate
    r = fit(p, params, plate_free, REFIT_NFEV_SCALE * est.final_nfev)
    other = cascade(est, p, r, plate_free, covariance(p, r, plate_free), None, smooth)
    for used in {id(p): p, id(other.problem): other.problem}.values():
        plates.calls, plates.model_s = plates.calls + used.calls, plates.model_s + used.model_s
    fits = [(chosen, before, 0), (other, birge(other.problem, other.result, other.free,
                                               other.cov.info), active(other.problem, other.result))]
    scale = kappa(p.obs) * max(1.0, min(b for _, b, _ in fits))
    scores = [_score(c.problem, c.result, c.free, n, scale) for c, _, n in fits]
    kept = fits[int(np.argmin(scores))][0]
    info = {"late_tried": True, "late_kept": kept is other,
            "late_score_gain": float(scores[0] - scores[1]), "late_birge_before": before}
    if kept is other:
        amp, _, late_amp = kept.problem.split(kept.result.linear, 1)
        info.update(summary(amp, late_amp))
    kept.cov.info.update(info)
    return kept
