"""nlos_cl's forward model against mitransient 1.3.1 (Mitsuba 3.9.1): three steps, two venvs.

  export  (.venv)              : each scene's target meshes as PLY, and nlos_cl's histograms
  render  (.venv-mitransient)  : transient_nlos_path, max_depth 3, first and last bounces
                                 excluded: the histogram of hidden path r1 + r2 per spot
  compare (.venv)              : renders convolved with the same bin-integrated pulse, scaled
                                 by W per render unit derived from both sides' definitions (no
                                 fit); energy per detector, onset (first bin over 5 % of the
                                 peak) and shape (max difference / peak)

`reference` (a 4 mm facet, not rendered by default) shows a limit of the renderer: the ray from
the wall to a hidden-geometry sample leaves 1500 float32 epsilons x (1 + |p|) (0.1-0.2 mm) off the
wall, lands that far off the sample and misses a 0.1-0.2 mm strip at a mesh's outer edges: a 4 mm
facet loses 3.5-6 % (per detector), a 0.3 m plate 0.05 %.
Run through scripts/mitransient_check.sh. Point spots only: mitransient's nlos_capture_meter
measures the exact pixel centres and the laser is focused on one point.
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
SPLITS = 4
OCCLUDING = ("l_block", "two_plates")  # rendered with BSDF sampling (see render)  # independent renders per scene, for the Monte Carlo noise
# the device: 20 m from the wall on the hidden side, above the targets (rays pass over them)
DEVICE = [-0.75, 20 / math.sqrt(2), 20 / math.sqrt(2)]


def scenes():
    """name -> (list of (mesh, reflectance spec)) built with nlos_cl (in .venv)."""
    import nlos_cl as nl
    from nlos_cl.meshes import l_block
    from nlos_cl.reflectance import GGX
    lam = lambda m, f=0.1284: (m, {"model": "lambertian", "brdf": f})  # noqa: E731
    return {
        "reference": [lam(nl.rectangle(0.004, 0.004, centre=(1.0, 1.5, 0.0), cell_m=0.01))],
        "plate": [lam(nl.rectangle(0.3, 0.6, centre=(1.0, 1.5, 0.0)))],
        "box": [lam(nl.box((0.3, 0.3, 0.6), (1.0, 1.5, 0.0)))],
        "sphere": [lam(nl.sphere(0.25, (1.0, 1.6, 0.0)))],
        "l_block": [lam(l_block(centre=(0.9, 1.4, 0.0)))],
        "two_plates": [lam(nl.rectangle(0.3, 0.3, centre=(0.8, 1.2, 0.0))),
                       lam(nl.rectangle(0.5, 0.5, centre=(1.1, 1.8, 0.05)))],
        "glossy": [(nl.rectangle(0.5, 0.5, centre=(-0.6, 1.2, 0.0), normal=(0, -1, 0)),
                    {"model": "ggx", "specular": 0.6, "roughness": 0.3, "diffuse": 0.2})],
    }, nl, GGX


def export(out: Path, names):
    all_scenes, nl, GGX = scenes()
    from nlos_cl.reflectance import from_spec
    setup = nl.paper_setup(detector_spots=SPOTS)
    for name in names:
        parts = all_scenes[name]
        targets = [nl.Target(m, brdf=from_spec(spec)) for m, spec in parts]
        for i, (mesh, _) in enumerate(parts):
            mesh.export(out / f"{name}_{i}.ply")
        meta = {"targets": [spec for _, spec in parts]}
        for occlusion in (True, False):
            scene = nl.Scene(setup, targets[0], 0.01, more_targets=tuple(targets[1:]),
                             occlusion=occlusion)
            paths = np.concatenate([np.linalg.norm(m.vertices, axis=1) for m, _ in parts])
            start = max(paths.min() + 0.3, 0.5)
            t0 = (2 * setup.device_distance_m + start - 0.3) / nl.SPEED_OF_LIGHT \
                + setup.pulse.peak_delay_s
            axis = nl.TimeAxis(t0, BIN_M / nl.SPEED_OF_LIGHT, 3000)
            hist = nl.simulate(scene, axis).histograms()
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


def render(out: Path, names, spp: int):
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
        t0 = time.perf_counter()
        parts = []  # SPLITS independent renders (seeds): their spread is the Monte Carlo noise
        for seed in range(SPLITS):
            _, transient = mi.render(scene, spp=max(1, spp // SPLITS), seed=seed)
            parts.append(np.array(transient)[0, :, :, 0] * scales[0])  # (4 pixels, bins)
        seconds = time.perf_counter() - t0
        parts = np.array(parts)
        energy = parts.sum(axis=2)  # (SPLITS, pixels)
        noise = energy.std(axis=0, ddof=1) / math.sqrt(SPLITS) / energy.mean(axis=0)
        np.save(out / f"{name}_render.npy", parts.mean(axis=0))
        (out / f"{name}_render.json").write_text(json.dumps(
            {"spp": SPLITS * max(1, spp // SPLITS), "seconds": seconds, "e_laser": e_laser,
             "cos_device": cos_device, "noise": noise[:3].tolist()}))


def _pulse_convolve(data, sigma_m):
    from scipy.special import erf
    half = int(math.ceil(6 * sigma_m / BIN_M))
    k = np.arange(-half, half + 1)
    taps = 0.5 * (erf((k + 0.5) * BIN_M / (math.sqrt(2) * sigma_m))
                  - erf((k - 0.5) * BIN_M / (math.sqrt(2) * sigma_m)))
    return np.stack([np.convolve(row, taps, mode="same") for row in data])


def compare(out: Path, names):
    """No constant is fitted: W per render unit follows from both sides' definitions (nlos_cl's
    Setup.power_scale, mitransient's laser irradiance and the wall's cosine towards the device),
    the same for every scene."""
    rows = ["| scene | detector | energy, occlusion on | off | onset (bins) | shape (% of peak) "
            "| MC noise (energy) | spp | render s |",
            "|---|---|---|---|---|---|---|---|---|"]
    for name in names:
        meta = json.loads((out / f"{name}.json").read_text())
        rmeta = json.loads((out / f"{name}_render.json").read_text())
        k = meta["nlos_units"] / (rmeta["cos_device"] * rmeta["e_laser"])
        raw = np.load(out / f"{name}_render.npy")[:3]
        r = k * _pulse_convolve(raw, meta["sigma_m"])
        on, off = (np.load(out / f"{name}_nlos_{s}.npy") for s in ("on", "off"))
        noise = rmeta.get("noise")
        for d in range(3):
            lead = lambda h: int(np.argmax(h > 0.05 * h.max()))  # noqa: E731
            e_on, e_off = on[d].sum() / r[d].sum() - 1, off[d].sum() / r[d].sum() - 1
            shape = np.abs(on[d] - r[d]).max() / r[d].max()
            mc = f"{100 * noise[d]:.2f} %" if noise else "-"
            rows.append(f"| {name} | {d} | {100 * e_on:+.2f} % | {100 * e_off:+.2f} % | "
                        f"{lead(on[d]) - lead(r[d]):+d} | {100 * shape:.2f} | {mc} | "
                        f"{rmeta['spp']} | {rmeta['seconds']:.1f} |")
    table = "\n".join(rows)
    (out / "table.md").write_text(table + "\n")
    print(table)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("step", choices=("export", "render", "compare"))
    parser.add_argument("--out", type=Path, default=Path("out/mitransient"))
    parser.add_argument("--spp", type=int, default=2 ** 16)
    parser.add_argument("--scenes", default="plate,box,sphere,l_block,two_plates,glossy")
    args = parser.parse_args()
    names = args.scenes.split(",")
    args.out.mkdir(parents=True, exist_ok=True)
    if args.step == "export":
        export(args.out, names)
    elif args.step == "render":
        render(args.out, names, args.spp)
    else:
        compare(args.out, names)


if __name__ == "__main__":
    main()
