"""How instructions read: the <text> element (schema, parser, lint), sentences from SysRep labels, values.

Procedures are written into a temporary directory and loaded by the real parser and lint against
the shipped SysReps.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from console.authoring import check_document, read_document
from pride.events import Event, EventKind
from pride.lint import lint_file
from pride.parser import load_procedure, parse_procedure
from pride.phrasing import describe_event, format_value, labelled_values, phrase, raw_form, template_json
from pride.sysrep import load_sysrep_dir

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
        "(id: ${at.id}, frame: ${frame}, position (0.35, 0, 1), orientation (0, 0, 0))",
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
    ("value", "units", "shown"),
    [
        (0.3500000000000001, None, "0.35"),
        (1.0 / 3.0, "m", "0.333 m"),
        (-0.0001, None, "-1.00e-04"),
        (-0.0, None, "0"),
        (True, None, "true"),
        (False, "m", "false"),
        (12, "s", "12 s"),
        ("SUCCEEDED", None, "SUCCEEDED"),
        ([0.62, -0.18, 0.95000001], None, "(0.62, -0.18, 0.95)"),
        (None, "m", "—"),
        ({"plan_valid": True}, None, "plan valid true"),
    ],
)
def test_values_read_rounded_with_units_and_never_as_reprs(value: object, units: str | None, shown: str) -> None:
    assert format_value(value, units) == shown


def test_results_are_labelled_from_the_sysrep_and_audit_records_read_as_words() -> None:
    at = SYSREPS["affordance_templates"]
    assert labelled_values({"plan_status": "PLANNED", "plan_valid": True, "end_pose": [0.5, 0.25]}, at) == [
        ("Plan Status", "PLANNED"),
        ("Plan Valid", "true"),
        ("end pose", "(0.5, 0.25)"),
    ]
    seen = Event(
        "r",
        3,
        EventKind.TELEMETRY_SEEN,
        "PAX",
        "1.9",
        {"system": "affordance_templates", "item": "execute_status", "value": "SUCCEEDED", "ok": True},
    )
    assert describe_event(seen) == "saw affordance_templates.execute_status = SUCCEEDED ✓"
    result = Event(
        "r",
        4,
        EventKind.COMMAND_RESULT,
        "alice",
        "1.3",
        {"success": True, "message": "planned", "values": {"x": 0.30000000000000004, "ok": False}},
    )
    assert describe_event(result) == "succeeded: planned · x 0.3, ok false"
