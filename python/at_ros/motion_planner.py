"""From a sequence of end-effector goals to timed joint trajectories, one per waypoint.

Each goal is reached from the end of the previous one (chained seeding, as the original AT
planner did): JOINT goals by IK + OMPL, CARTESIAN goals by a straight tool line whose samples
are solved by IK seeded from the previous sample and rejected on a joint jump. Gripper poses
change what the scene carries: closing on a graspable object attaches it to the tool for the
rest of the plan, opening detaches it.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from at_ros.ik import IkFailure, IkSolver
from at_ros.ompl_planner import JointPlanner, PlanningFailed
from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import PlannerSettings
from at_ros.time_parameterization import TimedPath, time_parameterize
from at_ros.transforms import angle_between, from_xyz_quat, to_xyz_quat

__all__ = ["Goal", "PlannedWaypoint", "MotionPlanner", "WaypointPlanningError"]

LOG = logging.getLogger(__name__)

JOINT = "JOINT"
CARTESIAN = "CARTESIAN"
GRASP_POSES = ("closed", "close", "grasp")
RELEASE_POSES = ("open", "release")
#: IK solutions tried as the goal of a JOINT waypoint before giving up.
GOAL_ALTERNATIVES = 3
#: How far (m) from the tool point a graspable object's origin may be to count as grasped.
GRASP_REACH = 0.25


@dataclass(frozen=True)
class Goal:
    label: str
    pose: np.ndarray  # world pose of the tool link
    planner_type: str
    end_effector_pose: str = ""
    position_tolerance: float = 1e-3
    orientation_tolerance: float = 1e-2


@dataclass(frozen=True)
class PlannedWaypoint:
    label: str
    path: TimedPath
    end_effector_pose: str
    planning_time: float


class WaypointPlanningError(RuntimeError):
    """A waypoint could not be planned; the message names the waypoint and why."""


def _slerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    dot = float(np.dot(q0, q1))
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + t * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = np.arccos(dot)
    return (np.sin((1 - t) * theta) * q0 + np.sin(t * theta) * q1) / np.sin(theta)


class MotionPlanner:
    def __init__(self, scene: PlanningScene, settings: PlannerSettings) -> None:
        self.scene = scene
        self.settings = settings
        rng = np.random.default_rng(settings.seed)
        self.ik = IkSolver(scene, seeds=settings.ik_seeds, iterations=settings.ik_iterations, residual=settings.ik_residual, rng=rng)
        self.joint_planner = JointPlanner(scene.limits.lower, scene.limits.upper, scene.is_valid, seed=settings.seed)

    def plan(self, start: np.ndarray, goals: list[Goal], *, held_object: str = "") -> list[PlannedWaypoint]:
        """Plan every goal in order from ``start``; the scene's attachment is restored afterwards.

        Raises:
            WaypointPlanningError: naming the first goal that failed and why.
        """
        scene = self.scene
        saved = scene.attachment
        scene.set_joints(start)
        if held_object:
            name = scene.object_name(held_object)
            if name is None:
                raise WaypointPlanningError(f"held object {held_object!r} is not in the planning scene")
            scene.attach(name)
        elif scene.attachment is not None:
            scene.detach()
        try:
            why = scene.collision(start)
            if why is not None:
                raise WaypointPlanningError(f"the start state is in collision ({why})")
            q = np.asarray(start, dtype=float)
            planned = []
            for goal in goals:
                t0 = time.perf_counter()
                path = self._plan_one(q, goal)
                timed = time_parameterize(path, scene.limits.velocity, self.settings.max_acceleration, velocity_scaling=self.settings.velocity_scaling)
                q = path[-1]
                self._update_attachment(q, goal.end_effector_pose)
                planned.append(PlannedWaypoint(goal.label, timed, goal.end_effector_pose, time.perf_counter() - t0))
            return planned
        finally:
            scene.attachment = saved

    def _plan_one(self, q: np.ndarray, goal: Goal) -> list[np.ndarray]:
        if goal.planner_type == JOINT:
            return self._joint(q, goal)
        if goal.planner_type == CARTESIAN:
            return self._cartesian(q, goal)
        raise WaypointPlanningError(f"waypoint {goal.label}: unknown planner type {goal.planner_type!r}")

    def _joint(self, q: np.ndarray, goal: Goal) -> list[np.ndarray]:
        """IK nearest to ``q``, then OMPL; if no path reaches that solution, other IK solutions
        (other arm configurations) are tried, since the nearest one may be boxed in."""
        limits = self.scene.limits
        failure = ""
        for attempt in range(GOAL_ALTERNATIVES):
            near = q if attempt == 0 else self.ik.rng.uniform(limits.lower, limits.upper)
            target = self.ik.solve(goal.pose, near, position_tolerance=goal.position_tolerance, orientation_tolerance=goal.orientation_tolerance)
            if isinstance(target, IkFailure):
                if attempt == 0:
                    raise WaypointPlanningError(f"waypoint {goal.label}: {target.describe()}")
                continue
            try:
                return self.joint_planner.plan(q, target, time_limit=self.settings.plan_time / GOAL_ALTERNATIVES, simplify_time=self.settings.simplify_time)
            except PlanningFailed as exc:
                failure = str(exc)
        raise WaypointPlanningError(f"waypoint {goal.label}: {failure} (tried {GOAL_ALTERNATIVES} IK solutions)")

    def _cartesian(self, q: np.ndarray, goal: Goal) -> list[np.ndarray]:
        scene = self.scene
        start_pose = scene.forward(q)
        p0, q0 = to_xyz_quat(start_pose)
        p1, q1 = to_xyz_quat(goal.pose)
        distance = float(np.linalg.norm(p1 - p0))
        rotation = angle_between(start_pose, goal.pose)
        steps = max(1, int(np.ceil(max(distance / self.settings.cartesian_step, rotation / 0.05))))
        path = [q]
        for i in range(1, steps + 1):
            t = i / steps
            target = from_xyz_quat(p0 + (p1 - p0) * t, _slerp(q0, q1, t))
            # Only the previous sample as seed: a random restart could jump to another arm configuration.
            result = self.ik.solve(target, path[-1], position_tolerance=goal.position_tolerance,
                                   orientation_tolerance=goal.orientation_tolerance, enough=1)
            if isinstance(result, IkFailure):
                raise WaypointPlanningError(f"waypoint {goal.label}: Cartesian line blocked at {t:.0%}: {result.describe()}")
            jump = float(np.max(np.abs(result - path[-1])))
            if jump > self.settings.jump_threshold:
                raise WaypointPlanningError(f"waypoint {goal.label}: Cartesian line breaks IK continuity at {t:.0%} (joint jump {jump:.2f} rad)")
            path.append(result)
        return path

    def _update_attachment(self, q: np.ndarray, end_effector_pose: str) -> None:
        scene = self.scene
        if end_effector_pose in RELEASE_POSES:
            scene.detach()
        elif end_effector_pose in GRASP_POSES and scene.attachment is None:
            tool = scene.forward(q)
            grasped = scene.nearest_graspable(tool[:3, 3], within=GRASP_REACH)
            if grasped is not None:
                scene.attach(grasped)
