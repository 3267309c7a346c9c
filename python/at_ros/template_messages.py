"""affordance_template_msgs built from library templates, robot configs and instances."""

from __future__ import annotations

import numpy as np
from affordance_template_msgs.msg import (
    AffordanceTemplateConfig,
    AffordanceTemplateStatus,
    EndEffectorConfig,
    EndEffectorPoseData,
    ObjectInfo,
    WaypointInfo,
    WaypointTrajectory,
)
from affordance_template_msgs.msg import (
    RobotConfig as RobotConfigMsg,
)
from geometry_msgs.msg import PoseStamped

from at_ros.instance import InstanceError, TemplateInstance
from at_ros.library import Template
from at_ros.messages import pose_from_matrix
from at_ros.robot_config import RobotConfig
from at_ros.transforms import invert

__all__ = ["template_config", "robot_config_message", "instance_status"]


def _stamped(frame: str, pose: np.ndarray) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose = pose_from_matrix(pose)
    return msg


def template_config(template: Template, robot: RobotConfig) -> AffordanceTemplateConfig:
    """A library template as the original get_templates returned it; poses are in object frames."""
    msg = AffordanceTemplateConfig()
    msg.filename = template.filename
    msg.type = template.name
    msg.image_path = template.image
    msg.display_objects = [o.name for o in template.display_objects]
    for trajectory in template.trajectories:
        wt = WaypointTrajectory()
        wt.name = trajectory.name
        for group in trajectory.groups:
            info = WaypointInfo()
            info.id = group.id
            ee = robot.end_effector_by_id(group.id)
            info.end_effector_name = ee.name if ee else ""
            info.num_waypoints = len(group.waypoints)
            info.waypoint_index = -1
            info.waypoint_plan_index = -1
            info.waypoint_poses = [_stamped(w.display_object, w.origin.matrix) for w in group.waypoints]
            info.end_effector_pose_names = [
                (robot.pose_name(ee.name, w.ee_pose) or "") if ee else "" for w in group.waypoints
            ]
            info.compact_view = [False] * len(group.waypoints)
            wt.waypoint_info.append(info)
        msg.trajectory_info.append(wt)
    return msg


def robot_config_message(robot: RobotConfig) -> RobotConfigMsg:
    msg = RobotConfigMsg()
    msg.filename = robot.filename
    msg.name = robot.robot_name
    msg.config_package = "caretaker"
    msg.config_file = str(robot.urdf)
    msg.planner_type = robot.planner_type
    msg.frame_id = robot.frame_id
    msg.root_offset = pose_from_matrix(robot.root_offset_matrix)
    for ee in robot.end_effectors:
        e = EndEffectorConfig()
        e.name, e.id = ee.name, ee.id
        e.pose_offset = pose_from_matrix(ee.pose_offset_matrix)
        e.tool_offset = pose_from_matrix(ee.tool_offset_matrix)
        msg.end_effectors.append(e)
    for pose in robot.end_effector_poses:
        d = EndEffectorPoseData()
        d.group, d.name, d.id = pose.group, pose.name, pose.id
        msg.end_effector_pose_data.append(d)
    return msg


def instance_status(
    instance: TemplateInstance,
    trajectory_name: str,
    frame: str,
    frame_pose: np.ndarray,
    *,
    plan_status: str,
    execute_status: str,
    plan_valid: bool,
) -> AffordanceTemplateStatus:
    """Status of one trajectory of an instance, poses expressed in ``frame`` (world pose ``frame_pose``)."""
    trajectory = instance.trajectory(trajectory_name)
    to_frame = invert(frame_pose)
    msg = AffordanceTemplateStatus()
    msg.type = instance.template.name
    msg.id = instance.id
    msg.trajectory_name = trajectory.name
    msg.plan_status = plan_status
    msg.execute_status = execute_status
    msg.plan_valid = plan_valid
    progress = instance.progress[trajectory.name]
    plan = instance.plan if instance.plan and instance.plan.trajectory == trajectory.name else None
    for group in trajectory.groups:
        ee = instance.robot.end_effector_by_id(group.id)
        info = WaypointInfo()
        info.id = group.id
        info.end_effector_name = ee.name if ee else ""
        info.num_waypoints = len(group.waypoints)
        info.waypoint_index = progress.current_index
        info.waypoint_plan_index = progress.plan_index
        info.plan_valid = plan is not None and plan_valid
        info.execution_valid = progress.execution_valid
        info.compact_view = [instance.hide_waypoints] * len(group.waypoints)
        info.control_frame = instance.robot.tool_link
        if ee is not None:
            try:
                for wp in instance.resolve(trajectory, ee):
                    info.waypoint_poses.append(_stamped(frame, to_frame @ wp.frame_pose))
                    info.waypoint_names.append(wp.label)
                    info.end_effector_pose_names.append(wp.end_effector_pose)
            except InstanceError:
                info.waypoint_poses, info.waypoint_names, info.end_effector_pose_names = [], [], []
        msg.waypoint_info.append(info)
    for obj in instance.template.display_objects:
        o = ObjectInfo()
        o.object_name = f"{obj.name}:{instance.id}"
        o.object_pose = _stamped(frame, to_frame @ instance.object_pose(obj.name))
        o.type = obj.shape.type
        o.mesh_resource = obj.shape.data
        o.size.x, o.size.y, o.size.z = (float(v) for v in obj.shape.size)
        o.rgba = [float(v) for v in obj.shape.rgba]
        o.parent = obj.parent
        o.controls = [bool(v) for v in (*obj.controls.xyz, *obj.controls.rpy)]
        o.control_scale = float(obj.controls.scale)
        msg.object_info.append(o)
    return msg
