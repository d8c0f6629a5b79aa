"""`nlos-cl locate F.h5`: nl.locate_capture (nlos_cl/localization/capture.py) with the command's
options, in the capture's own frame: --region is given along the file's axes, and positions,
covariances, truth and the region are reported in them (the JSON's `frame` says which).
Without --region the search region is derived from the capture (nlos_cl.localization.region:
in front of the wall, around every spot, out to what the time window reaches); a coarse
default region is refined around the answer, and an answer on the region's edge warns.
`--map` keeps each final grid's score map as an .npz."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ..io.json_format import covariance_in, covariance_json, rounded, vector_json
from ..localization.posterior import ArgmaxSpread
from .terminal import Elapsed

MANY_HISTOGRAMS = 256  # the paired model fit's cost: seconds below, minutes at 4,096


MAP_META = {"score", "frame", "axes", "units", "estimator", "score_kind"}


def is_map(path) -> bool:
    """A map `locate --map` wrote: an .npz of its arrays (since the frame rides inside: score,
    the three axes and what they mean; before: exactly score, x, y, z), read with
    allow_pickle=False: nothing in the file runs."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return (sorted(data.files) == ["score", "x", "y", "z"]
                    or MAP_META <= set(data.files) and len(data.files) == len(MAP_META) + 3)
    except Exception:  # noqa: BLE001 - anything unreadable is not our map
        return False


def is_map_file(path) -> bool:
    """A map `locate --map` may replace: its .npz, or a figure nlos_cl wrote (the MANIFEST)."""
    return Path(path).suffix.lower() == ".npz" and is_map(path)


def map_arrays(point) -> dict:
    """The final grid's score map along the file's axes (coordinates increasing), the axes
    named as the file's, with the frame, units, estimator and what the score is."""
    from ..io.json_format import INTERNAL
    loc, grid, frame = point.internal, point.grid, point.frame
    if not frame.is_permutation:  # a fitted wall's rotation: the map stays along our axes
        frame = INTERNAL
    m = np.asarray(frame.matrix)
    score = np.asarray(loc.score_map).transpose(2, 1, 0)  # ours (nz, ny, nx) -> [x, y, z]
    order = [int(np.argmax(np.abs(m[:, i]))) for i in range(3)]  # file axis i: ours order[i]
    score = score.transpose(order)
    coords = []
    for i, j in enumerate(order):
        c = m[j, i] * np.asarray(grid.axes()[j], dtype=np.float64)
        if c.size > 1 and c[0] > c[-1]:
            score, c = np.flip(score, axis=i), c[::-1]
        coords.append(c)
    kind = ("log of the joint likelihood (the sum of each detector's log)" if point.log_mode
            else "joint likelihood (the product of each detector's)")
    return {"score": np.ascontiguousarray(score), **dict(zip(frame.axes, coords)),
            "frame": json.dumps(point.frame.as_json()), "axes": np.array(frame.axes),
            "units": "m (axes); score: " + kind.split(" (")[0], "estimator": loc.estimator,
            "score_kind": kind + f", indexed [{', '.join(frame.axes)}]"}


def _map_path(args, i, n_sets) -> Path:
    out = Path(args.map)
    return out if n_sets == 1 else out.with_suffix(f".{i}{out.suffix}")


def _save_map(args, i, n_sets, point, entry, hist):
    from ..io.safe_write import atomic_write
    out, arrays = _map_path(args, i, n_sets), map_arrays(point)
    if out.suffix.lower() == ".png":
        from .plotting import map_figure, write_figure
        view = map_view(arrays, point, entry, hist)
        write_figure(out, lambda fh: map_figure(fh, view), what="--map", force=args.force)
        return str(out)

    def write(tmp):
        with open(tmp, "wb") as fh:  # a file object: savez would append .npz to a name
            np.savez_compressed(fh, **arrays)
    atomic_write(out, write, keep_unless=is_map, force=args.force, what="--map",
                 kind="a map nlos-cl locate wrote")
    return str(out)


def map_view(arrays, point, entry, hist) -> dict:
    """What the --map figure draws, seen from above: the map's maximum over the height axis
    (relative to its peak, in log), the wall, the spots, the truths and each target with its
    covariance, along the file's lateral and depth axes (ours x and y)."""
    from ..io.json_format import INTERNAL, entry_internal
    frame = point.frame
    if not frame.is_permutation:  # the map is along our axes (map_arrays): so is the figure
        entry, frame = entry_internal(entry, frame), INTERNAL
    m = np.asarray(frame.matrix)
    lat, dep, up = (int(np.argmax(np.abs(m[j]))) for j in range(3))  # file index of ours j
    score = np.asarray(arrays["score"], dtype=np.float64)
    peak = score.max()
    rel = score - peak if point.log_mode else np.log(np.maximum(score, 1e-300) / max(peak, 1e-300))
    image = rel.max(axis=up)  # the two axes left, in the file's order
    image = image.T if lat < dep else image  # rows along depth, columns lateral

    def two(points):
        p = np.atleast_2d(frame.from_internal(np.asarray(points, dtype=np.float64)))
        return p[:, [lat, dep]]

    def cov2(t):
        if t["covariance"] is None:
            return None
        c = np.array([[np.inf if v is None else v for v in row] for row in t["covariance"]])
        return c[np.ix_([lat, dep], [lat, dep])]
    truths = entry.get("truths") or ([entry["truth"]] if entry.get("truth") else [])
    return {"image": np.maximum(image, -30.0), "lateral": arrays[frame.axes[lat]],
            "depth": arrays[frame.axes[dep]], "labels": [frame.axes[k] for k in (lat, dep, up)],
            "spots": two(hist.detector_spots), "lasers": two(hist.laser_spots),
            "truths": np.asarray(truths, dtype=np.float64).reshape(-1, 3)[:, [lat, dep]],
            "targets": [(np.asarray(t["position"])[[lat, dep]], cov2(t))
                        for t in entry.get("targets", [])],
            "title": f"laser point {point.laser_point}: {point.location.estimator} estimator, "
                     f"score map (max over {frame.axes[up]}), {frame.name} frame"}


def _check_map_path(args) -> None:
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
        import math

        from ..core.limits import require_memory
        cells = math.prod(math.floor(abs(hi - lo) / args.step) + 1
                          for lo, hi in zip(args.region[::2], args.region[1::2]))
        # scored on the device (4 B a cell), read back as float64 (8 B) and compressed
        require_memory("--region", 12.0 * cells, f"--map of {cells:.3g} cells", "a smaller "
                       "--region or a larger --step (or leave --map out: the search alone "
                       "need not score every cell)")


NO_TARGET_STATUS = 3  # `nlos-cl locate`: no laser point held target signal


def _estimator(args, sets):
    """(estimator, note): --estimator, or with --reflectance the model fit that knows it
    (estimators' choose_estimator, the policy locate_capture applies); the paper's argmax, by
    name or as the paired default, with its likelihood's spread as its covariance."""
    from ..localization.estimators import choose_estimator
    from .cli_types import OPTION_FLAGS
    paired = any(h.paired for h in sets)
    if args.reflectance is None and (args.estimator == "paper" or args.estimator is None
                                     and paired):
        return ArgmaxSpread(), None if args.estimator else _paired_note(
            max(h.n_detectors for h in sets))
    if args.reflectance is None:
        return args.estimator, None
    return choose_estimator(args.estimator, targets=args.targets or 1,
                            reflectance=args.reflectance,
                            names=OPTION_FLAGS)[0], None


def _truths(hist):
    """Every target's centre the capture holds (ours), or None."""
    if hist.truths is not None:
        return np.asarray(hist.truths)
    return None if hist.truth is None else np.asarray(hist.truth).reshape(1, 3)


def matched(positions, truths) -> list:
    """Per found target, the index of the truth assigned to it (linear assignment on distance),
    or None where there are more targets than truths."""
    from scipy.optimize import linear_sum_assignment
    out = [None] * len(positions)
    if truths is None or not len(positions):
        return out
    dist = np.linalg.norm(np.asarray(positions)[:, None] - np.asarray(truths)[None], axis=2)
    for r, c in zip(*linear_sum_assignment(dist)):
        out[r] = int(c)
    return out


def _held(cov, grid):
    """The covariance (ours) with an infinite variance along every axis the search grid holds
    at one cell (a flat region: collinear wall spots, or --region so given): the answer's
    coordinate there was held, not measured, whatever spread the estimator reports."""
    if cov is None:
        return None
    cov = np.array(cov, dtype=np.float64)
    for j, n in enumerate(grid.shape):
        if n == 1:
            cov[j, :] = cov[:, j] = 0.0
            cov[j, j] = np.inf
    return cov


def target_json(t, frame, truth, grid) -> dict:
    """One target as the JSON gives it: position, covariance, each axis's 1-sigma (None and
    named in `unobservable` where the data hold no information on it), extent, shape, and its
    own truth and error."""
    own = _held(t.covariance, grid)
    cov = covariance_in(own, frame)
    var = np.full(3, np.inf) if cov is None else np.diag(cov)
    fit = t.fit
    out = {"position": vector_json(t.position, frame),
           "covariance": covariance_json(own, frame),
           "sd_m": [round(float(np.sqrt(v)), 5) if np.isfinite(v) else None for v in var],
           "unobservable": [a for a, v in zip(frame.axes, var) if not np.isfinite(v)],
           "extent_m": None if t.extent_m is None else rounded(t.extent_m),
           "shape": None if fit is None else fit.model,
           "truth": None if truth is None else vector_json(truth, frame),
           "error_m": None if truth is None else
           round(float(np.linalg.norm(np.asarray(t.position) - truth)), 5)}
    if cov is None:
        out["uncertainty"] = "the estimator gives no covariance"
    elif out["unobservable"]:
        out["uncertainty"] = (", ".join(out["unobservable"]) + " held, not measured: the "
                              "wall spots (or the search region) give no information along it")
    return out


def targets_json(point, truths) -> dict:
    """The point's targets, each matched to its own truth; `truth` and `error_m` the first
    target's (against its nearest truth where none was assigned to it)."""
    loc, frame = point.internal, point.frame
    if not loc.targets:
        return {"truths": None if truths is None else [vector_json(t, frame) for t in truths]}
    assigned = matched([t.position for t in loc.targets], truths)
    targets = [target_json(t, frame, None if k is None else truths[k], point.grid)
               for t, k in zip(loc.targets, assigned)]
    out = {"targets": targets, "truths": None if truths is None else
           [vector_json(t, frame) for t in truths]}
    if truths is not None:
        first = truths[assigned[0]] if assigned[0] is not None else truths[np.argmin(
            np.linalg.norm(truths - loc.targets[0].position, axis=1))]
        out["truth"] = vector_json(first, frame)
        out["error_m"] = round(float(np.linalg.norm(loc.targets[0].position - first)), 5)
    return out


def _axis_text(name, value, sd) -> str:
    return f"{name} {value:.4f} " + ("(unobservable)" if sd is None else f"± {sd:.4f}")


def text_lines(r, frame) -> str:
    """One laser point's answer as text: a line, then one line per target."""
    head = f"laser point {r['laser_point']}: "
    if not r["detected"]:
        return head + (f"no target in the search region {_ranges(frame, r['region']['ranges_m'])}"
                       f" (argmax of noise {r['argmax_cell']} m)")
    n = len(r["targets"])
    lines = [head + f"{n} target{'s' * (n != 1)} located by the {r['estimator']} estimator, "
             f"in the file's frame ({frame.name}), m, ± 1 sd:"]
    for i, t in enumerate(r["targets"], 1):
        line = f"  target {i}: " + ", ".join(_axis_text(a, v, sd) for a, v, sd in
                                              zip(frame.axes, t["position"], t["sd_m"]))
        if t["extent_m"] is not None:
            line += "; extent " + " x ".join(f"{v:.3f}" for v in t["extent_m"]) + " m"
        if t["shape"]:
            line += f"; {t['shape']}"
        if t["truth"] is not None:
            line += f"; truth {t['truth']}, error {t['error_m']:.4f} m"
        lines.append(line)
    for s in r.get("shadowed") or []:  # where a second target would return no light
        if s["region_part_m"]:
            lines.append(f"  a target behind target {s['target']}, "
                         f"{_ranges(frame, s['region_part_m'])}, would be hidden from the "
                         "laser spot")
    return "\n".join(lines)


def _ranges(frame, ranges) -> str:
    return ", ".join(f"{a} {lo:.2f} .. {hi:.2f}" for a, (lo, hi) in zip(frame.axes, ranges)) + " m"


def _paired_note(n: int):
    """What the default says on paired and confocal captures, in the command line's spelling
    and with the fit's cost for `n` histograms (measured: 8 confocal histograms 3.6 s against
    the argmax's 1.5 s; a 64 x 64 LCT scan still fitting after 280 s, with no progress bar)."""
    cost = (f"minutes on {n:,} histograms" if n > MANY_HISTOGRAMS else
            f"seconds on {n} histograms")
    return ("paired and confocal captures are located with the paper's argmax by default (the "
            f"model fit is checked on simulations only); pass --estimator model to fit (slower: "
            f"{cost})")


def locate(args) -> int:
    """nl.locate_capture with the command's options; the JSON is its as_json(), each target
    with its uncertainty and its own truth."""
    from dataclasses import replace as replaced

    from ..io.ytal.capture import read_capture_with_frame
    from ..localization.capture import locate_capture
    if args.map:
        _check_map_path(args)
    region = None if args.region is None else list(zip(args.region[::2], args.region[1::2]))
    h_s = None if args.h_ns is None else args.h_ns * 1e-9
    sets, frame = read_capture_with_frame(args.file)  # the sets keep every target's truth
    estimator, note = _estimator(args, sets)
    with Elapsed(f"locating ({getattr(estimator, 'name', estimator or 'model')} estimator)"):
        found = locate_capture(sets, frame=frame, region=region, step_m=args.step, h_s=h_s,
                               pulses=args.pulses, estimator=estimator, targets=args.targets,
                               log_mode=True if args.log else None,
                               background=args.background, negatives=args.negatives,
                               calibration=args.calibration, return_map=bool(args.map),
                               backend=args.device, names=("--region", "--step"))
    found = replaced(found, source=args.file)
    entries = []
    for point, hist in zip(found.points, sets):
        entry = point.as_json()
        entry.update(targets_json(point, _truths(hist)))
        entry["warnings"] = [note] * bool(note) + entry["warnings"]
        if args.map:
            entry["map"] = _save_map(args, point.laser_point, len(found.points), point, entry,
                                     hist)
        entries.append(entry)
        for w in entry["warnings"]:
            print(f"nlos-cl: warning: laser point {point.laser_point}: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(found.as_json(entries)))
    else:
        for r in entries:
            print(text_lines(r, found.frame))
    # exit status 3: no laser point's histograms hold target signal (docs/captures.md)
    return 0 if any(r["detected"] for r in entries) else NO_TARGET_STATUS
