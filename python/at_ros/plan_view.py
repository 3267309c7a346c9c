"""``get_plan``: a plan whole, for a view to show the motion before the operator executes it.

The original AT streamed its plan to RViz as a ghost robot; here a view (the ground's 3D view,
across the link) asks once per plan: ``ServerStatus.plan_id`` changes with every plan, and
``get_plan`` answers with the waypoints' arm motions joined into one joint trajectory, where
each waypoint is reached, the gripper pose taken there, the tool's pose at the end (the
planner's forward kinematics) and what became of the plan (planned, executed, halted, dropped
and why).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from affordance_template_msgs.srv import GetPlan
from builtin_interfaces.msg import Duration, Time
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from at_ros.frames import WORLD_FRAME, UnknownFrame
from at_ros.instance import InstanceError, PlanState
from at_ros.messages import matrix_from_pose, pose_from_matrix
from at_ros.server_core import ServerCore
from at_ros.transforms import invert

__all__ = ["PlanQueries", "joined_trajectory"]


def _seconds(d: Duration) -> float:
    return float(d.sec + d.nanosec * 1e-9)


def _duration(t: float) -> Duration:
    ns = int(round(t * 1e9))
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _time(t: float) -> Time:
    ns = int(round(t * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joined_trajectory(segments: list[Any], joint_names: tuple[str, ...]) -> tuple[JointTrajectory, list[int]]:
    """The arm trajectories of ``segments`` (PlannedSegment) as one, times running on from one to
    the next, and the index of the point where each segment ends (-1: before any point).

    A segment's first point at time 0 is the previous segment's last and is not repeated, so
    times strictly increase; a segment without motion reaches its waypoint where the last ended.
    """
    joined = JointTrajectory()
    joined.joint_names = list(joint_names)
    ends: list[int] = []
    offset = 0.0
    for segment in segments:
        trajectory = segment.arm_trajectory
        if trajectory.points and list(trajectory.joint_names) != joined.joint_names:
            raise InstanceError(
                f"waypoint {segment.label}: the planner's joints {list(trajectory.joint_names)} "
                f"are not the robot's {joined.joint_names}"
            )
        for k, point in enumerate(trajectory.points):
            t = _seconds(point.time_from_start)
            if k == 0 and t == 0.0 and joined.points:
                continue
            joined.points.append(
                JointTrajectoryPoint(
                    positions=list(point.positions),
                    velocities=list(point.velocities),
                    time_from_start=_duration(offset + t),
                )
            )
        if trajectory.points:
            offset += _seconds(trajectory.points[-1].time_from_start)
        ends.append(len(joined.points) - 1)
    return joined, ends


class PlanQueries:
    """The ``get_plan`` service on one :class:`ServerCore`."""

    def __init__(self, core: ServerCore) -> None:
        self.core = core

    def get_plan(self, request: GetPlan.Request, response: GetPlan.Response) -> Any:
        core = self.core
        instance = core.instance_named(request.name)
        if request.trajectory_name:
            instance.trajectory(request.trajectory_name)  # an unknown name says which exist
        with core.state_lock:
            plan = instance.last_plan(request.trajectory_name)
            if plan is None:
                which = f" of {request.trajectory_name!r}" if request.trajectory_name else ""
                raise InstanceError(f"{instance.key} has no plan{which} yet; call plan_command first")
            stale = (
                core.stale_reason(instance, plan) if plan.state == PlanState.PLANNED and instance.plan is plan else None
            )
            response.plan_id = plan.plan_id
            response.state = plan.state
            response.valid = plan.state == PlanState.PLANNED and instance.plan is plan and stale is None
            response.state_reason = stale or plan.state_reason
            response.planned_at = _time(plan.planned_at)
            response.state_since = _time(plan.state_since)
            response.trajectory_name = plan.trajectory
            response.end_effector = plan.end_effector
            segments = list(plan.segments)
        response.trajectory, response.waypoint_point_index = joined_trajectory(segments, core.robot.joint_names)
        response.waypoint_names = [s.label for s in segments]
        response.end_effector_poses = [s.end_effector_pose for s in segments]
        response.end_pose_link = core.robot.tool_link
        end_world = matrix_from_pose(segments[-1].tool_pose)
        try:
            frame, frame_pose = core.robot.frame_id, core.frames.lookup(core.robot.frame_id)
        except UnknownFrame:
            frame, frame_pose = WORLD_FRAME, np.eye(4)
        response.end_pose.header.frame_id = frame
        response.end_pose.pose = pose_from_matrix(invert(frame_pose) @ end_world)
        response.success = True
        response.message = f"plan {plan.plan_id} of {plan.trajectory!r} of {instance.key}: {plan.state.lower()}"
        return response
