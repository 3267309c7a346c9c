"""A test-side rclpy view of the robot, to check that a command sent through the PAX chain had
the same effect as the same call made directly: cached service clients with timeouts, and the
latest AT status, held object and filter latch."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from affordance_template_msgs.msg import DisplayObjectInfo, ServerStatus
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import Bool, String

from at_ros.api import LATCHED, PREFIX, SERVICES
from support.spinner import Spinner


class RobotProbe:
    """Calls AT services and watches robot topics directly over ROS 2; spins its own thread."""

    def __init__(self) -> None:
        if not rclpy.ok():
            rclpy.init()
        self.node = Node("pax_test_probe")
        self.clients = {name: self.node.create_client(kind, f"{PREFIX}/{name}") for name, kind in SERVICES.items()}
        self.status: ServerStatus | None = None
        self.held_object: str | None = None
        self.filter_locked: bool | None = None
        self._changed = threading.Condition()
        self.node.create_subscription(ServerStatus, f"{PREFIX}/status", self.status_callback, 10)
        self.node.create_subscription(String, "/gripper/held_object", self.held_callback, LATCHED)
        self.node.create_subscription(Bool, "/cdra/filter_locked", self.locked_callback, LATCHED)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self._spinner = Spinner(self.executor, self.node, name="pax-probe")

    def _set(self, name: str, value: Any) -> None:
        with self._changed:
            setattr(self, name, value)
            self._changed.notify_all()

    def status_callback(self, msg: ServerStatus) -> None:
        self._set("status", msg)

    def held_callback(self, msg: String) -> None:
        self._set("held_object", msg.data)

    def locked_callback(self, msg: Bool) -> None:
        self._set("filter_locked", msg.data)

    def wait_for(self, predicate: Callable[[], bool], timeout: float, what: str) -> None:
        """Block until ``predicate()`` holds after some topic update; TimeoutError names ``what``."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not predicate():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"{what} not seen within {timeout} s")
                self._changed.wait(remaining)

    def call(self, service: str, /, *, timeout: float = 60.0, **fields: Any) -> Any:
        """Call AT service ``service`` with request ``fields`` and return the response."""
        client = self.clients[service]
        if not client.wait_for_service(timeout_sec=30.0):
            raise TimeoutError(f"{PREFIX}/{service} is not available")
        request = SERVICES[service].Request()
        for key, value in fields.items():
            setattr(request, key, value)
        future = client.call_async(request)
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            raise TimeoutError(f"{PREFIX}/{service} did not answer within {timeout} s")
        return future.result()

    def register(self, type_name: str, instance_id: int, obj: str, frame: str) -> Any:
        """set_object_pose of one display object at the origin of ``frame``."""
        info = DisplayObjectInfo()
        info.type, info.id, info.name = type_name, instance_id, obj
        info.stamped_pose.header.frame_id = frame
        info.stamped_pose.pose.orientation.w = 1.0
        return self.call("set_object_pose", objects=[info])

    def close(self) -> None:
        self._spinner.stop()
        self.node.destroy_node()
