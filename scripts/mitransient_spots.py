"""Finite spots against mitransient: the laser spot and the detector spots rendered as disks by the
renderer's own area sampling, independent of nlos_cl's 7-point disk rule. Three steps, two venvs,
like mitransient_check.py (whose units, pulse and comparison helpers it reuses):

  export  (.venv)              : the target as PLY; nlos_cl's histograms with point and disk spots
  render  (.venv-mitransient)  : two cases, "disk" (7 cm laser, 10 cm detector spots) and "tiny"
                                 (0.5 mm disks: the same machinery against point-spot nlos_cl)
  compare (.venv)              : energy, onset and shape per detector, as in mitransient_check.py

How the renderer sees disks (nothing of nlos_cl's quadrature enters):
- Laser spot: a Mitsuba `disk` shape on the wall with an `area` emitter of uniform radiance
  f_w / (pi r^2): exactly what a uniformly lit Lambertian disk sends out. The integrator reaches it
  by next-event estimation (Mitsuba samples the disk uniformly by area), not by laser sampling,
  which aims at one point.
- Detector spots: `disk_meter` (below), mitransient's nlos_capture_meter whose samples land
  uniformly on a disk around each pixel centre (Mitsuba's concentric disk warp) instead of on the
  centre itself; each ray comes straight down from RAY_HEIGHT so that the sensor leg is the same
  constant for every point of the disk (nlos_cl takes the device distance as the same for all
  points of a disk too). A pixel is the wall's radiance averaged over the disk.

Two workarounds for mitransient 1.3.1 (measured in this set-up, see docs/physics.md):
- account_first_and_last_bounces=True is needed here (the target -> laser-disk leg is the NEE's
  "last bounce"), and then TransientNLOSPath.emitter_nee_sample adds the NEE distance to the
  caller's `distance` in place (drjit `+=`): the wall vertex's NEE towards the laser disk put
  |detector - laser| (1.0-1.5 m) into every later vertex's path. `NeeCopy` passes it a copy.
- Hidden-geometry sampling at the target vertex also picks points on the laser disk (it samples
  every shape but the relay wall) and counts those hits on top of the NEE, which carries no MIS
  weight: with 0.5 mm disks the energy came out 1.52x and 2.31x too high (detectors 0, 1). It is
  limited to the wall vertex (max depth 1); the target uses BSDF sampling, whose rare hits on the
  disk carry an MIS weight below 2e-6 (p_bsdf <= 1/pi against p_nee = r^2 / (A cos) >= 260 per
  sr for the 7 cm disk); with it the 0.5 mm case meets point-spot nlos_cl (the table).
"""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mitransient_check import (BIN_M, SPOTS, WALL_BRDF, onset,  # noqa: E402
                               render_in_watts, render_splits, shape_columns, step_parser,
                               write_table)

SPLITS = 8  # independent renders per case (seeds): energy noise and the half-split shape noise
RAY_HEIGHT = 0.01  # the disk meter's rays start 1 cm above the wall: below every target
START_OPL = 0.5  # hidden path r1 + r2 of bin 0 (the nearest point of the target is ~1.0 m)
CASES = {"disk": (0.035, 0.05), "tiny": (0.0005, 0.0005)}  # (laser, detector) disk radii, m
BRDF = 0.1284
# a 20 cm plate 30 cm from the wall facing it, beside the spots: the disks' nearest points
# shorten its shortest path by 2-8 cm (the laser disk alone by up to 3.2 cm)
PLATE = dict(width=0.2, height=0.2, centre=(-0.75, 0.3, 0.1), normal=(0, -1, 0))


def export(out: Path):
    import nlos_cl as nl
    mesh = nl.rectangle(PLATE["width"], PLATE["height"], centre=PLATE["centre"],
                        normal=PLATE["normal"])
    mesh.export(out / "spots_0.ply")
    meta = {"start_opl": START_OPL}
    for kind, finite in (("point", False), ("point", False), ("disk", True)):  # 1st: warm-up
        setup = nl.paper_setup(detector_spots=SPOTS, finite_spots=finite)
        scene = nl.Scene(setup, nl.Target(mesh, brdf=BRDF), 0.01)
        t0 = (2 * setup.device_distance_m + START_OPL) / nl.SPEED_OF_LIGHT \
            + setup.pulse.peak_delay_s
        axis = nl.TimeAxis(t0, BIN_M / nl.SPEED_OF_LIGHT, 3000)
        start = time.perf_counter()
        hist = nl.simulate(scene, axis).histograms()
        meta[f"nlos_seconds_{kind}"] = time.perf_counter() - start
        np.save(out / f"spots_nlos_{kind}.npy", hist.data)
        # W per unit of f_c f_w^2 x (mean over the disks of) the four-cosine integral
        meta.update(sigma_m=nl.SPEED_OF_LIGHT * setup.pulse.sigma_s,
                    nlos_units=setup.pulse.energy_j / axis.dt_s * setup.power_scale(1.0)
                    / setup.wall_brdf ** 2)
    (out / "spots.json").write_text(json.dumps(meta))


def _register(mi):
    """The disk meter and the integrator with the NEE distance copied (module docstring)."""
    import drjit as dr
    from mitransient.integrators.transientnlospath import TransientNLOSPath
    from mitransient.sensors.nloscapturemeter import NLOSCaptureMeter

    class DiskMeter(NLOSCaptureMeter):
        def __init__(self, props):
            super().__init__(props)
            self.radius = props.get("spot_radius", 0.05)

        def _ray(self, sample):
            cell = dr.floor(sample * self.film_size)  # the pixel; the rest picks the point
            centre = self.get_shape().sample_position(0.0, (cell + 0.5) / self.film_size).p
            disk = mi.warp.square_to_uniform_disk_concentric(sample * self.film_size - cell)
            p = centre + mi.Vector3f(disk.x, 0.0, disk.y) * self.radius  # the wall is y = 0
            return mi.RayDifferential3f(p + mi.Vector3f(0.0, RAY_HEIGHT, 0.0),
                                        mi.Vector3f(0.0, -1.0, 0.0), 0.0, [])

        def sample_ray(self, time, sample1, sample2, sample3, active=True):
            return self._ray(sample2), mi.Spectrum(1.0)  # radiance, as nlos_capture_meter

        def sample_ray_differential(self, time, sample1, sample2, sample3, active=True):
            return self._ray(sample2), mi.Spectrum(1.0)

    class NeeCopy(TransientNLOSPath):
        def emitter_nee_sample(self, mode, scene, sampler, si, bsdf, bsdf_ctx, beta, distance,
                               eta, depth, active_e, add_transient, **kwargs):
            return super().emitter_nee_sample(mode, scene, sampler, si, bsdf, bsdf_ctx, beta,
                                              mi.Float(distance), eta, depth, active_e,
                                              add_transient, **kwargs)

    mi.register_sensor("disk_meter", lambda props: DiskMeter(props))
    mi.register_integrator("transient_nlos_path_nee_copy", lambda props: NeeCopy(props))


def _scene_dict(mi, out: Path, laser_r: float, detector_r: float) -> dict:
    from mitsuba import ScalarTransform4f as T
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}}
    flat = T().rotate([1, 0, 0], -90)  # a unit shape in z = 0 onto the wall, normal +y
    film = {"type": "transient_hdr_film", "width": 3, "height": 1, "temporal_bins": 3000,
            "bin_width_opl": BIN_M, "start_opl": START_OPL + RAY_HEIGHT,
            "rfilter": {"type": "box"}}
    return {
        "type": "scene",
        "integrator": {"type": "transient_nlos_path_nee_copy", "max_depth": 3,
                       "nlos_laser_sampling": False, "nlos_hidden_geometry_sampling": True,
                       "nlos_hidden_geometry_sampling_max_depth": 1,
                       "account_first_and_last_bounces": True},
        # x in [-1.75, -0.25]: three pixels centred on the detector spots of SPOTS
        "relay_wall": {"type": "rectangle", "id": "relay_wall",
                       "to_world": T().translate([-1.0, 0, 0]) @ flat @ T().scale([0.75, 0.5, 1]),
                       "bsdf": {"type": "diffuse",
                                "reflectance": {"type": "rgb", "value": WALL_BRDF * math.pi}},
                       "nlos_sensor": {"type": "disk_meter", "spot_radius": detector_r,
                                       "film": film}},
        # the lit laser spot: f_w x unit irradiance spread over the disk (nlos_units' unit)
        "laser_spot": {"type": "disk", "to_world": flat @ T().scale([laser_r, laser_r, 1]),
                       "bsdf": black,
                       "emitter": {"type": "area", "radiance": {
                           "type": "rgb", "value": WALL_BRDF / (math.pi * laser_r ** 2)}}},
        "target": {"type": "ply", "filename": str(out / "spots_0.ply"), "face_normals": True,
                   "bsdf": {"type": "diffuse",
                            "reflectance": {"type": "rgb", "value": BRDF * math.pi}}},
    }


def render(out: Path, spp: int, splits: int):
    import mitsuba as mi
    mi.set_variant("llvm_ad_mono" if "llvm_ad_mono" in mi.variants() else "llvm_ad_rgb")
    import mitransient  # noqa: F401  (registers the plugins)
    _register(mi)
    for case, (laser_r, detector_r) in CASES.items():
        scene = mi.load_dict(_scene_dict(mi, out, laser_r, detector_r))
        # the laser spot is f_w x 1 by construction: no projector, no cosine to the device
        render_splits(mi, scene, out / f"spots_{case}", spp, splits, 1.0,
                      {"e_laser": 1.0, "cos_device": 1.0})


def compare(out: Path):
    meta = json.loads((out / "spots.json").read_text())
    model = {k: np.load(out / f"spots_nlos_{k}.npy") for k in ("point", "disk")}
    rows = ["| nlos_cl spots | render spots | detector | energy | onset (bins) | shape (% of peak) "
            "| shape noise | shape beyond 4 sigma | MC noise (energy) | render onset vs "
            "0.5 mm disks (bins) | spp | render s | nlos_cl s |", "|---" * 13 + "|"]
    renders = {}
    for case in CASES:
        rmeta = json.loads((out / f"spots_{case}_render.json").read_text())
        renders[case] = render_in_watts(out, f"spots_{case}", meta, rmeta), rmeta
    for kind, case in (("point", "tiny"), ("disk", "disk"), ("point", "disk")):
        (r, sigma, half), rmeta = renders[case]
        h = model[kind]
        for d in range(3):
            moved = onset(r[d]) - onset(renders["tiny"][0][0][d])
            rows.append(f"| {kind} | {'0.5 mm disks' if case == 'tiny' else '7 / 10 cm disks'} "
                        f"| {d} | {100 * (h[d].sum() / r[d].sum() - 1):+.2f} % | "
                        f"{onset(h[d]) - onset(r[d]):+d} | {shape_columns(h, r, sigma, half, d)} "
                        f"| {100 * rmeta['noise'][d]:.2f} % | {moved:+d} | {rmeta['spp']} | "
                        f"{rmeta['seconds']:.1f} | {meta[f'nlos_seconds_{kind}']:.2f} |")
    write_table(out / "spots_table.md", rows)


def main():
    args = step_parser(2 ** 24, SPLITS).parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    {"export": lambda: export(args.out), "compare": lambda: compare(args.out),
     "render": lambda: render(args.out, args.spp, args.splits)}[args.step]()


if __name__ == "__main__":
    main()
