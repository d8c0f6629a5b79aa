"""`nlos-cl convert SRC --out DST.h5`: a measured dataset as its authors publish it
(nlos_cl.io.datasets) into a y-tal capture that `nlos-cl locate` reads with no other option."""
from __future__ import annotations

# CLI option -> the readers' keyword (nlos_cl.io.datasets.<format>.read_<format>)
OPTIONS = {"dt_ps": "dt_ps", "t0_ps": "t0_ps", "width": "width_m", "grid_m": "grid_m",
           "transpose": "transpose", "flip": "flip", "gate_bins": "gate_bins"}


def main(args) -> int:
    from ..core.errors import require
    from ..io.datasets import detect, options_of, read_dataset
    from ..io.ytal.capture import write_capture
    name = args.format or detect(args.src)
    given = {key: getattr(args, opt) for opt, key in OPTIONS.items()
             if getattr(args, opt) not in (None, False)}
    extra = sorted(set(given) - options_of(name))
    flag = {key: "--" + opt.replace("_", "-") for opt, key in OPTIONS.items()}
    require(not extra, flag[extra[0]] if extra else "", f"is not an option of the {name} "
            "format", "drop it (`nlos-cl convert --help` says which options each format takes)")
    h = read_dataset(args.src, name, **given)
    path = write_capture(args.out, h, metadata={"converted_from": str(args.src),
                                                "dataset_format": name, "options": given},
                         force=args.force)
    kind = "confocal" if h.paired and (h.laser_spots == h.detector_spots).all() else (
        "paired (a laser spot per histogram)" if h.paired else "one laser spot")
    print(f"wrote {path}: {name}, {h.n_detectors} histograms x {h.time_axis.n_bins} bins of "
          f"{h.time_axis.dt_s * 1e12:g} ps, {kind}")
    return 0
