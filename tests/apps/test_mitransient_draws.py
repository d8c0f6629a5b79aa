"""scripts/mitransient_draws.py's own steps that need no renderer: the exported hidden-path axis
puts a point target's return in the bin nlos_cl's simulation puts it, and the pulse it convolves
renders with keeps their energy and their centre. (The renders themselves run in
.venv-mitransient: docs/results/rendered/draws-rendered.md.)"""
import importlib.util
import json
import math
from pathlib import Path

import numpy as np

import nlos_cl as nl

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "mitransient_draws.py"


def _script():
    spec = importlib.util.spec_from_file_location("mitransient_draws", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_pulse_keeps_energy_and_centre():
    m = _script()
    row = np.zeros((1, 401))
    row[0, 200] = 3.0
    out = m.pulse_convolved(row, 0.0003, 0.009)
    # the taps reach 6 sigma: 2.0e-9 of the energy lies beyond (5.9e-9 of these 3 units)
    assert abs(out.sum() - 3.0) < 7e-9
    assert int(np.argmax(out[0])) == 200
    assert np.allclose(out[0, 150:200], out[0, 250:200:-1])  # symmetric about the impulse


def test_the_exported_axis_is_nlos_cls_hidden_path(tmp_path):
    """Draw 0's axis: the hidden path |c - O| + |c - spot| of its target's centre, mapped to a
    bin by the exported start_opl and bin_opl, is where nlos_cl's simulation of a 2 cm plate at
    that centre, facing the wall, peaks (within the plate's own spread of paths)."""
    m = _script()
    m.export(tmp_path, range(0, 1))
    meta = json.loads((tmp_path / "draw0.json").read_text())
    centre = np.array(meta["draw"]["targets"][0]["centre"])
    spots = np.array(meta["spots"])
    scene = nl.Scene(nl.paper_setup(detector_spots=spots),
                     nl.Target(nl.rectangle(0.02, 0.02, centre=tuple(centre), normal=(0, -1, 0),
                                            cell_m=0.01)), 0.01)
    axis = nl.TimeAxis(meta["start_opl"] / nl.SPEED_OF_LIGHT, meta["bin_opl"] / nl.SPEED_OF_LIGHT,
                       meta["n_bins"])
    # the same axis as nlos_cl sees it: the start shifted back by the device legs and the delay
    setup = scene.setup
    t0 = (meta["start_opl"] + 2 * setup.device_distance_m) / nl.SPEED_OF_LIGHT \
        + setup.pulse.peak_delay_s
    hist = nl.simulate(scene, nl.TimeAxis(t0, axis.dt_s, axis.n_bins)).histograms().data
    path = np.linalg.norm(centre) + np.linalg.norm(spots - centre, axis=1)
    expected = (path - meta["start_opl"]) / meta["bin_opl"]
    assert np.all(np.abs(np.argmax(hist, axis=1) + 0.5 - expected) < 0.02 / meta["bin_opl"])
    assert math.isclose(meta["bin_opl"], nl.SPEED_OF_LIGHT * 1e-12)


def _layouts_script():
    import sys
    sys.path.insert(0, str(SCRIPT.parent))  # it imports mitransient_draws beside it
    spec = importlib.util.spec_from_file_location("mitransient_layouts",
                                                  SCRIPT.with_name("mitransient_layouts.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_layouts_pair_lasers_and_spots_as_documented():
    """scripts/mitransient_layouts.py: one laser at O; confocal, laser = spot; paired, spot i
    lit at spot i + 1 (no pair confocal); exhaustive, lasers O, spot 0 and spot S/2 with every
    spot (its first row block is the one-laser layout)."""
    m = _layouts_script()
    spots = np.array([[-1.0, 0.0, 0.2], [-0.5, 0.0, -0.3], [0.4, 0.0, 0.1], [0.8, 0.0, 0.6]])
    pairs = m.pairs_of(spots)
    lasers, seen = pairs["one"]
    assert np.array_equal(lasers, np.zeros((4, 3))) and np.array_equal(seen, spots)
    assert all(np.array_equal(a, spots) for a in pairs["confocal"])
    lasers, seen = pairs["paired"]
    assert np.array_equal(lasers, spots[[1, 2, 3, 0]]) and np.array_equal(seen, spots)
    lasers, seen = pairs["exhaustive"]
    assert lasers.shape == seen.shape == (12, 3)
    assert np.array_equal(lasers[:4], np.zeros((4, 3))) and np.array_equal(seen[:4], spots)
    assert np.array_equal(lasers[4:8], np.repeat(spots[[0]], 4, 0))
    assert np.array_equal(lasers[8:], np.repeat(spots[[2]], 4, 0))


def test_every_laser_point_gets_one_power():
    """mitransient_draws.delivered: the projector's irradiance at a wall point relative to O,
    cos(incidence) / distance^2 from the device (the factor the layouts' renders are divided
    by), 1 at O; further and more oblique points receive less."""
    m = _script()
    assert m.delivered([0.0, 0.0, 0.0]) == 1.0
    p = np.array([-0.8, 0.0, -0.228])
    v = np.asarray(m.DEVICE) - p
    o = np.asarray(m.DEVICE, float)
    expected = (v[1] / np.linalg.norm(v) ** 3) / (o[1] / np.linalg.norm(o) ** 3)
    assert math.isclose(m.delivered(p), expected, rel_tol=1e-12)
    assert 0.96 < m.delivered(p) < 0.97  # draw 0's spot 0: the 0.966 measured in its renders
