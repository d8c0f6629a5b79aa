"""Coarse-to-fine scoring (nlos_cl/search.py) finds the same argmax cell, with the same score and
the same located position, as scoring every cell: on random scenes of one or two point targets
(two targets' signals summed, near-tied included), noisy or clean, product or log scoring,
planes and volumes, on the device and on the float64 twins; with more detectors than one
scoring pass takes, the host-side search on a SPAD-like patch."""
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import nlos_cl as nl
from nlos_cl.localization.estimate import Capabilities
from nlos_cl.localization.paper import PaperArgmax
from nlos_cl.localization.locator import Locator
from nlos_cl.localization.search import CoarseToFine, coarse_factor
from nlos_cl.ops.ellipse_score import DET_TILE

SETTINGS = dict(deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
DT_S = 10e-12


def histograms(targets, amplitudes, n_det, width_m, noise, seed, n_bins=3000, patch=False):
    """Filtered-looking rows: a Gaussian of `width_m` (path) per target at its hidden path,
    summed, plus white noise of `noise` x the peak. The record (9 m of path) ends inside the
    paths of the far targets: signals cut by the record's end are searched too. Spots on a
    line 0.35 m apart, or (patch) on a SPAD-like patch of 5 cm pitch."""
    spots = np.array([[-0.4 - 0.35 * d, 0.0, 0.15 * (d % 3 - 1)] for d in range(n_det)])
    if patch:
        spots = np.array([[-1.0 - 0.05 * (d // 6), 0.0, 0.05 * (d % 6)] for d in range(n_det)])
    axis = nl.TimeAxis(2 * 20 / nl.SPEED_OF_LIGHT, DT_S, n_bins)
    cal = nl.PathCalibration(nl.SPEED_OF_LIGHT, np.full(n_det, -40.0))
    centres = cal.a_m_per_s * axis.centres() - 40.0
    data = np.zeros((n_det, n_bins))
    for p, a in zip(targets, amplitudes):
        path = np.linalg.norm(p) + np.linalg.norm(np.asarray(p) - spots, axis=1)
        data += a * np.exp(-0.5 * ((centres[None, :] - path[:, None]) / width_m) ** 2)
    rng = np.random.default_rng(seed)
    data += noise * rng.standard_normal(data.shape)
    return nl.HistogramSet(data, axis, spots, np.zeros(3), cal)


def same_answer(hist, grid, backend, log_mode, width_m):
    found = {}
    for search in ("exhaustive", "coarse_to_fine"):
        plan = Locator(hist.layout, grid, search=search, log_mode=log_mode, backend=backend,
                       signal_width_m=width_m, estimator="paper")
        try:
            found[search] = (plan(hist), plan.last_search)
        except nl.InputError as exc:  # no signal reaches the grid: both must say so
            found[search] = (str(exc), None)
    if isinstance(found["exhaustive"][0], str):
        assert found["exhaustive"][0] == found["coarse_to_fine"][0]
        return None
    (ex, _), (c2f, how) = found["exhaustive"], found["coarse_to_fine"]
    assert np.array_equal(ex.cell_position, c2f.cell_position)
    assert ex.score == c2f.score
    assert np.allclose(ex.position, c2f.position, rtol=0, atol=1e-12)  # float64 rounding
    return how


targets = st.tuples(st.floats(2.3, 5.7), st.floats(0.6, 3.9), st.floats(-0.4, 0.4))


@settings(max_examples=40, **SETTINGS)
@given(first=targets, second=targets, tie=st.sampled_from([0.0, 1e-3, 0.02, 0.3, 1.0]),
       n_det=st.integers(2, 5), width=st.floats(0.02, 0.15), noise=st.sampled_from([0.0, 0.1]),
       log_mode=st.booleans(), volume=st.booleans(), seed=st.integers(0, 99))
def test_coarse_to_fine_finds_the_exhaustive_argmax(runtime, first, second, tie, n_det, width,
                                                    noise, log_mode, volume, seed):
    """tie: the second target's amplitude is 1 - tie (0: exactly tied; 1: a single target)."""
    hist = histograms([first, second], [1.0, 1.0 - tie], n_det, width, noise, seed)
    grid = (nl.Grid((2.0, 0.5, -0.5), (0.03, 0.03, 0.05), (140, 120, 21)) if volume
            else nl.Grid.from_ranges(x=(2.0, 6.0), y=(0.5, 4.0), step_m=0.01))
    same_answer(hist, grid, runtime, log_mode, 0.065)


near = st.tuples(st.floats(2.3, 4.5), st.floats(0.6, 3.0), st.floats(-0.4, 0.4))  # in the record


@settings(max_examples=30, **SETTINGS)
@given(first=near, second=near, tie=st.sampled_from([0.0, 1e-3, 0.02, 0.3, 1.0]),
       n_det=st.integers(DET_TILE + 1, 3 * DET_TILE), noise=st.sampled_from([0.02, 0.1]),
       seed=st.integers(0, 99))
def test_many_detectors_search_on_the_host_with_the_same_argmax(runtime, first, second, tie,
                                                                n_det, noise, seed):
    """More detectors than one scoring pass takes (log scoring: a product of so many rows
    underflows): the host-side `run`, whose threshold comes from the best-bound centres only
    (search.TOP_CENTRES), finds the exhaustive argmax, near-ties and exact ties included."""
    hist = histograms([first, second], [1.0, 1.0 - tie], n_det, 0.065, noise, seed, patch=True)
    grid = nl.Grid.from_ranges(x=(2.0, 6.0), y=(0.5, 4.0), step_m=0.02)
    found = {}
    for search in ("exhaustive", "coarse_to_fine"):
        plan = Locator(hist.layout, grid, search=search, log_mode=True, backend=runtime,
                       signal_width_m=0.065, estimator="paper")
        found[search] = (plan(hist, detect=False), plan.last_search)
    (ex, _), (c2f, how) = found["exhaustive"], found["coarse_to_fine"]
    assert not plan._search.fusable(n_det)
    assume(how is not None)  # `run` answered (a flat map is scored whole: nothing to test)
    assert np.array_equal(ex.cell_position, c2f.cell_position) and ex.score == c2f.score


@pytest.mark.parametrize("log_mode", [False, True])
def test_on_the_twins_too(reference, log_mode):
    hist = histograms([(4.0, 2.0, 0.0), (3.0, 3.0, 0.0)], [1.0, 0.999], 3, 0.065, 0.02, 1)
    grid = nl.Grid.from_ranges(x=(2.5, 5.0), y=(1.0, 3.5), step_m=0.02)
    how = same_answer(hist, grid, reference, log_mode, 0.065)
    assert how is not None and how.cells_scored < grid.n_cells / 2


def test_it_scores_a_small_share_of_a_fine_grid(runtime):
    hist = histograms([(4.0, 2.0, 0.0)], [1.0], 3, 0.065, 0.02, 2, n_bins=5000)
    grid = nl.Grid.from_ranges(x=(0.0, 6.0), y=(0.01, 6.0), step_m=6 / 2047)
    how = same_answer(hist, grid, runtime, False, 0.065)
    assert how.cells_scored < grid.n_cells / 50


def test_the_coarse_step_follows_the_signal_width():
    grid = nl.Grid.from_ranges(step_m=0.01)
    assert coarse_factor(grid, 0.065) == 5  # (f - 1) |step| = 4 x 1.41 cm <= 6.5 cm
    assert coarse_factor(grid, 0.02) == 1  # a narrower signal than two cells: score them all
    assert coarse_factor(nl.Grid.from_ranges(x=(0, 0.3), y=(1, 1.3), step_m=0.01), 1.0) == 1
    plan = CoarseToFine(grid, np.array([1 / 0.003]), 0.065)
    assert plan.coarse.shape == (121, 120, 1)
    # the dilation covers twice the block radius in path (bins of 3 mm), plus a bin
    assert plan.half == int(np.ceil(2 * 2 * np.hypot(0.01, 0.01) / 0.003 + 0.01)) + 1


def test_a_flat_map_falls_back_to_every_cell(runtime):
    hist = histograms([(4.0, 2.0, 0.0)], [0.0], 3, 0.065, 1.0, 3)  # noise only
    grid = nl.Grid.from_ranges(x=(2.0, 4.0), y=(1.0, 3.0), step_m=0.01)
    same_answer(hist, grid, runtime, True, 0.065)


def test_unknown_search_is_a_clear_error():
    hist = histograms([(4.0, 2.0, 0.0)], [1.0], 3, 0.065, 0.0, 0)
    with pytest.raises(nl.InputError, match="search"):
        Locator(hist.layout, search="fast", estimator="paper")


class HostSideArgmax(PaperArgmax):
    """The paper's argmax through the general estimator seam (local): the host-side search
    (nlos_cl/search.py `run`) and the argmax op with the neighbourhood read row by row."""

    capabilities = Capabilities(local=True)  # not is_paper: the Locator must call it


@pytest.mark.parametrize("log_mode", [False, True])
@pytest.mark.parametrize("volume", [False, True])
def test_fused_device_search_matches_the_host_side_search(runtime, log_mode, volume):
    """One read per frame (fused_search, argmax_patch) against the host-side paths: the same
    cell, score and position, coarse to fine and exhaustive."""
    hist = histograms([(4.0, 2.0, 0.1), (3.0, 3.0, -0.1)], [1.0, 0.98], 3, 0.065, 0.05, 4)
    grid = (nl.Grid((2.5, 1.0, -0.3), (0.03, 0.03, 0.05), (90, 90, 13)) if volume
            else nl.Grid.from_ranges(x=(2.5, 5.0), y=(1.0, 3.5), step_m=0.01))
    for search in ("coarse_to_fine", "exhaustive"):
        fused = Locator(hist.layout, grid, search=search, log_mode=log_mode, backend=runtime,
                        estimator="paper")
        host = Locator(hist.layout, grid, search=search, log_mode=log_mode, backend=runtime,
                       estimator=HostSideArgmax())
        a, b = fused(hist), host(hist)
        assert np.array_equal(a.cell_position, b.cell_position)
        assert a.score == b.score
        assert np.allclose(a.position, b.position, rtol=0, atol=1e-12)


def test_auto_keeps_one_search_after_its_trials(runtime):
    from nlos_cl.localization.locator import AUTO_TRIALS
    hist = histograms([(4.0, 2.0, 0.0)], [1.0], 3, 0.065, 0.02, 5)
    grid = nl.Grid.from_ranges(x=(2.5, 5.0), y=(1.0, 3.5), step_m=0.01)
    plan, exhaustive = Locator(hist.layout, grid, backend=runtime, estimator="paper"), Locator(
        hist.layout, grid, backend=runtime, search="exhaustive", estimator="paper")
    expected = exhaustive(hist, detect=False)
    assert plan._choice.modes == ("coarse_to_fine", "coarse_to_fine_wide", "exhaustive")
    for _ in range(3 * (AUTO_TRIALS + 1)):  # each search, a warm-up and AUTO_TRIALS timed
        assert plan.chosen is None
        found = plan(hist, detect=False)  # peaks of 3.3 sigma: noise reaches them (detection)
        assert np.array_equal(found.cell_position, expected.cell_position)
        assert found.score == expected.score
    assert plan.chosen in ("coarse_to_fine", "exhaustive")
    # blocks of 5 cells (their diagonal within the 6.5 cm signal width) and of 7, the wider trial
    assert [plan._plans[m].factor for m in ("coarse_to_fine", "coarse_to_fine_wide")] == [5, 7]


class _SlowFromPaper:
    """An estimator that needs only the paper's estimate and takes 0.1 s over it (as a model
    fit takes tens of ms)."""
    name = "slow"
    capabilities = Capabilities(from_paper=True)

    def estimate(self, scored):
        import time
        time.sleep(0.1)
        return scored.paper


def test_auto_times_the_search_alone_for_an_estimator_from_the_paper(runtime):
    """search="auto" is open to estimators that need only the paper's estimate (the model fit:
    it had been held to "exhaustive", 4x the coarse-to-fine search on the tracker's 512^2
    region), and its trials time the search, not the estimator's work after it (with the fit
    in them, the fit's noise chose the search)."""
    from nlos_cl.localization.locator import AUTO_TRIALS
    hist = histograms([(4.0, 2.0, 0.0)], [1.0], 3, 0.065, 0.02, 5)
    grid = nl.Grid.from_ranges(x=(2.5, 5.0), y=(1.0, 3.5), step_m=0.01)
    plan = Locator(hist.layout, grid, backend=runtime, estimator=_SlowFromPaper())
    assert plan.search == "auto"
    expected = Locator(hist.layout, grid, backend=runtime, search="exhaustive",
                       estimator="paper")(hist, detect=False)
    for _ in range(3 * (AUTO_TRIALS + 1)):
        found = plan(hist, detect=False)
        assert np.array_equal(found.cell_position, expected.cell_position)
    trials = plan._choice._trials
    assert len(trials) == 3 * (AUTO_TRIALS + 1) and {m for m, _ in trials} == {
        "coarse_to_fine", "coarse_to_fine_wide", "exhaustive"}
    assert max(t for _, t in trials) < 0.1  # the estimator's 0.1 s is in none of them
    assert plan.chosen in ("coarse_to_fine", "exhaustive")


@pytest.mark.parametrize("grid", [nl.Grid((2.0, 0.5, 0.0), (0.01, 0.01, 0.01), (601, 60, 1)),
                                  nl.Grid((3.0, 1.0, -0.3), (0.03, 0.03, 0.03), (30, 30, 20))],
                         ids=["rows", "planes"])
def test_exhaustive_score_map_in_slabs(runtime, grid):
    """A map in several slabs (a device's allocation limit): argmax_patch reads the
    neighbourhood on the host, with the same answer as one slab."""
    from nlos_cl.ops.opencl_backend import OpenCLBackend as Runtime
    tiny = Runtime(max_alloc_bytes=24_000)
    hist = histograms([(3.5, 1.2, 0.0)], [1.0], 3, 0.065, 0.02, 8)
    a = Locator(hist.layout, grid, search="exhaustive", backend=runtime, estimator="paper")(hist)
    plan = Locator(hist.layout, grid, search="exhaustive", backend=tiny, estimator="paper")
    for _ in range(2):  # the second frame reuses the plan's buffers
        b = plan(hist)
        assert np.array_equal(a.cell_position, b.cell_position) and a.score == b.score
        assert np.array_equal(a.position, b.position)
    assert len(plan._scores.slabs) > 1


@pytest.mark.parametrize("noise", [0.0, 0.1])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_long_window_bounds_with_block_maxima(runtime, noise, seed):
    """Many detectors (20: the host-side search, `run`) and a window longer than max_filter's
    one-launch form (a wide signal on 3 mm bins): the bound dilates block maxima on a coarser
    axis (search._bound_blocks) and the search still finds the exhaustive argmax, near-tied
    targets included (log scoring, as for any many-detector frame)."""
    from nlos_cl.localization import search
    hist = histograms([(4.0, 2.0, 0.0), (3.2, 2.9, 0.1)], [1.0, 0.98], 20, 0.15, noise, seed,
                      n_bins=6000)  # 18 m of path: both targets' paths from every spot
    grid = nl.Grid.from_ranges(x=(2.0, 6.0), y=(0.5, 4.0), step_m=0.01)
    plan = CoarseToFine(grid, np.array([1 / (nl.SPEED_OF_LIGHT * DT_S)]), 0.15)
    assert 2 * plan.half + 1 > search.DIRECT_MAX_WINDOW and plan.block > 1
    assert (plan.block_half - 1) * plan.block >= plan.half + 1
    how = same_answer(hist, grid, runtime, True, 0.15)
    assert how is not None and how.blocks > 0 and how.cells_scored < grid.n_cells / 4


@pytest.mark.parametrize("blocks", [True, False])
def test_the_bound_is_above_every_cell_of_its_block(runtime, blocks, monkeypatch):
    """The property the search rests on, checked cell by cell: each coarse block's bound (on
    the dilated record, or on dilated block maxima: search._bound_blocks) is at least the
    score of every fine cell in the block (SLACK: float32 rounding), where the block's
    centre is a fine cell. Many detectors, noise, a window of ~100 bins."""
    from nlos_cl.localization import search
    from nlos_cl.ops.signals import as_signals
    if not blocks:
        monkeypatch.setattr(search, "_bound_blocks", lambda half: (None, None))
    hist = histograms([(4.0, 2.0, 0.0), (3.2, 2.9, 0.1)], [1.0, 0.98], 20, 0.15, 0.1, 4,
                      n_bins=6000)
    grid = nl.Grid.from_ranges(x=(2.0, 4.5), y=(1.0, 3.5), step_m=0.01)
    plan = Locator(hist.layout, grid, search="exhaustive", log_mode=True, backend=runtime,
                   signal_width_m=0.15, estimator="paper")
    sig = as_signals(hist, runtime)
    args = plan._args(sig)
    fine = runtime.to_numpy(plan.scores(sig, args))[0]  # (ny, nx)
    c2f = CoarseToFine(grid, args[4], 0.15)
    assert (c2f.block is not None) == blocks
    rows, wide = c2f._bounding_rows(runtime, sig.handle, args)
    bound = runtime.to_numpy(c2f._score(runtime, "bound", rows, wide, c2f.coarse))[0]
    f = c2f.fa[0]
    ny, nx = fine.shape
    for j, i in zip(*np.nonzero(c2f.valid[0])):
        best = fine[j * f:min((j + 1) * f, ny), i * f:min((i + 1) * f, nx)].max()
        assert bound[j, i] >= best - search.SLACK * (abs(best) + 1.0), (j, i, bound[j, i], best)


@pytest.mark.parametrize("n_bins, half", [(6000, 49), (997, 120), (300, 33)])
def test_block_maxima_cover_every_window_between_their_samples(runtime, n_bins, half):
    """What `_bounding_rows` must give, at every point u of the record (in bins, and a block
    beyond its ends): the interpolation of the two bounding samples around u is at least the
    record's maximum over [floor(u) + 1 - half, floor(u) + half] (zero outside the record),
    which bounds any fine cell within half - 1 bins of u (module docstring). On noise, whose
    maxima change from bin to bin, and lone spikes on a negative floor, which only the
    windows reaching them may see: samples two blocks off, or a dilation a block short, fail."""
    from nlos_cl.localization import search
    rng = np.random.default_rng(half)
    record = rng.standard_normal((3, n_bins)).astype(np.float32)
    record[1] = -1.0  # all negative: the zeros outside the record must count
    record[1, np.arange(3, n_bins, 3 * half + 11)] = 5.0  # apart by more than a bound reaches
    plan = CoarseToFine(nl.Grid.from_ranges(step_m=0.01), np.array([1.0]), 0.065)
    plan.half = half
    plan.block, plan.block_half = search._bound_blocks(half)
    path0, inv = np.full(3, 0.25), np.full(3, 4.0)  # bin k at path 0.25 + k / 4
    rows, wide = plan._bounding_rows(runtime, runtime.from_numpy(record),
                                     (None, None, None, path0, inv, True, 0.0))
    rows = runtime.to_numpy(rows)
    padded = np.concatenate([np.zeros((3, half + 1)), record, np.zeros((3, half + 1))], axis=1)
    for u in np.arange(-plan.block, n_bins + plan.block, 0.25):
        k = int(np.floor(u))
        lo, hi = k + 1 - half, k + half  # the window, shifted into `padded`
        need = padded[:, max(lo + half + 1, 0):max(hi + half + 2, 0)].max(axis=1, initial=-np.inf)
        at = (path0 + u / inv - wide[3]) * wide[4]  # u on the bounding rows' axis
        i0 = np.floor(at).astype(int)
        t = at - i0
        value = [(1 - t[d]) * (rows[d, i0[d]] if 0 <= i0[d] < rows.shape[1] else 0.0)
                 + t[d] * (rows[d, i0[d] + 1] if 0 <= i0[d] + 1 < rows.shape[1] else 0.0)
                 for d in range(3)]
        assert np.all(np.asarray(value) >= need - 1e-6), (u, value, need)
