"""y-tal's backprojection on the benchmark's scoring grids (see scripts/bench_peers.sh).

write-inputs OUT.npz [--smoke]   (nlos_cl's venv) the filtered signals of the paper's scene
                                 (3 detectors, 4,096 bins of 10 ps) and the grids
time-ytal IN.npz OUT.json        (the y-tal venv, numpy < 2) times tal.reconstruct.bp.solve,
                                 one call per detector, their product, its argmax: median of
                                 interleaved repeats with the spread, per grid.
nlos_cl's frame (x, y, z) is y-tal's (X, Y, Z) = (-x, z, y): the wall is y = 0 here, Z = 0 there.
"""
from __future__ import annotations

import json
import statistics
import sys
import time

import numpy as np

SIZES = (512, 2048)
REPEATS = 5


def grid_of(n):
    """The scoring rows' plane: x in [2, 6), y in [0.5, 4.5), n x n cells (origin, step, shape)."""
    return (2.0, 0.5, 0.0), (4.0 / n, 4.0 / n, 0.01), (n, n, 1)


def write_inputs(path, smoke=False):
    import nlos_cl as nl
    scene = nl.paper_scene(facet_size_m=0.02)
    axis = nl.TimeAxis(40 / nl.SPEED_OF_LIGHT, 10e-12, 4096)
    hist = nl.gauss_filter(nl.simulate(scene, axis)).histograms()
    paths = hist.path_axis()
    np.savez(path, data=hist.data / np.abs(hist.data).max(), spots=hist.detector_spots,
             laser=hist.laser_spot, centre0=paths.centre0_m, step=paths.step_m,
             sizes=np.array((128,) if smoke else SIZES))


def _capture(row, spot, laser, centre0, step):
    from tal.enums import GridFormat, HFormat, VolumeFormat
    from tal.io.capture_data import NLOSCaptureData
    to_tal = lambda p: np.array([-p[0], p[2], p[1]], np.float32)  # noqa: E731
    data = NLOSCaptureData()
    data.H = row.astype(np.float32)[:, None]
    data.H_format = HFormat.T_Si
    data.sensor_xyz, data.laser_xyz = to_tal(spot), to_tal(laser)
    data.sensor_grid_xyz = to_tal(spot)[None]
    data.sensor_grid_normals = np.array([[0, 0, 1.0]], np.float32)
    data.sensor_grid_format = GridFormat.N_3
    data.laser_grid_xyz = to_tal(laser)[None]
    data.laser_grid_normals = np.array([[0, 0, 1.0]], np.float32)
    data.laser_grid_format = GridFormat.N_3
    data.volume_format = VolumeFormat.UNKNOWN
    data.delta_t, data.t_start = np.float32(step), np.float32(centre0)
    data.t_accounts_first_and_last_bounces = False
    return data


def time_ytal(inputs, out):
    import tal
    from tal.enums import CameraSystem, VolumeFormat
    f = np.load(inputs)
    caps = [_capture(f["data"][d], f["spots"][d], f["laser"], f["centre0"][d], f["step"][d])
            for d in range(len(f["data"]))]
    rows = []
    for n in (int(v) for v in f["sizes"]):
        origin, step, shape = grid_of(n)
        xs, ys = origin[0] + step[0] * np.arange(n), origin[1] + step[1] * np.arange(n)
        yy, xx = np.meshgrid(ys, xs, indexing="ij")  # (ny, nx): our score map's layout
        volume = np.stack([-xx, np.zeros_like(xx), yy], axis=-1).reshape(-1, 3).astype(np.float32)

        def solve():
            joint = np.ones(len(volume))
            for cap in caps:
                rec = tal.reconstruct.bp.solve(cap, volume_xyz=volume,
                                               volume_format=VolumeFormat.N_3,
                                               camera_system=CameraSystem.DIRECT_LIGHT,
                                               progress=False)
                joint = joint * np.abs(np.asarray(rec).reshape(-1))
            return int(np.argmax(joint))
        best = solve()
        times = []
        for _ in range(REPEATS if n <= 512 else 3):
            start = time.perf_counter()
            solve()
            times.append(time.perf_counter() - start)
        med = statistics.median(times)
        rows.append({"grid": n, "seconds": med, "spread": (max(times) - min(times)) / med,
                     "argmax": [best % n, best // n], "repeats": len(times)})
        print(f"y-tal bp, {n}x{n} x {len(caps)} det: {med * 1e3:.1f} ms", flush=True)
    with open(out, "w") as fh:
        json.dump({"peer": f"y-tal {getattr(tal, '__version__', '?')} tal.reconstruct.bp.solve, "
                   "one call per detector, product", "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    if sys.argv[1] == "write-inputs":
        write_inputs(sys.argv[2], "--smoke" in sys.argv[3:])
    else:
        time_ytal(sys.argv[2], sys.argv[3])
