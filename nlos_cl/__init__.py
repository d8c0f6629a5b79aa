"""nlos_cl: locate objects hidden around a corner from time-of-flight histograms, with
OpenCL kernels for the photon-flight model, the Gauss filter and ellipse scoring.

Names are imported on first use (PEP 562), so `import nlos_cl` stays cheap and code that only
locates captures never loads trimesh, SciPy or matplotlib.
"""
from __future__ import annotations

import importlib

_EXPORTS = {
    ".backend": ("NumpyBackend", "resolve_backend"),
    ".capture": ("read_capture", "write_capture"),
    ".constants": ("SPEED_OF_LIGHT", "PAPER_H_S"),
    ".errors": ("DeviceError", "InputError"),
    ".estimators": ("Estimate", "LocatedTarget", "Location", "PaperArgmax"),
    ".grid": ("Grid",),
    ".histograms": ("HistogramSet", "Layout"),
    ".layouts": ("height_observable",),
    ".measured": ("CalibrationFit", "PhotonCounter", "fit_calibration", "peak_times",
                  "subtract_background", "with_calibration"),
    ".meshes": ("box", "l_block", "load_mesh", "rectangle", "sphere"),
    ".noise": ("AWGN",),
    ".ops": ("OPERATIONS",),
    ".paths": ("PathAxis", "PathCalibration", "TimeAxis", "default_time_axis"),
    ".pipeline": ("add_noise", "gauss_filter", "gauss_fit", "locate", "simulate"),
    ".plans": ("GaussFilter", "Locator"),
    ".reflectance": ("GGX", "Lambertian"),
    ".geometry": ("Facets",),
    ".scene": ("Pulse", "Scene", "Setup", "Target", "paper_scene", "paper_setup"),
    ".signals": ("Signals", "upload"),
    ".sweep": ("sweep",),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
__all__ = sorted(_WHERE)
__version__ = "0.1.0"


def __getattr__(name):
    module = _WHERE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
    else:  # a submodule: nl.runtime, nl.capture, ...
        try:
            value = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise  # a dependency of that module is missing: say so
            raise AttributeError(f"module 'nlos_cl' has no attribute {name!r}") from None
    globals()[name] = value
    return value


def __dir__():
    return __all__
