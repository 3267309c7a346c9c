"""From a sequence of end-effector goals to timed joint trajectories, one per waypoint.

Each goal is reached from the end of the previous one (chained seeding, as the original AT
planner did): JOINT goals by IK + OMPL, CARTESIAN goals by a straight tool line whose samples
are solved by IK seeded from the previous sample and rejected on a joint jump. What the scene
carries changes only where the template says so: at a waypoint that grasps an object, the
graspable object of the world found where the template's object is registered is attached to the
tool for the rest of the plan; at a waypoint that releases it, it is detached. A gripper pose
named "closed" near some object grasps nothing by itself.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from at_ros.ik import IkFailure, IkSolver
from at_ros.library import GRASP, RELEASE
from at_ros.ompl_planner import JointPlanner, PlanningFailed
from at_ros.planning_scene import PlanningScene
from at_ros.robot_config import PlannerSettings
from at_ros.time_parameterization import TimedPath, time_parameterize
from at_ros.transforms import angle_between, from_xyz_quat, invert, pose_text, to_xyz_quat

__all__ = ["Goal", "PlannedWaypoint", "MotionPlanner", "WaypointPlanningError"]


JOINT = "JOINT"
CARTESIAN = "CARTESIAN"
#: Halvings of a Cartesian step tried before a line counts as broken.
CARTESIAN_SUBDIVISIONS = 3
#: Share of plan_time per attempt, one attempt per IK solution (arm configuration) tried as the
#: goal of a JOINT waypoint: a reachable goal is found by RRTConnect in tens of ms, so a first
#: attempt that runs long is usually boxed in and another configuration is cheaper. A UR arm has
#: up to eight configurations per pose.
ATTEMPT_BUDGET = (0.1, 0.15, 0.2, 0.25, 0.3, 0.3, 0.3, 0.3)
GOAL_ALTERNATIVES = len(ATTEMPT_BUDGET)
#: Two IK solutions are different arm configurations when some joint differs by more (rad).
DISTINCT_CONFIGURATION = 0.5
#: Random-seed IK solves spent looking for a configuration not tried yet.
DISTINCT_SEARCH = 8


@dataclass(frozen=True)
class Goal:
    label: str
    pose: np.ndarray  # world pose of the tool link
    planner_type: str
    end_effector_pose: str = ""
    position_tolerance: float = 1e-3
    orientation_tolerance: float = 1e-2
    gripper_action: str = ""  # GRASP, RELEASE or "": what the template says happens here
    object_name: str = ""  # the template's display object grasped or released
    object_pose: np.ndarray | None = None  # world pose of that display object (for a grasp)
    source: str = ""  # "<template file>:<line>" that states this waypoint ("" = none does)

    @property
    def where(self) -> str:
        """The waypoint as failures name it: by its frame, and where to change it in its template."""
        return f"waypoint {self.label} ({self.source})" if self.source else f"waypoint {self.label}"


@dataclass(frozen=True)
class PlannedWaypoint:
    label: str
    path: TimedPath
    end_effector_pose: str
    planning_time: float


class WaypointPlanningError(RuntimeError):
    """A waypoint could not be planned; the message names the waypoint and why.

    ``final`` means retrying with another arm configuration cannot help (no configuration within
    the limits and free of collisions reaches the pose).
    """

    def __init__(self, message: str, *, final: bool = False) -> None:
        super().__init__(message)
        self.final = final


def _shape_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest joint difference modulo a full turn: solutions a turn apart on a joint have the
    same arm shape (the same collisions, the same Cartesian reach), so they are one configuration."""
    return float(np.max(np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))))


def _slerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    dot = float(np.dot(q0, q1))
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q: np.ndarray = q0 + t * (q1 - q0)
        normalized: np.ndarray = q / np.linalg.norm(q)
        return normalized
    theta = np.arccos(dot)
    slerped: np.ndarray = (np.sin((1 - t) * theta) * q0 + np.sin(t * theta) * q1) / np.sin(theta)
    return slerped


class MotionPlanner:
    def __init__(self, scene: PlanningScene, settings: PlannerSettings) -> None:
        self.scene = scene
        self.settings = settings
        rng = np.random.default_rng(settings.seed)
        self.ik = IkSolver(
            scene, seeds=settings.ik_seeds, iterations=settings.ik_iterations, residual=settings.ik_residual, rng=rng
        )
        self.joint_planner = JointPlanner(scene.limits.lower, scene.limits.upper, scene.is_valid, seed=settings.seed)

    def plan(
        self, start: np.ndarray, goals: list[Goal], *, held_object: str = "", held_transform: np.ndarray | None = None
    ) -> list[PlannedWaypoint]:
        """Plan every goal in order from ``start``; the scene (attachment, object poses) is restored afterwards.

        Args:
            held_object: the object in the gripper at ``start`` ("" = none).
            held_transform: its pose in the tool frame; by default where it is now.

        Raises:
            WaypointPlanningError: naming the first goal that failed and why.
        """
        scene = self.scene
        # Carrying an object during planning moves its body; the world must not keep that.
        saved = scene.snapshot()
        scene.set_joints(start)
        if held_object:
            name = scene.object_name(held_object)
            if name is None:
                raise WaypointPlanningError(f"held object {held_object!r} is not in the planning scene")
            scene.attach(name, held_transform)
        elif scene.attachment is not None:
            scene.detach()
        try:
            why = scene.collision(start)
            if why is not None:
                raise WaypointPlanningError(f"the start state is in collision ({why})")
            q = np.asarray(start, dtype=float)
            planned: list[PlannedWaypoint] = []
            i = 0
            while i < len(goals):
                # A unit: one goal plus the CARTESIAN goals that follow it. When a JOINT goal's
                # IK solution leaves the following straight lines no way through, another
                # solution (another arm configuration) is tried for the whole unit.
                end = i + 1
                while end < len(goals) and goals[end].planner_type == CARTESIAN:
                    end += 1
                unit = self._plan_unit(q, goals[i:end])
                planned.extend(unit)
                q = unit[-1].path.positions[-1]
                i = end
            return planned
        finally:
            scene.restore(saved)

    def _timed(self, goal: Goal, path: list[np.ndarray], started: float) -> PlannedWaypoint:
        timed = time_parameterize(
            path,
            self.scene.limits.velocity,
            self.settings.max_acceleration,
            velocity_scaling=self.settings.velocity_scaling,
        )
        return PlannedWaypoint(goal.label, timed, goal.end_effector_pose, time.perf_counter() - started)

    def _plan_unit(self, q: np.ndarray, unit: list[Goal]) -> list[PlannedWaypoint]:
        first = unit[0]
        if first.planner_type not in (JOINT, CARTESIAN):
            raise WaypointPlanningError(f"{first.where}: unknown planner type {first.planner_type!r}")
        # A failed attempt may have grasped and carried an object along its lines: the next
        # attempt starts from the world as it was.
        before = self.scene.snapshot()
        attempts = GOAL_ALTERNATIVES if first.planner_type == JOINT else 1
        failure = ""
        tried: list[np.ndarray] = []
        for attempt in range(attempts):
            self.scene.restore(before)
            started = time.perf_counter()
            try:
                if first.planner_type == JOINT:
                    path = self._joint(q, first, attempt, tried)
                else:
                    path = self._cartesian(q, first)
                out = [self._timed(first, path, started)]
                self._update_attachment(path[-1], first)
                for goal in unit[1:]:
                    started = time.perf_counter()
                    path = self._cartesian(path[-1], goal)
                    out.append(self._timed(goal, path, started))
                    self._update_attachment(path[-1], goal)
                return out
            except WaypointPlanningError as exc:
                # Report the nearest configuration's failure: the one an operator would expect.
                failure = failure or str(exc)
                if exc.final:
                    break
        # Only configurations that were tried are counted: an IK failure ends the search at the
        # first, and the search for another may find none.
        others = len(tried) - 1
        suffix = f" (and with {others} other arm configurations for {first.label})" if others > 0 else ""
        raise WaypointPlanningError(failure + suffix)

    def _joint(self, q: np.ndarray, goal: Goal, attempt: int, tried: list[np.ndarray]) -> list[np.ndarray]:
        """OMPL to an IK solution of ``goal``: the one nearest to ``q`` first; later attempts use
        a solution from random seeds that differs from every one tried (another arm configuration)."""
        limits = self.scene.limits
        solve = functools.partial(
            self.ik.solve, position_tolerance=goal.position_tolerance, orientation_tolerance=goal.orientation_tolerance
        )
        if attempt == 0:
            target = solve(goal.pose, q)
            if isinstance(target, IkFailure):
                # Every seed failed already: another attempt would not find a different answer.
                raise WaypointPlanningError(f"{goal.where}: {self._pose(goal)} {target.describe()}", final=True)
        else:
            for _ in range(DISTINCT_SEARCH):
                solved = solve(goal.pose, self.ik.rng.uniform(limits.lower, limits.upper), enough=1)
                if isinstance(solved, IkFailure):
                    continue
                # Solved near a random seed, it may sit a full turn away on some joint: the same
                # arm shape nearest to where the arm is costs the least motion.
                candidate = self.ik.wrap_into_limits(solved, q)
                if candidate is not None and all(_shape_distance(candidate, t) > DISTINCT_CONFIGURATION for t in tried):
                    target = candidate
                    break
            else:
                raise WaypointPlanningError(f"{goal.where}: no other arm configuration reaches it", final=True)
        tried.append(target)
        try:
            budget = self.settings.plan_time * ATTEMPT_BUDGET[attempt]
            return self.joint_planner.plan(q, target, time_limit=budget, simplify_time=self.settings.simplify_time)
        except PlanningFailed as exc:
            raise WaypointPlanningError(f"{goal.where}: {self._pose(goal)} is reachable, but {exc}") from exc

    def _cartesian(self, q: np.ndarray, goal: Goal) -> list[np.ndarray]:
        """A straight tool line to ``goal``, tracked by local IK from sample to sample.

        Each sample is solved only from the previous one (a random restart could switch arm
        configuration mid-line); a sample that does not converge or jumps is retried with the
        step halved, up to CARTESIAN_SUBDIVISIONS times, before the line is declared broken.
        """
        scene = self.scene
        start_pose = scene.forward(q)
        p0, q0 = to_xyz_quat(start_pose)
        p1, q1 = to_xyz_quat(goal.pose)
        distance = float(np.linalg.norm(p1 - p0))
        rotation = angle_between(start_pose, goal.pose)
        step = 1.0 / max(1, int(np.ceil(max(distance / self.settings.cartesian_step, rotation / 0.05))))
        path = [np.asarray(q, dtype=float)]
        t = 0.0
        while t < 1.0 - 1e-12:
            dt = min(step, 1.0 - t)
            for _ in range(CARTESIAN_SUBDIVISIONS + 1):
                target = from_xyz_quat(p0 + (p1 - p0) * (t + dt), _slerp(q0, q1, t + dt))
                result = self.ik.track(target, path[-1], goal.position_tolerance, goal.orientation_tolerance)
                jump = float(np.max(np.abs(result - path[-1]))) if result is not None else np.inf
                if jump <= self.settings.jump_threshold:
                    break
                dt /= 2
            else:
                blocked = f": {self.ik.blocked_by}" if result is None and self.ik.blocked_by else ""
                what = f"no IK solution continues the line{blocked}" if result is None else f"joint jump {jump:.2f} rad"
                raise WaypointPlanningError(
                    f"{goal.where}: the Cartesian line to {self._pose(goal)} breaks IK continuity at {t:.0%} ({what})"
                )
            assert result is not None  # the loop above broke only on a solution
            why = scene.collision(result)
            if why is not None:
                raise WaypointPlanningError(
                    f"{goal.where}: the Cartesian line to {self._pose(goal)} is blocked at {t + dt:.0%} "
                    f"by a collision ({why})"
                )
            path.append(result)
            t += dt
        return path

    def _pose(self, goal: Goal) -> str:
        """The goal as the robot sees it: in its base frame, where an operator can judge reach."""
        base_T_goal = invert(self.scene.base_pose()) @ goal.pose  # noqa: N806 (a_T_b notation)
        return f"the pose {pose_text(base_T_goal)} in {self.scene.base_link}"

    def _update_attachment(self, q: np.ndarray, goal: Goal) -> None:
        """Carry or let go of the object the template names at ``goal`` (arm at ``q``).

        Raises:
            WaypointPlanningError: a grasp where no graspable object of the world is within
                ``grasp_match`` of where the template's object is registered.
        """
        scene = self.scene
        if goal.gripper_action == RELEASE:
            scene.detach()
        elif goal.gripper_action == GRASP:
            assert goal.object_pose is not None
            reach = self.settings.grasp_match
            grasped = scene.nearest_graspable(goal.object_pose[:3, 3], within=reach)
            if grasped is None:
                raise WaypointPlanningError(
                    f"{goal.where}: grasps {goal.object_name!r}, "
                    "but no graspable object of the world is within "
                    f"{reach * 100:.0f} cm of where {goal.object_name!r} is registered; register it on the object",
                    final=True,
                )
            if scene.attachment is not None and scene.attachment.name != grasped:
                raise WaypointPlanningError(
                    f"{goal.where}: grasps {grasped!r} while holding {scene.attachment.name!r}", final=True
                )
            scene.set_joints(q)
            scene.attach(grasped)
