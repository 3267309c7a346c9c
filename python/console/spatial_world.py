"""The 3D view's data from what the habitat publishes over rosbridge (not from its files).

:mod:`console.spatial_scene` builds the contract from a scene file and a URDF on disk; the
ground has neither, it has the habitat's latched ``sim/visual_world`` (every drawn object with
its shapes and colours, the robot's root pose, joints, tool link) and ``robot_description``,
and the AT server's ``get_plan``. This module turns those rosbridge JSON messages into the same
contract (``spatial/README.md``), with the same checks and errors (:class:`SpatialDataError`
naming the bad value's place). Templates and joint/object updates are :mod:`console.spatial_updates`'s.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping
from typing import Any

from console import spatial_values as checked
from console.spatial_updates import joints_update, objects_update
from console.spatial_values import CONTRACT_VERSION, DOCUMENT_FRAME, SpatialDataError

__all__ = ["PLAN_SHOWN_STATES", "world_document", "plan_from_get_plan", "compose"]

Json = dict[str, Any]

PLAN_SHOWN_STATES = frozenset({"PLANNED", "EXECUTING"})
"""A plan is drawn as the ghost before it runs, and while it runs as the path the arm has been told
to follow (``commanded``: on a long link the arm drawn is where it was a light time ago, the path
where it is going); once executed, halted, failed or invalidated it goes (the live arm shows what
happened)."""

_KINDS = {"filter/": "filter", "target/": "target", "cabinet/lamp": "lamp"}


def _rgba(value: Any, where: str) -> list[float]:
    rgba = checked.numbers(value, 4, where)
    return rgba if any(rgba) else [0.6, 0.6, 0.6, 1.0]  # an unset colour (all zero) would be invisible


def _shape(value: Any, where: str) -> Json:
    s = checked.mapping(value, where)
    kind = checked.text(checked.required(s, "type", where), f"{where}.type")
    at = checked.ros_pose(s.get("pose", {}), f"{where}.pose")
    rgba = _rgba(s.get("rgba", [0, 0, 0, 0]), f"{where}.rgba")
    if kind == "box":
        return {
            "type": "box",
            "size": checked.numbers(checked.required(s, "size", where), 3, f"{where}.size"),
            "rgba": rgba,
            "pose": at,
        }
    if kind == "cylinder":
        return {
            "type": "cylinder",
            "radius": checked.number(checked.required(s, "radius", where), f"{where}.radius"),
            "length": checked.number(checked.required(s, "length", where), f"{where}.length"),
            "rgba": rgba,
            "pose": at,
        }
    raise SpatialDataError(f"{where}.type", f"unknown shape {kind!r}; expected box or cylinder")


def _objects(world: Mapping[str, Any]) -> list[Json]:
    out: list[Json] = []
    seen: set[str] = set()
    for i, value in enumerate(checked.sequence(world.get("objects", []), "visual_world.objects")):
        where = f"visual_world.objects[{i}]"
        o = checked.mapping(value, where)
        name = checked.text(checked.required(o, "name", where), f"{where}.name")
        if name in seen:
            raise SpatialDataError(f"{where}.name", f"two objects are named {name!r}")
        seen.add(name)
        kind = next((k for prefix, k in _KINDS.items() if name.startswith(prefix)), "body")
        shapes = [
            _shape(s, f"{where}.shapes[{k}]")
            for k, s in enumerate(checked.sequence(o.get("shapes", []), f"{where}.shapes"))
        ]
        out.append(
            {"name": name, "kind": kind, "pose": checked.ros_pose(o.get("pose", {}), f"{where}.pose"), "shapes": shapes}
        )
    return out


def world_document(
    visual_world: Mapping[str, Any],
    urdf: str,
    *,
    frames: Mapping[str, Any] | None = None,
    joints: Mapping[str, Any] | None = None,
    camera_url: str | None = None,
) -> Json:
    """The view's scene document from ``sim/visual_world`` and ``robot_description`` JSON.

    ``frames`` (``sim/frames``) and ``joints`` (``joint_states``) place what moves where it is
    now. The shipped robots are primitives; a URDF naming mesh files gets no ``mesh_urls``
    (the ground does not serve the habitat's files), so such meshes are left out, not fetched.
    """
    world = checked.mapping(visual_world, "visual_world")
    if not isinstance(urdf, str) or "<robot" not in urdf:
        raise SpatialDataError("robot_description.data", "expected the text of a URDF (no <robot> element found)")
    arm_joints = checked.names(checked.required(world, "arm_joints", "visual_world"), "visual_world.arm_joints")
    gripper_joints = checked.names(world.get("gripper_joints", []), "visual_world.gripper_joints")
    objects = _objects(world)
    document: Json = {
        "contract": CONTRACT_VERSION,
        "kind": "scene",
        "frame": DOCUMENT_FRAME,
        "name": checked.text(world.get("scene", ""), "visual_world.scene") or "scene",
        "robot": {
            "name": checked.text(checked.required(world, "robot_name", "visual_world"), "visual_world.robot_name"),
            "urdf": urdf,
            "mesh_urls": {},
            "base_link": _urdf_root(urdf),
            "tool_link": checked.text(checked.required(world, "tool_link", "visual_world"), "visual_world.tool_link"),
            "base_pose": checked.ros_pose(
                checked.required(world, "robot_base", "visual_world"), "visual_world.robot_base"
            ),
            "arm_joints": arm_joints,
            "end_effector_poses": {},
        },
        "joints": {"stamp": 0.0, "positions": {name: 0.0 for name in arm_joints + gripper_joints}},
        "objects": objects,
        "templates": [],
        "plan": None,
        "camera": {"url": camera_url},
        "viewpoint": None,
    }
    if frames is not None:
        moved = objects_update(frames)["poses"]
        for obj in objects:
            if obj["name"] in moved:
                obj["pose"] = moved[obj["name"]]
        if "robot_base" in moved:
            document["robot"]["base_pose"] = moved["robot_base"]
    if joints is not None:
        document["joints"] = {k: v for k, v in joints_update(joints).items() if k != "kind"}
    return document


def _urdf_root(urdf: str) -> str:
    """The URDF's root link: the one link that is no joint's child (what the base pose places)."""
    try:
        robot = ElementTree.fromstring(urdf)
    except ElementTree.ParseError as exc:
        raise SpatialDataError("robot_description.data", f"the URDF is not XML: {exc}") from None
    links = [link.get("name", "") for link in robot.findall("link")]
    children = {child.get("link", "") for child in robot.findall("joint/child")}
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise SpatialDataError("robot_description.data", f"expected one root link, found {roots or 'none'}")
    return roots[0]


# ------------------------------------------------------------------------------------- plan


def compose(a: Json, b: Json) -> Json:
    """The pose ``b`` (given in the frame whose pose is ``a``) in ``a``'s frame."""
    ax, ay, az, aw = a["quat"]
    bx, by, bz, bw = b["quat"]
    # rotate b's translation by a's quaternion: v' = v + 2w(q x v) + 2 q x (q x v)
    vx, vy, vz = b["xyz"]
    tx, ty, tz = 2 * (ay * vz - az * vy), 2 * (az * vx - ax * vz), 2 * (ax * vy - ay * vx)
    rx = vx + aw * tx + (ay * tz - az * ty)
    ry = vy + aw * ty + (az * tx - ax * tz)
    rz = vz + aw * tz + (ax * ty - ay * tx)
    return {
        "xyz": [a["xyz"][0] + rx, a["xyz"][1] + ry, a["xyz"][2] + rz],
        "quat": [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
    }


def plan_from_get_plan(
    answer: Mapping[str, Any],
    *,
    instance: str,
    frames: Mapping[str, Json],
    sent: tuple[str, str] | None = None,
) -> Json:
    """A ``plan`` update from a ``get_plan`` answer: the ghost while the plan is PLANNED, the
    commanded path (``commanded: true``) while EXECUTING, ``plan: null`` otherwise (executed,
    halted, failed, invalidated, none).

    ``sent``: the (instance, trajectory) whose motion command the run sent and has no answer
    for yet. That plan is the commanded path whatever state the habitat reported: across the
    light time a short motion is EXECUTED there before the ground has drawn it, and the arm
    drawn (a light time old) is still following that path.

    ``frames``: named poses in the document frame (``sim/frames``); the end pose, given in the
    robot's frame (``robot_base``), is placed in the document frame with them.
    """
    a = checked.mapping(answer, "get_plan")
    is_sent = sent is not None and sent == (instance, a.get("trajectory_name"))
    if not a.get("success") or (a.get("state") not in PLAN_SHOWN_STATES and not is_sent):
        return {"kind": "plan", "plan": None}
    traj = checked.mapping(checked.required(a, "trajectory", "get_plan"), "get_plan.trajectory")
    names = checked.names(
        checked.required(traj, "joint_names", "get_plan.trajectory"), "get_plan.trajectory.joint_names"
    )
    points: list[Json] = []
    for k, value in enumerate(
        checked.sequence(checked.required(traj, "points", "get_plan.trajectory"), "get_plan.trajectory.points")
    ):
        w = f"get_plan.trajectory.points[{k}]"
        p = checked.mapping(value, w)
        t = checked.duration(checked.required(p, "time_from_start", w), f"{w}.time_from_start")
        if points and t < points[-1]["time_from_start"]:
            raise SpatialDataError(
                f"{w}.time_from_start",
                f"time {t:.3f} s goes back (previous point at {points[-1]['time_from_start']:.3f} s)",
            )
        points.append(
            {
                "positions": checked.numbers(checked.required(p, "positions", w), len(names), f"{w}.positions"),
                "time_from_start": t,
            }
        )
    if not points:
        raise SpatialDataError("get_plan.trajectory.points", "a PLANNED plan without points")
    labels = checked.names(a.get("waypoint_names", []), "get_plan.waypoint_names")
    indices = checked.sequence(a.get("waypoint_point_index", []), "get_plan.waypoint_point_index")
    ee_poses = checked.sequence(a.get("end_effector_poses", []), "get_plan.end_effector_poses")
    if len(indices) != len(labels):
        raise SpatialDataError("get_plan.waypoint_point_index", f"{len(indices)} indices for {len(labels)} waypoints")
    waypoints = []
    for i, (label, index) in enumerate(zip(labels, indices, strict=True)):
        point = int(checked.number(index, f"get_plan.waypoint_point_index[{i}]"))
        if not 0 <= point < len(points):
            raise SpatialDataError(
                f"get_plan.waypoint_point_index[{i}]", f"point {point} of a plan of {len(points)} points"
            )
        waypoints.append(
            {"name": label, "point": point, "end_effector_pose": str(ee_poses[i]) if i < len(ee_poses) else ""}
        )
    end_pose = None
    stamped = a.get("end_pose")
    if isinstance(stamped, dict) and stamped.get("pose") is not None:
        frame = (
            checked.mapping(stamped.get("header", {}), "get_plan.end_pose.header").get("frame_id", "") or DOCUMENT_FRAME
        )
        local = checked.ros_pose(stamped["pose"], "get_plan.end_pose.pose")
        if frame == DOCUMENT_FRAME:
            end_pose = local
        elif frame in frames:
            end_pose = compose(frames[frame], local)
        else:
            raise SpatialDataError(
                "get_plan.end_pose.header.frame_id", f"frame {frame!r} is not among sim/frames' names"
            )
    return {
        "kind": "plan",
        "plan": {
            "instance": instance,
            "trajectory": checked.text(a.get("trajectory_name", ""), "get_plan.trajectory_name"),
            "joint_names": names,
            "points": points,
            "waypoints": waypoints,
            "tool_link": checked.text(a.get("end_pose_link", ""), "get_plan.end_pose_link"),
            "end_pose": end_pose,
            "commanded": a.get("state") == "EXECUTING" or is_sent,
        },
    }
