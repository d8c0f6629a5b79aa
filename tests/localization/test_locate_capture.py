"""nl.locate_capture: what `nlos-cl locate` does, as a library call (the CLI's JSON is its
as_json()), from a file or from HistogramSets, in the file's frame and in ours."""
import json
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.apps import cli
from nlos_cl.io.ytal.frames import INTERNAL, YTAL
from nlos_cl.io.json_format import covariance_json
from nlos_cl.localization.capture import search_region
from nlos_cl.localization.region import default_region

C = nl.SPEED_OF_LIGHT
TRUTH = np.array([4.0, 2.0, 0.0])  # ours; y-tal's (-4, 0, 2)


@pytest.fixture(scope="module")
def hist(runtime):
    axis = nl.TimeAxis(2 * 20 / C + 25e-9, 10e-12, 1500)
    return nl.simulate(nl.paper_scene(facet_size_m=0.02), axis, backend=runtime).histograms()


@pytest.fixture(scope="module")
def capture(hist, tmp_path_factory):
    return nl.write_capture(tmp_path_factory.mktemp("lc") / "c.h5", hist)


def test_the_cli_json_is_as_json(capture, capsys):
    assert cli.main(["locate", str(capture), "--json", "--estimator", "paper"]) == 0
    printed = json.loads(capsys.readouterr().out)
    found = json.loads(json.dumps(nl.locate_capture(str(capture), estimator="paper").as_json()))
    # the CLI adds to each target its spread, truth and error (apps/locate.py), and the truths
    assert {k: v for k, v in printed.items() if k not in ("targets", "truths")} == \
        {k: v for k, v in found.items() if k != "targets"}
    assert [t["position"] for t in printed["targets"]] == \
        [t["position"] for t in found["targets"]]


def test_positions_are_given_in_the_file_frame_and_in_ours(capture, hist):
    found = nl.locate_capture(capture)
    (point,) = found.points
    assert found.frame.name == "ytal" and found.source == str(capture)
    np.testing.assert_allclose(point.internal.position, TRUTH, atol=0.01)
    np.testing.assert_allclose(point.position, YTAL.from_internal(point.internal.position))
    np.testing.assert_allclose(found.position, [-4.0, 0.0, 2.0], atol=0.01)
    # the public Location is the file's too: no internal coordinate leaves without a conversion
    assert point.location.frame == "ytal" and point.internal.frame == "nlos_cl"
    np.testing.assert_allclose(point.location.position, point.position)
    np.testing.assert_allclose(point.location.targets[0].position, point.positions[0])
    np.testing.assert_array_equal(point.location.covariance, point.covariances[0])
    np.testing.assert_allclose(point.location.truth, YTAL.from_internal(TRUTH))
    ours, cov = point.internal.covariance, point.covariances[0]  # file (X, Y, Z) = (-x, z, y)
    assert np.isinf(ours[2, 2]) and np.isinf(cov[1, 1])  # the unobservable height
    assert cov[0, 0] == ours[0, 0] and cov[2, 2] == ours[1, 1] and cov[0, 2] == -ours[0, 1]
    assert point.as_json()["targets"][0]["covariance"] == covariance_json(
        point.internal.covariance, YTAL)
    assert any("height (up the wall) is unobservable" in w for w in point.warnings)
    assert not point.zoomed and not point.on_edge and point.log_mode is False
    sets = nl.locate_capture(hist, estimator="paper")  # already read: our frame
    assert sets.frame is INTERNAL and sets.source is None
    np.testing.assert_allclose(sets.position, sets.points[0].location.position)


def test_warnings_are_collected_not_raised(hist):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = nl.locate_capture(hist)
    assert found.points[0].warnings


def test_a_region_along_the_file_axes_or_a_grid_of_ours(capture):
    ranges = ((-4.3, -3.7), (0.0, 0.0), (1.7, 2.3))
    found = nl.locate_capture(capture, region=ranges, step_m=0.02, estimator="paper")
    point = found.points[0]
    assert point.grid.step == (0.02,) * 3 and point.grid is point.region
    lo_hi = YTAL.ranges(point.grid)
    np.testing.assert_allclose(lo_hi, ranges, atol=1e-9)
    grid = nl.Grid.from_ranges(x=(3.7, 4.3), y=(1.7, 2.3), step_m=0.02)
    ours = nl.locate_capture(capture, region=grid, estimator="paper").points[0]
    assert ours.grid is grid
    np.testing.assert_allclose(ours.location.position, point.location.position, atol=1e-6)


def test_a_coarsened_region_is_refined_on_a_zoom(capture):
    """A narrower filter asks for a finer step than 4 million cells allow: coarse, then zoom."""
    point = nl.locate_capture(capture, h_s=0.1e-9, estimator="paper").points[0]
    assert point.zoomed and min(point.grid.step) < min(point.region.step)
    np.testing.assert_allclose(point.internal.position, TRUTH, atol=0.05)


def test_an_edge_answer_warns_in_the_callers_words(capture):
    region = ((-4.02, -3.5), (0, 0), (1.5, 2.5))
    point = nl.locate_capture(capture, region=region, estimator="paper").points[0]
    assert point.on_edge and "widen it with region " in point.warnings[-1]
    cli_words = nl.locate_capture(capture, region=region, estimator="paper",
                                  names=("--region", "--step")).points[0]
    assert "widen it with --region " in cli_words.warnings[-1]


def test_calibration_and_background_apply_to_every_laser_point(hist):
    cal = nl.PathCalibration(C, [float(hist.calibration.b_m[0]) + 0.01])
    found = nl.locate_capture(hist, calibration=cal, estimator="paper")
    assert found.as_json()["calibration"] == {"a_m_per_s": C, "b_m": cal.b_m[0]}
    empty = nl.HistogramSet(np.zeros_like(hist.data), hist.time_axis, hist.detector_spots,
                            hist.laser_spot, hist.calibration)
    plain = nl.locate_capture(hist, estimator="paper").points[0].location.position
    minus = nl.locate_capture(hist, background=empty, estimator="paper")
    np.testing.assert_allclose(minus.points[0].location.position, plain)


@pytest.mark.parametrize("kwargs, field", [
    ({"region": (1, 2, 3)}, "region: expected three (low, high) ranges"),
    ({"region": (1, 2, 3), "names": ("--region", "--step")}, "--region: expected"),
    ({"region": ((-50, 50), (0.01, 50), (0, 50)), "step_m": 1e-4}, "region: 2.5e+17 cells"),
    ({"h_s": -1.0}, "h_s: the filter window"),
    ({"background": []}, "background: has 0 laser point(s)"),
    ({"estimator": "best"}, "estimator: unknown name"),
])
def test_bad_input_names_the_field(hist, kwargs, field):
    with pytest.raises(nl.InputError, match="Fix:") as info:
        nl.locate_capture(hist, **kwargs)
    assert field in str(info.value)


def test_not_a_capture_is_refused():
    with pytest.raises(nl.InputError, match="capture: expected a capture's path"):
        nl.locate_capture(42)


def test_covariance_json_moves_entries_with_the_frame():
    cov = np.diag([1e-4, 4e-4, np.inf])  # ours: z unobservable
    assert covariance_json(cov) == [[1e-4, 0.0, 0.0], [0.0, 4e-4, 0.0], [0.0, 0.0, None]]
    # y-tal (X, Y, Z) = (-x, z, y): our z is the file's Y
    assert covariance_json(cov, YTAL) == [[1e-4, -0.0, 0.0], [-0.0, None, 0.0],
                                          [0.0, 0.0, 4e-4]]
    assert covariance_json(None) is None


def test_search_region_is_the_derived_one_without_ranges(hist):
    grid, derived = search_region(hist)
    assert derived and grid == default_region(hist)
