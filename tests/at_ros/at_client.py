"""A test-side rclpy client of the AT server, the simulation and the planner: one cached client
per service, calls with timeouts, and the latest of each status topic."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from affordance_template_msgs.msg import DisplayObjectInfo, ServerStatus
from caretaker_sim_msgs.msg import NamedPoses
from caretaker_sim_msgs.srv import CaptureImage, GetFrames
from geometry_msgs.msg import Pose
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from at_ros.api import LATCHED, PREFIX, SERVICE_QOS, SERVICES
from support.spinner import Spinner


class AtClient:
    """Drives the AT services from a test; spins its own executor thread."""

    def __init__(self) -> None:
        if not rclpy.ok():
            rclpy.init()
        self.node = Node("at_test_client")
        self.clients = {
            name: self.node.create_client(t, f"{PREFIX}/{name}", qos_profile=SERVICE_QOS)
            for name, t in SERVICES.items()
        }
        self.unlock_client = self.node.create_client(Trigger, "/cdra/unlock_filter")
        self.capture_client = self.node.create_client(CaptureImage, "/camera/capture")
        self.status: ServerStatus | None = None
        self.status_count = 0
        self.frames: dict[str, Any] = {}
        self.held_object = ""
        self.cdra_present: bool | None = None
        self.joints: dict[str, float] = {}
        self._changed = threading.Condition()
        self.node.create_subscription(ServerStatus, f"{PREFIX}/status", self._status_callback, 10)
        self.node.create_subscription(NamedPoses, "/sim/frames", self._frames_callback, 10)
        self.node.create_subscription(String, "/gripper/held_object", self._held_callback, LATCHED)
        self.node.create_subscription(Bool, "/cdra/filter_present", self._present_callback, LATCHED)
        self.node.create_subscription(JointState, "/joint_states", self._joints_callback, 10)
        self.true_frames_client = self.node.create_client(GetFrames, "/sim/check/frames", qos_profile=SERVICE_QOS)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self._spinner = Spinner(self.executor, self.node, name="at-client")

    def _notify(self) -> None:
        with self._changed:
            self._changed.notify_all()

    def _status_callback(self, msg: ServerStatus) -> None:
        self.status = msg
        self.status_count += 1
        self._notify()

    def _frames_callback(self, msg: NamedPoses) -> None:
        self.frames = dict(zip(msg.names, msg.poses, strict=False))
        self._notify()

    def fresh_frames(self, timeout: float = 10.0) -> dict[str, Any]:
        """Where every named frame is once the robot is at rest, asked of the simulator then (its
        ground truth, ``sim/check/frames``): counting /sim/frames messages that arrive afterwards
        took, on a loaded machine, ones published before the motion's end and still queued."""
        self.wait_for(lambda: self.status is not None and not self.status.robot_active, timeout, "robot at rest")
        answer = self._call(self.true_frames_client, GetFrames.Request(), timeout, "sim/check/frames")
        return dict(zip(answer.frames.names, answer.frames.poses, strict=True))

    def _joints_callback(self, msg: JointState) -> None:
        self.joints = dict(zip(msg.name, msg.position, strict=False))
        self._notify()

    def joint(self, name: str) -> float:
        """The joint's latest position (waiting for joint_states if none came yet)."""
        self.wait_for(lambda: name in self.joints, 30, f"joint_states with {name}")
        return self.joints[name]

    def _held_callback(self, msg: String) -> None:
        self.held_object = msg.data
        self._notify()

    def _present_callback(self, msg: Bool) -> None:
        self.cdra_present = msg.data
        self._notify()

    def wait_for(self, predicate: Callable[[], bool], timeout: float = 30.0, what: str = "condition") -> None:
        deadline = time.monotonic() + timeout
        with self._changed:
            while not predicate():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"{what} not reached within {timeout} s")
                self._changed.wait(remaining)

    def call(self, service: str, /, *, call_timeout: float = 120.0, **fields: Any) -> Any:
        """Call AT service ``service`` with request ``fields``; its response."""
        request = SERVICES[service].Request()
        for key, value in fields.items():
            setattr(request, key, value)
        return self._call(self.clients[service], request, call_timeout, service)

    def _call(self, client: Client, request: Any, timeout: float, name: str) -> Any:
        if not client.wait_for_service(timeout_sec=30.0):
            raise TimeoutError(f"service {name} not available")
        future = client.call_async(request)
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            raise TimeoutError(f"service {name} did not answer in {timeout} s")
        return future.result()

    def unlock_filter(self) -> Any:
        return self._call(self.unlock_client, Trigger.Request(), 30.0, "unlock_filter")

    def capture(self, camera: str, label: str) -> Any:
        request = CaptureImage.Request()
        request.camera, request.label = camera, label
        return self._call(self.capture_client, request, 60.0, "capture")

    def register(self, type_name: str, instance_id: int, obj: str, frame: str, pose: Pose | None = None) -> Any:
        info = DisplayObjectInfo()
        info.type, info.id, info.name = type_name, instance_id, obj
        info.stamped_pose.header.frame_id = frame
        if pose is not None:
            info.stamped_pose.pose = pose
        else:
            info.stamped_pose.pose.orientation.w = 1.0
        return self.call("set_object_pose", objects=[info])

    def close(self) -> None:
        self._spinner.stop()
        self.node.destroy_node()
