"""`nlos-cl locate --map F.npz|F.png`: the score maps a researcher keeps, in the capture's frame.

The final grid is where the estimator looked; where the derived region had to be coarsened,
it is a fine zoom around one answer, and a map of it alone shows one target's neighbourhood.
So the whole search region is scored once more for the map (`region_map`): the paper's joint
likelihood, as the search's own coarse pass scores it, at a step giving at most
REGION_MAP_CELLS cells, with at most SEARCH_DETECTORS histograms spread over the wall (the
search's own rule). The .npz keeps both maps (`score` on the final grid, `region_score` on
the region), the .png draws the region with the final grid's map over it, and the final grid
beside it with each estimate's 2-sd ellipse."""
from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.json_format import INTERNAL

# 0.07 s of scoring for 8 histograms on 2 CPU cores (the 3.4 M-cell coarse pass of the
# same region: 0.35 s), 8 MB of float64
REGION_MAP_CELLS = 1_000_000
REGION_MAP_HEIGHT = 16  # heights kept at least (where the region has them) before the plan
MAP_META = {"score", "frame", "axes", "units", "estimator", "score_kind"}


def _map_keys(axes) -> tuple[set, set]:
    """(the keys of a final-grid map, the keys the whole region's map adds)."""
    return (MAP_META | set(axes),
            {"region_score", "region_note"} | {f"region_{a}" for a in axes})


def is_map(path) -> bool:
    """A map `locate --map` wrote: an .npz of its arrays (the final grid's score, its axes and
    what they mean, and since the region map the whole region's too; before the frame rode
    inside: exactly score, x, y, z), read with allow_pickle=False: nothing in the file runs."""
    try:
        with np.load(path, allow_pickle=False) as data:
            files = set(data.files)
            if files == {"score", "x", "y", "z"}:
                return True
            if not MAP_META <= files or data["axes"].shape != (3,):
                return False
            grid, region = _map_keys(str(a) for a in data["axes"])
            return files in (grid, grid | region)
    except Exception:  # noqa: BLE001 - anything unreadable is not our map
        return False


def is_map_file(path) -> bool:
    """A map `locate --map` may replace: its .npz, or a figure nlos_cl wrote (the MANIFEST)."""
    return Path(path).suffix.lower() == ".npz" and is_map(path)


def check_map_path(args) -> None:
    """Before any work: --map must be writable (never over a file nlos_cl did not write: an
    .npz of the user's own is kept unless --force)."""
    from ..core.errors import require
    from ..io.safe_write import require_writable
    suffix = Path(args.map).suffix.lower()
    require(suffix in (".npz", ".png"), "--map", f"{args.map} ends in {suffix or 'no suffix'}: "
            "the map is written by its extension", "name it .npz (the arrays, with frame, "
            "units, axes and estimator) or .png (a labelled figure)")
    require_writable(args.map, keep_unless=is_map_file, force=args.force, what="--map",
                     kind="a map nlos-cl locate wrote")
    if args.region is not None and args.step is not None:  # the map's size is known now
        from ..core.limits import require_memory
        cells = math.prod(math.floor(abs(hi - lo) / args.step) + 1
                          for lo, hi in zip(args.region[::2], args.region[1::2]))
        # scored on the device (4 B a cell), read back as float64 (8 B) and compressed
        require_memory("--region", 12.0 * cells, f"--map of {cells:.3g} cells", "a smaller "
                       "--region or a larger --step (or leave --map out: the search alone "
                       "need not score every cell)")


# ----------------------------------------------------------------------------- the region

@dataclass(frozen=True)
class RegionMap:
    """The whole search region's score map (ours, (nz, ny, nx)) on `grid`, from `used` of the
    point's `total` histograms."""

    score_map: np.ndarray
    grid: object
    used: int
    total: int


def region_maps(args, sets, found) -> list:
    """Per laser point, the whole region's map (RegionMap) where the final grid is a zoom of
    it, else None (the final grid's map is the region's). The capture is processed again as
    locate_capture processed it (the same steps, h and calibration): the maps are the
    answer's own likelihood."""
    if not any(p.zoomed for p in found.points):
        return [None] * len(found.points)
    from ..io.calibration import with_calibration
    from ..localization.capture import measured_processing
    processed, _, _ = measured_processing(
        sets, args.background, negatives=args.negatives, pulses=args.pulses, h_s=found.h_s,
        calibrated=args.calibration is not None, preprocess=True)
    if found.calibration is not None:
        processed = [with_calibration(h, found.calibration) for h in processed]
    return [region_map(p, h, found.h_s, args.device) if p.zoomed else None
            for p, h in zip(found.points, processed)]


def coarse_grid(region, cells: int | None = None):
    """`region` (a Grid) in at most `cells` cells: its own steps where they fit; else fewer
    heights first (ours z: the figure shows the maximum over it; REGION_MAP_HEIGHT at least),
    then a coarser plan on one step. An axis held at one cell stays so."""
    from ..core.grid import Grid
    cells = REGION_MAP_CELLS if cells is None else cells
    spans = [s * (n - 1) for s, n in zip(region.step, region.shape)]
    steps, shape = list(region.step), list(region.shape)
    if math.prod(shape) <= cells:
        return region
    heights = max(min(shape[2], cells // (shape[0] * shape[1])),
                  min(shape[2], REGION_MAP_HEIGHT))
    if heights < shape[2]:
        steps[2], shape[2] = spans[2] / (heights - 1), heights
    plan = [k for k in (0, 1) if shape[k] > 1]
    step = (math.prod(spans[k] for k in plan) * shape[2] / cells) ** (1.0 / max(len(plan), 1))
    while plan and math.prod(shape) > cells:  # a cell more per axis than span / step: 1 % more
        step *= 1.01
        for k in plan:
            steps[k], shape[k] = step, math.floor(spans[k] / step) + 1
    return Grid(region.origin, tuple(steps), tuple(shape))


def region_map(point, hist, h_s, backend) -> RegionMap:
    """The paper's joint likelihood over the point's whole region (coarse_grid), scored as the
    search's coarse pass scores it (the histograms spread over the wall where there are more
    than SEARCH_DETECTORS)."""
    from ..core.geometry import farthest_points
    from ..core.tuning import SEARCH_DETECTORS
    from ..localization.api import gauss_filter, locate
    total = hist.n_detectors
    if total > SEARCH_DETECTORS:
        hist = hist.select(farthest_points(np.hstack([hist.detector_spots, hist.laser_spots]),
                                           SEARCH_DETECTORS))
    grid = coarse_grid(point.region)
    with warnings.catch_warnings():
        # the same likelihood's notes (e.g. a height held) are the answer's, said already
        warnings.simplefilter("ignore")
        loc = locate(gauss_filter(hist, h_s, backend=backend), grid, estimator="paper",
                     log_mode=point.log_mode, return_map=True, detect=False)
    return RegionMap(np.asarray(loc.score_map), grid, hist.n_detectors, total)


# ----------------------------------------------------------------------------- the arrays

def map_frame(point):
    """The frame the maps' axes run along: the file's, or ours where the file's is a fitted
    wall's rotation (a map cannot be rotated without resampling)."""
    return point.frame if point.frame.is_permutation else INTERNAL


def along_file(score_map, grid, frame) -> tuple[np.ndarray, list]:
    """A score map of ours ((nz, ny, nx)) indexed along `frame`'s axes (a signed permutation of
    ours), each axis's coordinates increasing: (score, [coordinates per file axis])."""
    m, origin = np.asarray(frame.matrix), np.asarray(frame.origin)
    score = np.asarray(score_map).transpose(2, 1, 0)  # ours (nz, ny, nx) -> [x, y, z]
    order = [int(np.argmax(np.abs(m[:, i]))) for i in range(3)]  # file axis i: ours order[i]
    score = score.transpose(order)
    coords = []
    for i, j in enumerate(order):
        c = m[j, i] * np.asarray(grid.axes()[j], dtype=np.float64) + origin[i]
        if c.size > 1 and c[0] > c[-1]:
            score, c = np.flip(score, axis=i), c[::-1]
        coords.append(c)
    return np.ascontiguousarray(score), coords


def along_file_steps(grid, frame) -> list:
    """The grid's steps (ours) along `frame`'s axes (a signed permutation of ours)."""
    m = np.asarray(frame.matrix)
    return [grid.step[int(np.argmax(np.abs(m[:, i])))] for i in range(3)]


def map_arrays(point, region: RegionMap | None = None) -> dict:
    """The final grid's score map along the file's axes (coordinates increasing), the axes
    named as the file's, with the frame, units, estimator and what the score is; and where
    the final grid is a zoom, the whole region's map as region_score and region_<axis>."""
    frame = map_frame(point)
    score, coords = along_file(point.internal.score_map, point.grid, frame)
    kind = ("log of the joint likelihood (the sum of each detector's log)" if point.log_mode
            else "joint likelihood (the product of each detector's)")
    out = {"score": score, **dict(zip(frame.axes, coords)),
           "frame": json.dumps(frame.as_json()), "axes": np.array(frame.axes),
           "units": "m (axes); score: " + kind.split(" (")[0], "estimator": point.internal.estimator,
           "score_kind": kind + f", indexed [{', '.join(frame.axes)}]"}
    if region is not None:
        r_score, r_coords = along_file(region.score_map, region.grid, frame)
        steps = ", ".join(f"{a} {s:.3g}" for a, s in
                          zip(frame.axes, along_file_steps(region.grid, frame)))
        out.update({"region_score": r_score,
                    **{f"region_{a}": c for a, c in zip(frame.axes, r_coords)},
                    "region_note": f"the whole search region at steps {steps} m, scored "
                    f"for the map with {region.used} of {region.total} histograms (the paper's"
                    " likelihood, as the search's coarse pass); `score` is the final grid's"})
    return out


# ----------------------------------------------------------------------------- the figure

def save_map(args, out: Path, point, entry, hist, region: RegionMap | None) -> str:
    """The map written by its extension: a figure (.png) or the arrays (.npz), atomically."""
    from ..io.safe_write import atomic_write
    arrays = map_arrays(point, region)
    if out.suffix.lower() == ".png":
        from .plotting import map_figure, write_figure
        view = map_view(arrays, point, entry, hist, region)
        write_figure(out, lambda fh: map_figure(fh, view), what="--map", force=args.force)
        return str(out)

    def write(tmp):
        with open(tmp, "wb") as fh:  # a file object: savez would append .npz to a name
            np.savez_compressed(fh, **arrays)
    atomic_write(out, write, keep_unless=is_map, force=args.force, what="--map",
                 kind="a map nlos-cl locate wrote")
    return str(out)


def _plan(score, axes, lat, dep, up, peak, log_mode) -> dict:
    """A map seen from above: its maximum over the height axis relative to `peak` (in log),
    rows along depth and columns lateral, floored at -30."""
    score = np.asarray(score, dtype=np.float64)
    rel = score - peak if log_mode else np.log(np.maximum(score, 1e-300) / max(peak, 1e-300))
    image = rel.max(axis=up)  # the two axes left, in the file's order
    image = image.T if lat < dep else image
    return {"image": np.maximum(image, -30.0), "lateral": axes[lat], "depth": axes[dep]}


def map_view(arrays, point, entry, hist, region: RegionMap | None = None) -> dict:
    """What the --map figure draws, seen from above: the whole region's map (where the final
    grid is a zoom of it) with the final grid's over it, and the final grid alone; the wall,
    the spots, the truths and each target with its covariance, along the file's lateral and
    depth axes (ours x and y). Both maps are relative to one peak where they score the same
    histograms (they compare), else each to its own."""
    from ..io.json_format import entry_internal
    frame = map_frame(point)
    if frame is not point.frame:  # the maps are along our axes (map_frame): so is the figure
        entry = entry_internal(entry, point.frame)
    m = np.asarray(frame.matrix)
    lat, dep, up = (int(np.argmax(np.abs(m[j]))) for j in range(3))  # file index of ours j
    fine_peak = float(np.max(arrays["score"]))
    same = region is not None and region.used == region.total
    peak = max(fine_peak, float(np.max(arrays["region_score"]))) if same else fine_peak
    fine = _plan(arrays["score"], [arrays[a] for a in frame.axes], lat, dep, up, peak,
                 point.log_mode)
    step = f"step {min(point.grid.step) * 100:.3g} cm"
    panels = [fine | {"title": f"the final grid ({step})" if region is not None else
                      f"the search region ({step}: the final grid)"}]
    if region is not None:
        whole = _plan(arrays["region_score"], [arrays[f"region_{a}"] for a in frame.axes], lat,
                      dep, up, float(np.max(arrays["region_score"])) if not same else peak,
                      point.log_mode)
        panels.insert(0, whole | {"title": "the whole search region, the final grid outlined",
                                  "inset": fine})

    def two(points):
        p = np.atleast_2d(frame.from_internal(np.asarray(points, dtype=np.float64)))
        return p[:, [lat, dep]]

    def cov2(t):
        if t.get("covariance") is None:
            return None
        c = np.array([[np.inf if v is None else v for v in row] for row in t["covariance"]])
        return c[np.ix_([lat, dep], [lat, dep])]
    truths = entry.get("truths") or ([entry["truth"]] if entry.get("truth") else [])
    return {"panels": panels, "labels": [frame.axes[k] for k in (lat, dep, up)],
            "spots": two(hist.detector_spots), "lasers": two(hist.laser_spots),
            "truths": np.asarray(truths, dtype=np.float64).reshape(-1, 3)[:, [lat, dep]],
            "targets": [(np.asarray(t["position"])[[lat, dep]], cov2(t))
                        for t in entry.get("targets", [])],
            "relative": "one peak" if same or region is None else "each map's own peak",
            "title": f"laser point {point.laser_point}: {point.internal.estimator} estimator, "
                     f"{_count(len(entry.get('targets', [])))}; the paper's likelihood (max over"
                     f" {frame.axes[up]}), in the {frame.name} frame"}


def _count(n: int) -> str:
    return f"{n} target{'s' * (n != 1)}"
