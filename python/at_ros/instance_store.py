"""The AT server's instances on disk, so a restarted server carries on with the operator's setup.

A procedure refers to an instance by the id the server gave it (``cdra_filter:${cdra_at.id}``).
If the server process dies, those ids, the registrations the operator made and the waypoints
moved by hand must still mean the same after a restart, or the procedure cannot go on. So the
server (``caretaker at-server --state-file PATH``) writes them after every change and reads
them back when it starts.

Kept per instance: template, id, root pose, ``hide_waypoints``, registrations (frame, offset,
and the frame's pose when registered), waypoint overrides, and how far each trajectory got.
Not kept: plans. A plan belongs to the robot state and the world of its moment, and a restart
usually follows something that moved the robot; after a restart a trajectory is planned again
(execute without a plan is refused, saying so).

Each write replaces the file atomically (a sibling temporary file renamed over it), so a crash
mid-write leaves the previous state, never half a file.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from at_ros.instance import Registration, TemplateInstance
from at_ros.library import LibraryError, Template
from at_ros.robot_config import RobotConfig

__all__ = ["FORMAT_VERSION", "load_instances", "save_instances"]

FORMAT_VERSION = 1


def save_instances(path: Path, robot: RobotConfig, instances: dict[str, TemplateInstance]) -> None:
    """Write ``instances`` (of ``robot``'s server) to ``path``, replacing what was there."""
    document = {
        "format": FORMAT_VERSION,
        "robot": robot.robot_name,
        "instances": [_instance_to_json(instances[key]) for key in sorted(instances)],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    scratch = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    scratch.write_text(json.dumps(document, indent=1))
    os.replace(scratch, path)


def load_instances(path: Path, robot: RobotConfig, templates: dict[str, Template]) -> dict[str, TemplateInstance]:
    """The instances saved in ``path`` (none if it does not exist yet), keyed ``Type:id``.

    Raises:
        LibraryError: naming the file and the entry that cannot be restored (another robot's
            state, a template no longer in the library, a malformed entry).
    """
    if not path.exists():
        return {}
    try:
        document = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise LibraryError(path, "", f"cannot be read as AT server state: {exc}") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT_VERSION:
        raise LibraryError(path, "format", f"expected AT server state format {FORMAT_VERSION}")
    if document.get("robot") != robot.robot_name:
        raise LibraryError(path, "robot", f"state of robot {document.get('robot')!r}, but this server serves {robot.robot_name!r}")
    instances: dict[str, TemplateInstance] = {}
    for n, entry in enumerate(document.get("instances", [])):
        where = f"instances[{n}]"
        try:
            instance = _instance_from_json(entry, robot, templates, path, where)
        except LibraryError:
            raise
        except (KeyError, TypeError, ValueError) as exc:  # InstanceError too: a display object the template lost
            raise LibraryError(path, where, f"cannot be restored: {type(exc).__name__}: {exc}") from None
        instances[instance.key] = instance
    return instances


def _matrix(values: Any) -> np.ndarray:
    matrix = np.asarray(values, dtype=float).reshape(4, 4)
    if not np.all(np.isfinite(matrix)):
        raise ValueError("pose has non-finite values")
    return matrix


def _instance_to_json(instance: TemplateInstance) -> dict[str, Any]:
    return {
        "template": instance.template.name,
        "id": instance.id,
        "root_pose": instance.root_pose.tolist(),
        "hide_waypoints": instance.hide_waypoints,
        "current_trajectory": instance.current_trajectory,
        "registrations": {
            name: {"frame": r.frame, "offset": r.offset.tolist(), "frame_pose": r.frame_pose.tolist()}
            for name, r in instance.registrations.items()
        },
        "waypoint_overrides": [
            {"trajectory": trajectory, "end_effector_id": ee_id, "index": index, "origin": origin.tolist()}
            for (trajectory, ee_id, index), origin in instance.waypoint_overrides.items()
        ],
        "current_index": {name: p.current_index for name, p in instance.progress.items()},
    }


def _instance_from_json(entry: dict[str, Any], robot: RobotConfig, templates: dict[str, Template], path: Path, where: str) -> TemplateInstance:
    template = templates.get(entry["template"])
    if template is None:
        raise LibraryError(path, f"{where}.template", f"template {entry['template']!r} is not in the library (known: {', '.join(sorted(templates))})")
    instance = TemplateInstance(template, int(entry["id"]), robot, _matrix(entry["root_pose"]),
                                hide_waypoints=bool(entry["hide_waypoints"]), current_trajectory=str(entry["current_trajectory"]))
    for name, r in entry["registrations"].items():
        instance.register(name, Registration(str(r["frame"]), _matrix(r["offset"]), _matrix(r["frame_pose"])))
    for override in entry["waypoint_overrides"]:
        key = (str(override["trajectory"]), int(override["end_effector_id"]), int(override["index"]))
        instance.waypoint_overrides[key] = _matrix(override["origin"])
    for name, index in entry["current_index"].items():
        if name in instance.progress:
            instance.progress[name].current_index = int(index)
    return instance
