"""No motion after a halt, whatever the order in which halt, execute and SetGripper arrive.

The robot side's real processes (simulation, planner, AT server, command ledger), each held at a
named point by the test-only delay hooks (ros_process/delay_hooks.py) while a halt comes in:

- the halt overtakes an ``execute_command`` the ledger took but has not forwarded yet;
- the halt comes while the AT server is about to send the trajectory goal;
- the halt crosses the AT server's ``SetGripper`` request on its way into the simulation.

The witness is the simulation's own log: it logs its halt and every arm trajectory and finger
motion it starts; after the halt, none may start.
"""

from __future__ import annotations

import json
import re
import threading
from collections.abc import Iterator
from typing import Any

import pytest
from at_client import AtClient
from caretaker_ledger_msgs.srv import ExecuteOnce

from caretaker.processes import ManagedProcess
from caretaker.stack import Stack
from ros_process.delay_hooks import ENVIRONMENT
from support.stack import robot_parts

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=40)]

#: s each hooked point holds: time enough for the test's halt to arrive in the gap, under load.
HOLD = 4
MOTION_STARTS = ("trajectory started", "gripper started")


@pytest.fixture(scope="module")
def robot(ros_env: dict[str, str]) -> Iterator[tuple[Stack, AtClient, int]]:
    """The robot side with every hook holding; a ready_pose instance registered on the robot base."""
    hooks = f"ledger.forward={HOLD},at_server.send_goal={HOLD},sim.gripper={HOLD}"
    env = dict(ros_env, **{ENVIRONMENT: hooks})
    with robot_parts("iva", env, parts=("sim", "planner", "at-server", "ledger")) as parts:
        at = AtClient()
        try:
            at.wait_for(lambda: at.status is not None and at.status.planner_node_active, 60, "an active planner")
            added = at.call("add_template", class_type="ready_pose")
            assert added.success and at.register("ready_pose", added.id, "robot_base", "robot_base").success
            yield parts, at, added.id
        finally:
            at.close()


def _plan(at: AtClient, instance: int) -> None:
    planned = at.call("plan_command", type="ready_pose", id=instance, trajectory_name="ready")
    assert planned.success, planned.message


def _in_background(call: Any) -> tuple[threading.Thread, dict[str, Any]]:
    answer: dict[str, Any] = {}
    worker = threading.Thread(target=lambda: answer.update(result=call()), daemon=True)
    worker.start()
    return worker, answer


def _halt(parts: Stack, at: AtClient, reason: str, held: str, printed: dict[str, int]) -> None:
    """Once process ``held`` says it holds, halt through the AT server; wait for the robot's halt line."""
    parts.processes[held].wait_for_line(r"test delay hook .*: holding", 120, after=printed[held])
    halted = at.call("halt", reason=reason)
    assert halted.success, halted.message
    parts.processes["sim"].wait_for_line(re.escape(f"]: halt ({reason})"), 30, after=printed["sim"])


def _printed(parts: Stack) -> dict[str, int]:
    return {name: process.printed for name, process in parts.processes.items()}


def _after_halt(sim: ManagedProcess, reason: str) -> list[str]:
    """What the robot logged after the halt for ``reason`` (its lines are kept: few were printed since)."""
    lines = sim.tail(400).splitlines()
    at_halt = max(i for i, line in enumerate(lines) if f"]: halt ({reason})" in line)
    return lines[at_halt + 1 :]


def _started(lines: list[str]) -> list[str]:
    return [line for line in lines if any(start in line for start in MOTION_STARTS)]


def test_a_halt_that_overtakes_an_execute_held_in_the_ledger_keeps_it_from_moving(
    robot: tuple[Stack, AtClient, int],
) -> None:
    parts, at, instance = robot
    reason = "test: halt before the ledger forwards"
    _plan(at, instance)
    printed = _printed(parts)
    client = at.node.create_client(ExecuteOnce, "/command_ledger/execute")
    request = ExecuteOnce.Request(
        command_key="halt-order/1.1/1",
        service="/affordance_template_server/execute_command",
        type="affordance_template_msgs/srv/AffordanceTemplateExecuteCommand",
        request_json=json.dumps({"type": "ready_pose", "id": instance, "trajectory_name": "ready"}),
        timeout=60.0,
    )
    worker, answer = _in_background(lambda: at._call(client, request, 120, "command_ledger/execute"))
    _halt(parts, at, reason, "ledger", printed)
    worker.join(120)
    executed = answer["result"]
    assert executed.state == "FAILED" and f"halted ({reason}) before executing" in executed.message, executed.message
    assert "nothing moved" in executed.message
    after = _after_halt(parts.processes["sim"], reason)
    assert not _started(after), f"a motion started after the halt: {after}"


def test_a_halt_while_the_at_server_sends_the_goal_keeps_the_goal_from_leaving(
    robot: tuple[Stack, AtClient, int],
) -> None:
    parts, at, instance = robot
    reason = "test: halt while the goal is sent"
    _plan(at, instance)
    printed = _printed(parts)
    worker, answer = _in_background(
        lambda: at.call("execute_command", type="ready_pose", id=instance, trajectory_name="ready")
    )
    _halt(parts, at, reason, "at-server", printed)
    worker.join(120)
    executed = answer["result"]
    assert not executed.success and f"halted ({reason})" in executed.message, executed.message
    after = _after_halt(parts.processes["sim"], reason)
    assert not _started(after), f"a motion started after the halt: {after}"


def test_a_halt_that_crosses_set_gripper_keeps_the_fingers_still(robot: tuple[Stack, AtClient, int]) -> None:
    parts, at, instance = robot
    reason = "test: halt crossing SetGripper"
    _plan(at, instance)
    printed = _printed(parts)
    worker, answer = _in_background(
        lambda: at.call("execute_command", type="ready_pose", id=instance, trajectory_name="ready")
    )
    # The arm's goal is held too, then moves; the halt goes in while the gripper request is held.
    _halt(parts, at, reason, "sim", printed)
    worker.join(120)
    executed = answer["result"]
    assert not executed.success and f"halted ({reason})" in executed.message, executed.message
    # the held gripper request comes out of its hook after the halt (the execute may answer first)
    parts.processes["sim"].wait_for_line(r"gripper refused: halted", 60, after=printed["sim"])
    after = _after_halt(parts.processes["sim"], reason)
    assert not _started(after), f"a motion started after the halt: {after}"
    assert any("gripper refused: halted" in line for line in after), after
