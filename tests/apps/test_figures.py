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


def _kept_figures(monkeypatch):
    """Figures a drawing closes, kept open to be looked at."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    kept = []
    monkeypatch.setattr(plt, "close", lambda fig=None: kept.append(fig))
    return kept


def test_the_demo_figure_draws_the_default_answer_its_ellipse_spots_laser_and_wall(
        monkeypatch, tmp_path):
    from matplotlib.patches import Ellipse

    from nlos_cl.apps.cli import main
    kept = _kept_figures(monkeypatch)
    assert main(["demo", "--png", str(tmp_path / "demo.png"), "--step", "0.04"]) == 0
    (fig,) = [f for f in kept if f is not None]
    maps = [ax for ax in fig.axes if ax.images]
    assert len(maps) == 2  # the whole plane and the zoom
    for ax in maps:
        labels = {line.get_label(): line for line in ax.get_lines()}
        spots = labels["detector spots"].get_xydata()
        assert sorted(spots[:, 0]) == [-1.5, -1.0, -0.5] and not spots[:, 1].any()
        assert labels["laser spot"].get_xydata().tolist() == [[0.0, 0.0]]
        assert "relay wall (y = 0)" in labels
        answer = labels["answer (model fit, the default)"].get_xydata()[0]
        assert abs(answer[0] - 4.0) < 0.05 and abs(answer[1] - 2.0) < 0.05
        (ellipse,) = [p for p in ax.patches if isinstance(p, Ellipse)]
        assert tuple(ellipse.center) == tuple(answer) and 0 < ellipse.width < 0.1
    whole = maps[0]
    assert whole.get_xlim()[0] < -1.5  # every spot inside the view


def test_fig8_draws_every_detectors_signal(monkeypatch, tmp_path):
    """Each panel's window holds every detector's whole pulse (a window around detector A's
    cut off B and C, which arrive later)."""
    from types import SimpleNamespace

    from nlos_cl.apps.reproduce.common import Settings, simulate_clean
    from nlos_cl.apps.reproduce.paper import fig8

    def trials(scene, s, methods):  # the clean signals only: the located rows are not drawn
        found = SimpleNamespace(position=np.array([4.0, 2.0, 0.0]), error_m=0.01)
        return {m: [found] for m in methods}, simulate_clean(scene, s)
    monkeypatch.setattr(fig8, "run_trials", trials)
    shown = _capture(monkeypatch)
    fig8.fig8(Settings.make(quick=True), tmp_path)
    (fig,) = shown
    panels = [ax for ax in fig.axes if ax.get_lines()]
    assert len(panels) == 3
    for ax in panels:
        curves = ax.get_lines()
        assert [c.get_label() for c in curves] == ["detector A", "detector B", "detector C"]
        for c in curves:
            y = c.get_ydata()
            assert y.max() > 0 and y[0] < 0.02 * y.max() and y[-1] < 0.02 * y.max()


def test_fig6_marks_located_only_where_a_map_locates(monkeypatch, tmp_path):
    """One detector's map (the top row) is a ridge along its ellipse: its peak is no location,
    so only the joint maps (the bottom row) mark 'located'; each row has the legend."""
    import nlos_cl as nl
    shown = _capture(monkeypatch)
    scene = nl.paper_scene(position=(4.0, 2.0, 0.0))
    clean = nl.simulate(scene)
    grid = nl.Grid.from_ranges(x=(2.0, 5.0), y=(0.5, 3.5), step_m=0.05)
    single = nl.locate(clean.histograms().select([0]), grid, estimator="paper",  # p_A
                       return_map=True)
    joint = nl.locate(clean, grid, estimator="paper", return_map=True)
    plotting.maps_figure({"raw": (single, joint), "filter": (single, joint)}, scene.truth,
                         tmp_path, "fig6")
    (fig,) = shown
    top, bottom = fig.axes[0], fig.axes[2]  # row by row: two columns
    assert "located" not in {line.get_label() for line in top.get_lines()}
    assert "located" in {line.get_label() for line in bottom.get_lines()}
    assert top.get_legend() is not None and bottom.get_legend() is not None
