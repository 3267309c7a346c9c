"""Scene files: a world as data (``sim/scenes/*.yaml``), read and checked into dataclasses.

A scene names its robot model, where the robot stands, the static bodies, slots, filters,
inspection targets and cameras. Moving a rack or adding a target is a change to the file, not
to code. Paths in a scene (``robot.urdf``) are relative to the scene file. Every mistake is one
line naming file, line and key (:mod:`datafile`); building the world into pybullet is
``sim.world``, so reading a scene needs no physics engine.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path

from datafile import DataFileError, Field, load_file, shipped_or_path
from datafile.urdf import read_urdf

__all__ = [
    "SCENES_DIR",
    "CabinetSpec",
    "CameraSpec",
    "FilterModel",
    "FilterSpec",
    "GripperSpec",
    "MarkerSpec",
    "Pose",
    "RobotSpec",
    "Scene",
    "SceneError",
    "Shape",
    "SlotSpec",
    "StaticBody",
    "TargetModel",
    "TargetSpec",
    "filter_grasp_offset",
    "filter_parts",
    "filter_shapes",
    "load_scene",
    "marker_frame_pose",
    "marker_frames",
    "resolve_scene",
    "slot_body",
    "target_parts",
]

SCENES_DIR = Path(__file__).resolve().parent / "scenes"
SHAPE_TYPES = ("box", "cylinder")
#: The dictionary markers are drawn from unless the scene names another (OpenCV's name for it).
DEFAULT_MARKER_DICTIONARY = "DICT_APRILTAG_36h11"
RGBA = tuple[float, float, float, float]


class SceneError(DataFileError):
    """A scene file is missing, malformed or refers to something it does not define."""


@dataclass(frozen=True)
class Pose:
    """Position (m) and roll-pitch-yaw (rad); ``quaternion`` is pybullet's (x, y, z, w)."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        """Fixed-axis roll-pitch-yaw as (x, y, z, w), as pybullet's getQuaternionFromEuler."""
        half = [a / 2 for a in self.rpy]
        cr, cp, cy = (math.cos(a) for a in half)
        sr, sp, sy = (math.sin(a) for a in half)
        return (
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        )


@dataclass(frozen=True)
class Shape:
    """One primitive of a static body, placed in the body's frame."""

    type: str  # "box" | "cylinder"
    pose: Pose
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    length: float = 0.0


@dataclass(frozen=True)
class StaticBody:
    name: str
    pose: Pose
    color: tuple[float, float, float, float]
    shapes: tuple[Shape, ...]


@dataclass(frozen=True)
class SlotSpec:
    """A place a filter can be seated; ``pose`` is the seated filter's frame (x into the slot)."""

    name: str
    pose: Pose


@dataclass(frozen=True)
class FilterModel:
    body_size: tuple[float, float, float]
    handle_size: tuple[float, float, float]
    mass: float
    colors: dict[str, tuple[float, float, float, float]]


@dataclass(frozen=True)
class FilterSpec:
    id: str
    condition: str
    slot: str


@dataclass(frozen=True)
class CabinetSpec:
    slot: str
    locked: bool
    latch_pose: Pose
    latch_size: tuple[float, float, float]


@dataclass(frozen=True)
class TargetSpec:
    name: str
    condition: str  # "clean" or the kind of damage, e.g. "impact", "leak_stain"
    pose: Pose


@dataclass(frozen=True)
class TargetModel:
    panel_size: tuple[float, float, float]
    colors: dict[str, tuple[float, float, float, float]]
    mark_radius: dict[str, float]


@dataclass(frozen=True)
class CameraSpec:
    """A fixed camera (eye/target) or one mounted on a robot link looking along the link's z."""

    name: str
    width: int
    height: int
    fov_deg: float
    eye: tuple[float, float, float] | None = None
    target: tuple[float, float, float] | None = None
    link: str | None = None
    near: float = 0.05
    far: float = 40.0
    background: tuple[float, float, float] | None = None  # RGB 0..1 where nothing is drawn


@dataclass(frozen=True)
class MarkerSpec:
    """A fiducial marker printed on an object: ``pose`` in ``frame`` (z out of the printed face,
    x right and y up as the marker reads), ``size`` the black square's side in m."""

    id: int
    size: float
    frame: str  # a body, a slot, filter/<id> or target/<name>
    pose: Pose


@dataclass(frozen=True)
class GripperSpec:
    joints: tuple[str, ...]
    finger_links: tuple[str, ...]
    poses: dict[str, tuple[float, ...]]
    initial: str


@dataclass(frozen=True)
class RobotSpec:
    name: str
    urdf: Path
    base: Pose
    base_link: str
    tool_link: str
    arm_joints: tuple[str, ...]
    initial_positions: tuple[float, ...]
    gripper: GripperSpec | None


@dataclass(frozen=True)
class Scene:
    name: str
    path: Path
    gravity: tuple[float, float, float]
    physics_rate_hz: float
    robot: RobotSpec
    bodies: tuple[StaticBody, ...]
    slots: dict[str, SlotSpec]
    filter_model: FilterModel | None
    filters: tuple[FilterSpec, ...]
    cabinet: CabinetSpec | None
    targets: tuple[TargetSpec, ...]
    target_model: TargetModel | None
    cameras: dict[str, CameraSpec]
    markers: tuple[MarkerSpec, ...] = ()
    marker_dictionary: str = DEFAULT_MARKER_DICTIONARY


def slot_body(scene: Scene, slot: str) -> str | None:
    """The body a slot is part of: the one its name starts with (``rack/slot_1`` is the rack's)."""
    body = slot.partition("/")[0]
    return body if "/" in slot and any(b.name == body for b in scene.bodies) else None


def marker_frames(scene: Scene) -> list[str]:
    """The frames a marker may be fixed to: bodies, slots, filters and targets."""
    return (
        [b.name for b in scene.bodies]
        + list(scene.slots)
        + [f"filter/{f.id}" for f in scene.filters]
        + [f"target/{t.name}" for t in scene.targets]
    )


def marker_frame_pose(scene: Scene, name: str) -> Pose:
    """Where ``scene`` puts one of :func:`marker_frames` (a filter: the slot it is seated in)."""
    if name in scene.slots:
        return scene.slots[name].pose
    if name.startswith("filter/"):
        spec = next(f for f in scene.filters if f"filter/{f.id}" == name)
        return scene.slots[spec.slot].pose
    if name.startswith("target/"):
        return next(t.pose for t in scene.targets if f"target/{t.name}" == name)
    return next(b.pose for b in scene.bodies if b.name == name)


def filter_grasp_offset(model: FilterModel) -> Pose:
    """Pose of the gripper's ``tool0`` in a filter's frame when it holds the filter by its handle.

    The tool approaches along the filter's +x (into the slot), fingers closing across the
    handle's width (filter y): tool z = filter x, tool y = filter y, tool x = -filter z.
    """
    depth = model.body_size[0] / 2 + model.handle_size[0] / 2
    return Pose((-depth, 0.0, 0.0), (0.0, math.pi / 2, 0.0))


def filter_shapes(model: FilterModel) -> tuple[Shape, Shape]:
    """A filter cartridge's body (at its frame) and, in front of it (-x), its handle."""
    handle_x = -(model.body_size[0] / 2 + model.handle_size[0] / 2)
    return (
        Shape("box", Pose(), size=model.body_size),
        Shape("box", Pose((handle_x, 0.0, 0.0)), size=model.handle_size),
    )


def filter_parts(model: FilterModel, condition: str) -> tuple[tuple[Shape, RGBA], tuple[Shape, RGBA]]:
    """A filter's shapes with the colours it is drawn in: body by condition, handle its own."""
    body, handle = filter_shapes(model)
    color = model.colors[condition]
    return (body, color), (handle, model.colors.get("handle", color))


def target_parts(model: TargetModel, condition: str) -> tuple[tuple[Shape, RGBA], ...]:
    """An inspection panel (raised slightly off curved hulls) and its damage mark, if any,
    in the target's frame (z = surface normal), with their colours. Drawn only: no collision."""
    raise_by = 0.015 + model.panel_size[2] / 2
    panel = (Shape("box", Pose((0.0, 0.0, raise_by)), size=model.panel_size), model.colors["panel"])
    if condition == "clean":
        return (panel,)
    mark_z = raise_by + model.panel_size[2] / 2 + 0.002
    mark = Shape("cylinder", Pose((0.0, 0.0, mark_z)), radius=model.mark_radius[condition], length=0.004)
    return panel, (mark, model.colors[condition])


# --------------------------------------------------------------------------------------- loading


def _pose(field: Field | None) -> Pose:
    if field is None:
        return Pose()
    field.mapping(optional=("xyz", "rpy"))
    xyz, rpy = field.get("xyz"), field.get("rpy")
    return Pose(
        xyz.numbers(3) if xyz else (0.0, 0.0, 0.0),  # type: ignore[arg-type]
        rpy.numbers(3) if rpy else (0.0, 0.0, 0.0),  # type: ignore[arg-type]
    )


def _colors(field: Field) -> dict[str, tuple[float, float, float, float]]:
    return {name: value.numbers(4, min=0.0, max=1.0) for name, value in field.entries()}  # type: ignore[misc]


def _unique(items: list[Field], names: list[str], what: str) -> None:
    for i, name in enumerate(names):
        if name in names[:i]:
            raise items[i].fail(f"{what} {name!r} is defined twice")


def resolve_scene(scene: str | Path) -> Path:
    """A scene file path, or the shipped scene called ``scene`` (``iva``, ``eva``).

    Raises:
        SceneError: a bare name that is not a shipped scene.
    """
    return shipped_or_path(scene, SCENES_DIR, "scene", SceneError)


def load_scene(scene: str | Path) -> Scene:
    """Load a scene by path, or a shipped one by name.

    Raises:
        SceneError: ``file:line: key: problem`` when the file is malformed or inconsistent.
    """
    path = resolve_scene(scene)
    root = load_file(path, error=SceneError).mapping(
        required=("name", "robot"),
        optional=(
            "gravity",
            "physics_rate_hz",
            "bodies",
            "slots",
            "filter_model",
            "filters",
            "cabinet",
            "targets",
            "target_model",
            "cameras",
            "markers",
            "marker_dictionary",
        ),
    )
    robot = _load_robot(root["robot"])
    bodies = tuple(_load_body(b) for b in _listed(root, "bodies"))
    _unique(_listed(root, "bodies"), [b.name for b in bodies], "body")
    slot_fields = _listed(root, "slots")
    slots: dict[str, SlotSpec] = {}
    for s in slot_fields:
        s.mapping(required=("name", "pose"))
        name = s["name"].text()
        if name in slots:
            raise s["name"].fail(f"slot {name!r} is defined twice")
        slots[name] = SlotSpec(name, _pose(s["pose"]))
    filter_fields = _listed(root, "filters")
    filters = tuple(_load_filter(f, slots) for f in filter_fields)
    _unique(filter_fields, [f.id for f in filters], "filter")
    _unique(filter_fields, [f.slot for f in filters], "a filter in slot")
    filter_model = None
    if filters or root.has("filter_model"):
        fm = root["filter_model"].mapping(required=("body_size", "handle_size", "mass", "colors"))
        filter_model = FilterModel(
            fm["body_size"].numbers(3, min=1e-3),  # type: ignore[arg-type]
            fm["handle_size"].numbers(3, min=1e-3),  # type: ignore[arg-type]
            fm["mass"].number(min=1e-6),
            _colors(fm["colors"]),
        )
        for field, f in zip(filter_fields, filters, strict=False):
            if f.condition not in filter_model.colors:
                raise field["condition"].fail(f"condition {f.condition!r} has no colour in filter_model.colors")
    cabinet = None
    if root.has("cabinet"):
        c = root["cabinet"].mapping(required=("slot", "latch"), optional=("locked",))
        slot = c["slot"].text()
        if slot not in slots:
            raise c["slot"].fail(f"unknown slot {slot!r}; slots are {sorted(slots)}")
        latch = c["latch"].mapping(required=("xyz", "size"))
        locked = c.get("locked")
        cabinet = CabinetSpec(
            slot,
            locked.boolean() if locked else False,
            Pose(latch["xyz"].numbers(3)),  # type: ignore[arg-type]
            latch["size"].numbers(3, min=1e-3),  # type: ignore[arg-type]
        )
    target_fields = _listed(root, "targets")
    targets = tuple(_load_target(t) for t in target_fields)
    _unique(target_fields, [t.name for t in targets], "target")
    target_model = None
    if targets or root.has("target_model"):
        tm = root["target_model"].mapping(required=("panel_size", "colors"), optional=("mark_radius",))
        radius = tm.get("mark_radius")
        target_model = TargetModel(
            tm["panel_size"].numbers(3, min=1e-3),  # type: ignore[arg-type]
            _colors(tm["colors"]),
            {name: value.number(min=1e-4) for name, value in radius.entries()} if radius else {},
        )
        if "panel" not in target_model.colors:
            raise tm["colors"].fail("needs a 'panel' colour")
        for field, t in zip(target_fields, targets, strict=False):
            if t.condition != "clean" and (
                t.condition not in target_model.mark_radius or t.condition not in target_model.colors
            ):
                raise field["condition"].fail(
                    f"condition {t.condition!r} needs a colour and a mark_radius in target_model"
                )
    camera_fields = _listed(root, "cameras")
    cameras = [_load_camera(c) for c in camera_fields]
    _unique(camera_fields, [c.name for c in cameras], "camera")
    gravity = root.get("gravity")
    rate = root.get("physics_rate_hz")
    loaded = Scene(
        name=root["name"].text(),
        path=path,
        gravity=gravity.numbers(3) if gravity else (0.0, 0.0, -9.81),  # type: ignore[arg-type]
        physics_rate_hz=rate.number(min=10.0, max=10000.0) if rate else 240.0,
        robot=robot,
        bodies=bodies,
        slots=slots,
        filter_model=filter_model,
        filters=filters,
        cabinet=cabinet,
        targets=targets,
        target_model=target_model,
        cameras={c.name: c for c in cameras},
    )
    dictionary = root.get("marker_dictionary")
    marker_fields = _listed(root, "markers")
    if not marker_fields and dictionary is None:
        return loaded
    size = _dictionary_size(dictionary)
    frames = marker_frames(loaded)
    markers = tuple(_load_marker(m, frames, size) for m in marker_fields)
    _unique(marker_fields, [str(m.id) for m in markers], "marker")
    return replace(
        loaded, markers=markers, marker_dictionary=dictionary.text() if dictionary else DEFAULT_MARKER_DICTIONARY
    )


def _dictionary_size(f: Field | None) -> int:
    """How many markers the named OpenCV dictionary has (its ids are 0 to that, exclusive)."""
    import cv2  # only scenes with markers need OpenCV

    name = f.text() if f is not None else DEFAULT_MARKER_DICTIONARY
    known = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_") and isinstance(getattr(cv2.aruco, n), int))
    if name not in known:
        assert f is not None  # the default is one of them
        raise f.fail(f"unknown marker dictionary {name!r}; OpenCV's are {', '.join(known)}")
    return int(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).bytesList.shape[0])


def _load_marker(m: Field, frames: list[str], dictionary_size: int) -> MarkerSpec:
    m.mapping(required=("id", "size", "frame"), optional=("xyz", "rpy"))
    frame = m["frame"].text()
    if frame not in frames:
        raise m["frame"].fail(f"unknown frame {frame!r}; markers are fixed to one of {', '.join(frames)}")
    return MarkerSpec(
        id=m["id"].integer(min=0, max=dictionary_size - 1),
        size=m["size"].number(min=0.005, max=2.0),
        frame=frame,
        pose=_pose_of(m),
    )


def _listed(root: Field, key: str) -> list[Field]:
    value = root.get(key)
    return value.sequence() if value is not None else []


def _load_robot(r: Field) -> RobotSpec:
    r.mapping(
        required=("name", "urdf", "base", "tool_link", "arm_joints", "initial_positions"),
        optional=("base_link", "gripper"),
    )
    joints = r["arm_joints"].names(min_items=1)
    gripper = None
    if r.has("gripper"):
        g = r["gripper"].mapping(required=("joints", "finger_links", "poses", "initial"))
        gripper_joints = g["joints"].names(min_items=1)
        poses = {name: value.numbers(len(gripper_joints)) for name, value in g["poses"].entries()}
        if not poses:
            raise g["poses"].fail("name at least one gripper pose (e.g. open, closed)")
        initial = g["initial"].text()
        if initial not in poses:
            raise g["initial"].fail(f"unknown pose {initial!r}; poses are {sorted(poses)}")
        gripper = GripperSpec(gripper_joints, g["finger_links"].names(), poses, initial)
    # every name the scene gives the robot, checked where it is written, not when pybullet loads it
    urdf = read_urdf(r["urdf"].file_path())
    urdf.check_link(r["tool_link"])
    if r.has("base_link"):
        urdf.check_link(r["base_link"])
    for joint in r["arm_joints"].sequence():
        urdf.check_joint(joint)
    if r.has("gripper"):
        for joint in r["gripper"]["joints"].sequence():
            urdf.check_joint(joint)
        for link in r["gripper"]["finger_links"].sequence():
            urdf.check_link(link)
    base_link = r.get("base_link")
    return RobotSpec(
        name=r["name"].text(),
        urdf=r["urdf"].file_path(),
        base=_pose(r["base"]),
        base_link=base_link.text() if base_link else "base_link",
        tool_link=r["tool_link"].text(),
        arm_joints=joints,
        initial_positions=r["initial_positions"].numbers(len(joints)),
        gripper=gripper,
    )


def _load_body(b: Field) -> StaticBody:
    b.mapping(required=("name", "shapes"), optional=("pose", "color"))
    shapes = []
    for s in b["shapes"].sequence(min_items=1):
        kind = s.mapping(required=("type",), any_keys=True)["type"].choice(SHAPE_TYPES)
        if kind == "box":
            s.mapping(required=("type", "size"), optional=("xyz", "rpy"))
            shapes.append(Shape("box", _pose_of(s), size=s["size"].numbers(3, min=1e-4)))  # type: ignore[arg-type]
        else:
            s.mapping(required=("type", "radius", "length"), optional=("xyz", "rpy"))
            shapes.append(
                Shape("cylinder", _pose_of(s), radius=s["radius"].number(min=1e-4), length=s["length"].number(min=1e-4))
            )
    color = b.get("color")
    return StaticBody(
        b["name"].text(),
        _pose(b.get("pose")),
        color.numbers(4, min=0.0, max=1.0) if color else (0.7, 0.7, 0.7, 1.0),  # type: ignore[arg-type]
        tuple(shapes),
    )


def _pose_of(shape: Field) -> Pose:
    """A shape's own xyz/rpy keys, written inline next to its type and size."""
    xyz, rpy = shape.get("xyz"), shape.get("rpy")
    return Pose(xyz.numbers(3) if xyz else (0.0, 0.0, 0.0), rpy.numbers(3) if rpy else (0.0, 0.0, 0.0))  # type: ignore[arg-type]


def _load_filter(f: Field, slots: dict[str, SlotSpec]) -> FilterSpec:
    f.mapping(required=("id", "condition", "slot"))
    spec = FilterSpec(f["id"].text(), f["condition"].text(), f["slot"].text())
    if spec.slot not in slots:
        raise f["slot"].fail(f"unknown slot {spec.slot!r}; slots are {sorted(slots)}")
    return spec


def _load_target(t: Field) -> TargetSpec:
    t.mapping(required=("name", "condition", "pose"))
    return TargetSpec(t["name"].text(), t["condition"].text(), _pose(t["pose"]))


def _load_camera(c: Field) -> CameraSpec:
    c.mapping(
        required=("name", "width", "height", "fov_deg"), optional=("eye", "target", "link", "near", "far", "background")
    )
    link = c.get("link")
    eye = target = None
    if link is None:
        c.mapping(
            required=("name", "width", "height", "fov_deg", "eye", "target"), optional=("near", "far", "background")
        )
        eye = c["eye"].numbers(3)
        target = c["target"].numbers(3)
    elif c.has("eye") or c.has("target"):
        raise c.fail("a camera is either fixed (eye, target) or mounted on a link, not both")
    near, far, background = c.get("near"), c.get("far"), c.get("background")
    name = c["name"].text()
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
        # it names the camera's topics (camera/<name>/image): only a ROS name will do
        raise c["name"].fail(f"{name!r} is not a ROS name: letters, digits and _, starting with a letter")
    return CameraSpec(
        name=name,
        width=c["width"].integer(min=8, max=4096),
        height=c["height"].integer(min=8, max=4096),
        fov_deg=c["fov_deg"].number(min=1.0, max=179.0),
        eye=eye,  # type: ignore[arg-type]
        target=target,  # type: ignore[arg-type]
        link=None if link is None else link.text(),
        near=near.number(min=1e-4) if near else 0.05,
        far=far.number(min=1e-3) if far else 40.0,
        background=background.numbers(3, min=0.0, max=1.0) if background else None,  # type: ignore[arg-type]
    )
