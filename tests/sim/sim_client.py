"""A ROS 2 client of the simulation node for tests: its own rclpy context, spun on a thread.

Every wait is on a future or a condition with a timeout, never a sleep.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from builtin_interfaces.msg import Duration
from caretaker_sim_msgs.action import FollowJointTrajectory
from caretaker_sim_msgs.msg import NamedPoses, VisualWorld
from caretaker_sim_msgs.srv import CaptureImage, FindFilter, Halt, SetGripper
from rcl_interfaces.srv import SetParameters
from rclpy.action import ActionClient
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Bool, Float64, String
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectoryPoint

from support.sim_pace import SIM_PARAMETERS, parameter_request
from support.spinner import Spinner

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
TIMEOUT = 60.0


class SimClient:
    """Latest value of every sim topic, plus blocking calls of its action and services."""

    def __init__(self, name: str = "sim_test_client") -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._changed = threading.Condition()
        self.latest: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self.feedback: list[FollowJointTrajectory.Feedback] = []
        for topic, kind, qos in [
            ("/joint_states", JointState, 10),
            ("/sim/frames", NamedPoses, 10),
            ("/robot/moving", Bool, LATCHED),
            ("/gripper/held_object", String, LATCHED),
            ("/cdra/filter_locked", Bool, LATCHED),
            ("/cdra/filter_present", Bool, LATCHED),
            ("/cdra/installed_filter_id", String, LATCHED),
            ("/cdra/installed_filter_condition", String, LATCHED),
            ("/cdra/co2_partial_pressure", Float64, LATCHED),
            ("/robot_description", String, LATCHED),
            ("/sim/visual_world", VisualWorld, LATCHED),
        ]:
            self.node.create_subscription(kind, topic, self._store(topic), qos)
        self.trajectory_client = ActionClient(
            self.node, FollowJointTrajectory, "/arm_controller/follow_joint_trajectory"
        )
        self.gripper_client = self.node.create_client(SetGripper, "/gripper/set")
        self.capture_client = self.node.create_client(CaptureImage, "/camera/capture")
        self.unlock_client = self.node.create_client(Trigger, "/cdra/unlock_filter")
        self.lock_client = self.node.create_client(Trigger, "/cdra/lock_filter")
        self.filter_in_slot_client = self.node.create_client(FindFilter, "/cdra/filter_in_slot")
        self.slot_of_filter_client = self.node.create_client(FindFilter, "/cdra/slot_of_filter")
        self.halt_client = self.node.create_client(Halt, "/robot/halt")
        self.parameters_client = self.node.create_client(SetParameters, SIM_PARAMETERS)
        self.spin_error: BaseException | None = None
        self._spinner = Spinner(self.executor, self.node, name="sim-client", on_error=self._spin_failed)

    def _spin_failed(self, exc: BaseException) -> None:
        """Reported by the next wait instead of a silent stall."""
        with self._changed:
            self.spin_error = exc
            self._changed.notify_all()

    def close(self) -> None:
        self._spinner.stop()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    # ------------------------------------------------------------------ topics

    def _store(self, topic: str) -> Callable[[Any], None]:
        def callback(msg: Any) -> None:
            with self._changed:
                self.latest[topic] = msg
                self.counts[topic] = self.counts.get(topic, 0) + 1
                self._changed.notify_all()

        return callback

    def wait_for(self, predicate: Callable[[], bool], what: str, timeout: float = TIMEOUT) -> None:
        with self._changed:
            if not self._changed.wait_for(lambda: self.spin_error is not None or predicate(), timeout):
                raise AssertionError(
                    f"timed out after {timeout} s waiting for {what}; "
                    f"latest: { {k: v for k, v in self.latest.items() if k != '/sim/frames'} }"
                )
            if self.spin_error is not None and not predicate():
                raise AssertionError(f"the test client's executor died: {self.spin_error!r}") from self.spin_error

    def value(self, topic: str, timeout: float = TIMEOUT) -> Any:
        self.wait_for(lambda: topic in self.latest, f"a message on {topic}", timeout)
        return self.latest[topic]

    def fresh(self, topic: str, timeout: float = TIMEOUT) -> Any:
        """A message on ``topic`` published after this call: the second one to arrive from now
        (the first may have been in flight). Stamps are sim time, which can run ahead of the
        wall clock, so they cannot tell what is new."""
        with self._changed:
            seen = self.counts.get(topic, 0)
        self.wait_for(lambda: self.counts.get(topic, 0) >= seen + 2, f"a new message on {topic}", timeout)
        return self.latest[topic]

    def wait_value(self, topic: str, expected: Any, timeout: float = TIMEOUT) -> None:
        self.wait_for(
            lambda: topic in self.latest and self.latest[topic].data == expected, f"{topic} == {expected!r}", timeout
        )

    def joint_positions(self, names: Sequence[str]) -> list[float]:
        return _positions(self.fresh("/joint_states"), names)

    def wait_joints(self, names: Sequence[str], expected: Sequence[float], tol: float) -> None:
        """Wait until ``/joint_states`` shows ``names`` within ``tol`` of ``expected``: under load the
        messages taken after a result can still be ones queued before it."""

        def there() -> bool:
            msg = self.latest.get("/joint_states")
            return msg is not None and all(
                abs(q - e) <= tol for q, e in zip(_positions(msg, names), expected, strict=True)
            )

        self.wait_for(there, f"joint_states of {list(names)} at {list(expected)}")

    def frame(self, name: str) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        msg = self.fresh("/sim/frames")
        if name not in msg.names:
            raise AssertionError(f"no frame {name!r} in /sim/frames; frames are {list(msg.names)}")
        pose = msg.poses[list(msg.names).index(name)]
        return (pose.position.x, pose.position.y, pose.position.z), (
            pose.orientation.x,
            pose.orientation.y,
            pose.orientation.z,
            pose.orientation.w,
        )

    # ------------------------------------------------------------------ calls

    def _wait_future(self, future: Any, what: str, timeout: float = TIMEOUT) -> Any:
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout):
            raise AssertionError(f"{what}: no answer in {timeout} s")
        return future.result()

    def follow_and_cancel(
        self, joint_names: Sequence[str], points: Sequence[tuple[float, Sequence[float]]]
    ) -> tuple[int, FollowJointTrajectory.Result]:
        """Send a trajectory, cancel it at its first feedback; returns (goal status, result)."""
        self.feedback.clear()
        handle = self._wait_future(
            self._in_executor(
                lambda: self.trajectory_client.send_goal_async(
                    self._goal(joint_names, points, None, 0.0), feedback_callback=self._feedback_callback
                )
            ),
            "send goal",
        )
        assert handle.accepted, "goal not accepted"
        self.wait_for(lambda: bool(self.feedback), "trajectory feedback")
        self._wait_future(self._in_executor(handle.cancel_goal_async), "cancel")
        response = self._wait_future(self._in_executor(handle.get_result_async), "trajectory result")
        return response.status, response.result

    def start(self, joint_names: Sequence[str], points: Sequence[tuple[float, Sequence[float]]]) -> Any:
        """Send a trajectory and return its goal handle once accepted (see :meth:`result`)."""
        handle = self._wait_future(
            self._in_executor(
                lambda: self.trajectory_client.send_goal_async(self._goal(joint_names, points, None, 0.0))
            ),
            "send goal",
        )
        assert handle.accepted, "goal not accepted"
        return handle

    def result(self, handle: Any) -> tuple[int, FollowJointTrajectory.Result]:
        response = self._wait_future(self._in_executor(handle.get_result_async), "trajectory result")
        return response.status, response.result

    def follow(
        self,
        joint_names: Sequence[str],
        points: Sequence[tuple[float, Sequence[float]]],
        *,
        velocities: Sequence[Sequence[float]] | None = None,
        tolerance: float = 0.0,
    ) -> FollowJointTrajectory.Result:
        """Send a trajectory of (time_from_start, positions) points and wait for its result."""
        handle = self._wait_future(
            self._in_executor(
                lambda: self.trajectory_client.send_goal_async(
                    self._goal(joint_names, points, velocities, tolerance), feedback_callback=self._feedback_callback
                )
            ),
            "send goal",
        )
        assert handle.accepted, "goal not accepted"
        return self._wait_future(self._in_executor(handle.get_result_async), "trajectory result").result

    def _goal(
        self,
        joint_names: Sequence[str],
        points: Sequence[tuple[float, Sequence[float]]],
        velocities: Sequence[Sequence[float]] | None,
        tolerance: float,
    ) -> FollowJointTrajectory.Goal:
        if not self.trajectory_client.wait_for_server(timeout_sec=TIMEOUT):
            raise AssertionError("trajectory action server not available")
        goal = FollowJointTrajectory.Goal()
        goal.trajectory.joint_names = list(joint_names)
        for k, (t, q) in enumerate(points):
            pt = JointTrajectoryPoint()
            pt.positions = [float(v) for v in q]
            if velocities is not None:
                pt.velocities = [float(v) for v in velocities[k]]
            sec = math.floor(t) if math.isfinite(t) else 0
            pt.time_from_start = Duration(sec=int(sec), nanosec=int(round((t - sec) * 1e9)) if math.isfinite(t) else 0)
            goal.trajectory.points.append(pt)
        goal.goal_tolerance = tolerance
        return goal

    def _in_executor(self, call: Callable[[], Any]) -> Any:
        """Run ``call`` on the executor's thread and return what it returned.

        rclpy 7.1's ActionClient records a request's sequence number after sending it, without a
        lock: called from another thread, a fast server's response can be handled first and is
        then dropped ("Ignoring unexpected goal response"). On the executor thread it cannot.
        """
        task = self.executor.create_task(call)
        return self._wait_future(task, "a call on the executor thread")

    def _feedback_callback(self, message: Any) -> None:
        with self._changed:
            self.feedback.append(message.feedback)
            self._changed.notify_all()

    def _call(self, client: Any, request: Any, what: str) -> Any:
        if not client.wait_for_service(timeout_sec=TIMEOUT):
            raise AssertionError(f"service for {what} not available")
        return self._wait_future(client.call_async(request), what)

    def gripper(self, pose: str) -> SetGripper.Response:
        return self._call(self.gripper_client, SetGripper.Request(pose=pose), f"gripper {pose}")

    def halt(self, reason: str) -> Halt.Response:
        return self._call(self.halt_client, Halt.Request(reason=reason), "halt")

    def set_time_scale(self, value: float | str | bool) -> SetParameters.Response:
        """Set the simulator's ``time_scale`` parameter (of any type, to see a wrong one refused)."""
        return self.set_parameter("time_scale", value)

    def set_parameter(self, name: str, value: float | str | bool) -> SetParameters.Response:
        """Set the simulator's parameter ``name`` (to a value of any type, to see a wrong one refused)."""
        return self._call(self.parameters_client, parameter_request(name, value), f"{name} {value!r}").results[0]

    def unlock(self) -> Trigger.Response:
        return self._call(self.unlock_client, Trigger.Request(), "unlock")

    def lock(self) -> Trigger.Response:
        return self._call(self.lock_client, Trigger.Request(), "lock")

    def filter_in_slot(self, slot: str) -> FindFilter.Response:
        return self._call(self.filter_in_slot_client, FindFilter.Request(slot=slot), f"filter in {slot}")

    def slot_of_filter(self, filter_id: str) -> FindFilter.Response:
        return self._call(self.slot_of_filter_client, FindFilter.Request(filter_id=filter_id), f"slot of {filter_id}")

    def capture(self, camera: str, label: str = "") -> CaptureImage.Response:
        return self._call(self.capture_client, CaptureImage.Request(camera=camera, label=label), f"capture {camera}")

    def next_image(self, camera: str, timeout: float = TIMEOUT) -> Image:
        got: list[Image] = []
        done = threading.Event()

        def callback(msg: Image) -> None:
            got.append(msg)
            done.set()

        sub = self.node.create_subscription(Image, f"/camera/{camera}/image", callback, 2)
        try:
            if not done.wait(timeout):
                raise AssertionError(f"no image on /camera/{camera}/image in {timeout} s")
            return got[0]
        finally:
            self.node.destroy_subscription(sub)


def _positions(msg: Any, names: Sequence[str]) -> list[float]:
    index = {n: i for i, n in enumerate(msg.name)}
    return [msg.position[index[n]] for n in names]
