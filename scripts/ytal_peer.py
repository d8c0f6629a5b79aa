"""Real peers, both ways (run by scripts/ytal_peer.sh inside the y-tal venv, numpy < 2).

(a) nlos_cl writes captures (`nlos-cl simulate`, and the API for a small plate, in nlos_cl's
    own venv); y-tal reads them (`tal.io.read_capture`) and its backprojection
    (`tal.reconstruct.bp.solve`) must peak at the target (see check_ytal_reads_nlos).
(b) y-tal writes captures (`tal.io.write_capture`) of scenes placed in y-tal's frame (relay wall
    Z = 0, hidden space Z > 0, Y up; targets on both sides of X = 0), with histograms made here
    by an independent plate-scatterer model (no nlos_cl code); nlos_cl locates each:
    - `nlos-cl locate F.h5 --json` with no option: the position is taken in the frame the JSON
      declares (`frame`; none declared = the file's frame, as issue 10 requires);
    - the Python API: nl.locate_capture(path, estimator="paper") (the derived region, coarse
      -> zoom -> fine where its step was coarsened), positions in the file's frame.
(c) a confocal scan in LCT's published layout (a .mat with rect_data (Nx, Ny, T) and width,
    made here by an independent model of a small patch), converted by `nlos-cl convert`, is
    read by y-tal as the grid it is (T_Sx_Sy, X_Y_3, confocal) and reconstructed as it stands
    by tal.reconstruct.fk (f-k migration, which needs that grid) and tal.reconstruct.bp: both
    must peak at the patch (see check_ytal_reconstructs_converted_scan).
Exit 1 when any error exceeds TOLERANCE_M (or the backprojection misses); 0 otherwise.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import scipy.io
import yaml
from scipy.special import erf

import tal
from tal.enums import CameraSystem, GridFormat, HFormat, VolumeFormat

TOLERANCE_M = 0.05
BP_STEP_M, BP_CELLS = 0.02, 3
H_S = 0.65e-9
ROOT = Path(__file__).resolve().parent.parent
NLOS_PY = os.environ.get("NLOS_CL_PYTHON", str(ROOT / ".venv" / "bin" / "python"))
SENSORS = np.array([[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0]])
SENSORS_3D = np.array([[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0], [-1.0, 0.5, 0],
                       [-1.0, -0.5, 0]])
# (target centre in y-tal's frame, sensor layout, t_accounts_first_and_last_bounces)
SCENES = [((2.5, 0.0, 2.0), SENSORS, False), ((-3.0, 0.0, 1.5), SENSORS, True),
          ((4.0, 0.0, 2.0), SENSORS, False), ((1.0, 0.0, 3.5), SENSORS, True),
          ((-1.5, 0.0, 2.5), SENSORS, False), ((2.0, 0.4, 2.0), SENSORS_3D, True)]

API_CHECK = r"""
import json, sys
import nlos_cl as nl
out = []
for path in sys.argv[1:]:
    found = nl.locate_capture(path, estimator="paper", h_s=%(h)r)
    point = found.points[0]
    out.append({"position": point.position.tolist(), "frame": found.frame.name,
                "cells": point.region.n_cells, "step_m": point.region.step[0],
                "zoomed": point.zoomed, "on_edge": point.on_edge})
print(json.dumps(out))
""" % {"h": H_S}


def plate_histograms(centre, sensors, laser, delta_t, t_start, n_t, legs, seed,
                     size=0.3, cell=0.01, sigma_m=0.01):
    """A square Lambertian plate (0.3 m) facing the sensors' centre: each cell adds a Gaussian
    pulse
    (path sigma_m) at laser leg + |p - laser| + |p - sensor| + sensor leg, weighted by the four
    cosines and 1 / (r1^2 r2^2), integrated over each sample's [k - 1/2, k + 1/2) interval;
    2 % white noise. Independent of nlos_cl's code."""
    centre = np.asarray(centre, float)
    normal = sensors.mean(axis=0) - centre
    normal /= np.linalg.norm(normal)
    u = np.cross(normal, [0, 1.0, 0])
    u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-6 else np.array([1.0, 0, 0])
    v = np.cross(normal, u)
    ticks = (np.arange(int(round(size / cell))) + 0.5) * cell - size / 2
    a, b = np.meshgrid(ticks, ticks)
    pts = centre + a.reshape(-1, 1) * u + b.reshape(-1, 1) * v
    edges = t_start + (np.arange(n_t + 1) - 0.5) * delta_t
    H = np.zeros((n_t, len(sensors)))
    d1 = pts - laser
    r1 = np.linalg.norm(d1, axis=1)
    for i, s in enumerate(sensors):
        d2 = pts - s
        r2 = np.linalg.norm(d2, axis=1)
        cosines = (d1[:, 2] / r1) * (d2[:, 2] / r2) * np.clip(-(d1 @ normal) / r1, 0, None) \
            * np.clip(-(d2 @ normal) / r2, 0, None)
        weight = cosines * cell ** 2 / (r1 ** 2 * r2 ** 2)
        path = r1 + r2 + legs[0] + legs[1][i]
        cdf = 0.5 * (1 + erf((edges[None, :] - path[:, None]) / (np.sqrt(2) * sigma_m)))
        H[:, i] = (weight[:, None] * np.diff(cdf, axis=1)).sum(axis=0)
    rng = np.random.default_rng(seed)
    return (H + rng.normal(0, 0.02 * H.max(), H.shape)).astype(np.float32)


def write_ytal_capture(path, target, sensors, accounts, seed):
    laser = np.zeros(3)
    laser_xyz, sensor_xyz = np.array([-0.2, 0.0, 1.5]), np.array([-1.0, 0.0, 1.5])
    legs = (np.linalg.norm(laser_xyz - laser), np.linalg.norm(sensors - sensor_xyz, axis=1)) \
        if accounts else (0.0, np.zeros(len(sensors)))
    delta_t, n_t = 0.003, 4500
    t_start = 2.0 if accounts else 0.0
    data = tal.io.capture_data.NLOSCaptureData()
    data.H = plate_histograms(target, sensors, laser, delta_t, t_start, n_t, legs, seed)
    data.H_format = HFormat.T_Si
    data.sensor_xyz, data.laser_xyz = sensor_xyz.astype(np.float32), laser_xyz.astype(np.float32)
    data.sensor_grid_xyz = sensors.astype(np.float32)
    data.sensor_grid_normals = np.tile([0, 0, 1.0], (len(sensors), 1)).astype(np.float32)
    data.sensor_grid_format = GridFormat.N_3
    data.laser_grid_xyz = laser.reshape(1, 3).astype(np.float32)
    data.laser_grid_normals = np.array([[0, 0, 1.0]], np.float32)
    data.laser_grid_format = GridFormat.N_3
    data.volume_format = VolumeFormat.UNKNOWN
    data.delta_t, data.t_start = np.float32(delta_t), np.float32(t_start)
    data.t_accounts_first_and_last_bounces = accounts
    data.scene_info = {"original_format": "HDF5_TAL", "ytal_peer": {"target": list(target)}}
    tal.io.write_capture(str(path), data)


def run_nlos(*args):
    return subprocess.run([NLOS_PY, *args], capture_output=True, text=True, timeout=900)


SMALL_PLATE = r"""
import sys, numpy as np, nlos_cl as nl
setup = nl.paper_setup()
centre = np.array([-2.5, 2.5, 0.0])  # ours; y-tal (2.5, 0, 2.5)
mesh = nl.rectangle(0.05, 0.05, centre=centre, normal=[-0.75, 0, 0] - centre, cell_m=0.005)
axis = nl.TimeAxis(2 * 20 / nl.SPEED_OF_LIGHT, 10e-12, 3000)
hist = nl.simulate(nl.Scene(setup, nl.Target(mesh), 0.005, truth=centre), axis).histograms()
nl.write_capture(sys.argv[1], hist)
"""


def backprojection_peak(path):
    data = tal.io.read_capture(str(path))
    info = data.scene_info if isinstance(data.scene_info, dict) else yaml.safe_load(data.scene_info)
    t = np.asarray(info["nlos_cl"]["truth"], float)
    truth = np.array([-t[0], t[2], t[1]])  # nlos_cl (x, y, z) -> y-tal (X, Y, Z) = (-x, z, y)
    xs = np.arange(-6.0, 6.0 + 1e-9, BP_STEP_M)
    zs = np.arange(BP_STEP_M, 6.0 + 1e-9, BP_STEP_M)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    volume = np.stack([X, np.full_like(X, truth[1]), Z], axis=-1).reshape(-1, 3)
    rec = tal.reconstruct.bp.solve(data, volume_xyz=volume.astype(np.float32),
                                   volume_format=VolumeFormat.N_3,
                                   camera_system=CameraSystem.DIRECT_LIGHT, progress=False)
    return data, volume[int(np.argmax(np.abs(np.asarray(rec).reshape(-1))))], truth, info


def check_ytal_reads_nlos(folder: Path) -> bool:
    """Two captures written by nlos_cl: the paper's 0.3 m x 1.6 m plate (`nlos-cl simulate`)
    and a 5 cm plate (the Python API). Unfiltered backprojection peaks where the ellipses of
    the earliest return cross, which for an extended plate is its shortest-path part, not its
    centre: the paper's plate must peak on the plate (half-width 0.15 m, plus one voxel), the
    5 cm plate within BP_CELLS voxels of its centre."""
    ok = True
    paper, small = folder / "nlos_paper.h5", folder / "nlos_small.h5"
    for made in (run_nlos("-m", "nlos_cl.apps.cli", "simulate", "--out", str(paper), "--facet", "0.02"),
                 run_nlos("-c", SMALL_PLATE, str(small))):
        if made.returncode != 0:
            print(f"(a) nlos_cl could not write its capture: {made.stderr.strip()[-400:]}")
            return False
    for path, limit, what in ((paper, 0.15 + BP_STEP_M, "the paper's plate (on the plate)"),
                              (small, BP_CELLS * BP_STEP_M, f"a 5 cm plate ({BP_CELLS} cells)")):
        data, peak, truth, info = backprojection_peak(path)
        err = float(np.linalg.norm(peak - truth))
        ok &= err <= limit
        # scene_info is JSON written for YAML 1.1 too (nlos_cl.io.yamlfile): numbers stay numbers
        axis = info["nlos_cl"]["time_axis"]
        numbers = all(isinstance(axis[k], float) for k in ("t0_s", "dt_s"))
        ok &= numbers
        if not numbers:
            print(f"(a) y-tal read scene_info's time axis as {axis!r}: FAIL (numbers as text)")
        print(f"(a) y-tal {getattr(tal, '__version__', '')} read nlos_cl's capture of {what}: H "
              f"{data.H.shape} {data.H_format.name}; backprojection peak "
              f"{np.round(peak, 3).tolist()} vs truth {truth.tolist()}: {err:.3f} m = "
              f"{err / BP_STEP_M:.1f} voxels of {BP_STEP_M} m (limit {limit:.2f} m: "
              f"{'ok' if err <= limit else 'FAIL'})")
    return bool(ok)


def cli_position(path):
    found = run_nlos("-m", "nlos_cl.apps.cli", "locate", str(path), "--json")
    if found.returncode != 0:
        return None, f"exit {found.returncode}: {found.stderr.strip()[-300:]}"
    answer = json.loads(found.stdout)
    pos = np.asarray(answer["position"], float)
    frame = answer.get("frame")
    name = frame.get("name") if isinstance(frame, dict) else frame
    if name == "nlos_cl":  # internal frame declared: back to the file's
        pos = np.array([-pos[0], pos[2], pos[1]])
    note = f"frame {name!r}" if name else "no frame declared (taken as the file's)"
    return pos, note + ("; WARNING in output" if "warn" in found.stderr.lower() else "")


def check_nlos_reads_ytal(folder: Path) -> bool:
    paths = []
    for i, (target, sensors, accounts) in enumerate(SCENES):
        paths.append(folder / f"ytal_{i}.hdf5")
        write_ytal_capture(paths[-1], target, sensors, accounts, seed=i)
    api = run_nlos("-c", API_CHECK, *map(str, paths))
    api_results = json.loads(api.stdout) if api.returncode == 0 else None
    if api_results is None:
        print(f"(b) Python API check failed: {api.stderr.strip()[-600:]}")
    ok = api_results is not None
    print(f"(b) nlos_cl locates captures written by y-tal (errors in m, limit {TOLERANCE_M}):")
    for i, ((target, sensors, accounts), path) in enumerate(zip(SCENES, paths)):
        truth = np.asarray(target, float)
        pos, note = cli_position(path)
        cli_err = float(np.linalg.norm(pos - truth)) if pos is not None else float("inf")
        line = (f"  {path.name}: truth {list(target)}, {len(sensors)} sensors, legs "
                f"{'in' if accounts else 'out'} | CLI "
                + (f"{np.round(pos, 3).tolist()} error {cli_err:.3f}" if pos is not None
                   else "failed") + f" ({note})")
        ok &= cli_err <= TOLERANCE_M
        if api_results is not None:
            r = api_results[i]
            api_err = float(np.linalg.norm(np.asarray(r["position"]) - truth))
            ok &= api_err <= TOLERANCE_M
            line += (f" | API {np.round(r['position'], 3).tolist()} error {api_err:.3f} "
                     f"({r['cells']} cells of {r['step_m']:.3g} m"
                     + (", zoomed" if r["zoomed"] else "") + (", ON EDGE" if r["on_edge"]
                                                                 else "") + ")")
        print(line)
    return ok


# (c): a 32 x 32 confocal scan over +-0.4 m in LCT's 4 ps bins, of a 4 cm patch at PATCH
# (y-tal's frame); LCT's rule (nlos_cl.io.datasets.lct): rect_data[i, j] at the wall's
# (X, Y) = (-u_i, u_j), u = linspace(-width, width), photons at path 2 r, t = 0 the wall bounce
SCAN_N, SCAN_T, SCAN_WIDTH, SCAN_DT = 32, 1024, 0.4, 4e-12
PATCH = np.array([0.12, -0.08, 0.45])


def lct_scan(path, seed=7, size=0.04, cell=0.005, sigma_m=0.003):
    """An LCT .mat of the patch facing the wall (normal -Z): each cell a Gaussian pulse at the
    round trip 2 r, weighted by the two cosines and 1 / r^4, integrated over each bin; 2 %
    white noise. Independent of nlos_cl's code."""
    c = 299792458.0
    u = np.linspace(-SCAN_WIDTH, SCAN_WIDTH, SCAN_N)
    X, Y = np.meshgrid(-u, u, indexing="ij")
    wall = np.stack([X, Y, np.zeros_like(X)], axis=-1)
    ticks = (np.arange(round(size / cell)) + 0.5) * cell - size / 2
    edges = np.arange(SCAN_T + 1) * c * SCAN_DT
    cube = np.zeros((SCAN_N, SCAN_N, SCAN_T))
    for a in ticks:
        for b in ticks:
            d = wall - (PATCH + [a, b, 0.0])
            r = np.linalg.norm(d, axis=-1)
            weight = (-d[..., 2] / r) ** 2 * cell ** 2 / r ** 4
            cdf = 0.5 * (1 + erf((edges - 2 * r[..., None]) / (np.sqrt(2) * sigma_m)))
            cube += weight[..., None] * np.diff(cdf, axis=-1)
    cube += np.random.default_rng(seed).normal(0, 0.02 * cube.max(), cube.shape)
    scipy.io.savemat(path, {"rect_data": cube, "width": np.array([[SCAN_WIDTH]])})


def check_ytal_reconstructs_converted_scan(folder: Path) -> bool:
    """`nlos-cl convert` of lct_scan, read by tal.io.read_capture: it must be y-tal's confocal
    grid, and f-k migration (voxel (k, i, j): depth k delta_t / 2 over grid point (i, j)) and
    backprojection (a plane at the patch's Y, 1 cm voxels) must peak within TOLERANCE_M of it."""
    scan, out = folder / "lct_scan.mat", folder / "lct_scan.h5"
    lct_scan(scan)
    made = run_nlos("-m", "nlos_cl.apps.cli", "convert", str(scan), "--out", str(out))
    if made.returncode != 0:
        print(f"(c) nlos-cl convert failed: {made.stderr.strip()[-400:]}")
        return False
    data = tal.io.read_capture(str(out))
    layout = (f"H {data.H.shape} {data.H_format.name}, grids {data.sensor_grid_format.name}, "
              f"confocal {data.is_confocal()}")
    if data.H_format != HFormat.T_Sx_Sy or data.sensor_grid_format != GridFormat.X_Y_3 \
            or not data.is_confocal():
        print(f"(c) y-tal read the converted scan as {layout}: FAIL (f-k needs a T_Sx_Sy "
              "confocal X_Y_3 grid)")
        return False
    fk = np.asarray(tal.reconstruct.fk.solve(data))
    k, i, j = np.unravel_index(int(np.argmax(fk)), fk.shape)
    fk_peak = data.sensor_grid_xyz[i, j] + [0.0, 0.0, k * float(data.delta_t) / 2]
    xs, zs = np.arange(-0.4, 0.4 + 1e-9, 0.01), np.arange(0.2, 0.7 + 1e-9, 0.01)
    A, B = np.meshgrid(xs, zs, indexing="ij")
    volume = np.stack([A, np.full_like(A, PATCH[1]), B], axis=-1).reshape(-1, 3)
    bp = tal.reconstruct.bp.solve(data, volume_xyz=volume.astype(np.float32),
                                  volume_format=VolumeFormat.N_3,
                                  camera_system=CameraSystem.DIRECT_LIGHT, progress=False)
    bp_peak = volume[int(np.argmax(np.abs(np.asarray(bp).reshape(-1))))]
    ok = True
    for name, peak in (("f-k migration", fk_peak), ("backprojection", bp_peak)):
        err = float(np.linalg.norm(peak - PATCH))
        ok &= err <= TOLERANCE_M
        print(f"(c) y-tal read `nlos-cl convert`'s LCT scan as {layout}; its {name} peaks at "
              f"{np.round(peak, 3).tolist()} vs the patch {PATCH.tolist()}: {err:.3f} m (limit "
              f"{TOLERANCE_M} m: {'ok' if err <= TOLERANCE_M else 'FAIL'})")
    return bool(ok)


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        a = check_ytal_reads_nlos(Path(tmp))
        b = check_nlos_reads_ytal(Path(tmp))
        c = check_ytal_reconstructs_converted_scan(Path(tmp))
    print("ytal_peer: " + ("PASS" if a and b and c else "FAIL"))
    return 0 if a and b and c else 1


if __name__ == "__main__":
    sys.exit(main())
