"""Plots made from a study's table: the error against each axis (mean, 16-84 % band, max), one
line per estimator, and error maps over the true position (or over the first two numeric
axes) when the study varies them."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .study import Study


def plot_all(study: Study, table, out, force: bool = False) -> list[str]:
    """Write OUT/errors_by_axis.png and OUT/error_map.png (where the study has a map; each
    through results.write_output's rule); return their paths."""
    import matplotlib
    matplotlib.use("Agg")
    if "error_m" not in table.column_names:
        return []
    data = _ok_rows(table)
    if not data["error_m"].size:
        return []
    figures = [errors_by_axis(study, data, Path(out) / "errors_by_axis.png", force)]
    pair = _map_axes(study, data)
    if pair:
        figures.append(error_map(data, *pair, Path(out) / "error_map.png", force))
    return [str(f) for f in figures if f]


def _ok_rows(table) -> dict:
    failure = np.asarray(table.column("failure").to_pylist(), dtype=object)
    keep = failure == ""
    return {name: np.asarray(table.column(name).to_pylist(), dtype=object)[keep]
            for name in table.column_names}


def _varied(study: Study):
    return [a for a in study.axes if a.name not in ("seed", "estimator") and len(a.values) > 1]


def _numeric(values) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _label(value) -> str:
    return value if isinstance(value, str) else json.dumps(value)[:24]


def _save(fig, path: Path, force: bool) -> Path:
    """The figure as PNG at `path` (atomically, never over a file no sweep wrote), closed."""
    import matplotlib.pyplot as plt

    from .results import write_output
    try:
        write_output(path.parent, path.name, lambda tmp: fig.savefig(tmp, format="png",
                                                                     dpi=110), force)
    finally:
        plt.close(fig)
    return path


def errors_by_axis(study: Study, data: dict, path: Path, force: bool = False):
    import matplotlib.pyplot as plt
    axes = _varied(study) or [a for a in study.axes if a.name == "estimator"]
    fig, panels = plt.subplots(1, len(axes), figsize=(4.2 * len(axes), 3.4), squeeze=False)
    estimators = list(dict.fromkeys(data["estimator"]))
    for ax, axis in zip(panels[0], axes):
        values = list(dict.fromkeys(data[axis.name]))  # the table's cells, in study order
        x = np.asarray(values, float) if _numeric(axis.values) else np.arange(len(values))
        for est in estimators:
            stats = []
            for v in values:
                e = data["error_m"][(data[axis.name] == v) & (data["estimator"] == est)]
                e = e.astype(float)
                stats.append((e.mean(), *np.percentile(e, [16, 84]), e.max()) if e.size
                             else (np.nan,) * 4)
            mean, low, high, top = np.asarray(stats).T
            line, = ax.plot(x, mean, "o-", label=f"{est} mean")
            ax.fill_between(x, low, high, alpha=0.2, color=line.get_color(),
                            label=f"{est} 16-84 %")
            ax.plot(x, top, ":", color=line.get_color(), label=f"{est} max")
        if not _numeric(axis.values):
            ax.set_xticks(x, [_label(v) for v in values], rotation=30, fontsize=7)
        ax.set_xlabel(axis.name)
        ax.set_ylabel("error (m)")
        ax.set_yscale("log")
        ax.grid(alpha=0.3)
    panels[0][0].legend(fontsize=7)
    fig.suptitle((study.description or "sweep") + f": error per axis (mean, 16-84 %, max; "
                 f"{len(data['error_m'])} runs)", fontsize=9)
    fig.tight_layout()
    return _save(fig, path, force)


def _map_axes(study: Study, data: dict):
    """(x column, y column) for the error map: the true position when it varies in x and y,
    else the first two numeric varied axes; None when there is no map to draw."""
    if "truth_x_m" in data:
        tx, ty = (np.unique(data[c].astype(float)) for c in ("truth_x_m", "truth_y_m"))
        if tx.size > 1 and ty.size > 1:
            return "truth_x_m", "truth_y_m"
    numeric = [a.name for a in _varied(study) if _numeric(a.values)]
    return tuple(numeric[:2]) if len(numeric) >= 2 else None


def error_map(data: dict, xcol: str, ycol: str, path: Path, force: bool = False):
    """Mean error per (x, y) cell over everything else (error_map_figure), saved at `path`."""
    return _save(error_map_figure(data, xcol, ycol), path, force)


def error_map_figure(data: dict, xcol: str, ycol: str):
    """Mean error per (x, y) cell over everything else, one panel per estimator, every panel
    on one colour scale with one colorbar (so that their colours compare; logarithmic, as the
    estimators' errors differ by orders of magnitude)."""
    import matplotlib.pyplot as plt
    estimators = list(dict.fromkeys(data["estimator"]))
    fig, panels = plt.subplots(1, len(estimators), figsize=(4.4 * len(estimators) + 1, 3.8),
                               squeeze=False, layout="constrained")
    x, y = data[xcol].astype(float), data[ycol].astype(float)
    means = {}
    for est in estimators:
        pick = data["estimator"] == est
        cells = sorted(set(zip(x[pick], y[pick])))
        means[est] = (cells, [data["error_m"][pick & (x == cx) & (y == cy)].astype(float).mean()
                              for cx, cy in cells])
    norm = _log_norm(np.concatenate([m for _, m in means.values()]))
    for ax, est in zip(panels[0], estimators):
        cells, mean = means[est]
        cx, cy = np.asarray(cells).T
        art = ax.scatter(cx, cy, c=np.maximum(mean, norm.vmin), s=260, marker="s",
                         cmap="viridis", norm=norm)
        for a, b, m in zip(cx, cy, mean):
            ax.annotate(f"{m * 100:.1f}", (a, b), ha="center", va="center", fontsize=6,
                        color="white" if norm(m) < 0.6 else "black")
        ax.set_title(f"{est}: mean error (cm in cells)", fontsize=9)
        ax.set_xlabel(_axis_label(xcol))
        ax.set_ylabel(_axis_label(ycol))
        ax.set_aspect("equal", adjustable="datalim")
    bar = fig.colorbar(art, ax=list(panels[0]), label="mean error (m), one scale for all")
    ticks = [t for t in (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1, 2, 5)
             if norm.vmin <= t <= norm.vmax]
    bar.set_ticks(ticks, labels=[f"{t:g}" for t in ticks])
    bar.ax.minorticks_off()
    return fig


def _axis_label(column: str) -> str:
    """'truth_x_m' -> 'true x (m)'; a study's own axis name as it is."""
    if column.startswith("truth_") and column.endswith("_m"):
        return f"true {column[6:-2]} (m)"
    return column


def _log_norm(errors):
    """One logarithmic colour scale over every panel's errors (a zero error is drawn at the
    smallest positive one)."""
    from matplotlib.colors import LogNorm
    positive = errors[np.isfinite(errors) & (errors > 0)]
    low, high = (positive.min(), positive.max()) if positive.size else (1e-3, 1.0)
    return LogNorm(float(low), float(max(high, low * 1.01)))
