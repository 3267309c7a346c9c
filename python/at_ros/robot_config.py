"""Robot configurations in the original AT robot YAML form, plus what planning here needs.

Original keys (``robot_interface.cpp::load``): ``robot_name``, ``planner_type``, ``frame_id``,
``root_offset`` [x y z r p y], ``end_effector_group_map`` (name, id, pose_offset, tool_offset),
``end_effector_pose_map`` (name, group, id). Additions, since there is no MoveIt/SRDF here:
``urdf``, ``scene``, ``base_frame``, ``tool_link``, ``joint_names``, ``trajectory_action``,
``gripper_service`` and a ``planner`` block. Relative paths are relative to the repository root.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from at_ros.library import LibraryError, default_library_path, load_named_files
from at_ros.transforms import from_xyz_rpy

__all__ = [
    "EndEffector",
    "EndEffectorPose",
    "PlannerSettings",
    "RobotConfig",
    "load_robot_config",
    "load_robot_configs",
    "repository_root",
]


def repository_root() -> Path:
    return Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class EndEffector:
    name: str
    id: int
    pose_offset: tuple[float, ...] = (0.0,) * 6
    tool_offset: tuple[float, ...] = (0.0,) * 6

    @property
    def pose_offset_matrix(self) -> np.ndarray:
        return from_xyz_rpy(self.pose_offset[:3], self.pose_offset[3:])

    @property
    def tool_offset_matrix(self) -> np.ndarray:
        """The control point (e.g. between the fingers) in the tool link's frame."""
        return from_xyz_rpy(self.tool_offset[:3], self.tool_offset[3:])


@dataclass(frozen=True)
class EndEffectorPose:
    name: str  # the named gripper pose the robot understands ("open", "closed")
    group: str
    id: int


@dataclass(frozen=True)
class PlannerSettings:
    """How the planner node plans for this robot; defaults suit a 6-7 DOF arm."""

    seed: int = 1
    ik_seeds: int = 12
    ik_iterations: int = 200
    ik_residual: float = 1e-5
    plan_time: float = 2.0
    simplify_time: float = 0.1
    cartesian_step: float = 0.01  # m between checked Cartesian samples (MoveIt's eef_step)
    jump_threshold: float = 0.35  # rad: max joint change between Cartesian samples
    collision_margin: float = 0.0
    velocity_scaling: float = 0.5  # fraction of the URDF velocity limits
    max_acceleration: float = 2.0  # rad/s^2 per joint
    gripper_links: tuple[str, ...] = ()  # links allowed to touch the object being grasped


@dataclass(frozen=True)
class RobotConfig:
    robot_name: str
    frame_id: str
    root_offset: tuple[float, ...]
    end_effectors: tuple[EndEffector, ...]
    end_effector_poses: tuple[EndEffectorPose, ...]
    urdf: Path
    scene: Path
    base_frame: str
    tool_link: str
    joint_names: tuple[str, ...]
    trajectory_action: str
    gripper_service: str
    planner_type: str = "at_ros.planner_node"
    home_joints: tuple[float, ...] = ()
    planner: PlannerSettings = field(default_factory=PlannerSettings)
    filename: str = ""

    @property
    def root_offset_matrix(self) -> np.ndarray:
        return from_xyz_rpy(self.root_offset[:3], self.root_offset[3:])

    def end_effector(self, name: str) -> EndEffector | None:
        return next((e for e in self.end_effectors if e.name == name), None)

    def end_effector_by_id(self, ee_id: int) -> EndEffector | None:
        return next((e for e in self.end_effectors if e.id == ee_id), None)

    def pose_name(self, group: str, pose_id: int) -> str | None:
        return next((p.name for p in self.end_effector_poses if p.group == group and p.id == pose_id), None)


def _require(data: dict[str, Any], key: str, path: Path) -> Any:
    if key not in data:
        raise LibraryError(path, key, "missing required key")
    return data[key]


def _six(value: Any, key: str, path: Path) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != 6 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        raise LibraryError(path, key, f"expected [x, y, z, roll, pitch, yaw] (6 numbers), got {value!r}")
    return tuple(float(v) for v in value)


def _str(value: Any, key: str, path: Path, *, allow_empty: bool = False) -> str:
    if not isinstance(value, str) or (not value and not allow_empty):
        raise LibraryError(path, key, f"expected a non-empty string, got {value!r}")
    return value


def _int(value: Any, key: str, path: Path) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise LibraryError(path, key, f"expected an integer, got {value!r}")
    return value


def _planner(value: Any, path: Path) -> PlannerSettings:
    if value is None:
        return PlannerSettings()
    if not isinstance(value, dict):
        raise LibraryError(path, "planner", f"expected a mapping, got {type(value).__name__}")
    defaults = PlannerSettings()
    known = set(PlannerSettings.__dataclass_fields__)
    unknown = set(value) - known
    if unknown:
        raise LibraryError(path, f"planner.{sorted(unknown)[0]}", f"unknown setting; known: {', '.join(sorted(known))}")
    kwargs: dict[str, Any] = {}
    for key, raw in value.items():
        default = getattr(defaults, key)
        if isinstance(default, tuple):
            if not isinstance(raw, list) or not all(isinstance(v, str) for v in raw):
                raise LibraryError(path, f"planner.{key}", f"expected a list of names, got {raw!r}")
            kwargs[key] = tuple(raw)
        elif isinstance(default, int):
            kwargs[key] = _int(raw, f"planner.{key}", path)
        else:
            if isinstance(raw, bool) or not isinstance(raw, (int, float)) or raw < 0:
                raise LibraryError(path, f"planner.{key}", f"expected a non-negative number, got {raw!r}")
            kwargs[key] = float(raw)
    return PlannerSettings(**kwargs)


def load_robot_config(path: Path | str) -> RobotConfig:
    """Parse and validate one robot YAML file.

    Raises:
        LibraryError: naming the file and the key that is missing or wrong.
    """
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise LibraryError(path, "", f"cannot read: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark else str(path)
        raise LibraryError(where, "", f"invalid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise LibraryError(path, "", "expected a mapping at the top level")

    ees = _require(data, "end_effector_group_map", path)
    if not isinstance(ees, list) or not ees:
        raise LibraryError(path, "end_effector_group_map", "expected a non-empty list")
    end_effectors = []
    for i, e in enumerate(ees):
        key = f"end_effector_group_map[{i}]"
        if not isinstance(e, dict):
            raise LibraryError(path, key, "expected a mapping")
        end_effectors.append(
            EndEffector(
                name=_str(_require(e, "name", path), f"{key}.name", path),
                id=_int(_require(e, "id", path), f"{key}.id", path),
                pose_offset=_six(e.get("pose_offset", [0] * 6), f"{key}.pose_offset", path),
                tool_offset=_six(e.get("tool_offset", [0] * 6), f"{key}.tool_offset", path),
            )
        )
    poses = []
    for i, p in enumerate(data.get("end_effector_pose_map") or []):
        key = f"end_effector_pose_map[{i}]"
        if not isinstance(p, dict):
            raise LibraryError(path, key, "expected a mapping")
        group = _str(_require(p, "group", path), f"{key}.group", path)
        if group not in {e.name for e in end_effectors}:
            raise LibraryError(path, f"{key}.group", f"unknown end effector {group!r}; known: {', '.join(e.name for e in end_effectors)}")
        poses.append(EndEffectorPose(name=_str(_require(p, "name", path), f"{key}.name", path), group=group, id=_int(_require(p, "id", path), f"{key}.id", path)))

    joints = _require(data, "joint_names", path)
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) for j in joints):
        raise LibraryError(path, "joint_names", "expected a non-empty list of joint names")
    home = data.get("home_joints", [])
    if home and (not isinstance(home, list) or len(home) != len(joints)):
        raise LibraryError(path, "home_joints", f"expected {len(joints)} numbers, one per joint")
    root = repository_root()
    urdf = root / _str(_require(data, "urdf", path), "urdf", path)
    scene = root / _str(_require(data, "scene", path), "scene", path)
    return RobotConfig(
        robot_name=_str(_require(data, "robot_name", path), "robot_name", path),
        planner_type=str(data.get("planner_type", "at_ros.planner_node")),
        frame_id=_str(_require(data, "frame_id", path), "frame_id", path),
        root_offset=_six(_require(data, "root_offset", path), "root_offset", path),
        end_effectors=tuple(end_effectors),
        end_effector_poses=tuple(poses),
        urdf=urdf,
        scene=scene,
        base_frame=_str(_require(data, "base_frame", path), "base_frame", path),
        tool_link=_str(_require(data, "tool_link", path), "tool_link", path),
        joint_names=tuple(joints),
        home_joints=tuple(float(v) for v in home),
        trajectory_action=_str(_require(data, "trajectory_action", path), "trajectory_action", path),
        gripper_service=_str(data.get("gripper_service", ""), "gripper_service", path, allow_empty=True),
        planner=_planner(data.get("planner"), path),
        filename=str(path),
    )


def load_robot_configs(folder: Path | str | None = None) -> dict[str, RobotConfig]:
    """Every ``*.yaml`` robot config of a folder (default: the shipped library), keyed by robot_name."""
    folder = Path(folder) if folder else default_library_path() / "robots"
    return load_named_files(folder, "*.yaml", load_robot_config, "robot_name", "robot")
