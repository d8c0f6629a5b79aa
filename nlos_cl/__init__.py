"""nlos_cl: locate objects hidden around a corner from time-of-flight histograms, with
OpenCL kernels for the photon-flight model, the Gauss filter and ellipse scoring."""
from .capture import read_capture, write_capture
from .errors import DeviceError, InputError
from .histograms import Grid, HistogramSet, PathCalibration, TimeAxis, default_time_axis
from .measured import (CalibrationFit, PhotonCounter, fit_calibration, peak_times,
                       subtract_background, with_calibration)
from .pipeline import (Location, Signals, add_noise, gauss_filter, gauss_fit, locate,
                       resolve_backend, simulate, upload)
from .scene import (SPEED_OF_LIGHT, Facets, Pulse, Scene, Setup, Target, box, load_mesh,
                    paper_scene, paper_setup, rectangle, sphere)

__all__ = [
    "DeviceError", "InputError", "Grid", "HistogramSet", "PathCalibration", "TimeAxis",
    "default_time_axis", "Location", "Signals", "add_noise", "gauss_filter", "gauss_fit",
    "locate", "resolve_backend", "simulate", "upload", "SPEED_OF_LIGHT", "Facets", "Pulse",
    "Scene", "Setup", "Target", "box", "load_mesh", "paper_scene", "paper_setup", "rectangle",
    "sphere", "read_capture", "write_capture", "CalibrationFit", "PhotonCounter",
    "fit_calibration", "peak_times", "subtract_background", "with_calibration",
]
__version__ = "0.1.0"
