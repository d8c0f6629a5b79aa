"""HostProblem's plates evaluated by the plate_model operation (ops/plate_model.py) on the
problem's backend: HostProblem(kernel=True), ModelEstimator(model_on='kernel'). The same model
as the host's NumPy passes (model.batch) in float32, many plates a launch, and with a laser spot
per detector too (confocal scans, paired layouts), which the host's passes do not model."""
from __future__ import annotations

import time

import numpy as np

from ..shapes import plate


def evaluate(problem, rows, like) -> np.ndarray:
    """HostProblem._evaluate by the plate_model operation on the problem's backend (its Plan,
    made once per problem): each plate with the cell statistics of its `like` row (or its
    own), computed on the device for the distinct rows that lend them. A NumPy backend runs
    the operation's twin."""
    t = time.perf_counter()
    obs = problem.obs
    lenders = rows if like is None else like
    stat_rows, stat_of = np.unique(lenders, axis=0, return_inverse=True)
    sigma0sq = obs.sigma0_m ** 2 - obs.box_excess_m2
    if problem._plan is None and hasattr(problem.backend, "context"):
        from ....ops.plate_model import Plan
        problem._plan = Plan(problem.backend, obs.spots, obs.laser, problem._some,
                             _affine(problem), obs.dpath, problem.os, problem.lattice,
                             plate.flat_share(problem.lattice), plate.GAUSS_2)
    if problem._plan is not None:
        hist = problem._plan(rows, stat_rows, stat_of.reshape(-1), obs.edge0, sigma0sq, obs.n)
    else:
        hist = problem.backend.to_numpy(problem.backend.call(
            "plate_model", rows, stat_rows, stat_of.reshape(-1), obs.spots, obs.laser,
            problem._some, _affine(problem), obs.edge0, obs.dpath, sigma0sq, obs.n,
            problem.os, problem.lattice, plate.flat_share(problem.lattice), plate.GAUSS_2))
    problem.calls += len(rows)
    problem.model_s += time.perf_counter() - t
    return np.where(obs.valid[None], hist, 0.0)


def _affine(problem) -> np.ndarray:
    """(D, S): the shift at every spot from the statistics spots' (HostProblem._affine's
    basis times its pseudo-inverse; the identity where every spot is a statistics spot)."""
    if problem._affine is None:
        return np.eye(len(problem.obs.spots))
    basis, coef_of = problem._affine
    return basis @ coef_of
