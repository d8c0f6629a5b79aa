"""Working with measured histograms: path calibration (paper Eq. 26) and its CSV of pairs,
background subtraction, a photon-counting detector model (Poisson counts, dark counts, ambient
light, timing jitter, TDC binning) to test with, next to the paper's white Gaussian noise."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .constants import SPEED_OF_LIGHT
from .errors import require
from .histograms import HistogramSet, PathCalibration, TimeAxis

PLANCK = 6.62607015e-34


# ---------------------------------------------------------------------------- calibration

@dataclass(frozen=True)
class CalibrationFit:
    """path = a t + b fitted to (known free-space path, measured peak time) pairs."""

    calibration: PathCalibration
    rmse_m: float
    r2: float
    n_pairs: int

    @property
    def speed_error(self) -> float:
        """Relative deviation of the fitted slope from c (the paper measures 0.67 %)."""
        return self.calibration.a_m_per_s / SPEED_OF_LIGHT - 1.0


def fit_calibration(paths_m, peak_times_s) -> CalibrationFit:
    """Least-squares line path = a t + b (paper Eq. 26: s = 29.7 cm/ns t - 1269.1 cm), with its
    RMSE and coefficient of determination R^2."""
    p = np.asarray(paths_m, dtype=np.float64).reshape(-1)
    t = np.asarray(peak_times_s, dtype=np.float64).reshape(-1)
    require(p.size == t.size, "calibration pairs", f"{p.size} paths but {t.size} times",
            "pass one measured peak time per known path")
    require(p.size >= 3, "calibration pairs", f"only {p.size} pairs",
            "measure the target at 3 or more distances")
    require(bool(np.all(np.isfinite(p)) and np.all(np.isfinite(t))), "calibration pairs",
            "contain NaN or inf", "drop the failed measurements")
    require(float(np.ptp(t)) > 0, "calibration pairs", "all peak times are equal",
            "measure at different distances")
    a, b = np.polyfit(t, p, 1)
    residual = p - (a * t + b)
    total = float(np.sum((p - p.mean()) ** 2))
    r2 = 1.0 - float(np.sum(residual ** 2)) / total if total > 0 else float("nan")
    require(a > 0, "calibration pairs", f"the fitted slope is {a:.4g} m/s (path must grow with "
            "time)", "check that paths and times are paired in the same order")
    _require_speed_of_light(float(a))
    return CalibrationFit(PathCalibration(float(a), [float(b)]),
                          float(np.sqrt(np.mean(residual ** 2))), r2, int(p.size))


# (what the numbers were, paths factor, times factor), simplest first: a slope of c x paths /
# times factor; the first within 1.5x of the fitted slope is named
_UNITS = [("peak times in nanoseconds", 1, 1e9), ("peak times in picoseconds", 1, 1e12),
          ("peak times in microseconds", 1, 1e6), ("paths in centimetres", 100, 1),
          ("paths in millimetres", 1000, 1), ("paths in cm and times in ns", 100, 1e9),
          ("paths in cm and times in ps", 100, 1e12)]


def _require_speed_of_light(a: float) -> None:
    """A slope of path against time is a speed of light (the paper's differs from c by 0.67 %);
    more than 1.5x off is a unit mix-up, not a calibration. Names the likely unit."""
    ratio = a / SPEED_OF_LIGHT
    if 1 / 1.5 <= ratio <= 1.5:
        return
    guess = next((u[0] for u in _UNITS if abs(math.log10(ratio * u[2] / u[1])) < 0.176), None)
    require(False, "calibration pairs", f"the fitted slope is {a:.4g} m/s, {ratio:.3g} x the "
            "speed of light" + (f": likely {guess}" if guess else ""),
            "pass paths in metres and peak times in seconds (e.g. multiply ns by 1e-9)")


def peak_times(histograms: HistogramSet) -> np.ndarray:
    """Time of each histogram's maximum (seconds), refined by a parabola through 3 bins."""
    data = histograms.data
    k = np.clip(np.argmax(data, axis=1), 1, data.shape[1] - 2)
    rows = np.arange(len(data))
    m, c, p = data[rows, k - 1], data[rows, k], data[rows, k + 1]
    curvature = m - 2 * c + p
    offset = np.where(curvature < 0, 0.5 * (m - p) / np.where(curvature < 0, curvature, 1), 0)
    return histograms.time_axis.centres()[k] + np.clip(offset, -0.5, 0.5) * histograms.time_axis.dt_s


def with_calibration(histograms: HistogramSet, calibration: PathCalibration) -> HistogramSet:
    calibration.offsets(histograms.n_detectors)  # one offset, or one per detector
    return replace(histograms, calibration=calibration)


# ---------------------------------------------------------------------------- background

def subtract_background(histograms: HistogramSet, background: HistogramSet, *,
                        negatives: str = "keep", floor: float = 0.0) -> HistogramSet:
    """Signal minus a capture without the target (or a reference frame), bin by bin.

    negatives: 'keep' (default) keeps bins below 0: the filter averages noise on both sides of
    zero and the paper's scoring ignores negatives, while clipping leaves a positive offset the
    model estimator's noise model does not have (nlos_cl.tracking.background says what it did);
    'clip' sets them to 0; 'floor' sets bins below `floor` to `floor`.
    """
    require(negatives in ("clip", "floor", "keep"), "negatives",
            f"must be 'clip', 'floor' or 'keep', got {negatives!r}", "pick one of the three")
    require(background.data.shape == histograms.data.shape, "background",
            f"has shape {background.data.shape}, the signal {histograms.data.shape}",
            "record the background with the same detectors and time axis")
    gap = _path_gap(histograms, background)
    require(gap <= 0, "background.time_axis", f"its bins lie {gap:.3g} m of hidden path away "
            "from the signal's (beyond the float32 precision of the file format)",
            "record both with the same TDC settings and calibration")
    require(bool(np.allclose(background.detector_spots, histograms.detector_spots, rtol=0,
                             atol=1e-5)),
            "background.detector_spots", "differ from the signal's", "use the same spots")
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


# ---------------------------------------------------------------------------- photon counting

@dataclass(frozen=True)
class PhotonCounter:
    """A SPAD/SNSPD with a TDC: what it turns the returned power into.

    Expected counts per bin = (power x bin width / photon energy) x efficiency x pulses
    + (dark count rate + ambient rate) x bin width x pulses; the signal part is blurred by the
    timing jitter (Gaussian, sigma); bins are summed into TDC bins; each TDC bin is Poisson.
    Pile-up and dead time are not modelled (valid while counts per pulse stay << 1).
    """

    n_pulses: float = 80e6  # one second at 80 MHz
    efficiency: float = 0.8
    dark_count_rate_hz: float = 100.0
    ambient_rate_hz: float = 1e4
    jitter_s: float = 30e-12
    tdc_bin_s: float = 50e-12
    wavelength_m: float = 1530e-9

    def __post_init__(self):
        for name in ("n_pulses", "efficiency", "wavelength_m", "tdc_bin_s"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, f"photon_counter.{name}",
                    f"must be positive, got {value}", "pass a positive number")
        require(self.efficiency <= 1, "photon_counter.efficiency",
                f"must be at most 1, got {self.efficiency}", "pass a fraction, e.g. 0.8")
        for name in ("dark_count_rate_hz", "ambient_rate_hz", "jitter_s"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, f"photon_counter.{name}",
                    f"must be >= 0, got {value}", "pass 0 to switch it off")

    def expected_counts(self, histograms: HistogramSet) -> HistogramSet:
        axis = histograms.time_axis
        ratio = self.tdc_bin_s / axis.dt_s
        group = int(round(ratio))
        require(group >= 1 and abs(ratio - group) < 1e-6 * max(ratio, 1),
                "photon_counter.tdc_bin_s",
                f"{self.tdc_bin_s:.4g} s is not a whole number of the data's {axis.dt_s:.4g} s "
                "bins", "simulate with a bin width that divides the TDC bin")
        photon = PLANCK * SPEED_OF_LIGHT / self.wavelength_m
        signal = np.maximum(histograms.data, 0.0) * axis.dt_s / photon
        if self.jitter_s > 0:
            from scipy.ndimage import gaussian_filter1d
            signal = gaussian_filter1d(signal, self.jitter_s / axis.dt_s, axis=1, mode="constant")
        counts = (signal * self.efficiency
                  + (self.dark_count_rate_hz + self.ambient_rate_hz) * axis.dt_s) * self.n_pulses
        n_tdc = axis.n_bins // group
        counts = counts[:, :n_tdc * group].reshape(len(counts), n_tdc, group).sum(axis=2)
        tdc_axis = TimeAxis(axis.t0_s, axis.dt_s * group, n_tdc)
        return replace(histograms, data=counts, time_axis=tdc_axis, allow_negative=False)

    def counts(self, histograms: HistogramSet, seed: int = 0) -> HistogramSet:
        """Poisson photon counts (float64 array of integers), seeded."""
        require(isinstance(seed, (int, np.integer)) and seed >= 0, "seed",
                f"must be a non-negative integer, got {seed!r}", "pass e.g. 0")
        expected = self.expected_counts(histograms)
        drawn = np.random.default_rng(seed).poisson(expected.data).astype(np.float64)
        return replace(expected, data=drawn)

    def apply(self, signals, seed: int = 0):
        """The noise-model interface (nlos_cl.noise): counts of `signals` (in watts) as Signals
        on the same backend, on the TDC's time axis. Drawn on the host (NumPy's Poisson)."""
        from .signals import upload
        return upload(self.counts(signals.histograms(), seed), signals.backend)


# ---------------------------------------------------------------------------- calibration file

def read_calibration_pairs(path) -> tuple[np.ndarray, np.ndarray]:
    """(paths in m, peak times in s) from a CSV of pairs, one per row: separators ',' ';' tab
    or spaces; a header row and '#' comments are skipped; with ';' separators a decimal comma
    is read as a point; bytes that are not UTF-8 are read as Latin-1 (legacy spreadsheet
    exports), so a header like 'Zeit (µs)' still parses."""
    path = Path(path)
    where = f"calibration file {path}"
    require(path.is_file(), where, "does not exist or is not a file", "pass a CSV of pairs")
    require(path.stat().st_size <= 16 << 20, where, f"is {path.stat().st_size >> 20} MiB, too "
            "large for a list of calibration pairs", "pass a CSV with one row per measurement")
    raw = path.read_bytes()
    require(b"\0" not in raw, where, "is not a text file (it contains NUL bytes)",
            "export the pairs as CSV text")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    rows = []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if line:
            rows.append((number, _split_row(line)))
    require(bool(rows), where, "has no rows", "write one row per measurement: path (m), peak "
            "time (s), e.g. '2.5,5.17e-8'")
    pairs = []
    for i, (number, fields) in enumerate(rows):
        values = [_number(v) for v in fields]
        if i == 0 and None in values:
            continue  # a header row
        require(None not in values, f"{where}: line {number}", f"{fields!r} is not numeric",
                "keep only numbers below the header")
        require(len(values) == 2, f"{where}: line {number}", f"has {len(values)} column(s), "
                "expected 2: known path (m), peak time (s)", "write two numbers per row")
        pairs.append(values)
    require(bool(pairs), where, "has a header but no data rows",
            "add one row per measurement below the header")
    arr = np.array(pairs, dtype=np.float64)
    return arr[:, 0], arr[:, 1]


def _split_row(line: str) -> list[str]:
    if ";" in line:
        return [v.strip().replace(",", ".") for v in line.split(";")]
    if "," in line:
        return [v.strip() for v in line.split(",")]
    return line.split()


def _number(text: str) -> float | None:
    try:
        return float(text.strip().strip('"').strip("'"))
    except ValueError:
        return None
