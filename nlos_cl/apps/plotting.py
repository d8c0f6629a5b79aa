"""The figures of nlos_cl: `locate --map`'s, the paper's experiments (signals, probability
maps, sweeps, the 5 x 5 grid), `reproduce beyond`'s and the benchmark's performance figure
(the demo's: demo_figure, drawn with this module's helpers).

matplotlib is imported inside the functions (Agg backend), so importing this module costs
nothing; nothing in the library imports it at import time."""
from __future__ import annotations

from pathlib import Path

import numpy as np

DETECTOR_NAMES = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save(fig, out: Path, name: str, dpi: int = 80) -> str:
    """Write `out/name.png`, close the figure, return the file's name."""
    path = out / f"{name}.png"
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
    return path.name


def signal_window(y, t, frac=0.02) -> slice:
    """The bins where y exceeds `frac` of its peak, padded by half that span (>= 20 bins)."""
    idx = np.nonzero(y > frac * y.max())[0]
    pad = max((idx[-1] - idx[0]) // 2, 20)
    return slice(max(idx[0] - pad, 0), min(idx[-1] + pad, len(t)))


def _ellipse(ax, centre, cov, **style):
    """The 2-sigma ellipse of a 2 x 2 covariance (none where a variance is not finite)."""
    from matplotlib.patches import Ellipse
    if cov is None or not np.all(np.isfinite(cov)):
        return
    values, vectors = np.linalg.eigh(cov)
    angle = np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1]))
    ax.add_patch(Ellipse(centre, *(4 * np.sqrt(np.maximum(values[::-1], 0))), angle=angle,
                         fill=False, **style))


def _extent(panel):
    """imshow's extent of a plan map: the cells' edges, half a step beyond the centres."""
    lat, dep = panel["lateral"], panel["depth"]
    half = [(a[1] - a[0]) / 2 if a.size > 1 else 0.005 for a in (lat, dep)]
    return (lat[0] - half[0], lat[-1] + half[0], dep[0] - half[1], dep[-1] + half[1])


def _map_markers(ax, view, first: bool):
    """The wall, spots, truths and each estimate with its 2-sd ellipse (the file's axes); in
    the final grid's panel (not `first`) smaller marks, so that a cm-sized ellipse shows."""
    def label(text):
        return text if first else None
    from matplotlib import patheffects
    size, (lat, dep, _) = 1.0 if first else 0.6, view["labels"]
    edge = [patheffects.withStroke(linewidth=2.5, foreground="black")]  # legible on the peak
    ax.axhline(0.0, color="0.3", lw=3, label=label("relay wall"))
    ax.plot(*view["spots"].T, "^", color="C0", ms=6, label=label("detector spots"))
    ax.plot(*view["lasers"].T, "*", color="gold", mec="k", ms=11, label=label("laser spot"))
    if len(view["truths"]):
        ax.plot(*view["truths"].T, "x", color="lime", ms=9 * size, mew=2, label=label("truth"))
    for k, (centre, cov) in enumerate(view["targets"]):
        ax.plot(*centre, "+", color="cyan", ms=14 * size, mew=2,
                label=label("estimate") if k == 0 else None)
        sd = None if cov is None else np.sqrt(np.diag(cov))
        told = "" if first or sd is None or not np.all(np.isfinite(sd)) else \
            f": sd {lat} {sd[0] * 100:.2g} cm, {dep} {sd[1] * 100:.2g} cm"  # a tiny ellipse
        ax.annotate(f"{k + 1}{told}", centre, xytext=(6, 6), textcoords="offset points",
                    color="cyan", fontsize=9, fontweight="bold", path_effects=edge)
        _ellipse(ax, centre, cov, color="cyan", lw=1.5, label=label("2 sd") if k == 0 else None)


def map_figure(fh, view):
    """`nlos-cl locate --map F.png`: the score maps seen from above (locate_map.map_view), the
    whole search region's with the final grid's over it (outlined) and, beside it, the final
    grid alone, with the wall, the spots, the truths and each target with its 2-sigma ellipse,
    in the file's axes; one colour scale for every map."""
    from matplotlib.patches import Rectangle
    plt = pyplot()
    panels = view["panels"]
    fig, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels) + 1, 6),
                             layout="constrained", squeeze=False)
    style = {"origin": "lower", "cmap": "magma", "aspect": "equal", "vmin": -30.0, "vmax": 0.0}
    for i, (ax, panel) in enumerate(zip(axes[0], panels)):
        image = ax.imshow(panel["image"], extent=_extent(panel), **style)
        inset = panel.get("inset")
        if inset is not None:  # the final grid's finer map over the region's, outlined
            box = _extent(inset)
            ax.imshow(inset["image"], extent=box, **style)
            ax.add_patch(Rectangle((box[0], box[2]), box[1] - box[0], box[3] - box[2],
                                   fill=False, ec="white", lw=1, ls="--"))
        _map_markers(ax, view, first=i == 0)
        ax.set_xlabel(f"{view['labels'][0]} (m)")
        ax.set_ylabel(f"{view['labels'][1]} (m): depth from the wall")
        ax.set_title(panel["title"], fontsize=9)
        if i == 0:
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3)
            ax.autoscale()
        else:  # the final grid alone: the markers outside it are clipped
            box = _extent(panel)
            ax.set_xlim(box[0], box[1])
            ax.set_ylim(box[2], box[3])
    fig.colorbar(image, ax=list(axes[0]), shrink=0.8,
                 label=f"log-likelihood relative to the peak ({view['relative']})")
    fig.suptitle(view["title"], fontsize=10)
    fig.savefig(fh, dpi=90)
    plt.close(fig)


# ----------------------------------------------------------------------------- the paper

def map_panel(ax, location, title, truth, located: bool = True):
    """One probability map (normalised to its peak) with the truth and, where `located`, the
    located point."""
    x, y, _ = location.grid.axes()
    m = location.score_map[0]
    peak = m.max()
    ax.imshow(m / peak if peak > 0 else m, origin="lower", cmap="magma", aspect="equal",
              extent=(x[0], x[-1], y[0], y[-1]))
    ax.plot(truth[0], truth[1], "o", mfc="none", mec="red", ms=10, mew=2, label="truth")
    if located:
        ax.plot(*location.position[:2], "+", color="cyan", ms=12, mew=2, label="located")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def signals_figure(panels, title, out: Path, name: str) -> str:
    """panels: list of (label, t_ns, [(curve in W, style, legend)]); one panel per column."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4), layout="constrained")
    for ax, (label, t_ns, curves) in zip(np.atleast_1d(axes), panels):
        for y, style, legend in curves:
            ax.plot(t_ns, y * 1e15, style, lw=1.0, label=legend)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("arrival time (ns)")
        ax.set_ylabel("power (fW)")
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    return save(fig, out, name)


def maps_figure(maps, truth, out: Path, name: str) -> str:
    """maps: {method: (single-detector Location, joint Location)}, one column per method."""
    plt = pyplot()
    fig, axes = plt.subplots(2, len(maps), figsize=(4 * len(maps), 8), layout="constrained")
    for col, (method, (single, joint)) in enumerate(maps.items()):
        # one detector's map is a ridge along its ellipse: its peak locates nothing
        map_panel(axes[0, col], single, f"p_A from the {method} signal", truth, located=False)
        map_panel(axes[1, col], joint, f"joint, {method}: located "
                  f"({joint.position[0]:.2f}, {joint.position[1]:.2f})", truth)
    axes[0, 0].legend(fontsize=7)
    axes[1, 0].legend(fontsize=7)
    return save(fig, out, name)


def sweep_figure(rows, key, xlabel, title, out: Path, name: str,
                 methods=("filter", "fit")) -> str:
    """Error (mean +- std over seeds) against the swept quantity `key`, one curve per method."""
    plt = pyplot()
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
    return save(fig, out, name)


def grid_errors_figure(rows, errors, summary, out: Path, name: str) -> str:
    """The 5 x 5 grid (grid_errors_axes), saved as out/name.png."""
    return save(grid_errors_axes(rows, errors, summary), out, name)


def grid_errors_axes(rows, errors, summary):
    """The 5 x 5 grid: per method, the mean error per position (top; one logarithmic colour
    scale and one colorbar for every method, so that the panels compare; each cell's error
    written in cm) and the histogram of every error (bottom). rows: dicts with x, y,
    <method>_mean_m; errors: {method: [m]}. Returns the figure."""
    from matplotlib.colors import LogNorm
    plt = pyplot()
    fig, axes = plt.subplots(2, len(errors), figsize=(4 * len(errors) + 1, 7), layout="constrained",
                             squeeze=False)
    ys = sorted({r["y"] for r in rows})
    maps = {m: np.array([[r[f"{m}_mean_m"] for r in rows if r["y"] == y] for y in ys], float)
            for m in errors}
    finite = np.concatenate([e[np.isfinite(e) & (e > 0)] for e in maps.values()])
    norm = LogNorm(*(finite.min(), finite.max()) if finite.size else (1e-3, 1.0))
    for col, m in enumerate(errors):
        ax = axes[0, col]
        im = ax.imshow(maps[m], origin="lower", extent=(0.5, 5.5, 0.5, 5.5), cmap="viridis",
                       norm=norm)
        for (i, j), e in np.ndenumerate(maps[m]):
            ax.text(j + 1, i + 1, f"{e * 100:.1f}", ha="center", va="center", fontsize=7,
                    color="white" if norm(e) < 0.6 else "black")
        ax.set_title(f"{m}: mean error per position (cm)", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        axes[1, col].hist(errors[m], bins=20, color="C0")
        axes[1, col].set_title(f"{m}: mean {summary[m]['mean_m']:.4f} m, std "
                               f"{summary[m]['std_m']:.4f} m", fontsize=9)
        axes[1, col].set_xlabel("error (m)")
        axes[1, col].set_ylabel("count")
    bar = fig.colorbar(im, ax=list(axes[0]), label="mean error (m), one scale for all")
    ticks = [t for t in (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1, 2) if norm.vmin <= t <= norm.vmax]
    bar.set_ticks(ticks, labels=[f"{t:g}" for t in ticks])
    bar.ax.minorticks_off()
    return fig


# ----------------------------------------------------------------------------- the benchmark

PERFORMANCE_PANELS = (("forward", "facets x detectors x bins"), ("gauss_filter", "bins x taps"),
                      ("ellipse_score", "cells x detectors"))


def performance_figure(rows, path):
    """Kernel and NumPy-twin time against work, log-log, one panel per case.
    rows: objects with attributes case, work, kernel_s, twin_s."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2), layout="constrained")
    for ax, (case, xlabel) in zip(axes, PERFORMANCE_PANELS):
        case_rows = sorted((r for r in rows if r.case == case), key=lambda r: r.work)
        x = [r.work for r in case_rows]
        ax.loglog(x, [r.kernel_s for r in case_rows], "o-", label="OpenCL kernel")
        ax.loglog(x, [r.twin_s for r in case_rows], "s--", label="NumPy twin")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("time (s)")
        ax.set_title(case)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# ----------------------------------------------------------------------------- beyond the paper

def _beyond_bars(ax, rows):
    """Mean error of both estimators per case (bars), max as a dot; log scale."""
    y = np.arange(len(rows))
    for off, key, colour, label in ((-0.2, "paper", "0.55", "paper (argmax)"),
                                    (0.2, "model", "C3", "model fit")):
        mean = np.array([r[f"{key}_mean_m"] for r in rows], float)
        worst = np.array([r[f"{key}_max_m"] for r in rows], float)
        ax.barh(y + off, np.maximum(mean, 1e-4), height=0.4, color=colour, label=label + " mean")
        ax.plot(np.maximum(worst, 1e-4), y + off, "k.", ms=3)
    ax.set_yticks(y, [f"{r['section']}: {r['case'][:48]} [{r['measure']}]" for r in rows],
                  fontsize=6)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlabel("error (m); dot = max over frames")
    ax.axvline(0.1, color="C0", lw=0.8, ls="--")
    ax.legend(loc="lower right", fontsize=7)


def beyond_figure(summary, out: Path, name: str) -> str:
    """`reproduce beyond`: every case's mean/max error for both estimators, and the photon
    curve (error against signal photons per detector) where the run has one."""
    plt = pyplot()
    photons = [r for r in summary if r["section"] == "photons"]
    fig, axes = plt.subplots(1, 2 if photons else 1, figsize=(13, 2 + 0.22 * len(summary)),
                             gridspec_kw={"width_ratios": [3, 1]} if photons else None,
                             squeeze=False)
    _beyond_bars(axes[0, 0], summary)
    if photons:
        ax = axes[0, 1]
        n = [float(r["value"]) for r in photons]
        for key, style in (("paper", "o--"), ("model", "s-")):
            ax.plot(n, [r[f"{key}_mean_m"] for r in photons], style, label=f"{key} mean")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("signal photons per detector")
        ax.set_ylabel("error (m)")
        ax.set_title("photon counts", fontsize=9)
        ax.legend(fontsize=7)
    fig.suptitle("paper's argmax vs model-based estimator (this run)")
    fig.tight_layout()
    return save(fig, out, name)


def write_figure(path, draw, *, what: str, force: bool = False, keep_unless=None):
    """The figure `draw(fh)` saves (a plotting function given an open binary file) written to
    `path` through nlos_cl.io.safe_write.atomic_write: whole or not at all, never over a file
    nlos_cl did not write unless force, never through a link or onto a device. matplotlib takes
    a file object's format from savefig.format, so that is set from the suffix (.png, .pdf)."""
    from pathlib import Path

    import matplotlib

    from ..io.safe_write import atomic_write
    fmt = Path(path).suffix.lstrip(".").lower() or "png"

    def write(tmp):
        with matplotlib.rc_context({"savefig.format": fmt}), open(tmp, "wb") as fh:
            draw(fh)
    return atomic_write(path, write, keep_unless=keep_unless, force=force, what=what,
                        kind="a figure")
