"""Every module the hand-written docs name still exists: each `nlos_cl/...` path (and tests/,
scripts/, kernels/ path) in README.md and docs/*.md is a file or folder of the checkout, and each
dotted `nlos_cl.x.y` name is a module, or a module's attribute (a moved module left docs
pointing at its old place). A path the page itself calls deleted, and the house tour's example
of a file to add, are exempt."""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
PATH = re.compile(r"(?<![\w./-])((?:nlos_cl|tests|scripts|kernels)/[\w./-]*[\w/])")
DOTTED = re.compile(r"(?<![\w./-])(nlos_cl(?:\.[A-Za-z_]\w*)+)")
# named as files to create, not files that exist
EXAMPLES = {"nlos_cl/localization/centroid.py": "docs/architecture.md's house tour: the file a "
                                                "new estimator adds"}


def _mentions(pattern):
    for page in PAGES:
        for number, line in enumerate(page.read_text("utf-8").splitlines(), 1):
            for name in pattern.findall(line):
                yield f"{page.relative_to(ROOT)}:{number}", name, line


def missing_path(name: str, line: str) -> bool:
    return not ((ROOT / name).exists() or name in EXAMPLES or "deleted" in line)


def unresolved(dotted: str) -> str | None:
    """Why `dotted` names nothing (its longest module prefix lacks the rest), or None."""
    parts = dotted.split(".")
    k = next(k for k in range(len(parts), 0, -1)
             if ROOT.joinpath(*parts[:k]).with_suffix(".py").is_file()
             or ROOT.joinpath(*parts[:k], "__init__.py").is_file())
    obj = importlib.import_module(".".join(parts[:k]))
    for i, attr in enumerate(parts[k:], k):
        if not hasattr(obj, attr):
            return f"{'.'.join(parts[:i])} has no {attr}"
        obj = getattr(obj, attr)
    return None


def test_every_path_named_exists():
    gone = [f"{where}: {name}" for where, name, line in _mentions(PATH)
            if missing_path(name, line)]
    assert not gone, "paths in the docs that do not exist (moved? say where):\n" + "\n".join(gone)


def test_every_dotted_module_named_exists():
    gone = [f"{where}: {name} ({why})" for where, name, _ in _mentions(DOTTED)
            if (why := unresolved(name))]
    assert not gone, "dotted names in the docs that name nothing:\n" + "\n".join(gone)


@pytest.mark.parametrize("name, line, gone", [
    ("nlos_cl/io/scenefile.py", "", False), ("nlos_cl/io/scenes.py", "see it", True),
    ("nlos_cl/frames.py", "see nlos_cl/frames.py", True),  # scene-files.md's, before 9fd64f4
    ("scripts/old.py", "(since deleted)", False), ("nlos_cl/physics/", "", False)])
def test_the_path_check_can_fail(name, line, gone):
    assert missing_path(name, line) is gone


def test_a_file_name_is_no_dotted_name():
    assert not DOTTED.findall("its `files-written-by-nlos_cl.json`, docs/nlos_cl.md")
    assert DOTTED.findall("(nlos_cl.io.safe_write: atomic)") == ["nlos_cl.io.safe_write"]


def test_the_dotted_check_can_fail():
    assert unresolved("nlos_cl.io.scenefile.load_scene") is None
    assert unresolved("nlos_cl.device.runtime.get_runtime") == \
        "nlos_cl.device.runtime has no get_runtime"
    assert unresolved("nlos_cl.metadata.sequence") == "nlos_cl has no metadata"
