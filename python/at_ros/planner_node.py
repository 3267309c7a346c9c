"""The planner node: plans end-effector waypoint sequences on its own pybullet planning scene.

``caretaker planner --robot NAME|FILE`` serves ``planner/plan_waypoints`` (PlanWaypoints) and
beats ``planner/heartbeat`` at 2 Hz, in its ``--namespace``. It runs as its own process because
OMPL's solve() holds the GIL: inside the AT server it would starve status publishing and every
other callback. Everything runs on one executor thread, so frame updates never race a plan on
the scene. Its collision world comes from ``sim/collision_world`` (:mod:`at_ros.collision_scene`);
it prints READY once that has arrived.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from typing import Any

import numpy as np
import rclpy
from affordance_template_msgs.msg import PlannedSegment
from affordance_template_msgs.srv import PlanWaypoints
from builtin_interfaces.msg import Duration
from caretaker_sim_msgs.msg import CollisionWorld, NamedPoses
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import Bool, Header, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from at_ros.api import LATCHED, SERVICE_QOS
from at_ros.collision_scene import build_planning_scene
from at_ros.command_line import add_robot_options, choose_robot, split_ros_args
from at_ros.library import LibraryError
from at_ros.messages import matrix_from_pose, pose_from_matrix
from at_ros.motion_planner import Goal, MotionPlanner, PlannedWaypoint, WaypointPlanningError
from at_ros.planning_scene import PlanningScene
from at_ros.registered_world import RegisteredFrame, located_world
from at_ros.robot_config import RobotConfig
from at_ros.time_parameterization import TimedPath
from at_ros.transforms import invert
from ros_process import spinning

__all__ = ["PlannerNode", "main", "trajectory_message"]

WORLD_FRAME = "world"
#: How long the planner waits at start for the world's geometry before giving up.
WORLD_TIMEOUT = 60.0


def trajectory_message(joint_names: tuple[str, ...], path: TimedPath) -> JointTrajectory:
    msg = JointTrajectory()
    msg.joint_names = list(joint_names)
    for t, q, v in zip(path.times, path.positions, path.velocities, strict=False):
        point = JointTrajectoryPoint()
        point.positions = [float(x) for x in q]
        point.velocities = [float(x) for x in v]
        sec = int(t)
        point.time_from_start = Duration(sec=sec, nanosec=int(round((float(t) - sec) * 1e9)) % 1_000_000_000)
        msg.points.append(point)
    return msg


class PlannerNode(Node):
    """Plans on a world it does not have until ``sim/collision_world`` arrives (:attr:`scene`)."""

    def __init__(self, config: RobotConfig, *, namespace: str = "") -> None:
        super().__init__("planner", namespace=namespace)
        self.config = config
        self.scene: PlanningScene | None = None
        self.motion_planner: MotionPlanner | None = None
        self.world_error = ""
        self.held_object = ""
        self.robot_moving = False
        self.grasp_transform: np.ndarray | None = None  # held object in the tool frame
        self.frames: dict[str, np.ndarray] = {}  # the world model's named frames (sim/frames), latest
        self.world_subscription = self.create_subscription(
            CollisionWorld, "sim/collision_world", self.world_callback, LATCHED
        )
        self.frames_subscription = self.create_subscription(NamedPoses, "sim/frames", self.frames_callback, LATCHED)
        self.held_subscription = self.create_subscription(
            String, "gripper/held_object", self.held_object_callback, LATCHED
        )
        self.moving_subscription = self.create_subscription(Bool, "robot/moving", self.moving_callback, LATCHED)
        self.plan_service = self.create_service(
            PlanWaypoints, "planner/plan_waypoints", self.plan_callback, qos_profile=SERVICE_QOS
        )
        self.heartbeat_publisher = self.create_publisher(Header, "planner/heartbeat", 10)
        self.heartbeat_timer = self.create_timer(0.5, self.heartbeat_callback)

    def destroy_node(self) -> None:
        """Also let go of the planning scene's physics client, which the node owns."""
        if self.scene is not None:
            self.scene.close()
        super().destroy_node()  # type: ignore[no-untyped-call]  # rclpy is not annotated

    def world_callback(self, msg: CollisionWorld) -> None:
        """Build the planning scene once from the first world that arrives (the world is static;
        what moves follows on sim/frames)."""
        if self.scene is not None:
            return
        try:
            self.scene = build_planning_scene(self.config, msg)
        except ValueError as exc:
            self.world_error = f"the collision world of scene {msg.scene!r} cannot be used: {exc}"
            return
        self.motion_planner = MotionPlanner(self.scene, self.config.planner)

    def heartbeat_callback(self) -> None:
        msg = Header()
        msg.stamp = self.get_clock().now().to_msg()
        msg.frame_id = self.config.robot_name
        self.heartbeat_publisher.publish(msg)

    def held_object_callback(self, msg: String) -> None:
        if msg.data != self.held_object:
            self.held_object = msg.data
            self.grasp_transform = None

    def moving_callback(self, msg: Bool) -> None:
        self.robot_moving = bool(msg.data)

    def frames_callback(self, msg: NamedPoses) -> None:
        """Mirror moving things (filters) and the robot base from the simulation's ground truth.

        The grasp transform of a held object is measured when it is first seen held and again
        whenever the arm carries it, never while the arm rests: a resting simulated gripper lets
        its part sag, and planning with the sagged pose would scrape it along every slot.
        """
        if self.scene is None:
            return
        poses = {name: matrix_from_pose(pose) for name, pose in zip(msg.names, msg.poses, strict=False)}
        self.frames = poses
        for name, pose in poses.items():
            if name in self.scene.graspable:
                self.scene.set_obstacle_pose(name, pose)
            elif name == self.config.base_frame:
                self.scene.set_base_pose(pose)
        held = self.scene.object_name(self.held_object) if self.held_object else None
        if held in poses and self.config.tool_link in poses and (self.grasp_transform is None or self.robot_moving):
            self.grasp_transform = invert(poses[self.config.tool_link]) @ poses[held]

    def plan_callback(self, request: PlanWaypoints.Request, response: PlanWaypoints.Response) -> PlanWaypoints.Response:
        started = time.perf_counter()
        try:
            if self.motion_planner is None:
                raise WaypointPlanningError("the planner has no collision world yet (sim/collision_world)")
            start = self._start_state(request)
            goals = [self._goal(w) for w in request.waypoints]
            if not goals:
                raise WaypointPlanningError("no waypoints to plan")
            grasp = self.grasp_transform if request.held_object and request.held_object == self.held_object else None
            registered = [
                RegisteredFrame(r.frame, matrix_from_pose(r.pose), matrix_from_pose(r.against))
                for r in request.registered
            ]
            held = self.motion_planner.scene.object_name(request.held_object) if request.held_object else None
            with located_world(self.motion_planner.scene, registered, self.frames, held):
                planned = self.motion_planner.plan(start, goals, held_object=request.held_object, held_transform=grasp)
        except WaypointPlanningError as exc:
            response.success = False
            response.message = str(exc)
            self.get_logger().warning(f"plan failed: {exc}")  # type: ignore[no-untyped-call]  # rclpy is not annotated
            return response
        # The tool's pose at each waypoint as planned (FK of its last point): a view's ghost arm
        # and the AT server's get_plan report it; the world is left as it was.
        saved = self.motion_planner.scene.snapshot()
        try:
            tool_poses = [self.motion_planner.scene.forward(p.path.positions[-1]) for p in planned]
        finally:
            self.motion_planner.scene.restore(saved)
        response.segments = [self._segment(p, pose) for p, pose in zip(planned, tool_poses, strict=False)]
        response.success = True
        elapsed = time.perf_counter() - started
        response.message = f"planned {len(planned)} waypoints in {elapsed * 1000:.0f} ms"
        self.get_logger().info(response.message)  # type: ignore[no-untyped-call]
        return response

    def _start_state(self, request: PlanWaypoints.Request) -> np.ndarray:
        if request.robot_name and request.robot_name != self.config.robot_name:
            raise WaypointPlanningError(
                f"this planner plans for robot {self.config.robot_name!r}, not {request.robot_name!r}"
            )
        named = dict(zip(request.start_state.name, request.start_state.position, strict=False))
        missing = [j for j in self.config.joint_names if j not in named]
        if missing:
            raise WaypointPlanningError(f"start_state lacks joints {missing}")
        return np.array([named[j] for j in self.config.joint_names])

    def _goal(self, waypoint: Any) -> Goal:  # affordance_template_msgs/WaypointGoal
        frame = waypoint.pose.header.frame_id or WORLD_FRAME
        if frame != WORLD_FRAME:
            raise WaypointPlanningError(
                f"waypoint {waypoint.label}: goals must be in frame {WORLD_FRAME!r}, got {frame!r}"
            )
        return Goal(
            label=waypoint.label,
            source=waypoint.source,
            pose=matrix_from_pose(waypoint.pose.pose),
            planner_type=waypoint.planner_type,
            end_effector_pose=waypoint.end_effector_pose,
            position_tolerance=waypoint.position_tolerance or 1e-3,
            orientation_tolerance=waypoint.orientation_tolerance or 1e-2,
            gripper_action=waypoint.gripper_action,
            object_name=waypoint.object_name,
            object_pose=matrix_from_pose(waypoint.object_pose) if waypoint.gripper_action else None,
        )

    def _segment(self, planned: PlannedWaypoint, tool_pose: np.ndarray) -> PlannedSegment:
        segment = PlannedSegment()
        segment.label = planned.label
        segment.arm_trajectory = trajectory_message(self.config.joint_names, planned.path)
        segment.end_effector_pose = planned.end_effector_pose
        segment.tool_pose = pose_from_matrix(tool_pose)
        return segment


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="caretaker planner", description=__doc__.splitlines()[0])
    add_robot_options(parser)
    ours, ros_args = split_ros_args(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(ours)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        config = choose_robot(args).robot
    except LibraryError as exc:
        print(f"caretaker planner: {exc}", file=sys.stderr)
        return 2
    rclpy.init(args=["caretaker-planner", *ros_args])
    executor = SingleThreadedExecutor()
    with spinning(executor) as nodes:
        node = PlannerNode(config, namespace=args.namespace)
        nodes.append(node)
        executor.add_node(node)
        deadline = time.monotonic() + WORLD_TIMEOUT
        while node.scene is None and not node.world_error and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        if node.scene is None:
            topic = node.world_subscription.topic_name
            problem = node.world_error or (
                f"no collision world on {topic} within {WORLD_TIMEOUT:.0f} s; "
                "is the simulation (or world model) running in this ROS domain and namespace?"
            )
            print(f"caretaker planner: {problem}", file=sys.stderr)
            return 2
        print(f"READY planner {config.robot_name}", flush=True)
        executor.spin()
    return 0
