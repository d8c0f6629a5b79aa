"""`Signals`: histograms resident on a backend (an OpenCL buffer, or a NumPy array for the
reference backend) in units of `scale_w` watts, with the `Layout` the next stage needs. Stages
chain on the device; `histograms()` brings them back to the host in watts."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import require
from ..core.histograms import HistogramSet, Layout
from .backend import resolve_backend


@dataclass(frozen=True)
class Signals:
    """Physical value (W) = scale_w * values in `handle`, rows laid out as `layout` says."""

    backend: object
    handle: object
    scale_w: float
    layout: Layout

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
    peak = float(np.max(np.abs(histograms.data)))
    scale = 2.0 ** math.floor(math.log2(peak)) if peak > 0 else 1.0
    return Signals(backend, backend.from_numpy(histograms.data / scale), scale, histograms.layout)


def as_signals(value, backend=None) -> Signals:
    """Signals pass through; host histograms are uploaded."""
    return value if isinstance(value, Signals) else upload(value, backend)
