"""The fused deposit (kernels/forward.cl `deposit_direct`, ops.forward_passes.direct):
paths, weights and the linear split in one pass into each detector's float sub-bins over the
whole axis, for short windows on many detectors of a CPU device (a model fit's columns). It
must give the windowed deposit's histograms and spans, whatever part of the light the axis
cuts off, and be chosen only where it applies."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.paths import TimeAxis
from nlos_cl.ops import forward, forward_passes
from nlos_cl.physics import layouts
from nlos_cl.physics.reflectance import GGX


def _inputs(axis_share=(0.0, 1.0), confocal=False, spots=(5, 4)):
    patch = layouts.spad_patch((-1.0, 0.0, 0.0), spots, (0.07, 0.05))
    scene = nl.paper_scene(facet_size_m=0.03, detector_spots=patch)
    lasers = np.array(patch) if confocal else None
    full = forward._window(scene, 20e-12, laser=lasers)
    lo, hi = axis_share  # a record that starts late or ends early cuts the light off
    first = int(lo * full.n_bins)
    axis = TimeAxis(full.t0_s + first * full.dt_s, full.dt_s,
                    max(2, int(hi * full.n_bins) - first))
    args = forward.scene_inputs(scene, axis)
    return args[:2] + (lasers,) + args[3:] if confocal else args


def _both(runtime, monkeypatch, args):
    taken = []
    real = forward.direct_bins
    monkeypatch.setattr(forward, "direct_bins", lambda *a: taken.append(1) or real(*a))
    fused, span_f = forward.opencl(runtime, *args)
    assert taken, "the fused deposit was not chosen"
    monkeypatch.setattr(forward, "direct", lambda *a: False)
    windowed, span_w = forward.opencl(runtime, *args)
    return (runtime.to_numpy(fused), np.asarray(span_f)), (runtime.to_numpy(windowed),
                                                           np.asarray(span_w))


@pytest.mark.parametrize("share", [(0.0, 1.0), (0.3, 0.7), (0.0, 0.4), (0.6, 1.0)])
@pytest.mark.parametrize("confocal", [False, True])
def test_fused_equals_windowed_and_twin(runtime, monkeypatch, share, confocal):
    if not runtime.on_cpu:
        pytest.skip("the fused deposit runs on CPU devices only")
    args = _inputs(share, confocal)
    (fused, span_f), (windowed, span_w) = _both(runtime, monkeypatch, args)
    twin, span_t = forward.numpy(*args)
    peak = np.abs(twin).max()
    assert peak > 0
    # float32 paths of ~10 m (ulp ~1e-6 m, ~1e-3 of a sub-bin) measured from different bases:
    # the splits differ by ~1e-5 of the peak (measured up to 1.5e-5; each is 1.4-2e-5 from the
    # exact erf); the linear split's own error is ~1e-4 (ops/pulse.py), the twin's bound 1e-3
    assert np.abs(fused - windowed).max() <= 1e-4 * peak
    assert np.abs(fused - twin).max() <= 1e-3 * peak
    lit = np.isfinite(span_t[:, 0])
    assert np.array_equal(lit, np.isfinite(span_f[:, 0]))
    assert np.abs(span_f[lit] - span_t[lit]).max() <= 1e-5
    assert np.abs(span_f[lit] - span_w[lit]).max() <= 1e-5


def test_the_choice(runtime):
    cpu = runtime.on_cpu
    step, sigma = 0.0216, 0.0656  # a model column's bins and pulse
    many = forward_passes.ROWS_MIN_DETECTORS
    dpath = np.full(many, step)
    assert forward_passes.direct(runtime, many, 91, sigma, dpath, None, None) == cpu
    assert not forward_passes.direct(runtime, many - 1, 91, sigma, dpath, None, None)
    assert not forward_passes.direct(runtime, many, 91, sigma, dpath, GGX(0.5, 0.3, 0.2), None)
    assert not forward_passes.direct(runtime, many, 91, sigma, dpath, None, np.ones((many, 4), bool))
    # a whole record's axis (60,042 bins at 1 ps) keeps the windowed deposit
    assert not forward_passes.direct(runtime, many, 60042, 0.021, np.full(many, 3e-4), None, None)
