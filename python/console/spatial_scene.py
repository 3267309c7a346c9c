"""The 3D view's scene document: what the habitat is made of, as the view's JSON.

The browser's ``SpatialView`` (``spatial/``, contract in ``spatial/README.md``) builds itself
from data only. This module makes its scene document from what crosses the link as plain data
- a scene file's mapping, a URDF's text, and optionally the first ``/joint_states`` and
``/sim/frames`` - and :mod:`console.spatial_updates` makes the updates that follow it. It
imports neither rclpy nor the robot side, so the ground server can run it on what rosbridge
hands it, and tests on the shipped files.

Every input is hostile until checked: a malformed value raises :class:`SpatialDataError`
naming where it is (``scene.bodies[2].shapes[0].size``) and what was expected.

All poses are ``{"xyz": [x, y, z], "quat": [x, y, z, w]}`` in the document's ``frame``
(the world frame of the simulation, ``world``); roll-pitch-yaw in the scene files is fixed-axis
X, Y, Z as everywhere in Caretaker (R = Rz(yaw) Ry(pitch) Rx(roll)).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from console import spatial_values as checked
from console.spatial_updates import joints_update, objects_update
from console.spatial_values import CONTRACT_VERSION, DOCUMENT_FRAME, TARGET_RAISE, Json, SpatialDataError, pose

__all__ = ["scene_document"]

# ---------------------------------------------------------------------------- scene document


def _robot(scene: Mapping[str, Any], urdf: str, mesh_urls: Mapping[str, str]) -> Json:
    r = checked.mapping(checked.required(scene, "robot", "scene"), "scene.robot")
    arm_joints = checked.names(checked.required(r, "arm_joints", "scene.robot"), "scene.robot.arm_joints")
    initial = checked.numbers(
        checked.required(r, "initial_positions", "scene.robot"), len(arm_joints), "scene.robot.initial_positions"
    )
    positions = dict(zip(arm_joints, initial, strict=True))
    robot: Json = {
        "name": checked.text(checked.required(r, "name", "scene.robot"), "scene.robot.name"),
        "urdf": urdf,
        "mesh_urls": dict(mesh_urls),
        "base_link": checked.text(r.get("base_link", "base_link"), "scene.robot.base_link"),
        "tool_link": checked.text(checked.required(r, "tool_link", "scene.robot"), "scene.robot.tool_link"),
        "base_pose": checked.scene_pose(r.get("base"), "scene.robot.base"),
        "arm_joints": arm_joints,
        "end_effector_poses": {},
    }
    gripper = r.get("gripper")
    if gripper is not None:
        g = checked.mapping(gripper, "scene.robot.gripper")
        joints = checked.names(checked.required(g, "joints", "scene.robot.gripper"), "scene.robot.gripper.joints")
        named = checked.mapping(checked.required(g, "poses", "scene.robot.gripper"), "scene.robot.gripper.poses")
        robot["end_effector_poses"] = {
            str(name): dict(
                zip(joints, checked.numbers(values, len(joints), f"scene.robot.gripper.poses.{name}"), strict=True)
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
    for i, value in enumerate(checked.sequence(scene.get("bodies", []), "scene.bodies")):
        where = f"scene.bodies[{i}]"
        b = checked.mapping(value, where)
        rgba = checked.rgba(checked.required(b, "color", where), f"{where}.color")
        shapes = [
            checked.scene_shape(s, rgba, f"{where}.shapes[{k}]")
            for k, s in enumerate(checked.sequence(checked.required(b, "shapes", where), f"{where}.shapes"))
        ]
        out.append(
            {
                "name": checked.text(checked.required(b, "name", where), f"{where}.name"),
                "kind": "body",
                "pose": checked.scene_pose(b.get("pose"), f"{where}.pose"),
                "shapes": shapes,
            }
        )
    return out


def _slots(scene: Mapping[str, Any]) -> dict[str, Json]:
    slots = {}
    for i, value in enumerate(checked.sequence(scene.get("slots", []), "scene.slots")):
        s = checked.mapping(value, f"scene.slots[{i}]")
        slots[checked.text(checked.required(s, "name", f"scene.slots[{i}]"), f"scene.slots[{i}].name")] = (
            checked.scene_pose(checked.required(s, "pose", f"scene.slots[{i}]"), f"scene.slots[{i}].pose")
        )
    return slots


def _filters(scene: Mapping[str, Any], slots: Mapping[str, Json]) -> list[Json]:
    """Each filter as the simulation builds it: a body and, in front of it (-x), its handle."""
    if not scene.get("filters"):
        return []
    model = checked.mapping(checked.required(scene, "filter_model", "scene"), "scene.filter_model")
    body = checked.numbers(
        checked.required(model, "body_size", "scene.filter_model"), 3, "scene.filter_model.body_size"
    )
    handle = checked.numbers(
        checked.required(model, "handle_size", "scene.filter_model"), 3, "scene.filter_model.handle_size"
    )
    colors = checked.mapping(checked.required(model, "colors", "scene.filter_model"), "scene.filter_model.colors")
    out = []
    for i, value in enumerate(checked.sequence(scene["filters"], "scene.filters")):
        where = f"scene.filters[{i}]"
        f = checked.mapping(value, where)
        condition = checked.text(checked.required(f, "condition", where), f"{where}.condition")
        if condition not in colors:
            raise SpatialDataError(
                f"{where}.condition", f"no colour for {condition!r} in scene.filter_model.colors ({', '.join(colors)})"
            )
        slot = checked.text(checked.required(f, "slot", where), f"{where}.slot")
        if slot not in slots:
            raise SpatialDataError(f"{where}.slot", f"unknown slot {slot!r}; slots: {', '.join(slots)}")
        body_rgba = checked.rgba(colors[condition], f"scene.filter_model.colors.{condition}")
        handle_rgba = checked.rgba(colors.get("handle", body_rgba), "scene.filter_model.colors.handle")
        shapes = [
            checked.box(body, body_rgba),
            checked.box(handle, handle_rgba, pose((-(body[0] + handle[0]) / 2, 0.0, 0.0))),
        ]
        out.append(
            {
                "name": f"filter/{checked.text(checked.required(f, 'id', where), f'{where}.id')}",
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
    model = checked.mapping(checked.required(scene, "target_model", "scene"), "scene.target_model")
    panel = checked.numbers(
        checked.required(model, "panel_size", "scene.target_model"), 3, "scene.target_model.panel_size"
    )
    colors = checked.mapping(checked.required(model, "colors", "scene.target_model"), "scene.target_model.colors")
    radii = checked.mapping(model.get("mark_radius", {}), "scene.target_model.mark_radius")
    raise_by = TARGET_RAISE + panel[2] / 2
    out = []
    for i, value in enumerate(checked.sequence(scene["targets"], "scene.targets")):
        where = f"scene.targets[{i}]"
        t = checked.mapping(value, where)
        condition = checked.text(checked.required(t, "condition", where), f"{where}.condition")
        shapes = [
            checked.box(
                panel,
                checked.rgba(
                    checked.required(colors, "panel", "scene.target_model.colors"), "scene.target_model.colors.panel"
                ),
                pose((0, 0, raise_by)),
            )
        ]
        if condition != "clean":
            if condition not in radii or condition not in colors:
                raise SpatialDataError(
                    f"{where}.condition", f"no mark_radius/colour for {condition!r} in scene.target_model"
                )
            radius = checked.number(radii[condition], f"scene.target_model.mark_radius.{condition}")
            shapes.append(
                checked.cylinder(
                    radius,
                    0.004,
                    checked.rgba(colors[condition], f"scene.target_model.colors.{condition}"),
                    pose((0, 0, raise_by + panel[2] / 2 + 0.002)),
                )
            )
        name = checked.text(checked.required(t, "name", where), f"{where}.name")
        out.append(
            {
                "name": f"target/{name}",
                "kind": "target",
                "pose": checked.scene_pose(checked.required(t, "pose", where), f"{where}.pose"),
                "shapes": shapes,
            }
        )
    return out


def _cabinet_latch(scene: Mapping[str, Any], slots: Mapping[str, Json]) -> list[Json]:
    """The lock lamp beside the cabinet slot: red while locked, green when unlocked."""
    cabinet = scene.get("cabinet")
    if cabinet is None:
        return []
    c = checked.mapping(cabinet, "scene.cabinet")
    slot = checked.text(checked.required(c, "slot", "scene.cabinet"), "scene.cabinet.slot")
    if slot not in slots:
        raise SpatialDataError("scene.cabinet.slot", f"unknown slot {slot!r}; slots: {', '.join(slots)}")
    latch = checked.mapping(checked.required(c, "latch", "scene.cabinet"), "scene.cabinet.latch")
    rgba = [0.9, 0.1, 0.1, 1.0] if c.get("locked", False) else [0.1, 0.8, 0.2, 1.0]
    at = pose(checked.numbers(checked.required(latch, "xyz", "scene.cabinet.latch"), 3, "scene.cabinet.latch.xyz"))
    size = checked.numbers(checked.required(latch, "size", "scene.cabinet.latch"), 3, "scene.cabinet.latch.size")
    return [{"name": "cabinet/latch", "kind": "lamp", "pose": slots[slot], "shapes": [checked.box(size, rgba, at)]}]


def _viewpoint(scene: Mapping[str, Any]) -> Json | None:
    """The scene's fixed camera named ``scene`` (else the first fixed one): where the view starts."""
    fixed = []
    for i, value in enumerate(checked.sequence(scene.get("cameras", []), "scene.cameras")):
        c = checked.mapping(value, f"scene.cameras[{i}]")
        if "eye" in c and "target" in c:
            fixed.append((c.get("name") == "scene", i, c))
    if not fixed:
        return None
    _, i, c = max(fixed, key=lambda f: (f[0], -f[1]))
    return {
        "eye": checked.numbers(c["eye"], 3, f"scene.cameras[{i}].eye"),
        "target": checked.numbers(c["target"], 3, f"scene.cameras[{i}].target"),
        "fov_deg": checked.number(c.get("fov_deg", 50), f"scene.cameras[{i}].fov_deg"),
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
    scene = checked.mapping(scene, "scene")
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
        "name": checked.text(checked.required(scene, "name", "scene"), "scene.name"),
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
