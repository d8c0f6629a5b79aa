"""`Signals`: histograms resident on a backend (an OpenCL buffer, or a NumPy array for the
reference backend) in units of `scale_w` watts, with the `Layout` the next stage needs. Stages
chain on the device; `histograms()` brings them back to the host in watts."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import require
from ..core.histograms import HistogramSet, Layout
from .backend import NumpyBackend, read_values, resolve_backend


@dataclass(frozen=True)
class Signals:
    """Physical value (W) = scale_w * values in `handle`, rows laid out as `layout` says.
    host: the float32 host array an upload copied to the device (the same values), kept so that
    reading them costs nothing (`values`); None for a stage's output. filtered_h_s: the Gauss
    filter's window where they are its output (a later stage's output has none)."""

    backend: object
    handle: object
    scale_w: float
    layout: Layout
    host: np.ndarray | None = field(default=None, compare=False, repr=False)
    # the Gauss filter's window (s) where these are its output (localization.filter), else
    # None: nl.locate then checks that they are not the histograms themselves
    filtered_h_s: float | None = field(default=None, compare=False, repr=False)

    @property
    def n_detectors(self) -> int:
        return self.layout.n_detectors

    @property
    def shape(self) -> tuple[int, int]:
        return self.layout.shape

    def histograms(self) -> HistogramSet:
        """Read back to the host, in watts."""
        return HistogramSet.from_layout(self.backend.to_numpy(self.handle) * self.scale_w,
                                        self.layout)

    def values(self) -> np.ndarray:
        """The values on the host as stored, for reading only: the upload's own copy, or read
        from the backend (ops.backend.read_values). A 1,024 x 60,000-bin SPAD record uploaded
        and read back for the detection and the model fit cost 0.1-0.4 s, most of it the new
        array's page faults."""
        return self.host if self.host is not None else read_values(self.backend, self.handle)

    def derive(self, handle, scale_w=None) -> "Signals":
        """The same layout with new values (a later stage's output)."""
        return Signals(self.backend, handle, self.scale_w if scale_w is None else scale_w,
                       self.layout)

    def with_histograms(self, histograms: HistogramSet) -> "Signals":
        """Host histograms (a noise model's draw, say) as Signals on this backend."""
        return upload(histograms, self.backend)


def upload(histograms: HistogramSet, backend=None) -> Signals:
    """Put host histograms on a backend, normalised so that float32 neither under- nor
    overflows (measured powers are ~1e-20 W). The scale is a power of two, so scaling is exact:
    photon counts come back as the integers they were."""
    require(isinstance(histograms, HistogramSet), "histograms",
            f"expected a nlos_cl.HistogramSet, got {type(histograms).__name__}",
            "wrap your array: HistogramSet(data, time_axis, detector_spots, laser_spot, calibration)")
    backend = resolve_backend(backend)
    data = histograms.data
    peak = float(np.max(np.abs(data)))
    scale = 2.0 ** math.floor(math.log2(peak)) if peak > 0 else 1.0
    if isinstance(backend, NumpyBackend):  # the float64 twins: their own copy, unrounded
        return Signals(backend, backend.from_numpy(data / scale), scale, histograms.layout)
    # a device stores float32: divided in float64 and rounded once, without a float64
    # temporary; the host copy kept (Signals.values)
    values = np.divide(data, scale, out=np.empty(data.shape, np.float32), casting="same_kind")
    values.flags.writeable = False  # it must stay what the device holds
    return Signals(backend, backend.from_numpy(values), scale, histograms.layout, values)


def as_signals(value, backend=None) -> Signals:
    """Signals pass through; host histograms are uploaded."""
    return value if isinstance(value, Signals) else upload(value, backend)
