"""What perception is told about the world: where each marker sits on its object, and each
camera's calibration; both latched by the simulation node at start (``sim/markers``,
``camera/<name>/camera_info``), as a real robot's world model and calibration would serve them."""

from __future__ import annotations

from caretaker_sim_msgs.msg import Marker, Markers
from sensor_msgs.msg import CameraInfo

from sim.cameras import intrinsics
from sim.collision_world import pose_message
from sim.scene import CameraSpec, Scene

__all__ = ["camera_info", "markers_message"]


def markers_message(scene: Scene) -> Markers:
    """The markers the scene declares, where they are on their frames (the world model's)."""
    msg = Markers(dictionary=scene.marker_dictionary)
    for spec in scene.markers:
        msg.markers.append(Marker(id=spec.id, size=float(spec.size), frame=spec.frame, pose=pose_message(spec.pose)))
    return msg


def camera_info(spec: CameraSpec) -> CameraInfo:
    """``spec``'s calibration: the pinhole it renders with (``sim.cameras.intrinsics``), no distortion."""
    fx, fy, cx, cy = intrinsics(spec)
    msg = CameraInfo()
    msg.header.frame_id = f"camera/{spec.name}"
    msg.width, msg.height = spec.width, spec.height
    msg.distortion_model = "plumb_bob"
    msg.d = [0.0] * 5
    msg.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
    msg.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return msg
