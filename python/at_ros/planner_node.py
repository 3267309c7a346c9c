"""The planner node: plans end-effector waypoint sequences on its own pybullet planning scene.

``caretaker planner --robot NAME`` serves ``/planner/plan_waypoints`` (PlanWaypoints) and beats
``/planner/heartbeat`` at 2 Hz. It runs as its own process because OMPL's solve() holds the
GIL: inside the AT server it would starve status publishing and every other callback.
Everything runs on one executor thread, so frame updates never race a plan on the scene.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time

import numpy as np
import rclpy
from builtin_interfaces.msg import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, Header, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from affordance_template_msgs.msg import PlannedSegment
from affordance_template_msgs.srv import PlanWaypoints
from at_ros.api import SERVICE_QOS
from at_ros.library import LibraryError
from at_ros.messages import matrix_from_pose
from at_ros.motion_planner import Goal, MotionPlanner, PlannedWaypoint, WaypointPlanningError
from at_ros.robot_config import RobotConfig, load_robot_configs
from at_ros.scene_file import build_planning_scene
from at_ros.time_parameterization import TimedPath
from at_ros.transforms import invert
from caretaker_sim_msgs.msg import NamedPoses

__all__ = ["PlannerNode", "main", "trajectory_message"]

WORLD_FRAME = "world"
#: The simulation latches gripper/held_object and robot/moving.
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def trajectory_message(joint_names: tuple[str, ...], path: TimedPath) -> JointTrajectory:
    msg = JointTrajectory()
    msg.joint_names = list(joint_names)
    for t, q, v in zip(path.times, path.positions, path.velocities):
        point = JointTrajectoryPoint()
        point.positions = [float(x) for x in q]
        point.velocities = [float(x) for x in v]
        sec = int(t)
        point.time_from_start = Duration(sec=sec, nanosec=int(round((float(t) - sec) * 1e9)) % 1_000_000_000)
        msg.points.append(point)
    return msg


class PlannerNode(Node):
    def __init__(self, config: RobotConfig) -> None:
        super().__init__("planner")
        self.config = config
        self.scene = build_planning_scene(config)
        self.motion_planner = MotionPlanner(self.scene, config.planner)
        self.held_object = ""
        self.robot_moving = False
        self.grasp_transform: np.ndarray | None = None  # held object in the tool frame
        self.frames_subscription = self.create_subscription(NamedPoses, "/sim/frames", self.frames_callback, 10)
        self.held_subscription = self.create_subscription(String, "/gripper/held_object", self.held_object_callback, LATCHED)
        self.moving_subscription = self.create_subscription(Bool, "/robot/moving", self.moving_callback, LATCHED)
        self.plan_service = self.create_service(PlanWaypoints, "/planner/plan_waypoints", self.plan_callback, qos_profile=SERVICE_QOS)
        self.heartbeat_publisher = self.create_publisher(Header, "/planner/heartbeat", 10)
        self.heartbeat_timer = self.create_timer(0.5, self.heartbeat_callback)

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
        poses = {name: matrix_from_pose(pose) for name, pose in zip(msg.names, msg.poses)}
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
            start = self._start_state(request)
            goals = [self._goal(w) for w in request.waypoints]
            if not goals:
                raise WaypointPlanningError("no waypoints to plan")
            grasp = self.grasp_transform if request.held_object and request.held_object == self.held_object else None
            planned = self.motion_planner.plan(start, goals, held_object=request.held_object, held_transform=grasp)
        except WaypointPlanningError as exc:
            response.success = False
            response.message = str(exc)
            self.get_logger().warning(f"plan failed: {exc}")
            return response
        response.segments = [self._segment(p) for p in planned]
        response.success = True
        elapsed = time.perf_counter() - started
        response.message = f"planned {len(planned)} waypoints in {elapsed * 1000:.0f} ms"
        self.get_logger().info(response.message)
        return response

    def _start_state(self, request: PlanWaypoints.Request) -> np.ndarray:
        if request.robot_name and request.robot_name != self.config.robot_name:
            raise WaypointPlanningError(f"this planner plans for robot {self.config.robot_name!r}, not {request.robot_name!r}")
        named = dict(zip(request.start_state.name, request.start_state.position))
        missing = [j for j in self.config.joint_names if j not in named]
        if missing:
            raise WaypointPlanningError(f"start_state lacks joints {missing}")
        return np.array([named[j] for j in self.config.joint_names])

    def _goal(self, waypoint) -> Goal:  # noqa: ANN001 - affordance_template_msgs/WaypointGoal
        frame = waypoint.pose.header.frame_id or WORLD_FRAME
        if frame != WORLD_FRAME:
            raise WaypointPlanningError(f"waypoint {waypoint.label}: goals must be in frame {WORLD_FRAME!r}, got {frame!r}")
        return Goal(
            label=waypoint.label,
            pose=matrix_from_pose(waypoint.pose.pose),
            planner_type=waypoint.planner_type,
            end_effector_pose=waypoint.end_effector_pose,
            position_tolerance=waypoint.position_tolerance or 1e-3,
            orientation_tolerance=waypoint.orientation_tolerance or 1e-2,
        )

    def _segment(self, planned: PlannedWaypoint) -> PlannedSegment:
        segment = PlannedSegment()
        segment.label = planned.label
        segment.arm_trajectory = trajectory_message(self.config.joint_names, planned.path)
        segment.end_effector_pose = planned.end_effector_pose
        return segment


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="caretaker planner", description=__doc__.splitlines()[0])
    parser.add_argument("--robot", required=True, help="robot_name of a robot config in the AT library")
    args, ros_args = parser.parse_known_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        robots = load_robot_configs()
    except LibraryError as exc:
        print(f"caretaker planner: {exc}", file=sys.stderr)
        return 2
    if args.robot not in robots:
        print(f"caretaker planner: unknown robot {args.robot!r}; known: {', '.join(sorted(robots))}", file=sys.stderr)
        return 2
    rclpy.init(args=ros_args)
    node = None
    try:
        node = PlannerNode(robots[args.robot])
        print(f"READY planner {args.robot}", flush=True)
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
