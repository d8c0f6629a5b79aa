"""The `nlos-cl` command: info, demo, bench, reproduce, simulate, convert, locate, calibrate,
track, sweep.

A thin argparse layer: every command's work lives in nlos_cl/apps, imported only when that
command runs, so `nlos-cl --help` and `nlos-cl locate` pay for no import they do not use.
"""
from __future__ import annotations

import argparse
import sys

from ..core.limits import MAX_FRAMES, MAX_TARGETS
from . import terminal
from .convert import arguments as _convert_arguments
from .cli_types import (COORD, H_NS, MAX_ACCEL, MAX_FPS, MIN_FPS, SEED, Defaults as _Defaults,
                        Parser as _Parser, number as _number, reflectance as REFLECTANCE)


def _parents():
    device = _Parser(add_help=False)
    device.add_argument("--device", help="'P:D' indices or part of a device/platform name "
                        "(`nlos-cl info` lists them; default: PYOPENCL_CTX, else the best)")
    as_json = _Parser(add_help=False)
    as_json.add_argument("--json", action="store_true", help="print one JSON object")
    return device, as_json


def _demo_args(p):
    p.add_argument("--reference", action="store_true", help="run on the NumPy twins")
    p.add_argument("--png", default="nlos_demo.png", help="figure path ('' for none)")
    p.add_argument("--force", action="store_true",
                   help="let --png replace a file nlos_cl did not write")
    p.add_argument("--snr-db", type=_number("snr_db", "pass decibels, e.g. 10"), default=10.0)
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument("--h-ns", type=H_NS, default=0.65, help="Gauss filter window h (ns)")
    p.add_argument("--step", type=_number("grid.step", "pass metres, e.g. 0.01", positive=True),
                   default=0.01, help="grid step (m)")
    p.add_argument("--position", type=COORD, nargs=3, default=(4.0, 2.0, 0.0),
                   metavar=("X", "Y", "Z"), help="target centre (m, the paper's frame: x along "
                   "the wall, y out from it, z up)")
    p.add_argument("--estimator", choices=["model", "paper"], default="model",
                   help="whose answer heads the output (both are run and shown)")
    p.add_argument("--track", action="store_true", help="a short tracking demonstration: the "
                   "target walks a line over 30 frames, located per frame and Kalman-tracked")


def _bench_args(p):
    p.add_argument("--smoke", action="store_true", help="tiny sizes (for CI)")
    p.add_argument("--out", default="", help="write performance.md/.json/.png here")
    p.add_argument("--force", action="store_true",
                   help="let --out replace performance.* files nlos_cl did not write")


class _LazyChoices:
    """argparse choices read from a module only when a value is checked or help is shown: the
    experiments' names live in nlos_cl.apps.reproduce, whose import (~0.1 s: every experiment,
    tqdm, yaml) only `nlos-cl reproduce` should pay, not `nlos-cl locate`."""

    def __init__(self, first, module, attr):
        self.first, self.module, self.attr = list(first), module, attr

    def _names(self):
        import importlib
        return [*self.first, *getattr(importlib.import_module(self.module, __package__),
                                      self.attr)]

    def __contains__(self, value):
        return value in self._names()

    def __iter__(self):
        return iter(self._names())


def _reproduce_args(p):
    # a metavar, so that argparse does not list the choices (an import) while building
    p.add_argument("name", choices=_LazyChoices(["all"], ".reproduce", "EXPERIMENTS"),
                   metavar="NAME", help="the experiment: %(choices)s")
    p.add_argument("--out", default="out/reproduce", help="folder for figures and CSVs")
    p.add_argument("--seeds", type=_number("seeds", "pass a count, e.g. 3", minimum=1,
                                           integer=True), default=None,
                   help="noise seeds (default 3; 1 quick)")
    p.add_argument("--quick", action="store_true", help="coarse setting (CI)")
    p.add_argument("--doc", default="", help="write the paper-vs-ours report here "
                   "(default with 'all': OUT/paper-results.md)")
    p.add_argument("--force", action="store_true",
                   help="replace files in --out and --doc that nlos_cl did not write")
    p.add_argument("--only", nargs="+", default=None, metavar="SECTION",
                   help="beyond, tracking, draws: only these parts (tracking: speed memory "
                   "lines synthetic box crossing; draws: one multi closed mismatch crossings; "
                   "scenarios: families, e.g. occluders)")
    p.add_argument("--cold", action="store_true",
                   help="tracking: trackers with warm_start=False (for comparison; not with --doc)")
    p.add_argument("--draws", type=_number("draws", "pass a count, e.g. 200", minimum=1,
                                           integer=True), default=None,
                   help="draws: scenes per family (default 200; 1 with --quick)")
    p.add_argument("--jobs", type=_number("jobs", "pass a count, e.g. 2", minimum=1,
                                          integer=True), default=None,
                   help="draws: worker processes, each its own OpenCL context (default 1)")
    p.add_argument("--data", default=None, metavar="DIR",
                   help="real: the measured datasets' folder (default $NLOS_CL_REALDATA, else "
                   "../shared/realdata beside the repository)")


def _simulate_args(p):
    p.add_argument("scene", nargs="?", default=None,
                   help="a scene file (YAML: docs/scene-files.md); default: the paper's scene, "
                   "shaped by the options below")
    p.add_argument("--out", required=True, help="the .h5 file to write (atomically)")
    p.add_argument("--force", action="store_true", help="replace a file that is not a capture")
    p.add_argument("--position", type=COORD, nargs=3, default=None, metavar=("X", "Y", "Z"),
                   help="the paper's target centre (m) in y-tal's frame, as captures and "
                   "every output give it: X along the wall, Y up, Z the depth (default -4 0 2)")
    p.add_argument("--facet", type=_number("facet_size_m", "pass metres, e.g. 0.01",
                                           positive=True), default=None,
                   help="facet size (m; default 0.01)")
    p.add_argument("--dt-ps", type=_number("time_axis.dt_s", "pass picoseconds, e.g. 10",
                                           positive=True), default=None,
                   help="bin width (ps; default 10)")
    p.add_argument("--snr-db", type=_number("snr_db", "pass decibels, e.g. 10"), default=None,
                   help="add white Gaussian noise")
    p.add_argument("--photons", action="store_true", help="photon-counting detector + TDC")
    p.add_argument("--pulses", type=_number("photon_counter.n_pulses", "pass e.g. 80e6",
                                            positive=True), default=80e6,
                   help="laser pulses summed")
    p.add_argument("--tdc-ps", type=_number("photon_counter.tdc_bin_s", "pass picoseconds, "
                                            "e.g. 50", positive=True), default=50.0,
                   help="TDC bin (ps)")
    p.add_argument("--seed", type=SEED, default=None, help="noise seed (default 0)")
    p.add_argument("--frames", type=_number("frames", "pass a count, e.g. 50", minimum=1,
                                            integer=True, maximum=MAX_FRAMES), default=None,
                   help="write a sequence of N frames (scene file with trajectories)")
    p.add_argument("--fps", type=_number("fps", "pass a frame rate in Hz, e.g. 10",
                                         minimum=MIN_FPS, maximum=MAX_FPS), default=10.0,
                   help="frame rate of --frames (frame k at t = k / fps)")


def _locate_args(p):
    p.add_argument("file")
    p.add_argument("--region", type=_number("region", "pass finite ranges in metres"), nargs=6,
                   metavar=("A0", "A1", "B0", "B1", "C0", "C1"), default=None,
                   help="search ranges along the file's three axes (m; for y-tal files X, Y, Z "
                   "with the wall at Z = 0); default: derived from the capture")
    p.add_argument("--step", type=_number("grid.step", "pass metres, e.g. 0.01", positive=True),
                   default=None, help="grid step with --region (m; default from the bins and h)")
    p.add_argument("--h-ns", type=H_NS, default=None, help="Gauss filter window h (ns; default: "
                   "from the direct return's width where the capture has one, else 0.65)")
    p.add_argument("--pulses", type=_number("pulses", "pass the laser pulses per histogram, e.g. "
                                            "1e6", minimum=1), default=None,
                   help="laser pulses per histogram: correct SPAD pile-up (Coates; default off)")
    p.add_argument("--log", action="store_true", help="sum of logs (many detectors)")
    p.add_argument("--background", help="capture without the target, subtracted first")
    p.add_argument("--negatives", default="keep", choices=["keep", "clip", "floor"],
                   help="bins below 0 after --background: keep (default; clipping biases the "
                   "model estimator), clip to 0, or floor")
    p.add_argument("--calibration", help="CSV of (path m, peak time s) pairs: fit Eq. 26")
    p.add_argument("--map", help="save the score maps (the whole search region's and the "
                   "final grid's), by the extension: .npz (the arrays along the file's axes, "
                   "with frame, units and estimator) or .png (a figure: maps, wall, spots, "
                   "truths, estimates and their 2-sd ellipses)")
    p.add_argument("--force", action="store_true",
                   help="let --map replace a file nlos_cl did not write")
    _estimator_args(p)


def _targets(text):
    if text == "auto":
        return text
    return _number("targets", "pass a count, e.g. 1, or 'auto'", minimum=1, integer=True,
                   maximum=MAX_TARGETS)(text)


ESTIMATOR_CHOICES = _LazyChoices([], "..localization.estimators", "ESTIMATORS")  # the registry


def _estimator_args(p):
    p.add_argument("--estimator", choices=ESTIMATOR_CHOICES, metavar="NAME", default=None,
                   help="model: fit a plate's centre, size and yaw with the forward model, with "
                   "a covariance (docs/model-estimator.md); paper: the paper's argmax; mean: "
                   "the mean and covariance of the paper's likelihood "
                   "(default: model; paper for paired and confocal captures)")
    p.add_argument("--targets", type=_targets, default=None,
                   help="targets to fit (model estimator): a count, or 'auto' (every target the "
                   "data support, up to 3: a plate more is fitted while one fewer misses the "
                   "data and the BIC takes it); default: one, and more where the fit's residual "
                   "holds separate objects")
    _reflectance_arg(p)


def _reflectance_arg(p):
    p.add_argument("--reflectance", type=REFLECTANCE, default=None, metavar="MODEL[:K=V,...]",
                   help="the targets' reflectance in the model fit, e.g. retroreflective:retro="
                   "0.7,width_rad=0.005,diffuse=0.2 or ggx:specular=0.5,roughness=0.3 "
                   "(default: Lambertian, or a GGX lobe fitted where the Lambertian fit of one "
                   "target misses the data; lambertian holds it Lambertian; "
                   "docs/model-estimator.md). It asks for the model "
                   "fit, also on paired and confocal captures (whose default is the argmax)")


def _track_args(p):
    p.add_argument("file", help="a sequence (or capture) .h5 file: docs/tracking.md")
    p.add_argument("--video", default=None, help="write an animation (.gif, or .mp4 with ffmpeg)")
    p.add_argument("--csv", default=None, metavar="FILE.csv", help="write every frame's tracks, "
                   "measurements and truths as a table (the file's axes, ± 1 sd)")
    p.add_argument("--estimator", choices=ESTIMATOR_CHOICES, metavar="NAME", default=None,
                   help="per-frame estimator (model: centre and covariance, warm-started from "
                   "the tracks; paper: the argmax, faster; mean: the mean and covariance of "
                   "the paper's likelihood; default: model, paper for paired "
                   "and confocal captures)")
    p.add_argument("--targets", type=_targets, default="auto", help="targets to follow: a "
                   "count, or 'auto' (the default: found and ended from the data by the model "
                   "fit, up to 3)")
    _reflectance_arg(p)
    p.add_argument("--region", type=_number("region", "pass finite ranges in metres"), nargs=6,
                   default=None, metavar=("A0", "A1", "B0", "B1", "C0", "C1"),
                   help="search ranges along the file's axes (default: what the capture sees)")
    p.add_argument("--step", type=_number("grid.step", "pass metres, e.g. 0.01", positive=True),
                   default=None, help="grid step (m) with --region")
    p.add_argument("--h-ns", type=H_NS, default=None, help="Gauss filter window h (ns; "
                   "default: 0.65, or 2 bins where the bins are coarser)")
    p.add_argument("--background", default=None, metavar="BG.h5|none",
                   help="a target-free capture to subtract, or 'none' (default: the static "
                   "returns learned from frames spread over the sequence)")
    p.add_argument("--running-mean", type=_number("running_mean", "pass a weight in (0, 1], "
                                                  "e.g. 0.05", positive=True), default=None,
                   metavar="ALPHA", help="subtract a running mean of past frames (weight ALPHA)")
    p.add_argument("--accel", type=_number("accel", "pass m/s^2, e.g. 0.5", positive=True,
                                           maximum=MAX_ACCEL),
                   default=0.5, help="motion noise (m/s^2) of the constant-velocity model, "
                   "or of the manoeuvring mode with --motion imm")
    p.add_argument("--steady-accel", type=_number("steady_accel", "pass m/s^2 below --accel, "
                                                  "e.g. 0.05", positive=True, maximum=MAX_ACCEL),
                   default=0.05, help="motion noise (m/s^2) of the steady mode with --motion imm")
    p.add_argument("--motion", choices=["imm", "cv"], default="imm",
                   help="imm: a steady and a manoeuvring constant-velocity mode, mixed "
                   "(interacting multiple model); cv: one constant-velocity model (--accel)")
    p.add_argument("--max-frames", type=_number("max_frames", "pass a count", minimum=1,
                                                integer=True), default=None,
                   help="track the first N frames")
    p.add_argument("--full-search", action="store_true",
                   help="search the whole region every frame (default: while every target is "
                   "followed, only a box holding the tracks' gates, where that is cheaper: the "
                   "region's own scores; docs/tracking.md)")
    p.add_argument("--smooth", action="store_true",
                   help="offline: print every frame's tracks smoothed with the later frames "
                        "(Rauch-Tung-Striebel), after the last frame")
    p.add_argument("--lag", type=_number("lag", "pass a number of frames, e.g. 5", minimum=0,
                                         integer=True), default=0, metavar="L",
                   help="real time with a latency: each frame's line L frames later, "
                        "fixed-lag smoothed with them")
    p.add_argument("--force", action="store_true", help="replace an existing --video or --csv "
                   "file nlos_cl did not write")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _sweep_args(p):
    from .sweep_cmd import add_arguments  # argparse only: light
    add_arguments(p)


def _calibrate_args(p):
    p.add_argument("pairs", help="CSV rows: known free-space path (m), peak time (s)")


# name: (help, add arguments, takes --device, takes --json, "module:function" that runs it)
COMMANDS = {
    "info": ("list OpenCL devices, show the chosen one, self-check every operation",
             None, True, False, "selfcheck:main"),
    "demo": ("the paper's scene: simulate, noise, filter, locate", _demo_args, True, True,
             "demo:run"),
    "bench": ("every operation vs its NumPy twin and the device's limits", _bench_args, True,
              False, "bench_cmd:main"),
    "reproduce": ("re-run an experiment of the paper (or all)", _reproduce_args, False, True,
                  "reproduce_cmd:main"),
    "simulate": ("simulate a scene file (or the paper's scene) into a y-tal capture",
                 _simulate_args, True, False,
                 "simulate:simulate"),
    "convert": ("convert a measured dataset as downloaded (ccsocr, lct, fk, consumer-nlos, keyhole) to y-tal",
                _convert_arguments, False, False, "convert:main"),
    "locate": ("locate the target of a y-tal capture", _locate_args, True, True, "locate:locate"),
    "calibrate": ("fit path = a t + b (paper Eq. 26) from pairs", _calibrate_args, False, True,
                  "calibrate:calibrate"),
    "track": ("track hidden objects through a sequence of frames (Kalman tracks)", _track_args,
              True, True, "track:main"),
    "sweep": ("run a parameter study (YAML) as Dask tasks: runs.parquet, summary, plots",
              _sweep_args, False, False, "sweep_cmd:main"),
}


def parser(command: str | None = None) -> argparse.ArgumentParser:
    """The whole command line; `command`: only that command gets its options (the others keep
    their names and help, all that `nlos-cl --help` lists), so a one-shot run builds one
    sub-parser, not ten (~3 ms, and `sweep`'s options import nlos_cl.apps.sweep_cmd)."""
    device, as_json = _parents()
    top = _Parser(prog="nlos-cl", description=__doc__.split("\n\n")[0],
                  parents=[terminal.verbose_flag()])
    from .. import __version__  # the package's own (no import of its modules)
    top.add_argument("--version", action="version", version=f"nlos-cl {__version__}")
    sub = top.add_subparsers(dest="command", required=True)
    for name, (help_text, add_args, takes_device, takes_json, _) in COMMANDS.items():
        if command not in (None, name):
            sub.add_parser(name, help=help_text)
            continue
        parents = [p for p, on in ((device, takes_device), (as_json, takes_json)) if on]
        parents.append(terminal.verbose_flag())
        p = sub.add_parser(name, help=help_text, parents=parents, formatter_class=_Defaults)
        if add_args:
            add_args(p)
    return top


def _command_in(argv) -> str | None:
    """The command argparse will run: the first word that is not an option (the top level's
    options, --help and --verbose, take no value); None where that is no command."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in COMMANDS else None


@terminal.one_run  # warnings as one line each; --verbose
def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser(_command_in(argv)).parse_args(argv)
    import importlib

    from ..core.errors import DeviceError, InputError
    module, function = COMMANDS[args.command][-1].split(":")
    try:
        return getattr(importlib.import_module(f".{module}", __package__), function)(args)
    except (InputError, DeviceError) as exc:
        print(f"nlos-cl: {exc}", file=sys.stderr)
        return 2
    except MemoryError as exc:  # past every budget check (the address space ran out)
        print(f"nlos-cl: {args.command}: ran out of memory ({str(exc).split(': ', 1)[-1][:80]})."
              " Fix: a coarser facet_size_m, a smaller region or fewer spots, or raise the "
              "limit (ulimit -v, NLOS_CL_MEMORY_LIMIT)", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `nlos-cl ... | head`: the reader left; nothing more to say
        return 1
    except OSError as exc:  # an output path we could not write: say which and why
        print(f"nlos-cl: {exc.filename or 'output'}: {exc.strerror or exc}. Fix: pick a "
              "writable file path in an existing folder", file=sys.stderr)
        return 2


if __name__ == "__main__":
    terminal.leave(main())  # as `nlos-cl` (console.run) leaves
