"""A running Affordance Template instance: its frames, registrations, plans and progress.

Naming follows the original package because clients parse it: instance key and root frame
``<Type>:<id>``, object frames ``<object>:<id>``, waypoint frames ``<ee>.<wp>:<Type>:<id>``.
Registration is a snapshot: the object's world pose is resolved when it is set (as the original
did through TF), and the named frame it came from is remembered so a plan can be refused when
that frame has moved since planning.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from at_ros.library import GRASP, RELEASE, Template, Trajectory, Waypoint
from at_ros.robot_config import EndEffector, RobotConfig
from at_ros.transforms import angle_between, invert

__all__ = [
    "ExecutionOutcome",
    "PlanState",
    "Registration",
    "StoredPlan",
    "TemplateInstance",
    "InstanceError",
    "ResolvedWaypoint",
    "next_free_id",
    "path_sequence",
    "OBJECT_MOVED_POSITION",
    "OBJECT_MOVED_ANGLE",
]

#: A registered frame that moved more than this since planning makes the plan stale.
OBJECT_MOVED_POSITION = 0.005
OBJECT_MOVED_ANGLE = 0.02
MAX_ID = 255  # ids are uint8 in every AT message


class InstanceError(ValueError):
    """A request that names something this instance does not have; the message says what exists."""


def next_free_id(used: set[int]) -> int:
    """The lowest unused id (the original's getNextID)."""
    for i in range(MAX_ID + 1):
        if i not in used:
            return i
    raise InstanceError(f"all {MAX_ID + 1} ids of this template type are in use; delete an instance first")


def path_sequence(
    n: int, current: int, steps: int | None, *, direct: bool, backwards: bool, resume: bool = False
) -> list[int]:
    """Waypoint indices to plan, as the original's computePathSequence, plus ``steps=None``.

    ``steps=None`` (our default) is the whole trajectory, first to last; with ``resume`` (the
    last execution stopped part-way: halted, failed, or the server died) it is the rest of it,
    from the waypoint after ``current``, so a halted pull-out is not begun again from its
    approach with the filter in the gripper. ``direct`` plans only
    waypoint ``steps-1``; ``steps==0`` replans to the current waypoint; otherwise step +-1
    ``steps`` times from the current waypoint, wrapping around (a not-started trajectory uses
    its first step to reach waypoint 0, or the last one when going backwards).
    """
    if steps is None:
        if resume and not backwards and 0 <= current < n - 1:
            return list(range(current + 1, n))
        return list(range(n - 1, -1, -1)) if backwards else list(range(n))
    if direct:
        if not 1 <= steps <= n:
            raise InstanceError(f"direct planning needs steps between 1 and {n} (the waypoint number), got {steps}")
        return [steps - 1]
    if steps == 0:
        if current < 0:
            raise InstanceError("steps=0 replans to the current waypoint, but this trajectory has not started")
        return [current]
    if steps < 0:
        raise InstanceError(f"steps must be >= 0, got {steps}")
    sequence = []
    idx = current
    remaining = steps
    if idx < 0:
        idx = n - 1 if backwards else 0
        sequence.append(idx)
        remaining -= 1
    for _ in range(remaining):
        idx = (idx - 1) % n if backwards else (idx + 1) % n
        sequence.append(idx)
    return sequence


@dataclass(frozen=True)
class Registration:
    frame: str  # the named frame the object was registered to ("world" or a /sim/frames name)
    offset: np.ndarray  # object pose in that frame
    frame_pose: np.ndarray  # world pose of that frame when registered

    @property
    def world(self) -> np.ndarray:
        pose: np.ndarray = self.frame_pose @ self.offset
        return pose


@dataclass(frozen=True)
class ResolvedWaypoint:
    index: int
    label: str  # "<ee>.<wp>:<Type>:<id>"
    source: str  # "<template file>:<line>" of the waypoint, for messages
    waypoint: Waypoint
    frame_pose: np.ndarray  # world pose of the waypoint frame
    tool_goal: np.ndarray  # world pose the robot's tool link must take
    end_effector_pose: str
    gripper_action: str = ""  # "grasp", "release" or "" as the template states it
    object_name: str = ""  # the display object grasped or released
    object_pose: np.ndarray | None = None  # its world pose, to find it in the planner's scene


class PlanState:
    """What became of a plan: the closed set of affordance_template_msgs/srv/GetPlan."""

    PLANNED = "PLANNED"
    EXECUTING = "EXECUTING"
    EXECUTED = "EXECUTED"
    HALTED = "HALTED"
    FAILED = "FAILED"
    INVALIDATED = "INVALIDATED"


class ExecutionOutcome:
    """How a trajectory's last execution ended (kept in the state file)."""

    NONE = ""
    EXECUTING = "EXECUTING"  # read back from a state file: the server stopped during the execution
    SUCCEEDED = "SUCCEEDED"
    FAILED = "FAILED"
    HALTED = "HALTED"
    INTERRUPTED = (EXECUTING, FAILED, HALTED)


@dataclass
class StoredPlan:
    """A plan, what the world looked like when it was made (to refuse it once stale), and what
    became of it (``state``, for get_plan; the plan is kept after it ran or was dropped)."""

    trajectory: str
    end_effector: str
    indices: list[int]
    segments: list[Any]  # affordance_template_msgs/PlannedSegment
    start_joints: dict[str, float]
    registrations: dict[str, Registration]
    held_object: str
    plan_id: str = ""
    planned_at: float = field(default_factory=time.time)
    state: str = PlanState.PLANNED
    state_reason: str = "planned"
    state_since: float = field(default_factory=time.time)

    def set_state(self, state: str, reason: str) -> None:
        self.state, self.state_reason, self.state_since = state, reason, time.time()


@dataclass
class TrajectoryProgress:
    current_index: int = -1  # last executed waypoint
    plan_index: int = -1  # last planned waypoint
    execution_valid: bool = False
    outcome: str = ExecutionOutcome.NONE  # of the last execution
    outcome_message: str = ""

    @property
    def interrupted(self) -> bool:
        """The last execution stopped part-way: a plan without steps resumes after ``current_index``."""
        return self.outcome in ExecutionOutcome.INTERRUPTED


@dataclass
class TemplateInstance:
    template: Template
    id: int
    robot: RobotConfig
    root_pose: np.ndarray  # world pose of the AT root frame
    hide_waypoints: bool = False
    registrations: dict[str, Registration] = field(default_factory=dict)
    waypoint_overrides: dict[tuple[str, int, int], np.ndarray] = field(default_factory=dict)
    progress: dict[str, TrajectoryProgress] = field(default_factory=dict)
    plan: StoredPlan | None = None  # the plan execute_command would run
    plans: dict[str, StoredPlan] = field(
        default_factory=dict
    )  # the last plan of each trajectory, whatever became of it
    current_trajectory: str = ""

    def __post_init__(self) -> None:
        if not self.current_trajectory and self.template.trajectories:
            self.current_trajectory = self.template.trajectories[0].name
        for t in self.template.trajectories:
            self.progress.setdefault(t.name, TrajectoryProgress())

    @property
    def key(self) -> str:
        return f"{self.template.name}:{self.id}"

    # --- lookups that explain themselves -------------------------------------------------

    def trajectory(self, name: str) -> Trajectory:
        name = name or self.current_trajectory
        trajectory = self.template.trajectory(name)
        if trajectory is None:
            raise InstanceError(
                f"template {self.template.name!r} has no trajectory {name!r}; "
                f"it has: {', '.join(self.template.trajectory_names)}"
            )
        return trajectory

    def end_effector(self, trajectory: Trajectory, names: list[str]) -> EndEffector:
        """The robot end effector to plan for: the requested one, or the trajectory's only one."""
        mapped = []
        for group in trajectory.groups:
            ee = self.robot.end_effector_by_id(group.id)
            if ee is None:
                raise InstanceError(
                    f"trajectory {trajectory.name!r} uses end-effector id {group.id}, "
                    f"which robot {self.robot.robot_name!r} does not map "
                    f"(its end_effector_group_map has ids {[e.id for e in self.robot.end_effectors]})"
                )
            mapped.append(ee)
        if names:
            unknown = [n for n in names if n not in {e.name for e in mapped}]
            if unknown:
                raise InstanceError(
                    f"unknown end effector {unknown[0]!r} for trajectory {trajectory.name!r}; "
                    f"it has: {', '.join(e.name for e in mapped)}"
                )
            if len(names) > 1:
                raise InstanceError(
                    f"robot {self.robot.robot_name!r} has one arm; plan one end effector at a time, not {names}"
                )
            return next(e for e in mapped if e.name == names[0])
        if len(mapped) > 1:
            raise InstanceError(
                f"trajectory {trajectory.name!r} has several end effectors; "
                f"name one of: {', '.join(e.name for e in mapped)}"
            )
        return mapped[0]

    # --- frames ----------------------------------------------------------------------------

    def object_pose(self, name: str) -> np.ndarray:
        """World pose of display object ``name``: its registration, else parent (or root) x origin."""
        if name in self.registrations:
            return self.registrations[name].world
        obj = self.template.display_object(name)
        if obj is None:
            raise InstanceError(
                f"template {self.template.name!r} has no display object {name!r}; "
                f"it has: {', '.join(o.name for o in self.template.display_objects)}"
            )
        parent = self.object_pose(obj.parent) if obj.parent else self.root_pose
        pose: np.ndarray = parent @ obj.origin.matrix
        return pose

    def register(self, name: str, registration: Registration) -> None:
        if self.template.display_object(name) is None:
            raise InstanceError(
                f"template {self.template.name!r} has no display object {name!r}; "
                f"it has: {', '.join(o.name for o in self.template.display_objects)}"
            )
        previous = self.registrations.get(name)
        if previous is None or previous.frame != registration.frame:
            # Another object: an interrupted execution is not resumed on it, it starts over.
            for progress in self.progress.values():
                progress.outcome, progress.outcome_message = ExecutionOutcome.NONE, ""
        self.registrations[name] = registration
        self.invalidate_plan(f"{name}:{self.id} registered to {registration.frame!r}")

    def waypoint_origin(self, trajectory: str, ee_id: int, index: int, waypoint: Waypoint) -> np.ndarray:
        return self.waypoint_overrides.get((trajectory, ee_id, index), waypoint.origin.matrix)

    def set_waypoint(self, trajectory: Trajectory, ee: EndEffector, index: int, world_pose: np.ndarray) -> None:
        group = trajectory.group(ee.id)
        assert group is not None
        if not 0 <= index < len(group.waypoints):
            raise InstanceError(
                f"trajectory {trajectory.name!r} has waypoints 0..{len(group.waypoints) - 1} "
                f"for {ee.name!r}, not {index}"
            )
        parent = self.object_pose(group.waypoints[index].display_object)
        self.waypoint_overrides[(trajectory.name, ee.id, index)] = invert(parent) @ world_pose
        self.invalidate_plan(f"waypoint {ee.id}.{index}:{self.key} of {trajectory.name!r} moved")

    def resolve(self, trajectory: Trajectory, ee: EndEffector) -> list[ResolvedWaypoint]:
        """Every waypoint of ``trajectory`` for ``ee`` with its world frame and tool-link goal.

        The tool-link goal is waypoint x JSON tool_offset x robot pose_offset x inverse of the
        robot's tool_offset (the control point in the tool link): the control point lands on
        the waypoint's tool point. Hidden waypoints are resolved like any other.
        """
        group = trajectory.group(ee.id)
        assert group is not None
        out = []
        for i, wp in enumerate(group.waypoints):
            frame = self.object_pose(wp.display_object) @ self.waypoint_origin(trajectory.name, ee.id, i, wp)
            goal = frame @ wp.tool_offset.matrix @ ee.pose_offset_matrix @ invert(ee.tool_offset_matrix)
            pose_name = self.robot.pose_name(ee.name, wp.ee_pose)
            if pose_name is None:
                # The original silently broke its arm/gripper pairing here; say what to add instead.
                raise InstanceError(
                    f"waypoint {ee.id}.{i}:{self.key} uses ee_pose {wp.ee_pose}, which robot {self.robot.robot_name!r} "
                    f"does not map for end effector {ee.name!r}; add it to end_effector_pose_map"
                )
            action, held = (GRASP, wp.grasp) if wp.grasp else (RELEASE, wp.release) if wp.release else ("", "")
            out.append(
                ResolvedWaypoint(
                    i,
                    f"{ee.id}.{i}:{self.key}",
                    f"{self.template.filename}:{wp.line}",
                    wp,
                    frame,
                    goal,
                    pose_name,
                    action,
                    held,
                    self.object_pose(held) if held else None,
                )
            )
        return out

    # --- plans -----------------------------------------------------------------------------

    def invalidate_plan(self, reason: str) -> None:
        """Drop the executable plan; a plan not yet run is recorded INVALIDATED with ``reason``."""
        if self.plan is not None and self.plan.state == PlanState.PLANNED:
            self.plan.set_state(PlanState.INVALIDATED, reason)
        self.plan = None

    def last_plan(self, trajectory: str = "") -> StoredPlan | None:
        """The last plan of ``trajectory`` ("" = of any trajectory), whatever became of it."""
        if trajectory:
            return self.plans.get(trajectory)
        return max(self.plans.values(), key=lambda plan: plan.planned_at, default=None)

    def stale_reason(
        self,
        plan: StoredPlan,
        frames: dict[str, np.ndarray],
        joints: dict[str, float],
        held_object: str,
        joint_tolerance: float,
    ) -> str | None:
        """Why ``plan`` no longer fits the world, or None when it can be executed."""
        for name, reg in plan.registrations.items():
            if reg.frame == "world":
                continue
            now = frames.get(reg.frame)
            if now is None:
                return f"frame {reg.frame!r} of object {name!r} is no longer published"
            moved = float(np.linalg.norm(now[:3, 3] - reg.frame_pose[:3, 3]))
            turned = angle_between(now, reg.frame_pose)
            if moved > OBJECT_MOVED_POSITION or turned > OBJECT_MOVED_ANGLE:
                return (
                    f"object {name!r} moved since planning "
                    f"({reg.frame!r} moved {moved * 1000:.0f} mm, {np.degrees(turned):.1f} deg); plan again"
                )
        for joint, value in plan.start_joints.items():
            if joint not in joints:
                return f"joint {joint!r} is missing from /joint_states"
            if abs(joints[joint] - value) > joint_tolerance:
                return (
                    f"the robot moved since planning ({joint} is {joints[joint]:.3f} rad, "
                    f"the plan starts at {value:.3f}); plan again"
                )
        if held_object != plan.held_object:
            return (
                f"the gripper holds {held_object or 'nothing'!r} "
                f"but the plan was made holding {plan.held_object or 'nothing'!r}; plan again"
            )
        return None
