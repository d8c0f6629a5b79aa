"""Path calibration from measured histograms (paper Eq. 26): peak times, the least-squares fit
of hidden path against time, and the CSV of (path, peak time) pairs a lab records."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.errors import require
from ..core.histograms import HistogramSet, PathCalibration


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
            bad = next(v for v, x in zip(fields, values) if x is None)
            numeric = any(x is not None or _NUMBER_START.match(v.strip("\"'"))
                          for v, x in zip(fields, values))
            require(not numeric, f"{where}: line {number}", f"{bad[:40]!r} is not a number, yet the "
                    f"row {_shown(fields)} holds numbers, so it is a mistyped measurement, not a "
                    "header (a header holds only words)", "correct the number, or write the "
                    "header in words")
            continue  # a header row: words only
        require(None not in values, f"{where}: line {number}", f"{_shown(fields)} is not numeric",
                "keep only numbers below the header")
        require(len(values) == 2, f"{where}: line {number}", f"has {len(values)} column(s), "
                "expected 2: known path (m), peak time (s)", "write two numbers per row")
        pairs.append(values)
    require(bool(pairs), where, "has a header but no data rows",
            "add one row per measurement below the header")
    arr = np.array(pairs, dtype=np.float64)
    return arr[:, 0], arr[:, 1]


def _shown(fields) -> str:
    """A row as an error message shows it: one short line, whatever the file holds."""
    text = repr(fields)
    return text if len(text) <= 80 else text[:77] + "..."


_NUMBER_START = re.compile(r"[-+]?(\d|\.\d)")


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
