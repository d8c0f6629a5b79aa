"""What a sweep worker does for `reproduce beyond`: one frame of one case, both estimators, as
the case's CSV rows (one per truth). The study's runner (sweep builds the study).

A case is plain data (section, label, layout names, targets, search z range, K, signal
photons), so the table says what every run was. The clean simulation of a case is kept per
worker process (`worker_cache`): the runs of one case (its seeds) share a batch and simulate it
once; the simulation is deterministic, so a cached one equals a fresh one.
"""
from __future__ import annotations

import numpy as np

import nlos_cl as nl
from nlos_cl.sweep import worker_cache
from nlos_cl.sweep.registry import runner

from ..common import Settings
from . import cases as bc


@worker_cache(keep=3)
def clean(name: str, spec: dict, targets: list, settings: dict):
    """Clean signals of the targets on the layout `name` (its beyond.yaml `spec`)."""
    return bc.simulate(bc.layout({"layouts": {name: spec}}, name), Settings(**settings), targets)


def counter_for(clean_signals, photons: float) -> nl.PhotonCounter:
    """PhotonCounter (defaults) with its pulse count scaled to `photons` signal photons per
    detector (expected, summed over the record; background excluded)."""
    base, hist = nl.PhotonCounter(), clean_signals.histograms()
    total = base.expected_counts(hist).data.sum(axis=1)
    background = base.expected_counts(hist.with_data(np.zeros_like(hist.data))).data.sum(axis=1)
    signal = float(np.mean(total - background))
    return nl.PhotonCounter(n_pulses=base.n_pulses * photons / signal)


@runner  # the study's `runner` (registered: a study may name it)
def run(case: dict, seed: int, layouts: dict, settings: dict) -> list[dict]:
    """One frame of `case` with noise seed `seed`: both estimators, the CSV rows (one per
    truth). The model may see another layout's signals (the SPAD subset)."""
    s = Settings(**settings)
    lay = bc.layout({"layouts": layouts}, case["layout"])
    signals = clean(lay.name, layouts[lay.name], case["targets"], settings)
    model_lay, model_signals = None, None
    if case["model_layout"]:
        model_lay = bc.layout({"layouts": layouts}, case["model_layout"])
        model_signals = clean(model_lay.name, layouts[model_lay.name], case["targets"], settings)
    noise = None if case["photons"] is None else counter_for(signals, case["photons"])
    grid = bc.search_grid(s, case["z_range"])
    frame = bc.run_frame(signals, seed, lay, grid, s, case["k"], noise, model_signals, model_lay)
    truths = np.asarray([t[1] for t in case["targets"]], float)
    return bc.frame_rows(case["section"], case["case"], lay, seed, frame, truths)
