"""`nlos-cl demo --png`: each detector's raw and filtered signal, and the scene seen from above:
the paper's joint likelihood, the relay wall, every detector spot, the laser spot, the truth,
the answer `nl.locate` gives by default (the demo's --estimator) with its 2-sd ellipse, and the
likelihood's peak (the paper's argmax) where that is not the answer."""
from __future__ import annotations

import numpy as np

from ..core.constants import TINY
from .plotting import DETECTOR_NAMES, _ellipse, pyplot


def _signal_panel(ax, raw, filtered, path, d):
    support = np.nonzero(np.abs(filtered.data[d]) > 0.02 * np.abs(filtered.data[d]).max())[0]
    lo, hi = (support[0], support[-1]) if support.size else (0, raw.data.shape[1] - 1)
    pad = max((hi - lo) // 2, 10)
    sl = slice(max(lo - pad, 0), min(hi + pad, raw.data.shape[1]))
    ax.plot(path[d, sl], raw.data[d, sl] * 1e15, lw=0.6, color="0.6", label="raw + noise")
    ax.plot(path[d, sl], filtered.data[d, sl] * 1e15, lw=1.5, color="C3", label="Gauss filtered")
    ax.set_xlabel("hidden path r1 + r2 (m)")
    ax.set_ylabel("power (fW)")
    ax.set_title(f"detector {DETECTOR_NAMES[d % 26]} at x = {raw.detector_spots[d, 0]:.2f} m")
    ax.legend(loc="upper right", fontsize=8)


def _answer_label(answer) -> str:
    how = {"model": "model fit", "paper": "paper's argmax"}.get(answer.estimator,
                                                               answer.estimator)
    return f"answer ({how}, the default)" if answer.estimator == "model" else f"answer ({how})"


def _scene(ax, raw, location, answer):
    """Wall, spots, truth, the answer with its 2-sd ellipse and the map's peak, in the plane."""
    ax.axhline(0.0, color="0.75", lw=3, label="relay wall (y = 0)")
    ax.plot(*raw.detector_spots[:, :2].T, "^", color="C0", mec="w", ms=9, label="detector spots")
    ax.plot(*np.unique(raw.laser_spots[:, :2], axis=0).T, "*", color="gold", mec="k", ms=13, label="laser spot")
    if location.truth is not None:
        ax.plot(*location.truth[:2], "o", mfc="none", mec="cyan", ms=12, mew=2, label="truth")
    if answer.estimator != location.estimator:
        ax.plot(*location.position[:2], "x", color="0.85", ms=8, mew=1.5,
                label="map's peak (paper's argmax)")
    ax.plot(*answer.position[:2], "+", color="lime", ms=14, mew=2.5, label=_answer_label(answer))
    cov = answer.targets[0].covariance
    _ellipse(ax, answer.position[:2], None if cov is None else np.asarray(cov)[:2, :2],
             color="lime", lw=1.5, label="answer's 2-sd ellipse")


def _map_panel(ax, location, score, limits):
    grid = location.grid
    x, y, _ = grid.axes()
    image = ax.imshow(score, origin="lower", aspect="equal", cmap="magma",
                      extent=(x[0] - grid.step[0] / 2, x[-1] + grid.step[0] / 2,
                              y[0] - grid.step[1] / 2, y[-1] + grid.step[1] / 2))
    ax.set_facecolor("black")  # the likelihood is 0 off the searched grid as well
    ax.set_xlim(*limits[:2])
    ax.set_ylim(*limits[2:])
    ax.set_xlabel("x (m), along the wall")
    ax.set_ylabel("y (m), distance from the wall")
    return image


def _zoom(centre, location, answer) -> float:
    """Half the zoomed view's side (m): room for the answer, the map's peak and the answer's
    2-sd ellipse around `centre` (at least 3 cm)."""
    points = np.array([answer.position[:2], location.position[:2]]) - np.asarray(centre)[:2]
    cov = answer.targets[0].covariance
    sd = np.sqrt(np.nanmax(np.diag(np.asarray(cov, float))[:2])) if cov is not None else 0.0
    return float(max(0.03, 1.5 * np.abs(points).max(), 3 * (2 * sd if np.isfinite(sd) else 0)))


def demo_figure(raw, filtered, location, path_png, answer=None):
    """Raw and filtered signals per detector (top); the paper's joint likelihood `location`
    (its score map) seen from above, whole and zoomed on the truth, with the scene and the
    `answer` (a Location: the default estimator's; the likelihood's peak when None)."""
    plt = pyplot()
    answer = location if answer is None else answer
    n_det = raw.n_detectors
    fig = plt.figure(figsize=(4 * max(n_det, 3), 8.5), layout="constrained")
    grid_spec = fig.add_gridspec(2, max(n_det, 3))
    path = raw.hidden_path_axis()
    for d in range(n_det):
        _signal_panel(fig.add_subplot(grid_spec[0, d]), raw, filtered, path, d)
    x, y, _ = location.grid.axes()
    score = location.score_map[0] / max(location.score_map.max(), TINY)
    centre = location.truth if location.truth is not None else answer.position
    spots = np.vstack([raw.detector_spots, raw.laser_spots])
    whole = (min(x[0], spots[:, 0].min()) - 0.2, max(x[-1], spots[:, 0].max()) + 0.2,
             min(y[0], spots[:, 1].min()) - 0.2, y[-1])
    half = _zoom(centre, location, answer)
    views = ((grid_spec[1, :-1], whole, "the paper's joint likelihood, plane z = 0"),
             (grid_spec[1, -1], (centre[0] - half, centre[0] + half, centre[1] - half,
                                 centre[1] + half), f"zoom: +-{half * 100:.0f} cm around the "
              + ("truth" if location.truth is not None else "answer")))
    axes = []
    for spec, limits, title in views:
        axes.append(fig.add_subplot(spec))
        image = _map_panel(axes[-1], location, score, limits)
        _scene(axes[-1], raw, location, answer)
        axes[-1].set_title(title)
    axes[0].legend(loc="upper right", fontsize=8, framealpha=0.9)
    fig.colorbar(image, ax=axes[-1], label="joint likelihood (normalised)")
    fig.savefig(path_png, dpi=110)
    plt.close(fig)
