"""Issue 21's "every new geometry checked on simulations first": the same random targets
captured in four layouts, each simulated by nlos_cl AND rendered by mitransient 1.3.1, then
located by every estimator, so that a layout is judged against the one-laser layout on the
same targets, noise level and noise seed:

  one         the paper's layout: the laser at O, one histogram per detector spot;
  confocal    each histogram its own spot, laser point = detection point (LCT, Keyhole, f-k);
  paired      each histogram its own laser point and detection point: spot i lit at spot
              i + 1 (cyclic), CC-SOCR's scanned laser read by reciprocity is of this kind;
  exhaustive  a laser grid x a sensor grid located jointly: lasers {O, spot 0, spot S // 2}
              x every spot (its laser = sensor pairs are confocal, as y-tal's are).

The targets are `reproduce draws`' one-target draws (nlos_cl.simulation.draws.families, family
"one", the same index, SNR and noise seed as docs/results/draws/draws.md), every index in
--start .. --start + --count whose layout has at most MAX_SPOTS spots and no instrument mismatch
(SPAD patches of 25-64 spots would cost 3-7x the renders; the mismatch kinds change the
instrument, not the layout). Three steps, two venvs (as scripts/mitransient_draws.py, whose
render_pair renders one laser/spot pair):

  export  (.venv)              each target as PLY, its pairs and time axis as JSON
  render  (.venv-mitransient)  each distinct (laser, spot) pair once (the one-laser pairs
                               are also the exhaustive grid's first row)
  locate  (.venv)              per layout: nlos_cl's simulation (each pair its own
                               Setup, the detection point 1 mm beside a confocal laser point
                               as the forward model needs) and the render (pulse-convolved,
                               scaled to the simulation's total energy), the draw's noise
                               added, located by paper, mean, model and the default

Run through scripts/mitransient_layouts.sh; results in --out (default out/mitransient-layouts),
the page with --doc (docs/results/rendered/layouts-rendered.md).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mitransient_draws import delivered, pulse_convolved, render_axis, render_each  # noqa: E402

LAYOUTS = ("one", "confocal", "paired", "exhaustive")
ESTIMATORS = (("paper", {"estimator": "paper"}), ("mean", {"estimator": "mean"}),
              ("model", {"estimator": "model"}), ("default", {}))
MAX_SPOTS = 9
CONFOCAL_GAP_M = 1e-3  # nlos_cl's Setup refuses a detector spot on the laser spot


def chosen(start: int, count: int) -> list[int]:
    from nlos_cl.simulation.draws import families
    return [i for i in range(start, start + count)
            if len((d := families.draw("one", i))["layout"]["spots"]) <= MAX_SPOTS
            and not d["mismatch"]]


def pairs_of(spots: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(lasers (R, 3), detection spots (R, 3)) per layout, one row per histogram."""
    n, origin = len(spots), np.zeros((1, 3))
    grid = np.concatenate([origin, spots[[0, n // 2]]])
    return {"one": (np.repeat(origin, n, 0), spots), "confocal": (spots, spots),
            "paired": (np.roll(spots, -1, axis=0), spots),
            "exhaustive": (np.repeat(grid, n, 0), np.tile(spots, (len(grid), 1)))}


def _key(laser, spot) -> str:
    return " ".join(f"{v:.6f}" for v in (*laser, *spot))


def export(out: Path, indices):
    from nlos_cl.simulation.draws import families, scenes
    from nlos_cl.apps.reproduce.common import Settings
    s = Settings.make()
    for i in indices:
        d = families.draw("one", i)
        scenes.mesh_of(d["targets"][0], s.facet_m).export(out / f"draw{i}_0.ply")
        layouts = pairs_of(np.asarray(d["layout"]["spots"], float))
        keys = sorted({_key(a, b) for lasers, spots in layouts.values()
                       for a, b in zip(lasers, spots)})
        meta = {"draw": d, "pairs": keys, "n_targets": 1,
                **render_axis(scenes.scene(d, s), s)}
        (out / f"draw{i}.json").write_text(json.dumps(meta))


def render(out: Path, indices, spp: int, splits: int):
    def pairs(meta, plys):  # every distinct (laser, spot) of the four layouts, as exported
        return [((v := [float(x) for x in key.split()])[:3], v[3:], plys) for key in meta["pairs"]]
    render_each(out, indices, spp, splits, "pairs", pairs)


def simulated(d: dict, lasers, spots, axis, facet_m: float):
    """nlos_cl's clean HistogramSet of these pairs: each pair its own Setup (the forward model
    takes one laser spot per Setup); the set holds every row's own laser spot."""
    import nlos_cl as nl
    from nlos_cl.simulation.draws import scenes
    target = nl.Target(scenes.mesh_of(d["targets"][0], facet_m), 0.1284)
    rows, offsets, scale = [], [], None
    for laser, spot in zip(lasers, spots):
        seen = spot + (np.array([CONFOCAL_GAP_M, 0, 0]) if np.allclose(laser, spot) else 0)
        setup = nl.paper_setup(laser_spot=laser, detector_spots=[seen])
        h = nl.simulate(nl.Scene(setup, target, facet_m), axis).histograms()
        rows.append(h.data[0])
        offsets.append(h.calibration.offsets(1)[0])
        scale = h.calibration.a_m_per_s
    one_laser = bool(np.allclose(lasers, lasers[0]))  # the one-laser layout, not a paired one
    return nl.HistogramSet(np.array(rows), axis, spots, lasers[0] if one_laser else lasers,
                           nl.PathCalibration(scale, np.array(offsets)))


def locate_one(job) -> list[dict]:
    """Every estimator on draw i's four layouts, simulated and rendered: one row each."""
    out, i = job
    import nlos_cl as nl
    from nlos_cl.apps.reproduce.draws import run as draws_run
    from nlos_cl.simulation.draws import scenes
    from nlos_cl.apps.reproduce.common import Settings
    s = Settings.make()
    meta = json.loads((out / f"draw{i}.json").read_text())
    if not (out / f"draw{i}_pairs.npy").exists():
        return []
    d = meta["draw"]
    axis = nl.default_time_axis(scenes.scene(d, s).setup, s.dt_s)
    parts = np.load(out / f"draw{i}_pairs.npy").astype(np.float64)  # (pairs, splits, bins)
    where = {k: n for n, k in enumerate(meta["pairs"])}
    truth = np.asarray(d["targets"][0]["centre"], float)
    rows = []
    for layout, (lasers, spots) in pairs_of(np.asarray(d["layout"]["spots"], float)).items():
        clean = simulated(d, lasers, spots, axis, s.facet_m)
        picked = parts[[where[_key(a, b)] for a, b in zip(lasers, spots)]]
        halves = np.array([pulse_convolved(picked[:, j], meta["bin_opl"], meta["sigma_m"])
                           for j in range(picked.shape[1])])
        halves /= np.array([delivered(a) for a in lasers])[None, :, None]  # one laser power
        scale = clean.data.sum() / halves.mean(axis=0).sum()
        render = halves.mean(axis=0) * scale
        energy = render.sum(axis=1) / clean.data.sum(axis=1)
        # the largest shape difference against nlos_cl (per row, over its peak), and the same
        # measure between the renders' two independent halves (their Monte Carlo noise)
        peak = np.abs(clean.data).max(axis=1)
        shape = float((np.abs(render - clean.data).max(axis=1) / peak).max())
        mc = float((np.abs(halves[0] - halves[-1]).max(axis=1) * scale / 2 / peak).max())
        for source, data in (("nlos_cl", clean.data), ("mitransient", render)):
            frame = scenes.noisy(clean.with_data(data.astype(clean.data.dtype)), d)
            for label, options in ESTIMATORS:
                found, notes, seconds, _ = draws_run.locate(frame, options)
                error = float(np.linalg.norm(found[0] - truth)) if found else math.nan
                rows.append({"index": i, "shape": d["targets"][0]["shape"],
                             "layout_kind": d["layout"]["kind"], "spots": len(spots),
                             "snr_db": round(d["snr_db"], 2), "layout": layout,
                             "source": source, "estimator": label,
                             "error_m": round(error, 5), "seconds": round(seconds, 3),
                             "energy_ratio_min": round(float(energy.min()), 4),
                             "energy_ratio_max": round(float(energy.max()), 4),
                             "shape_diff": round(shape, 4), "mc_shape_noise": round(mc, 4),
                             "warnings": " | ".join(n[:80] for n in notes)})
        print(f"draw {i} {layout}: " + ", ".join(
            f"{r['source'][:3]} {r['estimator']} {r['error_m']}" for r in rows[-8:]), flush=True)
    return rows


def table(rows) -> str:
    """Per layout, source and estimator: median, p90, worst over the draws, failures (> 0.15 m),
    and how often the layout is within 2 cm of (or better than) the one-laser layout on the same
    draw, source and estimator."""
    one = {(r["index"], r["source"], r["estimator"]): float(r["error_m"]) for r in rows
           if r["layout"] == "one"}
    lines = ["| layout | source | estimator | n | median (m) | p90 (m) | worst (m) | failures "
             "(> 0.15 m) | within 0.02 m of one laser, or better |",
             "|---|---|---|---|---|---|---|---|---|"]
    for layout in LAYOUTS:
        for source in ("nlos_cl", "mitransient"):
            for label, _ in ESTIMATORS:
                part = [r for r in rows if (r["layout"], r["source"], r["estimator"]) ==
                        (layout, source, label)]
                if not part:
                    continue
                e = np.array([float(r["error_m"]) for r in part])
                e = np.where(np.isfinite(e), e, np.inf)
                fine = sum(e[k] <= one[(r["index"], source, label)] + 0.02
                           for k, r in enumerate(part))
                lines.append(f"| {layout} | {source} | {label} | {len(e)} | {np.median(e):.4f} "
                             f"| {np.percentile(e, 90):.4f} | {e.max():.4f} | "
                             f"{np.mean(e > 0.15):.0%} | {fine} of {len(e)} |")
    return "\n".join(lines) + "\n"


def locate(out: Path, indices, jobs: int):
    work = [(out, i) for i in indices]
    if jobs > 1:
        import multiprocessing as mp
        with mp.get_context("spawn").Pool(jobs) as pool:
            rows = [r for part in pool.map(locate_one, work, chunksize=1) for r in part]
    else:
        rows = [r for job in work for r in locate_one(job)]
    if not rows:
        raise SystemExit("no renders in " + str(out))
    with open(out / "layouts-rendered.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(table(rows))


def page(out: Path, doc: Path) -> None:
    with open(out / "layouts-rendered.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    renders = [json.loads(p.read_text()) for p in sorted(out.glob("draw*_render.json"))]
    draws = sorted({int(r["index"]) for r in rows})
    ratio = [float(r[k]) for r in rows for k in ("energy_ratio_min", "energy_ratio_max")]
    per = {(r["index"], r["layout"]): r for r in rows}  # a draw's layout: one render
    diff = np.array([float(r["shape_diff"]) for r in per.values()])
    mc = np.array([float(r["mc_shape_noise"]) for r in per.values()])
    doc.write_text("\n".join([
        "# Capture layouts on independent renders: confocal, paired and exhaustive against "
        "one laser",
        "",
        f"Generated by `bash scripts/mitransient_layouts.sh` ({len(draws)} targets: `reproduce "
        f"draws`' one-target draws {', '.join(map(str, draws))}, every index of the range with "
        f"at most {MAX_SPOTS} spots and no instrument mismatch; "
        f"{'/'.join(str(v) for v in sorted({r['spp'] for r in renders}))} samples per pair, "
        f"{sum(r['seconds'] for r in renders) / 60:.0f} min of rendering on 2 cores). Do not edit "
        "by hand; every row is in layouts-rendered.csv beside this page.",
        "",
        "Each target is captured in four layouts on its own draw's spots (scripts/"
        "mitransient_layouts.py says how): `one` (laser at O), `confocal` (laser point = "
        "detection point), `paired` (spot i lit at spot i + 1) and `exhaustive` (lasers O, spot 0 "
        "and spot S/2, each with every spot, located jointly); each simulated by nlos_cl and "
        "rendered by mitransient 1.3.1 (Mitsuba 3.9.1, transient_nlos_path, point spots, "
        "hidden-geometry sampling), the render pulse-convolved and scaled to the simulation's "
        "total energy, the draw's noise (SNR, seed) added, and located by the paper's argmax, "
        "the likelihood's mean, the model fit and the default (`nl.locate_capture`, no option: "
        "the model for one laser, the paper's argmax for the paired layouts). The error is the "
        "3-D distance to the target's centre (a closed target's centre lies behind the surface "
        "the argmax finds). The last column compares each draw with the same draw, source and "
        "estimator in the one-laser layout.",
        "",
        table(rows),
        f"The renders against nlos_cl's own clean histograms, per pair at nlos_cl's total "
        f"energy, each laser point given one power (mitransient's projector is a point source "
        f"at the device: mitransient_draws.delivered): energy ratio {min(ratio):.4f} .. "
        f"{max(ratio):.4f}; the largest shape difference (max |render - nlos_cl| / peak, per "
        f"draw and layout) median {np.median(diff):.3f}, max {diff.max():.3f}, where the renders' "
        f"own Monte Carlo noise on the same measure (half the difference of two independent "
        f"halves of the samples) is median {np.median(mc):.3f}, max {mc.max():.3f}.", ""]))
    (doc.with_suffix(".csv")).write_text((out / "layouts-rendered.csv").read_text())


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("step", choices=("export", "render", "locate", "page"))
    parser.add_argument("--out", type=Path, default=Path("out/mitransient-layouts"))
    parser.add_argument("--start", type=int, default=0, help="first draw index")
    parser.add_argument("--count", type=int, default=14, help="draw indices looked at")
    parser.add_argument("--spp", type=int, default=2 ** 18, help="samples per pair")
    parser.add_argument("--splits", type=int, default=2, help="independent renders per pair")
    parser.add_argument("--jobs", type=int, default=1, help="locate: draws located at once")
    parser.add_argument("--doc", type=Path, default=None, help="locate, page: write this page")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.step == "export":
        export(args.out, chosen(args.start, args.count))
    elif args.step == "render":
        exported = [i for i in range(args.start, args.start + args.count)
                    if (args.out / f"draw{i}.json").exists()]  # no nlos_cl in this venv
        render(args.out, exported, args.spp, args.splits)
    elif args.step == "locate":
        locate(args.out, chosen(args.start, args.count), args.jobs)
    if args.doc and args.step in ("locate", "page"):
        page(args.out, args.doc)


if __name__ == "__main__":
    main()
