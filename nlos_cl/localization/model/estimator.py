"""`ModelEstimator`: analysis by synthesis. Fit K upright plates (one target: a plate, or an
upright box where the plate misses the data) to the measured histograms with the forward model
(the registered "forward" operation, on the backend), report each target's centre, size and a
calibrated covariance. Plugs into `nl.locate(..., estimator="model")`."""
from __future__ import annotations

import functools
import time

import numpy as np

from ...core import progress
from ...core.blas_threads import serial_blas  # small products: threads only cost
from ...core.constants import FWHM_PER_SIGMA
from ...ops.gauss_filter import filter_window
from ...core.errors import refuse_moved, warn
from ...core.limits import require_targets
from ...core.tuning import SEARCH_DETECTORS
from ..estimate import Capabilities, Estimate, LocatedTarget, Prior
from ..fit_result import ModelFit, Parameter, WarmStart
from ..paper import PaperArgmax
from ..region import unseen_axis
from .forward import data, late
from .forward.likelihood import Problem
from .options import GROUPS, FitBudget, Instrument, check_options, model_reflectance
from .policy.depth import several_unseen_note, uncertain_note, unseen_note
from .policy.lobe import with_lobe
from .policy.rivals import rival_note
from .policy.filtered_search import searched, smooth_observation
from .policy.criteria import support
from .policy.sanity import checked, fit_checks, leftover_note, unfittable_line
from .policy.warm import hidden_diagnostics
from .shapes import plate
from .shapes.lattices import lattice_for
from .shapes.shape import MODELS, name_of
from .solve.covariance import centre_covariance, covariance
from .solve.fit import fit
from .solve.records import Chosen, Fitted

# Frame-free words: an answer is reported in the capture's frame, where height is Y (y-tal's)
# and ours z; the held axis shows as "unobservable" in the answer's own axes.
HEIGHT_WARNING = ("height (up the wall) is unobservable with collinear wall spots (rotating the "
                  "target about their line changes no path): it is held at the search "
                  "region's middle height; use spots off one line to measure it")
# spots on a vertical line: the azimuth about it is unseen, and x is held as z is for a line
# along x (random one-target draws on vertical lines: p90 0.32 m from the paper's argmax,
# which the fit had fallen back to)
X_WARNING = ("the position across a vertical line of wall spots is unobservable (rotating the "
             "target about their line changes no path): it is held at the search region's "
             "middle; use spots off one line to measure it")
HELD_WARNINGS = {2: HEIGHT_WARNING, 0: X_WARNING}
# model_on="auto": plate fits with up to this many detectors evaluate the model on the host
# (model.batch, a Jacobian's plates in one call), larger ones with the forward op on
# the device. On the paper's scene a forward call costs ~2 ms of launches and read-backs for
# ~240 samples a detector; the host's batched float64 model gives the same fit (costs within
# 1e-4) 3-5x faster (one-shot `nlos-cl locate`: docs/results/performance/performance.md). The closed shapes too
# (model.host_shapes; any laser layout): a Jacobian's 8 columns 40-70 -> 10-13 ms on 6 spots,
# 140-220 -> 40-65 ms on 42 (one-target draws 1 and 173).
HOST_DETECTORS = 64


def plates_path(model_on: str, n_spots: int, paired: bool) -> str:
    """Where a Lambertian plate fit's model runs: 'host' (model.batch's NumPy), 'kernel' (the
    plate_model operation) or 'forward op' (likelihood.Problem). model_on 'auto': the host up
    to HOST_DETECTORS spots (the kernel where each spot has its own laser spot, which only it
    models), the forward op beyond (bench: nlos-cl bench's model paths table)."""
    if model_on == "auto":
        if n_spots > HOST_DETECTORS:
            return "forward op"
        return "kernel" if paired else "host"
    if model_on == "kernel":
        return "kernel"
    return "host" if model_on == "host" and not paired else "forward op"


class ModelEstimator:
    """Fit `targets` plates (an int, or 'auto': add plates while they pass the test in
    model.select). `likelihood`: 'gauss' (AWGN; the data are compared after a Gauss
    filter of window h_s: None for the one the rows passed), 'poisson' (photon counts in `raw`), or 'auto' (counts when `raw`
    holds non-negative whole numbers). `backend`: where the forward model runs while fitting
    (default: the scored frame's backend). model_on: 'device' (the forward op on `backend`),
    'host' (plates in float64 NumPy, many per call: model.batch), 'kernel' (as host, its
    unshadowed plates by the plate_model op on `backend`) or 'auto' (host for up to
    HOST_DETECTORS detectors, plates and closed shapes). instrument: the pulse and jitter the
    model assumes (forward.data.Instrument); budget: the fits' evaluations (solve.fit.FitBudget:
    final_nfev, and warm_nfev for a warm-started fit, `estimate(scored, start=...)`). sanity: check each fit's size, misfit and
    place against the paper's argmax and, for one target, report the argmax instead of a fit
    that fails (model.sanity; False: report every fit as is). reflectance: the targets'
    reflectance model (nlos_cl.physics.reflectance: a Lambertian BRDF, GGX, Retroreflective),
    known, not fitted; the amplitude absorbs its scale; None: Lambertian, or a GGX lobe where
    the Lambertian fit misses the data and the lobe's evidence wins (policy.lobe)."""

    name = "model"

    @property
    def capabilities(self) -> Capabilities:
        """from_paper: the scored frame serves only the paper's estimate (a start, the no-signal
        test); warm_start: a fixed number of targets, plates allowed (docs/tracking.md)."""
        return Capabilities(from_paper=True, needs_raw=True, paired=True,
                            warm_start=isinstance(self.targets, int) and self.closed is not True)

    def __init__(self, targets=1, *, likelihood="auto", h_s=None,
                 instrument: Instrument = Instrument(), lattice=None, max_targets=3, backend=None,
                 budget: FitBudget = FitBudget(), closed="auto", model_on="auto", sanity=True,
                 reflectance=None, **moved):
        refuse_moved("ModelEstimator", moved, GROUPS, "the options of ModelEstimator's "
                     "docstring (docs/model-estimator.md)")
        check_options(targets, likelihood, closed, model_on)
        self.closed, self.model_on, self.sanity = closed, model_on, bool(sanity)
        self.targets, self.likelihood = targets, likelihood
        self.h_s = None if h_s is None else float(h_s)
        self.pulse_sigma_s = float(instrument.pulse_fwhm_s) / FWHM_PER_SIGMA
        self.jitter_s, self.lattice = float(instrument.jitter_s), lattice
        self.max_targets, self.backend = int(max_targets), backend
        self.final_nfev, self.warm_nfev = budget.final_nfev, int(budget.warm_nfev)
        self.reflectance = model_reflectance(reflectance)
        self.lobe_search = reflectance is None  # not told: a lobe where the data ask for one
        self.timings: dict = {}

    def window_s(self, scored) -> float:
        """The Gauss filter's window the scored rows passed: h_s where given, else the one the
        filter used (Signals.filtered_h_s), else the default for the bins."""
        if self.h_s is not None:
            return self.h_s
        sig = scored.signals
        return sig.filtered_h_s or filter_window(sig.layout.time_axis.dt_s)

    def observation(self, scored):
        return data.observation(scored, self.likelihood, frac=data.window_frac(self.targets),
                                h_s=self.window_s(scored), pulse_sigma_s=self.pulse_sigma_s,
                                jitter_s=self.jitter_s)

    # ------------------------------------------------------------------ the estimate
    def estimate(self, scored, prior: Prior | None = None, *, start=None) -> Estimate:
        """The targets in one frame. prior: None (the full fit from the data alone), or a
        Prior of (targets, 6) plate rows (x, y, z, width, height, yaw) to warm-start from, e.g.
        the previous frame's fit moved to where a tracker predicts it: only the final fit
        runs, from there (nlos_cl.localization.model.policy.warm), and the full fit replaces it where
        it misses the data; each target's fit.warm_start says which. Its size, size_sd hold a
        plate the others hide (model.warm.size_prior). start=rows is prior=Prior(rows)."""
        with serial_blas(), progress.staged("model fit: the histograms' windows and noise"):
            prior = Prior(start) if prior is None and start is not None else prior
            clock = {"start": time.perf_counter()}
            paper = scored.paper  # the Locator's fused search, or (no map read yet) from scores
            if paper is None:
                paper = PaperArgmax().estimate(scored)  # also rejects frames with no signal
            clock["argmax"] = time.perf_counter()
            obs = self.observation(scored)
            if isinstance(self.targets, int):  # before any fit: K the histograms can determine
                require_targets("targets", self.targets, len(obs.spots))
            clock["data"] = time.perf_counter()
            held = held_axis(obs, scored.grid)
            if held is None:  # collinear spots on a tilted line: no one axis to hold
                warn(unfittable_line(obs.spots, obs.laser))
                return Estimate(list(paper.targets), paper.cell_position, paper.score)
            observable = held.axis != 2  # the height (ModelFit.height_observable)
            free = held.free_mask()
            fitted, warm_info = _warm_or_cold(self, scored, obs, paper, free, held, prior, clock)
            fitted, lobe = (fitted, None) if prior is not None else with_lobe(
                self, fitted, lambda e: e._cold(scored, obs, paper, free, held, clock),
                (free, held, scored.backend))  # a glossy target: policy.lobe
            chosen, result, free, (cov_all, info) = fitted.chosen
            history = fitted.history
            info = _reported(chosen, result, free, cov_all, info, warm_info)
            if lobe is not None:
                info["reflectance"] = lobe
            notes = _notes(held, chosen.shape, result, cov_all, info)
            if self.sanity and (left := leftover_note(chosen, result, self.targets)):
                notes.append(left)
            for note in notes:
                warn(note)
            self.timings = _stages(clock, fitted.problem)
            hidden = hidden_diagnostics(chosen, result, prior)
            for h, kept in zip(hidden, support(chosen, result, free, info.get("birge_ratio"))):
                h["support"] = kept  # K >= 2: the BIC gain of keeping each plate
            located = [self._target(result, cov_all, k, dict(info, **hidden[k]), notes,
                                    obs, history, observable, chosen.shape)
                       for k in _order(result)]
            if self.sanity:
                located = checked(located, paper.targets[0].position, obs.spots, obs.laser)
            return Estimate(located, paper.cell_position, paper.score)

    def _cold(self, scored, obs, paper, free, held, clock):
        """The full fit: starts, short fits, final fit, covariance, plate or closed shape."""
        problem = self.problem(obs, self.backend or scored.backend)
        smooth = smooth_observation(self, scored, obs)  # counts: searched on it
        result, history, choice = self._fit(problem, paper.targets[0].position, free, held,
                                            smooth)
        clock["fit"] = time.perf_counter()
        if result is None:  # decided on a subset of many detectors (model.subset.cold_fit)
            return Fitted(problem, choice.chosen, history)
        cov = covariance(problem, result, free, reuse=result.jacobian is not None)
        clock["covariance"] = time.perf_counter()
        chosen = Chosen(problem, result, free, cov)
        if len(result.params) == 1:  # one target: a plate, or a box where the data ask for it
            from .policy.subset import plate_or_closed
            chosen = plate_or_closed(self, problem, result, free, cov, choice, smooth)
            clock["box"] = time.perf_counter()
            chosen = late.with_late(self, chosen, (result.params, free), problem,
                                    (fit, covariance, plate_or_closed), smooth)
        elif self.closed is not False:  # several: closed shapes for all, or one closed target
            from .policy.closed_many import several
            chosen = several(self, problem, chosen, paper.targets[0].position, held, smooth,
                             history)
            clock["box"] = time.perf_counter()
        return Fitted(problem, chosen, history)

    def problem(self, obs, backend):
        """The plates' Problem: the model on the host or with the forward op on `backend`
        (model_on); a HostProblem keeps `backend` for the closed shapes."""
        from .forward.batch import HostProblem
        from .forward.host_shapes import host_can
        lattice = self.lattice_for(obs)
        refl = self.reflectance
        on_host = host_can(refl) and (self.model_on in ("host", "kernel") or (
            self.model_on == "auto" and len(obs.spots) <= HOST_DETECTORS))
        path = plates_path(self.model_on, len(obs.spots), obs.laser.ndim == 2)
        problem = None
        if on_host and path != "forward op":
            problem = HostProblem(obs, lattice, backend, refl, path == "kernel")
            problem = None if problem.paired and not problem.kernel else problem
        if problem is None:
            problem = Problem(obs, backend, lattice, reflectance=refl)
        problem.closed_on_host = on_host  # model.host_shapes.shape_problem
        return problem

    def lattice_for(self, obs):
        """The plates' lattice (model.lattices.lattice_for; lattice=: the estimator's own)."""
        return lattice_for(obs, self.lattice)

    def _fit(self, problem, argmax_position, free, held, smooth=None):
        """(result, history, choice): fit_targets; with more than SEARCH_DETECTORS detectors
        on a spread subset, then the final fit on all of them (model.subset.cold_fit: result
        None where the choice made on the subset ends the fit; choice: that choice, or None).
        The final fit keeps its last Jacobian for the covariance (model.covariance's `reuse`,
        as the warm fits do): on the device's forward op, central differences cost 13 more
        columns (a 1,024-spot SPAD patch: 0.49 -> 0.035 s of a ~3.3 s locate, sds within
        0.5 %); fewer detectors keep the exact analytic derivatives, which cost a host call.
        smooth: None, or (counts) the frame's Gauss observation, searched instead
        (model.filtered_search)."""
        if len(problem.obs.spots) <= SEARCH_DETECTORS:
            return (*searched(self, problem, argmax_position, free, held, smooth), None)
        from .policy.subset import cold_fit
        return cold_fit(self, problem, argmax_position, free, held, smooth)

    def _target(self, result, cov_all, k, info, notes, obs, history, observable, shape):
        p = result.params[k]
        fit = _model_fit(shape, p, result, cov_all, k, info, notes, obs, history, observable,
                         self.timings)
        return LocatedTarget(p[:3].copy(), centre_covariance(cov_all, k, shape),
                             shape.extent(p), fit=fit)


def _model_fit(shape, p, result, cov_all, k, info, notes, obs, history, observable, timings):
    """Target k of a fit as a typed ModelFit (its JSON view is the old details dict)."""
    n = shape.N_PARAMS
    sd = np.sqrt(np.diag(cov_all)[k * n:(k + 1) * n])
    params = tuple(Parameter(name, float(v), float(lo), float(hi), bool(np.isfinite(s)),
                             float(s) if np.isfinite(s) else np.nan)
                   for name, v, lo, hi, s in zip(shape.NAMES, p, shape.LOWER, shape.UPPER, sd))
    diagnostics = {key: v for key, v in info.items() if key not in ("birge_ratio", "warm_start")}
    warm = info.get("warm_start")
    short = name_of(shape)
    return ModelFit(short, MODELS[short], params, float(result.linear[k]), shape.normal_of(p),
                    obs.mode, result.cost, result.n_residuals, info.get("birge_ratio"),
                    observable, dict(timings), tuple(history), tuple(notes),
                    None if warm is None else WarmStart(**warm), diagnostics)


def _warm_or_cold(est, scored, obs, paper, free, held, prior, clock) -> tuple[Fitted, dict]:
    """(fitted, warm_info): the warm fit from the Prior's rows (and sizes) where it explains
    the data, else the cold fit, unless the cold fit costs more than the misfit warm one (same
    data, same K; data costs alone: the warm fit's size prior is not counted)."""
    fitted, warm_info, missed = None, None, None
    if prior is not None:
        from .policy.warm import warm_or_retry
        fitted, warm_info, missed = warm_or_retry(est, obs, prior, free, held, scored.backend)
        clock["warm_fit"] = time.perf_counter()
    if fitted is None:
        fitted = est._cold(scored, obs, paper, free, held, clock)
        if missed is not None and missed.result.cost < fitted.result.cost:
            missed.problem.calls += fitted.problem.calls  # the timings count the cold fit's work
            missed.problem.model_s += fitted.problem.model_s
            fitted = missed
            warm_info = dict(warm_info, used=True, reason=warm_info["reason"] +
                             "; the cold fit cost more, so the warm fit is kept")
    return fitted, warm_info


def held_axis(obs, grid) -> plate.Held | None:
    """The axis the fit holds (plate.Held: none, z for collinear spots along x, x for spots
    along z) at the middle of the search region `grid` (which holds the same axis on the same
    plane: region.unseen_axis); None for collinear spots on a line along neither axis."""
    laser = np.asarray(obs.laser, np.float64)
    spots = np.asarray(obs.spots, np.float64)
    return _held_axis(spots.tobytes(), laser.tobytes(), laser.ndim, grid)


@functools.lru_cache(maxsize=32)
def _held_axis(spots: bytes, laser: bytes, laser_ndim: int, grid) -> plate.Held | None:
    """held_axis of one layout and region, made once (a tracker's frames share them: the
    collinearity tests were 0.1 ms of a ~10 ms frame). plate.Held is frozen."""
    spots = np.frombuffer(spots).reshape(-1, 3)
    laser = np.frombuffer(laser).reshape((-1, 3) if laser_ndim == 2 else (3,))
    middle = tuple(float(o + 0.5 * (n - 1) * s) for o, n, s in
                   zip(grid.origin, grid.shape, grid.step))
    if plate.height_observable(spots, laser):
        return plate.Held(None, middle)
    axis = unseen_axis(np.vstack([np.reshape(laser, (-1, 3)), spots]))
    return None if axis is None else plate.Held(axis, middle)


def _reported(chosen, result, free, cov_all, info, warm_info) -> dict:
    """info with the warm start's report (where one was tried) and what sanity.doubt reads:
    the misfit (the Birge ratio, or counts' deviance per degree of freedom, as criteria.misfit)
    and whether one target's depth is unseen."""
    if warm_info is not None:
        info = dict(info, warm_start=warm_info)
    return dict(info, **fit_checks(chosen, result, free, cov_all, info))


def _notes(held, shape, result, cov_all, info) -> list[str]:
    """What every answer of this fit says: an axis unobservable (collinear spots); one
    target's depth not seen by these spots; a target whose centre is poorly determined, or
    that another closed family fits nearly as well with its centre elsewhere (numbered as
    reported: `_order`)."""
    notes = [] if held.axis is None else [HELD_WARNINGS[held.axis].format(v=held.value)]
    depth = len(result.params) == 1 and unseen_note(shape, result, cov_all, info)
    if depth:
        notes.append(depth)
    for at, k in enumerate(_order(result)):
        notes.extend(why for why in (
            not shape.CLOSED and several_unseen_note(info, k, at),
            not depth and uncertain_note(centre_covariance(cov_all, k, shape), at),
            rival_note(info, k, at)) if why)
    return notes


def _order(result):
    """Targets by the signal energy they explain, strongest first."""
    return list(np.argsort(-np.abs(result.linear[:len(result.params)])))


def _stages(clock, problem) -> dict:
    keys = list(clock)
    out = {b: clock[b] - clock[a] for a, b in zip(keys, keys[1:])}
    out["forward_calls"] = problem.calls
    out["forward_s"] = problem.model_s
    out["total"] = clock[keys[-1]] - clock[keys[0]]
    return out
