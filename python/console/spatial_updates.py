"""The 3D view's live updates: joints, objects, templates and plans, from rosbridge JSON.

The habitat publishes the arm's joint states, the named frames of the simulation and the AT
server's template statuses and plans; the ground server hands them here as rosbridge JSON and
sends the results to the browser (contract in ``spatial/README.md``). Every input is checked
(:mod:`console.spatial_values`); nothing here imports rclpy or the robot side.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from console import spatial_values as checked
from console.spatial_values import DISPLAY_OBJECT_COLOR, DOCUMENT_FRAME, Json, SpatialDataError, pose

__all__ = ["PlanSegment", "joints_update", "located_update", "objects_update", "plan_update", "templates_update"]

# ---------------------------------------------------------------------------------- updates


def joints_update(joint_state: Mapping[str, Any]) -> Json:
    """A ``joints`` update from rosbridge JSON of sensor_msgs/JointState."""
    msg = checked.mapping(joint_state, "joint_states")
    names = checked.names(checked.required(msg, "name", "joint_states"), "joint_states.name")
    values = checked.numbers(checked.required(msg, "position", "joint_states"), len(names), "joint_states.position")
    return {
        "kind": "joints",
        "stamp": checked.stamp(msg.get("header"), "joint_states.header"),
        "positions": dict(zip(names, values, strict=True)),
    }


def objects_update(named_poses: Mapping[str, Any]) -> Json:
    """An ``objects`` update from rosbridge JSON of caretaker_sim_msgs/NamedPoses (``/sim/frames``).

    It carries every named frame; the view moves the objects it has by those names
    (``filter/<id>``, ``target/<name>``) and ignores the rest (slots, tool, cameras).
    """
    msg = checked.mapping(named_poses, "frames")
    frame = checked.mapping(msg.get("header", {}), "frames.header").get("frame_id", DOCUMENT_FRAME) or DOCUMENT_FRAME
    if frame != DOCUMENT_FRAME:
        raise SpatialDataError(
            "frames.header.frame_id", f"poses are in {frame!r}; the view's document frame is {DOCUMENT_FRAME!r}"
        )
    names = checked.names(checked.required(msg, "names", "frames"), "frames.names")
    poses = checked.sequence(checked.required(msg, "poses", "frames"), "frames.poses")
    if len(poses) != len(names):
        raise SpatialDataError("frames.poses", f"{len(poses)} poses for {len(names)} names")
    return {
        "kind": "objects",
        "stamp": checked.stamp(msg.get("header"), "frames.header"),
        "poses": {
            n: checked.ros_pose(p, f"frames.poses[{i}]") for i, (n, p) in enumerate(zip(names, poses, strict=True))
        },
    }


def located_update(result: Mapping[str, Any], frame_poses: Mapping[str, Json]) -> Json:
    """A ``located`` update from rosbridge JSON of caretaker_perception_msgs/LocateResult
    (``perception/last_result``): where the habitat's camera found an object, in the document
    frame (the result's frame, a named frame of ``/sim/frames`` or the document frame, composed
    with the pose), or why it did not. The view proposes the display objects registered to that
    object there; only the operator's Accept or drag registers anything."""
    where = "located"
    msg = checked.mapping(result, where)
    success = msg.get("success")
    if not isinstance(success, bool):
        raise SpatialDataError(f"{where}.success", f"expected true or false, got {success!r}")
    located: Json = {
        "object": checked.text(checked.required(msg, "object", where), f"{where}.object"),
        "camera": checked.text(checked.required(msg, "camera", where), f"{where}.camera"),
        "success": success,
        "message": str(msg.get("message", "")),
        "stamp": checked.stamp(msg.get("header"), f"{where}.header"),
        "residual_px": checked.number(msg.get("residual_px", 0.0), f"{where}.residual_px"),
        "offset_mm": checked.number(msg.get("offset_mm", 0.0), f"{where}.offset_mm"),
        "offset_deg": checked.number(msg.get("offset_deg", 0.0), f"{where}.offset_deg"),
        "markers": [
            int(checked.number(m, f"{where}.markers[{i}]"))
            for i, m in enumerate(checked.sequence(msg.get("markers", []), f"{where}.markers"))
        ],
        "pose": None,
    }
    if success:
        frame = checked.mapping(msg.get("header", {}), f"{where}.header").get("frame_id", "") or DOCUMENT_FRAME
        base = pose() if frame == DOCUMENT_FRAME else frame_poses.get(frame)
        if base is None:
            raise SpatialDataError(
                f"{where}.header.frame_id", f"the pose is in {frame!r}, a frame the view was not given"
            )
        xyz = checked.numbers(checked.required(msg, "xyz", where), 3, f"{where}.xyz")
        quat = checked.numbers(checked.required(msg, "quaternion", where), 4, f"{where}.quaternion")
        norm = sum(q * q for q in quat) ** 0.5
        if norm < 1e-9:
            raise SpatialDataError(f"{where}.quaternion", "the quaternion is zero")
        located["pose"] = checked.compose(base, {"xyz": xyz, "quat": [q / norm for q in quat]})
    return {"kind": "located", "located": located}


def _display_shape(info: Mapping[str, Any], where: str) -> Json:
    """ObjectInfo's shape; cylinder and sphere sizes are marker scales (diameters, length)."""
    kind = checked.text(checked.required(info, "type", where), f"{where}.type")
    size_msg = checked.mapping(checked.required(info, "size", where), f"{where}.size")
    size = [checked.number(checked.required(size_msg, k, f"{where}.size"), f"{where}.size.{k}") for k in "xyz"]
    if kind not in ("box", "cylinder", "sphere", "mesh"):
        raise SpatialDataError(
            f"{where}.type", f"unknown display object type {kind!r}; expected box, cylinder, sphere or mesh"
        )
    shape: Json = {"type": kind, "size": size, "rgba": list(DISPLAY_OBJECT_COLOR)}
    if kind == "mesh":
        shape["mesh"] = checked.text(checked.required(info, "mesh_resource", where), f"{where}.mesh_resource")
    return shape


def _template(
    status: Mapping[str, Any],
    where: str,
    frames: Mapping[str, Json],
    waypoint_objects: Mapping[str, Sequence[str]],
    registrations: Mapping[tuple[str, str], str],
) -> Json:
    type_name = checked.text(checked.required(status, "type", where), f"{where}.type")
    instance_id = int(checked.number(checked.required(status, "id", where), f"{where}.id"))
    key = f"{type_name}:{instance_id}"
    trajectory = checked.text(checked.required(status, "trajectory_name", where), f"{where}.trajectory_name")
    display_objects = []
    for i, value in enumerate(checked.sequence(status.get("object_info", []), f"{where}.object_info")):
        w = f"{where}.object_info[{i}]"
        info = checked.mapping(value, w)
        frame_name = checked.text(checked.required(info, "object_name", w), f"{w}.object_name")
        stamped = checked.mapping(checked.required(info, "object_pose", w), f"{w}.object_pose")
        _in_document_frame(stamped, f"{w}.object_pose")
        name = frame_name.split(":")[0]
        registered_to = info.get("registered_to", "") or registrations.get((key, name)) or DOCUMENT_FRAME
        entry: Json = {
            "name": name,
            "frame": frame_name,
            "pose": checked.ros_pose(checked.required(stamped, "pose", f"{w}.object_pose"), f"{w}.object_pose.pose"),
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
    for g, value in enumerate(checked.sequence(status.get("waypoint_info", []), f"{where}.waypoint_info")):
        w = f"{where}.waypoint_info[{g}]"
        info = checked.mapping(value, w)
        ee_id = int(checked.number(checked.required(info, "id", w), f"{w}.id"))
        ee_name = str(info.get("end_effector_name", ""))
        index = max(index, int(checked.number(info.get("waypoint_index", -1), f"{w}.waypoint_index")))
        plan_valid = plan_valid or bool(info.get("plan_valid", False))
        poses = checked.sequence(info.get("waypoint_poses", []), f"{w}.waypoint_poses")
        pose_names = checked.sequence(info.get("end_effector_pose_names", []), f"{w}.end_effector_pose_names")
        compact = checked.sequence(info.get("compact_view", []), f"{w}.compact_view")
        objects = waypoint_objects.get(ee_name, ())
        for k, stamped in enumerate(poses):
            _in_document_frame(checked.mapping(stamped, f"{w}.waypoint_poses[{k}]"), f"{w}.waypoint_poses[{k}]")
            waypoints.append(
                {
                    "name": f"{ee_id}.{k}:{key}",
                    "ee_id": ee_id,
                    "ee_name": ee_name,
                    "index": k,
                    "trajectory": trajectory,
                    "pose": checked.ros_pose(
                        checked.required(stamped, "pose", f"{w}.waypoint_poses[{k}]"), f"{w}.waypoint_poses[{k}].pose"
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
    frame = checked.mapping(stamped.get("header", {}), f"{where}.header").get("frame_id", "")
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
    registrations: Mapping[tuple[str, str], str] | None = None,
) -> Json:
    """A ``templates`` update (every running template) from the AT server's statuses.

    ``statuses``: rosbridge JSON of AffordanceTemplateStatus, one per running instance, asked
    with ``frame_id: world``. An ObjectInfo may carry ``registered_to`` (the named frame its
    registration is relative to; proposed addition); else ``registrations`` may say it (by
    ``("Type:id", display object)``: the frames the run registered them to). A drag is then sent
    in that frame, whose pose comes from ``frames`` (``/sim/frames`` JSON), and a located frame
    proposes the display objects registered to it. ``configs``: get_templates'
    AffordanceTemplateConfig JSON by template type, which says which display object each
    waypoint is defined on (its waypoint poses' frame_id).
    """
    frame_poses = objects_update(frames)["poses"] if frames is not None else {}
    frame_poses[DOCUMENT_FRAME] = pose()
    templates = []
    for i, status in enumerate(checked.sequence(statuses, "statuses")):
        s = checked.mapping(status, f"statuses[{i}]")
        config = (configs or {}).get(str(s.get("type", "")))
        waypoint_objects = (
            _waypoint_objects(config, str(s.get("trajectory_name", "")), f"configs[{s.get('type')!r}]")
            if config
            else {}
        )
        templates.append(_template(s, f"statuses[{i}]", frame_poses, waypoint_objects, registrations or {}))
    return {"kind": "templates", "templates": templates}


def _waypoint_objects(config: Mapping[str, Any], trajectory: str, where: str) -> dict[str, list[str]]:
    """End-effector name -> display object of each waypoint of ``trajectory``."""
    out: dict[str, list[str]] = {}
    for t, value in enumerate(
        checked.sequence(checked.mapping(config, where).get("trajectory_info", []), f"{where}.trajectory_info")
    ):
        wt = checked.mapping(value, f"{where}.trajectory_info[{t}]")
        if wt.get("name") != trajectory:
            continue
        for g, info in enumerate(
            checked.sequence(wt.get("waypoint_info", []), f"{where}.trajectory_info[{t}].waypoint_info")
        ):
            w = f"{where}.trajectory_info[{t}].waypoint_info[{g}]"
            stamped = checked.sequence(checked.mapping(info, w).get("waypoint_poses", []), f"{w}.waypoint_poses")
            out[str(info.get("end_effector_name", ""))] = [
                str(checked.mapping(checked.mapping(p, w).get("header", {}), w).get("frame_id", "")) for p in stamped
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
    names = checked.names(joint_names, "plan.joint_names")
    start = checked.numbers(start_positions, len(names), "plan.start_positions")
    points: list[Json] = [{"positions": start, "time_from_start": 0.0}]
    waypoints = []
    for s, segment in enumerate(segments):
        where = f"plan.segments[{s}]"
        traj = checked.mapping(segment.trajectory, f"{where}.trajectory")
        seg_names = checked.names(traj.get("joint_names", []), f"{where}.trajectory.joint_names")
        order = []
        for name in seg_names:
            if name not in names:
                raise SpatialDataError(
                    f"{where}.trajectory.joint_names", f"unknown joint {name!r}; the plan's joints: {', '.join(names)}"
                )
            order.append(names.index(name))
        offset = points[-1]["time_from_start"]
        for k, value in enumerate(checked.sequence(traj.get("points", []), f"{where}.trajectory.points")):
            w = f"{where}.trajectory.points[{k}]"
            p = checked.mapping(value, w)
            positions = list(points[-1]["positions"])
            for j, v in zip(
                order,
                checked.numbers(checked.required(p, "positions", w), len(seg_names), f"{w}.positions"),
                strict=True,
            ):
                positions[j] = v
            t = offset + checked.duration(checked.required(p, "time_from_start", w), f"{w}.time_from_start")
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
                "name": checked.text(segment.label, f"{where}.label"),
                "point": len(points) - 1,
                "end_effector_pose": segment.end_effector_pose,
            }
        )
    return {
        "kind": "plan",
        "plan": {
            "instance": checked.text(instance, "plan.instance"),
            "trajectory": checked.text(trajectory, "plan.trajectory"),
            "joint_names": names,
            "points": points,
            "waypoints": waypoints,
            "tool_link": tool_link,
            "end_pose": checked.ros_pose(end_pose, "plan.end_pose") if end_pose is not None else None,
        },
    }
