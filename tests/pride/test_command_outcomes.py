"""Command keys and outcomes in the executive: unknown outcomes hold, halts stop and hold, links and
the journal are run states, and every action names who did it.

The gateway is the lab bench double (a unit test of the executive); it keeps a ledger of keys as
the habitat does, so "never run twice" is checked on what it executed. The halt of the real arm
is tests/pride/test_halt_on_the_robot.py.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import pytest

from pride.events import PAX, Event, EventKind
from pride.executive import Executive, Hold, InstructionStatus, JournalFailure, Mode, OperatorActionError, RunStatus
from pride.systems import CancelResult, Outcome
from records.audit_log import Availability
from support.audit import RecordedJournal
from support.executive_runs import TIMEOUT, Bench, finished, held
from support.lab_gateway import LabGateway


def at_move(executive: Executive) -> None:
    executive.start("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("alice", "dock")


def of(journal: RecordedJournal, kind: EventKind, number: str | None = None) -> list[Event]:
    return [e for e in journal.events if e.kind is kind and (number is None or e.instruction == number)]


def test_an_unknown_outcome_holds_and_asking_again_learns_it_without_running_the_command_twice(bench: Bench) -> None:
    executive, gateway, journal = bench()
    gateway.lose_reply["move"] = "link lost since 10:00:00Z, outage budget of 20 s spent"
    at_move(executive)
    snap = held(executive, Hold.OUTCOME_UNKNOWN, "1.3")
    assert snap.reason == (
        "1.3: outcome of run-1/1.3/1 unknown: link lost since 10:00:00Z, outage budget of 20 s spent"
    )
    assert snap.unknown_key == "run-1/1.3/1" and snap.statuses["1.3"] is InstructionStatus.OUTCOME_UNKNOWN
    (result,) = of(journal, EventKind.COMMAND_RESULT, "1.3")
    assert (result.data.to_json()["outcome"], result.data.to_json()["success"], result.data.to_json()["key"]) == (
        "unknown",
        None,
        "run-1/1.3/1",
    )
    assert not of(journal, EventKind.INSTRUCTION_FAILED) and not of(journal, EventKind.INSTRUCTION_COMPLETED, "1.3")
    for refused in (
        lambda: executive.retry("alice"),
        lambda: executive.perform("alice"),
        lambda: executive.go_back("alice", "1.2", "redo"),
    ):
        with pytest.raises(OperatorActionError, match=r"outcome of run-1/1\.3/1 is unknown: ask again"):
            refused()

    executive.ask_again("alice")
    held(executive, Hold.CONFIRMATION, "2.1")
    assert [c for _, c, _ in gateway.sent].count("move") == 1 and gateway.resent == ["run-1/1.3/1"]
    (asked,) = of(journal, EventKind.RETRY, "1.3")
    assert (asked.actor, asked.data.to_json()["same_key"], asked.data.to_json()["key"]) == (
        "alice",
        True,
        "run-1/1.3/1",
    )
    resend = of(journal, EventKind.COMMAND_SENT, "1.3")[-1]
    assert (resend.actor, resend.data.to_json()["key"], resend.data.to_json()["resend"]) == (
        "alice",
        "run-1/1.3/1",
        True,
    )
    assert of(journal, EventKind.COMMAND_RESULT, "1.3")[-1].data.to_json()["outcome"] == "succeeded"
    assert executive.snapshot().variables["moved"]["arrived"] is True


@pytest.mark.parametrize("found", ["succeeded", "failed"])
def test_the_operator_records_what_became_of_a_command_of_unknown_outcome(bench: Bench, found: str) -> None:
    executive, gateway, journal = bench()
    gateway.lose_reply["move"] = "no reply"
    at_move(executive)
    held(executive, Hold.OUTCOME_UNKNOWN, "1.3")
    with pytest.raises(OperatorActionError, match="say why"):
        executive.resolve("bob", found, " ")
    with pytest.raises(OperatorActionError, match="record succeeded or failed, not 'halted'"):
        executive.resolve("bob", "halted", "camera")
    executive.resolve("bob", Outcome(found), "the camera shows the arm at the dock")
    (resolved,) = of(journal, EventKind.OUTCOME_RESOLVED, "1.3")
    assert (resolved.actor, resolved.data.to_json()) == (
        "bob",
        {"key": "run-1/1.3/1", "outcome": found, "reason": "the camera shows the arm at the dock"},
    )
    if found == "succeeded":
        snap = held(executive, Hold.CONFIRMATION, "2.1")
        assert of(journal, EventKind.INSTRUCTION_COMPLETED, "1.3")[0].actor == "bob"
        assert snap.variables["moved"] == {
            "success": True,
            "message": "recorded by bob: the camera shows the arm at the dock",
        }
        return
    snap = held(executive, Hold.FAILURE, "1.3")
    assert "run-1/1.3/1 failed (recorded by bob: the camera shows the arm at the dock)" in snap.reason
    executive.retry("bob")  # a new attempt: a new key, executed
    held(executive, Hold.CONFIRMATION, "2.1")
    assert [e.data.to_json()["key"] for e in of(journal, EventKind.COMMAND_SENT, "1.3")] == [
        "run-1/1.3/1",
        "run-1/1.3/2",
    ]
    assert [c for _, c, _ in gateway.sent].count("move") == 2


def test_halt_cancels_the_command_in_flight_records_it_halted_by_the_user_and_retry_is_a_new_attempt(
    bench: Bench,
) -> None:
    executive, gateway, journal = bench()
    gateway.block.add("vent")
    at_move(executive)
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.confirm("carol")
    assert gateway.blocking.wait(TIMEOUT)  # the vent is executing
    executive.halt("bob", "the arm is drifting")
    snap = held(executive, Hold.HALTED, "2.1")
    assert snap.reason == "halted by bob: the arm is drifting (2.1 was halted before it finished)"
    assert (snap.halted_by, snap.halt_reason, snap.statuses["2.1"]) == (
        "bob",
        "the arm is drifting",
        InstructionStatus.HALTED,
    )
    assert gateway.cancels == ["run-1/2.1/1"]
    (halt,) = of(journal, EventKind.HALT)
    assert (halt.actor, halt.data.to_json()["key"], halt.data.to_json()["cancel"]) == (
        "bob",
        "run-1/2.1/1",
        {"stopped": True, "message": "stopped where it was"},
    )
    (result,) = of(journal, EventKind.COMMAND_RESULT, "2.1")
    assert (result.data.to_json()["outcome"], result.data.to_json()["success"]) == ("halted", False)
    (ended,) = of(journal, EventKind.INSTRUCTION_HALTED, "2.1")
    assert (ended.actor, ended.data.to_json()["reason"], ended.data.to_json()["next"]) == (
        "bob",
        "the arm is drifting",
        "2.1",
    )
    assert not of(journal, EventKind.INSTRUCTION_COMPLETED, "2.1") and not of(journal, EventKind.INSTRUCTION_FAILED)
    assert not of(journal, EventKind.INSTRUCTION_STARTED, "2.2")  # automation holds
    with pytest.raises(OperatorActionError, match="halted by bob: the arm is drifting: continue, retry or skip"):
        executive.perform("bob")
    with pytest.raises(OperatorActionError, match="hazardous command: confirm it first"):
        executive.retry("bob")  # each attempt at a hazardous command is confirmed
    executive.confirm("bob")
    gateway.block.clear()
    executive.retry("bob")
    held(executive, Hold.OPERATOR_ACTION, "2.4")
    sent = of(journal, EventKind.COMMAND_SENT, "2.1")
    assert [(e.data.to_json()["key"], e.data.to_json()["confirmed_by"]) for e in sent] == [
        ("run-1/2.1/1", "carol"),
        ("run-1/2.1/2", "bob"),
    ]


class SlowToAnswerCancels(LabGateway):
    """The robot stops at once, but its answer to the cancel comes only when ``answer`` is set (a
    loaded machine, a long link): the operator may carry on before the halt's record is written."""

    def __init__(self, images: str) -> None:
        super().__init__(images)
        self.answer = threading.Event()

    def cancel(self, key: str) -> CancelResult:
        stopped = super().cancel(key)
        assert self.answer.wait(TIMEOUT)
        return stopped


def test_a_halt_answered_after_the_operator_carried_on_does_not_hold_the_run_again(
    bench: Bench, tmp_path: Path
) -> None:
    gateway = SlowToAnswerCancels(str(tmp_path / "images"))
    executive, _, journal = bench(gateway=gateway)
    gateway.block.add("vent")
    at_move(executive)
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.confirm("carol")
    assert gateway.blocking.wait(TIMEOUT)
    halting = threading.Thread(target=executive.halt, args=("bob", "the arm is drifting"))
    halting.start()
    held(executive, Hold.HALTED, "2.1")  # the vent ended halted; the robot's answer is still on its way
    gateway.blocking.clear()
    executive.confirm("bob")
    executive.retry("bob")  # the operator carries on: a new attempt, executing
    assert gateway.blocking.wait(TIMEOUT)
    gateway.answer.set()
    halting.join(TIMEOUT)
    assert not halting.is_alive()
    (halt,) = of(journal, EventKind.HALT)  # the halt is on the record all the same
    assert halt.actor == "bob" and halt.data.to_json()["cancel"] == {"stopped": True, "message": "stopped where it was"}
    gateway.release.set()
    held(executive, Hold.OPERATOR_ACTION, "2.4")  # not held as halted at 2.2


def test_halt_when_nothing_moves_holds_until_the_operator_continues(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.start("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.halt("alice")
    snap = held(executive, Hold.HALTED, "1.2")
    assert snap.reason == "halted by alice (at 1.2)" and gateway.cancels == []
    assert of(journal, EventKind.HALT)[0].data.to_json() == {
        "reason": "",
        "key": None,
        "cancel": None,
        "executing": False,
    }
    with pytest.raises(OperatorActionError, match="has not failed or been halted"):
        executive.retry("alice")
    executive.resume_automation("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.2")


def test_halt_ends_a_wait_at_once_and_stop_halts_first(bench: Bench) -> None:
    executive, gateway, journal = bench()
    gateway.stale.add("state")  # the wait of 1.4 would take its whole timeout
    at_move(executive)
    assert executive.wait_for(lambda s: s.executing and s.current == "1.4", TIMEOUT)
    executive.stop("dave", "end of the shift")
    executive.join(TIMEOUT)  # PAX's thread records how the wait ended
    assert finished(executive).status is RunStatus.STOPPED
    (ended,) = of(journal, EventKind.INSTRUCTION_HALTED, "1.4")
    assert (ended.actor, ended.data.to_json()["reason"]) == ("dave", "end of the shift")
    assert "halted while watching telemetry by dave: end of the shift" in ended.data.to_json()["detail"]
    (stopped,) = of(journal, EventKind.RUN_STOPPED)
    assert (stopped.actor, stopped.data.to_json()["reason"]) == ("dave", "end of the shift")


def test_a_lost_link_is_a_run_state_and_the_run_goes_on_when_it_is_back(bench: Bench) -> None:
    executive, gateway, journal = bench()
    gateway.block.add("move")
    at_move(executive)
    assert executive.wait_for(lambda s: s.executing and s.current == "1.3", TIMEOUT)
    since = datetime(2026, 11, 23, 10, 0, 0, tzinfo=UTC)
    gateway.set_link(False, in_flight=1, since=since.timestamp())
    snap = executive.wait_for(lambda s: s.link_lost_since is not None, TIMEOUT)
    assert snap is not None and (snap.link_lost_since, snap.commands_in_flight) == (since, 1)
    assert snap.link_summary() == "link lost since 10:00:00Z, 1 command in flight"
    assert snap.hold is None and snap.status is RunStatus.ACTIVE  # not a failure: it waits
    lost = executive.wait_for(lambda s: EventKind.LINK_LOST in journal.kinds(), TIMEOUT)
    assert lost is not None
    (event,) = of(journal, EventKind.LINK_LOST)
    assert (event.actor, event.instruction, event.data.to_json()) == (
        PAX,
        "1.3",
        {"links": ["ws://lab.bench:9090"], "since": since.isoformat(), "in_flight": 1, "quiet": False},
    )
    gateway.set_link(True)
    gateway.release.set()
    held(executive, Hold.CONFIRMATION, "2.1")
    # the supervisor records the link's return on its own thread: it may follow the move's result
    assert executive.wait_for(lambda s: EventKind.LINK_RESTORED in journal.kinds(), TIMEOUT) is not None
    (restored,) = of(journal, EventKind.LINK_RESTORED)
    assert restored.actor == PAX and restored.data.to_json()["since"] == since.isoformat()
    assert executive.snapshot().link_summary() == ""


def test_a_quiet_link_is_a_lost_link_from_when_it_was_last_heard(bench: Bench) -> None:
    """A held link stays connected for minutes before the keepalive gives it up; the run must say
    at once that it has no news, since when, and what is in flight, and not again when it drops."""
    executive, gateway, journal = bench()
    gateway.block.add("move")
    at_move(executive)
    assert executive.wait_for(lambda s: s.executing and s.current == "1.3", TIMEOUT)
    heard = datetime(2026, 11, 23, 10, 0, 0, tzinfo=UTC)
    gateway.set_link(True, in_flight=1, quiet_since=heard.timestamp())
    snap = executive.wait_for(lambda s: s.link_lost_since is not None, TIMEOUT)
    assert snap is not None and (snap.link_lost_since, snap.commands_in_flight, snap.link_quiet) == (heard, 1, True)
    assert snap.link_summary() == "no news since 10:00:00Z, 1 command in flight"
    assert snap.to_json()["link"] == {"state": "lost", "since": heard.isoformat(), "in_flight": 1, "quiet": True}
    assert executive.wait_for(lambda s: EventKind.LINK_LOST in journal.kinds(), TIMEOUT) is not None
    gateway.set_link(False, in_flight=1, since=heard.timestamp())  # the keepalive gives it up: the same loss
    snap = executive.wait_for(lambda s: not s.link_quiet, TIMEOUT)
    assert snap is not None and snap.link_lost_since == heard
    gateway.set_link(True)
    gateway.release.set()
    held(executive, Hold.CONFIRMATION, "2.1")
    assert executive.wait_for(lambda s: EventKind.LINK_RESTORED in journal.kinds(), TIMEOUT) is not None
    (lost,) = of(journal, EventKind.LINK_LOST)  # one loss, recorded when the link fell quiet
    assert lost.data.to_json() == {
        "links": ["ws://lab.bench:9090"],
        "since": heard.isoformat(),
        "in_flight": 1,
        "quiet": True,
    }


def test_a_verify_counts_the_light_time_into_its_timeout(bench: Bench) -> None:
    executive, gateway, journal = bench()
    gateway.delay = 0.5  # telemetry reaches the ground half a second after it happened
    gateway.stale.add("door_open")
    at_move(executive)
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.confirm("alice")
    held(executive, Hold.OPERATOR_ACTION, "3.1")  # the verify failed into its recover step
    (failed,) = of(journal, EventKind.INSTRUCTION_FAILED, "2.2")
    assert "(waited 2 s + 0.5 s light time)" in failed.data.to_json()["reason"]


def test_a_journal_that_fails_stops_the_run_at_once_with_its_reason_and_burns_no_number(bench: Bench) -> None:
    executive, gateway, journal = bench()
    gateway.block.add("move")
    at_move(executive)
    assert gateway.blocking.wait(TIMEOUT)  # the move was sent and recorded; its result will not be
    stored = len(journal.events)
    journal.fail_with = OSError("disk full")
    gateway.release.set()
    snap = finished(executive)
    assert snap.status is RunStatus.STOPPED
    assert snap.error == "OSError: disk full"
    assert len(journal.events) == stored and snap.last_seq == journal.events[-1].seq  # no event half-made
    assert [c for _, c, _ in gateway.sent] == ["move"]  # and nothing more done unrecorded
    with pytest.raises(OperatorActionError, match="is stopped"):
        executive.retry("alice")


def test_an_operator_action_the_journal_cannot_store_stops_the_run(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.start("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    journal.fail_with = OSError("database gone")
    with pytest.raises(JournalFailure, match="could not store operator_input: OSError: database gone"):
        executive.enter("alice", "dock")
    assert finished(executive).status is RunStatus.STOPPED
    assert gateway.sent == []


class GatedJournal(RecordedJournal):
    """Appends wait while the gate is closed, as the audit log waits out a database outage."""

    def __init__(self, journal: RecordedJournal) -> None:
        super().__init__(journal.log)
        self.gate = threading.Event()
        self.gate.set()
        self.waiting = threading.Event()

    def append(self, event: Event) -> None:
        if not self.gate.is_set():
            self.waiting.set()
            self.gate.wait()
        super().append(event)

    @property
    def availability(self) -> Availability:
        return Availability(True) if self.gate.is_set() else Availability(False, datetime.now(UTC), "gate closed")


def test_halt_reaches_the_robot_and_the_snapshot_answers_while_an_append_waits(
    bench: Bench, new_journal: Callable[..., RecordedJournal]
) -> None:
    journal = GatedJournal(new_journal())
    executive, gateway, _ = bench(journal=journal)
    gateway.block.add("move")
    at_move(executive)
    assert gateway.blocking.wait(TIMEOUT)
    journal.gate.clear()
    blocked = threading.Thread(target=executive.set_breakpoint, args=("erin", "2.2"))  # waits holding the lock
    halting = threading.Thread(target=executive.halt, args=("bob", "stop it now"))
    try:
        blocked.start()
        assert journal.waiting.wait(TIMEOUT)
        snap = executive.snapshot()  # does not wait for the append
        assert (snap.journal_available, snap.journal_error, snap.executing) == (False, "gate closed", True)
        assert "audit log unavailable since" in snap.journal_summary()
        halting.start()
        assert gateway.cancel_seen.wait(TIMEOUT)  # the cancel goes out although an append holds the executive's lock
        assert gateway.cancels == ["run-1/1.3/1"] and blocked.is_alive() and halting.is_alive()
    finally:
        journal.gate.set()  # whatever failed above, nothing stays blocked behind the gate
        blocked.join(TIMEOUT)
        if halting.ident is not None:  # started
            halting.join(TIMEOUT)
    held(executive, Hold.HALTED, "1.3")
    kinds = [e.kind for e in journal.events]
    assert EventKind.BREAKPOINT_SET in kinds and EventKind.HALT in kinds and EventKind.INSTRUCTION_HALTED in kinds


def test_manual_run_is_completed_by_the_operator_and_a_confirmed_send_names_its_confirmer(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.MANUAL, name="lab_records.xml")
    gateway.values["state"] = "shelf"
    executive.start("carol")
    held(executive, Hold.OPERATOR_INPUT, "1.1")
    executive.enter("carol", "shelf")
    for number in ("1.2", "1.3", "2.1"):
        held(executive, Hold.MANUAL_MODE, number)
        executive.perform("carol")
    assert finished(executive).status is RunStatus.COMPLETED
    assert journal.events[-1].kind is EventKind.RUN_COMPLETED and journal.events[-1].actor == "carol"
