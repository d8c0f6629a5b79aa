"""Fig. 10: the target at every point of a 5 x 5 grid of positions; the error of each method
per position and over all positions and seeds, against the paper's.

Run as a parameter study through the sweep machinery (nlos_cl.sweep; the study is the package
file nlos_cl/sweep/fig10.yaml with these Settings applied): OUT/fig10_sweep/ keeps the tidy
table of every run, and an interrupted run resumes where it stopped."""
from __future__ import annotations

from importlib import resources
from pathlib import Path

from nlos_cl import plotting

from .common import PAPER, Result, Settings, error_stats, title

METHODS = {"filter": "gauss", "fit": "gauss_fit", "raw": "none"}  # ours -> the study's filter


def fig10_study(s: Settings) -> dict:
    """nlos_cl/sweep/fig10.yaml with reproduce's Settings applied."""
    import yaml

    from nlos_cl.scenefile import yaml_loader
    text = resources.files("nlos_cl.sweep").joinpath("fig10.yaml").read_text("utf-8")
    study = yaml.load(text, Loader=yaml_loader())
    study["scene"]["facet_size_m"] = s.facet_m
    study["scene"]["time_axis"]["dt_s"] = s.dt_s
    study["scene"]["noise"]["snr_db"] = s.snr_db
    study.update(seeds=s.seeds, h_s=s.h_s)
    study["grid"]["step_m"] = s.grid_step_m
    return study


def fig10(s: Settings, out: Path) -> Result:
    from nlos_cl.sweep import sweep
    result = sweep(fig10_study(s), out / "fig10_sweep", progress=False, report=False,
                   resume=True)
    table = result.table().to_pylist()
    rows, errors = [], {m: [] for m in METHODS}
    for x in range(1, 6):
        for y in range(1, 6):
            row = {"x": x, "y": y}
            for m, how in METHODS.items():
                e = [r["error_m"] for r in table if (r["x"], r["y"], r["method"]) == (x, y, how)]
                errors[m].extend(e)
                st = error_stats(e)
                row.update({f"{m}_mean_m": st["mean_m"], f"{m}_max_m": st["max_m"]})
            rows.append(row)
    summary = {m: error_stats(errors[m]) for m in METHODS}
    summary["paper"] = PAPER["fig10"]
    figure = plotting.grid_errors_figure(rows, errors, summary, out, "fig10")
    return Result("fig10", title("fig10"), rows, summary, [figure])
