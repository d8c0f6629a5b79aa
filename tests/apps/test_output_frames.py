"""One frame everywhere: a known target lands at the same coordinates, in the capture's own
frame (y-tal's X, Y, Z = -x, z, y of ours), in every output a user sees or keeps: simulate's
message, locate's text, JSON, --map arrays (the final grid's and the whole region's) and
--map figure, the Python API's locate_capture (its Location
included) and track_sequence steps, track's text, JSON and --csv lines, and the video's view. The target sits off every
axis (X < 0, Y > 0, Z > 0, all different), so a sign or a swapped axis anywhere shows."""
import csv
import json
import re

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.apps.cli import main
from nlos_cl.apps.track_video import TopView
from nlos_cl.io.ytal.frames import YTAL
from nlos_cl.tracking import read_sequence

OURS = [0.8, 2.2, 0.35]  # the scene file's (x, y, z)
FILE = [-0.8, 0.35, 2.2]  # the capture's (X, Y, Z)
SCENE = f"""description: a square off every axis, seen by 8 spots on a circle
setup: {{detector_spots: {{circle: {{centre: [-1, 0, 0], radius_m: 0.5, count: 8}}}}}}
targets:
  - {{shape: rectangle, size_m: [0.4, 0.4], position: {OURS}, normal: [0, -1, 0]}}
facet_size_m: 0.02
time_axis: {{dt_s: 10e-12}}
noise: {{snr_db: 20, seed: 1}}
"""
NUMBER = r"(-?\d+\.\d+)"


def _run(capsys, *argv) -> tuple[int, str]:
    capsys.readouterr()
    status = main(list(argv))
    return status, capsys.readouterr().out


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frames")
    (folder / "square.yaml").write_text(SCENE)
    return folder


def test_a_located_target_has_the_same_coordinates_in_every_locate_output(capture, capsys,
                                                                          monkeypatch):
    scene, cap, arrays = capture / "square.yaml", capture / "square.h5", capture / "map.npz"
    status, said = _run(capsys, "simulate", str(scene), "--out", str(cap))
    assert status == 0
    told = json.loads(re.search(r"\(X, Y, Z\) = (\[\[.*?\]\])", said).group(1))
    np.testing.assert_allclose(told, [FILE], atol=1e-9)

    status, out = _run(capsys, "locate", str(cap), "--json", "--map", str(arrays))
    assert status == 0
    answer = json.loads(out)
    assert answer["frame"]["axes"] == ["X", "Y", "Z"]
    np.testing.assert_allclose(answer["truth"], FILE, atol=1e-5)
    np.testing.assert_allclose(answer["position"], FILE, atol=0.1)  # it is located, near
    with np.load(arrays, allow_pickle=False) as m:  # the map's best cell: the JSON's
        best = np.unravel_index(np.argmax(m["score"]), m["score"].shape)
        np.testing.assert_allclose([m[a][i] for a, i in zip("XYZ", best)],
                                   answer["argmax_cell"], atol=1e-5)
        # the whole region's map (the search zoomed): its best cell within a cell of it
        whole = [m[f"region_{a}"] for a in "XYZ"]
        best = np.unravel_index(np.argmax(m["region_score"]), m["region_score"].shape)
        steps = [a[1] - a[0] if a.size > 1 else 0.0 for a in whole]
        assert all(abs(a[i] - v) <= s + 1e-9 for a, i, v, s in
                   zip(whole, best, answer["argmax_cell"], steps))

    from nlos_cl.apps import plotting
    views, draw = [], plotting.map_figure
    monkeypatch.setattr(plotting, "map_figure", lambda fh, v: (views.append(v), draw(fh, v)))
    status, _ = _run(capsys, "locate", str(cap), "--map", str(capture / "map.png"))
    [view] = views  # the figure: X across, Z from the wall, the truth and answer where told
    assert status == 0 and view["labels"] == ["X", "Z", "Y"]
    np.testing.assert_allclose(view["truths"], [[FILE[0], FILE[2]]], atol=1e-9)
    np.testing.assert_allclose(view["targets"][0][0], np.take(answer["position"], [0, 2]),
                               atol=1e-4)

    status, text = _run(capsys, "locate", str(cap))
    line = re.search(rf"X {NUMBER} ± \S+, Y {NUMBER} ± \S+, Z {NUMBER} ± ", text)
    np.testing.assert_allclose([float(v) for v in line.groups()], answer["position"], atol=1e-4)
    assert "(z)" not in text + out  # no warning names our axes

    found = nl.locate_capture(str(cap))  # the API, as a notebook calls it
    point = found.points[0]
    for where in (found.position, point.position, point.location.position,
                  point.location.targets[0].position, point.positions[0]):
        np.testing.assert_allclose(where, answer["position"], atol=1e-4)
    np.testing.assert_allclose(point.location.truth, FILE, atol=1e-9)
    np.testing.assert_allclose(point.internal.position, YTAL.to_internal(point.position))


def test_a_tracked_target_has_the_same_coordinates_in_every_track_output(walk_file, capsys,
                                                                         tmp_path):
    seq = read_sequence(walk_file)
    truths = [seq.frame.from_internal(f.truths[0]) for f in seq]
    table = tmp_path / "tracks.csv"
    status, out = _run(capsys, "track", str(walk_file), "--json", "--no-progress", "--csv",
                       str(table))
    assert status == 0
    lines = [json.loads(x) for x in out.splitlines() if x.startswith("{")]
    assert len(lines) == len(seq) == 12
    rows = list(csv.DictReader(table.open()))
    assert list(rows[0])[:8] == ["frame", "t_s", "kind", "id", "status", "X", "Y", "Z"]
    for step, e in zip(nl.track_sequence(walk_file), lines):  # the API: the file's frame too
        assert step.as_json() == e
        np.testing.assert_allclose(step.positions, [t["position"] for t in e["tracks"]],
                                   atol=1e-5)
    status, text = _run(capsys, "track", str(walk_file), "--no-progress")
    said = [tuple(float(v) for v in m) for m in
            re.findall(rf"X {NUMBER} ± \S+, Y {NUMBER} ± \S+, Z {NUMBER} ± ", text)]
    assert len(said) == sum(len(e["tracks"]) for e in lines) > 0
    spoken = iter(said)
    for e, truth in zip(lines, truths):
        np.testing.assert_allclose(e["truths"][0], truth, atol=1e-5)
        assert truth[0] < 0 and abs(truth[1]) < 1e-9 and truth[2] > 1  # X = -x, Z = y
        kept = [r for r in rows if int(r["frame"]) == e["frame"]]
        got = {r["kind"]: [float(r[a]) for a in "XYZ"] for r in kept}
        np.testing.assert_allclose(got["truth"], e["truths"][0], atol=1e-5)
        for t in e["tracks"]:
            np.testing.assert_allclose(got["track"], t["position"], atol=1e-5)
            np.testing.assert_allclose(next(spoken), t["position"], atol=1e-4)
            assert np.linalg.norm(np.subtract(t["position"], truth)) < 0.3


def test_the_video_shows_the_files_axes():
    """The video's plane: X across and Z from the wall for a y-tal file; a map's hot cell,
    flipped and placed by the view, sits where its file coordinates say."""
    grid = nl.Grid.from_ranges(x=(1.0, 2.0), y=(0.5, 3.0), z=(0.2, 0.2), step_m=0.1)
    view = TopView(YTAL)
    assert view.labels[0].startswith("X") and view.labels[1].startswith("Z")
    (x, y, _) = grid.axes()
    i, j = 3, 17  # the hot cell (ours x index, y index)
    shown = np.zeros((len(y), len(x)))
    shown[j, i] = 1.0
    image = view.image(shown)
    row, col = np.unravel_index(np.argmax(image), image.shape)
    left, right, bottom, top = view.extent(grid)
    u = left + (col + 0.5) * (right - left) / image.shape[1]
    v = bottom + (row + 0.5) * (top - bottom) / image.shape[0]  # origin="lower"
    cell = YTAL.from_internal([x[i], y[j], 0.2])
    np.testing.assert_allclose([u, v], [cell[0], cell[2]], atol=1e-9)
    np.testing.assert_allclose(view.points([x[i], y[j], 0.2])[0], [cell[0], cell[2]])
