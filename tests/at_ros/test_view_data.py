"""What a 3D view needs from the robot side (issue 17), from the real stack: the robot's URDF,
the running template's display objects and waypoints in a named frame, and the plan whole
(``get_plan``), checked against forward kinematics computed here with pybullet."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator

import numpy as np
import pybullet as p
import pytest
from affordance_template_msgs.srv import GetPlan
from at_client import AtClient
from geometry_msgs.msg import Pose
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from at_ros.messages import matrix_from_pose
from at_ros.robot_config import load_robot_configs
from at_ros.transforms import from_xyz_rpy
from support.at_server import start_stack

pytestmark = [pytest.mark.ros, pytest.mark.slow]

DIRTY = "CDRA-F-0007"
ARM = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
#: A registration an operator might make by dragging: 2 cm along the slot, 3 degrees of yaw.
OFFSET = from_xyz_rpy([0.0, 0.02, 0.0], [0.0, 0.0, math.radians(3.0)])


@pytest.fixture(scope="module")
def at(ros_env: dict[str, str]) -> Iterator[AtClient]:
    yield from start_stack(ros_env, "iva", 0.0)


def _pose(matrix: np.ndarray) -> Pose:
    from at_ros.messages import pose_from_matrix

    return pose_from_matrix(matrix)


def _close(a: np.ndarray, b: np.ndarray, metres: float, radians: float) -> bool:
    turn = np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2, -1.0, 1.0)
    return bool(np.linalg.norm(a[:3, 3] - b[:3, 3]) <= metres and math.acos(turn) <= radians)


def _forward(joints: list[str], positions: list[float], link: str) -> np.ndarray:
    """The link's pose in the robot's root frame: the UR10's URDF in a pybullet client of our own."""
    client = p.connect(p.DIRECT)
    try:
        robot = p.loadURDF(
            str(load_robot_configs()["ur10"].urdf), [0, 0, 0], [0, 0, 0, 1], useFixedBase=True, physicsClientId=client
        )
        index = {
            p.getJointInfo(robot, j, physicsClientId=client)[1].decode(): j
            for j in range(p.getNumJoints(robot, physicsClientId=client))
        }
        links = {
            p.getJointInfo(robot, j, physicsClientId=client)[12].decode(): j
            for j in range(p.getNumJoints(robot, physicsClientId=client))
        }
        for name, q in zip(joints, positions, strict=False):
            p.resetJointState(robot, index[name], q, physicsClientId=client)
        state = p.getLinkState(robot, links[link], computeForwardKinematics=True, physicsClientId=client)
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = state[4]
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = state[5]
        return matrix_from_pose(pose)
    finally:
        p.disconnect(client)


def test_robot_description_is_the_urdf_with_the_arm_joints(at: AtClient) -> None:
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
    got: list[str] = []
    at.node.create_subscription(String, "/robot_description", lambda m: (got.append(m.data), at._notify()), latched)
    at.wait_for(lambda: bool(got), 30, "robot_description")
    urdf = ET.fromstring(got[0])
    assert urdf.tag == "robot" and urdf.get("name") == "ur10_gripper"
    assert set(ARM) <= {j.get("name") for j in urdf.iter("joint") if j.get("type") == "revolute"}


def test_template_status_gives_display_objects_and_waypoints_in_the_frame_asked(at: AtClient) -> None:
    added = at.call("add_template", class_type="cdra_filter")
    try:
        assert at.register("cdra_filter", added.id, "cdra_filter", f"filter/{DIRTY}", _pose(OFFSET)).success
        in_filter = at.call(
            "get_template_status", name=added.instance, trajectory_name="grasp_and_pull", frame_id=f"filter/{DIRTY}"
        ).affordance_template_status[0]
        obj = in_filter.object_info[0]
        assert obj.object_name == f"cdra_filter:{added.id}" and obj.object_pose.header.frame_id == f"filter/{DIRTY}"
        assert _close(matrix_from_pose(obj.object_pose.pose), OFFSET, 1e-3, 1e-3)
        assert obj.type == "box" and (obj.size.x, obj.size.y, obj.size.z) == pytest.approx((0.2, 0.14, 0.1))
        assert (
            list(obj.rgba) == pytest.approx([0.2, 0.9, 0.3, 0.5])
            and list(obj.controls) == [True] * 6
            and obj.parent == ""
        )
        filter_world = matrix_from_pose(at.fresh_frames()[f"filter/{DIRTY}"])
        in_world = at.call(
            "get_template_status", name=added.instance, trajectory_name="grasp_and_pull", frame_id="world"
        ).affordance_template_status[0]
        assert in_world.object_info[0].object_pose.header.frame_id == "world"
        assert _close(matrix_from_pose(in_world.object_info[0].object_pose.pose), filter_world @ OFFSET, 1e-3, 1e-3)
        info = in_world.waypoint_info[0]
        assert list(info.waypoint_names) == [f"0.{i}:{added.instance}" for i in range(4)]
        assert list(info.end_effector_pose_names) == ["open", "open", "closed", "closed"]
        # Waypoint 0 is 32 cm in front of the object, as the template states it.
        first = np.linalg.inv(filter_world @ OFFSET) @ matrix_from_pose(info.waypoint_poses[0].pose)
        assert first[:3, 3] == pytest.approx([-0.32, 0.0, 0.0], abs=1e-6)
        unknown = at.call("get_template_status", name=added.instance, frame_id="nowhere")
        assert not unknown.success and "nowhere" in unknown.message
    finally:
        at.call("delete_template", class_type="cdra_filter", id=added.id)


def test_get_plan_is_the_whole_motion_and_follows_what_becomes_of_it(at: AtClient) -> None:
    added = at.call("add_template", class_type="cdra_filter")
    name = added.instance
    try:
        none = at.call("get_plan", name=name, trajectory_name="grasp_and_pull")
        assert not none.success and "no plan" in none.message
        assert at.register("cdra_filter", added.id, "cdra_filter", f"filter/{DIRTY}").success
        assert at.call("plan_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull").success
        plan = at.call("get_plan", name=name, trajectory_name="")
        assert plan.success, plan.message
        assert plan.state == GetPlan.Response.PLANNED and plan.valid and plan.trajectory_name == "grasp_and_pull"
        at.wait_for(lambda: at.status.plan_id == plan.plan_id, 10, "the plan's id on the status topic")

        points = plan.trajectory.points
        assert list(plan.trajectory.joint_names) == ARM and len(points) > 4
        times = [pt.time_from_start.sec + pt.time_from_start.nanosec * 1e-9 for pt in points]
        assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:], strict=False))
        assert list(plan.waypoint_names) == [f"0.{i}:{name}" for i in range(4)]
        indices = list(plan.waypoint_point_index)
        assert (
            len(indices) == 4
            and all(0 <= i < len(points) for i in indices)
            and indices == sorted(indices)
            and indices[-1] == len(points) - 1
        )
        assert list(plan.end_effector_poses) == ["open", "open", "closed", "closed"]

        # The end pose is the tool link at the last point, in the robot's frame ...
        assert plan.end_pose_link == "tool0" and plan.end_pose.header.frame_id == "robot_base"
        end = matrix_from_pose(plan.end_pose.pose)
        assert _close(_forward(ARM, list(points[-1].positions), "tool0"), end, 1e-4, 1e-4)
        # ... at the last waypoint, and each waypoint's point is where the tool reaches it.
        status = at.call(
            "get_template_status", name=name, trajectory_name="grasp_and_pull", frame_id="robot_base"
        ).affordance_template_status[0]
        for index, waypoint in zip(indices, status.waypoint_info[0].waypoint_poses, strict=False):
            assert _close(
                _forward(ARM, list(points[index].positions), "tool0"), matrix_from_pose(waypoint.pose), 1e-3, 5e-3
            )

        again = at.call("plan_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull")
        assert again.success
        second = at.call("get_plan", name=name, trajectory_name="grasp_and_pull")
        assert second.plan_id != plan.plan_id and second.valid
        assert at.register("cdra_filter", added.id, "cdra_filter", f"filter/{DIRTY}", _pose(OFFSET)).success
        dropped = at.call("get_plan", name=name, trajectory_name="grasp_and_pull")
        assert dropped.plan_id == second.plan_id and dropped.state == GetPlan.Response.INVALIDATED and not dropped.valid
        assert "registered" in dropped.state_reason

        assert at.register("cdra_filter", added.id, "cdra_filter", f"filter/{DIRTY}").success
        assert at.call("plan_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull").success
        assert at.unlock_filter().success
        executed = at.call("execute_command", type="cdra_filter", id=added.id, trajectory_name="grasp_and_pull")
        assert executed.success, executed.message
        after = at.call("get_plan", name=name, trajectory_name="grasp_and_pull")
        assert after.state == GetPlan.Response.EXECUTED and not after.valid and "executed" in after.state_reason
        since = after.state_since.sec + after.state_since.nanosec * 1e-9
        assert since > after.planned_at.sec + after.planned_at.nanosec * 1e-9
    finally:
        at.call("delete_template", class_type="cdra_filter", id=added.id)


def test_stepping_waypoint_by_waypoint_previews_and_runs_each_step(at: AtClient) -> None:
    """The original AT's stepping (plan_command steps=[1]): each step's plan is the motion to the
    next waypoint only, from where the arm is; a view previews it with get_plan, then it runs.
    Runs after the pull-out above: the dirty filter is in the gripper and goes into rack slot 3."""
    at.wait_for(lambda: at.held_object == DIRTY, 10, "the dirty filter in the gripper")
    added = at.call("add_template", class_type="cdra_filter")
    name = added.instance
    try:
        assert at.register("cdra_filter", added.id, "cdra_filter", "rack/slot_3").success
        for k in range(4):
            step = at.call(
                "plan_command", type="cdra_filter", id=added.id, trajectory_name="insert_and_release", steps=[1]
            )
            assert step.success and f"waypoints [{k}]" in step.message, step.message
            preview = at.call("get_plan", name=name, trajectory_name="insert_and_release")
            assert list(preview.waypoint_names) == [f"0.{k}:{name}"] and preview.valid
            assert (
                len(preview.waypoint_point_index) == 1
                and preview.waypoint_point_index[0] == len(preview.trajectory.points) - 1
            )
            here = [at.joint(j) for j in ARM]
            assert max(abs(a - b) for a, b in zip(preview.trajectory.points[0].positions, here, strict=False)) < 0.02
            done = at.call("execute_command", type="cdra_filter", id=added.id, trajectory_name="insert_and_release")
            assert done.success, done.message
            status = at.call(
                "get_template_status", name=name, trajectory_name="insert_and_release"
            ).affordance_template_status[0]
            assert status.waypoint_info[0].waypoint_index == k
            assert (
                at.call("get_plan", name=name, trajectory_name="insert_and_release").state == GetPlan.Response.EXECUTED
            )
        at.wait_for(lambda: at.held_object == "", 10, "gripper empty")
        frames = at.fresh_frames()
        seated = matrix_from_pose(frames[f"filter/{DIRTY}"])[:3, 3] - matrix_from_pose(frames["rack/slot_3"])[:3, 3]
        assert np.linalg.norm(seated) < 0.01
    finally:
        at.call("delete_template", class_type="cdra_filter", id=added.id)
