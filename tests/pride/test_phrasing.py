"""How instructions read: the <text> element (schema, parser, lint), sentences from SysRep labels, values.

Procedures are written into a temporary directory and loaded by the real parser and lint against
the shipped SysReps.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from console.authoring import check_document, read_document
from pride.event_words import describe_event
from pride.events import Event, EventKind
from pride.phrasing import (
    Wording,
    command_text,
    fill_text,
    format_value,
    labelled_values,
    phrase,
    raw_form,
    template_json,
)
from procedure_language.lint import lint_file
from procedure_language.parser import load_procedure, parse_procedure
from procedure_language.sysrep import load_sysrep_dir

REPO = Path(__file__).resolve().parents[2]
SYSREPS = load_sysrep_dir(REPO / "sysrep")

PROCEDURE = """<?xml version="1.0" encoding="UTF-8"?>
<procedure id="phrases" title="Phrases" version="1">
  <uses system="affordance_templates"/>
  <uses system="cdra"/>
  <step id="one" title="One">
    <command system="affordance_templates" name="add_affordance_template" result="at">
      <text>Add the filter AT</text>
      <arg name="affordance_template">cdra_filter</arg>
      <arg name="hide_waypoints">false</arg>
    </command>
    <record name="frame" type="string">Which frame?</record>
    <command system="affordance_templates" name="set_display_object_pose">
      <arg name="affordance_template">cdra_filter:${at.id}</arg>
      <arg name="id">${at.id}</arg>
      <arg name="display_object">cdra_filter</arg>
      <arg name="frame">${frame}</arg>
      <arg name="x">0.35</arg> <arg name="y">0</arg> <arg name="z">1</arg>
      <arg name="roll">0</arg> <arg name="pitch">0</arg> <arg name="yaw">0</arg>
    </command>
    <command system="affordance_templates" name="plan_trajectory">
      <text>
        Plan the pull of cdra_filter:${at.id}
        out of ${frame}
      </text>
      <arg name="affordance_template">cdra_filter:${at.id}</arg>
      <arg name="trajectory">grasp_and_pull</arg>
    </command>
    <command system="affordance_templates" name="execute_plan">
      <arg name="affordance_template">cdra_filter:${at.id}</arg>
      <arg name="trajectory">grasp_and_pull</arg>
    </command>
    <verify system="cdra" telemetry="filter_locked" equals="false" timeout="5"/>
    <wait seconds="2.5"/>
    <wait system="affordance_templates" telemetry="plan_valid" equals="true" timeout="9">
      <text>Wait for a plan</text></wait>
    <if input="frame" equals="cabinet/slot" goto="two" else="one"/>
  </step>
  <step id="two" title="Two">
    <command system="cdra" name="lock_filter"/>
    <goto step="one"/>
  </step>
</procedure>
"""


@pytest.fixture
def procedure_file(tmp_path: Path) -> Path:
    path = tmp_path / "phrases.xml"
    path.write_text(PROCEDURE)
    return path


def test_sentences_are_the_authors_text_or_made_from_the_sysreps_labels(procedure_file: Path) -> None:
    assert lint_file(procedure_file, SYSREPS) == []
    procedure = load_procedure(procedure_file)
    said = {i.number: str(phrase(i, SYSREPS, procedure)) for i in procedure.instructions}
    assert said == {
        "1.1": "Add the filter AT",
        "1.2": "Which frame?",
        "1.3": 'Set Display Object Pose "cdra_filter" for cdra_filter:${at.id} '
        "(id: ${at.id}, frame: ${frame}, position (350, 0, 1000) mm, orientation 0°)",
        "1.4": "Plan the pull of cdra_filter:${at.id} out of ${frame}",  # written across lines, read as one
        "1.5": "Execute Plan for cdra_filter:${at.id} (trajectory: grasp_and_pull)",
        "1.6": "Verify Filter Locked is false",
        "1.7": "Wait 2.5 s",
        "1.8": "Wait for a plan",
        "1.9": "If the recorded frame is cabinet/slot, go to step 2 (Two), otherwise to step 1 (One)",
        "2.1": "Lock Filter",
        "2.2": "Go to step 1 (One)",
    }
    plan = procedure.instruction("1.4")
    assert template_json(phrase(plan, SYSREPS, procedure)) == [
        {"text": "Plan the pull of cdra_filter:"},
        {"ref": "at.id"},
        {"text": " out of "},
        {"ref": "frame"},
    ]
    assert (
        raw_form(plan)
        == "affordance_templates.plan_trajectory(affordance_template=cdra_filter:${at.id}, trajectory=grasp_and_pull)"
    )
    assert raw_form(procedure.instruction("1.6")) == "verify cdra.filter_locked = false (timeout 5 s)"
    written = next(n for n, line in enumerate(PROCEDURE.splitlines(), 1) if "Plan the pull" in line) - 1
    assert plan.at("text").line == written  # lint and the Author page point at the <text> element


def test_a_text_naming_a_value_not_known_there_or_given_twice_is_an_error(tmp_path: Path) -> None:
    unbound = tmp_path / "unbound.xml"
    unbound.write_text(PROCEDURE.replace("<text>Add the filter AT</text>", "<text>Add the AT for ${frame}</text>"))
    problems = [str(p) for p in lint_file(unbound, SYSREPS)]
    assert problems == [f"{unbound}:7:13: unbound variable 'frame': not recorded or returned before 1.1 on every path"]

    twice = tmp_path / "twice.xml"
    twice.write_text(
        PROCEDURE.replace(
            '<command system="cdra" name="lock_filter"/>',
            '<command system="cdra" name="lock_filter" text="Lock it"><text>Lock it</text></command>',
        )
    )
    procedure, problems = parse_procedure(twice)
    assert procedure is None and [p.message for p in problems] == [
        "the text is given twice: keep the text attribute or the <text> element"
    ]

    misplaced = tmp_path / "misplaced.xml"  # the schema wants it first, before the arguments
    misplaced.write_text(
        PROCEDURE.replace("<text>Add the filter AT</text>\n", "").replace(
            '<arg name="hide_waypoints">false</arg>', '<arg name="hide_waypoints">false</arg><text>late</text>'
        )
    )
    procedure, problems = parse_procedure(misplaced)
    assert procedure is None and "text" in problems[0].message


def test_the_author_page_keeps_the_text_when_it_opens_and_saves(procedure_file: Path) -> None:
    document = read_document(procedure_file)
    assert document["steps"][0]["items"][0]["text"] == "Add the filter AT"
    assert "text" not in document["steps"][0]["items"][2]  # generated, not written
    checked = check_document(document, procedure_file.parent, SYSREPS)
    assert checked["problems"] == []
    assert "<text>Add the filter AT</text>" in checked["xml"]
    assert checked["xml"].count("<text>") == 3


@pytest.mark.parametrize(
    ("value", "units", "name", "shown"),
    [
        (0.3500000000000001, None, "", "0.35"),
        (1.0 / 3.0, None, "", "0.3333"),  # 4 significant digits
        (12345.678, "s", "", "12346 s"),
        (0.000123, None, "", "0.0001"),  # never more than 4 decimals
        (-3.397308328442832e-10, None, "", "-3.4e-10"),
        (-0.0, None, "", "0"),
        (1.0 / 3.0, "m", "", "333 mm"),  # lengths in millimetres
        (0.0045, None, "x", "4.5 mm"),  # x/y/z are metres (REP 103) when the SysRep gives no units
        (-0.0000001, None, "z", "0 mm"),
        (1.5707959999869179, None, "pitch", "90°"),  # angles in degrees
        (0.2181661564992912, "rad", "", "12.5°"),
        (
            [0.14999985294229648, 0.45000000000002405, 0.30000000000000004, -3.4e-10, 1.570795999647377, 1.5707959],
            None,
            "end_pose",
            "position (150, 450, 300) mm, orientation (0, 90, 90)°",
        ),
        ([0.0, 0.0, 0.0, 0.0, 0.0, 0.0], None, "start_pose", "position 0 mm, orientation 0°"),
        ([0.1, -1.5707963, 3.14159265], None, "joint_positions", "(5.7, -90, 180)°"),  # joints in degrees
        (True, None, "", "true"),
        (False, "m", "", "false"),
        (12, "s", "", "12 s"),
        (7, None, "id", "7"),
        ("SUCCEEDED", None, "", "SUCCEEDED"),
        ([0.62, -0.18, 0.95000001], None, "", "(0.62, -0.18, 0.95)"),
        (None, "m", "", "—"),
        ({"plan_valid": True, "x": 0.25}, None, "", "plan valid true, x 250 mm"),
        (0.6552, None, "offset_mm", "0.7"),  # already millimetres (the sentence says "mm"): to 0.1 mm
        (12.3456, "mm", "", "12 mm"),
        (1.23456, None, "offset_deg", "1.2"),  # already degrees: to 0.1°
        (0.04, "deg", "", "0°"),
    ],
)
def test_values_read_rounded_with_units_and_never_as_reprs(
    value: object, units: str | None, name: str, shown: str
) -> None:
    assert format_value(value, units, name=name) == shown


def test_results_are_labelled_from_the_sysrep_and_audit_records_read_as_words() -> None:
    at = SYSREPS["affordance_templates"]
    assert labelled_values({"plan_status": "PLANNED", "plan_valid": True, "end_pose": [0.5, 0.25]}, at) == [
        ("Plan Status", "PLANNED"),
        ("Plan Valid", "true"),
        ("end pose", "(0.5, 0.25)"),
    ]
    pose = [0.45, 0.35, 0.3500000000000001, 8.49327084130506e-10, 1.5707959999869179, 0.7853980011248014]
    assert labelled_values({"end_pose": pose, "end_pose_frame": "robot_base"}, at) == [
        ("end pose", "position (450, 350, 350) mm, orientation (0, 90, 45)° in robot_base")  # one line, its frame
    ]
    # a located pose: its orientation in degrees, not again as a quaternion
    located = {"x": 0.5, "roll": 0.0, "pitch": 0.0, "yaw": 0.0001, "qx": 0.0, "qy": 0.0, "qz": 8.9e-05, "qw": 1.0}
    assert [label for label, _ in labelled_values(located)] == ["x", "roll", "pitch", "yaw"]
    assert labelled_values({"qx": 8.9e-05}) == [("qx", "8.9e-05")]  # without an angle to say it, it stays
    seen = Event(
        "r",
        3,
        EventKind.TELEMETRY_SEEN,
        "PAX",
        "1.9",
        {"system": "affordance_templates", "item": "execute_status", "value": "SUCCEEDED", "ok": True},
    )
    assert describe_event(seen, Wording(SYSREPS)) == "saw Execution Status = SUCCEEDED ✓"  # the SysRep's label
    assert describe_event(seen) == "saw Execute Status = SUCCEEDED ✓"  # no SysRep at hand: the id as a label
    result = Event(
        "r",
        4,
        EventKind.COMMAND_RESULT,
        "alice",
        "1.3",
        {"success": True, "message": "planned", "values": {"x": 0.30000000000000004, "ok": False}},
    )
    assert describe_event(result) == "succeeded: planned · x 300 mm, ok false"


def test_a_sent_command_reads_as_its_instruction_with_the_values_sent_and_its_call_only_when_raw(
    procedure_file: Path,
) -> None:
    procedure = load_procedure(procedure_file)
    env = {"at": {"id": 0, "instance": "cdra_filter:0"}, "frame": "cabinet/slot"}
    sent_args = {  # as the audit log keeps them: sorted by name, the literals typed
        "affordance_template": "cdra_filter:0",
        "display_object": "cdra_filter",
        "frame": "cabinet/slot",
        "id": 0,
        "pitch": 0.0,
        "roll": 0.0,
        "x": 0.35000000000000003,
        "y": 0.0,
        "yaw": 0.0,
        "z": 1.0,
    }
    shown = fill_text(str(phrase(procedure.instruction("1.3"), SYSREPS, procedure)), env)
    said = command_text("affordance_templates", "set_display_object_pose", sent_args, SYSREPS)
    expected = (
        'Set Display Object Pose "cdra_filter" for cdra_filter:0 '
        "(id: 0, frame: cabinet/slot, position (350, 0, 1000) mm, orientation 0°)"
    )
    assert said == shown == expected
    sent = Event(
        "r",
        5,
        EventKind.COMMAND_SENT,
        "PAX",
        "1.3",
        {"system": "affordance_templates", "command": "set_display_object_pose", "args": sent_args, "resend": True},
    )
    assert describe_event(sent, Wording(SYSREPS)) == f"sent again {said}"
    raw = describe_event(sent, Wording(SYSREPS, raw=True))
    assert raw.startswith(f"sent again {said} · raw: affordance_templates.set_display_object_pose(")
    assert "x=0.35000000000000003" in raw and "frame=cabinet/slot" in raw  # the call, values in full
    assert fill_text(
        "as located (${seen.offset_mm} mm, ${seen.offset_deg}°)", {"seen": {"offset_mm": 0.6552, "offset_deg": 0.04}}
    ) == (
        "as located (0.7 mm, 0°)"  # each value by what its name says it measures
    )
    assert fill_text("Remove cdra_filter:${at.id} from ${frame}", {"frame": "rack/slot_3"}) == (
        "Remove cdra_filter:‹at id: not known yet› from rack/slot_3"
    )
