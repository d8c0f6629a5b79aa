"""A background is compared with the signal in full (issue 59 item 4): shape, time axis,
detector spots and laser spot(s). `locate --background` compared no laser spots (a background
taken from another laser point: 5.8 m off, exit 0) and `track --background` the shape alone."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.errors import InputError
from nlos_cl.core.paths import TimeAxis


@pytest.fixture(scope="module")
def signal():
    return nl.add_noise(nl.simulate(nl.paper_scene()), 10.0, seed=1).histograms()


def _moved(h, *, laser=None, axis=None):
    return nl.HistogramSet(h.data * 0.5, axis or h.time_axis, h.detector_spots,
                           h.laser_spot if laser is None else laser, h.calibration)


@pytest.mark.parametrize("change", ["laser", "time axis"])
def test_a_background_taken_otherwise_is_refused_by_locate_and_track(signal, change, tmp_path):
    axis = signal.time_axis
    other = _moved(signal, laser=[0.3, 0.0, 0.0]) if change == "laser" else \
        _moved(signal, axis=TimeAxis(axis.t0_s + 50 * axis.dt_s, axis.dt_s, axis.n_bins))
    field = "background.laser_spot" if change == "laser" else "background.time_axis"
    with pytest.raises(InputError, match=field):
        nl.locate_capture(signal, background=other)
    frames = [(0.1 * k, signal) for k in range(3)]
    seq_path = nl.write_sequence(tmp_path / "s.h5", frames)
    with pytest.raises(InputError, match=field):
        nl.track_sequence(seq_path, background=other)


def test_a_background_taken_alike_is_used(signal, tmp_path):
    frames = [(0.1 * k, signal) for k in range(3)]
    seq_path = nl.write_sequence(tmp_path / "s.h5", frames)
    run = nl.track_sequence(seq_path, background=_moved(signal), estimator="paper")
    assert len(list(run)) == 3
    found = nl.locate_capture(signal, background=_moved(signal), estimator="paper")
    assert np.all(np.isfinite(found.position))
