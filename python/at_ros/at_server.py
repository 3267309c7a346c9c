"""The Affordance Template server node: instances, registration, plan, execute, status.

``caretaker at-server --robot NAME`` serves the services of ``affordance_template_msgs`` under
``/affordance_template_server/`` and publishes ``ServerStatus`` on
``/affordance_template_server/status`` at 5 Hz and on every change (the original had no status
topic; clients polled). Differences from the original, each fixing a defect it had:

- plan and execute answer with their real outcome (the original never filled ``status``);
- a plan is executed only while it still fits the world (robot and registered objects where
  they were at planning time, same object in the gripper); otherwise refused with the reason;
- a second robot command while one executes is refused, not queued;
- every wait has a timeout, and every bad request gets ``success: false`` and what to fix.

Threading: a MultiThreadedExecutor runs services, subscriptions and the status timer in
separate callback groups, so a long execute never blocks status or other services. Locks:
``_state_lock`` guards the instance table and status fields; ``_robot_lock`` is held while the
robot executes; each instance's ``command_lock`` serializes commands on that instance.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Header, String

from affordance_template_msgs.msg import AffordanceTemplateStatus, ServerStatus, WaypointGoal
from affordance_template_msgs.srv import (
    AddAffordanceTemplate,
    AffordanceTemplateExecuteCommand,
    AffordanceTemplatePlanCommand,
    DeleteAffordanceTemplate,
    GetAffordanceTemplateStatus,
    PlanWaypoints,
    SetObjectPose,
    SetWaypointPose,
)
from at_ros.action_client import RecordedActionClient
from at_ros.api import LATCHED, PREFIX, SERVICE_QOS, SERVICES, STATUS_TOPIC
from at_ros.frames import WORLD_FRAME, FrameTable, UnknownFrame
from at_ros.instance import InstanceError, Registration, StoredPlan, TemplateInstance, next_free_id, path_sequence
from at_ros.instance_store import load_instances, save_instances
from at_ros.library import LibraryError, Template, default_library_path, load_library
from at_ros.messages import matrix_from_pose, pose_from_matrix
from at_ros.robot_config import RobotConfig, load_robot_configs
from at_ros.template_messages import instance_status, robot_config_message, template_config
from caretaker_sim_msgs.action import FollowJointTrajectory
from caretaker_sim_msgs.msg import NamedPoses
from caretaker_sim_msgs.srv import SetGripper

__all__ = ["AffordanceTemplateServer", "main"]

HEARTBEAT_TIMEOUT = 5.0  # s; a plan may hold the planner's GIL for a few seconds
PLAN_TIMEOUT = 60.0
JOINT_TOLERANCE = 0.02  # rad the robot may drift from a plan's start and still run it
STATUS_PERIOD = 0.2
FRAME_WAIT = 3.0  # s to wait for a frame not (yet) published, as the original waited for TF


class CommandRefused(Exception):
    """A command that cannot run now or as asked; the message says what to fix."""


@dataclass
class ServerState:
    """What the status topic reports; guarded by the server's ``_state_lock``."""

    plan_status: str = ServerStatus.PLAN_IDLE
    execute_status: str = ServerStatus.EXECUTE_IDLE
    active_template: str = ""
    active_trajectory: str = ""
    last_error: str = ""
    executing: str = ""  # "Type:id" while the robot executes
    instances: dict[str, TemplateInstance] = field(default_factory=dict)


def _wait(future, timeout: float, what: str):  # noqa: ANN001, ANN202 - rclpy Future
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    if not done.wait(timeout):
        future.cancel()
        raise CommandRefused(f"{what} did not answer within {timeout:.0f} s")
    if future.exception() is not None:
        raise CommandRefused(f"{what} failed: {future.exception()}")
    return future.result()


class AffordanceTemplateServer(Node):
    def __init__(
        self,
        robot: RobotConfig,
        templates: dict[str, Template],
        robots: dict[str, RobotConfig],
        *,
        template_folder: Path | None = None,
        state_file: Path | None = None,
    ) -> None:
        """``template_folder`` is re-read when a template is asked for by a name not yet loaded,
        so adding a template is dropping a JSON file in the library: no restart, no code.
        ``state_file`` keeps the instances across a restart (:mod:`at_ros.instance_store`).

        Raises:
            LibraryError: the state file holds instances this library or robot cannot restore.
        """
        restored = load_instances(state_file, robot, templates) if state_file is not None else {}
        super().__init__("affordance_template_server")
        self.robot = robot
        self.templates = templates
        self.template_folder = template_folder
        self.frames_arrived = threading.Event()
        self.robots = robots
        self.frames = FrameTable()
        self.state = ServerState()
        self.state.instances = restored
        self.state_file = state_file
        self._state_lock = threading.RLock()
        self._robot_lock = threading.Lock()
        self._command_locks: dict[str, threading.Lock] = {}
        self._joints: dict[str, float] = {}
        self._robot_moving = False
        self._held_object = ""
        self._last_heartbeat = 0.0
        self._gripper_pose: str | None = None
        self._last_published: tuple | None = None

        services = ReentrantCallbackGroup()
        clients = ReentrantCallbackGroup()
        inputs = ReentrantCallbackGroup()
        status = MutuallyExclusiveCallbackGroup()

        self.status_publisher = self.create_publisher(ServerStatus, STATUS_TOPIC, 10)
        self.status_timer = self.create_timer(STATUS_PERIOD, self.status_timer_callback, callback_group=status)

        self.frames_subscription = self.create_subscription(NamedPoses, "/sim/frames", self.frames_callback, 10, callback_group=inputs)
        self.joint_subscription = self.create_subscription(JointState, "/joint_states", self.joint_states_callback, 10, callback_group=inputs)
        self.moving_subscription = self.create_subscription(Bool, "/robot/moving", self.moving_callback, LATCHED, callback_group=inputs)
        self.held_subscription = self.create_subscription(String, "/gripper/held_object", self.held_object_callback, LATCHED, callback_group=inputs)
        self.heartbeat_subscription = self.create_subscription(Header, "/planner/heartbeat", self.heartbeat_callback, 10, callback_group=inputs)

        self.planner_client = self.create_client(PlanWaypoints, "/planner/plan_waypoints", qos_profile=SERVICE_QOS, callback_group=clients)
        self.gripper_client = self.create_client(SetGripper, robot.gripper_service, qos_profile=SERVICE_QOS, callback_group=clients) if robot.gripper_service else None
        self.trajectory_client = RecordedActionClient(self, FollowJointTrajectory, robot.trajectory_action, callback_group=clients)

        for name, srv_type in SERVICES.items():
            callback = getattr(self, f"{name}_callback")
            self.create_service(srv_type, f"{PREFIX}/{name}", self._guarded(name, callback), qos_profile=SERVICE_QOS, callback_group=services)

    # --- inputs ----------------------------------------------------------------------------

    def frames_callback(self, msg: NamedPoses) -> None:
        self.frames.update(list(msg.names), [matrix_from_pose(p) for p in msg.poses])
        self.frames_arrived.set()

    def joint_states_callback(self, msg: JointState) -> None:
        with self._state_lock:
            self._joints.update(zip(msg.name, msg.position))

    def moving_callback(self, msg: Bool) -> None:
        with self._state_lock:
            self._robot_moving = bool(msg.data)
        self.publish_status()

    def held_object_callback(self, msg: String) -> None:
        with self._state_lock:
            self._held_object = msg.data
        self.publish_status()

    def heartbeat_callback(self, msg: Header) -> None:
        if msg.frame_id in ("", self.robot.robot_name):
            with self._state_lock:
                self._last_heartbeat = time.monotonic()

    # --- status ----------------------------------------------------------------------------

    def status_timer_callback(self) -> None:
        self.publish_status(force=True)

    def _plan_valid(self) -> bool:
        with self._state_lock:
            instance = self.state.instances.get(self.state.active_template)
            plan = instance.plan if instance else None
            if plan is None:
                return False
            return instance.stale_reason(plan, self.frames.snapshot(), dict(self._joints), self._held_object, JOINT_TOLERANCE) is None

    def status_message(self) -> ServerStatus:
        plan_valid = self._plan_valid()
        with self._state_lock:
            msg = ServerStatus()
            msg.stamp = self.get_clock().now().to_msg()
            msg.robot_name = self.robot.robot_name
            msg.robot_active = self._robot_moving
            msg.planner_node_active = time.monotonic() - self._last_heartbeat < HEARTBEAT_TIMEOUT
            msg.affordance_template_server_active = True
            msg.execute_status = self.state.execute_status
            msg.plan_status = self.state.plan_status
            msg.plan_valid = plan_valid
            msg.active_template = self.state.active_template
            msg.active_trajectory = self.state.active_trajectory
            msg.running_templates = sorted(self.state.instances)
            msg.last_error = self.state.last_error
        return msg

    def publish_status(self, *, force: bool = False) -> None:
        msg = self.status_message()
        key = (msg.robot_active, msg.planner_node_active, msg.execute_status, msg.plan_status, msg.plan_valid,
               msg.active_template, msg.active_trajectory, tuple(msg.running_templates), msg.last_error)
        with self._state_lock:
            changed = key != self._last_published
            self._last_published = key
        if force or changed:
            self.status_publisher.publish(msg)

    def _save_instances(self, done: str) -> None:
        """Write the instances to the state file after a change; ``done`` says what changed.

        The change has happened either way; a failed write is refused loudly, because a restart
        would lose it.
        """
        if self.state_file is None:
            return
        try:
            with self._state_lock:
                save_instances(self.state_file, self.robot, self.state.instances)
        except OSError as exc:
            raise CommandRefused(f"{done}, but the state file {self.state_file} could not be written ({exc}): a restart would lose it") from exc

    def _set_state(self, **fields: str) -> None:
        with self._state_lock:
            for name, value in fields.items():
                setattr(self.state, name, value)
        self.publish_status()

    # --- service plumbing ------------------------------------------------------------------

    def _guarded(self, name: str, callback):  # noqa: ANN001, ANN202
        """Answer every refusal with success false and its reason; log and report the unexpected."""

        def handle(request, response):  # noqa: ANN001, ANN202
            try:
                return callback(request, response)
            except (CommandRefused, InstanceError, UnknownFrame) as exc:
                message = str(exc)
            except Exception as exc:  # a bug must still answer the client, never hang it
                self.get_logger().error(f"{name} failed unexpectedly: {exc!r}")
                message = f"internal error in {name}: {exc!r}"
            response.success = False
            response.message = message
            with self._state_lock:
                self.state.last_error = f"{name}: {message}"
            self.publish_status()
            self.get_logger().warning(f"{name} refused: {message}")
            return response

        return handle

    def _template(self, name: str) -> Template:
        """The template called ``name``, re-reading the library folder once if it is not loaded yet.

        Raises:
            InstanceError: no such template, or the library no longer loads (the message says why).
        """
        template = self.templates.get(name)
        if template is None and self.template_folder is not None:
            try:
                self.templates = load_library(self.template_folder)
            except LibraryError as exc:
                raise InstanceError(f"unknown template {name!r}, and the library does not reload: {exc}") from None
            template = self.templates.get(name)
        if template is None:
            raise InstanceError(f"unknown template {name!r}; the library has: {', '.join(sorted(self.templates))}")
        return template

    def _instance(self, type_name: str, instance_id: int) -> TemplateInstance:
        key = f"{type_name}:{instance_id}"
        with self._state_lock:
            instance = self.state.instances.get(key)
            running = sorted(self.state.instances)
        if instance is None:
            self._template(type_name)
            raise InstanceError(f"no running instance {key!r}; running: {', '.join(running) or 'none'} (add_template first)")
        return instance

    def _command_lock(self, key: str) -> threading.Lock:
        with self._state_lock:
            return self._command_locks.setdefault(key, threading.Lock())

    def _succeed(self, response, message: str):  # noqa: ANN001, ANN202
        response.success = True
        response.message = message
        with self._state_lock:
            self.state.last_error = ""
        self.publish_status()
        return response

    # --- instances -------------------------------------------------------------------------

    def add_template_callback(self, request: AddAffordanceTemplate.Request, response: AddAffordanceTemplate.Response):
        template = self._template(request.class_type)
        frame = request.pose.header.frame_id
        if frame:
            root = self.frames.lookup(frame, FRAME_WAIT) @ matrix_from_pose(request.pose.pose)
        else:
            # The original placed new instances at the robot config's root_offset in frame_id.
            root = self.frames.lookup(self.robot.frame_id, FRAME_WAIT) @ self.robot.root_offset_matrix
        with self._state_lock:
            used = {i.id for i in self.state.instances.values() if i.template.name == template.name}
            instance = TemplateInstance(template, next_free_id(used), self.robot, root, hide_waypoints=request.hide_waypoints)
            self.state.instances[instance.key] = instance
        response.id = instance.id
        response.instance = instance.key
        self._save_instances(f"added {instance.key}")
        return self._succeed(response, f"added {instance.key}")

    def delete_template_callback(self, request: DeleteAffordanceTemplate.Request, response: DeleteAffordanceTemplate.Response):
        instance = self._instance(request.class_type, request.id)
        with self._state_lock:
            if self.state.executing == instance.key:
                raise CommandRefused(f"{instance.key} is executing; wait for it to finish before deleting it")
            del self.state.instances[instance.key]
            if self.state.active_template == instance.key:
                self.state.active_template = ""
                self.state.active_trajectory = ""
        self._save_instances(f"deleted {instance.key}")
        return self._succeed(response, f"deleted {instance.key}")

    def get_running_callback(self, request, response):  # noqa: ANN001, ANN201
        with self._state_lock:
            response.templates = sorted(self.state.instances)
        response.success = True
        response.message = f"{len(response.templates)} running"
        return response

    def get_templates_callback(self, request, response):  # noqa: ANN001, ANN201
        if request.name:
            self._template(request.name)
        names = [request.name] if request.name else sorted(self.templates)
        response.templates = [template_config(self.templates[n], self.robot) for n in names]
        response.success = True
        response.message = f"{len(names)} templates"
        return response

    def get_robots_callback(self, request, response):  # noqa: ANN001, ANN201
        if request.name and request.name not in self.robots:
            raise InstanceError(f"unknown robot {request.name!r}; known: {', '.join(sorted(self.robots))}")
        names = [request.name] if request.name else sorted(self.robots)
        response.robots = [robot_config_message(self.robots[n]) for n in names]
        response.success = True
        response.message = f"{len(names)} robots"
        return response

    # --- registration ----------------------------------------------------------------------

    def set_object_pose_callback(self, request: SetObjectPose.Request, response: SetObjectPose.Response):
        if not request.objects:
            raise CommandRefused("no objects given; pass one DisplayObjectInfo per object to register")
        # Check everything first: a request that fails changes nothing.
        updates = []
        for obj in request.objects:
            instance = self._instance(obj.type, obj.id)
            name = obj.name.split(":")[0]  # accept "cdra_filter" and the frame name "cdra_filter:0"
            if instance.template.display_object(name) is None:
                raise InstanceError(f"template {instance.template.name!r} has no display object {name!r}; it has: {', '.join(o.name for o in instance.template.display_objects)}")
            frame = obj.stamped_pose.header.frame_id or WORLD_FRAME
            frame_pose = self.frames.lookup(frame, FRAME_WAIT)
            updates.append((instance, name, Registration(frame, matrix_from_pose(obj.stamped_pose.pose), frame_pose)))
        for instance, name, registration in updates:
            with self._command_lock(instance.key), self._state_lock:
                instance.register(name, registration)
        done = "registered " + ", ".join(f"{n}:{i.id} to {r.frame}" for i, n, r in updates)
        self._save_instances(done)
        return self._succeed(response, done)

    def set_waypoint_pose_callback(self, request: SetWaypointPose.Request, response: SetWaypointPose.Response):
        instance = self._instance(request.type, request.id)
        trajectory = instance.trajectory(request.trajectory_name)
        ee = instance.end_effector(trajectory, [request.end_effector] if request.end_effector else [])
        group = trajectory.group(ee.id)
        assert group is not None
        if not 0 <= request.waypoint_id < len(group.waypoints):
            raise InstanceError(f"trajectory {trajectory.name!r} has waypoints 0..{len(group.waypoints) - 1} for {ee.name!r}, not {request.waypoint_id}")
        frame = request.pose.header.frame_id
        with self._command_lock(instance.key), self._state_lock:
            if frame:
                parent = self.frames.lookup(frame)
            else:
                parent = instance.object_pose(group.waypoints[request.waypoint_id].display_object)
            instance.set_waypoint(trajectory, ee, request.waypoint_id, parent @ matrix_from_pose(request.pose.pose))
        done = f"moved waypoint {ee.id}.{request.waypoint_id}:{instance.key} of {trajectory.name!r}"
        self._save_instances(done)
        return self._succeed(response, done)

    # --- plan ------------------------------------------------------------------------------

    def plan_command_callback(self, request: AffordanceTemplatePlanCommand.Request, response: AffordanceTemplatePlanCommand.Response):
        instance = self._instance(request.type, request.id)
        trajectory = instance.trajectory(request.trajectory_name)
        ee = instance.end_effector(trajectory, list(request.end_effectors))
        group = trajectory.group(ee.id)
        assert group is not None
        lock = self._command_lock(instance.key)
        if not lock.acquire(timeout=PLAN_TIMEOUT):
            raise CommandRefused(f"{instance.key} is busy with another command")
        try:
            with self._state_lock:
                if self.state.executing:
                    raise CommandRefused(f"the robot is executing {self.state.executing}; plan after it finishes")
                progress = instance.progress[trajectory.name]
                steps = int(request.steps[0]) if len(request.steps) else None
                indices = path_sequence(len(group.waypoints), progress.current_index, steps, direct=request.direct, backwards=request.backwards)
                resolved = instance.resolve(trajectory, ee)
                joints = dict(self._joints)
                held = self._held_object
                registrations = dict(instance.registrations)
                instance.current_trajectory = trajectory.name
                instance.invalidate_plan()
            self._set_state(plan_status=ServerStatus.PLAN_PLANNING, active_template=instance.key, active_trajectory=trajectory.name)
            try:
                segments = self._request_plan([resolved[i] for i in indices], joints, held)
            except CommandRefused as exc:
                self._set_state(plan_status=ServerStatus.PLAN_FAILED)
                raise CommandRefused(f"planning {trajectory.name!r} of {instance.key} failed: {exc}") from exc
            with self._state_lock:
                instance.plan = StoredPlan(
                    trajectory=trajectory.name, end_effector=ee.name, indices=indices, segments=segments,
                    start_joints={j: joints[j] for j in self.robot.joint_names}, registrations=registrations, held_object=held,
                )
                progress.plan_index = indices[-1]
            self._set_state(plan_status=ServerStatus.PLAN_PLANNED)
        finally:
            lock.release()
        message = f"planned {trajectory.name!r} of {instance.key}: waypoints {indices}"
        if request.execute:
            message += "; " + self._execute(instance, trajectory.name)
        response.affordance_template_status = self._status_of(instance, trajectory.name)
        return self._succeed(response, message)

    def _request_plan(self, waypoints, joints: dict[str, float], held: str):  # noqa: ANN001, ANN202
        missing = [j for j in self.robot.joint_names if j not in joints]
        if missing:
            raise CommandRefused(f"no /joint_states for {missing} yet; is the simulation running?")
        if not self.planner_client.wait_for_service(timeout_sec=2.0):
            raise CommandRefused("the planner node does not answer on /planner/plan_waypoints; start `caretaker planner --robot NAME`")
        request = PlanWaypoints.Request()
        request.robot_name = self.robot.robot_name
        request.start_state.name = list(self.robot.joint_names)
        request.start_state.position = [float(joints[j]) for j in self.robot.joint_names]
        request.held_object = held
        for wp in waypoints:
            goal = WaypointGoal()
            goal.label = wp.label
            goal.pose.header.frame_id = WORLD_FRAME
            goal.pose.pose = pose_from_matrix(wp.tool_goal)
            goal.planner_type = wp.waypoint.planner_type
            goal.end_effector_pose = wp.end_effector_pose
            # Tight: a 0.01 rad tilt at the gripper is 2 mm at the far end of a carried filter.
            goal.position_tolerance = 5e-4
            goal.orientation_tolerance = 2e-3
            request.waypoints.append(goal)
        result = _wait(self.planner_client.call_async(request), PLAN_TIMEOUT, "the planner")
        if not result.success:
            raise CommandRefused(result.message)
        return list(result.segments)

    # --- execute ---------------------------------------------------------------------------

    def execute_command_callback(self, request: AffordanceTemplateExecuteCommand.Request, response: AffordanceTemplateExecuteCommand.Response):
        instance = self._instance(request.type, request.id)
        trajectory = instance.trajectory(request.trajectory_name)
        if request.end_effectors:
            instance.end_effector(trajectory, list(request.end_effectors))
        message = self._execute(instance, trajectory.name)
        response.affordance_template_status = self._status_of(instance, trajectory.name)
        return self._succeed(response, message)

    def _execute(self, instance: TemplateInstance, trajectory: str) -> str:
        if not self._robot_lock.acquire(blocking=False):
            with self._state_lock:
                busy = self.state.executing
            raise CommandRefused(f"the robot is executing {busy or 'another command'}; this command was refused, not queued")
        try:
            with self._state_lock:
                plan = instance.plan
                if plan is None or plan.trajectory != trajectory:
                    raise CommandRefused(f"no valid plan for {trajectory!r} of {instance.key}; call plan_command first")
                reason = instance.stale_reason(plan, self.frames.snapshot(), dict(self._joints), self._held_object, JOINT_TOLERANCE)
                if reason is not None:
                    raise CommandRefused(f"the plan for {trajectory!r} of {instance.key} is no longer valid: {reason}")
                self.state.executing = instance.key
                instance.invalidate_plan()  # a plan runs once; the robot is about to leave its start
            self._set_state(execute_status=ServerStatus.EXECUTE_EXECUTING, active_template=instance.key, active_trajectory=trajectory)
            progress = instance.progress[trajectory]
            progress.execution_valid = False
            # Command the first gripper pose even if it seems unchanged: something else may have moved it.
            self._gripper_pose = None
            try:
                for index, segment in zip(plan.indices, plan.segments):
                    self._run_segment(segment)
                    progress.current_index = index
            except Exception as exc:  # whatever stopped the robot, the status must not stay EXECUTING
                self._set_state(execute_status=ServerStatus.EXECUTE_FAILED)
                reason = str(exc) if isinstance(exc, CommandRefused) else repr(exc)
                failure = f"executing {trajectory!r} of {instance.key} failed: {reason}"
                try:
                    self._save_instances(f"{instance.key} reached waypoint {progress.current_index} of {trajectory!r}")
                except CommandRefused as unsaved:
                    failure += f"; {unsaved}"
                raise CommandRefused(failure) from exc
            progress.execution_valid = True
            self._set_state(execute_status=ServerStatus.EXECUTE_SUCCEEDED)
            done = f"executed {trajectory!r} of {instance.key}: waypoints {plan.indices}"
            self._save_instances(done)
            return done
        finally:
            with self._state_lock:
                self.state.executing = ""
            self._robot_lock.release()

    def _run_segment(self, segment) -> None:  # noqa: ANN001 - affordance_template_msgs/PlannedSegment
        points = segment.arm_trajectory.points
        if len(points) >= 2:
            if not self.trajectory_client.wait_for_server(timeout_sec=5.0):
                raise CommandRefused(f"the trajectory action {self.robot.trajectory_action} is not available")
            goal = FollowJointTrajectory.Goal()
            goal.trajectory = segment.arm_trajectory
            handle = _wait(self.trajectory_client.send_goal_async(goal), 10.0, "the trajectory action")
            if not handle.accepted:
                raise CommandRefused(f"waypoint {segment.label}: the controller rejected the trajectory")
            last = points[-1].time_from_start
            timeout = 30.0 + 3.0 * (last.sec + last.nanosec * 1e-9)
            outcome = _wait(handle.get_result_async(), timeout, "the trajectory action")
            if outcome.result.error_code != FollowJointTrajectory.Goal.SUCCESSFUL:  # the .action puts the codes on Goal
                raise CommandRefused(f"waypoint {segment.label}: {outcome.result.error_string or f'error code {outcome.result.error_code}'}")
        pose = segment.end_effector_pose
        if pose and self.gripper_client is not None and pose != self._gripper_pose:
            if not self.gripper_client.wait_for_service(timeout_sec=5.0):
                raise CommandRefused(f"the gripper service {self.robot.gripper_service} is not available")
            request = SetGripper.Request()
            request.pose = pose
            result = _wait(self.gripper_client.call_async(request), 30.0, "the gripper")
            if not result.success:
                raise CommandRefused(f"waypoint {segment.label}: gripper {pose!r} failed: {result.message}")
            self._gripper_pose = pose
            with self._state_lock:
                self._held_object = result.held_object

    # --- status services -------------------------------------------------------------------

    def _status_of(self, instance: TemplateInstance, trajectory: str, frame: str = "") -> AffordanceTemplateStatus:
        frame = frame or self.robot.frame_id
        try:
            frame_pose = self.frames.lookup(frame)
        except UnknownFrame:
            if frame != self.robot.frame_id:
                raise
            frame, frame_pose = WORLD_FRAME, self.frames.lookup(WORLD_FRAME)
        with self._state_lock:
            active = self.state.active_template == instance.key and self.state.active_trajectory == trajectory
            plan_status = self.state.plan_status if active else ServerStatus.PLAN_IDLE
            execute_status = self.state.execute_status if active else ServerStatus.EXECUTE_IDLE
            valid = instance.plan is not None and instance.plan.trajectory == trajectory and (
                instance.stale_reason(instance.plan, self.frames.snapshot(), dict(self._joints), self._held_object, JOINT_TOLERANCE) is None
            )
            return instance_status(instance, trajectory, frame, frame_pose, plan_status=plan_status, execute_status=execute_status, plan_valid=valid)

    def get_template_status_callback(self, request: GetAffordanceTemplateStatus.Request, response: GetAffordanceTemplateStatus.Response):
        type_name, _, id_text = request.name.partition(":")
        if not id_text.isdigit():
            raise InstanceError(f"name must be 'Type:id' (e.g. 'cdra_filter:0'), got {request.name!r}")
        instance = self._instance(type_name, int(id_text))
        names = [instance.trajectory(request.trajectory_name).name] if request.trajectory_name else instance.template.trajectory_names
        response.affordance_template_status = [self._status_of(instance, n, request.frame_id) for n in names]
        response.current_trajectory = instance.current_trajectory
        response.trajectory_names = instance.template.trajectory_names
        response.success = True
        response.message = f"status of {instance.key}"
        return response

    def get_status_callback(self, request, response):  # noqa: ANN001, ANN201
        response.status = self.status_message()
        with self._state_lock:
            response.ready = not self.state.executing
        response.success = True
        response.message = "executing " + self.state.executing if self.state.executing else "ready"
        return response


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="caretaker at-server", description=__doc__.splitlines()[0])
    parser.add_argument("--robot", required=True, help="robot_name of a robot config in the AT library")
    parser.add_argument("--library", default=str(default_library_path()), help="library folder with templates/ and robots/")
    parser.add_argument("--state-file", type=Path,
                        help="keep the instances here and restore them at start, so a restarted server carries on (default: not kept)")
    args, ros_args = parser.parse_known_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        templates = load_library(f"{args.library}/templates")
        robots = load_robot_configs(f"{args.library}/robots")
    except LibraryError as exc:
        print(f"caretaker at-server: {exc}", file=sys.stderr)
        return 2
    if args.robot not in robots:
        print(f"caretaker at-server: unknown robot {args.robot!r}; known: {', '.join(sorted(robots))}", file=sys.stderr)
        return 2
    rclpy.init(args=ros_args)
    node = None
    executor = MultiThreadedExecutor(num_threads=6)
    try:
        try:
            node = AffordanceTemplateServer(robots[args.robot], templates, robots,
                                            template_folder=Path(args.library) / "templates", state_file=args.state_file)
        except LibraryError as exc:
            print(f"caretaker at-server: {exc}", file=sys.stderr)
            return 2
        if node.state.instances:
            print(f"restored {', '.join(sorted(node.state.instances))} from {args.state_file}", flush=True)
        executor.add_node(node)
        # Serving means able to register templates: that needs the world's frames.
        while not node.frames_arrived.is_set():
            executor.spin_once(timeout_sec=0.1)
        print(f"READY at-server {args.robot}", flush=True)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0

