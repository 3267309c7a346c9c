"""A ROS 2 client of the perception node and of the simulator's checks, for tests.

Its own rclpy context spun on a thread; every wait is on a future with a timeout, never a sleep.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
import rclpy
from caretaker_perception_msgs.msg import LocateResult
from caretaker_perception_msgs.srv import Locate
from caretaker_sim_msgs.srv import GetFrames, PrintMarker
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from at_ros.transforms import angle_between, from_xyz_quat, from_xyz_rpy, invert
from support.spinner import Spinner

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
TIMEOUT = 60.0


def matrix(pose: Any) -> np.ndarray:
    """A ``geometry_msgs/Pose`` as a 4x4 transform."""
    p, q = pose.position, pose.orientation
    return from_xyz_quat((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))


def located(answer: Any) -> np.ndarray:
    """The pose a locate answered (its x, y, z, roll, pitch, yaw; or the same keys of a result's values)."""
    get = answer.__getitem__ if isinstance(answer, dict) else lambda key: getattr(answer, key)
    return from_xyz_rpy([get(k) for k in ("x", "y", "z")], [get(k) for k in ("roll", "pitch", "yaw")])


def errors(pose: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """How far ``pose`` is from ``truth``: (mm, degrees)."""
    return float(np.linalg.norm(pose[:3, 3] - truth[:3, 3]) * 1000), math.degrees(angle_between(pose, truth))


class PerceptionClient:
    """Blocking calls of ``perception/locate`` and of ``sim/check/*``; the last latched result."""

    def __init__(self) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("perception_test_client", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.locate_client = self.node.create_client(Locate, "/perception/locate")
        self.frames_client = self.node.create_client(GetFrames, "/sim/check/frames")
        self.print_client = self.node.create_client(PrintMarker, "/sim/check/print_marker")
        self._results = threading.Condition()
        self.results: list[LocateResult] = []
        self.node.create_subscription(LocateResult, "/perception/last_result", self._result, LATCHED)
        self._spinner = Spinner(self.executor, self.node, name="perception-client")

    def _result(self, msg: LocateResult) -> None:
        with self._results:
            self.results.append(msg)
            self._results.notify_all()

    def last_result(self, object_name: str) -> LocateResult:
        """The newest latched result, once it is about ``object_name``."""
        with self._results:
            arrived = self._results.wait_for(
                lambda: bool(self.results) and self.results[-1].object == object_name, TIMEOUT
            )
            assert arrived, f"no perception/last_result about {object_name} within {TIMEOUT} s"
            return self.results[-1]

    def close(self) -> None:
        self._spinner.stop()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def _call(self, client: Any, request: Any) -> Any:
        assert client.wait_for_service(timeout_sec=TIMEOUT), f"{client.srv_name} is not served"
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        assert done.wait(TIMEOUT), f"{client.srv_name} did not answer within {TIMEOUT} s"
        return future.result()

    def locate(self, obj: str, camera: str, frame: str = "world", tolerance_px: float = 0.0) -> Locate.Response:
        request = Locate.Request(object=obj, camera=camera, frame=frame, tolerance_px=tolerance_px)
        return self._call(self.locate_client, request)

    def true_frames(self) -> dict[str, Any]:
        """The simulator's ground truth: frame name -> geometry_msgs/Pose in world."""
        frames = self._call(self.frames_client, GetFrames.Request()).frames
        return dict(zip(frames.names, frames.poses, strict=True))

    def truth(self, obj: str, frame: str = "world") -> np.ndarray:
        """Where ``obj`` really is, in ``frame`` (the simulator's ground truth)."""
        frames = self.true_frames()
        in_world = matrix(frames[obj])
        return in_world if frame == "world" else invert(matrix(frames[frame])) @ in_world

    def print_marker(self, marker_id: int, printed_id: int) -> None:
        response = self._call(self.print_client, PrintMarker.Request(id=marker_id, printed_id=printed_id))
        assert response.success, response.message
