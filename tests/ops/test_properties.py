"""Property-based: random scenes (target position, size, orientation), detector layouts, time
axes and grids; every kernel against its NumPy twin, with the tolerances of
test_kernels_vs_reference.py. 200 + 100 examples (about 20 s on 2 CPU cores)."""
import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nlos_cl as nl
from conftest import window_around

PROPERTY_SETTINGS = dict(deadline=None, derandomize=True,
                         suppress_health_check=[HealthCheck.too_slow,
                                                HealthCheck.function_scoped_fixture])

positions = st.tuples(st.floats(0.3, 5.5), st.floats(0.6, 5.5), st.floats(-1.0, 1.0))
layouts = st.lists(st.tuples(st.floats(-2.0, 2.0), st.floats(-1.0, 1.0)), min_size=1,
                   max_size=6, unique_by=lambda p: (round(p[0], 2), round(p[1], 2)))


def make_scene(position, width, height, turn, tilt, layout, facet):
    p = np.array(position)
    spots = np.array([[x, 0.0, z] for x, z in layout])
    spots = spots[np.linalg.norm(spots, axis=1) > 0.05]  # not on the laser spot
    if len(spots) == 0:
        spots = np.array([[-0.5, 0.0, 0.0]])
    towards = -p / np.linalg.norm(p)  # facing the laser spot O, turned and tilted a little
    mesh = nl.rectangle(width, height, centre=(0.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0),
                        cell_m=facet)
    mesh.apply_transform(nl_rotation(towards, turn, tilt))
    mesh.apply_translation(p)
    if mesh.vertices[:, 1].min() <= 0.01:
        mesh.apply_translation([0.0, 0.02 - mesh.vertices[:, 1].min(), 0.0])
    return nl.Scene(nl.paper_setup(detector_spots=spots), nl.Target(mesh), facet)


def outcome(call):
    """The result, or the InputError's message (so two backends can be compared either way)."""
    try:
        return call()
    except nl.InputError as exc:
        return str(exc)


def nl_rotation(direction, turn, tilt):
    """Rotate +x onto `direction`, then turn about z and tilt about the new horizontal axis."""
    import trimesh
    yaw = math.atan2(direction[1], direction[0]) + turn
    pitch = math.asin(np.clip(direction[2], -1, 1)) + tilt
    return (trimesh.transformations.rotation_matrix(yaw, [0, 0, 1])
            @ trimesh.transformations.rotation_matrix(-pitch, [0, 1, 0]))


@settings(max_examples=200, **PROPERTY_SETTINGS)
@given(position=positions, width=st.floats(0.02, 0.6), height=st.floats(0.02, 0.6),
       turn=st.floats(-0.9, 0.9), tilt=st.floats(-0.6, 0.6), layout=layouts,
       dt_ps=st.sampled_from([1.0, 4.0, 10.0, 50.0]))
def test_forward_matches_twin_on_random_scenes(runtime, reference, position, width, height,
                                               turn, tilt, layout, dt_ps):
    facet = max(width, height) / 12
    scene = make_scene(position, width, height, turn, tilt, layout, facet)
    axis = window_around(scene.setup, scene.target.mesh, dt_ps * 1e-12, margin_m=0.1)
    dev, twin = (outcome(lambda: nl.simulate(scene, axis, backend=be).histograms().data)
                 for be in (runtime, reference))
    if isinstance(twin, str) or isinstance(dev, str):  # e.g. turned away from every spot
        assert isinstance(dev, str) and isinstance(twin, str), (dev, twin)
        assert dev == twin and "scene.target" in twin
        return
    assert np.abs(dev - twin).max() <= 1e-3 * twin.max()


@settings(max_examples=100, **PROPERTY_SETTINGS)
@given(layout=layouts, origin=positions, step=st.floats(0.005, 0.1),
       shape=st.tuples(st.integers(1, 70), st.integers(1, 40), st.integers(1, 6)),
       log_mode=st.booleans(), centre_bin=st.integers(300, 2500), width_bins=st.floats(30, 300))
def test_ellipse_score_matches_twin_on_random_grids(runtime, reference, layout, origin, step,
                                                     shape, log_mode, centre_bin, width_bins):
    spots = np.array([[x, 0.0, z] for x, z in layout])
    n_det = len(spots)
    k = np.arange(3000)
    signal = np.exp(-0.5 * ((k[None, :] - centre_bin - 37 * np.arange(n_det)[:, None])
                            / width_bins) ** 2)
    hist = nl.HistogramSet(signal, nl.TimeAxis(0.0, 10e-12, 3000), spots, [0, 0, 0],
                           nl.PathCalibration(nl.SPEED_OF_LIGHT, [2.0]))
    grid = nl.Grid((origin[0], max(origin[1], 0.01), origin[2]), (step,) * 3, shape)
    a, b = (outcome(lambda: nl.locate(hist, grid, log_mode=log_mode, return_map=True,
                                      backend=be, estimator="paper").score_map) for be in (runtime, reference))
    if isinstance(a, str) or isinstance(b, str):  # the signal reaches no cell: both must say so
        assert isinstance(a, str) and isinstance(b, str), (a, b)
        assert a == b and a.startswith("grid")
        return
    if log_mode:  # compare likelihoods: log-space errors near the floor are meaningless
        a, b = np.exp(a), np.exp(b)
    assert np.abs(a - b).max() <= 1e-3 * max(b.max(), 1e-30)
