"""One exception type for everything a user can get wrong, so callers can catch it."""


class InputError(ValueError):
    """Bad user input. The message names the field and says how to fix it."""


class DeviceError(RuntimeError):
    """No usable OpenCL device, or a kernel that would not build or run."""


def require(condition: bool, field: str, problem: str, fix: str) -> None:
    """Raise InputError('<field>: <problem>. Fix: <fix>') unless condition holds."""
    if not condition:
        raise InputError(f"{field}: {problem}. Fix: {fix}")
