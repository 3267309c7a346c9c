"""The AT server's instances on disk, so a restarted server carries on with the operator's setup.

A procedure refers to an instance by the id the server gave it (``cdra_filter:${cdra_at.id}``).
If the server process dies, those ids, the registrations the operator made and the waypoints
moved by hand must still mean the same after a restart, or the procedure cannot go on. So the
server (``caretaker at-server --state-file PATH``) writes them after every change and reads
them back when it starts.

Kept per instance: template, id, root pose, ``hide_waypoints``, registrations (frame, offset,
and the frame's pose when registered), waypoint overrides, how far each trajectory got (written
after every waypoint executed) and how its last execution ended (``executions``: SUCCEEDED,
FAILED, HALTED with the message, or EXECUTING when the server stopped during it, read back as an
interrupted execution, so the next plan resumes after the last waypoint reached).
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

from at_ros.instance import ExecutionOutcome, InstanceError, Registration, TemplateInstance
from at_ros.library import LibraryError, Template
from at_ros.robot_config import RobotConfig
from datafile import Field, load_file

__all__ = ["FORMAT_VERSION", "load_instances", "save_instances"]

FORMAT_VERSION = 1
OUTCOMES = (ExecutionOutcome.EXECUTING, ExecutionOutcome.SUCCEEDED, ExecutionOutcome.FAILED, ExecutionOutcome.HALTED)


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
        LibraryError: ``file:line: key: problem`` naming the entry that cannot be restored
            (another robot's state, a template no longer in the library, a malformed entry).
    """
    if not path.exists():
        return {}
    root = load_file(path, error=LibraryError, json=True).mapping(required=("format", "robot", "instances"))
    if root["format"].integer() != FORMAT_VERSION:
        raise root["format"].fail(f"expected AT server state format {FORMAT_VERSION}")
    if root["robot"].text() != robot.robot_name:
        raise root["robot"].fail(
            f"state of robot {root['robot'].text()!r}, but this server serves {robot.robot_name!r}"
        )
    instances: dict[str, TemplateInstance] = {}
    for entry in root["instances"].sequence():
        try:
            instance = _instance_from_json(entry, robot, templates)
        except InstanceError as exc:  # a display object or trajectory the template lost
            raise entry.fail(f"cannot be restored: {exc}") from None
        instances[instance.key] = instance
    return instances


def _matrix(f: Field) -> np.ndarray:
    """A 4x4 pose written as four rows of four finite numbers."""
    return np.array([row.numbers(4) for row in f.sequence(min_items=4, max_items=4)])


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
        "executions": {
            name: {"outcome": p.outcome, "message": p.outcome_message}
            for name, p in instance.progress.items()
            if p.outcome
        },
    }


def _instance_from_json(entry: Field, robot: RobotConfig, templates: dict[str, Template]) -> TemplateInstance:
    entry.mapping(
        required=(
            "template",
            "id",
            "root_pose",
            "hide_waypoints",
            "current_trajectory",
            "registrations",
            "waypoint_overrides",
            "current_index",
        ),
        optional=("executions",),
    )
    name = entry["template"].text()
    template = templates.get(name)
    if template is None:
        raise entry["template"].fail(f"template {name!r} is not in the library (known: {', '.join(sorted(templates))})")
    instance = TemplateInstance(
        template,
        entry["id"].integer(min=0, max=255),
        robot,
        _matrix(entry["root_pose"]),
        hide_waypoints=entry["hide_waypoints"].boolean(),
        current_trajectory=entry["current_trajectory"].text(empty=True),
    )
    for object_name, r in entry["registrations"].entries():
        r.mapping(required=("frame", "offset", "frame_pose"))
        instance.register(object_name, Registration(r["frame"].text(), _matrix(r["offset"]), _matrix(r["frame_pose"])))
    for override in entry["waypoint_overrides"].sequence():
        override.mapping(required=("trajectory", "end_effector_id", "index", "origin"))
        key = (
            override["trajectory"].text(),
            override["end_effector_id"].integer(min=0, max=255),
            override["index"].integer(min=0, max=255),
        )
        instance.waypoint_overrides[key] = _matrix(override["origin"])
    for trajectory, index in entry["current_index"].entries():
        if trajectory in instance.progress:
            instance.progress[trajectory].current_index = index.integer(min=-1, max=255)
    executions = entry.get("executions")
    for trajectory, execution in executions.entries() if executions else []:
        execution.mapping(required=("outcome", "message"))
        outcome = execution["outcome"].text()
        if outcome not in OUTCOMES:
            raise execution["outcome"].fail(f"unknown outcome {outcome!r}; expected one of {', '.join(OUTCOMES)}")
        if trajectory in instance.progress:
            progress = instance.progress[trajectory]
            progress.outcome, progress.outcome_message = outcome, execution["message"].text(empty=True)
    return instance
