"""IK per waypoint: accurate, within limits, nearest to the previous state, failures explained."""

from __future__ import annotations

import numpy as np

from at_ros.ik import IkFailure, IkSolver
from at_ros.transforms import angle_between, from_xyz_rpy

from conftest import UR10_START


def test_reaches_a_pose_within_limits_and_near_the_seed(iva_scene) -> None:
    solver = IkSolver(iva_scene, rng=np.random.default_rng(3))
    target = iva_scene.forward(UR10_START) @ from_xyz_rpy([0.05, -0.05, 0.08], [0.1, 0.0, 0.2])
    q = solver.solve(target, UR10_START)
    assert not isinstance(q, IkFailure)
    assert iva_scene.within_limits(q)
    reached = iva_scene.forward(q)
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-4
    assert angle_between(reached, target) < 1e-3
    assert np.max(np.abs(q - UR10_START)) < 1.0  # same arm configuration, not a flipped one


def test_out_of_reach_is_reported_with_the_error(iva_scene) -> None:
    solver = IkSolver(iva_scene, seeds=4)
    failure = solver.solve(from_xyz_rpy([3.0, 0.0, 1.0], [0, 0, 0]), UR10_START)
    assert isinstance(failure, IkFailure)
    assert "unreachable" in failure.describe() and failure.position_error > 1.0


def test_wrap_into_limits_picks_the_turn_nearest_the_reference(iva_scene) -> None:
    solver = IkSolver(iva_scene)
    q = np.array([-1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    near = np.array([5.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    wrapped = solver.wrap_into_limits(q, near)
    assert abs(wrapped[0] - (-1.0 + 2 * np.pi)) < 1e-9
    # The elbow (limits +-pi) has no other turn inside its limits.
    assert solver.wrap_into_limits(np.array([0, 0, 3.0, 0, 0, 0.0]), np.array([0, 0, -3.0, 0, 0, 0.0]))[2] == 3.0
