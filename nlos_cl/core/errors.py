"""One exception type for everything a user can get wrong, so callers can catch it."""


class InputError(ValueError):
    """Bad user input. The message names the field and says how to fix it."""


class DeviceError(RuntimeError):
    """No usable OpenCL device, or a kernel that would not build or run."""


def require(condition: bool, field: str, problem: str, fix: str) -> None:
    """Raise InputError('<field>: <problem>. Fix: <fix>') unless condition holds."""
    if not condition:
        raise InputError(f"{field}: {problem}. Fix: {fix}")


SHOWN_CHARS = 60  # an echoed value fits in one line beside its field and the fix


def shown(value, limit: int = SHOWN_CHARS) -> str:
    """`value` as an error message echoes it: its repr on one line, at most `limit` characters,
    a longer one cut and its full length said. Every echo of what a user gave goes through
    here, so no message grows with the input (a 100 kB string, a 10^6-element array)."""
    import reprlib
    r = reprlib.Repr()
    r.maxstring = r.maxother = r.maxlong = limit + 2
    r.maxlist = r.maxtuple = r.maxset = r.maxfrozenset = r.maxdeque = r.maxarray = 6
    r.maxdict, r.maxlevel = 4, 3
    if isinstance(value, (str, bytes)) and len(value) > limit:  # its start, and its length
        return " ".join(repr(value[:limit]).split())[:limit] + f"... ({len(value):,} characters)"
    text = " ".join(r.repr(value).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def spelled(name: str, value) -> str:
    """How a user writes option `name` = `value`: a flag and its value (`--estimator paper`),
    or a keyword (`estimator='paper'`); errors name options the way their caller spells them."""
    return f"{name} {value}" if name.startswith("--") else f"{name}={value!r}"


def group_holding(option: str, groups: dict) -> str | None:
    """The argument of `groups` ({argument: option dataclass}) whose dataclass has a field
    `option`, or None."""
    return next((arg for arg, group in groups.items()
                 if option in getattr(group, "__dataclass_fields__", {})), None)


def refuse_moved(owner: str, moved: dict, groups: dict, takes: str) -> None:
    """A constructor's options grouped into dataclasses (`groups`: {argument: dataclass}): an
    option passed by its old flat name, or unknown, ends in one line naming where it lives now
    (or what `owner` takes)."""
    for name in moved:
        arg = group_holding(name, groups)
        if arg is not None:
            group = groups[arg]
            raise InputError(f"{owner}.{name}: is an option of {group.__name__} now "
                             f"({group.__module__}). Fix: pass {arg}={group.__name__}({name}=...)")
        raise InputError(f"{owner}.{name}: is not an option. Fix: pass {takes}")


def warn(message, category=UserWarning) -> None:
    """warnings.warn attributed to the first caller outside nlos_cl (its file and line): what
    a user sees points at their own line, never at a library module, however deep the call."""
    import os
    import sys
    import warnings
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep  # nlos_cl/
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_code.co_filename.startswith(root):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level + 1)
