"""The 'mean' estimator (nlos_cl/localization/posterior.py): the mean and covariance of the
paper's joint likelihood over the search region. Its moments against their cell-by-cell
definition and against a Gaussian likelihood whose mean and covariance are known; the
estimator's two passes (a sub-grid, then full resolution around its mean) against the moments
of the whole region's map; on simulations it lands on the target; the tracker's default for
paired and confocal captures."""
import json
import warnings

import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli
from nlos_cl.core.grid import Grid
from nlos_cl.localization.posterior import (LOG_SPAN, box_around, likelihood_moments,
                                            strided)

GRID = Grid((0.1, 0.2, -0.3), (0.02, 0.03, 0.05), (40, 30, 20))


def _cells(grid):
    ix, iy, iz = np.meshgrid(*(np.arange(n) for n in grid.shape), indexing="ij")
    o, s = np.asarray(grid.origin), np.asarray(grid.step)
    cells = np.stack([o[0] + s[0] * ix, o[1] + s[1] * iy, o[2] + s[2] * iz], axis=-1)
    return cells.transpose(2, 1, 0, 3)  # (nz, ny, nx, 3), the maps' order


def _definition(scores, grid, log_mode):
    """Every cell listed with its weight (float64), the weights normalised."""
    s = scores.astype(np.float64)
    w = np.exp(s - s.max()) if log_mode else s / s.max()
    w[w < np.exp(-LOG_SPAN)] = 0.0
    p, w = _cells(grid).reshape(-1, 3), w.ravel() / w.sum()
    mean = w @ p
    d = p - mean
    return mean, (d * w[:, None]).T @ d + np.diag(np.asarray(grid.step) ** 2 / 12)


@pytest.mark.parametrize("log_mode", [True, False])
def test_moments_are_their_cell_by_cell_definition(log_mode):
    """The three 2-D marginals against every cell listed. Tolerance: float32 weights (the
    map's own precision) summed in float64: ~1e-7 of the region, 1e-8 m asked of means
    within a 0.8 m box and 1e-8 m^2 of covariances ~0.01 m^2."""
    rng = np.random.default_rng(3)
    scores = (rng.normal(size=GRID.shape[::-1]) * 4).astype(np.float32)
    if not log_mode:
        scores = np.exp(scores / 4).astype(np.float32)
    mean, cov = likelihood_moments(scores, GRID, log_mode)
    want_mean, want_cov = _definition(scores, GRID, log_mode)
    assert np.abs(mean - want_mean).max() < 1e-8
    assert np.abs(cov - want_cov).max() < 1e-8
    # a mutation the test must see: one axis pair's cross term transposed
    assert np.abs(want_cov[0, 1] - want_cov[0, 2]) > 1e-4


def test_a_gaussian_likelihood_gives_its_mean_and_covariance():
    """Log scores of a correlated Gaussian (sds 2-3 cells, >= 4.5 sds from the region's ends)
    centred between cells: its mean within 0.01 mm, its covariance plus the cells' step^2 / 12
    within 0.5 % of the sds' products (a Gaussian sampled at >= 2 cells of sd keeps its
    moments to ~e^-79, and 4.5 sds of truncation changes them by ~1e-4)."""
    centre = np.array([0.513, 0.617, 0.151])
    sd = np.array([0.06, 0.09, 0.1])
    corr = np.array([[1.0, 0.5, -0.3], [0.5, 1.0, 0.2], [-0.3, 0.2, 1.0]])
    sigma = corr * np.outer(sd, sd)
    d = _cells(GRID) - centre
    scores = (-0.5 * np.einsum("...i,ij,...j->...", d, np.linalg.inv(sigma), d)).astype(np.float32)
    mean, cov = likelihood_moments(scores, GRID, True)
    assert np.abs(mean - centre).max() < 1e-5
    want = sigma + np.diag(np.asarray(GRID.step) ** 2 / 12)
    assert np.all(np.abs(cov - want) < 0.005 * np.outer(sd, sd)), cov - want


def test_sub_grid_and_box_are_cells_of_the_grid():
    sub = strided(GRID, 2)
    assert sub.origin == GRID.origin and sub.shape == (20, 15, 10)
    assert np.allclose(sub.step, np.asarray(GRID.step) * 2)
    plane = Grid((0.0, 0.5, 0.0), (0.01, 0.01, 0.01), (11, 7, 1))
    assert strided(plane, 2).shape == (6, 4, 1)  # a plane's one z stays
    centre, half = np.array([0.3, 0.5, 0.5]), np.array([0.05, 0.1, 0.3])
    box = box_around(GRID, centre, half)
    first = (np.asarray(box.origin) - GRID.origin) / np.asarray(GRID.step)
    assert np.allclose(first, np.round(first)) and np.all(first >= 0)  # on the grid's cells
    last = first + np.asarray(box.shape) - 1
    assert np.all(last <= np.asarray(GRID.shape) - 1)  # inside it
    # the asked cells 0.26..0.34 (x), 0.41..0.59 (y), 0.2..0.65 (z: 0.8 is past the end) held,
    # their counts 5, 7, 16 rounded up to powers of two (z: 16 of the grid's 20)
    assert box.shape == (8, 8, 16)
    lo, hi = np.asarray(box.origin), np.asarray(box.origin) + np.asarray(GRID.step) * last
    assert np.all(lo <= [0.26 + 1e-9, 0.41 + 1e-9, 0.2 + 1e-9]) and np.all(hi >= [0.34 - 1e-9, 0.59 - 1e-9, 0.65 - 1e-9])
    # wider than the grid along x: the grid's own count, not a power of two
    assert box_around(GRID, centre, np.array([2.0, 0.1, 0.1])).shape[0] == GRID.shape[0]
    far = box_around(GRID, np.array([9.0, 9.0, 9.0]), np.array([0.1] * 3))  # moved inside
    assert far.shape == (16, 8, 8)  # 11, 7 and 5 cells asked
    assert np.allclose(np.asarray(far.origin) + np.asarray(GRID.step) * (np.asarray(far.shape) - 1),
                       np.asarray(GRID.origin) + np.asarray(GRID.step) * (np.asarray(GRID.shape) - 1))


def _plate_capture(runtime, snr_db, seed):
    """The paper's three detectors and a 0.3 x 0.6 m plate at (4.0, 2.0, 0.2)."""
    truth = (4.0, 2.0, 0.2)
    mesh = nl.rectangle(0.3, 0.6, centre=truth, normal=(0.0, -1.0, 0.0), cell_m=0.03)
    scene = nl.Scene(nl.paper_setup(), nl.Target(mesh), 0.03, truth=truth)
    clean = nl.simulate(scene, nl.default_time_axis(scene.setup, 1e-11), backend=runtime)
    return nl.add_noise(clean, snr_db, seed=seed), np.array(truth)


@pytest.mark.parametrize("step", [0.01, 0.04])
def test_the_estimators_two_passes_give_the_whole_maps_moments(runtime, step):
    """On the plate's frame, a 2-D region: the estimator (sub-grid, then full resolution
    around it where that is smaller) against likelihood_moments of the whole map at full
    resolution. A 1 cm step (a sharp likelihood: the box pass runs) within 1 mm; 4 cm (the
    sub-grid's cells are 8 cm, the likelihood ~3 of them wide) within a quarter step."""
    noisy, truth = _plate_capture(runtime, 10.0, 1)
    sig = nl.gauss_filter(noisy)
    grid = nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0), step_m=step)
    mean = nl.locate(sig, grid, estimator="mean", log_mode=True)
    full = nl.locate(sig, grid, estimator="paper", log_mode=True, return_map=True)
    want, _ = likelihood_moments(full.score_map, grid, True)
    tol = 1e-3 if step == 0.01 else step / 4
    assert np.linalg.norm(mean.position - want) < tol, (mean.position, want)
    assert mean.estimator == "mean" and mean.targets[0].covariance is not None
    assert np.array_equal(mean.cell_position, full.cell_position)  # the argmax's, kept


def test_on_measured_frames_the_two_passes_give_the_whole_maps_moments(tmp_path):
    """The consumer sensor's six committed frames (16 zones, 250 ps bins: a broad likelihood,
    sds 0.07-0.41 m) on `nlos-cl track`'s own 3.5 M-cell region: the estimator's mean within
    1 cm of the whole map's at full resolution (measured 0.04-5.9 mm; the box pass, where it
    runs, leaves out the mass beyond 5 sds)."""
    from test_datasets_sequences import converted
    seq = converted(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        grid = nl.track_sequence(seq).tracker.grid
    for frame in seq:
        sig = nl.gauss_filter(frame.histograms)
        mean = nl.locate(sig, grid, estimator="mean", log_mode=True)
        full = nl.locate(sig, grid, estimator="paper", log_mode=True, return_map=True)
        want, _ = likelihood_moments(full.score_map, grid, True)
        assert np.linalg.norm(mean.position - want) < 0.01, (mean.position, want)


def test_the_mean_lies_on_the_plate_and_its_covariance_covers_the_argmax(runtime):
    """Physics: over 6 noise seeds at 0 dB the mean lies within the plate's half-width of its
    centre in (x, y) (the joint likelihood peaks on the plate's front, y = 2.0) and the paper's
    argmax of the same frame is inside the mean's 99.9 % ellipse (chi-square, 2 dof)."""
    grid = nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0), step_m=0.01)
    for seed in range(6):
        noisy, truth = _plate_capture(runtime, 0.0, seed)
        loc = nl.locate(nl.gauss_filter(noisy), grid, estimator="mean", log_mode=True)
        target = loc.targets[0]
        assert np.linalg.norm(loc.position[:2] - truth[:2]) < 0.15, loc.position
        d = np.asarray(target.details["argmax_m"])[:2] - loc.position[:2]
        assert d @ np.linalg.solve(target.covariance[:2, :2], d) < 13.8


def test_paired_sequences_are_tracked_with_the_mean_by_default(tmp_path, capsys):
    """`nlos-cl track` on a confocal sequence with no option: the mean (its warning says so);
    with --targets 2 the argmax (a mean of two targets lies between them)."""
    from test_datasets_sequences import converted
    converted(tmp_path)
    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli(["track", str(tmp_path / "walk.h5"), "--json", "--no-progress"]) == 0
    out = capsys.readouterr()
    assert "mean and covariance of the paper's likelihood by default" in out.err
    lines = [json.loads(line) for line in out.out.splitlines()]
    assert len(lines) == 6 and all(line["measurements"] for line in lines)
    assert cli(["track", str(tmp_path / "walk.h5"), "--json", "--no-progress",
                "--targets", "2"]) == 0
    assert "paper's argmax by default with several targets" in capsys.readouterr().err


def test_no_positive_likelihood_gives_no_moments():
    """A product map of zeros (or all NaN): (None, None), which the estimator answers with the
    argmax's cell, never a NaN position."""
    zeros = np.zeros(GRID.shape[::-1], np.float32)
    assert likelihood_moments(zeros, GRID, False) == (None, None)
    assert likelihood_moments(np.full_like(zeros, np.nan), GRID, True) == (None, None)


def test_the_mean_is_refused_for_several_targets(tmp_path, capsys):
    """A mean of two targets lies between them: `--estimator mean --targets 2` is a one-line
    error naming the option and the fix, before anything is tracked."""
    from test_datasets_sequences import converted
    converted(tmp_path)
    capsys.readouterr()
    assert cli(["track", str(tmp_path / "walk.h5"), "--json", "--no-progress",
                "--estimator", "mean", "--targets", "2"]) != 0
    out = capsys.readouterr()
    assert out.out == "" and "--estimator" in out.err and "--estimator paper or model" in out.err
