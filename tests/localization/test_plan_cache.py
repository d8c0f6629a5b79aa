"""nl.locate's plan cache (nlos_cl.localization.api.PLANS): a plan is reused for the same key,
built anew when any part of the key changes, bounded in number, and never gives a frame
another frame's answer."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.core.tuning import PLAN_CACHE
from nlos_cl.localization import api
from nlos_cl.localization.paper import PaperArgmax

C = nl.SPEED_OF_LIGHT
AXIS = nl.TimeAxis(2 * 20 / C + 25e-9, 10e-12, 1500)
GRID = nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0), step_m=0.02)


@pytest.fixture(scope="module")
def frames(runtime):
    """Two host frames of one wall layout, the target at two places (their truths differ)."""
    return [nl.simulate(nl.paper_scene(position=p, facet_size_m=0.02), AXIS,
                        backend=runtime).histograms() for p in ((4.0, 2.0, 0.0), (3.5, 2.5, 0.0))]


@pytest.fixture
def builds(monkeypatch):
    """The Locators nl.locate builds, on an empty cache (emptied again after the test)."""
    built = []

    class Counted(api.Locator):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            built.append(self)
    api.PLANS.clear()
    monkeypatch.setattr(api, "Locator", Counted)
    yield built
    api.PLANS.clear()


def locate(hist, runtime, **kw):
    kw = {"grid": GRID, "estimator": "paper", "backend": runtime, **kw}
    return nl.locate(nl.gauss_filter(hist, backend=kw["backend"]), kw.pop("grid"), **kw)


def test_the_same_key_reuses_one_plan(frames, runtime, builds):
    first = locate(frames[0], runtime)
    again = locate(frames[0], runtime)  # a new upload: a new Layout object, equal content
    assert len(builds) == 1 and len(api.PLANS) == 1
    np.testing.assert_array_equal(first.position, again.position)


def unshared(hist, runtime, grid=GRID, estimator="paper", backend=None, search="coarse_to_fine",
             **kw):
    """What a Locator of its own (nl.locate's defaults) gives."""
    sig = nl.gauss_filter(hist, backend=backend or runtime)
    return nl.Locator(sig.layout, grid, estimator=estimator, search=search, **kw)(sig)


def other_layout(hist):
    """The same frame recorded with the laser spot 10 cm along the wall."""
    return nl.HistogramSet(hist.data, hist.time_axis, hist.detector_spots,
                           hist.laser_spot + [0.1, 0.0, 0.0], hist.calibration, truth=hist.truth)


@pytest.mark.parametrize("change", ["layout", "grid", "estimator", "log_mode", "search",
                                    "signal_width_m", "backend"])
def test_any_change_of_the_key_builds_a_new_plan(frames, runtime, builds, change):
    hist, kw = frames[0], {}
    if change == "layout":
        hist = other_layout(hist)
    else:
        kw = {"grid": nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0), step_m=0.04),
              "estimator": PaperArgmax(), "log_mode": True, "search": "exhaustive",
              "signal_width_m": 0.1, "backend": nl.NumpyBackend()}
        kw = {change: kw[change]}
    locate(frames[0], runtime)
    changed = locate(hist, runtime, **kw)
    assert len(builds) == 2
    np.testing.assert_allclose(changed.position, unshared(hist, runtime, **kw).position,
                               rtol=0, atol=1e-9)  # the moved laser spot's answer too
    locate(hist, runtime, **kw)  # that key again: its plan, not a third
    assert len(builds) == 2


def test_an_estimator_object_is_keyed_by_identity(frames, runtime, builds):
    one, other = PaperArgmax(), PaperArgmax()
    for estimator in (one, one, other, one):
        locate(frames[0], runtime, estimator=estimator)
    assert len(builds) == 2 and builds[0].estimator is one and builds[1].estimator is other


def test_the_cache_keeps_the_most_recently_used(frames, runtime, builds):
    grids = [nl.Grid.from_ranges(x=(3.0, 5.0), y=(1.0, 3.0 + 0.02 * k), step_m=0.02)
             for k in range(PLAN_CACHE + 3)]
    for grid in grids:
        locate(frames[0], runtime, grid=grid)
        locate(frames[0], runtime, grid=grids[0])  # kept in use: never the oldest
    assert len(api.PLANS) == PLAN_CACHE and len(builds) == len(grids)
    locate(frames[0], runtime, grid=grids[-1])
    assert len(builds) == len(grids)  # still cached
    locate(frames[0], runtime, grid=grids[1])  # evicted long ago: built again
    assert len(builds) == len(grids) + 1 and len(api.PLANS) == PLAN_CACHE


def test_a_plan_in_use_is_out_of_the_cache(frames, runtime, builds):
    """Taken while a call runs, so a concurrent caller builds its own instead of sharing
    the plan's buffers."""
    locate(frames[0], runtime)
    sig = nl.gauss_filter(frames[0], backend=runtime)
    key = api._plan_key(sig, GRID, "paper", False, "coarse_to_fine", None)
    plan = api.PLANS.take(key, sig.backend, "paper")
    assert plan is builds[0] and len(api.PLANS) == 0
    assert api.PLANS.take(key, sig.backend, "paper") is None
    api.PLANS.give(key, plan, sig.backend)
    assert len(api.PLANS) == 1


@pytest.mark.parametrize("estimator", ["paper", None])  # None: the default, the model fit
def test_a_cached_plan_gives_each_frame_its_own_answer(frames, runtime, builds, estimator):
    results = []
    for hist in frames + frames[:1]:
        raw = nl.upload(hist, runtime)
        results.append(nl.locate(nl.gauss_filter(raw), GRID, estimator=estimator, raw=raw,
                                 return_map=estimator == "paper"))
    assert len(builds) == 1
    first, second, third = results
    for loc, hist in zip(results[:2], frames):  # the third is the first frame again (below)
        np.testing.assert_array_equal(loc.truth, hist.truth)  # the frame's truth, not the plan's
        raw = nl.upload(hist, runtime)
        alone = nl.Locator(raw.layout, GRID, estimator=estimator, search="coarse_to_fine")(
            nl.gauss_filter(raw), raw=raw)
        np.testing.assert_allclose(loc.position, alone.position, rtol=0, atol=1e-9)
        assert loc.error_m < 0.15  # near its own target (the paper's argmax is biased here)
    np.testing.assert_array_equal(third.truth, frames[0].truth)
    assert np.linalg.norm(first.position - second.position) > 0.5
    np.testing.assert_array_equal(first.position, third.position)
    if first.score_map is not None:  # the first answer's map is its own, unchanged
        np.testing.assert_array_equal(first.score_map, third.score_map)
        assert not np.array_equal(first.score_map, second.score_map)
