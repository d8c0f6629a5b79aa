"""The forward model with each detector's own laser spot (kernels/forward.cl -D PAIRED=1,
nlos_cl/ops/forward.py): the physics that pairing must keep, on every OpenCL device and on the
float64 twin."""
import numpy as np
import pytest

from nlos_cl.core.constants import SPEED_OF_LIGHT as C
from nlos_cl.ops import forward
from nlos_cl.ops.base import to_host

METHODS = ("deposit", "erf")


def _example_inputs(label):
    """The arguments of forward's own "check" example `label` (a paired or confocal layout)."""
    return {e.label: e for e in forward.examples("check")}[label].inputs(None)


def _forward(backend, args, method):
    return to_host(backend, backend.call("forward", *args, method))


@pytest.fixture(params=["device", "twin"])
def backend(request, device_runtime, reference):
    return device_runtime if request.param == "device" else reference


@pytest.mark.parametrize("method", METHODS)
def test_one_laser_written_per_detector_is_the_unpaired_op(backend, method):
    """Every lasers[d] = O: the same arithmetic as the unpaired op, so the identical result."""
    args = _example_inputs("paired: histograms, deposit")
    laser = np.array([0.1, 0.0, -0.05])
    paired = args[:2] + (np.tile(laser, (len(args[1]), 1)),) + args[3:]
    one = _forward(backend, args[:2] + (laser,) + args[3:], method)
    many = _forward(backend, paired, method)
    assert np.array_equal(one[0], many[0]) and np.array_equal(one[1], many[1])


@pytest.mark.parametrize("label", ["paired: histograms, deposit",
                                   "confocal: histograms, deposit"])
@pytest.mark.parametrize("method", METHODS)
def test_paired_histogram_is_its_own_laser_alone(backend, method, label):
    """Histogram d of a paired layout = the unpaired op for detector d alone, laser = lasers[d].
    Both run the same float32 operations per (facet, detector) (measured: bit-identical, on
    PoCL and on the twin), but PAIRED=1 and PAIRED=0 are separate builds that a compiler may
    round differently (FMA contraction): up to 2 ulps of a ~9 m float32 path, 1.9e-6 m, times
    the pulse's steepest slope, 0.61 / sigma of its peak per metre (sigma = 8.9 mm), is 1.3e-4
    of the peak: tolerance 2e-4 of the peak; path spans 1e-6 relative (8 ulps)."""
    facets, spots, lasers, edge0, dpath, sigma, n_bins, refl = _example_inputs(label)
    hist, span = _forward(backend, (facets, spots, lasers, edge0, dpath, sigma, n_bins, refl),
                          method)
    for d in range(len(spots)):
        alone = _forward(backend, (facets, spots[d:d + 1], lasers[d], edge0[d:d + 1],
                                   dpath[d:d + 1], sigma, n_bins, refl), method)
        assert np.abs(alone[0][0] - hist[d]).max() <= 2e-4 * np.abs(hist[d]).max(), d
        assert np.abs(alone[1][0] - span[d]).max() <= 1e-6 * span[d, 1], d


@pytest.mark.parametrize("method", METHODS)
def test_confocal_plate_peaks_at_twice_its_distance(backend, method):
    """A 4 cm plate 1.2 m in front of the middle one of the paper's three wall spots, facing
    it, each spot its own laser (confocal): histogram d peaks at path 2 r_d (r_d = |plate centre
    - spot_d|) within the pulse's sigma (8.9 mm). The outer spots see the plate turned by 23
    degrees: its paths spread over 2 r_d +- 2 (0.02 m) sin 23 deg = +- 16 mm, nearly
    symmetrically, so the peak stays at the centre's path."""
    from nlos_cl.physics.meshes import rectangle
    from nlos_cl.physics.scene import Scene, Target, paper_setup
    setup, centre = paper_setup(), np.array([-1.0, 1.2, 0.0])
    plate = rectangle(0.04, 0.04, centre=centre, normal=(0.0, -1.0, 0.0), cell_m=0.004)
    scene = Scene(setup, Target(plate), 0.004)
    spots = setup.detector_spots
    r = np.linalg.norm(centre - spots, axis=1)
    step, sigma = 1e-12 * C, C * setup.pulse.sigma_s
    edge0 = 2 * r.min() - 0.2
    n_bins = int(np.ceil((2 * r.max() + 0.2 - edge0) / step))
    hist, _ = _forward(backend, (scene.facets(), spots, spots.copy(), np.full(3, edge0),
                                 np.full(3, step), sigma, n_bins, None), method)
    peak = edge0 + (np.argmax(hist, axis=1) + 0.5) * step
    assert np.all(np.abs(peak - 2 * r) <= sigma), (peak - 2 * r, sigma)
