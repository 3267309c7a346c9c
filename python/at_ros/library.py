"""The Affordance Template library: template files in the original AT JSON format.

Every ``*.json`` under a library folder is one template, keyed by its ``"name"`` (the template
type, ``class_type`` in every service), as the original server's ``loadTemplates`` did. Unlike
the original parser (which logged ROS_ERROR and carried on, or segfaulted later), a malformed
file is rejected with :class:`LibraryError` naming the file, the line and the key path that is
wrong (the shared :mod:`datafile` mechanism), and unknown keys are errors, not ignored typos.

Two optional waypoint keys are ours: ``"grasp": "<display object>"`` says the gripper holds that
object from this waypoint on, ``"release": "<display object>"`` that it lets go of it here. The
planner carries exactly what the template says it grasps; without these keys it carries nothing
new (a file in the original format plans as before, never grasping on a guess).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import numpy as np

from at_ros.transforms import from_xyz_rpy
from datafile import DataFileError, Field, load_file

Named = TypeVar("Named")

__all__ = [
    "LibraryError",
    "load_named_files",
    "Origin",
    "Shape",
    "Controls",
    "DisplayObject",
    "Tolerances",
    "Waypoint",
    "EndEffectorGroup",
    "Trajectory",
    "Template",
    "load_template",
    "load_library",
    "default_library_path",
    "PLANNER_JOINT",
    "PLANNER_CARTESIAN",
    "GRASP",
    "RELEASE",
]

PLANNER_JOINT = "JOINT"
PLANNER_CARTESIAN = "CARTESIAN"
SHAPE_TYPES = ("mesh", "box", "sphere", "cylinder")


class LibraryError(DataFileError):
    """A template or robot file that cannot be used: ``file:line: key: problem``."""


@dataclass(frozen=True)
class Origin:
    """A pose as written in AT files: translation and fixed-axis roll-pitch-yaw."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def matrix(self) -> np.ndarray:
        return from_xyz_rpy(self.xyz, self.rpy)


@dataclass(frozen=True)
class Shape:
    type: str
    size: tuple[float, float, float]
    data: str = ""
    color: str = ""
    rgba: tuple[float, float, float, float] = (0.5, 0.5, 0.5, 1.0)


@dataclass(frozen=True)
class Controls:
    """Which interactive-marker axes an operator may drag; kept for clients that draw markers."""

    xyz: tuple[bool, bool, bool] = (True, True, True)
    rpy: tuple[bool, bool, bool] = (True, True, True)
    scale: float = 0.25


@dataclass(frozen=True)
class DisplayObject:
    name: str
    shape: Shape
    origin: Origin
    controls: Controls
    parent: str = ""  # "" = the AT root frame


@dataclass(frozen=True)
class Tolerances:
    """Position (m) and orientation (rad) bounds per axis, as [upper, lower] pairs in the file."""

    position: float = 0.01
    orientation: float = 0.0349


@dataclass(frozen=True)
class Waypoint:
    ee_pose: int
    display_object: str
    origin: Origin
    controls: Controls = Controls()
    planner_type: str = PLANNER_CARTESIAN
    conditioning_metric: str = "MIN_DISTANCE"
    tolerances: Tolerances = Tolerances()
    task_compatibility: tuple[tuple[int, int, int], tuple[int, int, int]] = ((1, 1, 1), (1, 1, 1))
    tool_offset: Origin = Origin()
    grasp: str = ""  # display object the gripper holds from this waypoint on ("" = none)
    release: str = ""  # display object the gripper lets go of at this waypoint
    #: Where the template file states it, so a waypoint that cannot be planned is found in the
    #: file; not part of what the waypoint is.
    line: int = field(default=0, compare=False)


@dataclass(frozen=True)
class EndEffectorGroup:
    id: int  # the abstract end-effector id; the robot config maps it to a real end effector
    waypoints: tuple[Waypoint, ...]


@dataclass(frozen=True)
class Trajectory:
    name: str
    groups: tuple[EndEffectorGroup, ...]

    def group(self, ee_id: int) -> EndEffectorGroup | None:
        return next((g for g in self.groups if g.id == ee_id), None)


@dataclass(frozen=True)
class Template:
    name: str
    image: str
    display_objects: tuple[DisplayObject, ...]
    trajectories: tuple[Trajectory, ...]
    filename: str = ""
    _objects_by_name: dict[str, DisplayObject] = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        self._objects_by_name.update({o.name: o for o in self.display_objects})

    def display_object(self, name: str) -> DisplayObject | None:
        return self._objects_by_name.get(name)

    def trajectory(self, name: str) -> Trajectory | None:
        return next((t for t in self.trajectories if t.name == name), None)

    @property
    def trajectory_names(self) -> list[str]:
        return [t.name for t in self.trajectories]


GRASP = "grasp"
RELEASE = "release"

_WAYPOINT_KEYS = (
    "controls",
    "planner_type",
    "conditioning_metric",
    "tolerances",
    "task_compatibility",
    "tool_offset",
    GRASP,
    RELEASE,
)


def _origin(f: Field) -> Origin:
    f.mapping(required=("xyz", "rpy"))
    return Origin(xyz=f["xyz"].numbers(3), rpy=f["rpy"].numbers(3))  # type: ignore[arg-type]


def _flags(f: Field) -> tuple[bool, bool, bool]:
    # The original accepted true/false and 0/1 alike.
    items = f.sequence()
    if len(items) != 3 or not all(i.node.value in (0, 1) and i.node.kind == "scalar" for i in items):
        raise f.fail(f"expected 3 booleans (true/false or 0/1), got {f.describe()}")
    return (bool(items[0].node.value), bool(items[1].node.value), bool(items[2].node.value))


def _controls(f: Field) -> Controls:
    f.mapping(required=("xyz", "rpy", "scale"))
    return Controls(xyz=_flags(f["xyz"]), rpy=_flags(f["rpy"]), scale=f["scale"].number(min=0.0))


def _shape(f: Field) -> Shape:
    kind = f.mapping(required=("type",), any_keys=True)["type"].choice(SHAPE_TYPES)
    if kind == "mesh":
        f.mapping(required=("type", "data", "size"), optional=("material",))
        return Shape(type=kind, size=f["size"].numbers(3), data=f["data"].text())  # type: ignore[arg-type]
    f.mapping(required=("type", "material", "size"))
    material = f["material"].mapping(required=("rgba",), optional=("color",))
    color = material.get("color")
    return Shape(
        type=kind,
        size=f["size"].numbers(3),  # type: ignore[arg-type]
        color=color.text(empty=True) if color else "",
        rgba=material["rgba"].numbers(4, min=0.0, max=1.0),  # type: ignore[arg-type]
    )


def _display_object(f: Field) -> DisplayObject:
    f.mapping(required=("name", "shape", "origin", "controls"), optional=("parent",))
    parent = f.get("parent")
    return DisplayObject(
        name=f["name"].text(),
        parent=parent.text(empty=True) if parent else "",
        shape=_shape(f["shape"]),
        origin=_origin(f["origin"]),
        controls=_controls(f["controls"]),
    )


def _tolerances(f: Field) -> Tolerances:
    f.mapping(optional=("x", "y", "z", "R", "P", "Y"))
    position: list[float] = []
    orientation: list[float] = []
    for axis, bucket in (
        ("x", position),
        ("y", position),
        ("z", position),
        ("R", orientation),
        ("P", orientation),
        ("Y", orientation),
    ):
        value = f.get(axis)
        if value is not None:
            pair = value.numbers(2)
            bucket.append(max(abs(pair[0]), abs(pair[1])))
    defaults = Tolerances()
    return Tolerances(
        position=min(position) if position else defaults.position,
        orientation=min(orientation) if orientation else defaults.orientation,
    )


def _task_compatibility(f: Field) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    f.mapping(required=("xyz", "rpy"))
    xyz, rpy = (tuple(int(v) for v in f[k].numbers(3, min=-1, max=1)) for k in ("xyz", "rpy"))
    return xyz, rpy  # type: ignore[return-value]


def _waypoint(f: Field) -> Waypoint:
    f.mapping(required=("ee_pose", "display_object", "origin"), optional=_WAYPOINT_KEYS)
    planner = f.get("planner_type")
    # The original silently turned any unknown string into JOINT; a typo should not change motion.
    planner_type = planner.choice((PLANNER_CARTESIAN, PLANNER_JOINT)) if planner else PLANNER_CARTESIAN
    grasp, release = f.get(GRASP), f.get(RELEASE)
    if grasp is not None and release is not None:
        raise release.fail("a waypoint either grasps or releases, not both")
    metric, tolerances, compat, controls, tool = (
        f.get(k) for k in ("conditioning_metric", "tolerances", "task_compatibility", "controls", "tool_offset")
    )
    return Waypoint(
        ee_pose=f["ee_pose"].integer(min=0, max=255),
        display_object=f["display_object"].text(),
        origin=_origin(f["origin"]),
        controls=_controls(controls) if controls else Controls(),
        planner_type=planner_type,
        conditioning_metric=metric.text() if metric else "MIN_DISTANCE",
        tolerances=_tolerances(tolerances) if tolerances else Tolerances(),
        task_compatibility=_task_compatibility(compat) if compat else ((1, 1, 1), (1, 1, 1)),
        tool_offset=_origin(tool) if tool else Origin(),
        grasp=grasp.text() if grasp else "",
        release=release.text() if release else "",
        line=f.line,
    )


def _trajectory(f: Field) -> Trajectory:
    f.mapping(required=("name", "end_effector_group"))
    groups = []
    group_fields = f["end_effector_group"].sequence(min_items=1)
    for g in group_fields:
        g.mapping(required=("id", "end_effector_waypoint"))
        groups.append(
            EndEffectorGroup(
                id=g["id"].integer(min=0, max=255),
                waypoints=tuple(_waypoint(w) for w in g["end_effector_waypoint"].sequence(min_items=1)),
            )
        )
    for i, group in enumerate(groups):
        if any(other.id == group.id for other in groups[:i]):
            raise group_fields[i]["id"].fail(f"end-effector group id {group.id} repeats")
    return Trajectory(name=f["name"].text(), groups=tuple(groups))


def _check_references(root: Field, template: Template) -> None:
    objects = root["display_objects"].sequence()
    names = [o.name for o in template.display_objects]
    for i, obj in enumerate(template.display_objects):
        if obj.name in names[:i]:
            raise objects[i]["name"].fail(f"display object {obj.name!r} is defined twice")
        if obj.parent and obj.parent not in names:
            raise objects[i]["parent"].fail(f"unknown display object {obj.parent!r}; known: {', '.join(names)}")
        seen, parent = {obj.name}, obj.parent
        while parent:
            if parent in seen:
                raise objects[i]["parent"].fail(f"parent chain of {obj.name!r} loops")
            seen.add(parent)
            parent = template.display_object(parent).parent  # type: ignore[union-attr]
    trajectories = root["end_effector_trajectory"].sequence()
    for ti, traj in enumerate(template.trajectories):
        if traj.name in template.trajectory_names[:ti]:
            raise trajectories[ti]["name"].fail(f"trajectory {traj.name!r} is defined twice")
        for gi, group in enumerate(traj.groups):
            waypoints = trajectories[ti]["end_effector_group"].sequence()[gi]["end_effector_waypoint"].sequence()
            for wi, wp in enumerate(group.waypoints):
                for key, name in (("display_object", wp.display_object), (GRASP, wp.grasp), (RELEASE, wp.release)):
                    if name and name not in names:
                        raise waypoints[wi][key].fail(f"unknown display object {name!r}; known: {', '.join(names)}")


def load_template(path: Path | str) -> Template:
    """Parse and validate one AT JSON file.

    Raises:
        LibraryError: ``file:line: key: problem`` for an unreadable file, a JSON syntax error, a
            missing, unknown or mistyped key, or a reference to an unknown display object.
    """
    path = Path(path)
    root = load_file(path, error=LibraryError, json=True)
    if (
        root.node.kind == "mapping"
        and root.has("end_effector_trajectories")
        and not root.has("end_effector_trajectory")
    ):
        raise root["end_effector_trajectories"].fail(
            "unknown key; the AT format names it 'end_effector_trajectory' (singular)"
        )
    root.mapping(required=("name", "image", "display_objects", "end_effector_trajectory"))
    template = Template(
        name=root["name"].text(),
        image=root["image"].text(empty=True),
        display_objects=tuple(_display_object(o) for o in root["display_objects"].sequence(min_items=1)),
        trajectories=tuple(_trajectory(t) for t in root["end_effector_trajectory"].sequence()),
        filename=str(path),
    )
    _check_references(root, template)
    return template


def load_library(folder: Path | str) -> dict[str, Template]:
    """Load every ``*.json`` under ``folder`` (recursively, following linked folders), keyed by name.

    Raises:
        LibraryError: the folder is missing, any file is malformed, two files share a name, or a
            linked folder leads back into itself.
    """
    return load_named_files(Path(folder), ".json", load_template, "name", "template", recursive=True)


def _files(folder: Path, suffix: str, recursive: bool) -> list[Path]:
    """The files ending in ``suffix`` in ``folder`` (and below it, following linked folders).

    A user links a shared set of templates into their library, so linked folders are followed;
    a link that leads back to a folder already on the way down would never end, so it is refused.
    """
    if not recursive:
        return sorted(p for p in folder.iterdir() if p.name.endswith(suffix) and p.is_file())
    found: list[Path] = []
    for top, dirs, files in os.walk(folder, followlinks=True, onerror=_walk_error):
        here = Path(top)
        ancestors = {
            Path(os.path.realpath(parent)) for parent in [here, *here.parents] if folder in [parent, *parent.parents]
        }
        for name in list(dirs):
            if Path(os.path.realpath(here / name)) in ancestors:
                raise LibraryError(
                    here / name, 0, "", "linked folder leads back into the library above it; remove the link"
                )
        dirs.sort()
        found += [here / name for name in sorted(files) if name.endswith(suffix) and (here / name).is_file()]
    return found


def _walk_error(exc: OSError) -> None:
    raise LibraryError(exc.filename or "", 0, "", f"cannot read folder: {exc.strerror}")


def load_named_files(
    folder: Path, suffix: str, load: Callable[[Path], Named], key: str, kind: str, *, recursive: bool = False
) -> dict[str, Named]:
    """Every file of ``folder`` ending in ``suffix``, loaded, keyed by its ``key`` attribute.

    Adding a template or a robot is adding a file, so a name two files claim is an error that
    names both: otherwise which one wins would depend on the order files are read in.
    """
    if not folder.is_dir():
        raise LibraryError(folder, 0, "", f"{kind} folder does not exist")
    loaded: dict[str, Named] = {}
    for path in _files(folder, suffix, recursive):
        item = load(path)
        name = getattr(item, key)
        if name in loaded:
            raise LibraryError(
                path, 0, key, f"{kind} {key} {name!r} is already used by {getattr(loaded[name], 'filename', '?')}"
            )
        loaded[name] = item
    return loaded


def default_library_path() -> Path:
    """The library shipped with at_ros: ``python/at_ros/library``."""
    return Path(__file__).resolve().parent / "library"
