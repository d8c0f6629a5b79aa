"""locator.detected_in reads a large record's filtered rows into a host array the Locator
keeps between frames (KEEP_ROWS_BYTES: a fresh 246 MB array was mostly page faults): the
values are the device's, frame after frame, in the same array; small records get a new one."""
import numpy as np

import nlos_cl as nl
from nlos_cl.localization import locator


def _frames(runtime, n=2):
    clean = nl.simulate(nl.paper_scene(facet_size_m=0.05), backend=runtime)
    return [nl.gauss_filter(nl.add_noise(clean, 10.0, seed=s)) for s in range(n)]


def test_a_large_records_rows_are_read_into_the_kept_array(runtime, monkeypatch):
    first, second = _frames(runtime)
    monkeypatch.setattr(locator, "KEEP_ROWS_BYTES", 1)  # every record counts as large
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
