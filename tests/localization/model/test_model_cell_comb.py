"""The plate's cell model leaves no comb at photon counts' narrow pulse (the lattice a counts
fit gets: lattices.counts_lattice, with plate.COUNTS_BLUR_SHARE).

Each lattice cell is four Gauss points plus a shared pulse blur. Where a cell spans several
pulse widths of path (counts are not Gauss-filtered: pulse and jitter alone, sigma ~1.3 cm of
path, against ~6.6 cm for filtered data), points placed to match each cell's variance exactly
(+-0.20 of the cell with half the variance in the blur) form a comb whose first harmonic
survives: a 0.95 m plate facing the wall was modelled 9 % off (L2), a 1.2 m plate seen
obliquely 19 %, and on draw 46 of the `counts` family the true plate cost 5,510 deviance
units where a converged lattice costs 3,783, so a cylinder 0.5 m off fitted better. Points at
the midpoints of a 2 x 2 sub-lattice (+-1/4: a quarter of the variance in the blur) cancel
that harmonic, and 32 cells across halve the cells.

What is checked: the model on the estimator's counts lattice against the same model on a
256 x 256 lattice (cells of < 0.5 cm: no comb at any share), relative L2 per detector. The
bound: a relative error e adds ~e^2 x (signal photons) to a detector's deviance; at the draws'
most, 20,000 photons a detector, e = 1.6 % adds ~5, a few degrees of freedom's worth, where
9 % added ~160. The old constants fail every case but the tall one."""
import math

import numpy as np
import pytest

from nlos_cl.localization.model.shapes import plate
from nlos_cl.localization.model.forward.batch import HostProblem
from nlos_cl.localization.model.forward.data import Observation
from nlos_cl.localization.model.estimator import ModelEstimator
from nlos_cl.localization.model.shapes.lattices import POISSON_LATTICE, counts_lattice

SIGMA0_M = 0.0127  # the counts' model pulse: 70 ps FWHM and 30 ps jitter, in metres of path
TDC_PATH_M = 0.0165  # a 55 ps TDC bin
BOUND = 0.016
LASER = np.zeros(3)
SPREAD = np.array([[1.0, 0, -0.36], [1.25, 0, -0.06], [0.5, 0, 0.3], [-0.5, 0, 0.0]])
LINE_Z = np.array([[0.0, 0, z] for z in np.linspace(-0.6, 0.6, 4)])
CASES = {  # plate rows (x, y, z, width, height, yaw) and the spots seeing them
    "0.95 m facing the wall (counts draw 46)": ([2.96, 3.95, -0.18, 0.95, 0.42, -math.pi / 2],
                                               SPREAD),
    "1.2 m seen obliquely": ([2.0, 2.5, 0.0, 1.2, 0.5, -math.pi / 2 + 0.6], SPREAD),
    "1.6 m tall": ([-1.0, 2.0, 0.2, 0.4, 1.6, -math.pi / 2 - 0.3], SPREAD),
    "tall, above a vertical line of spots": ([0.3, 2.0, 0.8, 0.4, 1.6, -math.pi / 2], LINE_Z),
    "wide, before a vertical line of spots": ([0.3, 2.0, 0.0, 1.2, 0.5, -math.pi / 2 + 0.4],
                                              LINE_Z),
}


def _observation(row, spots, sigma0=SIGMA0_M):
    """A counts observation whose windows hold every path of the plate (data unused)."""
    pts = plate.plate_facets(row, (64, 64)).centres
    paths = np.linalg.norm(pts - LASER, axis=1)[None] + \
        np.linalg.norm(pts[None] - spots[:, None], axis=2)
    lo = paths.min(axis=1) - 6 * sigma0 - 0.05
    n = int(np.ceil((paths.max(axis=1) + 6 * sigma0 + 0.05 - lo).max() / TDC_PATH_M)) + 1
    d = len(spots)
    return Observation("poisson", spots, LASER, lo, np.full(d, TDC_PATH_M), np.zeros((d, n)),
                       np.ones((d, n), bool), sigma0, np.ones(d), np.eye(1, n)[0],
                       lo + 0.5 * TDC_PATH_M)


def _error(row, spots, lattice, sigma0=SIGMA0_M):
    obs = _observation(row, spots, sigma0)
    ref = HostProblem(obs, (256, 256)).column(row)
    col = HostProblem(obs, lattice).column(row)
    return float(np.max(np.linalg.norm(col - ref, axis=1) / np.linalg.norm(ref, axis=1)))


def _lattice(obs):
    """What the estimator fits counts on: the lattice and its blur share."""
    lattice = ModelEstimator().lattice_for(obs)
    assert plate.flat_share(lattice) == plate.COUNTS_BLUR_SHARE
    return lattice


@pytest.mark.parametrize("case", list(CASES))
def test_no_comb_on_the_counts_lattice(case):
    row, spots = CASES[case]
    lattice = _lattice(_observation(row, spots))
    assert tuple(lattice) == POISSON_LATTICE
    assert _error(np.array(row), spots, lattice) < BOUND


@pytest.mark.parametrize("case", ["1.2 m seen obliquely", "tall, above a vertical line of spots"])
def test_a_narrower_pulse_gets_finer_cells(case):
    """An SNSPD's jitter (15 ps) and a 20 ps pulse: sigma0 0.6 cm, half the default's; the
    lattice doubles (counts_lattice) and holds the same bound."""
    row, spots = CASES[case]
    sigma0 = 0.006
    lattice = _lattice(_observation(row, spots, sigma0))
    assert tuple(lattice) == (64, 60)
    assert _error(np.array(row), spots, lattice, sigma0) < BOUND


def test_a_laser_spot_per_detector_stays_within_the_kernels_cells():
    """Paired and confocal layouts are modelled by ops.plate_model alone, whose cells are
    capped: a narrow pulse's lattice shrinks to fit (coarser, rather than no model at all)."""
    from nlos_cl.ops.plate_model import MAX_CELLS
    row, spots = CASES["1.2 m seen obliquely"]
    obs = _observation(row, spots, 0.006)
    from dataclasses import replace
    paired = replace(obs, laser=np.zeros((len(spots), 3)))
    nu, nv = counts_lattice(paired)
    assert nu * nv <= MAX_CELLS and nu >= 31


def test_the_old_placement_and_lattice_combed():
    """The test's power: half the variance in the blur (plate.BLUR_SHARE, a plain lattice's)
    on 16 cells across misses the bound by 6-12x on the wide plates; a quarter alone, 1-9x."""
    for case in ("0.95 m facing the wall (counts draw 46)", "1.2 m seen obliquely"):
        row, spots = CASES[case]
        assert _error(np.array(row), spots, (16, 32)) > 5 * BOUND
        assert _error(np.array(row), spots, plate.Lattice(16, 32, 0.25)) > BOUND


def test_a_deep_boxs_sides_take_cells_along_its_depth_too():
    """A box's side faces are cut along its depth (box.DEPTH_CELLS, 8, on filtered data): at
    counts' pulse a 0.6 m-deep box seen side-on was 2.6 % off on 8; the counts lattice's 16
    (lattices.counts_depth_cells) hold the bound."""
    from dataclasses import replace
    from nlos_cl.localization.model.shapes import box
    from nlos_cl.localization.model.forward.host_shapes import HostShapeProblem
    row = np.array([1.5, 2.5, 0.0, 0.5, 0.6, 0.6, -math.pi / 2 + 0.7])
    obs = _observation(np.r_[row[:5], row[6]], SPREAD)  # the front face's window, widened
    n = obs.y.shape[1] + 60
    obs = replace(obs, y=np.zeros((len(SPREAD), n)), valid=np.ones((len(SPREAD), n), bool))
    lattice = _lattice(obs)
    assert lattice.depth_cells == 16
    ref = HostShapeProblem(obs, box, plate.Lattice(128, 128, 0.25, 128)).column(row)

    def error(lat):
        col = HostShapeProblem(obs, box, lat).column(row)
        return float(np.max(np.linalg.norm(col - ref, axis=1) / np.linalg.norm(ref, axis=1)))
    assert error(lattice) < BOUND
    assert error(plate.Lattice(*lattice, lattice.blur_share, box.DEPTH_CELLS)) > BOUND


def test_a_lattice_survives_pickle_and_copy_whole():
    """A problem pickled to a worker or copied keeps its cells' share and depth cells (a tuple
    subclass rebuilds from its pair unless told: __getnewargs__)."""
    import copy
    import pickle
    lattice = plate.Lattice(32, 30, 0.25, 16)
    for again in (pickle.loads(pickle.dumps(lattice)), copy.deepcopy(lattice)):
        assert again == (32, 30) and again.blur_share == 0.25 and again.depth_cells == 16
        assert repr(again) == repr(lattice)


def test_coarser_problems_are_told_apart_by_their_share_not_only_their_cells():
    """HostProblem.coarser keeps one problem per lattice: a plain (8, 12) and a counts
    Lattice of the same cells are different models (their points sit apart), so they must
    not share a problem, whichever is asked for first."""
    row, spots = CASES["1.2 m seen obliquely"]
    problem = HostProblem(_observation(row, spots), plate.Lattice(16, 24, 0.25, 8))
    plain = problem.coarser((8, 12))
    counts = problem.coarser(plate.Lattice(8, 12, 0.25, 8))
    assert plain is not counts and plain is problem.coarser((8, 12))
    assert plate.flat_share(plain.lattice) == plate.BLUR_SHARE
    assert plate.flat_share(counts.lattice) == 0.25
    assert not np.allclose(plain.column(row), counts.column(row), rtol=1e-3, atol=0)
