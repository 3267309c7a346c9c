"""Building a scene into a pybullet client: the simulation's world, one body per thing in the file.

The simulation node builds its world here; the planner does not (it gets the collision world
from the simulation over ROS, see ``sim.collision_world``), so a robot side with real hardware
and a world model instead of this simulation plans the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import pybullet as p

from sim.markers import MarkerTextures, marker_visual
from sim.scene import (
    RGBA,
    FilterModel,
    MarkerSpec,
    Pose,
    Scene,
    SceneError,
    Shape,
    StaticBody,
    TargetModel,
    TargetSpec,
    filter_parts,
    filter_shapes,
    slot_body,
    target_parts,
)

__all__ = ["World", "build_world"]


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
    #: marker id -> (body, link) that shows it, and the textures they can show
    markers: dict[int, tuple[int, int]] = field(default_factory=dict)
    marker_textures: MarkerTextures | None = None

    def print_marker(self, marker_id: int, printed_id: int) -> None:
        """Show ``printed_id`` (-1: nothing, a covered tag) where marker ``marker_id`` is declared."""
        assert self.marker_textures is not None  # a world with markers has textures
        body, link = self.markers[marker_id]
        p.changeVisualShape(
            body, link, textureUniqueId=self.marker_textures.texture(printed_id), physicsClientId=self.client
        )

    def body_name(self, body_id: int) -> str:
        """Name of a body for messages ("rack", "filter/CDRA-F-0012", "ur10")."""
        if body_id == self.robot:
            return "robot"
        for prefix, table in (("", self.bodies), ("filter/", self.filters), ("target/", self.targets)):
            for name, bid in table.items():
                if bid == body_id:
                    return prefix + name
        return f"body {body_id}"


def _shape_arrays(shapes: tuple[Shape, ...]) -> dict[str, list[Any]]:
    kinds, extents, radii, lengths, positions, orientations = [], [], [], [], [], []
    for s in shapes:
        kinds.append(p.GEOM_BOX if s.type == "box" else p.GEOM_CYLINDER)
        extents.append([v / 2 for v in s.size])
        radii.append(s.radius)
        lengths.append(s.length)
        positions.append(list(s.pose.xyz))
        orientations.append(list(s.pose.quaternion))
    return {
        "shapeTypes": kinds,
        "halfExtents": extents,
        "radii": radii,
        "lengths": lengths,
        "positions": positions,
        "orientations": orientations,
    }


def _static_body(body: StaticBody, client: int) -> int:
    a = _shape_arrays(body.shapes)
    collision = p.createCollisionShapeArray(
        shapeTypes=a["shapeTypes"],
        halfExtents=a["halfExtents"],
        radii=a["radii"],
        lengths=a["lengths"],
        collisionFramePositions=a["positions"],
        collisionFrameOrientations=a["orientations"],
        physicsClientId=client,
    )
    visual = p.createVisualShapeArray(
        shapeTypes=a["shapeTypes"],
        halfExtents=a["halfExtents"],
        radii=a["radii"],
        lengths=a["lengths"],
        visualFramePositions=a["positions"],
        visualFrameOrientations=a["orientations"],
        physicsClientId=client,
    )
    body_id = p.createMultiBody(
        0.0, collision, visual, list(body.pose.xyz), list(body.pose.quaternion), physicsClientId=client
    )
    p.changeVisualShape(body_id, -1, rgbaColor=list(body.color), physicsClientId=client)
    return int(body_id)


def _part_arrays(parts: tuple[tuple[Shape, RGBA], ...], client: int) -> tuple[int, list[int]]:
    """One visual shape per part (so each keeps its colour): the first for the base, the rest for links."""
    visuals = []
    for shape, color in parts:
        kind = p.GEOM_BOX if shape.type == "box" else p.GEOM_CYLINDER
        visuals.append(
            p.createVisualShape(
                kind,
                halfExtents=[v / 2 for v in shape.size],
                radius=shape.radius,
                length=shape.length,
                visualFramePosition=list(shape.pose.xyz),
                visualFrameOrientation=list(shape.pose.quaternion),
                rgbaColor=list(color),
                physicsClientId=client,
            )
        )
    return visuals[0], visuals[1:]


def _multi_body(
    mass: float,
    collision: int,
    parts: tuple[tuple[Shape, RGBA], ...],
    pose: Pose,
    client: int,
    extra_visuals: tuple[int, ...] = (),
) -> int:
    """A body drawn as ``parts``; the parts after the first, then ``extra_visuals``, ride on
    fixed massless links (in that order: link i is the (i+1)-th part)."""
    base_visual, link_visuals = _part_arrays(parts, client)
    link_visuals += extra_visuals
    n = len(link_visuals)
    return int(
        p.createMultiBody(
            mass,
            collision,
            base_visual,
            list(pose.xyz),
            list(pose.quaternion),
            linkMasses=[0.0] * n,
            linkCollisionShapeIndices=[-1] * n,
            linkVisualShapeIndices=link_visuals,
            linkPositions=[[0, 0, 0]] * n,
            linkOrientations=[[0, 0, 0, 1]] * n,
            linkInertialFramePositions=[[0, 0, 0]] * n,
            linkInertialFrameOrientations=[[0, 0, 0, 1]] * n,
            linkParentIndices=[0] * n,
            linkJointTypes=[p.JOINT_FIXED] * n,
            linkJointAxis=[[0, 0, 1]] * n,
            physicsClientId=client,
        )
    )


def _filter_body(model: FilterModel, condition: str, pose: Pose, client: int, marker_visuals: tuple[int, ...]) -> int:
    shapes = filter_shapes(model)
    extents = [[v / 2 for v in s.size] for s in shapes]
    positions = [list(s.pose.xyz) for s in shapes]
    collision = p.createCollisionShapeArray(
        shapeTypes=[p.GEOM_BOX, p.GEOM_BOX],
        halfExtents=extents,
        collisionFramePositions=positions,
        physicsClientId=client,
    )
    return _multi_body(model.mass, collision, filter_parts(model, condition), pose, client, marker_visuals)


def _target_body(spec: TargetSpec, model: TargetModel, client: int) -> int:
    """A visual-only inspection panel with its damage mark."""
    return _multi_body(0.0, -1, target_parts(model, spec.condition), spec.pose, client)


def build_world(scene: Scene, client: int, *, with_filters: bool = True, with_targets: bool = True) -> World:
    """Build the scene's robot, static bodies, filters (in their slots) and targets into ``client``.

    The planner may pass ``with_filters=False`` and place filters itself from ``/sim/frames``.
    The robot is loaded with a fixed base and its initial joint positions from the scene file.
    """
    p.setGravity(*scene.gravity, physicsClientId=client)
    robot = p.loadURDF(
        str(scene.robot.urdf),
        list(scene.robot.base.xyz),
        list(scene.robot.base.quaternion),
        useFixedBase=True,
        flags=p.URDF_USE_INERTIA_FROM_FILE,
        physicsClientId=client,
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
        raise SceneError(scene.path, 0, "robot.arm_joints", f"robot model {scene.robot.urdf} has no joints {missing}")
    for name in [scene.robot.tool_link] + [c.link for c in scene.cameras.values() if c.link]:
        if name not in link_index:
            raise SceneError(scene.path, 0, "robot", f"robot model {scene.robot.urdf} has no link {name!r}")
    for name, q in zip(scene.robot.arm_joints, scene.robot.initial_positions, strict=False):
        p.resetJointState(robot, joint_index[name], q, physicsClientId=client)
    if scene.robot.gripper:
        for name, q in zip(
            scene.robot.gripper.joints, scene.robot.gripper.poses[scene.robot.gripper.initial], strict=False
        ):
            p.resetJointState(robot, joint_index[name], q, physicsClientId=client)
    world = World(client, robot, joint_index, link_index)
    for body in scene.bodies:
        world.bodies[body.name] = _static_body(body, client)
    if with_filters and scene.filter_model:
        for f in scene.filters:
            on_filter = [m for m in scene.markers if m.frame == f"filter/{f.id}"]
            visuals = tuple(marker_visual(m, scene.marker_dictionary, client) for m in on_filter)
            world.filters[f.id] = _filter_body(
                scene.filter_model, f.condition, scene.slots[f.slot].pose, client, visuals
            )
            first = len(filter_shapes(scene.filter_model)) - 1  # the link after the filter's parts
            world.markers.update({m.id: (world.filters[f.id], first + k) for k, m in enumerate(on_filter)})
    if with_targets and scene.target_model:
        for t in scene.targets:
            world.targets[t.name] = _target_body(t, scene.target_model, client)
    if scene.cabinet:
        slot = scene.slots[scene.cabinet.slot].pose
        pos, orn = p.multiplyTransforms(slot.xyz, slot.quaternion, scene.cabinet.latch_pose.xyz, [0, 0, 0, 1])
        latch_visual = p.createVisualShape(
            p.GEOM_BOX, halfExtents=[v / 2 for v in scene.cabinet.latch_size], physicsClientId=client
        )
        world.latch = p.createMultiBody(0.0, -1, latch_visual, pos, orn, physicsClientId=client)
    _fixed_markers(scene, world)
    if world.markers:
        world.marker_textures = MarkerTextures(scene.marker_dictionary, client)
        for marker_id in world.markers:
            world.print_marker(marker_id, marker_id)
    return world


def seated_filter_collisions(scene: Scene, *, depth: float = 1e-3) -> list[str]:
    """Each seated filter of ``scene`` that goes deeper than ``depth`` into a body other than the
    one its slot is part of, or into another filter, as "filter/<id> in <body>": a world where
    that is so cannot be (a displaced cabinet pushed its filter into the wall behind it)."""
    if not scene.filter_model or not scene.filters:
        return []
    client = p.connect(p.DIRECT)
    try:
        names = {_static_body(b, client): b.name for b in scene.bodies}
        seated = {}
        for f in scene.filters:
            body = _filter_body(scene.filter_model, f.condition, scene.slots[f.slot].pose, client, ())
            names[body] = f"filter/{f.id}"
            seated[body] = slot_body(scene, f.slot)
        p.performCollisionDetection(physicsClientId=client)
        found = []
        for body, carrier in seated.items():
            into = {
                names[c[2]]
                for c in p.getContactPoints(bodyA=body, physicsClientId=client)
                if c[8] < -depth and c[2] in names and names[c[2]] != carrier
            }
            found += [f"{names[body]} in {other}" for other in sorted(into)]
        return found
    finally:
        p.disconnect(client)


def _fixed_markers(scene: Scene, world: World) -> None:
    """A visual-only body per marker on a static frame (a body, a slot or a target), where that
    frame is in ``scene`` (the physical world: displaced, when it is)."""
    frames = {b.name: b.pose for b in scene.bodies} | {n: s.pose for n, s in scene.slots.items()}
    frames |= {f"target/{t.name}": t.pose for t in scene.targets}
    for marker in scene.markers:
        if marker.frame in frames:
            world.markers[marker.id] = (_marker_body(marker, frames[marker.frame], scene, world.client), -1)


def _marker_body(marker: MarkerSpec, frame: Pose, scene: Scene, client: int) -> int:
    visual = marker_visual(marker, scene.marker_dictionary, client)
    return int(p.createMultiBody(0.0, -1, visual, list(frame.xyz), list(frame.quaternion), physicsClientId=client))
