"""LCT's confocal scans (measured; ../shared/realdata, no licence: read, never committed;
skipped where absent). No truth ships with them, so the check is issue 21's: nlos_cl's answer
lies in front of the wall within 0.02 m in depth of the brightest voxel of a plain confocal
backprojection of the same file (the raw record summed at path 2 |c - s| over the scan
points, on 2 cm voxels: an independent, textbook reconstruction sharing no nlos_cl kernel)."""
import warnings
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl

LCT = Path(__file__).resolve().parents[3] / "shared" / "realdata" / "lct"


def backprojection_peak(h, step_m=0.02, every=2):
    """The brightest voxel of a confocal backprojection over every `every`-th scan point
    (reproduce real's reference, on a 0.8 m wide, 0.1-1.5 m deep volume)."""
    from nlos_cl.localization.backprojection import backprojection_peak as peak
    return peak(h, step_m, every, 0.4, (0.1, 1.5))


@pytest.mark.parametrize("name", ["data_s_u", "data_exit_sign"])
def test_confocal_scan_depth_matches_a_backprojection(name):
    path = LCT / f"{name}.mat"
    if not path.is_file():
        pytest.skip("../shared/realdata/lct is absent")
    h = nl.read_dataset(path)
    assert h.paired and np.allclose(h.laser_spots, h.detector_spots)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        position = nl.locate_capture(h).points[0].location.position
    assert position[1] > 0.1  # in front of the wall
    assert abs(position[1] - backprojection_peak(h)[1]) <= 0.02
