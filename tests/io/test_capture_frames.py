"""The capture's own frame, the default search region a capture can see, and locating a
y-tal-frame capture whose target lies on either side of X = 0 with no grid given."""
import h5py
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.io.ytal import frames
from nlos_cl.localization import region
from nlos_cl.io.ytal.capture import GRID_FORMATS, H_FORMATS

C = nl.SPEED_OF_LIGHT


def layout(spots, n_bins=1800, dt=10e-12, laser=(0, 0, 0), b=-40.0):
    return nl.HistogramSet(np.ones((len(spots), n_bins)), nl.TimeAxis(40 / C, dt, n_bins),
                           spots, laser, nl.PathCalibration(C, [b]))


PAPER = [[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0]]


def test_ytal_frame_maps_both_ways_and_names_its_axes():
    f = frames.YTAL
    pts = np.array([[1.0, 2.0, 3.0], [-4.0, 0.5, 0.1]])
    assert np.allclose(f.to_internal(pts), [[-1.0, 3.0, 2.0], [4.0, 0.1, 0.5]])
    assert np.allclose(f.from_internal(f.to_internal(pts)), pts)
    assert np.isclose(np.linalg.det(np.asarray(f.matrix)), 1.0)  # a rotation, no mirror
    assert f.as_json()["name"] == "ytal" and f.as_json()["axes"] == ["X", "Y", "Z"]


def test_grid_given_in_file_coordinates():
    g = frames.YTAL.grid([(-1.0, 2.0), (0.0, 0.0), (0.5, 3.0)], step_m=0.5)
    assert np.allclose(g.axes()[0], [-2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0])  # x = -X
    assert np.allclose(g.axes()[1], [0.5, 1.0, 1.5, 2.0, 2.5, 3.0])  # y = Z
    assert g.shape[2] == 1
    assert frames.YTAL.ranges(g) == ((-1.0, 2.0), (0.0, 0.0), (0.5, 3.0))
    with pytest.raises(nl.InputError, match=r"grid\.Z: .*hidden space is Z > 0"):
        frames.YTAL.grid([(-1, 1), (0, 0), (-1.0, 3.0)], step_m=0.1)
    with pytest.raises(nl.InputError, match=r"grid\.X"):
        frames.YTAL.grid([(1, -1), (0, 0), (1.0, 3.0)], step_m=0.1)


def test_default_region_covers_both_sides_out_to_the_window():
    h = layout(PAPER)  # hidden path reach = c * (40/c + 18 ns) - 40 = 5.40 m
    g = region.default_region(h)
    x, y, z = g.axes()
    reach = C * 1800 * 10e-12  # hidden path at the window's end
    A = reach / 2  # semi-major axis of every ellipse (foci O = 0 and D = (-d, 0, 0))
    # x: the box of the ellipse around O and D = -0.5 starts furthest right, that of D = -1.5
    # ends furthest left; y: the flattest ellipse (D = -1.5) is the lowest
    # cells sit on whole multiples of the step, inside the box: within one step of its edge
    assert -0.25 - A <= x[0] < -0.25 - A + g.step[0] and x[0] / g.step[0] == pytest.approx(
        round(x[0] / g.step[0]), abs=1e-6)
    assert x[-1] == pytest.approx(A - 0.75, abs=0.01)
    assert x[0] < -1.5 - 1 and x[-1] > 0 + 1  # over a metre beyond the spots on each side
    assert y[0] > 0 and y[-1] == pytest.approx(np.sqrt(A ** 2 - 0.75 ** 2), abs=0.01)
    assert g.shape[2] == 1 and z[0] == 0.0  # collinear spots: height unobservable
    assert g.step[0] == 0.01  # a max(h/3, dt) / 4 = 1.6 cm, rounded down to 1 cm

    def paths(c):
        return np.linalg.norm(c) + np.linalg.norm(np.asarray(c) - np.asarray(PAPER), axis=1)
    # the region's extreme points (at the wall, y = 0, for x) are in view of every detector ...
    for c in ([x[0], 0, 0], [x[-1], 0, 0], [-0.75, y[-1], 0]):
        assert paths(c).max() <= reach + 1e-9
    # ... and two cells beyond the region, one detector no longer sees it
    assert paths([x[0] - 2 * g.step[0], 0, 0]).max() > reach
    assert paths([x[-1] + 2 * g.step[0], 0, 0]).max() > reach
    assert paths([-0.75, y[-1] + 2 * g.step[0], 0]).max() > reach


def test_default_region_is_3d_when_height_is_observable_and_capped():
    h = layout([[-1, 0, 0], [1, 0, 0], [0, 0, 1]])
    g = region.default_region(h, max_cells=200_000)
    assert g.shape[2] > 1 and g.n_cells <= 200_000
    z = g.axes()[2]
    assert z[0] < -1 and z[-1] > 1  # below and above the spots
    assert g.step[0] > 0.01  # coarsened to fit


def test_vertical_line_of_spots_gives_the_plane_x_equal_their_x():
    g = region.default_region(layout([[0.3, 0, 0.5], [0.3, 0, 1.0]], laser=(0.3, 0, 0)))
    assert g.shape[0] == 1 and g.axes()[0][0] == pytest.approx(0.3) and g.shape[2] > 1


@pytest.mark.parametrize("h, message", [
    (lambda: layout([[-1, 0, 0]]), "single detector"),
    (lambda: layout(PAPER, n_bins=10, b=-45.0), "no hidden point is in view"),
])
def test_default_region_refuses_what_cannot_be_located(h, message):
    with pytest.raises(nl.InputError, match=message):
        region.default_region(h())


def test_on_region_edge():
    g = nl.Grid.from_ranges(x=(-1, 1), y=(0.1, 2), step_m=0.1)
    assert not region.on_region_edge([0.0, 1.0, 0.0], g)
    assert region.on_region_edge([-0.97, 1.0, 0.0], g)
    assert region.on_region_edge([0.0, 1.95, 0.0], g)
    assert region.on_region_edge([5.0, 1.0, 0.0], g)  # outside
    assert not region.on_region_edge([0.0, 1.0, 0.0], g)  # z: one cell, never an edge


def ytal_capture(path, hist, spots_ours):
    """A capture laid out as y-tal writes it, from a simulation in our frame."""
    with h5py.File(path, "w") as f:
        f["H"] = hist.data.T.astype(np.float32)
        for name, members, value in (("H_format", H_FORMATS, "T_Si"),
                                     ("sensor_grid_format", GRID_FORMATS, "N_3"),
                                     ("laser_grid_format", GRID_FORMATS, "N_3")):
            f.create_dataset(name, (1,), dtype=h5py.enum_dtype(members, basetype="i"))[0] = \
                members[value]
        f["sensor_grid_xyz"] = frames.to_ytal(spots_ours).astype(np.float32)
        f["laser_grid_xyz"] = frames.to_ytal([[0, 0, 0]]).astype(np.float32)
        f["delta_t"] = np.float32(C * hist.time_axis.dt_s)
        f["t_start"] = np.float32(C * (hist.time_axis.t0_s + 0.5 * hist.time_axis.dt_s)
                                  + hist.calibration.b_m[0])
        f["t_accounts_first_and_last_bounces"] = False


@pytest.mark.parametrize("truth_ytal", [(2.5, 0.0, 2.0), (-3.0, 0.0, 1.5)])
def test_a_ytal_capture_locates_on_either_side_with_no_grid_given(runtime, tmp_path, truth_ytal):
    """The issue's failure: a target at positive X is at negative x internally, outside the
    paper's grid. The default region covers it, and the answer comes back in the file's frame."""
    truth = frames.YTAL.to_internal(truth_ytal)
    setup = nl.paper_setup()
    normal = np.array([-0.75, 0, 0]) - truth
    mesh = nl.rectangle(0.3, 0.3, centre=truth, normal=normal, cell_m=0.01)
    axis = nl.TimeAxis(2 * 20 / C + setup.pulse.peak_delay_s, 10e-12, 3000)  # 9 m of path
    hist = nl.simulate(nl.Scene(setup, nl.Target(mesh), 0.01), axis, backend=runtime).histograms()
    ytal_capture(tmp_path / "y.hdf5", hist, setup.detector_spots)
    (capture,), frame = nl.capture.read_capture_with_frame(tmp_path / "y.hdf5")
    assert frame is frames.YTAL
    grid = region.default_region(capture, 0.65e-9)
    loc = nl.locate(nl.gauss_filter(capture, 0.65e-9, backend=runtime), grid, backend=runtime,
                     estimator="paper")
    found = frame.from_internal(loc.position)
    assert np.linalg.norm(found - truth_ytal) < 0.05, found
    assert not region.on_region_edge(loc.position, grid)


def test_zoom_region_refines_a_coarse_answer():
    h = layout([[-1, 0, 0], [1, 0, 0], [0, 0, 1]])
    coarse = region.default_region(h, max_cells=100_000)
    fine = region.zoom_region([0.5, 2.0, 0.3], coarse, h)
    assert fine.step[0] == 0.01 and fine.n_cells < 5_000_000
    lo, hi = [a[0] for a in fine.axes()], [a[-1] for a in fine.axes()]
    assert np.all(np.array(lo) <= [0.5, 2.0, 0.3]) and np.all(np.array(hi) >= [0.5, 2.0, 0.3])
    assert hi[0] - lo[0] == pytest.approx(8 * coarse.step[0], abs=0.02)
