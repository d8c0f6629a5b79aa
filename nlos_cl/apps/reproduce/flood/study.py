"""The confocal approximation of a multizone sensor, measured.

A consumer multizone ToF sensor (the ST VL53L8 of the consumer-nlos walk,
io/datasets/consumer_nlos.py) floods its whole field of view with one diffused pulse; each
of its 4 x 4 zones watches its own patch of the wall. nlos_cl reads such a capture as
confocal: zone d's laser point is its detection point, path 2 |p - d|. This study simulates
the sensor both ways and locates both as `nl.locate_capture` locates the converted captures:

- flood: laser points spread over the lit wall (`samples_per_zone`^2 per zone, each carrying
  the power of its solid angle: the emitter's intensity taken uniform over the field of view),
  histogram d = sum over laser points l of w_l * (l -> target -> d). The upstream data put
  t = 0 where zone d's own first bounce leaves the wall (2 |s - d| removed, s the sensor), so a
  laser point l also shifts its light by |s - l| - |s - d|: hidden path
  |s - l| - |s - d| + |l - p| + |p - d|;
- confocal: laser point = detection point = the zone's spot, path 2 |p - d|.

Both detect at the zone's spot (its patch's centre): only the illumination differs. The
sensor's pose is fitted to the dataset's own wall spots (fit_sensor; flood.yaml keeps it), so
the study runs without the dataset. `nlos-cl reproduce flood` (experiment) runs it and writes
docs/results/flood/flood.md.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

import nlos_cl as nl
from nlos_cl.core.constants import FWHM_PER_SIGMA, SPEED_OF_LIGHT
from nlos_cl.core.errors import require

from ..common import load_data

# boresight along -y (towards the wall): the rotation taking the sensor's +z to our -y
FACING_WALL = np.array([math.pi / 2, 0.0, 0.0])


def config() -> dict:
    return load_data("flood.yaml", __package__)


def _rotation(rotvec) -> np.ndarray:
    """Rodrigues' formula: the 3 x 3 rotation of a rotation vector (no SciPy needed)."""
    v = np.asarray(rotvec, dtype=np.float64)
    angle = float(np.linalg.norm(v))
    if angle < 1e-15:
        return np.eye(3)
    k = v / angle
    skew = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * skew + (1.0 - math.cos(angle)) * skew @ skew


@dataclass(frozen=True)
class MultizoneSensor:
    """A flood-lit multizone sensor at `position` (ours, y > 0), its zones a grid uniform in
    angle over a square field of view `fov_rad`; `rotvec` turns its axes (x along a zone row,
    y down the rows, z the boresight) into ours. Zone index = row * zones + column (the
    dataset's `hists.reshape(4, 4, -1)` order)."""

    position: np.ndarray
    rotvec: np.ndarray
    fov_rad: float
    zones: int = 4

    def __post_init__(self):
        p = np.asarray(self.position, dtype=np.float64)
        require(p.shape == (3,) and p[1] > 0, "sensor.position_m", f"must be a point in front "
                f"of the wall (y > 0), got {p.tolist()}", "pass the sensor's [x, y, z] in metres")
        require(0 < self.fov_rad < math.pi * 0.9, "sensor.fov_deg", f"must be in (0, 162) deg, "
                f"got {math.degrees(self.fov_rad):.4g}", "pass the field of view, e.g. 45")
        object.__setattr__(self, "position", p)
        object.__setattr__(self, "rotvec", np.asarray(self.rotvec, dtype=np.float64))

    @classmethod
    def from_config(cls, cfg: dict) -> "MultizoneSensor":
        return cls(cfg["position_m"], cfg["rotvec"], math.radians(cfg["fov_deg"]), cfg["zones"])

    def _angles(self, sub: int) -> np.ndarray:
        """Angles of `sub` equal sub-cells per zone along one axis, zone-major (n * sub,)."""
        n, cell = self.zones, self.fov_rad / self.zones
        return ((np.arange(n)[:, None] + (np.arange(sub)[None, :] + 0.5) / sub)
                * cell - 0.5 * self.fov_rad).ravel()

    def _wall(self, ax, ay) -> np.ndarray:
        """Where the rays of angles (ax, ay) (broadcast, flattened) meet the wall y = 0."""
        local = np.stack(np.broadcast_arrays(np.tan(ax), np.tan(ay), 1.0), axis=-1).reshape(-1, 3)
        d = local @ _rotation(self.rotvec).T
        require(bool(np.all(d[:, 1] < 0)), "sensor.rotvec", "turns part of the field of view "
                "away from the wall", "point the sensor at the wall")
        points = self.position - (self.position[1] / d[:, 1])[:, None] * d
        points[:, 1] = 0.0  # on the plane exactly (rounding)
        return points

    def zone_spots(self) -> np.ndarray:
        """(zones^2, 3) each zone's spot: where its centre ray meets the wall."""
        a = self._angles(1)
        return self._wall(a[None, :], a[:, None])  # rows (ay) outer, columns (ax) inner

    def flood(self, sub: int) -> tuple[np.ndarray, np.ndarray]:
        """(points (L, 3), weights (L,), summing to 1): the lit wall sampled `sub` x `sub` times
        per zone (row by row over the whole fine grid), each point the power of its solid
        angle dOmega = dax day / (cos^2 ax cos^2 ay (1 + tan^2 ax + tan^2 ay)^(3/2)) (the
        emitter's intensity uniform in the field)."""
        a = self._angles(sub)
        ax, ay = a[None, :], a[:, None]
        tx, ty = np.tan(ax), np.tan(ay)
        solid = (1.0 / (np.cos(ax) ** 2 * np.cos(ay) ** 2)) / (1.0 + tx ** 2 + ty ** 2) ** 1.5
        weights = np.broadcast_to(solid, (len(a), len(a))).ravel()
        return self._wall(ax, ay), weights / weights.sum()

    def path_offsets(self, lasers, spots) -> np.ndarray:
        """(L, D) |s - l| - |s - d|: how much later laser point l's light starts into the
        hidden scene than zone d's own first bounce, which the capture's t = 0 is."""
        to_laser = np.linalg.norm(np.asarray(lasers) - self.position, axis=1)
        to_spot = np.linalg.norm(np.asarray(spots) - self.position, axis=1)
        return to_laser[:, None] - to_spot[None, :]


def fit_sensor(spots, zones: int = 4) -> tuple[MultizoneSensor, float]:
    """(sensor, rms misfit m) whose zone centres best meet `spots` ((zones^2, 3), ours, on the
    wall; zone order as MultizoneSensor's): position, rotation and field of view by least
    squares, started facing the wall from a few stand-offs and turns."""
    from scipy.optimize import least_squares  # SciPy only when fitting
    spots = np.asarray(spots, dtype=np.float64)
    require(spots.shape == (zones * zones, 3), "spots", f"expected ({zones * zones}, 3), got "
            f"{spots.shape}", "pass one wall spot per zone")

    def misfit(q):
        try:
            model = MultizoneSensor(q[:3], q[3:6], q[6], zones).zone_spots()
        except nl.InputError:  # a trial pose that leaves the wall: far off
            return np.full(2 * len(spots), 1e3)
        return (model - spots)[:, [0, 2]].ravel()

    centre, best = spots.mean(axis=0), None
    for standoff in (0.3, 0.7, 1.5):
        for turn in np.radians([-40.0, 0.0, 40.0]):
            q0 = np.r_[centre + [0.0, standoff, 0.0], FACING_WALL + [0.0, 0.0, turn], 0.8]
            fit = least_squares(misfit, q0)
            if best is None or fit.cost < best.cost:
                best = fit
    q = best.x
    return (MultizoneSensor(q[:3], q[3:6], q[6], zones),
            float(np.sqrt(np.mean(misfit(q).reshape(-1, 2) ** 2 @ np.ones(2)))))


# ---------------------------------------------------------------------------- simulation

def simulate_zones(target: "nl.Target", sensor: MultizoneSensor, cfg: dict, *, flood: bool,
                   backend=None) -> "nl.HistogramSet":
    """The sensor's 16 histograms of `target`, as the consumer reader lays a capture out
    (confocal: laser spots = detector spots = the zone spots, t = 0 when light leaves the wall,
    no path offset), lit by the flood (`flood`) or confocally. Mean power per bin, W, for a
    nominal 1 nJ pulse and the paper's wall (only shapes matter to the argmax)."""
    from nlos_cl.core.paths import PathCalibration, TimeAxis
    from nlos_cl.ops.backend import resolve_backend
    from nlos_cl.ops.base import to_host
    backend = resolve_backend(backend)
    axis = TimeAxis(**cfg["time_axis"])
    spots = sensor.zone_spots()
    if flood:
        points, weights = sensor.flood(cfg["samples_per_zone"])
        offsets = sensor.path_offsets(points, spots)  # (L, D)
    else:
        points, weights, offsets = spots, np.ones(1), np.zeros((1, len(spots)))
    n_lasers, n_zones = len(weights), len(spots)
    # one paired forward call: row (l, d) is laser point l seen by zone d
    rows_spot = np.tile(spots, (n_lasers, 1))
    rows_laser = np.repeat(points, n_zones, axis=0) if flood else spots
    edge0 = SPEED_OF_LIGHT * axis.t0_s - offsets.ravel()
    dpath = np.full(len(rows_spot), SPEED_OF_LIGHT * axis.dt_s)
    sigma_path = SPEED_OF_LIGHT * cfg["pulse_fwhm_s"] / FWHM_PER_SIGMA
    facets = target.facets(cfg["facet_m"])
    hist, _ = backend.call("forward", facets, rows_spot, rows_laser, edge0, dpath, sigma_path,
                           axis.n_bins, target.reflectance, "deposit", None)
    hist = to_host(backend, hist).reshape(n_lasers, n_zones, axis.n_bins)
    data = np.tensordot(weights, hist, axes=1)  # the flood: the power-weighted sum
    setup = nl.Setup(laser_spot=(0.0, 0.0, 5.0), detector_spots=spots)  # its radiometry only
    watts = 0.5 * 1e-9 / axis.dt_s * setup.power_scale(target.reflectance.scale)
    centre = target.mesh.bounds.mean(axis=0)
    return nl.HistogramSet(watts * data, axis, spots, spots,
                           PathCalibration(SPEED_OF_LIGHT, [0.0]), truth=centre)


# ---------------------------------------------------------------------------- draws

def draw(index: int, cfg: dict, master_seed: int | None = None) -> dict:
    """Draw `index`'s target as plain data (shape, centre, size, yaw): a pure function of the
    index and the master seed (its own stream), a plate or a box facing the wall within
    `yaw_deg`, its centre uniform in the region and kept clear of the sensor."""
    t = cfg["targets"]
    seed = cfg["master_seed"] if master_seed is None else master_seed
    rng = np.random.default_rng(np.random.SeedSequence((int(seed), int(index))))
    sensor = np.asarray(cfg["sensor"]["position_m"])
    for _ in range(1000):
        centre = np.array([rng.uniform(*t["x"]), rng.uniform(*t["y"]), rng.uniform(*t["z"])])
        shape = t["shapes"][int(rng.integers(len(t["shapes"])))]
        size = rng.uniform(*t["size_m"], size=3)
        yaw = rng.uniform(-t["yaw_deg"], t["yaw_deg"])
        if np.linalg.norm(centre - sensor) >= t["min_from_sensor_m"]:
            return {"index": int(index), "shape": shape, "centre": centre.tolist(),
                    "size": size.tolist(), "yaw_deg": float(yaw)}
    require(False, "flood.yaml targets", "no centre found clear of the sensor in 1000 tries",
            "widen the region or lower min_from_sensor_m")


def target_of(d: dict, facet_m: float) -> "nl.Target":
    """The mesh of a draw: a one-sided plate (width, height = size[0], size[1]) or a box
    (edges = size), turned by yaw about the vertical, facing the wall (-y) at yaw 0."""
    yaw = math.radians(d["yaw_deg"])
    if d["shape"] == "plate":
        mesh = nl.rectangle(d["size"][0], d["size"][1], centre=d["centre"],
                            normal=(math.sin(yaw), -math.cos(yaw), 0.0), cell_m=facet_m)
    else:
        import trimesh  # apps may load it; only the box needs a turn
        mesh = nl.box(tuple(d["size"]), centre=(0.0, 0.0, 0.0), cell_m=facet_m)
        mesh.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0, 0, 1]))
        mesh.apply_translation(d["centre"])
    return nl.Target(mesh)


def mirror_reading(h: "nl.HistogramSet", sensor: MultizoneSensor) -> "nl.HistogramSet":
    """The same histograms read with a first-order flood model: light that leaves the sensor
    s, meets the lit wall and reaches p takes at least |s' - p| (s' the sensor mirrored in the
    wall, wherever the straight line s' -> p crosses the lit patch), so the earliest light in
    zone d has hidden path |s' - p| + |p - d| - |s - d|: one laser spot at s' (off the wall)
    and per-zone offsets b_d = |s - d|. It ignores where the patch clips that line and the
    light's spread over the patch."""
    from nlos_cl.core.paths import PathCalibration
    spots = np.asarray(h.detector_spots)
    mirror = sensor.position * np.array([1.0, -1.0, 1.0])
    offsets = np.linalg.norm(spots - sensor.position, axis=1)
    return nl.HistogramSet(h.data, h.time_axis, spots, mirror,
                           PathCalibration(SPEED_OF_LIGHT, offsets), truth=h.truth)


READINGS = ("confocal", "flood", "mirror")  # data: confocal, flood, flood; read as: confocal,
# confocal, mirror source


def run_draw(d: dict, cfg: dict, sensor: MultizoneSensor, backend=None) -> dict:
    """One draw simulated both ways and located three ways: confocal data and flood data each
    as locate_capture locates a converted consumer capture (its default for confocal layouts,
    the paper's argmax), and the flood data by mirror_reading (with the same argmax). The row:
    each location's error from the target's centre and from its surface, its depth error (y,
    the distance from the wall) and its distance from the confocal one ("shift")."""
    target = target_of(d, cfg["facet_m"])
    truth = target.mesh.bounds.mean(axis=0)
    row = dict(d, centre=[round(v, 4) for v in d["centre"]],
               size=[round(v, 4) for v in d["size"]], yaw_deg=round(d["yaw_deg"], 2))
    found = {}
    for name in READINGS[:2]:
        start = time.perf_counter()
        found[name] = simulate_zones(target, sensor, cfg, flood=name == "flood", backend=backend)
        row[f"{name}_simulate_s"] = round(time.perf_counter() - start, 3)
    found["mirror"] = mirror_reading(found["flood"], sensor)
    for name in READINGS:
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the confocal default's own note, every draw
            point = nl.locate_capture(found[name], backend=backend,
                                      estimator="paper" if name == "mirror" else None).points[0]
        found[name] = p = np.asarray(point.location.position)
        row.update({f"{name}_error_m": round(float(np.linalg.norm(p - truth)), 5),
                    f"{name}_surface_m": round(_surface_distance(d, p), 5),
                    f"{name}_depth_error_m": round(float(p[1] - truth[1]), 5),
                    f"{name}_position": [round(float(v), 4) for v in p],
                    f"{name}_estimator": point.location.estimator,
                    f"{name}_locate_s": round(time.perf_counter() - start, 3)})
        row[f"{name}_shift_m"] = round(float(np.linalg.norm(p - found["confocal"])), 5)
    return row


def _surface_distance(d: dict, point) -> float:
    """How far `point` is from the draw's surface (exact: in the target's own axes a plate is a
    box of thickness 0): the argmax finds the face the light reaches first, not the centre, so
    this is its error with that bias taken out."""
    yaw = math.radians(d["yaw_deg"])
    c, s = math.cos(yaw), math.sin(yaw)
    q = np.asarray(point, dtype=np.float64) - d["centre"]
    q = np.abs([c * q[0] + s * q[1], -s * q[0] + c * q[1], q[2]])  # turned back by -yaw
    half = 0.5 * np.asarray(d["size"], dtype=np.float64)
    if d["shape"] == "plate":  # width along x, height along z, no depth
        half = np.array([half[0], 0.0, half[1]])
    outside = np.maximum(q - half, 0.0)
    if np.any(outside > 0):
        return float(np.linalg.norm(outside))
    return float(np.min(half - q))  # inside a box: to its nearest face


def summary(rows: list[dict]) -> dict:
    """Per reading: median, p90 and worst of its errors (centre, surface, shift from the
    confocal location) and p10, median, p90 of its signed depth error."""
    out = {"draws": len(rows)}
    for name in READINGS:
        for key, qs in (("error_m", (50, 90, 100)), ("surface_m", (50, 90, 100)),
                        ("shift_m", (50, 90, 100)), ("depth_error_m", (10, 50, 90))):
            v = np.array([r[f"{name}_{key}"] for r in rows], dtype=np.float64)
            out[f"{name}_{key}"] = {_QUANTILE[q]: round(float(np.percentile(v, q)), 4)
                                    for q in qs}
    return out


_QUANTILE = {10: "p10", 50: "median", 90: "p90", 100: "worst"}
