"""The catalogue of bad inputs: each row is what a user might do and what they must get (an
error naming the field and saying how to fix it). tests/apps/test_bad_input.py runs every row;
`python tests/apps/error_catalogue.py docs/results/errors/errors.md` writes the catalogue with the exact
messages.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import trimesh

import nlos_cl as nl
from nlos_cl.io.ytal.reading import read_sequence
from nlos_cl.io.scenefile import load_scene
import nlos_cl.io.ytal.capture  # noqa: F401  (nl.capture)
from nlos_cl.core import limits  # noqa: F401
from nlos_cl.io import calibration, safe_write
from nlos_cl.io.ytal import fields, frames
from nlos_cl.localization import region
import nlos_cl.io.ytal.frames  # noqa: F401
import nlos_cl.io.calibration  # noqa: F401
from nlos_cl.device import devices
from nlos_cl.core.errors import DeviceError, InputError

C = nl.SPEED_OF_LIGHT
SPOTS = nl.paper_setup().detector_spots


def histograms(data=None, **kw):
    data = np.ones((3, 100)) if data is None else data
    args = dict(time_axis=nl.TimeAxis(1e-7, 1e-11, data.shape[-1] if data.ndim else 1),
                detector_spots=SPOTS, laser_spot=[0, 0, 0],
                calibration=nl.PathCalibration(C, [-40.0]))
    args.update(kw)
    return nl.HistogramSet(data, **args)


def with_bin(value):
    data = np.ones((3, 100))
    data[1, 7] = value
    return data


def no_device():
    original = devices.list_devices
    devices.list_devices = lambda: []
    try:
        devices.choose_device()
    finally:
        devices.list_devices = original


def write_file(name, text):
    import tempfile
    path = Path(tempfile.mkdtemp()) / name
    path.write_text(text)
    return path


def capture_file(edit=None):
    """A valid y-tal capture, then `edit` applied to its HDF5 fields."""
    import tempfile

    import h5py
    path = Path(tempfile.mkdtemp()) / "capture.h5"
    nl.write_capture(path, histograms(np.ones((3, 100))))
    if edit:
        with h5py.File(path, "a") as f:
            edit(f)
    return path


def truncated_capture():
    path = capture_file()
    path.write_bytes(path.read_bytes()[:1500])
    return path


def ccsocr_folder():
    """A tiny CC-SOCR pattern folder (sub_Sig.mat, C_i.mat, C_d.mat)."""
    import tempfile

    import scipy.io
    out = Path(tempfile.mkdtemp())
    for name, value in (("sub_Sig", np.ones((3, 50))), ("C_i", [[0, 1, 1], [0, 2, 1], [0, 3, 1]]),
                        ("C_d", [[0, 9, 9]] * 3)):
        scipy.io.savemat(out / f"{name}.mat", {name: np.asarray(value, np.uint16)})
    return str(out)


def replace_field(name, value):
    def edit(f):
        del f[name]
        f[name] = value
    return edit


def existing_file(name, content=b"my notes\n"):
    import tempfile
    path = Path(tempfile.mkdtemp()) / name
    path.write_bytes(content)
    return path


def folder(name):
    import tempfile
    path = Path(tempfile.mkdtemp()) / name
    path.mkdir()
    return path


def concurrent_writers():
    """Another writer finishes the same capture while this one is still writing."""
    path = capture_file()

    def slow(tmp):
        nl.write_capture(path, histograms(2 * np.ones((3, 100))))
        Path(tmp).write_bytes(b"")
    safe_write.atomic_write(path, slow, what="capture", keep_unless=fields.is_capture)


def huge_declared_capture():
    """A few-KB file whose H declares 10^9 x 3 float32 values (chunks never written)."""
    import h5py
    path = capture_file(lambda f: f.__delitem__("H"))
    with h5py.File(path, "a") as f:
        f.create_dataset("H", shape=(10 ** 9, 3), dtype=np.float32, chunks=(1024, 3))
    return path


def ytal_points(points):
    return nl.capture.to_ytal(np.asarray(points, float)).astype(np.float32)


def one_detector():
    return histograms(np.ones((1, 2000)), detector_spots=SPOTS[:1])


def small_scene():
    return nl.paper_scene(facet_size_m=0.05)


def symlink_to(target):
    """A link `out.h5` beside a fresh folder's file, pointing at `target`."""
    import tempfile
    link = Path(tempfile.mkdtemp()) / "link.h5"
    link.symlink_to(target)
    return link


def fifo(name="F.h5"):
    import os
    import tempfile
    path = Path(tempfile.mkdtemp()) / name
    os.mkfifo(path)
    return path


def external_h_capture():
    """A capture whose H is HDF5 external raw storage reading /etc/passwd."""
    import h5py

    def edit(f):
        shape = f["H"].shape
        del f["H"]
        f.create_dataset("H", shape=shape, dtype="u1",
                         external=[("/etc/passwd", 0, h5py.h5f.UNLIMITED)])
    return capture_file(edit)


def external_h_sequence():
    """A sequence file (frame axis) whose H is external raw storage reading /etc/passwd."""
    import h5py
    path = capture_file()
    with h5py.File(path, "a") as f:
        shape = (2,) + f["H"].shape
        del f["H"]
        f.create_dataset("H", shape=shape, dtype="u1",
                         external=[("/etc/passwd", 0, h5py.h5f.UNLIMITED)])
        f["frame_t_s"] = np.array([0.0, 0.1])
    return path


def virtual_h_capture():
    import h5py
    source = capture_file()

    def edit(f):
        shape, dtype = f["H"].shape, f["H"].dtype
        del f["H"]
        layout = h5py.VirtualLayout(shape=shape, dtype=dtype)
        layout[:] = h5py.VirtualSource(str(source), "H", shape=shape)
        f.create_virtual_dataset("H", layout)
    return capture_file(edit)


def linked_h_capture():
    import h5py
    source = capture_file()
    return capture_file(lambda f: (f.__delitem__("H"),
                                   f.__setitem__("H", h5py.ExternalLink(str(source), "H"))))


def runner_study(runner, axes=({"name": "command", "values": ["echo owned"]},)):
    from nlos_cl.sweep import load_study
    return load_study({"runner": runner, "axes": list(axes)})


def study_file():
    return write_file("study.yaml", "runner: \"os:system\"\naxes:\n"
                      "  - {name: command, values: [\"echo owned\"]}\n")


def alias_bomb(levels=9, width=9):
    lines = [f"a0: &a0 [{', '.join(['x'] * width)}]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * width)}]" for i in range(1, levels)]
    return "\n".join(lines) + f"\ndescription: *a{levels - 1}\ntargets: [{{shape: sphere}}]\n"


def load_study_dict(axis):
    from nlos_cl.sweep import load_study
    return load_study({"scene": {"targets": [{"shape": "sphere"}]}, "axes": [axis]})


def ms_sequence(times=(0.0, 100.0, 200.0), truths=3):
    """A 3-frame sequence, its frame_t_s and frame_truths then replaced."""
    import tempfile

    import h5py
    from nlos_cl.tracking import write_sequence
    path = write_sequence(Path(tempfile.mkdtemp()) / "seq.h5",
                          [(k * 0.1, histograms(), [[4.0, 2.0, 0.0]]) for k in range(3)])
    with h5py.File(path, "a") as f:
        replace_field("frame_t_s", np.asarray(times))(f)
        replace_field("frame_truths", np.zeros((truths, 1, 3)))(f)
    return path


class CommandLineError(Exception):
    """What `nlos-cl` printed on stderr when it exited with status 2."""


def cli(*args):
    """Run `nlos-cl ARGS` in this process: a bad input must exit 2 with one line on stderr."""
    import contextlib
    import io

    from nlos_cl.apps.cli import main
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            status = main([str(a) for a in args])
        except SystemExit as exc:  # argparse
            status = exc.code
    text = err.getvalue().strip()
    if status == 2 and len(text.splitlines()) == 1:
        raise CommandLineError(text)
    raise AssertionError(f"nlos-cl {' '.join(map(str, args))}: status {status}, stderr {text!r}")


# (what the user did, the field the message must name, the call)
CASES = [
    ("a histogram bin is NaN", "histograms.data", lambda: histograms(with_bin(np.nan))),
    ("a histogram bin is inf", "histograms.data", lambda: histograms(with_bin(np.inf))),
    ("negative photon counts where counts are declared", "histograms.data",
     lambda: histograms(-np.ones((3, 100)), allow_negative=False)),
    ("histograms given as a 1-D array", "histograms.data",
     lambda: nl.HistogramSet(np.ones(100), nl.TimeAxis(0, 1e-11, 100), SPOTS, [0, 0, 0],
                             nl.PathCalibration(C, [0.0]))),
    ("histogram length differs from the time axis", "histograms.data",
     lambda: histograms(np.ones((3, 90)), time_axis=nl.TimeAxis(0, 1e-11, 100))),
    ("2 histograms for 3 detector spots", "histograms.detector_spots",
     lambda: histograms(np.ones((2, 100)))),
    ("4 calibration offsets for 3 detectors", "calibration.b_m",
     lambda: histograms(calibration=nl.PathCalibration(C, [0.0, 1.0, 2.0, 3.0]))),
    ("calibration slope of zero", "calibration.a_m_per_s", lambda: nl.PathCalibration(0.0, [0.0])),
    ("a NaN start time", "time_axis.t0_s", lambda: nl.TimeAxis(float("nan"), 1e-12, 10)),
    ("a negative bin width", "time_axis.dt_s", lambda: nl.TimeAxis(0.0, -1e-12, 10)),
    ("an infinite bin width", "time_axis.dt_s", lambda: nl.TimeAxis(0.0, float("inf"), 10)),
    ("a negative number of bins", "time_axis.n_bins", lambda: nl.TimeAxis(0.0, 1e-12, -5)),
    ("an empty mesh", "target.mesh", lambda: nl.Target(trimesh.Trimesh())),
    ("a mesh whose faces all have zero area", "target.mesh",
     lambda: nl.Target(trimesh.Trimesh([[4, 1, 0], [4, 2, 0], [4, 3, 0]], [[0, 1, 2]],
                                       process=False))),
    ("a mesh with NaN vertices", "target.mesh",
     lambda: nl.Target(trimesh.Trimesh([[4, 1, 0], [4, 2, np.nan], [4, 3, 1]], [[0, 1, 2]],
                                       process=False))),
    ("something that is not a mesh", "target.mesh", lambda: nl.Target("person.obj")),
    ("a target behind the wall", "target.mesh", lambda: nl.Target(nl.box(centre=(1.0, -2.0, 0.0)))),
    ("a target that cuts through the wall", "target.mesh",
     lambda: nl.Target(nl.rectangle(centre=(4.0, 0.1, 0.0)))),
    ("a target turned away from the wall", "scene.target",
     lambda: nl.simulate(nl.Scene(nl.paper_setup(), nl.Target(nl.rectangle(normal=(1, 0, 0))),
                                  0.05), backend="reference")),
    ("a facet size of zero", "facet_size_m", lambda: nl.Target(nl.rectangle()).facets(0.0)),
    ("two detectors on the same spot", "setup.detector_spots",
     lambda: nl.Setup(detector_spots=[[-1, 0, 0], [-1, 0, 0]])),
    ("a detector on the laser spot", "setup.detector_spots",
     lambda: nl.Setup(detector_spots=[[0, 0, 0], [-1, 0, 0]])),
    ("a detector spot off the wall plane", "setup.detector_spots",
     lambda: nl.Setup(detector_spots=[[-1, 0.5, 0]])),
    ("a NaN laser spot", "setup.laser_spot", lambda: nl.Setup(laser_spot=[0, 0, float("nan")])),
    ("a negative device distance", "setup.device_distance_m",
     lambda: nl.Setup(device_distance_m=-20.0)),
    ("a pulse of zero width", "pulse.fwhm_s", lambda: nl.Pulse(fwhm_s=0.0)),
    ("a filter window h of zero", "h_s", lambda: nl.gauss_filter(histograms(), 0.0,
                                                                   backend="reference")),
    ("a negative filter window h", "h_s", lambda: nl.gauss_filter(histograms(), -1e-9,
                                                                    backend="reference")),
    ("a filter window narrower than one bin", "h_s",
     lambda: nl.gauss_filter(histograms(), 1e-13, backend="reference")),
    ("a filter window longer than the record", "h_s",
     lambda: nl.gauss_filter(histograms(), 1e-3, backend="reference")),
    ("a time window that ends before the signal arrives", "time_axis",
     lambda: nl.simulate(small_scene(), nl.TimeAxis(2 * 20 / C, 10e-12, 100),
                         backend="reference")),
    ("a grid with no cells", "grid.shape", lambda: nl.Grid((0, 0.01, 0), (0.01,) * 3, (0, 10, 1))),
    ("an inverted grid range", "grid.x", lambda: nl.Grid.from_ranges(x=(6.0, 0.0))),
    ("a grid step of zero", "grid.step", lambda: nl.Grid((0, 0.01, 0), (0.01, 0.0, 0.01), (5, 5, 1))),
    ("a grid behind the wall", "grid.origin", lambda: nl.Grid((0, -1.0, 0), (0.01,) * 3, (5, 5, 1))),
    ("a grid the signal never reaches", "grid",
     lambda: nl.locate(nl.gauss_filter(nl.simulate(small_scene(), backend="reference")),
                       nl.Grid.from_ranges(x=(40, 41), y=(40, 41), step_m=0.1),
                       estimator="paper")),
    ("a 10^10-cell grid scored as one map", "grid: has 1.08e+10 cells",
     lambda: nl.locate(nl.gauss_filter(nl.simulate(small_scene(), backend="reference")),
                       nl.Grid((0, 0.001, 0), (1e-4,) * 3, (60000, 60000, 3)),
                       search="exhaustive", backend="reference", estimator="paper")),
    ("a noise level of NaN dB", "snr_db",
     lambda: nl.add_noise(histograms(), float("nan"), backend="reference")),
    ("a negative noise seed", "seed", lambda: nl.add_noise(histograms(), 10.0, -1,
                                                            backend="reference")),
    ("a corrupt mesh file", "mesh file",
     lambda: nl.load_mesh(write_file("broken.stl", "solid x\nnot an stl at all\n"))),
    ("a mesh file that does not exist", "mesh file", lambda: nl.load_mesh("/nonexistent/person.obj")),
    ("an ASCII STL cut after its first facet", "an ASCII STL without its closing `endsolid`",
     lambda: nl.load_mesh(write_file("cut.stl", "solid x\nfacet normal 0 0 1\nouter loop\n"
                                     "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
                                     "endfacet\n"))),
    ("an OBJ cut inside its last line", "does not end with a line break",
     lambda: nl.load_mesh(write_file("cut.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2"))),
    ("a calibration CSV whose first row is a mistyped measurement", "is not a number, yet the row",
     lambda: calibration.read_calibration_pairs(write_file("p.csv", "2.5,5.17e-8x\n3,1e-8\n"))),
    ("a capture file missing a y-tal field", "missing field(s) ['t_start']",
     lambda: nl.read_capture(capture_file(lambda f: f.__delitem__("t_start")))),
    ("a capture whose delta_t is in seconds, not metres", "delta_t",
     lambda: nl.read_capture(capture_file(replace_field("delta_t", np.float32(1e-11))))),
    ("a capture whose H has the wrong shape", "H: has shape",
     lambda: nl.read_capture(capture_file(replace_field("H", np.zeros((100, 5), np.float32))))),
    ("a capture with a NaN in H", "H: 1 values are NaN",
     lambda: nl.read_capture(capture_file(lambda f: f["H"].__setitem__((3, 1), np.nan)))),
    ("a truncated capture file", "incomplete or corrupted file",
     lambda: nl.read_capture(truncated_capture())),
    ("a capture cut off by one byte (every field still listed)", "incomplete or corrupted file",
     lambda: nl.read_capture(existing_file("cut.h5", capture_file().read_bytes()[:-1]))),
    ("a capture path that is not an HDF5 file", "not an HDF5 file",
     lambda: nl.read_capture(existing_file("notes.h5", b"just some text, long enough"))),
    ("a capture declaring H far larger than memory", "H: declares 3.433e+04 MiB of data",
     lambda: nl.read_capture(huge_declared_capture(), max_bytes=2 ** 30)),
    ("a capture whose laser point is a sensor point", "sensor_grid_xyz: a detector spot "
     "coincides with the laser spot", lambda: nl.read_capture(capture_file(replace_field(
         "laser_grid_xyz", ytal_points(SPOTS[1:2]))))),
    ("a capture with two sensors on the same spot", "sensor_grid_xyz: points 1 and 2 are the "
     "same spot", lambda: nl.read_capture(capture_file(replace_field(
         "sensor_grid_xyz", ytal_points([SPOTS[0], SPOTS[1], SPOTS[1]]))))),
    ("a capture with a sensor 0.3 m off the wall", "sensor_grid_xyz: point 1",
     lambda: nl.read_capture(capture_file(replace_field(
         "sensor_grid_xyz", ytal_points(SPOTS + [[0, 0, 0], [0, 0.3, 0], [0, 0, 0]]))))),
    ("writing a capture over a file that is not a capture", "exists and is not an HDF5 capture",
     lambda: nl.write_capture(existing_file("thesis.h5"), histograms())),
    ("writing a capture into a folder that does not exist", "does not exist",
     lambda: nl.write_capture("/nonexistent-folder/c.h5", histograms())),
    ("writing a capture onto a folder path", "is a folder",
     lambda: nl.write_capture(folder("captures"), histograms())),
    ("two writers finishing the same capture at once", "by another writer while this one",
     concurrent_writers),
    ("a default search region for a single detector", "histograms.detector_spots",
     lambda: region.default_region(one_detector())),
    ("a default search region for a window that sees no hidden point", "time_axis",
     lambda: region.default_region(histograms(np.ones((3, 100))))),
    ("a grid in a capture's frame that reaches behind the wall", "grid.Z",
     lambda: frames.YTAL.grid([(-1, 1), (0, 0), (-1, 3)], step_m=0.1)),
    ("a capture with 2 laser points for 3 sensor points (neither one nor one each)",
     "laser_grid_xyz: has 2 points",
     lambda: nl.read_capture(capture_file(replace_field("laser_grid_xyz", np.float32(
         [[0, 0, 0], [0.5, 0, 0]]))))),
    ("a Fourier-domain y-tal capture (complex H)", "H: has dtype complex64: a Fourier-domain",
     lambda: nl.read_capture(capture_file(replace_field("H", np.ones((100, 3), np.complex64))))),
    ("nlos-cl convert of a folder that is no known dataset", "is a folder without sub_Sig.mat",
     lambda: cli("convert", folder("downloads"), "--out", "x.h5")),
    ("nlos-cl convert --width for a CC-SOCR folder", "--width: is not an option",
     lambda: cli("convert", ccsocr_folder(), "--out", "x.h5", "--width", 1)),
    ("too few calibration pairs", "calibration pairs",
     lambda: nl.fit_calibration([1.0, 2.0], [1e-9, 2e-9])),
    ("calibration peak times in nanoseconds", "peak times in nanoseconds",
     lambda: nl.fit_calibration([2.5, 3.0, 3.5], [51.7, 53.4, 55.0])),
    ("a calibration CSV with one column", "has 1 column(s)",
     lambda: calibration.read_calibration_pairs(write_file("pairs.csv", "2.5\n3.0\n3.5\n"))),
    ("a calibration CSV with no rows", "has no rows",
     lambda: calibration.read_calibration_pairs(write_file("pairs.csv", ""))),
    ("a calibration CSV with only a header", "has a header but no data rows",
     lambda: calibration.read_calibration_pairs(write_file("pairs.csv", "path;time\n"))),
    ("a calibration CSV with a text cell below the header", "line 3",
     lambda: calibration.read_calibration_pairs(write_file("pairs.csv",
                                                           "path,time\n2.5,5e-8\n3.0,n/a\n"))),
    ("a calibration file that is binary", "is not a text file",
     lambda: calibration.read_calibration_pairs(existing_file("pairs.csv", b"\x89PNG\x00\x01"))),
    ("a background recorded on another time axis", "background",
     lambda: nl.subtract_background(histograms(), histograms(np.ones((3, 80))))),
    ("a background shifted by one bin", "background.time_axis",
     lambda: nl.subtract_background(histograms(), histograms(
         time_axis=nl.TimeAxis(1e-7 + 1e-11, 1e-11, 100)))),
    ("a background subtracted from itself", "background: is the signal itself",
     lambda: nl.subtract_background(histograms(), histograms())),
    ("a background stronger than the signal in every bin", "at least as strong as the signal",
     lambda: nl.subtract_background(histograms(), histograms(2 * np.ones((3, 100))))),
    ("a TDC bin that is not a multiple of the data's bins", "photon_counter.tdc_bin_s",
     lambda: nl.PhotonCounter(tdc_bin_s=15e-12).expected_counts(histograms())),
    ("nlos-cl demo --step 0", "grid.step", lambda: cli("demo", "--step", 0, "--png", "")),
    ("nlos-cl demo --h-ns nan", "h_s", lambda: cli("demo", "--h-ns", "nan", "--png", "")),
    ("nlos-cl demo --png onto a folder", "--png", lambda: cli("demo", "--png", folder("figs"))),
    ("nlos-cl simulate --facet 0", "facet_size_m",
     lambda: cli("simulate", "--out", "x.h5", "--facet", 0)),
    ("nlos-cl simulate --facet 1e-5 (71.5 GiB of facets)", "facet_size_m",
     lambda: cli("simulate", "--out", folder("o") / "x.h5", "--facet", 1e-5)),
    ("nlos-cl simulate --dt-ps nan", "time_axis.dt_s",
     lambda: cli("simulate", "--out", "x.h5", "--dt-ps", "nan")),
    ("nlos-cl simulate --dt-ps 0.00001 (60 G bins)", "time_axis",
     lambda: cli("simulate", "--out", folder("o") / "x.h5", "--dt-ps", 1e-5)),
    ("nlos-cl simulate --out over a file that is not a capture", "--force",
     lambda: cli("simulate", "--out", existing_file("thesis.h5"), "--facet", 0.05)),
    ("nlos-cl reproduce fig10 --seeds -1", "seeds", lambda: cli("reproduce", "fig10", "--seeds",
                                                               -1)),
    ("nlos-cl locate --region with a NaN", "region",
     lambda: cli("locate", capture_file(), "--region", 0, 1, "nan", 1, 1, 2)),
    ("nlos-cl locate --step 0", "grid.step", lambda: cli("locate", capture_file(), "--step", 0)),
    ("nlos-cl locate --region of 2.5e14 cells", "--region",
     lambda: cli("locate", capture_file(), "--region", -50, 50, 0, 50, 0.01, 50, "--step",
                 0.001)),
    ("nlos-cl locate --map over a file that is not a map", "--map",
     lambda: cli("locate", capture_file(), "--map", existing_file("notes.txt"))),
    ("nlos-cl calibrate on a CSV with ';' and one column", "calibration file",
     lambda: cli("calibrate", write_file("pairs.csv", "path\n2.5\n3.0\n"))),
    ("a study whose runner is os:system", "runner 'os:system': cannot import 'os' from a "
     "study file", lambda: runner_study("os:system")),
    ("a study whose runner is subprocess:getoutput", "runner 'subprocess:getoutput'",
     lambda: runner_study("subprocess:getoutput")),
    ("a study whose runner is shutil:rmtree", "runner 'shutil:rmtree'",
     lambda: runner_study("shutil:rmtree", [{"name": "path", "values": ["/tmp/x"]}])),
    ("a runner reached through an nlos_cl module's import (os.system)", "runner "
     "'nlos_cl.sweep.engine:os.system': is posix's system", lambda: runner_study(
         "nlos_cl.sweep.engine:os.system")),
    ("nlos-cl sweep of a study file whose runner is os:system", "--allow-runner os",
     lambda: cli("sweep", study_file(), "--out", folder("o") / "s", "--workers", 0)),
    ("nlos-cl sweep --out into a folder holding the user's summary.csv", "--out",
     lambda: cli("sweep", write_file("s.yaml", "runner: nlos_cl.sweep.examples:paper_target\n"
                                     "axes: [{name: x, values: [3.0]}]\nseeds: 1\n"),
                 "--out", existing_file("summary.csv").parent, "--workers", 0)),
    ("a capture whose H is external raw storage (/etc/passwd)", "H: uses external raw storage",
     lambda: nl.read_capture(external_h_capture())),
    ("a sequence whose H is external raw storage (/etc/passwd)", "H: uses external raw storage",
     lambda: read_sequence(external_h_sequence())),
    ("a capture whose H is a virtual dataset", "H: uses a virtual dataset",
     lambda: nl.read_capture(virtual_h_capture())),
    ("a capture whose H is an external link", "H: is an external link",
     lambda: nl.read_capture(linked_h_capture())),
    ("a capture path that is a FIFO", "is a FIFO (named pipe), not a regular file",
     lambda: nl.read_capture(fifo())),
    ("a capture path that is a folder", "is a folder, not a regular file",
     lambda: nl.read_capture(folder("F.h5"))),
    ("writing a capture through a symbolic link", "is a symbolic link",
     lambda: nl.write_capture(symlink_to(capture_file()), histograms())),
    ("nlos-cl simulate --out link.h5 (a link to the user's file)", "is a symbolic link",
     lambda: cli("simulate", "--out", symlink_to(existing_file("thesis.h5")), "--facet", 0.05)),
    ("nlos-cl simulate --out /dev/null --force", "is a character device",
     lambda: cli("simulate", "--out", "/dev/null", "--force", "--facet", 0.05)),
    ("nlos-cl simulate --out onto a FIFO --force", "is a FIFO",
     lambda: cli("simulate", "--out", fifo(), "--force", "--facet", 0.05)),
    ("nlos-cl demo --png over the user's thesis.pdf", "--png",
     lambda: cli("demo", "--png", existing_file("thesis.pdf"))),
    ("nlos-cl locate --map over the user's own .npz", "--map",
     lambda: cli("locate", capture_file(), "--map", existing_file("mine.npz"))),
    ("nlos-cl reproduce fig5 --doc over the user's notes.md", "--doc",
     lambda: cli("reproduce", "fig5", "--quick", "--doc", existing_file("notes.md"))),
    ("nlos-cl reproduce --out over the user's fig5.csv", "--out",
     lambda: cli("reproduce", "fig5", "--quick", "--out", existing_file("fig5.csv").parent)),
    ("nlos-cl bench --out over the user's performance.md", "--out",
     lambda: cli("bench", "--smoke", "--out", existing_file("performance.md").parent)),
    ("a scene file with an alias bomb (9 levels x 9)", "aliases expand to more than",
     lambda: load_scene(write_file("bomb.yaml", alias_bomb()))),
    ("a scene file with `targets:` twice", "the key 'targets' appears twice",
     lambda: load_scene(write_file("twice.yaml", "targets: [{shape: sphere}]\n"
                                      "targets: [{shape: box}]\n"))),
    ("a scene file saved as UTF-16", "is UTF-16 text",
     lambda: load_scene(existing_file("u16.yaml", "targets: [{shape: sphere}]\n"
                                         .encode("utf-16")))),
    ("a scene file with device_distance_m: 1e39", "setup.device_distance_m",
     lambda: load_scene({"setup": {"device_distance_m": 1e39},
                            "targets": [{"shape": "sphere"}]})),
    ("a scene file with spad_patch counts [2.7, 2.7]", "spad_patch.counts[0]",
     lambda: load_scene({"setup": {"detector_spots": {"spad_patch": {
         "centre": [-1, 0, 0], "counts": [2.7, 2.7]}}}, "targets": [{"shape": "sphere"}]})),
    ("a scene file with a position in millimetres", "looks like millimetres",
     lambda: load_scene({"targets": [{"shape": "sphere", "position": [4000, 2000, 0]}]})),
    ("a study whose range stops at .inf", "axes[0].range.stop",
     lambda: load_study_dict({"path": "noise.snr_db", "range": {"start": 0, "stop": np.inf,
                                                                 "step": 1}})),
    ("a study axis named like a result column (error_m)", "reserved",
     lambda: load_study_dict({"path": "noise.snr_db", "name": "error_m", "values": [0]})),
    ("a capture whose boolean is the text 'maybe'", "t_accounts_first_and_last_bounces",
     lambda: nl.read_capture(capture_file(replace_field("t_accounts_first_and_last_bounces",
                                                        "maybe")))),
    ("a capture whose sensor grid is in millimetres", "sensor_grid_xyz: its points span",
     lambda: nl.read_capture(capture_file(lambda f: f["sensor_grid_xyz"].__setitem__(
         slice(None), f["sensor_grid_xyz"][()] * 1000)))),
    ("a MATLAB v7.3 .mat passed as a capture", "is a MATLAB .mat file",
     lambda: nl.read_capture(existing_file("scan.mat", b"MATLAB 7.3 MAT-file".ljust(512)
                                           + capture_file().read_bytes()))),
    ("a sequence whose frame_t_s are milliseconds", "looks like milliseconds",
     lambda: read_sequence(ms_sequence())),
    ("a sequence whose frame_truths miss a frame", "frame_truths",
     lambda: read_sequence(ms_sequence(times=(0.0, 0.1, 0.2), truths=2))),
    ("no OpenCL device on the machine", "No OpenCL device found", no_device),
    ("a device choice that matches no device", "matches no OpenCL device",
     lambda: devices.choose_device("no-such-device-xyz")),
]


def message(call) -> tuple[str, str]:
    try:
        call()
    except (InputError, DeviceError, CommandLineError) as exc:
        return type(exc).__name__, str(exc)
    return "", "(no error)"


def write_doc(path: Path) -> None:
    lines = ["# Bad input: what you get", "",
             "Generated by `python tests/apps/error_catalogue.py docs/results/errors/errors.md` from "
             "the cases that "
             "tests/apps/test_bad_input.py runs (do not edit by hand). Every error names the field "
             "and says how to fix it; `InputError` is a `ValueError`, `DeviceError` a "
             "`RuntimeError`. Nothing you pass is modified: arrays and meshes are copied and "
             "stored read-only.", "",
             "Not applicable today: *a device without float64 when asked for it* (no kernel "
             "uses float64; the host applies float64 scale factors) and *a file that would need "
             "pickle* (meshes are read by trimesh and captures by h5py; neither ever unpickles, "
             "and reading never modifies a file: captures are opened read-only).", "",
             "| # | what you did | error | message |", "|---|---|---|---|"]
    for i, (what, _, call) in enumerate(CASES, 1):
        kind, text = message(call)
        text = re.sub(r"/tmp/[^/ ]+/", "/tmp/.../", text)  # temporary folders differ per run
        lines.append(f"| {i} | {what} | {kind} | {text.replace('|', '/')} |")
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    write_doc(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/results/errors/errors.md"))
