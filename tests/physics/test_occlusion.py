"""Self-occlusion and mutual shadowing (nlos_cl/visibility.py): the ray caster against a
brute-force twin, geometry that decides visibility by itself, and the forward operation's mask."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.physics.meshes import l_block
from nlos_cl.physics.visibility import any_hit_brute, any_hit_numpy, visibility
from conftest import window_around


def test_cluster_caster_matches_brute_force():
    rng = np.random.default_rng(3)
    tris = rng.uniform(-1, 1, (700, 1, 3)) + rng.uniform(-0.2, 0.2, (700, 3, 3))
    origins = rng.uniform(-1.5, 1.5, (3000, 3))
    dirs = rng.standard_normal((3000, 3))
    dirs[:50, 0] = 0.0  # axis-parallel rays: slab test with infinite inverse components
    hits = any_hit_numpy(origins, dirs, tris)
    np.testing.assert_array_equal(hits, any_hit_brute(origins, dirs, tris))
    assert 0.1 < hits.mean() < 0.9


def l_scene(**kw):
    setup = nl.paper_setup(detector_spots=[[-0.5, 0, 0.0], [-1.0, 0, 0.2], [0.8, 0, -0.1]])
    return nl.Scene(setup, nl.Target(l_block(centre=(1.2, 1.5, 0.0))), 0.02, **kw)


def test_l_block_visibility_matches_brute_force():
    scene = l_scene()
    vis = scene.visibility()
    assert vis is not None and scene.visibility() is vis  # cached
    twin = visibility(scene.facets(), scene.setup.laser_spot, scene.setup.detector_spots,
                      [scene.target.mesh], 0, caster=any_hit_brute)
    np.testing.assert_array_equal(vis, twin)
    assert 0 < vis.mean() < 1


def test_concave_notch_faces_are_shadowed_by_the_block():
    # The notch's inner face y = 1.6 (x in [1.2, 1.5], facing the wall) sees a wall point P
    # iff the segment to P leaves the notch past the arm's corner: at the arm's front y = 1.3
    # it must be at x > 1.2 (the block is full height, the spots within its height).
    scene = l_scene()
    f, vis = scene.facets(), scene.visibility()
    inner = (np.abs(f.centres[:, 1] - 1.6) < 1e-9) & (f.normals[:, 1] < -0.99)
    assert inner.sum() > 10
    c = f.centres[inner]
    clear = lambda p: p[0] + (c[:, 0] - p[0]) * (1.3 / 1.6) > 1.2  # noqa: E731
    for d, spot in enumerate(scene.setup.detector_spots):
        np.testing.assert_array_equal(vis[d, inner], clear(scene.setup.laser_spot) & clear(spot))
    assert vis[:, inner].any() and not vis[:, inner].all()
    # The notch's side face x = 1.2 faces +x, away from every spot (all at x <= 0.8).
    side = (np.abs(f.centres[:, 0] - 1.2) < 1e-9) & (f.normals[:, 0] > 0.99)
    assert side.sum() > 10 and not vis[:, side].any()


def test_occlusion_changes_a_concave_scene_only(runtime):
    on, off = l_scene(), l_scene(occlusion=False)
    axis = window_around(on.setup, on.target.mesh, 20e-12)
    e_on = nl.simulate(on, axis, backend=runtime).histograms().data.sum()
    e_off = nl.simulate(off, axis, backend=runtime).histograms().data.sum()
    assert e_on < e_off * 0.999
    box = nl.Scene(on.setup, nl.Target(nl.box((0.3, 0.3, 0.4), (1.2, 1.5, 0))), 0.02)
    assert box.visibility() is None  # convex: nothing to test


def plate(centre, size=0.4):
    return nl.rectangle(size, size, centre=centre, normal=-np.asarray(centre) * [1, 1, 0],
                        cell_m=0.02)


def test_a_plate_fully_behind_another_returns_nothing(runtime, reference):
    setup = nl.paper_setup(detector_spots=[[-0.3, 0, 0.0], [0.3, 0, 0.0]])
    front = nl.Target(plate((0.0, 1.0, 0.0), 1.2))  # 1.2 m plate 1 m from the wall
    behind = nl.Target(plate((0.0, 2.5, 0.0), 0.2))  # 0.2 m plate behind it
    both = nl.Scene(setup, front, 0.02, more_targets=(behind,))
    alone = nl.Scene(setup, front, 0.02)
    assert not both.visibility(1).any() and both.visibility(0).all()
    axis = window_around(setup, front.mesh, 20e-12, margin_m=3.0)
    for backend in (runtime, reference):
        with pytest.warns(UserWarning, match="hidden from detector"):
            a = nl.simulate(both, axis, backend=backend).histograms().data
        b = nl.simulate(alone, axis, backend=backend).histograms().data
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * b.max())
    off = nl.Scene(setup, front, 0.02, more_targets=(behind,), occlusion=False)
    assert nl.simulate(off, axis, backend=reference).histograms().data.sum() > b.sum() * 1.001


def test_half_shadowed_plate_loses_the_shadowed_half(reference):
    # An opaque plate covering x < 0 in front of a target plate spanning x in [-0.2, 0.2]:
    # with the laser and both spots at x > 0.5, the shadow boundary is computed exactly.
    setup = nl.paper_setup(laser_spot=[1.0, 0, 0], detector_spots=[[0.9, 0, 0.0], [1.1, 0, 0]])
    target = nl.Target(nl.rectangle(0.4, 0.4, centre=(0.0, 2.0, 0.0), normal=(0, -1, 0),
                                    cell_m=0.01))
    blocker = nl.Target(nl.rectangle(1.0, 1.0, centre=(-0.5, 1.0, 0.0), normal=(0, -1, 0),
                                     cell_m=0.05))
    scene = nl.Scene(setup, target, 0.01, more_targets=(blocker,))
    f, vis = scene.facets(), scene.visibility()
    # A point (x, 2, z) sees wall point (sx, 0, sz) iff the segment crosses y = 1 at x > 0.
    for d, spot in enumerate(setup.detector_spots):
        clear = ((f.centres[:, 0] + setup.laser_spot[0]) / 2 > 0) & (
            (f.centres[:, 0] + spot[0]) / 2 > 0)
        np.testing.assert_array_equal(vis[d], clear)


@pytest.mark.parametrize("method", ["deposit", "erf"])
def test_forward_mask_kernel_matches_twin(device_runtime, reference, method):
    scene = l_scene()
    from nlos_cl.ops.forward import scene_inputs
    axis = window_around(scene.setup, scene.target.mesh, 20e-12)
    args = scene_inputs(scene, axis) + (method, scene.visibility())
    dev = device_runtime.to_numpy(device_runtime.forward(*args)[0])
    twin = reference.forward(*args)[0]
    assert np.abs(dev - twin).max() < 1e-3 * twin.max()
