"""The Affordance Template library: template files in the original AT JSON format.

Every ``*.json`` under a library folder is one template, keyed by its ``"name"`` (the template
type, ``class_type`` in every service), as the original server's ``loadTemplates`` did. Unlike
the original parser (which logged ROS_ERROR and carried on, or segfaulted later), a malformed
file is rejected with :class:`LibraryError` naming the file and the key path that is wrong.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from at_ros.transforms import from_xyz_rpy

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
]

PLANNER_JOINT = "JOINT"
PLANNER_CARTESIAN = "CARTESIAN"
SHAPE_TYPES = ("mesh", "box", "sphere", "cylinder")


class LibraryError(ValueError):
    """A template or robot file that cannot be used; the message names the file and the key."""

    def __init__(self, path: Path | str, key: str, problem: str) -> None:
        self.path = str(path)
        self.key = key
        self.problem = problem
        where = f"{self.path}: {key}: " if key else f"{self.path}: "
        super().__init__(where + problem)


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


class _Reader:
    """Walks parsed JSON and raises LibraryError naming the key path of anything wrong."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, key: str, problem: str) -> LibraryError:
        return LibraryError(self.path, key, problem)

    def obj(self, value: Any, key: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(key, f"expected an object, got {type(value).__name__}")
        return value

    def required(self, parent: dict[str, Any], name: str, key: str) -> Any:
        if name not in parent:
            raise self.fail(_join(key, name), "missing required key")
        return parent[name]

    def string(self, value: Any, key: str, *, allow_empty: bool = False) -> str:
        if not isinstance(value, str):
            raise self.fail(key, f"expected a string, got {type(value).__name__}")
        if not allow_empty and not value:
            raise self.fail(key, "must not be empty")
        return value

    def integer(self, value: Any, key: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"expected an integer, got {value!r}")
        return value

    def number(self, value: Any, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(key, f"expected a finite number, got {value!r}")
        return float(value)

    def numbers(self, value: Any, key: str, count: int) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != count:
            raise self.fail(key, f"expected a list of {count} numbers, got {value!r}")
        return tuple(self.number(v, f"{key}[{i}]") for i, v in enumerate(value))

    def flags(self, value: Any, key: str) -> tuple[bool, bool, bool]:
        # The original accepted true/false and 0/1 alike.
        if not isinstance(value, list) or len(value) != 3 or not all(v in (0, 1) for v in value):
            raise self.fail(key, f"expected 3 booleans (true/false or 0/1), got {value!r}")
        return (bool(value[0]), bool(value[1]), bool(value[2]))

    def array(self, value: Any, key: str) -> list[Any]:
        if not isinstance(value, list):
            raise self.fail(key, f"expected a list, got {type(value).__name__}")
        return value

    def origin(self, value: Any, key: str) -> Origin:
        o = self.obj(value, key)
        xyz = self.numbers(self.required(o, "xyz", key), _join(key, "xyz"), 3)
        rpy = self.numbers(self.required(o, "rpy", key), _join(key, "rpy"), 3)
        return Origin(xyz=xyz, rpy=rpy)  # type: ignore[arg-type]

    def controls(self, value: Any, key: str) -> Controls:
        c = self.obj(value, key)
        return Controls(
            xyz=self.flags(self.required(c, "xyz", key), _join(key, "xyz")),
            rpy=self.flags(self.required(c, "rpy", key), _join(key, "rpy")),
            scale=self.number(self.required(c, "scale", key), _join(key, "scale")),
        )


def _join(key: str, name: str) -> str:
    return f"{key}.{name}" if key else name


def _shape(r: _Reader, value: Any, key: str) -> Shape:
    s = r.obj(value, key)
    kind = r.string(r.required(s, "type", key), _join(key, "type"))
    if kind not in SHAPE_TYPES:
        raise r.fail(_join(key, "type"), f"unknown shape {kind!r}; expected one of {', '.join(SHAPE_TYPES)}")
    size = r.numbers(r.required(s, "size", key), _join(key, "size"), 3)
    if kind == "mesh":
        return Shape(type=kind, size=size, data=r.string(r.required(s, "data", key), _join(key, "data")))  # type: ignore[arg-type]
    material = r.obj(r.required(s, "material", key), _join(key, "material"))
    mkey = _join(key, "material")
    return Shape(
        type=kind,
        size=size,  # type: ignore[arg-type]
        color=r.string(material.get("color", ""), _join(mkey, "color"), allow_empty=True),
        rgba=r.numbers(r.required(material, "rgba", mkey), _join(mkey, "rgba"), 4),  # type: ignore[arg-type]
    )


def _display_object(r: _Reader, value: Any, key: str) -> DisplayObject:
    d = r.obj(value, key)
    return DisplayObject(
        name=r.string(r.required(d, "name", key), _join(key, "name")),
        parent=r.string(d.get("parent", ""), _join(key, "parent"), allow_empty=True),
        shape=_shape(r, r.required(d, "shape", key), _join(key, "shape")),
        origin=r.origin(r.required(d, "origin", key), _join(key, "origin")),
        controls=r.controls(r.required(d, "controls", key), _join(key, "controls")),
    )


def _tolerances(r: _Reader, value: Any, key: str) -> Tolerances:
    t = r.obj(value, key)
    position, orientation = [], []
    for axis, bucket in (("x", position), ("y", position), ("z", position), ("R", orientation), ("P", orientation), ("Y", orientation)):
        if axis in t:
            pair = r.numbers(t[axis], _join(key, axis), 2)
            bucket.append(max(abs(pair[0]), abs(pair[1])))
    defaults = Tolerances()
    return Tolerances(
        position=min(position) if position else defaults.position,
        orientation=min(orientation) if orientation else defaults.orientation,
    )


def _waypoint(r: _Reader, value: Any, key: str) -> Waypoint:
    w = r.obj(value, key)
    planner_type = r.string(w.get("planner_type", PLANNER_CARTESIAN), _join(key, "planner_type"))
    if planner_type not in (PLANNER_JOINT, PLANNER_CARTESIAN):
        # The original silently turned any unknown string into JOINT; a typo should not change motion.
        raise r.fail(_join(key, "planner_type"), f"expected {PLANNER_CARTESIAN!r} or {PLANNER_JOINT!r}, got {planner_type!r}")
    compat = ((1, 1, 1), (1, 1, 1))
    if "task_compatibility" in w:
        tc = r.obj(w["task_compatibility"], _join(key, "task_compatibility"))
        ckey = _join(key, "task_compatibility")
        compat = (
            tuple(int(v) for v in r.numbers(r.required(tc, "xyz", ckey), _join(ckey, "xyz"), 3)),
            tuple(int(v) for v in r.numbers(r.required(tc, "rpy", ckey), _join(ckey, "rpy"), 3)),
        )  # type: ignore[assignment]
    return Waypoint(
        ee_pose=r.integer(r.required(w, "ee_pose", key), _join(key, "ee_pose")),
        display_object=r.string(r.required(w, "display_object", key), _join(key, "display_object")),
        origin=r.origin(r.required(w, "origin", key), _join(key, "origin")),
        controls=r.controls(w["controls"], _join(key, "controls")) if "controls" in w else Controls(),
        planner_type=planner_type,
        conditioning_metric=r.string(w.get("conditioning_metric", "MIN_DISTANCE"), _join(key, "conditioning_metric")),
        tolerances=_tolerances(r, w["tolerances"], _join(key, "tolerances")) if "tolerances" in w else Tolerances(),
        task_compatibility=compat,
        tool_offset=r.origin(w["tool_offset"], _join(key, "tool_offset")) if "tool_offset" in w else Origin(),
    )


def _trajectory(r: _Reader, value: Any, key: str) -> Trajectory:
    t = r.obj(value, key)
    groups = []
    gkey = _join(key, "end_effector_group")
    raw_groups = r.array(r.required(t, "end_effector_group", key), gkey)
    if not raw_groups:
        raise r.fail(gkey, "a trajectory needs at least one end-effector group")
    for gi, g in enumerate(raw_groups):
        k = f"{gkey}[{gi}]"
        gobj = r.obj(g, k)
        wkey = _join(k, "end_effector_waypoint")
        raw_wps = r.array(r.required(gobj, "end_effector_waypoint", k), wkey)
        if not raw_wps:
            raise r.fail(wkey, "a group needs at least one waypoint")
        groups.append(
            EndEffectorGroup(
                id=r.integer(r.required(gobj, "id", k), _join(k, "id")),
                waypoints=tuple(_waypoint(r, w, f"{wkey}[{wi}]") for wi, w in enumerate(raw_wps)),
            )
        )
    ids = [g.id for g in groups]
    if len(set(ids)) != len(ids):
        raise r.fail(gkey, f"end-effector group ids repeat: {ids}")
    return Trajectory(name=r.string(r.required(t, "name", key), _join(key, "name")), groups=tuple(groups))


def _check_references(r: _Reader, template: Template, raw_trajectories: Sequence[Any]) -> None:
    names = [o.name for o in template.display_objects]
    if len(set(names)) != len(names):
        raise r.fail("display_objects", f"display object names repeat: {names}")
    for i, obj in enumerate(template.display_objects):
        if obj.parent and obj.parent not in names:
            raise r.fail(f"display_objects[{i}].parent", f"unknown display object {obj.parent!r}; known: {', '.join(names)}")
        seen, parent = {obj.name}, obj.parent
        while parent:
            if parent in seen:
                raise r.fail(f"display_objects[{i}].parent", f"parent chain of {obj.name!r} loops")
            seen.add(parent)
            parent = template.display_object(parent).parent  # type: ignore[union-attr]
    traj_names = template.trajectory_names
    if len(set(traj_names)) != len(traj_names):
        raise r.fail("end_effector_trajectory", f"trajectory names repeat: {traj_names}")
    for ti, traj in enumerate(template.trajectories):
        for gi, group in enumerate(traj.groups):
            for wi, wp in enumerate(group.waypoints):
                if wp.display_object not in names:
                    key = f"end_effector_trajectory[{ti}].end_effector_group[{gi}].end_effector_waypoint[{wi}].display_object"
                    raise r.fail(key, f"unknown display object {wp.display_object!r}; known: {', '.join(names)}")


def load_template(path: Path | str) -> Template:
    """Parse and validate one AT JSON file.

    Raises:
        LibraryError: unreadable file, JSON syntax error (with line and column), a missing or
            mistyped key, or a reference to an unknown display object.
    """
    path = Path(path)
    r = _Reader(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise LibraryError(path, "", f"cannot read: {exc.strerror}") from exc
    except json.JSONDecodeError as exc:
        raise LibraryError(f"{path}:{exc.lineno}:{exc.colno}", "", f"invalid JSON: {exc.msg}") from exc
    top = r.obj(data, "")
    if "end_effector_trajectories" in top and "end_effector_trajectory" not in top:
        raise r.fail("end_effector_trajectories", "unknown key; the AT format names it 'end_effector_trajectory' (singular)")
    objects = r.array(r.required(top, "display_objects", ""), "display_objects")
    if not objects:
        raise r.fail("display_objects", "a template needs at least one display object")
    trajectories = r.array(r.required(top, "end_effector_trajectory", ""), "end_effector_trajectory")
    template = Template(
        name=r.string(r.required(top, "name", ""), "name"),
        image=r.string(r.required(top, "image", ""), "image", allow_empty=True),
        display_objects=tuple(_display_object(r, o, f"display_objects[{i}]") for i, o in enumerate(objects)),
        trajectories=tuple(_trajectory(r, t, f"end_effector_trajectory[{i}]") for i, t in enumerate(trajectories)),
        filename=str(path),
    )
    _check_references(r, template, trajectories)
    return template


def load_library(folder: Path | str) -> dict[str, Template]:
    """Load every ``*.json`` under ``folder`` (recursively), keyed by template name.

    Raises:
        LibraryError: the folder is missing, any file is malformed, or two files share a name.
    """
    return load_named_files(Path(folder), "**/*.json", load_template, "name", "template")


def load_named_files(folder: Path, pattern: str, load: Callable[[Path], Named], key: str, kind: str) -> dict[str, Named]:
    """Every file of ``folder`` matching ``pattern``, loaded, keyed by its ``key`` attribute.

    Adding a template or a robot is adding a file, so a name two files claim is an error that
    names both: otherwise which one wins would depend on the order files are read in.
    """
    if not folder.is_dir():
        raise LibraryError(folder, "", f"{kind} folder does not exist")
    loaded: dict[str, Named] = {}
    for path in sorted(folder.glob(pattern)):
        item = load(path)
        name = getattr(item, key)
        if name in loaded:
            raise LibraryError(path, key, f"{kind} {key} {name!r} is already used by {loaded[name].filename}")
        loaded[name] = item
    return loaded


def default_library_path() -> Path:
    """The library shipped with at_ros: ``python/at_ros/library``."""
    return Path(__file__).resolve().parent / "library"
