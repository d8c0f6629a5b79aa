"""nlos_cl's study runners, by registration: a study file may name a function of nlos_cl as
its `runner` only when the function is marked `@runner` here. Every other function of the
package (the sweep engine itself, the CLI's main, the atomic file writer) is code a study must
not reach: they run studies, command lines or write files they are given.

A registered runner takes plain values from the study (positions, seeds, SNRs, layouts), never
a study, a command line or a path to write: the decorator refuses, when the module is
imported, a parameter named like one (FORBIDDEN) or a `*args` / `**kwargs` that would take any
name. The user's own modules are not registered: `--allow-runner MODULE` is their word.
"""
from __future__ import annotations

import inspect

OWN = "nlos_cl"  # the package whose functions run only when registered
# Parameter-name words (split on "_") of what a study must not hand a runner: another study,
# code or a command line, and files or folders to write.
FORBIDDEN = frozenset({"study", "runner", "command", "cmd", "argv", "args", "shell", "exec",
                       "code", "script", "out", "output", "path", "file", "filename", "folder",
                       "dir", "directory", "dest", "force", "overwrite"})
_REGISTERED: dict = {}  # 'module:qualname' -> the function


def name_of(fn) -> str:
    return f"{fn.__module__}:{fn.__qualname__}"


def refused_parameters(fn) -> list[str]:
    """The parameters of `fn` a study must not fill: named like a study, command or output
    path (FORBIDDEN, by word), or *args / **kwargs (any name at all)."""
    bad = []
    for p in inspect.signature(fn).parameters.values():
        words = set(p.name.lower().split("_"))
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) or words & FORBIDDEN:
            bad.append(p.name)
    return bad


def runner(fn):
    """Decorator: `fn` may be named as a study's `runner`. A parameter that could take a study,
    a command line or a path to write is a programming error, raised at import."""
    bad = refused_parameters(fn)
    if bad:
        raise TypeError(f"{name_of(fn)} cannot be a study runner: its parameters {bad} could "
                        "take a study, a command line or a path to write from study data")
    _REGISTERED[name_of(fn)] = fn
    return fn


def is_registered(fn) -> bool:
    try:
        return _REGISTERED.get(name_of(fn)) is fn
    except AttributeError:  # no __module__ / __qualname__: not a function of ours
        return False


def registered() -> list[str]:
    """The names of the runners registered so far (those of the modules imported)."""
    return sorted(_REGISTERED)


def is_own(module: str) -> bool:
    return module == OWN or module.startswith(OWN + ".")
