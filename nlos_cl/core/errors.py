"""One exception type for everything a user can get wrong, so callers can catch it."""


class InputError(ValueError):
    """Bad user input. The message names the field and says how to fix it."""


class DeviceError(RuntimeError):
    """No usable OpenCL device, or a kernel that would not build or run."""


def require(condition: bool, field: str, problem: str, fix: str) -> None:
    """Raise InputError('<field>: <problem>. Fix: <fix>') unless condition holds."""
    if not condition:
        raise InputError(f"{field}: {problem}. Fix: {fix}")


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
