"""The trial machinery of `reproduce beyond`: layouts and scenes from beyond.yaml, one noisy
frame located by both estimators (the paper's argmax and the model fit), errors per target
(matched by assignment), and the test of the model's 95 % region."""
from __future__ import annotations

import math
import re
import time
import warnings
from dataclasses import dataclass

import numpy as np

import nlos_cl as nl
from nlos_cl.physics import layouts

from ..common import Settings, load_data, simulate_clean


def config(quick: bool) -> dict:
    """beyond.yaml; with `quick`, its `quick` sections merged over the full ones, key by key."""
    data = load_data("beyond.yaml", __package__)
    over = data.pop("quick", {})
    if quick:
        for key, section in over.items():
            data[key] = {**data[key], **section}
    return data


@dataclass(frozen=True)
class Layout:
    name: str
    label: str
    spots: np.ndarray
    log_mode: bool

    @property
    def height_observable(self) -> bool:
        return layouts.height_observable(nl.paper_setup().laser_spot, self.spots)

    def line(self):
        """(point, unit direction) of the line through the laser spot and every spot, when
        they are collinear (height unobservable); None otherwise."""
        if self.height_observable:
            return None
        laser = nl.paper_setup().laser_spot
        far = self.spots[np.argmax(np.linalg.norm(self.spots - laser, axis=1))]
        return laser, (far - laser) / np.linalg.norm(far - laser)

    def observed(self, point) -> np.ndarray:
        """The point as these spots see it: with collinear spots, rotated about their line onto
        the search plane z = 0 (on the hidden side); otherwise the point itself."""
        line = self.line()
        if line is None:
            return np.asarray(point, float)
        along, rho = _line_coords(point, line)
        side = np.cross([0.0, 0.0, 1.0], line[1])
        side = side / np.linalg.norm(side) * (1.0 if side[1] >= 0 else -1.0)
        return line[0] + along * line[1] + rho * side

    def setup(self) -> nl.Setup:
        return nl.paper_setup(detector_spots=self.spots)


def layout(cfg: dict, name: str) -> Layout:
    spec = cfg["layouts"][name]
    if "circle" in spec:
        spots = layouts.circle(**spec["circle"])
    elif "spad_patch" in spec:
        p = spec["spad_patch"]
        spots = layouts.spad_patch(p["centre"], tuple(p["counts"]), tuple(p["pitch_m"]))
        every = int(spec.get("every", 1))
        nx, nz = p["counts"]
        keep = np.zeros((nx, nz), bool)
        keep[::every, ::every] = True
        spots = spots[keep.ravel()]
    else:
        spots = np.asarray(spec["spots"], dtype=float)
    return Layout(name, spec.get("label", name), spots, bool(spec.get("log_mode", False)))


def plate(s: Settings, size, position, normal=(-1.0, 0.0, 0.0)) -> nl.Target:
    return nl.Target(nl.rectangle(size[0], size[1], centre=tuple(position), normal=tuple(normal),
                                  cell_m=s.facet_m))


def simulate(lay: Layout, s: Settings, targets) -> object:
    """Clean signals of one or more (size, position, normal) targets on a layout."""
    first, *rest = [plate(s, *t) for t in targets]
    scene = nl.Scene(lay.setup(), first, s.facet_m, truth=tuple(targets[0][1]),
                     more_targets=tuple(rest))
    return simulate_clean(scene, s)


def search_grid(s: Settings, z_range=None) -> nl.Grid:
    """The paper's search plane z = 0, or a 3D region over `z_range`."""
    if z_range is None:
        return s.grid()
    return nl.Grid.from_ranges(x=(0.0, 6.0), y=(0.01, 6.0), z=tuple(z_range),
                               step_m=s.grid_step_m)


@dataclass
class Frame:
    """One noisy frame located by both estimators."""

    paper: np.ndarray  # (3,) the argmax
    model: list  # LocatedTargets ([] when the fit failed)
    model_s: float
    notes: list  # warnings and failures, as text


def noisy_frame(clean, seed: int, s: Settings, noise=None):
    noisy = nl.add_noise(clean, s.snr_db, seed, model=noise)
    return noisy, nl.gauss_filter(noisy, s.h_s)


def run_paper(clean, seed, lay: Layout, grid, s: Settings, noise=None) -> np.ndarray:
    _, filtered = noisy_frame(clean, seed, s, noise)
    return np.asarray(nl.locate(filtered, grid, log_mode=lay.log_mode, estimator="paper").position, float)


def run_model(clean, seed, lay: Layout, grid, s: Settings, targets=1, noise=None):
    """(LocatedTargets, seconds, notes) of the model fit; a failure is a note, not a crash."""
    from nlos_cl.localization.model import ModelEstimator
    noisy, filtered = noisy_frame(clean, seed, s, noise)
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            loc = nl.locate(filtered, grid, log_mode=lay.log_mode, raw=noisy,
                            estimator=ModelEstimator(targets=targets, h_s=s.h_s))
            found, notes = list(loc.targets), []
        except Exception as exc:  # reported in the table, the run goes on
            found, notes = [], [f"model failed: {type(exc).__name__}: {str(exc)[:160]}"]
    notes += sorted({_short(w.message) for w in caught})
    return found, time.perf_counter() - start, notes


def _short(message) -> str:
    """A warning as a short note: its first clause, without parentheses."""
    text = re.sub(r"\s*\([^)]*\)", "", str(message).split(":")[0])
    return "model warned: " + text[:80]


def run_frame(clean, seed, lay, grid, s, targets=1, noise=None, model_clean=None,
              model_lay=None) -> Frame:
    """Both estimators on one seed; the model may see another layout's signals (SPAD subset)."""
    paper = run_paper(clean, seed, lay, grid, s, noise)
    found, secs, notes = run_model(model_clean if model_clean is not None else clean, seed,
                                   model_lay or lay, grid, s, targets, noise)
    return Frame(paper, found, secs, notes)


def inside95(target, truth) -> bool | None:
    """Whether `truth` lies in the target's 95 % region: chi-square with as many degrees of
    freedom as observable axes (finite variance)."""
    from ....core.stats import chi2_quantile
    cov = target.covariance
    if cov is None:
        return None
    axes = np.isfinite(np.diag(cov))
    if not axes.any():
        return None
    d = (np.asarray(target.position) - truth)[axes]
    c = np.asarray(cov)[np.ix_(axes, axes)]
    try:
        m2 = float(d @ np.linalg.solve(c, d))
    except np.linalg.LinAlgError:
        return None
    return bool(m2 <= chi2_quantile(0.95, int(axes.sum())))


def match(found, truths) -> list:
    """For each truth, the found target assigned to it (linear assignment on distance); truths
    left over (fewer found) get their nearest found target; None when nothing was found."""
    from scipy.optimize import linear_sum_assignment
    if not found:
        return [None] * len(truths)
    dist = np.array([[np.linalg.norm(f.position - t) for f in found] for t in truths])
    rows, cols = linear_sum_assignment(dist)
    out = [found[int(np.argmin(d))] for d in dist]
    for r, c in zip(rows, cols):
        out[r] = found[c]
    return out


def _line_coords(p, line):
    """(position along the spots' line, distance from it): all that collinear spots observe."""
    origin, u = line
    rel = np.asarray(p, float) - origin
    along = float(rel @ u)
    return along, float(np.linalg.norm(rel - along * u))


def _errors(prefix, pos, truth, line=None) -> dict:
    keys = ("err3d_m", "errxy_m", "dz_m", "errline_m")
    if pos is None:
        return {f"{prefix}_{k}": math.nan for k in keys}
    d = np.asarray(pos, float) - truth
    on_line = math.nan
    if line is not None:
        (a1, r1), (a0, r0) = _line_coords(pos, line), _line_coords(truth, line)
        on_line = math.hypot(a1 - a0, r1 - r0)
    values = (np.linalg.norm(d), np.hypot(d[0], d[1]), abs(d[2]), on_line)
    return {f"{prefix}_{k}": round(float(v), 5) for k, v in zip(keys, values)}


def frame_rows(section, case, lay: Layout, seed, frame: Frame, truths) -> list[dict]:
    """One CSV row per truth: both estimators' errors, the model's time and 95 % test."""
    rows, truths = [], np.atleast_2d(truths)
    for i, (truth, tgt) in enumerate(zip(truths, match(frame.model, truths))):
        details = tgt.details if tgt is not None else {}
        inside = None if tgt is None else inside95(tgt, lay.observed(truth))
        rows.append({
            "section": section, "case": case, "layout": lay.name, "seed": seed, "target": i,
            "truth": " ".join(f"{v:g}" for v in truth),
            **_errors("paper", frame.paper, truth, lay.line()),
            **_errors("model", None if tgt is None else tgt.position, truth, lay.line()),
            "model_s": round(frame.model_s, 3), "found": len(frame.model),
            "inside95": "" if inside is None else inside,
            "birge": round(float(details.get("birge_ratio", math.nan)), 2),
            "notes": "; ".join(frame.notes)})
    return rows
