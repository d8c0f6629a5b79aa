"""Where a study's data come from: the study file or dict (`read_source`) and its `scene`, a
scene file's path or a mapping (`scene`). A scene file is the study's choice, not the user's,
so what is wrong with it is said by count and position, never by its text (a study naming
/etc/shadow or /etc/group must not print them).
"""
from __future__ import annotations

import copy
import re
from pathlib import Path

from ..core.errors import InputError, require
from ..io.scenefile import read_yaml
from .bounds import shown

MAX_PATH = 1024  # characters of a scene file's path (it is echoed in errors)
_TOKENS = re.compile(r"'[^']*'|\"[^\"]*\"|[*&][^\s,)]+")  # quoted text, *alias, &anchor


def scene(value, base_dir: Path) -> dict:
    """A study's `scene`: a scene file (relative to `base_dir`) read, or a mapping copied; the
    paths of mesh files in it made absolute (relative to where they were named)."""
    if isinstance(value, (str, Path)):
        require(len(str(value)) <= MAX_PATH and "\n" not in str(value), "scene", f"expected a "
                f"scene file path, got {shown(str(value))}", "write scene: my_scene.yaml")
        path = Path(value) if Path(value).is_absolute() else base_dir / value
        value, base_dir = _scene_file(path), path.parent
    require(isinstance(value, dict), "scene", f"expected a scene file path or a scene mapping, "
            f"got {shown(value)}", "write scene: my_scene.yaml, or the scene's keys inline")
    value = copy.deepcopy(value)
    for target in value.get("targets") or []:  # mesh files: relative to where they were named
        if isinstance(target, dict) and isinstance(target.get("file"), str):
            target["file"] = str((base_dir / target["file"]).resolve())
    return value


def _scene_file(path: Path) -> dict:
    """The scene file a study names. The study chose the file, not the user, so a YAML error
    gives its position, never its text (a study naming /etc/group must not print a group)."""
    from ..io.scenefile import TOP as SCENE_KEYS
    try:
        raw = read_yaml(path, "scene file")
        odd = [k for k in raw if k not in SCENE_KEYS]  # none shown: they may be a secret's lines
        require(not odd, f"study.scene: {shown(str(path))}", f"is not a scene file ({len(odd)} "
                f"of its {len(raw)} top-level keys are not scene keys)", f"name a scene file, "
                f"whose keys are among {sorted(SCENE_KEYS)} (docs/scene-files.md)")
        return raw
    except InputError as exc:
        cause = exc.__context__  # PyYAML's error or the reader's bound, behind `from None`
        problem = getattr(cause, "problem", None)
        if not problem:
            raise
        mark = getattr(cause, "problem_mark", None)
        where = "" if mark is None else f", line {mark.line + 1}, column {mark.column + 1}"
        problem = _TOKENS.sub("'...'", str(problem))  # the file's own words: keys, anchors
        raise InputError(f"study.scene: the scene file {shown(str(path))} is not a scene file "
                         f"nlos_cl reads ({shown(problem, 160)}{where}). Fix: name a scene "
                         "file (docs/scene-files.md), or write the scene inline") from None


def read_source(source, base_dir=None) -> tuple:
    """(the study's dict, the folder its scene paths are relative to) from a YAML file path or
    a dict (relative to `base_dir`, default the working folder)."""
    if not isinstance(source, dict):
        path = Path(source)
        raw = read_yaml(path, "study file")
        return raw, (path.parent if base_dir is None else Path(base_dir))
    return source, Path(base_dir or ".")
