"""Figures a researcher shows: compared panels share one colour scale (fig10's error maps),
fig8 draws every detector's signal, the demo figure draws the default answer with its 2-sd
ellipse, every detector spot, the laser spot and the wall."""
import numpy as np

from nlos_cl.apps import plotting


def _capture(monkeypatch):
    shown = []
    monkeypatch.setattr(plotting, "save", lambda fig, out, name, dpi=80: shown.append(fig) or name)
    return shown


def test_fig10_error_maps_share_one_colour_scale(monkeypatch, tmp_path):
    shown = _capture(monkeypatch)
    rng = np.random.default_rng(0)
    scale = {"filter": 0.05, "fit": 0.03, "raw": 0.4}
    rows = [{"x": x, "y": y, **{f"{m}_mean_m": s * (1 + rng.random()) for m, s in scale.items()}}
            for x in range(1, 6) for y in range(1, 6)]
    errors = {m: [r[f"{m}_mean_m"] for r in rows] for m in scale}
    summary = {m: {"mean_m": float(np.mean(e)), "std_m": float(np.std(e))} for m, e in errors.items()}
    plotting.grid_errors_figure(rows, errors, summary, tmp_path, "fig10")
    (fig,) = shown
    images = [im for ax in fig.axes for im in ax.images]
    assert len(images) == 3
    assert len({(im.norm.vmin, im.norm.vmax) for im in images}) == 1
    low, high = images[0].norm.vmin, images[0].norm.vmax
    every = np.concatenate([np.asarray(e) for e in errors.values()])
    assert low <= every.min() and high >= every.max()
    assert len(fig.axes) == 7  # 3 maps, 3 histograms, one colorbar
