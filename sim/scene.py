"""Scenes as data: load ``sim/scenes/<scene>.yaml`` and build its world into a pybullet client.

The simulation node and the planner both call :func:`build_world` on their own pybullet client,
so the planner's collision scene is made from exactly the same file as the simulated world.
Moving a rack or adding a target is a change to the YAML file, not to code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pybullet as p
import yaml

__all__ = [
    "ROBOTS_DIR",
    "SCENES_DIR",
    "CabinetSpec",
    "CameraSpec",
    "FilterModel",
    "FilterSpec",
    "GripperSpec",
    "Pose",
    "RobotSpec",
    "Scene",
    "SceneError",
    "Shape",
    "SlotSpec",
    "StaticBody",
    "TargetModel",
    "TargetSpec",
    "World",
    "build_world",
    "filter_grasp_offset",
    "load_scene",
]

SCENES_DIR = Path(__file__).resolve().parent / "scenes"
ROBOTS_DIR = Path(__file__).resolve().parent / "robots"


class SceneError(ValueError):
    """A scene file is missing, malformed or refers to something it does not define."""


@dataclass(frozen=True)
class Pose:
    """Position (m) and roll-pitch-yaw (rad); ``quaternion`` is pybullet's (x, y, z, w)."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        return tuple(p.getQuaternionFromEuler(self.rpy))  # type: ignore[return-value]


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


@dataclass
class World:
    """Body ids of a scene built into one pybullet client."""

    client: int
    robot: int
    joint_index: dict[str, int]
    link_index: dict[str, int]
    bodies: dict[str, int] = field(default_factory=dict)
    filters: dict[str, int] = field(default_factory=dict)
    targets: dict[str, int] = field(default_factory=dict)
    latch: int | None = None

    def body_name(self, body_id: int) -> str:
        """Name of a body for messages ("rack", "filter/CDRA-F-0012", "ur10")."""
        if body_id == self.robot:
            return "robot"
        for prefix, table in (("", self.bodies), ("filter/", self.filters), ("target/", self.targets)):
            for name, bid in table.items():
                if bid == body_id:
                    return prefix + name
        return f"body {body_id}"


# --------------------------------------------------------------------------------------- loading


class _Reader:
    """Typed access to a YAML mapping that names the file and key path in every error."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, where: str, message: str) -> SceneError:
        return SceneError(f"{self.path}: {where}: {message}")

    def mapping(self, data: Any, where: str) -> dict[str, Any]:
        if not isinstance(data, dict):
            raise self.fail(where, f"expected a mapping, got {type(data).__name__}")
        return data

    def get(self, data: dict[str, Any], key: str, where: str, default: Any = ...) -> Any:
        if key not in data:
            if default is ...:
                raise self.fail(where, f"missing key {key!r}")
            return default
        return data[key]

    def number(self, value: Any, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(where, f"expected a finite number, got {value!r}")
        return float(value)

    def vector(self, value: Any, n: int, where: str) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(where, f"expected a list of {n} numbers, got {value!r}")
        return tuple(self.number(v, f"{where}[{i}]") for i, v in enumerate(value))

    def pose(self, value: Any, where: str) -> Pose:
        if value is None:
            return Pose()
        data = self.mapping(value, where)
        unknown = set(data) - {"xyz", "rpy"}
        if unknown:
            raise self.fail(where, f"unknown keys {sorted(unknown)} (expected xyz, rpy)")
        return Pose(
            self.vector(data.get("xyz", [0, 0, 0]), 3, f"{where}.xyz"),  # type: ignore[arg-type]
            self.vector(data.get("rpy", [0, 0, 0]), 3, f"{where}.rpy"),  # type: ignore[arg-type]
        )

    def names(self, value: Any, where: str) -> tuple[str, ...]:
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            raise self.fail(where, f"expected a list of names, got {value!r}")
        return tuple(value)

    def colors(self, value: Any, where: str) -> dict[str, tuple[float, float, float, float]]:
        data = self.mapping(value, where)
        return {k: self.vector(v, 4, f"{where}.{k}") for k, v in data.items()}  # type: ignore[misc]


def _resolve(scene: str | Path) -> Path:
    path = Path(scene)
    if path.suffix in (".yaml", ".yml"):
        return path
    candidate = SCENES_DIR / f"{scene}.yaml"
    if not candidate.exists():
        known = sorted(f.stem for f in SCENES_DIR.glob("*.yaml"))
        raise SceneError(f"unknown scene {str(scene)!r}: expected one of {known} or a path to a .yaml file")
    return candidate


def load_scene(scene: str | Path) -> Scene:
    """Load a scene by name (``"iva"``, ``"eva"``) or by path to its YAML file.

    Raises:
        SceneError: naming the file and key when the file is malformed or inconsistent.
    """
    path = _resolve(scene)
    if not path.exists():
        raise SceneError(f"{path}: no such scene file")
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise SceneError(f"{path}: not valid YAML: {exc}") from exc
    r = _Reader(path)
    data = r.mapping(raw, "top level")
    robot = _load_robot(r, r.mapping(r.get(data, "robot", "top level"), "robot"))
    bodies = tuple(_load_body(r, r.mapping(b, f"bodies[{i}]"), f"bodies[{i}]") for i, b in enumerate(data.get("bodies", [])))
    slots: dict[str, SlotSpec] = {}
    for i, s in enumerate(data.get("slots", [])):
        s = r.mapping(s, f"slots[{i}]")
        name = str(r.get(s, "name", f"slots[{i}]"))
        slots[name] = SlotSpec(name, r.pose(r.get(s, "pose", f"slots[{i}]"), f"slots[{i}].pose"))
    filters = tuple(_load_filter(r, r.mapping(f, f"filters[{i}]"), f"filters[{i}]", slots) for i, f in enumerate(data.get("filters", [])))
    occupied = [f.slot for f in filters]
    for slot in set(occupied):
        if occupied.count(slot) > 1:
            raise r.fail("filters", f"more than one filter in slot {slot!r}")
    filter_model = None
    if filters:
        fm = r.mapping(r.get(data, "filter_model", "top level"), "filter_model")
        filter_model = FilterModel(
            r.vector(r.get(fm, "body_size", "filter_model"), 3, "filter_model.body_size"),  # type: ignore[arg-type]
            r.vector(r.get(fm, "handle_size", "filter_model"), 3, "filter_model.handle_size"),  # type: ignore[arg-type]
            r.number(r.get(fm, "mass", "filter_model"), "filter_model.mass"),
            r.colors(r.get(fm, "colors", "filter_model"), "filter_model.colors"),
        )
        for f in filters:
            if f.condition not in filter_model.colors:
                raise r.fail("filters", f"filter {f.id}: condition {f.condition!r} has no colour in filter_model.colors")
    cabinet = None
    if "cabinet" in data:
        c = r.mapping(data["cabinet"], "cabinet")
        slot = str(r.get(c, "slot", "cabinet"))
        if slot not in slots:
            raise r.fail("cabinet.slot", f"unknown slot {slot!r}; slots are {sorted(slots)}")
        latch = r.mapping(r.get(c, "latch", "cabinet"), "cabinet.latch")
        cabinet = CabinetSpec(
            slot,
            bool(r.get(c, "locked", "cabinet", False)),
            Pose(r.vector(r.get(latch, "xyz", "cabinet.latch"), 3, "cabinet.latch.xyz")),  # type: ignore[arg-type]
            r.vector(r.get(latch, "size", "cabinet.latch"), 3, "cabinet.latch.size"),  # type: ignore[arg-type]
        )
    targets = tuple(
        TargetSpec(
            str(r.get(t, "name", f"targets[{i}]")),
            str(r.get(t, "condition", f"targets[{i}]")),
            r.pose(r.get(t, "pose", f"targets[{i}]"), f"targets[{i}].pose"),
        )
        for i, t in enumerate(r.mapping(t, f"targets[{i}]") for i, t in enumerate(data.get("targets", [])))
    )
    target_model = None
    if targets:
        tm = r.mapping(r.get(data, "target_model", "top level"), "target_model")
        target_model = TargetModel(
            r.vector(r.get(tm, "panel_size", "target_model"), 3, "target_model.panel_size"),  # type: ignore[arg-type]
            r.colors(r.get(tm, "colors", "target_model"), "target_model.colors"),
            {k: r.number(v, f"target_model.mark_radius.{k}") for k, v in r.mapping(tm.get("mark_radius", {}), "target_model.mark_radius").items()},
        )
        for t in targets:
            if t.condition != "clean" and t.condition not in target_model.mark_radius:
                raise r.fail("targets", f"target {t.name}: condition {t.condition!r} has no mark_radius in target_model")
    cameras = {c.name: c for c in (_load_camera(r, r.mapping(c, f"cameras[{i}]"), f"cameras[{i}]") for i, c in enumerate(data.get("cameras", [])))}
    return Scene(
        name=str(r.get(data, "name", "top level")),
        path=path,
        gravity=r.vector(data.get("gravity", [0, 0, -9.81]), 3, "gravity"),  # type: ignore[arg-type]
        physics_rate_hz=r.number(data.get("physics_rate_hz", 240), "physics_rate_hz"),
        robot=robot,
        bodies=bodies,
        slots=slots,
        filter_model=filter_model,
        filters=filters,
        cabinet=cabinet,
        targets=targets,
        target_model=target_model,
        cameras=cameras,
    )


def _load_robot(r: _Reader, data: dict[str, Any]) -> RobotSpec:
    urdf = ROBOTS_DIR / str(r.get(data, "urdf", "robot"))
    if not urdf.exists():
        raise r.fail("robot.urdf", f"no such robot model {urdf}")
    joints = r.names(r.get(data, "arm_joints", "robot"), "robot.arm_joints")
    initial = r.vector(r.get(data, "initial_positions", "robot"), len(joints), "robot.initial_positions")
    gripper = None
    if "gripper" in data:
        g = r.mapping(data["gripper"], "robot.gripper")
        gjoints = r.names(r.get(g, "joints", "robot.gripper"), "robot.gripper.joints")
        poses = {
            str(k): r.vector(v, len(gjoints), f"robot.gripper.poses.{k}")
            for k, v in r.mapping(r.get(g, "poses", "robot.gripper"), "robot.gripper.poses").items()
        }
        initial_pose = str(r.get(g, "initial", "robot.gripper"))
        if initial_pose not in poses:
            raise r.fail("robot.gripper.initial", f"unknown pose {initial_pose!r}; poses are {sorted(poses)}")
        gripper = GripperSpec(gjoints, r.names(r.get(g, "finger_links", "robot.gripper"), "robot.gripper.finger_links"), poses, initial_pose)
    return RobotSpec(
        name=str(r.get(data, "name", "robot")),
        urdf=urdf,
        base=r.pose(r.get(data, "base", "robot"), "robot.base"),
        base_link=str(data.get("base_link", "base_link")),
        tool_link=str(r.get(data, "tool_link", "robot")),
        arm_joints=joints,
        initial_positions=initial,
        gripper=gripper,
    )


def _load_body(r: _Reader, data: dict[str, Any], where: str) -> StaticBody:
    shapes = []
    for i, s in enumerate(r.get(data, "shapes", where)):
        s = r.mapping(s, f"{where}.shapes[{i}]")
        kind = r.get(s, "type", f"{where}.shapes[{i}]")
        pose = r.pose({k: s[k] for k in ("xyz", "rpy") if k in s}, f"{where}.shapes[{i}]")
        if kind == "box":
            shapes.append(Shape("box", pose, size=r.vector(r.get(s, "size", f"{where}.shapes[{i}]"), 3, f"{where}.shapes[{i}].size")))  # type: ignore[arg-type]
        elif kind == "cylinder":
            shapes.append(
                Shape(
                    "cylinder",
                    pose,
                    radius=r.number(r.get(s, "radius", f"{where}.shapes[{i}]"), f"{where}.shapes[{i}].radius"),
                    length=r.number(r.get(s, "length", f"{where}.shapes[{i}]"), f"{where}.shapes[{i}].length"),
                )
            )
        else:
            raise r.fail(f"{where}.shapes[{i}].type", f"unknown shape type {kind!r} (expected box or cylinder)")
    return StaticBody(
        str(r.get(data, "name", where)),
        r.pose(data.get("pose"), f"{where}.pose"),
        r.vector(data.get("color", [0.7, 0.7, 0.7, 1.0]), 4, f"{where}.color"),  # type: ignore[arg-type]
        tuple(shapes),
    )


def _load_filter(r: _Reader, data: dict[str, Any], where: str, slots: dict[str, SlotSpec]) -> FilterSpec:
    spec = FilterSpec(str(r.get(data, "id", where)), str(r.get(data, "condition", where)), str(r.get(data, "slot", where)))
    if spec.slot not in slots:
        raise r.fail(f"{where}.slot", f"unknown slot {spec.slot!r}; slots are {sorted(slots)}")
    return spec


def _load_camera(r: _Reader, data: dict[str, Any], where: str) -> CameraSpec:
    link = data.get("link")
    eye = target = None
    if link is None:
        eye = r.vector(r.get(data, "eye", where), 3, f"{where}.eye")
        target = r.vector(r.get(data, "target", where), 3, f"{where}.target")
    return CameraSpec(
        name=str(r.get(data, "name", where)),
        width=int(r.number(r.get(data, "width", where), f"{where}.width")),
        height=int(r.number(r.get(data, "height", where), f"{where}.height")),
        fov_deg=r.number(r.get(data, "fov_deg", where), f"{where}.fov_deg"),
        eye=eye,  # type: ignore[arg-type]
        target=target,  # type: ignore[arg-type]
        link=None if link is None else str(link),
        near=r.number(data.get("near", 0.05), f"{where}.near"),
        far=r.number(data.get("far", 40.0), f"{where}.far"),
        background=None if "background" not in data else r.vector(data["background"], 3, f"{where}.background"),  # type: ignore[arg-type]
    )


# -------------------------------------------------------------------------------------- building


def filter_grasp_offset(model: FilterModel) -> Pose:
    """Pose of the gripper's ``tool0`` in a filter's frame when it holds the filter by its handle.

    The tool approaches along the filter's +x (into the slot), fingers closing across the
    handle's width (filter y): tool z = filter x, tool y = filter y, tool x = -filter z.
    """
    depth = model.body_size[0] / 2 + model.handle_size[0] / 2
    return Pose((-depth, 0.0, 0.0), (0.0, math.pi / 2, 0.0))


def _shape_arrays(shapes: tuple[Shape, ...]) -> dict[str, list[Any]]:
    kinds, extents, radii, lengths, positions, orientations = [], [], [], [], [], []
    for s in shapes:
        kinds.append(p.GEOM_BOX if s.type == "box" else p.GEOM_CYLINDER)
        extents.append([v / 2 for v in s.size])
        radii.append(s.radius)
        lengths.append(s.length)
        positions.append(list(s.pose.xyz))
        orientations.append(list(s.pose.quaternion))
    return {"shapeTypes": kinds, "halfExtents": extents, "radii": radii, "lengths": lengths, "positions": positions, "orientations": orientations}


def _static_body(body: StaticBody, client: int) -> int:
    a = _shape_arrays(body.shapes)
    collision = p.createCollisionShapeArray(
        shapeTypes=a["shapeTypes"], halfExtents=a["halfExtents"], radii=a["radii"], lengths=a["lengths"],
        collisionFramePositions=a["positions"], collisionFrameOrientations=a["orientations"], physicsClientId=client,
    )
    visual = p.createVisualShapeArray(
        shapeTypes=a["shapeTypes"], halfExtents=a["halfExtents"], radii=a["radii"], lengths=a["lengths"],
        visualFramePositions=a["positions"], visualFrameOrientations=a["orientations"], physicsClientId=client,
    )
    body_id = p.createMultiBody(0.0, collision, visual, list(body.pose.xyz), list(body.pose.quaternion), physicsClientId=client)
    p.changeVisualShape(body_id, -1, rgbaColor=list(body.color), physicsClientId=client)
    return body_id


def _filter_body(model: FilterModel, condition: str, pose: Pose, client: int) -> int:
    bx, _, _ = model.body_size
    hx = model.handle_size[0]
    kinds = [p.GEOM_BOX, p.GEOM_BOX]
    extents = [[v / 2 for v in model.body_size], [v / 2 for v in model.handle_size]]
    positions = [[0.0, 0.0, 0.0], [-(bx / 2 + hx / 2), 0.0, 0.0]]
    collision = p.createCollisionShapeArray(shapeTypes=kinds, halfExtents=extents, collisionFramePositions=positions, physicsClientId=client)
    # Visual shapes one per link so the handle keeps its own colour.
    body_visual = p.createVisualShape(p.GEOM_BOX, halfExtents=extents[0], rgbaColor=list(model.colors[condition]), physicsClientId=client)
    handle_visual = p.createVisualShape(
        p.GEOM_BOX, halfExtents=extents[1], visualFramePosition=positions[1],
        rgbaColor=list(model.colors.get("handle", model.colors[condition])), physicsClientId=client,
    )
    return p.createMultiBody(
        model.mass, collision, body_visual, list(pose.xyz), list(pose.quaternion),
        linkMasses=[0.0], linkCollisionShapeIndices=[-1], linkVisualShapeIndices=[handle_visual],
        linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]], linkInertialFramePositions=[[0, 0, 0]],
        linkInertialFrameOrientations=[[0, 0, 0, 1]], linkParentIndices=[0], linkJointTypes=[p.JOINT_FIXED],
        linkJointAxis=[[0, 0, 1]], physicsClientId=client,
    )


def _target_body(spec: TargetSpec, model: TargetModel, client: int) -> int:
    """A visual-only inspection panel with its damage mark; raised slightly off curved hulls."""
    raise_by = 0.015 + model.panel_size[2] / 2
    panel = p.createVisualShape(
        p.GEOM_BOX, halfExtents=[v / 2 for v in model.panel_size], visualFramePosition=[0, 0, raise_by],
        rgbaColor=list(model.colors["panel"]), physicsClientId=client,
    )
    link_visuals = []
    if spec.condition != "clean":
        link_visuals.append(
            p.createVisualShape(
                p.GEOM_CYLINDER, radius=model.mark_radius[spec.condition], length=0.004,
                visualFramePosition=[0, 0, raise_by + model.panel_size[2] / 2 + 0.002],
                rgbaColor=list(model.colors[spec.condition]), physicsClientId=client,
            )
        )
    n = len(link_visuals)
    return p.createMultiBody(
        0.0, -1, panel, list(spec.pose.xyz), list(spec.pose.quaternion),
        linkMasses=[0.0] * n, linkCollisionShapeIndices=[-1] * n, linkVisualShapeIndices=link_visuals,
        linkPositions=[[0, 0, 0]] * n, linkOrientations=[[0, 0, 0, 1]] * n, linkInertialFramePositions=[[0, 0, 0]] * n,
        linkInertialFrameOrientations=[[0, 0, 0, 1]] * n, linkParentIndices=[0] * n, linkJointTypes=[p.JOINT_FIXED] * n,
        linkJointAxis=[[0, 0, 1]] * n, physicsClientId=client,
    )


def build_world(scene: Scene, client: int, *, with_filters: bool = True, with_targets: bool = True) -> World:
    """Build the scene's robot, static bodies, filters (in their slots) and targets into ``client``.

    The planner may pass ``with_filters=False`` and place filters itself from ``/sim/frames``.
    The robot is loaded with a fixed base and its initial joint positions from the scene file.
    """
    p.setGravity(*scene.gravity, physicsClientId=client)
    robot = p.loadURDF(
        str(scene.robot.urdf), list(scene.robot.base.xyz), list(scene.robot.base.quaternion),
        useFixedBase=True, flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client,
    )
    joint_index: dict[str, int] = {}
    link_index: dict[str, int] = {scene.robot.base_link: -1}
    for j in range(p.getNumJoints(robot, physicsClientId=client)):
        info = p.getJointInfo(robot, j, physicsClientId=client)
        joint_index[info[1].decode()] = j
        link_index[info[12].decode()] = j
    needed = list(scene.robot.arm_joints) + (list(scene.robot.gripper.joints) if scene.robot.gripper else [])
    missing = [name for name in needed if name not in joint_index]
    if missing:
        raise SceneError(f"{scene.path}: robot {scene.robot.urdf.name} has no joints {missing}")
    for name in [scene.robot.tool_link] + [c.link for c in scene.cameras.values() if c.link]:
        if name not in link_index:
            raise SceneError(f"{scene.path}: robot {scene.robot.urdf.name} has no link {name!r}")
    for name, q in zip(scene.robot.arm_joints, scene.robot.initial_positions):
        p.resetJointState(robot, joint_index[name], q, physicsClientId=client)
    if scene.robot.gripper:
        for name, q in zip(scene.robot.gripper.joints, scene.robot.gripper.poses[scene.robot.gripper.initial]):
            p.resetJointState(robot, joint_index[name], q, physicsClientId=client)
    world = World(client, robot, joint_index, link_index)
    for body in scene.bodies:
        world.bodies[body.name] = _static_body(body, client)
    if with_filters and scene.filter_model:
        for f in scene.filters:
            world.filters[f.id] = _filter_body(scene.filter_model, f.condition, scene.slots[f.slot].pose, client)
    if with_targets and scene.target_model:
        for t in scene.targets:
            world.targets[t.name] = _target_body(t, scene.target_model, client)
    if scene.cabinet:
        slot = scene.slots[scene.cabinet.slot].pose
        pos, orn = p.multiplyTransforms(slot.xyz, slot.quaternion, scene.cabinet.latch_pose.xyz, [0, 0, 0, 1])
        latch_visual = p.createVisualShape(p.GEOM_BOX, halfExtents=[v / 2 for v in scene.cabinet.latch_size], physicsClientId=client)
        world.latch = p.createMultiBody(0.0, -1, latch_visual, pos, orn, physicsClientId=client)
    return world
