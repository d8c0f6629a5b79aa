"""nlos_cl's forward model against mitransient 1.3.1 (Mitsuba 3.9.1): three steps, two venvs.

  export  (.venv)              : each scene's target meshes as PLY, and nlos_cl's histograms
  render  (.venv-mitransient)  : transient_nlos_path, max_depth 3, first and last bounces
                                 excluded: the histogram of hidden path r1 + r2 per spot
  compare (.venv)              : renders convolved with the same bin-integrated pulse, scaled
                                 by W per render unit derived from both sides' definitions (no
                                 fit); energy per detector, onset (first bin over 5 % of the
                                 peak) and shape (max difference / peak), with the shape's
                                 Monte Carlo noise from the independent renders (--splits)

`reference` (a 4 mm facet, not rendered by default) shows a limit of the renderer: the ray from
the wall to a hidden-geometry sample leaves 1500 float32 epsilons x (1 + |p|) (0.1-0.2 mm) off the
wall, lands that far off the sample and misses a 0.1-0.2 mm strip at a mesh's outer edges: a 4 mm
facet loses 3.5-6 % (per detector), a 0.3 m plate 0.05 %.
Run through scripts/mitransient_check.sh. Point spots here: mitransient's nlos_capture_meter
measures the exact pixel centres and the laser is focused on one point; disk spots are checked by
scripts/mitransient_spots.py. `--facet` sets nlos_cl's facet size (the renders do not use it).
"""
from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

BIN_M = 0.002  # 2 mm of path per bin
SPOTS = [[-1.5, 0, 0], [-1.0, 0, 0], [-0.5, 0, 0]]  # + the laser spot's own pixel at x = 0
WALL_BRDF = 0.2579
SPLITS = 4  # independent renders (seeds) per scene, for the Monte Carlo noise (--splits)
OCCLUDING = ("l_block", "two_plates")  # rendered with BSDF sampling (see render)
# the device: 20 m from the wall on the hidden side, above the targets (rays pass over them)
DEVICE = [-0.75, 20 / math.sqrt(2), 20 / math.sqrt(2)]


def scenes():
    """name -> (list of (mesh, reflectance spec)) built with nlos_cl (in .venv)."""
    import nlos_cl as nl
    from nlos_cl.physics.meshes import l_block
    from nlos_cl.physics.reflectance import GGX
    lam = lambda m, f=0.1284: (m, {"model": "lambertian", "brdf": f})  # noqa: E731
    return {
        "reference": [lam(nl.rectangle(0.004, 0.004, centre=(1.0, 1.5, 0.0), cell_m=0.01))],
        "plate": [lam(nl.rectangle(0.3, 0.6, centre=(1.0, 1.5, 0.0)))],
        "box": [lam(nl.box((0.3, 0.3, 0.6), (1.0, 1.5, 0.0)))],
        "sphere": [lam(nl.sphere(0.25, (1.0, 1.6, 0.0)))],
        "l_block": [lam(l_block(centre=(0.9, 1.4, 0.0)))],
        # mitransient_spots.py's plate (30 cm from the wall, beside the spots), point spots
        "near_plate": [lam(nl.rectangle(0.2, 0.2, centre=(-0.75, 0.3, 0.1), normal=(0, -1, 0)))],
        "two_plates": [lam(nl.rectangle(0.3, 0.3, centre=(0.8, 1.2, 0.0))),
                       lam(nl.rectangle(0.5, 0.5, centre=(1.1, 1.8, 0.05)))],
        "glossy": [(nl.rectangle(0.5, 0.5, centre=(-0.6, 1.2, 0.0), normal=(0, -1, 0)),
                    {"model": "ggx", "specular": 0.6, "roughness": 0.3, "diffuse": 0.2})],
    }, nl, GGX


def export(out: Path, names, facet_m: float = 0.01):
    all_scenes, nl, GGX = scenes()
    from nlos_cl.physics.reflectance import from_spec
    setup = nl.paper_setup(detector_spots=SPOTS)
    for name in names:
        parts = all_scenes[name]
        targets = [nl.Target(m, brdf=from_spec(spec)) for m, spec in parts]
        for i, (mesh, _) in enumerate(parts):
            mesh.export(out / f"{name}_{i}.ply")
        meta = {"targets": [spec for _, spec in parts]}
        for occlusion in (False, True):  # on last: its time is the table's (visibility included)
            scene = nl.Scene(setup, targets[0], facet_m, more_targets=tuple(targets[1:]),
                             occlusion=occlusion)
            paths = np.concatenate([np.linalg.norm(m.vertices, axis=1) for m, _ in parts])
            start = max(paths.min() + 0.3, 0.5)
            t0 = (2 * setup.device_distance_m + start - 0.3) / nl.SPEED_OF_LIGHT \
                + setup.pulse.peak_delay_s
            axis = nl.TimeAxis(t0, BIN_M / nl.SPEED_OF_LIGHT, 3000)
            t0 = time.perf_counter()
            hist = nl.simulate(scene, axis).histograms()
            meta["nlos_seconds"] = time.perf_counter() - t0
            np.save(out / f"{name}_nlos_{'on' if occlusion else 'off'}.npy", hist.data)
        # nlos_cl's W per unit of (f_c f_w^2 x integral of the four cosines / (r1^2 r2^2) dA):
        # E / dt x S_d A / d^2 (Setup.power_scale without the BRDFs)
        meta.update(start_opl=float(start - 0.3), sigma_m=nl.SPEED_OF_LIGHT * setup.pulse.sigma_s,
                    watts=0.5 * setup.pulse.energy_j / axis.dt_s,
                    nlos_units=setup.pulse.energy_j / axis.dt_s * setup.power_scale(1.0)
                    / setup.wall_brdf ** 2)
        (out / f"{name}.json").write_text(json.dumps(meta))


def _bsdf(spec):
    if spec["model"] == "lambertian":
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": spec["brdf"] * math.pi}}
    conductor = {"type": "roughconductor", "distribution": "ggx", "alpha": spec["roughness"],
                 "material": "none", "sample_visible": True,
                 "specular_reflectance": {"type": "rgb", "value": 1.0}}
    w = spec["specular"] / (spec["specular"] + spec["diffuse"])
    diffuse = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 1.0}}
    # f = (1 - w) D / pi + w GGX, times (specular + diffuse): both albedos through `scale`
    return {"type": "blendbsdf", "weight": w, "bsdf_0": diffuse, "bsdf_1": conductor}, \
        spec["specular"] + spec["diffuse"]


def render(out: Path, names, spp: int, splits: int = SPLITS):
    import mitsuba as mi
    mi.set_variant("llvm_ad_mono" if "llvm_ad_mono" in mi.variants() else "llvm_ad_rgb")
    import drjit as dr
    import mitransient as mitr  # noqa: F401  (registers the plugins)
    from mitsuba import ScalarTransform4f as T
    for name in names:
        meta = json.loads((out / f"{name}.json").read_text())
        wall = {"type": "rectangle", "id": "relay_wall",
                "to_world": T().translate([-0.75, 0, 0]) @ T().rotate([1, 0, 0], -90)
                @ T().scale([1.0, 0.5, 1.0]),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": WALL_BRDF
                                                            * math.pi}},
                "nlos_sensor": {"type": "nlos_capture_meter", "sensor_origin": DEVICE,
                                "film": {"type": "transient_hdr_film", "width": 4, "height": 1,
                                         "temporal_bins": 3000, "bin_width_opl": BIN_M,
                                         "start_opl": meta["start_opl"],
                                         "rfilter": {"type": "box"}}}}
        desc = {"type": "scene", "relay_wall": wall,
                "integrator": {"type": "transient_nlos_path", "max_depth": 3,
                               "nlos_laser_sampling": True,
                               # hidden-geometry sampling aims at a point and takes whatever
                               # the ray hits first with that point's density: biased where a
                               # ray from the wall crosses targets twice (occlusion, concave
                               # meshes); cosine (BSDF) sampling is unbiased there
                               "nlos_hidden_geometry_sampling": name not in OCCLUDING,
                               "account_first_and_last_bounces": False},
                "laser": {"type": "projector", "id": "laser", "fov": 0.05,
                          "to_world": T().translate(DEVICE), "irradiance": 1.0}}
        scales = []
        for i, spec in enumerate(meta["targets"]):
            bsdf = _bsdf(spec)
            scale = 1.0
            if isinstance(bsdf, tuple):
                bsdf, scale = bsdf
            scales.append(scale)
            desc[f"target_{i}"] = {"type": "ply", "filename": str(out / f"{name}_{i}.ply"),
                                   "bsdf": bsdf, "face_normals": True}
        scene = mi.load_dict(desc)
        relay = [s for s in scene.shapes() if s.id() == "relay_wall"][0]
        mitr.nlos.focus_emitter_at_relay_wall_3dpoint(mi.Point3f(0, 0, 0), relay,
                                                      scene.emitters()[0])
        # mitransient's units, from its own laser: a pixel measures the radiance f_w x E_t x ...,
        # i.e. f_c f_w^2 cos(laser spot -> device) E_laser x the same integral as nlos_cl's
        it = dr.zeros(mi.Interaction3f)
        it.p = mi.Point3f(0, 0, 0)
        _, e_laser = scene.emitters()[0].sample_direction(it, mi.Point2f(0.5, 0.5))
        e_laser = float(np.array(e_laser).ravel()[0])
        cos_device = DEVICE[1] / float(np.linalg.norm(DEVICE))
        render_splits(mi, scene, out / name, spp, splits, scales[0],
                      {"e_laser": e_laser, "cos_device": cos_device})


def render_splits(mi, scene, prefix: Path, spp: int, splits: int, scale: float, units: dict):
    """`splits` independent renders (seeds): their mean, each one (for the shape noise) and the
    energy's standard error, in PREFIX_render.npy / _render_splits.npy / _render.json with the
    render's units (e_laser, cos_device)."""
    t0 = time.perf_counter()
    parts = np.array([np.array(mi.render(scene, spp=max(1, spp // splits), seed=seed)[1])
                      [0, :, :, 0] * scale for seed in range(splits)])  # (splits, pixels, bins)
    seconds = time.perf_counter() - t0
    energy = parts.sum(axis=2)
    noise = energy.std(axis=0, ddof=1) / math.sqrt(splits) / energy.mean(axis=0)
    np.save(f"{prefix}_render.npy", parts.mean(axis=0))
    np.save(f"{prefix}_render_splits.npy", parts.astype(np.float32))
    Path(f"{prefix}_render.json").write_text(json.dumps(
        {"spp": splits * max(1, spp // splits), "seconds": seconds, "noise": noise[:3].tolist(),
         **units}))


def _pulse_convolve(data, sigma_m, bin_m=BIN_M):
    """Each row convolved with the bin-integrated Gaussian pulse (to 6 sigma), centred: the
    time axes already hold the pulse's peak delay."""
    from scipy.special import erf
    half = int(math.ceil(6 * sigma_m / bin_m))
    k = np.arange(-half, half + 1)
    taps = 0.5 * (erf((k + 0.5) * bin_m / (math.sqrt(2) * sigma_m))
                  - erf((k - 0.5) * bin_m / (math.sqrt(2) * sigma_m)))
    return np.stack([np.convolve(row, taps, mode="same") for row in np.asarray(data, float)])


def onset(h):
    """First bin over 5 % of the peak."""
    return int(np.argmax(h > 0.05 * h.max()))


def render_in_watts(out: Path, name: str, meta: dict, rmeta: dict):
    """The render of detectors 0-2 in W per bin (pulse-convolved, scaled by the fixed W per
    render unit), its per-bin Monte Carlo sigma (spread of the splits / sqrt(splits)), and the
    shape noise: max |mean of even splits - mean of odd splits| / 2 / peak, which has the same
    distribution as the max-norm error of the full mean when the two halves are equal."""
    k = meta["nlos_units"] / (rmeta["cos_device"] * rmeta["e_laser"])
    split_file = out / f"{name}_render_splits.npy"
    if not split_file.exists():  # renders from before the splits were kept
        return k * _pulse_convolve(np.load(out / f"{name}_render.npy")[:3], meta["sigma_m"]), \
            None, None
    parts = np.array([k * _pulse_convolve(p[:3].astype(np.float64), meta["sigma_m"])
                      for p in np.load(split_file)])
    mean = parts.mean(axis=0)
    sigma = parts.std(axis=0, ddof=1) / math.sqrt(len(parts))
    half = np.abs(parts[0::2].mean(axis=0) - parts[1::2].mean(axis=0)).max(axis=1) / 2
    return mean, sigma, half / mean.max(axis=1)


def shape_columns(model, r, sigma, half, d):
    """Shape (% of peak), its half-split noise and the part of it beyond 4 sigma per bin
    (4 sigma: over ~10^3 bins a Gaussian passes it with probability ~6 %)."""
    peak = r[d].max()
    diff = np.abs(model[d] - r[d])
    if sigma is None:
        return f"{100 * diff.max() / peak:.2f} | - | -"
    beyond = np.maximum(diff - 4 * sigma[d], 0).max() / peak
    return f"{100 * diff.max() / peak:.2f} | {100 * half[d]:.2f} | {100 * beyond:.2f}"


def compare(out: Path, names):
    """No constant is fitted: W per render unit follows from both sides' definitions (nlos_cl's
    Setup.power_scale, mitransient's laser irradiance and the wall's cosine towards the device),
    the same for every scene."""
    rows = ["| scene | detector | energy, occlusion on | off | onset (bins) | shape (% of peak) "
            "| shape noise | shape beyond 4 sigma | MC noise (energy) | spp | render s "
            "| nlos_cl s |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name in names:
        meta = json.loads((out / f"{name}.json").read_text())
        rmeta = json.loads((out / f"{name}_render.json").read_text())
        r, sigma, half = render_in_watts(out, name, meta, rmeta)
        on, off = (np.load(out / f"{name}_nlos_{s}.npy") for s in ("on", "off"))
        noise = rmeta.get("noise")
        for d in range(3):
            e_on, e_off = on[d].sum() / r[d].sum() - 1, off[d].sum() / r[d].sum() - 1
            mc = f"{100 * noise[d]:.2f} %" if noise else "-"
            rows.append(f"| {name} | {d} | {100 * e_on:+.2f} % | {100 * e_off:+.2f} % | "
                        f"{onset(on[d]) - onset(r[d]):+d} | {shape_columns(on, r, sigma, half, d)}"
                        f" | {mc} | {rmeta['spp']} | {rmeta['seconds']:.1f} | "
                        f"{meta.get('nlos_seconds', float('nan')):.2f} |")
    write_table(out / "table.md", rows)


def write_table(path: Path, rows):
    table = "\n".join(rows)
    path.write_text(table + "\n")
    print(table)


def step_parser(spp: int, splits: int) -> argparse.ArgumentParser:
    """The arguments of both check scripts (this one and mitransient_spots.py)."""
    parser = argparse.ArgumentParser()
    parser.add_argument("step", choices=("export", "render", "compare"))
    parser.add_argument("--out", type=Path, default=Path("out/mitransient"))
    parser.add_argument("--spp", type=int, default=spp)
    parser.add_argument("--splits", type=int, default=splits,
                        help="independent renders per scene (even: the shape noise halves them)")
    return parser


def main():
    parser = step_parser(2 ** 16, SPLITS)
    parser.add_argument("--scenes", default="plate,box,sphere,l_block,two_plates,glossy")
    parser.add_argument("--facet", type=float, default=0.01,
                        help="nlos_cl's facet size in m (export only; the renders do not use it)")
    args = parser.parse_args()
    names = args.scenes.split(",")
    args.out.mkdir(parents=True, exist_ok=True)
    if args.step == "export":
        export(args.out, names, args.facet)
    elif args.step == "render":
        render(args.out, names, args.spp, args.splits)
    else:
        compare(args.out, names)


if __name__ == "__main__":
    main()
