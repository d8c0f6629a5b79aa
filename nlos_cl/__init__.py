"""nlos_cl: locate objects hidden around a corner from time-of-flight histograms, with
OpenCL kernels for the photon-flight model, the Gauss filter and ellipse scoring.

Names are imported on first use (PEP 562), so `import nlos_cl` stays cheap and code that only
locates captures never loads trimesh, SciPy or matplotlib.
"""
from __future__ import annotations

import importlib

_EXPORTS = {
    ".core.constants": ("SPEED_OF_LIGHT", "PAPER_H_S"),
    ".core.errors": ("DeviceError", "InputError"),
    ".core.geometry": ("Facets",),
    ".core.grid": ("Grid",),
    ".core.histograms": ("HistogramSet", "Layout"),
    ".core.paths": ("PathAxis", "PathCalibration", "TimeAxis", "default_time_axis"),
    ".physics.layouts": ("height_observable",),
    ".physics.meshes": ("box", "l_block", "load_mesh", "rectangle", "sphere"),
    ".physics.noise": ("AWGN", "PhotonCounter"),
    ".physics.reflectance": ("GGX", "Lambertian", "Retroreflective"),
    ".physics.scene": ("Pulse", "Scene", "Setup", "Target", "paper_scene", "paper_setup"),
    ".ops": ("OPERATIONS",),
    ".ops.backend": ("NumpyBackend", "resolve_backend"),
    ".ops.signals": ("Signals", "upload"),
    ".io.calibration": ("CalibrationFit", "fit_calibration", "peak_times", "with_calibration"),
    ".io.ytal.capture": ("read_capture", "write_capture"),
    ".io.datasets": ("read_dataset",),
    ".simulation.frame": ("add_noise", "simulate"),
    ".localization.api": ("gauss_filter", "gauss_fit", "locate"),
    ".localization.capture": ("locate_capture",),
    ".localization.estimate": ("Estimate", "LocatedTarget", "Location"),
    ".localization.filter": ("GaussFilter",),
    ".localization.locator": ("Locator",),
    ".localization.paper": ("PaperArgmax",),
    ".physics.trajectory": ("MovingTarget", "Trajectory"),
    ".io.ytal.reading": ("read_sequence",),
    ".io.ytal.sequence": ("write_sequence",),
    ".simulation.sequence": ("simulate_sequence",),
    ".localization.background": ("BackgroundRemover", "subtract_background"),
    ".tracking": ("Tracker",),
    ".tracking.sequences": ("track_sequence",),
    ".sweep": ("sweep",),
}
# Modules that lived at the top level before the layer folders (nl.runtime, `from nlos_cl
# import layouts`): still reachable under their old names.
_MOVED = {"constants": ".core.constants", "errors": ".core.errors", "erf": ".core.erf",
          "geometry": ".core.geometry", "grid": ".core.grid", "paths": ".core.paths",
          "histograms": ".core.histograms", "scene": ".physics.scene",
          "meshes": ".physics.meshes", "reflectance": ".physics.reflectance",
          "visibility": ".physics.visibility", "layouts": ".physics.layouts",
          "noise": ".physics.noise", "devices": ".device.devices", "runtime": ".device.runtime",
          "backend": ".ops.backend", "signals": ".ops.signals", "capture": ".io.ytal.capture",
          "scenefile": ".io.scenefile", "search": ".localization.search",
          "model": ".localization.model"}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
__all__ = sorted(_WHERE)
__version__ = "0.1.0"


def __getattr__(name):
    module = _WHERE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
    elif name in _MOVED:
        value = importlib.import_module(_MOVED[name], __name__)
    else:  # a submodule: nl.core, nl.tracking, ...
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
