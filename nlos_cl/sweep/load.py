"""One entry for every kind of study: a scene study (study.py) or a function's (runner.py)."""
from __future__ import annotations

from .bounds import check_study_data, shown
from .runner import load_runner_study
from .sources import read_source
from .study import Study, load_scene_study


def load_study(source, base_dir=None, allow_runner=()) -> Study:
    """A Study from a YAML file path or a dict (scene paths relative to the file, or to
    `base_dir`, default the working folder); a dict with a `runner` is a function's study,
    whose runner must be nlos_cl's or in a module of `allow_runner` (runner.resolve)."""
    if isinstance(source, Study):
        return source
    raw, base_dir = read_source(source, base_dir)
    check_study_data(raw, "study" if isinstance(source, dict) else
                     f"study file {shown(str(source), 200)}")  # before anything walks it
    if isinstance(raw, dict) and "runner" in raw:
        return load_runner_study(raw, base_dir, allow_runner)
    return load_scene_study(raw, base_dir)
