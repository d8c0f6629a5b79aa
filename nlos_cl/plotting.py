"""The demo figure: raw and filtered signals per detector, and the joint probability map."""
from __future__ import annotations

import numpy as np


def demo_figure(raw, filtered, location, path_png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n_det = raw.n_detectors
    fig = plt.figure(figsize=(4 * max(n_det, 3), 8.5), layout="constrained")
    grid_spec = fig.add_gridspec(2, max(n_det, 3))
    path = raw.hidden_path_axis()
    names = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
    for d in range(n_det):
        ax = fig.add_subplot(grid_spec[0, d])
        support = np.nonzero(np.abs(filtered.data[d]) > 0.02 * np.abs(filtered.data[d]).max())[0]
        lo, hi = (support[0], support[-1]) if support.size else (0, raw.data.shape[1] - 1)
        pad = max((hi - lo) // 2, 10)
        sl = slice(max(lo - pad, 0), min(hi + pad, raw.data.shape[1]))
        ax.plot(path[d, sl], raw.data[d, sl] * 1e15, lw=0.6, color="0.6", label="raw + noise")
        ax.plot(path[d, sl], filtered.data[d, sl] * 1e15, lw=1.5, color="C3", label="Gauss filtered")
        ax.set_xlabel("hidden path r1 + r2 (m)")
        ax.set_ylabel("power (fW)")
        ax.set_title(f"detector {names[d % 26]} at x = {raw.detector_spots[d, 0]:.2f} m")
        ax.legend(loc="upper right", fontsize=8)
    grid = location.grid
    x, y, _ = grid.axes()
    score = location.score_map[0] / max(location.score_map.max(), 1e-300)
    centre = location.truth if location.truth is not None else location.position
    views = ((grid_spec[1, :-1], (x[0], x[-1], y[0], y[-1]), "joint probability, plane z = 0"),
             (grid_spec[1, -1], (centre[0] - 0.3, centre[0] + 0.3, centre[1] - 0.3,
                                 centre[1] + 0.3), "zoom: +-0.3 m around the truth"))
    for spec, (x0, x1, y0, y1), title in views:
        ax = fig.add_subplot(spec)
        image = ax.imshow(score, origin="lower", aspect="equal", cmap="magma",
                          extent=(x[0] - grid.step[0] / 2, x[-1] + grid.step[0] / 2,
                                  y[0] - grid.step[1] / 2, y[-1] + grid.step[1] / 2))
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        if location.truth is not None:
            ax.plot(*location.truth[:2], "o", mfc="none", mec="cyan", ms=12, mew=2, label="truth")
        ax.plot(*location.position[:2], "x", color="lime", ms=12, mew=2.5, label="located")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m), distance from the wall")
        ax.set_title(title)
        ax.legend(loc="upper right", fontsize=8)
    fig.colorbar(image, ax=ax, label="joint likelihood (normalised)")
    fig.savefig(path_png, dpi=110)
    plt.close(fig)
