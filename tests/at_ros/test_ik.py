"""IK per waypoint: accurate, within limits, nearest to the previous state, failures explained."""

from __future__ import annotations

import re

import numpy as np

from at_ros.ik import IkFailure, IkSolver
from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import RobotConfig
from at_ros.transforms import angle_between, from_xyz_rpy
from support.planning_scenes import UR10_START, bench_planning_scene


def test_reaches_a_pose_within_limits_and_near_the_seed(iva_scene: PlanningScene) -> None:
    solver = IkSolver(iva_scene, rng=np.random.default_rng(3))
    target = iva_scene.forward(UR10_START) @ from_xyz_rpy([0.05, -0.05, 0.08], [0.1, 0.0, 0.2])
    q = solver.solve(target, UR10_START)
    assert not isinstance(q, IkFailure)
    assert iva_scene.within_limits(q)
    reached = iva_scene.forward(q)
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-4
    assert angle_between(reached, target) < 1e-3
    assert np.max(np.abs(q - UR10_START)) < 1.0  # same arm configuration, not a flipped one


def test_out_of_reach_is_reported_as_reach_alone(iva_scene: PlanningScene) -> None:
    solver = IkSolver(iva_scene, seeds=4)
    failure = solver.solve(from_xyz_rpy([3.0, 0.0, 1.0], [0, 0, 0]), UR10_START)
    assert isinstance(failure, IkFailure)
    assert failure == IkFailure(collision=None, beyond_limits=())  # neither limits nor a collision is blamed
    assert failure.describe() == "is out of reach"


def test_wrap_into_limits_picks_the_turn_nearest_the_reference(iva_scene: PlanningScene) -> None:
    solver = IkSolver(iva_scene)
    q = np.array([-1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    near = np.array([5.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    wrapped = solver.wrap_into_limits(q, near)
    assert abs(wrapped[0] - (-1.0 + 2 * np.pi)) < 1e-9
    # The elbow (limits +-pi) has no other turn inside its limits.
    assert solver.wrap_into_limits(np.array([0, 0, 3.0, 0, 0, 0.0]), np.array([0, 0, -3.0, 0, 0, 0.0]))[2] == 3.0


#: The bench arm's start (tests/fixtures/bench_arm/workbench.yaml): wrist pitch 0.25, near the
#: lower end of its one-sided range [0.2, 2.1].
BENCH_START = np.array([0.0, 0.3, 1.9, 0.0, 0.25, 0.0])
#: A grasp pose in front of shelf slot A: tool z along +x, 0.3 m before the part.
BENCH_GOAL = from_xyz_rpy([0.5, -0.25, 1.04], [0.0, np.pi / 2, 0.0])


def test_a_range_that_excludes_the_nearest_solution_is_solved_inside_it() -> None:
    config, scene = bench_planning_scene()
    try:
        solver = IkSolver(scene, seeds=32)
        natural = solver._unconstrained(BENCH_GOAL, BENCH_START)
        pitch = config.joint_names.index("wrist_pitch_joint")
        assert natural[pitch] < scene.limits.lower[pitch]  # what a solver ignoring limits answers
        q = solver.solve(BENCH_GOAL, BENCH_START)
        assert isinstance(q, np.ndarray) and scene.within_limits(q)
        assert np.linalg.norm(scene.forward(q)[:3, 3] - BENCH_GOAL[:3, 3]) < 1e-3
        assert q[pitch] > 0.2  # the flipped wrist
    finally:
        scene.close()


def test_a_pose_reachable_only_outside_the_limits_names_the_limit(
    narrow_wrist_bench: tuple[RobotConfig, PlanningScene],
) -> None:
    config, scene = narrow_wrist_bench
    failure = IkSolver(scene, seeds=16).solve(BENCH_GOAL, BENCH_START)
    assert isinstance(failure, IkFailure) and failure.collision is None
    assert re.search(
        r"^is reachable only outside the joint limits \(wrist_(pitch|roll)_joint would be -?\d+\.\d\d rad, "
        r"beyond its (lower|upper) limit -?\d+\.\d\d rad(, |\)$)",
        failure.describe(),
    ), failure.describe()
    for excess in failure.beyond_limits:  # each joint named is beyond the limit it is said to pass
        i = config.joint_names.index(excess.joint)
        limit = scene.limits.upper[i] if excess.upper else scene.limits.lower[i]
        assert excess.limit == limit and (excess.value > limit if excess.upper else excess.value < limit)


def test_a_line_that_runs_into_a_limit_names_the_joint() -> None:
    _, scene = bench_planning_scene()
    try:
        solver = IkSolver(scene)
        q = np.array([0.0, 0.6, 0.3, 0.0, 1.0, 0.0])  # elbow near its lower limit 0.25: the arm almost straight
        pose = scene.forward(q)
        reach = pose.copy()
        reach[:3, 3] += 0.05 * (pose[:3, 3] - scene.forward(np.zeros(6))[:3, 3]) / np.linalg.norm(pose[:3, 3])
        assert solver.track(reach, q, 1e-3, 1e-2) is None
        assert solver.blocked_by is not None and "elbow_joint at its lower limit 0.25 rad" in solver.blocked_by
    finally:
        scene.close()
