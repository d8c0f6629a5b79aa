"""Readers for datasets as downloaded (nlos_cl.io.datasets) and `nlos-cl convert`: tiny
synthetic files written here in each format (no real data is committed), then the real files
in ../shared/realdata where present (skipped otherwise)."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli

C = nl.SPEED_OF_LIGHT
REAL = Path(__file__).resolve().parents[3] / "shared" / "realdata"
HIDDEN = np.array([0.3, 0.9, 0.4])  # internal frame: 0.9 m in front of the wall


def ccsocr_folder(tmp_path, n=12, n_t=600, c_d=(0, 20, 15), depth=0):
    """A CC-SOCR pattern folder: one hidden point, each histogram's photon at the README's bin
    (|v - laser_i| + |v - detection point|) / (c * 16 ps)."""
    folder = tmp_path / "pattern"
    folder.mkdir()
    rng = np.random.default_rng(1)
    c_i = np.column_stack([np.full(n, depth), rng.permutation(40)[:n], rng.permutation(40)[:n]])
    c_d = np.tile(c_d, (n, 1))
    to_m = lambda idx: np.column_stack([-idx[:, 1], 0 * idx[:, 0], idx[:, 2]]) * 0.01  # noqa: E731
    path = (np.linalg.norm(HIDDEN - to_m(c_i), axis=1) + np.linalg.norm(HIDDEN - to_m(c_d), axis=1))
    sig = np.zeros((n, n_t), np.uint16)
    sig[np.arange(n), (path / (C * 16e-12)).astype(int)] = 100
    for name, value in (("sub_Sig", sig), ("C_i", c_i.astype(np.uint8)),
                        ("C_d", c_d.astype(np.uint8))):
        scipy.io.savemat(folder / f"{name}.mat", {name: value})
    return folder, sig, path


def lct_file(tmp_path, shape=(4, 3, 50), width=0.3, name="scan.mat"):
    cube = np.random.default_rng(2).integers(0, 9, size=shape).astype(np.uint16)
    scipy.io.savemat(tmp_path / name, {"rect_data": cube, "width": np.array([[width]])})
    return tmp_path / name, cube


def test_ccsocr_is_n_lasers_and_one_detector(tmp_path):
    folder, sig, path = ccsocr_folder(tmp_path)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    h = nl.read_dataset(folder)  # detected: a folder with sub_Sig.mat
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert h.paired and h.n_detectors == 12 and np.array_equal(h.data, sig)
    assert np.allclose(h.detector_spots, [-0.20, 0.0, 0.15])  # C_d (0, 20, 15) -> (-a, 0, b)
    assert np.all(h.laser_spots[:, 1] == 0) and len(np.unique(h.laser_spots, axis=0)) == 12
    assert h.time_axis.dt_s == pytest.approx(16e-12) and h.time_axis.t0_s == 0
    # each photon's bin holds the hidden path of the README's rule
    peak = h.hidden_path_axis()[np.arange(12), sig.argmax(axis=1)]
    assert np.all(np.abs(peak - path) <= 0.5 * C * 16e-12 + 1e-12)


def test_ccsocr_options_override_constants(tmp_path):
    folder, _, _ = ccsocr_folder(tmp_path)
    h = nl.read_dataset(folder, "ccsocr", dt_ps=8.0, t0_ps=-100.0, grid_m=0.02)
    assert h.time_axis.dt_s == pytest.approx(8e-12) and h.time_axis.t0_s == pytest.approx(-1e-10)
    assert np.allclose(h.detector_spots[0], [-0.40, 0.0, 0.30])


@pytest.mark.parametrize("edit, message", [
    (lambda f: scipy.io.savemat(f / "C_i.mat", {"C_i": np.ones((12, 3), np.uint8)}),
     "C_i: has points off the relay wall"),
    (lambda f: scipy.io.savemat(f / "C_d.mat", {"C_d": np.zeros((5, 3), np.uint8)}),
     "C_d: has 5 rows but sub_Sig has 12"),
    (lambda f: (f / "C_d.mat").unlink(), "C_d.mat: does not exist"),
    (lambda f: scipy.io.savemat(f / "C_i.mat", {"other": np.zeros((12, 3))}), "C_i: is missing"),
])
def test_bad_ccsocr_folders_name_the_file(tmp_path, edit, message):
    folder, _, _ = ccsocr_folder(tmp_path)
    edit(folder)
    with pytest.raises(nl.InputError, match=message + ".*Fix:"):
        nl.read_dataset(folder)


def test_lct_is_confocal_on_the_documented_grid(tmp_path):
    path, cube = lct_file(tmp_path)
    h = nl.read_dataset(path)  # detected: a .mat with rect_data
    assert h.paired and np.array_equal(h.laser_spots, h.detector_spots)
    assert np.array_equal(h.data, cube.reshape(12, 50))
    assert np.allclose(h.detector_spots[[0, 1, 3]], [[-0.3, 0, -0.3], [-0.3, 0, 0.0],
                                                     [-0.1, 0, -0.3]])  # x along axis 0
    assert h.time_axis.dt_s == pytest.approx(4e-12)
    t = nl.read_dataset(path, transpose=True, flip="x", gate_bins=5, width_m=0.6)
    assert np.array_equal(t.data[:, 5:], cube.transpose(1, 0, 2).reshape(12, 50)[:, 5:])
    assert not t.data[:, :5].any()
    assert np.allclose(t.detector_spots[0], [0.6, 0, -0.6])  # flipped x, transposed grid
    assert np.array_equal(scipy.io.loadmat(path)["rect_data"], cube)  # the file is untouched


@pytest.mark.parametrize("call, message", [
    (lambda p: nl.read_dataset(p.parent), "sub_Sig.mat"),
    (lambda p: nl.read_dataset(p, "lct", flip="y"), "flip: must be"),
    (lambda p: nl.read_dataset(p, "lct", gate_bins=50), "gate_bins: must be"),
    (lambda p: nl.read_dataset(p, "lct", grid_m=0.1), "lct options: \\['grid_m'\\]"),
    (lambda p: nl.read_dataset(p, "zaragoza"), "format: .zaragoza. is not one of"),
    (lambda p: nl.read_dataset(p.with_name("none.mat")), "does not exist"),
])
def test_bad_dataset_calls_name_the_field(tmp_path, call, message):
    path, _ = lct_file(tmp_path / "x" if (tmp_path / "x").mkdir() is None else tmp_path)
    with pytest.raises(nl.InputError, match=message + ".*Fix:"):
        call(path)


def test_mat_without_rect_data_is_not_guessed(tmp_path):
    scipy.io.savemat(tmp_path / "a.mat", {"data": np.zeros((2, 2, 4))})
    with pytest.raises(nl.InputError, match="holds no variable rect_data or meas.*--format"):
        nl.read_dataset(tmp_path / "a.mat")
    # `meas` alone is f-k's layout, which needs its tof.mat
    scipy.io.savemat(tmp_path / "b.mat", {"meas": np.zeros((2, 2, 4))})
    with pytest.raises(nl.InputError, match="has no tof.mat"):
        nl.read_dataset(tmp_path / "b.mat")


def test_convert_writes_a_capture_that_reads_back(tmp_path, capsys):
    folder, _, _ = ccsocr_folder(tmp_path)
    out = tmp_path / "c.h5"
    assert cli(["convert", str(folder), "--out", str(out)]) == 0
    assert "12 histograms x 600 bins of 16 ps, paired" in capsys.readouterr().out
    (back,) = nl.read_capture(out)
    h = nl.read_dataset(folder)
    assert back.paired and np.array_equal(back.data, h.data)
    assert np.allclose(back.laser_spots, h.laser_spots, atol=1e-6)
    assert np.allclose(back.detector_spots, h.detector_spots, atol=1e-6)
    assert cli(["convert", str(folder), "--out", str(out), "--dt-ps", "8"]) == 0  # a capture
    notes = tmp_path / "notes.h5"
    notes.write_text("mine")
    assert cli(["convert", str(folder), "--out", str(notes)]) == 2
    assert notes.read_text() == "mine"
    assert cli(["convert", str(folder), "--out", str(notes), "--force"]) == 0
    assert nl.read_capture(notes)[0].n_detectors == 12


def test_convert_refuses_options_of_another_format(tmp_path, capsys):
    folder, _, _ = ccsocr_folder(tmp_path)
    assert cli(["convert", str(folder), "--out", str(tmp_path / "c.h5"), "--width", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--width: is not an option of the ccsocr format" in err and "\n" not in err
    assert not (tmp_path / "c.h5").exists()


def test_convert_lct_round_trip(tmp_path):
    path, cube = lct_file(tmp_path)
    out = tmp_path / "l.h5"
    assert cli(["convert", str(path), "--out", str(out), "--flip", "z"]) == 0
    (back,) = nl.read_capture(out)
    assert back.paired and np.allclose(back.laser_spots, back.detector_spots, atol=1e-7)
    # written as y-tal's grid, X (= -x) and Y (= z) increasing: --flip z reverses both axes
    assert np.array_equal(back.data, cube[::-1, ::-1].reshape(12, 50))


@pytest.mark.skipif(not (REAL / "ccsocr-figure4" / "sparse").is_dir(),
                    reason="../shared/realdata/ccsocr-figure4 is absent")
def test_real_ccsocr_sparse_locates_the_four(tmp_path):
    out = tmp_path / "sparse.h5"
    assert cli(["convert", str(REAL / "ccsocr-figure4" / "sparse"), "--out", str(out)]) == 0
    run = subprocess.run([sys.executable, "-m", "nlos_cl.apps.cli", "locate", str(out), "--json",
                          "--estimator", "paper"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    depth = json.loads(run.stdout)["position"][2]  # the file's Z: CC-SOCR's depth
    assert 0.85 <= depth <= 1.00, depth


@pytest.mark.skipif(not (REAL / "lct" / "data_s_u.mat").is_file(),
                    reason="../shared/realdata/lct is absent")
def test_real_lct_reads_as_confocal():
    h = nl.read_dataset(REAL / "lct" / "data_s_u.mat")
    assert h.paired and h.data.shape == (4096, 2048)
    assert np.allclose(np.abs(h.detector_spots).max(axis=0), [0.35, 0.0, 0.35])
