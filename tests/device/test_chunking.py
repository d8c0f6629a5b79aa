"""Buffers over the device's allocation limit are split transparently: with a tiny forced
limit, every stage gives bit-identical results to the unchunked run (each output value is
computed by the same operations; only which buffer holds the intermediates changes)."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.errors import DeviceError
from nlos_cl.ops.gauss_filter import gauss_taps
from nlos_cl.ops.opencl_backend import OpenCLBackend as Runtime

C = nl.SPEED_OF_LIGHT


@pytest.fixture(scope="module")
def tiny():
    return Runtime(max_alloc_bytes=24_000)


@pytest.fixture(scope="module")
def scene_axis():
    scene = nl.paper_scene(facet_size_m=0.02)  # ~5,000 facets: 20 kB of paths per detector
    return scene, nl.TimeAxis(2 * 20 / C + 28e-9, 10e-12, 900)


def test_forward_in_detector_groups_is_identical(runtime, scene_axis):
    scene, axis = scene_axis
    n_pad = -(-scene.facets().count // 64) * 64
    tiny = Runtime(max_alloc_bytes=4 * n_pad + 100)  # room for one detector's paths, not two
    assert 4 * n_pad * 3 > tiny.max_alloc_bytes >= 4 * n_pad  # one detector per group
    whole = nl.simulate(scene, axis, backend=runtime).histograms().data
    split = nl.simulate(scene, axis, backend=tiny).histograms().data
    assert np.array_equal(whole, split)


def test_filter_in_row_groups_is_identical(runtime):
    data = np.random.default_rng(3).standard_normal((7, 2000))
    taps = gauss_taps(0.65e-9, 10e-12)
    small = Runtime(max_alloc_bytes=2 * 4 * (2000 + 2 * 65 + 32))  # two rows per group
    a = runtime.to_numpy(runtime.gauss_filter(runtime.from_numpy(data), taps))
    b = small.to_numpy(small.gauss_filter(small.from_numpy(data), taps))
    assert np.array_equal(a, b)


@pytest.mark.parametrize("grid", [nl.Grid((2.0, 0.5, 0.0), (0.01, 0.01, 0.01), (601, 60, 1)),
                                  nl.Grid((3.0, 1.0, -0.3), (0.03, 0.03, 0.03), (30, 30, 20))],
                         ids=["rows", "planes"])
def test_score_in_slabs_is_identical(runtime, tiny, scene_axis, grid):
    scene, axis = scene_axis
    filtered = nl.gauss_filter(nl.simulate(scene, axis, backend=runtime)).histograms()
    a = nl.locate(filtered, grid, return_map=True, backend=runtime, estimator="paper")
    b = nl.locate(filtered, grid, return_map=True, backend=tiny, estimator="paper")
    handle = tiny.ellipse_score(tiny.from_numpy(filtered.data / filtered.data.max()),
                                tiny.row_stats(tiny.from_numpy(filtered.data)),
                                filtered.detector_spots, filtered.laser_spot,
                                filtered.path_axis().centre0_m,
                                1 / filtered.path_axis().step_m,
                                grid, False, 1e-6)
    assert len(handle.slabs) > 2
    assert np.array_equal(a.score_map, b.score_map)
    assert np.array_equal(a.position, b.position)


def test_a_row_too_big_for_any_buffer_is_a_clear_error():
    with pytest.raises(DeviceError, match="Fix:"):
        Runtime(max_alloc_bytes=1000).groups(10, 4000, "a row of the score map")


def test_device_out_of_memory_retries_in_smaller_chunks():
    rt = Runtime(max_alloc_bytes=64 << 20)
    seen = []

    def stage():
        seen.append(rt.max_alloc_bytes)
        if rt.max_alloc_bytes > 16 << 20:
            raise nl.runtime.cl.MemoryError("clEnqueueNDRangeKernel failed: "
                                            "MEM_OBJECT_ALLOCATION_FAILURE")
        return "done"

    with pytest.warns(RuntimeWarning, match="out of memory"):
        assert rt.shrinking_on_oom(stage) == "done"
    assert seen == [64 << 20, 32 << 20, 16 << 20]


def test_device_out_of_memory_at_the_floor_says_what_to_reduce():
    rt = Runtime(max_alloc_bytes=1 << 20)

    def stage():
        raise nl.runtime.cl.MemoryError("MEM_OBJECT_ALLOCATION_FAILURE")

    with pytest.raises(DeviceError, match="reduce the grid"):
        rt.shrinking_on_oom(stage)
