"""The 3D view's data: what the habitat knows, as the view's JSON scene document and updates.

The browser's ``SpatialView`` (``spatial/``, contract in ``spatial/README.md``) builds itself
from data only. This module is the one producer of that data: it turns what crosses the link as
plain data - a scene file's mapping, a URDF's text, rosbridge JSON of ``/joint_states``,
``/sim/frames`` and the AT server's template statuses and plans - into the contract's
documents. It imports neither rclpy nor the robot side, so the ground server can run it on what
rosbridge hands it, and tests on the shipped files.

Every input is hostile until checked: a malformed value raises :class:`SpatialDataError`
naming where it is (``scene.bodies[2].shapes[0].size``) and what was expected.

All poses are ``{"xyz": [x, y, z], "quat": [x, y, z, w]}`` in the document's ``frame``
(the world frame of the simulation, ``world``); roll-pitch-yaw in the scene files is fixed-axis
X, Y, Z as everywhere in Caretaker (R = Rz(yaw) Ry(pitch) Rx(roll)).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = [
    "CONTRACT_VERSION",
    "DOCUMENT_FRAME",
    "DISPLAY_OBJECT_COLOR",
    "PlanSegment",
    "SpatialDataError",
    "scene_document",
    "joints_update",
    "objects_update",
    "templates_update",
    "plan_update",
    "pose",
]

CONTRACT_VERSION = 1
DOCUMENT_FRAME = "world"
#: The paper's colours: display objects green, waypoints teal (the view draws both).
DISPLAY_OBJECT_COLOR = (0.2, 0.9, 0.3, 0.45)
#: A target panel floats this far off a curved hull (the simulation draws it so).
TARGET_RAISE = 0.015

Json = dict[str, Any]


class SpatialDataError(ValueError):
    """Input the view's data cannot be made from; ``where`` names the bad value."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(f"{where}: {message}")
        self.where = where


# --------------------------------------------------------------------------- checked reading


def _mapping(value: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise SpatialDataError(where, f"expected a mapping, got {type(value).__name__}")
    return value


def _list(value: Any, where: str) -> Sequence[Any]:
    if not isinstance(value, (list, tuple)):
        raise SpatialDataError(where, f"expected a list, got {type(value).__name__}")
    return value


def _required(data: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in data:
        raise SpatialDataError(f"{where}.{key}", "missing required key")
    return data[key]


def _str(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise SpatialDataError(where, f"expected a non-empty string, got {value!r}")
    return value


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpatialDataError(where, f"expected a finite number, got {value!r}")
    return float(value)


def _numbers(value: Any, n: int, where: str) -> list[float]:
    items = _list(value, where)
    if len(items) != n:
        raise SpatialDataError(where, f"expected {n} numbers, got {len(items)}")
    return [_number(v, f"{where}[{i}]") for i, v in enumerate(items)]


def _names(value: Any, where: str) -> list[str]:
    return [_str(v, f"{where}[{i}]") for i, v in enumerate(_list(value, where))]


# --------------------------------------------------------------------------------- poses


def _quat_from_rpy(roll: float, pitch: float, yaw: float) -> list[float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    ]


def pose(xyz: Sequence[float] = (0.0, 0.0, 0.0), rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> Json:
    """A contract pose from position and fixed-axis roll-pitch-yaw."""
    return {"xyz": [float(v) for v in xyz], "quat": _quat_from_rpy(*(float(v) for v in rpy))}


def _scene_pose(value: Any, where: str) -> Json:
    """``{xyz, rpy}`` of a scene file (both optional, zeros by default)."""
    if value is None:
        return pose()
    data = _mapping(value, where)
    xyz = _numbers(data.get("xyz", [0, 0, 0]), 3, f"{where}.xyz")
    rpy = _numbers(data.get("rpy", [0, 0, 0]), 3, f"{where}.rpy")
    return pose(xyz, rpy)


def _ros_pose(value: Any, where: str) -> Json:
    """geometry_msgs/Pose as rosbridge JSON; the quaternion is normalized (a zero one is an error)."""
    data = _mapping(value, where)
    position = _mapping(_required(data, "position", where), f"{where}.position")
    orientation = _mapping(_required(data, "orientation", where), f"{where}.orientation")
    xyz = [_number(_required(position, k, f"{where}.position"), f"{where}.position.{k}") for k in "xyz"]
    quat = [_number(_required(orientation, k, f"{where}.orientation"), f"{where}.orientation.{k}") for k in "xyzw"]
    norm = math.sqrt(sum(q * q for q in quat))
    if norm < 1e-9:
        raise SpatialDataError(f"{where}.orientation", "the quaternion is zero")
    return {"xyz": xyz, "quat": [q / norm for q in quat]}


def _rgba(value: Any, where: str) -> list[float]:
    rgba = _numbers(value, 4, where)
    if any(not 0.0 <= c <= 1.0 for c in rgba):
        raise SpatialDataError(where, f"colour components must be within 0..1, got {rgba}")
    return rgba


# --------------------------------------------------------------------------------- shapes


def _box(size: Sequence[float], rgba: Sequence[float], at: Json | None = None) -> Json:
    return {"type": "box", "size": list(size), "rgba": list(rgba), "pose": at or pose()}


def _cylinder(radius: float, length: float, rgba: Sequence[float], at: Json | None = None) -> Json:
    """A cylinder along its own z axis (URDF's and pybullet's convention)."""
    return {"type": "cylinder", "radius": radius, "length": length, "rgba": list(rgba), "pose": at or pose()}


def _scene_shape(value: Any, rgba: list[float], where: str) -> Json:
    data = _mapping(value, where)
    kind = _required(data, "type", where)
    at = pose(
        _numbers(data.get("xyz", [0, 0, 0]), 3, f"{where}.xyz"), _numbers(data.get("rpy", [0, 0, 0]), 3, f"{where}.rpy")
    )
    if kind == "box":
        size = _numbers(_required(data, "size", where), 3, f"{where}.size")
        if any(v <= 0 for v in size):
            raise SpatialDataError(f"{where}.size", f"sizes must be positive, got {size}")
        return _box(size, rgba, at)
    if kind == "cylinder":
        radius = _number(_required(data, "radius", where), f"{where}.radius")
        length = _number(_required(data, "length", where), f"{where}.length")
        if radius <= 0 or length <= 0:
            raise SpatialDataError(where, f"radius and length must be positive, got {radius}, {length}")
        return _cylinder(radius, length, rgba, at)
    raise SpatialDataError(f"{where}.type", f"unknown shape type {kind!r}; expected box or cylinder")


# ---------------------------------------------------------------------------- scene document


def _robot(scene: Mapping[str, Any], urdf: str, mesh_urls: Mapping[str, str]) -> Json:
    r = _mapping(_required(scene, "robot", "scene"), "scene.robot")
    arm_joints = _names(_required(r, "arm_joints", "scene.robot"), "scene.robot.arm_joints")
    initial = _numbers(
        _required(r, "initial_positions", "scene.robot"), len(arm_joints), "scene.robot.initial_positions"
    )
    positions = dict(zip(arm_joints, initial, strict=True))
    robot: Json = {
        "name": _str(_required(r, "name", "scene.robot"), "scene.robot.name"),
        "urdf": urdf,
        "mesh_urls": dict(mesh_urls),
        "base_link": _str(r.get("base_link", "base_link"), "scene.robot.base_link"),
        "tool_link": _str(_required(r, "tool_link", "scene.robot"), "scene.robot.tool_link"),
        "base_pose": _scene_pose(r.get("base"), "scene.robot.base"),
        "arm_joints": arm_joints,
        "end_effector_poses": {},
    }
    gripper = r.get("gripper")
    if gripper is not None:
        g = _mapping(gripper, "scene.robot.gripper")
        joints = _names(_required(g, "joints", "scene.robot.gripper"), "scene.robot.gripper.joints")
        named = _mapping(_required(g, "poses", "scene.robot.gripper"), "scene.robot.gripper.poses")
        robot["end_effector_poses"] = {
            str(name): dict(
                zip(joints, _numbers(values, len(joints), f"scene.robot.gripper.poses.{name}"), strict=True)
            )
            for name, values in named.items()
        }
        initial_pose = g.get("initial")
        if initial_pose is not None:
            if initial_pose not in robot["end_effector_poses"]:
                raise SpatialDataError(
                    "scene.robot.gripper.initial",
                    f"unknown pose {initial_pose!r}; poses: {', '.join(robot['end_effector_poses'])}",
                )
            positions.update(robot["end_effector_poses"][initial_pose])
    robot["initial_positions"] = positions
    return robot


def _bodies(scene: Mapping[str, Any]) -> list[Json]:
    out = []
    for i, value in enumerate(_list(scene.get("bodies", []), "scene.bodies")):
        where = f"scene.bodies[{i}]"
        b = _mapping(value, where)
        rgba = _rgba(_required(b, "color", where), f"{where}.color")
        shapes = [
            _scene_shape(s, rgba, f"{where}.shapes[{k}]")
            for k, s in enumerate(_list(_required(b, "shapes", where), f"{where}.shapes"))
        ]
        out.append(
            {
                "name": _str(_required(b, "name", where), f"{where}.name"),
                "kind": "body",
                "pose": _scene_pose(b.get("pose"), f"{where}.pose"),
                "shapes": shapes,
            }
        )
    return out


def _slots(scene: Mapping[str, Any]) -> dict[str, Json]:
    slots = {}
    for i, value in enumerate(_list(scene.get("slots", []), "scene.slots")):
        s = _mapping(value, f"scene.slots[{i}]")
        slots[_str(_required(s, "name", f"scene.slots[{i}]"), f"scene.slots[{i}].name")] = _scene_pose(
            _required(s, "pose", f"scene.slots[{i}]"), f"scene.slots[{i}].pose"
        )
    return slots


def _filters(scene: Mapping[str, Any], slots: Mapping[str, Json]) -> list[Json]:
    """Each filter as the simulation builds it: a body and, in front of it (-x), its handle."""
    if not scene.get("filters"):
        return []
    model = _mapping(_required(scene, "filter_model", "scene"), "scene.filter_model")
    body = _numbers(_required(model, "body_size", "scene.filter_model"), 3, "scene.filter_model.body_size")
    handle = _numbers(_required(model, "handle_size", "scene.filter_model"), 3, "scene.filter_model.handle_size")
    colors = _mapping(_required(model, "colors", "scene.filter_model"), "scene.filter_model.colors")
    out = []
    for i, value in enumerate(_list(scene["filters"], "scene.filters")):
        where = f"scene.filters[{i}]"
        f = _mapping(value, where)
        condition = _str(_required(f, "condition", where), f"{where}.condition")
        if condition not in colors:
            raise SpatialDataError(
                f"{where}.condition", f"no colour for {condition!r} in scene.filter_model.colors ({', '.join(colors)})"
            )
        slot = _str(_required(f, "slot", where), f"{where}.slot")
        if slot not in slots:
            raise SpatialDataError(f"{where}.slot", f"unknown slot {slot!r}; slots: {', '.join(slots)}")
        body_rgba = _rgba(colors[condition], f"scene.filter_model.colors.{condition}")
        handle_rgba = _rgba(colors.get("handle", body_rgba), "scene.filter_model.colors.handle")
        shapes = [_box(body, body_rgba), _box(handle, handle_rgba, pose((-(body[0] + handle[0]) / 2, 0.0, 0.0)))]
        out.append(
            {
                "name": f"filter/{_str(_required(f, 'id', where), f'{where}.id')}",
                "kind": "filter",
                "pose": slots[slot],
                "shapes": shapes,
            }
        )
    return out


def _targets(scene: Mapping[str, Any]) -> list[Json]:
    """Inspection panels (z = hull normal) with their damage mark, as the simulation draws them."""
    if not scene.get("targets"):
        return []
    model = _mapping(_required(scene, "target_model", "scene"), "scene.target_model")
    panel = _numbers(_required(model, "panel_size", "scene.target_model"), 3, "scene.target_model.panel_size")
    colors = _mapping(_required(model, "colors", "scene.target_model"), "scene.target_model.colors")
    radii = _mapping(model.get("mark_radius", {}), "scene.target_model.mark_radius")
    raise_by = TARGET_RAISE + panel[2] / 2
    out = []
    for i, value in enumerate(_list(scene["targets"], "scene.targets")):
        where = f"scene.targets[{i}]"
        t = _mapping(value, where)
        condition = _str(_required(t, "condition", where), f"{where}.condition")
        shapes = [
            _box(
                panel,
                _rgba(_required(colors, "panel", "scene.target_model.colors"), "scene.target_model.colors.panel"),
                pose((0, 0, raise_by)),
            )
        ]
        if condition != "clean":
            if condition not in radii or condition not in colors:
                raise SpatialDataError(
                    f"{where}.condition", f"no mark_radius/colour for {condition!r} in scene.target_model"
                )
            radius = _number(radii[condition], f"scene.target_model.mark_radius.{condition}")
            shapes.append(
                _cylinder(
                    radius,
                    0.004,
                    _rgba(colors[condition], f"scene.target_model.colors.{condition}"),
                    pose((0, 0, raise_by + panel[2] / 2 + 0.002)),
                )
            )
        name = _str(_required(t, "name", where), f"{where}.name")
        out.append(
            {
                "name": f"target/{name}",
                "kind": "target",
                "pose": _scene_pose(_required(t, "pose", where), f"{where}.pose"),
                "shapes": shapes,
            }
        )
    return out


def _cabinet_latch(scene: Mapping[str, Any], slots: Mapping[str, Json]) -> list[Json]:
    """The lock lamp beside the cabinet slot: red while locked, green when unlocked."""
    cabinet = scene.get("cabinet")
    if cabinet is None:
        return []
    c = _mapping(cabinet, "scene.cabinet")
    slot = _str(_required(c, "slot", "scene.cabinet"), "scene.cabinet.slot")
    if slot not in slots:
        raise SpatialDataError("scene.cabinet.slot", f"unknown slot {slot!r}; slots: {', '.join(slots)}")
    latch = _mapping(_required(c, "latch", "scene.cabinet"), "scene.cabinet.latch")
    rgba = [0.9, 0.1, 0.1, 1.0] if c.get("locked", False) else [0.1, 0.8, 0.2, 1.0]
    at = pose(_numbers(_required(latch, "xyz", "scene.cabinet.latch"), 3, "scene.cabinet.latch.xyz"))
    size = _numbers(_required(latch, "size", "scene.cabinet.latch"), 3, "scene.cabinet.latch.size")
    return [{"name": "cabinet/latch", "kind": "lamp", "pose": slots[slot], "shapes": [_box(size, rgba, at)]}]


def _viewpoint(scene: Mapping[str, Any]) -> Json | None:
    """The scene's fixed camera named ``scene`` (else the first fixed one): where the view starts."""
    fixed = []
    for i, value in enumerate(_list(scene.get("cameras", []), "scene.cameras")):
        c = _mapping(value, f"scene.cameras[{i}]")
        if "eye" in c and "target" in c:
            fixed.append((c.get("name") == "scene", i, c))
    if not fixed:
        return None
    _, i, c = max(fixed, key=lambda f: (f[0], -f[1]))
    return {
        "eye": _numbers(c["eye"], 3, f"scene.cameras[{i}].eye"),
        "target": _numbers(c["target"], 3, f"scene.cameras[{i}].target"),
        "fov_deg": _number(c.get("fov_deg", 50), f"scene.cameras[{i}].fov_deg"),
    }


def scene_document(
    scene: Mapping[str, Any],
    urdf: str,
    *,
    frames: Mapping[str, Any] | None = None,
    joints: Mapping[str, Any] | None = None,
    mesh_urls: Mapping[str, str] | None = None,
    camera_url: str | None = None,
) -> Json:
    """The view's scene document from a scene file's mapping and the robot's URDF text.

    ``frames`` (rosbridge JSON of ``/sim/frames``) and ``joints`` (of ``/joint_states``), when
    given, place moving objects and the arm where the habitat says they are now rather than
    where the scene file starts them. ``mesh_urls`` maps URDF mesh URIs (``package://...``) to
    URLs the browser can fetch.
    """
    scene = _mapping(scene, "scene")
    if not isinstance(urdf, str) or "<robot" not in urdf:
        raise SpatialDataError("urdf", "expected the text of a URDF file (no <robot> element found)")
    slots = _slots(scene)
    objects = _bodies(scene) + _filters(scene, slots) + _targets(scene) + _cabinet_latch(scene, slots)
    seen: set[str] = set()
    for obj in objects:
        if obj["name"] in seen:
            raise SpatialDataError("scene", f"two objects are named {obj['name']!r}")
        seen.add(obj["name"])
    robot = _robot(scene, urdf, mesh_urls or {})
    document: Json = {
        "contract": CONTRACT_VERSION,
        "kind": "scene",
        "frame": DOCUMENT_FRAME,
        "name": _str(_required(scene, "name", "scene"), "scene.name"),
        "robot": robot,
        "joints": {"stamp": 0.0, "positions": dict(robot.pop("initial_positions"))},
        "objects": objects,
        "templates": [],
        "plan": None,
        "camera": {"url": camera_url},
        "viewpoint": _viewpoint(scene),
    }
    if frames is not None:
        moved = objects_update(frames)["poses"]
        for obj in objects:
            if obj["name"] in moved:
                obj["pose"] = moved[obj["name"]]
    if joints is not None:
        document["joints"] = {k: v for k, v in joints_update(joints).items() if k != "kind"}
    return document


# ---------------------------------------------------------------------------------- updates


def _stamp(header: Any, where: str) -> float:
    if header is None:
        return 0.0
    stamp = _mapping(_mapping(header, where).get("stamp", {}), f"{where}.stamp")
    return (
        _number(stamp.get("sec", 0), f"{where}.stamp.sec")
        + _number(stamp.get("nanosec", 0), f"{where}.stamp.nanosec") * 1e-9
    )


def joints_update(joint_state: Mapping[str, Any]) -> Json:
    """A ``joints`` update from rosbridge JSON of sensor_msgs/JointState."""
    msg = _mapping(joint_state, "joint_states")
    names = _names(_required(msg, "name", "joint_states"), "joint_states.name")
    values = _numbers(_required(msg, "position", "joint_states"), len(names), "joint_states.position")
    return {
        "kind": "joints",
        "stamp": _stamp(msg.get("header"), "joint_states.header"),
        "positions": dict(zip(names, values, strict=True)),
    }


def objects_update(named_poses: Mapping[str, Any]) -> Json:
    """An ``objects`` update from rosbridge JSON of caretaker_sim_msgs/NamedPoses (``/sim/frames``).

    It carries every named frame; the view moves the objects it has by those names
    (``filter/<id>``, ``target/<name>``) and ignores the rest (slots, tool, cameras).
    """
    msg = _mapping(named_poses, "frames")
    frame = _mapping(msg.get("header", {}), "frames.header").get("frame_id", DOCUMENT_FRAME) or DOCUMENT_FRAME
    if frame != DOCUMENT_FRAME:
        raise SpatialDataError(
            "frames.header.frame_id", f"poses are in {frame!r}; the view's document frame is {DOCUMENT_FRAME!r}"
        )
    names = _names(_required(msg, "names", "frames"), "frames.names")
    poses = _list(_required(msg, "poses", "frames"), "frames.poses")
    if len(poses) != len(names):
        raise SpatialDataError("frames.poses", f"{len(poses)} poses for {len(names)} names")
    return {
        "kind": "objects",
        "stamp": _stamp(msg.get("header"), "frames.header"),
        "poses": {n: _ros_pose(p, f"frames.poses[{i}]") for i, (n, p) in enumerate(zip(names, poses, strict=True))},
    }


def _display_shape(info: Mapping[str, Any], where: str) -> Json:
    """ObjectInfo's shape; cylinder and sphere sizes are marker scales (diameters, length)."""
    kind = _str(_required(info, "type", where), f"{where}.type")
    size_msg = _mapping(_required(info, "size", where), f"{where}.size")
    size = [_number(_required(size_msg, k, f"{where}.size"), f"{where}.size.{k}") for k in "xyz"]
    if kind not in ("box", "cylinder", "sphere", "mesh"):
        raise SpatialDataError(
            f"{where}.type", f"unknown display object type {kind!r}; expected box, cylinder, sphere or mesh"
        )
    shape: Json = {"type": kind, "size": size, "rgba": list(DISPLAY_OBJECT_COLOR)}
    if kind == "mesh":
        shape["mesh"] = _str(_required(info, "mesh_resource", where), f"{where}.mesh_resource")
    return shape


def _template(
    status: Mapping[str, Any], where: str, frames: Mapping[str, Json], waypoint_objects: Mapping[str, Sequence[str]]
) -> Json:
    type_name = _str(_required(status, "type", where), f"{where}.type")
    instance_id = int(_number(_required(status, "id", where), f"{where}.id"))
    key = f"{type_name}:{instance_id}"
    trajectory = _str(_required(status, "trajectory_name", where), f"{where}.trajectory_name")
    display_objects = []
    for i, value in enumerate(_list(status.get("object_info", []), f"{where}.object_info")):
        w = f"{where}.object_info[{i}]"
        info = _mapping(value, w)
        frame_name = _str(_required(info, "object_name", w), f"{w}.object_name")
        stamped = _mapping(_required(info, "object_pose", w), f"{w}.object_pose")
        _in_document_frame(stamped, f"{w}.object_pose")
        registered_to = info.get("registered_to", "") or DOCUMENT_FRAME
        entry: Json = {
            "name": frame_name.split(":")[0],
            "frame": frame_name,
            "pose": _ros_pose(_required(stamped, "pose", f"{w}.object_pose"), f"{w}.object_pose.pose"),
            "shape": _display_shape(info, w),
            "parent_frame": {"name": registered_to, "pose": frames.get(registered_to)},
        }
        if entry["parent_frame"]["pose"] is None:
            entry["movable"] = False
            entry["reason"] = f"registered to frame {registered_to!r}, whose pose the view was not given"
        display_objects.append(entry)
    waypoints = []
    index = -1
    plan_valid = False
    for g, value in enumerate(_list(status.get("waypoint_info", []), f"{where}.waypoint_info")):
        w = f"{where}.waypoint_info[{g}]"
        info = _mapping(value, w)
        ee_id = int(_number(_required(info, "id", w), f"{w}.id"))
        ee_name = str(info.get("end_effector_name", ""))
        index = max(index, int(_number(info.get("waypoint_index", -1), f"{w}.waypoint_index")))
        plan_valid = plan_valid or bool(info.get("plan_valid", False))
        poses = _list(info.get("waypoint_poses", []), f"{w}.waypoint_poses")
        pose_names = _list(info.get("end_effector_pose_names", []), f"{w}.end_effector_pose_names")
        compact = _list(info.get("compact_view", []), f"{w}.compact_view")
        objects = waypoint_objects.get(ee_name, ())
        for k, stamped in enumerate(poses):
            _in_document_frame(_mapping(stamped, f"{w}.waypoint_poses[{k}]"), f"{w}.waypoint_poses[{k}]")
            waypoints.append(
                {
                    "name": f"{ee_id}.{k}:{key}",
                    "ee_id": ee_id,
                    "ee_name": ee_name,
                    "index": k,
                    "trajectory": trajectory,
                    "pose": _ros_pose(
                        _required(stamped, "pose", f"{w}.waypoint_poses[{k}]"), f"{w}.waypoint_poses[{k}].pose"
                    ),
                    "end_effector_pose": str(pose_names[k]) if k < len(pose_names) else "",
                    "display_object": objects[k] if k < len(objects) else "",
                    "compact": bool(compact[k]) if k < len(compact) else False,
                }
            )
    return {
        "key": key,
        "type": type_name,
        "id": instance_id,
        "trajectory": trajectory,
        "waypoint_index": index,
        "plan_valid": plan_valid,
        "display_objects": display_objects,
        "waypoints": waypoints,
    }


def _in_document_frame(stamped: Mapping[str, Any], where: str) -> None:
    frame = _mapping(stamped.get("header", {}), f"{where}.header").get("frame_id", "")
    if frame != DOCUMENT_FRAME:
        raise SpatialDataError(
            f"{where}.header.frame_id",
            f"poses must be in {DOCUMENT_FRAME!r} (ask get_template_status with frame_id {DOCUMENT_FRAME!r}), "
            f"got {frame!r}",
        )


def templates_update(
    statuses: Sequence[Mapping[str, Any]],
    *,
    frames: Mapping[str, Any] | None = None,
    configs: Mapping[str, Mapping[str, Any]] | None = None,
) -> Json:
    """A ``templates`` update (every running template) from the AT server's statuses.

    ``statuses``: rosbridge JSON of AffordanceTemplateStatus, one per running instance, asked
    with ``frame_id: world``. An ObjectInfo may carry ``registered_to`` (the named frame its
    registration is relative to; proposed addition) - a drag is then sent in that frame, whose
    pose comes from ``frames`` (``/sim/frames`` JSON). ``configs``: get_templates'
    AffordanceTemplateConfig JSON by template type, which says which display object each
    waypoint is defined on (its waypoint poses' frame_id).
    """
    frame_poses = objects_update(frames)["poses"] if frames is not None else {}
    frame_poses[DOCUMENT_FRAME] = pose()
    templates = []
    for i, status in enumerate(_list(statuses, "statuses")):
        s = _mapping(status, f"statuses[{i}]")
        config = (configs or {}).get(str(s.get("type", "")))
        waypoint_objects = (
            _waypoint_objects(config, str(s.get("trajectory_name", "")), f"configs[{s.get('type')!r}]")
            if config
            else {}
        )
        templates.append(_template(s, f"statuses[{i}]", frame_poses, waypoint_objects))
    return {"kind": "templates", "templates": templates}


def _waypoint_objects(config: Mapping[str, Any], trajectory: str, where: str) -> dict[str, list[str]]:
    """End-effector name -> display object of each waypoint of ``trajectory``."""
    out: dict[str, list[str]] = {}
    for t, value in enumerate(_list(_mapping(config, where).get("trajectory_info", []), f"{where}.trajectory_info")):
        wt = _mapping(value, f"{where}.trajectory_info[{t}]")
        if wt.get("name") != trajectory:
            continue
        for g, info in enumerate(_list(wt.get("waypoint_info", []), f"{where}.trajectory_info[{t}].waypoint_info")):
            w = f"{where}.trajectory_info[{t}].waypoint_info[{g}]"
            stamped = _list(_mapping(info, w).get("waypoint_poses", []), f"{w}.waypoint_poses")
            out[str(info.get("end_effector_name", ""))] = [
                str(_mapping(_mapping(p, w).get("header", {}), w).get("frame_id", "")) for p in stamped
            ]
    return out


# ------------------------------------------------------------------------------------- plan


@dataclass(frozen=True)
class PlanSegment:
    """One waypoint's part of a plan: the arm motion to it, then the end-effector pose to take.

    ``trajectory`` is rosbridge JSON of trajectory_msgs/JointTrajectory (the AT server's
    PlannedSegment.arm_trajectory), times from the start of this segment.
    """

    label: str  # the waypoint's name "<ee>.<wp>:<Type>:<id>"
    trajectory: Mapping[str, Any]
    end_effector_pose: str = ""


def _duration(value: Any, where: str) -> float:
    d = _mapping(value, where)
    return _number(d.get("sec", 0), f"{where}.sec") + _number(d.get("nanosec", 0), f"{where}.nanosec") * 1e-9


def plan_update(
    *,
    instance: str,
    trajectory: str,
    joint_names: Sequence[str],
    start_positions: Sequence[float],
    segments: Sequence[PlanSegment],
    end_pose: Mapping[str, Any] | None = None,
    tool_link: str = "",
) -> Json:
    """A ``plan`` update: the segments joined into one timed joint path from the start state.

    Each waypoint's ``point`` is the index of the path point where the arm reaches it (a
    segment without arm motion, such as closing the gripper, reaches its waypoint where the
    previous one ended). ``end_pose`` is the tool link's pose at the end, rosbridge JSON of a
    geometry_msgs/Pose in the document frame.
    """
    names = _names(joint_names, "plan.joint_names")
    start = _numbers(start_positions, len(names), "plan.start_positions")
    points: list[Json] = [{"positions": start, "time_from_start": 0.0}]
    waypoints = []
    for s, segment in enumerate(segments):
        where = f"plan.segments[{s}]"
        traj = _mapping(segment.trajectory, f"{where}.trajectory")
        seg_names = _names(traj.get("joint_names", []), f"{where}.trajectory.joint_names")
        order = []
        for name in seg_names:
            if name not in names:
                raise SpatialDataError(
                    f"{where}.trajectory.joint_names", f"unknown joint {name!r}; the plan's joints: {', '.join(names)}"
                )
            order.append(names.index(name))
        offset = points[-1]["time_from_start"]
        for k, value in enumerate(_list(traj.get("points", []), f"{where}.trajectory.points")):
            w = f"{where}.trajectory.points[{k}]"
            p = _mapping(value, w)
            positions = list(points[-1]["positions"])
            for j, v in zip(
                order, _numbers(_required(p, "positions", w), len(seg_names), f"{w}.positions"), strict=True
            ):
                positions[j] = v
            t = offset + _duration(_required(p, "time_from_start", w), f"{w}.time_from_start")
            if t < points[-1]["time_from_start"] or (
                t == points[-1]["time_from_start"] and positions != points[-1]["positions"]
            ):
                raise SpatialDataError(
                    f"{w}.time_from_start",
                    f"time {t:.3f} s does not increase (previous point at {points[-1]['time_from_start']:.3f} s)",
                )
            if t > points[-1]["time_from_start"]:
                points.append({"positions": positions, "time_from_start": t})
        waypoints.append(
            {
                "name": _str(segment.label, f"{where}.label"),
                "point": len(points) - 1,
                "end_effector_pose": segment.end_effector_pose,
            }
        )
    return {
        "kind": "plan",
        "plan": {
            "instance": _str(instance, "plan.instance"),
            "trajectory": _str(trajectory, "plan.trajectory"),
            "joint_names": names,
            "points": points,
            "waypoints": waypoints,
            "tool_link": tool_link,
            "end_pose": _ros_pose(end_pose, "plan.end_pose") if end_pose is not None else None,
        },
    }
