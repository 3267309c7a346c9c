"""The Affordance Template server node: its ROS interface, its inputs and its status topic.

``caretaker at-server --robot NAME|FILE`` serves the services of ``affordance_template_msgs``
under ``affordance_template_server/`` (in its ``--namespace``) and publishes ``ServerStatus`` on
``affordance_template_server/status`` at 5 Hz and on every change (the original had no status
topic; clients polled). The services are implemented by concept: instances and registration in
:mod:`at_ros.instance_services`, plan and execute in :mod:`at_ros.plan_execute`, the plan for
views in :mod:`at_ros.plan_view`, halt in :mod:`at_ros.halt`, all on the shared state of
:mod:`at_ros.server_core`. Every refusal answers ``success: false`` and what to fix.

Threading: a MultiThreadedExecutor runs services, subscriptions and the status timer in
separate callback groups, so a long execute never blocks status or other services.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rclpy
from affordance_template_msgs.msg import ServerStatus
from affordance_template_msgs.srv import PlanWaypoints
from caretaker_sim_msgs.action import FollowJointTrajectory
from caretaker_sim_msgs.msg import NamedPoses
from caretaker_sim_msgs.srv import Halt as RobotHalt
from caretaker_sim_msgs.srv import SetGripper
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Header, String

from at_ros.action_client import RecordedActionClient
from at_ros.api import LATCHED, PREFIX, SERVICE_QOS, SERVICES, STATUS_TOPIC
from at_ros.command_line import add_robot_options, choose_robot, split_ros_args
from at_ros.frames import UnknownFrame
from at_ros.halt import HaltSwitch
from at_ros.instance import InstanceError
from at_ros.instance_services import InstanceServices
from at_ros.instance_store import load_instances
from at_ros.library import LibraryError, Template, load_library
from at_ros.messages import matrix_from_pose
from at_ros.plan_execute import PlanExecutor
from at_ros.plan_view import PlanQueries
from at_ros.robot_config import RobotConfig
from at_ros.server_core import CommandRefused, ServerCore
from ros_process import spinning

__all__ = ["AffordanceTemplateServer", "main"]

STATUS_PERIOD = 0.2


class AffordanceTemplateServer(Node):
    def __init__(
        self,
        robot: RobotConfig,
        templates: dict[str, Template],
        robots: dict[str, RobotConfig],
        *,
        template_folder: Path | None = None,
        state_file: Path | None = None,
        namespace: str = "",
    ) -> None:
        """``template_folder`` is re-read when a template is asked for by a name not yet loaded.
        ``state_file`` keeps the instances across a restart (:mod:`at_ros.instance_store`).

        Raises:
            LibraryError: the state file holds instances this library or robot cannot restore.
        """
        restored = load_instances(state_file, robot, templates) if state_file is not None else {}
        super().__init__("affordance_template_server", namespace=namespace)
        self.core = ServerCore(
            robot, templates, robots, template_folder=template_folder, state_file=state_file, instances=restored
        )
        self.core.publish_status = self.publish_status
        self._last_published: tuple[Any, ...] | None = None

        services = ReentrantCallbackGroup()
        clients = ReentrantCallbackGroup()
        inputs = ReentrantCallbackGroup()
        status = MutuallyExclusiveCallbackGroup()

        self.status_publisher = self.create_publisher(ServerStatus, STATUS_TOPIC, 10)
        self.status_timer = self.create_timer(STATUS_PERIOD, self.status_timer_callback, callback_group=status)

        self.frames_subscription = self.create_subscription(
            NamedPoses, "sim/frames", self.frames_callback, LATCHED, callback_group=inputs
        )
        self.joint_subscription = self.create_subscription(
            JointState, "joint_states", self.joint_states_callback, LATCHED, callback_group=inputs
        )
        self.moving_subscription = self.create_subscription(
            Bool, "robot/moving", self.moving_callback, LATCHED, callback_group=inputs
        )
        self.held_subscription = self.create_subscription(
            String, "gripper/held_object", self.held_object_callback, LATCHED, callback_group=inputs
        )
        self.heartbeat_subscription = self.create_subscription(
            Header, "planner/heartbeat", self.heartbeat_callback, 10, callback_group=inputs
        )

        self.halt_part = HaltSwitch(
            self.core,
            halt_client=self.create_client(
                RobotHalt, robot.halt_service, qos_profile=SERVICE_QOS, callback_group=clients
            )
            if robot.halt_service
            else None,
        )
        self.executor_part = PlanExecutor(
            self.core,
            planner_client=self.create_client(
                PlanWaypoints, "planner/plan_waypoints", qos_profile=SERVICE_QOS, callback_group=clients
            ),
            trajectory_client=RecordedActionClient(
                self, FollowJointTrajectory, robot.trajectory_action, callback_group=clients
            ),
            gripper_client=self.create_client(
                SetGripper, robot.gripper_service, qos_profile=SERVICE_QOS, callback_group=clients
            )
            if robot.gripper_service
            else None,
            halts=self.halt_part,
        )
        self.instance_part = InstanceServices(self.core)
        self.plan_part = PlanQueries(self.core)
        for name, srv_type in SERVICES.items():
            callback = self._handler(name)
            self.create_service(
                srv_type,
                f"{PREFIX}/{name}",
                self._guarded(name, callback),
                qos_profile=SERVICE_QOS,
                callback_group=services,
            )

    @property
    def frames_arrived(self) -> bool:
        return self.core.frames.age < float("inf")

    def _handler(self, name: str) -> Callable[[Any, Any], Any]:
        """The callback of service ``name``: the part that owns the concept, or the status query."""
        if name == "get_status":
            return self.get_status_callback
        for part in (self.instance_part, self.executor_part, self.plan_part, self.halt_part):
            if hasattr(part, name):
                handler: Callable[[Any, Any], Any] = getattr(part, name)
                return handler
        raise AssertionError(f"no handler for service {name!r}")

    def _guarded(self, name: str, callback: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
        """Answer every refusal with success false and its reason; log and report the unexpected."""

        def handle(request: Any, response: Any) -> Any:
            try:
                return callback(request, response)
            except (CommandRefused, InstanceError, UnknownFrame) as exc:
                message = str(exc)
            except Exception as exc:  # a bug must still answer the client, never hang it
                self.get_logger().error(f"{name} failed unexpectedly: {exc!r}")  # type: ignore[no-untyped-call]  # rclpy is not annotated
                message = f"internal error in {name}: {exc!r}"
            self.get_logger().warning(f"{name} refused: {message}")  # type: ignore[no-untyped-call]
            return self.core.refuse(name, response, message)

        return handle

    # --- inputs ----------------------------------------------------------------------------

    def frames_callback(self, msg: NamedPoses) -> None:
        self.core.frames.update(list(msg.names), [matrix_from_pose(p) for p in msg.poses])

    def joint_states_callback(self, msg: JointState) -> None:
        with self.core.joints_heard:
            self.core.inputs.joints.update(zip(msg.name, msg.position, strict=False))
            self.core.inputs.joints_stamp = msg.header.stamp
            self.core.joints_heard.notify_all()

    def moving_callback(self, msg: Bool) -> None:
        with self.core.state_lock:
            self.core.inputs.moving = bool(msg.data)
        self.publish_status()

    def held_object_callback(self, msg: String) -> None:
        with self.core.state_lock:
            self.core.inputs.held_object = msg.data
        self.publish_status()

    def heartbeat_callback(self, msg: Header) -> None:
        if msg.frame_id in ("", self.core.robot.robot_name):
            with self.core.state_lock:
                self.core.inputs.last_heartbeat = time.monotonic()

    # --- status ----------------------------------------------------------------------------

    def status_timer_callback(self) -> None:
        self.publish_status(force=True)

    def publish_status(self, *, force: bool = False) -> None:
        msg = self.core.status_message(self.get_clock().now().to_msg())
        key = (
            msg.robot_active,
            msg.planner_node_active,
            msg.execute_status,
            msg.plan_status,
            msg.plan_valid,
            msg.active_template,
            msg.active_trajectory,
            tuple(msg.running_templates),
            msg.last_error,
            msg.plan_id,
            msg.halt_reason,
        )
        with self.core.state_lock:
            changed = key != self._last_published
            self._last_published = key
        if force or changed:
            self.status_publisher.publish(msg)

    def get_status_callback(self, request: Any, response: Any) -> Any:
        response.status = self.core.status_message(self.get_clock().now().to_msg())
        with self.core.state_lock:
            executing = self.core.state.executing
        response.ready = not executing
        response.success = True
        response.message = "executing " + executing if executing else "ready"
        return response


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="caretaker at-server", description=__doc__.splitlines()[0])
    add_robot_options(parser)
    parser.add_argument(
        "--state-file",
        type=Path,
        help="keep the instances here and restore them at start, so a restarted server carries on (default: not kept)",
    )
    ours, ros_args = split_ros_args(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(ours)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        choice = choose_robot(args)
        templates = load_library(choice.templates)
    except LibraryError as exc:
        print(f"caretaker at-server: {exc}", file=sys.stderr)
        return 2
    rclpy.init(args=["caretaker-at-server", *ros_args])
    executor = MultiThreadedExecutor(num_threads=6)
    with spinning(executor) as nodes:
        try:
            node = AffordanceTemplateServer(
                choice.robot,
                templates,
                choice.robots,
                template_folder=choice.templates,
                state_file=args.state_file,
                namespace=args.namespace,
            )
        except LibraryError as exc:
            print(f"caretaker at-server: {exc}", file=sys.stderr)
            return 2
        nodes.append(node)
        if node.core.state.instances:
            print(f"restored {', '.join(sorted(node.core.state.instances))} from {args.state_file}", flush=True)
        executor.add_node(node)
        # Serving means able to register templates: that needs the world's frames.
        while not node.frames_arrived:
            executor.spin_once(timeout_sec=0.1)
        print(f"READY at-server {choice.robot.robot_name}", flush=True)
        executor.spin()
    return 0
