"""Monitors: what PAX watches on every telemetry update while the arm moves (pride/monitoring.py).

The lab bench (its gateway a double: a unit test of the executive); ``lab_monitors.xml`` watches
the bench temperature against its SysRep's red limit (above 40 for 2 samples: go to ``cool``) and
the door (it must stay shut: hold). The console's fold of what monitors saw and its words for a
value's limit state are checked here too (its Monitors panel: tests/web/test_console_follows_the_run.py).
The real-stack gripper monitor is in tests/interop.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from console.folded_run import fold_events
from console.monitor_states import limit_state
from pride.events import PAX, Event, EventKind
from pride.executive import Executive, Hold, InstructionStatus, Mode, RunStatus
from pride.monitoring import MonitorBoard
from pride.report import summarize, to_markdown
from procedure_language.limits import Limits
from procedure_language.lint import check_procedure, lint_file
from procedure_language.sysrep import SysRep, Telemetry
from support.audit import RecordedJournal
from support.executive_runs import TIMEOUT, Bench, finished, held
from support.procedures import FIXTURES, REPO


def of(journal: RecordedJournal, kind: EventKind) -> list[Event]:
    return [e for e in journal.events if e.kind is kind]


def test_a_red_limit_during_a_motion_halts_it_and_goes_to_the_contingency_step(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.AUTONOMOUS, "lab_monitors.xml")
    gateway.block.add("move")
    stop, held_meanwhile = gateway.cancel, []

    def answered_after_the_motion_ended(key: str) -> Any:  # as a robot does: once the arm is at rest
        answer = stop(key)
        held_meanwhile.append(executive.wait_for(lambda s: not s.executing, TIMEOUT).hold)
        return answer

    gateway.cancel = answered_after_the_motion_ended
    executive.start("alice")
    assert gateway.blocking.wait(TIMEOUT)  # the arm moves
    gateway.set("temperature", 45.0)  # one sample out: within the item's persistence (2 samples)
    gateway.set("temperature", 25.0)
    gateway.set("temperature", 46.0)
    gateway.set("temperature", 47.0)  # two in a row: violated
    snap = finished(executive)
    assert snap.status is RunStatus.COMPLETED
    (violated,) = of(journal, EventKind.MONITOR_VIOLATED)
    assert violated.instruction == "1.1" and violated.actor == PAX
    assert violated.data.to_json() == {
        "monitor": "lab.temperature (step 1)",
        "system": "lab",
        "telemetry": "temperature",
        "value": 47.0,
        "limit": "red above 40",
        "action": "goto:cool",
        "text": "The bench stays below its red temperature",
    }
    (halt,) = of(journal, EventKind.HALT)
    assert halt.actor == PAX and "The bench stays below its red temperature" in halt.data.to_json()["reason"]
    assert gateway.cancels == ["run-1/1.1/1"]  # the motion in flight was cancelled
    # the motion ended before the robot answered the halt: the run then waited for the halt's record
    # to go on to the contingency, and asked no operator to answer the halt (no prompt left behind)
    assert held_meanwhile == [None]
    assert snap.statuses["1.1"] is InstructionStatus.HALTED and snap.statuses["1.2"] is InstructionStatus.PENDING
    (went,) = of(journal, EventKind.WENT_TO)
    assert went.data.to_json() == {"from": "1.1", "next": "2.1", "reason": halt.data.to_json()["reason"]}
    assert snap.statuses["2.1"] is InstructionStatus.COMPLETED
    assert [c for _, c, _ in gateway.sent] == ["move"]  # never the capture
    said = to_markdown(summarize(list(journal.events)))
    assert "## Monitors" in said
    assert "at 1.1: monitor violated: lab.temperature = 47 (red above 40): HALT, then go to step cool" in said, said


def test_a_door_that_opens_holds_the_run_after_the_motion_and_its_return_is_recorded(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.AUTONOMOUS, "lab_monitors.xml")
    gateway.block.add("move")
    executive.start("alice")
    assert gateway.blocking.wait(TIMEOUT)
    gateway.set("door_open", True)
    assert executive.wait_for(lambda s: any(e.kind is EventKind.MONITOR_VIOLATED for e in journal.events), TIMEOUT)
    gateway.release.set()  # the motion ends normally: a hold is not a halt
    snap = held(executive, Hold.PAUSED, "1.2")
    assert snap.statuses["1.1"] is InstructionStatus.COMPLETED and [c for _, c, _ in gateway.sent] == ["move"]
    gateway.set("door_open", False)
    assert executive.wait_for(lambda s: any(e.kind is EventKind.MONITOR_CLEARED for e in journal.events), TIMEOUT)
    (cleared,) = of(journal, EventKind.MONITOR_CLEARED)
    assert cleared.data.to_json()["value"] is False
    executive.resume_automation("alice")
    assert finished(executive).status is RunStatus.COMPLETED
    assert [c for _, c, _ in gateway.sent] == ["move", "capture"]
    # the console's fold of the record: the door's last word is its clear, after one violation
    seen = fold_events("run-1", list(journal.events)).to_dict()["monitors"]["seen"]
    assert seen["lab.door_open (step 1)"] | {"time": "T"} == {
        "violated": False,
        "value": False,
        "limit": None,
        "action": None,
        "time": "T",
        "instruction": cleared.instruction,
        "seq": cleared.seq,
        "violations": 1,
    }


def test_the_console_says_a_values_limit_state_in_words_not_by_colour_alone() -> None:
    bands = Telemetry("t", "T", "real", limits=Limits(red_low=5, yellow_low=10, yellow_high=30, red_high=40))
    said = {value: limit_state(bands, value) for value in (20, 35, 45, 7, 2, "warm")}
    assert said[20] == {"state": "green", "words": "GREEN", "limit": None}
    assert said[35] == {"state": "yellow", "words": "YELLOW HIGH", "limit": "yellow below 10 or above 30"}
    assert said[45] == {"state": "red", "words": "RED HIGH", "limit": "red below 5 or above 40"}
    assert said[7] == {"state": "yellow", "words": "YELLOW LOW", "limit": "yellow below 10 or above 30"}
    assert said[2] == {"state": "red", "words": "RED LOW", "limit": "red below 5 or above 40"}
    assert said["warm"] == {"state": "red", "words": "RED", "limit": "red below 5 or above 40"}  # no side to name
    shut = Telemetry("door_open", "Door Open", "boolean", limits=Limits(equals=False))
    assert limit_state(shut, True) == {"state": "red", "words": "RED", "limit": "not false"}
    assert limit_state(shut, None) is None and limit_state(Telemetry("x", "X", "real"), 3.0) is None


def test_the_iva_insertion_watches_the_cabinet_lock_open_and_its_own_lock_step_is_not_watched(
    sysreps: dict[str, SysRep],
) -> None:
    """The shipped IVA procedure halts if the cabinet's lock closes while the clean filter goes in;
    the lock the procedure closes itself is a step of its own, where that monitor no longer watches."""
    procedure = check_procedure(REPO / "procedures" / "iva_cdra_filter_replacement.xml", sysreps).procedure
    steps = {step.id: step.number for step in procedure.steps}
    assert steps["lock_clean"] == steps["insert_clean"] + 1
    board = MonitorBoard(procedure, sysreps)
    board.enter(steps["insert_clean"])
    assert board.update("cdra", "filter_locked", False, now=0.0) == []
    (closed,) = board.update("cdra", "filter_locked", True, now=1.0)
    assert closed.violated and closed.monitor.on_violation == "halt"
    assert closed.reason == (
        "monitor The cabinet's lock stays open while the clean filter goes in: "
        "cdra.filter_locked = True (must be = false)"
    )
    board.enter(steps["lock_clean"])
    assert board.update("cdra", "filter_locked", True, now=2.0) == []


def test_a_monitor_in_a_called_procedure_is_an_error_not_silently_unwatched(sysreps: dict[str, SysRep]) -> None:
    problems = [str(p) for p in lint_file(FIXTURES / "lab_calls_monitored.xml", sysreps)]
    assert len(problems) == 2, problems
    for problem, line in zip(problems, (7, 10), strict=True):
        assert f"lab_monitors.xml:{line}:5: lab_monitors is called (" in problem, problem
        assert problem.endswith("a called procedure's monitors are not watched; put this monitor in the calling step")


def test_a_resumed_run_watches_the_monitors_of_the_steps_it_was_in_before(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    """A procedure-scoped monitor of step 1 still watches after a resume in step 2: the resume
    rebuilds which steps the run was in from its record."""
    executive, gateway, journal = bench(Mode.AUTONOMOUS, "lab_monitor_resumed.xml")
    executive.start("alice")
    held(executive, Hold.OPERATOR_ACTION, "2.1")
    executive.stop("alice", "runner restarted")
    executive.join(TIMEOUT)
    resumed = Executive.resume(
        check_procedure(FIXTURES / "lab_monitor_resumed.xml", sysreps),
        gateway,
        again := new_journal(journal.events),
        list(journal.events),
        "alice",
    )
    try:
        held(resumed, Hold.OPERATOR_ACTION, "2.1")
        gateway.set("door_open", True)
        assert resumed.wait_for(lambda s: bool(of(again, EventKind.MONITOR_VIOLATED)), TIMEOUT)
        (violated,) = of(again, EventKind.MONITOR_VIOLATED)
        assert violated.data.to_json()["monitor"] == "lab.door_open (step 1)"
    finally:
        resumed.stop("teardown")
