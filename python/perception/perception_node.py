"""``caretaker perception``: the habitat's perception node, locating objects from their markers.

Serves ``perception/locate`` (caretaker_perception_msgs/srv/Locate): an object (a frame of
``sim/frames`` with markers declared on it), a camera, the frame to answer in and a tolerance.
It takes one image through the robot side's ``camera/capture`` (which also says where the
camera was when it took it), finds the object's markers (:mod:`perception.locate`) and answers
the pose, its reprojection error and the markers used, or ``success: false`` with the reason.
Detection runs here, on the habitat, so only the answer (a few hundred bytes) crosses the link.

What it knows of the world comes from the robot side as any world model's would: the markers
declared on each object (``sim/markers``), each camera's calibration
(``camera/<name>/camera_info``) and the frames (``sim/frames``: where the world model has each
object, so the answer also says how far the located pose is from it). The last answer is
latched on ``perception/last_result`` (a view's proposal) and, one value per topic, on
``perception/last_*`` (the perception SysRep's telemetry, ``sysrep/perception.yaml``).
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import rclpy
from caretaker_perception_msgs.msg import LocateResult
from caretaker_perception_msgs.srv import Locate
from caretaker_sim_msgs.msg import Markers, NamedPoses
from caretaker_sim_msgs.srv import CaptureImage
from geometry_msgs.msg import Pose
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo
from std_msgs.msg import Bool, Float64, String

from at_ros.transforms import angle_between, from_xyz_quat, invert, to_xyz_quat, to_xyz_rpy
from perception.locate import DEFAULT_TOLERANCE_PX, Calibration, MarkerOnObject, NotLocated, locate
from ros_process import spinning

__all__ = ["PerceptionNode", "main"]

LOG = logging.getLogger("perception")

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
#: s to wait for the robot side's latched data (markers, a calibration) and for an image.
WAIT_S = 30.0


def _matrix(pose: Pose) -> np.ndarray:
    p, q = pose.position, pose.orientation
    return from_xyz_quat((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))


def _gray(image: Any) -> np.ndarray:
    """An 8-bit grey image from a ``sensor_msgs/Image`` in rgb8 or mono8."""
    data = np.frombuffer(bytes(image.data), dtype=np.uint8)
    if image.encoding == "mono8":
        return data.reshape(image.height, image.step)[:, : image.width]
    rgb = data.reshape(image.height, image.step)[:, : image.width * 3].reshape(image.height, image.width, 3)
    # ITU-R 601 luma, as cv2.cvtColor(RGB2GRAY) weighs it.
    gray: np.ndarray = (rgb @ np.array([0.299, 0.587, 0.114])).round().astype(np.uint8)
    return gray


@dataclass
class Latest:
    """The newest sample of a latched topic, and an event set once one has come."""

    value: Any = None
    arrived: threading.Event = field(default_factory=threading.Event)

    def put(self, value: Any) -> None:
        self.value = value
        self.arrived.set()

    def wait(self, what: str) -> Any:
        if not self.arrived.wait(WAIT_S):
            raise NotLocated(f"{what} did not arrive within {WAIT_S:.0f} s")
        return self.value


class PerceptionNode(Node):
    """The locate service and its telemetry."""

    def __init__(self, *, namespace: str = "", default_tolerance_px: float = DEFAULT_TOLERANCE_PX) -> None:
        super().__init__("caretaker_perception", namespace=namespace)
        self.default_tolerance_px = default_tolerance_px
        group = ReentrantCallbackGroup()
        self.markers = Latest()
        self.frames = Latest()
        self.calibrations: dict[str, Latest] = {}
        self._lock = threading.Lock()
        self.create_subscription(Markers, "sim/markers", self.markers.put, LATCHED, callback_group=group)
        self.create_subscription(NamedPoses, "sim/frames", self.frames.put, LATCHED, callback_group=group)
        self.capture = self.create_client(CaptureImage, "camera/capture", callback_group=group)
        self.result_pub = self.create_publisher(LocateResult, "perception/last_result", LATCHED)
        self.telemetry = {
            name: self.create_publisher(kind, f"perception/{name}", LATCHED)
            for name, kind in (
                ("last_object", String),
                ("last_success", Bool),
                ("last_message", String),
                ("last_residual_px", Float64),
                ("last_offset_mm", Float64),
            )
        }
        self.create_service(Locate, "perception/locate", self.locate_callback, callback_group=group)

    # ------------------------------------------------------------------ what the robot side tells

    def calibration(self, camera: str) -> Calibration:
        with self._lock:
            if camera not in self.calibrations:
                latest = self.calibrations[camera] = Latest()
                self.create_subscription(CameraInfo, f"camera/{camera}/camera_info", latest.put, LATCHED)
        info = self.calibrations[camera].wait(f"the calibration of camera {camera!r} (camera/{camera}/camera_info)")
        return Calibration(int(info.width), int(info.height), np.array(info.k, dtype=float).reshape(3, 3))

    def declared(self, name: str) -> tuple[str, list[MarkerOnObject]]:
        """The dictionary and the markers declared on object ``name``."""
        markers: Markers = self.markers.wait("the markers the world model declares (sim/markers)")
        on = [MarkerOnObject(m.id, m.size, _matrix(m.pose)) for m in markers.markers if m.frame == name]
        if not on:
            carrying = sorted({m.frame for m in markers.markers})
            raise NotLocated(f"no markers are declared on {name!r}; objects with markers: {', '.join(carrying)}")
        return markers.dictionary, on

    def frame(self, name: str) -> np.ndarray:
        """The world pose of a ``sim/frames`` frame (``world`` is the identity)."""
        if name == "world":
            return np.eye(4)
        frames: NamedPoses = self.frames.wait("the frames (sim/frames)")
        if name not in frames.names:
            raise NotLocated(f"unknown frame {name!r}; frames are world, {', '.join(frames.names)}")
        return _matrix(frames.poses[list(frames.names).index(name)])

    def take_image(self, camera: str) -> CaptureImage.Response:
        if not self.capture.wait_for_service(timeout_sec=WAIT_S):
            raise NotLocated("the robot's camera/capture service is not there")
        done = threading.Event()
        future = self.capture.call_async(CaptureImage.Request(camera=camera, label=""))
        future.add_done_callback(lambda _: done.set())
        if not done.wait(WAIT_S):
            raise NotLocated(f"camera {camera!r} gave no image within {WAIT_S:.0f} s")
        response: CaptureImage.Response = future.result()
        if not response.success:
            raise NotLocated(f"camera {camera!r} gave no image: {response.message}")
        return response

    # ------------------------------------------------------------------ the service

    def locate_callback(self, request: Locate.Request, response: Locate.Response) -> Locate.Response:
        frame = request.frame or "world"
        tolerance = request.tolerance_px if request.tolerance_px > 0 else self.default_tolerance_px
        result = LocateResult(object=request.object, camera=request.camera)
        result.header.frame_id = response.frame = frame
        try:
            dictionary, markers = self.declared(request.object)
            frame_pose = self.frame(frame)
            nominal = self.frame(request.object)
            image = self.take_image(request.camera)  # first: it names an unknown camera at once
            calibration = self.calibration(request.camera)
            result.header.stamp = image.image.header.stamp
            located = locate(_gray(image.image), calibration, dictionary, markers, tolerance)
        except NotLocated as exc:
            response.success = result.success = False
            response.message = result.message = f"{request.object} not located from {request.camera}: {exc}"
            LOG.warning("%s", response.message)
            self._publish(result)
            return response
        world_pose = _matrix(image.camera_pose) @ located.camera_to_object
        pose = invert(frame_pose) @ world_pose
        xyz, rpy = to_xyz_rpy(pose)
        _, quat = to_xyz_quat(pose)
        response.x, response.y, response.z = (float(v) for v in xyz)
        response.roll, response.pitch, response.yaw = rpy
        response.qx, response.qy, response.qz, response.qw = (float(v) for v in quat)
        response.residual_px = result.residual_px = located.residual_px
        response.markers = ",".join(str(i) for i in located.markers)
        response.distance = float(np.linalg.norm(located.camera_to_object[:3, 3]))
        response.offset_mm = result.offset_mm = float(np.linalg.norm(world_pose[:3, 3] - nominal[:3, 3]) * 1000)
        response.offset_deg = result.offset_deg = float(np.degrees(angle_between(nominal, world_pose)))
        response.success = result.success = True
        response.message = result.message = (
            f"{request.object} located from {request.camera} at {response.distance:.2f} m with marker(s) "
            f"{response.markers}, {located.residual_px:.2f} px: {response.offset_mm:.1f} mm and "
            f"{response.offset_deg:.1f} deg from where the world model has it"
        )
        result.xyz = [float(v) for v in xyz]
        result.quaternion = [float(v) for v in quat]
        result.markers = list(located.markers)
        LOG.info("%s", response.message)
        self._publish(result)
        return response

    def _publish(self, result: LocateResult) -> None:
        self.result_pub.publish(result)
        self.telemetry["last_object"].publish(String(data=result.object))
        self.telemetry["last_success"].publish(Bool(data=result.success))
        self.telemetry["last_message"].publish(String(data=result.message))
        self.telemetry["last_residual_px"].publish(Float64(data=float(result.residual_px)))
        self.telemetry["last_offset_mm"].publish(Float64(data=float(result.offset_mm)))


def main(argv: list[str] | None = None) -> int:
    """Serve ``perception/locate`` until Ctrl-C; prints ``READY perception <markers> markers``
    once the world model's markers have arrived."""
    parser = argparse.ArgumentParser(prog="caretaker perception", description=__doc__.splitlines()[0])
    parser.add_argument("--namespace", default="", help="the robot's ROS namespace")
    parser.add_argument(
        "--tolerance-px",
        type=float,
        default=DEFAULT_TOLERANCE_PX,
        help=f"largest reprojection error (px RMS) accepted when a request names none (default {DEFAULT_TOLERANCE_PX})",
    )
    args, ros_args = parser.parse_known_args(argv)
    if args.tolerance_px <= 0:
        parser.error("--tolerance-px must be positive")
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    rclpy.init(args=ros_args)
    executor = MultiThreadedExecutor(num_threads=4)
    with spinning(executor) as nodes:
        node = PerceptionNode(namespace=args.namespace, default_tolerance_px=args.tolerance_px)
        nodes.append(node)
        executor.add_node(node)
        deadline = time.monotonic() + WAIT_S
        while not node.markers.arrived.is_set() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.5)
        if node.markers.value is None:
            print(f"caretaker perception: no markers arrived on sim/markers within {WAIT_S:.0f} s", file=sys.stderr)
            return 1
        print(f"READY perception {len(node.markers.value.markers)} markers", flush=True)
        executor.spin()
    return 0
