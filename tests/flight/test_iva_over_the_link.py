"""The IVA procedure flown autonomously from a ground host to a habitat host across the Gateway link.

Habitat: ``caretaker up`` (simulation, planner, AT server, command ledger, rosbridge on wss://
with a secret). Link: 1.3 s each way (issue 15, "Done when"). Ground: ``caretaker run --auto``
with a binding that states the link, so every command goes through the habitat's ledger.

What the arm did is counted on the habitat (trajectory goals the simulation's controller carried
out, and the ledger's own records), never from the ground's log; the ground's audit log must
match it, command for command, with no false success. Scenarios share runs to keep the suite
short: each run flies the whole procedure and meets its faults at the pull-out of the dirty
filter and later executions.
"""

from __future__ import annotations

from datetime import UTC, datetime

import pytest

from pride.events import Event, EventKind

from .flight_support import PULL_OUT, Flight, commands, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow]

DELAY = 1.3
#: Arm trajectory goals of one run of the IVA procedure: one per planned waypoint segment that
#: moves the arm, over the six executions. If the templates change, a clean run shows the new
#: number (every goal SUCCEEDED once).
IVA_ARM_GOALS = 14
#: Commands of one run (adds, poses, plans, executes, unlock, lock, deletes) and its executions.
IVA_COMMANDS = 23
IVA_EXECUTIONS = 6
#: The first placement of a filter on the rack (step 3): the execution after the pull-out.
PLACE_DIRTY = "insert_and_release"


def assert_flown_exactly_once(f: Flight, run_id: str, status: str) -> None:
    """The run completed; every command ran once on the habitat and was logged with its real outcome."""
    events = f.events(run_id)
    assert status == "completed", [e.data for e in events if e.kind is EventKind.INSTRUCTION_FAILED]
    assert not [e for e in events if e.kind is EventKind.INSTRUCTION_FAILED]
    sent = commands(events)
    assert len(sent) == IVA_COMMANDS, [s.data["command"] for s, _ in sent]
    unanswered = [s.instruction for s, answer in sent if answer is None]
    assert not unanswered, f"commands without a logged outcome: {unanswered}"
    assert all(answer is not None and answer.data["success"] for _, answer in sent)
    # The habitat's own record: each command executed once, and it succeeded.
    records = f.habitat.ledger_records()
    assert len(records) == IVA_COMMANDS, [(r["command_key"], r["state"]) for r in records]
    assert {r["state"] for r in records} == {"SUCCEEDED"}, [(r["command_key"], r["message"]) for r in records]
    executions = [r for r in records if r["service"].endswith("/execute_command")]
    assert len(executions) == IVA_EXECUTIONS
    logged = [s.data["command"] for s, _ in sent]
    assert [r["service"].rsplit("/", 1)[-1] for r in records].count("execute_command") == logged.count("execute_plan")
    # What the arm did: every motion once, each carried out.
    goals = f.goals()
    assert len({goal for goal, _ in goals}) == len(goals) == IVA_ARM_GOALS, goals
    assert {status for _, status in goals} == {4}, goals


def assert_in_flight(events: list[Event], trajectory: str, moment: datetime) -> None:
    """``moment`` (a fault) fell while the ground waited for the first execution of ``trajectory``."""
    sent, answer = next((s, a) for s, a in commands(events) if s.data["command"] == "execute_plan"
                        and s.data["args"]["trajectory"] == trajectory)
    assert answer is not None and sent.time < moment < answer.time, (sent.time, moment, answer and answer.time)


def test_resets_and_a_bridge_crash_mid_motion_leave_every_motion_done_once(ros_env: dict[str, str]) -> None:
    """1.3 s one way; the connection reset for 10 s while the pull-out executes; the habitat's
    bridge killed (and restarted by ``caretaker up``) while the dirty filter is placed."""
    with flight(ros_env, delay=DELAY, time_scale="1") as f:
        run = f.run()
        f.await_execution(PULL_OUT)
        f.link.control.reset(10)
        reset_at = datetime.now(UTC)
        f.await_execution(PLACE_DIRTY)
        killed = f.kill_bridge()
        killed_at = datetime.now(UTC)
        restarted = f.habitat.up.wait_for_line(r"^restarted bridge", 120)
        run_id, status = result_of(run)
        assert_flown_exactly_once(f, run_id, status)
        assert_in_flight(f.events(run_id), PULL_OUT, reset_at)
        assert_in_flight(f.events(run_id), PLACE_DIRTY, killed_at)
        stats = f.link.control.stats()
        assert stats.resets == 1 and stats.refused >= 1, stats
        reset = [c for c in stats.connections if c.ended_by == "reset by outage"]
        assert reset, "the ground's connection was cut by the reset"
        assert "bridge died" in f.habitat.up.tail(400) and restarted, f"bridge {killed} not restarted"


def test_a_30_s_hold_on_a_lossy_link_mid_motion_is_ridden_out(ros_env: dict[str, str]) -> None:
    """1.3 s one way with 5 % of segments lost; all traffic held for 30 s from the start of the
    pull-out. The motion itself is not what is tested here: the simulation runs as fast as it can."""
    with flight(ros_env, delay=DELAY, link_options=["--loss", "0.05", "--seed", "15"], time_scale="0") as f:
        run = f.run()
        f.await_execution(PULL_OUT)
        f.link.control.hold(30)
        held_at = datetime.now(UTC)
        run_id, status = result_of(run)
        assert_flown_exactly_once(f, run_id, status)
        assert_in_flight(f.events(run_id), PULL_OUT, held_at)
        stats = f.link.control.stats()
        assert stats.holds == 1 and stats.up_stalls + stats.down_stalls > 0, stats
        assert not [c for c in stats.connections if c.ended_by == "reset by outage"]


def test_an_outcome_lost_with_the_habitat_is_unknown_and_holds(ros_env: dict[str, str]) -> None:
    """The whole habitat side dies during the pull-out and comes back with its memory lost (a new
    ledger epoch): what became of the pull-out cannot be learnt. The run says so and holds for an
    operator; it never logs the pull-out as a success (nor as a failure)."""
    with flight(ros_env, delay=DELAY, time_scale="1", outage_budget=120) as f:
        run = f.run()
        f.await_execution(PULL_OUT)
        f.habitat.up.kill()
        f.restart_habitat_without_memory()
        held = run.wait_for_line(r"outcome unknown|unknown outcome", 300)
        run_id = run.wait_for_line(r"^READY run ").split()[2]
        events = f.events(run_id)
        pull = next(s for s, _ in commands(events) if s.data["command"] == "execute_plan"
                    and s.data["args"]["trajectory"] == PULL_OUT)
        answers = [e for e in events if e.kind is EventKind.COMMAND_RESULT and e.instruction == pull.instruction]
        assert answers and all(a.data["outcome"] == "unknown" and a.data["success"] is None for a in answers), held
        assert not [e for e in events if e.kind in (EventKind.INSTRUCTION_COMPLETED, EventKind.INSTRUCTION_FAILED)
                    and e.instruction == pull.instruction]
        assert events[-1].kind is EventKind.AWAITING_OPERATOR and "unknown" in events[-1].data["reason"]
        assert run.running, "it holds: no RESULT"
