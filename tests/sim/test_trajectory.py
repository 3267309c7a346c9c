"""Trajectory validation and sampling (sim.trajectory), without a simulator."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest

from sim.trajectory import ErrorCode, JointLimit, Trajectory, TrajectoryError, validate_trajectory

JOINTS = ("a", "b")
LIMITS = {"a": JointLimit(-1.0, 1.0, 1.0), "b": JointLimit(-2.0, 2.0, 0.5), "finger": JointLimit(0.0, 0.04, 0.1)}


def validate(
    names: Sequence[str], points: list[tuple[float, list[float], list[float]]], current: tuple[float, ...] = (0.0, 0.0)
) -> Trajectory:
    return validate_trajectory(
        list(names), points, limits=LIMITS, controller_joints=JOINTS, current=current, other_joints=("finger",)
    )


def test_implicit_start_and_linear_sampling() -> None:
    traj = validate(["b", "a"], [(1.0, [0.4, 0.5], [])])
    assert traj.times == (0.0, 1.0)
    assert traj.positions == ((0.0, 0.0), (0.5, 0.4))
    pos, vel = traj.sample(0.5)
    assert pos == pytest.approx((0.25, 0.2))
    assert vel == pytest.approx((0.5, 0.4))
    assert traj.sample(2.0)[0] == (0.5, 0.4)


def test_hermite_sampling_matches_end_points_and_velocities() -> None:
    traj = validate(JOINTS, [(0.0, [0.0, 0.0], [0.0, 0.0]), (1.0, [0.5, 0.2], [0.0, 0.0])])
    assert traj.sample(0.0)[0] == pytest.approx((0.0, 0.0))
    assert traj.sample(0.5)[0] == pytest.approx((0.25, 0.1))
    assert traj.sample(0.5)[1][0] == pytest.approx(0.75)  # peak of the cubic: 1.5 × average speed
    assert traj.sample(1.0)[0] == pytest.approx((0.5, 0.2))


@pytest.mark.parametrize(
    "names, points, code, text",
    [
        (["a", "z"], [(1.0, [0, 0], [])], ErrorCode.INVALID_JOINTS, "unknown joint 'z'"),
        (["finger"], [(1.0, [0.01], [])], ErrorCode.INVALID_JOINTS, "not an arm joint"),
        (["a", "a"], [(1.0, [0, 0], [])], ErrorCode.INVALID_JOINTS, "repeat"),
        ([], [], ErrorCode.INVALID_JOINTS, "no joints"),
        (["a"], [], ErrorCode.INVALID_GOAL, "no points"),
        (["a"], [(1.0, [math.inf], [])], ErrorCode.INVALID_GOAL, "non-finite"),
        (["a"], [(math.nan, [0.1], [])], ErrorCode.INVALID_GOAL, "time_from_start is nan"),
        (["a"], [(1.0, [0.1, 0.2], [])], ErrorCode.INVALID_GOAL, "2 positions for 1 joints"),
        (["a"], [(3.0, [1.5], [])], ErrorCode.INVALID_GOAL, "outside its limits"),
        (["b"], [(1.0, [1.0], [])], ErrorCode.INVALID_GOAL, "over its velocity limit 0.5000"),
        (["a"], [(1.0, [0.5], [2.0])], ErrorCode.INVALID_GOAL, "exceeds its limit"),
        (["a"], [(1.0, [0.1], []), (0.5, [0.2], [])], ErrorCode.INVALID_GOAL, "must increase"),
        (["a"], [(-1.0, [0.1], [])], ErrorCode.INVALID_GOAL, "negative"),
        (["a"], [(0.0, [0.5], [])], ErrorCode.INVALID_GOAL, "away from the current position"),
    ],
)
def test_invalid_trajectories_are_refused_with_their_reason(
    names: Sequence[str], points: list[tuple[float, list[float], list[float]]], code: int, text: str
) -> None:
    with pytest.raises(TrajectoryError) as err:
        validate(names, points)
    assert err.value.code == code
    assert text in str(err.value)


def test_velocity_exactly_at_the_limit_passes() -> None:
    traj = validate(["b"], [(2.0, [1.0], [])])
    assert traj.duration == 2.0
