"""nl.write_capture and write_sequence write a confocal scan on a regular grid as y-tal writes its
grids (H_format T_Sx_Sy, H (T, Sx, Sy) per frame, sensor and laser grids X_Y_3), as `nlos-cl
convert` does, and read back the same histograms at the same spots (in the grid's row order),
with their truths; a confocal set that is no full grid stays T_Si."""
import h5py
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.io.ytal.capture import GRID_FORMATS, H_FORMATS
from nlos_cl.io.ytal.reading import read_sequence
from nlos_cl.io.ytal.sequence import write_sequence

C = nl.SPEED_OF_LIGHT
AXIS = nl.TimeAxis(1e-9, 16e-12, 40)
SX, SY = 4, 3


def grid_set(seed=0, drop=0, truth=(0.3, 1.2, 0.1)):
    """A confocal 4 x 3 raster (internal frame: the wall y = 0; X = -x, Y = z), its rows
    shuffled (less `drop` of them: then no full grid)."""
    rng = np.random.default_rng(seed)
    x, z = np.meshgrid(np.arange(SX) * 0.05 - 0.3, np.arange(SY) * 0.04 + 0.1, indexing="ij")
    spots = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
    spots = spots[rng.permutation(len(spots))][:len(spots) - drop]
    data = rng.integers(0, 50, size=(len(spots), AXIS.n_bins)).astype(float)  # float32-exact
    return nl.HistogramSet(data, AXIS, spots, spots, nl.PathCalibration(C, [0.0]),
                           truth=np.array(truth))


def same_by_spot(back, h):
    """The same histograms at the same spots, matched spot by spot."""
    row = {tuple(s): k for k, s in enumerate(np.round(h.detector_spots, 5))}
    match = [row[tuple(s)] for s in np.round(back.detector_spots, 5)]
    assert sorted(match) == list(range(h.n_detectors))
    np.testing.assert_array_equal(back.data, h.data[match])
    np.testing.assert_allclose(back.laser_spots, h.laser_spots[match], atol=1e-6)
    assert back.time_axis == h.time_axis and back.paired


def layout(path):
    with h5py.File(path, "r") as f:
        formats = (f["H_format"][0], f["sensor_grid_format"][0], f["laser_grid_format"][0])
        return formats, f["H"].shape, f["sensor_grid_xyz"].shape


GRID = (H_FORMATS["T_Sx_Sy"], GRID_FORMATS["X_Y_3"], GRID_FORMATS["X_Y_3"])


def test_write_capture_writes_a_confocal_grid_as_a_ytal_grid(tmp_path):
    h = grid_set()
    path = nl.write_capture(tmp_path / "grid.h5", h)
    assert layout(path) == (GRID, (AXIS.n_bins, SX, SY), (SX, SY, 3))
    (back,) = nl.read_capture(path)
    same_by_spot(back, h)
    np.testing.assert_allclose(back.truth, h.truth)


def test_a_confocal_set_that_is_no_grid_stays_flat(tmp_path):
    h = grid_set(drop=1)
    path = nl.write_capture(tmp_path / "flat.h5", h)
    formats, shape, _ = layout(path)
    assert formats[0] == H_FORMATS["T_Si"] and shape == (AXIS.n_bins, SX * SY - 1)
    (back,) = nl.read_capture(path)
    np.testing.assert_array_equal(back.data, h.data)  # T_Si: the rows in the set's order


@pytest.mark.parametrize("frames", [1, 3])
def test_a_sequence_of_grid_frames_is_written_as_ytal_grids(tmp_path, frames):
    base = grid_set()
    sets = [base.__class__(base.data + 7 * k, AXIS, base.detector_spots, base.laser_spot,
                           base.calibration, truth=np.array([0.3 + 0.1 * k, 1.2, 0.1]))
            for k in range(frames)]
    path = write_sequence(tmp_path / "seq.h5", [(0.1 * k, h) for k, h in enumerate(sets)])
    frame_shape = (AXIS.n_bins, SX, SY)
    assert layout(path) == (GRID, frame_shape if frames == 1 else (frames,) + frame_shape,
                            (SX, SY, 3))
    seq = read_sequence(path)
    assert len(seq) == frames
    for k, f in enumerate(seq):
        same_by_spot(f.histograms, sets[k])
        np.testing.assert_allclose(f.truths[0], sets[k].truth, atol=1e-12)
        assert f.t_s == pytest.approx(0.1 * k)


def test_frames_in_another_order_are_written_in_the_grid_order(tmp_path):
    """Every frame is put in frame 0's grid order: frames whose rows come in another order of
    the same spots are refused (another layout), as for T_Si, not written scrambled."""
    a, b = grid_set(seed=0), grid_set(seed=1)
    with pytest.raises(nl.InputError, match="frames\\[1\\]"):
        write_sequence(tmp_path / "mixed.h5", [(0.0, a), (0.1, b)])
