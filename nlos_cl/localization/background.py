"""Background removal: `subtract_background` for one measured capture (a target-free capture of
the same layout, on the host, with the checks that the two were taken alike), and
`BackgroundRemover` for frame streams, on the device (the registered "subtract_background"
operation), as in Gariepy et al.'s pipeline.

`BackgroundRemover(reference)` subtracts a fixed, target-free capture (what static clutter and
the wall return without the target); `BackgroundRemover(alpha=0.05)` subtracts an exponential
running mean of the past frames, updated in place on the device after each frame (b <- b +
alpha (frame - b)): static clutter is learnt, a moving target is not (it stays ~1/alpha frames
in one place at most). In running mode the first frame only starts the mean: its output is zero.
Negatives are kept by default (clip=False): the Gauss filter averages the noise on both sides of
zero and the paper's scoring ignores negative values, while clipping would leave a positive
offset that no estimator's noise model has. The model estimator fits it as a deep closed
shape: on the tracking notebook's person-sized box the clipped frames gave centres 0.36-0.73 m
behind the target."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..core.errors import require
from ..core.histograms import HistogramSet


def subtract_background(histograms: HistogramSet, background: HistogramSet, *,
                        negatives: str = "keep", floor: float = 0.0) -> HistogramSet:
    """Signal minus a capture without the target (or a reference frame), bin by bin.

    negatives: 'keep' (default) keeps bins below 0: the filter averages noise on both sides of
    zero and the paper's scoring ignores negatives, while clipping leaves a positive offset the
    model estimator's noise model does not have (BackgroundRemover below says what it did);
    'clip' sets them to 0; 'floor' sets bins below `floor` to `floor`.
    """
    require(negatives in ("clip", "floor", "keep"), "negatives",
            f"must be 'clip', 'floor' or 'keep', got {negatives!r}", "pick one of the three")
    require_alike(histograms, background)
    require(not np.array_equal(background.data, histograms.data), "background",
            "is the signal itself (equal in every bin), so nothing would be left",
            "pass the capture recorded without the target")
    diff = histograms.data - background.data
    require(bool(np.any(diff > 0)), "background", "is at least as strong as the signal in every "
            "bin, so nothing would be left", "pass the capture recorded without the target "
            "(and check that signal and background are not swapped)")
    if negatives == "clip":
        diff = np.maximum(diff, 0.0)
    elif negatives == "floor":
        diff = np.maximum(diff, floor)
    return replace(histograms, data=diff, allow_negative=True)


def require_alike(signal: HistogramSet, background: HistogramSet) -> None:
    """A background taken as the signal was: the same shape, time axis (hidden path per bin),
    detector spots and laser spot(s), so the pairing too (`track --background`
    checked the shape alone, `locate --background` not the laser spots: 5.8 m off)."""
    require(background.data.shape == signal.data.shape, "background",
            f"has shape {background.data.shape}, the signal {signal.data.shape}",
            "record the background with the same detectors and time axis")
    gap = _path_gap(signal, background)
    require(gap <= 0, "background.time_axis", f"its bins lie {gap:.3g} m of hidden path away "
            "from the signal's (beyond the float32 precision of the file format)",
            "record both with the same TDC settings and calibration")
    require(bool(np.allclose(background.detector_spots, signal.detector_spots, rtol=0,
                             atol=1e-5)),
            "background.detector_spots", "differ from the signal's", "use the same spots")
    require(background.laser_spots.shape == signal.laser_spots.shape and bool(np.allclose(
            background.laser_spots, signal.laser_spots, rtol=0, atol=1e-5)),
            "background.laser_spot", "differs from the signal's (another laser point, or "
            "another pairing)", "record the background with the same laser point(s)")


def _path_gap(signal: HistogramSet, background: HistogramSet) -> float:
    """How far (m of hidden path) the two sets' first and last bin centres differ beyond what
    float32 files can resolve: 1 % of a bin plus 4 float32 steps of the larger of 64 m (t_start
    with the device legs is ~40 m) and the paths themselves. <= 0: the same bins."""
    def ends(h):  # the hidden path at the first and last bin centres, per detector
        axis = h.path_axis()
        return np.stack([axis.centre0_m, axis.centre0_m + (axis.n_bins - 1) * axis.step_m], 1)
    p, q = ends(signal), ends(background)
    bin_m = signal.calibration.a_m_per_s * signal.time_axis.dt_s
    scale = max(64.0, float(np.abs(p).max()), float(np.abs(q).max()))
    tol = 0.01 * bin_m + 4 * float(np.finfo(np.float32).eps) * scale
    return float(np.abs(p - q).max()) - tol


class BackgroundRemover:
    """`remover(signals) -> Signals` (the same backend, in the background's units)."""

    def __init__(self, reference=None, *, alpha: float = 0.05, clip: bool = False,
                 backend=None):
        require(isinstance(alpha, (int, float)) and not isinstance(alpha, bool)
                and math.isfinite(alpha) and 0 < alpha <= 1, "alpha", "the running mean's "
                f"weight of a new frame must be in (0, 1], got {alpha!r}", "pass e.g. 0.05")
        self.alpha = 0.0 if reference is not None else float(alpha)
        self.clip, self.backend = bool(clip), backend
        self._bg, self._scale, self._shape = None, None, None
        self.frames_seen = 0
        if reference is not None:
            from ..ops.signals import as_signals
            ref = as_signals(reference, backend)
            self.backend = ref.backend
            # our own copy: the caller's buffer must not be aliased
            self._bg = ref.backend.from_numpy(ref.backend.to_numpy(ref.handle))
            self._scale, self._shape = ref.scale_w, ref.shape

    @property
    def mode(self) -> str:
        return "running mean" if self.alpha > 0 else "fixed reference"

    def background(self):
        """The current background on the host, as a HistogramSet-compatible array in W."""
        if self._bg is None:
            return None
        return self.backend_of().to_numpy(self._bg) * self._scale

    def backend_of(self):
        from ..ops.backend import resolve_backend
        return resolve_backend(self.backend)

    def __call__(self, signals):
        from ..ops.signals import as_signals
        sig = as_signals(signals, self.backend)
        be = sig.backend
        if self._shape is not None:
            require(sig.shape == self._shape, "frame", f"shape {sig.shape} differs from the "
                    f"background's {self._shape}", "record the background with the same "
                    "detectors and time axis")
        self.frames_seen += 1
        if self._bg is None:  # running mean: the first frame starts it
            self.backend = be
            self._bg = be.from_numpy(be.to_numpy(sig.handle))
            self._scale, self._shape = sig.scale_w, sig.shape
        frame = sig.handle
        if sig.scale_w != self._scale:  # into the background's units (exact: powers of two)
            frame = frame * (sig.scale_w / self._scale)
        out, self._bg = be.call("subtract_background", frame, self._bg, self.alpha, self.clip)
        return sig.derive(out, scale_w=self._scale)
