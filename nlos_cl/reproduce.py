"""`nlos-cl reproduce NAME`: every experiment of the paper as one command, writing its figure,
its table (CSV) and a summary with the paper's numbers beside ours.

Each experiment simulates its scenes once on the device, then for every noise seed runs the
device-resident pipeline (noise -> Gauss filter -> locate), the Gauss-fit baseline (a converged
SciPy fit per histogram, Eq. 25) and the raw signal, and reports mean +- std and max over seeds.
"""
from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from . import pipeline as pl
from .histograms import Grid, default_time_axis
from .scene import Pulse, Scene, Target, paper_setup, rectangle

# The paper's numbers, as printed (Section 3-4, Table 1, Fig. 5, 6, 8, 10).
PAPER = {
    "fig5": {"fwhm_ns": [0.88, 0.82, 0.79]},
    "fig6": {"raw": (3.64, 2.73), "fit": (3.88, 2.38), "filter": (4.04, 2.00)},
    "table1": {40: (4.02, 2.03), 50: (4.04, 1.99), 60: (4.02, 2.04), 70: (4.04, 2.00),
               80: (4.02, 2.08), 90: (4.03, 2.03)},
    "fig8": {"0.2x1.8": (4.02, 2.06), "0.5x1.5": (4.07, 1.93), "0.8x1.2": (4.00, 1.95)},
    "fig10": {"fit": {"mean_m": 0.3106, "std_m": 0.3010},
              "filter": {"mean_m": 0.0684, "std_m": 0.0245, "max_m": 0.12}},
}
METHODS = ("filter", "fit", "raw")
PAPER_POSITION = (4.0, 2.0, 0.0)


@dataclass(frozen=True)
class Settings:
    """How finely and how often: the full setting, or --quick for CI."""

    seeds: int = 3
    facet_m: float = 0.01
    grid_step_m: float = 0.01
    dt_s: float = 1e-12
    snr_db: float = 10.0
    h_s: float = 0.65e-9
    quick: bool = False

    @classmethod
    def make(cls, quick=False, seeds=None) -> "Settings":
        base = cls(seeds=1, facet_m=0.02, grid_step_m=0.02, quick=True) if quick else cls()
        return replace(base, seeds=seeds) if seeds else base

    def grid(self) -> Grid:
        return Grid.from_ranges(x=(0.0, 6.0), y=(0.01, 6.0), step_m=self.grid_step_m)

    def describe(self) -> str:
        return (f"{self.seeds} noise seed(s), AWGN at {self.snr_db:g} dB of each histogram's "
                f"measured power (mean square over the whole record), {self.dt_s * 1e12:g} ps "
                f"bins from the first possible arrival over 18 m of hidden path, facets <= "
                f"{self.facet_m * 100:g} cm, search grid z = 0, x in [0, 6] m, y in (0, 6] m, "
                f"step {self.grid_step_m * 100:g} cm, Gauss filter h = {self.h_s * 1e9:g} ns "
                "unless varied")


@dataclass
class Result:
    name: str
    title: str
    rows: list  # table rows (dicts), written as CSV
    summary: dict  # what --json prints
    figures: list = field(default_factory=list)
    seconds: float = 0.0


def paper_target(position=PAPER_POSITION, width=0.3, height=1.6, s: Settings = Settings(),
                 setup=None) -> Scene:
    """The paper's upright rectangle (perpendicular to the x axis, facing the wall side)."""
    mesh = rectangle(width, height, centre=position, normal=(-1.0, 0.0, 0.0), cell_m=s.facet_m)
    return Scene(setup or paper_setup(), Target(mesh), s.facet_m, truth=position)


def run_trials(scene: Scene, s: Settings, methods=METHODS, h_values=None):
    """Simulate once; per seed: noise, then locate with each method (and each h for 'filter').
    Returns {method or ('filter', h): [Location per seed]}, and the clean signals."""
    grid = s.grid()
    clean = pl.simulate(scene, default_time_axis(scene.setup, s.dt_s))
    h_values = h_values or [s.h_s]
    out = {}
    for seed in range(s.seeds):
        noisy = pl.add_noise(clean, s.snr_db, seed)
        if "filter" in methods:
            for h in h_values:
                key = "filter" if len(h_values) == 1 else ("filter", h)
                out.setdefault(key, []).append(pl.locate(pl.gauss_filter(noisy, h), grid))
        if "fit" in methods:
            out.setdefault("fit", []).append(pl.locate(pl.gauss_fit(noisy)[0], grid))
        if "raw" in methods:
            out.setdefault("raw", []).append(pl.locate(noisy, grid))
    return out, clean


def stats(locations) -> dict:
    errors = np.array([loc.error_m for loc in locations])
    pos = np.mean([loc.position for loc in locations], axis=0)
    return {"mean_m": round(float(errors.mean()), 4), "std_m": round(float(errors.std()), 4),
            "max_m": round(float(errors.max()), 4), "x": round(float(pos[0]), 3),
            "y": round(float(pos[1]), 3)}


def fwhm_ns(t_s, y) -> float:
    """Full width at half maximum of a single-peaked curve, by linear interpolation."""
    i = int(np.argmax(y))
    half = 0.5 * y[i]
    left = np.nonzero(y[:i] < half)[0]
    right = np.nonzero(y[i:] < half)[0]
    if not left.size or not right.size:
        return float("nan")
    a, b = left[-1], i + right[0]
    t_left = np.interp(half, [y[a], y[a + 1]], [t_s[a], t_s[a + 1]])
    t_right = np.interp(half, [y[b], y[b - 1]], [t_s[b], t_s[b - 1]])
    return float((t_right - t_left) * 1e9)


# ----------------------------------------------------------------------------- plotting

def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, out: Path, name: str, figures: list):
    path = out / f"{name}.png"
    fig.savefig(path, dpi=80)
    _plt().close(fig)
    figures.append(path.name)


def _map_panel(ax, location, title, truth):
    grid = location.grid
    x, y, _ = grid.axes()
    m = location.score_map[0]
    peak = m.max()
    ax.imshow(m / peak if peak > 0 else m, origin="lower", cmap="magma", aspect="equal",
              extent=(x[0], x[-1], y[0], y[-1]))
    ax.plot(truth[0], truth[1], "o", mfc="none", mec="red", ms=10, mew=2, label="truth")
    ax.plot(*location.position[:2], "+", color="cyan", ms=12, mew=2, label="located")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def _signals_figure(plt, panels, title):
    """panels: list of (label, t_ns, [(curve, style, legend)])."""
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4), layout="constrained")
    for ax, (label, t_ns, curves) in zip(np.atleast_1d(axes), panels):
        for y, style, legend in curves:
            ax.plot(t_ns, y * 1e15, style, lw=1.0, label=legend)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("arrival time (ns)")
        ax.set_ylabel("power (fW)")
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    return fig


def _window(y, t_ns, frac=0.02):
    idx = np.nonzero(y > frac * y.max())[0]
    pad = max((idx[-1] - idx[0]) // 2, 20)
    return slice(max(idx[0] - pad, 0), min(idx[-1] + pad, len(t_ns)))


# ----------------------------------------------------------------------------- experiments

def fig5(s: Settings, out: Path) -> Result:
    plt = _plt()
    clean = pl.simulate(paper_target(s=s), default_time_axis(paper_setup(), s.dt_s))
    noisy = pl.add_noise(clean, s.snr_db, 0)
    filtered = pl.gauss_filter(noisy, 0.8e-9).histograms()
    fitted, fit = pl.gauss_fit(noisy)
    c, n, fh = clean.histograms(), noisy.histograms(), fitted.histograms()
    t = c.time_axis.centres()
    rows, panels = [], []
    for d, name in enumerate("ABC"):
        row = {"detector": name, "fwhm_clean_ns": round(fwhm_ns(t, c.data[d]), 3),
               "fwhm_filtered_ns": round(fwhm_ns(t, filtered.data[d]), 3),
               "fwhm_fit_ns": round(fwhm_ns(t, fh.data[d]), 3),
               "fit_converged": bool(fit.converged[d]), "paper_fwhm_ns": PAPER["fig5"]["fwhm_ns"][d]}
        rows.append(row)
        sl = _window(c.data[d], t)
        panels.append((f"detector {name}: FWHM {row['fwhm_clean_ns']} ns (paper "
                       f"{row['paper_fwhm_ns']})", t[sl] * 1e9,
                       [(n.data[d, sl], "-", "raw + noise"), (filtered.data[d, sl], "--",
                                                              "Gauss filter h = 0.8 ns"),
                        (fh.data[d, sl], ":", "Gauss fit")]))
    figures = []
    _save(_signals_figure(plt, panels, "Fig. 5: signals at detectors A, B, C (10 dB)"), out,
          "fig5", figures)
    return Result("fig5", "Fig. 5: signal FWHM at A, B, C", rows,
                  {"fwhm_ns": [r["fwhm_clean_ns"] for r in rows],
                   "paper_fwhm_ns": PAPER["fig5"]["fwhm_ns"]}, figures)


def fig6(s: Settings, out: Path) -> Result:
    plt = _plt()
    scene = paper_target(s=s)
    trials, clean = run_trials(scene, s)
    grid = s.grid()
    noisy = pl.add_noise(clean, s.snr_db, 0)
    sources = {"raw": noisy, "fit": pl.gauss_fit(noisy)[0],
               "filter": pl.gauss_filter(noisy, s.h_s)}
    fig, axes = plt.subplots(2, 3, figsize=(12, 8), layout="constrained")
    for col, method in enumerate(("raw", "fit", "filter")):
        hist = sources[method].histograms()
        single = pl.locate(hist.select([0]), grid, return_map=True)
        joint = pl.locate(hist, grid, return_map=True)
        _map_panel(axes[0, col], single, f"p_A from the {method} signal", scene.truth)
        _map_panel(axes[1, col], joint, f"joint, {method}: located "
                   f"({joint.position[0]:.2f}, {joint.position[1]:.2f})", scene.truth)
    axes[0, 0].legend(fontsize=7)
    figures = []
    _save(fig, out, "fig6", figures)
    rows = [{"method": m, **stats(trials[m]), "paper_x": PAPER["fig6"][m][0],
             "paper_y": PAPER["fig6"][m][1]} for m in METHODS]
    return Result("fig6", "Fig. 6: located position with raw, fitted and filtered signals", rows,
                  {r["method"]: {k: r[k] for k in ("x", "y", "mean_m", "std_m", "max_m")}
                   for r in rows}, figures)


def _sweep_figure(rows, key, xlabel, title, out, name, methods=("filter", "fit")):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 3.8), layout="constrained")
    x = [r[key] for r in rows]
    for m in methods:
        if f"{m}_mean_m" in rows[0]:
            ax.errorbar(x, [r[f"{m}_mean_m"] for r in rows], yerr=[r[f"{m}_std_m"] for r in rows],
                        marker="o", capsize=3, label=f"Gauss {m}")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("position error (m)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend()
    figures = []
    _save(fig, out, name, figures)
    return figures


def _flat(method, st):
    return {f"{method}_{k}": v for k, v in st.items()}


def fig7a(s: Settings, out: Path) -> Result:
    deltas = [0.2, 0.6, 1.0] if s.quick else [round(0.1 * k, 1) for k in range(1, 11)]
    rows = []
    for delta in tqdm(deltas, desc="fig7a: detector spacing", leave=False):
        setup = paper_setup(detector_spots=[[-k * delta, 0.0, 0.0] for k in (1, 2, 3)])
        trials, _ = run_trials(paper_target(s=s, setup=setup), s, methods=("filter", "fit"))
        rows.append({"delta_m": delta, **_flat("filter", stats(trials["filter"])),
                     **_flat("fit", stats(trials["fit"]))})
    figures = _sweep_figure(rows, "delta_m", "detector spacing delta (m)",
                            "Fig. 7(a): error against detector spacing", out, "fig7a")
    return Result("fig7a", "Fig. 7(a): error against detector spacing (detectors at x = -k delta)",
                  rows, {"rows": rows}, figures)


def fig7b(s: Settings, out: Path) -> Result:
    hs = [0.1, 0.65, 1.5] if s.quick else [round(0.1 * k, 2) for k in range(1, 16)] + [0.65]
    hs = sorted(set(hs))
    trials, _ = run_trials(paper_target(s=s), s, methods=("filter",),
                           h_values=[h * 1e-9 for h in hs])
    rows = [{"h_ns": h, **_flat("filter", stats(trials[("filter", h * 1e-9)]))} for h in hs]
    figures = _sweep_figure(rows, "h_ns", "filter window h (ns)",
                            "Fig. 7(b): error against filter window", out, "fig7b", ("filter",))
    return Result("fig7b", "Fig. 7(b): error against the filter window h", rows, {"rows": rows},
                  figures)


def table1(s: Settings, out: Path) -> Result:
    rows = []
    for fwhm in tqdm((40, 50, 60, 70, 80, 90), desc="table1: laser FWHM", leave=False):
        setup = paper_setup(pulse=Pulse.from_laser(fwhm_s=fwhm * 1e-12))
        trials, _ = run_trials(paper_target(s=s, setup=setup), s, methods=("filter",))
        st = stats(trials["filter"])
        px, py = PAPER["table1"][fwhm]
        rows.append({"fwhm_ps": fwhm, "x": st["x"], "y": st["y"], "error_mean_m": st["mean_m"],
                     "paper_x": px, "paper_y": py,
                     "distance_to_paper_m": round(math.hypot(st["x"] - px, st["y"] - py), 3)})
    return Result("table1", "Table 1: located position against laser FWHM (filter)", rows,
                  {"rows": rows})


def fig8(s: Settings, out: Path) -> Result:
    plt = _plt()
    rows, panels = [], []
    for w, h in ((0.2, 1.8), (0.5, 1.5), (0.8, 1.2)):
        label = f"{w}x{h}"
        trials, clean = run_trials(paper_target(width=w, height=h, s=s), s,
                                   methods=("filter", "fit"))
        st = stats(trials["filter"])
        px, py = PAPER["fig8"][label]
        rows.append({"target_m": label, "x": st["x"], "y": st["y"], "error_mean_m": st["mean_m"],
                     "fit_error_mean_m": stats(trials["fit"])["mean_m"], "paper_x": px,
                     "paper_y": py,
                     "distance_to_paper_m": round(math.hypot(st["x"] - px, st["y"] - py), 3)})
        c = clean.histograms()
        t = c.time_axis.centres()
        sl = _window(c.data[0], t)
        panels.append((f"{w} m x {h} m: located ({st['x']:.2f}, {st['y']:.2f}), paper "
                       f"({px}, {py})", t[sl] * 1e9,
                       [(c.data[d, sl], "-", f"detector {n}") for d, n in enumerate("ABC")]))
    figures = []
    _save(_signals_figure(plt, panels, "Fig. 8: signals of three rectangles at (4, 2)"), out,
          "fig8", figures)
    return Result("fig8", "Fig. 8: rectangles of different shapes at (4, 2)", rows,
                  {"rows": rows}, figures)


def fig9(s: Settings, out: Path) -> Result:
    sides = [0.2, 0.8, 1.6] if s.quick else [0.1, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.6, 2.0]
    rows = []
    for side in tqdm(sides, desc="fig9: square side", leave=False):
        trials, _ = run_trials(paper_target(width=side, height=side, s=s), s,
                               methods=("filter", "fit"))
        rows.append({"side_m": side, **_flat("filter", stats(trials["filter"])),
                     **_flat("fit", stats(trials["fit"]))})
    figures = _sweep_figure(rows, "side_m", "side of the square target (m)",
                            "Fig. 9: error against target size", out, "fig9")
    return Result("fig9", "Fig. 9: error against the side of a square target", rows,
                  {"rows": rows}, figures)


def fig10(s: Settings, out: Path) -> Result:
    plt = _plt()
    coords = [(x, y) for x in range(1, 6) for y in range(1, 6)]
    rows = []
    per_method = {m: [] for m in METHODS}
    for x, y in tqdm(coords, desc="fig10: 5 x 5 positions", leave=False):
        trials, _ = run_trials(paper_target((float(x), float(y), 0.0), s=s), s)
        row = {"x": x, "y": y}
        for m in METHODS:
            st = stats(trials[m])
            per_method[m].extend(loc.error_m for loc in trials[m])
            row.update({f"{m}_mean_m": st["mean_m"], f"{m}_max_m": st["max_m"]})
        rows.append(row)
    summary = {}
    for m in METHODS:
        e = np.array(per_method[m])
        summary[m] = {"mean_m": round(float(e.mean()), 4), "std_m": round(float(e.std()), 4),
                      "max_m": round(float(e.max()), 4)}
    summary["paper"] = PAPER["fig10"]
    fig, axes = plt.subplots(2, 3, figsize=(12, 7), layout="constrained")
    for col, m in enumerate(METHODS):
        emap = np.array([[r[f"{m}_mean_m"] for r in rows if r["y"] == y] for y in range(1, 6)])
        im = axes[0, col].imshow(emap, origin="lower", extent=(0.5, 5.5, 0.5, 5.5), cmap="viridis")
        axes[0, col].set_title(f"{m}: error per position (m)", fontsize=9)
        axes[0, col].set_xlabel("x (m)")
        axes[0, col].set_ylabel("y (m)")
        fig.colorbar(im, ax=axes[0, col], label="error (m)")
        axes[1, col].hist(per_method[m], bins=20, color="C0")
        axes[1, col].set_title(f"{m}: mean {summary[m]['mean_m']:.4f} m, std "
                               f"{summary[m]['std_m']:.4f} m", fontsize=9)
        axes[1, col].set_xlabel("error (m)")
        axes[1, col].set_ylabel("count")
    figures = []
    _save(fig, out, "fig10", figures)
    return Result("fig10", "Fig. 10: the target at every point of a 5 x 5 grid", rows, summary,
                  figures)


EXPERIMENTS = {"fig5": fig5, "fig6": fig6, "fig7a": fig7a, "fig7b": fig7b, "table1": table1,
               "fig8": fig8, "fig9": fig9, "fig10": fig10}


def run(name: str, s: Settings, out: Path) -> list[Result]:
    out.mkdir(parents=True, exist_ok=True)
    names = list(EXPERIMENTS) if name == "all" else [name]
    results = []
    for n in tqdm(names, desc="reproduce", disable=len(names) == 1):
        start = time.perf_counter()
        result = EXPERIMENTS[n](s, out)
        result.seconds = time.perf_counter() - start
        with open(out / f"{n}.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(result.rows[0]))
            writer.writeheader()
            writer.writerows(result.rows)
        results.append(result)
    return results


def summary_json(results) -> str:
    if len(results) == 1:
        return json.dumps(results[0].summary)
    return json.dumps({r.name: r.summary for r in results})


def _pm(st, prefix=""):
    return f"{st[prefix + 'mean_m']:.4f} ± {st[prefix + 'std_m']:.4f} (max {st[prefix + 'max_m']:.4f})"


def _table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def _section(r: Result) -> str:
    """The markdown table of one experiment: the paper's numbers beside ours."""
    rows = r.rows
    if r.name == "fig5":
        return _table(["detector", "paper FWHM (ns)", "ours: clean signal", "ours: filtered h=0.8 ns",
                       "ours: Gauss fit"],
                      [(x["detector"], x["paper_fwhm_ns"], x["fwhm_clean_ns"], x["fwhm_filtered_ns"],
                        x["fwhm_fit_ns"]) for x in rows])
    if r.name == "fig6":
        return _table(["signal", "paper (x, y)", "ours (x, y), mean over seeds",
                       "ours: error mean ± std (max), m"],
                      [(x["method"], f"({x['paper_x']}, {x['paper_y']})",
                        f"({x['x']:.3f}, {x['y']:.3f})", _pm(x)) for x in rows])
    if r.name in ("fig7a", "fig9"):
        key, label = ("delta_m", "detector spacing (m)") if r.name == "fig7a" else \
            ("side_m", "square side (m)")
        return _table([label, "filter: error mean ± std (max), m", "fit: error mean ± std (max), m"],
                      [(x[key], _pm(x, "filter_"), _pm(x, "fit_")) for x in rows])
    if r.name == "fig7b":
        return _table(["h (ns)", "filter: error mean ± std (max), m", "located (x, y)"],
                      [(x["h_ns"], _pm(x, "filter_"), f"({x['filter_x']:.3f}, {x['filter_y']:.3f})")
                       for x in rows])
    if r.name in ("table1", "fig8"):
        key = "fwhm_ps" if r.name == "table1" else "target_m"
        label = "laser FWHM (ps)" if r.name == "table1" else "rectangle (m)"
        extra = [] if r.name == "table1" else ["ours: fit error (m)"]
        return _table([label, "paper (x, y)", "ours: filter (x, y)", "ours: filter error (m)",
                       "ours vs paper (m)"] + extra,
                      [(x[key], f"({x['paper_x']}, {x['paper_y']})", f"({x['x']:.3f}, {x['y']:.3f})",
                        x["error_mean_m"], x["distance_to_paper_m"])
                       + ((x["fit_error_mean_m"],) if r.name == "fig8" else ()) for x in rows])
    if r.name == "fig10":
        paper = r.summary["paper"]
        fmt = lambda d: (f"{d['mean_m']:.4f} ± {d['std_m']:.4f}"  # noqa: E731
                         + (f" (max {d['max_m']:.4f})" if "max_m" in d else ""))
        return _table(["signal", "paper: error mean ± std (max), m", "ours: error mean ± std (max), m"],
                      [(m, fmt(paper[m]) if m in paper else "-", fmt(r.summary[m])) for m in METHODS])
    return ""


def write_report(results, s: Settings, path: Path, out: Path, wall_s: float) -> None:
    """docs/paper-results.md: every experiment's numbers from this run, the paper's beside
    them, the settings, and the remarks (REMARKS) on where and why they differ."""
    from .runtime import get_runtime
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        figure_dir = out.resolve().relative_to(path.parent.resolve())
    except ValueError:
        figure_dir = out.resolve()
    parts = ["# The paper's numbers and ours", "",
             f"Generated by `nlos-cl reproduce all --out {out} --doc {path}` (do not edit by hand) "
             f"on {get_runtime().name}; wall time {wall_s:.0f} s.", "",
             f"Settings: {s.describe()}. The target is the paper's upright rectangle "
             "(perpendicular to the x axis, facing the wall side) unless an experiment varies it; "
             "'fit' is a converged least-squares Gaussian per whole histogram (SciPy, Eq. 25); "
             "'raw' scores the noisy signal itself. Errors are distances to the rectangle's centre "
             "in the plane z = 0.", "", GENERAL_REMARK, ""]
    for r in results:
        parts += [f"## {r.title}", "", _section(r), "", REMARKS.get(r.name, ""), ""]
        parts += [f"![{r.name}]({figure_dir / png})" for png in r.figures]
        parts.append("")
    path.write_text("\n".join(parts))


GENERAL_REMARK = """**Reading this page.** Nothing here is tuned to match the paper: the model, the filter and the
fit run exactly as documented, and the numbers below come from this run. Two choices shape all
of them. (1) *Noise*: the paper's "10 dB" is read as white Gaussian noise 10 dB below each
histogram's measured power (mean square over the whole 60 ns record, as MATLAB's `awgn(x, 10,
'measured')`). Averaged by a 0.65 ns filter over 1 ps bins it barely moves the result, so the
spread over seeds is often below a millimetre; a stronger or coloured noise would separate the
methods more. (2) *The Gauss fit is a genuine converged least-squares fit* of one Gaussian to
each whole histogram. On our simulated data (one pulse, zero-mean noise, no background) it is
accurate, and on the 5 x 5 grid it beats both the paper's fit row and our own filter. The
paper's fit suffers from the unstable background and noise of its data, which our simulation
does not contain; for a target whose signal is a broad plateau (wide targets, below) the fit is
in fact the more robust estimator here."""

REMARKS: dict = {
    "fig5": "Our pulse widths agree with the paper's to within 0.03 ns, with the same ordering "
            "(A widest). The remaining difference is plausibly the detected spot: we treat each "
            "detector spot as a point, the paper does not say how it integrates over the 0.1 m "
            "spot.",
    "fig6": "The filtered signal lands where the paper's does (within 2 cm of (4.04, 2.00)). The "
            "raw signal is worse than filtered, as in the paper, but not by as much on average: "
            "its error depends on where noise spikes fall on the long likelihood ridge (see the "
            "map), so the paper's single raw estimate (3.64, 2.73) is one draw of a wide "
            "distribution. Our fit is as good as the filter here (see the remark at the top).",
    "fig7a": "Detectors at x = -delta, -2 delta, -3 delta (delta = 0.5 m is the paper's default "
             "layout). As in the paper, small spacings make the three ellipses nearly coincide "
             "and the error grows; the error is flat from 0.5 to 0.8 m, consistent with the "
             "paper's choice of 0.6 m. Beyond 0.8 m it rises again for the filter (detector C "
             "moves far from the target's bright side).",
    "fig7b": "As in the paper, a window h below about 0.6 ns leaves the plateau's ripple in the "
             "signal and the estimate jumps along the likelihood ridge; from 0.65 ns on (the "
             "paper's choice) the result is stable.",
    "table1": "The laser FWHM does not change the located position (as the paper finds): every "
              "row lands within 0.07 m of the paper's and within 3 cm of the truth.",
    "fig8": "The first two shapes reproduce the paper's positions within 0.05 m. **The 0.8 m x "
            "1.2 m rectangle does not**: the filter puts it about 1.4 m away along the "
            "likelihood arc. Its signals are broad plateaus (0.6 m of path), so each detector's "
            "map is a wide annulus that is nearly flat across; with the paper's detectors all "
            "on one line through O, the three annuli overlap along a long stretch of arc and the "
            "argmax of the flat product slides along it, pulled towards the early (brighter, "
            "nearer) edge of each plateau. The fitted Gaussians peak at the plateaus' centres "
            "and locate it within 0.05 m. We report the argmax as the paper defines it; a "
            "non-collinear detector layout, or an estimator that uses the plateau's centre, "
            "would fix this. The paper's (4.00, 1.95) for this shape is not reproduced.",
    "fig9": "The paper reports that accuracy declines with target size; ours declines much more "
            "steeply for the filter: beyond a 0.4 m side the argmax slides along the arc for the "
            "reason given under Fig. 8 (flat-topped signals, collinear detectors), while the "
            "fit stays within 0.1 m up to 1.2 m. The paper's figure gives no numbers to compare.",
    "fig10": "The filter row matches the paper's (mean 0.065 m against 0.068 m; our worst "
             "position is 0.15 m against the paper's 0.12 m, at the grid's near-wall, large-x "
             "corner where the ellipses meet at the shallowest angles). Our genuine fit is much "
             "better than the paper's fit row (0.035 m against 0.31 m); see the remark at the "
             "top. The raw signal is the worst, as in the paper.",
}
