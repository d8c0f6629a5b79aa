"""One scenario draw through the command line, as a user runs it: `nlos-cl simulate
scene.yaml --out f.h5` (a sequence: `--frames N --fps F`), then `nlos-cl locate f.h5 --json`
(a sequence: `nlos-cl track seq.h5 --json`) with no option; the answer scored against the
draw's truths (score). The commands run in this process (nlos_cl.apps.cli.main, as the
`nlos-cl` script calls it), their output and warnings captured."""
from __future__ import annotations

import io
import time
import traceback
import warnings
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np

from . import scenes, score, sequences

WARNING = "nlos-cl: warning: "


def cli(argv) -> tuple:
    """(exit status, stdout, stderr) of `nlos-cl ARGV` run in this process; an exception
    that escapes the command is a crash: status 'crash', its traceback on stderr."""
    from ...cli import main
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(), redirect_stdout(out), redirect_stderr(err):
        warnings.simplefilter("always")  # each run says its warnings, not only the first run
        try:
            status = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse's refusals
            status = exc.code
        except Exception:  # noqa: BLE001 - a crash is what this run measures
            status = "crash"
            err.write(traceback.format_exc())
    return status, out.getvalue(), err.getvalue()


def said(stderr: str) -> list[str]:
    """The warnings a command printed, and its one-line refusal where it refused."""
    lines = [ln.strip() for ln in stderr.splitlines()]
    warned = [ln[len(WARNING):] for ln in lines if ln.startswith(WARNING)]
    refused = [ln for ln in lines if ln.startswith("nlos-cl: ") and not ln.startswith(WARNING)]
    return warned + refused


def simulate(d: dict, cfg: dict, folder: Path) -> tuple:
    """(the file written, None) or (None, why simulate failed): the draw as a user's files."""
    scene = scenes.write(d, cfg, folder)
    q = d.get("sequence")
    out = folder / ("seq.h5" if q else "f.h5")
    if d.get("wall") and d["wall"]["kind"] == "bumpy":
        scenes.simulate_bumpy(scene, d["wall"]["bumps_m"], out)
        return out, None
    extra = ["--frames", q["frames"], "--fps", q["fps"]] if q else []
    status, _, err = cli(["simulate", scene, "--out", out, *extra])
    if status != 0:
        return None, f"simulate exit {status}: " + " ".join(err.split())[-300:]
    if d.get("wall"):
        scenes.move(out, d["wall"])
    return out, None


def run(d: dict, cfg: dict, folder: Path) -> dict:
    """The draw's row: simulated, answered by the command with no option, scored."""
    start = time.perf_counter()
    path, why = simulate(d, cfg, folder)
    simulated = time.perf_counter()
    row = score.describe(d)
    if path is None:
        row.update(score.refused("simulate", why))
    else:
        command = "track" if d.get("sequence") else "locate"
        status, out, err = cli([command, path, "--json"])
        row["command"] = command
        if d.get("sequence"):
            row.update(score.track(cfg, status, out, said(err), truths_of(d, cfg, folder)))
        else:
            row.update(score.locate(cfg, status, out, said(err), static_truths(d, cfg, folder)))
    row["simulate_s"] = round(simulated - start, 2)
    row["answer_s"] = round(time.perf_counter() - simulated, 2)
    return row


def static_truths(d: dict, cfg: dict, folder: Path) -> tuple:
    """(truths in the capture file's frame (K, 3), each truth's lit share)."""
    spec = scenes.load(folder / "scene.yaml")
    k = sum(o["role"] in scenes.TRUTHS for o in d["objects"])
    truths = scenes.to_file(spec.scene.truths[:k], d.get("wall"))
    return truths, scenes.lit_shares(spec.scene)[:k]


def truths_of(d: dict, cfg: dict, folder: Path) -> dict:
    """A sequence's movers per scored frame: {frame: (truths in the file's frame, lit shares)}."""
    q = d["sequence"]
    movers = [o for o in d["objects"] if o["role"] in scenes.TRUTHS]
    span = scenes.span_of(d)
    out = {}
    for k in range(q["first_frame"], q["frames"]):
        t = k / q["fps"]
        where = np.array([sequences.at(o, t, span) for o in movers])
        lit = scenes.lit_shares(scenes.frame_scene(d, cfg, folder, t))[:len(movers)]
        out[k] = (scenes.to_file(where, None), lit)
    return out

