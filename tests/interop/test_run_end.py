"""A run that fails leaves no Affordance Template instance behind, on the real stack.

Before, a failed run left its instances running on the AT server, and with a deployment's state
folder the next ``caretaker up`` restored them: the next run's ``cdra_filter`` got id 1 or 2, not
0. Here an unattended ``caretaker run`` adds two templates and fails on a plan; its runner stops
it, and the stop deletes both through the AT SysRep (recorded as the runner's user). The AT
server's own list is then empty, and after the stack is brought up again from the same state
folder, the next run's template is ``cdra_filter:0``.
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlparse

import pytest
import roslibpy

from caretaker.processes import REPO, caretaker
from pride.events import Event, EventKind
from records.audit_log import AuditLog
from rosbridge.rosbridge_support import wait_until_discovered
from support.stack import stack_up, write_deployment

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=90)]

PROCEDURE = """<?xml version="1.0" encoding="UTF-8"?>
<procedure id="add_then_fail" title="Add the CDRA templates, then fail to plan" version="1.0">
  <uses system="affordance_templates"/>
  <step id="prepare" title="Add the templates">
    <verify system="affordance_templates" telemetry="affordance_template_server_active" equals="true" timeout="30"/>
    <command system="affordance_templates" name="add_affordance_template" result="cdra_at">
      <arg name="affordance_template">cdra_filter</arg>
      <arg name="hide_waypoints">false</arg>
    </command>
    <command system="affordance_templates" name="add_affordance_template" result="ready_at">
      <arg name="affordance_template">ready_pose</arg>
      <arg name="hide_waypoints">true</arg>
    </command>
    <command system="affordance_templates" name="plan_trajectory">
      <arg name="affordance_template">cdra_filter:${cdra_at.id}</arg>
      <arg name="trajectory">no_such_trajectory</arg>
    </command>
  </step>
</procedure>
"""
ADD_FILTER = "1.2"
AT = "/affordance_template_server"


def _run(procedure: Path, url: str, db: str, env: dict[str, str]) -> list[Event]:
    """Run ``procedure`` unattended to its end; its events."""
    runner = caretaker(
        "run",
        str(procedure),
        "--binding",
        str(REPO / "sysrep" / "bindings" / "iva.yaml"),
        "--rosbridge",
        url,
        "--auto",
        "--rehearsal",
        "--user",
        "ops",
        "--db",
        db,
        env=env,
        name="run",
    )
    try:
        result = runner.wait_for_line(r"^RESULT ", 300)
    finally:
        runner.stop()
    assert result.startswith("RESULT stopped"), runner.tail()
    assert not any(line.startswith("LEFT ") for line in runner.output), runner.tail()
    audit = AuditLog(db)
    try:
        return audit.events(result.split()[3])
    finally:
        audit.close()


def _running(url: str) -> list[str]:
    """The AT server's own list of instances (get_running), through rosbridge."""
    port = urlparse(url).port
    assert port
    wait_until_discovered("127.0.0.1", port, f"{AT}/status", f"{AT}/get_running", AT, timeout=60)
    ros = roslibpy.Ros(host="127.0.0.1", port=port)
    ros.run(30)
    try:
        service = roslibpy.Service(
            ros, f"{AT}/get_running", "affordance_template_msgs/srv/GetRunningAffordanceTemplates"
        )
        answer = service.call(roslibpy.ServiceRequest({}), timeout=30)
    finally:
        ros.close()
    assert answer["success"], answer
    return list(answer["templates"])


def _added(events: list[Event]) -> object:
    (result,) = [e for e in events if e.kind is EventKind.COMMAND_RESULT and e.instruction == ADD_FILTER]
    return result.data.to_json()["values"]["instance"]


def test_a_failed_run_leaves_no_instance_and_the_next_run_gets_id_0(tmp_path: Path, ros_env: dict[str, str]) -> None:
    procedure = tmp_path / "add_then_fail.xml"
    procedure.write_text(PROCEDURE)
    deployment = write_deployment(tmp_path, "iva", state_dir=str(tmp_path / "state"))
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    with stack_up(deployment, ros_env) as up:
        first = _run(procedure, up.url, db, ros_env)
        assert _running(up.url) == []
    failed = [e for e in first if e.kind is EventKind.INSTRUCTION_FAILED]
    assert [e.instruction for e in failed] == ["1.4"], failed
    assert _added(first) == "cdra_filter:0"
    taken = [e for e in first if e.kind is EventKind.COMMAND_RESULT and e.data.to_json().get("take_back")]
    assert [(e.actor, e.data.to_json()["take_back"], e.data.to_json()["success"]) for e in taken] == [
        ("ops", "cdra_filter:0", True),
        ("ops", "ready_pose:0", True),
    ]
    assert first[-1].kind is EventKind.RUN_STOPPED
    assert first[-1].data.to_json()["taken_back"] == ["cdra_filter:0", "ready_pose:0"]

    # the next stack restores what the state folder holds: nothing of the failed run
    with stack_up(deployment, ros_env) as up:
        assert _running(up.url) == []
        second = _run(procedure, up.url, db, ros_env)
    assert _added(second) == "cdra_filter:0"
