"""A draw (families: plain data) as nlos_cl's scene, simulated with the forward model, with
the noise and the mismatches the estimators do not assume added on the host: an exponential
instrument-response tail, noise relative to each histogram's peak, an ambient offset and a weak
delayed "fourth-bounce" background. (Another pulse width and a GGX target are the scene's own:
scenes.scene.)

`s`, where a function takes it, is any object with `facet_m` (the facet size, m) and `dt_s`
(the time bin, s): these two attributes are all that is read (apps/reproduce's Settings is one)."""
from __future__ import annotations

import math
import warnings

import numpy as np

from ...core.constants import TINY
from ...core.paths import default_time_axis
from ...physics.meshes import box, rectangle, sphere
from ...physics.noise import PhotonCounter, SensorNoise
from ...physics.reflectance import GGX
from ...physics.scene import Pulse, Scene, Target, paper_setup
from ..frame import add_noise, simulate as simulate_frame


def _turned(mesh, centre, yaw_deg: float):
    """The mesh turned by yaw_deg about the vertical through `centre`."""
    a = math.radians(yaw_deg)
    rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0],
                    [0.0, 0.0, 1.0]])
    mesh.vertices = (np.asarray(mesh.vertices) - centre) @ rot.T + centre
    return mesh


def cylinder_mesh(radius_m: float, height_m: float, centre, facet_m: float):
    """An upright closed cylinder (nlos_cl.physics.meshes has none): trimesh's, with enough
    sections that its chord error is below a tenth of a facet."""
    import trimesh  # (loaded already, by physics.meshes)
    sections = max(16, math.ceil(math.pi / math.acos(max(0.0, 1 - 0.1 * facet_m / radius_m))))
    mesh = trimesh.creation.cylinder(radius=radius_m, height=height_m, sections=sections)
    mesh.apply_translation(np.asarray(centre, float))
    return mesh


def mesh_of(t: dict, facet_m: float):
    """The target's triangle mesh (nlos_cl's meshes; the cylinder from trimesh)."""
    c = np.asarray(t["centre"], float)
    if t["shape"] == "plate":
        return rectangle(t["size"][0], t["size"][1], centre=tuple(c),
                            normal=tuple(t["normal"]), cell_m=facet_m)
    if t["shape"] == "box":
        # a box facing the spots (yaw 0) has its x face towards them: turn by the normal's angle
        angle = math.degrees(math.atan2(t["normal"][1], t["normal"][0])) - 180.0
        return _turned(box(tuple(t["size"]), centre=tuple(c), cell_m=facet_m), c, angle)
    if t["shape"] == "sphere":
        return sphere(t["radius_m"], centre=tuple(c), facet_size_m=facet_m)
    return cylinder_mesh(t["radius_m"], t["height_m"], c, facet_m)


def scene(d: dict, s) -> Scene:
    """The draw's Scene: its spots on the paper's setup (laser at O), its targets, and the
    mismatches that are part of the scene (pulse width, GGX reflectance)."""
    m = d["mismatch"] or {}
    setup = {"detector_spots": np.asarray(d["layout"]["spots"], float)}
    if m.get("kind") == "pulse":
        setup["pulse"] = Pulse(fwhm_s=m["fwhm_ps"] * 1e-12)
    brdf = 0.1284
    if m.get("kind") == "brdf":
        brdf = GGX(specular=m["specular"], roughness=m["roughness"], diffuse=m["diffuse"])
    first, *rest = [Target(mesh_of(t, s.facet_m), brdf) for t in d["targets"]]
    return Scene(paper_setup(**setup), first, s.facet_m,
                    truth=tuple(d["targets"][0]["centre"]), more_targets=tuple(rest))


def _convolve(data: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Each row convolved with a causal kernel (kernel[0] at zero delay), same length."""
    n = data.shape[1] + len(kernel)
    spectrum = np.fft.rfft(data, n, axis=1) * np.fft.rfft(kernel, n)
    return np.fft.irfft(spectrum, n, axis=1)[:, :data.shape[1]]


def irf_tail(data, dt_s: float, tau_ps: float, share: float) -> np.ndarray:
    """(1 - share) of the light as it came, `share` spread by an exponential of tau_ps."""
    t = np.arange(int(math.ceil(8 * tau_ps * 1e-12 / dt_s))) * dt_s
    tail = np.exp(-t / (tau_ps * 1e-12))
    kernel = share * tail / tail.sum()
    kernel[0] += 1.0 - share
    return _convolve(data, kernel)


def background(data, dt_s: float, m: dict) -> np.ndarray:
    """An ambient offset (a share of each histogram's peak) and a delayed, broad copy of the
    signal carrying `share` of its energy: a stand-in for light that bounced once more."""
    t = np.arange(int(math.ceil((m["delay_ns"] + 5 * m["sigma_ns"]) * 1e-9 / dt_s))) * dt_s
    lobe = np.exp(-0.5 * ((t - m["delay_ns"] * 1e-9) / (m["sigma_ns"] * 1e-9)) ** 2)
    late = _convolve(data, m["share"] * lobe / lobe.sum())
    return data + late + m["ambient_share"] * data.max(axis=1, keepdims=True)


def simulate(d: dict, s):
    """(clean HistogramSet, the simulation's warnings as text): the forward model on the
    draw's scene, with the draw's instrument response where it has one."""
    sc = scene(d, s)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        clean = simulate_frame(sc, default_time_axis(sc.setup, s.dt_s)).histograms()
    m = d["mismatch"] or {}
    if m.get("kind") == "irf_tail":
        clean = clean.with_data(irf_tail(clean.data, s.dt_s, m["tau_ps"], m["share"]))
    return clean, sorted({str(w.message)[:120] for w in caught})


def photon_counts(clean, counting: dict, seed: int):
    """A counts draw's frame: PhotonCounter counts in TDC bins, its pulses set so that the
    detectors' mean signal photons is the draw's (the ambient at the draw's rate)."""
    quiet = PhotonCounter(n_pulses=1.0, dark_count_rate_hz=0.0, ambient_rate_hz=0.0,
                             tdc_bin_s=counting["tdc_ps"] * 1e-12)
    per_pulse = float(np.mean(quiet.expected_counts(clean).data.sum(axis=1)))
    counter = PhotonCounter(n_pulses=counting["signal_photons"] / max(per_pulse, TINY),
                               ambient_rate_hz=counting["ambient_rate_hz"],
                               tdc_bin_s=counting["tdc_ps"] * 1e-12)
    return counter.counts(clean, seed=seed)


def noisy(clean, d: dict):
    """The frame the estimators see: AWGN at the draw's SNR (measured on the signal alone),
    or noise relative to each peak; then the background where the draw has one. A counts
    draw: Poisson photon counts instead (`photon_counts`)."""
    if d.get("counting"):
        return photon_counts(clean, d["counting"], d["noise_seed"])
    m = d["mismatch"] or {}
    if m.get("kind") == "peak_noise":
        model = SensorNoise(tuple(clean.data.max(axis=1) / 10 ** (m["peak_snr_db"] / 20)))
    else:  # the sigma AWGN(snr) draws for the clean signal, kept when a background is added
        model = SensorNoise.from_snr(clean, d["snr_db"])
    frame = clean
    if m.get("kind") == "background":
        frame = clean.with_data(background(clean.data, clean.time_axis.dt_s, m))
    return add_noise(frame, seed=d["noise_seed"], model=model).histograms()
