"""The glossy reflectance model (nlos_cl.physics.reflectance.GGX) through the reflectance seam: kernel
against twin, and properties of the BRDF itself that no implementation detail can fake."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.physics.reflectance import GGX, from_spec
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


def test_glossy_target_from_a_scene_file():
    from nlos_cl.io.scenefile import load_scene
    spec = load_scene({"targets": [{"shape": "rectangle", "position": [3, 1, 0],
                                    "reflectance": {"model": "ggx", "specular": 0.5,
                                                    "roughness": 0.2, "diffuse": 0.1}}]})
    assert spec.scene.target.reflectance == GGX(0.5, 0.2, 0.1)
    with pytest.raises(InputError, match="roughness"):
        from_spec({"model": "ggx", "roughness": 0.0})
    with pytest.raises(InputError, match="unknown key"):
        from_spec({"model": "ggx", "shininess": 3})
    with pytest.raises(InputError, match="exceeds 1"):
        GGX(specular=0.8, diffuse=0.5)
    with pytest.raises(InputError, match="together with brdf"):
        load_scene({"targets": [{"shape": "rectangle", "brdf": 0.1,
                                 "reflectance": {"model": "lambertian"}}]})
