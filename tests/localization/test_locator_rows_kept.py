"""locator.detected_in gives a large record's filtered rows (KEEP_ROWS_BYTES) without new host
pages: on a CPU device the buffer mapped in place (Runtime.view: read-only, the device's
values), elsewhere read into a host array the Locator keeps between frames (a fresh 246 MB
array was mostly page faults): the values are the device's, frame after frame, in the same
array; small records get a new one."""
import numpy as np

import nlos_cl as nl
from nlos_cl.localization import locator


def _frames(runtime, n=2):
    clean = nl.simulate(nl.paper_scene(facet_size_m=0.05), backend=runtime)
    return [nl.gauss_filter(nl.add_noise(clean, 10.0, seed=s)) for s in range(n)]


def test_a_large_records_rows_are_read_into_the_kept_array(runtime, monkeypatch):
    first, second = _frames(runtime)
    monkeypatch.setattr(locator, "KEEP_ROWS_BYTES", 1)  # every record counts as large
    monkeypatch.setattr(runtime, "view", lambda handle: None)  # a device that maps by copy
    kept, window = {}, None
    rows1, _ = locator.detected_in(first, window, kept)
    np.testing.assert_array_equal(rows1, first.values())
    rows2, _ = locator.detected_in(second, window, kept)
    assert rows2 is rows1 and kept["rows"] is rows2  # the same array, the new frame's values
    np.testing.assert_array_equal(rows2, second.values())


def test_small_records_and_host_copies_are_read_as_before(runtime):
    first, _ = _frames(runtime)
    kept = {}
    rows, _ = locator.detected_in(first, None, kept)  # 3 x 60,042 float32: under the limit
    assert kept == {}
    np.testing.assert_array_equal(rows, first.values())
    uploaded = nl.upload(first.histograms())
    assert locator.detected_in(uploaded, None, {})[0] is uploaded.host


def test_a_large_records_rows_are_mapped_on_a_cpu_device(runtime, monkeypatch):
    if not runtime.on_cpu:
        assert runtime.view(_frames(runtime, 1)[0].handle) is None  # a GPU reads instead
        return
    first, second = _frames(runtime)
    monkeypatch.setattr(locator, "KEEP_ROWS_BYTES", 1)
    kept = {}
    rows1, found1 = locator.detected_in(first, None, kept)
    np.testing.assert_array_equal(rows1, first.values())
    assert kept == {} and not rows1.flags.writeable  # nothing copied; nothing can write it
    rows2, found2 = locator.detected_in(second, None, kept)
    np.testing.assert_array_equal(rows2, second.values())
    assert found1.detected and found2.detected
    np.testing.assert_array_equal(rows1, first.values())  # each frame its own buffer
