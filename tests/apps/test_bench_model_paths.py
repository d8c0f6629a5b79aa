"""The bench's model paths table (apps/bench/model_paths.py): each path evaluates the same
Jacobian's plates of the same observation, so their histograms agree (float32 kernels against
float64 NumPy); the confocal layout has no host path; the table names the rule's choice."""
import math

import numpy as np

from nlos_cl.apps.bench import model_paths
from nlos_cl.localization.model.estimator import plates_path


def test_every_path_models_the_same_plates(runtime):
    for confocal in (False, True):
        obs = model_paths._observation(runtime, 16, confocal)
        rows, like = model_paths._jacobian_rows()
        problems = model_paths._problems(runtime, obs)
        assert ("host" in problems) is (not confocal)
        out = {name: p.column_batch(rows, like) for name, p in problems.items()}
        ref = out["kernel"]
        peak = float(np.abs(ref).max())
        assert peak > 0
        for name, hist in out.items():  # the plate and its stepped rows, path against path
            assert np.abs(hist - ref).max() <= 0.02 * peak, (confocal, name)


def test_the_table_says_what_auto_takes_and_what_was_fastest(runtime):
    rows = model_paths.table(runtime, smoke=True, say=lambda *_: None)
    assert [(r["layout"], r["spots"]) for r in rows] == [
        ("one laser", 3), ("one laser", 16), ("confocal", 3), ("confocal", 16)]
    for r in rows:
        assert r["auto"] == plates_path("auto", r["spots"], r["layout"] == "confocal")
        assert r["fastest"] in model_paths.PATHS
        assert math.isnan(r["host"]) is (r["layout"] == "confocal")
    text = model_paths.section(rows)
    assert "| confocal | 16 |" in text and "| - |" in text and "nan" not in text
