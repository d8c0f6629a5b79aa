"""Trajectories (piecewise-linear waypoints) and targets that follow them."""
import numpy as np
import pytest

import nlos_cl as nl
from nlos_cl.tracking import MovingTarget, Trajectory, frame_seed


def test_interpolates_between_waypoints_and_holds_outside():
    tr = Trajectory([0, 2, 4], [[2, 4, 0], [4, 4, 0], [4, 2, 1]])
    np.testing.assert_allclose(tr.at(1.0), [3, 4, 0])
    np.testing.assert_allclose(tr.at(3.0), [4, 3, 0.5])
    np.testing.assert_allclose(tr.at(-1.0), [2, 4, 0])
    np.testing.assert_allclose(tr.at(9.0), [4, 2, 1])
    np.testing.assert_allclose(tr.velocity(0.5), [1, 0, 0])
    np.testing.assert_allclose(tr.velocity(5.0), [0, 0, 0])
    assert tr.duration_s == 4.0


def test_single_waypoint_and_mapping():
    tr = Trajectory.from_mapping({"t_s": [0, 5], "positions": [[2, 4, 0], [5, 1, 0]]})
    np.testing.assert_allclose(tr.at(2.5), [3.5, 2.5, 0])
    still = Trajectory(0.0, [3, 2, 0])
    np.testing.assert_allclose(still.at(7), [3, 2, 0])


@pytest.mark.parametrize("t, p, field", [
    ([0, 0], [[1, 1, 0], [2, 1, 0]], "trajectory.t_s"),
    ([1, 0], [[1, 1, 0], [2, 1, 0]], "trajectory.t_s"),
    ([0, np.nan], [[1, 1, 0], [2, 1, 0]], "trajectory.t_s"),
    ([0, 1], [[1, 1, 0]], "trajectory.positions"),
    ([0, 1], [[1, 1], [2, 1]], "trajectory.positions"),
    ([0, 1], [[1, 1, 0], [2, -1, 0]], "trajectory.positions"),
    ([0, 1], [[1, 1, 0], [2, 1, np.inf]], "trajectory.positions"),
    ([], [], "trajectory.t_s"),
])
def test_bad_trajectories_name_the_field(t, p, field):
    with pytest.raises(nl.InputError, match=field.replace(".", r"\.")):
        Trajectory(t, p)


def test_bad_time_and_mapping():
    tr = Trajectory([0, 1], [[1, 1, 0], [2, 1, 0]])
    with pytest.raises(nl.InputError, match="^t:"):
        tr.at(float("nan"))
    with pytest.raises(nl.InputError, match="trajectory"):
        Trajectory.from_mapping({"positions": [[1, 1, 0]]})


def test_moving_target_centre_follows_the_trajectory():
    mesh = nl.rectangle(0.3, 0.6, centre=(3, 2, 0), cell_m=0.1)
    mt = MovingTarget(nl.Target(mesh), Trajectory([0, 1], [[2, 3, 0.2], [4, 3, 0.2]]))
    placed = mt.placed(0.5)
    np.testing.assert_allclose(placed.mesh.bounds.mean(axis=0), [3, 3, 0.2], atol=1e-12)
    np.testing.assert_allclose(mesh.bounds.mean(axis=0), [3, 2, 0])  # the caller's mesh kept
    with pytest.raises(nl.InputError, match="moving.target"):
        MovingTarget(mesh, mt.trajectory)


def test_frame_seeds_are_deterministic_and_distinct():
    seeds = [frame_seed(3, k) for k in range(100)]
    assert seeds == [frame_seed(3, k) for k in range(100)]
    assert len(set(seeds)) == 100 and frame_seed(4, 0) != seeds[0]
