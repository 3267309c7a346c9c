"""get_plan's joined trajectory: segments end to end, times running on, waypoint indices."""

from __future__ import annotations

import pytest
from affordance_template_msgs.msg import PlannedSegment
from builtin_interfaces.msg import Duration
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from at_ros.instance import InstanceError
from at_ros.plan_view import joined_trajectory

JOINTS = ("a", "b")


def _segment(label: str, points: list[tuple[float, list[float]]], joints: tuple[str, ...] = JOINTS) -> PlannedSegment:
    segment = PlannedSegment(label=label, arm_trajectory=JointTrajectory(joint_names=list(joints)))
    for t, q in points:
        ns = int(round(t * 1e9))
        segment.arm_trajectory.points.append(
            JointTrajectoryPoint(positions=q, time_from_start=Duration(sec=ns // 10**9, nanosec=ns % 10**9))
        )
    return segment


def _seconds(point: JointTrajectoryPoint) -> float:
    return point.time_from_start.sec + point.time_from_start.nanosec * 1e-9


def test_segments_join_end_to_end_and_each_waypoint_has_its_point() -> None:
    segments = [
        _segment("0.0", [(0.0, [0, 0]), (1.0, [1, 0]), (2.5, [1, 1])]),
        _segment("0.1", [(0.0, [1, 1]), (0.5, [1, 2])]),
        _segment("0.2", []),  # a gripper motion only: reached where the last ended
        _segment("0.3", [(0.0, [1, 2]), (1.0, [0, 2])]),
    ]
    joined, ends = joined_trajectory(segments, JOINTS)
    assert joined.joint_names == list(JOINTS)
    assert [list(p.positions) for p in joined.points] == [[0, 0], [1, 0], [1, 1], [1, 2], [0, 2]]
    assert [_seconds(p) for p in joined.points] == pytest.approx([0.0, 1.0, 2.5, 3.0, 4.0])
    assert ends == [2, 3, 3, 4]


def test_a_segment_of_other_joints_is_refused_by_name() -> None:
    with pytest.raises(InstanceError, match=r"waypoint 0.1: the planner's joints \['x', 'y'\]"):
        joined_trajectory([_segment("0.0", [(0.0, [0, 0])]), _segment("0.1", [(0.0, [0, 0])], ("x", "y"))], JOINTS)
