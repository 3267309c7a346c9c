"""``caretaker sim --scene FILE|iva|eva``: the simulated robot and world as a ROS 2 node.

Names and types follow docs/interfaces.md (Simulation). One thread steps the physics (paced to
``--time-scale`` × real time, or as fast as possible with 0 while anything moves) and publishes
the sim-time-rate topics; the executor's threads serve the action, services and cameras. They
meet at ``Simulation.world_lock``.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import rclpy
from builtin_interfaces.msg import Time
from caretaker_sim_msgs.action import FollowJointTrajectory
from caretaker_sim_msgs.msg import CollisionWorld, Markers, NamedPoses, VisualWorld
from caretaker_sim_msgs.srv import CaptureImage, FindFilter, GetFrames, Halt, PrintMarker
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from sim.cabin_air_node import CabinAirInterface
from sim.cabin_knobs import add_options, given
from sim.cameras import CameraImage, capture_file_name, fixed_camera_pose, render, write_png
from sim.cdra_cabinet import find_filter
from sim.collision_world import collision_world, point_pose
from sim.gripper_node import GripperInterface
from sim.halt_order import HaltOrder
from sim.perception_model import camera_info, markers_message
from sim.publish_gate import PublishGate
from sim.render_budget import RenderBudget
from sim.robot_description import robot_description
from sim.scene import SceneError, load_scene
from sim.simulation import Simulation
from sim.trajectory import ErrorCode, TrajectoryError, validate_trajectory
from sim.visual_world import visual_world

__all__ = ["SimNode", "main"]

LOG = logging.getLogger("sim")

JOINT_STATE_PERIOD = 1.0 / 60.0  # s of sim time (>= 50 Hz)
FRAMES_PERIOD = 0.1  # s of sim time
#: s of wall time between sim/frames at least: a view across the link asks for them at a
#: bounded rate, and at --time-scale 0 sim time can run many times faster than the wall clock.
FRAMES_MIN_WALL_PERIOD = 0.05
STATUS_PERIOD = 1.0  # s of sim time; status topics are also published on every change
#: s of sim time between repeats of joint states and frames that have not changed (publish_gate.py)
REST_PERIOD = 1.0
#: Physics steps of sim time per wake-up while nothing moves: a quarter of the wake-ups.
IDLE_BATCH = 4
#: s of sim time the physics still runs after the last thing moved, so that whatever was let go
#: settles; after that a world at rest only has its clock moved (Simulation.rest), which took an
#: idle simulator from 8 % of a core, most of it pybullet stepping bodies at rest, to next to nothing.
SETTLE_S = 0.5
#: s of wall time a trajectory's clock may stand still before its run is given up as stalled.
STALLED_S = 60.0
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
#: Requests a service keeps queued: ROS's default of 10 drops the rest of a burst silently.
SERVICE_QOS = QoSProfile(depth=1000, durability=DurabilityPolicy.VOLATILE, reliability=ReliabilityPolicy.RELIABLE)


class SimNode(Node):
    """ROS face of one :class:`Simulation`; owns the stepping thread."""

    def __init__(
        self, sim: Simulation, *, time_scale: float, namespace: str, capture_dir: Path, camera_period: float
    ) -> None:
        super().__init__("caretaker_sim", namespace=namespace)
        self.sim = sim
        # A parameter, so that a test (or an operator's tool) can slow one motion down to watch it
        # or halt it mid-way, and run the rest flat out: ``ros2 param set /caretaker_sim time_scale 0.25``.
        self.time_scale = time_scale
        # dynamic typing: ``time_scale 1`` (an integer) is as good as 1.0; the callback checks the value
        self.declare_parameter("time_scale", time_scale, ParameterDescriptor(dynamic_typing=True))
        self.add_on_set_parameters_callback(self._on_time_scale)
        self.capture_dir = capture_dir
        group = ReentrantCallbackGroup()
        # Latched: at rest they are published once a second (publish_gate.py), and a part that
        # starts then (an AT server restarted mid-run) must not plan without the arm's state.
        # Depth 1: a late subscriber gets the newest sample only, never a replay of older ones
        # (a depth of 10 handed a late reader the part's pose from mid-motion).
        self.joint_state_pub = self.create_publisher(JointState, "joint_states", LATCHED)
        self.frames_pub = self.create_publisher(NamedPoses, "sim/frames", LATCHED)
        self.moving_pub = self.create_publisher(Bool, "robot/moving", LATCHED)
        self.collision_world_pub = self.create_publisher(CollisionWorld, "sim/collision_world", LATCHED)
        self.collision_world_pub.publish(collision_world(sim.scene))
        self.visual_world_pub = self.create_publisher(VisualWorld, "sim/visual_world", LATCHED)
        self.visual_world_pub.publish(visual_world(sim.scene))
        self.description_pub = self.create_publisher(String, "robot_description", LATCHED)
        self.description_pub.publish(String(data=robot_description(sim.scene.robot.urdf)))
        self.markers_pub = self.create_publisher(Markers, "sim/markers", LATCHED)
        self.markers_pub.publish(markers_message(sim.scene))
        self.camera_info_pubs = {}
        for name, spec in sim.scene.cameras.items():
            self.camera_info_pubs[name] = self.create_publisher(CameraInfo, f"camera/{name}/camera_info", LATCHED)
            self.camera_info_pubs[name].publish(camera_info(spec))
        # The ground truth, for tests and world checks: nothing on the robot side calls these.
        self.true_frames_srv = self.create_service(
            GetFrames, "sim/check/frames", self.true_frames_callback, qos_profile=SERVICE_QOS, callback_group=group
        )
        self.print_marker_srv = self.create_service(
            PrintMarker, "sim/check/print_marker", self.print_marker_callback, qos_profile=SERVICE_QOS
        )
        # Stamps are sim time on a timeline that starts at the wall clock's now: at time scale 1
        # they track the wall clock (ages stay meaningful), and stamp differences are sim time.
        self._epoch_ns = self.get_clock().now().nanoseconds - int(sim.time * 1e9)
        # Halt has a node and a thread of its own (see main): it never queues behind a capture,
        # a gripper motion or a trajectory that holds the main executor's threads.
        self.halt_node = rclpy.create_node("caretaker_sim_halt", namespace=namespace)
        self.halt_srv = self.halt_node.create_service(Halt, "robot/halt", self.halt_callback, qos_profile=SERVICE_QOS)
        self.order = HaltOrder()  # under world_lock: the motion requests that crossed a halt never start
        self.trajectory_server = ActionServer(
            self,
            FollowJointTrajectory,
            "arm_controller/follow_joint_trajectory",
            execute_callback=self.execute_callback,
            goal_callback=self.goal_callback,
            cancel_callback=self.cancel_callback,
            callback_group=group,
        )
        self.capture_srv = self.create_service(
            CaptureImage, "camera/capture", self.capture_callback, qos_profile=SERVICE_QOS, callback_group=group
        )
        self.render_budget = RenderBudget()
        self.image_pubs = {name: self.create_publisher(Image, f"camera/{name}/image", 2) for name in sim.scene.cameras}
        if camera_period > 0:
            self.camera_timer = self.create_timer(camera_period, self.camera_timer_callback, callback_group=group)
        self.gripper = (
            GripperInterface(self, sim, self.order, self._wait, latched=LATCHED, services=SERVICE_QOS, group=group)
            if sim.gripper is not None
            else None
        )
        if sim.cabinet is not None:
            self.cdra_locked_pub = self.create_publisher(Bool, "cdra/filter_locked", LATCHED)
            self.cdra_present_pub = self.create_publisher(Bool, "cdra/filter_present", LATCHED)
            self.cdra_id_pub = self.create_publisher(String, "cdra/installed_filter_id", LATCHED)
            self.cdra_condition_pub = self.create_publisher(String, "cdra/installed_filter_condition", LATCHED)
            self.cdra_clean_pub = self.create_publisher(String, "cdra/clean_filter_ids", LATCHED)
            self.cabin_air = CabinAirInterface(self, sim, latched=LATCHED, group=group)
            self.unlock_srv = self.create_service(
                Trigger, "cdra/unlock_filter", self.unlock_callback, qos_profile=SERVICE_QOS, callback_group=group
            )
            self.lock_srv = self.create_service(
                Trigger, "cdra/lock_filter", self.lock_callback, qos_profile=SERVICE_QOS, callback_group=group
            )
            self.inventory_srvs = [
                self.create_service(
                    FindFilter, f"cdra/{name}", self.find_filter_callback, qos_profile=SERVICE_QOS, callback_group=group
                )
                for name in ("filter_in_slot", "slot_of_filter")
            ]
        self._last_status: tuple | None = None
        self._joint_gate = PublishGate(REST_PERIOD)
        self._frames_gate = PublishGate(REST_PERIOD)
        self.failed = False
        self._stop = threading.Event()
        self._stepper = threading.Thread(target=self._step_loop, name="sim-stepper", daemon=True)

    # ------------------------------------------------------------------ stepping thread

    def start(self) -> None:
        self._stepper.start()

    def stop(self) -> None:
        self._stop.set()
        if self._stepper.is_alive():
            self._stepper.join(10.0)

    def _step_loop(self) -> None:
        """Step, publish by sim time, and pace: real time × scale, or flat out while busy."""
        sim = self.sim
        next_joint_states = next_frames = next_status = 0.0
        frames_wall = 0.0
        wall_origin, sim_origin = time.monotonic(), sim.time
        paced_at = self.time_scale
        steps = 0
        moved_at = sim.time
        try:
            while not self._stop.is_set():
                sim.world_lock.give_way()  # a goal, a halt or a capture waiting for the world goes first
                with sim.world_lock:
                    if sim.busy:
                        sim.step()
                        moved_at = sim.time
                    elif sim.time - moved_at < SETTLE_S:
                        for _ in range(IDLE_BATCH):
                            sim.step()
                    else:
                        sim.rest(IDLE_BATCH)
                    now = sim.time
                    busy = sim.busy
                    if now >= next_joint_states:
                        next_joint_states = now + JOINT_STATE_PERIOD
                        self._publish_joint_states()
                        # status changes are looked for at the joint states' rate, not every step:
                        # a change seen 16 ms later is as good, for a quarter of the lookups
                        status = self._status()
                        if status != self._last_status or now >= next_status:
                            next_status = now + STATUS_PERIOD
                            self._publish_status(status)
                    if now >= next_frames and time.monotonic() - frames_wall >= FRAMES_MIN_WALL_PERIOD:
                        next_frames = now + FRAMES_PERIOD
                        frames_wall = time.monotonic()
                        self._publish_frames()
                steps += 1
                if self.time_scale != paced_at:  # changed at run time: pace from here at the new scale
                    paced_at = self.time_scale
                    wall_origin, sim_origin = time.monotonic(), now
                if self.time_scale > 0 or not busy:
                    # Idle at time scale 0 still runs at real time: nothing changes, and a
                    # simulator spinning flat out for nothing would starve the other processes.
                    scale = self.time_scale if self.time_scale > 0 else 1.0
                    target = wall_origin + (now - sim_origin) / scale
                    delay = target - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                    elif delay < -0.5:  # fell behind (machine busy): do not try to catch up
                        wall_origin, sim_origin = time.monotonic(), now
                else:
                    wall_origin, sim_origin = time.monotonic(), now
                    if steps % 50 == 0:
                        time.sleep(0)  # let the executor threads take the GIL
        except Exception:  # the stepper dying silently would freeze the robot while ROS looks alive
            if self._stop.is_set() or not self.context.ok():
                return  # Ctrl-C shut the ROS context down under a publish: a normal stop
            LOG.exception("simulation stepping failed; shutting down")
            self.failed = True
            rclpy.try_shutdown()

    def sim_stamp(self, sim_time: float | None = None) -> Time:
        """``sim_time`` (default: now; then the caller holds ``world_lock``) as header stamps carry it."""
        ns = self._epoch_ns + int(round((self.sim.time if sim_time is None else sim_time) * 1e9))
        return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def _publish_joint_states(self) -> None:
        names, positions, velocities = self.sim.joint_state()
        if not self._joint_gate.due([*positions, *velocities], self.sim.time):
            return
        msg = JointState()
        msg.header.stamp = self.sim_stamp()
        msg.name, msg.position, msg.velocity = names, positions, velocities
        self.joint_state_pub.publish(msg)

    def _publish_frames(self) -> None:
        frames = self.sim.frames()
        if not self._frames_gate.due([v for _, (pos, orn) in frames for v in (*pos, *orn)], self.sim.time):
            return
        self.frames_pub.publish(self._named_poses(frames))

    def _named_poses(self, frames: Sequence[tuple[str, CameraPose]]) -> NamedPoses:
        msg = NamedPoses()
        msg.header.stamp = self.sim_stamp()
        msg.header.frame_id = "world"
        for name, (pos, orn) in frames:
            msg.names.append(name)
            msg.poses.append(point_pose(pos, orn))
        return msg

    def true_frames_callback(self, request: GetFrames.Request, response: GetFrames.Response) -> GetFrames.Response:
        with self.sim.world_lock:
            response.frames = self._named_poses(self.sim.true_frames())
        return response

    def print_marker_callback(
        self, request: PrintMarker.Request, response: PrintMarker.Response
    ) -> PrintMarker.Response:
        markers = self.sim.world.markers
        if request.id not in markers:
            response.success = False
            response.message = f"no marker {request.id} is declared; markers are {sorted(markers)}"
            return response
        with self.sim.world_lock:
            self.sim.world.print_marker(request.id, request.printed_id)
        shown = "nothing (covered)" if request.printed_id < 0 else f"marker {request.printed_id}"
        response.success, response.message = True, f"marker {request.id} now shows {shown}"
        return response

    def _status(self) -> tuple:
        sim = self.sim
        cdra = sim.cabinet.telemetry(sim.filters) if sim.cabinet else None
        return (sim.moving, sim.held_object(), sim.gripper.grasp_state() if sim.gripper else "", cdra)

    def _publish_status(self, status: tuple) -> None:
        moving, held, grasp, cdra = status
        self._last_status = status
        self.moving_pub.publish(Bool(data=moving))
        if self.gripper is not None:
            self.gripper.publish(held, grasp)
        if cdra is not None:
            self.cdra_locked_pub.publish(Bool(data=cdra.filter_locked))
            self.cdra_present_pub.publish(Bool(data=cdra.filter_present))
            self.cdra_id_pub.publish(String(data=cdra.installed_filter_id))
            self.cdra_condition_pub.publish(String(data=cdra.installed_filter_condition))
            self.cdra_clean_pub.publish(String(data=cdra.clean_filter_ids))

    def _on_time_scale(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse a time scale that is not a finite number >= 0 (the pacing would divide by it)."""
        for parameter in parameters:
            if parameter.name != "time_scale":
                continue
            value = parameter.value
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
                return SetParametersResult(successful=False, reason=f"time_scale must be a number >= 0, got {value!r}")
            self.time_scale = float(value)
        return SetParametersResult(successful=True)

    def _wait(self, done: threading.Event, sim_seconds: float) -> bool:
        """Wait for a physics-thread event; the timeout follows the time scale, generously."""
        scale = self.time_scale if self.time_scale > 0 else 1.0
        return done.wait(sim_seconds / scale + 30.0)

    # ------------------------------------------------------------------ trajectory action

    def goal_callback(self, goal_request: FollowJointTrajectory.Goal) -> GoalResponse:
        # Accept all (refusals go in the result's error_string); logged, so a late start shows.
        LOG.info("trajectory goal accepted: %d points", len(goal_request.trajectory.points))
        # Noted before the client hears the goal accepted: a halt its client sends after that
        # answer (at_ros.halt) then keeps the goal from starting, even if this process's halt
        # thread serves it before the goal's execution begins (sim/halt_order.py).
        with self.sim.world_lock:
            self.order.arrived(id(goal_request), goal_request.issued)
        return GoalResponse.ACCEPT

    def cancel_callback(self, goal_handle: ServerGoalHandle) -> CancelResponse:
        return CancelResponse.ACCEPT

    def execute_callback(self, goal_handle: ServerGoalHandle) -> FollowJointTrajectory.Result:
        called = time.monotonic()
        goal = goal_handle.request
        result = FollowJointTrajectory.Result()
        sim = self.sim
        points = [
            (pt.time_from_start.sec + pt.time_from_start.nanosec * 1e-9, list(pt.positions), list(pt.velocities))
            for pt in goal.trajectory.points
        ]
        with sim.world_lock:
            ticket = self.order.take(id(goal))  # the goal is the request accepted
        try:
            if not math.isfinite(goal.goal_tolerance) or goal.goal_tolerance < 0:
                raise TrajectoryError(
                    ErrorCode.INVALID_GOAL, f"goal_tolerance {goal.goal_tolerance} must be a finite number >= 0"
                )
            with sim.world_lock:
                current = tuple(sim.arm_positions)
            trajectory = validate_trajectory(
                list(goal.trajectory.joint_names),
                points,
                limits=sim.limits,
                controller_joints=sim.arm_joints,
                current=current,
                other_joints=sim.gripper_joints,
            )
        except TrajectoryError as exc:
            self.get_logger().warning(f"trajectory refused: {exc}")
            goal_handle.abort()
            result.error_code, result.error_string = exc.code, str(exc)
            return result
        with sim.world_lock:
            halted = self.order.refusal(ticket)
            if halted is not None:  # crossed a halt on its way: it must not move
                LOG.warning("trajectory refused: %s", halted)
                goal_handle.abort()
                result.error_code, result.error_string = ErrorCode.HALTED, halted
                return result
            if goal_handle.is_cancel_requested:  # cancelled before it started (a client that gave up on it)
                goal_handle.canceled()
                result.error_code, result.error_string = ErrorCode.HALTED, "cancelled before it started: nothing moved"
                return result
            run = sim.start_trajectory(trajectory, goal.goal_tolerance)
        LOG.info(
            "trajectory started: %.3f s long (%.2f s after its execution began, waiting for the world)",
            trajectory.duration,
            time.monotonic() - called,
        )
        feedback = FollowJointTrajectory.Feedback()
        feedback.joint_names = list(sim.arm_joints)
        # A run ends by the sim's clock; the wall clock only tells a stepper that stopped (no
        # progress for STALLED_S): a crowded machine slows the sim's clock, it does not stop it.
        # Feedback at the start and every 50 ms of wall time: even a time-scale-0 run reports once.
        progressed, progressed_at = run.elapsed, time.monotonic()
        while True:
            feedback.desired, feedback.actual = (
                list(run.desired or trajectory.positions[0]),
                list(run.actual or current),
            )
            feedback.time_from_start = run.elapsed
            goal_handle.publish_feedback(feedback)
            if run.done.wait(0.05):
                break
            if run.elapsed != progressed:
                progressed, progressed_at = run.elapsed, time.monotonic()
            if goal_handle.is_cancel_requested or time.monotonic() - progressed_at > STALLED_S:
                with sim.world_lock:
                    run.cancel_requested = True
        result.error_code, result.error_string = run.error_code, run.error_string
        if run.cancel_requested and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        elif run.error_code == ErrorCode.SUCCESSFUL and not run.cancel_requested:
            goal_handle.succeed()
        else:
            if run.cancel_requested:
                result.error_code, result.error_string = (
                    ErrorCode.PATH_TOLERANCE_VIOLATED,
                    f"the simulator's clock stood still for {STALLED_S:.0f} s: the trajectory did not finish",
                )
            goal_handle.abort()
        return result

    # ------------------------------------------------------------------ halt

    def halt_callback(self, request: Halt.Request, response: Halt.Response) -> Halt.Response:
        reason = request.reason or "no reason given"
        with self.sim.world_lock:
            self.order.halted(reason, request.arrived)
            stopped = self.sim.halt(reason)
        self.get_logger().warning(
            f"halt ({reason}): stopped {', '.join(stopped)}" if stopped else f"halt ({reason}): nothing was moving"
        )
        response.success, response.stopped = True, bool(stopped)
        response.message = f"halted {' and '.join(stopped)}" if stopped else "nothing was moving"
        return response

    # ------------------------------------------------------------------ CDRA cabinet

    def unlock_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        return self._set_lock(False, response)

    def lock_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        return self._set_lock(True, response)

    def _set_lock(self, locked: bool, response: Trigger.Response) -> Trigger.Response:
        sim = self.sim
        assert sim.cabinet is not None
        with sim.world_lock:
            response.message = sim.cabinet.set_locked(locked, sim.filters)
            response.success = True
        # The stepper publishes the changed telemetry on its next step (one publishing thread).
        return response

    def find_filter_callback(self, request: FindFilter.Request, response: FindFilter.Response) -> FindFilter.Response:
        """Both inventory services: which one was asked shows in which field the request names."""
        with self.sim.world_lock:
            found = find_filter(self.sim.filters, filter_id=request.filter_id, slot=request.slot)
        response.success, response.message = found.found, found.message
        response.filter_id, response.slot, response.condition = found.filter_id, found.slot, found.condition
        return response

    # ------------------------------------------------------------------ cameras

    def _render(self, name: str, *, wait: bool) -> tuple[CameraImage, float, CameraPose] | None:
        """An image of camera ``name``, its sim time and the camera's pose then, when the render
        budget gives a turn (``wait``: wait for it; else None when it is not due)."""
        if not self.render_budget.take_turn(wait):
            return None
        sim = self.sim
        spec = sim.scene.cameras[name]
        spent = 0.0
        try:
            with sim.world_lock:
                started = time.monotonic()
                link_pose = sim.link_pose(sim.world.link_index[spec.link]) if spec.link else None
                image = render(spec, sim.client, link_pose), sim.time, link_pose or fixed_camera_pose(spec)
                spent = time.monotonic() - started
            return image
        finally:
            self.render_budget.done(spent)

    def _image_msg(self, image: CameraImage, sim_time: float) -> Image:
        msg = Image()
        msg.header.stamp = self.sim_stamp(sim_time)
        msg.header.frame_id = f"camera/{image.camera}"
        msg.height, msg.width, msg.encoding, msg.step = image.height, image.width, "rgb8", image.width * 3
        msg.data = image.rgb
        return msg

    def camera_timer_callback(self) -> None:
        for name, pub in self.image_pubs.items():
            if pub.get_subscription_count() > 0:  # rendering costs CPU: only for someone watching
                rendered = self._render(name, wait=False)
                if rendered is not None:  # else not due (the render budget): this period has no image
                    pub.publish(self._image_msg(*rendered[:2]))

    def capture_callback(self, request: CaptureImage.Request, response: CaptureImage.Response) -> CaptureImage.Response:
        cameras = self.sim.scene.cameras
        if request.camera not in cameras:
            response.success, response.message = (
                False,
                f"unknown camera {request.camera!r}; cameras are {sorted(cameras)}",
            )
            return response
        rendered = self._render(request.camera, wait=True)
        assert rendered is not None  # waited for its turn
        image, sim_time, (position, orientation) = rendered
        response.image = self._image_msg(image, sim_time)
        response.camera_pose = point_pose(position, orientation)
        response.success = True
        if request.label:
            path = self.capture_dir / capture_file_name(self.sim.scene.name, request.camera, request.label, sim_time)
            try:
                write_png(image, path)
            except OSError as exc:
                response.success, response.message = False, f"could not save {path}: {exc}"
                return response
            response.path = str(path.resolve())
            response.message = f"saved {response.path}"
        else:
            response.message = f"{image.width}x{image.height} image from {request.camera}"
        return response


CameraPose = tuple[tuple[float, ...], tuple[float, ...]]


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="caretaker sim", description="Run a pybullet world as the robot's hardware (ROS 2 node)."
    )
    parser.add_argument("--scene", required=True, help="scene name (iva, eva) or path to a scene YAML file")
    parser.add_argument(
        "--time-scale",
        type=float,
        default=1.0,
        help="sim seconds per wall second; 0 = as fast as possible while anything moves",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed for every random generator")
    add_options(parser)  # the cabin's air, for a demonstration (sim/cabin_knobs.py)
    parser.add_argument(
        "--displace",
        type=int,
        metavar="SEED",
        help="build the world with its slot bodies and targets moved by a random offset of this seed"
        " (sim/displacement.py); sim/frames still says where the scene file puts them",
    )
    parser.add_argument("--namespace", default="", help="ROS namespace for all topics and services")
    parser.add_argument(
        "--capture-dir",
        type=Path,
        default=Path(tempfile.gettempdir()) / "caretaker-captures",
        help="where /camera/capture saves PNGs",
    )
    parser.add_argument(
        "--camera-period",
        type=float,
        default=1.0,
        help="wall seconds between published camera images (0 = only on request)",
    )
    parser.add_argument(
        "--snapshot", type=Path, metavar="PNG", help="render the scene camera to this PNG and exit (no ROS)"
    )
    args = parser.parse_args(argv)
    if not math.isfinite(args.time_scale) or args.time_scale < 0:
        parser.error(f"--time-scale must be >= 0, got {args.time_scale}")
    return args


def snapshot(scene_name: str, path: Path, *, seed: int = 0) -> Path:
    """Render the scene's ``scene`` camera after a short settling time: the docs images."""
    sim = Simulation(load_scene(scene_name), seed=seed)
    try:
        for _ in range(int(0.5 / sim.dt)):
            sim.step()
        return write_png(render(sim.scene.cameras["scene"], sim.client), path)
    finally:
        sim.close()


def _spin_until_stopped(executor: SingleThreadedExecutor | MultiThreadedExecutor) -> None:
    """Spin until Ctrl-C or shutdown, whichever thread sees it.

    The signal handler shuts the context down between two waits at any moment: rcl then refuses
    the next wait set with an RCLError, which is the same stop, not a failure.
    """
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except _rclpy.RCLError:
        if rclpy.ok():
            raise


def main(argv: list[str] | None = None) -> int:
    args = _parse(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    try:
        if args.snapshot:
            print(f"wrote {snapshot(args.scene, args.snapshot, seed=args.seed)}")
            return 0
        sim = Simulation(load_scene(args.scene), seed=args.seed, displace=args.displace, cabin=given(args))
    except SceneError as exc:
        print(f"caretaker sim: {exc}", file=sys.stderr)
        return 2
    rclpy.init()
    node = SimNode(
        sim,
        time_scale=args.time_scale,
        namespace=args.namespace,
        capture_dir=args.capture_dir,
        camera_period=args.camera_period,
    )
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    halt_executor = SingleThreadedExecutor()
    halt_executor.add_node(node.halt_node)
    halts = threading.Thread(target=_spin_until_stopped, args=(halt_executor,), name="halt", daemon=True)
    try:  # from the first thread on: a Ctrl-C anywhere (even during the READY line) tears down
        halts.start()
        node.start()
        displaced = "" if args.displace is None else f" (displaced, seed {args.displace})"
        print(f"READY sim {sim.scene.name}{displaced}", flush=True)
        _spin_until_stopped(executor)
    except KeyboardInterrupt:  # during the start, before the executor took over
        pass
    finally:
        # The threads must have left rcl before the process exits (else it aborts: "terminate
        # called without an active exception"), so a second Ctrl-C must not cut this short.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        node.stop()
        halt_executor.shutdown()
        if halts.ident is not None:
            halts.join(10.0)
        executor.shutdown()
        node.halt_node.destroy_node()
        node.destroy_node()
        sim.close()
        rclpy.try_shutdown()
    return 1 if node.failed else 0


if __name__ == "__main__":
    sys.exit(main())
