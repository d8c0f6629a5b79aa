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


def is_map(path) -> bool:
    """A map `locate --map` wrote: an .npz whose arrays are exactly score, x, y, z (read with
    allow_pickle=False: nothing in the file runs)."""
    import numpy as np
    try:
        with np.load(path, allow_pickle=False) as data:
            return sorted(data.files) == ["score", "x", "y", "z"]
    except Exception:  # noqa: BLE001 - anything unreadable is not our map
        return False


def _save_map(args, i, n_sets, loc, grid):
    from pathlib import Path

    import numpy as np

    from ..io.safe_write import atomic_write
    out = Path(args.map) if n_sets == 1 else Path(args.map).with_suffix(f".{i}.npz")
    x, y, z = grid.axes()

    def write(tmp):
        with open(tmp, "wb") as fh:  # a file object: savez would append .npz to a name
            np.savez_compressed(fh, score=loc.score_map, x=x, y=y, z=z)
    atomic_write(out, write, keep_unless=is_map, force=args.force, what="--map",
                 kind="a map nlos-cl locate wrote")
    return str(out)


def _check_map_path(args) -> None:
    """Before any work: --map must be writable (never over a file nlos_cl did not write: an
    .npz of the user's own is kept unless --force)."""
    from ..io.safe_write import require_writable
    require_writable(args.map, keep_unless=is_map, force=args.force, what="--map",
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


def _estimator(args):
    """--estimator, or with --reflectance the model fit that knows it (estimators'
    choose_estimator; without one, locate_capture applies the same policy per laser point)."""
    if args.reflectance is None:
        return args.estimator
    from ..localization.estimators import choose_estimator
    from .cli_types import OPTION_FLAGS
    return choose_estimator(args.estimator, targets=args.targets, reflectance=args.reflectance,
                            names=OPTION_FLAGS)[0]


def locate(args) -> int:
    """nl.locate_capture with the command's options; the JSON is its as_json()."""
    from ..localization.capture import locate_capture
    if args.map:
        _check_map_path(args)
    region = None if args.region is None else list(zip(args.region[::2], args.region[1::2]))
    h_s = None if args.h_ns is None else args.h_ns * 1e-9
    found = locate_capture(args.file, region=region, step_m=args.step, h_s=h_s, pulses=args.pulses,
                           estimator=_estimator(args), targets=args.targets,
                           log_mode=True if args.log else None, background=args.background,
                           negatives=args.negatives, calibration=args.calibration,
                           return_map=bool(args.map), backend=args.device,
                           names=("--region", "--step"))
    entries = []
    for point in found.points:
        entry = point.as_json()
        if args.map:
            entry["map"] = _save_map(args, point.laser_point, len(found.points),
                                     point.location, point.grid)
        entries.append(entry)
        for w in point.warnings:
            print(f"nlos-cl: warning: laser point {point.laser_point}: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(found.as_json(entries)))
    else:
        frame = found.frame
        for r in entries:
            print(f"laser point {r['laser_point']}: " + (
                  f"located {r['position']} m in the file's frame ({frame.name})"
                  if r["detected"] else f"no target (argmax of noise {r['argmax_cell']} m)")
                  + (f", truth {r['truth']}, error {r['error_m']:.4f} m" if r["truth"] else ""))
    # exit status 3: no laser point's histograms hold target signal (docs/captures.md)
    return 0 if any(r["detected"] for r in entries) else NO_TARGET_STATUS
