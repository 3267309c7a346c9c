"""Adding an Affordance Template is adding a file: a running robot side can use it at once.

A template the AT server has never seen (a filter label check: stand off in front of a rack
filter, then back away) is written into the library folder of a running AT server; a procedure
that names it through the unchanged AT SysRep is linted and run autonomously right away.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from caretaker.processes import REPO, caretaker
from support.stack import robot_parts, write_deployment

pytestmark = [pytest.mark.ros, pytest.mark.slow]

LABEL_CHECK = {
    "name": "filter_label_check",
    "image": "package://at_ros/library/images/cdra_filter.png",
    "display_objects": [
        {
            "name": "filter",
            "shape": {
                "type": "box",
                "material": {"color": "blue", "rgba": [0.2, 0.3, 0.9, 0.5]},
                "size": [0.2, 0.14, 0.1],
            },
            "origin": {"xyz": [0, 0, 0], "rpy": [0, 0, 0]},
            "controls": {"xyz": [True, True, True], "rpy": [True, True, True], "scale": 0.3},
        }
    ],
    "end_effector_trajectory": [
        {
            "name": "look_at_label",
            "end_effector_group": [
                {
                    "id": 0,
                    "end_effector_waypoint": [
                        {
                            "ee_pose": 0,
                            "display_object": "filter",
                            "planner_type": "JOINT",
                            "origin": {"xyz": [-0.35, 0.0, 0.0], "rpy": [0.0, 1.570796, 0.0]},
                        },
                        {
                            "ee_pose": 0,
                            "display_object": "filter",
                            "planner_type": "CARTESIAN",
                            "origin": {"xyz": [-0.25, 0.0, 0.0], "rpy": [0.0, 1.570796, 0.0]},
                        },
                        {
                            "ee_pose": 0,
                            "display_object": "filter",
                            "planner_type": "CARTESIAN",
                            "origin": {"xyz": [-0.40, 0.0, 0.0], "rpy": [0.0, 1.570796, 0.0]},
                        },
                    ],
                }
            ],
        }
    ],
}

PROCEDURE = """<?xml version="1.0" encoding="UTF-8"?>
<procedure id="filter_label_check" title="Check the label of a rack filter" version="1.0">
  <uses system="affordance_templates"/>
  <step id="look" title="Look at the label of the filter in rack slot 2">
    <command system="affordance_templates" name="add_affordance_template" result="at">
      <arg name="affordance_template">filter_label_check</arg>
      <arg name="hide_waypoints">false</arg>
    </command>
    <command system="affordance_templates" name="set_display_object_pose">
      <arg name="affordance_template">filter_label_check:${at.id}</arg>
      <arg name="id">${at.id}</arg>
      <arg name="display_object">filter</arg>
      <arg name="frame">rack/slot_2</arg>
      <arg name="x">0</arg> <arg name="y">0</arg> <arg name="z">0</arg>
      <arg name="roll">0</arg> <arg name="pitch">0</arg> <arg name="yaw">0</arg>
    </command>
    <command system="affordance_templates" name="plan_trajectory">
      <arg name="affordance_template">filter_label_check:${at.id}</arg>
      <arg name="trajectory">look_at_label</arg>
    </command>
    <verify system="affordance_templates" telemetry="plan_valid" equals="true" timeout="15"/>
    <command system="affordance_templates" name="execute_plan">
      <arg name="affordance_template">filter_label_check:${at.id}</arg>
      <arg name="trajectory">look_at_label</arg>
    </command>
    <verify system="affordance_templates" telemetry="execute_status" equals="SUCCEEDED" timeout="15"/>
    <command system="affordance_templates" name="delete_affordance_template">
      <arg name="affordance_template">filter_label_check</arg>
      <arg name="id">${at.id}</arg>
    </command>
  </step>
</procedure>
"""


@pytest.fixture
def robot_side(tmp_path: Path, ros_env: dict[str, str]) -> Iterator[tuple[Path, str]]:
    """The IVA robot side serving a template library of the user's own (a copy of the shipped one)."""
    library = tmp_path / "library"
    shutil.copytree(REPO / "python" / "at_ros" / "library" / "templates", library / "templates")
    deployment = write_deployment(tmp_path, "iva", templates=str(library / "templates"))
    with robot_parts(deployment, ros_env) as stack:
        yield library, stack.bridge_url


def test_a_template_file_is_usable_from_a_procedure_at_once(
    robot_side: tuple[Path, str], tmp_path: Path, ros_env: dict[str, str]
) -> None:
    library, bridge_url = robot_side
    procedure = tmp_path / "filter_label_check.xml"
    procedure.write_text(PROCEDURE)
    (library / "templates" / "filter_label_check.json").write_text(json.dumps(LABEL_CHECK, indent=2))

    lint = caretaker("lint", str(procedure), env=ros_env, name="lint")
    lint.proc.wait(60)
    lint.stop()
    assert lint.proc.returncode == 0, lint.tail()

    db = f"sqlite:///{tmp_path / 'audit.db'}"
    run = caretaker(
        "run",
        str(procedure),
        "--binding",
        str(REPO / "sysrep" / "bindings" / "iva.yaml"),
        "--rosbridge",
        bridge_url,
        "--auto",
        "--rehearsal",
        "--user",
        "author",
        "--db",
        db,
        env=ros_env,
        name="run",
    )
    try:
        result = run.wait_for_line(r"^RESULT ", 300)
    finally:
        run.stop()
    assert result.startswith("RESULT completed"), run.tail()
    assert any("added filter_label_check:0" in line for line in run.output), run.tail()
