"""OMPL joint planning: straight moves shortcut, blocked moves go around, failures are reported."""

from __future__ import annotations

import time

import numpy as np
import pytest

from at_ros.ompl_planner import JointPlanner, PlanningFailed, segment_is_valid


def _wall_checker(q: np.ndarray) -> bool:
    # A wall across joint 0 in [-0.3, 0.3] unless joint 1 is above 1.0.
    return not (abs(q[0]) < 0.3 and q[1] < 1.0)


def test_free_straight_move_needs_no_search() -> None:
    planner = JointPlanner(-np.ones(3) * 3, np.ones(3) * 3, lambda q: True)
    path = planner.plan(np.zeros(3), np.ones(3), time_limit=1.0, simplify_time=0.1)
    assert len(path) == 2


def test_blocked_move_goes_around_and_every_state_is_valid() -> None:
    planner = JointPlanner(-np.ones(3) * 3, np.ones(3) * 3, _wall_checker, resolution=0.02, seed=5)
    start, goal = np.array([-1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    path = planner.plan(start, goal, time_limit=2.0, simplify_time=0.2)
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], goal)
    for a, b in zip(path, path[1:], strict=False):
        assert segment_is_valid(a, b, _wall_checker, 0.02)
    assert max(q[1] for q in path) >= 1.0


@pytest.mark.parametrize(
    ("start", "goal", "message"),
    [([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], "start state"), ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0], "goal state")],
)
def test_invalid_endpoints_are_named(start: list[float], goal: list[float], message: str) -> None:
    planner = JointPlanner(-np.ones(3) * 3, np.ones(3) * 3, _wall_checker)
    with pytest.raises(PlanningFailed, match=message):
        planner.plan(np.array(start), np.array(goal), time_limit=0.5, simplify_time=0.1)


def test_enclosed_goal_fails_after_the_time_limit() -> None:
    def boxed(q: np.ndarray) -> bool:
        inside = np.all(np.abs(q - 2.0) < 0.5)
        shell = np.all(np.abs(q - 2.0) < 0.8) and not np.all(np.abs(q - 2.0) < 0.6)
        return bool(not shell) or bool(inside)

    planner = JointPlanner(-np.ones(3) * 3, np.ones(3) * 3, boxed)
    with pytest.raises(PlanningFailed, match="no collision-free joint path"):
        planner.plan(np.zeros(3), np.full(3, 2.0), time_limit=0.3, simplify_time=0.1)


def test_the_time_limit_is_the_planners_own_cpu_time_not_the_wall_clock() -> None:
    """A starved planner (here: each check waits 1 ms off the CPU, as a thread descheduled by
    other work) still gets its whole budget: the same blocked move is found although its wall
    time runs far past the limit."""
    checks = 0

    def starved(q: np.ndarray) -> bool:
        nonlocal checks
        checks += 1
        time.sleep(0.001)  # off the CPU: the stand-in for a busy machine, not a synchronisation
        return _wall_checker(q)

    planner = JointPlanner(-np.ones(3) * 3, np.ones(3) * 3, starved, resolution=0.02, seed=5)
    began = time.perf_counter()
    path = planner.plan(np.array([-1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), time_limit=0.3, simplify_time=0.0)
    waited = time.perf_counter() - began
    assert max(q[1] for q in path) >= 1.0
    # a wall-clock limit would have stopped it after 0.3 s, with at most 300 checks made
    assert checks > 0.3 / 0.001 and waited > 0.3, (checks, waited)
