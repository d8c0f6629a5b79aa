"""`nlos-cl locate F.h5`: nl.locate_capture (nlos_cl/localization/capture.py) with the command's
options, in the capture's own frame: --region is given along the file's axes, and positions,
covariances, truth and the region are reported in them (the JSON's `frame` says which).
Without --region the search region is derived from the capture (nlos_cl.localization.region:
in front of the wall, around every spot, out to what the time window reaches); a coarse
default region is refined around the answer, and an answer on the region's edge warns.
`--map` keeps the score maps, the whole search region's and the final grid's, as arrays (.npz)
or a figure (.png): apps/locate_map.py."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ..io.json_format import covariance_in, covariance_json, rounded, vector_json
from ..localization.posterior import ArgmaxSpread
from .locate_map import check_map_path, region_maps, save_map
from .terminal import Elapsed

MANY_HISTOGRAMS = 256  # the paired model fit's cost: seconds below, minutes at 4,096


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
           "reflectance": _reflectance(fit),
           "truth": None if truth is None else vector_json(truth, frame),
           "error_m": None if truth is None else
           round(float(np.linalg.norm(np.asarray(t.position) - truth)), 5)}
    if cov is None:
        out["uncertainty"] = "the estimator gives no covariance"
    elif out["unobservable"]:
        out["uncertainty"] = (", ".join(out["unobservable"]) + " held, not measured: the "
                              "wall spots (or the search region) give no information along it")
    return out


def _reflectance(fit):
    """The GGX lobe the fit chose by evidence (model.policy.lobe: roughness, diffuse share of
    the albedo), or None: no fit, or the reflectance told (Lambertian unless --reflectance)."""
    lobe = {} if fit is None else (fit.diagnostics or {}).get("reflectance") or {}
    if lobe.get("model") != "ggx":
        return None
    return {"model": "ggx", "roughness": lobe["roughness"],
            "diffuse_share": lobe["diffuse_share"], "chosen_by": "evidence"}


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
        if isinstance(t.get("reflectance"), dict):
            lobe = t["reflectance"]
            line += (f", glossy (GGX lobe of roughness {lobe['roughness']:.2f}, diffuse "
                     f"{100 * lobe['diffuse_share']:.0f} %)")
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
        check_map_path(args)
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
    entries, n = [], len(found.points)
    regions = region_maps(args, sets, found) if args.map else [None] * n
    for point, hist, region in zip(found.points, sets, regions):
        entry = point.as_json()
        entry.update(targets_json(point, _truths(hist)))
        entry["warnings"] = [note] * bool(note) + entry["warnings"]
        if args.map:
            out = Path(args.map)
            out = out if n == 1 else out.with_suffix(f".{point.laser_point}{out.suffix}")
            entry["map"] = save_map(args, out, point, entry, hist, region)
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
