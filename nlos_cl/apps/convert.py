"""`nlos-cl convert SRC --out DST.h5`: a measured dataset as its authors publish it
(nlos_cl.io.datasets) into a y-tal capture that `nlos-cl locate` reads with no other option, or
for a sequence format (consumer-nlos) into a sequence file that `nlos-cl track` reads."""
from __future__ import annotations

import numpy as np

# CLI option -> the readers' keyword (nlos_cl.io.datasets.<format>.read_<format>)
OPTIONS = {"dt_ps": "dt_ps", "t0_ps": "t0_ps", "width": "width_m", "grid_m": "grid_m",
           "transpose": "transpose", "flip": "flip", "gate_bins": "gate_bins", "fps": "fps",
           "crop_bins": "crop_bins", "block": "block"}


def main(args) -> int:
    from ..core.errors import require
    from ..io.datasets import SEQUENCES, detect, options_of, read_dataset
    name = args.format or detect(args.src)
    # not `not in (None, False)`: 0 == False, and --t0-ps 0 or --gate-bins 0 was dropped
    given = {key: value for opt, key in OPTIONS.items()
             if (value := getattr(args, opt, None)) is not None and value is not False}
    extra = sorted(set(given) - options_of(name))
    flag = {key: "--" + opt.replace("_", "-") for opt, key in OPTIONS.items()}
    require(not extra, flag[extra[0]] if extra else "", f"is not an option of the {name} "
            "format", "drop it (`nlos-cl convert --help` says which options each format takes)")
    meta = {"converted_from": str(args.src), "dataset_format": name, "options": given}
    read = read_dataset(args.src, name, **given)
    if name in SEQUENCES:
        return _sequence(args, read, meta)
    from ..io.ytal.capture import write_capture
    h = read
    path = write_capture(args.out, h, metadata=meta, force=args.force)
    print(f"wrote {path}: {name}, {_describe(h)}")
    return 0


def _sequence(args, read, meta) -> int:
    """Write a sequence format's (frames, metadata) with write_sequence: the reader's metadata
    (fps, reference positions, stage truth) beside ours in scene_info."""
    from ..io.ytal.sequence import write_sequence
    frames, extra = read
    path = write_sequence(args.out, frames, fps=extra.get("fps"), metadata={**meta, **extra},
                          force=args.force)
    h = frames[0][1]
    print(f"wrote {path}: {meta['dataset_format']}, {len(frames)} frames at "
          f"{extra.get('fps') or 0:g} Hz, each {_describe(h)}")
    return 0


def _describe(h) -> str:
    kind = "confocal" if h.paired and np.allclose(h.laser_spots, h.detector_spots) else (
        "paired (a laser spot per histogram)" if h.paired else "one laser spot")
    return (f"{h.n_detectors} histograms x {h.time_axis.n_bins} bins of "
            f"{h.time_axis.dt_s * 1e12:g} ps, {kind}")
