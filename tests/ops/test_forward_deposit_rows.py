"""The forward model's two deposits (kernels/forward.cl): 32-bit atomics across facets
(`deposit`) and one work item per detector (`deposit_rows`, ops.forward_passes.deposit_kernel: many
detectors and not too many facets each, on a CPU device) add the same 64-bit fixed-point numbers, so their
histograms agree bit for bit; which one a pass takes follows its detectors and the device."""
import numpy as np

import nlos_cl as nl
from nlos_cl.device.runtime import cl
from nlos_cl.ops import forward, forward_passes
from nlos_cl.physics import layouts


def _histograms(runtime, monkeypatch, kernel, spots, cell):
    monkeypatch.setattr(forward_passes, "deposit_kernel", lambda rt, n, facets: kernel)
    monkeypatch.setattr(forward, "direct", lambda *a: False)  # the fused deposit's own test below
    scene = nl.paper_scene(facet_size_m=cell, detector_spots=spots)
    args = forward.scene_inputs(scene, forward._window(scene, 10e-12))
    hist, span = forward.opencl(runtime, *args)
    return runtime.to_numpy(hist), span


def test_both_deposits_give_the_same_bits(runtime, monkeypatch):
    spots = layouts.spad_patch((-1.0, 0.0, 0.0), (6, 5), (0.05, 0.05))
    atomic, span_a = _histograms(runtime, monkeypatch, "deposit", spots, 0.02)
    rows, span_r = _histograms(runtime, monkeypatch, "deposit_rows", spots, 0.02)
    assert atomic.max() > 0
    assert np.array_equal(atomic, rows) and np.array_equal(span_a, span_r)


def test_the_choice_follows_the_detectors_and_the_device(runtime):
    cpu = bool(runtime.device.type & cl.device_type.CPU)
    few, many = forward_passes.ROWS_MIN_DETECTORS, forward_passes.ROWS_MAX_FACETS
    assert forward_passes.deposit_kernel(runtime, few - 1, 100) == "deposit"
    assert forward_passes.deposit_kernel(runtime, few, few * many + 1) == "deposit"  # a detailed mesh
    assert forward_passes.deposit_kernel(runtime, few, few * many) == (
        "deposit_rows" if cpu else "deposit")

