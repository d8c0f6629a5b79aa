"""The house rules of docs/architecture.md, read from the code: every import (function-local
ones included, and importlib calls with a literal name) goes down or across the layer table,
never up; no two modules import each other, however indirectly; every package ships; and no
module, function or class outgrows the size a reader can hold."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "nlos_cl"
ARCHITECTURE = ROOT / "docs" / "architecture.md"
LIMITS = {"module lines": 350, "function lines": 60}
MAX_OPTIONS = 12  # a constructor's options; more are grouped in option dataclasses
MODEL = "nlos_cl.localization.model"  # the one layer whose rooms have an order of their own


def _numbered_paths(heading: str, doc: Path = ARCHITECTURE) -> list[tuple[str, str]]:
    """(row, second cell's `path`) of the numbered rows of the table under `heading`."""
    section = doc.read_text(encoding="utf-8").split(heading, 1)[1].split("\n## ", 1)[0]
    rows = []
    for row in section.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) >= 2 and cells[0].isdigit():
            rows.append((row, cells[1]))
    return rows


def layer_table(doc: Path = ARCHITECTURE) -> list[str]:
    """The layers, bottom first, as dotted prefixes ('nlos_cl.core', ..., 'nlos_cl' for the
    facade): the rows of the table under '## Layers' whose second cell is a `path`."""
    layers = []
    for row, cell in _numbered_paths("## Layers", doc):
        path = re.fullmatch(r"`nlos_cl/([\w/]*?)/?(__init__\.py)?`", cell)
        assert path, f"layer table row {row!r}: the second cell must be `nlos_cl/<folder>/`"
        folder = path.group(1)
        layers.append("nlos_cl" + ("." + folder.replace("/", ".") if folder else ""))
    return layers


def room_table(doc: Path = ARCHITECTURE, layer: str = MODEL) -> list[str]:
    """The rooms of one layer, first first, as dotted names: the rows of the table under
    '## Rooms inside `<layer folder>/`' whose second cell is a `path` (a folder or a module)."""
    folder = layer.removeprefix("nlos_cl.").replace(".", "/")
    rooms = []
    for row, cell in _numbered_paths(f"## Rooms inside `{folder}/`", doc):
        path = re.fullmatch(r"`(nlos_cl/[\w/]+?)(/|\.py)`", cell)
        assert path, f"room table row {row!r}: the second cell must be a `nlos_cl/...` path"
        rooms.append(path.group(1).replace("/", ".").removesuffix(".__init__"))
    return rooms


def module_name(path: Path, package: Path) -> str:
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(package: Path = PACKAGE) -> dict[str, set[str]]:
    """module -> the nlos_cl modules it imports anywhere in its body (absolute names)."""
    modules = {module_name(p, package): p for p in package.rglob("*.py")}
    found: dict[str, set[str]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        here = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = here.split(".")[:len(here.split(".")) - node.level + 1]
                    base = ".".join(up + ([node.module] if node.module else []))
                for a in node.names:  # `from pkg import module` imports the module
                    targets.add(f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base)
            elif isinstance(node, ast.Call) and _dynamic_import(node):
                arg = node.args[0]
                if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                    package_arg = node.args[1] if len(node.args) > 1 else None
                    targets.add(_absolute(arg.value, package_arg, name))
            elif isinstance(node, ast.Dict) and name == package.name:  # the facade's table
                targets |= {f"{package.name}{k.value}" for k in node.keys
                            if isinstance(k, ast.Constant) and str(k.value).startswith(".")}
                targets |= {f"{package.name}{v.value}" for v in node.values
                            if isinstance(v, ast.Constant) and str(v.value).startswith(".")}
        found[name] = {t for t in targets if t.split(".")[0] == package.name and t != name}
    return found


def _dynamic_import(node: ast.Call) -> bool:
    f = node.func
    return bool(node.args) and ((isinstance(f, ast.Name) and f.id == "__import__")
                                or (isinstance(f, ast.Attribute) and f.attr == "import_module"))


def _absolute(name: str, package_arg, module: str) -> str:
    if not name.startswith("."):
        return name
    return module.rpartition(".")[0] if name == "." else module.split(".")[0] + name


def layer_of(module: str, layers: list[str], exact: tuple[str, ...] = ("nlos_cl",)) -> int:
    """The index of the deepest layer prefix the module falls under; a package face named in
    `exact` (the facade, a room table's face) holds only itself."""
    best = None
    for i, prefix in enumerate(layers):
        if prefix in exact:
            if module == prefix:
                best = i
        elif module == prefix or module.startswith(prefix + "."):
            best = i
    if best is None:
        raise AssertionError(f"{module} is in no layer of docs/architecture.md: move it into a "
                             "layer folder or add the folder to the table")
    return best


def upward_imports(found: dict[str, set[str]], layers: list[str]) -> list[str]:
    bad = []
    for module, targets in sorted(found.items()):
        if module in layers and module != "nlos_cl":  # a layer's own (empty) face
            continue
        mine = layer_of(module, layers)
        for target in sorted(targets):
            if target in layers and target != "nlos_cl":
                continue  # importing a layer package itself is importing its face
            theirs = layer_of(target, layers)
            if theirs > mine:
                bad.append(f"{module} ({layers[mine]}) imports {target} ({layers[theirs]})")
    return bad


def upward_room_imports(found: dict[str, set[str]], rooms: list[str],
                        layer: str = MODEL) -> list[str]:
    """Imports between modules of one layer against its room order (the layer's face, last in
    the table, holds only itself; a room's face belongs to its room)."""
    inside = {m: {t for t in ts if t == layer or t.startswith(layer + ".")}
              for m, ts in found.items() if m.startswith(layer + ".")}
    bad = []
    for module, targets in sorted(inside.items()):
        mine = layer_of(module, rooms, exact=(layer,))
        for target in sorted(targets):
            theirs = layer_of(target, rooms, exact=(layer,))
            if theirs > mine:
                bad.append(f"{module} ({rooms[mine]}) imports {target} ({rooms[theirs]})")
    return bad


def circles(found: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), plus self-imports."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in found.get(v, ()):
            if w not in found:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(found):
        if v not in index:
            visit(v)
    return out


def _without_package_faces(found: dict[str, set[str]]) -> dict[str, set[str]]:
    """A package's __init__ that only re-exports its own modules is how Python loads a package
    before any module in it: an edge module -> its own package face is not a circle."""
    return {m: {t for t in ts if not (m.startswith(t + ".") and t != "nlos_cl")}
            for m, ts in found.items()}


def test_the_layer_table_names_every_folder():
    layers = layer_table()
    assert layers[0] == "nlos_cl.core" and "nlos_cl" in layers and layers[-1] == "nlos_cl.apps"
    folders = {module_name(p, PACKAGE) for p in PACKAGE.glob("*/__init__.py")}
    assert folders <= set(layers), f"folders missing from the table: {folders - set(layers)}"
    loose = sorted(p.name for p in PACKAGE.glob("*.py") if p.name != "__init__.py")
    assert not loose, f"modules outside any layer folder: {loose}"


def test_every_import_goes_down_or_across_the_layer_table():
    bad = upward_imports(imports(), layer_table())
    assert not bad, "imports against the layer order:\n" + "\n".join(bad)


def test_every_model_module_sits_in_a_room():
    rooms = room_table()
    assert rooms[-1] == MODEL, "the model's face comes last in its room table"
    layer_dir = PACKAGE.parent / MODEL.replace(".", "/")
    listed = {r for r in rooms if (PACKAGE.parent / (r.replace(".", "/") + ".py")).exists()
              or (PACKAGE.parent / r.replace(".", "/")).is_dir()}
    assert listed == set(rooms), f"rooms in the table that are not in the code: {set(rooms) - listed}"
    loose = sorted(p.name for p in layer_dir.glob("*.py")
                   if module_name(p, PACKAGE) not in rooms)
    assert not loose, f"modules of localization/model/ in no room: {loose}"
    folders = {module_name(p, PACKAGE) for p in layer_dir.glob("*/__init__.py")}
    assert folders <= set(rooms), f"folders of localization/model/ in no room: {folders - set(rooms)}"


def test_every_import_in_the_model_goes_down_or_across_its_rooms():
    bad = upward_room_imports(imports(), room_table())
    assert not bad, "imports against the model's room order:\n" + "\n".join(bad)


def test_the_room_check_catches_a_forward_model_reaching_into_policy():
    """The checker itself, on a copy of today's imports with one edge turned upward."""
    found = {m: set(ts) for m, ts in imports().items()}
    found[f"{MODEL}.forward.batch"].add(f"{MODEL}.policy.select")
    found[f"{MODEL}.shapes.plate"].add(f"{MODEL}.estimator")
    assert upward_room_imports(found, room_table()) == [
        f"{MODEL}.forward.batch ({MODEL}.forward) imports {MODEL}.policy.select ({MODEL}.policy)",
        f"{MODEL}.shapes.plate ({MODEL}.shapes) imports {MODEL}.estimator ({MODEL}.estimator)"]


def test_no_import_circles():
    found = circles(_without_package_faces(imports()))
    assert not found, "import circles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_the_checks_catch_an_upward_import_and_a_circle():
    """The checker itself: an op reaching up into the registry's user, and a circle."""
    layers = ["nlos_cl.core", "nlos_cl.device", "nlos_cl.ops", "nlos_cl", "nlos_cl.apps"]
    found = {"nlos_cl.device.runtime": {"nlos_cl.ops.registry"},
             "nlos_cl.ops.registry": {"nlos_cl.ops.forward"},
             "nlos_cl.ops.forward": {"nlos_cl.device.runtime"}}
    assert upward_imports(found, layers) == [
        "nlos_cl.device.runtime (nlos_cl.device) imports nlos_cl.ops.registry (nlos_cl.ops)"]
    assert circles(found) == [sorted(found)]


def test_every_package_is_packaged():
    pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    listed = set(re.findall(r'"(nlos_cl[\w.]*)"', pyproject.split("packages =", 1)[1]
                            .split("]", 1)[0]))
    packages = {module_name(p, PACKAGE) for p in PACKAGE.rglob("__init__.py")}
    assert packages <= listed, f"packages a wheel would leave out: {sorted(packages - listed)}"


def _sizes():
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        where = path.relative_to(ROOT)
        yield "module lines", f"{where}", len(text.splitlines())
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield "function lines", f"{where}:{node.lineno} {node.name}", \
                    node.end_lineno - node.lineno + 1


@pytest.mark.parametrize("kind", sorted(LIMITS))
def test_nothing_outgrows_what_a_reader_can_hold(kind):
    over = [f"{where}: {n}" for k, where, n in _sizes() if k == kind and n > LIMITS[kind]]
    assert not over, f"{kind} over {LIMITS[kind]}:\n" + "\n".join(over)


def test_library_tests_and_scripts_reach_the_library_not_the_apps():
    """Library behaviour is tested through the library: outside tests/apps/ a test may run a
    command end to end (nlos_cl.apps.cli, nlos_cl.apps.console), nothing else of apps; scripts
    likewise (the reproduce and bench internals are apps, not a second library)."""
    allowed = {"nlos_cl.apps", "nlos_cl.apps.cli", "nlos_cl.apps.console"}
    # Scripts that extend an app, not the library: the mitransient scripts run `reproduce
    # draws`' own locate and report on renders made in another venv (so their errors are
    # measured as the draws' are); oneshot_bench times `nlos-cl`'s own exit (terminal.leave);
    # track_draws tracks the scenario suite's and reproduce draws' own sequences, as they do.
    extends_an_app = {"mitransient_draws.py", "mitransient_layouts.py", "oneshot_bench.py",
                      "track_draws.py"}
    bad = []
    for path in sorted([*(ROOT / "tests").rglob("*.py"), *(ROOT / "scripts").rglob("*.py")]):
        if (ROOT / "tests" / "apps") in path.parents or path.name in extends_an_app:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("nlos_cl"):
                names = [f"{node.module}.{a.name}" if node.module == "nlos_cl.apps" else
                         node.module for a in node.names]
            bad += [f"{path.relative_to(ROOT)}: {n}" for n in names
                    if n.startswith("nlos_cl.apps") and n not in allowed]
    assert not bad, "apps reached from library tests or scripts:\n" + "\n".join(bad)


def constructor_options(tree: ast.AST) -> list[tuple[str, int, int]]:
    """(class, line, options) of every class with its own __init__: the parameters after self
    (keyword-only ones included, **kwargs not). Records (dataclasses without an __init__: a
    Track, a ModelFit) hold results, not options, and are not counted."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            for f in node.body:
                if isinstance(f, ast.FunctionDef) and f.name == "__init__":
                    a = f.args
                    out.append((node.name, node.lineno,
                                len(a.posonlyargs) + len(a.args) - 1 + len(a.kwonlyargs)))
    return out


def test_constructors_take_at_most_12_options():
    """A class is as big as its roles need; what a reader must hold is its options: at most
    MAX_OPTIONS, the rest grouped (tracking.options: MeasurementNoise, TrackRules, SearchPlan;
    model: Instrument, FitBudget) and roles injected as objects (the Tracker's estimator,
    motion, background)."""
    over = [f"{path.relative_to(ROOT)}:{line} {name}: {n}"
            for path in sorted(PACKAGE.rglob("*.py"))
            for name, line, n in constructor_options(ast.parse(path.read_text(encoding="utf-8")))
            if n > MAX_OPTIONS]
    assert not over, f"constructors over {MAX_OPTIONS} options:\n" + "\n".join(over)


def test_the_options_count_counts_keyword_only_and_not_kwargs():
    code = ("class Wide:\n    def __init__(self, a, b=1, *, " +
            ", ".join(f"k{i}=0" for i in range(11)) + ", **moved): pass\n")
    assert constructor_options(ast.parse(code)) == [("Wide", 1, 13)]
