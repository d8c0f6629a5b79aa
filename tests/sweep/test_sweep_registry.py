"""Runners by registration (nlos_cl/sweep/registry.py, issue 59 item 2): a study may name, of
nlos_cl's functions, only those marked @runner; every other function of every nlos_cl module is
refused in one line naming `runner` and the fix, however the name reaches it."""
import importlib
import inspect
import pkgutil

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nlos_cl
from nlos_cl.core.errors import InputError
from nlos_cl.sweep import load_study
from nlos_cl.sweep.registry import FORBIDDEN, is_registered, refused_parameters, registered
from nlos_cl.sweep.registry import runner as register
from nlos_cl.sweep.runner import resolve

REGISTERED = ("nlos_cl.sweep.examples:paper_target", "nlos_cl.apps.reproduce.beyond.runs:run")


def _modules():
    names = [m.name for m in pkgutil.walk_packages(nlos_cl.__path__, "nlos_cl.")
             if not m.name.endswith("__main__")]
    return {name: importlib.import_module(name) for name in names}


MODULES = _modules()  # every module of nlos_cl, imported (their runners register on import)
FUNCTIONS = sorted(f"{name}:{attr}" for name, mod in MODULES.items()
                   for attr, obj in vars(mod).items()
                   if callable(obj) and getattr(obj, "__module__", None) == name)


def test_every_unregistered_nlos_cl_function_is_refused():
    """The class, exhaustively: each of nlos_cl's ~1,300 module-level functions and classes."""
    assert len(FUNCTIONS) > 500 and set(REGISTERED) <= set(FUNCTIONS)
    ran = []
    for name in FUNCTIONS:
        try:
            ran.append((name, resolve(name)))
        except InputError as exc:
            text = str(exc)
            head = "runner: " if ":__" in name else f"runner {name!r}: "  # dunders: no name
            assert text.startswith(head) and "Fix:" in text and "\n" not in text
    assert sorted(name for name, _ in ran) == sorted(REGISTERED) == registered()
    assert all(is_registered(fn) for _, fn in ran)


@pytest.mark.parametrize("name", ["nlos_cl.sweep.engine:sweep", "nlos_cl.apps.cli:main",
                                  "nlos_cl.io.safe_write:write_text", "nlos_cl:sweep",
                                  "nlos_cl:locate", "nlos_cl.sweep.examples:clean"])
def test_the_red_team_s_runners_are_refused_even_when_nlos_cl_is_allowed(name):
    """--allow-runner is for the user's own modules: it does not open nlos_cl's functions."""
    for allow in ((), ("nlos_cl",), ("nlos_cl.apps", "nlos_cl.sweep", "nlos_cl.io")):
        with pytest.raises(InputError, match=rf"^runner {name!r}: .*Fix: "):
            load_study({"runner": name, "axes": [{"name": "study", "values": [1]}]},
                       allow_runner=allow)


def _attribute_paths(draw):
    module = draw(st.sampled_from(sorted(MODULES)))
    obj, parts = MODULES[module], []
    for _ in range(draw(st.integers(1, 3))):
        names = sorted(n for n in dir(obj) if not n.startswith("__"))
        if not names:
            break
        parts.append(draw(st.sampled_from(names)))
        try:
            obj = getattr(obj, parts[-1], None)
        except Exception:  # noqa: BLE001 - a property that raises: resolve must say so in a line
            break
    return f"{module}:{'.'.join(parts)}" if parts else f"{module}:x"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.composite(_attribute_paths)())
def test_any_name_into_nlos_cl_resolves_to_a_registered_runner_or_is_refused(name):
    """Attribute paths through modules, classes and imported names (`engine:os.system`,
    `examples:worker_cache`, a class's method): a registered runner, or one line."""
    try:
        fn = resolve(name, allow=("nlos_cl",))
    except InputError as exc:
        assert str(exc).startswith("runner") and "Fix:" in str(exc) and "\n" not in str(exc)
    else:
        assert is_registered(fn) or is_registered(inspect.unwrap(fn))


@pytest.mark.parametrize("name", ["nlos_cl.localization.model.policy.closed:BOX_YAWS.mT",
                                  "nlos_cl.localization.model.policy.closed:BOX_YAWS.tolist",
                                  "nlos_cl.sweep.examples:paper_target.func"])
def test_names_through_objects_run_no_property(name):
    """Through nlos_cl a name walks modules and classes only: an array's `.mT` (a property
    that raises ValueError on 1-D) or a bound method is not reached."""
    with pytest.raises(InputError, match=rf"^runner {name!r}: .* has no"):
        resolve(name)


@pytest.mark.parametrize("name", ["nlos_cl.sweep.examples:paper_target.__call__",
                                  "nlos_cl.sweep.examples:paper_target.__globals__",
                                  "nlos_cl.sweep.examples:__builtins__"])
def test_dunder_paths_are_no_runner_names(name):
    with pytest.raises(InputError, match=r"^runner: expected 'package.module:function'"):
        resolve(name)


def test_a_runner_cannot_take_a_study_a_command_or_an_output_path():
    for params in ("study", "out", "out_dir", "command", "argv", "scene_path", "force",
                   "*args", "**kwargs"):
        ns = {}
        exec(f"def f(x, {params}): pass", ns)  # noqa: S102 - a test's own source
        with pytest.raises(TypeError, match="cannot be a study runner"):
            register(ns["f"])
    for name in registered():  # and none registered does (checked again, by signature)
        module, _, attr = name.partition(":")
        fn = getattr(MODULES[module], attr)
        assert refused_parameters(fn) == []
        words = {w for p in inspect.signature(fn).parameters for w in p.split("_")}
        assert not words & FORBIDDEN


def test_registered_runners_load_without_an_opt_in():
    study = load_study({"runner": REGISTERED[0], "axes": [{"name": "x", "values": [3.0]}],
                        "seeds": 1})
    assert study.n_runs == 1 and study.runner == REGISTERED[0]


def test_long_runner_names_are_not_echoed_in_full():
    name = "nlos_cl." + "a" * 100_000 + ":run"
    with pytest.raises(InputError) as err:
        resolve(name)
    assert len(str(err.value)) < 400
