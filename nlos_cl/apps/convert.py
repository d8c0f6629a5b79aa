"""`nlos-cl convert SRC --out DST.h5`: a measured dataset as its authors publish it
(nlos_cl.io.datasets) into a y-tal capture that `nlos-cl locate` reads with no other option, or
for a sequence format (consumer-nlos) into a sequence file that `nlos-cl track` reads."""
from __future__ import annotations

from .cli_types import MAX_FPS, MIN_FPS, number as _number  # cli imports this: no NumPy here

# CLI option -> the readers' keyword (nlos_cl.io.datasets.<format>.read_<format>)
OPTIONS = {"dt_ps": "dt_ps", "t0_ps": "t0_ps", "width": "width_m", "grid_m": "grid_m",
           "transpose": "transpose", "flip": "flip", "gate_bins": "gate_bins", "fps": "fps",
           "crop_bins": "crop_bins", "block": "block", "static": "static"}


def main(args) -> int:
    """Convert, or on Ctrl-C say so in one line and exit 130 (the shell's code for SIGINT):
    the output is written atomically, so an interrupt leaves no part of it."""
    import sys
    try:
        return _convert(args)
    except KeyboardInterrupt:
        print(f"nlos-cl: convert {args.src}: interrupted (Ctrl-C); nothing was written to "
              f"{args.out}. Fix: run the command again to convert it", file=sys.stderr)
        return 130


def _convert(args) -> int:
    from ..core.errors import require
    from ..io.datasets import detect, options_of, read_dataset
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
    if isinstance(read, tuple):  # a sequence format's (frames, metadata)
        return _sequence(args, read, meta)
    from ..io.ytal.capture import write_scan
    h = read
    # a confocal grid scan as y-tal writes grids (T_Sx_Sy, X_Y_3), anything else T_Si
    path, grid = write_scan(args.out, h, metadata=meta, force=args.force)
    layout = (f"y-tal grid {grid.shape[0]} x {grid.shape[1]} (H_format T_Sx_Sy)" if grid
              else "y-tal list of spots (H_format T_Si)")
    print(f"wrote {path}: {name}, {_describe(h)}; {layout}")
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
    import numpy as np
    kind = "confocal" if h.paired and np.allclose(h.laser_spots, h.detector_spots) else (
        "paired (a laser spot per histogram)" if h.paired else "one laser spot")
    return (f"{h.n_detectors} histograms x {h.time_axis.n_bins} bins of "
            f"{h.time_axis.dt_s * 1e12:g} ps, {kind}")


def arguments(p):
    """`nlos-cl convert`'s options (the readers' keywords: OPTIONS)."""
    p.add_argument("src", help="the dataset as downloaded: a CC-SOCR folder (sub_Sig.mat, "
                   "C_i.mat, C_d.mat), an LCT .mat (rect_data, width), an f-k meas_*.mat (with "
                   "its tof.mat beside it) or its folder, or a consumer-nlos folder "
                   "of volume_*.npz frames or a Keyhole folder (scan_*.mat; both written as "
                   "sequences)")
    p.add_argument("--out", required=True, help="the y-tal .h5 capture (or sequence) to write "
                   "(atomically); a confocal scan on a regular grid as y-tal's grid (H_format "
                   "T_Sx_Sy, X_Y_3 grids), anything else as a list of spots (T_Si)")
    from ..io.datasets import FORMATS  # the readers' registry (a dict: no reader imported)
    p.add_argument("--format", choices=sorted(FORMATS), default=None,
                   help="the dataset's format (default: detected)")
    p.add_argument("--force", action="store_true", help="replace a file that is not a capture")
    p.add_argument("--dt-ps", type=_number("dt_ps", "pass picoseconds, e.g. 16", positive=True),
                   default=None, help="bin width (ps; default: the dataset's, ccsocr 16, lct 4, "
                   "fk 32, consumer-nlos 250)")
    p.add_argument("--t0-ps", type=_number("t0_ps", "pass picoseconds, e.g. 0"), default=None,
                   help="time of bin 0 after the wall bounce (ps; default 0)")
    p.add_argument("--width", type=_number("width_m", "pass metres, e.g. 0.35", positive=True),
                   default=None, help="lct, fk: half side of the scanned square (m; default: the "
                   "file's `width`; fk 1, or half calibration.mat's width)")
    p.add_argument("--grid-m", type=_number("grid_m", "pass metres, e.g. 0.01", positive=True),
                   default=None, help="ccsocr: metres per wall index (default 0.01)")
    p.add_argument("--transpose", action="store_true", help="lct, fk: swap the scan's two axes")
    p.add_argument("--flip", choices=["x", "z", "xz"], default=None,
                   help="lct, fk: reverse these wall axes of the scan")
    p.add_argument("--crop-bins", type=_number("crop_bins", "pass a bin count, e.g. 512",
                                               minimum=2, integer=True), default=None,
                   help="fk: bins kept after rectification (default 512, as upstream)")
    p.add_argument("--block", type=_number("block", "pass a count of scan points, e.g. 8",
                                           minimum=1, integer=True), default=None,
                   help="fk: sum N x N neighbouring scan points into one histogram (default: "
                   "the least power of two leaving <= 64 x 64 histograms)")
    p.add_argument("--gate-bins", type=_number("gate_bins", "pass a bin count, e.g. 600",
                                               minimum=0, integer=True), default=None,
                   help="lct: zero the first N bins (the direct return; upstream zeroes 600)")
    p.add_argument("--static", action="store_true",
                   help="consumer-nlos: pool every frame into one capture of a scene that does "
                   "not move while the sensor does (each frame's zones at its own wall spots)")
    p.add_argument("--fps", type=_number("fps", "pass frames per second, e.g. 14",
                                         minimum=MIN_FPS, maximum=MAX_FPS), default=None,
                   help="sequences: frame rate, frame k at k / fps (consumer-nlos default 14)")
