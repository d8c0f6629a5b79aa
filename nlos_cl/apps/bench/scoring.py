"""Scoring rows for `nlos-cl bench`: the `Locator` plan, coarse to fine, against exhaustive
scoring of every cell and, where scripts/bench_peers.sh has run, y-tal's backprojection on the
same signals and grid (docs/results/performance/performance-peers.json). Each row says whether
the argmax cells agree. nlos_cl's two searches are timed interleaved, in one run; y-tal in its
own venv."""
from __future__ import annotations

import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

PEERS_JSON = (Path(__file__).resolve().parents[3] / "docs" / "results" / "performance"
              / "performance-peers.json")


def read_peers() -> dict:
    """{grid size: y-tal row} from docs/results/performance/performance-peers.json, or {}
    where it is absent."""
    try:
        rows = json.loads(PEERS_JSON.read_text())["rows"]
    except (OSError, ValueError, KeyError):
        return {}
    return {int(r["grid"]): r for r in rows}


def _signals_of(rt, rows, spots, path0, dt_m):
    """Rows scored as histograms: a Layout whose calibration puts bin k's centre at
    path0 + k dt_m per detector."""
    from ...core.constants import SPEED_OF_LIGHT as C
    from ...core.histograms import HistogramSet
    from ...core.paths import PathCalibration, TimeAxis
    from ...ops.signals import upload
    axis = TimeAxis(0.0, dt_m / C, rows.shape[1])
    cal = PathCalibration(C, np.asarray(path0) - 0.5 * dt_m)
    return upload(HistogramSet(rows, axis, spots, np.zeros(3), cal), rt)


def cases(rt, smoke):
    """(label, signals, grid, log_mode, signal width m, peer grid size or None)."""
    import nlos_cl as nl

    from ...core.grid import Grid
    from ...core.paths import TimeAxis
    from ...ops.ellipse_score import _point_target_inputs
    from ...physics.scene import paper_scene
    paper = nl.gauss_filter(nl.simulate(paper_scene(facet_size_m=0.02),
                                        TimeAxis(40 / 299_792_458.0, 10e-12, 4096), backend=rt))
    sizes = (128,) if smoke else (512, 2048)
    out = [(f"plane {n}x{n} x 3 det (paper scene, 10 ps)", paper,
            Grid((2.0, 0.5, 0.0), (4 / n, 4 / n, 0.01), (n, n, 1)), False, None, n)
           for n in sizes]
    n, det, vol = (64, 64, 32) if smoke else (512, 1024, 256)
    spad_grid = Grid((2.0, 0.5, 0.0), (4 / n, 4 / n, 0.01), (n, n, 1))
    vol_grid = Grid((2.0, 0.5, -1.0), (4 / vol, 4 / vol, 2 / vol), (vol, vol, vol))
    for label, grid, n_det, log in ((f"SPAD {n}x{n} x {det} det (log)", spad_grid, det, True),
                                    (f"volume {vol}^3 x 3 det", vol_grid, 3, False)):
        args = _point_target_inputs(grid, n_det=n_det, n_bins=4096)(_Host())
        sig = _signals_of(rt, args[0], args[2], args[4], 1.0 / args[5][0])
        out.append((label, sig, grid, log, 0.1, None))  # rows: a Gaussian of sigma 10 cm
    return out


class _Host:
    """A stand-in backend that keeps inputs as host arrays."""

    @staticmethod
    def from_numpy(a):
        return np.asarray(a)


def _time(locators, sig, rt, repeats):
    times = {k: [] for k in locators}
    for k, loc in locators.items():  # warm-up (builds programs)
        loc(sig)
    for _ in range(repeats):  # interleaved
        for k, loc in locators.items():
            start = time.perf_counter()
            loc(sig)
            rt.finish()
            times[k].append(time.perf_counter() - start)
    return times


def scoring_rows(rt, smoke, Row):
    from ...localization.locator import Locator
    peers = read_peers()
    rows = []
    for label, sig, grid, log, width, peer_n in cases(rt, smoke):
        locs = {s: Locator(sig.layout, grid, log_mode=log, search=s, signal_width_m=width,
                           estimator="paper")
                for s in ("coarse_to_fine", "exhaustive")}
        times = _time(locs, sig, rt, 3 if smoke else 5)
        found = {s: locs[s](sig).cell_position for s in locs}
        med = {s: statistics.median(t) for s, t in times.items()}
        c2f = times["coarse_to_fine"]
        how = locs["coarse_to_fine"].last_search
        same = bool(np.array_equal(found["coarse_to_fine"], found["exhaustive"]))
        note = (f"argmax same as exhaustive: {'yes' if same else 'NO'}; "
                f"{how.cells_scored if how else grid.n_cells} of {grid.n_cells} cells scored finely")
        peer = {"exhaustive": med["exhaustive"]}
        if peer_n in peers:
            yt = peers[peer_n]
            peer["y-tal bp"] = yt["seconds"]
            cell = np.round((found["coarse_to_fine"][:2] - grid.origin[:2]) / grid.step[:2])
            note += (f"; y-tal argmax {yt['argmax']} vs ours {cell.astype(int).tolist()} "
                     f"(y-tal spread {100 * yt['spread']:.0f} %)")
        rows.append(Row("locate", label, grid.n_cells * sig.n_detectors, med["coarse_to_fine"],
                        math.nan, 0.0, grid.n_cells / med["coarse_to_fine"], "cells",
                        math.nan, "launches and host syncs (see analysis)", 0.0,
                        (max(c2f) - min(c2f)) / med["coarse_to_fine"], note=note, peers=peer))
    return rows
