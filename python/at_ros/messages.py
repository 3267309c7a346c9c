"""Conversions between ROS geometry messages and the 4x4 transforms used everywhere else."""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Pose

from at_ros.transforms import from_xyz_quat, to_xyz_quat

__all__ = ["matrix_from_pose", "pose_from_matrix"]


def matrix_from_pose(pose: Pose) -> np.ndarray:
    """4x4 of a geometry_msgs/Pose; an all-zero quaternion (an unset message) means identity."""
    q = [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w]
    if not any(q):
        q = [0.0, 0.0, 0.0, 1.0]
    return from_xyz_quat([pose.position.x, pose.position.y, pose.position.z], q)


def pose_from_matrix(t: np.ndarray) -> Pose:
    pos, quat = to_xyz_quat(t)
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in pos)
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (float(v) for v in quat)
    return pose
