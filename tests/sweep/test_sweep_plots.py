"""The sweep's error map compares estimators: every panel on one colour scale, one colorbar."""
import numpy as np

from nlos_cl.sweep import plots


def test_error_map_panels_share_one_colour_scale(monkeypatch, tmp_path):
    shown = []
    monkeypatch.setattr(plots, "_save", lambda fig, path, force: shown.append(fig) or path)
    xy = [(x, y) for x in (1.0, 2.0) for y in (1.0, 2.0)]
    data = {"estimator": np.array(["paper"] * 4 + ["model"] * 4, dtype=object),
            "truth_x_m": np.array([x for x, _ in xy] * 2, dtype=object),
            "truth_y_m": np.array([y for _, y in xy] * 2, dtype=object),
            "error_m": np.array([0.1, 0.2, 0.15, 0.3, 0.004, 0.01, 0.006, 0.02], dtype=object)}
    plots.error_map(data, "truth_x_m", "truth_y_m", tmp_path / "error_map.png")
    (fig,) = shown
    arts = [c for ax in fig.axes[:2] for c in ax.collections]
    assert len(arts) == 2
    limits = {(a.norm.vmin, a.norm.vmax) for a in arts}
    assert len(limits) == 1  # one scale
    (low, high), = limits
    assert low <= 0.004 and high >= 0.3  # spanning both panels' errors
    assert len(fig.axes) == 3  # two panels and one colorbar
    assert fig.axes[0].get_xlabel() == "true x (m)"
