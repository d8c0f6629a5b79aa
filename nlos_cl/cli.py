"""The `nlos-cl` command: info, demo, bench, reproduce, simulate, locate, calibrate.

A thin argparse layer: every command's work lives in nlos_cl/apps, imported only when that
command runs, so `nlos-cl --help` and `nlos-cl locate` pay for no import they do not use.
"""
from __future__ import annotations

import argparse
import sys


def _parents():
    device = argparse.ArgumentParser(add_help=False)
    device.add_argument("--device", help="'P:D' indices or part of a device/platform name "
                        "(`nlos-cl info` lists them; default: PYOPENCL_CTX, else the best)")
    as_json = argparse.ArgumentParser(add_help=False)
    as_json.add_argument("--json", action="store_true", help="print one JSON object")
    return device, as_json


def _demo_args(p):
    p.add_argument("--reference", action="store_true", help="run on the NumPy twins")
    p.add_argument("--png", default="nlos_demo.png", help="figure path ('' for none)")
    p.add_argument("--snr-db", type=float, default=10.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--h-ns", type=float, default=0.65, help="Gauss filter window h (ns)")
    p.add_argument("--step", type=float, default=0.01, help="grid step (m)")
    p.add_argument("--position", type=float, nargs=3, default=(4.0, 2.0, 0.0),
                   metavar=("X", "Y", "Z"), help="target centre (m)")


def _bench_args(p):
    p.add_argument("--smoke", action="store_true", help="tiny sizes (for CI)")
    p.add_argument("--out", default="", help="write performance.md/.json/.png here")


def _reproduce_args(p):
    from .apps.reproduce import EXPERIMENTS  # a light module: names only
    p.add_argument("name", choices=["all", *EXPERIMENTS])
    p.add_argument("--out", default="out/reproduce", help="folder for figures and CSVs")
    p.add_argument("--seeds", type=int, default=None, help="noise seeds (default 3; 1 quick)")
    p.add_argument("--quick", action="store_true", help="coarse setting (CI)")
    p.add_argument("--doc", default="", help="write the paper-vs-ours report here "
                   "(default with 'all': OUT/paper-results.md)")


def _simulate_args(p):
    p.add_argument("--out", required=True, help="the .h5 file to write")
    p.add_argument("--position", type=float, nargs=3, default=(4.0, 2.0, 0.0),
                   metavar=("X", "Y", "Z"))
    p.add_argument("--facet", type=float, default=0.01, help="facet size (m)")
    p.add_argument("--dt-ps", type=float, default=10.0, help="bin width (ps)")
    p.add_argument("--snr-db", type=float, default=None, help="add white Gaussian noise")
    p.add_argument("--photons", action="store_true", help="photon-counting detector + TDC")
    p.add_argument("--pulses", type=float, default=80e6, help="laser pulses summed")
    p.add_argument("--tdc-ps", type=float, default=50.0, help="TDC bin (ps)")
    p.add_argument("--seed", type=int, default=0)


def _locate_args(p):
    p.add_argument("file")
    p.add_argument("--grid", type=float, nargs=5, default=(0.0, 6.0, 0.01, 6.0, 0.01),
                   metavar=("X0", "X1", "Y0", "Y1", "STEP"), help="search plane (m)")
    p.add_argument("--z", type=float, nargs=2, default=(0.0, 0.0), metavar=("Z0", "Z1"))
    p.add_argument("--h-ns", type=float, default=0.65, help="Gauss filter window h (ns)")
    p.add_argument("--log", action="store_true", help="sum of logs (many detectors)")
    p.add_argument("--background", help="capture without the target, subtracted first")
    p.add_argument("--negatives", default="clip", choices=["clip", "floor", "keep"])
    p.add_argument("--calibration", help="CSV of (path m, peak time s) pairs: fit Eq. 26")
    p.add_argument("--map", help="save the probability map (.npz)")


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
    "simulate": ("simulate the paper's scene into a y-tal capture", _simulate_args, True, False,
                 "files:simulate"),
    "locate": ("locate the target of a y-tal capture", _locate_args, True, True, "files:locate"),
    "calibrate": ("fit path = a t + b (paper Eq. 26) from pairs", _calibrate_args, False, True,
                  "files:calibrate"),
}


def parser() -> argparse.ArgumentParser:
    device, as_json = _parents()
    top = argparse.ArgumentParser(prog="nlos-cl", description=__doc__.split("\n\n")[0])
    sub = top.add_subparsers(dest="command", required=True)
    for name, (help_text, add_args, takes_device, takes_json, _) in COMMANDS.items():
        parents = [p for p, on in ((device, takes_device), (as_json, takes_json)) if on]
        p = sub.add_parser(name, help=help_text, parents=parents)
        if add_args:
            add_args(p)
    return top


def main(argv=None) -> int:
    args = parser().parse_args(argv)
    import importlib

    from .errors import DeviceError, InputError
    module, function = COMMANDS[args.command][-1].split(":")
    try:
        return getattr(importlib.import_module(f".apps.{module}", __package__), function)(args)
    except (InputError, DeviceError) as exc:
        print(f"nlos-cl: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
