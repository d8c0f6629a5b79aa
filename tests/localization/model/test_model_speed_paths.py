"""The model estimator's faster paths give the old paths' numbers (issue 23): the row median, the
host model's cached histograms and taps, its per-plate cosines, the start candidates' closed-form
costs and coarse lattice, the ellipse start's analytic Jacobian and the solver's direct step.
No timings."""
import numpy as np
import pytest

from nlos_cl.localization.model.forward import batch
from nlos_cl.localization.model.solve import lm
from nlos_cl.localization.model.shapes import plate
from nlos_cl.localization.model.policy import starts
from nlos_cl.localization.model.forward.data import row_median
from nlos_cl.ops.forward import facet_paths

from conftest import model_observation, paper_frame

ON_PLANE = plate.Held(2, (0.0, 0.0, 0.0))  # the paper's line: z held at 0

TRUTH = (4.0, 2.0, 0.0)
PLATE = np.array([4.0, 2.0, 0.0, 0.3, 1.6, np.pi])  # facing the wall


@pytest.fixture(scope="module")
def obs(runtime):
    """The Gaussian observation of one 10 dB frame of the paper's scene."""
    return model_observation(*paper_frame(runtime, truth=TRUTH))


def _plates(rng, count):
    rows = np.tile(PLATE, (count, 1)) + rng.normal(size=(count, 6)) * [0.2, 0.2, 0.1, 0.05,
                                                                       0.2, 0.4]
    rows[:, 3:5] = np.abs(rows[:, 3:5]) + 0.05
    return rows


@pytest.mark.parametrize("shape", [(3, 601), (3, 600), (2, 1), (4, 2)])
def test_row_median_is_numpys(shape):
    rng = np.random.default_rng(0)
    for values in (rng.normal(size=shape), np.round(rng.normal(size=shape) * 2)):  # and ties
        kept = values.copy()
        assert np.array_equal(row_median(values), np.median(values, axis=1))
        assert np.array_equal(values, kept)  # the caller's rows are not partitioned
    values[0, 0] = np.nan
    assert np.array_equal(row_median(values), np.median(values, axis=1), equal_nan=True)


def test_plate_paths_are_the_forward_twins(obs):
    """batch._paths (one cosine per plate and spot) against ops.forward.facet_paths, per point,
    for plates facing the wall and one turned away from it."""
    rows = np.vstack([_plates(np.random.default_rng(1), 4), [4.0, 2.0, 0.0, 0.3, 1.6, 0.0]])
    centres, normal, area, _, _ = batch._cells(rows, (16, 24))
    path, weight = batch._paths(centres, normal, area, obs.spots, obs.laser)
    for b in range(len(rows)):
        normals = np.broadcast_to(normal[b], centres[b].shape)
        twin_path, twin_weight = facet_paths(centres[b], normals, np.full(len(normals), area[b]),
                                             obs.spots, obs.laser)
        lit = twin_weight > 0
        assert np.array_equal(weight[:, b] > 0, lit)
        np.testing.assert_allclose(path[:, b][lit], twin_path[lit], rtol=1e-13)
        np.testing.assert_allclose(weight[:, b], twin_weight, rtol=1e-12, atol=0)
    assert not (weight[:, -1] > 0).any()  # the plate turned away sends nothing


def test_remembered_histograms_and_taps_are_a_fresh_problems(obs):
    """A plate evaluated again (its histograms remembered), a Jacobian's plates (the taps
    remembered from their unmoved plate's call) and a batch of mixed widths: the numbers of a
    new problem that has remembered nothing, evaluating each plate alone."""
    rng = np.random.default_rng(2)
    rows = _plates(rng, 8)
    problem = batch.HostProblem(obs)
    first = problem.column_batch(rows)
    moved = rows + 2e-3
    stepped = problem.column_batch(moved, rows)
    again = problem.column_batch(rows)
    calls = problem.calls
    assert np.array_equal(again, first) and problem.calls == calls  # not evaluated again
    for i in range(len(rows)):
        alone = batch.HostProblem(obs)
        np.testing.assert_allclose(alone.column(rows[i]), first[i], rtol=0,
                                   atol=1e-12 * np.abs(first[i]).max())
        np.testing.assert_allclose(alone.column_batch(moved[i:i + 1], rows[i:i + 1])[0],
                                   stepped[i], rtol=0, atol=1e-12 * np.abs(stepped[i]).max())


def test_candidate_costs_are_the_problems(obs):
    """The closed-form costs of one-target candidates against Problem.linear and .residual,
    including a plate the spots do not see (amplitude 0) and one the data want negative."""
    problem = batch.HostProblem(obs)
    rows = np.vstack([starts.candidates([np.array(TRUTH)], obs.laser),
                      [4.0, 2.0, 0.0, 0.3, 1.6, 0.0]])
    cols = problem.column_batch(rows)
    cols[1] *= -1.0  # the data want a negative amplitude of it: held at 0
    expected = []
    for col in cols:
        lin = problem.linear(col[None])
        r = problem.residual(col[None], lin)
        expected.append(r @ r)
    np.testing.assert_allclose(starts._costs_alone(obs, cols), expected, rtol=1e-12)


def test_coarse_candidates_pick_the_full_lattices_starts(obs):
    """The candidates ranked on START_LATTICE start the fits where the fit's lattice would."""
    problem = batch.HostProblem(obs)
    rows = starts.candidates(starts.start_centres(obs, TRUTH, ON_PLANE), obs.laser)
    coarse = starts.best_starts(problem, rows)
    assert problem.calls == len(rows)  # the coarse problem's evaluations are counted here
    assert problem.coarser(starts.START_LATTICE).lattice == starts.START_LATTICE
    full = starts._best(problem, rows, None, 3)
    assert np.array_equal(np.array(coarse), np.array(full))


def test_ellipse_point_with_its_jacobian_is_the_finite_difference_answer(obs):
    paths = starts.mean_paths(obs)
    point = starts.ellipse_point(obs, paths, ON_PLANE)

    def res(v):
        c = np.array([v[0], v[1], 0.0])
        return np.linalg.norm(c - obs.laser, axis=-1) + np.linalg.norm(obs.spots - c, axis=1) \
            - paths
    differenced = lm.least_squares(res, point[:2] + [0.05, -0.05], bounds=([-np.inf, 0.05],
                                                                           np.inf)).x
    np.testing.assert_allclose(point[:2], differenced, atol=1e-6)


def test_a_detector_without_signal_is_left_out_of_the_start(obs):
    """A float32 record with one detector's values all zero (a CC-SOCR scan point's counts):
    its mean path is NaN (0 / 0: a 1e-300 floor is 0 in float32), the others' are float64's,
    and the ellipse start is the one the other detectors give (it raised 'x0: must be a
    finite vector' from `--estimator model` on 24 CC-SOCR points); none seen: the region's
    middle."""
    from dataclasses import replace
    y = obs.y.astype(np.float32)
    y[1] = 0.0
    dead = replace(obs, y=y)
    paths = starts.mean_paths(dead)
    assert np.isnan(paths[1]) and np.all(np.isfinite(paths[[0, 2]]))
    np.testing.assert_allclose(paths[[0, 2]], starts.mean_paths(obs)[[0, 2]], rtol=1e-6)
    rest = obs.detectors([0, 2])
    np.testing.assert_allclose(starts.ellipse_point(dead, paths, ON_PLANE),
                               starts.ellipse_point(rest, starts.mean_paths(rest), ON_PLANE),
                               atol=1e-9)
    middle = plate.Held(2, (1.0, 2.0, 0.5))
    assert np.array_equal(starts.ellipse_point(obs, np.full(3, np.nan), middle), [1.0, 2.0, 0.5])

def test_damped_step_without_index_arrays_is_the_indexed_one():
    rng = np.random.default_rng(4)
    j = rng.normal(size=(30, 5))
    a, g = j.T @ j, rng.normal(size=5)
    free = np.ones(5, bool)
    fast = lm._damped_step(a, g, 0.3, free)
    indexed = np.linalg.solve(a + 0.3 * np.eye(5), -g)
    assert np.array_equal(fast, indexed)
    free[2] = False
    step = lm._damped_step(a, g, 0.3, free)
    assert step[2] == 0.0 and np.array_equal(
        step[free], np.linalg.solve(a[np.ix_(free, free)] + 0.3 * np.eye(4), -g[free]))


def test_full_memories_never_lose_what_a_call_reads(obs):
    """The host model's bounded memories (cell statistics, taps) are cleared when full; a call
    that mixes remembered and new rows must still find both (the review found both raised
    KeyError once full: a several-target fit with targets='auto' fills them)."""
    rng = np.random.default_rng(5)
    known, new = _plates(rng, 2), _plates(rng, 2)
    problem = batch.HostProblem(obs)
    problem.column_batch(known)  # remembers their statistics and taps
    problem._stats.update((b"filler %d" % i, None) for i in range(70))  # both memories full
    problem._taps.update(((999, float(i)), None) for i in range(300))
    rows = np.vstack([known, new])
    got = problem.column_batch(rows + 1e-4, like=rows)  # known rows' statistics, new ones'
    fresh = batch.HostProblem(obs).column_batch(rows + 1e-4, like=rows)
    assert np.allclose(got, fresh, rtol=1e-12, atol=0)
