"""The estimators on independent renders of random scenes (issue 22): `reproduce draws`' one-target
draws rendered by mitransient 1.3.1 (Mitsuba 3) instead of nlos_cl's forward model, then located
exactly as `reproduce draws` locates its own simulations. Three steps, two venvs, like
mitransient_check.py:

  export  (.venv)              : each draw's target as PLY and what the render needs (spots,
                                 the time axis as hidden path, the pulse)
  render  (.venv-mitransient)  : per wall spot, one render of the hidden path r1 + r2 (laser spot
                                 -> target -> that spot), first and last bounces excluded
  locate  (.venv)              : each render convolved with the bin-integrated pulse, put in
                                 place of nlos_cl's clean histograms (same layout and time axis),
                                 scaled to nlos_cl's total energy (one constant per draw: the
                                 estimators fit the amplitude, and the noise follows the draw's
                                 SNR, so only the renders' shapes and per-spot ratios matter),
                                 the draw's noise added (simulation.draws.scenes.noisy), the
                                 paper's argmax and the default located (reproduce.draws.run
                                 .locate); errors as `reproduce draws` measures them

How a spot is rendered (nothing of nlos_cl's geometry enters): mitransient's nlos_capture_meter
measures the wall at its film's pixel centres; with a 1 x 1 film on a relay-wall rectangle
centred on the spot, that centre is the spot. The rectangle reaches past the laser spot O (the
projector is focused there). The device sits high above the wall (DEVICE) so that no target
shadows its rays; for a Lambertian wall the radiance a spot sends it does not depend on where it
is. Hidden-geometry sampling (every drawn target is convex). The renders' Monte Carlo noise is
reported beside each draw (two independent halves of the samples, `--splits 2`).

Run through scripts/mitransient_draws.sh, one --out folder per family (`--family closed`: the
closed family's draws). Files stay in --out (default out/mitransient-draws), out of git.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mitransient_check import _pulse_convolve  # noqa: E402

DEVICE = [0.0, 5.0, 20.0]  # m: the laser's and the meter's origin, far above every target
# Families of single convex targets (hidden-geometry sampling is unbiased for them; several
# targets shadow each other, where mitransient_check.py needs BSDF sampling and ~100x the samples)
FAMILIES = ("one", "closed")


def _indices(args) -> range:
    return range(args.start, args.start + args.count)


def export(out: Path, indices, family: str = "one"):
    from nlos_cl.simulation.draws import families, scenes
    from nlos_cl.apps.reproduce.common import Settings
    s = Settings.make()
    for i in indices:
        d = families.draw(family, i)
        for k, t in enumerate(d["targets"]):
            scenes.mesh_of(t, s.facet_m).export(out / f"draw{i}_{k}.ply")
        meta = {"draw": d, "spots": np.asarray(d["layout"]["spots"], float).tolist(),
                "laser": [0.0, 0.0, 0.0], "n_targets": len(d["targets"]),
                **render_axis(scenes.scene(d, s), s)}
        (out / f"draw{i}.json").write_text(json.dumps(meta))


def render_axis(scene, s) -> dict:
    """What a render needs of a draw's scene besides its geometry: nlos_cl's time axis as
    hidden path (bin k holds light that left at t0 + k dt minus the pulse's peak delay and the
    two device legs), the pulse's width in path, and the reflectances."""
    import nlos_cl as nl
    setup, c = scene.setup, nl.SPEED_OF_LIGHT
    axis = nl.default_time_axis(setup, s.dt_s)
    return {"brdf": 0.1284, "wall_brdf": float(setup.wall_brdf),
            "start_opl": c * (axis.t0_s - setup.pulse.peak_delay_s) - 2 * setup.device_distance_m,
            "bin_opl": c * axis.dt_s, "n_bins": axis.n_bins, "sigma_m": c * setup.pulse.sigma_s}


def render(out: Path, indices, spp: int, splits: int):
    render_each(out, indices, spp, splits, "render", lambda meta, plys: [
        (meta["laser"], spot, plys) for spot in meta["spots"]])


def render_each(out: Path, indices, spp: int, splits: int, name: str, pairs):
    """Each exported draw i not rendered yet: render_pair of every (laser, spot, plys) that
    pairs(meta, plys) lists, saved as draw{i}_{name}.npy (pairs, splits, bins) with its
    samples and seconds in draw{i}_render.json."""
    import mitsuba as mi
    mi.set_variant("llvm_ad_mono" if "llvm_ad_mono" in mi.variants() else "llvm_ad_rgb")
    import mitransient as mitr  # noqa: F401  (registers the plugins)
    for i in indices:
        target = out / f"draw{i}_{name}.npy"
        if target.exists():
            continue
        meta = json.loads((out / f"draw{i}.json").read_text())
        t0 = time.perf_counter()
        plys = [out / f"draw{i}_{k}.ply" for k in range(meta["n_targets"])]
        rows = [render_pair(mi, mitr, meta, laser, spot, p, spp, splits)
                for laser, spot, p in pairs(meta, plys)]
        np.save(target, np.array(rows, np.float32))
        (out / f"draw{i}_render.json").write_text(json.dumps(
            {"spp": splits * max(1, spp // splits), "seconds": time.perf_counter() - t0}))
        print(f"draw {i}: {len(rows)} pairs, {time.perf_counter() - t0:.1f} s", flush=True)


def render_pair(mi, mitr, meta: dict, laser, spot, plys, spp: int, splits: int) -> list:
    """`splits` independent renders (each spp / splits samples) of the hidden path laser spot
    -> targets (plys) -> `spot` on meta's time axis (start_opl, bin_opl, n_bins): a list of
    (bins,) arrays. The laser may be the spot itself (a confocal pair)."""
    from mitsuba import ScalarTransform4f as T
    reach = max(abs(spot[0] - laser[0]), abs(spot[2] - laser[2])) + 0.5  # covers the laser spot
    wall = {"type": "rectangle", "id": "relay_wall",
            "to_world": T().translate(spot) @ T().rotate([1, 0, 0], -90)
            @ T().scale([reach, reach, 1.0]),
            "bsdf": {"type": "diffuse",
                     "reflectance": {"type": "rgb", "value": meta["wall_brdf"] * math.pi}},
            "nlos_sensor": {"type": "nlos_capture_meter", "sensor_origin": DEVICE,
                            "film": {"type": "transient_hdr_film", "width": 1,
                                     "height": 1, "temporal_bins": meta["n_bins"],
                                     "bin_width_opl": meta["bin_opl"],
                                     "start_opl": meta["start_opl"],
                                     "rfilter": {"type": "box"}}}}
    desc = {"type": "scene", "relay_wall": wall,
            "integrator": {"type": "transient_nlos_path", "max_depth": 3,
                           "nlos_laser_sampling": True,
                           "nlos_hidden_geometry_sampling": True,
                           "account_first_and_last_bounces": False},
            "laser": {"type": "projector", "id": "laser", "fov": 0.05,
                      "to_world": T().translate(DEVICE), "irradiance": 1.0}}
    for k, ply in enumerate(plys):
        desc[f"target_{k}"] = {
            "type": "ply", "filename": str(ply), "face_normals": True,
            "bsdf": {"type": "diffuse",
                     "reflectance": {"type": "rgb", "value": meta["brdf"] * math.pi}}}
    scene = mi.load_dict(desc)
    relay = [s for s in scene.shapes() if s.id() == "relay_wall"][0]
    mitr.nlos.focus_emitter_at_relay_wall_3dpoint(mi.Point3f(*laser), relay, scene.emitters()[0])
    return [np.array(mi.render(scene, spp=max(1, spp // splits), seed=seed)[1])[0, 0, :, 0]
            for seed in range(splits)]


def delivered(laser) -> float:
    """The power mitransient's projector puts on a wall point, relative to O: it is a point
    source of fixed intensity at DEVICE (irradiance cos(incidence) / distance^2), where a laser
    puts its whole power on the spot wherever it points (nlos_cl's model). One constant for the
    one-laser layout; per laser point a factor of 0.97-1.11 in scripts/mitransient_layouts.py."""
    def irradiance(p):
        v = np.asarray(DEVICE, float) - np.asarray(p, float)
        return v[1] / np.linalg.norm(v) ** 3  # the wall's normal is +y
    return float(irradiance(laser) / irradiance([0.0, 0.0, 0.0]))


def pulse_convolved(data, bin_m: float, sigma_m: float) -> np.ndarray:
    """mitransient_check's pulse (bin-integrated Gaussian, centred) at these renders' bins."""
    return _pulse_convolve(data, sigma_m, bin_m)


def locate_one(job) -> list[dict]:
    """Both estimators on draw i's rendered frame: one row each ([] where it has no render)."""
    out, i = job
    from nlos_cl.apps.reproduce.draws import run as draws_run
    from nlos_cl.simulation.draws import scenes
    from nlos_cl.apps.reproduce.common import Settings
    s = Settings.make()
    rows = []
    if (out / f"draw{i}_render.npy").exists():
        meta = json.loads((out / f"draw{i}.json").read_text())
        d = meta["draw"]
        clean, _ = scenes.simulate(d, s)
        parts = np.load(out / f"draw{i}_render.npy").astype(np.float64)  # (spots, splits, bins)
        conv = np.stack([pulse_convolved(parts[:, j], meta["bin_opl"], meta["sigma_m"])
                         for j in range(parts.shape[1])], axis=1)
        render = conv.mean(axis=1)
        scale = clean.data.sum() / render.sum()
        render *= scale
        peak = np.abs(clean.data).max(axis=1)
        # the render against nlos_cl's own clean histograms (both at nlos_cl's total energy):
        # the per-spot energy ratio and the largest shape difference, and the Monte Carlo
        # noise of the same measure (the two halves of the samples)
        energy = render.sum(axis=1) / clean.data.sum(axis=1)
        shape = (np.abs(render - clean.data).max(axis=1) / peak).max()
        mc = (np.abs(conv[:, 0] - conv[:, -1]).max(axis=1) * scale / 2 / peak).max() \
            if conv.shape[1] > 1 else math.nan
        frame = scenes.noisy(clean.with_data(render.astype(clean.data.dtype)), d)
        rows = draws_run.located_rows(d, frame, {
            "energy_ratio_min": round(float(energy.min()), 4),
            "energy_ratio_max": round(float(energy.max()), 4),
            "shape_diff": round(float(shape), 4), "mc_shape_noise": round(float(mc), 4)})
        print(f"draw {i}: " + ", ".join(f"{r['estimator']} {r['error_m']}" for r in rows[-2:]),
              flush=True)
    return rows


def locate(out: Path, indices, jobs: int = 1):
    from nlos_cl.apps.reproduce.draws import report as draws_report
    work = [(out, i) for i in indices]
    if jobs > 1:
        import multiprocessing as mp
        with mp.get_context("spawn").Pool(jobs) as pool:
            rows = [r for part in pool.map(locate_one, work, chunksize=1) for r in part]
    else:
        rows = [r for job in work for r in locate_one(job)]
    if not rows:
        raise SystemExit("no renders in " + str(out))
    with open(out / "draws-rendered.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = ["| family | layouts | estimator | n | median (m) | p90 (m) | worst (m) "
             "| failures (> 0.15 m) | beyond 0.15 m without a warning |", "|---|---|---|---|---|---|---|---|---|"]
    seen_two = lambda r: (not str(r["layout"]).startswith("line")
                          and not draws_report._bool(r["depth_unseen"]))
    for family in sorted({r["family"] for r in rows}):
        for name, keep in (("all", lambda r: True),
                           ("off a line", lambda r: not str(r["layout"]).startswith("line")),
                           ("seen from two sides", seen_two)):
            if family != "closed" and name == "seen from two sides":
                continue
            for label in ("paper", "default"):
                part = [r for r in rows if r["family"] == family and r["estimator"] == label
                        and keep(r)]
                if not part:
                    continue
                st = draws_report.stats(part, 0.15)
                lines.append(f"| {family} | {name} | {label} | {st['n']} | "
                             f"{st['median_m']:.4f} | {st['p90_m']:.4f} | {st['worst_m']:.4f} | "
                             f"{st['failure_rate']:.1%} | {st['unwarned_failures']} |")
    table = "\n".join(lines) + "\n"
    (out / "draws-rendered.md").write_text(table)
    print(table)
    return rows, table


def page(rows, table: str, out: Path, seconds: float) -> str:
    """docs/results/rendered/draws-rendered.md: how the renders were made, the table, the renders'
    own check."""
    renders = [json.loads(p.read_text()) for p in sorted(out.glob("draw*_render.json"))]
    spp = sorted({r["spp"] for r in renders})
    render_s = sum(r["seconds"] for r in renders)
    one = {r["index"]: r for r in rows if r["estimator"] == "default"}
    ratio = [float(r["energy_ratio_min"]) for r in one.values()] + \
        [float(r["energy_ratio_max"]) for r in one.values()]
    diff = np.array([float(r["shape_diff"]) for r in one.values()])
    mc = np.array([float(r["mc_shape_noise"]) for r in one.values()])
    return "\n".join([
        "# Random draws on independent renders: mitransient instead of nlos_cl's forward model",
        "",
        f"Generated by `bash scripts/mitransient_draws.sh` (families {', '.join(sorted({r['family'] for r in rows}))}, "
        f"{len(one)} draws, {'/'.join(str(v) for v in spp)} samples per spot, "
        f"{render_s / 60:.0f} min of rendering, {seconds / 60:.0f} min of locating on 2 cores). "
        "Do not edit by hand; every row is in draws-rendered.csv beside this page.",
        "",
        "Each draw is `reproduce draws`' draw of the same family and index "
        "(docs/results/draws/draws.md: the "
        "same scene, SNR and noise seed), rendered by mitransient 1.3.1 (Mitsuba 3.9.1, "
        "transient_nlos_path, point spots, hidden-geometry sampling; scripts/mitransient_draws.py "
        "says how a spot is rendered), convolved with the pulse, scaled to nlos_cl's total "
        "energy (one constant per draw: the estimators fit the amplitude and the noise follows "
        "the draw's SNR), the draw's noise added, and located as `reproduce draws` locates: the "
        "paper's argmax and the default (`nl.locate_capture`, no option). The error is the 3-D "
        "distance to the truth's centre; a failure is above 0.15 m; unwarned failures as "
        "docs/results/draws/draws.md counts them.",
        "",
        table,
        "The renders against nlos_cl's own clean histograms of the same draws (both at nlos_cl's "
        f"total energy): per-spot energy ratio {min(ratio):.4f} .. {max(ratio):.4f}; the largest "
        f"shape difference (max |render - nlos_cl| / peak, per draw) median {np.median(diff):.3f}, "
        f"max {diff.max():.3f}, where the renders' own Monte Carlo noise on the same measure "
        f"(half the difference of two independent halves of the samples) is median "
        f"{np.nanmedian(mc):.3f}, max {np.nanmax(mc):.3f}.",
        "", *paired(rows), ""])


SIMULATED = Path(__file__).resolve().parents[1] / "docs" / "results" / "draws" / "draws.csv"


def paired(rows, sims: Path = SIMULATED) -> list[str]:
    """The same draws as nlos_cl simulated them (docs/results/draws/draws.csv, the default
    estimator): both distributions over the draws rendered here, and every draw whose error moved by
    more than 2 cm between the two."""
    if not sims.exists():
        return []
    with open(sims, newline="") as f:
        sim = {(r["family"], r["index"]): r for r in csv.DictReader(f)
               if r["estimator"] == "default"}
    pairs = [(r, sim[(r["family"], r["index"])]) for r in rows
             if r["estimator"] == "default" and (r["family"], r["index"]) in sim]
    if not pairs:
        return []
    out = ["## The same draws, simulated by nlos_cl (docs/results/draws/draws.csv, default "
           "estimator)", "",
           "| family | layouts | n | rendered: median / p90 (m) | simulated: median / p90 (m) |",
           "|---|---|---|---|---|"]
    for family in sorted({r["family"] for r, _ in pairs}):
        for name, keep in (("all", lambda r: True),
                           ("off a line", lambda r: not str(r["layout"]).startswith("line"))):
            part = [(a, b) for a, b in pairs if a["family"] == family and keep(a)]
            ren = np.array([float(a["error_m"]) for a, _ in part])
            sm = np.array([float(b["error_m"]) for _, b in part])
            out.append(f"| {family} | {name} | {len(part)} | {np.median(ren):.4f} / "
                       f"{np.percentile(ren, 90):.4f} | {np.median(sm):.4f} / "
                       f"{np.percentile(sm, 90):.4f} |")
    moved = [(a, b) for a, b in pairs if abs(float(a["error_m"]) - float(b["error_m"])) > 0.02]
    out += ["", f"Draws whose error moved by more than 0.02 m ({len(moved)} of {len(pairs)}):", "",
            "| family | index | target | layout | spots | SNR dB | rendered (m) | simulated (m) "
            "| fitted (rendered) |", "|---|---|---|---|---|---|---|---|---|"]
    out += [f"| {a['family']} | {a['index']} | {a['sub']} | {a['layout']} | {a['spots']} | "
            f"{float(a['snr_db']):.1f} | {float(a['error_m']):.4f} | {float(b['error_m']):.4f} | "
            f"{a.get('fitted', '')} |" for a, b in moved]
    return out


def write_page(out: Path, doc: Path):
    """The page from a finished folder: its draws-rendered.csv and the locate step's time; the
    CSV is copied beside the page."""
    with open(out / "draws-rendered.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    table = (out / "draws-rendered.md").read_text()
    seconds = json.loads((out / "locate.json").read_text())["seconds"]
    doc.write_text(page(rows, table, out, seconds))
    doc.with_suffix(".csv").write_text((out / "draws-rendered.csv").read_text())


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("step", choices=("export", "render", "locate", "page"))
    parser.add_argument("--out", type=Path, default=Path("out/mitransient-draws"))
    parser.add_argument("--start", type=int, default=0, help="first draw index")
    parser.add_argument("--count", type=int, default=20, help="draws (of --family)")
    parser.add_argument("--spp", type=int, default=2 ** 18, help="samples per spot")
    parser.add_argument("--splits", type=int, default=2,
                        help="independent renders per spot (their spread: the MC noise column)")
    parser.add_argument("--family", choices=FAMILIES, default="one",
                        help="export: which draws (reproduce draws' families of one target)")
    parser.add_argument("--doc", type=Path, default=None,
                        help="locate, page: write this page (and its .csv beside it) from "
                        "--out's located draws")
    parser.add_argument("--jobs", type=int, default=1, help="locate: draws located at once")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.step == "export":
        export(args.out, _indices(args), args.family)
    elif args.step == "render":
        render(args.out, _indices(args), args.spp, args.splits)
    elif args.step == "locate":
        start = time.perf_counter()
        locate(args.out, _indices(args), args.jobs)
        (args.out / "locate.json").write_text(json.dumps(
            {"seconds": time.perf_counter() - start}))
    if args.doc and args.step in ("locate", "page"):
        write_page(args.out, args.doc)


if __name__ == "__main__":
    main()
