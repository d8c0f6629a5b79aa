"""Background removal for streams: the device path against the NumPy twin, both modes."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.tracking import BackgroundRemover

C = nl.SPEED_OF_LIGHT


def _frames(n=6, seed=0):
    rng = np.random.default_rng(seed)
    axis = nl.TimeAxis(40 / C, 10e-12, 1024)
    spots = [[-0.5, 0, 0], [-1, 0, 0], [-1.5, 0, 0]]
    clutter = rng.random((3, 1024)) * 1e-13
    out = []
    for k in range(n):  # clutter + a moving bump + noise; scales differ from frame to frame
        data = clutter + 0.2e-13 * rng.standard_normal((3, 1024))
        data[:, 100 + 50 * k:120 + 50 * k] += 3e-13 * (1 + k)
        out.append(nl.HistogramSet(data, axis, spots, [0, 0, 0],
                                   nl.PathCalibration(C, [-40.0])))
    return out, clutter


@pytest.mark.parametrize("mode", ["fixed", "running"])
def test_device_matches_numpy(runtime, reference, mode):
    frames, clutter = _frames()
    ref = frames[0].with_data(clutter)
    make = (lambda be: BackgroundRemover(ref, clip=True, backend=be)) if mode == "fixed" else \
        (lambda be: BackgroundRemover(alpha=0.3, backend=be))  # both clip settings
    dev, twin = make(runtime), make(reference)
    for h in frames:
        a, b = dev(nl.upload(h, runtime)), twin(nl.upload(h, reference))
        ha, hb = a.histograms().data, b.histograms().data
        assert np.max(np.abs(ha - hb)) <= 1e-6 * np.max(np.abs(hb)) + 1e-30
    np.testing.assert_allclose(dev.background(), twin.background(),
                               rtol=0, atol=1e-6 * np.abs(twin.background()).max())


def test_fixed_reference_removes_the_clutter(reference):
    frames, clutter = _frames(3)
    remover = BackgroundRemover(frames[0].with_data(clutter), backend=reference)
    clipping = BackgroundRemover(frames[0].with_data(clutter), clip=True, backend=reference)
    for h in frames:  # negatives kept by default (clipping biases the model estimator)
        out = remover(h).histograms().data
        np.testing.assert_allclose(out, h.data - clutter, atol=1e-25)
        np.testing.assert_allclose(clipping(h).histograms().data, np.maximum(out, 0), atol=1e-25)
    assert remover.mode == "fixed reference"


def test_running_mean_learns_the_clutter(reference):
    frames, clutter = _frames(40)
    remover = BackgroundRemover(alpha=0.2, clip=False, backend=reference)
    outs = [remover(h).histograms().data for h in frames]
    assert not np.any(outs[0])  # the first frame only starts the mean
    bg = remover.background()
    # away from the bump's bins, the mean converges to the clutter (noise 0.2e-13 / sqrt(~10))
    assert np.median(np.abs(bg[:, :90] - clutter[:, :90])) < 0.2e-13
    assert remover.mode == "running mean"


def test_bad_input(reference):
    frames, clutter = _frames(1)
    with pytest.raises(nl.InputError, match="alpha"):
        BackgroundRemover(alpha=0)
    remover = BackgroundRemover(frames[0].with_data(clutter), backend=reference)
    short = nl.HistogramSet(np.ones((3, 10)), nl.TimeAxis(40 / C, 10e-12, 10),
                            frames[0].detector_spots, [0, 0, 0], nl.PathCalibration(C, [-40.0]))
    with pytest.raises(nl.InputError, match="frame"):
        remover(short)
