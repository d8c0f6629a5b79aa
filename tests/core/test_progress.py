"""core.progress: the stage a long computation names for the command line's progress line. The
model fit names its stages as it enters them (the closed shapes' search among them where it
runs) and leaves none behind when it returns (tests/apps/test_terminal.py: the line shows it)."""
import warnings

import numpy as np

import nlos_cl as nl
from nlos_cl.core import progress


def test_staged_restores_the_stage_it_interrupted():
    progress.stage("outer")
    with progress.staged("inner"):
        assert progress.current() == "inner"
    assert progress.current() == "outer"
    try:
        with progress.staged("failing"):
            raise ValueError("the block fails")
    except ValueError:
        pass
    assert progress.current() == "outer"
    progress.stage("")


def test_the_model_fit_names_its_stages_and_clears_them(runtime, monkeypatch):
    said = []
    real = progress.stage
    monkeypatch.setattr(progress, "stage", lambda text: said.append(text) or real(text))
    spots = [[-1.0, 0.0, -0.3], [-0.6, 0.0, 0.3], [-0.2, 0.0, -0.1]]
    box = nl.box((0.5, 0.5, 0.6), (2.5, 2.2, 0.0), cell_m=0.03)
    scene = nl.Scene(nl.paper_setup(detector_spots=spots), nl.Target(box), 0.03,
                     truth=(2.5, 2.2, 0.0))
    filtered = nl.gauss_filter(nl.simulate(scene, backend=runtime))
    grid = nl.Grid((1.8, 1.5, -0.5), (0.02, 0.02, 0.02), (71, 71, 51))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = nl.locate(filtered, grid)
    assert np.isfinite(found.position).all()
    assert said[0] == "model fit: the histograms' windows and noise"
    assert any(s.startswith("model fit: starts and short fits (3 histograms)") for s in said)
    assert found.targets[0].details["model"] == "upright box"  # so the closed shapes ran:
    assert any(s.startswith("model fit: closed shapes") for s in said)
    assert progress.current() == ""  # nothing left for the next line to show
