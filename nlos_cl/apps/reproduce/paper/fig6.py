"""Fig. 6: the probability maps of detector A alone and of all three detectors, from the raw,
fitted and filtered signals, and the located positions over noise seeds."""
from __future__ import annotations

from pathlib import Path

import nlos_cl as nl
from nlos_cl.apps import plotting

from ..common import METHODS, PAPER, Result, Settings, paper_target, run_trials, stats, title

MAP_METHODS = ("raw", "fit", "filter")  # the figure's columns, as in the paper


def fig6(s: Settings, out: Path) -> Result:
    scene = paper_target(s=s)
    trials, clean = run_trials(scene, s)
    grid = s.grid()
    noisy = nl.add_noise(clean, s.snr_db, 0)
    sources = {"raw": noisy, "fit": nl.gauss_fit(noisy)[0],
               "filter": nl.gauss_filter(noisy, s.h_s)}
    maps = {}
    for method in MAP_METHODS:
        hist = sources[method].histograms()
        # raw given: each signal scored as it is (nl.locate would filter the raw one)
        maps[method] = tuple(nl.locate(h, grid, return_map=True, estimator="paper", raw=h)
                             for h in (hist.select([0]), hist))
    figure = plotting.maps_figure(maps, scene.truth, out, "fig6")
    rows = [{"method": m, **stats(trials[m]), "paper_x": PAPER["fig6"][m][0],
             "paper_y": PAPER["fig6"][m][1]} for m in METHODS]
    return Result("fig6", title("fig6"), rows,
                  {r["method"]: {k: r[k] for k in ("x", "y", "mean_m", "std_m", "max_m")}
                   for r in rows}, [figure])
