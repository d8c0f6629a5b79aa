"""Every bad input gets an InputError naming the field and the fix; inputs stay unmodified."""
import numpy as np
import pytest
import trimesh

import nlos_cl as nl

C = nl.SPEED_OF_LIGHT


def raises(field, fn, *args, **kwargs):
    with pytest.raises(nl.InputError) as info:
        fn(*args, **kwargs)
    msg = str(info.value)
    assert field in msg and "Fix:" in msg, msg
    return msg


def good_histograms(data=None):
    data = np.ones((3, 100)) if data is None else data
    return nl.HistogramSet(data, nl.TimeAxis(1e-7, 1e-11, data.shape[1]),
                           nl.paper_setup().detector_spots, [0, 0, 0],
                           nl.PathCalibration(C, [-40.0]))


@pytest.mark.parametrize("kwargs", [dict(t0_s=float("nan"), dt_s=1e-12, n_bins=10),
                                    dict(t0_s=0.0, dt_s=float("inf"), n_bins=10),
                                    dict(t0_s=0.0, dt_s=-1e-12, n_bins=10),
                                    dict(t0_s=0.0, dt_s=1e-12, n_bins=-5)])
def test_bad_time_axis(kwargs):
    raises("time_axis.", nl.TimeAxis, **kwargs)


def test_nan_and_negative_bins():
    data = np.ones((3, 100))
    data[1, 5] = np.nan
    raises("histograms.data", good_histograms, data)
    neg = -np.ones((3, 100))
    raises("histograms.data", nl.HistogramSet, neg, nl.TimeAxis(0, 1e-11, 100),
           nl.paper_setup().detector_spots, [0, 0, 0], nl.PathCalibration(C, [0.0]),
           allow_negative=False)


def test_mismatched_shapes():
    raises("histograms.detector_spots", nl.HistogramSet, np.ones((2, 100)),
           nl.TimeAxis(0, 1e-11, 100), np.zeros((3, 3)), [0, 0, 0], nl.PathCalibration(C, [0.0]))
    raises("histograms.data", nl.HistogramSet, np.ones((3, 90)), nl.TimeAxis(0, 1e-11, 100),
           np.zeros((3, 3)), [0, 0, 0], nl.PathCalibration(C, [0.0]))


def test_empty_and_degenerate_meshes():
    raises("target.mesh", nl.Target, trimesh.Trimesh())
    flat = trimesh.Trimesh([[4, 1, 0], [4, 2, 0], [4, 3, 0]], [[0, 1, 2]], process=False)
    raises("target.mesh", nl.Target, flat)
    raises("target.mesh", nl.Target, "not a mesh")


def test_target_behind_or_on_the_wall():
    raises("target.mesh", nl.Target, nl.rectangle(centre=(4.0, 0.1, 0.0)))  # straddles y = 0
    raises("target.mesh", nl.Target, nl.box(centre=(1.0, -2.0, 0.0)))


def test_target_facing_away_lights_nothing():
    mesh = nl.rectangle(normal=(1.0, 0.0, 0.0))  # faces away from O and the spots
    scene = nl.Scene(nl.paper_setup(), nl.Target(mesh), 0.05)
    raises("scene.target", nl.simulate, scene)


def test_coincident_detectors_and_laser():
    raises("setup.detector_spots", nl.Setup, detector_spots=[[-1, 0, 0], [-1, 0, 0]])
    raises("setup.detector_spots", nl.Setup, detector_spots=[[0, 0, 0], [-1, 0, 0]])
    raises("setup.detector_spots", nl.Setup, detector_spots=[[-1, 0.5, 0]])  # off the wall
    raises("setup.laser_spot", nl.Setup, laser_spot=[0, 0, float("nan")])


@pytest.mark.parametrize("h", [0.0, -1e-9, float("nan"), 1e-13, 1e-3])
def test_bad_filter_window(h):
    raises("h_s", nl.gauss_filter, good_histograms(), h, backend="reference")


def test_window_that_ends_before_the_signal():
    scene = nl.paper_scene(facet_size_m=0.05)
    early = nl.TimeAxis(2 * 20 / C, 10e-12, 100)  # 1 ns of hidden path: the target is ~30 ns out
    msg = raises("time_axis", nl.simulate, scene, early)
    assert "n_bins" in msg


def test_empty_or_inverted_grid():
    raises("grid.shape", nl.Grid, (0, 0.01, 0), (0.01,) * 3, (0, 10, 1))
    raises("grid.x", nl.Grid.from_ranges, x=(6.0, 0.0))
    raises("grid.step", nl.Grid, (0, 0.01, 0), (0.01, 0.0, 0.01), (5, 5, 1))
    raises("grid.origin", nl.Grid, (0, -1.0, 0), (0.01,) * 3, (5, 5, 1))


def test_grid_the_signal_never_reaches():
    hist = nl.simulate(nl.paper_scene(facet_size_m=0.05), backend="reference").histograms()
    far = nl.Grid.from_ranges(x=(40, 41), y=(40, 41), step_m=0.1)
    raises("grid", nl.locate, nl.gauss_filter(hist, backend="reference"), far)


def test_bad_noise_arguments():
    raises("snr_db", nl.add_noise, good_histograms(), float("nan"), backend="reference")
    raises("seed", nl.add_noise, good_histograms(), 10.0, -1, backend="reference")


def test_bad_mesh_file(tmp_path):
    bad = tmp_path / "broken.stl"
    bad.write_text("solid nothing\nthis is not an stl\n")
    raises("mesh file", nl.load_mesh, bad)


def test_inputs_are_not_modified():
    data = np.ones((3, 100))
    spots = nl.paper_setup().detector_spots.copy()
    hist = good_histograms(data)
    data[0, 0] = 7.0  # the set holds its own copy
    assert hist.data[0, 0] == 1.0
    assert not hist.data.flags.writeable
    mesh = nl.rectangle()
    vertices = mesh.vertices.copy()
    target = nl.Target(mesh)
    mesh.apply_translation([1, 0, 0])  # later edits to the caller's mesh do not leak in
    assert np.array_equal(target.mesh.vertices, vertices)
    nl.gauss_filter(hist, backend="reference")
    assert np.array_equal(nl.paper_setup().detector_spots, spots)
