"""CC-SOCR figure 4 (measured; ../shared/realdata, skipped where absent): the planar "4" lies
at depth 0.85-1.00 m (the dataset's README, from the authors' setup), which is our y. The full
4,096-point scan and subsets of 3 to 24 points spread over it are located there with the
defaults (paired captures get the paper's argmax by default, and the answer says so: the
model fit left a Birge ratio of 370-500 here, reading the gated zeros as measured, and put 6
points' "4" at 1.34 m). Spread subsets, not index strides: farthest_points."""
import warnings
from pathlib import Path

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.geometry import farthest_points

FULL = Path(__file__).resolve().parents[3] / "shared" / "realdata" / "ccsocr-figure4" / "full"
pytestmark = pytest.mark.skipif(not FULL.is_dir(), reason="../shared/realdata is absent")


@pytest.fixture(scope="module")
def full():
    return nl.read_dataset(FULL)


def _depth(h) -> tuple[float, list]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        point = nl.locate_capture(h).points[0]
    return float(point.location.position[1]), list(point.warnings)


def test_the_full_scan_puts_the_4_at_its_depth(full):
    depth, notes = _depth(full)
    assert 0.85 <= depth <= 1.00
    assert any("paper's argmax by default" in n for n in notes)  # the default says so


@pytest.mark.parametrize("k", [3, 4, 6, 12, 24])
def test_spread_subsets_put_the_4_at_its_depth(full, k):
    depth, _ = _depth(full.select(farthest_points(full.laser_spots, k)))
    assert 0.85 <= depth <= 1.00


def test_farthest_points_spread_over_a_raster():
    """64 of a 64 x 64 raster: not on one line (an index stride would be), deterministic."""
    u = np.linspace(0.0, 1.26, 64)
    raster = np.array([(a, 0.0, b) for a in u for b in u])
    rows = farthest_points(raster, 64)
    assert len(set(rows)) == 64 and np.array_equal(rows, farthest_points(raster, 64))
    spread = np.linalg.svd(raster[rows] - raster[rows].mean(axis=0), compute_uv=False)
    assert spread[1] > 0.5 * spread[0]  # two wall axes, not a line
    stride = np.linspace(0, len(raster) - 1, 64).round().astype(int)
    line = np.linalg.svd(raster[stride] - raster[stride].mean(axis=0), compute_uv=False)
    assert line[1] < 0.1 * line[0]  # what the stride would have picked


@pytest.mark.parametrize("k", [3, 4])
def test_one_laser_by_reciprocity_puts_the_4_at_its_depth_without_numpy_noise(full, k):
    """The same points read as ONE laser (the SPAD point) and k detector spots (the layout
    the issue first met them in): the one-laser default, the model fit, on the "4" either way
    (3 points: a closed shape kept; 4: the argmax, the closed fit rejected). The records are
    gated (zero outside ~300-500 of 1,024 bins): read as measured zeros, the plate's deviance
    was 320-450 per degree of freedom; without them (localization.measured.gated) 3 points'
    plate is at ~70 and the reported fit under MISFIT_BIRGE. No numpy warning reaches the
    answer (4 points' start candidates overflowed a Newton step: likelihood._poisson_linear)."""
    from nlos_cl.core.histograms import reciprocal
    from nlos_cl.core.tuning import MISFIT_BIRGE
    h = reciprocal(full.select(farthest_points(full.laser_spots, k)))
    assert not h.paired
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        point = nl.locate_capture(h).points[0]
    assert 0.85 <= float(point.location.position[1]) <= 1.00
    assert not any("overflow" in n or "invalid value" in n for n in point.warnings)
    if k == 3:
        fit = point.location.targets[0].fit
        assert fit is not None and fit.diagnostics["misfit_ratio"] < MISFIT_BIRGE
        assert fit.diagnostics["plate_birge_ratio"] < MISFIT_BIRGE


def test_the_full_scan_as_one_laser_is_decided_on_a_spread_subset(full, monkeypatch):
    """All 4,096 points read as one laser and 4,096 detectors (model.subset): the plate
    misses the counts, the closed shape chosen on CHOICE_DETECTORS spread points is one the
    sanity check rejects (a cylinder 2.5 m long), so the answer is the argmax on the "4" and nothing was fitted on
    every detector (stop 48: over 7 minutes; now ~10 s on the 2-core machine, not asserted)."""
    from nlos_cl.core.histograms import reciprocal
    from nlos_cl.core.tuning import CHOICE_DETECTORS
    from nlos_cl.localization.model.policy import subset
    fitted_on = []
    cold_fit = subset.cold_fit

    def watched(est, problem, *args):
        answer = cold_fit(est, problem, *args)
        fitted_on.append(answer[0] is None and answer[2][0].obs.spots.shape[0])
        return answer
    monkeypatch.setattr(subset, "cold_fit", watched)
    depth, notes = _depth(reciprocal(full))
    assert 0.85 <= depth <= 1.00
    assert fitted_on == [CHOICE_DETECTORS]  # ended on the subset
    # rejected for its misfit before the gate was read (measured.gated), for its size since
    assert any("model fit rejected" in n for n in notes)
