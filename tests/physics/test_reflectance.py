"""The glossy (GGX) and retroreflective reflectance models (nlos_cl.physics.reflectance) through
the reflectance seam: kernel against twin, and properties of the BRDFs themselves that no
implementation detail can fake."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.ops.backend import NumpyBackend
from nlos_cl.physics.reflectance import GGX, Retroreflective, from_spec
from conftest import window_around


def brdf(model, n, l, v):
    return model.scale * model.factor(n[None], l[None], v[None, None])[0, 0]


def hemisphere(n_theta=400, n_phi=400):
    theta = (np.arange(n_theta) + 0.5) * (np.pi / 2 / n_theta)
    phi = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    d_omega = (np.sin(t) * (np.pi / 2 / n_theta) * (2 * np.pi / n_phi)).ravel()
    return dirs, d_omega


@pytest.mark.parametrize("roughness", [0.1, 0.3, 0.7])
def test_ggx_conserves_energy_and_is_reciprocal(roughness):
    model = GGX(specular=0.6, roughness=roughness, diffuse=0.3)
    n = np.array([0.0, 0.0, 1.0])
    dirs, d_omega = hemisphere()
    for theta_in in (0.0, 0.6, 1.2):
        l = np.array([np.sin(theta_in), 0.0, np.cos(theta_in)])
        f = model.scale * model.factor(n[None], l[None], dirs[None])[0]
        albedo = float((f * dirs[:, 2] * d_omega).sum())
        assert albedo <= 0.9 + 1e-3  # diffuse + specular: never more than comes in
        if roughness <= 0.1 and theta_in < 1.0:  # little single-scattering loss there
            assert albedo > 0.3 + 0.97 * 0.6
    rng = np.random.default_rng(0)
    for _ in range(20):
        a, b = rng.standard_normal((2, 3))
        a[2], b[2] = abs(a[2]), abs(b[2])
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        assert brdf(model, n, a, b) == pytest.approx(brdf(model, n, b, a), rel=1e-12)


@pytest.mark.parametrize("roughness", [0.1, 0.4, 0.9])
def test_ggx_microfacets_project_to_the_macro_surface(roughness):
    # The identity every microfacet model must meet (Heitz 2014, Eq. 2): the visible projected
    # microfacet area is the macro-surface's, int G1(o) max(0, o.m) D(m) dm = cos(theta_o).
    # D and G1 are read off the BRDF at the mirror configuration l = v = m ... here via the
    # factor with diffuse 0: f(l=o, v=reflect(o, m)) 4 cos_l cos_v / (G1(l) G1(v)) = D(m).
    model = GGX(specular=1.0, roughness=roughness)
    a2 = roughness ** 2
    dirs, d_omega = hemisphere(1500, 60)
    cos_m = dirs[:, 2]
    D = a2 / (np.pi * (cos_m ** 2 * (a2 - 1) + 1) ** 2)
    n = np.array([0.0, 0.0, 1.0])
    for theta_o in (0.2, 0.8, 1.3):
        o = np.array([np.sin(theta_o), 0, np.cos(theta_o)])
        g1 = 2 / (1 + np.sqrt(1 + a2 * np.tan(theta_o) ** 2))
        total = (g1 * np.maximum(dirs @ o, 0) * D * d_omega).sum()
        assert total == pytest.approx(np.cos(theta_o), rel=2e-3)
        # and the model's BRDF at l = v = o is D(n = o... ) G1(o)^2 / (4 cos^2) (h = o)
        expected = (a2 / (np.pi * (o[2] ** 2 * (a2 - 1) + 1) ** 2) * g1 * g1 / (4 * o[2] ** 2))
        assert brdf(model, n, o, o) == pytest.approx(expected, rel=1e-12)


def test_ggx_peaks_at_the_mirror_direction_and_diffuse_only_is_lambertian():
    model = GGX(specular=0.5, roughness=0.2)
    n = np.array([0.0, 0.0, 1.0])
    l = np.array([np.sin(0.5), 0, np.cos(0.5)])
    angles = np.linspace(-1.2, 1.2, 241)
    values = [brdf(model, n, l, np.array([np.sin(a), 0, np.cos(a)])) * np.cos(a) for a in angles]
    assert angles[int(np.argmax(values))] == pytest.approx(-0.5, abs=0.06)
    assert max(values) > 10 * values[-1]  # a lobe: the retro direction gets little
    diffuse = GGX(specular=0.0, roughness=0.5, diffuse=0.4)
    assert brdf(diffuse, n, l, n) == pytest.approx(0.4 / np.pi)


def glossy_scene(model):
    setup = nl.paper_setup(detector_spots=[[-0.5, 0, 0], [-1.0, 0, 0.3], [0.6, 0, -0.2]])
    mesh = nl.rectangle(0.6, 0.6, centre=(0.4, 1.5, 0.1), normal=(-0.2, -1, 0), cell_m=0.02)
    return nl.Scene(setup, nl.Target(mesh, brdf=model), 0.02)


@pytest.mark.parametrize("roughness", [0.05, 0.3, 0.9])
def test_ggx_from_cosines_is_the_vector_form(roughness):
    """The host models' form (n.l, n.v, l.v; n.h from them) against `factor` on random
    directions, some below the surface (0 in both)."""
    model = GGX(specular=0.6, roughness=roughness, diffuse=0.1)
    rng = np.random.default_rng(5)
    n = rng.standard_normal((300, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    l, v = (d / np.linalg.norm(d, axis=-1, keepdims=True) for d in
            (rng.standard_normal((300, 3)) + 0.8 * n, rng.standard_normal((4, 300, 3)) + 0.8 * n))
    want = model.factor(n, l, v)
    got = model.factor_of_cosines(np.sum(n * l, axis=1)[None], np.sum(n[None] * v, axis=2),
                                  np.sum(l[None] * v, axis=2))
    assert (want == 0).any() and (want > 0).any()
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("method", ["deposit", "erf"])
def test_ggx_kernel_matches_twin(device_runtime, reference, method):
    scene = glossy_scene(GGX(specular=0.7, roughness=0.25, diffuse=0.1))
    from nlos_cl.ops.forward import scene_inputs
    args = scene_inputs(scene, window_around(scene.setup, scene.target.mesh, 10e-12)) + (method,)
    dev = device_runtime.to_numpy(device_runtime.forward(*args)[0])
    twin = reference.forward(*args)[0]
    assert np.abs(dev - twin).max() < 1e-3 * twin.max()


def test_diffuse_only_ggx_simulates_as_lambertian(reference):
    a = glossy_scene(GGX(specular=0.0, roughness=0.3, diffuse=0.5))
    b = glossy_scene(0.5 / np.pi)
    axis = window_around(a.setup, a.target.mesh, 10e-12)
    ha, hb = (nl.simulate(s, axis, backend=reference).histograms().data for s in (a, b))
    np.testing.assert_allclose(ha, hb, rtol=1e-12, atol=1e-12 * hb.max())


LOBES_FROM_FILES = [  # (the scene file's reflectance, the model, bad entries: (spec, field))
    ({"model": "ggx", "specular": 0.5, "roughness": 0.2, "diffuse": 0.1}, GGX(0.5, 0.2, 0.1),
     [({"roughness": 0.0}, "roughness"), ({"shininess": 3}, "unknown key"),
      ({"specular": 0.8, "diffuse": 0.5}, "exceeds 1")]),
    ({"model": "retroreflective", "retro": 0.6, "width_rad": 0.01, "diffuse": 0.3},
     Retroreflective(0.6, 0.01, 0.3),
     [({"width_rad": 0.0}, "width_rad"), ({"retro": -0.1}, "retro"),
      ({"width_deg": 1}, "unknown key"), ({"retro": 0.9, "diffuse": 0.2}, "exceeds 1"),
      ({"retro": 0.0, "diffuse": 0.0}, "reflects nothing")])]


@pytest.mark.parametrize("spec, model, bad", LOBES_FROM_FILES, ids=["ggx", "retroreflective"])
def test_a_lobed_target_from_a_scene_file(spec, model, bad):
    from nlos_cl.io.scenefile import load_scene
    loaded = load_scene({"targets": [{"shape": "rectangle", "position": [3, 1, 0],
                                      "reflectance": spec}]})
    assert loaded.scene.target.reflectance == model
    for entries, field in bad:
        with pytest.raises(InputError, match=field):
            from_spec({"model": spec["model"], **entries})
    with pytest.raises(InputError, match="together with brdf"):
        load_scene({"targets": [{"shape": "rectangle", "brdf": 0.1,
                                 "reflectance": {"model": "lambertian"}}]})


# ------------------------------------------------------------------ retroreflective

def lobe_albedo_normal(width):
    """The retro lobe's albedo at normal incidence, 2 pi int_0^1 exp((mu - 1) / w^2) mu dmu,
    by quadrature (not the model's closed form)."""
    from scipy.integrate import quad
    return 2 * np.pi * quad(lambda mu: np.exp((mu - 1) / width ** 2) * mu, 0, 1,
                            points=[1 - 5 * width ** 2] if width < 0.4 else None,
                            epsabs=0, epsrel=1e-10, limit=200)[0]


def retro_brdf_by_hand(model, psi):
    """f at angle psi between to_laser and to_detector, from the formula in docs/physics.md."""
    lobe = np.exp((np.cos(psi) - 1) / model.width_rad ** 2)
    return model.diffuse / np.pi + model.retro * lobe / lobe_albedo_normal(model.width_rad)


def albedo_about(model, l, n, n_alpha=1500, n_phi=360):
    """int f(l, v) max(0, n.v) dv in polar coordinates about l (fine where a narrow lobe is)."""
    reach = min(np.pi, 12 * model.width_rad)  # the lobe is e^-72 of its peak beyond
    alpha = (np.arange(n_alpha) + 0.5) * (reach / n_alpha)
    phi = (np.arange(n_phi) + 0.5) * (2 * np.pi / n_phi)
    e1 = np.cross(l, [0.0, 1.0, 0.0] if abs(l[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(l, e1)
    a, p = np.meshgrid(alpha, phi, indexing="ij")
    v = (np.cos(a)[..., None] * l + np.sin(a)[..., None]
         * (np.cos(p)[..., None] * e1 + np.sin(p)[..., None] * e2)).reshape(-1, 3)
    d_omega = (np.sin(a) * (reach / n_alpha) * (2 * np.pi / n_phi)).ravel()
    f = model.scale * model.factor(n[None], l[None], v[None])[0]
    return float((f * np.maximum(v @ n, 0.0) * d_omega).sum())


@pytest.mark.parametrize("width", [0.005, 0.05, 0.5, 2.0])
def test_retro_lobe_conserves_energy_and_is_reciprocal(width):
    # retro = 1, diffuse = 0: the lobe alone, whose albedo is `retro` at normal incidence and
    # less at any other (the energy bound diffuse + retro <= 1 rests on that)
    model = Retroreflective(retro=1.0, width_rad=width, diffuse=0.0)
    n = np.array([0.0, 0.0, 1.0])
    normal = albedo_about(model, n, n)
    assert normal == pytest.approx(1.0, abs=2e-3)
    for theta_in in (0.3, 0.8, 1.2, 1.5):
        l = np.array([np.sin(theta_in), 0.0, np.cos(theta_in)])
        assert albedo_about(model, l, n) <= normal + 1e-6
    rng = np.random.default_rng(1)
    model = Retroreflective(retro=0.6, width_rad=width, diffuse=0.3)
    for _ in range(20):
        a, b = rng.standard_normal((2, 3))
        a[2], b[2] = abs(a[2]), abs(b[2])
        a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
        assert brdf(model, n, a, b) == pytest.approx(brdf(model, n, b, a), rel=1e-12)


def test_retro_peak_and_shape_follow_the_formula():
    model = Retroreflective(retro=0.7, width_rad=0.01, diffuse=0.2)
    n = np.array([0.0, 0.0, 1.0])
    l = np.array([np.sin(0.4), 0.0, np.cos(0.4)])
    for psi in (0.0, 0.005, 0.01, 0.02, 0.05, 0.5):  # v turned by psi about the y axis
        v = np.array([np.sin(0.4 + psi), 0.0, np.cos(0.4 + psi)])
        assert brdf(model, n, l, v) == pytest.approx(retro_brdf_by_hand(model, psi), rel=1e-9)
    assert brdf(model, n, l, -l) == 0.0  # below the surface
    # the host models' shortcut (l.v alone) is the same function above the surface
    rng = np.random.default_rng(3)
    v = l + 0.03 * rng.standard_normal((200, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    np.testing.assert_allclose(model.factor_of_cosine(v @ l), model.factor(n[None], l[None],
                                                                           v[:, None])[:, 0],
                               rtol=1e-9)


def test_wide_retro_lobe_is_lambertian():
    """width -> infinity: the lobe is flat and A -> pi, so f = (diffuse + retro) / pi."""
    wide = Retroreflective(retro=0.6, width_rad=1e3, diffuse=0.2)
    rng = np.random.default_rng(2)
    d = rng.standard_normal((2, 500, 3))
    d[..., 2] = np.abs(d[..., 2])
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    n = np.tile([0.0, 0.0, 1.0], (500, 1))
    # |l - v|^2 <= 4: the lobe is within 2 / w^2 = 2e-6 of flat
    assert np.abs(wide.factor(n, d[0], d[1][None]) - 1.0).max() < 3e-6
    a, b = glossy_scene(wide), glossy_scene(0.8 / np.pi)
    axis = window_around(a.setup, a.target.mesh, 10e-12)
    ha, hb = (nl.simulate(s, axis, backend=NumpyBackend()).histograms().data for s in (a, b))
    np.testing.assert_allclose(ha, hb, rtol=3e-6, atol=1e-9 * hb.max())


def retro_inputs(model, lasers_offset=None, laser=None):
    """forward's arguments for glossy_scene(model); each detector its own laser spot (the
    spots shifted by lasers_offset), or `laser` for all."""
    from nlos_cl.ops.forward import _window, scene_inputs
    scene = glossy_scene(model)
    lasers = scene.setup.detector_spots + lasers_offset if laser is None else laser
    args = scene_inputs(scene, _window(scene, 10e-12, laser=lasers))
    return args[:2] + (np.asarray(lasers, float),) + args[3:]


@pytest.mark.parametrize("method", ["deposit", "erf"])
def test_retro_kernel_matches_twin(device_runtime, reference, method):
    # 1e-3 of the peak is the forward op's tolerance (float32 paths, erf, the deposit's
    # split); the lobe adds lam |l - v| x (the float32 error of l - v, ~3e-7) <= 1e-4 of it
    # where |l - v| ~ w (the near-confocal case, lasers 3 cm from the spots, ~1.5 m away)
    near = retro_inputs(Retroreflective(retro=0.7, width_rad=0.02, diffuse=0.2),
                        lasers_offset=[0.03, 0.0, 0.0])
    wide = retro_inputs(Retroreflective(retro=0.8, width_rad=0.5, diffuse=0.1),
                        laser=np.zeros(3))  # the paper's one laser spot: the lobe's tails
    for args in (near, wide):
        dev = device_runtime.to_numpy(device_runtime.forward(*args, method)[0])
        twin = reference.forward(*args, method)[0]
        assert np.abs(dev - twin).max() < 1e-3 * twin.max()


@pytest.mark.parametrize("backend_name", ["device", "twin"])
def test_retro_confocal_return_over_wide_baseline_is_the_predicted_ratio(runtime, reference,
                                                                          backend_name):
    """A 1 cm plate 1 m from the wall, facing it, simulated (nl.simulate: the power scale with
    the model's `scale` included) with four (laser, detector) pairs: 0.1 mm apart (confocal:
    the setup refuses one spot for both), 2 and 4 cm apart (the lobe's angle psi ~ w and 2 w)
    and 1 m apart. A histogram's energy is a weighted sum over the plate of f times geometry,
    so a retroreflective target over a Lambertian one of brdf 1 (same geometry) must give
    f(psi), with psi from the plate's geometry alone; the plate's own spread of psi bounds how
    far off the mean may be. Neither implementation can fake this: it checks which directions
    reach the macro (facet -> laser and facet -> detector: retro where they coincide) and
    that the host applies the model's scale."""
    backend = runtime if backend_name == "device" else reference
    model = Retroreflective(retro=0.7, width_rad=0.02, diffuse=0.1)
    centre = np.array([0.0, 1.0, 0.0])
    spots = np.array([[-0.1, 0, 0], [-0.1, 0, 0.05], [-0.1, 0, -0.05], [-0.5, 0, 0]])
    lasers = spots + [[1e-4, 0, 0], [0.02, 0, 0], [0.04, 0, 0], [1.0, 0, 0]]
    mesh = nl.rectangle(0.01, 0.01, centre=centre, normal=(0, -1, 0), cell_m=0.005)
    energy = {"retro": [], "lambertian": []}
    for laser, spot in zip(lasers, spots):
        setup = nl.paper_setup(laser_spot=laser, detector_spots=[spot])
        axis = window_around(setup, mesh, 10e-12)
        for name, brdf_value in (("retro", model), ("lambertian", 1.0)):
            scene = nl.Scene(setup, nl.Target(mesh, brdf=brdf_value), 0.005)
            energy[name].append(
                nl.simulate(scene, axis, backend=backend).histograms().data.sum())
    ratio = np.array(energy["retro"]) / np.array(energy["lambertian"])
    corners = centre + np.array([[u, 0.0, w] for u in (-0.005, 0.0, 0.005)
                                 for w in (-0.005, 0.0, 0.005)])
    for k, (laser, spot) in enumerate(zip(lasers, spots)):
        to_l = laser - corners
        to_d = spot - corners
        cos_psi = np.einsum("ck,ck->c", to_l, to_d) / (
            np.linalg.norm(to_l, axis=1) * np.linalg.norm(to_d, axis=1))
        f = retro_brdf_by_hand(model, np.arccos(np.clip(cos_psi, -1, 1)))
        rel = 2e-5  # float32 sums (the device) and the erf's bins at the window's ends
        assert f.min() * (1 - rel) <= ratio[k] <= f.max() * (1 + rel), (k, ratio[k], f)
        # closer still: the plate is small and nearly symmetric about its centre, so the
        # spread's first order cancels and the mean is f(centre) to its square
        spread = (f.max() - f.min()) / f[4]
        assert abs(ratio[k] / f[4] - 1) <= spread ** 2 + rel, (k, ratio[k], f[4], spread)
    # and so the confocal return is brighter than the wide-baseline one by f(0) / f(1 m aside)
    expected = retro_brdf_by_hand(model, 0.0) / (model.diffuse / np.pi)
    assert ratio[0] / ratio[3] == pytest.approx(expected, rel=1e-3)
    assert expected > 100


