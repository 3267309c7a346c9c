"""Robot configurations in the original AT robot YAML form, plus what planning here needs.

Original keys (``robot_interface.cpp::load``): ``robot_name``, ``planner_type``, ``frame_id``,
``root_offset`` [x y z r p y], ``end_effector_group_map`` (name, id, pose_offset, tool_offset),
``end_effector_pose_map`` (name, group, id). Additions, since there is no MoveIt/SRDF here:
``urdf``, ``scene``, ``base_frame``, ``tool_link``, ``joint_names``, ``trajectory_action``,
``gripper_service``, ``halt_service`` and a ``planner`` block. Paths (``urdf``) are relative to the
config file. ROS names (``trajectory_action``, ``gripper_service``, ``halt_service``) without a
leading ``/`` are relative to the node's namespace, so one config serves a robot in any namespace.
Unknown keys are errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from at_ros.library import LibraryError, default_library_path, load_named_files
from at_ros.transforms import from_xyz_rpy
from datafile import Field, load_file
from datafile.urdf import read_urdf

__all__ = [
    "EndEffector",
    "EndEffectorPose",
    "PlannerSettings",
    "RobotConfig",
    "load_robot_config",
    "load_robot_configs",
]

_REQUIRED = (
    "robot_name",
    "frame_id",
    "root_offset",
    "end_effector_group_map",
    "urdf",
    "base_frame",
    "tool_link",
    "joint_names",
    "trajectory_action",
)


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
    grasp_match: float = 0.05  # m: a grasped object must be this close to where the template says it is


@dataclass(frozen=True)
class RobotConfig:
    robot_name: str
    frame_id: str
    root_offset: tuple[float, ...]
    end_effectors: tuple[EndEffector, ...]
    end_effector_poses: tuple[EndEffectorPose, ...]
    urdf: Path
    base_frame: str
    tool_link: str
    joint_names: tuple[str, ...]
    trajectory_action: str
    gripper_service: str
    halt_service: str = ""  # the robot's stop of every motion (caretaker_sim_msgs/srv/Halt); "" = none
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


_ORIGINAL_KEYS = ("planner_type", "config_package", "config_file", "end_effector_pose_map", "gripper_action")
_OUR_KEYS = ("gripper_service", "halt_service", "home_joints", "planner")


def _six(f: Field) -> tuple[float, ...]:
    if f.node.kind != "sequence" or len(f.node.items) != 6:
        raise f.fail(f"expected [x, y, z, roll, pitch, yaw] (6 numbers), got {f.describe()}")
    return f.numbers(6)


def _planner(f: Field | None) -> PlannerSettings:
    if f is None:
        return PlannerSettings()
    defaults = PlannerSettings()
    f.mapping(optional=PlannerSettings.__dataclass_fields__)
    settings: dict[str, Any] = {}
    for key, value in f.entries():
        default = getattr(defaults, key)
        if isinstance(default, tuple):
            settings[key] = value.names()
        elif isinstance(default, int):
            settings[key] = value.integer(min=0, max=2**31 - 1)
        else:
            settings[key] = value.number(min=0.0)
    return PlannerSettings(**settings)


def _end_effectors(f: Field) -> tuple[EndEffector, ...]:
    out: list[EndEffector] = []
    for e in f.sequence(min_items=1):
        e.mapping(required=("name", "id"), optional=("pose_offset", "tool_offset"))
        pose, tool = e.get("pose_offset"), e.get("tool_offset")
        ee = EndEffector(
            name=e["name"].text(),
            id=e["id"].integer(min=0, max=255),
            pose_offset=_six(pose) if pose else (0.0,) * 6,
            tool_offset=_six(tool) if tool else (0.0,) * 6,
        )
        if any(o.name == ee.name or o.id == ee.id for o in out):
            raise e.fail(f"end effector {ee.name!r} (id {ee.id}) repeats a name or id")
        out.append(ee)
    return tuple(out)


def _poses(f: Field | None, end_effectors: tuple[EndEffector, ...]) -> tuple[EndEffectorPose, ...]:
    out: list[EndEffectorPose] = []
    for p in f.sequence() if f is not None else []:
        p.mapping(required=("name", "group", "id"))
        group = p["group"].text()
        if group not in {e.name for e in end_effectors}:
            raise p["group"].fail(f"unknown end effector {group!r}; known: {', '.join(e.name for e in end_effectors)}")
        pose = EndEffectorPose(name=p["name"].text(), group=group, id=p["id"].integer(min=0, max=255))
        if any(o.group == pose.group and o.id == pose.id for o in out):
            raise p["id"].fail(f"pose id {pose.id} of {group!r} is mapped twice")
        out.append(pose)
    return tuple(out)


def load_robot_config(path: Path | str) -> RobotConfig:
    """Parse and validate one robot YAML file; its paths are relative to the file.

    Raises:
        LibraryError: ``file:line: key: problem`` for whatever is missing, unknown or wrong.
    """
    path = Path(path)
    root = load_file(path, error=LibraryError).mapping(required=_REQUIRED, optional=_ORIGINAL_KEYS + _OUR_KEYS)
    end_effectors = _end_effectors(root["end_effector_group_map"])
    joints = root["joint_names"].names(min_items=1)
    urdf = read_urdf(root["urdf"].file_path())
    urdf.check_link(root["tool_link"])
    for joint in root["joint_names"].sequence():
        urdf.check_joint(joint)
    home = root.get("home_joints")
    planner_type, gripper, halt = root.get("planner_type"), root.get("gripper_service"), root.get("halt_service")
    return RobotConfig(
        robot_name=root["robot_name"].text(),
        planner_type=planner_type.text() if planner_type else "at_ros.planner_node",
        frame_id=root["frame_id"].text(),
        root_offset=_six(root["root_offset"]),
        end_effectors=end_effectors,
        end_effector_poses=_poses(root.get("end_effector_pose_map"), end_effectors),
        urdf=root["urdf"].file_path(),
        base_frame=root["base_frame"].text(),
        tool_link=root["tool_link"].text(),
        joint_names=joints,
        home_joints=home.numbers(len(joints)) if home else (),
        trajectory_action=root["trajectory_action"].text(),
        gripper_service=gripper.text(empty=True) if gripper else "",
        halt_service=halt.text(empty=True) if halt else "",
        planner=_planner(root.get("planner")),
        filename=str(path),
    )


def load_robot_configs(folder: Path | str | None = None) -> dict[str, RobotConfig]:
    """Every ``*.yaml`` robot config of a folder (default: the shipped library), keyed by robot_name."""
    folder = Path(folder) if folder else default_library_path() / "robots"
    return load_named_files(folder, ".yaml", load_robot_config, "robot_name", "robot")
